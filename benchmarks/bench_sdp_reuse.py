"""Benchmark: the fixed-gain SDP of ``kalman_for_poles`` re-used through cvxpy parameters vs rebuilt.

A study over prescribed-pole targets (``PoleTargetDesigner``, ``design = "inverse"`` in a spec) solves
the same plant's fixed-gain SDP for many gains.  In continuous time the gain enters the SDP only
through cvxpy ``Parameter`` s (DPP), so optdesign keeps one problem per plant and thread and re-binds
the parameters (``optdesign.design.inverse_kalman.sdp_reuse``); ``reuse=False`` rebuilds (and
re-canonicalizes) it for every point.  Measured per point: the whole verb (placement of the unique
single-output gain, SDP, face polish, independent verification), and the SDP solve call alone.

Sets: Chang & Lee's Example 1 (n = 2) and random single-output plants n = 5, 10, 20, each with a
grid of ``scale x shift`` target variations of a feasible target (the poles of a random Kalman
filter); every point's Q is compared between the two variants.

Run:  python benchmarks/bench_sdp_reuse.py [--points 40]
Writes benchmarks/results/sdp_reuse.md.  Numbers, not pass/fail.
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import platform  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from optdesign import Plant, problems  # noqa: E402
from optdesign.classical.riccati import filter_are  # noqa: E402
from optdesign.design import inverse_kalman as ik  # noqa: E402
from optdesign.studies import PoleTargetDesigner, grid  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "results" / "sdp_reuse.md"


def random_plant(rng: np.random.Generator, n: int):
    while True:
        A = rng.standard_normal((n, n)) / np.sqrt(n)
        C = rng.standard_normal((1, n))
        plant = Plant(A, C, R=np.eye(1))
        if not plant.is_observable():
            continue
        F = rng.standard_normal((n, n)) / np.sqrt(n)
        try:
            poles = filter_are(plant.replace(Q=F @ F.T)).poles
        except Exception:  # noqa: BLE001 - draw again
            continue
        return plant, poles


def run(designer: PoleTargetDesigner, points: list[dict]):
    """Per-point wall times of the verb and of its SDP solve calls (``solve_cvxpy`` is imported by
    the verb at call time, so patching the module attribute times every call)."""
    from optdesign.solvers import cvxpy_backend

    solve_times = []

    real = cvxpy_backend.solve_cvxpy

    def timed(*a, **k):
        t0 = time.perf_counter()
        try:
            return real(*a, **k)
        finally:
            solve_times.append(time.perf_counter() - t0)

    cvxpy_backend.solve_cvxpy = timed
    try:
        times, res = [], []
        for p in points:
            t0 = time.perf_counter()
            r = designer(**p)
            times.append(time.perf_counter() - t0)
            res.append(r)
    finally:
        cvxpy_backend.solve_cvxpy = real
    return np.array(times), np.array(solve_times), res


def main() -> str:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=40, help="grid points per plant")
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    rng = np.random.default_rng(0)
    cases = [("chang_lee_1984_ex1 (n = 2)", problems.load("chang_lee_1984_ex1").plant.replace(G=None, Q=None),
              np.array([-5.0, -8.0]))]
    for n in (5, 10, 20):
        plant, poles = random_plant(rng, n)
        cases.append((f"random, n = {n}, p = 1", plant, poles))
    k = max(2, int(round(np.sqrt(args.points))))
    pts = grid(scale=np.linspace(1.0, 1.5, k), shift=np.linspace(0.0, -0.5, k))
    rows = []
    for label, plant, poles in cases:
        out = {}
        for reuse in (False, True):
            ik._SDP_CACHE.entries = None
            d = PoleTargetDesigner(plant=plant, poles=tuple(poles), method="inverse", inverse_method="sdp",
                                   reuse=reuse)
            d(**pts[0])  # imports, first canonicalization out of the medians (reported separately)
            out[reuse] = run(d, pts)
        (t0, s0, r0), (t1, s1, r1) = out[False], out[True]
        ok0 = sum(r.success for r in r0)
        ok1 = sum(r.success for r in r1)
        dq = max((float(np.linalg.norm(a.result.Q - b.result.Q) / max(1.0, np.linalg.norm(a.result.Q)))
                  for a, b in zip(r0, r1, strict=True) if a.success and b.success),
                 default=float("nan"))
        rows.append((label, len(pts), 1e3 * np.median(t0), 1e3 * np.median(t1), 1e3 * np.median(s0),
                     1e3 * np.median(s1), ok0, ok1, dq))
        print(f"{label}: verb {1e3 * np.median(t0):.1f} -> {1e3 * np.median(t1):.1f} ms/point, "
              f"SDP solve {1e3 * np.median(s0):.1f} -> {1e3 * np.median(s1):.1f} ms, verified {ok0}/{ok1}, "
              f"max rel |Q diff| {dq:.1e}", flush=True)
    head = ("| plant | points | verb, rebuilt (ms/point) | verb, re-used (ms/point) | speed-up | "
            "SDP solve call, rebuilt (ms) | SDP solve call, re-used (ms) | verified (rebuilt / re-used) | "
            "max relative Q difference (both verified) |\n|---|---|---|---|---|---|---|---|---|")
    body = "\n".join(f"| {r[0]} | {r[1]} | {r[2]:.1f} | {r[3]:.1f} | {r[2] / r[3]:.2f}x | {r[4]:.1f} | "
                     f"{r[5]:.1f} | {r[6]}/{r[7]} | {r[8]:.1e} |" for r in rows)
    text = ("# Fixed-gain SDP: cvxpy parameters re-used vs rebuilt per point\n\n"
            f"`python benchmarks/bench_sdp_reuse.py` -- {platform.machine()}, Python "
            f"{platform.python_version()}, single-threaded BLAS, medians over a {k} x {k} grid of "
            "target scale x shift per plant (`PoleTargetDesigner(method='inverse', inverse_method='sdp')`).\n\n"
            + head + "\n" + body + "\n\n"
            "The 'SDP solve call' column times `solve_cvxpy` (cvxpy canonicalization + Clarabel); the verb "
            "column adds the placement of the gain, the face polish and the independent verification "
            "(an extra Riccati solve), which re-use does not change.  Points that are not verified are "
            "target variations no Q >= 0 reaches (infeasible, with a certificate) or that the SDP "
            "cannot resolve; they are the same points in both variants.\n")
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text(text, encoding="utf-8")
    print(text)
    return text


if __name__ == "__main__":
    main()
