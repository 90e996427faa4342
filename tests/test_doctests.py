"""The Examples sections of the docstrings run and print what they say (they are the documentation site's
examples too).  Each module's doctests run with ``doctest``'s default comparison: the examples round
what they print, so that they do not depend on the last digits of another CPU."""

from __future__ import annotations

import doctest
import importlib
import pkgutil

import pytest

import optdesign


def _modules() -> list[str]:
    names = [optdesign.__name__]
    for info in pkgutil.walk_packages(optdesign.__path__, prefix="optdesign."):
        if not info.name.startswith("optdesign._problem_data") and not info.name.endswith("__main__"):
            names.append(info.name)
    return names


def _with_examples(name: str) -> bool:
    mod = importlib.import_module(name)
    return any(t.examples for t in doctest.DocTestFinder().find(mod, name))


MODULES = [m for m in _modules() if _with_examples(m)]


def test_there_are_examples_to_run():
    assert len(MODULES) >= 15, MODULES  # the verbs, the regions, the metrics, ... all have examples


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples(name):
    mod = importlib.import_module(name)
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    out: list[str] = []
    for test in doctest.DocTestFinder().find(mod, name):
        runner.run(test, out=out.append)
    result = runner.summarize(verbose=False)
    assert result.failed == 0, "".join(out)
