r"""Frequency-domain search machinery shared by the robustness analyses: the points ``s = j w`` /
``z = exp(j w dt)`` of a frequency, a grid seeded at the poles of a loop, and an adaptive minimizer
(grid, then bounded Brent refinement of the lowest local minima) that honours a time budget.

Used by :mod:`optdesign.analysis.robustness` (circle condition, margins) and by the output-delay
filter.  Frequencies are in rad/s; in discrete time the Nyquist frequency is ``pi / dt``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Literal, overload

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._deadline import Deadline
from .._validate import as_int, as_matrix, as_positive_float, as_vector
from ..errors import ValidationError
from ..model.plant import Plant

__all__ = ["as_gain", "frequency_points", "frequency_grid", "nudge_off_poles", "adaptive_minimize", "CHUNK",
           "return_difference_floor"]

#: frequencies evaluated per vectorized call while a time budget runs (checked between chunks)
CHUNK = 128

_CLUSTER = np.array([-16.0, -8, -4, -2, -1, -0.5, -0.25, 0, 0.25, 0.5, 1, 2, 4, 8, 16])


def as_gain(plant: Plant, L: ArrayLike) -> NDArray[np.float64]:
    """Check ``plant`` is a :class:`~optdesign.Plant` and return the filter gain ``L`` as an (n, p) matrix.

    Raises
    ------
    ValidationError
        ``plant`` is not a Plant.
    DimensionError, NotFiniteError
        ``L`` is not a finite (n, p) matrix.
    """
    if not isinstance(plant, Plant):
        raise ValidationError(f"plant must be an optdesign.Plant; found {type(plant).__name__}")
    return as_matrix("L", L, (plant.n, plant.p))


def frequency_points(plant: Plant, omega: NDArray[np.float64]) -> NDArray[np.complex128]:
    """``s = j w`` (continuous) or ``z = exp(j w dt)`` (discrete) for frequencies ``w`` in rad/s."""
    dt = plant.dt
    if dt is not None:
        return np.exp(1j * omega * dt)
    return 1j * omega  # type: ignore[return-value]  # stubs: float64 array * 1j is typed complexfloating[Any]


def frequency_grid(
    plant: Plant,
    L: ArrayLike | None = None,
    *,
    points_per_decade: int = 30,
    extra_poles: ArrayLike | None = None,
) -> NDArray[np.float64]:
    """Frequency grid (rad/s) seeded at the open- and closed-loop pole frequencies.

    Continuous time: a log grid from ``1e-3`` times the smallest to ``1e3`` times the largest
    pole modulus, ``w = 0``, and around every complex pole ``lambda`` a cluster
    ``|Im lambda| + |Re lambda| * t`` (``|t| <= 16``) that resolves a dip or peak of width
    ``|Re lambda|`` however lightly damped.  Discrete time: a uniform grid of ``[0, pi/dt]``, a log
    grid near 0, and clusters ``|arg z| + (1 - |z|) t`` around the poles.

    Parameters
    ----------
    plant : Plant
    L : (n, p) array_like, optional
        If given, the poles of ``A - L C`` seed the grid too.
    points_per_decade : int
        Density of the base log grid, an integer ``>= 1`` (at least 4 are used).
    extra_poles : (k,) array_like of complex, optional
        More seeds (e.g. the poles of a perturbed loop).

    Returns
    -------
    (k,) ndarray, sorted, nonnegative (within ``[0, pi/dt]`` in discrete time).

    Raises
    ------
    ValidationError
        ``plant`` not a Plant, ``points_per_decade`` not an integer ``>= 1``, ``extra_poles`` not
        numeric.
    DimensionError, NotFiniteError
        ``L`` or ``extra_poles`` malformed.
    """
    if not isinstance(plant, Plant):
        raise ValidationError(f"plant must be an optdesign.Plant; found {type(plant).__name__}")
    ppd = max(4, as_int("points_per_decade", points_per_decade, 1))
    poles = [np.linalg.eigvals(plant.A)]
    if L is not None:
        Lm = as_gain(plant, L)
        poles.append(np.linalg.eigvals(plant.A - Lm @ plant.C))
    if extra_poles is not None:
        poles.append(as_vector("extra_poles", extra_poles, allow_complex=True).astype(complex))
    lam = np.concatenate(poles)
    if plant.is_discrete:
        dt = plant.dt
        theta = [np.linspace(0.0, np.pi, 24 * ppd), np.pi * np.logspace(-6, 0, 6 * ppd)]
        for z in lam:
            if abs(z) < 1e-12:
                continue
            c = abs(np.angle(z))
            width = max(abs(1.0 - abs(z)), 1e-9)
            theta.append(c + width * _CLUSTER)
        th = np.concatenate(theta)
        th = th[(th >= 0.0) & (th <= np.pi)]
        return np.unique(np.concatenate([th, [0.0, np.pi]])) / dt
    mags = np.abs(lam)
    mags = mags[mags > 1e-12 * max(1.0, float(np.max(mags, initial=0.0)))]
    lo, hi = (float(np.min(mags)), float(np.max(mags))) if mags.size else (1.0, 1.0)
    lo, hi = math.log10(lo) - 3.0, math.log10(hi) + 3.0
    parts: list[ArrayLike] = [np.logspace(lo, hi, int(np.ceil((hi - lo) * ppd)) + 1), [0.0]]
    for z in lam:
        if abs(z.imag) > 0:
            parts.append(abs(z.imag) + max(abs(z.real), 1e-12 * abs(z)) * _CLUSTER)
        if abs(z) > 0:
            parts.append([abs(z)])
    w = np.concatenate(parts)
    return np.unique(w[w >= 0.0])


def nudge_off_poles(
    w: NDArray, pts_of: Callable[[NDArray], NDArray], poles: NDArray, scale: float
) -> NDArray:
    """Move frequencies off the open-loop poles on the stability boundary (T is infinite there)."""
    if poles.size == 0 or w.size == 0:
        return w
    w = w.copy()
    for _ in range(3):
        d = np.min(np.abs(pts_of(w)[:, None] - poles[None, :]), axis=1)
        bad = d < 1e-9 * scale
        if not np.any(bad):
            break
        w[bad] = w[bad] + 1e-7 * scale
    return w


def _evaluate(f: Callable[[NDArray], NDArray], grid: NDArray, deadline: Deadline) -> NDArray:
    """``f(grid)``; under a time budget in chunks of :data:`CHUNK`, stopping when it has expired (the
    result is then shorter than ``grid``; the first chunk is always evaluated)."""
    if not deadline.limited:
        return np.asarray(f(grid), dtype=float)
    out = []
    for i in range(0, grid.size, CHUNK):
        if i and deadline.expired:
            break
        out.append(np.asarray(f(grid[i:i + CHUNK]), dtype=float))
    return np.concatenate(out) if out else np.zeros(0)


@overload
def adaptive_minimize(
    f: Callable[[NDArray[np.float64]], NDArray[np.float64]], grid: NDArray[np.float64], *,
    n_refine: int = ..., log: bool = ..., xatol: float = ..., values: NDArray[np.float64] | None = ...,
    deadline: Deadline | float | None = ..., full_output: Literal[False] = ...,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]: ...
@overload
def adaptive_minimize(
    f: Callable[[NDArray[np.float64]], NDArray[np.float64]], grid: NDArray[np.float64], *,
    n_refine: int = ..., log: bool = ..., xatol: float = ..., values: NDArray[np.float64] | None = ...,
    deadline: Deadline | float | None = ..., full_output: Literal[True],
) -> tuple[NDArray[np.float64], NDArray[np.float64], bool]: ...
def adaptive_minimize(
    f: Callable[[NDArray[np.float64]], NDArray[np.float64]],
    grid: NDArray[np.float64],
    *,
    n_refine: int = 8,
    log: bool = True,
    xatol: float = 1e-10,
    values: NDArray[np.float64] | None = None,
    deadline: Deadline | float | None = None,
    full_output: bool = False,
) -> tuple[NDArray[np.float64], NDArray[np.float64]] | tuple[NDArray[np.float64], NDArray[np.float64], bool]:
    """Minimize a function of frequency: grid evaluation, then local bounded refinement.

    ``f`` maps a vector of frequencies to a vector of values.  After evaluating the grid, the
    ``n_refine`` lowest local minima are each refined by bounded Brent minimization
    (``scipy.optimize.minimize_scalar``) between their grid neighbours, in ``log w`` when
    ``log`` and the bracket is positive.  ``values`` may give ``f(grid)`` if already known
    (``grid`` must then be sorted and unique).

    Parameters
    ----------
    f : callable
    grid : (k,) array_like
    n_refine : int
        Number of local minima refined (``>= 0``).
    log : bool
    xatol : float
        Absolute tolerance of the refinement (in ``log w`` when ``log``), ``> 0``.
    values : (k,) array_like, optional
    deadline : Deadline or float, optional
        Time budget (a :class:`~optdesign._deadline.Deadline` shared with the caller, or seconds).
        Once it has expired, no further chunk of :data:`CHUNK` grid points is evaluated (the first
        always is) and no further minimum refined; what was evaluated is returned.
    full_output : bool
        Also return whether the search completed (the whole grid evaluated and every chosen
        minimum refined) before the budget ran out.

    Returns
    -------
    omega, values : (k,) ndarrays
        Every evaluated point (grid and refinement), sorted by frequency.
    complete : bool
        Only with ``full_output``.

    Raises
    ------
    ValidationError
        ``n_refine`` not an integer ``>= 0``, ``xatol`` not ``> 0``, a bad ``deadline``.
    """
    from scipy.optimize import minimize_scalar

    n_refine = as_int("n_refine", n_refine, 0)
    xatol = as_positive_float("xatol", xatol)
    dl = Deadline.of(deadline)
    if values is None:
        grid = np.unique(np.asarray(grid, dtype=float))
        vals = _evaluate(f, grid, dl)
        complete = vals.size == grid.size
        grid = grid[: vals.size]
    else:
        grid = np.asarray(grid, dtype=float)
        vals = np.asarray(values, dtype=float)
        complete = True
    k = grid.size
    left = np.concatenate([[np.inf], vals[:-1]])
    right = np.concatenate([vals[1:], [np.inf]])
    cand = np.flatnonzero((vals <= left) & (vals <= right))
    cand = cand[np.argsort(vals[cand])][:n_refine]
    xs, ys = [grid], [vals]
    for i in cand:
        if dl.expired:
            complete = False
            break
        a, b = grid[max(int(i) - 1, 0)], grid[min(int(i) + 1, k - 1)]
        if not b > a:
            continue
        use_log = log and a > 0
        if use_log:
            g = lambda x: float(f(np.array([math.exp(x)]))[0])  # noqa: E731
            lo, hi, tol = math.log(a), math.log(b), xatol
        else:
            g = lambda x: float(f(np.array([x]))[0])  # noqa: E731
            lo, hi, tol = a, b, xatol * max(b, 1e-300)
        res = minimize_scalar(g, bounds=(lo, hi), method="bounded", options={"xatol": tol, "maxiter": 200})
        x = math.exp(res.x) if use_log else float(res.x)
        xs.append(np.array([x]))
        ys.append(np.array([float(res.fun)]))
    w = np.concatenate(xs)
    v = np.concatenate(ys)
    order = np.argsort(w, kind="stable")
    if full_output:
        return w[order], v[order], complete
    return w[order], v[order]


def return_difference_floor(plant: Plant, L: NDArray, V: NDArray, R: NDArray, omega: float) -> float:
    r"""The rounding floor of ``lambda_min(T V T^* - R)`` at one frequency (absolute).

    ``T = I + C X`` with ``X = (s I - A)^-1 L`` from a backward-stable LU solve, whose forward
    error is at most ``eps cond_1(sI - A) ||X||`` (Higham, *Accuracy and Stability of Numerical
    Algorithms*, 2nd ed., Thm 7.2); so ``||dT|| <= eps ||C|| cond(sI - A) ||X||``, and the
    Hermitian form ``T V T^* - R`` is known to ``2 ||T|| ||V|| ||dT|| + p eps (||T||^2 ||V|| +
    ||R||)`` (Weyl: its eigenvalues move by at most that).  A violation smaller than this is
    rounding, not evidence (issue 26: ``-8e-5`` against ``||T R T^*|| = 6.7e11`` called a true
    Kalman gain "infeasible").

    Parameters
    ----------
    plant : Plant
    L : (n, p) ndarray
    V, R : (p, p) ndarrays
        The weights of ``T V T^* >= R`` (continuous: ``V = R``).
    omega : float
        Frequency (rad/s).

    Returns
    -------
    float
        The floor (``inf`` where ``sI - A`` is singular to working precision).
    """
    import scipy.linalg as sla

    eps = float(np.finfo(float).eps)
    n, p = plant.n, plant.p
    s = complex(frequency_points(plant, np.array([float(omega)]))[0])
    M = s * np.eye(n) - plant.A
    try:
        lu, piv = sla.lu_factor(M, check_finite=False)
        X = sla.lu_solve((lu, piv), L.astype(complex), check_finite=False)
        rcond = float(sla.lapack.zgecon(lu, float(np.linalg.norm(M, 1)), norm="1")[0])
    except (np.linalg.LinAlgError, ValueError):
        return math.inf
    if not (rcond > 0.0 and np.all(np.isfinite(X))):
        return math.inf
    T = np.eye(p) + plant.C @ X
    nT, nV, nR = (float(np.linalg.norm(T, 2)), float(np.linalg.norm(V, 2)), float(np.linalg.norm(R, 2)))
    dT = eps * float(np.linalg.norm(plant.C, 2)) * float(np.linalg.norm(X, 2)) / rcond
    return 2.0 * nT * nV * dT + p * eps * (nT * nT * nV + nR)
