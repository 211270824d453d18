"""tools/evidence/envelope.py: the grid, its trim and its verdicts (issue 15, point 5)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from tools.evidence import envelope as E


def test_paper_point_has_the_papers_speed_and_dynamic_pressure():
    v, q = E.flight_condition(2200.0 / 295.7028, 21000.0)
    assert v == pytest.approx(2200.0, rel=1e-4)
    assert q == pytest.approx(0.5 * 0.0757148627 * 2200.0 ** 2, rel=1e-3)


def test_every_quick_grid_point_is_set_up_and_trimmed():
    machs, hs = E.grid(quick=True)
    for m in machs:
        for h in hs:
            sc = E.point_scenario(float(m), float(h))
            assert sc.data["initial"]["h_m"] == h
            assert sc.data["actuators"]["initial"] == "trim"
            tr = E.trim_point(sc)
            assert tr["trim_ini_ok"] and tr["trim_cmd_ok"], (m, h, tr)
            assert 0.0 < tr["trim_cmd_max_deg"] <= 20.0


def test_trim_is_computed_at_each_point():
    """The trim depends on the point's Mach (the aerodynamic fits vary with Mach): two points
    at one altitude give different deflections, so each point is trimmed, not copied."""
    a = E.trim_point(E.point_scenario(7.0, 22e3))
    b = E.trim_point(E.point_scenario(12.0, 22e3))
    assert a["trim_ini_max_deg"] != b["trim_ini_max_deg"]


def test_spec_and_maps_from_rows():
    ok = {"mach": 7.0, "h_km": 22.0, "variant": "unco", "diverged": False, "error": "",
          "alpha_os_pct": 4.0, "beta_os_pct": 2.0, "mu_os_pct": 9.0,
          "alpha_ts_s": 2.0, "beta_ts_s": 1.0, "mu_ts_s": 4.9, "sat_s": 0.0, "trim_cmd_ok": True}
    late = dict(ok, mach=10.0, mu_ts_s=math.nan)
    div = dict(ok, h_km=30.0, diverged=True)
    assert E.meets_spec(ok) and not E.meets_spec(late) and not E.meets_spec(div)
    machs, hs = E.grid(quick=True)
    mp = E.maps([ok, late, div], machs, hs)
    assert mp[("unco", "os")][0, 0] == 9.0
    assert mp[("unco", "ts")][0, 1] == math.inf
    assert mp[("unco", "div")][1, 0] == 1.0 and np.isnan(mp[("unco", "os")][1, 0])
    assert np.isnan(mp[("unco", "os")][1, 1])                 # not flown


def test_map_b_disturbance_is_the_papers_at_the_papers_point():
    """Map (b): d(t) as a moment coefficient referenced to the paper's 183 kPa; map (a) keeps
    the paper's angular acceleration (no reference)."""
    a = E.point_scenario(10.0, 30e3)
    b = E.point_scenario(10.0, 30e3, disturbance="coefficient")
    assert a.data["disturbance"]["qbar_ref_Pa"] == 0.0
    assert b.data["disturbance"]["qbar_ref_Pa"] == pytest.approx(
        0.5 * 0.0757148627 * 2200.0 ** 2, rel=1e-3)
    with pytest.raises(ValueError):
        E.point_scenario(10.0, 30e3, disturbance="gust")


def test_summary_counts_unsettled_and_the_target_corridor():
    base = {"variant": "unco", "diverged": False, "error": "", "alpha_os_pct": 1.0,
            "beta_os_pct": 1.0, "mu_os_pct": 1.0, "alpha_ts_s": 1.0, "beta_ts_s": 1.0,
            "mu_ts_s": 1.0}
    rows = [dict(base, mach=7.0, h_km=22.0, qbar_kPa=139.0),
            dict(base, mach=7.0, h_km=30.0, qbar_kPa=41.0, mu_ts_s=math.nan),   # unsettled
            dict(base, mach=6.0, h_km=36.0, qbar_kPa=12.0)]                    # below 24 kPa
    assert E.unsettled(rows[1]) and not E.unsettled(rows[0])
    assert [E.in_target_corridor(r) for r in rows] == [True, True, False]
    text = E.summary(rows)
    assert "unsettled at 20 s 1 (of which settled once d(t) was switched off: 0)" in text
    assert "Mach <= 15: 1 of 2 (50 %)" in text
    # the release test's verdict: settled after d was switched off -> a forced response
    rows[1].update(release_ts_s=23.0, release_fe_deg=0.01, release_diverged=False)
    assert E.released(rows[1]) and not E.released(rows[0])
    assert "settled once d(t) was switched off: 1)" in E.summary(rows)
    assert not E.released(dict(rows[1], release_ts_s=math.nan))       # still unsettled
    assert not E.released(dict(rows[1], release_diverged=True))


@pytest.mark.parametrize("name, disturbance", [("paper_cruise", "accel"),
                                                ("paper_cruise_b", "coefficient")])
def test_paper_cruise_scenario_is_the_envelope_point_at_the_cruise(name, disturbance):
    """plant_sim/scenarios/paper_cruise[_b].toml (the Monte Carlo campaigns at the cruise point,
    docs/montecarlo.md) are the envelope's point Mach 7.5 / 28 km of map (a) and map (b): every
    section equal but the name and description."""
    from plant_sim.scenario import load
    f = load(name)
    p = E.point_scenario(7.5, 28e3, disturbance=disturbance)
    assert f.commands == p.commands
    for key in p.data:
        if key in ("name", "description"):
            continue
        assert f.data[key] == p.data[key], key


def test_counts_per_variant_and_over_the_corridor():
    """summary.json's counts: diverged (or not set up), unsettled, meeting the spec, and the
    same inside 24-300 kPa, Mach <= 15."""
    base = {"alpha_os_pct": 1.0, "beta_os_pct": 1.0, "mu_os_pct": 1.0, "alpha_ts_s": 1.0,
            "beta_ts_s": 1.0, "mu_ts_s": 1.0, "error": "", "diverged": False}
    rows = [
        {**base, "variant": "unco", "mach": 8.0, "h_km": 26.0, "qbar_kPa": 98.0},
        {**base, "variant": "unco", "mach": 8.0, "h_km": 40.0, "qbar_kPa": 12.0},
        {**base, "variant": "unco", "mach": 15.0, "h_km": 36.0, "qbar_kPa": 79.0,
         "diverged": True},
        {**base, "variant": "unco", "mach": 6.0, "h_km": 38.0, "qbar_kPa": 30.0,
         "mu_ts_s": float("nan")},
        {**base, "variant": "unco", "mach": 7.0, "h_km": 30.0, "qbar_kPa": 50.0,
         "alpha_os_pct": 12.0},
    ]
    c = E.counts(rows)["unco"]
    assert c == {"points": 5, "diverged": 1, "unsettled": 1, "unsettled_released": 0,
                 "meets_spec": 2, "corridor_points": 4, "corridor_meets_spec": 1}


def test_release_check_tells_a_forced_response_from_one_that_persists():
    """Mach 11 / 40 km, map (a): the paper's d(t) (a fixed angular acceleration) is beyond the
    surfaces' authority at 24 kPa, so mu is still outside its band at 20 s. Switched off at
    20 s, the flight settles: a forced response, not a limit cycle (issue 20's "no point
    limit-cycles"). The same release after only 2 s of d cannot be settled at 2 + 1 s."""
    r = E.fly_point(11.0, 40e3, 20.0, ("unco",), "accel")[0]
    assert E.unsettled(r)
    assert E.released(r), r
    assert 20.0 < r["release_ts_s"] < 20.0 + E.RELEASE_S
    assert r["release_fe_deg"] < 0.2
    short = E.release_check(11.0, 40e3, 2.0, False, {}, "accel", release_s=1.0)
    assert not math.isfinite(short["release_ts_s"])


def test_set_overrides_are_checked_against_the_law_table():
    assert E.parse_sets(["ALLOC_W_ROLL=0.3", " ALLOC_W_YAW = 200"]) == {
        "ALLOC_W_ROLL": 0.3, "ALLOC_W_YAW": 200.0}
    for bad in ("NOPE=1", "ALLOC_W_ROLL", "ALLOC_W_ROLL=x", "ALLOC_W_ROLL=5000"):
        with pytest.raises(ValueError):
            E.parse_sets([bad])
    with pytest.raises(SystemExit):
        E.main(["--set", "NOPE=1", "--quick", "--workers", "0", "--out", "/nonexistent/x"])


def test_set_overrides_reach_the_flight():
    """--set's values are flown in every variant (the flights are deterministic, so an ignored
    override would give the same figures): the law's surface limit cut to 2 deg at the paper's
    point changes each variant's flight, and flying the default value again changes nothing."""
    keys = ("alpha_os_pct", "mu_fe_deg", "usage_deg_s", "travel_deg")
    variants = ("unco", "co_eq19")
    free = E.fly_point(7.44, 21e3, 1.0, variants, "accel")
    same = E.fly_point(7.44, 21e3, 1.0, variants, "accel", {"ACT_MAX": 20.0})
    cut = E.fly_point(7.44, 21e3, 1.0, variants, "accel", {"ACT_MAX": 2.0})
    for f, s, c in zip(free, same, cut):
        assert [f[k] for k in keys] == [s[k] for k in keys]
        assert c["travel_deg"] < 0.8 * f["travel_deg"], (f["variant"], c, f)
