"""Independent re-checks of reported successes (issue 26's acceptance sweep).

Part A: random region designs, n = 3..10 (``well_conditioned_observer(plant, region=...)``, kappa2):
for every returned gain (any status: a ``time_limit`` answer is the best design so far), kappa2 of the returned gain recomputed with numpy (the unit-column
eigenvector matrix of ``A - L C``) and with ``optdesign.metrics.kappa2``, and the poles tested against the
region; counted: reported kappa2 that differs from the recomputed one beyond the agreement of two
computations of it, and poles outside the region.

Part B: random polytopes of plants (``robust_observer(ModelSet.polytope(...), region=...)``): for every
reported success, 200 random interior plants (Dirichlet weights) with their poles tested against the region.

Run:  python benchmarks/sweep_honesty.py [--designs 50] [--polytopes 20] [--time-limit 60]
Writes benchmarks/results/honesty_sweep.md.  Numbers, not pass/fail.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import _common  # noqa: F401  (single-threaded BLAS before numpy)
import numpy as np

import optdesign as od
from optdesign.analysis import metrics
from optdesign.design.verification import eigen_spread, kappa2_agreement_tol
from optdesign.model.model_set import ModelSet
from optdesign.regions import Disk, HalfPlane, Sector

EPS = float(np.finfo(float).eps)


def random_plant(rng: np.random.Generator, n: int, p: int) -> od.Plant:
    while True:
        plant = od.Plant(rng.standard_normal((n, n)), rng.standard_normal((p, n)))
        if plant.is_observable():
            return plant


def numpy_kappa2(X: np.ndarray) -> float:
    _, V = np.linalg.eig(X)
    return float(np.linalg.cond(V / np.linalg.norm(V, axis=0)))


def part_a(rng: np.random.Generator, count: int, time_limit: float) -> tuple[list[str], dict]:
    rows, tally = [], {"designs": 0, "success": 0, "checked": 0, "kappa2_differs": 0, "outside": 0}
    for i in range(count):
        n = int(rng.integers(3, 11))
        p = int(rng.integers(1, min(3, n - 1) + 1))
        plant = random_plant(rng, n, p)
        region = HalfPlane(float(rng.uniform(0.2, 1.0))) & Sector.from_damping(float(rng.uniform(0.3, 0.8))) \
            & Disk(0.0, float(rng.uniform(5.0, 20.0)))
        t0 = time.process_time()
        res = od.well_conditioned_observer(plant, region=region, time_limit=time_limit)
        cpu = time.process_time() - t0
        tally["designs"] += 1
        verdict = "-"
        tally["success"] += bool(res.success)
        has_gain = res.L is not None and bool(np.all(np.isfinite(res.L))) and np.isfinite(res.kappa2)
        if has_gain:  # every returned design, not only the successes: its reported kappa2 must be its own
            tally["checked"] += 1
            X = plant.A - res.L @ plant.C
            ev = np.linalg.eigvals(X)
            k_np, k_od = numpy_kappa2(X), metrics.kappa2(X)
            tol = kappa2_agreement_tol(max(k_np, 1.0), eigen_spread(X, ev))
            differs = not (abs(res.kappa2 - k_np) <= tol * max(1.0, k_np)
                           and abs(res.kappa2 - k_od) <= tol * max(1.0, k_od))
            outside = not region.contains(ev, tol=100 * EPS * max(1.0, float(np.linalg.norm(X))))
            tally["kappa2_differs"] += differs
            tally["outside"] += outside and bool(res.success)
            verdict = ("kappa2 DIFFERS " if differs else "") + ("OUTSIDE" if outside else "") or "ok"
        route = res.route.answered.name if getattr(res, "route", None) and res.route.answered else ""
        rows.append(f"| {i} | {n}, {p} | {res.status.value} | {res.kappa2:.6g} | {cpu:.2f} | {route} | {verdict} |")
        print(rows[-1], flush=True)
    return rows, tally


def part_b(rng: np.random.Generator, count: int, time_limit: float) -> tuple[list[str], dict]:
    rows, tally = [], {"polytopes": 0, "success": 0, "success_with_outside": 0}
    for i in range(count):
        n = int(rng.integers(2, 6))
        p = int(rng.integers(1, min(2, n - 1) + 1))
        nominal = random_plant(rng, n, p)
        verts = []
        for _ in range(int(rng.integers(2, 5))):
            dA = 0.2 * rng.standard_normal((n, n))
            verts.append(od.Plant(nominal.A + dA, nominal.C))
        models = ModelSet.polytope(verts)
        region = HalfPlane(float(rng.uniform(0.1, 0.6))) & Disk(0.0, 30.0)
        t0 = time.process_time()
        res = od.robust_observer(models, region=region, time_limit=time_limit)
        cpu = time.process_time() - t0
        tally["polytopes"] += 1
        outside = 0
        if res.success:
            tally["success"] += 1
            for plant in models.interior_points(200, rng=i):
                ev = np.linalg.eigvals(plant.A - res.L @ plant.C)
                outside += not region.contains(ev, tol=1e-9 * max(1.0, float(np.max(np.abs(ev)))))
            tally["success_with_outside"] += outside > 0
        rows.append(f"| {i} | {n}, {p}, {len(verts)} | {res.status.value} | {cpu:.2f} | {outside} |")
        print(rows[-1], flush=True)
    return rows, tally


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--designs", type=int, default=50)
    ap.add_argument("--polytopes", type=int, default=20)
    ap.add_argument("--time-limit", type=float, default=60.0)
    ap.add_argument("--seed", type=int, default=26)
    ap.add_argument("--out", type=Path, default=Path(__file__).parent / "results" / "honesty_sweep.md")
    args = ap.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    rows_a, ta = part_a(rng, args.designs, args.time_limit)
    rows_b, tb = part_b(rng, args.polytopes, args.time_limit)
    text = ["# Reported successes re-checked independently (`benchmarks/sweep_honesty.py`)", "",
            f"Seed {args.seed}; time_limit {args.time_limit} s per design; CPU = `time.process_time`.", "",
            f"**Region designs**: {ta['designs']} designs, {ta['success']} successes; of the "
            f"{ta['checked']} that returned a gain (any status), {ta['kappa2_differs']} with a reported kappa2 "
            f"that differs from the recomputed one; {ta['outside']} successes with poles outside the region.", "",
            "| # | n, p | status | kappa2 | CPU s | route | re-check |", "|---|---|---|---|---|---|---|", *rows_a, "",
            f"**Polytopes**: {tb['polytopes']} polytopes, {tb['success']} successes, "
            f"{tb['success_with_outside']} successes with an interior plant (of 200) outside the region.", "",
            "| # | n, p, vertices | status | CPU s | interior plants outside |", "|---|---|---|---|---|", *rows_b, ""]
    args.out.write_text("\n".join(text))
    print(f"A: {ta}\nB: {tb}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
