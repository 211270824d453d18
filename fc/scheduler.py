"""fc/scheduler.py - the scheduler owns time: deadlines, waiting, lateness statistics.

Real time: absolute deadlines ``t0 + k T`` on CLOCK_MONOTONIC. Waiting is a sleep to the
deadline (libc ``clock_nanosleep(TIMER_ABSTIME)`` through ctypes, or ``time.sleep``), never a
socket or epoll timeout, which CPython rounds to whole milliseconds (shared perf anchors,
section 2); sockets are drained non-blockingly after waking. SCHED_FIFO is requested when the
OS allows it; a refusal is reported to the caller for the log.

Real time, frame-synchronised (the default, ``--sync frame``): :class:`FrameGate` decides when
a sensor frame triggers the fast tick and when the deadline has to stand in for it; the
waiting itself (``select`` on the plant socket, microsecond timeout) is the caller's.

Lockstep: :class:`TickPlanner` turns sensor time stamps into fast/slow ticks, so the
loops run on sim time and a run is deterministic.
"""
from __future__ import annotations

import ctypes
import ctypes.util
import gc
import math
import os
import struct
import time

import numpy as np
from numba import carray, njit

from fc.control.carrays import i8p
from fc.frame_calls import int64_at

__all__ = ["monotonic_ns", "sleep_until_ns", "try_realtime", "freeze_heap", "release_heap",
           "collect_garbage", "garbage_due", "GC_NEW_CONTAINERS",
           "TickPlanner", "FrameGate", "LoopStats"]

monotonic_ns = time.monotonic_ns
CLOCK_MONOTONIC = 1
TIMER_ABSTIME = 1
PR_SET_TIMERSLACK = 29
#: containers (objects the collector tracks: lists, dicts, instances, ...) allocated and still
#: alive since the last collection from which the 1 Hz chore collects (:func:`garbage_due`).
#: In the fc's steady state the count creeps up by about 1 per second without objects to show
#: for it (37 after the first second, 57 after 20 s, while 3 objects were new in generation 0:
#: ``gc.get_count()[0]`` at each 1 Hz chore of ``tools.bench.allocs``'s replay, 10,000 frames,
#: COORDINATED and CRUISE; CPython's count is not exact), so a collection runs every few
#: minutes; a leak of cyclic garbage adds to it without bound, so it crosses any threshold.
#: Below 257 the count is one of CPython's cached small ints: reading it allocates nothing
GC_NEW_CONTAINERS = 256


class _Timespec(ctypes.Structure):
    _fields_ = [("tv_sec", ctypes.c_long), ("tv_nsec", ctypes.c_long)]


try:
    _libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
    _clock_nanosleep = _libc.clock_nanosleep
    _clock_nanosleep.argtypes = [ctypes.c_int, ctypes.c_int, ctypes.POINTER(_Timespec),
                                 ctypes.POINTER(_Timespec)]
    _clock_nanosleep.restype = ctypes.c_int
except (OSError, AttributeError):  # not Linux/glibc: fall back to time.sleep
    _libc = None
    _clock_nanosleep = None
_ts = _Timespec()
_ts_ref = ctypes.byref(_ts)


def sleep_until_ns(deadline_ns: int, spin_ns: int = 0) -> None:
    """Sleep until CLOCK_MONOTONIC reaches ``deadline_ns``; spin the last ``spin_ns``."""
    target = deadline_ns - spin_ns
    if _clock_nanosleep is not None:
        _ts.tv_sec, _ts.tv_nsec = divmod(target, 1_000_000_000)
        while _clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, _ts_ref, None) == 4:  # EINTR
            pass
    else:
        dt = target - time.monotonic_ns()
        if dt > 0:
            time.sleep(dt * 1e-9)
    if spin_ns:
        while time.monotonic_ns() < deadline_ns:
            pass


_pm_qos_fd: int | None = None


def hold_cpu_wakeup_latency(us: int = 0) -> str:
    """Ask the kernel (PM QoS, ``/dev/cpu_dma_latency``) for CPU wake-up latencies of at most
    ``us`` microseconds, held until the process exits (the kernel drops the request when the
    file closes), as cyclictest does. cpuidle then keeps idle CPUs in shallow states; on this
    VM (haltpoll) an idle vCPU polls instead of halting, so a timer or packet wake-up does not
    wait for the hypervisor (docs/performance.md: 1 kHz lateness p99 97-139 -> 46-48 us).
    Returns a message for fc.log."""
    global _pm_qos_fd
    if _pm_qos_fd is not None:
        return "CPU wake-up latency request already held"
    try:
        fd = os.open("/dev/cpu_dma_latency", os.O_WRONLY)
    except OSError as exc:
        return f"CPU wake-up latency request not available ({exc})"
    try:
        os.write(fd, struct.pack("i", int(us)))
    except OSError as exc:
        os.close(fd)
        return f"CPU wake-up latency request refused ({exc})"
    _pm_qos_fd = fd
    return f"CPU wake-up latency request: {int(us)} us (/dev/cpu_dma_latency)"


def freeze_heap() -> str:
    """Take the garbage collector off the loop's timing path (call once, before the loop).

    CPython's automatic collections run wherever an allocation crosses a threshold, inside a
    tick or between a frame and its answer; with numba, LLVM bindings and pymavlink loaded a
    young-generation pass costs 0.1-0.4 ms and a middle one ~1 ms (measured in the fc at 1 kHz,
    docs/performance.md). So: collect once, move every object alive after start-up to the
    permanent generation (``gc.freeze``: never scanned again) and turn automatic collection
    off; the loop calls :func:`collect_garbage` at a moment of its choosing (the fc: in its
    1 Hz housekeeping, after the tick's answer has gone, when :func:`garbage_due`). Returns a
    message for the log."""
    gc.collect()
    gc.freeze()
    gc.disable()
    refill_float_free_list()
    return f"garbage collector: {gc.get_freeze_count()} start-up objects frozen, " \
           "collections at most at 1 Hz outside the tick, when garbage may be due"


#: CPython 3.11 keeps up to this many freed float objects for reuse (``PyFloat_MAXFREELIST``);
#: a full collection empties the list (``clear_freelists``), and the frame path's floats (clock
#: readings, times) then come from the object allocator whenever the list runs dry: the I/O
#: thread, which shares it, takes floats from it too (measured: one block on the main thread a
#: few frames after a .tlog chunk went to the I/O thread, docs/performance.md)
FLOAT_FREE_LIST_N = 100


def refill_float_free_list(n: int = FLOAT_FREE_LIST_N) -> None:
    """Fill CPython's float free list: ``n`` floats made and dropped at once (called after each
    full collection, outside the tick), so the loop's floats are reused, not allocated."""
    floats = [k + 0.5 for k in range(n)]        # n new float objects ...
    del floats                                  # ... freed together: onto the free list


def release_heap() -> None:
    """Undo :func:`freeze_heap`: automatic collection on, the frozen objects collectable again."""
    gc.unfreeze()
    gc.enable()


def garbage_due(threshold: int = GC_NEW_CONTAINERS) -> bool:
    """Whether a collection may find something: at least ``threshold`` containers allocated
    and not freed since the last collection (``gc.get_count()[0]``: CPython counts a tracked
    object's allocation up and its deallocation down, not below 0). Cyclic garbage is made of
    containers nobody frees, so a leak of it makes this True in bounded time; a steady state
    whose containers are freed as fast as they are made keeps it False, and no collection runs
    (a full collection takes 16-28 Python blocks and empties CPython's free lists, so the
    frames after it allocated too: docs/performance.md). Allocates nothing while the count is
    a cached small int (below 257) and the 3-tuple comes from CPython's free list."""
    return gc.get_count()[0] >= threshold


def collect_garbage() -> int:
    """One full collection of what was allocated since :func:`freeze_heap` (the start-up heap is
    frozen, so this scans only the run's own objects), then the float free list it emptied
    refilled (:func:`refill_float_free_list`). Returns the number of objects freed."""
    freed = gc.collect()
    refill_float_free_list()
    return freed


def try_realtime(priority: int = 50) -> tuple[bool, str]:
    """Ask for SCHED_FIFO ``priority``, 1 ns timer slack and a 0 us CPU wake-up latency
    (:func:`hold_cpu_wakeup_latency`). Returns (SCHED_FIFO granted, message for fc.log)."""
    msgs = [hold_cpu_wakeup_latency(0)]
    if _libc is not None:
        try:
            _libc.prctl(PR_SET_TIMERSLACK, ctypes.c_ulong(1), 0, 0, 0)
        except (AttributeError, OSError):
            pass
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
        msgs.append(f"real-time scheduling: SCHED_FIFO priority {priority}")
        return True, "; ".join(msgs)
    except (AttributeError, PermissionError, OSError) as exc:
        msgs.append(f"real-time scheduling not available ({exc}); running SCHED_OTHER, "
                    "expect ms-scale wake-up stalls")
    return False, "; ".join(msgs)


# TickPlanner's state (int64[_ST_N]), updated in place by its compiled steps
_NEXT, _ANCHORED, _TICKS, _SKIPPED, _ST_N = 0, 1, 2, 3, 4
#: times (ns) below this in magnitude keep every sum of ``due`` in int64 (its compiled domain);
#: beyond it (a u64 stamp from a faulty plant, x 1000) the same steps run on Python ints
_SAFE_NS = 1 << 61
_SAFE_US = _SAFE_NS // 1000
_MIN_SAFE_NS, _MIN_SAFE_US = -_SAFE_NS, -_SAFE_US    # (bound once: ``-x`` makes an int)


@njit(cache=True)
def _due_p(st, t_ns, period_ns, max_catchup):
    """:meth:`TickPlanner.due` on its state (int64[_ST_N] at ``st``)."""
    s = carray(i8p(st), (_ST_N,))
    if s[_ANCHORED] == 0:
        s[_NEXT] = t_ns
        s[_ANCHORED] = 1
    nxt = s[_NEXT]
    if t_ns < nxt:
        return 0
    n = (t_ns - nxt) // period_ns + 1
    if n > max_catchup:
        s[_SKIPPED] += n - 1
        s[_NEXT] = t_ns + period_ns
        return 1
    s[_NEXT] = nxt + n * period_ns
    return n


@njit(cache=True)
def _due_us_p(st, t_us, period_ns, max_catchup):
    """:func:`_due_p` at ``t_us`` microseconds."""
    return _due_p(st, t_us * 1000, period_ns, max_catchup)


@njit(cache=True)
def _due_at_p(st, stamp, period_ns, max_catchup):
    """:func:`_due_us_p` at the stamp (us) in the int64 cell at ``stamp``."""
    return _due_p(st, carray(i8p(stamp), (1,))[0] * 1000, period_ns, max_catchup)


@njit(cache=True)
def _slow_due_p(st, ratio):
    """:meth:`TickPlanner.slow_due` on its state (int64[_ST_N] at ``st``)."""
    s = carray(i8p(st), (_ST_N,))
    due = s[_TICKS] % ratio == 0
    s[_TICKS] += 1
    return due


class TickPlanner:
    """Fast/slow tick bookkeeping on an integer nanosecond time base (sim or wall time).

    The slow loop runs on every ``ratio``-th fast tick (``fast_hz / slow_hz`` must be an
    integer, checked here). ``due(t_ns)`` returns how many fast ticks are due at time
    ``t_ns``; more than ``max_catchup`` are skipped and counted as overruns, and the
    deadlines are re-anchored on ``t_ns``.

    The state (``next_ns``, ``ticks``, ``skipped``) lives in an int64 array that compiled
    steps update in place (issue 24: no Python int per tick); it reads and assigns as ints
    (``next_ns`` None before the first deadline). A deadline beyond int64's safe range is
    kept as a Python int and stepped in Python, with the same results.
    """

    def __init__(self, fast_hz: float, slow_hz: float, max_catchup: int = 8) -> None:
        if fast_hz <= 0 or slow_hz <= 0:
            raise ValueError("loop rates must be positive")
        ratio = fast_hz / slow_hz
        if abs(ratio - round(ratio)) > 1e-9 or round(ratio) < 1:
            raise ValueError(f"fast rate {fast_hz} Hz must be an integer multiple of the "
                             f"slow rate {slow_hz} Hz")
        self.ratio = int(round(ratio))
        self.fast_hz = float(fast_hz)
        self.slow_hz = float(slow_hz)
        self.period_ns = int(round(1e9 / fast_hz))
        self.fast_dt_s = self.period_ns * 1e-9
        self.slow_dt_s = self.fast_dt_s * self.ratio
        self.max_catchup = max_catchup
        self._st = np.zeros(_ST_N, np.int64)
        self._st_p = int(self._st.__array_interface__["data"][0])
        self._big_next: int | None = None     # a deadline beyond the safe range (see above)
        # the compiled steps loaded now (on a scratch state), not in the first tick
        scratch = np.zeros(_ST_N, np.int64)
        p = int(scratch.__array_interface__["data"][0])
        _due_p(p, 0, self.period_ns, max_catchup)
        _due_us_p(p, 0, self.period_ns, max_catchup)
        _due_at_p(p, p + 8 * _TICKS, self.period_ns, max_catchup)
        _slow_due_p(p, self.ratio)

    @property
    def next_ns(self) -> int | None:
        """The next fast deadline (ns), None before the first."""
        if self._big_next is not None:
            return self._big_next
        return int(self._st[_NEXT]) if self._st[_ANCHORED] else None

    @next_ns.setter
    def next_ns(self, value: int | None) -> None:
        self._big_next = None
        if value is None:
            self._st[_ANCHORED] = 0
        elif _MIN_SAFE_NS < value < _SAFE_NS:
            self._st[_NEXT] = value
            self._st[_ANCHORED] = 1
        else:
            self._big_next = value
            self._st[_ANCHORED] = 1

    @property
    def ticks(self) -> int:
        """Fast ticks run (``slow_due`` calls)."""
        return int(self._st[_TICKS])

    @ticks.setter
    def ticks(self, value: int) -> None:
        self._st[_TICKS] = value

    @property
    def skipped(self) -> int:
        """Fast deadlines skipped (overruns)."""
        return self._st.item(_SKIPPED)              # (an int; no numpy scalar)

    @skipped.setter
    def skipped(self, value: int) -> None:
        self._st[_SKIPPED] = value

    def anchor(self, t_ns: int) -> None:
        """Start (or restart) the deadlines at ``t_ns``: the first tick is due at ``t_ns``."""
        self.next_ns = t_ns

    def due(self, t_ns: int) -> int:
        if self._big_next is None and _MIN_SAFE_NS < t_ns < _SAFE_NS:
            return _due_p(self._st_p, t_ns, self.period_ns, self.max_catchup)
        return self._due_py(t_ns)

    def due_us(self, t_us: int) -> int:
        """``due(t_us * 1000)`` (a frame stamp in us) without the product as a Python int."""
        if self._big_next is None and _MIN_SAFE_US < t_us < _SAFE_US:
            return _due_us_p(self._st_p, t_us, self.period_ns, self.max_catchup)
        return self._due_py(t_us * 1000)

    def due_at(self, stamp_at: int) -> int:
        """:meth:`due_us` of the frame stamp in the int64 cell at ``stamp_at`` (below
        fc/frame_calls.py STAMP_CELL_MAX_US, the safe range: fc/link.py ``read_frame_at``),
        read in the compiled call: no Python int for it."""
        if self._big_next is None:
            return _due_at_p(self._st_p, stamp_at, self.period_ns, self.max_catchup)
        return self._due_py(int64_at(stamp_at) * 1000)

    def _due_py(self, t_ns: int) -> int:
        """:func:`_due_p`'s steps on Python ints (times beyond the int64-safe range)."""
        if self.next_ns is None:
            self.anchor(t_ns)
        nxt = self.next_ns
        if t_ns < nxt:
            return 0
        n = (t_ns - nxt) // self.period_ns + 1
        if n > self.max_catchup:
            self.skipped += n - 1
            self.next_ns = t_ns + self.period_ns
            return 1
        self.next_ns = nxt + n * self.period_ns
        return int(n)

    def slow_due(self) -> bool:
        """Call once per fast tick, before running it: True when the slow loop runs too."""
        return _slow_due_p(self._st_p, self.ratio)


class FrameGate:
    """When the real-time fast tick runs if it follows the plant's sensor frames.

    Pure bookkeeping on integer CLOCK_MONOTONIC nanoseconds (no clock, no I/O), as the flight
    stacks run their rate loop on the IMU sample (PX4: on the gyro publication; ArduPilot:
    ``wait_for_sample``). ``next_ns`` is when the next tick is due, one period after the last
    one:

    * a new frame arriving at or after ``next_ns - accept_ns`` triggers the tick at once and
      the grid follows the plant's clock: an early frame re-anchors it (``next_ns = arrival +
      period``), a late one moves it by 1/8 of its lateness (its successor is expected on the
      plant's grid, not a period after the late frame). The answer is then one hop plus the
      tick's work after the frame;
    * a frame arriving earlier (the plant runs faster than the fast loop, a burst, or the grid
      is out of phase with the plant at start-up) is only absorbed (estimator); its successor,
      a plant period later, falls in the window and locks the grid on;
    * with no acceptable frame by ``next_ns + grace_ns`` the tick runs anyway (on an absorbed
      frame: a grid tick; on the last data: a fallback tick; both counted) and
      ``next_ns`` advances by one period, so the loop, its counters and the hold/failsafe
      logic keep their rate;
    * more than ``max_behind`` periods behind, the missed ticks are skipped (counted) and the
      deadlines re-anchored.

    ``accept_frac`` (< 0.5) bounds how early a frame may trigger a tick, so a plant at twice the
    fast rate cannot drive the law at twice its dt; ``grace_frac`` is how long a late frame is
    waited for.
    """

    TICK_FRAME, TICK_GRID, TICK_FALLBACK = 0, 1, 2
    LATE_GAIN_SHIFT = 3     # a late frame moves the grid by 1/8 of its lateness

    def __init__(self, period_ns: int, accept_frac: float = 0.4, grace_frac: float = 0.5,
                 max_behind: int = 2) -> None:
        if not 0.0 <= accept_frac < 0.5:
            raise ValueError("accept_frac must be in [0, 0.5)")
        if not 0.0 <= grace_frac < 1.0:
            raise ValueError("grace_frac must be in [0, 1)")
        self.period_ns = int(period_ns)
        self.accept_ns = int(period_ns * accept_frac)
        self.grace_ns = int(period_ns * grace_frac)
        self.max_behind = max_behind
        self.next_ns = 0
        self.pending = False        # a frame absorbed since the last tick
        self.frame_ticks = 0
        self.grid_ticks = 0
        self.fallback_ticks = 0
        self.absorbed = 0
        self.skipped = 0

    def start(self, now_ns: int) -> None:
        """First tick due one period from ``now_ns`` (or on the first frame)."""
        self.next_ns = now_ns + self.period_ns
        self.pending = False

    def wait_until_ns(self) -> int:
        """Latest time to wait for a frame before the tick runs without one."""
        return self.next_ns + self.grace_ns

    def on_frame(self, arrival_ns: int) -> bool:
        """A new frame arrived at ``arrival_ns``: True = run the tick now (re-anchored on the
        frame), False = absorbed, keep waiting."""
        if arrival_ns >= self.next_ns - self.accept_ns:
            err = arrival_ns - self.next_ns
            # follow the plant's clock: an early frame moves the grid to it at once, a late one
            # only by a fraction (a late frame is usually the plant's or the network's jitter,
            # and its successor comes on the plant's grid, not a period after the late one)
            self.next_ns += self.period_ns + (err if err < 0 else err >> self.LATE_GAIN_SHIFT)
            self.pending = False
            self.frame_ticks += 1
            return True
        self.pending = True
        self.absorbed += 1
        return False

    def on_timeout(self, now_ns: int) -> int:
        """The wait ended without a new frame at ``now_ns`` (>= ``wait_until_ns()``): the tick
        runs. Returns TICK_GRID (on an absorbed frame) or TICK_FALLBACK (no new frame)."""
        kind = self.TICK_GRID if self.pending else self.TICK_FALLBACK
        if kind == self.TICK_GRID:
            self.grid_ticks += 1
        else:
            self.fallback_ticks += 1
        self.next_ns += self.period_ns
        self.pending = False
        if now_ns - self.next_ns > self.max_behind * self.period_ns:
            missed = (now_ns - self.next_ns) // self.period_ns
            self.skipped += int(missed)
            self.next_ns = now_ns + self.period_ns
        return kind


class LoopStats:
    """Wake-up lateness and execution time of the fast loop (real time), preallocated.

    A tick is late when it woke more than ``late_frac`` of a period after its deadline.
    ``window_*`` are over the last ``window`` ticks (for telemetry, reset by ``roll``).
    """

    def __init__(self, period_ns: int, late_frac: float = 0.2, window: int = 1024) -> None:
        self.period_ns = period_ns
        self.late_ns = int(period_ns * late_frac)
        self.ticks = 0
        self.late = 0
        self.overruns = 0           # tick work longer than a period
        self.buf = np.zeros(window, dtype=np.int64)
        self._sorted = np.zeros(window, dtype=np.int64)     # scratch for roll()
        self.n = 0
        self.window_max_us = 0.0
        self.window_p99_us = 0.0
        self.exec_max_us = 0.0

    def record(self, lateness_ns: int, exec_ns: int) -> None:
        self.ticks += 1
        if lateness_ns > self.late_ns:
            self.late += 1
        if exec_ns > self.period_ns:
            self.overruns += 1
        if self.n < self.buf.shape[0]:
            self.buf[self.n] = lateness_ns
            self.n += 1
        if exec_ns * 1e-3 > self.exec_max_us:
            self.exec_max_us = exec_ns * 1e-3

    def roll(self) -> None:
        """Summarise the window (called from the slow housekeeping, ~1 Hz)."""
        n = self.n
        if n:
            # the 99th percentile by selection in a preallocated scratch (np.percentile costs
            # ~250 us cold at 1 kHz and delayed the next frame's tick); nearest rank
            w = self._sorted[:n]
            w[:] = self.buf[:n]
            k = min(n - 1, int(math.ceil(0.99 * n)) - 1)
            w.partition(k)
            self.window_p99_us = float(w[k]) * 1e-3
            self.window_max_us = float(self.buf[:n].max()) * 1e-3
        self.n = 0
