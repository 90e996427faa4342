r"""Levenberg-Marquardt search for a normal observer closed loop ``F = A - L C`` with its poles in a region.

The solver of :func:`optdesign.design.well_conditioned.normal_probe.normal_closed_loop` (which
validates the arguments and verifies a gain independently; the method is described there): with
``M = U^T V0`` (``V0`` an orthonormal basis of ``ker C``) a normal ``F = U Lambda U^T`` is an observer
closed loop iff ``M^T Lambda M = V0^T A V0`` and ``M^T Lambda^T Lambda M = (A V0)^T (A V0)``; the unknowns
are ``M = qf(Y)`` and the eigenvalue parameters of one block layout, the residual those two Gram
equations and a hinge on the region's constraints, and ``U`` the orthogonal Procrustes solution.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np
import scipy.linalg
from numpy.typing import NDArray

from ..model.regions import Region
from .tolerances import (
    EPS,
    LM_DAMPING_MAX,
    LM_DAMPING_MIN,
    LM_DAMPING_START,
    LM_DIAG_FLOOR,
    NORMAL_ROUNDING_FACTOR,
    rounding_level,
)

__all__ = ["normal_freedom", "search_normal_closed_loop"]



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


def _gram_residual(G1: NDArray, G2: NDArray, region: Region, layout: tuple[int, ...],
                   iu: tuple[NDArray, NDArray], x: NDArray, delta: float) -> tuple[NDArray, NDArray, NDArray]:
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
    M, Lambda)`` at the last iterate (converged: the residual below ``tol``).

    Hand-written rather than MINPACK's (``scipy.optimize.least_squares(method="lm")``), measured on
    the same residual, starts and budget (``benchmarks/bench_normal_search.py``,
    ``benchmarks/results/normal_search.md``): MINPACK finds 40 of 40 constructed cases against 39 at
    0.62x the CPU, but from the region sweep's pool starts it stops short of the normal closed loop
    at DIS2 grid point 288 (``tests/test_normal_probe.py::test_sweep_pool_attains_the_bound_at_grid_point_288``
    fails with it, for every budget tried up to 4 Jacobians more per iteration), where this loop,
    which stops only at ``tol`` or a damping of 1e10, reaches it."""
    k = M0.shape[1]
    x = np.concatenate([M0.ravel(), lam0])
    h = math.sqrt(EPS) * max(1.0, float(np.max(np.abs(x))))  # forward differences: sqrt(eps) relative
    iu = np.triu_indices(k)  # (the upper triangle of the k x k Gram residual; once per start)
    r, M, Lam = _gram_residual(G1, G2, region, layout, iu, x, delta)
    cost, mu = float(r @ r), LM_DAMPING_START
    eye = np.eye(x.size)
    for _ in range(iters):
        if np.linalg.norm(r) <= tol:
            return True, float(np.linalg.norm(r)), M, Lam
        J = np.column_stack([(_gram_residual(G1, G2, region, layout, iu, x + h * e, delta)[0] - r) / h
                             for e in eye])
        JtJ, grad = J.T @ J, J.T @ r
        while mu < LM_DAMPING_MAX:
            xn = x - np.linalg.solve(JtJ + mu * (np.diag(np.diag(JtJ)) + LM_DIAG_FLOOR * eye), grad)
            out = _gram_residual(G1, G2, region, layout, iu, xn, delta)
            cn = float(out[0] @ out[0])
            if cn < cost:
                x, cost, mu = xn, cn, max(mu / 3.0, LM_DAMPING_MIN)
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


def search_normal_closed_loop(A: NDArray, C: NDArray, V0: NDArray, region: Region, mats: Sequence[NDArray],
                              random_starts: int, rng: np.random.Generator, max_iter: int,
                              accept: Callable[[NDArray], bool]) -> tuple[NDArray | None, NDArray | None]:
    """Search from the closed loops ``mats`` ((n, n), in order), then ``random_starts`` rounds of one
    random start per block layout (all real, one pair, ...), ``max_iter`` Levenberg-Marquardt iterations each.

    ``A`` (n, n), ``C`` (p, n) of full row rank, ``V0`` (n, n - p) an orthonormal basis of ``ker C``
    (validated by the caller).  Returns ``(L, F)``: the gain ``L = (A - F) C^+`` of the first start
    that converges to a normal ``F`` and whose gain ``accept(L)`` takes (the caller's independent
    verification), or ``(None, F)`` with ``F`` the normal matrix of the start that came closest (the
    smallest residual)."""
    n = A.shape[0]
    G1, G2 = V0.T @ A @ V0, (A @ V0).T @ (A @ V0)
    Cpinv = np.linalg.pinv(C)
    scale = max(1.0, float(np.linalg.norm(A, 2)))
    # aim inside: a normal matrix's eigenvalues round by ~eps ||F||
    delta = rounding_level(1, scale, NORMAL_ROUNDING_FACTOR)
    tol = rounding_level(1, scale, NORMAL_ROUNDING_FACTOR) * scale  # G2 is quadratic in A
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
            if accept(L):
                return L, F
        if res < best[0]:
            best = (res, F)
    return None, best[1]
