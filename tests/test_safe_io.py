"""Studies never lose data (issue 26, item 4): no output outside the working folder unless asked,
no existing file overwritten unless asked, files written under a temporary name and renamed, never
through a symbolic link -- in the writer (:mod:`optdesign.studies.output`), the tables
(``SweepTable.to_csv / to_json``), ``run_spec`` and ``optdesign study``.  And a spec is refused,
with a typed one-line error, before it can exhaust memory: a 10^8-point grid, a NUL byte in a
name, deep nesting, a 5,000-digit integer."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from optdesign.cli import main
from optdesign.errors import OptDesignError, OutputExistsError, OutputPathError, ValidationError
from optdesign.studies import SweepTable, grid
from optdesign.studies.output import atomic_path, check_targets, output_folder, write_text
from optdesign.studies.spec import SpecError, load_spec, parse_spec, run_spec
from optdesign.studies.sweep import MAX_GRID_POINTS

#: a one-point study that runs in well under a second (kalman on the seed-000 plant, serial)
SPEC = ('[study]\nname = "{name}"\nproblem = "chang_lee_1984_ex1"\ndesign = "kalman"\n'
        'executor = "serial"\n{extra}[grid]\nq = [1.0]\n')


@pytest.fixture()
def work(tmp_path, monkeypatch):
    """A working folder inside tmp_path, with a sibling ``outside`` folder holding a file."""
    here = tmp_path / "work"
    here.mkdir()
    outside = tmp_path / "outside"
    outside.mkdir()
    (outside / "package.json").write_text('{"keep": true}')
    monkeypatch.chdir(here)
    return here


def run(argv, capsys):
    code = main(argv)
    cap = capsys.readouterr()
    return code, cap.out, cap.err


def one_line_error(code, err, match):
    assert code == 2, err
    assert err.startswith("optdesign: error: ") and err.count("\n") == 1 and "Traceback" not in err, err
    assert match in err, err


def write_spec(name="s", extra="", file="s.toml") -> Path:
    Path(file).write_text(SPEC.format(name=name, extra=extra))
    return Path(file)


def leftovers(folder: Path) -> list[str]:
    """Temporary files left behind in ``folder``."""
    return [p.name for p in folder.iterdir() if ".tmp" in p.name]


# ------------------------------------------------------------------ the writer


def test_write_text_never_overwrites_unless_asked(work):
    p = write_text("a.txt", "one")
    assert p.read_text() == "one"
    with pytest.raises(OutputExistsError, match=r"a.txt: exists; not overwritten \(overwrite=True"):
        write_text("a.txt", "two")
    assert Path("a.txt").read_text() == "one" and leftovers(work) == []
    write_text("a.txt", "two", overwrite=True)
    assert Path("a.txt").read_text() == "two" and leftovers(work) == []
    assert issubclass(OutputExistsError, FileExistsError) and issubclass(OutputExistsError, OptDesignError)


def test_write_text_never_writes_through_a_symlink(work):
    target = work.parent / "outside" / "package.json"
    os.symlink(target, "out.json")
    with pytest.raises(OutputExistsError, match=r"out.json: a symbolic link \(to .*package.json\)"):
        write_text("out.json", "{}")
    assert target.read_text() == '{"keep": true}'
    # overwriting replaces the link itself; the file it pointed to is untouched
    write_text("out.json", "{}", overwrite=True)
    assert not Path("out.json").is_symlink() and Path("out.json").read_text() == "{}"
    assert target.read_text() == '{"keep": true}'
    # a dangling link counts as taken too
    os.symlink(work / "nowhere", "dangling.csv")
    with pytest.raises(OutputExistsError, match="dangling.csv: a symbolic link"):
        write_text("dangling.csv", "x")


def test_atomic_path_keeps_the_old_file_when_the_writer_fails(work):
    Path("r.csv").write_text("old")
    with pytest.raises(RuntimeError, match="boom"), atomic_path("r.csv", overwrite=True) as tmp:
        assert tmp.parent == Path(".") and tmp.suffix == ".csv" and tmp.exists()
        tmp.write_text("half")
        raise RuntimeError("boom")
    assert Path("r.csv").read_text() == "old" and leftovers(work) == []


def test_a_folder_at_an_output_path_and_a_nul_byte_are_refused(work):
    Path("d.csv").mkdir()
    with pytest.raises(OutputPathError, match="d.csv: a folder is where a result file is to be written"):
        write_text("d.csv", "x", overwrite=True)
    with pytest.raises(OutputPathError, match="NUL character"):
        write_text("a\x00b.csv", "x")
    with pytest.raises(OutputPathError, match="NUL character"):
        output_folder("res\x00", field="--out")
    with pytest.raises(OutputExistsError, match="exists"):
        Path("e.csv").write_text("")
        check_targets(["new.csv", "e.csv"])


def test_output_folder_outside_the_working_folder_must_be_asked_for(work):
    assert output_folder("res") == Path("res") and Path("res").is_dir()
    assert output_folder(work / "abs_inside") == work / "abs_inside"
    for bad in ("../outside", str(work.parent / "outside"), "res/../../outside"):
        with pytest.raises(OutputPathError, match=r"study.output .*: outside the working folder"):
            output_folder(bad, field="study.output")
    os.symlink(work.parent / "outside", "link_out")  # a link leading out is outside too
    with pytest.raises(OutputPathError, match="outside the working folder"):
        output_folder("link_out/sub")
    assert not (work.parent / "outside" / "sub").exists()
    assert output_folder("../outside", allow_outside=True) == Path("../outside")


# ------------------------------------------------------------------ tables


def test_sweep_table_writers_take_overwrite(work):
    t = SweepTable(records=[{"q": 1.0, "success": True}], inputs=("q",))
    t.to_csv("t.csv")
    t.to_json("t.json")
    with pytest.raises(OutputExistsError, match="t.csv: exists"):
        t.to_csv("t.csv")
    with pytest.raises(OutputExistsError, match="t.json: exists"):
        t.to_json("t.json")
    assert json.loads(t.to_json("t.json", overwrite=True))["records"][0]["q"] == 1.0
    assert SweepTable.from_csv(t.to_csv("t.csv", overwrite=True)).records == [{"q": 1.0, "success": True}]
    assert leftovers(work) == []


# ------------------------------------------------------------------ run_spec (API)


def test_run_spec_refuses_a_spec_output_outside_and_overwrites_nothing(work):
    outside = work.parent / "outside"
    spec = load_spec(write_spec(name="package", extra='output = "../outside"\n'))
    with pytest.raises(OutputPathError, match=r"s.toml: study.output ../outside: outside the working folder"):
        run_spec(spec, progress=False)
    # asked for: still never over the existing package.json, checked before the sweep
    with pytest.raises(OutputExistsError, match=r"package.json: exists; not overwritten"):
        run_spec(spec, progress=False, allow_outside=True)
    assert (outside / "package.json").read_text() == '{"keep": true}'
    assert not (outside / "package.csv").exists()  # refused before the sweep: nothing written
    res = run_spec(spec, progress=False, allow_outside=True, overwrite=True)
    assert res.table.n_success == 1 and json.loads((outside / "package.json").read_text())["records"]
    with pytest.raises(ValidationError, match="overwrite must be True or False; found 'yes'"):
        run_spec(spec, overwrite="yes")
    # an absolute path elsewhere is outside too
    spec = load_spec(write_spec(extra=f'output = "{outside / "abs"}"\n'))
    with pytest.raises(OutputPathError, match="outside the working folder"):
        run_spec(spec, progress=False)
    assert not (outside / "abs").exists()


def test_run_spec_output_argument_is_the_callers_choice(work):
    spec = load_spec(write_spec())
    res = run_spec(spec, progress=False, output=work.parent / "outside" / "mine")
    assert res.csv == work.parent / "outside" / "mine" / "s.csv" and res.csv.is_file()


def test_run_spec_replaces_a_symlinked_output_not_its_target(work):
    victim = work.parent / "outside" / "package.json"
    spec = load_spec(write_spec())
    Path("s_results").mkdir()
    os.symlink(victim, "s_results/s.json")
    with pytest.raises(OutputExistsError, match=r"s.json: a symbolic link .* not written through it"):
        run_spec(spec, progress=False)
    res = run_spec(spec, progress=False, overwrite=True)
    assert victim.read_text() == '{"keep": true}'
    assert not res.json.is_symlink() and json.loads(res.json.read_text())["records"]


# ------------------------------------------------------------------ optdesign study (CLI)


def test_study_cli_outside_folder_needs_allow_outside(work, capsys):
    outside = work.parent / "outside"
    write_spec(name="package", extra='output = "../outside"\n')
    code, out, err = run(["study", "s.toml", "--no-progress"], capsys)
    one_line_error(code, err, "s.toml: study.output ../outside: outside the working folder")
    assert out == "" and sorted(p.name for p in outside.iterdir()) == ["package.json"]
    code, _, err = run(["study", "s.toml", "--no-progress", "--allow-outside"], capsys)
    one_line_error(code, err, "package.json: exists; not overwritten")
    assert (outside / "package.json").read_text() == '{"keep": true}'
    code, _, err = run(["study", "s.toml", "--no-progress", "--allow-outside", "--overwrite"], capsys)
    assert code == 0, err
    assert json.loads((outside / "package.json").read_text())["meta"]["design"] == "kalman"


def test_study_cli_never_replaces_results_silently(work, capsys):
    write_spec()
    Path("o").mkdir()
    Path("o/s.csv").write_text("precious")
    code, _, err = run(["study", "s.toml", "--no-progress", "--out", "o"], capsys)
    one_line_error(code, err, "o/s.csv: exists; not overwritten (overwrite=True, or --overwrite on "
                              "the command line replaces it)")
    assert Path("o/s.csv").read_text() == "precious" and not Path("o/s.json").exists()
    code, _, err = run(["study", "s.toml", "--no-progress", "--out", "o", "--overwrite"], capsys)
    assert code == 0, err
    assert Path("o/s.csv").read_text().startswith("q,") and leftovers(work / "o") == []


def test_study_cli_does_not_write_through_a_symlink(work, capsys):
    victim = work.parent / "outside" / "package.json"
    write_spec()
    Path("o").mkdir()
    os.symlink(victim, "o/s.csv")
    code, _, err = run(["study", "s.toml", "--no-progress", "--out", "o"], capsys)
    one_line_error(code, err, "o/s.csv: a symbolic link")
    assert victim.read_text() == '{"keep": true}'
    code, _, err = run(["study", "s.toml", "--no-progress", "--out", "o", "--overwrite"], capsys)
    assert code == 0, err
    assert victim.read_text() == '{"keep": true}' and not Path("o/s.csv").is_symlink()


def test_study_cli_out_flag_may_point_anywhere(work, capsys):
    write_spec()
    code, _, err = run(["study", "s.toml", "--no-progress", "--out", "../outside/o"], capsys)
    assert code == 0, err
    assert (work.parent / "outside" / "o" / "s.csv").is_file()


# ------------------------------------------------------------------ specs refused before they cost memory


def test_a_grid_of_1e8_points_is_refused_before_it_is_built(work, capsys):
    write_spec(file="big.toml").write_text(
        SPEC.format(name="big", extra="").replace("q = [1.0]", "q = {start = 1, stop = 2, num = 10000}\n"
                                                  "r = {start = 1, stop = 2, num = 10000}"))
    with pytest.raises(SpecError, match=rf"big.toml: grid: q 10000 x r 10000 is 100000000 points; at most "
                                        rf"{MAX_GRID_POINTS}"):
        load_spec("big.toml")
    code, _, err = run(["study", "big.toml"], capsys)
    one_line_error(code, err, "is 100000000 points")
    Path("one_axis.toml").write_text(SPEC.format(name="x", extra="").replace(
        "q = [1.0]", "q = {start = 1, stop = 2, num = 100000000}"))
    with pytest.raises(SpecError, match=r"grid.q.num: 100000000 values; at most"):
        load_spec("one_axis.toml")
    with pytest.raises(ValidationError, match="grid: a 10000 x b 10000 is 100000000 points"):
        grid(a=range(10_000), b=range(10_000))
    with pytest.raises(ValidationError, match="points; at most"):
        grid(a=(x for x in range(10**9)))  # a generator is read no further than the limit


def test_a_nul_byte_in_a_spec_name_or_path_is_a_spec_error(work):
    base = {"study": {"problem": "chang_lee_1984_ex1", "design": "kalman"}, "grid": {"q": [1.0]}}
    for key, value, match in (("name", "a\x00b", "study.name: must be a non-empty name without slashes or "
                                                 "control characters"),
                              ("name", "..", "study.name: must be a non-empty name"),
                              ("output", "res\x00", "study.output: must be a folder name"),
                              ("problem", "mine\x00.json", "study.problem: missing or not a string")):
        data = {**base, "study": {**base["study"], key: value}}
        with pytest.raises(SpecError, match=match):
            parse_spec(data, source="s.toml")
    with pytest.raises(SpecError, match=r"figure.file: must be a file name ending in .png"):
        parse_spec({**base, "figure": {"x": "q", "y": "kappa2", "file": "k\x00.png"}}, source="s.toml")
    with pytest.raises(SpecError, match="cannot read the spec file"):
        load_spec("a\x00b.toml")


def test_deep_nesting_and_huge_integers_in_a_spec_are_spec_errors(work, capsys):
    Path("deep.toml").write_text("x = " + "[" * 5000 + "]" * 5000 + "\n")
    with pytest.raises(SpecError, match="deep.toml: invalid TOML: arrays or tables nested too deeply"):
        load_spec("deep.toml")
    Path("digits.toml").write_text(SPEC.format(name="d", extra="").replace("q = [1.0]", "q = [" + "7" * 5000
                                                                            + "]"))
    with pytest.raises(SpecError, match="digits.toml: invalid TOML: a number that cannot be read"):
        load_spec("digits.toml")
    code, _, err = run(["study", "digits.toml"], capsys)
    one_line_error(code, err, "a number that cannot be read")
    # built in Python: an integer too long to print is described, not printed
    base = {"study": {"problem": "chang_lee_1984_ex1", "design": "kalman"}}
    with pytest.raises(SpecError, match=r"grid.q.num: must be an integer >= 1; found a negative integer of "
                                        r"about 5000 digits"):
        parse_spec({**base, "grid": {"q": {"start": 1, "stop": 2, "num": -(10**4999)}}})
    with pytest.raises(SpecError, match=r"grid.q.start: must be a finite number; found an integer of about"):
        parse_spec({**base, "grid": {"q": {"start": 10**400, "stop": 2, "num": 2}}})


def test_pareto_front_csv_takes_overwrite(work):
    import numpy as np

    from optdesign.studies import ParetoFront

    t = SweepTable(records=[{"max_gain": 1.0, "kappa2": 2.0}], inputs=("max_gain",))
    front = ParetoFront(objectives=("kappa2", "gain_norm"), table=t, values=np.array([[2.0, 1.0]]),
                        nondominated=np.array([True]))
    front.to_csv("front.csv")
    with pytest.raises(OutputExistsError, match="front.csv: exists"):
        front.to_csv("front.csv")
    assert "nondominated" in front.to_csv("front.csv", overwrite=True).read_text()


def test_figures_are_checked_before_the_sweep_and_never_written_through_a_link(work):
    pytest.importorskip("matplotlib")
    victim = work.parent / "outside" / "package.json"
    Path("f.toml").write_text(SPEC.format(name="f", extra="").replace("q = [1.0]", "q = [1.0, 2.0]")
                              + '[figure]\nx = "q"\ny = "kappa2"\nfile = "k.png"\n')
    spec = load_spec("f.toml")
    Path("f_results").mkdir()
    os.symlink(victim, "f_results/k.png")
    with pytest.raises(OutputExistsError, match="k.png: a symbolic link"):
        run_spec(spec, progress=False)
    assert not Path("f_results/f.csv").exists()  # refused before the sweep: nothing written
    res = run_spec(spec, progress=False, overwrite=True)
    assert res.figures == (Path("f_results/k.png"),) and not res.figures[0].is_symlink()
    assert res.figures[0].read_bytes().startswith(b"\x89PNG") and victim.read_text() == '{"keep": true}'
    assert leftovers(work / "f_results") == []
