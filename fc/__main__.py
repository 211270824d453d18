"""``python -m fc``: the flight-controller process (docs/fc.md, docs/architecture.md 10)."""
from __future__ import annotations

import argparse
import logging
import logging.handlers
import os
import queue
import signal
import sys
import time

from fc.link import parse_hostport


def _hostport(text: str) -> tuple[str, int]:
    try:
        return parse_hostport(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        prog="python -m fc",
        description="hyfc flight controller: fixed-rate attitude loops, MAVLink to the plant "
                    "and to ground stations (docs/fc.md). Prints READY when its sockets are "
                    "bound; SIGINT/SIGTERM flush the logs and exit 0.")
    ap.add_argument("--mode", choices=("lockstep", "realtime"), default="lockstep",
                    help="lockstep: loops driven by the plant's frame stamps (deterministic); "
                         "realtime: wall-clock deadlines (default %(default)s)")
    ap.add_argument("--plant-bind", type=_hostport, default=("127.0.0.1", 14560),
                    metavar="HOST:PORT", help="UDP address the plant sends to (default 127.0.0.1:14560)")
    ap.add_argument("--plant-sysid", type=int, default=2,
                    help="only plant frames from this MAVLink system id are accepted (default 2)")
    ap.add_argument("--gcs", type=_hostport, action="append", metavar="HOST:PORT",
                    help="ground-station output, repeatable (default 127.0.0.1:14550)")
    ap.add_argument("--gcs-bind", type=_hostport, default=("127.0.0.1", 14555), metavar="HOST:PORT",
                    help="local address of the ground-station socket (default 127.0.0.1:14555)")
    ap.add_argument("--fast-hz", type=float, default=500.0, help="fast loop rate (default 500)")
    ap.add_argument("--slow-hz", type=float, default=100.0,
                    help="slow loop rate, an integer divisor of --fast-hz (default 100)")
    ap.add_argument("--params", metavar="FILE",
                    help="parameter file (MAVProxy format), loaded at start and saved on change "
                         "(default OUT/params.parm)")
    ap.add_argument("--timeline", metavar="FILE",
                    help="TOML [[command]] timeline {t_s, alpha_deg, beta_deg, mu_deg} by sensor time")
    ap.add_argument("--out", metavar="DIR", help="run directory (default runs/fc-<UTC time>)")
    ap.add_argument("--arm", action="store_true", help="start armed")
    ap.add_argument("--flight-mode", choices=("MANUAL", "COORDINATED", "UNCOORDINATED", "CRUISE", "GUIDED"),
                    default="MANUAL", help="mode at start (default MANUAL)")
    ap.add_argument("--sysid", type=int, default=1, help="our MAVLink system id (default 1)")
    ap.add_argument("--signing-key-file", metavar="FILE",
                    help="enable MAVLink 2 signing on the GCS link; FILE holds the passphrase "
                         "(key = SHA-256, MAVProxy convention) and must be mode 600")
    ap.add_argument("--rt-priority", type=int, default=50,
                    help="SCHED_FIFO priority in realtime mode, 0 = do not ask (default 50)")
    ap.add_argument("--sync", choices=("frame", "clock"), default="frame",
                    help="realtime: run the fast tick when a sensor frame arrives, the deadline "
                         "standing in for a late one (frame, default), or on the fc's own "
                         "clock (clock)")
    ap.add_argument("--spin-us", type=int, default=0,
                    help="realtime: busy-wait this many us before each deadline or expected "
                         "frame (default 0)")
    ap.add_argument("--law-module", default="fc.control",
                    help="module providing AttitudeLaw and LAW_PARAMS (default fc.control; "
                         "tests inject stand-ins)")
    ap.add_argument("--internals-full-s", type=float, default=60.0, metavar="S",
                    help="internals log (fc_internals.npz): every fast tick for the first S s "
                         "of sensor time, then --internals-tail-hz rows per second "
                         "(default %(default)g)")
    ap.add_argument("--internals-tail-hz", type=float, default=None, metavar="HZ",
                    help="internals log: rows per second of sensor time after "
                         "--internals-full-s (default: half the slow-loop rate, --slow-hz)")
    ap.add_argument("--internals-full-rate", action="store_true",
                    help="internals log: every fast tick however long the run (816 bytes a "
                         "row: about 1.5 GB per hour at 500 Hz)")
    return ap


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)

    out = args.out or os.path.join("runs", "fc-" + time.strftime("%Y%m%dT%H%M%SZ", time.gmtime()))
    os.makedirs(out, exist_ok=True)
    # the loop only enqueues log records; a listener thread writes fc.log and stderr
    log = logging.getLogger("fc")
    log.setLevel(logging.INFO)
    fh = logging.FileHandler(os.path.join(out, "fc.log"))
    fh.setFormatter(logging.Formatter("%(asctime)s %(levelname)s %(message)s"))
    eh = logging.StreamHandler(sys.stderr)
    eh.setLevel(logging.WARNING)
    eh.setFormatter(logging.Formatter("fc: %(levelname)s %(message)s"))
    records: queue.SimpleQueue = queue.SimpleQueue()
    listener = logging.handlers.QueueListener(records, fh, eh, respect_handler_level=True)
    listener.start()
    log.addHandler(logging.handlers.QueueHandler(records))
    log.propagate = False
    try:
        return _run(args, out, log)
    finally:
        listener.stop()
        fh.close()


def _run(args, out: str, log: logging.Logger) -> int:
    from fc.app import FcConfig, FlightController
    from fc.scheduler import freeze_heap
    from hyfc_wire.numba_cache import cache_report

    cfg = FcConfig(mode=args.mode, plant_bind=args.plant_bind, plant_sysid=args.plant_sysid,
                   gcs=args.gcs or [("127.0.0.1", 14550)], gcs_bind=args.gcs_bind,
                   fast_hz=args.fast_hz, slow_hz=args.slow_hz, params=args.params,
                   timeline=args.timeline, out=out, arm=args.arm, flight_mode=args.flight_mode,
                   sysid=args.sysid, signing_key_file=args.signing_key_file,
                   realtime_priority=args.rt_priority, spin_us=args.spin_us, sync=args.sync,
                   law_module=args.law_module,
                   internals_full_rate_s=None if args.internals_full_rate else args.internals_full_s,
                   internals_tail_hz=args.internals_tail_hz)
    stopping = []

    def _stop(signum, _frame):
        stopping.append(signum)

    signal.signal(signal.SIGINT, _stop)
    signal.signal(signal.SIGTERM, _stop)
    t_build = time.perf_counter()
    try:
        fc = FlightController(cfg, log)
    except (OSError, ValueError, KeyError, ImportError) as exc:
        print(f"fc: {exc}", file=sys.stderr)
        return 2
    log.info("fc started: %s", cfg)
    # were the law's, estimator's and guidance's kernels in numba's cache (about 1 s), or
    # compiled (10-15 s; ``python -m tools.precompile`` fills the cache once: docs/fc.md)?
    log.info(cache_report(("fc",), time.perf_counter() - t_build))
    log.info("plant link bound at %s:%d, GCS link bound at %s:%d", *fc.plant.endpoint.address,
             *fc.gcs.endpoint.address)
    # the start-up heap frozen before READY: the first frames must not wait for that pass
    log.info(freeze_heap())
    print("READY", flush=True)
    try:
        fc.run(lambda: bool(stopping))
    finally:
        fc.close()
    log.info("fc stopped (signal %s)", stopping[0] if stopping else None)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
