"""Compare two campaigns case by case (e.g. a ``--hil`` subset against the in-process run).

``python -m tools.evidence.montecarlo compare DIR_A DIR_B``: for every (case, variant) present in both,
the difference B - A of each summary metric; prints, per variant, channel and metric, the
number of pairs, the largest |difference| and the case where it occurs. Meaningful when both
campaigns have the same scenario, dispersion text and seed (then case i is the same dispersed
vehicle in both); a warning says when they do not.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

from tools.evidence.montecarlo import results
from tools.evidence.montecarlo.campaign import MANIFEST, load_manifest
from tools.evidence.montecarlo.case import CHANNELS
from tools.evidence.montecarlo.summary import SUMMARY_METRICS


def compare(dir_a, dir_b) -> dict:
    """{"warnings": [...], "pairs": n, "variants": {V: {"CH.METRIC": {n, max_abs_diff, case}}}}."""
    ca, _ = load_manifest(dir_a)
    cb, _ = load_manifest(dir_b)
    warnings = [f"{k} differs ({getattr(ca, k)!r} vs {getattr(cb, k)!r}): case i is not the "
                "same vehicle in both" for k in ("scenario", "dispersions_text", "seed",
                                                  "duration_s")
                if getattr(ca, k) != getattr(cb, k)]
    fa, fb = (json.loads((Path(d) / MANIFEST).read_text()).get("code_fingerprints", [])
              for d in (dir_a, dir_b))
    if fa and fb and not set(fa) & set(fb):
        warnings.append(f"the law/plant code differs between the two campaigns "
                        f"({fa[-1]} vs {fb[-1]})")
    ra = {(r["case"], r["variant"]): r for r in results.read_rows(dir_a).to_pylist()}
    rb = {(r["case"], r["variant"]): r for r in results.read_rows(dir_b).to_pylist()}
    common = sorted(set(ra) & set(rb))
    out = {"a": str(dir_a), "b": str(dir_b), "backends": [ca.backend, cb.backend],
           "warnings": warnings, "pairs": len(common), "variants": {}}
    for key in common:
        a, b = ra[key], rb[key]
        vs = out["variants"].setdefault(key[1], {})
        for ch in CHANNELS:
            for m in SUMMARY_METRICS:
                col = f"{ch}.{m}"
                x, y = a.get(col), b.get(col)
                e = vs.setdefault(col, {"n": 0, "max_abs_diff": 0.0, "case": None,
                                        "undefined_in_one": 0})
                if x is None or y is None or math.isnan(x) != math.isnan(y):
                    e["undefined_in_one"] += 1
                    continue
                if math.isnan(x):
                    continue
                e["n"] += 1
                d = abs(y - x)
                if d >= e["max_abs_diff"]:
                    e["max_abs_diff"], e["case"] = d, key[0]
        dv = out.setdefault("diverged_mismatch", [])
        if bool(a["diverged"]) != bool(b["diverged"]):
            dv.append({"case": key[0], "variant": key[1]})
    return out


def table(c: dict) -> str:
    lines = [f"compare {c['a']} ({c['backends'][0]}) with {c['b']} ({c['backends'][1]}): "
             f"{c['pairs']} (case, variant) pairs"]
    lines += [f"warning: {w}" for w in c["warnings"]]
    for v, vs in c["variants"].items():
        lines.append(f"{v}:")
        for col, e in vs.items():
            extra = f", undefined in one: {e['undefined_in_one']}" if e["undefined_in_one"] else ""
            lines.append(f"  {col:26s} n {e['n']:5d}  max |B - A| {e['max_abs_diff']:.4g}"
                         f" (case {e['case']}){extra}")
    mm = c.get("diverged_mismatch", [])
    lines.append(f"diverged in one only: {len(mm)}" + (f" {mm[:10]}" if mm else ""))
    return "\n".join(lines)
