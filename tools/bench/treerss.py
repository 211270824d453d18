"""Memory of a command's whole process tree, sampled while it runs (issue 24).

    python -m tools.bench treerss [--every 0.5] [--log FILE.jsonl] -- COMMAND [ARGS...]

Runs COMMAND and every ``--every`` seconds reads VmRSS, RssAnon and RssFile (MB) of it and
of each descendant from /proc; prints the peak of the summed VmRSS (when, and each process's
share then), each process's own peak, and the wall time. ``--log`` keeps every sample (JSON
lines). A summed RSS counts twice the file pages that two processes map from the same file
(numba's LLVM library, numpy), which RssFile shows. Linux only. Figures only: no target is
asserted here.
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time


def _tree(pid: int) -> list[int]:
    out = [pid]
    try:
        with open(f"/proc/{pid}/task/{pid}/children") as f:
            kids = f.read().split()
    except OSError:
        return out
    for c in kids:
        out += _tree(int(c))
    return out


def _mem_mb(pid: int) -> dict:
    got = {}
    try:
        with open(f"/proc/{pid}/status") as f:
            for line in f:
                key = line.split(":", 1)[0]
                if key in ("VmRSS", "RssAnon", "RssFile"):
                    got[key] = int(line.split()[1]) / 1024.0
    except OSError:
        return {}
    return got


def _label(pid: int) -> str:
    try:
        with open(f"/proc/{pid}/cmdline", "rb") as f:
            argv = f.read().split(b"\0")
    except OSError:
        return f"pid {pid}"
    words = [a.decode(errors="replace") for a in argv if a]
    if not words:
        return ""
    if len(words) >= 3 and words[1] == "-m":
        return f"{words[2]} ({pid})"
    return f"{' '.join(words[:2])[-40:]} ({pid})"


def sample(argv: list[str], every_s: float = 0.5, log=None) -> dict:
    """Run ``argv``; the peaks of its process tree's memory (MB) and its wall time."""
    t0 = time.monotonic()
    proc = subprocess.Popen(argv)
    peak = {"sum_mb": 0.0, "t_s": 0.0, "processes": {}}
    own: dict[str, float] = {}
    labels: dict[int, str] = {}
    try:
        while proc.poll() is None:
            t = time.monotonic() - t0
            now = {}
            for pid in _tree(proc.pid):
                m = _mem_mb(pid)
                if m:
                    name = labels.get(pid) or _label(pid)     # blank while it execs
                    if not name:
                        continue
                    labels[pid] = name
                    now[name] = m
                    own[name] = max(own.get(name, 0.0), m.get("VmRSS", 0.0))
            total = sum(m.get("VmRSS", 0.0) for m in now.values())
            if total > peak["sum_mb"]:
                peak = {"sum_mb": total, "t_s": t, "processes": now}
            if log is not None:
                log.write(json.dumps({"t_s": round(t, 3), **now}) + "\n")
            time.sleep(every_s)
    except KeyboardInterrupt:
        proc.terminate()
        proc.wait(10)
    return {"returncode": proc.returncode, "wall_s": time.monotonic() - t0, "peak": peak,
            "own_peaks_mb": own}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m tools.bench treerss",
                                 description=__doc__.split("\n")[0])
    ap.add_argument("--every", type=float, default=0.5, help="sampling period, s (default 0.5)")
    ap.add_argument("--log", metavar="FILE", help="every sample as JSON lines")
    ap.add_argument("command", nargs=argparse.REMAINDER, help="-- COMMAND [ARGS...]")
    args = ap.parse_args(argv)
    cmd = args.command[1:] if args.command[:1] == ["--"] else args.command
    if not cmd:
        ap.error("give the command to run after --")
    if args.every <= 0:
        ap.error("--every must be > 0")
    log = open(args.log, "w") if args.log else None
    try:
        r = sample(cmd, args.every, log)
    finally:
        if log is not None:
            log.close()
    p = r["peak"]
    print(f"treerss: exit {r['returncode']}, wall {r['wall_s']:.1f} s; peak of the summed VmRSS "
          f"{p['sum_mb']:.0f} MB at {p['t_s']:.1f} s:")
    for name, m in p["processes"].items():
        print(f"  {name}: {m.get('VmRSS', 0):.0f} MB (anon {m.get('RssAnon', 0):.0f}, "
              f"file {m.get('RssFile', 0):.0f})")
    print("each process's own peak: " + ", ".join(f"{k} {v:.0f} MB"
                                                   for k, v in r["own_peaks_mb"].items()))
    return 0 if r["returncode"] == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
