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
"""
from __future__ import annotations

import numpy as np

from fc.control import kernels as K
from fc.control.layout import E_N, NM_N, S_N, STATUS_NAMES, X_N
from fc.control.nominal import load_tables
from fc.control.params import LAW_PARAMS, PARAM_INDEX, P_N, default_si_array, to_si

STATUS_N = S_N

_TABLES = None


def _tables():
    """The nominal tables, loaded once per process (read-only afterwards)."""
    global _TABLES
    if _TABLES is None:
        _TABLES = load_tables()
    return _TABLES


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
    """

    STATUS_NAMES = STATUS_NAMES
    STATUS_N = STATUS_N

    def __init__(self, overrides: dict[str, float] | None = None):
        self.par = default_si_array()
        self.x = np.zeros(X_N)
        self.nm = np.zeros(NM_N)
        self.status = np.zeros(S_N)
        self.delta_cmd_rad = np.zeros(3)
        self._cmd = np.zeros(3)
        self._zero3 = np.zeros(3)
        self.tab, self.atm, self.grid = _tables()
        self._values = {p.name: p.default for p in LAW_PARAMS}
        for name, value in (overrides or {}).items():
            self.set_param(name, value)

    # -- parameters ---------------------------------------------------------------------------
    def set_param(self, name: str, value: float) -> None:
        """Set parameter ``name`` to ``value`` in the table's unit (converted to SI here)."""
        self.par[PARAM_INDEX[name]] = to_si(name, value)
        self._values[name] = float(value)

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
        """Slow loop (Eqs. 27-30): est float64[E_N]; cmd_rad (alpha_c, beta_c, mu_c) rad."""
        c = self._cmd
        c[0] = cmd_rad[0]
        c[1] = cmd_rad[1]
        c[2] = cmd_rad[2]
        K.slow_kernel(est, c, float(dt_s), self.par, self.x, self.nm, self.status,
                      self.tab, self.atm, self.grid)

    def fast_step(self, est: np.ndarray, dt_s: float) -> None:
        """Fast loop (Eqs. 34-37, 44-47): writes ``delta_cmd_rad`` and ``status``."""
        K.fast_kernel(est, float(dt_s), self.par, self.x, self.nm, self.status,
                      self.tab, self.atm, self.grid, self.delta_cmd_rad)

    def cycle(self, est: np.ndarray, cmd_rad, slow_dt_s: float, fast_dt_s: float) -> None:
        """``slow_step`` then ``fast_step`` in one compiled call (saves one numba dispatch,
        ~0.6 us): for ticks where both loops are due."""
        c = self._cmd
        c[0] = cmd_rad[0]
        c[1] = cmd_rad[1]
        c[2] = cmd_rad[2]
        K.cycle_kernel(est, c, float(slow_dt_s), float(fast_dt_s), 1, self.par, self.x,
                       self.nm, self.status, self.tab, self.atm, self.grid, self.delta_cmd_rad)

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


def _check_est(est) -> None:
    if not isinstance(est, np.ndarray) or est.dtype != np.float64 or est.shape != (E_N,):
        raise ValueError(f"est must be a float64[{E_N}] numpy array (fc.control.layout E_*)")
    if not np.all(np.isfinite(est)):
        raise ValueError("est contains a non-finite value")


__all__ = ["AttitudeLaw", "STATUS_NAMES", "STATUS_N", "P_N"]
