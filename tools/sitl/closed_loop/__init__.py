"""tools.sitl.closed_loop: the one in-process closed loop (law + plant in one numba loop, no UDP).

- ``core``: the attitude loop, ``simulate(scenario, ...) -> ClosedLoopResult`` (the paper's law
  flying the plant, fed the truth or the fc's estimator on the sensors), and the per-frame
  pieces the other loops reuse (``sense_frame``, ``law_frame``, ``truth_kernel``);
- ``guided``: the guided loop, ``fly(scenario, ...) -> GuidedResult`` (fc.guidance + the law
  + the plant, targets from the scenario's ``[[target]]`` timeline), on ``core``'s frame pieces;
- ``reports``: the text reports of attitude flights (summary line, markdown table, perturbed
  comparison).

The command on top is ``python -m tools.fly attitude|guided`` (tools/fly.py). The attitude
loop's names are importable from the package itself (``from tools.sitl.closed_loop import
simulate``); the guided loop from ``tools.sitl.closed_loop.guided``.
"""
from tools.sitl.closed_loop.core import (TRUTH_N, ClosedLoopResult, law_frame, sense_frame,
                                         simulate, truth_kernel)

__all__ = ["TRUTH_N", "ClosedLoopResult", "law_frame", "sense_frame", "simulate",
           "truth_kernel"]
