"""The built wheel, installed into a fresh venv, runs the main job and ships LICENSE and py.typed.

Builds the wheel with pip (PEP 517, isolated build) from a copy of the source tree, so nothing is
written into the checkout; installs it with its dependencies from the package index into a new venv;
runs ``optdesign kalman`` there, outside the source tree; and reads the installed distribution's files
and metadata with ``importlib.metadata``.  About 20 s of CPU and 1-2 minutes of wall time (mostly the
dependencies' download), hence ``slow``.  Skipped, with the reason, only when the package index cannot
be reached (the build backend and the dependencies come from it); any other failure fails.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: not part of a source tree (VCS, caches, builds, local venvs)
IGNORE = shutil.ignore_patterns(".git", ".ci-venv", ".venv", "venv", "_build", "build", "dist", "__pycache__",
                                "*.egg-info", ".pytest_cache", ".hypothesis", ".ruff_cache", ".mypy_cache")

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

#: slow; one xdist group, so that the module fixture (the build) runs once under --dist loadgroup
pytestmark = [pytest.mark.slow, pytest.mark.xdist_group("wheel")]


def _run(cmd: list[str], cwd: Path, what: str) -> subprocess.CompletedProcess:
    proc = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True)
    if proc.returncode != 0:
        probe = subprocess.run([sys.executable, "-m", "pip", "download", "--no-deps", "-q", "-d",
                                str(cwd / "probe"), "setuptools>=77"], capture_output=True, text=True)
        if probe.returncode != 0:
            pytest.skip(f"{what} needs the package index, which cannot be reached: "
                        f"{(probe.stderr or probe.stdout).strip().splitlines()[-1:]}")
        pytest.fail(f"{what} failed (exit {proc.returncode}):\n{proc.stdout[-2000:]}\n{proc.stderr[-3000:]}")
    return proc


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    """(wheel path, venv python, venv bin folder, work dir) of a fresh install of the built wheel."""
    tmp = tmp_path_factory.mktemp("wheel")
    src = tmp / "src"
    shutil.copytree(ROOT, src, ignore=IGNORE)
    wheel_cmd = [sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "--wheel-dir", str(tmp / "dist")]
    _run([*wheel_cmd, str(src)], tmp, "building the wheel")
    wheels = sorted((tmp / "dist").glob("optdesign_control-*.whl"))
    assert len(wheels) == 1, wheels
    _run([sys.executable, "-m", "venv", str(tmp / "venv")], tmp, "creating a venv")
    bindir = tmp / "venv" / ("Scripts" if sys.platform == "win32" else "bin")
    python = bindir / "python"
    _run([str(python), "-m", "pip", "install", "-q", str(wheels[0])], tmp, "installing the wheel")
    work = tmp / "work"
    work.mkdir()
    return wheels[0], python, bindir, work


def test_wheel_contains_license_typing_marker_and_problem_data(installed):
    wheel = installed[0]
    names = zipfile.ZipFile(wheel).namelist()
    assert "optdesign/py.typed" in names
    assert any(n.endswith(".dist-info/licenses/LICENSE") for n in names), [n for n in names if "info/" in n]
    data = "optdesign/_problem_data/"
    shipped = {n[len(data):] for n in names if n.startswith(data) and n.endswith(".json")}
    on_disk = {p.relative_to(ROOT / "problems").as_posix() for p in (ROOT / "problems").rglob("*.json")}
    assert shipped == on_disk, f"problem files missing from the wheel: {sorted(on_disk - shipped)}"


def test_fresh_install_runs_the_main_job(installed):
    _, _, bindir, work = installed
    proc = subprocess.run([str(bindir / "optdesign"), "kalman", "--json"], cwd=work, capture_output=True,
                          text=True)
    assert proc.returncode == 0, proc.stderr[-3000:]
    out = json.loads(proc.stdout)
    assert out["problem"] == "chang_lee_1984_ex1" and out["success"] is True, out
    assert out["verification"] and all(c["passed"] for c in out["verification"].values()), out["verification"]


def test_installed_distribution_metadata(installed):
    _, python, _, work = installed
    script = """if True:
        import importlib.metadata as md, json, optdesign
        d = md.distribution("optdesign-control")
        files = [str(f) for f in d.files]
        licence = [f for f in d.files if str(f).endswith("licenses/LICENSE")]
        print(json.dumps({
            "module": optdesign.__file__, "files": files,
            "license": d.metadata.get("License-Expression"),
            "license_files": d.metadata.get_all("License-File"),
            "urls": d.metadata.get_all("Project-URL") or [],
            "license_text": d.locate_file(licence[0]).read_text() if licence else None,
        }))
    """
    proc = subprocess.run([str(python), "-c", script], cwd=work, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr[-3000:]
    meta = json.loads(proc.stdout)
    assert not Path(meta["module"]).is_relative_to(ROOT), "the fresh venv imported the source tree"
    assert "optdesign/py.typed" in meta["files"]
    assert meta["license"] == "BSD-3-Clause" and meta["license_files"] == ["LICENSE"]
    assert meta["license_text"] == (ROOT / "LICENSE").read_text()
    assert "BSD 3-Clause License" in meta["license_text"]
    declared = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"].get("urls", {})
    assert sorted(meta["urls"]) == sorted(f"{k}, {v}" for k, v in declared.items())
