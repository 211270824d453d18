"""Re-run one case of a campaign alone, with full logs and the main job's plots.

``python -m tools.evidence.montecarlo rerun OUT_DIR --case I`` rebuilds case I from the campaign's
manifest (same scenario, dispersion text, seed, duration, backend), flies each variant with
the full logging of the backend, and writes into ``OUT_DIR/case-I/``:

- ``case.json``: the dispersion values, the plant seed, the metrics of each variant, and the
  metrics stored in the campaign's rows for comparison (``matches_campaign``);
- ``scenario.toml``: the dispersed scenario as the plant takes it (fly it with the main job:
  ``python -m tools.hil run --scenario OUT_DIR/case-I/scenario.toml --seed SIM_SEED``);
- per variant the backend's full history (``<variant>/history.npz``); with ``--hil`` also the
  two processes' whole run directory (``<variant>/hil/``: truth.npz, fc.log, fc.tlog, ...);
- the main job's plots (``tools.sitl.plots``: fig2_attitude.png, ...), variants overlaid.
"""
from __future__ import annotations

import json
import math
import warnings
from pathlib import Path

import numpy as np

from tools.sitl import metrics as mt
from tools.sitl.rundata import json_safe
from tools.evidence.montecarlo import results
from tools.evidence.montecarlo.campaign import load_manifest
from tools.evidence.montecarlo.case import CHANNELS, code_fingerprint, fly_case, flight_metrics


def _row_metrics(out_dir, case: int) -> dict:
    t = results.read_rows(out_dir)
    rows = {}
    for r in t.to_pylist():
        if r["case"] == case:
            rows[r["variant"]] = r
    return rows


def _same(a, b) -> bool:
    if a is None or (isinstance(a, float) and math.isnan(a)):
        return b is None or (isinstance(b, float) and math.isnan(b))
    return b is not None and float(a) == float(b)


def rerun(out_dir, case: int, variants=None, out=None) -> str:
    """Re-run case ``case``; returns a short text report (also written as case.json)."""
    cfg, runs = load_manifest(out_dir)
    if not 0 <= case < runs:
        raise ValueError(f"--case {case} is not a case of the campaign in {out_dir}: "
                         f"it has cases 0..{runs - 1}")
    variants = tuple(variants or cfg.variants)
    dest = Path(out) if out else Path(out_dir) / f"case-{case}"
    dest.mkdir(parents=True, exist_ok=True)
    stored = _row_metrics(out_dir, case)
    codes = json.loads((Path(out_dir) / "campaign.json").read_text()).get("code_fingerprints", [])
    code_now = code_fingerprint()
    report = {"case": case, "campaign": str(out_dir), "campaign_seed": cfg.seed,
              "backend": cfg.backend, "code_fingerprint": code_now,
              "campaign_code_fingerprints": codes, "variants": {}}
    runs_for_plots = {}
    lines = [f"case {case} of {out_dir} (campaign seed {cfg.seed}, backend {cfg.backend})"]
    if codes and code_now not in codes:
        lines.append(f"  note: the law/plant code changed since the campaign ran (fingerprint "
                     f"{codes[-1]} -> {code_now}): differences from its rows are expected")
    for v in variants:
        vdir = dest / v
        vdir.mkdir(exist_ok=True)
        values, sim_seed, fl = fly_case(cfg, case, v, full=True,
                                        log_dir=vdir / "hil" if cfg.backend == "hil" else None)
        report["values"] = values
        report["sim_seed"] = sim_seed
        m = flight_metrics(fl)
        got = {f"{ch}.{k}": getattr(m["channels"][ch], k) for ch in CHANNELS
               for k in mt.METRIC_KEYS}
        entry = {"diverged": m["diverged"],
                 "metrics": {ch: mt.json_metrics(m["channels"][ch]) for ch in CHANNELS}}
        if v in stored:
            row = stored[v]
            diffs = {k: [row.get(k), got[k]] for k in got if not _same(got[k], row.get(k))}
            if bool(row["diverged"]) != m["diverged"]:
                diffs["diverged"] = [bool(row["diverged"]), m["diverged"]]
            entry["matches_campaign"] = not diffs
            entry["differences_campaign_rerun"] = diffs
        report["variants"][v] = entry
        hist = {"t_s": fl.t_s, "alpha_rad": fl.alpha_rad, "beta_rad": fl.beta_rad,
                "mu_rad": fl.mu_rad, "cmd_t_s": fl.cmd_t_s, "cmd_rad": fl.cmd_rad}
        full = fl.full if isinstance(fl.full, dict) else {}
        for k, val in full.items():
            if isinstance(val, np.ndarray):
                hist.setdefault(k, val)
        np.savez_compressed(vdir / "history.npz", **hist)
        runs_for_plots[v] = _plot_data(fl, entry)
        ch_txt = "  ".join(
            f"{ch}: os {_fmt(got[f'{ch}.overshoot_pct'])} % ts {_fmt(got[f'{ch}.settling_time_s'])} s "
            f"ef {_fmt(got[f'{ch}.final_error_deg'], '{:.3f}')} deg" for ch in CHANNELS)
        match = entry.get("matches_campaign")
        lines.append(f"  {v:14s} diverged {m['diverged']}  {ch_txt}  "
                     f"{'(same as the campaign row)' if match else '(DIFFERS from the campaign row)' if match is False else '(no campaign row)'}")
    report["values"] = report.get("values", {})
    if cfg.backend != "standin":
        from tools.evidence.montecarlo.case import dispersed_scenario
        (dest / "scenario.toml").write_text(
            f"# case {case} of campaign {out_dir} (seed {cfg.seed}, plant seed "
            f"{report.get('sim_seed')})\n" + dispersed_scenario(cfg, report["values"]).to_toml())
    results.write_json(dest / "case.json", json_safe(report))
    plots = _main_job_plots(runs_for_plots, cfg, case, dest)
    lines.append(f"  values: " + ", ".join(f"{k}={v:.4g}" for k, v in report["values"].items()))
    lines.append(f"  written: {dest}/case.json, scenario.toml, */history.npz" +
                 (", " + ", ".join(p.name for p in plots) if plots else ""))
    return "\n".join(lines)


def _fmt(x, f="{:.2f}"):
    return "-" if x is None else f.format(x)


def _plot_data(fl, entry) -> dict:
    """The normalised per-variant dict tools.sitl.plots expects (see tools.sitl.rundata)."""
    d = {"t_s": fl.t_s, "alpha_rad": fl.alpha_rad, "beta_rad": fl.beta_rad, "mu_rad": fl.mu_rad,
         "cmd_t_s": fl.cmd_t_s, "cmd_rad": fl.cmd_rad, "metrics": entry["metrics"]}
    for i, ch in enumerate(CHANNELS):
        d[f"cmd_{ch}_rad"] = fl.cmd_rad[:, i]
    if isinstance(fl.full, dict):
        for k, v in fl.full.items():
            d.setdefault(k, v)
    return d


def _main_job_plots(runs: dict, cfg, case: int, dest: Path) -> list[Path]:
    """tools.sitl.plots figures for the re-run (as many as the backend's data allows)."""
    try:
        from tools.sitl import plots
    except ImportError:
        return []
    meta = {"scenario": cfg.scenario, "mode": f"montecarlo case {case} ({cfg.backend})",
            "seed": cfg.seed}
    out = []
    for fn in ("fig_attitude", "fig_rates", "fig_surfaces", "fig_estimates"):
        f = getattr(plots, fn, None)
        if f is None:
            continue
        name = {"fig_attitude": "fig2_attitude.png", "fig_rates": "fig3_rates.png",
                "fig_surfaces": "fig4_surfaces.png", "fig_estimates": "estimates.png"}[fn]
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", UserWarning)  # empty legends of missing data
                out.append(Path(f(runs, meta, dest / name)))
        except (KeyError, TypeError, ValueError, IndexError):
            # the backend did not log what this figure needs (e.g. the stand-in)
            continue
    return out
