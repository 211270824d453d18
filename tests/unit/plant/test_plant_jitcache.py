"""plant_sim._jitcache: stale numba caches of the plant kernels are removed, fresh ones kept."""
import os
import time

from plant_sim import _jitcache


def test_stale_cache_files_are_removed_and_fresh_ones_kept(tmp_path):
    mod = tmp_path / "kern.py"
    mod.write_text("# kernel module stand-in\n")
    pyc = tmp_path / "__pycache__"
    pyc.mkdir()
    nbi = pyc / "kern.kern-10.py311.nbi"
    nbc = pyc / "kern.kern-10.py311.1.nbc"
    other = pyc / "other.f-1.py311.nbi"
    for f in (nbi, nbc, other):
        f.write_bytes(b"x")
    newest_src = max((_jitcache._HERE / f).stat().st_mtime for f in _jitcache.KERNEL_SOURCES)
    # GIVEN caches newer than every plant kernel source: kept
    future = max(newest_src, time.time()) + 100.0
    for f in (nbi, nbc):
        os.utime(f, (future, future))
    assert _jitcache.refresh(str(mod)) == 0 and nbi.exists() and nbc.exists()
    # WHEN a kernel source is newer than the cache: both files of that module go, others stay
    past = newest_src - 100.0
    for f in (nbi, nbc):
        os.utime(f, (past, past))
    assert _jitcache.refresh(str(mod)) == 2
    assert not nbi.exists() and not nbc.exists() and other.exists()
    # and a module without a cache is left alone
    assert _jitcache.refresh(str(tmp_path / "none.py")) == 0
