r"""Continuation in the target poles: a feasible point of the inverse Kalman problem where no start
of :mod:`optdesign.engines.inverse_kalman_engine` projects onto one (issue 26).

Why
---
With a large process noise (``Q ~ 1e3 F F'``) most Kalman poles sit next to the mirrored zeros of
the noise-to-output system and move little with Q: the residuals of the spectral conditions
(:mod:`optdesign.engines.spectral_factor`) have Jacobians of condition 1e9 .. 1e11 around the
solutions, and Gauss-Newton from a start whose poles are far off stalls at infeasible stationary
points (measured: every start of the engine, IPOPT from 7 starts).  But the Kalman poles of *any*
``Q0 = Gd V0 V0' Gd'`` are known exactly (scipy's Riccati solver), so ``V0`` is a feasible point of
the problem whose targets are those poles.

How
---
The targets move from the poles of ``Q0`` to the requested ones along a path of conjugate-closed,
stable pole sets (:func:`pole_path`): both sets are written as products of real quadratic factors
``s^2 + b s + c`` (a pair, or two real poles paired in sorted order; one linear factor when n is
odd), the factors matched by a linear assignment on ``(log b, log c)``, and the coefficients
interpolated geometrically -- every intermediate factor is stable (``b, c > 0``) with real
coefficients, so the poles stay conjugate-closed whether a pair splits into two real poles or two
real poles merge on the way (discrete time: the same in the bilinear image ``s = (z - 1)/(z + 1)``).
:func:`track` follows the solution with the engine's Gauss-Newton retraction
(:func:`~optdesign.engines.spectral_newton.project`: minimum-norm steps, the null vectors
re-initialized at each new target from the current Q), warm-started from the previous point, the
step in t doubled after a quick convergence and halved after a failure.  It works in the factor
``Q = Gd V V' Gd'`` of a fixed number of columns: a low rank (2, or p) tracks where the full rank
stalls (measured on the large-noise sweep: the full-rank factor reached t = 1 on 4 of 15 tracks,
rank 2 on 12, rank p on 11), as Q approaches the boundary of the PSD cone.

A local method: a path may end at a turning point (the step shrinks below its floor), and the point
reached at t = 1 is only a feasible point -- the engine's Newton then optimizes from it, and the
design layer verifies the result as any other.

References
----------
Allgower, E. L. & Georg, K., *Numerical Continuation Methods: An Introduction*, Springer (1990)
(predictor-corrector path following, steplength adaptation).  Anderson & Moore, *Optimal Filtering*
(1979) (the spectral factorization identity of the Kalman filter).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import linear_sum_assignment

from ..classical.placement import pole_error
from ..formulate.inverse_kalman import spectral_terms
from ..model.plant import Plant
from .inverse_kalman_starts import scipy_kalman
from .spectral_factor import FactorProblem, initial_null_vectors, spectral_blocks
from .spectral_newton import project
from .tolerances import EPS, HOMOTOPY_MIN_STEP, HOMOTOPY_ROUNDING, NORM_FLOOR, pole_tolerance

__all__ = ["pole_path", "track", "TrackReport", "pole_miss", "HOMOTOPY_FIRST_STEP", "HOMOTOPY_MAX_STEP",
           "HOMOTOPY_MIN_STEP", "HOMOTOPY_MAX_STEPS", "HOMOTOPY_FIRST_PASS"]

#: the first step in t and the largest (the smallest:
#: :data:`~optdesign.engines.tolerances.HOMOTOPY_MIN_STEP`)
HOMOTOPY_FIRST_STEP = 0.05
HOMOTOPY_MAX_STEP = 0.25
#: corrections per path (accepted or not); measured on the large-noise sweep: the tracks that reach
#: t = 1 take 16-288 (most under 60), those that do not mostly run into this limit
HOMOTOPY_MAX_STEPS = 300
#: corrections of every path before any is resumed (the engine's first pass over its starts)
HOMOTOPY_FIRST_PASS = 60
#: Gauss-Newton iterations per correction; a correction that converges within
#: :data:`_QUICK` of them doubles the step
_CORRECTIONS = 8
_QUICK = 3


def _quadratic_factors(z: NDArray) -> tuple[NDArray, NDArray]:
    """``(quads, lone)``: the coefficients ``(b, c)`` ((m, 2)) of the real quadratic factors
    ``s^2 + b s + c`` of the stable, conjugate-closed poles z (continuous time) -- the pairs, and
    the real poles paired in sorted order -- and the lone real pole (empty, or one: the most
    negative) when their number is odd."""
    tol = HOMOTOPY_ROUNDING * EPS * max(1.0, float(np.max(np.abs(z))))
    up = z[z.imag > tol]
    re = np.sort(z[np.abs(z.imag) <= tol].real)
    lone = re[:re.size % 2]
    re = re[re.size % 2:]
    quads = [(-2.0 * c.real, abs(c) ** 2) for c in up]
    quads += [(-(re[i] + re[i + 1]), re[i] * re[i + 1]) for i in range(0, re.size, 2)]
    return np.array(quads, dtype=float).reshape(-1, 2), lone


def _conjugate_sorted(z: NDArray, tol: float) -> NDArray[np.complex128]:
    """z with near-real values made real and each pair ``(a + jb, a - jb)`` adjacent, b > 0 first
    (the order of :func:`~optdesign.formulate.inverse_kalman.common.modal_blocks`)."""
    z = np.where(np.abs(z.imag) <= tol * np.maximum(1.0, np.abs(z)), z.real + 0j, z)
    out: list[complex] = []
    for v in sorted(z, key=lambda v: (v.real, -v.imag)):
        if v.imag > 0:
            out += [complex(v), complex(v.conjugate())]
        elif v.imag == 0:
            out.append(complex(v.real))
    return np.array(out, dtype=complex)


def pole_path(start: NDArray, target: NDArray, discrete: bool = False) -> Callable[[float], NDArray]:
    """The targets at ``t`` in [0, 1], from ``start`` (t = 0) to ``target`` (t = 1): stable and
    conjugate-closed all along (see the module docstring).

    Parameters
    ----------
    start, target : (n,) array_like of complex
        Stable (``Re < 0``; discrete: ``|z| < 1``), conjugate-closed pole sets of the same size.
    discrete : bool
        Interpolate in the bilinear image ``s = (z - 1) / (z + 1)`` of the unit disc.

    Returns
    -------
    callable
        ``t -> (n,) complex array`` (pairs adjacent, positive imaginary part first).
    """
    def to_s(z: NDArray) -> NDArray:
        z = np.asarray(z, dtype=complex)
        return (z - 1.0) / (z + 1.0) if discrete else z

    q0, l0 = _quadratic_factors(to_s(start))
    q1, l1 = _quadratic_factors(to_s(target))
    L0, L1 = np.log(q0), np.log(q1)
    r, c = linear_sum_assignment(np.sum((L0[:, None, :] - L1[None, :, :]) ** 2, axis=2))
    L0, L1 = L0[r], L1[c]
    lone0, lone1 = np.log(-l0), np.log(-l1)
    rtol = HOMOTOPY_ROUNDING * EPS

    def at(t: float) -> NDArray[np.complex128]:
        b, cc = np.exp((1.0 - t) * L0 + t * L1).T
        disc = np.sqrt((b * b - 4.0 * cc).astype(complex))
        # the root of larger modulus without cancellation, the other from the product c
        big = -0.5 * (b + disc)
        roots = np.concatenate([big, cc / big, -np.exp((1.0 - t) * lone0 + t * lone1) + 0j])
        z = (1.0 + roots) / (1.0 - roots) if discrete else roots
        return _conjugate_sorted(z, rtol)

    return at


@dataclass(frozen=True)
class TrackReport:
    """Outcome of :func:`track`.

    Attributes
    ----------
    V : (k, r) ndarray or None
        The factor at the last target reached, in physical units (``Qdec = V V'``).
    t : float
        How far along the path (1: the requested targets).
    steps : int
        Corrections tried (with those of the run it resumes).
    reason : str
    h : float
        The step in t it would try next (to resume it).
    resumable : bool
        It ran out of corrections (not into a turning point, nor out of time).
    """

    V: NDArray[np.float64] | None
    t: float
    steps: int
    reason: str
    h: float = HOMOTOPY_FIRST_STEP
    resumable: bool = False

    @property
    def reached(self) -> bool:
        return self.V is not None and self.t >= 1.0


def track(plant: Plant, Gd: NDArray, V0: NDArray, start: NDArray, target: NDArray, *,
          diagonal: bool = False, max_steps: int = HOMOTOPY_MAX_STEPS, t0: float = 0.0,
          h0: float = HOMOTOPY_FIRST_STEP, steps0: int = 0,
          expired: Callable[[], bool] | None = None) -> TrackReport:
    """Follow the factor V from ``V0`` (whose Kalman poles are ``start``) to the ``target`` poles.

    Parameters
    ----------
    plant : Plant
    Gd : (n, k) ndarray
        Noise input of the decision covariance (``Q = Gd V V' Gd'``).
    V0 : (k, r) ndarray
        The start's factor, physical units (diagonal: (k, k) diagonal).
    start : (n,) complex ndarray
        The Kalman poles of ``Gd V0 V0' Gd'``.
    target : (n,) complex ndarray
    diagonal : bool
        V diagonal (``Qdec = diag(v)^2``).
    max_steps : int
        Corrections at most.
    t0, h0, steps0 : float, float, int
        Where to resume a path (``V0`` its point at ``t0``; ``start`` its start's poles), its
        next step and its corrections so far (its ``t``, ``h``, ``steps``).
    expired : callable, optional
        Returns True when the caller's time is up.

    Returns
    -------
    TrackReport
    """
    A, C = plant.A, plant.C
    R = np.asarray(plant.R, dtype=float)
    at = pole_path(start, target, plant.is_discrete)
    t, h, V = float(t0), float(h0), np.array(V0, dtype=float)
    for step in range(steps0, steps0 + max_steps):
        if expired is not None and expired():
            return TrackReport(V, t, step, "time limit", h)
        tn = min(1.0, t + h)
        terms = spectral_terms(A, C, at(tn), plant.dt)
        ok, it = False, _CORRECTIONS
        if terms is not None:   # else a target on the way at an eigenvalue of A or its mirror
            scale = max(float(np.linalg.norm(V @ V.T, 2)), NORM_FLOOR)
            prob = FactorProblem(spectral_blocks(terms, R, Gd, scale), V.shape[1], "min_trace",
                                 diagonal=diagonal)
            Vs = V / np.sqrt(scale)
            x, ok, it = project(prob, prob.pack(Vs, 0.0, initial_null_vectors(prob.blocks, Vs @ Vs.T)),
                                max_iter=_CORRECTIONS)
        if ok:
            V = prob.unpack(x)[0] * np.sqrt(scale)
            t = tn
            if t >= 1.0:
                return TrackReport(V, t, step + 1, "reached the targets", h)
            h = min(HOMOTOPY_MAX_STEP, 2.0 * h if it <= _QUICK else h)
        else:
            h *= 0.5
            if h < HOMOTOPY_MIN_STEP:
                why = f"the step fell below {HOMOTOPY_MIN_STEP:g} at t = {t:.4g}"
                return TrackReport(V, t, step + 1, why, h)
    n = steps0 + max_steps
    return TrackReport(V, t, n, f"{n} corrections, at t = {t:.4g}", h, resumable=True)


def pole_miss(plant: Plant, L: NDArray, Q: NDArray, target: NDArray, tol: float,
              resolve: bool = True) -> float:
    """How far a design misses the targets, in units of the verification's pole tolerance
    (:func:`~optdesign.engines.tolerances.pole_tolerance`, as
    :func:`~optdesign.engines.inverse_kalman_result.verify_engine_design` sets it): the larger of the miss of ``eig(A - L C)`` and (``resolve``) of scipy's Kalman filter
    of Q -- above 1 the design fails that check; inf without a stabilizing Kalman filter or with
    non-finite values.  The rounding floor is computed only for a miss above ``tol`` (it only
    raises the tolerance): 0.04 ms for ``eig(A - L C)`` within ``tol`` at n = 12, 2 ms for the
    whole test with the re-solve.

    Parameters
    ----------
    plant : Plant
    L : (n, p) ndarray
    Q : (n, n) ndarray
    target : (n,) complex ndarray
    tol : float
        The pole accuracy asked for.
    resolve : bool
        Test scipy's Kalman filter of Q as well.
    """
    if not (np.all(np.isfinite(L)) and np.all(np.isfinite(Q))):
        return float("inf")
    gains = [L]
    if resolve:
        kal = scipy_kalman(plant, Q)
        if kal is None:
            return float("inf")
        gains.append(kal[0])
    out = 0.0
    for K in gains:
        F = plant.A - K @ plant.C
        err = pole_error(np.linalg.eigvals(F), target)
        if err > tol:
            out = max(out, err / pole_tolerance(F, tol))
    return out
