"""The documentation site (docs/): it builds with -W, every internal link and anchor resolves, every
public name and every committed figure is on it, and the user guide's code runs.

The build is the CI step of the site: ``python -m sphinx -W --keep-going -b html docs docs/_build/html``
(here on a copy of docs/, so that parallel test workers never write into the source tree).  It takes
about 30 s of CPU, hence ``slow``.
"""

from __future__ import annotations

import html
import importlib
import os
import re
import shutil
import subprocess
import sys
from dataclasses import dataclass
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import unquote, urlsplit

import pytest

#: one xdist group, so that the module fixture (the site build) runs once under --dist loadgroup
pytestmark = pytest.mark.xdist_group("docs")

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
EXAMPLES = ROOT / "examples"
GUIDE_PAGES = [DOCS / "index.rst", *sorted((DOCS / "guide").glob("*.rst"))]

sys.path.insert(0, str(DOCS / "_ext"))
import optdesign_docs  # noqa: E402, I001  (the site's generator: docs/_ext/optdesign_docs.py)


# --------------------------------------------------------------------------- an independent link checker


class _Page(HTMLParser):
    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.ids: set[str] = set()
        self.links: list[tuple[str, str]] = []  # (attribute, url)
        self.images: list[str] = []
        self.signatures: list[str] = []  # ids of documented Python objects

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        a = {k: v or "" for k, v in attrs}
        for key in ("id", "name"):
            if a.get(key):
                self.ids.add(a[key])
        if tag == "a" and "href" in a:
            self.links.append(("href", a["href"]))
        if tag in ("img", "script") and a.get("src"):
            self.links.append(("src", a["src"]))
            if tag == "img":
                self.images.append(a["src"])
        if tag == "link" and a.get("href") and "stylesheet" in a.get("rel", ""):
            self.links.append(("href", a["href"]))
        if tag == "dt" and "sig-object" in a.get("class", "").split() and a.get("id"):
            self.signatures.append(a["id"])


def parse_site(root: Path) -> dict[Path, _Page]:
    pages = {}
    for path in sorted(root.rglob("*.html")):
        page = _Page()
        page.feed(path.read_text(encoding="utf-8"))
        pages[path] = page
    return pages


def broken_links(root: Path, pages: dict[Path, _Page] | None = None) -> list[str]:
    """Every relative link (file and ``#anchor``) of the HTML under ``root`` that does not resolve."""
    pages = parse_site(root) if pages is None else pages
    broken = []
    for path, page in pages.items():
        if path.relative_to(root).parts[0] == "_static":
            continue  # the theme's assets (templates among them), not pages of the site
        for attr, url in page.links:
            parts = urlsplit(url)
            if parts.scheme or url.startswith("//"):
                continue  # external: not checked offline
            target = (path.parent / unquote(parts.path)).resolve() if parts.path else path
            if target.is_dir():
                target = target / "index.html"
            where = f"{path.relative_to(root)}: {attr}={url!r}"
            if not target.exists():
                broken.append(f"{where}: no file {target}")
            elif parts.fragment and target.suffix == ".html":
                ids = pages[target].ids if target in pages else set()
                if unquote(parts.fragment) not in ids:
                    broken.append(f"{where}: no anchor #{parts.fragment} in {target.name}")
    return broken


def test_link_checker_finds_broken_links(tmp_path):
    (tmp_path / "sub").mkdir()
    (tmp_path / "a.html").write_text(
        '<a href="sub/b.html#here">ok</a> <a href="sub/b.html#gone">bad anchor</a> '
        '<a href="missing.html">bad file</a> <img src="sub/fig.png"> <a href="https://x.org/y">ext</a> '
        '<a href="#self">self</a><span id="self"></span>')
    (tmp_path / "sub" / "b.html").write_text('<h1 id="here">b</h1>')
    found = broken_links(tmp_path)
    assert len(found) == 3, found
    assert any("#gone" in f for f in found) and any("missing.html" in f for f in found)
    assert any("fig.png" in f for f in found)


# --------------------------------------------------------------------------- the build


@dataclass
class Site:
    html: Path
    log: str
    returncode: int
    pages: dict[Path, _Page]


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Site:
    for mod in ("sphinx", "numpydoc", "pydata_sphinx_theme"):
        pytest.importorskip(mod, reason="the docs extra (sphinx, numpydoc, pydata-sphinx-theme) builds it")
    tmp = tmp_path_factory.mktemp("docs")
    src = tmp / "src"
    shutil.copytree(DOCS, src, ignore=shutil.ignore_patterns("_build", "api", "gallery", "_generated"))
    html = tmp / "html"
    cmd = [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-E", "-b", "html",
           "-d", str(tmp / "doctrees"), "-D", f"optdesign_examples_dir={EXAMPLES}", str(src), str(html)]
    env = {**os.environ, "PYTHONWARNINGS": "ignore::DeprecationWarning"}
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=tmp)
    return Site(html, proc.stdout + proc.stderr, proc.returncode, parse_site(html) if html.is_dir() else {})


@pytest.mark.slow
def test_site_builds_without_warnings(site):
    problems = [line for line in site.log.splitlines() if re.search(r"\b(WARNING|ERROR|CRITICAL)\b", line)]
    assert site.returncode == 0 and not problems, (
        f"sphinx -W failed (exit {site.returncode}); {len(problems)} problems:\n" + "\n".join(problems[:60])
        + ("" if problems else site.log[-3000:]))


@pytest.mark.slow
def test_every_internal_link_resolves(site):
    assert (site.html / "index.html").exists(), site.log[-3000:]
    broken = broken_links(site.html, site.pages)
    assert not broken, f"{len(broken)} broken links:\n" + "\n".join(broken[:40])


@pytest.mark.slow
def test_every_public_name_is_documented(site):
    """Each name in the ``__all__`` of each public module is a documented object of the API pages
    (by identity: the page may document it under another public name), linked from its module's page."""
    documented = []
    for path, page in site.pages.items():
        if "api" in path.relative_to(site.html).parts[:1]:
            for ident in page.signatures:
                found = optdesign_docs.lookup(ident)
                if found is not None:
                    documented.append(found[0])
    missing, unlinked = [], []
    for mod in optdesign_docs.public_modules():
        module = importlib.import_module(mod.name)
        page = site.pages.get(site.html / "api" / f"{mod.name}.html")
        hrefs = {url for _, url in page.links} if page else set()
        for name in mod.names:
            obj = getattr(module, name)
            if not any(d is obj for d in documented):
                missing.append(f"{mod.name}.{name}")
            if not any(url.rpartition("#")[2].endswith(f".{name}") for url in hrefs):
                unlinked.append(f"{mod.name}.{name}")
    assert not missing, f"public names without an API entry: {missing}"
    assert not unlinked, f"public names not linked from their module's page: {unlinked}"


@pytest.mark.slow
def test_gallery_shows_every_script_and_committed_figure(site):
    """Each script has a page with its committed output and figures; the index a thumbnail of each."""
    gallery = site.html / "gallery"
    scripts = sorted(EXAMPLES.glob("*.py"))
    for script in scripts:
        assert (gallery / f"{script.stem}.html").exists(), f"no gallery page for {script.name}"
    text = {p: p.read_text(encoding="utf-8") for p in gallery.glob("*.html")}
    figdir = EXAMPLES / "figures"
    figures = sorted(f.relative_to(figdir).as_posix() for f in figdir.rglob("*.png"))
    for fig in figures:
        assert any(f"<code class=\"docutils literal notranslate\"><span class=\"pre\">{fig}</span>" in t
                   for t in text.values()), f"{fig} is not in the gallery"
    on_pages = [img for p, page in site.pages.items() if p.parent == gallery and p.name != "index.html"
                for img in page.images]
    assert len(on_pages) == len(figures), f"{len(on_pages)} images on the pages for {len(figures)} figures"
    thumbs = site.pages[gallery / "index.html"].images
    with_figures = {optdesign_docs.figure_owner(f, [s.stem for s in scripts]) for f in figures}
    assert len(thumbs) == len(with_figures - {None}), thumbs
    for script in scripts:
        output = figdir / f"{script.stem}.txt"
        assert output.is_file(), f"no committed output of {script.name}: run docs/_ext/refresh_gallery.py"
        words = re.findall(r"[A-Za-z_]{4,}", output.read_text(encoding="utf-8"))[:5]  # markup-free
        page = text[gallery / f"{script.stem}.html"]
        assert 'id="output"' in page and all(w in page for w in words), f"{script.name}: output not shown"


@pytest.mark.slow
def test_notebooks_are_executed(site):
    """Both notebooks are on the site with their outputs: figures and printed text (myst-nb ran them),
    and no cell wrote to stderr (no cell hides it: no ``remove-stderr`` tag)."""
    for name in ("getting_started", "regions_and_pareto"):
        page = site.html / "notebooks" / f"{name}.html"
        assert page.exists(), f"no page for docs/notebooks/{name}.ipynb"
        images = site.pages[page].images
        assert len(images) >= 3, f"{name}: {len(images)} figures"
        text = page.read_text(encoding="utf-8")
        assert "cell_output" in text
        # nothing on stderr: no warning of the library's own, no solver chatter, no progress lines
        assert "output stderr" not in text, f"{name}: a cell wrote to stderr"


@pytest.mark.slow
def test_api_sidebar_lists_tasks_not_modules(site):
    """The API reference's navigation holds the task groups and one page per object; the modules
    (and the internal layers) are reachable from api/modules.html only, outside the sidebar."""
    index = (site.html / "api" / "index.html").read_text(encoding="utf-8")
    nav = index[index.find('class="bd-sidebar-primary'):index.find('class="bd-main')]
    assert nav, "no sidebar found in api/index.html"
    for title, _, _ in optdesign_docs.TASKS:
        assert html.escape(title) in nav, f"task group {title!r} not in the sidebar"
    assert 'href="generated/optdesign.kalman.html"' in nav
    assert "optdesign.design.verification.html" not in nav and "optdesign._validate.html" not in nav
    modules = site.pages[site.html / "api" / "modules.html"]
    assert any(url.endswith("optdesign.design.verification.html") for _, url in modules.links)


@pytest.mark.slow
def test_intersphinx_links_to_shipped_inventories(site):
    """References to SciPy and Python resolve through docs/_intersphinx/ offline."""
    place = (site.html / "api" / "generated" / "optdesign.place.html").read_text(encoding="utf-8")
    assert 'href="https://docs.scipy.org/doc/scipy/reference/generated/scipy.signal.place_poles.html' in place


# --------------------------------------------------------------------------- generator rules


def test_every_top_level_name_is_in_a_task_group():
    mods = optdesign_docs.public_modules()
    groups = optdesign_docs.task_groups(optdesign_docs.canonical_names(mods))
    titles = [title for title, _, _ in groups]
    assert "Other" not in titles, f"names of optdesign.__all__ in no task group: {groups[-1][2]}"
    listed = [full for _, _, fulls in groups for full in fulls]
    assert len(listed) == len(set(listed))


def test_task_groups_name_existing_objects():
    with pytest.raises(ValueError, match="does not exist"):
        optdesign_docs.expand_task_names(["optdesign.no_such_verb"])
    names = dict(optdesign_docs.expand_task_names(["optdesign.studies.*"]))
    from optdesign.studies.sweep import sweep as sweep_fn

    assert names["optdesign.studies.sweep"] is sweep_fn  # the function, not the module of that name


def test_every_public_verb_has_an_example():
    """Each function of ``optdesign.__all__`` (and the classes a user builds: Plant, ModelSet, the
    problem object) shows an Examples section with a doctest (run by tests/test_doctests.py)."""
    import inspect

    import optdesign
    from optdesign.compat import control, scipy

    verbs = {f"optdesign.{n}": getattr(optdesign, n) for n in optdesign.__all__
             if inspect.isfunction(getattr(optdesign, n))}
    built = ("Plant", "ModelSet", "InverseKalmanProblem")
    verbs.update({f"optdesign.{n}": getattr(optdesign, n) for n in built})
    for module in (control, scipy):  # the drop-ins
        verbs.update({f"{module.__name__}.{n}": getattr(module, n) for n in module.__all__
                      if inspect.isfunction(getattr(module, n))})
    missing = [name for name, obj in verbs.items()
               if "Examples\n--------\n>>>" not in (inspect.getdoc(obj) or "")]
    assert len(verbs) >= 37 and not missing, f"public verbs without an Examples section: {missing}"



def test_figure_owner_is_the_longest_shared_prefix():
    stems = ["seed000_inverse_kalman", "seed001_well_conditioned", "study_alpha_sector", "study_beta"]
    owner = optdesign_docs.figure_owner
    assert owner("seed000_pole_loci.png", stems) == "seed000_inverse_kalman"
    assert owner("study_alpha_sector/from_spec/alpha_sector_kappa2.png", stems) == "study_alpha_sector"
    assert owner("study_beta_front.png", stems) == "study_beta"
    assert owner("robust_aircraft_poles.png", stems) is None           # no script claims it
    assert owner("study_gamma.png", stems) is None                      # two scripts tie: none claims it


def test_canonical_names_document_each_object_once():
    mods = optdesign_docs.public_modules()
    canon = optdesign_docs.canonical_names(mods)
    import optdesign
    from optdesign.studies.sweep import sweep as sweep_fn

    assert canon[optdesign_docs.object_key(optdesign.Plant, "Plant")] == "optdesign.Plant"
    # re-exported by the package under the name of a module: documented where it is defined
    assert canon[optdesign_docs.object_key(sweep_fn, "sweep")] == "optdesign.studies.sweep.sweep"
    module_names = {m.name for m in mods}
    assert not module_names & set(canon.values())
    assert not any(part.startswith("_") for m in mods for part in m.name.split("."))


# --------------------------------------------------------------------------- the guide's content


def _python_blocks(path: Path) -> list[str]:
    """The ``.. code-block:: python`` blocks of an rst file, dedented."""
    lines = path.read_text(encoding="utf-8").splitlines()
    blocks, i = [], 0
    while i < len(lines):
        if re.match(r"^\s*\.\. code-block:: python\s*$", lines[i]):
            indent = len(lines[i]) - len(lines[i].lstrip()) + 3
            i += 1
            while i < len(lines) and lines[i].strip().startswith(":"):
                i += 1  # directive options
            body = []
            while i < len(lines) and (not lines[i].strip() or lines[i][:indent].isspace()):
                body.append(lines[i][indent:])
                i += 1
            blocks.append("\n".join(body).strip("\n"))
        else:
            i += 1
    return blocks


def test_python_block_extraction():
    assert _python_blocks(DOCS / "guide" / "questions.rst")[0].startswith("import numpy as np")


@pytest.mark.parametrize("page", [p for p in GUIDE_PAGES if _python_blocks(p)], ids=lambda p: p.name)
def test_guide_code_runs(page, tmp_path):
    """The Python examples of each page, run in order in one fresh interpreter (as a reader would)."""
    code = "\n\n".join(_python_blocks(page))
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path,
                          env={**os.environ, "MPLBACKEND": "Agg"})
    assert proc.returncode == 0, f"{page.name}: the guide's code fails:\n{proc.stderr[-3000:]}"


def test_status_table_lists_every_status():
    from optdesign import Status

    text = (DOCS / "guide" / "results.rst").read_text(encoding="utf-8")
    table = re.findall(r"^   \* - ``([a-z_]+)``$", text, flags=re.M)
    assert sorted(table) == sorted(s.value for s in Status), "docs/guide/results.rst: stale status table"
