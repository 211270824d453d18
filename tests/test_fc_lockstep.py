"""HIL tier: lockstep determinism with a --timeline, re-sent frames, real-time mode echo."""
from __future__ import annotations

import math
import os
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
