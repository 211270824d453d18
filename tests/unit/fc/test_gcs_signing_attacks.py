"""Unit tier: the signing attacks of issue 22 against ``GcsLink`` in process (fc/signing.py).

Each test replays one attack from a sender without the key and checks that the signed ground
station keeps its link: a forged timestamp on the GCS's own stream, every link id poisoned,
signed commands captured and replayed after a restart, unsigned HEARTBEATs filling the peer
table. All of them pass through a real UDP socket into ``poll``.
"""
from __future__ import annotations

import hashlib
import os
import socket

import pytest

os.environ["MAVLINK20"] = "1"
from fc.gcs import MAX_PEERS, GcsLink  # noqa: E402
from fc.link import mavlink as ML  # noqa: E402
from fc.signing import FILE_NAME, clock_timestamp  # noqa: E402
from tests.fc_harness import free_udp_port  # noqa: E402
from tests.unit.fc.test_gcs_links import _Null, _Vehicle  # noqa: E402

KEY = hashlib.sha256(b"correct horse battery staple").digest()
GCS_SYS, GCS_COMP, GCS_LINK = 255, 190, 0


def _codec(key: bytes | None, link_id: int = GCS_LINK, timestamp: int | None = None,
           sysid: int = GCS_SYS, compid: int = GCS_COMP):
    """A ground station's codec; ``key`` None: unsigned."""
    mav = ML.MAVLink(_Null(), srcSystem=sysid, srcComponent=compid)
    if key is not None:
        mav.signing.secret_key = key
        mav.signing.sign_outgoing = True
        mav.signing.link_id = link_id
        mav.signing.timestamp = clock_timestamp() if timestamp is None else timestamp
    return mav


class _Station:
    """A UDP socket on loopback that sends datagrams to the link and reads its answers."""

    def __init__(self) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.addr = self.sock.getsockname()

    def send(self, link: GcsLink, buf: bytes, now_s: float = 100.0) -> None:
        self.sock.sendto(buf, link.endpoint.address)
        for _ in range(200):                  # the datagram is on loopback: read it
            if link.poll(now_s):
                return
        raise AssertionError("the link never read the datagram")

    def close(self) -> None:
        self.sock.close()


@pytest.fixture()
def signed_link(tmp_path):
    links = []

    def make():
        v = _Vehicle()
        link = GcsLink(v, ("127.0.0.1", free_udp_port()), [], signing_key=KEY,
                       signing_path=str(tmp_path / FILE_NAME))
        links.append(link)
        return v, link
    yield make
    for link in links:
        link.close()


def _param_set(mav, value: float) -> bytes:
    return mav.param_set_encode(1, 1, b"TRIM_RUD_DEG", value,
                                ML.MAV_PARAM_TYPE_REAL32).pack(mav)


def _rudder(v) -> float:
    return v.params.get("TRIM_RUD_DEG")


def test_a_forged_future_timestamp_on_the_gcs_stream_changes_nothing(signed_link):
    v, link = signed_link()
    gcs, attacker = _Station(), _Station()
    try:
        # GIVEN a signed GCS that has been heard
        mav = _codec(KEY)
        gcs.send(link, _param_set(mav, 1.0))
        assert _rudder(v) == 1.0
        # WHEN a sender without the key sends the GCS's link id/sys/comp with a timestamp of
        # 2^48-10 and a garbage signature (a HEARTBEAT: a type accepted unsigned)
        forged = _codec(os.urandom(32), timestamp=2**48 - 10)
        attacker.send(link, forged.heartbeat_encode(6, 8, 0, 0, 0).pack(forged))
        # THEN the GCS's next signed messages are accepted: no state changed
        gcs.send(link, _param_set(mav, 2.0))
        assert _rudder(v) == 2.0
        assert link.guard.streams[(GCS_LINK, GCS_SYS, GCS_COMP)] < 2**47
        assert link.guard.bad_signatures == 1
    finally:
        gcs.close()
        attacker.close()


def test_256_forged_datagrams_poison_no_link_id(signed_link):
    v, link = signed_link()
    attacker, gcs = _Station(), _Station()
    try:
        # GIVEN a sender without the key poisoning every link id of the GCS's sys/comp
        for link_id in range(256):
            forged = _codec(b"\x01" * 32, link_id=link_id, timestamp=2**48 - 10)
            attacker.send(link, forged.heartbeat_encode(6, 8, 0, 0, 0).pack(forged))
        # THEN a signed GCS on any link id is accepted
        for value, link_id in ((3.0, 0), (4.0, 17), (5.0, 255)):
            gcs.send(link, _param_set(_codec(KEY, link_id=link_id), value))
            assert _rudder(v) == value
        assert link.guard.bad_signatures == 256 and len(link.guard.streams) == 3
    finally:
        attacker.close()
        gcs.close()


def test_signed_commands_captured_before_a_restart_do_not_replay_after_it(signed_link):
    v, link = signed_link()
    gcs = _Station()
    mav = _codec(KEY)
    # GIVEN a signed PARAM_SET and DO_SET_MODE MANUAL captured on the way to the fc
    cap_param = _param_set(mav, 6.0)
    cap_mode = mav.command_long_encode(1, 1, ML.MAV_CMD_DO_SET_MODE, 0, 1, 0, 0, 0, 0, 0,
                                       0).pack(mav)
    gcs.send(link, cap_param)
    gcs.send(link, cap_mode)
    assert _rudder(v) == 6.0
    gcs.send(link, _param_set(mav, 7.0))        # the GCS goes on
    # WHEN the fc saves its state and restarts (the file of fc/signing.py, beside the params)
    data = link.signing_snapshot()
    if data is not None:
        link.save_signing(data)
    link.close()
    v2, link2 = signed_link()
    attacker = _Station()
    try:
        v2.params.set("TRIM_RUD_DEG", 7.0)
        v2.modes.request_mode(1)
        before = (v2.modes.mode, link2.rejected_signing)
        # THEN both captures, replayed from another port, are rejected and change nothing
        attacker.send(link2, cap_param)
        attacker.send(link2, cap_mode)
        assert _rudder(v2) == 7.0 and v2.modes.mode == before[0]
        assert link2.guard.stale == 2 and link2.rejected_signing == before[1] + 2
        # and the GCS, going on with new timestamps, is still obeyed
        gcs.send(link2, _param_set(mav, 8.0))
        assert _rudder(v2) == 8.0
        # its own outgoing timestamps do not go back either
        assert link2.mav.signing.timestamp > link.mav.signing.timestamp
    finally:
        gcs.close()
        attacker.close()


def test_unsigned_heartbeats_from_many_ports_never_evict_a_signed_gcs(signed_link):
    _, link = signed_link()
    gcs = _Station()
    ports = [_Station() for _ in range(MAX_PEERS + 4)]
    try:
        # GIVEN a signed GCS with its own stream rates
        mav = _codec(KEY)
        gcs.send(link, mav.command_long_encode(1, 1, ML.MAV_CMD_SET_MESSAGE_INTERVAL, 0,
                                               ML.MAVLINK_MSG_ID_ATTITUDE, 20000, 0, 0, 0, 0,
                                               0).pack(mav))
        assert gcs.addr in link.links
        # WHEN unsigned HEARTBEATs come from MAX_PEERS + 4 other ports, each newer
        for k, p in enumerate(ports):
            tx = _codec(None, sysid=200 + k)
            p.send(link, tx.heartbeat_encode(6, 8, 0, 0, 0).pack(tx), now_s=100.1 + 0.1 * k)
        # THEN the signed GCS is still a peer with its own rates; the table stayed bounded
        assert gcs.addr in link.peers and gcs.addr in link.links
        assert link.links[gcs.addr].intervals[ML.MAVLINK_MSG_ID_ATTITUDE] == 0.02
        assert len(link.peers) == MAX_PEERS
    finally:
        gcs.close()
        for p in ports:
            p.close()


def test_the_signing_snapshot_is_taken_when_a_stream_changed_and_costs_nothing_else(signed_link):
    import json
    from tests.unit.fc.test_gcs_links import _blocks
    _v, link = signed_link()
    gcs = _Station()
    try:
        # GIVEN no signed stream heard: no snapshot, and the 1 Hz check takes no Python block
        assert link.signing_snapshot() is None
        assert _blocks(link.signing_snapshot) == 0
        # WHEN a signed message comes: one snapshot with that stream and the fc's timestamp
        mav = _codec(KEY)
        gcs.send(link, _param_set(mav, 6.0))
        data = link.signing_snapshot()
        assert data is not None
        doc = json.loads(data)
        assert doc["timestamp"] >= link.mav.signing.timestamp
        assert doc["streams"][0][:3] == [GCS_LINK, GCS_SYS, GCS_COMP]
        assert 0 < doc["streams"][0][3] <= mav.signing.timestamp      # its last message's
        # THEN nothing more until the stream moves on; a failed save is tried again
        assert link.signing_snapshot() is None and _blocks(link.signing_snapshot) == 0
        link.guard.path = os.path.join(os.path.dirname(link.guard.path), "no such dir", "s")
        link.save_signing(data)
        assert link.signing_snapshot() is not None
    finally:
        gcs.close()
