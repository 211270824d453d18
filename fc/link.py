"""fc/link.py - the flight controller's only MAVLink import: codec, sockets, plant link.

Everything that touches pymavlink in the fc lives here (docs/architecture.md section 1):
the generated ``ardupilotmega`` MAVLink 2 codec, a non-blocking UDP endpoint, the
datagram decoder that never raises, the plant link (sensor frames in, SERVO_OUTPUT_RAW
out, docs/wire.md) and the PWM <-> deflection mapping of docs/wire.md section 3.
``fc/gcs.py`` takes its codec (``new_codec``, ``mavlink``) from this module.
"""
from __future__ import annotations

import hashlib
import math
import os
import socket
import stat
import struct
from dataclasses import dataclass, field

import numpy as np

os.environ["MAVLINK20"] = "1"
from pymavlink.dialects.v20 import ardupilotmega as mavlink  # noqa: E402
# The standard-modes messages (AVAILABLE_MODES 435, CURRENT_MODE 436) and PARAM_ERROR (345)
# are in development.xml only (pymavlink 2.4.50): their classes are packed by the
# ardupilotmega codec (a message packs with its own CRC extra), nothing else is used from it.
from pymavlink.dialects.v20 import development as mavlink_dev  # noqa: E402

__all__ = [
    "mavlink", "mavlink_dev", "new_codec", "UdpEndpoint", "decode_datagram", "PlantLink",
    "LinkCounters", "LeanFramer",
    "deflection_to_pwm", "pwm_to_deflection", "load_signing_key", "parse_hostport",
    "M_T_S", "M_ROLL", "M_PITCH", "M_YAW", "M_P", "M_Q", "M_R", "M_AOA", "M_SSA",
    "M_AIRSPEED", "M_ALT", "M_CLIMB", "M_GROUNDSPEED", "M_HEADING", "M_N",
    "G_T_S", "G_LAT_DEG", "G_LON_DEG", "G_ALT_M", "G_VN", "G_VE", "G_VD", "G_FIX", "G_SATS",
    "G_HACC_M", "G_VACC_M", "G_SACC_M_S", "G_N",
]

# Measurement vector layout (docs/architecture.md section 4), SI.
M_T_S = 0
M_ROLL = 1
M_PITCH = 2
M_YAW = 3
M_P = 4
M_Q = 5
M_R = 6
M_AOA = 7
M_SSA = 8
M_AIRSPEED = 9
M_ALT = 10
M_CLIMB = 11
M_GROUNDSPEED = 12
M_HEADING = 13
M_N = 14

# GNSS sample layout (docs/wire.md section 2; plant_sim/gnss.py defines the same), SI and deg.
G_T_S = 0          # stamp of the frame that carried the sample (s)
G_LAT_DEG = 1
G_LON_DEG = 2
G_ALT_M = 3        # MSL
G_VN = 4           # m/s, NED
G_VE = 5
G_VD = 6
G_FIX = 7          # GPS_FIX_TYPE
G_SATS = 8
G_HACC_M = 9
G_VACC_M = 10
G_SACC_M_S = 11
G_N = 12

# PWM mapping of docs/wire.md section 3 (ArduPilot SERVOn_MIN/TRIM/MAX).
PWM_MIN_US = 1000
PWM_TRIM_US = 1500
PWM_MAX_US = 2000
DEFLECTION_LIMIT_RAD = math.radians(20.0)

MAX_DATAGRAM_B = 2048


def parse_hostport(text: str) -> tuple[str, int]:
    """Parse ``HOST:PORT`` into a socket address; ValueError with a clear message otherwise."""
    host, sep, port = text.rpartition(":")
    if not sep or not host:
        raise ValueError(f"expected HOST:PORT, got {text!r}")
    try:
        port_n = int(port)
    except ValueError:
        raise ValueError(f"port must be an integer in {text!r}") from None
    if not 0 <= port_n <= 65535:
        raise ValueError(f"port out of range in {text!r}")
    return host, port_n


class _NullFile:
    """Write sink for the codec: we send packed bytes ourselves."""

    def write(self, _buf: bytes) -> None:
        return None


def new_codec(sysid: int, compid: int = 1) -> mavlink.MAVLink:
    """A MAVLink 2 ``ardupilotmega`` codec sending as ``sysid``/``compid``.

    ``robust_parsing`` is on: malformed input becomes ``MAVLink_bad_data`` instead of raising.
    """
    mav = mavlink.MAVLink(_NullFile(), srcSystem=sysid, srcComponent=compid)
    mav.robust_parsing = True
    return mav


def decode_datagram(mav: mavlink.MAVLink, data: bytes) -> tuple[list, int]:
    """Decode one UDP datagram into messages; never raises.

    The parser state is reset first, so a truncated frame in one datagram cannot swallow
    the next datagram's bytes. Returns ``(messages, n_bad)`` where ``n_bad`` counts
    malformed frames (bad prefix, CRC, length, signature).
    """
    mav.buf = bytearray()
    mav.buf_index = 0
    mav.expected_length = mavlink.HEADER_LEN_V1 + 2
    mav.have_prefix_error = False
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


def deflection_to_pwm(delta_rad: float, trim_us: int = PWM_TRIM_US) -> int:
    """Surface deflection [rad] -> PWM [us] (docs/wire.md section 3), clipped to MIN..MAX."""
    if not math.isfinite(delta_rad):
        return trim_us
    if delta_rad >= 0.0:
        us = trim_us + delta_rad / DEFLECTION_LIMIT_RAD * (PWM_MAX_US - trim_us)
    else:
        us = trim_us + delta_rad / DEFLECTION_LIMIT_RAD * (trim_us - PWM_MIN_US)
    us = int(round(us))
    return PWM_MIN_US if us < PWM_MIN_US else PWM_MAX_US if us > PWM_MAX_US else us


def pwm_to_deflection(pwm_us: int, trim_us: int = PWM_TRIM_US) -> float:
    """PWM [us] -> deflection [rad], the inverse of :func:`deflection_to_pwm`."""
    pwm_us = min(max(pwm_us, PWM_MIN_US), PWM_MAX_US)
    if pwm_us >= trim_us:
        return (pwm_us - trim_us) / (PWM_MAX_US - trim_us) * DEFLECTION_LIMIT_RAD
    return (pwm_us - trim_us) / (trim_us - PWM_MIN_US) * DEFLECTION_LIMIT_RAD


#: Throttle on SERVO_OUTPUT_RAW servo4 (docs/wire.md s. 3): PWM 1000..2000 us = 0..1.
THROTTLE_PWM_MIN_US = 1000
THROTTLE_PWM_MAX_US = 2000


def throttle_to_pwm(throttle: float) -> int:
    """Throttle 0..1 -> servo4 PWM (us), clipped to 1000..2000; 0 (no output: the plant keeps
    its last throttle) for a value that is not finite."""
    if not math.isfinite(throttle):
        return 0
    us = int(round(THROTTLE_PWM_MIN_US + throttle * (THROTTLE_PWM_MAX_US - THROTTLE_PWM_MIN_US)))
    return min(max(us, THROTTLE_PWM_MIN_US), THROTTLE_PWM_MAX_US)


_SO_TIMESTAMPNS = getattr(socket, "SO_TIMESTAMPNS", 35)   # Linux value where Python lacks it
_TIMESPEC = struct.Struct("=qq")                          # struct timespec on 64-bit Linux
_ANC_B = socket.CMSG_SPACE(_TIMESPEC.size) if hasattr(socket, "CMSG_SPACE") else 64


class UdpEndpoint:
    """A bound, non-blocking UDP socket. ``recv`` returns None when nothing is waiting."""

    def __init__(self, host: str, port: int) -> None:
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 20)
        except OSError:
            pass
        try:
            sock.bind((host, port))
        except OSError as exc:
            sock.close()
            raise OSError(f"cannot bind UDP {host}:{port}: {exc}") from exc
        self._adopt(sock)

    @classmethod
    def wrap(cls, sock: socket.socket) -> "UdpEndpoint":
        """An endpoint over an already bound socket (made non-blocking)."""
        ep = cls.__new__(cls)
        ep._adopt(sock)
        return ep

    def _adopt(self, sock: socket.socket) -> None:
        sock.setblocking(False)
        self.sock = sock
        self.address = sock.getsockname()
        self.send_errors = 0
        #: kernel receive time of the last datagram ``recv`` returned (CLOCK_REALTIME, ns);
        #: 0 unless :meth:`enable_rx_timestamps` succeeded
        self.rx_ns = 0
        self._stamped = False

    def enable_rx_timestamps(self) -> bool:
        """Ask the kernel to stamp each datagram on arrival (``SO_TIMESTAMPNS``); ``recv``
        then stores the stamp in ``rx_ns``. Costs ~0.6 us per datagram (recvmsg instead of
        recvfrom). Returns False where the option is not available."""
        try:
            self.sock.setsockopt(socket.SOL_SOCKET, _SO_TIMESTAMPNS, 1)
        except (OSError, AttributeError):
            return False
        self._stamped = True
        return True

    def recv(self) -> tuple[bytes, tuple] | None:
        try:
            if self._stamped:
                data, anc, _flags, addr = self.sock.recvmsg(MAX_DATAGRAM_B, _ANC_B)
                self.rx_ns = 0
                for level, kind, cdata in anc:
                    if level == socket.SOL_SOCKET and kind == _SO_TIMESTAMPNS \
                            and len(cdata) >= 16:
                        sec, nsec = _TIMESPEC.unpack_from(cdata)
                        self.rx_ns = sec * 1_000_000_000 + nsec
                return data, addr
            return self.sock.recvfrom(MAX_DATAGRAM_B)
        except (BlockingIOError, InterruptedError):
            return None
        except OSError:
            # e.g. ICMP port unreachable reported on a later recv (ECONNREFUSED)
            return None

    def send(self, data: bytes, addr: tuple) -> bool:
        try:
            self.sock.sendto(data, addr)
            return True
        except OSError:
            self.send_errors += 1
            return False

    def fileno(self) -> int:
        return self.sock.fileno()

    def close(self) -> None:
        self.sock.close()


# ---- lean decode of the expected sensor datagram (performance; docs/performance.md) -------
_MAGIC2 = mavlink.PROTOCOL_MARKER_V2
_HDR2 = 10                                   # MAVLink 2 header length
_mcrf4xx = getattr(mavlink, "mcrf4xx", None)  # fastcrc's CRC-16/MCRF4XX, as the codec uses


def _crc16(data, init: int = 0xFFFF) -> int:
    """X.25 CRC (CRC-16/MCRF4XX) as the codec computes it, from ``init``."""
    if _mcrf4xx is not None:
        return _mcrf4xx(data, init)
    c = mavlink.x25crc()
    c.crc = init
    c.accumulate(bytes(data))
    return c.crc


class _LeanSensorDecoder:
    """Fast path for the one datagram the plant link expects (docs/wire.md section 2).

    Accepts only a datagram made of exactly ATTITUDE, AOA_SSA and VFR_HUD and at most one
    GPS_INPUT (any order, each once), unsigned MAVLink 2 with good CRCs, all from
    ``plant_sysid``, and unpacks them with
    the generated codec's own payload structs (zero-padding truncated payloads, as the codec
    does) straight into the measurement vector. Anything else returns -1 without touching
    ``meas_out``, and the caller takes the codec's general parser, which also does the
    counting: what is accepted or rejected, and the values, are the same as before; only the
    cost of the common case changes (about 3.5 us instead of 19 us per datagram).
    """

    _CLASSES = (mavlink.MAVLink_attitude_message, mavlink.MAVLink_aoa_ssa_message,
                mavlink.MAVLink_vfr_hud_message, mavlink.MAVLink_gps_input_message)

    def __init__(self) -> None:
        self.spec = {}
        for slot, cls in enumerate(self._CLASSES):
            size = cls.unpacker.size
            self.spec[cls.id] = (slot, cls.unpacker, size, bytes((cls.crc_extra,)), bytes(size))
        self._vals = [None, None, None, None]
        #: the GPS_INPUT payload tuple of the last accepted datagram, None if it had none
        self.gps = None

    def decode(self, data: bytes, plant_sysid: int, meas_out: np.ndarray) -> int:
        n = len(data)
        pos = 0
        vals = self._vals
        vals[0] = vals[1] = vals[2] = vals[3] = None
        spec = self.spec
        while pos < n:
            if n - pos < _HDR2 + 2 or data[pos] != _MAGIC2 or data[pos + 2] != 0:
                return -1                        # not MAVLink 2, or signed / incompat flags
            mlen = data[pos + 1]
            end = pos + _HDR2 + mlen
            if end + 2 > n or data[pos + 5] != plant_sysid:
                return -1
            sp = spec.get(data[pos + 7] | (data[pos + 8] << 8) | (data[pos + 9] << 16))
            if sp is None:
                return -1
            slot, unpacker, size, extra, zeros = sp
            if mlen > size or vals[slot] is not None:
                return -1
            if _crc16(extra, _crc16(data[pos + 1:end])) != data[end] | (data[end + 1] << 8):
                return -1
            payload = data[pos + _HDR2:end]
            if mlen < size:
                payload += zeros[mlen:]
            vals[slot] = unpacker.unpack(payload)
            pos = end + 2
        att, aoa, hud, self.gps = vals
        if att is None or aoa is None or hud is None:
            return -1
        # ATTITUDE <Iffffff time_boot_ms roll pitch yaw rollspeed pitchspeed yawspeed;
        # AOA_SSA <Qff time_usec AOA SSA; VFR_HUD <ffffhH airspeed groundspeed alt climb
        # heading throttle (wire order, checked by _lean_self_check)
        stamp = aoa[0]
        meas_out[M_T_S] = stamp * 1e-6
        meas_out[M_ROLL] = att[1]
        meas_out[M_PITCH] = att[2]
        meas_out[M_YAW] = att[3]
        meas_out[M_P] = att[4]
        meas_out[M_Q] = att[5]
        meas_out[M_R] = att[6]
        meas_out[M_AOA] = math.radians(aoa[1])
        meas_out[M_SSA] = math.radians(aoa[2])
        meas_out[M_AIRSPEED] = hud[0]
        meas_out[M_ALT] = hud[2]
        meas_out[M_CLIMB] = hud[3]
        meas_out[M_GROUNDSPEED] = hud[1]
        meas_out[M_HEADING] = math.radians(hud[4])
        return stamp


class _LeanServoPacker:
    """SERVO_OUTPUT_RAW with channels 1-4 only (port 0, other channels 0), framed as the
    codec's ``msg.pack`` does (MAVLink 2, unsigned, trailing-zero truncation), from the
    codec's own payload layout and CRC_EXTRA. Checked byte for byte against the codec by
    ``_lean_self_check``."""

    _CLS = mavlink.MAVLink_servo_output_raw_message

    def __init__(self, sysid: int, compid: int) -> None:
        import struct
        # wire order: time_usec (u32), servo1..4 (u16) lead the payload; the rest is zero
        assert self._CLS.unpacker.format.startswith("<IHHHH")
        self.head = struct.Struct("<IHHHH")
        self.hdr = bytearray((_MAGIC2, 0, 0, 0, 0, sysid & 0xFF, compid & 0xFF,
                              self._CLS.id & 0xFF, (self._CLS.id >> 8) & 0xFF,
                              self._CLS.id >> 16))
        self.extra = bytes((self._CLS.crc_extra,))

    def pack(self, seq: int, time_usec: int, s1: int, s2: int, s3: int, s4: int = 0) -> bytes:
        payload = self.head.pack(time_usec, s1, s2, s3, s4).rstrip(b"\0") or b"\0"
        h = self.hdr
        h[1] = len(payload)
        h[4] = seq
        frame = bytes(h) + payload
        crc = _crc16(self.extra, _crc16(frame[1:]))
        return frame + bytes((crc & 0xFF, crc >> 8))


def _payload_only(_mav, _crc_extra, payload, force_mavlink1=False):
    return payload


class LeanFramer:
    """MAVLink 2 framing (unsigned) of the codec's message objects without the codec's
    per-message overhead: the payload from the message's own generated ``pack`` (its wire-order
    struct, arrays and strings as the codec handles them), then trailing-zero truncation,
    header and CRC with CRC_EXTRA as ``msg.pack(mav)`` does: the same bytes (``ok`` is the
    start-up check against the codec; False: callers use ``msg.pack``). About 3 us instead
    of 9-12 us per message; the fc's flight log frames every message with it."""

    def __init__(self, sysid: int, compid: int) -> None:
        self.hdr = bytearray((_MAGIC2, 0, 0, 0, 0, sysid & 0xFF, compid & 0xFF, 0, 0, 0))
        self.ok = False
        try:
            self.ok = self._self_check(sysid, compid)
        except Exception:  # noqa: BLE001 - any surprise: the codec's own pack
            self.ok = False

    def frame(self, msg, seq: int) -> bytes:
        msg._pack = _payload_only          # the generated pack hands us its payload
        try:
            payload = msg.pack(None)
        finally:
            del msg._pack
        payload = payload.rstrip(b"\0") or b"\0"
        h = self.hdr
        mid = msg.get_msgId()           # (STATUSTEXT has a field named id)
        h[1] = len(payload)
        h[4] = seq
        h[7] = mid & 0xFF
        h[8] = (mid >> 8) & 0xFF
        h[9] = mid >> 16
        frame = bytes(h) + payload
        crc = _crc16(bytes((msg.crc_extra,)), _crc16(frame[1:]))
        return frame + bytes((crc & 0xFF, crc >> 8))

    def _self_check(self, sysid: int, compid: int) -> bool:
        c = new_codec(sysid, compid)
        samples = (c.attitude_encode(123, 0.1, -0.2, 0.3, 0.0, 1e-3, -2.5),
                   c.heartbeat_encode(1, 0, 129, 2, 4),
                   c.debug_vect_encode(b"SIM_T", 2_000_000, 2.0, 0.0, 0.0),
                   c.named_value_float_encode(7, b"GAMMA_DEG", -0.5),
                   c.home_position_encode(349054000, -1178839000, 21_000_000, 0.0, 0.0, 0.0,
                                          [1.0, 0.0, 0.0, 0.0], 0.0, 0.0, 0.0, 5),
                   c.gps_raw_int_encode(10, 3, 1, -1, 0, 65535, 65535, 65535, 0, 12, 0, 1500,
                                        3000, 100, 0, 0),
                   c.statustext_encode(6, b"home set"),
                   c.system_time_encode(0, 0))
        for seq, msg in zip((0, 1, 255, 7, 128, 3, 9, 200), samples):
            c.seq = seq
            if self.frame(msg, seq) != msg.pack(c):
                return False
        return True


def _lean_self_check(link: "PlantLink") -> bool:
    """True if the lean decoder gives exactly the general parser's result on a codec-built
    frame (field order, truncation, CRC_EXTRA of this pymavlink); else the link keeps the
    general parser only."""
    try:
        tx = new_codec(link.plant_sysid)
        buf = tx.attitude_encode(1234, 0.1, -0.2, 0.3, 0.01, -0.02, 0.0).pack(tx)
        buf += tx.aoa_ssa_encode(1_234_567, 2.5, 0.0).pack(tx)
        buf += tx.vfr_hud_encode(2200.0, 2190.0, 45, 0, 25000.0, -1.5).pack(tx)
        lean = link._lean
        for extra in (b"", tx.gps_input_encode(1_234_567, 0, 0, 0, 0, 3, 349054321, -1178839876,
                                                21000.5, 1.0, 1.0, 2199.5, -3.25, 1.5, 0.1, 1.5,
                                                3.0, 12, 0).pack(tx)):
            a = np.full(M_N, -1.0)
            b = np.full(M_N, -2.0)
            link._lean = None
            try:
                sa = link._decode(buf + extra, a)
                ga = link.gps.copy()
            finally:
                link._lean = lean
            link.gps[:] = 0.0
            sb = link._decode(buf + extra, b)
            if not (sa == sb == 1_234_567 and bool(np.array_equal(a, b))
                    and bool(np.array_equal(ga, link.gps))):
                return False
        link.gps[:] = 0.0
        link.gps_samples = 0
        link.counters.gnss = 0
        c = new_codec(link.sysid, link.compid)
        for seq, args in ((0, (0, 1500, 1500, 1500, 0)), (7, (123456, 1000, 2000, 1500, 1420)),
                          (255, (0xFFFFFFFF, 0, 0, 0, 0)), (3, (256, 0, 0, 0, 2000))):
            c.seq = seq
            ref = c.servo_output_raw_encode(args[0], 0, args[1], args[2], args[3],
                                            args[4], 0, 0, 0, 0).pack(c)
            if link._packer.pack(seq, *args) != ref:
                return False
        return True
    except Exception:  # noqa: BLE001 - any surprise: stay on the general parser
        return False


@dataclass(slots=True)
class LinkCounters:
    """Rejected and accepted input of the plant link (telemetry and fc.log)."""

    datagrams: int = 0
    frames: int = 0               # complete sensor frames accepted
    duplicates: int = 0           # frames with a stamp already answered (plant re-requests)
    rejected_sysid: int = 0       # from a system id other than the plant's
    rejected_addr: int = 0        # from another address than the first accepted one
    rejected_bad: int = 0         # malformed MAVLink (CRC, length, prefix)
    rejected_incomplete: int = 0  # datagram without the ATTITUDE+AOA_SSA+VFR_HUD triple
    gnss: int = 0                 # GNSS samples (GPS_INPUT) accepted with a frame
    gnss_rejected: int = 0        # GNSS samples dropped: non-finite or out of range
    outputs: int = 0
    relocks: int = 0              # new source address accepted after a data loss
    goodbyes: int = 0             # the plant said its run is over (docs/wire.md section 5)

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
    #: the newest GNSS sample (layout G_*; G_T_S = the stamp of the frame that carried it,
    #: G_FIX 0 until the first one); ``gps_samples`` counts them
    gps: np.ndarray = None
    gps_samples: int = 0
    _tx_codec: mavlink.MAVLink = None
    _lean: _LeanSensorDecoder | None = None
    _packer: _LeanServoPacker | None = None

    def __post_init__(self) -> None:
        self.gps = np.zeros(G_N)
        self.codec = new_codec(self.sysid, self.compid)
        self._tx_codec = new_codec(self.sysid, self.compid)
        self._lean = _LeanSensorDecoder()
        self._packer = _LeanServoPacker(self.sysid, self.compid)
        if not _lean_self_check(self):
            self._lean = None
            self._packer = None

    def read_frame(self, meas_out: np.ndarray) -> int:
        """Read datagrams until one complete accepted frame is decoded into ``meas_out``.

        Returns the frame stamp in us (u64) or -1 when no acceptable datagram is waiting.
        At most 64 datagrams are read per call (bounded work).
        """
        for _ in range(64):
            got = self.endpoint.recv()
            if got is None:
                return -1
            data, addr = got
            self.counters.datagrams += 1
            relock = False
            if self.peer is not None and addr != self.peer:
                if not self.relock_allowed:
                    self.counters.rejected_addr += 1
                    continue
                relock = True
            stamp = self._decode(data, meas_out)
            if stamp < 0:
                continue
            if self.peer is None or relock:
                if relock:
                    self.counters.relocks += 1
                self.peer = addr
                self.relock_allowed = False
            self.counters.frames += 1
            self.frame_rx_ns = self.endpoint.rx_ns
            self.ended = False
            return stamp
        return -1

    def _decode(self, data: bytes, meas_out: np.ndarray) -> int:
        if self._lean is not None:      # the common case, same result as below
            stamp = self._lean.decode(data, self.plant_sysid, meas_out)
            if stamp >= 0:
                g = self._lean.gps
                if g is not None:
                    # GPS_INPUT <QIiifffffffffHHBBBH: time_usec time_week_ms lat lon alt hdop
                    # vdop vn ve vd speed_acc horiz_acc vert_acc ignore_flags time_week gps_id
                    # fix_type satellites_visible yaw (wire order)
                    self._store_gps(stamp, g[2], g[3], g[4], g[7], g[8], g[9], g[16], g[17],
                                    g[11], g[12], g[10])
                return stamp
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

    def send_servo(self, stamp_us: int, pwm_us) -> bool:
        """Answer a frame: SERVO_OUTPUT_RAW echoing ``stamp_us`` mod 2^32 (docs/wire.md 3).

        ``pwm_us``: (left, right, rudder) or (left, right, rudder, throttle) in us; the
        throttle channel (servo4, ``throttle_to_pwm``) is 0 = no output when absent.
        """
        if self.peer is None:
            return False
        s4 = pwm_us[3] if len(pwm_us) > 3 else 0
        if self._packer is not None:    # same bytes as the codec's pack (self-checked)
            buf = self._packer.pack(self._tx_codec.seq, stamp_us & 0xFFFFFFFF,
                                    pwm_us[0], pwm_us[1], pwm_us[2], s4)
        else:
            buf = self._tx_codec.servo_output_raw_encode(
                stamp_us & 0xFFFFFFFF, 0, pwm_us[0], pwm_us[1], pwm_us[2], s4, 0, 0, 0,
                0).pack(self._tx_codec)
        ok = self.endpoint.send(buf, self.peer)
        self._tx_codec.seq = (self._tx_codec.seq + 1) % 256
        if ok:
            self.counters.outputs += 1
        return ok
