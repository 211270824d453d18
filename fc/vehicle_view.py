"""fc/vehicle_view.py - what the ground-station link (fc/gcs.py) reads of and asks the vehicle.

:class:`VehicleView` names exactly the members ``GcsLink`` uses; the flight controller
(fc/app.py ``FlightController``) implements it, and so do the tests' stub vehicles. A member
``GcsLink`` starts to use goes here first (docs/architecture.md, the fc's parts).
"""
from __future__ import annotations

from typing import Callable, Protocol, Sequence, runtime_checkable

import numpy as np

from fc.link import LinkCounters
from fc.mission import Mission
from fc.params import ParamTable

__all__ = ["ModeView", "PlantView", "VehicleView"]


class ModeView(Protocol):
    """The flight mode state GcsLink reports (fc/modes.py ``ModeManager``)."""

    mode: int                   # fc.modes.FlightMode
    armed: bool
    data_lost: bool
    fs_cause: int               # why FAILSAFE was entered, 0 none

    @property
    def law_active(self) -> bool: ...


class PlantView(Protocol):
    """The plant link's GNSS sample and counters (fc/link.py ``PlantLink``)."""

    gps: np.ndarray             # newest GNSS sample, fc/link.py G_*
    gps_samples: int
    counters: LinkCounters


@runtime_checkable
class VehicleView(Protocol):
    """The vehicle as the ground-station link sees it."""

    sysid: int
    compid: int
    params: ParamTable          # the one parameter table (read; sets go through set_param)
    modes: ModeView
    plant: PlantView
    mission: Mission            # the stored mission (MISSION mode flies it)
    meas: np.ndarray            # newest sensor frame, fc/link.py M_*
    meas_stamp_us: int          # its plant-time stamp, us
    pwm_us: Sequence[int]       # newest servo outputs 1..4, us

    # commands: None / (True, text) on success, else the reason
    def set_param(self, name: str, value: float) -> str | None: ...

    # the parameter file written now, off the loop: ``done(error)`` is called (from the I/O
    # thread) once it is on disk (None) or could not be written (the error); False when the
    # vehicle keeps no file (nothing to wait for)
    def save_params(self, done: Callable[[str | None], None]) -> bool: ...

    def request_mode(self, mode: int) -> tuple[bool, str]: ...

    def arm(self, armed: bool, forced: bool = False) -> tuple[bool, str]: ...

    def set_attitude_command(self, alpha_deg: float, beta_deg: float,
                             mu_deg: float) -> str | None: ...

    def set_guidance_targets(self, h_m: float | None = None, chi_rad: float | None = None,
                             V_m_s: float | None = None) -> str | None: ...

    def change_speed(self, v_m_s: float) -> str | None: ...

    def go_to(self, lat_deg: float, lon_deg: float, h_m: float | None,
              v_m_s: float | None) -> str | None: ...

    def orbit(self, lat_deg: float, lon_deg: float, radius_m: float,
              h_m: float | None) -> str | None: ...

    # telemetry sources
    def health_failed_bits(self) -> int: ...

    def error_counts(self) -> tuple[int, int, int, int, int]: ...

    def load_permille(self) -> int: ...

    def throttle_percent(self) -> int: ...

    def named_values(self) -> list: ...

    def debug_vectors(self) -> list: ...

    def nav_controller_output(self): ...
