"""Loop-lateness figures of the fc in real time with the plant running (issue 4 closing note).

Starts ``python -m fc --mode realtime --fast-hz F`` and ``python -m plant_sim run --mode
realtime`` on free loopback ports, flies the scenario for ``--duration`` wall seconds, stops
both with SIGINT, and prints the fast loop's wake-up lateness from fc_internals.npz
(median, p99, p99.9, max, share of ticks more than 20 % of a period late) plus the
execution time per tick. Ticks before ``--warmup`` seconds are dropped (numba cache load).

    python -m tools.bench fc-timing --fast-hz 500 1000 --duration 20

Figures only; nothing here asserts a timing goal.
"""
from __future__ import annotations

import argparse
import json
import os
import socket
import sys
import tempfile
import threading

import numpy as np

from tools.sitl.procs import Child, free_udp_port

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def _flood(port: int, stop: threading.Event, counter: list) -> None:
    """Blast the fc's GCS port: valid PARAM_REQUEST_LIST frames and garbage, as fast as possible."""
    os.environ["MAVLINK20"] = "1"
    from pymavlink.dialects.v20 import ardupilotmega as mavlink

    class _Null:
        def write(self, _b):
            return None

    mav = mavlink.MAVLink(_Null(), srcSystem=255, srcComponent=190)
    req = mav.param_request_list_encode(1, 1).pack(mav)
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    n = 0
    while not stop.is_set():
        try:
            sock.sendto(req if n % 2 else b"\xfd\x09\x00\x00garbage-garbage", ("127.0.0.1", port))
        except OSError:
            pass
        n += 1
    counter.append(n)
    sock.close()


def measure(fast_hz: float, slow_hz: float, duration_s: float, warmup_s: float, out: str,
            scenario: str, spin_us: int, rt_priority: int, flood: bool = False) -> dict:
    plant_port = free_udp_port()
    gcs_bind = free_udp_port()
    tag = f"{int(fast_hz)}{'_flood' if flood else ''}"
    fc_dir = os.path.join(out, f"fc_{tag}")
    plant_dir = os.path.join(out, f"plant_{tag}")
    stop_flood = threading.Event()
    flood_count: list = []
    fc = Child("fc", [sys.executable, "-m", "fc", "--mode", "realtime", "--fast-hz", str(fast_hz),
                      "--slow-hz", str(slow_hz), "--plant-bind", f"127.0.0.1:{plant_port}",
                      "--gcs-bind", f"127.0.0.1:{gcs_bind}", "--gcs",
                      f"127.0.0.1:{free_udp_port()}", "--out", fc_dir,
                      "--arm", "--flight-mode", "COORDINATED", "--spin-us", str(spin_us),
                      "--rt-priority", str(rt_priority)], None, cwd=REPO)
    try:
        fc.wait_for_line("READY", 90)
        plant = Child("plant", [sys.executable, "-m", "plant_sim", "run", "--scenario", scenario,
                                "--mode", "realtime", "--fc", f"127.0.0.1:{plant_port}",
                                "--bind", "127.0.0.1:0", "--out", plant_dir, "--duration",
                                str(duration_s + warmup_s + 5.0)], None, cwd=REPO)
        if flood:   # from the end of the warm-up, so the plant's start-up is not starved
            threading.Timer(warmup_s, lambda: threading.Thread(
                target=_flood, args=(gcs_bind, stop_flood, flood_count), daemon=True).start()
            ).start()
        try:
            plant.wait_exit(duration_s + warmup_s + 2.0)
        finally:
            stop_flood.set()
            plant.stop(int_wait_s=20.0, term_wait_s=None)
    finally:
        rc = fc.stop(int_wait_s=20.0, term_wait_s=None)
    sys.path.insert(0, REPO)
    from fc.internals_log import load
    log = load(fc_dir)
    wall = log["wall_s"]
    keep = (wall >= wall[0] + warmup_s) & (wall < wall[0] + warmup_s + duration_s)
    late_us = log["lateness_us"][keep]
    exec_us = log["exec_us"][keep]
    period_us = 1e6 / fast_hz
    flying = log["stamp_us"][keep] > 0
    with open(os.path.join(fc_dir, "fc.log")) as f:
        sched = [ln.split(" ", 3)[-1].strip() for ln in f if "scheduling" in ln]
    return {
        "fast_hz": fast_hz, "slow_hz": slow_hz, "ticks": int(late_us.size),
        "gcs_flood_datagrams": flood_count[0] if flood_count else 0,
        "wall_s": float(wall[keep][-1] - wall[keep][0]) if late_us.size else 0.0,
        "share_ticks_with_plant_data": float(flying.mean()) if flying.size else 0.0,
        "late_median_us": float(np.median(late_us)), "late_p99_us": float(np.percentile(late_us, 99)),
        "late_p999_us": float(np.percentile(late_us, 99.9)), "late_max_us": float(late_us.max()),
        "late_share_over_20pct": float(np.mean(late_us > 0.2 * period_us)),
        "exec_median_us": float(np.median(exec_us)), "exec_p99_us": float(np.percentile(exec_us, 99)),
        "fc_exit_code": rc, "scheduling": sched[0] if sched else "?",
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m tools.bench fc-timing", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--fast-hz", type=float, nargs="+", default=[500.0, 1000.0],
                    help="fast-loop rates to measure, one run each, Hz (default 500 1000)")
    ap.add_argument("--slow-hz", type=float, default=100.0,
                    help="the fc's slow-loop rate, Hz (default 100)")
    ap.add_argument("--duration", type=float, default=20.0, help="measured wall seconds per rate")
    ap.add_argument("--warmup", type=float, default=3.0, help="seconds dropped at the start")
    ap.add_argument("--scenario", default="paper",
                    help="plant scenario name or TOML path (default paper)")
    ap.add_argument("--spin-us", type=int, default=0,
                    help="passed to the fc: busy-wait this many us before a deadline (default 0)")
    ap.add_argument("--rt-priority", type=int, default=50,
                    help="passed to the fc: SCHED_FIFO priority, 0 = do not ask (default 50)")
    ap.add_argument("--gcs-flood", action="store_true",
                    help="also flood the fc's GCS port (PARAM_REQUEST_LIST + garbage) during the run")
    ap.add_argument("--out", help="directory for the runs (default: a temporary one)")
    ap.add_argument("--json", action="store_true", help="print JSON instead of a table")
    args = ap.parse_args(argv)
    out = args.out or tempfile.mkdtemp(prefix="fc_timing_")
    rows = [measure(hz, args.slow_hz, args.duration, args.warmup, out, args.scenario,
                    args.spin_us, args.rt_priority, args.gcs_flood) for hz in args.fast_hz]
    if args.json:
        print(json.dumps(rows, indent=2))
        return 0
    print(f"runs in {out}")
    if args.gcs_flood:
        print("GCS flood datagrams sent: " + ", ".join(str(r["gcs_flood_datagrams"]) for r in rows))
    print("| fast Hz | ticks | ticks with plant data | late median us | p99 us | p99.9 us | max us | late >20% of T "
          "| exec median us | exec p99 us | scheduling |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['fast_hz']:.0f} | {r['ticks']} | {100 * r['share_ticks_with_plant_data']:.1f} % "
              f"| {r['late_median_us']:.0f} "
              f"| {r['late_p99_us']:.0f} | {r['late_p999_us']:.0f} | {r['late_max_us']:.0f} "
              f"| {100 * r['late_share_over_20pct']:.2f} % | {r['exec_median_us']:.0f} "
              f"| {r['exec_p99_us']:.0f} | {r['scheduling']} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
