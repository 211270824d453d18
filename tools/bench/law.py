"""Benchmark of the control law: cost of one full cycle and of each part, in microseconds.

    python -m tools.bench law [--batches 2000] [--batch 50] [--calls 20000]

Two views, both printed as median and p99 (plus p99.9 for the per-call view):

1. **Per call from Python** (what the fc process pays each tick): ``Estimator.update``,
   ``law.slow_step``, ``law.fast_step`` (one packed entry point each, 2-3 array arguments),
   the fc tick (update + fast step), and the two kernels called directly (10 arguments).
   Each call is timed with ``time.perf_counter_ns`` (about 60-90 ns of timer overhead
   included; docs/perf_anchors). numba's dispatch of a call with ~10 array arguments is a
   large share of this figure.
2. **Inside numba, per part**: each part run ``--batch`` times in a compiled loop, the batch
   timed from Python; the figure is batch time / batch size, median and p99 over
   ``--batches`` batches. This is the cost of the computation itself:
   full cycle (slow + fast), slow loop (Eqs. 27-30 + prefilter), fast loop (Eqs. 34-37 +
   factors + allocation + actuator model), nominal model evaluation, factors + coordinated
   matrix (Eqs. 13/14/45), allocation (Eqs. 46-47), disturbance observer (Eq. 37).

The cycle is flown at the paper's initial state with its commands (coordinated law, steps).
"""
from __future__ import annotations

import argparse
import math
import time

import numpy as np
from numba import njit

from fc.control import kernels as K
from fc.control import layout as L
from fc.control.law import AttitudeLaw
from fc.control.nominal import eval_model
from fc.estimator import Estimator
from fc.link import M_AIRSPEED, M_ALT, M_AOA, M_N, M_P, M_PITCH, M_Q, M_R, M_SSA, M_T_S

DEG = math.pi / 180.0


@njit(cache=True)
def _b_cycle(n, est, cmd, par, x, nm, st, tab, atm, grid, delta):
    for _ in range(n):
        K.slow_kernel(est, cmd, 0.01, par, x, nm, st, tab, atm, grid)
        K.fast_kernel(est, 0.002, par, x, nm, st, tab, atm, grid, delta)


@njit(cache=True)
def _b_slow(n, est, cmd, par, x, nm, st, tab, atm, grid, delta):
    for _ in range(n):
        K.slow_kernel(est, cmd, 0.01, par, x, nm, st, tab, atm, grid)


@njit(cache=True)
def _b_fast(n, est, cmd, par, x, nm, st, tab, atm, grid, delta):
    for _ in range(n):
        K.fast_kernel(est, 0.002, par, x, nm, st, tab, atm, grid, delta)


@njit(cache=True)
def _b_model(n, est, cmd, par, x, nm, st, tab, atm, grid, delta):
    for _ in range(n):
        eval_model(est, par, tab, atm, grid, nm)


@njit(cache=True)
def _b_factors(n, est, cmd, par, x, nm, st, tab, atm, grid, delta):
    for _ in range(n):
        K.coordinated_factors(est, par, st, L.S_LAMBDA)
        K.coordinated_matrix(par, nm, st, L.S_LAMBDA)


@njit(cache=True)
def _b_alloc(n, est, cmd, par, x, nm, st, tab, atm, grid, delta):
    for _ in range(n):
        K.allocate(par, nm, 1.0e6, -2.0e6, 5.0e5, 0.7, delta, st)


@njit(cache=True)
def _b_observer(n, est, cmd, par, x, nm, st, tab, atm, grid, delta):
    c_d = K.dob_gain(10.0, 0.002)
    for _ in range(n):
        d0, d1, d2 = K.dob_estimate(x, c_d, est[L.E_P], est[L.E_Q], est[L.E_R])
        K.dob_update(x, c_d, 0.002, d0, d1, d2, est[L.E_P], est[L.E_Q], est[L.E_R])


PARTS = (("full cycle (slow + fast)", _b_cycle), ("slow loop", _b_slow),
         ("fast loop (incl. factors, allocation, observer)", _b_fast),
         ("nominal model evaluation", _b_model), ("factors + coordinated matrix", _b_factors),
         ("allocation", _b_alloc), ("disturbance observer", _b_observer))


def _setup():
    law = AttitudeLaw({"CO_ENABLE": 1, "REF_PF_EN": 0})
    est = np.array([1 * DEG, 5 * DEG, 0.0, 0.01, -0.02, 0.03, 2200.0, 21000.0, 0.0])
    cmd = np.array([5 * DEG, 0.0, 4 * DEG])
    law.reset(est)
    return law, est, cmd


def _stats(us):
    a = np.asarray(us)
    return float(np.median(a)), float(np.percentile(a, 99)), float(np.percentile(a, 99.9))


def _meas(n: int) -> np.ndarray:
    """n measurement vectors (2 ms apart) at the paper's point, rates and angles moving."""
    m = np.zeros((n, M_N))
    t = 0.002 * np.arange(1, n + 1)
    m[:, M_T_S] = t
    m[:, M_PITCH] = 6 * DEG + 0.5 * DEG * np.sin(t)
    m[:, M_AOA] = 1 * DEG + 0.5 * DEG * np.sin(t)
    m[:, M_SSA] = 5 * DEG * np.cos(0.3 * t)
    m[:, M_P] = 0.01 * np.sin(2 * t)
    m[:, M_Q] = -0.02 * np.cos(t)
    m[:, M_R] = 0.03 * np.sin(t)
    m[:, M_AIRSPEED] = 2200.0
    m[:, M_ALT] = 21000.0
    return m


def bench_fc_steps(calls: int):
    """Per-call times (us) of the fc's own calls: Estimator.update, law.slow_step,
    law.fast_step, and the fc tick (update + fast step; the slow step every 5th tick)."""
    law, est0, cmd = _setup()
    e = Estimator(0.1)
    seq = _meas(calls + 200)
    e.update(seq[0])
    law.reset(e.est)
    est = e.est
    pc = time.perf_counter_ns
    upd = np.empty(calls)
    slow = np.empty(calls // 5)
    fast = np.empty(calls)
    tick = np.empty(calls)
    for i in range(1, 200):                                # warm-up
        e.update(seq[i])
        law.slow_step(est, cmd, 0.01)
        law.fast_step(est, 0.002)
    for i in range(calls):
        m = seq[200 + i]
        t0 = pc()
        e.update(m)
        t1 = pc()
        if i % 5 == 0:
            law.slow_step(est, cmd, 0.01)
        t2 = pc()
        law.fast_step(est, 0.002)
        t3 = pc()
        upd[i] = (t1 - t0) / 1e3
        if i % 5 == 0:
            slow[i // 5] = (t2 - t1) / 1e3
        fast[i] = (t3 - t2) / 1e3
        tick[i] = (t3 - t0) / 1e3
    return {"Estimator.update": _stats(upd), "AttitudeLaw.slow_step": _stats(slow),
            "AttitudeLaw.fast_step": _stats(fast),
            "fc tick: update + slow_step/5 + fast_step": _stats(tick)}


def bench_per_call(calls: int):
    """Per-call times (us) from Python: wrapper cycle, slow kernel, fast kernel."""
    law, est, cmd = _setup()
    k = law.kernel_args()
    pc = time.perf_counter_ns
    for _ in range(200):                                   # warm-up
        law.slow_step(est, cmd, 0.01)
        law.fast_step(est, 0.002)
    for _ in range(200):
        law.cycle(est, cmd, 0.01, 0.002)
    wrap = np.empty(calls)
    cyc = np.empty(calls)
    slow = np.empty(calls)
    fast = np.empty(calls)
    par, x, nm, st, tab, atm, grid, delta = (k[n] for n in ("par", "x", "nm", "st", "tab",
                                                             "atm", "grid", "delta"))
    for i in range(calls):
        t0 = pc()
        law.slow_step(est, cmd, 0.01)
        law.fast_step(est, 0.002)
        t1 = pc()
        K.slow_kernel(est, cmd, 0.01, par, x, nm, st, tab, atm, grid)
        t2 = pc()
        K.fast_kernel(est, 0.002, par, x, nm, st, tab, atm, grid, delta)
        t3 = pc()
        law.cycle(est, cmd, 0.01, 0.002)
        t4 = pc()
        cyc[i] = (t4 - t3) / 1e3
        wrap[i] = (t1 - t0) / 1e3
        slow[i] = (t2 - t1) / 1e3
        fast[i] = (t3 - t2) / 1e3
    return {"AttitudeLaw.slow_step + fast_step (wrapper)": _stats(wrap),
            "slow_kernel called from Python": _stats(slow),
            "fast_kernel called from Python": _stats(fast),
            "slow_kernel + fast_kernel from Python": _stats(slow + fast),
            "AttitudeLaw.cycle (slow + fast in one call)": _stats(cyc)}


def bench_parts(batches: int, batch: int):
    """Per-call times (us) inside numba for each part: batch time / batch size."""
    out = {}
    pc = time.perf_counter_ns
    for name, fn in PARTS:
        law, est, cmd = _setup()
        k = law.kernel_args()
        args = (est, cmd, k["par"], k["x"], k["nm"], k["st"], k["tab"], k["atm"], k["grid"],
                k["delta"])
        law.slow_step(est, cmd, 0.01)
        law.fast_step(est, 0.002)
        fn(batch, *args)                                    # compile / load and warm up
        t = np.empty(batches)
        for i in range(batches):
            t0 = pc()
            fn(batch, *args)
            t[i] = (pc() - t0) / 1e3 / batch
        out[name] = _stats(t)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m tools.bench law", description=__doc__.split("\n")[0])
    ap.add_argument("--batches", type=int, default=2000,
                    help="timed batches per part, inside numba (default 2000)")
    ap.add_argument("--batch", type=int, default=50,
                    help="calls per batch, inside numba (default 50)")
    ap.add_argument("--calls", type=int, default=20000,
                    help="calls timed one by one from Python (default 20000)")
    a = ap.parse_args(argv)
    print("control-law cost, microseconds (median / p99 / p99.9)")
    print(f"-- per call from Python ({a.calls} calls, perf_counter_ns) --")
    for name, (med, p99, p999) in bench_fc_steps(a.calls).items():
        print(f"{name:52s} {med:7.3f} {p99:8.3f} {p999:8.3f}")
    for name, (med, p99, p999) in bench_per_call(a.calls).items():
        print(f"{name:52s} {med:7.3f} {p99:8.3f} {p999:8.3f}")
    print(f"-- inside numba, per part ({a.batches} batches of {a.batch}) --")
    for name, (med, p99, _p999) in bench_parts(a.batches, a.batch).items():
        print(f"{name:52s} {med:7.3f} {p99:8.3f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
