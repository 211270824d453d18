"""fc/cruise_track.py - CRUISE's course on a round Earth: hold the great circle.

CRUISE holds the altitude, course and speed it was engaged at (fc/guided.py). On the sphere
a constant course is a rhumb line: flown north it runs into the pole, where every direction is
south, and the guidance would turn back. What a vehicle holding its course is meant to do is
fly straight, i.e. along a great circle: the circle of pole vector n through the vehicle's
position at engagement, at the course it had (or, when someone else changes the course
target, through where the vehicle is then, at that course).

The guidance steers a north-referenced course error, e = wrap(chi_t - chi), with chi the
air-data course of the frame (fc/guided.py). So :meth:`CruiseTrack.tick` runs on **every**
guidance step, after the frame's inputs are read and before the step
(``GuidanceRunner.tick(..., before_step)``), and sets chi_t to the course, at the vehicle's
position at that frame, of the circle n: the direction n x x. Target and measured course then
refer to the same point and the same instant, and their difference is the angle between the
velocity and the circle, which does not depend on where north is. (Until issue 20 the target
was set at 10 Hz after the step: 3 km from the pole, where the circle's course turns at
V / d = 43 deg/s, the target lagged the measured course by 1-4 deg and the course loop banked
the vehicle 10-14 deg.)

The position x is the newest GNSS sample moved along the circle by the ground speed times the
sample's age. Near a pole that is not enough: north at x and north where the vehicle truly is
differ by the position error over the distance d to the pole (1.5 m at 3 km: 0.03 deg, 1 deg
at 90 m, anything at the pole itself), and the course loop's gain (about 12 deg of bank per
deg) would fly that. So within ``pole_guard_m`` of a pole (3 sigma of the receiver's
horizontal accuracy G_HACC_M, at least 1 m, over ``NORTH_TOL_RAD``: 5.2 km at 1.5 m) the
target is the measured course plus the guidance's own filtered course error (``GX_CHI_ERR_F``):
the course loop's input equals its filter's state, so the bank command holds what it was when
the vehicle entered the guard (about zero in a straight cruise), and the vehicle flies straight
through (4.6 s at Mach 7.5). Leaving the guard, the circle's course takes over again; no
transient, as the vehicle has flown the circle's great circle meanwhile.

No cross-track term: the circle is the one the vehicle is on (a drift sideways flies the
parallel circle, the course of n x x, as a course hold does on a flat earth). Without a fresh
fix (older than GNSS_MAX_AGE_S) the target holds, as before. Geometry in
fc/guidance/waypoints.py (``gc_pole``, ``gc_course_rad``; tests/unit/control/
test_waypoints_sphere.py). No sockets, clocks or logging here. The target is set on the
guidance itself (``GuidanceRunner.set_targets``), not through the fc's logged
``set_guidance_targets``: 50 Hz of course updates are not events.
"""
from __future__ import annotations

import math

from fc.guidance.waypoints import gc_course_rad, gc_pole, unit_vector
from fc.link import G_ALT_M, G_HACC_M, G_LAT_DEG, G_LON_DEG, G_T_S, G_VE, G_VN
from fc.mission_mode import MissionFlight

__all__ = ["CruiseTrack", "NORTH_TOL_RAD", "pole_guard_m"]

#: the largest error (rad) of the north reference, at 3 sigma of the GNSS position, with which
#: the circle's course is steered; closer to a pole the course loop holds (module docstring)
NORTH_TOL_RAD = math.radians(0.05)


def pole_guard_m(hacc_m: float) -> float:
    """Radius (m) about a pole within which north is not known to NORTH_TOL_RAD from a GNSS
    position of horizontal accuracy ``hacc_m`` (1 sigma, m; at least 1 m is assumed)."""
    h = hacc_m if math.isfinite(hacc_m) and hacc_m > 1.0 else 1.0
    return 3.0 * h / NORTH_TOL_RAD


def _wrap(a: float) -> float:
    return (a + math.pi) % (2.0 * math.pi) - math.pi


class CruiseTrack:
    """The great circle CRUISE holds (module docstring). ``pole`` is None until the first
    fresh fix after entering CRUISE; ``guarded`` is True while the vehicle is within the pole
    guard (the course loop holds)."""

    def __init__(self, earth_radius_m: float) -> None:
        self.r_m = float(earth_radius_m)
        self.pole: tuple[float, float, float] | None = None
        self.guarded = False
        self._chi_set = math.nan            # the course target this class set last (rad)
        self._changes_seen = -1

    def tick(self, fc) -> None:
        """One call per guidance step in CRUISE, before the step, with the frame's inputs read
        (``fc``: fc/app.py's FlightController, read through the members MissionFlight's
        MissionVehicle names, plus ``guid``: its ``chi_rad`` is the frame's course)."""
        if fc.modes.changes != self._changes_seen:     # (re-)entered: a new circle
            self._changes_seen = fc.modes.changes
            self.pole = None
            self.guarded = False
        if not MissionFlight._fix(fc):
            return                                      # no fresh fix: the target holds
        g = fc.plant.gps
        x = unit_vector(float(g[G_LAT_DEG]), float(g[G_LON_DEG]))
        chi_t = fc.guid.targets()[1]
        if self.pole is None or chi_t != self._chi_set:
            self.pole = gc_pole(x, chi_t)               # the circle at that course, from here
        n = self.pole
        # where the vehicle is now: the sample moved along the circle by ground speed x age
        age_s = max(0.0, fc.meas_stamp_us * 1e-6 - float(g[G_T_S]))
        th = math.hypot(float(g[G_VN]), float(g[G_VE])) * age_s / (self.r_m + float(g[G_ALT_M]))
        nx = (n[1] * x[2] - n[2] * x[1], n[2] * x[0] - n[0] * x[2], n[0] * x[1] - n[1] * x[0])
        c, s = math.cos(th), math.sin(th)
        x = (c * x[0] + s * nx[0], c * x[1] + s * nx[1], c * x[2] + s * nx[2])
        d_pole_m = self.r_m * math.atan2(math.hypot(x[0], x[1]), abs(x[2]))
        self.guarded = d_pole_m < pole_guard_m(float(g[G_HACC_M]))
        if self.guarded:       # hold the course loop: its input = its filter's state
            chi = _wrap(fc.guid.chi_rad + fc.guid.course_error_filtered())
        else:
            chi = gc_course_rad(n, x)
        if fc.guid.set_targets(chi_rad=chi) is None:
            self._chi_set = fc.guid.targets()[1]
