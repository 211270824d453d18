"""HIL tier: the mission protocol of the fc process over loopback UDP (pymavlink and MAVProxy).

The scripted ground station (tools/sitl/gcs.py) uploads the shipped short mission (plant_sim/scenarios/
mission_short.waypoints), reads it back, breaks an upload (a refused item, a missing item
answered by nobody: the fc's retries then its timeout) and finds the stored mission unchanged
each time. MAVProxy, headless, loads the file with ``wp load`` and lists it with ``wp list``.
"""
from __future__ import annotations

import os

import pytest

from tests.fc_harness import REPO, FcProcess, fc_with_gcs, free_udp_port, mavlink as ML
from tests.hil.test_mavproxy_fc import _Console, _mavproxy
from tools.sitl.gcs import read_wpl

pytestmark = pytest.mark.hil

SHORT = os.path.join(REPO, "plant_sim", "scenarios", "mission_short.waypoints")


def _same(got, item: dict, seq: int) -> bool:
    """A downloaded MISSION_ITEM_INT is item ``seq`` of the uploaded list."""
    return got.seq == seq and all(getattr(got, f) == item[f]
                                  for f in ("frame", "command", "x", "y", "z", "param1", "param2"))


@pytest.fixture(scope="module")
def fc_gcs(tmp_path_factory):
    with fc_with_gcs(str(tmp_path_factory.mktemp("fc_mission"))) as (fc, gcs):
        yield fc, gcs


def test_upload_download_and_mission_current(fc_gcs):
    _, gcs = fc_gcs
    items = read_wpl(SHORT)
    ack, asked = gcs.send_mission(items)
    assert ack is not None and ack.type == ML.MAV_MISSION_ACCEPTED
    assert asked == list(range(len(items)))
    cur = gcs.wait("MISSION_CURRENT", 5, cond=lambda m: m.total == len(items))
    assert cur.seq == 0 and cur.mission_state == ML.MISSION_STATE_NOT_STARTED
    got = gcs.download_mission()
    assert len(got) == len(items) and all(_same(g, it, k) for k, (g, it) in
                                          enumerate(zip(got, items)))


def test_broken_uploads_are_refused_and_the_mission_kept(fc_gcs):
    _, gcs = fc_gcs
    items = read_wpl(SHORT)
    ack, _ = gcs.send_mission(items)
    assert ack.type == ML.MAV_MISSION_ACCEPTED
    # an unsupported command (a loiter means nothing at Mach 7)
    bad = list(items)
    bad[2] = dict(items[2], command=ML.MAV_CMD_NAV_LOITER_UNLIM, autocontinue=1, param1=0.0,
                  param2=0.0, param3=0.0, param4=0.0)
    ack, _ = gcs.send_mission(bad)
    assert ack.type == ML.MAV_MISSION_UNSUPPORTED
    # item 1 never sent: requested again (retries), then the fc gives up
    ack, asked = gcs.send_mission(items, skip=1, timeout_s=30.0)
    assert ack is not None and ack.type == ML.MAV_MISSION_OPERATION_CANCELLED
    assert asked.count(1) >= 3
    got = gcs.download_mission()
    assert len(got) == len(items) and all(_same(g, it, k) for k, (g, it) in
                                          enumerate(zip(got, items)))


def test_mavproxy_wp_load_and_list(tmp_path):
    exe = _mavproxy()
    port = free_udp_port()
    with FcProcess(str(tmp_path / "run"), gcs_ports=(port,)) as fc:
        con = _Console(exe + [f"--master=udpin:127.0.0.1:{port}", "--no-state",
                              "--default-modules=link,wp", "--cmd=set requireexit 1"],
                       str(tmp_path))
        try:
            con.expect("online system 1", 20)
            con.send(f"wp load {SHORT}")
            con.expect("Sent all 4 waypoints", 20)
            con.send("wp list")
            con.expect("Requesting 4 waypoints", 20)
            lines = [con.expect("p1=", 10) for _ in range(4)]
        finally:
            con.close()
        assert fc.stop() == 0
    assert lines[0].startswith("16 0 35.1758193") and lines[1].startswith("178 2 ")
    assert "p2=2260.0" in lines[1] and lines[3].startswith("16 0 35.7166578")
