"""US Standard Atmosphere 1976 (NOAA/NASA/USAF, NOAA-S/T 76-1562), -5 km to 86 km geometric.

The seven layers below 86 km, each with a linear molecular-scale temperature in geopotential
altitude H = r0 h / (r0 + h) (r0 = 6,356,766 m, the 1976 standard's effective earth radius):

| layer | H_b (m) | lapse (K/m) |
|---|---|---|
| 0 | 0 | -0.0065 |
| 1 | 11,000 | 0 |
| 2 | 20,000 | +0.0010 |
| 3 | 32,000 | +0.0028 |
| 4 | 47,000 | 0 |
| 5 | 51,000 | -0.0028 |
| 6 | 71,000 | -0.0020 |
(top at H = 84,852 m = 86 km geometric.)

Pressure from the hydrostatic equation layer by layer (standard Eqs. 33a/33b), density from the
molecular-scale temperature (rho = p M0 / (R* Tm)), kinetic temperature T = Tm M/M0 with the
standard's Table 8 ratio M/M0 between 80 and 86 km (1 below), speed of sound from the
molecular-scale temperature (a = sqrt(gamma R* Tm / M0)), gravity g = g0 (r0 / (r0 + h))^2.

Outside [-5 km, 86 km] the altitude is clipped to the range (the caller can see it in the
returned flag).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from plant_sim._jitcache import refresh as _refresh_jit_cache

_refresh_jit_cache(__file__)

# Constants of the 1976 standard (SI).
G0_M_S2 = 9.80665
R_EARTH_M = 6356766.0
R_STAR_J_KMOL_K = 8314.32          # J/(kmol K), the standard's gas constant
M0_KG_KMOL = 28.9644               # sea-level mean molecular weight
R_AIR_J_KG_K = R_STAR_J_KMOL_K / M0_KG_KMOL
GAMMA_AIR = 1.4
T0_K = 288.15
P0_PA = 101325.0
H_MIN_M = -5000.0
H_MAX_M = 86000.0

# Layer bases (geopotential m) and lapse rates (K per geopotential m).
_HB = np.array([0.0, 11000.0, 20000.0, 32000.0, 47000.0, 51000.0, 71000.0, 84852.0])
_LB = np.array([-0.0065, 0.0, 0.0010, 0.0028, 0.0, -0.0028, -0.0020, 0.0])


def _layer_bases():
    tb = np.empty(8)
    pb = np.empty(8)
    tb[0] = T0_K
    pb[0] = P0_PA
    gmr = G0_M_S2 / R_AIR_J_KG_K
    for i in range(7):
        dh = _HB[i + 1] - _HB[i]
        tb[i + 1] = tb[i] + _LB[i] * dh
        if _LB[i] == 0.0:
            pb[i + 1] = pb[i] * math.exp(-gmr * dh / tb[i])
        else:
            pb[i + 1] = pb[i] * (tb[i] / tb[i + 1]) ** (gmr / _LB[i])
    return tb, pb


_TB, _PB = _layer_bases()

# Table 8 of the standard: M/M0 at geometric altitudes 80.0 .. 86.0 km in 0.5 km steps.
_MRATIO_H0_M = 80000.0
_MRATIO_DH_M = 500.0
_MRATIO = np.array([1.000000, 0.999996, 0.999989, 0.999971, 0.999941, 0.999909, 0.999870,
                    0.999829, 0.999786, 0.999741, 0.999694, 0.999641, 0.999579])

# Output layout of us76().
A_T_K = 0
A_P_PA = 1
A_RHO_KG_M3 = 2
A_SOUND_M_S = 3
A_G_M_S2 = 4
A_N = 5


@njit(cache=True)
def us76(h_m, out):
    """US Standard Atmosphere 1976 at geometric altitude ``h_m`` (m).

    Writes ``out[A_T_K]`` temperature (K), ``out[A_P_PA]`` pressure (Pa),
    ``out[A_RHO_KG_M3]`` density (kg/m^3), ``out[A_SOUND_M_S]`` speed of sound (m/s),
    ``out[A_G_M_S2]`` gravity (m/s^2). Returns 1 if ``h_m`` was outside [-5 km, 86 km] and
    was clipped, else 0.
    """
    clipped = 0
    h = h_m
    if h < H_MIN_M:
        h = H_MIN_M
        clipped = 1
    elif h > H_MAX_M:
        h = H_MAX_M
        clipped = 1
    hgp = R_EARTH_M * h / (R_EARTH_M + h)
    i = 0
    while i < 6 and hgp >= _HB[i + 1]:
        i += 1
    lb = _LB[i]
    dh = hgp - _HB[i]
    tm = _TB[i] + lb * dh
    gmr = G0_M_S2 / R_AIR_J_KG_K
    if lb == 0.0:
        p = _PB[i] * math.exp(-gmr * dh / _TB[i])
    else:
        p = _PB[i] * (_TB[i] / tm) ** (gmr / lb)
    ratio = 1.0
    if h > _MRATIO_H0_M:
        x = (h - _MRATIO_H0_M) / _MRATIO_DH_M
        k = int(x)
        if k >= 12:
            ratio = _MRATIO[12]
        else:
            f = x - k
            ratio = _MRATIO[k] + f * (_MRATIO[k + 1] - _MRATIO[k])
    out[A_T_K] = tm * ratio
    out[A_P_PA] = p
    out[A_RHO_KG_M3] = p / (R_AIR_J_KG_K * tm)
    out[A_SOUND_M_S] = math.sqrt(GAMMA_AIR * R_AIR_J_KG_K * tm)
    rr = R_EARTH_M / (R_EARTH_M + h)
    out[A_G_M_S2] = G0_M_S2 * rr * rr
    return clipped


@njit(cache=True)
def gravity_m_s2(h_m):
    """Gravity at geometric altitude ``h_m`` (inverse square from g0 at r0 = 6,356,766 m)."""
    rr = R_EARTH_M / (R_EARTH_M + h_m)
    return G0_M_S2 * rr * rr
