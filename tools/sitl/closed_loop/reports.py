"""Text reports of attitude flights in process (tools.sitl.closed_loop.core.simulate): one
summary line per flight, a markdown table of both variants with steps and with the prefilter,
and a coordinated-vs-uncoordinated comparison over perturbed copies of a scenario. The
command that prints them is ``python -m tools.fly attitude`` (tools/fly.py).
"""
from __future__ import annotations

import numpy as np

from plant_sim.scenario import Scenario, load
from tools.sitl.closed_loop.core import ClosedLoopResult, simulate


def summary_line(res: ClosedLoopResult) -> str:
    """One line of figures (overshoot %, settling s, final error deg, peak surfaces deg)."""
    m = res.metrics()

    def f(v, fmt):
        return "-" if v is None else format(v, fmt)

    parts = [f"{res.scenario} {'co' if res.coordinated else 'unco'} {res.command_shaping}:"]
    for ch in ("alpha", "beta", "mu"):
        c = m[ch]
        parts.append(f"{ch} os {f(c.overshoot_pct, '.1f')}% ts {f(c.settling_time_s, '.2f')}s "
                     f"fe {c.final_error_deg:.3f}")
    pk = m["surfaces"]["peak_deg"]
    parts.append(f"peak L/R/rud {pk['left_elevon']:.1f}/{pk['right_elevon']:.1f}/"
                 f"{pk['rudder']:.1f} deg sat {m['surfaces']['saturated_s']:.2f}s")
    if res.diverged:
        parts.append("DIVERGED")
    return " | ".join(parts)


def markdown_table(scenario, duration_s=None, law_overrides=None, estimate="truth") -> str:
    """Markdown table of the figures of both variants with steps and with the prefilter."""
    def f(v, fmt):
        return "-" if v is None else format(v, fmt)

    rows = ["| shaping | variant | alpha os % / ts s | beta os % / ts s | mu os % / ts s | "
            "final err a/b/m deg | peak L/R/rud deg | sat s |",
            "|---|---|---|---|---|---|---|---|"]
    for shaping in ("steps", "prefilter"):
        for co in (True, False):
            res = simulate(scenario, coordinated=co, duration_s=duration_s,
                           command_shaping=shaping, law_overrides=law_overrides,
                           estimate=estimate)
            m = res.metrics()
            cells = [f"{f(m[c].overshoot_pct, '.1f')} / {f(m[c].settling_time_s, '.2f')}"
                     for c in ("alpha", "beta", "mu")]
            fe = "/".join(f"{m[c].final_error_deg:.3f}" for c in ("alpha", "beta", "mu"))
            pk = m["surfaces"]["peak_deg"]
            rows.append(f"| {shaping} | {'coordinated' if co else 'uncoordinated'}"
                        f"{' (DIVERGED)' if res.diverged else ''} | " + " | ".join(cells)
                        + f" | {fe} | {pk['left_elevon']:.1f}/{pk['right_elevon']:.1f}/"
                        f"{pk['rudder']:.1f} | {m['surfaces']['saturated_s']:.2f} |")
    return "\n".join(rows)


def perturbed_comparison(n: int = 40, seed: int = 7, command_shaping: str = "steps",
                         law_overrides: dict | None = None, scenario: str = "paper") -> str:
    """Coordinated vs uncoordinated over ``n`` perturbed copies of ``scenario``.

    Each draw (numpy Generator seeded with ``seed``): every coefficient uncertainty
    (CL, CD, CY, Cl, Cm, Cn) uniform in +-30 %, initial sideslip uniform in +-5 deg,
    disturbance scale uniform in 0.5..1.5. Returns a text summary (the figures of
    docs/control_law.md section 9). A quick look, not a campaign: tools.evidence.montecarlo is that.
    """
    import copy
    base = load(scenario)
    rng = np.random.default_rng(seed)
    rows = {True: [], False: []}
    diverged = {True: 0, False: 0}
    for i in range(n):
        d = copy.deepcopy(base.data)
        for k in ("CL", "CD", "CY", "Cl", "Cm", "Cn"):
            d["uncertainty"][k] = float(rng.uniform(-0.3, 0.3))
        d["initial"]["beta_deg"] = float(rng.uniform(-5.0, 5.0))
        d["disturbance"]["scale"] = float(rng.uniform(0.5, 1.5))
        sc = Scenario(name=f"{scenario}-draw{i}", path=base.path, data=d,
                      commands=list(base.commands))
        for co in (True, False):
            res = simulate(sc, coordinated=co, command_shaping=command_shaping,
                           law_overrides=law_overrides)
            m = res.metrics()
            diverged[co] += res.diverged
            rows[co].append([np.nan if m[c].overshoot_pct is None else m[c].overshoot_pct
                             for c in ("alpha", "beta", "mu")]
                            + [max(m[c].final_error_deg for c in ("alpha", "beta", "mu")),
                               m["surfaces"]["saturated_s"]])
    co = np.array(rows[True])
    un = np.array(rows[False])
    out = [f"{n} draws of {scenario}, {command_shaping}: diverged co {diverged[True]} "
           f"unco {diverged[False]}; worst final error co {np.nanmax(co[:, 3]):.3f} unco "
           f"{np.nanmax(un[:, 3]):.3f} deg; max saturated co {np.nanmax(co[:, 4]):.2f} unco "
           f"{np.nanmax(un[:, 4]):.2f} s"]
    for j, ch in enumerate(("alpha", "beta", "mu")):
        ok = ~np.isnan(co[:, j]) & ~np.isnan(un[:, j])
        out.append(f"{ch} overshoot %: median co {np.median(co[ok, j]):.1f} unco "
                   f"{np.median(un[ok, j]):.1f}; max co {np.max(co[ok, j]):.1f} unco "
                   f"{np.max(un[ok, j]):.1f}; co lower in {int(np.sum(co[ok, j] < un[ok, j]))}"
                   f"/{int(ok.sum())}")
    return "\n".join(out)
