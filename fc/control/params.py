"""The control law's parameter table: every gain, bound and option, with unit, default and range.

One table (``LAW_PARAMS``) is the single source: the law reads its SI values from it through
``to_si``, the fc process exposes it over MAVLink (PARAM_VALUE index = position in the table,
names <= 16 characters) and generates docs/params.md from it. The order is stable: append new
parameters at the end, never reuse a retired slot.

Units are "human" units (what a G&C engineer types): degrees where an angle is meant, SI
otherwise. ``si_scale`` converts to the SI value the kernels use (the one conversion point,
house style 5). Integer options say so (``integer=True``) and list their values in the text.

Equation numbers refer to Mu, Wang, Wu, Ying, Trans. NUAA 35(6) 2018 (docs/control_law.md).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from fc.control.schedule_data import SCHED_AUTH, SCHED_MACH, SCHED_N, load_schedule

DEG = math.pi / 180.0


@dataclass(frozen=True, slots=True)
class Param:
    """One law parameter.

    name : <= 16 characters, uppercase (MAVLink param_id).
    default, min, max : in ``unit``.
    unit : human unit ("deg", "deg/s", "1/s", "-", ...).
    group : prefix family (CO, SLW, FST, DOB, ACT, REF, MDL, FLT, LAW).
    description : one or two sentences, with the paper's equation where there is one.
    si_scale : SI value = value * si_scale (DEG for degree parameters, else 1).
    integer : True for options and switches (the value must be a whole number).
    """
    name: str
    default: float
    min: float
    max: float
    unit: str
    group: str
    description: str
    si_scale: float = 1.0
    integer: bool = False


def checked_value(prm: Param, value: float) -> float:
    """The one validation rule of every parameter (the law's, the guidance's and the fc's
    table, fc/params.py): ``value`` in ``prm.unit`` as a float within [min, max].

    A bound that travelled as float32 over MAVLink (1.01 -> 1.00999999) is the bound: the
    float32 of each bound is accepted and the value clamped into [min, max]. Raises
    ValueError with the reason (not a number, not finite, outside the range, fractional for
    an integer option).
    """
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{prm.name}: {value!r} is not a number") from None
    if not math.isfinite(v):
        raise ValueError(f"{prm.name}: non-finite value refused")
    lo = min(prm.min, float(np.float32(prm.min)))
    hi = max(prm.max, float(np.float32(prm.max)))
    if v < lo or v > hi:
        unit = "" if prm.unit in ("-", "1", "") else f" {prm.unit}"   # "-": no unit to name
        raise ValueError(f"{prm.name}={v:g} outside [{prm.min:g}, {prm.max:g}]{unit}")
    if prm.integer and v != round(v):
        raise ValueError(f"{prm.name}={v:g} must be a whole number")
    return min(max(v, prm.min), prm.max)


def parse_sets(items) -> dict[str, float]:
    """``NAME=VALUE`` strings (the tools' ``--set``) -> {name: value}, each checked against the
    law's table (a known name, a value that ``checked_value`` accepts). Raises ValueError
    naming the bad item."""
    out = {}
    for item in items:
        name, eq, value = str(item).partition("=")
        name = name.strip()
        if not eq or not name:
            raise ValueError(f"{item!r}: expected NAME=VALUE")
        if name not in PARAM_INDEX:
            raise ValueError(f"{name!r}: not a law parameter (docs/params.md)")
        out[name] = checked_value(LAW_PARAMS[PARAM_INDEX[name]], value.strip())
    return out


def _p(name, default, lo, hi, unit, group, text, si_scale=1.0, integer=False):
    """One parameter record (the tables' shorthand; the guidance's table uses it too)."""
    return Param(name, float(default), float(lo), float(hi), unit, group, text,
                 si_scale, integer)


LAW_PARAMS: tuple[Param, ...] = (
    _p("PAPER_LITERAL", 0, 0, 1, "-", "LAW",
       "1 = fly the printed law: no omega_c limit, no integral/adaptation freeze, observer fed "
       "M_c, allocation clipped per surface, no prefilter (steps), no factor clamp or matrix "
       "guard. 0 = the documented deviations of docs/control_law.md are on.", integer=True),
    _p("CO_ENABLE", 1, 0, 1, "-", "CO",
       "1 = coordinated law (factors Eqs. 13/14/19 in the allocation matrix Eq. 45, surface "
       "coordination Eq. 47); 0 = uncoordinated baseline (all factors 0, no surface "
       "coordination). Set by the fc flight mode.", integer=True),
    _p("CO_FAC_EQ", 19, 14, 19, "-", "CO",
       "Inertia-coupling factors: 19 = Eq. 19, the factors Section 4.3 builds g_Gamma from "
       "(lambda_e = k4 alpha + k5 q, lambda_a = k6 beta + k7 p); 14 = Eq. 14 (lambda_e = k4 "
       "alpha + k5 p, lambda_a = k6 beta + k7 r). lambda_r = Eq. 13 + lambda_r3 in both.",
       integer=True),
    _p("CO_K1", 1, 0, 10, "s/rad", "CO", "k1 of Eq. 10/13: lambda_r1 = k1 p tan(alpha)."),
    _p("CO_K2", 1, 0, 10, "1/rad", "CO", "k2 of Eq. 12/13: k2 beta term of lambda_r2."),
    _p("CO_K3", 1, 0, 10, "s/rad", "CO",
       "k3 of Eq. 12/13: k3 p (1 - cos alpha) / (sin alpha + Delta_alpha)."),
    _p("CO_K4", 1, 0, 10, "1/rad", "CO", "k4 of Eq. 14/19: k4 alpha term of lambda_e."),
    _p("CO_K5", 1, 0, 10, "s/rad", "CO",
       "k5 of Eq. 14/19: rate term of lambda_e (p in Eq. 14, q in Eq. 19)."),
    _p("CO_K6", 1, 0, 10, "1/rad", "CO", "k6 of Eq. 14/19: k6 beta term of lambda_a."),
    _p("CO_K7", 1, 0, 10, "s/rad", "CO",
       "k7 of Eq. 14/19: rate term of lambda_a (r in Eq. 14, p in Eq. 19)."),
    _p("CO_K8", 1, 0, 10, "1/rad", "CO",
       "k8 of Eq. 14/19: lambda_r3 = k8 beta + k9 q, a term Eq. 19 writes into lambda_r "
       "(Section 5 gives only k1..k7; 1 like them, docs/control_law.md D3)."),
    _p("CO_K9", 1, 0, 10, "s/rad", "CO",
       "k9 of Eq. 14/19: q term of lambda_r3 (not given by Section 5; 1 like k1..k7)."),
    _p("CO_DALPHA", 0.05, 0.001, 1, "-", "CO",
       "Delta_alpha of Eq. 12: added to sin(alpha) to keep the k3 term away from its singularity."),
    _p("CO_NORM", 0, 0, 2, "-", "CO",
       "How a factor is added to g_f_delta (Eq. 45): 0 = relative to the diagonal entry "
       "(Gamma_ii = lambda_i g_ii); 1 = to the dimensionless coefficient per rad (Gamma_ii = "
       "lambda_i qbar S l_i, l = b, c, b); 2 = literally in N m/rad (does nothing).", integer=True),
    _p("CO_LAM_MAX", 0.5, 0, 10, "-", "CO",
       "Clamp |lambda_i| <= CO_LAM_MAX (0 = no clamp). With CO_NORM 0 a value < 1 keeps the sign "
       "of every diagonal entry."),
    _p("CO_SURF", 0, 0, 2, "-", "CO",
       "Surface coordination, Eq. 47 with E of Eq. 15: 0 = off; 1 = aileron-rudder interconnect "
       "delta_a_out = delta_a + E delta_r (after the inverse); 2 = literal delta_a = E delta_r. "
       "(A moment-preserving interconnect is identical to 0 with a full 3x3 inverse.)",
       integer=True),
    _p("CO_E", 0, 0, 1, "-", "CO",
       "Surface-deflection coupling degree E (Eq. 15), 0 < E <= 1. 0 = computed at the flight "
       "condition as |Cl_delta_r / Cl_delta_a| (rolling-moment effectiveness ratio, clipped to "
       "[0.01, 1])."),
    _p("CO_DET_MIN", 0.2, 0, 1, "-", "CO",
       "Guard: the coordinated matrix is used only if det(g_Gamma)/det(g_f_delta) and each "
       "g_Gamma_ii/g_f_delta_ii are >= CO_DET_MIN (not near-singular, no sign flip); "
       "otherwise g_f_delta is used and co_fallback is set."),
    _p("SLW_K1", 4, 0, 50, "1/s", "SLW",
       "K1 of Eq. 27 (alpha channel integral gain of the sliding surface)."),
    _p("SLW_K2", 4, 0, 50, "1/s", "SLW", "K2 of Eq. 27 (beta channel)."),
    _p("SLW_K3", 4, 0, 50, "1/s", "SLW", "K3 of Eq. 27 (mu channel)."),
    _p("SLW_KAPPA", 5, 0, 100, "1/s", "SLW", "kappa1 of Eq. 29 (slow-loop sliding-surface gain)."),
    _p("SLW_GAMMA", 20, 0, 1e4, "1/rad^2", "SLW",
       "Gamma1 of Eq. 30 (scalar x identity) for the relative estimate rho_Omega "
       "(theta_hat = theta_nom (1 + rho)); 0 = no adaptation."),
    _p("SLW_LEAK", 0.1, 0, 100, "1/s", "SLW",
       "lambda_Omega of Eq. 30: leakage of theta_hat_Omega toward the nominal model."),
    _p("SLW_TH_BND", 0.5, 0, 5, "-", "SLW",
       "Projection bound of Eq. 30: |theta_hat_i / theta_nom_i - 1| <= SLW_TH_BND."),
    _p("SLW_OMC_MAX", 3, 0, 180, "deg/s", "SLW",
       "Limit on each component of the virtual rate command omega_c (Eq. 29), applied by scaling "
       "the vector (direction kept). 0 = no limit.", si_scale=DEG),
    _p("SLW_AW", 1, 0, 1, "-", "SLW",
       "1 = freeze the integral of e1 (Eq. 27) and both adaptive laws while omega_c is limited "
       "or a surface saturates (anti-windup).", integer=True),
    _p("FST_KAPPA", 5, 0, 200, "1/s", "FST", "kappa2 of Eq. 35 (fast-loop rate-error gain)."),
    _p("FST_GAMMA", 5, 0, 1e4, "s^3/rad^2", "FST",
       "Gamma2 of Eq. 36 (scalar x identity) for the relative estimate rho_omega; "
       "0 = no adaptation."),
    _p("FST_LEAK", 0.1, 0, 100, "1/s", "FST",
       "lambda_omega of Eq. 36: leakage of theta_hat_omega toward the nominal model."),
    _p("FST_TH_BND", 0.5, 0, 5, "-", "FST",
       "Projection bound of Eq. 36: |theta_hat_i / theta_nom_i - 1| <= FST_TH_BND."),
    _p("FST_CF_WN", 40, 1, 500, "rad/s", "FST",
       "Natural frequency of the 2nd-order command filter that gives omega_c and omega_c_dot "
       "to Eq. 35 (the paper does not define omega_c_dot)."),
    _p("FST_CF_ZETA", 0.9, 0.3, 2, "-", "FST", "Damping ratio of the omega_c command filter."),
    _p("DOB_ENABLE", 1, 0, 1, "-", "DOB", "1 = disturbance observer of Eq. 37 on; 0 = d_hat = 0.",
       integer=True),
    _p("DOB_C", 10, 1.01, 200, "1/s", "DOB",
       "c of Eq. 37/41: Q(e) = c omega, L = c I (c > 1); the observer's bandwidth."),
    _p("DOB_ACHIEVED", 1, 0, 2, "-", "DOB",
       "Moment fed to the observer (Eq. 37): 1 = g_f_delta delta_model, the physical moment of "
       "the modelled actuators (limits, rate, lag); 2 = g_Gamma delta_model, the coordinated "
       "moment of Eq. 44 (M_c as the modelled actuators deliver it); 0 = M_c as printed.",
       integer=True),
    _p("ACT_MAX", 20, 1, 30, "deg", "ACT",
       "Deflection limit of each surface (the aerodynamic data's range).", si_scale=DEG),
    _p("ACT_RATE", 90, 1, 1000, "deg/s", "ACT",
       "Surface rate limit of the controller's actuator model (the observer's input) and of "
       "the rate-aware allocation (ALLOC_RATE).",
       si_scale=DEG),
    _p("ACT_TAU", 0.02, 0, 1, "s", "ACT",
       "First-order lag of the controller's actuator model (0 = none)."),
    _p("ALLOC_MODE", 2, 0, 2, "-", "ACT",
       "Saturation of the allocation (Eq. 46): 0 = clip each surface (printed paper); "
       "1 = scale the whole deflection vector so the moment keeps its direction; 2 = "
       "prioritised: the surface furthest beyond its limit is held at the limit and the "
       "others re-solved by weighted least squares on the axes' angular accelerations "
       "(weights ALLOC_W_ROLL/PITCH/YAW), repeated while a surface is beyond its limit.",
       integer=True),
    _p("REF_PF_EN", 1, 0, 1, "-", "REF",
       "1 = 2nd-order reference prefilter on Omega_c (gives Omega_c_dot); 0 = the paper's steps "
       "(Omega_c_dot = 0).", integer=True),
    _p("REF_PF_WN", 2, 0.1, 50, "rad/s", "REF", "Natural frequency of the reference prefilter."),
    _p("REF_PF_ZETA", 1, 0.3, 2, "-", "REF", "Damping ratio of the reference prefilter."),
    _p("MDL_MASS", 136078, 1e3, 1e7, "kg", "MDL",
       "Mass M of the controller's nominal model (Eq. 2)."),
    _p("MDL_IXX", 1.36e6, 1e3, 1e9, "kg m^2", "MDL", "Ixx of the nominal model (Eq. 4)."),
    _p("MDL_IYY", 1.5e7, 1e3, 1e9, "kg m^2", "MDL", "Iyy of the nominal model (Eq. 4)."),
    _p("MDL_IZZ", 1.36e7, 1e3, 1e9, "kg m^2", "MDL", "Izz of the nominal model (Eq. 4)."),
    _p("MDL_XCG", 0, -10, 10, "m", "MDL",
       "X_cg of Eq. 6: MRC -> c.g., positive aft, of the nominal model."),
    _p("SLW_CFB", 0, 0, 1, "-", "SLW",
       "1 = command-filtered backstepping compensation: xi_dot = -kappa1 xi + g_s (omega_c_lim "
       "- omega_c), and sigma_bar = sigma - xi replaces sigma in Eq. 30 and in the g_s^T sigma "
       "term of Eq. 35, so the omega_c limit does not feed back through them.", integer=True),
    _p("FLT_RATE_HZ", 20, 0, 200, "Hz", "FLT",
       "Cutoff of the 2nd-order (two 1st-order sections) low-pass on p, q, r as the fast loop "
       "uses them (e2, Xi, observer, factors); 0 = off. The paper assumes noise-free rates."),
    _p("FLT_ANG_HZ", 20, 0, 100, "Hz", "FLT",
       "Cutoff of the 2nd-order low-pass on alpha, beta, mu as e1 of the slow loop uses them "
       "(run at the fast rate, read by the slow loop); 0 = off."),
    _p("CO_MAP", 1, 0, 1, "-", "CO",
       "Where the factors act in Eq. 45: 0 = on the printed diagonal entries (roll-left "
       "elevon lambda_e, pitch-right elevon lambda_a, yaw-rudder lambda_r; CO_NORM applies); "
       "1 = on the axis the prose names (elevator loop = pitch row x (1 + lambda_e), aileron "
       "loop = roll row x (1 + lambda_a), rudder loop = yaw row x (1 + lambda_r)).",
       integer=True),
    _p("ALLOC_RATE", 0, 0, 2, "-", "ACT",
       "Rate-aware allocation: the change of the surface command per fast step is kept within "
       "ALLOC_RATE x ACT_RATE x dt by scaling the change vector (the change of moment keeps its "
       "direction); the shortfall goes to the unallocated moment and the observer sees the "
       "modelled actuators as before. 1 = the actuators' own rate, 0 = off (the command jumps, "
       "the actuators rate-limit each surface on their own)."),
    _p("FLT_ANG_CF", 1, 0, 20, "Hz", "FLT",
       "Crossover of the complementary attitude filter; > 0 replaces the FLT_ANG_HZ low-pass of "
       "alpha, beta, mu (e1 of the slow loop) by Omega_hat_dot = g_s(Omega_hat) omega + f1 + "
       "Psi^T theta_hat + 2 pi FLT_ANG_CF (Omega - Omega_hat) (Eq. 2 with the gyros' omega): "
       "the vanes' noise is filtered above the crossover, the gyros and the model carry the "
       "fast motion, without the low-pass's lag. 0 = off."),
)

#: The scheduled quantities: (family prefix of the SCH_* parameters, npz name, unit, min, max,
#: the fixed parameter it replaces while CTL_SCHED = 1, si_scale).
SCHED_FAMILIES: tuple[tuple[str, str, str, float, float, str, float], ...] = (
    ("SCH_KAP1_", "kappa1", "1/s", 0.0, 100.0, "SLW_KAPPA", 1.0),
    ("SCH_K_", "K", "1/s", 0.0, 50.0, "SLW_K1", 1.0),
    ("SCH_KAP2_", "kappa2", "1/s", 0.0, 200.0, "FST_KAPPA", 1.0),
    ("SCH_DOBC_", "dob_c", "1/s", 1.01, 200.0, "DOB_C", 1.0),
    ("SCH_CFWN_", "cf_wn", "rad/s", 1.0, 500.0, "FST_CF_WN", 1.0),
    ("SCH_FLTR_", "flt_rate_hz", "Hz", 0.0, 200.0, "FLT_RATE_HZ", 1.0),
    ("SCH_FLTA_", "flt_ang_hz", "Hz", 0.0, 100.0, "FLT_ANG_HZ", 1.0),
    ("SCH_OMC_", "omc_max_deg_s", "deg/s", 0.0, 180.0, "SLW_OMC_MAX", DEG),
)


def _schedule_params() -> tuple[Param, ...]:
    """CTL_SCHED and the SCH_* table, defaults from fc/control/data/schedule.npz (written by
    ``python -m tools.schedule_design``; docs/control_law.md "Scheduling")."""
    tab = load_schedule()
    out = [_p("CTL_SCHED", 1, 0, 1, "-", "SCH",
              "1 = the gains and filters of SCH_* are scheduled with the dynamic pressure the law "
              "computes from the estimated airspeed and altitude (replacing SLW_KAPPA, SLW_K1..3, "
              "FST_KAPPA, DOB_C, FST_CF_WN, FLT_RATE_HZ, FLT_ANG_HZ, SLW_OMC_MAX); 0 = those "
              "fixed parameters (the paper's gains, K = 4, kappa = 5).", integer=True)]
    for i in range(SCHED_N):
        out.append(_p(f"SCH_Q_{i + 1}", tab["qbar_kpa"][i], 1.0, 1000.0, "kPa", "SCH",
                      f"Dynamic pressure of schedule node {i + 1} (nodes increasing; below "
                      "the first and above the last the end values hold).", si_scale=1e3))
    for prefix, key, unit, lo, hi, target, scale in SCHED_FAMILIES:
        for i in range(SCHED_N):
            out.append(_p(f"{prefix}{i + 1}", tab[key][i], lo, hi, unit, "SCH",
                          f"{target} at schedule node {i + 1} (SCH_Q_{i + 1}), CTL_SCHED 1.",
                          si_scale=scale))
    # the Mach axis of the rate-command limit (after the qbar table: appended, order stable)
    for i in range(SCHED_N):
        out.append(_p(f"SCH_M_{i + 1}", tab[SCHED_MACH[0]][i], 0.0, 30.0, "-", "SCH",
                      f"Mach number of the rate-command limit's Mach node {i + 1} (nodes "
                      "increasing; below the first and above the last the end values hold)."))
    for i in range(SCHED_N):
        out.append(_p(f"SCH_OMCF_{i + 1}", tab[SCHED_MACH[1]][i], 0.01, 1.0, "-", "SCH",
                      f"Factor on the scheduled SLW_OMC_MAX at Mach node {i + 1} (SCH_M_"
                      f"{i + 1}), CTL_SCHED 1: the rudder authority the airframe's directional "
                      "instability leaves (1 where the airframe is directionally stable)."))
    for i in range(SCHED_N):
        out.append(_p(f"SCH_AUTH_{i + 1}", tab[SCHED_AUTH][i], 0.1, 10.0, "-", "SCH",
                      f"Authority factor at Mach node {i + 1} (SCH_M_{i + 1}), CTL_SCHED 1: the "
                      "gains and filters are looked up at the dynamic pressure times it (the "
                      "least effective channel's effectiveness at this Mach number over the "
                      "least over Mach 6-15, which the SCH_Q nodes were designed for; "
                      "SLW_OMC_MAX keeps the plain dynamic pressure)."))
    return tuple(out)


LAW_PARAMS = LAW_PARAMS + _schedule_params() + (
    _p("CO_LAMR_SCL", 1, 0, 1, "-", "CO",
       "Scale on the yaw-row factor lambda_r (Eq. 13 + lambda_r3) before its clamp; 1 = the "
       "paper's. While CTL_SCHED 1 the schedule writes the Mach factor SCH_OMCF into it: the "
       "rudder authority the airframe's directional instability leaves, so that the factor's "
       "cut of the yaw loop's gain (1 / (1 + lambda_r)) shrinks with it."),
    _p("ALLOC_W_ROLL", 1, 0.001, 1000, "-", "ACT",
       "ALLOC_MODE 2: weight of the roll axis's angular-acceleration shortfall (relative)."),
    _p("ALLOC_W_PITCH", 10, 0.001, 1000, "-", "ACT",
       "ALLOC_MODE 2: weight of the pitch axis's angular-acceleration shortfall (relative)."),
    _p("ALLOC_W_YAW", 300, 0.001, 1000, "-", "ACT",
       "ALLOC_MODE 2: weight of the yaw axis's angular-acceleration shortfall (relative)."),
    _p("ALLOC_YAW_T", 1, 0, 100, "s", "ACT",
       "ALLOC_MODE 2: yaw escalation: the yaw weight x (1 + t / ALLOC_YAW_T), t the time (s) "
       "the rudder alone has been asked beyond its limit, the elevons within theirs (counted "
       "down at the same rate otherwise); 0 off."),
    _p("ALLOC_YAW_MAX", 10, 1, 100, "-", "ACT",
       "ALLOC_MODE 2: the yaw escalation's largest factor."),
)

PARAM_INDEX: dict[str, int] = {p.name: i for i, p in enumerate(LAW_PARAMS)}

# Index constants into the SI parameter array the kernels use: positions in LAW_PARAMS, the
# one place the order is written (numba reads them as compile-time constants).
P_PAPER_LITERAL = PARAM_INDEX["PAPER_LITERAL"]
P_CO_ENABLE = PARAM_INDEX["CO_ENABLE"]
P_CO_FAC_EQ = PARAM_INDEX["CO_FAC_EQ"]
P_CO_K1 = PARAM_INDEX["CO_K1"]          # k1 .. k9 are P_CO_K1 + i - 1
P_CO_DALPHA = PARAM_INDEX["CO_DALPHA"]
P_CO_NORM = PARAM_INDEX["CO_NORM"]
P_CO_LAM_MAX = PARAM_INDEX["CO_LAM_MAX"]
P_CO_SURF = PARAM_INDEX["CO_SURF"]
P_CO_E = PARAM_INDEX["CO_E"]
P_CO_DET_MIN = PARAM_INDEX["CO_DET_MIN"]
P_SLW_K1 = PARAM_INDEX["SLW_K1"]        # K1, K2, K3 consecutive
P_SLW_KAPPA = PARAM_INDEX["SLW_KAPPA"]
P_SLW_GAMMA = PARAM_INDEX["SLW_GAMMA"]
P_SLW_LEAK = PARAM_INDEX["SLW_LEAK"]
P_SLW_TH_BND = PARAM_INDEX["SLW_TH_BND"]
P_SLW_OMC_MAX = PARAM_INDEX["SLW_OMC_MAX"]
P_SLW_AW = PARAM_INDEX["SLW_AW"]
P_FST_KAPPA = PARAM_INDEX["FST_KAPPA"]
P_FST_GAMMA = PARAM_INDEX["FST_GAMMA"]
P_FST_LEAK = PARAM_INDEX["FST_LEAK"]
P_FST_TH_BND = PARAM_INDEX["FST_TH_BND"]
P_FST_CF_WN = PARAM_INDEX["FST_CF_WN"]
P_FST_CF_ZETA = PARAM_INDEX["FST_CF_ZETA"]
P_DOB_ENABLE = PARAM_INDEX["DOB_ENABLE"]
P_DOB_C = PARAM_INDEX["DOB_C"]
P_DOB_ACHIEVED = PARAM_INDEX["DOB_ACHIEVED"]
P_ACT_MAX = PARAM_INDEX["ACT_MAX"]
P_ACT_RATE = PARAM_INDEX["ACT_RATE"]
P_ACT_TAU = PARAM_INDEX["ACT_TAU"]
P_ALLOC_MODE = PARAM_INDEX["ALLOC_MODE"]
P_ALLOC_YAW_T = PARAM_INDEX["ALLOC_YAW_T"]
P_ALLOC_YAW_MAX = PARAM_INDEX["ALLOC_YAW_MAX"]
P_ALLOC_W = PARAM_INDEX["ALLOC_W_ROLL"]   # roll, pitch, yaw consecutive
P_REF_PF_EN = PARAM_INDEX["REF_PF_EN"]
P_REF_PF_WN = PARAM_INDEX["REF_PF_WN"]
P_REF_PF_ZETA = PARAM_INDEX["REF_PF_ZETA"]
P_MDL_MASS = PARAM_INDEX["MDL_MASS"]
P_MDL_IXX = PARAM_INDEX["MDL_IXX"]
P_MDL_IYY = PARAM_INDEX["MDL_IYY"]
P_MDL_IZZ = PARAM_INDEX["MDL_IZZ"]
P_MDL_XCG = PARAM_INDEX["MDL_XCG"]
P_SLW_CFB = PARAM_INDEX["SLW_CFB"]
P_FLT_RATE_HZ = PARAM_INDEX["FLT_RATE_HZ"]
P_FLT_ANG_HZ = PARAM_INDEX["FLT_ANG_HZ"]
P_CO_MAP = PARAM_INDEX["CO_MAP"]
P_ALLOC_RATE = PARAM_INDEX["ALLOC_RATE"]
P_FLT_ANG_CF = PARAM_INDEX["FLT_ANG_CF"]
P_CTL_SCHED = PARAM_INDEX["CTL_SCHED"]
P_SCH_Q = PARAM_INDEX["SCH_Q_1"]           # SCHED_N nodes, then each family's SCHED_N values
P_SCH_KAP1 = PARAM_INDEX["SCH_KAP1_1"]
P_SCH_K = PARAM_INDEX["SCH_K_1"]
P_SCH_KAP2 = PARAM_INDEX["SCH_KAP2_1"]
P_SCH_DOBC = PARAM_INDEX["SCH_DOBC_1"]
P_SCH_CFWN = PARAM_INDEX["SCH_CFWN_1"]
P_SCH_FLTR = PARAM_INDEX["SCH_FLTR_1"]
P_SCH_FLTA = PARAM_INDEX["SCH_FLTA_1"]
P_SCH_OMC = PARAM_INDEX["SCH_OMC_1"]
P_SCH_M = PARAM_INDEX["SCH_M_1"]           # SCHED_N Mach nodes, then SCHED_N factors
P_SCH_OMCF = PARAM_INDEX["SCH_OMCF_1"]
P_SCH_AUTH = PARAM_INDEX["SCH_AUTH_1"]
P_CO_LAMR_SCL = PARAM_INDEX["CO_LAMR_SCL"]
#: the fixed parameters the schedule replaces while it is on (restored when it goes off)
SCHEDULED_NAMES = tuple(f[5] for f in SCHED_FAMILIES) + ("SLW_K2", "SLW_K3", "CO_LAMR_SCL")
P_N = len(LAW_PARAMS)
assert [PARAM_INDEX[f"CO_K{i}"] for i in range(1, 10)] == list(range(P_CO_K1, P_CO_K1 + 9))
assert [PARAM_INDEX[f"SLW_K{i}"] for i in (1, 2, 3)] == list(range(P_SLW_K1, P_SLW_K1 + 3))
for _f in ("SCH_Q_",) + tuple(f[0] for f in SCHED_FAMILIES) + ("SCH_M_", "SCH_OMCF_", "SCH_AUTH_"):
    assert [PARAM_INDEX[f"{_f}{i + 1}"] for i in range(SCHED_N)] == list(
        range(PARAM_INDEX[f"{_f}1"], PARAM_INDEX[f"{_f}1"] + SCHED_N)), _f
for _prm in LAW_PARAMS:
    assert len(_prm.name) <= 16 and _prm.name == _prm.name.upper(), _prm.name
    assert _prm.min <= _prm.default <= _prm.max, _prm.name


def check_value(name: str, value: float) -> float:
    """Validate ``value`` (human units) for parameter ``name``; return it as a float.

    Raises KeyError for an unknown name, ValueError for a value :func:`checked_value`
    refuses and for a CO_FAC_EQ other than 14 or 19.
    """
    if name not in PARAM_INDEX:
        raise KeyError(f"unknown control-law parameter {name!r}")
    v = checked_value(LAW_PARAMS[PARAM_INDEX[name]], value)
    if name == "CO_FAC_EQ" and v not in (14.0, 19.0):
        raise ValueError(f"{name}={v:g} refused: must be 14 or 19")
    return v


def to_si(name: str, value: float) -> float:
    """The SI value the kernels use for ``value`` given in the table's unit."""
    return check_value(name, value) * LAW_PARAMS[PARAM_INDEX[name]].si_scale


def default_si_array() -> np.ndarray:
    """A new float64[P_N] with every parameter's default in SI."""
    return np.array([p.default * p.si_scale for p in LAW_PARAMS], dtype=np.float64)
