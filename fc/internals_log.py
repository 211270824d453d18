"""fc/internals_log.py - log of estimator and law internals (``fc_internals.npz``).

One row per fast tick, float64 columns (names carry units). Rows go into preallocated
chunks; a full chunk is handed to a writer thread that appends it to the crash-safe raw
companion ``fc_internals.raw`` (column names in ``fc_internals.cols.json``), so the loop
never waits on the disk. The chunks are a fixed pool recycled between the two threads through
int64 cells stepped by compiled calls (a free stack, a ring of full chunks): a hand-over
allocates no Python object (issue 24; a queue put and get made 23 blocks per chunk).
``close()`` converts the raw file into ``fc_internals.npz`` (one array per column), streaming:
bounded memory however long the run. ``load(path)`` reads either.

Sized for long runs (issue 24): a row is 816 bytes, so every fast tick of an hour at 500 Hz
is 1.5 GB. By default (``python -m fc``) the first ``full_rate_s`` seconds of sensor time are
logged at the full rate, then one row per ``1/tail_hz`` s (the slow-loop rate); ``full_rate_s``
None keeps every row (``python -m fc --internals-full-rate``). The rows kept are the same rows
a full-rate log holds (``t_s`` says when each was taken).

A full disk costs rows, never the log (fc/storage.py): a chunk that cannot be written is
dropped whole (counted in ``lost_rows``, reported to the disk health), the raw file keeps only
whole rows, and the next chunk is tried again, so the log resumes when space returns. If the
npz cannot be written at ``close()``, no partial file is left and the raw companion is kept.
"""
from __future__ import annotations

import _thread
import json
import math
import os
import threading

import numpy as np
from numba import carray, njit

from fc.control.carrays import i8p
from fc.frame_calls import STAMP_CELL_MAX_US, int64_at
import hyfc_wire.rawnpz as _rawnpz
from fc.storage import AppendFile, DiskHealth, atomic_write, open_for_write

__all__ = ["InternalsLog", "load"]

# the row cursor (int64[CUR_N], ``InternalsLog.cursor_address``), kept by compiled steps: no
# Python int per row (issue 24)
CUR_N_ROWS = 0          # rows taken in ``chunk``
CUR_ROW = 1             # index in ``chunk`` of the row taken last
CUR_DECIMATED = 2       # rows not logged by choice (``decimated``)
CUR_N = 3


@njit(cache=True)
def _take_row_p(cur, chunk_rows):
    """Take the next row of a chunk of ``chunk_rows`` (its index into ``cur[CUR_ROW]``); False
    when the chunk is full."""
    c = carray(i8p(cur), (CUR_N,))
    if c[CUR_N_ROWS] >= chunk_rows:
        return False
    c[CUR_ROW] = c[CUR_N_ROWS]
    c[CUR_N_ROWS] += 1
    return True


@njit(cache=True)
def _count_p(cur, k):
    """``cur[k] += 1``."""
    carray(i8p(cur), (CUR_N,))[k] += 1


# the chunk pool (int64[POOL_HDR + 3 n_chunks], ``InternalsLog._pool``), shared by the frame
# thread and the writer thread. Only compiled calls step it, and they hold the GIL from start
# to end, so each step is atomic with respect to the other thread
POOL_CUR = 0            # the chunk being filled (-1: none, no chunk was free)
POOL_HEAD = 1           # full chunks handed to the writer so far (ring position, mod n)
POOL_TAIL = 2           # full chunks the writer has taken so far
POOL_NFREE = 3          # chunks on the free stack
POOL_ROWS_BEFORE = 4    # rows taken in the chunks handed over
POOL_DROPPED = 5        # rows not logged: no chunk free (the writer is behind)
POOL_HDR = 6            # then: the free stack [n], the ring's chunks [n], their rows [n]


@njit(cache=True)
def _hand_over_p(pool, cur, n_chunks, chunk_rows, take):
    """Hand the chunk being filled to the writer (when it holds rows); with ``take``, take a
    free chunk and its first row (``cur``: the row cursor). Returns the chunk taken, -1 when
    none is free (the row counted as dropped) or when ``take`` is 0."""
    p = carray(i8p(pool), (POOL_HDR + 3 * n_chunks,))
    c = carray(i8p(cur), (CUR_N,))
    k = p[POOL_CUR]
    n = c[CUR_N_ROWS]
    if k >= 0 and n > 0:
        slot = p[POOL_HEAD] % n_chunks
        p[POOL_HDR + n_chunks + slot] = k
        p[POOL_HDR + 2 * n_chunks + slot] = n
        p[POOL_HEAD] += 1
        p[POOL_ROWS_BEFORE] += n
        c[CUR_N_ROWS] = 0
        p[POOL_CUR] = -1
    if take == 0:
        return -1
    if p[POOL_CUR] >= 0:                # (an empty chunk kept: filled from its first row)
        k = p[POOL_CUR]
    elif p[POOL_NFREE] == 0:
        p[POOL_DROPPED] += 1
        return -1
    else:
        p[POOL_NFREE] -= 1
        k = p[POOL_HDR + p[POOL_NFREE]]
        p[POOL_CUR] = k
    c[CUR_N_ROWS] = 1
    c[CUR_ROW] = 0
    return k


@njit(cache=True)
def _pop_full_p(pool, n_chunks, chunk_rows, rows):
    """The writer's next full chunk, oldest first: its index when it holds ``chunk_rows``
    rows, index + ``n_chunks`` when fewer (their number in ``rows[0]``), -1 when none."""
    p = carray(i8p(pool), (POOL_HDR + 3 * n_chunks,))
    if p[POOL_TAIL] == p[POOL_HEAD]:
        return -1
    slot = p[POOL_TAIL] % n_chunks
    p[POOL_TAIL] += 1
    k = p[POOL_HDR + n_chunks + slot]
    n = p[POOL_HDR + 2 * n_chunks + slot]
    if n == chunk_rows:
        return k
    carray(i8p(rows), (1,))[0] = n
    return k + n_chunks


@njit(cache=True)
def _release_p(pool, n_chunks, k):
    """Chunk ``k`` written: back on the free stack (filled next)."""
    p = carray(i8p(pool), (POOL_HDR + 3 * n_chunks,))
    p[POOL_HDR + p[POOL_NFREE]] = k
    p[POOL_NFREE] += 1


# which rows are kept past the full-rate span (int64[KS_N], ``InternalsLog._keep``)
KS_HAVE_T0 = 0          # 1 once the first stamp is known
KS_T0 = 1               # the first row's stamp (us)
KS_FULL_END = 2         # the first stamp past the full-rate span (us)
KS_NEXT = 3             # the next tail row's stamp (us)
KS_N = 4


@njit(cache=True)
def _keep_p(ks, stamp_us, full_us, tail_us):
    """:meth:`InternalsLog._keep` on its int64[KS_N] state at ``ks``."""
    k = carray(i8p(ks), (KS_N,))
    if k[KS_HAVE_T0] == 0:
        k[KS_T0] = stamp_us
        k[KS_FULL_END] = stamp_us + full_us
        k[KS_HAVE_T0] = 1
    if stamp_us < k[KS_FULL_END]:
        return True
    if stamp_us < k[KS_NEXT]:
        return False
    since_us = stamp_us - k[KS_T0]
    k[KS_NEXT] = k[KS_T0] + (since_us // tail_us + 1) * tail_us
    return True


@njit(cache=True)
def _keep_at_p(ks, stamp, full_us, tail_us):
    """:func:`_keep_p` of the stamp in the int64 cell at ``stamp``."""
    return _keep_p(ks, carray(i8p(stamp), (1,))[0], full_us, tail_us)


NPZ_NAME = "fc_internals.npz"
RAW_NAME = "fc_internals.raw"
COLS_NAME = "fc_internals.cols.json"


class InternalsLog:
    """Row logger. ``row()`` returns the next preallocated row to fill in place."""

    def __init__(self, out_dir: str, columns: list[str], chunk_rows: int = 1024,
                 n_chunks: int = 16, disk: DiskHealth | None = None,
                 full_rate_s: float | None = None, tail_hz: float = 100.0) -> None:
        """``full_rate_s``: every row for this long (s of frame stamps from the first row),
        then one row per ``1/tail_hz`` s; None: every row, however long the run."""
        if full_rate_s is not None and not (math.isfinite(full_rate_s) and full_rate_s >= 0.0
                                            and math.isfinite(tail_hz) and tail_hz > 0.0):
            raise ValueError(f"internals log: full rate for {full_rate_s} s then {tail_hz} Hz: "
                             "need a finite span >= 0 s and a finite rate > 0 Hz")
        self.columns = list(columns)
        self.ncol = len(columns)
        self.col = {c: i for i, c in enumerate(columns)}
        self.dir = out_dir
        self.raw_path = os.path.join(out_dir, RAW_NAME)
        self.npz_path = os.path.join(out_dir, NPZ_NAME)
        self.disk = disk
        try:
            atomic_write(os.path.join(out_dir, COLS_NAME),
                         json.dumps({"columns": self.columns, "dtype": "float64",
                                     "full_rate_s": full_rate_s,
                                     "tail_hz": None if full_rate_s is None else tail_hz}).encode())
        except OSError as exc:
            if disk is None:
                raise
            disk.failed("internals log", exc)
        self._raw = AppendFile(self.raw_path, "internals log", disk)
        # the free chunks as a stack: the chunk the writer gave back last is filled next, so a
        # writer that keeps up cycles through two chunks and the others are never touched
        # (np.zeros: their pages are not resident until written; a FIFO touched them all,
        # 13.5 MB of the fc's RSS with 103 columns). The rest (16,384 rows, 33 s at 500 Hz)
        # stay free for a slow disk. Each chunk's array, data address and bytes are made once
        # here: a hand-over picks them from these lists by index (a cached small int)
        if not 1 <= n_chunks <= 256:
            raise ValueError(f"internals log: {n_chunks} chunks: need 1 to 256")
        self._chunks = [np.zeros((chunk_rows, self.ncol)) for _ in range(n_chunks)]
        self._addresses = [int(c.__array_interface__["data"][0]) for c in self._chunks]
        self._bytes = [memoryview(c).cast("B") for c in self._chunks]
        self._n_chunks = n_chunks
        self._chunk_rows = chunk_rows
        self._pool = np.zeros(POOL_HDR + 3 * n_chunks, np.int64)
        self._pool[POOL_HDR:POOL_HDR + n_chunks] = np.arange(n_chunks)[::-1]
        self._pool[POOL_NFREE] = n_chunks
        self._pool[POOL_CUR] = -1
        self._pool_p = int(self._pool.__array_interface__["data"][0])
        self._popped = np.zeros(1, np.int64)    # rows of a partial chunk the writer took
        self._popped_p = int(self._popped.__array_interface__["data"][0])
        self._cur = np.zeros(CUR_N, np.int64)    # the row cursor (CUR_*)
        #: the data address of the row cursor (int64[CUR_N]): ``cur[CUR_ROW]`` is the row the
        #: last :meth:`take_row` took (fc/telemetry.py ``fill_row_p`` reads it there)
        self.cursor_address = int(self._cur.__array_interface__["data"][0])
        self.lost_rows = 0         # rows not written: the disk refused them
        scratch = np.zeros(CUR_N, np.int64)     # the compiled steps loaded now, not per row
        _take_row_p(int(scratch.__array_interface__["data"][0]), 1)
        _count_p(int(scratch.__array_interface__["data"][0]), CUR_DECIMATED)
        pool = np.zeros(POOL_HDR + 3, np.int64)
        pool_p = int(pool.__array_interface__["data"][0])
        pool[POOL_CUR] = -1
        _hand_over_p(pool_p, int(scratch.__array_interface__["data"][0]), 1, 1, 1)
        _pop_full_p(pool_p, 1, 1, pool_p)
        _release_p(pool_p, 1, 0)
        #: the chunk being filled (float64[chunk_rows, ncol]; None when none was free) and its
        #: data address
        self.chunk: np.ndarray | None = None
        self.chunk_address = 0
        k = _hand_over_p(self._pool_p, self.cursor_address, n_chunks, chunk_rows, 1)
        self.chunk, self.chunk_address = self._chunks[k], self._addresses[k]
        self._cur[CUR_N_ROWS] = 0                # (no row taken yet)
        # the writer sleeps on a held lock; a hand-over releases it (no object made)
        self._wake = _thread.allocate_lock()
        self._wake.acquire()
        self._sync_done: threading.Event | None = None      # set once the writer is idle
        self._stop = False
        self._full_us = None if full_rate_s is None else int(round(full_rate_s * 1e6))
        self._tail_us = max(1, int(round(1e6 / tail_hz)))
        # which rows are kept (``_keep``): int64[KS_N] stepped by compiled calls; the same
        # state as Python ints in ``_ks_big`` while a stamp beyond the cells' range is in it
        self._ks = np.zeros(KS_N, np.int64)
        self._ks_p = int(self._ks.__array_interface__["data"][0])
        self._ks_big: list[int] | None = None
        ks = np.zeros(KS_N, np.int64)                                       # (loaded now)
        ks_p = int(ks.__array_interface__["data"][0])
        _keep_p(ks_p, 0, 1, 1)
        _keep_at_p(ks_p, ks_p, 1, 1)
        self._thread = threading.Thread(target=self._writer, name="internals-log", daemon=True)
        self._thread.start()
        self.closed = False

    def row(self, stamp_us: int | None = None) -> np.ndarray | None:
        """The next row (zeroed is not guaranteed: fill every column). None if no buffer free,
        or if the row of frame stamp ``stamp_us`` (us) is not kept (past ``full_rate_s``,
        between two tail rows; without a stamp every row is kept).
        A full chunk goes to the writer on the next call (or ``flush``), after the caller has
        filled its last row."""
        if not self.take_row(stamp_us):
            return None
        return self.chunk[int(self._cur[CUR_ROW])]

    def take_row(self, stamp_us: int | None = None) -> bool:
        """:meth:`row` for a compiled filler that takes addresses (fc/telemetry.py
        ``fill_row_p``: no array object and no int per row): True when a row was taken, at
        index ``cursor[CUR_ROW]`` of ``chunk`` (at ``chunk_address``)."""
        if self._full_us is not None and stamp_us is not None and not self._keep(stamp_us):
            _count_p(self.cursor_address, CUR_DECIMATED)
            return False
        return self._next_row()

    def take_row_at(self, stamp_at: int) -> bool:
        """:meth:`take_row` of the frame whose stamp is in the int64 cell at ``stamp_at`` (below
        fc/frame_calls.py STAMP_CELL_MAX_US), read in the compiled call: no int per row."""
        if self._full_us is not None:
            if self._ks_big is None:
                keep = _keep_at_p(self._ks_p, stamp_at, self._full_us, self._tail_us)
            else:
                keep = self._keep(int64_at(stamp_at))
            if not keep:
                _count_p(self.cursor_address, CUR_DECIMATED)
                return False
        return self._next_row()

    def _next_row(self) -> bool:
        """The next row of ``chunk`` taken (a full chunk handed to the writer first); False
        when no buffer is free."""
        if self.chunk is None or not _take_row_p(self.cursor_address, self._chunk_rows):
            k = _hand_over_p(self._pool_p, self.cursor_address, self._n_chunks,
                             self._chunk_rows, 1)
            self._wake_writer()
            if k < 0:
                self.chunk = None
                return False
            self.chunk, self.chunk_address = self._chunks[k], self._addresses[k]
        return True

    def _wake_writer(self) -> None:
        """Let the writer look at the ring (it may be awake already)."""
        try:
            self._wake.release()
        except RuntimeError:                # (not held: the writer is awake)
            pass

    @property
    def n(self) -> int:
        """Rows taken in ``chunk``."""
        return int(self._cur[CUR_N_ROWS])

    @property
    def rows(self) -> int:
        """Rows taken (filled) so far."""
        return int(self._pool[POOL_ROWS_BEFORE]) + self.n

    @property
    def dropped(self) -> int:
        """Rows not logged: no chunk was free (the writer is behind)."""
        return int(self._pool[POOL_DROPPED])

    @property
    def decimated(self) -> int:
        """Rows not logged by choice: past full_rate_s, between tail rows."""
        return int(self._cur[CUR_DECIMATED])

    def _keep(self, stamp_us: int) -> bool:
        """Is the row of this frame stamp (us) kept? Every one in the first ``full_rate_s``,
        then the first at or after each multiple of the tail period (from the first stamp)."""
        if self._ks_big is None and 0 <= stamp_us < STAMP_CELL_MAX_US:
            return _keep_p(self._ks_p, stamp_us, self._full_us, self._tail_us)
        # a stamp beyond the cells' range: the same steps on Python ints
        k = self._ks_big if self._ks_big is not None else self._ks.tolist()
        if not k[KS_HAVE_T0]:
            k[KS_T0] = stamp_us
            k[KS_FULL_END] = stamp_us + self._full_us
            k[KS_HAVE_T0] = 1
        keep = True
        if stamp_us >= k[KS_FULL_END]:
            if stamp_us < k[KS_NEXT]:
                keep = False
            else:
                since_us = stamp_us - k[KS_T0]
                k[KS_NEXT] = k[KS_T0] + (since_us // self._tail_us + 1) * self._tail_us
        if all(-STAMP_CELL_MAX_US < v < 2 * STAMP_CELL_MAX_US for v in k):
            self._ks[:] = k
            self._ks_big = None
        else:
            self._ks_big = k
        return keep

    def _writer(self) -> None:
        n_chunks, rows = self._n_chunks, self._chunk_rows
        row_b = 8 * self.ncol
        while True:
            self._wake.acquire()
            # read before the ring: every chunk handed before a sync or a close asked is in it
            done, stop = self._sync_done, self._stop
            while True:                     # every full chunk, oldest first
                k = _pop_full_p(self._pool_p, n_chunks, rows, self._popped_p)
                if k < 0:
                    break
                if k < n_chunks:            # no copy: the rows are contiguous
                    ok, n = self._raw.append(self._bytes[k]), rows
                else:
                    k -= n_chunks
                    n = int(self._popped[0])
                    ok = self._raw.append(self._bytes[k][:n * row_b])
                if not ok:
                    self.lost_rows += n
                _release_p(self._pool_p, n_chunks, k)
            if done is not None:
                self._sync_done = None
                done.set()
            if stop:
                break

    def flush(self) -> None:
        """Hand the partial chunk to the writer (e.g. at shutdown)."""
        if self.chunk is not None and self.n:
            _hand_over_p(self._pool_p, self.cursor_address, self._n_chunks, self._chunk_rows, 0)
            self.chunk = None
            self._wake_writer()

    def sync(self, timeout_s: float = 60.0) -> None:
        """Hand over the partial chunk and wait until the writer has put everything on disk
        (at most ``timeout_s``: TimeoutError)."""
        self.flush()
        done = threading.Event()
        self._sync_done = done
        self._wake_writer()
        if not done.wait(timeout_s):
            raise TimeoutError(f"internals log: the writer did not finish in {timeout_s} s")

    def close(self) -> str:
        """Flush, stop the writer, write ``fc_internals.npz``; returns its path."""
        if self.closed:
            return self.npz_path
        self.closed = True
        self.flush()
        self._stop = True
        self._wake_writer()
        self._thread.join(timeout=10.0)
        self._raw.close()
        # streamed: the raw rows are turned into columns one block at a time (a column-major
        # temp file), then each column is copied into its archive member: memory bounded by
        # the block, however long the fc has run
        tmp = self.npz_path + ".tmp"
        try:
            with open_for_write(tmp) as f:
                write_npz_from_raw(self.raw_path, self.columns, f)
            os.replace(tmp, self.npz_path)
        except OSError as exc:
            # a full disk: no partial npz; the raw companion stays (``load`` reads it)
            try:
                os.unlink(tmp)
            except OSError:
                pass
            if self.disk is None:
                raise
            self.disk.failed("internals log", exc)
            return self.raw_path
        os.unlink(self.raw_path)
        return self.npz_path


#: rows per block of the streamed conversion (hyfc_wire/rawnpz.py)
BLOCK_ROWS = _rawnpz.BLOCK_ROWS


def write_npz_from_raw(raw_path: str, columns: list[str], f, block_rows: int = BLOCK_ROWS) -> None:
    """``hyfc_wire.rawnpz.write_npz_from_raw`` (the archive ``np.savez`` writes, in bounded
    memory), its temp file written through fc/storage.py ``open_for_write``."""
    _rawnpz.write_npz_from_raw(raw_path, columns, f, block_rows, open_for_write)


def _read_raw(raw_path: str, columns: list[str]) -> dict[str, np.ndarray]:
    """One array per column (whole rows only)."""
    ncol = len(columns)
    n = os.path.getsize(raw_path) // (8 * ncol)
    table = np.fromfile(raw_path, dtype=np.float64, count=n * ncol).reshape(n, ncol)
    return {c: table[:, i].copy() for i, c in enumerate(columns)}


def load(path: str) -> dict[str, np.ndarray]:
    """Load the internals log: ``path`` is the npz, the raw companion or the run directory.

    Returns one array per column. After a crash (no npz), the raw companion is read.
    """
    if os.path.isdir(path):
        npz = os.path.join(path, NPZ_NAME)
        path = npz if os.path.exists(npz) else os.path.join(path, RAW_NAME)
    if path.endswith(".npz"):
        with np.load(path) as z:
            return {k: z[k] for k in z.files}
    cols_path = os.path.join(os.path.dirname(path), COLS_NAME)
    with open(cols_path, encoding="utf-8") as f:
        columns = json.load(f)["columns"]
    return _read_raw(path, columns)
