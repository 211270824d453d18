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
  so DO_SET_MODE sets it by the plain number 6 (float param2).

The law runs only when armed and in COORDINATED/UNCOORDINATED or a guidance mode
(:data:`GUIDANCE_MODES`); disarmed = surfaces at trim.
This module holds no clock: the caller passes wall times in seconds.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from enum import IntEnum

__all__ = ["FlightMode", "ModeManager", "FS_NONE", "FS_DATA", "FS_REQUESTED", "MODE_WIRE",
           "GUIDANCE_MODES", "STANDARD_MODE", "custom_mode_of",
           "mode_from_custom"]


class FlightMode(IntEnum):
    MANUAL = 0
    COORDINATED = 1
    UNCOORDINATED = 2
    FAILSAFE = 3
    CRUISE = 4
    GUIDED = 5
    MISSION = 6


# PX4 custom main modes and AUTO sub modes (PX4 px4_custom_mode.h; pymavlink and MAVSDK decode them)
PX4_MANUAL, PX4_ALTCTL, PX4_POSCTL, PX4_AUTO, PX4_ACRO, PX4_OFFBOARD, PX4_STABILIZED = range(1, 8)
PX4_AUTO_MISSION = 4


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
}

#: MAV_STANDARD_MODE a mode advertises in AVAILABLE_MODES/CURRENT_MODE (0: none).
STANDARD_MODE: dict[FlightMode, int] = {FlightMode.CRUISE: 3,     # MAV_STANDARD_MODE_CRUISE
                                        FlightMode.MISSION: 6}    # MAV_STANDARD_MODE_MISSION

_WIRE_TO_MODE = {v: k for k, v in MODE_WIRE.items()}


def custom_mode_of(mode: FlightMode) -> int:
    """HEARTBEAT/CURRENT_MODE ``custom_mode`` of ``mode``."""
    return MODE_WIRE[mode]


def mode_from_custom(value: float) -> int | None:
    """The hyfc mode number a requested custom mode means, or None if it means none.

    Accepted: the hyfc number itself (0..6, as ``long DO_SET_MODE 1 1``) or the exact
    ``custom_mode`` of a mode as sent in HEARTBEAT/AVAILABLE_MODES (QGroundControl's SET_MODE,
    tools/mavproxy_hyfc.py). NaN, fractions and anything else: None.
    """
    if not math.isfinite(value) or value != int(value):
        return None
    v = int(value)
    if v in _WIRE_TO_MODE:
        return int(_WIRE_TO_MODE[v])
    if 0 <= v <= 0xFFFF:
        return v          # a plain number; ModeManager.request_mode refuses the unknown ones
    return None


#: Modes in which the guidance (outer loop) runs and commands the law.
GUIDANCE_MODES = (FlightMode.CRUISE, FlightMode.GUIDED, FlightMode.MISSION)
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

    def set_armed(self, armed: bool, data_ok: bool) -> tuple[bool, str]:
        if armed and not data_ok:
            return False, "arming refused: no valid plant data"
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
