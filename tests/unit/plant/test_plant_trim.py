"""Moment trim against winged_cone.md section 6 ("Pitch trim (both elevons equal)")."""
import math

import numpy as np
import pytest

from plant_sim import dynamics as dy
from plant_sim.scenario import load, parse
from plant_sim.sim import PlantSim
from plant_sim.trim import trim_at, trim_report

DEG = math.pi / 180.0


def _nominal(x_cg):
    text = open(load("nominal").path).read().replace("x_cg_m = 0.0", f"x_cg_m = {x_cg}")
    return parse(text, f"nominal_xcg_{x_cg}")


@pytest.mark.parametrize("x_cg, alpha_deg, expected_deg", [
    (0.0, 1.0, 0.3), (0.0, 5.0, 7.9), (2.899, 1.0, -3.3), (2.899, 5.0, -9.5)])
def test_pitch_trim_matches_section6(x_cg, alpha_deg, expected_deg):
    r = trim_at(_nominal(x_cg), alpha_deg * DEG, 0.0)
    assert r.trimmed
    d = np.degrees(r.deflection_rad)
    assert d[0] == pytest.approx(d[1], abs=1e-9)          # symmetric at beta 0
    assert abs(d[2]) < 1e-9
    # section 6 divides the zero-deflection moment by the derivative at zero deflection (one
    # linear step: 7.94 deg at alpha 5, printed 7.9); the nonlinear trim is 7.953: 0.06 deg
    assert d[0] == pytest.approx(expected_deg, abs=0.06)
    assert np.all(np.abs(r.moment_left_N_m) < 1e-3)


def test_empty_mass_cg_saturates_pitch_trim_at_alpha5():
    # section 6: with x_cg 4.45 m the alpha 5 deg trim needs -21.9 deg (saturates)
    r = trim_at(_nominal(4.45), 5.0 * DEG, 0.0)
    assert not r.trimmed
    np.testing.assert_allclose(np.degrees(r.deflection_rad[:2]), [-20.0, -20.0], atol=1e-9)
    assert r.at_limit[:2] == (True, True)
    assert r.moment_left_N_m[1] > 1e5                       # nose-up moment left over


def test_initial_trim_holds_the_vehicle_still():
    sim = PlantSim(load("cg_aft"))                        # actuators.initial = "trim"
    assert np.any(np.abs(sim.trim_rad) > 1.0 * DEG)
    sim.p[dy.P_DIST_ON] = 0.0
    for _ in range(10):
        sim.step_frame(sim.trim_rad)
    assert np.all(np.abs(sim.x[dy.X_P:dy.X_R + 1]) < 2e-4)   # rad/s after 20 ms of an unstable airframe


def test_report_flags_the_paper_case_at_the_aft_cg():
    text = open(load("paper").path).read().replace("x_cg_m = 0.0", "x_cg_m = 2.90")
    report, ok = trim_report(parse(text, "paper_aft"))
    assert not ok and "NOT trimmable" in report
    report, ok = trim_report(load("paper"))
    assert ok and "NOT" not in report
