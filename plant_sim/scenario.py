"""Scenario files: TOML under plant_sim/scenarios/NAME.toml, strictly validated.

``load(name_or_path) -> Scenario``. Every key of the schema below has a default, a unit in its
name and a range; unknown keys, wrong types and out-of-range values raise ``ScenarioError``
with a message naming the file and the dotted key. The command timeline is a list of
``[[command]]`` tables ``{ t_s, alpha_deg, beta_deg, mu_deg }`` (architecture.md section 7),
read as every reader reads it (hyfc_wire.timeline: sorted by t_s, a left-out angle holds).
Degrees only here, at the edge; ``Scenario`` exposes SI helpers.
"""
from __future__ import annotations

import math
import os
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hyfc_wire.timeline import COMMAND, TARGET, TableSpec, TimelineError, read_entries, rows
from plant_sim import vehicle

SCENARIO_DIR = Path(__file__).resolve().parent / "scenarios"


class ScenarioError(ValueError):
    """A scenario file is missing, malformed or has a bad key/value (message names the key)."""


@dataclass(frozen=True)
class Key:
    kind: str                 # "float", "int", "bool", "str", "vec3"
    default: Any
    lo: float | None = None
    hi: float | None = None
    choices: tuple = ()
    doc: str = ""


INF = math.inf

SCHEMA: dict[str, Any] = {
    "name": Key("str", "", doc="scenario name"),
    "description": Key("str", "", doc="one-line description"),
    "flight_mode": Key("str", "attitude", choices=("attitude", "CRUISE", "GUIDED"),
                       doc="the controller's flight mode tools.hil flies it in by default: "
                           "attitude (COORDINATED/UNCOORDINATED), CRUISE or GUIDED; the plant "
                           "ignores it"),
    "seed": Key("int", 1, 0, 2**63 - 1, doc="seed of the sensor-noise generator"),
    "duration_s": Key("float", 20.0, 0.001, 1e6, doc="run length (sim time)"),
    "timing": {
        "physics_hz": Key("float", 1000.0, 10.0, 1e6, doc="RK4 step rate"),
        "frame_hz": Key("float", 500.0, 1.0, 1e5,
                        doc="sensor frame / exchange rate; physics_hz must be an integer multiple"),
    },
    "initial": {
        "V_m_s": Key("float", 2200.0, 100.0, 8000.0, doc="airspeed"),
        "h_m": Key("float", 21000.0, 0.0, 80000.0, doc="altitude (geometric)"),
        "alpha_deg": Key("float", 1.0, -10.0, 30.0, doc="angle of attack"),
        "beta_deg": Key("float", 0.0, -20.0, 20.0, doc="sideslip"),
        "mu_deg": Key("float", 0.0, -90.0, 90.0, doc="bank angle about the velocity"),
        "gamma_deg": Key("float", 0.0, -45.0, 45.0, doc="flight-path angle"),
        "chi_deg": Key("float", 0.0, -360.0, 360.0, doc="heading of the velocity"),
        "p_deg_s": Key("float", 0.0, -180.0, 180.0, doc="body roll rate"),
        "q_deg_s": Key("float", 0.0, -180.0, 180.0, doc="body pitch rate"),
        "r_deg_s": Key("float", 0.0, -180.0, 180.0, doc="body yaw rate"),
    },
    "vehicle": {
        "mass_kg": Key("float", vehicle.MASS_KG, 1000.0, 1e7),
        "Ixx_kg_m2": Key("float", vehicle.IXX_KG_M2, 1.0, 1e10),
        "Iyy_kg_m2": Key("float", vehicle.IYY_KG_M2, 1.0, 1e10),
        "Izz_kg_m2": Key("float", vehicle.IZZ_KG_M2, 1.0, 1e10),
        "Ixz_kg_m2": Key("float", vehicle.IXZ_KG_M2, -1e9, 1e9),
        "x_cg_m": Key("float", 0.0, -10.0, 10.0, doc="MRC -> c.g. distance, + aft"),
    },
    "speed": {
        "model": Key("str", "hold", choices=("hold", "none", "engine"),
                     doc="hold: thrust along body x holds V_ref; none: no thrust, V decays; "
                         "engine: thrust from the throttle command (SERVO_OUTPUT_RAW servo4)"),
        "V_ref_m_s": Key("float", 0.0, 0.0, 8000.0, doc="held speed; 0 = the initial V"),
        "k_1_s": Key("float", 0.5, 0.0, 100.0, doc="speed-hold gain"),
        "thrust_max_N": Key("float", 1.468e6, 0.0, 1e8, doc="330,000 lbf (S2 engine deck)"),
        "thrust_coef_max": Key("float", 0.02576, 0.0, 1.0,
                               doc="engine: C_T at full throttle, T = thr C_T qbar S (Wang & "
                                   "Stengel 2000), capped at thrust_max_N"),
        "throttle_tau_s": Key("float", 0.5, 0.0, 100.0, doc="engine: first-order lag; 0 = none"),
        "throttle_rate_1_s": Key("float", 0.0, 0.0, 1000.0,
                                 doc="engine: throttle rate limit (per s); 0 = none"),
        "throttle_initial": Key("float", -1.0, -1.0, 1.0,
                                doc="engine: throttle position and command at t = 0 (0..1); -1 = "
                                    "the throttle that balances drag and gravity at the initial "
                                    "state"),
    },
    "uncertainty": {
        # coefficient used = (1 + value) x model
        "CL": Key("float", 0.0, -0.9, 5.0),
        "CD": Key("float", 0.0, -0.9, 5.0),
        "CY": Key("float", 0.0, -0.9, 5.0),
        "Cl": Key("float", 0.0, -0.9, 5.0),
        "Cm": Key("float", 0.0, -0.9, 5.0),
        "Cn": Key("float", 0.0, -0.9, 5.0),
    },
    "disturbance": {
        "enabled": Key("bool", False),
        "amplitude": Key("float", 10.0, 0.0, 1e9, doc="A in A [0.5 sin 1.5t, 0.5 cos 2t, 0.5 sin 2t]"),
        "unit": Key("str", "deg/s^2", choices=("deg/s^2", "rad/s^2", "N*m"),
                    doc="angular acceleration, or a moment divided by the inertia"),
        "scale": Key("float", 1.0, 0.0, 1e6, doc="factor on the amplitude"),
        "phase_roll_deg": Key("float", 0.0, -360.0, 360.0, doc="phase added to the roll term's sine argument"),
        "phase_pitch_deg": Key("float", 0.0, -360.0, 360.0, doc="phase added to the pitch term's cosine argument"),
        "phase_yaw_deg": Key("float", 0.0, -360.0, 360.0, doc="phase added to the yaw term's sine argument"),
        "qbar_ref_Pa": Key("float", 0.0, 0.0, 1e7,
                           doc="0: d(t) as given (the paper's); > 0: d(t) x qbar / qbar_ref_Pa, a "
                               "moment coefficient equal to d at this dynamic pressure"),
        "end_s": Key("float", 0.0, 0.0, 1e7,
                     doc="0: d(t) for the whole flight; > 0: d(t) = 0 from this sim time (s) on, "
                         "e.g. to tell a forced oscillation from a limit cycle"),
    },
    "actuators": {
        "limit_deg": Key("float", vehicle.DEFLECTION_MAX_DEG, 0.1, vehicle.DEFLECTION_MAX_DEG),
        "rate_limit_deg_s": Key("float", 90.0, 0.0, 1e5, doc="0 = no rate limit"),
        "tau_s": Key("float", 0.02, 0.0, 10.0, doc="first-order lag; 0 = none"),
        "initial": Key("str", "zero", choices=("zero", "trim"),
                       doc="surface positions at t = 0: zero, or the initial-state trim"),
    },
    "servo": {
        "pwm_min_us": Key("int", 1000, 500, 2500),
        "pwm_trim_us": Key("int", 1500, 500, 2500),
        "pwm_max_us": Key("int", 2000, 500, 2500),
        "no_command_s": Key("float", 0.5, 0.0, 1e6,
                            doc="real time: after this long without SERVO_OUTPUT_RAW apply no_command"),
        "no_command": Key("str", "hold", choices=("hold", "trim"),
                          doc="hold the commands' recent mean (3 s), or go to the initial-state trim"),
        # the backup stability augmentation around the hold while the fc is silent
        # (plant_sim/hold.py, docs/plant.md s. 14); 0 = off, positive gains damp
        "backup_p_gain_s": Key("float", 0.0, 0.0, 10.0,
                               doc="differential elevon per measured roll rate (rad per rad/s)"),
        "backup_q_gain_s": Key("float", 0.0, 0.0, 10.0,
                               doc="symmetric elevon per measured pitch rate (rad per rad/s)"),
        "backup_r_gain_s": Key("float", 0.0, 0.0, 10.0,
                               doc="rudder per measured yaw rate (rad per rad/s)"),
        "backup_beta_gain": Key("float", 0.0, 0.0, 10.0,
                                doc="rudder per measured sideslip (rad per rad)"),
        "backup_authority_deg": Key("float", 5.0, 0.0, 20.0,
                                    doc="largest increment the damper adds to each surface"),
    },
    "sensors": {
        "enabled": Key("bool", True, doc="false: exact measurements (no noise, bias, latency)"),
        "noise": {
            "attitude_deg": Key("float", 0.0, 0.0, 90.0),
            "rate_deg_s": Key("float", 0.0, 0.0, 90.0),
            "aoa_deg": Key("float", 0.0, 0.0, 90.0),
            "ssa_deg": Key("float", 0.0, 0.0, 90.0),
            "airspeed_m_s": Key("float", 0.0, 0.0, 1000.0),
            "alt_m": Key("float", 0.0, 0.0, 10000.0),
            "climb_m_s": Key("float", 0.0, 0.0, 1000.0),
            "groundspeed_m_s": Key("float", 0.0, 0.0, 1000.0),
            "heading_deg": Key("float", 0.0, 0.0, 90.0),
        },
        "bias": {
            "roll_deg": Key("float", 0.0, -90.0, 90.0),
            "pitch_deg": Key("float", 0.0, -90.0, 90.0),
            "yaw_deg": Key("float", 0.0, -180.0, 180.0),
            "p_deg_s": Key("float", 0.0, -90.0, 90.0),
            "q_deg_s": Key("float", 0.0, -90.0, 90.0),
            "r_deg_s": Key("float", 0.0, -90.0, 90.0),
            "aoa_deg": Key("float", 0.0, -90.0, 90.0),
            "ssa_deg": Key("float", 0.0, -90.0, 90.0),
            "airspeed_m_s": Key("float", 0.0, -1000.0, 1000.0),
            "alt_m": Key("float", 0.0, -10000.0, 10000.0),
            "climb_m_s": Key("float", 0.0, -1000.0, 1000.0),
        },
        "latency_s": {
            "ahrs": Key("float", 0.0, 0.0, 0.5, doc="attitude, rates and heading"),
            "air_data": Key("float", 0.0, 0.0, 0.5, doc="alpha, beta, airspeed, altitude, climb"),
            "gps": Key("float", 0.0, 0.0, 0.5, doc="groundspeed and the GNSS receiver"),
        },
    },
    "earth": {
        "model": Key("str", "flat", choices=("flat", "sphere"),
                     doc="flat: the paper's flat, non-rotating NED earth; sphere: a "
                         "non-rotating sphere of the WGS-84 mean radius, starting at the "
                         "gnss origin (docs/plant.md section 5a)"),
    },
    "gnss": {
        "enabled": Key("bool", True, doc="false: no GNSS sample on the wire (fc: no position)"),
        "rate_hz": Key("float", 10.0, 0.1, 100.0, doc="receiver rate (rounded to whole frames)"),
        "origin_lat_deg": Key("float", 34.9054, -89.0, 89.0,
                              doc="latitude of the NED origin (default: Edwards AFB range)"),
        "origin_lon_deg": Key("float", -117.8839, -180.0, 180.0, doc="longitude of the NED origin"),
        "origin_alt_m": Key("float", 0.0, -500.0, 10000.0,
                            doc="MSL altitude of the NED origin (down = 0); 0: GNSS alt = h"),
        "satellites": Key("int", 12, 0, 255, doc="satellites visible (reported)"),
        "noise": {
            "horizontal_m": Key("float", 1.5, 0.0, 1000.0, doc="north and east, 1 sigma"),
            "vertical_m": Key("float", 3.0, 0.0, 1000.0, doc="down, 1 sigma"),
            "velocity_m_s": Key("float", 0.1, 0.0, 100.0, doc="each NED axis, 1 sigma"),
        },
    },
}

#: The ``[[command]]`` and ``[[target]]`` timelines (guided scenarios: cruise, mission) belong
#: to the controller; the plant reads them with the contract's reader (hyfc_wire.timeline: one
#: meaning for every reader) and uses the commands only for the trim report.


def _check_value(where: str, key: Key, value: Any) -> Any:
    if key.kind == "float":
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ScenarioError(f"{where}: expected a number, got {value!r}")
        value = float(value)
        if not math.isfinite(value):
            raise ScenarioError(f"{where}: must be finite, got {value!r}")
    elif key.kind == "int":
        if isinstance(value, bool) or not isinstance(value, int):
            raise ScenarioError(f"{where}: expected an integer, got {value!r}")
    elif key.kind == "bool":
        if not isinstance(value, bool):
            raise ScenarioError(f"{where}: expected true or false, got {value!r}")
        return value
    elif key.kind == "str":
        if not isinstance(value, str):
            raise ScenarioError(f"{where}: expected a string, got {value!r}")
        if key.choices and value not in key.choices:
            raise ScenarioError(f"{where}: must be one of {', '.join(key.choices)}; got {value!r}")
        return value
    if key.lo is not None and value < key.lo:
        raise ScenarioError(f"{where}: {value!r} is below the minimum {key.lo!r}")
    if key.hi is not None and value > key.hi:
        raise ScenarioError(f"{where}: {value!r} is above the maximum {key.hi!r}")
    return value


def _apply(src: str, schema: dict, given: dict, prefix: str) -> dict:
    out: dict[str, Any] = {}
    for k in given:
        if k not in schema:
            dotted = prefix + k
            known = ", ".join(sorted(schema))
            raise ScenarioError(f"{src}: unknown key '{dotted}' (known here: {known})")
    for k, spec in schema.items():
        dotted = prefix + k
        if isinstance(spec, dict):
            sub = given.get(k, {})
            if not isinstance(sub, dict):
                raise ScenarioError(f"{src}: '{dotted}' must be a table")
            out[k] = _apply(src, spec, sub, dotted + ".")
        elif k in given:
            out[k] = _check_value(f"{src}: '{dotted}'", spec, given[k])
        else:
            out[k] = spec.default
    return out


@dataclass
class Scenario:
    """A validated scenario: ``data`` holds every key (defaults filled in), degrees as written."""
    name: str
    path: str
    data: dict
    commands: list = field(default_factory=list)   # [(t_s, alpha_deg, beta_deg, mu_deg)]
    targets: list = field(default_factory=list)    # [(t_s, alt_m, course_deg, speed_m_s)]

    def get(self, dotted: str) -> Any:
        node: Any = self.data
        for part in dotted.split("."):
            node = node[part]
        return node

    @property
    def duration_s(self) -> float:
        return float(self.data["duration_s"])

    @property
    def seed(self) -> int:
        return int(self.data["seed"])

    def command_at(self, t_s: float) -> tuple[float, float, float]:
        """Commanded (alpha, beta, mu) in rad at sim time ``t_s`` (last entry with t <= t_s)."""
        cur = (0.0, 0.0, 0.0)
        for t, a, b, m in self.commands:
            if t <= t_s:
                cur = (math.radians(a), math.radians(b), math.radians(m))
        return cur

    def to_toml(self) -> str:
        """The scenario as used (all keys, defaults filled in), as TOML text."""
        lines: list[str] = []

        def fmt(v: Any) -> str:
            if isinstance(v, bool):
                return "true" if v else "false"
            if isinstance(v, str):
                return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
            if isinstance(v, float):
                return repr(v)
            return str(v)

        def emit(d: dict, prefix: str) -> None:
            scalars = [(k, v) for k, v in d.items() if not isinstance(v, dict)]
            tables = [(k, v) for k, v in d.items() if isinstance(v, dict)]
            if prefix and scalars:
                lines.append(f"\n[{prefix}]")
            for k, v in scalars:
                lines.append(f"{k} = {fmt(v)}")
            for k, v in tables:
                emit(v, f"{prefix}.{k}" if prefix else k)

        emit(self.data, "")
        for t, a, b, m in self.commands:
            lines.append("\n[[command]]")
            lines.append(f"t_s = {float(t)!r}\nalpha_deg = {float(a)!r}\nbeta_deg = {float(b)!r}\n"
                         f"mu_deg = {float(m)!r}")
        for row in self.targets:
            lines.append("\n[[target]]")
            lines.extend(f"{k} = {float(v)!r}" for k, v in zip(TARGET.keys, row))
        return "\n".join(lines) + "\n"


def _resolve(name_or_path: str | os.PathLike) -> Path:
    s = str(name_or_path)
    p = Path(s)
    if p.suffix == ".toml" or os.sep in s or "/" in s:
        if not p.is_file():
            raise ScenarioError(f"scenario file not found: {s}")
        return p
    cand = SCENARIO_DIR / f"{s}.toml"
    if not cand.is_file():
        raise ScenarioError(f"unknown scenario '{s}' (shipped: {', '.join(list_names())})")
    return cand


def list_names() -> list[str]:
    """Names of the shipped scenarios."""
    return sorted(p.stem for p in SCENARIO_DIR.glob("*.toml"))


def parse(text: str, src: str = "<string>", name: str = "") -> Scenario:
    """Validate TOML text into a Scenario (``src`` names it in error messages)."""
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise ScenarioError(f"{src}: not valid TOML: {e}") from None
    cmds_raw = raw.pop("command", None)
    tgts_raw = raw.pop("target", None)
    data = _apply(src, SCHEMA, raw, "")
    commands = _timeline(src, cmds_raw, COMMAND)
    targets = _timeline(src, tgts_raw, TARGET)
    t = data["timing"]
    ratio = t["physics_hz"] / t["frame_hz"]
    if abs(ratio - round(ratio)) > 1e-9 or round(ratio) < 1:
        raise ScenarioError(f"{src}: 'timing.physics_hz' ({t['physics_hz']}) must be an integer "
                            f"multiple of 'timing.frame_hz' ({t['frame_hz']})")
    sv = data["servo"]
    if not sv["pwm_min_us"] < sv["pwm_trim_us"] < sv["pwm_max_us"]:
        raise ScenarioError(f"{src}: 'servo.pwm_min_us' < 'servo.pwm_trim_us' < 'servo.pwm_max_us' "
                            f"does not hold ({sv['pwm_min_us']}, {sv['pwm_trim_us']}, {sv['pwm_max_us']})")
    if not data["name"]:
        data["name"] = name or Path(src).stem
    return Scenario(name=data["name"], path=src, data=data, commands=commands, targets=targets)


def _timeline(src: str, raw: Any, spec: TableSpec) -> list:
    """The ``[[spec.name]]`` timeline as full rows (tuples in ``spec.keys`` order, file units)."""
    try:
        return rows(read_entries(raw, spec, src), spec, src)
    except TimelineError as e:
        raise ScenarioError(str(e)) from None


def load(name_or_path: str | os.PathLike) -> Scenario:
    """Load and validate a shipped scenario by name, or a TOML file by path."""
    p = _resolve(name_or_path)
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as e:
        raise ScenarioError(f"cannot read scenario {p}: {e}") from None
    return parse(text, src=str(p), name=p.stem)
