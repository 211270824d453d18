"""fc/internals_log.py: rows round-trip, the raw companion is readable after a crash."""
from __future__ import annotations

import numpy as np

from fc.internals_log import InternalsLog, load


def test_rows_round_trip_through_npz(tmp_path):
    log = InternalsLog(str(tmp_path), ["t_s", "x_rad", "y_m"], chunk_rows=16, n_chunks=4)
    for i in range(100):
        row = log.row()
        if row is None:          # writer behind: wait for it, as the loop never does
            log.sync()
            row = log.row()
        row[:] = (i * 0.002, 2.0 * i, -i)
    path = log.close()
    data = load(path)
    assert set(data) == {"t_s", "x_rad", "y_m"}
    assert np.array_equal(data["x_rad"], 2.0 * np.arange(100))
    assert np.array_equal(load(str(tmp_path))["y_m"], -np.arange(100.0))   # by directory


def test_raw_companion_is_readable_without_close(tmp_path):
    log = InternalsLog(str(tmp_path), ["a", "b"], chunk_rows=8, n_chunks=4)
    for i in range(20):
        log.row()[:] = (i, i * i)
    log.sync()                   # as if the process died now: no npz yet
    data = load(str(tmp_path))
    assert np.array_equal(data["b"], np.arange(20.0) ** 2)
    log.close()


def test_full_buffers_drop_rows_and_count_them(tmp_path):
    import threading
    log = InternalsLog(str(tmp_path), ["a"], chunk_rows=4, n_chunks=1)
    disk_free = threading.Event()
    real_write = log._raw.write

    def slow_disk(buf):          # GIVEN a disk that blocks the writer thread
        disk_free.wait(10)
        return real_write(buf)

    log._raw.write = slow_disk
    for _ in range(4):           # WHEN the only chunk fills and goes to the writer
        log.row()[:] = 1.0
    results = [log.row() for _ in range(3)]
    # THEN rows are dropped and counted, the caller never blocks
    assert results == [None, None, None] and log.dropped == 3
    disk_free.set()
    log.sync()
    assert log.row() is not None        # the chunk came back
    log.close()
    assert len(load(str(tmp_path))["a"]) == 5
