"""The import direction of docs/architecture.md, enforced by walking every module's imports.

GIVEN every ``.py`` file of our packages (parsed with ``ast``, nothing is imported)
WHEN its ``import`` / ``from ... import`` statements are resolved to our modules
THEN no edge breaks a rule of ``ALLOWED``, the module-level imports form no cycle, and the
imports of ``NO_CYCLES``' packages form none either when deferred imports (inside functions)
count too.

The rules are data: ``ALLOWED`` maps a package to the packages of ours it may import (the
longest matching prefix wins); ``SHARED`` lists packages every one of ours may import and that
import nothing of ours but themselves (the wire contract: adding it is one line, e.g.
``SHARED = ("hyfc_wire",)``).
"""
from __future__ import annotations

import ast
import functools
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

#: packages anyone may import; they may import only themselves
SHARED: tuple[str, ...] = ("hyfc_wire",)

#: packages that may not import even the SHARED ones (the law stays pure)
PURE: tuple[str, ...] = ("fc.control",)

#: packages whose modules may not import each other in a circle even through deferred imports
#: (a cycle hidden in a function body is still two modules that need each other: the shared
#: piece goes into a third module both import, e.g. fc/mission_params.py, tools/evidence/margins/flight.py)
NO_CYCLES: tuple[str, ...] = ("fc", "plant_sim", "hyfc_wire", "tools")

#: package -> packages of ours it may import (itself always; SHARED always)
ALLOWED: dict[str, tuple[str, ...]] = {
    "fc.control": (),                      # the pure law: nothing of ours outside it
    "fc.guidance": ("fc.control",),        # the pure outer loop: itself and the law's layout
    "fc": (),                              # never plant_sim, tools or tests
    "plant_sim": (),                       # never fc, tools or tests
    "tools.sitl": ("fc", "plant_sim"),     # the harness: libraries, no command, no evidence
    "tools.evidence": ("fc", "plant_sim", "tools.sitl"),   # the evidence tools: never a command
    "tools": ("fc", "plant_sim"),          # the commands: never tests (see COMMANDS below)
    "tests": ("fc", "plant_sim", "tools"),
}

#: the commands live under this package; everything below it except LIBRARIES is a command
#: unit (``tools.hil``, ``tools.bench``, ``tools.soak``, ...), which may import the LIBRARIES and
#: its own modules, never another command unit (docs/architecture.md section 1)
COMMANDS = "tools"
LIBRARIES: tuple[str, ...] = ("tools.sitl", "tools.evidence")


def our_packages() -> list[str]:
    """Top-level packages of the repository (directories with an ``__init__.py``)."""
    return sorted(p.name for p in ROOT.iterdir() if (p / "__init__.py").is_file())


def module_files() -> dict[str, Path]:
    """Dotted module name -> file, for every module of our packages."""
    out = {}
    for pkg in our_packages():
        for f in sorted((ROOT / pkg).rglob("*.py")):
            parts = list(f.relative_to(ROOT).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts.pop()
            out[".".join(parts)] = f
    return out


def _within(name: str, pkg: str) -> bool:
    return name == pkg or name.startswith(pkg + ".")


def imports_of(name: str, path: Path, modules: dict[str, Path]) -> list[tuple[str, int, bool]]:
    """(imported module of ours, line, at module level) for each import in ``path``.

    ``from pkg import x`` counts as an import of ``pkg.x`` when that is a module, else of
    ``pkg``. Imports inside functions/classes are returned with ``at module level`` False.
    """
    tree = ast.parse(path.read_text(), filename=str(path))
    is_pkg = path.name == "__init__.py"
    here = name.split(".") if is_pkg else name.split(".")[:-1]
    tops = set(our_packages())
    found: list[tuple[str, int, bool]] = []

    def visit(node: ast.AST, top: bool) -> None:
        for child in ast.iter_child_nodes(node):
            nested = isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda,
                                        ast.ClassDef))
            if isinstance(child, ast.Import):
                for a in child.names:
                    targets = [a.name]
                    _add(targets, child.lineno, top)
            elif isinstance(child, ast.ImportFrom):
                if child.level:
                    base = here[:len(here) - (child.level - 1)] if child.level > 1 else here
                    mod = ".".join(base + ([child.module] if child.module else []))
                else:
                    mod = child.module or ""
                targets = []
                for a in child.names:
                    sub = f"{mod}.{a.name}"
                    targets.append(sub if sub in modules else mod)
                _add(targets, child.lineno, top)
            visit(child, top and not nested)

    def _add(targets: list[str], line: int, top: bool) -> None:
        for t in targets:
            if t.split(".")[0] in tops:
                while t not in modules and "." in t:      # attribute of a module
                    t = t.rsplit(".", 1)[0]
                found.append((t, line, top))

    visit(tree, True)
    return found


def _defines(path: Path, name: str) -> bool:
    """Whether the module at ``path`` binds ``name`` at module level (def, class, assignment,
    import; also inside a module-level ``try``/``if``/``with``), or star-imports anything."""
    names, star = _module_bindings(path)
    return star or name in names


@functools.lru_cache(maxsize=None)
def _module_bindings(path: Path) -> tuple[frozenset, bool]:
    """(names bound at module level, whether the module star-imports) of the file at ``path``:
    parsed once per file (each module's imports ask it name by name)."""
    def stmts(body):
        for node in body:
            yield node
            if not isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                for field in ("body", "orelse", "finalbody", "handlers"):
                    yield from stmts(getattr(node, field, []) or [])

    tree = ast.parse(path.read_text(), filename=str(path))
    names: set[str] = set()
    star = False
    for node in stmts(tree.body):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.add(node.name)
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            for a in node.names:
                if a.name == "*":
                    star = True
                else:
                    names.add(a.asname or a.name.split(".")[0])
        targets = node.targets if isinstance(node, ast.Assign) else \
            [node.target] if isinstance(node, (ast.AnnAssign, ast.AugAssign)) else []
        for t in targets:
            for n in ast.walk(t):
                if isinstance(n, ast.Name):
                    names.add(n.id)
    return frozenset(names), star


def unresolved_imports(modules: dict[str, Path]) -> list[str]:
    """Imports of our packages that name a module (or a package's member) that is not in this
    tree. With the project installed in editable mode elsewhere, such an import would quietly
    load the other tree's file (a module moved here, still present there), so it is reported."""
    tops = set(our_packages())
    bad = []
    for name, path in modules.items():
        tree = ast.parse(path.read_text(), filename=str(path))
        where = path.relative_to(ROOT) if path.is_relative_to(ROOT) else path
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                for a in node.names:
                    if a.name.split(".")[0] in tops and a.name not in modules:
                        bad.append(f"{where}:{node.lineno}: import {a.name}")
            elif isinstance(node, ast.ImportFrom) and not node.level and node.module \
                    and node.module.split(".")[0] in tops:
                if node.module not in modules:
                    bad.append(f"{where}:{node.lineno}: from {node.module} import ...")
                    continue
                for a in node.names:
                    if a.name == "*" or f"{node.module}.{a.name}" in modules:
                        continue
                    if not _defines(modules[node.module], a.name):
                        bad.append(f"{where}:{node.lineno}: from {node.module} import {a.name}")
    return bad


def rule_for(name: str) -> tuple[str, tuple[str, ...]] | None:
    """(package, allowed packages) of the longest matching ``ALLOWED``/``SHARED`` key."""
    for pkg in SHARED:
        if _within(name, pkg):
            return pkg, ()
    keys = [k for k in ALLOWED if _within(name, k)]
    if not keys:
        return None
    pkg = max(keys, key=len)
    return pkg, ALLOWED[pkg] + (() if pkg in PURE else SHARED)


def violations(modules: dict[str, Path]) -> list[str]:
    bad = []
    for name, path in modules.items():
        rule = rule_for(name)
        if rule is None:
            bad.append(f"{name}: no rule in ALLOWED for this package (add one)")
            continue
        pkg, allowed = rule
        where = path.relative_to(ROOT) if path.is_relative_to(ROOT) else path
        for target, line, _top in imports_of(name, path, modules):
            if not any(_within(target, ok) for ok in (pkg,) + allowed):
                bad.append(f"{where}:{line}: {pkg} must not import {target}")
    return bad


def command_unit(name: str) -> str | None:
    """``tools.X`` for a module of a command (``tools.hil.cli`` -> ``tools.hil``), None for a
    library module or a module outside COMMANDS."""
    if not _within(name, COMMANDS) or name == COMMANDS:
        return None
    if any(_within(name, lib) for lib in LIBRARIES):
        return None
    return ".".join(name.split(".")[:2])


def command_violations(modules: dict[str, Path]) -> list[str]:
    """Imports from one command unit into another (deferred imports included)."""
    bad = []
    for name, path in modules.items():
        unit = command_unit(name)
        if unit is None:
            continue
        where = path.relative_to(ROOT) if path.is_relative_to(ROOT) else path
        for target, line, _top in imports_of(name, path, modules):
            other = command_unit(target)
            if other is not None and other != unit:
                bad.append(f"{where}:{line}: command {unit} must not import command {target}")
    return bad


def cycles(modules: dict[str, Path], deferred: bool = False) -> list[list[str]]:
    """Strongly connected components (size > 1) of the import graph: module-level imports
    only, or (``deferred``) every import, also those inside functions and classes."""
    graph = {n: sorted({t for t, _, top in imports_of(n, p, modules)
                        if (top or deferred) and t != n and t in modules})
             for n, p in modules.items()}
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    out: list[list[str]] = []
    counter = [0]

    def strong(v: str) -> None:                   # Tarjan, recursive (the graph is small)
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on_stack.add(v)
        for w in graph[v]:
            if w not in index:
                strong(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in graph:
        if v not in index:
            strong(v)
    return out


@pytest.fixture(scope="module")
def modules() -> dict[str, Path]:
    return module_files()


def test_walk_sees_our_packages(modules):
    """The walk itself works: it finds the packages and resolves a known import."""
    assert {"fc", "plant_sim", "tools", "tests"} <= set(our_packages())
    assert "fc.control.law" in modules and "plant_sim.sim" in modules
    law = imports_of("fc.control.law", modules["fc.control.law"], modules)
    assert any(t.startswith("fc.control.") for t, _, _ in law)


def test_every_import_of_ours_resolves_in_this_tree(modules, tmp_path):
    """Every ``import``/``from ... import`` of our packages names a module of this tree (or a
    name its module defines): a path left behind by a move fails here, instead of loading the
    old file from another checkout through the editable install. The check itself sees a
    stale path."""
    bad = unresolved_imports(modules)
    assert not bad, "imports that do not resolve in this tree:\n" + "\n".join(bad)
    stale = tmp_path / "stale.py"
    stale.write_text("from tools import no_such_tool\nimport tools.no_such_module\n"
                     "from tools.sitl.closed_loop import simulate, no_such_name\n")
    found = unresolved_imports({"tools.stale": stale, **modules})
    assert [b.split(": ", 1)[1] for b in found] == [
        "from tools import no_such_tool", "import tools.no_such_module",
        "from tools.sitl.closed_loop import no_such_name"], found


def test_import_direction(modules):
    bad = violations(modules)
    assert not bad, "imports against docs/architecture.md's direction:\n" + "\n".join(bad)


def test_commands_import_libraries_not_commands(modules):
    bad = command_violations(modules)
    assert not bad, "a command imports another command:\n" + "\n".join(bad)


def test_layer_walk_sees_wrong_way_imports(modules, tmp_path):
    """The walk reports a harness module importing an evidence tool or a command, an evidence
    tool importing a command, and a command importing another command (deferred or not)."""
    sitl = tmp_path / "sitl_fake.py"
    sitl.write_text("from tools.evidence.mutate import ROOT\n\n\ndef f():\n"
                    "    from tools.hil import cli\n")
    ev = tmp_path / "ev_fake.py"
    ev.write_text("def f():\n    from tools.hil.cli import main\n")
    cmd = tmp_path / "cmd_fake.py"
    cmd.write_text("from tools.sitl.procs import Child\nfrom tools.evidence import mutate\n"
                   "from tools.soak import main\n")
    more = {**modules, "tools.sitl.sitl_fake": sitl, "tools.evidence.ev_fake": ev,
            "tools.cmd_fake": cmd}
    bad = violations(more)
    assert any("tools.sitl must not import tools.evidence.mutate" in b for b in bad), bad
    assert any("tools.sitl must not import tools.hil.cli" in b for b in bad), bad
    assert any("tools.evidence must not import tools.hil.cli" in b for b in bad), bad
    cbad = command_violations(more)
    assert cbad == [f"{cmd}:3: command tools.cmd_fake must not import command tools.soak"], cbad


def test_no_import_cycles(modules):
    found = cycles(modules)
    assert not found, "module-level import cycles:\n" + "\n".join(" <-> ".join(c) for c in found)


def test_no_import_cycles_deferred_imports_included(modules):
    """No cycle in fc/, plant_sim/, hyfc_wire/ or tools/ even counting the imports inside
    functions (issue 23: fc.params -> fc.mission_mode -> fc.params through MISSION_PARAMS,
    tools.evidence.margins <-> tools.evidence.margins.wire)."""
    ours = {n: p for n, p in modules.items() if n.split(".")[0] in NO_CYCLES}
    found = cycles(ours, deferred=True)
    assert not found, "import cycles (deferred imports included):\n" + "\n".join(
        " <-> ".join(c) for c in found)


def test_cycle_walk_sees_a_deferred_cycle(modules, tmp_path):
    """The walk finds a cycle that only a deferred import closes (and the module-level walk,
    by design, does not)."""
    a = tmp_path / "cyc_a.py"
    b = tmp_path / "cyc_b.py"
    a.write_text("from tools.cyc_b import g\n\n\ndef f():\n    return g()\n")
    b.write_text("def g():\n    from tools.cyc_a import f\n    return f\n")
    both = {**modules, "tools.cyc_a": a, "tools.cyc_b": b}
    assert ["tools.cyc_a", "tools.cyc_b"] in cycles(both, deferred=True)
    assert ["tools.cyc_a", "tools.cyc_b"] not in cycles(both)


def test_tools_never_import_tests(modules, tmp_path):
    """tools/ (the harness above all: one scripted ground station, tools/sitl/gcs.py) must not
    import tests/: no rule of ``ALLOWED`` lets it, and a harness module that did is reported,
    deferred import or not."""
    for pkg, allowed in ALLOWED.items():
        if _within(pkg, "tools"):
            assert not any(_within(ok, "tests") or _within("tests", ok) for ok in allowed), pkg
    fake = tmp_path / "gcs_fake.py"
    fake.write_text("def station():\n    from tests.fc_harness import FcProcess\n")
    bad = violations({**modules, "tools.sitl.gcs_fake": fake})
    assert any("tools.sitl must not import tests.fc_harness" in b for b in bad), bad
