"""The plant's GNSS receiver (plant_sim/gnss.py) and its wire encoding (docs/wire.md section 2):
noise statistics, latency, rate, the lat/lon mapping, its own random stream, GPS_INPUT packing
on the plant side and decoding on the fc side (lean and general paths)."""
from __future__ import annotations

import math
import os

import numpy as np
import pytest

from plant_sim import gnss as gn
from plant_sim.dynamics import X_PD, X_PE, X_PN
from plant_sim.scenario import parse
from plant_sim.sim import PlantSim

os.environ["MAVLINK20"] = "1"
from pymavlink.dialects.v20 import ardupilotmega as mavlink  # noqa: E402

FRAME_HZ = 500.0


def _scenario(extra: str = "", sensors: bool = True):
    return parse(f"""
name = "gnss_test"
[sensors]
enabled = {"true" if sensors else "false"}
{extra}
""")


@pytest.mark.parametrize("lat0, lon0, alt0", [(34.9054, -117.8839, 0.0), (-45.0, 179.9, 1500.0),
                                               (0.0, 0.0, 0.0), (80.0, -179.95, 10.0)])
def test_lat_lon_round_trip_and_scale(lat0, lon0, alt0):
    for n, e, d in ((0.0, 0.0, 0.0), (12_345.6, -54_321.0, -21_000.0), (-300e3, 250e3, 5.0)):
        lat, lon, alt = gn.ned_to_geodetic(n, e, d, lat0, lon0, alt0)
        assert -180.0 <= lon < 180.0
        back = gn.geodetic_to_ned(lat, lon, alt, lat0, lon0, alt0)
        assert back == pytest.approx((n, e, d), abs=1e-6)
    # one degree of latitude is the meridian arc: 110.57 km at the equator, 111.69 km at 80 deg
    rn, _ = gn._radii(lat0)
    assert 110_570 < math.radians(1.0) * rn < 111_700


def test_known_offset_near_the_default_origin():
    # 1 km north / east at 34.9054 N: 0.0090 deg of latitude, 0.0110 deg of longitude
    lat, lon, alt = gn.ned_to_geodetic(1000.0, 1000.0, -21000.0, 34.9054, -117.8839, 0.0)
    assert lat - 34.9054 == pytest.approx(1000.0 / 110_935.0 * 1.0, rel=2e-3)
    assert lon + 117.8839 == pytest.approx(1000.0 / (111_320.0 * math.cos(math.radians(34.9054))),
                                           rel=3e-3)
    assert alt == 21000.0


def _noise(h_m: float, v_m: float, vel_m_s: float) -> str:
    return (f"[gnss.noise]\nhorizontal_m = {h_m}\nvertical_m = {v_m}\n"
            f"velocity_m_s = {vel_m_s}\n")


def _samples(sim: PlantSim, n_frames: int, move: bool):
    """Run the receiver over ``n_frames`` (advancing the plant if ``move``); (frame, sample,
    clean NED position at that frame) per sample."""
    out = []
    clean = []
    for k in range(n_frames):
        clean.append((sim.x[X_PN], sim.x[X_PE], sim.x[X_PD]))
        g = sim.gnss.update(k, sim.x)
        if g is not None:
            out.append((k, g.copy()))
        if move:
            sim.step_frame(sim.trim_rad)
    return out, np.array(clean)


def test_rate_and_exact_sample_without_sensor_errors():
    sim = PlantSim(_scenario(sensors=False), seed=3)
    got, clean = _samples(sim, 600, move=True)
    # 10 Hz at 500 Hz frames: every 50th frame, starting with frame 0
    assert [k for k, _ in got] == list(range(0, 600, 50))
    o = sim.gnss.origin
    for k, g in got:
        assert g[gn.G_T_S] == pytest.approx(k / FRAME_HZ)
        assert g[gn.G_FIX] == 3
        ned = gn.geodetic_to_ned(g[gn.G_LAT_DEG], g[gn.G_LON_DEG], g[gn.G_ALT_M], *o)
        assert ned == pytest.approx(tuple(clean[k]), abs=1e-6)


def test_latency_is_whole_frames_of_the_true_trajectory():
    sc = _scenario("[sensors.latency_s]\ngps = 0.05\n" + _noise(0.0, 0.0, 0.0))
    sim = PlantSim(sc, seed=3)
    assert sim.gnss.delay == 25
    got, clean = _samples(sim, 400, move=True)
    assert [k for k, _ in got] == list(range(50, 400, 50))      # first capture at frame 25
    for k, g in got:
        ned = gn.geodetic_to_ned(g[gn.G_LAT_DEG], g[gn.G_LON_DEG], g[gn.G_ALT_M],
                                 *sim.gnss.origin)
        assert ned == pytest.approx(tuple(clean[k - 25]), abs=1e-6)
        # and not the current position: the vehicle moves ~110 m in 50 ms
        assert abs(ned[0] - clean[k][0]) > 50.0


def test_noise_statistics_and_seeding():
    sc = _scenario("[gnss]\nrate_hz = 100.0\n" + _noise(2.0, 4.0, 0.3))
    sim = PlantSim(sc, seed=11)
    got, _ = _samples(sim, 5 * 4000, move=False)       # 4000 samples of a fixed state
    o = sim.gnss.origin
    ned = np.array([gn.geodetic_to_ned(g[1], g[2], g[3], *o) for _, g in got])
    ned -= np.array([sim.x[X_PN], sim.x[X_PE], sim.x[X_PD]])
    vel = np.array([g[gn.G_VN:gn.G_VD + 1] for _, g in got])
    vel -= np.array(gn.velocity_ned(sim.x))
    n = len(got)
    assert n == 4000
    # sample std within 5 standard errors (std of a std ~ sigma / sqrt(2n))
    for col, sigma in ((ned[:, 0], 2.0), (ned[:, 1], 2.0), (ned[:, 2], 4.0), (vel[:, 0], 0.3),
                       (vel[:, 1], 0.3), (vel[:, 2], 0.3)):
        assert abs(col.std() - sigma) < 5 * sigma / math.sqrt(2 * n)
        assert abs(col.mean()) < 5 * sigma / math.sqrt(n)
    assert abs(np.corrcoef(ned[:, 0], ned[:, 1])[0, 1]) < 0.1
    # reported accuracies are the sigmas
    assert got[0][1][gn.G_HACC_M] == 2.0 and got[0][1][gn.G_VACC_M] == 4.0
    # same seed -> same samples; reset -> the stream starts over; another seed differs
    again, _ = _samples(PlantSim(sc, seed=11), 500, move=False)
    assert all(np.array_equal(a[1], b[1]) for a, b in zip(got[:100], again))
    sim.reset()
    after_reset, _ = _samples(sim, 500, move=False)
    assert all(np.array_equal(a[1], b[1]) for a, b in zip(got[:100], after_reset))
    other, _ = _samples(PlantSim(sc, seed=12), 500, move=False)
    assert not np.array_equal(got[0][1], other[0][1])


def test_receiver_does_not_disturb_the_other_sensors():
    sc = parse(open(os.path.join(os.path.dirname(gn.__file__), "scenarios", "paper.toml")).read())
    runs = []
    for use_gnss in (False, True):
        sim = PlantSim(sc, seed=5)
        m = np.zeros(14)
        rows = []
        for k in range(300):
            if use_gnss:
                sim.gnss.update(k, sim.x)
            sim.measure(m)
            rows.append(m.copy())
            sim.step_frame(sim.trim_rad)
        runs.append(np.array(rows))
    assert np.array_equal(runs[0], runs[1])


def test_disabled_receiver_sends_nothing():
    sim = PlantSim(_scenario("[gnss]\nenabled = false\n"), seed=1)
    assert all(sim.gnss.update(k, sim.x) is None for k in range(200))


# ---- wire: plant packing (GPS_INPUT in the sensor datagram) and fc decoding ----------------
def _sample():
    g = np.zeros(gn.G_N)
    g[gn.G_LAT_DEG], g[gn.G_LON_DEG], g[gn.G_ALT_M] = 34.9123456, -117.8765432, 21012.25
    g[gn.G_VN], g[gn.G_VE], g[gn.G_VD] = 2199.75, -12.5, 3.25
    g[gn.G_FIX], g[gn.G_SATS] = 3, 12
    g[gn.G_HACC_M], g[gn.G_VACC_M], g[gn.G_SACC_M_S] = 1.5, 3.0, 0.1
    return g


def _meas():
    return np.array([0.0, 0.1, -0.2, 3.0, 0.01, -0.02, 0.0, 0.05, -0.01, 2200.0, 21000.0, -1.5,
                     2199.0, 6.1])


def test_plant_packs_gps_input_with_the_frame():
    from plant_sim.link import PlantLink, PwmMap
    link = PlantLink(("127.0.0.1", 9), ("127.0.0.1", 0), PwmMap(1000, 1500, 2000, 0.35))
    try:
        assert link.lean
        for lean in (True, False):
            link.lean = lean
            link.build_sensors(1_500_000, _meas(), 40.0, _sample())
            data = bytes(link._out_mv[:link._out_len])
            msgs = mavlink.MAVLink(None).parse_buffer(data)
            assert [m.get_type() for m in msgs] == ["ATTITUDE", "AOA_SSA", "VFR_HUD", "GPS_INPUT"]
            seqs = [m.get_seq() for m in msgs]
            assert [(b - a) % 256 for a, b in zip(seqs, seqs[1:])] == [1, 1, 1]
            g = msgs[3]
            assert g.time_usec == 1_500_000 and g.fix_type == 3 and g.satellites_visible == 12
            assert (g.lat, g.lon) == (349123456, -1178765432)
            assert g.alt == pytest.approx(21012.25)
            assert (g.vn, g.ve, g.vd) == pytest.approx((2199.75, -12.5, 3.25))
            assert (g.horiz_accuracy, g.vert_accuracy) == pytest.approx((1.5, 3.0))
            assert g.speed_accuracy == pytest.approx(0.1)
            # frames without a sample stay three messages
            link.build_sensors(1_502_000, _meas(), 40.0)
            msgs = mavlink.MAVLink(None).parse_buffer(bytes(link._out_mv[:link._out_len]))
            assert len(msgs) == 3
    finally:
        link.close()


def test_fc_decodes_gps_input_on_both_paths():
    from fc.link import G_LAT_DEG, G_T_S, M_N, PlantLink, UdpEndpoint
    from plant_sim.link import PlantLink as PlantSide, PwmMap
    side = PlantSide(("127.0.0.1", 9), ("127.0.0.1", 0), PwmMap(1000, 1500, 2000, 0.35))
    fc = PlantLink(UdpEndpoint("127.0.0.1", 0), plant_sysid=2)
    try:
        assert fc._fast
        side.build_sensors(2_000_000, _meas(), 0.0, _sample())
        with_gps = bytes(side._out_mv[:side._out_len])
        side.build_sensors(2_002_000, _meas(), 0.0)
        without = bytes(side._out_mv[:side._out_len])
        results = []
        for lean in (True, False):
            fc._fast = lean
            fc.gps[:] = 0.0
            meas = np.zeros(M_N)
            assert fc._decode(with_gps, meas) == 2_000_000
            got = fc.gps.copy()
            assert got[G_T_S] == 2.0
            assert got[G_LAT_DEG] == pytest.approx(34.9123456, abs=1e-9)
            assert got[1:] == pytest.approx(_sample()[1:], rel=1e-6)
            # a frame without GNSS keeps the last sample (and its stamp)
            assert fc._decode(without, meas) == 2_002_000
            assert np.array_equal(fc.gps, got)
            results.append(got)
        assert np.array_equal(results[0], results[1])
        assert fc.gps_samples == 2 and fc.counters.gnss == 2
    finally:
        side.close()
        fc.endpoint.close()


def test_fc_drops_a_non_finite_or_out_of_range_gnss_sample():
    from fc.link import M_N, PlantLink, UdpEndpoint, new_codec
    fc = PlantLink(UdpEndpoint("127.0.0.1", 0), plant_sysid=2)
    tx = new_codec(2)
    try:
        base = (tx.attitude_encode(1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0).pack(tx)
                + tx.aoa_ssa_encode(1000, 1.0, 0.0).pack(tx)
                + tx.vfr_hud_encode(2200.0, 2200.0, 0, 0, 21000.0, 0.0).pack(tx))
        bad = ((0, 0, math.nan, 1.0), (0, 0, 21000.0, math.inf), (910_000_000, 0, 0.0, 0.0),
               (0, 0, 3.0e6, 0.0))
        for lat, lon, alt, vn in bad:
            frame = base + tx.gps_input_encode(1000, 0, 0, 0, 0, 3, lat, lon, alt, 1.0, 1.0, vn,
                                               0.0, 0.0, 0.1, 1.5, 3.0, 12, 0).pack(tx)
            for lean in (True, False):
                fc._fast = lean
                try:
                    assert fc._decode(frame, np.zeros(M_N)) == 1000     # the frame still counts
                finally:
                    fc._fast = True
        assert fc.gps_samples == 0 and fc.counters.gnss_rejected == 2 * len(bad)
        assert not fc.gps.any()
    finally:
        fc.endpoint.close()
