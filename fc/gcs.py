"""fc/gcs.py - the ground-station link: heartbeat, telemetry streams, parameters, commands.

Speaks MAVLink 2 (codec from fc/link.py) on one non-blocking UDP socket bound to
``--gcs-bind`` (default 127.0.0.1:14555), sending to every ``--gcs`` output (default
127.0.0.1:14550) and to every peer that has sent us a valid message (so a ground station
may also connect *to* the bind port). The wire contract (which message, field, unit,
direction) is in docs/fc.md. As a PX4/ArduPilot SITL session:

- modes travel with PX4's custom_mode layout and our numbers (fc/modes.py ``MODE_WIRE``),
  named by AVAILABLE_MODES / CURRENT_MODE (the MAVLink standard modes);
- stream rates are per link: a peer that asks gets its own schedule (``_Streams``) and loses
  it when it is forgotten after PEER_TIMEOUT_S of silence; the outputs keep the defaults;
- STATUSTEXT and this link's fc.log warnings are rate-limited and de-duplicated
  (fc/ratelimit.py), long texts chunked;
- integer parameters are INT32, bytewise (fc/params.py ``encode_value``); a refused set is
  answered at once with PARAM_ERROR and the unchanged PARAM_VALUE.
- the protocol services are modules of their own, each with its state (docs/fc.md section
  7a): TIMESYNC (fc/gcs_timesync.py), log download (fc/gcs_logs.py), read-only FTP
  (fc/gcs_ftp.py); this link dispatches their requests and sends their answers to the
  requester only (``_service_out``), paced within ``max_tx``; fc/gcs_streams.py holds the
  field rules of the streamed state (landed state, speeds that do not fit a field).

Work per call is bounded (``poll`` reads at most ``max_rx`` datagrams, ``service`` sends
at most ``max_tx`` messages), so a flood of ground-station traffic cannot stall the control
loop, and a ground station that goes away never affects control: sends are fire-and-forget.

The vehicle (fc/app.py) is reached through a typed interface, fc/vehicle_view.py
``VehicleView``: exactly the members read and called here.
"""
from __future__ import annotations

import math
import os
import queue
import struct
import time
from collections import deque

import numpy as np

from fc import gcs_frames as GF
from fc.control.carrays import ArrayAddress, address_of
from fc.frame_calls import FAST_IO, HOT_FRAMES, int64_at
from fc.link import (G_ALT_M, G_FIX, G_HACC_M, G_LAT_DEG, G_LON_DEG, G_SACC_M_S, G_SATS,
                     G_N, G_T_S, G_VACC_M, G_VD, G_VE, G_VN, M_AIRSPEED, M_HEADING, M_N, LeanFramer,
                     UdpEndpoint, decode_datagram, mavlink, mavlink_dev, new_codec)
from fc.gcs_ftp import FtpService
from fc.gcs_logs import MSG_IDS as LOG_MSGS, LogService
from fc.gcs_streams import cm_s_i16, cm_s_u16, landed_state, local_ned
from fc.gcs_timesync import answer as timesync_answer
from fc.mission import MSG_IDS as MISSION_MSGS, encode as mission_encode
from fc.modes import (FORCE_DISARM, MODE_OF_STANDARD, STANDARD_MODE, FlightMode, custom_mode_of,
                      decode_mode_request)
from fc.params import PROCESS_DRIVEN, decode_set_value, encode_value
from fc.ratelimit import RateLimiter
from fc.signing import SigningGuard, clock_timestamp
from fc.storage import AppendFile, DiskHealth
from fc.vehicle_view import VehicleView

__all__ = ["GcsLink", "STREAM_DEFAULTS_S", "UNSIGNED_ALLOWED", "CMD_ATTITUDE"]

ML = mavlink
MD = mavlink_dev
#: MAV_CMD_USER_1: set the attitude command (param1 alpha_c, param2 beta_c, param3 mu_c, deg;
#: NaN keeps the current value). MAVProxy: ``long USER_1 5 0 4``.
CMD_ATTITUDE = ML.MAV_CMD_USER_1

#: Default stream intervals [s] by message id (changed with SET_MESSAGE_INTERVAL /
#: REQUEST_DATA_STREAM). HEARTBEAT is always 1 Hz.
STREAM_DEFAULTS_S = {
    ML.MAVLINK_MSG_ID_SYS_STATUS: 1.0,
    ML.MAVLINK_MSG_ID_ATTITUDE: 0.1,
    ML.MAVLINK_MSG_ID_AOA_SSA: 0.1,
    ML.MAVLINK_MSG_ID_VFR_HUD: 0.25,
    ML.MAVLINK_MSG_ID_SERVO_OUTPUT_RAW: 0.1,
    ML.MAVLINK_MSG_ID_DEBUG_VECT: 0.1,          # each of CMD_DEG, EST_DEG, DELTA_DEG
    ML.MAVLINK_MSG_ID_NAMED_VALUE_FLOAT: 1.0,   # each named value once per interval
    MD.MAVLINK_MSG_ID_CURRENT_MODE: 2.0,        # standard modes: 0.5 Hz, and on every change
    ML.MAVLINK_MSG_ID_SYSTEM_TIME: 1.0,
    ML.MAVLINK_MSG_ID_GPS_RAW_INT: 0.2,
    ML.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: 0.1,  # from the first GNSS fix on
    ML.MAVLINK_MSG_ID_LOCAL_POSITION_NED: 0.1,   # from the first GNSS fix on (true velocity)
    ML.MAVLINK_MSG_ID_EXTENDED_SYS_STATE: 1.0,   # landed state (fc/gcs_streams.py)
    ML.MAVLINK_MSG_ID_HOME_POSITION: 5.0,        # from the first GNSS fix on
    ML.MAVLINK_MSG_ID_NAV_CONTROLLER_OUTPUT: 0.25,  # in the guidance modes only
    ML.MAVLINK_MSG_ID_MISSION_CURRENT: 1.0,      # and on every change (fc/mission.py)
}
#: The stream schedules' message ids, in the order a schedule is walked (every ``_Streams``
#: holds exactly these keys; a rate request for another id is refused)
STREAM_IDS = tuple(STREAM_DEFAULTS_S)
#: The streamed messages framed by compiled kernels from the vehicle's state arrays
#: (fc/gcs_frames.py; the same bytes as the codec's): no Python object per message. The rest
#: are built as the codec's message objects (``_build``).
FAST_STREAMS = frozenset({ML.MAVLINK_MSG_ID_ATTITUDE, ML.MAVLINK_MSG_ID_AOA_SSA,
                          ML.MAVLINK_MSG_ID_VFR_HUD, ML.MAVLINK_MSG_ID_SERVO_OUTPUT_RAW,
                          ML.MAVLINK_MSG_ID_DEBUG_VECT, ML.MAVLINK_MSG_ID_NAMED_VALUE_FLOAT,
                          ML.MAVLINK_MSG_ID_GPS_RAW_INT, ML.MAVLINK_MSG_ID_GLOBAL_POSITION_INT,
                          ML.MAVLINK_MSG_ID_LOCAL_POSITION_NED,
                          ML.MAVLINK_MSG_ID_NAV_CONTROLLER_OUTPUT,
                          ML.MAVLINK_MSG_ID_SYSTEM_TIME, ML.MAVLINK_MSG_ID_EXTENDED_SYS_STATE,
                          ML.MAVLINK_MSG_ID_MISSION_CURRENT, ML.MAVLINK_MSG_ID_HEARTBEAT,
                          ML.MAVLINK_MSG_ID_SYS_STATUS, MD.MAVLINK_MSG_ID_CURRENT_MODE,
                          ML.MAVLINK_MSG_ID_HOME_POSITION})
#: FAST_STREAMS about home: none is sent while home is not set. ``service`` looks for the first
#: fix (``_gnss``, which sets home) before the streams, so a walk that finds home unset skips
#: them without building them (``_build`` would look again and return None). GPS_RAW_INT and
#: SYS_STATUS are framed without home, and declined (the codec's path sets home) at a 3D fix.
HOME_STREAMS = frozenset({ML.MAVLINK_MSG_ID_GLOBAL_POSITION_INT,
                          ML.MAVLINK_MSG_ID_LOCAL_POSITION_NED, ML.MAVLINK_MSG_ID_HOME_POSITION})
#: ``STANDARD_MODE.get``, bound once: CPython 3.11 compiles a method call on a name that an
#: import bound (``from fc.modes import STANDARD_MODE``) as an attribute load, which made a
#: bound method object per call (CURRENT_MODE's block every 2 s, issue 24)
_standard_mode = STANDARD_MODE.get
#: DEBUG_VECT's round-robin cursor wraps here, a multiple of every count of vectors up to 6
#: (and 8, 10, 12, 15, 16): ``cursor % n`` is unchanged and the cursor stays a small int
#: (CPython caches the ints up to 256: no int object per message)
DV_CURSOR_WRAP = 240
_I64_MAX = (1 << 63) - 1
_MISSION_MODE = FlightMode.MISSION      # (bound once: a lookup on the enum class makes a block)
_U64_MASK = (1 << 64) - 1
#: GUIDED's target commands (``_guided_command``) -> the name in STATUSTEXT.
GUIDED_COMMANDS = {
    ML.MAV_CMD_GUIDED_CHANGE_SPEED: "GUIDED_CHANGE_SPEED",
    ML.MAV_CMD_GUIDED_CHANGE_ALTITUDE: "GUIDED_CHANGE_ALTITUDE",
    ML.MAV_CMD_GUIDED_CHANGE_HEADING: "GUIDED_CHANGE_HEADING",
    ML.MAV_CMD_DO_CHANGE_ALTITUDE: "DO_CHANGE_ALTITUDE",
    ML.MAV_CMD_DO_CHANGE_SPEED: "DO_CHANGE_SPEED",
}
#: Commands whose param5/param6 are a position (COMMAND_INT: x, y in degE7; z in m by frame).
POSITION_COMMANDS = frozenset({ML.MAV_CMD_DO_REPOSITION, ML.MAV_CMD_DO_ORBIT})
#: COMMAND_INT frames of a position: altitude AMSL, or above home
FRAMES_AMSL = (ML.MAV_FRAME_GLOBAL, ML.MAV_FRAME_GLOBAL_INT)
FRAMES_ABOVE_HOME = (ML.MAV_FRAME_GLOBAL_RELATIVE_ALT, ML.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT)
INT32_MAX = 2**31 - 1          # COMMAND_INT x/y "not given"


class _Command:
    """One COMMAND_LONG or COMMAND_INT, as the command handler reads it: ``param1`` ..
    ``param7`` (COMMAND_INT: x, y as numbers, z), ``lat_deg``/``lon_deg`` of a position
    command (NaN when not given: COMMAND_LONG NaN, COMMAND_INT INT32_MAX), ``frame`` (-1 for
    COMMAND_LONG) and the sender."""

    __slots__ = ("command", "param1", "param2", "param3", "param4", "param5", "param6",
                 "param7", "frame", "lat_deg", "lon_deg", "src")

    def __init__(self, m, is_int: bool) -> None:
        self.command = m.command
        self.param1, self.param2, self.param3, self.param4 = m.param1, m.param2, m.param3, m.param4
        self.src = (m.get_srcSystem(), m.get_srcComponent())
        if is_int:
            self.param5, self.param6, self.param7 = float(m.x), float(m.y), m.z
            self.frame = m.frame
            self.lat_deg = m.x * 1e-7 if m.x != INT32_MAX else math.nan
            self.lon_deg = m.y * 1e-7 if m.y != INT32_MAX else math.nan
        else:
            self.param5, self.param6, self.param7 = m.param5, m.param6, m.param7
            self.frame = -1
            self.lat_deg, self.lon_deg = m.param5, m.param6

    def get_srcSystem(self) -> int:
        return self.src[0]

    def get_srcComponent(self) -> int:
        return self.src[1]


#: REQUEST_DATA_STREAM stream id -> message ids.
DATA_STREAMS = {
    ML.MAV_DATA_STREAM_RAW_SENSORS: (ML.MAVLINK_MSG_ID_AOA_SSA,),
    ML.MAV_DATA_STREAM_EXTENDED_STATUS: (ML.MAVLINK_MSG_ID_SYS_STATUS,
                                         MD.MAVLINK_MSG_ID_CURRENT_MODE,
                                         ML.MAVLINK_MSG_ID_GPS_RAW_INT,
                                         ML.MAVLINK_MSG_ID_SYSTEM_TIME,
                                         ML.MAVLINK_MSG_ID_MISSION_CURRENT,
                                         ML.MAVLINK_MSG_ID_EXTENDED_SYS_STATE),
    ML.MAV_DATA_STREAM_POSITION: (ML.MAVLINK_MSG_ID_GLOBAL_POSITION_INT,
                                  ML.MAVLINK_MSG_ID_LOCAL_POSITION_NED,
                                  ML.MAVLINK_MSG_ID_NAV_CONTROLLER_OUTPUT),
    ML.MAV_DATA_STREAM_RC_CHANNELS: (ML.MAVLINK_MSG_ID_SERVO_OUTPUT_RAW,),
    ML.MAV_DATA_STREAM_EXTRA1: (ML.MAVLINK_MSG_ID_ATTITUDE,),
    ML.MAV_DATA_STREAM_EXTRA2: (ML.MAVLINK_MSG_ID_VFR_HUD,),
    ML.MAV_DATA_STREAM_EXTRA3: (ML.MAVLINK_MSG_ID_DEBUG_VECT, ML.MAVLINK_MSG_ID_NAMED_VALUE_FLOAT),
}
#: With signing on, unsigned (or badly signed) messages are accepted only of these types:
#: read-only requests. PARAM_SET, COMMAND_LONG/INT, SET_MODE and the rest are rejected.
UNSIGNED_ALLOWED = frozenset({
    ML.MAVLINK_MSG_ID_HEARTBEAT, ML.MAVLINK_MSG_ID_PARAM_REQUEST_LIST,
    ML.MAVLINK_MSG_ID_PARAM_REQUEST_READ, ML.MAVLINK_MSG_ID_MISSION_REQUEST_LIST,
    ML.MAVLINK_MSG_ID_MISSION_REQUEST_INT, ML.MAVLINK_MSG_ID_MISSION_REQUEST,
    ML.MAVLINK_MSG_ID_MISSION_ACK,      # a mission download (the vehicle only answers)
    ML.MAVLINK_MSG_ID_TIMESYNC, ML.MAVLINK_MSG_ID_SYSTEM_TIME,
})
#: The .tlog's own streams (docs/fc.md "Flight log"): the default rates plus the heartbeat.
#: The .tlog's streams: the defaults and HEARTBEAT, less the development-dialect messages
#: (CURRENT_MODE): the log is read with the ardupilotmega dialect, which does not know them
#: (``_log_msg`` leaves them out, so the log's sequence numbers have no gaps for its readers).
LOG_STREAMS_S = {k: v for k, v in {ML.MAVLINK_MSG_ID_HEARTBEAT: 1.0, **STREAM_DEFAULTS_S}.items()
                 if k in ML.mavlink_map}
#: A GNSS sample older than this (plant time) is stale: GPS health off, fix reported as NO_FIX.
GNSS_STALE_S = 1.0
#: A peer table of this many addresses is full: a newcomer evicts the oldest peer, but with
#: signing on an unsigned newcomer evicts only an unsigned peer (never a signed ground station)
MAX_PEERS = 8
PEER_TIMEOUT_S = 10.0
STATUSTEXT_CHUNK = 50          # STATUSTEXT.text is char[50]
STATUSTEXT_MAX_CHUNKS = 5      # longer texts are cut at 250 characters
#: PARAM_ERROR codes (development.xml); TYPE_MISMATCH is newer than pymavlink 2.4.50's table
PARAM_ERR_UNKNOWN = MD.MAV_PARAM_ERROR_DOES_NOT_EXIST
PARAM_ERR_RANGE = MD.MAV_PARAM_ERROR_VALUE_OUT_OF_RANGE
PARAM_ERR_READ_ONLY = MD.MAV_PARAM_ERROR_READ_ONLY
PARAM_ERR_TYPE = getattr(MD, "MAV_PARAM_ERROR_TYPE_MISMATCH", 7)
#: GUIDED_CHANGE_HEADING's heading (deg) is refused beyond +-this (a wrapped 1e9 deg is a turn
#: to an arbitrary course, not what anyone typed)
HEADING_LIMIT_DEG = 360.0
#: Mode changes from the ground stations: at most MODE_BURST at once, MODE_RATE_HZ sustained;
#: more are refused with a STATUSTEXT (each change resets the law and the guidance's state)
MODE_BURST = 4.0
MODE_RATE_HZ = 1.0
#: PARAM_SETs answered after their save (``GcsLink._save_then_echo``): beyond this many waiting
#: (a stuck disk, a flood) the answer goes at once, as before the save-first answer
ECHO_WAIT_MAX = 32


class _Streams:
    """One stream schedule and the codec (sequence numbers, signing link id) it is sent with.

    The default schedule serves the ``--gcs`` outputs and every peer that never asked for
    rates; a peer that sends REQUEST_DATA_STREAM or SET_MESSAGE_INTERVAL gets its own, as a
    PX4/ArduPilot link does, and loses it when it is forgotten after PEER_TIMEOUT_S of silence.
    """

    __slots__ = ("mav", "addr", "intervals", "next_due", "nv_cursor", "dv_cursor")

    def __init__(self, mav, intervals: dict[int, float], addr: tuple | None = None) -> None:
        self.mav = mav
        self.addr = addr                      # the peer; None for the default schedule
        self.intervals = dict(intervals)      # message id -> interval [s]; < 0 disabled
        self.next_due = {k: 0.0 for k in self.intervals}
        self.nv_cursor = 0
        self.dv_cursor = 0


class GcsLink:
    """Ground-station side of the fc. Single-threaded: called from the control loop."""

    def __init__(self, vehicle: VehicleView, bind: tuple[str, int], outputs: list[tuple[str, int]],
                 tlog_path: str | None = None, signing_key: bytes | None = None,
                 log=None, max_rx: int = 8, max_tx: int = 6, io=None,
                 sim_time: bool = False, signing_path: str | None = None,
                 disk: DiskHealth | None = None) -> None:
        self.v = vehicle
        self.log = log
        self.endpoint = UdpEndpoint(*bind)
        self.outputs = list(outputs)
        self.peers: dict[tuple, float] = {}
        self.signed_peers: set[tuple] = set()      # peers that sent a correctly signed message
        self.peers_refused = 0      # unsigned newcomers kept out by a table of signed peers
        self.disk = disk
        self._mode_tokens = MODE_BURST
        self._mode_refill_s = time.monotonic()
        self.mode_refused = 0
        self.mav = new_codec(vehicle.sysid, vehicle.compid)
        self.max_rx = max_rx
        self.max_tx = max_tx
        self.boot_s = time.monotonic()
        # the one time base of every message and of the .tlog (``time_us``): sim time (the
        # newest plant frame's stamp) when ``sim_time`` (lockstep), else time since boot
        self.sim_time = sim_time
        self.epoch_us = int(time.time() * 1e6)    # .tlog stamp = epoch + time base
        self.home: tuple[float, float, float] | None = None   # lat deg, lon deg, alt m MSL
        #: the stored mission (fc/mission.py): the vehicle's (MISSION mode flies it)
        self.mission = vehicle.mission
        self.default = _Streams(self.mav, STREAM_DEFAULTS_S)
        self.intervals = self.default.intervals        # the default schedule (outputs)
        self.next_due = self.default.next_due
        self.links: dict[tuple, _Streams] = {}         # peers that asked for their own rates
        self._rx_addr: tuple | None = None             # source of the message being handled
        self.next_heartbeat = 0.0
        # the earliest wall-clock time a stream or the heartbeat is due on any link (a call of
        # ``service`` before it, with nothing queued, sends nothing); 0.0 = walk the schedules
        # (recomputed after each walk, reset when a received message may have changed them)
        self.wall_due = 0.0
        # parameter answers: single reads/announcements queue (bounded) ahead of the list
        # download, which is a cursor: a repeated PARAM_REQUEST_LIST restarts it and can never
        # push out a pending read (a flood of list requests cannot starve a real GCS)
        self.param_queue: deque[int] = deque()
        # a PARAM_SET of a setting is answered once the parameter file is on disk (or with
        # ``NOT saved`` when it could not be written): (token, index, name) waiting for their
        # save, and the saves' results (token, error or None) from the I/O thread
        self._echo_wait: deque[tuple[int, int, str]] = deque()
        self._saved: queue.SimpleQueue = queue.SimpleQueue()
        self._save_token = 0
        self.list_next = -1        # next index of the list download, -1 = none running
        # STATUSTEXT: rate-limited and de-duplicated (fc/ratelimit.py), queued as chunks
        # (severity, text bytes, id, chunk_seq); the GCS link's own fc.log warnings likewise
        self.texts = RateLimiter()
        self.log_limit = RateLimiter()
        self.text_queue: deque[tuple[int, bytes, int, int]] = deque(maxlen=64)
        self.text_id = 0
        self.last_mode_sent: int | None = None
        self.oneshot: deque = deque(maxlen=16)
        # counters (telemetry: REJ_GCS, REJ_SIGN)
        self.rx_msgs = 0
        self.rejected_bad = 0
        self.rejected_signing = 0
        self.tx_errors = 0            # messages that could not be packed (never sent)
        self.ignored_target = 0
        # tlog: frames collect in memory; flush() hands the chunk to the I/O thread (``io``,
        # fc/iothread.py) so a slow disk never stalls the loop
        self.tlog = AppendFile(tlog_path, "tlog", disk) if tlog_path else None
        self._tlog_buf = bytearray()
        # chunks the I/O thread has written come back here emptied and are filled again: no
        # new bytearray per flush (issue 24); the I/O job is bound once
        self._tlog_spare: list[bytearray] = []
        self._tlog_put = self._put_tlog_chunk
        # the .tlog is a link of its own: its codec (own sequence numbers) and its streams,
        # paced by the time base (sim time in lockstep), not by the wall clock
        self.log_mav = new_codec(vehicle.sysid, vehicle.compid)
        self.log_framer = LeanFramer(vehicle.sysid, vehicle.compid)   # unsigned, codec's bytes
        #: the .tlog's streams, their intervals (us of the time base) and, in ``_log_st``,
        #: their next due times (GF.LOG_*: stepped by ``GF.log_walk_p``)
        self._log_ids = tuple(LOG_STREAMS_S)
        self._log_iv = np.array([int(round(iv * 1e6)) for iv in LOG_STREAMS_S.values()],
                                np.int64)
        self._log_iv_p = address_of(self._log_iv, np.int64, len(self._log_ids))
        self._log_flags = np.zeros(len(self._log_ids), np.int64)      # due in this walk
        self._log_flags_p = address_of(self._log_flags, np.int64, len(self._log_ids))
        self._log_tb = np.zeros(1, np.int64)       # the walk's time base (real time)
        self._log_tb_p = address_of(self._log_tb, np.int64, 1)
        # the .tlog schedule (GF.LOG_*: last time base seen, next due time, each stream's):
        # int64 stepped by a compiled call (``_service_log``), or Python ints in ``_log_big``
        # while one is beyond the cells' range
        self._log_st = np.zeros(GF.LOG_DUE + len(self._log_ids), np.int64)
        self._log_st_p = address_of(self._log_st, np.int64, self._log_st.size)
        self._log_big: list[int] | None = None
        self.io = io
        self._init_fast_frames()
        # the protocol services (one module each): log download of this .tlog, read-only FTP
        # of the run directory; their answers go to the requester only, never to the .tlog
        self.logs = LogService(tlog_path, self.epoch_us // 1_000_000)
        self.ftp = FtpService(os.path.dirname(tlog_path) if tlog_path else None, vehicle.params)
        self.services = {**{i: self.logs for i in LOG_MSGS},
                         ML.MAVLINK_MSG_ID_FILE_TRANSFER_PROTOCOL: self.ftp}
        self.signing = signing_key is not None
        self.signing_key = signing_key
        # signatures verified before any timestamp bookkeeping, stream timestamps persisted
        # (fc/signing.py: pymavlink's own check stores the timestamp of a forged frame)
        self.guard = (SigningGuard(signing_key, signing_path, log) if signing_key is not None
                      else None)
        if signing_key is not None:
            self._sign(self.mav, 0)
            self.mav.signing.timestamp = self.guard.start_timestamp()
            self.mav.signing.allow_unsigned_callback = self._allow_unsigned
            self.guard.install(self.mav)

    def _sign(self, mav, link_id: int) -> None:
        s = mav.signing
        s.secret_key = self.signing_key
        s.sign_outgoing = True
        s.link_id = link_id
        # never behind a timestamp already used (the links' own or the stored one)
        s.timestamp = max(clock_timestamp(), self.mav.signing.timestamp)

    def signing_snapshot(self) -> bytes | None:
        """The signing state file's bytes when a stream timestamp changed, else None (saved
        on the I/O thread with ``save_signing``; fc/signing.py). Nothing is computed while no
        stream changed (``guard.dirty``: ``guard.snapshot`` gives None then, whatever the
        timestamp): the 1 Hz chore took the largest timestamp over a generator and read the
        clock as a large int every second (issue 24)."""
        if self.guard is None or self.guard.path is None or not self.guard.dirty:
            return None
        own = max(link.mav.signing.timestamp for link in (self.default, *self.links.values()))
        return self.guard.snapshot(max(own, clock_timestamp()))

    def save_signing(self, data: bytes) -> None:
        """Write a ``signing_snapshot`` (I/O thread); a failure goes to the disk health."""
        try:
            self.guard.save(data)
        except OSError as exc:
            self.guard.dirty = True          # tried again at the next save
            new = self.disk is None or self.disk.failed("signing timestamps", exc)
            if new and self.log is not None:
                self.log.error("cannot save the signing timestamps: %s", exc)
            return
        if self.disk is not None:
            self.disk.ok("signing timestamps")

    # ------------------------------------------------------------------ plumbing
    @staticmethod
    def _allow_unsigned(_mav, msg_id: int) -> bool:
        return msg_id in UNSIGNED_ALLOWED

    # ------------------------------------------------------------------ compiled frames
    def _init_fast_frames(self) -> None:
        """The compiled framing of FAST_STREAMS (fc/gcs_frames.py): a frame buffer, its slices,
        the destinations as sockaddr_in. ``fast`` (decided at the first use, the vehicle being
        complete then: :meth:`_fast_ok`) is False, the codec's path for everything, when the
        vehicle's state is not in the arrays the kernels read (a stub vehicle), libc's
        ``sendto`` cannot be compiled (NUMBA_DISABLE_JIT), or a kernel's bytes differ from the
        codec's."""
        self._tx = np.zeros(GF.FRAME_MAX_B, np.uint8)
        self._tx_p = address_of(self._tx, np.uint8, GF.FRAME_MAX_B)
        mv = memoryview(self._tx)
        self._tx_views = tuple(mv[:n] for n in range(GF.FRAME_MAX_B + 1))
        self._tb = np.zeros(1, np.int64)        # the time base for the kernels (``_time_at``)
        self._tb_p = address_of(self._tb, np.int64, 1)
        self._meas_at = ArrayAddress(np.float64, M_N)
        self._pwm_at = ArrayAddress(np.int64, 4)
        self._frames_at = ArrayAddress(np.int64, HOT_FRAMES + 1)
        self._frames_p = 0                      # ``_frames_cell``: the address, of the array
        self._frames_of: np.ndarray | None = None
        self._gps_at = ArrayAddress(np.float64, G_N)
        # ``home`` as the GNSS kernels read it (GF.HOME_*), copied when ``home`` is rebound
        self._home_arr = np.zeros(GF.HOME_N)
        self._home_p = address_of(self._home_arr, np.float64, GF.HOME_N)
        self._home_src: tuple | None = None
        self._fd = self.endpoint.fileno()
        # the default schedule's destinations (``_default_addrs``): the IPv4 ones as
        # sockaddr_in rows for the compiled send, the others sent by ``socket``; rebuilt when
        # the peers or the own-rate links change (``_dests_dirty``)
        self._dests = np.zeros((len(self.outputs) + MAX_PEERS, GF.SOCKADDR_IN_B), np.uint8)
        self._dests_p = address_of(self._dests, np.uint8, self._dests.size)
        self._n_dests = 0
        self._slow_dests: tuple = ()
        self._dests_dirty = True
        # the int64 cell of the newest frame's stamp (the time base in lockstep), if the
        # vehicle keeps one (fc/intake.py ``stamp_at``): bound by ``warm_up`` (the vehicle
        # complete then); while None, the stamp is read as an int
        self._stamp_at: int | None = None
        self._dv_frame = getattr(self.v, "frame_debug_vector", None)
        self._dv_count = getattr(self.v, "debug_vector_count", None)
        self._nv_frame = getattr(self.v, "frame_named_value", None)
        self._nv_count = getattr(self.v, "named_value_count", None)
        self._nav_frame = getattr(self.v, "frame_nav_output", None)
        self._nav_active = getattr(self.v, "nav_output_active", None)
        self.fast: bool | None = None if FAST_IO else False

    def warm_up(self) -> bool:
        """Decide the compiled stream framing now, loading its kernels (the fc calls this at
        the end of its construction, before READY, so the first frames do not load them and
        ``hyfc-precompile`` compiles them): True when FAST_STREAMS use it."""
        scratch = np.zeros(GF.LOG_DUE + 1, np.int64)                  # (loaded now)
        sp = address_of(scratch, np.int64, GF.LOG_DUE + 1)
        GF.log_walk_p(sp, sp, sp, 1, sp)
        zeros = np.zeros(max(GF.GS_N, GF.TG_N, GF.E_N))     # (NAV: sent in guidance modes only)
        zp = address_of(zeros, np.float64, zeros.size)
        GF.nav_output_p(self._tx_p, -1, 0, 0, 1, 1, zp, zp, zp, False, 0.0, 0.0, 0.0)
        return self._fast_ok()

    def _fast_ok(self) -> bool:
        """Whether FAST_STREAMS go through the compiled framing (``fast``, decided once)."""
        if self.fast is None:
            self._stamp_at = getattr(self.v, "meas_stamp_at", None)
            try:
                self._meas_at.of(self.v.meas)
                self._pwm_at.of(self.v.pwm_us)
                self._frames_at.of(self.v.plant.counters.hot)
                self._gps_at.of(self.v.plant.gps)
            except (ValueError, AttributeError, TypeError):
                self.fast = False
                return False
            self.fast = self._fast_self_check()
            if not self.fast and self.log is not None:
                self.log.warning("ground-station streams: the compiled framing differs from "
                                 "the codec here; the codec frames them")
        return self.fast

    def _fast_self_check(self) -> bool:
        """The kernels' frames of the vehicle's state now equal the codec's (as ``_build``
        makes them), each with and without the .tlog stamp."""
        home = self.home
        if home is None:
            # the GNSS messages checked (and their kernels loaded) about a stand-in home, taken
            # back after: ``_gnss`` sets no home while one is set
            self.home = (0.0, 0.0, 0.0)
        try:
            c = new_codec(self.v.sysid, self.v.compid)
            us = self.time_us()
            for msg_id in (*STREAM_IDS, ML.MAVLINK_MSG_ID_HEARTBEAT):
                if msg_id not in FAST_STREAMS:
                    continue
                for k in range(self._n_debug_vectors() if msg_id == ML.MAVLINK_MSG_ID_DEBUG_VECT
                               else self._n_named_values()
                               if msg_id == ML.MAVLINK_MSG_ID_NAMED_VALUE_FLOAT else 1):
                    if self._stamp_at is None and (
                            msg_id == ML.MAVLINK_MSG_ID_GPS_RAW_INT
                            or (msg_id == ML.MAVLINK_MSG_ID_DEBUG_VECT
                                and k == self._n_debug_vectors() - 1)):
                        continue            # (no stamp cell: these take the codec's path)
                    msg = self._build(msg_id, k, us)    # (real time: the base moves on)
                    if msg is None:
                        continue            # (not sent now: NAV_CONTROLLER_OUTPUT outside
                                            # the guidance modes)
                    c.seq = 17
                    want = msg.pack(c)
                    n = self._frame_stream(msg_id, k, -1, 0, 17, us)
                    if bytes(self._tx[:n]) != want:
                        return False
                    n = self._frame_stream(msg_id, k, self.epoch_us, us, 17, us)
                    if bytes(self._tx[:n]) != struct.pack(">Q", self.epoch_us + us) + want:
                        return False
            GF.send_frame_p(self._fd, self._tx_p, 0, self._dests_p, 0)     # (loaded: sends none)
            return True
        except Exception:  # noqa: BLE001 - any surprise: the codec's path
            return False
        finally:
            self.home = home

    def _n_named_values(self) -> int:
        """How many NAMED_VALUE_FLOATs a stream period has (the vehicle's count, without
        building the pairs, when it gives one)."""
        if self._nv_count is not None:
            return self._nv_count()
        return len(self.v.named_values())

    def _n_debug_vectors(self) -> int:
        """How many DEBUG_VECTs a stream period has (the vehicle's, then SIM_T)."""
        if self._dv_count is not None:
            return self._dv_count() + 1
        return len(self._debug_vectors())

    def _frame_stream(self, msg_id: int, k: int, log_epoch_us: int, log_t_us: int, seq: int,
                      us: int) -> int:
        """:meth:`_frame_at` at the time base ``us``, the .tlog's stamp at ``log_t_us`` (us;
        0 framed when one is beyond int64)."""
        if not (0 <= us <= _I64_MAX and 0 <= log_t_us <= _I64_MAX):
            return 0
        self._tb[0] = us
        self._log_tb[0] = log_t_us
        return self._frame_at(msg_id, k, log_epoch_us, self._log_tb_p, seq, self._tb_p)

    def _time_at(self) -> int:
        """The address of an int64 cell holding the time base now (``time_us``): in lockstep
        the newest frame's stamp cell (no Python int for it), else ``_tb`` set to it; 0 when
        it is beyond int64 (the kernels decline)."""
        if self.sim_time and self._stamp_at is not None and not self.v.meas_stamp_big:
            return self._stamp_at
        us = self.time_us()
        if not 0 <= us <= _I64_MAX:
            return 0
        self._tb[0] = us
        return self._tb_p

    def _frame_at(self, msg_id: int, k: int, log_epoch_us: int, log_t_at: int, seq: int,
                  time_at: int) -> int:
        """Frame message ``msg_id`` of FAST_STREAMS (DEBUG_VECT: vector ``k``) at the time base
        in the int64 cell at ``time_at`` with sequence ``seq`` into ``_tx`` (with the .tlog
        stamp ``log_epoch_us`` + the int64 at ``log_t_at`` when ``log_epoch_us`` >= 0): the
        bytes written, or 0 when the kernel declines or ``time_at`` is 0 (the caller takes the
        codec's path)."""
        v = self.v
        if msg_id == ML.MAVLINK_MSG_ID_HEARTBEAT:
            base, custom, status = self._heartbeat_fields()
            return GF.heartbeat_p(self._tx_p, log_epoch_us, log_t_at, seq, v.sysid, v.compid,
                                  custom, ML.MAV_TYPE_FIXED_WING, ML.MAV_AUTOPILOT_GENERIC, base,
                                  status)
        if msg_id == MD.MAVLINK_MSG_ID_CURRENT_MODE:
            mode = v.modes.mode
            return GF.current_mode_p(self._tx_p, log_epoch_us, log_t_at, seq, v.sysid, v.compid,
                                     _standard_mode(mode, 0), custom_mode_of(mode))
        if msg_id == ML.MAVLINK_MSG_ID_SYS_STATUS:
            if self._stamp_at is None or v.meas_stamp_big:
                return 0
            c = v.error_counts()
            return GF.sys_status_p(self._tx_p, log_epoch_us, log_t_at, seq, v.sysid, v.compid,
                                   v.modes.law_active, v.health_failed_bits(),
                                   self._gps_at.of(v.plant.gps), self._stamp_at,
                                   self.home is not None, v.load_permille(), c[0], c[1], c[2],
                                   c[3], c[4])
        if msg_id == ML.MAVLINK_MSG_ID_MISSION_CURRENT:
            item, total, state, mode = self.mission.current_fields(self._mission_active())
            return GF.mission_current_p(self._tx_p, log_epoch_us, log_t_at, seq, v.sysid,
                                        v.compid, item, total, state, mode)
        if msg_id == ML.MAVLINK_MSG_ID_EXTENDED_SYS_STATE:
            return GF.extended_sys_state_p(
                self._tx_p, log_epoch_us, log_t_at, seq, v.sysid, v.compid,
                self._frames_cell(), v.modes.data_lost,
                self._meas_at.of(v.meas))
        if not time_at:
            return 0
        if msg_id == ML.MAVLINK_MSG_ID_SYSTEM_TIME:
            return GF.system_time_p(self._tx_p, log_epoch_us, log_t_at, seq, v.sysid, v.compid,
                                    time_at, self.epoch_us)
        if msg_id == ML.MAVLINK_MSG_ID_ATTITUDE:
            return GF.attitude_p(self._tx_p, log_epoch_us, log_t_at, seq, v.sysid, v.compid,
                                 time_at, self._meas_at.of(v.meas))
        if msg_id == ML.MAVLINK_MSG_ID_AOA_SSA:
            return GF.aoa_ssa_p(self._tx_p, log_epoch_us, log_t_at, seq, v.sysid, v.compid,
                                time_at, self._meas_at.of(v.meas))
        if msg_id == ML.MAVLINK_MSG_ID_VFR_HUD:
            return GF.vfr_hud_p(self._tx_p, log_epoch_us, log_t_at, seq, v.sysid, v.compid,
                                self._meas_at.of(v.meas), v.throttle_percent())
        if msg_id == ML.MAVLINK_MSG_ID_SERVO_OUTPUT_RAW:
            return GF.servo_raw_p(self._tx_p, log_epoch_us, log_t_at, seq, v.sysid, v.compid,
                                  time_at, self._pwm_at.of(v.pwm_us))
        if msg_id == ML.MAVLINK_MSG_ID_NAMED_VALUE_FLOAT:
            if self._nv_frame is None:
                return 0
            return self._nv_frame(k, self._tx_p, log_epoch_us, log_t_at, seq, v.sysid, v.compid,
                                  time_at)
        if msg_id == ML.MAVLINK_MSG_ID_DEBUG_VECT:
            if self._dv_frame is None:
                return 0
            if k < self._dv_count():
                return self._dv_frame(k, self._tx_p, log_epoch_us, log_t_at, seq, v.sysid,
                                      v.compid, time_at)
            if self._stamp_at is None or v.meas_stamp_big:
                return 0                # (the stamp as a Python int: the codec's path)
            return GF.sim_t_p(self._tx_p, log_epoch_us, log_t_at, seq, v.sysid, v.compid,
                              time_at, self._stamp_at,
                              self._frames_cell())
        if msg_id == ML.MAVLINK_MSG_ID_GPS_RAW_INT:
            # (declined at a 3D fix while home is not set: the codec's path sets it)
            if self._stamp_at is None or v.meas_stamp_big:
                return 0
            return GF.gps_raw_int_p(self._tx_p, log_epoch_us, log_t_at, seq, v.sysid, v.compid,
                                    time_at, self._gps_at.of(v.plant.gps), self._stamp_at,
                                    self.home is not None)
        if msg_id == ML.MAVLINK_MSG_ID_NAV_CONTROLLER_OUTPUT:
            if self._nav_frame is None:
                return 0
            return self._nav_frame(self._tx_p, log_epoch_us, log_t_at, seq, v.sysid, v.compid)
        if self.home is None:
            return 0                    # the codec's path (it sets home at the first fix)
        if self.home is not self._home_src:
            self._set_home_arr()
        if msg_id == ML.MAVLINK_MSG_ID_GLOBAL_POSITION_INT:
            return GF.global_position_int_p(self._tx_p, log_epoch_us, log_t_at, seq, v.sysid,
                                            v.compid, time_at, self._gps_at.of(v.plant.gps),
                                            self._meas_at.of(v.meas), self._home_p)
        if msg_id == ML.MAVLINK_MSG_ID_LOCAL_POSITION_NED:
            return GF.local_position_ned_p(self._tx_p, log_epoch_us, log_t_at, seq, v.sysid,
                                           v.compid, time_at, self._gps_at.of(v.plant.gps),
                                           self._home_p)
        if msg_id == ML.MAVLINK_MSG_ID_HOME_POSITION:
            return GF.home_position_p(self._tx_p, log_epoch_us, log_t_at, seq, v.sysid, v.compid,
                                      time_at, self._home_p)
        return 0

    def _frames_cell(self) -> int:
        """The address of the plant link's frame count (``LinkCounters.hot[HOT_FRAMES]``), bound
        once (an address plus an offset makes an int per call)."""
        hot = self.v.plant.counters.hot
        if hot is not self._frames_of:
            self._frames_p = self._frames_at.of(hot) + 8 * HOT_FRAMES
            self._frames_of = hot
        return self._frames_p

    def _set_home_arr(self) -> None:
        """``home`` into the GNSS kernels' array, with its latitude's cosine as ``local_ned``
        computes it."""
        lat, lon, alt = self.home
        h = self._home_arr
        h[GF.HOME_LAT_DEG] = lat
        h[GF.HOME_LON_DEG] = lon
        h[GF.HOME_ALT_M] = alt
        h[GF.HOME_COS_LAT] = math.cos(math.radians(lat))
        self._home_src = self.home

    def _refresh_dests(self) -> None:
        """The default schedule's destinations (``_default_addrs``) as sockaddr_in rows."""
        n = 0
        slow = []
        for addr in self._default_addrs():
            sa = GF.sockaddr_in(*addr) if len(addr) == 2 else None
            if sa is None or n >= len(self._dests):
                slow.append(addr)
            else:
                self._dests[n] = sa
                n += 1
        self._n_dests = n
        self._slow_dests = tuple(slow)
        self._dests_dirty = False

    def _send_frame(self, n: int) -> None:
        """Send the ``n`` bytes framed in ``_tx`` to the default schedule's destinations (as
        ``_send_on`` sends a message on the default link)."""
        if self._dests_dirty:
            self._refresh_dests()
        if self._n_dests:
            failed = GF.send_frame_p(self._fd, self._tx_p, n, self._dests_p, self._n_dests)
            if failed:
                self.endpoint.send_errors += failed
        if self._slow_dests:
            for addr in self._slow_dests:
                self.endpoint.send(self._tx_views[n], addr)

    def _log_fast(self, msg_id: int, t_at: int) -> None:
        """The .tlog's messages of one stream period of ``msg_id`` (FAST_STREAMS: every named
        value and every vector, in order) framed by the kernels and stamped with the time base
        at the int64 cell ``t_at``, as ``_stream_messages`` + ``_log_msg`` write them; one the
        kernel declines is built and written by the codec's path."""
        mav = self.log_mav
        time_at = self._time_at()
        if msg_id == ML.MAVLINK_MSG_ID_NAMED_VALUE_FLOAT:
            count = self._n_named_values()
        elif msg_id == ML.MAVLINK_MSG_ID_DEBUG_VECT:
            count = self._n_debug_vectors()
        elif self._none_due(msg_id):
            return
        else:
            count = 1
        k = 0
        while k < count:
            n = self._frame_at(msg_id, k, self.epoch_us, t_at, mav.seq, time_at)
            if n:
                self._tlog_buf += self._tx_views[n]
                mav.seq = (mav.seq + 1) % 256
            else:
                msg = self._build(msg_id, k)
                if msg is not None:
                    self._log_msg(msg, int64_at(t_at))
            k += 1

    def _none_due(self, msg_id: int) -> bool:
        """Whether FAST_STREAMS' ``msg_id`` has no message now (``_build`` would give None
        after the work): HOME_STREAMS before home (``service`` looked for the first fix before
        the streams), NAV_CONTROLLER_OUTPUT outside the guidance modes."""
        if msg_id == ML.MAVLINK_MSG_ID_NAV_CONTROLLER_OUTPUT:
            return self._nav_active is not None and not self._nav_active()
        return self.home is None and msg_id in HOME_STREAMS

    def _tlog_write(self, buf: bytes, t_us: int | None = None) -> None:
        """Append a frame to the .tlog, stamped epoch + time base (us, big-endian u64, mod
        2^64: a faulty plant's stamp near 2^64 raised here and stopped the fc; the compiled
        framing's int64 sum wraps the same way)."""
        if self.tlog is not None:
            if t_us is None:
                t_us = self.time_us()
            self._tlog_buf += struct.pack(">Q", (self.epoch_us + t_us) & _U64_MASK)
            self._tlog_buf += buf

    def _log_msg(self, msg, t_us: int | None = None) -> None:
        """Write ``msg`` to the .tlog, packed with the log's own codec (its sequence).
        Development-dialect messages (AVAILABLE_MODES, CURRENT_MODE, PARAM_ERROR) are left
        out: the log's readers use the ardupilotmega dialect (LOG_STREAMS_S)."""
        if msg.get_msgId() not in ML.mavlink_map:
            return
        mav = self.log_mav
        try:
            buf = self.log_framer.frame(msg, mav.seq) if self.log_framer.ok else msg.pack(mav)
        except (struct.error, ValueError, TypeError, OverflowError):
            return          # a message that cannot be packed is not logged
        mav.seq = (mav.seq + 1) % 256
        self._tlog_write(buf, t_us)

    def _pack(self, mav, msg) -> bytes | None:
        try:
            buf = msg.pack(mav)
        except (struct.error, ValueError, TypeError, OverflowError) as exc:
            # a message built from hostile input must never stop the control loop
            self.tx_errors += 1
            if self.log is not None and self.tx_errors == 1:
                self.log.warning("cannot pack %s: %r (counted, not sent)", msg.get_type(), exc)
            return None
        mav.seq = (mav.seq + 1) % 256
        return buf

    def _default_addrs(self):
        for addr in self.outputs:
            if addr not in self.links:
                yield addr
        for addr in self.peers:
            if addr not in self.outputs and addr not in self.links:
                yield addr

    def send(self, msg, log: bool = True) -> None:
        """Send ``msg`` to every output and peer (each own-rate peer with its own codec);
        ``log``: also write it to the .tlog (events; the periodic streams reach the .tlog
        through the log's own schedule instead)."""
        self._send_on(self.default, msg)
        for link in self.links.values():
            self._send_on(link, msg)
        if log and self.tlog is not None:
            self._log_msg(msg)

    def _send_on(self, link: _Streams, msg) -> None:
        """Send ``msg`` on one schedule's link: the default destinations, or that one peer."""
        buf = self._pack(link.mav, msg)
        if buf is None:
            return
        if link is self.default:
            for addr in self._default_addrs():
                self.endpoint.send(buf, addr)
        elif self.links.get(link.addr) is link:     # not forgotten meanwhile
            self.endpoint.send(buf, link.addr)

    def _send_to(self, addr, msg) -> None:
        """Send ``msg`` to one peer only (a service's answer), with that peer's codec."""
        buf = self._pack(self._link_of(addr).mav, msg)
        if buf is not None:
            self.endpoint.send(buf, addr)

    def _service_out(self, outputs: list) -> None:
        """Send a protocol service's outputs: ``(peer, message)`` or ``("text", sev, text)``."""
        for out in outputs:
            if out[0] == "text":
                self.statustext(out[1], out[2])
            else:
                self._send_to(*out)

    def _link_of(self, addr) -> _Streams:
        return self.links.get(addr, self.default)

    def _own_link(self, addr) -> _Streams:
        """The schedule of ``addr``, created (a copy of the defaults) on its first rate request."""
        link = self.links.get(addr)
        if link is None:
            link = _Streams(new_codec(self.v.sysid, self.v.compid), self.default.intervals, addr)
            if self.signing:
                self._sign(link.mav, (len(self.links) + 1) % 256)
            self.links[addr] = link
            self._dests_dirty = True
        return link

    def statustext(self, severity: int, text: str) -> None:
        """Queue a STATUSTEXT (MAV_SEVERITY_*), sent from ``service`` and mirrored to fc.log.

        Repeats and floods are held back and summarised (fc/ratelimit.py); a text longer than
        50 characters goes out in chunks (MAVLink 2 ``id``/``chunk_seq``).
        """
        if self.texts.allow(time.monotonic(), severity, text):
            self._queue_text(severity, text)

    def _queue_text(self, severity: int, text: str) -> None:
        if self.log is not None:
            self.log.info("STATUSTEXT[%d] %s", severity, text)
        raw = text.encode("ascii", "replace")[:STATUSTEXT_CHUNK * STATUSTEXT_MAX_CHUNKS]
        if len(raw) <= STATUSTEXT_CHUNK:
            self.text_queue.append((severity, raw, 0, 0))
            return
        self.text_id = self.text_id % 0xFFFF + 1
        # a receiver ends a message at its first chunk shorter than 50 characters
        n = len(raw) // STATUSTEXT_CHUNK + 1
        for k in range(n):
            self.text_queue.append((severity, raw[k * STATUSTEXT_CHUNK:(k + 1) * STATUSTEXT_CHUNK],
                                    self.text_id, k))

    def _warn(self, text: str) -> None:
        """A warning of the GCS link in fc.log, rate-limited like STATUSTEXT."""
        if self.log is not None and self.log_limit.allow(time.monotonic(), 4, text):
            self.log.warning(text)

    def _summaries(self) -> None:
        """Once a second: the "N suppressed" lines of bursts that have ended."""
        now = time.monotonic()
        if not self.texts.idle:             # (the idle limiters make no list)
            for sev, text in self.texts.summaries(now):
                self._queue_text(sev, text)
        if self.log is not None and not self.log_limit.idle:
            for _sev, text in self.log_limit.summaries(now):
                self.log.warning(text)

    def time_us(self) -> int:
        """The telemetry time base (us): lockstep: sim time of the newest plant frame (0
        before the first); real time: monotonic time since the fc started."""
        if self.sim_time:
            return int(self.v.meas_stamp_us)
        return int((time.monotonic() - self.boot_s) * 1e6)

    def time_boot_ms(self) -> int:
        return (self.time_us() // 1000) & 0xFFFFFFFF

    def close(self) -> None:
        """Write what is pending (synchronously: the loop has stopped) and close."""
        self.logs.close()
        self.ftp.close()
        if self.tlog is not None:
            self.tlog.append(self._tlog_buf)
            self._tlog_buf = bytearray()
            self.tlog.close()
            self.tlog = None
        self.endpoint.close()

    def flush(self) -> None:
        """Hand the collected tlog frames to the I/O thread (called ~1 Hz)."""
        if self.tlog is None or not self._tlog_buf:
            return
        chunk = self._tlog_buf
        self._tlog_buf = self._tlog_spare.pop() if self._tlog_spare else bytearray()
        if self.io is not None:
            self.io.submit(self._tlog_put, chunk)
        else:
            self._tlog_put(chunk)

    def _put_tlog_chunk(self, chunk: bytearray) -> None:
        """Append ``chunk`` to the .tlog (the I/O thread), then give it back to :meth:`flush`
        emptied (``list.append`` and ``pop`` are atomic: the two threads share the list)."""
        tlog = self.tlog
        if tlog is not None:
            tlog.append(chunk)
        chunk.clear()
        self._tlog_spare.append(chunk)

    # ------------------------------------------------------------------ receive
    def poll(self, now_s: float) -> int:
        """Read and handle at most ``max_rx`` datagrams. Returns how many were read."""
        n = 0
        while n < self.max_rx:
            got = self.endpoint.recv()
            if got is None:
                break
            n += 1
            data, addr = got
            before = self.mav.signing.reject_count
            msgs, n_bad = decode_datagram(self.mav, data)
            rejected_sig = self.mav.signing.reject_count - before
            self.rejected_signing += rejected_sig
            self.rejected_bad += max(0, n_bad - rejected_sig)
            for m in msgs:
                if m.get_srcSystem() == self.v.sysid:
                    continue  # our own echo or a clash: never obey it
                self.rx_msgs += 1
                self.wall_due = 0.0     # a new peer or rate request: schedules walked again
                self._tlog_write(bytes(m.get_msgbuf()))
                self._heard(addr, now_s, self.signing and m.get_signed())
                self._rx_addr = addr
                try:
                    self._handle(m, now_s)
                except Exception as exc:  # noqa: BLE001 - never die on a message
                    self.rejected_bad += 1
                    self._warn(f"GCS message {m.get_type()} not handled: {exc!r}")
        return n

    def _heard(self, addr, now_s: float, signed: bool) -> None:
        """Note a message from ``addr`` (``signed``: with a valid signature). A newcomer to a
        full table makes room (``_expire_peers``); with signing on, an unsigned newcomer that
        finds only signed peers is not added (its messages are still handled)."""
        if addr not in self.peers:
            self._dests_dirty = True
        if addr not in self.peers and len(self.peers) >= MAX_PEERS:
            self._expire_peers(now_s, force=True, newcomer_signed=signed)
            if len(self.peers) >= MAX_PEERS:
                self.peers_refused += 1
                return
        self.peers[addr] = now_s
        if signed:
            self.signed_peers.add(addr)

    def _forget(self, addr) -> None:
        self._dests_dirty = True
        del self.peers[addr]
        self.signed_peers.discard(addr)
        self.links.pop(addr, None)     # its rates go with it (an output: defaults again)

    def _expire_peers(self, now_s: float, force: bool = False,
                      newcomer_signed: bool = True) -> None:
        """Forget peers silent for PEER_TIMEOUT_S; ``force``: also the oldest one, to make
        room (with signing on: the oldest unsigned one, or a signed one for a signed newcomer
        only)."""
        if self.peers:                  # (no list made while there is none)
            for addr, t in list(self.peers.items()):
                if now_s - t > PEER_TIMEOUT_S:
                    self._forget(addr)
        if force and len(self.peers) >= MAX_PEERS:
            self._make_room(newcomer_signed)

    def _make_room(self, newcomer_signed: bool) -> None:
        """Forget the oldest peer for a newcomer (``_expire_peers``' ``force``). Its own method:
        the comprehension's closure over ``self`` made a cell object on every call of
        ``_expire_peers``, the heartbeat second's block (issue 24)."""
        pool = [a for a in self.peers if a not in self.signed_peers] if self.signing else []
        if not pool and (newcomer_signed or not self.signing):
            pool = list(self.peers)
        if pool:
            self._forget(min(pool, key=self.peers.get))

    def _for_us(self, m) -> bool:
        ts = getattr(m, "target_system", 0)
        tc = getattr(m, "target_component", 0)
        ok = ts in (0, self.v.sysid) and tc in (0, self.v.compid)
        if not ok:
            self.ignored_target += 1
        return ok

    def _handle(self, m, now_s: float) -> None:
        t = m.get_msgId()
        if t == ML.MAVLINK_MSG_ID_HEARTBEAT:
            return
        if t == ML.MAVLINK_MSG_ID_PARAM_REQUEST_LIST:
            if self._for_us(m):
                self.list_next = 0
        elif t == ML.MAVLINK_MSG_ID_PARAM_REQUEST_READ:
            if self._for_us(m):
                idx = self._param_index(m.param_id, m.param_index)
                if idx is None:                 # answered at once: no client time-out
                    self._param_error(m, m.param_index, PARAM_ERR_UNKNOWN)
                elif len(self.param_queue) < 4 * len(self.v.params):
                    self.param_queue.append(idx)
        elif t == ML.MAVLINK_MSG_ID_PARAM_SET:
            if self._for_us(m):
                self._param_set(m)
        elif t == ML.MAVLINK_MSG_ID_COMMAND_LONG:
            if self._for_us(m):
                self._command(_Command(m, False), now_s)
        elif t == ML.MAVLINK_MSG_ID_COMMAND_INT:
            if self._for_us(m):
                self._command(_Command(m, True), now_s)
        elif t == ML.MAVLINK_MSG_ID_SET_MODE:
            if m.target_system in (0, self.v.sysid):
                ok, text = self._request_mode(float(m.custom_mode), 0.0)
                self.statustext(ML.MAV_SEVERITY_INFO if ok else ML.MAV_SEVERITY_WARNING, text)
        elif t == ML.MAVLINK_MSG_ID_REQUEST_DATA_STREAM:
            if self._for_us(m):
                self._data_stream(m)
        elif t in MISSION_MSGS:
            if self._for_us(m):
                self.mission_send(self.mission.handle(m, now_s))
        elif t == ML.MAVLINK_MSG_ID_TIMESYNC:
            reply = timesync_answer(m, self.time_us() * 1000, self.v.sysid, self.v.compid)
            if reply is not None:
                self._send_to(self._rx_addr, reply)
        elif t in self.services:
            if self._for_us(m):
                self._service_out(self.services[t].handle(m, self._rx_addr, now_s))

    # ------------------------------------------------------------------ parameters
    def _param_index(self, param_id, index: int) -> int | None:
        params = self.v.params
        if index >= 0:
            return index if index < len(params) else None
        name = param_id if isinstance(param_id, str) else param_id.decode("ascii", "replace")
        name = name.rstrip("\x00")
        if name in params.index:
            return params.index[name]
        return params.index.get(name.upper())

    def _param_value(self, idx: int):
        params = self.v.params
        value, ptype = encode_value(params.defs[idx], float(params.values[idx]))
        return self.mav.param_value_encode(
            params.names[idx].encode("ascii"), value, ptype, len(params), idx)

    def _param_set(self, m) -> None:
        """Validate and apply; a refusal is answered at once: PARAM_ERROR, then PARAM_VALUE
        with the unchanged value (a GCS without PARAM_ERROR sees the value did not change)."""
        idx = self._param_index(m.param_id, -1)
        if idx is None:
            self._param_error(m, -1, PARAM_ERR_UNKNOWN)
            self.statustext(ML.MAV_SEVERITY_WARNING, f"unknown parameter {m.param_id}")
            return
        name = self.v.params.names[idx]
        value = decode_set_value(self.v.params.defs[idx], float(m.param_value), m.param_type)
        if value is None:
            reason, code = f"{name}: wrong type {m.param_type}", PARAM_ERR_TYPE
        else:
            reason = self.v.set_param(name, value)
            code = PARAM_ERR_READ_ONLY if name in PROCESS_DRIVEN else PARAM_ERR_RANGE
        if reason is not None:
            self._param_error(m, idx, code)
            self.statustext(ML.MAV_SEVERITY_WARNING, f"refused: {reason}")
        elif self._save_then_echo(idx, name):
            return                          # answered by ``service`` once the file is written
        elif (self.disk is not None and self.disk.failing
              and self.v.params.defs[idx].group != "command"):
            # set in memory, but the disk refuses writes: it would revert at a restart
            # (commands are never kept on file)
            err = self.disk.error_of("parameters") or "writes failing"
            self.statustext(ML.MAV_SEVERITY_ERROR, f"{name} set, NOT saved (disk: {err})")
        self.send(self._param_value(idx))   # current value, also when refused

    def _save_then_echo(self, idx: int, name: str) -> bool:
        """A setting was set: write the parameter file now (the I/O thread) and answer when it
        is on disk, so a value that cannot be saved is never echoed as simply accepted, not
        even before the disk's first failure (issue 22). False (answer at once) for commands
        (not kept on file), a vehicle without a file, or too many answers already waiting."""
        if (self.v.params.defs[idx].group == "command"
                or len(self._echo_wait) >= ECHO_WAIT_MAX):
            return False
        self._save_token += 1
        token = self._save_token
        self._echo_wait.append((token, idx, name))
        if not self.v.save_params(lambda err, tok=token: self._saved.put((tok, err))):
            self._echo_wait.pop()
            return False
        return True

    def _answer_saved(self) -> None:
        """The answers of the PARAM_SETs whose save finished (saves run in order on the one
        I/O thread): ``NOT saved (disk: ...)`` as an ERROR STATUSTEXT first when the file
        could not be written, then PARAM_VALUE with the value (set in memory either way)."""
        while True:
            try:
                token, err = self._saved.get_nowait()
            except queue.Empty:
                return
            while self._echo_wait and self._echo_wait[0][0] <= token:
                _, idx, name = self._echo_wait.popleft()
                if err is not None:
                    self.statustext(ML.MAV_SEVERITY_ERROR, f"{name} set, NOT saved (disk: {err})")
                self.send(self._param_value(idx))

    def _param_error(self, m, idx: int, code: int) -> None:
        self.send(MD.MAVLink_param_error_message(m.get_srcSystem(), m.get_srcComponent(),
                                                 m.param_id.encode("ascii", "replace")[:16]
                                                 if isinstance(m.param_id, str) else m.param_id,
                                                 idx, code))

    def announce_param(self, name: str) -> None:
        """Broadcast a value the vehicle changed itself (timeline, mode -> CO_ENABLE)."""
        idx = self.v.params.index.get(name)
        if idx is not None and len(self.param_queue) < 4 * len(self.v.params):
            self.param_queue.append(idx)

    # ------------------------------------------------------------------ commands
    def _ack(self, m, command: int, result: int) -> None:
        self.send(self.mav.command_ack_encode(command, result, 0, 0, m.get_srcSystem(),
                                              m.get_srcComponent()))

    def _command(self, m: _Command, now_s: float) -> None:
        """Every COMMAND_LONG and COMMAND_INT addressed to us gets exactly one COMMAND_ACK.
        Both go through the one handler (``_command_result``): every command is accepted in
        either form; a position command's COMMAND_INT x/y are degE7, z its altitude in
        ``frame``."""
        try:
            r = self._command_result(m)
        except Exception as exc:  # noqa: BLE001 - a bad command must still be answered
            r = ML.MAV_RESULT_FAILED
            self._warn(f"command {m.command} failed: {exc!r}")
        self._ack(m, m.command, r)

    @staticmethod
    def _whole(x: float) -> int | None:
        """``x`` as an int if it is a finite whole number, else None (NaN is not 0)."""
        if not math.isfinite(x) or x != round(x):
            return None
        return int(x)

    def _command_result(self, m) -> int:
        c = m.command
        if c == ML.MAV_CMD_COMPONENT_ARM_DISARM:
            flag = self._whole(m.param1)
            if flag not in (0, 1):
                self.statustext(ML.MAV_SEVERITY_WARNING, "arm/disarm refused: param1 must be 1 or 0")
                return ML.MAV_RESULT_DENIED
            ok, text = self.v.arm(flag == 1, forced=m.param2 == FORCE_DISARM)
            self.statustext(ML.MAV_SEVERITY_INFO if ok else ML.MAV_SEVERITY_WARNING, text)
            return ML.MAV_RESULT_ACCEPTED if ok else ML.MAV_RESULT_DENIED
        if c == ML.MAV_CMD_DO_SET_MODE:
            return self._mode_result(*self._request_mode(m.param2, m.param3))
        if c == ML.MAV_CMD_DO_SET_STANDARD_MODE:
            std = self._whole(m.param1)
            if std not in MODE_OF_STANDARD:
                self.statustext(ML.MAV_SEVERITY_WARNING,
                                f"standard mode {m.param1:g} refused: not one of ours")
                return ML.MAV_RESULT_DENIED
            return self._mode_result(*self._change_mode(MODE_OF_STANDARD[std],
                                                        f"standard mode {std}"))
        if c == ML.MAV_CMD_NAV_RETURN_TO_LAUNCH:
            return self._mode_result(*self._change_mode(FlightMode.RTL, "RTL"))
        if c in POSITION_COMMANDS:
            return self._position_command(m)
        if c == CMD_ATTITUDE:
            reason = self.v.set_attitude_command(m.param1, m.param2, m.param3)
            if reason is not None:
                self.statustext(ML.MAV_SEVERITY_WARNING, f"refused: {reason}")
                return ML.MAV_RESULT_DENIED
            return ML.MAV_RESULT_ACCEPTED
        if c in GUIDED_COMMANDS:
            return self._guided_command(m)
        if c == ML.MAV_CMD_SET_MESSAGE_INTERVAL:
            msg_id = self._whole(m.param1)
            if msg_id not in self.intervals:
                return ML.MAV_RESULT_DENIED
            link = self._own_link(self._rx_addr)
            self._set_interval(link, msg_id, m.param2)
            self.oneshot.append((link, self._message_interval(link, msg_id)))
            return ML.MAV_RESULT_ACCEPTED
        if c == ML.MAV_CMD_GET_MESSAGE_INTERVAL:
            msg_id = self._whole(m.param1)
            if msg_id is None or not 0 <= msg_id <= 0xFFFF:   # MESSAGE_INTERVAL.message_id u16
                return ML.MAV_RESULT_DENIED
            link = self._link_of(self._rx_addr)
            self.oneshot.append((link, self._message_interval(link, msg_id)))
            return ML.MAV_RESULT_ACCEPTED
        if c == ML.MAV_CMD_REQUEST_MESSAGE:
            msg_id = self._whole(m.param1)
            if msg_id == MD.MAVLINK_MSG_ID_AVAILABLE_MODES:
                # param2: 0 (or unset, NaN) all modes, k the k-th
                msgs = self._available_modes(0 if math.isnan(m.param2) else self._whole(m.param2))
                if not msgs:
                    return ML.MAV_RESULT_DENIED       # no mode with that index
                self.oneshot.extend(msgs)
                return ML.MAV_RESULT_ACCEPTED
            if msg_id == ML.MAVLINK_MSG_ID_AUTOPILOT_VERSION:
                msg = self._autopilot_version()
            elif msg_id == ML.MAVLINK_MSG_ID_HEARTBEAT:
                msg = self._heartbeat()
            else:
                msg = self._build(msg_id, 0) if msg_id is not None else None
            if msg is None:
                # a stream without data yet (HOME_POSITION before the first GNSS fix)
                return (ML.MAV_RESULT_TEMPORARILY_REJECTED if msg_id in STREAM_DEFAULTS_S
                        else ML.MAV_RESULT_UNSUPPORTED)
            self.oneshot.append(msg)
            return ML.MAV_RESULT_ACCEPTED
        if c == ML.MAV_CMD_GET_HOME_POSITION:          # legacy form of REQUEST_MESSAGE 242
            msg = self._build(ML.MAVLINK_MSG_ID_HOME_POSITION, 0)
            if msg is None:
                return ML.MAV_RESULT_TEMPORARILY_REJECTED
            self.oneshot.append(msg)
            return ML.MAV_RESULT_ACCEPTED
        if c == ML.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES:
            self.oneshot.append(self._autopilot_version())
            return ML.MAV_RESULT_ACCEPTED
        if c == ML.MAV_CMD_DO_SET_MISSION_CURRENT:
            seq = self._whole(m.param1)
            ok, out = self.mission.set_current(-1 if seq is None else seq)
            self.mission_send(out)
            return ML.MAV_RESULT_ACCEPTED if ok else ML.MAV_RESULT_DENIED
        if c == ML.MAV_CMD_PREFLIGHT_STORAGE:
            # parameters are saved on every accepted set: "write" is already done
            return ML.MAV_RESULT_ACCEPTED if m.param1 == 1 else ML.MAV_RESULT_UNSUPPORTED
        return ML.MAV_RESULT_UNSUPPORTED

    def _mode_result(self, ok: bool, text: str) -> int:
        self.statustext(ML.MAV_SEVERITY_INFO if ok else ML.MAV_SEVERITY_WARNING, text)
        return ML.MAV_RESULT_ACCEPTED if ok else ML.MAV_RESULT_DENIED

    def _position_command(self, m: _Command) -> int:
        """DO_REPOSITION (192): param1 ground speed m/s (< 0 or NaN: keep), param5/6 (x/y)
        the point, param7 (z) its altitude (NaN: keep), m AMSL (COMMAND_LONG; COMMAND_INT
        frames GLOBAL(_INT); GLOBAL_RELATIVE_ALT(_INT): above home). DO_ORBIT (34): param1
        radius m (> 0 clockwise, < 0 counter-clockwise), param5/6 the centre (not given: here),
        param7 altitude as above; param2 (speed) and param3 (yaw) are ignored: the speed
        target is kept and the nose points along the flight path. Both fly in GUIDED."""
        name = "DO_REPOSITION" if m.command == ML.MAV_CMD_DO_REPOSITION else "DO_ORBIT"
        h = m.param7 if math.isfinite(m.param7) else None
        if m.frame >= 0 and m.frame not in FRAMES_AMSL + FRAMES_ABOVE_HOME:
            reason = f"frame {m.frame} not supported (GLOBAL or GLOBAL_RELATIVE_ALT)"
        elif h is not None and m.frame in FRAMES_ABOVE_HOME and self.home is None:
            reason = "no home yet for a relative altitude"
        else:
            reason = None
            if h is not None and m.frame in FRAMES_ABOVE_HOME:
                h += self.home[2]
        lat, lon = m.lat_deg, m.lon_deg
        if reason is None and m.command == ML.MAV_CMD_DO_REPOSITION:
            if not (math.isfinite(lat) and math.isfinite(lon)):
                reason = "a position is needed"
            else:
                spd = m.param1 if math.isfinite(m.param1) and m.param1 > 0.0 else None
                reason = self.v.go_to(lat, lon, h, spd)
        elif reason is None:
            if not (math.isfinite(lat) and math.isfinite(lon)):
                g, _ = self._gnss()
                lat, lon = float(g[G_LAT_DEG]), float(g[G_LON_DEG])
            reason = self.v.orbit(lat, lon, m.param1, h)
        if reason is not None:
            self.statustext(ML.MAV_SEVERITY_WARNING, f"{name} refused: {reason}")
            return ML.MAV_RESULT_DENIED
        self._info(f"{name} {lat:.5f} {lon:.5f} accepted")
        return ML.MAV_RESULT_ACCEPTED

    def _guided_command(self, m) -> int:
        """GUIDED's target commands (docs/fc.md section 5): accepted in GUIDED only, each
        target validated by ``set_guidance_targets`` (DENIED with a STATUSTEXT otherwise).

        GUIDED_CHANGE_SPEED (43000): param1 speed type (0 airspeed; 1 ground speed, the same
        here: no wind), param2 speed m/s. GUIDED_CHANGE_ALTITUDE (43001): param1 altitude m
        AMSL. GUIDED_CHANGE_HEADING (43002): param1 heading type (0 course over ground, 1
        heading: the course is flown either way), param2 deg from north. DO_CHANGE_ALTITUDE
        (186): param1 altitude m, param2 frame (MAV_FRAME_GLOBAL, 0, only). DO_CHANGE_SPEED
        (178): param1 speed type (0/1 air/ground speed; 2, 3 climb/descent refused), param2
        speed m/s (-1 or NaN: no change), param3 throttle (ignored: the speed loop owns it);
        DO_CHANGE_SPEED is accepted in every guidance mode (in MISSION it holds until a speed
        item of the mission changes it).
        The commands' rate/acceleration limits are ignored: the guidance's own (GA_HDOT_MAX,
        GH_CHIDOT_MAX, GS_ACC_MAX) apply."""
        c = m.command
        name = GUIDED_COMMANDS[c]
        if c == ML.MAV_CMD_DO_CHANGE_SPEED and self.v.modes.mode != FlightMode.GUIDED:
            if m.param1 not in (0, 1):
                reason = "speed type must be 0 or 1 (air/ground speed)"
            elif m.param2 == -1 or math.isnan(m.param2):
                return ML.MAV_RESULT_ACCEPTED          # no change
            else:
                reason = self.v.change_speed(m.param2)
            if reason is not None:
                self.statustext(ML.MAV_SEVERITY_WARNING, f"{name} refused: {reason}")
                return ML.MAV_RESULT_DENIED
            self._info(f"{name} {m.param2:.1f} m/s accepted")
            return ML.MAV_RESULT_ACCEPTED
        if self.v.modes.mode != FlightMode.GUIDED:
            self.statustext(ML.MAV_SEVERITY_WARNING, f"{name} refused: only in GUIDED")
            return ML.MAV_RESULT_DENIED
        h = chi = spd = None
        bad = None
        if c == ML.MAV_CMD_GUIDED_CHANGE_ALTITUDE:
            h = m.param1
        elif c == ML.MAV_CMD_DO_CHANGE_ALTITUDE:
            h = m.param1
            if m.param2 not in (0, ML.MAV_FRAME_GLOBAL):
                bad = "frame must be MAV_FRAME_GLOBAL (AMSL)"
        elif c == ML.MAV_CMD_GUIDED_CHANGE_HEADING:
            if m.param1 not in (0, 1):
                bad = "param1 heading type must be 0 or 1"
            elif not abs(m.param2) <= HEADING_LIMIT_DEG:
                bad = f"heading {m.param2:g} deg beyond +-{HEADING_LIMIT_DEG:g} deg"
            chi = math.radians(m.param2) if math.isfinite(m.param2) else math.nan
        elif c == ML.MAV_CMD_GUIDED_CHANGE_SPEED:
            if m.param1 not in (0, 1):
                bad = "param1 speed type must be 0 or 1"
            spd = m.param2
        else:                                  # DO_CHANGE_SPEED
            if m.param1 not in (0, 1):
                bad = "speed type must be 0 or 1 (air/ground speed)"
            if not (m.param2 == -1 or math.isnan(m.param2)):
                spd = m.param2
        reason = bad or self.v.set_guidance_targets(h_m=h, chi_rad=chi, V_m_s=spd)
        if reason is not None:
            self.statustext(ML.MAV_SEVERITY_WARNING, f"{name} refused: {reason}")
            return ML.MAV_RESULT_DENIED
        self._info(f"{name} {m.param1:g} {m.param2:g} accepted")
        return ML.MAV_RESULT_ACCEPTED

    def _info(self, text: str) -> None:
        """An accepted ground-station command in fc.log (INFO), rate-limited like STATUSTEXT."""
        if self.log is not None and self.log_limit.allow(time.monotonic(), 6, text):
            self.log.info(text)

    def _request_mode(self, param2: float, param3: float = 0.0) -> tuple[bool, str]:
        """DO_SET_MODE param2/param3, SET_MODE custom_mode (param3 0): decoded by
        fc/modes.py ``decode_mode_request`` (PX4 main/sub, or the hyfc number / HEARTBEAT
        value); no match is refused."""
        mode, why = decode_mode_request(param2, param3)
        if mode is None:
            return False, why
        return self._change_mode(mode, f"mode {param2:g}")

    def _change_mode(self, mode: FlightMode, what: str) -> tuple[bool, str]:
        """Ask the vehicle for ``mode`` (a decoded request; ``what`` names it in a refusal)
        through the mode changes' rate limit: a change to another mode takes a token;
        FAILSAFE (the operator's stop) never waits."""
        change = mode != self.v.modes.mode and mode != FlightMode.FAILSAFE
        if change and not self._mode_change_allowed(time.monotonic()):
            self.mode_refused += 1
            return False, (f"{what} refused: more than {MODE_BURST:g} changes at "
                           f"once or {MODE_RATE_HZ:g}/s")
        ok, text = self.v.request_mode(mode)
        if change and not ok:
            self._mode_tokens += 1.0          # a refused change costs nothing
        return ok, text

    def _mode_change_allowed(self, now_s: float) -> bool:
        """The mode changes' token bucket (MODE_BURST, MODE_RATE_HZ): True takes a token."""
        self._mode_tokens = min(MODE_BURST, self._mode_tokens
                                + (now_s - self._mode_refill_s) * MODE_RATE_HZ)
        self._mode_refill_s = now_s
        if self._mode_tokens < 1.0:
            return False
        self._mode_tokens -= 1.0
        return True

    @staticmethod
    def _set_interval(link: _Streams, msg_id: int, interval_us: float) -> None:
        if not math.isfinite(interval_us) or interval_us < 0:
            link.intervals[msg_id] = -1.0           # disabled
        elif interval_us == 0:
            link.intervals[msg_id] = STREAM_DEFAULTS_S[msg_id]
        else:
            link.intervals[msg_id] = max(interval_us * 1e-6, 0.01)   # at most 100 Hz
        link.next_due[msg_id] = 0.0

    def _message_interval(self, link: _Streams, msg_id: int):
        iv = link.intervals.get(msg_id)
        if msg_id == ML.MAVLINK_MSG_ID_HEARTBEAT:
            us = 1_000_000
        elif iv is None:
            us = 0   # not available
        elif iv < 0:
            us = -1
        else:
            us = int(round(iv * 1e6))
        return self.mav.message_interval_encode(msg_id, us)

    def _data_stream(self, m) -> None:
        ids = (tuple(self.intervals) if m.req_stream_id == ML.MAV_DATA_STREAM_ALL
               else DATA_STREAMS.get(m.req_stream_id, ()))
        if not ids:
            return
        link = self._own_link(self._rx_addr)
        for msg_id in ids:
            if m.start_stop == 0 or m.req_message_rate == 0:
                link.intervals[msg_id] = -1.0
            else:
                link.intervals[msg_id] = max(1.0 / m.req_message_rate, 0.01)
            link.next_due[msg_id] = 0.0

    # ------------------------------------------------------------------ mission
    def _mission_active(self) -> bool:
        return self.v.modes.mode == _MISSION_MODE

    def mission_send(self, outputs: list) -> None:
        """Send the outputs of fc/mission.py ``Mission`` (protocol replies, MISSION_CURRENT,
        MISSION_ITEM_REACHED, texts) at the next ``service``."""
        active = self._mission_active()
        for out in outputs:
            if out[0] == "text":
                self.statustext(out[1], out[2])
            else:
                self.oneshot.append(mission_encode(self.mav, self.mission, out, active))

    # ------------------------------------------------------------------ transmit
    def _heartbeat_fields(self) -> tuple[int, int, int]:
        """HEARTBEAT's (base_mode, custom_mode, system_status) of the vehicle now."""
        modes = self.v.modes
        base = ML.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
        if modes.armed:
            base |= ML.MAV_MODE_FLAG_SAFETY_ARMED
        if modes.law_active:
            base |= ML.MAV_MODE_FLAG_STABILIZE_ENABLED
        if modes.fs_cause or modes.data_lost:
            status = ML.MAV_STATE_CRITICAL
        elif modes.armed:
            status = ML.MAV_STATE_ACTIVE
        else:
            status = ML.MAV_STATE_STANDBY
        return base, custom_mode_of(modes.mode), status

    def _heartbeat(self):
        base, custom, status = self._heartbeat_fields()
        return self.mav.heartbeat_encode(ML.MAV_TYPE_FIXED_WING, ML.MAV_AUTOPILOT_GENERIC,
                                         base, custom, status)

    def _send_heartbeat(self) -> None:
        """HEARTBEAT to every output and peer (``send``, not logged: the .tlog has its own):
        framed by the compiled kernel for the default schedule's destinations when its link
        is unsigned (``_send_frame``), by the codec for the own-rate links."""
        if self.default.mav.signing.sign_outgoing or not self._fast_ok():
            self.send(self._heartbeat(), log=False)
            return
        n = self._frame_at(ML.MAVLINK_MSG_ID_HEARTBEAT, 0, -1, 0, self.mav.seq, 0)
        if not n:
            self.send(self._heartbeat(), log=False)
            return
        self.mav.seq = (self.mav.seq + 1) % 256             # as _pack
        self._send_frame(n)
        if self.links:
            msg = self._heartbeat()
            for link in self.links.values():
                self._send_on(link, msg)

    def _current_mode(self):
        """CURRENT_MODE (standard modes): the mode's standard mode (CRUISE: MAV_STANDARD_MODE
        CRUISE, the rest none); custom = intended = the mode."""
        mode = self.v.modes.mode
        cm = custom_mode_of(mode)
        return MD.MAVLink_current_mode_message(_standard_mode(mode, 0), cm, cm)

    def _available_modes(self, index: int | None) -> list:
        """AVAILABLE_MODES for every mode (``index`` 0) or the one at ``index`` (1-based)."""
        modes = list(FlightMode)
        picked = (range(1, len(modes) + 1) if index == 0
                  else [index] if index is not None and 1 <= index <= len(modes) else [])
        return [MD.MAVLink_available_modes_message(
                    len(modes), i, _standard_mode(modes[i - 1], 0),
                    custom_mode_of(modes[i - 1]), 0,
                    modes[i - 1].name.encode("ascii")) for i in picked]

    def _autopilot_version(self):
        # integer parameters: bytewise in the float (the spec's default, PX4, MAVSDK, QGC)
        caps = (ML.MAV_PROTOCOL_CAPABILITY_PARAM_FLOAT | ML.MAV_PROTOCOL_CAPABILITY_MAVLINK2
                | ML.MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE
                | ML.MAV_PROTOCOL_CAPABILITY_MISSION_INT)
        version = (0 << 24) | (1 << 16) | (0 << 8) | 0xFF   # 0.1.0 release
        return self.mav.autopilot_version_encode(caps, version, 0, 0, 0, b"hyfc\0\0\0\0",
                                                 [0] * 8, [0] * 8, 0, 0, 0)

    def _gnss(self):
        """(newest GNSS sample (fc/link.py G_*), fix type to report): the sample's own fix
        while it is younger than GNSS_STALE_S of plant time, NO_FIX (1) once stale, NO_GPS (0)
        before any. Sets ``home`` at the first 3D fix."""
        g = self.v.plant.gps
        fix = int(g[G_FIX])
        if fix and self.v.meas_stamp_us * 1e-6 - g[G_T_S] > GNSS_STALE_S:
            fix = ML.GPS_FIX_TYPE_NO_FIX
        if self.home is None and fix >= ML.GPS_FIX_TYPE_3D_FIX:
            self.home = (float(g[G_LAT_DEG]), float(g[G_LON_DEG]), float(g[G_ALT_M]))
            self.statustext(ML.MAV_SEVERITY_INFO, "home set: %.7f %.7f %.0f m"
                            % self.home)
            # announced at once (to ground stations and the .tlog), then at the stream rate
            self.oneshot.append(self._build(ML.MAVLINK_MSG_ID_HOME_POSITION, 0))
        return g, fix

    def _debug_vectors(self) -> list:
        """The vehicle's DEBUG_VECTs plus SIM_T: x = sim time of the newest plant frame (s;
        NaN before the first), so a ground station can map the time base (time_usec) to sim
        time in real time."""
        t = self.v.meas_stamp_us * 1e-6 if self.v.plant.counters.frames else math.nan
        return self.v.debug_vectors() + [(b"SIM_T", (t, 0.0, 0.0))]

    def _build(self, msg_id: int, cursor: int, us: int | None = None):
        """The streamed message ``msg_id`` (``cursor``: which named value or vector) at time
        base ``us`` (default: now, ``time_us``)."""
        v = self.v
        if msg_id == ML.MAVLINK_MSG_ID_HEARTBEAT:
            return self._heartbeat()
        if msg_id == MD.MAVLINK_MSG_ID_CURRENT_MODE:
            return self._current_mode()
        if msg_id == ML.MAVLINK_MSG_ID_MISSION_CURRENT:
            return mission_encode(self.mav, self.mission, ("current",), self._mission_active())
        if us is None:
            us = self.time_us()
        ms = (us // 1000) & 0xFFFFFFFF
        if msg_id == ML.MAVLINK_MSG_ID_SYS_STATUS:
            present = (ML.MAV_SYS_STATUS_SENSOR_3D_GYRO | ML.MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE
                       | ML.MAV_SYS_STATUS_SENSOR_DIFFERENTIAL_PRESSURE | ML.MAV_SYS_STATUS_SENSOR_GPS
                       | ML.MAV_SYS_STATUS_SENSOR_ANGULAR_RATE_CONTROL
                       | ML.MAV_SYS_STATUS_SENSOR_ATTITUDE_STABILIZATION
                       | ML.MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS | ML.MAV_SYS_STATUS_AHRS
                       | ML.MAV_SYS_STATUS_LOGGING)
            enabled = present
            if not v.modes.law_active:
                enabled &= ~(ML.MAV_SYS_STATUS_SENSOR_ANGULAR_RATE_CONTROL
                             | ML.MAV_SYS_STATUS_SENSOR_ATTITUDE_STABILIZATION)
            health = 0xFFFFFFFF & ~v.health_failed_bits()
            if self._gnss()[1] < ML.GPS_FIX_TYPE_3D_FIX:
                health &= ~ML.MAV_SYS_STATUS_SENSOR_GPS
            c = v.error_counts()
            return self.mav.sys_status_encode(present, enabled, health, v.load_permille(),
                                              65535, -1, -1, 0, min(c[0], 65535),
                                              min(c[1], 65535), min(c[2], 65535),
                                              min(c[3], 65535), min(c[4], 65535))
        m = v.meas
        if msg_id == ML.MAVLINK_MSG_ID_ATTITUDE:
            return self.mav.attitude_encode(ms, m[1], m[2], m[3], m[4], m[5], m[6])
        if msg_id == ML.MAVLINK_MSG_ID_AOA_SSA:
            return self.mav.aoa_ssa_encode(us, math.degrees(m[7]), math.degrees(m[8]))
        if msg_id == ML.MAVLINK_MSG_ID_VFR_HUD:
            hdg = int(round(math.degrees(m[13]))) % 360 if math.isfinite(m[13]) else 0
            return self.mav.vfr_hud_encode(m[9], m[12], hdg, v.throttle_percent(), m[10], m[11])
        if msg_id == ML.MAVLINK_MSG_ID_SERVO_OUTPUT_RAW:
            p = v.pwm_us
            return self.mav.servo_output_raw_encode(us & 0xFFFFFFFF, 0,
                                                    p[0], p[1], p[2], p[3], 0, 0, 0, 0)
        if msg_id == ML.MAVLINK_MSG_ID_DEBUG_VECT:
            vectors = self._debug_vectors()
            name, xyz = vectors[cursor % len(vectors)]
            return self.mav.debug_vect_encode(name, us, *xyz)
        if msg_id == ML.MAVLINK_MSG_ID_NAMED_VALUE_FLOAT:
            items = v.named_values()
            name, value = items[cursor % len(items)]
            return self.mav.named_value_float_encode(ms, name, value)
        if msg_id == ML.MAVLINK_MSG_ID_SYSTEM_TIME:
            return self.mav.system_time_encode(self.epoch_us + us, ms)
        if msg_id == ML.MAVLINK_MSG_ID_GPS_RAW_INT:
            g, fix = self._gnss()
            spd = math.hypot(g[G_VN], g[G_VE])
            vel = cm_s_u16(spd)                          # UINT16_MAX (unknown) above 655 m/s
            cog = (int(round(math.degrees(math.atan2(g[G_VE], g[G_VN])) * 100.0)) % 36000
                   if fix and spd > 0.0 else 65535)
            return self.mav.gps_raw_int_encode(
                us, fix, int(round(g[G_LAT_DEG] * 1e7)), int(round(g[G_LON_DEG] * 1e7)),
                int(round(g[G_ALT_M] * 1000.0)), 65535, 65535, vel, cog, int(g[G_SATS]), 0,
                _u32(g[G_HACC_M] * 1000.0), _u32(g[G_VACC_M] * 1000.0),
                _u32(g[G_SACC_M_S] * 1000.0), 0, 0)
        if msg_id == ML.MAVLINK_MSG_ID_GLOBAL_POSITION_INT:
            g, fix = self._gnss()
            if self.home is None:
                return None
            hdg = (int(round(math.degrees(m[M_HEADING]) * 100.0)) % 36000
                   if math.isfinite(m[M_HEADING]) else 65535)
            return self.mav.global_position_int_encode(
                ms, int(round(g[G_LAT_DEG] * 1e7)), int(round(g[G_LON_DEG] * 1e7)),
                int(round(g[G_ALT_M] * 1000.0)), int(round((g[G_ALT_M] - self.home[2]) * 1000.0)),
                cm_s_i16(g[G_VN]), cm_s_i16(g[G_VE]), cm_s_i16(g[G_VD]), hdg)
        if msg_id == ML.MAVLINK_MSG_ID_LOCAL_POSITION_NED:
            g, fix = self._gnss()
            if self.home is None:
                return None
            x, y, z = local_ned(self.home, g[G_LAT_DEG], g[G_LON_DEG], g[G_ALT_M])
            return self.mav.local_position_ned_encode(ms, x, y, z, g[G_VN], g[G_VE], g[G_VD])
        if msg_id == ML.MAVLINK_MSG_ID_EXTENDED_SYS_STATE:
            has_data = v.plant.counters.frames > 0 and not v.modes.data_lost
            return self.mav.extended_sys_state_encode(ML.MAV_VTOL_STATE_UNDEFINED,
                                                      landed_state(has_data, m[M_AIRSPEED]))
        if msg_id == ML.MAVLINK_MSG_ID_NAV_CONTROLLER_OUTPUT:
            nav = v.nav_controller_output()
            return None if nav is None else self.mav.nav_controller_output_encode(*nav)
        if msg_id == ML.MAVLINK_MSG_ID_HOME_POSITION:
            self._gnss()
            if self.home is None:
                return None
            lat, lon, alt = self.home
            return self.mav.home_position_encode(
                int(round(lat * 1e7)), int(round(lon * 1e7)), int(round(alt * 1000.0)),
                0.0, 0.0, 0.0, [1.0, 0.0, 0.0, 0.0], 0.0, 0.0, 0.0, us)
        return None

    def _stream_messages(self, msg_id: int) -> list:
        """Every message of one stream period for the .tlog (all named values and vectors)."""
        if msg_id == ML.MAVLINK_MSG_ID_HEARTBEAT:
            return [self._heartbeat()]
        if msg_id == ML.MAVLINK_MSG_ID_DEBUG_VECT:       # the vectors built once
            us = self.time_us()
            return [self.mav.debug_vect_encode(name, us, *xyz)
                    for name, xyz in self._debug_vectors()]
        n = len(self.v.named_values()) if msg_id == ML.MAVLINK_MSG_ID_NAMED_VALUE_FLOAT else 1
        return [m for m in (self._build(msg_id, i) for i in range(n)) if m is not None]

    def _service_log(self) -> None:
        """The .tlog's streams at LOG_STREAMS_S rates of the time base (sim time in
        lockstep): due messages are written with the log's codec, stamped with the time base.
        Scheduled in whole microseconds, so a 0.1 s stream falls on the 0.1 s frames. The
        schedule is stepped by a compiled call on the time base's cell (lockstep: the newest
        frame's stamp; no Python int for it, nothing made on the frames where nothing is due);
        a time base or schedule beyond the cells' range is stepped on Python ints."""
        if self.tlog is None:
            return
        t_at = self._log_time_at() if self._log_big is None else 0
        if not t_at:
            self._service_log_py()
            return
        if not GF.log_walk_p(t_at, self._log_st_p, self._log_iv_p, len(self._log_ids),
                             self._log_flags_p):
            return
        ids, flags = self._log_ids, self._log_flags
        i, n = 0, len(ids)
        while i < n:                        # (an index loop: no iterator object)
            if flags.item(i):
                self._log_period(ids[i], t_at)
            i += 1

    def _log_time_at(self) -> int:
        """The address of an int64 cell holding the time base for the .tlog's walk (the
        newest frame's stamp cell in lockstep, else ``_log_tb``), 0 beyond the cells' range."""
        if self.sim_time and self._stamp_at is not None and not self.v.meas_stamp_big:
            return self._stamp_at
        us = self.time_us()
        if not -GF.LOG_SAFE_US < us < GF.LOG_SAFE_US:
            return 0
        self._log_tb[0] = us
        return self._log_tb_p

    def _log_period(self, msg_id: int, t_at: int) -> None:
        """Write one stream period of ``msg_id`` to the .tlog, stamped with the time base at
        the int64 cell ``t_at``."""
        if msg_id in FAST_STREAMS and self._fast_ok():
            self._log_fast(msg_id, t_at)
        elif msg_id == ML.MAVLINK_MSG_ID_HOME_POSITION and self.home is None:
            return      # (no message: ``service`` looked for the first fix before the streams;
            #            building the empty list took 16 blocks every 5 s, issue 24)
        else:
            t_us = int64_at(t_at)
            for msg in self._stream_messages(msg_id):
                self._log_msg(msg, t_us)

    def _service_log_py(self) -> None:
        """``_service_log``'s walk on Python ints (the schedule in ``_log_big`` or the time
        base beyond the cells' range): the same steps as ``GF.log_walk_p``, the messages built
        by the codec."""
        k = self._log_big or self._log_st.tolist()
        t_us = self.time_us()
        n = len(self._log_ids)
        if t_us < k[GF.LOG_LAST]:           # the plant restarted: the schedule starts over
            k[GF.LOG_DUE:] = [t_us] * n
            k[GF.LOG_NEXT] = t_us
        k[GF.LOG_LAST] = t_us
        if t_us >= k[GF.LOG_NEXT]:
            nxt = None
            for i, msg_id in enumerate(self._log_ids):
                due = k[GF.LOG_DUE + i]
                if t_us >= due:
                    for msg in self._stream_messages(msg_id):
                        self._log_msg(msg, t_us)
                    iv_us = int(self._log_iv[i])
                    due = due + iv_us if due + iv_us > t_us else t_us + iv_us
                    k[GF.LOG_DUE + i] = due
                if nxt is None or due < nxt:
                    nxt = due
            k[GF.LOG_NEXT] = nxt
        if all(-GF.LOG_SAFE_US < v < GF.LOG_SAFE_US for v in k):
            self._log_st[:] = k
            self._log_big = None
        else:
            self._log_big = k

    def service(self, now_s: float) -> int:
        """Send what is due (at most ``max_tx`` messages) on the wall clock ``now_s``, and write
        the .tlog's streams due on the time base. Returns how many were sent."""
        if self.home is None and self.v.plant.gps_samples:
            self._gnss()                   # home = the first fix, taken when it arrives
        if self._echo_wait:
            self._answer_saved()
        self._service_log()
        mission_out = self.mission.tick(now_s)
        if mission_out:
            self.mission_send(mission_out)
        if (now_s < self.wall_due and not self.oneshot and not self.text_queue
                and not self.param_queue and self.list_next < 0
                and not self.logs.busy and not self.ftp.busy
                and self.v.modes.mode == self.last_mode_sent):
            return 0                       # nothing due, nothing queued: most frames
        sent = 0
        if now_s >= self.next_heartbeat:
            nxt = self.next_heartbeat + 1.0          # (``max`` makes an argument iterator)
            self.next_heartbeat = nxt if nxt > now_s + 0.5 else now_s + 0.5
            self._send_heartbeat()
            self._expire_peers(now_s)
            self._summaries()
            sent += 1
        if self.v.modes.mode != self.last_mode_sent:       # CURRENT_MODE on every change
            self.last_mode_sent = self.v.modes.mode
            self.oneshot.append(self._current_mode())
        while self.oneshot and sent < self.max_tx:
            item = self.oneshot.popleft()
            if isinstance(item, tuple):                    # (link, msg): for one link only
                self._send_on(*item)
                if self.tlog is not None:
                    self._log_msg(item[1])
            elif item is not None:
                self.send(item)
            sent += 1
        if self.text_queue and sent < self.max_tx:
            sev, text, text_id, chunk = self.text_queue.popleft()
            self.send(self.mav.statustext_encode(sev, text, text_id, chunk))
            sent += 1
        n_param = 0
        while n_param < 2 and sent < self.max_tx:
            if self.param_queue:
                idx = self.param_queue.popleft()
            elif self.list_next >= 0:
                idx = self.list_next
                self.list_next = idx + 1 if idx + 1 < len(self.v.params) else -1
            else:
                break
            self.send(self._param_value(idx))
            n_param += 1
            sent += 1
        if self.logs.busy or self.ftp.busy:
            for svc in (self.logs, self.ftp):             # streamed answers, paced
                if svc.busy and sent < self.max_tx:
                    out = svc.take(now_s, self.max_tx - sent)
                    self._service_out(out)
                    sent += len(out)
        sent = self._streams(self.default, now_s, sent)
        if self.links:
            for link in list(self.links.values()):
                sent = self._streams(link, now_s, sent)
        self.wall_due = self._next_wall_due()
        return sent

    def _next_wall_due(self) -> float:
        """The earliest wall-clock time the heartbeat or an enabled stream of any schedule is
        due (a stream left due by ``max_tx`` makes it the past: the next call walks again)."""
        due = self._link_due(self.default, self.next_heartbeat)
        if self.links:
            for link in self.links.values():
                due = self._link_due(link, due)
        return due

    @staticmethod
    def _link_due(link: _Streams, due: float) -> float:
        """The earlier of ``due`` and the next due time of ``link``'s enabled streams (an index
        loop: no iterator object per call)."""
        next_due, intervals = link.next_due, link.intervals
        i, n = 0, len(STREAM_IDS)
        while i < n:
            msg_id = STREAM_IDS[i]
            i += 1
            if intervals[msg_id] >= 0.0 and next_due[msg_id] < due:
                due = next_due[msg_id]
        return due

    def _streams(self, link: _Streams, now_s: float, sent: int) -> int:
        """Send the streamed messages of one schedule that are due; returns ``sent`` updated.
        FAST_STREAMS on the default schedule, unsigned, go through the compiled framing
        (``_frame_stream``, ``_send_frame``)."""
        fast = (link is self.default and not link.mav.signing.sign_outgoing
                and self._fast_ok())
        i, n_ids = 0, len(STREAM_IDS)
        while i < n_ids:                    # (an index loop: no iterator object per walk)
            msg_id = STREAM_IDS[i]
            i += 1
            if sent >= self.max_tx:
                break
            iv = link.intervals[msg_id]
            if iv < 0 or now_s < link.next_due[msg_id]:
                continue
            if msg_id == ML.MAVLINK_MSG_ID_NAMED_VALUE_FLOAT:
                n_items = self._n_named_values()
                step = iv / n_items
                cursor = link.nv_cursor
                # wrapped at a multiple of the count (which is fixed): ``cursor % n_items``
                # unchanged, the cursor a small int (CPython's cached ints: none made per message)
                # (``max`` made an argument iterator: a block per message)
                wrap = 256 // n_items
                link.nv_cursor = (cursor + 1) % (n_items * (wrap if wrap > 1 else 1))
            elif msg_id == ML.MAVLINK_MSG_ID_DEBUG_VECT:
                n_vec = self._n_debug_vectors()
                step = iv / n_vec
                cursor = link.dv_cursor
                link.dv_cursor = (cursor + 1) % DV_CURSOR_WRAP
            else:
                step = iv
                cursor = 0
            nd = link.next_due[msg_id] + step
            link.next_due[msg_id] = nd if nd > now_s else now_s + step
            if fast and msg_id in FAST_STREAMS:
                if self._none_due(msg_id):
                    continue
                mav = link.mav
                k = (cursor % n_vec if msg_id == ML.MAVLINK_MSG_ID_DEBUG_VECT
                     else cursor % n_items if msg_id == ML.MAVLINK_MSG_ID_NAMED_VALUE_FLOAT
                     else 0)
                n = self._frame_at(msg_id, k, -1, 0, mav.seq, self._time_at())
                if n:
                    mav.seq = (mav.seq + 1) % 256       # as _pack
                    self._send_frame(n)
                    sent += 1
                    continue
            if msg_id == ML.MAVLINK_MSG_ID_HOME_POSITION and self.home is None:
                continue        # (``_build`` gives None: ``service`` looked for the first fix)
            msg = self._build(msg_id, cursor)
            if msg is not None:
                self._send_on(link, msg)
                sent += 1
        return sent


def _u32(x: float) -> int:
    """A non-negative finite value as u32 (rounded, saturated); 0 otherwise."""
    return min(int(round(x)), 0xFFFFFFFF) if math.isfinite(x) and x > 0.0 else 0
