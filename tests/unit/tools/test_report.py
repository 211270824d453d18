"""tools.evidence.report: the README's and the docs' generated tables agree with their committed data."""
from __future__ import annotations

import json
import shutil

import pytest

from tools.evidence import report


def test_committed_tables_match_their_data():
    """Every ``<!-- report:NAME -->`` block of the documents is what its docs/data/*.json
    renders today (run ``python -m tools.evidence.report write`` after importing a new run)."""
    blocks = []
    for doc in report.DOCUMENTS:
        path = report.ROOT / doc
        if path.exists():
            blocks += [m.group("name") for m in report._BLOCK.finditer(path.read_text())]
    assert {"hil_steps", "hil_steps_paper_gains", "mc_paper", "mc_paper_gains", "mc_cruise",
            "mc_cruise_b", "mc_surfaces", "beta0_dip", "hil_prefilter",
            "eq14_mirror_claim", "hil_compare_claim", "hil_alpha_claim",
            "envelope_claim", "mc_claim", "bench", "bench_compare"} <= set(blocks), blocks
    assert report.check() == []


def test_a_table_that_disagrees_with_its_data_is_reported(tmp_path):
    """GIVEN a copy of the documents and data; WHEN one source figure changes (or a table is
    edited by hand); THEN check names that table, and write repairs it."""
    for doc in report.DOCUMENTS:
        src = report.ROOT / doc
        if src.exists():
            (tmp_path / doc).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, tmp_path / doc)
    shutil.copytree(report.ROOT / report.DATA_DIR, tmp_path / report.DATA_DIR)
    assert report.check(tmp_path) == []
    # each run's data renders its own table (the paper's fixed gains' run included)
    for name, variant, channel, metric, tables in (
            ("hil_paper", "coordinated", "alpha", "overshoot_pct",
             {"hil_steps", "hil_compare_claim", "hil_alpha_claim"}),
            ("hil_paper_gains", "uncoordinated", "mu", "settling_time_s",
             {"hil_steps_paper_gains", "hil_compare_claim"}),
            ("hil_prefilter", "coordinated", "beta", "overshoot_pct", {"hil_prefilter"}),
            ("hil_paper_gains_eq14_mirror", "coordinated", "mu", "overshoot_pct",
             {"eq14_mirror_claim"})):
        data = tmp_path / report.DATA_DIR / f"{name}.json"
        d = json.loads(data.read_text())
        d["summary"]["runs"][variant][channel][metric] += 1.0
        data.write_text(json.dumps(d))
        assert set(report.check(tmp_path)) == {f"README.md: {x}" for x in tables}
        report.write(tmp_path)
        assert report.check(tmp_path) == []
    # each campaign's data renders its own table: the default law's, the fixed gains' (and the
    # surfaces' table drawn from it) and the cruise point's two
    # (and the campaigns' claim, mc_claim, quotes the default law's three)
    for name, tables in (("mc_paper", {"mc_paper", "mc_claim"}),
                         ("mc_paper_gains", {"mc_paper_gains", "mc_surfaces"}),
                         ("mc_cruise", {"mc_cruise", "mc_claim"}),
                         ("mc_cruise_b", {"mc_cruise_b", "mc_claim"})):
        data = tmp_path / report.DATA_DIR / f"{name}.json"
        d = json.loads(data.read_text())
        d["summary"]["variants"]["uncoordinated"]["meets_spec"] += 1
        d["summary"]["variants"]["uncoordinated"]["surfaces"]["peak_rudder_deg"]["p50"] += 1.0
        data.write_text(json.dumps(d))
        assert {c.split(": ")[1] for c in report.check(tmp_path)} == tables, name
        report.write(tmp_path)
        assert report.check(tmp_path) == []
    readme = tmp_path / "README.md"
    readme.write_text(readme.read_text().replace("| diverged | 0 |", "| diverged | 1 |", 1))
    assert report.check(tmp_path) == ["README.md: mc_paper"]


def test_unknown_block_is_an_error():
    with pytest.raises(KeyError):
        report.render("<!-- report:nope -->\nx\n<!-- /report:nope -->\n")


def test_the_comparison_claim_reads_its_directions_from_the_data(tmp_path):
    """GIVEN the main job's data with coordination made worse in alpha; THEN the README's
    reading says it does not lower the overshoot, and a later settling becomes "sooner" when
    the data say so (no direction is typed by hand)."""
    shutil.copytree(report.ROOT / report.DATA_DIR, tmp_path / report.DATA_DIR)
    before = report.claim_hil_compare(tmp_path)
    assert "coordination lowers alpha and mu overshoot" in before
    data = tmp_path / report.DATA_DIR / "hil_paper_gains.json"
    d = json.loads(data.read_text())
    runs = d["summary"]["runs"]
    runs["coordinated"]["alpha"]["overshoot_pct"] = runs["uncoordinated"]["alpha"]["overshoot_pct"] + 1
    runs["coordinated"]["alpha"]["settling_time_s"] = runs["uncoordinated"]["alpha"]["settling_time_s"] - 0.5
    data.write_text(json.dumps(d))
    after = report.claim_hil_compare(tmp_path)
    assert "does not lower both of alpha and mu overshoot" in after
    assert "settles alpha 0.50 s sooner" in after


def test_an_envelope_map_is_imported_and_its_claim_follows_it(tmp_path):
    """import-env copies a map's summary.json (tools.evidence.envelope.counts); the README's
    envelope claim changes with it."""
    shutil.copytree(report.ROOT / report.DATA_DIR, tmp_path / report.DATA_DIR)
    summary = tmp_path / "summary.json"
    d = json.loads((tmp_path / report.DATA_DIR / "env_b.json").read_text())["summary"]
    d["variants"]["co_eq19"]["corridor_meets_spec"] = 270
    d["variants"]["co_eq19"]["diverged"] = 2
    summary.write_text(json.dumps(d))
    report.import_summary(summary, "env_b", "python -m tools.evidence.envelope X", "env",
                          root=tmp_path, commit_override="abc1234")
    text = report.claim_envelope(tmp_path)
    assert "270 of 295 coordinated (92 %)" in text and "Diverged: 0 / 2 points" in text
    assert "`python -m tools.evidence.envelope X`" in text and "abc1234" in text


def test_a_bench_run_is_imported_and_its_verdicts_follow_its_figures(tmp_path):
    """import-bench copies ``python -m tools.bench --json FILE``'s figures (not its details);
    the issue-24 table says met or missed from them, with the floors of the same run."""
    fig = {"fc_frame_cpu_median_us": 6.5, "fc_frame_read_median_us": 2.0,
           "fc_frame_work_median_us": 4.0, "fc_frame_housekeeping_median_us": 0.5,
           "law_cycle_fc_median_us": 1.4, "plant_frame_path_us": 9.0,
           "fc_frame_link_floor_median_us": 5.5,
           "plant_rk4_step_in_loop_us": 2.5, "lockstep_500_rtf": 20.0,
           "lockstep_500_floor_rtf": 25.0, "pingpong_links_median_us": 78.0,
           "pingpong_raw_median_us": 31.0, "fc_py_allocs_per_frame_coordinated": 0.0,
           "fc_nrt_allocs_per_frame_coordinated": 0.0, "fc_py_allocs_per_frame_cruise": 0.01,
           "fc_nrt_allocs_per_frame_cruise": 0.0, "rt_1000_lateness_p99_us": 60.0,
           "rt_1000_late_20pct_pct": 0.05, "rt_1000_floor_lateness_p99_us": 55.0,
           "rt_1000_floor_late_20pct_pct": 0.04, "fc_peak_rss_mb": 185.0,
           "plant_peak_rss_mb": 171.0}
    src = tmp_path / "bench.json"
    src.write_text(json.dumps({"meta": {"utc": "2026-11-26T13:00:00Z",
                                        "load_avg_1min_at_part_start": {"law": 0.1, "x": 0.9}},
                               "figures": fig, "rows": [["x"]], "details": {"big": [1] * 100}}))
    report.import_summary(src, "bench", "python -m tools.bench --json F", "bench",
                          root=tmp_path, commit_override="abc1234")
    d = report.load_data("bench", tmp_path)
    assert set(d["summary"]) == {"meta", "figures"} and d["created_utc"].startswith("2026-11-26T13:00")
    rows = {r.split(" | ")[0].lstrip("| "): r for r in report.table_bench(tmp_path).splitlines()
            if r.startswith("| ")}
    assert "6.5 us = 2.0 + 4.0 + 0.5 | <= 7 us | met | the fc's link alone (receive + decode, framing + send) 5.5 us; the law alone (from Python) 1.40 us |" in rows["fc CPU per plant frame, in process (receive / frame / housekeeping)"]
    assert "9.0 us | <= 5 us | **missed** | two RK4 steps 5.0 us" in rows["plant per-frame path, no network"]
    assert "20.0x = 80 % of the links' limit | >= 75 % | met" in rows["lockstep at 500 Hz, plant process"]
    alloc = [r for k, r in rows.items() if k.startswith("fc allocations")]
    assert "0.000 / 0.000 | 0 / 0 | met" in alloc[0] and "**missed**" in alloc[1]
    assert "p99 60 us, 0.05 % late | p99 <= 50 us, < 0.1 % late | **missed** | a bare receiver: p99 55 us" in rows["real time 1 kHz, wake-up lateness"]
    assert "`python -m tools.bench --json F`, commit abc1234, 2026-11-26 13:00" in report.table_bench(tmp_path)


def test_the_hour_rows_follow_the_hour_run(tmp_path):
    """With docs/data/hour.json (``python -m tools.bench hour --json F``) the table gains the
    1-hour cruise's rows: wall time against the exchanges x the bench's ping-pong, logs, RSS."""
    (tmp_path / report.DATA_DIR).mkdir(parents=True)
    fig = {"pingpong_links_median_us": 78.0, "fc_py_allocs_per_frame_coordinated": 0.0}
    (tmp_path / "b.json").write_text(json.dumps({"meta": {"utc": "2026-11-26T13:00:00Z"},
                                                 "figures": fig}))
    report.import_summary(tmp_path / "b.json", "bench", "B", "bench", root=tmp_path)
    assert "cruise" not in report.table_bench(tmp_path)
    hf = {"hour_wall_s": 150.0, "hour_logs_mb": 263.0, "hour_peak_rss_mb": 401.0,
          "hour_exchanges": 1800000, "hour_duration_s": 3600.0, "hour_peak_rss_at_s": 232.0,
          "hour_log_files_mb": {"c/truth.npz": 81.0, "c/fc_internals.npz": 170.0, "c/x": 0.1},
          "hour_peak_rss_processes_mb": {"fc (12)": 185.0, "plant_sim (13)": 171.0,
                                         "tools.hil (11)": 45.0}}
    (tmp_path / "h.json").write_text(json.dumps({"meta": {"utc": "2026-11-26T14:00:00Z"},
                                                 "figures": hf}))
    report.import_summary(tmp_path / "h.json", "hour", "python -m tools.bench hour", "bench",
                          root=tmp_path)
    t = report.table_bench(tmp_path)
    assert "| the 1-hour lockstep cruise: wall time | 150 s | <= 80 s | **missed** | 1,800,000 exchanges x the links' ping-pong 78 us = 140 s |" in t
    assert "| 263 MB | <= 300 MB | met | fc_internals.npz 170, truth.npz 81, x 0 MB |" in t
    assert "| 401 MB | <= 400 MB | **missed** | at 232 s: fc 185, plant_sim 171, tools.hil 45 MB |" in t
    assert "`python -m tools.bench hour`" in t


def test_the_before_after_table_shows_both_runs_and_what_one_did_not_measure(tmp_path):
    (tmp_path / report.DATA_DIR).mkdir(parents=True)
    for name, commit, fig in (("bench_before", "aaa1111", {"fc_frame_cpu_median_us": 34.876}),
                              ("bench", "bbb2222", {"fc_frame_cpu_median_us": 25.168,
                                                    "fc_frame_link_floor_median_us": 12.0})):
        (tmp_path / f"{name}.json").write_text(json.dumps(
            {"meta": {"utc": "2026-11-26T12:24:00Z"}, "figures": fig}))
        report.import_summary(tmp_path / f"{name}.json", name, f"cmd {name}", "bench",
                              root=tmp_path, commit_override=commit)
    t = report.table_bench_compare(tmp_path)
    assert "| fc CPU per plant frame, in process (us) | 34.9 | 25.2 |" in t
    assert "| floor: the fc's link alone (us) | - | 12.0 |" in t
    assert "before (aaa1111, 12:24 UTC)" in t and "`cmd bench_before`" in t
    assert "RSS" not in t.split("Before:")[0]            # measured by neither run: no row
