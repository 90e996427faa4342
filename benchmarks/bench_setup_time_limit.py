"""Does set-up work count against ``time_limit`` at large n?  (issue 26, item 5)

For ``kalman``, ``kalman_for_poles``, ``is_kalman_optimal`` and ``well_conditioned_observer``
(fixed poles and region) on a random plant ``A = randn(n, n) / sqrt(n) - 2 I`` (stable), ``C =
randn(p, n)``, ``G = randn(n, 2)``, ``Q = I``, ``R = I`` (a small Q: the plant's own validation stays
cheap), each call with ``time_limit`` is timed (wall and
CPU) and its status (or typed error) printed; ``--profile`` adds the cumulative top of cProfile.

Usage::

    OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 flock /tmp/bench.lock \
        python benchmarks/bench_setup_time_limit.py --n 5000 --p 3 --time-limit 5 [--verbs kalman,...]

``--calibrate`` measures (CPU, one core) the LAPACK calls the up-front refusals estimate and prints
their coefficients ``c`` with ``seconds = c n^3 / FLOPS_PER_SECOND`` (n^4 for the resolvents):
the source of ``optdesign._deadline.DENSE_N3`` / ``DENSE_N4``.  Results:
``benchmarks/results/setup_time_limit.md``.
"""

from __future__ import annotations

import argparse
import cProfile
import io
import pathlib
import pstats
import sys
import time
from functools import partial

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))  # this checkout's optdesign

import numpy as np  # noqa: E402

import optdesign as od  # noqa: E402
from optdesign import Plant  # noqa: E402


def plant_of(n: int, p: int, seed: int = 0) -> Plant:
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n, n)) / np.sqrt(n) - 2.0 * np.eye(n)
    C = rng.standard_normal((p, n))
    return Plant(A, C, G=rng.standard_normal((n, 2)), Q=np.eye(2), R=np.eye(p))


def calls(plant: Plant, tl: float):
    n, p = plant.n, plant.p
    poles = -2.0 - np.arange(n) / n   # trace(A) = -2 n: the trace test does not answer first
    L = 1e-3 * np.ones((n, p))   # a stabilizing gain (A - 2 I is stable): the question is the set-up's time
    return {
        "kalman": lambda: od.kalman(plant, time_limit=tl),
        "kalman_for_poles": lambda: od.kalman_for_poles(plant, poles, time_limit=tl),
        "is_kalman_optimal": lambda: od.is_kalman_optimal(plant, L, time_limit=tl),
        "wco_poles": lambda: od.well_conditioned_observer(plant, poles=poles, time_limit=tl),
        "wco_region": lambda: od.well_conditioned_observer(
            plant, region=od.regions.HalfPlane(1.0) & od.regions.Disk(0.0, 10.0), time_limit=tl),
    }


def _lapack_calls(A, C) -> dict:
    """The calls of ``DENSE_N3`` on (A, C), as closures."""
    import scipy.linalg as sl

    n = A.shape[0]
    H = np.block([[A, -C.T @ C], [-np.eye(n), -A.T]])
    return {"eigvals": partial(np.linalg.eigvals, A), "eig": partial(np.linalg.eig, A),
            "schur": partial(sl.schur, A),
            "lyapunov": partial(sl.solve_continuous_lyapunov, A, -np.eye(n)),
            "hamiltonian_schur": partial(sl.schur, H),
            "care_qz": partial(sl.solve_continuous_are, A.T, C.T, np.eye(n), np.eye(C.shape[0]))}


def calibrate() -> None:
    """The coefficients of ``optdesign._deadline.DENSE_N3`` / ``DENSE_N4`` on this machine."""
    from optdesign._deadline import DENSE_N3, DENSE_N4, FLOPS_PER_SECOND
    from optdesign.formulate.inverse_kalman import spectral_terms

    def cpu(f) -> float:
        c = time.process_time()
        f()
        return time.process_time() - c

    rng = np.random.default_rng(0)
    for n in (200, 400):
        A = rng.standard_normal((n, n)) / np.sqrt(n) - 2.0 * np.eye(n)
        C = rng.standard_normal((3, n))
        runs = _lapack_calls(A, C)
        print(f"n = {n}: " + ", ".join(f"{k} {cpu(f) * FLOPS_PER_SECOND / n**3:.1f} (used {DENSE_N3[k]:g})"
                                       for k, f in runs.items()))
    for n in (100, 200, 300):
        A = rng.standard_normal((n, n)) / np.sqrt(n) - 2.0 * np.eye(n)
        C = rng.standard_normal((3, n))
        t = cpu(partial(spectral_terms, A, C, -2.0 - np.arange(n) / n, None))
        used = DENSE_N4["resolvents"]
        print(f"n = {n}: resolvents {t * FLOPS_PER_SECOND / n**4:.2f} per n^4 (used {used:g})")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=5000)
    ap.add_argument("--p", type=int, default=3)
    ap.add_argument("--time-limit", type=float, default=5.0)
    ap.add_argument("--verbs", default="kalman,kalman_for_poles,is_kalman_optimal,wco_poles,wco_region")
    ap.add_argument("--profile", action="store_true")
    ap.add_argument("--calibrate", action="store_true")
    args = ap.parse_args()
    if args.calibrate:
        calibrate()
        return
    tic = time.perf_counter()
    plant = plant_of(args.n, args.p)
    print(f"n = {args.n}, p = {args.p}, time_limit = {args.time_limit:g} s (plant built in "
          f"{time.perf_counter() - tic:.2f} s)", flush=True)
    table = calls(plant, args.time_limit)
    for name in args.verbs.split(","):
        prof = cProfile.Profile() if args.profile else None
        w0, c0 = time.perf_counter(), time.process_time()
        try:
            if prof:
                prof.enable()
            res = table[name]()
            out = f"status {res.status.value}: {res.message[:200]}"
        except Exception as exc:  # noqa: BLE001 - a benchmark reports every outcome
            out = f"{type(exc).__name__}: {str(exc)[:200]}"
        finally:
            if prof:
                prof.disable()
        wall, cpu = time.perf_counter() - w0, time.process_time() - c0
        print(f"{name:18s} wall {wall:7.2f} s  cpu {cpu:7.2f} s  ratio {wall / args.time_limit:5.2f}  "
              f"{out}", flush=True)
        if prof:
            s = io.StringIO()
            pstats.Stats(prof, stream=s).sort_stats("cumulative").print_stats(30)
            print(s.getvalue())


if __name__ == "__main__":
    main()
