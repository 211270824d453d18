"""tools/evidence/coordination.py - what the coordinated factors do, factor by factor (issue 15, point 2).

One command flies every configuration of the study and writes its rows and a summary::

    python -m tools.evidence.coordination --out runs/coord            # paper case + dispersed cases
    python -m tools.evidence.coordination --out runs/coord --cases 0  # the paper case only (seconds)

A *configuration* is (factor set, reading, sideslip sign, rate-command limit):

- factor set (:data:`FACTOR_SETS`): the uncoordinated baseline, all factors, each factor on
  alone and off alone (lambda_e, lambda_a, lambda_r through the gains k1..k9 of Eqs. 10-14/19),
  and the surface-coordination degree E of Eq. 47 (``CO_SURF`` 1; it does nothing at the
  default ``CO_SURF`` 0);
- reading (:data:`READINGS`): the factors of Eq. 14 or of Eq. 19, k8 = k9 = 1 or 0, the
  disturbance observer fed the achieved moment or M_c (``DOB_ACHIEVED``). Every reading sets
  each of those parameters explicitly, so the rows do not depend on the law's defaults;
- sign (:data:`SIGNS`): the paper's (beta0, mu_c) = (+5, +4) deg and its mirror (-5, -4);
- ``SLW_OMC_MAX``: the 3 deg/s rate-command limit of deviation V1 and looser values.

The paper case is flown in process with the law fed the plant's truth (tools.sitl.closed_loop,
as docs/control_law.md's figures). Dispersed cases are those of ``tools.evidence.montecarlo`` (the
``paper`` dispersion file, campaign seed ``--seed``; case i is the montecarlo's case i), flown
with the sensors and the fc's estimator in the loop, as the montecarlo's closed-loop backend
does; every configuration flies the same cases, so coordinated and uncoordinated are compared
case by case. The runs are Dask tasks on a LocalCluster (``--workers``; 0 = in this process).
"""
from __future__ import annotations

import argparse
import copy
import csv
import json
import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

CHANNELS = ("alpha", "beta", "mu")
SURFACES = ("left_elevon", "right_elevon", "rudder")

_K_E = ("CO_K4", "CO_K5")                        # lambda_e (Eq. 14/19)
_K_A = ("CO_K6", "CO_K7")                        # lambda_a (Eq. 14/19)
_K_R = ("CO_K1", "CO_K2", "CO_K3", "CO_K8", "CO_K9")   # lambda_r (Eqs. 10-13 + lambda_r3)


def _zero(*groups) -> dict:
    return {k: 0.0 for g in groups for k in g}


#: name -> (coordinated, parameter overrides applied after the reading's)
FACTOR_SETS: dict[str, tuple[bool, dict]] = {
    "none": (False, {}),
    "all": (True, {}),
    "e_only": (True, _zero(_K_A, _K_R)),
    "a_only": (True, _zero(_K_E, _K_R)),
    "r_only": (True, _zero(_K_E, _K_A)),
    "no_e": (True, _zero(_K_E)),
    "no_a": (True, _zero(_K_A)),
    "no_r": (True, _zero(_K_R)),
    "E_only": (True, {**_zero(_K_E, _K_A, _K_R), "CO_SURF": 1.0}),
    "all_E": (True, {"CO_SURF": 1.0}),
}

#: name -> the parameters that decide the paper's reading (set explicitly every time)
READINGS: dict[str, dict] = {
    "eq14": {"CO_FAC_EQ": 14.0, "CO_K8": 1.0, "CO_K9": 1.0, "DOB_ACHIEVED": 1.0},
    "eq19": {"CO_FAC_EQ": 19.0, "CO_K8": 1.0, "CO_K9": 1.0, "DOB_ACHIEVED": 1.0},
    "eq19_k89_0": {"CO_FAC_EQ": 19.0, "CO_K8": 0.0, "CO_K9": 0.0, "DOB_ACHIEVED": 1.0},
    "eq14_dobMc": {"CO_FAC_EQ": 14.0, "CO_K8": 1.0, "CO_K9": 1.0, "DOB_ACHIEVED": 0.0},
    "eq19_dobMc": {"CO_FAC_EQ": 19.0, "CO_K8": 1.0, "CO_K9": 1.0, "DOB_ACHIEVED": 0.0},
}

#: name -> (initial sideslip beta0 deg, bank command mu_c deg)
SIGNS: dict[str, tuple[float, float]] = {"pos": (5.0, 4.0), "neg": (-5.0, -4.0)}

#: parameters that do nothing in the uncoordinated law (dropped from its key: one run serves all)
_CO_ONLY = ("CO_FAC_EQ", "CO_SURF") + _K_E + _K_A + _K_R


@dataclass(frozen=True)
class Config:
    """One configuration of the study (small, picklable)."""

    factors: str
    reading: str
    sign: str
    omc_max_deg_s: float

    def overrides(self) -> dict:
        """The law's parameter overrides (table units) and the coordinated flag."""
        co, extra = FACTOR_SETS[self.factors]
        ov = dict(READINGS[self.reading])
        ov.update(extra)
        ov["SLW_OMC_MAX"] = float(self.omc_max_deg_s)
        if not co:
            for k in _CO_ONLY:
                ov.pop(k, None)
        return ov

    @property
    def coordinated(self) -> bool:
        return FACTOR_SETS[self.factors][0]

    def label(self) -> str:
        return f"{self.factors}/{self.reading}/{self.sign}/{self.omc_max_deg_s:g}"


def signed_scenario(base, sign: str):
    """``base`` with the initial sideslip and the bank command of ``sign`` (SIGNS)."""
    from plant_sim.scenario import Scenario
    beta0, mu_c = SIGNS[sign]
    data = copy.deepcopy(base.data)
    data["initial"]["beta_deg"] = beta0
    cmds = [(t, a, b, math.copysign(abs(m), mu_c) if m else m) for t, a, b, m in base.commands]
    return Scenario(name=f"{base.name}-{sign}", path=base.path, data=data, commands=cmds)


def run_metrics(res) -> dict:
    """Figures of one flight (tools.sitl.closed_loop.ClosedLoopResult) as a flat dict.

    Per channel: overshoot %, settling s, wrong-way dip (undershoot) %, final error deg.
    Surfaces: peak deg per surface, time on a limit s, usage = sum over surfaces of the
    time integral of |delta| (deg s) and travel = sum of |delta(k+1) - delta(k)| (deg).
    """
    m = res.metrics()
    row = {"diverged": bool(res.diverged)}
    for ch in CHANNELS:
        c = m[ch]
        row[f"{ch}_os_pct"] = _f(c.overshoot_pct)
        row[f"{ch}_ts_s"] = _f(c.settling_time_s)
        row[f"{ch}_dip_pct"] = _f(c.undershoot_pct)
        row[f"{ch}_fe_deg"] = _f(c.final_error_deg)
    for i, s in enumerate(SURFACES):
        row[f"peak_{s}_deg"] = float(m["surfaces"]["peak_deg"][s])
    row["sat_s"] = float(m["surfaces"]["saturated_s"])
    d = np.degrees(res.delta_rad)
    t = res.t_s
    row["usage_deg_s"] = float(np.sum(np.abs(d[:-1]).T * np.diff(t))) if len(t) > 1 else 0.0
    row["travel_deg"] = float(np.sum(np.abs(np.diff(d, axis=0))))
    return row


def _f(v) -> float:
    return math.nan if v is None else float(v)


def fly(cfg: Config, case: int | None, campaign_seed: int = 1, duration_s: float = 20.0) -> dict:
    """One run: the paper case (``case`` None, truth) or dispersed case ``case`` (sensors)."""
    from tools.sitl.closed_loop import simulate
    base, seed, est = _scenario_for(case, campaign_seed)
    sc = signed_scenario(base, cfg.sign)
    res = simulate(sc, coordinated=cfg.coordinated, duration_s=duration_s, seed=seed,
                   law_overrides=cfg.overrides(), command_shaping="steps", estimate=est)
    row = {"factors": cfg.factors, "reading": cfg.reading, "sign": cfg.sign,
           "omc_max_deg_s": cfg.omc_max_deg_s, "case": -1 if case is None else int(case)}
    row.update(run_metrics(res))
    return row


def _scenario_for(case, campaign_seed):
    from tools.evidence.montecarlo import case as mc_case
    if case is None:
        return mc_case._base_scenario("paper"), None, "truth"
    cc = _campaign_config(campaign_seed)
    values, sim_seed = mc_case.case_values(cc, int(case))
    return mc_case.dispersed_scenario(cc, values), sim_seed, "sensors"


def _campaign_config(campaign_seed: int):
    from tools.evidence.montecarlo import dispersions as dsp
    from tools.evidence.montecarlo.case import CampaignConfig
    path = dsp.resolve_path("paper")
    return CampaignConfig(scenario="paper", dispersions_text=path.read_text(),
                          dispersions_name="paper", seed=int(campaign_seed))


def fly_chunk(cfg: Config, cases: list, campaign_seed: int = 1) -> list[dict]:
    """The Dask task: ``cfg`` over ``cases`` (None = the paper case)."""
    return [fly(cfg, c, campaign_seed) for c in cases]


def configurations(factors=None, readings=None, signs=None, limits=(3.0, 5.0, 10.0)) -> list:
    """Every Config of the cross product, the uncoordinated ones de-duplicated (their key
    ignores the factor parameters, so one uncoordinated run per DOB reading serves all)."""
    out, seen = [], set()
    for f in factors or FACTOR_SETS:
        for r in readings or READINGS:
            for s in signs or SIGNS:
                for lim in limits:
                    c = Config(f, r, s, float(lim))
                    key = (c.coordinated, tuple(sorted(c.overrides().items())), s)
                    if key in seen:
                        continue
                    seen.add(key)
                    out.append(c)
    return out


def run_study(configs: list, cases: list, campaign_seed: int = 1, workers: int = 2,
              chunk: int = 25, progress=None) -> list[dict]:
    """Fly every config over ``cases``; Dask LocalCluster with ``workers`` (0 = in process)."""
    tasks = [(c, cases[i:i + chunk]) for c in configs for i in range(0, len(cases), chunk)]
    rows: list[dict] = []
    if workers <= 0:
        for k, (c, cs) in enumerate(tasks):
            rows += fly_chunk(c, cs, campaign_seed)
            if progress:
                progress(k + 1, len(tasks))
        return rows
    from distributed import as_completed
    from tools.evidence.montecarlo.campaign import cluster_client
    with cluster_client(workers) as client:
        futs = [client.submit(fly_chunk, c, cs, campaign_seed, pure=False) for c, cs in tasks]
        for k, fut in enumerate(as_completed(futs)):
            rows += fut.result()
            if progress:
                progress(k + 1, len(tasks))
    return rows


# ------------------------------------------------------------------------ summaries
def _paired(rows: list[dict]) -> dict:
    """{(reading, sign, limit, case): row of the uncoordinated run with that DOB input}."""
    base = {}
    for r in rows:
        if r["factors"] == "none":
            dob = READINGS[r["reading"]]["DOB_ACHIEVED"]
            base[(dob, r["sign"], r["omc_max_deg_s"], r["case"])] = r
    return base


def _base_of(base: dict, r: dict):
    return base.get((READINGS[r["reading"]]["DOB_ACHIEVED"], r["sign"], r["omc_max_deg_s"],
                     r["case"]))


def paper_table(rows: list[dict], factors=None, readings=None, limits=None) -> str:
    """Markdown: the paper case, one row per configuration (optionally only those factor sets,
    readings, limits), travel with the uncoordinated run's difference."""
    rows = [r for r in rows if r["case"] == -1]
    base = _paired(rows)
    rows = [r for r in rows if (factors is None or r["factors"] in factors)
            and (readings is None or r["reading"] in readings or r["factors"] == "none")
            and (limits is None or r["omc_max_deg_s"] in limits)]
    out = ["| limit deg/s | sign | reading | factors | os a/b/m % | ts a/b/m s | dip a/b/m % | "
           "peak L/R/rud deg | travel deg (co - unco) | diverged |", "|---|---|---|---|---|---|---|---|---|---|"]
    key = lambda r: (r["omc_max_deg_s"], r["sign"], r["reading"], list(FACTOR_SETS).index(r["factors"]))
    for r in sorted(rows, key=key):
        b = _base_of(base, r)
        if r["factors"] == "none" and r["reading"] not in ("eq14", "eq14_dobMc"):
            continue

        def tri(k, fmt=".1f"):
            return "/".join("-" if math.isnan(r[f"{c}_{k}"]) else format(r[f"{c}_{k}"], fmt)
                            for c in CHANNELS)
        du = "" if b is None or r is b else f" ({r['travel_deg'] - b['travel_deg']:+.0f})"
        reading = r["reading"]
        if r["factors"] == "none":
            reading = "dob M_c" if READINGS[r["reading"]]["DOB_ACHIEVED"] < 0.5 else "dob achieved"
        out.append(f"| {r['omc_max_deg_s']:g} | {r['sign']} | {reading} | {r['factors']} | "
                   f"{tri('os_pct')} | {tri('ts_s', '.2f')} | {tri('dip_pct')} | "
                   f"{r['peak_left_elevon_deg']:.1f}/{r['peak_right_elevon_deg']:.1f}/"
                   f"{r['peak_rudder_deg']:.1f} | {r['travel_deg']:.0f}{du} | "
                   f"{'yes' if r['diverged'] else ''} |")
    return "\n".join(out)


def dispersed_table(rows: list[dict]) -> str:
    """Markdown: per configuration over the dispersed cases, paired with the uncoordinated
    run of the same case: medians, and the share of cases where coordination is later / larger."""
    rows = [r for r in rows if r["case"] >= 0]
    base = _paired(rows)
    groups: dict = {}
    for r in rows:
        if r["factors"] == "none":
            continue
        groups.setdefault((r["omc_max_deg_s"], r["sign"], r["reading"], r["factors"]), []).append(r)
    out = ["| limit | sign | reading | factors | N | div co/unco | med os a/b/m % (unco) | "
           "os higher a/b/m % of cases | med ts a/b/m s (unco) | ts later a/b/m % of cases | "
           "med dip b/m % (unco) | med travel deg (unco) |",
           "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for key in sorted(groups, key=lambda k: (k[0], k[1], k[2], list(FACTOR_SETS).index(k[3]))):
        rs = groups[key]
        bs = [_base_of(base, r) for r in rs]
        pairs = [(r, b) for r, b in zip(rs, bs) if b is not None]
        if not pairs:
            continue
        n = len(pairs)
        dco = sum(r["diverged"] for r, _ in pairs)
        dun = sum(b["diverged"] for _, b in pairs)

        def med(k, which):
            v = np.array([(r if which == 0 else b)[k] for r, b in pairs], float)
            v = v[~np.isnan(v)]
            return math.nan if v.size == 0 else float(np.median(v))

        def share(k):
            # a NaN settling (never settled) counts as later than any number
            a = np.array([r[k] for r, _ in pairs], float)
            u = np.array([b[k] for _, b in pairs], float)
            a = np.where(np.isnan(a), np.inf, a)
            u = np.where(np.isnan(u), np.inf, u)
            ok = ~(np.isinf(a) & np.isinf(u))
            return 100.0 * float(np.mean(a[ok] > u[ok])) if ok.any() else math.nan

        def cell(k, fmt):
            return "/".join(f"{med(f'{c}_{k}', 0):{fmt}}" for c in CHANNELS) + " (" + \
                "/".join(f"{med(f'{c}_{k}', 1):{fmt}}" for c in CHANNELS) + ")"
        out.append(
            f"| {key[0]:g} | {key[1]} | {key[2]} | {key[3]} | {n} | {dco}/{dun} | "
            f"{cell('os_pct', '.1f')} | "
            + "/".join(f"{share(f'{c}_os_pct'):.0f}" for c in CHANNELS) + " | "
            f"{cell('ts_s', '.2f')} | "
            + "/".join(f"{share(f'{c}_ts_s'):.0f}" for c in CHANNELS) + " | "
            f"{med('beta_dip_pct', 0):.1f}/{med('mu_dip_pct', 0):.1f} "
            f"({med('beta_dip_pct', 1):.1f}/{med('mu_dip_pct', 1):.1f}) | "
            f"{med('travel_deg', 0):.0f} ({med('travel_deg', 1):.0f}) |")
    return "\n".join(out)


def write_rows(path: Path, rows: list[dict]) -> None:
    if not rows:
        return
    keys = list(rows[0]) + sorted({k for r in rows for k in r} - set(rows[0]))
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=keys, restval="")
        w.writeheader()
        w.writerows(rows)


def read_csv_rows(path: Path, text_keys=(), int_keys=()) -> list[dict]:
    """Rows written by :func:`write_rows`: text keys as str, "True"/"False" as bool, int keys
    as int, everything else float ("" -> NaN)."""
    out = []
    with open(path, newline="") as fh:
        for r in csv.DictReader(fh):
            d = {}
            for k, v in r.items():
                if k in text_keys:
                    d[k] = v
                elif v in ("True", "False"):
                    d[k] = v == "True"
                elif k in int_keys:
                    d[k] = int(v)
                else:
                    d[k] = float(v) if v != "" else math.nan
            out.append(d)
    return out


def read_rows(path: Path) -> list[dict]:
    return read_csv_rows(path, ("factors", "reading", "sign"), ("case",))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m tools.evidence.coordination", description=__doc__.split("\n")[0])
    ap.add_argument("--out", type=Path, default=Path("runs/coord"),
                    help="output directory for the tables and JSON (default runs/coord)")
    ap.add_argument("--cases", type=int, default=200,
                    help="dispersed cases per configuration (0 = the paper case only; 200)")
    ap.add_argument("--seed", type=int, default=1, help="tools.evidence.montecarlo campaign seed (1)")
    ap.add_argument("--workers", type=int, default=2, help="Dask workers (0 = in process)")
    ap.add_argument("--limits", default="3,5,10", help="SLW_OMC_MAX values, deg/s (3,5,10)")
    ap.add_argument("--dispersed-limits", default="3,5",
                    help="SLW_OMC_MAX values for the dispersed cases (3,5)")
    ap.add_argument("--dispersed-factors", default="none,all,e_only,a_only,r_only,no_a,all_E",
                    help="comma-separated factor sets flown over the dispersed cases")
    ap.add_argument("--dispersed-readings", default="eq14,eq19,eq19_k89_0",
                    help="comma-separated readings of the paper flown over the dispersed cases")
    ap.add_argument("--summary-only", action="store_true",
                    help="re-make summary.md from the rows already in --out")
    a = ap.parse_args(argv)
    a.out.mkdir(parents=True, exist_ok=True)
    lim = [float(x) for x in a.limits.split(",")]
    dlim = [float(x) for x in a.dispersed_limits.split(",")]
    t0 = time.perf_counter()
    if not a.summary_only:
        paper_cfgs = configurations(limits=lim)
        rows = run_study(paper_cfgs, [None], a.seed, workers=0)
        write_rows(a.out / "paper.csv", rows)
        print(f"paper case: {len(rows)} runs in {time.perf_counter() - t0:.1f} s", flush=True)
        if a.cases > 0:
            dcfgs = configurations(a.dispersed_factors.split(","),
                                   a.dispersed_readings.split(","), limits=dlim)
            t1 = time.perf_counter()
            last = [0.0]

            def prog(k, n):
                if time.perf_counter() - last[0] > 30 or k == n:
                    last[0] = time.perf_counter()
                    print(f"dispersed: {k}/{n} tasks, {last[0] - t1:.0f} s", flush=True)
            drows = run_study(dcfgs, list(range(a.cases)), a.seed, workers=a.workers,
                              progress=prog)
            write_rows(a.out / "dispersed.csv", drows)
            info = {"configs": len(dcfgs), "cases": a.cases, "runs": len(drows),
                    "wall_s": time.perf_counter() - t1, "workers": a.workers, "seed": a.seed}
            (a.out / "dispersed.json").write_text(json.dumps(info, indent=1))
            print(f"dispersed: {len(drows)} runs in {info['wall_s']:.0f} s", flush=True)
    text = ["# Coordination study", "", "## Paper case (truth, steps)", "",
            paper_table(read_rows(a.out / "paper.csv"))]
    if (a.out / "dispersed.csv").exists():
        text += ["", "## Dispersed cases (tools.evidence.montecarlo paper dispersions, sensors)", "",
                 dispersed_table(read_rows(a.out / "dispersed.csv"))]
    (a.out / "summary.md").write_text("\n".join(text) + "\n")
    print(f"wrote {a.out / 'summary.md'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
