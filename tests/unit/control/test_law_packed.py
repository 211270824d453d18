"""The fc's per-tick path on packed buffers (issue 7): AttitudeLaw and Estimator keep their
arrays as views of one buffer and call one compiled entry point per step. These tests check
that this path gives bit-identical results to the plain kernels on separate arrays, that the
public attributes are live views, and that the entry points allocate nothing per call."""
from __future__ import annotations

import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from fc.control import kernels as K
from fc.control import layout as L
from fc.control.law import AttitudeLaw
from fc.control.nominal import load_tables
from fc.control.params import P_N, PARAM_INDEX, default_si_array
from fc.estimator import (FLAG_OLD_STAMP, LIMITS_HI, LIMITS_LO, Estimator, estimate_kernel)
from fc.link import M_AIRSPEED, M_ALT, M_AOA, M_N, M_P, M_PITCH, M_ROLL, M_SSA, M_T_S

DEG = math.pi / 180.0
REPO = Path(__file__).resolve().parents[3]


def _meas_seq(n: int, seed: int = 5) -> np.ndarray:
    """n measurement vectors near the paper's point, with rates and angles that move, some
    invalid fields and some repeated stamps (the estimator's every branch)."""
    rng = np.random.default_rng(seed)
    m = np.zeros((n, M_N))
    t = 0.002 * np.arange(1, n + 1)
    m[:, M_T_S] = t
    m[:, M_ROLL] = 0.1 * np.sin(2.0 * t) + 1e-3 * rng.standard_normal(n)
    m[:, M_PITCH] = 0.05 + 0.02 * np.sin(1.3 * t)
    m[:, M_P] = 0.2 * np.cos(2.0 * t)
    m[:, M_P + 1] = 0.03 * np.cos(1.3 * t)
    m[:, M_P + 2] = 0.01 * rng.standard_normal(n)
    m[:, M_AOA] = 0.03 + 0.02 * np.sin(1.3 * t)
    m[:, M_SSA] = 0.01 * np.sin(0.7 * t)
    m[:, M_AIRSPEED] = 2200.0
    m[:, M_ALT] = 21000.0
    m[::37, M_AOA] = np.nan                  # invalid field: keeps the last good value
    m[5::53, M_AIRSPEED] = -5.0              # out of range
    m[9::61, M_T_S] = m[8::61, M_T_S][:len(m[9::61])]   # stamp does not advance
    return m


def _law_pair(overrides):
    """An AttitudeLaw and an independent set of plain arrays in the same start state."""
    law = AttitudeLaw(overrides)
    tab, atm, grid = load_tables()
    ref = {"par": law.par.copy(), "x": np.zeros(L.X_N), "nm": np.zeros(L.NM_N),
           "st": np.zeros(L.S_N), "tab": tab, "atm": atm, "grid": grid,
           "delta": np.zeros(3), "cmd": np.zeros(3)}
    return law, ref


@pytest.mark.parametrize("overrides", [{"CO_ENABLE": 1}, {"CO_ENABLE": 0, "REF_PF_EN": 1},
                                       {"CO_ENABLE": 1, "PAPER_LITERAL": 1}])
def test_packed_path_bit_identical_to_plain_kernels(overrides):
    seq = _meas_seq(1500)
    est_fc = Estimator(0.1)
    good, good_t = np.zeros(M_N), np.full(M_N, -np.inf)
    est_ref, masks_ref = np.zeros(L.E_N), np.zeros(2, dtype=np.int64)
    law, r = _law_pair(overrides)
    invalid_ref = 0
    started = False
    cmd = np.array([5 * DEG, 0.0, 4 * DEG])
    for i, m in enumerate(seq):
        ok = est_fc.update(m)
        ok_ref = estimate_kernel(m, good, good_t, LIMITS_LO, LIMITS_HI, 0.1, est_ref, masks_ref)
        invalid_ref += masks_ref[0] != 0
        assert ok is bool(ok_ref) and est_fc.healthy is ok
        assert np.array_equal(est_fc.est, est_ref) and np.array_equal(est_fc.masks, masks_ref)
        assert est_fc.invalid_frames == invalid_ref
        if not ok:
            continue
        if not started:
            law.reset(est_fc.est)
            K.reset_kernel(est_ref, r["par"], r["x"], r["st"], np.zeros(3))
            started = True
        c = cmd if i < 700 else (cmd[0], -2 * DEG, 0.0)   # an array, then a tuple
        if i % 5 == 0:
            law.slow_step(est_fc.est, c, 0.01)
            r["cmd"][:] = c
            K.slow_kernel(est_ref, r["cmd"], 0.01, r["par"], r["x"], r["nm"], r["st"],
                          r["tab"], r["atm"], r["grid"])
            assert np.array_equal(law.status, r["st"])
        if i % 211 == 0:
            law.cycle(est_fc.est, c, 0.01, 0.002)
            K.cycle_kernel(est_ref, r["cmd"], 0.01, 0.002, 1, r["par"], r["x"], r["nm"],
                           r["st"], r["tab"], r["atm"], r["grid"], r["delta"])
        law.fast_step(est_fc.est, 0.002)
        K.fast_kernel(est_ref, 0.002, r["par"], r["x"], r["nm"], r["st"], r["tab"], r["atm"],
                      r["grid"], r["delta"])
        assert np.array_equal(law.delta_cmd_rad, r["delta"])
        assert np.array_equal(law.status, r["st"]) and np.array_equal(law.x, r["x"])
        assert np.array_equal(law.nm, r["nm"])
    assert started and invalid_ref > 20
    assert np.array_equal(law.kernel_args()["cmd"], r["cmd"])
    assert np.abs(law.delta_cmd_rad).max() > 0.0


def test_law_attributes_are_views_of_one_buffer():
    law = AttitudeLaw({"CO_ENABLE": 1})
    for name in ("par", "x", "nm", "status", "delta_cmd_rad", "tab", "atm", "grid"):
        a = getattr(law, name)
        assert np.shares_memory(a, law.mem), name
        assert a.flags.c_contiguous and a.dtype == np.float64, name
    for a, b in zip((law.tab, law.atm, law.grid), load_tables()):
        assert a.shape == b.shape and np.array_equal(a, b)
    assert law.par.shape == (P_N,) and np.array_equal(law.par[:5], default_si_array()[:5])
    # a parameter set through the API is what the packed entry point reads
    law.set_param("ACT_MAX", 10.0)
    assert law.mem[K.MEM_PAR + PARAM_INDEX["ACT_MAX"]] == pytest.approx(10 * DEG)
    k = law.kernel_args()
    assert k["par"] is law.par and k["x"] is law.x and k["delta"] is law.delta_cmd_rad
    # two laws never share state (each has its own buffer, its own copy of the tables)
    other = AttitudeLaw()
    assert not np.shares_memory(other.mem, law.mem)


def test_surface_limit_reaches_the_packed_entry_point():
    """ACT_MAX set through set_param limits the command computed by fast_step."""
    law = AttitudeLaw({"CO_ENABLE": 1})
    est = np.array([1 * DEG, 5 * DEG, 0.0, 0.0, 0.0, 0.0, 2200.0, 21000.0, 0.0])
    law.reset(est)
    law.set_param("ACT_MAX", 2.0)
    big = np.array([12 * DEG, 0.0, 30 * DEG])
    for _ in range(50):
        law.slow_step(est, big, 0.01)
        for _ in range(5):
            law.fast_step(est, 0.002)
    assert np.abs(law.delta_cmd_rad).max() == pytest.approx(2 * DEG)
    assert law.status[L.S_SAT_ANY] == 1.0


def test_fast_step_bad_input_holds_command():
    law = AttitudeLaw()
    est = np.array([1 * DEG, 5 * DEG, 0.0, 0.0, 0.0, 0.0, 2200.0, 21000.0, 0.0])
    law.reset(est, np.array([0.01, -0.02, 0.03]))
    x0 = law.x.copy()
    bad = est.copy()
    bad[L.E_V] = np.nan
    law.fast_step(bad, 0.002)
    assert law.status[L.S_INPUT_BAD] == 1.0
    assert np.array_equal(law.delta_cmd_rad, [0.01, -0.02, 0.03])
    assert np.array_equal(law.x, x0)


def test_estimator_buffer_views_and_properties():
    e = Estimator(0.05)
    for name in ("est", "good", "good_t", "masks"):
        assert np.shares_memory(getattr(e, name), e.mem), name
    assert e.masks.dtype == np.int64 and e.masks.shape == (2,)
    assert e.stale_s == 0.05 and e.invalid_frames == 0 and not e.healthy
    assert np.array_equal(e.lo, LIMITS_LO) and np.array_equal(e.hi, LIMITS_HI)
    m = _meas_seq(3)[1:]                           # (row 0 has no valid alpha)
    assert e.update(m[0]) and e.healthy
    assert e.update(m[0]) and e.healthy            # same stamp: ignored, still healthy
    assert e.invalid_mask & FLAG_OLD_STAMP and e.invalid_frames == 1
    # stale_s is live: the fc sets it from its parameter table
    m2 = m[1].copy()
    m2[M_T_S] = m[0, M_T_S] + 0.03
    m2[M_AOA] = np.nan
    assert e.update(m2)                            # alpha 0.03 s old < 0.05 s
    e.stale_s = 0.02
    m2[M_T_S] += 0.001
    assert not e.update(m2) and e.stale_mask & (1 << M_AOA)
    assert e.invalid_frames == 3
    e.reset()
    assert e.invalid_frames == 0 and not e.masks.any() and np.all(e.good_t == -np.inf)
    assert e.stale_s == 0.02 and np.array_equal(e.lo, LIMITS_LO)


def test_entry_points_allocate_nothing_per_call():
    """numba runtime statistics in a fresh process: each call of an entry point costs the
    same fixed number of runtime records (one per array argument at the call boundary),
    none stay alive, and the count does not grow with the work done."""
    code = (
        "import numpy as np\n"
        "from numba.core.runtime import rtsys\n"
        "from fc.control.law import AttitudeLaw\n"
        "from fc.estimator import Estimator\n"
        "from fc.link import M_AIRSPEED, M_ALT, M_AOA, M_N, M_PITCH, M_SSA\n"
        "law = AttitudeLaw({'CO_ENABLE': 1})\n"
        "e = Estimator()\n"
        "meas = np.zeros(M_N)\n"
        "meas[[M_PITCH, M_AOA, M_SSA, M_AIRSPEED, M_ALT]] = 0.05, 0.03, 0.01, 2200.0, 21000.0\n"
        "cmd = np.array([0.0873, 0.0, 0.0698])\n"
        "def tick(i):\n"
        "    meas[0] = 0.002 * (i + 1)\n"
        "    e.update(meas)\n"
        "    if i % 5 == 0:\n"
        "        law.slow_step(e.est, cmd, 0.01)\n"
        "    law.fast_step(e.est, 0.002)\n"
        "tick(0); law.reset(e.est); tick(1)\n"
        "a = rtsys.get_allocation_stats()\n"
        "for i in range(2, 12): tick(i)\n"
        "b = rtsys.get_allocation_stats()\n"
        "for i in range(12, 1012): tick(i)\n"
        "c = rtsys.get_allocation_stats()\n"
        "n1 = b.alloc - a.alloc; n2 = c.alloc - b.alloc\n"
        "live = (c.alloc - c.free) - (a.alloc - a.free)\n"
        "print(n1, n2, live, c.mi_alloc - c.mi_free - (a.mi_alloc - a.mi_free))\n"
        "assert law.status[0] != 0.0 or np.abs(law.delta_cmd_rad).max() > 0\n"
    )
    env = dict(os.environ, NUMBA_NRT_STATS="1", PYTHONPATH=str(REPO))
    out = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True,
                         env=env, timeout=600)
    assert out.returncode == 0, out.stderr
    n1, n2, live, mi_live = (int(v) for v in out.stdout.split())
    # 10 ticks -> n1, 1000 ticks -> n2: exactly proportional, one record per array argument
    # of Estimator.update (meas, mem); none from the law's slow_step and fast_step, which
    # pass their arrays by address (fc/control/carrays.py, issue 24); nothing from the work
    # inside
    assert n2 == 100 * n1 and n1 == 2 * 10
    assert live == 0 and mi_live == 0
