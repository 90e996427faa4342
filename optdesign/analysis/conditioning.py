r"""Conditioning of the Lyapunov and Riccati equations: how accurately a computed solution is
known, from the data and the solution itself.

The linearization of the filter Riccati equation at its stabilizing solution P is a Lyapunov
operator of the error dynamics ``F = A - L C``:

* continuous: :math:`\Omega(Z) = F Z + Z F^T`,
* discrete: :math:`\Omega(Z) = Z - F Z F^T`.

A computed ``P`` with residual ``Res(P)`` is then off the exact solution by the Newton
correction ``E = -Omega^{-1}(Res(P))`` to first order, and the residual itself can only be
evaluated to ``~ n eps`` times the size of its terms, which ``||Omega^{-1}||`` amplifies.
:func:`rounding_response` estimates that amplification for perturbations of rounding size and
sign pattern (:func:`lyapunov_inverse_norm`: the norm-wise worst case, pessimistic for badly
scaled data), and :func:`optdesign.classical.riccati.filter_are_error` combines the two: an
*a posteriori* forward error estimate that follows the answer at hand -- a solver that loses
digits on a badly scaled problem shows a large residual and a large estimate, whatever the CPU --
instead of a bound tuned to one machine.

References
----------
Kenney, C., Laub, A. J. & Wette, M., "A stability-enhancing scaling procedure for Schur-Riccati
solvers", Systems & Control Letters 12 (1989) 241-250 (the Newton correction as error estimate).
Higham, N. J., *Accuracy and Stability of Numerical Algorithms*, 2nd ed., SIAM (2002), ch. 16
(Sylvester / Lyapunov equations: ``sep`` and its estimation).
Sun, J.-G., "Perturbation theory for algebraic Riccati equations", SIAM J. Matrix Anal. Appl.
19 (1998) 39-65.
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import numpy as np
import scipy.linalg
from numpy.typing import NDArray

__all__ = ["lyapunov_solve", "rounding_response", "sampled_response", "lyapunov_inverse_norm"]


def lyapunov_solve(F: NDArray, rhs: NDArray, discrete: bool, *, adjoint: bool = False) -> NDArray:
    """``Omega^{-1}(rhs)`` (or ``Omega^{-*}`` with ``adjoint``) for the Lyapunov operator of F.

    Parameters
    ----------
    F : (n, n) ndarray
        The error dynamics (stable: Hurwitz, or Schur in discrete time).
    rhs : (n, n) ndarray
    discrete : bool
        ``Omega(Z) = Z - F Z F'`` (True) or ``F Z + Z F'`` (False).
    adjoint : bool
        Solve with the adjoint operator (``F`` replaced by ``F'``).

    Returns
    -------
    (n, n) ndarray
    """
    Fo = F.T if adjoint else F
    if discrete:
        return scipy.linalg.solve_discrete_lyapunov(Fo, rhs)   # Z - Fo Z Fo' = rhs
    return scipy.linalg.solve_continuous_lyapunov(Fo, rhs)     # Fo Z + Z Fo' = rhs


def rounding_response(F: NDArray, magnitude: NDArray, discrete: bool, *, samples: int = 2,
                      seed: int = 0) -> float:
    """How much rounding at the level ``magnitude`` moves the solution of ``Omega(Z) = rhs``:
    ``max_k ||Omega^{-1}(magnitude o S_k)||_F`` over ``samples`` seeded random symmetric sign
    patterns ``S_k`` (a small-sample statistical estimate, Kenney & Laub 1994).

    Rounding perturbs each entry of the equation's terms by about ``n eps`` times its size, with
    no preferred sign; the response of the solution to such a perturbation is what a computed
    solution cannot be trusted beyond.  Unlike the norm-wise bound ``||Omega^{-1}|| ||magnitude||``
    it is not fooled by bad scaling (CAREX 1.6, 2.9; DAREX 2.3: 1e-6 .. 5e-3 norm-wise, 1e-14 ..
    3e-13 here, where the solutions are in fact accurate to 1e-14 .. 1e-11).

    Parameters
    ----------
    F : (n, n) ndarray
        Stable error dynamics.
    magnitude : (n, n) ndarray
        Entrywise rounding level (>= 0, symmetric).
    discrete : bool
    samples : int
    seed : int

    Returns
    -------
    float
        ``inf`` when F is not stable or a solve fails.

    References
    ----------
    Kenney, C. S. & Laub, A. J., "Small-sample statistical condition estimates for general matrix
    functions", SIAM J. Sci. Comput. 15 (1994) 36-61.
    """
    F = np.asarray(F, dtype=float)
    n = F.shape[0]
    if n == 0:
        return 0.0
    lam = np.linalg.eigvals(F)
    if (np.max(np.abs(lam)) >= 1.0) if discrete else (np.max(lam.real) >= 0.0):
        return float("inf")
    return sampled_response(lambda rhs: lyapunov_solve(F, rhs, discrete), magnitude, samples=samples,
                            seed=seed)


@functools.lru_cache(maxsize=128)
def _sign_patterns(n: int, samples: int, seed: int) -> tuple[NDArray, ...]:
    """The seeded symmetric sign patterns of :func:`sampled_response` (drawn once per size; read-only)."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(samples):
        S = rng.choice([-1.0, 1.0], size=(n, n))
        S = np.triu(S) + np.triu(S, 1).T
        S.flags.writeable = False
        out.append(S)
    return tuple(out)


def sampled_response(solve: Callable[[NDArray], NDArray], magnitude: NDArray, *, samples: int = 2,
                     seed: int = 0) -> float:
    """``max_k ||solve(magnitude o S_k)||_F`` over ``samples`` seeded random symmetric sign patterns
    ``S_k`` (``magnitude``: (n, n)): the sampling of :func:`rounding_response` for any solver of the
    operator equation (e.g. one that re-uses a Schur form); ``inf`` when a solve fails or is not
    finite."""
    worst = 0.0
    with np.errstate(all="ignore"):
        for S in _sign_patterns(magnitude.shape[0], max(1, int(samples)), int(seed)):
            try:
                nz = float(np.linalg.norm(solve(magnitude * S)))
            except (np.linalg.LinAlgError, ValueError):
                return float("inf")
            if not np.isfinite(nz):
                return float("inf")
            worst = max(worst, nz)
    return worst


def lyapunov_inverse_norm(F: NDArray, discrete: bool, *, iterations: int = 2, seed: int = 0) -> float:
    """Estimate of ``||Omega^{-1}||`` (Frobenius operator norm; ``1 / sep`` of F and ``-F'``).

    Power iteration on ``Omega^{-*} Omega^{-1}`` from a seeded random symmetric matrix: a lower
    bound that is usually within a small factor after two iterations (Higham 2002, sec. 16.4).
    ``inf`` when F is not stable or a solve fails.

    Parameters
    ----------
    F : (n, n) ndarray
    discrete : bool
    iterations : int
    seed : int

    Returns
    -------
    float
    """
    F = np.asarray(F, dtype=float)
    n = F.shape[0]
    if n == 0:
        return 0.0
    lam = np.linalg.eigvals(F)
    if (np.max(np.abs(lam)) >= 1.0) if discrete else (np.max(lam.real) >= 0.0):
        return float("inf")
    rng = np.random.default_rng(seed)
    Z = rng.standard_normal((n, n))
    Z = Z + Z.T
    Z /= np.linalg.norm(Z)
    est = 0.0
    with np.errstate(all="ignore"):
        try:
            for _ in range(max(1, iterations)):
                Y = lyapunov_solve(F, Z, discrete)
                W = lyapunov_solve(F, Y, discrete, adjoint=True)
                nw = float(np.linalg.norm(W))
                if not np.isfinite(nw) or nw == 0.0:
                    return float("inf") if not np.isfinite(nw) else est
                est = max(est, float(np.sqrt(nw)), float(np.linalg.norm(Y)))
                Z = W / nw
        except (np.linalg.LinAlgError, ValueError):
            return float("inf")
    return est
