"""fc/guidance/waypoints.py PointNavigator and orbit_course: RTL's and DO_REPOSITION's
geometry flown by a kinematic vehicle at Mach 7.5 whose turn rate is bounded by the
guidance's bank limit (chi_dot = clip(GH_K_CHI wrap(chi_t - chi), g tan(29.8 deg) / V)).
Pure: no fc, no plant."""
from __future__ import annotations

import math

import pytest

from fc.guidance.waypoints import (G0_M_S2, NavParams, PointNavigator, gc_course_rad,
                                   gc_destination, gc_distance_m, gc_pole, orbit_course,
                                   orbit_radius_m, unit_vector)

V_M_S = 2250.0
MU_MAX_RAD = math.radians(29.8)
K_CHI = 0.05                             # GH_K_CHI, 1/s


def _wrap(a: float) -> float:
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def _fly(nav: PointNavigator, x: tuple, chi: float, seconds: float, dt: float = 1.0):
    """Positions (unit vectors) every ``dt`` s of a vehicle steered by ``nav`` on the sphere:
    it moves V dt along the great circle of its course and carries that course along (the
    course at the new point of the same great circle)."""
    chidot_max = G0_M_S2 * math.tan(MU_MAX_RAD) / V_M_S
    track = []
    for _ in range(int(seconds / dt)):
        chi_t = nav.step(x)
        chi += max(-chidot_max, min(chidot_max, K_CHI * _wrap(chi_t - chi))) * dt
        n = gc_pole(x, chi)
        x = gc_destination(x, chi, V_M_S * dt)
        chi = gc_course_rad(n, x)
        track.append(x)
    return track


def test_orbit_course_is_continuous_at_the_circle_and_heads_for_the_centre_from_afar():
    c, r = (0.0, 0.0), 1.0e6
    for s in (1e-3, -1e-3):                       # just outside, just inside (north of c)
        chi = orbit_course((r + s, 0.0), c, r, True, 50e3, math.radians(20))
        assert abs(_wrap(chi - math.radians(90.0))) < 1e-3    # clockwise north of c: east
    far = orbit_course((1e9, 0.0), c, r, True, 50e3, math.radians(20))
    assert abs(_wrap(far - math.pi)) < 2e-3               # from far north: south, at c


HOME = (34.9, -117.9)                    # deg: the scenarios' start


@pytest.mark.parametrize("heading_deg", [180.0, 90.0, 0.0])
def test_return_flies_at_home_passes_over_it_and_circles_through_it(heading_deg):
    """GIVEN the vehicle 300 km north of home heading south, east or north (away) WHEN it
    returns THEN it passes within 5 km of home and then flies the circle through home (within
    5 km of it over the last lap), never asking more than the bank limit's turn rate."""
    R = orbit_radius_m(V_M_S, MU_MAX_RAD)
    nav = PointNavigator(NavParams(mu_max_rad=MU_MAX_RAD))
    home = unit_vector(*HOME)
    start = gc_destination(home, 0.0, 300e3)
    nav.goto(start, home, R)
    lap_s = 2 * math.pi * R / V_M_S
    track = _fly(nav, start, math.radians(heading_deg), 3 * lap_s)
    d_home = [gc_distance_m(p, home) for p in track]
    c = nav.centre_u
    off_circle = [abs(gc_distance_m(p, c) - R) for p in track[-int(lap_s):]]
    print(f"heading {heading_deg:.0f}: R {R / 1e3:.0f} km, closest to home "
          f"{min(d_home) / 1e3:.2f} km, off the circle over the last lap "
          f"{max(off_circle) / 1e3:.2f} km")
    assert nav.arrived
    assert min(d_home) < 5e3
    assert max(off_circle) < 5e3
    assert min(d_home[-int(lap_s):]) < 5e3           # the circle passes over home


@pytest.mark.parametrize("where", ["over the pole", "across the antimeridian"])
def test_return_from_the_far_side_flies_the_great_circle_home(where):
    """GIVEN the vehicle 8,000 km from home (past the north pole, or across the antimeridian:
    where the old flat map about home was wrong by thousands of km) WHEN it returns THEN it
    turns onto the great circle home and passes within 5 km of home."""
    R = orbit_radius_m(V_M_S, MU_MAX_RAD)
    nav = PointNavigator(NavParams(mu_max_rad=MU_MAX_RAD))
    home = unit_vector(*HOME)
    if where == "over the pole":
        start = unit_vector(72.6, 62.2)              # where the 1-hour cruise ends
    else:
        start = unit_vector(20.0, 150.0)
    d0 = gc_distance_m(start, home)
    nav.goto(start, home, R)
    track = _fly(nav, start, 0.0, d0 / V_M_S + 900.0)
    d_home = [gc_distance_m(p, home) for p in track]
    print(f"{where}: {d0 / 1e3:.0f} km out, closest to home {min(d_home) / 1e3:.2f} km")
    assert nav.arrived
    assert min(d_home) < 5e3
