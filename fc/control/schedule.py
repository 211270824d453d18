"""The gain schedule (issue 20): the law's gains and filters as functions of the flight
condition, read from the SCH_* parameters (fc/control/params.py; defaults from the table that
``python -m tools.schedule_design`` writes, docs/control_law.md "Scheduling").

    schedule_index(qbar_pa, par) -> (k, f)
        segment k and fraction f of the dynamic pressure on the nodes SCH_Q_1..SCH_Q_n,
        clamped at the table's edges (below the first node f = 0 on segment 0, above the
        last f = 1 on the last segment; NaN -> the first node)
    mach_index(mach, par) -> (k, f)
        the same on the Mach nodes SCH_M_1..n (the rate-command limit's Mach axis)
    schedule_value(par, base, k, f)
        linear interpolation of one family (par[base + k], par[base + k + 1])
    apply_schedule(qbar_pa, mach, par, x)
        writes the interpolated values into the slots of the fixed parameters they replace
        (SLW_KAPPA, SLW_K1..3, FST_KAPPA, DOB_C, FST_CF_WN, FLT_RATE_HZ, FLT_ANG_HZ,
        SLW_OMC_MAX), so every kernel reads them where it always did; the gains and filters
        are read at the effective dynamic pressure qbar x SCH_AUTH(Mach) (the nodes were
        designed for the least effective Mach number; where the surfaces are more effective
        the same noise budget allows the gains of a higher node); SLW_OMC_MAX is the
        dynamic-pressure value times the Mach factor SCH_OMCF (1 where the airframe is
        directionally stable, below 1 where its instability takes rudder authority), and the
        same factor scales the yaw-row coordination factor lambda_r (CO_LAMR_SCL); bumpless: the
        integral of e1 is rescaled so that K int(e1) is unchanged, and the observer's state so
        that d_hat = z + c omega is unchanged (c as the continuous gain)

The slow loop calls apply_schedule once per slow step (CTL_SCHED = 1 and not PAPER_LITERAL),
with the dynamic pressure and Mach number of the nominal model at the estimated airspeed and
altitude (the fc's own air data, never the plant's truth). No allocation: scalars and in-place writes.
"""
from __future__ import annotations

from numba import njit

from fc.control.layout import E_P, X_EF, X_INT_E1, X_Z
from fc.control.params import (
    P_DOB_C, P_FLT_ANG_HZ, P_FLT_RATE_HZ, P_FST_CF_WN, P_FST_KAPPA, P_SCH_CFWN, P_SCH_DOBC,
    P_SCH_FLTA, P_SCH_FLTR, P_SCH_K, P_SCH_KAP1, P_SCH_KAP2, P_SCH_M, P_SCH_OMC, P_SCH_OMCF,
    P_SCH_AUTH, P_SCH_Q, P_SLW_K1, P_CO_LAMR_SCL,
    P_SLW_KAPPA, P_SLW_OMC_MAX,
)
from fc.control.schedule_data import SCHED_N


@njit(cache=True, error_model="numpy")
def node_index(v, par, base):
    """(k, f): the node segment k (0 .. SCHED_N - 2) and fraction f in [0, 1] of ``v`` on the
    nodes par[base:base + SCHED_N], clamped at both ends (NaN -> the first node)."""
    if not (v > par[base]):                      # below the first node, or NaN
        return 0, 0.0
    if v >= par[base + SCHED_N - 1]:
        return SCHED_N - 2, 1.0
    k = 0
    while k < SCHED_N - 2 and v >= par[base + k + 1]:
        k += 1
    lo = par[base + k]
    span = par[base + k + 1] - lo
    f = (v - lo) / span if span > 0.0 else 0.0
    return k, min(max(f, 0.0), 1.0)


@njit(cache=True, error_model="numpy")
def schedule_index(qbar_pa, par):
    """(k, f) of ``qbar_pa`` (Pa) on the dynamic-pressure nodes SCH_Q_1..n (Pa)."""
    return node_index(qbar_pa, par, P_SCH_Q)


@njit(cache=True, error_model="numpy")
def mach_index(mach, par):
    """(k, f) of ``mach`` on the Mach nodes SCH_M_1..n."""
    return node_index(mach, par, P_SCH_M)


@njit(cache=True, inline="always", error_model="numpy")
def schedule_value(par, base, k, f):
    """One family's value between nodes k and k + 1 (SI)."""
    return (1.0 - f) * par[base + k] + f * par[base + k + 1]


@njit(cache=True, error_model="numpy")
def apply_schedule(qbar_pa, mach, par, x):
    """The scheduled gains at ``qbar_pa`` (Pa) and ``mach`` into their fixed parameters' slots
    of ``par`` (bumpless for the integral of e1 and the observer's estimate, see the module
    text)."""
    km, fm = mach_index(mach, par)
    k, f = schedule_index(qbar_pa * schedule_value(par, P_SCH_AUTH, km, fm), par)
    c_old = par[P_DOB_C]
    k_new = schedule_value(par, P_SCH_K, k, f)
    c_new = schedule_value(par, P_SCH_DOBC, k, f)
    par[P_SLW_KAPPA] = schedule_value(par, P_SCH_KAP1, k, f)
    for i in range(3):
        if k_new > 0.0:
            x[X_INT_E1 + i] *= par[P_SLW_K1 + i] / k_new
        par[P_SLW_K1 + i] = k_new
    par[P_FST_KAPPA] = schedule_value(par, P_SCH_KAP2, k, f)
    par[P_DOB_C] = c_new
    if c_new != c_old:
        for i in range(3):
            x[X_Z + i] -= (c_new - c_old) * x[X_EF + E_P + i]
    par[P_FST_CF_WN] = schedule_value(par, P_SCH_CFWN, k, f)
    par[P_FLT_RATE_HZ] = schedule_value(par, P_SCH_FLTR, k, f)
    par[P_FLT_ANG_HZ] = schedule_value(par, P_SCH_FLTA, k, f)
    rudder_share = schedule_value(par, P_SCH_OMCF, km, fm)
    kq, fq = schedule_index(qbar_pa, par)
    par[P_SLW_OMC_MAX] = schedule_value(par, P_SCH_OMC, kq, fq) * rudder_share
    par[P_CO_LAMR_SCL] = rudder_share
