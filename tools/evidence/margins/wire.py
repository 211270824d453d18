"""tools/evidence/margins/wire.py - the time-delay margin over the wire (tools.evidence.margins ``wire``).

Lockstep (default): the two processes fly in lockstep (tools.sitl.runner.run_variant, the main
job's machinery) with tools.sitl.linkimpair's frame delay between them: the plant applies at frame
k the fc's answer to frame k - N. Real time (``realtime=True``): the two processes fly in real
time and the relay holds each fc -> plant datagram (SERVO_OUTPUT_RAW) N wall-clock ms
(``Impairment(delay_s=...)``); the plant applies the newest answer at its next frame boundary,
so the loop sees N ms plus up to one frame plus the link's latency, and the load of the machine
matters (each row records the load average).

The relay runs inside the plant's process: the runner starts the plant as
``python -m tools.evidence.margins.wire --delay-frames N -- <plant arguments>`` (or ``--delay-ms X``),
which starts the relay toward the fc's port (the plant's ``--fc``), points the plant at the
relay, and runs the plant's own main (lockstep: the relay thread costs speed, never results).
"""
from __future__ import annotations

import argparse
import json
import sys
import threading
from pathlib import Path

import numpy as np


def plant_with_relay(argv=None) -> int:
    """Entry point: ``--delay-frames N -- <plant_sim arguments>`` (see the module docstring)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    cut = argv.index("--") if "--" in argv else len(argv)
    ap = argparse.ArgumentParser(
        prog="python -m tools.evidence.margins.wire",
        usage="python -m tools.evidence.margins.wire --delay-frames N -- <plant_sim arguments>",
        description="The plant with a lockstep frame-delay relay toward its --fc "
                    "(tools.evidence.margins wire starts it).")
    g = ap.add_mutually_exclusive_group(required=True)
    g.add_argument("--delay-frames", type=int,
                   help="lockstep: the plant applies at frame k the fc's answer to frame k - N")
    g.add_argument("--delay-ms", type=float,
                   help="real time: each fc -> plant datagram is held this many ms")
    a = ap.parse_args(argv[:cut])
    plant_argv = argv[cut + 1:]
    if "--fc" not in plant_argv:
        ap.error("the plant's arguments after -- must name --fc HOST:PORT")
    from tools.sitl.linkimpair import Impairment, LinkImpair, parse_hostport
    i = plant_argv.index("--fc")
    target = parse_hostport(plant_argv[i + 1])
    down = (Impairment(delay_frames=a.delay_frames) if a.delay_frames is not None
            else Impairment(delay_s=a.delay_ms * 1e-3))
    relay = LinkImpair(target, down=down).start()
    host, port = relay.listen_address
    plant_argv[i + 1] = f"{host}:{port}"
    from plant_sim.__main__ import main as plant_main
    try:
        rc = plant_main(plant_argv)
    finally:
        counters = relay.stop()
        print("RELAY " + json.dumps(counters), file=sys.stderr, flush=True)
    return rc


def wire_delay_runs(scenario, frames: list, out: Path, variant: str = "coordinated",
                    overrides: dict | None = None, duration_s: float = 20.0,
                    realtime: bool = False) -> int:
    """Fly ``scenario`` over the wire with each extra delay in ``frames`` (lockstep frames, or
    with ``realtime`` wall-clock ms); print and write ``out/wire.md`` / ``wire.json`` with the
    stability verdict of each (tools.evidence.margins.flight.stable)."""
    import os
    from tools.sitl import rundata
    from tools.sitl.runner import RunConfig, run_variant
    from tools.evidence.margins.flight import stable
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    scen_path = out / "scenario.toml"
    scen_path.write_text(scenario.to_toml())
    params = None
    if overrides:
        params = out / "params.parm"
        params.write_text("".join(f"{k} {v!r}\n" for k, v in overrides.items()))
    commands = rundata.read_timeline(scen_path)
    fdt = 1.0 / float(scenario.data["timing"]["frame_hz"])
    cmd = np.radians(np.array(scenario.commands[0][1:4], float))
    rows = []
    for n in frames:
        if realtime:
            vdir = out / f"delay_{float(n):07.2f}ms"
            relay = ("--delay-ms", repr(float(n)))
        else:
            vdir = out / f"delay_{n:04d}"
            relay = ("--delay-frames", str(int(n)))
        cfg = RunConfig(scenario=str(scen_path), mode="realtime" if realtime else "lockstep",
                        variants=(variant,), out_dir=out, duration_s=duration_s,
                        seed=int(scenario.seed), quiet=True, params_file=params,
                        plant_cmd=(sys.executable, "-m", "tools.evidence.margins.wire", *relay, "--"))
        load0 = os.getloadavg()[0]
        res = run_variant(cfg, variant, vdir, commands, str(scen_path), threading.Event())
        if realtime:
            row = {"mode": "realtime", "delay_ms": float(n), "ok": res.ok, "error": res.error,
                   "wall_s": res.wall_time_total_s,
                   "load_avg_1min": [round(load0, 2), round(os.getloadavg()[0], 2)]}
        else:
            row = {"delay_frames": int(n), "delay_ms": n * fdt * 1e3, "ok": res.ok,
                   "error": res.error, "wall_s": res.wall_time_total_s}
        if res.ok:
            fl = truth_flight(vdir, cmd, fdt)
            row["stable"] = stable(fl)
            row["diverged"] = fl.diverged
            tail = int(round(4.0 / fdt))
            row["tail_att_err_deg"] = np.degrees(np.abs(fl.att_rad[-tail:] - cmd)).max(0).tolist()
            row["tail_rate_rms_deg_s"] = np.degrees(np.std(fl.rate_rad_s[-tail:], axis=0)).tolist()
            if realtime:
                from tools.sitl.rundata import late_ticks_from_log
                row["late_ticks"] = late_ticks_from_log(vdir / "fc.log")
        rows.append(row)
        print(json.dumps(row), flush=True)
    (out / "wire.json").write_text(json.dumps(rows, indent=1))
    if realtime:
        lines = ["| extra delay ms (real time) | stable | tail attitude error a/b/m deg | "
                 "late ticks | load average (1 min) before / after | wall s |",
                 "|---|---|---|---|---|---|"]
    else:
        lines = ["| extra delay frames | ms | stable | tail attitude error a/b/m deg | wall s |",
                 "|---|---|---|---|---|"]
    for r in rows:
        err = "/".join(f"{v:.3f}" for v in r.get("tail_att_err_deg", [])) or r.get("error") or "-"
        if realtime:
            lines.append(f"| {r['delay_ms']:g} | {r.get('stable', '-')} | {err} | "
                         f"{r.get('late_ticks', '-')} | "
                         f"{' / '.join(str(x) for x in r['load_avg_1min'])} | {r['wall_s']:.1f} |")
        else:
            lines.append(f"| {r['delay_frames']} | {r['delay_ms']:.0f} | {r.get('stable', '-')} | "
                         f"{err} | {r['wall_s']:.1f} |")
    (out / "wire.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0 if all(r["ok"] for r in rows) else 1


def truth_flight(vdir: Path, cmd_rad: np.ndarray, frame_dt_s: float):
    """A tools.evidence.margins.flight.Flight from a run directory's plant truth log."""
    from plant_sim.truthlog import load
    from tools.evidence.margins.flight import Flight
    tr = load(str(Path(vdir) / "truth.npz"))
    att = np.column_stack([tr["alpha_rad"], tr["beta_rad"], tr["mu_rad"]])
    rate = np.column_stack([tr["p_rad_s"], tr["q_rad_s"], tr["r_rad_s"]])
    diverged = bool(np.any(~np.isfinite(att)) or np.any(np.abs(att) > np.radians(45.0)))
    z = np.zeros_like(att)
    return Flight(tr["t_s"], att, rate, z, z, cmd_rad, diverged, frame_dt_s)


if __name__ == "__main__":
    raise SystemExit(plant_with_relay())
