r"""Small linear-algebra building blocks shared by every layer above (one definition each).

* :func:`sym` -- the symmetric part ``(X + X') / 2`` of a square matrix (numpy arrays, and any
  object with ``+``, ``*`` and ``.T``, such as a cvxpy or CasADi expression);
* :func:`commutation` -- the commutation matrix ``K_{k,r}`` with ``vec(V') = K vec(V)``.

References
----------
J. R. Magnus and H. Neudecker, "The commutation matrix: some properties and applications",
Ann. Statist. 7 (1979) 381-394.
"""

from __future__ import annotations

from typing import TypeVar

import numpy as np
from numpy.typing import NDArray

__all__ = ["sym", "commutation"]

_M = TypeVar("_M")


def sym(X: _M) -> _M:
    """The symmetric part ``0.5 (X + X')`` of a square matrix.

    Parameters
    ----------
    X : (n, n) ndarray or matrix expression
        Anything with ``.T``, ``+`` and scalar ``*`` (numpy, cvxpy, CasADi).

    Returns
    -------
    (n, n) same type as ``X``
        Exactly symmetric for a float array (``X + X'`` rounds the same both ways).
    """
    return 0.5 * (X + X.T)  # type: ignore[attr-defined]


def commutation(k: int, r: int) -> NDArray[np.float64]:
    """The commutation matrix: ``K`` with ``vec(V') = K vec(V)`` for a ``(k, r)`` matrix ``V``.

    ``vec`` stacks columns (Fortran order): ``vec(V)[j k + i] = V[i, j]``.

    Parameters
    ----------
    k, r : int
        Shape of ``V``.

    Returns
    -------
    (k r, k r) ndarray
        A permutation matrix.

    Examples
    --------
    >>> V = np.arange(6.0).reshape(2, 3)
    >>> bool(np.array_equal(commutation(2, 3) @ V.ravel(order="F"), V.T.ravel(order="F")))
    True
    """
    K = np.zeros((k * r, k * r))
    i, j = np.meshgrid(np.arange(k), np.arange(r), indexing="ij")
    K[(i * r + j).ravel(), (j * k + i).ravel()] = 1.0
    return K
