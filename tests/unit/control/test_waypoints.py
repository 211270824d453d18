"""fc/guidance/waypoints.py: the waypoint navigation law alone (tier 1).

Bearing signs in each quadrant, cross-track correction direction, turn anticipation,
acceptance and sequencing through a mission, DO_CHANGE_SPEED, end of mission (hold).
Positions are placed on the navigator's sphere with pymap3d's geodesics (``_latlon``).
"""
import math

import pymap3d
import pytest
from pymap3d import vincenty

from fc.guidance.waypoints import (NavParams, WaypointNavigator, course_target, leg_geometry,
                                   local_ne, switch_distance_m, turn_radius_m)
from fc.mission import CMD_CHANGE_SPEED, CMD_WAYPOINT

HOME = (34.9054, -117.8839, 28000.0)


class FakeMission:
    """The part of fc.mission.Mission the navigator uses, over a list of item dicts."""

    def __init__(self, items):
        self.items = items
        self.current = 0
        self.finished = False
        self.version = 0
        self.reached = []

    @property
    def count(self):
        return len(self.items)

    def item(self, seq):
        return self.items[seq]

    def advance(self, seq):
        self.reached.append(seq)
        if seq + 1 < self.count:
            self.current = seq + 1
        else:
            self.finished = True
        return [("reached", seq), ("current",)]


SPHERE = pymap3d.Ellipsoid.from_name("wgs84_mean")     # the navigator's sphere


def _latlon(north_m, east_m, origin=HOME):
    """The point ``hypot(north, east)`` from ``origin`` along the great circle of azimuth
    atan2(east, north) (pymap3d's direct problem on the sphere): a straight line north is a
    meridian."""
    lat, lon = vincenty.vreckon(origin[0], origin[1], math.hypot(north_m, east_m),
                                math.degrees(math.atan2(east_m, north_m)), SPHERE)
    return float(lat), float(lon)


def _wp(north_m, east_m, alt_m, frame=0, accept_m=0.0, origin=HOME):
    lat, lon = _latlon(north_m, east_m, origin)
    return {"command": CMD_WAYPOINT, "frame": frame, "x": int(round(lat * 1e7)),
            "y": int(round(lon * 1e7)), "z": alt_m, "param1": 0.0, "param2": accept_m,
            "param3": 0.0, "param4": 0.0, "autocontinue": 1}


def _speed(v):
    return {"command": CMD_CHANGE_SPEED, "frame": 2, "x": 0, "y": 0, "z": 0.0, "param1": 0.0,
            "param2": v, "param3": -1.0, "param4": 0.0, "autocontinue": 1}


def test_local_ne_round_trip_and_scale():
    n1, _ = local_ne(HOME[0] + 1.0, HOME[1], HOME[0], HOME[1])
    _, e1 = local_ne(HOME[0], HOME[1] + 1.0, HOME[0], HOME[1])
    lat, lon = HOME[0] + 100e3 / n1, HOME[1] - 50e3 / e1
    n, e = local_ne(lat, lon, HOME[0], HOME[1])
    assert n == pytest.approx(100e3, abs=0.1) and e == pytest.approx(-50e3, abs=0.1)
    n1, _ = local_ne(HOME[0] + 1.0, HOME[1], HOME[0], HOME[1])
    assert 110.0e3 < n1 < 111.5e3               # a degree of latitude, m


@pytest.mark.parametrize("dn, de, chi_deg", [
    (1.0, 0.0, 0.0), (1.0, 1.0, 45.0), (0.0, 1.0, 90.0), (-1.0, 1.0, 135.0),
    (-1.0, 0.0, 180.0), (-1.0, -1.0, 225.0), (0.0, -1.0, 270.0), (1.0, -1.0, 315.0)])
def test_bearing_in_each_quadrant(dn, de, chi_deg):
    # GIVEN a leg from the origin to a point 100 km away in each direction, vehicle on it
    chi, e, to_go, dist = leg_geometry((0.0, 0.0), (dn * 1e5, de * 1e5), (0.0, 0.0))
    assert math.degrees(chi) % 360.0 == pytest.approx(chi_deg)
    assert e == pytest.approx(0.0, abs=1e-6) and to_go == pytest.approx(dist)
    assert math.degrees(course_target(chi, 0.0, 5e4, 0.35)) == pytest.approx(chi_deg % 360.0)


@pytest.mark.parametrize("offset_e, sign", [(10e3, -1.0), (-10e3, 1.0)])
def test_cross_track_turns_toward_the_leg(offset_e, sign):
    # GIVEN a northbound leg and the vehicle 10 km east (right) or west (left) of it
    chi, e, _, _ = leg_geometry((0.0, 0.0), (200e3, 0.0), (50e3, offset_e))
    assert e == pytest.approx(offset_e)
    c = course_target(chi, e, 5e4, math.radians(20.0))
    dc = (c + math.pi) % (2 * math.pi) - math.pi
    assert math.copysign(1.0, dc) == sign        # steer back toward the leg
    assert abs(dc) < math.radians(20.0)          # never beyond the intercept angle
    far = course_target(chi, 1e9 * math.copysign(1.0, e), 5e4, math.radians(20.0))
    assert abs((far + math.pi) % (2 * math.pi) - math.pi) == pytest.approx(math.radians(20.0), rel=1e-4)


def test_turn_anticipation_distance():
    r = turn_radius_m(2250.0, math.radians(25.0))
    assert r == pytest.approx(2250.0**2 / (9.80665 * math.tan(math.radians(25.0))))
    assert 1.0e6 < r < 1.2e6                     # ~1100 km at Mach 7
    d30 = switch_distance_m(2250.0, math.radians(25.0), math.radians(30.0), 2000.0)
    assert d30 == pytest.approx(r * math.tan(math.radians(15.0)))
    assert switch_distance_m(2250.0, math.radians(25.0), 0.0, 2000.0) == 2000.0
    assert switch_distance_m(2250.0, math.radians(25.0), math.radians(-30.0), 0.0) == pytest.approx(d30)


def _fly(nav, mis, path):
    """Step the navigator along a list of (north, east) positions; return the targets."""
    out = []
    for n, e in path:
        lat, lon = _latlon(n, e)
        h, chi, v, msgs = nav.step(mis, lat, lon, 2250.0)
        out.append((h, chi, v, msgs))
    return out


def test_sequencing_speed_items_and_end_of_mission():
    # GIVEN a straight mission north: wp 50 km (relative alt +2 km), speed 2350, wp 100 km
    mis = FakeMission([_wp(50e3, 0.0, 2000.0, frame=3), _speed(2350.0), _wp(100e3, 0.0, 29000.0)])
    nav = WaypointNavigator(NavParams(accept_m=2000.0))
    nav.start(mis, HOME, _latlon(0.0, 0.0), 28000.0, 0.0, 2250.0)
    # WHEN it is flown along the line, 1 km per step
    res = _fly(nav, mis, [(k * 1e3, 0.0) for k in range(0, 121)])
    # THEN the first target is wp 0 at home + 2 km, course north, speed unchanged
    h, chi, v, _ = res[0]
    assert h == pytest.approx(30000.0) and chi == pytest.approx(0.0, abs=1e-9) and v == 2250.0
    # wp 0 is reached 2 km before it (no turn at it: the acceptance radius), the speed item
    # applies at once, wp 1 next
    k0 = next(k for k, r in enumerate(res) if ("reached", 0) in r[3])
    assert k0 in (48, 49)                        # 2 km before it (degE7 rounding)
    assert ("reached", 1) in res[k0][3]
    assert res[k0][0] == pytest.approx(29000.0) and res[k0][2] == 2350.0
    k2 = next(k for k, r in enumerate(res) if ("reached", 2) in r[3])
    assert k2 in (98, 99) and mis.finished and mis.reached == [0, 1, 2]
    # after the end: the last targets held, nothing more reported
    assert all(r[:3] == res[k2][:3] and r[3] == [] for r in res[k2 + 1:])


def test_turn_switches_at_anticipation_distance_and_passed_waypoint():
    # GIVEN wp 0 400 km north then wp 1 turning 30 deg right (the great circle's course at
    # wp 0 changes from 0 to 30 deg)
    w1 = (500e3 * math.cos(math.radians(30.0)), 500e3 * math.sin(math.radians(30.0)))
    mis = FakeMission([_wp(400e3, 0.0, 28000.0),
                       _wp(*w1, 28000.0, origin=_latlon(400e3, 0.0))])
    nav = WaypointNavigator(NavParams(mu_max_rad=math.radians(25.0)))
    nav.start(mis, HOME, _latlon(0.0, 0.0), 28000.0, 0.0, 2250.0)
    d = switch_distance_m(2250.0, math.radians(25.0), math.radians(30.0), 2000.0)
    res = _fly(nav, mis, [(k * 1e3, 0.0) for k in range(0, 400)])
    k0 = next(k for k, r in enumerate(res) if ("reached", 0) in r[3])
    assert 400e3 - k0 * 1e3 == pytest.approx(d, abs=1e3)    # switched ~d before it
    # the next leg runs from wp 0 at 30 deg; the vehicle, 295 km before wp 0, is right of
    # that line extended back: it turns right, less than the leg's course
    chi = math.degrees(res[k0 + 1][1])
    assert 0.0 < chi < 30.0
    # a vehicle that misses a waypoint laterally still sequences once abeam of it
    mis2 = FakeMission([_wp(100e3, 0.0, 28000.0)])
    nav2 = WaypointNavigator()
    nav2.start(mis2, HOME, _latlon(0.0, 0.0), 28000.0, 0.0, 2250.0)
    res2 = _fly(nav2, mis2, [(k * 1e3, 30e3) for k in range(0, 120)])
    k = next(k for k, r in enumerate(res2) if ("reached", 0) in r[3])
    assert 97 <= k <= 100


def test_new_mission_version_restarts_the_leg_from_here():
    mis = FakeMission([_wp(100e3, 0.0, 28000.0)])
    nav = WaypointNavigator()
    nav.start(mis, HOME, _latlon(0.0, -50e3), 28000.0, 0.0, 2250.0)
    _, chi_a, _, _ = _fly(nav, mis, [(10e3, -50e3)])[0]
    mis.version += 1                                    # e.g. a set-current or re-upload
    _, chi_b, _, _ = _fly(nav, mis, [(10e3, -50e3)])[0]
    # before: the leg from (0, -50 km); after: the leg from here, on it, the great circle's
    # initial course to the wp (pymap3d's inverse problem on the sphere)
    _, az_deg = vincenty.vdist(*_latlon(10e3, -50e3), *_latlon(100e3, 0.0), SPHERE)
    assert chi_b == pytest.approx(math.radians(float(az_deg)), abs=1e-5)
    assert chi_a != pytest.approx(chi_b, abs=1e-3)
