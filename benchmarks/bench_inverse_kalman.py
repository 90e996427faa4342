"""Benchmark: Kalman filter with prescribed poles (issue 3) -- time per design and accuracy vs n.

For each n (2..40), a few random feasible targets (the poles of the Kalman filter of a random
plant with a random Q >= 0, continuous time) are solved by every method / backend that applies:

* ``sdp/clarabel``, ``sdp/scs``  -- one output (L fixed by the poles), SDP + face polish;
* ``nlp/ipopt``                  -- the spectral-identity NLP, with 1, 2 and max(2, n // 5) outputs;
* ``sequential``                 -- Solheim's method (one output); it succeeds only when every step
                                    keeps Q >= 0, so its success rate is part of the result.

Reported per (method, p, n): median wall time per design (validation, solve, polish and the
independent verification included), successes, and the median / worst pole error of an
independent Riccati solve with the returned Q (``are_resolve_poles``), next to the rounding floor
of the target poles themselves (single-output pole placement is exponentially ill-conditioned in
n, so no method can be checked below that floor).

Run:  python benchmarks/bench_inverse_kalman.py [--quick] [--reps 3] [--sizes 2,5,10,20,30]
Writes the markdown table to benchmarks/results/inverse_kalman.md (not with --quick).  The
targets are drawn in sequence from one generator over all sizes 2..40, so a --sizes subset
gets the same targets as the full run.
"""

from __future__ import annotations

# isort: off
from _common import random_observable_plant  # first: single-threaded BLAS before numpy
# isort: on

import argparse  # noqa: E402
import platform  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from optdesign import Plant, kalman_for_poles  # noqa: E402
from optdesign.classical.riccati import filter_are  # noqa: E402
from optdesign.errors import OptDesignError  # noqa: E402
from optdesign.metrics import eigenvalue_rounding_floor  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "results" / "inverse_kalman.md"


def random_target(rng: np.random.Generator, n: int, p: int, tries: int = 50):
    """A random observable plant (spectral radius ~1) and the poles of a random Kalman filter,
    or None when no draw gives a Riccati equation scipy can solve (single-output plants of
    order 30-40 are numerically unobservable: their filter ARE has no accurate solution)."""
    for _ in range(tries):
        plant = random_observable_plant(rng, n, p, noise=True)
        F = rng.standard_normal((n, n)) / np.sqrt(n)
        try:
            are = filter_are(plant.replace(Q=F @ F.T), residual_tol=1e-6)
        except OptDesignError:
            continue
        return plant, are
    return None


def run(method: str, solver: str | None, plant: Plant, poles) -> dict:
    t0 = time.perf_counter()
    res = kalman_for_poles(plant, poles, method=method, solver=solver)
    elapsed = time.perf_counter() - t0
    err = res.verification["are_resolve_poles"].value if "are_resolve_poles" in res.verification else np.inf
    return {"time": elapsed, "success": res.success, "err": err, "status": res.status.value}


def main() -> str:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="n up to 10, one repetition")
    ap.add_argument("--reps", type=int, default=3, help="targets per (p, n)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--sizes", type=str, default=None,
                    help="comma-separated subset of 2,5,10,20,30,40 to run (same targets as the full run)")
    args = ap.parse_args()
    all_sizes = [2, 5, 10] if args.quick else [2, 5, 10, 20, 30, 40]
    sizes = all_sizes if args.sizes is None else sorted({int(v) for v in args.sizes.split(",")})
    if not set(sizes) <= set(all_sizes):
        ap.error(f"--sizes must be a subset of {all_sizes}")
    reps = 1 if args.quick else args.reps
    rng = np.random.default_rng(args.seed)
    # (method, solver, outputs as a function of n, largest n)
    configs = [("sdp", "CLARABEL", lambda n: 1, 40), ("sdp", "SCS", lambda n: 1, 20),
               ("sequential", None, lambda n: 1, 40), ("nlp", None, lambda n: 1, 40),
               ("nlp", None, lambda n: 2, 40), ("nlp", None, lambda n: max(2, n // 5), 40)]
    rows = []
    warnings.simplefilter("ignore")
    warm_plant, warm = random_target(np.random.default_rng(99), 2, 1)  # imports and JIT out of the timing
    for method in ("sdp", "nlp", "sequential"):
        run(method, None, warm_plant, warm.poles)
    for n in all_sizes:
        if n not in sizes:  # draw (and discard) this size's targets: later sizes get the same ones
            for p in dict.fromkeys(pf(n) for _, _, pf, _ in configs):
                for _ in range(reps):
                    random_target(rng, n, p)
            continue
        targets = {}
        done = set()
        for method, solver, pfun, nmax in configs:
            p = pfun(n)
            label = method if solver is None else f"{method}/{solver.lower()}"
            if method == "nlp":
                label += "/ipopt"
            if n > nmax or (label, p) in done:
                continue
            done.add((label, p))
            if p not in targets:
                targets[p] = [t for t in (random_target(rng, n, p) for _ in range(reps)) if t is not None]
            if not targets[p]:
                rows.append({"method": label, "p": p, "n": n, "time": float("nan"), "ok": "-",
                             "err_med": float("nan"), "err_max": float("nan"), "floor": float("nan"),
                             "status": "no target: the filter ARE of a random plant is not solvable"})
                print(f"n={n:2d} p={p} {label:18s} no solvable random target", flush=True)
                continue
            floor = [eigenvalue_rounding_floor(plant.A - are.L @ plant.C) for plant, are in targets[p]]
            if statistics.median(floor) > 1e-3:
                rows.append({"method": label, "p": p, "n": n, "time": float("nan"), "ok": "-",
                             "err_med": float("nan"), "err_max": float("nan"),
                             "floor": statistics.median(floor),
                             "status": "not run: the target poles themselves are not computable"})
                print(f"n={n:2d} p={p} {label:18s} not run (floor {floor[0]:.1e}, ...)", flush=True)
                continue
            out = [run(method, solver, plant, are.poles) for plant, are in targets[p]]
            errs = [o["err"] for o in out]
            rows.append({
                "method": label, "p": p, "n": n,
                "time": statistics.median(o["time"] for o in out),
                "ok": f"{sum(o['success'] for o in out)}/{len(out)}",
                "err_med": statistics.median(errs), "err_max": max(errs),
                "floor": statistics.median(floor),
                "status": ",".join(sorted({o["status"] for o in out})),
            })
            r = rows[-1]
            print(f"n={n:2d} p={p} {label:18s} {r['time']:8.3f}s  ok {r['ok']}  pole err {r['err_med']:.1e} "
                  f"(max {r['err_max']:.1e}, floor {r['floor']:.1e})", flush=True)
    head = ("| method | p | n | time/design (s) | verified | pole error (median) | pole error (max) | "
            "rounding floor | statuses |\n|---|---|---|---|---|---|---|---|---|")
    body = "\n".join(
        f"| {r['method']} | {r['p']} | {r['n']} | {r['time']:.3f} | {r['ok']} | {r['err_med']:.1e} | "
        f"{r['err_max']:.1e} | {r['floor']:.1e} | {r['status']} |" for r in rows)
    note = (f"\n\nRandom continuous-time plants (A ~ N(0, 1/n), C ~ N(0, 1), R = I), targets = poles of "
            f"the Kalman filter of Q = F F' / n; {reps} target(s) per (p, n), seed {args.seed}.  Pole error: "
            f"optdesign.classical.placement.pole_error of an independent Riccati solve with the returned Q; "
            f"rounding floor: 10 eps max_i kappa_i ||A - LC|| / |lambda_i| of the target filter (the "
            f"accuracy to which its poles can be computed at all).  'verified' counts designs passing every "
            f"check (pole tolerance max(1e-8, floor), floor capped at 1e-6).  Sizes run: "
            f"{', '.join(map(str, sizes))}.  Machine: {platform.machine()}, "
            f"Python {platform.python_version()}, single-threaded BLAS, shared with other jobs.\n")
    table = "# kalman_for_poles: time and accuracy vs n\n\n" + head + "\n" + body + note
    print("\n" + table)
    if not args.quick:
        RESULTS.parent.mkdir(parents=True, exist_ok=True)
        RESULTS.write_text(table, encoding="utf-8")
        print(f"written to {RESULTS}")
    return table


if __name__ == "__main__":
    main()
