"""HIL tier: the ground-station commands SITL users expect, with the real clients (issue 21).

The fc (lockstep, armed in CRUISE) and the cruise scenario's plant as two processes, the
plant open-ended (Mach 7.5, 28 km, north from the origin, GNSS on); a scripted ground station
on a second telemetry output watches the vehicle (HEARTBEAT, GLOBAL_POSITION_INT,
NAV_CONTROLLER_OUTPUT, STATUSTEXT). Every wait is bounded; the processes are stopped at the end.

- MAVSDK: upload a mission, ``start_mission`` flies MISSION and ``mission_progress`` advances,
  ``disarm`` in flight is refused, ``return_to_launch`` turns for home, ``goto_location``
  flies to the point, ``hold`` holds (CRUISE);
- MAVProxy (with tools/mavproxy_hyfc.py): ``wp load``, ``mode MISSION``, ``wp clear`` in
  MISSION: CRUISE, holding the altitude, with the reason on the console.

Each test prints a transcript (``pytest -s``); docs/fc.md quotes them.
"""
from __future__ import annotations

import importlib.util
import math
import os
import sys
import time

import pytest

from tests.fc_harness import REPO, FcProcess, free_udp_port, mavlink as ML
from tools.sitl.gcs import ScriptedGcs
from tools.sitl.procs import Child, repo_env

pytestmark = pytest.mark.hil

LAT0, LON0 = 34.9054, -117.8839          # the cruise scenario's origin (home)
CRUISE, GUIDED, MISSION, RTL = 4, 5, 6, 7
WAIT_S = 120.0                           # the longest wait for the vehicle (wall clock)


@pytest.fixture()
def flight(tmp_path):
    """(fc, scripted gcs, the second output port for a client, transcript list)."""
    out = tmp_path / "fc"
    out.mkdir()
    (out / "params.parm").write_text("FS_TIMEOUT_S 30\n")    # a loaded machine pauses the plant
    client_port, gcs_port = free_udp_port(), free_udp_port()
    with FcProcess(str(out), "--arm", "--flight-mode", "CRUISE",
                   gcs_ports=(client_port, gcs_port)) as fc:
        gcs = ScriptedGcs(port=gcs_port)
        plant = Child("plant", [sys.executable, "-m", "plant_sim", "run", "--scenario", "cruise",
                                "--mode", "lockstep", "--fc", f"127.0.0.1:{fc.plant_port}",
                                "--bind", "127.0.0.1:0", "--out", str(tmp_path / "plant"),
                                "--duration", "0", "--seed", "1"],
                      tmp_path / "plant.console", env=repo_env(), cwd=REPO)
        lines: list[str] = []
        try:
            assert gcs.wait_text("home set", WAIT_S) is not None, "no GNSS fix"
            yield fc, gcs, client_port, lines
        finally:
            plant.stop()
            gcs.close()
            print("\n".join(lines))


def _pos(gcs, timeout_s: float = 10.0):
    """The newest GLOBAL_POSITION_INT: (lat deg, lon deg, alt m AMSL)."""
    gcs.drain()
    m = gcs.wait("GLOBAL_POSITION_INT", timeout_s)
    assert m is not None
    return m.lat * 1e-7, m.lon * 1e-7, m.alt * 1e-3


def _bearing_deg(a, b) -> float:
    """Bearing (deg, -180..180) from (lat, lon) a to b on the flat map (small distances)."""
    dn = b[0] - a[0]
    de = (b[1] - a[1]) * math.cos(math.radians(a[0]))
    return math.degrees(math.atan2(de, dn))


def _say(lines, gcs, text: str) -> None:
    lat, lon, alt = _pos(gcs)
    lines.append(f"[{time.strftime('%H:%M:%S')}] {text:<58} lat {lat:.4f} lon {lon:.4f} "
                 f"alt {alt:.0f} m")


def _wait_mode(gcs, number: int, timeout_s: float = 15.0):
    return gcs.wait("HEARTBEAT", timeout_s, cond=lambda m: m.custom_mode & 0xFFFF == number)


def _mavsdk():
    if importlib.util.find_spec("mavsdk") is None:
        pytest.skip("mavsdk is not installed (pip install -e .[test])")
    import mavsdk
    if int(mavsdk.__version__.split(".")[0]) < 4:
        pytest.skip(f"mavsdk {mavsdk.__version__}: the test drives the native binding (>= 4)")
    return mavsdk


def test_mavsdk_mission_progress_disarm_refused_rtl_and_goto(flight):
    _mavsdk()
    from mavsdk import ComponentType, Configuration, Mavsdk
    from mavsdk.plugins.action import Action, ActionError
    from mavsdk.plugins.mission import Mission, MissionItem, MissionPlan
    from mavsdk.plugins.telemetry import FlightMode, Telemetry
    fc, gcs, port, lines = flight
    sdk = Mavsdk(Configuration.create_with_component_type(ComponentType.GROUND_STATION))
    try:
        assert sdk.add_any_connection(f"udpin://127.0.0.1:{port}").name == "SUCCESS"
        system = sdk.first_autopilot(20.0)
        assert system is not None, "MAVSDK found no autopilot"
        mission, action, telemetry = Mission(system), Action(system), Telemetry(system)
        # GIVEN a three-waypoint mission ahead (north, at home's altitude)
        lat, lon, alt0 = _pos(gcs)
        items = [MissionItem(latitude_deg=lat + d, longitude_deg=LON0, relative_altitude_m=0.0,
                             is_fly_through=True)          # MAVSDK's defaults otherwise
                 for d in (0.1, 0.2, 0.3)]
        mission.upload_mission(MissionPlan(items))
        _say(lines, gcs, "MAVSDK upload_mission: 3 items: SUCCESS")
        # WHEN start_mission THEN MISSION, and the progress advances
        mission.start_mission()
        assert _wait_mode(gcs, MISSION) is not None
        deadline = time.monotonic() + 15.0
        while telemetry.flight_mode() != FlightMode.MISSION and time.monotonic() < deadline:
            time.sleep(0.1)
        assert telemetry.flight_mode() == FlightMode.MISSION
        _say(lines, gcs, "MAVSDK start_mission: SUCCESS, flight_mode MISSION")
        seen = []
        deadline = time.monotonic() + WAIT_S
        while time.monotonic() < deadline:
            p = mission.mission_progress()
            if not seen or (p.current, p.total) != seen[-1]:
                seen.append((p.current, p.total))
                _say(lines, gcs, f"MAVSDK mission_progress: {p.current}/{p.total}")
            if p.current >= 2:
                break
            time.sleep(0.2)
        assert seen[-1][0] >= 2 and seen[-1][1] == 3, seen
        # WHEN a plain disarm in flight THEN refused, still armed
        with pytest.raises(ActionError) as err:
            action.disarm()
        assert telemetry.armed()
        _say(lines, gcs, f"MAVSDK disarm: {err.value.result.name} (still armed)")
        # WHEN return_to_launch THEN RTL, the course target points home, the altitude holds
        action.return_to_launch()
        assert _wait_mode(gcs, RTL) is not None
        where = _pos(gcs)
        home_bearing = _bearing_deg(where, (LAT0, LON0))
        nav = gcs.wait("NAV_CONTROLLER_OUTPUT", 10,
                       cond=lambda m: abs((m.nav_bearing - home_bearing + 180) % 360 - 180) < 3)
        assert nav is not None, f"no course target toward home ({home_bearing:.0f} deg)"
        _say(lines, gcs, f"MAVSDK return_to_launch: SUCCESS, flight_mode "
                         f"{telemetry.flight_mode().name}, course target {nav.nav_bearing} deg "
                         f"(home at {home_bearing:.0f} deg)")
        bank = gcs.wait("ATTITUDE", WAIT_S, cond=lambda m: abs(math.degrees(m.roll)) > 10.0)
        assert bank is not None, "no turn toward home"
        _say(lines, gcs, f"RTL turning for home: roll {math.degrees(bank.roll):.1f} deg")
        assert abs(_pos(gcs)[2] - where[2]) < 150.0
        # WHEN goto_location (to the east) THEN GUIDED, the course target toward the point
        target = (where[0], where[1] + 2.0)
        action.goto_location(target[0], target[1], 28200.0, float("nan"))
        assert _wait_mode(gcs, GUIDED) is not None
        here = _pos(gcs)
        brg = _bearing_deg(here, target)
        nav = gcs.wait("NAV_CONTROLLER_OUTPUT", 10,
                       cond=lambda m: abs((m.nav_bearing - brg + 180) % 360 - 180) < 3
                       and abs(m.alt_error - (28200.0 - here[2])) < 100.0)
        assert nav is not None, f"no course target toward the point ({brg:.0f} deg)"
        _say(lines, gcs, f"MAVSDK goto_location: SUCCESS, GUIDED, course target "
                         f"{nav.nav_bearing} deg (point at {brg:.0f} deg), altitude target "
                         f"28200 m")
        # WHEN hold (PX4 AUTO.LOITER) THEN CRUISE: the altitude, course and speed held
        action.hold()
        assert _wait_mode(gcs, CRUISE) is not None
        _say(lines, gcs, "MAVSDK hold: SUCCESS, CRUISE (holding)")
        assert fc.proc.poll() is None
    finally:
        sdk.destroy()


# --------------------------------------------------------------------------------- MAVProxy
def test_mavproxy_wp_clear_in_mission_holds_in_cruise(flight, tmp_path):
    if importlib.util.find_spec("MAVProxy") is None:
        pytest.skip("MAVProxy is not installed (pip install -e .[test])")
    from tests.hil.test_mavproxy_fc import _Console
    fc, gcs, port, lines = flight
    lat, _, alt0 = _pos(gcs)
    wpl = tmp_path / "ahead.waypoints"
    wpl.write_text("QGC WPL 110\n" + "".join(
        f"{k}\t0\t0\t16\t0\t0\t0\t0\t{lat + 0.3 * (k + 1):.7f}\t{LON0:.7f}\t{alt0:.1f}\t1\n"
        for k in range(3)))
    con = _Console([sys.executable, "-m", "MAVProxy.mavproxy",
                    f"--master=udpin:127.0.0.1:{port}", "--no-state",
                    "--default-modules=link,param,misc,mode,wp",
                    "--load-module", "tools.mavproxy_hyfc", "--cmd=set param_ftp 0"],
                   str(tmp_path))
    try:
        con.expect("Mode CRUISE", 60)
        con.send(f"wp load {wpl}")
        con.expect("Sent all 3 waypoints", 60)
        con.send("mode MISSION")
        con.expect("AP: mode MISSION", 30)
        assert _wait_mode(gcs, MISSION) is not None
        gcs.wait("MISSION_CURRENT", 30, cond=lambda m: m.mission_state == 3)   # ACTIVE
        before = _pos(gcs)
        _say(lines, gcs, "MAVProxy: wp load (3 items), mode MISSION: flying it")
        con.send("wp clear")
        con.expect("AP: mission cleared while flying it", 30)
        # (MAVProxy announces a mode at most every 2 s and not the one it announced last,
        # CRUISE: the HEARTBEAT says it)
        assert _wait_mode(gcs, CRUISE) is not None
        _say(lines, gcs, "MAVProxy: wp clear -> AP: mission cleared ..., HEARTBEAT CRUISE")
        t_sim = gcs.wait("DEBUG_VECT", 5, cond=lambda m: m.name == "SIM_T")
        later = gcs.wait("DEBUG_VECT", WAIT_S,
                         cond=lambda m: m.name == "SIM_T" and m.x > t_sim.x + 20.0)
        assert later is not None, "the flight did not go on for 20 s of sim time"
        after = _pos(gcs)
        _say(lines, gcs, f"20 s of sim time later (altitude {after[2] - before[2]:+.0f} m)")
        hb = gcs.wait("HEARTBEAT", 5)
        assert hb.custom_mode & 0xFFFF == CRUISE and hb.system_status == ML.MAV_STATE_ACTIVE
        assert abs(after[2] - before[2]) < 100.0
    finally:
        con.close()
    console = "\n".join(con.out)
    lines.append("--- MAVProxy console (the wp clear moment) ---")
    lines += [ln for ln in con.out if "AP:" in ln or "Mode" in ln or "waypoint" in ln.lower()]
    assert "FAILSAFE" not in console and "law fault" not in console
    with open(os.path.join(fc.out, "fc.log")) as f:
        assert "law raised" not in f.read()
