"""fc/mission_mode.py - MISSION mode: the stored mission (fc/mission.py) flown by the guidance.

The glue between the pure waypoint navigator (fc/guidance/waypoints.py) and the fc (fc/app.py):
no sockets, clocks or logging. The fc calls

- :meth:`MissionFlight.entry_refusal` before entering MISSION: refused with no mission or
  without a fresh 3D GNSS fix and home (the first fix, fc/gcs.py);
- :meth:`MissionFlight.tick` after each guidance step in MISSION: every ``NAV_DIV``-th call
  (10 Hz at the guidance's 50 Hz: 225 m of flight at Mach 7, against a 2 km acceptance radius)
  it steps the navigator with the newest GNSS sample and sets the guidance's targets
  (``set_guidance_targets``: validated against the envelope; a refused target is reported once
  and the previous one kept) and NAV_CONTROLLER_OUTPUT's waypoint bearing and distance. It
  returns the mission's outputs for ``GcsLink.mission_send`` (MISSION_ITEM_REACHED,
  MISSION_CURRENT, texts).

Safety (docs/fc.md section 5, "ground-station input"): the navigator is the one place where
the ground station's mission reaches the guidance while it flies. A mission replaced or
cleared under it (``Mission.generation`` changed since entry), or any exception of the
navigator, never reaches the law: ``tick`` returns ``("hold", why)`` and the fc switches to
CRUISE (holding the current altitude, course and speed) with a STATUSTEXT saying why.

On entry (any mode change seen through ``ModeManager.changes``) the first leg starts at the
current position, the targets start at the current altitude, course and speed, and a finished
mission starts over from item 0. The navigator's parameters are the fc's (:data:`MISSION_PARAMS`,
appended to the fc's table, read at every navigator step): WP_ACCEPT_M (an item's param2
overrides it), WP_XT_LEN_M, WP_XT_ANG_DEG; the bank used for turn anticipation is the
guidance's GE_MU_MAX less GE_MU_MARGIN (the bank it commands).
"""
from __future__ import annotations

import math
from typing import Protocol

import numpy as np

from fc.control.layout import E_H, E_V
from fc.guidance.waypoints import (NavParams, WaypointNavigator, gc_azimuth_rad, gc_distance_m,
                                   unit_vector)
from fc.link import G_FIX, G_LAT_DEG, G_LON_DEG, G_T_S
from fc.link import mavlink as ML
from fc.mission_params import MISSION_PARAMS
from fc.params import ParamTable
from fc.vehicle_view import PlantView
from hyfc_wire.earth import EARTH_RADIUS_M

__all__ = ["MissionFlight", "MissionVehicle", "MISSION_PARAMS", "NAV_DIV", "GNSS_MAX_AGE_S",
           "nav_params"]

NAV_DIV = 5                 # navigator steps every NAV_DIV guidance steps
GNSS_MAX_AGE_S = 1.0        # a GNSS sample older than this (plant time) is not a fix


def nav_params(par: ParamTable, p: NavParams) -> None:
    """A navigator's parameters ``p`` from the fc's table ``par`` (SI): WP_ACCEPT_M,
    WP_XT_LEN_M, WP_XT_ANG_DEG, and the bank the guidance commands (GE_MU_MAX less
    GE_MU_MARGIN). Read at every navigator step, so a PARAM_SET applies while flying."""
    if "WP_ACCEPT_M" in par:
        p.accept_m = par.get("WP_ACCEPT_M")
        p.xt_len_m = par.get("WP_XT_LEN_M")
        p.chi_int_rad = math.radians(par.get("WP_XT_ANG_DEG"))
    if "GE_MU_MAX" in par:
        p.mu_max_rad = math.radians(par.get("GE_MU_MAX") - par.get("GE_MU_MARGIN"))


class _Home(Protocol):
    home: tuple[float, float, float] | None     # (lat deg, lon deg, alt m): the first fix


class _Estimate(Protocol):
    est: np.ndarray                             # the state estimate, fc/control/layout.py E_*


class _ModeChanges(Protocol):
    changes: int                                # counts mode changes (fc/modes.py)


class _NavOutput(Protocol):
    nav_wp: tuple[float, float, float] | None   # (bearing rad, distance m, cross-track m)


class MissionVehicle(Protocol):
    """What MISSION mode reads of and asks the vehicle: exactly the members
    :class:`MissionFlight` uses (fc/app.py ``FlightController`` implements it; a test's stub
    can too). A member MissionFlight starts to use goes here first."""

    plant: PlantView            # the newest GNSS sample (``plant.gps``, fc/link.py G_*)
    meas_stamp_us: int          # plant time of the newest sensor frame, us
    params: ParamTable          # the navigator's parameters (MISSION_PARAMS, GE_MU_*)
    gcs: _Home
    est: _Estimate
    modes: _ModeChanges
    guid: _NavOutput            # NAV_CONTROLLER_OUTPUT's waypoint, written here

    def guidance_targets(self) -> tuple[float, float, float]: ...

    def set_guidance_targets(self, h_m: float | None = None, chi_rad: float | None = None,
                             V_m_s: float | None = None) -> str | None: ...


class MissionFlight:
    """MISSION mode over a :class:`fc.mission.Mission` (``mission``)."""

    def __init__(self, mission, params: NavParams | None = None) -> None:
        self.mission = mission
        self.nav = WaypointNavigator(params or NavParams(earth_radius_m=EARTH_RADIUS_M))
        self._changes_seen = -1
        self._generation = -1                  # the mission's items flown since entry
        self._count = 0
        self._refused: tuple | None = None     # the last refused targets (reported once)

    @staticmethod
    def _fix(fc: MissionVehicle) -> bool:
        g = fc.plant.gps        # (``item``: Python floats, no numpy scalar per call)
        return (int(g.item(G_FIX)) >= ML.GPS_FIX_TYPE_3D_FIX
                and fc.meas_stamp_us * 1e-6 - g.item(G_T_S) <= GNSS_MAX_AGE_S)

    def entry_refusal(self, fc: MissionVehicle) -> str | None:
        """None if MISSION may be entered, else the reason."""
        if self.mission.count == 0:
            return "MISSION refused: no mission stored"
        if not self._fix(fc) or fc.gcs.home is None:
            return "MISSION refused: no GNSS fix"
        return None

    def _params(self, fc: MissionVehicle) -> None:
        """The navigator's parameters from the fc's table (SI)."""
        nav_params(fc.params, self.nav.p)

    def _start(self, fc: MissionVehicle) -> list:
        out = self.mission.restart() if self.mission.finished else []
        g = fc.plant.gps
        self._params(fc)
        _, chi, _ = fc.guidance_targets()
        self.nav.start(self.mission, fc.gcs.home, (float(g[G_LAT_DEG]), float(g[G_LON_DEG])),
                       float(fc.est.est[E_H]), chi, float(fc.est.est[E_V]))
        self._generation = self.mission.generation
        self._count = 0
        self._refused = None
        return out

    def set_speed(self, fc: MissionVehicle, v_m_s: float) -> str | None:
        """DO_CHANGE_SPEED while the mission flies: the speed target from now on (until a
        speed item of the mission changes it again), validated against the envelope. None on
        success, else the reason."""
        reason = fc.set_guidance_targets(V_m_s=v_m_s)
        if reason is None:
            self.nav.v_t = float(v_m_s)
        return reason

    def tick(self, fc: MissionVehicle) -> list:
        """One call per guidance step in MISSION. Returns outputs for ``mission_send``, and
        ``("hold", why)`` when MISSION must hold instead (the mission changed under it, or the
        navigator failed): the caller switches to CRUISE."""
        try:
            return self._tick(fc)
        except Exception as exc:  # noqa: BLE001 - GCS-made state must never reach the law
            return [("hold", f"mission navigation failed ({exc!r}): holding (CRUISE)")]

    def _tick(self, fc: MissionVehicle) -> list:
        out = []
        if fc.modes.changes != self._changes_seen:
            self._changes_seen = fc.modes.changes
            out += self._start(fc)
        elif self.mission.generation != self._generation:
            what = "cleared" if self.mission.count == 0 else "replaced"
            return [("hold", f"mission {what} while flying it: holding altitude, course and "
                             f"speed (CRUISE); set MISSION to fly the new one")]
        due = self._count == 0
        self._count = (self._count + 1) % NAV_DIV
        if not due or not self._fix(fc):
            return out           # without a fresh fix the last targets are held
        self._params(fc)
        g = fc.plant.gps
        lat, lon = float(g[G_LAT_DEG]), float(g[G_LON_DEG])
        h_t, chi_t, v_t, msgs = self.nav.step(self.mission, lat, lon, float(fc.est.est[E_V]))
        out += msgs
        targets = (h_t, chi_t, v_t)
        reason = fc.set_guidance_targets(h_m=h_t, chi_rad=chi_t, V_m_s=v_t)
        if reason is not None and targets != self._refused:
            self._refused = targets
            out.append(("text", ML.MAV_SEVERITY_WARNING, f"mission target refused: {reason}"))
        if self.mission.finished:
            fc.guid.nav_wp = None
        else:
            it = self.mission.item(self.mission.current)
            w = unit_vector(it["x"] * 1e-7, it["y"] * 1e-7)
            x = unit_vector(lat, lon)
            fc.guid.nav_wp = (gc_azimuth_rad(x, w), gc_distance_m(x, w, self.nav.p.earth_radius_m),
                              self.nav.xt_m)
        return out
