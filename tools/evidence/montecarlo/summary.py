"""The summary of a campaign: percentiles, share meeting the specification, failures.

Everything here is computed from the rows on disk (``results.read_rows``), so it can be
recomputed at any time, with another specification, without re-running a case
(``python -m tools.evidence.montecarlo summary OUT_DIR [--spec FILE]``).

A row *meets the spec* when it did not diverge, raised no error, and every channel has
overshoot <= overshoot_max_pct (an undefined overshoot, for a step under
``tools.sitl.metrics.MIN_STEP_DEG``, passes), a settling time that exists and is
<= settling_max_s, and final error <= final_error_max_deg. A row *fails* when it diverged or
raised; failures are listed with their seeds. Worst cases are the rows with the largest
overshoot / settling / final error per channel and variant.
"""
from __future__ import annotations

import math

import numpy as np

from tools.evidence.montecarlo import results
from tools.evidence.montecarlo.case import CHANNELS

PERCENTILES = (5, 50, 95, 99)
SUMMARY_METRICS = ("overshoot_pct", "settling_time_s", "final_error_deg")
_SPEC_OF = {"overshoot_pct": "overshoot_max_pct", "settling_time_s": "settling_max_s",
            "final_error_deg": "final_error_max_deg"}
#: rows listed per worst-case table
N_WORST = 5
#: surface figures summarised and compared case by case (columns "surf.<key>", docs/metrics.md)
SURFACE_SUMMARY = ("peak_left_elevon_deg", "peak_right_elevon_deg", "peak_rudder_deg",
                   "travel_total_deg", "chatter_left_elevon_deg", "chatter_right_elevon_deg",
                   "chatter_rudder_deg", "at_limit_s", "cmd_at_limit_s", "rate_cmd_limited_s")


def _clean(x):
    """NaN/inf -> None for JSON."""
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x


def _stats(x: np.ndarray) -> dict:
    finite = x[np.isfinite(x)]
    out = {"n": int(finite.size), "undefined": int(x.size - finite.size)}
    if finite.size:
        for p in PERCENTILES:
            out[f"p{p}"] = float(np.percentile(finite, p))
        out["mean"] = float(finite.mean())
        out["max"] = float(finite.max())
    else:
        for p in PERCENTILES:
            out[f"p{p}"] = None
        out["mean"] = out["max"] = None
    return out


def meets_spec(cols: dict, spec: dict) -> np.ndarray:
    """Boolean per row (see the module docstring). ``cols``: column name -> numpy array."""
    ok = ~cols["diverged"].astype(bool) & (cols["error"] == "")
    for ch in CHANNELS:
        os_ = cols[f"{ch}.overshoot_pct"]
        st = cols[f"{ch}.settling_time_s"]
        fe = cols[f"{ch}.final_error_deg"]
        ok &= ~(os_ > spec["overshoot_max_pct"][ch])          # NaN (undefined) passes
        ok &= np.isfinite(st) & (st <= spec["settling_max_s"][ch])
        ok &= np.isfinite(fe) & (fe <= spec["final_error_max_deg"][ch])
    return ok


def _columns(table) -> dict:
    cols = {}
    for name in table.column_names:
        col = table.column(name)
        if name in ("variant", "error", "backend", "worker"):
            cols[name] = np.asarray(col.to_pylist(), dtype=object)
        else:
            cols[name] = col.to_numpy(zero_copy_only=False)
    return cols


def spearman(x: np.ndarray, y: np.ndarray) -> float:
    """Spearman rank correlation over the finite pairs (NaN if fewer than 3 or constant)."""
    m = np.isfinite(x) & np.isfinite(y)
    if m.sum() < 3:
        return math.nan
    rx = np.argsort(np.argsort(x[m])).astype(float)
    ry = np.argsort(np.argsort(y[m])).astype(float)
    if rx.std() == 0 or ry.std() == 0:
        return math.nan
    return float(np.corrcoef(rx, ry)[0, 1])


def summarise(out_dir, spec: dict, dispersion_keys: list[str], variants: tuple[str, ...],
              meta: dict | None = None) -> dict:
    """The summary dict of a campaign directory (JSON-ready)."""
    table = results.read_rows(out_dir)
    cols = _columns(table)
    n_rows = table.num_rows
    out = {"meta": meta or {}, "spec": spec, "rows": n_rows,
           "cases": int(len(set(cols["case"].tolist()))) if n_rows else 0,
           "variants": {}, "failures": [], "sensitivity": {}}
    if n_rows == 0:
        return out
    ok_all = meets_spec(cols, spec)
    random_keys = [k for k in dispersion_keys
                   if k in cols and np.nanstd(cols[k]) > 0]
    for v in variants:
        sel = cols["variant"] == v
        n = int(sel.sum())
        if n == 0:
            continue
        div = cols["diverged"][sel].astype(bool)
        err = cols["error"][sel] != ""
        ok = ok_all[sel]
        wall = cols["wall_time_s"][sel]
        vs = {"rows": n, "diverged": int(div.sum()), "errors": int(err.sum()),
              "meets_spec": int(ok.sum()), "meets_spec_share": float(ok.mean()),
              "wall_time_s_per_case": _stats(wall), "metrics": {}, "worst": {}}
        for ch in CHANNELS:
            vs["metrics"][ch] = {}
            for m in SUMMARY_METRICS:
                x = cols[f"{ch}.{m}"][sel].astype(float)
                st = _stats(x)
                lim = spec[_SPEC_OF[m]][ch]
                within = np.isfinite(x) & (x <= lim)
                if m == "overshoot_pct":
                    within |= np.isnan(x)  # no step in this channel: nothing to overshoot
                st["share_within_spec"] = float(within.mean())
                vs["metrics"][ch][m] = st
                # worst rows: undefined settling (never settled) is the worst of all
                key = np.where(np.isnan(x), np.inf, x) if m == "settling_time_s" else \
                    np.where(np.isnan(x), -np.inf, x)
                idx = np.argsort(-key, kind="stable")[:N_WORST]
                vs["worst"].setdefault(ch, {})[m] = [
                    {"case": int(cols["case"][sel][k]), "sim_seed": int(cols["sim_seed"][sel][k]),
                     "value": _clean(float(x[k]))} for k in idx]
        vs["surfaces"] = {k: _stats(cols[f"surf.{k}"][sel].astype(float))
                          for k in SURFACE_SUMMARY if f"surf.{k}" in cols}
        out["variants"][v] = vs
        sens = {}
        for ch in CHANNELS:
            for m in SUMMARY_METRICS:
                y = cols[f"{ch}.{m}"][sel].astype(float)
                sens[f"{ch}.{m}"] = {k: _clean(spearman(cols[k][sel].astype(float), y))
                                     for k in random_keys}
        out["sensitivity"][v] = sens
    # failures: diverged or errored rows, with what re-runs them
    bad = cols["diverged"].astype(bool) | (cols["error"] != "")
    for k in np.nonzero(bad)[0]:
        out["failures"].append({
            "case": int(cols["case"][k]), "variant": str(cols["variant"][k]),
            "campaign_seed": int(cols["campaign_seed"][k]),
            "sim_seed": int(cols["sim_seed"][k]),
            "reason": str(cols["error"][k]) or "diverged",
        })
    # paired comparison when both variants ran on the same cases
    if {"coordinated", "uncoordinated"} <= set(out["variants"]):
        out["paired"] = _paired(cols)
    return out


def _paired(cols: dict) -> dict:
    """Share of cases where the coordinated variant has the smaller metric, per channel."""
    by = {}
    for i, (c, v) in enumerate(zip(cols["case"].tolist(), cols["variant"].tolist())):
        by.setdefault(c, {})[v] = i
    pairs = [(d["coordinated"], d["uncoordinated"]) for d in by.values()
             if "coordinated" in d and "uncoordinated" in d]
    out = {"cases": len(pairs)}
    if not pairs:
        return out
    ic, iu = (np.array(p) for p in zip(*pairs))
    for ch in CHANNELS:
        for m in SUMMARY_METRICS:
            a = cols[f"{ch}.{m}"][ic].astype(float)
            b = cols[f"{ch}.{m}"][iu].astype(float)
            both = np.isfinite(a) & np.isfinite(b)
            out[f"{ch}.{m}"] = {
                "coordinated_smaller_share": _clean(float(np.mean(a[both] < b[both]))
                                                    if both.any() else math.nan),
                "n": int(both.sum())}
    for k in SURFACE_SUMMARY:
        col = f"surf.{k}"
        if col not in cols:
            continue
        a = cols[col][ic].astype(float)
        b = cols[col][iu].astype(float)
        both = np.isfinite(a) & np.isfinite(b)
        n = int(both.sum())
        share = (lambda m: _clean(float(np.mean(m[both]))) if n else None)
        out[col] = {"coordinated_smaller_share": share(a < b),
                    "equal_share": share(a == b),
                    "coordinated_larger_share": share(a > b), "n": n}
    return out


def to_json(summary: dict) -> dict:
    """Replace every NaN/inf by None, recursively (strict JSON)."""
    from tools.sitl.rundata import json_safe
    return json_safe(summary)


def _f(x, fmt="{:.2f}"):
    return "-" if x is None else fmt.format(x)


def table(summary: dict) -> str:
    """The summary as a fixed-width text table."""
    lines = []
    meta = summary.get("meta", {})
    lines.append(f"campaign: scenario {meta.get('scenario', '?')}, dispersions "
                 f"{meta.get('dispersions', '?')}, seed {meta.get('seed', '?')}, backend "
                 f"{meta.get('backend', '?')}, {summary['cases']} cases, {summary['rows']} rows")
    spec = summary["spec"]
    sp = ", ".join(f"{k} " + "/".join(_f(spec[k][c], "{:g}") for c in CHANNELS)
                   for k in spec)
    lines.append(f"spec (alpha/beta/mu): {sp}")
    for v, vs in summary["variants"].items():
        lines.append("")
        lines.append(f"{v}: {vs['rows']} cases, meets spec {vs['meets_spec']} "
                     f"({100 * vs['meets_spec_share']:.1f} %), diverged {vs['diverged']}, "
                     f"errors {vs['errors']}")
        hdr = f"  {'channel':8s} {'metric':16s} " + " ".join(
            f"{'p' + str(p):>8s}" for p in PERCENTILES) + f" {'max':>8s} {'undef':>6s}"
        lines.append(hdr)
        for ch in CHANNELS:
            for m in SUMMARY_METRICS:
                st = vs["metrics"][ch][m]
                lines.append(f"  {ch:8s} {m:16s} " + " ".join(
                    f"{_f(st['p' + str(p)]):>8s}" for p in PERCENTILES) +
                    f" {_f(st['max']):>8s} {st['undefined']:>6d}")
    for v, vs in summary["variants"].items():
        lines.append("")
        lines.append(f"{v}: worst cases (case / sim seed)")
        for ch in CHANNELS:
            parts = []
            for m in SUMMARY_METRICS:
                w = vs["worst"][ch][m][0] if vs["worst"][ch][m] else None
                if w is not None:
                    parts.append(f"{m} {_f(w['value'], '{:.3g}')} ({w['case']} / {w['sim_seed']})")
            lines.append(f"  {ch:8s} " + "  ".join(parts))
    if "paired" in summary:
        p = summary["paired"]
        lines.append("")
        lines.append(f"paired ({p['cases']} cases): share where coordinated < uncoordinated")
        for ch in CHANNELS:
            lines.append(f"  {ch:8s} " + "  ".join(
                f"{m} {_f(p[f'{ch}.{m}']['coordinated_smaller_share'], '{:.2f}')}"
                for m in SUMMARY_METRICS))
    for v, vs in summary["variants"].items():
        if not vs.get("surfaces"):
            continue
        lines.append("")
        lines.append(f"{v}: surfaces (docs/metrics.md)   p50 / p95 / max")
        for k, st in vs["surfaces"].items():
            lines.append(f"  {k:26s} {_f(st['p50'])} / {_f(st['p95'])} / {_f(st['max'])}")
    if "paired" in summary and any(k.startswith("surf.") for k in summary["paired"]):
        p = summary["paired"]
        lines.append("")
        lines.append("paired surfaces: share of cases where coordinated is smaller / equal / "
                     "larger")
        for k, e in p.items():
            if k.startswith("surf."):
                lines.append(f"  {k[5:]:26s} {_f(e['coordinated_smaller_share'])} / "
                             f"{_f(e['equal_share'])} / {_f(e['coordinated_larger_share'])}"
                             f"  (n {e['n']})")
    fails = summary["failures"]
    lines.append("")
    lines.append(f"failures (diverged or error): {len(fails)}")
    for f in fails[:20]:
        lines.append(f"  case {f['case']:6d} {f['variant']:14s} campaign seed "
                     f"{f['campaign_seed']} sim seed {f['sim_seed']}: {f['reason']}")
    if len(fails) > 20:
        lines.append(f"  ... {len(fails) - 20} more in summary.json")
    return "\n".join(lines)
