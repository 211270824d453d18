"""Allocation (Eqs. 44-47) with saturation, and the controller's model of the actuators.

    allocate(par, nm, mc0, mc1, mc2, e_coup, delta, st, w_yaw_scale=1.0)
        delta = g_Gamma^-1 M_c (Eq. 46), Eq. 47 surface coordination, position limit
        (ALLOC_MODE: clip each surface, scale the vector, or the prioritised re-solve, whose
        yaw weight is multiplied by w_yaw_scale: the fast loop's yaw escalation); the
        saturation flags and the unallocated moment go to the status record (house style 9).
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

from fc.control.layout import (NM_GCO, NM_GFD, S_ALLOC_RATE, S_ALLOC_SCALE, S_M_UNALLOC, S_SAT,
                               S_SAT_ANY, X_DCMD, X_DM)
from fc.control.linalg3 import clip, matvec3, solve3
from fc.control.options import (ALLOC_PRIO, ALLOC_SCALE, SURF_INTERCONNECT, SURF_LITERAL,
                                option, switch_on)
from fc.control.params import (P_ACT_MAX, P_ACT_RATE, P_ACT_TAU, P_ALLOC_MODE, P_ALLOC_RATE,
                               P_ALLOC_W, P_CO_ENABLE, P_CO_SURF, P_MDL_IXX, P_MDL_IYY,
                               P_MDL_IZZ, P_PAPER_LITERAL)


@njit(cache=True, error_model="numpy")
def prioritised(a, o, e_coup, m0, m1, m2, w0, w1, w2, lim, d0, d1, d2):
    """Prioritised allocation under saturation (ALLOC_MODE 2), in the surfaces d (rad).

    a[o:o+9]: the allocation matrix G (row-major, N m/rad) of the variables u, with u = d
    except u1 = d1 - e_coup d2 (the interconnect of Eq. 47; e_coup 0 when it is off), so the
    columns acting on d are G0, G1, G2 - e_coup G1. m0..m2: the moment to deliver (N m);
    w0..w2: the weights of the axes' shortfalls (per (N m)^2; the caller divides by the
    inertias squared, so that a shortfall is weighed as angular acceleration); d0..d2: the
    unconstrained solution. While a free surface is beyond +-lim, the one furthest beyond is
    held at its limit and the free ones re-solved: min sum_i w_i (sum_j G_ij d_j - m_i)^2
    (a redistributed weighted pseudo-inverse). Returns the surfaces, each within +-lim.
    Scalars only (no array is created).
    """
    c00 = a[o]
    c10 = a[o + 3]
    c20 = a[o + 6]
    c01 = a[o + 1]
    c11 = a[o + 4]
    c21 = a[o + 7]
    c02 = a[o + 2] - e_coup * c01
    c12 = a[o + 5] - e_coup * c11
    c22 = a[o + 8] - e_coup * c21
    f0 = False
    f1 = False
    f2 = False
    for _ in range(3):
        # the free surface furthest beyond its limit
        worst = -1
        big = lim
        if not f0 and abs(d0) > big:
            worst = 0
            big = abs(d0)
        if not f1 and abs(d1) > big:
            worst = 1
            big = abs(d1)
        if not f2 and abs(d2) > big:
            worst = 2
            big = abs(d2)
        if worst < 0:
            break
        if worst == 0:
            d0 = math.copysign(lim, d0)
            f0 = True
        elif worst == 1:
            d1 = math.copysign(lim, d1)
            f1 = True
        else:
            d2 = math.copysign(lim, d2)
            f2 = True
        n_free = (0 if f0 else 1) + (0 if f1 else 1) + (0 if f2 else 1)
        if n_free == 0:
            break
        # the moment left to the free surfaces
        r0 = m0
        r1 = m1
        r2 = m2
        if f0:
            r0 -= c00 * d0
            r1 -= c10 * d0
            r2 -= c20 * d0
        if f1:
            r0 -= c01 * d1
            r1 -= c11 * d1
            r2 -= c21 * d1
        if f2:
            r0 -= c02 * d2
            r1 -= c12 * d2
            r2 -= c22 * d2
        if n_free == 1:
            if not f0:
                x0, x1, x2 = c00, c10, c20
            elif not f1:
                x0, x1, x2 = c01, c11, c21
            else:
                x0, x1, x2 = c02, c12, c22
            den = w0 * x0 * x0 + w1 * x1 * x1 + w2 * x2 * x2
            v = (w0 * x0 * r0 + w1 * x1 * r1 + w2 * x2 * r2) / den if den > 0.0 else 0.0
            if not f0:
                d0 = v
            elif not f1:
                d1 = v
            else:
                d2 = v
            continue
        # two free columns x, y: the 2x2 weighted normal equations
        if f0:
            x0, x1, x2 = c01, c11, c21
            y0, y1, y2 = c02, c12, c22
        elif f1:
            x0, x1, x2 = c00, c10, c20
            y0, y1, y2 = c02, c12, c22
        else:
            x0, x1, x2 = c00, c10, c20
            y0, y1, y2 = c01, c11, c21
        axx = w0 * x0 * x0 + w1 * x1 * x1 + w2 * x2 * x2
        axy = w0 * x0 * y0 + w1 * x1 * y1 + w2 * x2 * y2
        ayy = w0 * y0 * y0 + w1 * y1 * y1 + w2 * y2 * y2
        bx = w0 * x0 * r0 + w1 * x1 * r1 + w2 * x2 * r2
        by = w0 * y0 * r0 + w1 * y1 * r1 + w2 * y2 * r2
        det = axx * ayy - axy * axy
        if abs(det) > 0.0:
            vx = (ayy * bx - axy * by) / det
            vy = (axx * by - axy * bx) / det
        else:
            vx = 0.0
            vy = 0.0
        if f0:
            d1 = vx
            d2 = vy
        elif f1:
            d0 = vx
            d2 = vy
        else:
            d0 = vx
            d1 = vy
    return clip(d0, -lim, lim), clip(d1, -lim, lim), clip(d2, -lim, lim)


@njit(cache=True, error_model="numpy")
def allocate(par, nm, mc0, mc1, mc2, e_coup, delta, st, w_yaw_scale=1.0):
    """delta = g_Gamma^-1 M_c (Eq. 46), Eq. 47 surface coordination, position saturation.

    mc0..mc2: M_c (N m); e_coup: the coupling degree E of Eq. 15; w_yaw_scale: factor on
    ALLOC_W_YAW in the prioritised re-solve (>= 1, the fast loop's escalation; 1 = the
    parameter's weight). Writes delta[0:3] (rad),
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
    mode = option(par, P_ALLOC_MODE)
    literal = switch_on(par, P_PAPER_LITERAL)
    if big > limit_rad:
        sat_any = 1.0
        e_int = 0.0
        if switch_on(par, P_CO_ENABLE) and option(par, P_CO_SURF) == SURF_INTERCONNECT:
            e_int = e_coup
        prio = (mode == ALLOC_PRIO and not literal
                and not (switch_on(par, P_CO_ENABLE) and option(par, P_CO_SURF) == SURF_LITERAL))
        if prio:
            # prioritised: hold the worst surface at its limit, re-solve the others
            ixx = par[P_MDL_IXX]
            iyy = par[P_MDL_IYY]
            izz = par[P_MDL_IZZ]
            # the re-solve delivers the loops' moment M_c in the physical effectiveness
            # g_f_delta: with the surfaces short, the coordinated matrix's reshaping
            # (g_Gamma = g_f_delta + the factors, Eq. 45) is not kept (docs/control_law.md
            # s. 13: it let alpha overshoot 11-34 % at Mach 12-14 / 24-27 km)
            d0, d1, d2 = prioritised(nm, NM_GFD, e_int, mc0, mc1, mc2,
                                     par[P_ALLOC_W] / (ixx * ixx),
                                     par[P_ALLOC_W + 1] / (iyy * iyy),
                                     w_yaw_scale * par[P_ALLOC_W + 2] / (izz * izz), limit_rad,
                                     d0, d1, d2)
            u0 = d0
            u1 = d1 - e_int * d2
            u2 = d2
            scale = 1.0             # (as clipping: no common scale)
        elif mode == ALLOC_SCALE and not literal:
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
