"""Open-ended runs (issue 12 point 1): nothing in the plant, the controller or tools.hil is
sized by the requested duration, and a real-time session with ``--duration 0`` flies until
SIGINT, then writes its logs and summary and exits 0.

- tier 1: the plant's run loop (in process, real UDP on 127.0.0.1) asked for 1e7 s or for an
  open-ended run, stopped by SIGINT after a few frames: its traced allocations stay small
  (before the fix, the real-time loop allocated one float per requested frame: 37 GiB);
- tier 1: the fixed-size pieces (lateness histogram, the ground station's record rings);
- tier 2 (HIL): ``python -m tools.hil run --mode realtime --duration 0`` flown for a few
  seconds of sim time, stopped with SIGINT: exit 0, summary.json written, the plant said
  goodbye and the controller did not warn about lost plant data.
"""
from __future__ import annotations

import json
import logging
import math
import os
import re
import signal
import socket
import subprocess
import sys
import threading
import time
import tracemalloc
from pathlib import Path

import numpy as np
import pytest

from plant_sim import process as plant_process
from plant_sim import truthlog
from plant_sim.link import ServoResponder
from plant_sim.scenario import load
from plant_sim.sim import PlantSim
from tools.sitl.gcs import RingRecord
from tools.sitl.procs import repo_env

ROOT = Path(__file__).resolve().parents[2]
#: frames flown before the stop (0.1 s of sim time at the paper scenario's 500 Hz)
STOP_AFTER_FRAMES = 50
#: traced allocation allowed for a whole plant run (the fixed lateness histogram is 0.8 MB)
PEAK_MAX_BYTES = 64 * 2**20


class _Sink:
    """Counts the sensor datagrams a real-time plant sends (no fc: it holds its command)."""

    def __init__(self):
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(0.2)
        self.addr = self.sock.getsockname()
        self.received = 0

    def serve_one(self) -> None:
        try:
            self.sock.recvfrom(4096)
            self.received += 1
        except socket.timeout:
            pass

    def close(self):
        self.sock.close()


def _fly_plant_then_sigint(tmp_path, mode: str, duration_s: float):
    """Run plant_sim.process.run in this (main) thread; a helper thread answers or swallows
    the frames and sends SIGINT to this process after STOP_AFTER_FRAMES of them. Returns
    (stats, traced peak bytes, frames seen by the helper)."""
    sc = load("paper")
    PlantSim(sc, seed=0).step_frame(np.zeros(3))      # kernels loaded before tracing
    peer = ServoResponder() if mode == "lockstep" else _Sink()
    done = threading.Event()
    seen = []

    def _peer():
        while not done.is_set():
            if mode == "lockstep":
                peer.serve_one(lambda stamp, vals: (0.0, 0.0, 0.0), timeout_s=0.2)
                n = peer.answered
            else:
                peer.serve_one()
                n = peer.received
            if n >= STOP_AFTER_FRAMES and not seen:
                seen.append(n)
                signal.pthread_kill(threading.main_thread().ident, signal.SIGINT)

    cfg = plant_process.RunConfig(mode=mode, fc_addr=peer.addr, bind_addr=("127.0.0.1", 0),
                                  out_dir=tmp_path, duration_s=duration_s, seed=0,
                                  progress_every_s=0.0)
    th = threading.Thread(target=_peer, daemon=True)
    tracemalloc.start()
    th.start()
    try:
        stats = plant_process.run(sc, cfg, logging.getLogger("test_open_ended"))
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
        done.set()
        th.join(timeout=10)
        peer.sock.close()
    return stats, peak, seen


@pytest.mark.parametrize("mode", ["realtime", "lockstep"])
@pytest.mark.parametrize("duration_s", [1e7, 0.0], ids=["1e7s", "open-ended"])
def test_plant_allocates_nothing_proportional_to_the_requested_duration(tmp_path, mode,
                                                                        duration_s):
    stats, peak, seen = _fly_plant_then_sigint(tmp_path, mode, duration_s)
    print(f"{mode}, duration {duration_s:g} s: {stats.frames} frames, traced peak "
          f"{peak / 2**20:.1f} MiB")
    assert seen, "the plant stopped before the helper saw its frames"
    assert stats.exit_reason == "stopped by SIGINT"
    assert peak < PEAK_MAX_BYTES, f"traced peak {peak / 2**20:.0f} MiB"
    summary = json.loads((tmp_path / "plant_summary.json").read_text())
    assert summary["open_ended"] is (duration_s == 0)
    assert summary["frames"] == stats.frames >= STOP_AFTER_FRAMES
    assert summary["goodbye_sent"] == 3
    truth = truthlog.load(tmp_path)
    assert len(truth["t_s"]) == stats.frames
    if mode == "realtime":
        assert 0 <= summary["lateness_us_p50"] <= summary["lateness_us_p99"] \
            <= summary["lateness_us_max"]


def test_lateness_histogram_percentiles_to_one_microsecond():
    rng = np.random.default_rng(3)
    late_s = rng.exponential(40e-6, 20000)
    late_s[:3] = (0.0, 0.25, 2.0)                     # beyond the histogram: last bin, max kept
    h = plant_process.LatenessHistogram()
    for x in late_s:
        h.add(float(x))
    assert h.n == late_s.size
    assert h.counts.nbytes < 1 << 20                  # fixed, whatever the number of frames
    for q in (50, 90, 99):
        assert abs(h.percentile_us(q) - np.percentile(late_s * 1e6, q)) <= 1.0
    assert h.max_s == 2.0 and h.percentile_us(100) == pytest.approx(2.0e6)


def test_ground_station_records_are_rings_of_the_newest_rows():
    r = RingRecord(2, capacity=4)
    assert r.array().shape == (0, 2)
    for k in range(3):
        r.append((k, -k))
    assert r.array()[:, 0].tolist() == [0, 1, 2]
    for k in range(3, 10):
        r.append((k, -k))
    assert len(r) == 10                                 # every row counted
    assert r.array()[:, 0].tolist() == [6, 7, 8, 9]     # the newest kept, oldest first
    assert r.buf.shape == (4, 2)


def _free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.hil
def test_realtime_duration_0_flies_until_sigint_then_writes_the_summary(tmp_path):
    out = tmp_path / "open"
    env = repo_env()
    proc = subprocess.Popen(
        [sys.executable, "-m", "tools.hil", "run", "--mode", "realtime", "--duration", "0",
         "--variant", "coordinated", "--out", str(out), "--no-plots", "--progress-every", "0.5",
         "--gcs-out", f"127.0.0.1:{_free_udp_port()}"],
        cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        start_new_session=True)
    err_lines = []
    try:
        # wait (bounded) until the vehicle has flown 3 s of sim time, by its progress lines
        deadline = time.monotonic() + 240
        sim_t = 0.0
        while sim_t < 3.0 and time.monotonic() < deadline:
            line = proc.stderr.readline()
            if not line:
                break
            err_lines.append(line)
            m = re.search(r"sim t =\s*([0-9.]+)", line)
            if m:
                sim_t = float(m.group(1))
        assert sim_t >= 3.0, "".join(err_lines)
        proc.send_signal(signal.SIGINT)
        stdout, rest = proc.communicate(timeout=120)
        err = "".join(err_lines) + rest
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait(timeout=10)
    assert proc.returncode == 0, err
    summary = json.loads((out / "summary.json").read_text())
    run = summary["runs"]["coordinated"]
    assert run["status"] == "interrupted" and not run["diverged"]
    assert run["sim_time_s"] >= 3.0
    vdir = out / "coordinated"
    plant = json.loads((vdir / "plant_summary.json").read_text())
    assert plant["open_ended"] and plant["exit_reason"] == "stopped by SIGINT"
    assert (vdir / "truth.npz").is_file() and (vdir / "fc_internals.npz").is_file()
    assert not (vdir / "truth.raw").exists()
    fc_log = (vdir / "fc.log").read_text()
    assert "plant ended its run" in fc_log
    assert "plant data lost" not in fc_log and " WARNING " not in fc_log, fc_log
    assert math.isfinite(run["alpha"]["final_error_deg"])
