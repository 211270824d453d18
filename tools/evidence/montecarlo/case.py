"""One case of a campaign: draw its dispersions, fly each variant, measure it.

:func:`run_case` is the Dask task: a pure function of ``(config, case index)``; everything it
draws comes from the campaign seed and the index (``dispersions.variable_rng``,
``dispersions.case_sim_seed``), so a case re-run alone (``python -m tools.evidence.montecarlo rerun``)
gives the same rows.

A *backend* flies one variant of one dispersed case and returns its attitude history:

- ``closed_loop`` (default): ``tools.sitl.closed_loop.simulate``, the product's control law flying
  the product's plant in process (same code as the two-process product, without UDP);
- ``hil``: the two processes over loopback UDP (``tools.evidence.montecarlo.hil``), a faithful subset;
- ``standin``: a cheap decoupled second-order model, **not a flight simulation**: it exists
  only to exercise the campaign machinery (tests of resumption, summaries, plots) in a few
  milliseconds. A campaign run with it says so in every row and in its summary.

Metrics are those of the main job's ``summary.json`` (``tools.sitl.metrics``), computed here from
the true alpha, beta, mu of the plant against the scenario's command timeline.
"""
from __future__ import annotations

import functools
import hashlib
import json
import math
import os
import socket
import time
import traceback
from dataclasses import dataclass, field, asdict

import numpy as np

from tools.sitl import metrics as mt
from tools.evidence.montecarlo import dispersions as dsp
from tools.evidence.montecarlo.flight import Flight

CHANNELS = ("alpha", "beta", "mu")
VARIANTS = ("coordinated", "uncoordinated")
BACKENDS = ("closed_loop", "hil", "standin")


@dataclass(frozen=True)
class CampaignConfig:
    """Everything a worker needs to run any case of a campaign (small, picklable).

    Attributes
    ----------
    scenario : plant scenario name or path (``plant_sim.scenario.load``).
    dispersions_text : the dispersion file's TOML text (parsed again on each worker).
    dispersions_name : its name, for reports.
    seed : campaign seed; case i draws from (seed, i).
    variants : variants flown for every case (subset of VARIANTS).
    duration_s : simulated time per case, s (None: the scenario's).
    trace_dt_s : sampling of the alpha/beta/mu traces kept per case for envelopes, s.
    backend : one of BACKENDS.
    law_overrides : control-law parameter overrides (human units, fc.control.params).
    """

    scenario: str
    dispersions_text: str
    dispersions_name: str
    seed: int
    variants: tuple[str, ...] = VARIANTS
    duration_s: float | None = None
    trace_dt_s: float = 0.05
    backend: str = "closed_loop"
    law_overrides: dict = field(default_factory=dict)

    def __post_init__(self):
        bad = [v for v in self.variants if v not in VARIANTS]
        if bad or not self.variants:
            raise ValueError(f"variants must be a non-empty subset of {VARIANTS}, got "
                             f"{self.variants}")
        if self.backend not in BACKENDS:
            raise ValueError(f"backend must be one of {BACKENDS}, got {self.backend!r}")
        if self.duration_s is not None and not self.duration_s > 0:
            raise ValueError(f"duration_s must be > 0, got {self.duration_s}")
        if not self.trace_dt_s > 0:
            raise ValueError(f"trace_dt_s must be > 0, got {self.trace_dt_s}")

    def to_json(self) -> dict:
        return asdict(self)

    @classmethod
    def from_json(cls, d: dict) -> "CampaignConfig":
        d = dict(d)
        d["variants"] = tuple(d["variants"])
        return cls(**d)

    def dispersions_canonical(self) -> str:
        """The parsed distributions as text (what of the dispersion file decides the rows)."""
        disp = dispersions_of(self)
        return json.dumps([[k, d.kind, d.low, d.high, d.mean, d.std, d.value]
                           for k, d in disp.dists.items()])

    def identity(self) -> str:
        """Hash of what decides the rows (a resumed campaign must have the same).

        The dispersion file counts by its parsed distributions: comments, layout and its
        [spec] (which only the summary reads) may change between a run and its resume.
        """
        d = self.to_json()
        d["dispersions_text"] = self.dispersions_canonical()
        text = json.dumps(d, sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()[:16]


# ---------------------------------------------------------------------------------------
# per-worker caches (a worker runs many cases of the same campaign)

@functools.lru_cache(maxsize=8)
def _dispersions(text: str, name: str) -> dsp.Dispersions:
    return dsp.parse(text, name=name)


def dispersions_of(cfg: CampaignConfig) -> dsp.Dispersions:
    return _dispersions(cfg.dispersions_text, cfg.dispersions_name)


# ---------------------------------------------------------------------------------------
# backends

def _standin_flight(cfg: CampaignConfig, values: dict, variant: str, sim_seed: int,
                    full: bool) -> Flight:
    """STAND-IN, not a flight simulation: three decoupled second-order channels.

    Exercises the campaign machinery only (selected with ``--backend standin``). The natural
    frequency and damping move with the aerodynamic factors, the disturbance phases add a
    sinusoid, sensor noise adds a seeded random walk, so dispersions and seeds visibly change
    the metrics. The coordinated variant has more damping.
    """
    duration = cfg.duration_s or nominal_duration_s(cfg)
    dt = 0.01
    n = int(round(duration / dt)) + 1
    t = np.arange(n) * dt
    rng = np.random.Generator(np.random.PCG64(sim_seed))
    zeta0 = 0.7 if variant == "coordinated" else 0.5
    x0 = {"alpha": math.radians(values.get("initial.alpha_deg", 1.0)),
          "beta": math.radians(values.get("initial.beta_deg", 5.0)),
          "mu": math.radians(values.get("initial.mu_deg", 0.0))}
    cmd = {"alpha": math.radians(5.0), "beta": 0.0, "mu": math.radians(4.0)}
    coef = {"alpha": "aero.Cm", "beta": "aero.Cn", "mu": "aero.Cl"}
    phase = {"alpha": "disturbance.phase_pitch_deg", "beta": "disturbance.phase_yaw_deg",
             "mu": "disturbance.phase_roll_deg"}
    amp = values.get("disturbance.amplitude_factor", 1.0)
    noise = values.get("sensors.noise", 0.0) * values.get("sensors.noise_factor", 1.0)
    out = {}
    for ch in CHANNELS:
        k = values.get(coef[ch], 1.0)
        wn = 2.0 * math.sqrt(k)
        zeta = zeta0 / math.sqrt(k)
        ph = math.radians(values.get(phase[ch], 0.0))
        x, v = x0[ch], 0.0
        y = np.empty(n)
        w = rng.standard_normal(n) * 2e-4 * noise
        for i in range(n):
            y[i] = x
            d = 2e-3 * amp * math.sin(1.5 * t[i] + ph)
            acc = wn * wn * (cmd[ch] - x) - 2.0 * zeta * wn * v + d + w[i]
            v += acc * dt
            x += v * dt
        out[ch] = y
    cmd_rad = np.array([[cmd["alpha"], cmd["beta"], cmd["mu"]]])
    return Flight(t, out["alpha"], out["beta"], out["mu"], np.array([0.0]), cmd_rad)


@functools.lru_cache(maxsize=4)
def _base_scenario(name_or_path: str):
    from plant_sim.scenario import load
    return load(name_or_path)


def dispersed_scenario(cfg: CampaignConfig, values: dict):
    """The scenario of a case: the campaign's scenario with the case's values applied.

    The last one is kept: a case's variants fly the same dispersed scenario, and applying the
    values (a TOML round trip through the plant's own validation) is a few per cent of a
    case. The Scenario is not modified by the flights (plant_sim.sim.PlantSim reads it)."""
    key = (cfg.scenario, tuple(sorted((k, float(v)) for k, v in values.items())))
    if _last_dispersed[0] != key:
        from tools.evidence.montecarlo import apply
        _last_dispersed[:] = [key, apply.apply(_base_scenario(cfg.scenario), values)]
    return _last_dispersed[1]


_last_dispersed: list = [None, None]


def _closed_loop_flight(cfg: CampaignConfig, values: dict, variant: str, sim_seed: int,
                        full: bool) -> Flight:
    from tools.evidence.montecarlo import apply
    scen = dispersed_scenario(cfg, values)
    return apply.fly_closed_loop(scen, variant, cfg.duration_s, sim_seed, cfg.law_overrides,
                                 full=full)


def _hil_flight(cfg: CampaignConfig, values: dict, variant: str, sim_seed: int,
                full: bool, log_dir=None) -> Flight:
    from tools.evidence.montecarlo import hil
    scen = dispersed_scenario(cfg, values)
    return hil.fly(scen, variant, cfg.duration_s, sim_seed, cfg.law_overrides, full=full,
                   keep_dir=log_dir)


_BACKEND_FUNCS = {"closed_loop": _closed_loop_flight, "hil": _hil_flight,
                  "standin": _standin_flight}


# ---------------------------------------------------------------------------------------
# metrics and rows

def _nan_if_none(x):
    return math.nan if x is None else float(x)


def flight_metrics(fl: Flight) -> dict:
    """``{channel: ChannelMetrics}`` plus the divergence verdict, from a Flight."""
    out = {}
    for i, ch in enumerate(CHANNELS):
        y = getattr(fl, f"{ch}_rad")
        out[ch] = mt.channel_metrics(fl.t_s, y, fl.cmd_t_s, fl.cmd_rad[:, i], wrap=(ch == "mu"))
    diverged = bool(fl.diverged) or mt.is_diverged(fl.alpha_rad, fl.beta_rad, fl.mu_rad)
    return {"channels": out, "diverged": diverged}


def resample(t_s: np.ndarray, y: np.ndarray, dt_s: float, t_end_s: float) -> np.ndarray:
    """y on the grid 0, dt, ..., t_end (linear interpolation; NaN past the data's end)."""
    n = int(math.floor(t_end_s / dt_s + 1e-9)) + 1
    grid = np.arange(n) * dt_s
    out = np.interp(grid, t_s, y, right=math.nan)
    return out


def case_values(cfg: CampaignConfig, index: int) -> tuple[dict, int]:
    """The dispersion values and the plant seed of case ``index``."""
    disp = dispersions_of(cfg)
    return disp.sample(cfg.seed, index), dsp.case_sim_seed(cfg.seed, index)


def fly_case(cfg: CampaignConfig, index: int, variant: str, *, full: bool = False,
             log_dir=None):
    """Fly one variant of case ``index``: (values, sim_seed, Flight).

    ``log_dir``: with the ``hil`` backend, keep the processes' run directory there (truth log,
    fc.log, fc.tlog, internals; docs/hil.md) instead of a temporary one.
    """
    values, sim_seed = case_values(cfg, index)
    if cfg.backend == "hil":
        fl = _hil_flight(cfg, values, variant, sim_seed, full, log_dir)
    else:
        fl = _BACKEND_FUNCS[cfg.backend](cfg, values, variant, sim_seed, full)
    return values, sim_seed, fl


def run_case(cfg: CampaignConfig, index: int) -> list[dict]:
    """The Dask task: every variant of case ``index``, one row each.

    A case whose simulation raises gives rows with ``error`` set (and ``diverged`` true):
    a deterministic failure is a result, not a reason to retry.
    """
    rows = []
    values, sim_seed = case_values(cfg, index)
    worker = f"{socket.gethostname()}:{os.getpid()}"
    t_end = cfg.duration_s if cfg.duration_s is not None else nominal_duration_s(cfg)
    for variant in cfg.variants:
        t0 = time.perf_counter()
        c0 = time.process_time()
        row = {"case": int(index), "variant": variant, "campaign_seed": int(cfg.seed),
               "sim_seed": int(sim_seed), "backend": cfg.backend, "worker": worker,
               "error": ""}
        row.update({k: float(v) for k, v in values.items()})
        try:
            fl = _BACKEND_FUNCS[cfg.backend](cfg, values, variant, sim_seed, False)
            m = flight_metrics(fl)
            row["diverged"] = m["diverged"]
            for ch, cm in m["channels"].items():
                for key in mt.METRIC_KEYS:
                    row[f"{ch}.{key}"] = _nan_if_none(getattr(cm, key))
            for ch in CHANNELS:  # NaN past the end of a run stopped early (diverged)
                tr = resample(fl.t_s, getattr(fl, f"{ch}_rad"), cfg.trace_dt_s, t_end)
                row[f"trace.{ch}_deg"] = np.degrees(tr).astype(np.float32)
            row["sim_time_s"] = float(fl.t_s[-1])
            for key in mt.SURFACE_FIGURE_KEYS:      # docs/metrics.md "Surfaces"; NaN: unknown
                row[f"surf.{key}"] = _nan_if_none((fl.surfaces or {}).get(key))
        except Exception as exc:  # a case that cannot be flown is a (failed) result
            row["diverged"] = True
            tb = traceback.extract_tb(exc.__traceback__)
            where = f" (at {os.path.basename(tb[-1].filename)}:{tb[-1].lineno})" if tb else ""
            row["error"] = f"{type(exc).__name__}: {exc}{where}"
        row["wall_time_s"] = time.perf_counter() - t0
        row["cpu_time_s"] = time.process_time() - c0  # the worker's CPU: contention-free
        rows.append(row)
    return rows


def nominal_duration_s(cfg: CampaignConfig) -> float:
    """Simulated time of a case when the campaign does not set one: the scenario's."""
    if cfg.backend == "standin":
        return 20.0
    return float(_base_scenario(cfg.scenario).duration_s)


def command_timeline_deg(cfg: CampaignConfig) -> tuple[np.ndarray, np.ndarray]:
    """The scenario's command timeline: (times s (k,), commands deg (k, 3) alpha/beta/mu)."""
    if cfg.backend == "standin":
        return np.array([0.0]), np.array([[5.0, 0.0, 4.0]])
    from hyfc_wire.timeline import command_arrays
    t, cmd_rad = command_arrays(_base_scenario(cfg.scenario).commands)
    return np.asarray(t, float), np.degrees(np.asarray(cmd_rad, float))


#: the sources whose contents decide a case's result (fingerprinted into campaign.json)
_CODE_GLOBS = ("hyfc_wire/*.py", "fc/control/*.py", "fc/control/data/*", "plant_sim/*.py",
               "plant_sim/scenarios/*", "tools/sitl/closed_loop/core.py", "tools/sitl/metrics.py",
               "tools/evidence/montecarlo/case.py", "tools/evidence/montecarlo/apply.py",
               "tools/evidence/montecarlo/dispersions.py", "tools/evidence/montecarlo/flight.py")


def code_fingerprint() -> str:
    """Hash of the law's, the plant's and the case code's sources (16 hex digits).

    Stored with a campaign: ``rerun`` and a resume compare it, so a difference between a row
    and its re-run can be told apart from a change of the code in between.
    """
    from pathlib import Path
    root = Path(__file__).resolve().parents[3]
    h = hashlib.sha256()
    for pattern in _CODE_GLOBS:
        for f in sorted(root.glob(pattern)):
            if f.is_file():
                h.update(str(f.relative_to(root)).encode())
                h.update(f.read_bytes())
    return h.hexdigest()[:16]

