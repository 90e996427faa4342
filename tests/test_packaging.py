"""Packaging and project hygiene: what a fresh install and CI rely on."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

import optdesign

ROOT = Path(__file__).resolve().parents[1]

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib


def _pyproject():
    return tomllib.loads((ROOT / "pyproject.toml").read_text())


def test_every_package_is_listed_in_pyproject():
    listed = set(_pyproject()["tool"]["setuptools"]["packages"])
    on_disk = {
        ".".join(p.parent.relative_to(ROOT).parts)
        for p in (ROOT / "optdesign").rglob("__init__.py")
        if "__pycache__" not in p.parts
    }
    missing = on_disk - listed
    assert not missing, f"add to [tool.setuptools] packages in pyproject.toml: {sorted(missing)}"
    assert "optdesign._problem_data" in listed


def test_runtime_dependencies():
    deps = " ".join(_pyproject()["project"]["dependencies"])
    for name in ("numpy", "scipy", "casadi", "cvxpy", "scs", "clarabel"):
        assert name in deps


def test_readme_commands_match_ci():
    readme = (ROOT / "README.md").read_text()
    ci = (ROOT / ".ci" / "run").read_text()
    test_cmd = re.findall(r"^python -m pytest.*$", ci, flags=re.M)
    assert len(test_cmd) == 1, "the CI script must run exactly one pytest command"
    assert test_cmd[0] in readme, f"README must show the CI test command {test_cmd[0]!r}"
    install = re.search(r'pip install -q -e "\.\[([a-z,]+)\]"', ci)
    assert install and f'pip install -e ".[{install.group(1)}]"' in readme


def test_problem_data_is_package_data():
    from importlib import resources

    root = resources.files("optdesign._problem_data")
    files = [p for p in root.iterdir()]
    assert any(p.is_dir() for p in files), "problem sub-folders are installed"


def test_import_is_lazy():
    code = (
        "import sys, optdesign; "
        "heavy = [m for m in ('casadi', 'cvxpy', 'matplotlib', 'control', 'dask') if m in sys.modules]; "
        "print(','.join(heavy))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "", f"import optdesign pulled in {out.stdout.strip()}"


def test_public_names_resolve():
    missing = []
    for name in optdesign.__all__:
        try:
            getattr(optdesign, name)
        except (AttributeError, ImportError) as exc:
            missing.append(f"{name}: {exc}")
    assert not missing, missing
    with pytest.raises(AttributeError, match="has no attribute 'nope'"):
        optdesign.nope  # noqa: B018


def test_submodule_aliases():
    assert optdesign.metrics.eta is optdesign.analysis.metrics.eta
    assert optdesign.regions.Disk is optdesign.model.regions.Disk
    assert optdesign.riccati.filter_are is optdesign.classical.riccati.filter_are


def test_distribution_name_is_our_own():
    """The package index's ``optdesign`` is an unrelated project (a linear optimal design package,
    1.0.0, same import name): we publish as ``optdesign-control``; the import name stays ``optdesign``
    and the extras refer to our own distribution."""
    project = _pyproject()["project"]
    assert project["name"] == "optdesign-control"
    extras = " ".join(" ".join(v) for v in project["optional-dependencies"].values())
    assert "optdesign[" not in extras.replace("optdesign-control[", "")
    import optdesign

    assert optdesign.__version__ == project["version"]
    readme = (ROOT / "README.md").read_text()
    assert 'pip install optdesign-control' in readme
