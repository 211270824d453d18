"""hyfc flight controller: the autopilot process (``python -m fc``, docs/fc.md); the control law
is the pure library ``fc.control`` (docs/control_law.md)."""
from pathlib import Path as _Path

from hyfc_wire.numba_cache import drop_stale as _drop_stale


def _drop_stale_law_caches() -> None:
    """numba's ``cache=True`` checks only a kernel's own source file; the law's kernels freeze
    the constants of its layout and parameter modules and inline each other's functions. So
    every import of ``fc.control`` (it passes through this package) first drops the numba cache
    of each law module that is older than any law module. Done here, not inside fc/control,
    so that the law imports nothing of ours outside itself (docs/architecture.md s. 1)."""
    law = sorted((_Path(__file__).parent / "control").glob("*.py"))
    deps = [str(f) for f in law]
    for f in law:
        _drop_stale(f, deps)


_drop_stale_law_caches()
