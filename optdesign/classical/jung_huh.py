r"""Closed forms of seed 001 (Jung & Huh): second-order observers and Kalman filters.

The plant of seed 001, section 2.2, is the observable second-order companion form

.. math::

    A = \begin{bmatrix} 0 & 1 \\ a_1 & a_2 \end{bmatrix},\qquad C = [1\ \ 0],\qquad
    A - LC = \begin{bmatrix} -l_1 & 1 \\ a_1 - l_2 & a_2 \end{bmatrix} \quad (4)

Writing ``s = a2 + l1`` and ``c = a1 - l2``, the eigenvalues are ``(a2 - l1 +- sqrt(D)) / 2``
with discriminant ``D = s^2 + 4 c`` (eq 5).  The non-normality measure of the complex Schur
form follows from ``||N||_F^2 = ||X||_F^2 - |lambda_1|^2 - |lambda_2|^2``:

* real poles (``D > 0``): ``eta = |c - 1| / sqrt(D)``.  The paper's eq (21) prints
  ``|a1 - l2 + 1|`` in the numerator: the sign of the 1 is wrong (eq 15-17 give
  ``mn = -1/c`` and ``m - n = -sqrt(D)/c``, hence ``|mn + 1| / |m - n| = |c - 1| / sqrt(D)``);
  the paper's own Example 1 value ``kappa2 = 1.59`` at ``L = [10, 5]`` needs the corrected sign.
* complex poles (``D < 0``, which the paper does not treat although its second Example 1
  gain ``L = [10, 45]`` has complex poles): ``eta = sqrt(s^2 + (c + 1)^2) / sqrt(-D)``.
* ``D = 0``: a double eigenvalue, ``eta = kappa2 = inf``.

For every 2 x 2 matrix ``kappa2 = eta + sqrt(1 + eta^2)`` (eq 19), so bounds on eta are bounds
on kappa2: ``eta <= beta`` is ``kappa2 <= beta + sqrt(1 + beta^2)`` (2 + sqrt 5 for beta = 2).

Stability (eq 20) is ``l1 > a2`` and ``l2 > a1 + a2 l1``; the region ``{stable, eta <= beta}``
(seed 001 Fig. 2) is, for each ``l1``, the union of at most two ``l2``-intervals bounded by the
roots of two quadratics in ``c`` (:func:`observer_2x2_gain_region`).

Kalman filter of section 2.3: ``A = [[0, 1], [a, b]]``, ``G = [0, 1]'``, ``C = [1, 0]``,
``Q = q``, ``R = r``.  The steady-state gain depends on ``q/r`` only (eq 29):
``l1 = b + S``, ``l2 = a + b^2 + W + b S`` with ``W = sqrt(a^2 + q/r)``,
``S = sqrt(b^2 + 2a + 2W)``.  Eq (30)/(31) give eta only while the filter poles are real
(``b^2 + 2a > 2W``); :func:`kalman_2x2_eta` covers both cases, and :func:`kalman_2x2_eta_set`
returns the exact set of ``q/r`` with ``eta <= beta``: in terms of ``S`` the condition is a
quartic inequality on each branch, whose roots are found with ``numpy.roots`` and then
bracketed and polished with Brent's method on eta itself.

References
----------
Jung, J. & Huh, K., "Design of the well-conditioned observer using the non-normality
measure" (seed 001), eq (4)-(21), (29)-(31), Examples 1-2.
Huh, K. & Stein, J. L., "A non-normality measure of the condition number for monitoring
and control", ASME J. Dyn. Sys. Meas. Control 119 (1997) 217-222.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._validate import as_positive_float
from ..errors import DimensionError, ValidationError

__all__ = [
    "kappa2_from_eta_2x2",
    "eta_from_kappa2_2x2",
    "observer_2x2_poles",
    "observer_2x2_eta",
    "observer_2x2_kappa2",
    "observer_2x2_stable",
    "observer_2x2_gain_region",
    "jung_huh_eq21_printed",
    "kalman_2x2_gain",
    "kalman_2x2_eta",
    "kalman_2x2_kappa2",
    "kalman_2x2_eta_set",
    "QRSet",
]


def _real(name: str, x) -> float:
    try:
        v = float(x)
    except (TypeError, ValueError):
        raise ValidationError(f"{name} must be a real number; found {x!r}") from None
    if not np.isfinite(v):
        raise ValidationError(f"{name} must be finite; found {x!r}")
    return v


def _arr(name: str, x) -> NDArray[np.float64]:
    try:
        a = np.asarray(x, dtype=float)
    except (TypeError, ValueError):  # strings, complex numbers, ragged sequences
        raise ValidationError(f"{name} must be a real number or array of real numbers; found {x!r}") from None
    if not np.all(np.isfinite(a)):
        raise ValidationError(f"{name} must be finite; found a NaN or Inf entry")
    return a


def _companion_and_gains(a1, a2, l1, l2) -> tuple[float, float, NDArray[np.float64], NDArray[np.float64]]:
    """Validated ``a1, a2`` (scalars) and ``l1, l2`` broadcast together."""
    a1, a2 = _real("a1", a1), _real("a2", a2)
    l1, l2 = _arr("l1", l1), _arr("l2", l2)
    try:
        l1, l2 = np.broadcast_arrays(l1, l2)
    except ValueError:
        raise DimensionError(
            f"l1 and l2 must broadcast together; found shapes {l1.shape} and {l2.shape}"
        ) from None
    return a1, a2, l1, l2


def kappa2_from_eta_2x2(eta: ArrayLike) -> NDArray[np.float64]:
    """``kappa2 = eta + sqrt(1 + eta^2)`` for 2 x 2 matrices (seed 001 eq 19).

    Eq (19) prints ``sqrt(1 + 2 eta^2 + 2 eta sqrt(1 + eta^2))``, which is the same number
    (the square of ``eta + sqrt(1 + eta^2)`` is ``1 + 2 eta^2 + 2 eta sqrt(1 + eta^2)``).

    Parameters
    ----------
    eta : array_like, >= 0 (``inf`` allowed)

    Returns
    -------
    ndarray (0-d for scalar input)
    """
    e = np.asarray(eta, dtype=float)
    with np.errstate(invalid="ignore", over="ignore"):
        out = np.where(np.isinf(e), np.inf, e + np.sqrt(1.0 + e * e))
    return out


def eta_from_kappa2_2x2(kappa2: ArrayLike) -> NDArray[np.float64]:
    """Inverse of :func:`kappa2_from_eta_2x2`: ``eta = (kappa2 - 1/kappa2) / 2``."""
    k = np.asarray(kappa2, dtype=float)
    with np.errstate(invalid="ignore"):
        return np.where(np.isinf(k), np.inf, 0.5 * (k - 1.0 / k))


def observer_2x2_poles(a1: float, a2: float, l1: ArrayLike, l2: ArrayLike) -> NDArray[np.complex128]:
    """Eigenvalues of ``A - L C`` for the companion plant of seed 001 (eq 5).

    Parameters
    ----------
    a1, a2 : float
        ``A = [[0, 1], [a1, a2]]``, ``C = [1, 0]``.
    l1, l2 : array_like (broadcast together)
        Observer gain entries.

    Returns
    -------
    (..., 2) ndarray of complex
        ``(a2 - l1 + sqrt(D)) / 2`` and ``(a2 - l1 - sqrt(D)) / 2``, ``D = (a2 + l1)^2 + 4 (a1 - l2)``.
    """
    a1, a2, l1, l2 = _companion_and_gains(a1, a2, l1, l2)
    D = (a2 + l1) ** 2 + 4.0 * (a1 - l2)
    r = np.sqrt(D.astype(complex))
    return np.stack([(a2 - l1 + r) / 2.0, (a2 - l1 - r) / 2.0], axis=-1)


def observer_2x2_eta(a1: float, a2: float, l1: ArrayLike, l2: ArrayLike) -> NDArray[np.float64]:
    """Non-normality measure of ``A - L C`` in closed form (seed 001 eq 21, corrected).

    Parameters
    ----------
    a1, a2 : float
        ``A = [[0, 1], [a1, a2]]``, ``C = [1, 0]``.
    l1, l2 : array_like (broadcast together)

    Returns
    -------
    ndarray of float
        ``|c - 1| / sqrt(D)`` for real poles, ``sqrt(s^2 + (c + 1)^2) / sqrt(-D)`` for complex
        poles, ``inf`` for a double pole, with ``s = a2 + l1``, ``c = a1 - l2``, ``D = s^2 + 4c``.

    Notes
    -----
    Eq (21) of the paper has ``|a1 - l2 + 1|`` in the numerator (sign error) and covers the
    real-pole case only; :func:`jung_huh_eq21_printed` evaluates the printed formula.

    References
    ----------
    Seed 001, eq (4)-(21).
    """
    a1, a2, l1, l2 = _companion_and_gains(a1, a2, l1, l2)
    s = a2 + l1
    c = a1 - l2
    D = s * s + 4.0 * c
    with np.errstate(divide="ignore", invalid="ignore"):
        real_case = np.abs(c - 1.0) / np.sqrt(np.abs(D))
        cplx_case = np.sqrt(s * s + (c + 1.0) ** 2) / np.sqrt(np.abs(D))
    out = np.where(D > 0, real_case, cplx_case)
    return np.where(D == 0, np.inf, out)


def observer_2x2_kappa2(a1: float, a2: float, l1: ArrayLike, l2: ArrayLike) -> NDArray[np.float64]:
    """kappa2 of ``A - L C`` in closed form: eq (19) applied to :func:`observer_2x2_eta`."""
    return kappa2_from_eta_2x2(observer_2x2_eta(a1, a2, l1, l2))


def jung_huh_eq21_printed(a1: float, a2: float, l1: ArrayLike, l2: ArrayLike) -> NDArray[np.float64]:
    """Eq (21) exactly as printed: ``|a1 - l2 + 1| / sqrt((a2 + l1)^2 + 4 (a1 - l2))``.

    Kept only to document the paper's error: it is not eta (wrong sign of the 1; and it is
    ``nan`` for complex poles, where the square root has a negative argument).
    """
    a1, a2, l1, l2 = _companion_and_gains(a1, a2, l1, l2)
    D = (a2 + l1) ** 2 + 4.0 * (a1 - l2)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.abs(a1 - l2 + 1.0) / np.sqrt(D)


def observer_2x2_stable(a1: float, a2: float, l1: ArrayLike, l2: ArrayLike) -> NDArray[np.bool_]:
    """Constraint 1 of seed 001 (eq 20): ``l1 - a2 > 0`` and ``l2 - a1 - a2 l1 > 0`` (Hurwitz)."""
    a1, a2, l1, l2 = _companion_and_gains(a1, a2, l1, l2)
    return (l1 - a2 > 0) & (l2 - a1 - a2 * l1 > 0)


def observer_2x2_gain_region(a1: float, a2: float, beta: float, l1: float) -> list[tuple[float, float]]:
    """The ``l2``-intervals where ``A - L C`` is stable and ``eta <= beta`` (seed 001 Fig. 2).

    Parameters
    ----------
    a1, a2 : float
        ``A = [[0, 1], [a1, a2]]``, ``C = [1, 0]``.
    beta : float, > 0
        Bound on eta (Constraint 2); inside the region ``kappa2 <= beta + sqrt(1 + beta^2)``.
    l1 : float
        First gain entry.

    Returns
    -------
    list of (l2_lo, l2_hi)
        Disjoint, sorted intervals (closed at the eta bound; the stability boundary
        ``l2 = a1 + a2 l1`` itself is excluded, it is an open constraint).  Empty when
        ``l1 <= a2`` (unstable for every ``l2``).

    Notes
    -----
    With ``s = a2 + l1``, ``c = a1 - l2``, ``eta <= beta`` is

    * real poles: ``c^2 - (2 + 4 beta^2) c + 1 - beta^2 s^2 <= 0``, the interval
      ``c in (1 + 2 beta^2) -+ sqrt(4 beta^2 (1 + beta^2) + beta^2 s^2)``, which always lies
      on the real-pole side ``c > -s^2/4``;
    * complex poles: ``c^2 + (2 + 4 beta^2) c + 1 + (1 + beta^2) s^2 <= 0``, non-empty only for
      ``|s| <= 2 beta``: ``c in -(1 + 2 beta^2) -+ sqrt((1 + beta^2)(4 beta^2 - s^2))``, always on
      the complex side ``c < -s^2/4``.

    Stability requires ``c < -a2 l1``.

    Raises
    ------
    ValidationError
        Non-finite input or ``beta <= 0``.
    """
    a1, a2, l1 = _real("a1", a1), _real("a2", a2), _real("l1", l1)
    beta = as_positive_float("beta", beta)
    if not l1 > a2:
        return []
    s = a2 + l1
    b2 = beta * beta
    c_max = -a2 * l1  # stability: c < c_max (open)
    c_int: list[tuple[float, float]] = []
    disc_c = (1.0 + b2) * (4.0 * b2 - s * s)
    if disc_c >= 0:
        r = np.sqrt(disc_c)
        c_int.append((-(1.0 + 2.0 * b2) - r, -(1.0 + 2.0 * b2) + r))
    r = np.sqrt(4.0 * b2 * (1.0 + b2) + b2 * s * s)
    c_int.append(((1.0 + 2.0 * b2) - r, (1.0 + 2.0 * b2) + r))
    out = []
    for lo, hi in c_int:
        hi = min(hi, c_max)
        if hi > lo or (hi == lo and hi < c_max):
            out.append((float(a1 - hi), float(a1 - lo)))  # l2 = a1 - c reverses the order
    return sorted(out)


# --------------------------------------------------------------------------- Kalman (sec 2.3)


def _qr(name: str, x) -> NDArray[np.float64]:
    a = _arr(name, x)
    if np.any(a < 0):
        raise ValidationError(f"{name} (= q/r) must be >= 0; found {a[a < 0].ravel()[0]!r}")
    return a


def kalman_2x2_gain(a: float, b: float, q_over_r: ArrayLike) -> NDArray[np.float64]:
    """Steady-state Kalman gain of seed 001 eq (29).

    Plant ``A = [[0, 1], [a, b]]``, ``G = [0, 1]'``, ``C = [1, 0]``, ``Q = q``, ``R = r``;
    the gain ``L = P C' / r`` of the stabilizing solution of ``AP + PA' - PC'CP/r + GG'q = 0``.

    Parameters
    ----------
    a, b : float
    q_over_r : array_like, >= 0

    Returns
    -------
    (..., 2) ndarray
        ``[l1, l2] = [b + S, a + b^2 + W + b S]``, ``W = sqrt(a^2 + q/r)``, ``S = sqrt(b^2 + 2a + 2W)``.

    Raises
    ------
    ValidationError
        ``q_over_r`` negative or non-finite.

    References
    ----------
    Seed 001, eq (28)-(29).  (Eq (28) prints ``p11`` and ``p12``; ``L = [p11, p12] / r``.)
    """
    a, b = _real("a", a), _real("b", b)
    x = _qr("q_over_r", q_over_r)
    W = np.sqrt(a * a + x)
    S = np.sqrt(np.maximum(b * b + 2.0 * a + 2.0 * W, 0.0))  # >= 0 since W >= |a|
    return np.stack([b + S, a + b * b + W + b * S], axis=-1)


def kalman_2x2_eta(a: float, b: float, q_over_r: ArrayLike) -> NDArray[np.float64]:
    """eta of the Kalman error dynamics ``A - L C`` versus ``q/r`` (seed 001 eq 30, both cases).

    Eq (30) holds only while the filter poles are real (``b^2 + 2a > 2 sqrt(a^2 + q/r)``);
    beyond that point its denominator is the square root of a negative number.  This
    function evaluates the corrected closed form of :func:`observer_2x2_eta` at the gain of
    eq (29), which covers both cases.
    """
    G = kalman_2x2_gain(a, b, q_over_r)
    return observer_2x2_eta(a, b, G[..., 0], G[..., 1])


def kalman_2x2_kappa2(a: float, b: float, q_over_r: ArrayLike) -> NDArray[np.float64]:
    """kappa2 of the Kalman error dynamics versus ``q/r`` (eq 19 applied to :func:`kalman_2x2_eta`)."""
    return kappa2_from_eta_2x2(kalman_2x2_eta(a, b, q_over_r))


@dataclass(frozen=True)
class QRSet:
    """The set of noise ratios ``q/r >= 0`` whose Kalman filter has ``eta <= beta``.

    Attributes
    ----------
    intervals : tuple of (float, float)
        Disjoint closed intervals, sorted (the upper end may be ``inf``).
    beta : float
    boundary : tuple of float
        The roots of ``eta(q/r) = beta`` (polished with Brent's method).
    double_pole : float or None
        The ``q/r`` at which the filter has a double pole (``eta = inf``), if any.
    """

    intervals: tuple[tuple[float, float], ...]
    beta: float
    boundary: tuple[float, ...]
    double_pole: float | None

    def contains(self, q_over_r: ArrayLike) -> NDArray[np.bool_]:
        """Membership test (vectorized)."""
        x = np.asarray(q_over_r, dtype=float)
        out = np.zeros(x.shape, dtype=bool)
        for lo, hi in self.intervals:
            out |= (x >= lo) & (x <= hi)
        return out

    def __str__(self) -> str:
        parts = [f"[{lo:.6g}, {hi:.6g}]" for lo, hi in self.intervals]
        return " U ".join(parts) if parts else "(empty)"


def kalman_2x2_eta_set(a: float, b: float, beta: float) -> QRSet:
    """Exact set of ``q/r`` for which the seed-001 Kalman filter has ``eta <= beta``.

    Parameters
    ----------
    a, b : float
        ``A = [[0, 1], [a, b]]``, ``G = [0, 1]'``, ``C = [1, 0]``.
    beta : float, > 0

    Returns
    -------
    QRSet

    Notes
    -----
    With ``S = sqrt(b^2 + 2a + 2W)`` (a monotone reparametrization of ``q/r``, ``W = (S^2 - b^2
    - 2a)/2``), ``eta^2 <= beta^2`` becomes a quartic polynomial inequality in ``S`` on each
    branch:

    * real poles (``S^2 < 2b^2 + 4a``): ``(b^2 + 1 + bS + W)^2 - beta^2 (2b^2 + 4a - S^2) <= 0``;
    * complex poles (``S^2 > 2b^2 + 4a``): ``(2b + S)^2 + (1 - b^2 - bS - W)^2
      - beta^2 (S^2 - 2b^2 - 4a) <= 0``.

    The real roots of both quartics in the admissible range, the double-pole point and
    ``q/r = 0`` split ``[0, inf)`` into pieces on which membership is constant; each root is
    bracketed on the ``q/r`` axis and polished with :func:`scipy.optimize.brentq` applied to
    ``kalman_2x2_eta - beta``; membership of each piece is decided at its midpoint.

    Seed 001 prints ``q/r < 1.3 or 4 < q/r < 146`` for ``a = 2, b = -1, beta = 2``; that does not
    reproduce (the exact set is computed here; see ``tests/test_jung_huh.py``).

    Raises
    ------
    ValidationError
        Non-finite ``a``, ``b`` or ``beta <= 0``.
    """
    from scipy.optimize import brentq

    a, b = _real("a", a), _real("b", b)
    beta = as_positive_float("beta", beta)
    b2 = beta * beta
    k0 = b * b + 2.0 * a  # S^2 = k0 + 2W
    s_min = np.sqrt(max(k0 + 2.0 * abs(a), 0.0))  # S at q/r = 0
    split = 2.0 * b * b + 4.0 * a  # S^2 at the double pole

    P = np.polynomial.Polynomial
    S = P([0.0, 1.0])
    W = (S * S - k0) / 2.0
    f_real = (b * b + 1.0 + b * S + W) ** 2 - b2 * (split - S * S)
    f_cplx = (2.0 * b + S) ** 2 + (1.0 - b * b - b * S - W) ** 2 - b2 * (S * S - split)

    def s_to_x(s: float) -> float:
        w = (s * s - k0) / 2.0
        return max(w * w - a * a, 0.0)

    cands: list[float] = []
    for f, real_branch in ((f_real, True), (f_cplx, False)):
        for r in f.roots():
            if abs(r.imag) > 1e-8 * max(1.0, abs(r.real)) or r.real < s_min - 1e-12:
                continue
            s = float(r.real)
            if real_branch != (s * s < split):
                continue
            cands.append(s_to_x(s))
    double_pole = s_to_x(np.sqrt(split)) if split > 0 and np.sqrt(split) >= s_min else None

    def g(x: float) -> float:
        return float(kalman_2x2_eta(a, b, x)) - beta

    roots: list[float] = []
    for x0 in sorted(set(cands)):
        # bracket on the q/r axis around the polynomial root, then polish with Brent
        h = 1e-6 * max(1.0, x0)
        for _ in range(40):
            lo, hi = max(x0 - h, 0.0), x0 + h
            glo, ghi = g(lo), g(hi)
            if np.isfinite(glo) and np.isfinite(ghi) and glo * ghi <= 0:
                roots.append(
                    brentq(g, lo, hi, xtol=1e-14 * max(1.0, x0), rtol=1e-15)
                    if glo * ghi < 0
                    else (lo if glo == 0 else hi)
                )
                break
            if lo == 0.0 and abs(glo) < 1e-12:
                roots.append(0.0)
                break
            h *= 2.0
    roots = sorted(set(roots))
    pts = sorted(set([0.0, *roots] + ([double_pole] if double_pole is not None else [])))
    pieces: list[tuple[float, float]] = []
    bounds = pts + [np.inf]
    for lo, hi in zip(bounds[:-1], bounds[1:], strict=True):
        mid = 2.0 * lo + 1.0 if np.isinf(hi) else 0.5 * (lo + hi)
        if g(mid) <= 0:
            pieces.append((lo, hi))
    # merge pieces that touch at a root (membership on both sides)
    merged: list[tuple[float, float]] = []
    for lo, hi in pieces:
        if merged and merged[-1][1] == lo and (double_pole is None or lo != double_pole):
            merged[-1] = (merged[-1][0], hi)
        else:
            merged.append((lo, hi))
    return QRSet(
        intervals=tuple((float(lo), float(hi)) for lo, hi in merged),
        beta=beta,
        boundary=tuple(float(r) for r in roots),
        double_pole=double_pole,
    )
