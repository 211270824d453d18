"""fc/mission.py - the MAVLink mission protocol as a state machine (no I/O, no clock).

The mission microservice (mavlink.io "Mission Protocol") for ``mission_type`` MISSION:

- upload: GCS MISSION_COUNT(n) -> we MISSION_REQUEST_INT(0) ... each item MISSION_ITEM_INT
  (or the legacy MISSION_ITEM, converted) -> next request ... -> MISSION_ACK(ACCEPTED). An
  unanswered request is sent again after RETRY_S, at most RETRIES times; then the upload is
  cancelled (MISSION_ACK OPERATION_CANCELLED). Items go to a staging bank; the stored mission
  is replaced by it only when the last item is accepted, so a failed or cancelled upload
  loses nothing.
- download: MISSION_REQUEST_LIST -> MISSION_COUNT(n); MISSION_REQUEST_INT / MISSION_REQUEST
  (seq) -> MISSION_ITEM_INT(seq) (always the INT form, as PX4 answers both); the GCS's final
  MISSION_ACK ends it. A request beyond the count gets MISSION_ACK INVALID_SEQUENCE.
- MISSION_CLEAR_ALL -> MISSION_ACK(ACCEPTED), no mission.
- MISSION_SET_CURRENT / MAV_CMD_DO_SET_MISSION_CURRENT: the active item (``set_current``).
- ``advance(seq)``: the navigator reached item ``seq`` -> MISSION_ITEM_REACHED and
  MISSION_CURRENT.

Accepted items (anything else: MAV_MISSION_UNSUPPORTED):

- MAV_CMD_NAV_WAYPOINT (16): x = latitude, y = longitude (degE7), z = altitude (m) in frame
  GLOBAL (0) / GLOBAL_INT (5): metres above mean sea level (the plant's GNSS altitude), or
  GLOBAL_RELATIVE_ALT (3) / GLOBAL_RELATIVE_ALT_INT (6): metres above home (the first GNSS
  fix, HOME_POSITION). Other frames: MAV_MISSION_UNSUPPORTED_FRAME. The item is stored as
  sent (download returns it unchanged); the navigator resolves the frame when flying it.
  param1 (hold time), param3 (pass radius), param4 (yaw) are stored and not used: a vehicle
  at Mach 7 neither holds nor yaws at a point; param2 (acceptance radius, m) > 0 overrides
  the navigator's default for that waypoint.
- MAV_CMD_DO_CHANGE_SPEED (178): param1 speed type 0 (airspeed) or 1 (ground speed: the
  same with no wind), param2 speed (m/s, > 0; -1 = no change), param3 throttle (ignored: the
  guidance owns it). Applied when the sequence reaches it, then the sequence moves on.

Storage is allocated once: two banks of ``capacity`` items (active and staging) swapped on a
successful upload. Calls return a list of outputs ``(kind, *fields)`` for the caller to
encode and send (``encode``): ``("count", ts, tc, n)``, ``("request", ts, tc, seq)``,
``("item", ts, tc, seq)``, ``("ack", ts, tc, result, mission_type)``, ``("current",)``,
``("reached", seq)``, ``("text", severity, text)``.
"""
from __future__ import annotations

import math

import numpy as np

from fc.link import mavlink as ML

__all__ = ["Mission", "encode", "CAPACITY", "RETRY_S", "RETRIES", "MSG_IDS",
           "CMD_WAYPOINT", "CMD_CHANGE_SPEED", "FRAMES_MSL", "FRAMES_REL"]

CAPACITY = 64          # items
RETRY_S = 1.0          # a request not answered within this is sent again (s)
RETRIES = 5            # ... at most this many times, then the upload is cancelled
CMD_WAYPOINT = ML.MAV_CMD_NAV_WAYPOINT
CMD_CHANGE_SPEED = ML.MAV_CMD_DO_CHANGE_SPEED
FRAMES_MSL = (ML.MAV_FRAME_GLOBAL, ML.MAV_FRAME_GLOBAL_INT)
FRAMES_REL = (ML.MAV_FRAME_GLOBAL_RELATIVE_ALT, ML.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT)
MISSION = ML.MAV_MISSION_TYPE_MISSION

#: message ids the mission module handles (fc/gcs.py dispatches these to ``Mission.handle``)
MSG_IDS = frozenset({
    ML.MAVLINK_MSG_ID_MISSION_COUNT, ML.MAVLINK_MSG_ID_MISSION_ITEM_INT,
    ML.MAVLINK_MSG_ID_MISSION_ITEM, ML.MAVLINK_MSG_ID_MISSION_REQUEST_LIST,
    ML.MAVLINK_MSG_ID_MISSION_REQUEST_INT, ML.MAVLINK_MSG_ID_MISSION_REQUEST,
    ML.MAVLINK_MSG_ID_MISSION_CLEAR_ALL, ML.MAVLINK_MSG_ID_MISSION_SET_CURRENT,
    ML.MAVLINK_MSG_ID_MISSION_ACK,
})

# item fields: columns of the int and float arrays of a bank
I_CMD, I_FRAME, I_AUTO, I_X, I_Y, I_N = range(6)          # x, y: degE7
F_P1, F_P2, F_P3, F_P4, F_Z, F_N = range(6)               # params, z (m)


class _Bank:
    """``capacity`` mission items in two preallocated arrays."""

    __slots__ = ("ints", "flts", "count")

    def __init__(self, capacity: int) -> None:
        self.ints = np.zeros((capacity, I_N), dtype=np.int64)
        self.flts = np.zeros((capacity, F_N))
        self.count = 0


def _check_item(cmd: int, frame: int, p: tuple, x: int, y: int, z: float) -> int:
    """MAV_MISSION_ACCEPTED or the MAV_MISSION_* error of one item."""
    if cmd == CMD_WAYPOINT:
        if frame not in FRAMES_MSL + FRAMES_REL:
            return ML.MAV_MISSION_UNSUPPORTED_FRAME
        if not -900_000_000 <= x <= 900_000_000:
            return ML.MAV_MISSION_INVALID_PARAM5_X
        if not -1_800_000_000 <= y <= 1_800_000_000:
            return ML.MAV_MISSION_INVALID_PARAM6_Y
        if not math.isfinite(z):
            return ML.MAV_MISSION_INVALID_PARAM7
        if not (math.isfinite(p[1]) and p[1] >= 0.0):
            return ML.MAV_MISSION_INVALID_PARAM2
        return ML.MAV_MISSION_ACCEPTED
    if cmd == CMD_CHANGE_SPEED:
        if p[0] not in (0.0, 1.0):
            return ML.MAV_MISSION_INVALID_PARAM1
        if not (math.isfinite(p[1]) and (p[1] > 0.0 or p[1] == -1.0)):
            return ML.MAV_MISSION_INVALID_PARAM2
        return ML.MAV_MISSION_ACCEPTED
    return ML.MAV_MISSION_UNSUPPORTED


class Mission:
    """The stored mission and the protocol's transactions. Single-threaded, no clock: every
    call that can time out takes ``now_s`` (any monotonic seconds, the caller's clock).

    Attributes
    ----------
    count : number of stored items (0: no mission).
    current : the active item's sequence number (MISSION_CURRENT.seq).
    finished : True once the last item was reached (MISSION_STATE_COMPLETE).
    version : bumped whenever the stored mission or the current item changes other than by
        ``advance`` (the navigator restarts its leg on it).
    generation : bumped whenever the stored items change (an upload completed, a clear, an
        empty upload); not by MISSION_SET_CURRENT. MISSION mode holds when it changes under
        it (fc/mission_mode.py).
    """

    def __init__(self, capacity: int = CAPACITY, retry_s: float = RETRY_S,
                 retries: int = RETRIES) -> None:
        self.capacity = int(capacity)
        self.retry_s = float(retry_s)
        self.retries = int(retries)
        self._active = _Bank(self.capacity)
        self._staging = _Bank(self.capacity)
        self.current = 0
        self.finished = False
        self.version = 0
        self.generation = 0
        self.uploads_ok = 0
        self.uploads_failed = 0
        # upload in progress: partner (sysid, compid) or None, next seq, last request time, tries
        self._partner: tuple[int, int] | None = None
        self._next = 0
        self._sent_s = 0.0
        self._tries = 0
        #: the guidance's altitude limits at upload: () -> (lowest m MSL, highest m MSL, home
        #: altitude m MSL or None); None: not checked (the caller sets it, fc/app.py)
        self.alt_limits_m = None

    # ------------------------------------------------------------------ stored items
    @property
    def count(self) -> int:
        return self._active.count

    @property
    def uploading(self) -> bool:
        return self._partner is not None

    def item(self, seq: int) -> dict:
        """Item ``seq`` of the stored mission as a dict of MISSION_ITEM_INT fields."""
        if not 0 <= seq < self._active.count:
            raise IndexError(f"no mission item {seq} (count {self._active.count})")
        i, f = self._active.ints[seq], self._active.flts[seq]
        return {"seq": seq, "command": int(i[I_CMD]), "frame": int(i[I_FRAME]),
                "autocontinue": int(i[I_AUTO]), "param1": float(f[F_P1]),
                "param2": float(f[F_P2]), "param3": float(f[F_P3]), "param4": float(f[F_P4]),
                "x": int(i[I_X]), "y": int(i[I_Y]), "z": float(f[F_Z])}

    def state(self) -> int:
        """MISSION_CURRENT.mission_state (MISSION_STATE_*) apart from ACTIVE/PAUSED, which
        depend on the mode: the caller passes ``active`` to ``current_fields``."""
        if self._active.count == 0:
            return ML.MISSION_STATE_NO_MISSION
        return ML.MISSION_STATE_COMPLETE if self.finished else ML.MISSION_STATE_NOT_STARTED

    def current_fields(self, active: bool) -> tuple[int, int, int, int]:
        """(seq, total, mission_state, mission_mode) of MISSION_CURRENT; ``active``: the
        vehicle flies the mission (MISSION mode)."""
        st = self.state()
        if active and st == ML.MISSION_STATE_NOT_STARTED:
            st = ML.MISSION_STATE_ACTIVE
        return self.current, self._active.count, st, 1 if active else 0

    # ------------------------------------------------------------------ protocol
    def handle(self, m, now_s: float) -> list:
        """One mission message ``m`` (a decoded MAVLink message with the spec's field names,
        addressed to us) at time ``now_s``. Returns the outputs to send."""
        t = m.get_type()
        src = (m.get_srcSystem(), m.get_srcComponent())
        mtype = getattr(m, "mission_type", MISSION)
        if t == "MISSION_REQUEST_LIST":
            return [("count", *src, self._active.count if mtype == MISSION else 0, mtype)]
        if t == "MISSION_COUNT":
            return self._on_count(src, int(m.count), mtype, now_s)
        if t in ("MISSION_ITEM_INT", "MISSION_ITEM"):
            return self._on_item(src, m, t == "MISSION_ITEM_INT", mtype, now_s)
        if t in ("MISSION_REQUEST_INT", "MISSION_REQUEST"):
            if mtype != MISSION or not 0 <= m.seq < self._active.count:
                return [("ack", *src, ML.MAV_MISSION_INVALID_SEQUENCE, mtype)]
            return [("item", *src, int(m.seq))]
        if t == "MISSION_CLEAR_ALL":
            if mtype not in (MISSION, ML.MAV_MISSION_TYPE_ALL):
                return [("ack", *src, ML.MAV_MISSION_ACCEPTED, mtype)]   # none stored: done
            out = self._cancel(ML.MAV_MISSION_OPERATION_CANCELLED)
            self._active.count = 0
            self._changed(items=True)
            return out + [("ack", *src, ML.MAV_MISSION_ACCEPTED, mtype), ("current",)]
        if t == "MISSION_SET_CURRENT":
            return self.set_current(int(m.seq))[1]
        return []            # MISSION_ACK ending a download: nothing to do

    def set_current(self, seq: int) -> tuple[bool, list]:
        """Make item ``seq`` the active one. Returns (ok, outputs)."""
        if not 0 <= seq < self._active.count:
            return False, [("text", ML.MAV_SEVERITY_WARNING,
                            f"mission: no item {seq} (count {self._active.count})")]
        self.current = seq
        self._changed()
        return True, [("current",)]

    def advance(self, seq: int) -> list:
        """The navigator reached (or applied) item ``seq``: report it and make the next one
        current, or mark the mission finished after the last. Returns the outputs."""
        if seq != self.current or self.finished or not 0 <= seq < self._active.count:
            return []
        if seq + 1 < self._active.count:
            self.current = seq + 1
        else:
            self.finished = True
        return [("reached", seq), ("current",)]

    def restart(self) -> list:
        """Fly the mission again from item 0 (on entering MISSION after the end)."""
        self.current = 0
        self._changed()
        return [("current",)]

    def restore(self, items: list[dict], current: int, finished: bool = False) -> str | None:
        """Make ``items`` (dicts of MISSION_ITEM_INT fields, as ``item`` gives them) the stored
        mission, at item ``current`` (a mission kept across a restart, fc/mission_store.py).
        Every item is checked as at upload; None on success, else why nothing was stored."""
        if len(items) > self.capacity:
            return f"{len(items)} items, capacity {self.capacity}"
        b = self._staging
        for seq, it in enumerate(items):
            p = (float(it["param1"]), float(it["param2"]), float(it["param3"]),
                 float(it["param4"]))
            x, y, z = int(it["x"]), int(it["y"]), float(it["z"])
            result = _check_item(int(it["command"]), int(it["frame"]), p, x, y, z)
            if result != ML.MAV_MISSION_ACCEPTED:
                return f"item {seq} refused ({result})"
            b.ints[seq] = (int(it["command"]), int(it["frame"]), int(it["autocontinue"]), x, y)
            b.flts[seq] = (*p, z)
        b.count = len(items)
        self._active, self._staging = self._staging, self._active
        self.current = int(current) if 0 <= int(current) < b.count else 0
        self.version += 1
        self.finished = bool(finished) and b.count > 0
        return None

    def tick(self, now_s: float) -> list:
        """Retries and the timeout of an upload in progress. Returns the outputs."""
        if self._partner is None or now_s - self._sent_s < self.retry_s:
            return []
        if self._tries >= self.retries:
            self.uploads_failed += 1
            out = [("ack", *self._partner, ML.MAV_MISSION_OPERATION_CANCELLED, MISSION),
                   ("text", ML.MAV_SEVERITY_WARNING,
                    f"mission upload timed out at item {self._next}: mission kept")]
            self._partner = None
            return out
        return self._request(now_s, retry=True)

    # ------------------------------------------------------------------ upload
    def _on_count(self, src, n: int, mtype: int, now_s: float) -> list:
        if self._partner is not None and src != self._partner:
            return [("ack", *src, ML.MAV_MISSION_DENIED, mtype)]       # busy with another
        if mtype != MISSION:
            result = ML.MAV_MISSION_ACCEPTED if n == 0 else ML.MAV_MISSION_UNSUPPORTED
            return [("ack", *src, result, mtype)]
        if n > self.capacity:
            self._partner = None
            return [("ack", *src, ML.MAV_MISSION_NO_SPACE, mtype)]
        if n == 0:                             # an empty upload clears the mission
            self._partner = None
            self._active.count = 0
            self._changed(items=True)
            return [("ack", *src, ML.MAV_MISSION_ACCEPTED, mtype), ("current",)]
        self._partner = src                    # a repeated COUNT restarts the upload
        self._staging.count = n
        self._next = 0
        self._tries = 0
        return self._request(now_s)

    def _request(self, now_s: float, retry: bool = False) -> list:
        self._sent_s = now_s
        self._tries = self._tries + 1 if retry else 0
        return [("request", *self._partner, self._next)]

    def _on_item(self, src, m, is_int: bool, mtype: int, now_s: float) -> list:
        if self._partner is None or src != self._partner or mtype != MISSION:
            return []          # not in an upload with this partner: ignored (spec)
        seq = int(m.seq)
        if not 0 <= seq < self._staging.count:
            return self._cancel(ML.MAV_MISSION_INVALID_SEQUENCE)
        if seq != self._next:                  # a repeat, or one ahead: ask again
            if self._tries >= self.retries:    # ... a bounded number of times
                return self._cancel(ML.MAV_MISSION_OPERATION_CANCELLED,
                                    f"mission upload cancelled: item {seq} sent again while "
                                    f"item {self._next} was asked {self.retries + 1} times")
            return self._request(now_s, retry=True)
        x, y = (int(m.x), int(m.y)) if is_int else (_deg_e7(m.x), _deg_e7(m.y))
        p = (float(m.param1), float(m.param2), float(m.param3), float(m.param4))
        z = float(m.z)
        result = _check_item(int(m.command), int(m.frame), p, x, y, z)
        if result != ML.MAV_MISSION_ACCEPTED:
            return self._cancel(result, f"mission item {seq}: command {m.command} "
                                        f"frame {m.frame} refused ({result}): mission kept")
        bad_alt = self._altitude_refusal(int(m.command), int(m.frame), z)
        if bad_alt is not None:
            return self._cancel(ML.MAV_MISSION_INVALID_PARAM7,
                                f"mission item {seq}: {bad_alt}: mission kept")
        b = self._staging
        b.ints[seq] = (m.command, m.frame, m.autocontinue, x, y)
        b.flts[seq] = (*p, z)
        self._next = seq + 1
        if self._next < b.count:
            return self._request(now_s)
        # the last item: the staging bank becomes the mission
        partner = self._partner
        self._partner = None
        self._active, self._staging = self._staging, self._active
        self.uploads_ok += 1
        self.current = 0
        self._changed(items=True)
        return [("ack", *partner, ML.MAV_MISSION_ACCEPTED, MISSION), ("current",),
                ("text", ML.MAV_SEVERITY_INFO, f"mission: {b.count} items stored")]

    def _altitude_refusal(self, cmd: int, frame: int, z_m: float) -> str | None:
        """Why a waypoint's altitude ``z_m`` is outside the guidance's limits (``alt_limits_m``;
        a relative altitude is taken above home, or as a height bounded by the highest limit
        before home is known), or None."""
        if cmd != CMD_WAYPOINT or self.alt_limits_m is None:
            return None
        lo, hi, home = self.alt_limits_m()
        if frame in FRAMES_REL:
            if home is None:
                if abs(z_m) <= hi:
                    return None
                return f"altitude {z_m:g} m above home beyond {hi:.0f} m"
            h = z_m + home
        else:
            h = z_m
        if lo <= h <= hi:
            return None
        return f"altitude {h:g} m MSL outside [{lo:.0f}, {hi:.0f}] m (GT_ALT_*)"

    def _cancel(self, result: int, text: str | None = None) -> list:
        """End an upload in progress with ``result``; the stored mission is untouched."""
        if self._partner is None:
            return []
        partner = self._partner
        self._partner = None
        self.uploads_failed += 1
        out = [("ack", *partner, result, MISSION)]
        if text:
            out.append(("text", ML.MAV_SEVERITY_WARNING, text))
        return out

    def _changed(self, items: bool = False) -> None:
        if self.current >= self._active.count:
            self.current = 0
        self.finished = False
        self.version += 1
        if items:
            self.generation += 1


def _deg_e7(deg: float) -> int:
    """Legacy MISSION_ITEM float degrees -> degE7 (out of range or NaN -> an invalid value)."""
    if not math.isfinite(deg):
        return 2**31
    return int(round(deg * 1e7))


def encode(mav, mission: Mission, out: tuple, active: bool):
    """The MAVLink message for one output of :class:`Mission` (``None`` for "text", which the
    caller sends as STATUSTEXT), with the codec ``mav``; ``active``: MISSION mode."""
    kind = out[0]
    if kind == "count":
        return mav.mission_count_encode(out[1], out[2], out[3], out[4])
    if kind == "request":
        return mav.mission_request_int_encode(out[1], out[2], out[3], MISSION)
    if kind == "item":
        it = mission.item(out[3])
        return mav.mission_item_int_encode(
            out[1], out[2], it["seq"], it["frame"], it["command"],
            1 if it["seq"] == mission.current else 0, it["autocontinue"], it["param1"],
            it["param2"], it["param3"], it["param4"], it["x"], it["y"], it["z"], MISSION)
    if kind == "ack":
        return mav.mission_ack_encode(out[1], out[2], out[3], out[4])
    if kind == "current":
        return mav.mission_current_encode(*mission.current_fields(active))
    if kind == "reached":
        return mav.mission_item_reached_encode(out[1])
    return None
