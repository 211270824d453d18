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
