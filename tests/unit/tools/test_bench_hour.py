"""``python -m tools.bench hour`` (issue 24): the 1-hour cruise's wall time, logs and memory,
measured on a run of a few simulated seconds (the same command, shortened)."""
from __future__ import annotations

import json

import pytest

from tools.bench import hour


def test_dir_sizes_are_every_file_under_the_run(tmp_path):
    (tmp_path / "a").mkdir()
    (tmp_path / "a" / "x.bin").write_bytes(b"\0" * (1 << 20))
    (tmp_path / "y.txt").write_bytes(b"\0" * (1 << 19))
    assert hour.dir_sizes_mb(tmp_path) == {"a/x.bin": 1.0, "y.txt": 0.5}


def test_a_short_cruise_is_measured(tmp_path):
    out = tmp_path / "run"
    js = tmp_path / "h.json"
    assert hour.main(["--duration", "2", "--out", str(out), "--json", str(js)]) == 0
    d = json.loads(js.read_text())
    f = d["figures"]
    assert d["meta"]["command"].startswith("python -m tools.bench hour --duration 2")
    assert f["hour_exchanges"] == 1000                     # 2 s at the cruise's 500 Hz frames
    files = f["hour_log_files_mb"]
    assert {"coordinated/truth.npz", "coordinated/fc_internals.npz", "coordinated/fc.tlog"} <= set(files)
    assert f["hour_logs_mb"] == pytest.approx(sum(files.values()))
    assert f["hour_logs_mb"] > files["coordinated/truth.npz"] > 0.0
    # the sampler saw the fc and the plant beside the runner, at once
    procs = " ".join(f["hour_peak_rss_processes_mb"])
    assert "fc" in procs and "plant_sim" in procs and "tools.hil" in procs
    assert f["hour_peak_rss_mb"] == pytest.approx(sum(f["hour_peak_rss_processes_mb"].values()))
    assert f["hour_wall_s"] > 0.0


def test_a_run_directory_in_use_is_refused(tmp_path, capsys):
    (tmp_path / "old.npz").write_bytes(b"x")
    with pytest.raises(SystemExit) as e:
        hour.main(["--duration", "2", "--out", str(tmp_path)])
    assert e.value.code == 2
    assert "not empty" in capsys.readouterr().err
