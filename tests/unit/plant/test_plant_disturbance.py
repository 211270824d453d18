"""The paper's disturbance d(t), its unit and its per-axis phase (docs/plant.md)."""
from __future__ import annotations

import math
import re

import numpy as np
import pytest

from plant_sim.scenario import load, parse
from plant_sim.sim import PlantSim


def _dist_at_start(scenario) -> np.ndarray:
    sim = PlantSim(scenario)
    row = np.zeros(len(sim.TRUTH_NAMES))
    sim.truth_row(row)
    names = list(sim.TRUTH_NAMES)
    return row[[names.index(f"dist_{a}_rad_s2") for a in "pqr"]]


def test_paper_disturbance_at_t0_in_deg_s2():
    # GIVEN the paper scenario (A = 10 deg/s^2, phases 0) WHEN t = 0
    # THEN d = A [0.5 sin 0, 0.5 cos 0, 0.5 sin 0] = [0, 5, 0] deg/s^2, in rad/s^2 in the log
    d = _dist_at_start(load("paper"))
    assert d == pytest.approx([0.0, math.radians(5.0), 0.0], abs=1e-12)


def test_phase_shifts_each_axis():
    # GIVEN phases of 90, 90 and -90 deg on the three axes
    text = load("paper").to_toml()
    for key, value in (("phase_roll_deg", 90.0), ("phase_pitch_deg", 90.0),
                       ("phase_yaw_deg", -90.0)):
        text, n = re.subn(rf"(?m)^{key} = .*$", f"{key} = {value}", text)
        assert n == 1
    d = _dist_at_start(parse(text))
    # THEN at t = 0: 0.5 A sin(90 deg), 0.5 A cos(90 deg), 0.5 A sin(-90 deg)
    assert d == pytest.approx([math.radians(5.0), 0.0, -math.radians(5.0)], abs=1e-12)


# ---- d(t) as a moment coefficient (qbar_ref_Pa, envelope map b; docs/plant.md s. 8) ----------
def _with(text: str, **disturbance) -> str:
    for key, value in disturbance.items():
        text, n = re.subn(rf"(?m)^{key} = .*$", f"{key} = {value}", text)
        assert n == 1, key
    return text


def _qbar0(scenario) -> float:
    from plant_sim.atmosphere import A_N, A_RHO_KG_M3, us76
    o = np.zeros(A_N)
    us76(scenario.data["initial"]["h_m"], o)
    return 0.5 * o[A_RHO_KG_M3] * scenario.data["initial"]["V_m_s"] ** 2


def _angular_accel_of_disturbance(scenario, t_s: float) -> np.ndarray:
    """d as the dynamics apply it: omega_dot with d(t) minus omega_dot without (rad/s^2)."""
    from plant_sim import dynamics as dy
    sim = PlantSim(scenario)
    out = []
    for on in (1.0, 0.0):
        p = sim.p.copy()
        p[dy.P_DIST_ON] = on
        xdot = np.zeros(13)
        dy.deriv(sim.x[:13].copy(), t_s, 0.0, 0.0, 0.0, p, np.zeros(dy.W_N), xdot)
        out.append(xdot[dy.X_P:dy.X_R + 1].copy())
    return out[0] - out[1]


def test_coefficient_disturbance_equals_the_papers_at_the_reference_qbar():
    # GIVEN the paper scenario, d(t) as a coefficient referenced to its own initial qbar
    paper = load("paper")
    text = _with(paper.to_toml(), qbar_ref_Pa=repr(float(_qbar0(paper))))
    coef = parse(text)
    # THEN at the paper's point it is the paper's d, in the log and in the dynamics
    assert _dist_at_start(coef) == pytest.approx(_dist_at_start(paper), rel=1e-9, abs=1e-15)
    t_s = 0.7                                   # all three axes non-zero
    d_paper = _angular_accel_of_disturbance(paper, t_s)
    assert np.all(np.abs(d_paper) > 1e-3)
    np.testing.assert_allclose(_angular_accel_of_disturbance(coef, t_s), d_paper, rtol=1e-9)


def test_coefficient_disturbance_is_proportional_to_qbar():
    # GIVEN the same coefficient (paper's reference qbar) flown at 28 km (qbar ~ 2.5x lower)
    paper = load("paper")
    q_ref = _qbar0(paper)
    high = parse(_with(paper.to_toml(), h_m="28000.0"))
    coef_high = parse(_with(high.to_toml(), qbar_ref_Pa=repr(float(q_ref))))
    ratio = _qbar0(high) / q_ref
    assert 0.3 < ratio < 0.5
    # THEN the disturbance is the paper's times qbar / qbar_ref, in the log and the dynamics
    # (the plain d(t) does not change with altitude: it is an angular acceleration)
    np.testing.assert_allclose(_dist_at_start(coef_high), ratio * _dist_at_start(high),
                               rtol=1e-6, atol=1e-15)
    t_s = 0.7
    np.testing.assert_allclose(_angular_accel_of_disturbance(coef_high, t_s),
                               ratio * _angular_accel_of_disturbance(high, t_s), rtol=1e-6)
    np.testing.assert_allclose(_angular_accel_of_disturbance(high, t_s),
                               _angular_accel_of_disturbance(paper, t_s), rtol=1e-12)


# ---- d(t) switched off at end_s (the envelope's release test) --------------------------------
def test_disturbance_end_switches_d_off_from_that_time_on():
    # GIVEN the paper's d(t) with end_s = 1.0 s
    paper = load("paper")
    ended = parse(_with(paper.to_toml(), end_s="1.0"))
    # THEN before 1 s it is the paper's, from 1 s on it is zero in the dynamics
    np.testing.assert_allclose(_angular_accel_of_disturbance(ended, 0.7),
                               _angular_accel_of_disturbance(paper, 0.7), rtol=1e-12)
    assert np.all(np.abs(_angular_accel_of_disturbance(paper, 1.3)) > 1e-3)
    assert np.all(_angular_accel_of_disturbance(ended, 1.0) == 0.0)
    assert np.all(_angular_accel_of_disturbance(ended, 1.3) == 0.0)
    # and end_s = 0 (the default) keeps d for the whole flight
    assert paper.data["disturbance"]["end_s"] == 0.0


def test_disturbance_end_is_refused_when_negative():
    from plant_sim.scenario import ScenarioError
    with pytest.raises(ScenarioError):
        parse(_with(load("paper").to_toml(), end_s="-1.0"))
