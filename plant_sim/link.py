"""The plant's MAVLink link: the only module of plant_sim that imports pymavlink.

MAVLink 2, ardupilotmega dialect (AOA_SSA), pymavlink's generated codec on our own
non-blocking UDP socket (docs/wire.md sections 2-4):
- ``send_sensors``: ATTITUDE + AOA_SSA + VFR_HUD packed into ONE datagram per frame, into a
  preallocated bytearray; AOA_SSA.time_usec is the frame stamp.
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

    # ---- sending ----
    def _append(self, msg, pos: int) -> int:
        mav = self.mav
        b = msg.pack(mav)
        mav.seq = (mav.seq + 1) & 0xFF
        n = len(b)
        self._out_mv[pos:pos + n] = b
        return pos + n

    def build_sensors(self, stamp_us: int, meas, throttle_pct: float) -> None:
        """Pack ATTITUDE, AOA_SSA, VFR_HUD for one frame into the send buffer.

        meas: float64[14] measurement vector (architecture.md section 4, SI).
        """
        mav = self.mav
        pos = self._append(mav.attitude_encode((stamp_us // 1000) % U32, meas[1], meas[2], meas[3],
                                               meas[4], meas[5], meas[6]), 0)
        pos = self._append(mav.aoa_ssa_encode(stamp_us, meas[7] * RAD, meas[8] * RAD), pos)
        hdg = int(meas[13] * RAD + 0.5) % 360
        thr = int(min(100.0, max(0.0, throttle_pct)) + 0.5)
        pos = self._append(mav.vfr_hud_encode(meas[9], meas[12], hdg, thr, meas[10], meas[11]), pos)
        self._out_len = pos

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
                pwm = self.pwm
                c = self.cmd_rad
                if m.servo1_raw:
                    c[0] = pwm.to_rad(m.servo1_raw)
                if m.servo2_raw:
                    c[1] = pwm.to_rad(m.servo2_raw)
                if m.servo3_raw:
                    c[2] = pwm.to_rad(m.servo3_raw)
                self.cmd_stamp_u32 = stamp
                self.applied_count += 1

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

    ``answer(fn)`` is called with (stamp_us, meas_dict) and returns three deflections (rad).
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
        pw = [self.pwm.to_pwm(v) for v in d]
        msg = self.mav.servo_output_raw_encode(stamp % U32, 0, pw[0], pw[1], pw[2], 0, 0, 0, 0, 0)
        b = msg.pack(self.mav)
        self.mav.seq = (self.mav.seq + 1) & 0xFF
        self.sock.sendto(b, addr)
        self.peer = addr
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
