"""The control law's numba kernels: the entry points the fc and the tools call.

Paper: Mu, Wang, Wu, Ying, "Robust Coordinated Control for a Type of Hypersonic Aircraft",
Trans. NUAA 35(6) 2018. docs/control_law.md maps every equation to its function and lists
the decisions taken where the paper is garbled or silent. The kernels are split by the
paper's structure; this module holds the entry points and re-exports the rest:

    slow_loop    slow_kernel: reference prefilter, Eq. 27 sliding surface, Eq. 29 virtual
                 rate command omega_c (with its limit), Eq. 30 adaptive law for theta_Omega
    fast_loop    fast_kernel: input filters, command filter, Eq. 35 moment command M_c,
                 Eq. 36 adaptive law for theta_omega, factors, allocation, observer
    factors      coordinated_factors (Eqs. 10-14, 19), coordinated_matrix (Eq. 45)
    allocation   allocate (Eqs. 46-47 with saturation), rate_limit_command, actuator_model_step
    observer     dob_gain, dob_estimate, dob_update (Eq. 37)
    kinematics   gs, gs_inv, gs_t (Eq. 3) and their *_apply forms
    filters      second_order_phi/_step, lowpass2_step, input_ok
    linalg3      det3, solve3, matvec3, clip, wrap_pi
    options      named values of the integer options (CO_FAC_EQ, CO_SURF, ALLOC_MODE, ...)

All kernels work in place on flat float64 arrays (layouts in fc/control/layout.py, parameter
slots in fc/control/params.py) and allocate nothing:

    slow_kernel(est, cmd, dt_s, par, x, nm, st, tab, atm, grid)
    fast_kernel(est, dt_s, par, x, nm, st, tab, atm, grid, delta_out)
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

from numba import carray, njit

import numpy as np

from fc.control.carrays import f8p
from fc.control.allocation import actuator_model_step, allocate, rate_limit_command
from fc.control.factors import coordinated_factors, coordinated_matrix
from fc.control.fast_loop import fast_kernel
from fc.control.filters import input_ok, lowpass2_step, second_order_phi, second_order_step
from fc.control.kinematics import gs, gs_apply, gs_inv, gs_inv_apply, gs_t, gs_t_apply
from fc.control.layout import (
    ATM_N, E_N, E_ALPHA, E_P, G_N, G_NALPHA, G_NH, G_NMACH, NM_N, S_ALLOC_SCALE, S_N, T_N,
    X_AF1, X_AF2, X_CF, X_DCMD, X_DM, X_EF, X_N, X_OMC, X_PF, X_WF1, X_WF2, X_Z,
)
from fc.control.linalg3 import PI, clip, det3, matvec3, solve3, wrap_pi
from fc.control.observer import dob_estimate, dob_gain, dob_update
from fc.control.params import P_DOB_C, P_N
from fc.control.slow_loop import slow_kernel


__all__ = [
    "actuator_model_step", "allocate", "coordinated_factors", "coordinated_matrix",
    "cycle_entry", "cycle_kernel", "det3", "dob_estimate", "dob_gain", "dob_update",
    "fast_entry", "fast_kernel", "gs", "gs_apply", "gs_inv", "gs_inv_apply", "gs_t",
    "gs_t_apply", "input_ok", "lowpass2_step", "matvec3", "pack_tables", "rate_limit_command",
    "reset_kernel",
    "second_order_phi", "second_order_step", "slow_entry", "slow_kernel", "solve3",
    "unpack_tables", "clip", "wrap_pi", "PI",
    "MEM_PAR", "MEM_X", "MEM_NM", "MEM_ST", "MEM_DELTA", "MEM_CMD", "MEM_TABLES",
]


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
def slow_entry_p(est, est_n, cmd_rad, dt_s, mem, mem_n):
    """:func:`slow_entry` on the float64[est_n] estimate, the float64[3] command (rad) and the
    float64[mem_n] buffer given by address (fc/control/carrays.py: no array record per call)."""
    slow_entry(carray(f8p(est), (est_n,)), carray(f8p(cmd_rad), (3,)), dt_s,
               carray(f8p(mem), (mem_n,)))


@njit(cache=True, error_model="numpy")
def fast_entry_p(est, est_n, dt_s, mem, mem_n):
    """:func:`fast_entry` with its arrays given by address (as :func:`slow_entry_p`)."""
    fast_entry(carray(f8p(est), (est_n,)), dt_s, carray(f8p(mem), (mem_n,)))


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
