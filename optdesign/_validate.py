"""Input validation shared by every layer (private).

Each helper names the matrix in its error message and states expected vs found,
in the style of ``scipy.linalg._solvers``.  Never use ``assert`` for validation.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .errors import (
    DimensionError,
    NotConjugateClosedError,
    NotFiniteError,
    NotPositiveDefiniteError,
    NotPositiveSemidefiniteError,
    NotSymmetricError,
    OptDesignDeprecationWarning,
    ValidationError,
)

__all__ = [
    "renamed",
    "as_array",
    "as_matrix",
    "as_square",
    "as_vector",
    "check_symmetric",
    "check_psd",
    "check_pd",
    "as_poles",
    "as_frequencies",
    "as_real",
    "as_positive_float",
    "as_int",
    "as_bool",
    "as_options",
    "as_rng",
    "as_str",
    "as_gain_mask",
    "sym_tol",
    "shown",
]


def shown(value: object, limit: int = 60) -> str:
    """``repr(value)`` for an error message, at most ``limit`` characters: an integer too long to
    print (Python refuses to convert one of more than 4300 digits) is given by its number of
    digits, a long repr is cut with ``...``."""
    if isinstance(value, int) and not isinstance(value, bool):
        digits = math.ceil(abs(value).bit_length() * math.log10(2)) if value else 1
        if digits > limit:
            return f"{'a negative' if value < 0 else 'an'} integer of about {digits} digits"
    try:
        text = repr(value)
    except ValueError:  # pragma: no cover - a container holding such an integer
        return f"a {type(value).__name__}"
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _shape_str(shape: Sequence[int | None]) -> str:
    return "(" + ", ".join("?" if s is None else str(s) for s in shape) + ")"


def _numeric_array(name: str, X: ArrayLike, what: str, allow_complex: bool) -> NDArray:
    """``X`` as a float (or complex) array; strings -- numeric ones too --, objects, ragged nests and
    complex entries (unless allowed) are refused with a :class:`ValidationError` naming ``name``."""
    if isinstance(X, (str, bytes)):
        raise ValidationError(f"{name} must be a numeric {what}; found the string {X!r}")
    try:
        arr = np.asarray(X)
    except Exception as exc:  # ragged lists etc.
        raise ValidationError(f"{name} could not be converted to an array: {exc}") from None
    if arr.dtype == object:
        raise ValidationError(f"{name} must be a numeric {what}; found a ragged or non-numeric array")
    if arr.dtype.kind in "USV":
        first = arr.ravel()[0] if arr.size else ""
        raise ValidationError(f"{name} must be numeric; found dtype {arr.dtype} (e.g. {str(first)!r}: "
                              "numbers written as strings are not accepted)")
    if np.iscomplexobj(arr):
        if not allow_complex:
            if np.any(np.imag(arr) != 0):
                raise ValidationError(f"{name} must be real; found complex entries")
            arr = np.real(arr)
    elif not (np.issubdtype(arr.dtype, np.number) or arr.dtype == bool):
        raise ValidationError(f"{name} must be numeric; found dtype {arr.dtype}")
    return arr.astype(complex if np.iscomplexobj(arr) else float)


def as_array(
    name: str, X: ArrayLike, ndim: tuple[int, ...], *, allow_complex: bool = False
) -> NDArray[np.float64]:
    """A finite float (or complex) array with one of the allowed numbers of dimensions.

    For data whose shape varies (a signal ``(T,)`` or ``(T, p)``, a row or a matrix); no reshaping.

    Raises
    ------
    ValidationError
        Not numeric (strings, numeric ones included, objects, ragged nests), complex entries
        when ``allow_complex`` is false.
    DimensionError
        ``X.ndim`` not in ``ndim``.
    NotFiniteError
        A NaN or infinite entry (its index is named).
    """
    arr = _numeric_array(name, X, "array", allow_complex)
    if arr.ndim not in ndim:
        dims = " or ".join(f"{d}-D" for d in ndim)
        raise DimensionError(f"{name} must be {dims}; found {arr.ndim}-D shape {arr.shape}")
    _check_finite(name, arr)
    return arr


def _check_finite(name: str, arr: NDArray) -> None:
    if arr.size and not np.all(np.isfinite(arr)):
        bad = np.argwhere(~np.isfinite(arr))[0]
        where = int(bad[0]) if arr.ndim == 1 else tuple(int(b) for b in bad)
        raise NotFiniteError(f"{name} must be finite; found {arr[tuple(bad)]} at index {where}")


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

    Raises
    ------
    ValidationError
        Not numeric (strings, numeric ones included, objects, ragged nests), complex entries
        when ``allow_complex`` is false.
    DimensionError
        Not 2-D, or not of ``shape`` (``None`` entries are free).
    NotFiniteError
        A NaN or infinite entry (its index is named).
    """
    arr = _numeric_array(name, X, "matrix", allow_complex)
    if arr.ndim == 0:
        arr = arr.reshape(1, 1)
    elif arr.ndim == 1 and shape is not None:
        if shape[1] == 1:
            arr = arr.reshape(-1, 1)
        elif shape[0] == 1:
            arr = arr.reshape(1, -1)
    if arr.ndim != 2:
        expected = _shape_str(shape) if shape is not None else "a 2-D matrix"
        raise DimensionError(
            f"{name} must be 2-D with shape {expected}; found {arr.ndim}-D shape {arr.shape}")
    if shape is not None:
        for k in (0, 1):
            if shape[k] is not None and arr.shape[k] != shape[k]:
                raise DimensionError(
                    f"{name} has the wrong shape: expected {_shape_str(shape)}, found {arr.shape}"
                )
    _check_finite(name, arr)
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
    """A finite 1-D vector (of length ``n`` if given).

    A scalar is a vector of length 1.  A 2-D array with one row or one column -- shape ``(1, k)``
    or ``(k, 1)`` -- is an unambiguous vector and is flattened; anything else with more than one
    dimension (e.g. shape ``(2, 2)`` or ``(1, 1, k)``) is refused.

    Raises
    ------
    ValidationError
        Not numeric (strings, numeric ones included, objects, ragged nests); complex entries
        when ``allow_complex`` is false.
    DimensionError
        Not a vector, or the wrong length.
    NotFiniteError
        A NaN or infinite entry (its index is named).
    """
    arr = _numeric_array(name, x, "vector", allow_complex)
    if arr.ndim == 0:
        arr = arr.reshape(1)
    elif arr.ndim == 2 and 1 in arr.shape:
        arr = arr.reshape(-1)
    elif arr.ndim != 1:
        raise DimensionError(
            f"{name} must be a vector (shape (k,), or (1, k) / (k, 1)); found shape {arr.shape}")
    if n is not None and arr.shape[0] != n:
        raise DimensionError(f"{name} has the wrong length: expected {n}, found {arr.shape[0]}")
    _check_finite(name, arr)
    return arr


def as_frequencies(name: str, omega: ArrayLike, *, nonnegative: bool = True) -> NDArray[np.float64]:
    """A non-empty vector of finite real frequencies (rad/s), ``>= 0`` unless ``nonnegative`` is false.

    Frequency grids of the searches (circle condition, margins) are nonnegative: a real system's
    frequency response at ``-w`` is the conjugate of that at ``w``.

    Raises
    ------
    ValidationError
        Not a real numeric vector (see :func:`as_vector`), empty, or a negative entry (named).
    DimensionError, NotFiniteError
        As :func:`as_vector`.
    """
    w = as_vector(name, omega).astype(float)
    if w.size == 0:
        raise DimensionError(f"{name} must contain at least one frequency; found an empty array")
    if nonnegative and np.any(w < 0):
        bad = int(np.flatnonzero(w < 0)[0])
        raise ValidationError(f"{name} must be >= 0 (rad/s); found {w[bad]:g} at index {bad}")
    return w


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
        raise NotSymmetricError(
            f"{name} must be symmetric; found max |{name} - {name}'| = {asym:.3g} > {tol:.3g}")
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


def _is_real_scalar(value: object) -> bool:
    """A Python or numpy integer / float (or a 0-d real numeric array); bool is not a number here."""
    if isinstance(value, (bool, np.bool_)):
        return False
    if isinstance(value, (int, float, np.integer, np.floating)):
        return True
    return isinstance(value, np.ndarray) and value.ndim == 0 and value.dtype.kind in "iuf"


def as_real(name: str, value: object) -> float:
    """A finite real number (Python or numpy int / float).

    Raises
    ------
    ValidationError
        Anything else: a string (numeric ones too), a bool, a complex number, None, an array.
    NotFiniteError
        NaN or infinity.
    """
    if not _is_real_scalar(value):
        kind = "a string" if isinstance(value, (str, bytes)) else type(value).__name__
        raise ValidationError(f"{name} must be a real number; found {value!r} ({kind})")
    v = float(value)  # type: ignore[arg-type]
    if not np.isfinite(v):
        raise NotFiniteError(f"{name} must be finite; found {value!r}")
    return v


def as_positive_float(name: str, value: object, *, allow_zero: bool = False) -> float:
    """A finite scalar ``> 0`` (``>= 0`` with ``allow_zero``): Python or numpy int / float.

    Raises
    ------
    ValidationError
        Not a real number (strings -- numeric ones too --, bools, complex numbers are refused), not
        finite, or not positive.
    """
    cond = ">= 0" if allow_zero else "> 0"
    try:
        v = as_real(name, value)
    except NotFiniteError:
        raise NotFiniteError(f"{name} must be finite and {cond}; found {value!r}") from None
    if v < 0 or (v == 0 and not allow_zero):
        raise ValidationError(f"{name} must be finite and {cond}; found {value!r}")
    return v


def as_int(name: str, value, lo: int = 0) -> int:
    """An integer ``>= lo`` (Python or numpy integer; bool, float and str are refused)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)) or value < lo:
        raise ValidationError(f"{name} must be an integer >= {lo}; found {shown(value)}")
    return int(value)


def as_bool(name: str, value) -> bool:
    """A boolean (Python or numpy bool; 0/1 and strings such as "yes" are refused)."""
    if not isinstance(value, (bool, np.bool_)):
        raise ValidationError(f"{name} must be true or false; found {value!r}")
    return bool(value)


def as_options(name: str, options: object) -> dict[str, Any]:
    """Solver options: ``None`` (none) or a mapping from option names (strings) to values; a copy.

    Raises
    ------
    ValidationError
        Not a mapping (e.g. a list), or a key that is not a string.
    """
    if options is None:
        return {}
    if not isinstance(options, Mapping):
        raise ValidationError(f"{name} must be a dict of solver options (name -> value) or None; found "
                              f"{type(options).__name__} {options!r}")
    bad = [k for k in options if not isinstance(k, str)]
    if bad:
        raise ValidationError(f"{name} keys must be option names (strings); found {bad[0]!r}")
    return dict(options)


def as_rng(name: str, rng: object) -> np.random.Generator:
    """A numpy random generator from ``None`` (fresh entropy), an integer seed ``>= 0``, a
    :class:`numpy.random.SeedSequence` or a :class:`numpy.random.Generator` (returned as is).

    Raises
    ------
    ValidationError
        Anything else (a float, a bool, a string, a negative integer).
    """
    if rng is None or isinstance(rng, (np.random.Generator, np.random.SeedSequence)):
        return np.random.default_rng(rng)
    if isinstance(rng, (bool, np.bool_)) or not isinstance(rng, (int, np.integer)) or rng < 0:
        raise ValidationError(f"{name} must be None, an integer seed >= 0 or a numpy Generator; found "
                              f"{type(rng).__name__} {rng!r}")
    return np.random.default_rng(int(rng))


def as_str(name: str, value: object, choices: Sequence[str] | None = None) -> str:
    """A string (one of ``choices`` if given).

    Raises
    ------
    ValidationError
        Not a string, or not one of ``choices`` (they are listed).
    """
    if not isinstance(value, str):
        expected = "one of " + ", ".join(map(repr, choices)) if choices else "a string"
        raise ValidationError(f"{name} must be {expected}; found {type(value).__name__} {value!r}")
    if choices is not None and value not in choices:
        raise ValidationError(f"{name} must be one of {', '.join(map(repr, choices))}; found {value!r}")
    return value


def as_poles(
    name: str, poles: ArrayLike, n: int | None = None, *, tol: float = 1e-8
) -> NDArray[np.complex128]:
    """Validate a set of desired poles for a real system.

    Returns the poles as a complex vector, sorted with conjugate pairs adjacent
    (the member with positive imaginary part first) and conjugates made exact.

    ``poles`` is a vector of shape ``(k,)``.  A 2-D array is refused, a row ``(1, k)`` or a column
    ``(k, 1)`` too (as scipy's ``place_poles`` refuses them: since 0.2.0, a (k, 1) array was
    flattened before), as are strings, numeric ones included.

    Raises
    ------
    ValidationError
        Not numeric.
    NotFiniteError
        A NaN or infinite pole.
    DimensionError
        Not a vector, or the wrong number of poles.
    NotConjugateClosedError
        A complex pole without its conjugate (with multiplicity).
    """
    if not isinstance(poles, str):
        try:
            shape = np.shape(poles)
        except ValueError:  # ragged: as_vector names it
            shape = ()
        if len(shape) == 2 and 1 in shape:
            raise DimensionError(f"{name} must be a 1-D vector of shape (k,); found shape {shape} "
                                 f"(pass np.ravel({name}) for a row or a column)")
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
            raise NotConjugateClosedError(
                f"{name} is not closed under complex conjugation: {z} has no partner")
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


_UNSET: Any = object()


def _outside_level() -> int:
    """The ``stacklevel`` (for a ``warnings.warn`` in the function calling this one) of the first
    frame outside the optdesign package: a verb's wrapper (``one_warning_per_call``) adds a frame."""
    import os
    import sys

    package = os.path.dirname(os.path.abspath(__file__)) + os.sep
    frame: Any = sys._getframe(1)  # FrameType | None once it leaves the stack
    level = 1
    while frame is not None and os.path.abspath(frame.f_code.co_filename).startswith(package):
        frame, level = frame.f_back, level + 1
    return level


def renamed(new: str, new_value: Any, old: str, old_value: Any, default: Any, *, stacklevel: int = 4) -> Any:
    """An argument renamed in the one vocabulary of the verbs (``structure`` -> ``q_structure``,
    ``solver`` -> ``sdp_solver``, ...): the old spelling is accepted for one release with a
    :class:`~optdesign.errors.OptDesignDeprecationWarning`; both at once is an error.

    ``new_value`` / ``old_value`` are what the caller passed (``None`` = not given); returns the value
    to use (``default`` when neither was given).  The warning points at the first caller outside
    optdesign, however many frames of ours are between (``stacklevel``, kept for the callers, is
    the least level used).

    Raises
    ------
    ValidationError
        Both spellings given.
    """
    import warnings

    if old_value is None:
        return default if new_value is None else new_value
    if new_value is not None:
        raise ValidationError(f"give {new}= or its old spelling {old}=, not both")
    warnings.warn(f"{old}= is deprecated: use {new}= (the old spelling goes in the next release)",
                  OptDesignDeprecationWarning, stacklevel=max(stacklevel, _outside_level()))
    return old_value


def as_gain_mask(name: str, value: object, n: int, p: int, *,
                 label: str = " (mask of free entries of L)") -> NDArray[np.bool_] | None:
    """A mask of the free entries of a gain ``L`` (n, p) as a boolean array; None stays None.

    ``label`` follows ``name`` in the shape message (the design verbs say what the mask is; the solver
    layer leaves it out).

    Raises
    ------
    DimensionError
        Not of shape (n, p).
    ValidationError
        Ragged or non-numeric; entries other than booleans or 0/1; no free entry (L would be zero).
    """
    if value is None:
        return None
    what = f"{name} must be a boolean mask of shape ({n}, {p}) (True = free entry of L)"
    try:
        m = np.asarray(value)
    except (ValueError, TypeError):  # ragged nests
        raise ValidationError(f"{what}; found a ragged or non-numeric {type(value).__name__}") from None
    if m.dtype.kind not in "biuf":
        raise ValidationError(f"{what}; found dtype {m.dtype}")
    if m.shape != (n, p):
        raise DimensionError(f"{name}{label} must have shape ({n}, {p}); found {m.shape}")
    if m.dtype != bool:
        if not np.all(np.isin(m, (0, 1))):
            raise ValidationError(f"{name} must be boolean (a boolean mask: True = free entry of L, "
                                  "False = structural zero); found entries other than 0 and 1")
        m = m.astype(bool)
    if not m.any():
        raise ValidationError(f"{name} has no free entry: L would be zero (nothing to design)")
    return m
