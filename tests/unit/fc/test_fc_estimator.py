"""Tier 1: fc/estimator.py - measurement vector -> estimated state, validation, staleness.

mu and gamma are checked three ways: hand cases, an independent rotation-matrix
construction of the wind axes, and the plant's truth over a closed-loop bank manoeuvre.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from fc.estimator import (E_ALPHA, E_BETA, E_GAMMA, E_H, E_MU, E_P, E_V, FLAG_OLD_STAMP,
                          Estimator, mu_gamma)
from fc.link import M_AIRSPEED, M_ALT, M_AOA, M_N, M_P, M_PITCH, M_ROLL, M_SSA, M_T_S, M_YAW


def _rx(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def _ry(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def _rz(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def _meas(t=1.0, roll=0.0, pitch=0.0, yaw=0.0, alpha=0.0, beta=0.0, V=2000.0, h=21000.0):
    m = np.zeros(M_N)
    m[M_T_S], m[M_ROLL], m[M_PITCH], m[M_YAW] = t, roll, pitch, yaw
    m[M_AOA], m[M_SSA], m[M_AIRSPEED], m[M_ALT] = alpha, beta, V, h
    return m


@pytest.mark.parametrize("phi_deg", [-30.0, 0.0, 12.0, 60.0])
def test_wings_level_cases(phi_deg):
    # GIVEN zero aerodynamic angles THEN mu is the roll angle and gamma the pitch angle
    mu, gamma = mu_gamma(math.radians(phi_deg), 0.0, 0.0, 0.0)
    assert mu == pytest.approx(math.radians(phi_deg), abs=1e-12)
    assert gamma == pytest.approx(0.0, abs=1e-12)
    # GIVEN wings level, no sideslip THEN gamma = theta - alpha, mu = 0
    mu, gamma = mu_gamma(0.0, 0.3, 0.1, 0.0)
    assert gamma == pytest.approx(0.2, abs=1e-12) and mu == pytest.approx(0.0, abs=1e-12)


def test_matches_rotation_matrix_construction():
    """Wind axes built from C_nb and (alpha, beta), then read as ZYX Euler (chi, gamma, mu)."""
    rng = np.random.default_rng(7)
    for _ in range(300):
        phi, theta, psi = rng.uniform(-1.2, 1.2), rng.uniform(-1.2, 1.2), rng.uniform(-3, 3)
        alpha, beta = rng.uniform(-0.5, 0.5), rng.uniform(-0.3, 0.3)
        c_nb = _rz(psi) @ _ry(theta) @ _rx(phi)            # body -> NED
        c_bw = _ry(-alpha) @ _rz(beta)                     # wind -> body: x_w = [ca cb, sb, sa cb]
        c_nw = c_nb @ c_bw
        gamma_ref = -math.asin(c_nw[2, 0])
        mu_ref = math.atan2(c_nw[2, 1], c_nw[2, 2])
        mu, gamma = mu_gamma(phi, theta, alpha, beta)
        assert gamma == pytest.approx(gamma_ref, abs=1e-9)
        assert math.remainder(mu - mu_ref, 2 * math.pi) == pytest.approx(0.0, abs=1e-9)


def test_estimate_layout():
    e = Estimator(0.1)
    m = _meas(roll=0.2, pitch=0.1, alpha=0.05, beta=0.01)
    m[M_P] = 0.03
    assert e.update(m)
    assert e.est[E_ALPHA] == 0.05 and e.est[E_BETA] == 0.01 and e.est[E_P] == 0.03
    assert e.est[E_V] == 2000.0 and e.est[E_H] == 21000.0
    mu, gamma = mu_gamma(0.2, 0.1, 0.05, 0.01)
    assert e.est[E_MU] == mu and e.est[E_GAMMA] == gamma


@pytest.mark.parametrize("field,bad", [(M_AOA, math.nan), (M_AOA, 3.0), (M_AIRSPEED, -5.0),
                                       (M_ALT, math.inf), (M_ROLL, 7.0), (M_YAW, math.nan)])
def test_invalid_field_holds_last_good_and_flags(field, bad):
    e = Estimator(0.1)
    good = _meas(t=1.0, alpha=0.05)
    assert e.update(good)
    before = e.est.copy()
    m = _meas(t=1.002, alpha=0.05)
    m[field] = bad
    healthy = e.update(m)
    assert e.invalid_mask & (1 << field)
    assert np.array_equal(e.est, before)
    assert healthy           # one bad sample is held, not yet stale
    assert e.invalid_frames == 1


def test_held_field_becomes_stale_and_unhealthy():
    e = Estimator(stale_s=0.05)
    assert e.update(_meas(t=1.0))
    t = 1.0
    for _ in range(40):                       # 80 ms of frames with a NaN angle of attack
        t += 0.002
        m = _meas(t=t)
        m[M_AOA] = math.nan
        e.update(m)
    assert not e.healthy
    assert e.stale_mask & (1 << M_AOA)
    assert e.update(_meas(t=t + 0.002))       # a good value again: healthy
    assert e.stale_mask == 0


def test_old_stamp_is_ignored_and_flagged():
    e = Estimator(0.1)
    e.update(_meas(t=2.0, alpha=0.05))
    e.update(_meas(t=1.0, alpha=0.2))
    assert e.invalid_mask & FLAG_OLD_STAMP
    assert e.est[E_ALPHA] == 0.05


def test_never_seen_is_unhealthy():
    e = Estimator(0.1)
    m = _meas()
    m[M_AIRSPEED] = math.nan
    assert not e.update(m)


def test_accept_is_the_copy_then_update_in_one_call():
    # GIVEN two estimators fed the same frames, one through update(meas) after a copy, the
    # other through accept(frame, meas) (the frame intake's one compiled call)
    rng = np.random.default_rng(5)
    a, b = Estimator(0.1), Estimator(0.1)
    ma, mb = np.zeros(M_N), np.zeros(M_N)
    for k in range(50):
        frame = rng.normal(0.0, 0.2, M_N)
        frame[M_T_S] = 0.002 * k
        frame[M_AIRSPEED], frame[M_ALT] = 2000.0 + k, 20000.0
        if k % 7 == 3:
            frame[M_AOA] = math.nan             # an invalid field now and then
        ma[:] = frame
        ha = a.update(ma)
        hb = b.accept(frame, mb)
        # THEN meas, the estimate, the masks and the health are the same, bit for bit
        assert ha == hb == b.healthy
        assert np.array_equal(ma, mb, equal_nan=True) and np.array_equal(a.mem, b.mem,
                                                                          equal_nan=True)
    assert b.invalid_frames == a.invalid_frames > 0


def test_mu_gamma_match_plant_truth_over_a_bank_manoeuvre():
    """Closed loop in-process: PlantSim (sensor noise on) -> estimator -> law -> PlantSim."""
    sim_mod = pytest.importorskip("plant_sim.sim")
    from fc.control.law import AttitudeLaw
    from plant_sim.scenario import load

    sim = sim_mod.PlantSim(load("paper"), seed=3)
    col = {n: i for i, n in enumerate(sim_mod.TRUTH_NAMES)}
    est, law = Estimator(0.1), AttitudeLaw()
    m, row = np.zeros(M_N), np.zeros(sim_mod.TRUTH_N)
    sim.measure(m)
    est.update(m)
    law.reset(est.est)
    cmd = np.radians([5.0, 0.0, 4.0])
    dt = sim.frame_dt_s
    n = int(5.0 / dt)
    out = np.zeros((n, 4))
    for k in range(n):
        sim.measure(m)
        assert est.update(m)
        if k % 5 == 0:
            law.slow_step(est.est, cmd, 5 * dt)
        law.fast_step(est.est, dt)
        sim.command(law.delta_cmd_rad)
        sim.truth_row(row)
        out[k] = row[col["mu_rad"]], est.est[E_MU], row[col["gamma_rad"]], est.est[E_GAMMA]
        sim.advance()
    mu_err = np.degrees(out[:, 1] - out[:, 0])
    gamma_err = np.degrees(out[:, 3] - out[:, 2])
    print(f"mu error deg: rms {np.sqrt(np.mean(mu_err**2)):.4f} max {np.abs(mu_err).max():.4f}; "
          f"gamma error deg: rms {np.sqrt(np.mean(gamma_err**2)):.4f} max {np.abs(gamma_err).max():.4f}")
    assert np.degrees(np.ptp(out[:, 0])) > 2.0, "the manoeuvre must actually bank"
    assert np.degrees(np.ptp(out[:, 2])) > 1.0, "and change the flight-path angle"
    assert np.sqrt(np.mean(mu_err ** 2)) < 0.1 and np.abs(mu_err).max() < 0.5
    assert np.sqrt(np.mean(gamma_err ** 2)) < 0.1 and np.abs(gamma_err).max() < 0.5
