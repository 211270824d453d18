"""``python -m tools.precompile`` (``hyfc-precompile``) fills numba's cache with the kernels the
fc loads at start, with the signatures it uses: a fc started afterwards compiles nothing and
says so in fc.log (docs/fc.md, start-up)."""
from __future__ import annotations

import re
import subprocess
import sys

import pytest

from tests.fc_harness import REPO, FcProcess

pytestmark = [pytest.mark.hil, pytest.mark.slow]


def test_a_precompiled_cache_lets_the_fc_start_without_compiling(tmp_path, monkeypatch):
    # GIVEN an empty cache directory, for this test's processes only
    cache = tmp_path / "numba_cache"
    cache.mkdir()
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(cache))
    # WHEN the fc's part is precompiled into it
    res = subprocess.run([sys.executable, "-m", "tools.precompile", "--only", "fc"], cwd=REPO,
                         capture_output=True, text=True, timeout=280)
    assert res.returncode == 0, res.stderr
    m = re.search(r"precompile fc: (\d+) kernel specialisations compiled, (\d+) loaded",
                  res.stdout)
    assert m is not None, res.stdout
    assert int(m.group(1)) > 0 and int(m.group(2)) == 0       # it really started cold
    assert list(cache.rglob("*.nbi"))
    # THEN python -m fc loads every kernel it needs from there
    with FcProcess(str(tmp_path / "run")) as fc:
        assert fc.stop() == 0
    log = (tmp_path / "run" / "fc.log").read_text()
    assert "numba cache warm" in log, log
    assert "cold or stale" not in log
