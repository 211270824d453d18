"""The frame stamp in int64 cells (issue 24): the lockstep frame's compiled readers of the stamp
give what the Python-int path gave, and a faulty plant's u64 stamp keeps that path.

fc/link.py ``read_frame_at`` leaves the stamp in a cell; fc/intake.py ``take_at``, the
planner's ``due_at``, fc/internals_log.py ``take_row_at`` and fc/gcs.py ``_service_log`` read
it there. Stamps at or beyond fc/frame_calls.py STAMP_CELL_MAX_US take ``take`` / ``_keep`` /
``lockstep_frame`` on Python ints.
"""
from __future__ import annotations

import struct
import time

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from fc.control.carrays import address_of
from fc.frame_calls import STAMP_CELL_MAX_US
from fc.internals_log import InternalsLog
from fc.link import FRAME_AT, FRAME_BIG, mavlink as ML

MAX = STAMP_CELL_MAX_US
# stamps near each other (repeats, reorders, restarts), far apart, and beyond the cells
stamps = st.lists(st.one_of(st.integers(0, 3000), st.integers(0, 10**9),
                            st.integers(MAX - 5, MAX + 5), st.integers(MAX, 2**64 - 1)),
                  min_size=1, max_size=40)


def _intake_verdict(last: int, stamp: int, window: int) -> tuple[str, int]:
    """The intake's rule as it was on Python ints (fc/intake.py before the cells): the
    verdict and the newest stamp after it."""
    if stamp == last:
        return "duplicate", last
    if last >= 0 and stamp < last:
        if last - stamp <= window:
            return "late", last
        return "restart", stamp
    return "new", stamp


@settings(max_examples=30, deadline=None)
@given(seq=stamps, window=st.sampled_from([0, 100_000]))
def test_the_intake_on_cells_follows_the_python_rule(seq, window):
    # GIVEN a controller's frame intake (late window 0 as in lockstep, or real time's), fed
    # each stamp from a cell when below STAMP_CELL_MAX_US, else as a Python int
    from tools.bench.profile import _Rig
    rig = _Rig("COORDINATED")
    try:
        intake, c = rig.fc.intake, rig.fc.counters
        intake.late_window_us = window
        cell = np.zeros(1, np.int64)
        cell_at = address_of(cell, np.int64, 1)
        last = -1
        for stamp in seq:
            before = (c.duplicate_frames, c.reordered_frames, c.plant_resets)
            if stamp < MAX:
                cell[0] = stamp
                took = intake.take_at(cell_at, time.monotonic())
            else:
                took = intake.take(stamp, time.monotonic())
            verdict, last = _intake_verdict(last, stamp, window)
            # THEN the verdict, the counters and the stamps are the Python rule's
            after = (c.duplicate_frames, c.reordered_frames, c.plant_resets)
            assert took == (verdict in ("new", "restart")), (stamp, verdict)
            assert [a - b for a, b in zip(after, before)] == [
                verdict == "duplicate", verdict == "late", verdict == "restart"]
            assert intake.last_stamp_us == last and intake.stamp_us == last
            assert intake.stamp_big == (last >= MAX)
    finally:
        rig.close()


def _keep_rule(state: dict, stamp: int, full_us: int, tail_us: int) -> bool:
    """``InternalsLog._keep`` as it was on Python ints."""
    if state.get("t0") is None:
        state["t0"], state["end"], state["next"] = stamp, stamp + full_us, 0
    if stamp < state["end"]:
        return True
    if stamp < state["next"]:
        return False
    since = stamp - state["t0"]
    state["next"] = state["t0"] + (since // tail_us + 1) * tail_us
    return True


@settings(max_examples=40, deadline=None)
@given(steps=st.lists(st.one_of(st.integers(1, 3000), st.integers(-50_000, 0),
                                st.just(MAX), st.just(2**63)), min_size=1, max_size=200),
       t0=st.integers(0, 10**7))
def test_the_internals_log_keeps_the_rows_the_python_rule_kept(tmp_path_factory, steps, t0):
    # GIVEN an internals log at full rate for 10 ms then 100 rows/s, fed frame stamps that
    # step forward, back, and beyond the cells (from a cell below STAMP_CELL_MAX_US)
    log = InternalsLog(str(tmp_path_factory.mktemp("ilog")), ["a"], full_rate_s=0.01,
                       tail_hz=100.0)
    try:
        cell = np.zeros(1, np.int64)
        cell_at = address_of(cell, np.int64, 1)
        state: dict = {}
        stamp = t0
        for step in steps:
            stamp = step if step >= MAX else max(0, stamp + step)
            if stamp < MAX:
                cell[0] = stamp
                kept = log.take_row_at(cell_at)
            else:
                kept = log.take_row(stamp)
            # THEN every row is kept or dropped as the Python rule did
            assert kept == _keep_rule(state, stamp, 10_000, 10_000), stamp
    finally:
        log.close()


def _sensor_datagram(stamp_us: int) -> bytes:
    from tools.bench.standin import FrameCodec
    from tests.fc_harness import level_meas
    return FrameCodec().encode(level_meas(1.0, alpha_deg=3.9, V=2250.0, h=28000.0), stamp_us)


def _answer_stamp(rig) -> int:
    """time_usec of the SERVO_OUTPUT_RAW the fc sent to the plant socket."""
    data = rig.plant.recv(65536)
    c = ML.MAVLink(None)
    m = c.parse_buffer(data)[0]
    assert m.get_msgId() == ML.MAVLINK_MSG_ID_SERVO_OUTPUT_RAW
    return m.time_usec


def test_a_u64_stamp_takes_the_python_path_and_the_cells_come_back():
    # GIVEN a lockstep controller flying on ordinary frames
    from tools.bench.profile import _Rig
    rig = _Rig("COORDINATED")
    fc = rig.fc
    try:
        for stamp, code in ((1_000_000, FRAME_AT), (1_002_000, FRAME_AT),
                            (MAX + 7, FRAME_BIG),       # the compiled decoder's, beyond the cells
                            (2**63 + 5, FRAME_BIG),     # the general parser's
                            (2**64 - 1, FRAME_BIG),
                            (3_000_000, FRAME_AT)):     # plant time back: a restart
            rig.plant.sendto(_sensor_datagram(stamp), rig.addr)
            got = fc.plant.read_frame_at(fc.meas_scratch)
            # WHEN each frame is read and exchanged as the lockstep loop does
            assert got == code, stamp
            fc.loops.lockstep_exchange(got, time.monotonic())
            fc.loops.housekeeping(time.monotonic(), False)
            # THEN the answer echoes the stamp mod 2^32, the intake holds it (beyond the cells
            # as a Python int), and the housekeeping took it (the .tlog schedule included)
            assert _answer_stamp(rig) == stamp & 0xFFFFFFFF
            assert fc.meas_stamp_us == stamp and fc.meas_stamp_big == (stamp >= MAX)
        assert fc.counters.plant_resets == 1
        # AND the .tlog's frames are stamped with the time base, the u64 ones included
        tlog = bytes(fc.gcs._tlog_buf)
        assert tlog and struct.unpack(">Q", tlog[:8])[0] >= fc.gcs.epoch_us
    finally:
        rig.close()


def _walk_rule(state: dict, t_us: int, iv: list[int]) -> list[int]:
    """``GcsLink._service_log``'s schedule as it was on Python ints: the streams due at
    ``t_us`` (indices), their due times stepped."""
    due = state["due"]
    if t_us < state["last"]:
        due[:] = [t_us] * len(iv)
        state["next"] = t_us
    state["last"] = t_us
    if t_us < state["next"]:
        return []
    out, nxt = [], None
    for i, step in enumerate(iv):
        d = due[i]
        if t_us >= d:
            out.append(i)
            d = d + step if d + step > t_us else t_us + step
            due[i] = d
        if nxt is None or d < nxt:
            nxt = d
    state["next"] = nxt
    return out


@settings(max_examples=60, deadline=None)
@given(steps=st.lists(st.one_of(st.integers(0, 300_000), st.integers(-2_000_000, -1)),
                      min_size=1, max_size=120), t0=st.integers(0, 10**9))
def test_the_tlog_schedule_walk_is_the_python_rules(steps, t0):
    # GIVEN the .tlog's streams and intervals, and time bases stepping forward and back
    from fc import gcs_frames as GF
    from fc.gcs import LOG_STREAMS_S
    iv = [int(round(v * 1e6)) for v in LOG_STREAMS_S.values()]
    n = len(iv)
    ivs = np.array(iv, np.int64)
    state_arr = np.zeros(GF.LOG_DUE + n, np.int64)
    flags = np.zeros(n, np.int64)
    cell = np.zeros(1, np.int64)
    p = [address_of(a, np.int64, a.size) for a in (cell, state_arr, ivs, flags)]
    rule = {"last": 0, "next": 0, "due": [0] * n}
    t = t0
    for step in steps:
        t = max(0, t + step)
        cell[0] = t
        count = GF.log_walk_p(p[0], p[1], p[2], n, p[3])
        want = _walk_rule(rule, t, iv)
        # THEN the same streams are due, and the schedule is the same
        assert count == len(want)
        if count:
            assert [i for i in range(n) if flags[i]] == want
        assert state_arr.tolist() == [rule["last"], rule["next"], *rule["due"]]

