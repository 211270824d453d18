"""fc/gcs_timesync.py - the MAVLink time synchronisation service (TIMESYNC, id 111).

mavlink.io "Time Synchronization": a request carries ``tc1 = 0`` and ``ts1`` = the requester's
time (ns); the answer mirrors ``ts1`` unchanged and sets ``tc1`` = our time (ns), with
``target_system``/``target_component`` = the requester's ids (the current common.xml's
extension fields; a message with ``tc1 != 0`` is an answer to somebody's request and is not
answered). Our time is the fc's telemetry time base (docs/fc.md section 7: sim time in
lockstep, time since start in real time), in ns, so a ground station maps our ``time_boot_ms``
and ``time_usec`` to its clock with the offset it estimates.

pymavlink 2.4.50's dialects define TIMESYNC without the two target fields, so the answer is
``TimesyncTargeted``: the same message (id, CRC extra 34) with the extension fields packed
after ``ts1``; a reader that does not know them ignores them (MAVLink 2 extensions). The
request's own target fields are read from its payload bytes (``request_targets``).

Pure: a request in, the answer out (``answer``); no socket, no clock.
"""
from __future__ import annotations

import struct

from fc.link import mavlink as ML

__all__ = ["TimesyncTargeted", "answer", "request_targets"]

_TS = ML.MAVLink_timesync_message


class TimesyncTargeted(_TS):
    """TIMESYNC with the extension fields ``target_system``, ``target_component`` (uint8)."""

    fieldnames = ["tc1", "ts1", "target_system", "target_component"]
    ordered_fieldnames = ["tc1", "ts1", "target_system", "target_component"]
    fieldtypes = ["int64_t", "int64_t", "uint8_t", "uint8_t"]
    native_format = bytearray(b"<qqBB")
    orders = [0, 1, 2, 3]
    lengths = [1, 1, 1, 1]
    array_lengths = [0, 0, 0, 0]
    unpacker = struct.Struct("<qqBB")

    def __init__(self, tc1: int, ts1: int, target_system: int, target_component: int) -> None:
        _TS.__init__(self, tc1, ts1)
        self._fieldnames = TimesyncTargeted.fieldnames
        self.target_system = target_system
        self.target_component = target_component

    def pack(self, mav, force_mavlink1: bool = False) -> bytes:
        return self._pack(mav, self.crc_extra,
                          self.unpacker.pack(self.tc1, self.ts1, self.target_system,
                                             self.target_component),
                          force_mavlink1=force_mavlink1)


def request_targets(m) -> tuple[int, int]:
    """``(target_system, target_component)`` of a received TIMESYNC: the extension bytes 16
    and 17 of its payload (MAVLink 2 drops trailing zeros: absent = 0, broadcast)."""
    try:
        hdr = m.get_header()
        buf = m.get_msgbuf()
        start = 10 if buf[0] == 0xFD else 6            # MAVLink 2 / 1 header length
        payload = bytes(buf[start:start + hdr.mlen])
    except (AttributeError, IndexError, TypeError):
        return 0, 0
    payload = payload + bytes(max(0, 18 - len(payload)))
    return payload[16], payload[17]


def answer(m, now_ns: int, sysid: int, compid: int):
    """The answer to TIMESYNC ``m`` at our time ``now_ns`` (ns), or None: ``m`` is an answer
    itself (``tc1 != 0``), or a request addressed to another system or component."""
    if m.tc1 != 0:
        return None
    ts, tc = request_targets(m)
    if ts not in (0, sysid) or tc not in (0, compid):
        return None
    return TimesyncTargeted(int(now_ns), int(m.ts1), m.get_srcSystem(), m.get_srcComponent())
