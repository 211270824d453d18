"""Actuator limits/rates/lag and sensor noise statistics (plant_sim/dynamics.py, sensors.py)."""
import math

import numpy as np
import pytest

from plant_sim import dynamics as dy
from plant_sim.scenario import load, parse
from plant_sim.sensors import (M_AOA, M_N, M_P, M_PITCH, M_ROLL, M_SSA, M_T_S, M_AIRSPEED,
                               M_ALT, M_GROUNDSPEED, M_HEADING, M_YAW)
from plant_sim.sim import PlantSim

DEG = math.pi / 180.0


def _sim(text):
    return PlantSim(parse(text, "test"))


def test_position_limit_holds():
    sim = _sim(open(load("nominal").path).read())
    cmd = np.array([35.0 * DEG, -35.0 * DEG, 25.0 * DEG])
    peak = np.zeros(3)
    for _ in range(400):
        sim.step_frame(cmd)
        peak = np.maximum(peak, np.abs(sim.x[dy.X_DL:dy.X_DL + 3]))
    assert np.all(peak <= 20.0 * DEG + 1e-15)
    assert sim.x[dy.X_DL] == pytest.approx(20.0 * DEG, abs=1e-12)
    assert sim.x[dy.X_DR] == pytest.approx(-20.0 * DEG, abs=1e-12)


def test_rate_limit_holds_and_is_reached():
    text = open(load("nominal").path).read().replace("rate_limit_deg_s = 90.0", "rate_limit_deg_s = 60.0")
    sim = _sim(text)
    dt = sim.physics_dt_s
    cmd = np.array([20.0 * DEG, -20.0 * DEG, 10.0 * DEG])
    prev = sim.x[dy.X_DL:dy.X_DL + 3].copy()
    max_rate = 0.0
    for _ in range(int(0.05 / sim.frame_dt_s)):
        sim.step_frame(cmd)
        now = sim.x[dy.X_DL:dy.X_DL + 3]
        max_rate = max(max_rate, float(np.max(np.abs(now - prev))) / sim.frame_dt_s)
        prev = now.copy()
    assert max_rate <= 60.0 * DEG * (1 + 1e-12)
    assert max_rate == pytest.approx(60.0 * DEG, rel=1e-9)   # the lag alone would be faster
    # per physics step too: the largest single-step change is rate * dt
    sim.step_frame(-cmd)
    before = sim.x[dy.X_DL]
    dy.rk4_step(sim.x, sim.p, sim.w)
    assert abs(sim.x[dy.X_DL] - before) == pytest.approx(60.0 * DEG * dt, rel=1e-9)


def test_first_order_lag_without_rate_limit():
    text = open(load("nominal").path).read().replace("rate_limit_deg_s = 90.0", "rate_limit_deg_s = 0.0")
    text = text.replace("tau_s = 0.02", "tau_s = 0.05")
    sim = _sim(text)
    step = 2.0 * DEG
    cmd = np.array([step, step, step])
    n = int(round(0.05 / sim.frame_dt_s))
    for _ in range(n):
        sim.step_frame(cmd)
    # after one time constant: 1 - e^-1 of the step (exact discretisation)
    assert sim.x[dy.X_DL] == pytest.approx(step * (1 - math.exp(-1.0)), rel=1e-9)


def test_no_lag_no_rate_follows_command_in_one_step():
    text = open(load("nominal").path).read().replace("rate_limit_deg_s = 90.0", "rate_limit_deg_s = 0.0")
    text = text.replace("tau_s = 0.02", "tau_s = 0.0")
    sim = _sim(text)
    cmd = np.array([5.0 * DEG, -3.0 * DEG, 1.0 * DEG])
    sim.step_frame(cmd)
    np.testing.assert_allclose(sim.x[dy.X_DL:dy.X_DL + 3], cmd, rtol=0, atol=1e-15)


NOISY = """
[sensors.noise]
attitude_deg = 0.5
rate_deg_s = 0.2
aoa_deg = 0.1
ssa_deg = 0.3
airspeed_m_s = 2.0
alt_m = 5.0
climb_m_s = 0.1
groundspeed_m_s = 0.5
heading_deg = 0.05
"""


def _noisy_text(bias_pitch_deg=0.0, latency=0.0):
    text = open(load("nominal").path).read()
    a = text.index("[sensors.noise]")
    b = text.index("[sensors.latency_s]")
    text = text[:a] + NOISY.strip() + f"\n\n[sensors.bias]\npitch_deg = {bias_pitch_deg}\n\n" + text[b:]
    text = text.replace("[sensors]\nenabled = false", "[sensors]\nenabled = true")
    text = text.replace("air_data = 0.0", f"air_data = {latency}")
    return text


def test_sensor_noise_has_configured_statistics_for_a_fixed_seed():
    # GIVEN the plant frozen at its initial state, many frames of measurements
    sim = PlantSim(parse(_noisy_text(bias_pitch_deg=0.4), "noisy"), seed=7)
    clean = np.zeros(M_N)
    quiet = PlantSim(load("nominal"))
    quiet.measure(clean)
    n = 20000
    out = np.zeros((n, M_N))
    for k in range(n):
        sim.measure(out[k])
    err = out - clean
    std = err.std(axis=0)
    mean = err.mean(axis=0)
    tol = 4.0 / math.sqrt(2 * n)     # 4 sigma of a sample std estimate
    for ch, s in ((M_ROLL, 0.5 * DEG), (M_PITCH, 0.5 * DEG), (M_P, 0.2 * DEG), (M_AOA, 0.1 * DEG),
                  (M_SSA, 0.3 * DEG), (M_AIRSPEED, 2.0), (M_ALT, 5.0)):
        assert std[ch] == pytest.approx(s, rel=tol), ch
    assert mean[M_PITCH] == pytest.approx(0.4 * DEG, abs=4 * 0.5 * DEG / math.sqrt(n))
    assert abs(mean[M_ROLL]) < 4 * 0.5 * DEG / math.sqrt(n)
    # channels are independent
    assert abs(np.corrcoef(err[:, M_ROLL], err[:, M_PITCH])[0, 1]) < 4 / math.sqrt(n)
    assert np.all(out[:, M_T_S] == 0.0)
    # AND the same seed gives the same numbers, another seed different ones
    again = PlantSim(parse(_noisy_text(bias_pitch_deg=0.4), "noisy"), seed=7)
    other = PlantSim(parse(_noisy_text(bias_pitch_deg=0.4), "noisy"), seed=8)
    a = np.zeros(M_N)
    b = np.zeros(M_N)
    again.measure(a)
    other.measure(b)
    np.testing.assert_array_equal(a, out[0])
    assert not np.array_equal(b, out[0])


def test_sensor_latency_delays_by_whole_frames():
    sim = PlantSim(parse(_noisy_text(latency=0.01), "lat"))
    sim.p[dy.P_NOISE:dy.P_NOISE + M_N] = 0.0        # noise off, latency on
    truth = []
    meas = []
    cmd = np.array([0.0, 0.0, 0.0])
    m = np.zeros(M_N)
    clean = np.zeros(M_N)
    from plant_sim.sensors import clean_measurement
    for _ in range(20):
        clean_measurement(sim.x, np.zeros(8), clean)
        truth.append(clean.copy())
        sim.measure(m)
        meas.append(m.copy())
        sim.step_frame(cmd)
    d = 5   # 0.01 s at 500 Hz
    for k in range(d, 20):
        assert meas[k][M_AOA] == truth[k - d][M_AOA]
        assert meas[k][M_ROLL] == truth[k][M_ROLL]       # AHRS latency 0
        assert meas[k][M_T_S] == pytest.approx(k * sim.frame_dt_s, abs=1e-12)


def test_sensors_disabled_gives_exact_values():
    text = _noisy_text(bias_pitch_deg=1.0).replace("[sensors]\nenabled = true", "[sensors]\nenabled = false")
    sim = PlantSim(parse(text, "off"))
    m = np.zeros(M_N)
    sim.measure(m)
    assert m[M_PITCH] == pytest.approx(1.0 * DEG, abs=1e-15)
    assert m[M_AOA] == pytest.approx(1.0 * DEG, abs=1e-15)
    assert m[M_YAW] == pytest.approx(-5.0 * DEG, abs=1e-15)
    assert m[M_HEADING] == pytest.approx(2 * math.pi - 5.0 * DEG, abs=1e-12)   # yaw, 0..2 pi
    assert m[M_GROUNDSPEED] == pytest.approx(2200.0, abs=1e-9)
