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
    output = "alpha_sector_results" # folder, relative to the current directory (default
                                    # "<name>_results"; `optdesign study --out DIR` overrides it)
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
failed.  The output folder is relative to the *current directory* (never to the spec file: running
an example spec does not write into the source tree).

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
from ..errors import BackendUnavailableError, OptDesignError, ValidationError
from ..model.regions import Disk, Ellipse, HalfPlane, HorizontalStrip, Region, Sector, VerticalStrip
from ..plot.studies import LABELS, SYMBOLS, plot_table  # the figures live in optdesign.plot
from .designers import DESIGNERS
from .sweep import SweepTable, grid, sweep

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


# --------------------------------------------------------------------------- region / pole syntax

#: shape -> (number of parameters accepted, constructor, help)
REGION_SHAPES: dict[str, tuple[tuple[int, ...], Any, str]] = {
    "halfplane": ((1,), lambda a: HalfPlane(a[0]), "halfplane:ALPHA  (Re s <= -ALPHA)"),
    "sector": ((1,), lambda a: Sector.from_damping(a[0]), "sector:ZETA  (damping ratio >= ZETA, 0 < ZETA < "
                                                          "1)"),
    "disk": ((1, 2), lambda a: Disk(0.0, a[0]) if len(a) == 1 else Disk(a[0], a[1]),
             "disk:RADIUS or disk:CENTER,RADIUS"),
    "strip": ((2,), lambda a: VerticalStrip(a[0], a[1]), "strip:LO,HI  (LO <= Re s <= HI)"),
    "hstrip": ((1,), lambda a: HorizontalStrip(a[0]), "hstrip:OMEGA  (|Im s| <= OMEGA)"),
    "ellipse": ((3,), lambda a: Ellipse(a[0], a[1], a[2]), "ellipse:CENTER,A,B"),
    "stable": ((0,), lambda a: HalfPlane(0.0), "stable  (Re s <= 0)"),
}


def parse_region(text: str, *, field: str = "region") -> Region:
    """Parse ``"halfplane:1.5 & sector:0.7 & disk:20"`` into a :class:`~optdesign.regions.Region`.

    Raises
    ------
    ValidationError
        One line starting with ``field``: unknown shape, wrong number of numbers, a value that is
        not a number, an invalid parameter (e.g. ``sector:1.2``) or an empty intersection.
    """
    if not isinstance(text, str) or not text.strip():
        raise ValidationError(f"{field}: expected a region such as 'halfplane:1 & sector:0.7'; found "
                              f"{text!r}")
    members: list[Region] = []
    for term in text.split("&"):
        term = term.strip()
        if not term:
            raise ValidationError(f"{field}: empty member in {text!r} (members are joined by '&')")
        shape, _, args = term.partition(":")
        shape = shape.strip().lower()
        if shape not in REGION_SHAPES:
            raise ValidationError(f"{field}: unknown shape {shape!r} in {term!r}; expected one of "
                                  f"{', '.join(REGION_SHAPES)}")
        counts, make, usage = REGION_SHAPES[shape]
        parts = [a.strip() for a in args.split(",")] if args.strip() else []
        if len(parts) not in counts:
            raise ValidationError(f"{field}: {term!r} has {len(parts)} number(s); usage: {usage}")
        nums = []
        for a in parts:
            try:
                v = float(a)
            except ValueError:
                raise ValidationError(f"{field}: {a!r} in {term!r} is not a number; usage: {usage}") from None
            if not math.isfinite(v):
                raise ValidationError(f"{field}: {a!r} in {term!r} is not finite; usage: {usage}")
            nums.append(v)
        try:
            members.append(make(nums))
        except OptDesignError as exc:
            raise ValidationError(f"{field}: {term!r}: {exc}") from None
    region = members[0]
    try:
        for m in members[1:]:
            region = region & m
    except OptDesignError as exc:
        raise ValidationError(f"{field}: {' '.join(str(exc).split())}") from None
    return region


def _member_text(m: Region) -> tuple[str, str]:
    """(``--region`` syntax, meaning) of one region shape."""
    if isinstance(m, HalfPlane):
        if m.alpha == 0:
            return "stable", "Re s <= 0"
        return f"halfplane:{m.alpha:.6g}", f"Re s <= {-m.alpha:.6g}"
    if isinstance(m, Sector):
        deg = math.degrees(m.half_angle)
        if m.apex == 0:
            return (f"sector:{m.damping:.6g}",
                    f"damping ratio >= {m.damping:.6g} (a sector of half-angle {deg:.4g} deg)")
        return (f"Sector(half_angle={m.half_angle:.6g}, apex={m.apex:.6g})",
                f"|Im s| <= tan({deg:.4g} deg) ({m.apex:.6g} - Re s)")
    if isinstance(m, Disk):
        if m.center == 0:
            return f"disk:{m.radius:.6g}", f"|s| <= {m.radius:.6g}"
        return f"disk:{m.center:.6g},{m.radius:.6g}", f"|s - ({m.center:.6g})| <= {m.radius:.6g}"
    if isinstance(m, VerticalStrip):
        return f"strip:{m.lo:.6g},{m.hi:.6g}", f"{m.lo:.6g} <= Re s <= {m.hi:.6g}"
    if isinstance(m, HorizontalStrip):
        return f"hstrip:{m.omega:.6g}", f"|Im s| <= {m.omega:.6g}"
    if isinstance(m, Ellipse):
        return (f"ellipse:{m.center:.6g},{m.a:.6g},{m.b:.6g}",
                f"((Re s - ({m.center:.6g}))/{m.a:.6g})^2 + (Im s/{m.b:.6g})^2 <= 1")
    return repr(m), ""


def format_region(region: Region, *, meaning: bool = True) -> str:
    """A region in the syntax of :func:`parse_region` (its inverse), with what each member means.

    Examples
    --------
    >>> format_region(HalfPlane(1.0) & Disk(0.0, 20.0))
    'halfplane:1 & disk:20  (Re s <= -1; |s| <= 20)'
    >>> format_region(Sector.from_damping(0.7), meaning=False)
    'sector:0.7'
    """
    members = region.members if hasattr(region, "members") else (region,)
    parts = [_member_text(m) for m in members]
    text = " & ".join(p[0] for p in parts)
    glosses = [p[1] for p in parts if p[1]]
    return f"{text}  ({'; '.join(glosses)})" if meaning and glosses else text


def parse_poles(value: Any, *, field: str = "poles") -> np.ndarray:
    """Poles from ``"-1, -2, -3+1j, -3-1j"`` or a list of numbers / strings (complex vector).

    Raises
    ------
    ValidationError
        ``field`` named: an entry that is not a number, no entries.
    """
    items = [p.strip() for p in value.replace(";", ",").split(",")] if isinstance(value, str) else value
    if not isinstance(items, (list, tuple)) or not items:
        raise ValidationError(f"{field}: expected poles such as '-1, -2, -3+1j, -3-1j'; found {value!r}")
    out = []
    for s in items:
        try:
            z = complex(s.replace(" ", "").replace("i", "j")) if isinstance(s, str) else complex(s)
        except (ValueError, TypeError):
            raise ValidationError(f"{field}: {s!r} is not a number (write complex poles as -3+1j)") from None
        if not (math.isfinite(z.real) and math.isfinite(z.imag)):
            raise ValidationError(f"{field}: {s!r} is not finite")
        out.append(z)
    return np.asarray(out, dtype=complex)


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
    except (OSError, UnicodeDecodeError) as exc:
        raise SpecError(f"{path}: cannot read the spec file: {exc}") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SpecError(f"{path.name}: invalid TOML: {' '.join(str(exc).split())}") from None
    return parse_spec(data, source=path.name, base=path.parent, default_name=path.stem)


def _err(source: str, fieldname: str, msg: str) -> SpecError:
    return SpecError(f"{source}: {fieldname}: {msg}")


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(float(v))


def _axis_values(source: str, name: str, v: Any) -> list[Any]:
    f = f"grid.{name}"
    if isinstance(v, list):
        if not v:
            raise _err(source, f, "empty list of values")
        for x in v:
            if not (_is_number(x) or isinstance(x, str)):
                raise _err(source, f, f"values must be numbers; found {x!r}")
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
                raise _err(source, f"{f}.{k}", f"must be a finite number; found {v[k]!r}")
        num = v["num"]
        if isinstance(num, bool) or not isinstance(num, int) or num < 1:
            raise _err(source, f"{f}.num", f"must be an integer >= 1; found {num!r}")
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
    raise _err(source, f, f"expected a list of values or {{start, stop, num}}; found {v!r}")


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
    if not isinstance(name, str) or not name.strip() or any(c in name for c in "/\\"):
        raise _err(source, "study.name", f"must be a non-empty name without slashes; found {name!r}")
    problem = study.get("problem")
    if not isinstance(problem, str):
        raise _err(source, "study.problem", "missing or not a string (a problem name, see `optdesign list`, "
                                            f"or a problem file); found {problem!r}")
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
    if not isinstance(output, str) or not output.strip():
        raise _err(source, "study.output", f"must be a folder name; found {output!r}")
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
    if not isinstance(file, str) or not file.lower().endswith((".png", ".pdf", ".svg")) or "/" in file:
        raise _err(source, f"{pre}.file", f"must be a file name ending in .png, .pdf or .svg; found {file!r}")
    return FigureSpec(kind=kind, x=x, y=ys, series=series, value=value, logx=fr.get("logx", False),
                      logy=fr.get("logy", False), file=file, title=title)


# --------------------------------------------------------------------------- running


def _dask_client(spec: StudySpec, workers: int | None):
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        raise BackendUnavailableError("executor 'dask' needs dask.distributed: pip install "
                                      "'optdesign[dask]'") from None
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
                                      "'optdesign[plot]' (or skip the figures: optdesign study "
                                      "--no-figures, run_spec(..., figures=False))") from None


def run_spec(spec: StudySpec | str | Path, *, executor: str | None = None, workers: int | None = None,
             progress: bool | None = None, output: str | Path | None = None,
             figures: bool = True) -> StudyOutput:
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
        Overrides the spec's output folder (relative to the current directory).
    figures : bool, default True
        Draw the spec's figures.  When there are figures to draw, matplotlib is required *before*
        the sweep runs (:func:`require_matplotlib`), so that a long sweep does not end in an
        import error.

    Returns
    -------
    StudyOutput

    Raises
    ------
    SpecError
        The spec file is bad (``spec`` given as a path).
    ValidationError
        A bad ``executor``, ``workers``, ``progress`` or ``figures``.
    BackendUnavailableError
        Figures requested and matplotlib missing; executor ``"dask"`` without dask.distributed.
    """
    if not isinstance(spec, StudySpec):
        spec = load_spec(spec)
    exe = executor or spec.executor
    if exe not in _EXECUTORS:
        raise ValidationError(f"executor must be one of {', '.join(_EXECUTORS)}; found {exe!r}")
    if not isinstance(figures, bool):
        raise ValidationError(f"figures must be True or False; found {figures!r}")
    if figures and spec.figures:
        require_matplotlib(f"the figures of {spec.source}")
    w = workers or spec.workers
    out = Path(output) if output is not None else spec.output
    out.mkdir(parents=True, exist_ok=True)
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
    csv_path = table.to_csv(out / f"{spec.name}.csv")
    json_path = out / f"{spec.name}.json"
    table.to_json(json_path)
    title = spec.title or f"{spec.problem}: {spec.design}"
    figs = tuple(plot_table(table, fig, out / fig.file, title=title)
                 for fig in (spec.figures if figures else ()))
    return StudyOutput(spec=spec, table=table, csv=csv_path, json=json_path, figures=figs)
