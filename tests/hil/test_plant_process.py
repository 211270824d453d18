"""The plant process: CLI, real-time mode, SIGTERM, give-up, trim warning (loopback UDP)."""
import json
import math
import signal
import socket
import subprocess
import sys
import time

import numpy as np
import pytest

from plant_sim import truthlog
from plant_sim.hold import damper_increments
from plant_sim.link import ServoResponder
from plant_sim.scenario import load
from plant_sim.trim import trim_at

pytestmark = pytest.mark.hil

PY = sys.executable


def _plant(args, **kw):
    return subprocess.Popen([PY, "-m", "plant_sim", *args], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, **kw)


def _finish(proc, timeout=30):
    try:
        out, err = proc.communicate(timeout=timeout)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(timeout=10)
    return out, err


def test_cli_help_list_trim_and_bad_scenario():
    r = subprocess.run([PY, "-m", "plant_sim", "--help"], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0 and "run" in r.stdout and "trim" in r.stdout
    r = subprocess.run([PY, "-m", "plant_sim", "list"], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0 and {"paper", "nominal", "cg_aft"} <= {l.split()[0] for l in r.stdout.splitlines()}
    r = subprocess.run([PY, "-m", "plant_sim", "trim", "--scenario", "cg_aft"], capture_output=True,
                       text=True, timeout=60)
    assert r.returncode == 0 and "trimmed" in r.stdout and "-9.5" in r.stdout
    r = subprocess.run([PY, "-m", "plant_sim", "run", "--scenario", "nosuch"], capture_output=True,
                       text=True, timeout=60)
    assert r.returncode == 2 and "unknown scenario 'nosuch'" in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1


def test_realtime_run_completes_near_real_time(tmp_path):
    resp = ServoResponder()
    out = tmp_path / "rt"
    proc = _plant(["run", "--scenario", "nominal", "--mode", "realtime", "--fc", f"127.0.0.1:{resp.addr[1]}",
                   "--bind", "127.0.0.1:0", "--out", str(out), "--duration", "0.6", "--progress-every", "0.2"])
    try:
        deadline = time.monotonic() + 60
        while proc.poll() is None and time.monotonic() < deadline:
            resp.serve_fast(timeout_s=0.2)
        stdout, stderr = _finish(proc)
    finally:
        resp.close()
    assert proc.returncode == 0, stderr
    s = json.loads((out / "plant_summary.json").read_text())
    assert s["mode"] == "realtime" and s["frames"] == 300 and s["exit_reason"] == "completed"
    assert 0.3 < s["real_time_factor"] < 1.2
    assert s["servo_frames_accepted"] > 200
    assert "PROGRESS t_s=" in stdout
    assert len(truthlog.load(out)["t_s"]) == 301


def test_sigterm_while_waiting_flushes_and_exits_zero(tmp_path):
    fc = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    fc.bind(("127.0.0.1", 0))
    fc.settimeout(60.0)
    out = tmp_path / "term"
    proc = _plant(["run", "--scenario", "paper", "--fc", f"127.0.0.1:{fc.getsockname()[1]}",
                   "--bind", "127.0.0.1:0", "--out", str(out), "--rerequest-timeout", "0.05"])
    try:
        fc.recvfrom(2048)            # the first frame ...
        fc.recvfrom(2048)            # ... and its re-send: the plant is waiting for an answer
        proc.send_signal(signal.SIGTERM)
        _, stderr = _finish(proc)
    finally:
        fc.close()
    assert proc.returncode == 0, stderr
    s = json.loads((out / "plant_summary.json").read_text())
    assert s["exit_reason"] == "stopped by SIGTERM" and s["rerequests"] >= 1 and s["frames"] == 0
    assert (out / "truth.npz").is_file() and not (out / "truth.raw").exists()


def test_give_up_when_no_controller_answers(tmp_path):
    fc = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    fc.bind(("127.0.0.1", 0))
    try:
        proc = _plant(["run", "--scenario", "nominal", "--fc", f"127.0.0.1:{fc.getsockname()[1]}",
                       "--bind", "127.0.0.1:0", "--out", str(tmp_path / "gu"),
                       "--rerequest-timeout", "0.05", "--give-up", "0.3"])
        _, stderr = _finish(proc, timeout=60)
    finally:
        fc.close()
    assert proc.returncode == 2
    assert "no SERVO_OUTPUT_RAW answering frame 0" in stderr
    assert len(stderr.strip().splitlines()) == 1


def test_untrimmable_scenario_warns_at_start(tmp_path):
    text = open(load("paper").path).read()
    bad = tmp_path / "hard.toml"
    bad.write_text(text.replace("x_cg_m = 0.0", "x_cg_m = 2.90"))
    fc = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    fc.bind(("127.0.0.1", 0))
    fc.settimeout(60.0)
    try:
        proc = _plant(["run", "--scenario", str(bad), "--fc", f"127.0.0.1:{fc.getsockname()[1]}",
                       "--bind", "127.0.0.1:0", "--out", str(tmp_path / "w")])
        fc.recvfrom(2048)            # started: the warning was printed before the first frame
        proc.send_signal(signal.SIGINT)
        _, stderr = _finish(proc)
    finally:
        fc.close()
    assert proc.returncode == 0
    assert "WARNING: scenario paper cannot be trimmed" in stderr and str(bad) in stderr
    assert "NOT trimmable" in (tmp_path / "w" / "plant.log").read_text()


def test_realtime_without_commands_goes_to_trim(tmp_path):
    text = open(load("nominal").path).read()
    sc = tmp_path / "notrim.toml"
    sc.write_text(text.replace('no_command = "hold"', 'no_command = "trim"'))
    silent = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)     # receives, never answers
    silent.bind(("127.0.0.1", 0))
    out = tmp_path / "nc"
    try:
        proc = _plant(["run", "--scenario", str(sc), "--mode", "realtime", "--fc",
                       f"127.0.0.1:{silent.getsockname()[1]}", "--bind", "127.0.0.1:0",
                       "--out", str(out), "--duration", "0.3", "--progress-every", "0"])
        _, stderr = _finish(proc, timeout=60)
    finally:
        silent.close()
    assert proc.returncode == 0, stderr
    s = json.loads((out / "plant_summary.json").read_text())
    assert s["no_command_frames"] == s["frames"] == 150
    t = truthlog.load(out)
    expect = trim_at(load(sc), math.radians(1.0), math.radians(5.0)).deflection_rad
    assert abs(expect[0]) > 0.1                      # the nominal initial state needs ~ -10 deg
    for i, n in enumerate(("delta_cmd_left_rad", "delta_cmd_right_rad", "delta_cmd_rudder_rad")):
        assert t[n][:-1] == pytest.approx(expect[i], abs=1e-12)


def test_gc_off_schedule_freezes_and_restores_the_collector():
    import gc

    from plant_sim.process import gc_off_schedule
    assert gc.isenabled()
    with gc_off_schedule():
        assert not gc.isenabled()
        assert gc.get_freeze_count() > 0
    assert gc.isenabled() and gc.get_freeze_count() == 0


def test_realtime_silent_fc_hold_is_the_commands_mean_not_the_last_transient(tmp_path):
    """``servo.no_command = "hold"`` (the cruise scenario): a silent fc's surfaces are held at
    the recent mean of its commands (the trim it flew), not at its last command, which may be a
    transient (issue 22: a late-frame kick of -16 deg held through a 1 s blackout departed)."""
    resp = ServoResponder()
    out = tmp_path / "hold"
    silent_after_s = 0.8
    deg = math.pi / 180.0
    sent = []

    def answer(stamp_us, _m):
        k = len(sent)
        d = 15.0 * deg if stamp_us >= (silent_after_s - 0.01) * 1e6 else (2.0 if k % 2 else -2.0) * deg
        sent.append(d)
        return d, d, 0.0

    proc = _plant(["run", "--scenario", "cruise", "--mode", "realtime", "--fc",
                   f"127.0.0.1:{resp.addr[1]}", "--bind", "127.0.0.1:0", "--out", str(out),
                   "--duration", "1.6", "--progress-every", "0"])
    try:
        deadline = time.monotonic() + 60
        while proc.poll() is None and time.monotonic() < deadline:
            if sent and sent[-1] > 10.0 * deg:
                break                                   # the transient went: silence from now
            resp.serve_one(answer, timeout_s=0.2)
        _, stderr = _finish(proc, timeout=60)
    finally:
        resp.sock.close()
    assert proc.returncode == 0, stderr
    assert sent and sent[-1] == 15.0 * deg
    t = truthlog.load(out)
    last = float(t["t_s"][np.flatnonzero(np.abs(t["delta_cmd_left_rad"] - 15.0 * deg) < 1e-3)[-1]])
    # the last command is kept for no_command_s (0.5 s), then the hold
    sel = t["t_s"] > last + 0.01
    sel[-1] = False               # the final row is measured at the end, not a frame flown
    # the cruise's backup damper adds its increment on the rates the plant measured
    # (plant_sim/hold.py; the 0.5 s at 15 deg pitched the vehicle up): taken out here
    damper = damper_increments(load("cruise").data["servo"], t["meas_p_rad_s"][sel],
                               t["meas_q_rad_s"][sel], t["meas_r_rad_s"][sel],
                               t["meas_ssa_rad"][sel])[:, 0]
    held = t["delta_cmd_left_rad"][sel] - damper
    print(f"\nlast 15 deg command until t={last:.3f} s; run to {t['t_s'][-1]:.3f} s; "
          f"held {np.degrees(held[:3])} deg (+ damper {np.degrees(damper[:3])} deg)")
    assert held.size > 50
    # the mean of +-2 deg (and one 15 deg frame; under load not every answer is applied): near
    # 0, nowhere near the last 15 deg, and constant through the silence
    assert np.all(np.abs(held) < 1.0 * deg), np.degrees(held[:5])
    assert np.ptp(held) < 1e-9
