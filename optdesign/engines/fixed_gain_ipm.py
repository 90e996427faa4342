r"""A dense primal-dual interior-point method for the one-output fixed-gain SDP (an accelerator).

The fixed-gain SDP of :mod:`optdesign.backends.clarabel_fixed_gain` for the structure ``"full"`` and
the objective ``"min_trace"`` is one LMI in the variables ``x`` (``m = d(d + 1)/2``, ``d = n - p``):

.. math::  \min_x\ c' x \quad \text{s.t.}\quad Z(x) = Q_0 + \sum_i x_i T_i \succeq 0,
           \qquad c_i = \operatorname{tr} T_i,

with ``T_i = smat(T[:, i])``.  In the standard pair (``y = -x``, ``A_i = T_i``, ``C = Q_0``,
``b = c``) its primal is ``min <C, X>`` s.t. ``<A_i, X> = b_i``, ``X >= 0`` and the dual
``max b' y`` s.t. ``sum_i y_i A_i + Z = C``, ``Z >= 0``.  :func:`solve_fixed_gain_ipm` runs the
infeasible-start HKM direction with Mehrotra's predictor-corrector on that pair: per iteration the
``m x m`` Schur matrix ``M_ij = tr(A_i X A_j Z^-1)`` (two batched matmuls and one matrix product),
its Cholesky factor (re-used by the corrector), and step lengths to the PSD boundary from the
eigenvalues of the steps in the Cholesky frame of X and Z.

It is an accelerator, not a certificate: it stops at its own test (primal and dual infeasibility
and the duality gap relative to the data, :data:`IPM_TOL`) and returns None otherwise -- the caller
then solves the SDP on Clarabel, the only source of ``infeasible`` and of every certificate.

References
----------
Helmberg, C., Rendl, F., Vanderbei, R. J. & Wolkowicz, H., "An interior-point method for
semidefinite programming", SIAM J. Optim. 6(2), 342-361 (1996).
Todd, M. J., Toh, K. C. & Tutuncu, R. H., "On the Nesterov-Todd direction in semidefinite
programming", SIAM J. Optim. 8(3), 769-796 (1998); SDPT3 (Toh, Todd & Tutuncu 1999).
Vandenberghe, L. & Boyd, S., "Semidefinite programming", SIAM Review 38(1), 49-95 (1996).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import scipy.linalg as sl
from numpy.typing import NDArray

from .._deadline import Deadline
from .._validate import as_int, as_positive_float
from ..analysis.linalg import sym
from ..backends.clarabel_fixed_gain import FixedGainFamily, FixedGainSolution, smat
from ..results import Status
from .tolerances import IPM_FLOOR_FACTOR, IPM_TOL, rounding_level

__all__ = ["IPM_TOL", "IPM_MAX_ITER", "IpmReport", "symmetric_basis", "solve_fixed_gain_ipm",
           "standard_form_ipm"]

#: iterations before giving up (measured: 8-15 on 49 one-output targets, n = 2..20)
IPM_MAX_ITER = 60

_dpotrf, _dpotrs, _dtrtri, _dsyevr = sl.lapack.get_lapack_funcs(
    ("potrf", "potrs", "trtri", "syevr"), dtype=np.float64)


@dataclass(frozen=True)
class IpmReport:
    """Why :func:`solve_fixed_gain_ipm` stopped (also when it returned no solution).

    Attributes
    ----------
    converged : bool
    iterations : int
    reason : str
    primal_infeasibility, dual_infeasibility, gap : float
        Relative measures at the last iterate.
    """

    converged: bool
    iterations: int
    reason: str
    primal_infeasibility: float
    dual_infeasibility: float
    gap: float


def symmetric_basis(T: NDArray, n: int) -> NDArray[np.float64]:
    """The ``(m, n, n)`` stack of the symmetric matrices ``smat(T[:, i])``.

    Parameters
    ----------
    T : (n(n+1)/2, m) array_like
        Columns in Clarabel's scaled triangle (:func:`~optdesign.backends.clarabel_fixed_gain.svec`).
    n : int
    """
    return smat(np.asarray(T, dtype=float).T, n)


def _max_step(Li: NDArray, D: NDArray) -> float:
    """The largest a with ``F + a D >= 0`` for ``F = Lf Lf'``, ``Li = Lf^-1`` (inf when D >= 0)."""
    W = Li @ D @ Li.T
    w, _, _, _, info = _dsyevr(W, compute_v=0, range="I", il=1, iu=1)
    lam = float(w[0]) if info == 0 else float(np.linalg.eigvalsh(sym(W))[0])
    return np.inf if lam >= 0 else -1.0 / lam


def _chol_inv(F: NDArray) -> tuple[NDArray, NDArray]:
    """``(Lf, Lf^-1)`` with ``F = Lf Lf'`` (LAPACK potrf / trtri: the IPM's small matrices)."""
    Lf, info = _dpotrf(F, lower=1, clean=1)
    if info != 0:
        raise np.linalg.LinAlgError("not positive definite")
    Li, info = _dtrtri(Lf, lower=1)
    if info != 0:
        raise np.linalg.LinAlgError("singular Cholesky factor")
    return Lf, Li


def _schur(B: NDArray, Lx: NDArray, Lzi: NDArray) -> NDArray:
    """``M_ij = tr(A_i X A_j Z^-1) = <G_i, G_j>``, ``G_i = Lz^-1 A_i Lx`` (``X = Lx Lx'``,
    ``Z^-1 = Lz^-T Lz^-1``) for the stack B of the A_i: two matrix products over the stack and one
    Gram matrix (symmetric positive semidefinite by construction)."""
    m, n = B.shape[0], B.shape[1]
    W = (B.reshape(m * n, n) @ Lzi.T).reshape(m, n, n)          # A_i Lz^-T
    G = (W.transpose(0, 2, 1).reshape(m * n, n) @ Lx).reshape(m, -1)   # Lz^-1 A_i Lx
    return G @ G.T


def _stopping_rule(tol: float, max_iter: int) -> tuple[float, int]:
    """``tol`` (a positive number) and ``max_iter`` (an integer >= 1), validated."""
    return as_positive_float("tol", tol), as_int("max_iter", max_iter, lo=1)


def solve_fixed_gain_ipm(family: FixedGainFamily, *, tol: float = IPM_TOL, max_iter: int = IPM_MAX_ITER,
                         deadline: Deadline | None = None
                         ) -> tuple[FixedGainSolution | None, IpmReport]:
    """Solve the ``"full"`` / ``"min_trace"`` fixed-gain SDP of ``family`` by the dense IPM.

    Parameters
    ----------
    family : FixedGainFamily
        Its ``T`` (n(n+1)/2, m) and ``Q0`` (n, n) define the LMI.
    tol : float
        Relative primal / dual infeasibility and gap at which the method stops.
    max_iter : int
    deadline : Deadline, optional
        No new iteration is started once it has expired (no solution then).

    Returns
    -------
    solution : FixedGainSolution or None
        Status ``optimal`` (native ``"ipm: optimal"``) with P, Q of the returned x (physical units,
        as :func:`~optdesign.backends.clarabel_fixed_gain.solve_fixed_gain`); None when the method
        did not reach its stopping test or its answer fails its own checks -- solve on Clarabel then.
    report : IpmReport

    Raises
    ------
    ValidationError
        ``tol`` not a positive number, ``max_iter`` not an integer >= 1.
    """
    tol, max_iter = _stopping_rule(tol, max_iter)
    n = family.Q0.shape[0]
    T = np.asarray(family.T, dtype=float)
    m = T.shape[1]
    if m == 0 or not (np.all(np.isfinite(T)) and np.all(np.isfinite(family.Q0))):
        return None, IpmReport(False, 0, "empty or non-finite data", np.nan, np.nan, np.nan)
    colnorm = np.linalg.norm(T, axis=0)
    if np.any(colnorm <= rounding_level(1, max(1.0, float(np.max(colnorm))))):
        return None, IpmReport(False, 0, "a direction of x does not move Q", np.nan, np.nan, np.nan)
    Ts = T / colnorm                                      # x = xs / colnorm
    B = symmetric_basis(Ts, n)
    b = np.trace(B, axis1=1, axis2=2)                     # b = c: max b'y = -min c'xs (y = -xs)
    out, rep = standard_form_ipm(B, b, family.Q0, tol=tol, max_iter=max_iter, deadline=deadline)
    if out is None:
        return None, rep
    return _solution(family, -out[2] / colnorm, rep, out[3])


def standard_form_ipm(B: NDArray, b: NDArray, C: NDArray, *, tol: float = IPM_TOL,
                      max_iter: int = IPM_MAX_ITER, deadline: Deadline | None = None
                      ) -> tuple[tuple[NDArray, NDArray, NDArray, float] | None, IpmReport]:
    """The IPM of this module on a standard pair: ``min <C, X>`` s.t. ``<A_i, X> = b_i``, ``X >= 0`` and
    ``max b'y`` s.t. ``sum_i y_i A_i + Z = C``, ``Z >= 0`` (the A_i the stack B, (m, n, n), symmetric).

    Returns ``((X, Z, y, ||Rd||), report)`` when it met its stopping test (relative primal and dual
    infeasibility and gap at most ``tol``), else ``(None, report)``.

    Raises
    ------
    ValidationError
        ``tol`` not a positive number, ``max_iter`` not an integer >= 1.
    """
    tol, max_iter = _stopping_rule(tol, max_iter)
    m, n = B.shape[0], B.shape[1]
    Bf = B.reshape(m, -1)
    normb, normC = 1.0 + float(np.linalg.norm(b)), 1.0 + float(np.linalg.norm(C))
    # the SDPT3 starting point: X, Z multiples of I large enough for the data
    nb = np.linalg.norm(Bf, axis=1)
    xi = max(10.0, np.sqrt(n), n * float(np.max((1.0 + np.abs(b)) / (1.0 + nb))))
    eta = max(10.0, np.sqrt(n), float(np.max(nb)), float(np.linalg.norm(C)))
    X, Z, y = xi * np.eye(n), eta * np.eye(n), np.zeros(m)
    rep = IpmReport(False, 0, "not started", np.inf, np.inf, np.inf)
    for k in range(max_iter + 1):
        Rp = b - Bf @ X.ravel()
        Rd = C - Z - (y @ Bf).reshape(n, n)
        pobj, dobj = float(np.sum(C * X)), float(b @ y)
        rp, rd = float(np.linalg.norm(Rp)) / normb, float(np.linalg.norm(Rd)) / normC
        gap = abs(pobj - dobj) / (1.0 + abs(pobj) + abs(dobj))
        rep = IpmReport(False, k, "iteration limit", rp, rd, gap)
        if not (np.isfinite(pobj) and np.isfinite(dobj)):
            return None, IpmReport(False, k, "non-finite iterate", rp, rd, gap)
        if max(rp, rd, gap) <= tol:
            return (X, Z, y, float(np.linalg.norm(Rd))), IpmReport(True, k, "converged", rp, rd, gap)
        if k == max_iter:
            return None, rep
        if deadline is not None and deadline.expired:
            return None, IpmReport(False, k, "time limit", rp, rd, gap)
        step = _iterate(B, b, X, Z, y, Rd)
        if step is None:
            return None, IpmReport(False, k, "Cholesky failed (numerical)", rp, rd, gap)
        X, Z, y = step
    return None, rep


def _iterate(B, b, X, Z, y, Rd):
    """One Mehrotra predictor-corrector step of the HKM direction, or None on a failed factorization."""
    try:
        Lx, Lxi = _chol_inv(X)
        _, Lzi = _chol_inv(Z)
        Mc, info = _dpotrf(_schur(B, Lx, Lzi), lower=1)
        if info != 0:
            raise np.linalg.LinAlgError("Schur matrix not positive definite")
    except np.linalg.LinAlgError:
        return None
    Zi = Lzi.T @ Lzi
    n = X.shape[0]
    Bf = B.reshape(B.shape[0], -1)
    mu = float(np.sum(X * Z)) / n
    AZi = Bf @ Zi.ravel()
    XRdZi = Bf @ (X @ Rd @ Zi).ravel()

    def direction(sigma: float, corr: NDArray | None):
        rhs = b - sigma * mu * AZi + XRdZi
        if corr is not None:
            rhs = rhs + Bf @ (corr @ Zi).ravel()
        dy, _ = _dpotrs(Mc, rhs, lower=1)
        dZ = Rd - (dy @ Bf).reshape(n, n)
        W = X @ dZ if corr is None else X @ dZ + corr
        dX = sigma * mu * Zi - X - sym(W @ Zi)
        return dX, dy, dZ

    def steps(dX, dZ, gamma):
        return (min(1.0, gamma * _max_step(Lxi, dX)), min(1.0, gamma * _max_step(Lzi, dZ)))

    dXa, _, dZa = direction(0.0, None)
    ap, ad = steps(dXa, dZa, 1.0)
    mu_aff = float(np.sum((X + ap * dXa) * (Z + ad * dZa))) / n
    sigma = min(1.0, (mu_aff / mu) ** 3) if mu > 0 else 0.0
    dX, dy, dZ = direction(sigma, dXa @ dZa)
    ap, ad = steps(dX, dZ, 0.9 + 0.09 * min(ap, ad))
    Xn, Zn = sym(X + ap * dX), sym(Z + ad * dZ)
    return Xn, Zn, y + ad * dy


def _solution(family: FixedGainFamily, x: NDArray, rep: IpmReport, dual_residual: float
              ) -> tuple[FixedGainSolution | None, IpmReport]:
    """The FixedGainSolution of x, or None when Q(x) is not PSD to what the IPM's dual residual
    (``Q(x) = Z + Rd`` with ``Z > 0``, scaled units) and the rounding of ``Q`` from ``P`` allow."""
    P = family.P_of(x)
    Q = family.Q_of_P(P)
    if not (np.all(np.isfinite(P)) and np.all(np.isfinite(Q))):
        return None, replace(rep, converged=False, reason="non-finite answer")
    n = P.shape[0]
    lam = np.linalg.eigvalsh(Q)
    A = family.map.A
    if family.map.dt is None:   # Q = s LRL - A P - P A' (continuous) or P - F P F' - s LRL
        gain = 2.0 * float(np.linalg.norm(A))
    else:
        gain = 1.0 + float(np.linalg.norm(A - family.L @ family.map.C)) ** 2
    terms = gain * float(np.linalg.norm(P)) + family.scale * float(np.linalg.norm(family.LRL))
    floor = family.scale * dual_residual + rounding_level(n, terms, IPM_FLOOR_FACTOR)
    if lam[0] < -10.0 * floor:
        return None, replace(rep, converged=False,
                             reason=f"Q(x) not PSD: smallest eigenvalue {lam[0]:.3g} < -{10.0 * floor:.3g}")
    return FixedGainSolution(Status.OPTIMAL, "ipm: optimal", P, Q, Q, None, rep.iterations, 0.0), rep
