"""The plant's in-process API (docs/architecture.md section 12): ``PlantSim``.

    sim = PlantSim(load("paper"), seed=None)   # allocates once
    sim.measure(meas)                          # float64[14] at sim.t_s (section 4)
    sim.step_frame(cmd_rad)                    # latch the surface command, advance one frame
    sim.truth_row(row)                         # float64[TRUTH_N], names in PlantSim.TRUTH_NAMES

The frame loop the plant process runs (and tools can copy) is, per frame k at t_k:
measure -> send -> receive command -> ``command(cmd)`` -> ``truth_row`` (state, measurement
and command at t_k) -> ``advance()`` (n_sub RK4 steps to t_k+1). ``step_frame(cmd)`` is
``command(cmd)`` + ``advance()``.

For speed, tools call the njit kernels directly on ``sim.kernel_args()`` (see docs/plant.md,
"In-process API"): ``dynamics.advance_frame``, ``sensors.measure``, ``truth_kernel``.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from plant_sim._jitcache import refresh as _refresh_jit_cache
from plant_sim import dynamics as dy
from plant_sim.dynamics import (AX_ALPHA, AX_BETA, AX_L, AX_M, AX_MACH, AX_N, AX_QBAR,
                                AX_THRUST, AX_V, W_AUX, W_N, X_CLIP, X_CMD_L, X_DL, X_N,
                                X_P, X_PD, X_PE, X_PN, X_Q, X_R, X_STEP, X_U, X_V, X_W)
from plant_sim.scenario import Scenario
from plant_sim.sensors import M_N, MEAS_NAMES, RING_N
from plant_sim import sensors as se
from plant_sim.gnss import GnssSensor
from plant_sim.params import build_params  # noqa: F401  (also the public name here)

_refresh_jit_cache(__file__)

DEG = math.pi / 180.0

_STATE_NAMES = (
    "t_s", "alpha_rad", "beta_rad", "mu_rad", "p_rad_s", "q_rad_s", "r_rad_s", "V_m_s", "h_m",
    "gamma_rad", "chi_rad", "phi_rad", "theta_rad", "psi_rad", "mach", "qbar_pa",
    "pos_n_m", "pos_e_m", "u_m_s", "v_m_s", "w_m_s",
    "delta_cmd_left_rad", "delta_cmd_right_rad", "delta_cmd_rudder_rad",
    "delta_left_rad", "delta_right_rad", "delta_rudder_rad",
    "dist_p_rad_s2", "dist_q_rad_s2", "dist_r_rad_s2",
    "moment_l_N_m", "moment_m_N_m", "moment_n_N_m", "thrust_N", "aero_clip_flags",
)
TRUTH_NAMES: tuple[str, ...] = _STATE_NAMES + tuple("meas_" + n for n in MEAS_NAMES)
TRUTH_N = len(TRUTH_NAMES)
T_MEAS0 = len(_STATE_NAMES)      # first meas_* column


@njit(cache=True)
def truth_kernel(x, p, w, meas, out):
    """Fill one truth row (layout TRUTH_NAMES) from state x, the last measurement ``meas``.

    Aerodynamic moments (about the c.g., with the uncertainty multipliers) are evaluated at
    the current state and surface positions. ``w``: the work array of the simulation (its
    aero slots are overwritten).
    """
    flags = dy.aero_eval(x, x[X_DL], x[X_DL + 1], x[X_DL + 2], p, w)
    w[W_AUX + dy.AX_THR_POS] = x[dy.X_THR]
    thrust = dy.thrust_n(x, p, w)
    t = x[X_STEP] * p[dy.P_DT]
    o = W_AUX
    out[0] = t
    out[1] = w[o + AX_ALPHA]
    out[2] = w[o + AX_BETA]
    fp = w[dy.W_XT:dy.W_XT + 4]
    dy.flight_path(x, fp)
    gamma = fp[0]
    chi = fp[1]
    out[3] = fp[2]
    out[4] = x[X_P]
    out[5] = x[X_Q]
    out[6] = x[X_R]
    out[7] = w[o + AX_V]
    out[8] = -x[X_PD]
    out[9] = gamma
    out[10] = chi
    eu = w[dy.W_XT:dy.W_XT + 3]
    dy.euler_from_quat(x, eu)
    out[11] = eu[0]
    out[12] = eu[1]
    out[13] = eu[2]
    out[14] = w[o + AX_MACH]
    out[15] = w[o + AX_QBAR]
    out[16] = x[X_PN]
    out[17] = x[X_PE]
    out[18] = x[X_U]
    out[19] = x[X_V]
    out[20] = x[X_W]
    for k in range(3):
        out[21 + k] = x[X_CMD_L + k]
        out[24 + k] = x[X_DL + k]
    d0, d1, d2 = dy.disturbance_components(t, p, w[o + AX_QBAR])
    out[27] = d0
    out[28] = d1
    out[29] = d2
    out[30] = w[o + AX_L]
    out[31] = w[o + AX_M]
    out[32] = w[o + AX_N]
    out[33] = thrust
    out[34] = float(int(x[X_CLIP]) | flags)
    for i in range(M_N):
        out[35 + i] = meas[i]


@njit(cache=True)
def frame_kernel(x, p, w, ring, ring_count, rng_state, meas_work, meas, cmd_rad, row, n_sub):
    """One frame of the process loop in one call: latch ``cmd_rad``, write the truth row at t_k
    (with ``meas``, the measurement sent at t_k), advance to t_k+1 and measure into ``meas``.
    Returns the aero clip flags of the frame."""
    x[X_CMD_L] = cmd_rad[0]
    x[X_CMD_L + 1] = cmd_rad[1]
    x[X_CMD_L + 2] = cmd_rad[2]
    truth_kernel(x, p, w, meas, row)
    flags = dy.advance_frame_latched(x, p, w, n_sub)
    se.measure(x, p, ring, ring_count, rng_state, meas_work, meas)
    return flags


class PlantSim:
    """The winged-cone plant for in-process use (allocates everything once).

    Parameters
    ----------
    scenario : a validated ``plant_sim.scenario.Scenario``.
    seed : sensor-noise seed; ``None`` uses the scenario's ``seed``.
    """
    TRUTH_NAMES = TRUTH_NAMES
    TRUTH_N = TRUTH_N

    def __init__(self, scenario: Scenario, seed: int | None = None):
        self.scenario = scenario
        self.seed = int(scenario.seed if seed is None else seed)
        self.p, self.n_sub = build_params(scenario)
        self.physics_dt_s = float(self.p[dy.P_DT])
        self.frame_dt_s = float(self.p[dy.P_FRAME_DT])
        self.x = np.zeros(X_N)
        self.w = np.zeros(W_N)
        self.ring = np.zeros((RING_N, M_N))
        self.ring_count = np.zeros(1, dtype=np.int64)
        self.rng_state = np.zeros(1, dtype=np.uint64)
        self.meas_work = np.zeros(8)
        self.last_meas = np.zeros(M_N)
        self.cmd_rad = np.zeros(3)
        self.trim_rad = np.zeros(3)        # initial-state trim (set by reset when asked)
        self._trim_cache = None
        self.clip_frames = 0               # frames in which the aero inputs were clipped
        self.frames = 0
        #: GNSS receiver (its own noise stream): ``gnss.update(k, x)`` per frame, docs/plant.md
        self.gnss = GnssSensor(scenario, self.seed, self.frame_dt_s)
        self.reset()

    # ---- life cycle ----
    def reset(self) -> None:
        """Back to the scenario's initial state, sensor history and noise stream."""
        ini = self.scenario.data["initial"]
        dy.initial_state(ini["V_m_s"], ini["h_m"], ini["alpha_deg"] * DEG, ini["beta_deg"] * DEG,
                         ini["mu_deg"] * DEG, ini["gamma_deg"] * DEG, ini["chi_deg"] * DEG,
                         ini["p_deg_s"] * DEG, ini["q_deg_s"] * DEG, ini["r_deg_s"] * DEG, self.x)
        dy.init_sphere(self.x, self.p)      # round Earth: the Earth-centred block and its view
        if self.scenario.data["actuators"]["initial"] == "trim":
            if self._trim_cache is None:      # the scenario does not change: solve once
                from plant_sim.trim import trim_at
                res = trim_at(self.scenario, ini["alpha_deg"] * DEG, ini["beta_deg"] * DEG)
                self._trim_cache = res.deflection_rad.copy()
            self.trim_rad[:] = self._trim_cache
        else:
            self.trim_rad[:] = 0.0
        self.x[X_DL:X_DL + 3] = self.trim_rad
        self.x[X_CMD_L:X_CMD_L + 3] = self.trim_rad
        self.cmd_rad[:] = self.trim_rad
        self.w[:] = 0.0
        thr = self.initial_throttle()
        self.x[dy.X_THR] = thr
        self.x[dy.X_CMD_THR] = thr
        self.w[:] = 0.0
        self.ring[:] = 0.0
        self.ring_count[0] = 0
        self.rng_state[0] = np.uint64(self.seed & 0xFFFFFFFFFFFFFFFF)
        self.last_meas[:] = 0.0
        self.clip_frames = 0
        self.frames = 0
        if hasattr(self, "gnss"):
            self.gnss.reset()

    def warm_up(self) -> None:
        """Call every kernel the plant process uses once (compiled, or loaded from numba's
        cache, now rather than at the first frame), then reset."""
        m = np.zeros(M_N)
        row = np.zeros(self.TRUTH_N)
        self.measure(m)
        self.truth_row(row)
        self.step_frame(self.trim_rad.copy())
        self.frame(self.trim_rad.copy(), row)
        self.reset()

    def initial_throttle(self) -> float:
        """Engine model: the scenario's ``speed.throttle_initial``, or (if -1) the throttle
        whose thrust balances drag and gravity along the path at the current state:
        T cos(alpha) cos(beta) = D + m g sin(gamma), clipped to [0, 1]. 0 for other models."""
        if self.p[dy.P_SPEED_MODE] != dy.SPEED_ENGINE:
            return 0.0
        given = float(self.scenario.data["speed"]["throttle_initial"])
        if given >= 0.0:
            return given
        x, p, w = self.x, self.p, self.w
        dy.aero_eval(x, x[X_DL], x[X_DL + 1], x[X_DL + 2], p, w)
        fp = np.zeros(4)
        dy.flight_path(x, fp)
        o = W_AUX
        need = w[o + dy.AX_DRAG] + p[dy.P_MASS] * w[o + dy.AX_GRAV] * math.sin(fp[0])
        full = p[dy.P_ENG_CT] * w[o + AX_QBAR] * dy.S_REF_M2
        proj = math.cos(w[o + AX_ALPHA]) * math.cos(w[o + AX_BETA])
        if not full > 0.0 or proj <= 0.05:
            return 0.0
        return min(max(need / (proj * full), 0.0), 1.0)

    def throttle(self, thr: float) -> None:
        """Latch a throttle command (0..1; the engine speed model only, ignored otherwise)."""
        self.x[dy.X_CMD_THR] = thr

    @property
    def t_s(self) -> float:
        """Sim time (s) = physics steps x physics step (exact multiple)."""
        return float(self.x[X_STEP]) * self.physics_dt_s

    @property
    def frame_index(self) -> int:
        return self.frames

    # ---- per frame ----
    def command(self, servo_cmd_rad) -> None:
        """Latch a surface command (float64[3], rad: left elevon, right elevon, rudder)."""
        x = self.x
        x[X_CMD_L] = servo_cmd_rad[0]
        x[X_CMD_L + 1] = servo_cmd_rad[1]
        x[X_CMD_L + 2] = servo_cmd_rad[2]

    def advance(self) -> int:
        """Advance one frame (n_sub RK4 steps) with the latched command; returns clip flags."""
        flags = dy.advance_frame_latched(self.x, self.p, self.w, self.n_sub)
        self.frames += 1
        if flags:
            self.clip_frames += 1
        return flags

    def step_frame(self, servo_cmd_rad) -> int:
        """Apply a surface command (rad) and advance one frame; returns the aero clip flags."""
        flags = dy.advance_frame(self.x, servo_cmd_rad, self.p, self.w, self.n_sub)
        self.frames += 1
        if flags:
            self.clip_frames += 1
        return flags

    def measure(self, meas_out) -> None:
        """Sensor outputs at ``t_s`` into ``meas_out`` (float64[14], architecture.md section 4).

        Call once per frame: each call advances the latency buffer and the noise stream.
        """
        se.measure(self.x, self.p, self.ring, self.ring_count, self.rng_state, self.meas_work,
                   meas_out)
        self.last_meas[:] = meas_out

    def truth_row(self, out) -> None:
        """True state, inputs and the last measurement at ``t_s`` (layout TRUTH_NAMES)."""
        truth_kernel(self.x, self.p, self.w, self.last_meas, out)

    def kernel_args(self):
        """Arrays for the njit kernels: (x, p, w, n_sub, ring, ring_count, rng_state, meas_work).

        advance_frame(x, cmd, p, w, n_sub); measure(x, p, ring, ring_count, rng_state,
        meas_work, meas_out); truth_kernel(x, p, w, meas, out).
        """
        return (self.x, self.p, self.w, self.n_sub, self.ring, self.ring_count, self.rng_state,
                self.meas_work)

    def frame(self, cmd_rad, row) -> int:
        """The process loop's frame in one compiled call (see ``frame_kernel``): latch
        ``cmd_rad``, truth row at t_s into ``row``, advance, measure into ``self.last_meas``.
        Call ``measure`` once before the first frame."""
        flags = frame_kernel(self.x, self.p, self.w, self.ring, self.ring_count, self.rng_state,
                             self.meas_work, self.last_meas, cmd_rad, row, self.n_sub)
        self.frames += 1
        if flags:
            self.clip_frames += 1
        return flags
