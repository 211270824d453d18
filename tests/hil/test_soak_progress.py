"""``python -m tools.soak`` says how it is going while it runs (issue 12 point 7): progress
lines on stderr during the soak (sim time, the fc's late ticks and rejected input, failsafes,
what the relay dropped), the figures as JSON on stdout at the end."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tools.sitl.procs import repo_env

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.hil
def test_soak_prints_progress_while_it_runs(tmp_path):
    env = repo_env()
    proc = subprocess.Popen([sys.executable, "-m", "tools.soak", "--duration", "5",
                             "--progress-every", "1", "--flood-rate", "0", "--out",
                             str(tmp_path / "soak")],
                            cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, start_new_session=True)
    err_lines = []
    try:
        deadline = time.monotonic() + 240
        running_at_progress = None
        while time.monotonic() < deadline:
            line = proc.stderr.readline()
            if not line:
                break
            err_lines.append(line)
            if line.startswith("soak: t ="):
                running_at_progress = proc.poll() is None
                break
        assert running_at_progress, "no progress line while the soak ran:\n" + "".join(err_lines)
        out, rest = proc.communicate(timeout=180)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait(timeout=10)
    err = "".join(err_lines) + rest
    assert proc.returncode == 0, err
    progress = [ln for ln in err.splitlines() if ln.startswith("soak: t =")]
    assert len(progress) >= 2, err                       # about one a second for 5 s
    assert "late ticks" in progress[0] and "failsafes 0" in progress[0]
    assert "soak: done" in err.splitlines()[-1]
    fig = json.loads(out)                                # stdout is still only the figures
    assert fig["exit_codes"] == {"plant": 0, "fc": 0}
