"""fc/app.py - the flight-controller process: builds its parts and wires them.

Data flows one way per fast tick: sensor frame (fc/link.py) -> frame intake (fc/intake.py:
estimator, failsafe bookkeeping, timeline) -> [guidance, fc/guided.py] -> law.slow_step /
law.fast_step -> surface command -> SERVO_OUTPUT_RAW. The parts: run loops and housekeeping
(fc/loops.py), mode/failsafe (fc/mode_control.py around fc/modes.py), parameters
(fc/param_service.py, fc/params.py), telemetry (fc/telemetry.py), the ground station
(fc/gcs.py, which sees this controller as a fc/vehicle_view.py VehicleView); who calls whom:
docs/architecture.md, the fc's parts. The law (fc/control, docs/architecture.md section 11) is
injected: ``law_module`` names a module exposing ``AttitudeLaw`` and ``LAW_PARAMS``.
"""
from __future__ import annotations

import functools
import importlib
import logging
import math
import os
from dataclasses import dataclass, field

import numpy as np

from fc.cruise_track import CruiseTrack
from fc.estimator import E_N, Estimator
from fc.fused import FusedFrame
from fc.gcs import GcsLink
from fc.guided import GuidanceRunner
from fc.intake import REORDER_WINDOW_US, FrameIntake
from fc.internals_log import InternalsLog
from fc.iothread import IoThread
from fc.frame_calls import (ArrayAddress, address_of, surfaces_pwm_p,
                            surfaces_throttle_pwm_p)
from fc.link import M_N, PlantLink, UdpEndpoint, load_signing_key, mavlink
from fc.mission import Mission
from fc.mission_mode import MissionFlight
from fc.mission_store import FILE_NAME as MISSION_FILE, MissionStore
from fc.mode_control import ModeControl
from fc.modes import GUIDANCE_MODES, FlightMode, ModeManager
from fc.point_mode import PointFlight
from fc.param_service import ParamService, load_param_file
from fc.params import ParamTable, build_table
from fc.loops import Housekeeping, RunLoops
from fc.scheduler import FrameGate, LoopStats, TickPlanner
from fc.signing import FILE_NAME as SIGNING_FILE
from fc.storage import DiskHealth
from fc.telemetry import FcCounters, Telemetry, TickOutput
from fc.timeline import Timeline, load_timeline
from hyfc_wire.earth import EARTH_RADIUS_M

__all__ = ["FcConfig", "FlightController", "load_law_module"]

ML = mavlink
# the modes the tick compares with, bound once: looking a member up on the enum class makes a
# Python object on every lookup (measured: tools.bench.allocs), and the tick runs per frame
_CRUISE, _FAILSAFE = FlightMode.CRUISE, FlightMode.FAILSAFE
_MISSION, _RTL, _GUIDED = FlightMode.MISSION, FlightMode.RTL, FlightMode.GUIDED


@dataclass
class FcConfig:
    """Everything ``python -m fc`` takes on its command line (docs/architecture.md 10)."""

    mode: str = "lockstep"                 # lockstep | realtime
    plant_bind: tuple = ("127.0.0.1", 14560)
    plant_sysid: int = 2
    gcs: list = field(default_factory=lambda: [("127.0.0.1", 14550)])
    gcs_bind: tuple = ("127.0.0.1", 14555)
    fast_hz: float = 500.0
    slow_hz: float = 100.0
    params: str | None = None
    timeline: str | None = None
    out: str = "."
    arm: bool = False
    flight_mode: str = "MANUAL"
    sysid: int = 1
    compid: int = 1
    signing_key_file: str | None = None
    realtime_priority: int = 50            # SCHED_FIFO priority, 0 = do not ask
    spin_us: int = 0                       # busy-wait the last microseconds before a deadline
    sync: str = "frame"                    # realtime: frame (tick on the sensor frame) | clock
    law_module: str = "fc.control"
    #: internals log: every row for this long (s of sensor time), then one per two slow ticks;
    #: None: every row however long the run (fc/internals_log.py)
    internals_full_rate_s: float | None = 60.0
    #: internals log: rows per second after ``internals_full_rate_s`` (Hz); None: slow_hz / 2
    #: (50 Hz: the hour's logs within 300 MB with the plant's decimated truth, issue 24)
    internals_tail_hz: float | None = None


def load_law_module(name: str):
    """(AttitudeLaw class, LAW_PARAMS) from ``name`` (default ``fc.control``)."""
    if name == "fc.control":
        law_cls = importlib.import_module("fc.control.law").AttitudeLaw
        params = importlib.import_module("fc.control.params").LAW_PARAMS
        return law_cls, params
    mod = importlib.import_module(name)
    return mod.AttitudeLaw, mod.LAW_PARAMS


class FlightController:
    """The fc process. ``run(stop)`` loops until ``stop()`` returns True."""

    def __init__(self, cfg: FcConfig, log: logging.Logger | None = None) -> None:
        self.cfg = cfg
        self.log = log or logging.getLogger("fc")
        self.sysid = cfg.sysid
        self.compid = cfg.compid
        os.makedirs(cfg.out, exist_ok=True)
        self.planner = TickPlanner(cfg.fast_hz, cfg.slow_hz,
                                   max_catchup=1 if cfg.mode == "realtime" else 8)
        if cfg.mode not in ("lockstep", "realtime"):
            raise ValueError(f"--mode must be lockstep or realtime, not {cfg.mode!r}")
        self.stats = LoopStats(self.planner.period_ns)
        if cfg.sync not in ("frame", "clock"):
            raise ValueError(f"--sync must be frame or clock, not {cfg.sync!r}")
        self.gate = FrameGate(self.planner.period_ns)
        # cheap checks of the inputs first: a bad file fails before the law is loaded
        commands = load_timeline(cfg.timeline) if cfg.timeline else None
        key = load_signing_key(cfg.signing_key_file) if cfg.signing_key_file else None

        # --- parameters and law
        law_cls, law_params = load_law_module(cfg.law_module)
        self.params: ParamTable = build_table(law_params)
        law_names = {p.name for p in law_params}
        params_path = cfg.params or os.path.join(cfg.out, "params.parm")
        # what the fc keeps across restarts sits beside the parameters: the signing stream
        # timestamps (fc/signing.py), the mission and home
        state_dir = os.path.dirname(os.path.abspath(params_path))
        self.disk = DiskHealth()
        startup_texts = load_param_file(self.params, params_path, self.log)
        overrides = {n: self.params.get(n) for n in law_names}
        self.law = law_cls(overrides)
        d = getattr(self.law, "delta_cmd_rad", None)
        if not (isinstance(d, np.ndarray) and d.dtype == np.float64 and d.shape == (3,)):
            raise ValueError(f"law {cfg.law_module}: delta_cmd_rad must be a float64[3] array "
                             f"(docs/architecture.md section 11), not {type(d).__name__}")
        self.status_names = list(getattr(self.law, "STATUS_NAMES", ()))
        self._warm_up_law(law_cls, overrides)
        # the guidance (outer loop) of CRUISE/GUIDED (fc/guided.py), stepped from the fast tick
        self.guid = GuidanceRunner(self.params, cfg.fast_hz)
        self.guid.warm_up()
        # the stored mission (fc/mission.py, its protocol in fc/gcs.py) and MISSION mode
        self.mission = Mission()
        self.mission_flight = MissionFlight(self.mission)
        self.cruise_track = CruiseTrack(EARTH_RADIUS_M)
        # CRUISE's course target, set before each guidance step (bound once: no allocation)
        self._cruise_course = functools.partial(self.cruise_track.tick, self)
        # RTL, DO_REPOSITION and DO_ORBIT: a point flown by the guidance (fc/point_mode.py)
        self.point_flight = PointFlight()

        # --- state
        self.meas = np.zeros(M_N)
        self.meas_scratch = np.zeros(M_N)
        self.est = Estimator(self.params.get("EST_STALE_S"))
        # parameter changes after start-up, the process's own parameters in SI
        self.param_svc = ParamService(self.params, law_names, self.law, self.guid, self.est,
                                      params_path, self.log, disk=self.disk)
        self.settings = self.param_svc.settings
        self.out = TickOutput(self.settings.cmd_rad)
        self.pwm_us = self.out.pwm_us           # VehicleView (the same array)
        # the tick's output kernel's arrays by address (fc/frame_calls.py: no array record)
        self._src_at = ArrayAddress(np.float64, 3)
        self._delta_p = address_of(self.out.delta_rad, np.float64, 3)
        self._pwm_p = address_of(self.out.pwm_us, np.int64, 4)
        # the guidance modes' output kernel loaded now, not in the first tick that flies one
        spare = (np.zeros(3), np.zeros(3), np.full(1, 0.5), np.zeros(4, np.int64))
        surfaces_throttle_pwm_p(*(address_of(a, a.dtype, a.size) for a in spare[:3]), True,
                                address_of(spare[3], np.int64, 4))
        self.counters = FcCounters()
        self.modes = ModeManager()

        # --- links and logs (bind last: READY means everything is in place)
        self.plant = PlantLink(UdpEndpoint(*cfg.plant_bind), plant_sysid=cfg.plant_sysid,
                               sysid=cfg.sysid, compid=cfg.compid)
        self.io = IoThread(self.log)
        self.gcs = GcsLink(self, cfg.gcs_bind, cfg.gcs, os.path.join(cfg.out, "fc.tlog"),
                           signing_key=key, log=self.log, io=self.io,
                           sim_time=cfg.mode == "lockstep",
                           signing_path=os.path.join(state_dir, SIGNING_FILE), disk=self.disk)
        self.mission.alt_limits_m = self._mission_alt_limits    # checked at upload
        # the mission and home of the last run (fc/mission_store.py): a restart flies on
        self.mission_store = MissionStore(self.mission, os.path.join(state_dir, MISSION_FILE),
                                          self._home, self.log, self.disk)
        restored_home = self.mission_store.load()
        if restored_home is not None:
            self.gcs.home = restored_home
            startup_texts.append((ML.MAV_SEVERITY_INFO, "home restored: %.7f %.7f %.0f m"
                                  % restored_home))
        if self.mission.count:
            startup_texts.append((ML.MAV_SEVERITY_INFO,
                                  f"mission restored: {self.mission.count} items, "
                                  f"current {self.mission.current}"))
        if key is not None:
            self.log.info("MAVLink 2 signing enabled on the GCS link (key from %s)",
                          cfg.signing_key_file)
        self.mode_ctl = ModeControl(self.modes, self.params, self.settings, self.law, self.guid,
                                    self.est, self.meas, self.planner, self.plant,
                                    self.gcs.announce_param, self._event, self.log)
        self.intake = FrameIntake(self.meas, self.meas_scratch, self.est, self.mode_ctl,
                                  self.planner, cfg.mode == "lockstep", self.counters,
                                  Timeline(commands) if commands is not None else None,
                                  self.set_param, self.gcs.announce_param, self._event,
                                  REORDER_WINDOW_US if cfg.mode == "realtime" else 0)
        self.telemetry = Telemetry(self.out, self.counters, self.est, self.modes, self.plant,
                                   self.gcs, self.stats, self.planner, self.gate, self.law,
                                   self.status_names, self.guid)
        self.ilog = InternalsLog(cfg.out, self.telemetry.columns(), disk=self.disk,
                                 full_rate_s=cfg.internals_full_rate_s,
                                 tail_hz=cfg.internals_tail_hz or cfg.slow_hz / 2.0)
        # state files saved at 1 Hz when changed and at exit: (snapshot, save) pairs
        self.savers = ((self.gcs.signing_snapshot, self.gcs.save_signing),
                       (self.mission_store.snapshot, self.mission_store.save))
        housekeeping = Housekeeping(self.gcs, self.plant, self.intake, self.mode_ctl, self.stats,
                                    self.planner, self.counters, self.telemetry, self.param_svc,
                                    self.io, self._event, self.log, disk=self.disk,
                                    savers=self.savers)
        self.loops = RunLoops(cfg.mode, cfg.sync, cfg.spin_us, cfg.realtime_priority, self.plant,
                              self.gcs, self.intake, self.planner, self.gate, self.stats,
                              self.counters, self.telemetry, self.ilog, self.modes,
                              self.mode_ctl, self.out, self._fast_tick, housekeeping, self.log)
        # lockstep: the common frame in one compiled call (fc/fused.py), built on the parts
        # above; it says per frame whether it may run
        self.loops.fused = FusedFrame(self) if cfg.mode == "lockstep" else None
        for sev, text in startup_texts:
            self.gcs.statustext(sev, text)
        if cfg.flight_mode:
            ok, text = self.modes.request_mode(FlightMode[cfg.flight_mode.upper()])
            if not ok:
                raise ValueError(text)
        if cfg.arm:
            self.modes.set_armed(True, data_ok=True)
        self.mode_ctl.sync()
        self.telemetry.refresh()
        self.gcs.warm_up()          # the streams' compiled framing (fc/gcs_frames.py) loaded now

    # ------------------------------------------------------------------ parameters
    def set_param(self, name: str, value: float) -> str | None:
        """Validate and apply one parameter (GCS, timeline). None on success, else the reason."""
        reason = self.param_svc.set(name, value)
        if reason is None and name == "GUID_INNER_CO" and self.modes.mode in GUIDANCE_MODES:
            self.mode_ctl.resync()           # re-sync CO_ENABLE (and reset the law)
        return reason

    def save_params(self, done) -> bool:
        """The parameter file written now on the I/O thread; ``done(error or None)`` from
        there (a ground station's PARAM_SET is answered once it is on disk, fc/gcs.py)."""
        values = self.param_svc.snapshot(force=True)

        def job():
            done(self.param_svc.save(values))
        self.io.submit(job)
        return True

    def set_attitude_command(self, alpha_deg: float, beta_deg: float, mu_deg: float) -> str | None:
        """MAV_CMD_USER_1 / timeline: set alpha_c, beta_c, mu_c [deg]; NaN keeps a value."""
        pairs = [(n, v) for n, v in (("CMD_ALPHA_DEG", alpha_deg), ("CMD_BETA_DEG", beta_deg),
                                      ("CMD_MU_DEG", mu_deg)) if not math.isnan(v)]
        for n, v in pairs:
            reason = self.params.check(n, float(v))
            if reason is not None:
                return reason
        for n, v in pairs:
            self.set_param(n, float(v))
            self.gcs.announce_param(n)
        return None

    # ------------------------------------------------------------------ modes
    def request_mode(self, mode: int) -> tuple[bool, str]:
        if mode == FlightMode.MISSION and self.modes.mode != FlightMode.MISSION:
            reason = self.mission_flight.entry_refusal(self)
            if reason is not None:
                return False, reason
        if mode == FlightMode.RTL:
            reason = self.point_flight.entry_refusal(self)
            if reason is not None:
                return False, f"RTL refused: {reason}"
        return self.mode_ctl.request_mode(mode)     # RTL: home is set at the next step

    def arm(self, armed: bool, forced: bool = False) -> tuple[bool, str]:
        return self.mode_ctl.arm(armed, forced)

    def set_guidance_targets(self, h_m: float | None = None, chi_rad: float | None = None,
                             V_m_s: float | None = None) -> str | None:
        """Targets of the guidance (altitude m AMSL, course rad, airspeed m/s; None keeps one),
        validated against the envelope (GT_ALT_*, GT_SPD_*, GE_QBAR_*); the guidance clips
        what it flies by its own envelope limits. None on success, else the reason. GUIDED's
        ground-station commands and the navigators (mission, point) call it: it does not log
        (a navigator calls it at 10 Hz; the ground-station link logs its own commands)."""
        return self.guid.set_targets(h_m, chi_rad, V_m_s)

    def change_speed(self, v_m_s: float) -> str | None:
        """DO_CHANGE_SPEED in a guidance mode: the speed target from now on (in MISSION until
        a speed item changes it). None on success, else the reason."""
        if not self.modes.guidance_active:
            return "only in a guidance mode (CRUISE, GUIDED, MISSION, RTL)"
        if self.modes.mode == FlightMode.MISSION:
            return self.mission_flight.set_speed(self, v_m_s)
        return self.set_guidance_targets(V_m_s=v_m_s)

    def go_to(self, lat_deg: float, lon_deg: float, h_m: float | None,
              v_m_s: float | None) -> str | None:
        """DO_REPOSITION: GUIDED, flying to (lat, lon) deg at ``h_m`` m AMSL and ``v_m_s``
        (None: the present targets), then circling over it. None on success, else why not."""
        return self._point(lambda: self.point_flight.start_point(self, lat_deg, lon_deg,
                                                                 h_m, v_m_s))

    def orbit(self, lat_deg: float, lon_deg: float, radius_m: float,
              h_m: float | None) -> str | None:
        """DO_ORBIT: GUIDED, circling (lat, lon) deg at ``radius_m`` (> 0 clockwise) and
        ``h_m`` (None: the present target). None on success, else why not."""
        reason = self.point_flight.orbit_refusal(self, radius_m)   # before the mode changes
        return reason or self._point(lambda: self.point_flight.start_orbit(
            self, lat_deg, lon_deg, radius_m, h_m))

    def _point(self, start) -> str | None:
        """Enter GUIDED (unless in it) and start a point target with ``start()``."""
        if not self.modes.armed:
            return "disarmed"
        reason = self.point_flight.entry_refusal(self)
        if reason is not None:
            return reason
        if self.modes.mode != FlightMode.GUIDED:
            ok, text = self.mode_ctl.request_mode(FlightMode.GUIDED)
            if not ok:
                return text
        if not self.guid.engaged:
            return "the guidance is not engaged yet (no healthy estimate)"
        return start()

    def hold(self, why: str) -> None:
        """Leave MISSION/RTL/a point for CRUISE (the current altitude, course and speed held),
        saying why (the navigators' ``("hold", why)``)."""
        self.point_flight.stop()
        self._event(why, ML.MAV_SEVERITY_WARNING)
        self.mode_ctl.request_mode(FlightMode.CRUISE)

    def _nav_out(self, out: list) -> None:
        """The navigators' outputs: protocol messages and texts to the ground station, a
        ``("hold", why)`` to :meth:`hold`."""
        hold = [o[1] for o in out if o[0] == "hold"]
        rest = [o for o in out if o[0] != "hold"]
        if rest:
            self.gcs.mission_send(rest)
        if hold:
            self.hold(hold[0])

    def _home(self) -> tuple[float, float, float] | None:
        return self.gcs.home

    def _mission_alt_limits(self) -> tuple[float, float, float | None]:
        """(GT_ALT_MIN m, GT_ALT_MAX m, home altitude m MSL or None): a mission's waypoint
        altitudes are checked against them at upload (fc/mission.py)."""
        home = self.gcs.home
        return (self.params.get("GT_ALT_MIN"), self.params.get("GT_ALT_MAX"),
                None if home is None else home[2])

    def guidance_targets(self) -> tuple[float, float, float]:
        """(altitude m, course rad, speed m/s) the guidance flies (or last flew)."""
        return self.guid.targets()

    def _warm_up_law(self, law_cls, overrides: dict) -> None:
        """Run a throw-away law once so its kernels are loaded before the first real tick."""
        est = np.zeros(E_N)
        est[0], est[6], est[7] = 0.02, 2000.0, 20000.0   # alpha rad, V m/s, h m: plausible
        try:
            spare = law_cls(overrides)
            spare.reset(est)
            spare.slow_step(est, np.zeros(3), self.planner.slow_dt_s)
            spare.fast_step(est, self.planner.fast_dt_s)
        except Exception as exc:  # noqa: BLE001 - only a warm-up; the real call will tell
            self.log.warning("law warm-up failed: %r", exc)

    # ------------------------------------------------------------------ the tick
    def _fast_tick(self, slow: bool, held: bool) -> None:
        """One fast tick: the guidance (in its modes), the law (``slow``: its slow loop too;
        ``held``: no new data, the last command held), the surface and throttle outputs."""
        modes = self.modes
        out = self.out
        fresh = False
        if held and modes.law_active:
            src = out.delta_rad         # hold the last command: no new data to act on
        elif modes.law_active and not self.mode_ctl.reset_pending:
            try:
                if self.guid.engaged:
                    pre = self._cruise_course if modes.mode == _CRUISE else None
                    if self.guid.tick(self.est.est, self.meas, pre):
                        self._navigate()
                    out.cmd_active = self.guid.cmd_rad
                else:
                    out.cmd_active = self.settings.cmd_rad
                if slow:
                    self.law.slow_step(self.est.est, out.cmd_active, self.planner.slow_dt_s)
                self.law.fast_step(self.est.est, self.planner.fast_dt_s)
                src = self.law.delta_cmd_rad
                fresh = True
            except Exception as exc:  # noqa: BLE001 - a law fault must not stop the outputs
                self.counters.law_errors += 1
                self.log.exception("law raised: %r", exc)
                self.mode_ctl.law_fault()
                src = self.mode_ctl.hold.hold_rad(self.settings.trim_rad)
        elif modes.armed and modes.mode == _FAILSAFE:
            # hold the trim the law flew (not the TRIM_* defaults: 0 deg while the cruise
            # trims at 5.4 / 5.4 / 0 deg), as the plant holds a silent fc's commands averaged
            src = self.mode_ctl.hold.hold_rad(self.settings.trim_rad)
        else:
            src = self.settings.trim_rad
        if fresh:
            self.mode_ctl.hold.update(src, self.planner.fast_dt_s)
        # out.delta_rad = src and servo1..3 from it (compiled, deflection_to_pwm's rounding);
        # throttle only while the guidance flies (its last command held with the law); 0 = no
        # output otherwise (the plant keeps its throttle): the attitude modes' bytes unchanged
        if modes.guidance_active:
            surfaces_throttle_pwm_p(self._src_at.of(src), self._delta_p,
                                    self.guid.throttle_addr, self.guid.engaged, self._pwm_p)
        else:
            surfaces_pwm_p(self._src_at.of(src), self._delta_p, 0, self._pwm_p)

    def _navigate(self) -> None:
        """After a guidance step: the mission (MISSION), home (RTL) or a point (GUIDED) sets
        the targets (CRUISE's course follows the great circle flown at entry, set before each
        step: ``_cruise_course``, fc/cruise_track.py). Ground-station state enters the guidance
        here only, and never as an exception (the navigators answer ``("hold", why)`` instead,
        fc/mission_mode.py)."""
        mode = self.modes.mode
        if mode == _MISSION:
            self._nav_out(self.mission_flight.tick(self))
        elif mode == _RTL:
            pf = self.point_flight
            if not pf.active or pf.stale(self):        # entered before the guidance engaged
                reason = pf.start_home(self)
                if reason is not None:
                    self._nav_out([("hold", f"RTL cannot go home ({reason}): holding (CRUISE)")])
                    return
            self._nav_out(pf.tick(self))
        elif mode == _GUIDED and self.point_flight.active:
            self._nav_out(self.point_flight.tick(self))

    def _event(self, text: str, severity: int = ML.MAV_SEVERITY_NOTICE) -> None:
        self.gcs.statustext(severity, text)

    # telemetry sources for fc/gcs.py
    @property
    def meas_stamp_us(self) -> int:
        """Plant time of the newest frame, us."""
        return self.intake.stamp_us

    @property
    def meas_stamp_at(self) -> int:
        """The address of the int64 cell holding ``meas_stamp_us`` (compiled readers), valid
        while not ``meas_stamp_big``."""
        return self.intake.stamp_at

    @property
    def meas_stamp_big(self) -> bool:
        """Whether ``meas_stamp_us`` is beyond the cell at ``meas_stamp_at`` (a faulty plant's
        u64 stamp)."""
        return self.intake.stamp_big

    def health_failed_bits(self) -> int:
        bits = self.mode_ctl.health_failed_bits()
        if self.disk.failing:
            bits |= ML.MAV_SYS_STATUS_LOGGING     # a write failed and has not succeeded since
        return bits

    def load_permille(self) -> int:
        return self.counters.load_permille

    def error_counts(self) -> tuple[int, int, int, int, int]:
        return self.telemetry.error_counts()

    def named_values(self) -> list:
        return self.telemetry.named_values()

    def named_value_count(self) -> int:
        return self.telemetry.named_value_count()

    def debug_vectors(self) -> list:
        return self.telemetry.debug_vectors()

    def throttle_percent(self) -> int:
        return self.telemetry.throttle_percent()

    # optional members of VehicleView: GcsLink frames the DEBUG_VECTs and NAMED_VALUE_FLOATs
    # with fc/gcs_frames.py
    def debug_vector_count(self) -> int:
        return self.telemetry.debug_vector_count()

    def frame_debug_vector(self, k: int, tx: int, log_epoch_us: int, log_t_at: int, seq: int,
                           sysid: int, compid: int, time_at: int) -> int:
        return self.telemetry.frame_debug_vector(k, tx, log_epoch_us, log_t_at, seq, sysid,
                                                 compid, time_at)

    def frame_named_value(self, k: int, tx: int, log_epoch_us: int, log_t_at: int, seq: int,
                          sysid: int, compid: int, time_at: int) -> int:
        return self.telemetry.frame_named_value(k, tx, log_epoch_us, log_t_at, seq, sysid,
                                                compid, time_at)

    def nav_output_active(self) -> bool:
        return self.telemetry.nav_output_active()

    def frame_nav_output(self, tx: int, log_epoch_us: int, log_t_at: int, seq: int, sysid: int,
                         compid: int) -> int:
        return self.telemetry.frame_nav_output(tx, log_epoch_us, log_t_at, seq, sysid, compid)

    def nav_controller_output(self):
        return self.telemetry.nav_controller_output()

    def run(self, stop) -> None:
        """Loop until ``stop()`` returns True (fc/loops.py)."""
        self.loops.run(stop)

    # ------------------------------------------------------------------ shutdown
    def close(self) -> None:
        """Flush and close logs and sockets (SIGINT/SIGTERM path)."""
        self.io.close()
        # every save below reports its own failure (fc/storage.py): a full disk must not turn
        # a clean exit into a traceback
        if self.param_svc.dirty:
            self.param_svc.save()
        if self.gcs.guard is not None:
            self.gcs.guard.dirty = True        # the fc's own timestamp, stored at every exit
        for snapshot, save in self.savers:
            data = snapshot()
            if data is not None:
                save(data)
        c = self.plant.counters
        self.log.info(
            "exit: frames %d, outputs %d, duplicates %d, relocks %d, rejected plant %d "
            "(sysid %d, addr %d, bad %d, incomplete %d), gcs bad %d, gcs unsigned %d, "
            "late ticks %d/%d, overruns %d, skipped %d, law errors %d, reordered frames %d, "
            "fc stalls %d (longest %.2f s), gnss samples %d, gnss dropped %d",
            c.frames, c.outputs, self.counters.duplicate_frames, c.relocks, c.rejected,
            c.rejected_sysid, c.rejected_addr, c.rejected_bad, c.rejected_incomplete, self.gcs.rejected_bad,
            self.gcs.rejected_signing, self.stats.late, self.stats.ticks, self.stats.overruns,
            self.telemetry.skipped_ticks(), self.counters.law_errors,
            self.counters.reordered_frames, self.counters.fc_stalls,
            self.counters.fc_stall_max_s, c.gnss, c.gnss_rejected)
        fused = self.loops.fused
        if fused is not None:
            self.log.info("lockstep frames in one compiled step (fc/fused.py): %d of %d%s",
                          fused.frames, c.frames, "" if fused.enabled else " (not available: "
                          "another law, no libc I/O, or NUMBA_BOUNDSCHECK)")
        if self.cfg.mode == "realtime" and self.cfg.sync == "frame":
            g = self.gate
            self.log.info("frame-synchronised ticks: on a frame %d, on the deadline after an "
                          "early frame %d, fallback (no frame) %d; early frames absorbed %d",
                          g.frame_ticks, g.grid_ticks, g.fallback_ticks, g.absorbed)
        try:
            path = self.ilog.close()
            self.log.info("internals log: %s (%d rows, %d dropped, %d decimated)", path,
                          self.ilog.rows, self.ilog.dropped, self.ilog.decimated)
        except Exception as exc:  # noqa: BLE001 - the exit stays clean; the raw file is kept
            self.log.error("internals log not closed: %r", exc)
        finally:
            self.gcs.close()
            self.plant.endpoint.close()

