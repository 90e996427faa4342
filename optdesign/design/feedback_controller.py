r"""State feedback on its own measure: the controller mode of the fixed-pole placement engine.

``A - B K`` with prescribed poles is placed by the eigenstructure engine built on the dual pair
``(A', B')`` (:class:`~optdesign.engines.eigenstructure.EigenstructureEngine`), but with
``measure="left"``: the engine's left eigenvectors of ``A' - K' B'`` are the right eigenvectors of
``A - B K``, so it minimizes ``cond(X)`` of the unit-column right eigenvector matrix ``X`` of the
closed loop -- the measure of scipy's ``place_poles`` (its ``X``), MATLAB's ``place`` and the
Kautsky-Nichols-Van Dooren / Byers-Nash / Chu literature -- not the dual's (the left eigenvectors
of ``A - B K``).

Poles repeated beyond ``rank(B)``: with one input (``rank(B) = 1``) the poles fix the gain, which
Ackermann's formula gives (``A - B K`` is then defective: kappa2 infinite, and said so); with more
inputs no ``A - B K`` has a pole of geometric multiplicity above ``rank(B)`` and the request is
refused (:class:`~optdesign.errors.DefectivePolesError`, a ``ValueError``), as scipy refuses it.

Every answer is verified here, on ``A - B K`` itself (numpy's eigenvalues; the engine's basis
against the eigen-equation and against ``metrics.kappa2``), independently of the engine.

References
----------
Kautsky, Nichols & Van Dooren, Int. J. Control 41(5) (1985); Byers & Nash, "Approaches to robust
pole assignment", Int. J. Control 49(1) (1989); Chu, "Pole assignment via the Schur form", Systems
& Control Letters 56 (2007); Ackermann, Regelungstechnik 20 (1972).
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._deadline import Deadline
from ..analysis import metrics
from ..classical.placement import acker
from ..classical.riccati import sort_poles
from ..engines.eigenstructure import EigenstructureEngine, pole_multiplicities
from ..engines.eigenstructure_fixed import place_fixed
from ..errors import DefectivePolesError
from ..results import Check, Route, SolverStats, Stage, Status, Verification
from .verification import (
    POLE_FLOOR_CAP,
    eig_residual_check,
    eigen_spread,
    kappa2_agreement_check,
    pole_check,
    region_margin_check,
    stability_check,
)

__all__ = ["input_rank", "needs_ackermann", "controller_fields", "ackermann_fields",
           "region_controller_fields", "region_checks",
           "ackermann_observer", "backward_check", "charpoly_check",
           "POLE_TOL", "CHARPOLY_TOL"]

#: relative pole error accepted (as the observer verbs' ``pole_error``; raised to the rounding floor)
POLE_TOL = 1e-6
#: normalized characteristic-polynomial error accepted for a defective (Ackermann) closed loop,
#: whose eigenvalues are computable only to ``eps^(1/m)`` at a pole of multiplicity m; the
#: coefficients of ``det(sI - F)`` are (backward stable eigenvalues), so they are checked instead
CHARPOLY_TOL = 1e-8
#: backward error of a requested pole, ``sigma_min(F - lambda I) / max(||F||_2, |lambda|)``, accepted
#: in units of ``n eps`` (measured: 1e-18 for Ackermann's gain on the Chow-Kokotovic plant with
#: ||F|| ~ 1e6, 1e-7 for the same gain perturbed by 1e-6)
BACKWARD_FACTOR = 1e3

_EPS = float(np.finfo(float).eps)


def input_rank(M: NDArray) -> int:
    """Numerical rank of an input (or output) matrix, relative to its largest singular value."""
    s = np.linalg.svd(np.asarray(M, dtype=float), compute_uv=False)
    return int(np.sum(s > max(M.shape) * _EPS * (float(s[0]) if s.size else 0.0)))


def needs_ackermann(target: NDArray, rank: int, *, matrix: str = "B", loop: str = "A - B K") -> bool:
    """True when a pole repeats and ``rank == 1`` (the gain is fixed: Ackermann's formula).

    Raises
    ------
    DefectivePolesError
        A pole repeated more than ``rank`` times with ``rank >= 2``.
    """
    mults = pole_multiplicities(target)
    v, m = max(mults, key=lambda t: t[1])
    if m <= rank:
        return False
    if rank == 1:
        return True
    raise DefectivePolesError(
        f"poles: {complex(v):.6g} is requested {m} times but rank({matrix}) = {rank}: every eigenvalue of "
        f"{loop} has at most rank({matrix}) independent eigenvectors, so {loop} would be defective; with "
        f"rank({matrix}) >= 2 this request is refused (scipy's place_poles refuses it too); repeat a pole "
        f"at most {rank} times, or spread it (optdesign.engines.eigenstructure.spread_poles)",
        pole=v, multiplicity=m, rank=rank)


def _basis_checks(F: NDArray, X: NDArray, poles: NDArray, k2_x: float) -> tuple[list[Check], float]:
    """The engine's basis against the eigen-equation and metrics.kappa2; returns (checks, kappa2)."""
    checks = [eig_residual_check(F, X, poles)]
    k2_np = float(metrics.kappa2(F))
    if math.isfinite(k2_np):
        checks.append(kappa2_agreement_check(k2_x, k2_np, eigen_spread(F, poles)))
    # a semisimple repeated pole: the basis is not unique; the verified engine basis is reported
    return checks, k2_x


def _rename(checks: list[Check]) -> list[Check]:
    """Observer words in a check's detail -> state-feedback words (``stability_margin`` ->
    ``feedback_stability_margin``, as the dual route names it)."""
    names = {"stability_margin": "feedback_stability_margin"}
    return [Check(name=names.get(c.name, c.name), value=c.value, tolerance=c.tolerance, passed=c.passed, sense=c.sense,
                  detail=c.detail.replace("A - LC", "A - B K").replace("A - L C", "A - B K"))
            for c in checks]


def controller_fields(A: NDArray, B: NDArray, target: NDArray, *, objective: str, discrete: bool,
                      stable: bool, starts: int | None, seed: int, time_limit: float | Deadline | None,
                      gain_mask: NDArray | None = None, max_iter: int = 400,
                      final_ftol: float | None = None, warm_start: NDArray | None = None) -> dict[str, Any]:
    """Fixed poles on the engine in controller mode; the fields of a ``FeedbackDesign`` (K, poles,
    kappa2 (= cond(X)), X, ...) with the verification on ``A - B K``.

    ``gain_mask`` (m, n) of bool: free entries of K.  ``max_iter`` and ``final_ftol`` as
    :func:`~optdesign.engines.eigenstructure_fixed.place_fixed` (the drop-in's ``maxiter``, ``rtol``).
    ``warm_start`` (m, n): a gain K placing ``target`` (e.g. region mode's answer), one more start.
    """
    t0 = time.process_time()
    eng = EigenstructureEngine(A.T, B.T)
    out = place_fixed(eng.A, eng.C, target, objective=objective, starts=starts, seed=seed,  # type: ignore[arg-type]
                      deadline=Deadline.of(time_limit), engine=eng, measure="left", max_iter=max_iter,
                      gain_mask=None if gain_mask is None else np.asarray(gain_mask, dtype=bool).T,
                      final_ftol=final_ftol,
                      warm_start=None if warm_start is None else np.asarray(warm_start, dtype=float).T)
    cpu = time.process_time() - t0
    stage = Stage("eigenstructure_engine (controller mode: cond of the right eigenvectors of A - B K)",
                  "engine", "answered", out.message, cpu)
    stats = SolverStats(backend="eigenstructure", native_status=out.status.value, time=cpu,
                        iterations=int(out.iterations))
    L = np.asarray(out.L, dtype=float)
    if not np.all(np.isfinite(L)):
        nan = math.nan
        chk = [Check.at_most("finite_gain", math.inf, 0.0, "the engine found no gain")]
        return dict(K=None, poles=np.full(A.shape[0], nan + 0j), X=None, kappa2=nan, kappa2_right=nan,
                    eta=nan, kappa_fro=nan, gain_norm=nan, status=out.status, message=out.message,
                    verification=Verification.of(chk), solver_stats=stats,
                    route=(Stage(stage.name, "engine", out.status.value, out.message, cpu),), outcome=out)
    K = L.T
    F = A - B @ K
    checks: list[Check] = []
    pchk, _ = pole_check(F, target, POLE_TOL, name="feedback_pole_error", what="eig(A - B K) (numpy)")
    checks.append(pchk)
    if stable:
        checks += _rename([stability_check(F, discrete)])
    X = np.asarray(out.V, dtype=complex)   # measure="left": the unit-column right eigenvectors of A - B K
    more, k2 = _basis_checks(F, X, np.asarray(out.poles), float(out.kappa2))
    checks += _rename(more)
    if gain_mask is not None:
        zero = ~np.asarray(gain_mask, dtype=bool)
        off = float(np.max(np.abs(K[zero]))) if zero.any() else 0.0
        checks.append(Check.at_most("mask", off, 0.0, "largest |K| entry outside the structure mask"))
    kf = float(np.linalg.norm(X) * np.linalg.norm(np.linalg.inv(X)))
    status = Status.SOLVED if out.status == Status.SOLVED else out.status
    if status == Status.ITERATION_LIMIT:  # a verified improvement on its start (as the observer verbs)
        status = Status.OPTIMAL_INACCURATE
    msg = (f"state feedback, controller mode: cond(X) of the unit-column right eigenvectors of A - B K "
           f"= {k2:.6g} ({out.message})")
    return dict(K=K, poles=sort_poles(np.linalg.eigvals(F)), X=X, kappa2=k2, kappa2_right=k2,
                eta=float(metrics.eta(F)), kappa_fro=kf, gain_norm=float(np.linalg.norm(K, 2)),
                status=status, message=msg, verification=Verification.of(checks), solver_stats=stats,
                route=(stage,), outcome=out)


def charpoly_check(F: NDArray, target: NDArray) -> Check:
    """``feedback_charpoly_error``: the coefficients of ``det(sI - F)`` against those of the target
    poles, on the scale ``s = max(1, ||F||_2, max |pole|)`` and relative to ``binom(n, k)`` (the
    largest the k-th coefficient of n poles of modulus <= 1 can be)."""
    n = F.shape[0]
    s = max(1.0, float(np.linalg.norm(F, 2)), float(np.max(np.abs(target))))
    c_f = np.real(np.poly(np.linalg.eigvals(F / s)))
    c_t = np.real(np.poly(np.asarray(target) / s))
    binom = np.array([math.comb(n, k) for k in range(n + 1)], dtype=float)
    err = float(np.max(np.abs(c_f - c_t) / binom))
    return Check.at_most("feedback_charpoly_error", err, CHARPOLY_TOL,
                         "max |coefficient of det(sI - (A - B K)) - of prod(s - pole)| / binom(n, k), on the "
                         "scale max(1, ||A - B K||, max |pole|) (a defective loop: its eigenvalues are "
                         "not computable to better than eps^(1/multiplicity))")


def backward_check(F: NDArray, target: NDArray) -> Check:
    """``feedback_pole_backward_error``: each distinct requested pole ``lambda`` is an exact eigenvalue
    of a matrix within ``sigma_min(F - lambda I)`` of F; the largest such distance relative to
    ``max(||F||_2, |lambda|)``, against ``BACKWARD_FACTOR n eps``.  Sharp where eigenvalues are not
    (a Jordan block moves its eigenvalue by ``eps^(1/m)``; the backward error stays at eps)."""
    n = F.shape[0]
    nF = float(np.linalg.norm(F, 2))
    worst = 0.0
    for lam, _ in pole_multiplicities(target):
        s = np.linalg.svd(F - lam * np.eye(n), compute_uv=False)[-1]
        worst = max(worst, float(s) / max(nF, abs(lam), 1e-300))
    return Check.at_most("feedback_pole_backward_error", worst, BACKWARD_FACTOR * n * _EPS,
                         "max over the requested poles of sigma_min(A - B K - pole I) / max(||A - B K||, |pole|)")


def ackermann_fields(A: NDArray, B: NDArray, target: NDArray, *, discrete: bool, stable: bool) -> dict[str, Any]:
    """Repeated poles with ``rank(B) = 1``: the unique gain (Ackermann), kappa2 infinite."""
    t0 = time.process_time()
    K = acker(A, B, target)
    cpu = time.process_time() - t0
    F = A - B @ K
    checks = [backward_check(F, target), charpoly_check(F, target)]
    if stable:
        # the poles themselves are verified through the characteristic polynomial; stability of a
        # defective loop is decided on the target poles with the check's own margin
        worst = float(np.max(np.abs(target))) if discrete else float(np.max(np.real(target)))
        checks.append(Check.at_most("feedback_target_stability", worst, 1.0 if discrete else 0.0,
                                    "the requested poles are stable (spectral radius < 1 / max Re < 0)"))
    v, m = max(pole_multiplicities(target), key=lambda t: t[1])
    msg = (f"one input (rank(B) = 1): the poles fix the gain, computed by Ackermann's formula; pole "
           f"{complex(v):.6g} is repeated {m} times, so A - B K is defective (a Jordan block): kappa2 = inf")
    stage = Stage("ackermann", "direct", "answered", "rank one, repeated pole: the gain is unique", cpu)
    return dict(K=K, poles=sort_poles(np.linalg.eigvals(F)), X=None, kappa2=math.inf, kappa2_right=math.inf,
                eta=math.inf, kappa_fro=math.inf, gain_norm=float(np.linalg.norm(K, 2)), status=Status.SOLVED,
                message=msg, verification=Verification.of(checks),
                solver_stats=SolverStats(backend="ackermann", native_status="solved", time=cpu, iterations=0),
                route=(stage,), outcome=None)


def ackermann_observer(plant: Any, target: NDArray, objective: str, *, stable: bool, mask: NDArray | None,
                       max_gain: float | None) -> Any:
    """Observer mode of :func:`ackermann_fields`: a repeated pole with ``rank(C) = 1`` fixes L
    (Ackermann's formula on the dual ``(A', C')``); ``A - L C`` defective, kappa2 infinite.  An
    :class:`~optdesign.design.well_conditioned.results.ObserverDesign` with the checks on ``A - L C``
    (the gain bound and structural zeros checked, not designed for: the gain is unique)."""
    from .well_conditioned.results import ObserverDesign

    f = ackermann_fields(plant.A.T, plant.C.T, target, discrete=plant.is_discrete, stable=stable)
    L = f["K"].T
    F = plant.A - L @ plant.C
    checks = [backward_check(F, target), charpoly_check(F, target)] + [
        c for c in f["verification"] if c.name == "feedback_target_stability"]
    words = {"feedback_pole_backward_error": "pole_backward_error", "feedback_charpoly_error": "charpoly_error",
             "feedback_target_stability": "target_stability"}
    checks = [Check(name=words[c.name], value=c.value, tolerance=c.tolerance, passed=c.passed, sense=c.sense,
                    detail=c.detail.replace("A - B K", "A - L C")) for c in checks]
    gn = float(np.linalg.norm(L, 2))
    if mask is not None:
        off = float(np.max(np.abs(L[~mask]))) if (~mask).any() else 0.0
        checks.append(Check.at_most("mask", off, 0.0, "largest |L| entry outside the structure mask"))
    if max_gain is not None:
        checks.append(Check.at_most("gain_bound", gn, float(max_gain), "||L||_2 <= max_gain (the gain is unique)"))
    msg = f["message"].replace("rank(B)", "rank(C)").replace("A - B K", "A - L C").replace("one input", "one output")
    return ObserverDesign(L=L, poles=f["poles"], kappa2=math.inf, eta=math.inf, kappa_fro=math.inf, gain_norm=gn,
                          objective=objective, status=Status.SOLVED, message=msg, solver_stats=f["solver_stats"],
                          verification=Verification.of(checks), target_poles=target, plant=plant,
                          route=Route(f["route"]))


# --------------------------------------------------------------------------- region mode
def region_checks(A: NDArray, B: NDArray, K: NDArray, X: NDArray | None, region: Any, *,
                  discrete: bool) -> tuple[list[Check], float, NDArray]:
    """``(checks, cond(X), X)`` of a region-mode state-feedback gain, on ``A - B K`` itself.

    ``feedback_region_margin`` (the region's tolerance: ``REGION_TOL`` or the poles' rounding floor,
    relative to ``max(1, max |pole|)``), ``feedback_stability_margin``, and for the basis ``X``
    (right eigenvectors of ``A - B K``, columns normalized here; None: numpy's) ``eig_residual`` and
    ``kappa2_agreement`` (its condition number against ``metrics.kappa2``).  ``cond(X)`` is computed
    here from the unit-column ``X`` (one SVD).
    """
    F = A - B @ K
    summ = metrics.condition_summary(F)
    floor = min(float(summ["rounding_floor"]), POLE_FLOOR_CAP)
    rc = region_margin_check(region, np.linalg.eigvals(F), floor)
    checks = [Check(name="feedback_region_margin", value=rc.value, tolerance=rc.tolerance, passed=rc.passed,
                    sense=rc.sense, detail=rc.detail.replace("A - LC", "A - B K"))]
    checks += _rename([stability_check(F, discrete)])
    if X is None:
        X, w = metrics.eigenvector_matrix(F, return_eigenvalues=True)
    else:
        X = np.asarray(X, dtype=complex)
        X = X / np.linalg.norm(X, axis=0)
        w = np.einsum("ij,ij->j", X.conj(), F @ X)   # Rayleigh quotients: the poles of the columns
    s = np.linalg.svd(X, compute_uv=False)
    k2 = float(s[0] / s[-1]) if s[-1] > 0 else math.inf
    if not math.isfinite(k2):
        checks.append(Check.at_most("feedback_kappa2_finite", math.inf, 0.0, "A - B K has no eigenbasis"))
        return checks, k2, X
    more, _ = _basis_checks(F, X, w, k2)
    return checks + _rename(more), k2, X


def region_controller_fields(A: NDArray, B: NDArray, region: Any, *, dual: Any, objective: str,
                             discrete: bool, starts: int | None, seed: int, deadline: Deadline,
                             dual_K: NDArray | None) -> dict[str, Any] | None:
    """Poles free in ``region``, state feedback on its own measure.

    The region engine in controller mode (``measure="left"`` on the dual pair ``(A', B')``: ``cond(X)``
    of the unit-column right eigenvectors of ``A - B K``), one start at a time from the dual route's
    design ``dual_K`` and the usual region starts of the dual plant ``dual``
    (:func:`~.well_conditioned.starts.iter_region_starts`), then the fixed-pole controller mode
    (:func:`controller_fields`, warm-started) at the final poles.  Every candidate, the dual route's
    design too, is verified on ``A - B K`` (:func:`region_checks`) and the best verified one on
    ``cond(X)`` is returned: never worse than the dual route's.

    Returns
    -------
    dict or None
        The fields of a ``FeedbackDesign`` (as :func:`controller_fields`), plus ``chosen``
        (``"dual"``, ``"region"`` or ``"polish"``) and ``kappa2_dual_route``; None when no candidate
        passed its checks.
    """
    from ..engines.eigenstructure_region import RegionStart
    from ..errors import OptDesignError
    from .well_conditioned.starts import default_region_starts, iter_region_starts

    t0 = time.process_time()
    best: tuple | None = None     # (cond X, K, X, checks, chosen)
    specs: list[RegionStart] = []
    if dual_K is not None and np.all(np.isfinite(dual_K)):
        specs.append(RegionStart("the dual route's design", np.linalg.eigvals(A - B @ dual_K), dual_K.T))
        best = _verified(A, B, dual_K, None, region, discrete, "dual", best)
    k2_dual = best[0] if best is not None else math.nan
    rng = np.random.default_rng(seed)
    n_starts = default_region_starts(A.shape[0], objective) if starts is None else int(starts)
    specs += [RegionStart(o, np.asarray(P0, dtype=complex), L0)
              for o, L0, _, P0 in iter_region_starts(dual, region, n_starts, rng, None)]
    out, done, its, timed_out = _region_engine(A, B, region, specs, objective, seed, deadline)
    if out is not None:
        best = _verified(A, B, out.L.T, out.V, region, discrete, "region", best)
    detail = (f"{done} of {len(specs)} starts, the dual route's design first"
              + (", time limit reached" if timed_out else ""))
    stages = [("eigenstructure_engine, free poles (controller mode: cond(X) of the right eigenvectors of "
               "A - B K)", "engine", detail, time.process_time() - t0)]
    t1 = time.process_time()
    note = "skipped: no design or no time left"
    if best is not None and not deadline.expired:
        prev: tuple = best
        try:
            f = _polish(A, B, prev[1], objective, discrete, seed, deadline)
        except (OptDesignError, np.linalg.LinAlgError) as exc:   # e.g. the final poles repeat
            note = f"skipped: {type(exc).__name__}"
        else:
            if f is None:
                note = "skipped: a repeated pole with one input (the gain is fixed by the poles)"
                f = {"K": None, "solver_stats": SolverStats(backend="none")}
            its += int(f["solver_stats"].iterations or 0)
            if f["K"] is not None:
                new: tuple = _verified(A, B, f["K"], f["X"], region, discrete, "polish", prev) or prev
                note = f"cond(X) {prev[0]:.6g} -> {new[0]:.6g}" if new is not prev else "no better design"
                best = new
    stages.append(("eigenstructure_engine, fixed poles at the final poles (controller mode)", "polish", note,
                   time.process_time() - t1))
    if best is None:
        return None
    return _region_fields(A, B, best, stages, k2_dual=k2_dual, its=its, timed_out=timed_out,
                          inaccurate=out is not None and out.status == Status.ITERATION_LIMIT,
                          cpu=time.process_time() - t0)


def _polish(A: NDArray, B: NDArray, K: NDArray, objective: str, discrete: bool, seed: int,
            deadline: Deadline) -> dict[str, Any] | None:
    """:func:`controller_fields` at the poles of ``A - B K``, warm-started from ``K`` (None: a repeated
    pole with one input, the gain is fixed by the poles)."""
    P = np.linalg.eigvals(A - B @ K)
    if needs_ackermann(P, input_rank(B)):
        return None
    return controller_fields(A, B, P, objective=objective, discrete=discrete, stable=True, starts=None,
                             seed=seed, time_limit=deadline, warm_start=K)


def _verified(A: NDArray, B: NDArray, K: NDArray, X: NDArray | None, region: Any, discrete: bool, chosen: str,
              best: tuple | None) -> tuple | None:
    """``best``, or the candidate ``K`` if its checks pass and its ``cond(X)`` is smaller."""
    checks, k2, Xu = region_checks(A, B, K, X, region, discrete=discrete)
    if Verification.of(checks).passed and math.isfinite(k2) and (best is None or k2 < best[0]):
        return (k2, np.asarray(K, dtype=float), Xu, checks, chosen)
    return best


def _region_engine(A: NDArray, B: NDArray, region: Any, specs: list[Any], objective: str, seed: int,
                   deadline: Deadline) -> tuple[Any, int, int, bool]:
    """``place_region`` in controller mode, one start at a time (a start the engine refuses is
    skipped); ``(best outcome or None, starts run, iterations, timed out)``."""
    from ..engines.eigenstructure_region import place_region
    from ..errors import OptDesignError

    eng = EigenstructureEngine(A.T, B.T)
    best, done, its, timed_out = None, 0, 0, False
    for idx, st in enumerate(specs):
        if idx and deadline.expired:
            return best, done, its, True
        try:
            out = place_region(eng.A, eng.C, region, objective=objective, starts=[st], n_samples=0,
                               seed=seed + idx, deadline=deadline, engine=eng, measure="left")
        except (OptDesignError, np.linalg.LinAlgError):
            continue
        done, its = done + 1, its + int(out.iterations)
        timed_out |= out.status == Status.TIME_LIMIT
        if np.all(np.isfinite(out.L)) and (best is None or out.objective_value < best.objective_value):
            best = out
    return best, done, its, timed_out


def _region_fields(A: NDArray, B: NDArray, best: tuple, stages: list[tuple], *, k2_dual: float, its: int,
                   timed_out: bool, inaccurate: bool, cpu: float) -> dict[str, Any]:
    """The fields of the chosen region-mode design ``best = (cond X, K, X, checks, chosen)``."""
    k2, K, X, checks, chosen = best
    F = A - B @ K
    status = Status.TIME_LIMIT if timed_out else Status.OPTIMAL_INACCURATE if inaccurate else Status.OPTIMAL
    answered = {"region": 0, "polish": 1}.get(chosen)
    route = []
    for i, (name, kind, detail, t) in enumerate(stages):
        outcome = ("answered" if i == answered else "unchanged" if kind == "polish" else
                   "improved" if chosen == "polish" else status.value)
        route.append(Stage(name, kind, outcome, detail, t))
    src = {"dual": "the dual route's design (the controller mode did not improve on it)",
           "region": "the region engine in controller mode",
           "polish": "the fixed-pole controller mode at the region engine's poles"}[chosen]
    msg = (f"state feedback, controller mode, poles free in the region: cond(X) of the unit-column right "
           f"eigenvectors of A - B K = {k2:.6g}, from {src}; the dual route's design: {k2_dual:.6g}"
           + (" (time limit reached: best so far)" if timed_out else ""))
    kf = float(np.linalg.norm(X) * np.linalg.norm(np.linalg.inv(X)))
    stats = SolverStats(backend="eigenstructure", native_status=status.value, time=cpu, iterations=its)
    return dict(K=K, poles=sort_poles(np.linalg.eigvals(F)), X=X, kappa2=k2, kappa2_right=k2,
                eta=float(metrics.eta(F)), kappa_fro=kf, gain_norm=float(np.linalg.norm(K, 2)), status=status,
                message=msg, verification=Verification.of(checks), solver_stats=stats, route=tuple(route),
                outcome=None, chosen=chosen, kappa2_dual_route=k2_dual)
