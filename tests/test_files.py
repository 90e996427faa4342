"""Files never lose data (issue 26, item 4), for every writer of the library beyond the studies'
tables: the writer itself (:mod:`optdesign._files`), figures (``optdesign.plot.save_figure``,
``plot_pareto``, ``plot_table``), the seed papers' figures and summaries (``paperNNN.reproduce``,
``reproduce_all``, ``optdesign reproduce``).  For each: an existing file is kept byte for byte
(a typed error naming it), a symbolic link's target is never written, ``overwrite=True`` replaces
the file -- or the link itself -- and no temporary file is left behind."""

from __future__ import annotations

import os
import sys
import types
from pathlib import Path

import numpy as np
import pytest

from optdesign._files import atomic_path, check_targets, write_text
from optdesign.cli import main
from optdesign.errors import OutputExistsError, OutputPathError, ValidationError

PRECIOUS = b"precious \x00\xff bytes\n"


@pytest.fixture()
def work(tmp_path, monkeypatch):
    """A working folder, and a file elsewhere that a symbolic link will point to."""
    here = tmp_path / "work"
    here.mkdir()
    victim = tmp_path / "victim.txt"
    victim.write_bytes(PRECIOUS)
    monkeypatch.chdir(here)
    return here, victim


def leftovers(folder: Path) -> list[str]:
    return [p.name for p in folder.iterdir() if ".tmp" in p.name]


def existing(path: str | Path) -> Path:
    Path(path).write_bytes(PRECIOUS)
    return Path(path)


# ----------------------------------------------------------------------------- the writer


def test_write_text_keeps_existing_files_and_links(work):
    here, victim = work
    f = existing("a.txt")
    with pytest.raises(OutputExistsError, match=r"a.txt: exists; not overwritten \(overwrite=True, or "
                                                r"--overwrite on the command line replaces it\)") as err:
        write_text(f, "new")
    assert err.value.path == "a.txt" and f.read_bytes() == PRECIOUS
    os.symlink(victim, "link.txt")
    with pytest.raises(OutputExistsError, match=r"link.txt: a symbolic link \(to .*victim.txt\)"):
        write_text("link.txt", "new")
    write_text("link.txt", "new", overwrite=True)
    assert not Path("link.txt").is_symlink() and Path("link.txt").read_text() == "new"
    assert victim.read_bytes() == PRECIOUS
    assert write_text(f, "replaced", overwrite=True).read_text() == "replaced"
    assert leftovers(here) == []


def test_atomic_path_takes_any_writer_and_cleans_up(work):
    here, _ = work
    with atomic_path("m.npy") as tmp:
        assert tmp.parent == Path(".") and tmp.suffix == ".npy" and tmp.exists()
        np.save(tmp, np.arange(3))
    assert np.load("m.npy").tolist() == [0, 1, 2]
    with pytest.raises(OutputExistsError, match="m.npy: exists"), atomic_path("m.npy") as tmp:
        pytest.fail("the block must not run when the file exists")  # pragma: no cover
    with pytest.raises(ZeroDivisionError), atomic_path("m.npy", overwrite=True) as tmp:
        tmp.write_bytes(b"half a fi")
        1 / 0  # noqa: B018 - a writer failing half-way
    assert np.load("m.npy").tolist() == [0, 1, 2] and leftovers(here) == []
    with pytest.raises(ValidationError, match="overwrite must be True or False; found 'yes'"):
        write_text("n.txt", "x", overwrite="yes")
    with pytest.raises(OutputPathError, match="a folder is where a result file is to be written"):
        check_targets([here])


# ----------------------------------------------------------------------------- figures


@pytest.fixture()
def plt():
    mpl = pytest.importorskip("matplotlib")
    mpl.use("Agg")
    import matplotlib.pyplot as pyplot

    yield pyplot
    pyplot.close("all")


def _figure(plt):
    fig, ax = plt.subplots()
    ax.plot([0, 1], [1, 0])
    return fig


def test_save_figure_never_loses_a_file(work, plt):
    from optdesign.plot import save_figure

    here, victim = work
    f = existing("fig.png")
    fig = _figure(plt)
    with pytest.raises(OutputExistsError, match="fig.png: exists; not overwritten"):
        save_figure(fig, f)
    assert f.read_bytes() == PRECIOUS and plt.fignum_exists(fig.number)  # left open: save it elsewhere
    os.symlink(victim, "link.svg")
    with pytest.raises(OutputExistsError, match="link.svg: a symbolic link"):
        save_figure(fig, "link.svg", close=False)
    assert save_figure(fig, "link.svg", overwrite=True, close=False) == Path("link.svg")
    assert not Path("link.svg").is_symlink() and Path("link.svg").read_bytes().lstrip().startswith(b"<?xml")
    assert victim.read_bytes() == PRECIOUS
    assert save_figure(fig, "plain", close=False) == Path("plain.png")  # as fig.savefig("plain")
    assert Path("plain.png").read_bytes().startswith(b"\x89PNG")
    save_figure(fig, f, overwrite=True)
    assert f.read_bytes().startswith(b"\x89PNG") and not plt.fignum_exists(fig.number)
    assert leftovers(here) == []


def _front():
    """A two-point ParetoFront built by hand (no solves)."""
    from optdesign.studies import SweepTable
    from optdesign.studies.pareto import ParetoFront

    recs = [{"max_gain": None, "kappa2": 1.0, "gain_norm": 3.0, "success": True, "anchor": "kappa2"},
            {"max_gain": 2.0, "kappa2": 2.0, "gain_norm": 2.0, "success": True, "anchor": None}]
    table = SweepTable(records=recs, inputs=("max_gain",))
    return ParetoFront(objectives=("kappa2", "gain_norm"), table=table,
                       values=np.array([[1.0, 3.0], [2.0, 2.0]]), nondominated=np.array([True, True]),
                       designs=[None, None], levels={"gain_norm": [2.0]})


def test_plot_pareto_never_loses_a_file(work, plt):
    from optdesign.plot.studies import plot_pareto

    here, victim = work
    front = _front()
    f = existing("front.png")
    with pytest.raises(OutputExistsError, match="front.png: exists; not overwritten"):
        plot_pareto(front, f)
    assert f.read_bytes() == PRECIOUS
    os.symlink(victim, "link.png")
    with pytest.raises(OutputExistsError, match="link.png: a symbolic link"):
        front.plot("link.png")
    front.plot("link.png", overwrite=True)
    assert Path("link.png").read_bytes().startswith(b"\x89PNG") and victim.read_bytes() == PRECIOUS
    plot_pareto(front, f, overwrite=True)
    assert f.read_bytes().startswith(b"\x89PNG") and leftovers(here) == []


def test_plot_table_never_loses_a_file(work, plt):
    from optdesign.plot.studies import plot_table
    from optdesign.studies import SweepTable
    from optdesign.studies.spec import FigureSpec

    here, victim = work
    table = SweepTable(records=[{"q": 1.0, "kappa2": 2.0, "success": True},
                                {"q": 2.0, "kappa2": 3.0, "success": True}], inputs=("q",))
    spec = FigureSpec(x="q", y=("kappa2",), file="k.png")
    f = existing("k.png")
    with pytest.raises(OutputExistsError, match="k.png: exists; not overwritten"):
        plot_table(table, spec, f)
    assert f.read_bytes() == PRECIOUS and plt.get_fignums() == []  # refused before drawing
    os.symlink(victim, "link.png")
    with pytest.raises(OutputExistsError, match="link.png: a symbolic link"):
        plot_table(table, spec, "link.png")
    assert plot_table(table, spec, "link.png", overwrite=True) == Path("link.png")
    assert victim.read_bytes() == PRECIOUS and not Path("link.png").is_symlink()
    plot_table(table, spec, f, overwrite=True)
    assert f.read_bytes().startswith(b"\x89PNG") and leftovers(here) == []


# ----------------------------------------------------------------------------- seed papers


def _paper(calls: list):
    """A fake seed paper: one figure through the papers' save_figure, its reproduce decorated as
    the real ones."""
    from optdesign.studies.reproduce import (
        PaperReproduction,
        ReproRow,
        paper_reproduction,
        pyplot,
        save_figure,
    )

    @paper_reproduction
    def reproduce(outdir, *, quick=False, progress=None):
        calls.append(outdir)
        fig, ax = pyplot().subplots()
        ax.plot([0, 1], [0, 1])
        path = save_figure(fig, Path(outdir) / "seed000_fake.png", progress=progress)
        return PaperReproduction("000", "fake", (ReproRow("ex", "K", "1", "1", True),), (path,))

    return types.SimpleNamespace(reproduce=reproduce)


def test_a_papers_figures_are_never_overwritten_unasked(work, plt):
    import inspect

    here, victim = work
    paper = _paper(calls := [])
    assert inspect.signature(paper.reproduce).parameters["overwrite"].default is False
    f = existing("seed000_fake.png")
    with pytest.raises(OutputExistsError, match="seed000_fake.png: exists"):
        paper.reproduce(here)
    assert f.read_bytes() == PRECIOUS
    rep = paper.reproduce(here, overwrite=True)
    assert rep.figures == (here / "seed000_fake.png",) and f.read_bytes().startswith(b"\x89PNG")
    with pytest.raises(ValidationError, match="overwrite must be True or False"):
        paper.reproduce(here, overwrite=1)
    assert len(calls) == 2 and leftovers(here) == [] and victim.read_bytes() == PRECIOUS


def test_reproduce_all_checks_every_output_before_any_paper_runs(work, plt, monkeypatch):
    from optdesign.studies.reproduce import reproduce_all

    here, victim = work
    monkeypatch.setitem(sys.modules, "optdesign.studies.paper000", _paper(calls := []))
    out = here / "r"
    out.mkdir()
    os.symlink(victim, out / "summary.md")
    with pytest.raises(OutputExistsError, match="summary.md: a symbolic link"):
        reproduce_all(out, papers=["000"], progress=False)
    os.unlink(out / "summary.md")
    fig = existing(out / "seed000_fake.png")
    with pytest.raises(OutputExistsError, match="seed000_fake.png: exists"):
        reproduce_all(out, papers=["000"], progress=False)
    assert calls == [] and fig.read_bytes() == PRECIOUS  # refused before the paper ran
    reproduce_all(out, papers=["000"], progress=False, figure_format="svg")  # other files: no clash
    s = reproduce_all(out, papers=["000"], progress=False, overwrite=True)
    assert s.ok and fig.read_bytes().startswith(b"\x89PNG") and len(calls) == 2
    assert "## Seed 000" in s.markdown.read_text() and s.csv.read_text().startswith("paper,status")
    with pytest.raises(OutputExistsError, match="summary.md: exists"):
        reproduce_all(out, papers=["000"], progress=False)
    assert leftovers(out) == [] and victim.read_bytes() == PRECIOUS


def test_cli_reproduce_needs_overwrite(work, plt, monkeypatch, capsys):
    here, _ = work
    monkeypatch.setitem(sys.modules, "optdesign.studies.paper000", _paper(calls := []))
    assert main(["reproduce", "000", "--out", "r", "--no-progress"]) == 0
    summary = Path("r/summary.md")
    summary.write_bytes(PRECIOUS)
    capsys.readouterr()
    assert main(["reproduce", "000", "--out", "r", "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("optdesign: error: r/summary.md: exists; not overwritten") and err.count("\n") == 1
    assert summary.read_bytes() == PRECIOUS and len(calls) == 1
    assert main(["reproduce", "000", "--out", "r", "--no-progress", "--overwrite"]) == 0
    assert summary.read_text().startswith("# optdesign") and len(calls) == 2
    assert leftovers(here / "r") == []
