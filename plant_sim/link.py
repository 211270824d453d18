"""The plant's MAVLink link: the only module of plant_sim that imports pymavlink.

MAVLink 2, ardupilotmega dialect (AOA_SSA), pymavlink's generated codec on our own
non-blocking UDP socket (docs/wire.md sections 2-4):
- ``send_sensors``: ATTITUDE + AOA_SSA + VFR_HUD (+ GPS_INPUT on GNSS frames) packed into ONE
  datagram per frame, into a preallocated bytearray; AOA_SSA.time_usec is the frame stamp.
- ``poll_for`` / ``poll_latest``: drain the socket, decodes SERVO_OUTPUT_RAW from the fc's address and system id
  only, converts PWM to deflection through MIN/TRIM/MAX (ArduPilot SERVOn_*), and counts
  everything it rejects (malformed bytes, wrong source address, wrong system id, other
  messages). It never raises on input.
"""
from __future__ import annotations

import errno
import math
import os
import select
import socket

os.environ["MAVLINK20"] = "1"
from pymavlink.dialects.v20 import ardupilotmega as mavlink  # noqa: E402

DEG = math.pi / 180.0
RAD = 180.0 / math.pi
MSG_ID_SERVO_OUTPUT_RAW = mavlink.MAVLINK_MSG_ID_SERVO_OUTPUT_RAW
BAD_DATA = mavlink.MAVLink_bad_data
U32 = 1 << 32
HDR2 = 10            # MAVLink 2 header length
MAGIC2 = mavlink.PROTOCOL_MARKER_V2

_mcrf4xx = getattr(mavlink, "mcrf4xx", None)     # fastcrc's CRC-16/MCRF4XX, as the codec uses


def _crc16(data, init: int = 0xFFFF) -> int:
    """X.25 CRC (CRC-16/MCRF4XX) of the codec, starting from ``init``."""
    if _mcrf4xx is not None:
        return _mcrf4xx(data, init)
    c = mavlink.x25crc()
    c.crc = init
    c.accumulate(bytes(data))
    return c.crc


class _Packer:
    """Lean MAVLink 2 framing of one message type with the generated codec's own payload
    struct (wire field order), CRC_EXTRA and message id, written in place into a bytearray.
    Produces the same bytes as ``msg.pack(mav)`` (checked at link start-up)."""

    def __init__(self, cls, msg_id: int):
        self.st = cls.unpacker
        self.size = cls.unpacker.size
        self.crc_extra = cls.crc_extra
        self.id_lo = msg_id & 0xFF
        self.id_mid = (msg_id >> 8) & 0xFF
        self.id_hi = msg_id >> 16

    def pack_into(self, buf: bytearray, mv: memoryview, pos: int, seq: int, sysid: int,
                  compid: int, *fields) -> int:
        """Frame at ``pos``; returns the position after it."""
        pl = pos + HDR2
        self.st.pack_into(buf, pl, *fields)
        n = self.size
        while n > 1 and buf[pl + n - 1] == 0:       # MAVLink 2 trailing-zero truncation
            n -= 1
        buf[pos] = MAGIC2
        buf[pos + 1] = n
        buf[pos + 2] = 0
        buf[pos + 3] = 0
        buf[pos + 4] = seq
        buf[pos + 5] = sysid
        buf[pos + 6] = compid
        buf[pos + 7] = self.id_lo
        buf[pos + 8] = self.id_mid
        buf[pos + 9] = self.id_hi
        end = pl + n
        buf[end] = self.crc_extra                   # CRC covers header[1:], payload, CRC_EXTRA
        crc = _crc16(mv[pos + 1:end + 1])
        buf[end] = crc & 0xFF
        buf[end + 1] = crc >> 8
        return end + 2


_P_ATT = _Packer(mavlink.MAVLink_attitude_message, mavlink.MAVLINK_MSG_ID_ATTITUDE)
_P_AOA = _Packer(mavlink.MAVLink_aoa_ssa_message, mavlink.MAVLINK_MSG_ID_AOA_SSA)
_P_HUD = _Packer(mavlink.MAVLink_vfr_hud_message, mavlink.MAVLINK_MSG_ID_VFR_HUD)
_P_GPS = _Packer(mavlink.MAVLink_gps_input_message, mavlink.MAVLINK_MSG_ID_GPS_INPUT)
GPS_HDOP = 1.0       # GPS_INPUT hdop/vdop: a nominal constellation (accuracies carry the noise)
_SERVO = mavlink.MAVLink_servo_output_raw_message
# wire order: time_usec, servo1..8, port, servo9..16
_P_SERVO = _Packer(_SERVO, MSG_ID_SERVO_OUTPUT_RAW)
_SERVO_CRC_EXTRA = _SERVO.crc_extra
_SERVO_SIZE = _SERVO.unpacker.size
_ZEROS = bytes(_SERVO_SIZE)


def parse_hostport(text: str, what: str) -> tuple[str, int]:
    """'HOST:PORT' -> (host, port); ValueError with a clear message otherwise."""
    host, sep, port = text.rpartition(":")
    if not sep or not host:
        raise ValueError(f"{what}: expected HOST:PORT, got {text!r}")
    try:
        p = int(port)
    except ValueError:
        raise ValueError(f"{what}: port must be an integer, got {port!r}") from None
    if not 0 <= p <= 65535:
        raise ValueError(f"{what}: port {p} out of range 0..65535")
    return host, p


#: Throttle on SERVO_OUTPUT_RAW servo4 (docs/wire.md s. 3): PWM 1000..2000 us = 0..1.
THROTTLE_PWM_MIN_US = 1000
THROTTLE_PWM_MAX_US = 2000


def throttle_from_pwm(pwm_us: int) -> float:
    """servo4 PWM (us) -> throttle 0..1, clipped (1000 us = 0, 2000 us = 1)."""
    f = (pwm_us - THROTTLE_PWM_MIN_US) / (THROTTLE_PWM_MAX_US - THROTTLE_PWM_MIN_US)
    return 0.0 if f < 0.0 else 1.0 if f > 1.0 else f


class PwmMap:
    """PWM (us) <-> deflection (rad) as ArduPilot's SERVOn_MIN/TRIM/MAX (docs/wire.md s. 3)."""

    def __init__(self, pwm_min: int, pwm_trim: int, pwm_max: int, limit_rad: float):
        if not pwm_min < pwm_trim < pwm_max:
            raise ValueError("PWM map needs MIN < TRIM < MAX")
        self.pwm_min = pwm_min
        self.pwm_trim = pwm_trim
        self.pwm_max = pwm_max
        self.limit_rad = limit_rad
        self._up = limit_rad / (pwm_max - pwm_trim)
        self._down = limit_rad / (pwm_trim - pwm_min)

    def to_rad(self, pwm: int) -> float:
        if pwm < self.pwm_min:
            pwm = self.pwm_min
        elif pwm > self.pwm_max:
            pwm = self.pwm_max
        d = pwm - self.pwm_trim
        return d * self._up if d >= 0 else d * self._down

    def to_pwm(self, rad: float) -> int:
        if rad >= 0.0:
            v = self.pwm_trim + rad / self._up
        else:
            v = self.pwm_trim + rad / self._down
        v = int(round(v))
        return min(self.pwm_max, max(self.pwm_min, v))


class PlantLink:
    """UDP link of the plant to the fc.

    Parameters
    ----------
    fc_addr : (host, port) the fc listens on; sensor frames go there and servo frames are
        accepted only from there.
    bind_addr : (host, port) of the plant's own socket (port 0: ephemeral).
    sysid, compid : the plant's MAVLink identity (default 2, 1).
    fc_sysid : system id the servo frames must carry (default 1).
    pwm : PwmMap for the three surface channels.
    """

    def __init__(self, fc_addr, bind_addr, pwm: PwmMap, sysid: int = 2, compid: int = 1,
                 fc_sysid: int = 1):
        self.fc_addr = (socket.gethostbyname(fc_addr[0]), int(fc_addr[1]))
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 20)
        self.sock.bind((bind_addr[0], int(bind_addr[1])))
        self.sock.setblocking(False)
        self.local_addr = self.sock.getsockname()
        self.mav = mavlink.MAVLink(None, srcSystem=sysid, srcComponent=compid)
        self.mav.robust_parsing = True
        self.fc_sysid = fc_sysid
        self.pwm = pwm
        self._out = bytearray(512)
        self._out_mv = memoryview(self._out)
        self._out_len = 0
        self._rxbuf = bytearray(2048)
        self._rx_mv = memoryview(self._rxbuf)
        # latest accepted servo frame
        self.cmd_rad = [0.0, 0.0, 0.0]
        self.cmd_throttle = -1.0    # servo4 as throttle 0..1; -1 until a frame carries it
        self.cmd_stamp_u32 = -1
        self.cmd_count = 0          # valid servo frames accepted
        self.applied_count = 0      # of which applied (lockstep: the answer; real time: newest)
        # counters
        self.frames_sent = 0
        self.rx_datagrams = 0
        self.rejected_malformed = 0
        self.rejected_source = 0
        self.rejected_sysid = 0
        self.ignored_messages = 0
        self.send_errors = 0
        self._crcbuf = bytearray(300)
        self._crc_mv = memoryview(self._crcbuf)
        self._pad = bytearray(_SERVO_SIZE)
        self.lean = True
        self.lean = self._self_check()     # False: use the codec's message objects throughout

    # ---- sending ----
    def _append(self, msg, pos: int) -> int:
        mav = self.mav
        b = msg.pack(mav)
        mav.seq = (mav.seq + 1) & 0xFF
        n = len(b)
        self._out_mv[pos:pos + n] = b
        return pos + n

    def build_sensors(self, stamp_us: int, meas, throttle_pct: float, gnss=None) -> None:
        """Pack ATTITUDE, AOA_SSA, VFR_HUD (and GPS_INPUT when ``gnss`` holds a GNSS sample)
        for one frame into the send buffer.

        meas: float64[14] measurement vector (architecture.md section 4, SI); gnss: None or
        float64[G_N] GNSS sample (plant_sim/gnss.py layout, docs/wire.md section 2).
        """
        if not self.lean:
            self._build_with_codec(stamp_us, meas, throttle_pct, gnss)
            return
        buf = self._out
        mv = self._out_mv
        mav = self.mav
        seq = mav.seq
        sy = mav.srcSystem
        co = mav.srcComponent
        hdg = int(meas[13] * RAD + 0.5) % 360
        thr = int(min(100.0, max(0.0, throttle_pct)) + 0.5)
        pos = _P_ATT.pack_into(buf, mv, 0, seq, sy, co, (stamp_us // 1000) % U32,
                               meas[1], meas[2], meas[3], meas[4], meas[5], meas[6])
        pos = _P_AOA.pack_into(buf, mv, pos, (seq + 1) & 0xFF, sy, co, stamp_us,
                               meas[7] * RAD, meas[8] * RAD)
        # VFR_HUD wire order: airspeed, groundspeed, alt, climb, heading, throttle
        pos = _P_HUD.pack_into(buf, mv, pos, (seq + 2) & 0xFF, sy, co, meas[9], meas[12],
                               meas[10], meas[11], hdg, thr)
        if gnss is None:
            mav.seq = (seq + 3) & 0xFF
        else:
            # GPS_INPUT wire order: time_usec, time_week_ms, lat, lon, alt, hdop, vdop, vn, ve,
            # vd, speed_accuracy, horiz_accuracy, vert_accuracy, ignore_flags, time_week,
            # gps_id, fix_type, satellites_visible, yaw
            pos = _P_GPS.pack_into(buf, mv, pos, (seq + 3) & 0xFF, sy, co, stamp_us, 0,
                                   int(round(gnss[1] * 1e7)), int(round(gnss[2] * 1e7)),
                                   gnss[3], GPS_HDOP, GPS_HDOP, gnss[4], gnss[5], gnss[6],
                                   gnss[11], gnss[9], gnss[10], 0, 0, 0, int(gnss[7]),
                                   int(gnss[8]), 0)
            mav.seq = (seq + 4) & 0xFF
        self._out_len = pos

    def _build_with_codec(self, stamp_us: int, meas, throttle_pct: float, gnss=None) -> None:
        """The same frames through pymavlink's message objects (reference path)."""
        mav = self.mav
        pos = self._append(mav.attitude_encode((stamp_us // 1000) % U32, meas[1], meas[2], meas[3],
                                               meas[4], meas[5], meas[6]), 0)
        pos = self._append(mav.aoa_ssa_encode(stamp_us, meas[7] * RAD, meas[8] * RAD), pos)
        hdg = int(meas[13] * RAD + 0.5) % 360
        thr = int(min(100.0, max(0.0, throttle_pct)) + 0.5)
        pos = self._append(mav.vfr_hud_encode(meas[9], meas[12], hdg, thr, meas[10], meas[11]), pos)
        if gnss is not None:
            pos = self._append(mav.gps_input_encode(
                stamp_us, 0, 0, 0, 0, int(gnss[7]), int(round(gnss[1] * 1e7)),
                int(round(gnss[2] * 1e7)), gnss[3], GPS_HDOP, GPS_HDOP, gnss[4], gnss[5],
                gnss[6], gnss[11], gnss[9], gnss[10], int(gnss[8]), 0), pos)
        self._out_len = pos

    def _self_check(self) -> bool:
        """The lean packer and decoder give the codec's bytes and values (start-up check)."""
        import numpy as np
        meas = np.array([0.0, 0.1, -0.2, 3.0, 0.01, -0.02, 0.0, 0.05, -0.01, 2200.0, 21000.0,
                         -1.5, 2199.0, 6.1])
        gnss = np.array([0.0, 34.9054321, -117.8839876, 21000.5, 2199.5, -3.25, 1.5, 3.0, 12.0,
                         1.5, 3.0, 0.1])
        seq0 = self.mav.seq
        for g in (None, gnss):
            self.lean = True
            self.build_sensors(123456789, meas, 42.0, g)
            lean = bytes(self._out_mv[:self._out_len])
            self.mav.seq = seq0
            self._build_with_codec(123456789, meas, 42.0, g)
            ref = bytes(self._out_mv[:self._out_len])
            self.mav.seq = seq0
            if lean != ref:
                return False
        m = mavlink.MAVLink(None, srcSystem=self.fc_sysid, srcComponent=1)
        frame = m.servo_output_raw_encode(987654, 0, 1234, 1766, 0, 1500, 0, 0, 0, 0).pack(m)
        got = self._decode_servo_fast(frame, len(frame))
        return got == (self.fc_sysid, 987654, 1234, 1766, 0, 1500)

    def send_sensors(self) -> bool:
        """Send the last built sensor frame (again). Returns False if the OS refused it."""
        try:
            self.sock.sendto(self._out_mv[:self._out_len], self.fc_addr)
        except OSError as e:
            if e.errno in (errno.EAGAIN, errno.EWOULDBLOCK, errno.ECONNREFUSED, errno.ENOBUFS):
                self.send_errors += 1
                return False
            raise
        self.frames_sent += 1
        return True

    def send_goodbye(self, copies: int = 3) -> int:
        """Tell the fc that the run is over (docs/wire.md section 5): HEARTBEAT with
        ``system_status`` MAV_STATE_POWEROFF, sent ``copies`` times. Returns how many went."""
        mav = self.mav
        sent = 0
        for _ in range(copies):
            data = mav.heartbeat_encode(mavlink.MAV_TYPE_GENERIC, mavlink.MAV_AUTOPILOT_INVALID,
                                        0, 0, mavlink.MAV_STATE_POWEROFF).pack(mav)
            mav.seq = (mav.seq + 1) & 0xFF
            try:
                self.sock.sendto(data, self.fc_addr)
                sent += 1
            except OSError:
                self.send_errors += 1
        return sent

    # ---- receiving ----
    def wait_readable(self, timeout_s: float) -> bool:
        """Block up to ``timeout_s`` for the socket to become readable (select: us resolution)."""
        r, _, _ = select.select((self.sock,), (), (), max(0.0, timeout_s))
        return bool(r)

    def poll_for(self, want_stamp_u32: int) -> tuple[int, bool]:
        """Lockstep: drain the socket; apply only a servo frame whose stamp is ``want_stamp_u32``.

        Returns (servo frames accepted, whether the wanted one was among them). Frames with
        another stamp are accepted (valid) but not applied: the caller counts them as stale.
        """
        return self._drain(want_stamp_u32)

    def poll_latest(self) -> int:
        """Real time: drain the socket; apply the newest servo frame by stamp (older ones that
        arrive late are not applied). Returns the number of frames accepted."""
        return self._drain(-1)[0]

    def _drain(self, want: int) -> tuple[int, bool]:
        accepted = 0
        match = False
        sock = self.sock
        mav = self.mav
        while True:
            try:
                n, addr = sock.recvfrom_into(self._rxbuf)
            except (BlockingIOError, InterruptedError):
                return accepted, match
            except ConnectionRefusedError:
                continue           # ICMP from an earlier send to a closed port
            except OSError:
                self.rejected_malformed += 1
                return accepted, match
            self.rx_datagrams += 1
            if addr[0] != self.fc_addr[0] or addr[1] != self.fc_addr[1]:
                self.rejected_source += 1
                continue
            fast = self._decode_servo_fast(self._rxbuf, n) if self.lean else None
            if fast is not None:
                sysid, stamp, s1, s2, s3, s4 = fast
                if sysid != self.fc_sysid:
                    self.rejected_sysid += 1
                    continue
                accepted += 1
                self.cmd_count += 1
                if want >= 0:
                    if stamp != want:
                        continue
                    self._apply(stamp, s1, s2, s3, s4)
                    return accepted, True     # lockstep: the rest waits for the next drain
                if self.cmd_stamp_u32 >= 0 and ((stamp - self.cmd_stamp_u32) % U32) >= (U32 >> 1):
                    continue
                self._apply(stamp, s1, s2, s3, s4)
                continue
            try:
                msgs = mav.parse_buffer(self._rx_mv[:n])
            except Exception:       # never die on input; pymavlink may raise on odd bytes
                msgs = None
                self.rejected_malformed += 1
            if mav.buf_len() > 0:   # a datagram is self-contained: drop leftover partial bytes
                self.rejected_malformed += 1
            mav.buf = bytearray()
            mav.buf_index = 0
            mav.expected_length = mavlink.HEADER_LEN_V1 + 2
            if not msgs:
                continue
            for m in msgs:
                if isinstance(m, BAD_DATA):
                    self.rejected_malformed += 1
                    continue
                if m.get_msgId() != MSG_ID_SERVO_OUTPUT_RAW:
                    self.ignored_messages += 1
                    continue
                if m.get_srcSystem() != self.fc_sysid:
                    self.rejected_sysid += 1
                    continue
                accepted += 1
                self.cmd_count += 1
                stamp = m.time_usec
                if want >= 0:
                    if stamp != want:
                        continue
                    match = True
                elif self.cmd_stamp_u32 >= 0 and ((stamp - self.cmd_stamp_u32) % U32) >= (U32 >> 1):
                    continue        # older than the command already applied
                self._apply(stamp, m.servo1_raw, m.servo2_raw, m.servo3_raw, m.servo4_raw)

    def _apply(self, stamp: int, s1: int, s2: int, s3: int, s4: int = 0) -> None:
        """Latch a servo frame: PWM -> rad per surface channel, servo4 PWM -> throttle 0..1
        (``throttle_from_pwm``); a channel value 0 keeps its command."""
        pwm = self.pwm
        c = self.cmd_rad
        if s1:
            c[0] = pwm.to_rad(s1)
        if s2:
            c[1] = pwm.to_rad(s2)
        if s3:
            c[2] = pwm.to_rad(s3)
        if s4:
            self.cmd_throttle = throttle_from_pwm(s4)
        self.cmd_stamp_u32 = stamp
        self.applied_count += 1

    def decode_servo(self, data) -> tuple | None:
        """(sysid, time_usec, servo1, servo2, servo3, servo4) of a one-frame SERVO_OUTPUT_RAW
        datagram (lean path), or None if the datagram needs the general parser."""
        return self._decode_servo_fast(data, len(data))

    def _decode_servo_fast(self, buf, n: int):
        """Decode a datagram that is exactly one unsigned MAVLink 2 SERVO_OUTPUT_RAW with a good
        CRC: returns (sysid, time_usec, servo1, servo2, servo3, servo4), else None (the caller then
        takes the codec's general parser, which also counts malformed input)."""
        if n < HDR2 + 3 or buf[0] != MAGIC2 or buf[2] != 0:
            return None
        mlen = buf[1]
        if n != HDR2 + mlen + 2 or mlen > _SERVO_SIZE:
            return None
        if buf[7] != MSG_ID_SERVO_OUTPUT_RAW or buf[8] != 0 or buf[9] != 0:
            return None
        end = HDR2 + mlen
        cb = self._crcbuf
        cb[0:end - 1] = buf[1:end]
        cb[end - 1] = _SERVO_CRC_EXTRA
        if _crc16(self._crc_mv[:end]) != buf[end] | (buf[end + 1] << 8):
            return None
        pad = self._pad
        pad[0:mlen] = buf[HDR2:end]
        pad[mlen:] = _ZEROS[mlen:]
        v = _SERVO.unpacker.unpack_from(pad, 0)
        return buf[5], v[0], v[1], v[2], v[3], v[4]

    def counters(self) -> dict:
        return {
            "frames_sent": self.frames_sent,
            "rx_datagrams": self.rx_datagrams,
            "servo_frames_accepted": self.cmd_count,
            "servo_frames_applied": self.applied_count,
            "rejected_malformed": self.rejected_malformed,
            "rejected_source": self.rejected_source,
            "rejected_sysid": self.rejected_sysid,
            "ignored_messages": self.ignored_messages,
            "send_errors": self.send_errors,
        }

    def close(self) -> None:
        self.sock.close()


class ServoResponder:
    """A minimal fc stand-in for tests and benchmarks: answers sensor frames with
    SERVO_OUTPUT_RAW echoing the frame stamp (codec here so pymavlink stays in this module).

    ``serve_one(fn)`` calls fn(stamp_us, meas_dict), which returns three deflections (rad),
    or four values with a throttle (0..1) last, sent on servo4 (docs/wire.md s. 3).
    """

    def __init__(self, bind_addr=("127.0.0.1", 0), sysid: int = 1, pwm: PwmMap | None = None):
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(bind_addr)
        self.sock.setblocking(False)
        self.addr = self.sock.getsockname()
        self.mav = mavlink.MAVLink(None, srcSystem=sysid, srcComponent=1)
        self.mav.robust_parsing = True
        self.pwm = pwm or PwmMap(1000, 1500, 2000, 20.0 * DEG)
        self.answered = 0
        self.peer = None
        self._rx = bytearray(2048)
        self._tx = bytearray(128)
        self._tx_mv = memoryview(self._tx)

    def serve_one(self, fn, timeout_s: float = 1.0) -> bool:
        """Wait for one sensor datagram and answer it; False on timeout."""
        r, _, _ = select.select((self.sock,), (), (), timeout_s)
        if not r:
            return False
        try:
            data, addr = self.sock.recvfrom(2048)
        except BlockingIOError:
            return False
        msgs = self.mav.parse_buffer(data) or []
        vals = {}
        stamp = None
        for m in msgs:
            t = m.get_type()
            if t == "AOA_SSA":
                stamp = m.time_usec
                vals["aoa_deg"] = m.AOA
                vals["ssa_deg"] = m.SSA
            elif t == "ATTITUDE":
                vals.update(roll=m.roll, pitch=m.pitch, yaw=m.yaw, p=m.rollspeed, q=m.pitchspeed,
                            r=m.yawspeed, time_boot_ms=m.time_boot_ms)
            elif t == "VFR_HUD":
                vals.update(airspeed=m.airspeed, alt=m.alt, climb=m.climb, heading=m.heading,
                            groundspeed=m.groundspeed, throttle=m.throttle)
        if stamp is None:
            return False
        d = fn(stamp, vals)
        pw = [self.pwm.to_pwm(v) for v in d[:3]]
        s4 = 0
        if len(d) > 3:
            s4 = int(round(THROTTLE_PWM_MIN_US
                           + min(max(d[3], 0.0), 1.0) * (THROTTLE_PWM_MAX_US - THROTTLE_PWM_MIN_US)))
        msg = self.mav.servo_output_raw_encode(stamp % U32, 0, pw[0], pw[1], pw[2], s4, 0, 0, 0, 0)
        b = msg.pack(self.mav)
        self.mav.seq = (self.mav.seq + 1) & 0xFF
        self.sock.sendto(b, addr)
        self.peer = addr
        self.answered += 1
        return True

    def serve_fast(self, timeout_s: float = 1.0) -> bool:
        """Benchmark responder: answer one frame with a neutral PWM. Reads the stamp straight
        from the AOA_SSA frame (second in the datagram) and frames the reply with the lean
        packer: a few microseconds, so the exchange rate measures the plant and the network."""
        r, _, _ = select.select((self.sock,), (), (), timeout_s)
        if not r:
            return False
        try:
            n, addr = self.sock.recvfrom_into(self._rx)
        except BlockingIOError:
            return False
        b = self._rx
        if n < 2:
            return False
        pos = HDR2 + b[1] + 2                      # skip ATTITUDE
        if n < pos + HDR2 + 1:
            return False
        mlen = b[pos + 1]
        pay = bytearray(16)
        pay[0:min(mlen, 16)] = b[pos + HDR2:pos + HDR2 + min(mlen, 16)]
        stamp = int.from_bytes(pay[0:8], "little")
        end = _P_SERVO.pack_into(self._tx, self._tx_mv, 0, self.mav.seq, self.mav.srcSystem,
                                 self.mav.srcComponent, stamp % U32, 1500, 1500, 1500,
                                 0, 0, 0, 0, 0,         # servo4..8
                                 0,                     # port
                                 0, 0, 0, 0, 0, 0, 0, 0)  # servo9..16
        self.mav.seq = (self.mav.seq + 1) & 0xFF
        self.sock.sendto(self._tx_mv[:end], addr)
        self.answered += 1
        return True

    def send_raw(self, data: bytes, addr) -> None:
        self.sock.sendto(data, addr)

    def servo_frame(self, stamp_us: int, pwm3, sysid: int | None = None) -> bytes:
        """Bytes of a SERVO_OUTPUT_RAW frame (optionally from another system id)."""
        mav = self.mav if sysid is None else mavlink.MAVLink(None, srcSystem=sysid, srcComponent=1)
        return mav.servo_output_raw_encode(stamp_us % U32, 0, pwm3[0], pwm3[1], pwm3[2],
                                           0, 0, 0, 0, 0).pack(mav)

    def close(self) -> None:
        self.sock.close()
