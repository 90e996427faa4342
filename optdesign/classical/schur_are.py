r"""The Schur-method Riccati solvers, written from the textbook construction: :func:`hamiltonian_are`
(ordered real Schur form of the Hamiltonian matrix, seed 001 eq (25)-(27)) and :func:`symplectic_dare`
(ordered QZ of the symplectic pencil) -- the independent second way to the stabilizing solution beside
scipy's solvers (:mod:`optdesign.classical.riccati`, which re-exports both).

References
----------
Laub, A. J., "A Schur method for solving algebraic Riccati equations", IEEE TAC 24 (1979)
913-921.
Pappas, T., Laub, A. J. & Sandell, N. R., "On the numerical solution of the discrete-time
algebraic Riccati equation", IEEE TAC 25 (1980) 631-641.
Benner, P., "Symplectic balancing of Hamiltonian matrices", SIAM J. Sci. Comput. 22 (2001).
"""

from __future__ import annotations

import numpy as np
import scipy.linalg
from numpy.typing import ArrayLike, NDArray

from .._validate import as_matrix, as_square, check_pd, check_symmetric
from ..analysis.metrics import eigenvalue_condition
from ..errors import DimensionError, RiccatiError

__all__ = ["hamiltonian_are", "symplectic_dare", "format_pole"]

_EPS = float(np.finfo(float).eps)

#: relative asymmetry of U11'U21 above which the computed stable subspace is rejected
_LAGRANGIAN_TOL = 1e-8

#: default eigenvalue-on-the-boundary tolerance (a multiple of eps; see hamiltonian_are)
_BOUNDARY_TOL = 4.0 * _EPS


# --------------------------------------------------------------------------- helpers
def format_pole(z: complex) -> str:
    """A pole for messages: ``-5`` or ``-1+2j`` (6 significant digits).

    Examples
    --------
    >>> from optdesign.riccati import format_pole
    >>> format_pole(-5.0), format_pole(-1 + 2j)
    ('-5', '-1+2j')
    """
    z = complex(z)
    if z.imag == 0:
        return f"{z.real:.6g}"
    return f"{z.real:.6g}{z.imag:+.6g}j"


def _validate_are_args(a, b, q, r) -> tuple[NDArray, NDArray, NDArray, NDArray]:
    a = as_square("a", a)
    n = a.shape[0]
    if n == 0:
        raise DimensionError("a must have at least one row; found shape (0, 0)")
    b = as_matrix("b", b, (n, None))
    if b.shape[1] == 0:
        raise DimensionError(f"b must have at least one column; found shape {b.shape}")
    q = check_symmetric("q", as_square("q", q, n))
    r = check_pd("r", as_square("r", r, b.shape[1]))
    return a, b, q, r


def _gain_term(b: NDArray, r: NDArray) -> NDArray:
    """``b r^-1 b'`` (symmetric) via a Cholesky solve."""
    cho = scipy.linalg.cho_factor(r)
    G = b @ scipy.linalg.cho_solve(cho, b.T)
    return 0.5 * (G + G.T)


def _norm_scaling(G: NDArray, q: NDArray) -> float:
    """Scalar ``rho`` with ``X = rho X1``: equilibrates ``||rho G||_F = ||q / rho||_F``.

    The substitution maps ``(G, q)`` to ``(rho G, q / rho)`` and keeps the structure; it is
    what makes badly scaled problems such as CAREX 2.6 (||q|| ~ 1e6, ||G|| ~ 1e-6) solvable
    to full accuracy (plain balancing of H does not see the imbalance, since a dominates).
    """
    ng, nq = float(np.linalg.norm(G)), float(np.linalg.norm(q))
    if ng == 0.0 or nq == 0.0:
        return 1.0
    return float(2.0 ** np.round(0.5 * np.log2(nq / ng)))


def _symplectic_scaling(M: NDArray, n: int) -> NDArray | None:
    """Diagonal scaling ``diag(D, D^-1)`` (powers of 2) that balances ``M`` symplectically.

    Follows scipy's solvers (Benner 2001): balance ``|M|`` with zero diagonal, then impose
    ``diag(D, D^-1)`` so that the Hamiltonian / symplectic structure survives.  Returns the
    2n scale vector, or None when no scaling is needed.
    """
    M = np.abs(M)
    np.fill_diagonal(M, 0.0)
    _, (sca, _) = scipy.linalg.matrix_balance(M, separate=True, permute=False)
    lsca = np.log2(sca)
    s = np.round((lsca[n:] - lsca[:n]) / 2)
    if not np.any(s):
        return None
    return 2.0 ** np.r_[s, -s]


def _eig_condition(M: NDArray, N: NDArray | None = None):
    """Eigenvalues of ``M`` (or of the pencil ``M - lambda N``) and their first-order
    sensitivity to a relative backward error: ``|d lambda| <~ sens * (relative error)``.

    Standard matrix: ``sens = s ||M||_F`` with ``s = ||x|| ||y|| / |y^H x|``; pencil:
    ``sens = ||x|| ||y|| (||M||_F + |lambda| ||N||_F) / |y^H N x|`` (inf for infinite or
    defective eigenvalues).
    """
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        if N is None:
            w, s = eigenvalue_condition(M)
            sens = s * np.linalg.norm(M)
        else:
            w, Yl, Xr = scipy.linalg.eig(M, N, left=True, right=True)
            Xr = Xr / np.linalg.norm(Xr, axis=0)
            Yl = Yl / np.linalg.norm(Yl, axis=0)
            d = np.abs(np.einsum("ij,ik,kj->j", Yl.conj(), N, Xr))
            sens = (np.linalg.norm(M) + np.abs(w) * np.linalg.norm(N)) / d
        sens = np.where(np.isfinite(sens), sens, np.inf)
    return w, sens


def _subspace_solution(U: NDArray, n: int, kind: str, boundary: str, closest: str) -> NDArray:
    """``X = U21 U11^-1`` from an orthonormal basis U (2n x n) of the stable subspace."""
    U11, U21 = U[:n, :n], U[n:, :n]
    c = np.linalg.cond(U11)
    limit = 1.0 / (1e3 * n * _EPS)
    if not np.isfinite(c) or c > limit:
        raise RiccatiError(
            f"{kind}: the U11 block of the stable invariant-subspace basis is singular or "
            f"ill-conditioned (cond(U11) = {c:.3g} > {limit:.3g}), so there is no finite "
            f"stabilizing solution (typically (a, b) is not stabilizable or (q, a) has an "
            f"unobservable mode on the {boundary})"
        )
    # The stable subspace of a Hamiltonian matrix / symplectic pencil is Lagrangian:
    # U11' U21 is symmetric.  Its asymmetry measures the error of the computed subspace; it
    # is large when stable and unstable eigenvalues nearly meet on the boundary (the
    # subspace is then ill-conditioned) or were split wrongly by rounding.
    S = U11.T @ U21
    asym = float(np.linalg.norm(S - S.T, 1))
    lim = max(_LAGRANGIAN_TOL * float(np.linalg.norm(S, 1)), 1e3 * n * _EPS)
    if asym > lim:
        raise RiccatiError(
            f"{kind}: the computed stable subspace is not Lagrangian (||U11'U21 - U21'U11||_1 = "
            f"{asym:.3g} > {lim:.3g}): it is ill-conditioned because eigenvalues lie too close "
            f"to the {boundary} (closest: {closest}); the solution would be inaccurate"
        )
    X = np.linalg.solve(U11.T, U21.T).T
    return 0.5 * (X + X.T)


def _boundary_bound(sens: NDArray, tol: float, scale: float) -> NDArray:
    """How close to the boundary an eigenvalue must be to count as on it.

    ``min(tol * sens, sqrt(tol) * scale)``: the first-order rounding uncertainty of the
    eigenvalue, capped at the ``sqrt(eps)``-size split that rounding gives a double
    eigenvalue on the boundary (for higher-order defective eigenvalues, far from the
    boundary, the first-order sensitivity overstates the uncertainty).
    """
    return np.minimum(tol * sens, np.sqrt(tol) * scale)


def _boundary_error(kind: str, where: str, lam: complex, dist: float, bound: float) -> RiccatiError:
    return RiccatiError(
        f"{kind}: eigenvalue(s) on the {where} (closest: {format_pole(lam)}, distance {dist:.3g} "
        f"<= {bound:.3g}, its rounding uncertainty); no stabilizing solution exists (a mode on "
        f"the {where} that is uncontrollable or unobservable, or an indefinite problem)"
    )


# ------------------------------------------------------------------ continuous ARE
def hamiltonian_are(
    a: ArrayLike,
    b: ArrayLike,
    q: ArrayLike,
    r: ArrayLike,
    *,
    balance: bool = True,
    tol: float | None = None,
    trusted: bool = False,
) -> NDArray[np.float64]:
    r"""Stabilizing solution of the continuous ARE by the Schur method on the Hamiltonian.

    Solves ``a' X + X a - X b r^-1 b' X + q = 0`` (scipy's control-form signature) for the
    symmetric X that makes ``a - b r^-1 b' X`` stable, from the stable invariant subspace of

    .. math::

        H = \begin{bmatrix} a & -b r^{-1} b' \\ -q & -a' \end{bmatrix}.

    An ordered real Schur form ``H = U T U'`` (``scipy.linalg.schur(sort='lhp')``) puts the n
    stable eigenvalues first; the first n Schur vectors ``[U11; U21]`` span the stable
    subspace and ``X = U21 U11^-1`` (computed with a solve, then symmetrized).  Ordered Schur
    vectors are an orthonormal basis, unlike the raw eigenvectors of seed 001 eq (26), so
    the method also works when the stable eigenvalues are repeated or defective.

    For the Kalman filter (seed 001 eq (23)) call it with ``a = A'``, ``b = C'``,
    ``q = G Q G'``, ``r = R``; then H is the transpose-similar form of seed 001's
    eq (25) ``[[A', -C'R^-1C], [-GQG', -A]]`` and ``X = P`` (eq (26)-(27): ``P = Y X^-1``).

    Parameters
    ----------
    a : (n, n) array_like
    b : (n, m) array_like
    q : (n, n) array_like
        Symmetric.
    r : (m, m) array_like
        Symmetric positive definite (``b r^-1 b'`` is formed explicitly, so an
        ill-conditioned r costs accuracy: about ``cond(r) eps``, cf. CAREX 2.2).
    balance : bool
        Scale before the Schur form, preserving the Hamiltonian structure: ``X = rho X1``
        with ``rho`` (a power of 2) equilibrating ``||rho b r^-1 b'|| = ||q / rho||``, then a
        symplectic diagonal balancing ``diag(D, D^-1)`` (as scipy does).  Default True; it
        turns CAREX 2.6 from 3e-4 to 1e-15 relative accuracy.
    tol : float, optional
        Multiple of eps: an eigenvalue ``lambda`` of H counts as on the imaginary axis when
        ``|Re lambda| <= tol * sens(lambda)`` where ``sens = s(lambda) ||H||_F`` is its
        first-order sensitivity (``s`` = eigenvalue condition number), i.e. when it cannot be
        told apart from its mirror image ``-conj(lambda)``; the bound is capped at
        ``sqrt(tol) ||H||_F``, the size of the rounding split of a double eigenvalue on the
        axis.  Default ``4 eps``: a pair on the axis split by rounding (CAREX 2.5: by ~1e-8)
        is caught with a wide margin, while DAREX 2.5's closed-loop eigenvalue 2.2e-8 inside
        the unit circle (sensitivity ~1e8) is still accepted.  ``tol=0`` disables the test
        (the eigenvalue count and the Lagrangian check remain).
    trusted : bool
        The arguments are float arrays already validated (r symmetric positive definite, q
        symmetric): no validation and no boundary test (``tol`` is ignored; the eigenvalue
        count, the U11 condition and the Lagrangian check remain) -- the lean re-solve of a
        verification, which judges the answer by measured differences anyway.

    Returns
    -------
    X : (n, n) ndarray
        The stabilizing solution, symmetric.

    Raises
    ------
    DimensionError, NotFiniteError, NotSymmetricError, NotPositiveDefiniteError
        Bad input (names the argument and expected vs found).
    RiccatiError
        Says which failure: the Hamiltonian has eigenvalues on the imaginary axis (the
        closest one is given); the number of stable eigenvalues is not n; the U11 block is
        singular or ill-conditioned (its condition number is given); the computed subspace
        is not Lagrangian (stable and unstable eigenvalues nearly meet on the axis, so the
        subspace -- and X -- cannot be computed accurately, e.g. CAREX 2.8).

    References
    ----------
    Seed 001 (Jung & Huh), eq (25)-(27).  Laub, IEEE TAC 24 (1979) 913-921.

    Examples
    --------
    >>> import numpy as np
    >>> X = hamiltonian_are([[0., 1.], [0., 0.]], [[0.], [1.]], np.diag([1., 2.]), [[1.]])
    >>> np.round(X, 12)   # CAREX 1.1: X = [[2, 1], [1, 2]]
    array([[2., 1.],
           [1., 2.]])
    """
    kind = "hamiltonian_are"
    if trusted:
        a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
        q, r = np.asarray(q, dtype=float), np.asarray(r, dtype=float)
    else:
        a, b, q, r = _validate_are_args(a, b, q, r)
    n = a.shape[0]
    G = _gain_term(b, r)
    rho = _norm_scaling(G, q) if balance else 1.0
    H = np.block([[a, -rho * G], [-q / rho, -a.T]])
    sca = _symplectic_scaling(H, n) if balance else None
    if sca is not None:
        H = H * (sca[:, None] / sca[None, :])
    closest = "not computed (trusted input)"
    if not trusted:
        tol = _BOUNDARY_TOL if tol is None else float(tol)
        lam, sens = _eig_condition(H)
        dist = np.abs(lam.real)
        closest = format_pole(lam[int(np.argmin(dist))])
        bound = _boundary_bound(sens, tol, float(np.linalg.norm(H)))
        k = int(np.argmin(dist - bound))
        if 0 < bound[k] and dist[k] <= bound[k]:  # tol = 0 disables the test
            raise _boundary_error(kind, "imaginary axis", lam[k], dist[k], bound[k])
    try:
        _, U, sdim = scipy.linalg.schur(H, output="real", sort="lhp", check_finite=not trusted)
    except ValueError as exc:  # pragma: no cover - LAPACK could not reorder (eigenvalues too close)
        raise RiccatiError(f"{kind}: reordering the Schur form failed ({exc}); eigenvalues too "
                           f"close to the imaginary axis (closest: {closest})") from exc
    if sdim != n:
        raise RiccatiError(
            f"{kind}: expected n = {n} stable Hamiltonian eigenvalues, found {sdim} "
            f"(closest to the imaginary axis: {closest})"
        )
    X = _subspace_solution(U[:, :n], n, kind, "imaginary axis", closest)
    if sca is not None:
        X = X * (sca[:n, None] * sca[None, :n])
    return rho * X


# -------------------------------------------------------------------- discrete ARE
def symplectic_dare(
    a: ArrayLike,
    b: ArrayLike,
    q: ArrayLike,
    r: ArrayLike,
    *,
    balance: bool = True,
    tol: float | None = None,
) -> NDArray[np.float64]:
    r"""Stabilizing solution of the discrete ARE by ordered QZ of the symplectic pencil.

    Solves ``X = a' X a - a' X b (r + b' X b)^-1 b' X a + q`` for the symmetric X that makes
    ``a - b (r + b' X b)^-1 b' X a`` Schur stable, from the deflating subspace of the pencil

    .. math::

        \begin{bmatrix} a & 0 \\ -q & I \end{bmatrix} - \lambda
        \begin{bmatrix} I & b r^{-1} b' \\ 0 & a' \end{bmatrix}

    for the n eigenvalues inside the unit circle (``scipy.linalg.ordqz(sort='iuc')``):
    ``X = Z21 Z11^-1``.  Singular ``a`` is fine (it gives infinite eigenvalues, which QZ
    handles); singular ``r`` is not (use an extended-pencil solver).  A cross-check of
    :func:`scipy.linalg.solve_discrete_are`, which uses the extended (2n + m) pencil.

    Parameters
    ----------
    a : (n, n) array_like
    b : (n, m) array_like
    q : (n, n) array_like
        Symmetric.
    r : (m, m) array_like
        Symmetric positive definite.
    balance : bool
        Structure-preserving scaling before QZ (as in :func:`hamiltonian_are`).
    tol : float, optional
        Multiple of eps: a pencil eigenvalue counts as on the unit circle when
        ``||lambda| - 1| <= min(tol * sens(lambda), sqrt(tol))`` (first-order sensitivity,
        capped as in :func:`hamiltonian_are`).  Default ``4 eps``.

    Returns
    -------
    X : (n, n) ndarray
        The stabilizing solution, symmetric.

    Raises
    ------
    DimensionError, NotFiniteError, NotSymmetricError, NotPositiveDefiniteError
        Bad input.
    RiccatiError
        Eigenvalues on the unit circle (closest one reported); not n eigenvalues inside;
        singular / ill-conditioned Z11 (condition number reported); non-Lagrangian subspace.

    References
    ----------
    Pappas, Laub & Sandell, IEEE TAC 25 (1980) 631-641.

    Examples
    --------
    >>> X = symplectic_dare([[1.]], [[1.]], [[1.]], [[1.]])
    >>> round(float(X[0, 0]), 12)   # X = (1 + sqrt 5) / 2
    1.61803398875
    """
    kind = "symplectic_dare"
    a, b, q, r = _validate_are_args(a, b, q, r)
    n = a.shape[0]
    G = _gain_term(b, r)
    rho = _norm_scaling(G, q) if balance else 1.0
    I, Z0 = np.eye(n), np.zeros((n, n))
    M = np.block([[a, Z0], [-q / rho, I]])
    N = np.block([[I, rho * G], [Z0, a.T]])
    sca = _symplectic_scaling(np.abs(M) + np.abs(N), n) if balance else None
    if sca is not None:
        S = sca[:, None] / sca[None, :]
        M, N = M * S, N * S
    tol = _BOUNDARY_TOL if tol is None else float(tol)
    lam, sens = _eig_condition(M, N)
    finite = np.isfinite(lam)
    dist = np.full(lam.shape, np.inf)
    dist[finite] = np.abs(np.abs(lam[finite]) - 1.0)
    closest = format_pole(lam[int(np.argmin(dist))])
    bound = np.zeros(lam.shape)
    bound[finite] = _boundary_bound(sens[finite] / np.maximum(1.0, np.abs(lam[finite])), tol, 1.0)
    k = int(np.argmin(np.where(finite, dist - bound, np.inf)))
    if 0 < bound[k] and dist[k] <= bound[k]:  # tol = 0 disables the test
        raise _boundary_error(kind, "unit circle", lam[k], dist[k], bound[k])
    try:
        _, _, alpha, beta, _, Z = scipy.linalg.ordqz(M, N, sort="iuc", output="real")
    except ValueError as exc:  # pragma: no cover - LAPACK could not reorder
        raise RiccatiError(f"{kind}: reordering the QZ form failed ({exc}); eigenvalues too "
                           f"close to the unit circle (closest: {closest})") from exc
    inside = int(np.sum(np.abs(alpha) < np.abs(beta)))
    if inside != n:
        raise RiccatiError(
            f"{kind}: expected n = {n} pencil eigenvalues inside the unit circle, found "
            f"{inside} (closest to the circle: {closest})"
        )
    X = _subspace_solution(Z[:, :n], n, kind, "unit circle", closest)
    if sca is not None:
        X = X * (sca[:n, None] * sca[None, :n])
    return rho * X
