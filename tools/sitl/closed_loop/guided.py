"""In-process guided flight: guidance (fc.guidance) + the paper's law (fc.control) + the plant.

The outer loop of docs/guidance.md flies the plant through the attitude law, in one numba
loop like tools.sitl.closed_loop (whose set-up it reuses): per frame the plant's sensors (or
truth), the guidance when due (default 50 Hz), the law's slow and fast loops when due, the
throttle and surface commands into the plant, one plant frame. Targets come from the
scenario's ``[[target]]`` timeline (cruise, mission) or from the caller.

    from tools.sitl.closed_loop.guided import fly
    res = fly("cruise", duration_s=600)
    res.hold_figures(t_from_s=300)      # altitude / course / speed / inner-loop errors

    python -m tools.fly guided cruise --duration 3600       # the 1-hour hold figures
    python -m tools.fly guided steps                          # +2 km, +30 deg, +100 m/s
    python -m tools.fly guided mission                        # the mission scenario, per leg
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numba import njit

from fc.control import layout as L
from fc.control.law import AttitudeLaw
from fc.estimator import LIMITS_HI, LIMITS_LO
from fc.guidance import layout as G
from fc.guidance.guidance import Guidance, limit_names
from fc.guidance.kernels import course_from_air_data, guidance_reset, guidance_step
from hyfc_wire.earth import EARTH_RADIUS_M
from plant_sim import dynamics as dy
from plant_sim.scenario import Scenario, load
from plant_sim.sensors import M_AIRSPEED, M_AOA, M_CLIMB, M_PITCH, M_ROLL, M_SSA, M_YAW
from plant_sim.sim import TRUTH_N, TRUTH_NAMES
from tools.sitl.closed_loop.core import _divisor, diverged_row, law_frame, loop_setup, sense_frame

from hyfc_wire.numba_cache import drop_stale
from hyfc_wire.timeline import target_arrays

_ROOT = Path(__file__).resolve().parents[3]
drop_stale(__file__, [str(f) for pkg in ("fc/control", "fc/guidance", "plant_sim", "hyfc_wire")
                      for f in (_ROOT / pkg).glob("*.py")]
           + [str(_ROOT / "fc" / "estimator.py"), str(_ROOT / "fc" / "link.py"),
              str(_ROOT / "tools" / "sitl" / "closed_loop" / "core.py")])

DEG = math.pi / 180.0
_T_CHI = TRUTH_NAMES.index("chi_rad")
_T_ALPHA = TRUTH_NAMES.index("alpha_rad")


@njit(cache=True)
def _run_guided(n_frames, n_fast, n_slow, n_guid, dt_fast, dt_slow, dt_guid, rec_every,
                tg_t, tg_v, px, pp, pw, n_sub, meas, row, est, cmd,
                par, lx, nm, st, tab, atm, grid, delta,
                gp, mass_kg, xcg_m, gx, gout, gst, gw, tgt,
                out_truth, out_status, out_gst, out_cmd,
                use_sensors, ring, ring_count, rng_state, meas_work, good, good_t, lo, hi,
                stale_s, masks, gest):
    """The guided closed loop over ``n_frames`` frames; returns (frames flown, samples).

    Per frame: [sensors.measure], truth row, estimated state (truth, or the fc's estimator),
    course (truth chi, or with sensors the course of the air-relative velocity from the measured
    attitude, alpha and beta: fc.guidance.kernels.course_from_air_data; and the flight-path
    angle from the climb rate, asin(climb / airspeed), 10x less noisy than the estimator's
    theta - alpha), target of the timeline,
    guidance when due, slow loop when due, fast loop when due, record, throttle and surface
    commands into the plant, one plant frame. Stops early if |alpha|, |beta| or |mu| exceed
    45 deg (or NaN).
    """
    k_tg = 0
    n_tg = tg_t.shape[0]
    n_rec = 0
    frame_dt = pp[dy.P_FRAME_DT]
    t0 = px[dy.X_STEP] * pp[dy.P_DT]
    for k in range(n_frames):
        sense_frame(use_sensors, px, pp, pw, meas, row, est, ring, ring_count, rng_state,
                    meas_work, good, good_t, lo, hi, stale_s, masks)
        if use_sensors:
            chi = course_from_air_data(meas[M_ROLL], meas[M_PITCH], meas[M_YAW], meas[M_AOA],
                                       meas[M_SSA])
        else:
            chi = row[_T_CHI]
        t = t0 + k * frame_dt
        while k_tg + 1 < n_tg and tg_t[k_tg + 1] <= t + 1e-9:
            k_tg += 1
        for i in range(tgt.shape[0]):
            tgt[i] = tg_v[k_tg, i]
        if use_sensors:     # the guidance's flight-path angle: from the climb rate
            for i in range(L.E_N):
                gest[i] = est[i]
            gest[L.E_GAMMA] = math.asin(min(max(meas[M_CLIMB] / max(meas[M_AIRSPEED], 1.0),
                                                -1.0), 1.0))
        else:
            for i in range(L.E_N):
                gest[i] = est[i]
        if k == 0:
            guidance_reset(gest, gp, mass_kg, xcg_m, gx, px[dy.X_THR], gw, tab, atm, grid)
        if k % n_guid == 0:
            guidance_step(gest, chi, tgt, dt_guid, gp, mass_kg, xcg_m, gx, gout, gst, gw,
                          tab, atm, grid)
            cmd[0] = gout[0]
            cmd[1] = gout[1]
            cmd[2] = gout[2]
        law_frame(k, n_slow, n_fast, dt_slow, dt_fast, est, cmd,
                  par, lx, nm, st, tab, atm, grid, delta)
        if k % rec_every == 0:
            for i in range(row.shape[0]):
                out_truth[n_rec, i] = row[i]
            for i in range(st.shape[0]):
                out_status[n_rec, i] = st[i]
            for i in range(gst.shape[0]):
                out_gst[n_rec, i] = gst[i]
            for i in range(4):
                out_cmd[n_rec, i] = gout[i]
            out_cmd[n_rec, 4] = px[dy.X_THR]
            n_rec += 1
        if diverged_row(row):
            return k + 1, n_rec
        px[dy.X_CMD_THR] = gout[3]
        dy.advance_frame(px, delta, pp, pw, n_sub)
    return n_frames, n_rec


@dataclass
class GuidedResult:
    """Time histories of one guided flight (SI; one row per recorded frame).

    t_s : (n,) s. truth : (n, TRUTH_N) plant truth (names ``truth_names``). status : (n, S_N)
    the law's status. gstatus : (n, GS_N) the guidance status (names ``gstatus_names``;
    column ``limits`` is the limit bitfield). cmd : (n, 5) alpha_c, beta_c, mu_c (rad),
    throttle command, throttle position (0..1). targets_t_s (k,), targets (k, TG_N): the
    target timeline (rad for the course). diverged, wall_s, scenario, estimate, params.
    """
    t_s: np.ndarray
    truth: np.ndarray
    status: np.ndarray
    gstatus: np.ndarray
    cmd: np.ndarray
    targets_t_s: np.ndarray
    targets: np.ndarray
    diverged: bool
    wall_s: float
    scenario: str
    estimate: str
    coordinated: bool
    params: dict
    guidance_params: dict
    surface_limit_rad: float
    sphere: bool = False              # the scenario's [earth] model is "sphere"
    truth_names: tuple = field(default=TRUTH_NAMES)
    status_names: tuple = field(default=L.STATUS_NAMES)
    gstatus_names: tuple = field(default=G.GUIDANCE_STATUS_NAMES)

    def col(self, name: str) -> np.ndarray:
        """A truth column, else a guidance-status column, else a law-status column, by name."""
        for names, arr in ((self.truth_names, self.truth), (self.gstatus_names, self.gstatus),
                           (self.status_names, self.status)):
            if name in names:
                return arr[:, names.index(name)]
        raise KeyError(name)

    def target_at(self, t_s: np.ndarray) -> np.ndarray:
        """(n, TG_N) targets in force at the times ``t_s``."""
        i = np.searchsorted(self.targets_t_s, t_s + 1e-9, side="right") - 1
        return self.targets[np.clip(i, 0, len(self.targets_t_s) - 1)]

    def load_factor(self) -> np.ndarray:
        """(n,) load factor n = L / (m g) = (V gamma_dot + g_r cos gamma) / (g cos mu), from
        the truth (g 9.7 m/s^2 at cruise altitude; gamma_dot by central differences; g_r = g on
        the flat earth, g - V^2 / (R + h) on the sphere: its centrifugal relief, 0.08 g at
        Mach 7.5)."""
        gam = self.col("gamma_rad")
        gd = np.gradient(gam, self.t_s) if len(gam) > 2 else np.zeros_like(gam)
        g = 9.72
        V = self.col("V_m_s")
        g_r = g - V * V / (EARTH_RADIUS_M + self.col("h_m")) if self.sphere else g
        return (V * gd + g_r * np.cos(gam)) / (g * np.cos(self.col("mu_rad")))

    def hold_figures(self, t_from_s: float = 0.0) -> dict:
        """Hold accuracy after ``t_from_s``: max abs errors to the targets (altitude m, course
        deg, speed m/s), the inner loop's max abs error of alpha/beta/mu to the guidance's
        command (deg) and to the law's filtered reference (e1, deg), time with a surface at
        its limit (s), the range of the adaptive estimates and disturbance estimate, the
        throttle range, the guidance's integrators (altitude m s, speed m, flight path rad s:
        max abs value in the first and second half of the window) and the limits that were in
        force (names)."""
        sel = self.t_s >= t_from_s
        tg = self.target_at(self.t_s[sel])
        h_err = self.col("h_m")[sel] - tg[:, G.TG_H]
        chi_err = np.angle(np.exp(1j * (self.col("chi_rad")[sel] - tg[:, G.TG_CHI])))
        v_err = self.col("V_m_s")[sel] - tg[:, G.TG_V]
        att = self.truth[sel][:, _T_ALPHA:_T_ALPHA + 3]
        cmd_err = att - self.cmd[sel, 0:3]
        cmd_err[:, 2] = np.angle(np.exp(1j * cmd_err[:, 2]))
        e1 = self.status[sel][:, L.S_E1:L.S_E1 + 3]
        delta = self.truth[sel][:, TRUTH_NAMES.index("delta_left_rad"):
                                TRUTH_NAMES.index("delta_left_rad") + 3]
        dt = np.median(np.diff(self.t_s)) if len(self.t_s) > 1 else 0.0
        at_lim = np.any(np.abs(delta) >= self.surface_limit_rad - 0.05 * DEG, axis=1)
        rho = np.concatenate([self.status[sel][:, L.S_RHO_S:L.S_RHO_S + 4],
                              self.status[sel][:, L.S_RHO_F:L.S_RHO_F + 17]], axis=1)
        bits = np.bitwise_or.reduce(self.gstatus[sel, G.GS_LIMITS].astype(np.int64)) \
            if sel.any() else 0
        half = len(rho) // 2
        gi = self.gstatus[sel][:, [G.GS_H_INT, G.GS_V_INT, G.GS_G_INT]]
        return {
            "t_from_s": t_from_s, "t_to_s": float(self.t_s[-1]),
            "alt_err_max_m": float(np.max(np.abs(h_err))),
            "alt_err_rms_m": float(np.sqrt(np.mean(h_err ** 2))),
            "course_err_max_deg": float(np.degrees(np.max(np.abs(chi_err)))),
            "speed_err_max_m_s": float(np.max(np.abs(v_err))),
            "inner_cmd_err_max_deg": [float(v) for v in np.degrees(np.max(np.abs(cmd_err), 0))],
            "inner_e1_max_deg": [float(v) for v in np.degrees(np.max(np.abs(e1), 0))],
            "surface_at_limit_s": float(np.sum(at_lim) * dt),
            "surface_peak_deg": [float(v) for v in np.degrees(np.max(np.abs(delta), 0))],
            "rho_abs_max": float(np.max(np.abs(rho))),
            "rho_abs_max_first_half": float(np.max(np.abs(rho[:half]))) if half else 0.0,
            "rho_abs_max_second_half": float(np.max(np.abs(rho[half:]))) if half else 0.0,
            "d_hat_abs_max_rad_s2": float(np.max(np.abs(self.status[sel][:, L.S_D_HAT:L.S_D_HAT + 3]))),
            "throttle_range": [float(np.min(self.cmd[sel, 4])), float(np.max(self.cmd[sel, 4]))],
            "guidance_integrals_abs_max_halves": [
                [float(v) for v in np.max(np.abs(part), axis=0)] if len(part) else []
                for part in (gi[:half], gi[half:])],
            "limits_seen": limit_names(int(bits)),
        }

    def step_figures(self, t_step_s: float, channel: str, band: float,
                     t_end_s: float | None = None) -> dict:
        """Response to a target step at ``t_step_s`` on ``channel`` ("alt" m, "course" rad
        band in deg, "speed" m/s): settling time (the last entry into +-band of the new target,
        s after the step), overshoot beyond the target (m, deg or m/s), and the peaks of the
        envelope quantities (alpha, |mu| deg, load factor, |gamma| deg, qbar min/max Pa) with
        the limits that were in force during the response."""
        sel = (self.t_s >= t_step_s) & ((self.t_s <= t_end_s) if t_end_s is not None else True)
        t = self.t_s[sel]
        tg = self.target_at(t)
        h0 = self.target_at(np.array([t_step_s - 1e-3]))[0]
        if channel == "alt":
            y, r, r0, unit = self.col("h_m")[sel], tg[:, G.TG_H], h0[G.TG_H], 1.0
        elif channel == "speed":
            y, r, r0, unit = self.col("V_m_s")[sel], tg[:, G.TG_V], h0[G.TG_V], 1.0
        elif channel == "course":
            y = np.unwrap(self.col("chi_rad")[sel])
            r, r0, unit = tg[:, G.TG_CHI], h0[G.TG_CHI], 1.0 / DEG
        else:
            raise ValueError(f"unknown channel {channel!r}")
        err = (y - r) * unit
        out_band = np.nonzero(np.abs(err) > band)[0]
        settled = None
        if len(out_band) == 0:
            settled = 0.0
        elif out_band[-1] + 1 < len(t):
            settled = float(t[out_band[-1] + 1] - t_step_s)
        direction = np.sign(r[-1] - r0) if r[-1] != r0 else 1.0
        over = float(max(0.0, np.max(direction * err)))
        nz = self.load_factor()[sel]
        bits = np.bitwise_or.reduce(self.gstatus[sel, G.GS_LIMITS].astype(np.int64))
        return {
            "channel": channel, "t_step_s": t_step_s, "settling_s": settled,
            "overshoot": over, "final_err": float(err[-1]),
            "alpha_max_deg": float(np.degrees(np.max(self.col("alpha_rad")[sel]))),
            "alpha_min_deg": float(np.degrees(np.min(self.col("alpha_rad")[sel]))),
            "mu_abs_max_deg": float(np.degrees(np.max(np.abs(self.col("mu_rad")[sel])))),
            "gamma_abs_max_deg": float(np.degrees(np.max(np.abs(self.col("gamma_rad")[sel])))),
            "nz_max": float(np.max(nz[2:-2])) if len(nz) > 4 else float("nan"),
            "nz_min": float(np.min(nz[2:-2])) if len(nz) > 4 else float("nan"),
            "qbar_min_pa": float(np.min(self.col("qbar_pa")[sel])),
            "qbar_max_pa": float(np.max(self.col("qbar_pa")[sel])),
            "throttle_max": float(np.max(self.cmd[sel, 4])),
            "surface_peak_deg": float(np.degrees(np.max(np.abs(
                self.truth[sel][:, TRUTH_NAMES.index("delta_left_rad"):
                                TRUTH_NAMES.index("delta_left_rad") + 3])))),
            "limits_seen": limit_names(int(bits)),
        }


def target_timeline(scenario: Scenario) -> tuple[np.ndarray, np.ndarray]:
    """The scenario's [[target]] timeline as (times (k,) s, targets (k, TG_N) SI)."""
    t_s, alt_course_speed = target_arrays(scenario.targets, scenario.name)
    tg = np.zeros((len(t_s), G.TG_N))
    tg[:, G.TG_H] = alt_course_speed[:, 0]
    tg[:, G.TG_CHI] = alt_course_speed[:, 1]
    tg[:, G.TG_V] = alt_course_speed[:, 2]
    return t_s, tg


def fly(scenario: str | Scenario, *, duration_s: float | None = None, seed: int | None = None,
        targets: tuple[np.ndarray, np.ndarray] | None = None, coordinated: bool = True,
        law_overrides: dict | None = None, guidance_overrides: dict | None = None,
        fast_hz: float = 500.0, slow_hz: float = 100.0, guidance_hz: float = 50.0,
        record_every: int = 50, estimate: str = "sensors") -> GuidedResult:
    """Fly ``scenario`` under guidance, in process, and return the time histories.

    Parameters
    ----------
    scenario : name, path or loaded Scenario (needs [[target]] unless ``targets`` is given).
    duration_s : sim time, s (None: the scenario's). seed : sensor-noise seed (None: scenario's).
    targets : (times (k,) s, targets (k, TG_N)) overriding the scenario's [[target]] table.
    coordinated : the law's CO_ENABLE. law_overrides / guidance_overrides : parameters in
        table units (the law's prefilter REF_PF_EN stays on unless overridden, as in the fc).
    fast_hz, slow_hz, guidance_hz : loop rates, each dividing the scenario's frame rate.
    record_every : one sample every this many frames (default 50: 10 Hz at 500 Hz frames).
    estimate : "sensors" (the scenario's sensor model and the fc's estimator; course from the
        measured attitude, alpha and beta) or "truth" (the plant's state; course chi).
    """
    sc = scenario if isinstance(scenario, Scenario) else load(scenario)
    if estimate not in ("truth", "sensors"):
        raise ValueError(f"estimate must be 'truth' or 'sensors', got {estimate!r}")
    if int(record_every) < 1:
        raise ValueError("record_every must be >= 1")
    ov = dict(law_overrides or {})
    ov.setdefault("CO_ENABLE", 1.0 if coordinated else 0.0)
    law = AttitudeLaw(ov)
    gd = Guidance(guidance_overrides)
    lp = law.params()
    gd.set_model(lp["MDL_MASS"], lp["MDL_XCG"])
    su = loop_setup(sc, seed=seed, duration_s=duration_s, fast_hz=fast_hz, slow_hz=slow_hz,
                    record_every=record_every)
    n_guid = _divisor(1.0 / su.sim.frame_dt_s, guidance_hz, "guidance_hz")
    tg_t, tg_v = targets if targets is not None else target_timeline(sc)
    tg_t = np.ascontiguousarray(tg_t, dtype=np.float64)
    tg_v = np.ascontiguousarray(tg_v, dtype=np.float64)
    if tg_v.ndim != 2 or tg_v.shape[1] != G.TG_N or tg_v.shape[0] != tg_t.shape[0]:
        raise ValueError("targets must be (times (k,), values (k, TG_N))")
    n_frames, n_rec_max = su.n_frames, su.n_rec_max
    out_truth = np.zeros((n_rec_max, TRUTH_N))
    out_status = np.zeros((n_rec_max, L.S_N))
    out_gst = np.zeros((n_rec_max, G.GS_N))
    out_cmd = np.zeros((n_rec_max, 5))
    x, p, w, n_sub, ring, ring_count, rng_state, meas_work = su.plant
    k = law.kernel_args()
    gk = gd.kernel_args()
    args = (su.n_fast, su.n_slow, n_guid, su.frame_dt_s(su.n_fast), su.frame_dt_s(su.n_slow),
            su.frame_dt_s(n_guid), su.rec, tg_t, tg_v,
            x, p, w, n_sub, su.meas, su.row, su.est, su.cmd,
            k["par"], k["x"], k["nm"], k["st"], k["tab"], k["atm"], k["grid"], k["delta"],
            gk["par"], gk["mass_kg"], gk["xcg_m"], gk["gx"], gk["out"], gk["st"], gk["gw"],
            gk["tgt"], out_truth, out_status, out_gst, out_cmd,
            estimate == "sensors", ring, ring_count, rng_state, meas_work, su.good, su.good_t,
            LIMITS_LO, LIMITS_HI, 0.1, su.masks, np.zeros(L.E_N))
    _run_guided(0, *args)      # zero frames: load or compile the machine code, not timed
    t0 = time.perf_counter()
    frames, n_rec = _run_guided(n_frames, *args)
    wall = time.perf_counter() - t0
    return GuidedResult(
        t_s=out_truth[:n_rec, 0].copy(), truth=out_truth[:n_rec], status=out_status[:n_rec],
        gstatus=out_gst[:n_rec], cmd=out_cmd[:n_rec], targets_t_s=tg_t, targets=tg_v,
        diverged=bool(frames < n_frames), wall_s=wall, scenario=sc.name, estimate=estimate,
        coordinated=bool(ov["CO_ENABLE"]), params=lp, guidance_params=gd.params(),
        surface_limit_rad=float(p[dy.P_ACT_LIMIT]),
        sphere=sc.data["earth"]["model"] == "sphere")


def hold_then_step(h_m: float, chi_rad: float, V_m_s: float, t_step_s: float,
                   d_h_m: float = 0.0, d_chi_rad: float = 0.0, d_V_m_s: float = 0.0):
    """A two-row target timeline: hold (h, chi, V), then the step at ``t_step_s``."""
    t = np.array([0.0, t_step_s])
    v = np.zeros((2, G.TG_N))
    v[0, :3] = (h_m, chi_rad, V_m_s)
    v[1, :3] = (h_m + d_h_m, chi_rad + d_chi_rad, V_m_s + d_V_m_s)
    return t, v


STEPS = (("alt", {"d_h_m": 2000.0}, 50.0, "+2 km altitude"),
         ("course", {"d_chi_rad": 30.0 * DEG}, 0.5, "+30 deg course"),
         ("speed", {"d_V_m_s": 100.0}, 5.0, "+100 m/s speed"))


def step_responses(scenario: str = "cruise", t_step_s: float = 100.0, after_s: float = 500.0,
                   estimate: str = "sensors", **kw) -> list[dict]:
    """The three guided steps from the scenario's hold point, one flight each: figures of
    ``GuidedResult.step_figures`` plus the hold figures of the other two channels."""
    sc = load(scenario)
    h0, chi0_deg, v0 = sc.targets[0][1:4]
    out = []
    for ch, step, band, label in STEPS:
        tl = hold_then_step(h0, chi0_deg * DEG, v0, t_step_s, **step)
        res = fly(sc, duration_s=t_step_s + after_s, targets=tl, estimate=estimate, **kw)
        f = res.step_figures(t_step_s, ch, band)
        f["label"] = label
        f["band"] = band
        f["diverged"] = res.diverged
        hold = res.hold_figures(t_step_s)
        f["alt_dev_max_m"] = hold["alt_err_max_m"]
        f["course_dev_max_deg"] = hold["course_err_max_deg"]
        f["speed_dev_max_m_s"] = hold["speed_err_max_m_s"]
        f["surface_at_limit_s"] = hold["surface_at_limit_s"]
        out.append(f)
    return out


def plot_flight(res: GuidedResult, path, title: str = "") -> Path:
    """One PNG of a guided flight: altitude, course, speed and throttle against their targets
    (left), alpha, beta, mu against the guidance's commands and the surfaces (right)."""
    from tools.sitl.plots import CMD_STYLE, R2D, SURFACE_LABELS, _finish_axis, _save, _stairs, plt
    t = res.t_s
    fig, ax = plt.subplots(4, 2, figsize=(13, 10), sharex=True)
    line = dict(color="tab:blue", linewidth=1.3)
    tt, tv = res.targets_t_s, res.targets
    rows = ((ax[0, 0], res.col("h_m") / 1000.0, tv[:, G.TG_H] / 1000.0, "altitude [km]"),
            (ax[1, 0], np.degrees(np.unwrap(res.col("chi_rad"))), np.degrees(tv[:, G.TG_CHI]),
             "course [deg]"),
            (ax[2, 0], res.col("V_m_s"), tv[:, G.TG_V], "speed [m/s]"))
    for a, y, tgt, lab in rows:
        a.plot(t, y, label="flown", **line)
        a.plot(*_stairs(tt, tgt, t[-1]), label="target", **CMD_STYLE)
        _finish_axis(a, lab)
    ax[2, 0].plot(t, res.col("V_ref_m_s"), color="tab:green", linewidth=0.9, label="V_ref")
    ax[2, 0].legend(loc="best", fontsize=8)
    ax[3, 0].plot(t, res.cmd[:, 3], label="command", **CMD_STYLE)
    ax[3, 0].plot(t, res.cmd[:, 4], label="engine", **line)
    _finish_axis(ax[3, 0], "throttle [0..1]")
    for i, (name, lab) in enumerate((("alpha_rad", "alpha [deg]"), ("beta_rad", "beta [deg]"),
                                     ("mu_rad", "mu [deg]"))):
        a = ax[i, 1]
        a.plot(t, res.col(name) * R2D, label="flown", **line)
        a.plot(t, res.cmd[:, i] * R2D, label="guidance command", **CMD_STYLE)
        _finish_axis(a, lab)
    d0 = TRUTH_NAMES.index("delta_left_rad")
    for k, lab in enumerate(SURFACE_LABELS):
        ax[3, 1].plot(t, res.truth[:, d0 + k] * R2D, linewidth=1.0, label=lab)
    for sgn in (1, -1):
        ax[3, 1].axhline(sgn * res.surface_limit_rad * R2D, color="grey", linestyle="--",
                         linewidth=0.8)
    _finish_axis(ax[3, 1], "surfaces [deg]")
    for a in ax[3]:
        a.set_xlabel("time [s]")
    fig.suptitle(title or f"guided flight: scenario '{res.scenario}', {res.estimate}, "
                 f"{'coordinated' if res.coordinated else 'uncoordinated'} law", fontsize=11)
    fig.tight_layout()
    return _save(fig, Path(path))


def format_figures(d: dict) -> str:
    """A figures dict as one line ``key=value ...`` (floats to 4 significant digits, lists of
    floats joined with '/')."""
    parts = []
    for k, v in d.items():
        if isinstance(v, float):
            parts.append(f"{k}={v:.4g}")
        elif isinstance(v, list) and v and isinstance(v[0], float):
            parts.append(f"{k}=" + "/".join(f"{x:.4g}" for x in v))
        else:
            parts.append(f"{k}={v}")
    return " ".join(parts)


def mission_legs(res: GuidedResult) -> list[str]:
    """One line per leg of a flight's target timeline (a mission): the targets, where the leg
    ended (altitude m, course deg, speed m/s), its peak alpha, |mu| and load factor, and the
    guidance limits that were in force."""
    tt = list(res.targets_t_s) + [res.t_s[-1]]
    nz = res.load_factor()
    out = []
    for i in range(len(tt) - 1):
        sel = (res.t_s >= tt[i]) & (res.t_s < tt[i + 1])
        bits = int(np.bitwise_or.reduce(res.gstatus[sel, G.GS_LIMITS].astype(np.int64)))
        out.append(f"leg {i} t {tt[i]:.0f}-{tt[i + 1]:.0f} s: target h {res.targets[i, 0]:.0f} m "
                   f"chi {math.degrees(res.targets[i, 1]):.0f} deg V {res.targets[i, 2]:.0f} m/s; "
                   f"end h {res.col('h_m')[sel][-1]:.0f} chi "
                   f"{math.degrees(res.col('chi_rad')[sel][-1]):.2f} V {res.col('V_m_s')[sel][-1]:.1f}; "
                   f"peak alpha {math.degrees(res.col('alpha_rad')[sel].max()):.2f} deg, |mu| "
                   f"{math.degrees(np.abs(res.col('mu_rad')[sel]).max()):.2f} deg, n "
                   f"{nz[sel][2:-2].max():.3f}; limits {limit_names(bits)}")
    return out

