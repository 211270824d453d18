"""fc/loops.py - the flight controller's run loops and housekeeping.

One part of the flight controller (docs/architecture.md, the fc's parts; docs/fc.md, timing).
:class:`RunLoops` runs one of three loops until told to stop: lockstep (a tick per plant
frame, answered with that frame's stamp), real time frame-synchronised (``--sync frame``, a
tick per sensor frame, the deadline standing in for a late one) or real time on a free clock
(``--sync clock``). Every loop reads frames through the one frame intake (fc/intake.py), steps
the controller's fast tick (a callable: the law and guidance step of fc/app.py) and then the
:class:`Housekeeping` (ground station, failsafe check, 1 Hz chores), bounded work per call.
"""
from __future__ import annotations

import gc
import logging
import select
import time
from dataclasses import dataclass
from typing import Callable

from fc.fused import EXCHANGE_DONE, EXCHANGE_VERDICT, FUSED_DONE, FUSED_TICKS, FusedFrame
from fc.gcs import GcsLink
from fc.intake import FrameIntake
from fc.internals_log import InternalsLog
from fc.iothread import IoThread
from fc.link import FRAME_AT, FRAME_BIG, FRAME_NONE, PlantLink
from fc.link import mavlink as ML
from fc.mode_control import ModeControl
from fc.modes import ModeManager
from fc.param_service import ParamService
from fc.scheduler import (FrameGate, LoopStats, TickPlanner, collect_garbage, freeze_heap,
                          garbage_due, hold_cpu_wakeup_latency, release_heap, sleep_until_ns,
                          try_realtime)
from fc.storage import DiskHealth
from fc.telemetry import FcCounters, Telemetry, TickOutput

__all__ = ["FC_STALL_S", "GCS_POLL_S", "HOLD_AFTER_S", "Housekeeping", "RunLoops"]

#: Real time: with no new plant frame for this long (wall clock, 5 frame periods at 500 Hz) the
#: law is not stepped and the last surface command is held until data comes back or FAILSAFE
#: takes over; stepping it on a frozen estimate winds it up (docs/reliability.md, promise 2).
HOLD_AFTER_S = 0.01
#: Real time: the loops wait on the plant socket only, so the ground-station socket is read
#: (a non-blocking ``recvfrom``) at most this often (wall clock, s), and on every call while
#: the previous read found datagrams (a burst is drained at the tick rate). A ground station
#: is served within 2.5 frames at 500 Hz; lockstep reads it when its ``select`` says so.
GCS_POLL_S = 0.005
#: The fc's own loop stopped for longer than this (wall clock between two passes: the process
#: was not scheduled, stopped, or blocked) is a stall: counted (FC_STALLS), logged in fc.log
#: and said by STATUSTEXT (WARNING; at most one per STALL_TEXT_EVERY_S, with the count).
FC_STALL_S = 0.2
STALL_TEXT_EVERY_S = 5.0


@dataclass
class Housekeeping:
    """Ground station, failsafe, 1 Hz chores; called after each tick's answer has gone."""

    gcs: GcsLink
    plant: PlantLink
    intake: FrameIntake
    mode_ctl: ModeControl
    stats: LoopStats
    planner: TickPlanner
    counters: FcCounters
    telemetry: Telemetry
    param_svc: ParamService
    io: IoThread
    event: Callable[[str, int], None]
    log: logging.Logger
    #: disk faults, said once per minute (fc/storage.py)
    disk: DiskHealth | None = None
    #: small state files saved at 1 Hz when changed: (snapshot() -> data or None, save(data)),
    #: the snapshot taken in the loop, the save run on the I/O thread (signing, mission)
    savers: tuple = ()
    goodbyes_seen: int = 0
    relocks_seen: int = 0
    gnss_dropped_seen: int = 0      # plant.counters.gnss_rejected already reported
    chore: int = 0                  # which of the 1 Hz chores the next call does
    next_1hz: float = 0.0           # wall clock of the next round of 1 Hz chores
    next_gcs_poll: float = 0.0      # wall clock of the next GCS read when readiness is unknown
    next_stall_text: float = 0.0    # wall clock before which a stall is logged but not said

    def fc_stalled(self, gap_s: float, now_s: float) -> None:
        """The loop did not run for ``gap_s`` (wall clock) before ``now_s``: count it, log it,
        say it (rate-limited STATUSTEXT). In real time the plant flew on its own meanwhile (it
        holds the last command after its no-command time, docs/reliability.md)."""
        c = self.counters
        c.fc_stalls += 1
        c.fc_stall_max_s = max(c.fc_stall_max_s, gap_s)
        text = (f"fc stalled {gap_s:.2f} s: no tick ran (stall {c.fc_stalls}, "
                f"plant t={self.intake.meas[0]:.3f} s)")
        self.log.warning(text)
        if now_s >= self.next_stall_text:
            self.next_stall_text = now_s + STALL_TEXT_EVERY_S
            self.event(text, ML.MAV_SEVERITY_WARNING)

    def __call__(self, now_s: float, gcs_ready: bool | None = None) -> None:
        """Ground station, failsafe, 1 Hz chores. Bounded work per call.

        ``gcs_ready``: whether the caller's ``select`` found the GCS socket readable (lockstep);
        None when the caller does not wait on it (real time): then the socket is read at most
        every GCS_POLL_S, and on every call while the last read found datagrams."""
        if gcs_ready is None:
            if now_s >= self.next_gcs_poll:
                self.next_gcs_poll = now_s if self.gcs.poll(now_s) else now_s + GCS_POLL_S
        elif gcs_ready:
            self.gcs.poll(now_s)
        if self.plant.counters.goodbyes != self.goodbyes_seen:
            self._plant_said_goodbye()
        self.mode_ctl.check_data(now_s)
        if self.plant.counters.relocks != self.relocks_seen:
            self.relocks_seen = self.plant.counters.relocks
            self.event(f"plant link: new plant address {self.plant.peer[0]}:{self.plant.peer[1]}",
                       ML.MAV_SEVERITY_WARNING)
        if now_s >= self.next_1hz:
            # the 1 Hz chores, one per housekeeping call (each after a tick's answer has gone),
            # so no single call delays the next frame's tick by their sum
            stage = self.chore
            if stage == 0:
                self.stats.roll()
                self.counters.roll_load(self.planner.period_ns)
            elif stage == 1:
                if garbage_due():               # (else gc_us keeps the last collection's time)
                    t_gc = time.perf_counter()      # (floats: no int per reading)
                    collect_garbage()
                    self.counters.gc_us = (time.perf_counter() - t_gc) * 1e6
            elif stage == 2:
                self.telemetry.refresh()
                self._report_gnss_drops()
            else:
                self.gcs.flush()
                values = self.param_svc.snapshot()
                if values is not None:
                    self.io.submit(self.param_svc.save, values)
                k = 0                   # (by index: a for loop makes an iterator object)
                while k < len(self.savers):
                    snapshot, save = self.savers[k]
                    data = snapshot()
                    if data is not None:
                        self.io.submit(save, data)
                    k += 1
                text = self.disk.report(now_s) if self.disk is not None else None
                if text is not None:
                    self.event(text, ML.MAV_SEVERITY_ERROR)
            if stage == 3:
                self.chore = 0
                self.next_1hz = now_s + 1.0
            else:
                self.chore = stage + 1
        self.gcs.service(now_s)

    def _report_gnss_drops(self) -> None:
        """GNSS samples the plant link dropped since the last report (non-finite or out of
        range, fc/link.py ``_store_gps``): one WARNING STATUSTEXT (mirrored to fc.log, and
        rate-limited there) per 1 Hz round that saw any; the total is telemetry's GNSS_DROP."""
        n = self.plant.counters.gnss_rejected
        if n != self.gnss_dropped_seen:
            new = n - self.gnss_dropped_seen
            self.gnss_dropped_seen = n
            self.event(f"GNSS: {new} samples dropped (out of range or not finite), {n} in all",
                       ML.MAV_SEVERITY_WARNING)

    def _plant_said_goodbye(self) -> None:
        """The plant ended its run on purpose (docs/wire.md section 5): the silence that
        follows is not a loss of plant data, so no FAILSAFE and no warning; the next plant
        may come from a new address. A frame arriving later clears ``plant.ended``."""
        self.goodbyes_seen = self.plant.counters.goodbyes
        self.plant.relock_allowed = True
        text = f"plant ended its run at t={self.intake.meas[0]:.3f} s"
        self.log.info(text)
        self.event(text, ML.MAV_SEVERITY_INFO)


@dataclass
class RunLoops:
    """The run loops (module docstring). ``tick(slow, held)`` is the controller's fast tick:
    ``slow`` steps the slow loop too, ``held`` holds the last command (no new data)."""

    mode: str                       # lockstep | realtime
    sync: str                       # realtime: frame | clock
    spin_us: int
    realtime_priority: int
    plant: PlantLink
    gcs: GcsLink
    intake: FrameIntake
    planner: TickPlanner
    gate: FrameGate
    stats: LoopStats
    counters: FcCounters
    telemetry: Telemetry
    ilog: InternalsLog
    modes: ModeManager
    mode_ctl: ModeControl
    out: TickOutput
    tick: Callable[[bool, bool], None]
    housekeeping: Housekeeping
    log: logging.Logger
    # real time: no new frame for longer than HOLD_AFTER_S (wall clock) -> the law is not
    # stepped on the frozen estimate (it would wind up); the last command is held
    law_held: bool = False
    last_frame_wall_s: float = -1.0
    last_pass_wall_s: float = -1.0  # wall clock of the loop's previous pass (stall check)
    #: lockstep: the frame in one compiled call when it may (fc/fused.py ``FusedFrame``)
    fused: FusedFrame | None = None

    def _check_stall(self, now_s: float) -> None:
        """A pass of the loop at ``now_s``: a stall if the previous one was FC_STALL_S ago."""
        if self.last_pass_wall_s >= 0.0 and now_s - self.last_pass_wall_s > FC_STALL_S:
            self.housekeeping.fc_stalled(now_s - self.last_pass_wall_s, now_s)
        self.last_pass_wall_s = now_s

    def run(self, stop: Callable[[], bool]) -> None:
        """Loop until ``stop()`` returns True."""
        if gc.isenabled():              # python -m fc froze it before READY
            self.log.info(freeze_heap())
        try:
            if self.mode == "realtime":
                if self.realtime_priority > 0:
                    ok, msg = try_realtime(self.realtime_priority)
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
        pc = time.perf_counter      # a float: no int per frame (floats come from a free list)
        while not stop():
            # select() takes microsecond timeouts (no ms rounding); it only bounds idle waits.
            # It also says whether the GCS socket has datagrams: read it only then (a read
            # that finds nothing costs 2.5 us, docs/performance.md)
            try:
                ready = select.select(fds, [], [], 0.01)[0]
            except InterruptedError:
                ready = fds                 # unknown: read both
            gcs_ready = gcs_fd in ready
            now_s = mono()
            self._check_stall(now_s)
            # one frame per wake-up, read only when select says a datagram waits: the plant
            # sends frame k+1 only after our answer to k, so reading on after a frame would
            # find nothing (a failed receive per exchange, issue 24); frames that did arrive
            # together are taken one per wake-up, select returning at once. Housekeeping
            # follows every frame: the .tlog's sim-paced streams fall due on a frame's stamp,
            # so the log does not depend on how the frames were batched.
            if plant_fd in ready:
                fused = self.fused
                if fused is not None and fused.ready_rx():
                    # the receive and the frame in one compiled call (fc/fused.py); what it
                    # does not take comes back as read_frame_at's code or the intake's verdict
                    t0 = pc()
                    code = fused.exchange(t0, pc)
                    if code != FRAME_NONE:
                        if code != EXCHANGE_DONE:
                            self.lockstep_rest(code, mono())
                        self.counters.add_exec((pc() - t0) * 1e9)
                else:
                    code = self.plant.read_frame_at(self.intake.scratch)
                    if code >= 0:
                        t0 = pc()
                        self.lockstep_exchange(code, mono())   # the arrival, for the failsafe
                        self.counters.add_exec((pc() - t0) * 1e9)
            self.housekeeping(now_s, gcs_ready)

    def lockstep_rest(self, code: int, now_s: float) -> None:
        """The unfused rest of a ``FusedFrame.exchange`` that answered ``code``: a frame read
        (FRAME_AT, FRAME_BIG) as :meth:`lockstep_exchange`, or EXCHANGE_VERDICT + the intake's
        verdict from the verdict on."""
        if code >= EXCHANGE_VERDICT:
            self._frame_after_fused(code - EXCHANGE_VERDICT, now_s, time.perf_counter())
        else:
            self.lockstep_exchange(code, now_s)

    def lockstep_exchange(self, code: int, now_s: float) -> None:
        """The exchange of the frame ``PlantLink.read_frame_at`` read (``code`` FRAME_AT: its
        stamp in the link's cell; FRAME_BIG: a stamp beyond the cells, a faulty plant's u64,
        in ``big_stamp``), arrived at ``now_s`` (wall clock)."""
        if code == FRAME_AT:
            self.lockstep_frame_at(now_s)
        elif code == FRAME_BIG:
            self.lockstep_frame(self.plant.big_stamp, now_s)

    def lockstep_frame(self, stamp: int, now_s: float) -> None:
        """One lockstep exchange: the frame in ``intake.scratch`` stamped ``stamp`` (us),
        arrived at ``now_s`` (wall clock): the ticks its stamp makes due, one answer.
        :meth:`lockstep_frame_at` for a stamp given as a Python int (any u64)."""
        t_exec = time.perf_counter()
        if not self.intake.take(stamp, now_s):
            # the plant re-sent frame k (re-request): answer again with the same output
            self.plant.send_servo(stamp, self.out.pwm_us)
            return
        if self.modes.changes != self.mode_ctl.changes_seen:    # cheap check first
            self.mode_ctl.sync()
        n = self._run_ticks(self.planner.due_us(stamp))
        self.plant.send_servo(stamp, self.out.pwm_us)
        if n:
            self.telemetry.log_row(self.ilog, self.intake.meas, self.intake.stamp_us, 0,
                                   (time.perf_counter() - t_exec) * 1e9, now_s)

    def lockstep_frame_at(self, now_s: float) -> None:
        """:meth:`lockstep_frame` of the frame whose stamp is in the plant link's int64 cell
        (``PlantLink.read_frame_at`` answered FRAME_AT): the intake, the planner, the answer
        and the internals row read it there in their compiled calls. Allocates no Python
        object (issue 24): the clock is read as floats, the ticks counted down without a
        range."""
        t_exec = time.perf_counter()
        fused = self.fused
        if fused is not None and fused.ready():
            # the common case in one compiled call; back here from the intake's verdict for
            # a repeat or a restart (fc/fused.py)
            verdict = fused.step(now_s, t_exec, time.perf_counter)
            if verdict != FUSED_DONE:
                self._frame_after_fused(verdict, now_s, t_exec)
            return
        at = self.plant.stamp_cell_at
        if not self.intake.take_at(at, now_s):
            self.plant.send_servo_at(self.out.pwm_us)   # a re-sent frame: the same answer
            return
        self._frame_taken_at(now_s, t_exec)

    def _frame_after_fused(self, code: int, now_s: float, t_exec: float) -> None:
        """The rest of a frame the fused step gave back with ``code`` (not FUSED_DONE):
        FUSED_TICKS (taken, a guidance step due: its ticks on) or the intake's verdict."""
        if code == FUSED_TICKS:
            if self.modes.changes != self.mode_ctl.changes_seen:
                self.mode_ctl.sync()
            self._answer_at(self._run_ticks(self.fused.ticks), now_s, t_exec)
        else:
            self._frame_after_verdict(code, now_s, t_exec)

    def _frame_after_verdict(self, verdict: int, now_s: float, t_exec: float) -> None:
        """:meth:`lockstep_frame_at` after the intake's ``verdict`` on the frame (the fused
        step gave it back: not INTAKE_NEW)."""
        if not self.intake.after_verdict(verdict, now_s):
            self.plant.send_servo_at(self.out.pwm_us)   # a re-sent frame: the same answer
            return
        self._frame_taken_at(now_s, t_exec)

    def _frame_taken_at(self, now_s: float, t_exec: float) -> None:
        """:meth:`lockstep_frame_at` once the intake took the frame: ticks, answer, row."""
        if self.modes.changes != self.mode_ctl.changes_seen:
            self.mode_ctl.sync()
        self._answer_at(self._run_ticks(self.planner.due_at(self.plant.stamp_cell_at)), now_s,
                        t_exec)

    def _answer_at(self, n: int, now_s: float, t_exec: float) -> None:
        """After the ``n`` ticks of the frame in the link's stamp cell: the answer, the row."""
        self.plant.send_servo_at(self.out.pwm_us)
        if n:
            self.telemetry.log_row_at(self.ilog, self.intake.meas, self.plant.stamp_cell_at, 0,
                                      (time.perf_counter() - t_exec) * 1e9, now_s)

    def _run_ticks(self, n: int) -> int:
        """The ``n`` fast ticks a frame's stamp made due, each with its slow step when due.
        Returns ``n``."""
        k = n
        while k:
            self.tick(self.planner.slow_due(), False)
            k -= 1
        return n

    def _run_realtime(self, stop) -> None:
        if self.sync == "frame":
            self._run_realtime_frame(stop)
        else:
            self._run_realtime_clock(stop)

    def _run_realtime_clock(self, stop) -> None:
        """Free-running clock (``--sync clock``): ticks on absolute deadlines ``t0 + k T``,
        each answering the newest frame; the answer's delay is the phase between the fc's
        clock and the plant's (docs/fc.md)."""
        planner = self.planner
        planner.anchor(time.monotonic_ns() + planner.period_ns)
        spin_ns = self.spin_us * 1000
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
        spin_ns = self.spin_us * 1000
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
            stamp = self.plant.read_frame(self.intake.scratch)
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
        self._check_stall(now_s)
        have_frame = self.last_frame_wall_s >= 0.0
        if (have_frame and not self.law_held and self.modes.law_active
                and now_s - self.last_frame_wall_s > HOLD_AFTER_S):
            self.law_held = True
            self.counters.law_holds += 1
        if self.modes.changes != self.mode_ctl.changes_seen:    # cheap check first
            self.mode_ctl.sync()
        self.tick(self.planner.slow_due(), self.law_held)
        if have_frame:
            self.plant.send_servo(self.intake.stamp_us, self.out.pwm_us)
        exec_ns = time.monotonic_ns() - wake_ns
        self.stats.record(lateness_ns, exec_ns)
        self.counters.add_exec(exec_ns)
        self.telemetry.log_row(self.ilog, self.intake.meas, self.intake.stamp_us, lateness_ns,
                               exec_ns, now_s)
        self.housekeeping(now_s)
