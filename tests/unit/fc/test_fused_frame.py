"""fc/fused.py (issue 24): the lockstep frame in one compiled call flies exactly as the unfused path.

In process, on 127.0.0.1: the sensor datagrams of a short closed-loop flight
(``tools.bench.profile.record``) are replayed into two fresh controllers, one with its fused
step (``RunLoops.fused``) and one without; the answers sent, the internals-log rows (but the
wall-clock columns), the parts' state and the counters must be the same. Events injected
into the same frames of both (a repeated frame, plant time going back, mode changes, FAILSAFE)
must take the unfused path from where ``fc/fused.py`` says and come out the same.
"""
from __future__ import annotations

import ctypes
import dataclasses
import functools
import sys
import types

import numpy as np
import pytest

from fc.fused import EXCHANGE_DONE, EXCHANGE_VERDICT, FUSED_DONE, FUSED_TICKS
from fc.modes import FlightMode
from tools.bench.profile import _drain, _Rig, record

FRAMES = 420
WARM = 100                  # the allocation test's warm-up (frames)
#: the internals-log columns that are wall clock (not compared)
WALL_COLS = ("wall_s", "exec_us")


@pytest.fixture(scope="module")
def flight():
    return record(FRAMES, "COORDINATED")


@pytest.fixture(scope="module")
def cruise_flight():
    return record(FRAMES, "CRUISE")


class _Counted:
    """Counts the calls of ``obj.attr`` (an instance attribute shadowing the method)."""

    def __init__(self, obj, attr: str) -> None:
        self.n = 0
        self.results = []
        orig = getattr(obj, attr)

        def counted(*a, **kw):
            self.n += 1
            r = orig(*a, **kw)
            self.results.append(r)
            return r
        setattr(obj, attr, counted)


def _fly(datagrams: list, fused: bool, events=None, rig_factory=None, loop=False,
         flight_mode: str = "COORDINATED") -> dict:
    """Replay ``datagrams`` into a fresh controller, its fused step on or off: one lockstep
    loop step each, as ``tools.bench.profile`` (``read_frame_at`` + ``lockstep_exchange``:
    the fused step from the decoded frame), or ``loop``: its lockstep loop itself
    (``RunLoops.run``: the fused step from the receive), the next datagram sent once the
    previous ones were answered. ``events[k](rig)`` runs before frame k's datagram is sent (a
    callable may return datagrams to send instead of frame k's)."""
    rig = (rig_factory or _Rig)(flight_mode)
    try:
        fc = rig.fc
        if not fused:
            fc.loops.fused = None
        else:
            assert fc.loops.fused.enabled
        steps = _Counted(fc.loops.fused, "step") if fused else None
        exchanges = _Counted(fc.loops.fused, "exchange") if fused else None
        verdicts = _Counted(fc.intake, "after_verdict")
        answers = []

        def sends_of(k):
            sends = [datagrams[k]]
            if events and k in events:
                more = events[k](rig)
                if more is not None:
                    sends = more
            return sends
        if loop:
            state = {"k": 0, "waiting": 0}

            def stop():
                while True:
                    try:
                        answers.append(rig.plant.recv(65536))
                        state["waiting"] -= 1
                    except BlockingIOError:
                        break
                _drain(rig.sink)
                if state["waiting"] == 0 and state["k"] < len(datagrams):
                    sends = sends_of(state["k"])
                    state["k"] += 1
                    state["waiting"] = len(sends)
                    for d in sends:
                        rig.plant.sendto(d, rig.addr)
                return state["waiting"] == 0 and state["k"] == len(datagrams)
            fc.loops.run(stop)
        else:
            for k in range(len(datagrams)):
                for d in sends_of(k):
                    rig.plant.sendto(d, rig.addr)
                    rig.fc_step()
                    while True:
                        try:
                            answers.append(rig.plant.recv(65536))
                        except BlockingIOError:
                            break
                    _drain(rig.sink)
        ilog = fc.ilog
        cols = ilog.columns
        rows = ilog.chunk[:ilog.n].copy()
        counters = dataclasses.asdict(fc.counters)
        for name in ("exec_ns_sum", "exec_n", "load_permille", "gc_us"):
            counters.pop(name)      # wall clock
        link = fc.plant.counters
        return {
            "answers": answers,
            "rows": {c: rows[:, i] for i, c in enumerate(cols) if c not in WALL_COLS},
            "n_rows": (ilog.rows, ilog.decimated),
            "arrays": {"law": fc.law.mem.copy(), "est": fc.est.mem.copy(),
                       "hold": fc.mode_ctl.hold.cells.copy(), "hot": link.hot.copy(),
                       "planner": fc.planner._st.copy(), "intake": fc.intake._st.copy(),
                       "pwm": fc.out.pwm_us.copy(), "delta": fc.out.delta_rad.copy(),
                       "cmd_active": np.array(fc.out.cmd_active, copy=True),
                       "guid_out": fc.guid.g.out.copy(), "guid_gx": fc.guid.g.gx.copy(),
                       "guid_count": fc.guid._count.copy()},
            "python": (counters, fc.est.healthy, fc.mode_ctl.last_good_stamp_s,
                       fc.mode_ctl.last_good_wall_s >= 0.0, fc.mode_ctl.seen_data,
                       fc.plant._tx_codec.seq, fc.plant.endpoint.send_errors,
                       int(fc.modes.mode), fc.modes.armed, fc.modes.changes,
                       fc.mode_ctl.changes_seen, fc.mode_ctl.reset_pending,
                       fc.mode_ctl.hold.flown_s, link.frames, link.outputs,
                       fc.guid.engaged, fc.guid.steps, fc.guid.limits),
            "fused_steps": (steps.n + sum(1 for r in exchanges.results
                                          if r == EXCHANGE_DONE or r >= EXCHANGE_VERDICT)
                            if steps else 0),
            "fused_done": (sum(1 for r in steps.results if r == FUSED_DONE)
                           + sum(1 for r in exchanges.results if r == EXCHANGE_DONE)
                           if steps else 0),
            "exchanges": exchanges.n if exchanges else 0,
            "ticks_back": (sum(1 for r in steps.results if r == FUSED_TICKS)
                           + sum(1 for r in exchanges.results
                                 if r == EXCHANGE_VERDICT + FUSED_TICKS) if steps else 0),
            "verdicts": verdicts.n,
        }
    finally:
        rig.close()


def _same(a: dict, b: dict) -> None:
    assert a["answers"] == b["answers"]
    assert a["n_rows"] == b["n_rows"]
    for c in a["rows"]:
        assert np.array_equal(a["rows"][c], b["rows"][c], equal_nan=True), c
    for k in a["arrays"]:
        assert np.array_equal(a["arrays"][k], b["arrays"][k], equal_nan=True), k
    assert a["python"] == b["python"]


@pytest.mark.parametrize("loop", [False, True], ids=["from-the-frame", "from-the-receive"])
def test_the_fused_step_flies_the_unfused_frames(flight, loop):
    # GIVEN a recorded COORDINATED flight
    # WHEN it is replayed with and without the fused step
    unfused = _fly(flight, False, loop=loop)
    fused = _fly(flight, True, loop=loop)
    # THEN the fused step flew all its frames but the first (the law's engagement, a mode
    # change to act on), and everything the controller sent, logged and keeps is the same
    assert fused["fused_done"] >= FRAMES - 2
    assert fused["verdicts"] == FRAMES - fused["fused_done"]    # (the intake's, unfused)
    _same(unfused, fused)
    assert len(fused["answers"]) == FRAMES
    assert fused["exchanges"] == (FRAMES - 1 if loop else 0)   # (the first: no peer yet)


@pytest.mark.parametrize("loop", [False, True], ids=["from-the-frame", "from-the-receive"])
def test_a_guidance_mode_flies_the_fused_step_between_its_guidance_steps(cruise_flight, loop):
    # GIVEN a recorded CRUISE flight (the guidance engaged: its command, its throttle)
    # WHEN it is replayed with and without the fused step
    unfused = _fly(cruise_flight, False, loop=loop, flight_mode="CRUISE")
    fused = _fly(cruise_flight, True, loop=loop, flight_mode="CRUISE")
    # THEN everything sent, logged and kept is the same, the guidance's state included
    _same(unfused, fused)
    engaged, steps = fused["python"][-3], fused["python"][-2]
    assert engaged and steps == unfused["python"][-2]
    div = 10                            # 500 Hz frames, guidance at 50 Hz
    assert abs(steps - FRAMES / div) <= 2, steps
    # the frames with a guidance step due came back to Python (its ticks, answer, row), the
    # others went all the way in the compiled step
    assert abs(fused["ticks_back"] - steps) <= 1, (fused["ticks_back"], steps)
    assert fused["fused_done"] >= FRAMES - fused["ticks_back"] - 3
    # the throttle went out on servo4 (not 0: the guidance's command)
    assert all(len(a) > 0 for a in fused["answers"])
    assert fused["arrays"]["pwm"][3] > 0


def _events(datagrams):
    def repeat(rig):                    # the plant re-sends the previous frame, then this one
        return [datagrams[99], datagrams[100]]

    def back(rig):                      # plant time goes back (a restarted plant)
        return [datagrams[20]]

    def mode(m):
        def change(rig):
            ok, text = rig.fc.request_mode(m)
            assert ok, text
        return change

    def disarm(rig):
        rig.fc.modes.set_armed(False, data_ok=True)
    return {100: repeat, 140: mode(FlightMode.UNCOORDINATED), 200: back,
            260: mode(FlightMode.MANUAL), 300: mode(FlightMode.FAILSAFE), 360: disarm}


def _timeline_rig(flight_mode: str) -> _Rig:
    """A rig whose controller has a command timeline (``--timeline``): at 0, 0.1 s and 0.3 s
    of sensor time (frames 0, 50 and 150 at 500 Hz)."""
    from fc.timeline import Command, Timeline
    rig = _Rig(flight_mode)
    rig.fc.intake.timeline = Timeline([
        Command(0.0, (("CMD_ALPHA_DEG", 4.0),)),
        Command(0.1, (("CMD_ALPHA_DEG", 5.0), ("CMD_MU_DEG", 3.0))),
        Command(0.3, (("CMD_BETA_DEG", 0.5),))])
    return rig


@pytest.mark.parametrize("loop", [False, True], ids=["from-the-frame", "from-the-receive"])
def test_each_exceptional_frame_takes_the_unfused_path_and_flies_the_same(flight, loop):
    # GIVEN the same flight with a command timeline, a repeated frame, a mode change, plant
    # time going back (the timeline starts over), the law switched off (MANUAL: the trim),
    # FAILSAFE while armed (the hold's trim), a disarm
    events = _events(flight)
    # WHEN it is replayed with and without the fused step
    unfused = _fly(flight, False, events, _timeline_rig, loop)
    fused = _fly(flight, True, events, _timeline_rig, loop)
    # THEN everything is the same
    _same(unfused, fused)
    c = fused["python"][0]
    assert (c["duplicate_frames"], c["plant_resets"]) == (1, 1)
    # the fused step gave the repeat and the restart back to the intake (its verdicts) ...
    assert fused["fused_steps"] - fused["fused_done"] == 2
    assert fused["verdicts"] == FRAMES + 1 - fused["fused_done"]     # (one frame repeated)
    # ... flew MANUAL's and the disarmed frames (the trim) but not the 60 of FAILSAFE while
    # armed, nor the frames with a mode change to act on
    assert fused["python"][7] == int(FlightMode.FAILSAFE) and not fused["python"][8]
    assert 300 < fused["fused_done"] < FRAMES - 60


class _FaultyLaw:
    """A loadable law module (``load_law_module``): the built-in law, raising on a fast step
    after ``FAULT_AFTER`` of them."""

    FAULT_AFTER = 150


def _faulty_law_module():
    from fc.control.law import AttitudeLaw
    from fc.control.params import LAW_PARAMS

    class FaultyLaw(AttitudeLaw):
        steps = 0

        def fast_step(self, est, dt_s):
            FaultyLaw.steps += 1
            if FaultyLaw.steps > _FaultyLaw.FAULT_AFTER:
                raise FloatingPointError("injected law fault")
            super().fast_step(est, dt_s)
    mod = types.ModuleType("hyfc_test_faulty_law")
    mod.AttitudeLaw, mod.LAW_PARAMS = FaultyLaw, LAW_PARAMS
    return mod


def test_a_loaded_law_takes_the_unfused_path_and_its_fault_gives_failsafe(flight, monkeypatch):
    # GIVEN a controller whose law is loaded from another module and raises after a while
    import fc.app
    mod = _faulty_law_module()
    monkeypatch.setitem(sys.modules, mod.__name__, mod)
    monkeypatch.setattr(fc.app, "FcConfig",
                        functools.partial(fc.app.FcConfig, law_module=mod.__name__))
    rig = _Rig("COORDINATED")
    try:
        # THEN it never takes the fused step (a law other than the built-in one) ...
        assert not rig.fc.loops.fused.enabled
        monkeypatch.setattr(rig.fc.log, "disabled", True)     # (the law's traceback)
        for data in flight[:200]:
            rig.step(data)
        # ... and the fault is caught by the fast tick as before: counted, FAILSAFE
        assert rig.fc.counters.law_errors >= 1
        assert rig.fc.modes.mode == FlightMode.FAILSAFE
    finally:
        rig.close()


@pytest.mark.parametrize("mode", ["COORDINATED", "CRUISE"])
def test_the_fused_frame_allocates_nothing(flight, cruise_flight, mode):
    # GIVEN a controller flying the fused step, warm (in CRUISE, one frame in ten runs its
    # guidance step in Python: it allocates nothing either)
    from numba.core.runtime import _nrt_python, rtsys

    from tools.bench.allocs import PyAllocCounter, _marker
    flight = cruise_flight if mode == "CRUISE" else flight
    rig = _Rig(mode)
    stats_were_on = _nrt_python.memsys_stats_enabled()
    _nrt_python.memsys_enable_stats()
    try:
        fc = rig.fc
        for data in flight[:WARM]:
            rig.step(data)
        counter = PyAllocCounter()
        marks = np.zeros(4, np.int64)
        mark = _marker()
        c_p, m_p = ctypes.addressof(counter.counts), marks.ctypes.data
        mark(c_p, m_p, 0)
        loops, plant, scratch = fc.loops, fc.plant, fc.meas_scratch
        per = np.zeros(300, np.int64)
        fused = np.zeros(300, bool)
        with counter:
            nrt0 = rtsys.get_allocation_stats().mi_alloc
            for k, data in enumerate(flight[WARM:WARM + 300]):
                rig.plant.sendto(data, rig.addr)
                code = plant.read_frame_at(scratch)
                fused[k] = loops.fused.ready()      # (outside the window: a numpy bool)
                mark(c_p, m_p, 0)
                loops.lockstep_exchange(code, 1000.0 + k * 0.002)
                mark(c_p, m_p, 1)
                per[k] = marks.item(1) - marks.item(0)
                _drain(rig.plant, rig.sink)
            nrt1 = rtsys.get_allocation_stats().mi_alloc
        # WHEN 300 frames are exchanged THEN each took the fused step, and none allocated a
        # Python block or a numba record (the counting counted: see test_bench_allocs)
        assert fused.all()
        assert fc.counters.duplicate_frames == 0 and fc.plant.counters.outputs == WARM + 300
        # (the window's first frames left out: the first frame with Python work after the
        # test's own calls before the window, CRUISE's first guidance step, refills the free
        # lists those emptied: 0-10 blocks once, whatever the warm-up)
        assert int(per[10:].sum()) == 0
        assert nrt1 - nrt0 == 0
    finally:
        if not stats_were_on:
            _nrt_python.memsys_disable_stats()
        rig.close()
