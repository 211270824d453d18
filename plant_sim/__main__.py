"""python -m plant_sim: the winged-cone plant simulator process (docs/architecture.md s. 10).

    python -m plant_sim run --scenario NAME|PATH [--mode lockstep|realtime] [--fc HOST:PORT]
                            [--bind HOST:PORT] [--out DIR] [--duration S] [--seed N]
                            [--sysid 2] [--fc-sysid 1] [--rerequest-timeout S] [--give-up S]
                            [--progress-every S]
    python -m plant_sim trim --scenario NAME|PATH
    python -m plant_sim modes --scenario NAME|PATH [--offset-deg 0.2] [--surface rudder]
                              [--hold-s 10]
    python -m plant_sim list
"""
from __future__ import annotations

import argparse
import logging
import math
import os
import sys
import time
from pathlib import Path


def _parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        prog="python -m plant_sim",
        description="Winged-cone hypersonic plant simulator speaking MAVLink 2 over UDP "
                    "(docs/plant.md, docs/wire.md).")
    sub = ap.add_subparsers(dest="cmd", required=True, metavar="{run,trim,modes,list}")
    r = sub.add_parser("run", help="run a scenario against a flight controller",
                       description="Run a scenario: send sensor frames to the fc, apply its "
                                   "SERVO_OUTPUT_RAW, write truth.npz, plant.log, "
                                   "plant_summary.json and scenario.toml into --out.")
    r.add_argument("--scenario", required=True, help="shipped scenario name or a TOML path")
    r.add_argument("--mode", choices=("lockstep", "realtime"), default="lockstep",
                   help="lockstep: wait for the answer to every frame (deterministic); "
                        "realtime: advance with the wall clock (default: lockstep)")
    r.add_argument("--fc", default="127.0.0.1:14560", metavar="HOST:PORT",
                   help="where the fc listens (default 127.0.0.1:14560)")
    r.add_argument("--bind", default="127.0.0.1:14561", metavar="HOST:PORT",
                   help="the plant's own socket; port 0 = ephemeral (default 127.0.0.1:14561)")
    r.add_argument("--out", default=None, metavar="DIR",
                   help="run directory (default: a new directory under runs/)")
    r.add_argument("--duration", type=float, default=None, metavar="S",
                   help="sim time to run (default: the scenario's duration_s); 0: open-ended, "
                        "until SIGINT/SIGTERM (then the logs are written and the exit is 0)")
    r.add_argument("--seed", type=int, default=None, metavar="N",
                   help="sensor-noise seed (default: the scenario's seed)")
    r.add_argument("--sysid", type=int, default=2, help="the plant's MAVLink system id (default 2)")
    r.add_argument("--fc-sysid", type=int, default=1,
                   help="system id servo frames must carry (default 1)")
    r.add_argument("--rerequest-timeout", type=float, default=0.1, metavar="S",
                   help="lockstep: re-send a frame not answered within S (default 0.1)")
    r.add_argument("--give-up", type=float, default=120.0, metavar="S",
                   help="lockstep: fail when one frame stays unanswered for S (default 120)")
    r.add_argument("--progress-every", type=float, default=1.0, metavar="S",
                   help="print 'PROGRESS t_s=.. rtf=..' every S wall seconds; 0 = never")
    r.add_argument("--truth-full-s", type=float, default=60.0, metavar="S",
                   help="truth log (truth.npz): every frame for the first S s of sim time, "
                        "then --truth-tail-hz rows per second (default %(default)g)")
    r.add_argument("--truth-tail-hz", type=float, default=50.0, metavar="HZ",
                   help="truth log: rows per second of sim time after --truth-full-s "
                        "(default %(default)g)")
    r.add_argument("--truth-full-rate", action="store_true",
                   help="truth log: every frame however long the run (about 0.7 GB per hour "
                        "at 500 Hz)")
    r.add_argument("--python-frame", action="store_true",
                   help="lockstep: each frame through the Python path (build_sensors, "
                        "poll_for, PlantSim.frame) instead of the one compiled call; the same "
                        "outputs (a reference for tests and benchmarks)")
    t = sub.add_parser("trim", help="report the trim deflections of a scenario",
                       description="Surface deflections that balance the moments at the "
                                   "scenario's initial state and at each commanded attitude "
                                   "(or the best within the limits and the moment left).")
    t.add_argument("--scenario", required=True, help="shipped scenario name or a TOML path")
    m = sub.add_parser("modes", help="the small-perturbation modes, open loop and with the "
                                     "hold's backup damper",
                       description="Linearise the plant at the scenario's initial condition "
                                   "(plant_sim/modes.py): eigenvalues open loop and with the "
                                   "servo table's backup damper (plant_sim/hold.py), and the "
                                   "bank of a surface held off the trim.")
    m.add_argument("--scenario", required=True, help="shipped scenario name or a TOML path")
    m.add_argument("--offset-deg", type=float, default=0.2,
                   help="the held surface's offset from the trim, deg (0.2)")
    m.add_argument("--surface", choices=("left", "right", "rudder"), default="rudder",
                   help="which surface is held off the trim (rudder)")
    m.add_argument("--hold-s", type=float, default=10.0, help="how long it is held, s (10)")
    sub.add_parser("list", help="list the shipped scenarios")
    return ap


def _fail(msg: str) -> int:
    print(f"plant_sim: error: {msg}", file=sys.stderr, flush=True)
    return 2


def main(argv=None) -> int:
    args = _parser().parse_args(argv)
    from plant_sim.scenario import ScenarioError, list_names, load

    if args.cmd == "list":
        for n in list_names():
            try:
                print(f"{n:10s} {load(n).data['description']}")
            except ScenarioError as e:
                print(f"{n:10s} INVALID: {e}")
        return 0
    try:
        sc = load(args.scenario)
    except ScenarioError as e:
        return _fail(str(e))
    if args.cmd == "modes":
        from plant_sim.modes import report
        surface = ("left", "right", "rudder").index(args.surface)
        print(report(sc, args.offset_deg, surface, args.hold_s))
        return 0
    if args.cmd == "trim":
        from plant_sim.trim import trim_report
        text, ok = trim_report(sc)
        print(text)
        if not ok:
            print("WARNING: not trimmable within the surface limits at every point above")
        return 0

    from hyfc_wire.udp import parse_hostport
    from plant_sim.process import RunConfig, _Fatal, run
    try:
        fc = parse_hostport(args.fc, "--fc")
        bind = parse_hostport(args.bind, "--bind")
    except ValueError as e:
        return _fail(str(e))
    duration = sc.duration_s if args.duration is None else args.duration
    if not (duration >= 0 and math.isfinite(duration)):
        return _fail("--duration must be >= 0 (0: until SIGINT/SIGTERM)")
    if args.rerequest_timeout <= 0:
        return _fail("--rerequest-timeout must be > 0")
    for flag, v in (("--sysid", args.sysid), ("--fc-sysid", args.fc_sysid)):
        if not 1 <= v <= 255:
            return _fail(f"{flag} must be 1..255, got {v}")
    if args.give_up <= 0:
        return _fail("--give-up must be > 0")
    if not (math.isfinite(args.truth_full_s) and args.truth_full_s >= 0
            and math.isfinite(args.truth_tail_hz) and args.truth_tail_hz > 0):
        return _fail("--truth-full-s must be >= 0 and --truth-tail-hz > 0")
    seed = sc.seed if args.seed is None else args.seed
    out = Path(args.out) if args.out else Path("runs") / time.strftime(f"plant-%Y%m%d-%H%M%S-{os.getpid()}")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        return _fail(f"cannot create --out {out}: {e}")
    sc.data["seed"] = seed
    head = ""
    if duration > 0:
        sc.data["duration_s"] = duration
    else:
        head = "# flown open-ended (--duration 0): until SIGINT/SIGTERM, not duration_s\n"
    (out / "scenario.toml").write_text(head + sc.to_toml())
    log = logging.getLogger("plant_sim")
    log.setLevel(logging.INFO)
    fh = logging.FileHandler(out / "plant.log", mode="w")
    fh.setFormatter(logging.Formatter("%(asctime)s %(levelname)s %(message)s"))
    log.addHandler(fh)
    log.info("plant_sim run: %s", " ".join(sys.argv))
    cfg = RunConfig(mode=args.mode, fc_addr=fc, bind_addr=bind, out_dir=out, duration_s=duration,
                    seed=seed, sysid=args.sysid, fc_sysid=args.fc_sysid,
                    rerequest_timeout_s=args.rerequest_timeout, give_up_s=args.give_up,
                    progress_every_s=args.progress_every,
                    truth_full_rate_s=None if args.truth_full_rate else args.truth_full_s,
                    truth_tail_hz=args.truth_tail_hz, compiled_frame=not args.python_frame)
    try:
        stats = run(sc, cfg, log)
    except _Fatal as e:
        log.error("%s", e)
        return _fail(str(e))
    except OSError as e:
        log.error("%s", e)
        return _fail(f"socket error: {e}")
    except Exception as e:          # one line on stderr, the traceback in plant.log
        log.exception("internal error")
        return _fail(f"internal error: {type(e).__name__}: {e} (traceback in {out / 'plant.log'})")
    print(f"DONE frames={stats.frames} rerequests={stats.rerequests} out={out}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
