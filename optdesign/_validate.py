"""Input validation shared by every layer (private).

Each helper names the matrix in its error message and states expected vs found,
in the style of ``scipy.linalg._solvers``.  Never use ``assert`` for validation.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .errors import (
    DimensionError,
    NotConjugateClosedError,
    NotFiniteError,
    NotPositiveDefiniteError,
    NotPositiveSemidefiniteError,
    NotSymmetricError,
    ValidationError,
)

__all__ = [
    "as_matrix",
    "as_square",
    "as_vector",
    "check_symmetric",
    "check_psd",
    "check_pd",
    "as_poles",
    "as_positive_float",
    "as_int",
    "as_bool",
    "sym_tol",
]


def _shape_str(shape: Sequence[int | None]) -> str:
    return "(" + ", ".join("?" if s is None else str(s) for s in shape) + ")"


def as_matrix(
    name: str,
    X: ArrayLike,
    shape: tuple[int | None, int | None] | None = None,
    *,
    allow_complex: bool = False,
) -> NDArray[np.float64]:
    """Return ``X`` as a finite 2-D float (or complex) array, checking its shape.

    Scalars become (1, 1); 1-D input is *not* silently reshaped (ambiguous between a row
    and a column), except when ``shape`` fixes one side to 1.
    """
    try:
        arr = np.asarray(X)
    except Exception as exc:  # ragged lists etc.
        raise ValidationError(f"{name} could not be converted to an array: {exc}") from None
    if arr.dtype == object:
        raise ValidationError(f"{name} must be a numeric matrix; found a ragged or non-numeric array")
    if np.iscomplexobj(arr):
        if not allow_complex:
            if np.any(np.imag(arr) != 0):
                raise ValidationError(f"{name} must be real; found complex entries")
            arr = np.real(arr)
    elif not (np.issubdtype(arr.dtype, np.number) or arr.dtype == bool):
        raise ValidationError(f"{name} must be numeric; found dtype {arr.dtype}")
    arr = arr.astype(complex if np.iscomplexobj(arr) else float)
    if arr.ndim == 0:
        arr = arr.reshape(1, 1)
    elif arr.ndim == 1 and shape is not None:
        if shape[1] == 1:
            arr = arr.reshape(-1, 1)
        elif shape[0] == 1:
            arr = arr.reshape(1, -1)
    if arr.ndim != 2:
        expected = _shape_str(shape) if shape is not None else "a 2-D matrix"
        raise DimensionError(f"{name} must be 2-D with shape {expected}; found {arr.ndim}-D shape {arr.shape}")
    if shape is not None:
        for k in (0, 1):
            if shape[k] is not None and arr.shape[k] != shape[k]:
                raise DimensionError(
                    f"{name} has the wrong shape: expected {_shape_str(shape)}, found {arr.shape}"
                )
    if arr.size and not np.all(np.isfinite(arr)):
        bad = np.argwhere(~np.isfinite(arr))[0]
        raise NotFiniteError(
            f"{name} must be finite; found {arr[tuple(bad)]} at index {tuple(int(b) for b in bad)}"
        )
    return arr


def as_square(name: str, X: ArrayLike, n: int | None = None) -> NDArray[np.float64]:
    """A finite square matrix (of order ``n`` if given)."""
    arr = as_matrix(name, X)
    if arr.shape[0] != arr.shape[1]:
        raise DimensionError(f"{name} must be square; found shape {arr.shape}")
    if n is not None and arr.shape[0] != n:
        raise DimensionError(f"{name} has the wrong shape: expected ({n}, {n}), found {arr.shape}")
    return arr


def as_vector(name: str, x: ArrayLike, n: int | None = None, *, allow_complex: bool = False) -> NDArray:
    """A finite 1-D vector (of length ``n`` if given)."""
    arr = np.asarray(x)
    if arr.dtype == object:
        raise ValidationError(f"{name} must be a numeric vector; found a ragged or non-numeric array")
    if np.iscomplexobj(arr) and not allow_complex:
        if np.any(np.imag(arr) != 0):
            raise ValidationError(f"{name} must be real; found complex entries")
        arr = np.real(arr)
    arr = np.atleast_1d(arr).astype(complex if np.iscomplexobj(arr) else float)
    if arr.ndim != 1:
        arr = arr.squeeze()
        if arr.ndim != 1:
            raise DimensionError(f"{name} must be a vector; found shape {np.shape(x)}")
    if n is not None and arr.shape[0] != n:
        raise DimensionError(f"{name} has the wrong length: expected {n}, found {arr.shape[0]}")
    if not np.all(np.isfinite(arr)):
        raise NotFiniteError(f"{name} must be finite; found {arr[~np.isfinite(arr)][0]}")
    return arr


def sym_tol(X: NDArray) -> float:
    """Absolute tolerance for symmetry / definiteness tests, scaled with ||X||."""
    return 100.0 * np.finfo(float).eps * max(1.0, float(np.linalg.norm(X, 1))) * max(1, X.shape[0])


def check_symmetric(name: str, X: NDArray, tol: float | None = None) -> NDArray[np.float64]:
    """Raise unless ``X`` is symmetric to ``tol``; return the exactly symmetrized matrix."""
    if X.shape[0] != X.shape[1]:
        raise DimensionError(f"{name} must be square; found shape {X.shape}")
    tol = sym_tol(X) if tol is None else tol
    asym = float(np.max(np.abs(X - X.T))) if X.size else 0.0
    if asym > tol:
        raise NotSymmetricError(f"{name} must be symmetric; found max |{name} - {name}'| = {asym:.3g} > {tol:.3g}")
    return 0.5 * (X + X.T)


def check_psd(name: str, X: NDArray, tol: float | None = None) -> NDArray[np.float64]:
    """Raise unless ``X`` is symmetric positive semidefinite; return it symmetrized."""
    X = check_symmetric(name, X, tol)
    if X.size == 0:
        return X
    tol = sym_tol(X) if tol is None else tol
    lmin = float(np.linalg.eigvalsh(X)[0])
    if lmin < -tol:
        raise NotPositiveSemidefiniteError(
            f"{name} must be positive semidefinite; found smallest eigenvalue {lmin:.6g}"
        )
    return X


def check_pd(name: str, X: NDArray) -> NDArray[np.float64]:
    """Raise unless ``X`` is symmetric positive definite; return it symmetrized."""
    X = check_symmetric(name, X)
    if X.size == 0:
        return X
    lmin = float(np.linalg.eigvalsh(X)[0])
    if not lmin > sym_tol(X):
        raise NotPositiveDefiniteError(
            f"{name} must be positive definite; found smallest eigenvalue {lmin:.6g}"
        )
    return X


def as_positive_float(name: str, value, *, allow_zero: bool = False) -> float:
    """A finite positive scalar."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValidationError(f"{name} must be a real number; found {value!r}") from None
    if not np.isfinite(v) or v < 0 or (v == 0 and not allow_zero):
        cond = ">= 0" if allow_zero else "> 0"
        raise ValidationError(f"{name} must be finite and {cond}; found {value!r}")
    return v


def as_int(name: str, value, lo: int = 0) -> int:
    """An integer ``>= lo`` (Python or numpy integer; bool, float and str are refused)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)) or value < lo:
        raise ValidationError(f"{name} must be an integer >= {lo}; found {value!r}")
    return int(value)


def as_bool(name: str, value) -> bool:
    """A boolean (Python or numpy bool; 0/1 and strings such as "yes" are refused)."""
    if not isinstance(value, (bool, np.bool_)):
        raise ValidationError(f"{name} must be true or false; found {value!r}")
    return bool(value)


def as_poles(name: str, poles: ArrayLike, n: int | None = None, *, tol: float = 1e-8) -> NDArray[np.complex128]:
    """Validate a set of desired poles for a real system.

    Returns the poles as a complex vector, sorted with conjugate pairs adjacent
    (the member with positive imaginary part first) and conjugates made exact.

    Raises
    ------
    DimensionError
        Wrong number of poles.
    NotConjugateClosedError
        A complex pole without its conjugate (with multiplicity).
    """
    p = as_vector(name, poles, n, allow_complex=True).astype(complex)
    scale = max(1.0, float(np.max(np.abs(p)))) if p.size else 1.0
    is_real = np.abs(p.imag) <= tol * scale
    real = np.sort(p[is_real].real)
    cplx = list(p[~is_real])
    out: list[complex] = [complex(r) for r in real]
    upper = sorted((z for z in cplx if z.imag > 0), key=lambda z: (z.real, z.imag))
    lower = [z for z in cplx if z.imag < 0]
    for z in upper:
        if not lower:
            raise NotConjugateClosedError(f"{name} is not closed under complex conjugation: {z} has no partner")
        k = int(np.argmin([abs(w - np.conj(z)) for w in lower]))
        if abs(lower[k] - np.conj(z)) > 1e3 * tol * scale:
            raise NotConjugateClosedError(
                f"{name} is not closed under complex conjugation: {z} has no partner "
                f"(nearest candidate {lower[k]})"
            )
        w = lower.pop(k)
        zz = complex(0.5 * (z.real + w.real), 0.5 * (z.imag - w.imag))
        out.extend([zz, zz.conjugate()])
    if lower:
        raise NotConjugateClosedError(
            f"{name} is not closed under complex conjugation: {lower[0]} has no partner"
        )
    return np.asarray(out, dtype=complex)
