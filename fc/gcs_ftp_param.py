"""fc/gcs_ftp_param.py - the packed parameter file ``@PARAM/param.pck`` of MAVLink FTP.

ArduPilot's format (AP_Filesystem_Param; MAVProxy's ``param_ftp.ftp_param_decode`` reads it):
a little-endian header ``<HHH`` magic (0x671b; 0x671c "with defaults"), the number of
parameters in the file, the total number; then one entry per parameter:

    byte 0  type (low 4 bits: 1 int8, 2 int16, 3 int32, 4 float) | flags << 4
            (flag bit 0, with defaults only: a default follows the value)
    byte 1  (length of the name's new part - 1) << 4 | length of the prefix it shares with the
            previous entry's name (names are at most 16 characters)
    then the new part of the name, the value, and the default if flagged.

Integer options (the table's ``integer`` rows) are packed as int32 with their whole value,
the rest as float32, in the table order (the PARAM_VALUE index). ``?withdefaults=1`` (what
MAVProxy asks for) adds each default that differs from the value.
"""
from __future__ import annotations

import struct

__all__ = ["pack_params", "MAGIC", "MAGIC_DEFAULTS"]

MAGIC = 0x671B
MAGIC_DEFAULTS = 0x671C
_INT32, _FLOAT = 3, 4


def pack_params(params, with_defaults: bool = False) -> bytes:
    """``params``: the fc's ParamTable (fc/params.py: names, defs, values). The packed file."""
    n = len(params)
    out = bytearray(struct.pack("<HHH", MAGIC_DEFAULTS if with_defaults else MAGIC, n, n))
    last = b""
    for i in range(n):
        d = params.defs[i]
        name = params.names[i].encode("ascii")
        common = 0
        while common < min(len(name), len(last), 15) and name[common] == last[common]:
            common += 1
        if common == len(name):          # the new part must be at least one character
            common -= 1
        suffix = name[common:]
        value = float(params.values[i])
        default = float(d.default)
        has_default = with_defaults and value != default
        if d.integer:
            ptype, fmt = _INT32, "<i"
            conv = int
        else:
            ptype, fmt = _FLOAT, "<f"
            conv = float
        out.append(ptype | ((1 if has_default else 0) << 4))
        out.append(((len(suffix) - 1) << 4) | common)
        out += suffix
        out += struct.pack(fmt, conv(round(value) if d.integer else value))
        if has_default:
            out += struct.pack(fmt, conv(round(default) if d.integer else default))
        last = name
    return bytes(out)
