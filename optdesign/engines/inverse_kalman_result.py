"""The result of the inverse Kalman engine (:mod:`optdesign.engines.inverse_kalman_engine`) and the
independent checks of a returned design: :class:`EngineResult`, :func:`verify_engine_design` (numpy poles,
the Riccati residual and forward error, PSD eigenvalues, a scipy Riccati re-solve with the returned Q)
and :func:`engine_result`, which assembles a result, verified, from a design.

Split from the engine module (issue 29: modules under 800 lines, by responsibility): the search and
the one-output route propose designs, this module states and checks them.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..backends.clarabel_fixed_gain import FixedGainSolution
from ..classical.placement import pole_error
from ..classical.riccati import filter_are_error, filter_are_residual
from ..results import Check, DesignResult, SolverStats, Verification
from .inverse_kalman_setup import EngineSetup
from .inverse_kalman_starts import scipy_kalman
from .tolerances import (
    FORWARD_ERROR_TOL,
    POLE_FLOOR_CAP,
    RICCATI_RESIDUAL_TOL,
    pole_tolerance,
    rounding_level,
)

__all__ = ["EngineResult", "verify_engine_design", "engine_result", "sdp_record", "POLE_FLOOR_CAP",
           "RICCATI_RESIDUAL_TOL", "FORWARD_ERROR_TOL", "ROUNDING_FACTOR"]

#: the rounding allowance of a computed matrix of order n: ``ROUNDING_FACTOR n eps`` (a few roundings
#: per entry of an O(n)-term inner product, with a margin of 10)
ROUNDING_FACTOR = 10.0


@dataclass(frozen=True, kw_only=True, eq=False)
class EngineResult(DesignResult):
    """Outcome of :func:`solve_inverse_kalman` (physical units).

    Attributes
    ----------
    L : (n, p) ndarray or None
    P, Q : (n, n) ndarray or None
    Qw : ndarray or None
        ``"input"``: (m, m); ``"diagonal"``: (m, m) diagonal.
    status : Status
    message : str
    objective_value : float
        ``trace(Q)`` (min_trace), ``||Qdec - Q_nominal||_F`` (nearest) or ``lambda_min(Qdec)``
        (feasibility), with ``Qdec`` = Q (full) or Qw.
    iterations : int
        SQP, Gauss-Newton and Newton iterations over all starts.
    rank : int or None
        Rank of the decision covariance.
    verification : Verification
        Independent checks (numpy poles, the Riccati residual, PSD, a scipy Riccati re-solve
        with the returned Q reproducing L and the poles).
    solver_stats : SolverStats
    target_poles : (n,) complex ndarray
    details : dict
        Several outputs: per-start records (``"starts"``: kind, iterations of each stage, value,
        rank, CPU time), the certificate SDP (``"sdp"``), the KKT test of the returned point
        (``"kkt"``: smallest eigenvalue of the dual slack relative to its norm, complementarity,
        passed) and ``"best_start"``.  One output: the SDP (``"sdp"``), the gain the poles fix
        (``"L_unique"``).  An infeasible target: ``"certificate"`` (``kind`` ``"unstable_target"``,
        ``"sdp_infeasible"`` or ``"sdp_margin"``, with the unique gain ``L`` and the ``margin``).
        A target where the spectral form is singular: ``"applicable": False``.
    """

    L: NDArray[np.float64] | None
    P: NDArray[np.float64] | None
    Q: NDArray[np.float64] | None
    Qw: NDArray[np.float64] | None
    objective_value: float
    iterations: int
    rank: int | None
    details: dict = field(default_factory=dict)


def verify_engine_design(setup: EngineSetup, target: NDArray, L: NDArray, P: NDArray, Q: NDArray,
                         Qw: NDArray | None, tol: float) -> Verification:
    """Independent checks: numpy poles of ``A - L C``, the Riccati residual and forward error of P
    with Q, PSD eigenvalues, and a scipy Riccati re-solve with Q that must give L and the poles.

    Tolerances come from the data: the pole tolerance is ``max(tol, min(floor, 1e-6))`` with the
    rounding floor of the eigenvalues of ``A - L C``; the gains may differ by what the forward
    errors of the two Riccati solutions explain, plus the rounding of L itself (``4 (e1 + e2) ||P||
    ||C' S^-1|| / max(1, ||L||) + 10 n eps (1 + kappa)``, kappa the condition number of the unit
    eigenvectors of ``A - L C``, at most 1e-6); PSD eigenvalues down to ``-10 n eps`` (P: minus its
    forward error).
    """
    plant = setup.plant
    A, C, R = plant.A, plant.C, np.asarray(plant.R, dtype=float)
    n = plant.n
    F = A - L @ C
    ptol = pole_tolerance(F, tol)
    poles = np.linalg.eigvals(F)
    rnd = rounding_level(n, 1.0, ROUNDING_FACTOR)
    err = filter_are_error(plant.replace(G=None, Q=None), P, Qs=Q)
    checks = [
        Check.at_most("pole_error", pole_error(poles, target), ptol,
                      "max relative distance of eig(A - L C) to the targets (tolerance: tol or the rounding "
                      "floor of those poles)"),
        Check.at_most("riccati_residual", filter_are_residual(plant.replace(G=None, Q=None), P, Qs=Q),
                      RICCATI_RESIDUAL_TOL,
                      "relative residual of the filter ARE for the returned P with the returned Q"),
        Check.at_most("forward_error", err.relative, FORWARD_ERROR_TOL, "a posteriori relative error of P"),
        Check.at_least("Q_min_eig", float(np.linalg.eigvalsh(Q)[0]) / max(1.0, float(np.linalg.norm(Q, 2))),
                       -rnd, "smallest eigenvalue of Q / max(1, ||Q||)"),
        Check.at_least("P_min_eig", float(np.linalg.eigvalsh(P)[0]) / max(1.0, float(np.linalg.norm(P, 2))),
                       -(err.relative + rnd), "smallest eigenvalue of P / max(1, ||P||)"),
    ]
    if Qw is not None:
        G = setup.Gd
        checks.append(Check.at_least("Qw_min_eig", float(np.linalg.eigvalsh(Qw)[0]) / max(
            1.0, float(np.linalg.norm(Qw, 2))), -rnd, "smallest eigenvalue of Qw / max(1, ||Qw||)"))
        mis = float(np.linalg.norm(G @ Qw @ G.T - Q)) / max(1.0, float(np.linalg.norm(Q)))
        checks.append(Check.at_most("structure", mis, rnd, "||G Qw G' - Q|| / max(1, ||Q||)"))
    kal = scipy_kalman(plant, Q)
    if kal is None:
        checks.append(Check.at_most("are_resolve_gain", float("inf"), 0.0,
                                    "scipy's Riccati solver gave no stabilizing solution with the "
                                    "returned Q"))
        return Verification.of(checks)
    La, Pa, pa = kal
    err_a = filter_are_error(plant.replace(G=None, Q=None), Pa, Qs=Q)
    S = C @ P @ C.T + R if plant.is_discrete else R
    sens = float(np.linalg.norm(P)) * float(np.linalg.norm(np.linalg.solve(S, C).T, 2))
    nl = max(1.0, float(np.linalg.norm(L)))
    X = np.linalg.eig(F)[1]
    kappa = float(np.linalg.cond(X / np.linalg.norm(X, axis=0)))
    gtol = min(POLE_FLOOR_CAP, 4.0 * (err.relative + err_a.relative) * sens / nl + rnd * (1.0 + kappa))
    checks.append(Check.at_most("are_resolve_gain", float(np.linalg.norm(La - L)) / nl, gtol,
                                "||L_scipy - L|| / max(1, ||L||), L_scipy from scipy's Riccati solver "
                                "with the returned Q (tolerance: what the forward errors of the two P "
                                "explain, plus the rounding of L itself, 10 n eps kappa(eigenvectors of "
                                "A - L C))"))
    checks.append(Check.at_most("are_resolve_poles", pole_error(pa, target),
                                pole_tolerance(A - La @ C, tol),
                                "poles of that re-solve vs the targets"))
    return Verification.of(checks)


def engine_result(setup, target, status, message, t0, cpu0, *, tol: float, design=None,
                  objective=float("nan"), iterations=0, rank=None, details=None, native="") -> EngineResult:
    """The :class:`EngineResult` of a design ``(L, P, Q, Qw)`` (or of none), verified when the setup asks
    (:func:`verify_engine_design`; the failed checks named in the message)."""
    L = P = Q = Qw = None
    ver = Verification.of([])
    if design is not None:
        L, P, Q, Qw = design
        ver = verify_engine_design(setup, target, L, P, Q, Qw, tol) if setup.verify else Verification.of([])
        if setup.verify and not ver.passed:
            message += "; failed checks: " + ", ".join(c.name for c in ver.failed)
    stats = SolverStats(backend="spectral-newton+clarabel", native_status=native,
                        time=time.perf_counter() - t0, iterations=iterations,
                        extra={"cpu_time": time.process_time() - cpu0})
    return EngineResult(L=L, P=P, Q=Q, Qw=Qw, status=status, message=message, objective_value=objective,
                        iterations=iterations, rank=rank, verification=ver, solver_stats=stats,
                        target_poles=target, details=details or {})


def sdp_record(sol: FixedGainSolution | None) -> dict[str, Any]:
    """The record of a fixed-gain SDP solve kept in a result's details (empty for none)."""
    if sol is None:
        return {}
    return {"status": sol.status.value, "native": sol.native_status, "iterations": sol.iterations,
            "solve_time": sol.solve_time}
