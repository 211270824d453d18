"""Guidance + the paper's law + the plant in process (tools.sitl.closed_loop.guided): short seeded flights
from the cruise point, one per target. Sensors and the fc's estimator in the loop."""
from __future__ import annotations

import math

import numpy as np
import pytest

from fc.guidance import layout as G
from tools.sitl.closed_loop.guided import fly, hold_then_step

DEG = math.pi / 180.0
H0, V0 = 28000.0, 2250.0


def _fly(duration_s, law_overrides=None, **step):
    tl = hold_then_step(H0, 0.0, V0, 1.0, **step)
    res = fly("cruise", duration_s=duration_s, targets=tl, seed=3, record_every=10,
              law_overrides=law_overrides)
    assert not res.diverged
    assert res.hold_figures()["surface_at_limit_s"] == 0.0
    return res


def test_hold_keeps_altitude_course_and_speed():
    res = _fly(20.0)
    f = res.hold_figures(2.0)
    assert f["alt_err_max_m"] < 5.0
    assert f["course_err_max_deg"] < 0.05
    assert f["speed_err_max_m_s"] < 1.0
    assert max(f["inner_e1_max_deg"]) < 0.2


def test_altitude_target_climbs_within_the_load_factor_limit():
    res = _fly(15.0, d_h_m=2000.0)
    gam = res.col("gamma_rad")
    assert gam[-1] > 0.5 * DEG and res.col("h_m")[-1] > H0 + 30.0
    assert res.cmd[-1, G.GO_ALPHA] > res.cmd[0, G.GO_ALPHA] - 0.5 * DEG
    # the achieved load factor (the truth's, 50 Hz) stays below GE_NZ_MAX 1.6: the demand
    # stops GE_NZ_MARGIN (0.05) inside it, room for the inner loop's scatter about the demand
    nz = res.load_factor()[5:-5]
    assert nz.max() < 1.6 and nz.max() > 1.5
    assert res.col("nz_c").max() == pytest.approx(1.6 - 0.05)


#: the highest achieved bank allowed, deg: with the paper's fixed gains at least half the
#: guidance's 0.2 deg margin below GE_MU_MAX 30 deg stays free; the scheduled law (issue 20,
#: lower inner-loop gain at 63 kPa) uses the margin (measured 29.90 deg) but stays below 30
MU_MAX_DEG = {"scheduled": 30.0, "paper gains": 29.9}


@pytest.mark.parametrize("law", list(MU_MAX_DEG))
def test_course_target_banks_and_turns_the_right_way(law):
    res = _fly(15.0, {"CTL_SCHED": 0} if law == "paper gains" else None, d_chi_rad=30.0 * DEG)
    mu = res.col("mu_rad")
    # the achieved bank (truth) reaches GE_MU_MAX 30 deg less its margin (0.2 deg)
    assert mu.max() > 29.5 * DEG and mu.max() < MU_MAX_DEG[law] * DEG
    chi = np.unwrap(res.col("chi_rad"))
    assert chi[-1] - chi[0] > 0.5 * DEG
    assert abs(res.col("beta_rad")).max() < 0.3 * DEG                          # coordinated


def test_speed_target_opens_the_throttle_and_accelerates():
    res = _fly(15.0, d_V_m_s=100.0)
    assert res.cmd[-1, 4] > res.cmd[0, 4] + 0.1                      # throttle position
    assert res.col("V_m_s")[-1] > V0 + 10.0
    assert np.all(np.diff(res.col("V_ref_m_s")) <= 1.5 * 0.02 + 1e-9)   # GS_ACC_MAX per 20 ms
