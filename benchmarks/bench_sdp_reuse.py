"""Benchmark: the single-output fixed-gain SDP, built per design vs re-used per plant, cvxpy vs Clarabel
directly -- side by side in one process.

With one output the target poles fix L and the design is the fixed-gain SDP at that L.  A study over
prescribed-pole targets solves the same plant's SDP for many gains; what can be re-used:

* ``verb``               -- ``kalman_for_poles(plant, target, method="sdp")``: everything per call (the
                            verb no longer caches problems between calls; re-use is explicit);
* ``cvxpy rebuilt``      -- :func:`optdesign.formulate.inverse_kalman.build_fixed_gain_sdp` and its solve
                            with Clarabel, per gain;
* ``cvxpy re-used``      -- the same problem built once per plant, the gain re-bound through its cvxpy
                            Parameters (``set_gain``, DPP: no re-canonicalization), per gain the solve;
* ``Clarabel direct``    -- the engine's smallest conic form (``P = P0 + N X N'``, one PSD cone, no
                            equality; :mod:`optdesign.backends.clarabel_fixed_gain`), the plant's map
                            built once, per gain the family and the Clarabel call (with the engine's
                            settings: the QDLDL KKT solver);
* ``engine``             -- ``solve_inverse_kalman`` with a setup prepared once per plant: the unique gain,
                            the direct SDP, its polish onto the face and the independent verification.

Sets: Chang & Lee's Example 1 (n = 2) and random single-output plants n = 5, 10, 20, each with
``--points`` feasible targets (the poles of the Kalman filter of a random Q >= 0).  CPU seconds
(``time.process_time``) per design, medians; the trace of Q compared between the engine and the verb.

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
from optdesign.formulate.inverse_kalman import build_fixed_gain_sdp, spectral_terms  # noqa: E402
from optdesign.backends.clarabel_fixed_gain import family_map, fixed_gain_family, solve_fixed_gain  # noqa: E402
from optdesign.backends.cvxpy_backend import solve_cvxpy  # noqa: E402
from optdesign.engines.inverse_kalman_engine import prepare_inverse_kalman, solve_inverse_kalman  # noqa: E402
from optdesign.engines.spectral_factor import spectral_blocks  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "results" / "sdp_reuse.md"


def unique_gain(plant: Plant, target) -> np.ndarray:
    """The gain the poles fix (one output): the null vectors are the scalars 1."""
    terms = spectral_terms(plant.A, plant.C, np.asarray(target, dtype=complex), plant.dt)
    return spectral_blocks(terms, plant.R, np.eye(plant.n)).gain(np.ones((len(terms), 1), dtype=complex))[0]


def cpu(fn):
    t0 = time.process_time()
    out = fn()
    return out, time.process_time() - t0


def run(plant: Plant, targets: list) -> dict:
    R = np.asarray(plant.R, dtype=float)
    gains = [unique_gain(plant, t) for t in targets]
    out: dict = {k: [] for k in ("verb", "cvxpy rebuilt", "cvxpy re-used", "Clarabel direct", "engine")}
    solved = {k: 0 for k in ("cvxpy rebuilt", "cvxpy re-used", "Clarabel direct")}
    verb_res, eng_res = [], []
    for t in targets:
        r, s = cpu(lambda t=t: kalman_for_poles(plant, t, method="sdp"))
        out["verb"].append(s)
        verb_res.append(r)
    for L in gains:
        rep, s = cpu(lambda L=L: solve_cvxpy(build_fixed_gain_sdp(plant.A, plant.C, L, R).problem,
                                             "CLARABEL"))
        out["cvxpy rebuilt"].append(s)
        solved["cvxpy rebuilt"] += rep.status.is_solved
    sdp = build_fixed_gain_sdp(plant.A, plant.C, gains[0], R)
    solve_cvxpy(sdp.problem, "CLARABEL")   # the one canonicalization
    for L in gains:
        rep, s = cpu(lambda L=L: solve_cvxpy(sdp.set_gain(L).problem, "CLARABEL"))
        out["cvxpy re-used"].append(s)
        solved["cvxpy re-used"] += rep.status.is_solved
    fmap = family_map(plant.A, plant.C, plant.dt)
    for L in gains:
        sol, s = cpu(lambda L=L: solve_fixed_gain(fixed_gain_family(fmap, L, R)))
        out["Clarabel direct"].append(s)
        solved["Clarabel direct"] += sol.status.is_solved
    setup = prepare_inverse_kalman(plant)
    for t in targets:
        r, s = cpu(lambda t=t: solve_inverse_kalman(setup, t))
        out["engine"].append(s)
        eng_res.append(r)
    pairs = [(a, b) for a, b in zip(eng_res, verb_res, strict=True) if a.success and b.success]
    dq = max((abs(a.objective_value - b.objective_value) / max(1.0, abs(b.objective_value))
              for a, b in pairs), default=float("nan"))
    return {"t": {k: 1e3 * float(np.median(v)) for k, v in out.items()}, "solved": solved,
            "ok": (sum(r.success for r in verb_res), sum(r.success for r in eng_res)), "dq": dq}


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
    run(ex1, [[-5.0, -8.0]])   # imports and first calls out of the timing
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
        r = run(plant, targets)
        rows.append((label, len(targets), r))
        print(f"{label}: " + ", ".join(f"{k} {v:.1f} ms" for k, v in r["t"].items())
              + f"; verified verb/engine {r['ok'][0]}/{r['ok'][1]}; max rel trace diff {r['dq']:.1e}",
              flush=True)
    keys = list(rows[0][2]["t"])
    head = ("| plant | targets | " + " | ".join(f"{k} (ms)" for k in keys)
            + " | verb / engine | cvxpy re-used / Clarabel direct | SDPs solved (rebuilt / re-used / "
            "direct) | verified (verb / engine) | max relative difference of trace Q |\n|"
            + "---|" * (len(keys) + 7))
    body = "\n".join(
        f"| {label} | {cnt} | " + " | ".join(f"{r['t'][k]:.1f}" for k in keys)
        + f" | {r['t']['verb'] / r['t']['engine']:.1f}x"
        + f" | {r['t']['cvxpy re-used'] / r['t']['Clarabel direct']:.1f}x"
        + " | " + " / ".join(str(v) for v in r["solved"].values())
        + f" | {r['ok'][0]}/{r['ok'][1]} | {r['dq']:.1e} |" for label, cnt, r in rows)
    text = ("# Single-output fixed-gain SDP: built per design vs re-used per plant, cvxpy vs Clarabel "
            "directly\n\n"
            f"`python benchmarks/bench_sdp_reuse.py` -- {platform.machine()}, Python "
            f"{platform.python_version()}, single-threaded BLAS; CPU milliseconds per design, medians over "
            f"{args.points} feasible targets per plant (the poles of the Kalman filter of a random "
            "Q >= 0).\n\n"
            + head + "\n" + body + "\n\n"
            "'verb' and 'engine' are whole designs (gain, SDP, polish, independent verification); the "
            "three columns between time the SDP alone at the unique gain (an SDP that fails fast -- cvxpy's "
            "form has n p + n(n+1)/2 equalities, and Clarabel reports solver_error on some -- counts in the "
            "median too: see the solved counts).  The verb no longer caches SDPs between calls (re-use is "
            "explicit, through caller-held problem objects such as the engine's setup).  The direct form is "
            "small but its constraint matrix is dense (every X direction moves all of Q), and Clarabel's "
            "sparse LDL then factors the whole KKT matrix densely: per iteration it is slower than cvxpy's "
            "larger, sparser form from n ~ 15 on (20 ms vs 2 ms at n = 20) -- where that form, here, "
            "fails.  The engine and the 'Clarabel direct' column use Clarabel's QDLDL KKT solver "
            "(in `CLARABEL_OPTIONS`): on this dense KKT matrix it takes about half the CPU time of "
            "Clarabel's default choice at n = 15-25, as fast below (measured side by side: 181 -> 115 ms "
            "per SDP at n = 20 in this benchmark).\n")
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text(text, encoding="utf-8")
    print(text)
    return text


if __name__ == "__main__":
    main()
