"""CPU time of the well-conditioned verbs with their default settings on small problems (n <= 10).

Issue 11, item 9: the default must keep small problems under 10 s.  Measured with
``time.process_time()`` (CPU seconds of this process: the machine is shared), one design per row,
with the verbs' defaults (``starts=8`` for the observer, ``starts=4`` for the Kalman filter, no
time limit):

1. fixed poles: every problem of ``problems/poleplacement`` that has a diagonalizable answer
   (``allow_unstable=True``: the benchmarks are state-feedback problems), objective kappa2, and
   eta with ``kappa2_max = 1.2 x`` the best kappa2 (the trade-off of the test suite);
2. region mode: the COMPleib plants with ``n <= 10`` in :func:`suggested_region`;
3. random observable plants ``n = 3, 5, 8, 10``, ``p = max(2, n // 4)``, fixed random stable poles
   and a region;
4. ``well_conditioned_kalman`` on seed 001's Example 2 and a random ``n = 4`` plant.

``--profile NAME`` prints where the time of one row goes (cProfile, top 15 by cumulative time).
Run: ``python benchmarks/bench_wc_default_time.py [--quick] [--skip N] [--max-n N] [--out FILE]``; writes
``benchmarks/results/wc_default_time.md`` (not with ``--quick``).  Numbers, not pass/fail.
"""

from __future__ import annotations

# isort: off
from _common import random_observable_plant  # first: single-threaded BLAS before numpy
# isort: on

import argparse
import cProfile
import pstats
import sys
import time
from pathlib import Path

import numpy as np

from optdesign import Plant, problems, well_conditioned_kalman, well_conditioned_observer
from optdesign.design.well_conditioned import suggested_region
from optdesign.regions import Disk, HalfPlane, Sector

HERE = Path(__file__).resolve().parent
LIMIT = 10.0


def _cases(quick: bool):
    """``(group, name, n, p, thunk)`` rows."""
    rows = []
    pp = [n for n in problems.names() if n.startswith("pp_") and n != "pp_chowkokotovic"]
    for name in pp[:3] if quick else pp:
        pr = problems.load(name)
        plant, P = pr.plant, pr.targets["poles"]
        rows.append(("fixed, kappa2", name, plant.n, plant.p,
                     lambda plant=plant, P=P: well_conditioned_observer(plant, poles=P, allow_unstable=True)))
        if np.all(np.asarray(P).real < 0) and name in ("pp_byers3", "pp_byers5", "pp_knv1985_ex1"):
            def tradeoff(plant=plant, P=P):
                k = well_conditioned_observer(plant, poles=P).kappa2
                return well_conditioned_observer(plant, poles=P, objective="eta", kappa2_max=1.2 * k)
            rows.append(("fixed, eta s.t. kappa2 <= 1.2 min (2 designs)", name, plant.n, plant.p, tradeoff))
    cl = [n for n in problems.names() if n.startswith("compleib_")]
    for name in cl:
        plant = problems.load(name).plant
        if plant.n > 10 or (quick and name not in ("compleib_dis2", "compleib_ac17", "compleib_he1")):
            continue
        rows.append(("region (suggested_region)", name, plant.n, plant.p,
                     lambda plant=plant: well_conditioned_observer(plant, region=suggested_region(plant))))
    rng = np.random.default_rng(2024)
    for n in (3, 5) if quick else (3, 5, 8, 10):
        p = max(2, n // 4)
        plant = random_observable_plant(rng, n, p)
        P = -np.sort(rng.uniform(0.5, 4.0, n)).astype(complex)
        rows.append(("fixed, kappa2", f"random n={n}", n, p,
                     lambda plant=plant, P=P: well_conditioned_observer(plant, poles=P)))
        region = HalfPlane(0.5) & Sector.from_damping(0.5) & Disk(0.0, 5.0)
        rows.append(("region (HalfPlane(0.5) & Sector(0.5) & Disk(5))", f"random n={n}", n, p,
                     lambda plant=plant, region=region: well_conditioned_observer(plant, region=region)))
    ex2 = problems.load("jung_huh_ex2").plant
    rows.append(("kalman, eta", "jung_huh_ex2", ex2.n, ex2.p, lambda: well_conditioned_kalman(ex2)))
    A = rng.standard_normal((4, 4))
    A -= (np.max(np.linalg.eigvals(A).real) + 0.3) * np.eye(4)
    kp = Plant(A, rng.standard_normal((2, 4)), G=rng.standard_normal((4, 2)), Q=np.eye(2), R=np.eye(2))
    rows.append(("kalman, kappa2, full Q", "random n=4", 4, 2,
                 lambda: well_conditioned_kalman(kp, objective="kappa2", q_structure="full")))
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="a few rows only")
    ap.add_argument("--profile", metavar="NAME", help="profile the first row whose name contains NAME")
    ap.add_argument("--skip", type=int, default=0, help="skip the first SKIP rows (resume a long run)")
    ap.add_argument("--max-n", type=int, default=10, help="only problems with n <= MAX_N")
    ap.add_argument("--out", default=str(HERE / "results" / "wc_default_time.md"), help="result file")
    args = ap.parse_args(argv)
    rows = [r for r in _cases(args.quick)[args.skip:] if r[2] <= args.max_n]
    if args.profile:
        group, name, n, p, fn = next(r for r in rows if args.profile in r[1])
        prof = cProfile.Profile()
        prof.runcall(fn)
        pstats.Stats(prof).sort_stats("cumulative").print_stats(15)
        return 0
    lines = ["| mode | problem | n | p | status | kappa2 | starts run | CPU s |",
             "|---|---|---|---|---|---|---|---|"]
    over = []
    for group, name, n, p, fn in rows:
        t0 = time.process_time()
        d = fn()
        cpu = time.process_time() - t0
        if cpu > LIMIT:
            over.append((name, group, cpu))
        lines.append(f"| {group} | {name} | {n} | {p} | {d.status} | {d.kappa2:.6g} | {len(d.starts)} | "
                     f"{cpu:.2f} |")
        print(lines[-1], flush=True)
    total = sum(float(ln.rsplit("|", 2)[1]) for ln in lines[2:])
    summary = (f"\n{len(rows)} designs, {total:.1f} CPU s in all; over {LIMIT:g} s: "
               + (", ".join(f"{nm} ({g}, {c:.1f} s)" for nm, g, c in over) if over else "none"))
    print(summary)
    if not args.quick:
        out = Path(args.out)
        out.write_text("# Well-conditioned verbs, default settings, n <= 10 (CPU seconds)\n\n"
                       f"`python benchmarks/bench_wc_default_time.py` (python {sys.version.split()[0]}, "
                       "single-threaded BLAS, shared 2-core machine)\n\n" + "\n".join(lines) + "\n"
                       + summary + "\n")
        print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
