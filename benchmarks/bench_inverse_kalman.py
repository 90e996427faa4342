"""Benchmark: Kalman filter with prescribed poles -- the engine without an NLP vs the current verb vs
hand-written minimal SDPs, side by side in one process (issue 14).

For each size (n, p) a few random feasible targets (the poles of the Kalman filter of a random
plant with a random Q >= 0, continuous time; three per size) are solved by

* ``engine``      -- :func:`optdesign.engines.inverse_kalman_engine.solve_inverse_kalman` (SQP and
                     Newton on the null-vector parametrization of the gains with the target poles,
                     the fixed-gain SDP on Clarabel as certificate; one output: that SDP alone);
* ``nlp``         -- ``kalman_for_poles(method="nlp")`` (the spectral NLP on IPOPT, 3 starts);
* ``sdp``         -- ``kalman_for_poles(method="sdp")`` (one output: the fixed-gain SDP with polish;
                     several outputs: the NLP first, for L, then the SDP at it);
* ``min-SDP``     -- the minimal SDP of the issue, hand-written in cvxpy (P symmetric, Q >= 0,
                     P C' = L R, Q = L R L' - A P - P A', min trace Q) at the engine's gain, solved
                     with Clarabel, rebuilt per solve and with its gain as cvxpy Parameters re-used
                     (the second solve after re-binding them: the steady state of a sweep).

Every design is checked by the same independent test: scipy's Riccati solver with the returned Q
must give the target poles to their rounding floor (``eigenvalue_rounding_floor``, at least 1e-8)
and the returned L to 1e-6 relative; "verified" counts those.  Times are CPU seconds
(``time.process_time``) per design, medians over the targets; the ratios are of the medians.  The
engine and the re-used minimal SDP are timed as the median of 5 calls when a call takes under 0.2 s
(the first call of a process pays warm-up costs; the reference's first solve compiles it).  At
(40, 8) the verb (533 s per design in the README's run) is run only with ``--slow``.

Run:  python benchmarks/bench_inverse_kalman.py [--reps 3] [--sizes 2x1,10x4 [--merge]] [--slow]
      [--profile | --stages | --sdp-forms | --verify-ab | --first-try | --ipm | --form | --verb-ratio]
Writes benchmarks/results/inverse_kalman.md, .csv and .json; ``--profile`` writes
benchmarks/results/inverse_kalman_profile.md (cProfile of the engine at (20, 4) and (40, 8), time
per stage); ``--stages`` benchmarks/results/inverse_kalman_stages_one_output.md (CPU per stage of the
one-output verb); ``--sdp-forms`` benchmarks/results/inverse_kalman_sdp_forms.md (one fixed-gain
SDP on Clarabel: the direct form vs a sparse form, Clarabel's KKT solvers); ``--ipm``
benchmarks/results/inverse_kalman_one_output_ipm.md and .json (the one-output dense IPM vs Clarabel;
``--first-try`` and ``--ipm`` measure the general one-output route, the fallback of the n-constraint
form); ``--form`` benchmarks/results/inverse_kalman_one_output_form.md (the n-constraint form vs the
general route); ``--verb-ratio`` benchmarks/results/inverse_kalman_verb_ratio.md (the verb against the
re-used minimal cvxpy SDP, continuous and discrete).
"""

from __future__ import annotations

# isort: off
from _common import random_observable_plant  # first: single-threaded BLAS before numpy
# isort: on

import argparse  # noqa: E402
import contextlib  # noqa: E402
import cProfile  # noqa: E402
import csv  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import pstats  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import scipy.linalg as sl  # noqa: E402

from optdesign import InverseKalmanProblem, Plant, kalman_for_poles  # noqa: E402
from optdesign.analysis.metrics import eigenvalue_rounding_floor  # noqa: E402
from optdesign.classical.placement import pole_error  # noqa: E402
from optdesign.classical.riccati import filter_are  # noqa: E402
from optdesign.design.verification import POLE_FLOOR_CAP  # noqa: E402
from optdesign.errors import OptDesignError  # noqa: E402
from optdesign.engines.inverse_kalman_engine import prepare_inverse_kalman, solve_inverse_kalman  # noqa: E402

OUT = Path(__file__).resolve().parent / "results"
SIZES = [(2, 1), (10, 1), (20, 1), (5, 2), (10, 4), (20, 2), (20, 4), (40, 8)]


def _kalman_target(rng: np.random.Generator, plant: Plant):
    """``(plant, its Kalman filter of Q = F F' / n)`` for a random F, or None when scipy cannot solve
    that Riccati equation."""
    n = plant.n
    F = rng.standard_normal((n, n)) / np.sqrt(n)
    try:
        return plant, filter_are(plant.replace(Q=F @ F.T), residual_tol=1e-6)
    except OptDesignError:
        return None


def random_target(rng: np.random.Generator, n: int, p: int, tries: int = 50):
    """A random observable plant (spectral radius ~1, R = I) and the poles of the Kalman filter of
    ``Q = F F' / n``, or None when no draw gives a Riccati equation scipy can solve."""
    for _ in range(tries):
        out = _kalman_target(rng, random_observable_plant(rng, n, p, noise=True))
        if out is not None:
            return out
    return None


def random_discrete_target(rng: np.random.Generator, n: int, tries: int = 50):
    """A random observable discrete plant (one output, dt = 0.1, A ~ N(0, 1/n) scaled to spectral
    radius below 1/1.05, R = 1) and the poles of the Kalman filter (predictor form) of ``Q = F F' / n``."""
    for _ in range(tries):
        A = rng.standard_normal((n, n)) / np.sqrt(n)
        A = A / (1.05 * max(1.0, float(np.max(np.abs(np.linalg.eigvals(A))))))
        plant = Plant(A, rng.standard_normal((1, n)), R=np.eye(1), dt=0.1)
        out = _kalman_target(rng, plant) if plant.is_observable() else None
        if out is not None:
            return out
    return None


def independent_check(plant: Plant, target, L, Q) -> bool:
    """scipy's continuous Riccati solver with Q reproduces the targets (to their rounding floor) and
    L (to 1e-6 relative)."""
    if L is None or Q is None:
        return False
    try:
        P = sl.solve_continuous_are(plant.A.T, plant.C.T, 0.5 * (Q + Q.T), plant.R)
    except (np.linalg.LinAlgError, ValueError):
        return False
    La = P @ plant.C.T @ np.linalg.inv(plant.R)
    F = plant.A - La @ plant.C
    ok_poles = pole_error(np.linalg.eigvals(F), target) <= max(1e-8, eigenvalue_rounding_floor(F))
    return bool(ok_poles and np.linalg.norm(La - L) <= 1e-6 * max(1.0, np.linalg.norm(L)))


def timed(fn):
    t0 = time.process_time()
    out = fn()
    return out, time.process_time() - t0


#: a design or reference solve faster than this (CPU s) is repeated and its median taken
REPEAT_BELOW = 0.2
REPEATS = 5


def timed_median(fn):
    """``(result, CPU s)``: the median of :data:`REPEATS` calls when the first is faster than
    :data:`REPEAT_BELOW` (the first call of a process pays warm-up costs), else the one call."""
    out, t = timed(fn)
    if t >= REPEAT_BELOW:
        return out, t
    times = [t]
    for _ in range(REPEATS - 1):
        out, t = timed(fn)
        times.append(t)
    return out, float(np.median(times))


def _min_sdp_problem(A, C, LR, LRL):
    """The issue's minimal SDP (cvxpy) for the data ``L R`` and ``L R L'`` (arrays or Parameters):
    ``(problem, Q variable)``."""
    import cvxpy as cp

    n = A.shape[0]
    P = cp.Variable((n, n), symmetric=True)
    Q = cp.Variable((n, n), PSD=True)
    return cp.Problem(cp.Minimize(cp.trace(Q)), [P @ C.T == LR, Q == LRL - A @ P - P @ A.T]), Q


def _min_sdp_problem_discrete(n: int, C):
    """The minimal discrete SDP in a DPP form (cvxpy compiles it once): with ``F = A - L C``,
    ``F P C' = L R`` and ``Q = P - F P F' - L R L'`` (the predictor DARE at a fixed gain), the
    products with F written as ``(C kron F) vec(P)`` and ``(F kron F) vec(P)`` with the Kronecker
    products as Parameters.  ``(problem, Q variable, parameters CF, FF, LR, LRL)``."""
    import cvxpy as cp

    P = cp.Variable((n, n), symmetric=True)
    Q = cp.Variable((n, n), PSD=True)
    CF, FF = cp.Parameter((C.shape[0] * n, n * n)), cp.Parameter((n * n, n * n))
    LR, LRL = cp.Parameter((n * C.shape[0],)), cp.Parameter((n, n), symmetric=True)
    FPF = cp.reshape(FF @ cp.vec(P, order="F"), (n, n), order="F")
    cons = [CF @ cp.vec(P, order="F") == LR, Q == P - FPF - LRL]
    return cp.Problem(cp.Minimize(cp.trace(Q)), cons), Q, (CF, FF, LR, LRL)


def minimal_sdp_discrete(plant: Plant, L) -> tuple[float, float]:
    """:func:`minimal_sdp` (re-used) for a discrete plant: the DPP form of
    :func:`_min_sdp_problem_discrete`, its Parameters bound to the gain L, compiled by a first solve,
    re-bound and re-solved (timed, :func:`timed_median`)."""
    A, C, R = plant.A, plant.C, plant.R
    n = A.shape[0]
    F = A - L @ C
    LRL = L @ R @ L.T
    vals = (np.kron(C, F), np.kron(F, F), (L @ R).ravel(order="F"), 0.5 * (LRL + LRL.T))
    prob, Q, params = _min_sdp_problem_discrete(n, C)

    def bind_and_solve():
        for par, v in zip(params, vals, strict=True):
            par.value = v.copy()
        prob.solve(solver="CLARABEL")

    import cvxpy as cp

    try:
        bind_and_solve()
        _, t = timed_median(bind_and_solve)
    except cp.error.SolverError:   # Clarabel fails on this form: no reference time (reported)
        return float("nan"), float("nan")
    return float(np.trace(Q.value)) if Q.value is not None else float("nan"), t


def minimal_sdp(plant: Plant, L, reuse: bool, check_target=None) -> tuple[float, float]:
    """The issue's minimal SDP at the gain L: ``(trace Q, CPU seconds of the timed solve)``.
    ``reuse``: L R and L R L' are cvxpy Parameters, solved once (compilation), re-bound and the
    re-solves timed (:func:`timed_median`); else built and solved once, all timed.  ``check_target``
    (poles; with ``reuse``): each timed re-solve is followed by the check a careful user adds by hand,
    :func:`independent_check` (scipy's Riccati re-solve with the SDP's Q reproduces L and the poles)."""
    import cvxpy as cp

    A, C, R = plant.A, plant.C, plant.R
    n, p = A.shape[0], C.shape[0]
    LRv, LRLv = L @ R, L @ R @ L.T
    LRLv = 0.5 * (LRLv + LRLv.T)
    if not reuse:
        t0 = time.process_time()
        prob, Q = _min_sdp_problem(A, C, LRv, LRLv)
        prob.solve(solver="CLARABEL")
        return float(np.trace(Q.value)) if Q.value is not None else float("nan"), time.process_time() - t0
    LR, LRL = cp.Parameter((n, p)), cp.Parameter((n, n), symmetric=True)
    prob, Q = _min_sdp_problem(A, C, LR, LRL)
    LR.value, LRL.value = LRv, LRLv
    prob.solve(solver="CLARABEL")

    def resolve():
        LR.value, LRL.value = LRv.copy(), LRLv.copy()
        prob.solve(solver="CLARABEL")
        if check_target is not None and Q.value is not None:
            independent_check(plant, check_target, L, Q.value)

    _, t = timed_median(resolve)
    return float(np.trace(Q.value)) if Q.value is not None else float("nan"), t


def write_md(name: str, heading: str, text: str) -> None:
    """Print ``text`` and write it under ``heading`` to ``benchmarks/results/<name>``."""
    print(text)
    (OUT / name).write_text(heading + "\n\n" + text + "\n", encoding="utf-8")


#: the sizes of ``--verb-ratio`` beyond the main run's (one output; 3 targets each, drawn from seed n)
VERB_SIZES = (3, 4, 5, 6, 8, 12, 15)
#: the discrete sizes of ``--verb-ratio`` (one output; 2 targets each, drawn from seed 1000 + n)
VERB_SIZES_DISCRETE = (2, 5, 8, 10)


def verb_ratio(reps: int = 7) -> str:
    """The public verb ``kalman_for_poles(plant, poles)`` and a held ``InverseKalmanProblem(plant)``
    (built once per plant, as the reference compiles once) against the re-used minimal SDP at the
    verb's gain, per target, each the median of ``reps`` calls, interleaved in one process: the main
    run's targets (n = 2, 10, 20), then 3 targets at each of :data:`VERB_SIZES`; then discrete
    targets (:data:`VERB_SIZES_DISCRETE`) against the DPP form of :func:`minimal_sdp_discrete`."""
    rng = np.random.default_rng(0)
    drawn = [(size[0], k, t) for size in SIZES[:3]
             for k, t in enumerate([random_target(rng, *size) for _ in range(3)])]
    for n in VERB_SIZES:
        rn = np.random.default_rng(n)
        drawn += [(n, k, random_target(rn, n, 1)) for k in range(3)]
    discrete = []
    for n in VERB_SIZES_DISCRETE:
        rn = np.random.default_rng(1000 + n)
        discrete += [(n, k, random_discrete_target(rn, n)) for k in range(2)]
    lines = ["| n, p | target | rounding floor of its poles | verb status | verified | verb CPU ms "
             "| held problem CPU ms | min-SDP re-used CPU ms | verb / min-SDP | held / min-SDP "
             "| min-SDP + scipy check CPU ms | verb / (min-SDP + check) |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    rows = [(False, d) for d in sorted(drawn, key=lambda d: (d[0], d[1]))] + [(True, d) for d in discrete]
    for disc, (n, k, (plant, are)) in rows:
        held = InverseKalmanProblem(plant)
        held.solve(are.poles)
        tv, th, tr = [], [], []
        for _ in range(reps):
            r, t = timed(lambda pl=plant, tg=are.poles: kalman_for_poles(pl, tg))
            tv.append(t)
            th.append(timed(lambda tg=are.poles, h=held: h.solve(tg))[1])
            tr.append((minimal_sdp_discrete(plant, r.L) if disc else minimal_sdp(plant, r.L, reuse=True))[1])
        # m is nan where the reference failed (Clarabel on the discrete DPP form)
        v, h, m = float(np.median(tv)), float(np.median(th)), float(np.median(tr))
        mc = float("nan") if disc else minimal_sdp(plant, r.L, reuse=True, check_target=are.poles)[1]
        floor = eigenvalue_rounding_floor(plant.A - are.L @ plant.C)
        label = f"{n}, 1{' (discrete)' if disc else ''}"
        lines.append(f"| {label} | {k} | {floor:.1e} | {r.status.value} | {r.success} | {1e3 * v:.2f} | "
                     f"{1e3 * h:.2f} | {1e3 * m:.2f} | {v / m:.2f}x | {h / m:.2f}x | "
                     + ("- | - |" if disc else f"{1e3 * mc:.2f} | {v / mc:.2f}x |"))
        print(lines[-1], flush=True)
    return "\n".join(lines)


def run_size(n: int, p: int, targets, slow: bool) -> dict:
    rows = []
    verb = slow or n < 40
    for plant, are in targets:
        target = are.poles
        row = {"floor": eigenvalue_rounding_floor(plant.A - are.L @ plant.C)}
        res, row["engine_t"] = timed_median(
            lambda pl=plant, tg=target: solve_inverse_kalman(prepare_inverse_kalman(pl), tg))
        row["engine_ok"] = bool(res.success and independent_check(plant, target, res.L, res.Q))
        row["engine_obj"] = res.objective_value
        row["engine_status"] = res.status.value
        if res.L is not None:   # what the rounding of a computed gain does to these poles
            row["pole_err"] = pole_error(np.linalg.eigvals(plant.A - res.L @ plant.C), target)
        if res.L is not None:
            row["min_obj"], row["min_t"] = minimal_sdp(plant, res.L, reuse=False)
            _, row["min_reuse_t"] = minimal_sdp(plant, res.L, reuse=True)
        for method in ("nlp", "sdp") if verb else ():
            if method == "nlp" and p == 1 and n >= 20:
                continue  # (the NLP of one output: the SDP's job; not run at the large sizes)
            r, t = timed(lambda m=method, pl=plant, tg=target: kalman_for_poles(pl, tg, method=m))
            row[f"{method}_t"], row[f"{method}_obj"] = t, r.objective_value
            row[f"{method}_ok"] = bool(r.success and independent_check(plant, target, r.L, r.Q))
        rows.append(row)
        line = (f"  n={n} p={p}: engine {row['engine_t']:.2f}s ok={row['engine_ok']} "
                f"obj {row['engine_obj']:.6g}")
        line += "".join(f" | {m} {row[m + '_t']:.2f}s ok={row[m + '_ok']} obj {row[m + '_obj']:.6g}"
                        for m in ("nlp", "sdp") if m + "_t" in row)
        if "min_t" in row:
            line += f" | min-SDP {row['min_t']:.3f}s / re-used {row['min_reuse_t']:.3f}s"
        print(line + f" | floor {row['floor']:.1e}", flush=True)
    return {"n": n, "p": p, "rows": rows}


def median(rows, key):
    vals = [r[key] for r in rows if key in r and np.isfinite(r[key])]
    return statistics.median(vals) if vals else float("nan")


def summarize(res: dict) -> dict:
    rows = res["rows"]
    out = {"n": res["n"], "p": res["p"], "targets": len(rows)}
    for m in ("engine", "nlp", "sdp", "min", "min_reuse"):
        out[f"{m}_t"] = median(rows, f"{m}_t")
    for m in ("engine", "nlp", "sdp"):
        have = [r for r in rows if f"{m}_ok" in r]
        out[f"{m}_ok"] = f"{sum(r[f'{m}_ok'] for r in have)}/{len(have)}" if have else "-"
    rel = [(r["engine_obj"] - r["nlp_obj"]) / abs(r["nlp_obj"]) for r in rows
           if r.get("nlp_ok") and r.get("engine_ok")]
    out["vs_nlp"] = (f"{sum(v < -1e-7 for v in rel)} lower / {sum(abs(v) <= 1e-7 for v in rel)} equal / "
                     f"{sum(v > 1e-7 for v in rel)} higher" if rel else "-")
    out["floors"] = [r["floor"] for r in rows]
    out["pole_errs"] = [r.get("pole_err", float("nan")) for r in rows]
    return out


def fmt_t(v):
    return "-" if not np.isfinite(v) else (f"{v:.3f}" if v < 10 else f"{v:.1f}")


def ratio(a, b):
    return "-" if not (np.isfinite(a) and np.isfinite(b) and b > 0) else f"{a / b:.1f}x"


def table(summaries: list[dict]) -> str:
    head = ("| n, p | engine (s) | verified | `nlp` (s) | verified | `sdp` (s) | verified "
            "| min-SDP rebuilt (s) | min-SDP re-used (s) | nlp / engine | sdp / engine "
            "| engine / min-SDP re-used | sdp / min-SDP re-used | engine vs nlp objective "
            "| rounding floor / pole error of the engine's design, per target |\n|" + "---|" * 15)
    lines = []
    for s in summaries:
        errs = s.get("pole_errs", [float("nan")] * len(s["floors"]))
        floors = ", ".join(f"{f:.0e}" + ("" if not np.isfinite(e) else f" / {e:.0e}")
                           + ("" if not e > POLE_FLOOR_CAP else " (not computable)")
                           for f, e in zip(s["floors"], errs, strict=True))
        lines.append(
            f"| {s['n']}, {s['p']} | {fmt_t(s['engine_t'])} | {s['engine_ok']} | {fmt_t(s['nlp_t'])} "
            f"| {s['nlp_ok']} | {fmt_t(s['sdp_t'])} | {s['sdp_ok']} | {fmt_t(s['min_t'])} "
            f"| {fmt_t(s['min_reuse_t'])} "
            f"| {ratio(s['nlp_t'], s['engine_t'])} | {ratio(s['sdp_t'], s['engine_t'])} "
            f"| {ratio(s['engine_t'], s['min_reuse_t'])} | {ratio(s['sdp_t'], s['min_reuse_t'])} "
            f"| {s['vs_nlp']} | {floors} |")
    return head + "\n" + "\n".join(lines)


STAGES = [("starts (scale scan, placement)", "decision_starts"), ("SQP", "sqp"),
          ("Gauss-Newton restoration", "find_feasible"), ("Newton on the manifold", "newton"),
          ("certificate SDP (complement form, else Clarabel)", "_certify"),
          ("verification (independent re-solve)", "_verify")]


def profile(sizes, rng_seed: int) -> str:
    """cProfile of the engine on one target per size: cumulative CPU time per stage and the top
    functions by own time."""
    out = ["# Profile of the inverse Kalman engine (cProfile, CPU time)\n"]
    for n, p in sizes:
        plant, are = random_target(np.random.default_rng(rng_seed + 1000 * n + p), n, p)
        setup = prepare_inverse_kalman(plant)
        prof = cProfile.Profile(timer=time.process_time)
        prof.enable()
        res = solve_inverse_kalman(setup, are.poles)
        prof.disable()
        st = pstats.Stats(prof)
        total = sum(v[2] for v in st.stats.values())  # own times
        cum = {}
        for (file, _line, name), v in st.stats.items():
            for label, fn in STAGES:
                if name == fn and any(m in file for m in ("inverse_kalman_engine", "inverse_kalman_starts",
                                                          "spectral_newton")):
                    cum[label] = cum.get(label, 0.0) + v[3]
        own = sorted(((v[2], f"{Path(k[0]).name}:{k[2]}") for k, v in st.stats.items()), reverse=True)[:10]
        out.append(f"## n = {n}, p = {p}: {res.status.value}, verified {res.success}, {total:.1f} s CPU "
                   f"in total\n")
        out.append("| stage (cumulative, nested stages overlap) | CPU s | share |\n|---|---|---|")
        out += [f"| {label} | {cum.get(label, 0.0):.2f} | {100 * cum.get(label, 0.0) / total:.0f} % |"
                for label, _ in STAGES]
        out.append("\n| function (own time) | CPU s | share |\n|---|---|---|")
        out += [f"| `{name}` | {t:.2f} | {100 * t / total:.0f} % |" for t, name in own]
        starts = res.details.get("starts", [])
        out.append("\nper start: " + "; ".join(
            f"{r['kind']}: SQP {r.get('sqp_iterations', 0)} it ({r.get('sqp', '')}), restoration "
            f"{r.get('restoration_iterations', 0)} it, Newton "
            f"{sum(h['iterations'] for h in r.get('newton', []))} it, {r['cpu_time']:.1f} s"
            for r in starts) + "\n")
        print("\n".join(out[-3:]), flush=True)
    return "\n".join(out)


#: (module, attribute, label) of the one-output stages timed by :func:`one_output_stages`
ONE_OUTPUT_STAGES = [
    ("optdesign.design.inverse_kalman.verb:InverseKalmanProblem", "_early_answer", "early answers"),
    ("optdesign.design.inverse_kalman.engine_route", "prepare_inverse_kalman", "engine setup (map, form)"),
    ("optdesign.design.inverse_kalman.engine_route", "solve_inverse_kalman", "engine"),
    ("optdesign.engines.inverse_kalman_engine", "single_output_gain", "  gain (one batched solve)"),
    ("optdesign.engines.inverse_kalman_engine", "fixed_gain_family", "  the gain's family"),
    ("optdesign.engines.inverse_kalman_engine", "solve_one_output", "  SDP, n-constraint form (all of it)"),
    ("optdesign.engines.one_output_sdp", "_polish", "  Newton polish (part of the SDP row)"),
    ("optdesign.engines.one_output_sdp", "_kkt", "  KKT test (part of the SDP row)"),
    ("optdesign.engines.inverse_kalman_engine", "riccati_of_gain", "  design (Lyapunov P)"),
    ("optdesign.engines.inverse_kalman_engine", "spectral_terms", "  general route: spectral terms"),
    ("optdesign.engines.inverse_kalman_engine", "solve_fixed_gain", "  general route: Clarabel, direct form"),
    ("optdesign.engines.inverse_kalman_engine", "solve_fixed_gain_ipm", "  general route: dense IPM"),
    ("optdesign.engines.inverse_kalman_engine", "_optimize", "  general route: polish"),
    ("optdesign.design.inverse_kalman.engine_route", "verify_design", "verification"),
    ("optdesign.design.inverse_kalman.common", "newton_kalman_checks", "  Newton-step checks (all of them)"),
    ("optdesign.design.verification", "are_correction_of_terms",
     "  Newton correction and forward error (part of the row above)"),
    ("optdesign.design.verification", "hamiltonian_are", "  full checks: re-solve (lean: Hamiltonian)"),
    ("optdesign.design.verification", "independent_are", "  full checks: re-solve (scipy)"),
    ("optdesign.design.inverse_kalman.common", "pole_check", "  full checks: poles and their rounding floor"),
]


def one_output_stages(reps: int = 10) -> str:
    """CPU ms per stage of ``kalman_for_poles`` on one output (the engine route), timed by wrappers
    around the stage functions (cProfile's overhead would triple the small sizes); the targets of the
    main run at n = 2, 10 (all three) and 20 (its first, computable, target)."""
    import importlib

    acc: dict[str, float] = {}

    def timer(fn, label):
        def wrapped(*a, **k):
            t0 = time.process_time()
            try:
                return fn(*a, **k)
            finally:
                acc[label] = acc.get(label, 0.0) + time.process_time() - t0
        return wrapped

    saved = []
    for where, attr, label in ONE_OUTPUT_STAGES:
        mod, _, cls = where.partition(":")
        obj = importlib.import_module(mod)
        obj = getattr(obj, cls) if cls else obj
        saved.append((obj, attr, getattr(obj, attr)))
        setattr(obj, attr, timer(getattr(obj, attr), label))
    rng = np.random.default_rng(0)
    drawn = {size: [random_target(rng, *size) for _ in range(3)] for size in SIZES[:3]}
    cols = {}
    try:
        for n, picks in ((2, [0, 1, 2]), (10, [0, 1, 2]), (20, [0])):
            acc.clear()
            total, ok, count = 0.0, 0, 0
            for _ in range(reps if n < 20 else max(1, reps // 2)):
                for i in picks:
                    plant, are = drawn[(n, 1)][i]
                    res, t = timed(lambda pl=plant, tg=are.poles: kalman_for_poles(pl, tg))
                    total, ok, count = total + t, ok + res.success, count + 1
            cols[n] = {"total": 1e3 * total / count, **{k: 1e3 * v / count for k, v in acc.items()},
                       "verified": f"{ok}/{count}"}
    finally:
        for obj, attr, fn in saved:
            setattr(obj, attr, fn)
    labels = ["total"] + [label for _, _, label in ONE_OUTPUT_STAGES]
    lines = ["| stage (CPU ms per design; indented: part of the row above) | n = 2 | n = 10 | n = 20 |",
             "|---|---|---|---|"]
    for label in labels + ["verified"]:
        vals = [cols[n].get(label) for n in (2, 10, 20)]
        lines.append(f"| {label.strip() if not label.startswith('  ') else '- ' + label.strip()} | "
                     + " | ".join("-" if v is None else (v if isinstance(v, str) else f"{v:.2f}")
                                  for v in vals) + " |")
    return "\n".join(lines)


def sparse_fixed_gain(plant: Plant, L, options: dict) -> tuple[str, float, int]:
    """The fixed-gain SDP (one output, continuous, min trace Q) in the sparse form: svec P and svec Q
    as variables, ``P C' = L R`` and ``Q + A P + P A' = L R L'`` as equalities, Q in Clarabel's PSD
    cone; data scaled as the direct form's.  Returns (Clarabel status, trace Q, iterations)."""
    import clarabel
    import scipy.sparse as sp

    from optdesign.backends.clarabel_fixed_gain import CLARABEL_OPTIONS, smat, svec

    A, C, R = plant.A, plant.C, np.asarray(plant.R, dtype=float)
    n, p = C.shape[1], C.shape[0]
    LR = L @ R
    LRL = LR @ L.T
    s = max(float(np.linalg.norm(LRL)), float(np.linalg.norm(LR)))
    I, J = np.triu_indices(n)
    order = np.lexsort((I, J))
    I, J = I[order], J[order]
    w = np.where(I == J, 1.0, np.sqrt(2.0))
    nt, c, off = I.size, np.arange(I.size), I != J
    D = sp.csc_matrix((np.r_[1 / w, (1 / w)[off]], (np.r_[J * n + I, (I * n + J)[off]], np.r_[c, c[off]])),
                      shape=(n * n, nt))                          # vec(P) = D svec(P)
    S = sp.csc_matrix((w, (c, J * n + I)), shape=(nt, n * n))     # svec(X) = S vec(X)
    E = sp.identity(n, format="csc")
    As = sp.csc_matrix(A)
    Amat = sp.vstack([sp.hstack([sp.kron(sp.csc_matrix(C), E) @ D, sp.csc_matrix((n * p, nt))]),
                      sp.hstack([S @ (sp.kron(E, As) + sp.kron(As, E)) @ D, sp.identity(nt)]),
                      sp.hstack([sp.csc_matrix((nt, nt)), -sp.identity(nt)])], format="csc")
    b = np.r_[(LR / s).ravel(order="F"), svec(0.5 * (LRL + LRL.T) / s), np.zeros(nt)]
    q = np.r_[np.zeros(nt), (I == J).astype(float)]
    st = clarabel.DefaultSettings()
    st.verbose = False
    for k, v in {**CLARABEL_OPTIONS, **options}.items():
        setattr(st, k, v)
    sol = clarabel.DefaultSolver(sp.csc_matrix((2 * nt, 2 * nt)), q, Amat, b,
                                 [clarabel.ZeroConeT(n * p + nt), clarabel.PSDTriangleConeT(n)], st).solve()
    Q = s * smat(np.asarray(sol.x)[nt:], n)
    return str(sol.status), float(np.trace(Q)), int(sol.iterations)


def sdp_forms() -> str:
    """CPU ms of one fixed-gain SDP on Clarabel: the direct form (``solve_fixed_gain``) with Clarabel's
    default KKT solver and with QDLDL, and (one output) the sparse form of :func:`sparse_fixed_gain`
    with QDLDL and the default, each with Clarabel's default regularization and the 1e-7 of its first
    retry; the gain is the one the poles fix (one output, the main run's targets) or the Kalman gain of
    the target (several outputs).  Medians of 3 runs per target."""
    from optdesign.design.inverse_kalman.common import placed_gain
    from optdesign.backends.clarabel_fixed_gain import family_map, fixed_gain_family, solve_fixed_gain

    def cpu_ms(fn):
        out, ts = None, []
        for _ in range(3):
            out, t = timed(fn)
            ts.append(1e3 * t)
        return out, statistics.median(ts)

    rng = np.random.default_rng(0)
    drawn = {size: [random_target(rng, *size) for _ in range(3)] for size in SIZES}
    lines = ["| n, p | target | direct, default KKT | direct, QDLDL | sparse, default KKT | sparse, QDLDL "
             "| sparse, default KKT, reg 1e-7 |", "|---|---|---|---|---|---|---|"]
    for n, p in [(10, 1), (20, 1), (5, 2), (10, 4), (20, 2), (20, 4), (40, 8)]:
        for i, (plant, are) in enumerate(drawn[(n, p)][: 1 if n == 40 else 3]):
            L = placed_gain(plant, are.poles) if p == 1 else are.L
            fmap = family_map(plant.A, plant.C, plant.dt)
            cells = []
            for kkt in ("auto", "qdldl"):
                sol, t = cpu_ms(lambda L=L, k=kkt, fm=fmap, R=plant.R: solve_fixed_gain(
                    fixed_gain_family(fm, L, R), options={"direct_solve_method": k}))
                tr = float(np.trace(sol.Q)) if sol.Q is not None else float("nan")
                cells.append(f"{t:.1f} ms, {sol.native_status}, tr Q {tr:.9g}, {sol.iterations} it")
            for opts in ({"direct_solve_method": "auto"}, {}, {"direct_solve_method": "auto",
                                                               "static_regularization_constant": 1e-7}):
                if p > 1:
                    cells.append("-")
                    continue
                (st, tr, it), t = cpu_ms(lambda L=L, o=opts, pl=plant: sparse_fixed_gain(pl, L, o))
                cells.append(f"{t:.1f} ms, {st}, tr Q {tr:.9g}, {it} it")
            lines.append(f"| {n}, {p} | {i} | " + " | ".join(cells) + " |")
            print(lines[-1], flush=True)
    return "\n".join(lines)


def verify_ab(rounds: int = 15) -> str:
    """A/B in one process: the verb's verification of the engine's one-output designs with the
    Hamiltonian re-solve (``avoid="scipy"``, the re-solver before issue 14's second one-output pass)
    and with scipy's (``avoid="hamiltonian"``, the engine route's now), interleaved; CPU ms per
    verification, medians over the rounds; whether the two verdicts agree on every design."""
    from optdesign.design.inverse_kalman.common import verify_design

    rng = np.random.default_rng(0)
    drawn = {size: [random_target(rng, *size) for _ in range(3)] for size in SIZES[:3]}
    lines = ["| n | Hamiltonian re-solve (ms) | scipy re-solve (ms) | ratio | same verdicts |",
             "|---|---|---|---|---|"]
    for n, picks in ((2, [0, 1, 2]), (10, [0, 1, 2]), (20, [0])):
        t: dict[str, list[float]] = {"scipy": [], "hamiltonian": []}
        same = True
        for _ in range(rounds):
            for i in picks:
                plant, are = drawn[(n, 1)][i]
                r = kalman_for_poles(plant, are.poles)
                verdict = {}
                for avoid in ("scipy", "hamiltonian"):
                    (ver, _), dt = timed(lambda a=avoid, pl=plant, tg=are.poles, r=r: verify_design(
                        pl, tg, r.L, r.P, r.Q, None, "full", 1e-8, avoid=a))
                    t[avoid].append(1e3 * dt)
                    verdict[avoid] = ver.passed
                same &= verdict["scipy"] == verdict["hamiltonian"]
        h, sc = statistics.median(t["scipy"]), statistics.median(t["hamiltonian"])
        lines.append(f"| {n} | {h:.2f} | {sc:.2f} | {sc / h:.2f} | {'yes' if same else 'no'} |")
        print(lines[-1], flush=True)
    return "\n".join(lines)


@contextlib.contextmanager
def general_route():
    """The one-output engine without its first route, the n-constraint form
    (``optdesign.engines.one_output_sdp``): what runs when that form certifies nothing -- the A/B
    modes of the general route's own choices (``--first-try``, ``--ipm``) measure it."""
    import optdesign.engines.inverse_kalman_engine as eng

    real = eng._one_output_form
    eng._one_output_form = lambda *a, **k: None
    try:
        yield
    finally:
        eng._one_output_form = real


def form_ab(count: int = 40, discrete: int = 10) -> str:
    """The n-constraint form (``optdesign.engines.one_output_sdp``, the engine's first one-output
    route) against the general route it replaces (the direct form on Clarabel or the dense IPM,
    polished on its face), on the main run's one-output targets, ``count`` random continuous ones
    (n = 2..20, seed 123, as ``--ipm``) and ``discrete`` random discrete ones (n = 2..12, seed 7):
    statuses, verified designs, the largest relative objective difference, Clarabel's status on each
    form, CPU per design (interleaved per target, medians of 3)."""
    rng = np.random.default_rng(0)
    targets = [t for size in SIZES[:3] for t in (random_target(rng, *size) for _ in range(3))]
    rng = np.random.default_rng(123)
    targets += [t for t in (random_target(rng, int(rng.integers(2, 21)), 1) for _ in range(count)) if t]
    rng = np.random.default_rng(7)
    targets += [t for t in (random_discrete_target(rng, int(rng.integers(2, 13))) for _ in range(discrete))
                if t]
    out: dict[str, list] = {"n-constraint form": [], "general route": []}
    for plant, are in targets:
        for name in out:
            ts = []
            for _ in range(3):
                if name == "general route":
                    with general_route():
                        r, t = timed(lambda pl=plant, tg=are.poles: kalman_for_poles(pl, tg))
                else:
                    r, t = timed(lambda pl=plant, tg=are.poles: kalman_for_poles(pl, tg))
                ts.append(t)
            sdp = r.extra.get("engine", {}).get("sdp", {})
            out[name].append((plant.n, plant.is_discrete, r.status.value, r.success, r.objective_value,
                              sdp.get("native", "-"), statistics.median(ts)))
    ref = out["general route"]
    lines = [f"{len(targets)} one-output min-trace targets (the main run's 9 at n = 2, 10, 20, {count} "
             f"random continuous n = 2..20 (seed 123), {discrete} random discrete n = 2..12 (seed 7))", "",
             "| route | verified | optimal | same status as the general route | max rel. objective diff "
             "(both verified) | Clarabel's status | CPU per design, median (ms) | n <= 8 | n >= 15 | "
             "discrete |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for name, rows in out.items():
        same = sum(a[2] == b[2] for a, b in zip(rows, ref, strict=True))
        dif = max((abs(a[4] - b[4]) / max(1e-300, abs(b[4])) for a, b in zip(rows, ref, strict=True)
                   if a[3] and b[3]), default=0.0)
        natives = ", ".join(f"{k} {sum(r[5] == k for r in rows)}" for k in sorted({r[5] for r in rows}))

        def med(sel, rr=rows):
            vals = [r[6] for r in rr if sel(r)]
            return f"{1e3 * statistics.median(vals):.2f}" if vals else "-"

        lines.append(f"| {name} | {sum(r[3] for r in rows)}/{len(rows)} | "
                     f"{sum(r[2] == 'optimal' for r in rows)}/{len(rows)} | {same}/{len(rows)} | {dif:.1e} | "
                     f"{natives} | {med(lambda r: True)} | {med(lambda r: r[0] <= 8 and not r[1])} | "
                     f"{med(lambda r: r[0] >= 15)} | {med(lambda r: r[1])} |")
        print(lines[-1], flush=True)
    return "\n".join(lines)


def first_try_ab(count: int = 40) -> str:
    """The one-output first try (``ONE_OUTPUT_FIRST_TRY``) against Clarabel at the tight
    ``CLARABEL_OPTIONS`` as first try, on the main run's one-output targets and ``count`` random
    min-trace targets (n = 2..20, seed 123): the same statuses / verified count / optima?  Clarabel
    iterations of the accepted solve, how often the first try was not certified (solved again or
    not computable), CPU per design."""
    import optdesign.engines.inverse_kalman_engine as eng
    from optdesign.backends.clarabel_fixed_gain import CLARABEL_OPTIONS

    rng = np.random.default_rng(0)
    targets = [t for size in SIZES[:3] for t in (random_target(rng, *size) for _ in range(3))]
    rng = np.random.default_rng(123)
    targets += [t for t in (random_target(rng, int(rng.integers(2, 21)), 1) for _ in range(count)) if t]
    chosen = dict(eng.ONE_OUTPUT_FIRST_TRY)
    tight = {k: v for k, v in CLARABEL_OPTIONS.items() if k.startswith("tol")}
    configs = (("tight (1e-10)", tight), ("ONE_OUTPUT_FIRST_TRY", chosen))
    out: dict[str, list] = {name: [] for name, _ in configs}
    try:
        with general_route():
            for plant, are in targets:   # the two settings interleaved per target (a shared machine)
                for name, opts in configs:
                    eng.ONE_OUTPUT_FIRST_TRY.clear()
                    eng.ONE_OUTPUT_FIRST_TRY.update(opts)
                    ts = []
                    for _ in range(3):
                        r, t = timed(lambda pl=plant, tg=are.poles: kalman_for_poles(pl, tg))
                        ts.append(t)
                    e = r.extra.get("engine", {})
                    its = e.get("sdp", {}).get("iterations", 0)
                    out[name].append((r.status.value, r.success, r.objective_value, its, "first_try" in e,
                                      statistics.median(ts)))
    finally:
        eng.ONE_OUTPUT_FIRST_TRY.clear()
        eng.ONE_OUTPUT_FIRST_TRY.update(chosen)
    ref = out["tight (1e-10)"]
    lines = [f"{len(targets)} one-output min-trace targets (the main run's 9 at n = 2, 10, 20 and {count} "
             "random, n = 2..20, seed 123)", "",
             "| first try | verified | same status as tight | max rel. objective diff vs tight | median "
             "Clarabel iterations (accepted solve) | not certified (solved again / not computable) | CPU per "
             "design (median over targets of the median of 3, ms) | CPU, n >= 15 (ms) |",
             "|---|---|---|---|---|---|---|---|"]
    big = [plant.n >= 15 for plant, _ in targets]
    for name, rows in out.items():
        same = sum(a[0] == b[0] for a, b in zip(rows, ref, strict=True))
        dif = max((abs(a[2] - b[2]) / max(1.0, abs(b[2])) for a, b in zip(rows, ref, strict=True)
                   if np.isfinite(a[2]) and np.isfinite(b[2])), default=0.0)
        lines.append(f"| {name} | {sum(r[1] for r in rows)}/{len(rows)} | {same}/{len(rows)} | {dif:.1e} | "
                     f"{statistics.median(r[3] for r in rows):.0f} | {sum(r[4] for r in rows)} | "
                     f"{1e3 * statistics.median(r[5] for r in rows):.1f} | "
                     f"{1e3 * statistics.median(r[5] for r, b in zip(rows, big, strict=True) if b):.1f} |")
    return "\n".join(lines)


def ipm_ab(count: int = 40) -> tuple[str, str]:
    """The dense IPM (``optdesign.engines.fixed_gain_ipm``) against Clarabel (tight
    ``CLARABEL_OPTIONS``) on the same one-output min-trace SDPs at the unique gain (iterations, CPU
    ms (median of 3), relative trace-Q difference), and the whole design with the IPM on and off
    (``ONE_OUTPUT_IPM_MIN_DIM`` huge): verified, same status, objective difference, CPU.  Targets:
    the main run's one-output ones and ``count`` random ones (n = 2..20, seed 123, as
    ``--first-try``), the two settings interleaved per target (a shared machine)."""
    import optdesign.engines.inverse_kalman_engine as eng
    from optdesign.backends.clarabel_fixed_gain import family_map, fixed_gain_family, solve_fixed_gain
    from optdesign.engines.fixed_gain_ipm import solve_fixed_gain_ipm

    rng = np.random.default_rng(0)
    targets = [t for size in SIZES[:3] for t in (random_target(rng, *size) for _ in range(3))]
    rng = np.random.default_rng(123)
    targets += [t for t in (random_target(rng, int(rng.integers(2, 21)), 1) for _ in range(count)) if t]
    sdp: dict[int, list] = {}
    design: dict[str, list] = {"IPM on": [], "IPM off": []}
    on = eng.ONE_OUTPUT_IPM_MIN_DIM
    try:
        for plant, are in targets:
            fmap = family_map(plant.A, plant.C, None)
            fam = fixed_gain_family(fmap, are.L, np.asarray(plant.R, dtype=float))
            tc, ti = [], []
            for _ in range(3):
                ref, t = timed(lambda f=fam: solve_fixed_gain(f))
                tc.append(t)
                (sol, rep), t = timed(lambda f=fam: solve_fixed_gain_ipm(f))
                ti.append(t)
            dif = (abs(np.trace(sol.Q) - np.trace(ref.Q)) / max(1.0, abs(np.trace(ref.Q)))
                   if sol is not None and ref.Q is not None else float("nan"))
            floor = eigenvalue_rounding_floor(plant.A - are.L @ plant.C)
            sdp.setdefault(plant.n, []).append((ref.native_status, ref.iterations, rep.converged,
                                                rep.iterations, statistics.median(tc),
                                                statistics.median(ti), dif, floor))
            for name, dim in (("IPM on", on), ("IPM off", 10**9)):
                eng.ONE_OUTPUT_IPM_MIN_DIM = dim
                ts = []
                for _ in range(3):
                    with general_route():
                        r, t = timed(lambda pl=plant, tg=are.poles: kalman_for_poles(pl, tg))
                    ts.append(t)
                native = r.extra.get("engine", {}).get("sdp", {}).get("native", "")
                design[name].append((plant.n, r.status.value, r.success, r.objective_value,
                                     native == "ipm: optimal", statistics.median(ts)))
    finally:
        eng.ONE_OUTPUT_IPM_MIN_DIM = on
    lines = [f"{len(targets)} one-output min-trace targets (the main run's 9 at n = 2, 10, 20 and "
             f"{count} random, n = 2..20, seed 123)", "",
             "## One SDP at the unique gain: Clarabel (CLARABEL_OPTIONS) vs the dense IPM", "",
             "| n | targets | Clarabel statuses | IPM converged | median iterations Clarabel / IPM | "
             "CPU ms Clarabel / IPM (medians) | IPM / Clarabel | max rel. trace-Q diff, targets with "
             "floor <= 1e-8 | max rel. trace-Q diff, all |", "|---|---|---|---|---|---|---|---|---|"]
    for n in sorted(sdp):
        rows = sdp[n]
        sts = ", ".join(f"{k} {sum(r[0] == k for r in rows)}" for k in sorted({r[0] for r in rows}))
        good = [r[6] for r in rows if r[7] <= 1e-8 and np.isfinite(r[6])]
        tcm, tim = statistics.median(r[4] for r in rows), statistics.median(r[5] for r in rows)
        lines.append(f"| {n} | {len(rows)} | {sts} | {sum(r[2] for r in rows)}/{len(rows)} | "
                     f"{statistics.median(r[1] for r in rows):.0f} / "
                     f"{statistics.median(r[3] for r in rows):.0f} | "
                     f"{1e3 * tcm:.2f} / {1e3 * tim:.2f} | {tim / tcm:.2f} | "
                     f"{max(good) if good else float('nan'):.1e} | {np.nanmax([r[6] for r in rows]):.1e} |")
    ref = design["IPM off"]
    lines += ["", f"## The design (kalman_for_poles) with the IPM on (n - p >= {on}) and off", "",
              "| setting | verified | same status as off | max rel. objective diff vs off | designs from "
              "the IPM | CPU per design, median (ms) | CPU, n >= 10 (ms) | CPU, n >= 15 (ms) |",
              "|---|---|---|---|---|---|---|---|"]
    for name, rows in design.items():
        same = sum(a[1] == b[1] for a, b in zip(rows, ref, strict=True))
        dif = max((abs(a[3] - b[3]) / max(1.0, abs(b[3])) for a, b in zip(rows, ref, strict=True)
                   if np.isfinite(a[3]) and np.isfinite(b[3])), default=0.0)
        med = lambda lo, rr=rows: 1e3 * statistics.median(r[5] for r in rr if r[0] >= lo)  # noqa: E731
        lines.append(f"| {name} | {sum(r[2] for r in rows)}/{len(rows)} | {same}/{len(rows)} | {dif:.1e} | "
                     f"{sum(r[4] for r in rows)} | {med(0):.1f} | {med(10):.1f} | {med(15):.1f} |")
    return "\n".join(lines), json.dumps({"sdp": {str(k): v for k, v in sdp.items()}, "design": design})


def merge_earlier(summaries: list[dict], raw: list[dict]) -> list[tuple[int, int]]:
    """Add the sizes not re-run from the existing ``inverse_kalman.json`` (in place, in the order of
    :data:`SIZES`); returns the sizes taken from it."""
    path = OUT / "inverse_kalman.json"
    if not path.exists():
        return []
    old = json.loads(path.read_text(encoding="utf-8"))
    have = {(s["n"], s["p"]) for s in summaries}
    kept = [(s["n"], s["p"]) for s in old["summaries"] if (s["n"], s["p"]) not in have]
    summaries += [s for s in old["summaries"] if (s["n"], s["p"]) in kept]
    raw += [r for r in old["raw"] if (r["n"], r["p"]) in kept]
    order = {size: i for i, size in enumerate(SIZES)}
    summaries.sort(key=lambda s: order.get((s["n"], s["p"]), len(SIZES)))
    raw.sort(key=lambda r: order.get((r["n"], r["p"]), len(SIZES)))
    return kept


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reps", type=int, default=3, help="targets per size")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--sizes", type=str, default=None,
                    help="subset, e.g. 10x4,20x4 (same targets as the full run)")
    ap.add_argument("--slow", action="store_true", help="also run the verb at (40, 8)")
    ap.add_argument("--stages", action="store_true",
                    help="only the CPU per stage of the one-output verb at n = 2, 10, 20")
    ap.add_argument("--merge", action="store_true",
                    help="with --sizes: keep the other sizes' rows of the existing results (marked)")
    ap.add_argument("--verify-ab", action="store_true",
                    help="only the verification of one-output designs, Hamiltonian vs scipy re-solve")
    ap.add_argument("--sdp-forms", action="store_true",
                    help="only the fixed-gain SDP: direct vs sparse form, Clarabel's KKT solvers")
    ap.add_argument("--first-try", action="store_true",
                    help="only the one-output first try vs the tight Clarabel tolerances")
    ap.add_argument("--ipm", action="store_true",
                    help="only the one-output dense IPM vs Clarabel (one SDP, and the whole design)")
    ap.add_argument("--form", action="store_true",
                    help="only the one-output n-constraint form vs the general route it replaces")
    ap.add_argument("--verb-ratio", action="store_true",
                    help="only the one-output verb vs the re-used minimal SDP, per target (medians of 7)")
    ap.add_argument("--profile", action="store_true",
                    help="only the cProfile of the engine at (20, 4), (40, 8)")
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    warm = random_target(np.random.default_rng(99), 3, 2)   # imports and first calls out of the timing
    solve_inverse_kalman(prepare_inverse_kalman(warm[0]), warm[1].poles)
    kalman_for_poles(warm[0], warm[1].poles, method="nlp")
    if args.stages:
        write_md("inverse_kalman_stages_one_output.md",
                 "# kalman_for_poles, one output: CPU per stage\n\n`python "
                 "benchmarks/bench_inverse_kalman.py --stages` (means over 10 repetitions of the main run's "
                 "targets; n = 20: 5 of its first, the computable one)", one_output_stages())
        return
    if args.verify_ab:
        print(verify_ab())
        return
    if args.verb_ratio:
        write_md("inverse_kalman_verb_ratio.md",
                 "# kalman_for_poles (the verb), one output, vs the re-used minimal cvxpy SDP\n\n`python "
                 "benchmarks/bench_inverse_kalman.py --verb-ratio` (CPU time, medians of 7 interleaved calls "
                 "per target; the main run's targets, then 3 at each of n = "
                 + ", ".join(map(str, VERB_SIZES)) + ")", verb_ratio())
        return
    if args.form:
        write_md("inverse_kalman_one_output_form.md",
                 "# One output: the n-constraint form vs the general route\n\n`python "
                 "benchmarks/bench_inverse_kalman.py --form` (CPU time, the two routes interleaved per "
                 "target)",
                 form_ab())
        return
    if args.first_try:
        write_md("inverse_kalman_one_output_tolerances.md",
                 "# The one-output first try: Clarabel at ONE_OUTPUT_FIRST_TRY vs the tight tolerances\n\n"
                 "`python benchmarks/bench_inverse_kalman.py --first-try` (the machine shared with other "
                 "jobs)", first_try_ab())
        return
    if args.ipm:
        text, raw_json = ipm_ab()
        write_md("inverse_kalman_one_output_ipm.md",
                 "# The one-output fixed-gain SDP: the dense IPM vs Clarabel\n\n`python "
                 "benchmarks/bench_inverse_kalman.py --ipm` (CPU time, the machine shared with other jobs)",
                 text)
        (OUT / "inverse_kalman_one_output_ipm.json").write_text(raw_json + "\n", encoding="utf-8")
        return
    if args.sdp_forms:
        write_md("inverse_kalman_sdp_forms.md",
                 "# The fixed-gain SDP on Clarabel: direct vs sparse form, KKT solvers\n\n"
                 "`python benchmarks/bench_inverse_kalman.py --sdp-forms` (CPU ms per SDP, medians of 3; the "
                 "machine shared with other jobs)", sdp_forms())
        return
    if args.profile:
        text = profile([(20, 4), (40, 8)], args.seed)
        (OUT / "inverse_kalman_profile.md").write_text(text + "\n", encoding="utf-8")
        return
    wanted = SIZES if args.sizes is None else [tuple(int(v) for v in s.split("x"))
                                                for s in args.sizes.split(",")]
    rng = np.random.default_rng(args.seed)
    summaries, raw = [], []
    for n, p in SIZES:   # every size's targets are drawn, so that a subset gets the full run's targets
        targets = [t for t in (random_target(rng, n, p) for _ in range(args.reps)) if t is not None]
        if (n, p) not in wanted:
            continue
        res = run_size(n, p, targets, args.slow)
        raw.append(res)
        summaries.append(summarize(res))
    kept = merge_earlier(summaries, raw) if args.merge and args.sizes is not None else []
    text = ("# kalman_for_poles: the engine without an NLP vs the current verb vs minimal SDPs\n\n"
            f"`python benchmarks/bench_inverse_kalman.py` -- {platform.machine()}, Python "
            f"{platform.python_version()}, single-threaded BLAS, CPU seconds per design (medians of "
            f"{args.reps} targets, seed {args.seed}; the engine and the re-used minimal SDP: each the "
            f"median of {REPEATS} calls when a call takes under {REPEAT_BELOW} s), the machine shared with "
            "other jobs.\n\n"
            + table(summaries) + "\n\n"
            "Random continuous plants (A ~ N(0, 1/n), C ~ N(0, 1), R = I), targets = poles of the Kalman "
            "filter of Q = F F' / n.  'verified': scipy's Riccati solver with the returned Q reproduces the "
            "targets to their rounding floor (at least 1e-8) and L to 1e-6.  'min-SDP': the issue's "
            "hand-written minimal cvxpy SDP at the engine's L (a reference for the cost of one SDP at a "
            "known gain, not a design: its point is not polished).  'engine vs nlp objective': trace Q of "
            "the engine vs the NLP's (both local optima over L; 1e-7 relative is 'equal').  With one output "
            "the poles fix L: the engine is the fixed-gain SDP in its n-constraint form "
            "(optdesign.engines.one_output_sdp: Clarabel, a Newton polish, a KKT certificate), and where "
            "that certifies nothing its direct form (the dense IPM or Clarabel); the engine column "
            "includes its own verification with a scipy re-solve, the verb's is the lean one.  Last "
            "column, per target: the rounding floor of the poles "
            "(eigenvalue_rounding_floor: 10 eps times their condition, an upper estimate) and the relative "
            "pole error of the engine's gain (what rounding did); 'not computable': that error exceeds the "
            "verb's cap of 1e-6 -- the poles' condition is so large (floor 6e-2 .. 2) that the gain the "
            "targets fix cannot be computed in double precision to place them to 1e-6, so no method's design "
            "verifies (the verb returns the engine's design, unverified, status optimal_inaccurate, without "
            "running the SDP routes: the placed gain refined for its poles misses them too).  "
            "'-': not run (the verb at (40, 8) took 533 s per design in the README's "
            "run; `--slow` runs it).\n")
    if kept:
        text += ("\nRe-run in this run: " + ", ".join(f"({n}, {p})" for n, p in wanted) + "; the rows "
                 + ", ".join(f"({n}, {p})" for n, p in kept) + " are from the earlier run's "
                 "inverse_kalman.json (not re-run: `--merge`).\n")
    print("\n" + text)
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "inverse_kalman.md").write_text(text, encoding="utf-8")
    with open(OUT / "inverse_kalman.csv", "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        keys = ["engine_t", "engine_ok", "engine_obj", "engine_status", "nlp_t", "nlp_ok", "nlp_obj", "sdp_t",
                "sdp_ok", "sdp_obj", "min_t", "min_reuse_t", "min_obj", "floor"]
        w.writerow(["n", "p", "target"] + keys)
        for res in raw:
            for i, row in enumerate(res["rows"]):
                w.writerow([res["n"], res["p"], i] + [row.get(k, "") for k in keys])
    (OUT / "inverse_kalman.json").write_text(json.dumps({"summaries": summaries, "raw": raw}, indent=1,
                                                        default=float), encoding="utf-8")
    print(f"written to {OUT}/inverse_kalman.{{md,csv,json}}")


if __name__ == "__main__":
    main()
