"""What every route of :func:`kalman_for_poles` shares: the placed gain, the noise of a decision
covariance, the verification of a design, result helpers."""


from __future__ import annotations

import dataclasses
import warnings
from contextlib import contextmanager

import numpy as np
from numpy.typing import NDArray

from ..._validate import as_square, check_symmetric
from ...analysis.metrics import eigenvalue_rounding_floor
from ...classical.placement import place_observer, pole_error
from ...classical.riccati import filter_are
from ...engines.polish import refine_gain, sym
from ...errors import ValidationError
from ...formulate.inverse_kalman import (
    noise_input,
    psd_part,
)
from ...model.plant import Plant
from ...results import Check, SolverStats, Status, Verification
from ..verification import (
    check_violation,
    newton_kalman_checks,
    pole_check,
    pole_tolerance,
    psd_check,
    relative_difference,
    resolve_poles_check,
    riccati_checks,
)
from .results import InverseKalmanResult

METHODS = ("auto", "sdp", "nlp", "sequential")


EPS = float(np.finfo(float).eps)


def stable_poles(z: NDArray, discrete: bool) -> NDArray[np.bool_]:
    z = np.asarray(z, dtype=complex)
    return np.abs(z) < 1.0 if discrete else z.real < 0.0




rel = relative_difference




def noise_of(structure: str, G: NDArray | None, Wdec: NDArray) -> tuple[NDArray, NDArray | None]:
    """(Q, Qw) from the decision covariance."""
    if structure == "full":
        return sym(Wdec), None
    Qw = np.diag(np.asarray(Wdec).ravel()) if structure == "diagonal" else sym(Wdec)
    Gm = noise_input(structure, G)
    return sym(Gm @ Qw @ Gm.T), Qw


def project_psd(X: NDArray) -> NDArray:
    return sym(psd_part(X))


def placed_gain(plant: Plant, target: NDArray) -> NDArray:
    """Robust pole placement (scipy, refined by Newton); for one output and repeated targets,
    where scipy refuses, Ackermann's formula ``L = phi(A) O^-1 e_n`` (the gain is unique)."""
    try:
        L0 = place_observer(plant, target)
    except ValidationError:
        if plant.p != 1:
            raise
        n = plant.n
        coeffs = np.real(np.poly(target))
        phi = np.zeros((n, n))
        for c in coeffs:
            phi = phi @ plant.A + c * np.eye(n)
        e = np.zeros((n, 1))
        e[-1, 0] = 1.0
        return phi @ np.linalg.solve(plant.observability_matrix(), e)
    return refine_gain(plant.A, plant.C, L0, target)


def verify_design(plant: Plant, target: NDArray, L: NDArray, P: NDArray, Q: NDArray, Qw: NDArray | None,
                  structure: str, tol: float, *, avoid: str = "scipy") -> tuple[Verification, NDArray]:
    """Independent checks of a design (:mod:`optdesign.design.verification`: numpy eigenvalues,
    residual and forward error, re-solved ARE, PSD).  ``avoid``: the Riccati solver that produced L
    and P (:func:`~optdesign.design.verification.independent_are` re-solves with the other one);
    ``"hamiltonian"`` for designs from no Riccati solver (SDP points, Lyapunov solves): the re-solve
    is then scipy's, the cheaper one; ``"none"`` for those too, with the lean re-solve in continuous
    time (:func:`~optdesign.design.verification.lean_riccati_checks`; the full one decides whatever
    it does not pass); with one output and a full Q, first the checks of
    :func:`~optdesign.design.verification.newton_kalman_checks` (one Schur form, the re-solve a
    Newton step from P; the full checks decide whatever they do not pass)."""
    A, C = plant.A, plant.C
    if avoid == "none" and structure == "full" and plant.p == 1:
        lean = newton_kalman_checks(plant, L, P, Q, target, tol)
        if lean is not None:
            return Verification.of(lean[0]), lean[1]
    pcheck, poles = pole_check(A - L @ C, target, tol)
    kalman, are, _ = riccati_checks(plant, L, P, Q, what="the returned Q", avoid=avoid)
    checks = [pcheck, *kalman]
    if are is not None:
        gain = next(c for c in kalman if c.name == "are_resolve_gain")
        # the re-solved gain agrees with L (to its error estimates, at most 1e-6): A - L_are C is
        # A - L C to that level, and its poles miss the targets by at most L's pole error plus what
        # that gain difference moves them (resolve_pole_tolerance); otherwise its own rounding floor
        checks.append(resolve_poles_check(A, C, L, are.L, are.poles, target, pcheck, gain.passed, tol,
                                          "poles of the independent filter_are solve vs the targets"))
    if structure != "full" and Qw is not None:
        G = plant.G
        mis = rel(G @ Qw @ G.T, Q)
        off = float(np.max(np.abs(Qw - np.diag(np.diag(Qw))))) if structure == "diagonal" else 0.0
        stol = 10.0 * (plant.n + plant.m) * EPS * max(1.0, float(np.linalg.norm(G, 2)) ** 2)
        checks.append(Check.at_most("structure", max(mis, off), stol,
                                    "||G Qw G' - Q|| / max(1, ||Q||) (and off-diagonal of Qw for "
                                    "'diagonal'); rounding level of the product"))
        checks.append(psd_check("Qw_min_eig", Qw, what="Qw"))
    return Verification.of(checks), poles


def objective_of(objective: str, Q: NDArray, Wdec: NDArray, Qn: NDArray | None) -> float:
    if objective == "min_trace":
        return float(np.trace(Q))
    if objective == "nearest":
        return float(np.linalg.norm(Wdec - Qn)) if Qn is not None else float("nan")
    W = np.diag(Wdec) if np.ndim(Wdec) == 1 else Wdec
    return float(np.linalg.eigvalsh(sym(np.asarray(W)))[0])


def make_stats(backend: str, native: str = "", t: float = 0.0, iterations=None, **extra) -> SolverStats:
    return SolverStats(backend=backend, native_status=native, time=t, iterations=iterations, extra=extra)


def nominal_noise(plant: Plant, structure: str, objective: str, Q_nominal) -> NDArray | None:
    if Q_nominal is None:
        if objective != "nearest":
            return None
        if plant.Q is None:
            raise ValidationError("objective='nearest' needs Q_nominal (or a plant with Q to use as "
                                  "the nominal)")
        return plant.process_noise() if structure == "full" else np.asarray(plant.Q, dtype=float)
    k = plant.n if structure == "full" else plant.m
    what = "n x n (state-space Q)" if structure == "full" else "m x m (noise-input Qw)"
    Qn = as_square("Q_nominal", Q_nominal)
    if Qn.shape[0] != k:
        raise ValidationError(f"Q_nominal for structure={structure!r} must be {what}, i.e. ({k}, {k}); "
                              f"found {Qn.shape}")
    return check_symmetric("Q_nominal", Qn)


def empty_result(common, status, message, certificate, stats, verification=None, details=None):
    return InverseKalmanResult(
        L=None, Q=None, Qw=None, P=None, poles=None, status=status, message=message,
        solver_stats=stats, verification=verification or Verification.of([]), certificate=certificate,
        objective_value=float("nan"), extra=details or {}, **common)


@contextmanager
def quiet():
    """Silence the backends' advisory warnings (the statuses are reported in the result)."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=".*may be inaccurate.*")
        warnings.filterwarnings("ignore", message=".*Convergence was not reached.*")
        yield


def design_from_Q(plant, target, structure, Q, Qw, tol):
    """L and P by a Riccati solve with the optimizer's Q, then verified."""
    Q = project_psd(Q)
    if Qw is not None:
        Qw = np.diag(np.maximum(np.diag(Qw), 0.0)) if structure == "diagonal" else project_psd(Qw)
        Q = sym(plant.G @ Qw @ plant.G.T)
    are = filter_are(plant.replace(G=None, Q=Q), residual_tol=np.inf)
    ver, poles = verify_design(plant, target, are.L, are.P, Q, Qw, structure, tol)
    return are.L, are.P, Q, Qw, ver, poles


def decision_size(plant: Plant, structure: str) -> int:
    m = plant.m
    return {"full": plant.n * (plant.n + 1) // 2, "input": m * (m + 1) // 2, "diagonal": m}[structure]


#: the checks of a design's poles (:func:`verify_design`)
POLE_CHECKS = ("pole_error", "are_resolve_poles")


def design_violation(plant: Plant, res: InverseKalmanResult) -> float:
    """How far a design is from verifying: the largest
    :func:`~optdesign.design.verification.check_violation` of its checks (inf without a design).

    A failed pole check is measured against the rounding floor of the poles of ``A - L C``
    (:func:`~optdesign.analysis.metrics.eigenvalue_rounding_floor`) without the cap
    (:data:`~optdesign.design.verification.POLE_FLOOR_CAP`) of its tolerance: a pole error within
    that floor is as close as double precision places those poles, so it counts as no violation.
    """
    if res.L is None or not res.verification.checks:
        return float("inf")
    floor: float | None = None
    worst = 0.0
    for c in res.verification.checks:
        tol = None
        if c.name in POLE_CHECKS and not c.passed:
            if floor is None:
                floor = eigenvalue_rounding_floor(plant.A - res.L @ plant.C)
            tol = max(c.tolerance, floor) if np.isfinite(floor) else None
        worst = max(worst, check_violation(c, tol))
    return worst


def best_unverified(plant: Plant, candidates: list[InverseKalmanResult]) -> InverseKalmanResult | None:
    """The answer when no route verified a design: among the candidates with a design, the one with
    the smallest :func:`design_violation`, then the better objective (a larger margin for
    ``"feasibility"``, else the smaller value); None when no candidate has a design."""
    have = [r for r in candidates if r.L is not None and r.verification.checks]
    if not have:
        return None

    def key(r: InverseKalmanResult) -> tuple[float, float]:
        sign = -1.0 if r.objective == "feasibility" else 1.0
        obj = sign * r.objective_value
        return design_violation(plant, r), obj if np.isfinite(obj) else float("inf")

    return min(have, key=key)


def uncomputable_poles(plant: Plant, res: InverseKalmanResult, target: NDArray, tol: float) -> float | None:
    """One output, ``res`` fails its ``pole_error`` check: the pole error of :func:`placed_gain` (the
    gain the other routes start from, refined by Newton steps on its poles) when that fails the
    pole tolerance too -- the poles fix the gain and no computation of it places them (measured:
    those routes then give no verified design either, only worse unverified ones); else None."""
    if plant.p != 1 or res.L is None or "pole_error" not in res.verification or \
            res.verification["pole_error"].passed:
        return None
    try:
        L = placed_gain(plant, target)
    except (ValidationError, np.linalg.LinAlgError):
        return None
    F = plant.A - L @ plant.C
    err = pole_error(np.linalg.eigvals(F), target)
    return err if not err <= pole_tolerance(F, tol) else None


def with_status(res: InverseKalmanResult, status: Status, message: str) -> InverseKalmanResult:
    """``res`` with another status and message (the design and its checks kept)."""
    return dataclasses.replace(res, status=status, message=message)
