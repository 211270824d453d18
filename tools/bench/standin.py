"""A measuring stand-in for the plant process (tools.bench only; not a plant replacement).

    python -m tools.bench.standin --fc HOST:PORT --mode lockstep|realtime --frame-hz F
                                  --duration S --out FILE.json [--scenario paper]

It runs the real plant physics (``plant_sim.sim.PlantSim``, the scenario's RK4 at its
physics rate, sensors, actuators) and speaks the wire protocol of docs/wire.md to the fc with
the plant's own link codec (``plant_sim.link``), like ``python -m plant_sim run``, but it
also records what a benchmark needs and the plant process
does not report: the wall time at which each sensor frame k was sent and the time at which the
first SERVO_OUTPUT_RAW echoing k came back (sensor-to-servo latency, measured at the plant).

- lockstep: send frame k, wait (``select``, bounded) for its echo, apply it, advance one frame;
  re-send after ``--rerequest-timeout``. Real-time factor = sim time / wall time.
- realtime: frames on absolute wall-clock deadlines at ``--frame-hz``; between deadlines it
  waits in ``select`` with a microsecond timeout so an echo is time-stamped when it arrives;
  the latest command is applied at the next frame.

Writes ``--out`` (JSON) with the figures and exits 0; exits 2 with a one-line reason if the fc
stops answering. Prints ``DONE`` when the file is written.
"""
from __future__ import annotations

import argparse
import copy
import json
import math
import os
import select
import sys
import time

import numpy as np

from fc.link import (M_AIRSPEED, M_ALT, M_AOA, M_CLIMB, M_GROUNDSPEED, M_HEADING, M_N, M_P,
                     M_PITCH, M_Q, M_R, M_ROLL, M_SSA, M_YAW, UdpEndpoint, decode_datagram,
                     mavlink, new_codec, parse_hostport, pwm_to_deflection)

PLANT_SYSID = 2
WARMUP_FRAMES = 50          # not counted in the latency / RTF figures


def _summ(ns: np.ndarray) -> dict:
    us = np.asarray(ns, dtype=np.float64) * 1e-3
    if us.size == 0:
        nan = float("nan")
        return {"n": 0, "median_us": nan, "p99_us": nan, "max_us": nan, "mean_us": nan}
    return {"n": int(us.size), "median_us": float(np.median(us)),
            "p99_us": float(np.percentile(us, 99)), "max_us": float(us.max()),
            "mean_us": float(us.mean())}


class FrameCodec:
    """Sensor frame encoder / servo echo decoder (docs/wire.md sections 2-3), pymavlink's
    generic codec (used where no plant link is at hand: start-up probe, tests)."""

    def __init__(self) -> None:
        self.tx = new_codec(PLANT_SYSID)
        self.rx = new_codec(PLANT_SYSID)

    def encode(self, meas: np.ndarray, stamp_us: int) -> bytes:
        c = self.tx
        deg = math.degrees
        out = c.attitude_encode((stamp_us // 1000) & 0xFFFFFFFF, meas[M_ROLL], meas[M_PITCH],
                                meas[M_YAW], meas[M_P], meas[M_Q], meas[M_R]).pack(c)
        c.seq = (c.seq + 1) % 256
        out += c.aoa_ssa_encode(stamp_us, deg(meas[M_AOA]), deg(meas[M_SSA])).pack(c)
        c.seq = (c.seq + 1) % 256
        hdg = int(round(deg(meas[M_HEADING]))) % 360
        out += c.vfr_hud_encode(meas[M_AIRSPEED], meas[M_GROUNDSPEED], hdg, 0, meas[M_ALT],
                                meas[M_CLIMB]).pack(c)
        c.seq = (c.seq + 1) % 256
        return out

    def servo(self, data: bytes):
        """(time_usec, (s1, s2, s3)) of the SERVO_OUTPUT_RAW in ``data``, or None."""
        msgs, _bad = decode_datagram(self.rx, data)
        for m in msgs:
            if m.get_msgId() == mavlink.MAVLINK_MSG_ID_SERVO_OUTPUT_RAW:
                return int(m.time_usec), (m.servo1_raw, m.servo2_raw, m.servo3_raw)
        return None


class PlantWire:
    """The plant process's own link codec (``plant_sim.link``: lean encoder, lean servo
    decoder) on this stand-in's socket, so the stand-in costs what the plant costs."""

    def __init__(self, sim, fc: tuple) -> None:
        from plant_sim import dynamics as dy
        from plant_sim.link import PlantLink, PwmMap
        sv = sim.scenario.data["servo"]
        self.pwm = PwmMap(sv["pwm_min_us"], sv["pwm_trim_us"], sv["pwm_max_us"],
                          float(sim.p[dy.P_ACT_LIMIT]))
        self.link = PlantLink(fc, ("127.0.0.1", 0), self.pwm)
        self.sock = self.link.sock
        self._generic = FrameCodec()
        self._rx = UdpEndpoint.wrap(self.sock)      # the fc's receive path (kernel stamps)

    def send(self, meas: np.ndarray, stamp_us: int) -> None:
        self.link.build_sensors(stamp_us, meas, 0.0)
        self.link.send_sensors()

    def enable_rx_timestamps(self) -> bool:
        """Kernel receive stamps on this socket (``SO_TIMESTAMPNS``, CLOCK_REALTIME): ``recv``
        then sets ``rx_ns``, the time an echo arrived whatever this process was doing."""
        return self._rx.enable_rx_timestamps()

    @property
    def rx_ns(self) -> int:
        return self._rx.rx_ns

    def recv(self):
        return self._rx.recv()

    def servo(self, data: bytes):
        """(time_usec, (s1, s2, s3)) of a SERVO_OUTPUT_RAW datagram, or None."""
        r = self.link.decode_servo(data)
        if r is not None:
            return r[1], (r[2], r[3], r[4])
        return self._generic.servo(data)

    def to_rad(self, pwm: int) -> float:
        return self.pwm.to_rad(pwm)

    def fileno(self) -> int:
        return self.sock.fileno()

    def close(self) -> None:
        self.link.close()


def make_sim(scenario: str, frame_hz: float):
    from plant_sim.scenario import load
    from plant_sim.sim import PlantSim
    sc = copy.deepcopy(load(scenario))
    tm = sc.data["timing"]
    tm["frame_hz"] = float(frame_hz)
    if tm["physics_hz"] < frame_hz:
        tm["physics_hz"] = float(frame_hz)
    n = tm["physics_hz"] / frame_hz
    if abs(n - round(n)) > 1e-9:
        raise ValueError(f"physics rate {tm['physics_hz']} Hz is not a multiple of {frame_hz} Hz")
    return PlantSim(sc)


def _apply(cmd: np.ndarray, pwm, wire=None) -> None:
    for i in range(3):
        if pwm[i]:
            cmd[i] = wire.to_rad(pwm[i]) if wire is not None else pwm_to_deflection(pwm[i])


def run_lockstep(ep: PlantWire, fc: tuple, sim, duration_s: float, rerequest_s: float,
                 give_up_s: float) -> dict:
    codec = ep
    meas = np.zeros(M_N)
    cmd = sim.cmd_rad.copy()
    n = int(round(duration_s / sim.frame_dt_s)) + WARMUP_FRAMES
    rtt = np.zeros(n, dtype=np.int64)
    fd = ep.fileno()
    rereq = 0
    pc = time.perf_counter_ns
    t_start = 0
    for k in range(n):
        if k == WARMUP_FRAMES:
            t_start = pc()
        sim.measure(meas)
        stamp = int(round(sim.t_s * 1e6))
        t_send = pc()
        ep.send(meas, stamp)
        last_send = t_send
        while True:
            r, _, _ = select.select([fd], [], [], rerequest_s)
            if not r:
                if (pc() - t_send) * 1e-9 > give_up_s:
                    raise RuntimeError(f"fc did not answer frame {k} within {give_up_s:.0f} s")
                rereq += 1
                ep.link.send_sensors()
                last_send = pc()
                continue
            got = ep.recv()
            if got is None:
                continue
            s = codec.servo(got[0])
            if s is not None and s[0] == stamp & 0xFFFFFFFF:
                rtt[k] = pc() - last_send
                _apply(cmd, s[1], ep)
                break
        sim.step_frame(cmd)
    wall_s = (pc() - t_start) * 1e-9
    sim_s = (n - WARMUP_FRAMES) * sim.frame_dt_s
    return {"mode": "lockstep", "frames": n - WARMUP_FRAMES, "sim_time_s": sim_s,
            "wall_time_s": wall_s, "real_time_factor": sim_s / wall_s, "rerequests": rereq,
            "exchange": _summ(rtt[WARMUP_FRAMES:])}


def run_realtime(ep: PlantWire, fc: tuple, sim, duration_s: float) -> dict:
    """Wall-clock frames; latency of frame k = first echo of k - send time of k.

    Both ends of the latency are on CLOCK_REALTIME: the send time is read right after
    ``sendto`` returns, the echo's is the kernel's receive stamp (``SO_TIMESTAMPNS``), so an
    echo that arrives while this process is busy (physics, encoding) or descheduled is not
    charged to the fc. Where the stamps are not available the echo is timed when this process
    reads it (an upper bound). The garbage collector is kept off the loop (``freeze_heap``),
    as in the fc."""
    from fc.scheduler import freeze_heap, try_realtime
    rt_ok, rt_msg = try_realtime(50)
    freeze_heap()
    stamped = ep.enable_rx_timestamps()
    wall = time.time_ns
    codec = ep
    meas = np.zeros(M_N)
    cmd = sim.cmd_rad.copy()
    period_ns = int(round(sim.frame_dt_s * 1e9))
    period_us = period_ns // 1000
    n = int(round(duration_s / sim.frame_dt_s)) + WARMUP_FRAMES
    sent_ns = np.zeros(n, dtype=np.int64)
    echo_ns = np.zeros(n, dtype=np.int64)
    send_late_ns = np.zeros(n, dtype=np.int64)
    fd = ep.fileno()
    mono = time.monotonic_ns
    stamp0 = int(round(sim.t_s * 1e6))
    echoes = 0
    stale = 0
    nxt = mono() + period_ns
    k = 0
    last_echo_ns = mono()
    while k < n:
        while True:
            now = mono()
            if now >= nxt:
                break
            r, _, _ = select.select([fd], [], [], (nxt - now) * 1e-9)
            if not r:
                continue
            t_rx = wall()
            for _ in range(64):
                got = ep.recv()
                if got is None:
                    break
                s = codec.servo(got[0])
                if s is None:
                    continue
                echoes += 1
                last_echo_ns = mono()
                j = int(round(((s[0] - stamp0) & 0xFFFFFFFF) / period_us))
                if 0 <= j < k and echo_ns[j] == 0:
                    echo_ns[j] = ep.rx_ns if (stamped and ep.rx_ns) else t_rx
                else:
                    stale += 1
                _apply(cmd, s[1], ep)
        now = mono()
        send_late_ns[k] = now - nxt
        if k > 0:
            sim.command(cmd)
            sim.advance()
        sim.measure(meas)
        stamp = int(round(sim.t_s * 1e6))
        ep.send(meas, stamp)
        sent_ns[k] = wall()
        k += 1
        nxt += period_ns
        if mono() - nxt > 50 * period_ns:       # far behind (stall): re-anchor, do not burst
            nxt = mono() + period_ns
        if echoes and mono() - last_echo_ns > 5_000_000_000:
            raise RuntimeError("fc stopped answering (no SERVO_OUTPUT_RAW for 5 s)")
    # collect the last echoes for a moment
    t_end = mono() + 20 * period_ns
    while mono() < t_end:
        r, _, _ = select.select([fd], [], [], 0.001)
        if r:
            t_rx = wall()
            got = ep.recv()
            if got is not None:
                s = codec.servo(got[0])
                if s is not None:
                    j = int(round(((s[0] - stamp0) & 0xFFFFFFFF) / period_us))
                    if 0 <= j < n and echo_ns[j] == 0:
                        echo_ns[j] = ep.rx_ns if (stamped and ep.rx_ns) else t_rx
    sl = slice(WARMUP_FRAMES, n)
    answered = echo_ns[sl] > 0
    lat = (echo_ns[sl] - sent_ns[sl])[answered]
    return {"mode": "realtime", "frames": n - WARMUP_FRAMES, "frame_hz": 1e9 / period_ns,
            "answered_share": float(answered.mean()) if answered.size else 0.0,
            "stale_echoes": stale, "sched_fifo": rt_ok, "sched_msg": rt_msg,
            "echo_time": "kernel receive stamp" if stamped else "read time",
            "latency": _summ(lat), "send_lateness": _summ(send_late_ns[sl])}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m tools.bench.standin")
    ap.add_argument("--fc", required=True, help="HOST:PORT the fc binds for the plant link")
    ap.add_argument("--mode", choices=("lockstep", "realtime"), default="lockstep",
                    help="lockstep: wait for each frame's echo; realtime: frames on wall-clock "
                         "deadlines (default lockstep)")
    ap.add_argument("--frame-hz", type=float, default=500.0,
                    help="sensor frame rate, Hz (default 500)")
    ap.add_argument("--duration", type=float, default=5.0, help="sim seconds (lockstep) or "
                    "wall seconds (realtime) measured, after a short warm-up")
    ap.add_argument("--scenario", default="paper",
                    help="plant scenario name or TOML path (default paper)")
    ap.add_argument("--rerequest-timeout", type=float, default=0.2, metavar="S",
                    help="lockstep: re-send a frame not echoed within S seconds (default 0.2)")
    ap.add_argument("--give-up", type=float, default=10.0, metavar="S",
                    help="lockstep: exit 2 when a frame stays unanswered for S seconds "
                         "(default 10)")
    ap.add_argument("--out", required=True, help="JSON file for the figures")
    args = ap.parse_args(argv)
    try:
        fc = parse_hostport(args.fc)
        sim = make_sim(args.scenario, args.frame_hz)
        ep = PlantWire(sim, fc)
    except (ValueError, OSError) as exc:
        print(f"standin: {exc}", file=sys.stderr)
        return 2
    print("READY", flush=True)
    try:
        if args.mode == "lockstep":
            res = run_lockstep(ep, fc, sim, args.duration, args.rerequest_timeout, args.give_up)
        else:
            res = run_realtime(ep, fc, sim, args.duration)
    except RuntimeError as exc:
        print(f"standin: {exc}", file=sys.stderr)
        return 2
    finally:
        ep.close()
    res["scenario"] = args.scenario
    res["physics_hz"] = 1.0 / sim.physics_dt_s
    res["peak_rss_mb"] = _peak_rss_mb()
    with open(args.out, "w", encoding="utf-8") as f:
        json.dump(res, f, indent=2)
    print("DONE", flush=True)
    return 0


def _peak_rss_mb() -> float:
    """VmHWM of this process (MB), NaN if /proc is not there."""
    try:
        with open(f"/proc/{os.getpid()}/status", encoding="ascii") as f:
            for line in f:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return float("nan")


if __name__ == "__main__":
    raise SystemExit(main())
