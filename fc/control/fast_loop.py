"""Fast loop (Eqs. 34-37): the rate command omega_c to the surface command delta.

    fast_kernel(est, dt_s, par, x, nm, st, tab, atm, grid, delta_out)
        input filters (rates; the slow loop's angles), command filter (omega_c,
        omega_c_dot), Eq. 35 moment command M_c, the coordinated factors and allocation
        (fc.control.factors, fc.control.allocation), the Eq. 37 disturbance observer
        (fc.control.observer) and the Eq. 36 adaptive law for theta_omega.

Naming: channels p, q, r (roll, pitch, yaw); ``e2_*`` the rate error (rad/s), ``mc*`` the
moment command (N m), ``xi_theta_*`` = Xi^T theta_hat_omega per axis and ``d_hat_*`` the
observer's disturbance (rad/s^2). The per-axis arithmetic is written out: each axis has its
own inertia and its own slice of theta_omega, and numba keeps the scalars in registers.
"""
from __future__ import annotations

import math

from numba import njit

from fc.control.allocation import actuator_model_step, allocate, rate_limit_command
from fc.control.factors import coordinated_factors, coordinated_matrix
from fc.control.filters import input_ok, lowpass2_step, second_order_phi, second_order_step
from fc.control.kinematics import gs, gs_t
from fc.control.layout import (
    E_ALPHA, E_BETA, E_MU, E_N, E_P, E_Q, E_R, NM_E, NM_GCO, NM_GFD, NM_MACH, NM_QBAR, NM_XI,
    S_CO_FALLBACK, S_D_HAT, S_DELTA_CMD, S_DELTA_MODEL, S_E2, S_E_COUP, S_FROZEN,
    S_INPUT_BAD, S_LAMBDA, S_M_C, S_MACH, S_OMEGA_CF, S_QBAR, S_RHO_F, S_SAT,
    TH_F_N, TH_F_PITCH, TH_F_YAW,
    X_AF1, X_AF2, X_CF, X_CF_DOT, X_DCMD, X_DM, X_EF, X_FF1, X_FF2, X_FKIN, X_LIM, X_OMC, X_RHO_F,
    X_SAT, X_SIGMA, X_WF1, X_WF2, X_YAW_T,
)
from fc.control.linalg3 import clip, matvec3, wrap_pi
from fc.control.nominal import eval_model
from fc.control.observer import dob_estimate, dob_gain, dob_update
from fc.control.options import DOB_MOMENT_GCO, DOB_MOMENT_MC, option, switch_on
from fc.control.params import (
    P_ALLOC_YAW_MAX, P_ALLOC_YAW_T, P_CO_E, P_DOB_ACHIEVED, P_DOB_C, P_DOB_ENABLE, P_FLT_ANG_CF,
    P_FLT_ANG_HZ, P_FLT_RATE_HZ,
    P_FST_CF_WN, P_FST_CF_ZETA, P_FST_GAMMA, P_FST_KAPPA, P_FST_LEAK, P_FST_TH_BND,
    P_MDL_IXX, P_MDL_IYY, P_MDL_IZZ, P_PAPER_LITERAL, P_SLW_AW,
)


@njit(cache=True, inline="always", error_model="numpy")
def input_filters(est, dt, par, x, literal):
    """The fast loop's state x[X_EF:] = est with p, q, r through the input filter
    (FLT_RATE_HZ), and the slow loop's angle filter (FLT_ANG_HZ) run here at the fast rate.
    Returns the rate filter's corner (Hz; 0 = off), which the observer's model shares."""
    rate_hz = 0.0 if literal else par[P_FLT_RATE_HZ]
    ef = x[X_EF:X_EF + E_N]
    for i in range(E_N):
        ef[i] = est[i]
    for i in range(3):
        ef[E_P + i] = lowpass2_step(est[E_P + i], dt, rate_hz, x, X_WF1 + i, X_WF2 + i, False)
    cf_hz = 0.0 if literal else par[P_FLT_ANG_CF]
    if cf_hz > 0.0:
        complementary_attitude_step(est, dt, cf_hz, x)
    else:
        angle_hz = 0.0 if literal else par[P_FLT_ANG_HZ]
        lowpass2_step(est[E_ALPHA], dt, angle_hz, x, X_AF1, X_AF2, False)
        lowpass2_step(est[E_BETA], dt, angle_hz, x, X_AF1 + 1, X_AF2 + 1, False)
        lowpass2_step(est[E_MU], dt, angle_hz, x, X_AF1 + 2, X_AF2 + 2, True)
    return rate_hz


@njit(cache=True, inline="always", error_model="numpy")
def complementary_attitude_step(est, dt, cf_hz, x):
    """One step of the complementary attitude filter (FLT_ANG_CF) on x[X_AF2:X_AF2+3]:
    Omega_hat_dot = g_s(Omega_hat) omega + f + L (Omega - Omega_hat), L = 2 pi cf_hz (1/s),
    omega the gyros' body rates (rad/s, unfiltered: no lag on the fast path), f = f1 +
    Psi^T theta_hat of the last slow step (x[X_FKIN:], Eq. 2), Omega the vanes' alpha, beta
    and mu (rad). The correction is discretised exactly (stable for any dt); mu wraps.
    X_AF1 follows the output (a later switch to the low-pass starts from it)."""
    a_hat = x[X_AF2]
    b_hat = x[X_AF2 + 1]
    m_hat = x[X_AF2 + 2]
    k0, k1, k2 = gs(a_hat, b_hat, est[E_P], est[E_Q], est[E_R])
    g = 1.0 - math.exp(-2.0 * math.pi * cf_hz * dt)
    a_hat += dt * (k0 + x[X_FKIN])
    b_hat += dt * (k1 + x[X_FKIN + 1])
    m_hat = wrap_pi(m_hat + dt * (k2 + x[X_FKIN + 2]))
    x[X_AF2] = a_hat + g * (est[E_ALPHA] - a_hat)
    x[X_AF2 + 1] = b_hat + g * (est[E_BETA] - b_hat)
    x[X_AF2 + 2] = wrap_pi(m_hat + g * wrap_pi(est[E_MU] - m_hat))
    for i in range(3):
        x[X_AF1 + i] = x[X_AF2 + i]


@njit(cache=True, inline="always", error_model="numpy")
def xi_theta(nm, x):
    """Xi^T theta_hat_omega per axis (rad/s^2), theta_hat_i = theta_nom_i (1 + rho_i);
    theta_omega is ordered roll, pitch, yaw (layout TH_F_*)."""
    roll = 0.0
    for i in range(0, TH_F_PITCH):
        roll += nm[NM_XI + i] * (1.0 + x[X_RHO_F + i])
    pitch = 0.0
    for i in range(TH_F_PITCH, TH_F_YAW):
        pitch += nm[NM_XI + i] * (1.0 + x[X_RHO_F + i])
    yaw = 0.0
    for i in range(TH_F_YAW, TH_F_N):
        yaw += nm[NM_XI + i] * (1.0 + x[X_RHO_F + i])
    return roll, pitch, yaw


@njit(cache=True, inline="always", error_model="numpy")
def observer_moment(par, nm, x, delta_cmd, dt, literal, mc0, mc1, mc2):
    """Steps the actuator model over dt and returns the moment (N m) that acts over this
    step for the Eq. 37 observer: the achieved moment G delta of the modelled actuators
    (deviation, DOB_ACHIEVED 1: G = g_f_delta, the physical moment; 2: G = g_Gamma, the
    coordinated moment of Eq. 44; the mean deflection over the step) or M_c (printed)."""
    achieved = option(par, P_DOB_ACHIEVED)
    if achieved != DOB_MOMENT_MC and not literal:
        a0 = x[X_DM]
        a1 = x[X_DM + 1]
        a2 = x[X_DM + 2]
        actuator_model_step(par, x, delta_cmd, dt)
        a0 = 0.5 * (a0 + x[X_DM])
        a1 = 0.5 * (a1 + x[X_DM + 1])
        a2 = 0.5 * (a2 + x[X_DM + 2])
        g = NM_GCO if achieved == DOB_MOMENT_GCO else NM_GFD
        return matvec3(nm, g, a0, a1, a2)
    actuator_model_step(par, x, delta_cmd, dt)
    return mc0, mc1, mc2


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
    literal = switch_on(par, P_PAPER_LITERAL)
    rate_hz = input_filters(est, dt, par, x, literal)
    ef = x[X_EF:X_EF + E_N]
    eval_model(ef, par, tab, atm, grid, nm)
    alpha_rad = ef[E_ALPHA]
    beta_rad = ef[E_BETA]
    p_rad_s = ef[E_P]
    q_rad_s = ef[E_Q]
    r_rad_s = ef[E_R]
    ixx = par[P_MDL_IXX]
    iyy = par[P_MDL_IYY]
    izz = par[P_MDL_IZZ]

    # command filter: omega_c -> (omega_cf, omega_cf_dot)
    phi = second_order_phi(dt, par[P_FST_CF_WN], par[P_FST_CF_ZETA])
    for i in range(3):
        second_order_step(x[X_OMC + i], phi, x, X_CF + i, X_CF_DOT + i)

    # e2 = omega - omega_c
    e2_p = p_rad_s - x[X_CF]
    e2_q = q_rad_s - x[X_CF + 1]
    e2_r = r_rad_s - x[X_CF + 2]

    xi_theta_roll, xi_theta_pitch, xi_theta_yaw = xi_theta(nm, x)

    # Eq. 37: d_hat = z + Q(e), Q = c omega
    c_d = dob_gain(par[P_DOB_C], dt)
    dob = switch_on(par, P_DOB_ENABLE)
    if dob:
        d_hat_p, d_hat_q, d_hat_r = dob_estimate(x, c_d, p_rad_s, q_rad_s, r_rad_s)
    else:
        d_hat_p = 0.0
        d_hat_q = 0.0
        d_hat_r = 0.0

    # Eq. 35: M_c = -g_f^-1 (kappa2 e2 + Xi^T theta_hat + d_hat + g_s^T sigma - omega_c_dot)
    gst_p, gst_q, gst_r = gs_t(alpha_rad, beta_rad, x[X_SIGMA], x[X_SIGMA + 1], x[X_SIGMA + 2])
    kappa2 = par[P_FST_KAPPA]
    mc0 = -ixx * (kappa2 * e2_p + xi_theta_roll + d_hat_p + gst_p - x[X_CF_DOT])
    mc1 = -iyy * (kappa2 * e2_q + xi_theta_pitch + d_hat_q + gst_q - x[X_CF_DOT + 1])
    mc2 = -izz * (kappa2 * e2_r + xi_theta_yaw + d_hat_r + gst_r - x[X_CF_DOT + 2])

    # Eqs. 13/14/19 factors, Eq. 45 coordinated matrix, Eqs. 46-47 allocation
    coordinated_factors(ef, par, st, S_LAMBDA)
    fallback = coordinated_matrix(par, nm, st, S_LAMBDA)
    e_coup = par[P_CO_E] if par[P_CO_E] > 0.0 else nm[NM_E]
    # yaw escalation (ALLOC_YAW_T): while the rudder alone is asked beyond its limit and the
    # elevons have authority to spare, the re-solve's yaw weight grows with the time on it
    # (docs/control_law.md s. 13, "Yaw escalation": at Mach 15 / 27 km the fixed weight left the
    # sideslip beyond what the rudder holds and the bank ran off)
    w_yaw_scale = 1.0
    if par[P_ALLOC_YAW_T] > 0.0:
        w_yaw_scale = min(1.0 + x[X_YAW_T] / par[P_ALLOC_YAW_T], par[P_ALLOC_YAW_MAX])
    sat = allocate(par, nm, mc0, mc1, mc2, e_coup, delta_out, st, w_yaw_scale)
    if st[S_SAT + 2] > 0.0 and st[S_SAT] == 0.0 and st[S_SAT + 1] == 0.0:
        x[X_YAW_T] += dt
    else:
        x[X_YAW_T] = max(x[X_YAW_T] - dt, 0.0)
    rate_limit_command(par, nm, x, e_coup, dt, delta_out, st)
    x[X_SAT] = sat
    for i in range(3):
        x[X_DCMD + i] = delta_out[i]

    # Eq. 37 observer update with the moment that acts over this step
    m0, m1, m2 = observer_moment(par, nm, x, delta_out, dt, literal, mc0, mc1, mc2)
    if dob:
        # the model acceleration passes through the rates' input filter, so that the
        # observer compares filtered omega with filtered f (a plain DOB Q-filter)
        f0 = lowpass2_step(xi_theta_roll + m0 / ixx, dt, rate_hz, x, X_FF1, X_FF2, False)
        f1 = lowpass2_step(xi_theta_pitch + m1 / iyy, dt, rate_hz, x, X_FF1 + 1, X_FF2 + 1,
                           False)
        f2 = lowpass2_step(xi_theta_yaw + m2 / izz, dt, rate_hz, x, X_FF1 + 2, X_FF2 + 2,
                           False)
        dob_update(x, c_d, dt, f0, f1, f2, p_rad_s, q_rad_s, r_rad_s)

    # Eq. 36: rho_omega_dot = Gamma2 (Xi e2 - lambda_omega rho), projected onto the box
    freeze = (switch_on(par, P_SLW_AW) and not literal) and (sat > 0.5 or x[X_LIM] > 0.5)
    gamma2 = par[P_FST_GAMMA]
    if gamma2 > 0.0 and not freeze:
        leak = par[P_FST_LEAK]
        bound = par[P_FST_TH_BND]
        for i in range(TH_F_N):
            e2 = e2_p if i < TH_F_PITCH else (e2_q if i < TH_F_YAW else e2_r)
            rho = x[X_RHO_F + i] + dt * gamma2 * (nm[NM_XI + i] * e2 - leak * x[X_RHO_F + i])
            x[X_RHO_F + i] = clip(rho, -bound, bound)

    # status
    st[S_E2] = e2_p
    st[S_E2 + 1] = e2_q
    st[S_E2 + 2] = e2_r
    st[S_M_C] = mc0
    st[S_M_C + 1] = mc1
    st[S_M_C + 2] = mc2
    st[S_D_HAT] = d_hat_p
    st[S_D_HAT + 1] = d_hat_q
    st[S_D_HAT + 2] = d_hat_r
    for i in range(3):
        st[S_OMEGA_CF + i] = x[X_CF + i]
        st[S_DELTA_CMD + i] = delta_out[i]
        st[S_DELTA_MODEL + i] = x[X_DM + i]
    st[S_E_COUP] = e_coup
    st[S_CO_FALLBACK] = fallback
    for i in range(TH_F_N):
        st[S_RHO_F + i] = x[X_RHO_F + i]
    if freeze:
        st[S_FROZEN] = 1.0
    st[S_MACH] = nm[NM_MACH]
    st[S_QBAR] = nm[NM_QBAR]
