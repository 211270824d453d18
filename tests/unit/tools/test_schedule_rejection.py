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
