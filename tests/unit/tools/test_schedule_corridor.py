"""The gain-scheduled law (the default since issue 20) flies the paper's case across the
corridor: in process, the fc's estimator on the scenario's seeded sensor noise, the paper's
d(t) as a moment coefficient (tools.evidence.envelope map b: it scales with dynamic pressure).

Measured (seed 3, 20 s; overshoot % / final error deg, worst channel), scheduled vs the
paper's fixed gains (CTL_SCHED 0):
    Mach 8 / 26 km (98 kPa)     co 3.9 / 0.068   unco 3.5 / 0.068   paper gains 20 / 0.15, 17 / 0.15
    Mach 7.5 / 28 km (64 kPa)   co 7.1 / 0.071   unco 6.6 / 0.072   paper gains 28 / 0.84, 20 / 0.58
    Mach 8 / 30 km (54 kPa)     co 8.3 / 0.075   unco 7.8 / 0.076   paper gains 26 / 0.56, 24 / 0.77
The paper's gains overshoot 17-28 % in mu and at 64 and 54 kPa end in a lateral limit cycle
(final errors 0.3-0.8 deg): every bound below fails with them (the last test checks it at
54 kPa).
"""
from __future__ import annotations

import pytest

from tools.evidence.envelope import point_scenario
from tools.sitl.closed_loop import simulate

POINTS = [(8.0, 26e3), (7.5, 28e3), (8.0, 30e3)]
DURATION_S = 12.0
SEED = 3
#: the paper's spec bound on overshoot (issue 20), and a final error below the 0.2 deg
#: settling band of the 4-5 deg steps (measured 0.03-0.08 deg)
OVERSHOOT_MAX_PCT = 10.0
FINAL_ERROR_MAX_DEG = 0.12
#: every channel inside its band by then (measured mu 5.1-6.0 s at 54-64 kPa, others < 3 s)
SETTLING_MAX_S = 8.0


def _fly(mach, h_m, coordinated, overrides=None):
    sc = point_scenario(mach, h_m, disturbance="coefficient")
    res = simulate(sc, coordinated=coordinated, duration_s=DURATION_S, seed=SEED,
                   estimate="sensors", law_overrides=overrides)
    return res, res.metrics()


@pytest.mark.parametrize("coordinated", [True, False], ids=["co", "unco"])
@pytest.mark.parametrize("point", POINTS, ids=lambda p: f"M{p[0]:g}-{p[1] / 1e3:g}km")
def test_scheduled_law_meets_the_spec_across_the_corridor(point, coordinated):
    res, m = _fly(*point, coordinated)
    assert not res.diverged
    for name in ("alpha", "beta", "mu"):
        c = m[name]
        assert c.overshoot_pct is not None and c.overshoot_pct <= OVERSHOOT_MAX_PCT, (name, c)
        assert c.final_error_deg < FINAL_ERROR_MAX_DEG, (name, c)
        assert c.settling_time_s is not None and c.settling_time_s < SETTLING_MAX_S, (name, c)
    # a surface touches its limit for 0.03-0.07 s in the first transient at 54-64 kPa (the
    # initial 5 deg sideslip); bound as the paper case's tests (test_closed_loop.py)
    assert m["surfaces"]["saturated_s"] < 0.2


def test_the_papers_gains_fail_these_bounds_at_54_kpa():
    """The comparison the bounds were chosen against: the same flight with CTL_SCHED 0."""
    res, m = _fly(8.0, 30e3, True, {"CTL_SCHED": 0})
    worst_os = max(m[n].overshoot_pct or 0.0 for n in ("alpha", "beta", "mu"))
    worst_final = max(m[n].final_error_deg for n in ("alpha", "beta", "mu"))
    assert res.diverged or worst_os > OVERSHOOT_MAX_PCT or worst_final > FINAL_ERROR_MAX_DEG


def test_the_mach_factor_keeps_the_yaw_downward_gain_margin_at_mach_15():
    """Issue 20 item 1: at Mach 15 / 28 km (255 kPa, the airframe directionally unstable,
    Cn_beta -0.064) the yaw loop with its gain about trim cut to 0.5 (-6 dB; tools.evidence.margins's
    gain_ac, the paper's case from a 2 deg initial sideslip) stays stable with the rate-command
    limit's Mach factor, and diverges without it (SCH_OMCF_n = 1, the schedule before: the
    rudder command runs to its limit and the sideslip grows; measured -5.1 dB there). The
    allocation's yaw escalation (ALLOC_YAW_T, added later) also rescues that flight on its own,
    since the rudder alone sits on its limit there; so the comparison turns it off: the Mach
    factor alone keeps the loop stable, and without both it diverges."""
    from tools.evidence.margins import inproc as M
    sc = M.margin_scenario(point=(15.0, 28e3), initial_beta_deg=2.0)
    cut = M.make_inj("gain_ac", "yaw", gain=0.5)
    assert M.stable(M.fly(sc, cut, coordinated=False))
    assert M.stable(M.fly(sc, cut, coordinated=False, law_overrides={"ALLOC_YAW_T": 0}))
    before = {f"SCH_OMCF_{i}": 1.0 for i in range(1, 7)}
    before["ALLOC_YAW_T"] = 0
    assert not M.stable(M.fly(sc, cut, coordinated=False, law_overrides=before))


@pytest.mark.parametrize("point", [(15.0, 28e3), (15.0, 32e3)], ids=["M15-28km", "M15-32km"])
def test_coordination_keeps_flying_at_mach_15(point):
    """Issue 20 item 3: the coordinated law (Eq. 19 factors, k1..k9 = 1) flies the paper's case
    at Mach 15 / 28 and 32 km (map b's disturbance, the law fed the truth as tools.evidence.envelope).
    With the rate-command limit's Mach factor but the yaw-row factor lambda_r unscaled it
    diverged at 4.0 and 4.4 s (the factor's 1 / (1 + lambda_r) cut of the yaw loop's gain,
    lambda_r ~ 0.2 from the 5 deg sideslip, on a directionally unstable airframe with the rudder
    on its limit); the schedule scales lambda_r by the same rudder share (CO_LAMR_SCL). The
    bound: settled within the 0.2 deg band by 12 s (measured alpha settles in 7.3 s at 32 km,
    after a 66 % overshoot: flown, not yet within the paper's spec there)."""
    from tools.evidence.coordination import READINGS
    sc = point_scenario(*point, disturbance="coefficient")
    res = simulate(sc, coordinated=True, duration_s=12.0, law_overrides=dict(READINGS["eq19"]),
                   command_shaping="steps", estimate="truth")
    assert not res.diverged
    m = res.metrics()
    assert max(abs(m[c].final_error_deg) for c in ("alpha", "beta", "mu")) < 0.2
    assert res.params["CO_LAMR_SCL"] == 1.0                  # the parameter keeps the paper's


def _fly_truth(point, coordinated, overrides=None, duration_s=20.0):
    """The paper's case at ``point`` as tools.evidence.envelope flies map (b)."""
    from tools.evidence.coordination import READINGS
    ov = dict(READINGS["eq19"]) if coordinated else {}
    ov.update(overrides or {})
    sc = point_scenario(*point, disturbance="coefficient")
    return simulate(sc, coordinated=coordinated, duration_s=duration_s, law_overrides=ov,
                    command_shaping="steps", estimate="truth")


@pytest.mark.parametrize("coordinated", [True, False], ids=["co", "unco"])
def test_prioritised_allocation_keeps_alpha_within_the_spec_at_mach_13(coordinated):
    """Map (b) at Mach 13 / 27 km (222 kPa): the paper's 5 deg initial sideslip is beyond what
    the surfaces can trim there, the rudder and an elevon start on their limits. Scaling the
    whole deflection vector (ALLOC_MODE 1, the default before) starves the pitch axis with the
    others and alpha overshoots (measured 15 % unco, 24 % co); the prioritised allocation
    (ALLOC_MODE 2, yaw first) keeps it inside the spec (measured 0.9 % unco, 6.4 % co)."""
    os_of = lambda r: r.metrics()["alpha"].overshoot_pct                     # noqa: E731
    res = _fly_truth((13.0, 27e3), coordinated, duration_s=8.0)
    assert not res.diverged and os_of(res) <= OVERSHOOT_MAX_PCT
    before = _fly_truth((13.0, 27e3), coordinated, {"ALLOC_MODE": 1}, duration_s=8.0)
    assert before.diverged or os_of(before) > OVERSHOOT_MAX_PCT


@pytest.mark.parametrize("coordinated", [True, False], ids=["co", "unco"])
def test_prioritised_allocation_recovers_from_the_untrimmable_sideslip_at_mach_15(coordinated):
    """Map (b) at Mach 15 / 36 km (79 kPa): the rudder can trim at most about 4.3 deg of
    sideslip at Mach 15 (plant_sim.trim), the paper's case starts at 5. With the yaw axis
    served first the law brings the sideslip back and settles (measured within 0.05 deg at
    20 s); with the vector scaled (ALLOC_MODE 1) or the axes weighed equally the yaw
    shortfall grows the sideslip and the vehicle departs (diverged at 4.6-5.3 s)."""
    res = _fly_truth((15.0, 36e3), coordinated)
    assert not res.diverged
    m = res.metrics()
    assert max(abs(m[c].final_error_deg) for c in ("alpha", "beta", "mu")) < FINAL_ERROR_MAX_DEG
    for ov in ({"ALLOC_MODE": 1}, {"ALLOC_W_YAW": 1.0, "ALLOC_W_PITCH": 1.0}):
        assert _fly_truth((15.0, 36e3), coordinated, ov, duration_s=8.0).diverged, ov


def test_the_re_solve_under_saturation_delivers_the_loops_moment_at_mach_12_5():
    """Map (b) at Mach 12.5 / 25 km (279 kPa), coordinated: the untrimmable 5 deg sideslip
    puts the left elevon and the rudder on their limits for the first half second. When the
    prioritised allocation re-solved the free surfaces in the coordinated matrix g_Gamma, the
    factors' reshaping (lambda_e up to 0.25 while q is large) was kept with the surfaces short
    and alpha overshot 33.7 %; re-solving M_c in the physical g_f_delta gives 13.6 %
    (commit history of fc/control/allocation.py; docs/control_law.md s. 13). The bound sits
    between the two."""
    res = _fly_truth((12.5, 25e3), True, duration_s=8.0)
    assert not res.diverged
    assert res.metrics()["alpha"].overshoot_pct <= 20.0


def test_the_yaw_escalation_recovers_the_untrimmable_sideslip_at_mach_15_27_km():
    """Map (a) at Mach 15 / 27 km (296 kPa, the paper's d(t) as a fixed angular acceleration):
    the 5 deg start is beyond the 4.3 deg the rudder can hold, the rudder is on its limit from
    t = 0 with the elevons free. With the fixed yaw weight the sideslip only fell to 3.7 deg
    in 2 s while the bank ran off (mu -39 deg at 3 s) and the vehicle departed, in both
    variants; with the yaw weight escalated while the rudder alone is short (ALLOC_YAW_T,
    docs/control_law.md s. 13 "Yaw escalation") it recovers (measured: worst overshoot
    8.2 %, settled by 6.2 s). Coordinated, 8 s."""
    from tools.evidence.coordination import READINGS
    sc = point_scenario(15.0, 27e3, disturbance="accel")

    def fly(ov):
        return simulate(sc, coordinated=True, duration_s=8.0,
                        law_overrides={**READINGS["eq19"], **ov}, command_shaping="steps",
                        estimate="truth")
    res = fly({})
    assert not res.diverged
    m = res.metrics()
    assert max(abs(m[c].final_error_deg) for c in ("alpha", "beta", "mu")) < FINAL_ERROR_MAX_DEG
    assert fly({"ALLOC_YAW_T": 0}).diverged
