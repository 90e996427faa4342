r"""Robust observer design: one gain for many plant models (issue 15).

A real plant is never one model -- operating points, parameter uncertainty, failure modes.  The
verbs design one observer gain ``L`` for every model of a
:class:`~optdesign.model.model_set.ModelSet` (or a list of plants):

* :func:`~optdesign.design.robust_lmi.robust_lmi_observer` (module :mod:`optdesign.design.robust_lmi`)
  -- the **convex route**: regional pole placement with a common
  Lyapunov matrix over the models (Chilali & Gahinet 1996), H2 and H-infinity bounds of the
  estimation error in Luenberger form (the observer duals of Chilali, Gahinet & Apkarian 1999 /
  MATLAB's ``msfsyn``), in cvxpy with Clarabel or SCS
  (:mod:`optdesign.formulate.robust_lmi`).  It returns the gain **with its certificate** -- the
  Lyapunov matrix ``P`` -- and what ``P`` proves is recomputed in numpy
  (:func:`~optdesign.design.robust_verify.certify`): for a polytope (kind ``"polytope"``) the
  region and the bounds hold for *every convex combination* of the models, not only the models.
  An infeasible LMI answers with its Farkas certificate, verified in numpy -- which proves that no
  common quadratic certificate exists, not that no robust gain exists.
* :func:`robust_observer` (this module) -- the **NLP route**: the exact, non-convex problem on all models at
  once (:mod:`optdesign.formulate.robust_nlp`): minimize the worst-case (or weighted) kappa2 or
  H2 norm, or the gain, subject to hard pole regions per model, soft regions as penalties
  (gammasyn style), structural zeros and bounds (kappa2, H2, H-infinity, ``||L||_2``); scipy SLSQP
  with analytic gradients (IPOPT on request), multi-start from the LMI gain, the per-model designs
  and the nominal Kalman gain.  It reports how much it improves on the LMI gain and *checks*
  whether a common Lyapunov certificate still holds for the refined gain (the LMI's ``P``, then a
  fresh analysis SDP for the gain).
* :func:`per_model_designs` -- each model's own design (what one gain could do at best for that
  model), and :func:`evaluate_gain` -- any gain on the set (e.g. the nominal design on the others).

Every claimed success is verified on every model (:mod:`optdesign.design.robust_verify`): poles
and region membership, kappa2 / eta, H2 by a Lyapunov solve, H-infinity by the Hamiltonian
level-set iteration; a dense check at random interior points of the set is reported beside it.

Measured (``benchmarks/bench_robust.py --section solvers``, the 8 benchmark sets, from the same
verified LMI start): SLSQP reached a worst-case kappa2 at least as good as IPOPT's (limited-memory
Hessian, numpy callbacks) on 7 of 8 (IPOPT better on COMPleib AC17: 1.62 vs 1.84) at 1.2-22x less CPU
time, and IPOPT made no progress from the start on AC6 and HE5 (2.41 vs 1.13, 123 vs 74.5); SLSQP is
the default, IPOPT an option.

References
----------
M. Chilali and P. Gahinet, "H-infinity design with pole placement constraints: an LMI approach",
IEEE TAC 41(3), 1996.
M. Chilali, P. Gahinet and P. Apkarian, "Robust pole placement in LMI regions", IEEE TAC 44(12),
1999.
P. Vogt, E. Lenz and U. Konigorski, "gammasyn -- eine Toolbox zur robusten Polbereichsvorgabe
mittels beschraenkter Optimierung und Straffunktionen", at - Automatisierungstechnik 68(10), 2020.
"""

from __future__ import annotations

import dataclasses
import math
import time
import warnings
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
import scipy.optimize
from numpy.typing import ArrayLike, NDArray

from .._deadline import Deadline, as_time_limit
from .._validate import as_gain_mask, as_int, as_positive_float
from ..backends.casadi_backend import solve_nlpsol
from ..backends.report import one_warning_per_call
from ..classical.riccati import filter_are
from ..errors import ValidationError
from ..formulate.robust_nlp import KAPPA2_ORDERS, RobustNLP, build_robust_nlp
from ..model.model_set import ModelSet, as_model_set
from ..model.regions import Region
from ..results import Certificate, Check, SolverStats, Status, Verification
from .robust_gain import evaluate_gain, per_model_designs  # noqa: F401  (their old home: still importable here)
from .robust_lmi import certify_gain, lmi_design
from .robust_result import (
    RobustObserverDesign,
    RobustStart,
    as_regions,
    check_choice,
    failed_design,
    fixed_mode_certificate,
    optional_bound,
    robust_route,
)
from .robust_verify import DenseCheck, ModelMetrics, dense_check, evaluate_models, gain_checks

__all__ = ["robust_observer", "NLP_DEFAULTS"]

#: default NLP options (per continuation stage)
NLP_DEFAULTS: dict[str, Any] = {"maxiter": 200, "ftol": 1e-10, "orders": KAPPA2_ORDERS}


class _Stop(Exception):
    """The time budget ran out inside an NLP evaluation."""


@dataclass
class _Cand:
    L: NDArray
    rank: float
    value: float
    verified: bool
    mm: ModelMetrics
    verification: Verification
    converged: bool = False


@dataclass(frozen=True)
class _Spec:
    """The validated arguments of one robust_observer call."""

    ms: ModelSet
    regions: tuple[Region | None, ...]
    soft: tuple[Region | None, ...]
    objective: str
    aggregate: str
    mask: NDArray[np.bool_] | None
    kappa2_max: float | None
    bounds: dict[str, float | None]
    soft_weight: float
    starts: int
    nlp_starts: int
    per_model_starts: bool
    lmi_start: bool
    seed: int
    nlp_solver: str
    sdp_solver: str | None
    dense_points: int
    certify: bool
    opts: dict[str, Any]
    options: dict[str, Any] | None
    deadline: Deadline


def _value_of(objective: str, aggregate: str, mm: ModelMetrics, L: NDArray, w: NDArray) -> float:
    if objective == "gain":
        return float(np.linalg.norm(L))
    v = mm.kappa2 if objective == "kappa2" else mm.h2
    return float(np.max(v)) if aggregate == "max" else float(w @ v)


@one_warning_per_call
def robust_observer(
    models: ModelSet | list,
    *,
    region: Region | list | None = None,
    soft_region: Region | list | None = None,
    soft_weight: float = 1.0,
    objective: Literal["kappa2", "h2", "gain"] = "kappa2",
    aggregate: Literal["max", "mean"] = "max",
    kappa2_max: float | None = None,
    h2_max: float | None = None,
    hinf_max: float | None = None,
    gain_mask: ArrayLike | None = None,
    max_gain: float | None = None,
    weights: ArrayLike | None = None,
    starts: int = 2,
    nlp_starts: int = 4,
    per_model_starts: bool = True,
    lmi_start: bool = True,
    seed: int = 0,
    nlp_solver: Literal["slsqp", "ipopt"] = "slsqp",
    sdp_solver: str | None = None,
    dense_points: int = 200,
    certify_result: bool = True,
    time_limit: float | None = None,
    options: dict[str, Any] | None = None,
) -> RobustObserverDesign:
    """One observer gain for every model, by the exact NLP, from the LMI gain and per-model designs.

    Parameters
    ----------
    models : ModelSet or sequence of Plant
    region : Region or sequence of (Region or None), optional
        Hard pole region per model (default: the stability region).
    soft_region : Region or sequence of (Region or None), optional
        Soft regions: ``soft_weight * sum max(0, g)^2`` over the poles outside them is added to the
        objective (gammasyn's SQUAREPENALTY).
    soft_weight : float, default 1.0
    objective : {"kappa2", "h2", "gain"}, default "kappa2"
        Per-model kappa2 of ``A_i - L C_i``, H2 norm of the estimation error, or ``||L||_F`` (the
        smallest gain meeting the constraints).
    aggregate : {"max", "mean"}, default "max"
        Worst case over the models, or the weighted mean (the set's ``weights``).
    kappa2_max, h2_max, hinf_max : float, optional
        Bounds on every model (trade-offs: e.g. min worst-case kappa2 s.t. H2 <= h2_max).
    gain_mask : (n, p) array_like of bool, optional
        Free entries of L.
    max_gain : float, optional
        Bound on ``||L||_2``.
    weights : (N,) array_like, optional
    starts : int, default 2
        Extra starts: random perturbations of the best gain found.
    nlp_starts : int, default 4
        Every start gain (LMI, per-model designs, nominal Kalman gain) is first judged on all models;
        the NLP runs from the best ``nlp_starts`` of them (verified ones first).
    per_model_starts : bool, default True
        Start from each model's own design (:func:`per_model_designs`).
    lmi_start : bool, default True
        Start from the LMI gain (:func:`robust_lmi_observer`, objective ``"cond"``, same regions and
        bounds); it is kept as ``result.lmi``.
    seed : int, default 0
    nlp_solver : {"slsqp", "ipopt"}, default "slsqp"
    sdp_solver : {"CLARABEL", "SCS"}, optional
    dense_points : int, default 200
    certify_result : bool, default True
        Check whether a common Lyapunov certificate holds for the returned gain (the LMI's P, then an
        analysis SDP).
    time_limit : float, optional
        Seconds for the whole design; status ``time_limit`` with the best verified gain so far.
    options : dict, optional
        NLP options: ``maxiter`` (per stage), ``ftol``, ``orders`` (kappa2 continuation).

    Returns
    -------
    RobustObserverDesign
        ``method="nlp"``; ``improvement`` over the LMI gain; ``certified`` and ``lmi_certificate``;
        ``starts``; ``extra["per_model"]`` (the per-model designs' values).

    Raises
    ------
    ValidationError, DimensionError
        Bad models, regions, mask, bounds, objective, aggregate, solver or options.

    References
    ----------
    gammasyn (Vogt, Lenz & Konigorski 2020); Chilali & Gahinet 1996.

    Examples
    --------
    >>> from optdesign import ModelSet, Plant, robust_observer
    >>> from optdesign.regions import HalfPlane
    >>> models = ModelSet.vary(Plant([[0., 1.], [-2., -1.]], [[1., 0.]]), [(1, 0)], 0.2)  # A[1,0] +-20 %
    >>> d = robust_observer(models, region=HalfPlane(1.0), max_gain=10.0, starts=1, nlp_starts=1,
    ...                     per_model_starts=False, dense_points=0)
    >>> d.success, d.certified, len(models), round(d.worst_kappa2, 1)
    (True, True, 3, 1.2)
    """
    ms = as_model_set(models, weights)
    spec = _Spec(
        ms=ms,
        regions=as_regions(region, ms, "region", default=True),
        soft=as_regions(soft_region, ms, "soft_region", default=False),
        objective=check_choice("objective", objective, ("kappa2", "h2", "gain")),
        aggregate=check_choice("aggregate", aggregate, ("max", "mean")),
        mask=as_gain_mask("gain_mask", gain_mask, ms.n, ms.p, label=" (free entries of L)"),
        kappa2_max=optional_bound("kappa2_max", kappa2_max, 1.0),
        bounds={
            "h2_max": optional_bound("h2_max", h2_max),
            "hinf_max": optional_bound("hinf_max", hinf_max),
            "max_gain": optional_bound("max_gain", max_gain),
        },
        soft_weight=as_positive_float("soft_weight", soft_weight),
        starts=as_int("starts", starts, 0),
        nlp_starts=as_int("nlp_starts", nlp_starts, 1),
        per_model_starts=bool(per_model_starts),
        lmi_start=bool(lmi_start),
        seed=as_int("seed", seed, 0),
        nlp_solver=check_choice("nlp_solver", nlp_solver, ("slsqp", "ipopt")),
        sdp_solver=sdp_solver,
        dense_points=dense_count(dense_points),
        certify=bool(certify_result),
        opts={**NLP_DEFAULTS, **(options or {})},
        options=options,
        deadline=Deadline(as_time_limit(time_limit)),
    )
    unknown = set(spec.opts) - set(NLP_DEFAULTS)
    if unknown:
        raise ValidationError(f"options has unknown keys {sorted(unknown)}; known: maxiter, ftol, orders")
    b = spec.bounds
    if (objective == "h2" or b["h2_max"] or b["hinf_max"]) and not ms.has_noise_model:
        raise ValidationError(
            "the H2 objective, h2_max and hinf_max need a noise model (Q and R) in every model"
        )
    return _design(spec)


def _design(spec: _Spec) -> RobustObserverDesign:
    t_start = time.process_time()
    ms = spec.ms
    fixed = fixed_mode_certificate(ms, spec.regions)
    if fixed is not None:
        return failed_design(
            ms, spec.regions, "nlp", spec.objective, spec.aggregate, Status.INFEASIBLE, fixed.reason, fixed
        )
    lmi_res, per_model, start_list = _starts(spec)
    nlp = _build(spec, start_list)
    judge = _Judge(spec, nlp)
    best, records = _search(spec, nlp, judge, start_list)
    res = _nlp_result(spec, best, records, lmi_res, per_model, t_start)
    return dataclasses.replace(res, route=robust_route(res))


def _starts(spec: _Spec) -> tuple[RobustObserverDesign | None, list[RobustObserverDesign], list]:
    """The start gains: the LMI gain, each model's own design, the nominal Kalman gain."""
    ms, deadline = spec.ms, spec.deadline
    start_list: list[tuple[str, NDArray]] = []
    lmi_res = None
    if spec.lmi_start:
        lmi_res = lmi_design(
            ms,
            spec.regions,
            "cond",
            mask=spec.mask,
            sdp_solver=spec.sdp_solver,
            margin=None,
            dense_points=0,
            seed=spec.seed,
            deadline=deadline,
            options=None,
            **spec.bounds,
        )
        if np.all(np.isfinite(lmi_res.L)):
            start_list.append(("LMI (cond)", lmi_res.L))
    per_model: list[RobustObserverDesign] = []
    if spec.per_model_starts and len(ms) > 1:
        for i in range(len(ms)):
            if deadline.expired:
                break
            budget = deadline.fraction(1.0 / (len(ms) - i + 2)) if deadline.limited else None
            one = dataclasses.replace(
                spec,
                ms=ModelSet([ms[i]]),
                regions=(spec.regions[i],),
                soft=(spec.soft[i],),
                starts=0,
                per_model_starts=False,
                dense_points=0,
                certify=False,
                deadline=Deadline(budget),
            )
            d = _design(one)
            per_model.append(d)
            if np.all(np.isfinite(d.L)):
                start_list.append((f"{ms.label(i)} design", d.L))
    kal = _kalman_start(ms)
    if kal is not None:
        start_list.append(("Kalman gain (nominal)", kal))
    if not start_list:
        start_list.append(("zero gain", np.zeros((ms.n, ms.p))))
    if spec.mask is not None:
        start_list = [(o, np.where(spec.mask, L0, 0.0)) for o, L0 in start_list]
    return lmi_res, per_model, start_list


def _build(spec: _Spec, start_list: list) -> RobustNLP:
    """The NLP, with the gain scale of the starts and the H2 reference of the first start."""
    scale = max(1.0, max(float(np.max(np.abs(L0))) for _, L0 in start_list))
    h2_ref = 1.0
    if spec.objective == "h2":
        mm0 = evaluate_models(spec.ms, start_list[0][1], spec.regions)
        h2_ref = float(np.nanmax(mm0.h2) ** 2) if np.isfinite(np.nanmax(mm0.h2)) else 1.0
    return build_robust_nlp(
        spec.ms,
        regions=spec.regions,
        soft_regions=spec.soft,
        objective=spec.objective,
        aggregate=spec.aggregate,
        gain_mask=spec.mask,
        kappa2_max=spec.kappa2_max,
        soft_weight=spec.soft_weight,
        gain_scale=scale,
        h2_ref=h2_ref,
        **spec.bounds,
    )


def _search(spec: _Spec, nlp: RobustNLP, judge, start_list: list) -> tuple[_Cand | None, list[RobustStart]]:
    """Screen every start on all models; run the NLP from the best ``nlp_starts``, then from perturbations
    of the best gain; the best verified candidate and the history."""
    deadline = spec.deadline
    orders = (
        tuple(spec.opts["orders"]) if spec.objective == "kappa2" or spec.kappa2_max is not None else (None,)
    )
    screened = []
    for origin, L0 in start_list:
        if deadline.expired:
            break
        c0 = judge(L0)
        screened.append((0 if c0.verified else 1, c0.rank, origin, c0))
    if screened and all(t[0] for t in screened) and not deadline.expired:
        # no start meets the hard constraints (the LMI failed too): a feasibility phase from each of the
        # least violating starts gives the NLP feasible starts if it can
        screened.sort(key=lambda t: _violation(t[3]))
        for _, _, origin, c0 in screened[: spec.nlp_starts]:
            if deadline.expired:
                break
            c1 = judge(_feasibility_phase(spec, nlp, c0.L))
            screened.append((0 if c1.verified else 1, c1.rank, origin + " + feasibility phase", c1))
    screened.sort(key=lambda t: (t[0], t[1]))
    queue = [(origin, c0) for _, _, origin, c0 in screened]
    records: list[RobustStart] = []
    best: _Cand | None = None
    rng = np.random.default_rng(spec.seed)
    n_run = min(len(queue), spec.nlp_starts)
    for k in range(n_run + spec.starts):
        if deadline.expired:
            break
        if k < n_run:
            origin, c0 = queue[k]
        elif best is None:
            break
        else:
            origin = "perturbed best"
            c0 = judge(best.L * (1.0 + 0.3 * rng.standard_normal(best.L.shape)))
        t0 = time.process_time()
        cands, iters, conv, msg = _run_start(nlp, c0.L, orders, spec.opts, spec.nlp_solver, deadline, judge)
        ok = [c for c in (c0, *cands) if c.verified]
        pick = min(ok, key=lambda c: c.rank) if ok else (c0, *cands)[-1]
        pick.converged = conv
        records.append(
            RobustStart(
                k,
                origin,
                pick.verified,
                pick.value,
                c0.value if c0.verified else math.nan,
                conv,
                iters,
                time.process_time() - t0,
                msg,
            )
        )
        if pick.verified and (best is None or pick.rank < best.rank):
            best = pick
    for origin, c0 in queue[n_run:]:
        records.append(
            RobustStart(
                len(records),
                origin + " (screened out: no NLP)",
                c0.verified,
                c0.value,
                c0.value if c0.verified else math.nan,
                False,
                0,
                0.0,
                "not run",
            )
        )
        if c0.verified and (best is None or c0.rank < best.rank):
            best = c0
    return best, records


def _kalman_start(ms: ModelSet) -> NDArray | None:
    if not ms.has_noise_model:
        return None
    pl = ms[ms.nominal if ms.nominal is not None else 0]
    try:
        return filter_are(pl).L
    except (ValueError, np.linalg.LinAlgError):
        return None


def _violation(c: _Cand) -> float:
    """How far the worst pole of a candidate lies outside its region (0 inside; inf if unstable)."""
    m = c.mm.margin
    worst = float(np.nanmax(m)) if np.any(~np.isnan(m)) else 0.0
    return max(worst, 0.0) if math.isfinite(worst) else math.inf


def _feasibility_phase(spec: _Spec, nlp: RobustNLP, L0: NDArray) -> NDArray[np.float64]:
    """Minimize the squared violation of the hard regions, shrunk by ``1e-3`` times the pole scale, plus a
    small gain term, from ``L0`` (gammasyn's penalty approach; L-BFGS-B): a start inside the regions for
    the NLP, when no start is."""
    ms = spec.ms
    scale = max(1.0, max(float(np.max(np.abs(np.linalg.eigvals(pl.A)))) for pl in ms))
    ph = build_robust_nlp(
        ms,
        regions=(None,) * len(ms),
        soft_regions=spec.regions,
        objective="gain",
        gain_mask=spec.mask,
        soft_weight=1e8 / scale**2,
        gain_scale=nlp.gain_scale,
    )
    ph.soft_margin = 1e-3 * scale

    def fun(z):
        if spec.deadline.expired:
            raise _Stop
        f = ph.f(z)
        return f if math.isfinite(f) else 1e30

    try:
        res = scipy.optimize.minimize(
            fun,
            ph.point(L0),
            jac=ph.grad,
            method="L-BFGS-B",
            options={"maxiter": 5 * int(spec.opts["maxiter"])},
        )
    except _Stop:
        return np.asarray(L0, dtype=float)
    return ph.gain(res.x)


class _Judge:
    """Verify a gain on every model and rank it by the NLP's exact objective."""

    def __init__(self, spec: _Spec, nlp: RobustNLP):
        self.spec, self.nlp = spec, nlp
        self.norms = spec.objective == "h2" or any(spec.bounds[k] is not None for k in ("h2_max", "hinf_max"))

    def __call__(self, L: NDArray) -> _Cand:
        sp = self.spec
        L = np.asarray(L, dtype=float)
        if sp.mask is not None:
            L = np.where(sp.mask, L, 0.0)
        mm = evaluate_models(sp.ms, L, sp.regions, norms=self.norms)
        v = gain_checks(sp.ms, L, mm, sp.regions, mask=sp.mask, kappa2_max=sp.kappa2_max, **sp.bounds)
        value = _value_of(sp.objective, sp.aggregate, mm, L, np.asarray(sp.ms.weights, dtype=float))
        rank = self.nlp.exact_objective(L)
        return _Cand(L, rank if math.isfinite(rank) else math.inf, value, v.passed, mm, v)


def _run_start(
    nlp, L0: NDArray, orders, opts, solver: str, deadline: Deadline, judge
) -> tuple[list, int, bool, str]:
    """Continuation from ``L0``: one NLP solve per order; a verified candidate per stage."""
    cands: list[_Cand] = []
    x = nlp.point(L0)
    iters, converged, msg = 0, False, ""
    for order in orders:
        if deadline.expired:
            msg += "; time limit"
            break
        nlp.set_order(order)
        x = nlp.point(nlp.gain(x))
        try:
            x, it, ok, m = _solve_stage(nlp, x, opts, solver, deadline)
        except _Stop:
            msg += "; time limit"
            break
        iters += it
        converged = converged or ok
        msg = m
        cands.append(judge(nlp.gain(x)))
    return cands, iters, converged, msg


def _solve_stage(nlp, x0: NDArray, opts, solver: str, deadline: Deadline) -> tuple[NDArray, int, bool, str]:
    ubg = -nlp.constraint_margins()
    if solver == "ipopt":
        problem, plugin, keep = nlp.nlpsol_problem()
        ipopt = {
            "ipopt.max_iter": int(opts["maxiter"]),
            "ipopt.tol": float(opts["ftol"]) * 100,
            "ipopt.bound_relax_factor": 0.0,
            **deadline.ipopt_options(),
            **plugin,
        }
        rep = solve_nlpsol(problem, x0, np.full(ubg.size, -np.inf), ubg, ipopt)
        del keep
        return (
            np.asarray(rep.value(None), dtype=float),
            int(rep.stats.iterations or 0),
            rep.status.is_solved,
            rep.message,
        )

    def fun(z):
        if deadline.expired:
            raise _Stop
        f = nlp.f(z)
        return f if math.isfinite(f) else 1e20

    def cons(z):
        g = nlp.g(z)
        return np.where(np.isfinite(g), ubg - g, -1e20)

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = scipy.optimize.minimize(
            fun,
            x0,
            jac=nlp.grad,
            method="SLSQP",
            constraints=[{"type": "ineq", "fun": cons, "jac": lambda z: -nlp.jac(z)}],
            options={"maxiter": int(opts["maxiter"]), "ftol": float(opts["ftol"])},
        )
    return np.asarray(res.x, dtype=float), int(res.nit), bool(res.success), f"slsqp: {res.message}"


def _nlp_result(
    spec: _Spec, best: _Cand | None, records: list[RobustStart], lmi_res, per_model: list, t_start: float
) -> RobustObserverDesign:
    ms, regions, objective, aggregate, deadline = (
        spec.ms,
        spec.regions,
        spec.objective,
        spec.aggregate,
        spec.deadline,
    )
    stats = SolverStats(
        backend=spec.nlp_solver,
        native_status=records[-1].message if records else "",
        time=time.process_time() - t_start,
        iterations=sum(r.iterations for r in records),
        extra={"starts": len(records), "verified": sum(r.verified for r in records)},
    )
    extra: dict[str, Any] = {
        "per_model": [d.value for d in per_model],
        "per_model_success": [d.success for d in per_model],
    }
    if best is None:
        status = Status.TIME_LIMIT if deadline.expired else Status.NOT_FOUND
        cert = None
        why = f"no start gave a gain verified on every model ({len(records)} starts)"
        if (
            lmi_res is not None
            and lmi_res.certificate is not None
            and lmi_res.certificate.kind == "lmi_farkas"
        ):
            cert = lmi_res.certificate
            why += "; and no common Lyapunov matrix exists (LMI Farkas certificate) -- feasibility unknown"
        return failed_design(
            ms,
            regions,
            "nlp",
            objective,
            aggregate,
            status,
            why,
            cert,
            stats,
            starts=tuple(records),
            lmi=lmi_res,
            extra=extra,
        )
    L = best.L
    mm = evaluate_models(ms, L, regions)  # every metric (the ranking computed only what it needed)
    cert, how = None, "not checked"
    if spec.certify:
        cert, how = certify_gain(
            ms,
            regions,
            L,
            lmi_res,
            spec.sdp_solver,
            deadline,
            spec.bounds["h2_max"] is not None,
            spec.bounds["hinf_max"] is not None,
        )
    certified = bool(cert is not None and cert.holds) if spec.certify else None
    dense = dense_check(
        ms, L, regions[ms.nominal if ms.nominal is not None else 0], spec.dense_points, spec.seed
    )
    verification, polytope_note, polytope_ok = polytope_claim(ms, best.verification, cert, dense)
    if polytope_ok is False and _lmi_covers_polytope(lmi_res):
        # the NLP's gain leaves the region inside the polytope; the LMI gain is proven on all of it
        mm_l = evaluate_models(ms, lmi_res.L, regions)
        value_l = _value_of(objective, aggregate, mm_l, lmi_res.L, np.asarray(ms.weights, dtype=float))
        return dataclasses.replace(
            lmi_res, method="nlp", objective=objective, aggregate=aggregate, value=value_l, metrics=mm_l,
            starts=tuple(records), lmi=lmi_res, extra={**lmi_res.extra, **extra},
            message=(f"the NLP's best gain is verified at the vertices only{polytope_note}; the LMI gain, "
                     f"proven on the whole polytope by its common Lyapunov certificate, is returned: "
                     f"{lmi_res.message}"))
    improvement = math.nan
    if lmi_res is not None and np.all(np.isfinite(lmi_res.L)) and lmi_res.metrics is not None:
        lv = _value_of(objective, aggregate, lmi_res.metrics, lmi_res.L, np.asarray(ms.weights, dtype=float))
        improvement = lv / best.value if best.value > 0 else math.nan
    if deadline.expired:
        status = Status.TIME_LIMIT
    elif polytope_ok is False:  # an interior plant outside the region: no gain verified on the polytope
        status = Status.NOT_FOUND
    else:
        status = Status.OPTIMAL if best.converged else Status.OPTIMAL_INACCURATE
    what = {"kappa2": "kappa2", "h2": "H2", "gain": "||L||_F"}[objective]
    msg = (
        f"{'worst-case' if aggregate == 'max' else 'weighted'} {what} = {best.value:.6g} over "
        f"{len(ms)} models "
        f"(verified on every model{polytope_note}); {sum(r.verified for r in records)} of {len(records)} "
        f"starts verified"
    )
    if math.isfinite(improvement):
        msg += f"; {improvement:.3g}x better than the LMI gain"
    if spec.certify:
        covers = f" (covers {cert.covers})" if cert is not None and cert.holds else ""
        msg += f"; common Lyapunov certificate: {how}{covers}"
    return RobustObserverDesign(
        L=L,
        method="nlp",
        objective=objective,
        aggregate=aggregate,
        value=best.value,
        models=ms,
        regions=regions,
        status=status,
        message=msg,
        solver_stats=stats,
        verification=verification,
        metrics=mm,
        lmi_certificate=cert,
        certified=certified,
        dense=dense,
        starts=tuple(records),
        lmi=lmi_res,
        improvement=improvement,
        extra=extra,
        certificate=None if cert is None else Certificate("lmi", how, cert.as_dict()),
    )


def _lmi_covers_polytope(lmi_res) -> bool:
    """The LMI start succeeded and its certificate covers the convex hull of the models."""
    return bool(lmi_res is not None and lmi_res.success and lmi_res.lmi_certificate is not None
                and lmi_res.lmi_certificate.holds and lmi_res.lmi_certificate.covers == "convex hull")


#: the most random interior plants :func:`robust_observer` draws (each costs an eigendecomposition,
#: kappa2 and an H2 Lyapunov solve: O(n^3); 10**5 at n = 10 is about a minute)
DENSE_POINTS_MAX = 100_000


def dense_count(value: Any) -> int:
    """``dense_points``, an integer in ``[0, DENSE_POINTS_MAX]`` (refused beyond: issue 26 ran
    ``dense_points=10**7`` unbounded)."""
    k = as_int("dense_points", value, 0)
    if k > DENSE_POINTS_MAX:
        raise ValidationError(f"dense_points must be at most {DENSE_POINTS_MAX} (each interior plant "
                              f"costs an "
                              f"eigendecomposition, kappa2 and an H2 solve); found {k}")
    return k


def polytope_claim(ms: ModelSet, verification: Verification, cert, dense: DenseCheck):
    """What a gain verified at the models proves for a polytope (issue 26: 6 of 12 NLP successes
    had 8-44 of 200 interior plants outside the region while the message said "verified on every
    model").

    A polytope claim holds by a common Lyapunov certificate for the convex hull, or -- without one
    -- when every random interior plant of the dense check has its poles in the region (to the
    region's rounding tolerance).  Returns ``(verification, note, ok)``: the verification with a
    ``polytope_interior`` check added (failing when an interior plant is outside the region, or
    when nothing beyond the vertices was checked), a phrase for the message, and ``ok`` (None for
    a set that is not a polytope)."""
    if not ms.covers_convex_hull:
        return verification, "", None
    if cert is not None and cert.holds and cert.covers == "convex hull":
        check = Check.at_most("polytope_interior", 0.0, 0.0,
                              "a common Lyapunov certificate covers every convex combination of the models")
        note = "; the polytope by a common Lyapunov certificate"
        return verification + Verification.of([check]), note, True
    if dense.count == 0:
        check = Check.at_most("polytope_interior", math.nan, 0.0,
                              "no certificate and no interior plant checked (dense_points=0): only the "
                              "vertices are verified")
        return (verification + Verification.of([check]),
                "; ONLY THE VERTICES were verified: no certificate and dense_points=0", None)
    outside = dense.count - dense.in_region
    check = Check.at_most("polytope_interior", float(outside), 0.0,
                          f"random interior plants (of {dense.count}) with a pole outside the region or "
                          f"unstable")
    if outside:
        return (verification + Verification.of([check]),
                f"; but NOT on the polytope: {outside} of {dense.count} random interior plants have poles "
                f"outside the region (worst margin {dense.worst_margin:.3g}); only the vertices are verified",
                False)
    return (verification + Verification.of([check]),
            f"; no certificate for the polytope, all {dense.count} random interior plants in the region",
            True)
