r"""A dense BFGS method with a weak Wolfe line search, for smooth *and* nonsmooth objectives.

The eigenstructure engine (:mod:`optdesign.solvers.eigenstructure`) minimizes ``log kappa2`` of
an eigenvector matrix, a function that is smooth almost everywhere but not where the largest
or the smallest singular value is multiple -- which is typical at a minimizer.  BFGS with a
*weak* Wolfe line search (Armijo decrease and a curvature condition on the directional
derivative only, found by bracketing and bisection) is the method Lewis & Overton (2013)
found effective on such functions: it does not need the gradient to vanish, and it converges
(typically linearly) to nonsmooth local minimizers.  On smooth objectives it is ordinary BFGS.

No Hessian is ever formed: one evaluation is one function value and one gradient, both from
the same factorizations (measured in issue 13: an exact Lagrangian Hessian of the CasADi
formulation cost 50-390x a gradient).

Stopping rules (first met wins), each reported in :attr:`QNResult.reason`:

* ``"converged"``: the relative decrease of ``f`` over the last ``window`` iterations is below
  ``ftol`` (nonsmooth functions: the gradient need not vanish), or ``||g||_inf <= gtol``;
* ``"line search"``: no step satisfying the Wolfe conditions was found (at a nonsmooth
  minimizer this is the normal end, Lewis & Overton section 6.2);
* ``"max_iter"`` / ``"max_eval"``: budget exhausted; ``"time_limit"``: the deadline expired.

References
----------
A. S. Lewis and M. L. Overton, "Nonsmooth optimization via quasi-Newton methods",
Math. Programming 141 (2013) 135-163.
J. Nocedal and S. J. Wright, Numerical Optimization, 2nd ed., Springer 2006, ch. 6.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from .._deadline import Deadline

__all__ = ["QNResult", "bfgs_minimize", "bfgs_minimize_batch", "weak_wolfe"]

#: an objective: ``x -> (f, g)``; ``f = inf`` (any g) marks a point outside the domain
Objective = Callable[[NDArray[np.float64]], tuple[float, NDArray[np.float64] | None]]
#: a batched objective: ``X (k, m) -> (f (k,), G (k, m))``; ``f[i] = inf`` outside the domain
BatchObjective = Callable[[NDArray[np.float64]], tuple[NDArray[np.float64], NDArray[np.float64]]]


@dataclass(frozen=True)
class QNResult:
    """The end point of :func:`bfgs_minimize`.

    Attributes
    ----------
    x : (m,) ndarray
        Best point found (never worse than the start).
    f : float
        ``f(x)``.
    g : (m,) ndarray
        Gradient at ``x``.
    iterations : int
        Accepted BFGS steps.
    evaluations : int
        Objective evaluations (the start included).
    reason : str
        Why it stopped (see the module docstring).
    """

    x: NDArray[np.float64]
    f: float
    g: NDArray[np.float64]
    iterations: int
    evaluations: int
    reason: str


def weak_wolfe(
    fun: Objective,
    x: NDArray[np.float64],
    f: float,
    g: NDArray[np.float64],
    d: NDArray[np.float64],
    *,
    c1: float = 1e-4,
    c2: float = 0.9,
    max_eval: int = 40,
    xtol: float = 1e-10,
) -> tuple[float, NDArray[np.float64], float, NDArray[np.float64] | None, int, bool]:
    """Weak Wolfe line search by bracketing (doubling) and bisection (Lewis & Overton, Alg. 2.1).

    Parameters
    ----------
    fun : callable
        ``x -> (f, g)``.
    x, g : (m,) ndarray
        Current point and gradient; ``f`` its value.
    d : (m,) ndarray
        A descent direction (``g @ d < 0``).
    c1, c2 : float
        Armijo and curvature constants, ``0 < c1 < c2 < 1``.
    max_eval : int
        Evaluations allowed.
    xtol : float
        Give up when the bracket ``t ||d||`` is below ``xtol (1 + ||x||)`` (no meaningful step left).

    Returns
    -------
    t : float
        The last step tried.
    x_t : (m,) ndarray
        ``x + t d``.
    f_t, g_t : float, ndarray
        Value and gradient there.
    evaluations : int
    ok : bool
        Both conditions hold at ``t``.
    """
    lo, hi, t = 0.0, math.inf, 1.0
    gd = float(g @ d)
    dn, xn = float(np.linalg.norm(d)), 1.0 + float(np.linalg.norm(x))
    xt, ft, gt = x, f, g
    for k in range(1, max_eval + 1):
        xt = x + t * d
        ft, gt = fun(xt)
        if not math.isfinite(ft) or ft > f + c1 * t * gd:
            hi = t
        elif gt is not None and float(gt @ d) < c2 * gd:
            lo = t
        else:
            return t, xt, ft, gt, k, True
        t = 2.0 * lo if math.isinf(hi) else 0.5 * (lo + hi)
        if lo == 0.0 and hi * dn <= xtol * xn:
            return t, xt, ft, gt, k, False
    return t, xt, ft, gt, max_eval, False


def bfgs_minimize(
    fun: Objective,
    x0: NDArray[np.float64],
    *,
    max_iter: int = 500,
    max_eval: int = 5000,
    ftol: float = 1e-10,
    gtol: float = 0.0,
    window: int = 8,
    deadline: Deadline | None = None,
    H0: NDArray[np.float64] | None = None,
) -> tuple[QNResult, NDArray[np.float64]]:
    """Minimize ``fun`` by dense BFGS with a weak Wolfe line search.

    Parameters
    ----------
    fun : callable
        ``x -> (f, g)`` (a float and an (m,) gradient); ``f = inf`` outside the domain.
    x0 : (m,) ndarray
        Start (must have a finite value).
    max_iter, max_eval : int
        Budgets of steps and evaluations.
    ftol : float
        Relative decrease of ``f`` over ``window`` iterations below which it stops.
    gtol : float
        Stop when ``||g||_inf <= gtol`` (0: never; the nonsmooth default).
    window : int
        Iterations over which the decrease is measured.
    deadline : Deadline, optional
        Checked once per iteration.
    H0 : (m, m) ndarray, optional
        Initial inverse-Hessian approximation (default: scaled identity after the first step).

    Returns
    -------
    QNResult
        The best point (never worse than ``x0``).
    H : (m, m) ndarray
        The final inverse-Hessian approximation (to continue a related minimization).

    Raises
    ------
    ValueError
        ``fun(x0)`` is not finite (a caller bug: starts are checked before).
    """
    x = np.array(x0, dtype=float)
    f, g = fun(x)
    if not math.isfinite(f) or g is None:
        raise ValueError(f"bfgs_minimize: the objective is not finite at the start ({f!r})")
    m = x.size
    H = np.eye(m) if H0 is None else np.array(H0, dtype=float)
    scaled = H0 is not None
    nev, it, reason = 1, 0, "max_iter"
    hist = [f]
    while it < max_iter:
        if deadline is not None and deadline.expired:
            reason = "time_limit"
            break
        if gtol > 0 and float(np.max(np.abs(g))) <= gtol:
            reason = "converged"
            break
        d = -(H @ g)
        if not float(g @ d) < 0.0:  # lost positive definiteness (rounding): restart
            H = np.eye(m)
            scaled = False
            d = -g
            if not float(g @ d) < 0.0:
                reason = "converged"  # zero gradient
                break
        t, xn, fn, gn, k, ok = weak_wolfe(fun, x, f, g, d, max_eval=min(40, max_eval - nev))
        nev += k
        if not ok:
            if math.isfinite(fn) and fn < f and gn is not None:
                x, f, g = xn, fn, gn
                it += 1
            reason = "line search"
            break
        s = xn - x
        y = gn - g
        sy = float(s @ y)
        if sy > 0.0:
            if not scaled:
                H = (sy / float(y @ y)) * np.eye(m)
                scaled = True
            rho = 1.0 / sy
            Hy = H @ y
            H += (rho * rho * float(y @ Hy) + rho) * np.outer(s, s) - rho * (np.outer(s, Hy) + np.outer(Hy, s))
        x, f, g = xn, fn, gn
        it += 1
        hist.append(f)
        if len(hist) > window and hist[-1 - window] - f <= ftol * max(1.0, abs(f)):
            reason = "converged"
            break
        if nev >= max_eval:
            reason = "max_eval"
            break
    return QNResult(x, float(f), g, it, nev, reason), H


class _Member:
    """The state of one member of :func:`bfgs_minimize_batch` (a BFGS run and its line search)."""

    __slots__ = ("x", "f", "g", "H", "scaled", "d", "gd", "dn", "t", "lo", "hi", "ls", "it", "nev", "hist", "reason")

    def __init__(self, x: NDArray, f: float, g: NDArray, H0: NDArray | None) -> None:
        self.x, self.f, self.g = x, f, g
        self.H = np.eye(x.size) if H0 is None else np.array(H0, dtype=float)
        self.scaled = H0 is not None
        self.it, self.nev, self.hist, self.reason = 0, 1, [f], ""
        self.d = self.g
        self.gd, self.dn, self.t, self.lo, self.hi, self.ls = 0.0, 0.0, 1.0, 0.0, math.inf, 0

    def new_direction(self) -> bool:
        """Start a line search along ``-H g``; False when the gradient is zero."""
        d = -(self.H @ self.g)
        gd = float(self.g @ d)
        if not gd < 0.0:
            self.H = np.eye(self.x.size)
            self.scaled = False
            d = -self.g
            gd = float(self.g @ d)
            if not gd < 0.0:
                return False
        self.d, self.gd = d, gd
        self.dn = float(np.linalg.norm(d)) / (1.0 + float(np.linalg.norm(self.x)))
        self.t, self.lo, self.hi, self.ls = 1.0, 0.0, math.inf, 0
        return True

    def accept(self, xn: NDArray, fn: float, gn: NDArray) -> None:
        s, y = xn - self.x, gn - self.g
        sy = float(s @ y)
        if sy > 0.0:
            if not self.scaled:
                self.H = (sy / float(y @ y)) * np.eye(self.x.size)
                self.scaled = True
            rho = 1.0 / sy
            Hy = self.H @ y
            self.H += (rho * rho * float(y @ Hy) + rho) * np.outer(s, s) - rho * (
                np.outer(s, Hy) + np.outer(Hy, s)
            )
        self.x, self.f, self.g = xn, fn, gn
        self.it += 1
        self.hist.append(fn)


def bfgs_minimize_batch(
    fun: BatchObjective,
    X0: NDArray[np.float64],
    *,
    max_iter: int = 500,
    max_eval: int = 5000,
    ftol: float = 1e-10,
    window: int = 8,
    deadline: Deadline | None = None,
    H0: list[NDArray[np.float64] | None] | None = None,
    c1: float = 1e-4,
    c2: float = 0.9,
    xtol: float = 1e-10,
) -> tuple[list[QNResult], list[NDArray[np.float64]]]:
    """:func:`bfgs_minimize` on several starts in lockstep, one batched evaluation per round.

    Every round evaluates the trial points of all members still running in *one* call of
    ``fun`` (which can stack the members' matrices and call LAPACK once per factorization:
    on the small matrices of pole placement the per-call overhead of numpy dominates, so ``k``
    starts cost much less than ``k`` times one).  Each member runs its own BFGS and weak Wolfe
    line search (the same rules as :func:`bfgs_minimize` and :func:`weak_wolfe`) and stops on
    its own.

    Parameters
    ----------
    fun : callable
        ``X (k, m) -> (f (k,), G (k, m))``.
    X0 : (s, m) ndarray
        Starts (all with finite values).
    max_iter, max_eval, ftol, window, deadline
        As :func:`bfgs_minimize`, per member (the deadline for all).
    H0 : list of (m, m) ndarray or None, optional
        Initial inverse-Hessian approximations per member.
    c1, c2 : float
        Wolfe constants.
    xtol : float
        Relative step below which a line search gives up (:func:`weak_wolfe`).

    Returns
    -------
    results : list of QNResult
    H : list of (m, m) ndarray

    Raises
    ------
    ValueError
        A start without a finite value.
    """
    X0 = np.atleast_2d(np.asarray(X0, dtype=float))
    f0, G0 = fun(X0)
    if not np.all(np.isfinite(f0)):
        raise ValueError("bfgs_minimize_batch: the objective is not finite at a start")
    H0 = H0 if H0 is not None else [None] * X0.shape[0]
    mem = [_Member(X0[i].copy(), float(f0[i]), G0[i].copy(), H0[i]) for i in range(X0.shape[0])]
    running = []
    for m in mem:
        if m.new_direction():
            running.append(m)
        else:
            m.reason = "converged"
    while running:
        if deadline is not None and deadline.expired:
            for m in running:
                m.reason = "time_limit"
            break
        T = np.stack([m.x + m.t * m.d for m in running])
        fT, GT = fun(T)
        still = []
        for i, m in enumerate(running):
            ft, gt = float(fT[i]), GT[i]
            m.nev += 1
            m.ls += 1
            ok = False
            if not math.isfinite(ft) or ft > m.f + c1 * m.t * m.gd:
                m.hi = m.t
            elif float(gt @ m.d) < c2 * m.gd:
                m.lo = m.t
            else:
                ok = True
            if not ok:
                m.t = 2.0 * m.lo if math.isinf(m.hi) else 0.5 * (m.lo + m.hi)
                if m.ls >= 40 or (m.lo == 0.0 and m.hi * m.dn <= xtol) or m.nev >= max_eval:
                    m.reason = "max_eval" if m.nev >= max_eval else "line search"
                    continue
                still.append(m)
                continue
            m.accept(T[i].copy(), ft, gt.copy())
            if len(m.hist) > window and m.hist[-1 - window] - m.f <= ftol * max(1.0, abs(m.f)):
                m.reason = "converged"
            elif m.it >= max_iter:
                m.reason = "max_iter"
            elif m.nev >= max_eval:
                m.reason = "max_eval"
            elif not m.new_direction():
                m.reason = "converged"
            else:
                still.append(m)
        running = still
    return [QNResult(m.x, m.f, m.g, m.it, m.nev, m.reason) for m in mem], [m.H for m in mem]
