"""Tier 1: tools.sitl.metrics against closed-form step responses (docs/metrics.md)."""
import math

import numpy as np
import pytest
from scipy.optimize import brentq

from tools.sitl import metrics as M

DT_S = 1e-3
D2R = math.pi / 180.0


def _t(T_s, t0_s=0.0):
    return np.arange(0.0, T_s + DT_S / 2, DT_S) + t0_s


def _second_order_unit(t, zeta, wn):
    """Unit step response of wn^2 / (s^2 + 2 zeta wn s + wn^2), zeta < 1."""
    wd = wn * math.sqrt(1.0 - zeta * zeta)
    phi = math.acos(zeta)
    return 1.0 - np.exp(-zeta * wn * t) / math.sqrt(1.0 - zeta * zeta) * np.sin(wd * t + phi)


def test_first_order_step_matches_closed_form():
    # GIVEN y = A (1 - exp(-t / tau)), 0 -> 4 deg
    tau, A, T = 0.5, 4.0 * D2R, 8.0
    t = _t(T)
    y = A * (1.0 - np.exp(-t / tau))
    # WHEN
    m = M.channel_metrics(t, y, [0.0], [A])
    # THEN rise 10-90 % = tau ln 9, settling into the band b = tau ln(1 / b) (b above the floor)
    frac = M.SETTLE_BAND_FRAC
    assert 4.0 * frac > M.SETTLE_BAND_FLOOR_DEG
    assert m.overshoot_pct == 0.0
    assert m.rise_time_s == pytest.approx(tau * math.log(9.0), abs=2e-6)
    assert m.settling_time_s == pytest.approx(tau * math.log(1.0 / frac), abs=2e-6)
    assert m.band_deg == pytest.approx(4.0 * frac)
    # the 2 % criterion on request
    m2 = M.channel_metrics(t, y, [0.0], [A], band_frac=0.02, band_floor_deg=0.0)
    assert m2.settling_time_s == pytest.approx(tau * math.log(50.0), abs=2e-6)
    assert m.step_deg == pytest.approx(4.0)
    assert m.final_error_deg == pytest.approx(4.0 * math.exp(-(T - 1.0) / tau), rel=1e-3)
    rms = 4.0 * math.sqrt(tau / 2.0 * (1.0 - math.exp(-2.0 * T / tau)) / T)
    assert m.rms_error_deg == pytest.approx(rms, rel=1e-4)


@pytest.mark.parametrize("zeta", [0.3, 0.5, 0.7])
def test_second_order_overshoot_rise_settling(zeta):
    # GIVEN an underdamped second-order response 1 deg -> 5 deg (the paper's alpha step)
    wn, y0, c, T = 3.0, 1.0 * D2R, 5.0 * D2R, 12.0
    t = _t(T)
    y = y0 + (c - y0) * _second_order_unit(t, zeta, wn)
    m = M.channel_metrics(t, y, [0.0], [c])
    # THEN overshoot = exp(-pi zeta / sqrt(1 - zeta^2))
    assert m.overshoot_pct == pytest.approx(
        100.0 * math.exp(-math.pi * zeta / math.sqrt(1 - zeta**2)), rel=1e-4)
    # rise: 10 % and 90 % first crossings of the closed form
    f = lambda tt, lv: _second_order_unit(np.array([tt]), zeta, wn)[0] - lv  # noqa: E731
    t_pk = math.pi / (wn * math.sqrt(1 - zeta**2))
    rise = brentq(f, 1e-9, t_pk, args=(0.9,)) - brentq(f, 1e-9, t_pk, args=(0.1,))
    assert m.rise_time_s == pytest.approx(rise, abs=1e-5)
    # settling: last time |1 - y| leaves the band (5 % of the 4 deg step = 0.2 deg), from the
    # closed form on a fine grid
    frac = M.SETTLE_BAND_FRAC
    tf = np.linspace(0.0, T, 2_000_001)
    out = np.nonzero(np.abs(1.0 - _second_order_unit(tf, zeta, wn)) > frac)[0]
    assert m.settling_time_s == pytest.approx(tf[out[-1]], abs=2e-5)


def test_initial_error_driven_to_zero_beta_case():
    # GIVEN beta from 5 deg to a zero command with error e0 (5 e^-5t - 4 e^-4t)
    # (the paper's gains K = 4, kappa = 5 with an ideal inversion: docs/metrics.md)
    e0 = 5.0 * D2R
    t = _t(6.0)
    y = e0 * (5.0 * np.exp(-5.0 * t) - 4.0 * np.exp(-4.0 * t))
    m = M.channel_metrics(t, y, [0.0], [0.0])
    # THEN the excursion below zero, as % of the 5 deg initial error, is the closed-form
    # minimum at t = ln(25/16): (16/25)^4 (5 * 16/25 - 4) = -0.1342
    expect = -100.0 * (16 / 25) ** 4 * (5 * 16 / 25 - 4)
    assert m.overshoot_pct == pytest.approx(expect, rel=1e-5)
    assert m.step_deg == pytest.approx(-5.0)
    assert m.peak_error_deg == pytest.approx(5.0)


def test_mid_run_command_change_measured_from_last_step():
    # GIVEN command 0 until t = 2 s, then 4 deg; the channel sits at 0 then follows a first order
    tau, A = 0.4, 4.0 * D2R
    t = _t(8.0)
    y = np.where(t < 2.0, 0.0, A * (1.0 - np.exp(-np.clip(t - 2.0, 0.0, None) / tau)))
    m = M.channel_metrics(t, y, [0.0, 2.0], [0.0, A])
    # THEN times count from the step at t = 2 s
    assert m.t_step_s == pytest.approx(2.0)
    assert m.settling_time_s == pytest.approx(tau * math.log(1.0 / M.SETTLE_BAND_FRAC), abs=2e-6)
    assert m.rise_time_s == pytest.approx(tau * math.log(9.0), abs=2e-6)
    # a timeline entry that repeats the value is not a step
    m2 = M.channel_metrics(t, y, [0.0, 2.0, 5.0], [0.0, A, A])
    assert m2.t_step_s == pytest.approx(2.0)
    # a step after the end of the data is ignored
    m3 = M.channel_metrics(t, y, [0.0, 2.0, 50.0], [0.0, A, 0.0])
    assert m3.t_step_s == pytest.approx(2.0)


def test_command_equal_to_initial_value_has_no_overshoot_or_rise():
    # GIVEN mu commanded to 0 from 0, disturbed by a decaying bump of 0.3 deg
    t = _t(5.0)
    y = 0.3 * D2R * t * np.exp(1.0 - t)  # peak 0.3 deg at t = 1 s
    m = M.channel_metrics(t, y, [0.0], [0.0])
    assert m.overshoot_pct is None
    assert m.rise_time_s is None
    assert m.peak_error_deg == pytest.approx(0.3, rel=1e-6)
    # settling uses the absolute floor: last time 0.3 t e^(1-t) = floor, after the peak
    floor = M.SETTLE_BAND_FLOOR_DEG
    assert floor < 0.3
    t_settle = brentq(lambda s: 0.3 * s * math.exp(1.0 - s) - floor, 1.0, 5.0)
    assert m.band_deg == pytest.approx(M.SETTLE_BAND_FLOOR_DEG)
    assert m.settling_time_s == pytest.approx(t_settle, abs=1e-5)


def test_not_settled_and_never_rising_give_none():
    t = _t(3.0)
    y = 0.5 * 4.0 * D2R * (1.0 - np.exp(-t))  # goes only half way to 4 deg
    m = M.channel_metrics(t, y, [0.0], [4.0 * D2R])
    assert m.settling_time_s is None
    assert m.rise_time_s is None
    assert m.overshoot_pct == 0.0


def test_wrapped_channel_error():
    # mu near +-180 deg: 179.9 deg vs a command of -179.9 deg is a 0.2 deg error when wrapped
    t = _t(2.0)
    y = np.full_like(t, math.radians(179.9))
    m = M.channel_metrics(t, y, [0.0], [math.radians(-179.9)], wrap=True)
    assert m.final_error_deg == pytest.approx(0.2, abs=1e-9)
    mu = M.channel_metrics(t, y, [0.0], [math.radians(-179.9)], wrap=False)
    assert mu.final_error_deg == pytest.approx(359.8, abs=1e-9)


def test_command_at_zero_order_hold():
    v = M.command_at([0.0, 1.0, 3.0], [1.0, 2.0, 3.0], [-1.0, 0.0, 0.5, 1.0, 2.9, 3.0, 9.0])
    np.testing.assert_array_equal(v, [1.0, 1.0, 1.0, 2.0, 2.0, 3.0, 3.0])


def test_surface_metrics_peaks_and_saturated_time():
    t = _t(2.0)
    d = np.zeros((len(t), 3))
    lim = math.radians(20.0)
    d[:, 0] = np.where((t >= 0.5) & (t < 1.0), lim, 0.1)
    d[:, 1] = -0.2
    d[:, 2] = np.where(t > 1.5, -lim, 0.0)
    peak, sat_s = M.surface_metrics(t, d, lim)
    assert peak["left_elevon"] == pytest.approx(20.0)
    assert peak["right_elevon"] == pytest.approx(math.degrees(0.2))
    assert peak["rudder"] == pytest.approx(20.0)
    # 0.5 s on the left elevon plus the last ~0.5 s of the rudder (last sample excluded)
    assert sat_s == pytest.approx(0.5 + 0.5 - DT_S, abs=1.5e-3)


def test_surface_figures_closed_form():
    """GIVEN a ramp-and-hold on the left elevon, a 40 Hz command jitter on the rudder, a
    command at the limit for 0.3 s and the rate-command flag for 0.7 s; THEN travel, chatter
    and the times are the closed-form values."""
    t = _t(2.0)
    lim = math.radians(20.0)
    d = np.zeros((len(t), 3))
    d[:, 0] = np.radians(np.clip(10.0 * t, 0.0, 5.0))          # 0 -> 5 deg, then held
    d[:, 1] = np.radians(-3.0)
    c = d.copy()
    amp = math.radians(0.5)
    c[:, 2] = amp * np.sin(2 * math.pi * 40.0 * t)                # jitter, well above 5 Hz
    c[:, 1] = np.where((t >= 1.0) & (t < 1.3), -lim, c[:, 1])     # a command at its limit
    flag = ((t >= 0.2) & (t < 0.9)).astype(float)
    f = M.surface_figures(t, d, c, lim, flag)
    assert tuple(f) == M.SURFACE_FIGURE_KEYS
    assert f["peak_left_elevon_deg"] == pytest.approx(5.0)
    assert f["peak_right_elevon_deg"] == pytest.approx(3.0)
    assert f["travel_left_elevon_deg"] == pytest.approx(5.0)
    assert f["travel_right_elevon_deg"] == 0.0 and f["travel_rudder_deg"] == 0.0
    assert f["travel_total_deg"] == pytest.approx(5.0)
    # a 40 Hz sine passes a first-order 5 Hz high-pass with gain 40/sqrt(40^2 + 5^2)
    gain = 40.0 / math.hypot(40.0, 5.0)
    assert f["chatter_rudder_deg"] == pytest.approx(0.5 / math.sqrt(2) * gain, rel=0.03)
    assert f["chatter_right_elevon_deg"] > 1.0                    # the 17 deg jump and back
    # a ramp of 10 deg/s reads slope x tau = 0.32 deg while it lasts (0.5 of the 2 s): small
    tau_s = 1.0 / (2 * math.pi * 5.0)
    assert f["chatter_left_elevon_deg"] == pytest.approx(10.0 * tau_s * math.sqrt(0.25), rel=0.05)
    assert f["at_limit_s"] == 0.0
    assert f["cmd_at_limit_s"] == pytest.approx(0.3, abs=1.5e-3)
    assert f["rate_cmd_limited_s"] == pytest.approx(0.7, abs=1.5e-3)
    assert M.surface_figures(t, d, c, lim)["rate_cmd_limited_s"] is None


def test_is_diverged():
    ok = np.radians(np.linspace(0.0, 10.0, 50))
    assert not M.is_diverged(ok, -ok)
    assert M.is_diverged(ok, np.radians([0.0, 50.0]))
    assert M.is_diverged(np.array([0.0, np.nan]))


@pytest.mark.parametrize("t, y, ct, cv, msg", [
    ([0.0], [0.0], [0.0], [0.0], "two samples"),
    ([0.0, 0.0], [0.0, 0.0], [0.0], [0.0], "increasing"),
    ([0.0, 1.0], [0.0], [0.0], [0.0], "equal length"),
    ([0.0, 1.0], [0.0, 0.0], [], [], "timeline"),
])
def test_bad_input_is_a_clear_error(t, y, ct, cv, msg):
    with pytest.raises(ValueError, match=msg):
        M.channel_metrics(t, y, ct, cv)


def test_json_metrics_has_the_summary_keys_first():
    t = _t(2.0)
    m = M.channel_metrics(t, np.zeros_like(t), [0.0], [1.0 * D2R])
    d = M.json_metrics(m)
    assert list(d)[:5] == list(M.METRIC_KEYS)


def test_undershoot_is_the_wrong_way_move_as_percent_of_step():
    # GIVEN mu commanded 0 -> 4 deg that first dips to -1 deg (non-minimum-phase-like)
    t = _t(6.0)
    y = D2R * (4.0 * (1.0 - np.exp(-2.0 * t)) - 5.0 * t * np.exp(-4.0 * t) * 4.0 * math.e / 4.0)
    dip = float(np.min(y)) / D2R
    m = M.channel_metrics(t, y, [0.0], [4.0 * D2R])
    assert dip < 0.0
    assert m.undershoot_pct == pytest.approx(100.0 * -dip / 4.0, rel=1e-9)
    # a monotone response has none; an undefined step has None
    m2 = M.channel_metrics(t, 4.0 * D2R * (1.0 - np.exp(-t)), [0.0], [4.0 * D2R])
    assert m2.undershoot_pct == 0.0
    assert M.channel_metrics(t, np.zeros_like(t), [0.0], [0.0]).undershoot_pct is None


def test_circle_course_error_is_measured_without_north_over_the_pole():
    # GIVEN a truth flown along pymap3d's great circle straight over the north pole from
    # (89 N, 20 E), 100 Hz, its course 0.2 deg to the right of the circle from 48 s to 50 s
    # (the pole at 49.4 s), and an fc whose course target (the circle's course where the
    # vehicle is) is logged at 20 Hz, each row 20 ms late, as a decimated internals log can be
    import pymap3d
    from pymap3d import vincenty
    sphere = pymap3d.Ellipsoid.from_name("wgs84_mean")
    origin = (89.0, 20.0)
    t = np.arange(0.0, 60.0, 0.01)

    def course_at(t_s):
        dist = 2250.0 * np.asarray(t_s)
        lat, lon = vincenty.vreckon(*origin, dist, 0.0, sphere)
        _, az = vincenty.vdist(lat, lon, *vincenty.vreckon(*origin, dist + 1.0, 0.0, sphere), sphere)
        return np.radians(np.asarray(az, dtype=float))
    inject = np.where((t >= 48.0) & (t < 50.0), 0.2 * D2R, 0.0)
    # the truth's map about the origin: the distance along the initial azimuth (north)
    truth = {"t_s": t, "pos_n_m": 2250.0 * t, "pos_e_m": np.zeros_like(t),
             "chi_rad": course_at(t) + inject}
    tf = t[::5] + 0.02
    fc = {"t_s": tf, "guid_tgt_chi_rad": course_at(tf)}
    # WHEN measured
    e = M.circle_course_error_rad(truth, fc, origin)
    # THEN the injected error and nothing else, over the pole too
    assert abs(truth["chi_rad"][0]) < 1e-9 and abs(truth["chi_rad"][-1] - math.pi) < 1e-6
    assert np.max(np.abs(e - inject)) < 1e-6
    # while the north-referenced difference to the target in force reads degrees at the pole
    tg = M.targets_at(truth, {**fc, "guid_tgt_h_m": tf * 0, "guid_tgt_V_m_s": tf * 0})[:, 1]
    assert np.max(np.abs(np.degrees(M.wrap_rad(truth["chi_rad"] - tg)))) > 5.0
