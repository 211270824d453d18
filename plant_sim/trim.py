"""Moment trim: surface deflections that zero the aerodynamic moments about the c.g.

At a given alpha and beta (rates zero, the scenario's V, h, mass properties, x_cg and
uncertainty multipliers; mu does not enter the moments), solve
    l(dL, dR, dU) = m(dL, dR, dU) = n(dL, dR, dU) = 0,  |d| <= limit
by bounded least squares on the moments scaled by qbar S (b, c, b). If no deflection within
the limits balances them, the result is the best achievable point and the moment left over.
The disturbance d(t) is time-varying and is not part of the trim.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from plant_sim import dynamics as dy
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


def trim_at(sc: Scenario, alpha_rad: float, beta_rad: float) -> TrimResult:
    """Trim deflections at (alpha, beta) with the scenario's flight condition and vehicle."""
    from plant_sim.sim import build_params
    p, _ = build_params(sc)
    ini = sc.data["initial"]
    x = np.zeros(dy.X_N)
    dy.initial_state(ini["V_m_s"], ini["h_m"], alpha_rad, beta_rad, 0.0, 0.0, 0.0,
                     0.0, 0.0, 0.0, x)
    w = np.zeros(dy.W_N)
    lim = p[dy.P_ACT_LIMIT]

    def moments(d):
        dy.aero_eval(x, d[0], d[1], d[2], p, w)
        o = dy.W_AUX
        return np.array([w[o + dy.AX_L], w[o + dy.AX_M], w[o + dy.AX_N]])

    moments(np.zeros(3))
    qs = w[dy.W_AUX + dy.AX_QBAR] * S_REF_M2
    scale = np.array([qs * B_REF_M, qs * C_REF_M, qs * B_REF_M])
    m0 = moments(np.zeros(3))

    best = None
    for start in (np.zeros(3), np.array([0.5, 0.5, 0.0]) * lim, np.array([-0.5, -0.5, 0.0]) * lim):
        r = least_squares(lambda d: moments(d) / scale, start, bounds=(-lim, lim),
                          xtol=1e-14, ftol=1e-14, gtol=1e-14, method="trf")
        if best is None or r.cost < best.cost:
            best = r
    d = np.clip(best.x, -lim, lim)
    left = moments(d)
    trimmed = bool(np.all(np.abs(left / scale) < TRIM_TOL_COEF))
    at_limit = tuple(bool(abs(v) >= lim * (1 - 1e-6)) for v in d)
    return TrimResult(alpha_rad, beta_rad, d, left, m0, trimmed, at_limit)


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
