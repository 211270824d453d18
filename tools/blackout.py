"""``python -m tools.blackout``: scripted plant-link blackouts in CRUISE, one run per duration,
and what each cost (docs/reliability.md, issue 22).

Each run is the reliability rig (tools.sitl.rig: fc + clean relay + plant + ground station)
flying the cruise scenario in CRUISE. After ``--settle`` s of sim time the relay cuts the plant
link in both directions (``LinkImpair.set_blackout``) for the duration (wall seconds), then
restores it; the run goes on for ``--after`` s of sim time.

- real time: the plant flies on through the cut on its own no-command policy (the cruise
  scenario: hold the last command after 0.5 s); the fc hears nothing.
- lockstep: the plant waits for each answer by contract (docs/wire.md section 4), so a cut link
  freezes sim time: the blackout is a plant freeze seen from the fc (wall clock runs, sim time
  does not).

Figures per run (``blackout_figures``): the cut and the restore in sim time, FAILSAFE texts,
the modes flown, the largest |mu| and the alpha range from the cut to the end (a departure:
|mu| >= 10 deg or alpha outside [GE_ALPHA_MIN, GE_ALPHA_MAX]), the longest stretch with a
surface on its limit, the altitude and course away from the targets held before the cut, and
the recovery time: the first time after the restore from which the rig's ``STEADY_BOUNDS``
hold to the end (None if never). ``ok``: no departure, no surface on its limit > 0.5 s, back
within 30 s.

    python -m tools.blackout --mode realtime --durations 0.5 1 2 5 10 [--out DIR] [--seed 1]
    python -m tools.blackout --fault fc-stall --durations 3      # the fc's own stall instead
    python -m tools.blackout --analyse RUN_DIR ...               # figures of finished runs
    ... --markdown                      # also the table of docs/reliability.md (tables A, B)
"""
from __future__ import annotations

import argparse
import json
import math
import os
import signal
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from tools.sitl.metrics import SURFACE_LIMIT_DEG, wrap_rad
from tools.sitl.rig import Rig, RigConfig, STEADY_BOUNDS, steady_figures, steady_violations

DEG = math.pi / 180.0
#: a departure (issue 22): |mu| at or beyond this, deg
MU_DEPARTURE_DEG = 10.0
#: the envelope's alpha limits (GE_ALPHA_MIN / GE_ALPHA_MAX defaults), deg
ALPHA_ENVELOPE_DEG = (0.0, 10.0)
#: longest tolerated stretch with a surface on its limit, s
SURFACE_LIMIT_MAX_S = 0.5
#: the link must be back in the steady bounds within this after it returns, s
RECOVER_WITHIN_S = 30.0


def longest_run_s(flags: np.ndarray, t_s: np.ndarray) -> float:
    """The longest stretch of consecutive True samples, s (sample spacing from ``t_s``)."""
    if not flags.any():
        return 0.0
    dt = float(np.median(np.diff(t_s))) if len(t_s) > 1 else 0.0
    best = run = 0
    for f in flags:
        run = run + 1 if f else 0
        best = max(best, run)
    return best * dt


def recovery_time_s(truth: dict, internals: dict, t_restore_s: float, step_s: float = 0.5,
                    bounds: dict = STEADY_BOUNDS) -> float | None:
    """The first t >= t_restore_s (on a ``step_s`` grid) from which the steady bounds hold to the
    end of the run, minus t_restore_s; None if they never do (or less than 1 s is left)."""
    t_end = float(truth["t_s"][-1])
    t = t_restore_s
    while t < t_end - 1.0:
        if not steady_violations(steady_figures(truth, internals, t), bounds):
            return t - t_restore_s
        t += step_s
    return None


def blackout_figures(truth: dict, internals: dict, t_cut_s: float, t_restore_s: float) -> dict:
    """The figures of one blackout (module docstring); sim times in s, angles in deg."""
    tt = truth["t_s"]
    after = tt >= t_cut_s
    fi = internals["t_s"]
    before = np.nonzero(fi < t_cut_s)[0]
    i0 = int(before[-1]) if before.size else 0
    h_t = float(internals["guid_tgt_h_m"][i0])
    chi_t = float(internals["guid_tgt_chi_rad"][i0])
    mu = np.degrees(np.abs(truth["mu_rad"][after]))
    alpha = np.degrees(truth["alpha_rad"][after])
    d = np.stack([truth[k][after] for k in ("delta_left_rad", "delta_right_rad",
                                            "delta_rudder_rad")], 1)
    on_limit = np.any(np.abs(d) >= (SURFACE_LIMIT_DEG - 0.05) * DEG, 1)
    alt_err = truth["h_m"][after] - h_t
    modes = internals["mode"][fi >= t_cut_s - 1.0].astype(int)
    seq = [int(modes[0])] if modes.size else []
    for m in modes[1:]:
        if m != seq[-1]:
            seq.append(int(m))
    rec = recovery_time_s(truth, internals, t_restore_s)
    fs = internals["mode"] == 3
    fs_frames = np.unique(fi[fs]).size                  # plant frames answered in FAILSAFE
    fig = {
        "t_cut_s": round(t_cut_s, 3), "t_restore_s": round(t_restore_s, 3),
        "sim_time_cut_s": round(t_restore_s - t_cut_s, 3),
        "modes": seq,
        "mu_abs_max_deg": float(mu.max()),
        "alpha_range_deg": [float(alpha.min()), float(alpha.max())],
        "surface_on_limit_longest_s": longest_run_s(on_limit, tt[after]),
        "alt_from_target_before_cut_m": {"max": float(np.max(np.abs(alt_err))),
                                         "end": float(alt_err[-1])},
        "course_from_target_before_cut_deg": float(np.degrees(np.max(np.abs(
            wrap_rad(truth["chi_rad"][after] - chi_t))))),
        "target_alt_end_minus_before_m": float(internals["guid_tgt_h_m"][-1]) - h_t,
        "recovery_s": rec,
        "failsafe_frames": int(fs_frames),
        "failsafe_sim_s": float(fs_frames * np.median(np.diff(tt))),
    }
    departure = (fig["mu_abs_max_deg"] >= MU_DEPARTURE_DEG
                 or fig["alpha_range_deg"][0] < ALPHA_ENVELOPE_DEG[0]
                 or fig["alpha_range_deg"][1] > ALPHA_ENVELOPE_DEG[1])
    fig["departure"] = bool(departure)
    fig["ok"] = bool(not departure and fig["surface_on_limit_longest_s"] <= SURFACE_LIMIT_MAX_S
                     and rec is not None and rec <= RECOVER_WITHIN_S)
    return fig


def cut_and_restore(rig: Rig, settle_s: float, blackout_s: float,
                    fault: str = "link") -> tuple[float, float]:
    """Cut the plant link (both ways) once the plant reports ``settle_s`` of sim time, restore
    it ``blackout_s`` wall seconds later. Returns the plant's reported sim times (s) at the cut
    and at the restore (PROGRESS lines, every 0.25 s wall). ``fault="fc-stall"``: the fc
    process is stopped (SIGSTOP) instead, then continued (its own stall)."""
    if rig.wait_plant_time(settle_s, settle_s * 10 + 120) is None:
        raise RuntimeError(f"the plant did not reach t = {settle_s} s")
    if fault == "fc-stall":
        os.kill(rig.fc.pid, signal.SIGSTOP)
    else:
        rig.relay.set_blackout(True, "both")
    try:
        t_cut = rig.plant_time_now()
        t_end = time.monotonic() + blackout_s
        while time.monotonic() < t_end:
            rig.plant.wait_line(lambda s: False, min(0.05, max(0.0, t_end - time.monotonic())))
        t_restore = rig.plant_time_now()
    finally:
        if fault == "fc-stall":
            os.kill(rig.fc.pid, signal.SIGCONT)
        else:
            rig.relay.set_blackout(False, "both")
    return t_cut, t_restore


def cut_times_from_internals(internals: dict, t_cut_hint_s: float, mode: str) -> tuple[float,
                                                                                       float]:
    """The cut and restore in sim time from the fc's own log: in real time the stamp of the
    last frame before the longest wall gap between new stamps after the hint, and the first
    after it; in lockstep (sim time frozen) the same instant for both."""
    t = internals["t_s"]
    w = internals["wall_s"]
    new = np.nonzero(np.diff(t) > 0)[0] + 1
    new = new[t[new] >= t_cut_hint_s - 1.0]
    if new.size < 2:
        return t_cut_hint_s, t_cut_hint_s
    gaps = np.diff(w[new])
    k = int(np.argmax(gaps))
    t0, t1 = float(t[new[k]]), float(t[new[k + 1]])
    return (t0, t1) if mode == "realtime" else (t0, t0)


def one_run(out: Path, mode: str, blackout_s: float, settle_s: float, after_s: float,
            seed: int, fault: str = "link", scenario: str = "cruise") -> dict:
    sim_s = settle_s + after_s + (blackout_s if mode == "realtime" else 0.0) + 1.0
    cfg = RigConfig(out=out, duration_s=sim_s, seed=seed, mode=mode, scenario=scenario,
                    arm="start" if mode == "lockstep" else "gcs")
    with Rig(cfg) as rig:
        rig.start()
        hint, _ = cut_and_restore(rig, settle_s, blackout_s, fault)
        rcs = rig.finish()
        texts = [t for _, _, t in rig.gcs.texts]
        truth, internals = rig.truth(), rig.internals()
    t_cut, t_restore = cut_times_from_internals(internals, hint, mode)
    fig = {"mode": mode, "fault": fault, "blackout_wall_s": blackout_s, "exit_codes": rcs,
           **blackout_figures(truth, internals, t_cut, t_restore),
           "texts": [t for t in texts if "FAILSAFE" in t or "plant" in t or "stall" in t]}
    return fig


MODE_NAMES = {3: "FS", 4: "CRUISE", 5: "GUIDED"}
TABLE_HEAD = ("| blackout (wall) | plant time cut, s | modes | max abs mu, deg | alpha, deg | "
              "longest surface on limit, s | altitude from the target before the cut, max / "
              "end, m | frames answered in FAILSAFE | back in the steady bounds after | ok |\n"
              "|---|---|---|---|---|---|---|---|---|---|")


def markdown_table(runs: list[dict]) -> str:
    """The runs' figures as the table of docs/reliability.md (tables A and B), one row per
    run (``blackout_wall_s`` from the run, or from its directory's name)."""
    lines = [TABLE_HEAD]
    for r in runs:
        wall = r.get("blackout_wall_s")
        if wall is None:
            wall = float(Path(r["run"]).name.rsplit("-", 1)[-1].rstrip("s"))
        modes = " ".join(MODE_NAMES.get(m, str(m)) for m in r["modes"])
        a0, a1 = r["alpha_range_deg"]
        alt = r["alt_from_target_before_cut_m"]
        rec = "never" if r["recovery_s"] is None else f"{r['recovery_s']:.1f} s"
        lines.append(f"| {wall:g} s | {r['sim_time_cut_s']:.2f} | {modes} | "
                     f"{r['mu_abs_max_deg']:.1f} | {a0:.1f}..{a1:.1f} | "
                     f"{r['surface_on_limit_longest_s']:.2f} | {alt['max']:.0f} / {alt['end']:.0f} | "
                     f"{r['failsafe_frames']} | {rec} | {'yes' if r['ok'] else '**no**'} |")
    return "\n".join(lines)


def analyse(run_dir: Path, settle_s: float) -> dict:
    """The figures of a finished run (its directory, as ``one_run`` left it), the cut found
    from the fc's log after ``settle_s``."""
    from fc.internals_log import load as load_internals
    from plant_sim.truthlog import load as load_truth
    truth = load_truth(str(run_dir / "plant" / "truth.npz"))
    internals = load_internals(str(run_dir / "fc" / "fc_internals.npz"))
    mode = "lockstep" if "lockstep" in run_dir.name else "realtime"
    t_cut, t_restore = cut_times_from_internals(internals, settle_s, mode)
    return {"run": str(run_dir), "mode": mode,
            **blackout_figures(truth, internals, t_cut, t_restore)}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m tools.blackout",
                                 description="Plant-link blackouts in CRUISE (cruise scenario), "
                                             "one run per duration; prints the figures as JSON.")
    ap.add_argument("--mode", choices=("realtime", "lockstep"), default="realtime",
                    help="both processes' timing mode; in lockstep a cut link freezes sim "
                         "time (realtime)")
    ap.add_argument("--durations", type=float, nargs="+", default=[0.5, 1.0, 2.0, 5.0, 10.0],
                    help="blackout lengths, wall seconds (0.5 1 2 5 10)")
    ap.add_argument("--settle", type=float, default=12.0,
                    help="sim seconds flown before the cut (12)")
    ap.add_argument("--after", type=float, default=40.0,
                    help="sim seconds flown after the link is back (40)")
    ap.add_argument("--seed", type=int, default=1, help="seed of the plant (1)")
    ap.add_argument("--fault", choices=("link", "fc-stall"), default="link",
                    help="link: the plant link cut both ways (default); fc-stall: the fc "
                         "process stopped (SIGSTOP) for the duration")
    ap.add_argument("--scenario", default="cruise",
                    help="plant scenario, a name or a TOML path (cruise; e.g. a copy with the "
                         "servo table's backup_* gains at 0: the hold without its damper)")
    ap.add_argument("--out", help="run directory (default: a new temp directory)")
    ap.add_argument("--analyse", nargs="+", metavar="RUN_DIR",
                    help="no run: the figures of finished runs (their directories)")
    ap.add_argument("--markdown", action="store_true",
                    help="after the JSON, the runs as the table of docs/reliability.md")
    args = ap.parse_args(argv)
    if args.analyse:
        runs = [analyse(Path(d), args.settle) for d in args.analyse]
        print(json.dumps(runs, indent=2))
        if args.markdown:
            print(markdown_table(runs))
        return 0
    out = Path(args.out or tempfile.mkdtemp(prefix="hyfc-blackout-"))
    results = []
    for d in args.durations:
        fig = one_run(out / f"{args.mode}-{args.fault}-{d:g}s", args.mode, d, args.settle,
                      args.after, args.seed, args.fault, args.scenario)
        print(json.dumps(fig), file=sys.stderr, flush=True)
        results.append(fig)
    print(json.dumps({"out": str(out), "runs": results}, indent=2))
    if args.markdown:
        print(markdown_table(results))
    return 0 if all(r["exit_codes"]["plant"] == 0 and r["exit_codes"]["fc"] == 0
                    for r in results) else 1


if __name__ == "__main__":
    raise SystemExit(main())
