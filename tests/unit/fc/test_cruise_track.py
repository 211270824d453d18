"""fc/cruise_track.py: CRUISE holds the great circle it was engaged on (issue 21: a constant
course flown north runs into the pole and turns back), setting the target on every guidance
step and holding the course loop near a pole (issue 20). Against a stub vehicle flown along
pymap3d's great circles over and beside the north pole."""
import math
from types import SimpleNamespace

import numpy as np
import pymap3d
import pytest
from pymap3d import vincenty

from fc.cruise_track import NORTH_TOL_RAD, CruiseTrack, pole_guard_m
from fc.link import G_FIX, G_HACC_M, G_LAT_DEG, G_LON_DEG, G_N, G_T_S, G_VE, G_VN
from hyfc_wire.earth import EARTH_RADIUS_M

SPHERE = pymap3d.Ellipsoid.from_name("wgs84_mean")


class _Guid:
    """The GuidanceRunner members CruiseTrack uses: the targets, the frame's measured course
    ``chi_rad`` and the course loop's filtered error."""

    def __init__(self, chi):
        self.chi = chi
        self.chi_rad = chi
        self.e_f = 0.0

    def course_error_filtered(self):
        return self.e_f

    def targets(self):
        return 28000.0, self.chi, 2250.0

    def set_targets(self, h_m=None, chi_rad=None, v_m_s=None):
        self.chi = chi_rad
        return None


def _vehicle(chi0):
    return SimpleNamespace(plant=SimpleNamespace(gps=np.zeros(G_N)), meas_stamp_us=0,
                           modes=SimpleNamespace(changes=1), guid=_Guid(chi0))


def _sample(fc, t_s, lat, lon, vn, ve, age_s=0.0, hacc_m=1.5):
    """A GNSS sample taken ``age_s`` before the frame at ``t_s``; the frame's measured course
    is the sample's (the stub flies straight)."""
    g = fc.plant.gps
    g[G_T_S], g[G_LAT_DEG], g[G_LON_DEG], g[G_VN], g[G_VE], g[G_FIX] = t_s - age_s, lat, lon, vn, ve, 3
    g[G_HACC_M] = hacc_m
    fc.meas_stamp_us = int(round(t_s * 1e6))
    fc.guid.chi_rad = math.atan2(ve, vn)


def _course_errors(track, fc, start, s_max, ds, az0=0.0):
    """Fly ``fc`` along the great circle from ``start`` at course ``az0`` (deg); the course
    target after each guidance step minus the circle's own course there (deg, wrapped)."""
    err = []
    for s in np.arange(0.0, s_max, ds):
        lat, lon = (float(v) for v in vincenty.vreckon(*start, float(s), az0, SPHERE))
        _, az = vincenty.vdist(lat, lon, *vincenty.vreckon(*start, float(s) + 1e3, az0, SPHERE), SPHERE)
        _sample(fc, s / 2250.0, lat, lon, 2250.0 * math.cos(math.radians(float(az))),
                2250.0 * math.sin(math.radians(float(az))))
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
    track.tick(fc)
    assert abs(math.degrees(fc.guid.chi) - 90.0) < 1e-9
    # 500 km further east along it, the course target has turned south-east (great circle)
    lat, lon = (float(v) for v in vincenty.vreckon(45.0, 10.0, 500e3, 90.0, SPHERE))
    _sample(fc, 2.0, lat, lon, 0.0, 2250.0)
    track.tick(fc)
    _, az = vincenty.vdist(lat, lon, *vincenty.vreckon(45.0, 10.0, 501e3, 90.0, SPHERE), SPHERE)
    assert abs(math.degrees(fc.guid.chi) - float(az)) < 1e-3 and float(az) > 93.0
    # a fix older than the limit holds the target
    chi = fc.guid.chi
    _sample(fc, 10.0, 0.0, 0.0, 0.0, 2250.0, age_s=5.0)
    track.tick(fc)
    assert fc.guid.chi == chi


def _beside_the_pole(d_m):
    """Course (deg) at 89 N of the great circle that passes ``d_m`` beside the north pole."""
    return math.degrees(math.asin(math.sin(d_m / EARTH_RADIUS_M) / math.cos(math.radians(89.0))))


def test_the_sample_age_is_flown_along_the_circle():
    # GIVEN the circle 8 km beside the pole (outside the pole guard), where its course turns
    # at V / d = 16 deg/s, and a GNSS sample 0.1 s old taken at its closest approach
    az0 = _beside_the_pole(8000.0)
    fc = _vehicle(math.radians(az0))
    track = CruiseTrack(EARTH_RADIUS_M)
    _sample(fc, 5.0, 89.0, -117.9, 2250.0 * math.cos(math.radians(az0)),
            2250.0 * math.sin(math.radians(az0)))
    track.tick(fc)                          # engaged: the circle from here at az0
    s_cpa = float(EARTH_RADIUS_M * math.atan(math.tan(math.radians(1.0)) * math.cos(math.radians(az0))))

    def at(s):
        lat, lon = (float(v) for v in vincenty.vreckon(89.0, -117.9, s, az0, SPHERE))
        _, az = vincenty.vdist(lat, lon, *vincenty.vreckon(89.0, -117.9, s + 1.0, az0, SPHERE),
                               SPHERE)
        return lat, lon, float(az)
    lat, lon, az_then = at(s_cpa)
    h_m = 28000.0
    _, _, az_now = at(s_cpa + 225.0 * EARTH_RADIUS_M / (EARTH_RADIUS_M + h_m))
    fc.plant.gps[3] = h_m                   # G_ALT_M: the sample's altitude
    _sample(fc, 6.0, lat, lon, 2250.0 * math.cos(math.radians(az_then)),
            2250.0 * math.sin(math.radians(az_then)), age_s=0.1)
    track.tick(fc)
    # THEN the target is the circle's course where the vehicle is now (225 m on at 28 km),
    # 1.6 deg on from where the sample was taken
    assert not track.guarded
    assert abs(az_now - az_then) > 1.0
    assert abs((math.degrees(fc.guid.chi) - az_now + 180.0) % 360.0 - 180.0) < 2e-3


def test_near_the_pole_the_course_loop_holds():
    # GIVEN the circle straight over the pole, CRUISE engaged 10 km before it (hacc 1.5 m)
    fc = _vehicle(0.0)
    track = CruiseTrack(EARTH_RADIUS_M)
    start = vincenty.vreckon(90.0, 0.0, 10e3, 180.0, SPHERE)        # 10 km south of the pole
    start = (float(start[0]), float(start[1]))
    err = _course_errors(track, fc, start, 4e3, 1e3)
    assert not track.guarded and np.all(np.abs(err) < 1e-3)
    # WHEN the vehicle is within the guard (3 sigma of 1.5 m over 0.05 deg: 5.2 km), its
    # measured course off the circle by 0.3 deg and the course loop's filtered error 0.02 deg
    assert pole_guard_m(1.5) == pytest.approx(3.0 * 1.5 / NORTH_TOL_RAD) and 5100 < pole_guard_m(1.5) < 5200
    lat, lon = (float(v) for v in vincenty.vreckon(*start, 7e3, 0.0, SPHERE))
    fc.guid.e_f = math.radians(0.02)
    _sample(fc, 10.0, lat, lon, 2250.0, 0.0)
    fc.guid.chi_rad = math.radians(0.3)
    track.tick(fc)
    # THEN the target is the measured course plus the filtered error: the bank command holds
    assert track.guarded
    assert math.degrees(fc.guid.chi) == pytest.approx(0.32, abs=1e-9)
    # and a worse receiver widens the guard (hacc 3 m: 10.3 km), a better one narrows it to
    # the 1 m floor (2.9 km)
    assert pole_guard_m(3.0) == pytest.approx(2.0 * pole_guard_m(1.5))
    assert pole_guard_m(0.0) == pole_guard_m(1.0) == pytest.approx(3.0 / NORTH_TOL_RAD)
