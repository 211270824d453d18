"""The guidance (outer) loop's parameter table: gains, limits and the engine model, with units.

``GUIDANCE_PARAMS`` is in the style of the law's ``LAW_PARAMS`` (fc/control/params.py): one
``Param`` record per entry (name <= 16 characters, default, min, max, human unit, group,
description, SI scale). The fc can append it to its table (fc/params.py) without change; the
order is stable (append new entries at the end, never reuse a slot). ``to_si`` and
``default_si_array`` give the SI array the kernels read, indexed by the ``P_*`` constants.

Groups: GA_ altitude / flight-path angle, GH_ heading, GS_ speed / throttle, GE_ envelope
protection, GM_ the guidance's model of the engine. See docs/guidance.md.
"""
from __future__ import annotations

import math

import numpy as np

from fc.control.params import Param, _p, checked_value

DEG = math.pi / 180.0


GUIDANCE_PARAMS: tuple[Param, ...] = (
    _p("GA_K_H", 0.05, 0, 2, "1/s", "GA",
       "Altitude loop gain: climb-rate demand hdot_c = GA_K_H (h_t - h) + GA_K_HI int(h_t - h) dt."),
    _p("GA_K_HI", 0.0005, 0, 0.1, "1/s^2", "GA",
       "Altitude-error integral gain (anti-windup: frozen while a limit blocks the climb-rate "
       "demand in the error's direction, and clamped to +-GA_HI_MAX)."),
    _p("GA_HDOT_MAX", 120, 1, 1000, "m/s", "GA",
       "Limit of the climb-rate demand hdot_c; gamma_c = asin(hdot_c / V) before the envelope."),
    _p("GA_K_GAM", 0.4, 0, 5, "1/s", "GA",
       "Flight-path loop gain: gamma_dot_des = gamma_c_dot + GA_K_GAM (gamma_c - gamma)."),
    _p("GH_K_CHI", 0.05, 0, 2, "1/s", "GH",
       "Course loop gain: chi_dot_c = GH_K_CHI wrap(chi_t - chi); mu_c = atan(V chi_dot_c cos(gamma) / g)."),
    _p("GH_CHIDOT_MAX", 1.0, 0.01, 20, "deg/s", "GH",
       "Limit of the turn-rate demand chi_dot_c (the bank limit GE_MU_MAX usually binds first at "
       "hypersonic speed).", si_scale=DEG),
    _p("GS_K_V", 0.1, 0, 5, "1/s", "GS",
       "Speed loop gain: acceleration demand a_c = V_ref_dot + GS_K_V (V_ref - V) + GS_K_VI int(V_ref - V) dt."),
    _p("GS_K_VI", 0.005, 0, 1, "1/s^2", "GS",
       "Speed-error integral gain (anti-windup: frozen while the throttle is at a limit in the "
       "error's direction, clamped to +-GS_VI_MAX)."),
    _p("GS_ACC_MAX", 1.5, 0.01, 20, "m/s^2", "GS",
       "Rate limit of the speed reference V_ref toward the speed target (the commanded acceleration)."),
    _p("GE_ALPHA_MIN", 0, -5, 12, "deg", "GE",
       "Lowest alpha command (the aerodynamic data start at 0 deg).", si_scale=DEG),
    _p("GE_ALPHA_MAX", 10, 0, 12, "deg", "GE",
       "Highest alpha command (the aerodynamic data end at 12 deg).", si_scale=DEG),
    _p("GE_ALPHA_RATE", 1.0, 0.01, 20, "deg/s", "GE", "Rate limit of the alpha command.",
       si_scale=DEG),
    _p("GE_GAM_MAX", 3.0, 0.1, 30, "deg", "GE",
       "Limit of the flight-path angle command gamma_c (+-).", si_scale=DEG),
    _p("GE_GAM_RATE", 0.3, 0.01, 10, "deg/s", "GE", "Rate limit of the flight-path angle command.",
       si_scale=DEG),
    _p("GE_MU_MAX", 30, 0, 80, "deg", "GE",
       "Limit of the bank command |mu_c| (also bounded by the load factor: 1/cos(mu) <= GE_NZ_MAX).",
       si_scale=DEG),
    _p("GE_MU_RATE", 3.0, 0.01, 60, "deg/s", "GE", "Rate limit of the bank command.", si_scale=DEG),
    _p("GE_NZ_MIN", 0.3, -2, 1, "1", "GE",
       "Lowest load factor n = L / (m g) the flight-path loop may ask for (the demand "
       "(g cos(gamma) + V gamma_dot) / (g cos(mu)) before the model-error correction)."),
    _p("GE_NZ_MAX", 1.6, 1, 10, "1", "GE",
       "Highest load factor n = L / (m g) the flight-path loop may ask for (as GE_NZ_MIN); also "
       "bounds the bank: 1 / cos(mu) <= GE_NZ_MAX."),
    _p("GE_QBAR_MIN", 25000, 0, 1e6, "Pa", "GE",
       "Dynamic-pressure floor: within GE_QBAR_BAND above it the upper flight-path limit falls "
       "linearly to 0, below it to -GE_GAM_MAX (the vehicle descends)."),
    _p("GE_QBAR_MAX", 200000, 1000, 1e7, "Pa", "GE",
       "Dynamic-pressure ceiling: within GE_QBAR_BAND below it the lower flight-path limit rises "
       "linearly to 0, above it to +GE_GAM_MAX (the vehicle climbs)."),
    _p("GE_QBAR_BAND", 10000, 1, 1e6, "Pa", "GE",
       "Width of the dynamic-pressure protection ramps."),
    _p("GE_THR_RATE", 0.5, 0.01, 100, "1/s", "GE", "Rate limit of the throttle command (0..1 per s)."),
    _p("GM_CT_MAX", 0.02576, 0.0001, 1, "1", "GM",
       "Guidance's engine model: thrust coefficient at full throttle, T = throttle GM_CT_MAX qbar S "
       "(Wang & Stengel 2000), capped at GM_T_MAX (docs/guidance.md)."),
    _p("GM_T_MAX", 1.468e6, 1, 1e8, "N", "GM",
       "Guidance's engine model: thrust cap (330,000 lbf, the winged-cone engine deck)."),
    _p("GA_HI_MAX", 30, 0, 1000, "m/s", "GA",
       "Clamp of the altitude integral's contribution GA_K_HI int(h_t - h) dt to the climb-rate demand."),
    _p("GS_VI_MAX", 2.0, 0, 100, "m/s^2", "GS",
       "Clamp of the speed integral's contribution GS_K_VI int(V_ref - V) dt to the acceleration demand."),
    _p("GA_K_GAMI", 0.04, 0, 1, "1/s^2", "GA",
       "Flight-path integral gain: gamma_dot_des += GA_K_GAMI int(gamma_c - gamma) dt (takes out "
       "the nominal model's lift error; anti-windup as GA_K_HI; initialised at engage so that the "
       "lift demand equals the present trimmed lift)."),
    _p("GA_GI_MAX", 0.1, 0, 10, "deg/s", "GA",
       "Clamp of the flight-path integral's contribution to gamma_dot_des.", si_scale=DEG),
    _p("GH_CHI_TAU", 2.0, 0, 60, "s", "GH",
       "Time constant of the first-order low-pass on the course error (0 = none): at V K_chi / g "
       "~ 12 deg of bank per deg of course error, heading noise would reach the bank command."),
    _p("GA_HI_ZONE", 150, 1, 1e5, "m", "GA",
       "The altitude error is integrated only while |h_t - h| < GA_HI_ZONE (no windup over a "
       "climb or descent; the integral trims the last metres)."),
    _p("GA_GI_ZONE", 0.2, 0.001, 10, "deg", "GA",
       "The flight-path error is integrated only while |gamma_c - gamma| < GA_GI_ZONE (at "
       "hypersonic speed a small gamma-rate bias is a large load factor: 0.1 deg/s at 2250 m/s "
       "is 0.4 g).", si_scale=DEG),
    _p("GA_GDOT_TAU", 1.0, 0, 30, "s", "GA",
       "Time constant of the first-order low-pass on the feed-forward gamma_c_dot (0 = none): 1 m "
       "of altitude noise differentiated at 50 Hz would be 0.25 g of load-factor demand."),
    _p("GE_NZ_MARGIN", 0.05, 0, 0.5, "1", "GE",
       "Load-factor margin: the demand stays within [GE_NZ_MIN + m, GE_NZ_MAX - m], so the "
       "achieved load factor, which scatters about the demand with the inner loop's alpha "
       "tracking and the elevons' lift (+-0.03 at the cruise point), stays inside the envelope."),
    _p("GE_MU_MARGIN", 0.2, 0, 10, "deg", "GE",
       "Bank margin: |mu_c| <= GE_MU_MAX - m, so the achieved bank (the command plus the inner "
       "loop's tracking error, bounded at 0.2 deg) stays within GE_MU_MAX.", si_scale=DEG),
    _p("GE_ALPHA_MARGIN", 0.2, 0, 5, "deg", "GE",
       "Alpha margin: alpha_c within [GE_ALPHA_MIN + m, GE_ALPHA_MAX - m], so the achieved alpha "
       "(the command plus the inner loop's tracking error) stays within the alpha limits.",
       si_scale=DEG),
)

PARAM_INDEX = {p.name: i for i, p in enumerate(GUIDANCE_PARAMS)}

# Index constants into the SI parameter array the kernels use: positions in GUIDANCE_PARAMS, the
# one place the order is written (numba reads them as compile-time constants).
P_GA_K_H = PARAM_INDEX["GA_K_H"]
P_GA_K_HI = PARAM_INDEX["GA_K_HI"]
P_GA_HDOT_MAX = PARAM_INDEX["GA_HDOT_MAX"]
P_GA_K_GAM = PARAM_INDEX["GA_K_GAM"]
P_GH_K_CHI = PARAM_INDEX["GH_K_CHI"]
P_GH_CHIDOT_MAX = PARAM_INDEX["GH_CHIDOT_MAX"]
P_GS_K_V = PARAM_INDEX["GS_K_V"]
P_GS_K_VI = PARAM_INDEX["GS_K_VI"]
P_GS_ACC_MAX = PARAM_INDEX["GS_ACC_MAX"]
P_GE_ALPHA_MIN = PARAM_INDEX["GE_ALPHA_MIN"]
P_GE_ALPHA_MAX = PARAM_INDEX["GE_ALPHA_MAX"]
P_GE_ALPHA_RATE = PARAM_INDEX["GE_ALPHA_RATE"]
P_GE_GAM_MAX = PARAM_INDEX["GE_GAM_MAX"]
P_GE_GAM_RATE = PARAM_INDEX["GE_GAM_RATE"]
P_GE_MU_MAX = PARAM_INDEX["GE_MU_MAX"]
P_GE_MU_RATE = PARAM_INDEX["GE_MU_RATE"]
P_GE_NZ_MIN = PARAM_INDEX["GE_NZ_MIN"]
P_GE_NZ_MAX = PARAM_INDEX["GE_NZ_MAX"]
P_GE_QBAR_MIN = PARAM_INDEX["GE_QBAR_MIN"]
P_GE_QBAR_MAX = PARAM_INDEX["GE_QBAR_MAX"]
P_GE_QBAR_BAND = PARAM_INDEX["GE_QBAR_BAND"]
P_GE_THR_RATE = PARAM_INDEX["GE_THR_RATE"]
P_GM_CT_MAX = PARAM_INDEX["GM_CT_MAX"]
P_GM_T_MAX = PARAM_INDEX["GM_T_MAX"]
P_GA_HI_MAX = PARAM_INDEX["GA_HI_MAX"]
P_GS_VI_MAX = PARAM_INDEX["GS_VI_MAX"]
P_GA_K_GAMI = PARAM_INDEX["GA_K_GAMI"]
P_GA_GI_MAX = PARAM_INDEX["GA_GI_MAX"]
P_GH_CHI_TAU = PARAM_INDEX["GH_CHI_TAU"]
P_GA_HI_ZONE = PARAM_INDEX["GA_HI_ZONE"]
P_GA_GI_ZONE = PARAM_INDEX["GA_GI_ZONE"]
P_GA_GDOT_TAU = PARAM_INDEX["GA_GDOT_TAU"]
P_GE_NZ_MARGIN = PARAM_INDEX["GE_NZ_MARGIN"]
P_GE_MU_MARGIN = PARAM_INDEX["GE_MU_MARGIN"]
P_GE_ALPHA_MARGIN = PARAM_INDEX["GE_ALPHA_MARGIN"]
P_N = len(GUIDANCE_PARAMS)
assert all(len(p.name) <= 16 and p.min <= p.default <= p.max for p in GUIDANCE_PARAMS)
assert all((p.si_scale == DEG) == p.unit.startswith("deg") for p in GUIDANCE_PARAMS)


def check_value(name: str, value: float) -> float:
    """Validate one value in table units; KeyError (unknown name) or ValueError (bad value)."""
    if name not in PARAM_INDEX:
        raise KeyError(f"unknown guidance parameter {name!r}")
    return checked_value(GUIDANCE_PARAMS[PARAM_INDEX[name]], value)


def to_si(name: str, value: float) -> float:
    """The SI value of ``name`` = ``value`` (table units), validated."""
    return check_value(name, value) * GUIDANCE_PARAMS[PARAM_INDEX[name]].si_scale


def default_si_array() -> np.ndarray:
    """float64[P_N] of the defaults in SI."""
    return np.array([p.default * p.si_scale for p in GUIDANCE_PARAMS], dtype=np.float64)
