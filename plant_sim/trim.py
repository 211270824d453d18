"""Moment trim: surface deflections that zero the aerodynamic moments about the c.g.

At a given alpha and beta (rates zero, the scenario's V, h, mass properties, x_cg and
uncertainty multipliers; mu does not enter the moments), solve
    l(dL, dR, dU) = m(dL, dR, dU) = n(dL, dR, dU) = 0,  |d| <= limit
by bounded least squares on the moments scaled by qbar S (b, c, b): Gauss-Newton steps whose
linearised bounded problem is solved exactly by enumerating the 27 free/lower/upper patterns of
the three surfaces (the moments are close to linear in the deflections, so this converges in a
few steps; no scipy import, which would cost a second of every plant start). If no deflection
within the limits balances them, the result is the best achievable point and the moment left.
The disturbance d(t) is time-varying and is not part of the trim.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import itertools

import numpy as np

from plant_sim import dynamics as dy
from plant_sim.params import build_params
from plant_sim.scenario import Scenario
from plant_sim.vehicle import B_REF_M, C_REF_M, S_REF_M2

DEG = math.pi / 180.0
TRIM_TOL_COEF = 1e-7     # residual moment coefficient regarded as trimmed


@dataclass
class TrimResult:
    alpha_rad: float
    beta_rad: float
    deflection_rad: np.ndarray        # left elevon, right elevon, rudder
    moment_left_N_m: np.ndarray       # l, m, n about the c.g. at that deflection
    moment_zero_defl_N_m: np.ndarray  # l, m, n with all surfaces at zero
    trimmed: bool
    at_limit: tuple                   # per surface: True if at the position limit

    def describe(self, label: str) -> str:
        d = np.degrees(self.deflection_rad)
        m = self.moment_left_N_m
        state = "trimmed" if self.trimmed else "NOT trimmable within the limits"
        lim = ", ".join(n for n, f in zip(("left", "right", "rudder"), self.at_limit) if f)
        return (f"{label}: alpha {math.degrees(self.alpha_rad):.2f} deg, beta "
                f"{math.degrees(self.beta_rad):.2f} deg: {state}\n"
                f"  deflection (deg): left elevon {d[0]:+.3f}, right elevon {d[1]:+.3f}, "
                f"rudder {d[2]:+.3f}" + (f"  [at limit: {lim}]" if lim else "") + "\n"
                f"  moment left (N m): l {m[0]:+.4g}, m {m[1]:+.4g}, n {m[2]:+.4g}\n"
                f"  moment at zero deflection (N m): l {self.moment_zero_defl_N_m[0]:+.4g}, "
                f"m {self.moment_zero_defl_N_m[1]:+.4g}, n {self.moment_zero_defl_N_m[2]:+.4g}")


def _state_at(sc: Scenario, alpha_rad: float, beta_rad: float):
    """(params, state, work array, surface limit rad) at the scenario's V and h, rates zero."""
    p, _ = build_params(sc)
    ini = sc.data["initial"]
    x = np.zeros(dy.X_N)
    dy.initial_state(ini["V_m_s"], ini["h_m"], alpha_rad, beta_rad, 0.0, 0.0, 0.0,
                     0.0, 0.0, 0.0, x)
    return p, x, np.zeros(dy.W_N), p[dy.P_ACT_LIMIT]


def trim_at(sc: Scenario, alpha_rad: float, beta_rad: float) -> TrimResult:
    """Trim deflections at (alpha, beta) with the scenario's flight condition and vehicle."""
    p, x, w, lim = _state_at(sc, alpha_rad, beta_rad)

    def moments(d):
        dy.aero_eval(x, d[0], d[1], d[2], p, w)
        o = dy.W_AUX
        return np.array([w[o + dy.AX_L], w[o + dy.AX_M], w[o + dy.AX_N]])

    moments(np.zeros(3))
    qs = w[dy.W_AUX + dy.AX_QBAR] * S_REF_M2
    scale = np.array([qs * B_REF_M, qs * C_REF_M, qs * B_REF_M])
    m0 = moments(np.zeros(3))

    d = _bounded_gauss_newton(lambda dd: moments(dd) / scale, lim)
    left = moments(d)
    trimmed = bool(np.all(np.abs(left / scale) < TRIM_TOL_COEF))
    at_limit = tuple(bool(abs(v) >= lim * (1 - 1e-6)) for v in d)
    return TrimResult(alpha_rad, beta_rad, d, left, m0, trimmed, at_limit)


def yaw_moment_range(sc: Scenario, alpha_rad: float, beta_rad: float,
                     n_per_surface: int = 9) -> tuple[float, float]:
    """(smallest, largest) yaw moment about the c.g. (N m) that the three surfaces can give at
    (alpha, beta) within their limits (rates zero, the scenario's flight condition), over a
    grid of ``n_per_surface`` deflections per surface (the limits included): whether any
    deflection at all can stop a sideslip from growing, whatever the roll and pitch need."""
    p, x, w, lim = _state_at(sc, alpha_rad, beta_rad)
    vals = np.linspace(-lim, lim, int(n_per_surface))
    lo, hi = math.inf, -math.inf
    for d in itertools.product(vals, vals, vals):
        dy.aero_eval(x, d[0], d[1], d[2], p, w)
        n = float(w[dy.W_AUX + dy.AX_N])
        lo, hi = min(lo, n), max(hi, n)
    return lo, hi


_PATTERNS = tuple(itertools.product((0, -1, 1), repeat=3))   # free, at -limit, at +limit


def _bounded_linear_ls(r0: np.ndarray, jac: np.ndarray, d0: np.ndarray, lim: float) -> np.ndarray:
    """argmin |r0 + J (d - d0)| over |d_i| <= lim (exact, by active-set enumeration)."""
    best_d, best_cost = d0.copy(), float(r0 @ r0)
    for pat in _PATTERNS:
        d = np.empty(3)
        fixed = [i for i in range(3) if pat[i] != 0]
        free = [i for i in range(3) if pat[i] == 0]
        for i in fixed:
            d[i] = pat[i] * lim
        rhs = r0 - jac @ d0
        if fixed:
            rhs = rhs + jac[:, fixed] @ d[fixed]
        if free:
            sol, *_ = np.linalg.lstsq(jac[:, free], -rhs, rcond=None)
            if np.any(np.abs(sol) > lim * (1 + 1e-12)):
                continue
            d[free] = sol
        res = r0 + jac @ (d - d0)
        cost = float(res @ res)
        if cost < best_cost - 1e-30:
            best_d, best_cost = d, cost
    return best_d


def _bounded_gauss_newton(resid, lim: float, iters: int = 30) -> np.ndarray:
    """Bounded nonlinear least squares of a 3-vector residual in 3 deflections (rad)."""
    d = np.zeros(3)
    h = 1e-5                                  # rad; the fits are smooth polynomials in deg
    cost = float(resid(d) @ resid(d))
    for _ in range(iters):
        r0 = resid(d)
        jac = np.empty((3, 3))
        for j in range(3):
            e = np.zeros(3)
            e[j] = h
            jac[:, j] = (resid(np.clip(d + e, -lim, lim)) - resid(np.clip(d - e, -lim, lim))) / (
                np.clip(d[j] + h, -lim, lim) - np.clip(d[j] - h, -lim, lim))
        cand = _bounded_linear_ls(r0, jac, d, lim)
        step = cand - d
        # backtrack if the nonlinear cost does not fall
        for _ in range(20):
            c = float(resid(d + step) @ resid(d + step))
            if c <= cost:
                break
            step *= 0.5
        else:
            break
        d = np.clip(d + step, -lim, lim)
        done = np.max(np.abs(step)) < 1e-12 or abs(cost - c) <= 1e-30
        cost = c
        if done:
            break
    return d


def trim_report(sc: Scenario) -> tuple[str, bool]:
    """Trim at the initial state and at each distinct commanded (alpha, beta).

    Returns the report text and whether every point is trimmable within the limits.
    """
    ini = sc.data["initial"]
    lines = [f"scenario {sc.name} ({sc.path}): V {ini['V_m_s']} m/s, h {ini['h_m']} m, "
             f"x_cg {sc.data['vehicle']['x_cg_m']} m, limit +-{sc.data['actuators']['limit_deg']} deg; "
             f"uncertainty multipliers applied, disturbance not included"]
    ok = True
    r = trim_at(sc, ini["alpha_deg"] * DEG, ini["beta_deg"] * DEG)
    ok &= r.trimmed
    lines.append(r.describe("initial state"))
    seen = set()
    for t, a, b, m in sc.commands:
        if (a, b) in seen:
            continue
        seen.add((a, b))
        r = trim_at(sc, a * DEG, b * DEG)
        ok &= r.trimmed
        lines.append(r.describe(f"command at t = {t} s (mu {m} deg)"))
    return "\n".join(lines), ok
