"""Command line of the main job: ``python -m tools.hil run|report`` (docs/hil.md)."""
from __future__ import annotations

import argparse
import datetime as _dt
import json
import math
import os
import shlex
import shutil
import signal
import sys
import threading
from pathlib import Path

from tools.sitl import rundata
from tools.sitl.runner import RunConfig, controller_params, run_variant

VARIANTS = ("coordinated", "uncoordinated")
EXIT_OK, EXIT_FAILED, EXIT_USAGE, EXIT_INTERRUPTED = 0, 1, 2, 130


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m tools.hil",
        description="The main job: fly a scenario with the plant (python -m plant_sim) and the "
                    "controller (python -m fc) as two processes over loopback MAVLink/UDP, "
                    "compare the coordinated and uncoordinated controller, write a run "
                    "directory with logs, summary.json and plots (docs/hil.md).")
    sub = p.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("run", help="fly a scenario and write a run directory",
                       description="Fly a scenario and write a run directory. Exit code 0 when "
                                   "every variant completed, 1 when a process failed, 130 when "
                                   "interrupted (except --mode realtime --duration 0, where "
                                   "Ctrl-C is the normal end).")
    r.add_argument("--scenario", default="paper",
                   help="scenario name (plant_sim/scenarios/NAME.toml) or path (default: paper)")
    r.add_argument("--mode", choices=("lockstep", "realtime"), default="lockstep",
                   help="lockstep: deterministic, as fast as the processes go (default); "
                        "realtime: wall-clock paced, driven by a scripted ground station")
    r.add_argument("--variant", choices=VARIANTS + ("both",), default="both",
                   help="controller variant(s) to fly, each with fresh processes (default: both)")
    r.add_argument("--out", type=Path, default=None,
                   help="run directory (default: a new directory under runs/)")
    r.add_argument("--duration", type=float, default=None, metavar="S",
                   help="sim time to fly, s (default: the scenario's); 0 with --mode realtime: "
                        "until Ctrl-C")
    r.add_argument("--seed", type=int, default=0, help="random seed of the plant (default 0)")
    r.add_argument("--flight-mode", choices=("attitude", "CRUISE", "GUIDED", "MISSION"),
                   default=None,
                   help="attitude: the variant's COORDINATED/UNCOORDINATED mode flying the "
                        "scenario's [[command]] timeline; CRUISE/GUIDED: the guidance holds the "
                        "altitude, course and speed at engagement, the variant selects its inner "
                        "loop (GUID_INNER_CO); MISSION: the ground station uploads --mission and "
                        "the guidance flies it (CRUISE until then). Default: the scenario's "
                        "flight_mode, else attitude")
    r.add_argument("--mission", type=Path, default=None, metavar="FILE",
                   help="mission (QGC WPL 110, as MAVProxy 'wp load') flown in MISSION "
                        "(default: the scenario's NAME.waypoints next to its .toml)")
    r.add_argument("--command-shaping", choices=("steps", "prefilter"), default=None,
                   help="steps: the paper's step commands (REF_PF_EN 0, default in the attitude "
                        "modes); prefilter: the controller's reference prefilter (REF_PF_EN 1, "
                        "default in the guidance modes: the guidance's 50 Hz commands are not "
                        "steps to track)")
    r.add_argument("--gains", choices=("scheduled", "paper"), default="scheduled",
                   help="scheduled: the gain schedule (CTL_SCHED 1, the default); paper: the "
                        "paper's fixed gains (CTL_SCHED 0), to reproduce its comparison with "
                        "the law it was made with")
    r.add_argument("--params", type=Path, default=None, metavar="FILE",
                   help="extra controller parameters (MAVProxy 'NAME VALUE' file); the "
                        "command shaping and the gains are applied on top")
    r.add_argument("--gcs-out", action="append", default=None, metavar="HOST:PORT",
                   help="also stream the controller's telemetry to this ground station "
                        "(repeatable; realtime default 127.0.0.1:14550 for MAVProxy/QGC, "
                        "lockstep default none)")
    r.add_argument("--progress-every", type=float, default=1.0, metavar="S",
                   help="progress line every S wall seconds (default 1)")
    r.add_argument("--no-plots", action="store_true", help="do not write the PNG plots")
    r.add_argument("--quiet", action="store_true", help="no progress lines")
    r.add_argument("--plant-cmd", default=None, metavar="CMD",
                   help="advanced: command that starts the plant instead of "
                        "'python -m plant_sim' (e.g. under a profiler); split like a shell")
    r.add_argument("--fc-cmd", default=None, metavar="CMD",
                   help="advanced: command that starts the controller instead of 'python -m fc'")
    rep = sub.add_parser("report", help="regenerate summary.json and plots from a run's logs")
    rep.add_argument("run_dir", type=Path, metavar="RUN_DIR",
                     help="a run directory written by 'run' (holds run.json)")
    rep.add_argument("--no-plots", action="store_true", help="only summary.json")
    return p


def _scenario_file(ref: str) -> Path:
    """Path of a scenario given by name or path (docs/architecture.md section 7)."""
    p = Path(ref)
    if p.suffix == ".toml" or os.sep in ref:
        if not p.is_file():
            raise FileNotFoundError(f"scenario file {ref} not found")
        return p.resolve()
    import plant_sim
    cand = Path(plant_sim.__file__).parent / "scenarios" / f"{ref}.toml"
    if not cand.is_file():
        names = sorted(x.stem for x in cand.parent.glob("*.toml"))
        raise FileNotFoundError(f"unknown scenario {ref!r}; known: {', '.join(names) or 'none'}")
    return cand


def _scenario_flight_mode(path: Path) -> str:
    """The scenario's own ``flight_mode`` (top level: attitude, CRUISE or GUIDED), if any."""
    import tomllib
    try:
        with open(path, "rb") as f:
            return str(tomllib.load(f).get("flight_mode", "attitude"))
    except (OSError, ValueError):
        return "attitude"


def _scenario_duration(path: Path) -> float | None:
    """The scenario's own ``duration_s`` (top level), if any."""
    import tomllib
    try:
        with open(path, "rb") as f:
            d = tomllib.load(f).get("duration_s")
        return float(d) if d is not None else None
    except (OSError, ValueError, TypeError):
        return None


def _new_run_dir(scenario: str) -> Path:
    stamp = _dt.datetime.now(_dt.timezone.utc).strftime("%Y%m%dT%H%M%SZ")
    base = Path("runs") / f"{stamp}_{Path(scenario).stem}"
    d, n = base, 1
    while d.exists():
        n += 1
        d = Path(f"{base}_{n}")
    return d


def _versions() -> dict:
    import numpy
    out = {"python": sys.version.split()[0], "numpy": numpy.__version__}
    try:
        import subprocess
        rev = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                             text=True, timeout=5, cwd=Path(__file__).resolve().parents[2])
        if rev.returncode == 0:
            out["git"] = rev.stdout.strip()
            # the code that ran (a regenerated document under docs/ does not make it dirty)
            dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no",
                                    "--", "fc", "plant_sim", "hyfc_wire", "tools",
                                    "pyproject.toml"],
                                   capture_output=True, text=True, timeout=5,
                                   cwd=Path(__file__).resolve().parents[2])
            out["git_dirty"] = bool(dirty.stdout.strip())
    except (OSError, subprocess.SubprocessError):
        pass
    return out


def build_summary(run_dir: Path, meta: dict, plots: bool = True) -> tuple[dict, list]:
    """summary.json (and plots) of a run directory from its logs alone."""
    summary = {"scenario": meta["scenario"], "mode": meta["mode"], "seed": meta["seed"],
               "runs": {}}
    plot_runs: dict = {}
    errors = []
    for variant in meta["variants"]:
        vdir = run_dir / variant
        status = meta.get("status", {}).get(variant)
        # a run cut short on purpose (Ctrl-C, --duration 0) is not a divergence
        expect_s = meta.get("expected_sim_time_s") if status in (None, "ok") else None
        try:
            entry, pdata = rundata.variant_summary(vdir, expect_s)
        except (rundata.RunDataError, OSError, ValueError, KeyError) as exc:
            errors.append(f"{variant}: {exc}")
            continue
        if status is not None:
            entry["status"] = status
        summary["runs"][variant] = entry
        plot_runs[variant] = pdata
    for k in ("command_shaping", "duration_s", "scenario_file", "created_utc", "versions",
              "params", "params_file"):
        if k in meta:
            summary[k] = meta[k]
    if errors:
        summary["errors"] = errors
    summary = rundata.json_safe(summary)
    (run_dir / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    (run_dir / "summary.txt").write_text(format_table(summary) + "\n")
    written = []
    if plots and plot_runs:
        from tools.sitl import plots as plotmod
        written = plotmod.write_all(plot_runs, meta, run_dir)
    return summary, written


def format_table(summary: dict) -> str:
    """A short text table of a summary (both variants side by side)."""
    runs = summary.get("runs", {})
    if not runs:
        return "(no completed variant)"
    names = list(runs)

    def f(x, fmt="{:.2f}"):
        return "-" if x is None else fmt.format(x)

    rows = []
    for ch in ("alpha", "beta", "mu"):
        for key, label, fmt in (("overshoot_pct", "overshoot %", "{:.1f}"),
                                ("undershoot_pct", "wrong-way %", "{:.1f}"),
                                ("settling_time_s", "settling s", "{:.2f}"),
                                ("rise_time_s", "rise s", "{:.2f}"),
                                ("final_error_deg", "final err deg", "{:.3f}")):
            rows.append((f"{ch} {label}", [f(runs[n][ch].get(key), fmt) for n in names]))
    for s in ("left_elevon", "right_elevon", "rudder"):
        rows.append((f"peak {s} deg", [f(runs[n]["max_surface_deg"][s], "{:.1f}") for n in names]))
    rows.append(("saturated s", [f(runs[n]["saturated_s"]) for n in names]))
    for key, label in (("travel_total_deg", "surface travel deg"),
                       ("chatter_right_elevon_deg", "chatter r. elevon deg"),
                       ("cmd_at_limit_s", "command at limit s"),
                       ("rate_cmd_limited_s", "rate cmd limited s")):
        rows.append((label, [f(runs[n].get("surfaces", {}).get(key)) for n in names]))
    rows.append(("sim time s", [f(runs[n]["sim_time_s"]) for n in names]))
    rows.append(("real-time factor", [f(runs[n]["real_time_factor"], "{:.1f}") for n in names]))
    rows.append(("late ticks", [str(runs[n]["late_ticks"]) for n in names]))
    rows.append(("diverged", [str(runs[n]["diverged"]) for n in names]))
    w0 = max(len(r[0]) for r in rows)
    w = max(14, *(len(n) for n in names))
    head = (f"scenario {summary.get('scenario')}, {summary.get('mode')}, seed {summary.get('seed')}, "
            f"command shaping {summary.get('command_shaping', '?')}")
    lines = [head, " " * w0 + "  " + "  ".join(n.rjust(w) for n in names)]
    lines += [r[0].ljust(w0) + "  " + "  ".join(v.rjust(w) for v in r[1]) for r in rows]
    return "\n".join(lines)


def cmd_run(args) -> int:
    if args.duration is not None and (args.duration < 0 or not math.isfinite(args.duration)):
        print("tools.hil: --duration must be >= 0", file=sys.stderr)
        return EXIT_USAGE
    if args.duration == 0 and args.mode != "realtime":
        print("tools.hil: --duration 0 (until Ctrl-C) needs --mode realtime", file=sys.stderr)
        return EXIT_USAGE
    try:
        scen_path = _scenario_file(args.scenario)
        commands = rundata.read_timeline(scen_path)
    except (FileNotFoundError, rundata.RunDataError, ValueError) as exc:
        print(f"tools.hil: {exc}", file=sys.stderr)
        return EXIT_USAGE
    if args.params is not None and not args.params.is_file():
        print(f"tools.hil: parameter file {args.params} not found", file=sys.stderr)
        return EXIT_USAGE
    run_dir = args.out if args.out is not None else _new_run_dir(args.scenario)
    run_dir.mkdir(parents=True, exist_ok=True)
    variants = VARIANTS if args.variant == "both" else (args.variant,)
    gcs_out = tuple(args.gcs_out) if args.gcs_out else (
        ("127.0.0.1:14550",) if args.mode == "realtime" else ())
    flight_mode = args.flight_mode or _scenario_flight_mode(scen_path)
    if flight_mode == "attitude":
        flight_mode = ""
    if args.command_shaping is None:
        args.command_shaping = "prefilter" if flight_mode else "steps"
    mission_file = None
    if flight_mode == "MISSION":
        mission_file = args.mission or scen_path.with_suffix(".waypoints")
        if not mission_file.is_file():
            print(f"tools.hil: no mission file {mission_file} (give --mission FILE)",
                  file=sys.stderr)
            return EXIT_USAGE
    cfg = RunConfig(scenario=args.scenario, mode=args.mode, variants=variants,
                    flight_mode=flight_mode, mission_file=mission_file,
                    out_dir=run_dir, duration_s=args.duration, seed=args.seed,
                    command_shaping=args.command_shaping, params_file=args.params,
                    gains=args.gains,
                    gcs_out=gcs_out, progress_every_s=args.progress_every, quiet=args.quiet,
                    plant_cmd=tuple(shlex.split(args.plant_cmd or "")),
                    fc_cmd=tuple(shlex.split(args.fc_cmd or "")))
    shutil.copyfile(scen_path, run_dir / "scenario.toml")
    expected_s = args.duration if args.duration is not None else _scenario_duration(scen_path)
    if args.mode == "realtime" and args.duration == 0:
        expected_s = None
    meta = {"scenario": args.scenario, "mode": args.mode, "seed": args.seed,
            "expected_sim_time_s": expected_s,
            "variants": list(variants), "command_shaping": args.command_shaping,
            "gains": args.gains,
            "flight_mode": flight_mode or "attitude",
            "mission_file": None if mission_file is None else str(mission_file),
            "duration_s": args.duration, "scenario_file": str(scen_path),
            "created_utc": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
            "versions": _versions(), "gcs_out": list(gcs_out),
            "params": controller_params(cfg),
            "params_file": None if args.params is None else str(args.params),
            "status": {}}

    stop = threading.Event()

    def on_signal(signum, frame):
        if not stop.is_set():
            print(f"\ntools.hil: {signal.Signals(signum).name} received, stopping both "
                  f"processes...", file=sys.stderr)
        stop.set()

    old = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    failed = interrupted = False
    try:
        for variant in variants:
            if stop.is_set():
                break
            if not args.quiet:
                print(f"tools.hil: flying {variant} ({args.mode}) -> {run_dir / variant}",
                      file=sys.stderr)
            res = run_variant(cfg, variant, run_dir / variant, commands, str(scen_path), stop)
            meta["status"][variant] = ("ok" if res.ok else
                                       "interrupted" if res.interrupted else "failed")
            if res.error:
                print(f"tools.hil: {variant}: {res.error}", file=sys.stderr)
                meta["status"][variant] = "failed"
                meta.setdefault("errors", {})[variant] = res.error
                failed = True
                break
            if res.interrupted:
                interrupted = True
                break
    finally:
        for s, h in old.items():
            signal.signal(s, h)
    (run_dir / "run.json").write_text(json.dumps(rundata.json_safe(meta), indent=2) + "\n")
    flown = [v for v in variants if v in meta["status"]]
    meta_for_summary = dict(meta, variants=flown)
    summary, written = build_summary(run_dir, meta_for_summary, plots=not args.no_plots)
    print(format_table(summary))
    print(f"run directory: {run_dir}")
    for p in written:
        print(f"plot: {p}")
    if failed:
        return EXIT_FAILED
    if interrupted:
        forever = args.mode == "realtime" and args.duration == 0
        return EXIT_OK if forever else EXIT_INTERRUPTED
    return EXIT_OK


def cmd_report(args) -> int:
    run_dir: Path = args.run_dir
    meta_path = run_dir / "run.json"
    if not meta_path.is_file():
        print(f"tools.hil: {meta_path} not found (not a run directory?)", file=sys.stderr)
        return EXIT_USAGE
    meta = json.loads(meta_path.read_text())
    meta["variants"] = [v for v in meta.get("variants", VARIANTS) if (run_dir / v).is_dir()]
    summary, written = build_summary(run_dir, meta, plots=not args.no_plots)
    print(format_table(summary))
    for p in written:
        print(f"plot: {p}")
    return EXIT_FAILED if summary.get("errors") else EXIT_OK


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    if args.cmd == "run":
        return cmd_run(args)
    return cmd_report(args)
