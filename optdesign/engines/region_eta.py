r"""eta in the region mode of the eigenstructure engine: poles and eigenvectors both free (issue 28).

Huh & Stein's non-normality measure of ``A - L C = V Lambda W`` (``V = W^-1``, rows of ``W`` the left
eigenvectors) is

.. math::

    \eta^2 = \frac{\|V \Lambda W\|_F^2 - \sum_j |\lambda_j|^2}{\mathrm{gap}^2},
    \qquad \mathrm{gap} = \min_{i \ne j} |\lambda_i - \lambda_j| .

With fixed poles (``FixedPoleModel._eta`` of :mod:`optdesign.engines.eigenstructure`) the gap is a
constant; in region mode it moves with the poles and is a nonsmooth minimum.  This module gives the
smooth surrogate the region engine (:class:`~optdesign.engines.eigenstructure_region.RegionModel`)
minimizes, stage by stage:

* **the gap** is replaced by the soft minimum of the squared distances ``d_ij = |lambda_i -
  lambda_j|^2`` over the pairs ``i < j`` of all poles (a pair's two members included),
  ``g_k = (sum d_ij^-k)^(-1/k)``, a lower bound of ``gap^2`` within the factor ``m^(1/k)`` (``m``
  pairs), so that ``eta_k >= eta`` (an upper bound, as kappa2's ``phi_k``); the order ``k`` grows
  over the stages (:data:`ETA_STAGES`, the kappa2 continuation's 4, 64, 1024, 16384) and the last
  stage (``k = None``) is the exact minimum (its gradient: the mean over the tied pairs -- a pair
  of conjugate pairs ties by symmetry);
* **the departure** ``||V Lambda W||_F^2 - sum |lambda|^2`` depends on ``W`` and explicitly on
  the poles.  With ``E = V Lambda W``: ``d||E||_F^2 = Re sum conj(K) dW`` with ``K = 2 V^H (E^H E -
  E E^H)`` (``dV = -V dW V``; ``K = 0`` for a normal ``E``), and ``d||E||_F^2 / d lambda_j =
  2 conj(w_j E^H v_j)`` (``W`` fixed, complex gradient: ``df = Re sum conj(c_j) d lambda_j``);
* the value minimized is ``log(eta_k^2)`` (scale-free, as ``log kappa2``: the engine's separation
  barrier and relative stopping tests keep their meaning), with the departure floored at its
  rounding level ``n eps sum |lambda|^2`` (a normal ``A - L C`` has departure 0).

:func:`eta_terms` returns the value, ``K = df/dW`` (which the region model chains through its moving
bases, as for kappa2) and the explicit derivative with respect to the free poles' real and imaginary
parts (which it adds like its separation barrier's).

References
----------
J. Huh and E. Stein, "Eigenvalue gap and non-normality" (the measure, seed 001 eq. (1));
P. Henrici, "Bounds for iterates, inverses, spectral variation and fields of values of non-normal
matrices", Numer. Math. 4 (1962) (the departure from normality).
"""

from __future__ import annotations

import functools
import math

import numpy as np
from numpy.typing import NDArray

from .tolerances import EPS, REGION_STAGES

__all__ = ["ETA_STAGES", "ETA_WARM_STAGES", "soft_gap2", "departure2", "eta_terms", "pole_pairs"]

#: ``(gap order k, separation-barrier weight)`` per stage of eta in region mode: the orders of the
#: kappa2 continuation (the soft minimum of ``m`` squared distances is within ``m^(1/k)`` of the
#: minimum: 1.004 for ``k = 1024`` and ``m = 45`` pairs, n = 10), ending at the exact gap
ETA_STAGES: tuple[tuple[int | None, float], ...] = REGION_STAGES
#: a warm start's stages (a converged design of a nearby problem): the last two
ETA_WARM_STAGES: tuple[tuple[int | None, float], ...] = ETA_STAGES[-2:]
#: relative tie tolerance of the exact gap's gradient (``k = None``): distances equal to rounding
_TIE_RTOL = 8 * EPS


def soft_gap2(P: NDArray, k: int | None) -> tuple[NDArray[np.float64], NDArray[np.complex128]]:
    """The soft minimum ``g_k`` of the squared pole distances and its complex gradient.

    Parameters
    ----------
    P : (s, n) ndarray of complex
        Stacked poles (every pole of each member, conjugates included).
    k : int or None
        Order of the soft minimum ``g_k = (sum_{i<j} d_ij^-k)^(-1/k)``, ``d_ij = |P_i - P_j|^2``;
        None: the exact minimum.

    Returns
    -------
    g : (s,) ndarray
        ``g_k`` (``<= min d_ij``, equal for ``k = None``); 0 where two poles coincide.
    c : (s, n) ndarray of complex
        ``dg = Re sum_j conj(c_j) dP_j`` (at the exact minimum: the mean of the tied pairs'
        gradients, a subgradient); 0 where ``g = 0``.
    """
    s, n = P.shape
    iu, ju, inc = pole_pairs(n)
    D = P[:, iu] - P[:, ju]  # (s, m)
    d = D.real**2 + D.imag**2
    dmin = d.min(axis=1) if d.shape[1] else np.full(s, math.inf)
    pos = dmin > 0
    r = np.where(pos[:, None], dmin[:, None] / np.where(d > 0, d, 1.0), 0.0)  # in (0, 1]
    if k is None:
        w = (r >= 1.0 - _TIE_RTOL).astype(float)
        g = dmin.copy()
    else:
        w = r**k  # underflows to 0 far from the minimum: harmless
        g = dmin * np.where(pos, w.sum(axis=1), 1.0) ** (-1.0 / k)
    w = w / np.where(pos, w.sum(axis=1), 1.0)[:, None]
    # dg = g sum w_ij dd_ij / d_ij, dd_ij = 2 Re(conj(D_ij) (dP_i - dP_j))
    t = 2.0 * (g[:, None] * w / np.where(d > 0, d, 1.0)) * D
    c = t @ inc
    g = np.where(pos, g, 0.0)
    c[~pos] = 0.0
    return g, c


@functools.lru_cache(maxsize=64)
def pole_pairs(n: int) -> tuple[NDArray, NDArray, NDArray]:
    """``(i, j, incidence)`` of the pairs ``i < j`` of ``n`` poles; ``incidence`` (m, n): +1 at ``i``,
    -1 at ``j`` (read-only: shared between calls)."""
    iu, ju = np.triu_indices(n, 1)
    inc = np.zeros((iu.size, n))
    inc[np.arange(iu.size), iu] = 1.0
    inc[np.arange(iu.size), ju] = -1.0
    for a in (iu, ju, inc):
        a.flags.writeable = False
    return iu, ju, inc


def departure2(W: NDArray, P: NDArray) -> tuple[NDArray, NDArray, NDArray, NDArray]:
    """``||V Lambda W||_F^2 - sum |lambda|^2`` (floored at its rounding level) and its derivatives.

    Parameters
    ----------
    W : (s, n, n) ndarray
        Stacked left eigenvector matrices (rows ``w_j``); ``V = W^-1``.
    P : (s, n) ndarray of complex
        The poles of the rows.

    Returns
    -------
    nu : (s,) ndarray
        ``max(||E||_F^2 - (1 - n eps) sum |lambda|^2, eps^2 sum |lambda|^2)`` with ``E = V Lambda W``
        (the floor: the departure of a normal ``E`` is 0 to rounding; ``log nu`` stays finite); inf
        where ``W`` is singular.
    K : (s, n, n) ndarray
        ``d nu = Re sum conj(K) dW`` at fixed poles: ``2 V^H (E^H E - E E^H)`` (0 where floored or
        singular).
    c : (s, n) ndarray of complex
        ``d nu = Re sum_j conj(c_j) d lambda_j`` at fixed ``W``: ``2 conj(w_j E^H v_j) - 2 (1 - n eps)
        lambda_j``.
    ok : (s,) ndarray of bool
        ``W`` invertible (finite ``V``).
    """
    s, n = P.shape
    V, ok = _inverse(W)
    E = (V * P[:, None, :]) @ W
    Eh = np.swapaxes(E.conj(), -1, -2)
    lam2 = np.sum(P.real**2 + P.imag**2, axis=1)
    shrink = 1.0 - n * EPS
    raw = np.einsum("sij,sij->s", E.conj(), E).real - shrink * lam2
    floor = EPS**2 * np.maximum(lam2, 1.0)
    live = ok & (raw > floor)
    nu = np.where(ok, np.maximum(raw, floor), math.inf)
    Vh = np.swapaxes(V.conj(), -1, -2)
    K = 2.0 * Vh @ (Eh @ E - E @ Eh)
    diag = np.einsum("sjk,skj->sj", W @ Eh, V)  # w_j E^H v_j
    c = 2.0 * diag.conj() - 2.0 * shrink * P
    K[~live] = 0.0
    c[~live] = 0.0
    return nu, K, c, ok


def _inverse(W: NDArray) -> tuple[NDArray, NDArray]:
    """``(V, ok)``: the inverses of a stack (member by member where one is singular; ``ok`` False and
    ``V = 0`` there)."""
    try:
        V = np.linalg.inv(W)
        ok = np.all(np.isfinite(V), axis=(1, 2))
    except np.linalg.LinAlgError:
        V = np.zeros_like(W)
        ok = np.zeros(W.shape[0], dtype=bool)
        for i in range(W.shape[0]):
            try:
                V[i] = np.linalg.inv(W[i])
                ok[i] = bool(np.all(np.isfinite(V[i])))
            except np.linalg.LinAlgError:
                pass
    V[~ok] = 0.0
    return V, ok


def eta_terms(P: NDArray, W: NDArray, k: int | None) -> tuple[NDArray[np.float64], NDArray, NDArray]:
    """``log eta_k^2`` of region-model members, ``K = df/dW`` and the explicit pole derivative.

    Parameters
    ----------
    P : (s, n) ndarray of complex
        The members' poles, in the row order of ``W``.
    W : (s, n, n) ndarray
        The members' left eigenvector rows.
    k : int or None
        Order of the soft gap (:func:`soft_gap2`; None: the exact gap).

    Returns
    -------
    f : (s,) ndarray
        ``log(nu / g_k)`` (:func:`departure2`, :func:`soft_gap2`): ``log eta^2`` for ``k = None``
        (up to the departure's rounding floor); inf for a singular ``W`` or coincident poles.
    K : (s, n, n) ndarray
        ``df = Re sum conj(K) dW`` at fixed poles (0 where ``f`` is inf).
    c : (s, n) ndarray of complex
        ``df = Re sum conj(c_j) dlambda_j`` at fixed ``W`` (0 where ``f`` is inf); the caller folds
        a pair's two rows into its variables.
    """
    nu, Kn, cn, ok = departure2(W, P)
    g, cg = soft_gap2(P, k)
    good = ok & (g > 0) & np.isfinite(nu)
    nus = np.where(good, nu, 1.0)
    gs = np.where(good, g, 1.0)
    f = np.where(good, np.log(nus) - np.log(gs), math.inf)
    K = Kn / nus[:, None, None]
    c = cn / nus[:, None] - cg / gs[:, None]
    K[~good] = 0.0
    c[~good] = 0.0
    return f, K, c
