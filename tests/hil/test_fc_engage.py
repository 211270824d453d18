"""The law engages from the first healthy estimate, not from the empty pre-data estimate.

``python -m fc --arm --flight-mode COORDINATED`` engages the law before any plant data exists.
Resetting the law then would start its integrators, prefilter and observer from alpha = beta = 0,
V = 0 (measured on the paper scenario in real time: after 3 s, mu error 2.0 deg vs 0.35 deg when
armed after data arrived). The fc defers the reset to the first healthy frame.
"""
from __future__ import annotations

import math

import pytest

from fc.internals_log import load
from tests.fc_harness import FcProcess, ScriptedPlant, level_meas

pytestmark = pytest.mark.hil     # the fc as a real process over loopback UDP


def test_law_armed_before_data_starts_from_first_healthy_frame(tmp_path):
    # GIVEN the fc armed in COORDINATED from its command line, with the reference prefilter on
    params = tmp_path / "params.parm"
    params.write_text("REF_PF_EN 1\n")
    with FcProcess(str(tmp_path), "--arm", "--flight-mode", "COORDINATED",
                   "--params", str(params)) as fc:
        plant = ScriptedPlant(fc.plant_port)
        try:
            # WHEN the first frames arrive at alpha 1 deg, beta 5 deg
            for k in range(3):
                plant.exchange(level_meas(0.002 * k, alpha_deg=1.0, beta_deg=5.0))
        finally:
            plant.close()
        assert fc.stop() == 0
    log = load(str(tmp_path))
    # THEN the prefilter's reference starts at the measured state (it moves by far less than
    # 0.1 deg in one 2 ms tick at wn 2 rad/s), not at the zero pre-data estimate
    assert math.degrees(log["law_alpha_ref_rad"][0]) == \
        pytest.approx(1.0, abs=0.1)
    assert math.degrees(log["law_beta_ref_rad"][0]) == \
        pytest.approx(5.0, abs=0.1)
