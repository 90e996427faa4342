"""Benchmark: the fixed-gain SDP of ``kalman_for_poles`` re-used through cvxpy parameters vs rebuilt.

A study over prescribed-pole targets (``PoleTargetDesigner``, ``design = "inverse"`` in a spec) solves
the same plant's fixed-gain SDP for many gains (``PoleTargetDesigner(reuse=...)`` switches it).
In continuous time the gain enters the SDP only
through cvxpy ``Parameter`` s (DPP), so optdesign keeps one problem per plant and thread and re-binds
the parameters (``optdesign.design.inverse_kalman.sdp_reuse``); ``reuse=False`` rebuilds (and
re-canonicalizes) it for every point.  Measured per point: the whole verb (placement of the unique
single-output gain, SDP, face polish, independent verification), and the SDP solve call alone.

Sets: Chang & Lee's Example 1 (n = 2) and random single-output plants n = 5, 10, 20, each with
``--points`` feasible targets (the poles of the Kalman filter of a random Q >= 0); every design's Q
is compared between the two variants.

Run:  python benchmarks/bench_sdp_reuse.py [--points 30]
Writes benchmarks/results/sdp_reuse.md.  Numbers, not pass/fail.
"""

from __future__ import annotations

# isort: off
from _common import random_observable_plant  # first: single-threaded BLAS before numpy
# isort: on

import argparse  # noqa: E402
import platform  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from optdesign import Plant, kalman_for_poles, problems  # noqa: E402
from optdesign.classical.riccati import filter_are  # noqa: E402
from optdesign.design import inverse_kalman as ik  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "results" / "sdp_reuse.md"


def run(plant: Plant, targets: list[np.ndarray], reuse: bool):
    """Per-target wall times of ``kalman_for_poles(method="sdp")`` and of its SDP solve calls
    (``solve_cvxpy`` is imported by the verb at call time, so patching the module attribute
    times every call)."""
    from optdesign.solvers import cvxpy_backend

    solve_times: list[float] = []
    real = cvxpy_backend.solve_cvxpy

    def timed(*a, **k):
        t0 = time.perf_counter()
        try:
            return real(*a, **k)
        finally:
            solve_times.append(time.perf_counter() - t0)

    ik._SDP_CACHE.entries = None
    cvxpy_backend.solve_cvxpy = timed
    try:
        with ik.sdp_reuse(reuse):
            kalman_for_poles(plant, targets[0], method="sdp")  # imports, first canonicalization
            solve_times.clear()
            times, res = [], []
            for t in targets:
                t0 = time.perf_counter()
                res.append(kalman_for_poles(plant, t, method="sdp"))
                times.append(time.perf_counter() - t0)
    finally:
        cvxpy_backend.solve_cvxpy = real
    return np.array(times), np.array(solve_times), res


def main() -> str:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=30, help="targets per plant")
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    rng = np.random.default_rng(0)
    ex1 = problems.load("chang_lee_1984_ex1").plant.replace(G=None, Q=None)
    cases = [("chang_lee_1984_ex1 (n = 2)", ex1)]
    for n in (5, 10, 20):
        cases.append((f"random, n = {n}, p = 1", random_observable_plant(rng, n, 1, noise=True)))
    rows = []
    for label, plant in cases:
        n = plant.n
        targets = []
        while len(targets) < args.points:  # feasible targets: poles of Kalman filters of random Q >= 0
            F = rng.standard_normal((n, n)) / np.sqrt(n)
            try:
                targets.append(filter_are(plant.replace(Q=F @ F.T + 1e-3 * np.eye(n))).poles)
            except Exception:  # noqa: BLE001 - draw again
                continue
        (t0, s0, r0), (t1, s1, r1) = run(plant, targets, False), run(plant, targets, True)
        ok0 = sum(r.success for r in r0)
        ok1 = sum(r.success for r in r1)
        dq = max((float(np.linalg.norm(a.Q - b.Q) / max(1.0, np.linalg.norm(a.Q)))
                  for a, b in zip(r0, r1, strict=True) if a.success and b.success), default=float("nan"))
        rows.append((label, len(targets), 1e3 * np.median(t0), 1e3 * np.median(t1), 1e3 * np.median(s0),
                     1e3 * np.median(s1), ok0, ok1, dq))
        r = rows[-1]
        print(f"{label}: verb {r[2]:.1f} -> {r[3]:.1f} ms/design, SDP solve {r[4]:.1f} -> "
              f"{r[5]:.1f} ms, verified {ok0}/{ok1}, max rel |Q diff| {dq:.1e}", flush=True)
    head = ("| plant | targets | verb, rebuilt (ms/design) | verb, re-used (ms/design) | speed-up | "
            "SDP solve call, rebuilt (ms) | SDP solve call, re-used (ms) | verified (rebuilt / re-used) | "
            "max relative Q difference |\n|---|---|---|---|---|---|---|---|---|")
    body = "\n".join(f"| {r[0]} | {r[1]} | {r[2]:.1f} | {r[3]:.1f} | {r[2] / r[3]:.2f}x | {r[4]:.1f} | "
                     f"{r[5]:.1f} | {r[6]}/{r[7]} | {r[8]:.1e} |" for r in rows)
    text = ("# Fixed-gain SDP: cvxpy parameters re-used vs rebuilt per design\n\n"
            f"`python benchmarks/bench_sdp_reuse.py` -- {platform.machine()}, Python "
            f"{platform.python_version()}, single-threaded BLAS; medians over {args.points} feasible targets "
            "per plant (the poles of the Kalman filter of a random Q >= 0), `kalman_for_poles(plant, target, "
            "method='sdp')` with `sdp_reuse(False)` / `sdp_reuse(True)` (the default).\n\n"
            + head + "\n" + body + "\n\n"
            "The 'SDP solve call' column times `solve_cvxpy` (cvxpy canonicalization or parameter update, "
            "plus Clarabel); the verb column adds the placement of the gain, the face polish and the "
            "independent verification (an extra Riccati solve), which re-use does not change.\n")
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text(text, encoding="utf-8")
    print(text)
    return text


if __name__ == "__main__":
    main()
