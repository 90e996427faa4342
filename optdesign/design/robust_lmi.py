r"""The convex route of robust observer design: LMIs with a common Lyapunov matrix (issue 15).

:func:`robust_lmi_observer` poses regional pole placement (Chilali & Gahinet 1996) and the H2 /
H-infinity bounds of the estimation error in Luenberger form (the observer duals of Chilali, Gahinet
& Apkarian 1999 / MATLAB's ``msfsyn``) for every model at once, with one Lyapunov matrix ``P``
(:mod:`optdesign.formulate.robust_lmi`), solves them with Clarabel or SCS, and returns the gain
**with its certificate**: what ``P`` proves is recomputed in numpy
(:func:`~optdesign.design.robust_verify.certify`) -- for a polytope of plants (kind ``"polytope"``)
the region and the bounds hold for every convex combination of the models, not only the models.
An infeasible LMI answers with its Farkas certificate, verified in numpy: no common quadratic
certificate exists (a robust gain may still exist -- :func:`~optdesign.design.robust.robust_observer`
searches for one).  A model with an unobservable mode outside its region is a proof that no gain
exists at all (:func:`~optdesign.design.robust_result.fixed_mode_certificate`).

References
----------
M. Chilali and P. Gahinet, "H-infinity design with pole placement constraints: an LMI approach",
IEEE TAC 41(3), 1996.
M. Chilali, P. Gahinet and P. Apkarian, "Robust pole placement in LMI regions", IEEE TAC 44(12),
1999.
MathWorks Robust Control Toolbox, ``msfsyn`` (multi-model / multi-objective state-feedback synthesis).
"""

from __future__ import annotations

import dataclasses
import math
import time
import warnings
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._deadline import Deadline, as_time_limit, memory_budget
from .._validate import as_gain_mask, as_int, as_positive_float
from ..backends.cvxpy_backend import solve_cvxpy
from ..backends.report import one_warning_per_call
from ..errors import ValidationError
from ..formulate.robust_lmi import build_robust_lmi, default_margin
from ..model.model_set import ModelSet, as_model_set
from ..model.regions import Region
from ..results import Certificate, Check, SolverStats, Status, Verification
from .robust_result import (
    RobustObserverDesign,
    as_regions,
    check_choice,
    failed_design,
    fixed_mode_certificate,
    optional_bound,
    robust_route,
)
from .robust_verify import (
    LMICertificate,
    certificate_checks,
    certify,
    dense_check,
    evaluate_models,
    farkas_check,
    gain_checks,
)

__all__ = ["robust_lmi_observer", "lmi_design", "certify_gain"]


@one_warning_per_call
def robust_lmi_observer(
    models: ModelSet | list,
    *,
    region: Region | list | None = None,
    objective: Literal["cond", "gain", "h2", "hinf"] = "cond",
    h2_max: float | None = None,
    hinf_max: float | None = None,
    gain_mask: ArrayLike | None = None,
    max_gain: float | None = None,
    weights: ArrayLike | None = None,
    sdp_solver: str | None = None,
    margin: float | None = None,
    dense_points: int = 200,
    seed: int = 0,
    time_limit: float | None = None,
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
        H-infinity bounds, recomputed in numpy); ``certified``; ``certificate.kind == "lmi"`` (data: P).
        Infeasible LMIs: status ``infeasible`` with ``certificate.kind == "lmi_farkas"`` (verified
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

    Examples
    --------
    >>> from optdesign import ModelSet, Plant, robust_lmi_observer
    >>> from optdesign.regions import HalfPlane
    >>> models = ModelSet.vary(Plant([[0., 1.], [-2., -1.]], [[1., 0.]]), [(1, 0)], 0.2)
    >>> d = robust_lmi_observer(models, region=HalfPlane(1.0), max_gain=10.0, dense_points=0)
    >>> d.success, d.certified           # one common Lyapunov matrix: every plant of the polytope
    (True, True)
    """
    ms = as_model_set(models, weights)
    regions = as_regions(region, ms, "region", default=True)
    check_choice("objective", objective, ("cond", "gain", "h2", "hinf"))
    mask = as_gain_mask("gain_mask", gain_mask, ms.n, ms.p, label=" (free entries of L)")
    h2_max, hinf_max, max_gain = (
        optional_bound("h2_max", h2_max),
        optional_bound("hinf_max", hinf_max),
        optional_bound("max_gain", max_gain),
    )
    dense_points, seed = as_int("dense_points", dense_points, 0), as_int("seed", seed, 0)
    margin = None if margin is None else as_positive_float("margin", margin)
    if (objective in ("h2", "hinf") or h2_max or hinf_max) and not ms.has_noise_model:
        raise ValidationError(
            "the H2 / H-infinity objectives and bounds need a noise model (Q and R) in every model"
        )
    deadline = Deadline(as_time_limit(time_limit))
    res = lmi_design(
        ms,
        regions,
        objective,
        h2_max=h2_max,
        hinf_max=hinf_max,
        mask=mask,
        max_gain=max_gain,
        sdp_solver=sdp_solver,
        margin=margin,
        dense_points=dense_points,
        seed=seed,
        deadline=deadline,
        options=options,
    )
    return dataclasses.replace(res, route=robust_route(res))


def lmi_memory_estimate(n: int, models: int) -> int:
    """A lower bound of the bytes of the robust LMI's solve: each model's region LMI is a PSD cone
    of dimension at least n, whose block of the interior-point KKT system is dense, ``t (t + 1)``
    doubles with ``t = n(n+1)/2`` (measured: n = 300, two models asked for 32,617,082,400 bytes =
    2 * 8 * 45150 * 45151 in one allocation, and the interpreter aborted)."""
    t = n * (n + 1) // 2
    return 8 * t * (t + 1) * max(1, models)


def check_lmi_size(ms: ModelSet) -> None:
    """Refuse up front a robust LMI that cannot fit in memory (issue 26).

    Raises
    ------
    ValidationError
        The estimate of :func:`lmi_memory_estimate` exceeds :func:`memory_budget` (the message gives both).
    """
    need, budget = lmi_memory_estimate(ms.n, len(ms)), memory_budget()
    if need > budget:
        raise ValidationError(
            f"the robust LMI for {len(ms)} models of order n = {ms.n} needs at least {need / 2**30:.1f} GiB "
            f"(a dense block of (n(n+1)/2)^2 doubles per model in the interior-point solve), more than the "
            f"{budget / 2**30:.1f} GiB available to it: reduce the order (a balanced truncation) or the "
            f"number "
            f"of models")


def lmi_design(
    ms: ModelSet,
    regions: tuple[Region | None, ...],
    objective: str,
    *,
    h2_max: float | None,
    hinf_max: float | None,
    mask: NDArray[np.bool_] | None,
    max_gain: float | None,
    sdp_solver: str | None,
    margin: float | None,
    dense_points: int,
    seed: int,
    deadline: Deadline,
    options: dict[str, Any] | None,
) -> RobustObserverDesign:
    """The LMI design for validated arguments (the body of :func:`robust_lmi_observer`; also the
    start of :func:`~optdesign.design.robust.robust_observer`)."""
    check_lmi_size(ms)
    fixed = fixed_mode_certificate(ms, regions)
    if fixed is not None:
        return failed_design(ms, regions, "lmi", objective, "max", Status.INFEASIBLE, fixed.reason, fixed)
    t0 = time.process_time()
    lmi = build_robust_lmi(
        ms,
        regions,
        objective=objective,
        h2_max=h2_max,
        hinf_max=hinf_max,
        max_gain=max_gain,
        gain_mask=mask,
        margin=margin,
    )
    opts = {**(options or {}), **deadline.sdp_options(sdp_solver or "CLARABEL")}
    with warnings.catch_warnings():  # "solution may be inaccurate": the status says so, and we verify
        warnings.simplefilter("ignore", UserWarning)
        rep = solve_cvxpy(lmi.problem, sdp_solver, opts)
    stats = SolverStats(
        backend=rep.stats.backend,
        native_status=rep.stats.native_status,
        time=time.process_time() - t0,
        iterations=rep.stats.iterations,
        extra=dict(rep.stats.extra),
    )
    L = lmi.gain() if rep.status.is_solved else None
    if L is None:
        return _lmi_failure(ms, regions, objective, lmi, rep, stats, deadline)
    return _lmi_success(
        ms,
        regions,
        objective,
        lmi,
        rep,
        stats,
        L,
        h2_max=h2_max,
        hinf_max=hinf_max,
        mask=mask,
        max_gain=max_gain,
        dense_points=dense_points,
        seed=seed,
    )


def _lmi_failure(ms, regions, objective, lmi, rep, stats, deadline) -> RobustObserverDesign:
    """No gain: infeasible with a verified Farkas certificate, not found, or out of time."""
    if rep.status.is_infeasible:
        fk = farkas_check(lmi, ms)
        what = (
            "no common Lyapunov matrix P satisfies the LMIs at every model (a sufficient condition only: a "
            "robust gain may still exist -- try robust_observer)"
        )
        cert = Certificate("lmi_farkas", what, fk)
        if fk.get("verified"):
            msg = (
                f"LMIs infeasible: {what}; Farkas certificate verified in numpy: no solution within radius "
                f"{fk['radius']:.3g}"
            )
            check = Check.at_least(
                "farkas_radius",
                fk["radius"],
                1e8 * fk["scale"],
                "no LMI solution within this radius (dual certificate, numpy)",
            )
            return failed_design(
                ms, regions, "lmi", objective, "max", Status.INFEASIBLE, msg, cert, stats, [check]
            )
        msg = f"{rep.message}; the dual certificate did not verify ({fk}): feasibility unknown"
        return failed_design(ms, regions, "lmi", objective, "max", Status.NOT_FOUND, msg, cert, stats)
    if deadline.expired:
        status = Status.TIME_LIMIT
    else:
        status = rep.status if not rep.status.is_solved else Status.NUMERICAL_ERROR
    return failed_design(ms, regions, "lmi", objective, "max", status, f"no gain: {rep.message}", None, stats)


def _lmi_success(
    ms, regions, objective, lmi, rep, stats, L, *, h2_max, hinf_max, mask, max_gain, dense_points, seed
) -> RobustObserverDesign:
    """A gain: its certificate (numpy), its per-model checks and the dense check."""
    vals = lmi.values()
    want_h2 = objective == "h2" or h2_max is not None
    want_hinf = objective == "hinf" or hinf_max is not None
    cert = certify(ms, L, vals["P"], regions, h2=want_h2, hinf=want_hinf)
    mm = evaluate_models(ms, L, regions)
    checks = gain_checks(ms, L, mm, regions, mask=mask, max_gain=max_gain, h2_max=h2_max, hinf_max=hinf_max)
    nu = vals.get("nu")
    claim_h2 = math.sqrt(float(nu)) if (objective == "h2" and nu is not None) else h2_max
    claim_hinf = math.sqrt(float(nu)) if (objective == "hinf" and nu is not None) else hinf_max
    checks = checks + certificate_checks(cert, h2_claim=claim_h2, hinf_claim=claim_hinf)
    dense = dense_check(ms, L, regions[ms.nominal if ms.nominal is not None else 0], dense_points, seed)
    if ms.covers_convex_hull and dense.count and cert.holds:
        checks = checks + Verification.of(
            [
                Check.at_least(
                    "dense_region",
                    dense.in_region,
                    dense.count,
                    f"random convex combinations in the region ({dense.in_region}/{dense.count}): "
                    "the certificate's claim",
                )
            ]
        )
    value = {
        "cond": math.sqrt(cert.P_cond),
        "gain": float(np.linalg.norm(L, 2)),
        "h2": math.nan if claim_h2 is None else claim_h2,
        "hinf": math.nan if claim_hinf is None else claim_hinf,
    }[objective]
    covers = (
        "every convex combination of the models" if ms.covers_convex_hull else "the models (not between them)"
    )
    msg = (
        f"LMI {objective}: {rep.message}; common Lyapunov certificate {'holds' if cert.holds else 'FAILS'} "
        f"for {covers}"
        + (f"; certified H2 <= {cert.h2_bound:.6g}" if want_h2 else "")
        + (f"; certified H-infinity <= {cert.hinf_bound:.6g}" if want_hinf else "")
    )
    return RobustObserverDesign(
        L=L,
        method="lmi",
        objective=objective,
        aggregate="max",
        value=value,
        models=ms,
        regions=regions,
        status=rep.status,
        message=msg,
        solver_stats=stats,
        verification=checks,
        metrics=mm,
        lmi_certificate=cert,
        certified=cert.holds,
        dense=dense,
        certificate=Certificate("lmi", f"common Lyapunov matrix P, valid for {covers}", cert.as_dict()),
        extra={"margin": lmi.spec.margin, "diagonal_P": lmi.spec.diagonal_P},
    )


def certify_gain(
    ms: ModelSet,
    regions: tuple[Region | None, ...],
    L: NDArray,
    lmi_res: RobustObserverDesign | None,
    sdp_solver: str | None,
    deadline: Deadline,
    want_h2: bool,
    want_hinf: bool,
) -> tuple[LMICertificate | None, str]:
    """Does a common Lyapunov certificate hold for the gain ``L``?  The LMI design's P first, then an
    analysis SDP (``L`` fixed, ``P`` free) whose P is checked in numpy.

    Returns
    -------
    (LMICertificate or None, str)
        The certificate that was checked (None if none exists) and how it was obtained.
    """
    if lmi_res is not None and lmi_res.lmi_certificate is not None:
        c = certify(ms, L, lmi_res.lmi_certificate.P, regions, h2=want_h2, hinf=want_hinf)
        if c.holds:
            return c, "the LMI's P still certifies the refined gain"
    if deadline.expired:
        return None, "not checked (time limit)"
    # the NLP keeps the poles default_margin inside; certify with a tenth of it
    lmi = build_robust_lmi(ms, regions, objective="cond", fixed_gain=L, margin=0.1 * default_margin(ms))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        rep = solve_cvxpy(lmi.problem, sdp_solver, deadline.sdp_options(sdp_solver or "CLARABEL"))
    P = lmi.values()["P"]
    if rep.status.is_solved and P is not None:
        c = certify(ms, L, P, regions, h2=want_h2, hinf=want_hinf)
        how = (
            "a new common P (analysis SDP for the refined gain) certifies it"
            if c.holds
            else "the analysis SDP's P does not verify"
        )
        return c, how
    return None, f"no common Lyapunov matrix for the refined gain (analysis SDP: {rep.stats.native_status})"
