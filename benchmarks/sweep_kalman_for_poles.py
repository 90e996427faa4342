"""Feasible-by-construction targets for ``kalman_for_poles`` with several outputs (issue 26).

Each seed draws a plant ``A = randn(n, n) / sqrt(n)``, ``C = randn(p, n)``, ``R = I`` with
n in 8..12 and p in 3..4, and a process noise ``Q = F F'`` with F of ``r`` columns (r from 1 --
rank-deficient -- up to n: full rank); the target is the poles of *that* Q's steady-state
Kalman filter (scipy's CARE), so a design exists for every seed.  Every answer that is not a
success (``not_found`` above all) is listed with its message and route.

Usage::

    OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 flock /tmp/bench.lock \
        python benchmarks/sweep_kalman_for_poles.py [--seeds 170] [--time-limit 30] [--only 3,17]

Results: ``benchmarks/results/kalman_for_poles_sweep.md``.
"""

from __future__ import annotations

import argparse
import pathlib
import sys
import time

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))  # this checkout's optdesign

import numpy as np  # noqa: E402
import scipy.linalg as sla  # noqa: E402

from optdesign import Plant, kalman_for_poles  # noqa: E402

#: plant and noise families: ``scaled`` A = randn/sqrt(n); ``randn`` A = randn (eigenvalues spread
#: to ~sqrt(n)); ``stable`` the scaled A shifted stable; ``small_q`` / ``large_q`` Q scaled by 1e-3 / 1e3;
#: ``input`` / ``diagonal`` noise through a random G (n, m), m in 1..n, ``Q = G Qw G'`` with Qw full /
#: diagonal, designed with that ``q_structure``
FAMILIES = ("scaled", "randn", "stable", "small_q", "large_q", "input", "diagonal")


def case(seed: int, family: str = "scaled"):
    """``(plant, Q, poles, (n, p, r))`` of one seed: the target is the Kalman poles of Q."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(8, 13))
    p = int(rng.integers(3, 5))
    r = int(rng.choice([1, 2, p, n // 2, n])) if seed % 2 == 0 else int(rng.integers(1, n + 1))
    A = rng.standard_normal((n, n)) / np.sqrt(n)
    C = rng.standard_normal((p, n))
    F = rng.standard_normal((n, r))
    Q = F @ F.T
    if family == "randn":
        A = A * np.sqrt(n)
    elif family == "stable":
        A = A - (max(np.linalg.eigvals(A).real) + 0.1) * np.eye(n)
    elif family in ("small_q", "large_q"):
        Q = Q * (1e-3 if family == "small_q" else 1e3)
    G = None
    if family in ("input", "diagonal"):
        m = int(rng.integers(1, n + 1))
        G = rng.standard_normal((n, m))
        Fw = rng.standard_normal((m, m))
        Qw = np.diag(rng.uniform(0.1, 2.0, m)) if family == "diagonal" else Fw @ Fw.T
        Q, r = G @ Qw @ G.T, m
    R = np.eye(p)
    P = sla.solve_continuous_are(A.T, C.T, Q, R)
    L = P @ C.T
    poles = np.linalg.eigvals(A - L @ C)
    return Plant(A, C, R=R, G=G), Q, poles, (n, p, r)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=170)
    ap.add_argument("--time-limit", type=float, default=30.0)
    ap.add_argument("--family", default="scaled", choices=FAMILIES)
    ap.add_argument("--only", default="", help="comma-separated seeds")
    ap.add_argument("--out", default=str(pathlib.Path(__file__).parent / "results" /
                                         "kalman_for_poles_sweep.md"))
    args = ap.parse_args()
    seeds = [int(s) for s in args.only.split(",")] if args.only else list(range(args.seeds))
    rows, counts = [], {}
    for s in seeds:
        plant, Q, poles, (n, p, r) = case(s, args.family)
        tic, cpu = time.perf_counter(), time.process_time()
        structure = args.family if args.family in ("input", "diagonal") else "full"
        res = kalman_for_poles(plant, poles, q_structure=structure, time_limit=args.time_limit, seed=0)
        wall, cpu = time.perf_counter() - tic, time.process_time() - cpu
        st = res.status.value
        counts[st] = counts.get(st, 0) + 1
        route = str(getattr(res, "route", "") or "")
        rows.append((s, n, p, r, st, res.success, wall, cpu, float(np.trace(Q)), res.objective_value,
                     res.message.replace("|", "/")[:400], route))
        print(f"{args.family} seed {s:3d} n={n:2d} p={p} r={r:2d} {st:20s} {wall:6.2f} s", flush=True)
    bad = [row for row in rows if not row[5]]
    lines = ["# kalman_for_poles on feasible-by-construction targets (several outputs)", "",
             f"`python benchmarks/sweep_kalman_for_poles.py --family {args.family} --seeds {args.seeds} "
             f"--time-limit {args.time_limit:g}`"
             " (single-threaded BLAS, under `flock /tmp/bench.lock`).  Plant `A = randn(n,n)/sqrt(n)`, "
             "`C = randn(p,n)`, `R = I`, n = 8..12, p = 3..4; the target is the Kalman poles of `Q = F F'` "
             "(F with r columns): a design exists for every seed.",
             "",
             "Statuses: " + ", ".join(f"{k}: {v}" for k, v in sorted(counts.items())), "",
             f"Wall time: median {np.median([r[6] for r in rows]):.2f} s, "
             f"max {max(r[6] for r in rows):.2f} s; CPU per call: median "
             f"{np.median([r[7] for r in rows]):.2f} s, max {max(r[7] for r in rows):.2f} s; "
             f"trace(Q_found) <= trace(Q_true) in {sum(1 for r in rows if r[5] and r[9] <= r[8] * 1.000001)}"
             f" of {sum(1 for r in rows if r[5])} successes.", "",
             "## Not successful", "", "| seed | n | p | rank Q | status | wall s | CPU s | message | route |",
             "|---|---|---|---|---|---|---|---|---|"]
    lines += [f"| {r[0]} | {r[1]} | {r[2]} | {r[3]} | {r[4]} | {r[6]:.1f} | {r[7]:.1f} | {r[10]} | {r[11]} |"
              for r in bad]
    lines += ["", "## Answered by the continuation in the target poles", "",
              "| seed | n | p | rank Q | status | CPU s | trace(Q_found) | trace(Q_true) |",
              "|---|---|---|---|---|---|---|---|"]
    lines += [f"| {r[0]} | {r[1]} | {r[2]} | {r[3]} | {r[4]} | {r[7]:.2f} | {r[9]:.6g} | {r[8]:.6g} |"
              for r in rows if "pole continuation" in r[10]]
    pathlib.Path(args.out).write_text("\n".join(lines) + "\n")
    print("\n".join(lines[4:8]))


if __name__ == "__main__":
    main()
