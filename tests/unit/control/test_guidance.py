"""fc.guidance alone (no plant loop): each loop's direction, limits, rate limits, anti-windup,
bumpless engage, bad input, and the feed-forward near trim at the cruise point."""
from __future__ import annotations

import math

import numpy as np
import pytest

from fc.control.layout import E_ALPHA, E_BETA, E_GAMMA, E_H, E_MU, E_N, E_V
from fc.guidance import layout as G
from fc.guidance.guidance import Guidance, limit_names
from fc.guidance.kernels import course_from_air_data
from fc.guidance.params import GUIDANCE_PARAMS, PARAM_INDEX, check_value
from hyfc_wire.earth import EARTH_RADIUS_M

DEG = math.pi / 180.0
DT = 0.02                       # 50 Hz
H0, V0 = 28000.0, 2250.0        # the cruise point
ALPHA0 = 4.67 * DEG             # the nominal vehicle's 1-g trim there


def _est(alpha=ALPHA0, h=H0, V=V0, gamma=0.0, mu=0.0, beta=0.0):
    e = np.zeros(E_N)
    e[E_ALPHA], e[E_BETA], e[E_MU], e[E_V], e[E_H], e[E_GAMMA] = alpha, beta, mu, V, h, gamma
    return e


def _engaged(est=None, thr=0.44, **over):
    g = Guidance(over)
    est = _est() if est is None else est
    g.set_targets(h_m=est[E_H], chi_rad=0.0, V_m_s=est[E_V])
    g.reset(est, thr)
    return g, est


def _run(g, est, n, chi=0.0):
    for _ in range(n):
        g.step(est, chi, DT)
    return g


def test_parameter_table_is_well_formed():
    assert len({p.name for p in GUIDANCE_PARAMS}) == len(GUIDANCE_PARAMS)
    for p in GUIDANCE_PARAMS:
        assert len(p.name) <= 16 and p.name == p.name.upper() and p.min <= p.default <= p.max
        assert p.unit and p.description
    with pytest.raises(KeyError):
        check_value("NOPE", 1.0)
    with pytest.raises(ValueError):
        check_value("GE_MU_MAX", 95.0)
    with pytest.raises(ValueError):
        check_value("GA_K_H", math.nan)
    g = Guidance({"GE_MU_MAX": 25.0})
    assert g.par[PARAM_INDEX["GE_MU_MAX"]] == pytest.approx(25.0 * DEG)
    assert g.params()["GE_MU_MAX"] == pytest.approx(25.0)


def test_feedforward_is_near_the_plants_trim_at_the_cruise_point():
    """The alpha asked for level flight at Mach 7.5 / 28 km, from the nominal model's trimmed
    lift, gives the plant's lift = weight less the round Earth's centrifugal relief
    m V^2 / (R + h) (0.92 g; the cruise scenario flies the sphere) within 1 % (nominal vehicle,
    its own trim)."""
    from plant_sim import dynamics as dy
    from plant_sim.scenario import load
    from plant_sim.sim import build_params
    from plant_sim.trim import trim_at
    g = Guidance({"GA_K_GAMI": 0.0})     # the model alone: no integral taking up its error
    g.set_targets(h_m=H0, chi_rad=0.0, V_m_s=V0)
    est = _est(alpha=3.0 * DEG)          # far from trim: the feed-forward does not start there
    g.reset(est, -1.0)
    g.step(est, 0.0, DT)
    a_ff = g.status[G.GS_ALPHA_FF]
    assert 4.0 * DEG < a_ff < 5.5 * DEG
    sc = load("cruise")
    for k in sc.data["uncertainty"]:
        sc.data["uncertainty"][k] = 0.0
    p, _ = build_params(sc)
    tr = trim_at(sc, a_ff, 0.0)
    x = np.zeros(dy.X_N)
    dy.initial_state(V0, H0, a_ff, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, x)
    w = np.zeros(dy.W_N)
    d = tr.deflection_rad
    dy.aero_eval(x, d[0], d[1], d[2], p, w)
    lift = w[dy.W_AUX + dy.AX_LIFT]
    weight = p[dy.P_MASS] * w[dy.W_AUX + dy.AX_GRAV]
    assert sc.data["earth"]["model"] == "sphere"
    relief = V0 ** 2 / (EARTH_RADIUS_M + H0)                     # m/s^2, 0.08 g
    assert lift == pytest.approx(weight - p[dy.P_MASS] * relief, rel=0.01)
    grav = w[dy.W_AUX + dy.AX_GRAV]
    assert g.status[G.GS_NZ_C] == pytest.approx(1.0 - relief / grav, abs=2e-3)


def test_engage_without_the_throttle_in_use_is_bumpless_too():
    """Engaged with the throttle unknown (thr_now < 0, as the fc engages), the first step takes
    its own throttle; the flight-path integral must count that thrust's lift at once, else
    alpha_c leaves the engagement's alpha from the second step (0.046 deg at 3.9 deg: with the
    frame frozen the law's surfaces ran off, issue 22's FAILSAFE test)."""
    est = _est(alpha=3.9 * DEG)
    g, est = _engaged(est, thr=-1.0)
    _run(g, est, 20)
    assert g.out[G.GO_THR] > 0.1                                   # a thrust that lifts
    assert g.out[G.GO_ALPHA] == pytest.approx(3.9 * DEG, abs=1e-4 * DEG)


def test_engage_is_bumpless_at_trim():
    g, est = _engaged()
    _run(g, est, 50)
    assert abs(g.out[G.GO_ALPHA] - ALPHA0) < 0.01 * DEG
    assert g.out[G.GO_MU] == 0.0 and g.out[G.GO_BETA] == 0.0
    assert g.out[G.GO_THR] == pytest.approx(0.44, abs=1e-6)
    assert g.limits_in_force() == []


@pytest.mark.parametrize("dh, sign", [(+500.0, +1), (-500.0, -1)])
def test_altitude_loop_direction(dh, sign):
    g, est = _engaged()
    g.set_targets(h_m=H0 + dh)
    _run(g, est, 100)
    assert sign * g.status[G.GS_GAM_C] > 0.1 * DEG
    assert sign * (g.out[G.GO_ALPHA] - ALPHA0) > 0.1 * DEG       # pull up / push over
    assert sign * g.status[G.GS_HDOT_C] > 0


@pytest.mark.parametrize("dchi, sign", [(+10.0, +1), (-10.0, -1), (+350.0, -1)])
def test_course_loop_direction_and_wrap(dchi, sign):
    g, est = _engaged()
    g.set_targets(chi_rad=dchi * DEG)          # +350 deg is 10 deg left: turn left
    _run(g, est, 200)
    assert sign * g.out[G.GO_MU] > 5.0 * DEG
    assert g.out[G.GO_BETA] == 0.0


def test_coordinated_turn_bank_matches_the_turn_rate():
    g, est = _engaged(GH_CHI_TAU=0.0, GE_MU_RATE=60.0)
    g.set_targets(chi_rad=0.05 * DEG)          # small error: linear region, no limit
    _run(g, est, 100)
    chid = g.status[G.GS_CHIDOT_C]
    assert chid == pytest.approx(0.05 * 0.05 * DEG)
    g_m_s2 = 9.72
    assert math.tan(g.out[G.GO_MU]) == pytest.approx(V0 * chid / g_m_s2, rel=0.01)


@pytest.mark.parametrize("dv, sign", [(+50.0, +1), (-50.0, -1)])
def test_speed_loop_direction(dv, sign):
    g, est = _engaged()
    g.set_targets(V_m_s=V0 + dv)
    _run(g, est, 100)
    assert sign * (g.out[G.GO_THR] - 0.44) > 0.02
    assert sign * g.status[G.GS_V_REF] > sign * V0


def test_mach_target_sets_the_speed_reference():
    g, est = _engaged(GS_ACC_MAX=20.0)
    g.set_targets(mach=7.3)
    _run(g, est, 300)                          # V_ref ramps at GS_ACC_MAX to the target
    a_snd = V0 / g.status[G.GS_MACH]
    assert g.status[G.GS_V_REF] == pytest.approx(7.3 * a_snd)
    g.set_targets(V_m_s=2300.0)                # a speed target clears the Mach target
    _run(g, est, 300)
    assert g.status[G.GS_V_REF] == pytest.approx(2300.0)


def test_limits_bound_the_commands_and_are_flagged():
    g, est = _engaged(GE_GAM_MAX=2.0, GE_MU_MAX=25.0, GE_ALPHA_MAX=6.0)
    g.set_targets(h_m=H0 + 20000.0, chi_rad=90.0 * DEG, V_m_s=V0 + 1000.0)
    gam, mu, alpha, thr = [], [], [], []
    for _ in range(3000):
        g.step(est, 0.0, DT)
        gam.append(g.status[G.GS_GAM_C])
        mu.append(g.out[G.GO_MU])
        alpha.append(g.out[G.GO_ALPHA])
        thr.append(g.out[G.GO_THR])
    assert max(gam) <= 2.0 * DEG + 1e-12
    # the commands stop at the limits less their margins (GE_MU_MARGIN, GE_ALPHA_MARGIN 0.2 deg)
    assert max(mu) <= 24.8 * DEG + 1e-12 and max(mu) > 24.7 * DEG
    assert max(alpha) <= 5.8 * DEG + 1e-12
    assert max(thr) <= 1.0
    names = g.limits_in_force()
    for n in ("gamma_max", "mu_max", "thr_max", "hdot"):
        assert n in names
    assert limit_names(G.LIM_MU_MAX | G.LIM_QBAR_LOW) == ["qbar_low", "mu_max"]


def test_load_factor_limit_bounds_bank_and_pull_up():
    g, est = _engaged(GE_NZ_MAX=1.1, GE_MU_MAX=60.0)
    g.set_targets(chi_rad=90.0 * DEG)
    _run(g, est, 2000)
    assert abs(g.out[G.GO_MU]) <= math.acos(1.0 / 1.05) + 1e-12      # 17.8 deg, at n 1.1 - 0.05
    g, est = _engaged(GE_NZ_MAX=1.2)
    g.set_targets(h_m=H0 + 3000.0)
    nz = []
    for _ in range(400):
        g.step(est, 0.0, DT)
        nz.append(g.status[G.GS_NZ_C])
    assert max(nz) == pytest.approx(1.2 - 0.05) and "nz_max" in g.limits_in_force()


@pytest.mark.parametrize("margin", [0.0, 0.05, 0.2])
def test_envelope_margins_keep_the_commands_inside_the_limits(margin):
    # GIVEN margins on the load factor, the bank and alpha; WHEN every target asks beyond them
    g, est = _engaged(GE_NZ_MAX=1.3, GE_NZ_MARGIN=margin, GE_MU_MAX=25.0,
                      GE_MU_MARGIN=10 * margin)
    g.set_targets(h_m=H0 + 5000.0, chi_rad=90.0 * DEG)
    nz, mu = [], []
    for _ in range(1500):
        g.step(est, 0.0, DT)
        nz.append(g.status[G.GS_NZ_C])
        mu.append(g.out[G.GO_MU])
    # THEN each command settles at its limit less its margin, and the limit is flagged
    assert max(nz) == pytest.approx(1.3 - margin)
    assert max(mu) == pytest.approx((25.0 - 10 * margin) * DEG)
    assert {"nz_max", "mu_max"} <= set(g.limits_in_force())
    g, est = _engaged(GE_ALPHA_MAX=6.0, GE_ALPHA_MARGIN=10 * margin)
    g.set_targets(h_m=H0 + 5000.0)
    _run(g, est, 1500)
    assert g.out[G.GO_ALPHA] == pytest.approx((6.0 - 10 * margin) * DEG)
    assert "alpha_max" in g.limits_in_force()


def test_envelope_margins_that_cross_meet_in_the_middle():
    g, est = _engaged(GE_NZ_MIN=0.9, GE_NZ_MAX=1.1, GE_NZ_MARGIN=0.2)
    g.set_targets(h_m=H0 + 5000.0)
    _run(g, est, 200)
    assert g.status[G.GS_NZ_C] == pytest.approx(1.0)
    assert g.out[G.GO_MU] == 0.0                   # no bank at a 1-g bound


def test_rate_limits():
    g, est = _engaged(GE_MU_RATE=2.0, GE_GAM_RATE=0.1, GE_ALPHA_RATE=0.5, GE_THR_RATE=0.2)
    g.set_targets(h_m=H0 + 5000.0, chi_rad=60.0 * DEG, V_m_s=V0 + 500.0)
    prev = (g.out.copy(), g.status[G.GS_GAM_C])
    g.step(est, 0.0, DT)
    prev = (g.out.copy(), g.status[G.GS_GAM_C])
    seen = 0
    for _ in range(300):
        seen |= g.step(est, 0.0, DT)
        d = np.abs(g.out - prev[0])
        assert d[G.GO_MU] <= 2.0 * DEG * DT + 1e-12
        assert d[G.GO_ALPHA] <= 0.5 * DEG * DT + 1e-12
        assert d[G.GO_THR] <= 0.2 * DT + 1e-12
        assert abs(g.status[G.GS_GAM_C] - prev[1]) <= 0.1 * DEG * DT + 1e-12
        prev = (g.out.copy(), g.status[G.GS_GAM_C])
    assert {"mu_rate", "thr_rate", "alpha_rate", "gamma_rate"} <= set(limit_names(seen))


def test_speed_integral_does_not_wind_up_at_full_throttle():
    g, est = _engaged(GS_ACC_MAX=20.0)
    g.set_targets(V_m_s=V0 + 500.0)            # far beyond what the engine gives
    _run(g, est, 500)
    assert g.out[G.GO_THR] == 1.0 or "thr_max" in g.limits_in_force()
    v_int = g.gx[G.GX_V_INT]
    _run(g, est, 500)
    assert g.gx[G.GX_V_INT] == v_int           # frozen while saturated in the error's direction
    g.set_targets(V_m_s=V0 - 1.0)               # once the reference is back below V, it unwinds
    while g.status[G.GS_V_ERR] >= 0.0:
        g.step(est, 0.0, DT)
    v_int = g.gx[G.GX_V_INT]
    _run(g, est, 10)
    assert g.gx[G.GX_V_INT] < v_int


def test_altitude_integral_frozen_at_a_limit_and_outside_its_zone():
    # GIVEN an error inside the zone but a flight-path limit below what the loop asks
    g, est = _engaged(GE_GAM_MAX=0.1, GA_HI_ZONE=150.0)
    g.set_targets(h_m=H0 + 100.0)              # hdot demand 5 m/s > V sin(0.1 deg) = 3.9 m/s
    _run(g, est, 300)
    assert "gamma_max" in g.limits_in_force() and g.gx[G.GX_H_INT] == 0.0
    # WHEN no limit blocks the climb, THEN the same error integrates
    g, est = _engaged(GA_HI_ZONE=150.0, GE_NZ_MAX=10.0)
    g.set_targets(h_m=H0 + 100.0)
    _run(g, est, 50)
    assert g.gx[G.GX_H_INT] == pytest.approx(100.0 * 50 * DT)
    # outside the zone nothing integrates
    g, est = _engaged(GA_HI_ZONE=150.0)
    g.set_targets(h_m=H0 + 1000.0)
    _run(g, est, 50)
    assert g.gx[G.GX_H_INT] == 0.0


def _point_mass_climb(g, est, seconds):
    """Fly ``g`` over a point mass in the vertical plane (wings level, speed held) whose lift
    is the nominal model's trimmed lift at the guidance's alpha command (a perfect inner loop,
    no model error). Returns the altitude error (target - h, m) and climb rate (m/s) at the end."""
    from fc.guidance.kernels import _flight_condition, trimmed_coefficients
    for _ in range(int(round(seconds / DT))):
        g.step(est, 0.0, DT)
        est[E_ALPHA] = g.out[G.GO_ALPHA]
        _q, qS, mach, grav, _a = _flight_condition(est, g.work, g.atm, g.grid)
        cl, _cd = trimmed_coefficients(mach, est[E_ALPHA], g.xcg_m, g.tab, g.grid, g.work)
        est[E_GAMMA] += (cl * qS / g.mass_kg - grav * math.cos(est[E_GAMMA])) / est[E_V] * DT
        est[E_H] += est[E_V] * math.sin(est[E_GAMMA]) * DT
    return g.tgt[G.TG_H] - est[E_H], est[E_V] * math.sin(est[E_GAMMA])


def test_engaged_in_an_upset_the_flight_path_integral_unwinds_and_the_altitude_comes_back():
    """Issue 22's dive: engaged (recovery after a FAILSAFE) while the vehicle was in an upset,
    alpha 0.4 deg and sinking at 63 m/s, the engagement takes the low lift for a model error and
    starts the flight-path integral at -GA_GI_MAX. With the load-factor demand at GE_NZ_MAX the
    anti-windup froze it there, the lift stayed 40 % short and the vehicle sank for ever (13 km
    low after 110 s, limits nz_max, gamma_max, qbar_high, hdot: the issue's sequence).
    The integral must unwind and the altitude come back."""
    # GIVEN the guidance engaged in the upset, holding the altitude of the engagement
    est = _est(alpha=0.4 * DEG, gamma=-1.6 * DEG)
    g = Guidance()
    g.set_targets(h_m=H0, chi_rad=0.0, V_m_s=V0)
    g.reset(est, 0.44)
    assert g.gx[G.GX_G_INT] < 0.0               # the engagement's (wrong) model error
    # WHEN it flies 30 s, THEN the integral has unwound (it opposed the climb the loop asks)
    _point_mass_climb(g, est, 30.0)
    assert g.gx[G.GX_G_INT] >= -1e-9
    # AND after 120 s the vehicle is back near its altitude, no longer sinking
    h_err, hdot = _point_mass_climb(g, est, 90.0)
    assert abs(h_err) < 50.0 and abs(hdot) < 5.0, (h_err, hdot, g.limits_in_force())


def test_engaged_in_an_upset_the_commands_start_inside_the_envelope():
    """Issue 22: resumed after a data loss with the vehicle rolled over (mu 168 deg, alpha
    15 deg), the commands started at the upset and left it at GE_MU_RATE: the law was told to
    hold the upset for many seconds. They start inside the envelope's command limits."""
    g = Guidance()
    est = _est(alpha=15.0 * DEG, mu=168.0 * DEG, gamma=-5.0 * DEG)
    g.set_targets(h_m=H0, chi_rad=0.0, V_m_s=V0)
    g.reset(est, 0.44)
    p = g.params()
    assert abs(g.gx[G.GX_MU_C]) <= (p["GE_MU_MAX"] - p["GE_MU_MARGIN"]) * DEG + 1e-12
    assert g.gx[G.GX_ALPHA_C] <= (p["GE_ALPHA_MAX"] - p["GE_ALPHA_MARGIN"]) * DEG + 1e-12
    assert abs(g.gx[G.GX_GAM_C]) <= p["GE_GAM_MAX"] * DEG + 1e-12
    g.step(est, 0.0, DT)
    assert abs(g.out[G.GO_MU]) <= p["GE_MU_MAX"] * DEG
    assert g.out[G.GO_ALPHA] <= p["GE_ALPHA_MAX"] * DEG
    # and inside the envelope the engagement is still bumpless
    g2, est2 = _engaged(_est(mu=10.0 * DEG, gamma=1.0 * DEG))
    assert g2.gx[G.GX_MU_C] == 10.0 * DEG and g2.gx[G.GX_GAM_C] == 1.0 * DEG


def test_an_integral_opposing_its_error_unwinds_outside_its_zone_but_not_past_zero():
    # GIVEN an altitude integral wound up (climb) and a target far below (outside the zone)
    g, est = _engaged(GA_HI_ZONE=150.0)
    g.gx[G.GX_H_INT] = 100.0
    g.set_targets(h_m=H0 - 1000.0)
    # WHEN it steps, THEN the integral falls toward zero and stops there
    g.step(est, 0.0, DT)
    assert g.gx[G.GX_H_INT] == pytest.approx(100.0 - 1000.0 * DT)
    _run(g, est, 50)
    assert g.gx[G.GX_H_INT] == 0.0


def test_qbar_protection_turns_the_flight_path_limits():
    # below the floor: the upper flight-path limit is negative, a climb target is refused
    g, est = _engaged(GE_QBAR_MIN=70000.0, GE_QBAR_BAND=10000.0)    # qbar here is 63.5 kPa
    g.set_targets(h_m=H0 + 2000.0)
    _run(g, est, 500)
    assert g.status[G.GS_GAM_C] < 0.0 and "qbar_low" in g.limits_in_force()
    # above the ceiling: the lower limit is positive, a descent target is refused
    g, est = _engaged(GE_QBAR_MAX=60000.0, GE_QBAR_BAND=10000.0)
    g.set_targets(h_m=H0 - 2000.0)
    _run(g, est, 500)
    assert g.status[G.GS_GAM_C] > 0.0 and "qbar_high" in g.limits_in_force()


def test_bad_input_changes_nothing():
    g, est = _engaged()
    _run(g, est, 10)
    gx, out = g.gx.copy(), g.out.copy()
    bad = est.copy()
    bad[E_V] = math.nan
    assert g.step(bad, 0.0, DT) == G.LIM_INPUT_BAD
    assert g.step(est, math.inf, DT) == G.LIM_INPUT_BAD
    assert g.step(est, 0.0, 0.0) == G.LIM_INPUT_BAD
    assert g.step(est, 0.0, 2.0) == G.LIM_INPUT_BAD
    assert np.array_equal(g.gx, gx) and np.array_equal(g.out, out)
    with pytest.raises(ValueError):
        g.set_targets(h_m=math.nan)
    fresh = Guidance()                         # not reset: refuses to run
    assert fresh.step(est, 0.0, DT) == G.LIM_INPUT_BAD


def test_course_from_air_data():
    assert course_from_air_data(0.0, 0.05, 0.3, 0.05, 0.0) == pytest.approx(0.3, abs=1e-12)
    # wings level, pitch = alpha: the velocity is horizontal, beta to the right of the nose
    assert course_from_air_data(0.0, 0.05, 0.3, 0.05, 0.02) == pytest.approx(0.32, abs=2e-4)
    # banked with alpha: the velocity lies on the other side of the nose than the lift
    assert course_from_air_data(0.5, 0.0, 0.0, 0.05, 0.0) < 0.0
