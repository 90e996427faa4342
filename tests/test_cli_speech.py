"""What the ``optdesign`` command says (issue 30, item 6): the plant shown, noise inputs named as such,
checks in plain words with their numbers, repeated poles rounded and counted, infinite margins said in
words, one statement per fact, the valid tags listed, errata named, figures in a chosen format."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from optdesign import Plant, filter_margins, is_kalman_optimal, kalman
from optdesign.cli.common import format_poles
from optdesign.cli.main import main
from optdesign.cli.speech import plain_check
from optdesign.results import Check
from optdesign.studies.reproduce import PaperOutcome, PaperReproduction, ReproductionSummary, ReproRow


def run(argv, capsys):
    code = main(argv)
    cap = capsys.readouterr()
    return code, cap.out, cap.err


def test_kalman_shows_the_plant_and_names_the_noise_inputs(capsys):
    code, out, _ = run(["kalman"], capsys)
    assert code == 0
    for k in ("A", "C", "G", "Q", "R"):
        assert re.search(rf"^  {k} = \[\[", out, re.M), k
    assert "Q = [[ 76. -42.]" in out  # the problem's noise covariance, shown
    assert "m = 2 noise inputs w" in out and "(continuous, n = 2" not in out


def test_checks_read_in_plain_words_with_their_numbers(capsys):
    code, out, _ = run(["kalman"], capsys)
    assert code == 0
    assert "Newton correction of its residual" not in out
    assert re.search(r"\[ok  \] forward_error: P is accurate to about [0-9.e-]+ \(relative\), estimated from its "
                     r"residual and its sensitivity to rounding \(allowed 1e-06\)", out)
    assert "stability_margin: stable: every pole of A - L C has real part at most -5" in out
    assert "P agrees with the hamiltonian solver's to" in out
    # a check without its own phrase: its detail, the value and the bound in words
    c = Check.at_least("kappa2_bound", 3.0, 4.0, "kappa2 of the design")
    assert plain_check(c) == "[FAIL] kappa2_bound: kappa2 of the design: 3, must be at least 4"


def test_a_double_pole_prints_once_with_its_count(capsys):
    split = [-1 - 2.58096e-08j, -1 + 2.58096e-08j]  # a defective double pole as eig computes it
    assert format_poles(split) == "-1 (x2)"
    assert format_poles([-1.00000002, -0.99999998, -3.0]) == "-3, -1 (x2)"
    assert format_poles([-2 + 1j, -2 - 1j]) == "-2-1j, -2+1j"  # a true pair stays a pair
    assert format_poles([-1.0, -1.001]) == "-1.001, -1"  # distinct beyond the tolerance
    # the double integrator's Kalman filter with q11 = 2, q22 = 1 has a double pole at -1
    k = kalman(Plant([[0.0, 1.0], [0.0, 0.0]], [[1.0, 0.0]], Q=np.diag([2.0, 1.0]), R=[[1.0]]))
    assert format_poles(k.poles) == "-1 (x2)"


def test_infinite_margins_are_said_in_words():
    plant = Plant([[0.0, 1.0], [-4.0, -0.2]], np.eye(2), Q=np.diag([0.1, 1.0]), R=np.diag([0.5, 2.0]))
    text = filter_margins(plant, kalman(plant).L).summary()
    assert "nan rad/s" not in text and "inf deg" not in text
    assert "channel 0: gain margin -1.417 (lower), infinite (no crossing) (upper); " \
           "phase margin infinite (no crossing)" in text


def test_is_kalman_optimal_states_the_frequency_once():
    one = Plant([[1.0]], [[1.0]], Q=[[0.01]], R=[[1.0]])
    res = is_kalman_optimal(one, [[1.5]])  # A - L C = -0.5 stable, but q = L^2 - 2 L < 0
    assert not res.optimal
    assert res.message.count("rad/s") == 1 and res.message.count("-0.75") == 2, res.message
    assert "worst frequency" not in res.message and "SDP margin" not in res.message


def test_list_names_the_valid_tags(capsys):
    code, _, err = run(["list", "--tag", "seed"], capsys)
    assert code == 2
    assert "no problem matches tag='seed' (did you mean seed000, seed001, seed002, seed003, seed004?)" in err
    import re

    from optdesign import problems

    listed = re.search(r"tags: ([^(]*) \(a tag also matches a name prefix", err)
    assert listed, err
    every = sorted({t for name in problems.names() for t in problems.load(name).tags})
    assert listed.group(1).split(", ") == every
    code, _, err = run(["list", "--kind", "nope"], capsys)
    assert code == 2 and "kinds: generalized_observer" in err


def test_reproduce_names_documented_errata(tmp_path):
    rows = (ReproRow("eq (4.12)", "gain", "a", "b", False, "spurious inverse"),
            ReproRow("eq (4.20)", "integral", "c", "d", False, "sign"),
            ReproRow("Fig 2", "K(t)", None, "0.1", None))
    rep = PaperReproduction("004", "Ahn et al.", rows)
    summary = ReproductionSummary(tmp_path, (PaperOutcome("004", "Ahn", "ok", rep, time=1.0),),
                                  tmp_path / "s.md", tmp_path / "s.csv")
    line = summary.overview()
    assert ("3 values (0 agree with the print, 2 differ); the 2 that differ are documented errata of the "
            "paper: eq (4.12), eq (4.20); 0 figures") in line
    rows2 = (*rows, ReproRow("Ex 1", "L", "8", "9", False))
    rep2 = PaperReproduction("000", "x", rows2)
    line = ReproductionSummary(tmp_path, (PaperOutcome("000", "x", "ok", rep2),), tmp_path / "a",
                               tmp_path / "b").overview()
    assert "3 differ); 1 unexplained, 2 documented errata of the paper: eq (4.12), eq (4.20)" in line


SPEC = """
[study]
name = "tiny"
problem = "compleib_nn8"
design = "well_conditioned"
executor = "serial"

[fixed]
radius = 10.0

[grid]
alpha = [0.5, 1.0]

[figure]
x = "alpha"
y = ["kappa2"]
"""


@pytest.mark.parametrize("fmt, magic", [("svg", b"<?xml"), ("pdf", b"%PDF")])
def test_study_figures_in_the_chosen_format(tmp_path, capsys, fmt, magic):
    spec = tmp_path / "tiny.toml"
    spec.write_text(SPEC)
    code, out, err = run(["study", str(spec), "--no-progress", "--out", str(tmp_path / "o"), "--format", fmt],
                         capsys)
    assert code == 0, err
    fig = tmp_path / "o" / f"tiny_kappa2.{fmt}"
    assert fig.read_bytes().startswith(magic) and f"figure:  {fig}" in out
    assert not list((tmp_path / "o").glob("*.png"))


def test_figures_are_written_at_300_dpi(tmp_path):
    matplotlib = pytest.importorskip("matplotlib")
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from optdesign.studies.reproduce import save_figure

    fig, ax = plt.subplots(figsize=(2.0, 1.0))
    ax.plot([0, 1])
    path = save_figure(fig, tmp_path / "f.png")
    from PIL import Image

    with Image.open(path) as im:
        assert im.size == (600, 300)
        assert round(im.info["dpi"][0]) == 300
    assert Path(path).suffix == ".png"
