"""The well-conditioned Kalman filter: :class:`WellConditionedKalmanProblem` and the verb
:func:`well_conditioned_kalman` (seed 001, section 2.3).

The process-noise covariance is the design variable and the filter Riccati equation a constraint
of the NLP (:func:`optdesign.formulate.well_conditioned.build_kalman_nlp`): the result is a true
Kalman filter for the returned ``Q``, checked by an independent Riccati solve.  IPOPT only (the
placement engine has no Riccati constraint).
"""

from __future__ import annotations

import dataclasses
import math
from functools import partial
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from ..._deadline import Deadline, as_time_limit
from ..._progress import Progress, as_progress
from ..._validate import as_int, as_positive_float, renamed
from ...backends.report import one_warning_per_call
from ...classical.riccati import filter_are, filter_are_residual
from ...errors import ValidationError
from ...formulate.well_conditioned import (
    NLPScaling,
    PoleStructure,
    build_kalman_nlp,
    check_objective,
    check_q_structure,
)
from ...model.coerce import as_plant
from ...model.plant import Plant
from ...model.regions import Region
from ...results import Check, Verification
from .evaluation import (
    Candidate,
    Evaluated,
    check_region_stable,
    evaluate_candidate,
    metric_of,
    pick_best,
    start_record,
)
from .nlp_route import ipopt_options, read_candidate, solve_nlp, solver_error_candidate, stage_plan
from .problem import Objective, check_region, kappa2_bound, result_from
from .results import ObserverDesign, StartRecord

__all__ = ["WellConditionedKalmanProblem", "well_conditioned_kalman"]


@one_warning_per_call
def well_conditioned_kalman(
    plant: Plant | Any,
    *,
    region: Region | None = None,
    objective: Objective = "eta",
    q_structure: Literal["scalar", "diagonal", "full"] = "scalar",
    kappa2_max: float | None = None,
    eta_max: float | None = None,
    q_range: tuple[float, float] = (1e-3, 1e3),
    starts: int = 4,
    seed: int = 0,
    nlp_solver: str | None = None,
    options: dict[str, Any] | None = None,
    time_limit: float | None = None,
    progress: bool | None = None,
    solver: str | None = None,
) -> ObserverDesign:
    """A steady-state Kalman filter whose error dynamics are well conditioned.

    ``WellConditionedKalmanProblem(plant, ...).solve(region=region)``.  The process-noise covariance
    is the design variable (``R`` stays the plant's): the NLP minimizes the chosen metric of
    ``A - L C`` subject to the filter Riccati equation (continuous ARE, or the predictor DARE when
    ``plant.dt`` is set), ``P >= 0`` (Cholesky factor), ``Q >= 0`` and optional pole-region and
    metric bounds -- so the result is a true Kalman filter for the returned ``Q``, not merely an
    observer.

    Parameters
    ----------
    plant : Plant, python-control StateSpace or scipy StateSpace / lti / dlti
        ``A, C, G`` and ``R`` (identity when absent); with ``q_structure="scalar"`` the design is
        ``Q = q Q0`` with ``Q0 = plant.Q`` (identity when absent), i.e. seed 001's ``q/r``.
    region : Region, optional
        The filter poles must lie in it; it must lie in the closed stability region of the
        plant's time domain (ValidationError otherwise, as in :func:`well_conditioned_observer`).
    objective : {"eta", "kappa2", "kappa_fro"}, default "eta"
    q_structure : {"scalar", "diagonal", "full"}
        ``Q = q Q0``; ``Q = diag(q)``; ``Q = F F'`` (lower-triangular ``F``).
    kappa2_max, eta_max : float, optional
        Trade-off bounds.
    q_range : (float, float)
        Range of the scalar multipliers of ``Q0`` used as starting points (log-spaced).
    starts : int, default 4
    seed : int, default 0
    nlp_solver : {"ipopt"}
        (Old spelling ``solver=``: deprecated.)
    options : dict, optional
        IPOPT options (string keys), merged over the defaults.
    time_limit : float, optional
        Seconds of wall time (None: no limit); see :func:`well_conditioned_observer`.
    progress : bool or None
        Report the starts on stderr (None: only on a terminal).

    Returns
    -------
    ObserverDesign
        With ``Q``, ``P``, ``R``; verification adds the Riccati residual (recomputed with
        :func:`optdesign.riccati.filter_are_residual`), ``P >= 0``, ``Q >= 0`` and the gain
        against an independent Riccati solve for the returned ``Q``.  Status as for
        :func:`well_conditioned_observer` (``not_found`` when no start gave a verified filter,
        ``time_limit`` when the budget ran out).

    Raises
    ------
    ValidationError
        Unknown objective, q_structure or solver; bad bounds, ``options`` or ``time_limit``;
        ``q_range`` not two numbers ``0 < lo <= hi < inf``; a region reaching outside the
        stability region.
    NotObservableError
        ``(C, A)`` not detectable.

    References
    ----------
    Seed 001, section 2.3 and Example 2 (the gain depends on ``q/r`` only, eq 29).

    Examples
    --------
    >>> from optdesign import Plant, well_conditioned_kalman
    >>> from optdesign.regions import HalfPlane
    >>> plant = Plant([[0, 1], [2, -1]], [[1, 0]], G=[[0], [1]], R=[[1]])   # seed 001, Example 2
    >>> kf = well_conditioned_kalman(plant, objective="kappa2", region=HalfPlane(1.5), starts=1)
    >>> kf.success, round(float(kf.Q[0, 0]), 2), kf.poles.real.round(3).tolist()   # a true Kalman filter
    (True, 2.19, [-1.658, -1.5])
    """
    deadline = Deadline(as_time_limit(time_limit))
    nlp_solver = renamed("nlp_solver", nlp_solver, "solver", solver, "ipopt", stacklevel=3)
    problem = WellConditionedKalmanProblem(plant, objective=objective, q_structure=q_structure,
                                           kappa2_max=kappa2_max, eta_max=eta_max, q_range=q_range,
                                           starts=starts, seed=seed, nlp_solver=nlp_solver, options=options)
    return problem.solve(region=region, time_limit=deadline, progress=progress)


class WellConditionedKalmanProblem:
    """The well-conditioned Kalman question for one plant, held by the caller
    (:func:`well_conditioned_kalman` is ``WellConditionedKalmanProblem(...).solve(region=...)``).

    Built once: validation, the starting Kalman filters (one Riccati solve per noise level of
    ``q_range``); the NLPs are built on first use per pole structure and region and re-solved.

    Parameters
    ----------
    plant, objective, q_structure, kappa2_max, eta_max, q_range, starts, seed, nlp_solver, options
        As :func:`well_conditioned_kalman`.

    Raises
    ------
    ValidationError, NotObservableError
        As :func:`well_conditioned_kalman`.
    """

    def __init__(self, plant: Plant | Any, *, objective: Objective = "eta",
                 q_structure: Literal["scalar", "diagonal", "full"] = "scalar",
                 kappa2_max: float | None = None, eta_max: float | None = None,
                 q_range: tuple[float, float] = (1e-3, 1e3), starts: int = 4,
                 seed: int = 0, nlp_solver: str = "ipopt", options: dict[str, Any] | None = None) -> None:
        plant = as_plant(plant)
        check_objective(objective)
        check_q_structure(q_structure)
        if not isinstance(nlp_solver, str) or nlp_solver != "ipopt":
            raise ValidationError(f"nlp_solver must be 'ipopt' (CasADi/IPOPT is the NLP backend); found "
                                  f"{nlp_solver!r}")
        self.objective, self.q_structure = objective, q_structure
        self.starts = as_int("starts", starts, 1)
        self.seed = as_int("seed", seed, 0)
        self.eta_max = None if eta_max is None else as_positive_float("eta_max", eta_max)
        self.kappa2_max = kappa2_bound(kappa2_max)
        self.options = ipopt_options(options)
        self.q_range = _check_q_range(q_range)
        plant.require_observable(detectable_ok=True, what="a well-conditioned Kalman filter")
        self.plant = plant
        self.R = np.asarray(plant.R if plant.R is not None else np.eye(plant.p), dtype=float)
        Q0 = plant.Q if plant.Q is not None else np.eye(plant.m)
        self.base = plant.replace(R=self.R, Q=Q0)
        self.start_list = _kalman_starts(self.base, q_structure, *self.q_range, self.starts,
                                         np.random.default_rng(self.seed))
        self._nlps: dict[tuple, Any] = {}

    def _nlp(self, st: PoleStructure, region: Region | None):
        key = (st, repr(region))
        if key not in self._nlps:
            self._nlps[key] = build_kalman_nlp(self.base, st, objective=self.objective,
                                               q_structure=self.q_structure, region=region,
                                               kappa2_max=self.kappa2_max, eta_max=self.eta_max,
                                               scaling=NLPScaling.identity(self.base.n, self.base.p))
        return self._nlps[key]

    @one_warning_per_call
    def solve(self, region: Region | None = None, *, time_limit: float | Deadline | None = None,
              progress: bool | None = None) -> ObserverDesign:
        """The well-conditioned Kalman filter, optionally with its poles in ``region``.

        Parameters
        ----------
        region : Region, optional
        time_limit : float or Deadline, optional
        progress : bool or None

        Returns
        -------
        ObserverDesign
        """
        deadline = time_limit if isinstance(time_limit, Deadline) else Deadline(as_time_limit(time_limit))
        progress = as_progress(progress)
        if region is not None:
            check_region_stable(check_region(region), self.plant.is_discrete)
        base, objective = self.base, self.objective
        evaluate = partial(evaluate_candidate, base, target=None, region=region, mask=None, max_gain=None,
                           kappa2_max=self.kappa2_max, eta_max=self.eta_max)
        records: list[StartRecord] = []
        evaluated: list[Evaluated] = []
        qinfo: dict[int, tuple[NDArray, NDArray]] = {}
        with Progress(len(self.start_list), "well-conditioned Kalman filter", enabled=progress,
                      unit="start") as bar:
            for idx, (origin, init, st) in enumerate(self.start_list):
                if idx and deadline.expired:
                    break
                run = _kalman_start(self._nlp(st, region), init, objective, self.options, evaluate, deadline,
                                    force=idx == 0)
                if run is None:
                    continue
                cand, qinfo[idx] = run
                mtr, v = evaluate(cand)
                v = v + _kalman_checks(base, cand.L, *qinfo[idx])
                obj = metric_of(objective, mtr)
                records.append(start_record(idx, origin, cand, mtr, v, obj, cand.message))
                evaluated.append((obj, idx, mtr, v, cand))
                bar.update(1, note=f"best {objective} {min(e[0] for e in evaluated):.6g}")
        nan_qp = (np.full((base.m, base.m), np.nan), np.full((base.n, base.n), np.nan))
        Qb, Pb = qinfo[pick_best(evaluated)[1]] if evaluated else nan_qp
        return result_from(base, records, evaluated, objective=objective, target=None, region=region,
                           deadline=deadline, planned=len(self.start_list), route="nlp",
                           kalman={"Q": Qb, "P": Pb, "R": self.R})


def _check_q_range(q_range: Any) -> tuple[float, float]:
    """``(lo, hi)`` with ``0 < lo <= hi < inf`` from a pair of numbers."""
    if isinstance(q_range, (str, bytes)) or not hasattr(q_range, "__len__") or len(q_range) != 2:
        raise ValidationError(f"q_range must be a pair (lo, hi) of numbers; found {q_range!r}")
    try:
        lo, hi = (as_positive_float("q_range", q_range[0], allow_zero=True),
                  as_positive_float("q_range", q_range[1], allow_zero=True))
    except ValidationError:
        raise ValidationError(f"q_range must be a pair (lo, hi) of numbers; found {q_range!r}") from None
    if not (0 < lo <= hi):
        raise ValidationError(f"q_range must satisfy 0 < lo <= hi < inf; found {q_range!r}")
    return lo, hi


def _kalman_starts(base: Plant, q_structure: str, lo: float, hi: float, starts: int, rng) -> list:
    """Kalman filters for log-spaced multiples of ``Q0`` (random diagonal jitter): ``(origin, (P, theta, L),
    structure)`` per start whose Riccati equation has a solution.

    Raises
    ------
    ValidationError
        No start has one.
    """
    m = base.m
    Q0 = np.asarray(base.Q, dtype=float)
    mults = np.geomspace(lo, hi, starts) if starts > 1 else np.array([math.sqrt(lo * hi)])
    start_list = []
    for k, q in enumerate(mults):
        if q_structure == "scalar":
            Qs = q * Q0
            theta0: Any = q
        elif q_structure == "diagonal":
            d = q * np.maximum(np.diag(Q0), 1e-6) * (np.exp(0.3 * rng.standard_normal(m)) if k else 1.0)
            Qs = np.diag(d)
            theta0 = d
        else:
            Qs = q * Q0
            F = np.linalg.cholesky(Qs + 1e-12 * np.eye(m))
            theta0 = np.array([F[i, j] for i in range(m) for j in range(i + 1)])
        try:
            are = filter_are(base.replace(Q=Qs))
        except (ValueError, np.linalg.LinAlgError):
            continue
        st = PoleStructure.of(are.poles, tol=1e-7)
        start_list.append((f"riccati q={q:.3g}", (are.P, theta0, are.L), st))
    if not start_list:
        raise ValidationError(
            "no Riccati solution exists for any starting noise level in q_range; "
            "check detectability and that G Q G' excites the plant's modes"
        )
    return start_list


def _kalman_start(knlp, init, objective: str, opts, evaluate, deadline: Deadline, force: bool):
    """One start of the Kalman NLP through its continuation: ``(candidate, (Q, P))`` -- the best verified
    stage (with the start's iteration and time totals), else the last one; None when the deadline
    expired before its first stage (which runs anyway with ``force``)."""
    n, m = knlp.plant.n, knlp.plant.m
    knlp.set_initial(*init)
    plan, set_stage, _ = stage_plan(knlp.obs, objective, None)
    hist: list[Candidate] = []
    best = None
    good = None
    nan_q = (np.full((m, m), np.nan), np.full((n, n), np.nan))
    qp, best_qp = nan_q, None
    for J in plan:
        if deadline.expired and (hist or not force):
            break
        if J is not None:
            set_stage(J)
        if good is not None:
            knlp.obs.warm_start(good[0])
            knlp.opti.set_initial(knlp.Fp, good[1])
            knlp.opti.set_initial(knlp.theta, good[2])
        rep = solve_nlp(knlp.obs, opts, deadline)
        stage = "" if J is None else f"J={J}"
        c, readable = read_candidate(knlp.obs, rep, stage)
        if readable:
            try:
                qp = (knlp.noise(rep.value), np.asarray(rep.value(knlp.P), dtype=float).reshape(n, n))
            except RuntimeError as exc:  # CasADi cannot evaluate the iterate
                c, readable = solver_error_candidate(knlp.plant, rep, exc, stage), False
        hist.append(c)
        if not readable:
            qp = nan_q
            break
        if evaluate(c)[1].passed:
            good = (knlp.obs.snapshot(rep.value), np.asarray(rep.value(knlp.Fp), dtype=float),
                    np.asarray(rep.value(knlp.theta), dtype=float))
            best, best_qp = c, qp
    if not hist:
        return None
    cand = best if best is not None else hist[-1]
    cand = dataclasses.replace(cand, iterations=sum(h.iterations for h in hist),
                               time=sum(h.time for h in hist))
    return cand, (best_qp if best is not None else qp)


def _kalman_checks(plant: Plant, L: NDArray, Q: NDArray, P: NDArray) -> Verification:
    checks = []
    if not (np.all(np.isfinite(Q)) and np.all(np.isfinite(P)) and np.all(np.isfinite(L))):
        return Verification.of(
            [Check.at_most("finite_noise", float("inf"), 0.0, "Q, P or L has NaN/Inf entries")]
        )
    Qs = 0.5 * (Q + Q.T)
    Ps = 0.5 * (P + P.T)
    scaleQ = max(1.0, float(np.max(np.abs(Qs)))) if Qs.size else 1.0
    scaleP = max(1.0, float(np.max(np.abs(Ps))))
    checks.append(Check.at_least("Q_min_eig", float(np.linalg.eigvalsh(Qs)[0]), -1e-9 * scaleQ, "Q >= 0"))
    checks.append(Check.at_least("P_min_eig", float(np.linalg.eigvalsh(Ps)[0]), -1e-9 * scaleP, "P >= 0"))
    try:
        res = filter_are_residual(plant, Ps, Q=Qs)
    except (ValueError, np.linalg.LinAlgError) as exc:
        res = float("inf")
        checks.append(Check.at_most("riccati_residual", res, 1e-7, f"residual failed: {exc}"))
    else:
        checks.append(Check.at_most("riccati_residual", res, 1e-7, "relative residual of the filter ARE"))
    try:
        ref = filter_are(plant.replace(Q=Qs))
        dl = float(np.linalg.norm(L - ref.L) / max(np.linalg.norm(ref.L), 1e-300))
        checks.append(
            Check.at_most(
                "gain_vs_riccati", dl, 1e-5, "||L - L_ARE(Q)|| / ||L_ARE(Q)||, independent Riccati solve"
            )
        )
    except (ValueError, np.linalg.LinAlgError) as exc:
        checks.append(Check.at_most("gain_vs_riccati", float("inf"), 1e-5, f"Riccati solve failed: {exc}"))
    return Verification.of(checks)
