"""tools/precompile.py - fill numba's on-disk cache with every kernel the processes load.

``python -m tools.precompile`` (console script ``hyfc-precompile``) compiles, once, the numba
kernels the controller (``python -m fc``) and the plant (``python -m plant_sim``) load at start,
with the signatures they use: it runs the same warm-ups the processes run before READY (the
controller is built as ``python -m fc`` builds it, on ephemeral loopback ports in a temporary
directory; the plant's ``PlantSim.warm_up`` on the paper scenario). The two parts compile in
two processes at once (``--jobs``). Afterwards each process starts in about a second instead
of 10-15 s (docs/performance.md, "housekeeping and cold start"); the fc's log says which case
it met (fc/__main__.py).

The cache lands where numba puts it: ``__pycache__`` next to the sources (an editable install,
a writable site-packages), or NUMBA_CACHE_DIR when that is set. It stays valid until a kernel's
source changes (hyfc_wire/numba_cache.py drops stale entries), so the README's set-up and
``.ci/run`` run it once after ``pip install``. The in-process tools' own loops
(tools.sitl, tools.sitl.closed_loop.guided) are not compiled here: they compile on their first use.
"""
from __future__ import annotations

import argparse
import logging
import subprocess
import sys
import tempfile
import time

__all__ = ["PARTS", "compile_fc", "compile_plant", "main"]


def compile_fc() -> tuple[int, int]:
    """Build a lockstep controller as ``python -m fc`` does (law, estimator and guidance warm
    up in its constructor) and close it. Returns (kernels loaded, compiled) of ``fc``."""
    from fc.app import FcConfig, FlightController
    from hyfc_wire.numba_cache import kernel_stats
    log = logging.getLogger("tools.precompile")
    log.addHandler(logging.NullHandler())
    log.propagate = False
    with tempfile.TemporaryDirectory(prefix="hyfc-precompile-") as d:
        cfg = FcConfig(mode="lockstep", plant_bind=("127.0.0.1", 0), gcs=[],
                       gcs_bind=("127.0.0.1", 0), out=d)
        FlightController(cfg, log).close()
    return kernel_stats(("fc",))


def compile_plant() -> tuple[int, int]:
    """The plant process's warm-up on the paper scenario. Returns (loaded, compiled) of
    ``plant_sim``."""
    from hyfc_wire.numba_cache import kernel_stats
    from hyfc_wire.pwm import DEFAULT_PWM
    from plant_sim.link import PlantLink
    from plant_sim.scenario import load
    from plant_sim.sim import PlantSim
    PlantSim(load("paper")).warm_up()
    from plant_sim.frame_path import warm_up
    warm_up()           # the lockstep's compiled frame (plant_sim/frame_path.py)
    # the link's start-up check runs its compiled framing and servo decoding
    # (hyfc_wire.frame_kernels.sensor_frame, decode_servo) with the signatures of the run
    PlantLink(("127.0.0.1", 9), ("127.0.0.1", 0), DEFAULT_PWM).close()
    return kernel_stats(("plant_sim",))


#: part name -> the function that compiles it
PARTS = {"fc": compile_fc, "plant": compile_plant}


def _run_part(name: str) -> int:
    t0 = time.perf_counter()
    loaded, compiled = PARTS[name]()
    print(f"precompile {name}: {compiled} kernel specialisations compiled, {loaded} loaded "
          f"from the cache, {time.perf_counter() - t0:.1f} s", flush=True)
    return 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m tools.precompile",
        description="Compile the numba kernels of the controller and the plant into numba's "
                    "cache once, so that their processes start in about a second.")
    ap.add_argument("--only", choices=sorted(PARTS), action="append",
                    help="compile only this part (repeatable; default: all)")
    ap.add_argument("--jobs", type=int, default=2,
                    help="parts compiled at once, each in its own process (default 2; 1: in "
                         "this process, one after the other)")
    args = ap.parse_args(argv)
    names = args.only or list(PARTS)
    t0 = time.perf_counter()
    if args.jobs <= 1 or len(names) == 1:
        for name in names:
            _run_part(name)
    else:
        # one process per part: numba compiles under the GIL, so threads would not overlap
        failed = []
        for i in range(0, len(names), args.jobs):
            procs = [(n, subprocess.Popen([sys.executable, "-m", "tools.precompile",
                                           "--only", n, "--jobs", "1"]))
                     for n in names[i:i + args.jobs]]
            failed += [n for n, p in procs if p.wait() != 0]
        if failed:
            print(f"precompile: failed: {', '.join(failed)}", file=sys.stderr)
            return 1
    if len(names) > 1:
        print(f"precompile: done in {time.perf_counter() - t0:.1f} s", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
