"""``python -m tools.fly``: fly a scenario in process (tools.sitl.closed_loop) and print the figures.

    python -m tools.fly attitude [SCENARIO] [--shaping steps|prefilter] [--table] ...
        the paper's attitude law flying the plant (tools.sitl.closed_loop.core.simulate)
    python -m tools.fly guided [cruise|steps|mission] [--duration S] [--plot PNG] ...
        guidance + law + plant (tools.sitl.closed_loop.guided.fly)

Each subcommand's options: ``python -m tools.fly attitude --help``, ``... guided --help``.
"""
from __future__ import annotations

import argparse
import sys

SUBCOMMANDS = {"attitude": "the attitude law flying a scenario's command timeline",
               "guided": "guidance + the attitude law flying a scenario's targets"}


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    if argv and argv[0] == "attitude":
        from tools.sitl.closed_loop.reports import main as attitude_main
        return attitude_main(argv[1:])
    if argv and argv[0] == "guided":
        from tools.sitl.closed_loop.guided import main as guided_main
        return guided_main(argv[1:])
    ap = argparse.ArgumentParser(prog="python -m tools.fly", description=__doc__.split("\n")[0])
    ap.add_argument("subcommand", choices=sorted(SUBCOMMANDS),
                    help="; ".join(f"{k}: {v}" for k, v in SUBCOMMANDS.items()))
    ap.parse_args(argv)
    return 2


if __name__ == "__main__":
    raise SystemExit(main())
