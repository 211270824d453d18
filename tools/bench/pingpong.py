"""The loopback UDP round-trip floor: ping-pong between two processes (prints figures).

    python -m tools.bench pingpong [--n 20000] [--payload mavlink|raw] [--json FILE]

Two processes on 127.0.0.1, each with its own UDP socket. The parent sends, the child
answers, the parent times each round trip with ``time.perf_counter_ns``:

- ``mavlink``: the lockstep exchange of docs/wire.md without any simulation or control law.
  The parent encodes one sensor datagram (ATTITUDE + AOA_SSA + VFR_HUD, MAVLink 2) with a new
  stamp; the child decodes it (``fc.link.decode_datagram``) and answers a SERVO_OUTPUT_RAW
  echoing the stamp, which the parent decodes and checks. This is the floor a two-process
  lockstep cannot go below: plant + law cost come on top of it.
- ``links``: the same exchange through the two processes' own link modules: the parent
  builds and sends with ``plant_sim.link.PlantLink`` (its lean encoder) and waits for the
  answer with ``poll_for``; the child reads with ``fc.link.PlantLink.read_frame`` and answers
  with ``send_servo``. This is the lockstep floor of the code as it is: everything but the
  plant physics and the fc's estimator, law and bookkeeping.
- ``raw``: 64 bytes echoed unchanged (the kernel + CPython socket floor, no codec).

Both sides block in ``recvfrom`` with a 1 s timeout (the timeout only bounds a lost
datagram; a datagram that arrives wakes the receiver at once). The first ``n // 20`` round
trips are a warm-up and not counted. Nothing is asserted: this is a measurement.
"""
from __future__ import annotations

import argparse
import json
import signal
import socket
import sys
import time

import numpy as np

from tools.sitl.procs import Child

__all__ = ["run_pingpong", "summarize_us"]

PAYLOADS = ("mavlink", "links", "raw")
PLANT_SYSID = 2
FC_SYSID = 1
RAW_BYTES = 64
TIMEOUT_S = 1.0


def summarize_us(ns: np.ndarray) -> dict:
    """median / p99 / p99.9 / max / mean of a nanosecond array, in microseconds."""
    us = np.asarray(ns, dtype=np.float64) * 1e-3
    if us.size == 0:
        return {"n": 0, "median_us": float("nan"), "p99_us": float("nan"),
                "p999_us": float("nan"), "max_us": float("nan"), "mean_us": float("nan")}
    return {"n": int(us.size), "median_us": float(np.median(us)),
            "p99_us": float(np.percentile(us, 99)), "p999_us": float(np.percentile(us, 99.9)),
            "max_us": float(us.max()), "mean_us": float(us.mean())}


def _encode_sensor_frame(codec, mavlink, stamp_us: int) -> bytes:
    """One wire sensor datagram (docs/wire.md section 2) with plausible constant values."""
    buf = codec.attitude_encode(stamp_us // 1000, 0.01, 0.02, 0.5, 0.001, 0.002, 0.003).pack(codec)
    codec.seq = (codec.seq + 1) % 256
    buf += codec.aoa_ssa_encode(stamp_us, 2.0, 0.1).pack(codec)
    codec.seq = (codec.seq + 1) % 256
    buf += codec.vfr_hud_encode(2200.0, 2200.0, 28, 50, 25000.0, 0.5).pack(codec)
    codec.seq = (codec.seq + 1) % 256
    return buf


def _echo(payload: str) -> int:
    """Child side: bind port 0, print ``PORT n``, answer every datagram until ``b'STOP'``."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    sock.settimeout(30.0)   # bounds an idle child whose parent died
    print(f"PORT {sock.getsockname()[1]}", flush=True)
    if payload == "links":
        return _echo_links(sock)
    if payload == "mavlink":
        from fc.link import decode_datagram, mavlink, new_codec
        rx = new_codec(FC_SYSID)
        tx = new_codec(FC_SYSID)
    while True:
        try:
            data, addr = sock.recvfrom(2048)
        except socket.timeout:
            return 1
        if data == b"STOP":
            return 0
        if payload == "raw":
            sock.sendto(data, addr)
            continue
        msgs, _bad = decode_datagram(rx, data)
        stamp = 0
        for m in msgs:
            if m.get_msgId() == mavlink.MAVLINK_MSG_ID_AOA_SSA:
                stamp = int(m.time_usec)
        out = tx.servo_output_raw_encode(stamp & 0xFFFFFFFF, 0, 1500, 1500, 1500,
                                         0, 0, 0, 0, 0).pack(tx)
        tx.seq = (tx.seq + 1) % 256
        sock.sendto(out, addr)


def _echo_links(sock: socket.socket) -> int:
    """Child side of ``links``: the fc's plant link on the already bound socket."""
    import select

    from fc.link import PlantLink, UdpEndpoint
    ep = UdpEndpoint.wrap(sock)                 # the bound socket: same port as printed
    link = PlantLink(ep, plant_sysid=PLANT_SYSID, sysid=FC_SYSID)
    meas = np.zeros(14)
    pwm = [1500, 1500, 1500]
    while True:
        r, _, _ = select.select([sock], [], [], 30.0)
        if not r:
            return 1
        stamp = link.read_frame(meas)
        if stamp >= 0:
            link.send_servo(stamp, pwm)
        elif link.counters.rejected:   # the parent's STOP datagram (not MAVLink)
            return 0


def _child_alive(child) -> None:
    """A lost exchange: fail at once if the echo child died (instead of n timeouts)."""
    if child is not None and child.poll() is not None:
        raise RuntimeError(f"pingpong echo child exited with code {child.poll()}")


def _run_links(sock: socket.socket, peer: tuple, n: int, warm: int, child=None) -> dict:
    """Parent side of ``links``: the plant's link (its own socket) against the child."""
    from plant_sim.link import PlantLink, PwmMap
    link = PlantLink(peer, ("127.0.0.1", 0), PwmMap(1000, 1500, 2000, 0.349))
    meas = np.zeros(14)
    meas[9] = 2200.0
    meas[10] = 25000.0
    rtt = np.zeros(n, dtype=np.int64)
    lost = bad = 0
    pc = time.perf_counter_ns
    try:
        for i in range(warm + n):
            stamp = 1000 * (i + 1)
            meas[0] = stamp * 1e-6
            t0 = pc()
            link.build_sensors(stamp, meas, 50.0)
            link.send_sensors()
            while True:
                if not link.wait_readable(TIMEOUT_S):
                    lost += 1
                    _child_alive(child)
                    break
                _acc, match = link.poll_for(stamp & 0xFFFFFFFF)
                if match:
                    t1 = pc()
                    if i >= warm:
                        rtt[i - warm] = t1 - t0
                    break
        link.sock.sendto(b"STOP", peer)
    finally:
        link.close()
    res = summarize_us(rtt[rtt > 0])
    res.update({"payload": "links", "lost": lost, "bad": bad,
                "exchanges_per_s": 1e6 / res["median_us"] if res["n"] else float("nan")})
    return res


def run_pingpong(n: int = 20000, payload: str = "mavlink") -> dict:
    """Time ``n`` round trips to a child process; returns :func:`summarize_us` plus counts."""
    if payload not in PAYLOADS:
        raise ValueError(f"payload must be one of {PAYLOADS}, not {payload!r}")
    child = Child("pingpong-echo", [sys.executable, "-m", "tools.bench.pingpong", "--echo",
                                    "--payload", payload], None)
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        line = child.wait_for_line("PORT ", 60.0)
        peer = ("127.0.0.1", int(line.split()[1]))
        warm = max(n // 20, 10)
        if payload == "links":
            return _run_links(sock, peer, n, warm, child)
        sock.bind(("127.0.0.1", 0))
        sock.settimeout(TIMEOUT_S)
        if payload == "mavlink":
            from fc.link import decode_datagram, mavlink, new_codec
            tx = new_codec(PLANT_SYSID)
            rx = new_codec(PLANT_SYSID)
        rtt = np.zeros(n, dtype=np.int64)
        lost = 0
        bad = 0
        raw = bytes(range(RAW_BYTES))
        pc = time.perf_counter_ns
        for i in range(warm + n):
            stamp = 1000 * (i + 1)
            t0 = pc()
            if payload == "raw":
                sock.sendto(raw, peer)
            else:
                sock.sendto(_encode_sensor_frame(tx, mavlink, stamp), peer)
            try:
                data, _ = sock.recvfrom(2048)
            except socket.timeout:
                lost += 1
                _child_alive(child)
                continue
            if payload == "mavlink":
                msgs, _b = decode_datagram(rx, data)
                if not msgs or int(msgs[0].time_usec) != stamp & 0xFFFFFFFF:
                    bad += 1
            t1 = pc()
            if i >= warm:
                rtt[i - warm] = t1 - t0
        sock.sendto(b"STOP", peer)
        res = summarize_us(rtt[rtt > 0])
        res.update({"payload": payload, "lost": lost, "bad": bad,
                    "exchanges_per_s": 1e6 / res["median_us"] if res["n"] else float("nan")})
        return res
    finally:
        sock.close()
        if child.wait_exit(5.0) is None:      # after STOP it ends by itself
            child.stop(int_wait_s=0.0, term_wait_s=None, first_signal=signal.SIGKILL)
        child.close()


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m tools.bench pingpong",
                                 description="Loopback UDP ping-pong between two processes "
                                             "(the lockstep floor); prints figures.")
    ap.add_argument("--n", type=int, default=20000, help="timed round trips (default 20000)")
    ap.add_argument("--payload", choices=PAYLOADS + ("both",), default="both",
                    help="mavlink: the lockstep exchange with pymavlink; links: through the "
                         "plant's and the fc's link modules; raw: 64 bytes echoed; both: "
                         "all three (default both)")
    ap.add_argument("--json", metavar="FILE", help="also write the figures as JSON")
    ap.add_argument("--echo", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.echo:
        return _echo(args.payload)
    if args.n < 1:
        ap.error("--n must be >= 1")
    out = {}
    for p in (PAYLOADS if args.payload == "both" else (args.payload,)):
        r = run_pingpong(args.n, p)
        out[p] = r
        print(f"{p:8s} n={r['n']:6d}  median {r['median_us']:7.1f} us  p99 {r['p99_us']:7.1f} us"
              f"  p99.9 {r['p999_us']:7.1f} us  max {r['max_us']:8.1f} us  lost {r['lost']}"
              f"  -> {r['exchanges_per_s']:.0f} exchanges/s")
    if args.json:
        with open(args.json, "w", encoding="utf-8") as f:
            json.dump(out, f, indent=2)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
