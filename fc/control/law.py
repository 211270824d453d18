"""AttitudeLaw: the robust coordinated attitude law as a small stateful object (no I/O).

A thin wrapper over the numba kernels of fc/control/kernels.py (docs/architecture.md s. 11):
it allocates every array once, converts parameters from the table's human units to SI in
``set_param`` (the one conversion point), and calls the kernels. Typical use by the fc::

    law = AttitudeLaw({"CO_ENABLE": 1})
    law.reset(est)                                # est: float64[E_N] (fc.control.layout)
    every slow period:  law.slow_step(est, cmd_rad, dt_s)   # cmd_rad = alpha_c, beta_c, mu_c
    every fast period:  law.fast_step(est, dt_s)            # -> law.delta_cmd_rad (float64[3])
    law.status        # float64[STATUS_N], names in law.STATUS_NAMES

Tools that need speed call the kernels directly with ``law.kernel_args()``.

Per-tick cost: par, x, nm, status, delta_cmd_rad, the last command and the law's copy of
the nominal tables are views of one buffer ``mem`` (layout kernels.MEM_*), so
``slow_step``/``fast_step`` call one compiled entry point with 2 array arguments
(kernels.slow_entry / fast_entry) instead of 10: numba's per-argument unboxing was most of
the per-call cost. The wrappers do no other Python work (no copies, no conversions).
"""
from __future__ import annotations

import numpy as np

from fc.control import kernels as K
from fc.control.carrays import ArrayAddress, address_of
from fc.control.layout import (ATM_N, E_N, G_N, G_NALPHA, G_NH, G_NMACH, NM_N, S_N,
                               STATUS_NAMES, T_N, X_N)
from fc.control.nominal import load_tables
from fc.control.params import (LAW_PARAMS, PARAM_INDEX, P_N, SCHEDULED_NAMES,
                               default_si_array, to_si)

STATUS_N = S_N

_TABLES = None


def _tables():
    """The nominal tables packed (kernels.pack_tables: grid | tab | atm), loaded once per
    process; each law copies them into its ``mem``. Read-only."""
    global _TABLES
    if _TABLES is None:
        _TABLES = K.pack_tables(*load_tables())
    return _TABLES


def _table_views(mem: np.ndarray, o: int):
    """(tab, atm, grid) numpy views of the packed tables at mem[o:] (as K.unpack_tables)."""
    grid = mem[o:o + G_N]
    n_mach, n_alpha, n_h = int(grid[G_NMACH]), int(grid[G_NALPHA]), int(grid[G_NH])
    a = o + G_N
    b = a + n_mach * n_alpha * T_N
    return (mem[a:b].reshape(n_mach, n_alpha, T_N),
            mem[b:b + n_h * ATM_N].reshape(n_h, ATM_N), grid)


class AttitudeLaw:
    """The paper's slow/fast attitude law with coordinated allocation.

    Parameters
    ----------
    overrides : dict name -> value in the parameter table's units (fc.control.params);
        KeyError for an unknown name, ValueError for a value out of range.

    Attributes
    ----------
    delta_cmd_rad : float64[3]  surface command (rad): left elevon, right elevon, rudder.
    status : float64[STATUS_N]  internal status record (names in STATUS_NAMES).
    par : float64[P_N]          parameters in SI (read-only for callers; use set_param).
    x, nm : float64[X_N], float64[NM_N]  internal state and nominal model (layout.py).
    tab, atm, grid : the nominal tables (layout.py), the law's own copy (read-only).
    mem : float64[kernels.MEM_TABLES + tables]  the buffer that par, x, nm, status,
        delta_cmd_rad, tab, atm, grid are views of (allocated once; never rebind those).
    """

    STATUS_NAMES = STATUS_NAMES
    STATUS_N = STATUS_N

    def __init__(self, overrides: dict[str, float] | None = None):
        packed = _tables()
        m = self.mem = np.zeros(K.MEM_TABLES + packed.size)
        m[K.MEM_TABLES:] = packed
        self.par = m[K.MEM_PAR:K.MEM_PAR + P_N]
        self.par[:] = default_si_array()
        self.x = m[K.MEM_X:K.MEM_X + X_N]
        self.nm = m[K.MEM_NM:K.MEM_NM + NM_N]
        self.status = m[K.MEM_ST:K.MEM_ST + S_N]
        self.delta_cmd_rad = m[K.MEM_DELTA:K.MEM_DELTA + 3]
        self._cmd = m[K.MEM_CMD:K.MEM_CMD + 3]
        self._zero3 = np.zeros(3)
        # the loops' arrays by address (fc/control/carrays.py), bound on first use
        self._mem_p = address_of(m, np.float64, m.size)
        self._mem_n = m.size
        self._est_at = ArrayAddress(np.float64, E_N)
        self._cmd_at = ArrayAddress(np.float64, 3)
        self.tab, self.atm, self.grid = _table_views(m, K.MEM_TABLES)
        self._values = {p.name: p.default for p in LAW_PARAMS}
        for name, value in (overrides or {}).items():
            self.set_param(name, value)

    # -- parameters ---------------------------------------------------------------------------
    def set_param(self, name: str, value: float) -> None:
        """Set parameter ``name`` to ``value`` in the table's unit (converted to SI here).

        While the schedule is on (CTL_SCHED 1, PAPER_LITERAL 0) the slow loop overwrites the
        SI slots of the scheduled parameters (params.SCHEDULED_NAMES) with the schedule's
        values; when it goes off, their fixed values are put back here.
        """
        self.par[PARAM_INDEX[name]] = to_si(name, value)
        self._values[name] = float(value)
        if name in ("CTL_SCHED", "PAPER_LITERAL") and not self.scheduled():
            for fixed in SCHEDULED_NAMES:
                self.par[PARAM_INDEX[fixed]] = to_si(fixed, self._values[fixed])

    def scheduled(self) -> bool:
        """True if the gain schedule is on (CTL_SCHED 1 and PAPER_LITERAL 0)."""
        return self._values["CTL_SCHED"] >= 0.5 and self._values["PAPER_LITERAL"] < 0.5

    def get_param(self, name: str) -> float:
        """Current value of ``name`` in the table's unit."""
        if name not in PARAM_INDEX:
            raise KeyError(f"unknown control-law parameter {name!r}")
        return self._values[name]

    def params(self) -> dict[str, float]:
        """All parameters, name -> value in the table's units (a new dict)."""
        return dict(self._values)

    # -- loops --------------------------------------------------------------------------------
    def reset(self, est: np.ndarray, delta_rad: np.ndarray | None = None) -> None:
        """Start integrators, filters and estimates at the estimated state ``est``.

        ``delta_rad`` (optional, float64[3]): the surfaces' current deflection, if known, for
        the controller's actuator model (default 0).
        """
        d0 = self._zero3 if delta_rad is None else np.asarray(delta_rad, dtype=np.float64)
        _check_est(est)
        K.reset_kernel(est, self.par, self.x, self.status, d0)
        self.delta_cmd_rad[:] = d0

    def slow_step(self, est: np.ndarray, cmd_rad, dt_s: float) -> None:
        """Slow loop (Eqs. 27-30): est float64[E_N]; cmd_rad (alpha_c, beta_c, mu_c) rad
        (a float64[3] array is passed as is; any other sequence is copied first); dt_s (s), a
        float (an int would compile a second specialization on its first call)."""
        if type(cmd_rad) is not _ndarray:
            cmd_rad = self._copy_cmd(cmd_rad)
        # by address (fc/control/carrays.py): no numba array record per call; an array that
        # is not C-contiguous float64 goes through the array entry
        try:
            est_p = self._est_at.of(est)
            cmd_p = self._cmd_at.of(cmd_rad)
        except ValueError:
            _slow_entry(est, cmd_rad, dt_s, self.mem)
            return
        _slow_entry_p(est_p, E_N, cmd_p, dt_s, self._mem_p, self._mem_n)

    def fast_step(self, est: np.ndarray, dt_s: float) -> None:
        """Fast loop (Eqs. 34-37, 44-47): writes ``delta_cmd_rad`` and ``status``."""
        try:
            est_p = self._est_at.of(est)
        except ValueError:
            _fast_entry(est, dt_s, self.mem)
            return
        _fast_entry_p(est_p, E_N, dt_s, self._mem_p, self._mem_n)

    def cycle(self, est: np.ndarray, cmd_rad, slow_dt_s: float, fast_dt_s: float) -> None:
        """``slow_step`` then ``fast_step`` in one compiled call (saves one numba dispatch):
        for ticks where both loops are due."""
        if type(cmd_rad) is not _ndarray:
            cmd_rad = self._copy_cmd(cmd_rad)
        _cycle_entry(est, cmd_rad, slow_dt_s, fast_dt_s, self.mem)

    def _copy_cmd(self, cmd_rad) -> np.ndarray:
        c = self._cmd
        c[0] = cmd_rad[0]
        c[1] = cmd_rad[1]
        c[2] = cmd_rad[2]
        return c

    def kernel_args(self) -> dict[str, np.ndarray]:
        """The law's arrays for calling fc.control.kernels directly (no copies).

        Keys: par, x, nm, st (= status), tab, atm, grid, delta (= delta_cmd_rad), cmd.
        slow_kernel(est, cmd, dt, par, x, nm, st, tab, atm, grid);
        fast_kernel(est, dt, par, x, nm, st, tab, atm, grid, delta).
        """
        return {"par": self.par, "x": self.x, "nm": self.nm, "st": self.status,
                "tab": self.tab, "atm": self.atm, "grid": self.grid,
                "delta": self.delta_cmd_rad, "cmd": self._cmd}

    def status_dict(self) -> dict[str, float]:
        """The status record as name -> value (allocates; for logs and tests, not hot loops)."""
        return {n: float(v) for n, v in zip(STATUS_NAMES, self.status)}


_ndarray = np.ndarray
_slow_entry = K.slow_entry
_fast_entry = K.fast_entry
_slow_entry_p = K.slow_entry_p
_fast_entry_p = K.fast_entry_p
_cycle_entry = K.cycle_entry


def _check_est(est) -> None:
    if not isinstance(est, np.ndarray) or est.dtype != np.float64 or est.shape != (E_N,):
        raise ValueError(f"est must be a float64[{E_N}] numpy array (fc.control.layout E_*)")
    if not np.all(np.isfinite(est)):
        raise ValueError("est contains a non-finite value")


__all__ = ["AttitudeLaw", "STATUS_NAMES", "STATUS_N", "P_N"]
