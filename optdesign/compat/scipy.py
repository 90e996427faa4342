"""scipy's ``place_poles``, answered by optdesign: ``from optdesign.compat.scipy import place_poles``.

The call form, the result fields and their meanings, the errors and the warning of
:func:`scipy.signal.place_poles`; the gain minimizes ``cond(X)`` of the unit-column right
eigenvectors of ``A - B K`` (scipy's robustness measure) by optdesign's placement engine in
controller mode (:func:`optdesign.design.feedback.place`), scipy's YT and KNV0 placements among its
starts, and every answer is verified on ``A - B K`` (``result.verification``).

What differs, deliberately (``docs/guide/differences.rst``): ``X`` is the unit-column eigenvector
matrix of the answer rather than YT's iterate; ``rtol`` / ``nb_iter`` describe the engine's last
stage (see :func:`place_poles`); a pole repeated with a single input is placed (the gain is unique)
instead of refused.

References
----------
scipy.signal.place_poles (Tits & Yang 1996; Kautsky, Nichols & Van Dooren 1985).
"""

from __future__ import annotations

import math
import warnings
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from .._validate import as_int, as_str
from ..design.feedback import place
from ..design.feedback_controller import input_rank
from ..errors import SolverError

__all__ = ["place_poles", "PlacePolesResult"]


class PlacePolesResult:
    """scipy's ``Bunch`` of :func:`place_poles`: attribute access to its fields.

    Attributes
    ----------
    gain_matrix : (m, n) ndarray
        K with ``eig(A - B K) = requested_poles``.
    computed_poles : (n,) ndarray
        ``eig(A - B K)``, real poles increasing, then conjugate pairs in lexicographic order.
    requested_poles : (n,) ndarray
        The poles asked for, in the same order.
    X : (n, n) ndarray of complex
        ``(A - B K) X = X diag(computed_poles)``, unit-norm columns: its condition number is what the
        gain minimizes.
    rtol : float
        NaN when ``rank(B) = n`` and 0 when ``B`` has one column (nothing to optimize, as scipy);
        otherwise the relative decrease of ``log cond(X)`` over the last iterations of the engine's
        final stage (the quantity the tolerance ``rtol`` is compared with).
    nb_iter : int or float
        NaN when ``rank(B) = n``, 0 with one column (as scipy); otherwise the BFGS iterations of the
        engine's final stage for the returned gain (at most ``maxiter``).
    result : PlacementResult
        optdesign's full result (status, verification, route, the design).
    """

    _FIELDS = ("gain_matrix", "computed_poles", "requested_poles", "X", "rtol", "nb_iter")

    def __init__(self, **kwargs: Any) -> None:
        self.__dict__.update(kwargs)

    def keys(self) -> list[str]:
        return list(self._FIELDS)

    def __getitem__(self, key: str) -> Any:
        return self.__dict__[key]

    def __repr__(self) -> str:
        return "PlacePolesResult(" + ", ".join(f"{k}={self.__dict__[k]!r}" for k in self._FIELDS) + ")"


def place_poles(A: ArrayLike, B: ArrayLike, poles: ArrayLike, method: str = "YT", rtol: float = 1e-3,
                maxiter: int = 30) -> PlacePolesResult:
    """Compute K such that the eigenvalues of ``A - B K`` are ``poles``, with ``cond(X)`` minimal.

    scipy's signature, fields and errors (every error a ``ValueError``, also an
    :class:`~optdesign.errors.OptDesignError`); the answer is optdesign's
    (:func:`optdesign.design.feedback.place`): never worse in ``cond(X)`` than scipy's YT or KNV0
    (both are starts), verified on ``A - B K``.

    Parameters
    ----------
    A : (n, n) array_like
    B : (n, m) array_like
    poles : (n,) array_like
        1-D, conjugate-closed; a pole repeats at most ``rank(B)`` times (any number of times when
        ``rank(B) = 1``: the gain is then unique, ``A - B K`` defective).
    method : {"YT", "KNV0"}
        Accepted as scipy does (KNV0: real poles only); both are starts of the engine, which always
        runs.
    rtol : float
        ``<= 1``.  The engine's final stage stops when the relative decrease of ``log cond(X)`` over
        its last iterations is below ``min(rtol, 1e-9)`` (a looser ``rtol`` does not make the answer
        worse than the engine's own tolerance); ``<= 0`` runs the stage to ``maxiter``.
    maxiter : int
        ``>= 1``: BFGS iterations per stage of the engine.

    Returns
    -------
    PlacePolesResult

    Raises
    ------
    ValueError
        As scipy: bad method, poles not a 1-D array, A or B not 2-D or of wrong shapes, a wrong
        number of poles, poles not conjugate-closed, ``rtol > 1``, ``maxiter < 1``, a pole repeated
        more than ``rank(B) >= 2`` times, an uncontrollable ``(A, B)``, KNV0 with complex poles.
        Each is an optdesign error class that subclasses ``ValueError``.
    SolverError
        No verified gain was found (a ``RuntimeError``; scipy has no such case).

    Warns
    -----
    UserWarning
        "Convergence was not reached after maxiter iterations", as scipy, when the final stage hit
        ``maxiter`` before its decrease fell below ``rtol``; "Convergence was not reached to rtol"
        when it stopped earlier (no step decreases cond(X): a nonsmooth local minimum) above
        ``rtol`` -- then ``nb_iter < maxiter``, where scipy, which iterates until ``maxiter``,
        reports ``maxiter`` (``docs/guide/differences.rst``).

    Examples
    --------
    >>> import numpy as np, scipy.signal
    >>> A = np.array([[0, 7, 0, 0], [0, 0, 0, 7 / 3], [0, 0, 0, 0], [0, 0, 0, 0]])
    >>> B = np.array([[0, 0], [0, 0], [1, 0], [0, 1]])
    >>> fsf = place_poles(A, B, [-3, -1, -2 - 1j, -2 + 1j])
    >>> fsf.computed_poles.round(8).tolist()   # scipy's order: real poles, then pairs
    [(-3+0j), (-1+0j), (-2-1j), (-2+1j)]
    >>> bool(np.linalg.cond(fsf.X) <= np.linalg.cond(scipy.signal.place_poles(A, B, fsf.requested_poles).X))
    True
    """
    method = as_str("method", method, ("YT", "KNV0"))
    maxiter = as_int("maxiter", maxiter, 1)
    res = place(A, B, poles, method=method, rtol=rtol, maxiter=maxiter)
    if res.gain_matrix is None or not np.all(np.isfinite(res.gain_matrix)):
        raise SolverError(f"place_poles: no verified gain was found ({res.message})")
    Bm = np.asarray(B, dtype=float)
    n, rank = Bm.shape[0], input_rank(Bm)
    extra = res.extra
    cur_rtol: float
    nb_iter: float | int
    if rank == n:
        cur_rtol, nb_iter = math.nan, math.nan
    elif Bm.shape[1] == 1 or rank == 1:
        cur_rtol, nb_iter = 0.0, 0
    else:
        cur_rtol = float(extra.get("last_decrease", math.nan))
        nb_iter = int(extra.get("last_iterations", 0))
        if extra.get("stop_reason") == "max_iter" and not cur_rtol <= rtol:
            warnings.warn("Convergence was not reached after maxiter iterations.\n"
                          f"You asked for a tolerance of {float(rtol):f}, we got {cur_rtol:f}.",
                          UserWarning, stacklevel=2)
        elif not cur_rtol <= rtol:
            warnings.warn(f"Convergence was not reached to rtol = {float(rtol):g}: the engine stopped after "
                          f"{nb_iter} iterations of its last stage (fewer than maxiter = {maxiter}) where no step "
                          f"decreases cond(X) further (a nonsmooth local minimum); relative decrease "
                          f"{cur_rtol:.3g}.", UserWarning, stacklevel=2)
    if not res.success:
        warnings.warn(f"place_poles: the gain did not pass every check ({res.verification.summary()})",
                      UserWarning, stacklevel=2)
    return PlacePolesResult(gain_matrix=res.gain_matrix, computed_poles=res.computed_poles,
                            requested_poles=res.requested_poles, X=res.X, rtol=cur_rtol,
                            nb_iter=nb_iter, result=res)

