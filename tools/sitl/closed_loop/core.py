"""In-process closed loop: the control law (fc.control) flying the plant (plant_sim), no UDP.

Used by the law's closed-loop tests, by campaigns (tools.evidence.montecarlo) and by benchmarks. The
whole loop runs inside one numba function (plant RK4 frames, the law's slow and fast loops,
recording), so a 20 s flight at 500 Hz takes a fraction of a second once compiled.

    from tools.sitl.closed_loop import simulate
    res = simulate("paper", coordinated=True, command_shaping="steps")
    res.metrics()["alpha"].overshoot_pct

By default the estimated state the law sees is the plant's truth (alpha, beta, mu, p, q, r,
V, h, gamma exactly as the plant integrates them): the law is tested, not the estimator.
``estimate="sensors"`` puts the scenario's sensor model and the fc's estimator in the loop
instead. The HIL path (tools.hil) adds the wire and the processes.

Timing follows the fc's lockstep schedule (docs/wire.md s. 4): at each frame stamp the slow
loop runs when due, then the fast loop when due, then the plant advances one frame with the
latest surface command. The frame rate is the scenario's (``timing.frame_hz``); ``fast_hz``
and ``slow_hz`` must divide it.
"""
from __future__ import annotations

import math
import time
from pathlib import Path
from dataclasses import dataclass, field

import numpy as np
from numba import njit

from fc.control import layout as L
from fc.control.kernels import fast_kernel, reset_kernel, slow_kernel
from fc.control.law import AttitudeLaw
from plant_sim import dynamics as dy
from plant_sim.scenario import Scenario, load
from plant_sim.sensors import M_N, measure
from fc.estimator import LIMITS_HI, LIMITS_LO, estimate_kernel
from plant_sim.sim import TRUTH_N, TRUTH_NAMES, PlantSim, truth_kernel

from hyfc_wire.numba_cache import drop_stale
from hyfc_wire.timeline import command_arrays

# _run inlines the law's and the plant's kernels: recompile when any of them changed
_ROOT = Path(__file__).resolve().parents[3]
drop_stale(__file__, [str(f) for pkg in ("fc/control", "plant_sim", "hyfc_wire")
                      for f in (_ROOT / pkg).glob("*.py")]
           + [str(_ROOT / "fc" / "estimator.py"), str(_ROOT / "fc" / "link.py")])

DEG = math.pi / 180.0

# Truth columns 1..9 are alpha, beta, mu, p, q, r, V, h, gamma: the law's E_* order.
_TRUTH_EST0 = TRUTH_NAMES.index("alpha_rad")
assert TRUTH_NAMES[_TRUTH_EST0:_TRUTH_EST0 + L.E_N] == (
    "alpha_rad", "beta_rad", "mu_rad", "p_rad_s", "q_rad_s", "r_rad_s", "V_m_s", "h_m",
    "gamma_rad"), "plant truth layout no longer matches fc.control.layout E_*"
_T_DELTA = TRUTH_NAMES.index("delta_left_rad")
_T_DCMD = TRUTH_NAMES.index("delta_cmd_left_rad")

#: |alpha|, |beta| or |mu| beyond this (rad), or a non-finite state, stops a run as diverged.
DIVERGED_RAD = 45.0 * DEG


@njit(cache=True)
def sense_frame(use_sensors, px, pp, pw, meas, row, est, ring, ring_count, rng_state,
                meas_work, good, good_t, lo, hi, stale_s, masks):
    """The start of a frame of the in-process loops: [sensors.measure], the plant's truth row
    at t_k into ``row``, and the estimated state ``est`` (float64[E_N]): the truth's alpha ..
    gamma, or with ``use_sensors`` the fc's estimator (fc.estimator.estimate_kernel) on the
    measurement."""
    if use_sensors:
        measure(px, pp, ring, ring_count, rng_state, meas_work, meas)
    truth_kernel(px, pp, pw, meas, row)
    if use_sensors:
        estimate_kernel(meas, good, good_t, lo, hi, stale_s, est, masks)
    else:
        for i in range(L.E_N):
            est[i] = row[1 + i]


@njit(cache=True)
def law_frame(k, n_slow, n_fast, dt_slow, dt_fast, est, cmd,
              par, lx, nm, st, tab, atm, grid, delta):
    """The law's share of frame ``k`` in the fc's lockstep order: reset at frame 0, the slow
    loop when due, then the fast loop when due (writes ``delta``, the surface command)."""
    if k == 0:
        reset_kernel(est, par, lx, st, delta)
    if k % n_slow == 0:
        slow_kernel(est, cmd, dt_slow, par, lx, nm, st, tab, atm, grid)
    if k % n_fast == 0:
        fast_kernel(est, dt_fast, par, lx, nm, st, tab, atm, grid, delta)


@njit(cache=True)
def diverged_row(row):
    """True when the truth row's |alpha|, |beta| or |mu| exceeds DIVERGED_RAD (45 deg) or is
    not a number: the in-process loops stop there."""
    bad = False
    for i in range(3):
        v = row[1 + i]
        if not (abs(v) < 0.7853981633974483):     # 45 deg, also catches NaN
            bad = True
    return bad


@njit(cache=True)
def _run(n_frames, n_fast, n_slow, dt_fast, dt_slow, rec_every, cmd_t, cmd_v,
         px, pp, pw, n_sub, meas, row, est, cmd,
         par, lx, nm, st, tab, atm, grid, delta,
         out_truth, out_status,
         use_sensors, ring, ring_count, rng_state, meas_work, good, good_t, lo, hi, stale_s,
         masks):
    """The closed loop over ``n_frames`` frames; returns (frames flown, samples recorded).

    Per frame (the plant process's order): [sensors.measure], truth row, estimated state
    (truth, or fc.estimator.estimate_kernel on the measurement), slow loop when due, fast
    loop when due, record every ``rec_every``-th frame, plant advances one frame. Stops
    early if the true attitude diverges (|alpha|, |beta| or |mu| > 45 deg, or NaN).
    """
    k_cmd = 0
    n_cmd = cmd_t.shape[0]
    n_rec = 0
    frame_dt = pp[dy.P_FRAME_DT]
    t0 = px[dy.X_STEP] * pp[dy.P_DT]
    for k in range(n_frames):
        sense_frame(use_sensors, px, pp, pw, meas, row, est, ring, ring_count, rng_state,
                    meas_work, good, good_t, lo, hi, stale_s, masks)
        t = t0 + k * frame_dt
        while k_cmd + 1 < n_cmd and cmd_t[k_cmd + 1] <= t + 1e-9:
            k_cmd += 1
        cmd[0] = cmd_v[k_cmd, 0]
        cmd[1] = cmd_v[k_cmd, 1]
        cmd[2] = cmd_v[k_cmd, 2]
        law_frame(k, n_slow, n_fast, dt_slow, dt_fast, est, cmd,
                  par, lx, nm, st, tab, atm, grid, delta)
        if k % rec_every == 0:
            for i in range(row.shape[0]):
                out_truth[n_rec, i] = row[i]
            for i in range(st.shape[0]):
                out_status[n_rec, i] = st[i]
            n_rec += 1
        if diverged_row(row):
            return k + 1, n_rec
        dy.advance_frame(px, delta, pp, pw, n_sub)
    return n_frames, n_rec


@dataclass
class ClosedLoopResult:
    """Time histories of one closed-loop flight (SI; one row per recorded frame).

    Attributes
    ----------
    t_s : (n,) sim time of each sample, s.
    alpha_rad, beta_rad, mu_rad : (n,) true attitude.
    alpha_cmd_rad, beta_cmd_rad, mu_cmd_rad : (n,) raw command timeline (zero-order hold).
    alpha_ref_rad, beta_ref_rad, mu_ref_rad : (n,) the command the law tracked (after the
        prefilter, if on; equal to the raw command with steps).
    p_rad_s, q_rad_s, r_rad_s : (n,) true body rates.
    V_m_s, h_m : (n,) airspeed and altitude.
    delta_cmd_rad : (n, 3) surface commands; delta_rad : (n, 3) actual deflections (left
        elevon, right elevon, rudder).
    sat : (n, 3) the law's per-surface saturation flags (1 = allocation beyond the limit).
    sat_any, omega_c_limited : (n,) flags from the law's status.
    status : (n, STATUS_N) the law's full status record (names in ``status_names``).
    truth : (n, TRUTH_N) the plant's truth rows (names in ``truth_names``).
    diverged : True if the run stopped early (|alpha|, |beta| or |mu| > 45 deg or NaN).
    cmd_t_s, cmd_rad : the command timeline, (k,) s and (k, 3) rad.
    params : the law's parameters as flown (table units).
    scenario : the scenario name; coordinated, command_shaping, estimate as flown.
    wall_s : wall time of the loop (excluding loading / compiling the code), s.
    """
    t_s: np.ndarray
    alpha_rad: np.ndarray
    beta_rad: np.ndarray
    mu_rad: np.ndarray
    alpha_cmd_rad: np.ndarray
    beta_cmd_rad: np.ndarray
    mu_cmd_rad: np.ndarray
    alpha_ref_rad: np.ndarray
    beta_ref_rad: np.ndarray
    mu_ref_rad: np.ndarray
    p_rad_s: np.ndarray
    q_rad_s: np.ndarray
    r_rad_s: np.ndarray
    V_m_s: np.ndarray
    h_m: np.ndarray
    delta_cmd_rad: np.ndarray
    delta_rad: np.ndarray
    sat: np.ndarray
    sat_any: np.ndarray
    omega_c_limited: np.ndarray
    status: np.ndarray
    truth: np.ndarray
    diverged: bool
    cmd_t_s: np.ndarray
    cmd_rad: np.ndarray
    params: dict
    scenario: str
    coordinated: bool
    command_shaping: str
    estimate: str
    surface_limit_rad: float
    wall_s: float
    status_names: tuple = field(default=L.STATUS_NAMES)
    truth_names: tuple = field(default=TRUTH_NAMES)

    def status_col(self, name: str) -> np.ndarray:
        """One column of the law's status by name."""
        return self.status[:, self.status_names.index(name)]

    def truth_col(self, name: str) -> np.ndarray:
        """One column of the plant's truth by name."""
        return self.truth[:, self.truth_names.index(name)]

    def metrics(self) -> dict:
        """tools.metrics figures: {"alpha"|"beta"|"mu": ChannelMetrics, "surfaces": {...}}.

        "surfaces" holds "peak_deg" (per surface) and "saturated_s".
        """
        from tools.sitl.metrics import channel_metrics, surface_metrics
        out = {}
        for i, (ch, y) in enumerate((("alpha", self.alpha_rad), ("beta", self.beta_rad),
                                     ("mu", self.mu_rad))):
            out[ch] = channel_metrics(self.t_s, y, self.cmd_t_s, self.cmd_rad[:, i],
                                      wrap=(ch == "mu"))
        peak, sat_s = surface_metrics(self.t_s, self.delta_rad, self.surface_limit_rad)
        out["surfaces"] = {"peak_deg": peak, "saturated_s": sat_s}
        return out

    def surface_figures(self) -> dict:
        """tools.sitl.metrics.surface_figures of this flight (docs/metrics.md): achieved and
        commanded deflections, and the law's own rate-command-limit flag."""
        from tools.sitl.metrics import surface_figures
        return surface_figures(self.t_s, self.delta_rad, self.delta_cmd_rad,
                               self.surface_limit_rad, self.omega_c_limited)


@dataclass
class LoopSetup:
    """What every in-process loop builds before its first frame (``simulate``,
    tools.sitl.closed_loop.guided.fly): the plant, the loops' frame divisors, the number of
    frames and of recorded samples, and the per-frame work arrays of the sensors and the
    estimator (``sense_frame``'s arguments)."""
    sim: PlantSim
    n_frames: int               # frames to fly (duration / frame period + 1)
    n_fast: int                 # frames per fast-loop tick
    n_slow: int                 # frames per slow-loop tick
    rec: int                    # record one sample every ``rec`` frames
    n_rec_max: int              # samples at most
    plant: tuple                # PlantSim.kernel_args(): x, p, w, n_sub, ring, ring_count,
                                #   rng_state, meas_work
    meas: np.ndarray            # float64[M_N] the measurement
    row: np.ndarray             # float64[TRUTH_N] the truth row
    est: np.ndarray             # float64[E_N] the estimated state the law sees
    cmd: np.ndarray             # float64[3] alpha, beta, mu commands, rad
    good: np.ndarray            # float64[M_N] the estimator's last good measurement
    good_t: np.ndarray          # float64[M_N] its time stamps, s
    masks: np.ndarray           # int64[2] the estimator's rejection masks

    def frame_dt_s(self, n: int) -> float:
        """The period of a loop ticking every ``n`` frames, s."""
        return n * self.sim.frame_dt_s


def loop_setup(sc: Scenario, *, seed: int | None, duration_s: float | None, fast_hz: float,
               slow_hz: float, record_every: int) -> LoopSetup:
    """The plant of ``sc`` and the arrays of a flight of ``duration_s`` (None: the
    scenario's) with the fast and slow loops at ``fast_hz`` / ``slow_hz``.

    Raises ValueError when a rate does not divide the frame rate or the duration is not > 0.
    """
    sim = PlantSim(sc, seed=seed)
    frame_hz = 1.0 / sim.frame_dt_s
    n_fast = _divisor(frame_hz, fast_hz, "fast_hz")
    n_slow = _divisor(frame_hz, slow_hz, "slow_hz")
    dur = sc.duration_s if duration_s is None else float(duration_s)
    if not dur > 0.0:
        raise ValueError(f"duration_s must be > 0, got {dur}")
    n_frames = int(round(dur / sim.frame_dt_s)) + 1
    rec = int(record_every)
    return LoopSetup(sim=sim, n_frames=n_frames, n_fast=n_fast, n_slow=n_slow, rec=rec,
                     n_rec_max=(n_frames + rec - 1) // rec, plant=sim.kernel_args(),
                     meas=np.zeros(M_N), row=np.zeros(TRUTH_N), est=np.zeros(L.E_N),
                     cmd=np.zeros(3), good=np.zeros(M_N), good_t=np.full(M_N, -np.inf),
                     masks=np.zeros(2, dtype=np.int64))


def simulate(scenario: str | Scenario, *, coordinated: bool = True,
             duration_s: float | None = None, seed: int | None = None,
             law_overrides: dict | None = None, fast_hz: float = 500.0,
             slow_hz: float = 100.0, command_shaping: str = "steps",
             record_every: int = 1, estimate: str = "truth") -> ClosedLoopResult:
    """Fly ``scenario`` with the control law in process and return the time histories.

    Parameters
    ----------
    scenario : a scenario name or path (plant_sim.scenario.load) or a loaded Scenario.
    coordinated : True = coordinated law (CO_ENABLE 1), False = uncoordinated baseline.
    duration_s : simulated time, s (None: the scenario's duration_s).
    seed : the plant's seed (sensor noise; unused by the truth-fed law); None: the scenario's.
    law_overrides : control-law parameters {name: value} in the table's units
        (fc.control.params); CO_ENABLE and REF_PF_EN are set by ``coordinated`` and
        ``command_shaping`` and must not disagree with them here.
    fast_hz, slow_hz : loop rates, Hz; each must divide the scenario's frame rate.
    command_shaping : "steps" = the paper's step commands (REF_PF_EN 0); "prefilter" = the
        2nd-order reference prefilter (REF_PF_EN 1, REF_PF_WN / REF_PF_ZETA).
    record_every : record one sample every this many frames (1 = every frame).
    estimate : "truth" = the law sees the plant's true alpha, beta, mu, p, q, r, V, h, gamma;
        "sensors" = the scenario's sensor model (noise, bias, latency) and the fc's estimator
        (fc.estimator.estimate_kernel) in the loop, as in the fc process.

    Returns
    -------
    ClosedLoopResult (time histories, the law's status, the plant's truth, metrics()).

    Raises
    ------
    ValueError for inconsistent rates, options or parameters; KeyError for an unknown
    parameter name; plant_sim.scenario.ScenarioError for a bad scenario.
    """
    sc = scenario if isinstance(scenario, Scenario) else load(scenario)
    if command_shaping not in ("steps", "prefilter"):
        raise ValueError(f"command_shaping must be 'steps' or 'prefilter', got {command_shaping!r}")
    if estimate not in ("truth", "sensors"):
        raise ValueError(f"estimate must be 'truth' or 'sensors', got {estimate!r}")
    if int(record_every) < 1:
        raise ValueError("record_every must be >= 1")
    overrides = dict(law_overrides or {})
    forced = {"CO_ENABLE": 1.0 if coordinated else 0.0,
              "REF_PF_EN": 1.0 if command_shaping == "prefilter" else 0.0}
    for k, v in forced.items():
        if k in overrides and float(overrides[k]) != v:
            raise ValueError(f"law_overrides[{k!r}] = {overrides[k]} disagrees with "
                             f"coordinated={coordinated} / command_shaping={command_shaping!r}")
        overrides[k] = v
    law = AttitudeLaw(overrides)
    su = loop_setup(sc, seed=seed, duration_s=duration_s, fast_hz=fast_hz, slow_hz=slow_hz,
                    record_every=record_every)
    n_frames = su.n_frames
    cmd_t, cmd_v = command_arrays(sc.commands)
    out_truth = np.zeros((su.n_rec_max, TRUTH_N))
    out_status = np.zeros((su.n_rec_max, L.S_N))
    x, p, w, n_sub, ring, ring_count, rng_state, meas_work = su.plant
    k = law.kernel_args()
    args = (su.n_fast, su.n_slow, su.frame_dt_s(su.n_fast), su.frame_dt_s(su.n_slow), su.rec,
            cmd_t, cmd_v, x, p, w, n_sub, su.meas, su.row, su.est, su.cmd,
            k["par"], k["x"], k["nm"], k["st"], k["tab"], k["atm"], k["grid"],
            k["delta"], out_truth, out_status,
            estimate == "sensors", ring, ring_count, rng_state, meas_work, su.good, su.good_t,
            LIMITS_LO, LIMITS_HI, 0.1, su.masks)
    _run(0, *args)          # zero frames: loads (or compiles) the machine code, not timed
    t0 = time.perf_counter()
    _frames, n_rec = _run(n_frames, *args)
    wall = time.perf_counter() - t0
    tr = out_truth[:n_rec]
    stt = out_status[:n_rec]
    t = tr[:, 0]
    ci = np.searchsorted(cmd_t, t + 1e-9, side="right") - 1
    cz = cmd_v[np.clip(ci, 0, len(cmd_t) - 1)]
    col = TRUTH_NAMES.index
    return ClosedLoopResult(
        t_s=t, alpha_rad=tr[:, col("alpha_rad")], beta_rad=tr[:, col("beta_rad")],
        mu_rad=tr[:, col("mu_rad")],
        alpha_cmd_rad=cz[:, 0], beta_cmd_rad=cz[:, 1], mu_cmd_rad=cz[:, 2],
        alpha_ref_rad=stt[:, L.S_OMEGA_REF], beta_ref_rad=stt[:, L.S_OMEGA_REF + 1],
        mu_ref_rad=stt[:, L.S_OMEGA_REF + 2],
        p_rad_s=tr[:, col("p_rad_s")], q_rad_s=tr[:, col("q_rad_s")],
        r_rad_s=tr[:, col("r_rad_s")], V_m_s=tr[:, col("V_m_s")], h_m=tr[:, col("h_m")],
        delta_cmd_rad=stt[:, L.S_DELTA_CMD:L.S_DELTA_CMD + 3],
        delta_rad=tr[:, _T_DELTA:_T_DELTA + 3],
        sat=stt[:, L.S_SAT:L.S_SAT + 3], sat_any=stt[:, L.S_SAT_ANY],
        omega_c_limited=stt[:, L.S_OMC_LIM], status=stt, truth=tr,
        diverged=bool(_frames < n_frames), cmd_t_s=cmd_t, cmd_rad=cmd_v,
        params=law.params(), scenario=sc.name, coordinated=bool(coordinated),
        command_shaping=command_shaping, estimate=estimate,
        surface_limit_rad=float(p[dy.P_ACT_LIMIT]), wall_s=wall)


def _divisor(frame_hz: float, hz: float, what: str) -> int:
    if not hz > 0:
        raise ValueError(f"{what} must be > 0, got {hz}")
    n = frame_hz / hz
    if abs(n - round(n)) > 1e-9 or round(n) < 1:
        raise ValueError(f"{what} = {hz} Hz must divide the scenario's frame rate {frame_hz} Hz")
    return int(round(n))
