"""The studies sub-commands: `optdesign design`, `optdesign study`, `optdesign reproduce`.

Every user error (bad argument, bad spec file) is one line on stderr naming the field, exit code 2,
no traceback.
"""

from __future__ import annotations

import csv
import json
import os
import re
import sys
import types
from pathlib import Path

import numpy as np
import pytest

from optdesign import problems
from optdesign.cli import main
from optdesign.errors import BackendUnavailableError
from optdesign.regions import Disk, HalfPlane, Sector
from optdesign.studies.reproduce import PAPERS, PaperReproduction, ReproRow, paper_id, reproduce_all
from optdesign.studies.spec import load_spec, parse_poles, parse_region


@pytest.fixture(autouse=True)
def _in_tmp(tmp_path, monkeypatch):
    """Every test runs in its own folder: a study writes into the current directory."""
    monkeypatch.chdir(tmp_path)


def run(argv, capsys):
    code = main(argv)
    cap = capsys.readouterr()
    return code, cap.out, cap.err


def assert_one_line_error(code, err, match):
    assert code == 2, err
    assert err.startswith("optdesign: error: ")
    assert err.count("\n") == 1, err
    assert "Traceback" not in err
    assert match in err, err


# ------------------------------------------------------------------ design


def test_design_inverse_json(capsys):
    code, out, _ = run(["design", "chang_lee_1984_ex1", "--method", "inverse", "--json"], capsys)
    d = json.loads(out)
    assert code == 0 and d["success"] is True and d["method"] == "inverse"
    np.testing.assert_allclose(np.ravel(d["L"]), [8.0, -6.0], atol=1e-7)  # seed 000, Example 1
    Q = np.array(d["Q"])
    assert np.min(np.linalg.eigvalsh(Q)) >= -1e-9 * max(1.0, np.abs(Q).max())
    assert d["verification"]["pole_error"]["passed"] is True


def test_design_place_and_kalman_text(capsys):
    code, out, _ = run(["design", "pp_knv1985_ex1", "--method", "place", "--poles", "-1, -2, -3+1j, -3-1j"],
                       capsys)
    assert code == 0 and "status: solved" in out and "pole_error" in out
    code, out, _ = run(["design", "pp_knv1985_ex1", "--method", "place", "--json"], capsys)
    d = json.loads(out)
    plant = problems.load("pp_knv1985_ex1").plant
    poles = np.linalg.eigvals(plant.A - np.array(d["L"]) @ plant.C)
    np.testing.assert_allclose(np.sort(poles.real), np.sort(problems.load("pp_knv1985_ex1").targets["poles"]),
                               rtol=1e-6)
    code, out, _ = run(["design", "compleib_he1", "--method", "kalman", "--riccati", "hamiltonian"], capsys)
    assert code == 0 and "riccati_residual" in out and "kappa2 =" in out


@pytest.mark.parametrize("spelling", [["--poles", "-1,-2,-3,-4"], ["--poles=-1,-2,-3,-4"],
                                      ["--poles", " -1, -2, -3, -4"], ["--poles", "-1, -2, -3, -4"],
                                      ["--poles", "-4;-3;-2;-1"]])
def test_design_poles_spellings(spelling, capsys):
    # issue 11, item 6: `--poles -1,-2` was rejected by argparse ("expected one argument")
    code, out, err = run(["design", "pp_knv1985_ex1", "--method", "place", *spelling, "--json"], capsys)
    assert code == 0, err
    d = json.loads(out)
    assert d["success"] is True
    np.testing.assert_allclose(np.sort(np.asarray(d["target"]["re"])), [-4.0, -3.0, -2.0, -1.0])
    assert d["verification"]["stability_margin"]["passed"] is True


def test_negative_values_of_every_numeric_option():
    from optdesign.cli import build_parser, join_negative_values

    argv = ["design", "compleib_dis2", "--method", "well_conditioned", "--alpha", "-1e-3", "--radius", "-.5",
            "--max-gain", "-2", "--seed", "-1", "--poles", "-1,-2,-3"]
    args = build_parser().parse_args(join_negative_values(argv))
    got = (args.alpha, args.radius, args.max_gain, args.seed, args.poles)
    assert got == (-1e-3, -0.5, -2.0, -1, "-1,-2,-3")
    assert join_negative_values(["--poles", "-1", "--json"]) == ["--poles=-1", "--json"]
    assert join_negative_values(["show", "--", "--x", "-1"]) == ["show", "--", "--x", "-1"]
    assert join_negative_values(["--region", "halfplane:1"]) == ["--region", "halfplane:1"]


def test_design_place_refuses_to_call_unstable_poles_a_success(capsys):
    # issue 11, item 6: `--method place --poles=1,2,3,4` reported success: True for unstable A - L C
    code, out, _ = run(["design", "pp_knv1985_ex1", "--method", "place", "--poles=1,2,3,4", "--json"], capsys)
    d = json.loads(out)
    assert code == 1 and d["success"] is False and d["status"] == "solved"
    assert d["verification"]["pole_error"]["passed"] is True  # the poles were placed as asked...
    assert d["verification"]["stability_margin"]["passed"] is False  # ...but they are not an observer's
    assert d["verification"]["stability_margin"]["value"] == pytest.approx(-4.0)  # -max Re eig(A - L C)
    assert "A - L C is not stable" in d["message"] and "Re s < 0" in d["message"]
    code, out, _ = run(["design", "pp_knv1985_ex1", "--method", "place", "--poles", "-1,-2,-3,0"], capsys)
    assert code == 1 and "success: False" in out and "[FAIL] stability_margin" in out


def test_stability_check_uses_the_time_domain_of_the_plant():
    from optdesign.cli.design import with_stability_check
    from optdesign.studies.designers import place_baseline

    plant = problems.load("pp_knv1985_ex1").plant.replace(dt=0.1)  # discrete: |z| < 1 is stable
    ok = with_stability_check(plant, place_baseline(plant, [0.5, -0.5, 0.2, 0.1]))
    assert ok.success and ok.verification["stability_margin"].value == pytest.approx(0.5)
    bad = with_stability_check(plant, place_baseline(plant, [-1.5, -0.5, 0.2, 0.1]))  # stable if continuous
    assert not bad.success and "|z| < 1" in bad.message
    assert bad.verification["stability_margin"].value == pytest.approx(-0.5)


def test_design_well_conditioned_in_a_region(capsys):
    code, out, _ = run(["design", "compleib_dis2", "--method", "well_conditioned", "--region",
                        "halfplane:1 & sector:0.7", "--radius", "20", "--starts", "2", "--json"], capsys)
    d = json.loads(out)
    assert code == 0 and d["success"] is True
    plant = problems.load("compleib_dis2").plant
    poles = np.linalg.eigvals(plant.A - np.array(d["L"]) @ plant.C)  # recomputed here, not trusted
    assert (HalfPlane(1.0) & Sector.from_damping(0.7) & Disk(0.0, 20.0)).contains(poles, tol=1e-6)
    assert d["region"]["type"] == "Intersection"
    assert d["kappa2"] >= 1.0


@pytest.mark.parametrize(
    "argv, match",
    [
        (["design", "compleib_dis2"], "the following arguments are required: --method"),
        (["design", "compleib_dis2", "--method", "magic"], "argument --method: invalid choice: 'magic'"),
        (["design", "no_such_problem", "--method", "kalman"], "no problem named 'no_such_problem'"),
        (["design", "compleib_dis2", "--method", "well_conditioned", "--region", "circle:3"],
         "--region: unknown shape 'circle'"),
        (["design", "compleib_dis2", "--method", "well_conditioned", "--region", "sector:abc"],
         "--region: 'abc' in 'sector:abc' is not a number"),
        (["design", "compleib_dis2", "--method", "well_conditioned", "--region", "sector:1.2"],
         "--region: 'sector:1.2': Sector.from_damping zeta must be in (0, 1)"),
        (["design", "compleib_dis2", "--method", "well_conditioned", "--region", "disk:1,2,3"],
         "--region: 'disk:1,2,3' has 3 number(s)"),
        (["design", "compleib_dis2", "--method", "well_conditioned", "--region", "halfplane:5 & disk:1"],
         "--region: the intersection"),
        (["design", "compleib_dis2", "--method", "well_conditioned", "--region", "halfplane:1 &"],
         "--region: empty member"),
        (["design", "compleib_dis2", "--method", "well_conditioned", "--zeta", "1.5"],
         "--zeta: Sector.from_damping zeta must be in (0, 1); found 1.5"),
        (["design", "compleib_dis2", "--method", "well_conditioned", "--alpha", "fast"],
         "argument --alpha: invalid float value: 'fast'"),
        (["design", "compleib_dis2", "--method", "well_conditioned", "--radius", "-2"],
         "--radius must be a positive number"),
        (["design", "compleib_dis2", "--method", "well_conditioned", "--max-gain", "0"],
         "--max-gain must be a positive number"),
        (["design", "compleib_dis2", "--method", "well_conditioned", "--starts", "0", "--alpha", "1"],
         "--starts must be >= 1"),
        (["design", "compleib_dis2", "--method", "well_conditioned"],
         "needs --poles or a region (--region/--alpha/--zeta/--radius)"),
        (["design", "compleib_dis2", "--method", "well_conditioned", "--poles=-1,-2,-3", "--alpha", "1"],
         "give either --poles (fixed poles) or a region"),
        (["design", "compleib_dis2", "--method", "place", "--poles", "-1,-2,-3,-4"],
         "--poles has the wrong length: expected 3, found 4"),  # -1,-2,... is read as a value, not an option
        (["design", "compleib_dis2", "--method", "place", "--json", "-1,-2,-3"],
         "argument --json: ignored explicit argument '-1,-2,-3'"),
        (["design", "compleib_dis2", "--method", "place", "--poles", "-1, -2, x"], "--poles: 'x' is not a "
                                                                                   "number"),
        (["design", "compleib_dis2", "--method", "place", "--poles", "-1, -2"],
         "--poles has the wrong length: expected 3, found 2"),
        (["design", "compleib_dis2", "--method", "place", "--poles", "-1, -2+1j, -3"], "not closed under"),
        (["design", "compleib_dis2", "--method", "place"], "problem 'compleib_dis2' has no target poles: "
                                                           "give --poles"),
        (["design", "compleib_dis2", "--method", "kalman", "--poles=-1,-2,-3"],
         "--poles does not apply to --method kalman"),
        (["design", "compleib_dis2", "--method", "place", "--alpha", "1", "--poles=-1,-2,-3"],
         "--region/--alpha/--zeta/--radius does not apply to --method place"),
        (["design", "compleib_dis2", "--method", "inverse", "--objective", "kappa2"],
         "--objective: 'kappa2' is not an objective of --method inverse"),
        (["design", "compleib_dis2", "--method", "kalman", "--max-gain", "3"],
         "--max-gain does not apply to --method kalman"),
        (["design", "jung_huh_ex1", "--method", "kalman"], "has no noise model"),
        (["design", "jung_huh_ex1", "--method", "inverse", "--poles=-1,-2"], "has no measurement-noise"),
        (["design", "carex_1.3", "--method", "kalman"], "problem 'carex_1.3' has no valid plant"),
        (["design", "compleib_dis2", "--method", "well_conditioned", "--alpha", "inf"],
         "--alpha must be finite"),
        (["design", "compleib_dis2", "--method", "well_conditioned", "--alpha", "1", "--seed", "-1"],
         "--seed must be >= 0; found -1"),
        (["design", "compleib_dis2", "--method", "well_conditioned", "--alpha", "1", "--objective", "trace"],
         "--objective: 'trace' is not an objective of --method well_conditioned"),
    ],
)
def test_design_errors_are_one_line_exit_2(argv, match, capsys):
    code, _, err = run(argv, capsys)
    assert_one_line_error(code, err, match)


def test_region_and_pole_syntax():
    r = parse_region("halfplane:1.5 & sector:0.7 & disk:20 & strip:-30,0 & hstrip:9 & ellipse:-5,10,8")
    assert r.contains([-2.0, -3 + 1j, -3 - 1j]) and not r.contains([-1.0])
    assert parse_region("stable").contains([-1e-3]) and parse_region("disk:-1,0.5").contains([-1.2])
    np.testing.assert_allclose(parse_poles("-1; -2, -3+1j, -3-1i"), [-1, -2, -3 + 1j, -3 - 1j])
    assert parse_poles([-1, "-2+1j", "-2-1j"]).dtype == complex


# ------------------------------------------------------------------ study

GOOD_SPEC = """
[study]
name = "tiny"
problem = "compleib_nn8"
design = "well_conditioned"
executor = "serial"
chunksize = 2

[fixed]
radius = 10.0
region = "hstrip:5"

[grid]
alpha = {start = 0.5, stop = 1.0, num = 2}
zeta = [0.4, 0.8]

[figure]
x = "alpha"
y = ["kappa2", "gain_norm"]
series = "zeta"
"""


def test_study_runs_a_spec(tmp_path, capsys):
    spec = tmp_path / "tiny.toml"
    spec.write_text(GOOD_SPEC)
    code, out, err = run(["study", str(spec), "--no-progress"], capsys)
    assert code == 0, err
    assert "4 points, 4 successful" in out
    head = f"study tiny: compleib_nn8, design well_conditioned, 4 points on serial -> tiny_results{os.sep}"
    assert out.splitlines()[0] == head
    # the results go to the current directory (tmp_path here), never next to the spec file
    rows = list(csv.DictReader((tmp_path / "tiny_results" / "tiny.csv").open()))
    assert len(rows) == 4 and {r["zeta"] for r in rows} == {"0.4", "0.8"}
    assert all(r["success"] == "True" for r in rows)
    assert all(float(r["max_real_pole"]) <= -float(r["alpha"]) + 1e-6 for r in rows)
    png = tmp_path / "tiny_results" / "tiny_kappa2_gain_norm.png"
    assert png.stat().st_size > 10_000
    data = json.loads((tmp_path / "tiny_results" / "tiny.json").read_text())
    assert len(data["records"]) == 4 and data["meta"]["design"] == "well_conditioned"
    # JSON summary, output folder overridden, another executor
    code, out, _ = run(["study", str(spec), "--json", "--out", str(tmp_path / "o2"), "--executor", "threads",
                        "--workers", "2", "--no-progress"], capsys)
    summary = json.loads(out)
    assert code == 0 and summary["points"] == 4 and summary["successful"] == 4
    assert Path(summary["csv"]).parent == tmp_path / "o2"


def test_study_spec_other_designs(tmp_path):
    spec = tmp_path / "noise.toml"
    spec.write_text("""
[study]
problem = "compleib_he1"
design = "kalman"
executor = "serial"
[grid]
q = {start = 0.01, stop = 100.0, num = 3, log = true}
[figure]
x = "q"
y = "eta"
logx = true
""")
    from optdesign.studies.spec import run_spec

    res = run_spec(spec, progress=False)
    assert res.table.n_success == 3 and res.table.column("q").tolist() == pytest.approx([0.01, 1.0, 100.0])
    assert res.figures[0].name == "noise_eta.png"
    spec2 = tmp_path / "target.toml"
    spec2.write_text("""
[study]
problem = "chang_lee_1984_ex1"
design = "inverse"
executor = "serial"
[grid]
scale = [0.5, 1.0]
shift = [0.0, 6.0]
""")
    t = run_spec(spec2, progress=False).table
    # a target pole moved into the right half-plane is infeasible for every Kalman filter
    assert [r["success"] for r in t] == [True, False, True, False]
    assert {r["certificate"] for r in t if not r["success"]} == {"unstable_target"}


BAD_SPECS = [
    ("[study]\nproblem = 'compleib_nn8'\ndesign = 'well_conditioned'\n[grid]\nalpha = [1.0]\n[extra]\na = "
     "1\n",
     "tiny.toml: extra: unknown section"),
    ("[grid]\nalpha = [1.0]\n", "tiny.toml: study: missing [study] section"),
    ("[study]\ndesign = 'well_conditioned'\n[grid]\nalpha = [1.0]\n", "tiny.toml: study.problem: missing"),
    ("[study]\nproblem = 'nope'\ndesign = 'well_conditioned'\n[grid]\nalpha = [1.0]\n",
     "study.problem: no problem named 'nope'"),
    ("[study]\nproblem = 'compleib_nn8'\ndesign = 'magic'\n[grid]\nalpha = [1.0]\n",
     "study.design: must be one of well_conditioned"),
    ("[study]\nproblem = 'compleib_nn8'\ndesign = 'well_conditioned'\nexecutor = 'gpu'\n[grid]\nalpha = "
     "[1.0]\n",
     "study.executor: must be one of"),
    ("[study]\nproblem = 'compleib_nn8'\ndesign = 'well_conditioned'\nworkers = 0\n[grid]\nalpha = [1.0]\n",
     "study.workers: must be an integer >= 1"),
    ("[study]\nproblem = 'compleib_nn8'\ndesign = 'well_conditioned'\nspeed = 3\n[grid]\nalpha = [1.0]\n",
     "study.speed: unknown field"),
    ("[study]\nproblem = 'compleib_nn8'\ndesign = 'well_conditioned'\n[fixed]\ncolour = 3\n[grid]\nalpha = "
     "[1.0]\n",
     "fixed.colour: unknown argument for design 'well_conditioned'"),
    ("[study]\nproblem = 'compleib_nn8'\ndesign = 'well_conditioned'\n[fixed]\nregion = 'blob:1'\n[grid]\n"
     "alpha = [1.0]\n", "fixed.region: unknown shape 'blob'"),
    ("[study]\nproblem = 'compleib_nn8'\ndesign = 'well_conditioned'\n[fixed]\nobjective = 'speed'\n[grid]\n"
     "alpha = [1.0]\n", "fixed.objective: objective must be one of"),
    ("[study]\nproblem = 'compleib_nn8'\ndesign = 'well_conditioned'\n", "grid: missing or empty [grid]"),
    ("[study]\nproblem = 'compleib_nn8'\ndesign = 'well_conditioned'\n[grid]\nq = [1.0]\n",
     "grid.q: unknown axis for design 'well_conditioned'"),
    ("[study]\nproblem = 'compleib_nn8'\ndesign = 'well_conditioned'\n[grid]\nalpha = {start = 1, stop = "
     "2, num = 'ten'}\n",
     "grid.alpha.num: must be an integer >= 1; found 'ten'"),
    ("[study]\nproblem = 'compleib_nn8'\ndesign = 'well_conditioned'\n[grid]\nalpha = {start = 1, num = 3}\n",
     "grid.alpha.stop: missing"),
    ("[study]\nproblem = 'compleib_nn8'\ndesign = 'well_conditioned'\n[grid]\nalpha = []\n",
     "grid.alpha: empty list of values"),
    ("[study]\nproblem = 'compleib_nn8'\ndesign = 'well_conditioned'\n[grid]\nzeta = [0.5, 1.5]\n",
     "grid.zeta: zeta (damping ratio) must be in (0, 1)"),
    ("[study]\nproblem = 'compleib_nn8'\ndesign = 'well_conditioned'\n[fixed]\nradius = 1.0\n[grid]\nalpha "
     "= [5.0]\n",
     "grid.alpha: the intersection"),
    ("[study]\nproblem = 'compleib_nn8'\ndesign = 'well_conditioned'\n[grid]\nalpha = [1.0]\n[figure]\ny = "
     "'speed'\n",
     "figure.y: 'speed' is not a result column"),
    ("[study]\nproblem = 'compleib_nn8'\ndesign = 'well_conditioned'\n[grid]\nalpha = [1.0]\n[figure]\nx = "
     "'zeta'\n",
     "figure.x: must be an axis of the grid"),
    ("[study]\nproblem = 'compleib_nn8'\ndesign = 'well_conditioned'\n[grid]\nalpha = "
     "[1.0]\n[figure]\nkind = 'pie'\n",
     "figure.kind: must be 'line' or 'heatmap'"),
    ("[study]\nproblem = 'compleib_nn8'\ndesign = 'well_conditioned'\n[grid]\nalpha = "
     "[1.0]\n[figure]\nfile = 'a.txt'\n",
     "figure.file: must be a file name ending in .png"),
    ("[study]\nproblem = 'compleib_nn8'\ndesign = 'well_conditioned'\n[grid]\nalpha = [1.0, 2.0]\nzeta = "
     "[0.3, 0.6]\n"
     "[figure]\nx = 'alpha'\n", "figure.series: axis 'zeta' also varies"),
    ("[study]\nproblem = 'compleib_nn8'\ndesign = 'kalman'\n[grid]\nq = [1.0, -1.0]\n", "grid.q: q must be"),
    ("[study]\nproblem = 'jung_huh_ex1'\ndesign = 'kalman'\n[grid]\nq = [1.0]\n",
     "study.problem: plant 'jung_huh_ex1' has no Q and no R"),
    # a point whose region reaches into the right half-plane (unstable error dynamics) is refused
    ("[study]\nproblem = 'compleib_nn8'\ndesign = 'well_conditioned'\n[fixed]\nradius = 10.0\n[grid]\n"
     "alpha = [-1.0, 1.0]\n", "grid.alpha: the pole region"),
    ("[study]\nproblem = 'compleib_nn8'\ndesign = 'inverse'\n[grid]\nscale = [1.0]\n",
     "study.problem: problem 'compleib_nn8' has no target poles"),
    ("[study]\nproblem = 'compleib_nn8'\ndesign = 'inverse'\n[fixed]\nmethod = 'place'\n[grid]\nscale = "
     "[1.0]\n",
     "fixed.method: is set by design = 'inverse'"),
    ("[study\nproblem = 1\n", "tiny.toml: invalid TOML"),
    # field types are checked up front, not discovered as a failure at every point
    ("[study]\nproblem = 'compleib_nn8'\ndesign = 'well_conditioned'\n[fixed]\ninitial_gain = 'x'\n[grid]\n"
     "alpha = [1.0]\n", "fixed.initial_gain: initial_gain must be a finite (3, 2) array of numbers"),
    ("[study]\nproblem = 'compleib_nn8'\ndesign = 'well_conditioned'\n[fixed]\ninitial_gain = [[1, 2], [3]]\n"
     "[grid]\nalpha = [1.0]\n", "fixed.initial_gain: initial_gain must be a finite"),
    ("[study]\nproblem = 'compleib_nn8'\ndesign = 'well_conditioned'\n[fixed]\nwarm_start = 'yes'\n[grid]\n"
     "alpha = [1.0]\n", "fixed.warm_start: warm_start must be true or false; found 'yes'"),
    ("[study]\nproblem = 'compleib_nn8'\ndesign = 'well_conditioned'\n[fixed]\nreuse = 'no'\n[grid]\n"
     "alpha = [1.0]\n", "fixed.reuse: reuse must be true or false"),
    ("[study]\nproblem = 'compleib_nn8'\ndesign = 'well_conditioned'\n[fixed]\noptions = {'ipopt.tol' = "
     "[1]}\n[grid]\nalpha = [1.0]\n", "fixed.options: options: 'ipopt.tol' must map to a string or a number"),
    ("[study]\nproblem = 'compleib_nn8'\ndesign = 'well_conditioned'\n[fixed]\nradius = 10.0\n"
     "[grid]\nalpha = [1.0]\nradius = [5.0, 20.0]\n", "grid.radius: is also given in [fixed]"),
    ("[study]\nproblem = 'chang_lee_1984_ex1'\ndesign = 'inverse'\n[fixed]\ninverse_method = 'magic'\n"
     "[grid]\nscale = [1.0]\n", "fixed.inverse_method: inverse_method must be one of auto, sdp"),
    ("[study]\nproblem = 'chang_lee_1984_ex1'\ndesign = 'inverse'\n[fixed]\nstarts = 'x'\n[grid]\n"
     "scale = [1.0]\n", "fixed.starts: starts must be an integer >= 1; found 'x'"),
    ("[study]\nproblem = 'chang_lee_1984_ex1'\ndesign = 'inverse'\n[fixed]\nobjective = 'kappa2'\n[grid]\n"
     "scale = [1.0]\n", "fixed.objective: objective must be one of min_trace"),
]


@pytest.mark.parametrize("text, match", BAD_SPECS)
def test_bad_spec_files_give_one_line_naming_the_field(text, match, tmp_path, capsys):
    spec = tmp_path / "tiny.toml"
    spec.write_text(text)
    code, _, err = run(["study", str(spec)], capsys)
    assert_one_line_error(code, err, match)


def test_study_missing_file_and_bad_workers(tmp_path, capsys):
    code, _, err = run(["study", str(tmp_path / "absent.toml")], capsys)
    assert_one_line_error(code, err, "absent.toml: no such spec file")
    spec = tmp_path / "tiny.toml"
    spec.write_text(GOOD_SPEC)
    code, _, err = run(["study", str(spec), "--workers", "0"], capsys)
    assert_one_line_error(code, err, "--workers must be >= 1")
    code, _, err = run(["study", str(spec), "--executor", "cloud"], capsys)
    assert_one_line_error(code, err, "argument --executor: invalid choice: 'cloud'")


def test_example_spec_is_valid():
    spec = load_spec(Path(__file__).resolve().parents[1] / "examples" / "study_alpha_sector.toml")
    assert spec.design == "well_conditioned" and len(spec.points) >= 12 and spec.figures


# ------------------------------------------------------------------ reproduce


def _fake_paper(ok: bool):
    mod = types.ModuleType("fake_paper")

    def reproduce(outdir, *, quick=False):
        if not ok:
            raise RuntimeError("the fake paper\nbroke")
        from optdesign.studies.reproduce import pyplot

        plt = pyplot()
        fig, ax = plt.subplots()
        ax.plot([0, 1], [0, 1], label="y = x")
        ax.set_xlabel("x")
        ax.set_ylabel("y")
        ax.legend()
        path = Path(outdir) / "fake_fig.png"
        fig.savefig(path)
        rows = (ReproRow("ex 1", "K", "8, -6", "8, -6", True), ReproRow("ex 2", "Q | R", "1.5", "1.2", False,
                                                                         "printed value is a typo"))
        return PaperReproduction("000", "fake", rows, (path,))

    mod.reproduce = reproduce
    return mod


def test_reproduce_reports_missing_and_failing_papers(tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "optdesign.studies.paper000", _fake_paper(True))
    monkeypatch.setitem(sys.modules, "optdesign.studies.paper001", _fake_paper(False))
    monkeypatch.setitem(sys.modules, "optdesign.studies.paper004", None)  # import fails: "missing"
    out = tmp_path / "repro"
    code, text, err = run(["reproduce", "000", "seed001", "4", "--out", str(out), "--quick"], capsys)
    assert code == 1 and "Traceback" not in err + text
    assert "seed 001: failed: RuntimeError: the fake paper broke" in text
    assert "seed 004: missing" in text
    assert (out / "fake_fig.png").is_file()
    md = (out / "summary.md").read_text()
    assert "| 000 " in md and "**NO**" in md and "Q \\| R" in md and "[fake_fig.png](fake_fig.png)" in md
    rows = list(csv.DictReader((out / "summary.csv").open()))
    assert [(r["paper"], r["status"]) for r in rows] == [("000", "ok"), ("000", "ok"), ("001", "failed"),
                                                         ("004", "missing")]
    assert rows[1]["agrees"] == "no" and rows[1]["note"] == "printed value is a typo"


def test_reproduce_all_writes_real_figures(tmp_path):
    pytest.importorskip("optdesign.studies.paper002")
    s = reproduce_all(tmp_path, papers=["002"], quick=True)
    assert s.ok, s.overview()
    assert s.figures and all(f.is_file() and f.stat().st_size > 10_000 for f in s.figures)
    assert s.markdown.read_text().count("| ") > 10


def test_reproduce_errors(capsys):
    code, _, err = run(["reproduce", "007"], capsys)
    assert_one_line_error(code, err, "unknown paper '007'; expected one of 000, 001, 002, 003, 004")
    names = (1, "2", "003", "seed004", "paper000")
    assert [paper_id(x) for x in names] == ["001", "002", "003", "004", "000"]


def test_reproduce_and_study_out_folder_errors_name_the_flag(tmp_path, capsys, monkeypatch):
    afile = tmp_path / "afile"
    afile.write_text("x")
    code, _, err = run(["reproduce", "000", "--out", str(afile / "sub")], capsys)
    assert_one_line_error(code, err, f"--out {afile / 'sub'}: cannot create the folder")
    spec = tmp_path / "tiny.toml"
    spec.write_text(GOOD_SPEC)
    code, _, err = run(["study", str(spec), "--out", str(afile)], capsys)
    assert_one_line_error(code, err, f"--out {afile}: cannot create the folder")
    # without matplotlib, reproduce says what to install instead of failing every paper
    monkeypatch.setitem(sys.modules, "matplotlib", None)
    code, _, err = run(["reproduce", "000", "--out", str(tmp_path / "r")], capsys)
    assert_one_line_error(code, err, "needs matplotlib: pip install 'optdesign-control[plot]'")


# ------------------------------------------------------------------ issue 17, part 2: study


FAILING_SPEC = """
[study]
name = "shifts"
problem = "chang_lee_1984_ex1"
design = "inverse"
executor = "serial"
[grid]
scale = [0.5, 1.0]
shift = [0.0, 6.0]
"""


def test_study_header_is_printed_before_the_sweep(tmp_path, capsys, monkeypatch):
    import optdesign.cli.design as cli_design

    seen = {}
    real = cli_design.run_spec

    def spy(*args, **kwargs):
        seen["stdout before the sweep"] = capsys.readouterr().out
        return real(*args, **kwargs)

    monkeypatch.setattr(cli_design, "run_spec", spy)
    (tmp_path / "tiny.toml").write_text(GOOD_SPEC)
    code, out, err = run(["study", "tiny.toml", "--no-progress", "--no-figures"], capsys)
    assert code == 0, err
    assert seen["stdout before the sweep"].startswith("study tiny: compleib_nn8, design well_conditioned, "
                                                      "4 points on serial -> tiny_results")


def test_study_refuses_up_front_without_matplotlib(tmp_path, capsys, monkeypatch):
    import optdesign.studies.spec as spec_module

    def no_sweep(*args, **kwargs):
        raise AssertionError("the sweep ran although its figures could not be drawn")

    (tmp_path / "tiny.toml").write_text(GOOD_SPEC)
    real_sweep = spec_module.sweep
    monkeypatch.setitem(sys.modules, "matplotlib", None)
    monkeypatch.setattr(spec_module, "sweep", no_sweep)
    code, _, err = run(["study", "tiny.toml"], capsys)
    assert_one_line_error(code, err, "the figures of tiny.toml need matplotlib, which is not installed: "
                                     "pip install 'optdesign-control[plot]' (or skip the figures: optdesign study "
                                     "--no-figures")
    assert not (tmp_path / "tiny_results" / "tiny.csv").exists()
    with pytest.raises(BackendUnavailableError, match="need matplotlib"):
        spec_module.run_spec(tmp_path / "tiny.toml", progress=False)
    # --no-figures needs no matplotlib and writes the tables only
    monkeypatch.setattr(spec_module, "sweep", real_sweep)
    code, out, err = run(["study", "tiny.toml", "--no-figures", "--no-progress"], capsys)
    assert code == 0, err
    assert (tmp_path / "tiny_results" / "tiny.csv").is_file() and "figure:" not in out
    assert not list((tmp_path / "tiny_results").glob("*.png"))


def test_study_outputs_go_to_the_current_directory_not_the_source_tree(tmp_path, capsys):
    src = tmp_path / "src"
    src.mkdir()
    (src / "shifts.toml").write_text(FAILING_SPEC)
    run(["study", str(src / "shifts.toml"), "--allow-failures", "--no-progress"], capsys)
    assert sorted(p.name for p in src.iterdir()) == ["shifts.toml"]  # nothing next to the spec
    assert (tmp_path / "shifts_results" / "shifts.csv").is_file()
    # the spec's output folder is relative to the current directory too; --out overrides it
    (src / "shifts.toml").write_text(FAILING_SPEC.replace('executor = "serial"', 'executor = "serial"\n'
                                                                                 'output = "mine"'))
    run(["study", str(src / "shifts.toml"), "--allow-failures", "--no-progress"], capsys)
    assert (tmp_path / "mine" / "shifts.csv").is_file()
    run(["study", str(src / "shifts.toml"), "--allow-failures", "--no-progress", "--out", "elsewhere"],
        capsys)
    assert (tmp_path / "elsewhere" / "shifts.csv").is_file()
    assert sorted(p.name for p in src.iterdir()) == ["shifts.toml"]
    # the example spec: its results go to ./alpha_sector_results, not into examples/
    example = load_spec(Path(__file__).resolve().parents[1] / "examples" / "study_alpha_sector.toml")
    assert example.output == Path("alpha_sector_results")


def test_study_exit_code_1_when_a_point_fails_with_the_failed_points_listed(tmp_path, capsys):
    (tmp_path / "shifts.toml").write_text(FAILING_SPEC)
    code, out, _ = run(["study", "shifts.toml", "--no-progress"], capsys)
    assert code == 1  # it used to exit 0 when only some points succeeded
    assert "4 points, 2 successful, 2 failed" in out and "failed points (2 of 4):" in out
    listed = [ln for ln in out.splitlines() if ln.startswith("  scale = ")]
    assert [ln.split(":")[0] for ln in listed] == ["  scale = 0.5, shift = 6", "  scale = 1, shift = 6"]
    assert all(": infeasible: infeasible: no design exists (a global certificate says so); " in ln
               for ln in listed), listed
    # the same study again writes the same result files: asked for with --overwrite
    code, out, _ = run(["study", "shifts.toml", "--no-progress", "--allow-failures", "--overwrite"], capsys)
    assert code == 0 and "partial results accepted (--allow-failures)" in out
    code, out, _ = run(["study", "shifts.toml", "--no-progress", "--json", "--overwrite"], capsys)
    d = json.loads(out)
    assert code == 1 and d["failed"] == 2 and [f["shift"] for f in d["failed_points"]] == [6.0, 6.0]
    assert all(f["reason"].startswith("infeasible: ") for f in d["failed_points"])


def test_study_progress_goes_to_stderr_when_asked(tmp_path, capsys):
    (tmp_path / "shifts.toml").write_text(FAILING_SPEC)
    code, out, err = run(["study", "shifts.toml", "--allow-failures", "--no-progress"], capsys)
    assert err == ""
    code, out, err = run(["study", "shifts.toml", "--allow-failures", "--progress", "--overwrite"], capsys)
    assert code == 0 and "sweep:" not in out  # stdout keeps the results only
    # the sweep is shorter than the 1 s delay of its report: silent, or ending with 4/4
    assert err == "" or err.splitlines()[-1].startswith("sweep: 4/4 points")


def test_committed_example_results_are_consistent():
    """The committed results of examples/study_alpha_sector.py (regenerated by running it; a unit test
    cannot rerun the 2-minute study): the API sweep and the spec run agree, every point verified,
    failure reasons recorded as a column, and kappa2 never worse along a chunk (zeta loosens from 0.8
    to 0.2, each point warm-started from the previous one)."""
    folder = Path(__file__).resolve().parents[1] / "examples" / "figures" / "study_alpha_sector"
    api = list(csv.DictReader((folder / "api_alpha_sector.csv").open()))
    spec = list(csv.DictReader((folder / "from_spec" / "alpha_sector.csv").open()))
    assert len(api) == len(spec) == 16 and "reason" in api[0]
    key = lambda r: (float(r["alpha"]), float(r["zeta"]))  # noqa: E731
    by_point = {key(r): float(r["kappa2"]) for r in spec}
    for r in api:
        assert r["success"] == "True", r
        assert float(r["kappa2"]) == pytest.approx(by_point[key(r)], rel=1e-6)
    for alpha in {key(r)[0] for r in api}:
        chunk = sorted((r for r in api if key(r)[0] == alpha), key=lambda r: -key(r)[1])
        k2 = [float(r["kappa2"]) for r in chunk]
        assert all(b <= a * (1 + 1e-6) for a, b in zip(k2, k2[1:], strict=False)), (alpha, k2)


# ------------------------------------------------------------------ issue 17, part 2: output details


def test_region_is_echoed_in_the_syntax_it_was_given(capsys):
    code, out, _ = run(["design", "compleib_dis2", "--method", "well_conditioned", "--zeta", "0.7",
                        "--radius", "20", "--starts", "1"], capsys)
    assert code == 0
    line = next(ln for ln in out.splitlines() if ln.startswith("region: "))
    assert line.startswith("region: sector:0.7 & disk:20  (damping ratio >= 0.7 (a sector of half-angle "
                           "45.57 deg); |s| <= 20)")
    assert "half_angle=" not in out  # it was Sector(half_angle=0.795...)
    from optdesign.studies.spec import format_region

    for text in ("halfplane:1 & sector:0.7 & disk:20", "stable & strip:-30,0 & hstrip:9 & ellipse:-5,10,8",
                 "disk:-1,0.5"):
        assert format_region(parse_region(text), meaning=False) == text  # the inverse of parse_region


def test_infeasible_inverse_design_output(capsys):
    code, out, _ = run(["design", "chang_lee_1984_ex1", "--method", "inverse", "--poles=-1,2"], capsys)
    assert code == 1
    assert "poles of A - L C" not in out  # was "poles of A - L C: -"
    assert out.count("target pole(s) 2 not in the open left half-plane") == 1  # the certificate once
    assert "certificate: unstable_target: " in out
    assert out.rstrip().endswith("verification: none (no design to check)")  # was an empty "verification:"
    assert "L: none (no gain was designed; the status and the certificate say why)" in out


def test_a_dc_frequency_is_said_to_be_dc():
    from optdesign.cli.common import annotate_frequencies, pole_scale

    text = "lambda_min(T R T* - R) = -0.3 at omega = 4.5e-08 rad/s; worst frequency 4.5e-08 rad/s"
    out = annotate_frequencies(text, pole_scale([-0.45, -0.2]))
    assert out.count("(DC: zero frequency to the scan's resolution)") == 2
    assert annotate_frequencies("at omega = 0 rad/s", 1.0).endswith("rad/s (DC: zero frequency to the scan's "
                                                                    "resolution)")
    assert annotate_frequencies("at omega = 3.02 rad/s", 1.0) == "at omega = 3.02 rad/s"
    # the bound follows the plant's time scale: 4.5e-08 rad/s is not DC for poles at 1e-7 rad/s
    assert "DC" not in annotate_frequencies("omega = 4.5e-08 rad/s", pole_scale([-1e-7]))


def test_pole_order_is_the_same_in_every_verb(capsys):
    lines = {}
    for argv in (["kalman"], ["design", "chang_lee_1984_ex1", "--method", "inverse", "--poles=-5,-8"],
                 ["design", "chang_lee_1984_ex1", "--method", "kalman"],
                 ["design", "chang_lee_1984_ex1", "--method", "place", "--poles=-5,-8"]):
        code, out, _ = run(argv, capsys)
        assert code == 0
        lines[" ".join(argv)] = [ln.strip() for ln in out.splitlines()
                                 if ln.strip().startswith(("poles of A - L C", "target poles"))]
    for found in lines.values():
        assert all(ln.endswith(": -8, -5") for ln in found), lines
    code, out, _ = run(["design", "double_integrator_poles_m2pm2j", "--method", "inverse"], capsys)
    assert "target poles: -2-2j, -2+2j" in out and "poles of A - L C: -2-2j, -2+2j" in out
    code, out, _ = run(["design", "double_integrator_poles_m2pm2j", "--method", "inverse", "--json"], capsys)
    d = json.loads(out)
    assert d["target"]["im"] == pytest.approx([-2.0, 2.0]) and d["poles"]["im"] == pytest.approx([-2.0, 2.0])


def test_reproduce_reports_each_paper_and_figure(tmp_path, monkeypatch, capsys):
    mod = types.ModuleType("fake_paper")

    def reproduce(outdir, *, quick=False, progress=None):
        from optdesign.studies.reproduce import pyplot, save_figure

        fig, ax = pyplot().subplots()
        ax.plot([0, 1], [0, 1])
        path = save_figure(fig, Path(outdir) / "fake_fig.png", progress=progress)
        return PaperReproduction("000", "fake", (ReproRow("ex", "K", "1", "1", True),), (path,))

    mod.reproduce = reproduce
    monkeypatch.setitem(sys.modules, "optdesign.studies.paper000", mod)
    monkeypatch.setitem(sys.modules, "optdesign.studies.paper001", _fake_paper(True))  # no progress argument
    code, out, err = run(["reproduce", "000", "001", "--out", "r", "--progress"], capsys)
    assert code == 0
    assert out.splitlines()[0] == f"reproducing seed paper(s) 000, 001 -> r{os.sep}"  # first, before the work
    lines = err.splitlines()
    assert lines[0] == "seed 000 (1/2): " + PAPERS["000"]
    assert re.fullmatch(r"wrote fake_fig.png \(at \d+\.\d s\)", lines[1]), lines
    assert lines[2].startswith("reproduce: 1/2 papers (")
    assert re.search(r"; seed 000 ok in \d+\.\d s$", lines[2]), lines
    assert lines[3] == "seed 001 (2/2): " + PAPERS["001"]
    assert lines[-1].startswith("reproduce: 2/2 papers")
    code, out, err = run(["reproduce", "000", "--out", "r2"], capsys)
    assert code == 0 and err == ""  # not a terminal and not asked: silent
    from optdesign.cli import build_parser

    help_text = build_parser()._subparsers._group_actions[0].choices["reproduce"].format_help()
    assert "./optdesign-reproduction, in the current directory" in " ".join(help_text.split())
