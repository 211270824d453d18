"""The timelines a scenario (or ``python -m fc --timeline FILE``) carries: one reader, one meaning.

Two kinds of array of tables, in TOML:

- ``[[command]]`` ``{ t_s, alpha_deg, beta_deg, mu_deg }``: the attitude command the controller
  is to fly (docs/architecture.md section 7).
- ``[[target]]`` ``{ t_s, alt_m, course_deg, speed_m_s }``: the guidance targets of guided
  scenarios (docs/guidance.md).

The meaning, the same for every reader (the plant's scenario loader, the fc's timeline, the
tools):

1. ``t_s`` (sim time, s) is required in every entry; the other keys are optional. Every value
   is a finite number within the range of ``COMMAND.keys`` / ``TARGET.keys`` (file units:
   s, deg, m, m/s); an unknown key, a missing ``t_s`` or a bad value is an error
   (``TimelineError``, a ValueError naming the file and ``what[i].key``, ``i`` counted in
   file order).
2. The entries are sorted by ``t_s`` (stable: entries at the same time keep their file order).
3. An entry takes effect when the sim time reaches its ``t_s`` and holds until the next
   (zero-order hold). A key an entry leaves out keeps its previous value; before the first
   entry that sets it a key has its default (``COMMAND.defaults``: 0 deg, as the fc's
   CMD_*_DEG parameters). A target key has no default: the first target must give them all.
4. An empty (or absent) timeline is valid: ``[]``. As arrays (``command_arrays``) it is the
   defaults from t = 0; targets have no defaults, so an empty target timeline as arrays is an
   error.

``read_entries`` / ``read_file`` give the entries as written (dicts of the keys present, file
units) for readers that must know what an entry sets (the fc sets only those parameters);
``rows`` fills in the held values (tuples in ``keys`` order, file units); ``command_arrays``
and ``target_arrays`` give SI arrays for the in-process loops.
"""
from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field

import numpy as np

__all__ = ["TimelineError", "TableSpec", "COMMAND", "TARGET", "read_entries", "read_file",
           "rows", "command_arrays", "target_arrays"]


class TimelineError(ValueError):
    """A timeline that cannot be read; the message names the file and the entry."""


@dataclass(frozen=True)
class TableSpec:
    """One kind of timeline table: ``[[name]]`` with ``keys`` {key: (lo, hi)} in file units, the
    first being ``t_s``, and ``defaults`` {key: value before the first entry that sets it}."""

    name: str
    keys: dict
    defaults: dict = field(default_factory=dict)


COMMAND = TableSpec("command",
                    {"t_s": (0.0, 1e6), "alpha_deg": (-10.0, 30.0), "beta_deg": (-20.0, 20.0),
                     "mu_deg": (-90.0, 90.0)},
                    {"alpha_deg": 0.0, "beta_deg": 0.0, "mu_deg": 0.0})
TARGET = TableSpec("target",
                   {"t_s": (0.0, 1e6), "alt_m": (0.0, 80000.0), "course_deg": (-360.0, 360.0),
                    "speed_m_s": (100.0, 8000.0)})


def read_entries(raw, spec: TableSpec = COMMAND, src: str = "<timeline>") -> list[dict]:
    """Check the parsed TOML value of ``[[spec.name]]`` (None: absent) and return its entries
    sorted by ``t_s``: one dict per entry of the keys it gives, as floats in file units."""
    what = spec.name
    if raw is None:
        return []
    if not isinstance(raw, list):
        raise TimelineError(f"{src}: '{what}' must be an array of tables ([[{what}]])")
    out = []
    for i, entry in enumerate(raw):
        if not isinstance(entry, dict):
            raise TimelineError(f"{src}: {what}[{i}] must be a table")
        for k in entry:
            if k not in spec.keys:
                raise TimelineError(f"{src}: unknown key '{what}[{i}].{k}' "
                                    f"(known: {', '.join(spec.keys)})")
        if "t_s" not in entry:
            raise TimelineError(f"{src}: '{what}[{i}].t_s' is missing")
        row = {}
        for k, (lo, hi) in spec.keys.items():
            if k not in entry:
                continue
            v = entry[k]
            where = f"{src}: '{what}[{i}].{k}'"
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                raise TimelineError(f"{where}: expected a number, got {v!r}")
            v = float(v)
            if not math.isfinite(v):
                raise TimelineError(f"{where}: must be finite, got {v!r}")
            if not lo <= v <= hi:
                raise TimelineError(f"{where}: {v!r} is outside {lo!r}..{hi!r}")
            row[k] = v
        out.append(row)
    out.sort(key=lambda e: e["t_s"])
    return out


def read_file(path, spec: TableSpec = COMMAND) -> list[dict]:
    """``read_entries`` of the ``[[spec.name]]`` tables of the TOML file ``path`` (other tables
    are ignored: a scenario file is a valid timeline file)."""
    try:
        with open(path, "rb") as f:
            data = tomllib.load(f)
    except tomllib.TOMLDecodeError as exc:
        raise TimelineError(f"{path}: not valid TOML: {exc}") from None
    except OSError as exc:
        raise TimelineError(f"{path}: cannot read: {exc}") from None
    return read_entries(data.get(spec.name), spec, str(path))


def rows(entries: list[dict], spec: TableSpec = COMMAND, src: str = "<timeline>") -> list[tuple]:
    """The entries with every key filled in (held values, point 3): tuples in ``spec.keys``
    order, file units."""
    cur = dict(spec.defaults)
    out = []
    for i, e in enumerate(entries):
        cur.update(e)
        missing = [k for k in spec.keys if k not in cur]
        if missing:
            raise TimelineError(f"{src}: '{spec.name}[{i}].{missing[0]}' is missing "
                                f"(the first {spec.name} must give it)")
        out.append(tuple(cur[k] for k in spec.keys))
    return out


def command_arrays(command_rows: list[tuple]) -> tuple[np.ndarray, np.ndarray]:
    """Full ``[[command]]`` rows (``rows``) as SI arrays: times (k,) s and commands (k, 3) rad
    (alpha, beta, mu). Empty: the defaults from t = 0 (one row)."""
    if not command_rows:
        command_rows = [(0.0,) + tuple(COMMAND.defaults[k] for k in list(COMMAND.keys)[1:])]
    c = np.array(command_rows, dtype=np.float64)
    return np.ascontiguousarray(c[:, 0]), np.ascontiguousarray(np.radians(c[:, 1:4]))


def target_arrays(target_rows: list[tuple], src: str = "<timeline>"
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Full ``[[target]]`` rows as SI arrays: times (k,) s and (k, 3) altitude m, course rad,
    speed m/s. Empty: TimelineError (a target has no default)."""
    if not target_rows:
        raise TimelineError(f"{src}: no [[target]] timeline (a target has no default)")
    c = np.array(target_rows, dtype=np.float64)
    tg = np.empty((len(c), 3))
    tg[:, 0] = c[:, 1]
    tg[:, 1] = np.radians(c[:, 2])
    tg[:, 2] = c[:, 3]
    return np.ascontiguousarray(c[:, 0]), tg
