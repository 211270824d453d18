"""Re-runnable rule that files flat ``tests/test_*.py`` into the tiers and parts.

    python tests/refile.py            # git mv every flat tests/test_*.py to its folder
    python tests/refile.py --dry-run  # print where each would go

The rule (first match wins), documented in tests/README.md:

1. a file that marks any test ``pytest.mark.hil`` (real processes over loopback UDP) -> ``hil/``;
2. otherwise by name prefix, ``PREFIXES`` below -> ``unit/<part>/``.

A flat file no rule matches is left where it is and reported (exit code 1): add a prefix. After
the move, ``Path(__file__).resolve().parents[1]`` (the repository root seen from tests/) is
rewritten to the index of the file's new depth, so ROOT-relative paths keep working.
"""
from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

TESTS = Path(__file__).resolve().parent

#: (file name prefix, folder under tests/) for unit-tier files; first match wins
PREFIXES: tuple[tuple[str, str], ...] = (
    ("test_architecture", "unit"),          # the whole repository's import direction
    ("test_fc_link", "unit/wire"),          # the MAVLink contract between the two processes
    ("test_plant_link", "unit/wire"),
    ("test_throttle_wire", "unit/wire"),
    ("test_wire", "unit/wire"),
    ("test_law", "unit/control"),           # fc/control: the pure attitude law
    ("test_guidance", "unit/control"),      # fc/guidance: the pure outer loop
    ("test_waypoints", "unit/control"),     # fc/guidance/waypoints.py: pure navigation
    ("test_mission_", "unit/fc"),           # fc/mission.py: the mission protocol
    ("test_control", "unit/control"),
    ("test_fc_", "unit/fc"),                # the controller process's parts, in process
    ("test_frame_gate", "unit/fc"),
    ("test_gcs_", "unit/fc"),
    ("test_plant_", "unit/plant"),          # plant_sim, in process
    ("test_aero", "unit/plant"),
    ("test_atmosphere", "unit/plant"),
    ("test_", "unit/tools"),                # everything else is a tool's (tools/) unit test
)

_HIL = re.compile(r"pytest\.mark\.hil\b")
_ROOT = "Path(__file__).resolve().parents[1]"


def destination(path: Path) -> str | None:
    """Folder (relative to tests/) a flat test file belongs in, None if no rule matches."""
    if _HIL.search(path.read_text(errors="replace")):
        return "hil"
    for prefix, folder in PREFIXES:
        if path.name.startswith(prefix):
            return folder
    return None


def refile(dry_run: bool = False) -> int:
    unmatched = []
    for path in sorted(TESTS.glob("test_*.py")):
        folder = destination(path)
        if folder is None:
            unmatched.append(path.name)
            continue
        target = TESTS / folder / path.name
        print(f"{path.relative_to(TESTS.parent)} -> {target.relative_to(TESTS.parent)}")
        if dry_run:
            continue
        for d in [TESTS / folder, *(TESTS / folder).parents]:
            if d == TESTS:
                break
            d.mkdir(exist_ok=True)
            (d / "__init__.py").touch()
        subprocess.run(["git", "mv", str(path), str(target)], check=True, cwd=TESTS.parent)
        depth = len(target.relative_to(TESTS.parent).parts) - 1     # folders below the root
        text = target.read_text()
        if _ROOT in text:
            target.write_text(text.replace(_ROOT, f"Path(__file__).resolve().parents[{depth}]"))
    for name in unmatched:
        print(f"tests/{name}: no rule matches; add a prefix to tests/refile.py", file=sys.stderr)
    return 1 if unmatched else 0


if __name__ == "__main__":
    raise SystemExit(refile("--dry-run" in sys.argv[1:]))
