"""HIL tier: the mission protocol of the fc process over loopback UDP (pymavlink and MAVProxy).

A pymavlink ground station uploads the shipped short mission (plant_sim/scenarios/
mission_short.waypoints), reads it back, breaks an upload (a refused item, a missing item
answered by nobody: the fc's retries then its timeout) and finds the stored mission unchanged
each time. MAVProxy, headless, loads the file with ``wp load`` and lists it with ``wp list``.
"""
from __future__ import annotations

import os

import pytest
from pymavlink import mavwp

from tests.fc_harness import REPO, FcProcess, GcsClient, free_udp_port, mavlink as ML
from tests.hil.test_mavproxy_fc import _Console, _mavproxy

pytestmark = pytest.mark.hil

SHORT = os.path.join(REPO, "plant_sim", "scenarios", "mission_short.waypoints")


def load_wpl(path: str) -> list:
    """The items of a QGC WPL 110 file as MISSION_ITEM_INT messages for system 1."""
    loader = mavwp.MAVWPLoader(target_system=1, target_component=1)
    loader.load(path)
    return [ML.MAVLink_mission_item_int_message(
        1, 1, w.seq, w.frame, w.command, 0, w.autocontinue, w.param1, w.param2, w.param3,
        w.param4, int(round(w.x * 1e7)), int(round(w.y * 1e7)), w.z, 0)
        for w in (loader.wp(i) for i in range(loader.count()))]


def upload(gcs: GcsClient, items: list, skip: int | None = None, timeout_s: float = 10.0):
    """Answer the fc's requests with ``items`` (never item ``skip``); returns (MISSION_ACK or
    None, requested sequence numbers)."""
    gcs.conn.mav.mission_count_send(1, 1, len(items), 0)
    asked = []
    while True:
        m = gcs.wait(["MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK"], timeout_s)
        if m is None or m.get_type() == "MISSION_ACK":
            return m, asked
        asked.append(m.seq)
        if m.seq != skip:
            gcs.conn.mav.send(items[m.seq])


def download(gcs: GcsClient) -> list:
    gcs.conn.mav.mission_request_list_send(1, 1, 0)
    n = gcs.wait("MISSION_COUNT", 5).count
    got = []
    for seq in range(n):
        gcs.conn.mav.mission_request_int_send(1, 1, seq, 0)
        got.append(gcs.wait("MISSION_ITEM_INT", 5, lambda m, s=seq: m.seq == s))
    gcs.conn.mav.mission_ack_send(1, 1, ML.MAV_MISSION_ACCEPTED, 0)
    return got


def _same(a, b) -> bool:
    return all(getattr(a, f) == getattr(b, f)
               for f in ("seq", "frame", "command", "x", "y", "z", "param1", "param2"))


@pytest.fixture(scope="module")
def fc_gcs(tmp_path_factory):
    out = str(tmp_path_factory.mktemp("fc_mission"))
    port = free_udp_port()
    with FcProcess(out, gcs_ports=(port,)) as fc:
        gcs = GcsClient(port)
        try:
            assert gcs.wait("HEARTBEAT", 10) is not None
            yield fc, gcs
        finally:
            gcs.close()


def test_upload_download_and_mission_current(fc_gcs):
    _, gcs = fc_gcs
    items = load_wpl(SHORT)
    ack, asked = upload(gcs, items)
    assert ack is not None and ack.type == ML.MAV_MISSION_ACCEPTED
    assert asked == list(range(len(items)))
    cur = gcs.wait("MISSION_CURRENT", 5, lambda m: m.total == len(items))
    assert cur.seq == 0 and cur.mission_state == ML.MISSION_STATE_NOT_STARTED
    got = download(gcs)
    assert len(got) == len(items) and all(_same(a, b) for a, b in zip(got, items))


def test_broken_uploads_are_refused_and_the_mission_kept(fc_gcs):
    _, gcs = fc_gcs
    items = load_wpl(SHORT)
    ack, _ = upload(gcs, items)
    assert ack.type == ML.MAV_MISSION_ACCEPTED
    # an unsupported command (a loiter means nothing at Mach 7)
    bad = list(items)
    b = bad[2]
    bad[2] = ML.MAVLink_mission_item_int_message(1, 1, 2, b.frame, ML.MAV_CMD_NAV_LOITER_UNLIM, 0,
                                                 1, 0, 0, 0, 0, b.x, b.y, b.z, 0)
    ack, _ = upload(gcs, bad)
    assert ack.type == ML.MAV_MISSION_UNSUPPORTED
    # item 1 never sent: requested again (retries), then the fc gives up
    ack, asked = upload(gcs, items[:2] + items[2:], skip=1, timeout_s=10.0)
    assert ack is not None and ack.type == ML.MAV_MISSION_OPERATION_CANCELLED
    assert asked.count(1) >= 3
    got = download(gcs)
    assert len(got) == len(items) and all(_same(a, b) for a, b in zip(got, items))


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
