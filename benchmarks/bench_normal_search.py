"""The normal-closed-loop search: our Levenberg-Marquardt loop against MINPACK's (scipy's
``least_squares(method="lm")``) on the same residual, starts and budgets (issue 29 item 5).

Both run inside :func:`optdesign.design.well_conditioned.normal_probe.normal_closed_loop` (the library's
independent acceptance of each gain); only the per-start solve differs.  Cases: random constructed plants
(a normal in-region closed loop exists by construction, as in ``tests/test_normal_probe.py``), n = 3..6,
and the region sweep's grid point 288 (COMPleib DIS2, the pool designer's probe).  Printed: how many
cases each finds, CPU (``time.process_time``), the ratio.

Run:  python benchmarks/bench_normal_search.py [--cases 40] [--out benchmarks/results/normal_search.md]
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import _common  # noqa: F401  (single-threaded BLAS before numpy)
import numpy as np
import scipy.optimize

import optdesign.engines.normal_search as ns
from optdesign.design.well_conditioned.normal_probe import normal_closed_loop
from optdesign.regions import Disk, HalfPlane, Sector

_EPS = float(np.finfo(float).eps)


def minpack_solve_layout(G1, G2, region, layout, M0, lam0, delta, iters, tol):
    """The same contract as ``normal_search._solve_layout``, by MINPACK's LM (forward differences; the
    residual padded with zeros to at least the unknowns, as MINPACK needs; the same Jacobian budget)."""
    k = M0.shape[1]
    x0 = np.concatenate([M0.ravel(), lam0])
    iu = np.triu_indices(k)

    def fun(x):
        r = ns._gram_residual(G1, G2, region, layout, iu, x, delta)[0]
        return r if r.size >= x.size else np.concatenate([r, np.zeros(x.size - r.size)])

    if np.linalg.norm(fun(x0)) > tol:
        x0 = scipy.optimize.least_squares(fun, x0, method="lm", ftol=4 * _EPS, xtol=4 * _EPS, gtol=4 * _EPS,
                                          max_nfev=iters * (x0.size + 2)).x
    r, M, Lam = ns._gram_residual(G1, G2, region, layout, iu, x0, delta)
    res = float(np.linalg.norm(r))
    return res <= tol, res, M, Lam


def constructed(n, p, seed, region):
    """``A = F + L C`` with ``F`` normal, its poles in the region (tests/test_normal_probe.py)."""
    rng = np.random.default_rng(seed)
    U = np.linalg.qr(rng.standard_normal((n, n)))[0]
    z = region.sample_poles(2, rng=rng, n_real=0)
    reals = region.sample_poles(n - 2, rng=rng, n_real=n - 2).real
    Lam = np.zeros((n, n))
    Lam[:2, :2] = [[z[0].real, abs(z[0].imag)], [-abs(z[0].imag), z[0].real]]
    Lam[2:, 2:] = np.diag(reals)
    C = rng.standard_normal((p, n))
    return U @ Lam @ U.T + rng.standard_normal((n, p)) @ C, C


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=int, default=40)
    ap.add_argument("--out", type=Path, default=Path(__file__).parent / "results" / "normal_search.md")
    args = ap.parse_args(argv)
    region = HalfPlane(1.0) & Sector.from_damping(0.5) & Disk(0.0, 20.0)
    cases = []
    for seed in range(args.cases):
        rng = np.random.default_rng(seed)
        n = int(rng.integers(3, 7))
        p = int(rng.integers(max(1, (n + 1) // 2), n))
        if ns.normal_freedom(n, p) >= 0:
            cases.append((n, p, seed))
    from optdesign import problems
    dis2 = problems.load("compleib_dis2").plant
    # grid point 288 of bench_sweep_grid.py: alpha 1.205, damping 0.521, radius 20
    alpha, zeta = np.linspace(0.5, 3.0, 40)[11], np.linspace(0.9, 0.2, 25)[288 % 25]
    r288 = HalfPlane(alpha) & Sector.from_damping(zeta) & Disk(0.0, 20.0)
    ours = ns._solve_layout
    rows = []
    for label, solve in (("ours (hand-written LM)", ours), ("scipy least_squares lm (MINPACK)", minpack_solve_layout)):
        ns._solve_layout = solve
        try:
            found, t0 = 0, time.process_time()
            for n, p, seed in cases:
                A, C = constructed(n, p, seed, region)
                found += normal_closed_loop(A, C, region, seed=seed, random_starts=8) is not None
            cpu = time.process_time() - t0
            t0 = time.process_time()
            L288 = normal_closed_loop(dis2.A, dis2.C, r288, seed=0, random_starts=4)
            cpu288 = time.process_time() - t0
        finally:
            ns._solve_layout = ours
        rows.append((label, found, cpu, L288 is not None, cpu288))
        print(f"{label:34s} found {found}/{len(cases)}  CPU {cpu:.2f} s | DIS2 point 288: "
              f"{'found' if L288 is not None else 'not found'} ({cpu288:.2f} s)", flush=True)
    ratio = rows[1][2] / rows[0][2] if rows[0][2] > 0 else math.nan
    print(f"CPU ratio scipy / ours: {ratio:.2f}")
    lines = ["# Normal-closed-loop search: our LM loop vs MINPACK (`bench_normal_search.py`)", "",
             f"{len(cases)} constructed cases (n = 3..6, a normal in-region closed loop exists), 8 random starts "
             "per layout; DIS2 grid point 288 (4 random starts). CPU: `time.process_time`, single-threaded BLAS.",
             "", "| solve | constructed found | CPU s | DIS2 point 288 | CPU s |", "|---|---|---|---|---|"]
    lines += [f"| {a} | {b}/{len(cases)} | {c:.2f} | {'found' if d else 'not found'} | {e:.2f} |"
              for a, b, c, d, e in rows]
    lines += ["", f"CPU ratio MINPACK / ours on the constructed cases: {ratio:.2f}.", ""]
    args.out.write_text("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
