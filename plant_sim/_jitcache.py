"""Keep numba's on-disk caches of the plant kernels consistent with the plant's sources.

numba (``cache=True``) revalidates a cached function against its own source file only. The
plant's kernels call each other across modules and freeze module-level constants (state and
parameter indices, vehicle data) into the machine code, so editing e.g. ``vehicle.py`` or
``aero.py`` would leave ``dynamics.py``'s cache silently running the old code. ``refresh``
removes a kernel module's cache files when any of the plant's kernel sources is newer than
they are; each kernel module calls it at import, before its first compiled call.
(plant_sim never imports fc, so this is the plant's own copy of the idea.)
"""
from __future__ import annotations

from pathlib import Path

_HERE = Path(__file__).resolve().parent
KERNEL_SOURCES = ("vehicle.py", "atmosphere.py", "aero.py", "dynamics.py", "sensors.py", "sim.py")


def refresh(module_file: str) -> int:
    """Delete ``module_file``'s .nbi/.nbc files if a kernel source is newer; returns the count."""
    mod = Path(module_file).resolve()
    cache_dir = mod.parent / "__pycache__"
    try:
        cached = [p for p in cache_dir.iterdir()
                  if p.name.startswith(mod.stem + ".") and p.suffix in (".nbi", ".nbc")]
    except OSError:
        return 0
    if not cached:
        return 0
    try:
        built = min(p.stat().st_mtime for p in cached)
        newest = max((_HERE / f).stat().st_mtime for f in KERNEL_SOURCES)
    except OSError:
        return 0
    if newest <= built:
        return 0
    removed = 0
    for p in cached:
        try:
            p.unlink()
            removed += 1
        except OSError:        # another process got there first
            pass
    return removed
