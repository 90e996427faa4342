r"""H2 and H-infinity norms, and the estimation-error channel of an observer.

The estimation error ``e = x - x_hat`` of the observer ``x_hat' = A x_hat + L (y - C x_hat)`` of
the plant ``x' = A x + G w``, ``y = C x + v`` (``E[w w'] = Q``, ``E[v v'] = R``) obeys

.. math::

    e' = (A - L C)\, e + \begin{bmatrix} G Q^{1/2} & -L R^{1/2} \end{bmatrix}
         \begin{bmatrix} \hat w \\ \hat v \end{bmatrix}

with unit-intensity white ``(w^, v^)`` (discrete time: ``e[k+1] = (A - L C) e[k] + ...``, the
predictor form).  :func:`error_channel` returns this system with the error itself as output.

* Its **H2 norm** squared is the steady-state error variance ``trace(Sigma)``,
  ``(A - LC) Sigma + Sigma (A - LC)' + G Q G' + L R L' = 0`` (discrete:
  ``Sigma = (A - LC) Sigma (A - LC)' + G Q G' + L R L'``); the Kalman gain minimizes it.
* Its **H-infinity norm** is the worst-case energy (power) gain from the normalized noise to the
  error, ``sup_w sigma_max(T(j w))``, computed by the level-set (Hamiltonian-eigenvalue)
  iteration of Boyd & Balakrishnan / Bruinsma & Steinbuch: at a level ``gamma`` the purely
  imaginary eigenvalues of a Hamiltonian matrix are exactly the frequencies where a singular
  value of ``T`` equals ``gamma``; the midpoints of those intervals raise the lower bound, and
  a level without imaginary eigenvalues is an upper bound.  Quadratic convergence; the returned
  value is within ``rtol`` (relative) of the norm.  Discrete-time systems are mapped to
  continuous time by the bilinear transform ``z = (1 + s) / (1 - s)``, which preserves the
  H-infinity norm exactly (unit circle -> imaginary axis).

Both norms are ``inf`` for an unstable system (no steady state; unbounded gain).

References
----------
S. Boyd and V. Balakrishnan, "A regularity result for the singular values of a transfer
matrix and a quadratically convergent algorithm for computing its L-infinity norm", Systems &
Control Letters 15, 1990.
N. A. Bruinsma and M. Steinbuch, "A fast algorithm to compute the H-infinity norm of a
transfer function matrix", Systems & Control Letters 14, 1990.
K. Zhou, J. C. Doyle and K. Glover, *Robust and Optimal Control*, Prentice Hall 1996
(H2 norm by Lyapunov equations, chapter 4).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg
from numpy.typing import ArrayLike, NDArray

from .._validate import as_matrix, as_positive_float, as_square
from ..errors import ValidationError
from ..model.model_set import psd_sqrt
from ..model.plant import Plant

__all__ = [
    "HinfNorm",
    "is_stable",
    "h2_norm",
    "hinf_norm",
    "error_channel",
    "error_covariance",
    "estimation_error_h2",
    "estimation_error_hinf",
]


def is_stable(A: ArrayLike, dt: float | None = None) -> bool:
    """Strict stability: every eigenvalue has ``Re < 0`` (continuous) or ``|z| < 1`` (``dt`` given).

    Parameters
    ----------
    A : (n, n) array_like
    dt : float, optional
        Sampling period (its value is not used, only whether it is given).

    Raises
    ------
    DimensionError, NotFiniteError
    """
    w = np.linalg.eigvals(as_square("A", A))
    return bool(np.all(np.abs(w) < 1.0)) if dt is not None else bool(np.all(w.real < 0.0))


def _system(
    A: ArrayLike, B: ArrayLike, C: ArrayLike | None, D: ArrayLike | None
) -> tuple[NDArray, NDArray, NDArray, NDArray]:
    Am = as_square("A", A)
    n = Am.shape[0]
    Bm = as_matrix("B", B, (n, None))
    Cm = np.eye(n) if C is None else as_matrix("C", C, (None, n))
    Dm = np.zeros((Cm.shape[0], Bm.shape[1])) if D is None else as_matrix("D", D, (Cm.shape[0], Bm.shape[1]))
    return Am, Bm, Cm, Dm


def _check_dt(dt: float | None) -> float | None:
    return None if dt is None else as_positive_float("dt", dt)


def h2_norm(A: ArrayLike, B: ArrayLike, C: ArrayLike | None = None, *, dt: float | None = None) -> float:
    """H2 norm of ``(A, B, C)`` (no feedthrough) from the controllability Gramian.

    Parameters
    ----------
    A : (n, n) array_like
    B : (n, m) array_like
    C : (q, n) array_like, optional
        Default: the identity (the state itself is the output).
    dt : float, optional
        Sampling period; ``None`` for continuous time.

    Returns
    -------
    float
        ``sqrt(trace(C W C'))`` with ``A W + W A' + B B' = 0`` (discrete: ``W = A W A' + B B'``);
        ``inf`` when ``A`` is not strictly stable.

    Raises
    ------
    DimensionError, NotFiniteError
        Shapes do not match; a matrix is not finite.
    ValidationError
        ``dt`` not a positive number.

    Examples
    --------
    >>> from optdesign import h2_norm
    >>> round(h2_norm([[-1.0]], [[1.0]], [[1.0]]), 6)      # 1/(s + 1): sqrt(1/2)
    0.707107
    """
    Am, Bm, Cm, _ = _system(A, B, C, None)
    dt = _check_dt(dt)
    if not is_stable(Am, dt):
        return math.inf
    W = _gramian(Am, Bm, dt)
    return math.sqrt(max(0.0, float(np.trace(Cm @ W @ Cm.T))))


def _gramian(A: NDArray, B: NDArray, dt: float | None) -> NDArray[np.float64]:
    BB = B @ B.T
    if dt is None:
        W = scipy.linalg.solve_continuous_lyapunov(A, -BB)
    else:
        W = scipy.linalg.solve_discrete_lyapunov(A, BB)
    return 0.5 * (W + W.T)


@dataclass(frozen=True)
class HinfNorm:
    """An H-infinity norm and where it is attained.

    Attributes
    ----------
    value : float
        The norm (``inf`` for an unstable system), a lower bound within ``rtol`` of the norm.
    frequency : float
        A peak frequency in rad/s (rad/s of the sampled system for discrete time: ``theta / dt``,
        ``theta`` in ``[0, pi]``); ``inf`` when the supremum is the feedthrough's ``sigma_max(D)``
        approached at infinite frequency (continuous time); ``nan`` when unstable.
    upper : float
        A level certified by the Hamiltonian test to be above the norm (``value <= norm <= upper``
        up to the accuracy of the eigenvalue test).
    iterations : int
        Level-set iterations.
    """

    value: float
    frequency: float
    upper: float
    iterations: int

    def __float__(self) -> float:
        return float(self.value)


def _sigma_max(A: NDArray, B: NDArray, C: NDArray, D: NDArray, w: ArrayLike) -> NDArray[np.float64]:
    """``sigma_max(C (j w I - A)^-1 B + D)`` at the frequencies ``w`` (one batched solve)."""
    w = np.atleast_1d(np.asarray(w, dtype=float))
    n = A.shape[0]
    M = 1j * w[:, None, None] * np.eye(n)[None] - A[None]
    T = C[None] @ np.linalg.solve(M, np.broadcast_to(B, (w.size, *B.shape))) + D[None]
    return np.linalg.svd(T, compute_uv=False)[:, 0]


def _bilinear(A: NDArray, B: NDArray, C: NDArray, D: NDArray):
    """The continuous system with the same H-infinity norm: ``z = (1 + s) / (1 - s)``."""
    n = A.shape[0]
    M = np.linalg.inv(A + np.eye(n))
    r2 = math.sqrt(2.0)
    return M @ (A - np.eye(n)), r2 * (M @ B), r2 * (C @ M), D - C @ M @ B


def _imaginary_frequencies(H: NDArray, tol: float) -> NDArray[np.float64]:
    """The sorted nonnegative imaginary parts of the (numerically) imaginary eigenvalues of H."""
    lam = np.linalg.eigvals(H)
    scale = max(1.0, float(np.max(np.abs(lam)))) if lam.size else 1.0
    im = lam[np.abs(lam.real) <= tol * scale]
    return np.unique(np.round(np.abs(im.imag), 14))


def _hinf_continuous(A, B, C, D, rtol: float, max_iter: int) -> tuple[float, float, float, int]:
    sD = float(np.linalg.norm(D, 2)) if D.size else 0.0
    lam = np.linalg.eigvals(A)
    # initial lower bound: DC gain, the resonances of the poles, and a coarse log grid
    cands = [0.0]
    mags = np.abs(lam)
    cands += [float(m) for m in mags if m > 0]
    cands += [float(abs(z.imag)) for z in lam if z.imag != 0]
    lo_w = max(1e-6, 0.1 * float(np.min(mags[mags > 0]))) if np.any(mags > 0) else 1e-3
    hi_w = 10.0 * max(1.0, float(np.max(mags)))
    cands += list(np.geomspace(lo_w, hi_w, 40))
    vals = _sigma_max(A, B, C, D, cands)
    k = int(np.argmax(vals))
    glb, wpk = float(vals[k]), float(cands[k])
    if sD > glb:  # the supremum is approached at infinite frequency (the feedthrough)
        glb, wpk = sD, math.inf
    if glb == 0.0:
        return 0.0, 0.0, 0.0, 0
    # imaginary-axis test: loose on purpose (an eigenvalue that is not imaginary only costs one
    # evaluation at a midpoint, which then makes no progress and ends the iteration)
    tol_im = 1e-8
    it = 0
    gamma = glb
    for it in range(1, max_iter + 1):  # noqa: B007 - it is reported
        gamma = (1.0 + 2.0 * rtol) * glb
        Rm = D.T @ D - gamma**2 * np.eye(D.shape[1])
        Sm = D @ D.T - gamma**2 * np.eye(D.shape[0])
        Ri = np.linalg.inv(Rm)
        F = A - B @ Ri @ D.T @ C
        H = np.block([[F, -gamma * B @ Ri @ B.T], [gamma * C.T @ np.linalg.solve(Sm, C), -F.T]])
        ws = _imaginary_frequencies(H, tol_im)
        if ws.size == 0:
            return glb, wpk, gamma, it
        mids = [0.5 * (ws[i] + ws[i + 1]) for i in range(ws.size - 1)] if ws.size > 1 else []
        mids += [float(ws[0]), float(ws[-1])]
        vals = _sigma_max(A, B, C, D, mids)
        j = int(np.argmax(vals))
        if vals[j] <= glb * (1.0 + rtol):
            return glb, wpk, gamma, it  # no progress: the imaginary eigenvalues are rounding artefacts
        glb, wpk = float(vals[j]), float(mids[j])
    return glb, wpk, gamma, it


def hinf_norm(
    A: ArrayLike,
    B: ArrayLike,
    C: ArrayLike | None = None,
    D: ArrayLike | None = None,
    *,
    dt: float | None = None,
    rtol: float = 1e-10,
    max_iter: int = 60,
) -> HinfNorm:
    """H-infinity norm of ``(A, B, C, D)`` by the Hamiltonian level-set iteration.

    Parameters
    ----------
    A : (n, n) array_like
    B : (n, m) array_like
    C : (q, n) array_like, optional
        Default: the identity.
    D : (q, m) array_like, optional
        Default: zero.
    dt : float, optional
        Sampling period; ``None`` for continuous time.
    rtol : float, default 1e-10
        Relative accuracy of the level iteration.
    max_iter : int, default 60

    Returns
    -------
    HinfNorm
        ``value`` (``inf`` if A is not strictly stable), the peak ``frequency`` and a certified
        ``upper`` level.

    Raises
    ------
    DimensionError, NotFiniteError
    ValidationError
        ``dt`` or ``rtol`` not positive.

    References
    ----------
    Bruinsma & Steinbuch 1990; Boyd & Balakrishnan 1990 (module docstring).

    Examples
    --------
    >>> from optdesign import hinf_norm
    >>> h = hinf_norm([[0., 1.], [-1., -0.2]], [[0.], [1.]], [[1., 0.]])   # 1/(s^2 + 0.2 s + 1)
    >>> round(h.value, 4), round(h.frequency, 4)          # the resonance peak
    (5.0252, 0.9899)
    """
    Am, Bm, Cm, Dm = _system(A, B, C, D)
    dt = _check_dt(dt)
    rtol = as_positive_float("rtol", rtol)
    if not is_stable(Am, dt):
        return HinfNorm(math.inf, math.nan, math.inf, 0)
    if dt is None:
        g, w, up, it = _hinf_continuous(Am, Bm, Cm, Dm, rtol, max_iter)
        return HinfNorm(g, w, up, it)
    Ac, Bc, Cc, Dc = _bilinear(Am, Bm, Cm, Dm)
    g, w, up, it = _hinf_continuous(Ac, Bc, Cc, Dc, rtol, max_iter)
    return HinfNorm(g, 2.0 * math.atan(w) / dt, up, it)


# --------------------------------------------------------------------------- the error channel


def _gain(plant: Plant, L: ArrayLike) -> NDArray[np.float64]:
    if not isinstance(plant, Plant):
        raise ValidationError(f"plant must be an optdesign.Plant; found {type(plant).__name__}")
    return as_matrix("L", L, (plant.n, plant.p))


def error_channel(plant: Plant, L: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The estimation-error system ``e' = (A - L C) e + [G Q^(1/2), -L R^(1/2)] n`` (output ``e``).

    Parameters
    ----------
    plant : Plant
        With ``Q`` and ``R``.
    L : (n, p) array_like
        Observer gain.

    Returns
    -------
    X : (n, n) ndarray
        ``A - L C``.
    B : (n, m + p) ndarray
        ``[G Q^(1/2), -L R^(1/2)]``.

    Raises
    ------
    ValidationError
        ``plant`` is not a Plant or has no noise model.
    DimensionError
        ``L`` is not (n, p).
    """
    Lm = _gain(plant, L)
    plant.require_noise_model()
    Q, R = plant.Q, plant.R
    if Q is None or R is None:  # pragma: no cover - require_noise_model raised already
        raise ValidationError("the plant has no noise model")
    X = plant.A - Lm @ plant.C
    B = np.hstack([np.asarray(plant.G) @ psd_sqrt(Q), -Lm @ psd_sqrt(R)])
    return X, B


def error_covariance(plant: Plant, L: ArrayLike) -> NDArray[np.float64]:
    """Steady-state covariance ``Sigma`` of the estimation error (module docstring).

    Parameters
    ----------
    plant : Plant
        With ``Q`` and ``R``.
    L : (n, p) array_like

    Returns
    -------
    (n, n) ndarray
        Symmetric PSD; all entries ``inf`` when ``A - L C`` is not strictly stable.

    Raises
    ------
    ValidationError, DimensionError
        As for :func:`error_channel`.
    """
    X, B = error_channel(plant, L)
    if not is_stable(X, plant.dt):
        return np.full((plant.n, plant.n), np.inf)
    return _gramian(X, B, plant.dt)


def estimation_error_h2(plant: Plant, L: ArrayLike) -> float:
    """H2 norm of the estimation-error channel: ``sqrt(trace(Sigma))``, the RMS estimation error.

    Raises
    ------
    ValidationError, DimensionError
        As for :func:`error_channel`.
    """
    X, B = error_channel(plant, L)
    return h2_norm(X, B, dt=plant.dt)


def estimation_error_hinf(plant: Plant, L: ArrayLike, *, rtol: float = 1e-10) -> HinfNorm:
    """H-infinity norm of the estimation-error channel (worst-case noise-to-error gain).

    Raises
    ------
    ValidationError, DimensionError
        As for :func:`error_channel`.
    """
    X, B = error_channel(plant, L)
    return hinf_norm(X, B, dt=plant.dt, rtol=rtol)
