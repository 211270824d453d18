"""Slow loop (Eqs. 26-30): the attitude Omega = [alpha, beta, mu] to the rate command omega_c.

    slow_kernel(est, cmd, dt_s, par, x, nm, st, tab, atm, grid)
        reference prefilter, Eq. 27 sliding surface sigma, Eq. 29 virtual rate command
        omega_c (with its limit and the command-filter compensation xi), Eq. 30 adaptive law
        for theta_Omega; the status record st gets the loop's terms.

Naming: ``sigma_*`` is the sliding variable of a channel (rad), ``e1_*`` the tracking error
(rad), ``sin_*``/``cos_*`` trigonometric values; channels alpha, beta, mu. The per-channel
arithmetic is written out (three lines per equation): each channel's expression differs (the
mu error wraps, the mu row of Psi^T theta has two terms) and numba keeps the scalars in
registers.
"""
from __future__ import annotations

import math

from numba import njit

from fc.control.filters import input_ok, second_order_phi, second_order_step
from fc.control.kinematics import gs, gs_inv
from fc.control.layout import (
    E_ALPHA, E_BETA, E_GAMMA, E_MU, E_V, NM_G, NM_MACH, NM_PSI, NM_QBAR,
    S_E1, S_FROZEN, S_INPUT_BAD, S_MACH, S_OMC_LIM, S_OMEGA_C, S_OMEGA_REF, S_QBAR, S_RHO_S,
    S_SIGMA, S_XI, TH_S_N,
    X_AF2, X_FKIN, X_INT_E1, X_LIM, X_OMC, X_PF, X_PF_DOT, X_RHO_S, X_SAT, X_SIGMA, X_XI,
)
from fc.control.linalg3 import clip, wrap_pi
from fc.control.nominal import COS_MIN, V_MIN_M_S, eval_model
from fc.control.options import switch_on
from fc.control.schedule import apply_schedule
from fc.control.params import (
    P_CTL_SCHED, P_FLT_ANG_CF, P_FLT_ANG_HZ, P_PAPER_LITERAL, P_REF_PF_EN, P_REF_PF_WN,
    P_REF_PF_ZETA, P_SLW_AW,
    P_SLW_CFB, P_SLW_GAMMA, P_SLW_K1, P_SLW_KAPPA, P_SLW_LEAK, P_SLW_OMC_MAX, P_SLW_TH_BND,
)


@njit(cache=True, inline="always", error_model="numpy")
def reference_step(cmd, dt, par, x, literal):
    """Omega_c, Omega_c_dot into x[X_PF:], x[X_PF_DOT:]: the prefiltered command (REF_PF_EN)
    or the paper's steps (Omega_c_dot = 0)."""
    if switch_on(par, P_REF_PF_EN) and not literal:
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


@njit(cache=True, inline="always", error_model="numpy")
def tracking_error(est, par, x, literal):
    """e1 = Omega - Omega_c (rad), mu wrapped. With FLT_ANG_HZ > 0, Omega is the output of
    the input filter that the fast loop runs at its own (higher) rate, so the noise is
    filtered before the slow loop samples it."""
    if (par[P_FLT_ANG_HZ] > 0.0 or par[P_FLT_ANG_CF] > 0.0) and not literal:
        alpha_rad = x[X_AF2]
        beta_rad = x[X_AF2 + 1]
        mu_rad = x[X_AF2 + 2]
    else:
        alpha_rad = est[E_ALPHA]
        beta_rad = est[E_BETA]
        mu_rad = est[E_MU]
    return (alpha_rad - x[X_PF], beta_rad - x[X_PF + 1], wrap_pi(mu_rad - x[X_PF + 2]))


@njit(cache=True, inline="always", error_model="numpy")
def f1_gravity(g_m_s2, beta_rad, mu_rad, v_m_s, gamma_rad):
    """Eq. 26: f1, the gravity terms of Omega_dot (rad/s)."""
    cos_beta = max(math.cos(beta_rad), COS_MIN)
    cos_gamma = math.cos(gamma_rad)
    return (g_m_s2 * cos_gamma * math.cos(mu_rad) / (v_m_s * cos_beta),
            g_m_s2 * cos_gamma * math.sin(mu_rad) / v_m_s,
            -g_m_s2 * cos_gamma * math.cos(mu_rad) * math.sin(beta_rad) / (cos_beta * v_m_s))


@njit(cache=True, inline="always", error_model="numpy")
def psi_theta(nm, x):
    """Psi^T theta_hat_Omega, theta_hat_i = theta_nom_i (1 + rho_i) (Eq. 23 rows alpha, beta,
    mu; the mu row has two entries)."""
    return (nm[NM_PSI] * (1.0 + x[X_RHO_S]),
            nm[NM_PSI + 1] * (1.0 + x[X_RHO_S + 1]),
            nm[NM_PSI + 2] * (1.0 + x[X_RHO_S + 2]) + nm[NM_PSI + 3] * (1.0 + x[X_RHO_S + 3]))


@njit(cache=True, inline="always", error_model="numpy")
def xi_step(alpha_rad, beta_rad, scale, kappa1, dt, x):
    """Command-filtered backstepping compensation (deviation, SLW_CFB), one exact step of
    xi_dot = -kappa1 xi + g_s (omega_c_lim - omega_c) on x[X_XI:]."""
    d0, d1, d2 = gs(alpha_rad, beta_rad, (scale - 1.0) * x[X_OMC], (scale - 1.0) * x[X_OMC + 1],
                    (scale - 1.0) * x[X_OMC + 2])
    if kappa1 > 0.0:
        ek = math.exp(-kappa1 * dt)
        gk = (1.0 - ek) / kappa1
    else:
        ek = 1.0
        gk = dt
    x[X_XI] = ek * x[X_XI] + gk * d0
    x[X_XI + 1] = ek * x[X_XI + 1] + gk * d1
    x[X_XI + 2] = ek * x[X_XI + 2] + gk * d2


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
    literal = switch_on(par, P_PAPER_LITERAL)
    # gain schedule (CTL_SCHED): the gains at the estimated flight condition's dynamic pressure
    # (and the rate-command limit's Mach factor at its Mach number)
    if switch_on(par, P_CTL_SCHED) and not literal:
        apply_schedule(nm[NM_QBAR], nm[NM_MACH], par, x)
    alpha_rad = est[E_ALPHA]
    beta_rad = est[E_BETA]
    v_m_s = max(est[E_V], V_MIN_M_S)

    reference_step(cmd, dt, par, x, literal)
    e1_alpha, e1_beta, e1_mu = tracking_error(est, par, x, literal)

    # Eq. 27: sigma = e1 + K int(e1) dt, integral frozen while limited / saturated
    anti_windup = switch_on(par, P_SLW_AW) and not literal
    freeze = anti_windup and (x[X_SAT] > 0.5 or x[X_LIM] > 0.5)
    if not freeze:
        x[X_INT_E1] += e1_alpha * dt
        x[X_INT_E1 + 1] += e1_beta * dt
        x[X_INT_E1 + 2] += e1_mu * dt
    k1 = par[P_SLW_K1]
    k2 = par[P_SLW_K1 + 1]
    k3 = par[P_SLW_K1 + 2]
    sigma_alpha = e1_alpha + k1 * x[X_INT_E1]
    sigma_beta = e1_beta + k2 * x[X_INT_E1 + 1]
    sigma_mu = e1_mu + k3 * x[X_INT_E1 + 2]

    f1_alpha, f1_beta, f1_mu = f1_gravity(nm[NM_G], beta_rad, est[E_MU], v_m_s, est[E_GAMMA])
    psi_alpha, psi_beta, psi_mu = psi_theta(nm, x)
    # the complementary attitude filter's model term (FLT_ANG_CF), held until the next slow step
    x[X_FKIN] = f1_alpha + psi_alpha
    x[X_FKIN + 1] = f1_beta + psi_beta
    x[X_FKIN + 2] = f1_mu + psi_mu

    # Eq. 29 (Omega_c_dot where the OCR prints Omega_c):
    # omega_c = -g_s^-1 (kappa1 sigma + f1 + Psi^T theta_hat - Omega_c_dot + K e1)
    kappa1 = par[P_SLW_KAPPA]
    v0 = -(kappa1 * sigma_alpha + f1_alpha + psi_alpha - x[X_PF_DOT] + k1 * e1_alpha)
    v1 = -(kappa1 * sigma_beta + f1_beta + psi_beta - x[X_PF_DOT + 1] + k2 * e1_beta)
    v2 = -(kappa1 * sigma_mu + f1_mu + psi_mu - x[X_PF_DOT + 2] + k3 * e1_mu)
    x[X_OMC], x[X_OMC + 1], x[X_OMC + 2] = gs_inv(alpha_rad, beta_rad, v0, v1, v2)

    # limit on omega_c (deviation, SLW_OMC_MAX): scale the vector, keep its direction
    # (written out per channel: with a helper returning (scale, limited) and a loop for the
    # scaling, the in-numba slow step measured ~211 ns instead of ~199 ns, tools.bench_law)
    limit_rad_s = par[P_SLW_OMC_MAX]
    limited = 0.0
    scale = 1.0
    if limit_rad_s > 0.0 and not literal:
        big = max(abs(x[X_OMC]), max(abs(x[X_OMC + 1]), abs(x[X_OMC + 2])))
        if big > limit_rad_s:
            scale = limit_rad_s / big
            limited = 1.0
    # command-filtered backstepping compensation (deviation, SLW_CFB):
    # sigma_bar = sigma - xi, xi_dot = -kappa1 xi + g_s (omega_c_lim - omega_c)
    cfb = switch_on(par, P_SLW_CFB) and not literal
    if cfb:
        sigma_bar_alpha = sigma_alpha - x[X_XI]
        sigma_bar_beta = sigma_beta - x[X_XI + 1]
        sigma_bar_mu = sigma_mu - x[X_XI + 2]
        xi_step(alpha_rad, beta_rad, scale, kappa1, dt, x)
    else:
        sigma_bar_alpha = sigma_alpha
        sigma_bar_beta = sigma_beta
        sigma_bar_mu = sigma_mu
        for i in range(3):
            x[X_XI + i] = 0.0
    if limited > 0.5:
        x[X_OMC] *= scale
        x[X_OMC + 1] *= scale
        x[X_OMC + 2] *= scale
    x[X_LIM] = limited
    x[X_SIGMA] = sigma_bar_alpha
    x[X_SIGMA + 1] = sigma_bar_beta
    x[X_SIGMA + 2] = sigma_bar_mu

    # Eq. 30: rho_Omega_dot = Gamma1 (Psi sigma - lambda_Omega rho), projected onto the box
    freeze = freeze or (anti_windup and limited > 0.5)
    gamma1 = par[P_SLW_GAMMA]
    if gamma1 > 0.0 and not freeze:
        leak = par[P_SLW_LEAK]
        bound = par[P_SLW_TH_BND]
        for i in range(TH_S_N):
            sigma_row = (sigma_bar_alpha if i == 0 else
                         (sigma_bar_beta if i == 1 else sigma_bar_mu))
            rho = x[X_RHO_S + i] + dt * gamma1 * (nm[NM_PSI + i] * sigma_row
                                                   - leak * x[X_RHO_S + i])
            x[X_RHO_S + i] = clip(rho, -bound, bound)

    # status
    st[S_SIGMA] = sigma_alpha
    st[S_SIGMA + 1] = sigma_beta
    st[S_SIGMA + 2] = sigma_mu
    st[S_E1] = e1_alpha
    st[S_E1 + 1] = e1_beta
    st[S_E1 + 2] = e1_mu
    for i in range(3):
        st[S_OMEGA_C + i] = x[X_OMC + i]
        st[S_OMEGA_REF + i] = x[X_PF + i]
        st[S_XI + i] = x[X_XI + i]
    st[S_OMC_LIM] = limited
    st[S_FROZEN] = 1.0 if freeze else 0.0
    for i in range(TH_S_N):
        st[S_RHO_S + i] = x[X_RHO_S + i]
    st[S_MACH] = nm[NM_MACH]
    st[S_QBAR] = nm[NM_QBAR]
