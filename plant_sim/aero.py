"""Winged-cone aerodynamics: Keshmiri-Colgren-Mirmirani fits, hypersonic branch (M >= 4).

Source: Keshmiri, Colgren, Mirmirani, AIAA 2005-6257 (S2), as transcribed in
/work/shared/docs/winged_cone.md section 2 (C_Y_beta's leading term read as -0.29253*M).
Units inside the polynomials: alpha and all deflections in deg, beta in rad, rates through
p b/(2V), q c/(2V), r b/(2V) with p, q, r in rad/s. Sign convention of the database (S1):
elevon +d = trailing edge up, rudder +d = trailing edge left.

Totals (S2):
    CL = CL0 + dCL(dR) + dCL(dL)
    CD = CD0 + dCD(dR) + dCD(dL) + dCDr(dr)
    CY = CYb beta + f(dR) - f(dL) + dCYr(dr)
    Cl = Clb beta + g(dR) - g(dL) + dClr(dr) + Clr r_hat + Clp p_hat
    Cm = Cm0 + dCm(dR) + dCm(dL) + dCmr(dr) + Cmq q_hat
    Cn = Cnb beta + h(dR) - h(dL) + dCnr(dr) + Cnp p_hat + Cnr r_hat
All moments are about the moment reference centre (MRC); the transfer to the c.g. is done by
the dynamics (plant_sim/dynamics.py, winged_cone.md section 3).

Clipping (winged_cone.md section 2, "Validity"): alpha to [0, 12] deg, Mach to [4, 24],
each deflection to [-20, +20] deg, before the polynomials are evaluated. beta and the rate
terms are not clipped (they enter linearly). ``coefficients`` returns a bit mask of what was
clipped (CLIP_ALPHA | CLIP_MACH | CLIP_DEFLECTION) so a run can count it.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from plant_sim._jitcache import refresh as _refresh_jit_cache
from plant_sim.vehicle import (ALPHA_MAX_DEG, ALPHA_MIN_DEG, B_REF_M, C_REF_M,
                               DEFLECTION_MAX_DEG, MACH_MAX, MACH_MIN, S_REF_M2)

_refresh_jit_cache(__file__)

# Output layout of coefficients().
C_L = 0
C_D = 1
C_Y = 2
C_ROLL = 3    # Cl
C_PITCH = 4   # Cm
C_YAW = 5     # Cn
C_N = 6

CLIP_ALPHA = 1
CLIP_MACH = 2
CLIP_DEFLECTION = 4

DEG = math.pi / 180.0


@njit(cache=True, inline="always")
def _clip(x, lo, hi):
    if x < lo:
        return lo
    if x > hi:
        return hi
    return x


@njit(cache=True)
def cl0(a, M):
    aM = a * M
    return (-8.19e-2 + 4.70e-2 * M + 1.86e-2 * a - 4.73e-4 * aM - 9.19e-3 * M**2
            - 1.52e-4 * a**2 + 5.99e-7 * aM**2 + 7.74e-4 * M**3 + 4.08e-6 * a**3
            - 2.93e-5 * M**4 - 3.91e-7 * a**4 + 4.12e-7 * M**5 + 1.30e-8 * a**5)


@njit(cache=True)
def dcl_elevon(a, M, d):
    return (-1.45e-5 + 1.01e-4 * a + 7.10e-6 * M - 4.14e-4 * d - 3.51e-6 * a * d
            + 4.70e-6 * a * M + 8.72e-6 * M * d - 1.70e-7 * a * M * d)


@njit(cache=True)
def cd0(a, M):
    aM = a * M
    return (8.717e-2 - 3.307e-2 * M + 3.179e-3 * a - 1.250e-4 * aM + 5.036e-3 * M**2
            - 1.100e-3 * a**2 + 1.405e-7 * aM**2 - 3.658e-4 * M**3 + 3.175e-4 * a**3
            + 1.274e-5 * M**4 - 2.985e-5 * a**4 - 1.705e-7 * M**5 + 9.766e-7 * a**5)


@njit(cache=True)
def dcd_elevon(a, M, d):
    aMd = a * M * d
    return (4.5548e-4 + 2.5411e-5 * a - 1.1436e-4 * M - 3.6417e-5 * d - 5.3015e-7 * aMd
            + 3.2187e-6 * a**2 + 3.0140e-6 * M**2 + 6.9629e-6 * d**2 + 2.1026e-12 * aMd**2)


@njit(cache=True)
def dcd_rudder(a, M, d):
    aMd = a * M * d
    return (7.50e-4 - 2.29e-5 * a - 9.69e-5 * M - 1.83e-6 * d + 9.13e-9 * aMd
            + 8.76e-7 * a**2 + 2.70e-6 * M**2 + 1.97e-6 * d**2 - 1.77e-11 * aMd**2)


@njit(cache=True)
def cy_beta(a, M):
    aM = a * M
    return (-2.9253e-1 * M + 2.8803e-3 * a - 2.8943e-4 * aM + 5.4822e-2 * M**2
            + 7.3535e-4 * a**2 - 4.6490e-9 * (a * M**2)**2 - 2.0675e-8 * (a**2 * M)**2
            + 4.6205e-6 * aM**2 + 2.6144e-11 * (a**2 * M**2)**2 - 4.3203e-3 * M**3
            - 3.7405e-4 * a**3 + 1.5495e-4 * M**4 + 2.8183e-5 * a**4 - 2.0829e-6 * M**5
            - 5.2083e-7 * a**5)


@njit(cache=True)
def cy_elevon(a, M, d):
    aMd = a * M * d
    return (-1.02e-6 - 1.12e-7 * a + 4.48e-7 * M + 2.27e-7 * d + 4.11e-9 * aMd
            + 2.82e-9 * a**2 - 2.36e-8 * M**2 - 5.04e-8 * d**2 + 4.50e-14 * aMd**2)


@njit(cache=True)
def dcy_rudder(a, M, d):
    return 3.84e-4 * d - 1.17e-5 * a * d - 1.07e-5 * M * d + 2.60e-7 * a * M * d


@njit(cache=True)
def cl_beta(a, M):
    aM = a * M
    return (-1.402e-1 + 3.326e-2 * M - 7.590e-4 * a + 8.596e-6 * aM - 3.794e-3 * M**2
            + 2.354e-6 * a**2 - 1.044e-8 * aM**2 + 2.219e-4 * M**3 - 6.462e-6 * M**4
            + 7.419e-8 * M**5)


@njit(cache=True)
def cl_elevon(a, M, d):
    aMd = a * M * d
    return (3.570e-4 - 9.569e-5 * a - 3.598e-5 * M + 1.170e-4 * d + 2.794e-8 * aMd
            + 4.950e-6 * a**2 + 1.411e-6 * M**2 - 1.160e-6 * d**2 - 4.641e-11 * aMd**2)


@njit(cache=True)
def dcl_rudder(a, M, d):
    return 1.1441e-4 * d - 2.6824e-6 * a * d - 3.5496e-6 * M * d + 5.5547e-8 * a * M * d


@njit(cache=True)
def cl_r(a, M):
    aM = a * M
    return (3.82e-1 - 1.06e-1 * M + 1.94e-3 * a - 8.15e-5 * aM + 1.45e-2 * M**2
            - 9.76e-6 * a**2 + 4.49e-8 * aM**2 - 1.02e-3 * M**3 - 2.70e-7 * a**3
            + 3.56e-5 * M**4 + 3.19e-8 * a**4 - 4.81e-7 * M**5 - 1.06e-9 * a**5)


@njit(cache=True)
def cl_p(a, M):
    aM = a * M
    return (-2.99e-1 + 7.47e-2 * M + 1.38e-3 * a - 8.78e-5 * aM - 9.13e-3 * M**2
            - 2.04e-4 * a**2 - 1.52e-7 * aM**2 + 5.73e-4 * M**3 - 3.86e-5 * a**3
            - 1.79e-5 * M**4 + 4.21e-6 * a**4 + 2.20e-7 * M**5 - 1.15e-7 * a**5)


@njit(cache=True)
def cm0(a, M):
    aM = a * M
    return (-2.192e-2 + 7.739e-3 * M - 2.260e-3 * a + 1.808e-4 * aM - 8.849e-4 * M**2
            + 2.616e-4 * a**2 - 2.880e-7 * aM**2 + 4.617e-5 * M**3 - 7.887e-5 * a**3
            - 1.143e-6 * M**4 + 8.288e-6 * a**4 + 1.082e-8 * M**5 - 2.789e-7 * a**5)


@njit(cache=True)
def dcm_elevon(a, M, d):
    return (-5.67e-5 - 6.59e-5 * a - 1.51e-6 * M + 2.89e-4 * d + 4.48e-6 * a * d
            - 4.46e-6 * a * M - 5.87e-6 * M * d + 9.72e-8 * a * M * d)


@njit(cache=True)
def dcm_rudder(a, M, d):
    return (-2.79e-5 * a - 5.89e-8 * a**2 + 1.58e-3 * M**2 + 6.42e-8 * a**3
            - 6.69e-4 * M**3 - 2.10e-8 * a**4 + 1.05e-4 * M**4 + 1.43e-7 * d**4
            + 3.14e-9 * a**5 - 7.74e-6 * M**5 - 2.18e-10 * a**6 + 2.70e-7 * M**6
            - 3.38e-10 * d**6 + 5.74e-12 * a**7 - 3.58e-9 * M**7)


@njit(cache=True)
def cm_q(a, M):
    aM = a * M
    return (-1.36 + 3.86e-1 * M + 7.85e-4 * a + 1.40e-4 * aM - 5.42e-2 * M**2
            + 2.36e-3 * a**2 - 1.95e-6 * aM**2 + 3.80e-3 * M**3 - 1.48e-3 * a**3
            - 1.30e-4 * M**4 + 1.69e-4 * a**4 + 1.71e-6 * M**5 - 5.93e-6 * a**5)


@njit(cache=True)
def cn_beta(a, M):
    aM = a * M
    return (6.9980e-4 * a + 5.9115e-2 * M - 7.5250e-5 * aM + 2.5160e-4 * a**2
            - 1.4824e-2 * M**2 - 2.1924e-7 * aM**2 - 1.0777e-4 * a**3 + 1.2692e-3 * M**3
            + 1.0707e-8 * aM**3 + 9.4989e-6 * a**4 - 4.7098e-5 * M**4
            - 5.5472e-11 * aM**4 - 2.5953e-7 * a**5 + 6.4284e-7 * M**5
            + 8.5863e-14 * aM**5)


@njit(cache=True)
def cn_elevon(a, M, d):
    aMd = a * M * d
    return (2.10e-4 + 1.83e-5 * a - 3.56e-5 * M - 1.30e-5 * d - 8.93e-8 * aMd
            - 6.39e-7 * a**2 + 8.16e-7 * M**2 + 1.97e-6 * d**2 + 1.41e-11 * aMd**2)


@njit(cache=True)
def dcn_rudder(a, M, d):
    return -5.28e-4 * d + 1.39e-5 * a * d + 1.65e-5 * M * d - 3.13e-7 * a * M * d


@njit(cache=True)
def cn_p(M):
    return (3.68e-1 - 9.79e-2 * M + 1.24e-2 * M**2 - 8.05e-4 * M**3 + 2.57e-5 * M**4
            - 3.20e-7 * M**5)


@njit(cache=True)
def cn_r(a, M):
    aM = a * M
    return (-2.41 + 5.96e-1 * M - 2.74e-3 * a + 2.09e-4 * aM - 7.57e-2 * M**2
            + 1.15e-3 * a**2 - 6.53e-8 * aM**2 + 4.90e-3 * M**3 - 3.87e-4 * a**3
            - 1.57e-4 * M**4 + 3.60e-5 * a**4 + 1.96e-6 * M**5 - 1.18e-6 * a**5)


@njit(cache=True)
def coefficients(alpha_deg, mach, beta_rad, p_hat, q_hat, r_hat,
                 d_left_deg, d_right_deg, d_rudder_deg, out):
    """Aerodynamic coefficients about the MRC (dimensionless).

    Parameters
    ----------
    alpha_deg : angle of attack (deg); clipped to [0, 12].
    mach : Mach number; clipped to [4, 24].
    beta_rad : sideslip (rad); not clipped.
    p_hat, q_hat, r_hat : p b/(2V), q c/(2V), r b/(2V) (p, q, r body rates in rad/s).
    d_left_deg, d_right_deg, d_rudder_deg : left elevon, right elevon, rudder (deg, database
        signs); each clipped to [-20, 20].
    out : float64[6], written with CL, CD, CY, Cl, Cm, Cn (indices C_L .. C_YAW).

    Returns
    -------
    int bit mask of the inputs that were clipped (CLIP_ALPHA, CLIP_MACH, CLIP_DEFLECTION).
    """
    flags = 0
    a = alpha_deg
    if a < ALPHA_MIN_DEG or a > ALPHA_MAX_DEG:
        a = _clip(a, ALPHA_MIN_DEG, ALPHA_MAX_DEG)
        flags |= CLIP_ALPHA
    M = mach
    if M < MACH_MIN or M > MACH_MAX:
        M = _clip(M, MACH_MIN, MACH_MAX)
        flags |= CLIP_MACH
    lim = DEFLECTION_MAX_DEG
    dl = d_left_deg
    dr = d_right_deg
    du = d_rudder_deg
    if (dl < -lim or dl > lim or dr < -lim or dr > lim or du < -lim or du > lim):
        dl = _clip(dl, -lim, lim)
        dr = _clip(dr, -lim, lim)
        du = _clip(du, -lim, lim)
        flags |= CLIP_DEFLECTION
    b = beta_rad
    out[C_L] = cl0(a, M) + dcl_elevon(a, M, dr) + dcl_elevon(a, M, dl)
    out[C_D] = cd0(a, M) + dcd_elevon(a, M, dr) + dcd_elevon(a, M, dl) + dcd_rudder(a, M, du)
    out[C_Y] = cy_beta(a, M) * b + cy_elevon(a, M, dr) - cy_elevon(a, M, dl) + dcy_rudder(a, M, du)
    out[C_ROLL] = (cl_beta(a, M) * b + cl_elevon(a, M, dr) - cl_elevon(a, M, dl)
                   + dcl_rudder(a, M, du) + cl_r(a, M) * r_hat + cl_p(a, M) * p_hat)
    out[C_PITCH] = (cm0(a, M) + dcm_elevon(a, M, dr) + dcm_elevon(a, M, dl)
                    + dcm_rudder(a, M, du) + cm_q(a, M) * q_hat)
    out[C_YAW] = (cn_beta(a, M) * b + cn_elevon(a, M, dr) - cn_elevon(a, M, dl)
                  + dcn_rudder(a, M, du) + cn_p(M) * p_hat + cn_r(a, M) * r_hat)
    return flags


@njit(cache=True)
def control_effectiveness(alpha_rad, mach, qbar_pa, x_cg_m, defl_rad, g_out, c_work):
    """Control-effectiveness matrix g_f_delta (N m per rad) about the c.g.

    Rows: roll, pitch, yaw moment (l, m, n); columns: left elevon, right elevon, rudder
    (the paper's delta_e, delta_a, delta_r in the winged-cone reading, winged_cone.md
    section 6). Partial derivatives of
        l = qbar S b Cl,
        m = qbar S c Cm + x_cg qbar S (CD sin(alpha) + CL cos(alpha)),
        n = qbar S b Cn + x_cg qbar S CY                        (winged_cone.md section 3)
    with respect to each deflection at ``defl_rad`` (float64[3], rad), beta = 0 and zero
    rates, by central differences of +-0.01 deg (the fits are at most quadratic in a
    deflection near zero, so this is exact to rounding). ``g_out``: float64[3, 3];
    ``c_work``: float64[2, 6] scratch.
    """
    h_deg = 0.01
    a_deg = alpha_rad / DEG
    sa = math.sin(alpha_rad)
    ca = math.cos(alpha_rad)
    qs = qbar_pa * S_REF_M2
    for j in range(3):
        d0 = defl_rad[0] / DEG
        d1 = defl_rad[1] / DEG
        d2 = defl_rad[2] / DEG
        for s in range(2):
            sign = 1.0 if s == 0 else -1.0
            e0 = d0 + (sign * h_deg if j == 0 else 0.0)
            e1 = d1 + (sign * h_deg if j == 1 else 0.0)
            e2 = d2 + (sign * h_deg if j == 2 else 0.0)
            coefficients(a_deg, mach, 0.0, 0.0, 0.0, 0.0, e0, e1, e2, c_work[s])
        k = 1.0 / (2.0 * h_deg * DEG)
        dCL = (c_work[0, C_L] - c_work[1, C_L]) * k
        dCD = (c_work[0, C_D] - c_work[1, C_D]) * k
        dCY = (c_work[0, C_Y] - c_work[1, C_Y]) * k
        g_out[0, j] = qs * B_REF_M * (c_work[0, C_ROLL] - c_work[1, C_ROLL]) * k
        g_out[1, j] = (qs * C_REF_M * (c_work[0, C_PITCH] - c_work[1, C_PITCH]) * k
                       + x_cg_m * qs * (dCD * sa + dCL * ca))
        g_out[2, j] = qs * B_REF_M * (c_work[0, C_YAW] - c_work[1, C_YAW]) * k + x_cg_m * qs * dCY


def coefficient_names():
    """Names of the entries of ``coefficients``' output, in order."""
    return ("CL", "CD", "CY", "Cl", "Cm", "Cn")


def effectiveness_matrix(alpha_rad: float, mach: float, qbar_pa: float, x_cg_m: float = 0.0,
                         defl_rad=(0.0, 0.0, 0.0)) -> np.ndarray:
    """Convenience wrapper of ``control_effectiveness``: returns a new float64[3, 3]."""
    g = np.empty((3, 3))
    control_effectiveness(float(alpha_rad), float(mach), float(qbar_pa), float(x_cg_m),
                          np.asarray(defl_rad, dtype=np.float64), g, np.empty((2, 6)))
    return g
