"""Ground-station safety and the standard commands (issue 21), in process: a FlightController
fed sensor frames and GNSS samples directly (no plant process; sockets on free loopback
ports), its ground-station handler called with real MAVLink messages.

- a mission cleared or replaced while MISSION flies it: CRUISE, holding, with a STATUSTEXT,
  and no law fault (before: ``law raised: IndexError('no mission item 0 (count 0)')``, FAILSAFE);
- a disarm in flight is DENIED unless forced (param2 21196);
- DO_SET_MODE in PX4's layout (MAVSDK's start_mission/hold/return_to_launch), an unknown
  mode DENIED, DO_SET_STANDARD_MODE for every advertised standard mode;
- NAV_RETURN_TO_LAUNCH, DO_REPOSITION (COMMAND_LONG and COMMAND_INT), DO_ORBIT,
  DO_CHANGE_SPEED in MISSION;
- fc.log stays bounded in every mode.
"""
from __future__ import annotations

import logging
import math
import time

import pytest

from fc.app import FcConfig, FlightController
from fc.gcs import MODE_BURST, _Command
from fc.guidance.waypoints import local_ne
from fc.link import G_ALT_M, G_FIX, G_LAT_DEG, G_LON_DEG, G_T_S, M_T_S, new_codec
from fc.link import mavlink as ML
from fc.modes import FORCE_DISARM, STANDARD_MODE, FlightMode
from tests.fc_harness import free_udp_port, level_meas
from tests.unit.fc.test_mission_protocol import _upload, _wp

LAT0, LON0 = 34.9054, -117.8839
V_M_S, H_M = 2250.0, 28000.0
R_EARTH_M = 6371000.0


class _Lines(logging.Handler):
    def __init__(self) -> None:
        super().__init__(logging.DEBUG)
        self.lines: list[str] = []

    def emit(self, record) -> None:
        self.lines.append(record.getMessage())


@pytest.fixture()
def vehicle(tmp_path):
    """An fc armed in CRUISE, flying north at Mach 7.5 / 28 km with a 3D fix (home set)."""
    log = logging.getLogger(f"fc.test.{id(tmp_path)}")
    log.setLevel(logging.DEBUG)
    log.propagate = False
    lines = _Lines()
    log.addHandler(lines)
    cfg = FcConfig(plant_bind=("127.0.0.1", free_udp_port()), gcs=[("127.0.0.1", free_udp_port())],
                   gcs_bind=("127.0.0.1", free_udp_port()), out=str(tmp_path), arm=True,
                   flight_mode="CRUISE")
    fc = FlightController(cfg, log)
    fc.test_lines = lines.lines
    fc.test_t = 0.0
    fly(fc, 0.2)
    assert fc.guid.engaged and fc.gcs.home is not None
    try:
        yield fc
    finally:
        fc.close()


def fly(fc, seconds: float) -> None:
    """Frames at the fast rate for ``seconds`` of sim time, a GNSS sample every 0.1 s (the
    vehicle flies north at V_M_S), the ground-station link serviced as the loop does."""
    n = int(round(seconds * fc.cfg.fast_hz))
    g = fc.plant.gps
    for _ in range(n):
        t = fc.test_t
        m = level_meas(t, alpha_deg=3.9, V=V_M_S, h=H_M)
        if fc.plant.gps_samples == 0 or t - g[G_T_S] >= 0.1 - 1e-9:
            g[G_FIX] = ML.GPS_FIX_TYPE_3D_FIX
            g[G_LAT_DEG] = LAT0 + math.degrees(V_M_S * t / R_EARTH_M)
            g[G_LON_DEG], g[G_ALT_M], g[G_T_S] = LON0, H_M, t
            fc.plant.gps_samples += 1
        fc.meas_scratch[:] = m
        fc.loops.lockstep_frame(int(round(m[M_T_S] * 1e6)), time.monotonic())
        fc.test_t = t + 1.0 / fc.cfg.fast_hz
    fc.gcs.service(time.monotonic())


GCS = new_codec(255, 190)


def command(fc, cmd: int, *p: float) -> int:
    """COMMAND_LONG ``cmd`` (params 1..7, missing ones 0) through the fc's command handler."""
    p = list(p) + [0.0] * (7 - len(p))
    msg = GCS.command_long_encode(1, 1, cmd, 0, *p)
    msg.pack(GCS)
    return fc.gcs._command_result(_Command(msg, False))


def command_int(fc, cmd: int, frame: int, p: tuple, x: int, y: int, z: float) -> int:
    msg = GCS.command_int_encode(1, 1, frame, cmd, 0, 0, *p, x, y, z)
    msg.pack(GCS)
    return fc.gcs._command_result(_Command(msg, True))


def texts(fc) -> str:
    return "\n".join(line for line in fc.test_lines if line.startswith("STATUSTEXT"))


def upload(fc, n: int = 2) -> None:
    """``n`` waypoints 300 km apart to the north at 28 km."""
    items = [_wp(GCS, k, LAT0 + 2.7 * (k + 1), LON0, H_M) for k in range(n)]
    out = _upload(GCS, fc.mission, items)
    assert out[0][:4] == ("ack", 255, 190, ML.MAV_MISSION_ACCEPTED)


# ------------------------------------------------------------------ a mission changed under MISSION
@pytest.mark.parametrize("change", ["clear", "empty upload", "replace"])
def test_mission_changed_while_flown_holds_in_cruise(vehicle, change):
    fc = vehicle
    upload(fc)
    assert fc.request_mode(FlightMode.MISSION)[0]
    fly(fc, 0.5)
    assert fc.modes.mode == FlightMode.MISSION
    h_before = fc.est.est[7]
    # WHEN the ground station changes the mission under it
    if change == "clear":
        msg = GCS.mission_clear_all_encode(1, 1, 0)
        msg.pack(GCS)
        fc.gcs._handle(msg, time.monotonic())
        assert fc.mission.count == 0
    elif change == "empty upload":
        _upload(GCS, fc.mission, [])
    else:
        upload(fc, 3)
    fly(fc, 0.5)
    # THEN it holds in CRUISE at the altitude, course and speed of that moment, says why, and
    # the law never raised
    assert fc.modes.mode == FlightMode.CRUISE
    assert fc.counters.law_errors == 0 and not fc.modes.fs_cause
    word = {"clear": "cleared", "empty upload": "cleared", "replace": "replaced"}[change]
    assert f"mission {word} while flying it: holding" in texts(fc)
    h_t, chi_t, v_t = fc.guidance_targets()
    assert abs(h_t - h_before) < 20.0 and abs(v_t - V_M_S) < 5.0
    assert abs(math.remainder(chi_t, 2 * math.pi)) < math.radians(2.0)   # north, as flown


def test_a_navigator_exception_holds_instead_of_a_law_fault(vehicle):
    fc = vehicle
    upload(fc)
    assert fc.request_mode(FlightMode.MISSION)[0]
    fly(fc, 0.2)

    def broken(*_a, **_k):
        raise RuntimeError("corrupt item")
    fc.mission_flight.nav.step = broken
    fly(fc, 0.3)
    assert fc.modes.mode == FlightMode.CRUISE and fc.counters.law_errors == 0
    assert "mission navigation failed (RuntimeError('corrupt item'))" in texts(fc)


def test_set_current_in_flight_is_not_an_edit(vehicle):
    fc = vehicle
    upload(fc, 3)
    assert fc.request_mode(FlightMode.MISSION)[0]
    fly(fc, 0.2)
    assert command(fc, ML.MAV_CMD_DO_SET_MISSION_CURRENT, 1) == ML.MAV_RESULT_ACCEPTED
    fly(fc, 0.3)
    assert fc.modes.mode == FlightMode.MISSION and fc.mission.current == 1


# ------------------------------------------------------------------ arming
def test_disarm_in_flight_is_refused_unless_forced(vehicle):
    fc = vehicle
    assert command(fc, ML.MAV_CMD_COMPONENT_ARM_DISARM, 0) == ML.MAV_RESULT_DENIED
    assert fc.modes.armed
    assert f"disarm refused: in flight (param2 {FORCE_DISARM} forces it)" in texts(fc)
    assert command(fc, ML.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1234) == ML.MAV_RESULT_DENIED
    assert command(fc, ML.MAV_CMD_COMPONENT_ARM_DISARM, 0, FORCE_DISARM) == \
        ML.MAV_RESULT_ACCEPTED
    assert not fc.modes.armed


def test_disarm_is_allowed_once_the_plant_ended_its_run(vehicle):
    fc = vehicle
    fc.plant.ended = True
    assert command(fc, ML.MAV_CMD_COMPONENT_ARM_DISARM, 0) == ML.MAV_RESULT_ACCEPTED


# ------------------------------------------------------------------ modes
def test_px4_layout_and_hyfc_numbers_and_unknown_modes(vehicle):
    fc = vehicle
    upload(fc)
    for p, want in (((1, 4, 4), FlightMode.MISSION),        # MAVSDK start_mission
                    ((1, 4, 3), FlightMode.CRUISE),         # hold / pause_mission
                    ((129, 4, 5), FlightMode.RTL),          # return_to_launch
                    ((1, 5, 0), FlightMode.GUIDED),         # the hyfc number
                    ((1, 6, 0), FlightMode.MISSION)):
        fc.gcs._mode_tokens = MODE_BURST         # (the rate limit: test_fc_input_limits.py)
        assert command(fc, ML.MAV_CMD_DO_SET_MODE, *p) == ML.MAV_RESULT_ACCEPTED, p
        fly(fc, 0.05)
        assert fc.modes.mode == want, p
    for p in ((1, 4, 2), (1, 4, 6), (1, 9, 0), (1, 2, 7), (1, math.nan, 0)):
        assert command(fc, ML.MAV_CMD_DO_SET_MODE, *p) == ML.MAV_RESULT_DENIED, p
        assert fc.modes.mode == FlightMode.MISSION
    assert "mode AUTO.TAKEOFF refused: no such mode on hyfc" in texts(fc)


@pytest.mark.parametrize("mode", sorted(STANDARD_MODE, key=int))
def test_every_advertised_standard_mode_can_be_set(vehicle, mode):
    fc = vehicle
    upload(fc)
    assert command(fc, ML.MAV_CMD_DO_SET_STANDARD_MODE, STANDARD_MODE[mode]) == \
        ML.MAV_RESULT_ACCEPTED
    assert fc.modes.mode == mode
    assert command(fc, ML.MAV_CMD_DO_SET_STANDARD_MODE, 2) == ML.MAV_RESULT_DENIED   # ORBIT


# ------------------------------------------------------------------ return, reposition, orbit
def _bearing_to(fc, lat, lon) -> float:
    g = fc.plant.gps
    x = local_ne(g[G_LAT_DEG], g[G_LON_DEG], *fc.gcs.home[:2])
    w = local_ne(lat, lon, *fc.gcs.home[:2])
    return math.atan2(w[1] - x[1], w[0] - x[0])


def test_return_to_launch_turns_for_home_at_the_same_altitude_and_speed(vehicle):
    fc = vehicle
    fly(fc, 2.0)                                 # 4.5 km north of home
    assert command(fc, ML.MAV_CMD_NAV_RETURN_TO_LAUNCH) == ML.MAV_RESULT_ACCEPTED
    fly(fc, 0.3)
    assert fc.modes.mode == FlightMode.RTL and fc.point_flight.what == "home"
    h_t, chi_t, v_t = fc.guidance_targets()
    assert abs(h_t - H_M) < 20.0 and abs(v_t - V_M_S) < 5.0
    # home is behind: the course target points at it (the cross-track law: on the leg)
    err = math.remainder(chi_t - _bearing_to(fc, *fc.gcs.home[:2]), 2 * math.pi)
    assert abs(err) < math.radians(1.0)


def test_reposition_long_and_int_fly_to_the_point_in_guided(vehicle):
    fc = vehicle
    lat, lon = LAT0 + 1.0, LON0 + 3.0            # north-east, ~300 km
    assert command(fc, ML.MAV_CMD_DO_REPOSITION, -1, 0, 0, math.nan, lat, lon, 28500.0) == \
        ML.MAV_RESULT_ACCEPTED
    fly(fc, 0.3)
    assert fc.modes.mode == FlightMode.GUIDED and fc.point_flight.active
    h_t, chi_t, _ = fc.guidance_targets()
    assert h_t == 28500.0
    assert abs(math.remainder(chi_t - _bearing_to(fc, lat, lon), 2 * math.pi)) < math.radians(1)
    # COMMAND_INT, degE7 and an altitude above home
    lat, lon = LAT0 - 1.0, LON0 + 1.0
    assert command_int(fc, ML.MAV_CMD_DO_REPOSITION, ML.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
                       (2300.0, 0, 0, math.nan), int(lat * 1e7), int(lon * 1e7), 300.0) == \
        ML.MAV_RESULT_ACCEPTED
    fly(fc, 0.3)
    h_t, chi_t, v_t = fc.guidance_targets()
    assert h_t == pytest.approx(fc.gcs.home[2] + 300.0) and v_t == 2300.0
    assert abs(math.remainder(chi_t - _bearing_to(fc, lat, lon), 2 * math.pi)) < math.radians(1)
    # outside the envelope: DENIED, with the reason
    assert command(fc, ML.MAV_CMD_DO_REPOSITION, -1, 0, 0, 0, lat, lon, 60000.0) == \
        ML.MAV_RESULT_DENIED
    assert "DO_REPOSITION refused: altitude 60000 m outside" in texts(fc)
    # a GUIDED course target ends the point
    assert command(fc, ML.MAV_CMD_GUIDED_CHANGE_HEADING, 0, 90.0) == ML.MAV_RESULT_ACCEPTED
    fly(fc, 0.3)
    assert not fc.point_flight.active
    assert fc.guidance_targets()[1] == pytest.approx(math.radians(90.0))


def test_orbit_below_the_turn_limit_is_refused_with_the_least_radius(vehicle):
    fc = vehicle
    assert command(fc, ML.MAV_CMD_DO_ORBIT, 50000.0, math.nan, 0, 0, math.nan, math.nan,
                   math.nan) == ML.MAV_RESULT_DENIED
    assert fc.modes.mode == FlightMode.CRUISE
    assert "DO_ORBIT refused: radius 50 km below the 1" in texts(fc)
    least = fc.point_flight.least_radius_m(fc)
    assert 1.0e6 < least < 1.5e6                 # Mach 7.5, 29.8 deg of bank: ~1200 km
    assert command(fc, ML.MAV_CMD_DO_ORBIT, -1.1 * least, math.nan, 0, 0, math.nan, math.nan,
                   math.nan) == ML.MAV_RESULT_ACCEPTED
    fly(fc, 0.3)
    assert fc.modes.mode == FlightMode.GUIDED and fc.point_flight.nav.arrived
    assert not fc.point_flight.nav.clockwise


def test_change_speed_is_accepted_in_mission_and_kept(vehicle):
    fc = vehicle
    upload(fc)
    assert fc.request_mode(FlightMode.MISSION)[0]
    fly(fc, 0.2)
    assert command(fc, ML.MAV_CMD_DO_CHANGE_SPEED, 0, 2300.0, -1) == ML.MAV_RESULT_ACCEPTED
    fly(fc, 0.5)                                 # several navigator steps
    assert fc.modes.mode == FlightMode.MISSION and fc.guidance_targets()[2] == 2300.0
    assert command(fc, ML.MAV_CMD_DO_CHANGE_SPEED, 0, 9000.0, -1) == ML.MAV_RESULT_DENIED


# ------------------------------------------------------------------ fc.log
def test_fc_log_is_bounded_in_every_mode(vehicle):
    """Each mode flown for 4 s of sim time (MISSION's navigator steps 40 times): at most 30
    fc.log lines a minute each, after the mode change's own lines (before: 10 a second in
    MISSION, ``guidance targets: ...`` on every navigator step)."""
    fc = vehicle
    upload(fc)
    rates = {}
    for mode in (FlightMode.COORDINATED, FlightMode.UNCOORDINATED, FlightMode.CRUISE,
                 FlightMode.GUIDED, FlightMode.MISSION, FlightMode.RTL, FlightMode.MANUAL,
                 FlightMode.FAILSAFE):
        ok, text = fc.request_mode(mode)
        assert ok, text
        fly(fc, 0.5)                             # the change's own lines
        n0 = len(fc.test_lines)
        fly(fc, 4.0)
        rates[mode.name] = (len(fc.test_lines) - n0) * 60.0 / 4.0
    print("fc.log lines per minute:", rates)
    assert max(rates.values()) <= 30.0, rates


# ------------------------------------------------------------------ refusal wording
def test_parameter_refusals_read_whole_and_name_the_parameter_once(vehicle):
    fc = vehicle
    assert fc.set_param("CO_FAC_EQ", 99) == "CO_FAC_EQ=99 outside [14, 19]"      # no " -"
    assert fc.set_param("CO_FAC_EQ", 15) == "CO_FAC_EQ=15 refused: must be 14 or 19"
    assert fc.set_param("FS_TIMEOUT_S", 1000.0).endswith("] s")                   # a unit
