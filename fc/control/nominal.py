"""The controller's nominal model of the winged-cone: tables, interpolation, Eqs. 2-6 and 20-26.

The controller knows the vehicle only through this module: the reference geometry below, the
mass properties of the parameter table (MDL_*), and the tables of
``data/nominal_model.npz`` (generated offline by tools/gen_nominal_model.py from the published
fits at zero uncertainty). It never imports the plant.

``eval_model`` evaluates, at the current estimated state, everything the law needs from the
model (layout NM_*):
- Mach number, dynamic pressure, density, speed of sound, gravity;
- the aerodynamic coefficients and derivatives (bilinear in Mach and alpha, clamped to the
  table's box: Mach 4..24, the plant's fits' whole hypersonic range, alpha 0..12 deg);
- g_f_delta (Eq. 45's effectiveness matrix, N m/rad) about the c.g. of the nominal model:
  l = qSb Cl, m = qSc Cm + X_cg qS (CD sin a + CL cos a), n = qSb Cn + X_cg qS CY (Eq. 6);
- E (Eq. 15) as the rolling-moment effectiveness ratio |Cl_delta_r / Cl_delta_a|;
- the nominal parameter vectors theta_Omega (Eq. 22, 4 entries) and theta_omega (17, ordered
  roll, pitch, yaw), and each entry's contribution Psi_i theta_i / Xi_i theta_i (Eqs. 23-24)
  to Omega_dot / omega_dot. The adaptive laws estimate theta_hat_i = theta_i (1 + rho_i),
  so Psi_i theta_i is the regressor of rho_i (docs/control_law.md, "relative estimates").
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from numba import njit

from fc.control.layout import (
    ATM_G, ATM_RHO, ATM_SOUND, C_DRAG, C_LIFT, C_PITCH, C_ROLL, C_SIDE, C_YAW,
    E_ALPHA, E_BETA, E_GAMMA, E_H, E_MU, E_P, E_Q, E_R, E_V,
    G_ALPHA0, G_DALPHA, G_DH, G_DMACH, G_H0, G_MACH0, G_NALPHA, G_NH, G_NMACH,
    NM_COEF, NM_E, NM_G, NM_GFD, NM_MACH, NM_PSI, NM_QBAR, NM_RHO, NM_SOUND, NM_TH_F,
    NM_TH_S, NM_XI, T_CD0, T_CL0, T_CPITCH0, T_CPITCH_Q, T_CROLL_B, T_CROLL_P, T_CROLL_R,
    T_CY_B, T_CYAW_B, T_CYAW_P, T_CYAW_R, T_DEL, T_N, TH_F_PITCH, TH_F_ROLL, TH_F_YAW,
)
from fc.control.params import P_MDL_IXX, P_MDL_IYY, P_MDL_IZZ, P_MDL_MASS, P_MDL_XCG


# Reference geometry of the winged-cone (NASA TM-102610 Table I; docs/winged_cone.md s. 1):
# the controller's own copy; tools/gen_nominal_model.py checks it against the plant's.
S_REF_M2 = 334.73
B_REF_M = 18.288
C_REF_M = 24.384

TABLE_PATH = Path(__file__).with_name("data") / "nominal_model.npz"

V_MIN_M_S = 1.0          # guards for divisions by V (the law is not meant for V < 1 m/s)
COS_MIN = 1e-3           # guard for 1/cos(beta), 1/cos(gamma)


def load_tables(path: Path | str = TABLE_PATH):
    """Load (tab, atm, grid) float64 arrays from the committed npz (C-contiguous copies)."""
    with np.load(path) as z:
        tab = np.ascontiguousarray(z["tab"], dtype=np.float64)
        atm = np.ascontiguousarray(z["atm"], dtype=np.float64)
        grid = np.ascontiguousarray(z["grid"], dtype=np.float64)
        geom = z["geometry"]
    if not np.allclose(geom, [S_REF_M2, B_REF_M, C_REF_M], rtol=0, atol=0):
        raise ValueError(f"{path}: reference geometry {geom} differs from fc.control.nominal")
    return tab, atm, grid


@njit(cache=True, inline="always", error_model="numpy")
def _frac_index(x, x0, dx, n):
    """Clamped cell index and fraction of x on the uniform grid x0 + k dx, k < n."""
    u = (x - x0) / dx
    if u <= 0.0:
        return 0, 0.0
    top = n - 1.0
    if u >= top:
        return int(top) - 1, 1.0
    k = int(u)
    return k, u - k


@njit(cache=True, error_model="numpy")
def interp_table(mach, alpha_rad, tab, grid, out, off):
    """Bilinear interpolation of all T_N columns at (mach, alpha); writes out[off:off+T_N]."""
    i, fm = _frac_index(mach, grid[G_MACH0], grid[G_DMACH], grid[G_NMACH])
    j, fa = _frac_index(alpha_rad, grid[G_ALPHA0], grid[G_DALPHA], grid[G_NALPHA])
    w00 = (1.0 - fm) * (1.0 - fa)
    w01 = (1.0 - fm) * fa
    w10 = fm * (1.0 - fa)
    w11 = fm * fa
    for k in range(T_N):
        out[off + k] = (w00 * tab[i, j, k] + w01 * tab[i, j + 1, k]
                        + w10 * tab[i + 1, j, k] + w11 * tab[i + 1, j + 1, k])


@njit(cache=True, error_model="numpy")
def interp_atmosphere(h_m, atm, grid, out, off):
    """Linear interpolation of rho, speed of sound, g at altitude h; writes out[off:off+3]."""
    i, f = _frac_index(h_m, grid[G_H0], grid[G_DH], grid[G_NH])
    for k in range(3):
        out[off + k] = (1.0 - f) * atm[i, k] + f * atm[i + 1, k]


@njit(cache=True, error_model="numpy")
def eval_model(est, par, tab, atm, grid, nm):
    """Evaluate the nominal model at the estimated state ``est``; fills ``nm`` (NM_*)."""
    alpha = est[E_ALPHA]
    beta = est[E_BETA]
    mu = est[E_MU]
    p = est[E_P]
    q = est[E_Q]
    r = est[E_R]
    V = max(est[E_V], V_MIN_M_S)
    gam = est[E_GAMMA]
    m = par[P_MDL_MASS]
    ixx = par[P_MDL_IXX]
    iyy = par[P_MDL_IYY]
    izz = par[P_MDL_IZZ]
    xcg = par[P_MDL_XCG]

    # atmosphere -> Mach, qbar (ATM_RHO, ATM_SOUND, ATM_G are consecutive from NM_RHO)
    interp_atmosphere(est[E_H], atm, grid, nm, NM_RHO)
    rho = nm[NM_RHO + ATM_RHO]
    a_snd = nm[NM_RHO + ATM_SOUND]
    nm[NM_SOUND] = a_snd
    nm[NM_G] = nm[NM_RHO + ATM_G]
    mach = V / a_snd
    qbar = 0.5 * rho * V * V
    nm[NM_MACH] = mach
    nm[NM_QBAR] = qbar
    nm[NM_RHO] = rho

    interp_table(mach, alpha, tab, grid, nm, NM_COEF)
    c = NM_COEF
    CL = nm[c + T_CL0]
    CD = nm[c + T_CD0]
    CYb = nm[c + T_CY_B]
    qS = qbar * S_REF_M2
    qSb = qS * B_REF_M
    qSc = qS * C_REF_M
    sa = math.sin(alpha)
    ca = math.cos(alpha)

    # g_f_delta (N m/rad): rows l, m, n; columns left elevon, right elevon, rudder
    for j in range(3):
        dCL = nm[c + T_DEL + 3 * C_LIFT + j]
        dCD = nm[c + T_DEL + 3 * C_DRAG + j]
        dCY = nm[c + T_DEL + 3 * C_SIDE + j]
        nm[NM_GFD + j] = qSb * nm[c + T_DEL + 3 * C_ROLL + j]
        nm[NM_GFD + 3 + j] = (qSc * nm[c + T_DEL + 3 * C_PITCH + j]
                              + xcg * qS * (dCD * sa + dCL * ca))
        nm[NM_GFD + 6 + j] = qSb * nm[c + T_DEL + 3 * C_YAW + j] + xcg * qS * dCY

    # E (Eq. 15): rolling-moment effectiveness of the rudder over that of the "aileron"
    # (the right elevon, the paper's delta_a), clipped to the paper's 0 < E <= 1.
    cl_da = nm[c + T_DEL + 3 * C_ROLL + 1]
    cl_dr = nm[c + T_DEL + 3 * C_ROLL + 2]
    e = abs(cl_dr) / max(abs(cl_da), 1e-12)
    nm[NM_E] = min(max(e, 0.01), 1.0)

    # nominal theta_Omega (Eq. 22) and Psi_i theta_i (Eq. 23, Psi2 in the form that
    # reproduces f_beta of Eq. 2: +qbar S beta / (M V))
    cb = max(math.cos(beta), COS_MIN)
    cg = max(math.cos(gam), COS_MIN)
    tg = math.sin(gam) / cg
    tb = math.sin(beta) / cb
    mV = m * V
    nm[NM_TH_S + 0] = CL
    nm[NM_TH_S + 1] = CYb
    nm[NM_TH_S + 2] = CYb
    nm[NM_TH_S + 3] = CL
    nm[NM_PSI + 0] = -qS / (mV * cb) * CL
    nm[NM_PSI + 1] = qS * beta / mV * CYb
    nm[NM_PSI + 2] = qS * beta * tg * math.cos(mu) / mV * CYb
    nm[NM_PSI + 3] = qS * (tg * math.sin(mu) + tb) / mV * CL

    # nominal theta_omega (Eq. 22, ordered roll, pitch, yaw) and Xi_i theta_i (Eq. 24).
    # Mass properties are constant in the nominal model: the I_dot entries are 0 (inert).
    hb = B_REF_M / (2.0 * V)
    hc = C_REF_M / (2.0 * V)
    t = NM_TH_F
    x = NM_XI
    k = TH_F_ROLL
    nm[t + k + 0] = (iyy - izz) / ixx
    nm[t + k + 1] = 0.0
    nm[t + k + 2] = nm[c + T_CROLL_B] / ixx
    nm[t + k + 3] = nm[c + T_CROLL_P] / ixx
    nm[t + k + 4] = nm[c + T_CROLL_R] / ixx
    nm[x + k + 0] = q * r * nm[t + k + 0]
    nm[x + k + 1] = -p * nm[t + k + 1]
    nm[x + k + 2] = qSb * beta * nm[t + k + 2]
    nm[x + k + 3] = qSb * hb * p * nm[t + k + 3]
    nm[x + k + 4] = qSb * hb * r * nm[t + k + 4]
    k = TH_F_PITCH
    nm[t + k + 0] = (izz - ixx) / iyy
    nm[t + k + 1] = 0.0
    nm[t + k + 2] = nm[c + T_CPITCH0] / iyy
    nm[t + k + 3] = nm[c + T_CPITCH_Q] / iyy
    nm[t + k + 4] = CD / iyy
    nm[t + k + 5] = CL / iyy
    nm[x + k + 0] = p * r * nm[t + k + 0]
    nm[x + k + 1] = -q * nm[t + k + 1]
    nm[x + k + 2] = qSc * nm[t + k + 2]
    nm[x + k + 3] = qSc * hc * q * nm[t + k + 3]
    nm[x + k + 4] = xcg * qS * sa * nm[t + k + 4]
    nm[x + k + 5] = xcg * qS * ca * nm[t + k + 5]
    k = TH_F_YAW
    nm[t + k + 0] = (ixx - iyy) / izz
    nm[t + k + 1] = 0.0
    nm[t + k + 2] = nm[c + T_CYAW_B] / izz
    nm[t + k + 3] = nm[c + T_CYAW_P] / izz
    nm[t + k + 4] = nm[c + T_CYAW_R] / izz
    nm[t + k + 5] = CYb / izz
    nm[x + k + 0] = p * q * nm[t + k + 0]
    nm[x + k + 1] = -r * nm[t + k + 1]
    nm[x + k + 2] = qSb * beta * nm[t + k + 2]
    nm[x + k + 3] = qSb * hb * p * nm[t + k + 3]
    nm[x + k + 4] = qSb * hb * r * nm[t + k + 4]
    nm[x + k + 5] = xcg * qS * beta * nm[t + k + 5]
