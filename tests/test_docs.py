"""The documentation site (docs/): it builds with -W, every internal link and anchor resolves, every
public name and every committed figure is on it, and the user guide's code runs.

The build is the CI step of the site: ``python -m sphinx -W --keep-going -b html docs docs/_build/html``
(here on a copy of docs/, so that parallel test workers never write into the source tree).  It takes
about 30 s of CPU, hence ``slow``.
"""

from __future__ import annotations

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
        if path.parent.name == "api":
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
    gallery = site.html / "gallery"
    for script in sorted(EXAMPLES.glob("*.py")):
        assert (gallery / f"{script.stem}.html").exists(), f"no gallery page for {script.name}"
    text = {p: p.read_text(encoding="utf-8") for p in gallery.glob("*.html")}
    images = [img for p, page in site.pages.items() if p.parent == gallery for img in page.images]
    figdir = EXAMPLES / "figures"
    figures = sorted(f.relative_to(figdir).as_posix() for f in figdir.rglob("*.png"))
    for fig in figures:
        assert any(f"examples/figures/{fig}" in t for t in text.values()), f"{fig} is not in the gallery"
    assert len(images) == len(figures), f"{len(images)} images in the gallery for {len(figures)} figures"


# --------------------------------------------------------------------------- generator rules


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
