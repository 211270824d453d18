"""Authority at low dynamic pressure (issue 20): the rate-aware allocation (ALLOC_RATE) and the
complementary attitude filter (FLT_ANG_CF), each alone and in the closed loop at the cruise
point (Mach 7.5 / 28 km, 63 kPa) with the paper scenario's 0.05 deg vane noise."""
from __future__ import annotations

import math

import numpy as np
import pytest

from fc.control import kernels as K
from fc.control import layout as L
from fc.control.law import AttitudeLaw
from fc.control.nominal import eval_model

DEG = math.pi / 180.0
DT_FAST_S = 0.002


def _est(alpha_deg=3.9, beta_deg=0.0, mu_deg=0.0, p=0.0, q=0.0, r=0.0):
    return np.array([alpha_deg * DEG, beta_deg * DEG, mu_deg * DEG, p, q, r, 2250.0, 28000.0,
                     0.0])


def _law(**overrides):
    law = AttitudeLaw(overrides)
    eval_model(_est(), law.par, law.tab, law.atm, law.grid, law.nm)
    return law


# ---- the rate-aware allocation alone ---------------------------------------------------------
@pytest.mark.parametrize("co,surf", [(0, 0), (1, 1), (1, 2)])
def test_a_command_step_beyond_the_rate_is_spread_direction_kept(co, surf):
    """GIVEN a dense g_Gamma and a last command WHEN the allocation asks for a change larger
    than ACT_RATE x dt THEN every surface moves at most ACT_RATE x dt, the change vector is the
    requested one scaled (direction kept), and the moment not delivered is added to the
    unallocated moment (Eq. 47 undone)."""
    law = _law(ALLOC_RATE=1, CO_ENABLE=co, CO_SURF=surf)
    rng = np.random.default_rng(7)
    G = rng.normal(size=(3, 3)) * 1e7 + np.diag([3e7, -3e7, 3e7])
    law.nm[L.NM_GCO:L.NM_GCO + 9] = G.ravel()
    prev = np.array([1.0, -2.0, 0.5]) * DEG
    law.x[L.X_DCMD:L.X_DCMD + 3] = prev
    want = np.array([4.0, -3.0, -1.0]) * DEG            # 3 deg in 2 ms: 1500 deg/s
    delta = want.copy()
    law.status[L.S_M_UNALLOC:L.S_M_UNALLOC + 3] = [1.0, 2.0, 3.0]
    e_coup = 0.3
    s = K.rate_limit_command(law.par, law.nm, law.x, e_coup, DT_FAST_S, delta, law.status)
    step = 90.0 * DEG * DT_FAST_S
    assert s == pytest.approx(step / (3.0 * DEG))
    assert np.max(np.abs(delta - prev)) == pytest.approx(step)
    np.testing.assert_allclose(delta - prev, s * (want - prev), rtol=1e-12)
    assert law.status[L.S_ALLOC_RATE] == s
    short = (1.0 - s) * (want - prev)
    if co and surf == 1:
        short[1] -= e_coup * short[2]
    elif co and surf == 2:
        short[1] = 0.0
    np.testing.assert_allclose(law.status[L.S_M_UNALLOC:L.S_M_UNALLOC + 3],
                               np.array([1.0, 2.0, 3.0]) + G @ short, rtol=1e-12)


def test_a_reachable_change_and_the_switch_off_leave_the_command_alone():
    law = _law(ALLOC_RATE=1)
    prev = np.array([1.0, -2.0, 0.5]) * DEG
    law.x[L.X_DCMD:L.X_DCMD + 3] = prev
    small = prev + np.array([0.1, -0.15, 0.05]) * DEG  # within 0.18 deg per 2 ms
    delta = small.copy()
    assert K.rate_limit_command(law.par, law.nm, law.x, 0.3, DT_FAST_S, delta, law.status) == 1.0
    np.testing.assert_array_equal(delta, small)
    for off in (_law(ALLOC_RATE=0), _law(ALLOC_RATE=1, PAPER_LITERAL=1)):
        off.x[L.X_DCMD:L.X_DCMD + 3] = prev
        big = prev + 5.0 * DEG
        delta = big.copy()
        assert K.rate_limit_command(off.par, off.nm, off.x, 0.3, DT_FAST_S, delta,
                                    off.status) == 1.0
        np.testing.assert_array_equal(delta, big)


def test_fast_step_command_moves_at_most_the_actuator_rate():
    """The whole fast loop: a large attitude error asks for a large moment at once; the
    surface command still changes by at most ACT_RATE x dt per fast step."""
    law = AttitudeLaw({"ALLOC_RATE": 1, "REF_PF_EN": 0})
    est = _est()
    law.reset(est)
    cmd = (8.0 * DEG, 3.0 * DEG, 10.0 * DEG)
    last = law.delta_cmd_rad.copy()
    worst = 0.0
    for k in range(200):
        if k % 5 == 0:
            law.slow_step(est, cmd, 5 * DT_FAST_S)
        law.fast_step(est, DT_FAST_S)
        worst = max(worst, float(np.max(np.abs(law.delta_cmd_rad - last))))
        last = law.delta_cmd_rad.copy()
    assert worst == pytest.approx(90.0 * DEG * DT_FAST_S, rel=1e-9)


# ---- the complementary attitude filter alone ---------------------------------------------------
def _filter_run(cf_hz, alpha_of_t, q_of_t, noise_rad=0.0, n=2000, seed=3):
    """Run the fast loop's input filter alone on alpha(t) with body rate q(t) (wings level,
    beta 0: alpha_dot = q + f); returns (t, filtered alpha)."""
    law = AttitudeLaw({"FLT_ANG_CF": cf_hz})
    rng = np.random.default_rng(seed)
    est = _est(alpha_deg=math.degrees(alpha_of_t(0.0)))
    law.reset(est)
    out = np.empty(n)
    t = np.arange(n) * DT_FAST_S
    for k in range(n):
        est[L.E_ALPHA] = alpha_of_t(t[k]) + noise_rad * rng.standard_normal()
        est[L.E_Q] = q_of_t(t[k])
        K.fast_kernel(est, DT_FAST_S, law.par, law.x, law.nm, law.status, law.tab, law.atm,
                      law.grid, law.delta_cmd_rad)
        out[k] = law.x[L.X_AF2]
    return t, out


def test_complementary_filter_follows_a_manoeuvre_without_the_low_pass_lag():
    """GIVEN alpha moving as 2 deg sin(2 t) with the matching q WHEN filtered THEN the
    complementary estimate (1 Hz crossover) follows it within 0.01 deg; the 20 Hz low-pass
    lags it by ~16 ms (0.06 deg at the zero crossings)."""
    a0 = 3.9 * DEG
    amp = 2.0 * DEG
    alpha = lambda t: a0 + amp * math.sin(2.0 * t)                   # noqa: E731
    q = lambda t: amp * 2.0 * math.cos(2.0 * t)                      # noqa: E731
    t, cf = _filter_run(1.0, alpha, q)
    _, lp = _filter_run(0.0, alpha, q)
    ref = np.array([alpha(tt) for tt in t])
    k = t > 0.5
    assert np.max(np.abs(cf[k] - ref[k])) < 0.01 * DEG
    assert np.max(np.abs(lp[k] - ref[k])) > 0.04 * DEG


def test_complementary_filter_attenuates_vane_noise():
    """White vane noise (0.05 deg per 2 ms sample) at a constant attitude: the 1 Hz
    complementary filter passes under 0.01 deg rms, less than half what the 20 Hz low-pass
    passes."""
    const = lambda t: 3.9 * DEG                                      # noqa: E731
    zero = lambda t: 0.0                                             # noqa: E731
    _, cf = _filter_run(1.0, const, zero, noise_rad=0.05 * DEG, n=5000)
    _, lp = _filter_run(0.0, const, zero, noise_rad=0.05 * DEG, n=5000)
    cf_rms = np.std(cf[1000:])
    lp_rms = np.std(lp[1000:])
    assert cf_rms < 0.01 * DEG and cf_rms < 0.5 * lp_rms


# ---- the closed loop at the cruise point with the paper's vanes --------------------------------
def _cruise_with_vanes(vane_deg: float):
    from plant_sim.scenario import load, parse
    text = load("cruise").to_toml()
    head = "[sensors.noise]\nattitude_deg = 0.02\nrate_deg_s = 0.05\n"
    i = text.index(head) + len(head)
    j = text.index("airspeed_m_s", i)
    text = text[:i] + f"aoa_deg = {vane_deg}\nssa_deg = {vane_deg}\n" + text[j:]
    return parse(text, name="cruise")


def _fly_cruise(**overrides):
    from tools.sitl.closed_loop import simulate
    res = simulate(_cruise_with_vanes(0.05), coordinated=True, duration_s=12.0, seed=1,
                   estimate="sensors", command_shaping="prefilter", law_overrides=overrides)
    assert not res.diverged
    k = res.t_s > 4.0
    rate_deg_s = np.degrees(np.abs(np.diff(res.delta_cmd_rad, axis=0)) / np.diff(res.t_s)[:, None])
    return (np.degrees(np.std(res.beta_rad[k])), np.degrees(np.std(res.delta_rad[k, 2])),
            res.metrics()["surfaces"]["saturated_s"], float(np.max(rate_deg_s)))


def test_cruise_with_the_papers_vanes_flies_without_a_limit_cycle():
    """GIVEN the cruise point (63 kPa) with 0.05 deg vane noise, the law alone at the trim
    attitude, sensors and the fc's estimator, seed 1, 12 s WHEN flown with the defaults
    (complementary attitude filter) THEN no lateral limit cycle: beta < 0.05 deg rms after
    4 s, rudder < 3 deg rms about its mean, no surface on its limit. Main's law (before issue
    20; FLT_ANG_CF 0) gives beta 0.067 deg rms and rudder 6.7 deg rms here (the limit cycle
    still growing; over 30 s: 0.17 and 10.8 deg); the defaults 0.005 and 1.2 deg."""
    beta_rms, rudder_rms, sat_s, _ = _fly_cruise()
    assert beta_rms < 0.05 and rudder_rms < 3.0 and sat_s == 0.0


def test_cruise_rate_aware_allocation_asks_at_most_the_actuator_rate():
    """The same flight with the rate-aware allocation on (ALLOC_RATE 1): the surface command
    never changes faster than the actuators' 90 deg/s (main's law asks up to 1,130 deg/s here,
    the complementary filter alone 430 deg/s), and there is no limit cycle."""
    beta_rms, rudder_rms, sat_s, rate_max = _fly_cruise(ALLOC_RATE=1)
    assert rate_max <= 90.0 * (1.0 + 1e-9)
    assert beta_rms < 0.05 and rudder_rms < 3.0 and sat_s == 0.0


def test_complementary_filter_step_is_the_equation():
    """One fast step of V8 from a preset state: Omega_hat + dt (g_s(Omega_hat) omega + f)
    pulled toward the vanes by 1 - exp(-2 pi f_c dt); mu wraps across +-180 deg; the slow
    step stores f = f1 + Psi^T theta_hat for it."""
    cf = 1.5
    law = AttitudeLaw({"FLT_ANG_CF": cf})
    est = _est(alpha_deg=4.0, beta_deg=1.0, mu_deg=179.9, p=0.02, q=-0.015, r=0.01)
    law.reset(est)
    law.slow_step(est, (4.0 * DEG, 0.0, 179.0 * DEG), 0.01)
    f = law.x[L.X_FKIN:L.X_FKIN + 3].copy()
    assert np.all(f != 0.0)
    hat = np.array([3.9 * DEG, 1.2 * DEG, -179.8 * DEG])
    law.x[L.X_AF2:L.X_AF2 + 3] = hat
    K.fast_kernel(est, DT_FAST_S, law.par, law.x, law.nm, law.status, law.tab, law.atm,
                  law.grid, law.delta_cmd_rad)
    kin = np.array(K.gs(hat[0], hat[1], est[L.E_P], est[L.E_Q], est[L.E_R]))
    pred = hat + DT_FAST_S * (kin + f)
    g = 1.0 - math.exp(-2.0 * math.pi * cf * DT_FAST_S)
    wrap = lambda v: (v + math.pi) % (2.0 * math.pi) - math.pi      # noqa: E731
    exp = pred + g * (est[:3] - pred)
    exp[2] = wrap(wrap(pred[2]) + g * wrap(est[2] - wrap(pred[2])))
    np.testing.assert_allclose(law.x[L.X_AF2:L.X_AF2 + 3], exp, rtol=1e-12, atol=1e-15)
