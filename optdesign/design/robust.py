r"""Robust observer design: one gain for many plant models (issue 15).

A real plant is never one model -- operating points, parameter uncertainty, failure modes.  The
verbs here design one observer gain ``L`` for every model of a
:class:`~optdesign.model.model_set.ModelSet` (or a list of plants):

* :func:`robust_lmi_observer` -- the **convex route**: regional pole placement with a common
  Lyapunov matrix over the models (Chilali & Gahinet 1996), H2 and H-infinity bounds of the
  estimation error in Luenberger form (the observer duals of Chilali, Gahinet & Apkarian 1999 /
  MATLAB's ``msfsyn``), in cvxpy with Clarabel or SCS
  (:mod:`optdesign.formulate.robust_lmi`).  It returns the gain **with its certificate** -- the
  Lyapunov matrix ``P`` -- and what ``P`` proves is recomputed in numpy
  (:func:`~optdesign.design.robust_verify.certify`): for a polytope (kind ``"polytope"``) the
  region and the bounds hold for *every convex combination* of the models, not only the models.
  An infeasible LMI answers with its Farkas certificate, verified in numpy -- which proves that no
  common quadratic certificate exists, not that no robust gain exists.
* :func:`robust_observer` -- the **NLP route**: the exact, non-convex problem on all models at
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

Measured (``benchmarks/bench_robust.py``): SLSQP reached better worst-case kappa2 than IPOPT
(limited-memory Hessian, numpy callbacks) on 5 of 7 COMPleib sets at 5-40x less CPU time, and
IPOPT diverged on three of them; SLSQP is the default.

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

import math
import time
import warnings
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._deadline import Deadline, as_time_limit
from .._validate import as_int, as_positive_float
from ..errors import DimensionError, ValidationError
from ..formulate.robust_nlp import KAPPA2_ORDERS
from ..model.model_set import ModelSet, as_model_set
from ..model.regions import Region, stability_region
from ..results import Check, ResultMixin, SolverStats, Status, Verification
from .robust_verify import (
    DenseCheck,
    LMICertificate,
    ModelMetrics,
    certificate_checks,
    certify,
    dense_check,
    evaluate_models,
    farkas_check,
    gain_checks,
)

__all__ = [
    "RobustObserverDesign",
    "RobustStart",
    "robust_observer",
    "robust_lmi_observer",
    "per_model_designs",
    "evaluate_gain",
    "fixed_mode_certificate",
]

#: default NLP options (per continuation stage)
NLP_DEFAULTS: dict[str, Any] = {"maxiter": 200, "ftol": 1e-10, "orders": KAPPA2_ORDERS}


# --------------------------------------------------------------------------- result


@dataclass(frozen=True)
class RobustStart:
    """One start of the NLP route.

    Attributes
    ----------
    index : int
    origin : str
        ``"LMI (cond)"``, ``"model k design"``, ``"Kalman gain (nominal)"``, ``"perturbed best"``.
    verified : bool
        Its best candidate passed every check on every model.
    value : float
        The objective of its best candidate (worst-case or weighted kappa2 / H2, or ``||L||_F``).
    start_value : float
        The objective at the start gain (nan when the start gain was not verified).
    converged : bool
        A continuation stage reported convergence.
    iterations : int
    time : float
        CPU seconds.
    message : str
    """

    index: int
    origin: str
    verified: bool
    value: float
    start_value: float
    converged: bool
    iterations: int
    time: float
    message: str = ""


@dataclass(frozen=True, kw_only=True)
class RobustObserverDesign(ResultMixin):
    """A robust observer gain for a set of models, with its evidence.

    Attributes
    ----------
    L : (n, p) ndarray
        The gain (NaN when nothing was found); error dynamics ``A_i - L C_i``.
    method : {"lmi", "nlp"}
    objective : str
    aggregate : str
        ``"max"`` (worst case) or ``"mean"`` (weighted).
    value : float
        The objective: worst-case / weighted kappa2 or H2 (``"cond"``: ``sqrt(cond P)`` of the
        certificate, ``"gain"``: ``||L||_2``).
    models : ModelSet
    regions : tuple of (Region or None)
        The hard region of each model.
    metrics : ModelMetrics or None
        Per model: poles, kappa2, eta, H2, H-infinity, region margin (see also the properties).
    lmi_certificate : LMICertificate or None
        The common Lyapunov matrix and what it proves (LMI route: the solver's P; NLP route: the
        LMI's P if it still certifies the refined gain, else a fresh analysis SDP's, else None).
    certified : bool or None
        A common Lyapunov certificate holds for ``L`` (None: not checked).
    dense : DenseCheck or None
        The gain at random interior plants of the set.
    starts : tuple of RobustStart
        NLP route: the per-start history.
    lmi : RobustObserverDesign or None
        NLP route: the LMI design it started from.
    improvement : float
        NLP route: (objective of the LMI gain) / (objective of the returned gain); nan if none.
    status, message, solver_stats, verification, certificate, target_poles, extra
        The common result fields; ``certificate`` is a dict ``{"kind", "reason", "data"}``
        (infeasible: the proof; LMI route: ``"lmi"`` with P).
    """

    L: NDArray[np.float64]
    method: str
    objective: str
    aggregate: str
    value: float
    models: ModelSet
    regions: tuple[Region | None, ...]
    status: Status
    message: str
    solver_stats: SolverStats
    verification: Verification
    metrics: ModelMetrics | None = None
    lmi_certificate: LMICertificate | None = None
    certified: bool | None = None
    dense: DenseCheck | None = None
    starts: tuple[RobustStart, ...] = ()
    lmi: RobustObserverDesign | None = None
    improvement: float = math.nan
    certificate: dict[str, Any] | None = None
    target_poles: NDArray[np.complex128] | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    # per-model views
    @property
    def poles(self) -> tuple[NDArray[np.complex128], ...]:
        """``eig(A_i - L C_i)`` per model."""
        return self.metrics.poles if self.metrics is not None else ()

    @property
    def kappa2(self) -> NDArray[np.float64]:
        """kappa2 per model."""
        return self.metrics.kappa2 if self.metrics is not None else np.zeros(0)

    @property
    def eta(self) -> NDArray[np.float64]:
        return self.metrics.eta if self.metrics is not None else np.zeros(0)

    @property
    def h2(self) -> NDArray[np.float64]:
        """H2 norm of the estimation error per model (nan without noise models)."""
        return self.metrics.h2 if self.metrics is not None else np.zeros(0)

    @property
    def hinf(self) -> NDArray[np.float64]:
        return self.metrics.hinf if self.metrics is not None else np.zeros(0)

    @property
    def worst_kappa2(self) -> float:
        return self.metrics.worst("kappa2") if self.metrics is not None else math.nan

    @property
    def worst_h2(self) -> float:
        return self.metrics.worst("h2") if self.metrics is not None else math.nan

    def record(self) -> dict[str, Any]:
        """Scalar summary for tables and sweeps."""
        return {
            "status": Status(self.status).value, "success": self.success, "method": self.method,
            "objective": self.objective, "value": self.value, "worst_kappa2": self.worst_kappa2,
            "worst_h2": self.worst_h2, "worst_hinf": self.metrics.worst("hinf") if self.metrics else math.nan,
            "gain_norm": float(np.linalg.norm(self.L, 2)) if np.all(np.isfinite(self.L)) else math.nan,
            "models": len(self.models), "certified": self.certified,
            "dense_fraction": self.dense.fraction if self.dense is not None else math.nan,
            "improvement": self.improvement, "time": self.solver_stats.time,
        }

    def summary(self) -> str:
        """A readable report: status, the per-model table and the checks."""
        lines = [f"{self.method.upper()} robust observer ({len(self.models)} models): {Status(self.status).value}, "
                 f"success {self.success}", self.message]
        if self.metrics is not None:
            lines.append(f"{'model':<40} {'kappa2':>10} {'eta':>10} {'H2':>10} {'Hinf':>10} {'margin':>10}")
            for i in range(len(self.models)):
                m = self.metrics
                lines.append(f"{self.models.label(i)[:40]:<40} {m.kappa2[i]:>10.4g} {m.eta[i]:>10.4g} "
                             f"{m.h2[i]:>10.4g} {m.hinf[i]:>10.4g} {m.margin[i]:>10.3g}")
        if self.dense is not None and self.dense.count:
            lines.append(f"dense check: {self.dense.in_region}/{self.dense.count} random interior plants in the "
                         f"region, worst kappa2 {self.dense.worst_kappa2:.4g}")
        lines.append(self.verification.summary())
        return "\n".join(lines)

    def __repr__(self) -> str:
        return (f"RobustObserverDesign(method={self.method}, status={Status(self.status).value}, "
                f"success={self.success}, value={self.value:.6g}, models={len(self.models)}, "
                f"certified={self.certified})")


# --------------------------------------------------------------------------- validation


def _regions(region: Any, models: ModelSet, name: str, default: bool) -> tuple[Region | None, ...]:
    """One region (or None) per model from a Region, a sequence of them, or None."""
    N = len(models)
    if region is None:
        return tuple(stability_region(models.is_discrete) for _ in range(N)) if default else (None,) * N
    if isinstance(region, Region):
        out: tuple[Region | None, ...] = (region,) * N
    else:
        try:
            out = tuple(region)
        except TypeError:
            raise ValidationError(f"{name} must be a Region, a sequence of {N} Regions, or None; "
                                  f"found {type(region).__name__}") from None
        if len(out) != N:
            raise DimensionError(f"{name} must give one region per model: expected {N}, found {len(out)}")
        for k, r in enumerate(out):
            if r is not None and not isinstance(r, Region):
                raise ValidationError(f"{name}[{k}] must be a Region or None; found {type(r).__name__}")
    for k, r in enumerate(out):
        if r is not None:
            _check_region_stable(r, models.is_discrete, f"{name}[{k}]" if not isinstance(region, Region) else name)
    return out


def _sup_modulus(region: Region) -> float:
    """``max |z|`` over a bounded region (ray bisection from an interior point)."""
    x0 = region.interior_point()
    th = np.linspace(0.0, math.pi, 721)
    d = np.exp(1j * th)
    lo, hi = np.zeros(th.size), np.full(th.size, 4.0)
    while np.any(region.distance(x0 + hi * d) <= 0.0):
        hi = np.where(region.distance(x0 + hi * d) <= 0.0, 2.0 * hi, hi)
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        inside = region.distance(x0 + mid * d) <= 0.0
        lo, hi = np.where(inside, mid, lo), np.where(inside, hi, mid)
    return float(np.max(np.abs(x0 + hi * d)))


def _check_region_stable(region: Region, discrete: bool, name: str) -> None:
    """A hard region must lie in the closed stability region of the models' time domain."""
    if discrete:
        sup = _sup_modulus(region) if region.bounded else math.inf
        if sup > 1.0 + 1e-9:
            raise ValidationError(f"{name} {region!r} reaches |z| = {sup:.6g} > 1, outside the discrete-time "
                                  "stability region; intersect it with Disk.unit(r), r <= 1")
    elif region.real_interval()[1] > 0.0:
        raise ValidationError(f"{name} {region!r} reaches Re s = {region.real_interval()[1]:.6g} > 0, outside the "
                              "continuous-time stability region; intersect it with HalfPlane(alpha), alpha >= 0")


def _check_mask(gain_mask: Any, n: int, p: int) -> NDArray[np.bool_] | None:
    if gain_mask is None:
        return None
    m = np.asarray(gain_mask)
    if m.shape != (n, p):
        raise DimensionError(f"gain_mask (free entries of L) must have shape ({n}, {p}); found {m.shape}")
    if m.dtype != bool:
        if not np.all(np.isin(m, (0, 1))):
            raise ValidationError("gain_mask must be boolean (True = free entry of L, False = structural zero)")
        m = m.astype(bool)
    if not m.any():
        raise ValidationError("gain_mask has no free entry: L would be zero (nothing to design)")
    return m


def _opt_bound(name: str, value: Any, lo: float | None = None) -> float | None:
    if value is None:
        return None
    v = as_positive_float(name, value)
    if lo is not None and v < lo:
        raise ValidationError(f"{name} must be >= {lo:g}; found {value!r}")
    return v


def _check_choice(name: str, value: Any, allowed: tuple[str, ...]) -> str:
    if value not in allowed:
        raise ValidationError(f"{name} must be one of {allowed}; found {value!r}")
    return value


def fixed_mode_certificate(models: ModelSet, regions: tuple[Region | None, ...]) -> dict[str, Any] | None:
    """A global proof of infeasibility, if there is one: a model with an unobservable mode outside its
    region (no gain moves an unobservable eigenvalue of ``A - L C``).

    Returns
    -------
    dict or None
        ``{"kind": "fixed_mode", "reason": ..., "data": {"model", "mode", "region", "distance"}}``.
    """
    for i, pl in enumerate(models):
        modes = pl.unobservable_modes()
        reg = regions[i] if regions[i] is not None else stability_region(models.is_discrete)
        for z in modes:
            d = float(reg.distance([z])[0])
            if d > 0.0:
                return {"kind": "fixed_mode",
                        "reason": f"{models.label(i)} has the unobservable mode {complex(z):.6g}, at distance {d:.3g} "
                                  f"outside its region {reg!r}: no gain L moves it",
                        "data": {"model": i, "mode": complex(z), "region": reg.to_dict(), "distance": d}}
    return None


def _nan_design(models, regions, method, objective, aggregate, status, message, certificate=None,
                stats=None, checks=None, **kw) -> RobustObserverDesign:
    return RobustObserverDesign(
        L=np.full((models.n, models.p), np.nan), method=method, objective=objective, aggregate=aggregate,
        value=math.nan, models=models, regions=regions, status=status, message=message,
        solver_stats=stats or SolverStats(backend="analytic", native_status=str(status)),
        verification=Verification.of(checks or [Check.at_most("found", 1.0, 0.0, message)]),
        certificate=certificate, **kw)


# --------------------------------------------------------------------------- the LMI route


def robust_lmi_observer(
    models: ModelSet | list, *, region: Region | list | None = None,
    objective: Literal["cond", "gain", "h2", "hinf"] = "cond",
    h2_max: float | None = None, hinf_max: float | None = None, gain_mask: ArrayLike | None = None,
    max_gain: float | None = None, weights: ArrayLike | None = None, sdp_solver: str | None = None,
    margin: float | None = None, dense_points: int = 200, seed: int = 0, time_limit: float | None = None,
    options: dict[str, Any] | None = None,
) -> RobustObserverDesign:
    """Robust observer gain by LMIs with a common Lyapunov matrix: a gain with a certificate.

    Parameters
    ----------
    models : ModelSet or sequence of Plant
        ``N`` models with the same n, p, m and time domain.
    region : Region or sequence of (Region or None), optional
        Hard pole region per model (default: the stability region); it must lie in the closed
        stability region of the time domain.
    objective : {"cond", "gain", "h2", "hinf"}, default "cond"
        Minimize ``cond(P)`` (the conditioning of the certificate, a proxy of kappa2), the bound on
        ``||L||_2``, the guaranteed worst-case H2 norm or H-infinity norm of the estimation error
        (module :mod:`optdesign.formulate.robust_lmi`).
    h2_max, hinf_max : float, optional
        Bounds on every model's H2 / H-infinity norm (need noise models Q, R).
    gain_mask : (n, p) array_like of bool, optional
        Free entries of L (the others are structural zeros); makes P diagonal (conservative).
    max_gain : float, optional
        Bound on ``||L||_2`` (conservative: ``||P^-1 Y||``).
    weights : (N,) array_like, optional
        Replace the set's weights (unused by the LMIs; kept in the result).
    sdp_solver : {"CLARABEL", "SCS"}, optional
    margin : float, optional
        Region strictness (default ``1e-6 max(1, max ||A_i||)``).
    dense_points : int, default 200
        Random interior plants for the dense check (0: none).
    seed : int, default 0
    time_limit : float, optional
        Seconds (the SDP solver's time limit).
    options : dict, optional
        SDP solver options.

    Returns
    -------
    RobustObserverDesign
        ``method="lmi"``; ``lmi_certificate`` with ``P`` and what it proves (region shrink, H2 and
        H-infinity bounds, recomputed in numpy); ``certified``; ``certificate = {"kind": "lmi", ...}``.
        Infeasible LMIs: status ``infeasible`` with ``certificate["kind"] == "lmi_farkas"`` (verified
        in numpy: no common Lyapunov matrix exists -- a robust gain may still exist, try
        :func:`robust_observer`), or ``"fixed_mode"`` (no gain can meet the region at all).

    Raises
    ------
    ValidationError
        Bad models, regions, mask, bounds, objective or options; norms without noise models.
    DimensionError
        A region list or mask of the wrong size.

    References
    ----------
    Chilali & Gahinet 1996; Chilali, Gahinet & Apkarian 1999; MathWorks ``msfsyn``.
    """
    ms = as_model_set(models, weights)
    regions = _regions(region, ms, "region", default=True)
    _check_choice("objective", objective, ("cond", "gain", "h2", "hinf"))
    mask = _check_mask(gain_mask, ms.n, ms.p)
    h2_max, hinf_max, max_gain = (_opt_bound("h2_max", h2_max), _opt_bound("hinf_max", hinf_max),
                                  _opt_bound("max_gain", max_gain))
    dense_points, seed = as_int("dense_points", dense_points, 0), as_int("seed", seed, 0)
    margin = None if margin is None else as_positive_float("margin", margin)
    if (objective in ("h2", "hinf") or h2_max or hinf_max) and not ms.has_noise_model:
        raise ValidationError("the H2 / H-infinity objectives and bounds need a noise model (Q and R) in every model")
    deadline = Deadline(as_time_limit(time_limit))
    return _lmi_design(ms, regions, objective, h2_max=h2_max, hinf_max=hinf_max, mask=mask, max_gain=max_gain,
                       sdp_solver=sdp_solver, margin=margin, dense_points=dense_points, seed=seed,
                       deadline=deadline, options=options)


def _lmi_design(ms: ModelSet, regions, objective: str, *, h2_max, hinf_max, mask, max_gain, sdp_solver, margin,
                dense_points: int, seed: int, deadline: Deadline, options) -> RobustObserverDesign:
    from ..formulate.robust_lmi import build_robust_lmi
    from ..solvers.cvxpy_backend import solve_cvxpy

    fixed = fixed_mode_certificate(ms, regions)
    if fixed is not None:
        return _nan_design(ms, regions, "lmi", objective, "max", Status.INFEASIBLE, fixed["reason"], fixed)
    t0 = time.process_time()
    lmi = build_robust_lmi(ms, regions, objective=objective, h2_max=h2_max, hinf_max=hinf_max,
                           max_gain=max_gain, gain_mask=mask, margin=margin)
    opts = {**(options or {}), **deadline.sdp_options(sdp_solver or "CLARABEL")}
    rep = solve_cvxpy(lmi.problem, sdp_solver, opts)
    stats = SolverStats(backend=rep.stats.backend, native_status=rep.stats.native_status,
                        time=time.process_time() - t0, iterations=rep.stats.iterations, extra=dict(rep.stats.extra))
    L = lmi.gain() if rep.status.is_solved else None
    if L is None:
        if rep.status.is_infeasible:
            fk = farkas_check(lmi, ms)
            what = ("no common Lyapunov matrix P satisfies the LMIs at every model (a sufficient condition only: a "
                    "robust gain may still exist -- try robust_observer)")
            cert = {"kind": "lmi_farkas", "reason": what, "data": fk}
            if fk.get("verified"):
                msg = (f"LMIs infeasible: {what}; Farkas certificate verified in numpy: no solution within radius "
                       f"{fk['radius']:.3g}")
                return _nan_design(ms, regions, "lmi", objective, "max", rep.status, msg, cert, stats,
                                   [Check.at_least("farkas_radius", fk["radius"], 1e8 * fk["scale"],
                                                   "no LMI solution within this radius (dual certificate, numpy)")])
            msg = f"{rep.message}; the dual certificate did not verify ({fk}): feasibility unknown"
            return _nan_design(ms, regions, "lmi", objective, "max", Status.NOT_FOUND, msg, cert, stats)
        status = Status.TIME_LIMIT if deadline.expired else (
            rep.status if not rep.status.is_solved else Status.NUMERICAL_ERROR)
        return _nan_design(ms, regions, "lmi", objective, "max", status, f"no gain: {rep.message}", None, stats)
    vals = lmi.values()
    P = vals["P"]
    want_h2 = objective == "h2" or h2_max is not None
    want_hinf = objective == "hinf" or hinf_max is not None
    cert = certify(ms, L, P, regions, h2=want_h2, hinf=want_hinf)
    mm = evaluate_models(ms, L, regions)
    checks = gain_checks(ms, L, mm, regions, mask=mask, max_gain=max_gain, h2_max=h2_max, hinf_max=hinf_max)
    nu = vals.get("nu")
    claim_h2 = math.sqrt(float(nu)) if (objective == "h2" and nu is not None) else h2_max
    claim_hinf = math.sqrt(float(nu)) if (objective == "hinf" and nu is not None) else hinf_max
    checks = checks + certificate_checks(cert, h2_claim=claim_h2, hinf_claim=claim_hinf)
    dense = dense_check(ms, L, regions[ms.nominal if ms.nominal is not None else 0], dense_points, seed)
    if ms.covers_convex_hull and dense.count and cert.holds:
        checks = checks + Verification.of([Check.at_least(
            "dense_region", dense.in_region, dense.count,
            f"random convex combinations in the region ({dense.in_region}/{dense.count}): what the certificate proves")])
    value = {"cond": math.sqrt(cert.P_cond), "gain": float(np.linalg.norm(L, 2)),
             "h2": claim_h2 if claim_h2 is not None else math.nan,
             "hinf": claim_hinf if claim_hinf is not None else math.nan}[objective]
    covers = "every convex combination of the models" if ms.covers_convex_hull else "the models (not between them)"
    status = rep.status
    msg = (f"LMI {objective}: {rep.message}; common Lyapunov certificate {'holds' if cert.holds else 'FAILS'} "
           f"for {covers}" + (f"; certified H2 <= {cert.h2_bound:.6g}" if want_h2 else "")
           + (f"; certified H-infinity <= {cert.hinf_bound:.6g}" if want_hinf else ""))
    return RobustObserverDesign(
        L=L, method="lmi", objective=objective, aggregate="max", value=value, models=ms, regions=regions,
        status=status, message=msg, solver_stats=stats, verification=checks, metrics=mm, lmi_certificate=cert,
        certified=cert.holds, dense=dense,
        certificate={"kind": "lmi", "reason": f"common Lyapunov matrix P, valid for {covers}",
                     "data": cert.as_dict()},
        extra={"margin": lmi.spec.margin, "diagonal_P": lmi.spec.diagonal_P})


# --------------------------------------------------------------------------- the NLP route


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


def _value_of(objective: str, aggregate: str, mm: ModelMetrics, L: NDArray, w: NDArray) -> float:
    if objective == "gain":
        return float(np.linalg.norm(L))
    v = mm.kappa2 if objective == "kappa2" else mm.h2
    return float(np.max(v)) if aggregate == "max" else float(w @ v)


def robust_observer(
    models: ModelSet | list, *, region: Region | list | None = None, soft_region: Region | list | None = None,
    soft_weight: float = 1.0, objective: Literal["kappa2", "h2", "gain"] = "kappa2",
    aggregate: Literal["max", "mean"] = "max", kappa2_max: float | None = None, h2_max: float | None = None,
    hinf_max: float | None = None, gain_mask: ArrayLike | None = None, max_gain: float | None = None,
    weights: ArrayLike | None = None, starts: int = 2, per_model_starts: bool = True, lmi_start: bool = True,
    seed: int = 0, nlp_solver: Literal["slsqp", "ipopt"] = "slsqp", sdp_solver: str | None = None,
    dense_points: int = 200, certify_gain: bool = True, time_limit: float | None = None,
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
    per_model_starts : bool, default True
        Start from each model's own design (:func:`per_model_designs`).
    lmi_start : bool, default True
        Start from the LMI gain (:func:`robust_lmi_observer`, objective ``"cond"``, same regions and
        bounds); it is kept as ``result.lmi``.
    seed : int, default 0
    nlp_solver : {"slsqp", "ipopt"}, default "slsqp"
    sdp_solver : {"CLARABEL", "SCS"}, optional
    dense_points : int, default 200
    certify_gain : bool, default True
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
    """
    from ..formulate.robust_nlp import build_robust_nlp

    ms = as_model_set(models, weights)
    regions = _regions(region, ms, "region", default=True)
    soft = _regions(soft_region, ms, "soft_region", default=False)
    _check_choice("objective", objective, ("kappa2", "h2", "gain"))
    _check_choice("aggregate", aggregate, ("max", "mean"))
    _check_choice("nlp_solver", nlp_solver, ("slsqp", "ipopt"))
    mask = _check_mask(gain_mask, ms.n, ms.p)
    kappa2_max = _opt_bound("kappa2_max", kappa2_max, 1.0)
    h2_max, hinf_max, max_gain = (_opt_bound("h2_max", h2_max), _opt_bound("hinf_max", hinf_max),
                                  _opt_bound("max_gain", max_gain))
    soft_weight = as_positive_float("soft_weight", soft_weight)
    starts, seed, dense_points = as_int("starts", starts, 0), as_int("seed", seed, 0), as_int("dense_points",
                                                                                            dense_points, 0)
    opts = {**NLP_DEFAULTS, **(options or {})}
    unknown = set(opts) - {"maxiter", "ftol", "orders"}
    if unknown:
        raise ValidationError(f"options has unknown keys {sorted(unknown)}; known: maxiter, ftol, orders")
    if (objective == "h2" or h2_max or hinf_max) and not ms.has_noise_model:
        raise ValidationError("the H2 objective, h2_max and hinf_max need a noise model (Q and R) in every model")
    deadline = Deadline(as_time_limit(time_limit))
    t_start = time.process_time()
    fixed = fixed_mode_certificate(ms, regions)
    if fixed is not None:
        return _nan_design(ms, regions, "nlp", objective, aggregate, Status.INFEASIBLE, fixed["reason"], fixed)
    bounds = dict(h2_max=h2_max, hinf_max=hinf_max, max_gain=max_gain)
    # ---- starts
    start_list: list[tuple[str, NDArray]] = []
    lmi_res = None
    if lmi_start:
        lmi_res = _lmi_design(ms, regions, "cond", mask=mask, sdp_solver=sdp_solver, margin=None, dense_points=0,
                              seed=seed, deadline=deadline, options=None, **bounds)
        if np.all(np.isfinite(lmi_res.L)):
            start_list.append(("LMI (cond)", lmi_res.L))
    per_model: list[RobustObserverDesign] = []
    if per_model_starts and len(ms) > 1:
        for i in range(len(ms)):
            if deadline.expired:
                break
            d = robust_observer(ModelSet([ms[i]]), region=regions[i], soft_region=soft[i], soft_weight=soft_weight,
                                objective=objective, kappa2_max=kappa2_max, gain_mask=mask, seed=seed,
                                starts=0, per_model_starts=False, nlp_solver=nlp_solver, sdp_solver=sdp_solver,
                                dense_points=0, certify_gain=False, options=options,
                                time_limit=deadline.fraction(1.0 / (len(ms) - i + 2)) if deadline.limited else None,
                                **bounds)
            per_model.append(d)
            if np.all(np.isfinite(d.L)):
                start_list.append((f"{ms.label(i)} design", d.L))
    kal = _kalman_start(ms)
    if kal is not None:
        start_list.append(("Kalman gain (nominal)", kal))
    if not start_list:
        start_list.append(("zero gain", np.zeros((ms.n, ms.p))))
    if mask is not None:
        start_list = [(o, np.where(mask, L0, 0.0)) for o, L0 in start_list]
    scale = max(1.0, max(float(np.max(np.abs(L0))) for _, L0 in start_list))
    h2_ref = 1.0
    if objective == "h2":
        mm0 = evaluate_models(ms, start_list[0][1], regions)
        h2_ref = float(np.nanmax(mm0.h2) ** 2) if np.isfinite(np.nanmax(mm0.h2)) else 1.0
    nlp = build_robust_nlp(ms, regions=regions, soft_regions=soft, objective=objective, aggregate=aggregate,
                           gain_mask=mask, kappa2_max=kappa2_max, soft_weight=soft_weight, gain_scale=scale,
                           h2_ref=h2_ref, **bounds)
    judge = _Judge(ms, regions, nlp, objective, aggregate, mask, kappa2_max, bounds)
    orders = tuple(opts["orders"]) if objective == "kappa2" or kappa2_max is not None else (None,)
    records: list[RobustStart] = []
    best: _Cand | None = None
    rng = np.random.default_rng(seed)
    k = 0
    while k < len(start_list) + starts:
        if deadline.expired:
            break
        if k < len(start_list):
            origin, L0 = start_list[k]
        else:
            if best is None:
                break
            origin = "perturbed best"
            L0 = best.L * (1.0 + 0.3 * rng.standard_normal(best.L.shape))
        t0 = time.process_time()
        c0 = judge(L0)
        cands, iters, conv, msg = _run_start(nlp, L0, orders, opts, nlp_solver, deadline, judge)
        cands = [c0, *cands]
        ok = [c for c in cands if c.verified]
        pick = min(ok, key=lambda c: c.rank) if ok else cands[-1]
        pick.converged = conv
        records.append(RobustStart(k, origin, pick.verified, pick.value, c0.value if c0.verified else math.nan,
                                   conv, iters, time.process_time() - t0, msg))
        if pick.verified and (best is None or pick.rank < best.rank):
            best = pick
        k += 1
    return _nlp_result(ms, regions, objective, aggregate, best, records, lmi_res, per_model, deadline, t_start,
                       dense_points, seed, certify_gain, sdp_solver, nlp_solver, mask, kappa2_max, bounds)


def _kalman_start(ms: ModelSet) -> NDArray | None:
    if not ms.has_noise_model:
        return None
    from ..classical.riccati import filter_are

    pl = ms[ms.nominal if ms.nominal is not None else 0]
    try:
        return filter_are(pl).L
    except (ValueError, np.linalg.LinAlgError):
        return None


class _Judge:
    """Verify a gain on every model and rank it by the NLP's exact objective."""

    def __init__(self, ms, regions, nlp, objective, aggregate, mask, kappa2_max, bounds):
        self.ms, self.regions, self.nlp = ms, regions, nlp
        self.objective, self.aggregate, self.mask = objective, aggregate, mask
        self.kappa2_max, self.bounds = kappa2_max, bounds

    def __call__(self, L: NDArray) -> _Cand:
        L = np.asarray(L, dtype=float)
        if self.mask is not None:
            L = np.where(self.mask, L, 0.0)
        need = self.objective == "h2" or any(self.bounds[k] is not None for k in ("h2_max", "hinf_max"))
        mm = evaluate_models(self.ms, L, self.regions, norms=need)
        v = gain_checks(self.ms, L, mm, self.regions, mask=self.mask, kappa2_max=self.kappa2_max, **self.bounds)
        value = _value_of(self.objective, self.aggregate, mm, L, self.ms.weights)
        rank = self.nlp.exact_objective(L)
        return _Cand(L, rank if math.isfinite(rank) else math.inf, value, v.passed, mm, v)


def _run_start(nlp, L0: NDArray, orders, opts, solver: str, deadline: Deadline, judge) -> tuple[list, int, bool, str]:
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
    import scipy.optimize

    ubg = -nlp.constraint_margins()
    if solver == "ipopt":
        from ..solvers.casadi_backend import solve_nlpsol

        problem, plugin, keep = nlp.nlpsol_problem()
        ipopt = {"ipopt.max_iter": int(opts["maxiter"]), "ipopt.tol": float(opts["ftol"]) * 100,
                 "ipopt.bound_relax_factor": 0.0, **deadline.ipopt_options(), **plugin}
        rep = solve_nlpsol(problem, x0, np.full(ubg.size, -np.inf), ubg, ipopt)
        del keep
        return np.asarray(rep.value(), dtype=float), int(rep.stats.iterations or 0), rep.status.is_solved, rep.message

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
        res = scipy.optimize.minimize(fun, x0, jac=nlp.grad, method="SLSQP",
                                      constraints=[{"type": "ineq", "fun": cons, "jac": lambda z: -nlp.jac(z)}],
                                      options={"maxiter": int(opts["maxiter"]), "ftol": float(opts["ftol"])})
    return np.asarray(res.x, dtype=float), int(res.nit), bool(res.success), f"slsqp: {res.message}"


def _certify_gain(ms, regions, L, lmi_res, sdp_solver, deadline, want_h2, want_hinf):
    """Does a common Lyapunov certificate hold for L?  The LMI's P first, then an analysis SDP."""
    from ..formulate.robust_lmi import build_robust_lmi
    from ..solvers.cvxpy_backend import solve_cvxpy

    if lmi_res is not None and lmi_res.lmi_certificate is not None:
        c = certify(ms, L, lmi_res.lmi_certificate.P, regions, h2=want_h2, hinf=want_hinf)
        if c.holds:
            return c, "the LMI's P still certifies the refined gain"
    if deadline.expired:
        return None, "not checked (time limit)"
    from ..formulate.robust_lmi import default_margin

    # the NLP keeps the poles default_margin inside; certify with a tenth of it
    lmi = build_robust_lmi(ms, regions, objective="cond", fixed_gain=L, margin=0.1 * default_margin(ms))
    rep = solve_cvxpy(lmi.problem, sdp_solver, deadline.sdp_options(sdp_solver or "CLARABEL"))
    P = lmi.values()["P"]
    if rep.status.is_solved and P is not None:
        c = certify(ms, L, P, regions, h2=want_h2, hinf=want_hinf)
        return c, ("a new common P (analysis SDP for the refined gain) certifies it" if c.holds
                   else "the analysis SDP's P does not verify")
    return None, f"no common Lyapunov matrix for the refined gain (analysis SDP: {rep.stats.native_status})"


def _nlp_result(ms, regions, objective, aggregate, best, records, lmi_res, per_model, deadline, t_start,
                dense_points, seed, certify_gain, sdp_solver, nlp_solver, mask, kappa2_max, bounds):
    stats = SolverStats(backend=nlp_solver, native_status=records[-1].message if records else "",
                        time=time.process_time() - t_start, iterations=sum(r.iterations for r in records),
                        extra={"starts": len(records), "verified": sum(r.verified for r in records)})
    extra: dict[str, Any] = {"per_model": [d.value for d in per_model],
                             "per_model_success": [d.success for d in per_model]}
    if best is None:
        status = Status.TIME_LIMIT if deadline.expired else Status.NOT_FOUND
        cert = None
        why = f"no start gave a gain verified on every model ({len(records)} starts)"
        if lmi_res is not None and lmi_res.certificate is not None and lmi_res.certificate["kind"] == "lmi_farkas":
            cert = lmi_res.certificate
            why += "; and no common Lyapunov matrix exists (LMI Farkas certificate) -- feasibility unknown"
        return _nan_design(ms, regions, "nlp", objective, aggregate, status, why, cert, stats, starts=tuple(records),
                           lmi=lmi_res, extra=extra)
    L = best.L
    mm = evaluate_models(ms, L, regions)  # every metric (the ranking computed only what it needed)
    want_h2, want_hinf = bounds["h2_max"] is not None, bounds["hinf_max"] is not None
    cert, how = (None, "not checked")
    if certify_gain:
        cert, how = _certify_gain(ms, regions, L, lmi_res, sdp_solver, deadline, want_h2, want_hinf)
    certified = None if not certify_gain else bool(cert is not None and cert.holds)
    dense = dense_check(ms, L, regions[ms.nominal if ms.nominal is not None else 0], dense_points, seed)
    improvement = math.nan
    if lmi_res is not None and np.all(np.isfinite(lmi_res.L)) and lmi_res.metrics is not None:
        lv = _value_of(objective, aggregate, lmi_res.metrics, lmi_res.L, ms.weights)
        improvement = lv / best.value if best.value > 0 else math.nan
    status = Status.TIME_LIMIT if deadline.expired else (Status.OPTIMAL if best.converged else
                                                          Status.OPTIMAL_INACCURATE)
    what = {"kappa2": "kappa2", "h2": "H2", "gain": "||L||_F"}[objective]
    msg = (f"{'worst-case' if aggregate == 'max' else 'weighted'} {what} = {best.value:.6g} over {len(ms)} models "
           f"(verified on every model); {sum(r.verified for r in records)} of {len(records)} starts verified")
    if math.isfinite(improvement):
        msg += f"; {improvement:.3g}x better than the LMI gain"
    if certify_gain:
        msg += f"; common Lyapunov certificate: {how}"
    return RobustObserverDesign(
        L=L, method="nlp", objective=objective, aggregate=aggregate, value=best.value, models=ms, regions=regions,
        status=status, message=msg, solver_stats=stats, verification=best.verification, metrics=mm,
        lmi_certificate=cert, certified=certified, dense=dense, starts=tuple(records), lmi=lmi_res,
        improvement=improvement, extra=extra,
        certificate=None if cert is None else {"kind": "lmi", "reason": how, "data": cert.as_dict()})


# --------------------------------------------------------------------------- helpers for users


def per_model_designs(models: ModelSet | list, **kwargs: Any) -> list[RobustObserverDesign]:
    """Each model's own robust-observer design (one model at a time): what one gain can do for that
    model alone -- the reference a gain for all models is measured against.

    Parameters
    ----------
    models : ModelSet or sequence of Plant
    **kwargs
        As for :func:`robust_observer` (``region`` may be per model); ``per_model_starts`` is off.

    Returns
    -------
    list of RobustObserverDesign
        One per model (local optima: the NLP is non-convex, so these are not proven bounds).
    """
    ms = as_model_set(models)
    regions = _regions(kwargs.pop("region", None), ms, "region", default=True)
    kwargs.pop("per_model_starts", None)
    return [robust_observer(ModelSet([ms[i]]), region=regions[i], per_model_starts=False, **kwargs)
            for i in range(len(ms))]


def evaluate_gain(models: ModelSet | list, L: ArrayLike, *, region: Region | list | None = None,
                  dense_points: int = 0, seed: int = 0) -> tuple[ModelMetrics, Verification, DenseCheck]:
    """Any gain on every model of a set (e.g. the nominal design on the others).

    Returns
    -------
    metrics : ModelMetrics
    verification : Verification
        Stability and region membership on every model.
    dense : DenseCheck
        At ``dense_points`` random interior plants.

    Raises
    ------
    ValidationError, DimensionError
        Bad models, regions or gain.
    """
    from .._validate import as_matrix

    ms = as_model_set(models)
    regions = _regions(region, ms, "region", default=True)
    L = as_matrix("L", L, (ms.n, ms.p))
    mm = evaluate_models(ms, L, regions)
    v = gain_checks(ms, L, mm, regions)
    return mm, v, dense_check(ms, L, regions[ms.nominal if ms.nominal is not None else 0],
                              as_int("dense_points", dense_points, 0), as_int("seed", seed, 0))
