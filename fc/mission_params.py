"""The mission navigator's parameters (fc/guidance/waypoints.py NavParams), appended to the fc's
table by fc.params.build_table and read by MISSION mode (fc/mission_mode.py).

A module of their own so that fc.params (the table) and fc.mission_mode (the mode, which
reads the table) do not import each other (tests/unit/test_architecture.py: no import cycle,
deferred imports included).
"""
from __future__ import annotations

from fc.control.params import Param as ParamDef

__all__ = ["MISSION_PARAMS"]

#: The navigator's parameters (fc/guidance/waypoints.py NavParams), appended to the fc's table.
MISSION_PARAMS: tuple[ParamDef, ...] = (
    ParamDef("WP_ACCEPT_M", 2000.0, 100.0, 100000.0, "m", "mission",
             "Least acceptance radius of a waypoint, measured along the leg; an item's param2 "
             "> 0 overrides it. A turn is anticipated further out (docs/guidance.md 2a)."),
    ParamDef("WP_XT_LEN_M", 50000.0, 1000.0, 1000000.0, "m", "mission",
             "Cross-track length scale L_xt: the course target turns toward the leg by "
             "WP_XT_ANG_DEG (2/pi) atan(e / L_xt)."),
    ParamDef("WP_XT_ANG_DEG", 20.0, 1.0, 60.0, "deg", "mission",
             "Intercept angle toward the leg far from it (cross-track law)."),
)
