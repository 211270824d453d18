"""Small-perturbation modes of the plant at a scenario's initial condition, open loop and with
the backup damper of the hold on a silent fc (plant_sim/hold.py).

    python -m plant_sim modes --scenario cruise

The model: the rigid-body derivative (``dynamics.deriv``, flat earth, the scenario's
uncertainty multipliers, thrust held) linearised by central differences at the initial
airspeed, altitude and alpha, wings level, rates zero, surfaces at the moment trim
(``trim.trim_at``). States z = (u, v, w, p, q, r, phi, theta) in m/s, rad/s, rad; inputs the
three surfaces (rad). The round Earth's lift relief (0.92 g at the cruise) leaves a
longitudinal residual in the derivative at this point; it does not enter the Jacobian's
lateral block, which is what the damper is for. With the damper the surfaces follow their
commands through the actuator's first-order lag (``actuators.tau_s``; the rate limit is not
in a linear model).

Besides the eigenvalues the report integrates the linear model for ``--hold-s`` seconds with
a held surface ``--offset-deg`` off the trim on one surface (the rudder by default), open loop
and damped: the bank a silent fc's hold costs when the mean it holds is not exactly the trim.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from plant_sim import dynamics as dy
from plant_sim.params import build_params
from plant_sim.scenario import Scenario
from plant_sim.trim import trim_at

DEG = math.pi / 180.0
#: state names of the linear model, in order
STATE_NAMES = ("u_m_s", "v_m_s", "w_m_s", "p_rad_s", "q_rad_s", "r_rad_s", "phi_rad",
               "theta_rad")
Z_U, Z_V, Z_W, Z_P, Z_Q, Z_R, Z_PHI, Z_THETA = range(8)
_LATERAL = (Z_V, Z_P, Z_R, Z_PHI)


@dataclass
class LinearModel:
    a: np.ndarray            # (8, 8) dz/dt per state
    b: np.ndarray            # (8, 3) dz/dt per surface (rad)
    V_m_s: float
    trim_rad: np.ndarray     # the moment trim the model is taken at
    tau_s: float             # actuator lag


def _quat_zyx(phi, theta, psi):
    cr, sr = math.cos(phi / 2), math.sin(phi / 2)
    cp, sp = math.cos(theta / 2), math.sin(theta / 2)
    cy, sy = math.cos(psi / 2), math.sin(psi / 2)
    return (cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy)


def linear_model(sc: Scenario) -> LinearModel:
    """The linear model at the scenario's initial condition (module docstring)."""
    p, _ = build_params(sc)
    p[dy.P_EARTH] = dy.EARTH_FLAT
    p[dy.P_DIST_ON] = 0.0
    ini = sc.data["initial"]
    a0 = ini["alpha_deg"] * DEG
    V = float(ini["V_m_s"])
    trim = trim_at(sc, a0, 0.0).deflection_rad
    x0 = np.zeros(dy.X_N)
    dy.initial_state(V, ini["h_m"], a0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, x0)
    w = np.zeros(dy.W_N)
    thr = 0.5
    x = x0.copy()
    xd = np.zeros(dy.X_RB_N)
    z0 = np.array([x0[dy.X_U], x0[dy.X_V], x0[dy.X_W], 0.0, 0.0, 0.0, 0.0, a0])

    def f(z, d):
        x[:] = x0
        x[dy.X_U:dy.X_W + 1] = z[0:3]
        x[dy.X_P:dy.X_R + 1] = z[3:6]
        x[dy.X_Q0:dy.X_Q3 + 1] = _quat_zyx(z[Z_PHI], z[Z_THETA], 0.0)
        w[dy.W_AUX + dy.AX_THR_POS] = thr
        dy.deriv(x, 0.0, d[0], d[1], d[2], p, w, xd)
        phi, th = z[Z_PHI], z[Z_THETA]
        pp, qq, rr = z[Z_P], z[Z_Q], z[Z_R]
        out = np.empty(8)
        out[0:3] = xd[dy.X_U:dy.X_W + 1]
        out[3:6] = xd[dy.X_P:dy.X_R + 1]
        out[Z_PHI] = pp + (qq * math.sin(phi) + rr * math.cos(phi)) * math.tan(th)
        out[Z_THETA] = qq * math.cos(phi) - rr * math.sin(phi)
        return out

    eps = np.array([0.1, 0.1, 0.1, 1e-4, 1e-4, 1e-4, 1e-4, 1e-4])
    a = np.zeros((8, 8))
    for j in range(8):
        e = np.zeros(8)
        e[j] = eps[j]
        a[:, j] = (f(z0 + e, trim) - f(z0 - e, trim)) / (2 * eps[j])
    b = np.zeros((8, 3))
    for j in range(3):
        e = np.zeros(3)
        e[j] = 1e-4
        b[:, j] = (f(z0, trim + e) - f(z0, trim - e)) / 2e-4
    return LinearModel(a, b, V, trim, float(sc.data["actuators"]["tau_s"]))


def damper_gain(servo: dict, V_m_s: float) -> np.ndarray:
    """The hold's damper (plant_sim/hold.py) as a (3, 8) gain on the linear model's states:
    surface increments (rad) = K z (beta taken as v / V)."""
    k = np.zeros((3, 8))
    kp, kq, kr, kb = (servo["backup_p_gain_s"], servo["backup_q_gain_s"],
                      servo["backup_r_gain_s"], servo["backup_beta_gain"])
    k[0, Z_P], k[0, Z_Q] = kp, -kq
    k[1, Z_P], k[1, Z_Q] = -kp, -kq
    k[2, Z_R], k[2, Z_V] = kr, -kb / V_m_s
    return k


def closed_loop(m: LinearModel, k: np.ndarray) -> np.ndarray:
    """The (11, 11) system of (z, surface deviations) with the surfaces commanded K z through
    the actuator lag (tau > 0), or the (8, 8) A + B K (tau = 0)."""
    if m.tau_s <= 0.0:
        return m.a + m.b @ k
    n = 8
    acl = np.zeros((n + 3, n + 3))
    acl[:n, :n] = m.a
    acl[:n, n:] = m.b
    acl[n:, :n] = k / m.tau_s
    acl[n:, n:] = -np.eye(3) / m.tau_s
    return acl


def classify(a: np.ndarray, tau_s: float = 0.0) -> list[tuple[complex, str]]:
    """Eigenvalues with ``lateral`` / ``longitudinal`` by where each eigenvector lives (v, p,
    r, phi vs u, w, q, theta; velocities scaled by 1/2000 m/s to angle-like sizes), or
    ``actuator`` for the fast lags of an (11, 11) system (real part below -1 / (2 tau))."""
    ev, vec = np.linalg.eig(a)
    out = []
    for i in range(len(ev)):
        e = complex(ev[i])
        if a.shape[0] > 8 and tau_s > 0.0 and e.real < -0.5 / tau_s:
            out.append((e, "actuator"))
            continue
        v = np.abs(vec[:8, i])
        v[[Z_U, Z_V, Z_W]] /= 2000.0
        lat = np.linalg.norm(v[list(_LATERAL)])
        lon = np.linalg.norm(v[[Z_U, Z_W, Z_Q, Z_THETA]])
        out.append((e, "lateral" if lat >= lon else "longitudinal"))
    out.sort(key=lambda e: (e[1], -e[0].real, abs(e[0].imag)))
    return out


def held_offset_bank_deg(m: LinearModel, k: np.ndarray, offset_rad: np.ndarray,
                         hold_s: float) -> float:
    """The largest |phi| (deg) of the linear model over ``hold_s`` with the surfaces held
    ``offset_rad`` (float64[3]) off the trim, from the trim, with the damper K (zeros: open loop)."""
    acl = closed_loop(m, k)
    n = acl.shape[0]
    if n == 8:
        forcing = m.b @ offset_rad
    else:
        forcing = np.zeros(n)
        forcing[8:] = offset_rad / m.tau_s       # the surfaces' command carries the offset
    z = np.zeros(n)
    dt = 1e-3
    worst = 0.0

    def fz(zz):
        return acl @ zz + forcing

    for _ in range(int(round(hold_s / dt))):
        k1 = fz(z)
        k2 = fz(z + 0.5 * dt * k1)
        k3 = fz(z + 0.5 * dt * k2)
        k4 = fz(z + dt * k3)
        z = z + dt / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
        worst = max(worst, abs(z[Z_PHI]))
    return math.degrees(worst)


def _mode_line(e: complex, kind: str) -> str:
    wn = abs(e)
    if abs(e.imag) > 1e-9:
        zeta = -e.real / wn if wn > 0 else 0.0
        return (f"  {kind:12s} {e.real:+9.4f} {e.imag:+9.4f}j 1/s  (omega_n {wn:.3f} rad/s, "
                f"damping ratio {zeta:+.3f})")
    tc = (f"time constant {-1.0 / e.real:.2f} s" if e.real < 0
          else f"doubling time {math.log(2) / e.real:.2f} s" if e.real > 0 else "neutral")
    return f"  {kind:12s} {e.real:+9.4f}            1/s  ({tc})"


def report(sc: Scenario, offset_deg: float = 0.2, surface: int = 2, hold_s: float = 10.0) -> str:
    """The modes open loop and damped, and the bank of a held offset (module docstring)."""
    m = linear_model(sc)
    sv = sc.data["servo"]
    k = damper_gain(sv, m.V_m_s)
    ini = sc.data["initial"]
    lines = [f"scenario {sc.name}: V {ini['V_m_s']} m/s, h {ini['h_m']} m, alpha "
             f"{ini['alpha_deg']} deg, wings level, surfaces at the moment trim "
             f"{np.round(np.degrees(m.trim_rad), 3).tolist()} deg (flat-earth linearisation)",
             f"lateral derivatives: L_beta {m.a[Z_P, Z_V] * m.V_m_s:+.3f} 1/s^2, L_p "
             f"{m.a[Z_P, Z_P]:+.4f} 1/s, N_beta {m.a[Z_R, Z_V] * m.V_m_s:+.4f} 1/s^2, N_r "
             f"{m.a[Z_R, Z_R]:+.4f} 1/s; per rad of surface (left, right, rudder): "
             f"p' {np.round(m.b[Z_P], 3).tolist()}, q' {np.round(m.b[Z_Q], 3).tolist()}, "
             f"r' {np.round(m.b[Z_R], 3).tolist()} 1/s^2",
             "open loop (surfaces held):"]
    lines += [_mode_line(e, kd) for e, kd in classify(m.a) if kd != "actuator"]
    gains = (f"backup_p_gain_s {sv['backup_p_gain_s']}, backup_q_gain_s {sv['backup_q_gain_s']}, "
             f"backup_r_gain_s {sv['backup_r_gain_s']}, backup_beta_gain {sv['backup_beta_gain']}")
    lines.append(f"with the hold's damper ({gains}; actuator lag {m.tau_s} s):")
    lines += [_mode_line(e, kd) for e, kd in classify(closed_loop(m, k), m.tau_s)]
    off = np.zeros(3)
    off[surface] = offset_deg * DEG
    name = ("left elevon", "right elevon", "rudder")[surface]
    ol = held_offset_bank_deg(m, np.zeros((3, 8)), off, hold_s)
    cl = held_offset_bank_deg(m, k, off, hold_s)
    lines.append(f"{name} held {offset_deg} deg off the trim for {hold_s} s from the trim: "
                 f"largest bank {ol:.1f} deg open loop, {cl:.2f} deg with the damper")
    return "\n".join(lines)
