"""tools.sitl.gcs.ScriptedGcs, the one scripted ground station, against a stand-in vehicle socket."""
from __future__ import annotations

import socket
import threading
import time

import pytest

from tools.sitl.gcs import ScriptedGcs, mavlink


class _Null:
    def write(self, _b):
        return None


def test_recording_gcs_waits_and_answers_through_its_codec():
    # GIVEN a recording ground station without heartbeats and a vehicle (system 1) socket
    gcs = ScriptedGcs(port=0, heartbeat=False, record=True)
    veh = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    veh.bind(("127.0.0.1", 0))
    veh.settimeout(5.0)
    mav = mavlink.MAVLink(_Null(), srcSystem=1, srcComponent=1)
    try:
        # WHEN the vehicle sends a heartbeat, a counter and a text, and a stranger a heartbeat
        stranger = mavlink.MAVLink(_Null(), srcSystem=7, srcComponent=1)
        veh.sendto(stranger.heartbeat_encode(1, 3, 0, 11, 4).pack(stranger),
                   ("127.0.0.1", gcs.port))
        for msg in (mav.heartbeat_encode(1, 3, 0, 42, 4),
                    mav.named_value_float_encode(0, b"LATE_CNT", 3.0),
                    mav.statustext_encode(4, b"FAILSAFE: plant data lost")):
            veh.sendto(msg.pack(mav), ("127.0.0.1", gcs.port))
        # THEN the waits see the vehicle's messages only
        assert gcs.heartbeat_mode(5.0) == 42
        assert gcs.wait_named("LATE_CNT", lambda v: v >= 3.0, 5.0) == 3.0
        assert gcs.wait_text("FAILSAFE", 5.0) == "FAILSAFE: plant data lost"
        assert gcs.find(lambda m: m.get_type() == "HEARTBEAT" and m.custom_mode == 11) is None
        # AND pymavlink's generated senders reach the vehicle, from system 250
        gcs.conn.mav.param_request_read_send(1, 1, b"FS_TIMEOUT_S", -1)
        data, _ = veh.recvfrom(2048)
        (m,) = mav.parse_buffer(data)
        assert m.get_type() == "PARAM_REQUEST_READ" and m.get_srcSystem() == 250
    finally:
        gcs.close()
        veh.close()


class _Vehicle:
    """A stand-in vehicle (system 1) on its own socket, talking to the station's port."""

    def __init__(self, gcs: ScriptedGcs, key: bytes | None = None):
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(5.0)
        self.to = ("127.0.0.1", gcs.port)
        self.mav = mavlink.MAVLink(_Null(), srcSystem=1, srcComponent=1)
        if key is not None:
            self.mav.signing.secret_key = key
            self.mav.signing.sign_outgoing = True
            # MAVLink signing time stamps: 10 us since 2015-01-01, never going back
            self.mav.signing.timestamp = int((time.time() - 1420070400) * 1e5) + 1000
        self.rx = mavlink.MAVLink(_Null())

    def send(self, msg) -> None:
        self.sock.sendto(msg.pack(self.mav), self.to)
        self.mav.seq = (self.mav.seq + 1) % 256

    def recv(self):
        data, _ = self.sock.recvfrom(2048)
        (m,) = self.rx.parse_buffer(data)
        return m

    def close(self) -> None:
        self.sock.close()


def test_wait_reads_a_stream_or_looks_back_from_a_time():
    # GIVEN a station that has logged three vehicle heartbeats (modes 1, 2, 3)
    gcs = ScriptedGcs(port=0)
    veh = _Vehicle(gcs)
    try:
        for mode in (1, 2, 3):
            veh.send(veh.mav.heartbeat_encode(1, 3, 0, mode, 4))
        assert gcs.wait("HEARTBEAT", 5.0, 0.0, cond=lambda m: m.custom_mode == 3) is not None
        # WHEN it is read as a stream THEN each wait returns the next one, in order
        assert [gcs.wait("HEARTBEAT", 1.0).custom_mode for _ in range(3)] == [1, 2, 3]
        assert gcs.wait("HEARTBEAT", 0.2) is None
        # AND a wait from a receive time looks back without consuming
        assert gcs.wait(["HEARTBEAT", "SYS_STATUS"], 1.0, since=0.0).custom_mode == 1
        assert gcs.heartbeat_mode(1.0) == 1
        # AND drain() marks everything read; a predicate as the third argument is refused
        veh.send(veh.mav.heartbeat_encode(1, 3, 0, 4, 4))
        assert gcs.wait("HEARTBEAT", 5.0, 0.0, cond=lambda m: m.custom_mode == 4) is not None
        gcs.drain()
        assert gcs.wait("HEARTBEAT", 0.2) is None
        with pytest.raises(TypeError):
            gcs.wait("HEARTBEAT", 1.0, lambda m: True)
    finally:
        gcs.close()
        veh.close()


def test_command_is_retried_and_answered_only_by_an_ack_after_its_send():
    # GIVEN a station with an old COMMAND_ACK (DENIED) for the same command in its log
    gcs = ScriptedGcs(port=0)
    veh = _Vehicle(gcs)
    cmd = mavlink.MAV_CMD_COMPONENT_ARM_DISARM
    try:
        veh.send(veh.mav.command_ack_encode(cmd, mavlink.MAV_RESULT_DENIED))
        assert gcs.wait("COMMAND_ACK", 5.0, 0.0) is not None
        got = []

        def answer_second_try():
            for _ in range(2):
                m = veh.recv()
                got.append((m.get_type(), m.confirmation, m.param1))
            veh.send(veh.mav.command_ack_encode(cmd, mavlink.MAV_RESULT_ACCEPTED))

        th = threading.Thread(target=answer_second_try)
        th.start()
        # WHEN the vehicle ignores the first COMMAND_LONG and acknowledges the second
        ack = gcs.command(cmd, 1.0, timeout_s=4.0, tries=2)
        th.join(5.0)
        # THEN the station sent it twice (confirmation 0, 1) and returns the new ACK
        assert got == [("COMMAND_LONG", 0, 1.0), ("COMMAND_LONG", 1, 1.0)]
        assert ack is not None and ack.result == mavlink.MAV_RESULT_ACCEPTED
    finally:
        gcs.close()
        veh.close()


def test_signing_station_refuses_unsigned_vehicle_messages_and_signs_its_own():
    key = bytes(range(32))
    gcs = ScriptedGcs(port=0, key=key)
    unsigned, signed = _Vehicle(gcs), _Vehicle(gcs, key=key)
    try:
        # WHEN an unsigned and then a signed vehicle send a heartbeat each
        unsigned.send(unsigned.mav.heartbeat_encode(1, 3, 0, 7, 4))
        signed.send(signed.mav.heartbeat_encode(1, 3, 0, 8, 4))
        # THEN only the signed one is logged
        assert gcs.wait("HEARTBEAT", 5.0).custom_mode == 8
        assert gcs.find(lambda m: m.get_type() == "HEARTBEAT" and m.custom_mode == 7) is None
        # AND what the station sends (to the last sender) is signed
        gcs.mav.param_request_read_send(1, 1, b"FS_TIMEOUT_S", -1)
        data, _ = signed.sock.recvfrom(2048)
        signed.rx.signing.secret_key = key
        (m,) = signed.rx.parse_buffer(data)
        assert m.get_type() == "PARAM_REQUEST_READ" and m.get_signed()
    finally:
        gcs.close()
        unsigned.close()
        signed.close()


def test_a_peer_station_speaks_first_and_lists_a_time_window():
    # GIVEN a vehicle socket and a peer station told where it is (it has not heard it yet)
    veh = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    veh.bind(("127.0.0.1", 0))
    veh.settimeout(5.0)
    gcs = ScriptedGcs(port=0, vehicle=veh.getsockname())
    mav = mavlink.MAVLink(_Null(), srcSystem=1, srcComponent=1)
    try:
        # WHEN the station sends first THEN the vehicle gets it
        gcs.mav.heartbeat_send(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
        data, addr = veh.recvfrom(2048)
        assert mavlink.MAVLink(_Null()).parse_buffer(data)[0].get_type() == "HEARTBEAT"
        # AND messages() lists what arrived in a receive-time window, oldest first
        for text in (b"one", b"two"):
            veh.sendto(mav.statustext_encode(6, text).pack(mav), addr)
            mav.seq += 1
        assert gcs.wait_text("two", 5.0) == "two"
        t_mid = time.monotonic()
        veh.sendto(mav.statustext_encode(6, b"three").pack(mav), addr)
        assert gcs.wait_text("three", 5.0) == "three"
        assert [m.text for m in gcs.messages("STATUSTEXT")] == ["one", "two", "three"]
        assert [m.text for m in gcs.messages("STATUSTEXT", t_mid)] == ["three"]
        assert gcs.messages("STATUSTEXT", 0.0, t_mid, cond=lambda m: m.text == "one")[0].text \
            == "one"
    finally:
        gcs.close()
        veh.close()
