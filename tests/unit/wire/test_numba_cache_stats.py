"""hyfc_wire.numba_cache.kernel_stats: which kernels a process compiled and which it loaded
from numba's cache (the fc's start-up line, ``python -m tools.precompile``'s report)."""
from __future__ import annotations

import subprocess
import sys
import textwrap

KERNEL_MODULE = textwrap.dedent("""
    from numba import njit

    @njit(cache=True)
    def twice(x):
        return 2.0 * x
""")

PROBE = textwrap.dedent("""
    import sys
    sys.path.insert(0, sys.argv[1])
    import hyfc_tmpkern
    from hyfc_wire.numba_cache import kernel_stats
    assert kernel_stats(("hyfc_tmpkern",)) == (0, 0)      # nothing called yet
    hyfc_tmpkern.twice(1.5)
    print(*kernel_stats(("hyfc_tmpkern",)))
    print(*kernel_stats(("no_such_package",)))
""")


def _probe(path) -> list[str]:
    res = subprocess.run([sys.executable, "-c", PROBE, str(path)], capture_output=True,
                         text=True, timeout=120)
    assert res.returncode == 0, res.stderr
    return res.stdout.split("\n")[:2]


def test_a_kernel_is_counted_compiled_then_loaded_from_the_cache(tmp_path):
    # GIVEN a cache=True kernel in a fresh module (its cache next to it, empty)
    (tmp_path / "hyfc_tmpkern.py").write_text(KERNEL_MODULE)
    # WHEN the first process calls it: compiled; other packages are not counted
    assert _probe(tmp_path) == ["0 1", "0 0"]
    # THEN the next process loads it from the cache instead
    assert _probe(tmp_path) == ["1 0", "0 0"]
