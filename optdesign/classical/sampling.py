"""Sampling a continuous-time process noise: Van Loan's matrix exponential.

``van_loan`` is used by :func:`optdesign.design.kalman.kalmd`, the output-delay Kalman filter
(:mod:`optdesign.design.output_delay`) and the noise estimation of continuous plants.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg
from numpy.typing import ArrayLike, NDArray

from .._validate import as_positive_float, as_square, check_psd

__all__ = ["van_loan"]


def van_loan(A: ArrayLike, W: ArrayLike, Ts: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    r"""``Ad = e^(A Ts)`` and ``Qd = int_0^Ts e^(A t) W e^(A' t) dt`` by one matrix exponential.

    ``expm([[-A, W], [0, A']] Ts) = [[., E12], [0, E22]]`` gives ``Ad = E22'`` and ``Qd = Ad E12``
    (Van Loan 1978, Theorem 1), symmetrized.

    Parameters
    ----------
    A : (n, n) array_like
    W : (n, n) array_like
        Symmetric PSD (``G Q G'``).
    Ts : float
        Sampling period, > 0.

    Returns
    -------
    Ad, Qd : (n, n) ndarray

    Raises
    ------
    ValidationError, DimensionError, NotFiniteError
        Bad ``Ts`` or matrices (named).

    References
    ----------
    Van Loan, C. F., IEEE TAC 23(3) (1978) 395-404.

    Examples
    --------
    >>> from optdesign import van_loan
    >>> Ad, Qd = van_loan([[0., 1.], [0., 0.]], [[0., 0.], [0., 1.]], 0.1)  # double integrator
    >>> Ad.tolist()
    [[1.0, 0.1], [0.0, 1.0]]
    >>> (Qd * 3e4).round(6).tolist()        # [[Ts^3/3, Ts^2/2], [Ts^2/2, Ts]], times 3e4
    [[10.0, 150.0], [150.0, 3000.0]]
    """
    A = as_square("A", A)
    n = A.shape[0]
    W = check_psd("W", as_square("W", W, n))
    Ts = as_positive_float("Ts", Ts)
    Mx = np.zeros((2 * n, 2 * n))
    Mx[:n, :n], Mx[:n, n:], Mx[n:, n:] = -A, W, A.T
    E = scipy.linalg.expm(Mx * Ts)
    Ad = E[n:, n:].T
    Qd = Ad @ E[:n, n:]
    return Ad, 0.5 * (Qd + Qd.T)
