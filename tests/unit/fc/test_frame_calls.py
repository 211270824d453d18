"""fc/frame_calls.py, fc/control/carrays.py (issue 24): the frame path's compiled calls take
array addresses; they compute exactly what the array entries compute, allocate no numba
record, refuse an array they cannot view, and a datagram the compiled decoder rejects still
goes to the general parser without raising."""
from __future__ import annotations

import pathlib

import numpy as np
import pytest
from numba.core.runtime import _nrt_python

from fc.control import kernels as K
from fc.control.carrays import ArrayAddress, address_of
from fc.control.law import AttitudeLaw
from fc.control.layout import E_N
from fc.estimator import EM_N, Estimator, accept_entry, accept_p
from fc.frame_calls import blend3_p, decode_sensor_p, servo_frame_p, surfaces_pwm_p
from fc.link import M_N, PlantLink, UdpEndpoint
from fc.telemetry import fill_row, fill_row_p
from hyfc_wire import frame_kernels as FK
from tests.fc_harness import ScriptedPlant, level_meas

CORPUS = pathlib.Path(__file__).resolve().parents[2] / "fuzz_corpus"


def _p(a: np.ndarray) -> int:
    return address_of(a, a.dtype, a.size)


def test_array_address_binds_once_and_refuses_what_it_cannot_view():
    # GIVEN a memo for float64[3]
    at = ArrayAddress(np.float64, 3)
    a, b = np.zeros(3), np.zeros(4)
    # THEN the same array gives the same address, another array its own
    assert at.of(a) == at.of(a) == a.__array_interface__["data"][0]
    assert at.of(b) == b.__array_interface__["data"][0] and at.arr is b
    # AND an array of another type, too short, strided or read-only is refused at binding
    ro = np.zeros(3)
    ro.flags.writeable = False
    for bad in (np.zeros(3, np.float32), np.zeros(2), np.zeros(6)[::2], ro, [0.0, 0.0, 0.0]):
        with pytest.raises(ValueError):
            at.of(bad)


def test_law_steps_by_address_equal_the_array_entries_bit_for_bit():
    # GIVEN two laws from the same state, one stepped through slow_step/fast_step (addresses),
    # one through the array entries
    rng = np.random.default_rng(3)
    est = np.array([0.03, 0.001, 0.02, 0.01, -0.02, 0.005, 2200.0, 21000.0, 0.0])
    a, b = AttitudeLaw({"CO_ENABLE": 1}), AttitudeLaw({"CO_ENABLE": 1})
    a.reset(est)
    b.reset(est)
    cmd = np.array([0.0873, 0.0, 0.0698])
    for i in range(200):
        e = est + rng.normal(0.0, 1e-3, E_N)
        if i % 5 == 0:
            a.slow_step(e, cmd, 0.01)
            K.slow_entry(e, cmd, 0.01, b.mem)
        a.fast_step(e, 0.002)
        K.fast_entry(e, 0.002, b.mem)
    # THEN their whole buffers (state, status, command) are the same bits
    assert a.mem.tobytes() == b.mem.tobytes()
    assert np.abs(a.delta_cmd_rad).max() > 0.0


def test_frame_kernels_by_address_equal_the_array_entries():
    rng = np.random.default_rng(5)
    # estimator intake
    frame = level_meas(1.0)
    m1, m2 = np.zeros(M_N), np.zeros(M_N)
    e1, e2 = Estimator(), Estimator()
    for k in range(50):
        frame[0] = 1.0 + 0.002 * k
        frame[1:4] += rng.normal(0.0, 1e-3, 3)
        h1 = accept_p(_p(frame), _p(m1), M_N, _p(e1.mem), EM_N)
        h2 = accept_entry(frame, m2, e2.mem)
        assert h1 == h2
    assert e1.mem.tobytes() == e2.mem.tobytes() and m1.tobytes() == m2.tobytes()
    # surfaces + PWM
    for _ in range(50):
        src = rng.normal(0.0, 0.2, 3)
        d1, d2 = np.zeros(3), np.zeros(3)
        p1, p2 = np.zeros(4, np.int64), np.zeros(4, np.int64)
        surfaces_pwm_p(_p(src), _p(d1), 1420, _p(p1))
        FK.surfaces_pwm(src, d2, 1420, p2)
        assert d1.tobytes() == d2.tobytes() and p1.tolist() == p2.tolist()
    # SERVO_OUTPUT_RAW framing
    for seq, t in ((0, 0), (7, 123456), (255, 0xFFFFFFFF)):
        pwm = np.array([1000, 2000, 1500, 1420], np.int64)
        o1 = np.zeros(FK.SERVO_FRAME_MAX_B, np.uint8)
        o2 = np.zeros(FK.SERVO_FRAME_MAX_B, np.uint8)
        n1 = servo_frame_p(_p(o1), o1.size, seq, 1, 1, t, _p(pwm))
        n2 = FK.servo_frame(o2, seq, 1, 1, t, pwm)
        assert n1 == n2 and o1.tobytes() == o2.tobytes()
    # the surface hold's running estimate: the Python loop it replaced
    dst, ref = np.zeros(3), np.zeros(3)
    for _ in range(100):
        src = rng.normal(0.0, 0.1, 3)
        k = float(rng.uniform(1e-4, 1.0))
        blend3_p(_p(dst), _p(src), k)
        for i in range(3):
            ref[i] += k * (src[i] - ref[i])
    assert dst.tobytes() == ref.tobytes()
    # internals-log row
    st = rng.normal(size=12)
    emem, cmd, delta, tgt = e1.mem, rng.normal(size=3), rng.normal(size=3), rng.normal(size=3)
    chunk, r2 = np.zeros((3, 50)), np.zeros(50)
    dims = np.array([50, st.size, 10], np.int64)
    cursor = np.array([2, 1], np.int64)             # (rows taken, the row taken last)
    fill_row_p(_p(chunk), _p(cursor), _p(dims), _p(m1), 12.5, 3.0e6, 0, 4, True, True, _p(emem), _p(cmd),
               _p(delta), 1234.0, 5678.0, _p(st), 0.4, 3, _p(tgt))
    fill_row(r2, m1, 12.5, 3.0e6, 4, True, True, emem, cmd, delta, 1234, 5678, st, 10, 0.4, 3,
             tgt)
    assert chunk[1].tobytes() == r2.tobytes()            # row 1 of the chunk, the others kept
    assert not chunk[0].any() and not chunk[2].any()
    # the same row with the stamp read from an int64 cell (the lockstep frame's)
    chunk[1] = 0.0
    cell = np.array([3_000_000], np.int64)
    fill_row_p(_p(chunk), _p(cursor), _p(dims), _p(m1), 12.5, 0.0, _p(cell), 4, True, True,
               _p(emem), _p(cmd), _p(delta), 1234.0, 5678.0, _p(st), 0.4, 3, _p(tgt))
    assert chunk[1].tobytes() == r2.tobytes()


def test_calls_by_address_allocate_no_numba_record():
    # GIVEN the numba runtime's statistics
    was_on = _nrt_python.memsys_stats_enabled()
    _nrt_python.memsys_enable_stats()
    try:
        src, d, p = np.full(3, 0.1), np.zeros(3), np.zeros(4, np.int64)
        args = (_p(src), _p(d), 1400, _p(p))
        surfaces_pwm_p(*args)
        m0 = _nrt_python.memsys_get_stats_mi_alloc()
        for _ in range(100):
            surfaces_pwm_p(*args)
        m1 = _nrt_python.memsys_get_stats_mi_alloc()
        for _ in range(100):
            FK.surfaces_pwm(src, d, 1400, p)
        m2 = _nrt_python.memsys_get_stats_mi_alloc()
    finally:
        if not was_on:
            _nrt_python.memsys_disable_stats()
    # THEN the address entry takes none, the array entry one per array per call (the counter
    # counts)
    assert m1 - m0 == 0 and m2 - m1 == 300


@pytest.fixture(scope="module")
def link():
    ep = UdpEndpoint("127.0.0.1", 0)
    lk = PlantLink(ep, plant_sysid=2)
    assert lk._fast
    yield lk
    ep.close()


def test_rejected_datagrams_go_to_the_general_parser_and_never_raise(link):
    # GIVEN the fuzz corpus (malformed, truncated, foreign, doubled datagrams) and a good frame
    plant = ScriptedPlant(9)
    try:
        good = plant.frame_bytes(level_meas(1.0))
    finally:
        plant.close()
    samples = [p.read_bytes() for p in sorted(CORPUS.glob("*.bin"))] + [good]
    assert len(samples) > 50
    for data in samples:
        got = []
        for fast in (True, False):
            link._fast = fast
            meas = np.full(M_N, -7.0)
            for f in link.counters.__slots__:
                setattr(link.counters, f, 0)
            # WHEN each is decoded by the compiled path (addresses) and by the general parser
            stamp = link._decode(data, meas)
            got.append((stamp, meas.tobytes(), [getattr(link.counters, f)
                                                for f in link.counters.__slots__]))
        link._fast = True
        # THEN neither raised and both give the same stamp, values and rejection counts
        assert got[0] == got[1], data[:16]
    stamp = link._decode(good, np.zeros(M_N))
    assert stamp >= 0


def _two_guidances(h_m: float, chi_rad: float, V_m_s: float):
    """(state, guidance a, guidance b): both reset at the same state, with the same targets."""
    from fc.guidance.guidance import Guidance
    est = np.array([0.03, 0.0, 0.0, 0.0, 0.0, 0.0, 2200.0, 21000.0, 0.0])
    a, b = Guidance(), Guidance()
    for g in (a, b):
        g.reset(est, -1.0)
        g.set_targets(h_m, chi_rad, V_m_s)
    return est, a, b


def test_guidance_step_by_address_equals_the_array_entry():
    # GIVEN two guidances from the same state and targets, one stepped by Guidance.step
    # (addresses), one through the array entry
    from fc.guidance import kernels as GK
    est, a, b = _two_guidances(21500.0, 0.1, 2300.0)
    rng = np.random.default_rng(1)
    for _ in range(100):
        e = est + rng.normal(0.0, 1e-3, E_N)
        la = a.step(e, 0.05, 0.02)
        lb = GK.guidance_step(e, 0.05, b.tgt, 0.02, b.par, b.mass_kg, b.xcg_m, b.gx, b.out,
                              b.status, b.work, b.tab, b.atm, b.grid)
        # THEN the limits, state, outputs and status are the same bits
        assert la == lb
    for name in ("gx", "out", "status", "work"):
        assert getattr(a, name).tobytes() == getattr(b, name).tobytes(), name
    assert a.out.any()


def test_guidance_step_f_gives_the_bitfield_as_a_float_and_the_same_state():
    # GIVEN two guidances from the same state and targets far from the vehicle's (so the
    # limits engage, bits past 256 among them), one stepped by step, one by step_f
    est, a, b = _two_guidances(30000.0, 1.5, 3000.0)
    rng = np.random.default_rng(2)
    seen = set()
    for _ in range(200):
        e = est + rng.normal(0.0, 1e-3, E_N)
        la = a.step(e, 0.05, 0.02)
        lb = b.step_f(e, 0.05, 0.02)
        # THEN step_f's float holds the same bits as step's int
        assert type(la) is int and type(lb) is float and float(la) == lb
        seen.add(la)
    assert max(seen) > 256, seen            # (an int CPython does not cache was compared)
    # and the state, outputs and status are the same bits
    for name in ("gx", "out", "status", "work"):
        assert getattr(a, name).tobytes() == getattr(b, name).tobytes(), name
    # and with a bitfield past 256, step_f takes no block from Python's object allocator,
    # step one per call (tools/bench/allocs.py's counter; the with-block's own cost measured)
    assert la > 256, la
    from tools.bench.allocs import PyAllocCounter
    a.step(e, 0.05, 0.02), b.step_f(e, 0.05, 0.02)
    counts = []
    for g, f in ((None, None), (b, b.step_f), (a, a.step)):
        counter = PyAllocCounter()
        with counter:
            if f is not None:
                f(e, 0.05, 0.02)
                f(e, 0.05, 0.02)
                f(e, 0.05, 0.02)
        counts.append(int(counter.counts[0]) + int(counter.counts[1]))
    assert counts[1] == counts[0] and counts[2] >= counts[0] + 3, counts
