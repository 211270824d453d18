"""Smoke test of the benchmark command: it runs and reports every figure as a finite number.

Timing is never asserted here (docs/performance.md): only that ``python -m tools.bench
--quick --json FILE`` exits 0 and writes one finite number for each figure of issue 7.
"""
from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

pytestmark = pytest.mark.hil     # the benchmark starts the fc and plant processes over UDP

#: One or more figures per point of the benchmark (law, plant, floor, lockstep, real time,
#: start-up, memory, in-process closed loop).
EXPECTED = (
    "law_cycle_fc_median_us", "law_cycle_fc_p99_us", "law_cycle_kernels_median_us",
    "law_estimator_median_us", "law_slow_step_p99_us", "law_fast_step_median_us",
    "law_allocate_median_us",
    "plant_rk4_step_median_us", "plant_rk4_step_in_loop_us",
    "pingpong_mavlink_median_us", "pingpong_mavlink_p99_us", "pingpong_raw_median_us",
    "pingpong_links_median_us",
    "lockstep_500_rtf", "lockstep_1000_rtf", "lockstep_500_exchange_median_us",
    "rt_1000_lateness_median_us", "rt_1000_lateness_p99_us", "rt_1000_lateness_max_us",
    "rt_1000_late_20pct_pct", "rt_1000_latency_median_us", "rt_1000_latency_p99_us",
    "rt_500_lateness_p99_us", "rt_500_latency_p99_us", "rt_1000_clock_lateness_p99_us",
    "startup_warm_first_servo_s",
    "fc_peak_rss_mb", "standin_peak_rss_mb", "fc_rss_growth_mb_per_min",
    "closed_loop_sim_s_per_wall_s",
    "fc_py_allocs_per_frame", "fc_nrt_allocs_per_frame",
)


@pytest.mark.timeout(400)
def test_quick_bench_writes_every_figure_as_a_finite_number(tmp_path):
    out = tmp_path / "bench.json"
    proc = subprocess.run([sys.executable, "-m", "tools.bench", "--quick", "--json", str(out),
                           "--keep", str(tmp_path / "runs")],
                          cwd=ROOT, capture_output=True, text=True, timeout=380)
    assert proc.returncode == 0, proc.stderr[-3000:]
    data = json.loads(out.read_text())
    figs = data["figures"]
    missing = [k for k in EXPECTED if k not in figs]
    assert not missing, f"figures missing: {missing}; skipped: {data['skipped']}"
    bad = {k: v for k, v in figs.items() if not (isinstance(v, (int, float)) and math.isfinite(v))}
    assert not bad, f"non-finite figures: {bad}"
    # JSBSim is in the optional bench extra: either measured or skipped with the reason
    assert "jsbsim_x15_step_us" in figs or "jsbsim_x15_step_us" in data["skipped"]
    # the printed table carries the same rows as the JSON
    assert len(data["rows"]) >= 10
    for row in data["rows"]:
        assert row["figure"] in proc.stdout
