"""fc/internals_log.py: rows round-trip, the raw companion is readable after a crash."""
from __future__ import annotations

import numpy as np

from fc.internals_log import POOL_HDR, POOL_HEAD, InternalsLog, load


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
    real_wake = log._wake_writer

    def watched_wake():             # (called after each hand-over: the ring's newest chunk)
        slot = (int(log._pool[POOL_HEAD]) - 1) % 4
        k = int(log._pool[POOL_HDR + 4 + slot])
        n = int(log._pool[POOL_HDR + 8 + slot])
        handed.append(log._chunks[k][:n].copy())
        real_wake()

    log._wake_writer = watched_wake
    # WHEN ten rows are filled one after the other (two chunks fill up)
    for i in range(10):
        log.row()[:] = i + 1.0
    log.flush()
    # THEN every row the writer got was filled, the last of each chunk too
    assert [h[:, 0].tolist() for h in handed] == [[1.0, 2.0, 3.0, 4.0], [5.0, 6.0, 7.0, 8.0],
                                                  [9.0, 10.0]]
    log.close()
    assert load(str(tmp_path))["a"].tolist() == [float(i + 1) for i in range(10)]


def _fill_every_tick(log: InternalsLog, n: int, dt_us: int = 2000) -> np.ndarray:
    """Offer the row of every 500 Hz tick (stamps 0, 2 ms, ...); returns the stamps offered."""
    stamps = np.arange(n) * dt_us
    for s in stamps.tolist():
        r = log.row(s)
        if r is not None:
            r[:] = (s * 1e-6, s * 3.0)
    return stamps


def test_a_long_run_keeps_full_rate_first_then_one_row_per_slow_tick(tmp_path):
    # GIVEN a log kept at full rate for 1 s, then at 100 Hz, offered 3 s of 500 Hz ticks
    log = InternalsLog(str(tmp_path), ["t_s", "x"], chunk_rows=64, n_chunks=64,
                       full_rate_s=1.0, tail_hz=100.0)
    stamps = _fill_every_tick(log, 1500)
    data = load(log.close())
    # THEN every tick of the first second, then every 5th (the rows themselves unchanged)
    want = stamps[(stamps < 1_000_000) | (stamps % 10_000 == 0)]
    assert np.array_equal(data["t_s"], want * 1e-6)
    assert np.array_equal(data["x"], want * 3.0)
    assert len(want) == 500 + 200 and log.decimated == 1500 - 700 and log.dropped == 0


def test_full_rate_keeps_every_row_however_long(tmp_path):
    log = InternalsLog(str(tmp_path), ["t_s", "x"], chunk_rows=64, n_chunks=64,
                       full_rate_s=None)
    stamps = _fill_every_tick(log, 1500)
    assert np.array_equal(load(log.close())["x"], stamps * 3.0) and log.decimated == 0


def test_tail_rows_follow_the_sensor_time_not_the_row_count(tmp_path):
    # GIVEN irregular stamps past the full-rate span (realtime: repeated, skipped frames)
    log = InternalsLog(str(tmp_path), ["t_s", "x"], full_rate_s=0.0, tail_hz=100.0)
    kept = [s for s in (0, 0, 4000, 10_000, 10_000, 12_000, 31_000, 39_000, 40_000)
            if log.row(s) is not None]
    # THEN the first row at or after each 10 ms mark, each once
    assert kept == [0, 10_000, 31_000, 40_000]
    log.close()


def test_streamed_conversion_equals_numpy_savez_in_bounded_memory(tmp_path):
    import tracemalloc

    from fc.internals_log import write_npz_from_raw
    # GIVEN a raw file of 40,000 rows x 12 columns (3.8 MB)
    cols = [f"c{i}" for i in range(12)]
    table = np.random.default_rng(3).standard_normal((40_000, 12))
    raw = tmp_path / "fc_internals.raw"
    table.tofile(raw)
    with open(raw, "ab") as f:
        f.write(b"\x01" * 20)                      # a torn last row (a kill mid-write): left out
    # WHEN it is converted 1000 rows at a time
    tracemalloc.start()
    with open(tmp_path / "out.npz", "wb") as f:
        write_npz_from_raw(str(raw), cols, f, block_rows=1000)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    # THEN np.load reads each column as written, and memory stayed near two blocks (~0.2 MB)
    with np.load(tmp_path / "out.npz") as z:
        assert z.files == cols
        for i, c in enumerate(cols):
            assert np.array_equal(z[c], table[:, i])
    assert peak < 1_500_000, peak
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fc_internals.raw", "out.npz"]


def test_a_decimation_that_means_nothing_is_refused(tmp_path):
    import pytest
    for full_s, hz in ((60.0, 0.0), (60.0, -5.0), (-1.0, 100.0), (float("nan"), 100.0),
                       (60.0, float("inf"))):
        with pytest.raises(ValueError):
            InternalsLog(str(tmp_path), ["t_s"], full_rate_s=full_s, tail_hz=hz)


def test_a_chunk_is_not_refilled_before_the_writer_released_it(tmp_path):
    import threading
    # GIVEN a pool of two chunks and a writer held inside its first write
    log = InternalsLog(str(tmp_path), ["a"], chunk_rows=4, n_chunks=2)
    in_write, disk_free = threading.Event(), threading.Event()
    real_append = log._raw.append
    written = []

    def held_disk(buf):
        written.append(np.frombuffer(bytes(buf), np.float64).tolist())  # what the disk got
        in_write.set()
        assert disk_free.wait(10)
        return real_append(buf)

    log._raw.append = held_disk
    # WHEN 4 rows fill the first chunk, the writer takes it, and 4 more fill the second
    for i in range(4):
        log.row()[:] = i + 1.0
    first = log.chunk
    assert log.row() is not None        # (hands the first chunk over)
    second = log.chunk
    log.chunk[0] = 5.0
    assert in_write.wait(10)
    for i in range(5, 8):
        log.row()[:] = i + 1.0
    # THEN the next rows are dropped, not written into the chunk the writer holds
    assert [log.row() for _ in range(3)] == [None, None, None] and log.dropped == 3
    assert first[:, 0].tolist() == [1.0, 2.0, 3.0, 4.0]
    disk_free.set()
    log.sync()
    # and once the writer gave both back, the one given back last is filled again, from its
    # first row
    assert log.row() is not None and log.chunk is second and log.n == 1
    log.chunk[0] = 9.0
    log.close()
    assert written[:2] == [[1.0, 2.0, 3.0, 4.0], [5.0, 6.0, 7.0, 8.0]]
    assert load(str(tmp_path))["a"].tolist() == [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0]


def test_the_data_written_equals_the_rows_logged_with_a_slow_writer(tmp_path):
    import random
    import time
    # GIVEN small chunks and a writer that pauses at random (0-2 ms per chunk)
    rng = random.Random(4)
    log = InternalsLog(str(tmp_path), ["a", "b"], chunk_rows=8, n_chunks=3)
    real_append = log._raw.append

    def slow_disk(buf):
        time.sleep(rng.random() * 0.002)
        return real_append(buf)

    log._raw.append = slow_disk
    # WHEN 5,000 rows are offered, some of them while every chunk is with the writer
    kept = []
    for i in range(5000):
        row = log.row()
        if row is not None:
            row[:] = (i, -2.0 * i)
            kept.append(i)
        if i % 500 == 0:
            time.sleep(0.001)
    rows, dropped = log.rows, log.dropped
    log.close()
    # THEN every row logged is on disk once, in order, and every other was counted dropped
    data = load(str(tmp_path))
    assert data["a"].tolist() == [float(i) for i in kept]
    assert data["b"].tolist() == [-2.0 * i for i in kept]
    assert rows == len(kept) and dropped == 5000 - len(kept) and dropped > 0
