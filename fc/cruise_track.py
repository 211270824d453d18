"""fc/cruise_track.py - CRUISE's course on a round Earth: hold the great circle.

CRUISE holds the altitude, course and speed it was engaged at (fc/guided.py). On the sphere
a constant course is a rhumb line: flown north it runs into the pole, where every direction is
south, and the guidance would turn back. What a vehicle holding its course is meant to do is
fly straight, i.e. along a great circle. So, while CRUISE flies and the GNSS has a fresh fix,
every ``NAV_DIV``-th guidance step (10 Hz) :class:`CruiseTrack` sets the course target to the
course, at the vehicle's position, of the great circle it was on when CRUISE began (or when
the course target was last changed by someone else: the circle then starts at that course,
from where the vehicle is). The position is the newest GNSS sample moved along the circle by
the ground speed times the sample's age, so the target refers to where the vehicle is when
it is set, as the measured course does; it then holds for NAV_DIV guidance steps (0.1 s,
225 m at Mach 7.5): straight over a pole the two can disagree for at most that long.

No cross-track term: the circle is the one the vehicle is on (a drift sideways moves the
circle with it, as a course hold does on a flat earth). Geometry in fc/guidance/waypoints.py
(``gc_pole``, ``gc_course_rad``; tests/unit/control/test_waypoints_sphere.py). No sockets,
clocks or logging here: fc/app.py calls :meth:`CruiseTrack.tick` after each guidance step in
CRUISE. The target is set on the guidance itself (``GuidanceRunner.set_targets``), not
through the fc's logged ``set_guidance_targets``: 10 Hz of course updates are not events.
"""
from __future__ import annotations

import math

from fc.guidance.waypoints import gc_course_rad, gc_pole, unit_vector
from fc.link import G_LAT_DEG, G_LON_DEG, G_T_S, G_VE, G_VN
from fc.mission_mode import NAV_DIV, MissionFlight

__all__ = ["CruiseTrack"]


class CruiseTrack:
    """The great circle CRUISE holds (module docstring). ``pole`` is None until the first
    fresh fix after entering CRUISE."""

    def __init__(self, earth_radius_m: float) -> None:
        self.r_m = float(earth_radius_m)
        self.pole: tuple[float, float, float] | None = None
        self._chi_set = math.nan            # the course target this class set last (rad)
        self._changes_seen = -1
        self._count = 0

    def tick(self, fc) -> None:
        """One call per guidance step in CRUISE (``fc``: fc/app.py's FlightController, read
        through the members MissionFlight's MissionVehicle names, plus ``guid``)."""
        if fc.modes.changes != self._changes_seen:     # (re-)entered: a new circle
            self._changes_seen = fc.modes.changes
            self.pole = None
            self._count = 0
        due = self._count == 0
        self._count = (self._count + 1) % NAV_DIV
        if not due or not MissionFlight._fix(fc):
            return                                      # no fresh fix: the target holds
        g = fc.plant.gps
        x = unit_vector(float(g[G_LAT_DEG]), float(g[G_LON_DEG]))
        chi_t = fc.guid.targets()[1]
        if self.pole is None or chi_t != self._chi_set:
            self.pole = gc_pole(x, chi_t)               # the circle at that course, from here
        n = self.pole
        # where the vehicle is now: the sample moved along the circle by ground speed x age
        age_s = max(0.0, fc.meas_stamp_us * 1e-6 - float(g[G_T_S]))
        th = math.hypot(float(g[G_VN]), float(g[G_VE])) * age_s / self.r_m
        nx = (n[1] * x[2] - n[2] * x[1], n[2] * x[0] - n[0] * x[2], n[0] * x[1] - n[1] * x[0])
        c, s = math.cos(th), math.sin(th)
        x = (c * x[0] + s * nx[0], c * x[1] + s * nx[1], c * x[2] + s * nx[2])
        chi = gc_course_rad(n, x)
        if fc.guid.set_targets(chi_rad=chi) is None:
            self._chi_set = fc.guid.targets()[1]
