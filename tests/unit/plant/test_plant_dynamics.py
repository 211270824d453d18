"""Rigid-body checks of the plant's 6-DOF RK4 integrator (plant_sim/dynamics.py)."""
import math

import numpy as np
import pytest

from plant_sim import dynamics as dy
from plant_sim.atmosphere import G0_M_S2, R_EARTH_M
from plant_sim.scenario import load, parse
from plant_sim.sim import PlantSim

DEG = math.pi / 180.0


def _no_aero(sim):
    """Switch off aerodynamic forces and moments, thrust and the disturbance."""
    sim.p[dy.P_UNC:dy.P_UNC + 6] = 0.0
    sim.p[dy.P_SPEED_MODE] = dy.SPEED_NONE
    sim.p[dy.P_DIST_ON] = 0.0


def _c_nb(x):
    q0, q1, q2, q3 = x[dy.X_Q0:dy.X_Q3 + 1]
    return np.array([
        [q0*q0 + q1*q1 - q2*q2 - q3*q3, 2*(q1*q2 - q0*q3), 2*(q1*q3 + q0*q2)],
        [2*(q1*q2 + q0*q3), q0*q0 - q1*q1 + q2*q2 - q3*q3, 2*(q2*q3 - q0*q1)],
        [2*(q1*q3 - q0*q2), 2*(q2*q3 + q0*q1), q0*q0 - q1*q1 - q2*q2 + q3*q3]])


def test_torque_free_motion_conserves_momentum_and_energy():
    # GIVEN a tumbling body (distinct inertias, Ixz != 0) with no external moment
    text = open(load("nominal").path).read()
    text = text.replace("Ixz_kg_m2 = 0.0", "Ixz_kg_m2 = 4.0e5")
    text = text.replace("p_deg_s = 0.0", "p_deg_s = 40.0").replace("q_deg_s = 0.0", "q_deg_s = -25.0")
    text = text.replace("r_deg_s = 0.0", "r_deg_s = 30.0")
    sim = PlantSim(parse(text, "torque_free"))
    _no_aero(sim)
    x, p = sim.x, sim.p
    inertia = np.array([[p[dy.P_IXX], 0, -p[dy.P_IXZ]], [0, p[dy.P_IYY], 0], [-p[dy.P_IXZ], 0, p[dy.P_IZZ]]])

    def invariants():
        w = x[dy.X_P:dy.X_R + 1]
        return _c_nb(x) @ (inertia @ w), 0.5 * w @ inertia @ w

    h0, e0 = invariants()
    cmd = np.zeros(3)
    # WHEN it turns for 10 s (several tumbling periods) at 1 kHz
    for _ in range(int(10.0 / sim.frame_dt_s)):
        sim.step_frame(cmd)
    h1, e1 = invariants()
    # THEN inertial angular momentum and rotational energy hold to RK4 accuracy
    assert np.linalg.norm(h1 - h0) / np.linalg.norm(h0) < 1e-9
    assert abs(e1 - e0) / e0 < 1e-9
    # and the rates did change (it is a real tumble, not a trivial spin)
    assert abs(x[dy.X_Q] - (-25.0 * DEG)) > 1e-3


def test_ballistic_flight_matches_closed_form():
    # GIVEN no aerodynamics or thrust, launched at gamma 10 deg
    text = open(load("nominal").path).read().replace("gamma_deg = 0.0", "gamma_deg = 10.0")
    sim = PlantSim(parse(text, "ballistic"))
    _no_aero(sim)
    x = sim.x
    v0 = 2200.0
    vn0, vd0 = v0 * math.cos(10 * DEG), -v0 * math.sin(10 * DEG)
    h0 = 21000.0
    cmd = np.zeros(3)
    t_end = 8.0
    for _ in range(int(round(t_end / sim.frame_dt_s))):
        sim.step_frame(cmd)
    assert sim.t_s == pytest.approx(t_end, abs=1e-12)
    v_ned = _c_nb(x) @ x[dy.X_U:dy.X_W + 1]
    # THEN horizontal motion is uniform ...
    assert v_ned[0] == pytest.approx(vn0, abs=1e-8)
    assert x[dy.X_PN] == pytest.approx(vn0 * t_end, abs=1e-6)
    assert abs(x[dy.X_PE]) < 1e-9 and abs(v_ned[1]) < 1e-9
    # ... energy with inverse-square gravity is conserved exactly (closed-form invariant) ...
    def energy(vd, h):
        return 0.5 * vd * vd - G0_M_S2 * R_EARTH_M**2 / (R_EARTH_M + h)
    h1 = -x[dy.X_PD]
    assert energy(v_ned[2], h1) == pytest.approx(energy(vd0, h0), abs=1e-6)
    # ... and the altitude agrees with the constant-g parabola to the gravity change (< 0.1 m)
    g_mid = G0_M_S2 * (R_EARTH_M / (R_EARTH_M + 0.5 * (h0 + h1)))**2
    h_closed = h0 - vd0 * t_end - 0.5 * g_mid * t_end**2
    assert h1 == pytest.approx(h_closed, abs=0.1)
    # body rates untouched, attitude fixed
    assert np.all(np.abs(x[dy.X_P:dy.X_R + 1]) < 1e-15)


def test_symmetric_flight_stays_symmetric():
    # GIVEN symmetric initial flight (beta 0, mu 0, no rates), equal elevons, zero rudder
    text = open(load("nominal").path).read().replace("beta_deg = 5.0", "beta_deg = 0.0", 1)
    sim = PlantSim(parse(text, "symmetric"))
    cmd = np.array([3.0 * DEG, 3.0 * DEG, 0.0])
    row = np.zeros(sim.TRUTH_N)
    names = sim.TRUTH_NAMES
    for _ in range(int(3.0 / sim.frame_dt_s)):
        sim.step_frame(cmd)
    sim.truth_row(row)
    r = dict(zip(names, row))
    # THEN the lateral states stay exactly zero while the longitudinal ones move
    for k in ("beta_rad", "p_rad_s", "r_rad_s", "mu_rad", "phi_rad", "psi_rad", "v_m_s", "pos_e_m"):
        assert abs(r[k]) < 1e-12, k
    assert abs(r["q_rad_s"]) > 1e-4
    assert abs(r["alpha_rad"] - 1.0 * DEG) > 1e-3


def test_initial_state_reproduces_the_scenario_angles():
    sim = PlantSim(load("paper"))
    row = np.zeros(sim.TRUTH_N)
    sim.truth_row(row)
    r = dict(zip(sim.TRUTH_NAMES, row))
    assert r["alpha_rad"] == pytest.approx(1.0 * DEG, abs=1e-12)
    assert r["beta_rad"] == pytest.approx(5.0 * DEG, abs=1e-12)
    assert r["mu_rad"] == pytest.approx(0.0, abs=1e-12)
    assert r["gamma_rad"] == pytest.approx(0.0, abs=1e-12)
    assert r["V_m_s"] == pytest.approx(2200.0, abs=1e-9)
    assert r["h_m"] == 21000.0
    assert r["mach"] == pytest.approx(7.440, abs=5e-4)
    assert r["qbar_pa"] == pytest.approx(183230.0, abs=5.0)
    # section 6: initial moments about the MRC with the nominal model, scaled by the paper's -20 %
    assert r["moment_l_N_m"] == pytest.approx(-2.95e6 * 0.8, rel=2e-3)
    assert r["moment_n_N_m"] == pytest.approx(1.23e6 * 0.8, rel=4e-3)


def test_mu_and_gamma_from_a_banked_climbing_state():
    text = open(load("nominal").path).read()
    text = text.replace("mu_deg = 0.0", "mu_deg = 30.0", 1).replace("gamma_deg = 0.0", "gamma_deg = 7.0")
    text = text.replace("chi_deg = 0.0", "chi_deg = 120.0").replace("beta_deg = 5.0", "beta_deg = -3.0", 1)
    sim = PlantSim(parse(text, "banked"))
    out = np.zeros(4)
    dy.flight_path(sim.x, out)
    assert out[0] == pytest.approx(7.0 * DEG, abs=1e-12)
    assert out[1] == pytest.approx(120.0 * DEG, abs=1e-12)
    assert out[2] == pytest.approx(30.0 * DEG, abs=1e-12)


def test_speed_hold_holds_and_none_decays():
    cmd = np.zeros(3)
    hold = PlantSim(load("nominal"))
    for _ in range(int(2.0 / hold.frame_dt_s)):
        hold.step_frame(np.array([0.0, 0.0, 0.0]))
    row = np.zeros(hold.TRUTH_N)
    hold.truth_row(row)
    r = dict(zip(hold.TRUTH_NAMES, row))
    assert abs(r["V_m_s"] - 2200.0) < 0.5
    assert r["thrust_N"] > 0.0
    text = open(load("nominal").path).read().replace('model = "hold"', 'model = "none"')
    text = text.replace("beta_deg = 5.0", "beta_deg = 0.0", 1)
    free = PlantSim(parse(text, "nothrust"))
    # trim-free 1 s with zero surfaces: drag alone decelerates by about 2.5 m/s^2 (section "Speed")
    for _ in range(int(1.0 / free.frame_dt_s)):
        free.step_frame(cmd)
    free.truth_row(row)
    r = dict(zip(free.TRUTH_NAMES, row))
    assert 2200.0 - r["V_m_s"] == pytest.approx(2.5, abs=0.5)
    assert r["thrust_N"] == 0.0
