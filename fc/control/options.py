"""Named values of the law's integer options (parameter table: fc/control/params.py).

The parameter array is float64 (it is one MAVLink PARAM_SET away from any value the table
validates), so an option is read as ``option(par, P_X)`` (the nearest whole number) and
compared with the names below; a 0/1 switch is read as ``switch_on(par, P_X)``. Module-level
ints, not an IntEnum, so that numba freezes them into the kernels.
"""
from __future__ import annotations

from numba import njit


# CO_FAC_EQ: which equation gives lambda_e, lambda_a
FAC_EQ14 = 14            # Eq. 14 (the prose before it): lambda_e = k4 alpha + k5 p, ...
FAC_EQ19 = 19            # Eq. 19 (what Section 4.3 builds g_Gamma from): k4 alpha + k5 q, ...

# CO_NORM: how a factor is added to the diagonal of g_f_delta (Eq. 45)
NORM_RELATIVE = 0        # Gamma_ii = lambda_i g_ii
NORM_COEFFICIENT = 1     # Gamma_ii = lambda_i qbar S l_i (per-rad coefficient)
NORM_LITERAL = 2         # Gamma_ii = lambda_i in N m/rad

# CO_MAP: where the factors act
MAP_DIAGONAL = 0         # diag(lambda) added (CO_NORM applies)
MAP_PROSE = 1            # each row scaled by (1 + lambda) of the loop the prose names

# CO_SURF: surface coordination (Eq. 47)
SURF_OFF = 0
SURF_INTERCONNECT = 1    # delta_a_out = delta_a + E delta_r
SURF_LITERAL = 2         # delta_a = E delta_r

# ALLOC_MODE: saturation of the allocation (Eq. 46)
ALLOC_CLIP = 0           # clip each surface (the printed paper)
ALLOC_SCALE = 1          # scale the whole vector (the moment keeps its direction)
ALLOC_PRIO = 2           # fix the worst surface at its limit, re-solve the rest by weighted
                         # least squares on the axes' angular accelerations (ALLOC_W_*)

# DOB_ACHIEVED: the moment fed to the observer (Eq. 37)
DOB_MOMENT_MC = 0        # M_c as printed
DOB_MOMENT_GFD = 1       # g_f_delta delta_model (the physical moment)
DOB_MOMENT_GCO = 2       # g_Gamma delta_model (the coordinated moment of Eq. 44)


@njit(cache=True, inline="always", error_model="numpy")
def option(par, i):
    """The integer option par[i] (nearest whole number)."""
    return int(par[i] + 0.5)


@njit(cache=True, inline="always", error_model="numpy")
def switch_on(par, i):
    """True if the 0/1 switch par[i] is on."""
    return par[i] > 0.5
