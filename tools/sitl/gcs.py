"""The one scripted ground station of the SITL harness: the main job's (tools.hil, with
heartbeats), the reliability rig's (tools.sitl.rig) and the HIL tests' (tests/); tools.hil's
only MAVLink import.

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
operator would, and records the mission's progress (MISSION_CURRENT, MISSION_ITEM_REACHED).
Every message it sends carries the next sequence number of its one codec (heartbeat thread
and commands share it under a lock).

It records what it receives (ATTITUDE, AOA_SSA, heartbeats, mission progress) and what it
sent, with the vehicle's time stamps, so a run can be checked against the plant's truth, and
logs every message (bounded) for the waits of the rig and the tests: the next message of a
type, a command's COMMAND_ACK, a parameter's PARAM_VALUE, the mission protocol, STATUSTEXTs
and NAMED_VALUE_FLOAT counters. It can sign (MAVLink 2 signing key, changeable at any time).
"""
from __future__ import annotations

import bisect
import functools
import itertools
import math
import os
import socket
import threading
import time
from collections import deque
from dataclasses import dataclass, field

import numpy as np

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
#: high-rate streams left out of the message log unless ``record`` (they fill ``Telemetry``)
RECORD_SKIP = ("ATTITUDE", "AOA_SSA", "VFR_HUD", "DEBUG_VECT", "SERVO_OUTPUT_RAW")
#: messages the log keeps at least (the newest; it drops this many when it holds twice as many)
LOG_KEEP = 10000


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
    (once it has been heard, or to ``vehicle`` before), so callers can use pymavlink's generated senders directly."""

    def __init__(self, gcs: "ScriptedGcs"):
        self.gcs = gcs

    def write(self, buf: bytes) -> None:
        addr = self.gcs.vehicle_addr
        if addr is not None:
            try:
                self.gcs.sock.sendto(buf, addr)
            except OSError:
                pass


@functools.cache
def _codec_class(dialect):
    """The station's codec class over ``dialect`` (a pymavlink v20 dialect module): every
    message it sends, from any thread and whether through ``send`` or a generated ``*_send``,
    is packed, numbered and written under one lock."""

    class Codec(dialect.MAVLink):
        def __init__(self, out, lock: threading.Lock, **ids):
            super().__init__(out, **ids)
            self._lock = lock

        def send(self, mavmsg, force_mavlink1: bool = False) -> None:
            with self._lock:
                super().send(mavmsg, force_mavlink1=force_mavlink1)

    return Codec


def _matcher(match, cond):
    """``match`` (a message type, a list of types or a predicate on the message) and ``cond``
    (None or a predicate) as one predicate."""
    if callable(match):
        first = match
    else:
        types = (match,) if isinstance(match, str) else tuple(match)
        first = lambda m: m.get_type() in types  # noqa: E731
    return first if cond is None else (lambda m: first(m) and cond(m))


class ScriptedGcs:
    """The scripted ground station on 127.0.0.1:``port`` (0 = any free port; see ``self.port``):
    the main job's, the reliability rig's and the tests'.

    Parameters
    ----------
    sysid, compid : its MAVLink ids (default 250/190, a Mission Planner-like GCS).
    key : MAVLink 2 signing key (32 bytes), see :meth:`setup_signing`.
    heartbeat : send a GCS HEARTBEAT every second, as an operator's ground station does (the
        main job); the rig and the tests do not, so the vehicle hears only what they send.
    record : keep every message received in the log, the high-rate streams (RECORD_SKIP)
        included; without it those go only to the telemetry rings (``tel``).
    vehicle : (host, port) to send to before the vehicle has been heard: a peer ground
        station talking to the fc's ``--gcs-bind`` port (default None: listen where the fc
        sends, a ``--gcs`` output, and answer whoever the vehicle's messages come from).
    dialect : the pymavlink v20 dialect of the codec (default ``ardupilotmega``; e.g.
        ``development`` for the standard-modes messages AVAILABLE_MODES and CURRENT_MODE).
    log_keep : messages the log keeps at least (default LOG_KEEP; it holds up to twice as
        many, each a pymavlink message object of about 0.5-1 KB).

    Every message the vehicle (system 1) sends is logged in arrival order with its monotonic
    receive time (the newest ``log_keep`` at least). :meth:`wait` reads the log either as a
    stream (the next unread message, as pymavlink's ``recv_match``) or from a receive time
    (``since``), :meth:`messages` lists a receive-time window; :meth:`command`,
    :meth:`param_get`, :meth:`param_set`, :meth:`send_mission` and :meth:`download_mission`
    wait for the answer to what they sent, received after the send (the operator's
    ``set_param``, ``arm``, ``set_mode``, ``set_command_deg``, ``upload_mission`` are built on
    them). ``named`` holds the latest NAMED_VALUE_FLOAT values and ``texts`` the STATUSTEXTs
    ((monotonic s, severity, text)).

    ``mav`` is its codec (``gcs.mav.param_set_send(...)`` goes to the vehicle once it has been
    heard) and ``conn`` the object itself, as with a pymavlink connection.
    """

    def __init__(self, host: str = "127.0.0.1", port: int = 0, sysid: int = GCS_SYSID,
                 compid: int = GCS_COMPID, key: bytes | None = None, heartbeat: bool = False,
                 record: bool = True, vehicle: tuple[str, int] | None = None,
                 dialect=mavlink, log_keep: int = LOG_KEEP):
        if log_keep < 1:
            raise ValueError(f"log_keep must be >= 1, not {log_keep}")
        self.log_keep = log_keep
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind((host, port))
        self.sock.settimeout(0.1)
        self.port = self.sock.getsockname()[1]
        self.mav = _codec_class(dialect)(_ToVehicle(self), threading.Lock(), srcSystem=sysid,
                                         srcComponent=compid)
        self.mav.robust_parsing = True
        if key is not None:
            self.setup_signing(key)
        self.conn = self
        self.vehicle_addr: tuple[str, int] | None = vehicle
        self.tel = Telemetry()
        self.sent: list[tuple[float, str, float]] = []  # (vehicle sim time s, what, value)
        self.record = record
        self._log: list[tuple[float, object]] = []      # (monotonic receive time s, message)
        self._log_base = 0                               # log index of _log[0]
        self._cursor = 0                                 # log index of the next unread message
        self.named: dict[str, float] = {}
        self.texts: list[tuple[float, int, str]] = []
        self._cond = threading.Condition()
        self.cv = self._cond
        self._stop = threading.Event()
        #: set to make every pending and later wait_for() raise GcsError at once
        self.abort = threading.Event()
        self._rx = threading.Thread(target=self._rx_loop, name="gcs-rx", daemon=True)
        self._rx.start()
        self._hb_thread = None
        if heartbeat:
            self._hb_thread = threading.Thread(target=self._hb_loop, name="gcs-hb", daemon=True)
            self._hb_thread.start()

    def setup_signing(self, key: bytes, sign_outgoing: bool = True) -> None:
        """MAVLink 2 signing with ``key`` (32 bytes), as pymavlink's ``mavutil`` does it: the
        codec then refuses unsigned and wrongly signed incoming messages, and signs what it
        sends if ``sign_outgoing``. Callable again at any time (a new key, a new link id)."""
        s = self.mav.signing
        s.secret_key = key
        s.sign_outgoing = sign_outgoing
        s.link_id = next(_LINK_IDS) & 0xFF            # one per link, as mavutil does
        s.timestamp = int((time.time() - 1420070400) * 100 * 1000)

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
                    self._keep(m)
                    self._cond.notify_all()

    def _keep(self, m) -> None:
        t = m.get_type()
        now = time.monotonic()
        if t == "NAMED_VALUE_FLOAT":
            self.named[m.name] = m.value
        elif t == "STATUSTEXT":
            self.texts.append((now, m.severity, m.text))
        if self.record or t not in RECORD_SKIP:
            self._log.append((now, m))
            if len(self._log) > 2 * self.log_keep:
                del self._log[:self.log_keep]
                self._log_base += self.log_keep

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

    # ---- waits -----------------------------------------------------------------------------
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

    def _end(self) -> int:
        """The log index the next message received will get."""
        with self._cond:
            return self._log_base + len(self._log)

    def _index_at(self, since: float) -> int:
        """The log index of the first message kept that was received at or after ``since``."""
        k = bisect.bisect_left(self._log, since, key=lambda row: row[0])
        return self._log_base + k

    def _scan(self, start: int, pred, timeout_s: float, until: float = math.inf):
        """(log index, message) of the first message at log index >= ``start`` received by
        ``until`` (monotonic s) satisfying ``pred``, waiting up to ``timeout_s`` for it to
        arrive; None at the timeout."""
        deadline = time.monotonic() + timeout_s
        i = start
        with self._cond:
            while True:
                i = max(i, self._log_base)
                while i < self._log_base + len(self._log):
                    t, m = self._log[i - self._log_base]
                    if t > until:
                        return None
                    if pred(m):
                        return i, m
                    i += 1
                left = deadline - time.monotonic()
                if left <= 0:
                    return None
                self._cond.wait(min(left, 0.2))

    def _take(self, hit):
        """The message of a ``_scan`` hit, marking it and what came before it read."""
        if hit is None:
            return None
        self._cursor = max(self._cursor, hit[0] + 1)
        return hit[1]

    def wait(self, match, timeout_s: float = 10.0, since: float | None = None, *, cond=None):
        """The first message matching ``match`` (a type such as ``"HEARTBEAT"``, a list of
        types, or a predicate on the message) and ``cond`` (a predicate, optional); None at the
        timeout (s; 0 looks once).

        Without ``since`` the log is read as a stream: the search starts at the first unread
        message and the message returned, and every one before it, count as read (``drain``
        marks all read). With ``since`` (monotonic s) it starts at the first message received
        at or after that time and marks nothing read."""
        if callable(since):
            raise TypeError("wait(): the third argument is ``since`` (monotonic s); pass a "
                            "predicate as cond=")
        pred = _matcher(match, cond)
        if since is None:
            return self._take(self._scan(self._cursor, pred, timeout_s))
        with self._cond:
            start = self._index_at(since)
        hit = self._scan(start, pred, timeout_s)
        return None if hit is None else hit[1]

    def drain(self) -> None:
        """Mark every message received so far read (the next stream ``wait`` sees only later
        ones)."""
        self._cursor = self._end()

    def find(self, pred, since: float = 0.0, until: float = math.inf):
        """First message received in [since, until] (monotonic s) satisfying ``pred``, without
        waiting; None if there is none."""
        with self._cond:
            start = self._index_at(since)
        hit = self._scan(start, pred, 0.0, until)
        return None if hit is None else hit[1]

    def messages(self, match, since: float = 0.0, until: float = math.inf, *,
                 cond=None) -> list:
        """Every message kept that was received in [since, until] (monotonic s) and matches
        ``match`` and ``cond`` (as :meth:`wait`), oldest first, without waiting."""
        pred, out = _matcher(match, cond), []
        with self._cond:
            i = self._index_at(since)
            while (hit := self._scan(i, pred, 0.0, until)) is not None:
                out.append(hit[1])
                i = hit[0] + 1
        return out

    def wait_text(self, needle: str, timeout_s: float, since: float = 0.0) -> str | None:
        """The first STATUSTEXT containing ``needle`` received since ``since``; None at the
        timeout."""
        m = self.wait("STATUSTEXT", timeout_s, since, cond=lambda m: needle in m.text)
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
        m = self.wait("HEARTBEAT", timeout_s, since)
        return None if m is None else m.custom_mode

    # ---- send ------------------------------------------------------------------------------
    def _reply(self, send, match, cond, timeout_s: float):
        """Call ``send()`` and return the first message matching ``match`` and ``cond``
        received after it (marked read, as a stream ``wait`` would); None at the timeout."""
        start = self._end()
        send()
        return self._take(self._scan(start, _matcher(match, cond), timeout_s))

    def _hb_loop(self) -> None:
        while not self._stop.wait(1.0):
            if self.vehicle_addr is None:
                continue                  # nobody to send to yet (no sequence number used)
            self.mav.heartbeat_send(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0,
                                    mavlink.MAV_STATE_ACTIVE)

    def _record(self, what: str, value: float) -> None:
        t = self.tel.sim_time_s()
        self.sent.append((math.nan if t is None else t, what, float(value)))

    def command(self, command: int, *params: float, timeout_s: float = 5.0, tries: int = 1,
                target_system: int = VEHICLE_SYSID):
        """COMMAND_LONG (params 1..7, missing ones 0) to the vehicle, sent up to ``tries``
        times (confirmation 0, 1, ...; ``timeout_s / tries`` apart, as MAVProxy retries) until
        a COMMAND_ACK for it arrives; that COMMAND_ACK, None at the timeout."""
        p = list(params) + [0.0] * (7 - len(params))
        for confirmation in range(tries):
            ack = self._reply(lambda: self.mav.command_long_send(
                target_system, VEHICLE_COMPID, command, confirmation, *p),
                "COMMAND_ACK", lambda m: m.command == command, timeout_s / tries)
            if ack is not None:
                return ack
        return None

    def _command_result(self, what: str, command: int, *params: float) -> int:
        """``command`` as the scripted operator sends it (3 tries in 3 s); its MAV_RESULT,
        recorded in ``sent``. GcsError naming ``what`` if no COMMAND_ACK comes."""
        ack = self.command(command, *params, timeout_s=3.0, tries=3)
        if ack is None:
            raise GcsError(f"no COMMAND_ACK for {what} (command {command})")
        self._record(f"COMMAND_{command}", ack.result)
        return ack.result

    def _refused(self, what: str, result: int) -> GcsError:
        texts = "; ".join(list(self.tel.statustext)[-3:])
        return GcsError(f"{what} refused (MAV_RESULT {result}){': ' + texts if texts else ''}")

    def param_get(self, name: str, timeout_s: float = 5.0):
        """PARAM_REQUEST_READ of ``name``; the PARAM_VALUE answering it, None at the timeout."""
        return self._reply(lambda: self.mav.param_request_read_send(
            VEHICLE_SYSID, VEHICLE_COMPID, name.encode(), -1),
            "PARAM_VALUE", lambda m: m.param_id == name, timeout_s)

    def param_set(self, name: str, value: float, timeout_s: float = 5.0):
        """One PARAM_SET of ``name`` (REAL32); the PARAM_VALUE echo (the value the vehicle
        kept, which a refused set leaves unchanged), None at the timeout."""
        return self._reply(lambda: self.mav.param_set_send(
            VEHICLE_SYSID, VEHICLE_COMPID, name.encode(), float(value),
            mavlink.MAV_PARAM_TYPE_REAL32),
            "PARAM_VALUE", lambda m: m.param_id == name, timeout_s)

    def set_param(self, name: str, value: float, timeout_s: float = 5.0) -> None:
        """PARAM_SET with retries (as MAVProxy: up to 3 tries, 1 s apart) until echoed;
        GcsError if never echoed or echoed with another value."""
        for _ in range(3):
            m = self.param_set(name, value, min(1.0, timeout_s))
            if m is None:
                continue
            from fc.params import wire_number   # (here: the runner does not load the table)
            got = wire_number(m.param_value, m.param_type)
            if abs(got - value) > 1e-5 * max(1.0, abs(value)):
                raise GcsError(f"vehicle refused {name} = {value} (kept {got})")
            self._record(name, value)
            return
        raise GcsError(f"no PARAM_VALUE for {name} after 3 tries")

    def arm(self, timeout_s: float = 15.0) -> None:
        """Arm; a refusal (e.g. the vehicle has no valid plant data yet) is retried, as an
        operator would, each time new telemetry arrives, until ``timeout_s``."""
        deadline = time.monotonic() + timeout_s
        while True:
            r = self._command_result("arming", MAV_CMD_COMPONENT_ARM_DISARM, 1.0)
            if r == mavlink.MAV_RESULT_ACCEPTED:
                return
            if r != mavlink.MAV_RESULT_DENIED or time.monotonic() > deadline:
                raise self._refused("arming", r)
            n = len(self.tel.aoa)
            self.wait_for(lambda tel: len(tel.aoa) > n, 5.0, "telemetry after a refused arm")

    def set_mode(self, custom_mode: int) -> None:
        """Select the flight mode ``custom_mode`` (DO_SET_MODE); GcsError unless ACCEPTED."""
        r = self._command_result(f"mode {custom_mode}", MAV_CMD_DO_SET_MODE,
                                 float(mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED),
                                 float(custom_mode))
        if r != mavlink.MAV_RESULT_ACCEPTED:
            raise self._refused(f"mode {custom_mode}", r)

    def set_command_deg(self, alpha_deg: float = math.nan, beta_deg: float = math.nan,
                        mu_deg: float = math.nan) -> None:
        """Attitude command in deg (NaN keeps the current value), confirmed by COMMAND_ACK."""
        r = self._command_result("attitude command", MAV_CMD_USER_1, alpha_deg, beta_deg,
                                 mu_deg)
        if r != mavlink.MAV_RESULT_ACCEPTED:
            raise self._refused("attitude command", r)
        for what, v in zip(("alpha_deg", "beta_deg", "mu_deg"), (alpha_deg, beta_deg, mu_deg)):
            if math.isfinite(v):
                self._record(what, v)

    # ---- mission protocol ------------------------------------------------------------------
    def send_mission(self, items: list[dict], timeout_s: float = 20.0, skip: int | None = None):
        """The mission protocol's upload of ``items`` (:func:`read_wpl`): MISSION_COUNT (sent
        again if neither a request nor an ACK comes within 2 s, 3 tries), then each
        MISSION_REQUEST(_INT) answered with its MISSION_ITEM_INT (never item ``skip``: a lost
        item, for tests), until MISSION_ACK or ``timeout_s``. Returns (the MISSION_ACK or
        None, the item numbers the vehicle asked for, in order)."""
        deadline = time.monotonic() + timeout_s
        asking = ("MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK")
        m = None
        for _ in range(3):
            m = self._reply(lambda: self.mav.mission_count_send(
                VEHICLE_SYSID, VEHICLE_COMPID, len(items), mavlink.MAV_MISSION_TYPE_MISSION),
                asking, None, min(2.0, max(0.0, deadline - time.monotonic())))
            if m is not None or time.monotonic() >= deadline:
                break
        asked: list[int] = []
        while m is not None and m.get_type() != "MISSION_ACK":
            asked.append(m.seq)
            if m.seq != skip and 0 <= m.seq < len(items):
                it = items[m.seq]
                self.mav.mission_item_int_send(
                    VEHICLE_SYSID, VEHICLE_COMPID, m.seq, it["frame"], it["command"], 0,
                    it["autocontinue"], it["param1"], it["param2"], it["param3"], it["param4"],
                    it["x"], it["y"], it["z"], mavlink.MAV_MISSION_TYPE_MISSION)
            m = self.wait(asking, max(0.0, deadline - time.monotonic()))
        return m, asked

    def upload_mission(self, items: list[dict], timeout_s: float = 20.0) -> None:
        """:meth:`send_mission`, as the scripted operator does it: GcsError unless the vehicle
        ACCEPTED the mission."""
        ack, _ = self.send_mission(items, timeout_s)
        if ack is None:
            raise GcsError("mission upload: no MISSION_ACK")
        if ack.type != mavlink.MAV_MISSION_ACCEPTED:
            raise GcsError(f"mission refused (MAV_MISSION_RESULT {ack.type})")
        self._record("mission_items", len(items))

    def download_mission(self, timeout_s: float = 5.0) -> list | None:
        """The vehicle's mission (MISSION_REQUEST_LIST, then MISSION_REQUEST_INT per item,
        then MISSION_ACK): its MISSION_ITEM_INT messages, None if an answer did not come
        within ``timeout_s`` (each)."""
        count = self._reply(lambda: self.mav.mission_request_list_send(
            VEHICLE_SYSID, VEHICLE_COMPID, mavlink.MAV_MISSION_TYPE_MISSION),
            "MISSION_COUNT", None, timeout_s)
        if count is None:
            return None
        got = []
        for seq in range(count.count):
            item = self._reply(lambda s=seq: self.mav.mission_request_int_send(
                VEHICLE_SYSID, VEHICLE_COMPID, s, mavlink.MAV_MISSION_TYPE_MISSION),
                "MISSION_ITEM_INT", lambda m, s=seq: m.seq == s, timeout_s)
            if item is None:
                return None
            got.append(item)
        self.mav.mission_ack_send(VEHICLE_SYSID, VEHICLE_COMPID, mavlink.MAV_MISSION_ACCEPTED,
                                  mavlink.MAV_MISSION_TYPE_MISSION)
        return got

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
