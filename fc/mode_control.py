"""fc/mode_control.py - flight mode, law and guidance engagement, data-loss failsafe.

One part of the flight controller (docs/architecture.md, the fc's parts), around the mode
state machine of fc/modes.py (which decides; this part acts). After any mode or arming change
(:meth:`ModeControl.sync`): CO_ENABLE follows the mode (GUID_INNER_CO in the guidance modes),
the law is reset at engagement from the current estimate (or on the first healthy frame when
the estimate is not healthy yet), the guidance engaged or re-targeted. The data-loss failsafe
(docs/fc.md, docs/reliability.md): FAILSAFE after FS_TIMEOUT_S of wall clock without a healthy
frame, the surfaces held at the trim the law flew (:class:`SurfaceHold`); recovery into the mode
it was in (FS_RECOVER), judged on plant time: at once if the plant froze (its time advanced less
than FS_TIMEOUT_S over the gap: nothing flew without the fc), the law and guidance resuming
where they stopped; otherwise after FS_RECOVER_S of plant time with data back, the law reset at
the new state and the guidance resuming its targets and integrals (only its commands start
from the new state).
"""
from __future__ import annotations

import logging
import math
from typing import Callable

import numpy as np

from fc.estimator import Estimator
from fc.frame_calls import ArrayAddress, address_of, blend3_p
from fc.gcs_streams import IN_AIR_SPEED_M_S
from fc.guided import GuidanceRunner
from fc.link import M_AIRSPEED, PlantLink
from fc.link import mavlink as ML
from fc.modes import FS_DATA, GUIDANCE_MODES, FlightMode, ModeManager
from fc.param_service import ProcessSettings
from fc.params import ParamTable
from fc.scheduler import TickPlanner

__all__ = ["DATA_LOSS_BITS", "HOLD_FLOWN", "HOLD_N", "ModeControl", "SurfaceHold",
           "TRIM_EST_TAU_S"]

#: SYS_STATUS health bits cleared while plant data is lost (docs/fc.md, failsafe).
DATA_LOSS_BITS = (ML.MAV_SYS_STATUS_SENSOR_3D_GYRO | ML.MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE
                  | ML.MAV_SYS_STATUS_SENSOR_DIFFERENTIAL_PRESSURE | ML.MAV_SYS_STATUS_AHRS
                  | ML.MAV_SYS_STATUS_SENSOR_ATTITUDE_STABILIZATION)


#: time constant of the trim estimate (the law's commands low-passed), s
TRIM_EST_TAU_S = 3.0
#: SurfaceHold.cells: the estimate (rad) at 0..2, the law time averaged (s) at HOLD_FLOWN
HOLD_FLOWN = 3
HOLD_N = 4

#: how the law and guidance resume after a data-loss FAILSAFE
RESUME_NONE, RESUME_FROZEN, RESUME_FLOWN = 0, 1, 2


class SurfaceHold:
    """The trim the law flew: its surface commands (rad, left elevon, right elevon, rudder)
    averaged, a running mean over the first TRIM_EST_TAU_S of flight and a first-order
    low-pass after it. What FAILSAFE holds (the plant holds the commands of a silent fc
    averaged the same way: plant_sim/hold.py ``HOLD_TAU_S``). Three floats, updated in
    place, no allocation."""

    def __init__(self, tau_s: float = TRIM_EST_TAU_S) -> None:
        self.tau_s = tau_s
        # est_rad (rad) and the law time averaged so far (s) in one float64[4]: the fc's fused
        # frame step (fc/fused.py) updates both in place
        self.cells = np.zeros(HOLD_N)
        self.est_rad = self.cells[:3]
        # update()'s arrays by address (fc/frame_calls.py: no object allocated per tick)
        self._est_p = address_of(self.est_rad, np.float64, 3)
        self._src_at = ArrayAddress(np.float64, 3)

    @property
    def flown_s(self) -> float:
        """Law time averaged so far, s (0: no estimate)."""
        return self.cells.item(HOLD_FLOWN)

    @flown_s.setter
    def flown_s(self, value: float) -> None:
        self.cells[HOLD_FLOWN] = value

    def update(self, delta_rad: np.ndarray, dt_s: float) -> None:
        """One fast tick of the law's fresh command ``delta_rad`` (rad)."""
        c = self.cells
        f = c.item(HOLD_FLOWN) + dt_s
        c[HOLD_FLOWN] = f
        tau = self.tau_s
        k = dt_s / (tau if tau < f else f)      # min(f, tau) without min's argument iterator
        blend3_p(self._est_p, self._src_at.of(delta_rad), k)

    def clear(self) -> None:
        self.flown_s = 0.0

    def hold_rad(self, fallback_rad: np.ndarray) -> np.ndarray:
        """The estimate once the law flew, else ``fallback_rad`` (the TRIM_* parameters)."""
        return self.est_rad if self.cells.item(HOLD_FLOWN) > 0.0 else fallback_rad


class ModeControl:
    """Acts on the mode state machine's decisions: law, guidance, failsafe."""

    def __init__(self, modes: ModeManager, params: ParamTable, settings: ProcessSettings,
                 law, guid: GuidanceRunner, est: Estimator, meas: np.ndarray,
                 planner: TickPlanner, plant: PlantLink,
                 announce_param: Callable[[str], None],
                 event: Callable[[str, int], None], log: logging.Logger) -> None:
        self.modes = modes
        self.params = params
        self.settings = settings
        self.law = law
        self.guid = guid
        self.est = est
        self.meas = meas                # the newest sensor frame (fc/link.py M_*), in place
        self.planner = planner
        self.plant = plant
        self.announce_param = announce_param    # PARAM_VALUE of a value the process set
        self.event = event                      # STATUSTEXT (severity) and fc.log
        self.log = log
        self.changes_seen = -1          # the mode manager's change count acted on
        self.engaged = False            # the law runs from an engagement (no reset on a
                                        # switch between law modes with the same CO)
        # True while the law is engaged but the estimate is not yet healthy: the law is reset
        # (integrators, observer, estimates start from the current state) on the first
        # healthy frame.
        self.reset_pending = False
        self.seen_data = False          # a healthy frame since start-up
        self.last_good_wall_s = -1.0    # wall clock of the newest healthy frame
        self.last_good_stamp_s = -1.0   # plant time of the newest healthy frame
        self.lost_stamp_s = -1.0        # plant time of the last healthy frame before a loss
        self.resume = RESUME_NONE       # how the next sync resumes after a data-loss FAILSAFE
        self.hold = SurfaceHold()       # the trim FAILSAFE holds

    def resync(self) -> None:
        """Act again on the next :meth:`sync` (re-engages the law, reset at the new state)."""
        self.changes_seen = -1

    def restart(self) -> None:
        """Plant time went backwards: the law and the guidance start over at the new state."""
        self.changes_seen = -1
        self.engaged = False
        self.guid.disengage()

    def request_mode(self, mode: int) -> tuple[bool, str]:
        ok, text = self.modes.request_mode(mode)
        self.sync()
        return ok, text

    def in_air(self) -> bool:
        """Flying, as far as the fc knows, for the disarm rule: plant data seen, the plant's run
        not ended, and the newest frame's airspeed above IN_AIR_SPEED_M_S (EXTENDED_SYS_STATE's
        threshold, fc/gcs_streams.py), also after the data was lost (the last word is that it
        flies; EXTENDED_SYS_STATE says UNDEFINED then)."""
        v = float(self.meas[M_AIRSPEED])
        return (self.seen_data and not self.plant.ended
                and (v > IN_AIR_SPEED_M_S or not math.isfinite(v)))

    def arm(self, armed: bool, forced: bool = False) -> tuple[bool, str]:
        """Arm/disarm (COMPONENT_ARM_DISARM): a disarm in flight only when ``forced``."""
        ok, text = self.modes.set_armed(armed, data_ok=self.est.healthy and self.seen_data
                                        and not self.modes.data_lost and not self.plant.ended,
                                        in_air=self.in_air(), forced=forced)
        self.sync()
        return ok, text

    def sync(self) -> None:
        """After any mode/arming change: CO_ENABLE from the mode, law reset on engagement."""
        modes = self.modes
        if modes.changes == self.changes_seen:
            return
        self.changes_seen = modes.changes
        co_changed = False
        if modes.mode in (FlightMode.COORDINATED, FlightMode.UNCOORDINATED):
            co = modes.co_enable
        elif modes.mode in GUIDANCE_MODES:
            co = 1.0 if self.params.get("GUID_INNER_CO") > 0.5 else 0.0
        else:
            co = None
        if co is not None and "CO_ENABLE" in self.params and self.params.get("CO_ENABLE") != co:
            self.law.set_param("CO_ENABLE", co)
            self.params.force("CO_ENABLE", co)
            co_changed = True
            self.announce_param("CO_ENABLE")
        resume, self.resume = self.resume, RESUME_NONE
        if modes.law_active:
            if resume == RESUME_FROZEN and not co_changed and not self.reset_pending:
                self.engaged = True     # nothing flew without us: the law runs on where it was
            elif self.engaged and not co_changed and not self.reset_pending:
                pass        # a switch between law modes with the same law: it runs on, bumpless
            elif self.est.healthy:
                self._engage_law(resume)
            else:
                self.reset_pending = True   # engaged before data: reset on first healthy frame
        else:
            self.engaged = False
        if not modes.armed:
            self.hold.clear()
        self._sync_guidance(resume)
        self.log.info("mode %s, %s", modes.mode.name, "armed" if modes.armed else "disarmed")

    def _engage_law(self, resume: int = RESUME_NONE) -> None:
        """Start the law from the current (healthy) estimate (and the guidance, in its modes)."""
        self.law.reset(self.est.est)
        self.reset_pending = False
        self.engaged = True
        self.planner.ticks = 0      # slow loop runs on the first tick after engagement
        if self.modes.guidance_active:
            self._guidance_on(resume)

    def _guidance_on(self, resume: int) -> None:
        """Engage the guidance: after a data-loss FAILSAFE in the mode it flew before, resume
        it (its targets and integrals kept); otherwise hold the current state."""
        if resume != RESUME_NONE and self.guid.mode_before_off == self.modes.mode:
            self.guid.resume(self.est.est, self.meas, keep_state=resume == RESUME_FROZEN)
        else:
            self.guid.engage(self.est.est, self.meas, self.modes.mode)

    def _sync_guidance(self, resume: int = RESUME_NONE) -> None:
        """Guidance engagement after a mode change: engaged from the current state on entry
        into a guidance mode (with the law, once the estimate is healthy), re-targeted to the
        current altitude, course and speed on a switch between guidance modes, resumed after
        a data-loss FAILSAFE."""
        if not self.modes.guidance_active:
            if self.guid.engaged:
                self.guid.disengage()
            return
        if self.reset_pending:
            return                  # engaged with the law on the first healthy frame
        if not self.guid.engaged:
            self._guidance_on(resume)
        elif self.guid.mode != self.modes.mode:
            self.guid.hold_current(self.est.est, self.meas, self.modes.mode)

    def law_fault(self) -> None:
        """The law raised: FAILSAFE (the caller puts the surfaces at trim)."""
        self.modes.request_mode(FlightMode.FAILSAFE)
        self.event("law fault: FAILSAFE", ML.MAV_SEVERITY_CRITICAL)
        self.sync()

    # ---------------------------------------------------------------- data-loss failsafe
    def on_frame(self, now_s: float, stamp_s: float = -1.0) -> None:
        """After the estimator took a new frame that arrived at ``now_s`` (wall clock),
        stamped ``stamp_s`` (plant time, s; negative: unknown, the wall clock stands in)."""
        if self.plant.relock_allowed and not self.modes.data_lost:
            self.plant.relock_allowed = False
        if not self.est.healthy:
            return
        self.seen_data = True
        if self.reset_pending and self.modes.law_active:
            self._engage_law()
        self.last_good_wall_s = now_s
        t_s = stamp_s if stamp_s >= 0.0 else now_s
        if self.modes.data_lost:        # (on_data_ok has nothing to do otherwise)
            self._data_back(t_s, stamp_s >= 0.0)
        self.last_good_stamp_s = t_s

    def _data_back(self, t_s: float, stamped: bool) -> None:
        """A healthy frame at plant time ``t_s`` while data is lost: recover (module docstring).
        Frozen: plant time moved on by less than FS_TIMEOUT_S over the whole gap."""
        s = self.settings
        gap_s = t_s - self.lost_stamp_s
        frozen = stamped and self.lost_stamp_s >= 0.0 and 0.0 <= gap_s <= s.fs_timeout_s
        resume_from = self.modes.mode_before_fs if self.modes.fs_cause == FS_DATA else None
        text = self.modes.on_data_ok(t_s, s.fs_recover, s.fs_recover_s, at_once=frozen)
        if text is None:
            return
        if frozen:      # (a STATUSTEXT holds 50 characters: the detail goes to fc.log)
            text = text.replace("plant data back", "plant data back (froze)", 1)
        self.log.info("%s; %.3f s of plant time in the gap", text, gap_s)
        self.event(text, ML.MAV_SEVERITY_NOTICE)
        if resume_from is not None and self.modes.mode == resume_from:
            self.resume = RESUME_FROZEN if frozen else RESUME_FLOWN
        self.sync()

    def check_data(self, now_s: float) -> None:
        """Housekeeping: FAILSAFE once healthy frames stop for FS_TIMEOUT_S (not after the
        plant said goodbye)."""
        modes = self.modes
        if (self.seen_data and not modes.data_lost and not self.plant.ended
                and now_s - self.last_good_wall_s > self.settings.fs_timeout_s):
            self.lost_stamp_s = self.last_good_stamp_s
            text = modes.on_data_lost()
            self.plant.relock_allowed = True   # a restarted plant may come from a new port
            if text:
                self.log.warning(text)
                self.event(text, ML.MAV_SEVERITY_CRITICAL)
                self.sync()
        elif modes.data_lost and now_s - self.last_good_wall_s > 0.05:
            modes.on_data_gap()

    def health_failed_bits(self) -> int:
        """SYS_STATUS health bits failed now."""
        if self.modes.data_lost or self.plant.ended:
            return DATA_LOSS_BITS
        if self.seen_data and not self.est.healthy:
            return ML.MAV_SYS_STATUS_AHRS
        return 0
