"""fc/internals_log.py - full-rate log of estimator and law internals (``fc_internals.npz``).

One row per fast tick, float64 columns (names carry units). Rows go into preallocated
chunks; a full chunk is handed to a writer thread that appends it to the crash-safe raw
companion ``fc_internals.raw`` (column names in ``fc_internals.cols.json``), so the loop
never waits on the disk. ``close()`` converts the raw file into ``fc_internals.npz``
(one array per column). ``load(path)`` reads either.

A full disk costs rows, never the log (fc/storage.py): a chunk that cannot be written is
dropped whole (counted in ``lost_rows``, reported to the disk health), the raw file keeps only
whole rows, and the next chunk is tried again, so the log resumes when space returns. If the
npz cannot be written at ``close()``, no partial file is left and the raw companion is kept.
"""
from __future__ import annotations

import json
import os
import queue
import threading

import numpy as np

from fc.storage import AppendFile, DiskHealth, atomic_write, open_for_write

__all__ = ["InternalsLog", "load"]

NPZ_NAME = "fc_internals.npz"
RAW_NAME = "fc_internals.raw"
COLS_NAME = "fc_internals.cols.json"


class InternalsLog:
    """Row logger. ``row()`` returns the next preallocated row to fill in place."""

    def __init__(self, out_dir: str, columns: list[str], chunk_rows: int = 2048,
                 n_chunks: int = 8, disk: DiskHealth | None = None) -> None:
        self.columns = list(columns)
        self.ncol = len(columns)
        self.col = {c: i for i, c in enumerate(columns)}
        self.dir = out_dir
        self.raw_path = os.path.join(out_dir, RAW_NAME)
        self.npz_path = os.path.join(out_dir, NPZ_NAME)
        self.disk = disk
        try:
            atomic_write(os.path.join(out_dir, COLS_NAME),
                         json.dumps({"columns": self.columns, "dtype": "float64"}).encode())
        except OSError as exc:
            if disk is None:
                raise
            disk.failed("internals log", exc)
        self._raw = AppendFile(self.raw_path, "internals log", disk)
        self._free: queue.Queue = queue.Queue()
        for _ in range(n_chunks):
            self._free.put(np.zeros((chunk_rows, self.ncol)))
        self._full: queue.Queue = queue.Queue()
        self.chunk = self._free.get()
        self._chunk_rows = chunk_rows
        self.n = 0
        self.rows = 0
        self.dropped = 0           # rows not logged: no free buffer (the writer is behind)
        self.lost_rows = 0         # rows not written: the disk refused them
        self._thread = threading.Thread(target=self._writer, name="internals-log", daemon=True)
        self._thread.start()
        self.closed = False

    def row(self) -> np.ndarray | None:
        """The next row (zeroed is not guaranteed: fill every column). None if no buffer free.
        A full chunk goes to the writer on the next call (or ``flush``), after the caller has
        filled its last row."""
        if self.n == self._chunk_rows or self.chunk is None:
            if self.chunk is not None:
                self._full.put((self.chunk, self.n))
                self.chunk = None
            try:
                self.chunk = self._free.get_nowait()
            except queue.Empty:
                self.dropped += 1
                return None
            self.n = 0
        r = self.chunk[self.n]
        self.n += 1
        self.rows += 1
        return r

    def _writer(self) -> None:
        while True:
            item = self._full.get()
            if item is None:
                self._full.task_done()
                break
            chunk, n = item
            if not self._raw.append(chunk[:n].data):   # no copy: the rows are contiguous
                self.lost_rows += n
            self._free.put(chunk)
            self._full.task_done()

    def flush(self) -> None:
        """Hand the partial chunk to the writer (e.g. at shutdown)."""
        if self.chunk is not None and self.n:
            self._full.put((self.chunk, self.n))
            self.chunk = None

    def sync(self) -> None:
        """Hand over the partial chunk and wait until the writer has put everything on disk."""
        self.flush()
        self._full.join()

    def close(self) -> str:
        """Flush, stop the writer, write ``fc_internals.npz``; returns its path."""
        if self.closed:
            return self.npz_path
        self.closed = True
        self.flush()
        self._full.put(None)
        self._thread.join(timeout=10.0)
        self._raw.close()
        # from a read-only map of the raw file, one column at a time (np.savez streams each
        # into the archive): bounded memory however long the fc has run
        tmp = self.npz_path + ".tmp"
        try:
            data = _read_raw(self.raw_path, self.columns, mapped=True)
            with open_for_write(tmp) as f:
                np.savez(f, **data)
            del data
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


def _read_raw(raw_path: str, columns: list[str], mapped: bool = False) -> dict[str, np.ndarray]:
    """One array per column; ``mapped``: views of a read-only map of the file (no copy)."""
    ncol = len(columns)
    n = os.path.getsize(raw_path) // (8 * ncol)
    if mapped and n:
        table = np.memmap(raw_path, dtype=np.float64, mode="r", shape=(n, ncol))
        return {c: table[:, i] for i, c in enumerate(columns)}
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
