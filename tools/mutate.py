"""Mutation testing of the control law: does a wrong law fail the law's tests?

    python -m tools.mutate                       # kernels.py, fast unit tests, report
    python -m tools.mutate --list                # the mutants only, no test run
    python -m tools.mutate --jit-tests tests/test_closed_loop.py::test_coordination_pins

Each mutant is ONE change to the source of a law module (default fc/control/kernels.py),
inside the functions that carry the paper's equations (``FUNCTIONS``):

    sign      a binary + becomes - and vice versa (also += / -=); a unary minus removed
    drop      one term of a sum or difference removed (a + b -> a, a + b -> b, a - b -> -b)
    muldiv    * becomes / and vice versa
    const     a float constant c becomes 2 c (0.0 becomes 1.0)

Index arithmetic (inside ``x[...]``) is left alone: it is layout, not an equation. The
mutant is written into a temporary copy of the project (never in place); the chosen tests
run in a subprocess with a per-mutant timeout. A mutant is *killed* if the tests fail (or
time out), *survived* if they pass. Stage 1 runs ``--tests`` with NUMBA_DISABLE_JIT=1 (no
compilation per mutant: the kernels run as plain Python, so pick tests that call the
kernels a few thousand times at most); stage 2 (``--jit-tests``, optional) reruns only the
survivors against tests that need compiled code (closed loops), each paying a numba
compile of the mutant.

The report (``--report``, default docs/mutation_report.md) lists every mutant with
file:line, the function, the equation named by the nearest ``Eq.`` comment above it, the
change and the verdict. This is a tool, not a CI test (docs/control_law.md section 12).
"""
from __future__ import annotations

import argparse
import ast
import copy
import datetime as _dt
import os
import shutil
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: The kernels' functions that carry the paper's equations (and their helpers).
FUNCTIONS = ("gs_inv_apply", "gs_apply", "gs_t_apply", "solve3", "det3", "slow_kernel",
             "coordinated_factors", "coordinated_matrix", "allocate", "actuator_model_step",
             "dob_gain", "dob_estimate", "dob_update", "fast_kernel")

#: Stage 1: unit tests of each equation, fast without JIT.
DEFAULT_TESTS = ("tests/test_law_equations.py", "tests/test_law_units.py::test_gs_inverse_and_determinant",
                 "tests/test_law_units.py::test_solve3_matches_numpy",
                 "tests/test_law_units.py::test_factors_hand_computed",
                 "tests/test_law_units.py::test_allocator_exact_when_unsaturated",
                 "tests/test_law_units.py::test_allocator_reports_shortfall_and_keeps_direction",
                 "tests/test_law_units.py::test_surface_coordination_eq47",
                 "tests/test_law_units.py::test_coordinated_matrix_guard_rejects_sign_flip",
                 "tests/test_law_units.py::test_observer_converges_to_constant_disturbance",
                 "tests/test_law_units.py::test_projection_identity_inside_and_bounded_outside",
                 "tests/test_law_units.py::test_factors_zero_when_uncoordinated_and_clamped")

COPY_DIRS = ("fc", "plant_sim", "tools", "tests")


@dataclass
class Mutant:
    """One change: ``ident`` is the position of the node in the module's ast.walk order."""
    index: int
    line: int
    function: str
    equation: str
    kind: str
    change: str
    source: str
    verdict: str = ""
    stage: str = ""
    seconds: float = 0.0


# -------------------------------------------------------------------------------------------
# Finding and applying mutations (ast: the rest of the module is unparsed unchanged)
# -------------------------------------------------------------------------------------------
def _index_nodes(tree):
    """ids of nodes inside a Subscript's slice (index arithmetic: not mutated)."""
    skip = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Subscript):
            for sub in ast.walk(node.slice):
                skip.add(id(sub))
    return skip


def _equation_label(lines, func_line, line):
    """The nearest comment above ``line`` (inside the function) that names an equation."""
    for i in range(line - 1, func_line - 1, -1):
        s = lines[i - 1].strip()
        if s.startswith("#") and "Eq." in s:
            return s.lstrip("# ").split(":")[0][:60]
    return ""


_OPS = {ast.Add: "+", ast.Sub: "-", ast.Mult: "*", ast.Div: "/"}


def _candidates(tree, lines, functions):
    """(path of the node, kind, change text, line, function, equation) per mutation."""
    skip = _index_nodes(tree)
    out = []
    for fn in tree.body:
        if not isinstance(fn, ast.FunctionDef) or fn.name not in functions:
            continue
        for node in ast.walk(fn):
            if id(node) in skip or not hasattr(node, "lineno"):
                continue
            ln = node.lineno
            eq = _equation_label(lines, fn.lineno, ln) or fn.name
            if isinstance(node, ast.BinOp) and type(node.op) in _OPS:
                op = _OPS[type(node.op)]
                if op in "+-":
                    other = "-" if op == "+" else "+"
                    out.append((node, "sign", f"'{op}' -> '{other}'", ln, fn.name, eq))
                    out.append((node, "drop", f"drop right term of '{op}'", ln, fn.name, eq))
                    out.append((node, "drop", f"drop left term of '{op}'", ln, fn.name, eq))
                else:
                    other = "/" if op == "*" else "*"
                    out.append((node, "muldiv", f"'{op}' -> '{other}'", ln, fn.name, eq))
            elif isinstance(node, ast.AugAssign) and type(node.op) in (ast.Add, ast.Sub):
                op = _OPS[type(node.op)]
                other = "-" if op == "+" else "+"
                out.append((node, "sign", f"'{op}=' -> '{other}='", ln, fn.name, eq))
            elif isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub):
                out.append((node, "sign", "unary '-' removed", ln, fn.name, eq))
            elif (isinstance(node, ast.Constant) and type(node.value) is float):
                new = 1.0 if node.value == 0.0 else 2.0 * node.value
                out.append((node, "const", f"{node.value!r} -> {new!r}", ln, fn.name, eq))
    return out


def _apply(tree, target, kind, change):
    """A mutated deep copy of ``tree`` (``target`` found by position in ast.walk order)."""
    order = list(ast.walk(tree))
    pos = order.index(target)
    new = copy.deepcopy(tree)
    node = list(ast.walk(new))[pos]
    if kind == "sign":
        if isinstance(node, ast.UnaryOp):
            _replace(new, node, node.operand)
        elif isinstance(node, (ast.BinOp, ast.AugAssign)):
            node.op = ast.Sub() if isinstance(node.op, ast.Add) else ast.Add()
    elif kind == "drop":
        if change.startswith("drop right"):
            _replace(new, node, node.left)
        elif isinstance(node.op, ast.Add):
            _replace(new, node, node.right)
        else:
            _replace(new, node, ast.UnaryOp(op=ast.USub(), operand=node.right))
    elif kind == "muldiv":
        node.op = ast.Div() if isinstance(node.op, ast.Mult) else ast.Mult()
    elif kind == "const":
        node.value = 1.0 if node.value == 0.0 else 2.0 * node.value
    return ast.fix_missing_locations(new)


def _replace(tree, old, new):
    for parent in ast.walk(tree):
        for field, value in ast.iter_fields(parent):
            if value is old:
                setattr(parent, field, new)
                return
            if isinstance(value, list):
                for i, v in enumerate(value):
                    if v is old:
                        value[i] = new
                        return
    raise ValueError("node not found")


def find_mutants(path: Path, functions=FUNCTIONS):
    """[(Mutant, mutated source)] for the module at ``path``."""
    text = path.read_text()
    lines = text.splitlines()
    tree = ast.parse(text)
    out = []
    for i, (node, kind, change, ln, fn, eq) in enumerate(_candidates(tree, lines, functions)):
        src = ast.unparse(_apply(tree, node, kind, change))
        if src == ast.unparse(tree):
            continue
        out.append((Mutant(i, ln, fn, eq, kind, change, lines[ln - 1].strip()), src))
    return out


# -------------------------------------------------------------------------------------------
# Running the tests against one mutant
# -------------------------------------------------------------------------------------------
def _make_copy(dst: Path):
    for d in COPY_DIRS:
        shutil.copytree(ROOT / d, dst / d, ignore=shutil.ignore_patterns(
            "__pycache__", "*.pyc", ".pytest_cache"))
    for f in ("pyproject.toml",):
        if (ROOT / f).exists():
            shutil.copy2(ROOT / f, dst / f)


def _run_tests(work: Path, rel: str, src: str, tests, jit: bool, timeout_s: float):
    """Write ``src`` into the copy at ``rel``, run pytest; (killed, seconds, tail of output)."""
    target = work / rel
    original = target.read_text()
    target.write_text(src)
    env = dict(os.environ, PYTHONPATH=str(work), PYTHONDONTWRITEBYTECODE="1")
    if jit:
        env.pop("NUMBA_DISABLE_JIT", None)
        env["NUMBA_CACHE_DIR"] = str(work / ".numba_cache")
        shutil.rmtree(work / ".numba_cache", ignore_errors=True)
    else:
        env["NUMBA_DISABLE_JIT"] = "1"
    cmd = [sys.executable, "-m", "pytest", "-x", "-q", "-p", "no:cacheprovider",
           "-p", "no:randomly", *tests]
    t0 = time.perf_counter()
    try:
        r = subprocess.run(cmd, cwd=work, env=env, capture_output=True, text=True,
                           timeout=timeout_s)
        killed = r.returncode != 0
        tail = (r.stdout + r.stderr).strip().splitlines()[-1:] or [""]
    except subprocess.TimeoutExpired:
        killed, tail = True, ["timeout"]
    finally:
        target.write_text(original)
    return killed, time.perf_counter() - t0, tail[0]


def run(rel: str, tests, jit_tests, timeout_s: float, jit_timeout_s: float, jobs: int,
        only=None, progress=True):
    """Mutate ``rel`` and run the tests; returns the list of Mutants with verdicts."""
    found = find_mutants(ROOT / rel)
    if only:
        found = [(m, s) for m, s in found if m.line in only]
    with tempfile.TemporaryDirectory(prefix="hyfc-mutate-") as tmp:
        works = []
        for j in range(max(1, jobs)):
            w = Path(tmp) / f"w{j}"
            _make_copy(w)
            works.append(w)
        # the unmutated law must pass, else every mutant would read as killed
        ok, _, tail = _run_tests(works[0], rel, (works[0] / rel).read_text(), tests, False,
                                 timeout_s * 3)
        if ok:
            raise SystemExit(f"the tests fail on the unmutated code: {tail}")

        def one(k_ms):
            k, (m, src) = k_ms
            w = works[k % len(works)]
            killed, dt, tail = _run_tests(w, rel, src, tests, False, timeout_s)
            m.verdict, m.stage, m.seconds = ("killed" if killed else "survived"), "unit", dt
            if progress:
                print(f"[{k + 1}/{len(found)}] {rel}:{m.line} {m.change:28s} {m.verdict:8s} "
                      f"{dt:5.1f}s {tail[:60]}", flush=True)
            return m

        # each worker needs its own copy: split the mutants by worker, one thread each
        buckets = [[(k, f) for k, f in enumerate(found) if k % len(works) == j]
                   for j in range(len(works))]
        with ThreadPoolExecutor(len(works)) as ex:
            list(ex.map(lambda b: [one(kf) for kf in b], buckets))
        if jit_tests:
            for m, src in found:
                if m.verdict != "survived":
                    continue
                killed, dt, tail = _run_tests(works[0], rel, src, jit_tests, True,
                                              jit_timeout_s)
                m.stage, m.seconds = "jit", m.seconds + dt
                m.verdict = "killed" if killed else "survived"
                if progress:
                    print(f"[jit] {rel}:{m.line} {m.change:28s} {m.verdict} {dt:.1f}s {tail[:60]}",
                          flush=True)
    return [m for m, _ in found]


# -------------------------------------------------------------------------------------------
# Report
# -------------------------------------------------------------------------------------------
def report(rel: str, mutants, tests, jit_tests, equivalent: dict, wall_s: float) -> str:
    n = len(mutants)
    killed = [m for m in mutants if m.verdict == "killed"]
    surv = [m for m in mutants if m.verdict == "survived"]
    by_kind = {}
    for m in mutants:
        k = by_kind.setdefault(m.kind, [0, 0])
        k[0] += 1
        k[1] += m.verdict == "killed"
    out = [f"# Mutation report: `{rel}`", "",
           f"Generated by `python -m tools.mutate` on "
           f"{_dt.datetime.now(_dt.timezone.utc).strftime('%Y-%m-%d %H:%M UTC')} "
           f"({wall_s / 60:.1f} min). Functions mutated: {', '.join(f'`{f}`' for f in FUNCTIONS)}.",
           "", "Stage 1 tests (NUMBA_DISABLE_JIT=1): " + ", ".join(f"`{t}`" for t in tests) + ".",
           "", ("Stage 2 tests (compiled, survivors of stage 1 only): "
                + ", ".join(f"`{t}`" for t in jit_tests) + ".") if jit_tests else
           "Stage 2: not run.", "",
           f"**{n} mutants: {len(killed)} killed, {len(surv)} survived.**", "",
           "| kind | mutants | killed |", "|---|---|---|"]
    for k, (a, b) in sorted(by_kind.items()):
        out.append(f"| {k} | {a} | {b} |")
    out += ["", "## Survivors", ""]
    if not surv:
        out.append("None.")
    else:
        out += ["| line | function | equation | change | source | judged |",
                "|---|---|---|---|---|---|"]
        for m in surv:
            why = equivalent.get((m.line, m.change), "")
            out.append(f"| {rel}:{m.line} | `{m.function}` | {m.equation} | {m.change} | "
                       f"`{m.source[:70]}` | {why} |")
    out += ["", "## Every mutant", "", "| line | function | equation | change | verdict | stage |",
            "|---|---|---|---|---|---|"]
    for m in mutants:
        out.append(f"| {m.line} | `{m.function}` | {m.equation} | {m.change} | {m.verdict} | "
                   f"{m.stage} |")
    return "\n".join(out) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m tools.mutate", description=__doc__.split("\n")[0])
    ap.add_argument("--file", default="fc/control/kernels.py",
                    help="module to mutate, relative to the project root")
    ap.add_argument("--tests", nargs="+", default=list(DEFAULT_TESTS),
                    help="stage 1 pytest node ids (run with NUMBA_DISABLE_JIT=1)")
    ap.add_argument("--jit-tests", nargs="*", default=[],
                    help="stage 2 pytest node ids (compiled), run on stage-1 survivors only")
    ap.add_argument("--timeout", type=float, default=120.0, help="per mutant, stage 1, s")
    ap.add_argument("--jit-timeout", type=float, default=600.0, help="per mutant, stage 2, s")
    ap.add_argument("--jobs", type=int, default=2, help="mutants run in parallel (stage 1)")
    ap.add_argument("--lines", type=int, nargs="*", default=None,
                    help="only mutants on these source lines")
    ap.add_argument("--list", action="store_true", help="list the mutants and exit")
    ap.add_argument("--report", type=Path, default=ROOT / "docs" / "mutation_report.md")
    a = ap.parse_args(argv)
    if a.list:
        for m, _ in find_mutants(ROOT / a.file):
            print(f"{a.file}:{m.line} {m.function} [{m.equation}] {m.kind}: {m.change}")
        return 0
    t0 = time.perf_counter()
    mutants = run(a.file, a.tests, a.jit_tests, a.timeout, a.jit_timeout, a.jobs, a.lines)
    text = report(a.file, mutants, a.tests, a.jit_tests, EQUIVALENT, time.perf_counter() - t0)
    a.report.parent.mkdir(parents=True, exist_ok=True)
    a.report.write_text(text)
    n_s = sum(m.verdict == "survived" for m in mutants)
    print(f"{len(mutants)} mutants, {len(mutants) - n_s} killed, {n_s} survived; "
          f"report {a.report}")
    return 0


#: Survivors judged equivalent (or outside the law's equations), keyed (line, change), with
#: the reason; filled in from a run's report after reading each survivor (docs/control_law.md).
EQUIVALENT: dict = {}

if __name__ == "__main__":
    raise SystemExit(main())
