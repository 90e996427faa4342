r"""Study specifications: a sweep described in a TOML file (``optdesign study SPEC.toml``).

Format
------
::

    [study]
    name = "alpha_sector"           # optional (default: the file name)
    title = "..."                   # optional, used in the figure
    problem = "compleib_dis2"       # a library problem (`optdesign list`), or a problem file
                                    # (mine.json / .toml / .npz / .mat, relative to the spec file;
                                    # see optdesign.problems.load_file)
    design = "well_conditioned"     # the study verb (see below)
    output = "alpha_sector_results" # folder, relative to the current directory and inside it
                                    # (default "<name>_results"; `optdesign study --out DIR`
                                    # overrides it; see "Where results go" below)
    executor = "processes"          # processes | threads | serial | dask (default processes)
    workers = 2                     # optional: pool size / Dask LocalCluster workers
    scheduler = "tcp://host:8786"   # optional, executor = "dask": an existing cluster
    chunksize = 25                  # optional: points per task (warm starts run within a chunk)
    timeout = 3600                  # optional: seconds for the whole sweep

    [fixed]                         # keyword arguments of the designer, fixed for every point
    radius = 20.0
    objective = "kappa2"
    region = "halfplane:0.1"        # same syntax as `optdesign design --region`

    [grid]                          # one axis per entry; the sweep is their Cartesian product
    alpha = {start = 0.5, stop = 3.0, num = 6}      # evenly spaced (log = true: geometric)
    zeta = [0.3, 0.5, 0.7]                          # explicit values

    [figure]                        # optional; [[figure]] (an array of tables) for several
    kind = "line"                   # line (default) | heatmap
    x = "alpha"                     # an axis of the grid
    y = "kappa2"                    # line: a result column, or a list of them
    series = "zeta"                 # line: one curve per value of this axis (legend)
    logy = false                    # log-scaled y axis (also logx)
    file = "kappa2.png"             # default "<name>_<y>.png"
    # heatmap: x and y are axes, value = "kappa2" is the column shown in colour

Study verbs (``design``) and their grid axes:

========================== ============================================== ===============================
design                     designer (:mod:`optdesign.studies.designers`)  axes
========================== ============================================== ===============================
``well_conditioned``       :class:`RegionSweepDesigner`                   alpha, zeta, radius, max_gain,
                           (build once, re-solve)                         kappa2_max, eta_max
``kalman``                 :class:`KalmanNoiseDesigner` (q/r)             q, r
``inverse``                :class:`PoleTargetDesigner`, inverse           scale, shift
``place``                  :class:`PoleTargetDesigner`, place             scale, shift
``well_conditioned_poles`` :class:`PoleTargetDesigner`, fixed poles       scale, shift
========================== ============================================== ===============================

Results: ``<output>/<name>.csv`` (one row per point: inputs, status, success, metrics, time,
error, and for a failed point its ``reason`` in one line), ``<output>/<name>.json`` and the
figure(s).  Only successful (solved and verified) points are drawn; the title says how many
failed.

Where results go (the rules: :mod:`optdesign.studies.output`): the output folder is relative to the
*current directory* (never to the spec file) and must lie inside it unless the caller asks
(``--allow-outside``; ``--out DIR`` may be anywhere); an existing result file is never overwritten
unless asked (``--overwrite``), checked before the sweep.  A grid has at most
:data:`~optdesign.studies.sweep.MAX_GRID_POINTS` points, counted before any is built.

Every mistake in a spec file raises :class:`SpecError` (a :class:`~optdesign.errors.ValidationError`)
with a one-line message that names the file and the field, e.g.
``study.toml: grid.alpha.num: must be an integer >= 1; found 'ten'``.

Region syntax (``region`` in ``[fixed]`` and ``optdesign design --region``): members joined by
``&``, each ``shape:numbers`` -- ``halfplane:ALPHA`` (``Re s <= -ALPHA``), ``sector:ZETA`` (damping
ratio ``>= ZETA``), ``disk:RADIUS`` or ``disk:CENTER,RADIUS``, ``strip:LO,HI`` (``LO <= Re s <= HI``),
``hstrip:OMEGA`` (``|Im s| <= OMEGA``), ``ellipse:CENTER,A,B``, ``stable`` (``Re s <= 0``).
Example: ``"halfplane:1.5 & sector:0.7 & disk:20"``.
"""

from __future__ import annotations

import dataclasses
import math
import sys
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .. import problems
from .._validate import shown
from ..errors import BackendUnavailableError, OptDesignError, OutputPathError, ValidationError
from ..model.regions import Region
from ..plot.studies import LABELS, SYMBOLS, plot_table  # the figures live in optdesign.plot
from .designers import DESIGNERS
from .output import check_targets, file_name, output_folder
from .sweep import MAX_GRID_POINTS, SweepTable, grid, sweep
from .syntax import REGION_SHAPES, format_region, parse_poles, parse_region

__all__ = [
    "SpecError",
    "StudySpec",
    "FigureSpec",
    "StudyOutput",
    "load_spec",
    "parse_spec",
    "run_spec",
    "parse_region",
    "parse_poles",
    "plot_table",
    "LABELS",
    "SYMBOLS",
    "REGION_SHAPES",
    "require_matplotlib",
    "format_region",
]

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib


class SpecError(ValidationError):
    """A mistake in a study spec (one line naming the file and the field)."""


# --------------------------------------------------------------------------- spec

_STUDY_KEYS = ("name", "title", "problem", "design", "output", "executor", "workers", "scheduler",
               "chunksize", "timeout")
_EXECUTORS = ("processes", "threads", "serial", "dask")
_FIGURE_KEYS = ("kind", "x", "y", "series", "value", "logx", "logy", "file", "title")

@dataclass(frozen=True)
class FigureSpec:
    """One figure of a study (see the module docstring)."""

    kind: str = "line"
    x: str = ""
    y: tuple[str, ...] = ()
    series: str | None = None
    value: str | None = None
    logx: bool = False
    logy: bool = False
    file: str = ""
    title: str = ""


@dataclass(frozen=True)
class StudySpec:
    """A parsed, validated study spec."""

    name: str
    problem: str
    design: str
    designer: Any
    points: tuple[dict[str, Any], ...]
    axes: dict[str, list[Any]]
    output: Path
    executor: str = "processes"
    workers: int | None = None
    scheduler: str | None = None
    chunksize: int | None = None
    timeout: float | None = None
    title: str = ""
    figures: tuple[FigureSpec, ...] = ()
    source: str = "<spec>"


@dataclass(frozen=True)
class StudyOutput:
    """What :func:`run_spec` produced."""

    spec: StudySpec
    table: SweepTable
    csv: Path
    json: Path
    figures: tuple[Path, ...] = field(default_factory=tuple)


def load_spec(path: str | Path) -> StudySpec:
    """Read and validate a TOML study spec (a problem file it names is relative to the spec file;
    the output folder is relative to the current directory).

    Raises
    ------
    SpecError
        Unreadable file, invalid TOML, or a bad field (the message names it).
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise SpecError(f"{path}: no such spec file") from None
    except (OSError, ValueError) as exc:  # not UTF-8, or a NUL character in the path
        raise SpecError(f"{path}: cannot read the spec file: {exc}") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SpecError(f"{path.name}: invalid TOML: {' '.join(str(exc).split())}") from None
    except RecursionError:
        raise SpecError(f"{path.name}: invalid TOML: arrays or tables nested too deeply") from None
    except ValueError as exc:  # an integer beyond Python's digit limit
        raise SpecError(f"{path.name}: invalid TOML: a number that cannot be read "
                        f"({' '.join(str(exc).split())[:120]})") from None
    return parse_spec(data, source=path.name, base=path.parent, default_name=path.stem)


def _err(source: str, fieldname: str, msg: str) -> SpecError:
    return SpecError(f"{source}: {fieldname}: {msg}")


def _is_number(v: Any) -> bool:  # a finite float, or an integer within the float range
    return (isinstance(v, (int, float)) and not isinstance(v, bool)
            and (abs(v) <= sys.float_info.max if isinstance(v, int) else math.isfinite(v)))


def _axis_values(source: str, name: str, v: Any) -> list[Any]:
    f = f"grid.{name}"
    if isinstance(v, list):
        if not v:
            raise _err(source, f, "empty list of values")
        if len(v) > MAX_GRID_POINTS:
            raise _err(source, f, f"{len(v)} values; at most {MAX_GRID_POINTS} "
                                  "(optdesign.studies.sweep.MAX_GRID_POINTS)")
        for x in v:
            if not (_is_number(x) or isinstance(x, str)):
                raise _err(source, f, f"values must be numbers; found {shown(x)}")
        return list(v)
    if isinstance(v, Mapping):
        unknown = set(v) - {"start", "stop", "num", "log"}
        if unknown:
            raise _err(source, f"{f}.{sorted(unknown)[0]}", "unknown key; a range has start, stop, num, log")
        for k in ("start", "stop", "num"):
            if k not in v:
                raise _err(source, f"{f}.{k}", "missing (a range needs start, stop and num)")
        for k in ("start", "stop"):
            if not _is_number(v[k]):
                raise _err(source, f"{f}.{k}", f"must be a finite number; found {shown(v[k])}")
        num = v["num"]
        if isinstance(num, bool) or not isinstance(num, int) or num < 1:
            raise _err(source, f"{f}.num", f"must be an integer >= 1; found {shown(num)}")
        if num > MAX_GRID_POINTS:
            raise _err(source, f"{f}.num", f"{shown(num)} values; at most {MAX_GRID_POINTS} "
                                           "(optdesign.studies.sweep.MAX_GRID_POINTS)")
        log = v.get("log", False)
        if not isinstance(log, bool):
            raise _err(source, f"{f}.log", f"must be true or false; found {log!r}")
        if log:
            if not (v["start"] > 0 and v["stop"] > 0):
                raise _err(source, f"{f}.start", "a log range needs start > 0 and stop > 0")
            vals = np.geomspace(v["start"], v["stop"], num)
        else:
            vals = np.linspace(v["start"], v["stop"], num)
        return [float(x) for x in vals]
    if _is_number(v):
        return [v]
    raise _err(source, f, f"expected a list of values or {{start, stop, num}}; found {shown(v)}")


def _designer_fields(cls) -> list[str]:
    return [f.name for f in dataclasses.fields(cls) if f.name not in ("problem", "plant")]


def _columns_of(design: str) -> tuple[str, ...]:
    common = ("kappa2", "eta", "gain_norm", "max_real_pole", "time", "solver_time", "success")
    if design == "well_conditioned":
        return (*common, "kappa_fro", "iterations", "converged")
    if design == "kalman":
        return (*common, "residual", "max_abs_pole")
    return (*common, "pole_error", "trace_Q", "max_abs_pole")


def _fixed_arguments(source: str, fixed: Mapping[str, Any], cls: Any, forced: Mapping[str, Any],
                     design: str) -> tuple[dict[str, Any], dict[str, Any]]:
    """The designer's keyword arguments and the constant grid values given in ``[fixed]``."""
    fields = _designer_fields(cls)
    axes_allowed = list(cls.AXES)
    kwargs: dict[str, Any] = {}
    constant_point: dict[str, Any] = {}
    for k, v in fixed.items():
        f = f"fixed.{k}"
        if k in forced:
            raise _err(source, f, f"is set by design = {design!r}")
        if k not in fields and k not in axes_allowed:
            allowed = sorted(set(fields) - set(forced)) + [a for a in axes_allowed if a not in fields]
            raise _err(source, f, f"unknown argument for design {design!r}; expected one of "
                                  f"{', '.join(allowed)}")
        if k == "region":
            try:
                v = parse_region(v, field=f) if isinstance(v, str) else v
            except ValidationError as exc:
                raise SpecError(f"{source}: {exc}") from None
            if not isinstance(v, Region):
                raise _err(source, f, "must be a region string such as 'halfplane:1 & sector:0.7'")
        elif k == "poles":
            try:
                v = tuple(parse_poles(v, field=f))
            except ValidationError as exc:
                raise SpecError(f"{source}: {exc}") from None
        elif k == "options":
            if not isinstance(v, Mapping):
                raise _err(source, f, "must be a table of IPOPT options")
            v = dict(v)
        if k in fields:
            kwargs[k] = v
        else:
            constant_point[k] = v
    return kwargs, constant_point


def _make_designer(source: str, cls: Any, prob: problems.Problem, forced: Mapping[str, Any],
                   kwargs: Mapping[str, Any]) -> Any:
    """The designer of the spec; its validation errors name the ``[fixed]`` field (or the problem).

    A library problem is passed by name (each worker loads it); a problem file by its plant (and
    its target poles, unless ``[fixed]`` gives poles)."""
    if prob.origin == "library":
        what: dict[str, Any] = {"problem": prob.name}
    else:
        what = {"plant": prob.plant}
        names = {f.name for f in dataclasses.fields(cls)}
        if "poles" in names and "poles" not in kwargs and "poles" in prob.targets:
            what["poles"] = tuple(complex(z) for z in np.asarray(prob.targets["poles"]).ravel())
    try:
        return cls(**what, **forced, **kwargs)
    except ValidationError as exc:
        msg = " ".join(str(exc).split())
        where = next((f"fixed.{k}" for k in kwargs if k in msg), None)
        if where is None:
            about_problem = any(w in msg for w in ("noise", "target poles", "problem"))
            where = "study.problem" if about_problem else "fixed"
            if "target poles" in msg:
                msg += " (in [fixed], e.g. poles = ['-1', '-2+1j', '-2-1j'])"
        raise _err(source, where, msg) from None


def parse_spec(data: Mapping[str, Any], *, source: str = "<spec>", base: str | Path = ".",
               default_name: str = "study") -> StudySpec:
    """Validate a spec already read from TOML (a dict); see the module docstring for the format.

    Raises
    ------
    SpecError
        A bad or missing field (one line naming it).
    """
    if not isinstance(data, Mapping):
        raise SpecError(f"{source}: a spec is a TOML document with [study], [fixed], [grid], [figure]")
    unknown = set(data) - {"study", "fixed", "grid", "figure"}
    if unknown:
        raise _err(source, sorted(unknown)[0], "unknown section; a spec has [study], [fixed], [grid], "
                                               "[figure]")
    study = data.get("study")
    if not isinstance(study, Mapping):
        raise _err(source, "study", "missing [study] section (problem, design, ...)")
    for k in study:
        if k not in _STUDY_KEYS:
            raise _err(source, f"study.{k}", f"unknown field; [study] has {', '.join(_STUDY_KEYS)}")
    name = study.get("name", default_name)
    try:
        name = file_name("name", name)
    except OutputPathError:
        raise _err(source, "study.name", f"must be a non-empty name without slashes or control "
                                         f"characters (it names the result files); found {shown(name)}") \
            from None
    problem = study.get("problem")
    if not isinstance(problem, str) or "\x00" in problem:
        raise _err(source, "study.problem", "missing or not a string (a problem name, see `optdesign list`, "
                                            f"or a problem file); found {shown(problem)}")
    ref: str | Path = problem
    if problems.is_problem_file(problem) and not Path(problem).is_absolute():
        ref = Path(base) / problem  # a problem file next to the spec
    try:
        prob = problems.load(ref)
    except OptDesignError as exc:
        raise _err(source, "study.problem", str(exc)) from None
    if prob.plant is None:
        raise _err(source, "study.problem", f"problem {problem!r} has no valid plant")
    design = study.get("design")
    if design not in DESIGNERS:
        raise _err(source, "study.design", f"must be one of {', '.join(DESIGNERS)}; found {design!r}")
    cls, forced = DESIGNERS[design]
    executor = study.get("executor", "processes")
    if executor not in _EXECUTORS:
        raise _err(source, "study.executor", f"must be one of {', '.join(_EXECUTORS)}; found {executor!r}")
    ints: dict[str, int | None] = {}
    for k in ("workers", "chunksize"):
        v = study.get(k)
        if v is not None and (isinstance(v, bool) or not isinstance(v, int) or v < 1):
            raise _err(source, f"study.{k}", f"must be an integer >= 1; found {v!r}")
        ints[k] = v
    timeout = study.get("timeout")
    if timeout is not None and not (_is_number(timeout) and timeout > 0):
        raise _err(source, "study.timeout", f"must be a positive number of seconds; found {timeout!r}")
    scheduler = study.get("scheduler")
    if scheduler is not None and (not isinstance(scheduler, str) or executor != "dask"):
        raise _err(source, "study.scheduler", "must be an address string, with executor = \"dask\"")
    title = study.get("title", "")
    if not isinstance(title, str):
        raise _err(source, "study.title", f"must be a string; found {title!r}")
    output = study.get("output", f"{name}_results")
    if not isinstance(output, str) or not output.strip() or "\x00" in output:
        raise _err(source, "study.output", f"must be a folder name (no NUL character); found "
                                           f"{shown(output)}")
    out_path = Path(output)  # relative to the current directory, like --out

    # fixed arguments
    fixed = data.get("fixed", {})
    if not isinstance(fixed, Mapping):
        raise _err(source, "fixed", "must be a table of designer arguments")
    axes_allowed = list(cls.AXES)
    kwargs, constant_point = _fixed_arguments(source, fixed, cls, forced, design)
    designer = _make_designer(source, cls, prob, forced, kwargs)

    # grid
    g = data.get("grid")
    if not isinstance(g, Mapping) or not g:
        raise _err(source, "grid", f"missing or empty [grid] (axes for design {design!r}: "
                                   f"{', '.join(axes_allowed)})")
    axes: dict[str, list[Any]] = {}
    for k, v in g.items():
        if k not in axes_allowed:
            raise _err(source, f"grid.{k}", f"unknown axis for design {design!r}; expected one of "
                                            f"{', '.join(axes_allowed)}")
        if k in fixed:
            raise _err(source, f"grid.{k}", "is also given in [fixed]")
        axes[k] = _axis_values(source, k, v)
    for k, v in constant_point.items():
        axes[k] = [v]
    count = math.prod(len(v) for v in axes.values())  # counted before any point is built
    if count > MAX_GRID_POINTS:
        sizes = " x ".join(f"{k} {len(v)}" for k, v in axes.items() if len(v) > 1)
        raise _err(source, "grid", f"{sizes} is {count} points; at most {MAX_GRID_POINTS} "
                                   "(optdesign.studies.sweep.MAX_GRID_POINTS): split the study")
    pts = grid(**axes)
    # validate the values of every point through the designer (cheap, no solving)
    for p in pts:
        try:
            designer.check_point(**p)
        except ValidationError as exc:
            msg = " ".join(str(exc).split())
            bad = next((k for k in p if k in msg), next(iter(p)))
            sect = "fixed" if bad in constant_point else "grid"
            raise _err(source, f"{sect}.{bad}", f"{msg} (at point {p})") from None

    # figures
    figs_raw = data.get("figure", [])
    if isinstance(figs_raw, Mapping):
        figs_raw = [figs_raw]
    if not isinstance(figs_raw, list):
        raise _err(source, "figure", "must be a table [figure] or an array of tables [[figure]]")
    figures = []
    for i, fr in enumerate(figs_raw):
        figures.append(_parse_figure(source, fr, i if len(figs_raw) > 1 else None, axes, design, name))
    return StudySpec(name=name, problem=problem, design=design, designer=designer, points=tuple(pts),
                     axes=axes, output=out_path, executor=executor, workers=ints["workers"],
                     scheduler=scheduler,
                     chunksize=ints["chunksize"], timeout=None if timeout is None else float(timeout),
                     title=title, figures=tuple(figures), source=source)


def _parse_figure(source: str, fr: Any, index: int | None, axes: dict[str, list], design: str,
                  name: str) -> FigureSpec:
    pre = "figure" if index is None else f"figure[{index}]"
    if not isinstance(fr, Mapping):
        raise _err(source, pre, "must be a table")
    for k in fr:
        if k not in _FIGURE_KEYS:
            raise _err(source, f"{pre}.{k}", f"unknown field; a figure has {', '.join(_FIGURE_KEYS)}")
    kind = fr.get("kind", "line")
    if kind not in ("line", "heatmap"):
        raise _err(source, f"{pre}.kind", f"must be 'line' or 'heatmap'; found {kind!r}")
    columns = _columns_of(design)
    axis_names = list(axes)
    x = fr.get("x", axis_names[0])
    if x not in axes:
        raise _err(source, f"{pre}.x", f"must be an axis of the grid ({', '.join(axis_names)}); found {x!r}")
    for k in ("logx", "logy"):
        if not isinstance(fr.get(k, False), bool):
            raise _err(source, f"{pre}.{k}", f"must be true or false; found {fr[k]!r}")
    title = fr.get("title", "")
    if not isinstance(title, str):
        raise _err(source, f"{pre}.title", f"must be a string; found {title!r}")
    if kind == "heatmap":
        y = fr.get("y")
        if y not in axes or y == x:
            raise _err(source, f"{pre}.y", f"a heatmap needs y = another axis of the grid "
                                           f"({', '.join(a for a in axis_names if a != x)}); found {y!r}")
        value = fr.get("value", "kappa2")
        if value not in columns:
            raise _err(source, f"{pre}.value", f"must be a result column ({', '.join(columns)}); found "
                                               f"{value!r}")
        others = [a for a in axis_names if a not in (x, y) and len(axes[a]) > 1]
        if others:
            raise _err(source, pre, f"a heatmap shows two axes; {others[0]!r} also varies")
        if fr.get("series") is not None:
            raise _err(source, f"{pre}.series", "not used by a heatmap")
        file = fr.get("file", f"{name}_{value}_{x}_{y}.png")
        ys: tuple[str, ...] = (y,)
        series = None
    else:
        y = fr.get("y", "kappa2")
        ys = tuple([y] if isinstance(y, str) else y) if isinstance(y, (str, list)) else ()
        if not ys:
            raise _err(source, f"{pre}.y", "must be a result column or a list of them "
                                           f"({', '.join(columns)})")
        for c in ys:
            if c not in columns:
                raise _err(source, f"{pre}.y", f"{c!r} is not a result column of design {design!r}; "
                                               f"expected one of {', '.join(columns)}")
        series = fr.get("series")
        if series is not None and (series not in axes or series == x):
            raise _err(source, f"{pre}.series", f"must be another axis of the grid; found {series!r}")
        others = [a for a in axis_names if a not in (x, series) and len(axes[a]) > 1]
        if others:
            raise _err(source, f"{pre}.series" if series is None else pre,
                       f"axis {others[0]!r} also varies: give it as series (or fix it) so that each curve "
                       f"is a function of {x!r}")
        value = None
        file = fr.get("file", f"{name}_{'_'.join(ys)}.png")
    try:
        file = file_name("file", file)
    except OutputPathError:
        file = None
    if file is None or not file.lower().endswith((".png", ".pdf", ".svg")):
        raise _err(source, f"{pre}.file", f"must be a file name ending in .png, .pdf or .svg (no slashes "
                                          f"or control characters); found {shown(fr.get('file', file))}")
    return FigureSpec(kind=kind, x=x, y=ys, series=series, value=value, logx=fr.get("logx", False),
                      logy=fr.get("logy", False), file=file, title=title)


# --------------------------------------------------------------------------- running


def _dask_client(spec: StudySpec, workers: int | None):
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        raise BackendUnavailableError("executor 'dask' needs dask.distributed: pip install "
                                      "'optdesign-control[dask]'") from None
    if spec.scheduler:
        return Client(spec.scheduler, timeout=60), None
    import logging

    cluster = LocalCluster(n_workers=workers or 2, threads_per_worker=1, dashboard_address=":0",
                           silence_logs=logging.ERROR)
    return Client(cluster, timeout=60), cluster


def require_matplotlib(what: str = "figures") -> None:
    """Raise :class:`~optdesign.errors.BackendUnavailableError` now if matplotlib is missing (before
    any work whose figures could not be drawn).

    Raises
    ------
    BackendUnavailableError
        matplotlib cannot be imported; the message says what to install (or how to skip figures).
    """
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        raise BackendUnavailableError(f"{what} need matplotlib, which is not installed: pip install "
                                      "'optdesign-control[plot]' (or skip the figures: optdesign study "
                                      "--no-figures, run_spec(..., figures=False))") from None


def run_spec(spec: StudySpec | str | Path, *, executor: str | None = None, workers: int | None = None,
             progress: bool | None = None, output: str | Path | None = None,
             figures: bool = True, overwrite: bool = False, allow_outside: bool = False) -> StudyOutput:
    """Run a study: sweep, CSV + JSON, figure(s).

    Parameters
    ----------
    spec : StudySpec, or path of a TOML spec
    executor : {"processes", "threads", "serial", "dask"}, optional
        Overrides the spec's.
    workers : int, optional
        Overrides the spec's.
    progress : bool or None
        Progress on stderr, one step per point (:func:`~optdesign.studies.sweep`): ``None``
        (default) only on a terminal, ``True`` always, ``False`` never.
    output : path, optional
        Overrides the spec's output folder (relative to the current directory; may lie outside it).
    figures : bool, default True
        Draw the spec's figures.  When there are figures to draw, matplotlib is required *before*
        the sweep runs (:func:`require_matplotlib`), so that a long sweep does not end in an
        import error.
    overwrite : bool, default False
        Replace existing result files, or symbolic links in their place (the link, never its
        target); without it an existing one is an error, raised before the sweep starts.
    allow_outside : bool, default False
        Accept a spec whose output folder (``study.output``) lies outside the current directory.

    Returns
    -------
    StudyOutput

    Raises
    ------
    SpecError
        The spec file is bad (``spec`` given as a path).
    ValidationError
        A bad ``executor``, ``workers``, ``progress`` or flag.
    OutputPathError
        The spec's output folder outside the current directory (``allow_outside`` False), or not
        writable.
    OutputExistsError
        A result file exists and ``overwrite`` is False (checked before the sweep).
    BackendUnavailableError
        Figures requested and matplotlib missing; executor ``"dask"`` without dask.distributed.
    """
    if not isinstance(spec, StudySpec):
        spec = load_spec(spec)
    exe = executor or spec.executor
    if exe not in _EXECUTORS:
        raise ValidationError(f"executor must be one of {', '.join(_EXECUTORS)}; found {exe!r}")
    for flag, value in (("figures", figures), ("overwrite", overwrite), ("allow_outside", allow_outside)):
        if not isinstance(value, bool):
            raise ValidationError(f"{flag} must be True or False; found {shown(value)}")
    if figures and spec.figures:
        require_matplotlib(f"the figures of {spec.source}")
    w = workers or spec.workers
    if output is not None:
        out = output_folder(output, allow_outside=True, field="output")
    else:
        out = output_folder(spec.output, allow_outside=allow_outside, field=f"{spec.source}: study.output")
    csv_path, json_path = out / f"{spec.name}.csv", out / f"{spec.name}.json"
    drawn = spec.figures if figures else ()
    check_targets([csv_path, json_path, *(out / fig.file for fig in drawn)], overwrite=overwrite)
    client = cluster = None
    try:
        if exe == "dask":
            client, cluster = _dask_client(spec, w)
            target: Any = client
        else:
            target = exe
        table = sweep(spec.designer, list(spec.points), executor=target, progress=progress,
                      chunksize=spec.chunksize, timeout=spec.timeout, workers=w if exe != "dask" else None)
    finally:
        if client is not None:
            client.close()
        if cluster is not None:
            cluster.close()
    table.meta.update({"problem": spec.problem, "design": spec.design, "spec": spec.source})
    table.to_csv(csv_path, overwrite=overwrite)
    table.to_json(json_path, overwrite=overwrite)
    title = spec.title or f"{spec.problem}: {spec.design}"
    figs = []
    for fig in drawn:  # drawn into a temporary file, renamed (optdesign._files)
        figs.append(plot_table(table, fig, out / fig.file, title=title, overwrite=overwrite))
    return StudyOutput(spec=spec, table=table, csv=csv_path, json=json_path, figures=tuple(figs))
