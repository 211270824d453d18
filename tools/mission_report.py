"""tools/mission_report.py - figures and a picture of a mission flown by tools.hil (MISSION).

Reads one variant directory of a run (``tools.hil run --flight-mode MISSION``): the plant's
truth (truth.npz), the fc's internals (fc_internals.npz: the guidance's targets and the law's
commands), the fc's sim-paced .tlog (MISSION_ITEM_REACHED and the GNSS position at each) and
the mission file (QGC WPL 110). Prints, per waypoint, the sim time it was reached, where (the
along-track distance still to go and the cross-track error of the leg, from the GNSS
position), and the tracking errors of the flight in MISSION: altitude, course and speed
against the guidance's targets, alpha/beta/mu against the law's commands. ``--plot PNG``
draws altitude, course, speed, the ground track and alpha/beta/mu against their commands.
The errors cover the fc's internals rows in MISSION while armed. The times of the .tlog are the
fc's time base: sim time in lockstep, the fc's uptime in real time.

    python -m tools.mission_report runs/X/coordinated --mission plant_sim/scenarios/mission.waypoints \
        --plot docs/img/mission_flight.png
"""
from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

from fc.guidance.waypoints import leg_geometry, local_ne
from fc.modes import FlightMode
from tools.sitl.gcs import read_wpl

CMD_WAYPOINT = 16


def reached_events(tlog: Path) -> list[tuple[int, float, float, float]]:
    """(seq, sim time s, lat, lon deg) of each MISSION_ITEM_REACHED in the .tlog, at the last
    GLOBAL_POSITION_INT before it (time_boot_ms: sim time in lockstep)."""
    from pymavlink import mavutil
    conn = mavutil.mavlink_connection(str(tlog), dialect="ardupilotmega")
    pos, out = None, []
    while True:
        m = conn.recv_match(type=["GLOBAL_POSITION_INT", "MISSION_ITEM_REACHED"])
        if m is None:
            return out
        if m.get_type() == "GLOBAL_POSITION_INT":
            pos = (m.time_boot_ms * 1e-3, m.lat * 1e-7, m.lon * 1e-7)
        elif pos is not None:
            out.append((m.seq, *pos))


def analyse(vdir: Path, mission_file: Path, home: tuple[float, float]) -> dict:
    """The figures of one variant directory (see the module docstring)."""
    items = read_wpl(mission_file)
    tr = np.load(vdir / "truth.npz")
    il = np.load(vdir / "fc_internals.npz")
    ev = reached_events(vdir / "fc.tlog")
    wps = [s for s, it in enumerate(items) if it["command"] == CMD_WAYPOINT]
    ne = {s: local_ne(items[s]["x"] * 1e-7, items[s]["y"] * 1e-7, *home) for s in wps}
    rows = []
    prev = None
    for seq, t, lat, lon in ev:
        if seq not in ne:
            rows.append({"seq": seq, "t_s": round(t, 2), "command": items[seq]["command"]})
            continue
        x = local_ne(lat, lon, *home)
        start = prev if prev is not None else (0.0, 0.0)
        _, e, to_go, dist = leg_geometry(start, ne[seq], x)
        rows.append({"seq": seq, "t_s": round(t, 2), "command": CMD_WAYPOINT,
                     "to_go_km": round(to_go / 1000, 2), "xtrack_m": round(e, 0),
                     "dist_km": round(dist / 1000, 2)})
        prev = ne[seq]
    in_mission = (il["mode"] == int(FlightMode.MISSION)) & (il["armed"] > 0.5)
    t = il["t_s"][in_mission]
    out = {"waypoints": rows, "items": len(items), "reached": len(ev),
           "mission_s": [float(t[0]), float(t[-1])] if t.size else None}
    if t.size:
        tt = tr["t_s"]

        def truth(name):
            return np.interp(t, tt, tr[name])
        err = {
            "alt_m": truth("h_m") - il["guid_tgt_h_m"][in_mission],
            "course_deg": np.degrees((truth("chi_rad") - il["guid_tgt_chi_rad"][in_mission]
                                      + math.pi) % (2 * math.pi) - math.pi),
            "speed_m_s": truth("V_m_s") - il["guid_tgt_V_m_s"][in_mission],
        }
        for a in ("alpha", "beta", "mu"):
            err[f"{a}_deg"] = np.degrees(truth(f"{a}_rad") - il[f"cmd_{a}_rad"][in_mission])
        out["errors"] = {k: {"rms": round(float(np.sqrt(np.mean(v * v))), 3),
                             "max_abs": round(float(np.max(np.abs(v))), 3)}
                         for k, v in err.items()}
        lim = math.radians(20.0)
        out["surface_max_deg"] = round(math.degrees(max(
            float(np.max(np.abs(tr[c]))) for c in ("delta_left_rad", "delta_right_rad",
                                                  "delta_rudder_rad"))), 2)
        out["surface_at_limit"] = bool(out["surface_max_deg"] >= math.degrees(lim) - 0.05)
    return out


def _deg180(a_rad):
    """Angles in degrees wrapped to [-180, 180)."""
    return (np.degrees(a_rad) + 180.0) % 360.0 - 180.0


def plot(vdir: Path, mission_file: Path, home: tuple[float, float], path: Path,
         title: str) -> Path:
    """altitude, course, speed against the guidance's targets; the ground track with the
    waypoints; alpha, beta, mu against the law's commands; the surfaces."""
    from tools.sitl.plots import CMD_STYLE, R2D, SURFACE_LABELS, _finish_axis, _save, plt
    items = read_wpl(mission_file)
    tr = np.load(vdir / "truth.npz")
    il = np.load(vdir / "fc_internals.npz")
    k = max(1, len(il["t_s"]) // 20000)                   # about 20 000 points per line
    t, tt = il["t_s"][::k], tr["t_s"]
    kt = max(1, len(tt) // 20000)
    guided = il["mode"][::k] >= int(FlightMode.CRUISE)

    def tgt(name, scale=1.0):
        return np.where(guided, il[name][::k] * scale, np.nan)
    line = dict(color="tab:blue", linewidth=1.3)
    fig, ax = plt.subplots(4, 2, figsize=(13, 11))
    sub = tr["t_s"][::kt]
    ev = reached_events(vdir / "fc.tlog")
    rows = ((ax[0, 0], tr["h_m"][::kt] / 1000.0,
             tgt("guid_tgt_h_m", 1e-3), "altitude [km]"),
            (ax[1, 0], _deg180(tr["chi_rad"][::kt]),
             _deg180(tgt("guid_tgt_chi_rad")), "course [deg]"),
            (ax[2, 0], tr["V_m_s"][::kt], tgt("guid_tgt_V_m_s"),
             "speed [m/s]"))
    for a, y, target, lab in rows:
        a.plot(sub, y, label="flown (truth)", **line)
        a.plot(t, target, label="guidance target", **CMD_STYLE)
        for seq, ts, _, _ in ev:
            a.axvline(ts, color="grey", linewidth=0.6, alpha=0.6)
        _finish_axis(a, lab)
    ax[2, 0].set_xlabel("time [s] (grey: MISSION_ITEM_REACHED)")
    g = ax[3, 0]
    g.plot(tr["pos_e_m"][::max(1, len(tt) // 5000)] / 1000.0,
           tr["pos_n_m"][::max(1, len(tt) // 5000)] / 1000.0, label="track (truth)", **line)
    wps = [local_ne(it["x"] * 1e-7, it["y"] * 1e-7, *home) for it in items
           if it["command"] == CMD_WAYPOINT]
    g.plot([w[1] / 1000.0 for w in wps], [w[0] / 1000.0 for w in wps], "k:o", markersize=4,
           linewidth=0.9, label="waypoints")
    g.set_xlabel("east [km]")
    g.set_aspect("equal", adjustable="datalim")
    _finish_axis(g, "north [km]")
    for i, a in enumerate(("alpha", "beta", "mu")):
        x = ax[i, 1]
        x.plot(sub, tr[f"{a}_rad"][::kt] * R2D,
               label="flown (truth)", **line)
        x.plot(t, il[f"cmd_{a}_rad"][::k] * R2D, label="command", **CMD_STYLE)
        _finish_axis(x, f"{a} [deg]")
    s = ax[3, 1]
    for j, lab in enumerate(SURFACE_LABELS):
        c = ("delta_left_rad", "delta_right_rad", "delta_rudder_rad")[j]
        s.plot(sub, tr[c][::kt] * R2D, linewidth=1.0, label=lab)
    for sgn in (1, -1):
        s.axhline(sgn * 20.0, color="grey", linestyle="--", linewidth=0.8)
    s.set_xlabel("time [s]")
    _finish_axis(s, "surfaces [deg]")
    fig.suptitle(title, fontsize=11)
    fig.tight_layout()
    return _save(fig, path)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m tools.mission_report", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("variant_dir", type=Path, help="RUN_DIR/coordinated (or uncoordinated)")
    ap.add_argument("--mission", type=Path, default=None,
                    help="mission file (default: the run's, from RUN_DIR/run.json)")
    ap.add_argument("--home", type=float, nargs=2, default=(34.9054, -117.8839),
                    metavar=("LAT", "LON"), help="home (the scenario's GNSS origin), deg")
    ap.add_argument("--plot", type=Path, default=None, metavar="PNG",
                    help="write the picture (altitude, course, speed, track, alpha/beta/mu)")
    ap.add_argument("--json", action="store_true", help="print the figures as JSON")
    a = ap.parse_args(argv)
    meta_path = a.variant_dir.parent / "run.json"
    meta = json.loads(meta_path.read_text()) if meta_path.is_file() else {}
    mission = a.mission or (Path(meta["mission_file"]) if meta.get("mission_file") else None)
    if mission is None or not mission.is_file():
        print("tools.mission_report: no mission file (give --mission FILE)", file=sys.stderr)
        return 2
    home = tuple(a.home)
    res = analyse(a.variant_dir, mission, home)
    if a.json:
        print(json.dumps(res, indent=1))
    else:
        print(f"mission {mission}: {res['reached']} of {res['items']} items reached; "
              f"MISSION from {res['mission_s'][0]:.1f} to {res['mission_s'][1]:.1f} s")
        for r in res["waypoints"]:
            if r["command"] == CMD_WAYPOINT:
                print(f"  item {r['seq']}: t {r['t_s']:8.2f} s  to go {r['to_go_km']:7.2f} km  "
                      f"cross-track {r['xtrack_m']:7.0f} m")
            else:
                print(f"  item {r['seq']}: t {r['t_s']:8.2f} s  (command {r['command']})")
        for k, v in res.get("errors", {}).items():
            print(f"  error {k:11s} rms {v['rms']:9.3f}  max {v['max_abs']:9.3f}")
        print(f"  surfaces: max {res.get('surface_max_deg')} deg, at limit "
              f"{res.get('surface_at_limit')}")
    if a.plot is not None:
        title = (f"mission flight: {mission.name}, scenario '{meta.get('scenario', '?')}', "
                 f"{meta.get('mode', '?')}, {a.variant_dir.name} law, seed {meta.get('seed', '?')}")
        print(f"wrote {plot(a.variant_dir, mission, home, a.plot, title)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
