"""The plant's MAVLink link: the only module of plant_sim that imports pymavlink.

MAVLink 2, ardupilotmega dialect (AOA_SSA), pymavlink's generated codec on our own
non-blocking UDP socket (docs/wire.md sections 2-4):
- ``send_sensors``: ATTITUDE + AOA_SSA + VFR_HUD (+ GPS_INPUT on GNSS frames) packed into ONE
  datagram per frame, into a preallocated bytearray; AOA_SSA.time_usec is the frame stamp.
- ``poll_for`` / ``poll_latest``: drain the socket, decodes SERVO_OUTPUT_RAW from the fc's address and system id
  only, converts PWM to deflection through MIN/TRIM/MAX (ArduPilot SERVOn_*), and counts
  everything it rejects (malformed bytes, wrong source address, wrong system id, other
  messages). It never raises on input.

The message layouts, the lean framing (same bytes as the codec), the PWM map and the codec
itself come from the contract package (hyfc_wire); this module is the plant's one MAVLink edge.
"""
from __future__ import annotations

import errno
import math
import select
import socket

import numpy as np

from hyfc_wire.codec import mavlink, new_codec, reset_parser
from hyfc_wire.frame_kernels import SENSOR_FRAME_MAX_B, SV_N, decode_servo, sensor_frame
from hyfc_wire.framing import GPS_HDOP, HDR2, U32, SensorFramer, ServoPacker
from hyfc_wire.layout import G_N
from hyfc_wire.pwm import DEFAULT_PWM, PwmMap, throttle_from_pwm, throttle_to_pwm

RAD = 180.0 / math.pi
MSG_ID_SERVO_OUTPUT_RAW = mavlink.MAVLINK_MSG_ID_SERVO_OUTPUT_RAW
BAD_DATA = mavlink.MAVLink_bad_data
_SENSOR_FRAMER = SensorFramer()


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
        self.mav = new_codec(sysid, compid)
        self.fc_sysid = fc_sysid
        self.pwm = pwm
        self._out = bytearray(max(512, SENSOR_FRAME_MAX_B))
        self._out_mv = memoryview(self._out)
        self._out_np = np.frombuffer(self._out, dtype=np.uint8)     # the same memory
        self._no_gnss = np.zeros(G_N)
        self._out_len = 0
        self._rxbuf = bytearray(2048)
        self._rx_mv = memoryview(self._rxbuf)
        self._rx_np = np.frombuffer(self._rxbuf, dtype=np.uint8)    # the same memory
        self._servo_rec = np.zeros(SV_N, dtype=np.int64)
        self._scratch_np = np.zeros(len(self._rxbuf), dtype=np.uint8)  # decode_servo(data)
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
        mav = self.mav
        # compiled framing (hyfc_wire.frame_kernels.sensor_frame, the same bytes); a value the
        # codec's struct refuses (-1) goes through the Python framer, which raises as before
        pos = sensor_frame(self._out_np, mav.seq, mav.srcSystem, mav.srcComponent, stamp_us,
                           meas, throttle_pct, self._no_gnss if gnss is None else gnss,
                           gnss is not None)
        if pos >= 0:
            frames = 3 if gnss is None else 4
        else:
            pos, frames = _SENSOR_FRAMER.pack_into(self._out, self._out_mv, mav.seq,
                                                   mav.srcSystem, mav.srcComponent, stamp_us,
                                                   meas, throttle_pct, gnss)
        mav.seq = (mav.seq + frames) & 0xFF
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
        m = new_codec(self.fc_sysid)
        frame = m.servo_output_raw_encode(987654, 0, 1234, 1766, 0, 1500, 0, 0, 0, 0).pack(m)
        got = self.decode_servo(frame)
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
            fast = self.decode_rx(n) if self.lean else None
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
            acc, got = self.parse_rx(n, want)
            accepted += acc
            match = match or got

    def parse_rx(self, n: int, want: int) -> tuple[int, bool]:
        """The codec's general parser on the datagram in the first ``n`` bytes of the receive
        buffer (one the compiled decoder did not take): counts what it rejects, accepts and
        applies SERVO_OUTPUT_RAW frames as the drain does (``want``: the lockstep's stamp, or
        -1 for the newest). Returns (frames accepted, whether ``want`` was among them)."""
        mav = self.mav
        accepted = 0
        match = False
        try:
            msgs = mav.parse_buffer(self._rx_mv[:n])
        except Exception:       # never die on input; pymavlink may raise on odd bytes
            msgs = None
            self.rejected_malformed += 1
        if mav.buf_len() > 0:   # a datagram is self-contained: drop leftover partial bytes
            self.rejected_malformed += 1
        reset_parser(mav)
        if not msgs:
            return accepted, match
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
        return accepted, match

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
        n = len(data)
        if n > len(self._scratch_np):
            return None
        buf = self._scratch_np            # writable, preallocated: the kernel's one signature
        buf[:n] = np.frombuffer(data, dtype=np.uint8)
        return self._decode_servo_fast(buf, n)

    def decode_rx(self, n: int):
        """``decode_servo`` of the first ``n`` bytes of the receive buffer (where the drain's
        ``recvfrom_into`` puts each datagram; ``put_rx`` for a benchmark): no copy."""
        return self._decode_servo_fast(self._rx_np, n)

    def put_rx(self, data) -> int:
        """Place ``data`` in the receive buffer as a receive would (benchmarks); its length."""
        n = len(data)
        self._rx_np[:n] = np.frombuffer(data, dtype=np.uint8)
        return n

    def _decode_servo_fast(self, buf, n: int):
        """(sysid, time_usec, servo1..4) of a datagram (``buf``: uint8 array) that is exactly
        one good unsigned SERVO_OUTPUT_RAW, else None (the caller takes the general parser,
        which counts). Compiled: ``hyfc_wire.frame_kernels.decode_servo``."""
        r = self._servo_rec
        if not decode_servo(buf, n, r):
            return None
        return tuple(r.tolist())       # (sysid, time_usec, servo1..4): the SV_* order

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
        self.mav = new_codec(sysid)
        self.pwm = pwm or DEFAULT_PWM
        self._servo_packer = ServoPacker(sysid)
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
        s4 = throttle_to_pwm(d[3]) if len(d) > 3 else 0
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
        end = self._servo_packer.pack_into(self._tx, self._tx_mv, 0, self.mav.seq, stamp % U32,
                                           1500, 1500, 1500)
        self.mav.seq = (self.mav.seq + 1) & 0xFF
        self.sock.sendto(self._tx_mv[:end], addr)
        self.answered += 1
        return True

    def send_raw(self, data: bytes, addr) -> None:
        self.sock.sendto(data, addr)

    def servo_frame(self, stamp_us: int, pwm3, sysid: int | None = None) -> bytes:
        """Bytes of a SERVO_OUTPUT_RAW frame (optionally from another system id)."""
        mav = self.mav if sysid is None else new_codec(sysid)
        return mav.servo_output_raw_encode(stamp_us % U32, 0, pwm3[0], pwm3[1], pwm3[2],
                                           0, 0, 0, 0, 0).pack(mav)

    def close(self) -> None:
        self.sock.close()
