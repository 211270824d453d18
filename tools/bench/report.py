"""Print the markdown table of a ``tools.bench --json`` file (for docs/performance.md).

    python -m tools.bench.report bench.json
"""
from __future__ import annotations

import argparse
import json

from tools.bench.cli import Report, print_table


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m tools.bench.report",
                                 description="Print the markdown table of a tools.bench --json "
                                             "file (for docs/performance.md).")
    ap.add_argument("bench_json", metavar="BENCH.json",
                    help="figures written by 'python -m tools.bench --json FILE'")
    args = ap.parse_args(argv)
    with open(args.bench_json, encoding="utf-8") as f:
        data = json.load(f)
    rep = Report()
    rep.rows = data["rows"]
    rep.skipped = data.get("skipped", {})
    meta = data.get("meta", {})
    print(f"`{meta.get('command', 'python -m tools.bench')}` at {meta.get('utc', '?')}"
          + (" (PM QoS 0 us held)" if meta.get("pm_qos_held") else "") + ", "
          f"{meta.get('wall_s', 0):.0f} s; load average (1 min) at the start of each part: "
          + ", ".join(f"{k} {v:.1f}" for k, v in meta.get("load_avg_1min_at_part_start",
                                                          {}).items()))
    print()
    print_table(rep)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
