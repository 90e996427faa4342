"""Pole placement, the classical baselines.

``place_observer`` returns L with ``eig(A - L C) = poles`` using scipy's robust
Kautsky-Nichols-Van Dooren / Tits-Yang algorithm on the dual pair (A', C'); ``acker`` is
Ackermann's formula for a rank-one input matrix (the unique gain, also for repeated poles).
"""

from __future__ import annotations

import warnings

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._validate import as_matrix, as_poles, as_square
from ..errors import DimensionError, NotObservableError, ValidationError
from ..model.plant import Plant

__all__ = ["place_observer", "pole_error", "acker"]


def pole_error(achieved: ArrayLike, target: ArrayLike) -> float:
    """Largest relative distance between two pole sets under the matching that makes it smallest.

    ``min over matchings pi of max_i |achieved_i - target_pi(i)| / max(1, |target_pi(i)|)``: the
    smallest ``e`` such that every achieved pole lies within ``e`` (relative) of its own target
    pole (the bottleneck assignment).  It depends on neither set's order.

    The Hungarian matching of least *total* distance (``scipy.optimize.linear_sum_assignment``)
    gives this value when its largest distance is already a lower bound (each pole's nearest
    target, each target's nearest pole): always near a solution, the verification's case.  Far
    from one, matchings tie in total distance (real poles on a line) and the largest distance of
    the one it returns depended on the order of the poles: 0.456 or 0.572 for the same five poles
    of a discrete Kalman filter (round 14, tests/test_placement.py).  There a threshold search over
    the distances finds the bottleneck value (one assignment of 0/1 costs per step).
    """
    from scipy.optimize import linear_sum_assignment

    a = np.asarray(achieved, dtype=complex).ravel()
    t = np.asarray(target, dtype=complex).ravel()
    if a.shape != t.shape:
        raise DimensionError(f"pole sets differ in size: {a.size} achieved vs {t.size} target")
    if a.size == 0:
        return 0.0
    cost = np.abs(a[:, None] - t[None, :]) / np.maximum(1.0, np.abs(t))[None, :]
    r, c = linear_sum_assignment(cost)
    upper = float(np.max(cost[r, c]))
    lower = float(max(np.max(np.min(cost, axis=0)), np.max(np.min(cost, axis=1))))
    if upper <= lower:
        return upper
    levels = np.unique(cost[(cost >= lower) & (cost < upper)])
    lo, hi = 0, levels.size  # levels[hi] (upper when hi = size) admits a perfect matching
    while lo < hi:
        mid = (lo + hi) // 2
        over = (cost > levels[mid]).astype(float)
        r, c = linear_sum_assignment(over)
        if over[r, c].sum() == 0.0:
            hi = mid
        else:
            lo = mid + 1
    return float(levels[lo]) if lo < levels.size else upper


def place_observer(
    plant: Plant, poles: ArrayLike, *, method: str = "YT", rtol: float = 1e-6, maxiter: int = 100
) -> NDArray[np.float64]:
    """Observer gain with prescribed error-dynamics poles (scipy.signal.place_poles on the dual).

    Parameters
    ----------
    plant : Plant
        Uses A (n, n) and C (p, n).
    poles : (n,) array_like of complex
        Desired eigenvalues of ``A - L C``, a 1-D array (closed under conjugation; multiplicity at
        most ``rank(C)``; for a repeated pole with ``rank(C) = 1`` use :func:`acker` on the dual,
        ``acker(A', C', poles)'``).
    method : {"YT", "KNV0"}
        scipy's robust placement algorithm.

    Returns
    -------
    L : (n, p) ndarray

    Raises
    ------
    NotObservableError
        (C, A) unobservable (names the modes): the poles cannot all be placed.
    ValidationError
        A pole repeated more than ``rank(C)`` times (no diagonalizable A - LC exists).
    DimensionError
        ``poles`` not a 1-D array of n (a column (n, 1) is refused, not flattened).

    References
    ----------
    Kautsky, Nichols & Van Dooren (1985); Tits & Yang (1996); ``scipy.signal.place_poles``.
    """
    from scipy.signal import place_poles

    poles = as_poles("poles", poles, plant.n)   # 1-D only: a column (n, 1) is refused, not flattened
    plant.require_observable(what="pole placement")
    rank = np.linalg.matrix_rank(plant.C)
    vals, counts = np.unique(np.round(poles, 10), return_counts=True)
    if counts.max() > rank:
        raise ValidationError(
            f"pole {vals[np.argmax(counts)]} is repeated {counts.max()} times but C has rank {rank}: "
            "place_poles cannot assign a pole with multiplicity greater than rank(C)"
        )
    try:
        with warnings.catch_warnings():
            # YT stops at maxiter with a UserWarning; the gain still places the poles (callers verify
            # eig(A - L C)), and the warning says nothing the caller can act on.
            warnings.filterwarnings("ignore", message="Convergence was not reached", category=UserWarning)
            res = place_poles(plant.A.T, plant.C.T, poles, method=method, rtol=rtol, maxiter=maxiter)
    except (ValueError, np.linalg.LinAlgError) as exc:  # pragma: no cover - guarded above
        raise NotObservableError(f"pole placement failed: {exc}") from exc
    return np.asarray(res.gain_matrix, dtype=float).T


def acker(A: ArrayLike, B: ArrayLike, poles: ArrayLike) -> NDArray[np.float64]:
    """State-feedback gain of Ackermann's formula: ``eig(A - B K) = poles`` for ``rank(B) = 1``.

    With one input the gain is fixed by the poles (repeated ones included, where ``A - B K`` is then
    a single Jordan block per pole: defective, kappa2 infinite):
    ``K = e_n' [b, A b, ..., A^{n-1} b]^-1 phi(A)``, ``phi`` the monic polynomial of the poles.
    Computed on ``A / s`` and ``poles / s`` (``s = max(||A||_2, max |pole|)``, then ``K = K_s``
    scaled back: ``phi_s(A / s) = phi(A) / s^n``) so that the powers stay bounded.  A ``B`` with
    several proportional columns (``rank 1``, ``B = b g'``, ``||g|| = 1``) gets the minimum-norm
    ``K = g k'``.

    Parameters
    ----------
    A : (n, n) array_like
    B : (n, m) array_like
        Of rank one.
    poles : (n,) array_like of complex
        Conjugate-closed.

    Returns
    -------
    K : (m, n) ndarray

    Raises
    ------
    DimensionError
        Shapes do not match, or ``rank(B) != 1``.
    NotControllableError
        ``(A, B)`` is not controllable (the controllability matrix is numerically singular).

    References
    ----------
    Ackermann, J., "Der Entwurf linearer Regelungssysteme im Zustandsraum", Regelungstechnik 20
    (1972) 297-300; python-control ``acker``.

    Examples
    --------
    >>> acker([[0, 1], [0, 0]], [[0], [1]], [-1, -1]).tolist()
    [[1.0, 2.0]]
    """
    from ..errors import NotControllableError

    A = as_square("A", A)
    n = A.shape[0]
    B = as_matrix("B", B, (n, None))
    P = as_poles("poles", poles, n)
    U, sv, Vt = np.linalg.svd(B)
    rank = int(np.sum(sv > max(B.shape) * np.finfo(float).eps * (sv[0] if sv.size else 0.0)))
    if rank != 1:
        raise DimensionError(f"acker needs rank(B) = 1; found rank(B) = {rank}")
    b, g = U[:, 0] * sv[0], Vt[0]
    s = max(float(np.linalg.norm(A, 2)), float(np.max(np.abs(P))), 1e-300)
    As = A / s
    coef = np.real(np.poly(P / s))
    ctrb = np.empty((n, n))
    ctrb[:, 0] = b
    for k in range(1, n):
        ctrb[:, k] = As @ ctrb[:, k - 1]
    phi = np.zeros((n, n))
    for c in coef:  # Horner: phi(As)
        phi = phi @ As + c * np.eye(n)
    sv_c = np.linalg.svd(ctrb, compute_uv=False)
    if not sv_c[-1] > n * np.finfo(float).eps * sv_c[0]:
        raise NotControllableError(
            f"(A, B) is not controllable: the controllability matrix has condition number "
            f"{sv_c[0] / sv_c[-1] if sv_c[-1] > 0 else float('inf'):.3g}; Ackermann's formula needs it invertible",
            modes=np.array([], dtype=complex))
    en = np.zeros(n)
    en[-1] = 1.0
    krow = np.linalg.solve(ctrb.T, en) @ phi * s  # K_s = e_n' ctrb_s^-1 phi_s(A_s); K = s K_s
    return np.outer(g, krow)
