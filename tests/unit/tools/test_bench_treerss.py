"""tools.bench treerss: the memory of a command's process tree, child processes included."""
from __future__ import annotations

import sys

from tools.bench.treerss import main, sample

#: a parent that starts a child holding 80 MB of touched memory for a second
CHILD = ("import subprocess, sys; subprocess.run([sys.executable, '-c', "
         "'import time; b = bytearray(80 << 20); b[::4096] = b\"x\" * len(b[::4096]); "
         "time.sleep(1.0)'], check=True)")


def test_the_peak_sums_the_child_processes_memory():
    r = sample([sys.executable, "-c", CHILD], every_s=0.05)
    assert r["returncode"] == 0
    assert len(r["peak"]["processes"]) == 2                 # parent and child at the peak
    child = [m for m in r["peak"]["processes"].values() if m["VmRSS"] >= 80.0]
    assert child, r["peak"]
    assert r["peak"]["sum_mb"] >= 80.0 + min(m["VmRSS"] for m in r["peak"]["processes"].values())


def test_the_command_line_needs_a_command_and_reports_its_exit(capsys):
    try:
        main(["--every", "0.05"])
    except SystemExit as e:
        assert e.code == 2
    else:
        raise AssertionError("no command accepted")
    assert main(["--every", "0.05", "--", sys.executable, "-c", "raise SystemExit(3)"]) == 1
    assert "exit 3" in capsys.readouterr().out
