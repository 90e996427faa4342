"""The problem library: named design problems stored as data files, with citations and
reference values.

Files live in the top-level ``problems/`` folder of the source tree, installed as package
data (``optdesign._problem_data``), one JSON file per problem, grouped in sub-folders
(``seeds/``, ``carex/``, ``darex/``, ``compleib/``, ``poleplacement/``, ``kf/``).

File schema (JSON)::

    {
      "name": "chang_lee_1984_ex1",         # unique, lower case; equals the file stem
      "title": "...", "kind": "inverse_kalman", "tags": ["seed000", ...],
      "citation": "...",                    # the paper / benchmark collection
      "source": "...",                      # where the numbers were taken from
      "notes": "...",                       # known errors of the printed values, conventions
      "plant": {"A": [[..]], "C": [[..]], "G": .., "Q": .., "R": .., "dt": null, "B": ..},
      "targets": {...},                     # what to design for (poles, region, beta, ...)
      "references": {...},                  # expected results (printed or analytic)
      "data": {...}                         # any further raw matrices
    }

Matrices are nested lists; complex arrays are ``{"re": [...], "im": [...]}``.  ``plant`` may be
``null`` when the data cannot form a valid :class:`~optdesign.Plant` (e.g. singular R);
``notes`` then says why.

A user's own problem
--------------------
:func:`load` also takes the path of a problem file (:func:`load_file`), and so does every place
that takes a problem name (``optdesign design ./mine.json --method kalman``, ``optdesign kalman
mine.npz``, a study spec's ``problem = "mine.toml"``).  Formats, chosen by the suffix:

* ``.json`` / ``.toml``: the schema above, or the minimal form with the plant's fields at the top
  level -- ``{"A": [[0, 1], [-2, -3]], "C": [[1, 0]], "Q": [[1, 0], [0, 1]], "R": [[1]]}``, optional
  ``G``, ``B``, ``dt`` (absent, ``null`` or ``0``: continuous time), ``name``, ``title``, ``notes``
  and ``poles`` (target poles: numbers, strings such as ``"-1+2j"``, or ``{"re": [...], "im":
  [...]}``);
* ``.npz`` (``numpy.savez``): arrays with those names, read with ``allow_pickle=False``;
* ``.mat`` (MATLAB ``save mine.mat A C Q R``, formats up to v7; v7.3/HDF5 is refused): variables
  with those names, read by :func:`scipy.io.loadmat`.

Files are read safely: no pickle, no ``eval``; the file size (at most :data:`MAX_FILE_BYTES`) and
every matrix's shape (no dimension above :data:`MAX_DIMENSION`) are checked before any matrix is
built, then every matrix's type, shape, finiteness, symmetry and definiteness.  Nothing is
expanded before its size is known: the nesting of JSON/TOML (at most :data:`MAX_NESTING`
levels), the declared shape and type of every ``.npz`` member (its ``.npy`` header) and of every
``.mat`` variable (:func:`scipy.io.whosmat`), and the expanded size of every compressed member
(counted by streaming, nothing kept) must stay within :data:`MAX_ARRAY_BYTES` per array and
:data:`MAX_EXPANDED_BYTES` in all; an unknown member is refused before anything is read.  Every mistake
raises :class:`ProblemFileError` naming the file and the field, e.g. ``mine.json: plant.R: R must
be positive definite ...``; an unknown field is refused (a typo would otherwise be ignored).
"""

from __future__ import annotations

import json
import os
import sys
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import cache, lru_cache
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from ._array_files import Limits, check_size, file_error, read_mat, read_npz
from ._validate import as_matrix, as_poles, as_positive_float, as_square, as_str
from .errors import ProblemFileError, ProblemNotFoundError, ValidationError
from .model.plant import Plant

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

__all__ = ["Problem", "ProblemFileError", "names", "load", "load_file", "load_all", "describe",
           "is_problem_file", "FILE_SUFFIXES", "MAX_DIMENSION", "MAX_FILE_BYTES", "MAX_ARRAY_BYTES",
           "MAX_EXPANDED_BYTES", "MAX_NESTING"]

#: suffixes of the problem files :func:`load` accepts instead of a library name
FILE_SUFFIXES = (".json", ".toml", ".npz", ".mat")
#: the largest dimension (states, outputs, noise or control inputs) a problem file may have
MAX_DIMENSION = 2000
#: the largest problem file read (bytes)
MAX_FILE_BYTES = 256 * 2**20
#: the largest array a problem file may declare (bytes, once expanded): a complex
#: ``MAX_DIMENSION x MAX_DIMENSION`` matrix (64 MiB)
MAX_ARRAY_BYTES = 16 * MAX_DIMENSION**2
#: the most a problem file may expand to, all its arrays (or compressed members) together (bytes)
MAX_EXPANDED_BYTES = MAX_FILE_BYTES
#: the deepest nesting of lists / tables a JSON or TOML problem file may have (a matrix of the
#: library schema sits 4 deep: ``{"plant": {"A": [[...]]}}``)
MAX_NESTING = 32

_PLANT_KEYS = ("A", "C", "G", "Q", "R", "dt", "B", "name")


@dataclass(frozen=True, eq=False)
class Problem:
    """One named design problem.

    Attributes
    ----------
    name, title, kind : str
        ``kind`` says what the problem is for (``"kalman"``, ``"inverse_kalman"``,
        ``"observer"``, ``"riccati_care"``, ``"riccati_dare"``, ``"pole_placement"``,
        ``"riccati_de"``, ``"generalized_observer"``, ``"output_delay"``, ...).
    plant : Plant or None
    targets, references, data : dict
        Decoded values: lists of numbers become ndarrays, ``{"re", "im"}`` complex ndarrays.
    citation, source, notes : str
    tags : tuple of str
    path : str
        The file it was read from (relative to the library for a library problem).
    origin : str
        ``"library"`` or ``"file"`` (a user's problem file, :func:`load_file`).
    """

    name: str
    title: str
    kind: str
    plant: Plant | None
    targets: dict[str, Any] = field(default_factory=dict)
    references: dict[str, Any] = field(default_factory=dict)
    data: dict[str, Any] = field(default_factory=dict)
    citation: str = ""
    source: str = ""
    notes: str = ""
    tags: tuple[str, ...] = ()
    path: str = ""
    origin: str = "library"

    def __repr__(self) -> str:
        return f"Problem({self.name!r}, kind={self.kind!r}, plant={self.plant!r})"


def _root():
    try:
        return resources.files("optdesign._problem_data")
    except ModuleNotFoundError:  # running from a source tree that was not pip-installed
        return _source_root()


def _decode(value: Any) -> Any:
    """JSON value -> numpy where it is numeric data."""
    if isinstance(value, dict):
        if set(value) == {"re", "im"}:
            return np.asarray(value["re"], dtype=float) + 1j * np.asarray(value["im"], dtype=float)
        return {k: _decode(v) for k, v in value.items()}
    if isinstance(value, list) and value and _is_numeric_nest(value):
        return np.asarray(value, dtype=float)
    if isinstance(value, list):
        return [_decode(v) for v in value]
    return value


def _is_numeric_nest(value: Any) -> bool:
    if isinstance(value, list):
        return all(_is_numeric_nest(v) for v in value) and len(value) > 0
    return isinstance(value, (int, float)) and not isinstance(value, bool)


@lru_cache(maxsize=1)
def _index() -> dict[str, str]:
    """name -> relative path of every problem file."""
    out: dict[str, str] = {}

    def walk(node, prefix: str) -> None:
        for child in sorted(node.iterdir(), key=lambda c: c.name):
            if child.is_dir():
                if not child.name.startswith(("_", ".")):
                    walk(child, f"{prefix}{child.name}/")
            elif child.name.endswith(".json"):
                stem = child.name[: -len(".json")]
                if stem in out:
                    raise ValidationError(
                        f"duplicate problem name {stem!r}: {out[stem]} and {prefix}{child.name}")
                out[stem] = f"{prefix}{child.name}"

    walk(_root(), "")
    return out


def names(tag: str | None = None, kind: str | None = None) -> list[str]:
    """Names of the problems in the library, optionally filtered.

    Parameters
    ----------
    tag : str, optional
        Keep problems carrying this tag (e.g. ``"seed000"``, ``"benchmark"``) *or* whose
        name starts with it (e.g. ``"carex"``).
    kind : str, optional
        Keep problems of this kind (e.g. ``"riccati_care"``, ``"pole_placement"``).

    Raises
    ------
    ValidationError
        ``tag`` or ``kind`` is given but is not a string.

    Examples
    --------
    >>> from optdesign import problems
    >>> "chang_lee_1984_ex1" in problems.names(), len(problems.names()) > 20
    (True, True)
    """
    tag = None if tag is None else as_str("tag", tag)
    kind = None if kind is None else as_str("kind", kind)
    all_names = sorted(_index())
    if tag is None and kind is None:
        return all_names
    out = []
    for n in all_names:
        raw = _raw(n)
        if tag is not None and tag not in raw.get("tags", []) and not n.startswith(tag):
            continue
        if kind is not None and raw.get("kind") != kind:
            continue
        out.append(n)
    return out


@cache
def _raw(name: str) -> dict[str, Any]:
    idx = _index()
    if name not in idx:
        close = [n for n in idx if name.lower() in n.lower()][:8]
        hint = f"; did you mean {', '.join(close)}?" if close else "; `optdesign list` shows them all"
        raise ProblemNotFoundError(f"no problem named {name!r} in the library{hint}")
    node = _root()
    for part in idx[name].split("/"):
        node = node / part
    return json.loads(node.read_text(encoding="utf-8"))


def is_problem_file(name: Any) -> bool:
    """Whether ``name`` is meant as a file rather than a library name: a path object, or a string
    that ends in one of :data:`FILE_SUFFIXES` or contains a path separator (library names such
    as ``carex_1.1`` contain neither)."""
    if isinstance(name, os.PathLike):
        return True
    if not isinstance(name, str):
        return False
    return name.lower().endswith(FILE_SUFFIXES) or "/" in name or os.sep in name


def load(name: str | os.PathLike) -> Problem:
    """Load a problem by name, or from a user's problem file.

    Parameters
    ----------
    name : str or path
        A name from :func:`names` (the file stem), or the path of a problem file
        (:func:`is_problem_file`; read by :func:`load_file`).

    Returns
    -------
    Problem

    Raises
    ------
    ProblemNotFoundError
        No such problem (the message suggests close names).
    ProblemFileError
        A problem file that is missing, unreadable or has a bad field (the message names the file
        and the field).
    ValidationError
        ``name`` is not a string or a path.

    Examples
    --------
    >>> from optdesign import problems
    >>> ex1 = problems.load("chang_lee_1984_ex1")
    >>> ex1.plant.A.tolist(), ex1.targets["poles"].tolist()
    ([[0.0, 1.0], [-6.0, -5.0]], [-5.0, -8.0])
    """
    if is_problem_file(name):
        return load_file(name)
    name = as_str("name", name)
    if name not in _index() and Path(name).is_file():  # a file of a kind we do not read
        return load_file(name)
    raw = _raw(name)
    plant_raw = raw.get("plant")
    plant = None
    if plant_raw is not None:
        kw = {k: plant_raw[k] for k in _PLANT_KEYS if plant_raw.get(k) is not None}
        kw.setdefault("name", raw.get("name", name))
        plant = Plant(**kw)
    return Problem(
        name=raw.get("name", name),
        title=raw.get("title", ""),
        kind=raw.get("kind", ""),
        plant=plant,
        targets=_decode(raw.get("targets", {})),
        references=_decode(raw.get("references", {})),
        data=_decode(raw.get("data", {})),
        citation=raw.get("citation", ""),
        source=raw.get("source", ""),
        notes=raw.get("notes", ""),
        tags=tuple(raw.get("tags", ())),
        path=_index()[name],
    )


def load_all(tag: str | None = None, kind: str | None = None) -> list[Problem]:
    """Every problem (optionally filtered), loaded."""
    return [load(n) for n in names(tag=tag, kind=kind)]


def _show(value: Any, indent: str) -> str:
    """A value for :func:`describe`: arrays as numbers (no ``array(...)``), nested dicts one key a
    line."""
    if isinstance(value, Mapping):
        return "".join(f"\n{indent}{k}:{'' if isinstance(v, Mapping) else ' '}{_show(v, indent + '  ')}"
                       for k, v in value.items())
    if isinstance(value, (list, tuple)) and any(isinstance(v, (Mapping, np.ndarray)) for v in value):
        return "".join(f"\n{indent}- {_show(v, indent + '  ')}" for v in value)
    if isinstance(value, np.ndarray):
        if np.iscomplexobj(value) and not np.any(value.imag):
            value = value.real
        with np.printoptions(precision=6, suppress=True, linewidth=100):
            return str(value).replace("\n", "\n" + indent)
    return str(value)


def describe(name: str | os.PathLike) -> str:
    """A few lines describing a problem (used by ``optdesign show``).

    Examples
    --------
    >>> from optdesign import problems
    >>> print(problems.describe("chang_lee_1984_ex1").splitlines()[0])      # doctest: +ELLIPSIS
    chang_lee_1984_ex1...
    """
    p = load(name)
    lines = [f"{p.name}: {p.title}", f"  kind: {p.kind}"]
    if p.citation:
        lines.append(f"  citation: {p.citation}")
    if p.source:
        lines.append(f"  source: {p.source}")
    if p.plant is not None:
        lines.append(f"  plant: {p.plant!r}")
        with np.printoptions(precision=6, suppress=True, linewidth=100):
            for k in ("A", "C", "G", "Q", "R"):
                v = getattr(p.plant, k)
                if v is not None:
                    body = str(v).replace("\n", "\n      ")
                    lines.append(f"    {k} = {body}")
    for label, d in (("targets", p.targets), ("references", p.references)):
        if d:
            lines.append(f"  {label}:")
            for k, v in d.items():
                sep = ":" if isinstance(v, Mapping) else " = "
                lines.append(f"    {k}{sep}{_show(v, '      ')}")
    if p.notes:
        lines.append(f"  notes: {p.notes}")
    lines.append(f"  file: problems/{p.path}" if p.origin == "library" else f"  file: {p.path}")
    return "\n".join(lines)


# --------------------------------------------------------------------------- a user's problem file


#: the plant's matrices in a problem file, and the other fields of the minimal form
_MATRIX_KEYS = ("A", "C", "G", "Q", "R", "B")
_MINIMAL_KEYS = (*_MATRIX_KEYS, "dt", "name", "title", "notes", "poles")
_SCHEMA_KEYS = ("name", "title", "kind", "tags", "citation", "source", "notes", "plant", "targets",
                "references", "data")


_file_error = file_error


def _limits() -> Limits:
    """The limits of a binary problem file, read from this module when a file is read (so that a
    caller may change them: ``optdesign.problems.MAX_ARRAY_BYTES = ...``)."""
    return Limits(dimension=MAX_DIMENSION, array_bytes=MAX_ARRAY_BYTES, expanded_bytes=MAX_EXPANDED_BYTES,
                  fields=_MINIMAL_KEYS, matrices=_MATRIX_KEYS)


def _nested_shape(value: Any) -> tuple[int, ...]:
    """The shape of a nested list along its first elements (no array is built)."""
    shape = []
    while isinstance(value, (list, tuple)):
        shape.append(len(value))
        if not value:
            break
        value = value[0]
    return tuple(shape)


def _check_size(src: str, fieldname: str, shape: tuple[int, ...]) -> None:
    check_size(src, fieldname, shape, MAX_DIMENSION)


def _nesting_depth(value: Any, limit: int) -> int:
    """How deeply lists and tables nest in ``value`` (``[[1]]``: 2), counted without recursion; the
    count stops at the first level beyond ``limit``."""
    deepest = 0
    stack = [(value, 1)] if isinstance(value, (list, Mapping)) else []
    while stack:
        v, d = stack.pop()
        deepest = max(deepest, d)
        if d > limit:
            break
        children = v.values() if isinstance(v, Mapping) else v
        stack.extend((c, d + 1) for c in children if isinstance(c, (list, Mapping)))
    return deepest


def _read_text_mapping(path: Path, src: str) -> dict[str, Any]:
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise _file_error(src, None, f"not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    too_deep = (f"nested more than {MAX_NESTING} levels deep (lists / tables; "
                "optdesign.problems.MAX_NESTING)")
    try:
        data = json.loads(text) if path.suffix.lower() == ".json" else tomllib.loads(text)
    except json.JSONDecodeError as exc:
        raise _file_error(src, None, f"invalid JSON: {exc.msg} at line {exc.lineno} column {exc.colno}") \
            from None
    except tomllib.TOMLDecodeError as exc:
        raise _file_error(src, None, f"invalid TOML: {exc}") from None
    except RecursionError:
        raise _file_error(src, None, too_deep) from None
    except ValueError as exc:  # Python's limit on the digits of an integer (4300 by default)
        limit = getattr(sys, "get_int_max_str_digits", lambda: 4300)()
        reason = (f"an integer of more than {limit} digits (Python's limit for reading integers)"
                  if "digits" in str(exc) else " ".join(str(exc).split()))
        raise _file_error(src, None, f"a number that cannot be read: {reason}") from None
    if not isinstance(data, dict):
        raise _file_error(src, None, f"expected an object with the plant's matrices (A, C, ...); found "
                                     f"{type(data).__name__}")
    if _nesting_depth(data, MAX_NESTING) > MAX_NESTING:
        raise _file_error(src, None, too_deep)
    for key in ("plant", None):
        block = data.get(key) if key else data
        if isinstance(block, Mapping):
            for k in _MATRIX_KEYS:
                if k in block:
                    _check_size(src, f"plant.{k}" if key else k, _nested_shape(block[k]))
    return data


def _text(src: str, fieldname: str, value: Any) -> str:
    if isinstance(value, np.ndarray) and value.dtype.kind == "U" and value.size == 1:
        value = str(value.ravel()[0])
    if not isinstance(value, str):
        raise _file_error(src, fieldname, f"must be a string; found {type(value).__name__}")
    return value


def _dt(src: str, fieldname: str, value: Any) -> float | None:
    """``dt``: absent, null or 0 (MATLAB's ``Ts = 0``) -> continuous time."""
    if isinstance(value, np.ndarray) and value.size == 1 and value.dtype.kind in "iuf":
        value = value.ravel()[0].item()
    if value is None or (isinstance(value, (int, float)) and not isinstance(value, bool) and value == 0):
        return None
    try:
        return as_positive_float("dt", value)
    except ValidationError as exc:
        raise _file_error(src, fieldname, f"{exc} (0 or absent: continuous time)") from None


def _poles(src: str, fieldname: str, value: Any, n: int) -> np.ndarray:
    if isinstance(value, Mapping) and set(value) == {"re", "im"}:
        try:
            value = np.asarray(value["re"], dtype=float) + 1j * np.asarray(value["im"], dtype=float)
        except (TypeError, ValueError):
            raise _file_error(src, fieldname, "re and im must be lists of numbers") from None
    elif isinstance(value, (list, tuple)):
        items = []
        for v in value:
            if isinstance(v, str):
                try:
                    v = complex(v.replace(" ", "").replace("i", "j"))
                except ValueError:
                    raise _file_error(src, fieldname, f"{v!r} is not a number (write complex poles as "
                                                      f"'-3+1j')") from None
            items.append(v)
        value = items
    if not isinstance(value, (str, list)) and np.ndim(value) == 2 and 1 in np.shape(value):
        value = np.ravel(value)  # a MATLAB vector (.mat files have no 1-D arrays): a row or a column
    try:
        return as_poles("poles", value, n)
    except ValidationError as exc:
        raise _file_error(src, fieldname, str(exc)) from None


def _plant_from(src: str, block: Mapping[str, Any], prefix: str, default_name: str) -> Plant:
    """The plant of a file's matrices, every field checked with its name."""
    missing = [k for k in ("A", "C") if k not in block]
    if missing:
        raise _file_error(src, f"{prefix}{missing[0]}", "missing (a plant needs at least A and C)")
    kw: dict[str, Any] = {}
    for k in _MATRIX_KEYS:
        v = block.get(k)
        if v is None:
            continue
        try:
            kw[k] = as_square(k, v) if k in ("A", "Q", "R") else as_matrix(k, v)
        except ValidationError as exc:
            raise _file_error(src, f"{prefix}{k}", str(exc)) from None
    kw["dt"] = _dt(src, f"{prefix}dt", block.get("dt"))
    name = block.get("name", default_name)
    kw["name"] = _text(src, f"{prefix}name", name)
    try:
        return Plant(**kw)
    except ValidationError as exc:
        msg = " ".join(str(exc).split())
        culprit = next((k for k in (*_MATRIX_KEYS, "dt") if msg.startswith(k + " ")), None)
        raise _file_error(src, f"{prefix}{culprit}" if culprit else prefix.rstrip(".") or "plant", msg) \
            from None


def _problem_from(src: str, data: Mapping[str, Any], path: Path) -> Problem:
    """A Problem from a file's top-level mapping (library schema or the minimal form)."""
    schema = "plant" in data
    allowed = _SCHEMA_KEYS if schema else _MINIMAL_KEYS
    unknown = [k for k in data if k not in allowed]
    if unknown:
        form = ("the library schema (name, title, plant, targets, ...)" if schema
                else f"a plant file ({', '.join(_MINIMAL_KEYS)})")
        raise _file_error(src, unknown[0], f"unknown field for {form}")
    default_name = path.stem
    if schema:
        block = data["plant"]
        if block is not None and not isinstance(block, Mapping):
            raise _file_error(src, "plant", f"must be an object with the matrices A, C, ...; found "
                                            f"{type(block).__name__}")
        bad = [k for k in (block or {}) if k not in (*_MATRIX_KEYS, "dt", "name")]
        if bad:
            keys = ", ".join((*_MATRIX_KEYS, "dt", "name"))
            raise _file_error(src, f"plant.{bad[0]}", f"unknown field; a plant has {keys}")
        name = _text(src, "name", data.get("name", default_name))
        plant = None if block is None else _plant_from(src, {"name": name, **block}, "plant.", name)
        targets = data.get("targets", {})
        for k in ("targets", "references", "data"):
            if not isinstance(data.get(k, {}), Mapping):
                raise _file_error(src, k, f"must be an object; found {type(data[k]).__name__}")
        targets = dict(_decode(targets))
        if "poles" in targets and plant is not None:
            targets["poles"] = _poles(src, "targets.poles", data["targets"]["poles"], plant.n)
        tags = data.get("tags", [])
        if not isinstance(tags, list) or not all(isinstance(t, str) for t in tags):
            raise _file_error(src, "tags", "must be a list of strings")
        texts = {k: _text(src, k, data.get(k, "")) for k in ("kind", "citation", "source", "notes")}
        return Problem(name=name, title=_text(src, "title", data.get("title", f"{name} (from {src})")),
                       kind=texts["kind"] or "user", plant=plant, targets=targets,
                       references=_decode(data.get("references", {})), data=_decode(data.get("data", {})),
                       citation=texts["citation"], source=texts["source"], notes=texts["notes"],
                       tags=tuple(tags), path=str(path), origin="file")
    plant = _plant_from(src, data, "", default_name)
    targets = {} if data.get("poles") is None else {"poles": _poles(src, "poles", data["poles"], plant.n)}
    name = plant.name or default_name
    return Problem(name=name, title=_text(src, "title", data.get("title", f"{name} (from {src})")),
                   kind="user", plant=plant, targets=targets,
                   notes=_text(src, "notes", data.get("notes", "")), source=str(path), path=str(path),
                   origin="file")


def load_file(path: str | os.PathLike) -> Problem:
    """Load a user's problem from a file: JSON / TOML, ``.npz`` or MATLAB ``.mat``.

    The formats and what is checked are in the module docstring ("A user's own problem").

    Parameters
    ----------
    path : str or path
        A file whose suffix is one of :data:`FILE_SUFFIXES`.

    Returns
    -------
    Problem
        ``origin == "file"``; ``name`` is the file's ``name`` field or its stem; ``kind`` is
        ``"user"`` unless the file says otherwise; ``targets["poles"]`` from ``poles``.

    Raises
    ------
    ProblemFileError
        No such file, an unknown suffix, a file above :data:`MAX_FILE_BYTES`, invalid JSON/TOML, a
        matrix above :data:`MAX_DIMENSION`, an object array, an unknown or malformed field (not
        numeric, wrong shape, NaN/inf, Q not PSD, R not PD, ...): one line naming the file and
        the field.
    ValidationError
        ``path`` is neither a string nor a path.

    Examples
    --------
    >>> import json, os, tempfile
    >>> d = tempfile.mkdtemp()
    >>> f = os.path.join(d, "mine.json")
    >>> with open(f, "w") as fh:
    ...     json.dump({"A": [[0, 1], [-2, -3]], "C": [[1, 0]], "Q": [[1, 0], [0, 1]], "R": [[1]]}, fh)
    >>> load_file(f).plant.n
    2
    """
    if not isinstance(path, (str, os.PathLike)):
        raise ValidationError(f"path must be a string or a path; found {type(path).__name__} {path!r}")
    p = Path(path)
    src = str(path)
    if "\x00" in src:
        raise _file_error(repr(src[:60]), None, "the path contains a NUL character (\\x00), which no file "
                                                "system accepts")
    suffix = p.suffix.lower()
    if suffix not in FILE_SUFFIXES:
        raise _file_error(src, None, f"unknown kind of problem file {suffix or '(no suffix)'!r}; expected "
                                     f"{', '.join(FILE_SUFFIXES)} (or a library name: `optdesign list`)")
    if not p.is_file():
        raise _file_error(src, None, "no such problem file" if not p.exists() else "not a file")
    try:
        size = p.stat().st_size
    except OSError as exc:
        raise _file_error(src, None, f"cannot read the file ({exc.strerror or exc})") from None
    if size > MAX_FILE_BYTES:
        raise _file_error(src, None, f"the file has {size} bytes; at most {MAX_FILE_BYTES} are read "
                                     "(optdesign.problems.MAX_FILE_BYTES)")
    try:
        if suffix in (".json", ".toml"):
            data = _read_text_mapping(p, src)
        elif suffix == ".npz":
            data = read_npz(p, src, _limits())
        else:
            data = read_mat(p, src, _limits())
    except PermissionError as exc:
        raise _file_error(src, None, f"cannot read the file ({exc.strerror or exc})") from None
    return _problem_from(src, data, p)


def _source_root() -> Path:  # used by tests to compare with the source tree
    return Path(__file__).resolve().parents[1] / "problems"
