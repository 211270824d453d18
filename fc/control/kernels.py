"""The control law's numba kernels: slow loop, fast loop, observer, factors, allocation.

Paper: Mu, Wang, Wu, Ying, "Robust Coordinated Control for a Type of Hypersonic Aircraft",
Trans. NUAA 35(6) 2018. docs/control_law.md maps every equation to the function below and lists
the decisions taken where the paper is garbled or silent.

All kernels work in place on flat float64 arrays (layouts in fc/control/layout.py, parameter
slots in fc/control/params.py) and allocate nothing:

    slow_kernel(est, cmd, dt_s, par, x, nm, st, tab, atm, grid)
        reference prefilter, Eq. 27 sliding surface, Eq. 29 virtual rate command omega_c
        (with its limit), Eq. 30 adaptive law for theta_Omega.
    fast_kernel(est, dt_s, par, x, nm, st, tab, atm, grid, delta_out)
        input filters (rates; the slow loop's angles), command filter (omega_c,
        omega_c_dot), Eq. 35 moment command M_c, Eq. 36 adaptive law
        for theta_omega, Eqs. 13/14/19 factors, Eqs. 44-47 coordinated allocation with
        saturation, the controller's actuator model and the Eq. 37 disturbance observer.
    reset_kernel(est, par, x, st, delta0)
    cycle_kernel(est, cmd, dt_slow, dt_fast, n_fast, par, x, nm, st, tab, atm, grid, delta)
        one slow step then n_fast fast steps.

Packed entry points (the fc's per-tick path, fc.control.law.AttitudeLaw): the same kernels
on views of one array, so that a call from Python unboxes 2 arrays instead of 10 (numba's
dispatch costs 40-80 ns per array argument; the fast loop's arithmetic is ~0.45 us):

    mem : float64[MEM_TABLES + tables]   par | x | nm | st | delta | cmd at MEM_PAR, MEM_X,
          ..., then the law's copy of pack_tables(tab, atm, grid) at MEM_TABLES
    slow_entry(est, cmd_rad, dt_s, mem)     copies cmd_rad to mem[MEM_CMD:], slow step
    fast_entry(est, dt_s, mem)              fast step, delta into mem[MEM_DELTA:]
    cycle_entry(est, cmd_rad, dt_slow_s, dt_fast_s, mem)   slow then one fast step

Conventions: Omega = [alpha, beta, mu] (rad), omega = [p, q, r] (rad/s), surfaces
[left elevon, right elevon, rudder] (rad), moments [l, m, n] (N m).
"""
from __future__ import annotations

import math

from numba import njit

import numpy as np

from fc.control.layout import (
    ATM_N, G_N, G_NALPHA, G_NH, G_NMACH, NM_N, S_N, T_N, X_N,
    E_N, E_ALPHA, E_BETA, E_GAMMA, E_MU, E_P, E_Q, E_R, E_V,
    NM_E, NM_G, NM_GCO, NM_GFD, NM_MACH, NM_PSI, NM_QBAR, NM_XI,
    S_ALLOC_SCALE, S_CO_FALLBACK, S_D_HAT, S_DELTA_CMD, S_DELTA_MODEL, S_E1, S_E2,
    S_E_COUP, S_FROZEN, S_LAMBDA, S_M_C, S_M_UNALLOC, S_MACH, S_OMC_LIM, S_OMEGA_C,
    S_OMEGA_CF, S_OMEGA_REF, S_QBAR, S_RHO_F, S_RHO_S, S_SAT, S_SAT_ANY, S_SIGMA, S_XI, S_INPUT_BAD,
    TH_F_N, TH_F_PITCH, TH_F_YAW, TH_S_N,
    X_CF, X_CF_DOT, X_DCMD, X_DM, X_INT_E1, X_LIM, X_OMC, X_PF, X_PF_DOT, X_RHO_F,
    X_RHO_S, X_SAT, X_SIGMA, X_XI, X_Z, X_AF1, X_AF2, X_WF1, X_WF2, X_EF, X_FF1, X_FF2,
)
from fc.control.nominal import B_REF_M, C_REF_M, S_REF_M2, V_MIN_M_S, COS_MIN, eval_model
from fc.control.params import (
    P_ACT_MAX, P_ACT_RATE, P_ACT_TAU, P_ALLOC_MODE, P_CO_DALPHA, P_CO_DET_MIN, P_CO_E,
    P_CO_ENABLE, P_CO_FAC_EQ, P_CO_K1, P_CO_LAM_MAX, P_CO_NORM, P_CO_SURF, P_DOB_ACHIEVED,
    P_DOB_C, P_DOB_ENABLE, P_FST_CF_WN, P_FST_CF_ZETA, P_FST_GAMMA, P_FST_KAPPA, P_FST_LEAK,
    P_FST_TH_BND, P_MDL_IXX, P_MDL_IYY, P_MDL_IZZ, P_PAPER_LITERAL, P_REF_PF_EN, P_REF_PF_WN,
    P_REF_PF_ZETA, P_SLW_AW, P_SLW_GAMMA, P_SLW_K1, P_SLW_KAPPA, P_SLW_LEAK, P_SLW_OMC_MAX,
    P_SLW_TH_BND, P_SLW_CFB, P_FLT_RATE_HZ, P_FLT_ANG_HZ, P_CO_MAP, P_N,
)

PI = math.pi


@njit(cache=True, inline="always", error_model="numpy")
def wrap_pi(a):
    """Angle wrapped into [-pi, pi)."""
    return (a + PI) % (2.0 * PI) - PI


@njit(cache=True, inline="always", error_model="numpy")
def clip(v, lo, hi):
    if v < lo:
        return lo
    if v > hi:
        return hi
    return v


# ---------------------------------------------------------------------------------------------
# 3x3 helpers on flat row-major storage a[off : off + 9]
# ---------------------------------------------------------------------------------------------
@njit(cache=True, inline="always", error_model="numpy")
def det3(a, o):
    return (a[o] * (a[o + 4] * a[o + 8] - a[o + 5] * a[o + 7])
            - a[o + 1] * (a[o + 3] * a[o + 8] - a[o + 5] * a[o + 6])
            + a[o + 2] * (a[o + 3] * a[o + 7] - a[o + 4] * a[o + 6]))


@njit(cache=True, error_model="numpy")
def solve3(a, o, b0, b1, b2, out, oo):
    """Solve A u = b for the 3x3 A = a[o:o+9] (row-major) by cofactors; writes out[oo:oo+3].

    Returns det(A); the caller guarantees it is not 0.
    """
    c00 = a[o + 4] * a[o + 8] - a[o + 5] * a[o + 7]
    c01 = a[o + 5] * a[o + 6] - a[o + 3] * a[o + 8]
    c02 = a[o + 3] * a[o + 7] - a[o + 4] * a[o + 6]
    det = a[o] * c00 + a[o + 1] * c01 + a[o + 2] * c02
    inv = 1.0 / det
    c10 = a[o + 2] * a[o + 7] - a[o + 1] * a[o + 8]
    c11 = a[o] * a[o + 8] - a[o + 2] * a[o + 6]
    c12 = a[o + 1] * a[o + 6] - a[o] * a[o + 7]
    c20 = a[o + 1] * a[o + 5] - a[o + 2] * a[o + 4]
    c21 = a[o + 2] * a[o + 3] - a[o] * a[o + 5]
    c22 = a[o] * a[o + 4] - a[o + 1] * a[o + 3]
    # inverse = adjugate / det, adjugate = cofactor matrix transposed
    out[oo] = (c00 * b0 + c10 * b1 + c20 * b2) * inv
    out[oo + 1] = (c01 * b0 + c11 * b1 + c21 * b2) * inv
    out[oo + 2] = (c02 * b0 + c12 * b1 + c22 * b2) * inv
    return det


# ---------------------------------------------------------------------------------------------
# Eq. 3: g_s and its inverse (det g_s = -sec(beta))
# ---------------------------------------------------------------------------------------------
@njit(cache=True, error_model="numpy")
def gs_inv_apply(alpha, beta, v0, v1, v2, out, o):
    """out[o:o+3] = g_s^-1 v, with g_s^-1 = [[0, sa, ca cb], [1, 0, sb], [0, -ca, sa cb]]."""
    sa = math.sin(alpha)
    ca = math.cos(alpha)
    sb = math.sin(beta)
    cb = math.cos(beta)
    out[o] = sa * v1 + ca * cb * v2
    out[o + 1] = v0 + sb * v2
    out[o + 2] = -ca * v1 + sa * cb * v2


@njit(cache=True, error_model="numpy")
def gs_apply(alpha, beta, w0, w1, w2, out, o):
    """out[o:o+3] = g_s w (Eq. 3)."""
    sa = math.sin(alpha)
    ca = math.cos(alpha)
    cb = max(math.cos(beta), COS_MIN)
    tb = math.sin(beta) / cb
    out[o] = -ca * tb * w0 + w1 - sa * tb * w2
    out[o + 1] = sa * w0 - ca * w2
    out[o + 2] = (ca * w0 + sa * w2) / cb


@njit(cache=True, error_model="numpy")
def gs_t_apply(alpha, beta, s0, s1, s2, out, o):
    """out[o:o+3] = g_s^T s (g_s of Eq. 3), the cross term of Eq. 35."""
    sa = math.sin(alpha)
    ca = math.cos(alpha)
    cb = max(math.cos(beta), COS_MIN)
    tb = math.sin(beta) / cb
    out[o] = -ca * tb * s0 + sa * s1 + ca / cb * s2
    out[o + 1] = s0
    out[o + 2] = -sa * tb * s0 - ca * s1 + sa / cb * s2


# ---------------------------------------------------------------------------------------------
# Reference prefilter and command filter (the paper leaves Omega_c_dot, omega_c_dot undefined)
# ---------------------------------------------------------------------------------------------
@njit(cache=True, error_model="numpy")
def second_order_phi(dt, wn, zeta):
    """State-transition matrix (phi11, phi12, phi21, phi22) of y'' = -wn^2 y - 2 zeta wn y'
    over dt: the exact (zero-order-hold) discretisation of the 2nd-order filters, stable and
    accurate for any wn dt (a 25 Hz loop with wn 40 rad/s included)."""
    sg = zeta * wn
    E = math.exp(-sg * dt)
    d = 1.0 - zeta * zeta
    if abs(d) < 1e-6:                       # critically damped
        return (E * (1.0 + wn * dt), E * dt, -E * wn * wn * dt, E * (1.0 - wn * dt))
    if d > 0.0:                             # under-damped
        wd = wn * math.sqrt(d)
        c = math.cos(wd * dt)
        sn = math.sin(wd * dt)
    else:                                   # over-damped
        wd = wn * math.sqrt(-d)
        c = math.cosh(wd * dt)
        sn = math.sinh(wd * dt)
    return (E * (c + sg / wd * sn), E * sn / wd, -E * wn * wn / wd * sn,
            E * (c - sg / wd * sn))


@njit(cache=True, error_model="numpy")
def second_order_step(u, phi, x, ix, ixd):
    """One exact step of y'' = wn^2 (u - y) - 2 zeta wn y' (u held) on x[ix], x[ixd]."""
    e = x[ix] - u
    v = x[ixd]
    x[ix] = u + phi[0] * e + phi[1] * v
    x[ixd] = phi[2] * e + phi[3] * v


# ---------------------------------------------------------------------------------------------
# Input filters (deviation: the paper assumes noise-free measurements)
# ---------------------------------------------------------------------------------------------
@njit(cache=True, error_model="numpy")
def lowpass2_step(u, dt, fc_hz, x, i1, i2, wrap):
    """Two exact-discretised 1st-order low-pass sections at ``fc_hz`` (stable for any dt).

    Updates x[i1], x[i2] toward u and returns the output x[i2]; ``fc_hz`` <= 0 passes u
    through (and keeps the states on it). ``wrap``: the signal is an angle taken modulo 2 pi.
    """
    if fc_hz <= 0.0:
        x[i1] = u
        x[i2] = u
        return u
    a = 1.0 - math.exp(-2.0 * PI * fc_hz * dt)
    if wrap:
        x[i1] = wrap_pi(x[i1] + a * wrap_pi(u - x[i1]))
        x[i2] = wrap_pi(x[i2] + a * wrap_pi(x[i1] - x[i2]))
    else:
        x[i1] += a * (u - x[i1])
        x[i2] += a * (x[i1] - x[i2])
    return x[i2]


# ---------------------------------------------------------------------------------------------
# Slow loop (Eqs. 26-30)
# ---------------------------------------------------------------------------------------------
@njit(cache=True, error_model="numpy")
def input_ok(est, dt):
    """True if every entry of est is finite and 0 < dt <= 1 s (else the step is skipped)."""
    if not (dt > 0.0 and dt <= 1.0):
        return False
    for i in range(E_N):
        if not math.isfinite(est[i]):
            return False
    return True


@njit(cache=True, error_model="numpy")
def slow_kernel(est, cmd, dt, par, x, nm, st, tab, atm, grid):
    """Slow loop: Omega_c shaping, sigma (Eq. 27), omega_c (Eq. 29), theta_Omega (Eq. 30).

    A non-finite est or cmd, or dt outside (0, 1] s, leaves every state untouched and sets
    st[S_INPUT_BAD] (the fast loop keeps flying the last omega_c).
    """
    if not (input_ok(est, dt) and math.isfinite(cmd[0]) and math.isfinite(cmd[1])
            and math.isfinite(cmd[2])):
        st[S_INPUT_BAD] = 1.0
        return
    st[S_INPUT_BAD] = 0.0
    eval_model(est, par, tab, atm, grid, nm)
    literal = par[P_PAPER_LITERAL] > 0.5
    alpha = est[E_ALPHA]
    beta = est[E_BETA]
    mu = est[E_MU]
    V = max(est[E_V], V_MIN_M_S)
    gam = est[E_GAMMA]

    # reference: prefiltered command (Omega_c, Omega_c_dot) or the paper's steps
    if par[P_REF_PF_EN] > 0.5 and not literal:
        phi = second_order_phi(dt, par[P_REF_PF_WN], par[P_REF_PF_ZETA])
        second_order_step(cmd[0], phi, x, X_PF, X_PF_DOT)
        second_order_step(cmd[1], phi, x, X_PF + 1, X_PF_DOT + 1)
        # bank: filter toward the command taken the short way round
        u_mu = x[X_PF + 2] + wrap_pi(cmd[2] - x[X_PF + 2])
        second_order_step(u_mu, phi, x, X_PF + 2, X_PF_DOT + 2)
    else:
        for i in range(3):
            x[X_PF + i] = cmd[i]
            x[X_PF_DOT + i] = 0.0

    # e1 = Omega - Omega_c; with FLT_ANG_HZ > 0, Omega is the output of the input filter that
    # the fast loop runs at its own (higher) rate, so the noise is filtered before the slow
    # loop samples it
    if par[P_FLT_ANG_HZ] > 0.0 and not literal:
        af = x[X_AF2]
        bf = x[X_AF2 + 1]
        mf = x[X_AF2 + 2]
    else:
        af = alpha
        bf = beta
        mf = mu
    e1a = af - x[X_PF]
    e1b = bf - x[X_PF + 1]
    e1m = wrap_pi(mf - x[X_PF + 2])

    # Eq. 27: sigma = e1 + K int(e1) dt, integral frozen while limited / saturated
    freeze = (par[P_SLW_AW] > 0.5 and not literal) and (x[X_SAT] > 0.5 or x[X_LIM] > 0.5)
    if not freeze:
        x[X_INT_E1] += e1a * dt
        x[X_INT_E1 + 1] += e1b * dt
        x[X_INT_E1 + 2] += e1m * dt
    k1 = par[P_SLW_K1]
    k2 = par[P_SLW_K1 + 1]
    k3 = par[P_SLW_K1 + 2]
    sa_ = e1a + k1 * x[X_INT_E1]
    sb_ = e1b + k2 * x[X_INT_E1 + 1]
    sm_ = e1m + k3 * x[X_INT_E1 + 2]

    # Eq. 26: f1
    g = nm[NM_G]
    cb = max(math.cos(beta), COS_MIN)
    cgam = math.cos(gam)
    f1a = g * cgam * math.cos(mu) / (V * cb)
    f1b = g * cgam * math.sin(mu) / V
    f1m = -g * cgam * math.cos(mu) * math.sin(beta) / (cb * V)

    # Psi^T theta_hat_Omega, theta_hat_i = theta_nom_i (1 + rho_i) (Eq. 23 rows alpha, beta, mu)
    pa = nm[NM_PSI] * (1.0 + x[X_RHO_S])
    pb = nm[NM_PSI + 1] * (1.0 + x[X_RHO_S + 1])
    pm = nm[NM_PSI + 2] * (1.0 + x[X_RHO_S + 2]) + nm[NM_PSI + 3] * (1.0 + x[X_RHO_S + 3])

    # Eq. 29 (Omega_c_dot where the OCR prints Omega_c):
    # omega_c = -g_s^-1 (kappa1 sigma + f1 + Psi^T theta_hat - Omega_c_dot + K e1)
    kap = par[P_SLW_KAPPA]
    v0 = -(kap * sa_ + f1a + pa - x[X_PF_DOT] + k1 * e1a)
    v1 = -(kap * sb_ + f1b + pb - x[X_PF_DOT + 1] + k2 * e1b)
    v2 = -(kap * sm_ + f1m + pm - x[X_PF_DOT + 2] + k3 * e1m)
    gs_inv_apply(alpha, beta, v0, v1, v2, x, X_OMC)

    # limit on omega_c (deviation, SLW_OMC_MAX): scale the vector, keep its direction
    lim = par[P_SLW_OMC_MAX]
    limited = 0.0
    s = 1.0
    if lim > 0.0 and not literal:
        big = max(abs(x[X_OMC]), max(abs(x[X_OMC + 1]), abs(x[X_OMC + 2])))
        if big > lim:
            s = lim / big
            limited = 1.0
    # command-filtered backstepping compensation (deviation, SLW_CFB):
    # sigma_bar = sigma - xi, xi_dot = -kappa1 xi + g_s (omega_c_lim - omega_c)
    cfb = par[P_SLW_CFB] > 0.5 and not literal
    if cfb:
        sa_b = sa_ - x[X_XI]
        sb_b = sb_ - x[X_XI + 1]
        sm_b = sm_ - x[X_XI + 2]
    else:
        sa_b = sa_
        sb_b = sb_
        sm_b = sm_
    if cfb:
        dp_ = (s - 1.0) * x[X_OMC]
        dq_ = (s - 1.0) * x[X_OMC + 1]
        dr_ = (s - 1.0) * x[X_OMC + 2]
        gs_apply(alpha, beta, dp_, dq_, dr_, st, S_XI)
        if kap > 0.0:
            ek = math.exp(-kap * dt)
            gk = (1.0 - ek) / kap
        else:
            ek = 1.0
            gk = dt
        for i in range(3):
            x[X_XI + i] = ek * x[X_XI + i] + gk * st[S_XI + i]
    else:
        for i in range(3):
            x[X_XI + i] = 0.0
    if limited > 0.5:
        x[X_OMC] *= s
        x[X_OMC + 1] *= s
        x[X_OMC + 2] *= s
    x[X_LIM] = limited
    x[X_SIGMA] = sa_b
    x[X_SIGMA + 1] = sb_b
    x[X_SIGMA + 2] = sm_b

    # Eq. 30: rho_Omega_dot = Gamma1 (Psi sigma - lambda_Omega rho), projected onto the box
    freeze = freeze or ((par[P_SLW_AW] > 0.5 and not literal) and limited > 0.5)
    gam1 = par[P_SLW_GAMMA]
    if gam1 > 0.0 and not freeze:
        leak = par[P_SLW_LEAK]
        bnd = par[P_SLW_TH_BND]
        for i in range(TH_S_N):
            srow = sa_b if i == 0 else (sb_b if i == 1 else sm_b)
            r = x[X_RHO_S + i] + dt * gam1 * (nm[NM_PSI + i] * srow - leak * x[X_RHO_S + i])
            x[X_RHO_S + i] = clip(r, -bnd, bnd)

    # status
    st[S_SIGMA] = sa_
    st[S_SIGMA + 1] = sb_
    st[S_SIGMA + 2] = sm_
    st[S_E1] = e1a
    st[S_E1 + 1] = e1b
    st[S_E1 + 2] = e1m
    for i in range(3):
        st[S_OMEGA_C + i] = x[X_OMC + i]
        st[S_OMEGA_REF + i] = x[X_PF + i]
    for i in range(3):
        st[S_XI + i] = x[X_XI + i]
    st[S_OMC_LIM] = limited
    st[S_FROZEN] = 1.0 if freeze else 0.0
    for i in range(TH_S_N):
        st[S_RHO_S + i] = x[X_RHO_S + i]
    st[S_MACH] = nm[NM_MACH]
    st[S_QBAR] = nm[NM_QBAR]


# ---------------------------------------------------------------------------------------------
# Coordinated factors (Eqs. 10-14, 19)
# ---------------------------------------------------------------------------------------------
@njit(cache=True, error_model="numpy")
def coordinated_factors(est, par, out, o):
    """lambda_e, lambda_a, lambda_r into out[o:o+3] (0 when CO_ENABLE = 0)."""
    if par[P_CO_ENABLE] < 0.5:
        out[o] = 0.0
        out[o + 1] = 0.0
        out[o + 2] = 0.0
        return
    alpha = est[E_ALPHA]
    beta = est[E_BETA]
    p = est[E_P]
    q = est[E_Q]
    r = est[E_R]
    k = P_CO_K1 - 1          # par[k + i] is k_i
    sa = math.sin(alpha)
    ca = math.cos(alpha)
    # Eq. 10: lambda_r1 = k1 p tan(alpha)
    lr1 = par[k + 1] * p * sa / ca
    # Eq. 12: lambda_r2 = k2 beta + k3 p (1 - cos alpha) / (sin alpha + Delta_alpha)
    den = sa + par[P_CO_DALPHA]
    if abs(den) < 1e-6:
        den = 1e-6 if den >= 0.0 else -1e-6
    lr2 = par[k + 2] * beta + par[k + 3] * p * (1.0 - ca) / den
    # Eq. 14: lambda_r3 = k8 beta + k9 q
    lr3 = par[k + 8] * beta + par[k + 9] * q
    if par[P_CO_FAC_EQ] > 16.5:
        # Eq. 19 (default: the factors Section 4.3 builds g_Gamma from)
        le = par[k + 4] * alpha + par[k + 5] * q
        la = par[k + 6] * beta + par[k + 7] * p
    else:
        # Eq. 14 (the prose before it)
        le = par[k + 4] * alpha + par[k + 5] * p
        la = par[k + 6] * beta + par[k + 7] * r
    # Eq. 13 + Eq. 19: lambda_r = lambda_r1 + lambda_r2 + lambda_r3
    lr = lr1 + lr2 + lr3
    lmax = par[P_CO_LAM_MAX]
    if lmax > 0.0 and par[P_PAPER_LITERAL] < 0.5:
        le = clip(le, -lmax, lmax)
        la = clip(la, -lmax, lmax)
        lr = clip(lr, -lmax, lmax)
    out[o] = le
    out[o + 1] = la
    out[o + 2] = lr


@njit(cache=True, error_model="numpy")
def coordinated_matrix(par, nm, lam, lo):
    """Eq. 45: g_Gamma = g_f_delta + diag(lambda) (normalised per CO_NORM) into nm[NM_GCO].

    Returns 1.0 if the guard rejected it (then g_Gamma = g_f_delta), else 0.0. Guard (off
    with PAPER_LITERAL, which only rejects an exactly singular matrix): det(g_Gamma) /
    det(g_f_delta) >= CO_DET_MIN and g_Gamma_ii / g_f_delta_ii >= CO_DET_MIN for each i.
    """
    for i in range(9):
        nm[NM_GCO + i] = nm[NM_GFD + i]
    norm = int(par[P_CO_NORM] + 0.5)
    qS = nm[NM_QBAR] * S_REF_M2
    if par[P_CO_MAP] > 0.5:
        # the loops the prose names: aileron -> roll row, elevator -> pitch row,
        # rudder -> yaw row, each scaled by (1 + lambda)
        for j in range(3):
            nm[NM_GCO + j] *= 1.0 + lam[lo + 1]
            nm[NM_GCO + 3 + j] *= 1.0 + lam[lo]
            nm[NM_GCO + 6 + j] *= 1.0 + lam[lo + 2]
        norm = -1
    for i in range(3):
        d = NM_GCO + 4 * i
        if norm == -1:
            pass
        elif norm == 0:
            nm[d] += lam[lo + i] * nm[NM_GFD + 4 * i]
        elif norm == 1:
            lref = C_REF_M if i == 1 else B_REF_M
            nm[d] += lam[lo + i] * qS * lref
        else:
            nm[d] += lam[lo + i]
    det_g = det3(nm, NM_GFD)
    det_c = det3(nm, NM_GCO)
    if not abs(det_g) > 0.0:
        ok = False
    elif par[P_PAPER_LITERAL] > 0.5:
        ok = abs(det_c) > 1e-9 * abs(det_g)
    else:
        # accept only if det keeps its sign and size, and no diagonal entry flips or vanishes
        dmin = par[P_CO_DET_MIN]
        ok = det_c / det_g >= dmin
        for i in range(3):
            d = 4 * i
            ok = ok and nm[NM_GCO + d] / nm[NM_GFD + d] >= dmin
    if not ok:
        for i in range(9):
            nm[NM_GCO + i] = nm[NM_GFD + i]
        return 1.0
    return 0.0


# ---------------------------------------------------------------------------------------------
# Allocation (Eqs. 44-47) with saturation
# ---------------------------------------------------------------------------------------------
@njit(cache=True, error_model="numpy")
def allocate(par, nm, mc0, mc1, mc2, e_coup, delta, st):
    """delta = g_Gamma^-1 M_c (Eq. 46), Eq. 47 surface coordination, position saturation.

    Writes delta[0:3] (rad), the saturation flags and the unallocated moment into st;
    returns 1.0 if any surface was requested beyond its limit.
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
    d0 = delta[0]
    d1 = delta[1]
    d2 = delta[2]
    # Eq. 47: delta_a (right elevon) coordinated with the rudder through E
    if par[P_CO_ENABLE] > 0.5:
        mode = int(par[P_CO_SURF] + 0.5)
        if mode == 1:
            d1 = d1 + e_coup * d2          # interconnect: delta_a_out = delta_a + E delta_r
        elif mode == 2:
            d1 = e_coup * d2               # literal: delta_coa = E delta_r
    lim = par[P_ACT_MAX]
    big = max(abs(d0), max(abs(d1), abs(d2)))
    sat_any = 0.0
    st[S_SAT] = 1.0 if abs(d0) > lim else 0.0
    st[S_SAT + 1] = 1.0 if abs(d1) > lim else 0.0
    st[S_SAT + 2] = 1.0 if abs(d2) > lim else 0.0
    scale = 1.0
    if big > lim:
        sat_any = 1.0
        if par[P_ALLOC_MODE] > 0.5 and par[P_PAPER_LITERAL] < 0.5:
            # direction-preserving: scale the whole vector (the moment keeps its direction)
            scale = lim / big
            d0 *= scale
            d1 *= scale
            d2 *= scale
            ua = delta[0] * scale
            ub = delta[1] * scale
            uc = delta[2] * scale
        else:
            # clip each surface (the printed paper)
            d0 = clip(d0, -lim, lim)
            d1 = clip(d1, -lim, lim)
            d2 = clip(d2, -lim, lim)
            ua = clip(delta[0], -lim, lim)
            ub = clip(delta[1], -lim, lim)
            uc = clip(delta[2], -lim, lim)
    else:
        ua = delta[0]
        ub = delta[1]
        uc = delta[2]
    # unallocated moment (in the coordinated matrix's terms)
    g = NM_GCO
    st[S_M_UNALLOC] = mc0 - (nm[g] * ua + nm[g + 1] * ub + nm[g + 2] * uc)
    st[S_M_UNALLOC + 1] = mc1 - (nm[g + 3] * ua + nm[g + 4] * ub + nm[g + 5] * uc)
    st[S_M_UNALLOC + 2] = mc2 - (nm[g + 6] * ua + nm[g + 7] * ub + nm[g + 8] * uc)
    st[S_ALLOC_SCALE] = scale
    st[S_SAT_ANY] = sat_any
    delta[0] = d0
    delta[1] = d1
    delta[2] = d2
    return sat_any


@njit(cache=True, error_model="numpy")
def actuator_model_step(par, x, delta_cmd, dt):
    """The controller's model of the actuators: position limit, first-order lag, rate limit.

    Advances x[X_DM:X_DM+3] over dt toward delta_cmd (rad).
    """
    lim = par[P_ACT_MAX]
    tau = par[P_ACT_TAU]
    rmax = par[P_ACT_RATE] * dt
    a = 1.0 if tau <= 0.0 else 1.0 - math.exp(-dt / tau)
    for i in range(3):
        tgt = clip(delta_cmd[i], -lim, lim)
        step = clip(a * (tgt - x[X_DM + i]), -rmax, rmax)
        x[X_DM + i] = clip(x[X_DM + i] + step, -lim, lim)


# ---------------------------------------------------------------------------------------------
# Disturbance observer (Eq. 37, after the paper's Ref. 33)
# ---------------------------------------------------------------------------------------------
@njit(cache=True, inline="always", error_model="numpy")
def dob_gain(c, dt):
    """Discrete observer gain c_d = (1 - exp(-c dt)) / dt (-> c as dt -> 0).

    With Q = c_d omega the discrete observer below is exactly a first-order filter of
    bandwidth c on the finite-difference measurement of d, stable for any c dt.
    """
    return (1.0 - math.exp(-c * dt)) / dt


@njit(cache=True, inline="always", error_model="numpy")
def dob_estimate(x, c_d, w0, w1, w2):
    """Eq. 37: d_hat = z + Q(omega), Q = c_d omega (rad/s^2 per axis)."""
    return x[X_Z] + c_d * w0, x[X_Z + 1] + c_d * w1, x[X_Z + 2] + c_d * w2


@njit(cache=True, error_model="numpy")
def dob_update(x, c_d, dt, f0, f1, f2, w0, w1, w2):
    """Eq. 37: z_dot = -L z - L (f + Q(omega)), L = c I, over one step of dt.

    f = Xi^T theta_hat + g_f M is the modelled angular acceleration (rad/s^2) without the
    disturbance over the step. Discretised as z+ = (1 - c_d dt) z - c_d dt (f + c_d omega),
    which gives d_hat+ = e^(-c dt) d_hat + (1 - e^(-c dt)) ((omega+ - omega)/dt - f).
    """
    a = c_d * dt
    x[X_Z] = (1.0 - a) * x[X_Z] - a * (f0 + c_d * w0)
    x[X_Z + 1] = (1.0 - a) * x[X_Z + 1] - a * (f1 + c_d * w1)
    x[X_Z + 2] = (1.0 - a) * x[X_Z + 2] - a * (f2 + c_d * w2)


# ---------------------------------------------------------------------------------------------
# Fast loop (Eqs. 34-37) + factors + allocation
# ---------------------------------------------------------------------------------------------
@njit(cache=True, error_model="numpy")
def fast_kernel(est, dt, par, x, nm, st, tab, atm, grid, delta_out):
    """Fast loop: M_c (Eq. 35), theta_omega (Eq. 36), observer (Eq. 37), allocation (44-47).

    A non-finite est or dt outside (0, 1] s holds the last surface command in delta_out,
    leaves every state untouched and sets st[S_INPUT_BAD].
    """
    if not input_ok(est, dt):
        st[S_INPUT_BAD] = 1.0
        for i in range(3):
            delta_out[i] = x[X_DCMD + i]
        return
    st[S_INPUT_BAD] = 0.0
    literal = par[P_PAPER_LITERAL] > 0.5
    # the fast loop's state: est with p, q, r through the input filter (FLT_RATE_HZ)
    fr = 0.0 if literal else par[P_FLT_RATE_HZ]
    ef = x[X_EF:X_EF + E_N]
    for i in range(E_N):
        ef[i] = est[i]
    for i in range(3):
        ef[E_P + i] = lowpass2_step(est[E_P + i], dt, fr, x, X_WF1 + i, X_WF2 + i, False)
    # the slow loop's angle filter (FLT_ANG_HZ), run here at the fast rate
    fa = 0.0 if literal else par[P_FLT_ANG_HZ]
    lowpass2_step(est[E_ALPHA], dt, fa, x, X_AF1, X_AF2, False)
    lowpass2_step(est[E_BETA], dt, fa, x, X_AF1 + 1, X_AF2 + 1, False)
    lowpass2_step(est[E_MU], dt, fa, x, X_AF1 + 2, X_AF2 + 2, True)
    eval_model(ef, par, tab, atm, grid, nm)
    alpha = ef[E_ALPHA]
    beta = ef[E_BETA]
    p = ef[E_P]
    q = ef[E_Q]
    r = ef[E_R]
    ixx = par[P_MDL_IXX]
    iyy = par[P_MDL_IYY]
    izz = par[P_MDL_IZZ]

    # command filter: omega_c -> (omega_cf, omega_cf_dot)
    phi = second_order_phi(dt, par[P_FST_CF_WN], par[P_FST_CF_ZETA])
    for i in range(3):
        second_order_step(x[X_OMC + i], phi, x, X_CF + i, X_CF_DOT + i)

    # e2 = omega - omega_c
    e2p = p - x[X_CF]
    e2q = q - x[X_CF + 1]
    e2r = r - x[X_CF + 2]

    # Xi^T theta_hat_omega per axis (theta_hat_i = theta_nom_i (1 + rho_i))
    xr = 0.0
    for i in range(0, TH_F_PITCH):
        xr += nm[NM_XI + i] * (1.0 + x[X_RHO_F + i])
    xp = 0.0
    for i in range(TH_F_PITCH, TH_F_YAW):
        xp += nm[NM_XI + i] * (1.0 + x[X_RHO_F + i])
    xy = 0.0
    for i in range(TH_F_YAW, TH_F_N):
        xy += nm[NM_XI + i] * (1.0 + x[X_RHO_F + i])

    # Eq. 37: d_hat = z + Q(e), Q = c omega
    c_d = dob_gain(par[P_DOB_C], dt)
    dob = par[P_DOB_ENABLE] > 0.5
    if dob:
        dp, dq, dr = dob_estimate(x, c_d, p, q, r)
    else:
        dp = 0.0
        dq = 0.0
        dr = 0.0

    # Eq. 35: M_c = -g_f^-1 (kappa2 e2 + Xi^T theta_hat + d_hat + g_s^T sigma - omega_c_dot)
    gs_t_apply(alpha, beta, x[X_SIGMA], x[X_SIGMA + 1], x[X_SIGMA + 2], st, S_E2)
    gtp = st[S_E2]
    gtq = st[S_E2 + 1]
    gtr = st[S_E2 + 2]
    kap = par[P_FST_KAPPA]
    mc0 = -ixx * (kap * e2p + xr + dp + gtp - x[X_CF_DOT])
    mc1 = -iyy * (kap * e2q + xp + dq + gtq - x[X_CF_DOT + 1])
    mc2 = -izz * (kap * e2r + xy + dr + gtr - x[X_CF_DOT + 2])

    # Eqs. 13/14/19 factors, Eq. 45 coordinated matrix, Eqs. 46-47 allocation
    coordinated_factors(ef, par, st, S_LAMBDA)
    fallback = coordinated_matrix(par, nm, st, S_LAMBDA)
    e_coup = par[P_CO_E] if par[P_CO_E] > 0.0 else nm[NM_E]
    sat = allocate(par, nm, mc0, mc1, mc2, e_coup, delta_out, st)
    x[X_SAT] = sat
    for i in range(3):
        x[X_DCMD + i] = delta_out[i]

    # Eq. 37 observer update with the moment that acts over this step: the achieved moment
    # G delta of the modelled actuators (deviation, DOB_ACHIEVED 1: G = g_f_delta, the
    # physical moment; 2: G = g_Gamma, the coordinated moment of Eq. 44) or M_c (printed).
    if par[P_DOB_ACHIEVED] > 0.5 and not literal:
        a0 = x[X_DM]
        a1 = x[X_DM + 1]
        a2 = x[X_DM + 2]
        actuator_model_step(par, x, delta_out, dt)
        a0 = 0.5 * (a0 + x[X_DM])
        a1 = 0.5 * (a1 + x[X_DM + 1])
        a2 = 0.5 * (a2 + x[X_DM + 2])
        g = NM_GCO if par[P_DOB_ACHIEVED] > 1.5 else NM_GFD
        m0 = nm[g] * a0 + nm[g + 1] * a1 + nm[g + 2] * a2
        m1 = nm[g + 3] * a0 + nm[g + 4] * a1 + nm[g + 5] * a2
        m2 = nm[g + 6] * a0 + nm[g + 7] * a1 + nm[g + 8] * a2
    else:
        actuator_model_step(par, x, delta_out, dt)
        m0 = mc0
        m1 = mc1
        m2 = mc2
    if dob:
        # the model acceleration passes through the rates' input filter, so that the
        # observer compares filtered omega with filtered f (a plain DOB Q-filter)
        f0 = lowpass2_step(xr + m0 / ixx, dt, fr, x, X_FF1, X_FF2, False)
        f1 = lowpass2_step(xp + m1 / iyy, dt, fr, x, X_FF1 + 1, X_FF2 + 1, False)
        f2 = lowpass2_step(xy + m2 / izz, dt, fr, x, X_FF1 + 2, X_FF2 + 2, False)
        dob_update(x, c_d, dt, f0, f1, f2, p, q, r)

    # Eq. 36: rho_omega_dot = Gamma2 (Xi e2 - lambda_omega rho), projected onto the box
    freeze = (par[P_SLW_AW] > 0.5 and not literal) and (sat > 0.5 or x[X_LIM] > 0.5)
    gam2 = par[P_FST_GAMMA]
    if gam2 > 0.0 and not freeze:
        leak = par[P_FST_LEAK]
        bnd = par[P_FST_TH_BND]
        for i in range(TH_F_N):
            e = e2p if i < TH_F_PITCH else (e2q if i < TH_F_YAW else e2r)
            rr = x[X_RHO_F + i] + dt * gam2 * (nm[NM_XI + i] * e - leak * x[X_RHO_F + i])
            x[X_RHO_F + i] = clip(rr, -bnd, bnd)

    # status
    st[S_E2] = e2p
    st[S_E2 + 1] = e2q
    st[S_E2 + 2] = e2r
    st[S_OMEGA_CF] = x[X_CF]
    st[S_OMEGA_CF + 1] = x[X_CF + 1]
    st[S_OMEGA_CF + 2] = x[X_CF + 2]
    st[S_M_C] = mc0
    st[S_M_C + 1] = mc1
    st[S_M_C + 2] = mc2
    st[S_D_HAT] = dp
    st[S_D_HAT + 1] = dq
    st[S_D_HAT + 2] = dr
    st[S_E_COUP] = e_coup
    st[S_CO_FALLBACK] = fallback
    for i in range(3):
        st[S_DELTA_CMD + i] = delta_out[i]
        st[S_DELTA_MODEL + i] = x[X_DM + i]
    for i in range(TH_F_N):
        st[S_RHO_F + i] = x[X_RHO_F + i]
    if freeze:
        st[S_FROZEN] = 1.0
    st[S_MACH] = nm[NM_MACH]
    st[S_QBAR] = nm[NM_QBAR]


# ---------------------------------------------------------------------------------------------
# Reset
# ---------------------------------------------------------------------------------------------
@njit(cache=True, error_model="numpy")
def reset_kernel(est, par, x, st, delta0):
    """Start every integrator, filter and estimate at the current estimated state.

    The prefilter starts at the current Omega (so a prefiltered command moves smoothly from
    there), omega_c and its filter at the current omega, the estimates at the nominal model
    (rho = 0), the observer at d_hat = 0 (z = -c omega), the actuator model at ``delta0``.
    """
    for i in range(x.shape[0]):
        x[i] = 0.0
    for i in range(st.shape[0]):
        st[i] = 0.0
    for i in range(3):
        x[X_PF + i] = est[E_ALPHA + i]
        x[X_OMC + i] = est[E_P + i]
        x[X_CF + i] = est[E_P + i]
        x[X_Z + i] = -par[P_DOB_C] * est[E_P + i]
        x[X_DM + i] = delta0[i]
        x[X_DCMD + i] = delta0[i]
        x[X_AF1 + i] = est[E_ALPHA + i]
        x[X_AF2 + i] = est[E_ALPHA + i]
        x[X_WF1 + i] = est[E_P + i]
        x[X_WF2 + i] = est[E_P + i]
    for i in range(E_N):
        x[X_EF + i] = est[i]
    st[S_ALLOC_SCALE] = 1.0


@njit(cache=True, error_model="numpy")
def cycle_kernel(est, cmd, dt_slow, dt_fast, n_fast, par, x, nm, st, tab, atm, grid,
                 delta_out):
    """One slow step followed by ``n_fast`` fast steps (benchmarks, in-numba closed loops)."""
    slow_kernel(est, cmd, dt_slow, par, x, nm, st, tab, atm, grid)
    for _ in range(n_fast):
        fast_kernel(est, dt_fast, par, x, nm, st, tab, atm, grid, delta_out)


# ---------------------------------------------------------------------------------------------
# Packed entry points: one law's arrays as views of one buffer (fewer arguments to unbox)
# ---------------------------------------------------------------------------------------------
MEM_PAR = 0                     # par   float64[P_N]  parameters (SI)
MEM_X = MEM_PAR + P_N           # x     float64[X_N]  internal state
MEM_NM = MEM_X + X_N            # nm    float64[NM_N] nominal model
MEM_ST = MEM_NM + NM_N          # st    float64[S_N]  status
MEM_DELTA = MEM_ST + S_N        # delta float64[3]    surface command (rad)
MEM_CMD = MEM_DELTA + 3         # cmd   float64[3]    last attitude command (rad)
MEM_TABLES = MEM_CMD + 3        # the law's copy of pack_tables: grid | tab | atm


def pack_tables(tab, atm, grid) -> np.ndarray:
    """One float64 array ``grid | tab | atm`` (C order), the tail of a packed ``mem``.

    Allocates; call once per process (fc.control.law does). The shapes come from ``grid``
    (G_NMACH, G_NALPHA, G_NH); ValueError if the arrays disagree with it.
    """
    grid = np.asarray(grid, dtype=np.float64)
    shape_tab = (int(grid[G_NMACH]), int(grid[G_NALPHA]), T_N)
    shape_atm = (int(grid[G_NH]), ATM_N)
    if grid.shape != (G_N,) or tab.shape != shape_tab or atm.shape != shape_atm:
        raise ValueError(f"tables {tab.shape}, {atm.shape}, {grid.shape} disagree with grid "
                         f"{shape_tab}, {shape_atm}, ({G_N},)")
    return np.concatenate((grid, np.ravel(tab), np.ravel(atm))).astype(np.float64)


@njit(cache=True, inline="always", error_model="numpy")
def unpack_tables(mem, o):
    """(tab, atm, grid) views of the pack_tables array at mem[o:] (no copy)."""
    grid = mem[o:o + G_N]
    n_mach = int(grid[G_NMACH])
    n_alpha = int(grid[G_NALPHA])
    n_h = int(grid[G_NH])
    a = o + G_N
    b = a + n_mach * n_alpha * T_N
    tab = mem[a:b].reshape((n_mach, n_alpha, T_N))
    atm = mem[b:b + n_h * ATM_N].reshape((n_h, ATM_N))
    return tab, atm, grid


@njit(cache=True, error_model="numpy")
def slow_entry(est, cmd_rad, dt_s, mem):
    """slow_kernel on a packed ``mem`` (MEM_*); cmd_rad (alpha_c, beta_c, mu_c) rad is copied
    to mem[MEM_CMD:MEM_CMD + 3] first (as AttitudeLaw.slow_step always did); dt_s (s)."""
    cmd = mem[MEM_CMD:MEM_CMD + 3]
    cmd[0] = cmd_rad[0]
    cmd[1] = cmd_rad[1]
    cmd[2] = cmd_rad[2]
    tab, atm, grid = unpack_tables(mem, MEM_TABLES)
    slow_kernel(est, cmd, dt_s, mem[MEM_PAR:MEM_PAR + P_N], mem[MEM_X:MEM_X + X_N],
                mem[MEM_NM:MEM_NM + NM_N], mem[MEM_ST:MEM_ST + S_N], tab, atm, grid)


@njit(cache=True, error_model="numpy")
def fast_entry(est, dt_s, mem):
    """fast_kernel on a packed ``mem``; the surface command (rad) lands in
    mem[MEM_DELTA:MEM_DELTA + 3]; dt_s (s)."""
    tab, atm, grid = unpack_tables(mem, MEM_TABLES)
    fast_kernel(est, dt_s, mem[MEM_PAR:MEM_PAR + P_N], mem[MEM_X:MEM_X + X_N],
                mem[MEM_NM:MEM_NM + NM_N], mem[MEM_ST:MEM_ST + S_N], tab, atm, grid,
                mem[MEM_DELTA:MEM_DELTA + 3])


@njit(cache=True, error_model="numpy")
def cycle_entry(est, cmd_rad, dt_slow_s, dt_fast_s, mem):
    """slow_entry then fast_entry in one call (cycle_kernel with n_fast = 1)."""
    cmd = mem[MEM_CMD:MEM_CMD + 3]
    cmd[0] = cmd_rad[0]
    cmd[1] = cmd_rad[1]
    cmd[2] = cmd_rad[2]
    tab, atm, grid = unpack_tables(mem, MEM_TABLES)
    cycle_kernel(est, cmd, dt_slow_s, dt_fast_s, 1, mem[MEM_PAR:MEM_PAR + P_N],
                 mem[MEM_X:MEM_X + X_N], mem[MEM_NM:MEM_NM + NM_N],
                 mem[MEM_ST:MEM_ST + S_N], tab, atm, grid, mem[MEM_DELTA:MEM_DELTA + 3])
