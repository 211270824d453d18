"""fc/modes.py ``decode_mode_request``: the one table of mode requests (DO_SET_MODE param2 /
param3, SET_MODE custom_mode), the standard modes, and the in-flight disarm rule. Pure."""
from __future__ import annotations

import math

import pytest

from fc.modes import (FORCE_DISARM, MODE_OF_STANDARD, MODE_WIRE, PX4_REQUEST, STANDARD_MODE,
                      FlightMode, ModeManager, decode_mode_request)

F = FlightMode
NAN = math.nan


@pytest.mark.parametrize("param2, param3, want", [
    # PX4's main/sub mode (MAVSDK's DO_SET_MODE param2/param3)
    (4, 4, F.MISSION),            # mission.start_mission (AUTO.MISSION)
    (4, 3, F.CRUISE),             # action.hold, mission.pause_mission (AUTO.LOITER): hold
    (4, 5, F.RTL),                # action.return_to_launch (AUTO.RTL)
    # hyfc's own number, param3 0 (MAVProxy ``long DO_SET_MODE 1 N``, pymavlink set_mode)
    (0, 0, F.MANUAL), (1, 0, F.COORDINATED), (2, 0, F.UNCOORDINATED), (3, 0, F.FAILSAFE),
    (4, 0, F.CRUISE), (5, 0, F.GUIDED), (6, 0, F.MISSION), (7, 0, F.RTL),
    (6, NAN, F.MISSION),          # param3 not given
    # a whole custom_mode: our HEARTBEAT value, or PX4's layout with the low 16 bits 0
    (0x00030004, 0, F.CRUISE), (0x00070002, 0, F.UNCOORDINATED), (0x00010003, 0, F.FAILSAFE),
    (0x04040000, 0, F.MISSION), (0x05040000, 0, F.RTL), (0x03040000, 0, F.CRUISE),
    (0x00030000, 0, F.CRUISE), (0x00060000, 0, F.GUIDED), (0x00070000, 0, F.COORDINATED),
    (0x00010000, 0, F.MANUAL), (0x04040006, 0, F.MISSION),   # SET_MODE's exact uint32
])
def test_requests_that_mean_a_mode(param2, param3, want):
    assert decode_mode_request(param2, param3) == (want, "")


@pytest.mark.parametrize("param2, param3, word", [
    (4, 2, "AUTO.TAKEOFF"), (4, 6, "AUTO.LAND"), (4, 1, "AUTO.READY"),
    (4, 8, "AUTO.FOLLOW_TARGET"), (3, 1, "PX4 3/1"), (2, 7, "PX4 2/7"),
    (8, 0, "unknown mode 8"), (42, 0, "unknown mode 42"),
    (0x00020000, 0, "ALTCTL"), (0x00050000, 0, "ACRO"), (0x02040000, 0, "AUTO.TAKEOFF"),
    (0x00070009, 0, "not a mode"),
    (0x04040008, 0, "not a mode"),    # MISSION's HEARTBEAT value rounded to a float32
    (NAN, 0, "not a mode"), (1.5, 0, "not a mode"), (-1, 0, "not a mode"),
    (4, 1.5, "not a mode"), (4, -4, "not a mode"), (math.inf, 0, "not a mode"),
])
def test_requests_without_a_match_are_refused_never_mapped(param2, param3, word):
    mode, why = decode_mode_request(param2, param3)
    assert mode is None and word in why and "refused" in why


def test_every_mode_is_reached_by_its_number_and_its_heartbeat_value_below_2_24():
    for mode in FlightMode:
        assert decode_mode_request(int(mode), 0)[0] == mode
        wire = MODE_WIRE[mode]
        if wire < 2**24:                          # exact in COMMAND_LONG's float param2
            assert decode_mode_request(float(wire), 0)[0] == mode


def test_every_px4_request_means_the_mode_we_advertise_as_that_px4_mode():
    """What MAVSDK shows for a HEARTBEAT of ours, requested back, gives that mode (the
    hold AUTO.LOITER, not advertised, is CRUISE)."""
    for mode, wire in MODE_WIRE.items():
        key = ((wire >> 16) & 0xFF, wire >> 24)
        if mode not in (F.UNCOORDINATED, F.FAILSAFE):   # they share PX4 modes with 1 and 0
            assert PX4_REQUEST[key] == mode, mode


def test_standard_modes_decode_to_the_modes_that_advertise_them():
    assert MODE_OF_STANDARD == {3: F.CRUISE, 6: F.MISSION, 5: F.RTL}
    for mode, std in STANDARD_MODE.items():
        assert MODE_OF_STANDARD[std] == mode


def test_disarm_in_the_air_needs_the_force_code():
    m = ModeManager()
    m.request_mode(F.CRUISE)
    assert m.set_armed(True, data_ok=True)[0]
    ok, text = m.set_armed(False, data_ok=True, in_air=True)
    assert not ok and m.armed and str(FORCE_DISARM) in text
    assert m.set_armed(False, data_ok=True, in_air=True, forced=True)[0] and not m.armed
    # on the ground (or disarmed already) nothing is needed
    assert m.set_armed(True, data_ok=True)[0]
    assert m.set_armed(False, data_ok=True, in_air=False)[0] and not m.armed
    assert m.set_armed(False, data_ok=True, in_air=True)[0]
