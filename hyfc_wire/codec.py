"""The MAVLink codec of the wire (docs/wire.md): MAVLink 2, ``ardupilotmega`` dialect.

The one module of this package that imports pymavlink (the generated codec only, never
``mavutil``). Each process reaches it through its own link module (``fc/link.py``,
``plant_sim/link.py``), which stay the processes' only MAVLink edges.
"""
from __future__ import annotations

import os

os.environ["MAVLINK20"] = "1"          # before pymavlink is imported anywhere
from pymavlink.dialects.v20 import ardupilotmega as mavlink  # noqa: E402

__all__ = ["mavlink", "development_dialect", "new_codec", "reset_parser"]


def development_dialect():
    """pymavlink's ``development`` dialect, imported on first call: the standard-modes
    messages (AVAILABLE_MODES 435, CURRENT_MODE 436) and PARAM_ERROR (345) are in
    development.xml only (pymavlink 2.4.50); their classes are packed by the ardupilotmega
    codec (a message packs with its own CRC extra), nothing else is used from it. Only the fc's
    ground-station link uses them (fc/link.py ``mavlink_dev``): the plant, which imports this
    module too, never loads the dialect (5 MB of its RSS)."""
    from pymavlink.dialects.v20 import development
    return development


class _NullFile:
    """Write sink for the codec: we send packed bytes ourselves."""

    def write(self, _buf: bytes) -> None:
        return None


def new_codec(sysid: int, compid: int = 1) -> mavlink.MAVLink:
    """A MAVLink 2 ``ardupilotmega`` codec sending as ``sysid``/``compid``.

    ``robust_parsing`` is on: malformed input becomes ``MAVLink_bad_data`` instead of raising.
    """
    mav = mavlink.MAVLink(_NullFile(), srcSystem=sysid, srcComponent=compid)
    mav.robust_parsing = True
    return mav


def reset_parser(mav: mavlink.MAVLink) -> None:
    """Forget any partial frame in the codec's parser: each datagram is parsed on its own,
    so a truncated frame in one datagram cannot swallow the next datagram's bytes."""
    mav.buf = bytearray()
    mav.buf_index = 0
    mav.expected_length = mavlink.HEADER_LEN_V1 + 2
    mav.have_prefix_error = False
