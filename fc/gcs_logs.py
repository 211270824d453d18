"""fc/gcs_logs.py - the MAVLink log download service (LOG_REQUEST_*), serving the run's .tlog.

mavlink.io "Onboard Log Download" (ArduPilot's and PX4's log handler), for one log, id 1:
the flight log of this run (``fc.tlog``, docs/fc.md section 10), which is still being written.

- LOG_REQUEST_LIST(start, end) -> LOG_ENTRY(id 1, num_logs 1, last_log_num 1, time_utc = the
  fc's start (s, UTC), size = the bytes on disk now) when 1 is in [start, end]; a run without a
  log answers LOG_ENTRY(0, 0, 0, 0, 0) ("No logs"). The size is a snapshot (the file keeps
  growing), taken by a list while no transfer runs and held until LOG_REQUEST_END, so a
  download has the length its list said.
- LOG_REQUEST_DATA(id 1, ofs, count) -> LOG_DATA(ofs, count <= 90, data) from ``ofs`` up to
  min(ofs + count, size): streamed, at most ``per_call`` messages per ``take`` and
  ``rate_hz`` on average (a token bucket on the wall clock). The last message has count < 90;
  when the end falls on a multiple of 90, one more with count 0 ends it (MAVProxy's end test).
  A request at or past the end answers count 0 at once. The requests of a download are queued
  (at most MAX_RANGES, a repeat once) and served in order: a ground station that lost
  messages asks for its gaps in a burst of requests (MAVProxy: up to 20), and each is served
  (ArduPilot serves only the last one). Such a burst says the station could not keep up (its
  socket buffer overflowed while it was not scheduled): the rate halves, once per burst, down
  to RATE_MIN_HZ. A request for the whole log (offset 0 to the end) starts a new download at
  RATE_HZ; a request from another peer drops the ranges queued for the previous one. Another id: nothing is sent (as ArduPilot).
- LOG_REQUEST_END: stops a transfer, drops the size snapshot.
- LOG_ERASE: refused (the running flight's log is never erased), with a STATUSTEXT.

The file is read with ``os.pread`` on a read-only descriptor, opened at the first data request,
at most ``per_call`` x 90 bytes per call, from the GCS link's service (the housekeeping side),
never from the frame path. Calls return outputs for the caller (fc/gcs.py) to send:
``(peer, message)`` to one peer, ``("text", severity, text)`` a STATUSTEXT.
"""
from __future__ import annotations

import os
from collections import deque

from fc.link import mavlink as ML

__all__ = ["LogService", "Pacer", "MSG_IDS", "LOG_ID", "CHUNK", "RATE_HZ", "PER_CALL", "MAX_RANGES"]

LOG_ID = 1                # the one log: this run's fc.tlog
CHUNK = 90                # LOG_DATA.data is uint8_t[90]
RATE_HZ = 1000.0          # LOG_DATA messages per second on average (90 kB/s)
PER_CALL = 4              # ... and at most this many per ``take``
MAX_RANGES = 32           # requested ranges queued (MAVProxy asks for up to 20 gaps at once)
RATE_MIN_HZ = 100.0       # the rate halves on each burst of gap requests, down to this

MSG_IDS = frozenset({
    ML.MAVLINK_MSG_ID_LOG_REQUEST_LIST, ML.MAVLINK_MSG_ID_LOG_REQUEST_DATA,
    ML.MAVLINK_MSG_ID_LOG_REQUEST_END, ML.MAVLINK_MSG_ID_LOG_ERASE,
})


class Pacer:
    """A token bucket on the wall clock: ``rate_hz`` messages per second on average, at most
    ``per_call`` at once (the streamed answers of this service and of fc/gcs_ftp.py)."""

    __slots__ = ("rate_hz", "per_call", "tokens", "t_last")

    def __init__(self, rate_hz: float = RATE_HZ, per_call: int = PER_CALL) -> None:
        self.rate_hz = float(rate_hz)
        self.per_call = int(per_call)
        self.tokens = float(per_call)
        self.t_last: float | None = None

    def allowance(self, now_s: float, budget: int) -> int:
        """How many messages may go now (at most ``budget``); ``spend`` what was sent."""
        if self.t_last is not None:
            self.tokens = min(float(self.per_call),
                              self.tokens + max(0.0, now_s - self.t_last) * self.rate_hz)
        self.t_last = now_s
        return max(0, min(budget, int(self.tokens)))

    def spend(self, n: int) -> None:
        self.tokens -= n


class LogService:
    """The log handler's state: the size snapshot and the queued ranges of the transfer."""

    def __init__(self, path: str | None, time_utc_s: int, rate_hz: float = RATE_HZ,
                 per_call: int = PER_CALL) -> None:
        self.path = path
        self.time_utc_s = int(time_utc_s)
        self.pacer = Pacer(rate_hz, per_call)
        self.size: int | None = None      # the snapshot of the log's length (bytes)
        self.fd: int | None = None
        self.peer = None                  # the transfer's requester
        # the requested ranges [ofs, end, end_marker], served in order; ofs advances as sent
        self.ranges: deque[list] = deque(maxlen=MAX_RANGES)
        self.rate_hz = float(rate_hz)     # the rate a new download starts at
        self.t_slowed = -1e9              # when the rate was last halved (s, wall clock)
        self.sent = 0                     # LOG_DATA messages sent (counter)
        self.gap_requests = 0             # requests for ranges a station lost (counter)

    @property
    def busy(self) -> bool:
        """A transfer is running (``take`` has messages to give)."""
        return bool(self.ranges)

    def _disk_size(self) -> int:
        try:
            return os.stat(self.path).st_size
        except OSError:
            return 0

    def handle(self, m, peer, now_s: float) -> list:
        """Handle one LOG_* request from ``peer``; returns the immediate outputs."""
        t = m.get_msgId()
        if t == ML.MAVLINK_MSG_ID_LOG_REQUEST_LIST:
            if self.path is None:
                return [(peer, ML.MAVLink_log_entry_message(0, 0, 0, 0, 0))]
            if not m.start <= LOG_ID <= m.end:
                return []
            if self.size is None or not self.busy:     # no transfer running: a fresh size
                self.size = self._disk_size()
            return [(peer, ML.MAVLink_log_entry_message(LOG_ID, 1, LOG_ID, self.time_utc_s,
                                                        self.size))]
        if t == ML.MAVLINK_MSG_ID_LOG_REQUEST_DATA:
            if self.path is None or m.id != LOG_ID:
                return []
            if self.size is None:
                self.size = self._disk_size()
            end = min(self.size, m.ofs + m.count)
            if m.ofs >= end:
                return [(peer, self._data(m.ofs, b""))]
            if peer != self.peer:               # another station: its own download
                self.ranges.clear()
                self.peer = peer
            if m.ofs == 0 and end == self.size:
                # a new download (the whole log): forget the old ranges, start at full rate
                self.ranges.clear()
                self.pacer.rate_hz = self.rate_hz
            else:
                # a range the station lost: it could not take the rate; halve it once per
                # burst of such requests (MAVProxy sends them together), down to RATE_MIN_HZ
                self.gap_requests += 1
                if now_s - self.t_slowed > 0.5:
                    self.t_slowed = now_s
                    self.pacer.rate_hz = max(RATE_MIN_HZ, self.pacer.rate_hz * 0.5)
            start, end = int(m.ofs), int(end)
            if not any(r[3] == start and r[1] == end for r in self.ranges):   # repeats: once
                self.ranges.append([start, end, end % CHUNK == 0 and end == self.size, start])
            return []
        if t == ML.MAVLINK_MSG_ID_LOG_REQUEST_END:
            self.ranges.clear()
            self.size = None
            return []
        if t == ML.MAVLINK_MSG_ID_LOG_ERASE:
            return [("text", ML.MAV_SEVERITY_WARNING,
                     "log erase refused: the flight log of a running fc is kept")]
        return []

    def _data(self, ofs: int, data: bytes):
        self.sent += 1
        return ML.MAVLink_log_data_message(LOG_ID, ofs & 0xFFFFFFFF, len(data),
                                           list(data) + [0] * (CHUNK - len(data)))

    def take(self, now_s: float, budget: int) -> list:
        """The next LOG_DATA messages of the queued ranges, ``(peer, message)``: at most
        ``budget``, ``per_call`` and what the rate allows since the last call."""
        if not self.ranges:
            return []
        n = self.pacer.allowance(now_s, budget)
        out = []
        if n <= 0:
            return out
        if self.fd is None:
            try:
                self.fd = os.open(self.path, os.O_RDONLY)
            except OSError:
                self.ranges.clear()
                return [("text", ML.MAV_SEVERITY_WARNING, "log download: cannot read fc.tlog")]
        peer = self.peer
        while len(out) < n and self.ranges:
            rng = self.ranges[0]
            ofs, end, marker, _start = rng
            if ofs >= end:                   # done: the count-0 end marker if it needs one
                self.ranges.popleft()
                if marker:
                    out.append((peer, self._data(ofs, b"")))
                continue
            try:
                data = os.pread(self.fd, min(CHUNK, end - ofs), ofs)
            except OSError:
                data = b""
            if not data:                     # shorter on disk than listed: end here
                self.ranges.popleft()
                out.append((peer, self._data(ofs, b"")))
                continue
            out.append((peer, self._data(ofs, data)))
            rng[0] = ofs + len(data)
            if rng[0] >= end and not marker:
                self.ranges.popleft()
        self.pacer.spend(len(out))
        return out

    def close(self) -> None:
        if self.fd is not None:
            os.close(self.fd)
            self.fd = None
