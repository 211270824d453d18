"""fc/point_mode.py - flying to a point and circling: RTL, DO_REPOSITION, DO_ORBIT.

The glue between the pure :class:`fc.guidance.waypoints.PointNavigator` and the fc (fc/app.py),
as fc/mission_mode.py is for missions: no sockets, clocks or logging. It sees the vehicle
through :class:`fc.mission_mode.MissionVehicle`.

- RTL mode: on entry, fly back toward home (the first fix, HOME_POSITION) at the altitude and
  speed of entry, then circle over it.
- DO_REPOSITION (GUIDED): fly to the point at its altitude (or the present target) and speed
  (param1 > 0, or the present target), then circle over it.
- DO_ORBIT (GUIDED): circle the centre at the radius given, if the envelope allows it.

The circle's radius is the least the guidance's bank limit allows with a quarter of its tangent
in reserve (:func:`fc.guidance.waypoints.orbit_radius_m` at the faster of the speed and its
target; docs/guidance.md section 2b: 1202 km at 2250 m/s with GE_MU_MAX 30
deg); an orbit asked smaller is refused with the least radius in the reason. :meth:`tick` runs
every guidance step (the navigator every ``NAV_DIV``-th, with a fresh fix, as a mission) and
sets the course target; the altitude and speed targets are set once, at the start.
"""
from __future__ import annotations

import math

from fc.control.layout import E_H, E_V
from fc.guidance.waypoints import NavParams, PointNavigator, orbit_radius_m, unit_vector
from fc.link import G_LAT_DEG, G_LON_DEG
from fc.link import mavlink as ML
from fc.mission_mode import NAV_DIV, MissionFlight, MissionVehicle, nav_params
from hyfc_wire.earth import EARTH_RADIUS_M

__all__ = ["PointFlight"]


class PointFlight:
    """RTL and GUIDED's point targets over a :class:`PointNavigator` (``nav``)."""

    def __init__(self) -> None:
        self.nav = PointNavigator(NavParams(earth_radius_m=EARTH_RADIUS_M))
        self.active = False            # a point or an orbit is being flown
        self.what = ""                 # "home", "reposition", "orbit" (texts, NAV output)
        self._changes = -1             # the mode-change count it was started under
        self._count = 0
        self._chi_set: float | None = None   # the last course target set here (rad)

    # ------------------------------------------------------------------ helpers
    @staticmethod
    def _fix(fc: MissionVehicle) -> bool:
        return MissionFlight._fix(fc)

    def _params(self, fc: MissionVehicle) -> None:
        nav_params(fc.params, self.nav.p)

    def least_radius_m(self, fc: MissionVehicle, v_m_s: float | None = None) -> float:
        """The least orbit radius (m) at ``v_m_s`` (default: the present speed)."""
        self._params(fc)
        v = float(fc.est.est[E_V]) if v_m_s is None else v_m_s
        return orbit_radius_m(max(v, 1.0), self.nav.p.mu_max_rad)

    def _here(self, fc: MissionVehicle) -> tuple[float, float]:
        g = fc.plant.gps
        return float(g[G_LAT_DEG]), float(g[G_LON_DEG])

    def entry_refusal(self, fc: MissionVehicle) -> str | None:
        """None if a point can be flown now, else the reason."""
        if not self._fix(fc) or fc.gcs.home is None:
            return "no GNSS fix"
        return None

    def orbit_refusal(self, fc: MissionVehicle, radius_m: float) -> str | None:
        """None if an orbit of ``radius_m`` can be flown now, else the reason."""
        reason = self.entry_refusal(fc)
        if reason is None and not (math.isfinite(radius_m) and radius_m != 0.0):
            reason = "radius must be a number other than 0"
        if reason is None:
            least = self.least_radius_m(fc)
            if abs(radius_m) < least:
                reason = (f"radius {abs(radius_m) / 1000:.0f} km below the "
                          f"{least / 1000:.0f} km the bank limit allows at "
                          f"{float(fc.est.est[E_V]):.0f} m/s (GE_MU_MAX)")
        return reason

    def stale(self, fc: MissionVehicle) -> bool:
        """The mode changed since the point was started."""
        return fc.modes.changes != self._changes

    # ------------------------------------------------------------------ starts
    def start_home(self, fc: MissionVehicle) -> str | None:
        """RTL: toward home at the present altitude and speed, then circle over it."""
        home = fc.gcs.home
        reason = self.entry_refusal(fc)
        if reason is None:
            reason = fc.set_guidance_targets(h_m=float(fc.est.est[E_H]),
                                             V_m_s=float(fc.est.est[E_V]))
        if reason is None:
            self._goto(fc, (home[0], home[1]), "home")
        return reason

    def start_point(self, fc: MissionVehicle, lat_deg: float, lon_deg: float,
                    h_m: float | None, v_m_s: float | None) -> str | None:
        """DO_REPOSITION: to (lat, lon) deg at ``h_m`` (m AMSL; None keeps the target) and
        ``v_m_s`` (None keeps it), then circle over it."""
        reason = self.entry_refusal(fc)
        if reason is None and not (-90.0 <= lat_deg <= 90.0 and -180.0 <= lon_deg <= 180.0):
            reason = f"position {lat_deg:g}, {lon_deg:g} deg not valid"
        if reason is None:
            reason = fc.set_guidance_targets(h_m=h_m, V_m_s=v_m_s)
        if reason is None:
            self._goto(fc, (lat_deg, lon_deg), "reposition")
        return reason

    def start_orbit(self, fc: MissionVehicle, lat_deg: float, lon_deg: float,
                    radius_m: float, h_m: float | None) -> str | None:
        """DO_ORBIT: circle (lat, lon) deg at |radius_m| (> 0 clockwise, < 0 counter-clockwise)
        at ``h_m`` (None keeps the target); refused below the least radius."""
        reason = self.orbit_refusal(fc, radius_m)
        if reason is None:
            reason = fc.set_guidance_targets(h_m=h_m)
        if reason is None:
            self.nav.orbit(unit_vector(lat_deg, lon_deg), abs(radius_m), radius_m > 0.0)
            self._started(fc, "orbit")
        return reason

    def _goto(self, fc: MissionVehicle, point: tuple[float, float], what: str) -> None:
        here = self._here(fc)
        v = max(float(fc.est.est[E_V]), fc.guidance_targets()[2])   # the faster: the wider
        self.nav.goto(unit_vector(*here), unit_vector(*point), self.least_radius_m(fc, v))
        self._started(fc, what)

    def _started(self, fc: MissionVehicle, what: str) -> None:
        self.active = True
        self.what = what
        self._changes = fc.modes.changes
        self._count = 0
        self._chi_set = None

    def stop(self) -> None:
        self.active = False

    # ------------------------------------------------------------------ the tick
    def tick(self, fc: MissionVehicle) -> list:
        """One call per guidance step while a point is flown. Returns STATUSTEXT outputs
        (``("text", severity, text)``), or ``("hold", why)`` if it cannot go on."""
        if self.stale(fc):                             # the mode changed: a new start is due
            self.active = False
            return []
        if self._chi_set is not None and fc.guidance_targets()[1] != self._chi_set:
            self.active = False                        # GUIDED_CHANGE_HEADING took over
            return [("text", ML.MAV_SEVERITY_INFO, f"{self.what}: ended by a course target")]
        due = self._count == 0
        self._count = (self._count + 1) % NAV_DIV
        if not due or not self._fix(fc):
            return []                                  # without a fresh fix: course held
        try:
            x_u = unit_vector(*self._here(fc))
            was = self.nav.arrived
            chi = self.nav.step(x_u)
            reason = fc.set_guidance_targets(chi_rad=chi)
            if reason is None:
                self._chi_set = fc.guidance_targets()[1]
        except Exception as exc:  # noqa: BLE001 - never reach the law as an exception
            self.active = False
            return [("hold", f"{self.what} navigation failed ({exc!r}): holding (CRUISE)")]
        out = []
        if reason is not None:
            out.append(("text", ML.MAV_SEVERITY_WARNING, f"{self.what} course refused: {reason}"))
        if self.nav.arrived and not was:
            out.append(("text", ML.MAV_SEVERITY_INFO, f"{self.what}: arrived, circling at "
                                   f"{self.nav.radius_m / 1000:.0f} km radius"))
        fc.guid.nav_wp = (self.nav.target_bearing(x_u), self.nav.dist_m, 0.0)
        return out
