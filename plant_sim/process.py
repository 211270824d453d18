"""The plant process: lockstep and real-time frame loops over the MAVLink link.

Lockstep (docs/wire.md section 4): for frame k at t_k the plant measures, sends the sensor
datagram (stamp t_k in us), waits for the SERVO_OUTPUT_RAW echoing t_k mod 2^32 (re-sending
the same datagram every ``rerequest_timeout_s`` and counting it; answers with another stamp
are counted as stale and ignored), latches the command, logs the truth row at t_k and
advances one frame. No wall clock enters the physics: the same seed gives bit-identical
truth.

Real time: frame k is due at wall time t0 + k T (absolute deadlines; select() waits with
microsecond timeouts while receiving, then a busy poll for the last 200 us). At each deadline the plant applies the newest servo
command it has (newest by stamp), measures, sends, logs and advances. If no command has been
accepted for ``no_command_s`` (or none yet) it applies the scenario's ``servo.no_command``:
``hold`` keeps the commands' recent mean (:data:`HOLD_TAU_S`; the last command before any
came), ``trim`` goes to the initial-state trim, either with the backup damper of the
``servo.backup_*`` gains on the plant's own rates and sideslip (plant_sim/hold.py); such
frames are counted. A frame more than one period late counts as late; more than 50 periods behind, the
schedule is re-based on the current time (counted as a resync) instead of bursting.
"""
from __future__ import annotations

import contextlib
import gc
import itertools
import json
import logging
import math
import signal
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from hyfc_wire.numba_cache import cache_report
from hyfc_wire.pwm import PwmMap
from plant_sim import dynamics as dy
from plant_sim.frame_path import (B_CLIP, B_ENCODE_REFUSED, B_FLUSH, B_SEND_FAILED, FAST_IO,
                                  MODE_DECODE, MODE_FRAME, MODE_RECV, MODE_WAIT, R_FALLBACK,
                                  R_NONE, R_STALE, FramePath, lockstep_frame_p)
from plant_sim.frame_path import warm_up as frame_path_warm_up
from plant_sim.hold import HOLD_TAU_S, SilentHold  # noqa: F401  (HOLD_TAU_S: also here)
from plant_sim.link import PlantLink
from plant_sim.scenario import Scenario
from plant_sim.sim import PlantSim
from plant_sim.trim import trim_report
from plant_sim.truthlog import TruthWriter

U32 = 1 << 32
DEG = math.pi / 180.0
MODE_IN = MODE_WAIT | MODE_RECV | MODE_DECODE      # the lockstep's answer, without sending
SPIN_S = 200e-6      # real time: busy-poll the last 200 us before a frame deadline


@dataclass
class RunConfig:
    mode: str = "lockstep"
    fc_addr: tuple = ("127.0.0.1", 14560)
    bind_addr: tuple = ("127.0.0.1", 14561)
    out_dir: Path = Path("runs")
    duration_s: float = 20.0              # sim time to run; 0: open-ended, until SIGINT/SIGTERM
    seed: int = 1
    sysid: int = 2
    fc_sysid: int = 1
    rerequest_timeout_s: float = 0.1
    give_up_s: float = 120.0
    progress_every_s: float = 1.0
    quiet: bool = False
    #: truth log (plant_sim/truthlog.py): every frame for this long (s of sim time), then
    #: ``truth_tail_hz`` rows per second; None: every frame however long the run
    truth_full_rate_s: float | None = 60.0
    truth_tail_hz: float = 50.0
    #: lockstep: each frame in one compiled call (plant_sim/frame_path.py); False: the Python
    #: path (the reference; the same outputs)
    compiled_frame: bool = True


@dataclass
class RunStats:
    frames: int = 0
    rerequests: int = 0
    stale_commands: int = 0
    no_command_frames: int = 0
    no_command_episodes: int = 0      # real time: silences of the fc after it had answered
    late_frames: int = 0
    resyncs: int = 0
    aero_clip_frames: int = 0
    wall_time_s: float = 0.0
    exit_reason: str = "completed"
    extra: dict = field(default_factory=dict)


def truth_decimation(cfg: RunConfig, frame_dt_s: float) -> dict:
    """TruthWriter's ``full_rows`` and ``every`` for ``cfg`` at frames of ``frame_dt_s`` s."""
    if cfg.truth_full_rate_s is None:
        return {"full_rows": None, "every": 1}
    frame_hz = 1.0 / frame_dt_s
    return {"full_rows": int(round(cfg.truth_full_rate_s * frame_hz)),
            "every": max(1, int(round(frame_hz / cfg.truth_tail_hz)))}


class _Stop:
    def __init__(self):
        self.requested = False
        self.signal_name = ""

    def __call__(self, signum, frame):
        self.requested = True
        self.signal_name = signal.Signals(signum).name


def run(sc: Scenario, cfg: RunConfig, log: logging.Logger) -> RunStats:
    """Run one scenario over the link; returns the statistics (also written as JSON)."""
    out = Path(cfg.out_dir)
    sim = PlantSim(sc, seed=cfg.seed)
    stats = RunStats()
    t_warm = time.perf_counter()
    sim.warm_up()       # the numba kernels loaded (or compiled) before the first frame is due
    if cfg.mode == "lockstep" and cfg.compiled_frame:
        frame_path_warm_up()
    log.info(cache_report(("plant_sim",), time.perf_counter() - t_warm))

    text, ok = trim_report(sc)
    for line in text.splitlines():
        log.info("trim: %s", line)
    if not ok:
        msg = (f"WARNING: scenario {sc.name} cannot be trimmed within the surface limits "
               f"(python -m plant_sim trim --scenario {sc.path})")
        print(msg, file=sys.stderr, flush=True)
        log.warning(msg)
    stats.extra["trim_ok"] = bool(ok)

    sv = sc.data["servo"]
    pwm = PwmMap(sv["pwm_min_us"], sv["pwm_trim_us"], sv["pwm_max_us"], sim.p[dy.P_ACT_LIMIT])
    link = PlantLink(cfg.fc_addr, cfg.bind_addr, pwm, sysid=cfg.sysid, fc_sysid=cfg.fc_sysid)
    link.cmd_rad[:] = list(sim.trim_rad)
    log.info("link: plant %s:%d -> fc %s:%d (sysid %d, fc sysid %d), mode %s",
             link.local_addr[0], link.local_addr[1], link.fc_addr[0], link.fc_addr[1],
             cfg.sysid, cfg.fc_sysid, cfg.mode)
    writer = TruthWriter(out, sim.TRUTH_NAMES, **truth_decimation(cfg, sim.frame_dt_s))
    stop = _Stop()
    old = {s: signal.signal(s, stop) for s in (signal.SIGINT, signal.SIGTERM)}
    # None: open-ended; nothing below is sized by the requested duration
    n_frames = int(round(cfg.duration_s / sim.frame_dt_s)) if cfg.duration_s > 0 else None
    t_wall0 = time.perf_counter()
    try:
        with gc_off_schedule():
            if cfg.mode == "lockstep":
                _lockstep(sim, link, writer, cfg, stats, stop, n_frames, log)
            else:
                _realtime(sim, link, writer, cfg, stats, stop, n_frames, sc, log)
        # the final state, measured but not sent
        if stats.exit_reason == "completed":
            sim.truth_row(writer.row(keep=True))     # t_end: the state and its measurement
        # a planned end (complete or stopped by a signal, not a failure): say so before the
        # logs are written, so the fc does not take the silence for a loss of plant data
        stats.extra["goodbye_sent"] = link.send_goodbye()
    finally:
        stats.wall_time_s = time.perf_counter() - t_wall0
        for s, h in old.items():
            signal.signal(s, h)
        writer.close()
        link.close()
        if stop.requested and stats.exit_reason == "completed":
            stats.exit_reason = f"stopped by {stop.signal_name}"
        stats.aero_clip_frames = sim.clip_frames
        lat = stats.extra.pop("lateness", None)
        if lat is not None and lat.n:
            stats.extra.update(lateness_us_p50=lat.percentile_us(50),
                               lateness_us_p99=lat.percentile_us(99),
                               lateness_us_max=lat.max_s * 1e6)
        summary = {
            "scenario": sc.name,
            "mode": cfg.mode,
            "seed": cfg.seed,
            "open_ended": n_frames is None,
            "sim_time_s": sim.t_s,
            "wall_time_s": stats.wall_time_s,
            "real_time_factor": sim.t_s / stats.wall_time_s if stats.wall_time_s > 0 else 0.0,
            "frames": stats.frames,
            "frame_hz": 1.0 / sim.frame_dt_s,
            "physics_hz": 1.0 / sim.physics_dt_s,
            "rerequests": stats.rerequests,
            "stale_commands": stats.stale_commands,
            "no_command_frames": stats.no_command_frames,
            "no_command_episodes": stats.no_command_episodes,
            "late_frames": stats.late_frames,
            "resyncs": stats.resyncs,
            "aero_clip_frames": stats.aero_clip_frames,
            "truth_rows": writer.rows,
            "truth_rows_decimated": writer.decimated,
            "gnss_samples": sim.gnss.samples,
            "exit_reason": stats.exit_reason,
            **stats.extra,
            **link.counters(),
        }
        (out / "plant_summary.json").write_text(json.dumps(summary, indent=2) + "\n")
        log.info("summary: %s", json.dumps(summary))
    return stats


def _warn_clip(sim, stats, log):
    """Say once when the run first leaves the aerodynamic data's validity (docs/plant.md s. 3)."""
    from plant_sim.aero import CLIP_ALPHA, CLIP_DEFLECTION, CLIP_MACH
    f = int(sim.x[dy.X_CLIP])
    what = [n for b, n in ((CLIP_ALPHA, "alpha outside 0..12 deg"), (CLIP_MACH, "Mach outside 4..24"),
                           (CLIP_DEFLECTION, "deflection beyond 20 deg")) if f & b]
    t = sim.t_s - sim.frame_dt_s
    stats.extra["aero_clip_first_t_s"] = t
    msg = (f"WARNING: aerodynamic inputs clipped to the fits' validity from t={t:.3f} s "
           f"({', '.join(what)}); frames counted in plant_summary.json aero_clip_frames")
    print(msg, file=sys.stderr, flush=True)
    log.warning(msg)


def _progress(cfg, sim, t_wall0, now):
    """``PROGRESS t_s=... rtf=...``: sim time over the wall time since the run began at
    ``t_wall0`` (perf_counter s; never a re-based schedule)."""
    el = now - t_wall0
    rtf = sim.t_s / el if el > 0 else 0.0
    print(f"PROGRESS t_s={sim.t_s:.3f} rtf={rtf:.1f}", flush=True)


@contextlib.contextmanager
def gc_off_schedule():
    """The garbage collector off the frame schedule: start-up objects frozen (never scanned
    again), automatic passes off (0.1-1 ms each, wherever an allocation crosses a threshold);
    the loops collect once a second right after a frame has gone (as the fc does,
    docs/performance.md). Restored on exit."""
    gc.collect()
    gc.freeze()
    gc.disable()
    try:
        yield
    finally:
        gc.unfreeze()
        gc.enable()


def _lockstep(sim, link, writer, cfg, stats, stop, n_frames, log):
    """The lockstep loop: the compiled frame path (plant_sim/frame_path.py) when the link
    frames lean and libc's calls compile, else the Python path (the same outputs)."""
    if cfg.compiled_frame and link.lean and FAST_IO:
        return _lockstep_compiled(sim, link, writer, cfg, stats, stop, n_frames, log)
    return _lockstep_python(sim, link, writer, cfg, stats, stop, n_frames, log)


def _lockstep_compiled(sim, link, writer, cfg, stats, stop, n_frames, log):
    """``_lockstep_python`` with each frame in one compiled call (``lockstep_frame_p``: receive,
    decode, latch, truth row, physics, sensors, frame and send the next frame's datagram).
    Python takes what the call hands back: waiting, datagrams the compiled decoder rejects
    (the codec's parser, as before), re-requests, GNSS frames, truth blocks to flush, the
    clip warning, the end of the run."""
    meas = sim.last_meas
    frame_dt = sim.frame_dt_s
    timeout = cfg.rerequest_timeout_s
    perf = time.perf_counter
    x = sim.x
    gnss = sim.gnss
    tmax = float(sim.p[dy.P_TMAX])
    thr_scale = 100.0 / tmax if tmax > 0 else 0.0
    fp = FramePath(sim, link, writer, thr_scale)
    step = lockstep_frame_p
    a = fp.addr
    wait_ms = math.ceil(timeout * 1e3)     # poll()'s wait for the answer, ms
    t_wall0 = perf()
    next_progress = t_wall0 + cfg.progress_every_s if cfg.progress_every_s > 0 else math.inf
    next_gc = t_wall0 + 1.0
    last = n_frames - 1 if n_frames is not None else -1
    sim.measure(meas)
    # frame 0's datagram from Python; each compiled frame k then sends frame k+1's
    link.build_sensors(0, meas, x[dy.X_THRUST] * thr_scale, gnss.update(0, x))
    gnss_next = gnss.next_event(1)
    link.send_sensors()
    fp.enter()
    try:
        for k in range(n_frames) if n_frames is not None else itertools.count():
            if stop.requested:            # also when the fc answers every frame at once
                stats.exit_reason = f"stopped by {stop.signal_name}"
                return
            k1 = k + 1
            # frame k+1 in Python when it has a GNSS event, none after the last frame
            mode = MODE_IN if k1 >= gnss_next or k == last else MODE_FRAME
            t_sent = perf()
            t_first = t_sent
            r = step(a, k, mode, wait_ms)        # waits (poll) for the answer, runs the frame
            while True:
                while r < R_NONE:                        # drain as PlantLink._drain does
                    if r == R_STALE:
                        stats.stale_commands += 1
                    elif r == R_FALLBACK:                # the codec's general parser
                        want = int(round(k * frame_dt * 1e6)) % U32
                        fp.leave()
                        acc, match = link.parse_rx(fp.rx_len(), want)
                        if match:                        # the drain went on after such a match
                            acc += link.poll_for(want)[0]
                            c = link.cmd_rad
                            x[dy.X_CMD_L] = c[0]
                            x[dy.X_CMD_L + 1] = c[1]
                            x[dy.X_CMD_L + 2] = c[2]
                            if link.cmd_throttle >= 0.0:
                                x[dy.X_CMD_THR] = link.cmd_throttle
                        fp.enter()
                        if match:
                            stats.stale_commands += acc - 1
                            r = step(a, k, mode & ~MODE_IN, 0)
                            break
                        stats.stale_commands += acc
                    r = step(a, k, mode & ~MODE_WAIT, 0)  # the next datagram, no wait
                if r >= 0:
                    break
                # nothing (more) waiting: the wait timed out, a signal came, or the drain is done
                if stop.requested:
                    stats.exit_reason = f"stopped by {stop.signal_name}"
                    return
                now = perf()
                if now >= t_sent + timeout:
                    if now - t_first > cfg.give_up_s:
                        stats.exit_reason = (f"no SERVO_OUTPUT_RAW answering frame {k} "
                                             f"(t={k * frame_dt:.3f} s) for {cfg.give_up_s} s")
                        raise _Fatal(stats.exit_reason)
                    fp.leave()
                    link.send_sensors()
                    fp.enter()
                    stats.rerequests += 1
                    t_sent = now
                r = step(a, k, mode, max(0, math.ceil((t_sent + timeout - perf()) * 1e3)))
            stats.frames = k1
            if r:
                if r & B_FLUSH:
                    fp.flush_truth()
                if r & B_CLIP and "aero_clip_first_t_s" not in stats.extra:
                    _warn_clip(sim, stats, log)
                if r & (B_ENCODE_REFUSED | B_SEND_FAILED):
                    fp.leave()
                    if r & B_ENCODE_REFUSED:             # the Python framer (raises, as before)
                        link.build_sensors(int(round(k1 * frame_dt * 1e6)), meas,
                                           x[dy.X_THRUST] * thr_scale, None)
                    link.send_sensors()
                    fp.enter()
            if mode != MODE_FRAME and k != last and not stop.requested:
                fp.leave()
                link.build_sensors(int(round(k1 * frame_dt * 1e6)), meas,
                                   x[dy.X_THRUST] * thr_scale, gnss.update(k1, x))
                gnss_next = gnss.next_event(k1 + 1)
                link.send_sensors()
                fp.enter()
            if k & 63 == 0:
                now = perf()
                if now >= next_gc:
                    gc.collect()
                    next_gc = now + 1.0
                if now >= next_progress:
                    _progress(cfg, sim, t_wall0, now)
                    next_progress = now + cfg.progress_every_s
    finally:
        fp.leave()


def _lockstep_python(sim, link, writer, cfg, stats, stop, n_frames, log):
    """The lockstep loop in Python (each frame: ``build_sensors``, ``send_sensors``,
    ``poll_for``, ``PlantSim.frame``): the reference of the compiled loop, and the path of a
    link that does not frame lean or of NUMBA_DISABLE_JIT."""
    meas = sim.last_meas
    cmd = np.zeros(3)
    frame_dt = sim.frame_dt_s
    timeout = cfg.rerequest_timeout_s
    perf = time.perf_counter
    x = sim.x
    gnss = sim.gnss
    tmax = float(sim.p[dy.P_TMAX])
    thr_scale = 100.0 / tmax if tmax > 0 else 0.0
    t_wall0 = perf()
    next_progress = t_wall0 + cfg.progress_every_s if cfg.progress_every_s > 0 else math.inf
    next_gc = t_wall0 + 1.0
    sim.measure(meas)
    for k in range(n_frames) if n_frames is not None else itertools.count():
        if stop.requested:            # also when the fc answers every frame at once
            stats.exit_reason = f"stopped by {stop.signal_name}"
            return
        stamp = int(round(k * frame_dt * 1e6))
        want = stamp % U32
        link.build_sensors(stamp, meas, x[dy.X_THRUST] * thr_scale, gnss.update(k, x))
        link.send_sensors()
        t_sent = perf()
        t_first = t_sent
        while True:
            link.wait_readable(t_sent + timeout - perf())
            acc, match = link.poll_for(want)
            if match:
                stats.stale_commands += acc - 1
                break
            stats.stale_commands += acc
            if stop.requested:
                stats.exit_reason = f"stopped by {stop.signal_name}"
                return
            now = perf()
            if now >= t_sent + timeout:
                if now - t_first > cfg.give_up_s:
                    stats.exit_reason = (f"no SERVO_OUTPUT_RAW answering frame {k} "
                                         f"(t={k * frame_dt:.3f} s) for {cfg.give_up_s} s")
                    raise _Fatal(stats.exit_reason)
                link.send_sensors()
                stats.rerequests += 1
                t_sent = now
        c = link.cmd_rad
        cmd[0] = c[0]
        cmd[1] = c[1]
        cmd[2] = c[2]
        if link.cmd_throttle >= 0.0:          # servo4 (engine model only; else ignored)
            x[dy.X_CMD_THR] = link.cmd_throttle
        if sim.frame(cmd, writer.row()) and "aero_clip_first_t_s" not in stats.extra:
            _warn_clip(sim, stats, log)
        stats.frames += 1
        if k & 63 == 0:
            now = perf()
            if now >= next_gc:
                gc.collect()
                next_gc = now + 1.0
            if now >= next_progress:
                _progress(cfg, sim, t_wall0, now)
                next_progress = now + cfg.progress_every_s


def _realtime(sim, link, writer, cfg, stats, stop, n_frames, sc, log):
    meas = sim.last_meas
    cmd = np.zeros(3)
    frame_dt = sim.frame_dt_s
    perf = time.perf_counter
    sv = sc.data["servo"]
    no_cmd_s = sv["no_command_s"]
    to_trim = sv["no_command"] == "trim"
    trim = sim.trim_rad.copy()
    if to_trim and not trim.any():
        from plant_sim.trim import trim_at
        ini = sc.data["initial"]
        trim[:] = trim_at(sc, ini["alpha_deg"] * DEG, ini["beta_deg"] * DEG).deflection_rad
    x = sim.x
    gnss = sim.gnss
    # the hold on a silent fc (plant_sim/hold.py): the commands' recent mean (not the last
    # command, which may be a transient: issue 22, a law answering late frames at -16 deg, held
    # for 1 s, departed) or the trim, with the backup damper on the plant's own rates
    hold = SilentHold(sv, trim, frame_dt)
    tmax = float(sim.p[dy.P_TMAX])
    thr_scale = 100.0 / tmax if tmax > 0 else 0.0
    t0 = perf()                # the schedule's base: re-based by a resync
    t_start = t0               # the run's start: the progress line's real-time factor
    next_progress = t0 + cfg.progress_every_s if cfg.progress_every_s > 0 else math.inf
    next_gc = t0 + 1.0
    last_cmd_wall = -math.inf
    silent = False
    engaged = False            # the hold's base fixed for the current silence
    last_count = 0
    k = 0
    base_k = 0
    lateness = LatenessHistogram()
    stats.extra["lateness"] = lateness            # summarised and removed by run()
    limit = n_frames if n_frames is not None else math.inf
    sim.measure(meas)
    while k < limit:
        if stop.requested:
            stats.exit_reason = f"stopped by {stop.signal_name}"
            return
        deadline = t0 + (k - base_k) * frame_dt
        while True:
            link.poll_latest()
            now = perf()
            rem = deadline - now
            if rem <= 0.0:
                break
            if rem > SPIN_S:
                link.wait_readable(rem - SPIN_S)     # select(): microsecond timeouts
            # within SPIN_S of the deadline: spin on the socket (timer slack and wake-up latency
            # are 50-100 us here, perf_anchors.md section 2)
        fresh = link.cmd_count != last_count       # a command arrived since the last frame
        if fresh:
            last_count = link.cmd_count
            if silent:
                silent = False
                log.info("servo commands back after %.2f s without (t=%.3f s)",
                         now - last_cmd_wall, k * frame_dt)
            last_cmd_wall = now
        late = now - deadline
        lateness.add(late)
        if late > frame_dt:
            stats.late_frames += 1
            if late > 50 * frame_dt:
                t0 = now
                base_k = k
                stats.resyncs += 1
        if now - last_cmd_wall > no_cmd_s:
            stats.no_command_frames += 1
            if not engaged:
                engaged = True                     # the base is fixed for the whole silence
                hold.engage(x[dy.X_CMD_L:dy.X_CMD_L + 3])
            if not silent and last_cmd_wall > -math.inf:
                silent = True                      # logged once per episode, not per frame
                stats.no_command_episodes += 1
                log.warning("no servo command for %.2f s (t=%.3f s): %s%s", now - last_cmd_wall,
                            k * frame_dt, "surfaces to trim" if to_trim
                            else "holding the commands' recent mean",
                            ", backup damper on" if hold.damping else "")
            hold.output(meas, cmd)
        else:
            engaged = False
            c = link.cmd_rad
            cmd[0] = c[0]
            cmd[1] = c[1]
            cmd[2] = c[2]
            if fresh:                              # the mean of the commands received
                hold.command_received(cmd)
            if link.cmd_throttle >= 0.0:      # servo4 (engine model only; else ignored)
                x[dy.X_CMD_THR] = link.cmd_throttle
        stamp = int(round(k * frame_dt * 1e6))
        link.build_sensors(stamp, meas, x[dy.X_THRUST] * thr_scale, gnss.update(k, x))
        link.send_sensors()
        if sim.frame(cmd, writer.row()) and "aero_clip_first_t_s" not in stats.extra:
            _warn_clip(sim, stats, log)
        stats.frames += 1
        k += 1
        if now >= next_gc:                         # after the frame went: 1 Hz, bounded
            gc.collect()
            next_gc = now + 1.0
        if now >= next_progress:
            _progress(cfg, sim, t_start, now)
            next_progress = now + cfg.progress_every_s


class LatenessHistogram:
    """Real-time frame lateness in fixed memory, whatever the length of the run: counts in
    1 us bins up to ``max_us`` (a later frame counts in the last bin) and the exact maximum.
    Percentiles are read to 1 us (the middle of the bin, never above the maximum); one that
    falls in the last bin (beyond ``max_us``) reads as the maximum."""

    def __init__(self, max_us: int = 100_000):
        self.counts = np.zeros(max_us + 1, dtype=np.int64)
        self.top_bin = max_us
        self.max_s = 0.0

    @property
    def n(self) -> int:
        return int(self.counts.sum())

    def add(self, late_s: float) -> None:
        """Count one frame ``late_s`` seconds after its deadline."""
        i = int(late_s * 1e6)
        self.counts[i if i < self.top_bin else self.top_bin] += 1
        if late_s > self.max_s:
            self.max_s = late_s

    def percentile_us(self, q: float) -> float:
        """The ``q``-th percentile (0..100) of the lateness, us."""
        cum = np.cumsum(self.counts)
        rank = max(1, math.ceil(q / 100.0 * int(cum[-1])))
        i = int(np.searchsorted(cum, rank))
        if i >= self.top_bin:
            return self.max_s * 1e6
        return min(i + 0.5, self.max_s * 1e6)


class _Fatal(RuntimeError):
    """A run cannot complete (message is the one-line reason)."""
