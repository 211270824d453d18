"""Plant truth log: rows of PlantSim.TRUTH_NAMES, one per frame (full rate) or decimated.

Sized for long runs (issue 24): a row is about 390 bytes, so every frame of an hour at 500 Hz
is 0.7 GB. With ``full_rows`` set (``python -m plant_sim run``: the first ``--truth-full-s``
seconds of frames, default 60 s) the first ``full_rows`` rows are kept, then one row in
``every`` (``--truth-tail-hz``, default 50 Hz); ``--truth-full-rate`` keeps every row. The
rows kept are the rows a full-rate log holds at the same frames, bit for bit (``t_s`` says when
each was taken); a row the caller marks ``keep`` (the final state) is always kept.

While running, rows go to ``truth.raw`` (little-endian float64, row-major, no header) in
blocks of ``block_rows`` rows, flushed to the OS after each block, with the column names in
``truth.raw.json`` written first: a crash loses at most one block. ``close()`` converts the raw
file to ``truth.npz`` (one float64 array per column, keyed by column name) and removes the raw
pair. ``load(path)`` reads a run directory, a ``truth.npz`` or a left-over ``truth.raw``.
"""
from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from hyfc_wire.rawnpz import write_npz_from_raw


#: rows per block of the exit-time conversion to truth.npz (x 8 bytes x columns, twice: the
#: block and its transpose; about 2 MB)
TRUTH_NPZ_BLOCK_ROWS = 2048


class TruthWriter:
    """Block-buffered, crash-safe writer. ``row()`` returns the next row buffer to fill."""

    def __init__(self, out_dir: str | os.PathLike, names, block_rows: int = 500,
                 full_rows: int | None = None, every: int = 1):
        """``full_rows``: keep every row of the first ``full_rows`` frames, then one in
        ``every`` (counted from the first tail frame); None: every row."""
        if full_rows is not None and (full_rows < 0 or every < 1):
            raise ValueError(f"truth log: {full_rows} full-rate rows then 1 in {every}: "
                             "need >= 0 rows and every >= 1")
        self.dir = Path(out_dir)
        self.names = tuple(names)
        self.n = len(self.names)
        self.raw_path = self.dir / "truth.raw"
        self.meta_path = self.dir / "truth.raw.json"
        self.npz_path = self.dir / "truth.npz"
        self.meta_path.write_text(json.dumps({"columns": list(self.names), "dtype": "<f8"}))
        self._f = open(self.raw_path, "wb")
        self.block = np.zeros((block_rows, self.n))
        self.block_rows = block_rows
        self.fill = 0
        self.rows = 0
        self.full_rows = full_rows
        self.every = int(every)
        self.offered = 0            # rows asked for (frames), kept or not
        self.decimated = 0          # rows not kept by choice (past full_rows, between tail rows)
        self._discard = np.zeros(self.n)

    def row(self, keep: bool = False) -> np.ndarray:
        """The buffer for the next row (fill it completely); flushes full blocks. A row that
        the decimation does not keep gets a scratch buffer (filled and dropped); ``keep``:
        kept whatever the decimation says (the run's final state)."""
        k = self.offered
        self.offered = k + 1
        if (not keep and self.full_rows is not None and k >= self.full_rows
                and (k - self.full_rows) % self.every):
            self.decimated += 1
            return self._discard
        if self.fill == self.block_rows:
            self.flush()
        r = self.block[self.fill]
        self.fill += 1
        self.rows += 1
        return r

    def flush(self) -> None:
        if self.fill:
            self._f.write(self.block[:self.fill].astype("<f8", copy=False).tobytes())
            self._f.flush()
            self.fill = 0

    def close(self) -> Path:
        """Flush, write truth.npz, remove the raw pair; returns the npz path."""
        self.flush()
        self._f.close()
        # streamed through a column-major temp file (hyfc_wire/rawnpz.py): np.savez's archive
        # in bounded memory. (Columns read out of a map of the raw rows made the whole file
        # resident at exit: +78 MB of the plant's RSS after a 1-hour run.) Blocks of
        # TRUTH_NPZ_BLOCK_ROWS: the fc is still running while the plant converts, and the
        # processes' summed RSS peaks here
        tmp = self.dir / "truth.tmp.npz"
        with open(tmp, "wb") as f:
            write_npz_from_raw(str(self.raw_path), list(self.names), f, TRUTH_NPZ_BLOCK_ROWS)
        os.replace(tmp, self.npz_path)
        self.raw_path.unlink(missing_ok=True)
        self.meta_path.unlink(missing_ok=True)
        return self.npz_path


def _read_raw(raw: Path, names) -> dict[str, np.ndarray]:
    """Columns of a raw file."""
    n = len(names)
    rows = os.path.getsize(raw) // (8 * n)
    flat = np.fromfile(raw, dtype="<f8", count=rows * n)
    arr = flat.reshape(rows, n)
    return {name: np.ascontiguousarray(arr[:, i]) for i, name in enumerate(names)}


def load(path: str | os.PathLike) -> dict[str, np.ndarray]:
    """Truth log as {column name: float64 array}; ``path``: run dir, truth.npz or truth.raw."""
    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(f"no such truth log or run directory: {p}")
    if p.is_dir():
        if (p / "truth.npz").is_file():
            p = p / "truth.npz"
        elif (p / "truth.raw").is_file():
            p = p / "truth.raw"
        else:
            raise FileNotFoundError(f"no truth.npz or truth.raw in {p}")
    if p.suffix == ".npz":
        with np.load(p) as z:
            return {k: z[k] for k in z.files}
    if p.suffix == ".raw":
        meta = json.loads((p.parent / (p.name + ".json")).read_text())
        return _read_raw(p, meta["columns"])
    raise ValueError(f"not a truth log: {p}")
