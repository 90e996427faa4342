r"""The inverse Kalman problem without an NLP: null-vector Newton outside, the fixed-gain SDP inside.

Given a plant ``(A, C, R[, G, dt])`` and stable target poles, find ``Q >= 0`` (in a structure),
``P >= 0`` and the steady-state Kalman gain ``L`` with ``eig(A - L C) = targets``, the best
``Q`` for an objective among all such.

How
---
The poles fix L only for one output.  With p outputs the gains with the target poles are
parametrized by one null vector ``g_b`` per target block (:mod:`optdesign.engines.spectral_factor`:
``L' W = G`` with ``w_b = -G1_b^T g_b``), and a gain is a Kalman gain of ``Q`` iff every
``(R + G2_b Q G1_b^T) g_b = 0`` -- bilinear in ``(Q, g)``, linear in Q for fixed g (the fixed-gain
SDP: :mod:`optdesign.backends.clarabel_fixed_gain`).  With ``Qdec = V V'`` (``Q = Gd Qdec Gd'``)
:func:`solve_inverse_kalman` runs, from each of a few starts (a scaled identity whose Kalman poles
are closest to the targets, the nominal for ``"nearest"``, seeded random covariances, a caller's
warm start; :mod:`optdesign.engines.inverse_kalman_starts`):

1. *Feasibility* -- SQP over ``(V, g)`` (V of ``min(k, 2p + 2)`` columns) with a filter line search
   until nearly feasible, the objective reduced on the way, then Gauss-Newton onto the feasible
   set (from where the SQP stopped, else from the start with a full-rank factor): a Kalman filter
   with exactly the target poles.  Descending while becoming feasible lands in better basins than
   projecting first (measured on the cross-validation targets: 0 of 100 worse than the NLP with
   the SQP, 1 with the projection alone).
2. *Optimization over L* -- Newton's method on the feasible manifold (closed-form reduced Hessian
   of the Lagrangian, trust-region steps, retraction by Gauss-Newton, vanishing columns of V
   truncated), then the dual slack S of the joint problem: a negative eigenvalue adds a column
   (a rank-increasing descent direction) and Newton continues; S >= 0 at the end is a KKT point
   over every decision covariance.

and keeps the best local optimum, then

3. *Certificate* -- the fixed-gain SDP at that L: for a full Q and the minimal trace first in its
   complement form (``n p - p(p - 1)/2`` constraints, :mod:`optdesign.engines.one_output_sdp`: the
   dense IPM or Clarabel, a Newton polish, a KKT test), else on Clarabel in the direct form: the
   objective's global optimum over the Q of that gain; a better SDP point restarts step 2 from it,
   else the Newton point (exact to rounding) is the answer.  The status is ``optimal`` only when
   that SDP was solved and agrees; the KKT data (dual slack eigenvalue, complementarity) are in
   ``details["kkt"]``.

When no start (nor the rescue starts) reaches a feasible point, or the design of the best misses
the targets (residuals at rounding level do not imply the poles where their Jacobian has condition
~1e11: large noises, issue 26), *continuation in the target poles*
(:mod:`optdesign.engines.pole_homotopy`) runs: the targets move from the Kalman poles of a low-rank
start to the requested ones and Gauss-Newton tracks the factor; the first path end whose Q's Kalman
filter has the targets goes through steps 2-3.  Where the optimum from it misses the targets (not
computable in double precision), Newton stops at the last point whose design places them
(``optimal_inaccurate``, not a local optimum; the message says so).  Its paths are recorded in
``details["starts"]`` (``kind`` ``"pole continuation ..."``, ``steps``, ``continuation``: why the
path ended, ``pole_miss``, ``end_value``).  Not run where the decision covariance has fewer
parameters than pole conditions.

What optimum: a local optimum over L of the objective (several starts, the best kept), at which
the returned Q is the global optimum of the convex family of Q of the returned L.

One output: L is fixed by the poles (``g_b = 1``) and step 3 alone answers, globally -- for a full Q
and the minimal trace first in the SDP's n-constraint form (:mod:`optdesign.engines.one_output_sdp`:
Clarabel, a Newton polish, a KKT certificate), and where that certifies nothing in the direct form
(the dense IPM or Clarabel, polished on its face, repaired if need be) -- an infeasible SDP (or a
negative maximal margin) is a certificate that no ``Q >= 0`` of the structure reaches the targets
(status ``infeasible``).  Several outputs: when no start gives a Kalman filter with the targets the
status is ``not_found`` (a local method: feasibility unknown), never ``infeasible``.

The state that depends only on the plant and the fixed choices (structure, objective) is built
once by :func:`prepare_inverse_kalman` (:mod:`optdesign.engines.inverse_kalman_setup`) -- in
continuous time the SDP's constraint matrix and (full Q, minimal trace) its complement form -- and
re-used for every target, as a caller-held problem object would.

References
----------
Chang & Lee 1984 (seed 000); Anderson & Moore, *Optimal Filtering* (1979); Moore, IEEE TAC 21
(1976) (parametric pole placement); Burer & Monteiro, Math. Program. 95 (2003); Waechter &
Biegler, Math. Program. 106 (2006) (the filter line search); Allgower & Georg, *Numerical
Continuation Methods* (1990) (the continuation).
"""

from __future__ import annotations

import time
from dataclasses import replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._deadline import Deadline, dense_kkt_refusal, dense_time_refusal
from .._validate import as_int, as_poles, as_positive_float
from ..backends.clarabel_fixed_gain import (
    CLARABEL_OPTIONS,
    GAIN_RELATION_RTOL,
    FixedGainFamily,
    FixedGainSolution,
    fixed_gain_family,
    riccati_of_gain,
    solve_fixed_gain,
)
from ..classical.placement import pole_error
from ..classical.riccati import filter_gain
from ..formulate.inverse_kalman import spectral_terms
from ..formulate.inverse_kalman.common import single_output_gain
from ..results import Status
from .fixed_gain_ipm import solve_fixed_gain_ipm
from .inverse_kalman_parts import (
    EngineCandidate,
    candidate_from_sdp,
    candidate_from_start,
    nominal_factor,
    physical_objective,
    repaired_candidate,
    sdp_value,
    warm_factor,
)
from .inverse_kalman_result import POLE_FLOOR_CAP, EngineResult, engine_result, sdp_record
from .inverse_kalman_setup import SCALE_FLOOR, EngineSetup, engine_applies, prepare_inverse_kalman
from .inverse_kalman_starts import decision_starts, homotopy_starts, rescue_starts, stable_mask
from .one_output_sdp import OneOutputSolution, one_output_form, solve_one_output
from .pole_homotopy import HOMOTOPY_FIRST_PASS, HOMOTOPY_MAX_STEPS, pole_miss, track
from .polish import refine_gain
from .spectral_factor import FactorProblem, initial_null_vectors, spectral_blocks
from .spectral_newton import escape_direction, newton, project
from .tolerances import (
    CLARABEL_MARGIN_FACTOR,
    ESCAPE_NORM_FLOOR,
    ESCAPE_STEP,
    FIRST_TRY_TOL,
    IK_KKT_TOL,
    INVERSE_KALMAN_POLE_TOL,
)

__all__ = ["EngineSetup", "EngineResult", "prepare_inverse_kalman", "solve_inverse_kalman",
           "engine_applies", "ONE_OUTPUT_FIRST_TRY", "ONE_OUTPUT_FIRST_TRY_MIN_DIM",
           "ONE_OUTPUT_IPM_MIN_DIM"]

#: a one-output SDP margin ``t < -MARGIN_CERTIFICATE_TOL max(1, |Wdec|)`` certifies infeasibility:
#: 1000x Clarabel's feasibility tolerance (``CLARABEL_OPTIONS["tol_feas"]`` = 1e-10)
MARGIN_CERTIFICATE_TOL = CLARABEL_MARGIN_FACTOR * CLARABEL_OPTIONS["tol_feas"]


def _continuation(setup: EngineSetup, terms: list, target: NDArray, Qn: NDArray | None, seed: int,
                  tol: float, deadline: Deadline, records: list) -> EngineCandidate | None:
    """A feasible point by continuation in the target poles from the Kalman poles of a start
    (:func:`~optdesign.engines.inverse_kalman_starts.homotopy_starts`,
    :func:`~optdesign.engines.pole_homotopy.track`; issue 26: large noises whose solutions no start
    projects onto): the first path end that projects onto the targets' residuals and whose Q's
    Kalman filter has the targets (:func:`~optdesign.engines.pole_homotopy.pole_miss`); None when
    none does (each path is recorded in ``records``).  Every path first gets
    :data:`HOMOTOPY_FIRST_PASS` corrections (the paths that arrive mostly do within them), then
    those that ran out of corrections (not into a turning point) are resumed, furthest first."""
    diagonal = setup.structure == "diagonal"
    waiting = []
    for kind, V0, start in homotopy_starts(setup, target, seed, deadline):
        if deadline.expired:
            return None
        rep = track(setup.plant, setup.Gd, V0, start, target, diagonal=diagonal,
                    max_steps=HOMOTOPY_FIRST_PASS, expired=lambda: deadline.expired)
        rec: dict[str, Any] = {"kind": kind}
        records.append(rec)
        cand = _path_end(setup, terms, target, Qn, tol, rep, rec)
        if cand is not None:
            return cand
        if rep.resumable:
            waiting.append((rep, start, rec))
    for rep, start, rec in sorted(waiting, key=lambda w: -w[0].t):
        if deadline.expired or rep.V is None:
            break
        rep = track(setup.plant, setup.Gd, rep.V, start, target, diagonal=diagonal, t0=rep.t, h0=rep.h,
                    max_steps=HOMOTOPY_MAX_STEPS - HOMOTOPY_FIRST_PASS, expired=lambda: deadline.expired,
                    steps0=rep.steps)
        cand = _path_end(setup, terms, target, Qn, tol, rep, rec)
        if cand is not None:
            return cand
    return None


def _path_end(setup: EngineSetup, terms: list, target: NDArray, Qn: NDArray | None, tol: float, rep,
              rec: dict) -> EngineCandidate | None:
    """The candidate at the end of a path that reached the targets, projected onto their residuals,
    when the Kalman filter of its Q has them; else None.  ``rec`` records the path."""
    tic = time.process_time()
    rec.update(steps=rep.steps, continuation=rep.reason, feasible=False)
    if not rep.reached or rep.V is None:
        return None
    diagonal = setup.structure == "diagonal"
    scale = max(float(np.linalg.norm(rep.V @ rep.V.T, 2)), SCALE_FLOOR)
    blocks = spectral_blocks(terms, np.asarray(setup.plant.R, dtype=float), setup.Gd, scale)
    prob = FactorProblem(blocks, rep.V.shape[1], setup.objective, None if Qn is None else Qn / scale,
                         diagonal)
    Vs = rep.V / np.sqrt(scale)
    x, ok, _ = project(prob, prob.pack(Vs, 0.0, initial_null_vectors(blocks, Vs @ Vs.T)))
    if not ok:
        return None
    cand = EngineCandidate(prob, x, scale, kind=rec["kind"], iterations=rep.steps)
    # feasible to rounding in the residuals, whose Jacobian may have condition 1e11: the Kalman
    # filter of its Q may still miss the targets (measured: 6e-8 at trace 6790, 9e-10 at 12828 on
    # the same target); then the next path
    rec["pole_miss"] = _design_miss(setup, cand, target, tol)
    rec["feasible"] = rec["pole_miss"] <= 1.0
    rec["end_value"] = cand.value
    rec["cpu_time"] = rec.get("cpu_time", 0.0) + time.process_time() - tic
    return cand if rec["feasible"] else None


def _sdp_at(setup: EngineSetup, cand: EngineCandidate, Qn: NDArray | None,
            deadline: Deadline) -> FixedGainSolution:
    """The fixed-gain SDP at the gain of the candidate's null vectors: for ``"full"`` / ``"min_trace"``
    first in its complement form (:func:`_complement_form_at`; at n = 40, p = 8 0.6 s where Clarabel
    takes 8-9 s), else (or when that certifies nothing) on Clarabel in the direct form."""
    _, _, g = cand.parts()
    L, _ = cand.problem.blocks.gain(g)
    plant = setup.plant
    fam = fixed_gain_family(setup.family, L, np.asarray(plant.R, dtype=float), Qn)
    if setup.structure == "full" and setup.objective == "min_trace":
        tic = time.process_time()
        out = _complement_form_at(setup, fam, deadline)
        if out is not None:
            sol, Q, P = out
            native = f"complement form: {sol.native_status}"
            return FixedGainSolution(status=Status.OPTIMAL, native_status=native, P=P, Q=Q, Wdec=Q, t=None,
                                     iterations=sol.iterations, solve_time=time.process_time() - tic)
    return solve_fixed_gain(fam, setup.structure, plant.G, setup.objective, Qn, deadline=deadline)


def _complement_form_at(setup: EngineSetup, fam: FixedGainFamily,
                        deadline: Deadline) -> tuple[OneOutputSolution, NDArray, NDArray] | None:
    """``(solution, Q, P)``: the min-trace Q of ``fam`` in the complement form of the fixed-gain SDP (the
    setup's, else the gain's; ``n p - p(p - 1)/2`` constraints:
    :func:`~optdesign.engines.one_output_sdp.solve_one_output`), Newton-polished and KKT-certified,
    and its Riccati solution; None when the form certifies nothing."""
    if fam.gain_residual > GAIN_RELATION_RTOL or deadline.expired:
        return None
    form = setup.complement_form if setup.complement_form is not None else one_output_form(fam.T)
    if form is None:
        return None
    sol = solve_one_output(form, fam, deadline=deadline)
    if sol.Q is None:
        return None
    plant = setup.plant
    P = riccati_of_gain(plant.A, plant.C, fam.L, fam.R, sol.Q, plant.dt)
    return (sol, sol.Q, P) if np.all(np.isfinite(P)) and np.all(np.isfinite(fam.L)) else None


def _optimize(cand: EngineCandidate, deadline: Deadline, max_rounds: int = 6) -> EngineCandidate:
    """Stage 2: Newton over (V, g) on the feasible manifold, with a rank increase along the
    eigenvector of a negative eigenvalue of the dual slack (:func:`escape_direction`) and Newton
    again, until the dual slack is positive semidefinite (a KKT point of the problem over every
    decision covariance) or the ranks are exhausted."""
    prob, x = cand.problem, cand.x
    blocks = prob.blocks
    for _ in range(max_rounds):
        rep = newton(prob, x, expired=lambda: deadline.expired)
        cand.iterations += rep.iterations
        prob, x = rep.problem, rep.x
        cand.multipliers = rep.multipliers
        cand.history.append({"rank": prob.rank, "iterations": rep.iterations, "f": rep.f,
                             "reduced_gradient": rep.reduced_gradient, "reason": rep.reason,
                             "truncated": rep.truncated})
        if deadline.expired or prob.diagonal:
            break
        S_tol = IK_KKT_TOL * max(1.0, float(np.linalg.norm(prob.dual_slack(x, rep.multipliers), 2)))
        u = escape_direction(prob, x, rep.multipliers, S_tol)
        if u is None or prob.rank >= blocks.k:
            break
        V, t, g = prob.unpack(x)
        V = np.column_stack([V, ESCAPE_STEP * max(ESCAPE_NORM_FLOOR, float(np.linalg.norm(V))) * u])
        new = FactorProblem(blocks, prob.rank + 1, prob.objective, prob.nominal, False, prob.fixed_g,
                            prob.g_fixed)
        xn, ok, _ = project(new, new.pack(V, t, g))
        if not ok:
            break
        prob, x = new, xn
    cand.problem, cand.x = prob, x
    return cand


#: relative agreement of the certificate SDP's optimum with the Newton point (1000x Clarabel's gap)
_AGREE = CLARABEL_MARGIN_FACTOR * CLARABEL_OPTIONS["tol_gap_rel"]


def _kkt(cand: EngineCandidate) -> dict[str, float]:
    """The KKT test of the final point over every decision covariance: the smallest eigenvalue of
    the dual slack S relative to ``||S||`` (``>= -1e-9``: S is PSD) and ``||S V|| / (||S|| ||V||)``
    (complementarity).  With S PSD the point is also the global optimum over the Q of its gain (a
    dual certificate of the convex fixed-gain problem)."""
    if cand.multipliers is None:
        return {}
    prob, x = cand.problem, cand.x
    S = prob.dual_slack(x, cand.multipliers)
    V, _, _ = prob.unpack(x)
    ns = max(float(np.linalg.norm(S, 2)), SCALE_FLOOR)
    if prob.diagonal:
        d = np.diag(S)
        return {"min_eig": float(np.min(d)) / ns,
                "complementarity": float(np.max(np.abs(d * np.diag(V)))) / ns,
                "passed": bool(np.min(d) >= -IK_KKT_TOL * ns)}
    comp = float(np.linalg.norm(S @ V)) / (ns * max(float(np.linalg.norm(V)), SCALE_FLOOR))
    me = float(np.linalg.eigvalsh(S)[0]) / ns
    return {"min_eig": me, "complementarity": comp, "passed": bool(me >= -IK_KKT_TOL)}


def _certify(setup: EngineSetup, best: EngineCandidate, Qn: NDArray | None, deadline: Deadline,
             rounds: int = 3) -> tuple[EngineCandidate, FixedGainSolution | None, bool]:
    """Stage 3: the fixed-gain SDP at the candidate's gain; a better SDP point restarts Newton from
    it.  Returns ``(candidate, last SDP solution, agreed)``."""
    sol = None
    for _ in range(rounds):
        sol = _sdp_at(setup, best, Qn, deadline)
        if not sol.status.is_solved:
            return best, sol, False
        v, ref = sdp_value(setup.objective, sol, Qn, setup.structure), best.value
        unit = best.scale ** (2 if setup.objective == "nearest" else 1)
        tol = _AGREE * max(abs(ref), unit)
        if v >= ref - tol:
            return best, sol, bool(v <= ref + tol)
        _, _, g = best.parts()
        cand = candidate_from_sdp(setup, best.problem.blocks, g, sol, best.scale, Qn, fixed=False)
        if cand is None or deadline.expired:
            return best, sol, False
        cand.kind, cand.iterations = best.kind + " (from the certificate SDP)", best.iterations
        cand = _optimize(cand, deadline)
        if not cand.value < ref:
            return best, sol, False
        best = cand
    return best, sol, False


def _design(setup: EngineSetup, cand: EngineCandidate):
    """(L, P, Q, Qw, Wdec) in physical units from a feasible point.

    The gain of the null vectors, ``L' = G W^-1``, places the poles to rounding but is accurate only
    to ``eps cond(W)`` in the directions that keep them; P, the Lyapunov solution of ``A - L C`` with
    ``L R L' + Q`` (the Riccati solution for Q), is insensitive to that error, so L is then taken from
    P by the Kalman gain formula (``P C' R^-1``, discrete ``A P C' (C P C' + R)^-1``).  One output: the
    poles fix the gain, kept (the formula adds P's rounding: at n = 15, poles off 1.9e-6, not 6.6e-7)."""
    plant = setup.plant
    V, t, g = cand.parts()
    Qdec = cand.problem.qdec(V, t) * cand.scale
    Qdec = 0.5 * (Qdec + Qdec.T)
    L, _ = cand.problem.blocks.gain(g)
    Q = setup.Gd @ Qdec @ setup.Gd.T
    Q = 0.5 * (Q + Q.T)
    R = np.asarray(plant.R, dtype=float)
    A, C = plant.A, plant.C
    P = riccati_of_gain(A, C, L, R, Q, plant.dt)
    if plant.p > 1:
        L = filter_gain(A, C, R, P, plant.is_discrete)
    if setup.structure == "full":
        return L, P, Q, None, Qdec
    Qw = np.diag(np.diag(Qdec)) if setup.structure == "diagonal" else Qdec
    return L, P, Q, Qw, (np.diag(Qdec).copy() if setup.structure == "diagonal" else Qdec)


def _design_miss(setup: EngineSetup, cand: EngineCandidate, target: NDArray, tol: float,
                 resolve: bool = True) -> float:
    """:func:`~optdesign.engines.pole_homotopy.pole_miss` of the candidate's design (above 1: it fails)."""
    L, _, Q, _, _ = _design(setup, cand)
    return pole_miss(setup.plant, L, Q, target, tol, resolve)


def solve_inverse_kalman(setup: EngineSetup, poles: ArrayLike, *, Q_nominal: ArrayLike | None = None,
                         starts: int = 3, seed: int = 0, time_limit: float | Deadline | None = None,
                         tol: float = INVERSE_KALMAN_POLE_TOL,
                         warm_start: ArrayLike | None = None) -> EngineResult:
    """The Kalman filter with the target poles whose Q is best for the setup's objective.

    Parameters
    ----------
    setup : EngineSetup
        From :func:`prepare_inverse_kalman` (built once per plant, structure and objective).
    poles : (n,) array_like of complex
        Targets, closed under conjugation.
    Q_nominal : array_like, optional
        Objective ``"nearest"``: (n, n) for ``"full"``, (m, m) otherwise (required).
    starts : int
        Decision-covariance starts (several outputs): the scaled identity whose Kalman poles are
        closest to the targets, the scaled nominal (``"nearest"``), then seeded random ones;
        ``warm_start`` comes first when given.  When none gives a feasible point, as many rescue
        starts again (random covariances over a range of scales).
    seed : int
        Seeds the random starts.
    time_limit : float, Deadline or None
        Seconds of wall time; on expiry the best design found so far is returned with status
        ``time_limit``.
    tol : float
        Pole accuracy required by the verification (raised to the rounding floor of the poles).
    warm_start : array_like, optional
        A decision covariance to start from (e.g. the answer for a nearby target).

    Returns
    -------
    EngineResult
        ``optimal`` when the certificate SDP at the returned gain was solved and agrees (solved to
        Clarabel's reduced accuracy only: when the dual slack of the Newton point certifies it as
        well -- at an optimal gain the family of Q often has no interior point); ``optimal`` means a
        local optimum over L at which Q is the global optimum of the gain's family;
        ``infeasible`` only for one output (an infeasible fixed-gain SDP at the unique gain, a
        global certificate) or an unstable target; ``not_found`` when no start (nor the
        continuation in the targets) gave a Kalman filter with the targets; ``solver_error``
        with ``details["applicable"] = False`` where a target is an eigenvalue of A or of its
        mirror image (:func:`engine_applies`).  ``optimal_inaccurate`` also for a feasible point
        that is not a local optimum, where the optimum is not computable (the message says so).

    Raises
    ------
    ValidationError
        Wrong number of poles (DimensionError), not conjugate-closed, bad ``tol`` / ``starts`` /
        ``seed`` / ``time_limit``, a missing or malformed ``Q_nominal`` / ``warm_start``.
    """
    t0, cpu0 = time.perf_counter(), time.process_time()
    deadline = Deadline.of(time_limit)
    plant = setup.plant
    target = as_poles("poles", poles, plant.n)
    tol = as_positive_float("tol", tol)
    starts = as_int("starts", starts, 1)
    seed = as_int("seed", seed, 0)
    Qn = nominal_factor(setup, Q_nominal)
    warm = warm_factor(setup, warm_start)
    common = dict(tol=tol)
    if not np.all(stable_mask(target, plant.is_discrete)):
        where = "inside the unit circle" if plant.is_discrete else "in the open left half-plane"
        msg = f"infeasible: a target pole is not {where}, and every steady-state Kalman filter is stable"
        return engine_result(setup, target, Status.INFEASIBLE, msg, t0, cpu0,
                       details={"certificate": {"kind": "unstable_target"}}, **common)
    why = dense_time_refusal([("resolvents", plant.n)], deadline, f"the engine's resolvents at n = {plant.n}")
    if why:   # issue 26: n solves of order n, O(n^4), not interruptible between stages
        return engine_result(setup, target, Status.TIME_LIMIT, f"no design: {why}", t0, cpu0,
                             details={"refused": why}, **common)
    if setup.one_output_route:
        L = single_output_gain(plant.A, plant.C, target, plant.dt, setup.eig_A)
        fast = None if L is None else _one_output_form(setup, target, L, deadline, t0, cpu0, tol)
        if fast is not None:
            return fast
    terms = spectral_terms(plant.A, plant.C, target, plant.dt)
    if terms is None:
        msg = ("not applicable: a target pole is an eigenvalue of A or of its mirror image (or a "
               "discrete target is 0), where the spectral conditions are singular")
        return engine_result(setup, target, Status.SOLVER_ERROR, msg, t0, cpu0, details={"applicable": False},
                       **common)
    if plant.p == 1:
        return _single_output(setup, target, terms, Qn, deadline, t0, cpu0, tol)
    return _several_outputs(setup, target, terms, Qn, starts, seed, warm, deadline, t0, cpu0, tol)


#: Clarabel's settings for the first, cheaper one-output solve (objective ``"min_trace"``, whose optima
#: are low-rank faces the KKT test certifies): gap and feasibility to 1e-6, at most 3 iterative
#: refinement steps per KKT solve.  The polish finishes the point on its face, and the answer is kept
#: only when the final point is ``optimal`` and its own KKT test passes (the dual slack of the Newton
#: point PSD: a certificate that does not depend on Clarabel's accuracy); otherwise the SDP is solved
#: again at :data:`~optdesign.backends.clarabel_fixed_gain.CLARABEL_OPTIONS` and the design decided as
#: before.  Measured (``benchmarks/results/inverse_kalman_one_output_tolerances.md``): 5 Clarabel
#: iterations instead of 8-9 at n = 20, the same statuses and optima (to 3e-13 relative) on 49 targets.
ONE_OUTPUT_FIRST_TRY: dict[str, Any] = {"tol_gap_abs": FIRST_TRY_TOL, "tol_gap_rel": FIRST_TRY_TOL,
                                        "tol_feas": FIRST_TRY_TOL,
                                        "iterative_refinement_max_iter": 3}
#: the first try only where Clarabel dominates: ``n - p`` at least this (its dense KKT matrix has over
#: 200 rows).  Measured (``--first-try``, ``--stages``): at n = 10 the polish from the looser point costs
#: more (+3 ms) than Clarabel saves (-1 ms); at n >= 15 it wins (n = 20: SDP 100 -> 55 ms, polish +2 ms)
ONE_OUTPUT_FIRST_TRY_MIN_DIM = 14
#: the dense IPM first (``"full"`` / ``"min_trace"``, one output) at ``n - p`` at least this: CPU per
#: SDP 1.3-2.5x Clarabel's at n <= 7 (Python overhead per iteration), 0.9x at n = 8, 0.55-0.75x at
#: n = 9-12, 0.3x at n = 14-20 (``--ipm``, benchmarks/results/inverse_kalman_one_output_ipm.md)
ONE_OUTPUT_IPM_MIN_DIM = 9


def _single_output(setup, target, terms, Qn, deadline, t0, cpu0, tol) -> EngineResult:
    """One output: the poles fix L (``g_b = 1``); the fixed-gain SDP at it answers globally.

    Tried in turn, each kept only when the polished point is ``optimal`` and passes its own KKT
    test, or (as ``optimal_inaccurate``) when the unique gain misses the targets beyond the
    verification's cap (not computable): for ``"full"`` / ``"min_trace"`` with ``n - p >=``
    :data:`ONE_OUTPUT_IPM_MIN_DIM` and computable targets the dense IPM
    (:func:`~optdesign.engines.fixed_gain_ipm.solve_fixed_gain_ipm`, an accelerator: when it does
    not converge to its own test, the next try); for ``"min_trace"`` with ``n - p >=``
    :data:`ONE_OUTPUT_FIRST_TRY_MIN_DIM` Clarabel at :data:`ONE_OUTPUT_FIRST_TRY`; finally (and
    for the other objectives and smaller systems) Clarabel at
    :data:`~optdesign.backends.clarabel_fixed_gain.CLARABEL_OPTIONS` -- the only source of
    ``infeasible``."""
    plant = setup.plant
    R = np.asarray(plant.R, dtype=float)
    t_size, d = plant.n * (plant.n + 1) // 2, plant.n - plant.p
    why = dense_kkt_refusal(t_size + d * (d + 1) // 2, deadline,
                            f"the direct form of the fixed-gain SDP at n = {plant.n}")
    if why:  # issue 26: O(n^4) memory and O(n^6) time, past time_limit and into the OOM killer
        status = Status.TIME_LIMIT if deadline.limited and "s left" in why else Status.NOT_FOUND
        return engine_result(setup, target, status, f"no design: {why}", t0, cpu0, tol=tol,
                       details={"refused": why})
    g = np.ones((len(terms), 1), dtype=complex)
    L, _ = spectral_blocks(terms, R, setup.Gd).gain(g)
    fam = fixed_gain_family(setup.family, L, R, Qn)
    first = setup.objective == "min_trace" and d >= ONE_OUTPUT_FIRST_TRY_MIN_DIM
    ipm = setup.objective == "min_trace" and setup.structure == "full" and d >= ONE_OUTPUT_IPM_MIN_DIM
    miss = pole_error(np.linalg.eigvals(plant.A - L @ plant.C), target) if (first or ipm) else 0.0
    # the IPM only where the targets are computable (its answer is kept only when certified)
    tries = (["the dense IPM"] if ipm and miss <= POLE_FLOOR_CAP else []) + (
        ["Clarabel at ONE_OUTPUT_FIRST_TRY"] if first else [])   # low-rank optima the KKT test certifies
    notes: list[str] = []
    for label in tries:
        if label == "the dense IPM":
            sol, rep = solve_fixed_gain_ipm(fam, deadline=deadline)
            if sol is None:   # not converged to its test: an accelerator, not a verdict
                notes.append(f"{label}: {rep.reason}")
                continue
            res = _one_output_at(setup, target, terms, Qn, deadline, t0, cpu0, tol, fam, g, None, sol=sol)
        else:
            res = _one_output_at(setup, target, terms, Qn, deadline, t0, cpu0, tol, fam, g,
                                 ONE_OUTPUT_FIRST_TRY)
        if (res.status == Status.OPTIMAL and res.details.get("kkt", {}).get("passed")) or deadline.expired:
            return _noted(res, notes)
        if res.status.is_solved and miss > POLE_FLOOR_CAP:
            # the unique gain itself misses the targets beyond the verification's cap: no design
            # with these poles is computable in double precision, whatever the SDP's accuracy; not
            # certified, so at best optimal_inaccurate
            note = (f"not KKT-certified after {label}, not solved again: the unique gain misses the "
                    f"targets by {miss:.2g} (not computable)")
            res.details["first_try"] = note
            return _noted(replace(res, status=Status.OPTIMAL_INACCURATE, message=f"{res.message}; {note}"),
                          notes)
        notes.append(f"{label}: not certified")
    res = _one_output_at(setup, target, terms, Qn, deadline, t0, cpu0, tol, fam, g, None)
    if first:
        res.details["first_try"] = "Clarabel at ONE_OUTPUT_FIRST_TRY: not certified; solved again"
    return _noted(res, notes)


def _one_output_form(setup: EngineSetup, target: NDArray, L: NDArray, deadline: Deadline, t0: float,
                     cpu0: float, tol: float) -> EngineResult | None:
    """One output, ``"full"`` / ``"min_trace"``: the fixed-gain SDP at the unique gain L in its
    n-constraint form (:func:`_complement_form_at`); None when that does not certify a solution (the
    general one-output route then runs: the dense IPM, Clarabel on the direct form, a repair, and
    every verdict).  A unique gain that misses the targets beyond the verification's cap is first
    refined by Newton steps on its poles (:func:`~optdesign.engines.polish.refine_gain`: the same
    gain in exact arithmetic, its poles placed better in floating point; measured: an n = 15
    target's 1.4e-6 -> 7.5e-7); ``optimal_inaccurate`` when it still does (not computable)."""
    plant = setup.plant
    miss = first = pole_error(np.linalg.eigvals(plant.A - L @ plant.C), target)
    if miss > POLE_FLOOR_CAP:
        L = refine_gain(plant.A, plant.C, L, target)
        miss = pole_error(np.linalg.eigvals(plant.A - L @ plant.C), target)
    out = _complement_form_at(setup, fixed_gain_family(setup.family, L, np.asarray(plant.R, dtype=float)),
                              deadline)
    if out is None:
        return None
    sol, Q, P = out
    status = Status.OPTIMAL if miss <= POLE_FLOOR_CAP else Status.OPTIMAL_INACCURATE
    solver = "the dense IPM" if sol.native_status.startswith("ipm") else f"Clarabel {sol.native_status}"
    msg = (f"one output: the poles fix L; fixed-gain SDP in its n-constraint form ({solver}, "
           f"{sol.iterations} iterations), Newton-polished ({sol.newton_iterations} steps) to rank "
           f"{sol.rank}; KKT certificate")
    if miss < first:
        msg += f"; the unique gain refined for its poles (pole error {first:.2g} -> {miss:.2g})"
    if status != Status.OPTIMAL:
        msg += f"; the unique gain misses the targets by {miss:.2g} (not computable)"
    details = {"sdp": {"status": "optimal", "native": sol.native_status, "iterations": sol.iterations,
                       "form": "n constraints", "newton_iterations": sol.newton_iterations},
               "L_unique": L, "gain_refined": bool(miss < first), "kkt": sol.kkt}
    return engine_result(setup, target, status, msg, t0, cpu0, design=(L, P, Q, None),
                   objective=float(np.trace(Q)), iterations=sol.iterations, rank=sol.rank, tol=tol,
                   details=details, native=sol.native_status)


def _noted(res: EngineResult, notes: list[str]) -> EngineResult:
    """``res`` with the earlier tries that were not kept in ``details["tries"]``."""
    if notes:
        res.details["tries"] = "; ".join(notes)
    return res


def _one_output_at(setup, target, terms, Qn, deadline, t0, cpu0, tol, fam, g,
                   options: dict[str, Any] | None, sol: FixedGainSolution | None = None) -> EngineResult:
    """The one-output design from the fixed-gain SDP of ``fam`` solved with Clarabel ``options``
    (over :data:`CLARABEL_OPTIONS`), or from the given solution ``sol``, polished on its face."""
    plant = setup.plant
    R = np.asarray(plant.R, dtype=float)
    L = fam.L
    if sol is None:
        sol = solve_fixed_gain(fam, setup.structure, plant.G, setup.objective, Qn, options=options,
                               deadline=deadline)
    details: dict[str, Any] = {"sdp": sdp_record(sol), "L_unique": L}
    common = dict(tol=tol, native=sol.native_status, details=details)
    if sol.status.is_infeasible:
        details["certificate"] = {"kind": "sdp_infeasible", "L": L}
        msg = (f"infeasible: no Q >= 0 of structure {setup.structure!r} has a Kalman gain with these "
               f"poles (the fixed-gain SDP at the unique gain is infeasible: Clarabel {sol.native_status})")
        return engine_result(setup, target, sol.status, msg, t0, cpu0, **common)
    if not sol.status.is_solved or sol.Wdec is None:
        status = Status.TIME_LIMIT if deadline.expired else sol.status
        return engine_result(setup, target, status,
                             f"the fixed-gain SDP failed: Clarabel {sol.native_status}", t0, cpu0, **common)
    wscale = max(1.0, float(np.max(np.abs(sol.Wdec))))
    if sol.t is not None and sol.t < -MARGIN_CERTIFICATE_TOL * wscale:
        details["certificate"] = {"kind": "sdp_margin", "margin": sol.t, "L": L}
        msg = (f"infeasible: the largest smallest eigenvalue of the decision covariance over the Q "
               f"family of the unique gain is {sol.t:.4g} < 0")
        return engine_result(setup, target, Status.INFEASIBLE, msg, t0, cpu0, objective=sol.t, **common)
    scale = max(SCALE_FLOOR, float(np.linalg.norm(sol.Wdec)))
    blocks = spectral_blocks(terms, R, setup.Gd, scale)
    cand = candidate_from_sdp(setup, blocks, g, sol, scale, Qn, fixed=True)
    how = "polished on its face"
    if cand is None:   # an inaccurate SDP point: Gauss-Newton and Newton from its PSD part instead
        cand = repaired_candidate(setup, blocks, g, sol, scale, Qn, deadline)
        how = "not exact on any face; Newton from its PSD part"
    if cand is None:
        msg = "the fixed-gain SDP point fits no face of the PSD cone, and no Newton repair reached one"
        return engine_result(setup, target, Status.NUMERICAL_ERROR, msg, t0, cpu0, **common)
    cand = _optimize(cand, deadline)
    kkt = details["kkt"] = _kkt(cand)
    L, P, Q, Qw, Wdec = _design(setup, cand)
    converged = bool(cand.history and cand.history[-1]["reason"].startswith("converged"))
    if sol.status == Status.OPTIMAL and converged and how.startswith("polished"):
        status = Status.OPTIMAL
    else:   # the SDP inaccurate: the dual slack of the Newton point is the certificate
        status = Status.OPTIMAL if (converged and kkt.get("passed")) else Status.OPTIMAL_INACCURATE
    solver = "dense IPM" if sol.native_status.startswith("ipm") else "Clarabel"
    msg = (f"one output: the poles fix L; fixed-gain SDP ({solver} {sol.native_status}) {how} (rank "
           f"{cand.problem.rank}, Newton {cand.history[-1]['reason'] if cand.history else 'not run'}"
           f"{'; KKT certificate' if kkt.get('passed') else ''})")
    return engine_result(setup, target, status, msg, t0, cpu0, design=(L, P, Q, Qw),
                   objective=physical_objective(setup.objective, Wdec, Qn, Q), iterations=cand.iterations,
                   rank=cand.problem.rank, **common)


def _from_starts(setup, target, terms, Qn, starts, seed, warm, deadline,
                 records: list) -> tuple[EngineCandidate | None, int]:
    """Stages 1-2 from each start (the rescue starts when none is feasible): ``(best, iterations)``."""
    best: EngineCandidate | None = None
    iterations = 0
    queue = decision_starts(setup, target, Qn, starts, seed, warm, deadline)
    rescue = True
    while queue:
        kind, W = queue.pop(0)
        if deadline.expired:
            break
        tic = time.process_time()
        rec: dict[str, Any] = {"kind": kind}
        records.append(rec)
        cand = candidate_from_start(setup, terms, W, Qn, deadline, rec)
        rec["feasible"] = cand is not None
        if cand is not None:
            cand.kind = kind
            cand = _optimize(cand, deadline)
            rec.update(value=cand.value, rank=cand.problem.rank, newton=cand.history)
            if best is None or cand.value < best.value:
                best = cand
        iterations += rec.get("sqp_iterations", 0) + rec.get("restoration_iterations", 0) + \
            rec.get("projection_iterations", 0) + sum(h["iterations"] for h in rec.get("newton", []))
        rec["cpu_time"] = time.process_time() - tic
        if not queue and best is None and rescue:   # nothing feasible yet: as many rescue starts again
            queue, rescue = rescue_starts(setup, target, starts, seed, deadline), False
    return best, iterations


def _continued(setup, target, terms, Qn, seed, tol, deadline, records: list):
    """Stages 1-3 from the continuation's point (:func:`_continuation`): ``(candidate, SDP solution,
    agreed, miss)``, or None when no path reaches the targets.  When the optimum from that point
    misses the targets (``miss > 1`` times the pole tolerance: not computable in double precision,
    measured on large noises), the point itself is returned (no SDP)."""
    cand = _continuation(setup, terms, target, Qn, seed, tol, deadline, records)
    if cand is None:
        return None
    point = replace(cand, x=cand.x.copy(), history=[])
    cand = _optimize(cand, deadline)
    records[-1].update(value=cand.value, rank=cand.problem.rank, newton=cand.history)
    cand, sol, agreed = _certify(setup, cand, Qn, deadline)
    miss = _design_miss(setup, cand, target, tol)
    return (_descend_placing(setup, point, target, tol, deadline), None, False, miss) if miss > 1.0 \
        else (cand, sol, agreed, 0.0)


#: Newton iterations per check of :func:`_descend_placing`, at most in all, and the halvings of the
#: last chunk's way when its end misses the targets
_PLACING_CHUNK, _PLACING_MAX_ITER, _PLACING_HALVINGS = 2, 60, 4


def _descend_placing(setup: EngineSetup, point: EngineCandidate, target: NDArray, tol: float,
                     deadline: Deadline) -> EngineCandidate:
    """Newton from a feasible point whose design places the targets, in chunks of
    :data:`_PLACING_CHUNK` iterations at its rank, keeping the last iterate whose design still
    does (:func:`~optdesign.engines.pole_homotopy.pole_miss` at most 1): the objective lowered
    as far as the targets stay computable (where the optimum itself is not)."""
    keep, prob, x = point, point.problem, point.x
    for _ in range(0, _PLACING_MAX_ITER, _PLACING_CHUNK):
        if deadline.expired:
            break
        rep = newton(prob, x, max_iter=_PLACING_CHUNK, expired=lambda: deadline.expired)
        trial = replace(point, problem=rep.problem, x=rep.x, multipliers=rep.multipliers,
                        iterations=keep.iterations + rep.iterations, history=[])
        shorter = 0
        while rep.problem is prob and shorter < _PLACING_HALVINGS and trial.value < keep.value and \
                _design_miss(setup, trial, target, tol) > 1.0:   # half the way, projected
            xh, ok, _ = project(prob, 0.5 * (x + trial.x))
            trial = replace(trial, x=xh) if ok else keep
            shorter += 1
        if not trial.value < keep.value or _design_miss(setup, trial, target, tol) > 1.0:
            break
        keep, prob, x = trial, rep.problem, trial.x
        if shorter or rep.converged or rep.reason.startswith("no decrease"):
            break
    return keep


def _decision_parameters(setup: EngineSetup) -> int:
    """Free parameters of the decision covariance: ``k`` (diagonal), else ``k (k + 1) / 2``."""
    k = setup.k
    return k if setup.structure == "diagonal" else k * (k + 1) // 2


def _several_outputs(setup, target, terms, Qn, starts, seed, warm, deadline, t0, cpu0, tol) -> EngineResult:
    """Stages 1-3 of the module docstring from each start; the best local optimum is certified.  When
    no start is feasible, or the design of the best misses the targets (the residuals at rounding
    level do not imply the poles where their Jacobian is ill-conditioned), the continuation in the
    target poles (:func:`_continued`) is tried as well."""
    plant = setup.plant
    records: list[dict[str, Any]] = []
    best, iterations = _from_starts(setup, target, terms, Qn, starts, seed, warm, deadline, records)
    sol, agreed, miss = None, False, 0.0
    if best is not None:
        best, sol, agreed = _certify(setup, best, Qn, deadline)
    # the test of a found design without scipy's re-solve (0.1 ms, not 2: it runs on every target);
    # no continuation where the structure has fewer parameters than pole conditions: the targets on
    # the way are then generically out of reach (measured: input family, 10 of 170 seeds)
    if not deadline.expired and _decision_parameters(setup) >= plant.n and (
            best is None or _design_miss(setup, best, target, tol, False) > 1.0):
        found = _continued(setup, target, terms, Qn, seed, tol, deadline, records)
        iterations += sum(rec.get("steps", 0) for rec in records)
        if found is not None:
            best, sol, agreed, miss = found
    details: dict[str, Any] = {"starts": records}
    if best is None:
        status = Status.TIME_LIMIT if deadline.expired else Status.NOT_FOUND
        msg = (f"no Kalman filter with these poles found from {len(records)} start(s) (a local search: "
               f"feasibility unknown)")
        return engine_result(setup, target, status, msg, t0, cpu0, iterations=iterations, tol=tol,
                       details=details)
    details.update(sdp=sdp_record(sol), best_start=best.kind, kkt=_kkt(best))
    L, P, Q, Qw, Wdec = _design(setup, best)
    kkt_ok = bool(details["kkt"].get("passed"))
    what = "a local optimum over L"
    if deadline.expired:
        status, how = Status.TIME_LIMIT, "the time limit ran out; the best design so far"
    elif miss > 1.0:
        status, what = Status.OPTIMAL_INACCURATE, "a feasible point, not a local optimum,"
        how = (f"the Newton optimum from it misses the targets by {miss:.3g} times the pole tolerance "
               f"(not computable): Newton stopped where the design still places them")
    elif sol is not None and sol.status == Status.OPTIMAL and agreed:
        status, how = Status.OPTIMAL, "the fixed-gain SDP at that L (Clarabel Solved) agrees"
    elif sol is not None and sol.status == Status.OPTIMAL_INACCURATE and agreed and kkt_ok:
        # at an optimal gain the family of Q often has no interior point (the SDP is solved only
        # to Clarabel's reduced tolerances); the dual slack of the Newton point is then the exact
        # certificate of the convex problem at that gain
        status, how = Status.OPTIMAL, ("the fixed-gain SDP at that L (Clarabel AlmostSolved) agrees and "
                                       "the dual slack certifies it (KKT)")
    else:
        status = Status.OPTIMAL_INACCURATE
        what_sdp = "failed" if sol is None or not sol.status.is_solved else f"returned {sol.native_status}"
        how = (f"no certificate: the fixed-gain SDP at that L {what_sdp}"
               + ("" if agreed else " and does not agree"))
    msg = (f"{plant.p} outputs: {what} from {len(records)} start(s) (best: {best.kind}; rank "
           f"{best.problem.rank}); {how}")
    return engine_result(setup, target, status, msg, t0, cpu0, design=(L, P, Q, Qw),
                   objective=physical_objective(setup.objective, Wdec, Qn, Q), iterations=iterations,
                   rank=best.problem.rank, tol=tol, details=details,
                   native="" if sol is None else sol.native_status)
