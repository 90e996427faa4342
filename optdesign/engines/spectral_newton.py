r"""Newton methods on the Kalman spectral conditions (the problem of
:mod:`optdesign.engines.spectral_factor`): the smooth local solver behind
:mod:`optdesign.engines.inverse_kalman_engine`.

Methods
-------
* :func:`project` -- Gauss-Newton (minimum-norm steps) onto ``r = 0``, the normalizations of g kept
  (``||g_b|| = 1``, repeated targets orthonormal null vectors): the retraction, and the feasibility
  phase from an infeasible start (:func:`find_feasible`, with a backtracking line search).
* :func:`newton` -- Newton's method on the feasible manifold: the null-space (reduced) Hessian of
  the Lagrangian, a trust-region step in the tangent space, the retraction and an Armijo line
  search on the Lagrangian; the gauge ``V -> V U`` removed by ``skew(V' dV) = 0``; columns of V
  whose singular value vanishes are truncated (a rank-deficient factor is a degenerate point where
  Newton converges only linearly).
* :func:`sqp` -- from an infeasible start: normal plus tangential steps with a filter line search.
* :func:`escape_direction` -- the rank-increasing descent direction of a negative eigenvalue of the
  dual slack.

All quantities are scaled: ``R`` and ``Q`` by ``scale`` (the caller's), so that ``Qdec`` is O(1).

References
----------
Moore, B. C., "On the flexibility offered by state feedback in multivariable systems beyond closed
loop eigenvalue assignment", IEEE TAC 21 (1976) 689-692 (the eigenvector parametrization).
Anderson & Moore, *Optimal Filtering* (1979) (the spectral factorization identity).  Burer, S. &
Monteiro, R. D. C., Math. Program. 95 (2003) 329-357 (the factorization ``Q = V V'``).  Absil,
Mahony & Sepulchre, *Optimization Algorithms on Matrix Manifolds* (2008) (Newton with retraction).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sl
from numpy.typing import NDArray
from scipy.linalg import lapack

from .spectral_factor import FactorProblem, residual_scale
from .tolerances import (
    ARMIJO_C1,
    DECREASE_ROUNDING_FACTOR,
    FEASIBLE_RESIDUAL_FACTOR,
    FILTER_GAMMA_F,
    FILTER_GAMMA_THETA,
    FILTER_THETA_MAX_FACTOR,
    GN_MIN_STEP,
    MIN_STEP,
    NEWTON_GTOL,
    QR_RANK_RTOL,
    RADIUS_SHRINK_MIN,
    SQP_FEAS_RTOL,
    TR_BISECT_RTOL,
    TR_SHIFT_RTOL,
    TRUNCATE_RTOL,
    rounding_level,
)

__all__ = ["NewtonReport", "project", "find_feasible", "newton", "sqp", "escape_direction"]



def _householder(Mt: NDArray, pivoting: bool = False):
    """Householder QR of a tall ``Mt`` in LAPACK's compact form: ``((h, tau), R, piv)`` (``piv`` the
    identity unless ``pivoting``).  Q is applied by :func:`_apply_q`, never formed: forming it
    (``orgqr``) costs 2-4x the factorization at the engine's sizes (measured: 1040 x 500, the QR
    0.037 s, its economic Q 0.076 s more, its full Q 0.23 s more)."""
    if pivoting:
        (h, tau), R, piv = sl.qr(Mt, mode="raw", pivoting=True, check_finite=False)
    else:
        (h, tau), R = sl.qr(Mt, mode="raw", check_finite=False)
        piv = np.arange(Mt.shape[1])
    return (h[:, :tau.size], tau), R, piv   # a wide Mt: min(N, m) reflectors


def _apply_q(ht: tuple, X: NDArray, trans: bool = False, overwrite: bool = False) -> NDArray[np.float64]:
    """``Q X`` (``Q' X`` with ``trans``) for the Q of :func:`_householder` ((N, N)) and X ((N,) or
    (N, c)): LAPACK ``ormqr`` on the reflectors (blocked).  X is copied unless ``overwrite``."""
    h, tau = ht
    vec = X.ndim == 1
    if not overwrite:
        X = np.array(X, dtype=float, order="F", copy=True)
    if X.size == 0 or tau.size == 0:   # nothing to apply, or no reflectors (Q = I)
        return X
    C = X.reshape(-1, 1) if vec else X
    lwork = max(1, 64 * C.shape[1])
    out, _, info = lapack.dormqr("L", "T" if trans else "N", h, tau, C, lwork=lwork, overwrite_c=1)
    if info != 0:  # pragma: no cover - LAPACK argument errors only
        raise RuntimeError(f"dormqr failed (info {info})")
    return out[:, 0] if vec else out


def _lstsq(M: NDArray, b: NDArray) -> NDArray:
    """Minimum-norm solution of ``M x = b`` for a wide M of full row rank: blocked QR of M'
    (``M' = Q R``, ``x = Q [R'^-1 b; 0]``; level-3 BLAS, several times faster than a pivoting
    least-squares driver here); least squares (LAPACK gelsy) when M is not of full row rank."""
    m, n = M.shape
    if m <= n:
        ht, Rf, _ = _householder(M.T)
        d = np.abs(np.diag(Rf))
        if d.size and d.min() > QR_RANK_RTOL * d.max():
            y = np.zeros(n)
            y[:m] = sl.solve_triangular(Rf, b, trans="T", check_finite=False)
            return _apply_q(ht, y, overwrite=True)
    return sl.lstsq(M, b, lapack_driver="gelsy", check_finite=False)[0]


# ============================================================================ methods
def project(problem: FactorProblem, x: NDArray, *, max_iter: int = 12,
            tol_factor: float = FEASIBLE_RESIDUAL_FACTOR) -> tuple[NDArray, bool, int]:
    """Gauss-Newton (minimum-norm steps, normalizations kept) from x onto the residuals' zero set.

    Returns ``(x, converged, iterations)``: converged when ``||c|| <= tol_factor *``
    :func:`residual_scale` (the residuals at rounding level); stops early when a step does not
    reduce ``||c||`` by 10 % (after the first two), returning the best iterate.
    """
    x = problem.normalize(x)
    c = problem.c(x)
    best = (float(np.linalg.norm(c)), x)
    for it in range(max_iter):
        if best[0] <= tol_factor * residual_scale(problem, best[1]) * np.sqrt(max(1, c.size)):
            return best[1], True, it
        J = problem.jac(x)
        T = problem.tangent_rows(x, gauge=False)
        dx = _lstsq(np.vstack([J, T]), np.concatenate([-c, np.zeros(T.shape[0])]))
        x = problem.normalize(x + dx)
        c = problem.c(x)
        nc = float(np.linalg.norm(c))
        if not np.isfinite(nc):
            break
        if nc < best[0]:
            improved = nc < 0.9 * best[0]
            best = (nc, x)
            if not improved and it >= 2:
                break
        elif it >= 2:
            break
    ok = best[0] <= tol_factor * residual_scale(problem, best[1]) * np.sqrt(max(1, c.size))
    return best[1], bool(ok), max_iter


def find_feasible(problem: FactorProblem, x: NDArray, *, max_iter: int = 60, truncate: float = TRUNCATE_RTOL,
                  expired: Callable[[], bool] | None = None) -> tuple[FactorProblem, NDArray, bool, int]:
    """Gauss-Newton with a backtracking line search on ``||c||`` from an infeasible start.

    Columns of V whose singular value falls below ``truncate`` (relative) are removed on the way
    (the Jacobian degenerates as Q loses rank, and Gauss-Newton crawls there).  Returns
    ``(problem, x, converged, iterations)`` -- the problem changes when columns are removed.  A
    local method: no convergence says nothing about the existence of a solution.
    """
    x = problem.normalize(x)
    c = problem.c(x)
    nc = float(np.linalg.norm(c))
    for it in range(max_iter):
        if nc <= FEASIBLE_RESIDUAL_FACTOR * residual_scale(problem, x) * np.sqrt(c.size):
            return problem, x, True, it
        if expired is not None and expired():
            return problem, x, False, it
        pr2, x2, dropped = _truncate(problem, x, truncate)
        if dropped:
            problem, x = pr2, x2
            c = problem.c(x)
            nc = float(np.linalg.norm(c))
        J = problem.jac(x)
        T = problem.tangent_rows(x, gauge=False)
        dx = _lstsq(np.vstack([J, T]), np.concatenate([-c, np.zeros(T.shape[0])]))
        alpha = 1.0
        while alpha > GN_MIN_STEP:
            xn = problem.normalize(x + alpha * dx)
            cn = problem.c(xn)
            nn = float(np.linalg.norm(cn))
            if nn < (1.0 - ARMIJO_C1 * alpha) * nc:
                break
            alpha *= 0.5
        else:
            return problem, x, False, it
        x, c, nc = xn, cn, nn
    return problem, x, bool(nc <= 100.0 * residual_scale(problem, x) * np.sqrt(c.size)), max_iter


@dataclass(frozen=True)
class NewtonReport:
    """Outcome of :func:`newton`.

    Attributes
    ----------
    x : ndarray
        Last (feasible) iterate.
    converged : bool
        The reduced gradient reached its tolerance.
    iterations : int
    f : float
        Objective at x (scaled).
    reduced_gradient : float
        ``||Z' grad f||`` at x.
    multipliers : ndarray
        Least-squares multipliers of the residuals at x.
    reason : str
        Why it stopped.
    truncated : int
        Columns of V removed (vanishing singular values).
    problem : FactorProblem
        The problem of x (its rank changes when columns are truncated).
    """

    x: NDArray[np.float64]
    converged: bool
    iterations: int
    f: float
    reduced_gradient: float
    multipliers: NDArray[np.float64]
    reason: str
    truncated: int
    problem: FactorProblem


class _Factored:
    """Pivoted QR of ``M'`` (``M'[:, piv] = Q R``): the null space of M, least-squares multipliers
    and minimum-norm solutions of ``M dx = b`` (the rows of a dependent set are dropped).  Q is kept
    as Householder reflectors (:func:`_householder`); only the null-space columns are formed."""

    def __init__(self, M: NDArray):
        ht, Rf, piv = _householder(M.T)                        # blocked: fast; rank-revealing below
        d = np.abs(np.diag(Rf))
        if d.size and d.min() <= QR_RANK_RTOL * d.max():  # dependent rows: the pivoted factorization
            ht, Rf, piv = _householder(M.T, pivoting=True)
            d = np.abs(np.diag(Rf))
        self.rank = int(np.sum(d > QR_RANK_RTOL * d.max())) if d.size else 0
        N = M.shape[1]
        E = np.zeros((N, N - self.rank), order="F")
        E[self.rank:, :] = np.eye(N - self.rank)
        self.Z = _apply_q(ht, E, overwrite=True)
        self.ht = ht
        self.R1 = Rf[:self.rank, :self.rank]
        self.piv = piv
        self.m = M.shape[0]
        self.N = N

    def multipliers(self, grad: NDArray) -> NDArray[np.float64]:
        """``lam`` with ``M' lam = -grad`` in the least-squares sense."""
        lam = np.zeros(self.m)
        if self.rank:
            qg = _apply_q(self.ht, np.asarray(grad, dtype=float), trans=True)[:self.rank]
            lam[self.piv[:self.rank]] = sl.solve_triangular(self.R1, -qg, check_finite=False)
        return lam

    def min_norm(self, b: NDArray) -> NDArray[np.float64]:
        """The minimum-norm dx with ``M dx = b`` (on the independent rows)."""
        y = np.zeros(self.N)
        if self.rank:
            y[:self.rank] = sl.solve_triangular(self.R1, b[self.piv[:self.rank]], trans="T",
                                                check_finite=False)
        return _apply_q(self.ht, y, overwrite=True)


def _reduced_step(Hz: NDArray, gz: NDArray, radius: float) -> NDArray:
    """The trust-region step of ``gz`` and ``Hz``: the Newton step by Cholesky where Hz is
    positive definite and the step fits in the radius, else the trust-region subproblem on the
    tridiagonal form of Hz (:func:`_tr_step_tridiagonal`; :func:`_tr_step` on its eigenvalues below
    :data:`TRIDIAGONAL_MIN_DIM`)."""
    Hs = 0.5 * (Hz + Hz.T)
    try:
        cho = sl.cho_factor(Hs, check_finite=False)
        d = -sl.cho_solve(cho, gz, check_finite=False)
        if np.linalg.norm(d) <= radius:
            return d
    except np.linalg.LinAlgError:
        pass
    d = _tr_step_tridiagonal(Hs, gz, radius) if Hs.shape[0] >= TRIDIAGONAL_MIN_DIM else None
    if d is None:   # small, or a tridiagonal shift not positive definite in rounding
        d = _tr_step(*np.linalg.eigh(Hs), gz, radius)
    return d


#: the trust-region subproblem on the tridiagonal form from this reduced dimension (below, the
#: eigendecomposition: fewer Python-level steps).  Measured (CPU per step, random indefinite H):
#: d = 32 0.58 / 0.65 ms (eigenvectors / tridiagonal), 48 0.79 / 0.78, 64 1.14 / 0.90, 128 2.9 / 1.8,
#: 256 14 / 5.7, 540 72 / 28
TRIDIAGONAL_MIN_DIM = 64


def _tr_step_tridiagonal(H: NDArray, g: NDArray, radius: float) -> NDArray | None:
    """:func:`_tr_step` for a symmetric H ((d, d)) without its eigenvectors: ``H = Q T Q'`` with T
    tridiagonal (LAPACK ``sytrd``; Q kept as reflectors), the smallest eigenvalue of T by
    bisection (``stebz``), ``||(T + lam I)^-1 b||`` by tridiagonal LDL' solves (``ptsv``) in the
    same bisection on lam, and the hard case's eigenvector by inverse iteration (``stein``); the
    step ``Q d``.  The same minimizer (More & Sorensen 1983) as :func:`_tr_step`; None where a
    shifted T that must be positive definite is not in rounding (the caller then uses
    :func:`_tr_step`)."""
    n = H.shape[0]
    lwork = int(lapack.dsytrd_lwork(n, lower=1)[0])
    c, dd, e, tau, info = lapack.dsytrd(H, lower=1, lwork=max(lwork, 1))
    if info != 0:  # pragma: no cover - LAPACK argument errors only
        return None
    ht = (np.asfortranarray(c[1:, :-1]), tau)

    def q_apply(v: NDArray, trans: bool) -> NDArray:   # Q = diag(1, Q~), Q~ the reflectors of ht
        out = v.copy()
        out[1:] = _apply_q(ht, v[1:], trans=trans)
        return out

    b = q_apply(np.asarray(g, dtype=float), True)
    w = sl.eigvalsh_tridiagonal(dd, e, check_finite=False)
    wmin = float(w[0])

    def solve(lam: float, rhs: NDArray) -> NDArray | None:
        """``(T + lam I)^-1 rhs`` (positive definite: LDL'), None when it is not."""
        _, _, x, info = lapack.dptsv(dd + lam, e, rhs)
        return x if info == 0 else None

    if wmin > 0:
        x = solve(0.0, -b)
        if x is not None and np.linalg.norm(x) <= radius:
            return q_apply(x, False)
    lo = max(0.0, -wmin)
    shift = TR_SHIFT_RTOL * max(1.0, float(np.max(np.abs(w))))

    def size(lam: float) -> float:
        x = solve(lam, b)
        return float("inf") if x is None else float(np.linalg.norm(x))

    if size(lo + shift) <= radius:      # hard case: the gradient misses the lowest eigenvector
        u = sl.eigh_tridiagonal(dd, e, select="i", select_range=(0, 0), check_finite=False)[1][:, 0]
        x = solve(lo + shift, b)
        if x is None:  # pragma: no cover - not positive definite in rounding
            return None
        x = x - float(u @ x) * u
        tau_ = np.sqrt(max(radius ** 2 - float(x @ x), 0.0))
        return q_apply(-x + (-tau_ if float(u @ b) >= 0 else tau_) * u, False)
    hi = _multiplier(size, lo + shift, lo + float(np.linalg.norm(b)) / radius + shift, radius)
    x = solve(hi, b)
    return None if x is None else q_apply(-x, False)


def _multiplier(size: Callable[[float], float], lo: float, hi: float, radius: float) -> float:
    """The trust-region multiplier: the smallest lam in ``[lo, hi]`` with ``size(lam) <= radius``
    to 1e-12 relative, by bisection (``size`` decreases from above the radius at lo to at most the
    radius at hi)."""
    for _ in range(100):
        mid = np.sqrt(lo * hi) if lo > 0 else 0.5 * hi
        if size(mid) > radius:
            lo = mid
        else:
            hi = mid
        if hi - lo <= TR_BISECT_RTOL * hi:
            break
    return hi


def _tr_step(w: NDArray, E: NDArray, g: NDArray, radius: float) -> NDArray:
    """Minimizer of ``g'd + d' H d / 2`` over ``||d|| <= radius`` for ``H = E diag(w) E'``
    (the trust-region subproblem in the eigenbasis: ``d = -(H + lam I)^-1 g`` with the smallest
    ``lam >= max(0, -min w)`` that keeps d in the region; the hard case adds the eigenvector of
    the smallest eigenvalue).  More & Sorensen (1983), by bisection on lam."""
    b = E.T @ g
    wmin = float(w[0])
    if wmin > 0:
        d = -b / w
        if np.linalg.norm(d) <= radius:
            return E @ d
    lo = max(0.0, -wmin)
    shift = TR_SHIFT_RTOL * max(1.0, float(np.max(np.abs(w))))

    def size(lam):
        return float(np.linalg.norm(b / (w + lam)))

    if size(lo + shift) <= radius:      # hard case: the gradient misses the lowest eigenvector
        d = -b / (w + lo + shift)
        d[0] = 0.0
        tau = np.sqrt(max(radius ** 2 - float(d @ d), 0.0))
        d[0] = -tau if b[0] >= 0 else tau
        return E @ d
    hi = _multiplier(size, lo + shift, lo + float(np.linalg.norm(b)) / radius + shift, radius)
    return E @ (-b / (w + hi))


#: the chord retraction: at most this many corrections, each reducing the residuals by the factor
#: below.  Measured at n = 40, p = 8 (140 retractions of a design): the stale Jacobian contracts by
#: 0.1-0.5 per correction, so 6 corrections at 0.5 converged 11 times and 30 at 0.9 55 times, each
#: failure paying a Gauss-Newton projection (a QR per step); the objectives were equal or better
#: (0.2-0.3 % on 2 of 3 targets)
CHORD_MAX_ITER = 30
CHORD_RATE = 0.9


def _chord_project(problem: FactorProblem, x: NDArray, fac: _Factored, n_rows: int,
                   max_iter: int = CHORD_MAX_ITER) -> tuple[NDArray, bool]:
    """The retraction by the chord method: Gauss-Newton corrections with the factored Jacobian
    of the base point (``n_rows`` residual rows, the tangent rows' right-hand side 0) while each
    reduces ``||c||`` by :data:`CHORD_RATE`; falls back to :func:`project` when it stalls."""
    x = problem.normalize(x)
    c = problem.c(x)
    nc = float(np.linalg.norm(c))
    tol = 100.0 * residual_scale(problem, x) * np.sqrt(max(1, c.size))
    rhs = np.zeros(fac.m)
    for _ in range(max_iter):
        if nc <= tol:
            return x, True
        rhs[:n_rows] = -c
        xn = problem.normalize(x + fac.min_norm(rhs))
        cn = problem.c(xn)
        nn = float(np.linalg.norm(cn))
        if not nn < CHORD_RATE * nc:
            break
        x, c, nc = xn, cn, nn
    if nc <= tol:
        return x, True
    xp, ok, _ = project(problem, x)
    return xp, ok


def _truncate(problem: FactorProblem, x: NDArray, rel: float) -> tuple[FactorProblem, NDArray, int]:
    """Drop the columns of V whose singular values are below ``rel`` times the largest."""
    if problem.diagonal or problem.rank <= 1:
        return problem, x, 0
    V, t, g = problem.unpack(x)
    U, sv, _ = np.linalg.svd(V, full_matrices=False)
    keep = int(np.sum(sv > rel * sv[0]))
    if keep >= problem.rank or keep == 0:
        return problem, x, 0
    new = FactorProblem(problem.blocks, keep, problem.objective, problem.nominal, False,
                        problem.fixed_g, problem.g_fixed)
    return new, new.pack(U[:, :keep] * sv[:keep], t, g), problem.rank - keep


def _polish(problem: FactorProblem, x: NDArray) -> tuple[NDArray, float]:
    """The residuals down to rounding (the line search accepts 100x that): ``(x, f)``."""
    xp, _, _ = project(problem, x, tol_factor=1.0)
    if np.linalg.norm(problem.c(xp)) <= np.linalg.norm(problem.c(x)):
        x = xp
    return x, problem.f(x)


def newton(problem: FactorProblem, x: NDArray, *, max_iter: int = 100, gtol: float = NEWTON_GTOL,
           truncate: float = TRUNCATE_RTOL, expired: Callable[[], bool] | None = None,
           log: list | None = None) -> NewtonReport:
    """Newton's method for ``min f`` on the feasible manifold ``c = 0`` from a feasible x.

    Each iteration: the null space Z of the residual Jacobian and the tangent rows, least-squares
    multipliers, the reduced Hessian ``Z' H Z`` of the Lagrangian, the trust-region step of
    ``Z' grad f`` and ``Z'HZ`` (``_reduced_step``: the Newton step where Z'HZ is positive
    definite and the step fits in the radius), the retraction (chord method, else
    :func:`project`) and an Armijo line search on the Lagrangian (f alone is sensitive to the
    retraction's tolerance in the normal directions); the radius grows after full steps and
    shrinks to the accepted length otherwise.  Columns of V with singular value below
    ``truncate`` (relative) are removed first.  Stops when ``||Z' grad f|| <= gtol * max(1, |f|)``
    or the predicted decrease is rounding (then the residuals are polished to rounding), after
    ``max_iter`` iterations, when no step decreases the merit, or when ``expired()``.  ``log``
    (a list) receives one ``(f, ||Z' grad f||, step length, rank)`` per iteration.
    """
    f = problem.f(x)
    truncated = 0
    mu = np.zeros(problem.blocks.ng)
    gz_norm = float("inf")
    reason = "iteration limit"
    radius = max(1.0, float(np.linalg.norm(x)))
    it = 0
    for it in range(max_iter):
        if expired is not None and expired():
            reason = "time limit"
            break
        pr2, x2, dropped = _truncate(problem, x, truncate)
        if dropped:
            x2, ok, _ = project(pr2, x2)
            if ok:
                problem, x, f = pr2, x2, pr2.f(x2)
                truncated += dropped
        grad = problem.grad(x)
        J = problem.jac(x)
        fac = _Factored(np.vstack([J, problem.tangent_rows(x)]))
        Z = fac.Z
        mu = fac.multipliers(grad)[:J.shape[0]]
        gz = Z.T @ grad
        gz_norm = float(np.linalg.norm(gz))
        if Z.shape[1] == 0 or gz_norm <= gtol * max(1.0, abs(f)):
            x, f = _polish(problem, x)
            return NewtonReport(x, True, it, f, gz_norm, mu, "converged", truncated, problem)
        Hz = problem.reduced_hessian(x, mu, Z)
        dx = Z @ _reduced_step(Hz, gz, radius)
        ndx = float(np.linalg.norm(dx))
        slope = float(grad @ dx)
        # the predicted decrease is rounding
        if -slope <= rounding_level(1, max(1.0, abs(f)), DECREASE_ROUNDING_FACTOR):
            x, f = _polish(problem, x)
            return NewtonReport(x, True, it, f, gz_norm, mu, "converged (decrease at rounding level)",
                                truncated, problem)
        # merit: the Lagrangian -- insensitive to first order to the retraction's tolerance in
        # the normal directions (f alone is not: its gradient is mostly normal)
        merit = f + float(mu @ problem.c(x))
        alpha = 1.0
        accepted = False
        while alpha > MIN_STEP:
            xn, ok = _chord_project(problem, x + alpha * dx, fac, J.shape[0])
            if ok:
                fn = problem.f(xn)
                if fn + float(mu @ problem.c(xn)) <= merit + ARMIJO_C1 * alpha * slope:
                    accepted = True
                    break
            alpha *= 0.5
        if log is not None:
            log.append((f, gz_norm, alpha if accepted else 0.0, problem.rank))
        if not accepted:
            reason = "no decrease along the Newton direction"
            break
        radius = max(radius, 2.0 * ndx) if alpha == 1.0 else max(alpha * ndx, RADIUS_SHRINK_MIN * radius)
        x, f = xn, fn
    return NewtonReport(x, False, it + 1, f, gz_norm, mu, reason, truncated, problem)


def _filter_accepts(filt: list, theta: float, f: float) -> bool:
    """Not dominated by a filter entry ``(theta_j, f_j)`` (the margins are in the entries)."""
    return all(theta < tj or f < fj for tj, fj in filt)


def sqp(problem: FactorProblem, x: NDArray, *, max_iter: int = 100, feas_rel: float = SQP_FEAS_RTOL,
        truncate: float = TRUNCATE_RTOL, expired: Callable[[], bool] | None = None,
        log: list | None = None) -> NewtonReport:
    """SQP from an infeasible x until it is nearly feasible (``||c|| <= feas_rel *`` the size of the
    residuals' terms), the objective reduced on the way.

    Each step is the minimum-norm normal step ``dn`` (``J dn = -c``, the tangent rows kept) plus the
    tangential step of the trust-region subproblem of ``Z'(grad f + H dn)`` and ``Z'HZ``
    (``_reduced_step``: negative curvature is followed, not flipped), with a filter line
    search on ``(theta, f)``, ``theta = ||c||`` (Waechter & Biegler's rules, simplified: a trial
    point is accepted when the filter does not dominate it and it reduces theta or f by a margin
    of theta, or -- where the step is a descent direction that dominates the infeasibility -- when
    it satisfies Armijo's condition on f); the step is kept within a radius that grows after a
    full step and shrinks to the accepted length otherwise.  Moving towards feasibility and
    optimality together lands in better basins than projecting onto the feasible set first
    (measured on the cross-validation targets).  The caller finishes with :func:`project` (or
    :func:`find_feasible`) and :func:`newton`; ``converged`` means nearly feasible.

    References
    ----------
    Waechter, A. & Biegler, L. T., "On the implementation of an interior-point filter line-search
    algorithm for large-scale nonlinear programming", Math. Program. 106 (2006) 25-57.
    """
    x = problem.normalize(x)
    mu = np.zeros(problem.blocks.ng)
    truncated = 0
    it = 0
    f = problem.f(x)
    gz_norm = float("inf")
    c = problem.c(x)
    theta0 = float(np.linalg.norm(c))
    theta_max = FILTER_THETA_MAX_FACTOR * max(1.0, theta0)
    filt: list[tuple[float, float]] = [(theta_max, -np.inf)]
    g_th, g_f = FILTER_GAMMA_THETA, FILTER_GAMMA_F
    radius = max(1.0, float(np.linalg.norm(x)))
    for it in range(max_iter):
        if expired is not None and expired():
            return NewtonReport(x, False, it, f, gz_norm, mu, "time limit", truncated, problem)
        pr2, x2, dropped = _truncate(problem, x, truncate)
        if dropped:  # a new point (the dropped columns change theta and f): a new filter
            problem, x, truncated = pr2, x2, truncated + dropped
            filt = [(theta_max, -np.inf)]
        c = problem.c(x)
        theta = float(np.linalg.norm(c))
        f = problem.f(x)
        if theta <= feas_rel * problem.scale_c(x):
            return NewtonReport(x, True, it, f, gz_norm, mu, "nearly feasible", truncated, problem)
        grad = problem.grad(x)
        J = problem.jac(x)
        fac = _Factored(np.vstack([J, problem.tangent_rows(x)]))
        rhs = np.zeros(fac.m)
        rhs[:J.shape[0]] = -c
        dn = fac.min_norm(rhs)
        mu = fac.multipliers(grad)[:J.shape[0]]
        H = problem.hess(x, mu)
        Z = fac.Z
        ndn = float(np.linalg.norm(dn))
        if ndn > radius:
            dn *= radius / ndn
            ndn = radius
        dx = dn
        if Z.shape[1]:
            gz = Z.T @ (grad + H @ dn)
            gz_norm = float(np.linalg.norm(Z.T @ grad))
            Hz = problem.reduced_hessian(x, mu, Z, H)
            dx = dn + Z @ _reduced_step(Hz, gz, max(np.sqrt(max(radius ** 2 - ndn ** 2, 0.0)), 0.1 * radius))
        ndx = float(np.linalg.norm(dx))
        m = float(grad @ dx)
        alpha = 1.0
        accepted = False
        while alpha > MIN_STEP:
            xn = problem.normalize(x + alpha * dx)
            th_n, f_n = float(np.linalg.norm(problem.c(xn))), problem.f(xn)
            if np.isfinite(th_n) and np.isfinite(f_n) and _filter_accepts(filt, th_n, f_n):
                switching = m < 0 and alpha * (-m) ** 2.3 > theta ** 1.1
                if switching and f_n <= f + ARMIJO_C1 * alpha * m:
                    accepted = True
                    break
                if not switching and (th_n <= (1 - g_th) * theta or f_n <= f - g_f * theta):
                    filt.append(((1 - g_th) * theta, f - g_f * theta))
                    accepted = True
                    break
            alpha *= 0.5
        if log is not None:
            log.append((f, theta, alpha if accepted else 0.0, problem.rank))
        if not accepted:
            return NewtonReport(x, False, it, f, gz_norm, mu, "the filter line search failed", truncated,
                                problem)
        radius = max(radius, 2.0 * ndx) if alpha == 1.0 else max(alpha * ndx, RADIUS_SHRINK_MIN * radius)
        x = xn
    return NewtonReport(x, False, it + 1, problem.f(x), gz_norm, mu, "iteration limit", truncated, problem)


def escape_direction(problem: FactorProblem, x: NDArray, mu: NDArray,
                     tol: float) -> NDArray[np.float64] | None:
    """The eigenvector of the most negative eigenvalue of the dual slack S (see the module
    docstring) when that eigenvalue is below ``-tol``; else None (x is a KKT point of the
    problem over every ``Qdec >= 0``)."""
    S = problem.dual_slack(x, mu)
    w, U = np.linalg.eigh(S)
    if w[0] >= -tol:
        return None
    return U[:, 0]
