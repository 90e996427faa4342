r"""Newton methods on the Kalman spectral conditions (the problem of
:mod:`optdesign.solvers.spectral_factor`): the smooth local solver behind
:mod:`optdesign.solvers.inverse_kalman_engine`.

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

from .spectral_factor import FactorProblem, residual_scale

__all__ = ["NewtonReport", "project", "find_feasible", "newton", "sqp", "escape_direction"]

_EPS = float(np.finfo(float).eps)


def _lstsq(M: NDArray, b: NDArray) -> NDArray:
    """Minimum-norm solution of ``M x = b`` for a wide M of full row rank: blocked QR of M'
    (``M' = Q R``, ``x = Q R'^-1 b``; level-3 BLAS, several times faster than a pivoting
    least-squares driver here); least squares (LAPACK gelsy) when M is not of full row rank."""
    m, n = M.shape
    if m <= n:
        Qf, Rf = sl.qr(M.T, mode="economic", check_finite=False)
        d = np.abs(np.diag(Rf))
        if d.size and d.min() > 1e-11 * d.max():
            return Qf @ sl.solve_triangular(Rf, b, trans="T", check_finite=False)
    return sl.lstsq(M, b, lapack_driver="gelsy", check_finite=False)[0]


# ============================================================================ methods
def project(problem: FactorProblem, x: NDArray, *, max_iter: int = 12,
            tol_factor: float = 100.0) -> tuple[NDArray, bool, int]:
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


def find_feasible(problem: FactorProblem, x: NDArray, *, max_iter: int = 60, truncate: float = 1e-5,
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
        if nc <= 100.0 * residual_scale(problem, x) * np.sqrt(c.size):
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
        while alpha > 1e-6:
            xn = problem.normalize(x + alpha * dx)
            cn = problem.c(xn)
            nn = float(np.linalg.norm(cn))
            if nn < (1.0 - 1e-4 * alpha) * nc:
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
    and minimum-norm solutions of ``M dx = b`` (the rows of a dependent set are dropped)."""

    def __init__(self, M: NDArray):
        Qf, Rf = sl.qr(M.T, mode="full", check_finite=False)   # blocked: fast; rank-revealing below
        piv = np.arange(M.shape[0])
        d = np.abs(np.diag(Rf))
        if d.size and d.min() <= 1e-11 * d.max():  # dependent rows: the pivoted factorization
            Qf, Rf, piv = sl.qr(M.T, mode="full", pivoting=True, check_finite=False)
            d = np.abs(np.diag(Rf))
        self.rank = int(np.sum(d > 1e-11 * d.max())) if d.size else 0
        self.Z = Qf[:, self.rank:]
        self.Q1 = Qf[:, :self.rank]
        self.R1 = Rf[:self.rank, :self.rank]
        self.piv = piv
        self.m = M.shape[0]

    def multipliers(self, grad: NDArray) -> NDArray[np.float64]:
        """``lam`` with ``M' lam = -grad`` in the least-squares sense."""
        lam = np.zeros(self.m)
        if self.rank:
            lam[self.piv[:self.rank]] = sl.solve_triangular(self.R1, -(self.Q1.T @ grad), check_finite=False)
        return lam

    def min_norm(self, b: NDArray) -> NDArray[np.float64]:
        """The minimum-norm dx with ``M dx = b`` (on the independent rows)."""
        if not self.rank:
            return np.zeros(self.Q1.shape[0])
        y = sl.solve_triangular(self.R1, b[self.piv[:self.rank]], trans="T", check_finite=False)
        return self.Q1 @ y


def _reduced_step(Hz: NDArray, gz: NDArray, radius: float) -> NDArray:
    """The trust-region step of ``gz`` and ``Hz``: the Newton step by Cholesky where Hz is
    positive definite and the step fits in the radius, else :func:`_tr_step` on its eigenvalues."""
    Hs = 0.5 * (Hz + Hz.T)
    try:
        cho = sl.cho_factor(Hs, check_finite=False)
        d = -sl.cho_solve(cho, gz, check_finite=False)
        if np.linalg.norm(d) <= radius:
            return d
    except np.linalg.LinAlgError:
        pass
    w, E = np.linalg.eigh(Hs)
    return _tr_step(w, E, gz, radius)


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
    shift = 1e-12 * max(1.0, float(np.max(np.abs(w))))

    def size(lam):
        return float(np.linalg.norm(b / (w + lam)))

    if size(lo + shift) <= radius:      # hard case: the gradient misses the lowest eigenvector
        d = -b / (w + lo + shift)
        d[0] = 0.0
        tau = np.sqrt(max(radius ** 2 - float(d @ d), 0.0))
        d[0] = -tau if b[0] >= 0 else tau
        return E @ d
    hi = lo + float(np.linalg.norm(b)) / radius + shift
    lo = lo + shift
    for _ in range(100):                 # size(lam) decreases from > radius (lo) to <= radius (hi)
        mid = np.sqrt(lo * hi) if lo > 0 else 0.5 * hi
        if size(mid) > radius:
            lo = mid
        else:
            hi = mid
        if hi - lo <= 1e-12 * hi:
            break
    return E @ (-b / (w + hi))


def _chord_project(problem: FactorProblem, x: NDArray, fac: _Factored, n_rows: int,
                   max_iter: int = 6) -> tuple[NDArray, bool]:
    """The retraction by the chord method: Gauss-Newton corrections with the factored Jacobian
    of the base point (``n_rows`` residual rows, the tangent rows' right-hand side 0); falls back
    to :func:`project` when it stalls."""
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
        if not nn < 0.5 * nc:
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


def newton(problem: FactorProblem, x: NDArray, *, max_iter: int = 100, gtol: float = 1e-10,
           truncate: float = 1e-5, expired: Callable[[], bool] | None = None,
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
        Hz = Z.T @ problem.hess(x, mu) @ Z
        dx = Z @ _reduced_step(Hz, gz, radius)
        ndx = float(np.linalg.norm(dx))
        slope = float(grad @ dx)
        if -slope <= 16.0 * _EPS * max(1.0, abs(f)):  # the predicted decrease is rounding
            x, f = _polish(problem, x)
            return NewtonReport(x, True, it, f, gz_norm, mu, "converged (decrease at rounding level)",
                                truncated, problem)
        # merit: the Lagrangian -- insensitive to first order to the retraction's tolerance in
        # the normal directions (f alone is not: its gradient is mostly normal)
        merit = f + float(mu @ problem.c(x))
        alpha = 1.0
        accepted = False
        while alpha > 1e-8:
            xn, ok = _chord_project(problem, x + alpha * dx, fac, J.shape[0])
            if ok:
                fn = problem.f(xn)
                if fn + float(mu @ problem.c(xn)) <= merit + 1e-4 * alpha * slope:
                    accepted = True
                    break
            alpha *= 0.5
        if log is not None:
            log.append((f, gz_norm, alpha if accepted else 0.0, problem.rank))
        if not accepted:
            reason = "no decrease along the Newton direction"
            break
        radius = max(radius, 2.0 * ndx) if alpha == 1.0 else max(alpha * ndx, 1e-8 * radius)
        x, f = xn, fn
    return NewtonReport(x, False, it + 1, f, gz_norm, mu, reason, truncated, problem)


def _filter_accepts(filt: list, theta: float, f: float) -> bool:
    """Not dominated by a filter entry ``(theta_j, f_j)`` (the margins are in the entries)."""
    return all(theta < tj or f < fj for tj, fj in filt)


def sqp(problem: FactorProblem, x: NDArray, *, max_iter: int = 100, feas_rel: float = 1e-6,
        truncate: float = 1e-5, expired: Callable[[], bool] | None = None,
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
    theta_max = 1e4 * max(1.0, theta0)
    filt: list[tuple[float, float]] = [(theta_max, -np.inf)]
    g_th, g_f = 1e-5, 1e-5
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
            Hz = Z.T @ H @ Z
            dx = dn + Z @ _reduced_step(Hz, gz, max(np.sqrt(max(radius ** 2 - ndn ** 2, 0.0)), 0.1 * radius))
        ndx = float(np.linalg.norm(dx))
        m = float(grad @ dx)
        alpha = 1.0
        accepted = False
        while alpha > 1e-8:
            xn = problem.normalize(x + alpha * dx)
            th_n, f_n = float(np.linalg.norm(problem.c(xn))), problem.f(xn)
            if np.isfinite(th_n) and np.isfinite(f_n) and _filter_accepts(filt, th_n, f_n):
                switching = m < 0 and alpha * (-m) ** 2.3 > theta ** 1.1
                if switching and f_n <= f + 1e-4 * alpha * m:
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
        radius = max(radius, 2.0 * ndx) if alpha == 1.0 else max(alpha * ndx, 1e-8 * radius)
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
