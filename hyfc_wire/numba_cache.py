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
"""
from __future__ import annotations

import os
from pathlib import Path

__all__ = ["drop_stale", "package_files"]


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

