r"""Dense BFGS with a weak Wolfe line search, for smooth *and* nonsmooth objectives, on a batch of starts.

The eigenstructure engine (:mod:`optdesign.engines.eigenstructure`) minimizes ``log kappa2`` of
an eigenvector matrix, a function that is smooth almost everywhere but not where the largest
or the smallest singular value is multiple -- which is typical at a minimizer.  BFGS with a
*weak* Wolfe line search (Armijo decrease and a curvature condition on the directional
derivative only, found by bracketing and bisection) is the method Lewis & Overton (2013)
found effective on such functions: it does not need the gradient to vanish, and it converges
(typically linearly) to nonsmooth local minimizers.  On smooth objectives it is ordinary BFGS.

Several starts run in lockstep (:func:`bfgs_minimize_batch`): every round evaluates the trial
points of all running starts in one call, so the objective can stack their matrices and call
LAPACK once -- on the small matrices of pole placement numpy's per-call overhead dominates.
Each start keeps its own inverse-Hessian approximation and line search and stops on its own.
No Hessian is ever formed: one evaluation is one value and one gradient (measured in issue 13:
an exact Lagrangian Hessian of the CasADi formulation cost 50-390x a gradient).

Why ours and not scipy's (issue 29; ``benchmarks/bench_quasi_newton.py``,
``benchmarks/results/quasi_newton.md``): on the placement objective, through the engine's
continuation, from the same starts with the same stopping rule, on the 29 benchmark placement
problems and 14 random plants (n = 5..10), this method in lockstep took 5.05 s of CPU in all
against 12.79 s for ``scipy.optimize.minimize(method="BFGS")`` (2.53x) and 14.91 s for
``"L-BFGS-B"`` (2.95x), at the same best kappa2 (all within 1e-4 relative on every problem).  The
lockstep accounts for 2.08x (one start at a time: 10.51 s); the rest is a cheaper iteration (137 us
against scipy BFGS's 227 us per evaluation of the same objective), although scipy BFGS needs
fewer evaluations (0.73x ours).  L-BFGS-B was faster on 2 of the 43 problems (0.79x, 0.85x).

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
from scipy.linalg import blas

from .._deadline import Deadline
from .tolerances import ARMIJO_C1, QN_FTOL, QN_XTOL, WOLFE_C2

__all__ = ["QNResult", "bfgs_minimize", "bfgs_minimize_batch"]

#: a batched objective: ``X (k, m) -> (f (k,), G (k, m))`` (or ``(X, index)`` with ``pass_index``);
#: ``f[i] = inf`` outside the domain
BatchObjective = Callable[..., tuple[NDArray[np.float64], NDArray[np.float64]]]
#: an objective of one point: ``x -> (f, g)``
Objective = Callable[[NDArray[np.float64]], tuple[float, NDArray[np.float64] | None]]

#: doublings of the step allowed while the curvature condition fails (beyond: take the step)
_MAX_EXPAND = 12
#: evaluations allowed in one line search
_MAX_LINE = 40


@dataclass(frozen=True)
class QNResult:
    """The end point of one start.

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
    decrease : float
        Relative decrease of ``f`` over the last ``window`` iterations (or since the start, if
        fewer), ``(f_{k - window} - f) / max(1, |f|)``: what the ``ftol`` test compares.
    """

    x: NDArray[np.float64]
    f: float
    g: NDArray[np.float64]
    iterations: int
    evaluations: int
    reason: str
    decrease: float = float("nan")


class _Member:
    """The state of one start: its BFGS iterate and its current weak Wolfe line search."""

    __slots__ = ("x", "f", "g", "H", "scaled", "d", "gd", "dn", "t", "lo", "hi", "ls", "up",
                 "at_lo", "it", "nev", "hist", "reason", "leg_it", "leg_nev", "leg_f", "first_stop",
                 "pending")

    def __init__(self, x: NDArray, f: float, g: NDArray, H0: NDArray | None) -> None:
        self.x, self.f, self.g = x, f, g
        # symmetric, stored (and updated by BLAS) in its upper triangle, Fortran order
        self.H = np.eye(x.size, order="F") if H0 is None else np.array(H0, dtype=float, order="F")
        self.scaled = H0 is not None
        self.it, self.nev, self.hist, self.reason = 0, 1, [f], ""
        # the current leg (since the start or the last restart): its iterations, evaluations and
        # starting value; the value at the end of the first leg (None: not restarted); whether the
        # point awaits its evaluation after a restart
        self.leg_it, self.leg_nev, self.leg_f = 0, 1, f
        self.first_stop: float | None = None
        self.pending = False
        self.d = g
        self.gd = self.dn = 0.0
        self.t, self.lo, self.hi, self.ls, self.up = 1.0, 0.0, math.inf, 0, 0
        self.at_lo: tuple[NDArray, float, NDArray] | None = None

    def new_direction(self) -> bool:
        """Start a line search along ``-H g`` (``-g`` if that is not a descent direction)."""
        d = blas.dsymv(-1.0, self.H, self.g)
        gd = float(self.g @ d)
        if not gd < 0.0:
            self.H = np.eye(self.x.size, order="F")
            self.scaled = False
            d = -self.g
            gd = float(self.g @ d)
            if not gd < 0.0:
                return False
        self.d, self.gd = d, gd
        self.dn = math.sqrt(float(d @ d)) / (1.0 + math.sqrt(float(self.x @ self.x)))
        self.t, self.lo, self.hi, self.ls, self.up, self.at_lo = 1.0, 0.0, math.inf, 0, 0, None
        return True

    def trial(self) -> NDArray:
        return self.x + self.t * self.d

    def step(self, xt: NDArray, ft: float, gt: NDArray, c1: float, c2: float, xtol: float) -> str:
        """Advance the line search with the value at the trial point: ``"accept"``, ``"continue"``
        or ``"fail"``."""
        self.nev += 1
        self.leg_nev += 1
        self.ls += 1
        if not math.isfinite(ft) or ft > self.f + c1 * self.t * self.gd:
            self.hi = self.t
        elif float(gt @ self.d) < c2 * self.gd:
            self.lo, self.at_lo = self.t, (xt, ft, gt)
            if math.isinf(self.hi):
                self.up += 1
                if self.up > _MAX_EXPAND:  # f keeps decreasing linearly (a flat direction): take it
                    return "accept"
        else:
            self.at_lo = (xt, ft, gt)
            return "accept"
        self.t = 2.0 * self.lo if math.isinf(self.hi) else 0.5 * (self.lo + self.hi)
        if self.ls >= _MAX_LINE or (self.lo == 0.0 and self.hi * self.dn <= xtol):
            return "fail"
        return "continue"

    def accept(self) -> None:
        """Take the accepted trial point and update the inverse-Hessian approximation."""
        assert self.at_lo is not None
        xn, fn, gn = self.at_lo
        s, y = xn - self.x, gn - self.g
        sy = float(s @ y)
        if sy > 0.0:
            if not self.scaled:
                self.H = (sy / float(y @ y)) * np.eye(self.x.size, order="F")
                self.scaled = True
            # H+ = H + c s s' - (h s' + s h'), h = H y / sy, c = (1 + y'h) / sy; in place on the upper
            # triangle (BLAS dsyr / dsyr2: O(m^2) without temporaries, the cost that matters for
            # m = n p in the hundreds)
            h = blas.dsymv(1.0 / sy, self.H, y)
            c = (1.0 + float(y @ h)) / sy
            self.H = blas.dsyr(c, s, a=self.H, overwrite_a=1)
            self.H = blas.dsyr2(-1.0, h, s, a=self.H, overwrite_a=1)
        self.x, self.f, self.g = xn, fn, gn
        self.it += 1
        self.leg_it += 1
        self.hist.append(fn)

    def restarted(self, f: float, g: NDArray) -> None:
        """Begin a new leg at the same point with its value and gradient in the caller's new
        coordinates: as a fresh call from here with the same inverse-Hessian approximation (the
        decrease window starts again; the approximation counts as scaled)."""
        self.f, self.g, self.pending, self.reason = f, g, False, ""
        self.nev += 1
        self.leg_it, self.leg_nev, self.leg_f, self.hist, self.scaled = 0, 1, f, [f], True


def bfgs_minimize_batch(
    fun: BatchObjective,
    X0: NDArray[np.float64],
    *,
    max_iter: int = 500,
    max_eval: int = 5000,
    ftol: float = QN_FTOL,
    gtol: float = 0.0,
    window: int = 8,
    deadline: Deadline | None = None,
    H0: list[NDArray[np.float64] | None] | None = None,
    c1: float = ARMIJO_C1,
    c2: float = WOLFE_C2,
    xtol: float = QN_XTOL,
    pass_index: bool = False,
    keep: int = 0,
    keep_margin: float = 0.0,
    keep_horizon: float = 0.0,
    restart: Callable[[int, NDArray[np.float64], float, float], bool] | None = None,
    first_legs: Callable[[NDArray[np.float64]], bool] | None = None,
) -> tuple[list[QNResult], list[NDArray[np.float64]]]:
    """Minimize ``fun`` from every row of ``X0`` by BFGS with a weak Wolfe line search, in lockstep.

    Parameters
    ----------
    fun : callable
        ``X (k, m) -> (f (k,), G (k, m))``; ``f[i] = inf`` marks a point outside the domain.
    X0 : (s, m) ndarray
        Starts (all with finite values).
    max_iter, max_eval : int
        Budgets of steps and evaluations, per start.
    ftol : float
        Relative decrease of ``f`` over ``window`` iterations below which a start stops.
    gtol : float
        Stop when ``||g||_inf <= gtol`` (0: never; the default for nonsmooth functions).
    window : int
        Iterations over which the decrease is measured.
    deadline : Deadline, optional
        Checked once per round; on expiry every running start stops (``"time_limit"``).
    H0 : list of (m, m) ndarray or None, optional
        Initial inverse-Hessian approximations (default: scaled identity after the first step);
        only their upper triangles are read.
    c1, c2 : float
        Wolfe constants, ``0 < c1 < c2 < 1``.
    xtol : float
        A line search gives up when its bracket ``t ||d|| / (1 + ||x||)`` is below ``xtol``.
    pass_index : bool
        Call ``fun(X, index)`` with the rows of ``X0`` that ``X`` holds (objectives with state per
        start, such as the anchored bases of the region mode).
    keep : int
        A caller that goes on with only the ``keep`` starts of lowest value (0: all): once ``keep``
        starts have stopped, a running start whose value exceeds the ``keep``-th lowest value of
        the stopped ones by more than ``keep_margin`` (relative to ``max(1, |value|)``) stops,
        ``"pruned"`` -- its value only decreases, but it is already worse than ``keep`` finished
        starts (the stragglers that set a lockstep batch's rounds, region mode's second stage).
    keep_horizon : float
        With ``keep``: a running start is pruned only when it would still be above that bar after
        ``keep_horizon`` more windows at its current rate (its decrease over the last ``window``
        iterations); 0: its value alone decides.  A start still descending fast goes on.
    restart : callable, optional
        ``restart(i, x, f_leg, f) -> bool``, called when start ``i``'s line search fails at ``x``
        (value ``f``; ``f_leg`` the value its current leg began with).  True: the caller has changed
        the coordinates of the objective for that start (the region mode's re-anchoring at a chart's
        edge, which leaves ``x`` the same point); the start is evaluated there again and goes on in
        the same batch as if called afresh with its inverse-Hessian approximation -- a new leg, with
        ``max_iter`` and ``max_eval`` per leg -- instead of waiting for every other start to stop.
        A restarted start is never pruned by ``keep``, and counts for ``keep`` with its value at the
        end of its first leg (as in a batch called again for the restarted starts alone).
    first_legs : callable, optional
        With ``restart``: ``first_legs(X) -> bool``, called once, when every start has ended its
        first leg (stopped or restarted), with every start's point ``X`` (s, m); True ends the batch
        there (the running starts end at their points, ``"line search"``) -- where a batch called
        again for the restarted starts alone would not be called (the region mode's global optimum
        found).

    Returns
    -------
    results : list of QNResult
        One per start, never worse than the start.
    H : list of (m, m) ndarray
        The final inverse-Hessian approximations (to continue a related minimization; symmetric,
        only the upper triangle is maintained -- pass them back as ``H0`` as they are).

    Raises
    ------
    ValueError
        A start without a finite value (a caller bug: starts are checked before); ``keep`` or
        ``keep_horizon`` negative.
    """
    if keep < 0:
        raise ValueError(f"bfgs_minimize_batch: keep must be >= 0 (0: keep every start); found {keep}")
    if not keep_horizon >= 0:
        raise ValueError("bfgs_minimize_batch: keep_horizon must be >= 0 (0: the value alone); "
                         f"found {keep_horizon}")
    X0 = np.atleast_2d(np.asarray(X0, dtype=float))
    f0, G0 = fun(X0, np.arange(X0.shape[0])) if pass_index else fun(X0)
    if not np.all(np.isfinite(f0)):
        raise ValueError("bfgs_minimize_batch: the objective is not finite at a start")
    H0 = H0 if H0 is not None else [None] * X0.shape[0]
    mem = [_Member(X0[i].copy(), float(f0[i]), G0[i].copy(), H0[i]) for i in range(X0.shape[0])]
    index = {id(m): i for i, m in enumerate(mem)}
    running = []
    for m in mem:
        if gtol > 0 and float(np.max(np.abs(m.g))) <= gtol:
            m.reason = "converged"
        elif m.new_direction():
            running.append(m)
        else:
            m.reason = "converged"
    while running:
        if deadline is not None and deadline.expired:
            for m in running:
                m.reason = "time_limit"
            break
        T = np.stack([m.x if m.pending else m.trial() for m in running])
        fT, GT = fun(T, np.array([index[id(m)] for m in running])) if pass_index else fun(T)
        still = []
        for i, m in enumerate(running):
            if m.pending:  # a restarted start at its point, in the caller's new coordinates
                m.restarted(float(fT[i]), GT[i].copy())
                if not math.isfinite(m.f):
                    m.reason = "line search"
                elif (gtol > 0 and float(np.max(np.abs(m.g))) <= gtol) or not m.new_direction():
                    m.reason = "converged"
                else:
                    still.append(m)
                continue
            what = m.step(T[i].copy(), float(fT[i]), GT[i].copy(), c1, c2, xtol)
            if what == "continue" and m.leg_nev < max_eval:
                still.append(m)
                continue
            if what != "accept":
                m.reason = "max_eval" if m.leg_nev >= max_eval else "line search"
                if m.at_lo is not None:  # an Armijo step was found on the way: keep it
                    m.accept()
                if m.reason == "line search" and restart is not None \
                        and restart(index[id(m)], m.x, m.leg_f, m.f):
                    m.first_stop = m.f if m.first_stop is None else m.first_stop
                    m.pending, m.reason = True, ""
                    still.append(m)
                continue
            m.accept()
            if len(m.hist) > window and m.hist[-1 - window] - m.f <= ftol * max(1.0, abs(m.f)):
                m.reason = "converged"
            elif gtol > 0 and float(np.max(np.abs(m.g))) <= gtol:
                m.reason = "converged"
            elif m.leg_it >= max_iter:
                m.reason = "max_iter"
            elif m.leg_nev >= max_eval:
                m.reason = "max_eval"
            elif not m.new_direction():
                m.reason = "converged"
            else:
                still.append(m)
        if keep and still:
            stopped = sorted(m.f if m.first_stop is None else m.first_stop
                             for m in mem if m.reason or m.first_stop is not None)
            if len(stopped) >= keep:
                bar = stopped[keep - 1] + keep_margin * max(1.0, abs(stopped[keep - 1]))
                for m in still:
                    if m.first_stop is None and m.f - keep_horizon * _decrease_abs(m.hist, m.f, window) > bar:
                        m.reason = "pruned"
                still = [m for m in still if not m.reason]
        if first_legs is not None and all(m.reason or m.first_stop is not None for m in mem):
            if first_legs(np.stack([m.x for m in mem])):
                for m in still:
                    m.reason, m.pending = "line search", False
                still = []
            first_legs = None
        running = still
    return [QNResult(m.x, m.f, m.g, m.it, m.nev, m.reason, _decrease(m.hist, m.f, window)) for m in mem], \
        [m.H for m in mem]


def _decrease_abs(hist: list[float], f: float, window: int) -> float:
    """Decrease of ``f`` over the last ``window`` accepted iterations (or all of them)."""
    return float(hist[-1 - min(window, len(hist) - 1)] - f) if len(hist) > 1 else 0.0


def _decrease(hist: list[float], f: float, window: int) -> float:
    """Relative decrease of ``f`` over the last ``window`` accepted iterations (or all of them)."""
    return _decrease_abs(hist, f, window) / max(1.0, abs(f))


def bfgs_minimize(
    fun: Objective,
    x0: NDArray[np.float64],
    **options,
) -> tuple[QNResult, NDArray[np.float64]]:
    """:func:`bfgs_minimize_batch` for one start and an objective of one point ``x -> (f, g)``.

    Parameters
    ----------
    fun : callable
        ``x -> (f, g)``; ``f = inf`` outside the domain.
    x0 : (m,) ndarray
    **options
        Those of :func:`bfgs_minimize_batch` (``H0`` a single matrix or None).

    Returns
    -------
    QNResult, (m, m) ndarray

    Raises
    ------
    ValueError
        ``fun(x0)`` is not finite.
    """

    def batch(X):
        f, g = fun(X[0])
        return np.array([f]), np.zeros((1, X.shape[1])) if g is None else g[None, :]

    H0 = options.pop("H0", None)
    res, H = bfgs_minimize_batch(batch, np.asarray(x0, dtype=float)[None, :], H0=[H0], **options)
    return res[0], H[0]
