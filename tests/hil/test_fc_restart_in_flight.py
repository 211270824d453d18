"""HIL tier: the fc killed in flight and restarted keeps its mission and home (issue 22, item 7).

The fc and the plant run as processes in lockstep (the plant waits, re-sending its frame,
while the fc is away); a mission is uploaded and flown, the fc is killed (SIGKILL: no exit
path runs) and started again on the same run directory and plant port. The new fc reports
the first run's home (not the position at the restart, some km further on) and serves the same
mission at the same item (fc/mission_store.py).
"""
from __future__ import annotations

import json
import os
import signal
import sys
import time

import pytest

from tests.fc_harness import REPO, FcProcess, free_udp_port
from tools.sitl.gcs import ScriptedGcs, read_wpl
from tools.sitl.procs import Child

pytestmark = pytest.mark.hil

SHORT = "plant_sim/scenarios/mission_short.waypoints"
MISSION_MODE = 6


def _fc(out: str, plant_port: int, gcs_port: int) -> FcProcess:
    return FcProcess(out, "--plant-bind", f"127.0.0.1:{plant_port}", "--arm",
                     "--flight-mode", "CRUISE", gcs_ports=(gcs_port,))


def _wait_file(path: str, timeout_s: float, n_items: int) -> bool:
    """Wait (bounded) until the mission file holds ``n_items`` items: it may first be written
    with home alone (home is set at the first fix, before the upload)."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        try:
            with open(path) as f:
                if len(json.load(f)["items"]) == n_items:
                    return True
        except (OSError, ValueError, KeyError):
            pass                                  # not there yet, or being replaced
        time.sleep(0.05)
    return False


def test_mission_and_home_survive_an_fc_restart_in_flight(tmp_path):
    out = str(tmp_path / "fc")
    os.makedirs(out)
    with open(os.path.join(out, "params.parm"), "w") as f:
        f.write("FS_TIMEOUT_S 30\n")              # a loaded machine may pause the plant
    plant_port = free_udp_port()
    items = read_wpl(os.path.join(REPO, SHORT))
    plant = Child("plant", [sys.executable, "-m", "plant_sim", "run", "--scenario", "mission",
                            "--mode", "lockstep", "--fc", f"127.0.0.1:{plant_port}",
                            "--bind", "127.0.0.1:0", "--out", str(tmp_path / "plant"),
                            "--duration", "0", "--give-up", "300"], None, cwd=REPO)
    try:
        # GIVEN an fc flying the mission, with home set at the first GNSS fix
        gcs_port = free_udp_port()
        fc = _fc(out, plant_port, gcs_port).__enter__()
        gcs = ScriptedGcs(port=gcs_port)
        try:
            home1 = gcs.wait("HOME_POSITION", 60.0)
            assert home1 is not None, "no home from the first run"
            gcs.upload_mission(items)
            gcs.set_mode(MISSION_MODE)
            cur = gcs.wait("MISSION_CURRENT", 10.0, cond=lambda m: m.total == len(items))
            assert cur is not None
            # the mission file is written within a second of the change (fc/loops.py)
            assert _wait_file(os.path.join(out, "mission.json"), 10.0, len(items))
            pos1 = gcs.wait("GLOBAL_POSITION_INT", 5.0)
            # WHEN the fc is killed in flight and started again
            fc.child.stop(int_wait_s=5.0, term_wait_s=None, first_signal=signal.SIGKILL)
        finally:
            gcs.close()
            fc.__exit__(None, None, None)
        gcs_port = free_udp_port()
        with _fc(out, plant_port, gcs_port) as fc2:
            gcs = ScriptedGcs(port=gcs_port)
            try:
                # THEN home is the first run's, though the vehicle is elsewhere now
                home2 = gcs.wait("HOME_POSITION", 60.0)
                assert home2 is not None
                assert (home2.latitude, home2.longitude, home2.altitude) == (
                    home1.latitude, home1.longitude, home1.altitude)
                pos2 = gcs.wait("GLOBAL_POSITION_INT", 10.0, since=time.monotonic())
                assert pos2 is not None and pos1 is not None
                assert abs(pos2.lat - home2.latitude) > 10000       # > 1 km north of home now
                # and the mission is the one uploaded, at the item it had reached
                got = gcs.download_mission()
                assert got is not None and len(got) == len(items)
                assert [(m.command, m.x, m.y, m.z) for m in got] == [
                    (it["command"], it["x"], it["y"], it["z"]) for it in items]
                cur2 = gcs.wait("MISSION_CURRENT", 10.0, since=time.monotonic())
                assert cur2.total == len(items) and cur2.seq >= cur.seq
                # the restarted fc flies it on
                gcs.set_mode(MISSION_MODE)
            finally:
                gcs.close()
            assert fc2.stop() == 0
    finally:
        plant.stop(int_wait_s=10.0, term_wait_s=5.0)
