"""Sphinx extension of the optdesign site: pages generated from the package, so they follow the code.

At ``builder-inited`` it writes (only when their text changed, so incremental builds stay incremental):

* ``api/`` -- the reference grouped by task (:data:`TASKS`: ``api/index.rst`` holds one table and one
  captioned toctree per task, ``api/generated/<name>.rst`` one page per object), and one orphan page per
  public module (found by walking the package; modules and packages whose name has a component starting
  with ``_`` are private and skipped), listing the module's ``__all__``, linked from ``api/modules.rst``
  but kept out of the sidebar.  Every public object is documented once, at its *canonical* name: the
  first public module, in :func:`module_order`, whose ``__all__`` holds it (``optdesign.Plant`` rather
  than ``optdesign.model.plant.Plant``; a constant: the first that also assigns it, where its ``#:``
  comment is) -- on its own page when a task group lists it, else on its module's page; the other
  modules that export it link there.
* ``gallery/`` -- one page per script of ``examples/``: the script's docstring, what it printed and the
  figures it drew (the committed snapshot in ``examples/figures/``: ``<stem>.txt`` and the PNGs, written
  by ``docs/_ext/refresh_gallery.py``; the build does not run the scripts, together they take minutes)
  and its source; the index shows a thumbnail of each script's first figure.  A figure belongs to the
  script whose file stem shares the longest ``_``-separated prefix with the figure's path below
  ``figures/``.
* ``guide/_generated/problems.rst`` -- the problem library table, from :func:`optdesign.problems.load_all`.
* ``guide/_generated/cli.rst`` -- the ``optdesign`` command's help texts, from its argparse parser.

Nothing here is hand-copied from the package: rename a function and its page follows.
"""

from __future__ import annotations

import ast
import builtins
import contextlib
import enum
import importlib
import importlib.util
import inspect
import io
import os
import pkgutil
import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from optdesign_tasks import TASKS  # the task groups of the API reference (docs/_ext/optdesign_tasks.py)

__all__ = [
    "ApiEntry",
    "PublicModule",
    "public_modules",
    "internal_modules",
    "module_order",
    "canonical_names",
    "object_key",
    "TASKS",
    "expand_task_names",
    "task_groups",
    "object_page",
    "api_pages",
    "gallery_pages",
    "figure_owner",
    "problems_page",
    "cli_page",
    "unique_suffix_match",
    "write_if_changed",
    "generate",
    "setup",
]

PACKAGE = "optdesign"
#: layer order of the sub-packages (imports flow downward; the reference follows it)
LAYERS = ("model", "analysis", "classical", "formulate", "backends", "engines", "design", "compat", "plot",
          "studies")
#: data reprs longer than this are not shown in the signature line
MAX_VALUE_REPR = 80
HEADING = "=-~^"

# --------------------------------------------------------------------------- public modules


@dataclass
class PublicModule:
    """One public module: its name, whether it is a package, its public names (``__all__``)."""

    name: str
    is_package: bool
    names: tuple[str, ...]
    has_all: bool
    submodules: list[str] = field(default_factory=list)

    @property
    def module(self) -> Any:
        return importlib.import_module(self.name)


def _is_private(name: str) -> bool:
    return any(part.startswith("_") for part in name.split("."))


def module_order(name: str) -> tuple:
    """Sort key: the package, then shallow before deep, then layer order, then alphabetical.

    Shallow first makes the convenience namespaces (``optdesign.regions``, ``optdesign.studies``)
    the canonical home of what they export.
    """
    parts = name.split(".")
    layer = LAYERS.index(parts[1]) if len(parts) > 1 and parts[1] in LAYERS else len(LAYERS)
    return (len(parts), layer, name)


def public_modules(package: str = PACKAGE) -> list[PublicModule]:
    """Every public module of ``package`` (sorted by :func:`module_order`)."""
    root = importlib.import_module(package)
    found = {package: True}
    for info in pkgutil.walk_packages(root.__path__, package + "."):
        if _is_private(info.name) or info.name.endswith("__main__"):
            continue
        found[info.name] = info.ispkg
    mods = []
    for name in sorted(found, key=module_order):
        module = importlib.import_module(name)
        names = getattr(module, "__all__", None)
        mods.append(PublicModule(name, found[name], tuple(names or ()), names is not None))
    by_name = {m.name: m for m in mods}
    for m in mods:
        parent = m.name.rpartition(".")[0]
        if parent in by_name:
            by_name[parent].submodules.append(m.name)
    return mods


def internal_modules(package: str = PACKAGE) -> list[PublicModule]:
    """The foundation modules below every layer whose names are public although the module is not
    (``optdesign._deadline``, ``optdesign._validate``, ...: a private module with an ``__all__``, directly
    under the package).  Docstrings refer to them; the reference lists them last, as internals."""
    root = importlib.import_module(package)
    mods = []
    for info in pkgutil.iter_modules(root.__path__, package + "."):
        short = info.name.rpartition(".")[2]
        if not short.startswith("_") or short.startswith("__"):
            continue
        names = getattr(importlib.import_module(info.name), "__all__", None)
        if names is not None:
            mods.append(PublicModule(info.name, info.ispkg, tuple(names), True))
    return sorted(mods, key=lambda m: m.name)


def object_key(obj: Any, name: str) -> tuple:
    """Identity of a public object: classes and functions by where they are defined, data by the
    object itself and the name it is exported under (two constants may share one float object)."""
    if inspect.isclass(obj) or inspect.isroutine(obj):
        return ("def", getattr(obj, "__module__", ""), getattr(obj, "__qualname__", name))
    return ("data", id(obj), name)


def module_assignments(module_name: str) -> frozenset[str]:
    """Names a module assigns at its top level (``NAME = ...``, ``NAME: T = ...``): where a constant's
    ``#:`` comment, which autodoc shows as its documentation, is written."""
    if module_name not in _ASSIGNED:
        try:
            tree = ast.parse(inspect.getsource(importlib.import_module(module_name)))
        except (OSError, TypeError):
            tree = ast.Module(body=[], type_ignores=[])
        names = set()
        for node in tree.body:
            targets = node.targets if isinstance(node, ast.Assign) else \
                [node.target] if isinstance(node, ast.AnnAssign) else []
            names.update(t.id for t in targets if isinstance(t, ast.Name))
        _ASSIGNED[module_name] = frozenset(names)
    return _ASSIGNED[module_name]


_ASSIGNED: dict[str, frozenset[str]] = {}


def canonical_names(mods: Iterable[PublicModule]) -> dict[tuple, str]:
    """Object key -> its canonical full name: the first module in order that exports it -- for a
    constant (data), the first that exports it *and assigns it*, where its ``#:`` documentation is.

    A name that is also a module (``optdesign.studies.sweep`` is a function re-exported by the
    package and a module) cannot be an object's canonical name: the object is then documented in a
    later module (its defining one).
    """
    mods = list(mods)
    module_names = {m.name for m in mods}
    canon: dict[tuple, str] = {}
    fallback: dict[tuple, str] = {}
    for m in mods:
        for name in m.names:
            full = f"{m.name}.{name}"
            if full in module_names:
                continue
            obj = getattr(m.module, name)
            key = object_key(obj, name)
            if inspect.isclass(obj) or inspect.isroutine(obj) or name in module_assignments(m.name):
                canon.setdefault(key, full)
            else:
                fallback.setdefault(key, full)
    return {**fallback, **canon}


# --------------------------------------------------------------------------- API pages


@dataclass
class ApiEntry:
    """One public name of a module page: the autodoc directive and options that document it here
    (``directive`` None: documented at ``canonical``), and the module it is listed under."""

    name: str
    canonical: str
    directive: str | None
    options: list[str]
    group: str


def _directive(obj: Any) -> tuple[str, list[str]]:
    if inspect.isclass(obj) and issubclass(obj, BaseException):
        return "autoexception", [":members:", ":show-inheritance:"]
    if inspect.isclass(obj):
        options = [":members:", ":show-inheritance:"]
        if issubclass(obj, enum.Enum):
            options.append(":undoc-members:")
        return "autoclass", options
    if inspect.isroutine(obj):
        return "autofunction", []
    options = [":no-value:"] if len(repr(obj)) > MAX_VALUE_REPR else []
    return "autodata", options


def _title(text: str, level: int) -> list[str]:
    return [text, HEADING[level] * len(text), ""]


def _first_line(module_name: str) -> str:
    doc = inspect.getdoc(importlib.import_module(module_name)) or ""
    return doc.strip().splitlines()[0].rstrip(".") if doc.strip() else module_name


def _relative(full: str, module: str) -> str:
    """``full`` as autosummary wants it on the page of ``module`` (relative below it, shown short)."""
    prefix = module + "."
    rest = full[len(prefix):] if full.startswith(prefix) else full
    return rest if "." not in rest else f"~{rest}"


def _group(obj: Any, page: str) -> str:
    """Where an entry of ``page`` comes from: the layer module that defines it (three name components,
    ``optdesign.design.inverse_kalman`` for everything of that package), or the page itself."""
    defined = getattr(obj, "__module__", None) if inspect.isclass(obj) or inspect.isroutine(obj) else None
    if not defined or not defined.startswith(PACKAGE + "."):
        return page
    group = ".".join(defined.split(".")[:3])
    return page if group == page or page.startswith(group + ".") else group


def module_page(m: PublicModule, canon: dict[tuple, str], own_pages: frozenset[str] = frozenset()) -> str:
    """The rst text of one module page (an orphan: the sidebar shows the task groups, not the modules).
    Objects whose canonical name is in ``own_pages`` are documented on a page of their own and only
    listed (linked) here."""
    module = m.module
    entries = []
    for name in m.names:
        obj = getattr(module, name)
        full = canon.get(object_key(obj, name), f"{m.name}.{name}")
        here = full == f"{m.name}.{name}" and full not in own_pages
        directive, options = _directive(obj) if here else (None, [])
        entries.append(ApiEntry(name, full, directive, options, _group(obj, m.name)))
    lines = [":orphan:", ""] + _title(f"``{m.name}``", 0)
    lines += [f".. automodule:: {m.name}", "   :no-members:", ""]
    if m.submodules:
        lines += [".. rubric:: Modules", "", ".. autosummary::", ""]
        lines += [f"   {_relative(sub, m.name)}" for sub in m.submodules] + [""]
    if not m.has_all:
        lines += ["This package defines no ``__all__`` of its own: its public names are those of its "
                  "modules above.", ""]
        return "\n".join(lines)
    if entries:
        lines += [".. rubric:: Public names", "", ".. autosummary::", "   :nosignatures:", ""]
        # autosummary wants names of the current module relative to it
        lines += [f"   {_relative(e.canonical, m.name)}" for e in entries] + [""]
    elsewhere = [e for e in entries if e.directive is None and e.canonical not in own_pages]
    if elsewhere:
        lines += ["Documented at their canonical names: "
                  + ", ".join(f":py:obj:`{e.canonical}`" for e in elsewhere) + ".", ""]
    documented = [e for e in entries if e.directive is not None]
    groups = list(dict.fromkeys(e.group for e in documented))
    for group in groups:
        if len(groups) > 1:
            lines += _title(f"From ``{group}``" if group != m.name else "Defined here", 1)
        if group != m.name:
            lines += [f"Defined in :py:mod:`{group}`: {_first_line(group)}.", ""]
        for e in (e for e in documented if e.group == group):
            lines += [f".. {e.directive}:: {e.canonical}"] + [f"   {o}" for o in e.options] + [""]
    return "\n".join(lines)


def expand_task_names(names: Iterable[str]) -> list[tuple[str, Any]]:
    """``(dotted name, object)`` of each name of a task group, ``module.*`` expanded to the module's
    ``__all__``.  An object is looked up as an attribute of its module (``optdesign.studies.sweep`` is
    the function the namespace exports, not the module of that name)."""
    out = []
    for name in names:
        parent, _, attr = name.rpartition(".")
        module = importlib.import_module(parent)
        if attr == "*":
            out += [(f"{parent}.{n}", getattr(module, n)) for n in module.__all__]
        elif not hasattr(module, attr):
            raise ValueError(f"TASKS names {name!r}, which does not exist")
        else:
            out.append((name, getattr(module, attr)))
    return out


def task_groups(canon: dict[tuple, str]) -> list[tuple[str, str, list[str]]]:
    """``(title, intro, canonical names)`` of each task group of :data:`TASKS` -- an object once, in its
    first group -- then "Other" with the names of ``optdesign.__all__`` that no group holds."""
    seen: set[str] = set()
    groups = []
    for title, intro, names in TASKS:
        fulls = []
        for dotted, obj in expand_task_names(names):
            full = canon.get(object_key(obj, dotted.rpartition(".")[2]), dotted)
            if full not in seen:
                seen.add(full)
                fulls.append(full)
        groups.append((title, intro, fulls))
    package = importlib.import_module(PACKAGE)
    other = [full for n in package.__all__
             if (full := canon.get(object_key(getattr(package, n), n), f"{PACKAGE}.{n}")) not in seen]
    if other:
        groups.append(("Other", "Public names that no task group lists yet.", other))
    return groups


def object_page(full: str, public: list[str]) -> str:
    """The page of one object: its autodoc entry, and the other public names it is exported under."""
    found = lookup(full)
    if found is None:
        raise ValueError(f"no object {full!r}")
    directive, options = _directive(found[0])
    lines = _title(f"``{full}``", 0)
    aliases = [p for p in public if p != full]
    if aliases:
        lines += ["Also exported as " + ", ".join(f"``{a}``" for a in aliases) + ".", ""]
    lines += [f".. {directive}:: {full}"] + [f"   {o}" for o in options] + [""]
    return "\n".join(lines)


def api_pages(mods: list[PublicModule]) -> dict[str, str]:
    """``relative path -> rst`` for the API reference: ``api/index.rst`` (the task groups, each a table
    and a captioned toctree of one page per object), ``api/generated/<name>.rst`` (those pages),
    ``api/modules.rst`` (every module, linked) and one orphan page per module."""
    canon = canonical_names(mods)
    groups = task_groups(canon)
    own = frozenset(full for _, _, fulls in groups for full in fulls)
    pages = {f"api/{m.name}.rst": module_page(m, canon, own) for m in mods}
    public: dict[str, list[str]] = {}
    for m in mods:
        if not _is_private(m.name):
            for name in m.names:
                full = canon.get(object_key(getattr(m.module, name), name))
                if full is not None:
                    public.setdefault(full, []).append(f"{m.name}.{name}")
    for full in own:
        pages[f"api/generated/{full}.rst"] = object_page(full, public.get(full, []))
    index = _title("API reference", 0) + [
        ".. currentmodule:: optdesign", "",
        "The public names of :mod:`optdesign`, grouped by the task they serve, one page each.  The",
        "same objects module by module (and the layers below the namespaces): :doc:`modules`.", "",
    ]
    for title, intro, fulls in groups:
        index += _title(title, 1) + [intro, "", ".. autosummary::", "   :nosignatures:", ""]
        index += [f"   {_relative(full, PACKAGE)}" for full in fulls] + [""]  # relative to currentmodule
        index += [".. toctree::", "   :hidden:", f"   :caption: {title}", ""]
        index += [f"   generated/{full}" for full in fulls] + [""]
    index += [".. toctree::", "   :hidden:", "   :caption: Modules", "", "   modules", ""]
    pages["api/index.rst"] = "\n".join(index)
    modules = _title("Modules", 0) + [
        "Every public module of :mod:`optdesign` and every name in its ``__all__``, generated from the",
        "package.  An object is documented once, under the first public name it has (the top-level",
        "``optdesign`` namespace first, then the convenience modules, then the layers; a constant where it",
        "is assigned); the other modules that export it link there.", "",
    ]
    sections: dict[str, list[str]] = {}
    for m in mods:
        parts = m.name.split(".")
        if _is_private(m.name):
            key = "Internals (foundation modules, not a stable API)"
        else:
            key = "Namespaces" if len(parts) <= 2 else f"Layer ``{'.'.join(parts[:2])}``"
        sections.setdefault(key, []).append(m.name)
    for caption, names in sections.items():
        modules += _title(caption, 1)
        # a package's modules right after it (the reference order itself is shallow-first)
        modules += [f"* :doc:`{name}`: {_cell(_first_line(name))}"
                    for name in (names if caption == "Namespaces" else sorted(names))] + [""]
    pages["api/modules.rst"] = "\n".join(modules)
    return pages


# --------------------------------------------------------------------------- gallery


def _tokens(text: str) -> list[str]:
    return re.split(r"[_/]", text)


def figure_owner(figure: str, stems: Iterable[str]) -> str | None:
    """The script stem that owns ``figure`` (its path below ``figures/``, ``/``-separated): the
    stem sharing the longest ``_``/``/``-separated prefix with it; None when no stem shares one or
    two share the longest."""
    best, best_len, tie = None, 0, False
    fig = _tokens(figure)
    for stem in stems:
        common = 0
        for a, b in zip(_tokens(stem), fig, strict=False):
            if a != b:
                break
            common += 1
        if common > best_len:
            best, best_len, tie = stem, common, False
        elif common == best_len and common > 0:
            tie = True
    return None if tie or best_len == 0 else best


def _script_doc(path: Path) -> str:
    return ast.get_docstring(ast.parse(path.read_text(encoding="utf-8"))) or ""


#: thumbnails per row of the gallery's index
GALLERY_COLUMNS = 3


def _thumbnail_table(cells: list[list[str]]) -> list[str]:
    """A ``list-table`` of :data:`GALLERY_COLUMNS` columns holding the rst lines of each cell."""
    lines = [".. list-table::", "   :class: optdesign-gallery", ""]
    cells = cells + [[""]] * (-len(cells) % GALLERY_COLUMNS)
    for start in range(0, len(cells), GALLERY_COLUMNS):
        for col, cell in enumerate(cells[start:start + GALLERY_COLUMNS]):
            head = "   * - " if col == 0 else "     - "
            lines += [(head if i == 0 else "       ") + line if line else "" for i, line in enumerate(cell)]
            if not any(cell):
                lines[-1] = head.rstrip()
    return lines + [""]


def gallery_pages(examples: Path, docs: Path) -> dict[str, str]:
    """``relative path -> rst`` for the gallery (``gallery/index.rst`` and one page per script).

    Each script's page shows its docstring, what it printed (``examples/figures/<stem>.txt``), its
    figures and its source; the index shows a thumbnail of each script's first figure.  The output and
    the figures are the committed snapshot of ``examples/figures/``, written by
    ``docs/_ext/refresh_gallery.py`` (the build does not run the scripts: together they take minutes).
    """
    scripts = sorted(examples.glob("*.py"))
    figdir = examples / "figures"
    figures = sorted(p.relative_to(figdir).as_posix() for p in figdir.rglob("*.png")) if figdir.is_dir() \
        else []
    owners = {f: figure_owner(f, [s.stem for s in scripts]) for f in figures}
    rel = Path(os.path.relpath(examples, docs / "gallery")).as_posix()
    pages: dict[str, str] = {}
    cells: list[list[str]] = []
    for script in scripts:
        doc = _script_doc(script)
        summary = doc.splitlines()[0] if doc else script.stem  # rst, as the docstring wrote it
        lines = _title(f"``{script.name}``", 0) + [doc, ""]
        if f"examples/{script.name}" not in doc:
            lines += [f"Run: ``python examples/{script.name}``", ""]
        output = figdir / f"{script.stem}.txt"
        if output.is_file():
            lines += _title("Output", 1) + [
                f"What ``python examples/{script.name}`` printed (the committed snapshot; timings are of",
                "the machine that ran it):", "",
                f".. literalinclude:: {rel}/figures/{output.name}", "   :language: text", ""]
        mine = [f for f in figures if owners[f] == script.stem]
        if mine:
            lines += _title("Figures", 1)
            for fig in mine:
                lines += [f".. figure:: {rel}/figures/{fig}", "   :width: 100%", "",
                          f"   ``{fig}``", ""]
        for extra in sorted(examples.glob(f"{script.stem}.*")):
            if extra.suffix != ".py":
                lines += _title(f"``{extra.name}``", 1) + [
                    f".. literalinclude:: {rel}/{extra.name}", f"   :language: {extra.suffix[1:]}", ""]
        lines += _title("Source", 1) + [f".. literalinclude:: {rel}/{script.name}", "   :language: python",
                                        ""]
        pages[f"gallery/{script.stem}.rst"] = "\n".join(lines)
        cell = [f".. image:: {rel}/figures/{mine[0]}", "   :width: 100%", f"   :alt: {script.stem}", ""] \
            if mine else []
        cells.append(cell + [f":doc:`{script.stem}`", "", summary])
    index = _title("Gallery", 0) + [
        "The scripts of ``examples/``, each with what it prints and the figures it draws.  What is shown",
        "is the committed snapshot in ``examples/figures/`` (building the site does not run the scripts:",
        "together they take minutes); ``python docs/_ext/refresh_gallery.py`` reruns them and rewrites it.",
        "Run a script yourself and its files go to ``examples/_build/`` (or ``$OPTDESIGN_EXAMPLES_OUT``).",
        "", ".. toctree::", "   :hidden:", "",
    ] + [f"   {s.stem}" for s in scripts] + [""] + _thumbnail_table(cells)
    orphans = [f for f in figures if owners[f] is None]
    if orphans:
        index += ["Figures no script claims (by name): " + ", ".join(f"``{f}``" for f in orphans), ""]
    pages["gallery/index.rst"] = "\n".join(index)
    return pages


# --------------------------------------------------------------------------- problem library, CLI


def _cell(text: Any) -> str:
    """Escape a value for an rst table cell (one line)."""
    s = " ".join(str(text).split())
    return re.sub(r"([*`|_\\])", r"\\\1", s) if s else "-"


def problems_page() -> str:
    """The problem library as a table (name, kind, plant size, title, citation)."""
    from optdesign import problems

    rows = problems.load_all()
    lines = [".. list-table::", "   :header-rows: 1", "   :widths: 18 10 8 32 32", "",
             "   * - name", "     - kind", "     - plant", "     - what it is", "     - citation"]
    for p in rows:
        plant = "-" if p.plant is None else f"n={p.plant.n}, p={p.plant.p}"
        plant += "" if p.plant is None or p.plant.dt is None else ", discrete"
        lines += [f"   * - ``{p.name}``", f"     - {_cell(p.kind)}", f"     - {plant}",
                  f"     - {_cell(p.title)}", f"     - {_cell(p.citation)}"]
    return "\n".join([f"{len(rows)} problems.", ""] + lines + [""])


def _help(parser: Any, argv: list[str]) -> str:
    out = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.suppress(SystemExit):
        parser.parse_args(argv)
    return out.getvalue().rstrip()


def cli_page() -> str:
    """The help of the ``optdesign`` command and of each sub-command."""
    import argparse

    from optdesign import cli

    old = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = "100"  # argparse wraps to the terminal width: make the page reproducible
    try:
        parser = cli.build_parser()
        commands = [name for action in parser._actions if isinstance(action, argparse._SubParsersAction)
                    for name in action.choices]
        blocks = [("optdesign -h", _help(parser, ["-h"]))]
        blocks += [(f"optdesign {c} -h", _help(cli.build_parser(), [c, "-h"])) for c in commands]
    finally:
        if old is None:
            os.environ.pop("COLUMNS", None)
        else:
            os.environ["COLUMNS"] = old
    lines: list[str] = []
    for title, text in blocks:
        lines += _title(f"``{title}``", 1) + [".. code-block:: text", ""]
        lines += [("   " + line).rstrip() for line in text.splitlines()] + [""]
    return "\n".join(lines)


# --------------------------------------------------------------------------- cross-references

#: canonical names of the current build (set at builder-inited)
_STATE: dict[str, Any] = {"canon": {}}


def lookup(dotted: str) -> tuple[Any, list[str]] | None:
    """``(object, attribute path)`` of a dotted name: the longest importable module prefix, then
    attributes; None if it does not resolve."""
    parts = dotted.split(".")
    for cut in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:cut]))
        except ImportError:
            continue
        try:
            for attr in parts[cut:]:
                obj = getattr(obj, attr)
        except AttributeError:
            return None
        return obj, parts
    return None


def _defining_module(obj: Any) -> str | None:
    if inspect.ismodule(obj):
        return obj.__name__
    return getattr(obj, "__module__", None) if inspect.isclass(obj) or inspect.isroutine(obj) else None


def context_modules(node: Any) -> list[str]:
    """Modules a bare name in ``node`` may be relative to: the page's current module, then the
    defining modules of the documented objects around it (a docstring's names are relative to the
    module that wrote it, not to the namespace it is documented in)."""
    from sphinx import addnodes

    mods = [node["py:module"]] if node.get("py:module") else []
    if node.get("py:module") and node.get("py:class"):
        mods.insert(0, f"{node['py:module']}.{node['py:class']}")
    parent = node.parent
    while parent is not None:
        if isinstance(parent, addnodes.desc):
            sig = next((c for c in parent.children if isinstance(c, addnodes.desc_signature)), None)
            if sig is not None and sig.get("module"):
                # the top-level object documented (a method's class) and the module defining it
                found = lookup(f"{sig['module']}.{sig['fullname'].split('.')[0]}")
                for m in (_defining_module(found[0]) if found else None, sig["module"]):
                    if m and m not in mods:
                        mods.append(m)
        parent = parent.parent
    # then the packages above each module, up to optdesign: a name as its package exports it
    for m in list(mods):
        while "." in m:
            m = m.rpartition(".")[0]
            if m not in mods:
                mods.append(m)
    return mods


def resolve_target(target: str, contexts: list[str]) -> tuple[Any, str] | None:
    """The object a reference means and the dotted name it resolved under (absolute first)."""
    target = target.removesuffix("()").lstrip("~.")
    for candidate in [target] + [f"{m}.{target}" for m in contexts]:
        found = lookup(candidate)
        if found is not None:
            return found[0], candidate
    return None


def canonical_of(obj: Any, dotted: str) -> str | None:
    """Canonical full name of ``obj`` found as ``dotted`` (members: their owner's canonical name
    plus the member path)."""
    canon = _STATE["canon"]
    qualname = getattr(obj, "__qualname__", "")
    if (inspect.isroutine(obj) or inspect.isclass(obj)) and "." in qualname and "<" not in qualname:
        # a member: where its defining class is documented (inherited members included)
        owner, _, member = qualname.rpartition(".")
        found = lookup(f"{obj.__module__}.{owner}")
        if found is not None and found[0] is not obj:
            owner_full = canonical_of(found[0], f"{obj.__module__}.{owner}")
            if owner_full is not None:
                return f"{owner_full}.{member}"
    parts = dotted.split(".")
    for cut in range(len(parts), 0, -1):
        found = lookup(".".join(parts[:cut]))
        if found is None:
            continue
        full = canon.get(object_key(found[0], parts[cut - 1]))
        if full is not None:
            return ".".join([full] + parts[cut:])
        if inspect.ismodule(found[0]):
            return None
    return None


def _on_missing_reference(app: Any, env: Any, node: Any, contnode: Any) -> Any:
    """Resolve a reference to any public path of an object (``optdesign.classical.riccati.filter_are``,
    a bare name relative to the docstring's own module) to where the object is documented."""
    if node.get("refdomain") != "py":
        return None
    from sphinx.util.nodes import make_refnode

    domain = env.get_domain("py")
    resolved = resolve_target(node["reftarget"], context_modules(node))
    full = None
    if resolved is not None:
        obj, dotted = resolved
        full = obj.__name__ if inspect.ismodule(obj) else canonical_of(obj, dotted)
    if full not in domain.objects:
        full = unique_suffix_match(node["reftarget"], domain.objects)
    entry = domain.objects.get(full) if full else None
    if entry is None:
        return None
    return make_refnode(app.builder, node["refdoc"], entry.docname, entry.node_id, contnode, full)


def unique_suffix_match(target: str, documented: Mapping[str, Any]) -> str | None:
    """The one documented optdesign object whose full name ends with ``.target`` (a bare name that its
    docstring's module does not import, as Sphinx's own ``.name`` search does); None when none or
    several match.  ``documented``: the Python domain's objects (full name -> entry with ``docname``,
    ``node_id``); names that are aliases of one entry (autodoc's ``:canonical:``) count once."""
    target = target.removesuffix("()").lstrip("~.")
    if target.startswith(PACKAGE + "."):
        return None
    matches: dict[tuple[str, str], str] = {}
    for name, entry in documented.items():
        if name.startswith(PACKAGE + ".") and name.endswith("." + target):
            key = (entry.docname, entry.node_id)
            if key not in matches or getattr(documented[matches[key]], "aliased", False):
                matches[key] = name
    return next(iter(matches.values())) if len(matches) == 1 else None


def _on_warn_missing_reference(app: Any, domain: Any, node: Any) -> bool | None:
    """Silence unresolved references to objects outside optdesign (numpy, scipy, builtins: no
    inventory offline); a reference into optdesign that does not resolve is a dangling link and
    keeps its warning."""
    if node.get("refdomain") != "py":
        return None
    target = node["reftarget"].removesuffix("()").lstrip("~.")
    resolved = resolve_target(target, context_modules(node))
    if resolved is not None:
        module = _defining_module(resolved[0]) or resolved[1]
        return True if not module.startswith(PACKAGE) else None
    head = target.split(".")[0]
    if hasattr(builtins, head) or head != PACKAGE and importlib.util.find_spec(head) is not None:
        return True  # an external module's name that does not resolve: not ours to check
    return None


# --------------------------------------------------------------------------- Sphinx glue


def write_if_changed(path: Path, text: str) -> bool:
    """Write ``text`` to ``path`` unless it already holds it (keeps Sphinx's incremental build)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.exists() and path.read_text(encoding="utf-8") == text:
        return False
    path.write_text(text, encoding="utf-8")
    return True


def generate(docs: Path, examples: Path) -> dict[str, str]:
    """Every generated page (``relative path -> rst``); stale generated API pages are removed."""
    mods = public_modules() + internal_modules()
    _STATE["canon"] = canonical_names(mods)
    pages = api_pages(mods)
    pages.update(gallery_pages(examples, docs))
    pages["guide/_generated/problems.rst"] = problems_page()
    pages["guide/_generated/cli.rst"] = cli_page()
    for folder in ("api", "api/generated", "gallery"):
        for old in (docs / folder).glob("*.rst") if (docs / folder).is_dir() else ():
            if f"{folder}/{old.name}" not in pages:
                old.unlink()
    for rel, text in pages.items():
        write_if_changed(docs / rel, text)
    return pages


def _on_process_docstring(app: Any, what: str, name: str, obj: Any, options: Any, lines: list[str]) -> None:
    """A constant without a ``#:`` comment gets no documentation -- not its type's docstring (autodoc
    falls back to ``float.__doc__``, ``dict.__doc__``, ...)."""
    if what in ("data", "attribute") and lines and not inspect.isclass(obj) and not inspect.isroutine(obj):
        own = inspect.getdoc(type(obj)) or ""
        if "\n".join(lines).strip() == own.strip():
            lines[:] = []


def _on_builder_inited(app: Any) -> None:
    generate(Path(app.srcdir), (Path(app.confdir) / app.config.optdesign_examples_dir).resolve())


def setup(app: Any) -> dict[str, Any]:
    app.add_config_value("optdesign_examples_dir", "../examples", "env")
    app.connect("builder-inited", _on_builder_inited)
    app.connect("autodoc-process-docstring", _on_process_docstring, priority=100)  # before numpydoc
    app.connect("missing-reference", _on_missing_reference)
    app.connect("warn-missing-reference", _on_warn_missing_reference)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
