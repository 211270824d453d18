"""``python -m tools.fly``: fly a scenario in process (tools.sitl.closed_loop) and print the figures.

    python -m tools.fly attitude [SCENARIO] [--shaping steps|prefilter] [--table] [--perturbed N]
        the attitude law flying the scenario's command timeline
        (tools.sitl.closed_loop.core.simulate; the reports of tools.sitl.closed_loop.reports)
    python -m tools.fly guided [cruise|steps|mission] [--duration S] [--plot PNG]
        guidance + the attitude law flying the scenario's targets
        (tools.sitl.closed_loop.guided.fly)
"""
from __future__ import annotations

import argparse


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="python -m tools.fly", description=__doc__.split("\n")[0])
    sub = ap.add_subparsers(dest="what", required=True, metavar="attitude|guided")

    at = sub.add_parser("attitude", help="the attitude law flying a scenario's command timeline",
                        description="Fly a scenario in process and print the figures.")
    at.add_argument("scenario", nargs="?", default="paper",
                    help="plant scenario name or TOML path (default paper)")
    at.add_argument("--duration", type=float, default=None, metavar="S",
                    help="sim seconds to fly (default: the scenario's)")
    at.add_argument("--shaping", choices=("steps", "prefilter"), default="steps",
                    help="the paper's step commands or the law's reference prefilter "
                         "(default steps)")
    at.add_argument("--variant", choices=("coordinated", "uncoordinated", "both"), default="both",
                    help="controller variant(s) to fly (default both)")
    at.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                    help="law parameter override (table units), repeatable")
    at.add_argument("--estimate", choices=("truth", "sensors"), default="truth",
                    help="the law sees the plant's truth, or the sensors through the fc's "
                         "estimator (default truth)")
    at.add_argument("--perturbed", type=int, default=0, metavar="N",
                    help="compare the variants over N perturbed copies of the scenario")
    at.add_argument("--table", action="store_true",
                    help="print a markdown table (both variants, steps and prefilter)")

    gu = sub.add_parser("guided", help="guidance + the attitude law flying a scenario's targets",
                        description="Guided flight in process: hold, steps, mission.")
    gu.add_argument("flight", choices=("cruise", "steps", "mission"), nargs="?", default="cruise",
                    help="cruise: hold the cruise point; steps: altitude, course and speed steps; "
                         "mission: the mission scenario's targets (default cruise)")
    gu.add_argument("--scenario", default=None, help="scenario (default: cruise, or mission)")
    gu.add_argument("--duration", type=float, default=None,
                    help="sim time to fly, s (default: the chosen flight's own length)")
    gu.add_argument("--transient", type=float, default=300.0,
                    help="hold figures from this sim time on (s)")
    gu.add_argument("--estimate", choices=("truth", "sensors"), default="sensors",
                    help="feed the loops the truth or the fc's estimator on the sensors")
    gu.add_argument("--seed", type=int, default=None,
                    help="sensor noise seed (default: the scenario's)")
    gu.add_argument("--uncoordinated", action="store_true",
                    help="fly the uncoordinated inner law (default coordinated)")
    gu.add_argument("--plot", default=None, metavar="PNG",
                    help="cruise/mission: write a plot of the flight to this file")
    return ap


def attitude(a: argparse.Namespace) -> int:
    from tools.sitl.closed_loop import simulate
    from tools.sitl.closed_loop.reports import markdown_table, perturbed_comparison, summary_line
    from fc.control.params import parse_sets
    try:
        ov = parse_sets(a.set)
    except ValueError as exc:
        raise SystemExit(f"python -m tools.fly: --set: {exc}") from None
    variants = (True, False) if a.variant == "both" else (a.variant == "coordinated",)
    if a.perturbed:
        print(perturbed_comparison(a.perturbed, command_shaping=a.shaping, law_overrides=ov,
                                   scenario=a.scenario))
        return 0
    if a.table:
        print(markdown_table(a.scenario, duration_s=a.duration, law_overrides=ov,
                             estimate=a.estimate))
        return 0
    for co in variants:
        res = simulate(a.scenario, coordinated=co, duration_s=a.duration,
                       command_shaping=a.shaping, law_overrides=ov, estimate=a.estimate)
        print(summary_line(res) + f" | wall {res.wall_s:.2f}s")
    return 0


def guided(a: argparse.Namespace) -> int:
    from tools.sitl.closed_loop.guided import (fly, format_figures, mission_legs, plot_flight,
                                               step_responses)
    co = not a.uncoordinated
    if a.flight == "steps":
        for f in step_responses(a.scenario or "cruise", estimate=a.estimate, coordinated=co,
                                seed=a.seed):
            print(format_figures(f))
        return 0
    name = a.scenario or a.flight
    res = fly(name, duration_s=a.duration, estimate=a.estimate, coordinated=co, seed=a.seed)
    print(f"{name}: {res.t_s[-1]:.0f} s sim in {res.wall_s:.1f} s wall, diverged={res.diverged}")
    if a.plot:
        print(f"plot: {plot_flight(res, a.plot)}")
    if a.flight == "mission":
        for line in mission_legs(res):
            print(line)
        print(format_figures(res.hold_figures(0.0)))
        return 0
    print(format_figures(res.hold_figures(a.transient)))
    return 0


def main(argv: list[str] | None = None) -> int:
    a = build_parser().parse_args(argv)
    return attitude(a) if a.what == "attitude" else guided(a)


if __name__ == "__main__":
    raise SystemExit(main())
