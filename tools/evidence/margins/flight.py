"""tools/evidence/margins/flight.py - one injected flight and its stability verdict, shared by
tools.evidence.margins (in process) and tools.evidence.margins.wire (over the wire), which import this module
and not each other (tests/unit/test_architecture.py: no import cycle)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class Flight:
    """One injected flight. Arrays per frame: t_s (n,), att_rad / rate_rad_s / v_c_rad /
    v_out_rad (n, 3); cmd_rad (3,) the step command; diverged: stopped early."""

    t_s: np.ndarray
    att_rad: np.ndarray
    rate_rad_s: np.ndarray
    v_c_rad: np.ndarray
    v_out_rad: np.ndarray
    cmd_rad: np.ndarray
    diverged: bool
    frame_dt_s: float


def stable(fl: Flight, tail_s: float = 4.0, att_tol_deg: float = 0.25,
           rate_tol_deg_s: float = 0.5) -> bool:
    """True if the flight ends settled: not diverged, and over the last ``tail_s`` the
    attitude error stays within ``att_tol_deg`` (about the 5 % settling band of the paper's
    4-5 deg steps) and each rate within ``rate_tol_deg_s`` of its mean over that window (the
    steady pull-up keeps q near 0.4 deg/s). A limit cycle or a divergence fails one of them."""
    if fl.diverged:
        return False
    n = int(round(tail_s / fl.frame_dt_s))
    e = np.degrees(np.abs(fl.att_rad[-n:] - fl.cmd_rad))
    r = np.degrees(fl.rate_rad_s[-n:])
    osc = np.abs(r - r.mean(axis=0))
    return bool(np.all(np.isfinite(e)) and np.all(np.isfinite(osc)) and e.max() < att_tol_deg
                and osc.max() < rate_tol_deg_s)
