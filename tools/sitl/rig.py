"""The real-time rig (plant + fc + impairment relay + ground station) of the reliability tests,
the soak (``python -m tools.soak``) and the fuzz campaign.

``Rig`` starts the controller and the plant as real processes on loopback UDP (free ports), the
seeded impairment relay of tools/sitl/linkimpair.py on the plant link, and a pymavlink ground
station that records everything the controller sends (STATUSTEXT, HEARTBEAT modes,
NAMED_VALUE_FLOAT counters, SYS_STATUS). Every wait is bounded and every process is stopped by
``Rig.close`` (SIGINT, then SIGKILL). ``Flood`` runs ``python -m tools.soak flood`` as a child.

By default the rig flies the ``cruise`` scenario in CRUISE: the guidance holds the altitude,
course and speed at arming (Mach 7.5 at 28 km, a steady flight), with the law's reference
prefilter on (REF_PF_EN 1, as tools.hil in the guidance modes). ``steady_figures`` gives its
figures over a time window. ``scenario="paper", flight_mode="COORDINATED"`` flies the paper's
attitude step (``timeline``), with ``tracking_error_deg`` against its command.
"""
from __future__ import annotations

import json
import math
import os
import random
import signal
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from tools.sitl.linkimpair import Impairment, LinkImpair
from tools.sitl.gcs import ScriptedGcs
from tools.sitl.procs import Child, free_udp_port, repo_env

ROOT = Path(__file__).resolve().parents[2]
READY_TIMEOUT_S = 120.0            # cold numba cache on a busy 2-core machine
PAPER_CMD_DEG = {"alpha": 5.0, "beta": 0.0, "mu": 4.0}
GUIDANCE_MODES = ("CRUISE", "GUIDED", "MISSION")

#: the impairment of promise 1 (docs/reliability.md)
PROMISE1_IMPAIRMENT = Impairment(loss=0.05, jitter_s=0.005, dup=0.01, reorder=0.01)


def child_env() -> dict:
    """``repo_env`` with MAVLink 2 for pymavlink in the child."""
    return repo_env(MAVLINK20="1")


class Proc(Child):
    """A child of the rig (``tools.sitl.procs.Child``): cwd the repository, ``child_env()``,
    stderr merged into stdout, console appended; ``history`` holds the lines seen so far."""

    def __init__(self, name: str, argv: list[str], console: Path) -> None:
        super().__init__(name, argv, console, env=child_env(), cwd=str(ROOT), merge_stderr=True,
                         console_mode="a")

    def stop(self, sig: int = signal.SIGINT, timeout_s: float = 15.0) -> int:
        """Signal the group, wait, escalate to SIGKILL. Returns the exit code."""
        return super().stop(int_wait_s=timeout_s, term_wait_s=None, first_signal=sig)


class GroundStation(ScriptedGcs):
    """The rig's ground station: the scripted one (``tools.sitl.gcs.ScriptedGcs``) bound where
    the fc sends telemetry, recording everything, without heartbeats of its own."""

    def __init__(self, port: int, sysid: int = 250, compid: int = 190,
                 key: bytes | None = None) -> None:
        super().__init__("127.0.0.1", port, sysid=sysid, compid=compid, key=key,
                         heartbeat=False, record=True)


@dataclass
class RigConfig:
    out: Path
    duration_s: float = 8.0              # plant sim time (real time: wall seconds)
    seed: int = 1
    scenario: str = "cruise"
    impair_up: Impairment | None = None  # plant -> fc
    impair_down: Impairment | None = None
    relay: bool = True                   # a relay (clean if no impairment) on the plant link
    params: dict = field(default_factory=dict)
    fc_extra: tuple = ()
    plant_extra: tuple = ()
    signing_key_file: str | None = None
    timeline: tuple = ((0.0, 5.0, 0.0, 4.0),)   # (t_s, alpha, beta, mu) deg: the paper's step
                                                # (flown in COORDINATED/UNCOORDINATED only)
    arm: str = "gcs"    # "gcs": armed by the ground station once plant data is valid;
                        # "start": --arm on the command line; "no": stays disarmed
    gcs_sysid: int = 250
    flight_mode: str = "CRUISE"   # the mode it is armed in (CRUISE: the guidance holds the state)
    mode: str = "realtime"        # both processes' --mode: realtime | lockstep (the plant waits
                                  # for each answer: a cut link freezes sim time)

    def fc_params(self) -> dict:
        """``params`` with, when armed in a guidance mode, the reference prefilter on
        (REF_PF_EN 1) unless given: the guidance's 50 Hz commands are not steps to track
        (docs/guidance.md 2). Disarmed (``arm="no"``) the fc starts on its own file."""
        if (self.arm != "no" and self.flight_mode in GUIDANCE_MODES
                and "REF_PF_EN" not in self.params):
            return {"REF_PF_EN": 1.0, **self.params}
        return dict(self.params)


class Rig:
    """fc (real time, armed by the ground station in ``flight_mode``, by default CRUISE over the
    cruise scenario) + relay + plant + ground station."""

    def __init__(self, cfg: RigConfig) -> None:
        self.cfg = cfg
        self.out = Path(cfg.out)
        self.out.mkdir(parents=True, exist_ok=True)
        self.plant_port = free_udp_port()
        self.gcs_bind_port = free_udp_port()
        self.gcs_port = free_udp_port()
        self.plant_bind_port = free_udp_port()
        self.params_path = self.out / "params.parm"
        self.fc: Proc | None = None
        self.plant: Proc | None = None
        self.relay: LinkImpair | None = None
        self.gcs: GroundStation | None = None
        self.fc_runs = 0

    # ------------------------------------------------------------------ start
    def write_inputs(self) -> None:
        lines = []
        for t, a, b, m in self.cfg.timeline:
            lines += ["[[command]]", f"t_s = {t!r}", f"alpha_deg = {a!r}", f"beta_deg = {b!r}",
                      f"mu_deg = {m!r}", ""]
        (self.out / "timeline.toml").write_text("\n".join(lines))
        params = self.cfg.fc_params()
        if params and not self.params_path.exists():
            self.params_path.write_text("".join(f"{k} {v!r}\n" for k, v in params.items()))

    def fc_argv(self) -> list[str]:
        c = self.cfg
        argv = [sys.executable, "-m", "fc", "--mode", c.mode,
                "--plant-bind", f"127.0.0.1:{self.plant_port}",
                "--gcs-bind", f"127.0.0.1:{self.gcs_bind_port}",
                "--gcs", f"127.0.0.1:{self.gcs_port}",
                "--params", str(self.params_path), "--out", str(self.out / "fc"),
                "--timeline", str(self.out / "timeline.toml")]
        if c.arm in ("start", "gcs"):
            argv += ["--flight-mode", c.flight_mode]
        if c.arm == "start":
            argv += ["--arm"]
        if c.signing_key_file:
            argv += ["--signing-key-file", c.signing_key_file]
        return argv + list(c.fc_extra)

    def start_fc(self) -> Proc:
        self.fc_runs += 1
        (self.out / "fc").mkdir(exist_ok=True)
        self.fc = Proc("fc", self.fc_argv(), self.out / f"fc.console.{self.fc_runs}.log")
        if self.fc.wait_line(lambda s: s.strip() == "READY", READY_TIMEOUT_S) is None:
            rc = self.fc.stop(signal.SIGKILL)
            raise RuntimeError(f"fc did not print READY (rc={rc}); see {self.fc.console_path}: "
                               + " | ".join(self.fc.history[-5:]))
        return self.fc

    def start(self, plant: bool = True) -> "Rig":
        self.write_inputs()
        self.gcs = GroundStation(self.gcs_port, sysid=self.cfg.gcs_sysid)
        self.start_fc()
        # the ground station can talk once it has heard the fc (udpin replies to the sender)
        if self.gcs.heartbeat_mode(10.0) is None:
            raise RuntimeError("no HEARTBEAT from the fc within 10 s")
        target = ("127.0.0.1", self.plant_port)
        if self.cfg.relay:
            self.relay = LinkImpair(target, up=self.cfg.impair_up, down=self.cfg.impair_down,
                                    seed=self.cfg.seed).start()
            target = self.relay.listen_address
        self.plant_target = target
        if plant:
            self.start_plant()
            if self.cfg.arm == "gcs":
                self.arm_when_data_valid()
        return self

    def arm_when_data_valid(self, timeout_s: float = 60.0) -> float:
        """Arm from the ground station as soon as the fc accepts (valid plant data), as an
        operator does; the law then starts from a real estimate. Returns the wall time taken."""
        t0 = time.monotonic()
        while time.monotonic() - t0 < timeout_s:
            ack = self.gcs.command(400, 1.0, timeout_s=1.0)    # MAV_CMD_COMPONENT_ARM_DISARM
            if ack is not None and ack.result == 0:
                return time.monotonic() - t0
            if self.plant is not None and self.plant.proc.poll() is not None:
                break
            self.plant.wait_line(lambda s: False, 0.02) if self.plant else None
        raise RuntimeError("the fc did not accept ARM (no valid plant data?)")

    def start_plant(self) -> Proc:
        c = self.cfg
        argv = [sys.executable, "-m", "plant_sim", "run", "--scenario", c.scenario,
                "--mode", c.mode, "--fc", f"{self.plant_target[0]}:{self.plant_target[1]}",
                "--bind", f"127.0.0.1:{self.plant_bind_port}", "--out", str(self.out / "plant"),
                "--duration", repr(float(c.duration_s)), "--seed", str(c.seed),
                "--progress-every", "0.25", *c.plant_extra]
        self.plant = Proc("plant", argv, self.out / "plant.console.log")
        return self.plant

    def wait_plant_time(self, t_s: float, timeout_s: float) -> float | None:
        """Wait until the plant reports sim time >= t_s (PROGRESS lines)."""
        def ok(line):
            return line.startswith("PROGRESS") and _progress_t(line) >= t_s
        line = self.plant.wait_line(ok, timeout_s)
        return None if line is None else _progress_t(line)

    def plant_time_now(self) -> float:
        """The plant's latest reported sim time (its last PROGRESS line), 0 before any."""
        with self.plant.cv:
            for ln in reversed(self.plant.history):
                if ln.startswith("PROGRESS"):
                    return _progress_t(ln)
        return 0.0

    # ------------------------------------------------------------------ finish
    def finish(self, timeout_s: float | None = None, stop_plant: bool = False) -> dict:
        """Wait for the plant to complete (or stop it now with SIGINT, which is a clean end:
        it flushes its logs and exits 0), stop the fc (SIGINT), return the exit codes."""
        t = timeout_s if timeout_s is not None else self.cfg.duration_s * 3 + 60
        if stop_plant and self.plant is not None:
            self.plant.stop(signal.SIGINT)
        rc_plant = self.plant.wait_exit(t) if self.plant else None
        if rc_plant is None and self.plant is not None:
            rc_plant = self.plant.stop()
        rc_fc = self.fc.stop() if self.fc else None
        return {"plant": rc_plant, "fc": rc_fc}

    def close(self) -> None:
        for p in (self.plant, self.fc):
            if p is not None:
                try:
                    p.stop(timeout_s=10)
                except Exception:  # noqa: BLE001 - best effort at teardown
                    pass
        if self.relay is not None:
            self.relay.stop()
        if self.gcs is not None:
            self.gcs.close()

    def __enter__(self) -> "Rig":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # ------------------------------------------------------------------ results
    def truth(self) -> dict:
        from plant_sim.truthlog import load
        return load(str(self.out / "plant" / "truth.npz"))

    def internals(self) -> dict:
        from fc.internals_log import load
        return load(str(self.out / "fc" / "fc_internals.npz"))

    def plant_summary(self) -> dict:
        return json.loads((self.out / "plant" / "plant_summary.json").read_text())

    def fc_log(self) -> str:
        p = self.out / "fc" / "fc.log"
        return p.read_text(errors="replace") if p.exists() else ""


def _progress_t(line: str) -> float:
    try:
        return float(line.split("t_s=")[1].split()[0])
    except (IndexError, ValueError):
        return -1.0


def tracking_error_deg(truth: dict, t_from_s: float, cmd_deg: dict = PAPER_CMD_DEG) -> dict:
    """Max and RMS |truth - command| [deg] per channel for t >= t_from_s."""
    t = truth["t_s"]
    sel = t >= t_from_s
    out = {}
    for ch in ("alpha", "beta", "mu"):
        e = np.degrees(truth[f"{ch}_rad"][sel]) - cmd_deg[ch]
        out[ch] = {"max": float(np.max(np.abs(e))) if e.size else math.nan,
                   "rms": float(np.sqrt(np.mean(e * e))) if e.size else math.nan}
    return out


def time_window(log: dict, t0_s: float, t1_s: float = math.inf) -> dict:
    """The rows of a per-sample log (truth or fc internals: columns of one length, ``t_s``
    among them) with t0_s <= t_s < t1_s."""
    sel = (log["t_s"] >= t0_s) & (log["t_s"] < t1_s)
    return {k: v[sel] for k, v in log.items()}


def steady_figures(truth: dict, internals: dict, t0_s: float, t1_s: float = math.inf) -> dict:
    """The hold figures of a guided flight (``tools.sitl.metrics.hold_figures``: altitude, course
    and speed against the fc's targets, the inner loop against the guidance's command and the
    law's e1, surfaces at their limits, adaptive estimates) over t0_s <= t < t1_s."""
    from tools.sitl.metrics import hold_figures
    return hold_figures(time_window(truth, t0_s, t1_s), time_window(internals, t0_s, t1_s), t0_s)


#: bounds of a steady cruise flight under the reliability promises (docs/reliability.md):
#: altitude (m), course (deg), speed (m/s) against the fc's targets (the engagement's throttle
#: step dips the speed by about 2 m/s), the inner loop (alpha, beta, mu against the guidance's
#: command, deg: the attitude tolerance of the paper-scenario promises, room for a stalled
#: real-time tick on a loaded machine)
STEADY_BOUNDS = {"alt_err_max_m": 10.0, "course_err_max_deg": 0.1, "speed_err_max_m_s": 5.0,
                 "inner_cmd_err_max_deg": (1.0, 1.0, 1.5)}


def steady_violations(fig: dict, bounds: dict = STEADY_BOUNDS) -> list[str]:
    """The figures of ``steady_figures`` beyond ``bounds`` ([] if none; a NaN figure, as
    without a guidance target, is beyond), for an assertion message."""
    out = []
    for k, b in bounds.items():
        vals = fig[k] if isinstance(fig[k], list) else [fig[k]]
        lim = b if isinstance(b, tuple) else (b,) * len(vals)
        if not all(v <= m for v, m in zip(vals, lim)):
            out.append(f"{k} {vals} > {b}")
    return out


def late_ticks(internals: dict, period_s: float = 0.002, late_frac: float = 0.2,
               t_from_s: float = 0.0) -> tuple[int, int]:
    """(late ticks, ticks) of the fc's fast loop from its internals log (lateness_us column)."""
    lat = internals["lateness_us"]
    t = internals["t_s"]
    sel = t >= t_from_s
    lat = lat[sel]
    return int(np.sum(lat > period_s * late_frac * 1e6)), int(lat.size)


# ---------------------------------------------------------------------- flood
class Flood:
    """A ground-station flood at ``rate_hz`` datagrams/s for ``duration_s`` (bounded), loopback.

    Mix: PARAM_REQUEST_LIST, COMMAND_LONG (REQUEST_MESSAGE / unknown commands), PARAM_SET of an
    unknown name, random garbage and truncated frames; seeded. Runs in a separate process
    (``python -m tools.soak flood``) so the sender does not share the test's interpreter.
    """

    def __init__(self, target: tuple[str, int], rate_hz: float, duration_s: float,
                 seed: int = 0, sysid: int = 251) -> None:
        self.argv = [sys.executable, "-m", "tools.soak", "flood", "--target",
                     f"{target[0]}:{target[1]}", "--rate", repr(float(rate_hz)),
                     "--duration", repr(float(duration_s)), "--seed", str(seed),
                     "--sysid", str(sysid)]
        self.child: Child | None = None
        self.sent: int | None = None

    def start(self) -> "Flood":
        self.child = Child("flood", self.argv, None, env=child_env(), cwd=str(ROOT))
        return self

    def wait(self, timeout_s: float) -> int:
        """The number of datagrams sent (the child's ``FLOOD sent=N`` line); killed at the
        timeout."""
        if self.child.wait_exit(timeout_s) is None:
            self.stop()
        self.child.close()
        for line in self.child.history:
            if line.startswith("FLOOD sent="):
                self.sent = int(line.split("=")[1].split()[0])
        if self.sent is None:
            raise RuntimeError(f"flood did not report: {self.child.death_message()}")
        return self.sent

    def stop(self) -> None:
        if self.child is not None and self.child.poll() is None:
            self.child.stop(int_wait_s=0.0, term_wait_s=None, first_signal=signal.SIGKILL)


# ---------------------------------------------------------------------- plant stalls
class PlantStaller:
    """Random plant stalls (the soak's ``--stall-max``): the plant process is stopped (SIGSTOP)
    for a uniform 0.1..``max_s`` s at intervals uniform in 0.5..1.5 ``every_s``, seeded, then
    continued (SIGCONT, also on ``stop``). In real time a stopped plant does not advance its sim
    time (it re-bases its schedule on waking, plant_sim/process.py): a plant freeze, as a host
    that does not schedule it. ``stalls`` lists (wall time from start, seconds)."""

    def __init__(self, pid: int, max_s: float, every_s: float, seed: int = 0) -> None:
        self.pid = pid
        self.max_s = max_s
        self.every_s = every_s
        self.rng = random.Random(seed)
        self.stalls: list[tuple[float, float]] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="plant-staller", daemon=True)
        self._t0 = time.monotonic()

    def start(self) -> "PlantStaller":
        self._thread.start()
        return self

    def _run(self) -> None:
        while not self._stop.wait(self.rng.uniform(0.5, 1.5) * self.every_s):
            d = self.rng.uniform(0.1, self.max_s)
            try:
                os.kill(self.pid, signal.SIGSTOP)
            except ProcessLookupError:
                return
            try:
                self.stalls.append((time.monotonic() - self._t0, d))
                self._stop.wait(d)
            finally:
                try:
                    os.kill(self.pid, signal.SIGCONT)
                except ProcessLookupError:
                    return

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(self.max_s + 5.0)
        try:
            os.kill(self.pid, signal.SIGCONT)
        except ProcessLookupError:
            pass


def proc_usage(pid: int) -> tuple[int, int] | None:
    """(resident set size kB, open file descriptors) of a live process, from /proc; None if
    it is gone or /proc is not there."""
    try:
        with open(f"/proc/{pid}/status") as f:
            rss = next(int(ln.split()[1]) for ln in f if ln.startswith("VmRSS:"))
        return rss, len(os.listdir(f"/proc/{pid}/fd"))
    except (OSError, StopIteration, ValueError):
        return None
