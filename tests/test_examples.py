"""The scripts of examples/: each runs in a fresh interpreter with DeprecationWarnings as errors, exits 0,
prints its results, writes its files into the build folder it is given (``$OPTDESIGN_EXAMPLES_OUT``) and
nothing into the source tree, and leaves stderr empty -- no warning of the library's own, nothing printed
by CasADi/IPOPT or cvxpy (captured at the file-descriptor level: the child's fd 2 is a pipe, so C++
output counts too).

The nine scripts take 3 to 80 s each (the longest run with ``--quick`` where they have it), hence
``slow``: ``.ci/run`` runs them in its ``-m slow`` step.
"""

from __future__ import annotations

import ast
import os
import subprocess
import sys
from pathlib import Path

import pytest

from optdesign.plot import FIGURE_DPI

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
SCRIPTS = sorted(EXAMPLES.glob("*.py"))
#: scripts with a shorter mode (fewer lengths, replications or sweep points; the same code paths)
QUICK = {"estimate_noise", "robust_aircraft"}


def _tree_state(folder: Path) -> dict[str, float]:
    return {str(p.relative_to(folder)): p.stat().st_mtime_ns for p in folder.rglob("*")
            if p.is_file() and "_build" not in p.parts and "__pycache__" not in p.parts}


def test_every_script_says_how_to_run_it():
    for script in SCRIPTS:
        doc = ast.get_docstring(ast.parse(script.read_text(encoding="utf-8"))) or ""
        assert f"examples/{script.name}" in doc, f"{script.name}: its docstring does not say how to run it"


def test_no_script_writes_beside_the_sources():
    """Static check (fast): every output folder of a script comes from the build folder."""
    for script in SCRIPTS:
        text = script.read_text(encoding="utf-8")
        assert "OPTDESIGN_EXAMPLES_OUT" in text, f"{script.name} does not honour $OPTDESIGN_EXAMPLES_OUT"
        assert '/ "figures"' not in text, f"{script.name} writes into examples/figures/"


@pytest.mark.slow
@pytest.mark.parametrize("script", SCRIPTS, ids=lambda p: p.stem)
def test_example_runs_cleanly(script, tmp_path):
    out = tmp_path / "out"
    before = _tree_state(EXAMPLES)
    cmd = [sys.executable, "-W", "error::DeprecationWarning", str(script)]
    cmd += ["--quick"] if script.stem in QUICK else []
    env = {**os.environ, "OPTDESIGN_EXAMPLES_OUT": str(out), "MPLBACKEND": "Agg",
           "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1",
           # the optdesign of this checkout, not another install
           "PYTHONPATH": os.pathsep.join([str(ROOT), *filter(None, [os.environ.get("PYTHONPATH")])])}
    env.pop("PYTHONWARNINGS", None)
    proc = subprocess.run(cmd, cwd=tmp_path, env=env, stdin=subprocess.DEVNULL, capture_output=True,
                          text=True, timeout=900)
    assert proc.returncode == 0, f"{script.name} exited {proc.returncode}:\n{proc.stderr[-4000:]}"
    assert proc.stderr == "", f"{script.name} wrote to stderr:\n{proc.stderr[-4000:]}"
    assert len(proc.stdout.splitlines()) >= 5, f"{script.name} printed too little:\n{proc.stdout}"
    written = [p for p in out.rglob("*") if p.is_file()] if out.is_dir() else []
    pngs = [p for p in written if p.suffix == ".png"]
    assert pngs, f"{script.name} wrote no figure into {out}"
    Image = pytest.importorskip("PIL.Image")
    for png in pngs:  # the seed papers' figures too (paper001 and paper002 were pinned at 120 dpi)
        with Image.open(png) as im:
            assert round(im.info["dpi"][0]) == FIGURE_DPI, f"{png.name}: {im.info['dpi']} dpi"
    assert _tree_state(EXAMPLES) == before, f"{script.name} changed files in examples/"
    assert not list(tmp_path.glob("*_results")), f"{script.name} wrote into the working directory"


def test_seed002_figures_at_the_library_resolution(tmp_path):
    """paper002 pinned its figures at 120 dpi (paper001 too), below every other figure's 300."""
    pytest.importorskip("matplotlib")
    Image = pytest.importorskip("PIL.Image")
    from optdesign.studies import paper002

    rep = paper002.reproduce(tmp_path, quick=True)
    assert len(rep.figures) == 2
    for path in rep.figures:
        with Image.open(path) as im:
            assert round(im.info["dpi"][0]) == FIGURE_DPI, f"{Path(path).name}: {im.info['dpi']} dpi"
