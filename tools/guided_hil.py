"""Guided flight over the wire: figures of a tools.hil run in a guidance mode, and guided steps
sent from a ground station mid-flight.

    # hold figures of a run (altitude, course, speed against the fc's targets, inner loop,
    # surfaces, adaptive estimates, limits), after the transient; on the round Earth in CRUISE
    # also the course error to the great circle held, measured without north
    # (course_err_circle_max_deg, tools.sitl.metrics.circle_course_error_rad)
    python -m tools.guided_hil figures RUN_DIR/coordinated --from 300

    # a lockstep GUIDED flight of the cruise scenario (tools.hil, two processes over UDP) with
    # the scripted ground station (tools/sitl/gcs.py) sending +2 km altitude, +30 deg
    # heading, +100 m/s in turn
    python -m tools.guided_hil steps --out DIR [--at 100 600 1100] [--duration 1600]

The fc logs its targets (fc_internals.npz ``guid_tgt_*``), so the figures need nothing else
than the run directory: the plant's truth.npz and the fc's internals (docs/guidance.md).
"""
from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from fc.guidance.guidance import limit_names
from tools.sitl.metrics import DEG, SURFACE_LIMIT_DEG, hold_figures, targets_at, wrap_rad  # noqa: F401

STEPS = (("alt", 43001, lambda h, chi, v: (h + 2000.0,), 50.0, "+2 km altitude"),
         ("course", 43002, lambda h, chi, v: (0, math.degrees(chi) + 30.0), 0.5, "+30 deg heading"),
         ("speed", 43000, lambda h, chi, v: (0, v + 100.0), 5.0, "+100 m/s"))


def load_run(vdir: Path) -> tuple[dict, dict]:
    """(truth columns, fc internals columns) of one variant directory."""
    from fc.internals_log import load
    z = np.load(Path(vdir) / "truth.npz")
    names = ("t_s", "h_m", "V_m_s", "chi_rad", "alpha_rad", "beta_rad", "mu_rad", "gamma_rad",
             "qbar_pa", "delta_left_rad", "delta_right_rad", "delta_rudder_rad", "thrust_N",
             "pos_n_m", "pos_e_m")
    truth = {n: z[n] for n in names}
    fc = load(str(vdir))
    return truth, fc


def step_figures(truth: dict, fc: dict, channel: str, t_step_s: float, band: float,
                 t_end_s: float) -> dict:
    """Response to the target change at ``t_step_s`` (the fc's target log): settling time (last
    entry into +-band, s), overshoot past the target, the envelope quantities' peaks and the
    limits in force until ``t_end_s``."""
    sel = (truth["t_s"] >= t_step_s) & (truth["t_s"] < t_end_s)
    t = truth["t_s"][sel]
    tg = targets_at(truth, fc)[sel]
    if channel == "alt":
        err, r0 = truth["h_m"][sel] - tg[:, 0], truth["h_m"][sel][0] - tg[-1, 0]
    elif channel == "speed":
        err, r0 = truth["V_m_s"][sel] - tg[:, 2], truth["V_m_s"][sel][0] - tg[-1, 2]
    else:
        err = np.degrees(wrap_rad(truth["chi_rad"][sel] - tg[:, 1]))
        r0 = err[0]
    out_band = np.nonzero(np.abs(err) > band)[0]
    settled = (0.0 if len(out_band) == 0 else
               float(t[out_band[-1] + 1] - t_step_s) if out_band[-1] + 1 < len(t) else None)
    direction = -np.sign(r0) if r0 else 1.0
    g = 9.72
    gam = truth["gamma_rad"][sel]
    nz = (truth["V_m_s"][sel] * np.gradient(gam, t) + g * np.cos(gam)) / (
        g * np.cos(truth["mu_rad"][sel]))
    nz_f = np.convolve(nz, np.ones(50) / 50, mode="valid")      # 0.1 s mean: no noise peaks
    fsel = (fc["t_s"] >= t_step_s) & (fc["t_s"] < t_end_s)
    bits = np.bitwise_or.reduce(fc["guid_limits"][fsel].astype(np.int64))
    d = np.stack([truth[k][sel] for k in ("delta_left_rad", "delta_right_rad",
                                          "delta_rudder_rad")], 1)
    return {"channel": channel, "t_step_s": round(t_step_s, 3), "settling_s": settled,
            "overshoot": float(max(0.0, np.max(direction * err))),
            "final_err": float(err[-1]),
            "alpha_min_max_deg": [float(np.degrees(truth["alpha_rad"][sel].min())),
                                  float(np.degrees(truth["alpha_rad"][sel].max()))],
            "mu_abs_max_deg": float(np.degrees(np.abs(truth["mu_rad"][sel]).max())),
            "gamma_abs_max_deg": float(np.degrees(np.abs(gam).max())),
            "nz_min_max": [float(nz_f.min()), float(nz_f.max())],
            "qbar_min_max_kpa": [float(truth["qbar_pa"][sel].min() / 1e3),
                                 float(truth["qbar_pa"][sel].max() / 1e3)],
            "surface_peak_deg": float(np.degrees(np.abs(d).max())),
            "limits_seen": limit_names(int(bits))}


def _drive_steps(port: int, at_s: list[float], log) -> list[dict]:
    """The ground station (tools.sitl.gcs.ScriptedGcs on ``port``, where the fc sends): wait
    for the fc's sim time (DEBUG_VECT SIM_T) to reach each ``at_s`` and send the step as
    COMMAND_LONG; returns the acks."""
    from tools.sitl.gcs import ScriptedGcs
    gcs = ScriptedGcs(port=port)
    sim_t = -1.0
    h = chi = v = None
    acks = []
    deadline = time.monotonic() + 3600.0
    try:
        for (channel, cmd, params, band, label), t_at in zip(STEPS, at_s):
            while sim_t < t_at and time.monotonic() < deadline:
                m = gcs.wait(("DEBUG_VECT", "VFR_HUD", "NAV_CONTROLLER_OUTPUT"), 1.0)
                if m is None:
                    continue
                if m.get_type() == "DEBUG_VECT" and m.name == "SIM_T" and math.isfinite(m.x):
                    sim_t = m.x
                elif m.get_type() == "VFR_HUD":
                    h, v = m.alt, m.airspeed
                elif m.get_type() == "NAV_CONTROLLER_OUTPUT":
                    chi = math.radians(m.nav_bearing)
            p = list(params(h, chi, v)) + [0.0] * 7
            ack = gcs.command(cmd, *p[:7], timeout_s=10.0)
            acks.append({"label": label, "sim_t_s": sim_t, "params": p[:2],
                         "result": None if ack is None else ack.result})
            log(f"guided_hil: t={sim_t:.2f} s {label} {p[:2]} -> ack "
                f"{None if ack is None else ack.result}")
    finally:
        gcs.close()
    return acks


def run_steps(out: Path, at_s: list[float], duration_s: float, seed: int, variant: str) -> dict:
    from tools.sitl.procs import free_udp_port
    port = free_udp_port()
    cmd = [sys.executable, "-m", "tools.hil", "run", "--scenario", "cruise", "--flight-mode",
           "GUIDED", "--variant", variant, "--duration", repr(duration_s), "--seed", str(seed),
           "--out", str(out), "--gcs-out", f"127.0.0.1:{port}", "--no-plots", "--quiet"]
    proc = subprocess.Popen(cmd)
    try:
        acks = _drive_steps(port, at_s, lambda s: print(s, flush=True))
        rc = proc.wait(timeout=3600)
    finally:
        if proc.poll() is None:
            proc.terminate()
            proc.wait(timeout=30)
    truth, fc = load_run(out / variant)
    ends = list(at_s[1:]) + [duration_s]
    figs = []
    for (channel, _c, _p, band, label), ack, t_end in zip(STEPS, acks, ends):
        # the fc's own record of when the target changed (sim time)
        col = {"alt": "guid_tgt_h_m", "course": "guid_tgt_chi_rad", "speed": "guid_tgt_V_m_s"}
        v = fc[col[channel]]
        ch = np.nonzero((np.diff(v) != 0) & (fc["t_s"][1:] > ack["sim_t_s"] - 5.0))[0]
        t_step = float(fc["t_s"][ch[0] + 1]) if len(ch) else ack["sim_t_s"]
        f = step_figures(truth, fc, channel, t_step, band, t_end)
        f.update(label=label, band=band, ack=ack["result"])
        figs.append(f)
    return {"rc": rc, "acks": acks, "steps": figs}


def sphere_origin(vdir: Path) -> tuple[float, float] | None:
    """(lat, lon) deg of the GNSS origin of a round-Earth run (the scenario copy tools.hil
    keeps beside the variant directory), None on the flat earth or without the copy."""
    from plant_sim.scenario import ScenarioError, load
    for path in (Path(vdir) / "scenario.toml", Path(vdir).parent / "scenario.toml"):
        if path.is_file():
            try:
                d = load(path).data
            except ScenarioError:
                return None
            if d["earth"]["model"] != "sphere":
                return None
            return d["gnss"]["origin_lat_deg"], d["gnss"]["origin_lon_deg"]
    return None


def _print(d):
    print(json.dumps(d, indent=1))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    f = sub.add_parser("figures", help="hold figures of a variant directory")
    f.add_argument("vdir", type=Path, help="a variant directory of a tools.hil run "
                   "(RUN_DIR/coordinated) flown in a guidance mode")
    f.add_argument("--from", dest="t_from", type=float, default=300.0,
                   help="figures from this sim time on (s, default 300: after the transient)")
    s = sub.add_parser("steps", help="guided steps from a ground station, lockstep over UDP")
    s.add_argument("--out", type=Path, required=True, help="run directory to write (tools.hil)")
    s.add_argument("--at", type=float, nargs=3, default=[100.0, 600.0, 1100.0],
                   help="sim times of the altitude, heading and speed steps (s)")
    s.add_argument("--duration", type=float, default=1600.0, help="sim time to fly, s (1600)")
    s.add_argument("--seed", type=int, default=0, help="random seed of the plant (0)")
    s.add_argument("--variant", choices=("coordinated", "uncoordinated"), default="coordinated",
                   help="the inner law (GUID_INNER_CO), default coordinated")
    a = ap.parse_args(argv)
    if a.cmd == "figures":
        truth, fc = load_run(a.vdir)
        _print(hold_figures(truth, fc, a.t_from, sphere_origin(a.vdir)))
        return 0
    _print(run_steps(a.out, a.at, a.duration, a.seed, a.variant))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
