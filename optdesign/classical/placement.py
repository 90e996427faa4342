"""Observer pole placement (duality with state feedback): the classical baseline.

``place_observer`` returns L with ``eig(A - L C) = poles`` using scipy's robust
Kautsky-Nichols-Van Dooren / Tits-Yang algorithm on the dual pair (A', C').
"""

from __future__ import annotations

import warnings

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._validate import as_poles
from ..errors import DimensionError, NotObservableError, ValidationError
from ..model.plant import Plant

__all__ = ["place_observer", "pole_error"]


def pole_error(achieved: ArrayLike, target: ArrayLike) -> float:
    """Largest relative distance between two pole sets after optimal matching.

    ``max_i |achieved_i - target_pi(i)| / max(1, |target_pi(i)|)`` with the matching pi
    found by the Hungarian algorithm (robust to ordering and near-conjugate ties).
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
    return float(np.max(cost[r, c]))


def place_observer(
    plant: Plant, poles: ArrayLike, *, method: str = "YT", rtol: float = 1e-6, maxiter: int = 100
) -> NDArray[np.float64]:
    """Observer gain with prescribed error-dynamics poles (scipy.signal.place_poles on the dual).

    Parameters
    ----------
    plant : Plant
        Uses A (n, n) and C (p, n).
    poles : (n,) array_like of complex
        Desired eigenvalues of ``A - L C`` (closed under conjugation; multiplicity at most p).
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

    References
    ----------
    Kautsky, Nichols & Van Dooren (1985); Tits & Yang (1996); ``scipy.signal.place_poles``.
    """
    from scipy.signal import place_poles

    poles = as_poles("poles", poles, plant.n)
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
