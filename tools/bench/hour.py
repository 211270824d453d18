"""The 1-hour lockstep cruise as a benchmark: wall time, logs and memory (issue 24).

    python -m tools.bench hour [--duration 3600] [--out DIR] [--json FILE] [--every 0.5]

Runs the main job's cruise for ``--duration`` simulated seconds in lockstep (the coordinated
law, the README's command: ``python -m tools.hil run --scenario cruise --duration D --variant
coordinated --out DIR --no-plots --quiet``) under ``tools.bench.treerss``'s sampler, then
measures what issue 24 asks of it:

- ``hour_wall_s``: the whole command's wall time (s): start-up, the flight, the logs'
  conversion and the metrics;
- ``hour_logs_mb``: every file the run wrote under ``DIR`` (MB = 2^20 bytes), with each file's
  size;
- ``hour_peak_rss_mb``: the peak over the run of the VmRSS summed over the process tree (the
  runner, the fc and the plant; MB), and when it came;
- ``hour_exchanges``: the lockstep exchanges flown (frames at the scenario's frame rate), so
  that the floor of the wall time on this machine is ``exchanges x`` the links' ping-pong
  (``python -m tools.bench --only pingpong``).

Prints the figures and, with ``--json``, writes them as ``{"meta": ..., "figures": ...}``
(``python -m tools.evidence.report import-bench FILE --as hour`` puts them beside the bench's
table). Exits 1 if the run failed. No target is asserted here.
"""
from __future__ import annotations

import argparse
import datetime as _dt
import json
import os
import shutil
import sys
import tempfile
from pathlib import Path

__all__ = ["dir_sizes_mb", "main", "run_hour"]

MB = float(1 << 20)


def dir_sizes_mb(root: Path) -> dict[str, float]:
    """Size (MB) of every file under ``root``, by path relative to it."""
    root = Path(root)
    out = {}
    for dirpath, _dirs, files in os.walk(root):
        for name in files:
            p = Path(dirpath) / name
            try:
                out[str(p.relative_to(root))] = p.stat().st_size / MB
            except OSError:
                continue
    return dict(sorted(out.items()))


def _frame_hz(scenario: str = "cruise") -> float:
    from plant_sim.scenario import load
    return float(load(scenario).data["timing"]["frame_hz"])


def run_hour(out: Path, duration_s: float = 3600.0, every_s: float = 0.5) -> dict:
    """The cruise for ``duration_s`` (sim s) into ``out``; the figures (module docstring)."""
    from tools.bench.treerss import sample
    argv = [sys.executable, "-m", "tools.hil", "run", "--scenario", "cruise", "--duration",
            f"{duration_s:g}", "--variant", "coordinated", "--out", str(out), "--no-plots",
            "--quiet"]
    r = sample(argv, every_s)
    sizes = dir_sizes_mb(out)
    peak = r["peak"]
    return {"returncode": r["returncode"], "command": " ".join(["python"] + argv[1:]),
            "hour_wall_s": r["wall_s"], "hour_logs_mb": sum(sizes.values()),
            "hour_log_files_mb": sizes, "hour_peak_rss_mb": peak["sum_mb"],
            "hour_peak_rss_at_s": peak["t_s"],
            "hour_peak_rss_processes_mb": {k: v.get("VmRSS", 0.0)
                                           for k, v in peak["processes"].items()},
            "hour_own_peaks_mb": r["own_peaks_mb"], "hour_duration_s": duration_s,
            "hour_exchanges": int(round(duration_s * _frame_hz()))}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m tools.bench hour",
                                 description=__doc__.split("\n")[0])
    ap.add_argument("--duration", type=float, default=3600.0,
                    help="simulated seconds of cruise (default 3600)")
    ap.add_argument("--out", metavar="DIR",
                    help="the run's directory (default: a temporary one, removed after)")
    ap.add_argument("--json", metavar="FILE", help="also write the figures as JSON")
    ap.add_argument("--every", type=float, default=0.5, help="RSS sampling period, s")
    args = ap.parse_args(argv)
    if args.duration <= 0 or args.every <= 0:
        ap.error("--duration and --every must be > 0")
    tmp = None
    if args.out:
        out = Path(args.out)
        if out.exists() and any(out.iterdir()):
            ap.error(f"--out {out} exists and is not empty: its files would be counted")
    else:
        tmp = tempfile.mkdtemp(prefix="hyfc-hour-")
        out = Path(tmp) / "run"
    try:
        load0 = os.getloadavg()[0]
        utc = _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")
        f = run_hour(out, args.duration, args.every)
    finally:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)
    print(f"{f['command']}: exit {f['returncode']}")
    print(f"  wall {f['hour_wall_s']:.1f} s for {f['hour_exchanges']} lockstep exchanges")
    print(f"  logs {f['hour_logs_mb']:.1f} MB: " + ", ".join(
        f"{k} {v:.1f}" for k, v in f["hour_log_files_mb"].items() if v >= 0.05))
    print(f"  peak RSS summed over the processes {f['hour_peak_rss_mb']:.0f} MB at "
          f"{f['hour_peak_rss_at_s']:.0f} s: " + ", ".join(
              f"{k} {v:.0f}" for k, v in f["hour_peak_rss_processes_mb"].items()))
    if args.json:
        meta = {"command": "python -m tools.bench hour " + " ".join(argv or sys.argv[1:]),
                "utc": utc, "cores": os.cpu_count(),
                "load_avg_1min_at_part_start": {"hour": load0}}
        Path(args.json).write_text(json.dumps({"meta": meta, "figures": f}, indent=1) + "\n")
    return 0 if f["returncode"] == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
