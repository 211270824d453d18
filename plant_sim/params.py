"""Scenario -> the plant's parameter vector (SI): ``build_params``.

Its own module so that both ``plant_sim.sim`` (the frame loop) and ``plant_sim.trim`` (the
trim solver) can use it without importing each other.
"""
from __future__ import annotations

import math

import numpy as np

from plant_sim import dynamics as dy
from plant_sim.dynamics import P_N
from plant_sim.scenario import Scenario
from plant_sim.sensors import (M_AIRSPEED, M_ALT, M_AOA, M_CLIMB, M_GROUNDSPEED, M_HEADING,
                               M_P, M_PITCH, M_Q, M_R, M_ROLL, M_SSA, M_YAW, RING_N)

DEG = math.pi / 180.0


def build_params(sc: Scenario) -> tuple[np.ndarray, int]:
    """Parameter vector (SI) and physics steps per frame from a validated scenario."""
    d = sc.data
    p = np.zeros(P_N)
    v = d["vehicle"]
    p[dy.P_MASS] = v["mass_kg"]
    p[dy.P_IXX] = v["Ixx_kg_m2"]
    p[dy.P_IYY] = v["Iyy_kg_m2"]
    p[dy.P_IZZ] = v["Izz_kg_m2"]
    p[dy.P_IXZ] = v["Ixz_kg_m2"]
    p[dy.P_XCG] = v["x_cg_m"]
    inertia = np.array([[v["Ixx_kg_m2"], 0.0, -v["Ixz_kg_m2"]],
                        [0.0, v["Iyy_kg_m2"], 0.0],
                        [-v["Ixz_kg_m2"], 0.0, v["Izz_kg_m2"]]])
    if np.linalg.det(inertia) <= 0.0:
        raise ValueError(f"{sc.path}: inertia matrix (Ixx, Iyy, Izz, Ixz) is not positive definite")
    p[dy.P_IINV:dy.P_IINV + 9] = np.linalg.inv(inertia).ravel()
    tm = d["timing"]
    p[dy.P_DT] = 1.0 / tm["physics_hz"]
    p[dy.P_FRAME_DT] = 1.0 / tm["frame_hz"]
    n_sub = int(round(tm["physics_hz"] / tm["frame_hz"]))
    u = d["uncertainty"]
    for i, k in enumerate(("CL", "CD", "CY", "Cl", "Cm", "Cn")):
        p[dy.P_UNC + i] = 1.0 + u[k]
    ds = d["disturbance"]
    p[dy.P_DIST_ON] = 1.0 if ds["enabled"] else 0.0
    amp = ds["amplitude"] * ds["scale"]
    if ds["unit"] == "deg/s^2":
        amp *= DEG
    p[dy.P_DIST_AMP] = amp
    p[dy.P_DIST_MOMENT] = 1.0 if ds["unit"] == "N*m" else 0.0
    for i, k in enumerate(("phase_roll_deg", "phase_pitch_deg", "phase_yaw_deg")):
        p[dy.P_DIST_PHASE + i] = ds[k] * DEG
    p[dy.P_DIST_QREF] = ds["qbar_ref_Pa"]
    p[dy.P_DIST_END] = ds["end_s"]
    s = d["speed"]
    p[dy.P_SPEED_MODE] = dy.SPEED_HOLD if s["model"] == "hold" else dy.SPEED_NONE
    p[dy.P_VREF] = s["V_ref_m_s"] if s["V_ref_m_s"] > 0.0 else d["initial"]["V_m_s"]
    p[dy.P_KV] = s["k_1_s"]
    p[dy.P_TMAX] = s["thrust_max_N"]
    if s["model"] == "engine":
        p[dy.P_SPEED_MODE] = dy.SPEED_ENGINE
    p[dy.P_ENG_CT] = s["thrust_coef_max"]
    p[dy.P_ENG_TAU] = s["throttle_tau_s"]
    p[dy.P_ENG_RATE] = s["throttle_rate_1_s"]
    if d["earth"]["model"] == "sphere":
        from plant_sim.earth import EARTH_RADIUS_M, origin_vectors   # pymap3d: only here
        p[dy.P_EARTH] = dy.EARTH_SPHERE
        p[dy.P_EARTH_R] = EARTH_RADIUS_M
        p[dy.P_ORIGIN:dy.P_ORIGIN + 9] = origin_vectors(d["gnss"]["origin_lat_deg"],
                                                        d["gnss"]["origin_lon_deg"])
    a = d["actuators"]
    p[dy.P_ACT_LIMIT] = a["limit_deg"] * DEG
    p[dy.P_ACT_RATE] = a["rate_limit_deg_s"] * DEG
    p[dy.P_ACT_TAU] = a["tau_s"]
    sn = d["sensors"]
    p[dy.P_SENSORS_ON] = 1.0 if sn["enabled"] else 0.0
    nz, bs, lat = sn["noise"], sn["bias"], sn["latency_s"]
    noise = {M_ROLL: nz["attitude_deg"] * DEG, M_PITCH: nz["attitude_deg"] * DEG,
             M_YAW: nz["attitude_deg"] * DEG, M_P: nz["rate_deg_s"] * DEG,
             M_Q: nz["rate_deg_s"] * DEG, M_R: nz["rate_deg_s"] * DEG,
             M_AOA: nz["aoa_deg"] * DEG, M_SSA: nz["ssa_deg"] * DEG,
             M_AIRSPEED: nz["airspeed_m_s"], M_ALT: nz["alt_m"], M_CLIMB: nz["climb_m_s"],
             M_GROUNDSPEED: nz["groundspeed_m_s"], M_HEADING: nz["heading_deg"] * DEG}
    bias = {M_ROLL: bs["roll_deg"] * DEG, M_PITCH: bs["pitch_deg"] * DEG, M_YAW: bs["yaw_deg"] * DEG,
            M_P: bs["p_deg_s"] * DEG, M_Q: bs["q_deg_s"] * DEG, M_R: bs["r_deg_s"] * DEG,
            M_AOA: bs["aoa_deg"] * DEG, M_SSA: bs["ssa_deg"] * DEG,
            M_AIRSPEED: bs["airspeed_m_s"], M_ALT: bs["alt_m"], M_CLIMB: bs["climb_m_s"]}
    frame_hz = tm["frame_hz"]
    delay = {}
    for ch in (M_ROLL, M_PITCH, M_YAW, M_P, M_Q, M_R, M_HEADING):
        delay[ch] = lat["ahrs"]
    for ch in (M_AOA, M_SSA, M_AIRSPEED, M_ALT, M_CLIMB):
        delay[ch] = lat["air_data"]
    for ch in (M_GROUNDSPEED,):
        delay[ch] = lat["gps"]
    for ch, val in noise.items():
        p[dy.P_NOISE + ch] = val
    for ch, val in bias.items():
        p[dy.P_BIAS + ch] = val
    for ch, sec in delay.items():
        frames = int(round(sec * frame_hz))
        if frames > RING_N - 1:
            raise ValueError(f"{sc.path}: sensors.latency_s gives {frames} frames; at most "
                             f"{RING_N - 1} frames at {frame_hz} Hz")
        p[dy.P_DELAY + ch] = frames
    return p, n_sub
