"""Benchmark: the doubling DARE solver of the closest-poles search against scipy's QZ solver.

``optdesign.classical.riccati.filter_dare_doubling`` (structure-preserving doubling,
Chu, Fan, Lin & Wang 2004) is the first solver tried in ``fast_pole_error``, the inner loop of the
Nelder-Mead closest-poles search (thousands of filter DAREs per infeasible discrete target);
``scipy.linalg.solve_discrete_are(balanced=False)`` decides when it does not converge or ends at a
solution that is not stabilizing.  This script keeps that choice honest:

* CPU per solve (``time.process_time``, median of ``--reps`` batches, single-threaded BLAS) of
  both, on random discrete plants n = 2..10, p = 1, 2, Q = F F' over ten decades of scale and
  singular diagonal Q (half its entries zero, so (A, Q) need not be detectable);
* agreement: the largest relative difference of P where both return the stabilizing solution,
  each one's relative DARE residual, and how often the doubling hands over to scipy.

Run:  python benchmarks/bench_dare_doubling.py [--cases 100] [--reps 5]
Writes benchmarks/results/dare_doubling.md.
"""

from __future__ import annotations

import argparse
import platform
import statistics
import time
from pathlib import Path

import _common  # noqa: F401  (single-threaded BLAS before numpy)
import numpy as np
from scipy.linalg import solve_discrete_are

from optdesign import Plant
from optdesign.classical.riccati import filter_are_residual, filter_dare_doubling, filter_gain

RESULTS = Path(__file__).resolve().parent / "results" / "dare_doubling.md"


def cases(rng: np.random.Generator, n: int, p: int, count: int) -> list:
    out = []
    for s in range(count):
        A = rng.standard_normal((n, n))
        A = rng.uniform(0.3, 1.5) * A / np.max(np.abs(np.linalg.eigvals(A)))
        C = rng.standard_normal((p, n))
        if s % 3:
            F = rng.standard_normal((n, n)) * np.exp(rng.uniform(-11.5, 11.5) / 2)
            Q = F @ F.T
        else:
            Q = np.diag(rng.uniform(0.0, 1.0, n) * (rng.uniform(size=n) > 0.5))
        out.append((A, C, Q, np.eye(p)))
    return out


def stabilizing(A, C, R, P) -> bool:
    return bool(np.max(np.abs(np.linalg.eigvals(A - filter_gain(A, C, R, P, True) @ C))) < 1.0)


def residual(A, C, Q, R, P) -> float:
    """The library's relative residual (``filter_are_residual``: ``||Res||_F`` over the sum of the
    terms' norms)."""
    return filter_are_residual(Plant(A, C, R=R, dt=1.0), P, Qs=Q)


def cpu_per_solve(fn, batch: list, reps: int) -> float:
    times = []
    for _ in range(reps):
        t0 = time.process_time()
        for A, C, Q, R in batch:
            try:
                fn(A, C, Q, R)
            except (np.linalg.LinAlgError, ValueError):
                pass
        times.append((time.process_time() - t0) / len(batch))
    return statistics.median(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=int, default=100)
    ap.add_argument("--reps", type=int, default=5)
    args = ap.parse_args()
    rng = np.random.default_rng(20261207)

    def scipy_dare(A, C, Q, R):
        return solve_discrete_are(A.T, C.T, Q, R, balanced=False)

    rows = []
    for n in (2, 3, 4, 6, 10):
        for p in (1, 2):
            batch = cases(rng, n, p, args.cases)
            t_scipy = cpu_per_solve(scipy_dare, batch, args.reps)
            t_sda = cpu_per_solve(filter_dare_doubling, batch, args.reps)
            diff, res_s, res_d, handed = 0.0, 0.0, 0.0, 0
            for A, C, Q, R in batch:
                Pd = filter_dare_doubling(A, C, Q, R)
                if Pd is None or not stabilizing(A, C, R, Pd):
                    handed += 1
                    continue
                try:
                    Ps = scipy_dare(A, C, Q, R)
                except (np.linalg.LinAlgError, ValueError):
                    continue
                if not stabilizing(A, C, R, Ps):
                    continue
                diff = max(diff, float(np.abs(Ps - Pd).max() / max(1.0, np.abs(Ps).max())))
                if not np.any(Q):  # P = 0: a relative residual of rounding-size entries means nothing
                    continue
                res_s = max(res_s, residual(A, C, Q, R, Ps))
                res_d = max(res_d, residual(A, C, Q, R, Pd))
            rows.append((n, p, t_scipy * 1e6, t_sda * 1e6, t_scipy / t_sda, diff, res_s, res_d, handed))
            print(rows[-1], flush=True)
    lines = [
        "# Doubling DARE solver vs scipy.linalg.solve_discrete_are",
        "",
        f"`benchmarks/bench_dare_doubling.py --cases {args.cases} --reps {args.reps}`; "
        f"{platform.processor() or platform.machine()}, Python {platform.python_version()}, numpy "
        f"{np.__version__}; CPU per solve (median of {args.reps} batches of {args.cases} plants), "
        "single-threaded BLAS.  *max rel diff*: largest |P_scipy - P_doubling| / max(1, |P_scipy|) "
        "where both are stabilizing; *residual*: each one's largest relative DARE residual there "
        "(`filter_are_residual`: the residual's Frobenius norm over the sum of the terms'; not at Q = 0, "
        "where P = 0 and scipy returns entries of 1e-16, a relative residual of 0.15-0.8); "
        "*handed over*: plants where the doubling did not converge or ended at a non-stabilizing "
        "solution (scipy decides those in `fast_pole_error`).",
        "",
        "| n | p | scipy us | doubling us | ratio | max rel diff | residual scipy | residual doubling "
        "| handed over |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for n, p, ts, td, r, d, rs, rd, h in rows:
        lines.append(f"| {n} | {p} | {ts:.0f} | {td:.0f} | {r:.2f}x | {d:.1e} | {rs:.1e} | {rd:.1e} "
                     f"| {h} / {args.cases} |")
    RESULTS.write_text("\n".join(lines) + "\n")
    print(f"wrote {RESULTS}")


if __name__ == "__main__":
    main()
