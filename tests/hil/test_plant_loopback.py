"""Loopback: the plant process in lockstep against a scripted controller stand-in over UDP.

The stand-in (plant_sim.link.ServoResponder, in this test process) answers every sensor frame
with SERVO_OUTPUT_RAW echoing the frame stamp; a simple rate damper makes the commands depend
on the measurements. Two runs with the same seed must give bit-identical truth logs; garbage,
a wrong system id and a foreign source address are rejected and counted without harm.
"""
import json
import math
import socket
import sys

import numpy as np
import pytest

from plant_sim import truthlog
from plant_sim.link import ServoResponder
from plant_sim.scenario import load
from plant_sim.sim import PlantSim
from tools.sitl.procs import run_serving

pytestmark = pytest.mark.hil

DEG = math.pi / 180.0
DURATION_S = 1.0


def _law(stamp_us, v):
    # rate damping plus a pitch-up bias; deterministic function of the measurements
    p, q, r = v["p"], v["q"], v["r"]
    pitch = 2.0 * DEG - 0.5 * q
    roll = -0.3 * p
    return (pitch - roll, pitch + roll, 0.4 * r)


def _run(tmp_path, name, inject):
    resp = ServoResponder()
    foreign = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    foreign.bind(("127.0.0.1", 0))
    out = tmp_path / name
    argv = [sys.executable, "-m", "plant_sim", "run", "--scenario", "paper", "--mode", "lockstep",
            "--fc", f"127.0.0.1:{resp.addr[1]}", "--bind", "127.0.0.1:0", "--out", str(out),
            "--duration", str(DURATION_S), "--seed", "5", "--progress-every", "0"]
    n = 0

    def serve() -> None:
        nonlocal n
        if resp.serve_one(_law, timeout_s=0.5):
            n += 1
            if inject and n in (10, 200) and resp.peer:
                resp.send_raw(b"\xfd\x09garbage-not-mavlink", resp.peer)
                resp.send_raw(resp.servo_frame(123456, (1500, 1500, 1500), sysid=77), resp.peer)
                foreign.sendto(resp.servo_frame(0, (1000, 1000, 1000)), resp.peer)

    try:
        proc = run_serving("plant", argv, serve, 60.0)
    finally:
        resp.close()
        foreign.close()
    assert proc.poll() == 0, proc.stderr_tail
    stdout = "\n".join(proc.history)
    return out, stdout, resp.answered


def test_lockstep_loopback_completes_and_is_reproducible(tmp_path):
    out_a, stdout_a, answered_a = _run(tmp_path, "a", inject=True)
    out_b, _, answered_b = _run(tmp_path, "b", inject=False)
    frames = int(round(DURATION_S * 500))
    assert answered_a == frames and answered_b == frames
    assert "DONE frames=%d" % frames in stdout_a
    summary = json.loads((out_a / "plant_summary.json").read_text())
    assert summary["exit_reason"] == "completed"
    assert summary["frames"] == frames and summary["sim_time_s"] == pytest.approx(DURATION_S)
    assert summary["rerequests"] == 0
    assert summary["rejected_malformed"] >= 2
    assert summary["rejected_sysid"] == 2
    assert summary["rejected_source"] == 2
    a = truthlog.load(out_a)
    b = truthlog.load(out_b)
    assert set(a) == set(b) and len(a["t_s"]) == frames + 1
    for k in a:
        np.testing.assert_array_equal(a[k], b[k], err_msg=k)
    # the commands the stand-in computed arrived through the PWM map (1 us = 0.04 deg)
    q = a["meas_q_rad_s"][:-1]
    expected_left = 2.0 * DEG - 0.5 * q + 0.3 * a["meas_p_rad_s"][:-1]
    assert np.max(np.abs(a["delta_cmd_left_rad"][:-1] - expected_left)) <= 0.021 * DEG
    # and the plant flew: the sideslip moment rolled the vehicle, the truth moved
    assert np.ptp(a["p_rad_s"]) > 1e-3
    assert (out_a / "scenario.toml").is_file() and (out_a / "plant.log").is_file()
    # the process and the in-process API are the same plant: replaying the logged commands
    # through PlantSim.frame with the scenario as used reproduces every column bit for bit
    sim = PlantSim(load(out_a / "scenario.toml"))
    row = np.zeros(sim.TRUTH_N)
    cmd = np.zeros(3)
    sim.measure(sim.last_meas)
    names = sim.TRUTH_NAMES
    for k in range(frames):
        cmd[0] = a["delta_cmd_left_rad"][k]
        cmd[1] = a["delta_cmd_right_rad"][k]
        cmd[2] = a["delta_cmd_rudder_rad"][k]
        sim.frame(cmd, row)
        for i, n in enumerate(names):
            assert row[i] == a[n][k], (n, k)
