"""HIL tier: a mission flown end to end in lockstep (tools.hil, real fc and plant processes),
and MISSION's entry conditions in process.

The scripted ground station uploads plant_sim/scenarios/mission_short.waypoints (4 items, 90 km,
a speed change) over UDP and selects MISSION; the fc flies it through the guidance and reports
its progress (MISSION_ITEM_REACHED, MISSION_CURRENT), which the ground station records with the
vehicle's sim time (mission_progress.json). The plant's truth gives the track.
"""
from __future__ import annotations

import json
import math
import time
from pathlib import Path

import numpy as np
import pytest

from fc.app import FcConfig, FlightController
from fc.modes import FlightMode
from fc.params import build_table
from fc.link import new_codec
from tests.fc_harness import free_udp_port, level_meas
from tests.hil.test_hil_main import _hil
from tools.sitl.gcs import read_wpl

pytestmark = pytest.mark.hil

SHORT = "plant_sim/scenarios/mission_short.waypoints"
MISSION_COMPLETE = 5          # MISSION_STATE_COMPLETE


@pytest.fixture(scope="module")
def mission_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("mission") / "run"
    r = _hil("run", "--scenario", "mission", "--flight-mode", "MISSION", "--mission", SHORT,
             "--variant", "coordinated", "--duration", "45", "--seed", "1", "--out", str(out),
             "--no-plots", "--quiet")
    assert r.returncode == 0, f"tools.hil failed:\n{r.stdout}\n{r.stderr}"
    return out / "coordinated"


def test_mission_upload_and_progress_in_lockstep(mission_run):
    prog = json.loads((mission_run / "mission_progress.json").read_text())
    assert prog["acks"] == [0]                              # MAV_MISSION_ACCEPTED
    assert prog["requests"][:4] == [0, 1, 2, 3]
    # every item reported reached, in order, at increasing sim times within the run
    seqs = [s for _, s in prog["reached"]]
    times = [t for t, _ in prog["reached"]]
    assert seqs == [0, 1, 2, 3]
    assert all(b >= a for a, b in zip(times, times[1:])) and 0.0 < times[-1] < 45.0
    # MISSION_CURRENT went through the items and ended COMPLETE, total 4
    cur = prog["current"]
    assert cur[-1][1:] == [3, 4, MISSION_COMPLETE]
    assert {c[1] for c in cur} >= {0, 2, 3}


def _reached_positions(tlog) -> dict:
    """seq -> (lat, lon) deg of the last GLOBAL_POSITION_INT before each MISSION_ITEM_REACHED
    in the fc's sim-paced .tlog (10 Hz of sim time: 225 m apart at Mach 7)."""
    from pymavlink import mavutil
    conn = mavutil.mavlink_connection(str(tlog), dialect="ardupilotmega")
    pos, out = None, {}
    while True:
        m = conn.recv_match(type=["GLOBAL_POSITION_INT", "MISSION_ITEM_REACHED"])
        if m is None:
            return out
        if m.get_type() == "GLOBAL_POSITION_INT":
            pos = (m.lat * 1e-7, m.lon * 1e-7)
        elif pos is not None:
            out[m.seq] = pos


def test_mission_waypoints_reached_where_the_law_says(mission_run):
    from fc.guidance.waypoints import leg_geometry, local_ne, switch_distance_m
    items = read_wpl(SHORT)
    home = (34.9054, -117.8839)
    ne = {s: local_ne(items[s]["x"] * 1e-7, items[s]["y"] * 1e-7, *home) for s in (0, 2, 3)}
    at = {s: local_ne(*p, *home) for s, p in _reached_positions(mission_run / "fc.tlog").items()}
    assert sorted(at) == [0, 1, 2, 3]
    # the last waypoint (no turn after it): switched within its 2 km acceptance radius, along
    # track, less than 1.5 km across the leg from wp 2 (the legs start at the waypoints while
    # the vehicle switched 18 km early at wp 0; the cross-track law's time constant, ~100 s, is
    # longer than this 40 s mission: a few hundred metres remain)
    _, e, to_go, _ = leg_geometry(ne[2], ne[3], at[3])
    assert -300.0 < to_go <= 2000.0 + 300.0 and abs(e) < 1500.0
    # wp 0 (1.9 deg turn after it): switched at the turn-anticipation distance (~15 km at the
    # bank the guidance commands, GE_MU_MAX less GE_MU_MARGIN) ahead
    chi1 = math.atan2(ne[2][1] - ne[0][1], ne[2][0] - ne[0][0])
    mu_max = math.radians(build_table().get("GE_MU_MAX") - build_table().get("GE_MU_MARGIN"))
    d = switch_distance_m(2250.0, mu_max, chi1, 2000.0)
    _, _, to_go0, _ = leg_geometry((0.0, 0.0), ne[0], at[0])
    assert abs(to_go0 - d) < 1000.0


def test_mission_flight_stays_in_the_envelope(mission_run):
    tr = np.load(mission_run / "truth.npz")
    # the speed item (2260 m/s) and the altitude (28 100 m) are being flown to
    assert tr["V_m_s"][-1] > 2252.0 and abs(tr["h_m"][-1] - 28100.0) < 150.0
    # no surface at its 20 deg limit
    for c in ("delta_left_rad", "delta_right_rad", "delta_rudder_rad"):
        assert np.max(np.abs(tr[c])) < math.radians(19.5)


def test_mission_mode_refused_without_mission_or_fix(tmp_path):
    # GIVEN an fc in process, armed in CRUISE, fed frames without GNSS
    cfg = FcConfig(plant_bind=("127.0.0.1", free_udp_port()), gcs=[("127.0.0.1", free_udp_port())],
                   gcs_bind=("127.0.0.1", free_udp_port()), out=str(tmp_path), arm=True,
                   flight_mode="CRUISE")
    fc = FlightController(cfg)
    try:
        for k in range(50):
            m = level_meas(k / 500.0, alpha_deg=3.9, V=2250.0, h=28000.0)
            fc.meas_scratch[:] = m
            fc.loops.lockstep_frame(int(round(m[0] * 1e6)), time.monotonic())
        # WHEN MISSION is requested with no mission THEN refused, mode kept
        ok, text = fc.request_mode(FlightMode.MISSION)
        assert not ok and "no mission" in text and fc.modes.mode == FlightMode.CRUISE
        # WHEN a mission is stored but there is no GNSS fix THEN refused for the fix
        gcs = new_codec(255, 190)
        for msg in (gcs.mission_count_encode(1, 1, 1, 0),
                    gcs.mission_item_int_encode(1, 1, 0, 0, 16, 0, 1, 0, 0, 0, 0, 352000000,
                                                -1178839000, 28000.0, 0)):
            msg.pack(gcs)
            fc.mission.handle(msg, 0.0)
        assert fc.mission.count == 1
        ok, text = fc.request_mode(FlightMode.MISSION)
        assert not ok and "no GNSS fix" in text and fc.modes.mode == FlightMode.CRUISE
        # the navigator takes its parameters from the fc's table (PARAM_SET while flying)
        fc.set_param("WP_ACCEPT_M", 5000.0)
        fc.set_param("WP_XT_ANG_DEG", 10.0)
        fc.mission_flight._params(fc)
        p = fc.mission_flight.nav.p
        assert p.accept_m == 5000.0 and p.chi_int_rad == pytest.approx(math.radians(10.0))
        fc.set_param("GE_MU_MAX", 25.0)
        fc.mission_flight._params(fc)
        assert p.mu_max_rad == pytest.approx(math.radians(25.0 - build_table().get("GE_MU_MARGIN")))
    finally:
        fc.close()


def test_mission_report_figures_and_plot(mission_run, tmp_path):
    from tools.mission_report import analyse, plot
    res = analyse(mission_run, Path(SHORT), (34.9054, -117.8839))
    assert res["reached"] == res["items"] == 4
    assert [r["seq"] for r in res["waypoints"]] == [0, 1, 2, 3]
    assert res["errors"]["beta_deg"]["max_abs"] < 0.5 and not res["surface_at_limit"]
    png = plot(mission_run, Path(SHORT), (34.9054, -117.8839),
               tmp_path / "m.png", "test")
    assert png.stat().st_size > 10_000


def test_nav_controller_output_reports_the_waypoint(mission_run):
    """In MISSION, NAV_CONTROLLER_OUTPUT (the sim-paced .tlog) carries the distance and bearing
    to the active waypoint and the leg's cross-track error."""
    from pymavlink import mavutil
    conn = mavutil.mavlink_connection(str(mission_run / "fc.tlog"), dialect="ardupilotmega")
    rows = []
    while True:
        m = conn.recv_match(type="NAV_CONTROLLER_OUTPUT")
        if m is None:
            break
        rows.append((m.wp_dist, m.target_bearing, m.xtrack_error))
    with_wp = [r for r in rows if 0 < r[0] < 65535]
    assert len(with_wp) > 10
    # the waypoints lie ~north (close to one, its bearing turns with the cross-track offset)
    assert all(abs(b) <= 8 for d, b, _ in with_wp if d > 10000)
    assert any(x != 0.0 for _, _, x in with_wp) and all(abs(x) < 5000 for _, _, x in with_wp)
