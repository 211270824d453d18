"""fc/timeline.py - the attitude-command timeline (``python -m fc --timeline FILE``).

A TOML file of ``[[command]]`` tables ``{ t_s, alpha_deg, beta_deg, mu_deg }`` as in the
scenario files (docs/architecture.md section 7). Each entry sets CMD_ALPHA_DEG, CMD_BETA_DEG,
CMD_MU_DEG when the sensor time stamp reaches ``t_s`` (deterministic in lockstep). A missing
angle keeps its current command.
"""
from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass

__all__ = ["Command", "load_timeline", "Timeline"]

_KEYS = {"t_s", "alpha_deg", "beta_deg", "mu_deg"}
_PARAM_OF = (("alpha_deg", "CMD_ALPHA_DEG"), ("beta_deg", "CMD_BETA_DEG"), ("mu_deg", "CMD_MU_DEG"))


@dataclass(frozen=True, slots=True)
class Command:
    t_s: float
    values: tuple[tuple[str, float], ...]   # (parameter name, degrees)


def load_timeline(path: str) -> list[Command]:
    """Read and check a timeline; ValueError naming the entry on any problem."""
    with open(path, "rb") as f:
        try:
            data = tomllib.load(f)
        except tomllib.TOMLDecodeError as exc:
            raise ValueError(f"{path}: not valid TOML: {exc}") from None
    entries = data.get("command", [])
    if not isinstance(entries, list):
        raise ValueError(f"{path}: 'command' must be an array of tables ([[command]])")
    out: list[Command] = []
    for k, e in enumerate(entries):
        if not isinstance(e, dict) or "t_s" not in e:
            raise ValueError(f"{path}: command #{k} needs t_s")
        extra = set(e) - _KEYS
        if extra:
            raise ValueError(f"{path}: command #{k} has unknown keys {sorted(extra)}")
        vals = []
        for key, pname in _PARAM_OF:
            if key in e:
                v = float(e[key])
                if not math.isfinite(v):
                    raise ValueError(f"{path}: command #{k} {key} is not finite")
                vals.append((pname, v))
        t = float(e["t_s"])
        if not math.isfinite(t):
            raise ValueError(f"{path}: command #{k} t_s is not finite")
        out.append(Command(t, tuple(vals)))
    out.sort(key=lambda c: c.t_s)
    return out


class Timeline:
    """Cursor over a sorted command list: ``due(t_s)`` yields commands whose time has come."""

    def __init__(self, commands: list[Command]) -> None:
        self.commands = commands
        self.next = 0

    def due(self, t_s: float) -> list[Command]:
        out = []
        while self.next < len(self.commands) and self.commands[self.next].t_s <= t_s + 1e-9:
            out.append(self.commands[self.next])
            self.next += 1
        return out
