"""Rerun the example scripts and rewrite the gallery's committed snapshot in ``examples/figures/``.

Run from the repository root (all scripts take a few minutes; name some to run only those)::

    python docs/_ext/refresh_gallery.py                       # every script of examples/
    python docs/_ext/refresh_gallery.py seed002_kalman_robustness

Each script runs in a fresh interpreter on this checkout's ``optdesign``, with its build folder a
temporary directory (``$OPTDESIGN_EXAMPLES_OUT``) and DeprecationWarnings as errors; a script that
fails or writes to stderr is reported and its snapshot is left as it was.  Otherwise:

* what it printed goes to ``examples/figures/<stem>.txt`` (the temporary folder's path replaced by
  ``examples/_build``), shown on its gallery page;
* its PNG figures are copied, scaled down to at most :data:`MAX_WIDTH` pixels wide (the scripts draw at
  300 dpi; the snapshot is for the site and the README, and stays small in git);
* its other files (the CSV and JSON tables of the studies) are copied as they are.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples"
SNAPSHOT = EXAMPLES / "figures"
#: width in pixels of the committed figures (the site shows them at most ~1100 px wide)
MAX_WIDTH = 1200


def copy_figure(src: Path, dst: Path) -> None:
    """Copy a PNG, scaled down to :data:`MAX_WIDTH` pixels wide (dpi metadata scaled alike) and stored
    with a 256-colour palette (a line plot loses nothing visible; the file is 3-4x smaller)."""
    from PIL import Image

    dst.parent.mkdir(parents=True, exist_ok=True)
    with Image.open(src) as im:
        im.load()
        scale = min(1.0, MAX_WIDTH / im.width)
        dpi = im.info.get("dpi", (300.0, 300.0))
        small = im.convert("RGB")
        if scale < 1.0:
            size = (round(im.width * scale), round(im.height * scale))
            small = small.resize(size, Image.Resampling.LANCZOS)
    small = small.quantize(colors=256, dither=Image.Dither.NONE)
    small.save(dst, optimize=True, dpi=(dpi[0] * scale, dpi[1] * scale))


def refresh(script: Path) -> str | None:
    """Run one script and rewrite its snapshot; an error message, or None."""
    with tempfile.TemporaryDirectory(prefix=f"optdesign-{script.stem}-") as tmp:
        out = Path(tmp) / "out"
        env = {**os.environ, "OPTDESIGN_EXAMPLES_OUT": str(out), "MPLBACKEND": "Agg",
               "PYTHONPATH": os.pathsep.join([str(ROOT), *filter(None, [os.environ.get("PYTHONPATH")])])}
        env.pop("PYTHONWARNINGS", None)
        proc = subprocess.run([sys.executable, "-W", "error::DeprecationWarning", str(script)], cwd=tmp,
                              env=env, stdin=subprocess.DEVNULL, capture_output=True, text=True)
        if proc.returncode != 0 or proc.stderr:
            return f"exit {proc.returncode}, stderr:\n{proc.stderr[-3000:]}"
        text = proc.stdout.replace(str(out), "examples/_build").replace(tmp, "<tmp>")
        (SNAPSHOT / f"{script.stem}.txt").write_text(text, encoding="utf-8")
        for path in sorted(p for p in out.rglob("*") if p.is_file()):
            dst = SNAPSHOT / path.relative_to(out)
            if path.suffix == ".png":
                copy_figure(path, dst)
            else:
                dst.parent.mkdir(parents=True, exist_ok=True)
                shutil.copyfile(path, dst)
            print(f"  {dst.relative_to(ROOT)}")
    return None


def main(argv: list[str]) -> int:
    scripts = sorted(EXAMPLES.glob("*.py"))
    if argv:
        by_stem = {s.stem: s for s in scripts}
        unknown = [a for a in argv if a not in by_stem]
        if unknown:
            print(f"no example {unknown}; expected one of {sorted(by_stem)}", file=sys.stderr)
            return 2
        scripts = [by_stem[a] for a in argv]
    failed = 0
    for script in scripts:
        print(f"{script.name}:", flush=True)
        error = refresh(script)
        if error:
            failed += 1
            print(f"  FAILED ({error})", file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
