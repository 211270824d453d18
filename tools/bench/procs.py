"""Two-process figures of tools.bench: lockstep, real time, start-up, memory.

Every run starts real processes on 127.0.0.1 with free ports, in their own process groups
(``tools.sitl.procs.Child``), and stops them in ``finally``:

- the fc: ``python -m fc`` (the real flight controller, armed in COORDINATED);
- the plant: ``python -m plant_sim run`` (lockstep real-time factor as the plant reports it in
  ``plant_summary.json``) and the measuring stand-in ``python -m tools.bench.standin``, which
  runs the same plant physics and also records per-frame send and echo times (the plant
  process does not), giving the sensor-to-servo latency measured at the plant;
- a ground station (:class:`GcsSink`, a thread in this process) that sends HEARTBEAT at 1 Hz,
  asks for every stream at ``GCS_STREAM_HZ`` and counts what the fc streams.

Wake-up lateness comes from the fc's own record: ``fc_internals.npz`` column ``lateness_us``
(one row per fast tick, wall clock in ``wall_s``), restricted to the ticks while the plant
streamed.
"""
from __future__ import annotations

import copy
import json
import os
import select
import shutil
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

from tools.sitl.procs import Child, free_udp_port

GCS_STREAM_HZ = 50          # REQUEST_DATA_STREAM rate asked by the benchmark's ground station
READY_TIMEOUT_S = 120.0     # a cold numba cache compiles for tens of seconds on a loaded machine
PY = sys.executable


def _rss_mb(pid: int) -> tuple[float, float]:
    """(current RSS, peak RSS = VmHWM) of ``pid`` in MB from /proc; NaN if gone."""
    cur = peak = float("nan")
    try:
        with open(f"/proc/{pid}/status", encoding="ascii") as f:
            for line in f:
                if line.startswith("VmRSS:"):
                    cur = int(line.split()[1]) / 1024.0
                elif line.startswith("VmHWM:"):
                    peak = int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return cur, peak


class RssSampler(threading.Thread):
    """Samples the RSS of some pids every ``every_s`` until ``stop()``."""

    def __init__(self, pids: dict, every_s: float = 0.25) -> None:
        super().__init__(daemon=True)
        self.pids = dict(pids)
        self.every_s = every_s
        self.samples = {name: [] for name in pids}   # (monotonic s, rss MB)
        self.peak = {name: float("nan") for name in pids}
        self._ev = threading.Event()

    def run(self) -> None:
        while not self._ev.wait(self.every_s):
            self.sample()

    def sample(self) -> None:
        now = time.monotonic()
        for name, pid in self.pids.items():
            cur, peak = _rss_mb(pid)
            if cur == cur:
                self.samples[name].append((now, cur))
                self.peak[name] = peak

    def stop(self) -> None:
        self._ev.set()
        self.join(timeout=2.0)
        self.sample()

    def growth(self, name: str, skip_frac: float = 0.2) -> dict:
        """RSS growth of ``name`` after the first ``skip_frac`` of the run (warm-up)."""
        s = self.samples.get(name) or []
        if len(s) < 4:
            return {"rss_growth_mb": float("nan"), "rss_growth_mb_per_min": float("nan"),
                    "window_s": 0.0}
        t = np.array([a for a, _ in s])
        r = np.array([b for _, b in s])
        i0 = int(len(s) * skip_frac)
        dt = t[-1] - t[i0]
        slope = np.polyfit(t[i0:] - t[i0], r[i0:], 1)[0] if dt > 0 else float("nan")
        return {"rss_growth_mb": float(r[-1] - r[i0]), "rss_growth_mb_per_min": float(slope * 60),
                "window_s": float(dt), "rss_start_mb": float(r[i0]), "rss_end_mb": float(r[-1])}


class GcsSink(threading.Thread):
    """A streaming ground station: heartbeat 1 Hz, REQUEST_DATA_STREAM(ALL), counts messages."""

    def __init__(self) -> None:
        super().__init__(daemon=True)
        from fc.link import decode_datagram, mavlink, new_codec
        self._ml = mavlink
        self._decode = decode_datagram
        self._rx = new_codec(255, 190)
        self._tx = new_codec(255, 190)
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(0.1)
        self.port = self.sock.getsockname()[1]
        self.fc_addr: tuple | None = None
        self.messages = 0
        self.bytes = 0
        self.t_first = None
        self.t_last = None
        self._ev = threading.Event()

    def _send(self, msg) -> None:
        if self.fc_addr is None:
            return
        try:
            self.sock.sendto(msg.pack(self._tx), self.fc_addr)
        except OSError:
            pass
        self._tx.seq = (self._tx.seq + 1) % 256

    def run(self) -> None:
        ml = self._ml
        next_hb = 0.0
        asked = 0.0
        while not self._ev.is_set():
            try:
                data, addr = self.sock.recvfrom(4096)
            except socket.timeout:
                data = None
            except OSError:
                data = None
            now = time.monotonic()
            if data:
                msgs, _ = self._decode(self._rx, data)
                if msgs:
                    if self.fc_addr is None:
                        self.fc_addr = addr
                    self.messages += len(msgs)
                    self.bytes += len(data)
                    self.t_first = self.t_first or now
                    self.t_last = now
            if self.fc_addr is not None and now >= next_hb:
                next_hb = now + 1.0
                self._send(self._tx.heartbeat_encode(ml.MAV_TYPE_GCS, ml.MAV_AUTOPILOT_INVALID,
                                                     0, 0, 0))
                if now - asked > 5.0:      # (re)ask: the fc may drop a silent peer
                    asked = now
                    self._send(self._tx.request_data_stream_encode(
                        1, 1, ml.MAV_DATA_STREAM_ALL, GCS_STREAM_HZ, 1))

    def stop(self) -> dict:
        self._ev.set()
        self.join(timeout=2.0)
        self.sock.close()
        span = (self.t_last - self.t_first) if self.t_first and self.t_last else 0.0
        return {"messages": self.messages, "msgs_per_s": self.messages / span if span else 0.0,
                "bytes_per_s": self.bytes / span if span else 0.0,
                "requested_hz": GCS_STREAM_HZ}


class Session:
    """A temporary directory plus the children started in it (all stopped by ``close``)."""

    def __init__(self, keep: str | None = None, tag: str = "bench") -> None:
        self.dir = Path(tempfile.mkdtemp(prefix=f"hyfc-{tag}-", dir=keep))
        self.keep = keep is not None
        self.children: list[Child] = []

    def start(self, name: str, argv: list[str], env: dict | None = None) -> Child:
        c = Child(name, argv, self.dir / f"{name}.console.txt", env=env)
        self.children.append(c)
        return c

    def close(self) -> None:
        for c in reversed(self.children):
            try:
                c.stop(int_wait_s=10.0, term_wait_s=5.0)
            except Exception:  # noqa: BLE001 - best effort: stop every child
                pass
        if not self.keep:
            shutil.rmtree(self.dir, ignore_errors=True)


def _fc_argv(out: Path, mode: str, fast_hz: float, plant_port: int, gcs_port: int) -> list[str]:
    return [PY, "-m", "fc", "--mode", mode, "--fast-hz", f"{fast_hz:g}", "--slow-hz", "100",
            "--plant-bind", f"127.0.0.1:{plant_port}", "--gcs", f"127.0.0.1:{gcs_port}",
            "--gcs-bind", f"127.0.0.1:{free_udp_port()}", "--arm", "--flight-mode", "COORDINATED",
            "--internals-full-rate", "--out", str(out)]


def _scenario_file(d: Path, frame_hz: float) -> Path:
    """The paper scenario at ``frame_hz`` frames (physics at least as fast), as a TOML file."""
    from plant_sim.scenario import load
    sc = copy.deepcopy(load("paper"))
    tm = sc.data["timing"]
    tm["frame_hz"] = float(frame_hz)
    tm["physics_hz"] = max(float(tm["physics_hz"]), float(frame_hz))
    path = d / f"paper_{int(frame_hz)}hz.toml"
    path.write_text(sc.to_toml())
    return path


def _wait_exit(child: Child, timeout_s: float) -> int:
    try:
        return child.proc.wait(timeout=timeout_s)
    except Exception as exc:  # subprocess.TimeoutExpired
        raise RuntimeError(f"{child.name} did not finish within {timeout_s:.0f} s "
                           f"(see {child.console_path})") from exc


def _pinned(argv: list[str], cpu: int | None) -> list[str]:
    """``argv`` run on CPU ``cpu`` only (util-linux taskset; unchanged if cpu is None)."""
    if cpu is None:
        return argv
    if shutil.which("taskset") is None:
        raise RuntimeError("taskset (util-linux) not found: cannot pin processes")
    return ["taskset", "-c", str(cpu)] + argv


def lockstep(fast_hz: float, sim_s: float, keep: str | None = None,
             real_plant: bool = True, standin_sim_s: float | None = None,
             pin_cpu: int | None = None, standin: bool = True) -> dict:
    """Lockstep fc + plant at ``fast_hz`` frames (one fast tick per frame).

    ``sim_s`` for the plant-process run, ``standin_sim_s`` (default ``sim_s``) for the
    measuring stand-in's run, whose fc RSS samples give the heap-growth figure.
    ``pin_cpu``: run both processes on that one CPU (a lockstep exchange is sequential).
    """
    standin_sim_s = sim_s if standin_sim_s is None else standin_sim_s
    out: dict = {"fast_hz": fast_hz, "sim_s": sim_s, "standin_sim_s": standin_sim_s,
                 "pin_cpu": pin_cpu}
    runs = [("standin", None)] if standin else []
    if real_plant and _have_plant_process():
        runs.insert(0, ("plant", None))
    if not runs:
        raise RuntimeError("no plant to run (plant_sim has no __main__ and standin=False)")
    for kind, _ in runs:
        s = Session(keep, f"lockstep{int(fast_hz)}-{kind}")
        try:
            port = free_udp_port()
            gcs = GcsSink()
            gcs.start()
            fc = s.start("fc", _pinned(_fc_argv(s.dir / "fc", "lockstep", fast_hz, port,
                                                gcs.port), pin_cpu))
            fc.wait_for_line("READY", READY_TIMEOUT_S)
            if kind == "plant":
                sc = _scenario_file(s.dir, fast_hz)
                pl = s.start("plant", _pinned(
                    [PY, "-m", "plant_sim", "run", "--scenario", str(sc), "--mode", "lockstep",
                     "--fc", f"127.0.0.1:{port}", "--bind", "127.0.0.1:0", "--out",
                     str(s.dir / "plant"), "--duration", f"{sim_s:g}", "--progress-every",
                     "1000"], pin_cpu))
            else:
                pl = s.start("standin", _pinned(
                    [PY, "-m", "tools.bench.standin", "--fc", f"127.0.0.1:{port}", "--mode",
                     "lockstep", "--frame-hz", f"{fast_hz:g}", "--duration",
                     f"{standin_sim_s:g}", "--out", str(s.dir / "standin.json")], pin_cpu))
            # 20 Hz: a quick stand-in run lasts well under a second of wall time
            rss = RssSampler({"fc": fc.pid, kind: pl.pid}, every_s=0.05)
            rss.start()
            rc = _wait_exit(pl, 60.0 + 10.0 * max(sim_s, standin_sim_s))
            rss.stop()
            gcs_res = gcs.stop()
            if rc != 0:
                raise RuntimeError(pl.death_message())
            if kind == "plant":
                summ = json.loads((s.dir / "plant" / "plant_summary.json").read_text())
                out["plant"] = {"real_time_factor": float(summ["real_time_factor"]),
                                "wall_time_s": summ.get("wall_time_s"),
                                "sim_time_s": summ.get("sim_time_s"),
                                "rerequests": summ.get("rerequests"),
                                "peak_rss_mb": rss.peak[kind]}
            else:
                r = json.loads((s.dir / "standin.json").read_text())
                r["peak_rss_mb"] = rss.peak[kind]
                out["standin"] = r
            out.setdefault("fc_peak_rss_mb", rss.peak["fc"])
            out["fc_peak_rss_mb"] = max(out["fc_peak_rss_mb"], rss.peak["fc"])
            out[f"fc_rss_{kind}"] = rss.growth("fc", skip_frac=0.5)
            out[f"gcs_{kind}"] = gcs_res
        finally:
            s.close()
    src = out.get("plant") or out.get("standin")
    out["real_time_factor"] = src["real_time_factor"]
    out["rtf_source"] = "plant_sim process" if "plant" in out else "tools.bench.standin"
    return out


def realtime(fast_hz: float, wall_s: float, keep: str | None = None,
             fc_mode: str = "realtime", fc_extra: tuple = (), skip_s: float = 1.0) -> dict:
    """Real-time fc at ``fast_hz`` with the measuring stand-in plant and a streaming GCS.

    ``fc_mode="lockstep"`` runs the fc's frame-triggered loop (it answers each frame as it
    arrives) against the same real-time plant: the sensor-to-servo latency the fc's code
    achieves when its tick is triggered by the frame; there are no wall-clock ticks, so no
    lateness figures (NaN).
    """
    from fc.internals_log import load as load_internals
    s = Session(keep, f"realtime{int(fast_hz)}-{fc_mode}")
    try:
        port = free_udp_port()
        gcs = GcsSink()
        gcs.start()
        fc_out = s.dir / "fc"
        fc = s.start("fc", _fc_argv(fc_out, fc_mode, fast_hz, port, gcs.port) + list(fc_extra))
        fc.wait_for_line("READY", READY_TIMEOUT_S)
        pl = s.start("standin", [PY, "-m", "tools.bench.standin", "--fc", f"127.0.0.1:{port}",
                                 "--mode", "realtime", "--frame-hz", f"{fast_hz:g}",
                                 "--duration", f"{wall_s:g}", "--out",
                                 str(s.dir / "standin.json")])
        rss = RssSampler({"fc": fc.pid, "standin": pl.pid})
        rss.start()
        pl.wait_for_line("READY", READY_TIMEOUT_S)
        t_plant0 = time.monotonic()
        rc = _wait_exit(pl, 60.0 + 3.0 * wall_s)
        t_plant1 = time.monotonic()
        rss.stop()
        gcs_res = gcs.stop()
        if rc != 0:
            raise RuntimeError(pl.death_message())
        fc.stop(int_wait_s=10.0, term_wait_s=5.0)
        r = json.loads((s.dir / "standin.json").read_text())
        d = load_internals(str(fc_out / "fc_internals.npz"))
        wall = np.asarray(d["wall_s"])
        late = np.asarray(d["lateness_us"])
        # the ticks while the plant streamed, after its warm-up (skip_s)
        sel = (wall > t_plant0 + skip_s) & (wall < t_plant1 - 0.1)
        lat = late[sel] if fc_mode == "realtime" else late[:0]
        period_us = 1e6 / fast_hz
        ex = np.asarray(d["exec_us"])[sel]
        res = {"fast_hz": fast_hz, "wall_s": wall_s, "fc_mode": fc_mode, "ticks": int(sel.sum()),
               "lateness_median_us": float(np.median(lat)) if lat.size else float("nan"),
               "lateness_p99_us": float(np.percentile(lat, 99)) if lat.size else float("nan"),
               "lateness_max_us": float(lat.max()) if lat.size else float("nan"),
               "late_20pct_share_pct": float((lat > 0.2 * period_us).mean() * 100)
               if lat.size else float("nan"),
               "tick_exec_median_us": float(np.median(ex)) if ex.size else float("nan"),
               "tick_exec_p99_us": float(np.percentile(ex, 99)) if ex.size else float("nan"),
               "latency_median_us": r["latency"]["median_us"],
               "latency_p99_us": r["latency"]["p99_us"],
               "latency_max_us": r["latency"]["max_us"],
               "answered_share": r["answered_share"],
               "plant_send_lateness_p99_us": r["send_lateness"]["p99_us"],
               "plant_sched_fifo": r["sched_fifo"],
               "fc_peak_rss_mb": rss.peak["fc"], "standin_peak_rss_mb": rss.peak["standin"],
               "fc_rss": rss.growth("fc"), "gcs": gcs_res}
        return res
    finally:
        s.close()


def realtime_floor(fast_hz: float, wall_s: float, keep: str | None = None) -> dict:
    """:func:`realtime`'s measuring stand-in plant against a bare receiver instead of the fc
    (``tools.bench.rtfloor``: the fc's link, scheduling request and ``select`` wait, no work):
    the host's wake-up lateness floor at ``fast_hz`` at the time of the run (us)."""
    s = Session(keep, f"rtfloor{int(fast_hz)}")
    try:
        port = free_udp_port()
        out = s.dir / "rtfloor.json"
        rx = s.start("rtfloor", [PY, "-m", "tools.bench.rtfloor", "--plant-bind",
                                 f"127.0.0.1:{port}", "--out", str(out), "--period-us",
                                 f"{1e6 / fast_hz:g}", "--skip", str(int(fast_hz))])
        rx.wait_for_line("READY", READY_TIMEOUT_S)
        pl = s.start("standin", [PY, "-m", "tools.bench.standin", "--fc", f"127.0.0.1:{port}",
                                 "--mode", "realtime", "--frame-hz", f"{fast_hz:g}",
                                 "--duration", f"{wall_s:g}", "--out",
                                 str(s.dir / "standin.json")])
        pl.wait_for_line("READY", READY_TIMEOUT_S)
        rc = _wait_exit(pl, 60.0 + 3.0 * wall_s)
        if rc != 0:
            raise RuntimeError(pl.death_message())
        if _wait_exit(rx, 30.0) != 0:
            raise RuntimeError(rx.death_message())
        res = json.loads(out.read_text())
        res["fast_hz"] = fast_hz
        return res
    finally:
        s.close()


def startup(cold: bool, keep: str | None = None, precompiled: bool = False) -> dict:
    """Process start to the first SERVO_OUTPUT_RAW: ``python -m fc`` (lockstep) is started and
    a sensor frame is sent every 2 ms until the first answer. ``cold``: NUMBA_CACHE_DIR points
    to an empty directory, so every kernel compiles; with ``precompiled`` ``python -m
    tools.precompile`` fills it first (its wall time in ``precompile_s``, not in the start)."""
    from fc.link import UdpEndpoint
    from tools.bench.standin import FrameCodec
    s = Session(keep, ("startup-precompiled" if precompiled else "startup-cold") if cold
                else "startup-warm")
    ep = UdpEndpoint("127.0.0.1", 0)
    try:
        env = dict(os.environ)
        extra = {}
        if cold:
            cache = s.dir / "numba_cache"
            cache.mkdir()
            env["NUMBA_CACHE_DIR"] = str(cache)
            if precompiled:
                t_pre = time.perf_counter()
                subprocess.run([PY, "-m", "tools.precompile"], env=env, check=True,
                               stdout=subprocess.DEVNULL, timeout=READY_TIMEOUT_S * 2)
                extra["precompile_s"] = time.perf_counter() - t_pre
        port = free_udp_port()
        codec = FrameCodec()
        meas = np.zeros(14)
        meas[2] = 0.03
        meas[7] = 0.03
        meas[9] = 2200.0
        meas[10] = 25000.0
        meas[12] = 2200.0
        t0 = time.perf_counter()
        fc = s.start("fc", _fc_argv(s.dir / "fc", "lockstep", 500, port, free_udp_port()),
                     env=env)
        k = 0
        deadline = t0 + READY_TIMEOUT_S
        while time.perf_counter() < deadline:
            k += 1
            stamp = 2000 * k
            meas[0] = stamp * 1e-6
            ep.send(codec.encode(meas, stamp), ("127.0.0.1", port))
            r, _, _ = select.select([ep.fileno()], [], [], 0.002)
            if r:
                got = ep.recv()
                if got is not None and codec.servo(got[0]) is not None:
                    t1 = time.perf_counter()
                    return {"cold": cold, "precompiled": precompiled,
                            "first_servo_s": t1 - t0,
                            "cpu_s_at_first_servo": _cpu_s(fc.pid), **extra}
            if fc.poll() is not None:
                raise RuntimeError(fc.death_message())
        raise RuntimeError(f"no SERVO_OUTPUT_RAW within {READY_TIMEOUT_S:.0f} s of start")
    finally:
        ep.close()
        s.close()


def _cpu_s(pid: int) -> float:
    """CPU time (user + system, s) used so far by ``pid`` (/proc/PID/stat), NaN if unknown."""
    try:
        with open(f"/proc/{pid}/stat", encoding="ascii") as f:
            fields = f.read().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError):
        return float("nan")


def _have_plant_process() -> bool:
    import importlib.util
    return importlib.util.find_spec("plant_sim.__main__") is not None
