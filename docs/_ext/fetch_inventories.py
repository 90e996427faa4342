"""Download the intersphinx inventories of the projects the site links to into ``docs/_intersphinx/``.

Run on a machine with network access, then commit the files::

    python docs/_ext/fetch_inventories.py            # every project of docs/conf.py's INTERSPHINX_SITES
    python docs/_ext/fetch_inventories.py numpy scipy

The site's build reads these files (it never goes online unless ``OPTDESIGN_DOCS_ONLINE=1``), so the
links to numpy, scipy, python-control, cvxpy, CasADi ... work in an offline build (CI) too.  A project
without a file is left out of intersphinx: its names render as code, unlinked, without a warning.
"""

from __future__ import annotations

import ast
import sys
import urllib.request
from pathlib import Path

DOCS = Path(__file__).resolve().parents[1]


def sites() -> dict[str, str]:
    """``INTERSPHINX_SITES`` of docs/conf.py, read without importing it (the import needs optdesign)."""
    tree = ast.parse((DOCS / "conf.py").read_text(encoding="utf-8"))
    for node in tree.body:
        names = [getattr(t, "id", "") for t in getattr(node, "targets", [])]
        if isinstance(node, ast.Assign) and "INTERSPHINX_SITES" in names:
            return ast.literal_eval(node.value)
    raise SystemExit("docs/conf.py defines no INTERSPHINX_SITES")


def main(argv: list[str]) -> int:
    known = sites()
    names = argv or list(known)
    unknown = [n for n in names if n not in known]
    if unknown:
        print(f"unknown project(s) {unknown}; expected one of {sorted(known)}", file=sys.stderr)
        return 2
    out = DOCS / "_intersphinx"
    out.mkdir(exist_ok=True)
    failed = 0
    for name in names:
        url = known[name].rstrip("/") + "/objects.inv"
        try:
            with urllib.request.urlopen(url, timeout=30) as response:  # noqa: S310 - fixed https URLs
                data = response.read()
        except OSError as err:
            print(f"{name}: {url}: {err}", file=sys.stderr)
            failed += 1
            continue
        if not data.startswith(b"# Sphinx inventory version"):
            print(f"{name}: {url} is not a Sphinx inventory", file=sys.stderr)
            failed += 1
            continue
        (out / f"{name}.inv").write_bytes(data)
        print(f"{name}: {len(data):,} bytes -> {out / (name + '.inv')}")
    return 1 if failed else 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
