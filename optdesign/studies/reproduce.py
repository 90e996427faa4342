"""Shared pieces for reproducing the seed papers (used by ``optdesign reproduce`` and ``examples/``).

Each paper has a module ``optdesign.studies.paperNNN`` with a function
``reproduce(outdir, *, quick=False, progress=None) -> PaperReproduction`` that recomputes the
paper's examples with the library, writes its figures (PNG) into ``outdir`` (each reported to
``progress``, a :class:`optdesign._progress.Progress`, by :func:`save_figure`) and returns the table
of printed vs reproduced values.  :func:`reproduce_all` runs them all (a paper module that is
missing or fails is reported, not raised) and writes a summary table of printed vs reproduced
values (``summary.md`` and ``summary.csv``) next to the figures.

Files are written as every file optdesign writes (:mod:`optdesign._files`): never over an existing
file or symbolic link unless asked (``overwrite=True``; ``optdesign reproduce --overwrite``), to a
temporary name renamed onto the name, never through a symbolic link.  :func:`reproduce_all` checks
its outputs -- ``summary.md``, ``summary.csv`` and each requested paper's figures, named
``seed<id>_*.<format>`` -- before any paper runs.
"""

from __future__ import annotations

import contextvars
import csv
import functools
import importlib
import inspect
import io
import math
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .._files import as_overwrite, check_targets, write_text
from .._progress import Progress, as_progress
from ..errors import ValidationError
from ..plot.figures import FIGURE_DPI, FIGURE_FORMATS
from ..plot.figures import pyplot as _pyplot
from ..plot.figures import save_figure as _save
from .sweep import one_line_error

__all__ = [
    "ReproRow",
    "PaperReproduction",
    "pyplot",
    "output_dir",
    "save_figure",
    "paper_reproduction",
    "format_table",
    "fmt",
    "PAPERS",
    "paper_id",
    "PaperOutcome",
    "ReproductionSummary",
    "reproduce_all",
]


@dataclass(frozen=True)
class ReproRow:
    """One printed-vs-reproduced value.

    ``printed`` is the number as the paper prints it (None if the paper prints none);
    ``reproduced`` is what optdesign computes; ``agrees`` says whether they match to the
    paper's printed precision; ``note`` explains any difference (e.g. a known typo).
    """

    example: str
    quantity: str
    printed: str | None
    reproduced: str
    agrees: bool | None
    note: str = ""


@dataclass(frozen=True)
class PaperReproduction:
    """Everything reproduced from one paper."""

    paper: str
    title: str
    rows: tuple[ReproRow, ...] = ()
    figures: tuple[Path, ...] = field(default_factory=tuple)

    def table(self) -> str:
        return format_table(self.rows)


def format_table(rows) -> str:
    """A plain-text table of rows (example | quantity | printed | reproduced | agrees | note)."""
    head = ("example", "quantity", "printed", "reproduced", "agrees", "note")
    body = [(r.example, r.quantity, r.printed if r.printed is not None else "-", r.reproduced,
             {True: "yes", False: "NO", None: "-"}[r.agrees], r.note) for r in rows]
    widths = [min(60, max(len(str(x)) for x in col)) for col in zip(head, *body, strict=True)]
    line = lambda cells: " | ".join(str(c)[:60].ljust(w) for c, w in zip(cells, widths, strict=True))  # noqa: E731
    out = [line(head), "-+-".join("-" * w for w in widths)]
    out += [line(b) for b in body]
    return "\n".join(out)


def pyplot():
    """matplotlib.pyplot (matplotlib's own backend choice: ``Agg`` without a display, ``inline`` in
    Jupyter), or a clear error naming the extra.  No backend is forced."""
    return _pyplot()


def output_dir(outdir: str | Path) -> Path:
    """The folder of a paper's figures as a Path, created if missing."""
    out = Path(outdir)
    out.mkdir(parents=True, exist_ok=True)
    return out


#: the file format of the figures of a :func:`reproduce_all` call (set for the call's duration only)
_FIGURE_FORMAT: contextvars.ContextVar[str | None] = contextvars.ContextVar("figure_format", default=None)


#: whether the figures of a paper's ``reproduce(..., overwrite=...)`` call may replace existing files
_OVERWRITE: contextvars.ContextVar[bool] = contextvars.ContextVar("overwrite_figures", default=False)


def save_figure(fig, path: str | Path, *, dpi: int = FIGURE_DPI, layout: bool = True,
                progress: Progress | None = None, overwrite: bool | None = None, **savefig_kw) -> Path:
    """Lay out (``tight_layout`` unless ``layout=False``), write and close a figure; its path.

    Written at ``dpi`` (default 300) in the format of the path's suffix (``.png``, ``.svg``,
    ``.pdf``) -- or, inside :func:`reproduce_all` with ``figure_format``, in that format -- by
    :func:`optdesign.plot.save_figure` (a temporary file renamed onto ``path``, never through a
    symbolic link).  ``overwrite`` (default: that of the paper's ``reproduce`` call, else False)
    allows replacing an existing file.  ``progress`` (optional) gets one line naming the file.

    Raises
    ------
    OutputExistsError
        A file or symbolic link at ``path`` and overwriting not asked for."""
    fmt_ = _FIGURE_FORMAT.get()
    if fmt_ is not None:
        path = Path(path).with_suffix("." + fmt_)
    ow = _OVERWRITE.get() if overwrite is None else as_overwrite(overwrite)
    path = _save(fig, path, dpi=dpi, layout=layout, overwrite=ow, **savefig_kw)
    if progress is not None:
        progress.line(f"wrote {path.name} (at {progress.elapsed:.1f} s)")
    return path


def paper_reproduction(fn: Callable[..., PaperReproduction]) -> Callable[..., PaperReproduction]:
    """Give a paper's ``reproduce(outdir, *, quick=False, progress=None)`` the keyword
    ``overwrite: bool = False``: whether its figures (written by :func:`save_figure`) may replace
    files already in ``outdir``.  Without it an existing figure is an
    :class:`~optdesign.errors.OutputExistsError` naming it.

    Raises
    ------
    ValidationError
        ``overwrite`` not a bool.
    """

    @functools.wraps(fn)
    def reproduce(*args: Any, overwrite: bool = False, **kwargs: Any) -> PaperReproduction:
        token = _OVERWRITE.set(as_overwrite(overwrite))
        try:
            return fn(*args, **kwargs)
        finally:
            _OVERWRITE.reset(token)

    sig = inspect.signature(fn)
    reproduce.__signature__ = sig.replace(parameters=[  # type: ignore[attr-defined]
        *sig.parameters.values(),
        inspect.Parameter("overwrite", inspect.Parameter.KEYWORD_ONLY, default=False, annotation="bool")])
    reproduce.__doc__ = (fn.__doc__ or "").rstrip() + (
        "\n\n    ``overwrite=True`` replaces figures already in ``outdir`` (default: an existing one is "
        "an OutputExistsError).\n")
    return reproduce


def fmt(x, digits: int = 4) -> str:
    """Format a number or array compactly for the table."""
    import numpy as np

    a = np.asarray(x)
    if a.ndim == 0:
        v = complex(a)
        if v.imag == 0 or math.isnan(v.real):
            return f"{v.real:.{digits}g}"
        return f"{v.real:.{digits}g}{v.imag:+.{digits}g}j"
    return "[" + ", ".join(fmt(v, digits) for v in a.ravel()) + "]"


# --------------------------------------------------------------------------- all papers

#: seed paper id -> short title (the module is ``optdesign.studies.paper<id>``)
PAPERS: dict[str, str] = {
    "000": "Chang & Lee 1984: Kalman gain with pre-specified estimator eigenvalues",
    "001": "Jung & Huh: well-conditioned observer via the non-normality measure",
    "002": "Lee: frequency-domain properties of Kalman filters with output delay",
    "003": "Kim, Lee & Kim: generalized observer and output-noise rejection",
    "004": "Ahn et al.: Kalman filter design via block-pulse functions",
}


def paper_id(name: str | int) -> str:
    """Normalize a paper name: ``2``, ``"2"``, ``"002"``, ``"seed002"``, ``"paper002"`` -> ``"002"``.

    Raises
    ------
    ValidationError
        Not one of the seed papers.
    """
    s = str(name).strip().lower()
    for prefix in ("paper", "seed"):
        if s.startswith(prefix):
            s = s[len(prefix):]
    if s.isdigit() and s.zfill(3) in PAPERS:
        return s.zfill(3)
    raise ValidationError(f"unknown paper {name!r}; expected one of {', '.join(PAPERS)} (or seed000, ...)")


@dataclass(frozen=True)
class PaperOutcome:
    """What reproducing one paper gave.

    Attributes
    ----------
    paper : str
        ``"000"`` ... ``"004"``.
    title : str
    status : str
        ``"ok"``; ``"missing"`` (no module ``optdesign.studies.paper<id>`` or no ``reproduce``);
        ``"failed"`` (it raised; ``error`` has the one-line reason); ``"figures missing"``
        (a figure it reported was not written).
    reproduction : PaperReproduction or None
    error : str or None
    time : float
        Seconds.
    """

    paper: str
    title: str
    status: str
    reproduction: PaperReproduction | None = None
    error: str | None = None
    time: float = 0.0

    @property
    def ok(self) -> bool:
        return self.status == "ok"

    @property
    def figures(self) -> tuple[Path, ...]:
        return tuple(self.reproduction.figures) if self.reproduction is not None else ()


@dataclass(frozen=True)
class ReproductionSummary:
    """The outcome of :func:`reproduce_all`: per-paper outcomes and the summary files."""

    outdir: Path
    outcomes: tuple[PaperOutcome, ...]
    markdown: Path
    csv: Path

    @property
    def ok(self) -> bool:
        """Every requested paper was reproduced and wrote its figures."""
        return all(o.ok for o in self.outcomes)

    @property
    def figures(self) -> tuple[Path, ...]:
        return tuple(f for o in self.outcomes for f in o.figures)

    def overview(self) -> str:
        """A short plain-text table: one line per paper."""
        lines = []
        for o in self.outcomes:
            rows = o.reproduction.rows if o.reproduction is not None else ()
            agree = sum(1 for r in rows if r.agrees is True)
            differ = sum(1 for r in rows if r.agrees is False)
            what = (f"{len(rows)} values ({agree} agree with the print, {differ} differ){_errata(rows)}; "
                    f"{len(o.figures)} figures" if o.reproduction is not None else (o.error or ""))
            lines.append(f"seed {o.paper}  {o.status:<15} {o.time:7.1f} s  {what}")
        return "\n".join(lines)


def _errata(rows) -> str:
    """``; the 4 that differ are documented errata of the paper: eq (4.12), ...``: the differing rows
    that carry a note (the paper's misprints, on the docs' errata page) named, the others counted."""
    differ = [r for r in rows if r.agrees is False]
    if not differ:
        return ""
    known = list(dict.fromkeys(r.example for r in differ if r.note))
    n_known = sum(1 for r in differ if r.note)
    if n_known == len(differ):
        who = "it is a" if n_known == 1 else f"the {n_known} that differ are"
        return f"; {who} documented {'erratum' if n_known == 1 else 'errata'} of the paper: {', '.join(known)}"
    text = f"; {len(differ) - n_known} unexplained"
    return text + (f", {n_known} documented errata of the paper: {', '.join(known)}" if known else "")


def _md_cell(x) -> str:
    return " ".join(str(x).split()).replace("|", "\\|")


def _run_paper(pid: str, outdir: Path, quick: bool, progress: Progress | None = None) -> PaperOutcome:
    title = PAPERS[pid]
    modname = f"optdesign.studies.paper{pid}"
    t0 = time.perf_counter()
    try:
        module = importlib.import_module(modname)
    except ModuleNotFoundError as exc:
        if exc.name == modname:
            return PaperOutcome(pid, title, "missing", error=f"module {modname} does not exist (not "
                                                             "written yet)")
        return PaperOutcome(pid, title, "failed", error=f"importing {modname}: {one_line_error(exc)}",
                            time=time.perf_counter() - t0)
    except Exception as exc:  # noqa: BLE001 - reported in the table
        return PaperOutcome(pid, title, "failed", error=f"importing {modname}: {one_line_error(exc)}",
                            time=time.perf_counter() - t0)
    fn = getattr(module, "reproduce", None)
    if not callable(fn):
        return PaperOutcome(pid, title, "missing", error=f"{modname} has no reproduce(outdir, *, quick) "
                                                         "function")
    params = inspect.signature(fn).parameters
    kw: dict[str, Any] = {"progress": progress} if progress is not None and "progress" in params else {}
    if "overwrite" in params:  # else its figures follow reproduce_all's own (the context variable)
        kw["overwrite"] = _OVERWRITE.get()
    try:
        rep = fn(outdir, quick=quick, **kw)
    except Exception as exc:  # noqa: BLE001 - a failing paper is reported, the others still run
        return PaperOutcome(pid, title, "failed", error=one_line_error(exc), time=time.perf_counter() - t0)
    finally:
        _close_figures()
    dt = time.perf_counter() - t0
    if not isinstance(rep, PaperReproduction):
        return PaperOutcome(pid, title, "failed", error=f"reproduce() returned {type(rep).__name__}, "
                            f"not a PaperReproduction", time=dt)
    missing = [str(f) for f in rep.figures if not Path(f).is_file()]
    if missing:
        return PaperOutcome(pid, title, "figures missing", rep, "figure(s) not written: "
                                                                f"{', '.join(missing)}", dt)
    return PaperOutcome(pid, title, "ok", rep, None, dt)


def _close_figures() -> None:
    import sys

    if "matplotlib.pyplot" in sys.modules:
        sys.modules["matplotlib.pyplot"].close("all")


def _existing_outputs(out: Path, ids: list[str], figure_format: str) -> list[Path]:
    """What :func:`reproduce_all` would write over in ``out``: the summary files and each paper's
    figures (``seed<id>_*.<format>``, links included, dangling ones too)."""
    found = [out / "summary.md", out / "summary.csv"]
    try:
        with os.scandir(out) as it:
            names = sorted(e.name for e in it)
    except OSError:
        return found
    prefixes = tuple(f"seed{pid}_" for pid in ids)
    return found + [out / n for n in names if n.startswith(prefixes) and n.endswith("." + figure_format)]


def reproduce_all(outdir: str | Path, papers=None, quick: bool = False,
                  progress: bool | None = None, figure_format: str = "png", *,
                  overwrite: bool = False) -> ReproductionSummary:
    """Reproduce seed papers: every figure into ``outdir``, and a summary of printed vs reproduced values.

    Parameters
    ----------
    outdir : str or Path
        Folder for the figures and the summary (created if missing).
    papers : iterable of str, optional
        Paper ids (``"000"`` ... ``"004"``; ``"seed001"``, ``2`` ... accepted); default all.
    quick : bool
        Passed to each paper's ``reproduce`` (smaller grids and fewer starts, for CI).
    progress : bool or None
        Report each paper (started, finished, how long) and each figure written, on stderr:
        ``None`` (default) only when stderr is a terminal, ``True`` always, ``False`` never.
    figure_format : {"png", "svg", "pdf"}
        File format of every figure (raster figures at 300 dpi).
    overwrite : bool, default False
        Replace the summary and figures already in ``outdir``.  Without it, any of them there
        (a file or a symbolic link) is an :class:`~optdesign.errors.OutputExistsError` before
        any paper runs.  Files are written to a temporary name and renamed, never through a
        symbolic link (:mod:`optdesign._files`).

    Returns
    -------
    ReproductionSummary
        Per-paper outcomes; ``summary.md`` (one section per paper: status, figures, the table of
        printed vs reproduced values with notes) and ``summary.csv`` (one row per value; a paper
        that is missing or failed has one row saying so) are written into ``outdir``.  A missing or
        failing paper does not stop the others; ``summary.ok`` is False then.

    Raises
    ------
    ValidationError
        An unknown paper id; ``progress`` not a bool or None; ``figure_format`` not one of
        png, svg, pdf; ``overwrite`` not a bool.
    OutputExistsError
        A summary file or a requested paper's figure exists in ``outdir`` and ``overwrite`` is
        False (nothing run, nothing written).
    """
    if figure_format not in FIGURE_FORMATS:
        raise ValidationError(f"figure_format must be one of {', '.join(FIGURE_FORMATS)}; found {figure_format!r}")
    ids = list(PAPERS) if papers is None else list(dict.fromkeys(paper_id(p) for p in papers))
    progress = as_progress(progress)
    overwrite = as_overwrite(overwrite)
    out = Path(outdir)
    check_targets(_existing_outputs(out, ids, figure_format), overwrite=overwrite)
    out.mkdir(parents=True, exist_ok=True)
    results = []
    token = _FIGURE_FORMAT.set(figure_format)
    token_ow = _OVERWRITE.set(overwrite)
    try:
        with Progress(len(ids), "reproduce", enabled=progress, unit="paper") as bar:
            for i, pid in enumerate(ids):
                bar.line(f"seed {pid} ({i + 1}/{len(ids)}): {PAPERS[pid]}")
                o = _run_paper(pid, out, quick, bar)
                results.append(o)
                bar.update(1, note=f"seed {pid} {o.status} in {o.time:.1f} s")
    finally:
        _OVERWRITE.reset(token_ow)
        _FIGURE_FORMAT.reset(token)
    outcomes = tuple(results)
    md_path = out / "summary.md"
    csv_path = out / "summary.csv"
    lines = ["# optdesign: seed papers reproduced", "",
             f"Figures are in this folder. Mode: {'quick' if quick else 'full'}.", "",
             "| paper | status | values | agree | differ | figures | time (s) |",
             "|---|---|---|---|---|---|---|"]
    for o in outcomes:
        rows = o.reproduction.rows if o.reproduction is not None else ()
        lines.append(f"| {o.paper} {_md_cell(o.title)} | {o.status} | {len(rows)} | "
                     f"{sum(1 for r in rows if r.agrees is True)} | "
                     f"{sum(1 for r in rows if r.agrees is False)} | "
                     f"{len(o.figures)} | {o.time:.1f} |")
    for o in outcomes:
        lines += ["", f"## Seed {o.paper}: {o.title}", "", f"Status: **{o.status}**" +
                  (f" -- {_md_cell(o.error)}" if o.error else "")]
        if o.reproduction is not None:
            if o.figures:
                lines += ["", "Figures: " + ", ".join(f"[{Path(f).name}]({Path(f).name})" for f in o.figures)]
            lines += ["", "| example | quantity | printed | reproduced | agrees | note "
                          "|", "|---|---|---|---|---|---|"]
            for r in o.reproduction.rows:
                agrees = {True: "yes", False: "**NO**", None: "-"}[r.agrees]
                lines.append(f"| {_md_cell(r.example)} | {_md_cell(r.quantity)} | "
                             f"{_md_cell(r.printed if r.printed is not None else '-')} | "
                             f"{_md_cell(r.reproduced)} | "
                             f"{agrees} | {_md_cell(r.note)} |")
    write_text(md_path, "\n".join(lines) + "\n", overwrite=overwrite)
    fh = io.StringIO()
    w = csv.writer(fh)
    w.writerow(["paper", "status", "example", "quantity", "printed", "reproduced", "agrees", "note"])
    for o in outcomes:
        if o.reproduction is None or not o.reproduction.rows:
            w.writerow([o.paper, o.status, "", "", "", "", "", o.error or ""])
            continue
        for r in o.reproduction.rows:
            w.writerow([o.paper, o.status, r.example, r.quantity, "" if r.printed is None else r.printed,
                        r.reproduced, {True: "yes", False: "no", None: ""}[r.agrees], r.note])
    write_text(csv_path, fh.getvalue(), overwrite=overwrite, newline="")
    return ReproductionSummary(out, outcomes, md_path, csv_path)
