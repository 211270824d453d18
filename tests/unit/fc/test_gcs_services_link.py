"""Unit tier: the protocol services as the GCS link serves them (fc/gcs.py dispatch): a peer
on loopback sends a request, ``poll``/``service`` run in process, the peer reads the answer.
Also the stream fields of issue 21: EXTENDED_SYS_STATE, speeds that do not fit their fields."""
from __future__ import annotations

import os
import select
import socket
import time

os.environ["MAVLINK20"] = "1"
from fc.gcs import GcsLink  # noqa: E402
from fc.link import (G_ALT_M, G_FIX, G_LAT_DEG, G_LON_DEG, G_T_S, G_VD, G_VE,  # noqa: E402
                     G_VN, M_AIRSPEED, mavlink as ML, mavlink_dev as MD, new_codec)
from tests.fc_harness import free_udp_port  # noqa: E402
from tests.unit.fc.test_gcs_links import _Vehicle  # noqa: E402


class _Peer:
    """A ground station socket talking to an in-process GcsLink."""

    def __init__(self, link: GcsLink) -> None:
        self.link = link
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.tx = new_codec(255, 190)
        self.rx = new_codec(254, 1)
        self.t = 100.0

    def send(self, msg) -> None:
        self.sock.sendto(msg.pack(self.tx), self.link.endpoint.address)
        for _ in range(200):                         # the datagram is on loopback: read it
            if self.link.poll(self.t):
                return
            time.sleep(0.001)
        raise AssertionError("the link never read the datagram")

    def answers(self, kind, timeout_s: float = 2.0, n_service: int = 50) -> list:
        """Run ``service`` a few times and return the messages of type ``kind`` (a name or a
        tuple of names) this peer received."""
        got = []
        deadline = time.monotonic() + timeout_s
        for _ in range(n_service):
            self.t += 0.01
            self.link.service(self.t)
        while time.monotonic() < deadline:
            r, _, _ = select.select([self.sock], [], [], 0.05)
            if not r:
                break
            data = self.sock.recv(65536)
            for m in self.rx.parse_buffer(data) or []:
                if m.get_type() in ((kind,) if isinstance(kind, str) else kind):
                    got.append(m)
        return got

    def close(self) -> None:
        self.sock.close()


def _link(tmp_path, vehicle=None) -> GcsLink:
    tlog = str(tmp_path / "fc.tlog")
    return GcsLink(vehicle or _Vehicle(), ("127.0.0.1", free_udp_port()),
                   [("127.0.0.1", free_udp_port())], tlog_path=tlog)


def test_param_read_of_an_unknown_name_is_answered_at_once_with_param_error(tmp_path):
    link = _link(tmp_path)
    peer = _Peer(link)
    try:
        peer.send(ML.MAVLink_param_request_read_message(1, 1, b"NO_SUCH_PARAM", -1))
        (err,) = peer.answers("PARAM_ERROR")
        assert err.param_id == "NO_SUCH_PARAM" and err.param_index == -1
        assert err.error == MD.MAV_PARAM_ERROR_DOES_NOT_EXIST
        assert (err.target_system, err.target_component) == (255, 190)
        peer.send(ML.MAVLink_param_request_read_message(1, 1, b"", 9999))      # index too big
        assert peer.answers("PARAM_ERROR")[0].param_index == 9999
        peer.send(ML.MAVLink_param_request_read_message(1, 1, b"FS_TIMEOUT_S", -1))
        assert peer.answers("PARAM_VALUE")[0].param_id == "FS_TIMEOUT_S"
    finally:
        peer.close()
        link.close()


def test_timesync_log_list_and_ftp_are_answered_to_the_requester(tmp_path):
    link = _link(tmp_path)
    peer = _Peer(link)
    try:
        link.v.meas_stamp_us = 0
        peer.send(ML.MAVLink_timesync_message(0, 42))
        (ts,) = peer.answers("TIMESYNC")
        assert ts.ts1 == 42 and ts.tc1 > 0
        link.flush()                                  # the .tlog on disk holds something
        peer.send(ML.MAVLink_log_request_list_message(1, 1, 0, 0xFFFF))
        (entry,) = peer.answers("LOG_ENTRY")
        assert entry.num_logs == 1 and entry.size == os.path.getsize(tmp_path / "fc.tlog") > 0
        peer.send(ML.MAVLink_log_request_data_message(1, 1, 1, 0, 0xFFFFFFFF))
        data = peer.answers("LOG_DATA")
        assert sum(m.count for m in data) == entry.size
        payload = [0] * 251
        payload[3] = 3                                # ListDirectory "/"
        payload[4] = 1
        payload[12] = ord("/")
        peer.send(ML.MAVLink_file_transfer_protocol_message(0, 1, 1, payload))
        (ftp,) = peer.answers("FILE_TRANSFER_PROTOCOL")
        assert ftp.payload[3] == 128 and b"Ffc.tlog" in bytes(ftp.payload[12:])
    finally:
        peer.close()
        link.close()
    # the services' answers stay out of the flight log (it would grow as it is downloaded);
    # the requests are in it, as every received message
    types = _tlog_types(tmp_path / "fc.tlog")
    assert {"LOG_REQUEST_DATA", "FILE_TRANSFER_PROTOCOL", "TIMESYNC"} <= types[255]
    assert not {"LOG_DATA", "LOG_ENTRY", "FILE_TRANSFER_PROTOCOL", "TIMESYNC"} & types[1]


def _tlog_types(path) -> dict[int, set[str]]:
    """The message types of a .tlog by source system id."""
    from pymavlink import mavutil
    log = mavutil.mavlink_connection(str(path), dialect="ardupilotmega")
    by_sys: dict[int, set[str]] = {}
    try:
        while (m := log.recv_match()) is not None:
            by_sys.setdefault(m.get_srcSystem(), set()).add(m.get_type())
    finally:
        log.close()
    return by_sys


def _flying(v: _Vehicle, vn_m_s: float = 2200.0) -> _Vehicle:
    v.meas[M_AIRSPEED] = 2200.0
    v.plant.counters.frames = 10
    v.meas_stamp_us = 2_000_000
    g = v.plant.gps
    g[G_T_S], g[G_LAT_DEG], g[G_LON_DEG], g[G_ALT_M] = 2.0, 34.9, -117.9, 21000.0
    g[G_VN], g[G_VE], g[G_VD], g[G_FIX] = vn_m_s, -30.0, 1.5, 3
    v.plant.gps_samples = 1
    return v


def test_extended_sys_state_says_in_air_at_mach_7_and_undefined_without_data(tmp_path):
    v = _flying(_Vehicle())
    link = _link(tmp_path, v)
    try:
        m = link._build(ML.MAVLINK_MSG_ID_EXTENDED_SYS_STATE, 0)
        assert m.landed_state == ML.MAV_LANDED_STATE_IN_AIR
        assert m.vtol_state == ML.MAV_VTOL_STATE_UNDEFINED
        v.modes.data_lost = True
        m = link._build(ML.MAVLINK_MSG_ID_EXTENDED_SYS_STATE, 0)
        assert m.landed_state == ML.MAV_LANDED_STATE_UNDEFINED
        assert ML.MAVLINK_MSG_ID_EXTENDED_SYS_STATE in link.intervals     # streamed
    finally:
        link.close()


def test_speeds_that_do_not_fit_are_unknown_and_local_position_ned_has_them(tmp_path):
    link = _link(tmp_path, _flying(_Vehicle()))
    try:
        link.service(100.0)                               # home = the first fix
        gpi = link._build(ML.MAVLINK_MSG_ID_GLOBAL_POSITION_INT, 0)
        assert (gpi.vx, gpi.vy, gpi.vz) == (32767, -3000, 150)    # 2200 m/s: unknown
        raw = link._build(ML.MAVLINK_MSG_ID_GPS_RAW_INT, 0)
        assert raw.vel == 65535
        ned = link._build(ML.MAVLINK_MSG_ID_LOCAL_POSITION_NED, 0)
        assert (ned.vx, ned.vy, ned.vz) == (2200.0, -30.0, 1.5)
        assert (ned.x, ned.y, ned.z) == (0.0, 0.0, 0.0)           # at home
    finally:
        link.close()


def test_extended_sys_state_on_request(tmp_path):
    link = _link(tmp_path, _flying(_Vehicle()))
    peer = _Peer(link)
    try:
        peer.send(ML.MAVLink_command_long_message(1, 1, ML.MAV_CMD_REQUEST_MESSAGE, 0,
                                                  ML.MAVLINK_MSG_ID_EXTENDED_SYS_STATE,
                                                  0, 0, 0, 0, 0, 0))
        got = peer.answers(("EXTENDED_SYS_STATE", "COMMAND_ACK"))
        acks = [m for m in got if m.get_type() == "COMMAND_ACK"]
        assert [a.result for a in acks] == [ML.MAV_RESULT_ACCEPTED]
        states = [m for m in got if m.get_type() == "EXTENDED_SYS_STATE"]
        assert states and states[0].landed_state == ML.MAV_LANDED_STATE_IN_AIR
    finally:
        peer.close()
        link.close()


def test_tlog_chunks_are_recycled_only_after_the_io_thread_wrote_them(tmp_path):
    import struct
    import threading

    from fc.iothread import IoThread
    # GIVEN a link whose I/O thread is held by a job ahead of the .tlog's chunks
    io = IoThread()
    link = _link(tmp_path)
    link.io = io
    held, free = threading.Event(), threading.Event()

    def hold():
        held.set()
        assert free.wait(10)

    io.submit(hold)
    assert held.wait(10)
    frames = [bytes([k]) * (5 + k) for k in range(6)]
    try:
        # WHEN frames are logged and flushed twice while the thread is held
        for k in (0, 1, 2):
            link._tlog_write(frames[k], 1000 * k)
        first = link._tlog_buf
        link.flush()
        assert link._tlog_buf is not first and link._tlog_spare == []
        for k in (3, 4):
            link._tlog_write(frames[k], 1000 * k)
        second = link._tlog_buf
        link.flush()
        # THEN no handed chunk was taken back before it was written
        assert link._tlog_buf is not first and link._tlog_buf is not second
        free.set()
        io.close()
        # and once written, both came back emptied, and the next flush takes one of them
        assert sorted(map(id, link._tlog_spare)) == sorted((id(first), id(second)))
        assert first == b"" and second == b""
        link.io = None                              # (no I/O thread now: written at once)
        link._tlog_write(frames[5], 5000)
        link.flush()
        assert link._tlog_buf is first or link._tlog_buf is second
    finally:
        link.close()
    # and the file holds every frame once, in order, each after its stamp
    want = b"".join(struct.pack(">Q", link.epoch_us + 1000 * k) + f for k, f in enumerate(frames))
    assert (tmp_path / "fc.tlog").read_bytes().endswith(want)
