"""Keep numba's on-disk caches of the plant kernels consistent with the plant's sources.

numba (``cache=True``) revalidates a cached function against its own source file only. The
plant's kernels call each other across modules and freeze module-level constants (state and
parameter indices, vehicle data, the contract's ``M_*`` layout) into the machine code, so
editing e.g. ``vehicle.py`` or ``aero.py`` would leave ``dynamics.py``'s cache silently running
the old code. ``refresh`` removes a kernel module's cache files when any of the plant's kernel
sources is newer than they are (hyfc_wire.numba_cache); each kernel module calls it at import,
before its first compiled call.
"""
from __future__ import annotations

from pathlib import Path

from hyfc_wire import layout as _layout
from hyfc_wire.numba_cache import drop_stale

_HERE = Path(__file__).resolve().parent
KERNEL_SOURCES = ("vehicle.py", "atmosphere.py", "aero.py", "dynamics.py", "sensors.py", "sim.py")


def refresh(module_file: str) -> int:
    """Delete ``module_file``'s .nbi/.nbc files if a kernel source is newer; returns the count."""
    return drop_stale(module_file, [_HERE / f for f in KERNEL_SOURCES] + [_layout.__file__])
