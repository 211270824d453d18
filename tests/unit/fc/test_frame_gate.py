"""Unit tier: fc.scheduler.FrameGate (the frame-synchronised real-time tick) and the
garbage-collector hold (freeze_heap / garbage_due / collect_garbage / release_heap), with
injected times."""
from __future__ import annotations

import gc

import pytest

from fc.scheduler import (FLOAT_FREE_LIST_N, GC_NEW_CONTAINERS, FrameGate, collect_garbage,
                          freeze_heap, garbage_due, release_heap)

T = 1_000_000          # 1 kHz period, ns
US = 1_000


def _drive(gate: FrameGate, arrivals: list[int], end_ns: int) -> list[tuple[int, str]]:
    """Simulate the fc's wait loop on ``arrivals`` (ns, sorted): returns (tick time, kind)."""
    ticks = []
    i = 0
    now = 0
    while True:
        until = gate.wait_until_ns()
        nxt = arrivals[i] if i < len(arrivals) else None
        if nxt is not None and nxt < until:
            now = nxt
            i += 1
            if gate.on_frame(now):
                ticks.append((now, "frame"))
        else:
            now = until
            if now > end_ns:
                return ticks
            kind = gate.on_timeout(now)
            ticks.append((now, "grid" if kind == FrameGate.TICK_GRID else "fallback"))


def test_same_rate_plant_every_frame_triggers_its_tick():
    g = FrameGate(T)
    g.start(0)
    # the plant's grid is 0.3 T out of phase with the fc's start, with +-50 us jitter
    arrivals = [300 * US + k * T + (50 * US if k % 3 == 0 else -20 * US) for k in range(1000)]
    ticks = _drive(g, arrivals, arrivals[-1])
    frame_ticks = [t for t, kind in ticks if kind == "frame"]
    # the first frame finds the grid out of phase (absorbed); its successor locks the grid
    # on, and from then on each frame triggers its own tick on arrival
    assert frame_ticks == arrivals[1:]
    assert g.absorbed == 1 and g.grid_ticks == 0
    assert g.fallback_ticks == 0


def test_grid_ahead_of_the_plant_locks_on_after_one_frame():
    g = FrameGate(T)
    g.start(0)                                # first tick due at 1.0 ms
    arrivals = [200 * US + k * T for k in range(50)]   # 0.8 T early against that grid
    ticks = _drive(g, arrivals, arrivals[-1])
    # one frame absorbed, then every frame triggers its own tick
    assert [t for t, kind in ticks if kind == "frame"] == arrivals[1:]
    assert g.absorbed == 1


def test_late_frame_does_not_push_the_grid_a_whole_lateness_later():
    g = FrameGate(T)
    g.start(0)
    arrivals = [k * T + T for k in range(20)]
    arrivals[5] += 400 * US                   # one frame 0.4 T late (plant or network jitter)
    ticks = _drive(g, arrivals, arrivals[-1])
    frame_ticks = [t for t, kind in ticks if kind == "frame"]
    assert frame_ticks == arrivals            # its successor, on time, still triggers a tick
    assert g.absorbed == 0


def test_missing_frames_fall_back_to_the_deadline_at_the_fast_rate():
    g = FrameGate(T)
    g.start(0)
    arrivals = [k * T + T for k in range(10)] + [k * T + T for k in range(30, 40)]
    ticks = _drive(g, arrivals, 40 * T)
    fb = [t for t, kind in ticks if kind == "fallback"]
    assert 19 <= len(fb) <= 21                # the 20-frame gap is filled at the fast rate
    gaps = [b - a for a, b in zip(fb, fb[1:])]
    assert all(g_ == T for g_ in gaps[1:-1])
    assert [t for t, kind in ticks if kind == "frame"][-10:] == arrivals[-10:]


def test_plant_at_twice_the_fast_rate_does_not_double_the_tick_rate():
    g = FrameGate(2 * T)                      # fc 500 Hz, plant 1 kHz
    g.start(0)
    arrivals = [k * T + T for k in range(400)]
    ticks = _drive(g, arrivals, arrivals[-1])
    assert 195 <= len(ticks) <= 205           # ~200 ticks for 400 frames
    assert g.absorbed >= 195


def test_plant_at_half_the_fast_rate_ticks_at_the_fast_rate():
    g = FrameGate(T)                          # fc 1 kHz, plant 500 Hz
    g.start(0)
    arrivals = [k * 2 * T + T for k in range(200)]
    ticks = _drive(g, arrivals, arrivals[-1])
    assert 395 <= len(ticks) <= 405
    assert g.frame_ticks == 200


def test_far_behind_skips_instead_of_bursting():
    g = FrameGate(T, max_behind=2)
    g.start(0)
    g.on_timeout(20 * T)                      # the process stalled for ~20 periods
    assert g.skipped >= 15
    assert g.next_ns == 21 * T


@pytest.mark.parametrize("kw", [{"accept_frac": 0.5}, {"accept_frac": -0.1},
                                {"grace_frac": 1.0}])
def test_bad_gate_settings_are_refused(kw):
    with pytest.raises(ValueError):
        FrameGate(T, **kw)


def test_freeze_heap_turns_automatic_collection_off_and_release_restores_it():
    assert gc.isenabled()
    try:
        msg = freeze_heap()
        assert not gc.isenabled()
        assert gc.get_freeze_count() > 0
        assert "frozen" in msg

        class Cycle:
            pass

        a, b = Cycle(), Cycle()
        a.b, b.a = b, a
        del a, b
        assert collect_garbage() >= 2         # the 1 Hz pass still frees the run's cycles
    finally:
        release_heap()
    assert gc.isenabled()
    assert gc.get_freeze_count() == 0


class _Cycle:
    pass


def _make_cycles(n: int) -> None:
    """``n`` pairs of objects referring to each other, dropped: 2 n containers of cyclic
    garbage that only a collection frees."""
    for _ in range(n):
        a, b = _Cycle(), _Cycle()
        a.b, b.a = b, a


def test_no_collection_is_due_when_nothing_was_allocated():
    # GIVEN the heap frozen and collected (the fc's state after start-up)
    try:
        freeze_heap()
        collect_garbage()
        # WHEN objects are made and freed again (no container outlives the loop), or nothing
        for _ in range(1000):
            x = [1.0, 2.0]
            del x
        # THEN no collection is due, even at a threshold of 16 containers (the test's own
        # frame and iterator count 2)
        assert not garbage_due(16), gc.get_count()
        assert not garbage_due(), gc.get_count()
    finally:
        release_heap()


def test_a_collection_is_due_once_cyclic_garbage_was_made():
    # GIVEN the heap frozen and collected
    try:
        freeze_heap()
        collect_garbage()
        # WHEN fewer cycles than the threshold are leaked, then enough to cross it
        _make_cycles(10)
        assert not garbage_due(), gc.get_count()
        _make_cycles(GC_NEW_CONTAINERS // 2)
        # THEN a collection is due, frees every leaked object, and is not due after it
        assert garbage_due(), gc.get_count()
        assert collect_garbage() >= 2 * (10 + GC_NEW_CONTAINERS // 2)
        assert not garbage_due(), gc.get_count()
    finally:
        release_heap()


@pytest.mark.parametrize("threshold", [16, 100, 300])
def test_the_collection_is_due_at_the_threshold(threshold):
    # GIVEN the heap frozen and collected, and containers kept alive one by one
    try:
        freeze_heap()
        collect_garbage()
        kept = []
        while len(kept) < 2 * threshold and not garbage_due(threshold):
            kept.append(_Cycle())
        # THEN it is due once the kept containers reach the threshold (give or take the list
        # and the test's own frame)
        assert threshold - 4 <= len(kept) <= threshold, (len(kept), gc.get_count())
    finally:
        release_heap()


def _floats_allocated_after(collect, n: int) -> int:
    """Python object-allocator blocks taken by ``n`` floats made (and kept) right after
    ``collect()`` (tools.bench.allocs' counter: every block of PYMEM_DOMAIN_OBJ)."""
    from tools.bench.allocs import PyAllocCounter
    counter = PyAllocCounter()
    keep = [None] * n
    idx = list(range(n))
    base = 0.25
    collect()
    with counter:
        for i in idx:                   # (one block: the list's iterator)
            keep[i] = base + i          # a new float object each
    return int(counter.counts[0]) + int(counter.counts[1])


def test_the_floats_after_a_collection_come_from_the_free_list():
    # GIVEN a full collection, which empties CPython's free lists: plain gc.collect() makes the
    # next floats come from the object allocator, a block each
    try:
        freeze_heap()
        n = FLOAT_FREE_LIST_N // 2
        plain = _floats_allocated_after(gc.collect, n)
        # WHEN the fc's collection runs instead, THEN the same floats take no block (the list
        # refilled after the collection): the window's own few blocks beside them (3-6,
        # depending on the heap the tests before left)
        ours = _floats_allocated_after(collect_garbage, n)
        assert plain >= n, plain
        assert ours <= n // 5, (plain, ours)
    finally:
        release_heap()
