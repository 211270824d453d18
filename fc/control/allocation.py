"""Allocation (Eqs. 44-47) with saturation, and the controller's model of the actuators.

    allocate(par, nm, mc0, mc1, mc2, e_coup, delta, st)
        delta = g_Gamma^-1 M_c (Eq. 46), Eq. 47 surface coordination, position limit
        (ALLOC_MODE: clip each surface or scale the vector); the saturation flags and the
        unallocated moment go to the status record (house style 9).
    rate_limit_command(par, nm, x, e_coup, dt, delta, st)
        rate-aware allocation: the command's change per fast step kept within what the
        actuators can travel (ALLOC_RATE x ACT_RATE x dt), the change vector scaled (direction
        kept), the shortfall added to the unallocated moment.
    actuator_model_step(par, x, delta_cmd, dt)
        position limit, first-order lag, rate limit of the modelled surfaces (x[X_DM:]).

Surfaces [left elevon, right elevon, rudder] (rad), moments [l, m, n] (N m).
"""
from __future__ import annotations

import math

from numba import njit

from fc.control.layout import (NM_GCO, S_ALLOC_RATE, S_ALLOC_SCALE, S_M_UNALLOC, S_SAT,
                               S_SAT_ANY, X_DCMD, X_DM)
from fc.control.linalg3 import clip, matvec3, solve3
from fc.control.options import (ALLOC_SCALE, SURF_INTERCONNECT, SURF_LITERAL, option,
                                switch_on)
from fc.control.params import (P_ACT_MAX, P_ACT_RATE, P_ACT_TAU, P_ALLOC_MODE, P_ALLOC_RATE,
                               P_CO_ENABLE, P_CO_SURF, P_PAPER_LITERAL)


@njit(cache=True, error_model="numpy")
def allocate(par, nm, mc0, mc1, mc2, e_coup, delta, st):
    """delta = g_Gamma^-1 M_c (Eq. 46), Eq. 47 surface coordination, position saturation.

    mc0..mc2: M_c (N m); e_coup: the coupling degree E of Eq. 15. Writes delta[0:3] (rad),
    the saturation flags and the unallocated moment into st; returns 1.0 if any surface was
    requested beyond its limit.
    """
    det = solve3(nm, NM_GCO, mc0, mc1, mc2, delta, 0)
    if not (abs(det) > 0.0 and math.isfinite(delta[0]) and math.isfinite(delta[1])
            and math.isfinite(delta[2])):
        # no control authority (qbar ~ 0) or non-finite input: neutral surfaces, all flagged
        for i in range(3):
            delta[i] = 0.0
            st[S_SAT + i] = 1.0
        st[S_M_UNALLOC] = mc0
        st[S_M_UNALLOC + 1] = mc1
        st[S_M_UNALLOC + 2] = mc2
        st[S_ALLOC_SCALE] = 0.0
        st[S_SAT_ANY] = 1.0
        return 1.0
    # u: the allocation g_Gamma^-1 M_c; d: the surfaces after Eq. 47 (rad)
    u0 = delta[0]
    u1 = delta[1]
    u2 = delta[2]
    d0 = u0
    d1 = u1
    d2 = u2
    # Eq. 47: delta_a (right elevon) coordinated with the rudder through E
    if switch_on(par, P_CO_ENABLE):
        surf = option(par, P_CO_SURF)
        if surf == SURF_INTERCONNECT:
            d1 = d1 + e_coup * d2          # delta_a_out = delta_a + E delta_r
        elif surf == SURF_LITERAL:
            d1 = e_coup * d2               # delta_coa = E delta_r
    limit_rad = par[P_ACT_MAX]
    big = max(abs(d0), max(abs(d1), abs(d2)))
    sat_any = 0.0
    st[S_SAT] = 1.0 if abs(d0) > limit_rad else 0.0
    st[S_SAT + 1] = 1.0 if abs(d1) > limit_rad else 0.0
    st[S_SAT + 2] = 1.0 if abs(d2) > limit_rad else 0.0
    scale = 1.0
    if big > limit_rad:
        sat_any = 1.0
        if option(par, P_ALLOC_MODE) == ALLOC_SCALE and not switch_on(par, P_PAPER_LITERAL):
            # direction-preserving: scale the whole vector (the moment keeps its direction)
            scale = limit_rad / big
            d0 *= scale
            d1 *= scale
            d2 *= scale
            u0 *= scale
            u1 *= scale
            u2 *= scale
        else:
            # clip each surface (the printed paper)
            d0 = clip(d0, -limit_rad, limit_rad)
            d1 = clip(d1, -limit_rad, limit_rad)
            d2 = clip(d2, -limit_rad, limit_rad)
            u0 = clip(u0, -limit_rad, limit_rad)
            u1 = clip(u1, -limit_rad, limit_rad)
            u2 = clip(u2, -limit_rad, limit_rad)
    # unallocated moment (in the coordinated matrix's terms)
    m0, m1, m2 = matvec3(nm, NM_GCO, u0, u1, u2)
    st[S_M_UNALLOC] = mc0 - m0
    st[S_M_UNALLOC + 1] = mc1 - m1
    st[S_M_UNALLOC + 2] = mc2 - m2
    st[S_ALLOC_SCALE] = scale
    st[S_SAT_ANY] = sat_any
    delta[0] = d0
    delta[1] = d1
    delta[2] = d2
    return sat_any


@njit(cache=True, error_model="numpy")
def rate_limit_command(par, nm, x, e_coup, dt, delta, st):
    """Rate-aware allocation: keep the surface command's change per fast step reachable.

    delta (rad, after ``allocate``) moves from the last command x[X_DCMD:] by at most
    step = ALLOC_RATE x ACT_RATE x dt on every surface: if a surface asks for more, the whole
    change vector is scaled by step / max_i |delta_i - delta_prev_i|, so the change of moment
    G (delta - delta_prev) keeps its direction (with three surfaces and three moments there is
    nothing to redistribute to; per-surface rate clipping in the actuators would turn it). The
    moment not delivered this step is added to the unallocated moment (in the allocation's
    terms: Eq. 47 undone, as ``allocate`` reports it). Off (ALLOC_RATE 0) under PAPER_LITERAL.
    Writes delta in place and st[S_ALLOC_RATE] (the scale, 1 = not limited); returns it.
    """
    fr = par[P_ALLOC_RATE]
    st[S_ALLOC_RATE] = 1.0
    if not fr > 0.0 or switch_on(par, P_PAPER_LITERAL):
        return 1.0
    step_rad = fr * par[P_ACT_RATE] * dt
    c0 = delta[0] - x[X_DCMD]
    c1 = delta[1] - x[X_DCMD + 1]
    c2 = delta[2] - x[X_DCMD + 2]
    big = max(abs(c0), max(abs(c1), abs(c2)))
    if not big > step_rad:
        return 1.0
    s = step_rad / big
    delta[0] = x[X_DCMD] + s * c0
    delta[1] = x[X_DCMD + 1] + s * c1
    delta[2] = x[X_DCMD + 2] + s * c2
    # the change not made, back in the allocation's variables u (Eq. 47 undone)
    r0 = (1.0 - s) * c0
    r1 = (1.0 - s) * c1
    r2 = (1.0 - s) * c2
    if switch_on(par, P_CO_ENABLE):
        surf = option(par, P_CO_SURF)
        if surf == SURF_INTERCONNECT:
            r1 = r1 - e_coup * r2
        elif surf == SURF_LITERAL:
            r1 = 0.0                      # the right elevon follows the rudder
    m0, m1, m2 = matvec3(nm, NM_GCO, r0, r1, r2)
    st[S_M_UNALLOC] += m0
    st[S_M_UNALLOC + 1] += m1
    st[S_M_UNALLOC + 2] += m2
    st[S_ALLOC_RATE] = s
    return s


@njit(cache=True, error_model="numpy")
def actuator_model_step(par, x, delta_cmd, dt):
    """The controller's model of the actuators: position limit, first-order lag, rate limit.

    Advances x[X_DM:X_DM+3] over dt (s) toward delta_cmd (rad).
    """
    limit_rad = par[P_ACT_MAX]
    tau_s = par[P_ACT_TAU]
    step_max_rad = par[P_ACT_RATE] * dt
    a = 1.0 if tau_s <= 0.0 else 1.0 - math.exp(-dt / tau_s)
    for i in range(3):
        target = clip(delta_cmd[i], -limit_rad, limit_rad)
        step = clip(a * (target - x[X_DM + i]), -step_max_rad, step_max_rad)
        x[X_DM + i] = clip(x[X_DM + i] + step, -limit_rad, limit_rad)
