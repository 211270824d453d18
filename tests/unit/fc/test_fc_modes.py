"""fc/modes.py, fc/scheduler.py TickPlanner, fc/timeline.py: pure logic, no sockets."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fc.modes import FS_DATA, FS_NONE, FS_REQUESTED, FlightMode, ModeManager
from fc.scheduler import LoopStats, TickPlanner
from fc.timeline import Timeline, load_timeline


def test_law_runs_only_armed_in_law_modes():
    m = ModeManager()
    assert not m.law_active
    assert m.request_mode(FlightMode.COORDINATED)[0]
    assert not m.law_active
    assert not m.set_armed(True, data_ok=False)[0]
    assert m.set_armed(True, data_ok=True)[0] and m.law_active and m.co_enable == 1.0
    m.request_mode(FlightMode.UNCOORDINATED)
    assert m.law_active and m.co_enable == 0.0
    m.request_mode(FlightMode.MANUAL)
    assert not m.law_active
    assert not m.request_mode(42)[0]


def test_data_loss_failsafe_and_automatic_recovery():
    m = ModeManager()
    m.request_mode(FlightMode.COORDINATED)
    m.set_armed(True, True)
    assert "FAILSAFE" in m.on_data_lost()
    assert m.mode == FlightMode.FAILSAFE and m.fs_cause == FS_DATA and not m.law_active
    assert m.on_data_lost() is None                        # reported once
    assert not m.request_mode(FlightMode.MANUAL)[0]        # refused while data is lost
    assert m.on_data_ok(10.0, recover=True, recover_s=0.2) is None
    assert m.on_data_ok(10.1, recover=True, recover_s=0.2) is None
    assert "COORDINATED" in m.on_data_ok(10.25, recover=True, recover_s=0.2)
    assert m.mode == FlightMode.COORDINATED and m.fs_cause == FS_NONE and m.law_active


def test_recovery_restarts_after_a_gap_and_can_be_manual():
    m = ModeManager()
    m.request_mode(FlightMode.UNCOORDINATED)
    m.on_data_lost()
    m.on_data_ok(1.0, True, 0.2)
    m.on_data_gap()
    assert m.on_data_ok(1.25, True, 0.2) is None           # the clock restarted at 1.25
    m2 = ModeManager()
    m2.request_mode(FlightMode.COORDINATED)
    m2.on_data_lost()
    assert "staying" in m2.on_data_ok(0.0, recover=False, recover_s=0.0)
    assert m2.mode == FlightMode.FAILSAFE
    assert m2.request_mode(FlightMode.COORDINATED)[0]


def test_requested_failsafe_is_not_left_automatically():
    m = ModeManager()
    m.request_mode(FlightMode.COORDINATED)
    m.request_mode(FlightMode.FAILSAFE)
    assert m.fs_cause == FS_REQUESTED
    assert m.on_data_ok(5.0, True, 0.0) is None
    assert m.mode == FlightMode.FAILSAFE


def test_tick_planner_lockstep_rates():
    p = TickPlanner(500, 100)
    assert p.ratio == 5 and p.fast_dt_s == pytest.approx(0.002)
    # frames at 1 kHz: a fast tick every other frame
    ticks = [p.due(k * 1_000_000) for k in range(10)]
    assert ticks == [1, 0, 1, 0, 1, 0, 1, 0, 1, 0]
    slow = [p.slow_due() for _ in range(10)]
    assert slow == [True, False, False, False, False] * 2
    # frames at 250 Hz: two fast ticks per frame
    p = TickPlanner(500, 100)
    assert [p.due(k * 4_000_000) for k in range(4)] == [1, 2, 2, 2]


def test_tick_planner_skips_beyond_catchup_and_counts():
    p = TickPlanner(1000, 100, max_catchup=1)
    p.anchor(0)
    assert p.due(0) == 1
    assert p.due(5_500_000) == 1 and p.skipped == 4     # deadlines 1..5 ms: one run, 4 skipped
    assert p.next_ns == 6_500_000


@pytest.mark.parametrize("fast,slow", [(500, 300), (500, 0), (0, 100), (100, 500)])
def test_tick_planner_rejects_bad_ratios(fast, slow):
    with pytest.raises(ValueError):
        TickPlanner(fast, slow)


class _PythonPlanner:
    """TickPlanner's steps as they were in Python (before its state went into a compiled
    step's array, issue 24): the reference."""

    def __init__(self, period_ns: int, ratio: int, max_catchup: int) -> None:
        self.period_ns, self.ratio, self.max_catchup = period_ns, ratio, max_catchup
        self.next_ns, self.ticks, self.skipped = None, 0, 0

    def due(self, t_ns: int) -> int:
        if self.next_ns is None:
            self.next_ns = t_ns
        if t_ns < self.next_ns:
            return 0
        n = (t_ns - self.next_ns) // self.period_ns + 1
        if n > self.max_catchup:
            self.skipped += n - 1
            self.next_ns = t_ns + self.period_ns
            return 1
        self.next_ns += n * self.period_ns
        return int(n)

    def slow_due(self) -> bool:
        due = self.ticks % self.ratio == 0
        self.ticks += 1
        return due


# one step: a time (ns; some beyond int64, as a u64 stamp x 1000 from a faulty plant), a stamp
# (us, due_us), a restart (next_ns = None), an anchor, a slow_due, ticks reset to 0
_STEP = st.one_of(
    st.tuples(st.just("due"), st.one_of(st.integers(-10**10, 10**11),
                                        st.integers(0, (2**64 - 1) * 1000))),
    st.tuples(st.just("due_us"), st.one_of(st.integers(0, 10**8), st.integers(0, 2**64 - 1))),
    st.tuples(st.just("restart"), st.none()), st.tuples(st.just("anchor"),
                                                        st.integers(-10**10, 10**11)),
    st.tuples(st.just("slow"), st.none()), st.tuples(st.just("ticks0"), st.none()))


@settings(max_examples=300, deadline=None)
@given(st.sampled_from([(500, 100, 8), (1000, 100, 1), (400, 50, 3)]),
       st.lists(_STEP, max_size=40))
def test_tick_planner_steps_as_the_python_planner_did(rates, steps):
    # GIVEN the compiled planner and the Python reference at the same rates
    fast, slow, catchup = rates
    p = TickPlanner(fast, slow, max_catchup=catchup)
    ref = _PythonPlanner(p.period_ns, p.ratio, catchup)
    # WHEN both take the same steps
    for kind, x in steps:
        if kind == "due":
            got, want = p.due(x), ref.due(x)
        elif kind == "due_us":
            got, want = p.due_us(x), ref.due(x * 1000)
        elif kind == "slow":
            got, want = p.slow_due(), ref.slow_due()
        else:
            if kind == "restart":
                p.next_ns = ref.next_ns = None
            elif kind == "anchor":
                p.anchor(x)
                ref.next_ns = x
            else:
                p.ticks = ref.ticks = 0
            got = want = None
        # THEN every answer and the state after it are the same
        assert got == want and type(got) is type(want), (kind, x)
        assert (p.next_ns, p.ticks, p.skipped) == (ref.next_ns, ref.ticks, ref.skipped)


def test_loop_stats_counts_late_ticks():
    s = LoopStats(2_000_000)
    for lat in (0, 100_000, 500_000, 3_000_000):
        s.record(lat, 50_000)
    s.record(0, 2_500_000)
    assert s.ticks == 5 and s.late == 2 and s.overruns == 1
    s.roll()
    assert s.window_max_us == 3000.0


def test_loop_stats_window_p99_is_the_nearest_rank_percentile():
    s = LoopStats(1_000_000, window=1024)
    rng = np.random.default_rng(3)
    lat = rng.integers(0, 400_000, 1000)
    for v in lat:
        s.record(int(v), 10_000)
    s.roll()
    expect = np.sort(lat)[int(np.ceil(0.99 * 1000)) - 1] * 1e-3
    assert s.window_p99_us == pytest.approx(expect)
    assert s.window_max_us == pytest.approx(lat.max() * 1e-3)
    s.record(7_000, 0)                  # the next window starts empty
    s.roll()
    assert s.window_p99_us == pytest.approx(7.0) and s.window_max_us == pytest.approx(7.0)


def test_timeline_load_and_due(tmp_path):
    path = tmp_path / "tl.toml"
    path.write_text("[[command]]\nt_s = 1.0\nalpha_deg = 5\nmu_deg = 4\n"
                    "[[command]]\nt_s = 0.0\nalpha_deg = 1\nbeta_deg = 0\nmu_deg = 0\n")
    tl = Timeline(load_timeline(str(path)))
    first = tl.due(0.0)
    assert [c.t_s for c in first] == [0.0]
    assert tl.due(0.5) == []
    (c,) = tl.due(1.0)
    assert dict(c.values) == {"CMD_ALPHA_DEG": 5.0, "CMD_MU_DEG": 4.0}


@pytest.mark.parametrize("text", ["[[command]]\nalpha_deg = 1\n", "[[command]]\nt_s = 0\nfoo = 1\n",
                                  "[[command]\n", "[[command]]\nt_s = 0\nalpha_deg = nan\n"])
def test_timeline_errors_are_clear(tmp_path, text):
    path = tmp_path / "tl.toml"
    path.write_text(text)
    with pytest.raises(ValueError, match="tl.toml"):
        load_timeline(str(path))
