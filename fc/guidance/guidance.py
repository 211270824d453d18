"""Guidance: the outer loop as a small stateful object over the njit kernels (no I/O).

    g = Guidance({"GE_MU_MAX": 25})          # table units (fc.guidance.params)
    g.reset(est, thr_now=-1.0)               # est: the law's float64[E_N]
    every guidance period (e.g. 20 ms):
        g.step(est, chi_rad, dt_s)           # -> g.out = alpha_c, beta_c, mu_c (rad), throttle
    g.set_targets(h_m=..., chi_rad=..., V_m_s=... or mach=...)
    g.status, g.status_dict(), g.limits_in_force()

The nominal model (mass, c.g. offset and tables) is the law's (fc.control); pass the law's
``MDL_MASS`` / ``MDL_XCG`` through ``set_model`` if they differ from the defaults. Tools that
need speed call ``kernels.guidance_step`` directly with ``kernel_args()``.
"""
from __future__ import annotations

import math

import numpy as np

from fc.control.carrays import ArrayAddress
from fc.control.layout import E_N
from fc.control.nominal import load_tables
from fc.control.params import LAW_PARAMS, PARAM_INDEX as LAW_INDEX
from fc.guidance import kernels as K
from fc.guidance.layout import (GO_N, GS_LIMITS, GS_N, GUIDANCE_STATUS_NAMES, GX_N,
                                LIMIT_NAMES, TG_CHI, TG_H, TG_MACH, TG_N, TG_V)
from fc.guidance.params import (GUIDANCE_PARAMS, P_N, PARAM_INDEX, default_si_array,
                                to_si)

_TABLES = None


def _tables():
    global _TABLES
    if _TABLES is None:
        _TABLES = load_tables()
    return _TABLES


def limit_names(bits: int) -> list[str]:
    """Names (layout.LIMIT_NAMES) of the bits set in a limit bitfield."""
    return [n for i, n in enumerate(LIMIT_NAMES) if int(bits) >> i & 1]


class Guidance:
    """Altitude, course and speed targets -> alpha/beta/mu commands and a throttle command.

    Parameters
    ----------
    overrides : dict name -> value in the guidance table's units (fc.guidance.params).
    """

    STATUS_NAMES = GUIDANCE_STATUS_NAMES

    def __init__(self, overrides: dict | None = None) -> None:
        self.par = default_si_array()
        self.tgt = np.zeros(TG_N)
        self.gx = np.zeros(GX_N)
        self.out = np.zeros(GO_N)
        self.status = np.zeros(GS_N)
        self.work = np.zeros(K.GW_N)
        self.tab, self.atm, self.grid = _tables()
        # step()'s arrays by address, bound on first use (fc/control/carrays.py)
        self._at = [ArrayAddress(np.float64, n) for n in (E_N, TG_N, P_N, GX_N, GO_N, GS_N,
                                                           K.GW_N, self.tab.size,
                                                           self.atm.size, self.grid.size)]
        self._sizes = (E_N, TG_N, P_N, GX_N, GO_N, GS_N, K.GW_N) + self._table_dims()
        self.mass_kg = LAW_PARAMS[LAW_INDEX["MDL_MASS"]].default
        self.xcg_m = LAW_PARAMS[LAW_INDEX["MDL_XCG"]].default
        for k, v in (overrides or {}).items():
            self.set_param(k, v)

    def set_param(self, name: str, value: float) -> None:
        """Set one parameter in table units (KeyError unknown, ValueError out of range)."""
        self.par[PARAM_INDEX[name]] = to_si(name, value)

    def params(self) -> dict:
        """Every parameter in table units."""
        return {p.name: float(self.par[i] / p.si_scale) for i, p in enumerate(GUIDANCE_PARAMS)}

    def set_model(self, mass_kg: float, xcg_m: float) -> None:
        """The nominal model's mass (kg) and MRC -> c.g. offset (m, + aft): the law's MDL_*."""
        if not (math.isfinite(mass_kg) and mass_kg > 0 and math.isfinite(xcg_m)):
            raise ValueError(f"bad nominal model: mass {mass_kg} kg, x_cg {xcg_m} m")
        self.mass_kg = float(mass_kg)
        self.xcg_m = float(xcg_m)

    def set_targets(self, h_m: float | None = None, chi_rad: float | None = None,
                    V_m_s: float | None = None, mach: float | None = None) -> None:
        """Set any of the targets (None keeps it). A speed target clears the Mach target and
        a Mach target (> 0) overrides the speed target."""
        for v in (h_m, chi_rad, V_m_s, mach):
            if v is not None and not math.isfinite(v):
                raise ValueError("targets must be finite")
        if h_m is not None:
            self.tgt[TG_H] = h_m
        if chi_rad is not None:
            self.tgt[TG_CHI] = chi_rad
        if V_m_s is not None:
            self.tgt[TG_V] = V_m_s
            self.tgt[TG_MACH] = 0.0
        if mach is not None:
            self.tgt[TG_MACH] = mach

    def reset(self, est: np.ndarray, thr_now: float = -1.0) -> None:
        """Start at the current state (bumpless); ``thr_now`` the throttle in use (0..1), or
        negative to start at the first step's own throttle."""
        K.guidance_reset(est, self.par, self.mass_kg, self.xcg_m, self.gx, float(thr_now),
                         self.work, self.tab, self.atm, self.grid)

    def step(self, est: np.ndarray, chi_rad: float, dt_s: float) -> int:
        """One guidance step; writes ``out`` and ``status``; returns the limit bitfield.
        The arrays go by address (fc/control/carrays.py: no numba record per step), with the
        shapes bound at construction (the tables are never rebound); an array that cannot be
        viewed so (not C-contiguous float64) goes through the array entry."""
        return self._step(est, chi_rad, dt_s, K.guidance_step_p)

    def step_f(self, est: np.ndarray, chi_rad: float, dt_s: float) -> float:
        """:meth:`step` returning the limit bitfield as a float (the same bits, exact): no
        Python int made per step when a bit past 256 is set (the fc's tick)."""
        return float(self._step(est, chi_rad, dt_s, K.guidance_step_pf))

    def _step(self, est: np.ndarray, chi_rad: float, dt_s: float, kernel_p):
        """:meth:`step` through ``kernel_p`` (the by-address entry: ``guidance_step_p`` or
        ``guidance_step_pf``)."""
        a = self._at
        try:
            est_p = a[0].of(est)
            tgt_p, par_p, gx_p = a[1].of(self.tgt), a[2].of(self.par), a[3].of(self.gx)
            out_p, st_p, gw_p = a[4].of(self.out), a[5].of(self.status), a[6].of(self.work)
            tab_p, atm_p, grid_p = a[7].of(self.tab), a[8].of(self.atm), a[9].of(self.grid)
        except ValueError:
            return K.guidance_step(est, float(chi_rad), self.tgt, float(dt_s), self.par,
                                   self.mass_kg, self.xcg_m, self.gx, self.out, self.status,
                                   self.work, self.tab, self.atm, self.grid)
        return kernel_p(est_p, float(chi_rad), tgt_p, float(dt_s), par_p, self.mass_kg,
                        self.xcg_m, gx_p, out_p, st_p, gw_p, tab_p, atm_p, grid_p, self._sizes)

    def _table_dims(self) -> tuple:
        return self.tab.shape + self.atm.shape + self.grid.shape

    def status_dict(self) -> dict:
        return dict(zip(GUIDANCE_STATUS_NAMES, (float(v) for v in self.status)))

    def limits_in_force(self) -> list[str]:
        return limit_names(int(self.status[GS_LIMITS]))

    def kernel_args(self) -> dict:
        return {"tgt": self.tgt, "par": self.par, "gx": self.gx, "out": self.out,
                "st": self.status, "gw": self.work, "tab": self.tab, "atm": self.atm,
                "grid": self.grid, "mass_kg": self.mass_kg, "xcg_m": self.xcg_m}
