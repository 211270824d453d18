"""Campaign throughput benchmark: prints figures, asserts nothing.

    python -m tools.bench campaign [--runs 1000] [--workers 1,2] [--scenario paper]
                                     [--duration S] [--backend closed_loop|standin] [--keep DIR]

For each worker count, runs a fresh campaign of ``--runs`` cases (both variants) on a new
LocalCluster into a temporary directory (or ``--keep DIR/wK``) and prints: total wall time
(cluster start included), compute wall time (first submission to last row), cases per second,
the mean in-task time per variant, the speed-up against the first worker count, the
in-task CPU time (what the cases cost without contention: the machine is shared), and the
campaign's simulated seconds per wall second as a share of K x the in-process closed loop's
(``tools.sitl.closed_loop.simulate`` of the nominal scenario for the cases' duration, with the
sensor model and estimator in the loop as the cases fly it, median of 5, measured first in the
same run; issue 16's figure for K = 2).
"""
from __future__ import annotations

import argparse
import os
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np

from tools.evidence.montecarlo import dispersions as dsp
from tools.evidence.montecarlo import results
from tools.evidence.montecarlo.campaign import run_campaign
from tools.evidence.montecarlo.case import CampaignConfig


def _inproc_rate(scenario: str, duration_s: float | None) -> float:
    """Simulated seconds per wall second of the in-process loop on the nominal scenario as
    the campaign's cases fly it (the sensor model and the fc's estimator in the loop,
    tools.evidence.montecarlo.apply.fly_closed_loop), the loop alone as ``simulate`` times it (set-up
    excluded), median of 5 flights."""
    from tools.sitl.closed_loop import simulate
    simulate(scenario, duration_s=0.1, estimate="sensors")     # loads (or compiles) the code
    rates = []
    for _ in range(5):
        r = simulate(scenario, duration_s=duration_s, estimate="sensors")
        rates.append(float(r.t_s[-1] - r.t_s[0]) / r.wall_s)
    return float(np.median(rates))


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m tools.bench campaign")
    p.add_argument("--runs", type=int, default=1000, help="cases per campaign (default 1000)")
    p.add_argument("--workers", default="1,2", help="comma-separated worker counts")
    p.add_argument("--scenario", default="paper",
                   help="plant scenario name or path (default paper)")
    p.add_argument("--dispersions", default="paper",
                   help="shipped dispersions name or path (default paper)")
    p.add_argument("--duration", type=float, default=None, metavar="S",
                   help="simulated seconds per case (default: the scenario's)")
    p.add_argument("--backend", default="closed_loop", choices=("closed_loop", "standin"),
                   help="closed_loop (default) or standin (the toy model of the campaign "
                        "machinery)")
    p.add_argument("--seed", type=int, default=1, help="campaign seed (default 1)")
    p.add_argument("--keep", default=None, help="keep the campaigns under this directory")
    args = p.parse_args(argv)
    disp = dsp.load(args.dispersions)
    cfg = CampaignConfig(scenario=args.scenario, dispersions_text=disp.source_text,
                         dispersions_name=disp.name, seed=args.seed,
                         duration_s=args.duration, backend=args.backend)
    print(f"campaign benchmark: {args.runs} cases x {len(cfg.variants)} variants, scenario "
          f"{args.scenario}, duration {args.duration or 'scenario'}, backend {args.backend}, "
          f"{os.cpu_count()} cores")
    inproc = None
    if args.backend == "closed_loop":
        inproc = _inproc_rate(args.scenario, args.duration)
        print(f"in-process closed loop (nominal {args.scenario}, one thread, this run): "
              f"{inproc:.0f}x real time")
    first = None
    for k in [int(x) for x in args.workers.split(",")]:
        if args.keep:
            out = Path(args.keep) / f"w{k}"
            shutil.rmtree(out, ignore_errors=True)
        else:
            out = Path(tempfile.mkdtemp(prefix=f"mc-bench-w{k}-"))
        t0 = time.perf_counter()
        res = run_campaign(cfg, args.runs, out, workers=k, progress_stream=open(os.devnull, "w"))
        wall = time.perf_counter() - t0
        t = results.read_rows(out, columns=["wall_time_s", "cpu_time_s", "error", "sim_time_s"])
        walls = t.column("wall_time_s").to_numpy()
        cpu = t.column("cpu_time_s").to_numpy()
        var = t.column("variant").to_pylist()
        errs = sum(1 for e in t.column("error").to_pylist() if e)
        per = {v: float(walls[[x == v for x in var]].mean()) for v in cfg.variants}
        rate = res.ran / res.compute_wall_s if res.compute_wall_s > 0 else float("nan")
        if first is None:
            first = res.compute_wall_s
        print(f"workers {k}: wall {wall:7.1f} s (cluster start {res.cluster_start_s:.1f} s, "
              f"compute {res.compute_wall_s:.1f} s)  {rate:6.1f} cases/s  in-task per case: "
              + ", ".join(f"{v} {1e3 * s:.0f} ms" for v, s in per.items())
              + f"  errors {errs}  speed-up {first / res.compute_wall_s:.2f}x")
        print(f"           in-task CPU {cpu.sum():.1f} s in all (median {1e3 * np.median(cpu):.0f} "
              f"ms per variant): on {k} idle core(s) the cases alone need "
              f"{cpu.sum() / k:.1f} s; load average now {os.getloadavg()[0]:.1f}")
        if inproc:
            sim_rate = float(np.nansum(t.column("sim_time_s").to_numpy())) / res.compute_wall_s
            print(f"           simulated {sim_rate:.0f} s per wall second = "
                  f"{100 * sim_rate / (k * inproc):.0f} % of {k} x the in-process loop "
                  f"({k * inproc:.0f}x)")
        if not args.keep:
            shutil.rmtree(out, ignore_errors=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
