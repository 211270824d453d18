"""fc/modes.py - flight modes, arming and the plant-data failsafe state machine.

Modes travel as HEARTBEAT ``custom_mode`` (base_mode has MAV_MODE_FLAG_CUSTOM_MODE_ENABLED)
and are set with MAV_CMD_DO_SET_MODE (param2) or SET_MODE (docs/fc.md section 5). On the wire
``custom_mode`` is PX4's layout (main mode << 16 | sub mode << 24) with the hyfc mode number
in the low 16 bits that PX4 leaves unused (:data:`MODE_WIRE`), so MAVSDK and pymavlink read a
PX4 mode close in meaning, and the ground stations that know our names (QGroundControl through
AVAILABLE_MODES, MAVProxy through tools/mavproxy_hyfc.py) read ours:

- MANUAL (0): surfaces at the TRIM_* parameters (no RC on this vehicle: passthrough of trim).
- COORDINATED (1): the law with CO_ENABLE = 1.
- UNCOORDINATED (2): the law with CO_ENABLE = 0.
- FAILSAFE (3): surfaces held at trim: armed, the trim the law flew (the running mean of its
  commands, fc/mode_control.py ``SurfaceHold``), else the TRIM_* parameters. Entered on
  plant-data loss (automatic) or on request.
- CRUISE (4): the guidance (fc/guidance) holds the altitude, course and speed at entry; the
  law tracks its alpha/beta/mu commands (inner variant: parameter GUID_INNER_CO).
- GUIDED (5): the guidance flies targets from the ground station (GUIDED_CHANGE_*,
  DO_CHANGE_ALTITUDE/SPEED); entered holding the current altitude, course and speed.
- MISSION (6): the guidance flies the stored mission (fc/mission.py, fc/mission_mode.py);
  refused with no mission or no GNSS fix. Its custom_mode (PX4 AUTO.MISSION) is above 2^24,
  so DO_SET_MODE sets it by the plain number 6 (float param2) or PX4's main/sub 4/4.
- RTL (7): the guidance flies back toward home at the altitude and speed of entry, then circles
  over it (fc/point_mode.py); refused without a GNSS fix and home. PX4 AUTO.RTL (4/5).

Mode requests are decoded in one place, :func:`decode_mode_request` over :data:`PX4_REQUEST`
(docs/fc.md section 5): DO_SET_MODE's param2/param3 as PX4's main/sub mode when the sub mode
is not 0, else param2 as the hyfc number or a whole HEARTBEAT custom_mode; a request with no
match is refused, never mapped to a neighbour.

The law runs only when armed and in COORDINATED/UNCOORDINATED or a guidance mode
(:data:`GUIDANCE_MODES`); disarmed = surfaces at trim.
This module holds no clock: the caller passes wall times in seconds.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from enum import IntEnum

__all__ = ["FlightMode", "ModeManager", "FS_NONE", "FS_DATA", "FS_REQUESTED", "MODE_WIRE",
           "GUIDANCE_MODES", "STANDARD_MODE", "MODE_OF_STANDARD", "PX4_REQUEST", "FORCE_DISARM",
           "custom_mode_of", "decode_mode_request"]


class FlightMode(IntEnum):
    MANUAL = 0
    COORDINATED = 1
    UNCOORDINATED = 2
    FAILSAFE = 3
    CRUISE = 4
    GUIDED = 5
    MISSION = 6
    RTL = 7


# PX4 custom main modes and AUTO sub modes (PX4 px4_custom_mode.h; pymavlink and MAVSDK decode them)
PX4_MANUAL, PX4_ALTCTL, PX4_POSCTL, PX4_AUTO, PX4_ACRO, PX4_OFFBOARD, PX4_STABILIZED = range(1, 8)
PX4_RATTITUDE = 8
(PX4_AUTO_READY, PX4_AUTO_TAKEOFF, PX4_AUTO_LOITER, PX4_AUTO_MISSION, PX4_AUTO_RTL, PX4_AUTO_LAND,
 PX4_AUTO_RESERVED, PX4_AUTO_FOLLOW_TARGET, PX4_AUTO_PRECLAND) = range(1, 10)
#: PX4's names of its (main, sub) modes, for the refusal texts
PX4_NAMES = {(PX4_MANUAL, 0): "MANUAL", (PX4_ALTCTL, 0): "ALTCTL", (PX4_POSCTL, 0): "POSCTL",
             (PX4_AUTO, PX4_AUTO_READY): "AUTO.READY", (PX4_AUTO, PX4_AUTO_TAKEOFF): "AUTO.TAKEOFF",
             (PX4_AUTO, PX4_AUTO_LOITER): "AUTO.LOITER",
             (PX4_AUTO, PX4_AUTO_MISSION): "AUTO.MISSION",
             (PX4_AUTO, PX4_AUTO_RTL): "AUTO.RTL", (PX4_AUTO, PX4_AUTO_LAND): "AUTO.LAND",
             (PX4_AUTO, PX4_AUTO_FOLLOW_TARGET): "AUTO.FOLLOW_TARGET",
             (PX4_AUTO, PX4_AUTO_PRECLAND): "AUTO.PRECLAND", (PX4_ACRO, 0): "ACRO",
             (PX4_OFFBOARD, 0): "OFFBOARD", (PX4_STABILIZED, 0): "STABILIZED",
             (PX4_RATTITUDE, 0): "RATTITUDE"}
#: MAV_CMD_COMPONENT_ARM_DISARM param2 that forces a disarm in flight (PX4, ArduPilot)
FORCE_DISARM = 21196


def _px4(main: int, sub: int, number: int) -> int:
    """HEARTBEAT custom_mode: PX4's main/sub mode bytes, the hyfc mode number in bits 0-15."""
    return (sub << 24) | (main << 16) | number


#: hyfc mode -> HEARTBEAT ``custom_mode``. MAVSDK reads MANUAL, STABILIZED, STABILIZED, MANUAL
#: (the law modes hold attitude; FAILSAFE holds the surfaces at trim, as MANUAL does here);
#: the low 16 bits tell COORDINATED from UNCOORDINATED and MANUAL from FAILSAFE.
MODE_WIRE: dict[FlightMode, int] = {
    FlightMode.MANUAL: _px4(PX4_MANUAL, 0, FlightMode.MANUAL),
    FlightMode.COORDINATED: _px4(PX4_STABILIZED, 0, FlightMode.COORDINATED),
    FlightMode.UNCOORDINATED: _px4(PX4_STABILIZED, 0, FlightMode.UNCOORDINATED),
    FlightMode.FAILSAFE: _px4(PX4_MANUAL, 0, FlightMode.FAILSAFE),
    FlightMode.CRUISE: _px4(PX4_POSCTL, 0, FlightMode.CRUISE),      # hold altitude, course, speed
    FlightMode.GUIDED: _px4(PX4_OFFBOARD, 0, FlightMode.GUIDED),    # targets from the GCS
    # a stored mission (fc/mission_mode.py); above 2^24: DO_SET_MODE sets it by the number 6
    FlightMode.MISSION: _px4(PX4_AUTO, PX4_AUTO_MISSION, FlightMode.MISSION),
    # back toward home, then circle over it (fc/point_mode.py); above 2^24 as MISSION
    FlightMode.RTL: _px4(PX4_AUTO, PX4_AUTO_RTL, FlightMode.RTL),
}

#: MAV_STANDARD_MODE a mode advertises in AVAILABLE_MODES/CURRENT_MODE (0: none); the same
#: table decodes MAV_CMD_DO_SET_STANDARD_MODE (:data:`MODE_OF_STANDARD`).
STANDARD_MODE: dict[FlightMode, int] = {FlightMode.CRUISE: 3,     # MAV_STANDARD_MODE_CRUISE
                                        FlightMode.MISSION: 6,    # MAV_STANDARD_MODE_MISSION
                                        FlightMode.RTL: 5}        # ..._SAFE_RECOVERY
MODE_OF_STANDARD: dict[int, FlightMode] = {v: k for k, v in STANDARD_MODE.items()}

#: The one decoding table of PX4's (main, sub) mode requests (MAVSDK: DO_SET_MODE param2/3;
#: SET_MODE's custom_mode bits 16-23/24-31) -> the hyfc mode meaning the same. Everything
#: else PX4 has (ALTCTL, ACRO, AUTO.TAKEOFF/LAND/READY/FOLLOW_TARGET/PRECLAND, RATTITUDE) has
#: no hyfc counterpart and is refused.
PX4_REQUEST: dict[tuple[int, int], FlightMode] = {
    (PX4_MANUAL, 0): FlightMode.MANUAL,               # advertised so (MANUAL)
    (PX4_STABILIZED, 0): FlightMode.COORDINATED,      # advertised so (COORDINATED)
    (PX4_POSCTL, 0): FlightMode.CRUISE,               # advertised so (CRUISE)
    (PX4_OFFBOARD, 0): FlightMode.GUIDED,             # advertised so (GUIDED)
    (PX4_AUTO, PX4_AUTO_MISSION): FlightMode.MISSION,  # MAVSDK start_mission
    (PX4_AUTO, PX4_AUTO_LOITER): FlightMode.CRUISE,   # MAVSDK hold, pause_mission: hold
    (PX4_AUTO, PX4_AUTO_RTL): FlightMode.RTL,         # MAVSDK return_to_launch
}

_WIRE_TO_MODE = {v: k for k, v in MODE_WIRE.items()}


def custom_mode_of(mode: FlightMode) -> int:
    """HEARTBEAT/CURRENT_MODE ``custom_mode`` of ``mode``."""
    return MODE_WIRE[mode]


def _whole(x: float) -> int | None:
    """``x`` as an int if it is a finite whole number, else None."""
    if not math.isfinite(x) or x != int(x):
        return None
    return int(x)


def decode_mode_request(param2: float, param3: float = 0.0) -> tuple[FlightMode | None, str]:
    """The hyfc mode a mode request means: (mode, "") or (None, why not).

    The one decoder of DO_SET_MODE (``param2``, ``param3``) and SET_MODE (``custom_mode``,
    ``param3`` 0):

    - ``param3`` a whole number > 0: PX4's main mode ``param2`` and sub mode ``param3``
      (MAVSDK: 4/4 AUTO.MISSION, 4/3 AUTO.LOITER, 4/5 AUTO.RTL), through :data:`PX4_REQUEST`;
    - ``param3`` 0 (or NaN: not given): ``param2`` is the hyfc mode number (0..7), or a whole
      ``custom_mode``: a HEARTBEAT value of ours (exact in a float below 2^24), else PX4's
      layout with the low 16 bits 0 (main << 16 | sub << 24, QGroundControl's SET_MODE of a
      PX4 mode), through :data:`PX4_REQUEST`.

    PX4's modes without a sub mode (MANUAL 1, ALTCTL 2, POSCTL 3, ...) sent as a plain main
    mode with sub mode 0 cannot be told from the hyfc numbers: there the number is hyfc's.
    No match, NaN, fractions: (None, reason); never a neighbouring mode.
    """
    sub = 0 if math.isnan(param3) else _whole(param3)
    main = _whole(param2)
    if main is None or sub is None or main < 0 or sub < 0:
        return None, f"mode {param2:g}/{param3:g} refused: not a mode"
    if sub > 0:
        mode = PX4_REQUEST.get((main, sub))
        if mode is None:
            name = PX4_NAMES.get((main, sub), f"PX4 {main}/{sub}")
            return None, f"mode {name} refused: no such mode on hyfc"
        return mode, ""
    if main in _WIRE_TO_MODE:
        return _WIRE_TO_MODE[main], ""
    if main <= 0xFFFF:
        try:
            return FlightMode(main), ""
        except ValueError:
            return None, f"unknown mode {main} refused"
    if main & 0xFFFF or main > 0xFFFFFFFF:
        return None, f"mode {main:#x} refused: not a mode"
    key = ((main >> 16) & 0xFF, main >> 24)
    mode = PX4_REQUEST.get(key)
    if mode is None:
        name = PX4_NAMES.get(key, f"PX4 {key[0]}/{key[1]}")
        return None, f"mode {name} refused: no such mode on hyfc"
    return mode, ""


#: Modes in which the guidance (outer loop) runs and commands the law.
GUIDANCE_MODES = (FlightMode.CRUISE, FlightMode.GUIDED, FlightMode.MISSION, FlightMode.RTL)
#: Modes in which the law runs (when armed).
LAW_MODES = (FlightMode.COORDINATED, FlightMode.UNCOORDINATED) + GUIDANCE_MODES
FS_NONE = 0       # not in failsafe
FS_DATA = 1       # entered because plant data was lost
FS_REQUESTED = 2  # entered on request from the ground station


@dataclass(slots=True)
class ModeManager:
    """Mode, arming and failsafe. Methods return ``(ok, text)``; ``text`` is for STATUSTEXT."""

    mode: FlightMode = FlightMode.MANUAL
    armed: bool = False
    fs_cause: int = FS_NONE
    mode_before_fs: FlightMode = FlightMode.MANUAL
    data_lost: bool = False
    data_back_since_s: float = -1.0
    changes: int = 0   # bumped on every mode/arming change (the app resets the law on it)

    @property
    def law_active(self) -> bool:
        return self.armed and self.mode in LAW_MODES

    @property
    def guidance_active(self) -> bool:
        return self.armed and self.mode in GUIDANCE_MODES

    @property
    def co_enable(self) -> float:
        return 1.0 if self.mode == FlightMode.COORDINATED else 0.0

    def request_mode(self, mode: int) -> tuple[bool, str]:
        try:
            mode = FlightMode(int(mode))
        except ValueError:
            return False, f"unknown mode {mode}"
        if mode == FlightMode.FAILSAFE:
            if self.mode != FlightMode.FAILSAFE:
                self.mode_before_fs = self.mode
                self._set(mode)
            self.fs_cause = FS_REQUESTED if self.fs_cause == FS_NONE else self.fs_cause
            return True, "mode FAILSAFE (requested)"
        if self.data_lost:
            return False, f"mode {mode.name} refused: plant data lost"
        self.fs_cause = FS_NONE
        self._set(mode)
        return True, f"mode {mode.name}"

    def set_armed(self, armed: bool, data_ok: bool, in_air: bool = False,
                  forced: bool = False) -> tuple[bool, str]:
        """Arm or disarm. A disarm while ``in_air`` is refused unless ``forced`` (the force
        code FORCE_DISARM in param2, as PX4 and ArduPlane)."""
        if armed and not data_ok:
            return False, "arming refused: no valid plant data"
        if not armed and self.armed and in_air and not forced:
            return False, f"disarm refused: in flight (param2 {FORCE_DISARM} forces it)"
        if armed != self.armed:
            self.armed = armed
            self.changes += 1
        return True, "armed" if armed else "disarmed"

    def on_data_lost(self) -> str | None:
        """Plant data absent beyond FS_TIMEOUT_S. Returns the event text once."""
        if self.data_lost:
            return None
        self.data_lost = True
        self.data_back_since_s = -1.0
        if self.mode != FlightMode.FAILSAFE:
            self.mode_before_fs = self.mode
            self._set(FlightMode.FAILSAFE)
            self.fs_cause = FS_DATA
            return "FAILSAFE: plant data lost, surfaces held at trim"
        return "plant data lost (already in FAILSAFE)"

    def on_data_ok(self, now_s: float, recover: bool, recover_s: float,
                   at_once: bool = False) -> str | None:
        """Valid plant data arrived at ``now_s`` (the fc passes plant time, s: the recovery is
        judged on the flight, not on the wall clock). Recovery after ``recover_s`` of data
        back, or ``at_once`` (the plant froze: no time passed without the fc). Returns an event
        text or None."""
        if not self.data_lost:
            return None
        if self.data_back_since_s < 0.0:
            self.data_back_since_s = now_s
        if not at_once and now_s - self.data_back_since_s < recover_s:
            return None
        self.data_lost = False
        if self.fs_cause == FS_DATA and recover:
            self.fs_cause = FS_NONE
            self._set(self.mode_before_fs)
            return f"plant data back: FAILSAFE -> {self.mode.name}"
        return "plant data back: staying in FAILSAFE until a mode is set"

    def on_data_gap(self) -> None:
        """Data stopped again before recovery completed."""
        self.data_back_since_s = -1.0

    def _set(self, mode: FlightMode) -> None:
        if mode != self.mode:
            self.mode = mode
            self.changes += 1
