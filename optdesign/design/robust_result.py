"""The result of the robust observer verbs and the input checks they share (issue 15).

:class:`RobustObserverDesign` is the result of :func:`~optdesign.design.robust.robust_observer` and
:func:`~optdesign.design.robust_lmi.robust_lmi_observer`: the gain, the per-model metrics, the
evidence (verification, LMI certificate, dense check) and the common result fields
(``status, message, solver_stats, verification, certificate, target_poles, extra``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._validate import as_positive_float
from ..errors import DimensionError, ValidationError
from ..model.model_set import ModelSet
from ..model.regions import Region, stability_region
from ..results import Certificate, Check, DesignResult, Route, SolverStats, Stage, Status, Verification
from .robust_verify import DenseCheck, LMICertificate, ModelMetrics

__all__ = [
    "RobustObserverDesign",
    "RobustStart",
    "as_regions",
    "optional_bound",
    "check_choice",
    "fixed_mode_certificate",
    "failed_design",
]


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


@dataclass(frozen=True, kw_only=True, eq=False)
class RobustObserverDesign(DesignResult):
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
        The common result fields (:class:`~optdesign.results.DesignResult`); ``certificate`` is a
        :class:`~optdesign.results.Certificate`: infeasible -- the proof (``"fixed_mode"``, or
        ``"lmi_farkas"`` for the LMIs); a gain with a common Lyapunov matrix -- ``"lmi"`` with ``P``.
    """

    L: NDArray[np.float64]
    method: str
    objective: str
    aggregate: str
    value: float
    models: ModelSet
    regions: tuple[Region | None, ...]
    metrics: ModelMetrics | None = None
    lmi_certificate: LMICertificate | None = None
    certified: bool | None = None
    dense: DenseCheck | None = None
    starts: tuple[RobustStart, ...] = ()
    lmi: RobustObserverDesign | None = None
    improvement: float = math.nan

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
        """The common record (:meth:`DesignResult.record`) with the worst-case metrics over the models."""
        out = super().record()
        out.update(
            worst_kappa2=self.worst_kappa2,
            worst_h2=self.worst_h2,
            worst_hinf=self.metrics.worst("hinf") if self.metrics else math.nan,
            gain_norm=float(np.linalg.norm(self.L, 2)) if np.all(np.isfinite(self.L)) else math.nan,
            models=len(self.models),
            dense_fraction=self.dense.fraction if self.dense is not None else math.nan,
        )
        return out

    def summary(self) -> str:
        """A readable report: status, the per-model table and the checks."""
        lines = [
            f"{self.method.upper()} robust observer ({len(self.models)} models): "
            f"{Status(self.status).value}, "
            f"success {self.success}",
            self.message,
        ]
        if self.metrics is not None:
            lines.append(f"{'model':<40} {'kappa2':>10} {'eta':>10} {'H2':>10} {'Hinf':>10} {'margin':>10}")
            for i in range(len(self.models)):
                m = self.metrics
                lines.append(
                    f"{self.models.label(i)[:40]:<40} {m.kappa2[i]:>10.4g} {m.eta[i]:>10.4g} "
                    f"{m.h2[i]:>10.4g} {m.hinf[i]:>10.4g} {m.margin[i]:>10.3g}"
                )
        if self.dense is not None and self.dense.count:
            lines.append(
                f"dense check: {self.dense.in_region}/{self.dense.count} random interior plants in the "
                f"region, worst kappa2 {self.dense.worst_kappa2:.4g}"
            )
        if self.certificate is not None:
            lines.append(f"certificate: {self.certificate}")
        if self.route:
            lines.append(f"route: {self.route}")
        lines.append(self.verification.summary())
        return "\n".join(lines)

    def __repr__(self) -> str:
        return (
            f"RobustObserverDesign(method={self.method}, status={Status(self.status).value}, "
            f"success={self.success}, value={self.value:.6g}, models={len(self.models)}, "
            f"certified={self.certified})"
        )


# --------------------------------------------------------------------------- validation


def as_regions(region: Any, models: ModelSet, name: str, default: bool) -> tuple[Region | None, ...]:
    """One region (or None) per model from a Region, a sequence of them, or None (``default``: the
    stability region of the time domain); each must lie in the closed stability region.

    Raises
    ------
    ValidationError
        Not a Region / sequence of Regions, or a region reaching outside the stability region.
    DimensionError
        A sequence of the wrong length.
    """
    N = len(models)
    if region is None:
        return tuple(stability_region(models.is_discrete) for _ in range(N)) if default else (None,) * N
    if isinstance(region, Region):
        out: tuple[Region | None, ...] = (region,) * N
    else:
        try:
            out = tuple(region)
        except TypeError:
            raise ValidationError(
                f"{name} must be a Region, a sequence of {N} Regions, or None; found {type(region).__name__}"
            ) from None
        if len(out) != N:
            raise DimensionError(f"{name} must give one region per model: expected {N}, found {len(out)}")
        for k, r in enumerate(out):
            if r is not None and not isinstance(r, Region):
                raise ValidationError(f"{name}[{k}] must be a Region or None; found {type(r).__name__}")
    for k, r in enumerate(out):
        if r is not None:
            _check_region_stable(
                r, models.is_discrete, f"{name}[{k}]" if not isinstance(region, Region) else name
            )
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
            raise ValidationError(
                f"{name} {region!r} reaches |z| = {sup:.6g} > 1, outside the discrete-time "
                "stability region; intersect it with Disk.unit(r), r <= 1"
            )
    elif region.real_interval()[1] > 0.0:
        raise ValidationError(
            f"{name} {region!r} reaches Re s = {region.real_interval()[1]:.6g} > 0, outside the "
            "continuous-time stability region; intersect it with HalfPlane(alpha), alpha >= 0"
        )


def optional_bound(name: str, value: Any, lo: float | None = None) -> float | None:
    """None, or a finite number ``> 0`` (and ``>= lo`` if given); ValidationError otherwise."""
    if value is None:
        return None
    v = as_positive_float(name, value)
    if lo is not None and v < lo:
        raise ValidationError(f"{name} must be >= {lo:g}; found {value!r}")
    return v


def check_choice(name: str, value: Any, allowed: tuple[str, ...]) -> str:
    """``value`` if it is one of ``allowed``; ValidationError naming the argument otherwise."""
    if value not in allowed:
        raise ValidationError(f"{name} must be one of {allowed}; found {value!r}")
    return value


def fixed_mode_certificate(models: ModelSet, regions: tuple[Region | None, ...]) -> Certificate | None:
    """A global proof of infeasibility, if there is one: a model with an unobservable mode outside its
    region (no gain moves an unobservable eigenvalue of ``A - L C``).

    Returns
    -------
    Certificate or None
        Kind ``"fixed_mode"``, data ``model``, ``mode``, ``region`` (its dict), ``distance``.
    """
    for i, pl in enumerate(models):
        modes = pl.unobservable_modes()
        given = regions[i]
        reg = given if given is not None else stability_region(models.is_discrete)
        for z in modes:
            d = float(reg.distance([z])[0])
            if d > 0.0:
                why = (
                    f"{models.label(i)} has the unobservable mode {complex(z):.6g}, at distance {d:.3g} "
                    f"outside its region {reg!r}: no gain L moves it"
                )
                return Certificate(
                    "fixed_mode", why, model=i, mode=complex(z), region=reg.to_dict(), distance=d
                )
    return None


def failed_design(
    models,
    regions,
    method,
    objective,
    aggregate,
    status,
    message,
    certificate=None,
    stats=None,
    checks=None,
    **kw,
) -> RobustObserverDesign:
    """A result without a gain (NaN): infeasible with its proof, not found, or out of time."""
    return RobustObserverDesign(
        L=np.full((models.n, models.p), np.nan),
        method=method,
        objective=objective,
        aggregate=aggregate,
        value=math.nan,
        models=models,
        regions=regions,
        status=status,
        message=message,
        solver_stats=stats or SolverStats(backend="analytic", native_status=str(status)),
        verification=Verification.of(checks or [Check.at_most("found", 1.0, 0.0, message)]),
        certificate=certificate,
        **kw,
    )


def robust_route(res: RobustObserverDesign) -> Route:
    """The route of a robust design (issue 26, item 2), built in one place from what the result
    records: the LMI (the convex route, or the NLP's first start), each NLP start and whether its
    gain verified, the common-Lyapunov certificate check, the dense check of a polytope.  The
    stage that produced the returned gain is ``answered``."""
    stages: list[Stage] = []
    has_gain = bool(np.all(np.isfinite(res.L))) if res.L is not None else False
    lmi = res if res.method == "lmi" else res.lmi
    if lmi is not None:
        st = lmi.solver_stats
        detail = "" if st is None else f"{st.backend}: {st.native_status}"
        answered = has_gain and Status(res.status).is_solved and (
            res.method == "lmi" or (lmi is not res and np.array_equal(res.L, lmi.L)))
        out = "answered" if answered else Status(lmi.status).value
        stages.append(Stage("robust_lmi", "backend", out, detail))
    if res.method == "nlp":
        verified = [s for s in res.starts if s.verified]
        from_lmi = lmi is not None and lmi is not res and has_gain and np.array_equal(res.L, lmi.L)
        best = min(verified, key=lambda s: s.value) if (verified and has_gain and not from_lmi) else None
        backend = "nlp"
        for s in res.starts:
            out = "answered" if s is best else ("rejected" if not s.verified else "unchanged")
            stages.append(Stage(f"{backend} from {s.origin}", "engine", out, f"value {s.value:.4g}"))
    if res.lmi_certificate is not None:
        cert = res.lmi_certificate
        stages.append(Stage("common_lyapunov_certificate", "certificate", "holds" if cert.holds else "fails",
                            f"covers the {cert.covers}"))
    if res.dense is not None and res.dense.count:
        d = res.dense
        stages.append(Stage("dense_check", "check", f"{d.in_region}/{d.count} in region",
                            "random interior plants"))
    if not stages:
        stages.append(Stage(res.method, "backend", Status(res.status).value))
    return Route(stages)
