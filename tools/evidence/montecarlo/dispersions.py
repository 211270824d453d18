"""Dispersion files: what a campaign varies, how, and within which bounds.

A dispersion file is TOML (``tools/evidence/dispersions/NAME.toml`` or any path). Each section groups
variables of one part of the plant; each variable is either a fixed value (a number, or a
boolean for switches) or a distribution table::

    [aero]
    CL = { dist = "uniform", low = 0.8, high = 1.2 }          # factor on the coefficient
    Cm = { dist = "normal", mean = 1.0, std = 0.1, low = 0.8, high = 1.2 }

    [initial]
    alpha_deg = { dist = "uniform", low = 0.5, high = 1.5 }

    [sensors]
    noise = true                                               # a switch

    [spec]                                                     # what counts as a success
    overshoot_max_pct = 30.0

Distributions
-------------
- ``uniform``: ``low``, ``high`` (``low < high``).
- ``normal``: ``mean``, ``std`` (> 0), optional ``low`` / ``high``: truncated to the bounds
  by inverse-CDF sampling (one uniform draw per value, never rejection), ``mean`` inside them.
- ``fixed``: ``value`` (same as writing the number directly).

Every variable has a unit in its name or is a dimensionless factor (``*_factor`` and the
aerodynamic coefficients, 1 = nominal), and a physical range (a factor > 0, a time constant
>= 0, ...). Unknown sections, unknown variables, unknown fields of a distribution, missing
fields, non-numbers and bounds outside the physical range are all rejected with a
:class:`DispersionError` that names the offending key (``aero.CL.low``).

Sampling
--------
Each variable of case ``i`` of a campaign with seed ``S`` is drawn from its own stream,
``SeedSequence(S, spawn_key=(i, 0, crc32(key)))``: a case re-runs alone with the same values,
and adding or removing a variable from the file does not change the others' draws. The plant's
own noise seed of the case is ``case_sim_seed(S, i)``; both variants of a case share it
(common random numbers, so the variants are compared on the same dispersed vehicle).
"""
from __future__ import annotations

import math
import tomllib
import zlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.special import ndtr, ndtri

#: Directory of the shipped dispersion files (``--dispersions paper`` finds ``paper.toml``).
SHIPPED_DIR = Path(__file__).resolve().parent.parent / "dispersions"


class DispersionError(ValueError):
    """A dispersion file is malformed; the message names the key at fault."""


@dataclass(frozen=True)
class Variable:
    """One quantity a dispersion file may set.

    Attributes
    ----------
    key : "section.name".
    unit : unit of the values written in the file ("1" for factors, "deg", "deg/s", "m", "s").
    description : one line for docs and errors.
    lo, hi : physical range of the value (inclusive unless ``lo_open``).
    lo_open : the lower bound is exclusive (factors must be > 0).
    is_switch : a boolean on/off switch (fixed only).
    """

    key: str
    unit: str
    description: str
    lo: float = -math.inf
    hi: float = math.inf
    lo_open: bool = False
    is_switch: bool = False

    def check_range(self, x: float, where: str) -> None:
        if not math.isfinite(x):
            raise DispersionError(f"{where}: {x!r} is not a finite number")
        if x < self.lo or (self.lo_open and x <= self.lo) or x > self.hi:
            lo = "(" if self.lo_open else "["
            raise DispersionError(
                f"{where} = {x!r} is outside the physical range {lo}{self.lo}, {self.hi}] "
                f"of {self.key} ({self.description}, unit {self.unit})")


# Aerodynamic coefficients the plant can scale: the six totals (forces CL, CD, CY; moments
# Cl, Cm, Cn). A factor multiplies the whole coefficient (all its terms, control increments
# included), as the paper's "+-20 % on the aerodynamic coefficients" does.
AERO_COEFFICIENTS = ("CL", "CD", "CY", "Cl", "Cm", "Cn")

_VARIABLES: tuple[Variable, ...] = (
    *(Variable(f"aero.{c}", "1", f"factor on the aerodynamic coefficient {c}", lo=0.0,
               hi=10.0, lo_open=True) for c in AERO_COEFFICIENTS),
    Variable("mass.mass_factor", "1", "factor on the vehicle mass", 0.0, 10.0, True),
    Variable("mass.ixx_factor", "1", "factor on Ixx", 0.0, 10.0, True),
    Variable("mass.iyy_factor", "1", "factor on Iyy", 0.0, 10.0, True),
    Variable("mass.izz_factor", "1", "factor on Izz", 0.0, 10.0, True),
    Variable("mass.x_cg_m", "m", "moment reference centre to c.g., positive aft", -20.0, 20.0),
    Variable("initial.alpha_deg", "deg", "initial angle of attack", -30.0, 30.0),
    Variable("initial.beta_deg", "deg", "initial sideslip", -30.0, 30.0),
    Variable("initial.mu_deg", "deg", "initial bank about the velocity vector", -90.0, 90.0),
    Variable("initial.p_deg_s", "deg/s", "initial body roll rate", -180.0, 180.0),
    Variable("initial.q_deg_s", "deg/s", "initial body pitch rate", -180.0, 180.0),
    Variable("initial.r_deg_s", "deg/s", "initial body yaw rate", -180.0, 180.0),
    Variable("disturbance.amplitude_factor", "1",
             "factor on the scenario's disturbance amplitude (0 = off)", 0.0, 100.0),
    Variable("disturbance.phase_roll_deg", "deg", "phase added to the roll disturbance",
             -360.0, 360.0),
    Variable("disturbance.phase_pitch_deg", "deg", "phase added to the pitch disturbance",
             -360.0, 360.0),
    Variable("disturbance.phase_yaw_deg", "deg", "phase added to the yaw disturbance",
             -360.0, 360.0),
    Variable("sensors.noise", "bool", "sensor noise on (true) or off (false)", is_switch=True),
    Variable("sensors.noise_factor", "1", "factor on every sensor noise standard deviation",
             0.0, 100.0),
    Variable("sensors.bias_alpha_deg", "deg", "bias of the angle-of-attack sensor", -10.0, 10.0),
    Variable("sensors.bias_beta_deg", "deg", "bias of the sideslip sensor", -10.0, 10.0),
    Variable("sensors.bias_roll_deg", "deg", "bias of the roll attitude", -10.0, 10.0),
    Variable("sensors.bias_pitch_deg", "deg", "bias of the pitch attitude", -10.0, 10.0),
    Variable("sensors.bias_yaw_deg", "deg", "bias of the yaw attitude", -10.0, 10.0),
    Variable("sensors.bias_p_deg_s", "deg/s", "bias of the roll-rate gyro", -10.0, 10.0),
    Variable("sensors.bias_q_deg_s", "deg/s", "bias of the pitch-rate gyro", -10.0, 10.0),
    Variable("sensors.bias_r_deg_s", "deg/s", "bias of the yaw-rate gyro", -10.0, 10.0),
    Variable("actuators.tau_s", "s", "first-order lag time constant of every surface", 0.0, 1.0),
    Variable("actuators.rate_max_deg_s", "deg/s", "rate limit of every surface", 0.0, 10000.0,
             True),
)

#: Every variable a dispersion file may set, by key.
VARIABLES: dict[str, Variable] = {v.key: v for v in _VARIABLES}
SECTIONS = tuple(dict.fromkeys(k.split(".")[0] for k in VARIABLES))

_DIST_FIELDS = {
    "uniform": ({"low", "high"}, set()),
    "normal": ({"mean", "std"}, {"low", "high"}),
    "fixed": ({"value"}, set()),
}

# The specification a case must meet to count as a success. Scalars apply to all three
# channels; a table {alpha = .., beta = .., mu = ..} sets channels one by one.
CHANNELS = ("alpha", "beta", "mu")
SPEC_DEFAULTS = {
    "overshoot_max_pct": 30.0,
    "settling_max_s": 5.0,
    "final_error_max_deg": 0.2,
}


@dataclass(frozen=True)
class Distribution:
    """How one variable is drawn (``kind`` uniform / normal / fixed)."""

    key: str
    kind: str
    low: float = math.nan
    high: float = math.nan
    mean: float = math.nan
    std: float = math.nan
    value: float = math.nan

    def sample(self, rng: np.random.Generator) -> float:
        """Draw one value (exactly one uniform draw from ``rng`` unless fixed)."""
        if self.kind == "fixed":
            return self.value
        u = float(rng.random())
        if self.kind == "uniform":
            return self.low + u * (self.high - self.low)
        # truncated normal by inverse CDF: u mapped into [Phi(a), Phi(b)]
        a = -math.inf if math.isnan(self.low) else (self.low - self.mean) / self.std
        b = math.inf if math.isnan(self.high) else (self.high - self.mean) / self.std
        pa, pb = float(ndtr(a)), float(ndtr(b))
        x = self.mean + self.std * float(ndtri(pa + u * (pb - pa)))
        if not math.isnan(self.low):
            x = max(x, self.low)
        if not math.isnan(self.high):
            x = min(x, self.high)
        return x

    def describe(self) -> str:
        if self.kind == "fixed":
            return f"{self.value:g}"
        if self.kind == "uniform":
            return f"U[{self.low:g}, {self.high:g}]"
        s = f"N({self.mean:g}, {self.std:g})"
        if not (math.isnan(self.low) and math.isnan(self.high)):
            s += f" in [{self.low:g}, {self.high:g}]"
        return s


@dataclass(frozen=True)
class Dispersions:
    """A validated dispersion file.

    Attributes
    ----------
    name : the file's stem (``paper``) or ``[campaign] name``.
    description : ``[campaign] description`` (free text).
    dists : variable key -> Distribution, in file order.
    spec : success specification, ``{metric: {channel: limit}}`` (see SPEC_DEFAULTS).
    source_text : the file's text as read (kept in the campaign directory).
    """

    name: str
    description: str
    dists: dict[str, Distribution]
    spec: dict[str, dict[str, float]]
    source_text: str = field(repr=False, default="")

    @property
    def random_keys(self) -> list[str]:
        """Keys drawn at random (not fixed), in file order: the columns worth plotting."""
        return [k for k, d in self.dists.items() if d.kind != "fixed"]

    def sample(self, campaign_seed: int, case_index: int) -> dict[str, float]:
        """The values of case ``case_index`` (key -> value in the file's unit)."""
        out = {}
        for key, dist in self.dists.items():
            out[key] = dist.sample(variable_rng(campaign_seed, case_index, key))
        return out


def variable_rng(campaign_seed: int, case_index: int, key: str) -> np.random.Generator:
    """The independent random stream of one variable of one case."""
    ss = np.random.SeedSequence(int(campaign_seed),
                                spawn_key=(int(case_index), 0, zlib.crc32(key.encode())))
    return np.random.Generator(np.random.PCG64(ss))


def case_sim_seed(campaign_seed: int, case_index: int) -> int:
    """Seed of the plant's own randomness (sensor noise) for case ``case_index``."""
    ss = np.random.SeedSequence(int(campaign_seed), spawn_key=(int(case_index), 1))
    return int(ss.generate_state(1, np.uint32)[0])


def _num(x, where: str) -> float:
    if isinstance(x, bool) or not isinstance(x, (int, float)):
        raise DispersionError(f"{where}: expected a number, got {x!r}")
    x = float(x)
    if not math.isfinite(x):
        raise DispersionError(f"{where}: {x!r} is not a finite number")
    return x


def _parse_dist(key: str, raw, var: Variable) -> Distribution:
    if var.is_switch:
        if not isinstance(raw, bool):
            raise DispersionError(f"{key}: a switch takes true or false, got {raw!r}")
        return Distribution(key, "fixed", value=1.0 if raw else 0.0)
    if not isinstance(raw, dict):
        x = _num(raw, key)
        var.check_range(x, key)
        return Distribution(key, "fixed", value=x)
    if "dist" not in raw:
        raise DispersionError(f"{key}: a distribution table needs 'dist' "
                              f"(one of {', '.join(_DIST_FIELDS)})")
    kind = raw["dist"]
    if kind not in _DIST_FIELDS:
        raise DispersionError(f"{key}.dist: unknown distribution {kind!r} "
                              f"(expected one of {', '.join(_DIST_FIELDS)})")
    required, optional = _DIST_FIELDS[kind]
    given = set(raw) - {"dist"}
    unknown = given - required - optional
    if unknown:
        bad = sorted(unknown)[0]
        raise DispersionError(f"{key}.{bad}: unknown field for a {kind} distribution "
                              f"(allowed: {', '.join(sorted(required | optional))})")
    missing = required - given
    if missing:
        raise DispersionError(f"{key}: a {kind} distribution needs "
                              f"{', '.join(sorted(missing))}")
    vals = {f: _num(raw[f], f"{key}.{f}") for f in given}
    for f in ("low", "high", "mean", "value"):
        if f in vals:
            var.check_range(vals[f], f"{key}.{f}")
    if kind == "uniform":
        if not vals["low"] < vals["high"]:
            raise DispersionError(f"{key}: low ({vals['low']:g}) must be below high "
                                  f"({vals['high']:g})")
    elif kind == "normal":
        if not vals["std"] > 0.0:
            raise DispersionError(f"{key}.std: must be > 0, got {vals['std']:g}")
        lo, hi = vals.get("low", -math.inf), vals.get("high", math.inf)
        if not lo < hi:
            raise DispersionError(f"{key}: low ({lo:g}) must be below high ({hi:g})")
        if not lo <= vals["mean"] <= hi:
            raise DispersionError(f"{key}.mean: {vals['mean']:g} is outside [low, high] = "
                                  f"[{lo:g}, {hi:g}]")
        # an unbounded side of a normal may cross the physical range: require a bound there
        for side, bound, phys in (("low", lo, var.lo), ("high", hi, var.hi)):
            if math.isinf(bound) and math.isfinite(phys):
                raise DispersionError(
                    f"{key}: a normal distribution of {var.key} needs '{side}' (the value "
                    f"must stay within the physical range [{var.lo:g}, {var.hi:g}])")
    return Distribution(key, kind, **vals)


def _parse_spec(raw) -> dict[str, dict[str, float]]:
    if not isinstance(raw, dict):
        raise DispersionError("spec: must be a table")
    spec = {m: {c: v for c in CHANNELS} for m, v in SPEC_DEFAULTS.items()}
    for metric, val in raw.items():
        where = f"spec.{metric}"
        if metric not in SPEC_DEFAULTS:
            raise DispersionError(f"{where}: unknown specification "
                                  f"(allowed: {', '.join(SPEC_DEFAULTS)})")
        if isinstance(val, dict):
            for ch, lim in val.items():
                if ch not in CHANNELS:
                    raise DispersionError(f"{where}.{ch}: unknown channel "
                                          f"(allowed: {', '.join(CHANNELS)})")
                x = _num(lim, f"{where}.{ch}")
                if x < 0:
                    raise DispersionError(f"{where}.{ch}: must be >= 0, got {x:g}")
                spec[metric][ch] = x
        else:
            x = _num(val, where)
            if x < 0:
                raise DispersionError(f"{where}: must be >= 0, got {x:g}")
            spec[metric] = {c: x for c in CHANNELS}
    return spec


def parse(text: str, name: str = "dispersions") -> Dispersions:
    """Validate the TOML text of a dispersion file (see the module docstring)."""
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise DispersionError(f"{name}: not valid TOML: {exc}") from None
    description = ""
    spec = _parse_spec({})
    dists: dict[str, Distribution] = {}
    for section, body in doc.items():
        if section == "campaign":
            if not isinstance(body, dict):
                raise DispersionError("campaign: must be a table")
            for k, v in body.items():
                if k not in ("name", "description") or not isinstance(v, str):
                    raise DispersionError(f"campaign.{k}: unknown key or not a string "
                                          "(allowed: name, description)")
            name = body.get("name", name)
            description = body.get("description", "")
            continue
        if section == "spec":
            spec = _parse_spec(body)
            continue
        if section not in SECTIONS:
            raise DispersionError(f"{section}: unknown section (allowed: campaign, spec, "
                                  f"{', '.join(SECTIONS)})")
        if not isinstance(body, dict):
            raise DispersionError(f"{section}: must be a table of variables")
        for var_name, raw in body.items():
            key = f"{section}.{var_name}"
            if key not in VARIABLES:
                allowed = [k.split(".", 1)[1] for k in VARIABLES if k.startswith(section + ".")]
                raise DispersionError(f"{key}: unknown variable (allowed in [{section}]: "
                                      f"{', '.join(allowed)})")
            dists[key] = _parse_dist(key, raw, VARIABLES[key])
    return Dispersions(name=name, description=description, dists=dists, spec=spec,
                       source_text=text)


def resolve_path(name_or_path: str | Path) -> Path:
    """A shipped name (``paper``) or a path to a TOML file."""
    p = Path(name_or_path)
    if p.suffix == ".toml" or p.exists():
        if not p.is_file():
            raise DispersionError(f"dispersion file {p} does not exist")
        return p
    shipped = SHIPPED_DIR / f"{name_or_path}.toml"
    if shipped.is_file():
        return shipped
    names = sorted(q.stem for q in SHIPPED_DIR.glob("*.toml"))
    raise DispersionError(f"no dispersion file {name_or_path!r} (not a path; shipped: "
                          f"{', '.join(names) or 'none'})")


def load(name_or_path: str | Path) -> Dispersions:
    """Load and validate a dispersion file by shipped name or path."""
    path = resolve_path(name_or_path)
    return parse(path.read_text(), name=path.stem)


def nominal(name: str = "nominal") -> Dispersions:
    """No dispersion at all (every case flies the scenario as written)."""
    return parse("", name=name)
