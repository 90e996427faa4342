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
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from functools import cache, lru_cache
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from ._validate import as_str
from .errors import ProblemNotFoundError, ValidationError
from .model.plant import Plant

__all__ = ["Problem", "names", "load", "load_all", "describe"]

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
        The file it was read from.
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


def load(name: str) -> Problem:
    """Load a problem by name.

    Parameters
    ----------
    name : str
        A name from :func:`names` (the file stem).

    Returns
    -------
    Problem

    Raises
    ------
    ProblemNotFoundError
        No such problem (the message suggests close names).
    ValidationError
        ``name`` is not a string.
    """
    raw = _raw(as_str("name", name))
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


def describe(name: str) -> str:
    """A few lines describing a problem (used by ``optdesign show``)."""
    p = load(name)
    lines = [f"{p.name}: {p.title}", f"  kind: {p.kind}", f"  citation: {p.citation}"]
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
                with np.printoptions(precision=6, suppress=True, linewidth=100):
                    lines.append(f"    {k} = {str(v).replace(chr(10), chr(10) + '      ')}")
    if p.notes:
        lines.append(f"  notes: {p.notes}")
    lines.append(f"  file: problems/{p.path}")
    return "\n".join(lines)


def _source_root() -> Path:  # used by tests to compare with the source tree
    return Path(__file__).resolve().parents[1] / "problems"
