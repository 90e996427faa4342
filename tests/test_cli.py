"""The ``optdesign`` command: outputs, JSON, and one-line errors with exit code 2."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from optdesign import problems
from optdesign.classical.placement import pole_error
from optdesign.cli import DEFAULT_PROBLEM, main


def test_list(capsys):
    assert main(["list"]) == 0
    out = capsys.readouterr().out
    assert DEFAULT_PROBLEM in out and "carex_1.1" in out and "problems" in out


def test_list_filters_and_json(capsys):
    assert main(["list", "--kind", "riccati_care", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    assert rows and all(r["kind"] == "riccati_care" for r in rows)


def test_show(capsys):
    assert main(["show", DEFAULT_PROBLEM]) == 0
    out = capsys.readouterr().out
    assert "citation" in out and "A =" in out
    assert main(["show", DEFAULT_PROBLEM, "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["name"] == DEFAULT_PROBLEM


def test_kalman_default_problem(capsys):
    assert main(["kalman"]) == 0
    out = capsys.readouterr().out
    assert DEFAULT_PROBLEM in out and "poles" in out.lower()


def test_kalman_json(capsys):
    assert main(["kalman", DEFAULT_PROBLEM, "--json", "--method", "hamiltonian"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["success"] is True and d["residual"] < 1e-10 and len(d["L"]) == 2


@pytest.mark.parametrize(
    "argv, match",
    [
        (["show", "no_such_problem"], "no problem named 'no_such_problem'"),
        (["kalman", "no_such_problem"], "no problem named"),
        (["kalman", DEFAULT_PROBLEM, "--method", "magic"], "invalid choice: 'magic'"),
        (["frobnicate"], "invalid choice: 'frobnicate'"),
        (["list", "--kind", "no_such_kind"], "no problem matches kind='no_such_kind'"),
        (["kalman", "carex_1.3"], "problem 'carex_1.3' has no valid plant (Control form"),
        (["kalman", "jung_huh_ex1"], "problem 'jung_huh_ex1' has no noise model (Q and R)"),
    ],
)
def test_errors_are_one_line_exit_2(argv, match, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert match in err
    assert err.count("\n") == 1 and "Traceback" not in err


def test_json_output_is_strict_json():
    """Non-finite numbers come out as strings ("inf", "nan"): JSON itself has no Infinity or NaN."""
    from optdesign.cli import jsonable

    obj = {"a": np.array([1.0, np.inf]), "z": np.array([1 + 2j, complex(np.nan, 0)]),
           "k": np.float64(-np.inf), "flag": np.bool_(True), "n": np.int64(3), "rows": [(0.5, float("nan"))]}
    text = json.dumps(jsonable(obj), allow_nan=False)  # raises if a non-finite float slipped through
    assert json.loads(text) == {"a": [1.0, "inf"], "z": {"re": [1.0, "nan"], "im": [2.0, 0.0]}, "k": "-inf",
                                "flag": True, "n": 3, "rows": [[0.5, "nan"]]}


def test_console_script_entry_point():
    out = subprocess.run([sys.executable, "-m", "optdesign", "show", "nope"], capture_output=True, text=True)
    assert out.returncode == 2 and out.stderr.startswith("optdesign: error:")
    assert "Traceback" not in out.stderr


def test_feedback_mode_places_state_feedback_poles(capsys):
    """``optdesign design ... --feedback``: a controller by duality on the problem's (A, B)."""
    assert main(["design", "pp_knv1985_ex1", "--method", "place", "--feedback", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["feedback"] and out["success"]
    prob = problems.load("pp_knv1985_ex1")
    A, B = np.asarray(prob.data["A"]), np.asarray(prob.data["B"])
    K = np.asarray(out["K"])
    assert pole_error(np.linalg.eigvals(A - B @ K), prob.targets["poles"]) < 1e-8
    # a plant without B is refused with the reason, exit code 2
    assert main(["design", "chang_lee_1984_ex1", "--method", "inverse", "--feedback"]) == 2
    assert "has no input matrix B" in capsys.readouterr().err


def test_kalman_options_on_the_command_line(capsys):
    assert main(["kalman", "kf_analytic_double_integrator_ct", "--kalmd", "0.1"]) == 0
    assert "discrete, dt = 0.1" in capsys.readouterr().out
    assert main(["kalman", "--sensors", "x"]) == 2
    assert "--sensors must be comma-separated" in capsys.readouterr().err


# ------------------------------------------------------------------ issue 17, part 2: output details


def test_show_prints_numbers_not_reprs(capsys):
    # nested dicts of arrays were dumped as {'norm2_H': array(...)}
    assert main(["show", "carex_1.1"]) == 0
    out = capsys.readouterr().out
    assert "array(" not in out and "{" not in out
    assert "\n    computed:\n      norm2_H: 2.414213562373095\n" in out


def test_kalman_and_design_share_one_title_line(capsys):
    assert main(["kalman"]) == 0
    first_kalman = capsys.readouterr().out.splitlines()[0]
    assert main(["design", DEFAULT_PROBLEM, "--method", "kalman"]) == 0
    first_design = capsys.readouterr().out.splitlines()[0]
    title = problems.load(DEFAULT_PROBLEM).title
    assert first_kalman == first_design == f"problem: {DEFAULT_PROBLEM} -- {title}"


def test_filter_margins_repr_is_one_short_line():
    from optdesign.analysis.robustness import filter_margins
    from optdesign.design.kalman import kalman

    plant = problems.load(DEFAULT_PROBLEM).plant
    m = filter_margins(plant, kalman(plant).L)
    text = repr(m)
    assert len(text) < 200 and "\n" not in text and "array(" not in text  # was a 600-character dump
    assert text.startswith("FilterMargins(continuous, stable; circle condition holds; guaranteed gain "
                           "(0.5, inf)")
    assert "summary" not in text and "channel" in m.summary()


def test_hostile_files_end_in_one_line_exit_2_in_a_fresh_process(tmp_path):
    """Issue 26: a file claiming a huge shape gave numpy's MemoryError traceback and exit 1, deep
    nesting a RecursionError, a 5,000-digit integer Python's ValueError -- now one line, exit 2."""
    import io
    import zipfile

    header = io.BytesIO()
    np.lib.format.write_array_header_1_0(header, {"descr": "<f8", "fortran_order": False,
                                                  "shape": (2000, 2000, 2000)})
    with zipfile.ZipFile(tmp_path / "huge.npz", "w") as zf:
        zf.writestr("A.npy", header.getvalue())
    (tmp_path / "deep.json").write_text("[" * 100_000 + "]" * 100_000)
    (tmp_path / "digits.toml").write_text("A = [[" + "9" * 5000 + "]]\n")
    for name, match in (("huge.npz", "A: shape (2000, 2000, 2000) of float64 declares"),
                        ("deep.json", "nested more than 32 levels deep"),
                        ("digits.toml", "an integer of more than 4300 digits")):
        proc = subprocess.run([sys.executable, "-m", "optdesign", "kalman", str(tmp_path / name)],
                              capture_output=True, text=True, timeout=120)
        assert proc.returncode == 2, proc.stderr
        assert proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr and match in proc.stderr


def test_study_help_names_overwrite_and_allow_outside(capsys):
    with pytest.raises(SystemExit):
        main(["study", "--help"])
    out = capsys.readouterr().out
    assert "--overwrite" in out and "--allow-outside" in out


@pytest.mark.parametrize("args", [
    ["kalman"],
    ["design", "chang_lee_1984_ex1", "--method", "well_conditioned", "--region",
     "halfplane:1 & sector:0.7 & disk:20"],
    ["design", "chang_lee_1984_ex1", "--method", "inverse", "--poles", "-3, -4"],
])
def test_commands_are_silent_on_stderr(args):
    """Issue 26 item 3: solver chatter (IPOPT banners, CasADi warnings, cvxpy's inaccuracy warnings) never
    reaches the terminal; a successful command writes nothing to stderr (a fresh process, so that a
    native library's own output would show)."""
    proc = subprocess.run([sys.executable, "-m", "optdesign", *args], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stderr == "", proc.stderr[-2000:]
    assert "Ipopt" not in proc.stdout and "WARNING" not in proc.stdout
