"""Sphinx configuration of the optdesign site.

Build (from the repository root; the ``docs`` extra installs what it needs)::

    python -m sphinx -W --keep-going -b html docs docs/_build/html

The notebooks in ``docs/notebooks`` are executed by myst-nb.  The API reference, the gallery, the problem table and the command-line help are generated from the
package at each build by ``docs/_ext/optdesign_docs.py``; the rest is written by hand.
"""

from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path

import optdesign

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE / "_ext"))

project = "optdesign"
author = "optdesign developers"
copyright = "optdesign developers, BSD-3-Clause"
release = optdesign.__version__
version = ".".join(release.split(".")[:2])

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "sphinx.ext.intersphinx",
    "numpydoc",
    "myst_nb",
    "optdesign_docs",
]

exclude_patterns = ["_build", "README.md", "**/_generated", "**/.ipynb_checkpoints"]
templates_path: list[str] = []
root_doc = "index"
optdesign_examples_dir = "../examples"

# -- notebooks (myst-nb) -----------------------------------------------------------------------------------
# docs/notebooks/*.ipynb are executed at every build (their outputs are never stored in git), so the site
# shows what the code prints and draws today; a cell that raises fails the build.  myst-nb rather than
# nbsphinx: it runs the notebooks through jupyter's own client with no pandoc binary to install, and it
# renders each output's richest form (our results' _repr_html_ tables, the pole maps as images).
nb_execution_mode = "force"
# the notebooks' kernel: quiet (ipykernel warns on stderr that its local TCP transport is not encrypted,
# which a -W build would count as a problem), in a throw-away IPython directory (no history in the tree)
_IPYTHONDIR = Path(tempfile.mkdtemp(prefix="optdesign-docs-ipython-"))
(_IPYTHONDIR / "profile_default").mkdir()
(_IPYTHONDIR / "profile_default" / "ipython_kernel_config.py").write_text('c.IPKernelApp.log_level = "ERROR"\n')
os.environ["IPYTHONDIR"] = str(_IPYTHONDIR)
# the notebooks' kernel imports the optdesign this build documents (the checkout), not another install
os.environ["PYTHONPATH"] = os.pathsep.join(
    [str(Path(optdesign.__file__).resolve().parents[1]), *filter(None, [os.environ.get("PYTHONPATH")])])
nb_execution_raise_on_error = True
nb_execution_timeout = 600
nb_merge_streams = True
# a cell writing to stderr (a warning of ours, solver chatter, progress lines) fails the -W build
nb_output_stderr = "warn"

# -- cross-references -----------------------------------------------------------------------------------
# Every reference into optdesign must resolve (a dangling one is a broken link): optdesign_docs resolves
# any public path of an object to where it is documented and silences only references to other packages
# (numpy, scipy, builtins) that no inventory resolves.
nitpicky = True

# intersphinx: links to the peers' documentation.  The build must pass -W offline (CI has no network),
# so each project's inventory is read from docs/_intersphinx/<name>.inv when that file is shipped
# (``python docs/_ext/fetch_inventories.py`` downloads them, on a machine with network), and from the
# project's site only when OPTDESIGN_DOCS_ONLINE=1; a project with neither is left out (its references
# then render as code, unlinked, as without intersphinx).
INTERSPHINX_SITES = {
    "python": "https://docs.python.org/3/",
    "numpy": "https://numpy.org/doc/stable/",
    "scipy": "https://docs.scipy.org/doc/scipy/",
    "control": "https://python-control.readthedocs.io/en/latest/",
    "cvxpy": "https://www.cvxpy.org/",
    "casadi": "https://web.casadi.org/python-api/",
    "matplotlib": "https://matplotlib.org/stable/",
}
_ONLINE = os.environ.get("OPTDESIGN_DOCS_ONLINE") == "1"


def _inventory_locations(name: str) -> tuple[str | None, ...]:
    local = HERE / "_intersphinx" / f"{name}.inv"
    return tuple([str(local)] * local.is_file() + [None] * _ONLINE)


intersphinx_mapping = {name: (url, _inventory_locations(name)) for name, url in INTERSPHINX_SITES.items()
                       if _inventory_locations(name)}
intersphinx_timeout = 10
intersphinx_disabled_reftypes = ["std:doc"]  # a :doc: link is always ours

# -- autodoc / autosummary / numpydoc -----------------------------------------------------------------
autosummary_generate = False          # the module pages are written by optdesign_docs, not by autosummary
autodoc_typehints = "none"            # the numpydoc Parameters sections carry the types and shapes
autodoc_member_order = "bysource"
autodoc_default_options: dict[str, object] = {}
autodoc_inherit_docstrings = False    # a method without a docstring of its own shows none (not the stdlib's)
numpydoc_show_class_members = False   # members are documented by autodoc (:members:), not listed twice
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False
numpydoc_validation_checks: set[str] = set()

# -- HTML ---------------------------------------------------------------------------------------------
html_theme = "pydata_sphinx_theme"
html_title = f"optdesign {release}"
html_static_path: list[str] = []
html_show_sourcelink = False
html_theme_options = {
    "navigation_with_keys": False,
    "show_toc_level": 2,
    "header_links_before_dropdown": 6,
    "secondary_sidebar_items": ["page-toc"],
}
html_context = {"default_mode": "light"}
