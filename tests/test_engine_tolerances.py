"""The engines hold no tolerance literal: every threshold is named in optdesign/engines/tolerances.py
(issue 29), and the shared building blocks (sym, commutation) are defined once."""

from __future__ import annotations

import ast
import io
import re
import tokenize
from pathlib import Path

import numpy as np
import pytest

import optdesign
from optdesign.analysis.linalg import commutation, sym
from optdesign.engines import tolerances

ENGINES = Path(optdesign.__file__).parent / "engines"
PACKAGE = Path(optdesign.__file__).parent
#: modules whose literals have not moved to the table yet (none: every engine file is covered)
PENDING: set[str] = set()


def _engine_modules():
    return sorted(p for p in ENGINES.glob("*.py") if p.name not in PENDING | {"tolerances.py"})


def _exponent_literals(path: Path) -> list[str]:
    """Numbers written with an exponent (1e-8, 1e3, 2.5E-4) in code, not in strings or comments."""
    out = []
    for tok in tokenize.generate_tokens(io.StringIO(path.read_text()).readline):
        hexa = tok.string.lower().startswith("0x")
        if tok.type == tokenize.NUMBER and re.search(r"[eE]", tok.string) and not hexa:
            out.append(f"{path.name}:{tok.start[0]}: {tok.string}")
    return out


@pytest.mark.parametrize("path", _engine_modules(), ids=lambda p: p.name)
def test_no_tolerance_literal_in_engine_code(path):
    assert _exponent_literals(path) == []
    assert "finfo" not in path.read_text(), "use tolerances.EPS"


def test_every_table_entry_is_exported_and_documented():
    src = (ENGINES / "tolerances.py").read_text()
    tree = ast.parse(src)
    names = [t.id for node in tree.body if isinstance(node, (ast.Assign, ast.AnnAssign))
             for t in (node.targets if isinstance(node, ast.Assign) else [node.target])
             if isinstance(t, ast.Name) and t.id.isupper()]
    assert sorted(names) == sorted(n for n in tolerances.__all__ if n.isupper())
    lines = src.splitlines()
    for node in tree.body:
        if isinstance(node, (ast.Assign, ast.AnnAssign)) and getattr(node, "target", None) is None \
                and node.targets[0].id == "__all__":
            continue
        if isinstance(node, (ast.Assign, ast.AnnAssign)):
            # a comment line (#: ...) above each entry, or the entry shares the comment of the one before
            above = lines[node.lineno - 2].strip()
            assert above.startswith("#") or re.match(r"^[A-Z_]+ = ", above), lines[node.lineno - 1]


def test_rounding_level_is_the_product_it_replaced():
    eps = np.finfo(float).eps
    for size, scale, factor in [(7, 3.5, 1e3), (1, 2.0, 100.0), (12, 1e-3, 1.0), (3, 0.0, 8.0)]:
        assert tolerances.rounding_level(size, scale, factor) == factor * size * eps * scale


def test_one_sym_and_one_commutation():
    defs = []
    for p in PACKAGE.rglob("*.py"):
        for node in ast.walk(ast.parse(p.read_text())):
            if isinstance(node, ast.FunctionDef) and node.name.lstrip("_") in ("sym", "commutation"):
                defs.append(f"{p.relative_to(PACKAGE)}:{node.name}")
    assert sorted(defs) == ["analysis/linalg.py:commutation", "analysis/linalg.py:sym"]
    rng = np.random.default_rng(0)
    V = rng.standard_normal((3, 4))
    assert np.array_equal(commutation(3, 4) @ V.ravel(order="F"), V.T.ravel(order="F"))
    X = rng.standard_normal((4, 4))
    S = sym(X)
    assert np.array_equal(S, S.T) and np.allclose(S, (X + X.T) / 2, rtol=0, atol=0)
