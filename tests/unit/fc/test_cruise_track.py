"""fc/cruise_track.py: CRUISE holds the great circle it was engaged on (issue 21: a constant
course flown north runs into the pole and turns back). Against a stub vehicle flown along
pymap3d's great circle over the north pole."""
import math
from types import SimpleNamespace

import numpy as np
import pymap3d
from pymap3d import vincenty

from fc.cruise_track import CruiseTrack
from fc.link import G_FIX, G_LAT_DEG, G_LON_DEG, G_N, G_T_S, G_VE, G_VN
from fc.mission_mode import NAV_DIV
from hyfc_wire.earth import EARTH_RADIUS_M

SPHERE = pymap3d.Ellipsoid.from_name("wgs84_mean")


class _Guid:
    def __init__(self, chi):
        self.chi = chi

    def targets(self):
        return 28000.0, self.chi, 2250.0

    def set_targets(self, h_m=None, chi_rad=None, v_m_s=None):
        self.chi = chi_rad
        return None


def _vehicle(chi0):
    return SimpleNamespace(plant=SimpleNamespace(gps=np.zeros(G_N)), meas_stamp_us=0,
                           modes=SimpleNamespace(changes=1), guid=_Guid(chi0))


def _sample(fc, t_s, lat, lon, vn, ve, age_s=0.0):
    g = fc.plant.gps
    g[G_T_S], g[G_LAT_DEG], g[G_LON_DEG], g[G_VN], g[G_VE], g[G_FIX] = t_s - age_s, lat, lon, vn, ve, 3
    fc.meas_stamp_us = int(round(t_s * 1e6))


def _course_errors(track, fc, start, s_max, ds):
    """Fly ``fc`` along the great circle north from ``start``; the course target after each
    navigator step minus the circle's own course there (deg, wrapped)."""
    err = []
    for s in np.arange(0.0, s_max, ds):
        lat, lon = (float(v) for v in vincenty.vreckon(*start, float(s), 0.0, SPHERE))
        _, az = vincenty.vdist(lat, lon, *vincenty.vreckon(*start, float(s) + 1e3, 0.0, SPHERE), SPHERE)
        _sample(fc, s / 2250.0, lat, lon, 2250.0 * math.cos(math.radians(float(az))),
                2250.0 * math.sin(math.radians(float(az))))
        for _ in range(NAV_DIV):
            track.tick(fc)
        err.append((math.degrees(fc.guid.chi) - float(az) + 180.0) % 360.0 - 180.0)
    return np.array(err)


def test_cruise_course_target_follows_the_great_circle_over_the_pole():
    # GIVEN CRUISE engaged at course 0 (north) at 89 N
    fc = _vehicle(0.0)
    track = CruiseTrack(EARTH_RADIUS_M)
    # WHEN the vehicle flies straight on over the pole (111 km ahead) and 200 km beyond
    err = _course_errors(track, fc, (89.0, -117.9), 311e3, 5e3)
    # THEN the course target is the circle's course everywhere: north, then south
    assert np.all(np.abs(err) < 1e-3), err
    assert abs(math.degrees(fc.guid.chi) - 180.0) < 1e-3


def test_a_course_set_by_someone_else_starts_a_new_circle_and_a_stale_fix_holds():
    fc = _vehicle(0.0)
    track = CruiseTrack(EARTH_RADIUS_M)
    _sample(fc, 1.0, 45.0, 10.0, 2250.0, 0.0)
    track.tick(fc)
    assert abs(fc.guid.chi) < 1e-12
    # a ground station sets course 90: the circle now runs east from here (course 90 here)
    fc.guid.chi = math.radians(90.0)
    for _ in range(NAV_DIV):
        track.tick(fc)
    assert abs(math.degrees(fc.guid.chi) - 90.0) < 1e-9
    # 500 km further east along it, the course target has turned south-east (great circle)
    lat, lon = (float(v) for v in vincenty.vreckon(45.0, 10.0, 500e3, 90.0, SPHERE))
    _sample(fc, 2.0, lat, lon, 0.0, 2250.0)
    for _ in range(NAV_DIV):
        track.tick(fc)
    _, az = vincenty.vdist(lat, lon, *vincenty.vreckon(45.0, 10.0, 501e3, 90.0, SPHERE), SPHERE)
    assert abs(math.degrees(fc.guid.chi) - float(az)) < 1e-3 and float(az) > 93.0
    # a fix older than the limit holds the target
    chi = fc.guid.chi
    _sample(fc, 10.0, 0.0, 0.0, 0.0, 2250.0, age_s=5.0)
    for _ in range(NAV_DIV):
        track.tick(fc)
    assert fc.guid.chi == chi


def test_the_sample_age_is_flown_along_the_circle():
    # GIVEN a sample 0.1 s old, 150 m before the pole, flying north at 2250 m/s
    fc = _vehicle(0.0)
    track = CruiseTrack(EARTH_RADIUS_M)
    lat, lon = (float(v) for v in vincenty.vreckon(89.0, -117.9, 111e3, 0.0, SPHERE))
    track.tick(fc)                          # engaged (no fix yet)
    _sample(fc, 5.0, 89.0, -117.9, 2250.0, 0.0)
    for _ in range(NAV_DIV):
        track.tick(fc)
    d_pole, _ = vincenty.vdist(lat, lon, 90.0, 0.0, SPHERE)
    lat2, lon2 = (float(v) for v in vincenty.vreckon(89.0, -117.9, 111e3 + float(d_pole) - 150.0,
                                                     0.0, SPHERE))
    _sample(fc, 6.0, lat2, lon2, 2250.0, 0.0, age_s=0.1)
    for _ in range(NAV_DIV):
        track.tick(fc)
    # THEN the target is the course past the pole (where the vehicle is now), south
    assert abs(math.degrees(fc.guid.chi) - 180.0) < 1e-3
