"""fc/app.py - the flight-controller process: loops, glue between links, estimator and law.

Data flows one way per fast tick: sensor frame (fc/link.py) -> estimator (fc/estimator.py)
-> [slow loop: law.slow_step] -> law.fast_step -> surface command -> SERVO_OUTPUT_RAW.
Mode logic lives in fc/modes.py, the ground station in fc/gcs.py, parameters in fc/params.py,
time in fc/scheduler.py. The law (fc/control, docs/architecture.md section 11) is injected:
``law_module`` names a module exposing ``AttitudeLaw`` and ``LAW_PARAMS``.
"""
from __future__ import annotations

import gc
import importlib
import logging
import math
import os
import select
import time
from dataclasses import dataclass, field

import numpy as np

from fc.estimator import E_N, Estimator
from fc.gcs import GcsLink
from fc.guided import GuidanceRunner
from fc.internals_log import InternalsLog
from fc.intake import FrameIntake
from fc.mission import Mission
from fc.mission_mode import MissionFlight
from fc.iothread import IoThread
from fc.link import (M_N, PlantLink, UdpEndpoint, deflection_to_pwm, load_signing_key,
                     mavlink)
from fc.mode_control import ModeControl
from fc.modes import GUIDANCE_MODES, FlightMode, ModeManager
from fc.param_service import ParamService, load_param_file
from fc.params import ParamTable, build_table
from fc.scheduler import (FrameGate, LoopStats, TickPlanner, collect_garbage, freeze_heap,
                          hold_cpu_wakeup_latency, release_heap, sleep_until_ns,
                          try_realtime)
from fc.telemetry import FcCounters, Telemetry, TickOutput
from fc.timeline import Timeline, load_timeline

__all__ = ["FcConfig", "FlightController", "load_law_module"]

#: Real time: with no new plant frame for this long (wall clock, 5 frame periods at 500 Hz) the
#: law is not stepped and the last surface command is held until data comes back or FAILSAFE
#: takes over; stepping it on a frozen estimate winds it up (docs/reliability.md, promise 2).
HOLD_AFTER_S = 0.01

ML = mavlink


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
        startup_texts = load_param_file(self.params, params_path, self.log)
        overrides = {n: self.params.get(n) for n in law_names}
        self.law = law_cls(overrides)
        self.status_names = list(getattr(self.law, "STATUS_NAMES", ()))
        self._warm_up_law(law_cls, overrides)
        # the guidance (outer loop) of CRUISE/GUIDED (fc/guided.py), stepped from the fast tick
        self.guid = GuidanceRunner(self.params, cfg.fast_hz)
        self.guid.warm_up()
        # the stored mission (fc/mission.py, its protocol in fc/gcs.py) and MISSION mode
        self.mission = Mission()
        self.mission_flight = MissionFlight(self.mission)

        # --- state
        self.meas = np.zeros(M_N)
        self.meas_scratch = np.zeros(M_N)
        self.est = Estimator(self.params.get("EST_STALE_S"))
        # parameter changes after start-up, the process's own parameters in SI
        self.param_svc = ParamService(self.params, law_names, self.law, self.guid, self.est,
                                      params_path, self.log)
        self.settings = self.param_svc.settings
        self.out = TickOutput(self.settings.cmd_rad)
        self.pwm_us = self.out.pwm_us           # VehicleView (the same list)
        self.counters = FcCounters()
        self.modes = ModeManager()
        # real time: no new frame for longer than HOLD_AFTER_S (wall clock) -> the law is not
        # stepped on the frozen estimate (it would wind up); the last command is held
        self.law_held = False
        self.last_frame_wall_s = -1.0
        self._goodbyes_seen = 0
        self._chore = 0                 # which of the 1 Hz chores the next housekeeping does
        self._relocks_seen = 0

        # --- links and logs (bind last: READY means everything is in place)
        self.plant = PlantLink(UdpEndpoint(*cfg.plant_bind), plant_sysid=cfg.plant_sysid,
                               sysid=cfg.sysid, compid=cfg.compid)
        self.io = IoThread(self.log)
        self.gcs = GcsLink(self, cfg.gcs_bind, cfg.gcs, os.path.join(cfg.out, "fc.tlog"),
                           signing_key=key, log=self.log, io=self.io,
                           sim_time=cfg.mode == "lockstep")
        if key is not None:
            self.log.info("MAVLink 2 signing enabled on the GCS link (key from %s)",
                          cfg.signing_key_file)
        self.mode_ctl = ModeControl(self.modes, self.params, self.settings, self.law, self.guid,
                                    self.est, self.meas, self.planner, self.plant,
                                    self.gcs.announce_param, self._event, self.log)
        self.intake = FrameIntake(self.meas, self.meas_scratch, self.est, self.mode_ctl,
                                  self.planner, cfg.mode == "lockstep", self.counters,
                                  Timeline(commands) if commands is not None else None,
                                  self.set_param, self.gcs.announce_param, self._event)
        self.telemetry = Telemetry(self.out, self.counters, self.est, self.modes, self.plant,
                                   self.gcs, self.stats, self.planner, self.gate, self.law,
                                   self.status_names, self.guid)
        self.ilog = InternalsLog(cfg.out, self.telemetry.columns())
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

    # ------------------------------------------------------------------ parameters
    def set_param(self, name: str, value: float) -> str | None:
        """Validate and apply one parameter (GCS, timeline). None on success, else the reason."""
        reason = self.param_svc.set(name, value)
        if reason is None and name == "GUID_INNER_CO" and self.modes.mode in GUIDANCE_MODES:
            self.mode_ctl.resync()           # re-sync CO_ENABLE (and reset the law)
        return reason

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
        return self.mode_ctl.request_mode(mode)

    def arm(self, armed: bool) -> tuple[bool, str]:
        return self.mode_ctl.arm(armed)

    def set_guidance_targets(self, h_m: float | None = None, chi_rad: float | None = None,
                             V_m_s: float | None = None) -> str | None:
        """Targets of the guidance (altitude m AMSL, course rad, airspeed m/s; None keeps one),
        validated against the envelope (GT_ALT_*, GT_SPD_*, GE_QBAR_*); the guidance clips
        what it flies by its own envelope limits. None on success, else the reason. GUIDED's
        ground-station commands and the mission manager call it."""
        reason = self.guid.set_targets(h_m, chi_rad, V_m_s)
        if reason is None:
            self.log.info("guidance targets: %.0f m, %.2f deg, %.1f m/s",
                          self.guid.targets()[0], math.degrees(self.guid.targets()[1]),
                          self.guid.targets()[2])
        return reason

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
    def _fast_tick(self, slow: bool) -> None:
        if self.modes.law_active and self.law_held:
            pass                        # hold the last command: no new data to act on
        elif self.modes.law_active and not self.mode_ctl.reset_pending:
            try:
                if self.guid.engaged:
                    if (self.guid.tick(self.est.est, self.meas)
                            and self.modes.mode == FlightMode.MISSION):
                        self.gcs.mission_send(self.mission_flight.tick(self))
                    self.out.cmd_active = self.guid.cmd_rad
                else:
                    self.out.cmd_active = self.settings.cmd_rad
                if slow:
                    self.law.slow_step(self.est.est, self.out.cmd_active, self.planner.slow_dt_s)
                self.law.fast_step(self.est.est, self.planner.fast_dt_s)
                self.out.delta_rad[:] = self.law.delta_cmd_rad
            except Exception as exc:  # noqa: BLE001 - a law fault must not stop the outputs
                self.counters.law_errors += 1
                self.log.exception("law raised: %r", exc)
                self.mode_ctl.law_fault()
                self.out.delta_rad[:] = self.settings.trim_rad
        else:
            self.out.delta_rad[:] = self.settings.trim_rad
        d = self.out.delta_rad
        self.pwm_us[0] = deflection_to_pwm(d[0])
        self.pwm_us[1] = deflection_to_pwm(d[1])
        self.pwm_us[2] = deflection_to_pwm(d[2])
        # throttle only while the guidance flies (its last command held with the law); 0 = no
        # output otherwise (the plant keeps its throttle): the attitude modes' bytes unchanged
        self.pwm_us[3] = self.guid.throttle_pwm() if self.modes.guidance_active else 0

    def _event(self, text: str, severity: int = ML.MAV_SEVERITY_NOTICE) -> None:
        self.gcs.statustext(severity, text)

    # ------------------------------------------------------------------ housekeeping
    def _housekeeping(self, now_s: float) -> None:
        """Ground station, failsafe, 1 Hz chores. Bounded work per call."""
        self.gcs.poll(now_s)
        if self.plant.counters.goodbyes != self._goodbyes_seen:
            self._plant_said_goodbye()
        self.mode_ctl.check_data(now_s)
        if self.plant.counters.relocks != self._relocks_seen:
            self._relocks_seen = self.plant.counters.relocks
            self._event(f"plant link: new plant address {self.plant.peer[0]}:{self.plant.peer[1]}",
                        ML.MAV_SEVERITY_WARNING)
        if now_s >= self._next_1hz:
            # the 1 Hz chores, one per housekeeping call (each after a tick's answer has gone),
            # so no single call delays the next frame's tick by their sum
            stage = self._chore
            if stage == 0:
                self.stats.roll()
                self.counters.roll_load(self.planner.period_ns)
            elif stage == 1:
                t_gc = time.perf_counter_ns()
                collect_garbage()
                self.counters.gc_us = (time.perf_counter_ns() - t_gc) * 1e-3
            elif stage == 2:
                self.telemetry.refresh()
            else:
                self.gcs.flush()
                values = self.param_svc.snapshot()
                if values is not None:
                    self.io.submit(self.param_svc.save, values)
            if stage == 3:
                self._chore = 0
                self._next_1hz = now_s + 1.0
            else:
                self._chore = stage + 1
        self.gcs.service(now_s)

    def _plant_said_goodbye(self) -> None:
        """The plant ended its run on purpose (docs/wire.md section 5): the silence that
        follows is not a loss of plant data, so no FAILSAFE and no warning; the next plant
        may come from a new address. A frame arriving later clears ``plant.ended``."""
        self._goodbyes_seen = self.plant.counters.goodbyes
        self.plant.relock_allowed = True
        text = f"plant ended its run at t={self.meas[0]:.3f} s"
        self.log.info(text)
        self.gcs.statustext(ML.MAV_SEVERITY_INFO, text)

    # telemetry sources for fc/gcs.py
    @property
    def meas_stamp_us(self) -> int:
        """Plant time of the newest frame, us."""
        return self.intake.stamp_us

    def health_failed_bits(self) -> int:
        return self.mode_ctl.health_failed_bits()

    def load_permille(self) -> int:
        return self.counters.load_permille

    def error_counts(self) -> tuple[int, int, int, int, int]:
        return self.telemetry.error_counts()

    def named_values(self) -> list:
        return self.telemetry.named_values()

    def debug_vectors(self) -> list:
        return self.telemetry.debug_vectors()

    def throttle_percent(self) -> int:
        return self.telemetry.throttle_percent()

    def nav_controller_output(self):
        return self.telemetry.nav_controller_output()

    # ------------------------------------------------------------------ loops
    def run(self, stop) -> None:
        self._next_1hz = 0.0
        if gc.isenabled():              # python -m fc froze it before READY
            self.log.info(freeze_heap())
        try:
            if self.cfg.mode == "realtime":
                if self.cfg.realtime_priority > 0:
                    ok, msg = try_realtime(self.cfg.realtime_priority)
                    (self.log.info if ok else self.log.warning)(msg)
                self._run_realtime(stop)
            else:
                # each lockstep exchange wakes an idle CPU; keep wake-ups off the hypervisor's
                # path (docs/performance.md: idle vCPUs halt on this VM, a round trip triples)
                self.log.info(hold_cpu_wakeup_latency(0))
                self._run_lockstep(stop)
        finally:
            release_heap()      # automatic collection back on (an embedding process goes on)

    def _run_lockstep(self, stop) -> None:
        plant_fd = self.plant.endpoint.fileno()
        gcs_fd = self.gcs.endpoint.fileno()
        fds = [plant_fd, gcs_fd]
        mono = time.monotonic
        while not stop():
            # select() takes microsecond timeouts (no ms rounding); it only bounds idle waits
            try:
                select.select(fds, [], [], 0.01)
            except InterruptedError:
                pass
            now_s = mono()
            for _ in range(16):   # frames per wake-up: bounded
                stamp = self.plant.read_frame(self.meas_scratch)
                if stamp < 0:
                    break
                t0 = time.perf_counter_ns()
                self._lockstep_frame(stamp, mono())     # the arrival time, for the failsafe
                self.counters.add_exec(time.perf_counter_ns() - t0)
            self._housekeeping(now_s)

    def _lockstep_frame(self, stamp: int, now_s: float) -> None:
        t_exec = time.perf_counter_ns()
        if not self.intake.take(stamp, now_s):
            # the plant re-sent frame k (re-request): answer again with the same output
            self.plant.send_servo(stamp, self.pwm_us)
            return
        self.mode_ctl.sync()
        n = self.planner.due(stamp * 1000)
        for _ in range(n):
            self._fast_tick(self.planner.slow_due())
        self.plant.send_servo(stamp, self.pwm_us)
        if n:
            self.telemetry.log_row(self.ilog, self.meas, self.intake.stamp_us, 0,
                                   time.perf_counter_ns() - t_exec)

    def _run_realtime(self, stop) -> None:
        if self.cfg.sync == "frame":
            self._run_realtime_frame(stop)
        else:
            self._run_realtime_clock(stop)

    def _run_realtime_clock(self, stop) -> None:
        """Free-running clock (``--sync clock``): ticks on absolute deadlines ``t0 + k T``,
        each answering the newest frame; the answer's delay is the phase between the fc's
        clock and the plant's (docs/fc.md)."""
        planner = self.planner
        planner.anchor(time.monotonic_ns() + planner.period_ns)
        spin_ns = self.cfg.spin_us * 1000
        mono_ns = time.monotonic_ns
        while not stop():
            deadline = planner.next_ns
            sleep_until_ns(deadline, spin_ns)
            wake = mono_ns()
            planner.due(wake)
            self._rt_drain(wake * 1e-9)
            self._rt_tick(wake, wake - deadline)

    def _run_realtime_frame(self, stop) -> None:
        """Frame-synchronised (``--sync frame``, the default): the fast tick runs when a new
        sensor frame arrives, the deadline standing in when a frame is late or missing
        (:class:`fc.scheduler.FrameGate`). Waits are ``select`` on the plant socket with a
        microsecond timeout; with ``--spin-us`` the last microseconds before the expected
        frame are polled instead. Lateness of a frame tick = wake-up time minus the kernel's
        receive stamp of the frame (``SO_TIMESTAMPNS``); of a deadline tick = wake-up time minus
        the deadline."""
        gate = self.gate
        spin_ns = self.cfg.spin_us * 1000
        mono_ns = time.monotonic_ns
        wall_ns = time.time_ns
        sel = select.select
        fds = [self.plant.endpoint.fileno()]
        stamped = self.plant.endpoint.enable_rx_timestamps()
        gate.start(mono_ns())
        while not stop():
            until = gate.wait_until_ns()
            now = mono_ns()
            if now < until:
                sleep_to = until - spin_ns if spin_ns else until
                try:
                    ready = sel(fds, [], [], (sleep_to - now) * 1e-9) if sleep_to > now else ()
                    if not ready and spin_ns:
                        while not ready and mono_ns() < until:
                            ready = sel(fds, [], [], 0.0)[0]
                except InterruptedError:
                    continue
            wake = mono_ns()
            wake_wall = wall_ns()
            n_new, rx_ns = self._rt_drain(wake * 1e-9)
            if n_new:
                if not gate.on_frame(wake):
                    continue                    # early frame: absorbed, tick at the deadline
                lateness = wake_wall - rx_ns if (stamped and rx_ns) else 0
            elif wake < until:
                continue                        # woken by a duplicate or rejected datagram
            else:
                gate.on_timeout(wake)
                lateness = wake - until
            self._rt_tick(wake, lateness)

    def _rt_drain(self, now_s: float) -> tuple[int, int]:
        """Read every waiting frame through the estimator, in arrival order. Returns (new
        frames, kernel receive stamp of the first of them, ns)."""
        n_new = 0
        first_rx_ns = 0
        for _ in range(64):   # bounded work per wake-up
            stamp = self.plant.read_frame(self.meas_scratch)
            if stamp < 0:
                break
            if not self.intake.take(stamp, now_s):
                continue
            if n_new == 0:
                first_rx_ns = self.plant.frame_rx_ns
            n_new += 1
            self.last_frame_wall_s = now_s
            self.law_held = False
        return n_new, first_rx_ns

    def _rt_tick(self, wake_ns: int, lateness_ns: int) -> None:
        """One real-time fast tick (woken at ``wake_ns``), its answer and the housekeeping."""
        now_s = wake_ns * 1e-9
        have_frame = self.last_frame_wall_s >= 0.0
        if (have_frame and not self.law_held and self.modes.law_active
                and now_s - self.last_frame_wall_s > HOLD_AFTER_S):
            self.law_held = True
            self.counters.law_holds += 1
        self.mode_ctl.sync()
        self._fast_tick(self.planner.slow_due())
        if have_frame:
            self.plant.send_servo(self.intake.stamp_us, self.pwm_us)
        exec_ns = time.monotonic_ns() - wake_ns
        self.stats.record(lateness_ns, exec_ns)
        self.counters.add_exec(exec_ns)
        self.telemetry.log_row(self.ilog, self.meas, self.intake.stamp_us, lateness_ns, exec_ns)
        self._housekeeping(now_s)

    # ------------------------------------------------------------------ shutdown
    def close(self) -> None:
        """Flush and close logs and sockets (SIGINT/SIGTERM path)."""
        self.io.close()
        if self.param_svc.dirty:
            self.param_svc.save()
        c = self.plant.counters
        self.log.info(
            "exit: frames %d, outputs %d, duplicates %d, relocks %d, rejected plant %d "
            "(sysid %d, addr %d, bad %d, incomplete %d), gcs bad %d, gcs unsigned %d, "
            "late ticks %d/%d, overruns %d, skipped %d, law errors %d",
            c.frames, c.outputs, self.counters.duplicate_frames, c.relocks, c.rejected, c.rejected_sysid,
            c.rejected_addr, c.rejected_bad, c.rejected_incomplete, self.gcs.rejected_bad,
            self.gcs.rejected_signing, self.stats.late, self.stats.ticks, self.stats.overruns,
            self.telemetry.skipped_ticks(), self.counters.law_errors)
        if self.cfg.mode == "realtime" and self.cfg.sync == "frame":
            g = self.gate
            self.log.info("frame-synchronised ticks: on a frame %d, on the deadline after an "
                          "early frame %d, fallback (no frame) %d; early frames absorbed %d",
                          g.frame_ticks, g.grid_ticks, g.fallback_ticks, g.absorbed)
        try:
            path = self.ilog.close()
            self.log.info("internals log: %s (%d rows, %d dropped)", path, self.ilog.rows,
                          self.ilog.dropped)
        finally:
            self.gcs.close()
            self.plant.endpoint.close()

