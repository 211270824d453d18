"""From a run directory's logs to the summary and the plot data (no processes, no sockets).

Reads one variant directory (``RUN/coordinated``, ``RUN/uncoordinated``): the plant's truth
log (``plant_sim.truthlog.load``), the controller's internals log (``fc.internals_log.load``),
``plant_summary.json`` and the command timeline actually flown (``timeline.toml``), and builds

- the per-variant entry of ``summary.json`` (docs/metrics.md), and
- the normalised arrays ``tools.sitl.plots`` draws (SI, names with units).

``python -m tools.hil report RUN_DIR`` is this module applied to every variant of a run.
"""
from __future__ import annotations

import json
import math
import re
import tomllib
from pathlib import Path

import numpy as np

from hyfc_wire import timeline


TIMELINE_FILE = "timeline.toml"
CHANNELS = ("alpha", "beta", "mu")
#: default command of a channel before the first timeline entry sets it (fc CMD_*_DEG default)
DEFAULT_CMD_DEG = 0.0
#: keys that depend on the wall clock or on packet timing, never compared between two runs of
#: the same seed ("link": the plant's link counters such as re-requested frames)
WALL_CLOCK_KEYS = ("wall_time_s", "real_time_factor", "created_utc", "wall_time_total_s",
                   "link")


class RunDataError(RuntimeError):
    """A log needed for the summary is missing or unreadable."""


# ---- timeline ---------------------------------------------------------------------------
def read_timeline(path: Path) -> list[dict]:
    """The ``[[command]]`` tables of a TOML file (scenario or timeline): hyfc_wire.timeline's
    entries (sorted by t_s, the keys each gives, deg)."""
    try:
        return timeline.read_file(path)
    except timeline.TimelineError as e:
        raise RunDataError(str(e)) from None


def write_timeline(path: Path, commands: list[dict], header: str = "") -> None:
    lines = [f"# {ln}" for ln in header.splitlines()] if header else []
    for c in commands:
        lines.append("[[command]]")
        for key in ("t_s", "alpha_deg", "beta_deg", "mu_deg"):
            if key in c:
                lines.append(f"{key} = {float(c[key])!r}")
        lines.append("")
    Path(path).write_text("\n".join(lines) + "\n")


def channel_timeline(commands: list[dict], ch: str) -> tuple[np.ndarray, np.ndarray]:
    """(t_s, value_rad) of one channel: a missing angle keeps its previous value (as the fc)."""
    t, v = [], []
    cur = DEFAULT_CMD_DEG
    for c in commands:
        cur = c.get(f"{ch}_deg", cur)
        t.append(c["t_s"])
        v.append(math.radians(cur))
    if not t:
        t, v = [0.0], [math.radians(DEFAULT_CMD_DEG)]
    return np.asarray(t, dtype=float), np.asarray(v, dtype=float)


# ---- logs -------------------------------------------------------------------------------
def _first(d: dict, *names):
    for n in names:
        if n in d:
            return np.asarray(d[n])
    return None


def load_truth(vdir: Path) -> dict:
    """The plant's truth log of a variant directory as a dict of arrays."""
    path = Path(vdir) / "truth.npz"
    if not path.exists():
        raise RunDataError(f"{path} is missing (the plant did not finish writing its truth log)")
    try:
        from plant_sim.truthlog import load
    except ImportError:  # plant_sim not importable here: the npz is one array per column
        with np.load(path) as z:
            return {k: z[k] for k in z.files}
    return load(str(path))


def load_internals(vdir: Path) -> dict | None:
    path = Path(vdir) / "fc_internals.npz"
    if not path.exists():
        return None
    from fc.internals_log import load
    return load(str(path))


def load_internals_cached(vdir: Path) -> dict | None:
    """load_internals, read once per variant directory and file version (variant_summary
    reads it twice)."""
    path = Path(vdir) / "fc_internals.npz"
    try:
        key = (str(path.resolve()), path.stat().st_mtime_ns)
    except OSError:
        return None
    if _internals_cache[0] != key:
        _internals_cache[:] = [key, load_internals(vdir)]
    return _internals_cache[1]


_internals_cache: list = [None, None]

#: fc/modes.py FlightMode values in which the attitude law flies (COORDINATED, UNCOORDINATED,
#: CRUISE, GUIDED, MISSION); MANUAL and FAILSAFE hold its status
LAW_MODES = (1.0, 2.0, 4.0, 5.0, 6.0)


def surface_entry(truth: dict, internals: dict | None, limit_rad: float) -> dict:
    """summary.json's ``surfaces`` (tools.sitl.metrics.surface_figures, docs/metrics.md): from
    the truth log, and the rate-command limit's flag from the fc's internals log
    (``law_omega_c_limited``) while the law was active (None without that column)."""
    cmd = truth.get("delta_cmd_rad")
    if cmd is None:
        cmd = truth["delta_rad"]
    flag, flag_t = None, None
    if internals and "law_omega_c_limited" in internals and "t_s" in internals:
        flag_t = np.asarray(internals["t_s"], float)
        flag = np.asarray(internals["law_omega_c_limited"], float)
        if "armed" in internals and "mode" in internals:      # the law flies (fc/modes.py):
            active = (internals["armed"] > 0.5) & np.isin(internals["mode"], LAW_MODES)
            flag = np.where(active, flag, 0.0)
    from tools.sitl import metrics      # (imported when a run is over: not while it runs)
    return metrics.surface_figures(truth["t_s"], truth["delta_rad"], cmd, limit_rad,
                                   flag, flag_t)


def truth_series(truth: dict) -> dict:
    """Normalised SI arrays from the truth log (column names: plant_sim.sim.TRUTH_NAMES)."""
    out = {"t_s": _first(truth, "t_s")}
    for ch in CHANNELS:
        out[f"{ch}_rad"] = _first(truth, f"{ch}_rad")
    for ch in ("p", "q", "r"):
        out[f"{ch}_rad_s"] = _first(truth, f"{ch}_rad_s")
    cols = [_first(truth, n) for n in ("delta_left_rad", "delta_right_rad", "delta_rudder_rad")]
    missing = [k for k, v in out.items() if v is None]
    if missing or any(c is None for c in cols):
        raise RunDataError(f"truth log lacks columns {missing or 'delta_*_rad'}; "
                           f"has {sorted(truth)}")
    out["delta_rad"] = np.column_stack(cols)
    cmd = [_first(truth, f"delta_cmd_{s}_rad") for s in ("left", "right", "rudder")]
    out["delta_cmd_rad"] = np.column_stack(cmd) if all(c is not None for c in cmd) else None
    # the true disturbance, as the angular acceleration it causes (rad/s^2)
    dist = [_first(truth, f"dist_{ax}_rad_s2") for ax in ("p", "q", "r")]
    out["dtrue"] = np.column_stack(dist) if all(d is not None for d in dist) else None
    return out


def internals_series(internals: dict | None) -> dict:
    """d_hat, the relative adaptive estimates and the shaped command from the fc's internals
    log (columns of fc/app.py: ``law_`` + fc.control STATUS_NAMES), where the law was active."""
    none = {"int_t_s": None, "dhat": None, "theta_hat": None, "theta_nominal": None,
            "shaped_cmd_t_s": None, "shaped_cmd_rad": None}
    if not internals or "t_s" not in internals:
        return none
    t = np.asarray(internals["t_s"])
    active = np.ones(len(t), dtype=bool)
    if "armed" in internals and "mode" in internals:
        active = (internals["armed"] > 0.5) & np.isin(internals["mode"], (1.0, 2.0))
    if not np.any(active):
        return none
    dh = [_first(internals, f"law_d_hat_{ax}_rad_s2") for ax in ("p", "q", "r")]
    rho = [k for k in internals if k.startswith("law_rho_")]
    shaped = [_first(internals, f"law_{ch}_ref_rad") for ch in CHANNELS]
    return {
        "int_t_s": t[active],
        "dhat": np.column_stack(dh)[active] if all(d is not None for d in dh) else None,
        # the law logs rho with theta_hat = theta_nominal (1 + rho): plot theta_hat / nominal
        "theta_hat": (1.0 + np.column_stack([internals[k] for k in rho])[active]) if rho else None,
        "theta_nominal": None,
        "shaped_cmd_t_s": t[active],
        "shaped_cmd_rad": (np.column_stack(shaped)[active]
                           if all(x is not None for x in shaped) else None),
    }


def timeline_from_internals(internals: dict | None) -> list[dict] | None:
    """The command timeline as the controller applied it (its ``cmd_*_rad`` columns): one
    entry at the first row and one at every change. None if the columns are absent."""
    if not internals or "t_s" not in internals:
        return None
    cols = [_first(internals, f"cmd_{ch}_rad") for ch in CHANNELS]
    if any(c is None for c in cols) or len(internals["t_s"]) == 0:
        return None
    c = np.column_stack(cols)
    t = np.asarray(internals["t_s"])
    change = np.nonzero(np.any(np.diff(c, axis=0) != 0.0, axis=1))[0] + 1
    out = []
    for k in np.concatenate(([0], change)):
        e = {"t_s": float(t[k])}
        # round off the deg -> rad -> deg trip (6.000000000000001)
        e.update({f"{ch}_deg": round(math.degrees(float(c[k, i])), 9)
                  for i, ch in enumerate(CHANNELS)})
        out.append(e)
    return out


def late_ticks_from_log(path: Path) -> int | None:
    """The controller's own count of late fast-loop ticks, from its exit line in fc.log."""
    try:
        text = Path(path).read_text(errors="replace")
    except OSError:
        return None
    found = re.findall(r"late ticks (\d+)/\d+", text)
    return int(found[-1]) if found else None


def read_json(path: Path) -> dict:
    try:
        return json.loads(Path(path).read_text())
    except FileNotFoundError:
        return {}
    except json.JSONDecodeError as exc:
        raise RunDataError(f"{path}: not valid JSON ({exc})") from None


# ---- summary ----------------------------------------------------------------------------
def surface_limit_rad(vdir: Path, default_deg: float = 20.0) -> float:
    """Deflection limit of the scenario flown (``[actuators] limit_deg`` of the scenario copy
    in the variant directory or the run directory), rad."""
    for path in (Path(vdir) / "scenario.toml", Path(vdir).parent / "scenario.toml"):
        try:
            with open(path, "rb") as f:
                data = tomllib.load(f)
        except (OSError, tomllib.TOMLDecodeError):
            continue
        lim = data.get("actuators", {}).get("limit_deg")
        if lim is not None:
            return math.radians(float(lim))
    return math.radians(default_deg)


def variant_summary(vdir: Path, requested_duration_s: float | None = None,
                    surface_limit: float | None = None) -> tuple[dict, dict]:
    """(summary entry, plot data) of one variant directory (docs/metrics.md)."""
    from tools.sitl import metrics      # (imported when a run is over: not while it runs)
    vdir = Path(vdir)
    surface_limit_rad_ = surface_limit if surface_limit is not None else surface_limit_rad(vdir)
    truth = truth_series(load_truth(vdir))
    commands = read_timeline(vdir / TIMELINE_FILE)
    plant = read_json(vdir / "plant_summary.json")
    t = truth["t_s"]
    entry: dict = {}
    plot = dict(truth)
    plot.update(internals_series(load_internals_cached(vdir)))
    for ch in CHANNELS:
        ct, cv = channel_timeline(commands, ch)
        m = metrics.channel_metrics(t, truth[f"{ch}_rad"], ct, cv, wrap=(ch == "mu"))
        entry[ch] = metrics.json_metrics(m)
        plot[f"cmd_{ch}_rad"] = cv
        plot["cmd_t_s"] = ct
    peak, sat_s = metrics.surface_metrics(t, truth["delta_rad"], surface_limit_rad_)
    entry["max_surface_deg"] = peak
    entry["saturated_s"] = sat_s
    entry["surfaces"] = surface_entry(truth, load_internals_cached(vdir), surface_limit_rad_)
    sim_time = float(t[-1])
    entry["sim_time_s"] = sim_time
    entry["wall_time_s"] = float(plant.get("wall_time_s", math.nan))
    entry["real_time_factor"] = float(plant.get("real_time_factor", math.nan))
    late = late_ticks_from_log(vdir / "fc.log")
    entry["late_ticks"] = int(late) if late is not None else 0
    if late is None:
        entry["late_ticks_note"] = "fc.log has no 'late ticks' line (controller did not exit cleanly)"
    short = (requested_duration_s is not None and requested_duration_s > 0
             and sim_time < requested_duration_s - 0.05)
    entry["diverged"] = bool(metrics.is_diverged(*(truth[f"{c}_rad"] for c in CHANNELS))
                             or short)
    # the plant's own counters (frames, re-requests, ...): timing-dependent, for diagnosis
    entry["link"] = {k: plant[k] for k in plant if k not in ("wall_time_s", "real_time_factor")}
    plot["limit_rad"] = surface_limit_rad_
    plot["metrics"] = entry
    plot["max_surface_deg"] = peak
    return entry, plot


def strip_wall_clock(summary: dict) -> dict:
    """A copy of a summary without the keys that differ between identical runs."""
    if isinstance(summary, dict):
        return {k: strip_wall_clock(v) for k, v in summary.items() if k not in WALL_CLOCK_KEYS}
    if isinstance(summary, list):
        return [strip_wall_clock(v) for v in summary]
    return summary


def json_safe(obj):
    """Replace NaN/inf by None so the file is strict JSON."""
    if isinstance(obj, dict):
        return {k: json_safe(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [json_safe(v) for v in obj]
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    if isinstance(obj, np.generic):
        return json_safe(obj.item())
    return obj
