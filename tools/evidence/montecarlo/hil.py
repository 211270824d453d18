"""The ``--hil`` backend: a case flown by the two processes over loopback UDP.

Uses the main job's machinery (``tools.sitl.runner.run_variant``, lockstep mode): the dispersed
scenario is written as a TOML file, the controller process (``python -m fc``) and the plant
process (``python -m plant_sim run``) are started on free loopback ports, fly the variant, are
stopped, and the run directory's logs are read back with ``tools.sitl.rundata`` (the same code
that makes the main job's ``summary.json``). Slower than in process (process start-up plus a
UDP exchange per frame), so meant for a faithful subset of cases; each Dask task then runs two
processes of its own.
"""
from __future__ import annotations

import shutil
import tempfile
import threading
from pathlib import Path

import numpy as np


def fly(scenario, variant: str, duration_s, sim_seed: int, law_overrides: dict,
        full: bool = False, keep_dir: Path | None = None):
    """Fly one variant of a dispersed scenario through the two processes (lockstep)."""
    from tools.sitl import rundata
    from tools.sitl.runner import RunConfig, run_variant
    from tools.evidence.montecarlo.flight import Flight
    if law_overrides:
        raise ValueError("law overrides are not supported with --hil yet")
    tmp = Path(tempfile.mkdtemp(prefix="mc-hil-")) if keep_dir is None else Path(keep_dir)
    tmp.mkdir(parents=True, exist_ok=True)
    try:
        scen_path = tmp / "scenario.toml"
        scen_path.write_text(scenario.to_toml())
        commands = rundata.read_timeline(scen_path)
        cfg = RunConfig(scenario=str(scen_path), mode="lockstep", variants=(variant,),
                        out_dir=tmp, duration_s=duration_s, seed=int(sim_seed), quiet=True)
        vdir = tmp / variant
        res = run_variant(cfg, variant, vdir, commands, str(scen_path), threading.Event())
        if not res.ok:
            raise RuntimeError(f"HIL run failed: {res.error}")
        entry, plot = rundata.variant_summary(vdir, duration_s)
        cmd_t = plot["cmd_t_s"]
        cmd = np.column_stack([plot[f"cmd_{ch}_rad"] for ch in ("alpha", "beta", "mu")])
        return Flight(t_s=np.asarray(plot["t_s"], float),
                      alpha_rad=np.asarray(plot["alpha_rad"], float),
                      beta_rad=np.asarray(plot["beta_rad"], float),
                      mu_rad=np.asarray(plot["mu_rad"], float),
                      cmd_t_s=np.asarray(cmd_t, float), cmd_rad=cmd,
                      diverged=bool(entry["diverged"]), surfaces=entry.get("surfaces"),
                      full=plot if full else None)
    finally:
        if keep_dir is None:
            shutil.rmtree(tmp, ignore_errors=True)
