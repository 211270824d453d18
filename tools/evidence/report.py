"""tools/evidence/report.py - the README's and the docs' headline tables, written from the runs' JSON.

    python -m tools.evidence.report import-hil runs/<run> --as hil_paper --command "python -m tools.hil run"
    python -m tools.evidence.report import-mc runs/mc-paper --as mc_paper --command "python -m tools.evidence.montecarlo ..."
    python -m tools.evidence.report import-env runs/env_b --as env_b --command "python -m tools.evidence.envelope ..."
    python -m tools.evidence.report import-bench runs/bench.json --as bench --command "python -m tools.bench --json runs/bench.json"
    python -m tools.evidence.report write          # rewrite every generated table from docs/data/*.json
    python -m tools.evidence.report check          # exit 1 if a committed table differs from its data

A run's figures reach the documents in two steps, and no figure is typed by hand:
1. ``import-hil`` / ``import-mc`` copy a run's ``summary.json`` (the main job's, or a
   campaign's) into ``docs/data/NAME.json`` with the command that produced it, the commit of
   the code that ran (the run's own record where it has one) and the date: the committed
   source data.
2. ``write`` renders each table of ``TABLES`` from that data into every document that holds
   its block, between ``<!-- report:NAME -->`` and ``<!-- /report:NAME -->``; each table names
   its command, commit and date under it. ``check`` renders them again and compares:
   tests/unit/tools/test_report.py fails when a committed table disagrees with its data.
"""
from __future__ import annotations

import argparse
import datetime as _dt
import json
import math
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
DATA_DIR = "docs/data"
#: documents that may hold generated blocks
DOCUMENTS = ("README.md", "docs/coordination.md", "docs/montecarlo.md", "docs/metrics.md",
             "docs/margins.md", "docs/control_law.md", "docs/performance.md")
CHANNELS = ("alpha", "beta", "mu")
SURFACES = ("left_elevon", "right_elevon", "rudder")


def _git(*args: str) -> str:
    try:
        return subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True,
                              timeout=10).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return ""


def _commit_now() -> str:
    head = _git("rev-parse", "--short", "HEAD") or "unknown"
    dirty = _git("status", "--porcelain", "--", "fc", "plant_sim", "hyfc_wire", "tools")
    return head + ("+dirty" if dirty else "")


# ---------------------------------------------------------------------------------------
# import: a run's summary.json -> docs/data/NAME.json
# ---------------------------------------------------------------------------------------
def import_summary(summary_path: Path, name: str, command: str, kind: str,
                   root: Path = ROOT, commit_override: str | None = None,
                   created_override: str | None = None) -> Path:
    """Copy ``summary_path`` into ``docs/data/<name>.json`` as {"kind", "command", "commit",
    "created_utc", "summary"}. The commit is the run's own (``versions.git``) when it
    recorded one, else the tree's HEAD now (``+dirty`` if the code differs from it), unless
    ``commit_override`` / ``created_override`` say better (a campaign records neither)."""
    s = json.loads(Path(summary_path).read_text())
    if kind == "hil":
        s.pop("params", None)
        for run in s.get("runs", {}).values():
            run.pop("link", None)
        v = s.get("versions", {})
        commit = (v.get("git") or _commit_now()) + ("+dirty" if v.get("git_dirty") else "")
        created = s.get("created_utc") or _now()
    elif kind == "mc":
        for key in ("sensitivity", "failures"):
            s.pop(key, None)
        for vs in s.get("variants", {}).values():
            vs.pop("worst", None)
        commit = _commit_now()
        created = _mtime_utc(summary_path)
    elif kind == "env":
        commit = _commit_now()
        created = _mtime_utc(summary_path)
    elif kind == "bench":
        # python -m tools.bench --json FILE: the figures and the run's record, not the details
        s = {"meta": s.get("meta", {}), "figures": s.get("figures", {})}
        commit = _commit_now()
        utc = s["meta"].get("utc")
        created = (utc.replace("Z", "+00:00") if isinstance(utc, str)
                   else _mtime_utc(summary_path))
    else:
        raise ValueError(f"kind must be 'hil', 'mc', 'env' or 'bench', got {kind!r}")
    commit = commit_override or commit
    created = created_override or created
    out = Path(root) / DATA_DIR / f"{name}.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({"kind": kind, "command": command, "commit": commit,
                               "created_utc": created, "summary": s}, indent=1,
                              sort_keys=False) + "\n")
    return out


def _now() -> str:
    return _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%S+00:00")


def _mtime_utc(path: Path) -> str:
    t = Path(path).stat().st_mtime
    return _dt.datetime.fromtimestamp(t, _dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%S+00:00")


def load_data(name: str, root: Path = ROOT) -> dict:
    return json.loads((Path(root) / DATA_DIR / f"{name}.json").read_text())


# ---------------------------------------------------------------------------------------
# tables
# ---------------------------------------------------------------------------------------
def _f(x, fmt: str) -> str:
    return "-" if x is None else fmt.format(x)


def _caption(d: dict, source: str) -> str:
    return (f"*Written by `python -m tools.evidence.report` from `{DATA_DIR}/{source}.json`: "
            f"`{d['command']}`, commit {d['commit']}, {d['created_utc'][:16].replace('T', ' ')}"
            f" UTC.*")


def table_hil_steps(root: Path = ROOT, source: str = "hil_paper", paper: bool = True) -> str:
    """The main job's comparison (README): metrics and surfaces of both variants, with the
    paper's own figures quoted (they are the paper's, not measured here) when ``paper``.
    ``source``: the default law's run (``hil_paper``), the paper's fixed gains'
    (``hil_paper_gains``) or the prefilter's (``hil_prefilter``)."""
    d = load_data(source, root)
    runs = d["summary"]["runs"]
    co, un = runs["coordinated"], runs["uncoordinated"]

    def three(run, key, fmt):
        return " / ".join(_f(run[ch].get(key), fmt) for ch in CHANNELS)

    def surf(run, keys, fmt):
        return " / ".join(_f(run["surfaces"].get(k), fmt) for k in keys)

    peaks = [f"peak_{s}_deg" for s in SURFACES]
    chat = [f"chatter_{s}_deg" for s in SURFACES]
    rows = [
        ("overshoot alpha / beta / mu (%)", three(co, "overshoot_pct", "{:.1f}"),
         three(un, "overshoot_pct", "{:.1f}"), "10 / smaller / smaller", "35 / - / -"),
        ("settling time alpha / beta / mu (s)", three(co, "settling_time_s", "{:.2f}"),
         three(un, "settling_time_s", "{:.2f}"), "not given", "not given"),
        ("final error alpha / beta / mu (deg)", three(co, "final_error_deg", "{:.3f}"),
         three(un, "final_error_deg", "{:.3f}"), "", ""),
        ("mu wrong-way dip (% of the step)", _f(co["mu"].get("undershoot_pct"), "{:.1f}"),
         _f(un["mu"].get("undershoot_pct"), "{:.1f}"), "", ""),
        ("peak left elevon / right elevon / rudder (deg)", surf(co, peaks, "{:.1f}"),
         surf(un, peaks, "{:.1f}"), "", ""),
        ("total surface travel (deg)", surf(co, ["travel_total_deg"], "{:.0f}"),
         surf(un, ["travel_total_deg"], "{:.0f}"), "", ""),
        ("command chatter, 5 Hz high-pass RMS, l / r / rudder (deg)", surf(co, chat, "{:.2f}"),
         surf(un, chat, "{:.2f}"), "", ""),
        ("time with a surface (achieved) at its limit (s)", surf(co, ["at_limit_s"], "{:.2f}"),
         surf(un, ["at_limit_s"], "{:.2f}"), "", ""),
        ("time with a surface command at its limit (s)", surf(co, ["cmd_at_limit_s"], "{:.2f}"),
         surf(un, ["cmd_at_limit_s"], "{:.2f}"), "", ""),
        ("time with the rate-command limit active (s)",
         surf(co, ["rate_cmd_limited_s"], "{:.2f}"), surf(un, ["rate_cmd_limited_s"], "{:.2f}"),
         "", ""),
    ]
    if paper:
        lines = [f"| `{d['command']}` | coordinated | uncoordinated | paper, coordinated | "
                 "paper, uncoordinated |", "|---|---|---|---|---|"]
        lines += ["| " + " | ".join(r) + " |" for r in rows]
    else:
        lines = [f"| `{d['command']}` | coordinated | uncoordinated |", "|---|---|---|"]
        lines += ["| " + " | ".join(r[:3]) + " |" for r in rows]
    return "\n".join(lines) + "\n\n" + _caption(d, source)


def table_hil_steps_paper_gains(root: Path = ROOT) -> str:
    """The main job flown with the paper's fixed gains (``--gains paper``), for the README's
    comparison with the paper."""
    return table_hil_steps(root, "hil_paper_gains")


def table_hil_prefilter(root: Path = ROOT) -> str:
    """The main job with the law's reference prefilter (``--command-shaping prefilter``); the
    paper flew steps, so its figures are not quoted beside it."""
    return table_hil_steps(root, "hil_prefilter", paper=False)


def claim_eq14_mirror(root: Path = ROOT) -> str:
    """The paper's fixed gains with the coordinated factors of Eq. 14 instead of Eq. 19, and
    with the sideslip and bank signs mirrored, in two sentences (README), from the runs' data."""
    e19 = load_data("hil_paper_gains", root)
    e14 = load_data("hil_paper_gains_eq14", root)
    m19 = load_data("hil_paper_gains_mirror", root)
    m14 = load_data("hil_paper_gains_eq14_mirror", root)

    def three(d, variant, key="overshoot_pct", fmt="{:.1f}"):
        run = d["summary"]["runs"][variant]
        return " / ".join(_f(run[ch].get(key), fmt) for ch in CHANNELS)

    return (f"With the paper's fixed gains and Eq. 14's factors instead (`CO_FAC_EQ` 14) the "
            f"coordinated law overshoots alpha / beta / mu by {three(e14, 'coordinated')} % "
            f"and settles in {three(e14, 'coordinated', 'settling_time_s', '{:.2f}')} s (Eq. 19: "
            f"{three(e19, 'coordinated')} % and "
            f"{three(e19, 'coordinated', 'settling_time_s', '{:.2f}')} s; uncoordinated "
            f"{three(e19, 'uncoordinated')} %). With the sideslip and bank signs mirrored "
            f"(scenario `paper_mirror`) coordination gives {three(m19, 'coordinated')} % with "
            f"Eq. 19 and {three(m14, 'coordinated')} % with Eq. 14, against "
            f"{three(m19, 'uncoordinated')} % uncoordinated. (`{e14['command']}`, "
            f"`{m19['command']}`, `{m14['command']}`; the parameter file holds `CO_FAC_EQ 14`; "
            f"commit {e14['commit']}, {e14['created_utc'][:10]}, written by "
            f"`python -m tools.evidence.report`.)")


def _cmp(a: float, b: float, fmt: str = "{:.1f}") -> str:
    """"a vs b" with the format."""
    return f"{fmt.format(a)} vs {fmt.format(b)}"


def claim_hil_compare(root: Path = ROOT) -> str:
    """The README's reading of the main job's two tables (coordinated against uncoordinated,
    the paper's fixed gains and the default law), with every figure and every direction
    ("lowers", "later") taken from the runs' data."""
    pg = load_data("hil_paper_gains", root)["summary"]["runs"]
    df = load_data("hil_paper", root)["summary"]["runs"]

    def v(runs, var, ch, key):
        return runs[var][ch].get(key)

    def lower(runs, ch, key="overshoot_pct"):
        return v(runs, "coordinated", ch, key) < v(runs, "uncoordinated", ch, key)

    def dt(runs, ch):
        return (v(runs, "coordinated", ch, "settling_time_s")
                - v(runs, "uncoordinated", ch, "settling_time_s"))

    def when(x):
        return f"{abs(x):.2f} s {'later' if x > 0 else 'sooner'}"

    def os_pair(runs, ch):
        return _cmp(v(runs, "coordinated", ch, "overshoot_pct"),
                    v(runs, "uncoordinated", ch, "overshoot_pct"))

    both = lower(pg, "alpha") and lower(pg, "mu")
    first = (f"With the paper's fixed gains (second table) coordination "
             f"{'lowers' if both else 'does not lower both of'} alpha and mu overshoot "
             f"({os_pair(pg, 'alpha')} %, {os_pair(pg, 'mu')} %) and settles mu "
             f"{when(dt(pg, 'mu'))}; its alpha rises in "
             f"{_cmp(v(pg, 'coordinated', 'alpha', 'rise_time_s'), v(pg, 'uncoordinated', 'alpha', 'rise_time_s'), '{:.2f}')} s "
             f"(the run's summary) and it settles alpha {when(dt(pg, 'alpha'))} and beta "
             f"{when(dt(pg, 'beta'))}.")
    spread = max(abs(v(df, "coordinated", ch, "overshoot_pct")
                     - v(df, "uncoordinated", ch, "overshoot_pct")) for ch in CHANNELS)
    lowers_df = lower(df, "alpha") and lower(df, "mu")
    second = (f" With the default law (first table) the two variants' overshoots lie within "
              f"{spread:.1f} points of each other and coordination "
              f"{'lowers' if lowers_df else 'does not lower'} the overshoot (alpha "
              f"{os_pair(df, 'alpha')} %, mu {os_pair(df, 'mu')} %); it settles alpha "
              f"{when(dt(df, 'alpha'))} "
              f"({_cmp(v(df, 'coordinated', 'alpha', 'settling_time_s'), v(df, 'uncoordinated', 'alpha', 'settling_time_s'), '{:.2f}')} s).")
    d0 = load_data("hil_paper", root)
    return (first + second + f" (From `docs/data/hil_paper_gains.json` and "
            f"`docs/data/hil_paper.json`, commit {d0['commit']}, written by "
            f"`python -m tools.evidence.report`.)")


def claim_hil_alpha(root: Path = ROOT) -> str:
    """The alpha overshoot we measure where the paper reports 35 % / 10 % (README)."""
    pg = load_data("hil_paper_gains", root)["summary"]["runs"]
    df = load_data("hil_paper", root)["summary"]["runs"]

    def a(runs, var):
        return f"{runs[var]['alpha']['overshoot_pct']:.1f} %"

    return (f"With its fixed gains and its steps we measure {a(pg, 'uncoordinated')} and "
            f"{a(pg, 'coordinated')} (the second table; the default law: "
            f"{a(df, 'uncoordinated')} and {a(df, 'coordinated')}).")


def claim_envelope(root: Path = ROOT) -> str:
    """The default law's envelope maps (README): the corridor shares and the divergences of
    map (b) and map (a), from docs/data/env_b.json and env_a.json."""
    b = load_data("env_b", root)
    a = load_data("env_a", root)

    def share(v):
        return f"{v['corridor_meets_spec']} of {v['corridor_points']}"

    def pct(v):
        return f"{100.0 * v['corridor_meets_spec'] / max(v['corridor_points'], 1):.0f} %"

    bu, bc = b["summary"]["variants"]["unco"], b["summary"]["variants"]["co_eq19"]
    au, ac = a["summary"]["variants"]["unco"], a["summary"]["variants"]["co_eq19"]
    return (f"Map (b) (`{b['command']}`): the spec holds at **{share(bu)} points of 24-300 kPa, "
            f"Mach <= 15, uncoordinated ({pct(bu)}) and {share(bc)} coordinated ({pct(bc)})**; "
            f"the target is 90 % in both. Diverged: {bu['diverged']} / {bc['diverged']} points; "
            f"unsettled at 20 s: {bu['unsettled']} / {bc['unsettled']}. Map (a) (`{a['command']}`): "
            f"{share(au)} ({pct(au)}) and {share(ac)} ({pct(ac)}); diverged {au['diverged']} / "
            f"{ac['diverged']}, unsettled {au['unsettled']} / {ac['unsettled']}"
            + (f" (of which {au['unsettled_released']} / {ac['unsettled_released']} settle once "
               f"d(t) is switched off: forced, not limit cycles)"
               if "unsettled_released" in au and "unsettled_released" in ac else "")
            + f". (Commit "
            f"{b['commit']}, {b['created_utc'][:10]}"
            + (f"; map (a) commit {a['commit']}, {a['created_utc'][:10]}"
               if a.get("commit") != b.get("commit") else "")
            + ", written by "
            f"`python -m tools.evidence.report`.)")


def table_beta0(root: Path = ROOT) -> str:
    """The mu wrong-way dip with and without the paper's untrimmed 5 deg initial sideslip."""
    a = load_data("hil_paper", root)
    b = load_data("hil_paper_beta0", root)
    lines = ["| mu wrong-way dip, % of the 4 deg step | coordinated | uncoordinated |",
             "|---|---|---|"]
    for d, label in ((a, "paper case, beta0 = 5 deg"), (b, "beta0 = 0 (`paper_beta0`)")):
        r = d["summary"]["runs"]
        lines.append(f"| {label} | {_f(r['coordinated']['mu'].get('undershoot_pct'), '{:.1f}')}"
                     f" | {_f(r['uncoordinated']['mu'].get('undershoot_pct'), '{:.1f}')} |")
    return ("\n".join(lines) + "\n\n" + _caption(a, "hil_paper") + "\n" +
            _caption(b, "hil_paper_beta0"))


def _pct(x) -> str:
    return "-" if x is None else f"{100 * x:.1f} %"


def table_mc(root: Path = ROOT, source: str = "mc_paper") -> str:
    """A campaign's headline table (README, docs/montecarlo.md): spec, divergence, overshoot
    and settling percentiles, and the case-by-case shares. ``source``: the paper's campaign
    with the default law (``mc_paper``), with the paper's fixed gains (``mc_paper_gains``), or
    the paper's case at the cruise point with its d(t) as an angular acceleration
    (``mc_cruise``) or as a moment coefficient (``mc_cruise_b``)."""
    d = load_data(source, root)
    s = d["summary"]
    vs = s["variants"]
    co, un = vs["coordinated"], vs["uncoordinated"]
    lines = [f"| {s['cases']:,} dispersed cases | coordinated | uncoordinated |", "|---|---|---|",
             f"| meets the spec | {co['meets_spec']} ({_pct(co['meets_spec_share'])}) | "
             f"{un['meets_spec']} ({_pct(un['meets_spec_share'])}) |",
             f"| diverged | {co['diverged']} | {un['diverged']} |"]
    for ch in CHANNELS:
        cells = []
        for v in (co, un):
            st = v["metrics"][ch]["overshoot_pct"]
            cells.append(f"{_f(st['p50'], '{:.1f}')} / {_f(st['p95'], '{:.1f}')} / "
                         f"{_f(st['max'], '{:.1f}')}")
        lines.append(f"| {ch} overshoot, median / p95 / max (%) | {cells[0]} | {cells[1]} |")
    cells = [" / ".join(_f(v["metrics"][ch]["settling_time_s"]["p95"], "{:.1f}")
                        for ch in CHANNELS) for v in (co, un)]
    lines.append(f"| settling alpha / beta / mu, p95 (s) | {cells[0]} | {cells[1]} |")
    p = s.get("paired", {})
    if p:
        lines += ["", f"| case by case ({p['cases']:,} cases): coordinated smaller | alpha | beta "
                  "| mu |", "|---|---|---|---|"]
        for m, label in (("overshoot_pct", "overshoot"), ("settling_time_s", "settling time"),
                         ("final_error_deg", "final error")):
            lines.append(f"| {label} | " + " | ".join(
                _pct(p.get(f"{ch}.{m}", {}).get("coordinated_smaller_share")) for ch in CHANNELS)
                + " |")
    return "\n".join(lines) + "\n\n" + _caption(d, source)


def table_mc_paper_gains(root: Path = ROOT) -> str:
    """The paper's campaign flown with the paper's fixed gains (before issue 20's default)."""
    return table_mc(root, "mc_paper_gains")


def table_mc_cruise(root: Path = ROOT) -> str:
    """The paper's case dispersed at the cruise point (scenario ``paper_cruise``)."""
    return table_mc(root, "mc_cruise")


def table_mc_cruise_b(root: Path = ROOT) -> str:
    """The paper's case dispersed at the cruise point, d(t) as a moment coefficient (scenario
    ``paper_cruise_b``)."""
    return table_mc(root, "mc_cruise_b")


def table_mc_surfaces(root: Path = ROOT) -> str:
    """The surfaces over the campaign, coordinated against uncoordinated (docs/coordination.md).
    From the 1,000-case campaign flown with the paper's fixed gains (``mc_paper_gains``), the
    one docs/coordination.md analyses."""
    d = load_data("mc_paper_gains", root)
    s = d["summary"]
    vs = s["variants"]
    p = s.get("paired", {})
    labels = {"peak_left_elevon_deg": "peak left elevon (deg)",
              "peak_right_elevon_deg": "peak right elevon (deg)",
              "peak_rudder_deg": "peak rudder (deg)", "travel_total_deg": "total travel (deg)",
              "chatter_left_elevon_deg": "chatter left elevon (deg)",
              "chatter_right_elevon_deg": "chatter right elevon (deg)",
              "chatter_rudder_deg": "chatter rudder (deg)",
              "at_limit_s": "achieved deflection at its limit (s)",
              "cmd_at_limit_s": "command at its limit (s)",
              "rate_cmd_limited_s": "rate-command limit active (s)"}
    lines = [f"| {s['cases']:,} dispersed cases | coordinated median / p95 | uncoordinated "
             "median / p95 | coordinated smaller / equal / larger |", "|---|---|---|---|"]
    for k, label in labels.items():
        cells = []
        for v in ("coordinated", "uncoordinated"):
            st = vs[v].get("surfaces", {}).get(k)
            cells.append("-" if st is None else
                         f"{_f(st['p50'], '{:.2f}')} / {_f(st['p95'], '{:.2f}')}")
        e = p.get(f"surf.{k}", {})
        share = " / ".join(_pct(e.get(x)) for x in ("coordinated_smaller_share", "equal_share",
                                                     "coordinated_larger_share"))
        lines.append(f"| {label} | {cells[0]} | {cells[1]} | {share} |")
    return "\n".join(lines) + "\n\n" + _caption(d, "mc_paper_gains")


def claim_mc_surfaces(root: Path = ROOT) -> str:
    """The campaign's surface shares in one sentence (docs/coordination.md s. 4,
    docs/control_law.md s. 9), so the prose quotes the data too (``mc_paper_gains``, as
    ``table_mc_surfaces``)."""
    d = load_data("mc_paper_gains", root)
    p = d["summary"].get("paired", {})

    def sh(key, which):
        return _pct(p.get(f"surf.{key}", {}).get(which))

    return (f"over {p.get('cases', 0):,} dispersed paper cases coordination gives the smaller "
            f"rudder peak in {sh('peak_rudder_deg', 'coordinated_smaller_share')}, the smaller "
            f"total travel in {sh('travel_total_deg', 'coordinated_smaller_share')} and the "
            f"smaller rudder chatter in {sh('chatter_rudder_deg', 'coordinated_smaller_share')}"
            f" of the cases, but the larger right-elevon peak in "
            f"{sh('peak_right_elevon_deg', 'coordinated_larger_share')} and the larger "
            f"left-elevon peak in {sh('peak_left_elevon_deg', 'coordinated_larger_share')}; "
            f"the rate-command limit is active longer in "
            f"{sh('rate_cmd_limited_s', 'coordinated_larger_share')} (`{d['command']}`, "
            f"commit {d['commit']}, `python -m tools.evidence.report`).")


def claim_mc(root: Path = ROOT) -> str:
    """The three default-law campaigns in one paragraph (README, docs/montecarlo.md): the
    share meeting the spec per variant against issue 20's 99 %, and the worst final error per
    channel, from docs/data/mc_paper.json, mc_cruise_b.json and mc_cruise.json."""
    parts = []
    for name, what in (("mc_paper", "at the paper's point (`paper`)"),
                       ("mc_cruise_b", "at the cruise point with d(t) scaled with dynamic "
                                       "pressure (`paper_cruise_b`)"),
                       ("mc_cruise", "at the cruise point with the paper's d(t) kept at its "
                                     "183 kPa size (`paper_cruise`)")):
        d = load_data(name, root)
        v = d["summary"]["variants"]
        co, un = v["coordinated"], v["uncoordinated"]
        n = d["summary"].get("cases", co.get("rows", 0))

        def worst_fe(var):
            m = var.get("metrics", {})
            return " / ".join(f"{m.get(ch, {}).get('final_error_deg', {}).get('max', math.nan):.3f}"
                              for ch in ("alpha", "beta", "mu"))

        verdict = ("both meet issue 20's 99 %"
                   if min(co["meets_spec_share"], un["meets_spec_share"]) >= 0.99
                   else "below issue 20's 99 %")
        parts.append(f"{what}: **{co['meets_spec']} / {un['meets_spec']} of {n:,} cases** "
                     f"coordinated / uncoordinated ({_pct(co['meets_spec_share'])} / "
                     f"{_pct(un['meets_spec_share'])}, {verdict}; worst final error alpha / "
                     f"beta / mu {worst_fe(co)} deg coordinated, {worst_fe(un)} deg "
                     f"uncoordinated; commit {d['commit']})")
    return ("Cases meeting the spec in the default law's 1,000-case campaigns: " + "; ".join(parts) +
            ". (Written by `python -m tools.evidence.report` from `docs/data/mc_paper.json`, "
            "`mc_cruise_b.json`, `mc_cruise.json`.)")


def _ok(met: bool) -> str:
    return "met" if met else "**missed**"


def table_bench(root: Path = ROOT, source: str = "bench", hour_source: str = "hour") -> str:
    """Issue 24's numbers from one ``python -m tools.bench --json FILE`` run: each figure, its
    target, whether it is met, and the floor the same run measured under it; with
    ``docs/data/<hour_source>.json`` (``python -m tools.bench hour --json FILE``) the 1-hour
    cruise's wall time (its floor: the exchanges at the bench's ping-pong), logs and memory."""
    d = load_data(source, root)
    f = d["summary"]["figures"]
    g = f.get
    nan = math.nan
    rows = ["| figure | measured | issue 24's target | | floor, same run |",
            "|---|---|---|---|---|"]
    cpu = g("fc_frame_cpu_median_us", nan)
    rows.append(f"| fc CPU per plant frame, in process (receive / frame / housekeeping) | "
                f"{cpu:.1f} us = {g('fc_frame_read_median_us', nan):.1f} + "
                f"{g('fc_frame_work_median_us', nan):.1f} + "
                f"{g('fc_frame_housekeeping_median_us', nan):.1f} | <= 7 us | {_ok(cpu <= 7)} | "
                + (f"the fc's link alone (receive + decode, framing + send) "
                   f"{g('fc_frame_link_floor_median_us'):.1f} us; "
                   if g("fc_frame_link_floor_median_us") is not None else "")
                + f"the law alone (from Python) {g('law_cycle_fc_median_us', nan):.2f} us |")
    pp = g("plant_frame_path_us", nan)
    rk = g("plant_rk4_step_in_loop_us", nan)
    rows.append(f"| plant per-frame path, no network | {pp:.1f} us | <= 5 us | {_ok(pp <= 5)} | "
                f"two RK4 steps {2 * rk:.1f} us |")
    rtf = g("lockstep_500_rtf", nan)
    flo = g("lockstep_500_floor_rtf", nan)
    share = rtf / flo if flo else nan
    rows.append(f"| lockstep at 500 Hz, plant process | {rtf:.1f}x = {share * 100:.0f} % of the "
                f"links' limit | >= 75 % | {_ok(share >= 0.75)} | the links' ping-pong "
                f"{g('pingpong_links_median_us', nan):.0f} us ({flo:.1f}x); raw UDP "
                f"{g('pingpong_raw_median_us', nan):.0f} us |")
    for mode in ("coordinated", "cruise"):
        py = g(f"fc_py_allocs_per_frame_{mode}", nan)
        nrt = g(f"fc_nrt_allocs_per_frame_{mode}", nan)
        rows.append(f"| fc allocations per plant frame, {mode.upper()}: Python blocks / numba "
                    f"records | {py:.3f} / {nrt:.3f} | 0 / 0 | {_ok(py == 0 and nrt == 0)} | |")
    lp = g("rt_1000_lateness_p99_us", nan)
    ls = g("rt_1000_late_20pct_pct", nan)
    fp = g("rt_1000_floor_lateness_p99_us")
    fs = g("rt_1000_floor_late_20pct_pct")
    floor = (f"a bare receiver: p99 {fp:.0f} us, {fs:.2f} % late" if fp is not None
             else "not measured in this run")
    rows.append(f"| real time 1 kHz, wake-up lateness | p99 {lp:.0f} us, {ls:.2f} % late | "
                f"p99 <= 50 us, < 0.1 % late | {_ok(lp <= 50 and ls < 0.1)} | {floor} |")
    rows.append(f"| peak RSS, fc / plant (lockstep run) | {g('fc_peak_rss_mb', nan):.0f} / "
                f"{g('plant_peak_rss_mb', nan):.0f} MB | | | |")
    hour_path = Path(root) / DATA_DIR / f"{hour_source}.json"
    tail = ""
    if hour_path.exists():
        h = load_data(hour_source, root)
        hf = h["summary"]["figures"]
        wall, logs, rss = hf["hour_wall_s"], hf["hour_logs_mb"], hf["hour_peak_rss_mb"]
        n = hf["hour_exchanges"]
        ping = g("pingpong_links_median_us", nan)
        sim = f"{hf['hour_duration_s'] / 3600:g}-hour" if hf["hour_duration_s"] % 3600 == 0 \
            else f"{hf['hour_duration_s']:g} s"
        rows.append(f"| the {sim} lockstep cruise: wall time | {wall:.0f} s | <= 80 s | "
                    f"{_ok(wall <= 80)} | {n:,} exchanges x the links' ping-pong {ping:.0f} us "
                    f"= {n * ping * 1e-6:.0f} s |")
        big = sorted(hf["hour_log_files_mb"].items(), key=lambda kv: -kv[1])[:3]
        rows.append(f"| the {sim} cruise: logs | {logs:.0f} MB | <= 300 MB | {_ok(logs <= 300)} "
                    f"| " + ", ".join(f"{k.split('/')[-1]} {v:.0f}" for k, v in big) + " MB |")
        procs = hf["hour_peak_rss_processes_mb"]
        rows.append(f"| the {sim} cruise: peak RSS summed over the processes | {rss:.0f} MB | "
                    f"<= 400 MB | {_ok(rss <= 400)} | at {hf['hour_peak_rss_at_s']:.0f} s: "
                    + ", ".join(f"{k.split(' (')[0]} {v:.0f}" for k, v in procs.items()) + " MB |")
        tail = " The cruise's rows: " + _caption(h, hour_source)
    load = d["summary"]["meta"].get("load_avg_1min_at_part_start", {})
    lo = f"{min(load.values()):.1f}-{max(load.values()):.1f}" if load else "-"
    return ("\n".join(rows) + f"\n\nLoad average at the parts' starts {lo}. " +
            _caption(d, source) + tail)


#: the rows of the before/after table: (figure key in tools.bench's JSON, label, format)
BENCH_COMPARE_ROWS = (
    ("fc_frame_cpu_median_us", "fc CPU per plant frame, in process (us)", "{:.1f}"),
    ("fc_frame_read_median_us", ". receive + decode (us)", "{:.1f}"),
    ("fc_frame_work_median_us", ". frame (us)", "{:.1f}"),
    ("fc_frame_housekeeping_median_us", ". housekeeping (us)", "{:.1f}"),
    ("fc_frame_loop_cpu_median_us", "fc CPU per plant frame as the lockstep loop reads (us)",
     "{:.1f}"),
    ("fc_frame_link_floor_median_us", "floor: the fc's link alone (us)", "{:.1f}"),
    ("fc_py_allocs_per_frame_coordinated", "fc Python blocks per frame, COORDINATED", "{:.3f}"),
    ("fc_py_allocs_per_frame_cruise", "fc Python blocks per frame, CRUISE", "{:.3f}"),
    ("fc_nrt_allocs_per_frame", "fc numba records per frame (worse mode)", "{:.3f}"),
    ("plant_frame_path_us", "plant per-frame path (us)", "{:.1f}"),
    ("plant_frame_physics_us", "floor: the plant's frame without the wire, in numba (us)",
     "{:.1f}"),
    ("plant_rk4_step_in_loop_us", "plant RK4 step in the loop (us)", "{:.2f}"),
    ("pingpong_raw_median_us", "floor: raw UDP ping-pong (us)", "{:.1f}"),
    ("pingpong_links_median_us", "floor: ping-pong through the links (us)", "{:.1f}"),
    ("lockstep_500_rtf", "lockstep 500 Hz, plant process (x real time)", "{:.1f}"),
    ("lockstep_500_floor_rtf", "the links' limit at 500 Hz (x real time)", "{:.1f}"),
    ("lockstep_1000_rtf", "lockstep 1 kHz, plant process (x real time)", "{:.1f}"),
    ("rt_1000_lateness_p99_us", "real time 1 kHz, lateness p99 (us)", "{:.0f}"),
    ("rt_1000_late_20pct_pct", "real time 1 kHz, late > 20 % of the period (%)", "{:.2f}"),
    ("rt_1000_floor_lateness_p99_us", "floor: a bare receiver's lateness p99 (us)", "{:.0f}"),
    ("rt_1000_latency_p99_us", "real time 1 kHz, sensor-to-servo latency p99 (us)", "{:.0f}"),
    ("closed_loop_sim_s_per_wall_s", "in-process closed loop (x real time)", "{:.0f}"),
    ("startup_warm_first_servo_s", "warm start-up to the first servo output (s)", "{:.2f}"),
    ("fc_peak_rss_mb", "peak RSS, fc (MB)", "{:.0f}"),
    ("plant_peak_rss_mb", "peak RSS, plant (MB)", "{:.0f}"),
)


def table_bench_compare(root: Path = ROOT, before: str = "bench_before",
                        after: str = "bench") -> str:
    """Two ``python -m tools.bench --json`` runs side by side (``BENCH_COMPARE_ROWS``); a figure
    one run did not measure shows as -."""
    b, a = load_data(before, root), load_data(after, root)
    fb, fa = b["summary"]["figures"], a["summary"]["figures"]
    head = (f"| figure | before ({b['commit']}, {b['created_utc'][11:16]} UTC) | after "
            f"({a['commit']}, {a['created_utc'][11:16]} UTC) |")
    rows = [head, "|---|---|---|"]
    for key, label, fmt in BENCH_COMPARE_ROWS:
        x, y = fb.get(key), fa.get(key)
        if x is None and y is None:
            continue
        rows.append(f"| {label} | {_f(x, fmt)} | {_f(y, fmt)} |")
    return ("\n".join(rows) + "\n\nBefore: " + _caption(b, before) + " After: " +
            _caption(a, after))


#: block name -> the function that renders it
TABLES = {"hil_steps": table_hil_steps, "hil_steps_paper_gains": table_hil_steps_paper_gains,
          "hil_prefilter": table_hil_prefilter, "eq14_mirror_claim": claim_eq14_mirror,
          "hil_compare_claim": claim_hil_compare, "hil_alpha_claim": claim_hil_alpha,
          "envelope_claim": claim_envelope,
          "beta0_dip": table_beta0, "mc_paper": table_mc,
          "mc_paper_gains": table_mc_paper_gains, "mc_cruise": table_mc_cruise,
          "mc_cruise_b": table_mc_cruise_b,
          "mc_surfaces": table_mc_surfaces, "mc_surfaces_claim": claim_mc_surfaces,
          "mc_claim": claim_mc, "bench": table_bench, "bench_compare": table_bench_compare}

_BLOCK = re.compile(r"(<!-- report:(?P<name>[a-z0-9_]+) -->\n)(?P<body>(?:.*?\n)??)"
                    r"(<!-- /report:(?P=name) -->)", re.S)


def render(text: str, root: Path = ROOT) -> tuple[str, list[str]]:
    """``text`` with every generated block rewritten; (new text, names of the blocks)."""
    names = []

    def sub(m):
        name = m.group("name")
        if name not in TABLES:
            raise KeyError(f"unknown generated table {name!r} (tools.evidence.report.TABLES)")
        names.append(name)
        return m.group(1) + TABLES[name](root) + "\n" + m.group(4)

    return _BLOCK.sub(sub, text), names


def _documents(root: Path):
    """(doc name, path, text, rendered text, block names) of each document present."""
    for doc in DOCUMENTS:
        path = Path(root) / doc
        if path.exists():
            text = path.read_text()
            new, names = render(text, root)
            yield doc, path, text, new, names


def check(root: Path = ROOT) -> list[str]:
    """The generated blocks that differ from what their data renders: ["FILE: NAME"]."""
    bad = []
    for doc, _path, text, new, _names in _documents(root):
        if new != text:
            old_blocks = {m.group("name"): m.group("body") for m in _BLOCK.finditer(text)}
            new_blocks = {m.group("name"): m.group("body") for m in _BLOCK.finditer(new)}
            bad += [f"{doc}: {n}" for n in new_blocks if new_blocks[n] != old_blocks.get(n)]
    return bad


def write(root: Path = ROOT) -> list[str]:
    """Rewrite every generated block; returns ["FILE: NAME"] of the blocks written."""
    done = []
    for doc, path, text, new, names in _documents(root):
        if new != text:
            path.write_text(new)
        done += [f"{doc}: {n}" for n in names]
    return done


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m tools.evidence.report",
                                 description=__doc__.split("\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    for kind in ("hil", "mc", "env", "bench"):
        what = {"hil": "run", "mc": "campaign", "env": "envelope map",
                "bench": "benchmark run (its --json FILE)"}[kind]
        p = sub.add_parser(f"import-{kind}", help=f"copy a {what}"
                           "'s summary.json into docs/data/NAME.json")
        p.add_argument("dir", type=Path, help="the run (or campaign) directory; import-bench: "
                       "the JSON file `python -m tools.bench --json FILE` wrote")
        p.add_argument("--as", dest="name", required=True, help="NAME of docs/data/NAME.json")
        p.add_argument("--command", required=True, help="the command that produced the run")
        p.add_argument("--commit", default=None,
                       help="the commit the run was made with (default: the run's own record, "
                            "else HEAD now)")
        p.add_argument("--created", default=None,
                       help="when the run was made, ISO UTC (default: the run's own record, "
                            "else the summary's file time)")
    sub.add_parser("write", help="rewrite every generated table from docs/data/*.json")
    sub.add_parser("check", help="exit 1 if a generated table differs from its data")
    a = ap.parse_args(argv)
    if a.cmd.startswith("import-"):
        src = a.dir if a.cmd == "import-bench" else a.dir / "summary.json"
        out = import_summary(src, a.name, a.command, a.cmd[len("import-"):],
                             commit_override=a.commit, created_override=a.created)
        print(f"wrote {out.relative_to(ROOT) if out.is_relative_to(ROOT) else out}")
        return 0
    if a.cmd == "write":
        for x in write():
            print(f"wrote {x}")
        return 0
    bad = check()
    for x in bad:
        print(f"differs from its data: {x}", file=sys.stderr)
    return 1 if bad else 0


if __name__ == "__main__":
    raise SystemExit(main())
