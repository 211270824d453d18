"""fc/timeline.py - the attitude-command timeline (``python -m fc --timeline FILE``).

A TOML file of ``[[command]]`` tables ``{ t_s, alpha_deg, beta_deg, mu_deg }`` as in the
scenario files (docs/architecture.md section 7), read by the contract's one reader
(hyfc_wire.timeline: checked, sorted by t_s). Each entry sets CMD_ALPHA_DEG, CMD_BETA_DEG,
CMD_MU_DEG when the sensor time stamp reaches ``t_s`` (deterministic in lockstep). A missing
angle keeps its current command.
"""
from __future__ import annotations

from dataclasses import dataclass

from hyfc_wire.timeline import read_file

__all__ = ["Command", "load_timeline", "Timeline"]

_PARAM_OF = (("alpha_deg", "CMD_ALPHA_DEG"), ("beta_deg", "CMD_BETA_DEG"), ("mu_deg", "CMD_MU_DEG"))


@dataclass(frozen=True, slots=True)
class Command:
    t_s: float
    values: tuple[tuple[str, float], ...]   # (parameter name, degrees)


def load_timeline(path: str) -> list[Command]:
    """Read and check a timeline, sorted by t_s; ValueError naming the file and the entry."""
    return [Command(e["t_s"], tuple((pname, e[key]) for key, pname in _PARAM_OF if key in e))
            for e in read_file(path)]


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
