"""The real-time wake-up floor: the fc's frame-synchronised wait with no work (tools.bench).

    python -m tools.bench.rtfloor --plant-bind HOST:PORT --out FILE.json [--rt-priority 50]

A bare receiver standing in for the fc in ``tools.bench``'s real-time rows: the fc's plant
link (fc/link.py ``PlantLink`` on a ``UdpEndpoint`` with the kernel's receive stamps), the
same scheduling request as ``python -m fc --mode realtime`` (fc/scheduler.py
``try_realtime``: SCHED_FIFO at ``--rt-priority``, 1 ns timer slack, 0 us CPU wake-up
latency), the same wait (``select`` on the plant socket) and the same lateness as the fc's
frame ticks (fc/loops.py ``_run_realtime_frame``: wall clock at the wake-up minus the kernel's
receive stamp of the frame, ns). Each frame is answered at once with a fixed
SERVO_OUTPUT_RAW (its stamp echoed), so the measuring stand-in plant runs as against the fc.
No law, no estimator, no ground station, no log: what is left is the host's own cost of waking
a process on a datagram, the floor under the fc's wake-up lateness on the same machine at the
same time.

Ends after ``--idle-s`` without a datagram (the stand-in finished) and writes ``--out``:
the lateness figures in us (median, p99, max, share of frames later than 20 % of
``--period-us``), one per wake-up that found a frame (``frames``: as the fc's ticks, the
first frame's stamp), and the frames answered. Exits 0; 2 with a one-line reason on a bad argument.
"""
from __future__ import annotations

import argparse
import json
import select
import sys
import time

import numpy as np

__all__ = ["lateness_figures", "main"]

PLANT_SYSID = 2
FC_SYSID = 1
MAX_FRAMES = 1 << 20        # preallocated lateness record (about 17 min at 1 kHz)


def lateness_figures(lateness_ns: np.ndarray, period_us: float, skip: int = 0) -> dict:
    """Median / p99 / max (us) and the share (%) later than 20 % of ``period_us`` of the
    lateness record ``lateness_ns`` (ns), the first ``skip`` frames left out (warm-up)."""
    lat_us = np.asarray(lateness_ns, dtype=float)[skip:] * 1e-3
    if lat_us.size == 0:
        nan = float("nan")
        return {"frames": 0, "lateness_median_us": nan, "lateness_p99_us": nan,
                "lateness_max_us": nan, "late_20pct_share_pct": nan}
    return {"frames": int(lat_us.size),
            "lateness_median_us": float(np.median(lat_us)),
            "lateness_p99_us": float(np.percentile(lat_us, 99)),
            "lateness_max_us": float(lat_us.max()),
            "late_20pct_share_pct": float((lat_us > 0.2 * period_us).mean() * 100.0)}


def main(argv: list[str] | None = None) -> int:
    from fc.link import M_N, PlantLink
    from fc.scheduler import try_realtime
    from hyfc_wire.udp import UdpEndpoint, parse_hostport
    ap = argparse.ArgumentParser(prog="python -m tools.bench.rtfloor", description=__doc__.split(
        "\n\n")[0])
    ap.add_argument("--plant-bind", required=True, help="HOST:PORT to receive sensor frames on")
    ap.add_argument("--out", required=True, help="JSON file for the figures")
    ap.add_argument("--rt-priority", type=int, default=50,
                    help="SCHED_FIFO priority as the fc asks for it, 0 = do not ask (default 50)")
    ap.add_argument("--period-us", type=float, default=1000.0,
                    help="the frame period, for the share of late frames (default 1000)")
    ap.add_argument("--skip", type=int, default=1000,
                    help="frames left out at the start (warm-up; default 1000)")
    ap.add_argument("--idle-s", type=float, default=2.0,
                    help="end after this long without a datagram (default 2 s)")
    args = ap.parse_args(argv)
    try:
        host, port = parse_hostport(args.plant_bind, "--plant-bind")
    except ValueError as exc:
        print(f"rtfloor: {exc}", file=sys.stderr)
        return 2
    if args.rt_priority > 0:
        ok, msg = try_realtime(args.rt_priority)
    else:
        ok, msg = False, "SCHED_OTHER (not asked)"
    try:
        ep = UdpEndpoint(host, port)
    except OSError as exc:
        print(f"rtfloor: {exc}", file=sys.stderr)
        return 2
    stamped = ep.enable_rx_timestamps()
    link = PlantLink(ep, plant_sysid=PLANT_SYSID, sysid=FC_SYSID)
    meas = np.zeros(M_N)
    pwm = np.array([1500, 1500, 1500, 0], dtype=np.int64)
    lateness_ns = np.zeros(MAX_FRAMES, dtype=np.int64)
    n = 0                   # wake-ups with a frame: one lateness each (the first frame's)
    answered = 0            # frames answered
    fds = [ep.fileno()]
    print("READY", flush=True)
    wall_ns = time.time_ns
    while True:
        ready = select.select(fds, [], [], args.idle_s)[0]
        if not ready:
            break
        wake_wall = wall_ns()
        got_frame = False
        while True:                         # drain, as the fc's _rt_drain
            stamp = link.read_frame(meas)
            if stamp < 0:
                break
            if not got_frame and n < MAX_FRAMES:
                lateness_ns[n] = wake_wall - link.frame_rx_ns if stamped else 0
                n += 1
            got_frame = True
            answered += 1
            link.send_servo(stamp, pwm)
    res = lateness_figures(lateness_ns[:n], args.period_us, args.skip)
    res.update({"frames_answered": answered, "sched_fifo": ok, "scheduling": msg, "rx_timestamps": stamped})
    with open(args.out, "w", encoding="utf-8") as fh:
        json.dump(res, fh, indent=1)
    print("DONE", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
