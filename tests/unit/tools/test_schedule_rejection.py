"""The scheduled law rejects the paper's d(t) at the paper's point (issue 20: the campaigns'
final-error spec is 0.1 deg, docs/montecarlo.md).

The paper's case climbs: the law's dynamic pressure falls from 183 kPa to about 97 kPa by
t = 20 s, so the final error (max |error| over the last second) is that of the 100 kPa node.
In process, the fc's estimator on the scenario's seeded sensor noise, the full 20 s.
Measured (seed 0; final error alpha / beta / mu deg): the schedule designed without a
rejection target 0.112 / 0.112 / 0.052 (co), 0.104 / 0.114 / 0.055 (unco); with the target
(tools.schedule_design DIST_ERR_MAX_RAD) 0.070 / 0.071 / 0.035, 0.077 / 0.071 / 0.036.
"""
from __future__ import annotations

import pytest

from tools.sitl.closed_loop import simulate

SEED = 0
#: between the two measurements above, below the campaigns' 0.1 deg spec
FINAL_ERROR_MAX_DEG = 0.09
#: the paper's spec, kept while the gains rise
OVERSHOOT_MAX_PCT = 10.0


@pytest.mark.parametrize("coordinated", [True, False], ids=["co", "unco"])
def test_scheduled_law_rejects_the_papers_disturbance_at_the_papers_point(coordinated):
    res = simulate("paper", coordinated=coordinated, seed=SEED, estimate="sensors")
    assert not res.diverged
    m = res.metrics()
    for name in ("alpha", "beta", "mu"):
        c = m[name]
        assert c.final_error_deg < FINAL_ERROR_MAX_DEG, (name, c)
        assert c.overshoot_pct is not None and c.overshoot_pct <= OVERSHOOT_MAX_PCT, (name, c)


#: the 1000-case paper campaign's worst case on the schedule before the grid's refinement
#: (tools.schedule_design GRID, 2026-11-26): seed 1, case 973 (the roll moment coefficient
#: x 0.817), uncoordinated mu final error 0.112 deg, coordinated 0.110; 0.090 / 0.087 after
CAMPAIGN_SEED = 1
WORST_CASE = 973


@pytest.mark.parametrize("variant", ["coordinated", "uncoordinated"])
def test_the_campaigns_worst_dispersed_case_meets_the_final_error_spec(variant):
    """The dispersed case that failed the paper campaign's 0.1 deg final-error spec (mu) flies
    within it: the 100 kPa node, where the case's last second is flown, rejects d(t) better
    (docs/control_law.md s. 13, "The refined grid")."""
    from tools.evidence.montecarlo import case as C
    from tools.evidence.montecarlo import dispersions as dsp
    d = dsp.load("paper")
    cfg = C.CampaignConfig(scenario="paper", dispersions_text=d.source_text,
                           dispersions_name=d.name, seed=CAMPAIGN_SEED, variants=(variant,))
    values, _seed, fl = C.fly_case(cfg, WORST_CASE, variant)
    assert values["aero.Cl"] < 0.85                 # the case is the weak-roll corner it was
    m = C.flight_metrics(fl)
    assert not m["diverged"]
    for ch, c in m["channels"].items():
        assert c.final_error_deg < 0.1, (ch, c)


#: the authority axis off: the gains of the plain dynamic pressure (docs/control_law.md s. 13,
#: "The authority axis")
AUTH_OFF = {f"SCH_AUTH_{i}": 1.0 for i in range(1, 7)}


@pytest.mark.parametrize("coordinated", [True, False], ids=["co", "unco"])
def test_at_the_cruise_the_authority_axis_rejects_the_papers_fixed_disturbance(coordinated):
    """The paper's d(t) at its 183 kPa size, flown at the cruise (Mach 7.5 / 28 km, 63 kPa:
    three times the relative disturbance). The gains looked up at qbar x SCH_AUTH (about 93
    kPa there) leave less than 0.09 deg in every channel; looked up at the plain 63 kPa they
    leave more in beta. Measured (seed 0, worst channel): 0.074 co / 0.073 unco deg with the
    axis, 0.111 / 0.110 without."""
    res = simulate("paper_cruise", coordinated=coordinated, seed=SEED, estimate="sensors")
    assert not res.diverged
    m = res.metrics()
    for name in ("alpha", "beta", "mu"):
        assert m[name].final_error_deg < FINAL_ERROR_MAX_DEG, (name, m[name])
        assert m[name].overshoot_pct <= OVERSHOOT_MAX_PCT, (name, m[name])
    off = simulate("paper_cruise", coordinated=coordinated, seed=SEED, estimate="sensors",
                   law_overrides=AUTH_OFF).metrics()
    assert max(off[n].final_error_deg for n in ("alpha", "beta", "mu")) > 0.1
