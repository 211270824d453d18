"""tools.sitl.rig's steady-flight checks (the reliability promises' bounds) on made-up logs:
the window, the bounds per channel, a missing target (NaN) counted as a violation, and the
prefilter parameter the rig adds in the guidance modes."""
from __future__ import annotations

import math

import numpy as np

from tools.sitl.rig import RigConfig, STEADY_BOUNDS, steady_violations, time_window


def _fig(**over):
    fig = {"alt_err_max_m": 1.0, "course_err_max_deg": 0.01, "speed_err_max_m_s": 1.0,
           "inner_cmd_err_max_deg": [0.1, 0.1, 0.1]}
    fig.update(over)
    return fig


def test_a_steady_flight_has_no_violation():
    assert steady_violations(_fig()) == []


def test_each_bound_is_checked_per_channel():
    assert steady_violations(_fig(alt_err_max_m=10.5)) == ["alt_err_max_m [10.5] > 10.0"]
    # mu has a wider bound (1.5 deg) than alpha and beta (1.0 deg)
    assert steady_violations(_fig(inner_cmd_err_max_deg=[0.1, 0.1, 1.2])) == []
    v = steady_violations(_fig(inner_cmd_err_max_deg=[0.1, 1.2, 0.1]))
    assert len(v) == 1 and v[0].startswith("inner_cmd_err_max_deg")
    assert set(STEADY_BOUNDS) <= set(_fig())


def test_a_missing_target_is_a_violation():
    v = steady_violations(_fig(alt_err_max_m=math.nan, speed_err_max_m_s=math.nan))
    assert len(v) == 2


def test_time_window_keeps_the_rows_inside():
    log = {"t_s": np.arange(10.0), "x": np.arange(10.0) * 2}
    w = time_window(log, 3.0, 6.0)
    assert list(w["t_s"]) == [3.0, 4.0, 5.0] and list(w["x"]) == [6.0, 8.0, 10.0]


def test_the_rig_turns_the_prefilter_on_in_the_guidance_modes_only():
    assert RigConfig(out="x").fc_params() == {"REF_PF_EN": 1.0}
    assert RigConfig(out="x", params={"REF_PF_EN": 0.0}).fc_params() == {"REF_PF_EN": 0.0}
    assert RigConfig(out="x", flight_mode="COORDINATED", scenario="paper").fc_params() == {}
    assert RigConfig(out="x", arm="no").fc_params() == {}
