"""Where the in-process closed loop's time goes, per frame, each part timed alone in numba.

The in-process loop (tools.sitl.closed_loop._run) does per frame: the plant's truth row
(``truth_kernel``: what the law reads), the law (slow loop every 5th frame, fast loop every
frame: ``law_frame``), the recording of the truth row and the law's status, and the plant's
advance by one frame (``advance_frame``: two RK4 steps at 1 kHz physics). This module times each
part in a loop of its own inside numba, from the state the paper scenario starts in, so the
sum can be set against the whole loop and the plant's share (the "plant alone" reference of
issue 16) read off: the ceiling of "in-process / plant alone" is plant / (plant + the rest).
Nothing is asserted: the function returns figures (us per frame).
"""
from __future__ import annotations

import time

import numpy as np
from numba import njit

from plant_sim import dynamics as dy
from tools.sitl.closed_loop import law_frame, truth_kernel

__all__ = ["closed_loop_parts"]


@njit(cache=True)
def _plant_frames(n, x, delta, p, w, n_sub):
    for _ in range(n):
        dy.advance_frame(x, delta, p, w, n_sub)


@njit(cache=True)
def _truth_rows(n, x, p, w, meas, row):
    for _ in range(n):
        truth_kernel(x, p, w, meas, row)


@njit(cache=True)
def _law_frames(n, n_slow, dt_fast_s, dt_slow_s, est, cmd, par, lx, nm, st, tab, atm, grid,
                delta):
    for k in range(n):
        law_frame(k + 1, n_slow, 1, dt_slow_s, dt_fast_s, est, cmd, par, lx, nm, st, tab, atm,
                  grid, delta)


@njit(cache=True)
def _records(n, row, st, out_truth, out_status):
    m = out_truth.shape[0]
    for k in range(n):
        j = k % m
        for i in range(row.shape[0]):
            out_truth[j, i] = row[i]
        for i in range(st.shape[0]):
            out_status[j, i] = st[i]


def _median_us_per_frame(fn, n: int, reps: int, *args) -> float:
    fn(10, *args)                         # loads (or compiles) the machine code
    per = []
    for _ in range(reps):
        t0 = time.perf_counter()
        fn(n, *args)
        per.append((time.perf_counter() - t0) / n * 1e6)
    return float(np.median(per))


def closed_loop_parts(quick: bool = False, scenario: str = "paper") -> dict:
    """Per-frame cost (us, median of batches) of each part of the in-process loop."""
    import fc.control.layout as L
    from fc.control.law import AttitudeLaw
    from hyfc_wire.layout import M_N
    from plant_sim.scenario import load
    from plant_sim.sim import PlantSim
    from tools.sitl.closed_loop import TRUTH_N
    n = 2000 if quick else 10000
    reps = 3 if quick else 7
    sim = PlantSim(load(scenario))
    x, p, w, n_sub, _ring, _rc, _rng, _mw = sim.kernel_args()
    x0 = x.copy()
    law = AttitudeLaw({"CO_ENABLE": 1.0, "REF_PF_EN": 0.0})
    k = law.kernel_args()
    meas = np.zeros(M_N)
    row = np.zeros(TRUTH_N)
    truth_kernel(x, p, w, meas, row)
    est = np.ascontiguousarray(row[1:1 + L.E_N])
    cmd = np.array(sim.cmd_rad, dtype=np.float64) if np.size(sim.cmd_rad) == 3 else np.zeros(3)
    law.reset(est, cmd)
    dt = sim.frame_dt_s
    out = {"frame_dt_s": dt}
    out["plant_us"] = _median_us_per_frame(_plant_frames, n, reps, x, np.zeros(3), p, w, n_sub)
    x[:] = x0
    out["truth_row_us"] = _median_us_per_frame(_truth_rows, n, reps, x, p, w, meas, row)
    out["law_us"] = _median_us_per_frame(_law_frames, n, reps, 5, dt, 5 * dt, est, cmd,
                                         k["par"], k["x"], k["nm"], k["st"], k["tab"],
                                         k["atm"], k["grid"], k["delta"])
    out["record_us"] = _median_us_per_frame(_records, n, reps, row, k["st"],
                                            np.zeros((1000, row.size)),
                                            np.zeros((1000, k["st"].size)))
    out["sum_us"] = out["plant_us"] + out["truth_row_us"] + out["law_us"] + out["record_us"]
    out["plant_share_ceiling"] = out["plant_us"] / out["sum_us"]
    out["ceiling_without_truth_row"] = out["plant_us"] / (out["plant_us"] + out["law_us"])
    return out
