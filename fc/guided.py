"""fc/guided.py - the guidance (outer loop, fc/guidance) inside the fc process.

The glue between the pure guidance and the fc: its parameters from the fc's table, its
inputs from the estimator and the sensor frame, its fixed rate (:data:`GUIDANCE_HZ`, every
``div`` fast ticks), engagement (bumpless: reset from the current state, targets = the current
altitude, course and speed) and the validation of targets a ground station or a mission sets.
No sockets, clocks or logging here either: fc/app.py calls it from the fast tick.

Inputs (docs/guidance.md section 2, "In the fc"):

- the law's estimate ``est`` (fc/estimator.py: alpha, beta, mu, p, q, r, V, h, gamma) with
  gamma replaced by asin(climb / airspeed) from the frame (10x less noisy than the estimator's
  theta - alpha, as tools/sitl/closed_loop/guided.py);
- the course chi of the air-relative velocity from the frame's roll, pitch, yaw and the
  estimate's alpha, beta (``course_from_air_data``). Not the GNSS course: the plant has no
  wind, so the two agree, and the air-data course comes with every frame, without the GNSS
  sample's rate and delay; with wind the GNSS course would be the one to steer (not done).
"""
from __future__ import annotations

import math

import numpy as np

from fc.control.carrays import address_of
from fc.control.layout import ATM_N, ATM_RHO, E_GAMMA, E_H, E_N, E_V
from fc.frame_calls import count_p
from fc.control.nominal import interp_atmosphere
from fc.guidance import layout as G
from fc.guidance.guidance import Guidance
from fc.guidance.kernels import course_from_air_data
from fc.guidance.params import GUIDANCE_PARAMS
from fc.link import M_AIRSPEED, M_CLIMB, M_PITCH, M_ROLL, M_YAW, throttle_to_pwm

__all__ = ["GUIDANCE_HZ", "GUIDANCE_NAMES", "GuidanceRunner"]

#: The guidance's rate (Hz): it steps every round(fast_hz / GUIDANCE_HZ) fast ticks.
GUIDANCE_HZ = 50.0
GUIDANCE_NAMES = frozenset(p.name for p in GUIDANCE_PARAMS)


class GuidanceRunner:
    """The fc's guidance: a :class:`Guidance` stepped at its own rate from the fast tick.

    ``cmd_rad`` (alpha_c, beta_c, mu_c, rad) is a view of the guidance's output: the law's
    command in the guidance modes. ``engaged`` is False until :meth:`engage`.
    """

    def __init__(self, params, fast_hz: float) -> None:
        self.g = Guidance({n: params.get(n) for n in GUIDANCE_NAMES})
        if "MDL_MASS" in params and "MDL_XCG" in params:
            self.g.set_model(params.get("MDL_MASS"), params.get("MDL_XCG"))
        self.params = params
        self.div = max(1, int(round(fast_hz / GUIDANCE_HZ)))
        self.dt_s = self.div / fast_hz
        # fast ticks since the last guidance step, mod div: an int64 cell (``count``), so the
        # fused lockstep frame (fc/fused.py) steps it on the ticks where the guidance is not due
        self._count = np.zeros(1, np.int64)
        self.count_addr = address_of(self._count, np.int64, 1)
        # guidance steps since start (tests, telemetry): an int64 counted by a compiled call
        # (an int past 256 per step otherwise)
        self._steps = np.zeros(1, np.int64)
        self._steps_p = address_of(self._steps, np.int64, 1)
        self.engaged = False
        self.mode = -1                  # the guidance mode it was last engaged or re-targeted in
        self.mode_before_off = -1       # the mode it flew when last disengaged (resume)
        self.gest = np.zeros(E_N)
        self.chi_rad = 0.0
        self.cmd_rad = self.g.out[0:3]  # a view: the kernel writes ``out`` in place
        # the throttle command out[GO_THR] for the fast tick without a Python object per read:
        # its address (the compiled output, fc/frame_calls.py) and ``out`` as a memoryview
        # (a read gives a float, not a numpy scalar)
        self.throttle_addr = (address_of(self.g.out, np.float64, G.GO_N)
                              + G.GO_THR * self.g.out.itemsize)
        self._out_mv = memoryview(self.g.out)
        #: the limit bitfield of the last step (LIM_*), as a float: an int past 256 was a new
        #: Python object per step (issue 24)
        self.limits = 0.0
        self._atm = np.zeros(ATM_N)
        #: (bearing to the waypoint rad, distance m, cross-track error m, + right of the leg)
        #: for NAV_CONTROLLER_OUTPUT, set by a mission (fc/mission_mode.py)
        self.nav_wp: tuple[float, float, float] | None = None

    # ------------------------------------------------------------------ parameters
    def set_param(self, name: str, value: float) -> None:
        if name in GUIDANCE_NAMES:
            self.g.set_param(name, value)
        elif name in ("MDL_MASS", "MDL_XCG"):
            self.g.set_model(self.params.get("MDL_MASS"), self.params.get("MDL_XCG"))

    def warm_up(self) -> None:
        """One throw-away reset and step so the kernels are loaded before the first tick."""
        spare = Guidance(self.g.params())
        est = np.zeros(E_N)
        est[0], est[E_V], est[E_H] = 0.065, 2250.0, 28000.0
        spare.reset(est)
        spare.set_targets(h_m=28000.0, chi_rad=0.0, V_m_s=2250.0)
        spare.step_f(est, 0.0, self.dt_s)           # (the tick's entry)
        course_from_air_data(0.0, 0.05, 0.0, 0.05, 0.0)
        spare_count = np.zeros(1, np.int64)
        count_p(address_of(spare_count, np.int64, 1))

    # ------------------------------------------------------------------ inputs
    def _inputs(self, est: np.ndarray, meas: np.ndarray) -> None:
        """``gest`` (the estimate, gamma from the climb rate) and ``chi_rad`` from a frame;
        a value that is not finite keeps the last good one."""
        # Python floats (``item``), no numpy scalars, and no min/max (their argument
        # iterator): the same operations on the same doubles, no object per step
        np.copyto(self.gest, est)
        v = meas.item(M_AIRSPEED)
        s = meas.item(M_CLIMB) / (1.0 if 1.0 > v else v)           # / max(v, 1.0)
        if math.isfinite(s):
            s = -1.0 if -1.0 > s else s                              # max(s, -1.0)
            self.gest[E_GAMMA] = math.asin(1.0 if 1.0 < s else s)    # min(., 1.0)
        chi = course_from_air_data(meas.item(M_ROLL), meas.item(M_PITCH), meas.item(M_YAW),
                                   est.item(0), est.item(1))
        if math.isfinite(chi):
            self.chi_rad = chi

    # ------------------------------------------------------------------ engagement
    def engage(self, est: np.ndarray, meas: np.ndarray, mode: int) -> None:
        """Start from the current state (bumpless) holding the current altitude, course and
        speed. The throttle starts at the first step's own (feed-forward) value."""
        self._inputs(est, meas)
        self.g.reset(self.gest, -1.0)
        self.hold_current(est, meas, mode)
        self.count = 0
        self.engaged = True

    def hold_current(self, est: np.ndarray, meas: np.ndarray, mode: int) -> None:
        """Targets := the current altitude, course and speed (entry into CRUISE or GUIDED);
        the guidance's own state runs on (no reset)."""
        self._inputs(est, meas)
        self.g.set_targets(h_m=float(est[E_H]), chi_rad=self.chi_rad, V_m_s=float(est[E_V]))
        self.mode = int(mode)
        self.nav_wp = None

    def disengage(self) -> None:
        self.mode_before_off = self.mode
        self.engaged = False
        self.mode = -1

    def resume(self, est: np.ndarray, meas: np.ndarray, keep_state: bool) -> None:
        """Engage again in the mode it flew before :meth:`disengage` (after a data-loss
        FAILSAFE), with the targets it had. ``keep_state``: nothing flew meanwhile (the plant
        froze), so it runs on exactly where it stopped. Otherwise its integrals (the learned
        model errors) and targets are kept and its commands start from the current state, the
        throttle from its last command (what the plant kept)."""
        if not keep_state:
            gx = self.g.gx
            kept = (gx[G.GX_H_INT], gx[G.GX_V_INT], gx[G.GX_G_INT])
            thr = float(self.g.out[G.GO_THR])
            self._inputs(est, meas)
            self.g.reset(self.gest, thr if 0.0 <= thr <= 1.0 else -1.0)
            gx[G.GX_H_INT], gx[G.GX_V_INT], gx[G.GX_G_INT] = kept
        self.mode = self.mode_before_off
        self.count = 0
        self.engaged = True

    @property
    def count(self) -> int:
        """Fast ticks since the last guidance step, mod ``div`` (0: the next tick steps it)."""
        return self._count.item(0)

    @count.setter
    def count(self, n: int) -> None:
        self._count[0] = n

    # ------------------------------------------------------------------ the tick
    def tick(self, est: np.ndarray, meas: np.ndarray, before_step=None) -> bool:
        """Called every fast tick while a guidance mode flies: steps the guidance on every
        ``div``-th call (the first call after engagement included). True if it stepped.
        ``before_step`` (no arguments), if given, is called after the frame's inputs are read
        and before the step: CRUISE's course target for this frame (fc/cruise_track.py)."""
        c = self._count.item(0)
        due = c == 0
        c += 1
        self._count[0] = c if c < self.div else 0
        if not due:
            return False
        self._inputs(est, meas)
        if before_step is not None:
            before_step()
        self.limits = self.g.step_f(self.gest, self.chi_rad, self.dt_s)
        count_p(self._steps_p)
        return True

    @property
    def steps(self) -> int:
        """Guidance steps since start."""
        return self._steps.item(0)

    def course_error_filtered(self) -> float:
        """The course loop's filtered error wrap(chi_t - chi) (rad) after the last step; 0
        before the first (docs/guidance.md section 3, GH_CHI_TAU)."""
        e = float(self.g.gx[G.GX_CHI_ERR_F])
        return e if math.isfinite(e) else 0.0

    def throttle(self) -> float:
        """The throttle command 0..1 (0 when not engaged)."""
        return self._out_mv[G.GO_THR] if self.engaged else 0.0

    def throttle_pwm(self) -> int:
        """servo4 PWM (us) of the throttle command; 0 (no output) when not engaged."""
        return throttle_to_pwm(self.g.out[G.GO_THR]) if self.engaged else 0

    # ------------------------------------------------------------------ targets
    def targets(self) -> tuple[float, float, float]:
        """(altitude m, course rad, speed m/s) in force."""
        t = self.g.tgt
        return float(t[G.TG_H]), float(t[G.TG_CHI]), float(t[G.TG_V])

    def qbar_pa(self, h_m: float, v_m_s: float) -> float:
        """Dynamic pressure of the nominal atmosphere at (h, V), Pa."""
        interp_atmosphere(float(h_m), self.g.atm, self.g.grid, self._atm, 0)
        return 0.5 * float(self._atm[ATM_RHO]) * v_m_s * v_m_s

    def check_targets(self, h_m: float | None, chi_rad: float | None,
                      v_m_s: float | None) -> str | None:
        """None if the targets (None keeps one) are inside the envelope, else the reason:
        altitude in [GT_ALT_MIN, GT_ALT_MAX], speed in [GT_SPD_MIN, GT_SPD_MAX] and the
        dynamic pressure of the resulting (altitude, speed) in [GE_QBAR_MIN, GE_QBAR_MAX]."""
        p = self.params
        for name, v in (("altitude", h_m), ("course", chi_rad), ("speed", v_m_s)):
            if v is not None and not math.isfinite(v):
                return f"{name} target not finite"
        if h_m is not None and not p.get("GT_ALT_MIN") <= h_m <= p.get("GT_ALT_MAX"):
            return (f"altitude {h_m:.0f} m outside [{p.get('GT_ALT_MIN'):.0f}, "
                    f"{p.get('GT_ALT_MAX'):.0f}] (GT_ALT_*)")
        if v_m_s is not None and not p.get("GT_SPD_MIN") <= v_m_s <= p.get("GT_SPD_MAX"):
            return (f"speed {v_m_s:.0f} m/s outside [{p.get('GT_SPD_MIN'):.0f}, "
                    f"{p.get('GT_SPD_MAX'):.0f}] (GT_SPD_*)")
        h0, _, v0 = self.targets() if self.engaged else (None, None, None)
        h = h_m if h_m is not None else h0
        v = v_m_s if v_m_s is not None else v0
        if h is not None and v is not None and (h_m is not None or v_m_s is not None):
            q = self.qbar_pa(h, v)
            lo, hi = p.get("GE_QBAR_MIN"), p.get("GE_QBAR_MAX")
            if not lo <= q <= hi:
                return (f"qbar {q / 1000:.1f} kPa at {h:.0f} m, {v:.0f} m/s outside "
                        f"[{lo / 1000:.0f}, {hi / 1000:.0f}] kPa (GE_QBAR_*)")
        return None

    def set_targets(self, h_m: float | None = None, chi_rad: float | None = None,
                    v_m_s: float | None = None) -> str | None:
        """Validate (:meth:`check_targets`) and set; None on success, else the reason."""
        reason = self.check_targets(h_m, chi_rad, v_m_s)
        if reason is None:
            self.g.set_targets(h_m=h_m, chi_rad=chi_rad, V_m_s=v_m_s)
        return reason

    # ------------------------------------------------------------------ telemetry
    def nav_output(self, est: np.ndarray) -> tuple:
        """NAV_CONTROLLER_OUTPUT fields: nav_roll deg (the bank command mu_c), nav_pitch deg
        (gamma_c + alpha_c: the pitch of the commanded flight path, wings level), nav_bearing
        deg (the course target), target_bearing deg (to the waypoint, else the course target),
        wp_dist m (0 without a waypoint), alt_error m (target - altitude), aspd_error m/s
        (speed reference - airspeed), xtrack_error m (the mission leg's, else 0)."""
        st = self.g.status
        h_t, chi_t, _ = self.targets()
        nav_bearing = int(round(math.degrees(chi_t))) % 360
        if self.nav_wp is not None:
            tb = int(round(math.degrees(self.nav_wp[0]))) % 360
            dist = min(max(int(round(self.nav_wp[1])), 0), 65535)
        else:
            tb, dist = nav_bearing, 0
        return (math.degrees(st[G.GS_MU_C]), math.degrees(st[G.GS_GAM_C] + st[G.GS_ALPHA_C]),
                nav_bearing if nav_bearing < 180 else nav_bearing - 360,
                tb if tb < 180 else tb - 360, dist, h_t - float(est[E_H]),
                float(st[G.GS_V_ERR]), 0.0 if self.nav_wp is None else float(self.nav_wp[2]))
