r"""A normal observer closed loop with its poles in a region: a cheap certificate of ``kappa2 = 1``.

A real matrix ``F`` is normal iff ``F = U Lambda U^T`` with ``U`` orthogonal and ``Lambda`` block
diagonal with real scalars ``c`` and 2x2 blocks ``[[a, b], [-b, a]]`` (the pairs ``a +- i b``); a
normal matrix has an orthonormal eigenbasis, so the 2-norm condition number of its unit-column
eigenvector matrix is 1, the lower bound of kappa2 (Golub & Van Loan, *Matrix Computations*, 4th
ed., sec. 7.1.3 and 7.2.2).  ``F`` is an observer closed loop ``A - L C`` iff ``(F - A) V0 = 0`` for
an orthonormal basis ``V0`` of ``ker C``; then ``L = (A - F) C^+`` gives ``A - L C = F`` (``C^+ C`` is
the projector ``I - V0 V0^T`` onto the row space of a full-row-rank ``C``).

:func:`normal_closed_loop` solves for ``U`` in closed form and searches the rest: with ``M = U^T V0``
(orthonormal columns), ``F V0 = A V0`` reads ``U^T A V0 = Lambda M``, and an orthogonal ``U`` with
``U^T [V0, A V0] = [M, Lambda M]`` exists iff the two Gram matrices agree (two families of real vectors
with one Gram matrix differ by an orthogonal map), i.e. iff ``M^T Lambda M = V0^T A V0`` and
``M^T Lambda^T Lambda M = (A V0)^T (A V0)``; ``U`` is then the orthogonal Procrustes solution.  So the
unknowns are ``M`` (``M = qf(Y)``, ``Y`` free ``n x (n - p)``) and the eigenvalue parameters of one
block layout (all real, one pair, ...), and the residual is the two Gram equations and a hinge
``max(0, g_k + delta)`` on the region's smooth constraints ``g_k <= 0`` (``Region.constraints``), solved
by Levenberg-Marquardt from a few starts.  (For ``n - p = 1`` the Gram equations say that the point
``(v^T A v, ||A v||^2)`` is the mean of ``(Re lambda, |lambda|^2)`` under the weights ``|M_block|^2``.)
The manifold of normal closed loops has dimension ``n (n + 1) / 2 - n (n - p)``; when that is
negative the observer structure leaves no freedom for normality in general and the probe does not run.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..._validate import as_int, as_matrix, as_rng, as_square
from ...analysis import metrics
from ...engines.normal_search import normal_freedom, search_normal_closed_loop
from ...errors import DimensionError, ValidationError
from ...model.regions import Region
from ..verification import eigen_spread, kappa2_agreement_tol

__all__ = ["normal_closed_loop", "normal_freedom"]

_EPS = float(np.finfo(float).eps)


def normal_closed_loop(A: ArrayLike, C: ArrayLike, region: Region, *, starts: Sequence[ArrayLike] = (),
                       random_starts: int = 4, seed: object = 0, max_iter: int = 20,
                       full_output: bool = False
                       ) -> NDArray | None | tuple[NDArray | None, NDArray | None]:
    """An observer gain whose closed loop ``A - L C`` is normal with its poles in ``region``.

    A normal closed loop has ``kappa2 = 1`` (an orthonormal eigenbasis), the lower bound of the
    2-norm condition number of the unit-column eigenvector matrix: a gain found here is a global
    optimum of the well-conditioned region design.  The search is local (a few least-squares runs
    of a handful of parameters), so None does not prove that no such gain exists.

    Parameters
    ----------
    A : (n, n) array_like
    C : (p, n) array_like
        Full row rank.
    region : Region
        The pole region (``contains``, ``distance``, ``project``, ``sample_poles``).
    starts : sequence of (n, p) or (n, n) array_like, optional
        Gains ``L`` (their closed loops ``A - L C``) or closed-loop matrices, tried first in the
        order given: the real Schur vectors and the region-projected poles of each are one start.
    random_starts : int, default 4
        More starts: for each block layout of the poles (all real, one pair, ...) a random ``M``
        (normal ``Y``) and poles drawn from region samples (``region.sample_poles``), this many
        rounds.
    seed : None, int or numpy Generator, default 0
        Of the region samples.
    max_iter : int, default 20
        Levenberg-Marquardt iterations per start.
    full_output : bool, default False
        Also return the normal matrix of the start that came closest (the smallest residual), a
        start for the next, nearby problem (a continuation along a sweep).

    Returns
    -------
    (n, p) ndarray or None
        ``L = (A - F) C^+`` for the normal ``F`` found, verified independently: every pole of
        ``A - L C`` in ``region`` (``region.contains`` to the rounding of a normal matrix's
        eigenvalues, ``10 eps ||A - L C||_F``) and its kappa2 equal to 1 within the accuracy of a
        computed kappa2 (:func:`~optdesign.design.verification.kappa2_agreement_tol`).  None when
        no start reaches such a gain, and without a search when
        ``normal_freedom(n, p) < 0`` (more equations ``(F - A) ker C = 0`` than the ``n (n + 1) / 2``
        parameters of a normal matrix).
    (L or None, F) : tuple, with ``full_output``
        ``F`` the normal ``(n, n)`` matrix of the gain found, or of the start that came closest
        (None without a search).

    Raises
    ------
    DimensionError
        ``A`` not square, ``C`` not ``(p, n)`` with ``1 <= p <= n``, a start of the wrong shape.
    NotFiniteError
        NaN or Inf in ``A``, ``C`` or a start.
    ValidationError
        ``region`` not a Region; ``C`` rank deficient; ``random_starts`` or ``max_iter`` not an
        integer in range; a bad ``seed``.
    """
    A = as_square("A", A)
    n = A.shape[0]
    C = as_matrix("C", C)
    if C.shape[1] != n or not 1 <= C.shape[0] <= n:
        raise DimensionError(f"C must be (p, {n}) with 1 <= p <= {n}; found shape {C.shape}")
    p = C.shape[0]
    if not isinstance(region, Region):
        raise ValidationError(f"region must be an optdesign Region; found {type(region).__name__}")
    random_starts = as_int("random_starts", random_starts, 0)
    max_iter = as_int("max_iter", max_iter, 1)
    rng = as_rng("seed", seed)
    mats = []
    for k, S in enumerate(starts):
        S = as_matrix(f"starts[{k}]", S)
        if S.shape not in ((n, p), (n, n)):
            raise DimensionError(f"starts[{k}] must be a gain ({n}, {p}) or a closed loop ({n}, {n}); "
                                 f"found shape {S.shape}")
        mats.append(A - S @ C if S.shape == (n, p) else S)
    _, sv, Vt = np.linalg.svd(C)
    if sv[-1] <= n * _EPS * sv[0]:
        raise ValidationError(f"C must have full row rank {p}; found singular values {sv}")
    if normal_freedom(n, p) < 0:
        return (None, None) if full_output else None
    L, F = search_normal_closed_loop(A, C, Vt[p:].T, region, mats, random_starts, rng, max_iter,
                                     accept=lambda L: _verified(A - L @ C, region))
    return (L, F) if full_output else L


def _verified(X: NDArray, region: Region) -> bool:
    """Poles of ``X`` in ``region`` and ``kappa2(X) = 1`` to the accuracy of a computed kappa2."""
    ev = np.linalg.eigvals(X)
    if not region.contains(ev, tol=10.0 * _EPS * float(np.linalg.norm(X))):
        return False
    k2 = metrics.kappa2(X)
    return bool(math.isfinite(k2) and k2 <= 1.0 + kappa2_agreement_tol(1.0, eigen_spread(X, ev)))
