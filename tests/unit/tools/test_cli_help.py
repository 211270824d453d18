"""Every option of every command line has help text (issue 12 point 7).

The entry points are found, not listed: every ``python -m`` module of fc/, plant_sim/ and
tools/ (a package's ``__main__.py`` or a module with ``if __name__ == "__main__"``). Each is run
as ``__main__`` with ``ArgumentParser.parse_args`` replaced by a stand-in that hands back the
parser instead of parsing, so nothing else runs; the walk then follows every subcommand.
Commands a module dispatches by hand before its parser (``tools.evidence.montecarlo rerun`` ...) are
named in ``DISPATCHED``.
"""
from __future__ import annotations

import argparse
import runpy
import sys
import warnings
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[3]
PACKAGES = ("fc", "plant_sim", "tools")
#: subcommands chosen by argv[0] before any parser is built: module -> argv prefixes
DISPATCHED = {"tools.evidence.montecarlo": [[], ["rerun"], ["summary"], ["compare"]],
              "tools.bench": [[], ["law"], ["plant"], ["pingpong"], ["fc-timing"], ["campaign"]]}


def entry_points() -> list[str]:
    """Module names that ``python -m`` runs, below PACKAGES."""
    mods = []
    for pkg in PACKAGES:
        for path in sorted((ROOT / pkg).rglob("*.py")):
            rel = path.relative_to(ROOT).with_suffix("")
            if "control" in rel.parts or "__pycache__" in rel.parts:
                continue
            text = path.read_text(errors="replace")
            if path.name == "__main__.py":
                mods.append(".".join(rel.parts[:-1]))
            elif 'if __name__ == "__main__"' in text and path.name != "__init__.py":
                mods.append(".".join(rel.parts))
    return mods


class _Captured(Exception):
    def __init__(self, parser):
        super().__init__(parser.prog)
        self.parser = parser


def parsers_of(module: str, argv: list[str], monkeypatch) -> argparse.ArgumentParser | None:
    """The parser ``python -m module *argv`` builds (None if it builds none)."""
    def capture(self, args=None, namespace=None):
        raise _Captured(self)

    monkeypatch.setattr(argparse.ArgumentParser, "parse_args", capture)
    monkeypatch.setattr(argparse.ArgumentParser, "parse_known_args", capture)
    monkeypatch.setattr(sys, "argv", [module, *argv])
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)   # runpy: already imported
            runpy.run_module(module, run_name="__main__", alter_sys=False)
    except _Captured as c:
        return c.parser
    except SystemExit:
        return None
    return None


def undocumented(parser: argparse.ArgumentParser, where: str) -> list[str]:
    """Options and positionals of ``parser`` and its subcommands without help text."""
    missing = []
    for a in parser._actions:
        if isinstance(a, argparse._HelpAction):
            continue
        if isinstance(a, argparse._SubParsersAction):
            helped = {c.dest for c in a._choices_actions if c.help}
            for name, sub in a.choices.items():
                if name not in helped:
                    missing.append(f"{where} {name} (subcommand)")
                missing += undocumented(sub, f"{where} {name}")
            continue
        if a.help == argparse.SUPPRESS:
            continue
        if not (a.help or "").strip():
            missing.append(f"{where} {'/'.join(a.option_strings) or a.dest}")
    return missing


def test_entry_points_are_found():
    mods = set(entry_points())
    assert {"fc", "plant_sim", "tools.hil", "tools.evidence.montecarlo", "tools.soak", "tools.fuzz",
            "tools.relay", "tools.bench", "tools.fly", "tools.evidence.margins"} <= mods, sorted(mods)


@pytest.mark.parametrize("module", entry_points())
def test_every_option_has_help_text(module, monkeypatch):
    missing = []
    for argv in DISPATCHED.get(module, [[]]):
        where = " ".join(["python -m", module, *argv])
        parser = parsers_of(module, argv, monkeypatch)
        assert parser is not None, f"{where} builds no argparse parser (no --help)"
        missing += undocumented(parser, where)
    assert not missing, "options without help text:\n" + "\n".join(missing)
