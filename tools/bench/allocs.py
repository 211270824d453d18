"""Allocations per plant frame in the fc's steady state (tools.bench, issue 24).

A count, not a time: valid on a loaded machine. The sensor datagrams of a closed-loop flight
(``tools.bench.profile.record``: the stand-in physics against a real controller, the given
flight mode) are replayed into a fresh ``fc.app.FlightController`` in process, one datagram
per step of its lockstep loop (``plant.read_frame_at``, ``loops.lockstep_exchange``,
``loops.housekeeping``). After ``WARM_FRAMES`` frames, over the measured frames:

- Python: every block taken from Python's object allocator (``PYMEM_DOMAIN_OBJ``: every
  Python object, and the small buffers of lists, dicts, bytearrays) while the controller's
  calls run. The domain's allocator is wrapped for the measurement by counting functions
  compiled with ``numba.cfunc`` that forward each call to the allocator they replace (the way
  ``tracemalloc`` hooks it; Python code cannot be the hook, it would allocate). Gross count:
  a block allocated and freed within the frame counts. The feeding of the socket and the
  counter reads are outside the counted window (the read's own block is calibrated out).
- numba: NRT records (``rtsys.get_allocation_stats()``, ``mi_alloc``): one per array wrapped
  for a compiled call or created inside one, freed at its end; ``alloc`` (NRT data
  allocations) reported beside it.
- growth (``block_growth``): ``sys.getallocatedblocks()`` after a full collection at
  checkpoints of the replay (net blocks kept: a leak grows it in proportion to the frames).

The frames are paced as in a real-time run: the loop's clock (``now_s``) is the sensor time
(2 ms per frame at 500 Hz), so the ground-station streams and the 1 Hz chores come as often per
frame as in flight (one round of 1 Hz chores every ``frame_hz`` frames).
"""
from __future__ import annotations

import ctypes
import gc
import math
import sys

import numpy as np

__all__ = ["PyAllocCounter", "block_growth", "count_allocations", "fc_allocations"]

WARM_FRAMES = 200           # replayed first: caches, first-call paths, buffers that grow once
PYMEM_DOMAIN_OBJ = 2        # Include/cpython/pymem.h


class _PyMemAllocatorEx(ctypes.Structure):
    _fields_ = [("ctx", ctypes.c_void_p), ("malloc", ctypes.c_void_p),
                ("calloc", ctypes.c_void_p), ("realloc", ctypes.c_void_p),
                ("free", ctypes.c_void_p)]


_HOOKS = None


def _compile_hooks(orig: _PyMemAllocatorEx):
    """The four counting wrappers of ``orig`` (compiled once per process: the addresses of the
    functions they forward to are compiled in, so they are never cached on disk)."""
    from numba import cfunc, types
    malloc = ctypes.CFUNCTYPE(ctypes.c_void_p, ctypes.c_void_p, ctypes.c_size_t)(orig.malloc)
    calloc = ctypes.CFUNCTYPE(ctypes.c_void_p, ctypes.c_void_p, ctypes.c_size_t,
                              ctypes.c_size_t)(orig.calloc)
    realloc = ctypes.CFUNCTYPE(ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p,
                               ctypes.c_size_t)(orig.realloc)
    free = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_void_p)(orig.free)
    state_p = types.CPointer(types.int64)     # ctx: int64[4] = malloc, calloc, realloc, orig ctx

    @cfunc(types.voidptr(state_p, types.size_t))
    def h_malloc(st, size):
        st[0] += 1
        return malloc(st[3], size)

    @cfunc(types.voidptr(state_p, types.size_t, types.size_t))
    def h_calloc(st, n, size):
        st[1] += 1
        return calloc(st[3], n, size)

    @cfunc(types.voidptr(state_p, types.voidptr, types.size_t))
    def h_realloc(st, p, size):
        st[2] += 1
        return realloc(st[3], p, size)

    @cfunc(types.void(state_p, types.voidptr))
    def h_free(st, p):
        free(st[3], p)

    # the ctypes function objects stay referenced with the compiled hooks
    return (h_malloc, h_calloc, h_realloc, h_free, (malloc, calloc, realloc, free))


class PyAllocCounter:
    """Counts the blocks Python's object allocator hands out while installed (``with``).

    ``counts``: ctypes int64[4] (malloc, calloc, realloc, -); ``blocks()`` = malloc + calloc,
    read without allocating more than the int it returns."""

    def __init__(self) -> None:
        global _HOOKS
        self._orig = _PyMemAllocatorEx()
        ctypes.pythonapi.PyMem_GetAllocator(ctypes.c_int(PYMEM_DOMAIN_OBJ),
                                            ctypes.byref(self._orig))
        if _HOOKS is None:
            _HOOKS = (self._orig.malloc, _compile_hooks(self._orig))
        elif _HOOKS[0] != self._orig.malloc:
            raise RuntimeError("the object allocator changed since the hooks were compiled")
        self.counts = (ctypes.c_int64 * 4)()
        self.counts[3] = self._orig.ctx or 0
        h = _HOOKS[1]
        self._hook = _PyMemAllocatorEx(ctypes.addressof(self.counts), h[0].address,
                                       h[1].address, h[2].address, h[3].address)
        self.installed = False

    def __enter__(self) -> "PyAllocCounter":
        ctypes.pythonapi.PyMem_SetAllocator(ctypes.c_int(PYMEM_DOMAIN_OBJ),
                                            ctypes.byref(self._hook))
        self.installed = True
        return self

    def __exit__(self, *exc) -> None:
        ctypes.pythonapi.PyMem_SetAllocator(ctypes.c_int(PYMEM_DOMAIN_OBJ),
                                            ctypes.byref(self._orig))
        self.installed = False


_MARK = None


def _marker():
    """``mark(counts, marks, k)``: ``marks[k] = counts[0] + counts[1]`` (the blocks counted so
    far; both int64 arrays by address), compiled: the call makes no Python object."""
    global _MARK
    if _MARK is None:
        from numba import carray, njit

        from fc.control.carrays import i8p

        @njit
        def mark(counts, marks, k):
            c = carray(i8p(counts), (4,))
            carray(i8p(marks), (4,))[k] = c[0] + c[1]
        _MARK = mark
    return _MARK


def _nrt_stats():
    from numba.core.runtime import rtsys
    return rtsys.get_allocation_stats()


class _Replay:
    """A fresh controller in ``flight_mode`` fed ``datagrams`` one per lockstep loop step, the
    loop's clock being the sensor time (``frame_hz``), the 1 Hz chores due once per
    ``frame_hz`` frames (one stage per frame, as ``Housekeeping`` does them)."""

    def __init__(self, datagrams: list, flight_mode: str, frame_hz: float = 500.0) -> None:
        from tools.bench.profile import _drain, _Rig
        self.datagrams = datagrams
        self.frame_hz = frame_hz
        self.per_chores = max(1, int(round(frame_hz)))
        self.rig = _Rig(flight_mode)
        self._drain = _drain
        self.k = 0

    def feed(self) -> float:
        """Send the next datagram; the loop clock (s) of its frame."""
        k, hk = self.k, self.rig.hk
        self.rig.plant.sendto(self.datagrams[k], self.rig.addr)
        if k % self.per_chores == 0:
            hk.next_1hz = 0.0
        elif hk.chore == 0:
            hk.next_1hz = math.inf
        self.k = k + 1
        return 1000.0 + k / self.frame_hz

    def step(self, now_s: float) -> None:
        """One step of the lockstep loop on the datagram sent (as ``fc.loops._run_lockstep``)."""
        fc = self.rig.fc
        code = fc.plant.read_frame_at(fc.meas_scratch)
        if code >= 0:
            fc.loops.lockstep_exchange(code, now_s)
        fc.loops.housekeeping(now_s, False)

    def drain(self) -> None:
        self._drain(self.rig.plant, self.rig.sink)

    def run(self, n: int) -> None:
        for _ in range(n):
            self.step(self.feed())
            self.drain()

    def close(self) -> None:
        self.rig.close()


def count_allocations(datagrams: list, flight_mode: str = "COORDINATED",
                      frame_hz: float = 500.0) -> dict:
    """Replay ``datagrams`` (the first ``WARM_FRAMES`` uncounted) into a fresh controller in
    ``flight_mode``; allocations per measured frame (see the module docstring)."""
    from numba.core.runtime import _nrt_python
    n = len(datagrams) - WARM_FRAMES
    if n <= 0:
        raise ValueError(f"need more than {WARM_FRAMES} datagrams")
    stats_were_on = _nrt_python.memsys_stats_enabled()
    _nrt_python.memsys_enable_stats()
    # the bench's own objects are made before the controller and its warm-up (whose first
    # 1 Hz chore collects what was made before it): compiling the marker or a list per frame
    # made enough new containers for the fc's rule (fc/scheduler.py ``garbage_due``) to run a
    # collection in the counted window that only the bench had made due
    counter = PyAllocCounter()
    # the windows' edges: a compiled call copies the count into ``marks[k]`` (no Python
    # int is made inside a window: reading the ctypes counter from Python made one or two,
    # depending on the values, so a window's own cost was not a constant)
    marks = np.zeros(4, np.int64)
    mark = _marker()
    c_p, m_p = ctypes.addressof(counter.counts), marks.ctypes.data
    mark(c_p, m_p, 0)                       # (compiled or loaded before the count)
    # per frame: the receive (read_frame_at), the frame (lockstep_exchange), the housekeeping
    # (ground station, .tlog streams, 1 Hz chores), as ``_Replay.step``
    per = np.zeros((n, 3), np.int64)
    rep = _Replay(datagrams, flight_mode, frame_hz)
    try:
        rep.run(WARM_FRAMES)
        feed, drain = rep.feed, rep.drain
        fc = rep.rig.fc
        plant, meas, loops = fc.plant, fc.meas_scratch, fc.loops
        with counter:
            empty = 0                       # the window's own cost: two marks, nothing between
            for _ in range(1000):
                mark(c_p, m_p, 0)
                mark(c_p, m_p, 1)
                empty += marks.item(1) - marks.item(0)
            read_cost = empty / 1000.0
            blocks0 = sys.getallocatedblocks()
            nrt0 = _nrt_stats()
            for k in range(n):
                now = feed()
                mark(c_p, m_p, 0)
                code = plant.read_frame_at(meas)
                mark(c_p, m_p, 1)
                if code >= 0:
                    loops.lockstep_exchange(code, now)
                mark(c_p, m_p, 2)
                loops.housekeeping(now, False)
                mark(c_p, m_p, 3)
                per[k, 0] = marks.item(1) - marks.item(0)
                per[k, 1] = marks.item(2) - marks.item(1)
                per[k, 2] = marks.item(3) - marks.item(2)
                drain()
            nrt1 = _nrt_stats()
            blocks1 = sys.getallocatedblocks()
            realloc = counter.counts[2]
        per = per.tolist()
        parts = [sum(r[i] for r in per) / n - read_cost for i in range(3)]
        net = sorted(sum(r) for r in per)
        quiet = sum(1 for r in per if not any(r))
        frame_free = sum(1 for r in per if r[0] == 0 and r[1] == 0)
        hk_free = sum(1 for r in per if r[2] == 0)
        py = sum(parts)
        return {"flight_mode": flight_mode, "frames": n,
                "py_allocs_per_frame": py,
                "py_allocs_per_frame_read": parts[0],
                "py_allocs_per_frame_frame": parts[1],
                "py_allocs_per_frame_housekeeping": parts[2],
                "py_allocs_frame_median": float(net[n // 2]),
                "py_alloc_free_frames_pct": 100.0 * quiet / n,
                "py_alloc_free_frame_paths_pct": 100.0 * frame_free / n,
                "py_alloc_free_housekeeping_pct": 100.0 * hk_free / n,
                "py_window_read_cost": read_cost,
                "py_reallocs_total": int(realloc),
                "nrt_allocs_per_frame": (nrt1.mi_alloc - nrt0.mi_alloc) / n,
                "nrt_data_allocs_per_frame": (nrt1.alloc - nrt0.alloc) / n,
                "blocks_net_change": int(blocks1 - blocks0),
                "note": "in process, one datagram per lockstep loop step; loop clock = sensor "
                        "time; py = blocks from PYMEM_DOMAIN_OBJ (gross, while the fc's calls "
                        "run; _read / _frame / _housekeeping: read_frame_at, lockstep_exchange, "
                        "housekeeping); alloc_free_frames: frames whose three calls allocated "
                        "nothing; alloc_free_frame_paths: frames whose read and frame allocated "
                        "nothing (the housekeeping aside); alloc_free_housekeeping: frames "
                        "whose housekeeping allocated nothing (no stream or chore due); nrt = "
                        "numba NRT meminfo records (mi_alloc)"}
    finally:
        rep.close()
        if not stats_were_on:
            _nrt_python.memsys_disable_stats()


def block_growth(datagrams: list, flight_mode: str, checkpoints: list[int],
                 frame_hz: float = 500.0) -> list[int]:
    """``sys.getallocatedblocks()`` after a full collection, at each checkpoint (a number of
    frames replayed after the first ``WARM_FRAMES``): what the controller keeps. A leak of
    one block per frame grows it by one per frame."""
    rep = _Replay(datagrams, flight_mode, frame_hz)
    try:
        rep.run(WARM_FRAMES)
        out, done = [], 0
        for cp in checkpoints:
            rep.run(cp - done)
            done = cp
            gc.collect()
            out.append(sys.getallocatedblocks())
        return out
    finally:
        rep.close()


def fc_allocations(quick: bool = False, frames: int | None = None) -> dict:
    """``count_allocations`` in COORDINATED and in CRUISE: {mode: result}."""
    from tools.bench.profile import record
    n = frames or (300 if quick else 3000)
    out = {}
    for mode in ("COORDINATED", "CRUISE"):
        out[mode] = count_allocations(record(WARM_FRAMES + n, mode), mode)
    return out
