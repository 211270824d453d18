"""tools/envelope.py - the paper's fixed gains across the flight envelope (issue 15, point 5).

A grid of flight conditions (Mach x altitude) across the winged-cone's hypersonic corridor;
at each point inside the dynamic-pressure corridor the paper's case is flown with the paper's
fixed gains: the scenario ``paper`` (its +-20 % uncertainty, its disturbance, its steps alpha
1 -> 5, beta 5 -> 0, mu 0 -> 4 deg) with the initial speed and altitude of the point, the
surfaces starting at the plant's moment trim of the initial state (``actuators.initial =
"trim"``). Each point is first trimmed with ``plant_sim.trim.trim_at`` at the initial state and
at the commanded one (alpha 5, beta 0 deg): a point whose commanded state cannot be trimmed
within the surface limits is reported as such. Variants: uncoordinated, and coordinated with
the factors of Eq. 14 and of Eq. 19 (readings set explicitly, tools.coordination.READINGS).
The law sees the plant's truth (as tools.sitl.closed_loop's paper-case figures). Each point is one
Dask task (LocalCluster, ``--workers``; 0 = in this process).

    python -m tools.envelope --out runs/env                 # the full grid
    python -m tools.envelope --quick --out runs/env_quick   # 2 x 2 points, a smoke test
    python -m tools.envelope --out runs/env --plots-only --img docs/img   # pictures again

Writes ``points.csv`` (one row per point and variant), ``envelope.json`` (grid, corridor,
wall time) and heat maps (PNG) of overshoot, settling, saturation and divergence, and of
coordination's effect (coordinated minus uncoordinated).
"""
from __future__ import annotations

import argparse
import copy
import json
import math
import time
from pathlib import Path

import numpy as np

GAMMA_AIR = 1.4
#: the dynamic-pressure corridor flown, Pa: it contains the paper's point (183 kPa at Mach 7.4,
#: 21 km) and the classic air-breathing band (24-96 kPa, 500-2000 psf)
Q_MIN_PA = 10e3
Q_MAX_PA = 300e3
#: the paper's spec of the campaigns (tools/dispersions/paper.toml [spec])
SPEC_OS_PCT = 10.0
SPEC_TS_S = 5.0
VARIANTS = {"unco": (False, "eq14"), "co_eq14": (True, "eq14"), "co_eq19": (True, "eq19")}


def flight_condition(mach: float, h_m: float) -> tuple[float, float]:
    """(airspeed m/s, dynamic pressure Pa) at ``mach`` and ``h_m`` (US76)."""
    from plant_sim.atmosphere import us76
    o = np.zeros(8)
    us76(float(h_m), o)
    p_pa, a_m_s = o[1], o[3]
    return mach * a_m_s, 0.5 * GAMMA_AIR * p_pa * mach * mach


def point_scenario(mach: float, h_m: float, base: str = "paper"):
    """The paper's scenario flown at (mach, h_m), surfaces starting at the initial trim."""
    from plant_sim.scenario import Scenario, load, parse
    sc = load(base)
    d = copy.deepcopy(sc.data)
    v, _ = flight_condition(mach, h_m)
    d["initial"]["V_m_s"] = float(v)
    d["initial"]["h_m"] = float(h_m)
    d["actuators"]["initial"] = "trim"
    ed = Scenario(name=f"{sc.name}-M{mach:g}-h{h_m / 1e3:g}km", path=sc.path, data=d,
                  commands=list(sc.commands))
    return parse(ed.to_toml(), src=f"{sc.path} (envelope point)", name=ed.name)


def trim_point(sc) -> dict:
    """Moment trim at the initial state and at the commanded one (deg, flags)."""
    from plant_sim.trim import trim_at
    ini = sc.data["initial"]
    _, a_c, b_c, _ = sc.commands[0]
    out = {}
    for tag, a, b in (("ini", ini["alpha_deg"], ini["beta_deg"]), ("cmd", a_c, b_c)):
        tr = trim_at(sc, math.radians(a), math.radians(b))
        out[f"trim_{tag}_ok"] = bool(tr.trimmed)
        out[f"trim_{tag}_max_deg"] = float(np.degrees(np.max(np.abs(tr.deflection_rad))))
    return out


def fly_point(mach: float, h_m: float, duration_s: float = 20.0, variants=tuple(VARIANTS)) -> list:
    """The Dask task: trim one point and fly each variant; one row per variant."""
    from tools.sitl.closed_loop import simulate
    from tools.coordination import READINGS, run_metrics
    v, q = flight_condition(mach, h_m)
    base = {"mach": float(mach), "h_km": h_m / 1e3, "V_m_s": v, "qbar_kPa": q / 1e3}
    try:
        sc = point_scenario(mach, h_m)
        base.update(trim_point(sc))
    except Exception as exc:  # noqa: BLE001 - a point that cannot be set up is a result
        return [{**base, "variant": var, "error": f"{type(exc).__name__}: {exc}",
                 "diverged": True} for var in variants]
    rows = []
    for var in variants:
        co, reading = VARIANTS[var]
        ov = dict(READINGS[reading])
        t0 = time.perf_counter()
        try:
            res = simulate(sc, coordinated=co, duration_s=duration_s, law_overrides=ov,
                           command_shaping="steps", estimate="truth")
            row = {**base, "variant": var, "error": ""}
            row.update(run_metrics(res))
        except Exception as exc:  # noqa: BLE001
            row = {**base, "variant": var, "error": f"{type(exc).__name__}: {exc}",
                   "diverged": True}
        row["wall_s"] = time.perf_counter() - t0
        rows.append(row)
    return rows


def grid(quick: bool = False):
    """(Mach values, altitudes m) of the campaign."""
    if quick:
        return np.array([7.0, 10.0]), np.array([22e3, 30e3])
    return np.arange(6.0, 15.01, 0.5), np.arange(20e3, 40.01e3, 1e3)


def run(out: Path, quick: bool = False, workers: int = 2, duration_s: float = 20.0) -> list:
    machs, hs = grid(quick)
    pts = [(float(m), float(h)) for h in hs for m in machs
           if Q_MIN_PA <= flight_condition(m, h)[1] <= Q_MAX_PA]
    t0 = time.perf_counter()
    rows: list = []
    if workers <= 0:
        for m, h in pts:
            rows += fly_point(m, h, duration_s)
    else:
        from distributed import as_completed
        from tools.montecarlo.campaign import cluster_client
        with cluster_client(workers) as client:
            futs = [client.submit(fly_point, m, h, duration_s, pure=False) for m, h in pts]
            for fut in as_completed(futs):
                rows += fut.result()
    wall = time.perf_counter() - t0
    out.mkdir(parents=True, exist_ok=True)
    from tools.coordination import write_rows
    write_rows(out / "points.csv", rows)
    info = {"mach": machs.tolist(), "h_m": hs.tolist(), "points": len(pts), "runs": len(rows),
            "q_corridor_Pa": [Q_MIN_PA, Q_MAX_PA], "workers": workers, "wall_s": wall,
            "duration_s": duration_s}
    (out / "envelope.json").write_text(json.dumps(info, indent=1))
    print(f"envelope: {len(pts)} points, {len(rows)} runs, {wall:.0f} s wall, {workers} workers")
    return rows


def read_points(path: Path) -> list[dict]:
    from tools.coordination import read_csv_rows
    return read_csv_rows(path, ("variant", "error"))


def _worst(r: dict, key: str) -> float:
    """Worst channel of ``key`` (os_pct, ts_s); a channel that never settles is inf."""
    vals = []
    for ch in ("alpha", "beta", "mu"):
        v = r.get(f"{ch}_{key}", math.nan)
        if key == "ts_s" and not (isinstance(v, float) and math.isfinite(v)):
            v = math.inf
        vals.append(v)
    return float(np.nanmax(vals))


def meets_spec(r: dict) -> bool:
    """Not diverged, every channel overshoots <= 10 % and settles within 5 s (paper spec)."""
    return (not r.get("diverged")) and not r.get("error") and \
        _worst(r, "os_pct") <= SPEC_OS_PCT and _worst(r, "ts_s") <= SPEC_TS_S


def maps(rows: list[dict], machs, hs) -> dict:
    """{(variant, figure): 2-D array [h, mach]} with NaN outside the corridor."""
    idx_m = {round(m, 6): i for i, m in enumerate(machs)}
    idx_h = {round(h / 1e3, 6): j for j, h in enumerate(hs)}
    out = {}
    for r in rows:
        i, j = idx_m.get(round(r["mach"], 6)), idx_h.get(round(r["h_km"], 6))
        if i is None or j is None:
            continue
        div = bool(r.get("diverged")) or bool(r.get("error"))
        figs = {"os": math.nan if div else _worst(r, "os_pct"),
                "ts": math.nan if div else _worst(r, "ts_s"),
                "sat": r.get("sat_s", math.nan), "div": 1.0 if div else 0.0,
                "spec": 1.0 if meets_spec(r) else 0.0,
                "trim": (1.0 if r.get("trim_cmd_ok") else 0.0)}
        for k, v in figs.items():
            a = out.setdefault((r["variant"], k), np.full((len(hs), len(machs)), np.nan))
            a[j, i] = v
    return out


def plot(rows: list[dict], machs, hs, img_dir: Path, prefix: str = "envelope") -> list[Path]:
    """Heat maps: per figure (overshoot, settling, saturation, divergence + spec) one PNG with a
    panel per variant and the difference coordinated (Eq. 14, Eq. 19) minus uncoordinated."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    mp = maps(rows, machs, hs)
    img_dir.mkdir(parents=True, exist_ok=True)
    dm = (machs[1] - machs[0]) / 2 if len(machs) > 1 else 0.5
    dh = (hs[1] - hs[0]) / 2e3 if len(hs) > 1 else 0.5
    ext = [machs[0] - dm, machs[-1] + dm, hs[0] / 1e3 - dh, hs[-1] / 1e3 + dh]
    qgrid = np.array([[flight_condition(m, h)[1] / 1e3 for m in machs] for h in hs])
    paths = []
    specs = (("os", "worst-channel overshoot %", 0, 40, "viridis", 20),
             ("ts", "worst-channel settling time s (inf: not settled)", 0, 10, "viridis", 5),
             ("sat", "time any surface is on its limit s", 0, 5, "magma", 2))
    for key, title, lo, hi, cmap, dlim in specs:
        fig, axes = plt.subplots(1, 5, figsize=(24, 4.6), constrained_layout=True)
        for ax, var in zip(axes[:3], VARIANTS):
            a = mp.get((var, key))
            im = ax.imshow(np.clip(a, lo, hi) if a is not None else np.zeros((1, 1)),
                           origin="lower", extent=ext, aspect="auto", cmap=cmap, vmin=lo, vmax=hi)
            _decorate(ax, var, mp.get((var, "div")), machs, hs, qgrid)
        fig.colorbar(im, ax=axes[:3], shrink=0.9, label=title)
        for ax, var in zip(axes[3:], ("co_eq14", "co_eq19")):
            a, b = mp.get((var, key)), mp.get(("unco", key))
            d = None if a is None or b is None else np.where(np.isinf(a) & np.isinf(b), 0.0, a - b)
            im2 = ax.imshow(np.clip(d, -dlim, dlim) if d is not None else np.zeros((1, 1)),
                            origin="lower", extent=ext, aspect="auto", cmap="RdBu_r",
                            vmin=-dlim, vmax=dlim)
            _decorate(ax, f"{var} minus unco (blue: coordination better)",
                      mp.get((var, "div")), machs, hs, qgrid)
        fig.colorbar(im2, ax=axes[3:], shrink=0.9, label=f"difference ({title.split(' ')[-1]})")
        fig.suptitle(f"{title}; paper case (steps, +-20 % uncertainty, d(t)) flown at each "
                     f"(Mach, altitude); x = diverged; contours: dynamic pressure kPa")
        p = img_dir / f"{prefix}_{key}.png"
        fig.savefig(p, dpi=80)
        plt.close(fig)
        paths.append(p)
    fig, axes = plt.subplots(1, 3, figsize=(16, 4.6), constrained_layout=True)
    for ax, var in zip(axes, VARIANTS):
        a = mp.get((var, "spec"))
        ax.imshow(a if a is not None else np.zeros((1, 1)), origin="lower", extent=ext,
                  aspect="auto", cmap="RdYlGn", vmin=0, vmax=1)
        _decorate(ax, f"{var}: green = meets spec (os <= 10 %, ts <= 5 s), red = not",
                  mp.get((var, "div")), machs, hs, qgrid)
        tr = mp.get((var, "trim"))
        if tr is not None:
            jj, ii = np.nonzero(tr == 0.0)
            ax.plot(machs[ii], hs[jj] / 1e3, "s", mfc="none", mec="k", ms=6)
    fig.suptitle("where the paper's fixed gains hold (x = diverged, open square = commanded "
                 "state not trimmable within +-20 deg; blank = outside the q corridor)")
    p = img_dir / f"{prefix}_spec.png"
    fig.savefig(p, dpi=80)
    plt.close(fig)
    paths.append(p)
    return paths


def _decorate(ax, title, div, machs, hs, qgrid):
    ax.set_title(title, fontsize=9)
    ax.set_xlabel("Mach")
    ax.set_ylabel("altitude km")
    if div is not None:
        jj, ii = np.nonzero(div == 1.0)
        ax.plot(machs[ii], hs[jj] / 1e3, "kx", ms=5)
    if len(machs) > 1 and len(hs) > 1:
        cs = ax.contour(machs, hs / 1e3, qgrid, levels=[10, 25, 50, 100, 183, 300], colors="w",
                        linewidths=0.6)
        ax.clabel(cs, fontsize=6, fmt="%g")
    ax.plot([7.44], [21.0], "r*", ms=9)


def summary(rows: list[dict]) -> str:
    """Text: per variant, points flown, diverged, meeting the spec, and where coordination
    helps or hurts (worst-channel overshoot and settling, paired by point)."""
    by = {}
    for r in rows:
        by.setdefault(r["variant"], {})[(r["mach"], r["h_km"])] = r
    lines = []
    for var, pts in by.items():
        n = len(pts)
        div = sum(bool(r.get("diverged")) or bool(r.get("error")) for r in pts.values())
        ok = [k for k, r in pts.items() if meets_spec(r)]
        lines.append(f"{var}: {n} points, diverged {div}, meet spec {len(ok)}"
                     + (f" (Mach {min(k[0] for k in ok):g}-{max(k[0] for k in ok):g}, "
                        f"{min(k[1] for k in ok):g}-{max(k[1] for k in ok):g} km)" if ok else ""))
    un = by.get("unco", {})
    for var in ("co_eq14", "co_eq19"):
        co = by.get(var, {})
        both = [k for k in co if k in un and not co[k].get("diverged") and not un[k].get("diverged")]
        if not both:
            continue
        dos = np.array([_worst(co[k], "os_pct") - _worst(un[k], "os_pct") for k in both])
        dts = np.array([_worst(co[k], "ts_s") - _worst(un[k], "ts_s") for k in both])
        dts = dts[np.isfinite(dts)]
        lines.append(f"{var} vs unco over {len(both)} points both flew: worst overshoot lower in "
                     f"{int(np.sum(dos < 0))}, higher in {int(np.sum(dos > 0))} (median "
                     f"{np.median(dos):+.1f} pt); worst settling shorter in {int(np.sum(dts < 0))}, "
                     f"longer in {int(np.sum(dts > 0))} (median {np.median(dts):+.2f} s)")
        only_co = sum(1 for k in co if k in un and meets_spec(co[k]) and not meets_spec(un[k]))
        only_un = sum(1 for k in co if k in un and meets_spec(un[k]) and not meets_spec(co[k]))
        lines.append(f"  meets spec only coordinated: {only_co} points; only uncoordinated: {only_un}")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m tools.envelope",
                                 description=__doc__.split("\n")[0])
    ap.add_argument("--out", type=Path, default=Path("runs/env"),
                    help="output directory for the grid results (default runs/env)")
    ap.add_argument("--quick", action="store_true", help="2 x 2 points (smoke test)")
    ap.add_argument("--workers", type=int, default=2, help="Dask workers (0 = in process)")
    ap.add_argument("--duration", type=float, default=20.0, help="simulated time per run, s")
    ap.add_argument("--img", type=Path, default=None, help="heat maps here (default: --out)")
    ap.add_argument("--plots-only", action="store_true", help="re-plot --out's points.csv")
    a = ap.parse_args(argv)
    if not a.plots_only:
        rows = run(a.out, a.quick, a.workers, a.duration)
    rows = read_points(a.out / "points.csv")
    machs, hs = grid(a.quick)
    paths = plot(rows, machs, hs, a.img or a.out)
    text = summary(rows)
    (a.out / "summary.txt").write_text(text + "\n")
    print(text)
    print("pictures: " + ", ".join(str(p) for p in paths))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
