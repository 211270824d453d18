"""Coordinated factors (Eqs. 10-14, 19) and the coordinated control matrix g_Gamma (Eq. 45).

    coordinated_factors(est, par, out, o)   lambda_e, lambda_a, lambda_r -> out[o:o+3]
    coordinated_matrix(par, nm, lam, lo)    g_Gamma = g_f_delta + the factors -> nm[NM_GCO:]

Options (fc/control/options.py): CO_FAC_EQ (Eq. 14 or 19), CO_MAP (diagonal or the prose's
row scaling), CO_NORM (how a factor is added to the diagonal). docs/control_law.md
sections 6-7 give the reading of the garbled equations.
"""
from __future__ import annotations

import math

from numba import njit

from fc.control.layout import E_ALPHA, E_BETA, E_P, E_Q, E_R, NM_GCO, NM_GFD, NM_QBAR
from fc.control.linalg3 import clip, det3
from fc.control.nominal import B_REF_M, C_REF_M, S_REF_M2
from fc.control.options import (FAC_EQ19, MAP_PROSE, NORM_COEFFICIENT, NORM_RELATIVE, option,
                                switch_on)
from fc.control.params import (P_CO_DALPHA, P_CO_DET_MIN, P_CO_ENABLE, P_CO_FAC_EQ, P_CO_K1,
                               P_CO_LAM_MAX, P_CO_LAMR_SCL, P_CO_MAP, P_CO_NORM,
                               P_PAPER_LITERAL)


ROW_PITCH = 3            # first entry of the pitch row in a flat 3x3 (roll 0, yaw 6)
ROW_YAW = 6


@njit(cache=True, error_model="numpy")
def coordinated_factors(est, par, out, o):
    """lambda_e, lambda_a, lambda_r into out[o:o+3] (0 when CO_ENABLE = 0)."""
    if not switch_on(par, P_CO_ENABLE):
        out[o] = 0.0
        out[o + 1] = 0.0
        out[o + 2] = 0.0
        return
    alpha_rad = est[E_ALPHA]
    beta_rad = est[E_BETA]
    p_rad_s = est[E_P]
    q_rad_s = est[E_Q]
    r_rad_s = est[E_R]
    k = P_CO_K1 - 1          # par[k + i] is the paper's k_i
    sin_alpha = math.sin(alpha_rad)
    cos_alpha = math.cos(alpha_rad)
    # Eq. 10: lambda_r1 = k1 p tan(alpha)
    lambda_r1 = par[k + 1] * p_rad_s * sin_alpha / cos_alpha
    # Eq. 12: lambda_r2 = k2 beta + k3 p (1 - cos alpha) / (sin alpha + Delta_alpha)
    den = sin_alpha + par[P_CO_DALPHA]
    if abs(den) < 1e-6:
        den = 1e-6 if den >= 0.0 else -1e-6
    lambda_r2 = par[k + 2] * beta_rad + par[k + 3] * p_rad_s * (1.0 - cos_alpha) / den
    # Eq. 14: lambda_r3 = k8 beta + k9 q
    lambda_r3 = par[k + 8] * beta_rad + par[k + 9] * q_rad_s
    if option(par, P_CO_FAC_EQ) == FAC_EQ19:
        # Eq. 19 (default: the factors Section 4.3 builds g_Gamma from)
        lambda_e = par[k + 4] * alpha_rad + par[k + 5] * q_rad_s
        lambda_a = par[k + 6] * beta_rad + par[k + 7] * p_rad_s
    else:
        # Eq. 14 (the prose before it)
        lambda_e = par[k + 4] * alpha_rad + par[k + 5] * p_rad_s
        lambda_a = par[k + 6] * beta_rad + par[k + 7] * r_rad_s
    # Eq. 13 + Eq. 19: lambda_r = lambda_r1 + lambda_r2 + lambda_r3, scaled by CO_LAMR_SCL
    # (1, the paper's, unless the schedule shrinks it where the airframe is directionally
    # unstable: docs/control_law.md s. 13)
    lambda_r = (lambda_r1 + lambda_r2 + lambda_r3) * par[P_CO_LAMR_SCL]
    lambda_max = par[P_CO_LAM_MAX]
    if lambda_max > 0.0 and not switch_on(par, P_PAPER_LITERAL):
        lambda_e = clip(lambda_e, -lambda_max, lambda_max)
        lambda_a = clip(lambda_a, -lambda_max, lambda_max)
        lambda_r = clip(lambda_r, -lambda_max, lambda_max)
    out[o] = lambda_e
    out[o + 1] = lambda_a
    out[o + 2] = lambda_r


@njit(cache=True, error_model="numpy")
def coordinated_matrix(par, nm, lam, lo):
    """Eq. 45: g_Gamma = g_f_delta + diag(lambda) (normalised per CO_NORM) into nm[NM_GCO].

    ``lam[lo:lo+3]`` = lambda_e, lambda_a, lambda_r. Returns 1.0 if the guard rejected it
    (then g_Gamma = g_f_delta), else 0.0. Guard (off with PAPER_LITERAL, which only rejects
    an exactly singular matrix): det(g_Gamma) / det(g_f_delta) >= CO_DET_MIN and
    g_Gamma_ii / g_f_delta_ii >= CO_DET_MIN for each i.
    """
    for i in range(9):
        nm[NM_GCO + i] = nm[NM_GFD + i]
    if option(par, P_CO_MAP) == MAP_PROSE:
        # the loops the prose names: aileron -> roll row, elevator -> pitch row,
        # rudder -> yaw row, each scaled by (1 + lambda)
        for j in range(3):
            nm[NM_GCO + j] *= 1.0 + lam[lo + 1]
            nm[NM_GCO + ROW_PITCH + j] *= 1.0 + lam[lo]
            nm[NM_GCO + ROW_YAW + j] *= 1.0 + lam[lo + 2]
    else:
        norm = option(par, P_CO_NORM)
        qbar_s_n = nm[NM_QBAR] * S_REF_M2          # qbar S (N)
        for i in range(3):
            d = NM_GCO + 4 * i                     # diagonal entry i
            if norm == NORM_RELATIVE:
                nm[d] += lam[lo + i] * nm[NM_GFD + 4 * i]
            elif norm == NORM_COEFFICIENT:
                lref_m = C_REF_M if i == 1 else B_REF_M
                nm[d] += lam[lo + i] * qbar_s_n * lref_m
            else:                                  # NORM_LITERAL
                nm[d] += lam[lo + i]
    det_gfd = det3(nm, NM_GFD)
    det_gco = det3(nm, NM_GCO)
    if not abs(det_gfd) > 0.0:
        ok = False
    elif switch_on(par, P_PAPER_LITERAL):
        ok = abs(det_gco) > 1e-9 * abs(det_gfd)
    else:
        # accept only if det keeps its sign and size, and no diagonal entry flips or vanishes
        dmin = par[P_CO_DET_MIN]
        ok = det_gco / det_gfd >= dmin
        for i in range(3):
            d = 4 * i
            ok = ok and nm[NM_GCO + d] / nm[NM_GFD + d] >= dmin
    if not ok:
        for i in range(9):
            nm[NM_GCO + i] = nm[NM_GFD + i]
        return 1.0
    return 0.0
