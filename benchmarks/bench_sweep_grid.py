"""The whole 1,000-point region sweep of ``bench_sweep.py``, serially in one process: CPU per point.

Run:  python benchmarks/bench_sweep_grid.py run MODE [--rows K:OFF] --json FILE
      python benchmarks/bench_sweep_grid.py report FILE... [--out benchmarks/results/sweep_grid.md]

``run`` designs every point of the grid (alpha x damping sector, chunks of 25 points = one alpha, in the
order of ``bench_sweep.py``) with ``RegionSweepDesigner`` in mode MODE -- ``pool`` (the default designer),
``always`` (``placement="always"``), ``fallback``, or ``cold`` (``warm_start=False``: the issue's "re-used
cold point") -- and writes the CPU time (``time.process_time``) and kappa2 of every point as JSON; ``--rows
K:OFF`` keeps the alpha rows ``i`` with ``i % K == OFF`` (to split a long mode over two processes).
``report`` merges such files by mode and writes the table: mean and median CPU per point, the ratio of each
reference's mean to the mode's, and each mode's kappa2 against the references' at every point.  The
references: ``always``, ``cold`` and the issue's baseline, the cold mode on the code when issue 13 was filed
(commit ``BASELINE_COMMIT``), measured on the same machine::

    git clone -q . /tmp/base && git -C /tmp/base checkout -q 4b45ef1
    cp benchmarks/bench_sweep_grid.py /tmp/base/benchmarks/
    cd /tmp/base/benchmarks
    PYTHONPATH=/tmp/base python bench_sweep_grid.py run cold --label baseline --json base.json

Numbers, not pass/fail.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import sys
import time
from pathlib import Path

import _common  # noqa: E402,F401  (single-threaded BLAS before numpy)
import numpy as np  # noqa: E402

from optdesign.studies import RegionSweepDesigner, grid  # noqa: E402

RADIUS = 20.0  # as bench_sweep.py
CHUNK = 25
#: the label of the issue's baseline run (the cold mode on the code of BASELINE_COMMIT)
BASELINE = "baseline"
BASELINE_COMMIT = "4b45ef1"
MODES = {"always": {"placement": "always"}, "pool": {"placement": "pool"},
         "fallback": {"placement": "fallback"}, "cold": {"warm_start": False, "placement": "always"}}


def points() -> list[dict]:
    return grid(alpha=np.linspace(0.5, 3.0, 40), zeta=np.linspace(0.9, 0.2, CHUNK))


def run(mode: str, rows: str | None, out: str, options: dict | None = None, label: str | None = None) -> None:
    k, off = (map(int, rows.split(":")) if rows else (1, 0))
    pts = points()
    index = [i for i in range(len(pts)) if (i // CHUNK) % k == off]
    kw = {**MODES[mode], **({"options": options} if options else {})}  # (the baseline code has no options)
    designer = RegionSweepDesigner(problem="compleib_dis2", radius=RADIUS, **kw)
    cpu, kappa2, verified = [], [], []
    for c in range(0, len(index), CHUNK):
        session = designer.start_chunk()  # a chunk carries its warm starts, as in a sweep
        for i in index[c:c + CHUNK]:
            c0 = time.process_time()
            r = session(**pts[i])
            cpu.append(time.process_time() - c0)
            kappa2.append(float(r.kappa2))
            verified.append(bool(r.verification.passed))
        print(f"{mode}: {len(cpu)} points, {sum(cpu):.1f} s CPU", flush=True)
    Path(out).write_text(json.dumps({"mode": label or mode, "index": index, "cpu": cpu, "kappa2": kappa2,
                                     "verified": verified}))


def report(files: list[str], out: str) -> None:
    n = len(points())
    modes: dict[str, dict[str, np.ndarray]] = {}
    for f in files:
        d = json.loads(Path(f).read_text())
        m = modes.setdefault(d["mode"], {"cpu": np.full(n, np.nan), "kappa2": np.full(n, np.nan),
                                         "verified": np.zeros(n, bool)})
        for key in ("cpu", "kappa2", "verified"):
            m[key][d["index"]] = d[key]
    # the references a mode is compared with: the placement starts at every point, the cold mode, and
    # the baseline (the code when issue 13 was filed, run with --label baseline; see the docstring)
    refs = {k: modes[k] for k in ("always", "cold", BASELINE) if k in modes}
    lines = [
        "# The whole 1,000-point region sweep, serially: CPU per point",
        "",
        f"`benchmarks/bench_sweep_grid.py` on {datetime.date.today()} -- {platform.platform()}, Python "
        f"{platform.python_version()}, OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS')}.  COMPleib DIS2, "
        "the grid of `bench_sweep.py` (alpha = linspace(0.5, 3, 40) x zeta = linspace(0.9, 0.2, 25), chunks "
        "of 25 points = one alpha, zeta descending: the sector widens along a chunk).  CPU: "
        "`time.process_time` around each point's design (every point counted, the chunks' first "
        "points included).  Modes: `pool` (the default designer), `always` (`placement=\"always\"`: the "
        "placement starts at every point), `cold` (`warm_start=False`: the issue's re-used cold point, on "
        f"today's code), `{BASELINE}` (the cold mode at commit {BASELINE_COMMIT}, when the issue was filed).",
        "",
        "| mode | points | verified | mean CPU ms/point | median CPU ms/point | total CPU s "
        + "".join(f"| {k} mean / mean " for k in refs)
        + "".join(f"| kappa2 worse than {k} by > 0.1 % | worst / {k} | better than {k} by > 0.1 % "
                  for k in refs)
        + "|",
        "|---|---|---|---|---|---|" + "---|" * (4 * len(refs)),
    ]
    for name, m in modes.items():
        ok = ~np.isnan(m["cpu"])
        c = m["cpu"][ok] * 1e3
        row = [name, str(ok.sum()), str(int(m["verified"][ok].sum())), f"{c.mean():.1f}",
               f"{np.median(c):.1f}", f"{c.sum() / 1e3:.1f}"]
        row += [f"{np.nanmean(other['cpu']) * 1e3 / c.mean():.1f}x" for other in refs.values()]
        for other in refs.values():
            r = m["kappa2"][ok] / other["kappa2"][ok]
            row += [str(int((r > 1 + 1e-3).sum())), f"{np.nanmax(r):.4g}", str(int((r < 1 - 1e-3).sum()))]
        lines.append("| " + " | ".join(row) + " |")
    Path(out).write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("run")
    r.add_argument("mode", choices=sorted(MODES))
    r.add_argument("--rows", default=None, help="K:OFF -- the alpha rows i with i %% K == OFF")
    r.add_argument("--json", required=True)
    r.add_argument("--options", default=None, help="IPOPT options over the designer's, as JSON")
    r.add_argument("--label", default=None, help="the mode's name in the report (default: MODE)")
    p = sub.add_parser("report")
    p.add_argument("files", nargs="+")
    p.add_argument("--out", default=str(Path(__file__).resolve().parent / "results" / "sweep_grid.md"))
    args = ap.parse_args(argv)
    if args.cmd == "run":
        run(args.mode, args.rows, args.json, json.loads(args.options) if args.options else None, args.label)
    else:
        report(args.files, args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
