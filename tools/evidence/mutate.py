"""Mutation testing of the control law: does a wrong law fail the law's tests?

    python -m tools.evidence.mutate                       # the law's modules, fast unit tests, report
    python -m tools.evidence.mutate --quick               # 10 mutants, ~12 s of CPU (run by the tests)
    python -m tools.evidence.mutate --list                # the mutants only, no test run
    python -m tools.evidence.mutate --jit-tests "test_closed_loop.py::test_documented_figures[paper-co-steps-truth]"

Each mutant is ONE change to the source of a law module (default: every module of
``TARGETS``, fc/control/slow_loop.py, fast_loop.py, factors.py, ...), inside the functions
that carry the paper's equations (``TARGETS[module]``):

    sign      a binary + becomes - and vice versa (also += / -=); a unary minus removed
    drop      one term of a sum or difference removed (a + b -> a, a + b -> b, a - b -> -b)
    muldiv    * becomes / and vice versa
    const     a float constant c becomes 2 c (0.0 becomes 1.0)
    named     the hand-made wrong laws of ``NAMED`` (a gain halved, an adaptation's sign)
    index     (the gain schedule only, ``INDEX_FUNCTIONS``) a node index k inside x[...]
              shifted by +1 or -1: the gains of the wrong flight condition (issue 20)

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
change and the verdict. Test files are named by file name and found under tests/
(``find_tests``), so a moved test file is still run and a missing one is an error. The full
set is a tool run on demand; ``--quick`` (the named mutants and one sign flip per main
kernel) runs in the test suite (tests/unit/tools/test_mutate_tool.py) and exits 1 if any
mutant survives (docs/control_law.md section 12).
"""
from __future__ import annotations

import argparse
import ast
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

ROOT = Path(__file__).resolve().parents[2]

#: The law's modules and, in each, the functions that carry the paper's equations (and their
#: helpers). solve3 and det3 (3x3 algebra, checked against numpy) are available with
#: --files fc/control/linalg3.py --functions solve3 det3.
TARGETS = {
    "fc/control/kinematics.py": ("gs_inv", "gs", "gs_t"),
    "fc/control/slow_loop.py": ("reference_step", "tracking_error", "f1_gravity", "psi_theta",
                                "xi_step", "slow_kernel"),
    "fc/control/factors.py": ("coordinated_factors", "coordinated_matrix"),
    "fc/control/allocation.py": ("allocate", "prioritised", "actuator_model_step"),
    "fc/control/observer.py": ("dob_gain", "dob_estimate", "dob_update"),
    "fc/control/fast_loop.py": ("input_filters", "xi_theta", "observer_moment", "fast_kernel"),
    "fc/control/linalg3.py": ("matvec3",),
    "fc/control/schedule.py": ("node_index", "schedule_index", "mach_index", "schedule_value",
                               "apply_schedule"),
}
#: functions where the "index" kind shifts the schedule's node index ``k`` inside a subscript
INDEX_FUNCTIONS = ("node_index", "schedule_value")
#: every function of TARGETS (the default of find_mutants)
FUNCTIONS = tuple(f for fns in TARGETS.values() for f in fns)
KINDS = ("sign", "drop", "muldiv", "const", "named", "index")

#: Stage 1: unit tests of each equation, fast without JIT, and the behavioural tests of the
#: adaptation; file names (and node ids inside them), found under tests/ by ``find_tests``
#: wherever the file lives, so a test file that moves does not silently drop out.
DEFAULT_TESTS = ("test_law_equations.py", "test_law_units.py::test_gs_inverse_and_determinant",
                 "test_law_units.py::test_solve3_matches_numpy",
                 "test_law_units.py::test_factors_hand_computed",
                 "test_law_units.py::test_allocator_exact_when_unsaturated",
                 "test_law_units.py::test_allocator_reports_shortfall_and_keeps_direction",
                 "test_law_units.py::test_surface_coordination_eq47",
                 "test_law_units.py::test_prioritised_allocation_holds_the_worst_surface_and_reoptimises_the_rest",
                 "test_law_units.py::test_prioritised_allocation_serves_the_yaw_axis_first",
                 "test_law_units.py::test_yaw_escalation_scale_is_the_yaw_weight_times_the_scale",
                 "test_law_units.py::test_yaw_escalation_time_counts_only_while_the_rudder_alone_is_short",
                 "test_law_units.py::test_yaw_escalation_weighs_the_re_solve_by_the_time_on_the_limit",
                 "test_law_units.py::test_prioritised_allocation_with_the_interconnect_stays_within_limits",
                 "test_law_units.py::test_prioritised_allocator_properties_hypothesis",
                 "test_law_units.py::test_prioritised_on_small_hand_made_matrices",
                 "test_law_units.py::test_slow_step_writes_the_complementary_filter_model_term",
                 "test_law_units.py::test_tracking_error_reads_the_attitude_filter_when_either_is_on",
                 "test_law_units.py::test_the_printed_law_runs_no_attitude_filter",
                 "test_law_units.py::test_coordinated_matrix_guard_rejects_sign_flip",
                 "test_law_units.py::test_observer_converges_to_constant_disturbance",
                 "test_law_units.py::test_projection_identity_inside_and_bounded_outside",
                 "test_law_units.py::test_factors_zero_when_uncoordinated_and_clamped",
                 "test_adaptation.py", "test_schedule.py")


@dataclass(frozen=True)
class Named:
    """A hand-made mutant: ``old`` (which must occur exactly once in ``file``) becomes ``new``.
    For wrong laws the operator kinds cannot write (a gain halved, a regressor's sign)."""
    file: str
    function: str
    old: str
    new: str
    what: str


#: Hand-made mutants, in the full set and in --quick (docs/control_law.md section 12).
NAMED = (
    Named("fc/control/fast_loop.py", "fast_kernel", "(nm[NM_XI + i] * e2 - leak",
          "(-nm[NM_XI + i] * e2 - leak", "Eq. 36: sign of the adaptation flipped"),
    Named("fc/control/fast_loop.py", "fast_kernel", "gamma2 = par[P_FST_GAMMA]",
          "gamma2 = 0.5 * par[P_FST_GAMMA]", "Eq. 36: Gamma2 halved"),
    Named("fc/control/slow_loop.py", "slow_kernel", "gamma1 = par[P_SLW_GAMMA]",
          "gamma1 = 0.5 * par[P_SLW_GAMMA]", "Eq. 30: Gamma1 halved"),
    Named("fc/control/slow_loop.py", "slow_kernel", "(nm[NM_PSI + i] * sigma_row",
          "(-nm[NM_PSI + i] * sigma_row", "Eq. 30: sign of the adaptation flipped"),
    Named("fc/control/fast_loop.py", "fast_kernel",
          "if st[S_SAT + 2] > 0.0 and st[S_SAT] == 0.0 and st[S_SAT + 1] == 0.0:",
          "if st[S_SAT + 2] > 0.0:",
          "yaw escalation counting whenever the rudder is short (the elevons' gate dropped)"),
    Named("fc/control/schedule.py", "apply_schedule",
          "k, f = schedule_index(qbar_pa * schedule_value(par, P_SCH_AUTH, km, fm), par)",
          "k, f = schedule_index(qbar_pa, par)",
          "schedule: the gains read at the plain dynamic pressure (the authority axis dropped)"),
)

#: --quick: the named mutants plus the first sign flip of each of these functions: a few
#: mutants that run in the test suite (tests/unit/tools/test_mutate_tool.py).
QUICK_SIGN_FUNCTIONS = ("slow_kernel", "fast_kernel", "coordinated_factors", "allocate",
                        "dob_update", "gs_inv")


def find_tests(names=DEFAULT_TESTS, root: Path | None = None) -> list[str]:
    """Pytest node ids for ``names`` (``file.py`` or ``file.py::test``): each file is looked up
    under ``root``/tests wherever it lives. FileNotFoundError if a file is missing or found
    twice (a moved or duplicated test file must not silently drop out of the run)."""
    root = ROOT if root is None else Path(root)
    out = []
    for name in names:
        fname, sep, rest = name.partition("::")
        if "/" in fname:                        # an explicit path: taken as given
            if not (root / fname).is_file():
                raise FileNotFoundError(f"test file {fname} not found under {root}")
            out.append(name)
            continue
        hits = sorted(p for p in (root / "tests").rglob(fname) if p.is_file())
        if len(hits) != 1:
            raise FileNotFoundError(f"test file {fname}: {len(hits)} matches under "
                                    f"{root / 'tests'} (need exactly one)")
        out.append(hits[0].relative_to(root).as_posix() + sep + rest)
    return out


COPY_DIRS = ("fc", "plant_sim", "tools", "tests")


@dataclass
class Mutant:
    """One change: ``index`` is the position of the candidate in the module's walk order."""
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
    file: str = ""


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
            elif (isinstance(node, ast.Subscript) and fn.name in INDEX_FUNCTIONS
                  and any(isinstance(n, ast.Name) and n.id == "k"
                          for n in ast.walk(node.slice))):
                for shift in ("+1", "-1"):
                    out.append((node, "index", f"node index k {shift} in "
                                f"'{ast.unparse(node)}'", ln, fn.name, eq))
            elif (isinstance(node, ast.Constant) and type(node.value) is float):
                new = 1.0 if node.value == 0.0 else 2.0 * node.value
                out.append((node, "const", f"{node.value!r} -> {new!r} (col {node.col_offset})",
                            ln, fn.name, eq))
    return out


def _mutated_source(tree, node, kind, change):
    """The module's source with ONE change at ``node``; ``tree`` is restored afterwards."""
    if kind == "index":
        old_slice = node.slice
        op = ast.Add() if "k +1" in change else ast.Sub()
        node.slice = ast.BinOp(left=old_slice, op=op, right=ast.Constant(1))
        try:
            return ast.unparse(tree)
        finally:
            node.slice = old_slice
    if kind == "sign" and isinstance(node, ast.UnaryOp):
        repl = node.operand
    elif kind == "drop" and change.startswith("drop right"):
        repl = node.left
    elif kind == "drop":
        repl = (node.right if isinstance(node.op, ast.Add)
                else ast.UnaryOp(op=ast.USub(), operand=node.right))
    else:
        repl = None
    if repl is not None:
        _replace(tree, node, repl)
        try:
            return ast.unparse(tree)
        finally:
            _replace(tree, repl, node)
    if kind == "const":
        old = node.value
        node.value = 1.0 if old == 0.0 else 2.0 * old
    else:
        old = node.op
        if kind == "sign":
            node.op = ast.Sub() if isinstance(old, ast.Add) else ast.Add()
        else:
            node.op = ast.Div() if isinstance(old, ast.Mult) else ast.Mult()
    try:
        return ast.unparse(tree)
    finally:
        if kind == "const":
            node.value = old
        else:
            node.op = old


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


def find_mutants(path: Path, functions=FUNCTIONS, kinds=KINDS):
    """[(Mutant, mutated source)] for the module at ``path``."""
    text = path.read_text()
    lines = text.splitlines()
    tree = ast.parse(text)
    out = []
    base = ast.unparse(tree)
    path = Path(path)
    try:
        rel = path.resolve().relative_to(ROOT).as_posix()
    except ValueError:
        rel = path.name
    for i, (node, kind, change, ln, fn, eq) in enumerate(_candidates(tree, lines, functions)):
        if kind not in kinds:
            continue
        src = _mutated_source(tree, node, kind, change)
        if src == base:
            continue
        out.append((Mutant(i, ln, fn, eq, kind, change, lines[ln - 1].strip(), file=rel), src))
    return out


def named_mutants(named=NAMED, root: Path | None = None):
    """[(Mutant, mutated source)] for the hand-made mutants ``named`` (kind "named"; index
    -1, -2, ... so their keys never collide with the operator mutants'). ValueError if a
    mutant's ``old`` text is not found exactly once: the law changed under it, and the
    mutant must be rewritten, not dropped."""
    root = ROOT if root is None else Path(root)
    out = []
    for k, nm in enumerate(named):
        text = (root / nm.file).read_text()
        if text.count(nm.old) != 1:
            raise ValueError(f"named mutant {nm.what!r}: {nm.old!r} occurs "
                             f"{text.count(nm.old)} times in {nm.file} (need exactly one)")
        pos = text.index(nm.old)
        line = text.count("\n", 0, pos) + 1
        out.append((Mutant(-1 - k, line, nm.function, nm.what, "named",
                           f"{nm.old!r} -> {nm.new!r}", text.splitlines()[line - 1].strip(),
                           file=nm.file), text.replace(nm.old, nm.new)))
    return out


def quick_mutants(targets=TARGETS, functions=QUICK_SIGN_FUNCTIONS, named=NAMED):
    """The --quick set: the named mutants and the first sign flip of each of ``functions``."""
    found = []
    for fn in functions:
        rel = next(r for r, fns in targets.items() if fn in fns)
        found += find_mutants(ROOT / rel, (fn,), ("sign",))[:1]
    return named_mutants(named) + found


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


PROJECT_MODULES = ("fc.", "tools.", "tests.", "test_")


def exec_into(mod, src: str, prefixes=PROJECT_MODULES) -> int:
    """Execute ``src`` into the imported module ``mod``, then give every module whose name
    starts with one of ``prefixes`` the new function wherever it held one of ``mod``'s old
    functions (``from fc.control.factors import allocate``, fc.control.kernels' re-exports,
    fc.control.law's aliases). With NUMBA_DISABLE_JIT=1 the kernels are plain functions.
    Returns the number of names rebound outside ``mod``."""
    old = {k: v for k, v in vars(mod).items()
           if callable(v) and getattr(v, "__module__", None) == mod.__name__}
    exec(compile(src, mod.__file__, "exec"), mod.__dict__)
    swap = {id(v): mod.__dict__[k] for k, v in old.items() if mod.__dict__.get(k) is not v}
    n = 0
    for name, other in list(sys.modules.items()):
        if other is None or other is mod or not name.startswith(prefixes):
            continue
        d = vars(other)
        for k, v in list(d.items()):
            new = swap.get(id(v))
            if new is not None:
                d[k] = new
                n += 1
    return n


def _worker(job_file: str) -> int:
    """Stage 1 in one long-lived process (NUMBA_DISABLE_JIT=1, PYTHONPATH = the copy): for
    each mutant of ``job_file`` (JSON: tests, timeout, mutants [[key, module, source]]),
    execute the mutated source into the imported module's namespace, rebind the names other
    modules imported from it (``from fc.control.factors import allocate``, the re-exports of
    fc.control.kernels, fc.control.law's entry points), run pytest in process, restore.
    Prints one JSON line per mutant. Saves the interpreter, numpy and pytest start-up that
    dominate a subprocess per mutant."""
    import importlib
    import json
    import signal

    import pytest

    job = json.loads(Path(job_file).read_text())
    originals = {}
    load = exec_into

    def alarm(_sig, _frm):
        raise TimeoutError("mutant timed out")

    signal.signal(signal.SIGALRM, alarm)
    args = ["-x", "-q", "-p", "no:cacheprovider", "--no-header", "-p", "no:randomly",
            *job["tests"]]
    if pytest.main(args) != 0:               # the unmutated module must pass in process
        print("BASELINE FAILED", flush=True)
        return 2
    for key, module, src in job["mutants"]:
        mod = importlib.import_module(module)
        if module not in originals:
            originals[module] = Path(mod.__file__).read_text()
        t0 = time.perf_counter()
        try:
            load(mod, src)
            signal.alarm(int(job["timeout"]))
            rc = pytest.main(args)
            killed = rc != 0
            why = f"pytest exit {rc}"
        except BaseException as exc:        # a mutant that breaks the module is killed
            killed, why = True, type(exc).__name__
        finally:
            signal.alarm(0)
            load(mod, originals[module])
        print("MUTANT " + json.dumps({"key": key, "killed": killed,
                                      "seconds": time.perf_counter() - t0, "why": why}),
              flush=True)
    return 0


def _key(m: Mutant) -> str:
    return f"{m.file}#{m.index}"


def _run_worker(work: Path, tests, items, timeout_s: float, on_result):
    """Run one stage-1 worker process over ``items`` [(Mutant, source)] in the copy ``work``."""
    import json
    job = work / "mutate_job.json"
    job.write_text(json.dumps({"tests": list(tests), "timeout": timeout_s,
                               "mutants": [[_key(m), m.file[:-3].replace("/", "."), src]
                                           for m, src in items]}))
    env = dict(os.environ, PYTHONPATH=str(work), PYTHONDONTWRITEBYTECODE="1",
               NUMBA_DISABLE_JIT="1")
    by_key = {_key(m): m for m, _ in items}
    proc = subprocess.Popen([sys.executable, "-m", "tools.evidence.mutate", "--worker", str(job)],
                            cwd=work, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.DEVNULL, text=True)
    for line in proc.stdout:
        if line.startswith("BASELINE FAILED"):
            proc.wait()
            raise SystemExit(f"the tests fail on the unmutated code in the worker ({work})")
        if line.startswith("MUTANT "):
            r = json.loads(line[7:])
            m = by_key[r["key"]]
            m.verdict = "killed" if r["killed"] else "survived"
            m.stage, m.seconds = "unit", r["seconds"]
            on_result(m, r["why"])
    proc.wait()
    for m, _ in items:                       # the worker died before reaching these
        if not m.verdict:
            m.verdict, m.stage = "killed", "unit (worker died)"
            on_result(m, "worker died")


def select(targets: dict, kinds=KINDS, only=None, named=NAMED):
    """[(Mutant, source)]: the named mutants whose file is in ``targets`` (when "named" is in
    ``kinds``), then every operator mutant of ``targets`` {rel path: functions} of ``kinds``
    (``only``: the source lines to keep, in any module)."""
    found = []
    if "named" in kinds:
        found += named_mutants([n for n in named if n.file in targets])
    found += [f for rel, fns in targets.items() for f in find_mutants(ROOT / rel, fns, kinds)]
    if only:
        found = [(m, s) for m, s in found if m.line in only]
    return found


def run(found, tests, jit_tests, timeout_s: float, jit_timeout_s: float, jobs: int,
        progress=True):
    """Run the tests against each of ``found`` [(Mutant, source)]; returns the list of
    Mutants with verdicts."""
    with tempfile.TemporaryDirectory(prefix="hyfc-mutate-") as tmp:
        works = []
        for j in range(max(1, jobs)):
            w = Path(tmp) / f"w{j}"
            _make_copy(w)
            works.append(w)
        # (each worker first checks that the unmutated law passes, else it stops the run)

        done = [0]

        def report_one(m, why):
            done[0] += 1
            if progress:
                print(f"[{done[0]}/{len(found)}] {m.file}:{m.line} {m.change:28s} {m.verdict:8s} "
                      f"{m.seconds:5.2f}s {why}", flush=True)

        # one long-lived worker per copy, the mutants dealt out round-robin
        buckets = [[f for k, f in enumerate(found) if k % len(works) == j]
                   for j in range(len(works))]
        with ThreadPoolExecutor(len(works)) as ex:
            list(ex.map(lambda jb: _run_worker(works[jb[0]], tests, jb[1], timeout_s,
                                               report_one), enumerate(buckets)))
        if jit_tests:
            for m, src in found:
                if m.verdict != "survived":
                    continue
                killed, dt, tail = _run_tests(works[0], m.file, src, jit_tests, True,
                                              jit_timeout_s)
                m.stage, m.seconds = "jit", m.seconds + dt
                m.verdict = "killed" if killed else "survived"
                if progress:
                    print(f"[jit] {m.file}:{m.line} {m.change:28s} {m.verdict} {dt:.1f}s "
                          f"{tail[:60]}", flush=True)
    return [m for m, _ in found]


# -------------------------------------------------------------------------------------------
# Report
# -------------------------------------------------------------------------------------------
def _commit() -> str:
    """The project's HEAD commit (short), with ``+dirty`` if the law's sources differ from it."""
    try:
        head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, text=True,
                              capture_output=True, timeout=10).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--", *TARGETS], cwd=ROOT,
                               text=True, capture_output=True, timeout=10).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    return (head or "unknown") + ("+dirty" if dirty else "")


def report(targets: dict, mutants, tests, jit_tests, equivalent: dict, wall_s: float,
           kinds=KINDS, command: str = "python -m tools.evidence.mutate") -> str:
    n = len(mutants)
    killed = [m for m in mutants if m.verdict == "killed"]
    surv = [m for m in mutants if m.verdict == "survived"]
    by_kind = {}
    for m in mutants:
        k = by_kind.setdefault(m.kind, [0, 0])
        k[0] += 1
        k[1] += m.verdict == "killed"
    mutated = "; ".join(f"`{rel}`: " + ", ".join(f"`{f}`" for f in fns)
                        for rel, fns in targets.items())
    out = ["# Mutation report: the control law's kernels", "",
           f"Generated by `{command}` at commit {_commit()} on "
           f"{_dt.datetime.now(_dt.timezone.utc).strftime('%Y-%m-%d %H:%M UTC')} "
           f"({wall_s / 60:.1f} min wall, load average {os.getloadavg()[0]:.1f} at the end). "
           f"Functions mutated: {mutated}; kinds: {', '.join(kinds)}.",
           "", "Stage 1 tests (NUMBA_DISABLE_JIT=1): " + ", ".join(f"`{t}`" for t in tests) + ".",
           "", ("Stage 2 tests (compiled, survivors of stage 1 only): "
                + ", ".join(f"`{t}`" for t in jit_tests) + ".") if jit_tests else
           "Stage 2: not run.", "",
           f"**{n} mutants: {len(killed)} killed, {len(surv)} survived "
           f"({sum((m.source, m.change) in equivalent for m in surv)} judged equivalent).**",
           "",
           "| kind | mutants | killed |", "|---|---|---|"]
    for k, (a, b) in sorted(by_kind.items()):
        out.append(f"| {k} | {a} | {b} |")
    named = [m for m in mutants if m.kind == "named"]
    if named:
        out += ["", "## Hand-made mutants (`tools.evidence.mutate.NAMED`)", "",
                "| line | wrong law | change | verdict |", "|---|---|---|---|"]
        for m in named:
            out.append(f"| {m.file}:{m.line} | {m.equation} | `{m.change}` | {m.verdict} |")
    out += ["", "## Survivors", ""]
    if not surv:
        out.append("None.")
    else:
        out += ["| line | function | equation | change | source | judged |",
                "|---|---|---|---|---|---|"]
        for m in surv:
            why = equivalent.get((m.source, m.change), "not judged: a test is missing")
            out.append(f"| {m.file}:{m.line} | `{m.function}` | {m.equation} | {m.change} | "
                       f"`{m.source[:70]}` | {why} |")
    out += ["", "## Every mutant", "", "| line | function | equation | change | verdict | stage |",
            "|---|---|---|---|---|---|"]
    for m in mutants:
        out.append(f"| {m.file}:{m.line} | `{m.function}` | {m.equation} | {m.change} | {m.verdict} | "
                   f"{m.stage} |")
    return "\n".join(out) + "\n"


def main(argv=None) -> int:
    """Exit status 0 when every mutant is killed or judged equivalent, 1 otherwise."""
    ap = argparse.ArgumentParser(prog="python -m tools.evidence.mutate", description=__doc__.split("\n")[0])
    ap.add_argument("--files", nargs="+", default=list(TARGETS),
                    help="modules to mutate, relative to the project root (default: TARGETS)")
    ap.add_argument("--tests", nargs="+", default=list(DEFAULT_TESTS),
                    help="stage 1 tests, run with NUMBA_DISABLE_JIT=1: pytest node ids, or a "
                         "file name (with ::test) looked up under tests/ (default: "
                         "DEFAULT_TESTS)")
    ap.add_argument("--jit-tests", nargs="*", default=[],
                    help="stage 2 tests (compiled), run on stage-1 survivors only (node ids "
                         "or file names, as --tests)")
    ap.add_argument("--timeout", type=float, default=120.0, help="per mutant, stage 1, s")
    ap.add_argument("--jit-timeout", type=float, default=600.0, help="per mutant, stage 2, s")
    ap.add_argument("--jobs", type=int, default=2, help="mutants run in parallel (stage 1)")
    ap.add_argument("--lines", type=int, nargs="*", default=None,
                    help="only mutants on these source lines")
    ap.add_argument("--functions", nargs="+", default=None,
                    help="functions to mutate in each of --files (default: TARGETS[file])")
    ap.add_argument("--kinds", nargs="+", default=list(KINDS), choices=KINDS,
                    help="mutation kinds")
    ap.add_argument("--quick", action="store_true",
                    help="a few mutants only (NAMED and the first sign flip of each of "
                         "QUICK_SIGN_FUNCTIONS), one worker; no report unless --report")
    ap.add_argument("--list", action="store_true", help="list the mutants and exit")
    ap.add_argument("--report", type=Path, default=None,
                    help="where the Markdown report goes (default docs/mutation_report.md; "
                         "none with --quick)")
    ap.add_argument("--worker", default=None, help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.worker:
        return _worker(a.worker)
    targets = {}
    for rel in a.files:
        fns = a.functions if a.functions else TARGETS.get(rel)
        if not fns:
            ap.error(f"{rel} is not in TARGETS: name its functions with --functions")
        targets[rel] = tuple(fns)
    found = quick_mutants() if a.quick else select(targets, a.kinds, a.lines)
    if a.list:
        for m, _ in found:
            print(f"{m.file}:{m.line} {m.function} [{m.equation}] {m.kind}: {m.change}")
        return 0
    try:
        tests = find_tests(a.tests)
        jit_tests = find_tests(a.jit_tests)
    except FileNotFoundError as exc:
        ap.error(str(exc))
    t0 = time.perf_counter()
    mutants = run(found, tests, jit_tests, a.timeout, a.jit_timeout, 1 if a.quick else a.jobs)
    n_s = sum(m.verdict == "survived" and (m.source, m.change) not in EQUIVALENT
              for m in mutants)
    report_path = a.report or (None if a.quick else ROOT / "docs" / "mutation_report.md")
    if report_path is not None:
        command = "python -m tools.evidence.mutate" + "".join(
            f" {x}" if x.startswith("-") or " " not in x else f' "{x}"'
            for x in (sys.argv[1:] if argv is None else argv))
        text = report(targets if not a.quick else {m.file: () for m in mutants}, mutants,
                      tests, jit_tests, EQUIVALENT, time.perf_counter() - t0,
                      ("quick",) if a.quick else a.kinds, command)
        report_path.parent.mkdir(parents=True, exist_ok=True)
        report_path.write_text(text)
    killed = sum(m.verdict == "killed" for m in mutants)
    print(f"{len(mutants)} mutants, {killed} killed, {len(mutants) - killed} survived "
          f"({n_s} not judged equivalent) in {time.perf_counter() - t0:.1f} s"
          + (f"; report {report_path}" if report_path else ""))
    return 1 if n_s else 0


#: Survivors read and judged equivalent, keyed (source line, change), with the reason
#: (docs/control_law.md section 12). Keyed on the text, not the line number, so it survives
#: edits elsewhere in the module. Empty since the split into modules: the integer options
#: are read through options.option / switch_on (not mutated), and the observer's moment
#: shares linalg3.matvec3 with the allocator's unallocated moment, whose tests use a dense
#: matrix (docs/mutation_report.md: no survivor).
EQUIVALENT: dict = {
    ("v = (w0 * x0 * r0 + w1 * x1 * r1 + w2 * x2 * r2) / den if den > 0.0 else 0.0",
     "0.0 -> 1.0 (col 85)"):
        "unreachable: one free column with den = 0 is a zero column, which made the 2x2 step "
        "before it singular (free surfaces set to 0, none beyond its limit), so the loop ends "
        "before a single column is left",
    ("while k < SCHED_N - 2 and v >= par[base + k + 1]:", "'-' -> '+'"):
        "the bound is redundant: v at or above the last node returned before the loop, so "
        "v >= par[base + k + 1] fails at k = SCHED_N - 2 at the latest",
    ("while k < SCHED_N - 2 and v >= par[base + k + 1]:", "drop right term of '-'"):
        "the bound is redundant: v at or above the last node returned before the loop, so "
        "v >= par[base + k + 1] fails at k = SCHED_N - 2 at the latest",
    ("f = (v - lo) / span if span > 0.0 else 0.0", "0.0 -> 1.0 (col 43)"):
        "unreachable: at the loop's exit v >= par[base + k] (k > 0) or v > par[base] (k = 0) "
        "and v < par[base + k + 1], so span > 0",
    ("return k, min(max(f, 0.0), 1.0)", "1.0 -> 2.0 (col 31)"):
        "f < 1 already: v < par[base + k + 1] at the loop's exit (v at or above the last "
        "node returned before it)",
}

if __name__ == "__main__":
    raise SystemExit(main())
