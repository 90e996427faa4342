"""Benchmark: the Riccati differential equation (issue 5, seed 004) -- accuracy and time of the
three methods of ``optdesign.riccati_de`` at the same accuracy target, n = 2..50.

For each n, a random plant (seeded; spectral radius ~1, ``p = max(1, n // 4)`` outputs, ``G = I``,
``Q = F F'/n + 0.1 I``, ``R = I``), ``P0 = I``, horizon ``t_final`` (10 s, and 1000 s for a subset):

* ``transition`` -- the exact restarted Hamiltonian transition matrix, 100 output intervals;
* ``ode``        -- ``solve_ivp`` (DOP853 / Radau); the loosest ``tol`` in 10^-2 .. 10^-10 (``rtol =
                    tol / 10^4``) whose measured error meets the target;
* ``bpf``        -- the paper's block-pulse recursion; the smallest ``m = 25 * 2^k`` whose measured
                    error at the block midpoints meets the target (up to m = 8192).

The error is ``max_k ||P_k - P_ref(t_k)||_F / max_k ||P_ref(t_k)||_F`` against the exact flow
recomputed with an 8x shorter base step (``max_norm = 1/16``).  Time: the method's own computation
(``solver_stats.time``: no error estimate, no steady-state solve), median of ``--reps`` runs.

Run:  python benchmarks/bench_riccati_de.py [--quick] [--target 1e-6] [--reps 3]
Writes the markdown table to benchmarks/results/riccati_de.md.
"""

from __future__ import annotations

import os

# single-threaded BLAS: stable timings on a shared machine (OpenBLAS threads oversubscribe it)
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse  # noqa: E402
import platform  # noqa: E402
import statistics  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from optdesign import Plant, riccati_de  # noqa: E402
from optdesign.classical.bpf import filter_hamiltonian, riccati_flow  # noqa: E402
from optdesign.errors import RiccatiError  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "results" / "riccati_de.md"

#: spectral radius of the Hamiltonian after time rescaling (the paper's example has 0.8)
RADIUS = 0.8


def random_plant(rng: np.random.Generator, n: int, radius: float | None = RADIUS) -> Plant:
    """A random observable plant (possibly unstable), with time rescaled so that the Hamiltonian
    of its Riccati DE has spectral radius ``radius`` (None: as drawn)."""
    p = max(1, n // 4)
    while True:
        A = rng.standard_normal((n, n)) / np.sqrt(n)
        C = rng.standard_normal((p, n))
        F = rng.standard_normal((n, n))
        plant = Plant(A, C, Q=F @ F.T / n + 0.1 * np.eye(n), R=np.eye(p))
        if plant.is_observable():
            break
    if radius is None:
        return plant
    M = filter_hamiltonian(plant.A, plant.C, plant.process_noise(), plant.R)
    c = radius / float(np.max(np.abs(np.linalg.eigvals(M))))
    # t -> t / c: A, W and C'R^-1C all scale by c (the equation keeps its form)
    return plant.replace(A=c * plant.A, Q=c * plant.Q, R=plant.R / c)


def rel(P, Pref) -> float:
    return float(np.max(np.linalg.norm(P - Pref, axis=(1, 2))) / np.max(np.linalg.norm(Pref, axis=(1, 2))))


def timed(reps: int, fn):
    out = [fn() for _ in range(reps)]
    return out[0], statistics.median(r.solver_stats.time for r in out)


def bench_one(plant: Plant, tf: float, target: float, reps: int, with_bpf: bool, max_m: int):
    n = plant.n
    P0 = np.eye(n)
    M = filter_hamiltonian(plant.A, plant.C, plant.process_noise(), plant.R)
    t = np.linspace(0.0, tf, 101)
    ref, _ = riccati_flow(M, P0, t, max_norm=1.0 / 16)
    rows = []
    tr, sec = timed(reps, lambda: riccati_de(plant, P0, tf, steps=100, estimate_error=False))
    e = rel(tr.P, ref)
    rows.append(("transition", f"{tr.solver_stats.extra['doublings']} doublings", sec, e, e <= target))
    # ode: loosest tolerance that meets the target
    found = None
    for k in range(2, 11):
        tol = 10.0 ** -k
        od = riccati_de(plant, P0, tf, method="ode", steps=100, tol=tol, estimate_error=False)
        if od.status.is_solved and rel(od.P, ref) <= target:
            found = tol
            break
    if found is None:
        rows.append(("ode", "target not met at tol 1e-10", float("nan"), rel(od.P, ref), False))
    else:
        od, sec = timed(reps, lambda: riccati_de(plant, P0, tf, method="ode", steps=100, tol=found,
                                                 estimate_error=False))
        integ = od.solver_stats.extra["integrator"]
        rows.append(("ode", f"{integ}, tol {found:.0e}, nfev {od.solver_stats.extra['nfev']}", sec,
                     rel(od.P, ref), True))
    if with_bpf:
        m, e = 25, np.inf
        failure = ""
        while m <= max_m:
            try:
                b = riccati_de(plant, P0, tf, method="bpf", steps=m, estimate_error=False)
            except RiccatiError as exc:
                failure = str(exc).split(":")[1].strip()
                break
            exact, _ = riccati_flow(M, P0, b.t, max_norm=1.0 / 16)
            e = rel(b.P, exact)
            if e <= target:
                break
            m *= 2
        if failure:
            rows.append(("bpf", f"m = {m}: RiccatiError ({failure})", float("nan"), float("nan"), False))
            return rows
        if e <= target:
            b, sec = timed(reps, lambda: riccati_de(plant, P0, tf, method="bpf", steps=m,
                                                    estimate_error=False))
            rows.append(("bpf", f"m = {m}", sec, e, True))
        else:
            rows.append(("bpf", f"m = {m // 2}: error {e:.1e}", b.solver_stats.time, e, False))
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="n = 2, 5, 10 only, one repetition")
    ap.add_argument("--target", type=float, default=1e-6, help="relative accuracy target")
    ap.add_argument("--reps", type=int, default=3)
    args = ap.parse_args()
    sizes = (2, 5, 10) if args.quick else (2, 5, 10, 20, 50)
    reps = 1 if args.quick else args.reps
    rng = np.random.default_rng(2026)
    lines = [
        f"# Riccati differential equation: accuracy and time at target {args.target:.0e}",
        "",
        "`python benchmarks/bench_riccati_de.py" + (" --quick" if args.quick else "") + "` -- "
        f"{platform.processor() or platform.machine()}, Python {platform.python_version()}, "
        "single-threaded BLAS.  Random plants (p = max(1, n/4)), time-rescaled so that the Hamiltonian M",
        f"has spectral radius {RADIUS} as in the paper's example (last row: not rescaled), P0 = I, 100",
        "output intervals; error against the exact flow with an 8x shorter base step; time = the",
        f"method's own computation, median of {reps} run(s).",
        "",
        "| n | rho(M) | t_final | method | setting | time [ms] | error | target met |",
        "|---|---|---|---|---|---|---|---|",
    ]
    cases = [(n, 10.0, True, RADIUS) for n in sizes] + [(n, 1000.0, False, RADIUS) for n in (2, 10)]
    cases.append((10, 10.0, True, None))          # not rescaled: Hamiltonian radius ~4.5
    for n, tf, with_bpf, radius in cases:
        plant = random_plant(rng, n, radius)
        M = filter_hamiltonian(plant.A, plant.C, plant.process_noise(), plant.R)
        rho = float(np.max(np.abs(np.linalg.eigvals(M))))
        max_m = 8192 if n <= 20 else 2048
        for method, setting, sec, err, ok in bench_one(plant, tf, args.target, reps, with_bpf, max_m):
            line = (f"| {n} | {rho:.2g} | {tf:g} | {method} | {setting} | {sec * 1e3:.1f} | {err:.1e} | "
                    f"{'yes' if ok else 'NO'} |")
            lines.append(line)
            print(line, flush=True)
    lines += [
        "",
        "Reading: the exact transition method reaches rounding error (1e-13..1e-15) at a cost independent",
        "of the horizon (one exponential and a few doublings, then one O(n^3) restart per output time); the",
        "ODE solver needs a tolerance well below the target and its cost grows with the horizon; the",
        "block-pulse recursion is second order, so a 1e-6 target needs thousands of blocks of 2n x 2n work",
        "each.  bpf is not run on the 1000 s horizon: it inverts a transition matrix taken from t = 0,",
        "whose condition number grows like e^{2 Re(lambda) t}; the last row (Re(lambda) ~ 4.5) shows it",
        "failing at t_final = 10 whatever m.",
    ]
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text("\n".join(lines) + "\n", encoding="utf-8")
    print(f"\nwritten to {RESULTS}")


if __name__ == "__main__":
    main()
