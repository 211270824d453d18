"""fc/guidance/waypoints.py's great-circle geometry against the geodesy library (pymap3d's
geodesics on the same sphere), and a mission flown over the pole and across the antimeridian
(issue 21: navigation must stay right where a flat map about home breaks)."""
import math

import numpy as np
import pymap3d
import pytest
from pymap3d import vincenty

from fc.guidance.waypoints import (EARTH_RADIUS_M, NavParams, WaypointNavigator, gc_azimuth_rad,
                                   gc_course_rad, gc_distance_m, gc_leg, gc_pole, unit_vector)
from fc.mission import CMD_WAYPOINT
from hyfc_wire.earth import EARTH_RADIUS_M as CONTRACT_RADIUS_M

SPHERE = pymap3d.Ellipsoid.from_name("wgs84_mean")
PAIRS = [((34.9054, -117.8839), (51.47, -0.45)),        # Edwards -> London
         ((10.0, 179.5), (-5.0, -170.0)),               # across the antimeridian
         ((89.9, 0.0), (89.9, 180.0)),                  # over the north pole
         ((-88.0, -30.0), (-85.0, 150.0)),              # over the south pole
         ((0.0, 0.0), (0.5, 179.0)),                    # nearly antipodal
         ((45.0, 10.0), (45.0, 10.00001))]              # a metre apart


def test_the_navigators_sphere_is_the_contracts():
    assert EARTH_RADIUS_M == CONTRACT_RADIUS_M == SPHERE.semimajor_axis == SPHERE.semiminor_axis
    assert NavParams().earth_radius_m == CONTRACT_RADIUS_M


@pytest.mark.parametrize("a, b", PAIRS)
def test_distance_and_course_match_the_library(a, b):
    d_ref, az_ref = vincenty.vdist(*a, *b, SPHERE)
    ua, ub = unit_vector(*a), unit_vector(*b)
    assert gc_distance_m(ua, ub) == pytest.approx(float(d_ref), rel=1e-9, abs=1e-6)
    if float(d_ref) > 1.0:
        dc = (math.degrees(gc_azimuth_rad(ua, ub)) - float(az_ref) + 180.0) % 360.0 - 180.0
        assert abs(dc) < 1e-6


@pytest.mark.parametrize("a, b", PAIRS[:4])
def test_leg_geometry_along_and_beside_the_great_circle(a, b):
    # GIVEN a leg A -> B and points along it (the library's direct problem)
    d_ref, az0 = vincenty.vdist(*a, *b, SPHERE)
    pa, pb = unit_vector(*a), unit_vector(*b)
    for frac in (0.0, 0.3, 0.7):
        s = frac * float(d_ref)
        lat, lon = vincenty.vreckon(*a, s, float(az0), SPHERE)
        x = unit_vector(float(lat), float(lon))
        chi, e, to_go, dist = gc_leg(pa, pb, x)
        # THEN on it: no cross-track error, the rest of the leg to go, the course toward B
        assert abs(e) < 1e-3 and to_go == pytest.approx(float(d_ref) - s, abs=1e-3)
        _, az_x = vincenty.vdist(float(lat), float(lon), *b, SPHERE)
        assert abs((math.degrees(chi) - float(az_x) + 180.0) % 360.0 - 180.0) < 1e-6
        # AND 10 km to the right of it: e = +10 km (and, away from the poles' meridian
        # convergence, about the same course)
        rlat, rlon = vincenty.vreckon(float(lat), float(lon), 10e3, float(az_x) + 90.0, SPHERE)
        chi_r, e_r, _, _ = gc_leg(pa, pb, unit_vector(float(rlat), float(rlon)))
        assert e_r == pytest.approx(10e3, abs=1.0)
        if abs(float(lat)) < 80.0:
            assert abs((chi_r - chi + math.pi) % (2 * math.pi) - math.pi) < 3e-3


def test_great_circle_hold_course_flips_at_the_pole_and_stays_on_the_circle():
    # GIVEN the great circle flown north from 85 N along 117.9 W
    x0 = unit_vector(85.0, -117.9)
    n = gc_pole(x0, 0.0)
    courses = []
    for s in np.arange(0.0, 1.2e6, 50e3):
        lat, lon = vincenty.vreckon(85.0, -117.9, float(s), 0.0, SPHERE)
        x = unit_vector(float(lat), float(lon))
        assert abs(np.dot(n, x)) < 1e-9                 # every point is on the circle
        courses.append(math.degrees(gc_course_rad(n, x)))
    # THEN its course is north before the pole (556 km on), south after it
    courses = np.array(courses)
    assert np.allclose(courses[:11], 0.0, atol=1e-6) or np.allclose(courses[:11] % 360.0, 0.0, atol=1e-6)
    assert np.allclose(courses[12:], 180.0, atol=1e-6)


class _Mission:
    def __init__(self, items):
        self.items, self.current, self.finished, self.version = items, 0, False, 0

    @property
    def count(self):
        return len(self.items)

    def item(self, seq):
        return self.items[seq]

    def advance(self, seq):
        if seq + 1 < self.count:
            self.current = seq + 1
        else:
            self.finished = True
        return [("reached", seq)]


def _wp(lat, lon):
    return {"command": CMD_WAYPOINT, "frame": 0, "x": int(round(lat * 1e7)),
            "y": int(round(lon * 1e7)), "z": 28000.0, "param1": 0.0, "param2": 0.0,
            "param3": 0.0, "param4": 0.0, "autocontinue": 1}


@pytest.mark.parametrize("start, wps", [
    ((80.0, -117.9), [(85.0, 62.1), (70.0, 62.1)]),      # over the north pole and on south
    ((10.0, 175.0), [(10.5, -178.0), (11.0, -170.0)]),   # across the antimeridian
])
def test_mission_over_the_pole_and_across_the_antimeridian(start, wps):
    # GIVEN a mission whose legs cross the pole or the antimeridian, flown along its great
    # circles (the library's direct problem, 5 km per step)
    mis = _Mission([_wp(*w) for w in wps])
    nav = WaypointNavigator(NavParams(accept_m=2000.0, mu_max_rad=math.radians(0.001)))
    nav.start(mis, (start[0], start[1], 0.0), start, 28000.0, 0.0, 2250.0)
    reached = []
    pts = [start] + [(mis.item(k)["x"] * 1e-7, mis.item(k)["y"] * 1e-7) for k in range(2)]
    for leg in range(2):
        d, az = vincenty.vdist(*pts[leg], *pts[leg + 1], SPHERE)
        for s in np.arange(0.0, float(d) + 5e3, 5e3):
            lat, lon = vincenty.vreckon(*pts[leg], float(s), float(az), SPHERE)
            _, chi, _, out = nav.step(mis, float(lat), float(lon), 2250.0)
            reached += [o[1] for o in out]
            if not mis.finished and mis.current == leg:
                # THEN on the leg the course target is the leg's own course there, no
                # cross-track error
                _, az_here = vincenty.vdist(float(lat), float(lon), *pts[leg + 1], SPHERE)
                if float(d) - s > 10e3:
                    assert abs((math.degrees(chi) - float(az_here) + 180) % 360 - 180) < 1e-3
                    assert abs(nav.xt_m) < 1.0
    # AND every waypoint is reached once, in order, within the acceptance radius
    assert reached == [0, 1] and mis.finished
