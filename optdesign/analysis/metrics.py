r"""Conditioning metrics of a matrix: eigenvector condition numbers and non-normality.

The observer matrix ``A - L C`` of a well-conditioned observer has a well-conditioned
eigenvector matrix.  Seed 001 (Jung & Huh) measures this by

* ``kappa2`` -- the 2-norm condition number of the eigenvector matrix whose columns have
  unit 2-norm, and
* ``eta`` -- Huh & Stein's non-normality measure
  ``eta = ||N||_F / min_{i != j} |lambda_i - lambda_j|``, where ``U^H X U = Lambda + N`` is
  the *complex* Schur form (``N`` strictly upper triangular), seed 001 eq (1), (13).

For a 2 x 2 matrix with distinct eigenvalues the two are tied exactly,
``kappa2 = eta + sqrt(1 + eta^2)`` (seed 001 eq (19)).

Repeated and defective eigenvalues
----------------------------------
Two computed eigenvalues are treated as *coincident* when they cannot be told apart in
floating point:

.. math::

    |\lambda_i - \lambda_j| \le \mathrm{tol}\,(s_i + s_j)\,\|X\|_F ,
    \qquad \mathrm{tol} = 8 n \varepsilon \ \text{(default)},

where ``s_i = ||y_i|| ||x_i|| / |y_i^H x_i|`` is the condition number of ``lambda_i`` (the
2-norm of row ``i`` of ``V^{-1}`` when ``V`` has unit columns).  The right-hand side is the
first-order amount by which a backward error of ``tol ||X||_F`` can move the two
eigenvalues, so a pair closer than that is indistinguishable from a double eigenvalue.
A Jordan block (whose computed eigenvalues split by about ``eps^(1/k)``) always lands on the
coincident side -- measured: at most 0.05 of the bound over 1000 random orthogonal and
general similarity transforms of Jordan blocks of size 2..6 -- while ``[[0, 1e6], [0, 1]]``
(kappa2 = 2e6) is 140 times above it.  Matrices with eta beyond ~1e7 sit within a few eps
of a defective matrix and are reported as coincident.

When some pair is coincident, ``min_gap`` is 0 and ``kappa2``, ``kappa_fro`` and ``eta`` are
``inf``: for a defective matrix no eigenvector basis exists, and for a *normal* matrix with a
repeated eigenvalue (e.g. the identity) the unit-column eigenvector basis is not unique
(any basis of the eigenspace will do, with any condition number >= 1), so no finite value
is meaningful either.  ``departure`` is always finite.

All functions accept real or complex square matrices.

References
----------
Jung, J. & Huh, K., "Design of the well-conditioned observer using the non-normality
measure" (seed 001), eq (1), (13)-(19).
Huh, K. & Stein, J. L., "A non-normality measure of the condition number for monitoring
and control", ASME J. Dyn. Sys. Meas. Control 119 (1997) 217-222.
Henrici, P., "Bounds for iterates, inverses, spectral variation and fields of values of
non-normal matrices", Numer. Math. 4 (1962) 24-40.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, overload

import numpy as np
import scipy.linalg
from numpy.typing import ArrayLike, NDArray

from .._validate import as_int, as_matrix, as_positive_float
from ..errors import DimensionError

__all__ = [
    "eigenvector_matrix",
    "kappa2",
    "kappa_fro",
    "departure",
    "min_gap",
    "eta",
    "condition_summary",
    "coincidence_tol",
    "eigenvalue_condition",
    "eigenvalue_rounding_floor",
]

_EPS = float(np.finfo(float).eps)


def coincidence_tol(n: int) -> float:
    """Default relative tolerance ``8 n eps`` for declaring two eigenvalues coincident.

    See the module docstring for the criterion it enters.

    Raises
    ------
    ValidationError
        ``n`` is not an integer ``>= 0``.
    """
    return 8.0 * max(1, as_int("n", n, 0)) * _EPS


def _as_square(X: ArrayLike, name: str = "X") -> NDArray:
    arr = as_matrix(name, X, allow_complex=True)
    if arr.shape[0] != arr.shape[1]:
        raise DimensionError(f"{name} must be square; found shape {arr.shape}")
    if arr.shape[0] == 0:
        raise DimensionError(f"{name} must have at least one row; found shape {arr.shape}")
    return arr


def _schur(X: NDArray) -> tuple[NDArray[np.complex128], NDArray[np.complex128]]:
    """Complex Schur form ``X = Z T Z^H`` (no balancing)."""
    T, Z = scipy.linalg.schur(X.astype(complex), output="complex")
    return T, Z


def _triangular_eigvecs(T: NDArray[np.complex128]) -> NDArray[np.complex128]:
    """Eigenvectors of an upper triangular T by back substitution (as LAPACK's ztrevc).

    Column k solves ``(T[:k, :k] - T[k, k] I) y = -T[:k, k]`` with ``y_k = 1``; pivots
    smaller than ``eps ||T||_F`` are replaced by that value (ztrevc's perturbation), so
    repeated eigenvalues give (nearly) parallel, not infinite, vectors.  Columns are
    normalized to unit 2-norm.
    """
    n = T.shape[0]
    Y = np.zeros((n, n), dtype=complex)
    smin = max(_EPS * float(np.linalg.norm(T)), np.finfo(float).tiny)
    for k in range(n):
        Y[k, k] = 1.0
        if k:
            M = T[:k, :k] - T[k, k] * np.eye(k)
            d = np.diagonal(M).copy()
            small = np.abs(d) < smin
            d[small] = smin
            M[np.diag_indices(k)] = d
            with np.errstate(over="ignore", invalid="ignore"):
                Y[:k, k] = scipy.linalg.solve_triangular(M, -T[:k, k], check_finite=False)
        col = Y[:, k]
        nrm = np.linalg.norm(col) if np.all(np.isfinite(col)) else np.inf
        if not np.isfinite(nrm) or nrm == 0.0:
            Y[:, k] = np.nan  # overflow: marks the spectrum as numerically defective
        else:
            Y[:, k] = col / nrm
    return Y


def _unit_eigvecs(X: NDArray) -> tuple[NDArray[np.complex128], NDArray[np.complex128], NDArray]:
    """Eigenvalues, unit-column eigenvectors (canonical phase) and the triangular Schur factor.

    Eigenvectors come from the complex Schur form (not from ``numpy.linalg.eig``, whose
    LAPACK driver balances the matrix first and can return wrong eigenvectors for badly
    scaled input such as ``[[0, 1e-126], [1, 1]]``).
    """
    T, Z = _schur(X)
    w = np.diagonal(T).copy()
    V = Z @ _triangular_eigvecs(T)
    V = V / np.linalg.norm(V, axis=0)
    # canonical phase: the largest-magnitude entry of each column is real positive
    with np.errstate(invalid="ignore"):
        idx = np.argmax(np.abs(V), axis=0)
        piv = V[idx, np.arange(V.shape[1])]
        V = V * (np.abs(piv) / piv)
    return w, V, T


@dataclass(frozen=True)
class _Spectrum:
    w: NDArray[np.complex128]  # eigenvalues
    V: NDArray[np.complex128]  # unit-column eigenvectors
    Vinv: NDArray[np.complexfloating] | None  # None when V is (numerically) singular
    gap: float  # min computed |w_i - w_j| (inf for n = 1)
    coincident: bool  # some pair is numerically coincident
    departure: float  # ||strict upper triangle of the complex Schur factor||_F


def _pow2_scale(X: NDArray) -> float:
    """A power of two near ``||X||_F`` (1 for a zero matrix): dividing by it is exact and
    keeps subnormal or huge matrices away from underflow / overflow."""
    nrm = float(np.max(np.abs(X))) if X.size else 0.0
    return 1.0 if nrm == 0.0 else float(2.0 ** np.round(np.log2(nrm)))


def _spectrum(X: NDArray, tol: float | None) -> _Spectrum:
    n = X.shape[0]
    tol = coincidence_tol(n) if tol is None else as_positive_float("tol", tol, allow_zero=True)
    scale = _pow2_scale(X)
    X = X / scale
    w, V, T = _unit_eigvecs(X)
    w = w * scale
    dep = float(np.linalg.norm(np.triu(T, 1))) * scale
    if n == 1:
        return _Spectrum(w, V, np.ones((1, 1), complex), float("inf"), False, dep)
    Vinv = None
    if np.all(np.isfinite(V)):
        try:
            Vinv = np.linalg.solve(V, np.eye(n))
        except np.linalg.LinAlgError:
            Vinv = None
        if Vinv is not None and not np.all(np.isfinite(Vinv)):
            Vinv = None
    d = np.abs(w[:, None] - w[None, :]) / scale
    np.fill_diagonal(d, np.inf)
    gap = float(np.min(d)) * scale
    if Vinv is None:
        coincident = True
    else:
        s = np.linalg.norm(Vinv, axis=1)  # eigenvalue condition numbers (V has unit columns)
        bound = tol * (s[:, None] + s[None, :]) * np.linalg.norm(X)
        coincident = bool(np.any(d <= bound))
    return _Spectrum(w, V, Vinv, gap, coincident, dep)


@overload
def eigenvector_matrix(X: ArrayLike, *, return_eigenvalues: Literal[False] = ...
                       ) -> NDArray[np.complex128]: ...
@overload
def eigenvector_matrix(X: ArrayLike, *, return_eigenvalues: Literal[True]
                       ) -> tuple[NDArray[np.complex128], NDArray[np.complex128]]: ...
def eigenvector_matrix(
    X: ArrayLike, *, return_eigenvalues: bool = False
) -> NDArray[np.complex128] | tuple[NDArray[np.complex128], NDArray[np.complex128]]:
    """Eigenvector matrix of ``X`` with unit 2-norm columns.

    Parameters
    ----------
    X : (n, n) array_like
        Real or complex square matrix.
    return_eigenvalues : bool
        Also return the eigenvalues (in the order of the columns).

    Returns
    -------
    V : (n, n) ndarray of complex
        ``X V = V diag(w)``; every column has unit 2-norm, and its largest-magnitude entry is
        real and positive (so conjugate eigenvalues of a real matrix get conjugate columns).
    w : (n,) ndarray of complex
        Only if ``return_eigenvalues``.

    Raises
    ------
    DimensionError
        ``X`` is not square (or is empty).
    NotFiniteError
        ``X`` contains NaN or Inf.

    Notes
    -----
    No check for defectiveness is made here: for a defective matrix the returned columns are
    (nearly) linearly dependent, and :func:`kappa2` reports ``inf``.
    """
    A = _as_square(X)
    scale = _pow2_scale(A)
    w, V, _ = _unit_eigvecs(A / scale)
    return (V, w * scale) if return_eigenvalues else V


def eigenvalue_condition(X: ArrayLike) -> tuple[NDArray[np.complex128], NDArray[np.float64]]:
    """Eigenvalues and their condition numbers ``s_i = ||x_i|| ||y_i|| / |y_i^H x_i|``.

    A perturbation ``E`` moves ``lambda_i`` by about ``s_i ||E||`` to first order.  Computed
    from the unit-column eigenvector matrix V (``s_i`` = 2-norm of row i of ``V^-1``).

    Parameters
    ----------
    X : (n, n) array_like

    Returns
    -------
    w : (n,) ndarray of complex
    s : (n,) ndarray of float
        ``>= 1``; ``inf`` where V is numerically singular (defective X).

    Raises
    ------
    DimensionError, NotFiniteError
    """
    A = _as_square(X)
    scale = _pow2_scale(A)
    w, V, _ = _unit_eigvecs(A / scale)
    s = np.full(w.shape, np.inf)
    if np.all(np.isfinite(V)):
        try:
            Vinv = np.linalg.solve(V, np.eye(V.shape[0]))
            if np.all(np.isfinite(Vinv)):
                s = np.linalg.norm(Vinv, axis=1)
        except np.linalg.LinAlgError:
            pass
    return w * scale, s


def eigenvalue_rounding_floor(X: ArrayLike) -> float:
    """How accurately the eigenvalues of ``X`` can be computed at all, relatively:
    ``10 eps max_i s_i ||X||_F / max(1, |lambda_i|)`` with ``s_i`` the eigenvalue condition numbers
    (:func:`eigenvalue_condition`).

    No design can be verified to better than its poles can be computed; a check of pole accuracy
    below this level would test rounding, not the design.

    Parameters
    ----------
    X : (n, n) array_like

    Returns
    -------
    float
        ``>= 0``; ``inf`` for a (numerically) defective X.

    Raises
    ------
    DimensionError, NotFiniteError
    """
    w, s = eigenvalue_condition(X)
    if w.size == 0:
        return 0.0
    rel = s * float(np.linalg.norm(np.asarray(X))) / np.maximum(1.0, np.abs(w))
    floor = 10.0 * _EPS * float(np.max(rel))
    return floor if np.isfinite(floor) else float("inf")


def kappa2(X: ArrayLike, *, tol: float | None = None) -> float:
    """2-norm condition number of the unit-column eigenvector matrix of ``X``.

    ``kappa2 = ||V||_2 ||V^-1||_2`` (seed 001, section 2.1), >= 1, equal to 1 exactly when
    ``X`` is normal with distinct eigenvalues.

    Parameters
    ----------
    X : (n, n) array_like
    tol : float, optional
        Relative coincidence tolerance (default ``8 n eps``; see the module docstring).

    Returns
    -------
    float
        ``inf`` when two eigenvalues are numerically coincident (defective, or repeated);
        1.0 for a 1 x 1 matrix.

    Raises
    ------
    DimensionError, NotFiniteError
        ``X`` not square / not finite.
    ValidationError
        ``X`` not numeric; ``tol`` not a finite number ``>= 0``.

    Examples
    --------
    >>> import numpy as np
    >>> A, C = np.array([[0., 1.], [2., -1.]]), np.array([[1., 0.]])
    >>> round(kappa2(A - np.array([[10.], [5.]]) @ C), 4)   # seed 001, Example 1
    1.5914
    """
    sp = _spectrum(_as_square(X), tol)
    if sp.coincident:
        return float("inf")
    if sp.w.size == 1:
        return 1.0
    sv = np.linalg.svd(sp.V, compute_uv=False)
    return float(sv[0] / sv[-1]) if sv[-1] > 0 else float("inf")


def kappa_fro(X: ArrayLike, *, tol: float | None = None) -> float:
    """Frobenius-norm condition number ``||V||_F ||V^-1||_F`` of the unit-column eigenvector matrix.

    With unit columns ``||V||_F = sqrt(n)``, so ``kappa_fro >= n`` (equality for a normal
    matrix with distinct eigenvalues); Lam & Tam (1997) minimize it (seed 001, ref [5]).

    Parameters
    ----------
    X : (n, n) array_like
    tol : float, optional
        Relative coincidence tolerance (default ``8 n eps``).

    Returns
    -------
    float
        ``inf`` for numerically coincident eigenvalues; 1.0 for a 1 x 1 matrix.

    Raises
    ------
    DimensionError, NotFiniteError

    Examples
    --------
    >>> from optdesign.metrics import kappa_fro
    >>> round(kappa_fro([[-1.0, 0.0], [0.0, -2.0]]), 6)   # orthonormal eigenvectors: n
    2.0
    """
    sp = _spectrum(_as_square(X), tol)
    if sp.coincident or sp.Vinv is None:
        return float("inf")
    return float(np.linalg.norm(sp.V) * np.linalg.norm(sp.Vinv))


def departure(X: ArrayLike) -> float:
    """Henrici's departure from normality, ``||N||_F`` of the complex Schur form ``U^H X U = Lambda + N``.

    Equivalently ``sqrt(||X||_F^2 - sum |lambda_i|^2)`` (this identity is not used, since it
    loses all accuracy by cancellation when X is nearly normal).  Zero exactly for normal
    matrices, finite for every matrix (defective ones included).

    Parameters
    ----------
    X : (n, n) array_like

    Returns
    -------
    float

    Raises
    ------
    DimensionError, NotFiniteError

    Notes
    -----
    The *complex* Schur form is essential: the real Schur form keeps 2 x 2 blocks for complex
    pairs, and the strictly upper triangular part of a real Schur form contains one
    off-diagonal entry of each block -- which is not part of ``N`` (seed 001's printed
    eta = 2.41 for the aircraft example is that real-Schur quantity; the departure gives 3.107).

    Examples
    --------
    >>> from optdesign.metrics import departure
    >>> round(departure([[-1.0, 10.0], [0.0, -2.0]]), 6)   # the strictly upper part of the Schur form
    10.0
    """
    A = _as_square(X)
    scale = _pow2_scale(A)
    T, _ = _schur(A / scale)
    return float(np.linalg.norm(np.triu(T, 1))) * scale


def min_gap(X: ArrayLike, *, tol: float | None = None) -> float:
    """Smallest distance between two eigenvalues, ``min_{i != j} |lambda_i - lambda_j|``.

    Parameters
    ----------
    X : (n, n) array_like
    tol : float, optional
        Relative coincidence tolerance (default ``8 n eps``).

    Returns
    -------
    float
        0.0 when two eigenvalues are numerically coincident (so a Jordan block gives exactly
        0, not its ~sqrt(eps) rounding split); ``inf`` for a 1 x 1 matrix (no pair).

    Raises
    ------
    DimensionError, NotFiniteError

    Examples
    --------
    >>> from optdesign.metrics import min_gap
    >>> round(min_gap([[-1.0, 10.0], [0.0, -2.0]]), 6)
    1.0
    """
    sp = _spectrum(_as_square(X), tol)
    return 0.0 if sp.coincident else sp.gap


def eta(X: ArrayLike, *, tol: float | None = None) -> float:
    """Huh & Stein's non-normality measure ``departure(X) / min_gap(X)`` (seed 001 eq (1)).

    Parameters
    ----------
    X : (n, n) array_like
    tol : float, optional
        Relative coincidence tolerance (default ``8 n eps``).

    Returns
    -------
    float
        ``inf`` for numerically coincident eigenvalues (also for a normal matrix with a
        repeated eigenvalue, where the ratio is 0/0); 0.0 for a 1 x 1 matrix.

    Raises
    ------
    DimensionError, NotFiniteError

    Notes
    -----
    For 2 x 2 matrices ``kappa2(X) = eta + sqrt(1 + eta^2)`` (seed 001 eq (19)); in general
    Huh & Stein bound kappa2 by a monotone function of eta.

    Examples
    --------
    >>> from optdesign.metrics import eta
    >>> eta([[-1.0, 0.0], [0.0, -2.0]])            # normal: no departure
    0.0
    >>> round(eta([[-1.0, 10.0], [0.0, -2.0]]), 6)   # ||N||_F / gap = 10 / 1
    10.0
    """
    sp = _spectrum(_as_square(X), tol)
    if sp.w.size == 1:
        return 0.0
    if sp.coincident:
        return float("inf")
    return sp.departure / sp.gap


def condition_summary(X: ArrayLike, *, tol: float | None = None) -> dict[str, float | bool]:
    """All metrics of ``X`` at once (one eigendecomposition, one Schur form).

    Parameters
    ----------
    X : (n, n) array_like
    tol : float, optional
        Relative coincidence tolerance (default ``8 n eps``).

    Returns
    -------
    dict
        ``{"kappa2", "kappa_fro", "departure", "min_gap", "eta", "rounding_floor"}`` (floats, as
        returned by the individual functions; ``rounding_floor``: :func:`eigenvalue_rounding_floor`)
        and ``"coincident"`` (bool: two eigenvalues are numerically coincident, hence the
        infinities).

    Raises
    ------
    DimensionError, NotFiniteError
    """
    A = _as_square(X)
    n = A.shape[0]
    sp = _spectrum(A, tol)
    dep = sp.departure
    floor = _rounding_floor(sp, float(np.linalg.norm(A)))
    if n == 1:
        return {"kappa2": 1.0, "kappa_fro": 1.0, "departure": dep, "min_gap": float("inf"),
                "eta": 0.0, "coincident": False, "rounding_floor": floor}
    if sp.coincident or sp.Vinv is None:
        inf = float("inf")
        return {"kappa2": inf, "kappa_fro": inf, "departure": dep, "min_gap": 0.0,
                "eta": inf, "coincident": True, "rounding_floor": floor}
    sv = np.linalg.svd(sp.V, compute_uv=False)
    return {
        "kappa2": float(sv[0] / sv[-1]),
        "kappa_fro": float(np.linalg.norm(sp.V) * np.linalg.norm(sp.Vinv)),
        "departure": dep,
        "min_gap": sp.gap,
        "eta": dep / sp.gap,
        "coincident": False,
        "rounding_floor": floor,
    }


def _rounding_floor(sp: _Spectrum, norm_x: float) -> float:
    """:func:`eigenvalue_rounding_floor` from a computed spectrum (the same V and ``V^-1``)."""
    if sp.w.size == 0:
        return 0.0
    s = np.linalg.norm(sp.Vinv, axis=1) if sp.Vinv is not None else np.full(sp.w.shape, np.inf)
    floor = 10.0 * _EPS * float(np.max(s * norm_x / np.maximum(1.0, np.abs(sp.w))))
    return floor if np.isfinite(floor) else float("inf")
