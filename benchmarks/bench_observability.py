"""Benchmark: observability checks at scale (issue 11, item 8) -- ``Plant.unobservable_modes`` against
the Riccati solve it guards, and the whole ``kalman`` verb, for single-output plants n = 50..400.

Columns (CPU seconds, ``time.process_time``, median of ``--reps`` runs, single-threaded BLAS):

* ``staircase (before)`` -- the previous implementation, kept here as the reference: the same
  orthogonal staircase, but every step multiplied the full n x n matrix by a dense n x n
  transformation (O(n^4) for p = 1) and nothing was kept between calls;
* ``staircase (now)``   -- ``Plant.unobservable_modes`` (Householder reflectors applied to the rows
  and columns each step changes, O(n^3)), first call on a fresh plant (no cached answer);
* ``python-control``    -- ``numpy.linalg.matrix_rank(control.obsv(A, C))``, the usual peer check,
  with the rank it finds (an observable plant has rank n: at this scale the observability matrix
  is numerically singular and the rank test gives a wrong answer);
* ``scipy CARE``        -- ``scipy.linalg.solve_continuous_are`` alone;
* ``kalman (before/now)`` -- ``optdesign.kalman(plant)`` (solve, cross-check with the Hamiltonian
  solver, verification) with the previous staircase patched in / as it is now.

Plants: ``A = N(0, 1/n) - 1.5 I`` (stable), ``C ~ N(0, 1)`` (1 x n), ``Q = I``, ``R = 1``.  (Which
modes the staircase finds is tested in tests/test_plant.py; here: time only.)

Run:  python benchmarks/bench_observability.py [--sizes 50 100 200 400] [--reps 3]
Writes the markdown table to benchmarks/results/observability.md (observability_prescott.md when run
with OPENBLAS_CORETYPE=Prescott, the generic kernel of another CPU).
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse  # noqa: E402
import platform  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import scipy.linalg  # noqa: E402

import optdesign as od  # noqa: E402
from optdesign import Plant  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "results" / "observability.md"


def dense_staircase(plant: Plant, tol: float | None = None) -> np.ndarray:
    """The implementation before issue 11 (reference for the 'before' columns)."""
    from scipy.linalg import matrix_balance

    n = plant.n
    tol = (1e3 * n * np.finfo(float).eps) if tol is None else float(tol)
    _, (s, _) = matrix_balance(plant.A, permute=False, separate=True)
    Ab = (plant.A * s[None, :]) / s[:, None]
    Cb = plant.C * s[None, :]
    na = max(float(np.linalg.norm(Ab, 1)), 1.0)
    nc = float(np.linalg.norm(Cb, 1))
    if nc == 0.0:
        return np.linalg.eigvals(plant.A).astype(complex)
    Cb = Cb * (na / nc)
    atol = tol * na
    F = Ab.T.copy()
    block = Cb.T
    k = 0
    while True:
        U, sv, _ = np.linalg.svd(block, full_matrices=True)
        r = int(np.sum(sv > atol))
        if r == 0:
            break
        if k + r == n:
            return np.zeros(0, dtype=complex)
        T = np.eye(n)
        T[k:, k:] = U
        F = T.T @ F @ T
        block = F[k + r:, k:k + r]
        k += r
    return np.linalg.eigvals(F[k:, k:]).astype(complex)


def cpu(reps: int, fn):
    out, times = None, []
    for _ in range(reps):
        t = time.process_time()
        out = fn()
        times.append(time.process_time() - t)
    return out, statistics.median(times)


def random_plant(n: int, seed: int = 0) -> Plant:
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n, n)) / np.sqrt(n) - 1.5 * np.eye(n)
    return Plant(A, rng.standard_normal((1, n)), Q=np.eye(n), R=[[1.0]])


def fresh(plant: Plant) -> Plant:
    return plant.replace()  # a new plant: no cached staircase


def bench(n: int, reps: int) -> dict[str, object]:
    plant = random_plant(n)
    A, C = plant.A, plant.C
    _, t_old = cpu(reps, lambda: dense_staircase(plant))
    modes, t_new = cpu(reps, lambda: fresh(plant).unobservable_modes())
    plant.unobservable_modes()
    _, t_cached = cpu(reps, lambda: plant.unobservable_modes())  # the second call of kalman()
    try:
        import control

        rank, t_ctrl = cpu(reps, lambda: int(np.linalg.matrix_rank(control.obsv(A, C))))
    except ImportError:  # pragma: no cover
        rank, t_ctrl = -1, float("nan")
    _, t_care = cpu(reps, lambda: scipy.linalg.solve_continuous_are(A.T, C.T, np.eye(n), np.eye(1)))
    kf, t_kal = cpu(reps, lambda: od.kalman(fresh(plant)))
    original = Plant.unobservable_modes
    try:
        Plant.unobservable_modes = dense_staircase  # type: ignore[method-assign]
        _, t_kal_old = cpu(reps, lambda: od.kalman(fresh(plant)))
    finally:
        Plant.unobservable_modes = original  # type: ignore[method-assign]
    return dict(n=n, old=t_old, new=t_new, cached=t_cached, rank=rank, ctrl=t_ctrl, care=t_care, kal=t_kal,
                kal_old=t_kal_old, ok=kf.success, modes=modes.size)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[50, 100, 200, 400])
    ap.add_argument("--reps", type=int, default=3)
    args = ap.parse_args()
    core = os.environ.get("OPENBLAS_CORETYPE", "native")
    head = ("| n | staircase (before) | staircase (now) | ratio | now / CARE | python-control rank (time) "
            "| scipy CARE | kalman before | kalman now | ratio |")
    lines = [f"Observability checks, p = 1, CPU seconds (median of {args.reps}); "
             f"{platform.processor() or platform.machine()}, OpenBLAS core {core}.", "", head,
             "|" + "---|" * (head.count("|") - 1)]
    print(lines[0])
    for n in args.sizes:
        r = bench(n, args.reps)
        row = (f"| {n} | {r['old']:.3f} | {r['new']:.4f} (cached {r['cached']:.1e}) | "
               f"{r['old'] / r['new']:.0f}x | {r['new'] / r['care']:.3f} | {r['rank']} ({r['ctrl']:.3f}) | "
               f"{r['care']:.3f} | {r['kal_old']:.3f} | {r['kal']:.3f} | {r['kal_old'] / r['kal']:.2f}x |")
        print(row, "" if r["ok"] else "(kalman not verified)", flush=True)
        lines.append(row)
    lines += ["", "ratio = before / now.  `now / CARE`: the observability check costs this fraction of the "
              "Riccati solve it guards.  The python-control rank of an observable plant should be n."]
    RESULTS.parent.mkdir(exist_ok=True)
    suffix = "" if core == "native" else f"_{core.lower()}"
    out = RESULTS.with_name(f"observability{suffix}.md")
    out.write_text("\n".join(lines) + "\n")
    print(f"written to {out}")


if __name__ == "__main__":
    main()
