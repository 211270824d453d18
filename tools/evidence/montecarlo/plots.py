"""Campaign plots (PNG, matplotlib Agg), written into the campaign directory.

- ``envelopes.png``: alpha, beta, mu over all cases, per variant: min-max band, 5-95 %
  band, median, and the command;
- ``histograms.png``: overshoot, settling time and final error per channel, variants
  overlaid, the specification limit drawn;
- ``sensitivity.png``: the metric against the most influential dispersions (largest
  |Spearman rank correlation| per channel), variants overlaid.

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

from tools.evidence.montecarlo import results  # noqa: E402
from tools.evidence.montecarlo.case import CHANNELS  # noqa: E402
from tools.evidence.montecarlo.summary import SUMMARY_METRICS, _SPEC_OF, _columns  # noqa: E402

COLORS = {"coordinated": "tab:blue", "uncoordinated": "tab:orange"}
LABELS = {"alpha": "alpha (deg)", "beta": "beta (deg)", "mu": "mu (deg)"}
METRIC_LABELS = {"overshoot_pct": "overshoot (%)", "settling_time_s": "settling time (s)",
                 "final_error_deg": "final error (deg)"}


def _color(v: str) -> str:
    return COLORS.get(v, "tab:green")


def _title(fig, what: str, meta: dict, n: int) -> None:
    fig.suptitle(f"{what}\nscenario '{meta.get('scenario', '?')}', dispersions "
                 f"'{meta.get('dispersions', '?')}', {n} cases, seed {meta.get('seed', '?')}, "
                 f"backend {meta.get('backend', '?')}", fontsize=10)


def _save(fig, path) -> Path:
    fig.tight_layout(rect=(0, 0, 1, 0.94))
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)


#: width of the zoom on the transient (right column of envelopes.png), s
ZOOM_S = 5.0


def envelopes(out_dir, meta: dict, variants, trace_dt_s: float,
              commands: tuple | None = None) -> Path:
    """alpha/beta/mu envelopes over all cases (reads the trace columns).

    Left column: the whole run; right column: the first ZOOM_S seconds (the transient), when
    the run is longer than that.
    """
    table = results.read_rows(out_dir, columns=["error", *results.TRACE_COLUMNS], traces=True)
    var = np.asarray(table.column("variant").to_pylist(), dtype=object)
    n_cases = len(set(table.column("case").to_pylist()))
    bands = {}  # (channel, variant) -> (t, lo, p5, p50, p95, hi)
    t_end = 0.0
    for ch in CHANNELS:
        col = table.column(f"trace.{ch}_deg").to_pylist()
        for v in variants:
            traces = [np.asarray(c, dtype=float) for c, vv in zip(col, var)
                      if vv == v and c is not None]
            if not traces:
                continue
            n = max(len(tr) for tr in traces)
            arr = np.full((len(traces), n), np.nan)
            for k, tr in enumerate(traces):
                arr[k, :len(tr)] = tr
            t = np.arange(n) * trace_dt_s
            t_end = max(t_end, float(t[-1]))
            with np.errstate(all="ignore"), _quiet():
                lo, hi = np.nanmin(arr, axis=0), np.nanmax(arr, axis=0)
                p5, p50, p95 = np.nanpercentile(arr, [5, 50, 95], axis=0)
            bands[ch, v] = (t, lo, p5, p50, p95, hi)
    zoom = t_end > 1.5 * ZOOM_S
    if zoom:
        fig, grid = plt.subplots(3, 2, figsize=(13, 9), sharex="col",
                                 gridspec_kw={"width_ratios": [2, 1]})
    else:
        fig, grid = plt.subplots(3, 1, figsize=(9, 9), sharex=True, squeeze=False)
    for r, ch in enumerate(CHANNELS):
        for c_ax, ax in enumerate(grid[r]):
            for v in variants:
                if (ch, v) not in bands:
                    continue
                t, lo, p5, p50, p95, hi = bands[ch, v]
                c = _color(v)
                ax.fill_between(t, lo, hi, color=c, alpha=0.15, linewidth=0,
                                label=f"{v}: min-max")
                ax.fill_between(t, p5, p95, color=c, alpha=0.35, linewidth=0,
                                label=f"{v}: 5-95 %")
                ax.plot(t, p50, color=c, linewidth=1.3, label=f"{v}: median")
            if commands is not None:
                cmd_t, cmd_deg = commands
                i = CHANNELS.index(ch)
                xs = np.repeat(np.append(cmd_t, max(t_end, cmd_t[-1])), 2)[1:-1]
                ax.plot(xs, np.repeat(cmd_deg[:, i], 2), color="black", linestyle=":",
                        linewidth=1.2, label="command")
            ax.grid(alpha=0.3)
            if c_ax == 0:
                ax.set_ylabel(LABELS[ch])
            else:
                ax.set_xlim(0.0, ZOOM_S)
    grid[0][0].legend(fontsize=7, ncol=2, loc="lower right")
    grid[-1][0].set_xlabel("time (s)")
    if zoom:
        grid[0][1].set_title(f"first {ZOOM_S:g} s", fontsize=9)
        grid[-1][1].set_xlabel("time (s)")
    _title(fig, "Attitude envelopes over all cases", meta, n_cases)
    return _save(fig, Path(out_dir) / "envelopes.png")


class _quiet:
    """Silence numpy's all-NaN-slice warnings (columns past a diverged case's end)."""

    def __enter__(self):
        import warnings
        self._w = warnings.catch_warnings()
        self._w.__enter__()
        warnings.simplefilter("ignore", RuntimeWarning)

    def __exit__(self, *a):
        return self._w.__exit__(*a)


def histograms(out_dir, meta: dict, variants, spec: dict) -> Path:
    """Histograms of overshoot, settling time, final error per channel and variant."""
    table = results.read_rows(out_dir)
    cols = _columns(table)
    fig, axes = plt.subplots(3, 3, figsize=(12, 9))
    n_cases = len(set(cols["case"].tolist())) if table.num_rows else 0
    for r, ch in enumerate(CHANNELS):
        for c, m in enumerate(SUMMARY_METRICS):
            ax = axes[r, c]
            data = {v: cols[f"{ch}.{m}"][cols["variant"] == v].astype(float) for v in variants}
            finite = np.concatenate([x[np.isfinite(x)] for x in data.values()] or [np.zeros(0)])
            if finite.size:
                lo, hi = float(finite.min()), float(finite.max())
                bins = np.linspace(lo, hi if hi > lo else lo + 1e-9, 31)
                for v, x in data.items():
                    x = x[np.isfinite(x)]
                    und = int((~np.isfinite(data[v])).sum())
                    lab = f"{v}" + (f" ({und} undefined)" if und else "")
                    ax.hist(x, bins=bins, color=_color(v), alpha=0.5, label=lab)
            lim = spec[_SPEC_OF[m]][ch]
            ax.axvline(lim, color="red", linestyle="--", linewidth=1, label="spec")
            ax.set_xlabel(f"{ch} {METRIC_LABELS[m]}")
            ax.grid(alpha=0.3)
            if c == 0:
                ax.set_ylabel("cases")
            ax.legend(fontsize=7)
    _title(fig, "Metric histograms per variant", meta, n_cases)
    return _save(fig, Path(out_dir) / "histograms.png")


def sensitivity(out_dir, meta: dict, variants, summary: dict, n_top: int = 3,
                metric: str = "overshoot_pct") -> Path | None:
    """``metric`` of each channel against its ``n_top`` most influential dispersions."""
    sens = summary.get("sensitivity", {})
    if not sens:
        return None
    table = results.read_rows(out_dir)
    cols = _columns(table)
    fig, axes = plt.subplots(3, n_top, figsize=(4 * n_top, 9), squeeze=False)
    n_cases = summary.get("cases", 0)
    any_key = False
    for r, ch in enumerate(CHANNELS):
        score: dict[str, float] = {}
        for v in variants:
            for k, rho in sens.get(v, {}).get(f"{ch}.{metric}", {}).items():
                if rho is not None and math.isfinite(rho):
                    score[k] = max(score.get(k, 0.0), abs(rho))
        top = sorted(score, key=lambda k: -score[k])[:n_top]
        for c in range(n_top):
            ax = axes[r, c]
            if c >= len(top):
                ax.set_axis_off()
                continue
            any_key = True
            k = top[c]
            for v in variants:
                sel = cols["variant"] == v
                rho = sens.get(v, {}).get(f"{ch}.{metric}", {}).get(k)
                lab = f"{v} (rho {rho:+.2f})" if rho is not None else v
                ax.scatter(cols[k][sel], cols[f"{ch}.{metric}"][sel], s=6, alpha=0.5,
                           color=_color(v), label=lab)
            ax.set_xlabel(k)
            ax.set_ylabel(f"{ch} {METRIC_LABELS[metric]}")
            ax.grid(alpha=0.3)
            ax.legend(fontsize=7)
    if not any_key:
        plt.close(fig)
        return None
    _title(fig, f"{METRIC_LABELS[metric]} against the most influential dispersions "
                f"(Spearman rank correlation)", meta, n_cases)
    return _save(fig, Path(out_dir) / "sensitivity.png")


def write_all(out_dir: os.PathLike, meta: dict, variants, spec: dict, summary: dict,
              trace_dt_s: float, commands=None) -> list[Path]:
    paths = [envelopes(out_dir, meta, variants, trace_dt_s, commands),
             histograms(out_dir, meta, variants, spec)]
    p = sensitivity(out_dir, meta, variants, summary)
    if p is not None:
        paths.append(p)
    return paths
