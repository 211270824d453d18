"""Truth log: crash-safe raw blocks while running, truth.npz at the end, load() of either."""
import numpy as np
import pytest

from plant_sim.truthlog import TruthWriter, load


def test_rows_survive_a_crash_block_by_block_and_close_writes_npz(tmp_path):
    names = ("t_s", "alpha_rad", "meas_q_rad_s")
    w = TruthWriter(tmp_path, names, block_rows=4)
    for k in range(10):
        w.row()[:] = (k * 0.002, 0.01 * k, -k)
    # GIVEN the process dies now (no close): the two full blocks are on disk, read via the raw pair
    crashed = load(tmp_path)
    assert list(crashed) == list(names)
    np.testing.assert_array_equal(crashed["alpha_rad"], 0.01 * np.arange(8))
    # WHEN it closes normally: every row in truth.npz, raw pair removed
    path = w.close()
    assert path.name == "truth.npz" and not (tmp_path / "truth.raw").exists()
    assert not (tmp_path / "truth.raw.json").exists()
    done = load(path)
    assert list(done) == list(names)
    np.testing.assert_array_equal(done["meas_q_rad_s"], -np.arange(10.0))
    assert load(tmp_path)["t_s"][-1] == pytest.approx(0.018)


def test_partial_trailing_row_is_dropped_and_bad_paths_fail(tmp_path):
    names = ("a", "b", "c")
    w = TruthWriter(tmp_path, names, block_rows=2)
    for k in range(2):
        w.row()[:] = (k, k, k)
    w.flush()
    with open(tmp_path / "truth.raw", "ab") as f:   # a torn write: one and a half values
        f.write(np.float64(7.0).tobytes() + b"\x00\x01\x02")
    got = load(tmp_path / "truth.raw")
    assert len(got["a"]) == 2
    with pytest.raises(FileNotFoundError):
        load(tmp_path / "empty_dir_that_is_missing")
    (tmp_path / "x").mkdir()
    with pytest.raises(FileNotFoundError):
        load(tmp_path / "x")
    with pytest.raises(ValueError):
        load(tmp_path / "truth.raw.json")


def test_decimated_log_keeps_the_full_rate_rows_bit_for_bit(tmp_path):
    # GIVEN the same rows written at full rate and decimated (5 full rows, then 1 in 3)
    rng = np.random.default_rng(2)
    names = ("t_s", "x", "y")
    rows = [(k * 1e-3, *rng.normal(size=2)) for k in range(40)]
    (tmp_path / "full").mkdir()
    (tmp_path / "dec").mkdir()
    full = TruthWriter(tmp_path / "full", names, block_rows=4)
    dec = TruthWriter(tmp_path / "dec", names, block_rows=4, full_rows=5, every=3)
    for k, r in enumerate(rows):
        keep = k == len(rows) - 1          # the final state: kept whatever the decimation
        full.row(keep=keep)[:] = r
        dec.row(keep=keep)[:] = r
    a, b = load(full.close()), load(dec.close())
    # THEN the decimated log holds rows 0..4, then 5, 8, 11, ..., and the last, each exactly the
    # full-rate row at that index
    kept = list(range(5)) + list(range(5, 39, 3)) + [39]
    assert dec.rows == len(kept) and dec.decimated == 40 - len(kept) and full.decimated == 0
    for n in names:
        assert a[n][kept].tobytes() == b[n].tobytes()
    with pytest.raises(ValueError):
        TruthWriter(tmp_path, names, full_rows=0, every=0)
