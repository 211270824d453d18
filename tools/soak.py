"""tools/soak.py - the real-time rig (plant + fc + impairment relay + ground station) and the soak run.

``Rig`` starts the controller and the plant as real processes on loopback UDP (free ports), the
seeded impairment relay of tools/linkimpair.py on the plant link, and a pymavlink ground
station that records everything the controller sends (STATUSTEXT, HEARTBEAT modes,
NAMED_VALUE_FLOAT counters, SYS_STATUS). The reliability tests (tests/test_reliability_*.py)
and the soak command below are built on it; every wait is bounded and every process is
stopped by ``Rig.close`` (SIGINT, then SIGKILL).

Soak (``python -m tools.soak``): flies the cruise scenario in CRUISE (the guidance holds
altitude, course and speed; ``--scenario paper --flight-mode COORDINATED`` for the paper's
step) in real time for ``--duration`` wall seconds with the plant link impaired (default: 5 % loss, 0-5 ms jitter, 1 % duplicates,
1 % reordering, both directions) and, optionally, a ground-station flood, then prints the
figures of docs/reliability.md: tracking error after settling (in CRUISE the hold figures of
tools/guided_hil.py: altitude, course, speed against the targets, the inner loop), late ticks per 1000, rejected
input counters, relay counters, failsafe entries, process exit codes.

    python -m tools.soak --duration 60 --flood-rate 2000 --seed 1 [--out DIR]
"""
from __future__ import annotations

import argparse
import json
import math
import os
import random
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from tools.linkimpair import Impairment, LinkImpair

ROOT = Path(__file__).resolve().parents[1]
READY_TIMEOUT_S = 120.0            # cold numba cache on a busy 2-core machine
PAPER_CMD_DEG = {"alpha": 5.0, "beta": 0.0, "mu": 4.0}

#: the impairment of promise 1 (docs/reliability.md)
PROMISE1_IMPAIRMENT = Impairment(loss=0.05, jitter_s=0.005, dup=0.01, reorder=0.01)


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def child_env() -> dict:
    env = dict(os.environ)
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    env["MAVLINK20"] = "1"
    return env


class Proc:
    """A child process in its own process group; stdout lines collected; bounded waits."""

    def __init__(self, name: str, argv: list[str], console: Path) -> None:
        self.name = name
        self.argv = argv
        self.lines: list[str] = []
        self.cv = threading.Condition()
        self.console_path = console
        self._console = open(console, "a", buffering=1)
        self._console.write("$ " + " ".join(argv) + "\n")
        self.proc = subprocess.Popen(argv, cwd=ROOT, env=child_env(), stdin=subprocess.DEVNULL,
                                     stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                     bufsize=1, start_new_session=True)
        self._t = threading.Thread(target=self._pump, daemon=True)
        self._t.start()

    def _pump(self) -> None:
        for line in self.proc.stdout:
            self._console.write(line)
            with self.cv:
                self.lines.append(line.rstrip("\n"))
                self.cv.notify_all()
        with self.cv:
            self.cv.notify_all()

    @property
    def pid(self) -> int:
        return self.proc.pid

    def wait_line(self, pred, timeout_s: float) -> str | None:
        """First output line satisfying ``pred`` (already seen or new), None at timeout/exit."""
        deadline = time.monotonic() + timeout_s
        i = 0
        with self.cv:
            while True:
                while i < len(self.lines):
                    if pred(self.lines[i]):
                        return self.lines[i]
                    i += 1
                left = deadline - time.monotonic()
                if left <= 0 or (self.proc.poll() is not None and not self._t.is_alive()):
                    return None
                self.cv.wait(min(left, 0.2))

    def wait_exit(self, timeout_s: float) -> int | None:
        try:
            return self.proc.wait(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            return None

    def stop(self, sig: int = signal.SIGINT, timeout_s: float = 15.0) -> int:
        """Signal the group, wait, escalate to SIGKILL. Returns the exit code."""
        if self.proc.poll() is None:
            try:
                os.killpg(self.proc.pid, sig)
            except ProcessLookupError:
                pass
            if self.wait_exit(timeout_s) is None:
                try:
                    os.killpg(self.proc.pid, signal.SIGKILL)
                except ProcessLookupError:
                    pass
                self.proc.wait(timeout=10)
        self._t.join(5)
        self._console.close()
        return self.proc.returncode

    def kill9(self) -> int:
        """SIGKILL the process itself (the crash of promise 3)."""
        self.proc.send_signal(signal.SIGKILL)
        self.proc.wait(timeout=10)
        return self.proc.returncode


class GroundStation:
    """A pymavlink ground station bound where the fc sends telemetry; records in a thread."""

    def __init__(self, port: int, sysid: int = 250, compid: int = 190,
                 key: bytes | None = None) -> None:
        os.environ["MAVLINK20"] = "1"
        from pymavlink import mavutil
        self.mavutil = mavutil
        self.conn = mavutil.mavlink_connection(f"udpin:127.0.0.1:{port}", source_system=sysid,
                                               source_component=compid, dialect="ardupilotmega")
        if key is not None:
            self.conn.setup_signing(key, sign_outgoing=True)
        self.cv = threading.Condition()
        self.msgs: list = []            # (monotonic time, message)
        self.named: dict[str, float] = {}
        self.texts: list[tuple[float, int, str]] = []
        self._stop = threading.Event()
        self._t = threading.Thread(target=self._run, daemon=True)
        self._t.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                m = self.conn.recv_match(blocking=True, timeout=0.1)
            except Exception:  # noqa: BLE001 - socket closed at shutdown
                if self._stop.is_set():
                    return
                continue
            if m is None:
                continue
            t = m.get_type()
            if t == "BAD_DATA":
                continue
            now = time.monotonic()
            with self.cv:
                if t == "NAMED_VALUE_FLOAT":
                    self.named[m.name] = m.value
                elif t == "STATUSTEXT":
                    self.texts.append((now, m.severity, m.text))
                if t not in ("ATTITUDE", "AOA_SSA", "VFR_HUD", "DEBUG_VECT", "SERVO_OUTPUT_RAW"):
                    self.msgs.append((now, m))
                    if len(self.msgs) > 20000:
                        del self.msgs[:10000]
                self.cv.notify_all()

    def wait(self, pred, timeout_s: float, since: float = 0.0):
        """First recorded message after ``since`` satisfying ``pred(m)``; None at timeout."""
        deadline = time.monotonic() + timeout_s
        with self.cv:
            while True:
                for t, m in self.msgs:
                    if t >= since and pred(m):
                        return m
                left = deadline - time.monotonic()
                if left <= 0:
                    return None
                self.cv.wait(min(left, 0.2))

    def find(self, pred, since: float = 0.0, until: float = math.inf):
        """First recorded message received in [since, until] satisfying ``pred`` (no wait)."""
        with self.cv:
            for t, m in self.msgs:
                if since <= t <= until and pred(m):
                    return m
        return None

    def wait_text(self, needle: str, timeout_s: float, since: float = 0.0) -> str | None:
        m = self.wait(lambda m: m.get_type() == "STATUSTEXT" and needle in m.text, timeout_s,
                      since)
        return None if m is None else m.text

    def wait_named(self, name: str, pred, timeout_s: float) -> float | None:
        """Wait until NAMED_VALUE_FLOAT ``name`` satisfies ``pred(value)``; returns the value."""
        deadline = time.monotonic() + timeout_s
        with self.cv:
            while True:
                v = self.named.get(name)
                if v is not None and pred(v):
                    return v
                left = deadline - time.monotonic()
                if left <= 0:
                    return None
                self.cv.wait(min(left, 0.2))

    def heartbeat_mode(self, timeout_s: float = 3.0, since: float = 0.0):
        m = self.wait(lambda m: m.get_type() == "HEARTBEAT" and m.get_srcSystem() == 1,
                      timeout_s, since)
        return None if m is None else m.custom_mode

    def command(self, command: int, *params: float, timeout_s: float = 5.0):
        p = list(params) + [0.0] * (7 - len(params))
        since = time.monotonic()
        self.conn.mav.command_long_send(1, 1, command, 0, *p)
        return self.wait(lambda m: m.get_type() == "COMMAND_ACK" and m.command == command,
                         timeout_s, since)

    def close(self) -> None:
        self._stop.set()
        self._t.join(2)
        self.conn.close()


@dataclass
class RigConfig:
    out: Path
    duration_s: float = 8.0              # plant sim time (real time: wall seconds)
    seed: int = 1
    scenario: str = "paper"
    impair_up: Impairment | None = None  # plant -> fc
    impair_down: Impairment | None = None
    relay: bool = True                   # a relay (clean if no impairment) on the plant link
    params: dict = field(default_factory=dict)
    fc_extra: tuple = ()
    plant_extra: tuple = ()
    signing_key_file: str | None = None
    timeline: tuple = ((0.0, 5.0, 0.0, 4.0),)   # (t_s, alpha, beta, mu) deg: the paper's step
    arm: str = "gcs"    # "gcs": armed by the ground station once plant data is valid;
                        # "start": --arm on the command line; "no": stays disarmed
    gcs_sysid: int = 250
    flight_mode: str = "COORDINATED"   # the mode it is armed in (CRUISE: the guidance)


class Rig:
    """fc (real time, armed COORDINATED, paper timeline) + relay + plant + ground station."""

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
        if self.cfg.params and not self.params_path.exists():
            self.params_path.write_text("".join(f"{k} {v!r}\n" for k, v in self.cfg.params.items()))

    def fc_argv(self) -> list[str]:
        c = self.cfg
        argv = [sys.executable, "-m", "fc", "--mode", "realtime",
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
                               + " | ".join(self.fc.lines[-5:]))
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
                "--mode", "realtime", "--fc", f"{self.plant_target[0]}:{self.plant_target[1]}",
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
            for ln in reversed(self.plant.lines):
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
        self.proc: subprocess.Popen | None = None
        self.sent: int | None = None

    def start(self) -> "Flood":
        self.proc = subprocess.Popen(self.argv, cwd=ROOT, env=child_env(),
                                     stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        return self

    def wait(self, timeout_s: float) -> int:
        try:
            out, err = self.proc.communicate(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            out, err = self.proc.communicate(timeout=5)
        for line in out.splitlines():
            if line.startswith("FLOOD sent="):
                self.sent = int(line.split("=")[1].split()[0])
        if self.sent is None:
            raise RuntimeError(f"flood did not report: rc={self.proc.returncode} {err[-500:]}")
        return self.sent

    def stop(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait(timeout=5)


def flood_main(target: tuple[str, int], rate_hz: float, duration_s: float, seed: int,
               sysid: int) -> int:
    """Send the flood mix; prints ``FLOOD sent=N seconds=S``. Never more than rate*duration."""
    os.environ["MAVLINK20"] = "1"
    from pymavlink.dialects.v20 import ardupilotmega as ml

    class _Null:
        def write(self, _b):
            return None

    mav = ml.MAVLink(_Null(), srcSystem=sysid, srcComponent=190)
    rng = random.Random(seed)

    def pk(msg):
        b = msg.pack(mav)
        mav.seq = (mav.seq + 1) % 256
        return b

    templates = [
        lambda: pk(mav.param_request_list_encode(1, 1)),
        lambda: pk(mav.command_long_encode(1, 1, ml.MAV_CMD_REQUEST_MESSAGE, 0,
                                           ml.MAVLINK_MSG_ID_AUTOPILOT_VERSION, 0, 0, 0, 0, 0, 0)),
        lambda: pk(mav.command_long_encode(1, 1, 31337, 0, 0, 0, 0, 0, 0, 0, 0)),
        lambda: pk(mav.param_set_encode(1, 1, b"NO_SUCH_PARAM", 1.0, 9)),
        lambda: bytes(rng.getrandbits(8) for _ in range(rng.randint(1, 120))),
        lambda: pk(mav.param_request_list_encode(1, 1))[:rng.randint(1, 8)],
    ]
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    n_total = int(rate_hz * duration_s)
    t0 = time.monotonic()
    sent = 0
    batch = max(1, int(rate_hz / 200))     # bursts every 5 ms
    while sent < n_total:
        due = t0 + sent / rate_hz
        now = time.monotonic()
        if due > now:
            time.sleep(due - now)   # pacing of a load generator, not a wait for an event
        for _ in range(min(batch, n_total - sent)):
            try:
                s.sendto(templates[rng.randrange(len(templates))](), target)
            except OSError:
                pass
            sent += 1
    print(f"FLOOD sent={sent} seconds={time.monotonic() - t0:.3f}", flush=True)
    return 0


# ---------------------------------------------------------------------- soak CLI
class _Say:
    """Progress lines on stderr (the figures go to stdout as JSON); silent if every_s <= 0."""

    def __init__(self, every_s: float):
        self.every_s = every_s

    def __call__(self, text: str) -> None:
        if self.every_s > 0:
            print(text, file=sys.stderr, flush=True)


def progress_line(rig: Rig, duration_s: float) -> str:
    """One line of a running soak: sim time, the fc's late ticks and rejected input (its
    NAMED_VALUE_FLOAT counters), FAILSAFE entries so far, what the relay dropped."""
    nv = rig.gcs.named
    with rig.gcs.cv:
        failsafes = sum(1 for _, _, t in rig.gcs.texts if "FAILSAFE" in t)
    dropped = sum(d.get("dropped", 0) for d in rig.relay.counters.values()) if rig.relay else 0
    return (f"soak: t = {rig.plant_time_now():7.1f} / {duration_s:g} s   late ticks "
            f"{nv.get('LATE_CNT', 0):.0f}   rejected gcs {nv.get('REJ_GCS', 0):.0f} plant "
            f"{nv.get('REJ_PLANT', 0):.0f}   failsafes {failsafes}   relay dropped {dropped}")


def watch_progress(rig: Rig, duration_s: float, say) -> None:
    """Until the plant has finished (bounded): a progress line every ``say.every_s`` s."""
    deadline = time.monotonic() + duration_s * 3 + 60
    every = say.every_s if say.every_s > 0 else 1.0
    while time.monotonic() < deadline:
        if rig.plant.wait_exit(min(every, max(0.0, deadline - time.monotonic()))) is not None:
            return
        say(progress_line(rig, duration_s))


def soak(args) -> int:
    out = Path(args.out or tempfile.mkdtemp(prefix="hyfc-soak-"))
    imp = Impairment(loss=args.loss, jitter_s=args.jitter_ms * 1e-3, dup=args.dup,
                     reorder=args.reorder)
    guided = args.flight_mode != "COORDINATED"
    cfg = RigConfig(out=out, duration_s=args.duration, seed=args.seed, impair_up=imp,
                    impair_down=imp, scenario=args.scenario, flight_mode=args.flight_mode,
                    params={"REF_PF_EN": 1.0} if guided else {})
    fig: dict = {"duration_s": args.duration, "seed": args.seed, "impairment": imp.__dict__,
                 "scenario": args.scenario, "flight_mode": args.flight_mode,
                 "flood_rate_hz": args.flood_rate, "out": str(out)}
    say = _Say(args.progress_every)
    say(f"soak: {args.duration:g} s in real time, seed {args.seed}, run directory {out}")
    with Rig(cfg) as rig:
        rig.start()
        say(f"soak: fc (pid {rig.fc.pid}) and plant (pid {rig.plant.pid}) flying, armed")
        flood = None
        if args.flood_rate > 0:
            rig.wait_plant_time(1.0, 60)
            flood = Flood(("127.0.0.1", rig.gcs_bind_port), args.flood_rate,
                          max(0.0, args.duration - 2.0), seed=args.seed).start()
            say(f"soak: ground-station flood started ({args.flood_rate:g} datagrams/s)")
        watch_progress(rig, args.duration, say)
        rcs = rig.finish()
        say(f"soak: done (exit codes plant {rcs['plant']}, fc {rcs['fc']}); figures follow")
        if flood is not None:
            fig["flood_sent"] = flood.wait(30)
        truth, internals = rig.truth(), rig.internals()
        fig["exit_codes"] = rcs
        if guided:
            from tools.guided_hil import hold_figures
            # after the engagement transient (10 s, or half of a shorter run)
            fig["hold_figures"] = hold_figures(truth, internals, min(10.0, 0.5 * args.duration))
        else:
            fig["tracking_error_deg_after_3s"] = tracking_error_deg(truth, 3.0)
        late, ticks = late_ticks(internals, t_from_s=1.0)
        fig["late_ticks"] = late
        fig["ticks"] = ticks
        fig["late_per_1000"] = 1000.0 * late / max(ticks, 1)
        fig["relay"] = rig.relay.counters
        ps = rig.plant_summary()
        fig["plant"] = {k: ps.get(k) for k in ("frames", "late_frames", "no_command_frames",
                                               "rejected_malformed", "rejected_source",
                                               "rejected_sysid", "real_time_factor")}
        fig["fc_named_values"] = {k: v for k, v in rig.gcs.named.items()
                                  if k in ("REJ_PLANT", "REJ_GCS", "REJ_SIGN", "LATE_CNT",
                                           "DUP_FRAMES", "FS_CAUSE", "SKIPPED", "OVERRUN")}
        fig["failsafe_texts"] = [t for _, _, t in rig.gcs.texts if "FAILSAFE" in t]
    print(json.dumps(fig, indent=2))
    ok = rcs["plant"] == 0 and rcs["fc"] == 0
    return 0 if ok else 1


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m tools.soak",
                                 description="Real-time soak: cruise scenario with an impaired "
                                             "plant link and a ground-station flood; prints the "
                                             "figures of docs/reliability.md as JSON.")
    sub = ap.add_subparsers(dest="cmd")
    f = sub.add_parser("flood", help="send a bounded ground-station flood (used by the soak)")
    f.add_argument("--target", required=True, metavar="HOST:PORT",
                   help="the fc's ground-station socket")
    f.add_argument("--rate", type=float, default=2000.0,
                   help="datagrams per second, up to 100000 (2000)")
    f.add_argument("--duration", type=float, default=5.0, help="seconds, up to 3600 (5)")
    f.add_argument("--seed", type=int, default=0, help="seed of the message mix (0)")
    f.add_argument("--sysid", type=int, default=251,
                   help="MAVLink system id the flood sends as (251)")
    for p in (ap,):
        p.add_argument("--duration", type=float, default=60.0, help="wall/sim seconds (60)")
        p.add_argument("--scenario", default="cruise", help="plant scenario (cruise)")
        p.add_argument("--flight-mode", choices=("CRUISE", "COORDINATED"), default="CRUISE",
                       help="CRUISE: the guidance holds the state at arming (default); "
                            "COORDINATED: the paper's attitude step (with --scenario paper)")
        p.add_argument("--seed", type=int, default=1,
                       help="seed of the plant and of the link impairment (1)")
        p.add_argument("--loss", type=float, default=0.05,
                       help="plant link: fraction of datagrams dropped, each way (0.05)")
        p.add_argument("--jitter-ms", type=float, default=5.0,
                       help="plant link: extra delay, uniform 0..J ms, each way (5)")
        p.add_argument("--dup", type=float, default=0.01,
                       help="plant link: fraction of datagrams duplicated (0.01)")
        p.add_argument("--reorder", type=float, default=0.01,
                       help="plant link: fraction of datagrams reordered (0.01)")
        p.add_argument("--flood-rate", type=float, default=2000.0,
                       help="ground-station datagrams per second, 0 = no flood (2000)")
        p.add_argument("--out", help="run directory (default: a new temp directory)")
        p.add_argument("--progress-every", type=float, default=5.0, metavar="S",
                       help="a progress line on stderr every S wall seconds, 0 = none (5)")
    args = ap.parse_args(argv)
    if args.cmd == "flood":
        from tools.linkimpair import parse_hostport
        if args.rate <= 0 or args.rate > 100000 or args.duration < 0 or args.duration > 3600:
            ap.error("--rate must be in (0, 100000] and --duration in [0, 3600]")
        return flood_main(parse_hostport(args.target), args.rate, args.duration, args.seed,
                          args.sysid)
    return soak(args)


if __name__ == "__main__":
    raise SystemExit(main())
