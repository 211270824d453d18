"""Command line of the robustness campaigns (docs/montecarlo.md).

    python -m tools.evidence.montecarlo --scenario NAME --runs N [--variant coordinated|uncoordinated|both]
                               [--dispersions NAME|FILE] [--workers K] [--scheduler ADDRESS]
                               [--connect-timeout S]
                               [--out DIR] [--seed S] [--hil] [--duration S] [--spec FILE]
    python -m tools.evidence.montecarlo rerun OUT_DIR --case I [--variant V] [--out DIR]
    python -m tools.evidence.montecarlo summary OUT_DIR [--spec FILE] [--no-plots]
    python -m tools.evidence.montecarlo compare DIR_A DIR_B
"""
from __future__ import annotations

import argparse
import sys
import time
import tomllib
from pathlib import Path

from tools.evidence.montecarlo import dispersions as dsp


def _variants(s: str) -> tuple[str, ...]:
    if s == "both":
        return ("coordinated", "uncoordinated")
    if s in ("coordinated", "uncoordinated"):
        return (s,)
    raise argparse.ArgumentTypeError(f"--variant: expected coordinated, uncoordinated or both, "
                                     f"got {s!r}")


def _positive_int(s: str) -> int:
    try:
        v = int(s)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {s!r}") from None
    if v < 1:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {s!r}")
    return v


def _positive_float(s: str) -> float:
    try:
        v = float(s)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive number, got {s!r}") from None
    if not v > 0:
        raise argparse.ArgumentTypeError(f"expected a positive number, got {s!r}")
    return v


def load_spec(path: str | None, default: dict) -> dict:
    """A specification file: TOML with a [spec] table (or the spec keys at top level)."""
    if path is None:
        return default
    try:
        doc = tomllib.loads(Path(path).read_text())
    except (OSError, tomllib.TOMLDecodeError) as exc:
        raise dsp.DispersionError(f"--spec {path}: {exc}") from None
    return dsp._parse_spec(doc.get("spec", doc))


def _run_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m tools.evidence.montecarlo",
        description="Monte Carlo robustness campaign: dispersed cases of a scenario flown by "
                    "the coordinated and/or uncoordinated controller, as tasks on Dask "
                    "distributed. Other commands: 'rerun OUT_DIR --case I', "
                    "'summary OUT_DIR', 'compare DIR_A DIR_B'.")
    p.add_argument("--scenario", default="paper", help="plant scenario name or path "
                   "(default paper)")
    p.add_argument("--runs", type=_positive_int, required=True, help="number of cases")
    p.add_argument("--variant", type=_variants, default=_variants("both"),
                   help="coordinated, uncoordinated or both (default both)")
    p.add_argument("--dispersions", default="paper",
                   help="shipped name (tools/evidence/dispersions/NAME.toml) or path (default paper)")
    p.add_argument("--workers", type=_positive_int, default=None,
                   help="LocalCluster worker processes (default: all cores)")
    p.add_argument("--scheduler", default=None,
                   help="address of an existing Dask scheduler, tcp://host:port")
    p.add_argument("--connect-timeout", type=_positive_float, default=10.0, metavar="S",
                   help="with --scheduler: give up connecting after S seconds (default 10)")
    p.add_argument("--out", default=None, help="campaign directory (default runs/mc-...); "
                   "an existing one with the same options is resumed")
    p.add_argument("--seed", type=int, default=1, help="campaign seed (default 1)")
    p.add_argument("--hil", action="store_true",
                   help="fly each case through the two processes over loopback UDP")
    p.add_argument("--duration", type=_positive_float, default=None,
                   help="simulated seconds per case (default: the scenario's)")
    p.add_argument("--spec", default=None, help="TOML file with a [spec] table overriding "
                   "the dispersion file's")
    p.add_argument("--backend", choices=("closed_loop", "standin"), default="closed_loop",
                   help="closed_loop (default). standin: a toy model that only exercises the "
                        "campaign machinery, not a flight simulation")
    p.add_argument("--trace-dt", type=_positive_float, default=0.05,
                   help="sampling of the stored alpha/beta/mu traces, s (default 0.05)")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    p.add_argument("--quiet", action="store_true", help="no progress bar, no table")
    return p


def _finish(out_dir: Path, cfg, spec: dict, plots: bool, quiet: bool, extra_meta=None) -> dict:
    from tools.evidence.montecarlo import plots as mcplots
    from tools.evidence.montecarlo import results, summary
    from tools.evidence.montecarlo.case import command_timeline_deg, dispersions_of
    disp = dispersions_of(cfg)
    meta = {"scenario": cfg.scenario, "dispersions": cfg.dispersions_name, "seed": cfg.seed,
            "backend": cfg.backend, "variants": list(cfg.variants),
            "duration_s": cfg.duration_s, **(extra_meta or {})}
    s = summary.summarise(out_dir, spec, list(disp.dists), cfg.variants, meta)
    if plots and s["rows"]:
        try:
            cmds = command_timeline_deg(cfg)
        except Exception:  # the plot is still useful without the command line
            cmds = None
        paths = mcplots.write_all(out_dir, meta, cfg.variants, spec, s, cfg.trace_dt_s, cmds)
        s["plots"] = [str(p) for p in paths]
    results.write_json(out_dir / "summary.json", summary.to_json(s))
    text = summary.table(s)
    (out_dir / "summary.txt").write_text(text + "\n")
    if not quiet:
        print(text)
        print(f"\nrows: {out_dir / 'rows'}   summary: {out_dir / 'summary.json'}")
        for p in s.get("plots", []):
            print(f"plot: {p}")
    return s


def main_run(argv) -> int:
    from tools.evidence.montecarlo.campaign import CampaignError, run_campaign
    from tools.evidence.montecarlo.case import CampaignConfig
    args = _run_parser().parse_args(argv)
    if args.scheduler and args.workers:
        print("error: --workers sizes the local cluster; with --scheduler the existing "
              "cluster's workers run the cases (size it with 'dask worker --nworkers')",
              file=sys.stderr)
        return 2
    try:
        path = dsp.resolve_path(args.dispersions)
        disp = dsp.parse(path.read_text(), name=path.stem)
        spec = load_spec(args.spec, disp.spec)
    except dsp.DispersionError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    backend = "hil" if args.hil else args.backend
    cfg = CampaignConfig(scenario=args.scenario, dispersions_text=disp.source_text,
                         dispersions_name=disp.name, seed=args.seed, variants=args.variant,
                         duration_s=args.duration, trace_dt_s=args.trace_dt, backend=backend)
    out = Path(args.out) if args.out else Path("runs") / (
        f"mc-{Path(args.scenario).stem}-{disp.name}-s{args.seed}-"
        f"{time.strftime('%Y%m%d-%H%M%S')}")
    try:
        res = run_campaign(cfg, args.runs, out, workers=args.workers, scheduler=args.scheduler,
                           connect_timeout_s=args.connect_timeout,
                           progress_stream=open("/dev/null", "w") if args.quiet else None)
    except CampaignError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    if not args.quiet:
        print(f"campaign {out}: {res.ran} cases run, {res.skipped} already finished, "
              f"{res.failures} failed rows, {len(res.lost)} lost; wall {res.wall_s:.1f} s "
              f"(cluster start {res.cluster_start_s:.1f} s, compute {res.compute_wall_s:.1f} s "
              f"on {res.nthreads} worker threads)")
    for i, why in res.lost[:10]:
        print(f"lost case {i}: {why} (not written; a resume retries it)", file=sys.stderr)
    if res.interrupted:
        print(f"interrupted: finished cases are saved; resume with the same command "
              f"and --out {out}", file=sys.stderr)
        return 130
    _finish(out, cfg, spec, not args.no_plots, args.quiet,
            {"wall_s": res.wall_s, "compute_wall_s": res.compute_wall_s,
             "nthreads": res.nthreads})
    if res.lost:
        print(f"incomplete: {len(res.lost)} cases lost (see above); run the same command with "
              f"--out {out} to retry them", file=sys.stderr)
        return 1
    return 0


def main_summary(argv) -> int:
    from tools.evidence.montecarlo.campaign import CampaignError, load_manifest
    from tools.evidence.montecarlo.case import dispersions_of
    p = argparse.ArgumentParser(prog="python -m tools.evidence.montecarlo summary",
                                description="Summary, table and plots of a campaign directory "
                                            "(recomputed from its rows).")
    p.add_argument("out_dir", help="campaign directory")
    p.add_argument("--spec", default=None, help="TOML file with a [spec] table")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    args = p.parse_args(argv)
    try:
        cfg, _ = load_manifest(args.out_dir)
        spec = load_spec(args.spec, dispersions_of(cfg).spec)
    except (CampaignError, dsp.DispersionError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    _finish(Path(args.out_dir), cfg, spec, not args.no_plots, False)
    return 0


def main_rerun(argv) -> int:
    from tools.evidence.montecarlo.campaign import CampaignError
    from tools.evidence.montecarlo.rerun import rerun
    p = argparse.ArgumentParser(prog="python -m tools.evidence.montecarlo rerun",
                                description="Re-run one case of a campaign alone, with full "
                                            "logs and the main job's plots.")
    p.add_argument("out_dir", help="campaign directory")
    p.add_argument("--case", type=int, required=True, help="case index")
    p.add_argument("--variant", type=_variants, default=None,
                   help="coordinated, uncoordinated or both (default: the campaign's)")
    p.add_argument("--out", default=None, help="where to write (default OUT_DIR/case-I)")
    args = p.parse_args(argv)
    try:
        report = rerun(args.out_dir, args.case, variants=args.variant, out=args.out)
    except (CampaignError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(report)
    return 0


def main_compare(argv) -> int:
    from tools.evidence.montecarlo.campaign import CampaignError
    from tools.evidence.montecarlo.compare import compare, table
    p = argparse.ArgumentParser(prog="python -m tools.evidence.montecarlo compare",
                                description="Compare two campaigns case by case (e.g. a --hil "
                                            "subset against the in-process campaign).")
    p.add_argument("dir_a", help="first campaign directory")
    p.add_argument("dir_b", help="second campaign directory (same cases and variants)")
    args = p.parse_args(argv)
    try:
        c = compare(args.dir_a, args.dir_b)
    except CampaignError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(table(c))
    return 0


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv and argv[0] == "compare":
        return main_compare(argv[1:])
    if argv and argv[0] == "rerun":
        return main_rerun(argv[1:])
    if argv and argv[0] == "summary":
        return main_summary(argv[1:])
    if argv and argv[0] == "run":
        argv = argv[1:]
    return main_run(argv)


if __name__ == "__main__":
    sys.exit(main())
