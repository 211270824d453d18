"""Print the markdown table of a ``tools.bench --json`` file (for docs/performance.md).

    python -m tools.bench.report bench.json
"""
from __future__ import annotations

import json
import sys

from tools.bench.cli import Report, print_table


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) != 1:
        print("usage: python -m tools.bench.report BENCH.json", file=sys.stderr)
        return 2
    with open(argv[0], encoding="utf-8") as f:
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
