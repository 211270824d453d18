"""Sensor models: AHRS (attitude, body rates, heading = yaw), air data (alpha, beta, true
airspeed, altitude, climb), ground speed, each with seeded white noise, a constant bias and a
latency.

The measurement vector layout is the contract of docs/architecture.md section 4 (``M_*``,
defined once in hyfc_wire.layout for the plant and the fc).

Per channel i (all configurable, each off-able: std 0, bias 0, latency 0):
    meas[i] = clean[i](t - latency_i) + bias_i + std_i * n,   n ~ N(0, 1) (seeded)
Latency is a whole number of frames (the scenario's seconds rounded to the nearest frame);
the time stamp meas[M_T_S] is the frame's sim time (the time the frame is sent). Angles are
wrapped after noise: roll and yaw to (-pi, pi], heading to [0, 2 pi).

Randomness: a per-simulation splitmix64 generator (state in a uint64[1] array) with
Box-Muller, so two simulations in one process never share a stream and the same seed gives
the same noise sequence.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from hyfc_wire.layout import (M_AIRSPEED, M_ALT, M_AOA, M_CLIMB,  # noqa: F401 (re-exported)
                              M_GROUNDSPEED, M_HEADING, M_N, M_P, M_PITCH, M_Q, M_R, M_ROLL,
                              M_SSA, M_T_S, M_YAW, MEAS_NAMES)
from plant_sim._jitcache import refresh as _refresh_jit_cache
from plant_sim.dynamics import (P_BIAS, P_DELAY, P_NOISE, P_DT, P_SENSORS_ON, X_P, X_PD, X_Q,
                                X_R, X_STEP, euler_from_quat, flight_path)

_refresh_jit_cache(__file__)

RING_N = 256          # latency buffer length in frames (max latency RING_N - 1 frames)

TWO_PI = 2.0 * math.pi


@njit(cache=True)
def rng_uniform(state):
    """Uniform double in (0, 1) from a splitmix64 generator with state in ``state[0]``."""
    state[0] += np.uint64(0x9E3779B97F4A7C15)
    z = state[0]
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    z = z ^ (z >> np.uint64(31))
    return ((z >> np.uint64(11)) + np.uint64(1)) * (1.0 / 9007199254740994.0)


@njit(cache=True)
def rng_normal(state):
    """Standard normal deviate (Box-Muller, one of the pair)."""
    u1 = rng_uniform(state)
    u2 = rng_uniform(state)
    return math.sqrt(-2.0 * math.log(u1)) * math.cos(TWO_PI * u2)


@njit(cache=True)
def clean_measurement(x, w, out):
    """Noise-free measurement vector of state ``x`` (w: float64[>= 7] scratch)."""
    euler_from_quat(x, w[0:3])
    flight_path(x, w[3:7])
    gamma = w[3]
    V = w[6]
    u = x[3]
    v = x[4]
    ww = x[5]
    out[M_ROLL] = w[0]
    out[M_PITCH] = w[1]
    out[M_YAW] = w[2]
    out[M_P] = x[X_P]
    out[M_Q] = x[X_Q]
    out[M_R] = x[X_R]
    out[M_AOA] = math.atan2(ww, u)
    out[M_SSA] = math.asin(min(1.0, max(-1.0, v / V)))
    out[M_AIRSPEED] = V
    out[M_ALT] = -x[X_PD]
    out[M_CLIMB] = V * math.sin(gamma)
    out[M_GROUNDSPEED] = V * math.cos(gamma)
    hd = w[2]                      # VFR_HUD.heading: the vehicle's compass heading (yaw)
    if hd < 0.0:
        hd += TWO_PI
    out[M_HEADING] = hd


@njit(cache=True)
def _wrap_pi(a):
    while a > math.pi:
        a -= TWO_PI
    while a <= -math.pi:
        a += TWO_PI
    return a


@njit(cache=True)
def measure(x, p, ring, ring_count, rng_state, w, meas_out):
    """Sensor outputs at the current frame (advance the latency ring by one frame).

    x: state (float64[X_N]); p: parameters; ring: float64[RING_N, M_N] clean history;
    ring_count: int64[1] frames pushed so far; rng_state: uint64[1]; w: float64[>= 7] scratch;
    meas_out: float64[M_N].
    """
    k = ring_count[0]
    slot = k % RING_N
    clean_measurement(x, w, ring[slot])
    ring[slot, M_T_S] = x[X_STEP] * p[P_DT]
    ring_count[0] = k + 1
    on = p[P_SENSORS_ON] != 0.0
    for i in range(M_N):
        d = int(p[P_DELAY + i]) if on else 0
        if d > k:
            d = k
        val = ring[(k - d) % RING_N, i]
        if on and i != M_T_S:
            val += p[P_BIAS + i]
            s = p[P_NOISE + i]
            if s > 0.0:
                val += s * rng_normal(rng_state)
        meas_out[i] = val
    meas_out[M_T_S] = ring[slot, M_T_S]
    meas_out[M_ROLL] = _wrap_pi(meas_out[M_ROLL])
    meas_out[M_YAW] = _wrap_pi(meas_out[M_YAW])
    h = meas_out[M_HEADING] % TWO_PI
    meas_out[M_HEADING] = h
