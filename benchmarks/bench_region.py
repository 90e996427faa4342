"""Region-mode designs of the well-conditioned observer: today's default (the base commit) and the new
default route side by side (issue 28).

Run:  python benchmarks/bench_region.py run {new,base} --set {subset,full} --objective {kappa2,eta} --json F
          [--route auto|engine|fast|multistart|nlp|default]
      python benchmarks/bench_region.py report BASE.json NEW.json [...] --out benchmarks/results/region.md

``run new`` imports the checkout this script lives in and designs with the verb's default (``--route R``:
``WellConditionedProblem(route=R)``); ``run base`` re-runs this script in a subprocess
with ``PYTHONPATH`` set to a checkout of the commit before issue 28 (``BASE_COMMIT``), made once with::

    mkdir /tmp/region-base-d9d35ed && git archive d9d35ed | tar -x -C /tmp/region-base-d9d35ed

(as ``bench_sweep_grid.py`` measures its baseline).  Each design is one call of
``well_conditioned_observer(plant, region=..., objective=..., time_limit=TIME_LIMIT)``; CPU is
``time.process_time`` around it, single-threaded BLAS (``_common``).  Cases: every continuous COMPleib
plant with n <= 10 (``suggested_region``), random plants n = 3..10 (two per size plus four more; ``p =
max(1, n // 3)``, A ~ N(0, 1/n)) and n = 20 (p = 5), n = 30 (p = 7) with the region of the issue's random
example, ``HalfPlane(0.5) & Sector.from_damping(0.5) & Disk(0, 5)``.  ``--set subset``: REA2, DIS1, HE5,
AC6 and five random plants.  Numbers, not pass/fail.  Time every run under ``flock /tmp/bench.lock``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import _common  # noqa: F401  (single-threaded BLAS before numpy)
import numpy as np

BASE_COMMIT = "d9d35ed"
BASE_DIR = "/tmp/region-base-d9d35ed"
#: the commit before this round's change (the barrier engine), made as the base: ``git archive a924a43``
PREV_COMMIT = "a924a43"
PREV_DIR = "/tmp/region-prev-a924a43"
DIRS = {"base": (BASE_COMMIT, BASE_DIR), "prev": (PREV_COMMIT, PREV_DIR)}
#: seconds of wall time per design (both codes): today's default ran past 120 s on some n = 9-10 plants
TIME_LIMIT = 150.0
SUBSET_COMPLEIB = ("compleib_rea2", "compleib_dis1", "compleib_he5", "compleib_ac6")


def random_cases(full: bool) -> list[tuple[str, int, int, int]]:
    """``(name, n, p, seed)`` of the random plants."""
    if not full:
        sizes = [5, 5, 6, 8, 10]
    else:
        sizes = [n for n in range(3, 11) for _ in range(2)] + [4, 6, 8, 10] + [20, 30]
    out, count = [], {}
    for n in sizes:
        k = count.get(n, 0)
        count[n] = k + 1
        p = 5 if n == 20 else 7 if n == 30 else max(1, n // 3) if n > 5 or k else 2
        out.append((f"random_n{n}_p{p}_s{k}", n, p, 1000 * n + k))
    return out


def cases(which: str):
    from _common import random_observable_plant

    from optdesign import problems
    from optdesign.design.well_conditioned import suggested_region
    from optdesign.regions import Disk, HalfPlane, Sector

    names = (SUBSET_COMPLEIB if which == "subset" else
             [n for n in problems.names() if n.startswith("compleib")])
    for name in names:
        plant = problems.load(name).plant
        if plant.n <= 10 and not plant.is_discrete:
            yield name, plant, suggested_region(plant)
    for name, n, p, seed in random_cases(which == "full"):
        plant = random_observable_plant(np.random.default_rng(seed), n, p)
        yield name, plant, HalfPlane(0.5) & Sector.from_damping(0.5) & Disk(0.0, 5.0)


def run(which: str, objective: str, out: str, only: str | None, route: str | None, code: str = "new") -> None:
    from optdesign import metrics, well_conditioned_observer
    from optdesign.design.well_conditioned import WellConditionedProblem

    rows = []
    for name, plant, region in cases(which):
        if only and name not in only.split(","):
            continue
        c0 = time.process_time()
        if route is None:  # the verb's default
            d = well_conditioned_observer(plant, region=region, objective=objective, time_limit=TIME_LIMIT)
        else:
            d = WellConditionedProblem(plant, objective=objective, route=route).solve(region=region,
                                                                                      time_limit=TIME_LIMIT)
        cpu = time.process_time() - c0
        k2 = float(metrics.kappa2(plant.A - d.L @ plant.C)) if np.all(np.isfinite(d.L)) else float("nan")
        trace = getattr(d, "route", None)
        rows.append({"name": name, "n": plant.n, "p": plant.p, "status": d.status.value,
                     "kappa2": float(d.kappa2), "eta": float(d.eta), "kappa2_recomputed": k2,
                     "verified": bool(d.verification.passed),
                     "cpu": cpu, "route": str(trace.answered.name) if trace and trace.answered else
                     d.solver_stats.extra.get("route", "")})
        print(f"{name} n={plant.n} p={plant.p} {objective} {d.status.value} {d.kappa2:.6g} eta {d.eta:.6g} "
              f"cpu {cpu:.2f} s", flush=True)
        label = DIRS[code][0] if code in DIRS else "this checkout"
        Path(out).write_text(json.dumps({"objective": objective, "code": code, "commit": label, "rows": rows},
                                        indent=1))


def report(files: list[str], out: str) -> None:
    """Pairs (base, new) per objective, in the order given: one table each."""
    lines = ["# Region-mode designs: the previous default (base) against the new default (new)", "",
             f"Base: commit {BASE_COMMIT}, the verb's default then (IPOPT from 8 starts, then one engine "
             "start; in this checkout `route='multistart'`).  New: this checkout, kappa2 with "
             "`route='engine'` (= the new default `'auto'`: the placement engine from 8 starts in lockstep, "
             "IPOPT only as the fallback), eta with the verb's default (IPOPT from 8 starts, as in the "
             "base).  CPU seconds per design (`time.process_time`, single-threaded BLAS), "
             f"time limit {TIME_LIMIT:g} s per design.  `rel` = (new - base) / base of the objective "
             "(negative: new better).  Produced by `benchmarks/bench_region.py`.", ""]
    data = [json.loads(Path(f).read_text()) for f in files]
    for base, new in zip(data[::2], data[1::2], strict=True):
        obj = base["objective"]
        b = {r["name"]: r for r in base["rows"]}
        nw = {r["name"]: r for r in new["rows"]}
        names = [r["name"] for r in new["rows"]]  # a base run cut short leaves its later rows out
        lines += [f"## objective {obj}", "",
                  f"| plant | n, p | base {obj} | base status | base CPU | new {obj} | new status | "
                  "new CPU | "
                  "rel | speed-up |", "|---|---|---|---|---|---|---|---|---|---|"]
        worse, speed, cb, cn = [], [], [], []
        for k in names:
            rn = nw[k]
            if k not in b:
                lines.append(f"| {k} | {rn['n']}, {rn['p']} | – | – | – | {rn[obj]:.6g} | {rn['status']} | "
                             f"{rn['cpu']:.2f} | | |")
                if rn["n"] <= 10:
                    cn.append(rn["cpu"])
                continue
            rb = b[k]
            vb, vn = rb[obj], rn[obj]
            rel = (vn - vb) / vb if np.isfinite(vb) and np.isfinite(vn) else float("nan")
            if (np.isfinite(rel) and rel > 1e-3) or (np.isfinite(vb) and not np.isfinite(vn)):
                worse.append(k)
            sp = rb["cpu"] / max(rn["cpu"], 1e-9)
            speed.append(sp)
            if rn["n"] <= 10:
                cb.append(rb["cpu"])
                cn.append(rn["cpu"])
            lines.append(f"| {k} | {rn['n']}, {rn['p']} | {vb:.6g} | {rb['status']} | {rb['cpu']:.2f} | "
                         f"{vn:.6g} | "
                         f"{rn['status']} | {rn['cpu']:.2f} | {rel:+.1e} | {sp:.1f}x |")
        lines += ["", f"- median CPU per design at n <= 10: base {np.median(cb):.2f} s ({len(cb)} plants), "
                  "new "
                  f"{np.median(cn):.2f} s ({len(cn)} plants); median speed-up on the plants both ran "
                  f"{np.median(speed):.1f}x",
                  f"- plants more than 1e-3 (relative) worse than base: {len(worse)}"
                  + (f" ({', '.join(worse)})" if worse else ""), ""]
    Path(out).write_text("\n".join(lines) + "\n")


def main() -> None:
    ap = argparse.ArgumentParser()
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("run")
    r.add_argument("code", choices=("new", "base", "prev"))
    r.add_argument("--set", default="subset", choices=("subset", "full"))
    r.add_argument("--objective", default="kappa2", choices=("kappa2", "eta"))
    r.add_argument("--only", default=None)
    r.add_argument("--json", required=True)
    r.add_argument("--route", default=None, help="WellConditionedProblem(route=...) (new code only; "
                   "default: the verb's default)")
    r.add_argument("--inner", action="store_true", help=argparse.SUPPRESS)
    p = sub.add_parser("report")
    p.add_argument("files", nargs="+")
    p.add_argument("--out", default="benchmarks/results/region.md")
    a = ap.parse_args()
    if a.cmd == "report":
        report(a.files, a.out)
        return
    if a.code in DIRS and not a.inner:
        root = DIRS[a.code][1]
        env = {**os.environ, "PYTHONPATH": root}
        args = [sys.executable, __file__, "run", a.code, "--set", a.set, "--objective", a.objective,
                "--json", a.json, "--inner"] + (["--only", a.only] if a.only else [])
        subprocess.run(args, env=env, check=True)
        return
    import optdesign

    expected = DIRS[a.code][1] if a.code in DIRS else str(Path(__file__).resolve().parents[1])
    if not str(Path(optdesign.__file__).resolve()).startswith(expected):
        raise SystemExit(f"imported {optdesign.__file__}, expected a checkout under {expected}")
    route = None if a.code in DIRS else a.route
    run(a.set, a.objective, a.json, a.only, None if route == "default" else route, a.code)


if __name__ == "__main__":
    main()
