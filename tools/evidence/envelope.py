"""tools/evidence/envelope.py - the paper's fixed gains across the flight envelope (issue 15, point 5).

A grid of flight conditions (Mach x altitude) across the winged-cone's hypersonic corridor;
at each point inside the dynamic-pressure corridor the paper's case is flown with the paper's
fixed gains: the scenario ``paper`` (its +-20 % uncertainty, its disturbance, its steps alpha
1 -> 5, beta 5 -> 0, mu 0 -> 4 deg) with the initial speed and altitude of the point, the
surfaces starting at the plant's moment trim of the initial state (``actuators.initial =
"trim"``). Each point is first trimmed with ``plant_sim.trim.trim_at`` at the initial state and
at the commanded one (alpha 5, beta 0 deg): a point whose commanded state cannot be trimmed
within the surface limits is reported as such. Variants: uncoordinated, and coordinated with
the factors of Eq. 14 and of Eq. 19 (readings set explicitly, tools.evidence.coordination.READINGS).
The law sees the plant's truth (as tools.sitl.closed_loop's paper-case figures). Each point is one
Dask task (LocalCluster, ``--workers``; 0 = in this process).

Two maps (issue 20): ``--disturbance accel`` (map a, the default) flies the paper's d(t) as an
angular acceleration, the same at every point; ``--disturbance coefficient`` (map b) flies it as
a moment coefficient (scenario ``[disturbance] qbar_ref_Pa``, docs/plant.md s. 8): equal to the
paper's at the paper's dynamic pressure, proportional to the point's dynamic pressure elsewhere,
as a gust or an asymmetry would be.

    python -m tools.evidence.envelope --out runs/env                 # the full grid, map (a)
    python -m tools.evidence.envelope --disturbance coefficient --out runs/env_b   # map (b)
    python -m tools.evidence.envelope --quick --out runs/env_quick   # 2 x 2 points, a smoke test
    python -m tools.evidence.envelope --out runs/env --plots-only --img docs/img   # pictures again

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

from fc.control.params import parse_sets

GAMMA_AIR = 1.4
#: the dynamic-pressure corridor flown, Pa: it contains the paper's point (183 kPa at Mach 7.4,
#: 21 km) and the classic air-breathing band (24-96 kPa, 500-2000 psf)
Q_MIN_PA = 10e3
Q_MAX_PA = 300e3
#: the issue-20 target corridor (the spec at >= 90 % of its points), kPa
TARGET_Q_KPA = (24.0, 300.0)
#: the paper's spec of the campaigns (tools/evidence/dispersions/paper.toml [spec])
SPEC_OS_PCT = 10.0
SPEC_TS_S = 5.0
#: the release test (``release_check``): flown this long after d(t) is switched off, s
RELEASE_S = 15.0
VARIANTS = {"unco": (False, "eq14"), "co_eq14": (True, "eq14"), "co_eq19": (True, "eq19")}
#: --disturbance: map (a) the paper's angular acceleration, map (b) a moment coefficient
DISTURBANCES = ("accel", "coefficient")
#: file-name prefix of each map's pictures
MAP_PREFIX = {"accel": "envelope", "coefficient": "envelope_b"}


def flight_condition(mach: float, h_m: float) -> tuple[float, float]:
    """(airspeed m/s, dynamic pressure Pa) at ``mach`` and ``h_m`` (US76)."""
    from plant_sim.atmosphere import us76
    o = np.zeros(8)
    us76(float(h_m), o)
    p_pa, a_m_s = o[1], o[3]
    return mach * a_m_s, 0.5 * GAMMA_AIR * p_pa * mach * mach


def point_scenario(mach: float, h_m: float, base: str = "paper", disturbance: str = "accel",
                   disturbance_end_s: float = 0.0):
    """The paper's scenario flown at (mach, h_m), surfaces starting at the initial trim.

    ``disturbance``: "accel" keeps the base scenario's d(t) (map a); "coefficient" makes it a
    moment coefficient equal to the base's d(t) at the base scenario's initial dynamic pressure
    (the paper's point, 183 kPa), so it scales with the point's dynamic pressure (map b).
    ``disturbance_end_s`` > 0: d(t) switched off from that sim time on (the release test).
    """
    from plant_sim.scenario import Scenario, load, parse
    if disturbance not in DISTURBANCES:
        raise ValueError(f"disturbance {disturbance!r}: one of {DISTURBANCES}")
    sc = load(base)
    d = copy.deepcopy(sc.data)
    if disturbance == "coefficient":
        d["disturbance"]["qbar_ref_Pa"] = paper_qbar_pa(sc)
    if disturbance_end_s > 0.0:
        d["disturbance"]["end_s"] = float(disturbance_end_s)
    v, _ = flight_condition(mach, h_m)
    d["initial"]["V_m_s"] = float(v)
    d["initial"]["h_m"] = float(h_m)
    d["actuators"]["initial"] = "trim"
    ed = Scenario(name=f"{sc.name}-M{mach:g}-h{h_m / 1e3:g}km", path=sc.path, data=d,
                  commands=list(sc.commands))
    return parse(ed.to_toml(), src=f"{sc.path} (envelope point)", name=ed.name)


def paper_qbar_pa(sc) -> float:
    """Dynamic pressure (Pa, US76) of scenario ``sc``'s initial state: the reference at which
    map (b)'s moment-coefficient disturbance equals the scenario's own d(t)."""
    from plant_sim.atmosphere import A_N, A_RHO_KG_M3, us76
    o = np.zeros(A_N)
    us76(float(sc.data["initial"]["h_m"]), o)
    return 0.5 * float(o[A_RHO_KG_M3]) * float(sc.data["initial"]["V_m_s"]) ** 2


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


def fly_point(mach: float, h_m: float, duration_s: float = 20.0, variants=tuple(VARIANTS),
              disturbance: str = "accel", overrides: dict | None = None) -> list:
    """The Dask task: trim one point and fly each variant; one row per variant.

    ``overrides``: law parameters {name: value} (table units) set on top of each variant's
    reading, e.g. a weight swept over the map (``--set``)."""
    from tools.sitl.closed_loop import simulate
    from tools.evidence.coordination import READINGS, run_metrics
    v, q = flight_condition(mach, h_m)
    base = {"mach": float(mach), "h_km": h_m / 1e3, "V_m_s": v, "qbar_kPa": q / 1e3}
    try:
        sc = point_scenario(mach, h_m, disturbance=disturbance)
        base.update(trim_point(sc))
    except Exception as exc:  # noqa: BLE001 - a point that cannot be set up is a result
        return [{**base, "variant": var, "error": f"{type(exc).__name__}: {exc}",
                 "diverged": True} for var in variants]
    rows = []
    for var in variants:
        co, reading = VARIANTS[var]
        ov = dict(READINGS[reading])
        ov.update(overrides or {})
        t0 = time.perf_counter()
        try:
            res = simulate(sc, coordinated=co, duration_s=duration_s, law_overrides=ov,
                           command_shaping="steps", estimate="truth")
            row = {**base, "variant": var, "error": ""}
            row.update(run_metrics(res))
        except Exception as exc:  # noqa: BLE001
            row = {**base, "variant": var, "error": f"{type(exc).__name__}: {exc}",
                   "diverged": True}
        if unsettled(row):
            row.update(release_check(mach, h_m, duration_s, co, ov, disturbance))
        row["wall_s"] = time.perf_counter() - t0
        rows.append(row)
    return rows


def release_check(mach: float, h_m: float, duration_s: float, coordinated: bool, overrides: dict,
                  disturbance: str, release_s: float = RELEASE_S) -> dict:
    """The release test of a point left unsettled: the same flight again, with d(t) switched off
    at ``duration_s`` and flown ``release_s`` longer. A forced response (the disturbance beyond
    the surfaces' authority) settles once d is gone; a limit cycle or a drift does not.

    Returns {"release_ts_s": worst channel's settling time of the longer flight (s; NaN: some
    channel still outside its band at the end), "release_fe_deg": worst final error (deg),
    "release_diverged": bool}.
    """
    from tools.sitl.closed_loop import simulate
    from tools.evidence.coordination import run_metrics
    sc = point_scenario(mach, h_m, disturbance=disturbance, disturbance_end_s=duration_s)
    try:
        res = simulate(sc, coordinated=coordinated, duration_s=duration_s + release_s,
                       law_overrides=overrides, command_shaping="steps", estimate="truth")
        r = run_metrics(res)
    except Exception:  # noqa: BLE001 - a failed release is reported, not raised
        return {"release_ts_s": math.nan, "release_fe_deg": math.nan, "release_diverged": True}
    ts = _worst(r, "ts_s")
    return {"release_ts_s": ts if math.isfinite(ts) else math.nan,
            "release_fe_deg": float(np.nanmax([r[f"{c}_fe_deg"] for c in ("alpha", "beta", "mu")])),
            "release_diverged": bool(r["diverged"])}


def released(r: dict) -> bool:
    """An unsettled point whose release test settled: its oscillation was forced by d(t)."""
    v = r.get("release_ts_s", math.nan)
    return unsettled(r) and r.get("release_diverged") is not True and \
        isinstance(v, float) and math.isfinite(v)


def grid(quick: bool = False):
    """(Mach values, altitudes m) of the campaign."""
    if quick:
        return np.array([7.0, 10.0]), np.array([22e3, 30e3])
    return np.arange(6.0, 15.01, 0.5), np.arange(20e3, 40.01e3, 1e3)


def run(out: Path, quick: bool = False, workers: int = 2, duration_s: float = 20.0,
        variants=tuple(VARIANTS), disturbance: str = "accel",
        overrides: dict | None = None) -> list:
    machs, hs = grid(quick)
    pts = [(float(m), float(h)) for h in hs for m in machs
           if Q_MIN_PA <= flight_condition(m, h)[1] <= Q_MAX_PA]
    variants = tuple(variants)
    t0 = time.perf_counter()
    rows: list = []
    if workers <= 0:
        for m, h in pts:
            rows += fly_point(m, h, duration_s, variants, disturbance, overrides)
    else:
        from distributed import as_completed
        from tools.evidence.montecarlo.campaign import cluster_client
        with cluster_client(workers) as client:
            futs = [client.submit(fly_point, m, h, duration_s, variants, disturbance, overrides,
                                  pure=False)
                    for m, h in pts]
            for fut in as_completed(futs):
                rows += fut.result()
    wall = time.perf_counter() - t0
    out.mkdir(parents=True, exist_ok=True)
    from tools.evidence.coordination import write_rows
    write_rows(out / "points.csv", rows)
    info = {"mach": machs.tolist(), "h_m": hs.tolist(), "points": len(pts), "runs": len(rows),
            "q_corridor_Pa": [Q_MIN_PA, Q_MAX_PA], "workers": workers, "wall_s": wall,
            "duration_s": duration_s, "variants": list(variants), "disturbance": disturbance,
            "overrides": dict(overrides or {})}
    (out / "envelope.json").write_text(json.dumps(info, indent=1))
    print(f"envelope: {len(pts)} points, {len(rows)} runs, {wall:.0f} s wall, {workers} workers")
    return rows


def read_points(path: Path) -> list[dict]:
    from tools.evidence.coordination import read_csv_rows
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


def plot(rows: list[dict], machs, hs, img_dir: Path, prefix: str = "envelope",
         suffix: str = "", disturbance: str = "accel") -> list[Path]:
    """Heat maps: per figure (overshoot, settling, saturation, divergence + spec) one PNG
    (``{prefix}_{figure}{suffix}.png``) with a panel per variant flown and the difference of
    each coordinated variant minus uncoordinated."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    mp = maps(rows, machs, hs)
    flown = {r["variant"] for r in rows}
    vars_ = [v for v in VARIANTS if v in flown] or list(VARIANTS)
    diffs = [v for v in vars_ if v != "unco"] if "unco" in vars_ else []
    nv, nd = len(vars_), len(diffs)
    case = ("d(t) as the paper's angular acceleration" if disturbance == "accel" else
            "d(t) as a moment coefficient, the paper's at 183 kPa")
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
        fig, axes = plt.subplots(1, nv + nd, figsize=(4.8 * (nv + nd), 4.6),
                                 constrained_layout=True, squeeze=False)
        axes = axes[0]
        for ax, var in zip(axes[:nv], vars_):
            a = mp.get((var, key))
            im = ax.imshow(np.clip(a, lo, hi) if a is not None else np.zeros((1, 1)),
                           origin="lower", extent=ext, aspect="auto", cmap=cmap, vmin=lo, vmax=hi)
            _decorate(ax, var, mp.get((var, "div")), machs, hs, qgrid)
        fig.colorbar(im, ax=axes[:nv], shrink=0.9, label=title)
        for ax, var in zip(axes[nv:], diffs):
            a, b = mp.get((var, key)), mp.get(("unco", key))
            d = None if a is None or b is None else np.where(np.isinf(a) & np.isinf(b), 0.0, a - b)
            im2 = ax.imshow(np.clip(d, -dlim, dlim) if d is not None else np.zeros((1, 1)),
                            origin="lower", extent=ext, aspect="auto", cmap="RdBu_r",
                            vmin=-dlim, vmax=dlim)
            _decorate(ax, f"{var} minus unco (blue: coordination better)",
                      mp.get((var, "div")), machs, hs, qgrid)
        if nd:
            fig.colorbar(im2, ax=axes[nv:], shrink=0.9,
                         label=f"difference ({title.split(' ')[-1]})")
        fig.suptitle(f"{title}; paper case (steps, +-20 % uncertainty, {case}) flown at each "
                     f"(Mach, altitude); x = diverged; contours: dynamic pressure kPa")
        p = img_dir / f"{prefix}_{key}{suffix}.png"
        fig.savefig(p, dpi=80)
        plt.close(fig)
        paths.append(p)
    fig, axes = plt.subplots(1, nv, figsize=(5.4 * nv, 4.6), constrained_layout=True,
                             squeeze=False)
    for ax, var in zip(axes[0], vars_):
        a = mp.get((var, "spec"))
        ax.imshow(a if a is not None else np.zeros((1, 1)), origin="lower", extent=ext,
                  aspect="auto", cmap="RdYlGn", vmin=0, vmax=1)
        _decorate(ax, f"{var}: green = meets spec (os <= 10 %, ts <= 5 s), red = not",
                  mp.get((var, "div")), machs, hs, qgrid)
        tr = mp.get((var, "trim"))
        if tr is not None:
            jj, ii = np.nonzero(tr == 0.0)
            ax.plot(machs[ii], hs[jj] / 1e3, "s", mfc="none", mec="k", ms=6)
    fig.suptitle(f"where the spec holds, {case} (x = diverged, open square = commanded "
                 "state not trimmable within +-20 deg; blank = outside the q corridor)")
    p = img_dir / f"{prefix}_spec{suffix}.png"
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


def unsettled(r: dict) -> bool:
    """Flown to the end without diverging, but some channel is still outside its settling band
    at the last sample (settling time null): a limit cycle, or a residual oscillation or drift
    larger than the 5 % band (docs/metrics.md), after 20 s."""
    return (not r.get("diverged")) and not r.get("error") and math.isinf(_worst(r, "ts_s"))


def in_target_corridor(r: dict) -> bool:
    """The issue-20 target's points: 24-300 kPa, Mach <= 15."""
    return TARGET_Q_KPA[0] <= r["qbar_kPa"] <= TARGET_Q_KPA[1] and r["mach"] <= 15.0 + 1e-9


def counts(rows: list[dict]) -> dict:
    """Per variant: points flown, diverged (or not set up), unsettled at the end, meeting the
    spec, and the same over the 24-300 kPa, Mach <= 15 corridor (``summary.json``, which
    ``python -m tools.evidence.report import-env`` copies into docs/data)."""
    by: dict = {}
    for r in rows:
        by.setdefault(r["variant"], {})[(r["mach"], r["h_km"])] = r
    out = {}
    for var, pts in by.items():
        cor = [r for r in pts.values() if in_target_corridor(r)]
        out[var] = {"points": len(pts),
                    "diverged": sum(bool(r.get("diverged")) or bool(r.get("error"))
                                    for r in pts.values()),
                    "unsettled": sum(unsettled(r) for r in pts.values()),
                    "unsettled_released": sum(released(r) for r in pts.values()),
                    "meets_spec": sum(meets_spec(r) for r in pts.values()),
                    "corridor_points": len(cor),
                    "corridor_meets_spec": sum(meets_spec(r) for r in cor)}
    return out


def summary(rows: list[dict]) -> str:
    """Text: per variant, points flown, diverged, unsettled at the end, meeting the spec
    (everywhere and in the 24-300 kPa corridor), and where coordination helps or hurts
    (worst-channel overshoot and settling, paired by point)."""
    by = {}
    for r in rows:
        by.setdefault(r["variant"], {})[(r["mach"], r["h_km"])] = r
    lines = []
    for var, pts in by.items():
        n = len(pts)
        div = sum(bool(r.get("diverged")) or bool(r.get("error")) for r in pts.values())
        uns = sum(unsettled(r) for r in pts.values())
        rel = sum(released(r) for r in pts.values())
        ok = [k for k, r in pts.items() if meets_spec(r)]
        cor = [r for r in pts.values() if in_target_corridor(r)]
        cor_ok = sum(meets_spec(r) for r in cor)
        lines.append(f"{var}: {n} points, diverged {div}, unsettled at 20 s {uns} "
                     f"(of which settled once d(t) was switched off: {rel}), "
                     f"meet spec {len(ok)}"
                     + (f" (Mach {min(k[0] for k in ok):g}-{max(k[0] for k in ok):g}, "
                        f"{min(k[1] for k in ok):g}-{max(k[1] for k in ok):g} km)" if ok else "")
                     + f"; in 24-300 kPa, Mach <= 15: {cor_ok} of {len(cor)} "
                       f"({100.0 * cor_ok / max(len(cor), 1):.0f} %)")
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
    ap = argparse.ArgumentParser(prog="python -m tools.evidence.envelope",
                                 description=__doc__.split("\n")[0])
    ap.add_argument("--out", type=Path, default=Path("runs/env"),
                    help="output directory for the grid results (default runs/env)")
    ap.add_argument("--quick", action="store_true", help="2 x 2 points (smoke test)")
    ap.add_argument("--workers", type=int, default=2, help="Dask workers (0 = in process)")
    ap.add_argument("--duration", type=float, default=20.0, help="simulated time per run, s")
    ap.add_argument("--img", type=Path, default=None, help="heat maps here (default: --out)")
    ap.add_argument("--plots-only", action="store_true", help="re-plot --out's points.csv")
    ap.add_argument("--disturbance", choices=DISTURBANCES, default=None,
                    help="accel: the paper's d(t) as an angular acceleration at every point "
                         "(map a, default); coefficient: d(t) as a moment coefficient, the "
                         "paper's at its 183 kPa, scaling with dynamic pressure (map b). "
                         "With --plots-only: read from --out's envelope.json")
    ap.add_argument("--variants", default=",".join(VARIANTS),
                    help=f"comma-separated subset of {','.join(VARIANTS)} (default all)")
    ap.add_argument("--suffix", default="",
                    help="appended to the pictures' names, e.g. _before -> envelope_spec_before.png")
    ap.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                    help="a law parameter (table units) set in every variant on top of its "
                         "reading, e.g. --set ALLOC_W_ROLL=0.3; repeatable")
    a = ap.parse_args(argv)
    try:
        overrides = parse_sets(a.set)
    except ValueError as exc:
        ap.error(f"--set: {exc}")
    variants = tuple(v.strip() for v in a.variants.split(",") if v.strip())
    bad = [v for v in variants if v not in VARIANTS]
    if bad or not variants:
        ap.error(f"--variants: unknown {bad}; choose from {','.join(VARIANTS)}")
    dist = a.disturbance
    if a.plots_only and dist is None and (a.out / "envelope.json").exists():
        dist = json.loads((a.out / "envelope.json").read_text()).get("disturbance", "accel")
    dist = dist or "accel"
    if not a.plots_only:
        rows = run(a.out, a.quick, a.workers, a.duration, variants, dist, overrides)
    rows = read_points(a.out / "points.csv")
    machs, hs = grid(a.quick)
    paths = plot(rows, machs, hs, a.img or a.out, MAP_PREFIX[dist], a.suffix, dist)
    text = summary(rows)
    (a.out / "summary.txt").write_text(text + "\n")
    meta = (json.loads((a.out / "envelope.json").read_text())
            if (a.out / "envelope.json").exists() else {})
    (a.out / "summary.json").write_text(json.dumps(
        {"disturbance": dist, "duration_s": meta.get("duration_s"),
         "wall_s": meta.get("wall_s"), "variants": counts(rows)}, indent=1) + "\n")
    print(text)
    print("pictures: " + ", ".join(str(p) for p in paths))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
