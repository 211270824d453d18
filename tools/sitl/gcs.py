"""The scripted ground station of the SITL harness: the main job's (tools.hil) and the
reliability rig's (tools.sitl.rig, ``record=True``, no heartbeats); tools.hil's only MAVLink
import.

A small MAVLink 2 ground station (system id 250, component 190) on its own non-blocking UDP
socket, using pymavlink's generated ``ardupilotmega`` codec (docs/architecture.md section 1).
In realtime runs it does what an operator does in MAVProxy: wait for the vehicle's heartbeat,
set the attitude command (``COMMAND_LONG MAV_CMD_USER_1``: param1..3 = alpha_c, beta_c, mu_c in
deg, NaN keeps a value; MAVProxy ``long USER_1 5 0 4``), select the flight mode, arm, and then
send each new command of the scenario's timeline when the vehicle's sim time reaches it. Every
message of the vehicle carries one time base (``time_boot_ms`` / ``time_usec``): sim time in
lockstep, the controller's time since boot in real time; the ``DEBUG_VECT`` named ``SIM_T``
(x = sim time of the vehicle's newest plant frame, s) maps that base to sim time (docs/fc.md).
In lockstep runs it only listens (the controller is armed and fed its timeline on its command
line, docs/hil.md), except with ``--flight-mode MISSION``: it uploads the mission (a QGC WPL 110
file, :func:`read_wpl`, :meth:`ScriptedGcs.upload_mission`) and selects MISSION, as an
operator would, and records the mission's progress (MISSION_CURRENT, MISSION_ITEM_REACHED). Every message it sends carries the next sequence number of its one codec
(heartbeat thread and commands share it under a lock).

It records what it receives (ATTITUDE, heartbeats) and what it sent, with the vehicle's time
stamps, so a run can be checked against the plant's truth; with ``record`` it also keeps every
message (bounded), the NAMED_VALUE_FLOAT counters and STATUSTEXTs for the rig's waits, and it
can sign (MAVLink 2 signing key).
"""
from __future__ import annotations

import itertools
import math
import os
import socket
import threading
import time
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from fc.params import wire_number

os.environ["MAVLINK20"] = "1"
from pymavlink.dialects.v20 import ardupilotmega as mavlink  # noqa: E402

GCS_SYSID = 250
GCS_COMPID = mavlink.MAV_COMP_ID_MISSIONPLANNER
VEHICLE_SYSID = 1
VEHICLE_COMPID = 1
CMD_PARAMS = ("CMD_ALPHA_DEG", "CMD_BETA_DEG", "CMD_MU_DEG")
MAV_CMD_COMPONENT_ARM_DISARM = 400
MAV_CMD_DO_SET_MODE = 176
MAV_CMD_USER_1 = mavlink.MAV_CMD_USER_1   # fc/gcs.py CMD_ATTITUDE
#: telemetry records kept (the newest; about 7 h of ATTITUDE at the fc's default 10 Hz)
RECORD_ROWS = 1 << 18
#: high-rate streams left out of ``ScriptedGcs.msgs`` (``record``)
RECORD_SKIP = ("ATTITUDE", "AOA_SSA", "VFR_HUD", "DEBUG_VECT", "SERVO_OUTPUT_RAW")


class GcsError(RuntimeError):
    """The vehicle did not do what the ground station asked within the time allowed."""


class RingRecord:
    """The newest ``capacity`` rows of ``width`` floats in fixed memory (the oldest row is
    overwritten), so an open-ended session does not grow. ``len()`` counts every row added."""

    def __init__(self, width: int, capacity: int = RECORD_ROWS):
        self.buf = np.zeros((capacity, width))
        self.count = 0

    def append(self, row) -> None:
        self.buf[self.count % len(self.buf)] = row
        self.count += 1

    def __len__(self) -> int:
        return self.count

    def array(self) -> np.ndarray:
        """The rows kept, oldest first (a copy)."""
        cap = len(self.buf)
        if self.count <= cap:
            return self.buf[:self.count].copy()
        k = self.count % cap
        return np.concatenate((self.buf[k:], self.buf[:k]))


@dataclass
class Telemetry:
    """What the ground station heard from the vehicle (filled by the receive thread; the
    records are rings of the newest RECORD_ROWS rows)."""

    #: ATTITUDE: sim time of the last AOA_SSA stamp (s), roll, pitch, yaw, p, q, r (rad, rad/s)
    att: RingRecord = field(default_factory=lambda: RingRecord(7))
    #: AOA_SSA: time_usec / 1e6 (sim time, s), AOA, SSA (deg, as on the wire)
    aoa: RingRecord = field(default_factory=lambda: RingRecord(3))
    sim_t_s: float | None = None                      # newest sim time stamp seen
    base_minus_sim_s: float | None = None             # vehicle time base - sim time (SIM_T)
    heartbeats: int = 0
    last_heartbeat: object = None
    base_mode: int = 0
    custom_mode: int = -1
    statustext: deque = field(default_factory=lambda: deque(maxlen=1000))
    param_values: dict = field(default_factory=dict)  # name -> last PARAM_VALUE value
    acks: list = field(default_factory=list)          # (command, result)
    home: tuple | None = None                         # HOME_POSITION lat, lon deg, alt m
    mission_requests: list = field(default_factory=list)   # MISSION_REQUEST(_INT) seq
    mission_acks: list = field(default_factory=list)       # MISSION_ACK type
    #: MISSION_CURRENT changes: (sim time s, seq, total, mission_state)
    mission_current: list = field(default_factory=list)
    mission_reached: list = field(default_factory=list)    # (sim time s, seq)
    bad_datagrams: int = 0

    def sim_time_s(self) -> float | None:
        return self.sim_t_s


_LINK_IDS = itertools.count()


class _ToVehicle:
    """The codec's output file: what ``mav.send`` / ``mav.*_send`` writes goes to the vehicle
    (once it has been heard), so callers can use pymavlink's generated senders directly."""

    def __init__(self, gcs: "ScriptedGcs"):
        self.gcs = gcs

    def write(self, buf: bytes) -> None:
        addr = self.gcs.vehicle_addr
        if addr is not None:
            try:
                self.gcs.sock.sendto(buf, addr)
            except OSError:
                pass


class ScriptedGcs:
    """A ground station on 127.0.0.1:``port`` (0 = any free port; see ``self.port``).

    Parameters
    ----------
    sysid, compid : its MAVLink ids (default 250/190, a Mission Planner-like GCS).
    key : MAVLink 2 signing key (32 bytes): outgoing messages are signed, incoming unsigned
        ones are refused by the codec.
    heartbeat : send a GCS HEARTBEAT every second (an operator's ground station does; the
        reliability rig's recorder does not).
    record : also keep every message received (``msgs``: (monotonic s, message), without the
        high-rate streams), the latest NAMED_VALUE_FLOAT values (``named``) and STATUSTEXTs
        (``texts``: (monotonic s, severity, text)), for ``wait`` / ``find`` / ``wait_named``.

    ``conn`` is the object itself and ``mav`` its codec, so ``gcs.conn.mav.param_set_send(...)``
    works as with a pymavlink connection.
    """

    def __init__(self, host: str = "127.0.0.1", port: int = 0, sysid: int = GCS_SYSID,
                 compid: int = GCS_COMPID, key: bytes | None = None, heartbeat: bool = True,
                 record: bool = False):
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind((host, port))
        self.sock.settimeout(0.1)
        self.port = self.sock.getsockname()[1]
        self.mav = mavlink.MAVLink(_ToVehicle(self), srcSystem=sysid, srcComponent=compid)
        self.mav.robust_parsing = True
        if key is not None:           # as pymavlink's mavutil setup_signing(key, sign_outgoing)
            self.mav.signing.secret_key = key
            self.mav.signing.sign_outgoing = True
            self.mav.signing.link_id = next(_LINK_IDS)     # one per link, as mavutil does
            self.mav.signing.timestamp = int((time.time() - 1420070400) * 100 * 1000)
        self.conn = self
        self.vehicle_addr: tuple[str, int] | None = None
        self.tel = Telemetry()
        self.sent: list[tuple[float, str, float]] = []  # (vehicle sim time s, what, value)
        self.record = record
        self.msgs: list = []            # (monotonic time, message), with ``record``
        self.named: dict[str, float] = {}
        self.texts: list[tuple[float, int, str]] = []
        self._cond = threading.Condition()
        self.cv = self._cond
        self._tx_lock = threading.Lock()
        self._stop = threading.Event()
        #: set to make every pending and later wait_for() raise GcsError at once
        self.abort = threading.Event()
        self._rx = threading.Thread(target=self._rx_loop, name="gcs-rx", daemon=True)
        self._rx.start()
        self._hb_thread = None
        if heartbeat:
            self._hb_thread = threading.Thread(target=self._hb_loop, name="gcs-hb", daemon=True)
            self._hb_thread.start()

    # ---- receive ---------------------------------------------------------------------------
    def _rx_loop(self) -> None:
        while not self._stop.is_set():
            try:
                data, addr = self.sock.recvfrom(4096)
            except socket.timeout:
                continue
            except OSError:
                if self._stop.is_set():
                    return
                continue
            try:
                msgs = self.mav.parse_buffer(data) or []
            except Exception:  # a malformed datagram never stops the ground station
                self.tel.bad_datagrams += 1
                continue
            for m in msgs:
                if m.get_type() == "BAD_DATA" or m.get_srcSystem() != VEHICLE_SYSID:
                    continue
                with self._cond:
                    self.vehicle_addr = addr
                    self._handle(m)
                    if self.record:
                        self._keep(m)
                    self._cond.notify_all()

    def _keep(self, m) -> None:
        t = m.get_type()
        now = time.monotonic()
        if t == "NAMED_VALUE_FLOAT":
            self.named[m.name] = m.value
        elif t == "STATUSTEXT":
            self.texts.append((now, m.severity, m.text))
        if t not in RECORD_SKIP:
            self.msgs.append((now, m))
            if len(self.msgs) > 20000:
                del self.msgs[:10000]

    def _handle(self, m) -> None:
        t = m.get_type()
        tel = self.tel
        if t == "ATTITUDE":
            if tel.sim_t_s is not None:
                tel.att.append((tel.sim_t_s, m.roll, m.pitch, m.yaw, m.rollspeed,
                                m.pitchspeed, m.yawspeed))
        elif t == "DEBUG_VECT" and m.name.rstrip("\x00") == "SIM_T":
            if math.isfinite(m.x):        # NaN: the vehicle has no plant frame yet
                tel.base_minus_sim_s = m.time_usec / 1e6 - m.x
        elif t == "AOA_SSA":
            if tel.base_minus_sim_s is None:
                return                    # the time base is not mapped to sim time yet
            tel.sim_t_s = m.time_usec / 1e6 - tel.base_minus_sim_s
            tel.aoa.append((tel.sim_t_s, m.AOA, m.SSA))
        elif t == "HEARTBEAT":
            tel.heartbeats += 1
            tel.base_mode = m.base_mode
            tel.custom_mode = m.custom_mode
            tel.last_heartbeat = m
        elif t == "PARAM_VALUE":
            name = m.param_id.rstrip("\x00") if isinstance(m.param_id, str) else m.param_id
            tel.param_values[name] = wire_number(m.param_value, m.param_type)
        elif t == "COMMAND_ACK":
            tel.acks.append((m.command, m.result))
        elif t == "STATUSTEXT":
            tel.statustext.append(m.text)
        elif t == "HOME_POSITION":
            tel.home = (m.latitude * 1e-7, m.longitude * 1e-7, m.altitude * 1e-3)
        elif t in ("MISSION_REQUEST_INT", "MISSION_REQUEST"):
            tel.mission_requests.append(m.seq)
        elif t == "MISSION_ACK":
            tel.mission_acks.append(m.type)
        elif t == "MISSION_CURRENT":
            row = (m.seq, m.total, m.mission_state)
            if not tel.mission_current or tel.mission_current[-1][1:] != row:
                tel.mission_current.append((_nan_if_none(tel.sim_t_s), *row))
        elif t == "MISSION_ITEM_REACHED":
            tel.mission_reached.append((_nan_if_none(tel.sim_t_s), m.seq))

    def wait_for(self, pred, timeout_s: float, what: str):
        """Wait (bounded) until ``pred(self.tel)`` is true; GcsError naming ``what`` otherwise."""
        deadline = time.monotonic() + timeout_s
        with self._cond:
            while not pred(self.tel):
                if self.abort.is_set():
                    raise GcsError(f"aborted while waiting for {what}")
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    raise GcsError(f"{what} not seen within {timeout_s:.0f} s")
                self._cond.wait(timeout=min(remaining, 0.2))

    def wait(self, pred, timeout_s: float, since: float = 0.0):
        """First recorded message after ``since`` (monotonic s) satisfying ``pred(m)``; None at
        the timeout (needs ``record``)."""
        deadline = time.monotonic() + timeout_s
        with self._cond:
            while True:
                for t, m in self.msgs:
                    if t >= since and pred(m):
                        return m
                left = deadline - time.monotonic()
                if left <= 0:
                    return None
                self._cond.wait(min(left, 0.2))

    def find(self, pred, since: float = 0.0, until: float = math.inf):
        """First recorded message received in [since, until] satisfying ``pred`` (no wait)."""
        with self._cond:
            for t, m in self.msgs:
                if since <= t <= until and pred(m):
                    return m
        return None

    def wait_text(self, needle: str, timeout_s: float, since: float = 0.0) -> str | None:
        m = self.wait(lambda m: m.get_type() == "STATUSTEXT" and needle in m.text, timeout_s,
                      since)
        return None if m is None else m.text

    def wait_named(self, name: str, pred, timeout_s: float) -> float | None:
        """Wait until NAMED_VALUE_FLOAT ``name`` satisfies ``pred(value)``; returns the value."""
        deadline = time.monotonic() + timeout_s
        with self._cond:
            while True:
                v = self.named.get(name)
                if v is not None and pred(v):
                    return v
                left = deadline - time.monotonic()
                if left <= 0:
                    return None
                self._cond.wait(min(left, 0.2))

    def heartbeat_mode(self, timeout_s: float = 3.0, since: float = 0.0):
        """custom_mode of the vehicle's first HEARTBEAT after ``since``; None at the timeout."""
        m = self.wait(lambda m: m.get_type() == "HEARTBEAT" and m.get_srcSystem() == 1,
                      timeout_s, since)
        return None if m is None else m.custom_mode

    # ---- send ------------------------------------------------------------------------------
    def _send(self, msg) -> None:
        if self.vehicle_addr is None:
            return
        with self._tx_lock:            # one codec, one sequence: heartbeat thread and commands
            buf = msg.pack(self.mav)
            self.mav.seq = (self.mav.seq + 1) & 0xFF
            try:
                self.sock.sendto(buf, self.vehicle_addr)
            except OSError:
                pass

    def _hb_loop(self) -> None:
        while not self._stop.wait(1.0):
            self._send(mavlink.MAVLink_heartbeat_message(
                mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0,
                mavlink.MAV_STATE_ACTIVE, 3))

    def _record(self, what: str, value: float) -> None:
        t = self.tel.sim_time_s()
        self.sent.append((math.nan if t is None else t, what, float(value)))

    def set_param(self, name: str, value: float, timeout_s: float = 5.0) -> None:
        """PARAM_SET with retries (as MAVProxy: up to 3 tries, 1 s apart) until echoed."""
        pid = name.encode()
        for _ in range(3):
            with self._cond:
                self.tel.param_values.pop(name, None)
            self._send(mavlink.MAVLink_param_set_message(
                VEHICLE_SYSID, VEHICLE_COMPID, pid, float(value), mavlink.MAV_PARAM_TYPE_REAL32))
            try:
                self.wait_for(lambda tel: name in tel.param_values, min(1.0, timeout_s),
                              f"PARAM_VALUE {name}")
            except GcsError:
                continue
            got = self.tel.param_values[name]
            if abs(got - value) > 1e-5 * max(1.0, abs(value)):
                raise GcsError(f"vehicle refused {name} = {value} (kept {got})")
            self._record(name, value)
            return
        raise GcsError(f"no PARAM_VALUE for {name} after 3 tries")

    def command_long(self, command: int, *params: float, timeout_s: float = 3.0) -> int:
        """COMMAND_LONG with up to 3 tries; returns the COMMAND_ACK result."""
        p = list(params) + [0.0] * (7 - len(params))
        for confirmation in range(3):
            n0 = len(self.tel.acks)
            self._send(mavlink.MAVLink_command_long_message(
                VEHICLE_SYSID, VEHICLE_COMPID, command, confirmation, *p))
            try:
                self.wait_for(lambda tel: any(c == command for c, _ in tel.acks[n0:]),
                              timeout_s / 3, f"COMMAND_ACK for command {command}")
            except GcsError:
                continue
            result = next(r for c, r in self.tel.acks[n0:] if c == command)
            self._record(f"COMMAND_{command}", result)
            return result
        raise GcsError(f"no COMMAND_ACK for command {command}")

    def command(self, command: int, *params: float, timeout_s: float = 5.0):
        """One COMMAND_LONG (no retry); the COMMAND_ACK message, None at the timeout (needs
        ``record``)."""
        p = list(params) + [0.0] * (7 - len(params))
        since = time.monotonic()
        self.mav.command_long_send(VEHICLE_SYSID, VEHICLE_COMPID, command, 0, *p)
        return self.wait(lambda m: m.get_type() == "COMMAND_ACK" and m.command == command,
                         timeout_s, since)

    def arm(self, timeout_s: float = 15.0) -> None:
        """Arm; a refusal (e.g. the vehicle has no valid plant data yet) is retried, as an
        operator would, each time new telemetry arrives, until ``timeout_s``."""
        deadline = time.monotonic() + timeout_s
        while True:
            r = self.command_long(MAV_CMD_COMPONENT_ARM_DISARM, 1.0)
            if r == mavlink.MAV_RESULT_ACCEPTED:
                return
            if r != mavlink.MAV_RESULT_DENIED or time.monotonic() > deadline:
                texts = "; ".join(list(self.tel.statustext)[-3:])
                raise GcsError(f"arming refused (MAV_RESULT {r}){': ' + texts if texts else ''}")
            n = len(self.tel.aoa)
            self.wait_for(lambda tel: len(tel.aoa) > n, 5.0, "telemetry after a refused arm")

    def set_mode(self, custom_mode: int) -> None:
        r = self.command_long(MAV_CMD_DO_SET_MODE,
                              float(mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED), float(custom_mode))
        if r != mavlink.MAV_RESULT_ACCEPTED:
            raise GcsError(f"mode {custom_mode} refused (MAV_RESULT {r})")

    def set_command_deg(self, alpha_deg: float = math.nan, beta_deg: float = math.nan,
                        mu_deg: float = math.nan) -> None:
        """Attitude command in deg (NaN keeps the current value), confirmed by COMMAND_ACK."""
        r = self.command_long(MAV_CMD_USER_1, alpha_deg, beta_deg, mu_deg)
        if r != mavlink.MAV_RESULT_ACCEPTED:
            raise GcsError(f"attitude command refused (MAV_RESULT {r})")
        for what, v in zip(("alpha_deg", "beta_deg", "mu_deg"), (alpha_deg, beta_deg, mu_deg)):
            if math.isfinite(v):
                self._record(what, v)

    def upload_mission(self, items: list[dict], timeout_s: float = 20.0) -> None:
        """Upload ``items`` (:func:`read_wpl`) with the mission protocol: MISSION_COUNT, then
        each MISSION_REQUEST(_INT) answered with its MISSION_ITEM_INT, until MISSION_ACK. The
        COUNT is sent again if no request comes within 2 s (3 tries). GcsError unless
        ACCEPTED."""
        deadline = time.monotonic() + timeout_s
        for _ in range(3):
            with self._cond:
                n_req, n_ack = len(self.tel.mission_requests), len(self.tel.mission_acks)
            self._send(mavlink.MAVLink_mission_count_message(
                VEHICLE_SYSID, VEHICLE_COMPID, len(items), mavlink.MAV_MISSION_TYPE_MISSION))
            try:
                self.wait_for(lambda tel: len(tel.mission_requests) > n_req
                              or len(tel.mission_acks) > n_ack, 2.0, "MISSION_REQUEST")
                break
            except GcsError:
                continue
        else:
            raise GcsError("no MISSION_REQUEST after 3 MISSION_COUNTs")
        while True:
            with self._cond:
                if len(self.tel.mission_acks) > n_ack:
                    result = self.tel.mission_acks[n_ack]
                    break
                todo = self.tel.mission_requests[n_req:]
                n_req = len(self.tel.mission_requests)
            for seq in todo:
                if 0 <= seq < len(items):
                    it = items[seq]
                    self._send(mavlink.MAVLink_mission_item_int_message(
                        VEHICLE_SYSID, VEHICLE_COMPID, seq, it["frame"], it["command"], 0,
                        it["autocontinue"], it["param1"], it["param2"], it["param3"],
                        it["param4"], it["x"], it["y"], it["z"],
                        mavlink.MAV_MISSION_TYPE_MISSION))
            left = deadline - time.monotonic()
            if left <= 0:
                raise GcsError("mission upload: no MISSION_ACK")
            self.wait_for(lambda tel: len(tel.mission_requests) > n_req
                          or len(tel.mission_acks) > n_ack, left, "MISSION_REQUEST or MISSION_ACK")
        if result != mavlink.MAV_MISSION_ACCEPTED:
            raise GcsError(f"mission refused (MAV_MISSION_RESULT {result})")
        self._record("mission_items", len(items))

    # ---- records ---------------------------------------------------------------------------
    def telemetry_arrays(self) -> dict:
        """ATTITUDE (stamped with the newest AOA_SSA sim time) and AOA_SSA records (the newest
        RECORD_ROWS of each)."""
        with self._cond:
            a = self.tel.att.array()
            aa = self.tel.aoa.array()
        return {"t_s": a[:, 0], "roll_rad": a[:, 1], "pitch_rad": a[:, 2], "yaw_rad": a[:, 3],
                "p_rad_s": a[:, 4], "q_rad_s": a[:, 5], "r_rad_s": a[:, 6],
                "aoa_t_s": aa[:, 0], "aoa_deg": aa[:, 1], "ssa_deg": aa[:, 2]}

    def close(self) -> None:
        self._stop.set()
        self._rx.join(timeout=2.0)
        if self._hb_thread is not None:
            self._hb_thread.join(timeout=2.0)
        self.sock.close()


def _nan_if_none(x):
    return math.nan if x is None else x


def read_wpl(path) -> list[dict]:
    """The items of a QGC WPL 110 file (MAVProxy ``wp save``/``wp load``, QGroundControl's
    plain-text missions): one tab-separated line per item, ``seq current frame command p1 p2
    p3 p4 lat lon alt autocontinue``. Returns MISSION_ITEM_INT fields (x, y in degE7).
    ValueError on a malformed file."""
    with open(path) as f:
        lines = [ln.strip() for ln in f if ln.strip() and not ln.startswith("#")]
    if not lines or not lines[0].startswith("QGC WPL 110"):
        raise ValueError(f"{path}: not a QGC WPL 110 file")
    items = []
    for k, ln in enumerate(lines[1:]):
        a = ln.split()
        if len(a) != 12 or int(a[0]) != k:
            raise ValueError(f"{path}: item line {k + 1}: expected 12 fields, seq {k}")
        items.append({"frame": int(a[2]), "command": int(a[3]), "param1": float(a[4]),
                      "param2": float(a[5]), "param3": float(a[6]), "param4": float(a[7]),
                      "x": int(round(float(a[8]) * 1e7)), "y": int(round(float(a[9]) * 1e7)),
                      "z": float(a[10]), "autocontinue": int(a[11])})
    return items
