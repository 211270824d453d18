"""Plant benchmark: cost per RK4 step, plant-side cost per frame, lockstep exchanges per second.

    python -m tools.bench plant [--scenario paper] [--seconds 20] [--lockstep-seconds 10]

Prints (medians of repeated batches; the machine is shared, so read the spread too):
1. RK4 step (us): the whole loop inside numba (dynamics.advance_frames), and one
   PlantSim.step_frame call from Python per frame divided by the steps per frame.
2. The plant's per-frame path without the network (us): decode one SERVO_OUTPUT_RAW datagram,
   PWM -> rad, latch, truth row, advance, measure, frame the three sensor messages, as the
   lockstep loop does (one compiled call, plant_sim/frame_path.py); and the same work through
   the earlier Python path (build_sensors, decode_rx, to_rad, PlantSim.frame) for comparison.
3. Lockstep: `python -m plant_sim run --mode lockstep` as a process against a trivial
   responder in this process (decode the stamp, answer with a fixed PWM); exchanges per second
   and the real-time factor from plant_summary.json.
4. If the optional jsbsim package is installed: JSBSim's X-15 at dt 1/1000 s, us per
   fdm.run() (perf_anchors.md section 4 method: outputs off, airborne initial condition,
   reset before each batch), in the same process for comparison.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from plant_sim import dynamics as dy
from hyfc_wire.pwm import DEFAULT_PWM
from plant_sim.link import PlantLink, PwmMap, ServoResponder
from plant_sim.scenario import load
from plant_sim.sim import PlantSim
from tools.sitl.procs import run_serving


def _median_spread(vals):
    vals = sorted(vals)
    return statistics.median(vals), vals[0], vals[-1]


def bench_rk4(sc_name: str, sim_seconds: float, batches: int = 7):
    sim = PlantSim(load(sc_name))
    x, p, w, n_sub = sim.x, sim.p, sim.w, sim.n_sub
    cmd = np.array([0.02, 0.03, 0.0])
    dy.advance_frames(x, cmd, p, w, n_sub, 10)          # compile / cache load
    n_frames = int(sim_seconds / sim.frame_dt_s / batches)
    kernel, python = [], []
    for _ in range(batches):
        sim.reset()
        t = time.perf_counter()
        dy.advance_frames(x, cmd, p, w, n_sub, n_frames)
        kernel.append((time.perf_counter() - t) / (n_frames * n_sub) * 1e6)
        sim.reset()
        t = time.perf_counter()
        for _ in range(n_frames):
            sim.step_frame(cmd)
        python.append((time.perf_counter() - t) / (n_frames * n_sub) * 1e6)
    return _median_spread(kernel), _median_spread(python), n_sub


def bench_frame_path(sc_name: str, frames: int = 5000, batches: int = 5):
    """The lockstep loop's per-frame work as the plant process does it now, without the
    network: one ``plant_sim.frame_path.lockstep_frame_p`` call per frame that decodes the
    servo datagram in the receive buffer, maps PWM to rad, writes the truth row into the truth
    log's block (flushed to a temporary file when full, as in a run), advances the frame,
    measures and frames the next sensor datagram (``MODE_DECODE | MODE_ENCODE``: no receive,
    no send). (median, min, max) us per frame over ``batches`` batches of ``frames``."""
    from plant_sim.frame_path import MODE_DECODE, MODE_ENCODE, B_FLUSH, FramePath, lockstep_frame_p
    from plant_sim.truthlog import TruthWriter
    sc = load(sc_name)
    sim = PlantSim(sc)
    sv = sc.data["servo"]
    pwm = PwmMap(sv["pwm_min_us"], sv["pwm_trim_us"], sv["pwm_max_us"], sim.p[dy.P_ACT_LIMIT])
    resp = ServoResponder()
    link = PlantLink(("127.0.0.1", resp.addr[1]), ("127.0.0.1", 0), pwm)
    res = []
    with tempfile.TemporaryDirectory() as tmp:
        writer = TruthWriter(tmp, sim.TRUTH_NAMES)
        fp = FramePath(sim, link, writer, 1e-4)
        n_servo = link.put_rx(resp.servo_frame(0, (1510, 1490, 1500)))  # as a receive leaves it
        fp.set_rx_len(n_servo)
        step, a, mode = lockstep_frame_p, fp.addr, MODE_DECODE | MODE_ENCODE
        for _ in range(batches):
            sim.reset()
            sim.measure(sim.last_meas)
            fp.enter()
            t = time.perf_counter()
            for _ in range(frames):
                # frame 0 each time: the datagram's stamp answers it (the work does not depend
                # on k); the next frame's datagram is framed with stamp 2000 us
                if step(a, 0, mode, 0) & B_FLUSH:
                    fp.flush_truth()
            res.append((time.perf_counter() - t) / frames * 1e6)
            fp.leave()
        writer.close()
    link.close()
    resp.close()
    return _median_spread(res)


def bench_frame_physics(sc_name: str, frames: int = 5000, batches: int = 5):
    """The floor under :func:`bench_frame_path`: the same compiled frame without the wire
    (``lockstep_frame_p`` with mode 0: truth row, two RK4 steps, sensors) called from a loop
    inside numba, so no Python call either. (median, min, max) us per frame."""
    from plant_sim.frame_path import FramePath, physics_loop
    from plant_sim.truthlog import TruthWriter
    sc = load(sc_name)
    sim = PlantSim(sc)
    resp = ServoResponder()
    link = PlantLink(("127.0.0.1", resp.addr[1]), ("127.0.0.1", 0), DEFAULT_PWM)
    res = []
    with tempfile.TemporaryDirectory() as tmp:
        # every row decimated: no block fills, the loop never needs Python
        writer = TruthWriter(tmp, sim.TRUTH_NAMES, full_rows=0, every=1 << 40)
        fp = FramePath(sim, link, writer, 1e-4)
        physics_loop(fp.addr, 1)
        for _ in range(batches):
            sim.reset()
            sim.measure(sim.last_meas)
            fp.enter()
            t = time.perf_counter()
            physics_loop(fp.addr, frames)
            res.append((time.perf_counter() - t) / frames * 1e6)
            fp.leave()
        writer.close()
    link.close()
    resp.close()
    return _median_spread(res)


def bench_frame_path_python(sc_name: str, frames: int = 5000, batches: int = 5):
    """The per-frame path before the compiled frame (plant_sim/frame_path.py), kept to
    reproduce the earlier figure: ``build_sensors``, ``decode_rx``, ``PwmMap.to_rad`` and
    ``PlantSim.frame`` from Python, the truth row into a fixed array."""
    sc = load(sc_name)
    sim = PlantSim(sc)
    sv = sc.data["servo"]
    pwm = PwmMap(sv["pwm_min_us"], sv["pwm_trim_us"], sv["pwm_max_us"], sim.p[dy.P_ACT_LIMIT])
    resp = ServoResponder()
    link = PlantLink(("127.0.0.1", resp.addr[1]), ("127.0.0.1", 0), pwm)
    row = np.zeros(sim.TRUTH_N)
    cmd = np.zeros(3)
    n_servo = link.put_rx(resp.servo_frame(0, (1510, 1490, 1500)))  # as recvfrom_into leaves it
    res = []
    x = sim.x
    for _ in range(batches):
        sim.reset()
        sim.measure(sim.last_meas)
        t = time.perf_counter()
        for k in range(frames):
            link.build_sensors(k * 2000, sim.last_meas, x[dy.X_THRUST] * 1e-4)
            _, _, s1, s2, s3, _ = link.decode_rx(n_servo)
            cmd[0] = pwm.to_rad(s1)
            cmd[1] = pwm.to_rad(s2)
            cmd[2] = pwm.to_rad(s3)
            sim.frame(cmd, row)
        res.append((time.perf_counter() - t) / frames * 1e6)
    link.close()
    resp.close()
    return _median_spread(res)


def bench_lockstep(sc_name: str, sim_seconds: float):
    resp = ServoResponder()
    with tempfile.TemporaryDirectory() as tmp:
        argv = [sys.executable, "-m", "plant_sim", "run", "--scenario", sc_name, "--mode",
                "lockstep", "--fc", f"127.0.0.1:{resp.addr[1]}", "--bind", "127.0.0.1:0",
                "--out", tmp, "--duration", str(sim_seconds), "--progress-every", "0"]
        try:
            proc = run_serving("plant", argv, lambda: resp.serve_fast(timeout_s=0.5), 300.0)
        finally:
            resp.close()
        if proc.poll() != 0:
            raise SystemExit(f"plant failed: {proc.death_message()}")
        return json.loads((Path(tmp) / "plant_summary.json").read_text())


def bench_jsbsim(batches: int = 7, steps: int = 2000):
    """us per JSBSim X-15 step at 1 kHz, or None without jsbsim."""
    try:
        import jsbsim
    except ImportError:
        return None
    sys.stdout.flush()
    saved = os.dup(1)                       # JSBSim prints a banner from C++: keep stdout clean
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, 1)
    try:
        fdm = jsbsim.FGFDMExec(jsbsim.get_default_root_dir())
        fdm.set_debug_level(0)
        loaded = fdm.load_model("X15")
    finally:
        os.dup2(saved, 1)
        os.close(saved)
        os.close(devnull)
    if not loaded:
        return None
    fdm.disable_output()
    fdm.set_dt(1.0 / 1000.0)
    fdm["ic/h-sl-ft"] = 60000.0
    fdm["ic/vc-kts"] = 400.0
    fdm["ic/gamma-deg"] = 0.0
    res = []
    for _ in range(batches):
        fdm.run_ic()
        t = time.perf_counter()
        for _ in range(steps):
            fdm.run()
        res.append((time.perf_counter() - t) / steps * 1e6)
    return _median_spread(res)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m tools.bench plant", description=__doc__.split("\n")[0])
    ap.add_argument("--scenario", default="paper",
                    help="plant scenario name or TOML path (default paper)")
    ap.add_argument("--seconds", type=float, default=20.0, help="sim seconds for the RK4 batches")
    ap.add_argument("--lockstep-seconds", type=float, default=10.0, help="sim seconds of the lockstep run")
    ap.add_argument("--no-jsbsim", action="store_true", help="skip the JSBSim X-15 comparison")
    args = ap.parse_args(argv)
    (k_med, k_lo, k_hi), (p_med, p_lo, p_hi), n_sub = bench_rk4(args.scenario, args.seconds)
    print(f"rk4_step_us (loop inside numba)      median {k_med:.3f}  min {k_lo:.3f}  max {k_hi:.3f}")
    print(f"rk4_step_us (step_frame from Python, /{n_sub}) median {p_med:.3f}  min {p_lo:.3f}  max {p_hi:.3f}")
    j = None if args.no_jsbsim else bench_jsbsim()
    if j is not None:
        print(f"jsbsim_x15_step_us (dt 1 ms, same process) median {j[0]:.3f}  min {j[1]:.3f}  max {j[2]:.3f}")
    elif not args.no_jsbsim:
        print("jsbsim_x15_step_us                   n/a (jsbsim not installed)")
    f_med, f_lo, f_hi = bench_frame_path(args.scenario)
    print(f"plant_frame_path_us (no network)     median {f_med:.1f}  min {f_lo:.1f}  max {f_hi:.1f}")
    f_med, f_lo, f_hi = bench_frame_physics(args.scenario)
    print(f"plant_frame_physics_us (truth row, 2 RK4 steps, sensors; loop in numba) median "
          f"{f_med:.2f}  min {f_lo:.2f}  max {f_hi:.2f}")
    f_med, f_lo, f_hi = bench_frame_path_python(args.scenario)
    print(f"plant_frame_path_us (Python path, before the compiled frame) median {f_med:.1f}  "
          f"min {f_lo:.1f}  max {f_hi:.1f}")
    s = bench_lockstep(args.scenario, args.lockstep_seconds)
    ex = s["frames"] / s["wall_time_s"]
    print(f"lockstep_exchanges_per_s             {ex:.0f}  ({1e6 / ex:.0f} us per exchange, "
          f"rtf {s['real_time_factor']:.1f} at {s['frame_hz']:.0f} Hz frames, "
          f"{s['frames']} frames, rerequests {s['rerequests']})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
