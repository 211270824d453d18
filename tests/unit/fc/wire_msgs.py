"""Helpers of the fc's unit tests: a message as the fc's codec receives it off the wire."""
from __future__ import annotations

import os

os.environ["MAVLINK20"] = "1"
from fc.link import decode_datagram, mavlink as ML, new_codec  # noqa: E402


class _Null:
    def write(self, _b):
        return None


def received(msg, sysid: int = 255, compid: int = 190):
    """``msg`` packed by a ground station (``sysid``/``compid``) and decoded by the fc's codec
    (header, source ids and payload bytes as in the fc)."""
    tx = ML.MAVLink(_Null(), srcSystem=sysid, srcComponent=compid)
    msgs, bad = decode_datagram(new_codec(1, 1), msg.pack(tx))
    assert bad == 0 and len(msgs) == 1
    return msgs[0]
