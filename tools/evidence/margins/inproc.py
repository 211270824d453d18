"""tools/evidence/margins/inproc.py - gain, phase and time-delay margins of the nonlinear law (issue 15, point 4).

The loop is broken at the actuator input, one channel at a time, as an autopilot is certified:
the law's surface command is split into three *virtual* channels

    roll  v_l = (left - right) / 2     (differential elevons)
    pitch v_m = (left + right) / 2     (symmetric elevons)
    yaw   v_n = rudder

and a perturbation is inserted in one of them (or in all three) between the law and the
plant's actuators, in closed-loop simulation of the full nonlinear law against the full plant
(the law fed the plant's truth, in one numba loop as tools.sitl.closed_loop):

- **gain**: v_out = k v; the gain margin is the smallest k > 1 (and the largest k < 1) at which
  the loop loses stability (divergence, or a persistent oscillation: :func:`stable`);
- **delay**: v_out(t) = v(t - N frames) (a ring buffer; all three channels: the link delays
  every surface); the time-delay margin is the largest N that stays stable;
- **all-pass**: a first-order all-pass (a - s)/(a + s) (unit gain, phase lag 2 atan(w/a)) set
  to lag phi at the channel's measured crossover; the phase margin is the largest phi that
  stays stable (a time-domain check of the sweep);
- **sine**: v_out = v + A sin(w t) from ``t_on``; the broken-loop transfer at w is
  L(jw) = -V(jw) / V_out(jw) (Fourier projection over whole periods). A sweep gives the
  crossover |L| = 1 with its phase margin, and the gain margin at the -180 deg crossing.

Over the wire (``wire`` subcommand): the same delay, but between the two processes in
lockstep: tools.sitl.linkimpair's ``delay_frames`` holds the fc's SERVO_OUTPUT_RAW answers N frames
and re-stamps them, so the plant applies at frame k the fc's answer to frame k - N (exactly the
in-process ring buffer).

    python -m tools.evidence.margins --out runs/margins              # in process, both variants
    python -m tools.evidence.margins wire --frames 20,40 --out runs/margins_wire

The case: the paper's (scenario ``paper``, uncertainty on, steps) at 1 kHz frames (1 ms delay
resolution, law at 500/100 Hz), with the paper's sinusoidal disturbance OFF (``--disturbance``
turns it on): a persistent forced oscillation would otherwise be read as a limit cycle and would
sit on the sweep's frequencies.
"""
from __future__ import annotations

import argparse
import copy
import json
import math
import time
from pathlib import Path

import numpy as np
from numba import njit

from fc.control import layout as L
from plant_sim import dynamics as dy
from plant_sim.sim import TRUTH_N, TRUTH_NAMES, truth_kernel
from tools.evidence.margins.flight import Flight, stable
from tools.sitl.closed_loop import law_frame

from hyfc_wire.numba_cache import drop_stale

# _loop inlines the law's and the plant's kernels (numba links a callee into its caller's
# cache and checks only the caller's file): recompile when any of them changed. Without it,
# a parameter slot that moved (a parameter added before it) was read from its old index.
_ROOT = Path(__file__).resolve().parents[3]
drop_stale(__file__, [str(f) for pkg in ("fc/control", "plant_sim", "hyfc_wire", "tools/sitl",
                                   "tools/sitl/closed_loop")
                      for f in (_ROOT / pkg).glob("*.py")])

CHANNELS = ("roll", "pitch", "yaw")
ALL = 3                                   # channel index meaning all three
MODES = {"none": 0, "gain": 1, "delay": 2, "allpass": 3, "sine": 4, "gain_ac": 5}

# inj layout (float64[INJ_N])
I_MODE, I_CH, I_GAIN, I_DELAY_N, I_AP_A, I_AMP, I_OMEGA, I_T_ON, I_LP_W = range(9)
INJ_N = 9
#: corner of the low-pass that gives "gain_ac" its reference (the trim and the slow part), rad/s
AC_CORNER_RAD_S = 0.2

_TRUTH_EST0 = TRUTH_NAMES.index("alpha_rad")
RING_MAX = 4096                            # longest delay, frames


# ------------------------------------------------------------------------ the injection block
@njit(cache=True)
def to_virtual(delta, v):
    """Surfaces (left, right, rudder) rad -> virtual channels (roll, pitch, yaw) rad."""
    v[0] = 0.5 * (delta[0] - delta[1])
    v[1] = 0.5 * (delta[0] + delta[1])
    v[2] = delta[2]


@njit(cache=True)
def from_virtual(v, delta):
    """Virtual channels (roll, pitch, yaw) rad -> surfaces (left, right, rudder) rad."""
    delta[0] = v[1] + v[0]
    delta[1] = v[1] - v[0]
    delta[2] = v[2]


@njit(cache=True)
def inject(inj, v_in, t_s, dt_s, k, ring, ap_state, v_out):
    """The perturbation at sample ``k`` (time ``t_s``, step ``dt_s``): v_in -> v_out (rad).

    ``ring`` (RING_MAX, 3): delay line, primed with the first input (``k`` == 0);
    ``ap_state`` (3, 3): the all-pass's last input and output per channel (Tustin form of
    (a - s)/(a + s): unit gain at every frequency, phase -2 atan(w/a) up to frequency warping),
    and the low-pass reference of "gain_ac" (v_out = v_ref + k (v - v_ref), v_ref = v through
    a first-order low-pass of corner inj[I_LP_W]: the gain acts on the perturbation about
    trim, not on the trim deflection itself).
    Channels not selected by inj[I_CH] pass unchanged.
    """
    mode = int(inj[I_MODE])
    ch = int(inj[I_CH])
    n = int(inj[I_DELAY_N])
    if k == 0:
        for j in range(RING_MAX):
            for i in range(3):
                ring[j, i] = v_in[i]
        for i in range(3):
            ap_state[0, i] = v_in[i]
            ap_state[1, i] = v_in[i]
            ap_state[2, i] = v_in[i]
    slot = k % RING_MAX
    for i in range(3):
        ring[slot, i] = v_in[i]
    for i in range(3):
        x = v_in[i]
        y = x
        if ch == ALL or ch == i:
            if mode == 1:
                y = inj[I_GAIN] * x
            elif mode == 2:
                y = ring[(k - n) % RING_MAX, i] if n > 0 else x
            elif mode == 3:
                c = 2.0 / dt_s
                a = inj[I_AP_A]
                # (a - s)/(a + s), s = c (z - 1)/(z + 1):
                # y_k = ((a - c) x_k + (a + c) x_{k-1} - (a - c) y_{k-1}) / (a + c)
                y = ((a - c) * x + (a + c) * ap_state[0, i] - (a - c) * ap_state[1, i]) / (a + c)
            elif mode == 4 and t_s >= inj[I_T_ON]:
                y = x + inj[I_AMP] * math.sin(inj[I_OMEGA] * (t_s - inj[I_T_ON]))
            elif mode == 5:
                ref = ap_state[2, i] + (1.0 - math.exp(-inj[I_LP_W] * dt_s)) * (x - ap_state[2, i])
                ap_state[2, i] = ref
                y = ref + inj[I_GAIN] * (x - ref)
        ap_state[0, i] = x
        ap_state[1, i] = y
        v_out[i] = y


def make_inj(mode: str = "none", channel: int | str = ALL, gain: float = 1.0,
             delay_frames: int = 0, allpass_a: float = 1.0, amp_rad: float = 0.0,
             omega_rad_s: float = 0.0, t_on_s: float = 0.0,
             lp_corner_rad_s: float = AC_CORNER_RAD_S) -> np.ndarray:
    """The injection vector (float64[INJ_N]); ``channel`` an index, a name, or "all"."""
    if isinstance(channel, str):
        channel = ALL if channel == "all" else CHANNELS.index(channel)
    if not 0 <= int(delay_frames) < RING_MAX:
        raise ValueError(f"delay_frames must be in [0, {RING_MAX}), got {delay_frames}")
    inj = np.zeros(INJ_N)
    inj[I_MODE] = MODES[mode]
    inj[I_CH] = channel
    inj[I_GAIN] = gain
    inj[I_DELAY_N] = int(delay_frames)
    inj[I_AP_A] = allpass_a
    inj[I_AMP] = amp_rad
    inj[I_OMEGA] = omega_rad_s
    inj[I_T_ON] = t_on_s
    inj[I_LP_W] = lp_corner_rad_s
    return inj


def allpass_a_for(phase_rad: float, omega_rad_s: float) -> float:
    """The all-pass corner a that lags ``phase_rad`` at ``omega_rad_s``: 2 atan(w/a) = phase."""
    if not 0.0 < phase_rad < math.pi:
        raise ValueError("the all-pass lags between 0 and 180 deg")
    return omega_rad_s / math.tan(phase_rad / 2.0)


# ------------------------------------------------------------------------ the closed loop
@njit(cache=True)
def _loop(n_frames, n_fast, n_slow, dt_fast, dt_slow, frame_dt, cmd, inj,
          px, pp, pw, n_sub, meas, row, est, par, lx, nm, st, tab, atm, grid, delta,
          ring, ap_state, v_c, v_o, d_out, rec_att, rec_rate, rec_vc, rec_vo):
    """Closed loop with the injection between the law and the actuators (truth-fed law).

    Records every frame: attitude (alpha, beta, mu) rad, rates (p, q, r) rad/s, the law's
    virtual command v_c and the perturbed v_out. Returns the frames flown (fewer if the
    attitude passed 45 deg or became NaN).
    """
    for k in range(n_frames):
        truth_kernel(px, pp, pw, meas, row)
        for i in range(L.E_N):
            est[i] = row[_TRUTH_EST0 + i]
        law_frame(k, n_slow, n_fast, dt_slow, dt_fast, est, cmd,
                  par, lx, nm, st, tab, atm, grid, delta)
        to_virtual(delta, v_c)
        inject(inj, v_c, k * frame_dt, frame_dt, k, ring, ap_state, v_o)
        from_virtual(v_o, d_out)
        for i in range(3):
            rec_att[k, i] = row[_TRUTH_EST0 + i]
            rec_rate[k, i] = row[_TRUTH_EST0 + 3 + i]
            rec_vc[k, i] = v_c[i]
            rec_vo[k, i] = v_o[i]
        bad = False
        for i in range(3):
            if not (abs(row[_TRUTH_EST0 + i]) < 0.7853981633974483):
                bad = True
        if bad:
            return k + 1
        dy.advance_frame(px, d_out, pp, pw, n_sub)
    return n_frames


def margin_scenario(disturbance: bool = False, frame_hz: float = 1000.0, base: str = "paper",
                    sensor_noise: bool = True, point: tuple | None = None,
                    initial_beta_deg: float | None = None):
    """The paper's scenario at ``frame_hz`` frames, its disturbance on or off, its sensor noise
    on or off (the noise only matters over the wire, where the fc estimates from sensors);
    ``point`` = (Mach, altitude m): flown there instead, surfaces starting at the initial trim
    (tools.evidence.envelope.point_scenario); ``initial_beta_deg``: the initial sideslip instead of the
    scenario's (where the paper's 5 deg cannot be trimmed within the surfaces' limits)."""
    from plant_sim.scenario import load, parse
    if point is None:
        sc = load(base)
    else:
        from tools.evidence.envelope import point_scenario
        sc = point_scenario(float(point[0]), float(point[1]), base)
    d = copy.deepcopy(sc.data)
    d["timing"]["frame_hz"] = float(frame_hz)
    d["disturbance"]["enabled"] = bool(disturbance)
    if initial_beta_deg is not None:
        d["initial"]["beta_deg"] = float(initial_beta_deg)
    if not sensor_noise:
        for k in d["sensors"]["noise"]:
            d["sensors"]["noise"][k] = 0.0
    from plant_sim.scenario import Scenario
    edited = Scenario(name=f"{sc.name}-margins", path=sc.path, data=d, commands=list(sc.commands))
    return parse(edited.to_toml(), src=f"{sc.path} (margins)", name=edited.name)


def trim_verdict(scenario, beta_tol_deg: float = 0.01) -> dict:
    """Can the airframe hold the scenario's initial state? (issue 20: why a point has no margin)

    Moment trim (plant_sim.trim.trim_at, the plant's own aerodynamics and uncertainty, the
    surfaces within their limits) at the initial (alpha0, beta0) and at the first command's
    (alpha_c, beta_c). Where the initial state cannot be trimmed, the largest initial sideslip
    (same sign, alpha0 kept) that can, by bisection to ``beta_tol_deg``. Returns a dict:
    ``ini_ok``, ``cmd_ok`` (bool), ``ini_defl_deg`` (left elevon, right elevon, rudder at the
    best trim), ``ini_at_limit`` (surface names at their limit), ``ini_accel_left_deg_s2``
    (roll, pitch, yaw angular acceleration the best trim leaves, deg/s^2), ``beta0_max_deg``
    (None if the initial state trims) and ``text`` (one line for the reports).
    """
    from plant_sim.trim import trim_at, yaw_moment_range
    ini = scenario.data["initial"]
    a0, b0 = float(ini["alpha_deg"]), float(ini["beta_deg"])
    _, a_c, b_c, _ = scenario.commands[0]
    tr = trim_at(scenario, math.radians(a0), math.radians(b0))
    tc = trim_at(scenario, math.radians(float(a_c)), math.radians(float(b_c)))
    mp = scenario.data["vehicle"]
    inertia = np.array([float(mp["Ixx_kg_m2"]), float(mp["Iyy_kg_m2"]), float(mp["Izz_kg_m2"])])
    names = ("left elevon", "right elevon", "rudder")
    at_lim = [n for n, f in zip(names, tr.at_limit) if f]
    acc = np.degrees(tr.moment_left_N_m / inertia)
    # the most restoring yaw acceleration any deflection gives (positive: it turns the nose
    # into the wind, r of the sign that lowers |beta| through beta_dot = -r cos(alpha) + ...)
    n_lo, n_hi = yaw_moment_range(scenario, math.radians(a0), math.radians(b0))
    restoring = math.degrees((n_hi if b0 >= 0.0 else -n_lo) / inertia[2])
    out = {"ini_ok": bool(tr.trimmed), "cmd_ok": bool(tc.trimmed),
           "yaw_restoring_max_deg_s2": restoring,
           "ini_defl_deg": [float(v) for v in np.degrees(tr.deflection_rad)],
           "ini_at_limit": at_lim, "ini_accel_left_deg_s2": [float(v) for v in acc],
           "beta0_max_deg": None}
    if tr.trimmed:
        out["text"] = (f"the initial state (alpha {a0:g}, beta {b0:g} deg) trims within the "
                       f"surfaces' limits: the law, not the airframe, is the limit")
        return out
    lo, hi = 0.0, abs(b0)
    sgn = 1.0 if b0 >= 0.0 else -1.0
    while hi - lo > beta_tol_deg:
        mid = 0.5 * (lo + hi)
        if trim_at(scenario, math.radians(a0), math.radians(sgn * mid)).trimmed:
            lo = mid
        else:
            hi = mid
    out["beta0_max_deg"] = sgn * lo
    d = out["ini_defl_deg"]
    if restoring < 0.0:
        verdict = (f"the airframe is the limit: at beta {b0:g} deg no deflection within the "
                   f"limits stops the sideslip from growing (the most restoring yaw "
                   f"acceleration the surfaces give is {restoring:+.2f} deg/s^2); ")
    else:
        verdict = (f"the surfaces can still turn the sideslip back (up to {restoring:+.2f} "
                   f"deg/s^2 of yaw acceleration): not the airframe alone; ")
    out["text"] = verdict + (
                   f"the airframe cannot trim the initial state (alpha {a0:g}, beta {b0:g} deg) "
                   f"within the surfaces' limits: best trim left elevon {d[0]:+.1f}, right "
                   f"elevon {d[1]:+.1f}, rudder {d[2]:+.1f} deg ({', '.join(at_lim)} at the "
                   f"limit), leaving {acc[0]:+.2f} / {acc[1]:+.2f} / {acc[2]:+.2f} deg/s^2 "
                   f"roll / pitch / yaw; the largest initial sideslip it trims is "
                   f"{sgn * lo:+.2f} deg" + ("" if tc.trimmed else
                                            "; the commanded state cannot be trimmed either"))
    return out


def fly(scenario, inj: np.ndarray, *, coordinated: bool = True, law_overrides: dict | None = None,
        duration_s: float = 20.0, fast_hz: float = 500.0, slow_hz: float = 100.0) -> Flight:
    """Fly ``scenario`` (steps to its first command) with the injection ``inj``."""
    from fc.control.law import AttitudeLaw
    from plant_sim.sim import PlantSim
    ov = dict(law_overrides or {})
    ov["CO_ENABLE"] = 1.0 if coordinated else 0.0
    ov["REF_PF_EN"] = 0.0
    law = AttitudeLaw(ov)
    sim = PlantSim(scenario)
    fdt = sim.frame_dt_s
    n_fast = int(round(1.0 / (fast_hz * fdt)))
    n_slow = int(round(1.0 / (slow_hz * fdt)))
    if abs(n_fast * fast_hz * fdt - 1) > 1e-9 or abs(n_slow * slow_hz * fdt - 1) > 1e-9:
        raise ValueError("fast_hz and slow_hz must divide the frame rate")
    n = int(round(duration_s / fdt)) + 1
    x, p, w, n_sub, *_ = sim.kernel_args()
    k = law.kernel_args()
    cmd = np.radians(np.array(scenario.commands[0][1:4], dtype=np.float64))
    rec = [np.zeros((n, 3)) for _ in range(4)]
    args = (n_fast, n_slow, n_fast * fdt, n_slow * fdt, fdt, cmd, np.asarray(inj, np.float64),
            x, p, w, n_sub, np.zeros(64), np.zeros(TRUTH_N), np.zeros(L.E_N),
            k["par"], k["x"], k["nm"], k["st"], k["tab"], k["atm"], k["grid"], k["delta"],
            np.zeros((RING_MAX, 3)), np.zeros((3, 3)), np.zeros(3), np.zeros(3), np.zeros(3),
            *rec)
    flown = _loop(n, *args)
    m = flown
    return Flight(np.arange(m) * fdt, rec[0][:m], rec[1][:m], rec[2][:m], rec[3][:m], cmd,
                  bool(flown < n), fdt)


# ------------------------------------------------------------------------ verdicts and finders
def bisect_boundary(is_stable, good: float, bad: float, tol: float, max_iter: int = 40):
    """The boundary between a stable value ``good`` and an unstable ``bad`` of a scalar
    perturbation, to within ``tol``: (last stable, first unstable). ``is_stable(v) -> bool``."""
    if not is_stable(good):
        raise ValueError(f"the loop is not stable at the nominal value {good}")
    if is_stable(bad):
        return bad, math.inf if bad > good else -math.inf
    return _bisect(is_stable, good, bad, tol, max_iter)


def _bisect(is_stable, good, bad, tol, max_iter):
    for _ in range(max_iter):
        if abs(bad - good) <= tol:
            break
        mid = 0.5 * (good + bad)
        if is_stable(mid):
            good = mid
        else:
            bad = mid
    return good, bad


def scan_boundary(is_stable, values, tol: float, max_iter: int = 20):
    """Walk ``values`` (from the nominal outwards) to the first unstable one, then bisect
    between it and the last stable one: (last stable, first unstable); (last value, inf) if
    none is unstable. A scan first, because the nonlinear loop need not be monotonic in the
    perturbation (a bisection alone could land on a stable island past an unstable value)."""
    values = list(values)
    if not is_stable(values[0]):
        raise ValueError(f"the loop is not stable at the nominal value {values[0]}")
    for good, bad in zip(values[:-1], values[1:]):
        if not is_stable(bad):
            return _bisect(is_stable, good, bad, tol, max_iter)
    return values[-1], (math.inf if values[-1] > values[0] else -math.inf)


def loop_transfer(t_s: np.ndarray, v_c: np.ndarray, v_out: np.ndarray, omega_rad_s: float,
                  t_from_s: float, n_periods: int | None = None) -> complex:
    """Broken-loop transfer L(jw) = -V_c(jw) / V_out(jw) at the break point, from the
    Fourier projection of the recorded signals over whole periods from ``t_from_s``."""
    period = 2.0 * math.pi / omega_rad_s
    if n_periods is None:
        n_periods = int((t_s[-1] - t_from_s) // period)
    if n_periods < 1:
        raise ValueError("fewer than one whole period recorded after t_from_s")
    m = (t_s >= t_from_s) & (t_s < t_from_s + n_periods * period)
    ph = np.exp(-1j * omega_rad_s * t_s[m])
    yc = np.sum((v_c[m] - v_c[m].mean()) * ph)
    yo = np.sum((v_out[m] - v_out[m].mean()) * ph)
    return complex(-yc / yo)


def crossings(omegas: np.ndarray, lvals: np.ndarray) -> dict:
    """Crossover and margins from a sweep L(jw_i), sorted by w (log-interpolated).

    Returns {"omega_c": the highest gain crossover |L| = 1 (rad/s), "pm_deg": 180 + phase
    there (phase taken in (-360, 0]), "omega_180" / "gm_db": the phase crossing of -180 deg
    (mod 360) above the crossover with the smallest |L| and -20 log10 |L| there (the upper gain
    margin), "omega_180_low" / "gm_low_db": the crossing below it with the smallest |L| > 1
    (a gain *reduction* margin, negative dB: the loop is conditionally stable)}; None where the
    sweep does not cross.
    """
    w = np.asarray(omegas, float)
    lv = np.asarray(lvals, complex)
    lm = np.log(np.abs(lv))
    ph = np.angle(lv)                       # (-pi, pi]; -180 crossings are +-pi wraps
    lw = np.log(w)
    out = {"omega_c": None, "pm_deg": None, "omega_180": None, "gm_db": None,
           "omega_180_low": None, "gm_low_db": None}
    for i in range(len(w) - 1):
        if lm[i] >= 0.0 > lm[i + 1]:
            f = lm[i] / (lm[i] - lm[i + 1])
            out["omega_c"] = math.exp(lw[i] + f * (lw[i + 1] - lw[i]))
            d = (ph[i + 1] - ph[i] + math.pi) % (2 * math.pi) - math.pi
            phc = ph[i] + f * d
            out["pm_deg"] = 180.0 + math.degrees((phc + 2 * math.pi) % (2 * math.pi) - 2 * math.pi)
    for i in range(len(w) - 1):
        # phase measured from -180 deg, wrapped to (-pi, pi]: a sign change without a jump
        a = (ph[i] + 2 * math.pi) % (2 * math.pi) - math.pi
        b = (ph[i + 1] + 2 * math.pi) % (2 * math.pi) - math.pi
        if a * b > 0 or abs(a - b) > math.pi or a == b:
            continue
        f = a / (a - b)
        om = math.exp(lw[i] + f * (lw[i + 1] - lw[i]))
        gm = -20.0 * (lm[i] + f * (lm[i + 1] - lm[i])) / math.log(10.0)
        if gm > 0 and (out["gm_db"] is None or gm < out["gm_db"]):
            out["omega_180"], out["gm_db"] = om, gm
        if gm < 0 and (out["gm_low_db"] is None or gm > out["gm_low_db"]):
            out["omega_180_low"], out["gm_low_db"] = om, gm
    return out


# ------------------------------------------------------------------------ the campaign
def sweep(scenario, channel: str, omegas, *, coordinated=True, law_overrides=None,
          amp_deg: float = 0.3, t_on_s: float = 8.0, settle_periods: int = 2,
          min_record_s: float = 6.0) -> list[complex]:
    """L(jw) of ``channel`` at each w: one flight per frequency, a sine of ``amp_deg`` added
    from ``t_on_s`` (after the step transient), measured after ``settle_periods``."""
    out = []
    for w in omegas:
        period = 2 * math.pi / w
        n_per = max(3, int(math.ceil(min_record_s / period)))
        t_from = t_on_s + settle_periods * period
        dur = t_from + n_per * period + 0.01
        fl = fly(scenario, make_inj("sine", channel, amp_rad=math.radians(amp_deg),
                                    omega_rad_s=w, t_on_s=t_on_s),
                 coordinated=coordinated, law_overrides=law_overrides, duration_s=dur)
        if fl.diverged:
            out.append(complex(math.nan, math.nan))
            continue
        i = CHANNELS.index(channel)
        out.append(loop_transfer(fl.t_s, fl.v_c_rad[:, i], fl.v_out_rad[:, i], w, t_from, n_per))
    return out


#: The margins one run can measure (``--only``): the sweep (crossover, PM, GM), the all-pass
#: phase margin (needs the crossover: a sweep runs first), the gain about trim (gain_ac) and of
#: the whole command (gain), up and down, the delay in each channel and in all three.
MARGINS = ("sweep", "pm_allpass", "gain_ac", "gain", "delay", "delay_all")
#: the sweep of the crossover when only the all-pass phase margin needs it (fewer frequencies)
QUICK_OMEGAS = np.geomspace(1.0, 40.0, 12)


def channel_margins(scenario, channel: str, *, coordinated=True, law_overrides=None,
                    omegas=None, duration_s: float = 20.0, which=MARGINS) -> dict:
    """The margins of one channel named in ``which`` (MARGINS): sweep (crossover, PM, GM),
    gain scans up and down (about trim and whole command), all-pass phase margin at the
    crossover. Entries not measured are None."""
    if omegas is None:
        omegas = np.geomspace(0.5, 60.0, 18) if "sweep" in which else QUICK_OMEGAS
    omegas = np.asarray(omegas)
    kw = dict(coordinated=coordinated, law_overrides=law_overrides)
    cr = {"omega_c": None, "pm_deg": None, "omega_180": None, "gm_db": None,
          "omega_180_low": None, "gm_low_db": None}
    lv = []
    if "sweep" in which or "pm_allpass" in which:
        lv = sweep(scenario, channel, omegas, **kw)
        ok = np.isfinite(np.abs(lv))
        cr = crossings(omegas[ok], np.asarray(lv)[ok])

    def st_gain(mode):
        return lambda k: stable(fly(scenario, make_inj(mode, channel, gain=k),
                                    duration_s=duration_s, **kw))
    up = np.geomspace(1.0, 16.0, 13)
    down = np.geomspace(1.0, 1.0 / 16.0, 13)
    gains = {f"{mode}_{d}": (scan_boundary(st_gain(mode), vals, tol) if mode in which else None)
             for mode in ("gain", "gain_ac")
             for d, vals, tol in (("up", up, 0.02), ("down", down, 0.01))}
    pm_ap = None
    if cr["omega_c"] and "pm_allpass" in which:
        wc = cr["omega_c"]

        def st_phase(phi_deg):
            if phi_deg <= 0.0:
                return stable(fly(scenario, make_inj(), duration_s=duration_s, **kw))
            a = allpass_a_for(math.radians(phi_deg), wc)
            return stable(fly(scenario, make_inj("allpass", channel, allpass_a=a),
                              duration_s=duration_s, **kw))
        pm_ap = scan_boundary(st_phase, np.arange(0.0, 180.0, 10.0), 1.0)
    return {"channel": channel, "coordinated": coordinated, "sweep_omega": list(map(float, omegas)),
            "sweep_L": [[float(z.real), float(z.imag)] for z in lv], **cr,
            **gains, "pm_allpass_deg": pm_ap}


def delay_margin(scenario, *, coordinated=True, law_overrides=None, channel="all",
                 duration_s: float = 20.0, max_frames: int = 400) -> tuple[int, int]:
    """(largest stable delay, smallest unstable delay) in frames, delay in ``channel``."""
    def st(nf):
        return stable(fly(scenario, make_inj("delay", channel, delay_frames=int(round(nf))),
                          coordinated=coordinated, law_overrides=law_overrides,
                          duration_s=duration_s))
    good, bad = scan_boundary(st, np.arange(0, max_frames + 1, 5), 1.0)
    return int(round(good)), (None if math.isinf(bad) else int(round(bad)))


def _db(k):
    return None if k is None or not math.isfinite(k) or k <= 0 else 20.0 * math.log10(k)


def _bound(b, fmt=".2f", db=False):
    """'last stable / first unstable' of a boundary pair; dB of the last stable if ``db``;
    '-' if not measured (None)."""
    if b is None:
        return "-"
    good, bad = b
    txt = f"{good:{fmt}} / {'none' if not math.isfinite(bad) else format(bad, fmt)}"
    if db:
        d = _db(good)
        txt += f" ({'-' if d is None else format(d, '+.1f')} dB)"
    return txt


def margins_table(results: list[dict], delays: dict, frame_dt_s: float) -> str:
    """Markdown table of :func:`channel_margins` results and the per-channel delay margins."""
    def f(v, fmt):
        return "-" if v is None else format(v, fmt)
    rows = ["| variant | channel | crossover rad/s | PM sweep deg | PM all-pass deg (stable / not) | "
            "GM sweep dB (w180 rad/s) | low GM sweep dB | gain up, about trim (gain_ac) | "
            "gain up, whole command | gain down, about trim | gain down, whole | "
            "delay margin ms (this channel) |", "|" + "---|" * 12]
    for r in results:
        var = "co" if r["coordinated"] else "unco"
        pa = r["pm_allpass_deg"]
        dly = delays.get((var, r["channel"]))
        rows.append(
            f"| {var} | {r['channel']} | {f(r['omega_c'], '.2f')} | {f(r['pm_deg'], '.0f')} | "
            f"{'-' if pa is None else _bound(pa, '.0f')} | "
            f"{f(r['gm_db'], '.1f')} ({f(r['omega_180'], '.1f')}) | {f(r['gm_low_db'], '.1f')} | "
            f"{_bound(r['gain_ac_up'], db=True)} | {_bound(r['gain_up'], db=True)} | "
            f"{_bound(r['gain_ac_down'], db=True)} | {_bound(r['gain_down'], db=True)} | "
            f"{'-' if dly is None else _bound((dly[0] * frame_dt_s * 1e3, math.inf if dly[1] is None else dly[1] * frame_dt_s * 1e3), '.0f')} |")
    return "\n".join(rows)


#: the issue-20 targets the summary checks: all-pass PM (deg), gain about trim up and down (dB),
#: all-channel delay (s)
TARGET_PM_DEG = 45.0
TARGET_GM_DB = 6.0
TARGET_DM_S = 0.050


def grid_table(dirs) -> str:
    """Markdown summary of several runs' margins.json (one row per point, variant and
    channel): all-pass phase margin, gain about trim up / down, all-channel delay, and whether
    each meets the issue-20 targets. A variant whose unperturbed loop was not stable reads 0."""
    from plant_sim.atmosphere import A_N, A_RHO_KG_M3, A_SOUND_M_S, us76
    rows = ["| point | qbar kPa | variant | channel | PM all-pass deg | gain up about trim dB | "
            "gain down about trim dB | delay all channels ms | targets met |",
            "|" + "---|" * 9]
    for d in dirs:
        j = json.loads((Path(d) / "margins.json").read_text())
        pt = j.get("point") or "7.44,21"
        m, h = (float(x) for x in pt.split(","))
        atm = np.zeros(A_N)
        us76(h * 1e3, atm)
        q_kpa = 0.5 * atm[A_RHO_KG_M3] * (m * atm[A_SOUND_M_S]) ** 2 / 1e3
        label = pt + ("" if j.get("initial_beta_deg") is None
                      else f" (beta0 {j['initial_beta_deg']:g} deg)")
        if j.get("overrides"):
            label += " " + " ".join(f"{k}={v:g}" for k, v in j["overrides"].items())
        fdt = j["frame_dt_s"]
        by_var = {}
        for r in j["results"]:
            by_var.setdefault("co" if r["coordinated"] else "unco", []).append(r)
        for var in ("co", "unco"):
            dl = j["delays"].get(f"{var}/all")
            if dl is None:
                continue
            dm_s = dl[0] * fdt
            if var not in by_var:
                why = (j.get("trim") or {}).get("text")
                rows.append(f"| {label} | {q_kpa:.0f} | {var} | all | - | - | - | 0 | no: the "
                            "unperturbed loop is not stable" + (f" ({why})" if why else "")
                            + " |")
                continue
            for r in by_var[var]:
                pm = r["pm_allpass_deg"][0] if r["pm_allpass_deg"] else None
                up = _db(r["gain_ac_up"][0]) if r["gain_ac_up"] else None
                dn = _db(r["gain_ac_down"][0]) if r["gain_ac_down"] else None
                ok = (pm is not None and pm >= TARGET_PM_DEG and up is not None
                      and up >= TARGET_GM_DB and dn is not None and -dn >= TARGET_GM_DB
                      and dm_s >= TARGET_DM_S)
                rows.append(f"| {label} | {q_kpa:.0f} | {var} | {r['channel']} | "
                            f"{'-' if pm is None else format(pm, '.0f')} | "
                            f"{'-' if up is None else format(up, '+.1f')} | "
                            f"{'-' if dn is None else format(dn, '+.1f')} | "
                            f"{dm_s * 1e3:.0f} | {'yes' if ok else 'no'} |")
    return "\n".join(rows)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m tools.evidence.margins", description=__doc__.split("\n")[0])
    sub = ap.add_subparsers(dest="cmd")
    ap.add_argument("--out", type=Path, default=Path("runs/margins"),
                    help="output directory (default runs/margins)")
    ap.add_argument("--variants", default="co,unco",
                    help="comma-separated law variants: co, unco (default both)")
    ap.add_argument("--channels", default="roll,pitch,yaw",
                    help="comma-separated channels where the loop is broken (default all three)")
    ap.add_argument("--disturbance", action="store_true", help="keep the paper's d(t) on")
    ap.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                    help="law parameter override (table units), repeatable (e.g. CO_FAC_EQ=19)")
    ap.add_argument("--point", default=None, metavar="MACH,H_KM",
                    help="fly the paper's case at this flight condition (default: the paper's)")
    ap.add_argument("--initial-beta", type=float, default=None, metavar="DEG",
                    help="initial sideslip instead of the paper's 5 deg (a point where that "
                         "cannot be trimmed)")
    ap.add_argument("--only", default=",".join(MARGINS),
                    help="comma-separated margins to measure, of " + ", ".join(MARGINS)
                         + " (default all; issue 20's three: pm_allpass,gain_ac,delay_all)")
    w = sub.add_parser("wire", help="time-delay margin over the wire (two processes, lockstep "
                                    "frames, or wall-clock ms in real time)")
    w.add_argument("--frames", default="0,5,10,15,20,25",
                   help="extra delays to fly, frames (1 ms each)")
    w.add_argument("--out", type=Path, default=Path("runs/margins_wire"),
                   help="output directory (default runs/margins_wire)")
    w.add_argument("--variant", default="coordinated", choices=("coordinated", "uncoordinated"),
                   help="the fc's flight mode (default coordinated)")
    w.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                   help="a law parameter for the fc (repeatable)")
    w.add_argument("--disturbance", action="store_true",
                   help="keep the scenario's disturbance on (default off, as in process)")
    w.add_argument("--noise", action="store_true", help="keep the sensors' noise on")
    w.add_argument("--realtime-ms", default=None, metavar="MS,MS,...",
                   help="fly in real time instead, the relay holding each servo datagram "
                        "this many wall-clock ms (one flight per value; --frames ignored)")
    t = sub.add_parser("table", help="summarise runs' margins.json against issue 20's targets")
    t.add_argument("dirs", nargs="+", type=Path, help="run directories (--out of earlier runs)")
    a = ap.parse_args(argv)
    if a.cmd == "table":
        print(grid_table(a.dirs))
        return 0
    from fc.control.params import parse_sets
    try:
        ov = parse_sets(a.set)
    except ValueError as exc:
        ap.error(f"--set: {exc}")
    a.out.mkdir(parents=True, exist_ok=True)
    if a.cmd == "wire":
        sc = margin_scenario(disturbance=a.disturbance, sensor_noise=a.noise)
        from tools.evidence.margins.wire import wire_delay_runs
        if a.realtime_ms is not None:
            return wire_delay_runs(sc, [float(x) for x in a.realtime_ms.split(",")], a.out,
                                   a.variant, ov, realtime=True)
        return wire_delay_runs(sc, [int(x) for x in a.frames.split(",")], a.out, a.variant, ov)
    point = None
    if a.point:
        m, h = (float(x) for x in a.point.split(","))
        point = (m, h * 1e3)
    sc = margin_scenario(disturbance=a.disturbance, point=point, initial_beta_deg=a.initial_beta)
    which = tuple(x.strip() for x in a.only.split(",") if x.strip())
    unknown = set(which) - set(MARGINS)
    if unknown:
        ap.error(f"--only: unknown margins {sorted(unknown)} (of {', '.join(MARGINS)})")
    t0 = time.perf_counter()
    results, delays = [], {}
    trim = None                 # trim_verdict, computed where the unperturbed loop fails
    for var in a.variants.split(","):
        co = var == "co"
        if not stable(fly(sc, make_inj(), coordinated=co, law_overrides=ov)):
            if trim is None:
                trim = trim_verdict(sc)
            print(f"{var}: the unperturbed loop is not stable at this point: no margin; "
                  f"{trim['text']}", flush=True)
            delays[(var, "all")] = (0, 0)
            continue
        for ch in a.channels.split(","):
            r = channel_margins(sc, ch, coordinated=co, law_overrides=ov, which=which)
            results.append(r)
            if "delay" in which:
                delays[(var, ch)] = delay_margin(sc, coordinated=co, law_overrides=ov,
                                                 channel=ch)
            brief = {k: r[k] for k in ("omega_c", "pm_deg", "gm_db", "gm_low_db", "gain_up",
                                       "gain_ac_up", "gain_down", "gain_ac_down",
                                       "pm_allpass_deg")}
            print(f"{var} {ch}: {json.dumps(brief)} delay {delays.get((var, ch))} frames "
                  f"({time.perf_counter() - t0:.0f} s)", flush=True)
        if "delay_all" in which:
            delays[(var, "all")] = delay_margin(sc, coordinated=co, law_overrides=ov,
                                                channel="all")
            print(f"{var} all-channel delay margin {delays[(var, 'all')]} frames", flush=True)
    fdt = 1.0 / sc.data["timing"]["frame_hz"]
    table = margins_table(results, delays, fdt)
    all_rows = []
    for v in a.variants.split(","):
        if (v, "all") not in delays:
            continue
        good, bad = delays[(v, "all")]
        all_rows.append(f"| {v} | all three | {good * fdt * 1e3:.0f} ms stable, "
                        f"{'-' if bad is None else format(bad * fdt * 1e3, '.0f')} ms not |")
    text = (table + "\n\n| variant | delayed channels | time-delay margin |\n|---|---|---|\n"
            + "\n".join(all_rows) + "\n")
    (a.out / "margins.md").write_text(text)
    (a.out / "margins.json").write_text(json.dumps(
        {"results": results, "delays": {f"{k[0]}/{k[1]}": v for k, v in delays.items()},
         "frame_dt_s": fdt, "overrides": ov, "disturbance": a.disturbance,
         "point": a.point, "only": list(which), "initial_beta_deg": a.initial_beta,
         "trim": trim,
         "wall_s": time.perf_counter() - t0}, indent=1))
    print(text)
    print(f"wall {time.perf_counter() - t0:.0f} s")
    return 0

