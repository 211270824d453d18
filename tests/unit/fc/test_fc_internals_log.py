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
    real_append = log._raw.append

    def slow_disk(buf):          # GIVEN a disk that blocks the writer thread
        disk_free.wait(10)
        return real_append(buf)

    log._raw.append = slow_disk
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


def test_row_kernel_puts_each_value_in_its_named_column():
    # GIVEN the telemetry's column names for a law with three status values
    from types import SimpleNamespace

    from fc.estimator import EM_EST, EM_MASKS, EM_N
    from fc.telemetry import Telemetry, fill_row
    cols = Telemetry.columns(SimpleNamespace(status_names=["s0", "s1", "s2"]))
    emem = np.zeros(EM_N)
    emem[EM_EST:EM_EST + 9] = np.arange(9.0) + 0.5
    emem.view(np.int64)[EM_MASKS:EM_MASKS + 2] = (5, 6)
    status = np.array([7.0, 8.0, 9.0, 99.0])       # longer than the names: only 3 logged
    row = np.full(len(cols), np.nan)
    # WHEN the compiled kernel fills a row
    fill_row(row, np.array([1.25]), 123.5, 2_000_001, 2, True, False, emem,
             np.array([0.1, 0.2, 0.3]), np.array([-0.1, -0.2, -0.3]), 1500, 2_500_000, status,
             3, 0.75, 4, np.array([21000.0, 1.5, 2200.0, 0.9]))
    # THEN every column holds its value (the order is the columns' one)
    got = dict(zip(cols, row.tolist()))
    assert got["t_s"] == 1.25 and got["wall_s"] == 123.5 and got["stamp_us"] == 2_000_001.0
    assert (got["mode"], got["armed"], got["est_healthy"]) == (2.0, 1.0, 0.0)
    assert (got["est_invalid_mask"], got["est_stale_mask"]) == (5.0, 6.0)
    assert [got["est_" + c] for c in ("alpha_rad", "gamma_rad")] == [0.5, 8.5]
    assert (got["cmd_mu_rad"], got["delta_left_rad"]) == (0.3, -0.1)
    assert (got["lateness_us"], got["exec_us"]) == (1.5, 2500.0)
    assert [got["law_s0"], got["law_s2"]] == [7.0, 9.0]
    assert (got["guid_throttle"], got["guid_limits"]) == (0.75, 4.0)
    assert (got["guid_tgt_h_m"], got["guid_tgt_V_m_s"]) == (21000.0, 2200.0)
    assert not np.isnan(row).any()


def test_a_chunk_goes_to_the_writer_only_after_its_last_row_is_filled(tmp_path):
    # GIVEN a log whose hand-over to the writer thread is watched: what the writer gets is
    # copied at that moment (the writer may write it to disk at once)
    log = InternalsLog(str(tmp_path), ["a"], chunk_rows=4, n_chunks=4)
    handed = []
    real_put = log._full.put

    def watched_put(item):
        if item is not None:
            handed.append(item[0][:item[1]].copy())
        real_put(item)

    log._full.put = watched_put
    # WHEN ten rows are filled one after the other (two chunks fill up)
    for i in range(10):
        log.row()[:] = i + 1.0
    log.flush()
    # THEN every row the writer got was filled, the last of each chunk too
    assert [h[:, 0].tolist() for h in handed] == [[1.0, 2.0, 3.0, 4.0], [5.0, 6.0, 7.0, 8.0],
                                                  [9.0, 10.0]]
    log.close()
    assert load(str(tmp_path))["a"].tolist() == [float(i + 1) for i in range(10)]
