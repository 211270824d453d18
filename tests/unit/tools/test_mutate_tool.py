"""tools.mutate finds and applies the mutations it documents (the tool, not a mutation run)."""
from __future__ import annotations

import ast

from tools.mutate import find_mutants

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

    from tools.mutate import exec_into

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
