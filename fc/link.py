"""fc/link.py - the flight controller's MAVLink edge: codec, sockets, plant link.

Everything that touches MAVLink in the fc goes through here (docs/architecture.md section 1):
the codec, the UDP endpoint, the measurement and GNSS layouts, the PWM map and the lean framing
are the contract package's (hyfc_wire, shared with the plant and re-exported here for the fc);
this module adds the datagram decoder that never raises, the signing key and the plant link
(sensor frames in, SERVO_OUTPUT_RAW out, docs/wire.md). The plant link's per-frame path is
compiled (``hyfc_wire.frame_kernels``): the datagram is received into a preallocated buffer
and decoded there, the answer framed into another one. ``fc/gcs.py`` takes its codec
(``new_codec``, ``mavlink``) from this module.
"""
from __future__ import annotations

import hashlib
import math
import os
import select
import socket
import stat
import sys
from dataclasses import dataclass, field

import numpy as np

from fc.frame_calls import (FAST_IO, HOT_DATAGRAMS, HOT_EMPTY_READS, HOT_FRAMES, HOT_N,
                            HOT_OUTPUTS, IO_LEN, IO_N, IO_STAMP, RX_FRAME, RX_FRAME_BIG, RX_NONE, RX_OTHER,
                            RX_REJECTED, SOCKADDR_IN_B, STAMP_CELL_MAX_US, ArrayAddress,
                            address_of, decode_sensor_p, recv_sensor_p, send_servo_at_p,
                            send_servo_p, servo_frame_p, surfaces_pwm_p)
from hyfc_wire.codec import development_dialect, mavlink, new_codec, reset_parser
from hyfc_wire.frame_kernels import (GR_FIX, GR_HACC_M, GR_LAT_E7, GR_LON_E7, GR_N,
                                     GR_PRESENT, GR_SACC_M_S, GR_SATS, GR_VACC_M, GR_VD, GR_VE,
                                     GR_VN, SERVO_FRAME_MAX_B, decode_sensor, pwm_map,
                                     servo_frame, surfaces_pwm)  # noqa: F401 (re-exported)
from hyfc_wire.frame_kernels import GR_ALT_M as GR_ALT
from hyfc_wire.framing import LeanFramer
from hyfc_wire.layout import (G_ALT_M, G_FIX, G_HACC_M, G_LAT_DEG, G_LON_DEG, G_N, G_SACC_M_S,
                              G_SATS, G_T_S, G_VACC_M, G_VD, G_VE, G_VN, M_AIRSPEED, M_ALT,
                              M_AOA, M_CLIMB, M_GROUNDSPEED, M_HEADING, M_N, M_P, M_PITCH, M_Q,
                              M_R, M_ROLL, M_SSA, M_T_S, M_YAW)
from hyfc_wire.pwm import (DEFLECTION_LIMIT_RAD, PWM_MAX_US, PWM_MIN_US,  # noqa: F401
                           PWM_TRIM_US, THROTTLE_PWM_MAX_US, THROTTLE_PWM_MIN_US,
                           deflection_to_pwm, pwm_to_deflection, throttle_to_pwm)
from hyfc_wire.udp import MAX_DATAGRAM_B, UdpEndpoint, parse_hostport  # noqa: F401

__all__ = [
    "mavlink", "mavlink_dev", "new_codec", "UdpEndpoint", "decode_datagram", "PlantLink",
    "LinkCounters", "LeanFramer", "FRAME_AT", "FRAME_BIG", "FRAME_NONE",
    "deflection_to_pwm", "pwm_to_deflection", "throttle_to_pwm", "pwm_map", "surfaces_pwm",
    "load_signing_key",
    "parse_hostport",
    "M_T_S", "M_ROLL", "M_PITCH", "M_YAW", "M_P", "M_Q", "M_R", "M_AOA", "M_SSA",
    "M_AIRSPEED", "M_ALT", "M_CLIMB", "M_GROUNDSPEED", "M_HEADING", "M_N",
    "G_T_S", "G_LAT_DEG", "G_LON_DEG", "G_ALT_M", "G_VN", "G_VE", "G_VD", "G_FIX", "G_SATS",
    "G_HACC_M", "G_VACC_M", "G_SACC_M_S", "G_N",
]

#: ``PlantLink.read_frame_at``'s codes
FRAME_AT = 0        # a frame; its stamp in the int64 cell at ``stamp_cell_at``
FRAME_BIG = 1       # a frame; its stamp (>= STAMP_CELL_MAX_US) in ``big_stamp``
FRAME_NONE = -1     # no acceptable datagram waiting

#: the development dialect (standard modes, PARAM_ERROR: the ground-station link's), loaded
#: here, by the fc only (hyfc_wire/codec.py ``development_dialect``)
mavlink_dev = development_dialect()


def decode_datagram(mav: mavlink.MAVLink, data: bytes) -> tuple[list, int]:
    """Decode one UDP datagram into messages; never raises.

    The parser state is reset first, so a truncated frame in one datagram cannot swallow
    the next datagram's bytes. Returns ``(messages, n_bad)`` where ``n_bad`` counts
    malformed frames (bad prefix, CRC, length, signature).
    """
    reset_parser(mav)
    out: list = []
    n_bad = 0
    try:
        msgs = mav.parse_buffer(data) or []
    except Exception:  # noqa: BLE001 - a malformed packet must never kill the process
        return out, 1
    for m in msgs:
        if m.get_type() == "BAD_DATA":
            n_bad += 1
        else:
            out.append(m)
    if mav.buf_len() > 0:
        n_bad += 1  # trailing truncated frame
    return out, n_bad


def load_signing_key(path: str) -> bytes:
    """Read a MAVLink 2 signing key from ``path``.

    The file holds a passphrase (first line, stripped); the key is SHA-256(passphrase) as in
    MAVProxy's ``signing setup``/``signing key``. The file must be a regular file readable
    only by its owner (mode 0600 or stricter), like an ssh private key; the key is never logged.
    """
    st = os.stat(path)
    if not stat.S_ISREG(st.st_mode):
        raise ValueError(f"signing key file {path} is not a regular file")
    if st.st_mode & (stat.S_IRWXG | stat.S_IRWXO):
        raise PermissionError(
            f"signing key file {path} is accessible by group/others "
            f"(mode {stat.S_IMODE(st.st_mode):o}); chmod 600 it")
    with open(path, "rb") as f:
        passphrase = f.read().split(b"\n", 1)[0].strip()
    if not passphrase:
        raise ValueError(f"signing key file {path} is empty")
    return hashlib.sha256(passphrase).digest()


def _lean_self_check(link: "PlantLink") -> bool:
    """True if the compiled decoder gives exactly the general parser's result on a
    codec-built frame, and the compiled framing the codec's SERVO_OUTPUT_RAW bytes (field
    order, truncation, CRC_EXTRA of this pymavlink); else the link keeps the general parser
    and the codec's framing only."""
    try:
        tx = new_codec(link.plant_sysid)
        buf = tx.attitude_encode(1234, 0.1, -0.2, 0.3, 0.01, -0.02, 0.0).pack(tx)
        buf += tx.aoa_ssa_encode(1_234_567, 2.5, 0.0).pack(tx)
        buf += tx.vfr_hud_encode(2200.0, 2190.0, 45, 0, 25000.0, -1.5).pack(tx)
        for extra in (b"", tx.gps_input_encode(1_234_567, 0, 0, 0, 0, 3, 349054321, -1178839876,
                                                21000.5, 1.0, 1.0, 2199.5, -3.25, 1.5, 0.1, 1.5,
                                                3.0, 12, 0).pack(tx)):
            a = np.full(M_N, -1.0)
            b = np.full(M_N, -2.0)
            link._fast = False
            try:
                sa = link._decode(buf + extra, a)
                ga = link.gps.copy()
            finally:
                link._fast = True
            link.gps[:] = 0.0
            sb = link._decode(buf + extra, b)
            if not (sa == sb == 1_234_567 and bool(np.array_equal(a, b))
                    and bool(np.array_equal(ga, link.gps))):
                return False
        link.gps[:] = 0.0
        link.gps_samples = 0
        link.counters.gnss = 0
        pwm = np.zeros(4, np.int64)
        delta = np.zeros(3)
        for d in ((0.0, 0.1, -0.1), (0.35, -0.35, math.nan), (1e-3, -2e-3, 0.2)):
            # (also compiles/loads the fast tick's kernel before the first tick)
            src = np.array(d)
            surfaces_pwm_p(address_of(src, np.float64, 3), address_of(delta, np.float64, 3), 0,
                           address_of(pwm, np.int64, 4))
            if (pwm.tolist() != [deflection_to_pwm(x) for x in d] + [0]
                    or not np.array_equal(delta, d, equal_nan=True)):
                return False
        c = new_codec(link.sysid, link.compid)
        for seq, args in ((0, (0, 1500, 1500, 1500, 0)), (7, (123456, 1000, 2000, 1500, 1420)),
                          (255, (0xFFFFFFFF, 0, 0, 0, 0)), (3, (256, 0, 0, 0, 2000))):
            c.seq = seq
            ref = c.servo_output_raw_encode(args[0], 0, args[1], args[2], args[3],
                                            args[4], 0, 0, 0, 0).pack(c)
            n = servo_frame_p(link._tx_addr, SERVO_FRAME_MAX_B, seq, link.sysid, link.compid,
                              args[0], link._pwm_at.of(np.array(args[1:], np.int64)))
            if bytes(link._tx[:n]) != ref:
                return False
        return True
    except Exception:  # noqa: BLE001 - any surprise: stay on the general parser
        return False


_LITTLE = sys.byteorder == "little"     # sockaddr_in's family is in host order


def _libc_io_self_check(link: "PlantLink") -> bool:
    """True if the compiled receive and answer (libc ``recvfrom``/``sendto``, fc/frame_calls.py)
    work on this system as ``socket``'s calls do, on a pair of throw-away loopback sockets:
    a datagram from an unknown source is handed back with its length and its source's
    address; from the locked source it is decoded (the general parser's stamp and values);
    the answer arrives as the codec's SERVO_OUTPUT_RAW; an empty socket reads nothing. Else the
    link keeps ``socket``'s calls. (Also loads the two kernels before the first frame.)"""
    a = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    b = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    saved = (link.peer, link._peer_sa_of, link.counters.hot.copy(), link._fd)
    try:
        for x in (a, b):
            x.bind(("127.0.0.1", 0))
            x.setblocking(False)
        tx = new_codec(link.plant_sysid)
        frame = (tx.attitude_encode(1234, 0.1, -0.2, 0.3, 0.01, -0.02, 0.0).pack(tx)
                 + tx.aoa_ssa_encode(7_654_321, 2.5, -0.5).pack(tx)
                 + tx.vfr_hud_encode(2200.0, 2190.0, 45, 0, 25000.0, -1.5).pack(tx))
        want = np.zeros(M_N)
        if link._decode_general(frame, want) != 7_654_321:
            return False
        link._fd = a.fileno()
        link.peer = None
        got = np.zeros(M_N)
        if link._read_frame_compiled(got) != FRAME_NONE or link.counters.empty_reads != saved[2][
                HOT_EMPTY_READS] + 1:
            return False
        for locked in (False, True):
            b.sendto(frame, a.getsockname())
            select.select([a], [], [], 1.0)
            link.peer = b.getsockname() if locked else None
            link._bind_peer_sa()
            code = recv_sensor_p(link._fd, link._rx_addr, MAX_DATAGRAM_B, link._sa_addr,
                                 link._salen_addr, link._peer_sa_addr, locked, link.plant_sysid,
                                 link._meas_at.of(got), M_N, link._gps_raw_addr, GR_N,
                                 link._hot_at.of(link.counters.hot), link._io_addr)
            if locked:
                if (code != RX_FRAME or link._io.item(IO_STAMP) != 7_654_321
                        or not np.array_equal(got, want)):
                    return False
            elif (code != RX_OTHER or int(link._io[IO_LEN]) != len(frame)
                  or link._source() != b.getsockname()):
                return False
        link.peer = b.getsockname()
        link._bind_peer_sa()
        pwm = np.array([1000, 2000, 1500, 1420], np.int64)
        if not send_servo_p(link._fd, link._tx_addr, SERVO_FRAME_MAX_B, 9, link.sysid,
                            link.compid, 123456, link._pwm_at.of(pwm), link._peer_sa_addr,
                            link._hot_at.of(link.counters.hot)):
            return False
        select.select([b], [], [], 1.0)
        data, src = b.recvfrom(MAX_DATAGRAM_B)
        c = new_codec(link.sysid, link.compid)
        c.seq = 9
        ref = c.servo_output_raw_encode(123456, 0, 1000, 2000, 1500, 1420, 0, 0, 0, 0).pack(c)
        return data == ref and src == a.getsockname()
    except Exception:  # noqa: BLE001 - any surprise: keep socket's calls
        return False
    finally:
        link.peer, link._peer_sa_of, link._fd = saved[0], saved[1], saved[3]
        link.counters.hot[:] = saved[2]
        link._peer_sa[:] = 0
        link._gps_raw[:] = 0.0
        a.close()
        b.close()


def _pwm4(pwm_us) -> np.ndarray:
    """servo1..4 as int64[4] (servo4 0 = no output when ``pwm_us`` has three values)."""
    v = [int(x) for x in pwm_us[:4]]
    return np.array(v + [0] * (4 - len(v)), np.int64)


def _hot_counter(i: int, doc: str) -> property:
    """A counter kept in ``LinkCounters.hot[i]`` (read as an int, settable)."""
    def get(self) -> int:
        return int(self.hot[i])

    def put(self, value: int) -> None:
        self.hot[i] = value
    return property(get, put, doc=doc)


@dataclass(slots=True)
class LinkCounters:
    """Rejected and accepted input of the plant link (telemetry and fc.log).

    ``datagrams``, ``frames``, ``outputs`` and ``empty_reads`` live in the int64 array ``hot``,
    which the compiled receive and answer count in (fc/frame_calls.py: no Python int per
    frame); they read and assign as ints."""

    duplicates: int = 0           # frames with a stamp already answered (plant re-requests)
    rejected_sysid: int = 0       # from a system id other than the plant's
    rejected_addr: int = 0        # from another address than the first accepted one
    rejected_bad: int = 0         # malformed MAVLink (CRC, length, prefix)
    rejected_incomplete: int = 0  # datagram without the ATTITUDE+AOA_SSA+VFR_HUD triple
    gnss: int = 0                 # GNSS samples (GPS_INPUT) accepted with a frame
    gnss_rejected: int = 0        # GNSS samples dropped: non-finite or out of range
    relocks: int = 0              # new source address accepted after a data loss
    goodbyes: int = 0             # the plant said its run is over (docs/wire.md section 5)
    hot: np.ndarray = field(default_factory=lambda: np.zeros(HOT_N, np.int64))

    datagrams = _hot_counter(HOT_DATAGRAMS, "datagrams received")
    frames = _hot_counter(HOT_FRAMES, "complete sensor frames accepted")
    outputs = _hot_counter(HOT_OUTPUTS, "SERVO_OUTPUT_RAW sent")
    empty_reads = _hot_counter(HOT_EMPTY_READS, "receives that found nothing (or failed)")

    @property
    def rejected(self) -> int:
        return (self.rejected_sysid + self.rejected_addr + self.rejected_bad
                + self.rejected_incomplete)


@dataclass(slots=True)
class PlantLink:
    """The plant side of the fc (docs/wire.md): one datagram = one sensor frame.

    ``poll`` drains the socket without blocking and keeps the newest complete frame; the
    caller answers with ``send_servo``. Only frames from ``plant_sysid`` are accepted and,
    after the first accepted frame, only from that source address. After a plant-data loss the
    caller may set ``relock_allowed``: the next valid frame from ``plant_sysid`` then fixes a
    new source address (a restarted plant on another port), counted in ``relocks``.
    """

    endpoint: UdpEndpoint
    plant_sysid: int = 2
    sysid: int = 1
    compid: int = 1
    codec: mavlink.MAVLink = None
    peer: tuple | None = None
    relock_allowed: bool = False
    counters: LinkCounters = field(default_factory=LinkCounters)
    #: kernel receive time of the datagram of the last frame ``read_frame`` returned
    #: (CLOCK_REALTIME ns, 0 unless the endpoint stamps arrivals)
    frame_rx_ns: int = 0
    #: the plant said goodbye (its run is over) and no frame has come since
    ended: bool = False
    #: the stamp (us) of the last frame ``read_frame_at`` answered FRAME_BIG for
    big_stamp: int = 0
    #: the newest GNSS sample (layout G_*; G_T_S = the stamp of the frame that carried it,
    #: G_FIX 0 until the first one); ``gps_samples`` counts them
    gps: np.ndarray = None
    gps_samples: int = 0
    _tx_codec: mavlink.MAVLink = None
    #: the compiled decoder and framing are in use (their start-up self-check passed)
    _fast: bool = True
    _rx: bytearray = None           # the received datagram (recv_into), and as uint8
    _rx_u8: np.ndarray = None
    _gps_raw: np.ndarray = None     # decode_sensor's raw GPS_INPUT fields (GR_*)
    _tx: bytearray = None           # the SERVO_OUTPUT_RAW frame being sent, and as uint8
    _tx_u8: np.ndarray = None
    _tx_mv: memoryview = None
    _tx_views: tuple = ()           # _tx_mv[:n] for every frame length n (no slice per send)
    _gps_raw_mv: memoryview = None  # _gps_raw as a memoryview (a read gives a float)
    # the compiled calls' arrays by address (fc/frame_calls.py: no numba array record per call)
    _rx_addr: int = 0
    _gps_raw_addr: int = 0
    _tx_addr: int = 0
    _meas_at: ArrayAddress = None
    _pwm_at: ArrayAddress = None
    _hot_at: ArrayAddress = None    # counters.hot
    #: the receive and the answer call libc from compiled code (fc/frame_calls.py; their
    #: start-up self-check passed, the socket is IPv4 and does not stamp arrivals)
    _fast_io: bool = False
    _fd: int = -1
    _sa: np.ndarray = None          # the source of the last datagram (sockaddr_in bytes)
    _salen: np.ndarray = None       # its length (uint32[1])
    _peer_sa: np.ndarray = None     # ``peer`` as sockaddr_in bytes (zeros when None)
    _peer_sa_of: tuple | None = None    # the ``peer`` that _peer_sa holds
    _io: np.ndarray = None          # int64[IO_N]: the receive's length, the frame's stamp
    stamp_cell_at: int = 0          # the address of ``_io[IO_STAMP]`` (``read_frame_at``)
    _sa_addr: int = 0
    _salen_addr: int = 0
    _peer_sa_addr: int = 0
    _io_addr: int = 0

    def __post_init__(self) -> None:
        self.gps = np.zeros(G_N)
        self.codec = new_codec(self.sysid, self.compid)
        self._tx_codec = new_codec(self.sysid, self.compid)
        self._rx = bytearray(MAX_DATAGRAM_B)
        self._rx_u8 = np.frombuffer(self._rx, np.uint8)
        self._gps_raw = np.zeros(GR_N)
        self._tx = bytearray(SERVO_FRAME_MAX_B)
        self._tx_u8 = np.frombuffer(self._tx, np.uint8)
        self._tx_mv = memoryview(self._tx)
        self._tx_views = tuple(self._tx_mv[:n] for n in range(SERVO_FRAME_MAX_B + 1))
        self._gps_raw_mv = memoryview(self._gps_raw)
        self._rx_addr = ArrayAddress(np.uint8, MAX_DATAGRAM_B, self._rx_u8).addr
        self._gps_raw_addr = ArrayAddress(np.float64, GR_N, self._gps_raw).addr
        self._tx_addr = ArrayAddress(np.uint8, SERVO_FRAME_MAX_B, self._tx_u8).addr
        self._meas_at = ArrayAddress(np.float64, M_N)
        self._pwm_at = ArrayAddress(np.int64, 4)
        self._hot_at = ArrayAddress(np.int64, HOT_N)
        self._sa = np.zeros(SOCKADDR_IN_B, np.uint8)
        self._salen = np.zeros(1, np.uint32)
        self._peer_sa = np.zeros(SOCKADDR_IN_B, np.uint8)
        self._io = np.zeros(IO_N, np.int64)
        self._sa_addr = address_of(self._sa, np.uint8, SOCKADDR_IN_B)
        self._salen_addr = address_of(self._salen, np.uint32, 1)
        self._peer_sa_addr = address_of(self._peer_sa, np.uint8, SOCKADDR_IN_B)
        self._io_addr = address_of(self._io, np.int64, IO_N)
        #: the address of the int64 cell holding the stamp of the frame ``read_frame_at``
        #: answered FRAME_AT for (the intake, the planner and the answer read it there)
        self.stamp_cell_at = self._io_addr + 8 * IO_STAMP
        self._fd = self.endpoint.sock.fileno()
        self._fast = _lean_self_check(self)
        self._fast_io = (self._fast and FAST_IO and self.endpoint.sock.family == socket.AF_INET
                         and _libc_io_self_check(self))

    def read_frame(self, meas_out: np.ndarray) -> int:
        """Read datagrams until one complete accepted frame is decoded into ``meas_out``.

        Returns the frame stamp in us (u64) or -1 when no acceptable datagram is waiting.
        At most 64 datagrams are read per call (bounded work). :meth:`read_frame_at` without
        the stamp as a Python int."""
        code = self.read_frame_at(meas_out)
        if code == FRAME_AT:
            return self._io.item(IO_STAMP)
        return self.big_stamp if code == FRAME_BIG else -1

    def read_frame_at(self, meas_out: np.ndarray) -> int:
        """:meth:`read_frame` returning a code: FRAME_AT (the stamp, below STAMP_CELL_MAX_US, in
        the int64 cell at ``stamp_cell_at``), FRAME_BIG (a stamp at or beyond it, a faulty
        plant's u64: in ``big_stamp``, a Python int) or FRAME_NONE. In the common case (a frame
        from the locked peer) no Python object is made (``_fast_io``: receive, source check and
        decode in one compiled call, the stamp left in the cell)."""
        if self._fast_io and not self.endpoint.stamped:
            return self._read_frame_compiled(meas_out)
        rx = self._rx
        for _ in range(64):
            got = self.endpoint.recv_into(rx)
            if got is None:
                self.counters.empty_reads += 1
                return FRAME_NONE
            n, addr = got
            self.counters.datagrams += 1
            stamp = self._accept(n, addr, meas_out)
            if stamp >= 0:
                return self._stamp_code(stamp)
        return FRAME_NONE

    def _stamp_code(self, stamp: int) -> int:
        """A frame stamped ``stamp`` (a Python int) taken: into the cell, or ``big_stamp``."""
        if stamp < STAMP_CELL_MAX_US:
            self._io[IO_STAMP] = stamp
            return FRAME_AT
        self.big_stamp = stamp
        return FRAME_BIG

    def _read_frame_compiled(self, meas_out: np.ndarray) -> int:
        """:meth:`read_frame_at` through ``recv_sensor_p`` (counted there); a datagram it does
        not take (another source, none locked yet, rejected by the compiled decoder) goes
        through :meth:`_accept` as the socket path's would."""
        if self.peer is not self._peer_sa_of:
            self._bind_peer_sa()
        meas = self._meas_at.of(meas_out)
        hot = self._hot_at.of(self.counters.hot)
        locked = self.peer is not None
        k = 64                          # (counted down: no range object per call)
        while k:
            k -= 1
            code = recv_sensor_p(self._fd, self._rx_addr, MAX_DATAGRAM_B, self._sa_addr,
                                 self._salen_addr, self._peer_sa_addr, locked,
                                 self.plant_sysid, meas, M_N, self._gps_raw_addr, GR_N, hot,
                                 self._io_addr)
            if code == RX_FRAME or code == RX_FRAME_BIG:
                return self._frame_received(code)
            if code == RX_NONE:
                return FRAME_NONE
            src = self.peer if code == RX_REJECTED else self._source()
            stamp = self._accept(int(self._io[IO_LEN]), src, meas_out)
            if stamp >= 0:
                return self._stamp_code(stamp)
            locked = self.peer is not None
            if self.peer is not self._peer_sa_of:
                self._bind_peer_sa()
        return FRAME_NONE

    def _frame_received(self, code: int) -> int:
        """After ``recv_sensor_p`` answered RX_FRAME or RX_FRAME_BIG: the frame's GNSS sample
        (if any), its arrival, the run not ended; FRAME_AT or FRAME_BIG."""
        if self._gps_raw_mv[GR_PRESENT]:       # (a float: no numpy scalar per frame)
            self._take_gps(self._io.item(IO_STAMP))
        self.frame_rx_ns = self.endpoint.rx_ns
        self.ended = False
        if code == RX_FRAME_BIG:
            return self._stamp_code(self._io.item(IO_STAMP))
        return FRAME_AT

    def read_frame_after(self, code: int, meas_out: np.ndarray) -> int:
        """:meth:`read_frame_at` when ``recv_sensor_p`` has already answered ``code`` for the
        first datagram (the fused lockstep exchange, fc/fused.py, with ``meas_out`` as its
        frame): that datagram as the receive loop takes it, then the next ones as it would."""
        if code == RX_FRAME or code == RX_FRAME_BIG:
            return self._frame_received(code)
        if code == RX_NONE:
            return FRAME_NONE
        src = self.peer if code == RX_REJECTED else self._source()
        stamp = self._accept(int(self._io[IO_LEN]), src, meas_out)
        if stamp >= 0:
            return self._stamp_code(stamp)
        return self._read_frame_compiled(meas_out)

    def _accept(self, n: int, addr: tuple, meas_out: np.ndarray) -> int:
        """The datagram of ``n`` bytes in the receive buffer, from ``addr`` (counted as
        received): its stamp (the source locked or relocked to ``addr`` as needed), or -1
        (counted)."""
        relock = False
        if self.peer is not None and addr != self.peer:
            if not self.relock_allowed:
                self.counters.rejected_addr += 1
                return -1
            relock = True
        stamp = self._decode_rx(n, meas_out)
        if stamp < 0:
            return -1
        if self.peer is None or relock:
            if relock:
                self.counters.relocks += 1
            self.peer = addr
            self.relock_allowed = False
        self.counters.frames += 1
        self.frame_rx_ns = self.endpoint.rx_ns
        self.ended = False
        return stamp

    def _source(self) -> tuple:
        """The source of the datagram ``recv_sensor_p`` received (its sockaddr_in) as
        ``socket`` gives it: (dotted IPv4 address, port)."""
        sa = self._sa
        return socket.inet_ntoa(sa[4:8].tobytes()), int.from_bytes(sa[2:4].tobytes(), "big")

    def _bind_peer_sa(self) -> None:
        """``_peer_sa`` := ``peer`` as sockaddr_in bytes (all zero when None: matches no
        source, and the answer is not sent then)."""
        sa = self._peer_sa
        sa[:] = 0
        if self.peer is not None:
            sa[0:2] = np.frombuffer(socket.AF_INET.to_bytes(2, "little" if _LITTLE else "big"),
                                    np.uint8)
            sa[2:4] = np.frombuffer(int(self.peer[1]).to_bytes(2, "big"), np.uint8)
            sa[4:8] = np.frombuffer(socket.inet_aton(socket.gethostbyname(self.peer[0])),
                                    np.uint8)
        self._peer_sa_of = self.peer

    def _decode(self, data: bytes, meas_out: np.ndarray) -> int:
        """Decode the datagram ``data`` into ``meas_out``: its stamp (us), or -1 (counted)."""
        n = len(data)
        if n > len(self._rx):
            return self._decode_general(data, meas_out)
        self._rx[:n] = data
        return self._decode_rx(n, meas_out)

    def _decode_rx(self, n: int, meas_out: np.ndarray) -> int:
        """``_decode`` of the first ``n`` bytes of the receive buffer: the compiled decoder in
        the common case; anything it rejects (its code says why) goes to the codec's general
        parser, which counts what it rejects: the same result, only the cost changes."""
        if self._fast:
            stamp = decode_sensor_p(self._rx_addr, MAX_DATAGRAM_B, n, self.plant_sysid,
                                    self._meas_at.of(meas_out), M_N, self._gps_raw_addr, GR_N)
            if stamp >= 0:
                self._take_gps(stamp)
                return stamp
        return self._decode_general(bytes(self._rx[:n]), meas_out)

    def _take_gps(self, stamp: int) -> None:
        """The GPS_INPUT the compiled decoder found in the frame stamped ``stamp``, if any."""
        if self._gps_raw_mv[GR_PRESENT]:       # (a float: no numpy scalar per frame)
            g = self._gps_raw
            self._store_gps(stamp, int(g[GR_LAT_E7]), int(g[GR_LON_E7]), g[GR_ALT], g[GR_VN],
                            g[GR_VE], g[GR_VD], int(g[GR_FIX]), int(g[GR_SATS]), g[GR_HACC_M],
                            g[GR_VACC_M], g[GR_SACC_M_S])

    def _decode_general(self, data: bytes, meas_out: np.ndarray) -> int:
        """The codec's general parser: any datagram, every rejection counted."""
        msgs, n_bad = decode_datagram(self.codec, data)
        if n_bad:
            self.counters.rejected_bad += 1
            return -1
        if self.peer is not None and self._is_goodbye(msgs):
            return -1
        att = aoa = hud = gps = None
        for m in msgs:
            if m.get_srcSystem() != self.plant_sysid:
                self.counters.rejected_sysid += 1
                return -1
            t = m.get_msgId()
            if t == mavlink.MAVLINK_MSG_ID_ATTITUDE:
                att = m
            elif t == mavlink.MAVLINK_MSG_ID_AOA_SSA:
                aoa = m
            elif t == mavlink.MAVLINK_MSG_ID_VFR_HUD:
                hud = m
            elif t == mavlink.MAVLINK_MSG_ID_GPS_INPUT:
                gps = m
        if att is None or aoa is None or hud is None:
            self.counters.rejected_incomplete += 1
            return -1
        stamp = int(aoa.time_usec)
        if gps is not None:
            self._store_gps(stamp, gps.lat, gps.lon, gps.alt, gps.vn, gps.ve, gps.vd,
                            gps.fix_type, gps.satellites_visible, gps.horiz_accuracy,
                            gps.vert_accuracy, gps.speed_accuracy)
        meas_out[M_T_S] = stamp * 1e-6
        meas_out[M_ROLL] = att.roll
        meas_out[M_PITCH] = att.pitch
        meas_out[M_YAW] = att.yaw
        meas_out[M_P] = att.rollspeed
        meas_out[M_Q] = att.pitchspeed
        meas_out[M_R] = att.yawspeed
        meas_out[M_AOA] = math.radians(aoa.AOA)
        meas_out[M_SSA] = math.radians(aoa.SSA)
        meas_out[M_AIRSPEED] = hud.airspeed
        meas_out[M_ALT] = hud.alt
        meas_out[M_CLIMB] = hud.climb
        meas_out[M_GROUNDSPEED] = hud.groundspeed
        meas_out[M_HEADING] = math.radians(hud.heading)
        return stamp

    def _is_goodbye(self, msgs: list) -> bool:
        """A datagram of the plant's HEARTBEAT with MAV_STATE_POWEROFF: its run is over
        (docs/wire.md section 5). Sets ``ended``; counted once per run (the plant sends
        a few copies)."""
        if not msgs or any(m.get_srcSystem() != self.plant_sysid
                           or m.get_msgId() != mavlink.MAVLINK_MSG_ID_HEARTBEAT
                           or m.system_status != mavlink.MAV_STATE_POWEROFF for m in msgs):
            return False
        if not self.ended:
            self.ended = True
            self.counters.goodbyes += 1
        return True

    def _store_gps(self, stamp_us: int, lat_e7: int, lon_e7: int, alt_m: float, vn: float,
                   ve: float, vd: float, fix: int, sats: int, hacc_m: float, vacc_m: float,
                   sacc_m_s: float) -> None:
        """Keep a GNSS sample (GPS_INPUT fields, degE7 and m) in ``gps`` (layout G_*). A sample
        with a non-finite value or out of range (lat/lon beyond +-90/180 deg, |alt| beyond the
        i32 mm of the ground-station messages) is dropped and counted (``gnss_rejected``)."""
        if not (abs(lat_e7) <= 900_000_000 and abs(lon_e7) <= 1_800_000_000
                and abs(alt_m) < 2.0e6 and math.isfinite(vn + ve + vd + hacc_m + vacc_m
                                                         + sacc_m_s)):
            self.counters.gnss_rejected += 1
            return
        g = self.gps
        g[G_T_S] = stamp_us * 1e-6
        g[G_LAT_DEG] = lat_e7 * 1e-7
        g[G_LON_DEG] = lon_e7 * 1e-7
        g[G_ALT_M] = alt_m
        g[G_VN] = vn
        g[G_VE] = ve
        g[G_VD] = vd
        g[G_FIX] = fix
        g[G_SATS] = sats
        g[G_HACC_M] = hacc_m
        g[G_VACC_M] = vacc_m
        g[G_SACC_M_S] = sacc_m_s
        self.gps_samples += 1
        self.counters.gnss += 1

    def send_servo_at(self, pwm_us) -> bool:
        """:meth:`send_servo` answering the frame :meth:`read_frame_at` answered FRAME_AT for:
        its stamp read from the cell in the compiled call (no Python int for it) when the
        answer is framed and sent compiled and ``pwm_us`` is the int64[4] it takes."""
        if self._fast_io and self.peer is not None and type(pwm_us) is np.ndarray and len(
                pwm_us) == 4:
            try:
                pwm_addr = self._pwm_at.of(pwm_us)
            except ValueError:
                pwm_addr = 0
            if pwm_addr:
                if self.peer is not self._peer_sa_of:
                    self._bind_peer_sa()
                return self._sent(send_servo_at_p(self._fd, self._tx_addr, SERVO_FRAME_MAX_B,
                                                  self._tx_codec.seq, self.sysid, self.compid,
                                                  self.stamp_cell_at, pwm_addr,
                                                  self._peer_sa_addr,
                                                  self._hot_at.of(self.counters.hot)))
        return self.send_servo(self._io.item(IO_STAMP), pwm_us)

    def _sent(self, ok: bool) -> bool:
        """After a compiled answer (counted there when sent): a failed send counted, the
        sequence stepped."""
        if not ok:
            self.endpoint.send_errors += 1
        self._tx_codec.seq = (self._tx_codec.seq + 1) % 256
        return ok

    def send_servo(self, stamp_us: int, pwm_us) -> bool:
        """Answer a frame: SERVO_OUTPUT_RAW echoing ``stamp_us`` mod 2^32 (docs/wire.md 3).

        ``pwm_us``: (left, right, rudder) or (left, right, rudder, throttle) in us; the
        throttle channel (servo4, ``throttle_to_pwm``) is 0 = no output when absent.
        """
        if self.peer is None:
            return False
        if self._fast:                  # same bytes as the codec's pack (self-checked)
            if type(pwm_us) is not np.ndarray or len(pwm_us) != 4:
                pwm_us = _pwm4(pwm_us)
            try:
                pwm_addr = self._pwm_at.of(pwm_us)
            except ValueError:          # not int64: converted as servo_frame would
                pwm_addr = self._pwm_at.of(_pwm4(pwm_us))
            if stamp_us > 0xFFFFFFFF:   # (the kernel takes the low 32 bits of an int64)
                stamp_us &= 0xFFFFFFFF
            if self._fast_io:           # framed and sent in one compiled call (counted there)
                if self.peer is not self._peer_sa_of:
                    self._bind_peer_sa()
                return self._sent(send_servo_p(self._fd, self._tx_addr, SERVO_FRAME_MAX_B,
                                               self._tx_codec.seq, self.sysid, self.compid,
                                               stamp_us, pwm_addr, self._peer_sa_addr,
                                               self._hot_at.of(self.counters.hot)))
            buf = self._tx_views[servo_frame_p(self._tx_addr, SERVO_FRAME_MAX_B,
                                               self._tx_codec.seq, self.sysid, self.compid,
                                               stamp_us, pwm_addr)]
        else:
            s4 = pwm_us[3] if len(pwm_us) > 3 else 0
            buf = self._tx_codec.servo_output_raw_encode(
                stamp_us & 0xFFFFFFFF, 0, pwm_us[0], pwm_us[1], pwm_us[2], s4, 0, 0, 0,
                0).pack(self._tx_codec)
        ok = self.endpoint.send(buf, self.peer)
        self._tx_codec.seq = (self._tx_codec.seq + 1) % 256
        if ok:
            self.counters.outputs += 1
        return ok
