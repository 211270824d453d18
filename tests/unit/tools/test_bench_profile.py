"""``python -m tools.bench profile`` (issue 16): the per-part report of the fc's frame path.

A smoke test of the tool, not of any time: a short replay must produce a table whose parts
are the controller's own calls (so a renamed method shows up here, not as a silent zero) and
a cProfile listing of the controller's functions.
"""
from __future__ import annotations

import json

from tools.bench import profile


def test_profile_reports_every_frame_part(tmp_path, capsys):
    out = tmp_path / "p.json"
    assert profile.main(["--frames", "300", "--top", "500", "--chore-every", "100",
                         "--json", str(out)]) == 0
    d = json.loads(out.read_text())
    rows = {r["part"]: r for r in d["parts"]}
    # the per-frame parts were wrapped and called once per frame: in COORDINATED the frame is
    # one compiled call (fc/fused.py), the unfused parts are not called
    for part in ("read_frame", "recv", "fused_ready", "fused", "fused_kernel", "gcs_service",
                 "tlog_streams"):
        assert rows[part]["calls_per_frame"] == 1.0, part
        assert rows[part]["mean_us_per_frame"] > 0.0, part
    for part in ("estimator", "fast_step", "pwm", "send_servo", "framing", "log_row"):
        assert rows[part]["calls_per_frame"] == 0.0, part
    # no ground-station traffic in the replay: its socket is not read (the lockstep loop reads
    # it only when its select says so)
    assert rows["gcs_poll"]["calls_per_frame"] == 0.0
    # the 1 Hz chores were made due (every 100 frames: each chore once per round of 4)
    for part in ("stats_roll", "gc_due", "telemetry", "gcs_flush"):
        assert rows[part]["calls_per_frame"] > 0.0, part
    # and no collection ran: the replay's steady state leaves nothing to collect
    # (fc/scheduler.py ``garbage_due``)
    assert rows["gc"]["calls_per_frame"] == 0.0
    assert rows["total"]["mean_us_per_frame"] > 0.0
    assert d["plain"]["frames"] == 300 and d["plain"]["wall_median_us"] > 0.0
    # every function is listed (--top above the count), so the frame entry is there whatever the load
    assert "lockstep_frame" in d["cprofile"]
    assert "| total |" in capsys.readouterr().out


def test_guidance_part_runs_in_cruise(tmp_path):
    out = tmp_path / "p.json"
    assert profile.main(["--frames", "50", "--no-cprofile", "--flight-mode", "CRUISE",
                         "--json", str(out)]) == 0
    rows = {r["part"]: r for r in json.loads(out.read_text())["parts"]}
    # a guidance mode takes the fused frame but on the frames with a guidance step due (one
    # in ten at 500 Hz: the guidance at 50 Hz), whose ticks, answer and row are the unfused
    # parts (the estimator ran in the compiled step on every frame)
    assert rows["fused_ready"]["calls_per_frame"] == 1.0
    assert rows["fused_kernel"]["calls_per_frame"] == 1.0
    assert rows["guidance"]["calls_per_frame"] == 0.1
    for part in ("fast_step", "send_servo", "framing", "log_row"):
        assert rows[part]["calls_per_frame"] == 0.1, part
    assert rows["estimator"]["calls_per_frame"] == 0.0
