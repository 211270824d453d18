"""A 20-case campaign on a 2-worker LocalCluster (tools.evidence.montecarlo): complete results, a summary
consistent with the rows, a re-run of one case identical to its row, and an interrupted campaign
that resumes without repeating finished cases.

The cases fly the real in-process closed loop (``tools.sitl.closed_loop``: the product's control law
and plant) on the full 20 s paper scenario with the shipped ``paper`` dispersions; a case takes
about 40 ms per variant once compiled, so the file needs no shortened cases (about 10 s warm;
the first run on a fresh checkout also compiles the numba kernels on each worker).
"""
import logging

import numpy as np
import pyarrow.parquet as pq
import pytest

from tools.sitl import metrics as mt
from tools.evidence.montecarlo import dispersions as dsp
from tools.evidence.montecarlo import results, summary
from tools.evidence.montecarlo.campaign import CampaignError, run_campaign
from tools.evidence.montecarlo.case import CHANNELS, CampaignConfig, run_case
from tools.evidence.montecarlo.rerun import rerun

distributed = pytest.importorskip("distributed")

RUNS = 20
DURATION_S = 20.0
BACKEND = "closed_loop"


@pytest.fixture(scope="module")
def client():
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                       host="127.0.0.1", dashboard_address=":0",
                                       silence_logs=logging.ERROR)
    cl = distributed.Client(cluster)
    try:
        yield cl
    finally:
        cl.close()
        cluster.close()


def _cfg(seed=11):
    d = dsp.load("paper")
    return CampaignConfig(scenario="paper", dispersions_text=d.source_text,
                          dispersions_name=d.name, seed=seed, duration_s=DURATION_S,
                          trace_dt_s=0.1, backend=BACKEND)


@pytest.fixture(scope="module")
def campaign(client, tmp_path_factory):
    out = tmp_path_factory.mktemp("mc20")
    cfg = _cfg()
    res = run_campaign(cfg, RUNS, out, client=client, progress_stream=_Null())
    return cfg, out, res


class _Null:
    def write(self, s):
        return len(s)

    def flush(self):
        pass


def _raw_keys(out):
    """(case, variant) of every row in every part file, duplicates kept."""
    keys = []
    for f in results.part_files(out):
        t = pq.read_table(f, columns=["case", "variant"])
        keys += list(zip(t.column("case").to_pylist(), t.column("variant").to_pylist()))
    return keys


def test_results_complete(campaign):
    cfg, out, res = campaign
    assert (res.ran, res.skipped, res.lost, res.interrupted) == (RUNS, 0, [], False)
    keys = _raw_keys(out)
    # one row per case and variant, no duplicates, nothing missing
    assert sorted(keys) == sorted((i, v) for i in range(RUNS) for v in cfg.variants)
    t = results.read_rows(out, traces=True)
    assert set(results.METRIC_COLUMNS) <= set(t.column_names)
    # the surface figures (docs/metrics.md "Surfaces") of every row, from the closed loop
    assert set(results.SURFACE_COLUMNS) <= set(t.column_names)
    for c in results.SURFACE_COLUMNS:
        assert np.all(np.isfinite(np.asarray(t.column(c).to_pylist(), float))), c
    assert min(t.column("surf.rate_cmd_limited_s").to_pylist()) > 0.0
    assert set(dsp.load("paper").dists) <= set(t.column_names)
    errors = [e for e in t.column("error").to_pylist() if e]
    assert errors == []
    for c in results.TRACE_COLUMNS:
        lens = {len(x) for x in t.column(c).to_pylist()}
        assert lens == {int(round(DURATION_S / cfg.trace_dt_s)) + 1}
    # every case drew its own dispersions
    assert len(set(t.column("aero.Cm").to_pylist())) == RUNS


def test_summary_consistent_with_rows(campaign):
    cfg, out, _ = campaign
    d = dsp.load("paper")
    s = summary.summarise(out, d.spec, list(d.dists), cfg.variants)
    rows = results.read_rows(out).to_pylist()
    assert s["rows"] == len(rows) == 2 * RUNS and s["cases"] == RUNS
    for v in cfg.variants:
        mine = [r for r in rows if r["variant"] == v]
        vs = s["variants"][v]
        assert vs["rows"] == len(mine)
        assert vs["diverged"] == sum(r["diverged"] for r in mine)
        # share meeting the spec, recomputed row by row from the definition
        ok = 0
        for r in mine:
            good = not r["diverged"] and not r["error"]
            for ch in CHANNELS:
                os_ = r[f"{ch}.overshoot_pct"]
                st = r[f"{ch}.settling_time_s"]
                fe = r[f"{ch}.final_error_deg"]
                good &= (np.isnan(os_) or os_ <= d.spec["overshoot_max_pct"][ch])
                good &= (not np.isnan(st)) and st <= d.spec["settling_max_s"][ch]
                good &= fe <= d.spec["final_error_max_deg"][ch]
            ok += bool(good)
        assert vs["meets_spec"] == ok
        for ch in CHANNELS:
            for m in summary.SUMMARY_METRICS:
                x = np.array([r[f"{ch}.{m}"] for r in mine], dtype=float)
                x = x[np.isfinite(x)]
                st = vs["metrics"][ch][m]
                assert st["n"] == x.size
                if x.size:
                    assert st["p50"] == pytest.approx(np.median(x))
                    assert st["max"] == pytest.approx(x.max())
    fails = {(f["case"], f["variant"]) for f in s["failures"]}
    assert fails == {(r["case"], r["variant"]) for r in rows if r["diverged"] or r["error"]}
    # surfaces: per-variant stats and the case-by-case shares, recomputed from the rows
    co = {r["case"]: r for r in rows if r["variant"] == "coordinated"}
    un = {r["case"]: r for r in rows if r["variant"] == "uncoordinated"}
    for k in summary.SURFACE_SUMMARY:
        col = f"surf.{k}"
        x = np.array([r[col] for r in co.values()], float)
        assert s["variants"]["coordinated"]["surfaces"][k]["max"] == pytest.approx(x.max())
        a = np.array([co[c][col] for c in sorted(co)])
        b = np.array([un[c][col] for c in sorted(co)])
        e = s["paired"][col]
        assert e["coordinated_smaller_share"] == pytest.approx(np.mean(a < b))
        assert e["equal_share"] + e["coordinated_smaller_share"] + \
            e["coordinated_larger_share"] == pytest.approx(1.0)


def test_rerun_of_one_case_gives_identical_metrics(campaign, tmp_path):
    cfg, out, _ = campaign
    case = 7
    stored = {r["variant"]: r for r in results.read_rows(out).to_pylist() if r["case"] == case}
    # the task itself, run again here, in another process than the worker that ran it
    again = {r["variant"]: r for r in run_case(cfg, case)}
    for v in cfg.variants:
        for k in results.METRIC_COLUMNS:
            a, b = stored[v][k], again[v][k]
            assert (np.isnan(a) and np.isnan(b)) or a == b, (v, k, a, b)
        assert stored[v]["sim_seed"] == again[v]["sim_seed"]
    # and the rerun command (full logs) agrees with the rows
    text = rerun(out, case, out=tmp_path / "case7")
    assert "DIFFERS" not in text
    import json
    rep = json.loads((tmp_path / "case7" / "case.json").read_text())
    assert all(rep["variants"][v]["matches_campaign"] for v in cfg.variants)
    assert (tmp_path / "case7" / "coordinated" / "history.npz").is_file()


def test_interrupted_campaign_resumes_without_repeating(client, tmp_path):
    cfg = _cfg(seed=5)
    first = []

    def stop_after_six(i, rows):
        first.append(i)
        if len(first) == 6:
            raise KeyboardInterrupt  # what Ctrl-C does in the driver

    res1 = run_campaign(cfg, RUNS, tmp_path, client=client, progress_stream=_Null(),
                        on_case=stop_after_six)
    assert res1.interrupted and res1.ran == 6
    done1 = results.finished_cases(tmp_path, cfg.variants)
    assert done1 == set(first)

    second = []
    res2 = run_campaign(cfg, RUNS, tmp_path, client=client, progress_stream=_Null(),
                        on_case=lambda i, rows: second.append(i))
    assert not res2.interrupted
    assert res2.skipped == 6 and res2.ran == RUNS - 6
    assert set(second).isdisjoint(done1)
    assert set(second) | done1 == set(range(RUNS))
    keys = _raw_keys(tmp_path)
    assert len(keys) == len(set(keys)) == 2 * RUNS


def test_other_campaign_in_same_directory_refused(campaign):
    cfg, out, _ = campaign
    with pytest.raises(CampaignError, match="seed"):
        run_campaign(_cfg(seed=99), RUNS, out, client=None)


def test_metrics_are_the_main_jobs(campaign):
    """The row's metrics are tools.sitl.metrics' on the case's trajectory (same definitions as
    summary.json): checked on the decimated trace, within its resolution."""
    cfg, out, _ = campaign
    t = results.read_rows(out, traces=True).to_pylist()
    r = next(x for x in t if x["case"] == 3 and x["variant"] == "coordinated")
    tt = np.arange(len(r["trace.alpha_deg"])) * cfg.trace_dt_s
    from tools.evidence.montecarlo.case import command_timeline_deg
    ct, cd = command_timeline_deg(cfg)
    m = mt.channel_metrics(tt, np.radians(r["trace.alpha_deg"]), ct, np.radians(cd[:, 0]))
    assert m.final_error_deg == pytest.approx(r["alpha.final_error_deg"], abs=0.05)


def test_existing_cluster_by_scheduler_address(client, tmp_path):
    # GIVEN a running cluster known only by its address (as --scheduler tcp://host:port)
    addr = client.scheduler.address
    assert addr.startswith("tcp://127.0.0.1:")
    # WHEN a campaign is sent to it THEN every case lands, as on a private LocalCluster
    cfg = _cfg(seed=21)
    res = run_campaign(cfg, 4, tmp_path, scheduler=addr, progress_stream=_Null())
    assert (res.ran, res.lost, res.nthreads) == (4, [], 2)
    assert results.finished_cases(tmp_path, cfg.variants) == {0, 1, 2, 3}


def test_compare_a_campaign_with_itself_finds_no_difference(campaign):
    from tools.evidence.montecarlo.compare import compare
    cfg, out, _ = campaign
    c = compare(out, out)
    assert c["pairs"] == 2 * RUNS and c["warnings"] == [] and c["diverged_mismatch"] == []
    for v in cfg.variants:
        assert all(e["max_abs_diff"] == 0.0 for e in c["variants"][v].values())


def test_summary_command_writes_strict_json_table_and_plots(campaign, capsys):
    import json
    from tools.evidence.montecarlo import __main__ as cli
    cfg, out, _ = campaign
    assert cli.main(["summary", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "meets spec" in printed and "worst cases" in printed
    s = json.loads((out / "summary.json").read_text(),
                   parse_constant=lambda c: pytest.fail(f"non-strict JSON constant {c}"))
    assert s["cases"] == RUNS
    for name in ("envelopes.png", "histograms.png", "sensitivity.png"):
        p = out / name
        assert p.is_file() and p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_command_line_campaign_then_resume_runs_nothing(tmp_path):
    """The documented command end to end (own LocalCluster, 1 worker), then the same command
    again: everything already finished, exit 0, no new rows."""
    import subprocess
    import sys
    out = tmp_path / "cli"
    cmd = [sys.executable, "-m", "tools.evidence.montecarlo", "--scenario", "paper", "--runs", "3",
           "--workers", "1", "--duration", "2", "--seed", "4", "--out", str(out), "--no-plots"]
    for attempt in range(2):
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=240)
        assert p.returncode == 0, p.stderr[-2000:]
        expect = "3 cases run, 0 already finished" if attempt == 0 else \
            "0 cases run, 3 already finished"
        assert expect in p.stdout
    assert "meets spec" in p.stdout
    assert sorted(_raw_keys(out)) == sorted((i, v) for i in range(3)
                                            for v in ("coordinated", "uncoordinated"))
    assert (out / "summary.json").is_file() and (out / "campaign.json").is_file()
