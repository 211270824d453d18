"""Drop numba on-disk caches that are older than the modules they were compiled against.

numba's ``cache=True`` checks only the source file of the cached function itself. A kernel
that calls functions of another module, or reads its module-level index constants (which
numba freezes into the machine code, e.g. ``hyfc_wire.layout``'s ``M_*``), keeps its stale
cache when that other module changes: it would silently run old code with old array layouts.
``drop_stale(module_file, deps)`` deletes the cache files of ``module_file`` when any
dependency is newer than them; call it at module import, before the first call of a cached
function. The controller's law, the plant's kernels and the in-process loops all use it.

Only the default cache location (``__pycache__`` next to the module) is handled; with
NUMBA_CACHE_DIR set, clear that directory after changing the code.

``kernel_stats(packages)`` says how the loaded kernels got their machine code (from the cache or
compiled in this process): ``cache_report`` is the line the fc and the plant log at start,
``python -m tools.precompile`` prints the counts.
"""
from __future__ import annotations

import os
import sys
from pathlib import Path

__all__ = ["cache_report", "drop_stale", "kernel_stats", "package_files"]


def _cache_files(module_file: Path) -> list[Path]:
    pyc = module_file.parent / "__pycache__"
    try:
        names = list(pyc.iterdir())
    except OSError:
        return []
    stem = module_file.stem + "."
    return [p for p in names if p.name.startswith(stem) and p.suffix in (".nbi", ".nbc")]


def drop_stale(module_file: str | os.PathLike, deps) -> int:
    """Delete ``module_file``'s numba cache (.nbi/.nbc) if a file in ``deps`` is newer than the
    oldest of them; returns how many files were deleted (0: none, or fresh)."""
    files = _cache_files(Path(module_file).resolve())
    if not files:
        return 0
    try:
        oldest = min(p.stat().st_mtime for p in files)
        newest_dep = max(Path(d).stat().st_mtime for d in deps)
    except (OSError, ValueError):
        return 0
    if newest_dep <= oldest:
        return 0
    n = 0
    for p in files:
        try:
            p.unlink()
            n += 1
        except OSError:        # another process got there first
            pass
    return n


def package_files(*modules) -> list[str]:
    """Source files of the given imported modules (for ``deps``)."""
    return [m.__file__ for m in modules]



def kernel_stats(packages: tuple[str, ...]) -> tuple[int, int]:
    """(loaded from the on-disk cache, compiled in this process): counts of the numba kernel
    specialisations so far, over the kernels defined in the already imported modules of
    ``packages`` (e.g. ``("fc",)``). A warm start loads only the entry points called from
    Python; a cold one also compiles every kernel they call (counted as compiled too)."""
    from numba.core.dispatcher import Dispatcher
    hits = misses = 0
    for name, mod in list(sys.modules.items()):
        if mod is None or name.split(".", 1)[0] not in packages:
            continue
        for obj in list(vars(mod).values()):
            if isinstance(obj, Dispatcher) and obj.__module__ == name:
                st = obj.stats
                hits += sum(st.cache_hits.values())
                misses += sum(st.cache_misses.values())
    return hits, misses


def cache_report(packages: tuple[str, ...], warm_up_s: float) -> str:
    """The start-up log line of a process whose kernels (``packages``) were just warmed up in
    ``warm_up_s``: loaded from the cache, or compiled (then how to avoid it next time)."""
    loaded, compiled = kernel_stats(packages)
    if compiled:
        return (f"numba cache cold or stale: {compiled} kernel specialisations compiled at "
                f"start ({loaded} loaded), warm-up {warm_up_s:.1f} s; run `python -m "
                f"tools.precompile` (hyfc-precompile) once after installing or changing the code")
    return f"numba cache warm: {loaded} kernels loaded, warm-up {warm_up_s:.2f} s"
