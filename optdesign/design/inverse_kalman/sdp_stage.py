"""The fixed-gain SDP as a stage: solver attempts and retries, the whitening preconditioner, the
feasibility margin, the polish of an SDP point onto its face of the PSD cone."""


from __future__ import annotations

import warnings
from contextlib import contextmanager

import numpy as np
from numpy.typing import NDArray

from ..._deadline import Deadline
from ...backends import cvxpy_backend
from ...backends.clarabel_fixed_gain import riccati_of_gain
from ...backends.cvxpy_backend import default_sdp_solver, solve_cvxpy
from ...engines.polish import face_polish
from ...errors import OptDesignDeprecationWarning, SolverError
from ...formulate.inverse_kalman import (
    build_fixed_gain_sdp,
)
from ...model.plant import Plant
from ...results import Status
from .common import sym


def sdp_solvers() -> tuple[str, ...]:
    """Installed SDP solvers (discovered once per process by the backend)."""
    return cvxpy_backend.available_sdp_solvers()


@contextmanager
def sdp_reuse(enabled: bool):
    """Deprecated no-op context manager (kept for one release).

    :func:`kalman_for_poles` used to keep a hidden per-thread cache of parametric fixed-gain SDPs,
    so that the same call could give a (slightly) different answer depending on what ran before
    in the process.  Every call now builds its own problem; re-use is explicit through the
    caller-held problem objects.
    """
    warnings.warn("sdp_reuse() has no effect: kalman_for_poles no longer caches SDPs between calls",
                  OptDesignDeprecationWarning, stacklevel=3)
    yield


def whitening(plant: Plant, L: NDArray, R: NDArray) -> NDArray | None:
    """A state transformation ``T`` (``x = T x~``) that whitens the error covariance of the
    observer driven by its measurement noise alone, ``P_v`` (``F P_v + P_v F' + L R L' = 0``,
    discrete ``P_v = F P_v F' + L R L'``, ``F = A - L C``): ``T = U diag(sqrt(lambda))`` from
    ``P_v = U diag(lambda) U'`` (eigenvalues floored at 1e-10 of the largest).  The Kalman P of
    any Q in the gain's family is ``P_v`` plus the process-noise part, so in these coordinates the
    fixed-gain SDP sees P of order one instead of spanning the decades the physical P may span
    (the regression case ``tests/data/is_kalman_optimal_false_no_discrete_n8_p2.npz``: P from 0.87
    to 1.1e7, the SDP inaccurate; whitened, it solves to optimal).  None (identity) when F is not
    stable, ``L R L' = 0`` or P_v is well scaled already."""
    F = plant.A - L @ plant.C
    lam_F = np.linalg.eigvals(F)
    if (np.max(np.abs(lam_F)) >= 1.0) if plant.is_discrete else (np.max(lam_F.real) >= 0.0):
        return None
    LRL = L @ R @ L.T
    LRL = 0.5 * (LRL + LRL.T)
    if not np.any(LRL):
        return None
    with np.errstate(all="ignore"):
        try:
            Pv = riccati_of_gain(plant.A, plant.C, L, R, np.zeros_like(LRL), plant.dt)
        except (np.linalg.LinAlgError, ValueError):
            return None
    lam, U = np.linalg.eigh(0.5 * (Pv + Pv.T))
    if not (np.all(np.isfinite(lam)) and lam[-1] > 0):
        return None
    d = np.sqrt(np.maximum(lam, 1e-10 * lam[-1]))
    if d[-1] / d[0] < 10.0:  # well scaled already: the physical coordinates are fine
        return None
    return U * d


def transformed(plant: Plant, T: NDArray) -> Plant:
    """The plant in the coordinates ``x = T x~`` (A~ = T^-1 A T, C~ = C T, G~ = T^-1 G)."""
    Ti = np.linalg.inv(T)
    return plant.replace(A=Ti @ plant.A @ T, C=plant.C @ T, G=Ti @ plant.G)


def fixed_gain_sdp(plant: Plant, L: NDArray, R: NDArray, structure: str, objective: str,
                    Qn: NDArray | None, T: NDArray | None = None, physical: bool = True):
    """The fixed-gain SDP of ``plant`` bound to ``L`` (built for this call: no hidden re-use),
    in the coordinates ``x = T x~`` when T is given; the objective is the physical noise's
    (``physical``) or the whitened one's."""
    if T is None:
        return build_fixed_gain_sdp(plant.A, plant.C, L, R, dt=plant.dt, structure=structure,
                                    G=plant.G, objective=objective, Q_nominal=Qn)
    pt = transformed(plant, T)
    return build_fixed_gain_sdp(pt.A, pt.C, np.linalg.solve(T, L), R, dt=plant.dt, structure=structure,
                                G=pt.G, objective=objective, Q_nominal=Qn, T=T if physical else None)


#: retries after a numerical failure of the SDP solver: (solver, extra options)
SDP_RETRIES = ((None, None), ("CLARABEL", {"static_regularization_constant": 1e-7}), ("SCS", None))


def sdp_attempts(solver: str | None):
    """``(solver name, options)`` to try in turn: the requested (or default) solver, then the
    installed alternatives of :data:`SDP_RETRIES` -- Clarabel with stronger regularization
    always, SCS only when no solver was requested.  Raises BackendUnavailableError (naming the
    package) when no SDP solver is installed."""
    avail = sdp_solvers()
    if not avail:
        default_sdp_solver()  # raises BackendUnavailableError naming the package
    first = (solver or avail[0]).upper()
    for alt, opts in SDP_RETRIES:
        name = first if alt is None else alt
        if alt is not None and (name not in avail or (solver is not None and name != first)
                                or (name == first and opts is None)):
            continue
        yield name, opts


def sdp_fixed_gain(plant: Plant, L: NDArray, R: NDArray, structure: str, objective: str,
                    Qn: NDArray | None, solver: str | None, deadline: Deadline | None = None, *,
                    whiten: bool = False, physical: bool = True):
    """Solve the fixed-gain SDP.  Returns ``(P, Wdec, report, sdp)`` in physical units, or
    ``(None, None, report, sdp)`` on failure.

    ``whiten``: in the whitened coordinates of :func:`whitening` (a retry for badly scaled
    families: an inconclusive or unverified physical answer), with the physical objective
    (``physical``) or the whitened one (certificates, where any PSD member will do).  Whitening
    is a preconditioner, not a safe default: where the observer-noise covariance is itself nearly
    singular it makes the problem worse (measured: a rank-one-Q boundary gain whose whitened SDP
    reported "optimal" with a wrong margin), so a whitened answer is used only when it verifies.

    A numerical failure of the backend (not an infeasibility verdict) is retried: Clarabel
    with stronger static regularization, then SCS -- the latter only when no solver was
    requested.  ``report.stats.extra["attempts"]`` lists what was tried.
    """
    deadline = Deadline.of(deadline)
    T = whitening(plant, L, R) if whiten else None
    attempts = []
    rep = sdp = None
    for name, opts in sdp_attempts(solver):
        sdp = fixed_gain_sdp(plant, L, R, structure, objective, Qn, T, physical)
        rep = solve_cvxpy(sdp.problem, name, {**(opts or {}), **deadline.sdp_options(name)})
        attempts.append(f"{name.lower()}{'' if not opts else ' ' + str(opts)}: {rep.stats.native_status}")
        if rep.status.is_solved or rep.status.is_infeasible or rep.status == Status.UNBOUNDED \
                or deadline.expired:
            break
    if rep is None or sdp is None:  # pragma: no cover - sdp_attempts yields the first solver or raises
        raise SolverError("the fixed-gain SDP was not attempted: no SDP solver to try", backend="cvxpy")
    rep.stats.extra["attempts"] = attempts
    rep.stats.extra["whitened"] = T is not None
    if not rep.status.is_solved or sdp.P.value is None:
        return None, None, rep, sdp
    P = sdp.scale * np.asarray(sdp.P.value)
    W = sdp_decision(sdp, structure)
    if T is not None:
        P = sym(T @ P @ T.T)
        if structure == "full":
            W = sym(T @ W @ T.T)
    return P, W, rep, sdp


def sdp_decision(sdp, structure: str) -> NDArray:
    """The decision covariance of a solved SDP in the SDP's units times its scale: Q (``"full"``),
    Qw (``"input"``) or the vector qw (``"diagonal"``)."""
    W = sdp.scale * np.asarray((sdp.Q if structure == "full" else sdp.Qw).value)
    return W.ravel() if structure == "diagonal" else W


def feasibility_margin(plant: Plant, L: NDArray, R: NDArray, structure: str, solver: str | None,
            deadline: Deadline | None = None, *, whiten: bool = False):
    """Max over the Q family of the smallest eigenvalue of the decision covariance: the
    feasibility SDP.  Returns ``(t, P, Wdec, report)`` (P, Wdec physical).

    ``whiten``: solve in the whitened coordinates of :func:`whitening`, maximizing the smallest
    eigenvalue of the *whitened* covariance -- a search for a certificate (any PSD member will
    do), used only when the physical SDP is inconclusive; its ``t`` is then in whitened units and
    is never used for a verdict."""
    P0, W0, rep, sdp = sdp_fixed_gain(plant, L, R, structure, "feasibility", None, solver, deadline,
                                       whiten=whiten, physical=not whiten)
    if P0 is None:
        return float("nan"), None, None, rep
    return float(sdp.scale * sdp.t.value), P0, W0, rep


def polished_point(plant, L, R, structure, P0, W0, *, whiten: bool = False):
    """Face polish of an SDP point (:func:`face_polish`; in the whitened coordinates of
    :func:`whitening` with ``whiten``); ``(P, Wdec, residual)`` in physical units, or None when
    no face fits."""
    T = whitening(plant, L, R) if whiten else None
    if T is None:
        return face_polish(plant.A, plant.C, L, R, plant.dt, structure, plant.G, P0, W0, 1e-9)
    Ti = np.linalg.inv(T)
    pt = transformed(plant, T)
    W0t = sym(Ti @ W0 @ Ti.T) if structure == "full" else W0
    pol = face_polish(pt.A, pt.C, Ti @ L, R, plant.dt, structure, pt.G, sym(Ti @ P0 @ Ti.T), W0t, 1e-9)
    if pol is None:
        return None
    P, W, res = pol
    return sym(T @ P @ T.T), (sym(T @ W @ T.T) if structure == "full" else W), res

