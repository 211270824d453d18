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
