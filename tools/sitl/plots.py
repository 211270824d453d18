"""Plots of a run (PNG, matplotlib Agg): the counterparts of the paper's Figs. 2-4 and more.

Each function takes the per-variant data of a run in the normalised form built by
``tools.sitl.rundata`` (SI arrays, names with units) and writes one PNG:

- ``fig2_attitude.png``: alpha, beta, mu with their commands (paper Fig. 2);
- ``fig3_rates.png``: body rates p, q, r (paper Fig. 3);
- ``fig4_surfaces.png``: surface deflections with their limits (paper Fig. 4);
- ``estimates.png``: the disturbance observer's estimate against the true disturbance moment,
  and the adaptive parameter estimates relative to their nominal values.

Coordinated and uncoordinated runs are overlaid (solid / dashed) when both are present.
Degrees only here, at the edge.
"""
from __future__ import annotations

import math
import os
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

R2D = 180.0 / math.pi
#: line style per variant; unknown variants fall back to the first
STYLE = {
    "coordinated": dict(color="tab:blue", linestyle="-", linewidth=1.4),
    "uncoordinated": dict(color="tab:orange", linestyle="--", linewidth=1.4),
}
CMD_STYLE = dict(color="black", linestyle=":", linewidth=1.3)
SURFACE_LABELS = ("left elevon", "right elevon", "rudder")


def _style(variant: str) -> dict:
    return STYLE.get(variant, STYLE["coordinated"])


def _title(fig, what: str, meta: dict) -> None:
    shaping = meta.get("command_shaping", "steps")
    sub = (f"scenario '{meta.get('scenario', '?')}', {meta.get('mode', '?')} mode, "
           f"command shaping: {shaping}, seed {meta.get('seed', '?')}")
    fig.suptitle(f"{what}\n{sub}", fontsize=11)


def _stairs(cmd_t_s, cmd_val, t_end_s):
    """Step-shaped polyline of a zero-order-hold timeline up to t_end_s."""
    t = np.asarray(cmd_t_s, dtype=float)
    v = np.asarray(cmd_val, dtype=float)
    xs = np.repeat(np.append(t, max(t_end_s, t[-1])), 2)[1:-1]
    ys = np.repeat(v, 2)
    return xs, ys


def _save(fig, path: Path) -> Path:
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _finish_axis(ax, ylabel: str) -> None:
    ax.set_ylabel(ylabel)
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize=8)


def _finish(fig, axes, title: str, meta: dict, path: os.PathLike) -> Path:
    axes[-1].set_xlabel("time [s]")
    _title(fig, title, meta)
    fig.tight_layout()
    return _save(fig, path)


def fig_attitude(runs: dict, meta: dict, path: os.PathLike) -> Path:
    """alpha, beta, mu (deg) against time for each variant, with the command drawn."""
    fig, axes = plt.subplots(3, 1, figsize=(9, 8.5), sharex=True)
    chans = (("alpha", "angle of attack alpha"), ("beta", "sideslip beta"),
             ("mu", "bank about velocity mu"))
    t_end = max(float(r["t_s"][-1]) for r in runs.values())
    for ax, (ch, label) in zip(axes, chans):
        for variant, r in runs.items():
            m = r.get("metrics", {}).get(ch, {})
            os_pct = m.get("overshoot_pct")
            extra = f" (overshoot {os_pct:.1f} %)" if os_pct is not None else ""
            ax.plot(r["t_s"], r[f"{ch}_rad"] * R2D, label=f"{variant}{extra}", **_style(variant))
            if meta.get("command_shaping") == "prefilter" and r.get("shaped_cmd_rad") is not None:
                ti, sc = r["shaped_cmd_t_s"], r["shaped_cmd_rad"]
                idx = ("alpha", "beta", "mu").index(ch)
                ax.plot(ti, sc[:, idx] * R2D, color="0.55", linewidth=0.9,
                        label=f"shaped command ({variant})" if variant == next(iter(runs)) else None)
        first = next(iter(runs.values()))
        xs, ys = _stairs(first["cmd_t_s"], first[f"cmd_{ch}_rad"], t_end)
        ax.plot(xs, ys * R2D, label="command", **CMD_STYLE)
        _finish_axis(ax, f"{label} [deg]")
    return _finish(fig, axes, "Attitude tracking (cf. paper Fig. 2): coordinated vs "
                   "uncoordinated", meta, path)


def fig_rates(runs: dict, meta: dict, path: os.PathLike) -> Path:
    """Body rates p, q, r (deg/s) against time for each variant."""
    fig, axes = plt.subplots(3, 1, figsize=(9, 8.5), sharex=True)
    chans = (("p", "roll rate p"), ("q", "pitch rate q"), ("r", "yaw rate r"))
    for ax, (ch, label) in zip(axes, chans):
        for variant, r in runs.items():
            ax.plot(r["t_s"], r[f"{ch}_rad_s"] * R2D, label=variant, **_style(variant))
        ax.axhline(0.0, color="0.6", linewidth=0.8)
        _finish_axis(ax, f"{label} [deg/s]")
    return _finish(fig, axes, "Body angular rates (cf. paper Fig. 3)", meta, path)


def fig_surfaces(runs: dict, meta: dict, path: os.PathLike) -> Path:
    """Actual surface deflections (deg) with the deflection limits."""
    fig, axes = plt.subplots(3, 1, figsize=(9, 8.5), sharex=True)
    for i, (ax, label) in enumerate(zip(axes, SURFACE_LABELS)):
        lim_deg = None
        for variant, r in runs.items():
            peak = r.get("max_surface_deg", {}).get(label.replace(" ", "_"))
            extra = f" (peak {peak:.1f} deg)" if peak is not None else ""
            ax.plot(r["t_s"], r["delta_rad"][:, i] * R2D, label=f"{variant}{extra}",
                    **_style(variant))
            if r.get("limit_rad") is not None:
                lim_deg = float(np.broadcast_to(r["limit_rad"], (3,))[i]) * R2D
        if lim_deg is not None:
            for s in (1, -1):
                ax.axhline(s * lim_deg, color="red", linestyle="-.", linewidth=0.9,
                           label="deflection limit" if s == 1 else None)
        _finish_axis(ax, f"{label} [deg]")
    return _finish(fig, axes, "Control surface deflections, actual (cf. paper Fig. 4; "
                   "elevon + = trailing edge up, rudder + = trailing edge left)", meta, path)


def fig_estimates(runs: dict, meta: dict, path: os.PathLike) -> Path:
    """Disturbance estimate vs the true disturbance moment, and the adaptive estimates."""
    have_theta = any(r.get("theta_hat") is not None for r in runs.values())
    nrows = 4 if have_theta else 3
    fig, axes = plt.subplots(nrows, 1, figsize=(9, 2.6 * nrows + 1.0), sharex=True)
    axis_names = ("roll (p)", "pitch (q)", "yaw (r)")
    for i in range(3):
        ax = axes[i]
        true_drawn = False
        for variant, r in runs.items():
            if r.get("dhat") is not None:
                ax.plot(r["int_t_s"], r["dhat"][:, i] * R2D, label=f"d_hat ({variant}): disturbance + model error",
                        **_style(variant))
            if r.get("dtrue") is not None and not true_drawn:
                ax.plot(r["t_s"], r["dtrue"][:, i] * R2D, color="black", linewidth=1.0,
                        alpha=0.8, label="true disturbance (plant)")
                true_drawn = True
        _finish_axis(ax, f"{axis_names[i]} disturbance\n[deg/s^2]")
    if have_theta:
        ax = axes[3]
        for variant, r in runs.items():
            th = r.get("theta_hat")
            if th is None:
                continue
            nom = r.get("theta_nominal")
            if nom is not None:
                nom = np.asarray(nom, dtype=float)
                safe = np.where(np.abs(nom) > 1e-12, nom, 1.0)
                vals = th / safe
            else:
                vals = th
            st = _style(variant)
            for j in range(vals.shape[1]):
                ax.plot(r["int_t_s"], vals[:, j], color=st["color"], linestyle=st["linestyle"],
                        linewidth=0.8, alpha=0.7, label=variant if j == 0 else None)
        _finish_axis(ax, "adaptive estimates\ntheta_hat / nominal [-]")
    return _finish(fig, axes, "Disturbance observer (angular acceleration, Eq. 37) vs the "
                   "plant's true disturbance; adaptive estimates", meta, path)


def write_all(runs: dict, meta: dict, out_dir: os.PathLike) -> list[Path]:
    """Write every figure of a run into out_dir; returns the paths written."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = [fig_attitude(runs, meta, out_dir / "fig2_attitude.png"),
             fig_rates(runs, meta, out_dir / "fig3_rates.png"),
             fig_surfaces(runs, meta, out_dir / "fig4_surfaces.png")]
    if any(r.get("dhat") is not None or r.get("theta_hat") is not None for r in runs.values()):
        paths.append(fig_estimates(runs, meta, out_dir / "estimates.png"))
    return paths
