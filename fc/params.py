"""fc/params.py - the one parameter table of the flight controller.

The table is the control law's ``LAW_PARAMS`` (fc/control/params.py) followed by the
process parameters below (attitude commands, failsafe, estimator, trims, guidance modes) and
the guidance's ``GUIDANCE_PARAMS`` (fc/guidance/params.py). It is the single
source for the MAVLink parameter protocol (names <= 16 characters, uppercase, stable indices;
integer and enum options INT32, encoded bytewise in the float field as the MAVLink spec, PX4,
MAVSDK and QGroundControl do; the rest REAL32: :func:`encode_value`), for validation (range,
finiteness), for persistence (MAVProxy ``param save`` format, written atomically) and for
``docs/params.md`` (``python -m fc.params --write-docs``; a test checks the file is current).
"""
from __future__ import annotations

import math
import os
import re
import struct
import sys
import time
from typing import Iterable

import numpy as np

from fc.control.params import Param, checked_value
from fc.storage import atomic_write

__all__ = ["ParamDef", "PROCESS_PARAMS", "ParamTable", "ParamFileError", "build_table",
           "render_markdown", "law_param_defs", "UNITS", "encode_value", "decode_set_value"]

NAME_MAX = 16
NAME_RE = re.compile(r"^[A-Z][A-Z0-9_]{0,15}$")

#: Unit vocabulary of the table (PX4 PR #15502: one spelling per unit): unit -> meaning.
#: A parameter whose unit is not here is refused when the table is built.
UNITS: dict[str, str] = {
    "deg": "angle, degrees (SI: rad)", "deg/s": "angular rate, degrees per second",
    "rad": "angle, radians", "rad/s": "angular rate", "rad/s^2": "angular acceleration",
    "1/rad": "per radian", "1/rad^2": "per radian squared", "s/rad": "seconds per radian",
    "s^3/rad^2": "seconds cubed per radian squared", "s": "seconds", "ms": "milliseconds",
    "us": "microseconds", "Hz": "hertz", "1/s": "per second", "1/s^2": "per second squared",
    "m": "metres", "m/s": "metres per second", "m/s^2": "metres per second squared",
    "kg": "kilograms", "kg m^2": "moment of inertia", "N": "newtons", "N m": "newton metres",
    "Pa": "pascals", "%": "percent",
    "1": "dimensionless number (a ratio, a count)", "-": "dimensionless option or gain",
    "bool": "switch, 0 or 1",
}


#: One record type for every parameter, the law's and the process's (fc/control/params.py):
#: name, default, min, max, unit, group, description, si_scale, integer.
ParamDef = Param


#: Parameters owned by the fc process (not the law). Order is the wire order after the law's.
PROCESS_PARAMS: tuple[ParamDef, ...] = (
    ParamDef("CMD_ALPHA_DEG", 0.0, -10.0, 20.0, "deg", "command",
             "Commanded angle of attack alpha_c; the range is the command limit."),
    ParamDef("CMD_BETA_DEG", 0.0, -10.0, 10.0, "deg", "command",
             "Commanded sideslip beta_c; the range is the command limit."),
    ParamDef("CMD_MU_DEG", 0.0, -60.0, 60.0, "deg", "command",
             "Commanded bank angle about the velocity vector mu_c; the range is the command limit."),
    ParamDef("FS_TIMEOUT_S", 0.5, 0.02, 30.0, "s", "failsafe",
             "Plant data (valid sensor frames) absent for longer than this, wall clock: FAILSAFE."),
    ParamDef("FS_RECOVER", 1.0, 0.0, 1.0, "bool", "failsafe",
             "1: leave FAILSAFE automatically to the previous mode once data has been back "
             "for FS_RECOVER_S; 0: stay in FAILSAFE until the ground station sets a mode.",
             integer=True),
    ParamDef("FS_RECOVER_S", 0.2, 0.0, 10.0, "s", "failsafe",
             "Plant time valid plant data must be back before automatic recovery from "
             "FAILSAFE; none after a plant freeze (plant time moved on less than FS_TIMEOUT_S)."),
    ParamDef("EST_STALE_S", 0.1, 0.002, 5.0, "s", "estimator",
             "A measurement whose last valid value is older than this (sensor time) is stale; "
             "the estimator holds the last good value and flags it."),
    ParamDef("TRIM_ELEVL_DEG", 0.0, -20.0, 20.0, "deg", "trim",
             "Left elevon position in MANUAL, disarmed, and FAILSAFE before the law flew (then it "
             "holds the law's trim) (trailing edge up +)."),
    ParamDef("TRIM_ELEVR_DEG", 0.0, -20.0, 20.0, "deg", "trim",
             "Right elevon position in MANUAL, disarmed, and FAILSAFE before the law flew (then it "
             "holds the law's trim) (trailing edge up +)."),
    ParamDef("TRIM_RUD_DEG", 0.0, -20.0, 20.0, "deg", "trim",
             "Rudder position in MANUAL, disarmed, and FAILSAFE before the law flew (then it "
             "holds the law's trim) (trailing edge left +)."),
    ParamDef("GUID_INNER_CO", 1.0, 0.0, 1.0, "bool", "guidance",
             "Inner loop in the guidance modes (CRUISE, GUIDED, MISSION, RTL): 1 the coordinated law "
             "(CO_ENABLE 1), 0 the uncoordinated (CO_ENABLE 0).", integer=True),
    ParamDef("GT_ALT_MIN", 20000.0, 0.0, 100000.0, "m", "guidance",
             "Lowest altitude target a ground station or mission may set (AMSL); lower is refused."),
    ParamDef("GT_ALT_MAX", 40000.0, 0.0, 100000.0, "m", "guidance",
             "Highest altitude target a ground station or mission may set (AMSL); higher is refused."),
    ParamDef("GT_SPD_MIN", 1200.0, 0.0, 10000.0, "m/s", "guidance",
             "Lowest airspeed target a ground station or mission may set; lower is refused."),
    ParamDef("GT_SPD_MAX", 3200.0, 0.0, 10000.0, "m/s", "guidance",
             "Highest airspeed target a ground station or mission may set; higher is refused."),
)

#: Law parameters the process drives itself (a PARAM_SET is refused with a hint).
PROCESS_DRIVEN = {"CO_ENABLE": "CO_ENABLE follows the flight mode: set COORDINATED or UNCOORDINATED"}


def law_param_defs(law_params: Iterable) -> list[ParamDef]:
    """Convert the law's ``Param`` rows (fc/control/params.py) to :class:`ParamDef`."""
    return [ParamDef(p.name, float(p.default), float(p.min), float(p.max), str(p.unit),
                     str(p.group), str(p.description),
                     si_scale=float(getattr(p, "si_scale", 1.0)),
                     integer=bool(getattr(p, "integer", False)))
            for p in law_params]


def _check_defs(defs: list[ParamDef]) -> None:
    seen: set[str] = set()
    for d in defs:
        if not NAME_RE.match(d.name) or len(d.name) > NAME_MAX:
            raise ValueError(f"parameter name {d.name!r}: uppercase, <= {NAME_MAX} characters")
        if d.name in seen:
            raise ValueError(f"parameter {d.name} defined twice (law and process tables collide?)")
        seen.add(d.name)
        if d.unit not in UNITS:
            raise ValueError(f"parameter {d.name}: unit {d.unit!r} not in the vocabulary "
                             "(fc/params.py UNITS)")
        if not (math.isfinite(d.min) and math.isfinite(d.max) and d.min <= d.default <= d.max):
            raise ValueError(f"parameter {d.name}: default {d.default} outside [{d.min}, {d.max}]")


# MAV_PARAM_TYPE (common.xml): REAL32 9; the integer types and their bytewise layout in the
# 4 bytes of the float field (little-endian, the low bytes carry the value)
PARAM_TYPE_REAL32 = 9
PARAM_TYPE_INT32 = 6
_INT_LAYOUT = {1: "<B", 2: "<b", 3: "<H", 4: "<h", 5: "<I", 6: "<i"}   # UINT8 .. INT32


def encode_value(d: ParamDef, value: float) -> tuple[float, int]:
    """``(param_value, param_type)`` of PARAM_VALUE: INT32 bytewise for integer options."""
    if d.integer:
        return struct.unpack("<f", struct.pack("<i", int(round(value))))[0], PARAM_TYPE_INT32
    return float(value), PARAM_TYPE_REAL32


def decode_set_value(d: ParamDef, param_value: float, param_type: int) -> float | None:
    """The number a PARAM_SET asks for, or None when its type does not fit the parameter.

    Integer options take any integer type (bytewise, the spec) or REAL32 (the plain number:
    MAVProxy sends REAL32 to non-PX4 autopilots); REAL32 options take REAL32 only (0, an
    unset type, is read as REAL32).
    """
    if param_type in (0, PARAM_TYPE_REAL32):
        return float(param_value)
    if d.integer and param_type in _INT_LAYOUT:
        return wire_number(param_value, param_type)
    return None


def wire_number(param_value: float, param_type: int) -> float:
    """The number a PARAM_VALUE/PARAM_SET carries: integer types bytewise in the float field,
    REAL32 (or an unset type) as the float itself. For readers of the wire (tools, tests)."""
    fmt = _INT_LAYOUT.get(param_type)
    if fmt is None:
        return float(param_value)
    raw = struct.pack("<f", param_value)
    return float(struct.unpack(fmt, raw[:struct.calcsize(fmt)])[0])


class ParamFileError(ValueError):
    """A parameter file that cannot be read (syntax, non-finite value)."""


class ParamTable:
    """Values of every parameter, in the table order (the MAVLink index), in the table's
    units. The SI conversion is not here: the law and the guidance convert what they are
    given (``si_scale``, fc/control/params.py ``to_si``), the fc process its own parameters
    (fc/app.py ``_apply_process_params``)."""

    def __init__(self, defs: list[ParamDef]) -> None:
        _check_defs(defs)
        self.defs = list(defs)
        self.names = [d.name for d in defs]
        self.index = {n: i for i, n in enumerate(self.names)}
        self.values = np.array([d.default for d in defs], dtype=np.float64)

    def __len__(self) -> int:
        return len(self.names)

    def __contains__(self, name: str) -> bool:
        return name in self.index

    def get(self, name: str) -> float:
        return float(self.values[self.index[name]])

    def defn(self, name: str) -> ParamDef:
        return self.defs[self.index[name]]

    def check(self, name: str, value: float) -> str | None:
        """None if ``value`` may be set, else the reason (for STATUSTEXT and fc.log)."""
        if name not in self.index:
            return f"unknown parameter {name}"
        try:
            checked_value(self.defs[self.index[name]], value)
        except ValueError as exc:
            return str(exc)
        return None

    def set(self, name: str, value: float) -> str | None:
        """Set if valid (:func:`fc.control.params.checked_value`, the one rule); returns None
        on success, else the reason (value unchanged)."""
        if name not in self.index:
            return f"unknown parameter {name}"
        try:
            self.values[self.index[name]] = checked_value(self.defs[self.index[name]], value)
        except ValueError as exc:
            return str(exc)
        return None

    def force(self, name: str, value: float) -> None:
        """Set a value the process drives itself (e.g. CO_ENABLE from the mode), no validator."""
        self.values[self.index[name]] = float(value)

    # ---------------------------------------------------------------- persistence
    def save(self, path: str) -> None:
        """Write all values atomically (temp file in the same directory, fsync, rename).

        Format: MAVProxy ``param save`` (``NAME value`` per line, ``#`` comments), which
        MAVProxy ``param load`` reads back.
        """
        lines = [f"# hyfc parameters, {time.strftime('%Y-%m-%dT%H:%M:%SZ', time.gmtime())}\n"]
        lines += [f"{n:<16.16s} {float(v):.9g}\n" for n, v in zip(self.names, self.values)]
        atomic_write(path, "".join(lines).encode("ascii"))

    @staticmethod
    def read_file(path: str) -> dict[str, float]:
        """Parse a MAVProxy/Mission Planner parameter file; ParamFileError when malformed."""
        out: dict[str, float] = {}
        try:
            with open(path, "r", encoding="utf-8") as f:
                lines = f.readlines()
        except UnicodeDecodeError as exc:
            raise ParamFileError(f"{path}: not a text file ({exc})") from None
        for lineno, raw in enumerate(lines, 1):
            line = raw.split("#", 1)[0].strip().replace(",", " ")
            if not line:
                continue
            parts = line.split()
            if len(parts) != 2:
                raise ParamFileError(f"{path}:{lineno}: expected 'NAME VALUE', got {raw.strip()!r}")
            name, text = parts[0].upper(), parts[1]
            try:
                value = float(int(text[2:], 16)) if text.lower().startswith("0x") else float(text)
            except ValueError:
                raise ParamFileError(f"{path}:{lineno}: {text!r} is not a number") from None
            if not math.isfinite(value):
                raise ParamFileError(f"{path}:{lineno}: non-finite value for {name}")
            out[name] = value
        return out

    def load(self, path: str) -> tuple[list[str], list[str]]:
        """Apply a parameter file. Returns ``(applied_names, warnings)``.

        Unknown names and out-of-range values are skipped with a warning (the default
        stays). A malformed file raises ParamFileError and changes nothing.
        """
        values = self.read_file(path)
        applied: list[str] = []
        warnings: list[str] = []
        for name, value in values.items():
            if name not in self.index:
                warnings.append(f"{path}: unknown parameter {name} ignored")
                continue
            if name in PROCESS_DRIVEN:
                continue
            reason = self.set(name, value)
            if reason is not None:
                warnings.append(f"{path}: {reason}; default kept")
            else:
                applied.append(name)
        return applied, warnings


def set_aside(path: str) -> str:
    """Rename a bad parameter file to ``PATH.corrupt-<UTC stamp>`` and return the new name."""
    dest = f"{path}.corrupt-{time.strftime('%Y%m%dT%H%M%SZ', time.gmtime())}"
    n = 0
    while os.path.exists(dest):
        n += 1
        dest = f"{path}.corrupt-{time.strftime('%Y%m%dT%H%M%SZ', time.gmtime())}.{n}"
    os.replace(path, dest)
    return dest


def build_table(law_params: Iterable | None = None) -> ParamTable:
    """The full table: law parameters (default: ``fc.control.params.LAW_PARAMS``) + process
    + guidance (``fc.guidance.params.GUIDANCE_PARAMS``) + mission (``fc.mission_params``)."""
    from fc.guidance.params import GUIDANCE_PARAMS
    from fc.mission_params import MISSION_PARAMS
    if law_params is None:
        from fc.control.params import LAW_PARAMS
        law_params = LAW_PARAMS
    return ParamTable(law_param_defs(law_params) + list(PROCESS_PARAMS)
                      + law_param_defs(GUIDANCE_PARAMS) + list(MISSION_PARAMS))


def render_markdown(table: ParamTable) -> str:
    """docs/params.md, generated from the table."""
    lines = [
        "# Parameters",
        "",
        "Generated by `python -m fc.params --write-docs` from the one parameter table",
        "(`fc/control/params.py` LAW_PARAMS, then `fc/params.py` PROCESS_PARAMS, then",
        "`fc/guidance/params.py` GUIDANCE_PARAMS). Do not edit by hand.",
        "",
        "Type INT32 (PARAM_VALUE `param_type` 6) marks integer and enum options: their value",
        "travels bytewise in the float field (MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE, as",
        "PX4); REAL32 (9) the rest. Index = row number below starting at 0. A refused set (outside",
        "[min, max], non-finite, fractional for an integer, wrong type, read-only) is answered at",
        "once with PARAM_ERROR, PARAM_VALUE with the unchanged value and a STATUSTEXT with the reason.",
        "",
        f"{len(table)} parameters.",
        "",
        "| index | name | type | default | min | max | unit | group | description |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for i, d in enumerate(table.defs):
        desc = d.description.replace("|", "\\|").replace("\n", " ")
        ptype = "INT32" if d.integer else "REAL32"
        lines.append(f"| {i} | `{d.name}` | {ptype} | {d.default:g} | {d.min:g} | {d.max:g} "
                     f"| {d.unit} | {d.group} | {desc} |")
    lines.append("")
    return "\n".join(lines)


def _main(argv: list[str]) -> int:
    import argparse
    ap = argparse.ArgumentParser(prog="python -m fc.params",
                                 description="Print or write docs/params.md from the table.")
    ap.add_argument("--write-docs", metavar="PATH", nargs="?", const="docs/params.md",
                    help="write the Markdown reference (default docs/params.md)")
    args = ap.parse_args(argv)
    text = render_markdown(build_table())
    if args.write_docs:
        with open(args.write_docs, "w", encoding="utf-8") as f:
            f.write(text)
    else:
        sys.stdout.write(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(_main(sys.argv[1:]))
