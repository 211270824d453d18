"""tools.evidence.mutate finds and applies the mutations it documents (the tool, not a mutation run)."""
from __future__ import annotations

import ast

import pytest

from tools.evidence.mutate import find_mutants

SOURCE = '''\
def law(x, a, b):
    # Eq. 9: y = a x - b / 2
    y = a * x[0 + 1] - b / 2.0
    y += -a
    return y


def other(a):
    return a + 1.0
'''


def test_mutants_of_one_function(tmp_path):
    path = tmp_path / "mod.py"
    path.write_text(SOURCE)
    found = find_mutants(path, functions=("law",))
    changes = {(m.line, m.kind, m.change) for m, _ in found}
    # GIVEN one difference, one product, one quotient, one augmented sum, one unary minus
    # and one float constant; THEN each kind is proposed, and the index x[0 + 1] is not
    assert (3, "sign", "'-' -> '+'") in changes
    assert (3, "drop", "drop right term of '-'") in changes
    assert (3, "drop", "drop left term of '-'") in changes
    assert (3, "muldiv", "'*' -> '/'") in changes and (3, "muldiv", "'/' -> '*'") in changes
    assert (3, "const", "2.0 -> 4.0 (col 27)") in changes
    assert (4, "sign", "'+=' -> '-='") in changes and (4, "sign", "unary '-' removed") in changes
    assert all(m.function == "law" for m, _ in found)          # other() untouched
    assert all(m.equation.startswith("Eq. 9") for m, _ in found if m.line == 3)
    assert len(found) == 8
    # each mutant is exactly one change: it parses, differs from the original, and the
    # original is intact afterwards (mutations are applied to a copy)
    base = ast.unparse(ast.parse(SOURCE))
    sources = {src for _, src in found}
    assert len(sources) == len(found) and base not in sources
    for _, src in found:
        ast.parse(src)
    assert path.read_text() == SOURCE
    dropped = [src for m, src in found if m.change == "drop left term of '-'"][0]
    assert "y = -(b / 2.0)" in dropped


def test_exec_into_rebinds_names_imported_elsewhere(tmp_path, monkeypatch):
    """A mutant of one law module reaches the modules that imported its functions by name."""
    import importlib
    import sys

    from tools.evidence.mutate import exec_into

    # GIVEN module a with f, and module b that did `from a import f` and calls it
    (tmp_path / "test_mut_a.py").write_text("def f(x):\n    return x + 1.0\n")
    (tmp_path / "test_mut_b.py").write_text(
        "from test_mut_a import f\n\n\ndef g(x):\n    return 2.0 * f(x)\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    try:
        a = importlib.import_module("test_mut_a")
        b = importlib.import_module("test_mut_b")
        assert b.g(1.0) == 4.0
        original = (tmp_path / "test_mut_a.py").read_text()
        # WHEN a mutated source is executed into a
        n = exec_into(a, original.replace("+", "-"), prefixes=("test_mut_",))
        # THEN b's name f is the mutated function; restoring the source restores b
        assert n == 1 and b.f is a.f and b.g(1.0) == 0.0
        exec_into(a, original, prefixes=("test_mut_",))
        assert b.g(1.0) == 4.0
    finally:
        sys.modules.pop("test_mut_a", None)
        sys.modules.pop("test_mut_b", None)


def test_default_tests_are_found_in_the_tree(tmp_path):
    """tools.evidence.mutate looks its test files up under tests/ (a moved file is still found; a
    missing or duplicated one is an error, not a silently shorter run)."""
    from tools.evidence.mutate import DEFAULT_TESTS, ROOT, find_tests

    found = find_tests(DEFAULT_TESTS)
    assert len(found) == len(DEFAULT_TESTS)
    for node in found:
        assert (ROOT / node.split("::")[0]).is_file(), node
    # GIVEN a tree where the file moved one folder down: it is found there
    (tmp_path / "tests" / "unit" / "deep").mkdir(parents=True)
    (tmp_path / "tests" / "unit" / "deep" / "test_x.py").write_text("")
    assert find_tests(["test_x.py::test_a"], tmp_path) == ["tests/unit/deep/test_x.py::test_a"]
    # a file that is nowhere, or in two places, or an explicit path that does not exist
    (tmp_path / "tests" / "test_x.py").write_text("")
    for bad in (["test_missing.py"], ["test_x.py"], ["tests/test_law_equations.py"]):
        with pytest.raises(FileNotFoundError):
            find_tests(bad, tmp_path)


def test_named_mutants_apply_exactly_once():
    """Each hand-made mutant's text is in its file exactly once, and changes only that."""
    from tools.evidence.mutate import NAMED, ROOT, named_mutants

    found = named_mutants()
    assert [m.equation for m, _ in found] == [n.what for n in NAMED]
    for (m, src), n in zip(found, NAMED):
        original = (ROOT / n.file).read_text()
        assert src != original and src.replace(n.new, n.old, 1) == original
        assert n.old.strip("(") in m.source and m.kind == "named"
    with pytest.raises(ValueError):
        named_mutants([NAMED[0].__class__(NAMED[0].file, "f", "no such text", "x", "w")])


@pytest.mark.slow
def test_quick_mutation_run_kills_every_mutant():
    """`python -m tools.evidence.mutate --quick`: the hand-made mutants (Eqs. 30 and 36 signs and gains)
    and a sign flip per main kernel, against the law's unit tests found in the tree: every one
    is killed (a moved test file, a weakened test or a surviving sign flip fails here).
    About 12 s of CPU."""
    import subprocess
    import sys

    from tools.evidence.mutate import NAMED, QUICK_SIGN_FUNCTIONS, ROOT

    r = subprocess.run([sys.executable, "-m", "tools.evidence.mutate", "--quick"], cwd=ROOT,
                       capture_output=True, text=True, timeout=280)
    n = len(NAMED) + len(QUICK_SIGN_FUNCTIONS)
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    assert f"{n} mutants, {n} killed, 0 survived" in r.stdout, r.stdout[-2000:]
