"""The plant's round Earth (plant_sim/dynamics.py deriv_sphere, plant_sim/earth.py,
docs/plant.md section 5a), checked against the closed form and the geodesy library (pymap3d).

GIVEN a non-rotating sphere and no aerodynamic force, a vehicle at orbital speed is in a
circular orbit: it needs no lift to stay level, and its track is the great circle that
pymap3d's direct problem gives, over the pole and across the antimeridian alike.
"""
import math

import numpy as np
import pymap3d
import pytest
from pymap3d import vincenty

from hyfc_wire.earth import EARTH_RADIUS_M
from plant_sim import dynamics as dy
from plant_sim.atmosphere import G0_M_S2, R_EARTH_M
from plant_sim.earth import EARTH, geodetic, offset_geodetic
from plant_sim.gnss import GnssSensor
from plant_sim.scenario import load, parse
from plant_sim.sim import PlantSim

DEG = math.pi / 180.0


def _g(h_m):
    """US76 gravity at altitude h (m/s^2): the plant's."""
    return G0_M_S2 * (R_EARTH_M / (R_EARTH_M + h_m)) ** 2


def _coast(earth: str, V: float, h: float, lat0: float, lon0: float, chi_deg: float,
           gamma_deg: float = 0.0) -> PlantSim:
    """The nominal scenario without aerodynamics, thrust or disturbance, on ``earth``, at
    (lat0, lon0) flying course ``chi_deg`` at V (m/s), h (m), no noise."""
    text = open(load("nominal").path).read()
    text += (f'\n[earth]\nmodel = "{earth}"\n')
    sc = parse(text, "coast")
    sc.data["initial"].update(V_m_s=V, h_m=h, chi_deg=chi_deg, gamma_deg=gamma_deg,
                              alpha_deg=0.0, beta_deg=0.0, mu_deg=0.0)
    sc.data["gnss"].update(origin_lat_deg=lat0, origin_lon_deg=lon0)
    sc.data["sensors"]["enabled"] = False
    sim = PlantSim(sc)
    sim.p[dy.P_UNC:dy.P_UNC + 6] = 0.0
    sim.p[dy.P_SPEED_MODE] = dy.SPEED_NONE
    sim.p[dy.P_DIST_ON] = 0.0
    return sim


def _fly(sim: PlantSim, t_s: float) -> None:
    x, p, w, n_sub = sim.x, sim.p, sim.w, sim.n_sub
    dy.advance_frames(x, np.zeros(3), p, w, n_sub, int(round(t_s / sim.frame_dt_s)))


def test_the_sphere_is_the_librarys_wgs84_mean_sphere():
    e = pymap3d.Ellipsoid.from_name("wgs84_mean")
    assert EARTH_RADIUS_M == e.semimajor_axis == e.semiminor_axis
    assert EARTH.semimajor_axis == EARTH.semiminor_axis == EARTH_RADIUS_M


@pytest.mark.parametrize("lat0, lon0, chi_deg, t_s", [
    (85.0, 178.0, 0.0, 150.0),       # straight over the north pole (at about 70 s)
    (60.0, 179.9, 60.0, 60.0),       # across the antimeridian
    (-88.0, -30.0, 170.0, 60.0),     # over the south pole
])
def test_orbital_speed_needs_no_lift_and_follows_the_great_circle(lat0, lon0, chi_deg, t_s):
    # GIVEN level flight at orbital speed on the sphere, no lift
    h0 = 28000.0
    r = EARTH_RADIUS_M + h0
    v_orb = math.sqrt(_g(h0) * r)
    sim = _coast("sphere", v_orb, h0, lat0, lon0, chi_deg)
    # WHEN it coasts
    _fly(sim, t_s)
    # THEN it stays level (a flat earth drops it by g t^2 / 2: 100-1100 km here)
    assert -sim.x[dy.X_PD] == pytest.approx(h0, abs=0.5)
    assert math.sqrt(np.sum(sim.x[dy.X_U:dy.X_W + 1] ** 2)) == pytest.approx(v_orb, abs=1e-3)
    # AND its position is the library's great-circle destination (distance on the surface)
    lat, lon, h = geodetic(sim.x[dy.X_S:dy.X_S + 3])
    s_m = v_orb * t_s * EARTH_RADIUS_M / r
    lat_ref, lon_ref = vincenty.vreckon(lat0, lon0, s_m, chi_deg, EARTH)
    dist_err, _ = vincenty.vdist(lat, lon, float(lat_ref), float(lon_ref), EARTH)
    assert float(dist_err) < 5.0
    assert -90.0 <= lat <= 90.0 and -180.0 <= lon < 180.0
    assert h == pytest.approx(h0, abs=0.5)


def test_flat_earth_drops_where_the_sphere_holds():
    # the same coast on the flat earth falls (the scenario flag changes the physics)
    h0 = 28000.0
    v_orb = math.sqrt(_g(h0) * (EARTH_RADIUS_M + h0))
    sim = _coast("flat", v_orb, h0, 34.9, -117.9, 0.0)
    _fly(sim, 10.0)
    assert h0 - (-sim.x[dy.X_PD]) == pytest.approx(0.5 * _g(h0) * 100.0, rel=0.01)


@pytest.mark.parametrize("V, relief", [(2250.0, 0.0814), (4500.0, 0.3255)])
def test_centrifugal_relief_at_mach_7_5_and_15(V, relief):
    # GIVEN level flight without lift at Mach 7.5 (15), 28 km, on the sphere and on the flat earth
    h0, t = 28000.0, 2.0
    drops = {}
    for earth in ("flat", "sphere"):
        sim = _coast(earth, V, h0, 10.0, 20.0, 45.0)
        _fly(sim, t)
        drops[earth] = h0 + sim.x[dy.X_PD]
    # THEN the sphere's fall is (1 - V^2 / (r g)) of the flat one: 8 % relief (31 % at Mach 15)
    r = EARTH_RADIUS_M + h0
    assert V * V / (r * _g(h0)) == pytest.approx(relief, abs=5e-4)
    assert 1.0 - drops["sphere"] / drops["flat"] == pytest.approx(relief, abs=2e-3)


def test_gnss_keeps_a_fix_over_the_pole():
    # GIVEN the cruise's start flown straight north from 89.5 deg at Mach 7.5 on the sphere
    h0, V = 28000.0, 2250.0
    sim = _coast("sphere", V, h0, 89.5, -117.9, 0.0)
    sim.p[dy.P_UNC:dy.P_UNC + 6] = 0.0
    gn = GnssSensor(sim.scenario, 0, sim.frame_dt_s)
    lats, lons = [], []
    cmd = np.zeros(3)
    # WHEN it crosses the pole (56 km ahead: 25 s), sampled at the receiver's rate
    for k in range(int(40.0 / sim.frame_dt_s)):
        s = gn.update(k, sim.x)
        if s is not None:
            lats.append(s[1])
            lons.append(s[2])
        sim.step_frame(cmd)
    # THEN every sample is a valid position, and the track goes through the pole and on
    lats, lons = np.array(lats), np.array(lons)
    assert len(lats) == 400 and np.all(np.isfinite(lats)) and np.all(np.isfinite(lons))
    assert np.all(np.abs(lats) <= 90.0) and np.all(np.abs(lons) <= 180.0)
    assert lats.max() > 89.99
    assert lons[0] == pytest.approx(-117.9, abs=1e-6) and lons[-1] == pytest.approx(62.1, abs=1e-6)
    # the distance flown between the first and last samples is the library's
    d, _ = vincenty.vdist(lats[0], lons[0], lats[-1], lons[-1], EARTH)
    assert float(d) == pytest.approx(39.9 * V * EARTH_RADIUS_M / (EARTH_RADIUS_M + h0), rel=2e-3)


def test_offset_geodetic_is_metres_along_the_local_axes_at_the_pole():
    r_pole = np.array([0.0, 0.0, EARTH_RADIUS_M + 1000.0])
    lat, lon, h = offset_geodetic(r_pole, 10.0, 0.0, -5.0)
    assert h == pytest.approx(1005.0, abs=1e-4)     # + 10^2 / (2 r): 8 um
    d, _ = vincenty.vdist(90.0, 0.0, lat, lon, EARTH)
    assert float(d) == pytest.approx(10.0 * EARTH_RADIUS_M / (EARTH_RADIUS_M + 1005.0), rel=1e-4)


def test_flat_earth_flag_leaves_the_paper_case_unchanged():
    # GIVEN the paper scenario as shipped and with the flat earth written out
    base = load("paper")
    assert base.data["earth"]["model"] == "flat"
    explicit = parse(open(base.path).read() + '\n[earth]\nmodel = "flat"\n', "paper_flat")
    rows = []
    for sc in (base, explicit):
        sim = PlantSim(sc)
        row = np.zeros(sim.TRUTH_N)
        out = []
        m = np.zeros(14)
        sim.measure(m)
        for _ in range(400):
            sim.frame(sim.trim_rad.copy(), row)
            out.append(row.copy())
        rows.append(np.array(out))
    # THEN the truth is bit-identical, and the sphere's is not
    assert np.array_equal(rows[0], rows[1])
    sph = parse(open(base.path).read() + '\n[earth]\nmodel = "sphere"\n', "paper_sphere")
    sim = PlantSim(sph)
    row = np.zeros(sim.TRUTH_N)
    m = np.zeros(14)
    sim.measure(m)
    for _ in range(400):
        sim.frame(sim.trim_rad.copy(), row)
    assert not np.array_equal(row, rows[0][-1])
