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
import scipy.linalg
from numpy.typing import ArrayLike, NDArray

from ..._validate import as_int, as_matrix, as_rng
from ...analysis import metrics
from ...errors import DimensionError, ValidationError
from ...model.regions import Region
from ..verification import eigen_spread, kappa2_agreement_tol

__all__ = ["normal_closed_loop", "normal_freedom"]

_EPS = float(np.finfo(float).eps)


def normal_freedom(n: int, p: int) -> int:
    """``n (n + 1) / 2 - n (n - p)``: the dimension of the normal matrices ``A - L C`` (generically)
    -- orthogonal ``U`` and ``n`` eigenvalue parameters against the ``n (n - p)`` equations
    ``(F - A) V0 = 0``."""
    return n * (n + 1) // 2 - n * (n - p)


def _layouts(n: int) -> list[tuple[int, ...]]:
    """Block sizes (1: a real pole, 2: a complex pair) summing to ``n``, fewest pairs first."""
    out: set[tuple[int, ...]] = set()
    todo: list[tuple[int, ...]] = [()]
    while todo:
        t = todo.pop()
        if sum(t) == n:
            out.add(t)
        todo += [t + (s,) for s in (1, 2) if sum(t) + s <= n]
    return sorted(out, key=lambda t: (t.count(2), t))


def _blocks(layout: tuple[int, ...], lam: NDArray) -> tuple[NDArray, NDArray]:
    """``Lambda`` of a layout from its parameters and its poles (one per real, ``a + i |b|`` per pair)."""
    n = sum(layout)
    Lam = np.zeros((n, n))
    poles = np.empty(len(layout), complex)
    i = k = 0
    for j, s in enumerate(layout):
        if s == 1:
            Lam[i, i] = lam[k]
            poles[j] = lam[k]
        else:
            a, b = lam[k], lam[k + 1]
            Lam[i:i + 2, i:i + 2] = [[a, b], [-b, a]]
            poles[j] = complex(a, abs(b))
        i += s
        k += s
    return Lam, poles


def _start_from(X: NDArray | None, V0: NDArray, region: Region, layout: tuple[int, ...] | None,
                rng: np.random.Generator,
                samples: dict[int, NDArray]) -> tuple[tuple[int, ...], NDArray, NDArray]:
    """``(layout, M0, eigenvalue parameters)``: from the real Schur form ``X = Z T Z'`` (its own layout,
    ``M0 = Z' V0``, its poles projected into the region), or for ``X`` None a random ``M0`` and
    poles in ``layout`` drawn from ``samples`` (``{1: real region samples, 2: complex ones}``)."""
    n, k = V0.shape
    if X is None:
        assert layout is not None, "a random start needs its block layout"
        lam: list[float] = []
        for s in layout:
            z = samples[s][rng.integers(len(samples[s]))]
            lam += [z.real] if s == 1 else [z.real, abs(z.imag)]
        return layout, rng.standard_normal((n, k)), np.asarray(lam)
    T, Z = scipy.linalg.schur(X, output="real")
    sizes, i = [], 0
    while i < n:
        s = 2 if i + 1 < n and T[i + 1, i] != 0 else 1
        sizes.append(s)
        i += s
    lam, i = [], 0
    for s in sizes:
        w = np.linalg.eigvals(T[i:i + s, i:i + s])
        z = complex(region.project([w[np.argmax(w.imag)]])[0])
        # a pair's block [[a, b], [c, a]] (b c < 0) as [[a, b'], [-b', a]] with the sign of b: exact for
        # a normal X (the chain's start), a start otherwise
        lam += [z.real] if s == 1 else [z.real, math.copysign(z.imag, T[i, i + 1])]
        i += s
    return tuple(sizes), Z.T @ V0, np.asarray(lam)


def _q_factor(Y: NDArray) -> NDArray:
    """The Q factor of ``Y = Q R`` ((n, k), n >= k), as ``np.linalg.qr(Y)[0]`` (the same LAPACK
    Householder routines ``dgeqrf`` + ``dorgqr``, without its wrapper: 4 against 21 us at n = 3)."""
    qr, tau, _, _ = scipy.linalg.lapack.dgeqrf(Y)
    return scipy.linalg.lapack.dorgqr(qr, tau)[0]


def _gram_residual(G1: NDArray, G2: NDArray, region: Region, layout: tuple[int, ...], iu: tuple[NDArray, NDArray],
                   x: NDArray, delta: float) -> tuple[NDArray, NDArray, NDArray]:
    """``(residual, M, Lambda)``: ``M = qf(Y)`` (orthonormal columns), residual ``M' Lam M - G1``,
    the upper triangle of ``M' Lam' Lam M - G2`` and the region hinge ``max(0, g + delta)``."""
    n, k = sum(layout), G1.shape[0]
    M = _q_factor(x[:n * k].reshape(n, k))
    Lam, poles = _blocks(layout, x[n * k:])
    LM = Lam @ M
    g = np.asarray(region.constraints(poles.real, poles.imag), dtype=float) + delta
    r = np.concatenate([(M.T @ LM - G1).ravel(), (LM.T @ LM - G2)[iu], np.maximum(0.0, g).ravel()])
    return r, M, Lam


def _solve_layout(G1: NDArray, G2: NDArray, region: Region, layout: tuple[int, ...], M0: NDArray,
                  lam0: NDArray, delta: float, iters: int,
                  tol: float) -> tuple[bool, float, NDArray, NDArray]:
    """Levenberg-Marquardt (forward-difference Jacobian) from one start: ``(converged, residual norm,
    M, Lambda)`` at the last iterate (converged: the residual below ``tol``)."""
    k = M0.shape[1]
    x = np.concatenate([M0.ravel(), lam0])
    h = math.sqrt(_EPS) * max(1.0, float(np.max(np.abs(x))))
    iu = np.triu_indices(k)  # (the upper triangle of the k x k Gram residual; once per start)
    r, M, Lam = _gram_residual(G1, G2, region, layout, iu, x, delta)
    cost, mu = float(r @ r), 1e-3
    eye = np.eye(x.size)
    for _ in range(iters):
        if np.linalg.norm(r) <= tol:
            return True, float(np.linalg.norm(r)), M, Lam
        J = np.column_stack([(_gram_residual(G1, G2, region, layout, iu, x + h * e, delta)[0] - r) / h
                             for e in eye])
        JtJ, grad = J.T @ J, J.T @ r
        while mu < 1e10:
            xn = x - np.linalg.solve(JtJ + mu * (np.diag(np.diag(JtJ)) + 1e-12 * eye), grad)
            out = _gram_residual(G1, G2, region, layout, iu, xn, delta)
            cn = float(out[0] @ out[0])
            if cn < cost:
                x, cost, mu = xn, cn, max(mu / 3.0, 1e-12)
                r, M, Lam = out
                break
            mu *= 4.0
        else:
            break
    return bool(np.linalg.norm(r) <= tol), float(np.linalg.norm(r)), M, Lam


def _normal_from(A: NDArray, V0: NDArray, M: NDArray, Lam: NDArray) -> NDArray:
    """``F = Q' Lam Q`` with ``Q`` orthogonal mapping ``[V0, A V0]`` to ``[M, Lam M]`` (orthogonal
    Procrustes; exact when their Gram matrices agree), so that ``F V0 = A V0``."""
    X1, X2 = np.hstack([V0, A @ V0]), np.hstack([M, Lam @ M])
    P, _, Rt = np.linalg.svd(X2 @ X1.T)
    Q = P @ Rt
    return Q.T @ Lam @ Q


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
    A = as_matrix("A", A)
    n = A.shape[0]
    if A.shape != (n, n):
        raise DimensionError(f"A must be square; found shape {A.shape}")
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
    V0 = Vt[p:].T
    k = n - p
    G1, G2 = V0.T @ A @ V0, (A @ V0).T @ (A @ V0)
    Cpinv = np.linalg.pinv(C)
    scale = max(1.0, float(np.linalg.norm(A, 2)))
    delta = 100.0 * _EPS * scale  # aim inside: a normal matrix's eigenvalues round by ~eps ||F||
    tol = 100.0 * _EPS * scale * scale  # G2 is quadratic in A
    tries: list[tuple[NDArray | None, tuple[int, ...] | None]] = [(X, None) for X in mats]
    tries += [(None, lay) for _ in range(random_starts) for lay in _layouts(n)]
    samples: dict[int, NDArray] = {}
    if random_starts:
        samples = {1: region.sample_poles(n, rng=rng, n_real=n)}
        if n > 1:
            z = region.sample_poles(2 * (n // 2), rng=rng, n_real=0)
            samples[2] = z[z.imag > 0]
    best: tuple[float, NDArray | None] = (math.inf, None)
    for X, lay in tries:
        layout, M0, lam0 = _start_from(X, V0, region, lay, rng, samples)
        ok, res, M, Lam = _solve_layout(G1, G2, region, layout, M0, lam0, delta, max_iter, tol)
        F = _normal_from(A, V0, M, Lam)
        if ok:
            L = (A - F) @ Cpinv
            if _verified(A - L @ C, region):
                return (L, F) if full_output else L
        if res < best[0]:
            best = (res, F)
    return (None, best[1]) if full_output else None


def _verified(X: NDArray, region: Region) -> bool:
    """Poles of ``X`` in ``region`` and ``kappa2(X) = 1`` to the accuracy of a computed kappa2."""
    ev = np.linalg.eigvals(X)
    if not region.contains(ev, tol=10.0 * _EPS * float(np.linalg.norm(X))):
        return False
    k2 = metrics.kappa2(X)
    return bool(math.isfinite(k2) and k2 <= 1.0 + kappa2_agreement_tol(1.0, eigen_spread(X, ev)))
