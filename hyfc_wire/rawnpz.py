"""hyfc_wire/rawnpz.py - a raw row-major float64 log turned into an npz in bounded memory.

Both processes log rows to a raw file while they run (the fc's internals log, the plant's truth
log) and convert it to ``.npz`` (one ``<column>.npy`` member per column, the archive
``np.savez`` writes) when they stop. Converting by reading columns out of the raw rows touches
the whole file for every column: a map of it becomes resident (the plant's 1-hour truth log,
81 MB, was briefly resident in full at exit) and loading it costs its size again. Here the
rows go once, a block at a time, into a column-major temp file, and each column is then
copied into its member: the memory in use is one block, however long the run.
"""
from __future__ import annotations

import os
import zipfile

import numpy as np

__all__ = ["BLOCK_ROWS", "write_npz_from_raw"]

#: rows per block of the streamed conversion (x 8 bytes x columns: about 6 MB at 100 columns)
BLOCK_ROWS = 8192


def write_npz_from_raw(raw_path: str, columns: list[str], f, block_rows: int = BLOCK_ROWS,
                       open_temp=None) -> None:
    """Write the npz of a raw row-major float64 file (whole rows only) to the binary file
    ``f``: the archive ``np.savez`` writes (one uncompressed ``<column>.npy`` member each,
    the same bytes), in bounded memory. A column-major temp file beside ``raw_path`` holds
    the columns meanwhile (opened for writing by ``open_temp(path)``, default ``open(path,
    "wb")``); it is removed on return, failure included."""
    ncol = len(columns)
    n = os.path.getsize(raw_path) // (8 * ncol)
    col_path = str(raw_path) + ".columns.tmp"
    opener = open_temp or (lambda p: open(p, "wb"))
    try:
        with open(raw_path, "rb") as src, opener(col_path) as dst:
            for r0 in range(0, n, block_rows):
                m = min(block_rows, n - r0)
                block = np.fromfile(src, dtype="<f8", count=m * ncol).reshape(m, ncol)
                cols = np.ascontiguousarray(block.T)
                for i in range(ncol):
                    dst.seek((i * n + r0) * 8)
                    dst.write(cols[i].data)
        header = {"descr": np.lib.format.dtype_to_descr(np.dtype("<f8")),
                  "fortran_order": False, "shape": (n,)}
        with open(col_path, "rb") as src, \
                zipfile.ZipFile(f, mode="w", compression=zipfile.ZIP_STORED, allowZip64=True) as zf:
            for i, name in enumerate(columns):
                with zf.open(name + ".npy", "w", force_zip64=True) as member:
                    np.lib.format.write_array_header_1_0(member, header)
                    src.seek(i * n * 8)
                    left = n * 8
                    while left:
                        buf = src.read(min(left, 1 << 20))
                        if not buf:
                            raise OSError(f"{col_path}: short read")
                        member.write(buf)
                        left -= len(buf)
    finally:
        try:
            os.unlink(col_path)
        except OSError:
            pass
