"""HIL tier: lockstep determinism with a --timeline, re-sent frames, real-time mode echo."""
from __future__ import annotations

import math
import os
import signal
import time

import numpy as np
import pytest

from fc.internals_log import load
from tests.fc_harness import ClosedLoop, FcProcess, ScriptedPlant, level_meas

pytestmark = pytest.mark.hil

TIMELINE = """
[[command]]
t_s = 0.0
alpha_deg = 1.0
beta_deg = 0.0
mu_deg = 0.0

[[command]]
t_s = 0.5
alpha_deg = 5.0
mu_deg = 4.0
"""


def _fly(out: str, timeline: str, n_frames: int) -> list:
    # the wall-clock failsafe must not trip while the test process loads its own kernels
    os.makedirs(out)
    with open(os.path.join(out, "params.parm"), "w") as f:
        f.write("FS_TIMEOUT_S 30\n")
    with FcProcess(out, "--arm", "--flight-mode", "COORDINATED", "--timeline", timeline) as fc:
        loop = ClosedLoop(fc.plant_port, seed=5)
        try:
            loop.run(n_frames)
        finally:
            loop.close()
        assert fc.stop() == 0
    return loop.outputs


def test_lockstep_with_timeline_is_deterministic(tmp_path):
    tl = tmp_path / "timeline.toml"
    tl.write_text(TIMELINE)
    a = _fly(str(tmp_path / "a"), str(tl), 600)
    b = _fly(str(tmp_path / "b"), str(tl), 600)
    assert len(a) == 600 and a == b
    log = load(str(tmp_path / "a"))
    t, cmd_alpha = log["t_s"], log["cmd_alpha_rad"]
    assert np.all(cmd_alpha[t < 0.5 - 1e-9] == pytest.approx(math.radians(1.0)))
    assert np.all(cmd_alpha[t >= 0.5] == pytest.approx(math.radians(5.0)))
    assert np.all(np.diff(t) > 0)               # one fast tick per frame at 500 Hz frames


def test_resent_frame_is_answered_again_without_a_new_tick(tmp_path):
    with FcProcess(str(tmp_path), "--arm", "--flight-mode", "COORDINATED") as fc:
        plant = ScriptedPlant(fc.plant_port)
        try:
            for k in range(20):
                plant.exchange(level_meas(0.002 * k))
            first = plant.exchange(level_meas(0.040))
            again = plant.exchange(level_meas(0.040))      # the plant's re-request
            assert again.time_usec == first.time_usec == 40_000
            assert (again.servo1_raw, again.servo2_raw, again.servo3_raw) == \
                (first.servo1_raw, first.servo2_raw, first.servo3_raw)
        finally:
            plant.close()
        assert fc.stop() == 0
    log = load(str(tmp_path))
    assert len(log["t_s"]) == 21


def test_realtime_mode_echoes_newest_stamp(tmp_path):
    with FcProcess(str(tmp_path), "--mode", "realtime", "--fast-hz", "1000",
                   "--slow-hz", "100") as fc:
        plant = ScriptedPlant(fc.plant_port)
        try:
            stamps = set()
            echoed = []
            t0 = time.monotonic()
            k = 0
            while time.monotonic() - t0 < 1.0:       # frames at ~500 Hz, no lockstep
                k += 1
                stamp = 2000 * k
                plant.send_frame(level_meas(stamp * 1e-6))
                stamps.add(stamp)
                ans = plant.recv_servo(0.002)
                if ans is not None:
                    echoed.append(ans.time_usec)
            deadline = time.monotonic() + 1.0
            while time.monotonic() < deadline:
                ans = plant.recv_servo(0.05)
                if ans is None:
                    break
                echoed.append(ans.time_usec)
        finally:
            plant.close()
        assert fc.stop() == 0
    assert len(echoed) > 200                 # the fc outputs at its own rate
    assert set(echoed) <= stamps             # always a stamp it received
    assert echoed == sorted(echoed)          # newest used: never goes back
    log = load(str(tmp_path))
    assert len(log["lateness_us"]) > 500     # ~1000 ticks per wall second were logged
    with open(os.path.join(tmp_path, "fc.log")) as f:
        assert "scheduling" in f.read()      # SCHED_FIFO granted or the refusal logged


def _realtime_session(out: str, *extra: str, n_frames: int = 150) -> tuple[list, list, str]:
    """Frames 10 ms apart (with a few ms of jitter) to a 100 Hz real-time fc; each frame waits
    (bounded) for the first answer echoing its own stamp. Returns (stamps sent, stamps of the
    answers seen, fc.log)."""
    rng = np.random.default_rng(7)
    sent, echoed = [], []
    with FcProcess(out, "--mode", "realtime", "--fast-hz", "100", "--slow-hz", "20",
                   *extra) as fc:
        plant = ScriptedPlant(fc.plant_port)
        try:
            t_next = time.monotonic()
            for k in range(1, n_frames + 1):
                t_next += 0.010 + rng.uniform(-0.002, 0.002)
                while time.monotonic() < t_next:
                    ans = plant.recv_servo(max(0.0, t_next - time.monotonic()))
                    if ans is not None:
                        echoed.append(ans.time_usec)
                stamp = 10_000 * k
                plant.send_frame(level_meas(stamp * 1e-6))
                sent.append(stamp)
        finally:
            plant.close()
        assert fc.stop() == 0
    with open(os.path.join(out, "fc.log")) as f:
        return sent, echoed, f.read()


def _frame_ticks(log_text: str) -> int:
    import re
    m = re.search(r"frame-synchronised ticks: on a frame (\d+)", log_text)
    assert m, "the fc did not report its frame-synchronised ticks"
    return int(m.group(1))


def test_realtime_frame_sync_runs_a_tick_on_each_frame(tmp_path):
    """The default real-time schedule: a sensor frame triggers the fast tick (and its answer)
    instead of waiting for the fc's own clock; the deadline only stands in for missing frames."""
    sent, echoed, log_text = _realtime_session(str(tmp_path))
    assert set(echoed) <= set(sent)
    assert len(set(echoed)) >= 0.9 * len(sent)          # (nearly) every frame answered
    # the frames came at the fast rate, so (nearly) every one triggered its own tick
    assert _frame_ticks(log_text) >= 0.9 * len(sent)
    assert "garbage collector:" in log_text             # the collector is off the schedule
    log = load(str(tmp_path))
    lat = np.asarray(log["lateness_us"])
    assert lat.size >= 0.9 * len(sent) and (lat >= -1000).all()   # wake minus kernel arrival


def test_realtime_clock_sync_still_available(tmp_path):
    sent, echoed, log_text = _realtime_session(str(tmp_path), "--sync", "clock", n_frames=60)
    assert set(echoed) <= set(sent) and len(set(echoed)) >= 30
    assert "frame-synchronised ticks" not in log_text


def test_bad_sync_choice_is_refused():
    import subprocess
    import sys
    r = subprocess.run([sys.executable, "-m", "fc", "--sync", "gps"], capture_output=True,
                       text=True, timeout=60)
    assert r.returncode == 2 and "--sync" in r.stderr


def test_plant_reset_restarts_loops_and_timeline(tmp_path):
    tl = tmp_path / "timeline.toml"
    tl.write_text("[[command]]\nt_s = 0.0\nalpha_deg = 1.0\n[[command]]\nt_s = 0.02\nalpha_deg = 3.0\n")
    out = str(tmp_path / "run")
    os.makedirs(out)
    with open(os.path.join(out, "params.parm"), "w") as f:
        f.write("FS_TIMEOUT_S 30\n")
    with FcProcess(out, "--timeline", str(tl)) as fc:
        plant = ScriptedPlant(fc.plant_port)
        try:
            for k in range(20):                        # 0 .. 38 ms
                plant.exchange(level_meas(0.002 * k))
            for k in range(5):                         # the plant restarted: 0 .. 8 ms again
                assert plant.exchange(level_meas(0.002 * k)).time_usec == 2000 * k
        finally:
            plant.close()
        assert fc.stop() == 0
    log = load(out)
    cmd = log["cmd_alpha_rad"]
    assert len(cmd) == 25
    assert cmd[19] == pytest.approx(math.radians(3.0))
    assert np.allclose(cmd[20:], math.radians(1.0))    # the timeline started over
    with open(os.path.join(out, "fc.log")) as f:
        assert "plant time went backwards" in f.read()


def test_sigterm_keeps_the_decimated_internals_log(tmp_path):
    # GIVEN an fc logging at full rate for 0.1 s of sensor time, then one row per two slow
    # ticks (the default tail, 50 Hz)
    with FcProcess(str(tmp_path), "--arm", "--flight-mode", "COORDINATED",
                   "--internals-full-s", "0.1") as fc:
        plant = ScriptedPlant(fc.plant_port)
        try:
            for k in range(200):                       # 0.4 s of 500 Hz frames
                plant.exchange(level_meas(0.002 * k))
        finally:
            plant.close()
        # WHEN it is stopped by SIGTERM (not the harness's SIGINT)
        rc = fc.child.stop(first_signal=signal.SIGTERM, int_wait_s=20.0, term_wait_s=None)
        fc.returncode = rc
    assert rc == 0
    # THEN the npz holds the first 0.1 s at 500 Hz and then 50 Hz: 50 + 15 rows
    assert sorted(os.listdir(tmp_path)).count("fc_internals.npz") == 1
    t = load(str(tmp_path))["t_s"]
    assert np.allclose(t[:50], 0.002 * np.arange(50))
    assert np.allclose(t[50:], 0.1 + 0.02 * np.arange(15))
    with open(tmp_path / "fc.log") as f:
        assert "65 rows, 0 dropped, 135 decimated" in f.read()
