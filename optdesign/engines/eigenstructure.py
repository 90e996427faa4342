r"""Well-conditioned observer pole placement by a dedicated eigenstructure algorithm (issue 13).

The observer ``A - L C`` with prescribed poles ``lambda_1..lambda_n`` is parametrized by its
*left* eigenvectors: ``w_j (A - L C) = lambda_j w_j`` holds for some ``L`` iff
``w_j (A - lambda_j I) Z = 0`` with ``Z`` a basis of ``null(C)``, i.e. ``w_j^T`` lies in the
``r``-dimensional subspace ``S_j = span(N_j)`` (``r = rank C``; the dual of Kautsky, Nichols &
Van Dooren's ``S_j``).  With ``w_j = (N_j c_j)^T`` (``c_j`` real for a real pole, complex for the
upper member of a conjugate pair, whose partner row is the conjugate) every ``c`` gives the gain

.. math:: L = W^{-1} G, \qquad g_j = w_j (A - \lambda_j I) C^+ ,

whose error dynamics have exactly the prescribed poles and the right eigenvector matrix
``V = W^{-1}``.  The objectives are functions of ``V~ = V D^{-1}`` (unit columns, ``d_j = ||V e_j||``):

* ``kappa2``: ``log(sigma_max(V~) / sigma_min(V~))`` -- the *exact* condition number that
  :func:`optdesign.analysis.metrics.kappa2` measures, nonsmooth where the extreme singular values
  are multiple.  Minimized by continuation on the smooth upper bound
  ``phi_k = [log sum sigma_i^{2k} + log sum sigma_i^{-2k}] / (2k)`` (``0 <= phi_k - log kappa2 <=
  log(n) / k``), then by BFGS on the exact function (:mod:`optdesign.engines.quasi_newton`);
* ``kappa_fro``: ``log ||V~||_F ||V~^{-1}||_F`` (smooth);
* ``eta``: ``(||A - LC||_F^2 - sum |lambda|^2) / gap^2 = eta^2`` for fixed poles (smooth).

Gradients are analytic: for ``f(V~)`` with ``df = Re tr(F^H dV~)``,
``H = F D^{-1} - V diag(Re(f_j^H v~_j) / d_j^2)`` and ``df/dW = -V^H H V^H``; a function of ``L`` with
``dphi = Re tr(Gamma^H dL)`` contributes
``dphi/dw_j = conj((A - lambda_j I) C^+ Gamma^H v_j - L Gamma^H v_j)``
(from ``dL = sum_j v_j dw_j ((A - lambda_j I) C^+ - L)``).  One evaluation costs one inverse and one
SVD of an ``n x n`` matrix: no Hessian is formed.

One output (``rank C = 1``): every ``S_j`` is a line, ``W`` is fixed up to row scaling, so the gain is
unique -- the one of Ackermann's formula and scipy's YT -- and is computed directly
(status ``solved``).  At an unobservable mode of ``(C, A)`` the subspace is larger (its bases are
zero-padded to a common width; the extra coordinates are inert elsewhere).  A pole repeated more
than ``rank C`` times has no diagonalizable design (:class:`DefectivePolesError`);
:func:`spread_poles` gives the nearest distinct pole set for a separation the caller chooses.

The engine holds everything that does not depend on the poles (``Z``, ``C^+``) and caches the
null-space bases per pole value, so a caller-held problem object re-solves cheaply
(:class:`EigenstructureEngine`); :func:`optdesign.engines.eigenstructure_fixed.place_fixed` and
:func:`optdesign.engines.eigenstructure_region.place_region` are the functional entry points.

References
----------
J. Kautsky, N. K. Nichols and P. Van Dooren, "Robust pole assignment in linear state feedback",
Int. J. Control 41 (1985) 1129-1155.
A. L. Tits and Y. Yang, "Globally convergent algorithms for robust pole assignment by state
feedback", IEEE Trans. Automat. Control 41 (1996) 1432-1452.
A. S. Lewis and M. L. Overton, "Nonsmooth optimization via quasi-Newton methods", Math.
Programming 141 (2013) 135-163.
Jung & Huh (seed 001): kappa2 and eta of the error dynamics.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._validate import as_int, as_matrix, as_poles, as_positive_float
from ..errors import DefectivePolesError, DimensionError, ValidationError
from .tolerances import (
    CONJUGATE_RTOL,
    NORM_FLOOR,
    NULL_BASIS_FACTOR,
    PBH_RANK_FACTOR,
    POLE_COINCIDE_RTOL,
    SPREAD_REAL_RTOL,
    rounding_level,
)

__all__ = [
    "OBJECTIVES",
    "MEASURES",
    "left_spectral_objective",
    "KAPPA2_CONTINUATION",
    "DefectivePolesError",
    "EigenstructureEngine",
    "FixedPoleModel",
    "spread_poles",
    "pole_multiplicities",
    "spectral_objective",
    "spectral_dW",
    "padded_bases",
]


#: objectives of the engine
OBJECTIVES = ("kappa2", "kappa_fro", "eta")

#: orders ``k`` of the smooth kappa2 bound ``phi_k`` minimized before the exact function
#: (``None``).  Measured: starting at the exact function lets BFGS stall for hundreds of iterations
#: at a tie of singular values (scipy's car example: 551 evaluations to reach 1e-3 of the optimum,
#: 285 in all through a continuation); on 24 tuning cases (the benchmark problems, random n <= 10)
#: with 5 starts, this schedule ended within 3e-8 of a 16-start reference on all, while
#: (4, 32, 256, exact) left 2 cases above 1e-4 at the same cost
KAPPA2_CONTINUATION: tuple[int | None, ...] = (4, 64, 1024, 16384, None)

Objective = Literal["kappa2", "kappa_fro", "eta"]

#: which eigenvectors of ``A - L C`` the conditioning objectives measure (:class:`FixedPoleModel`)
MEASURES = ("right", "left")
Measure = Literal["right", "left"]


# --------------------------------------------------------------------------- pole sets


def pole_multiplicities(poles: ArrayLike, *, rtol: float = POLE_COINCIDE_RTOL) -> list[tuple[complex, int]]:
    """Distinct poles and their multiplicities (poles within ``rtol max(1, |p|)`` coincide).

    Parameters
    ----------
    poles : (n,) array_like of complex

    Returns
    -------
    list of (complex, int)
        In order of first appearance.
    """
    p = np.asarray(poles, dtype=complex).ravel()
    out: list[tuple[complex, int]] = []
    for z in p:
        for k, (v, m) in enumerate(out):
            if abs(z - v) <= rtol * max(1.0, abs(v)):
                out[k] = (v, m + 1)
                break
        else:
            out.append((complex(z), 1))
    return out


def spread_poles(poles: ArrayLike, rank: int, separation: float) -> NDArray[np.complex128]:
    """The nearest distinct-pole set: poles repeated more than ``rank`` times spread on a circle.

    Each pole ``p`` of multiplicity ``m > rank`` is replaced by ``m`` distinct points on the circle
    of radius ``separation * max(1, |p|)`` around it, at angles ``2 pi k / m`` (``k = 0..m-1``) for
    a real ``p`` (a conjugate-closed set: real points at angle 0 and, for even ``m``, pi), and at
    ``pi (2k + 1) / m`` rotated into distinct points for the upper member of a pair (its conjugate
    partner gets the conjugates).  Poles repeated at most ``rank`` times are kept: ``A - L C`` can
    have them as semisimple eigenvalues.

    Parameters
    ----------
    poles : (n,) array_like of complex
        Conjugate-closed.
    rank : int
        ``rank(C)``, ``>= 1``.
    separation : float
        Relative radius, ``> 0`` (the pole error of the design is this radius).

    Returns
    -------
    (n,) ndarray of complex
        Conjugate-closed; real poles first, then pairs (:func:`optdesign._validate.as_poles` order).

    Raises
    ------
    ValidationError
        Bad ``rank`` or ``separation``; poles not conjugate-closed.

    Examples
    --------
    >>> spread_poles([-1.0, -1.0, -3.0], 1, 1e-2).round(6)
    array([-3.  +0.j, -1.01+0.j, -0.99+0.j])
    """
    P = as_poles("poles", poles)
    rank = as_int("rank", rank, 1)
    sep = as_positive_float("separation", separation)
    out: list[complex] = []
    for v, m in pole_multiplicities(P):
        if v.imag < 0:
            continue  # handled with its upper partner
        if m <= rank:
            out += [v] * m if v.imag == 0 else [v, v.conjugate()] * m
            continue
        rad = sep * max(1.0, abs(v))
        if v.imag == 0:
            ang = 2.0 * math.pi * np.arange(m) / m
            pts = v + rad * np.exp(1j * ang)
            pts = np.where(np.abs(pts.imag) <= SPREAD_REAL_RTOL * rad, pts.real + 0j, pts)
            out += list(pts)
        else:
            ang = math.pi * (2 * np.arange(m) + 1) / m
            pts = v + rad * np.exp(1j * ang)
            for z in pts:
                out += [complex(z), complex(z).conjugate()]
    res = as_poles("spread poles", np.asarray(out))
    if len(pole_multiplicities(res)) < len(res) and rank == 1:  # pragma: no cover - by construction
        raise ValidationError("spread_poles produced coincident poles")
    return res


@dataclass(frozen=True)
class _Slots:
    """Poles in the engine's row order: real poles (ascending), then pairs ``(z, conj z)``."""

    real: NDArray[np.float64]  # (nr,)
    upper: NDArray[np.complex128]  # (npair,) members with Im > 0

    @property
    def nr(self) -> int:
        return int(self.real.size)

    @property
    def npair(self) -> int:
        return int(self.upper.size)

    @property
    def n(self) -> int:
        return self.nr + 2 * self.npair

    @property
    def row_poles(self) -> NDArray[np.complex128]:
        """The pole of every row of ``W`` (= of every column of ``V``)."""
        out = np.empty(self.n, dtype=complex)
        out[: self.nr] = self.real
        out[self.nr :: 2] = self.upper
        out[self.nr + 1 :: 2] = self.upper.conj()
        return out

    @classmethod
    def of(cls, poles: NDArray[np.complex128]) -> _Slots:
        P = np.asarray(poles, dtype=complex)  # validated by the caller (as_poles order and exactness)
        real = np.sort(P[P.imag == 0].real)
        up = P[P.imag > 0]
        up = up[np.lexsort((up.imag, up.real))]
        return cls(real, up)


# --------------------------------------------------------------------------- the engine


class EigenstructureEngine:
    """The pole-independent part of the eigenstructure parametrization of ``A - L C``.

    Holds ``A``, ``C``, ``rank C``, a basis ``Z`` of ``null(C)`` and ``C^+``, and caches the
    orthonormal basis ``N(lambda)`` of ``S(lambda) = {w : w (A - lambda I) Z = 0}`` per pole
    value, so that a problem object re-solving for new poles or objectives pays only for new
    poles.  Cheap to build (one SVD of ``C``).

    Parameters
    ----------
    A : (n, n) array_like
    C : (p, n) array_like

    Raises
    ------
    DimensionError
        Shapes do not match, or ``C`` is zero.
    NotFiniteError
        NaN or Inf entries.
    """

    def __init__(self, A: ArrayLike, C: ArrayLike) -> None:
        A = as_matrix("A", A)
        if A.shape[0] != A.shape[1] or A.shape[0] == 0:
            raise DimensionError(f"A must be square and nonempty; found shape {A.shape}")
        n = A.shape[0]
        C = as_matrix("C", C)
        if C.shape[1] != n:
            raise DimensionError(f"C must have n = {n} columns (A is {n} x {n}); found shape {C.shape}")
        U, s, Vt = np.linalg.svd(C)
        tol = rounding_level(max(C.shape), float(s[0]) if s.size else 0.0)
        r = int(np.sum(s > tol))
        if r == 0:
            raise DimensionError("C must have rank >= 1 (it is zero): no output, no observer")
        self.A = A
        self.C = C
        self.n, self.p, self.rank = n, C.shape[0], r
        self.Z = Vt[r:].T.copy()  # (n, n - r), orthonormal basis of null(C)
        self.Cpinv = (Vt[:r].T / s[:r]) @ U[:, :r].T  # (n, p)
        self.scale = float(np.linalg.norm(A, 2))
        self._bases: dict[complex, NDArray] = {}

    # ------------------------------------------------------------------ bases
    def basis(self, lam: complex) -> NDArray:
        """Orthonormal ``N`` (n, d) with ``S(lam) = {(N c)^T}``; real for a real ``lam``.

        ``d = n - rank((A - lam I) Z)``: ``rank C`` for every ``lam`` except an unobservable mode of
        ``(C, A)``, where it is larger by that mode's geometric multiplicity.  From the complete QR
        with column pivoting of ``M = (A - lam I) Z`` (rank-revealing, at the cost of a plain QR; a
        full SVD made the one-output case 1.9x slower than scipy's YT at n = 50, measured): its
        trailing ``d`` columns of ``Q`` span ``range(M)^perp``; ``w M = 0`` is the bilinear (not
        Hermitian) condition, so ``N`` is their complex conjugate.
        """
        import scipy.linalg

        lam = complex(lam)
        N = self._bases.get(lam)
        if N is not None:
            return N
        n, r = self.n, self.rank
        if r == n:
            N = np.eye(n)
        else:
            M = (self.A - lam * np.eye(n)) @ self.Z if lam.imag else (self.A - lam.real * np.eye(n)) @ self.Z
            Q, R, _ = scipy.linalg.qr(M, mode="full", pivoting=True, check_finite=False)
            tol = rounding_level(n, max(float(np.abs(R[0, 0])) if R.size else 0.0, self.scale, abs(lam)),
                                 NULL_BASIS_FACTOR)
            rank = int(np.sum(np.abs(np.diagonal(R)) > tol))
            N = Q[:, rank:].conj()
            if lam.imag == 0:
                N = np.ascontiguousarray(N.real)
        if len(self._bases) > 4096:  # a long sweep: keep the cache bounded
            self._bases.clear()
        self._bases[lam] = N
        return N

    def unobservable_modes(self) -> NDArray[np.complex128]:
        """Eigenvalues ``mu`` of ``A`` with ``rank [A - mu I; C] < n`` (PBH test, relative tolerance)."""
        w = np.linalg.eigvals(self.A)
        out = []
        scale = max(float(np.linalg.norm(self.A, 2)), float(np.linalg.norm(self.C, 2)), NORM_FLOOR)
        for mu in w:
            s = np.linalg.svd(np.vstack([self.A - mu * np.eye(self.n), self.C]), compute_uv=False)
            if s[-1] <= rounding_level(self.n, scale, PBH_RANK_FACTOR):
                out.append(mu)
        return np.asarray(out, dtype=complex)

    def model(self, poles: ArrayLike, *, measure: Measure = "right") -> FixedPoleModel:
        """The parametrization for one pole set (bases from the cache); ``measure`` as
        :class:`FixedPoleModel`."""
        return FixedPoleModel(self, poles, measure=measure)


class FixedPoleModel:
    """Eigenvector coordinates -> gain, eigenbasis and objective, for one fixed pole set.

    The real coordinate vector ``x`` holds, in order, ``c_j`` (r entries) for every real pole,
    then ``Re c_j`` and ``Im c_j`` for every pair (``j`` in the row order of ``_Slots``).

    Parameters
    ----------
    engine : EigenstructureEngine
    poles : (n,) array_like of complex
        Conjugate-closed; a pole may repeat up to ``rank C`` times.
    tol : float, default 1e-8
        Relative tolerance of :func:`~optdesign._validate.as_poles` (real vs complex, conjugate
        partners); 0 for poles that are exactly conjugate-closed (a pair close to the real axis
        stays a pair).
    measure : {"right", "left"}, default "right"
        Which eigenvectors of ``A - L C`` the objectives (kappa2, kappa_fro) measure: ``"right"``
        the unit-column right eigenvectors ``V~`` (the observer's measure); ``"left"`` the unit-norm
        left eigenvectors, i.e. ``X = W~^T`` with unit columns -- the right eigenvectors of the
        transpose ``(A - L C)' = A_c - B_c K`` of a state-feedback loop (``A_c = A'``,
        ``B_c = C'``, ``K = L'``): cond(X) of scipy's ``place_poles`` and of Byers & Nash.  eta is
        invariant under transposition and the same in both.

    Raises
    ------
    DimensionError
        Wrong number of poles.
    NotConjugateClosedError
        Poles not closed under conjugation.
    DefectivePolesError
        A pole repeated more than ``rank C`` times.
    """

    def __init__(self, engine: EigenstructureEngine, poles: ArrayLike, *, tol: float = CONJUGATE_RTOL,
                 measure: Measure = "right") -> None:
        if measure not in MEASURES:
            raise ValidationError(f"measure must be one of {MEASURES}; found {measure!r}")
        self.engine = engine
        self.measure = measure
        n = engine.n
        P = as_poles("poles", poles, n, tol=tol)
        sl = self.slots = _Slots.of(P)
        Br = [engine.basis(complex(v)) for v in sl.real]
        Bp = [engine.basis(complex(v)) for v in sl.upper]
        dims = {complex(v): B.shape[1] for v, B in zip([*sl.real, *sl.upper], [*Br, *Bp], strict=True)}
        for v, m in pole_multiplicities(P):
            dim = dims[complex(v.real, abs(v.imag))]
            if m > dim:
                raise DefectivePolesError(
                    f"pole {v:.6g} is requested {m} times but rank(C) = {engine.rank}: the eigenspace of "
                    f"A - LC for it has dimension <= {dim}, so A - LC would be defective (kappa2 = inf); "
                    "give a separation for the nearest distinct-pole design",
                    pole=v,
                    multiplicity=m,
                    rank=engine.rank,
                )
        # subspaces of an unobservable mode are larger: pad every basis to the largest dimension
        # with zero columns (their coordinates are inert: zero gradient, no effect on W)
        r = max(dims.values())
        self.r = r
        self.poles = sl.row_poles
        self.Nr = padded_bases(Br, n, r, float)
        self.Np = padded_bases(Bp, n, r, complex)
        self._Np_conj = self.Np.conj()
        self.complex = sl.npair > 0
        self.size = r * (sl.nr + 2 * sl.npair)
        self._dims = (n, r, sl.nr, sl.npair, r * sl.nr, r * (sl.nr + sl.npair))
        # min gap between distinct poles (eta), and sum |lambda|^2
        d = np.abs(self.poles[:, None] - self.poles[None, :])
        np.fill_diagonal(d, np.inf)
        self.gap = float(np.min(d)) if n > 1 else math.inf
        self.lam2 = float(np.sum(np.abs(self.poles) ** 2))

    # ------------------------------------------------------------------ coordinates
    def _split(self, X: NDArray) -> tuple[NDArray, NDArray]:
        """``(c_real (s, nr, r), c_pair (s, npair, r))`` of a stack of coordinate vectors ``(s, m)``."""
        _, r, nr, npair, k1, k2 = self._dims
        s = X.shape[0]
        return X[:, :k1].reshape(s, nr, r), (X[:, k1:k2] + 1j * X[:, k2:]).reshape(s, npair, r)

    def W(self, x: NDArray) -> NDArray:
        """The left eigenvector matrix (rows ``w_j``) of coordinates ``x`` (m,), or a stack ``(s, n, n)``
        of them for a stack ``(s, m)``."""
        X = np.asarray(x, dtype=float)
        Ws = self._W(np.atleast_2d(X))
        return Ws[0] if X.ndim == 1 else Ws

    def _W(self, X: NDArray) -> NDArray:
        n, _, nr, _, _, _ = self._dims
        cr, cp = self._split(X)
        Wr = (self.Nr @ cr[..., None])[..., 0]  # w_j = N_j c_j (matmul: less overhead than einsum)
        if not self.complex:
            return Wr
        Wp = (self.Np @ cp[..., None])[..., 0]
        W = np.empty((X.shape[0], n, n), dtype=complex)
        W[:, :nr] = Wr
        W[:, nr::2] = Wp
        W[:, nr + 1 :: 2] = Wp.conj()
        return W

    def coords_from_rows(self, W: NDArray) -> NDArray[np.float64]:
        """Coordinates of rows (projected on the subspaces ``S_j``), each slot normalized."""
        sl = self.slots
        W = np.asarray(W)
        cr = np.einsum("jkr,jk->jr", self.Nr, W[: sl.nr].real)
        cp = np.einsum("jkr,jk->jr", self.Np.conj(), W[sl.nr :: 2])
        return self.normalize(np.concatenate([cr.ravel(), cp.real.ravel(), cp.imag.ravel()]))

    def normalize(self, x: NDArray) -> NDArray[np.float64]:
        """Unit-norm coordinates per slot, the sign (real pole) or phase (pair) of each slot's largest
        entry fixed real positive: the objectives are invariant to both, so equal points get equal
        coordinates."""
        cr, cp = self._split(np.asarray(x, dtype=float)[None, :])
        cr, cp = cr[0], cp[0]
        if cr.size:
            k = np.argmax(np.abs(cr), axis=1)
            sg = np.where(cr[np.arange(cr.shape[0]), k] < 0, -1.0, 1.0)
            nr_ = np.linalg.norm(cr, axis=1)
            cr = cr * (sg / np.where(nr_ > 0, nr_, 1.0))[:, None]
        if cp.size:
            k = np.argmax(np.abs(cp), axis=1)
            piv = cp[np.arange(cp.shape[0]), k]
            ph = np.where(np.abs(piv) > 0, np.abs(piv) / np.where(piv == 0, 1, piv), 1.0)
            npn = np.linalg.norm(cp, axis=1)
            cp = cp * (ph / np.where(npn > 0, npn, 1.0))[:, None]
        return np.concatenate([cr.ravel(), cp.real.ravel(), cp.imag.ravel()])

    def random_coords(self, rng: np.random.Generator) -> NDArray[np.float64]:
        return self.normalize(rng.standard_normal(self.size))

    def coords_from_gain(self, L: ArrayLike) -> NDArray[np.float64] | None:
        """Coordinates of the left eigenvectors of ``A - L C`` matched to the poles (None if ``L``
        is not finite or its eigenvectors cannot be computed).

        The eigenvalues of ``A - L C`` are matched to the model's poles by an optimal assignment;
        each left eigenvector is projected on its pole's subspace.  Exact when ``L`` places the
        poles (a YT or KNV0 gain); a projection (an initial guess) otherwise.
        """
        import scipy.linalg
        from scipy.optimize import linear_sum_assignment

        eng = self.engine
        L = np.asarray(L, dtype=float)
        if L.shape != (eng.n, eng.p) or not np.all(np.isfinite(L)):
            return None
        try:
            w, Vl = scipy.linalg.eig(eng.A - L @ eng.C, left=True, right=False)
        except (np.linalg.LinAlgError, ValueError):
            return None
        if not (np.all(np.isfinite(w)) and np.all(np.isfinite(Vl))):
            return None
        cost = np.abs(self.poles[:, None] - w[None, :])
        rows, cols = linear_sum_assignment(cost)
        W = np.empty((eng.n, eng.n), dtype=complex)
        W[rows] = Vl[:, cols].conj().T
        return self.coords_from_rows(W)

    # ------------------------------------------------------------------ evaluation
    def evaluate(
        self, x: NDArray, objective: str = "kappa2", k: int | None = None, *, gradient: bool = True
    ) -> tuple[float, NDArray[np.float64] | None]:
        """The objective (``log kappa2``, its bound ``phi_k``, ``log kappa_fro`` or ``eta^2``) and
        its gradient in ``x``; ``(inf, None)`` where ``W`` is singular."""
        f, G = self.evaluate_batch(np.asarray(x, dtype=float)[None, :], objective, k, gradient=gradient)
        if not math.isfinite(f[0]):
            return math.inf, None
        return float(f[0]), None if G is None else G[0]

    def evaluate_batch(
        self, X: NDArray, objective: str = "kappa2", k: int | None = None, *, gradient: bool = True
    ) -> tuple[NDArray[np.float64], NDArray[np.float64] | None]:
        """:meth:`evaluate` for a stack of coordinate vectors ``X`` (s, m): ``(f (s,), G (s, m))``.

        One stacked inverse and SVD for all members (numpy's per-call overhead dominates at these
        sizes: measured, a batch of 4 costs about 1.5 single evaluations at n = 6).  Members with a
        singular ``W`` get ``f = inf`` and a zero gradient.
        """
        W = self._W(X)
        try:
            if objective == "eta":
                f, K = self._eta(W, gradient)
            elif self.measure == "left":
                f, K = left_spectral_objective(W, objective, k, gradient)
            else:
                f, K, _ = spectral_objective(W, objective, k, gradient)
        except np.linalg.LinAlgError:
            if X.shape[0] == 1:
                return np.full(1, math.inf), np.zeros_like(X) if gradient else None
            return self._each(X, objective, k, gradient)
        return f, None if K is None else self._grad(K)

    def _each(self, X, objective, k, gradient):
        f = np.full(X.shape[0], math.inf)
        G = np.zeros_like(X) if gradient else None
        for i in range(X.shape[0]):
            fi, Gi = self.evaluate_batch(X[i : i + 1], objective, k, gradient=gradient)
            f[i] = fi[0]
            if G is not None and Gi is not None:
                G[i] = Gi[0]
        return f, G

    def _eta(self, W: NDArray, gradient: bool) -> tuple[NDArray, NDArray | None]:
        """``eta^2 = (||A - LC||_F^2 - sum |lambda|^2) / gap^2`` and ``d(eta^2)/dW`` (fixed poles),
        through :meth:`gain_gradient` with ``d||E||_F^2 / dL = -2 E C^T``."""
        eng = self.engine
        V = np.linalg.inv(W)
        if not np.isfinite(V).all():
            raise np.linalg.LinAlgError("numerically singular eigenvector matrix")
        L = self._gain_from(W, V)
        E = eng.A - L @ eng.C
        g2 = self.gap**2 if math.isfinite(self.gap) else 1.0
        if g2 == 0.0:  # coincident poles (e.g. start poles projected onto one boundary point): eta = inf
            return np.full(W.shape[0], math.inf), np.zeros_like(W) if gradient else None
        f = (np.einsum("sij,sij->s", E, E) - self.lam2) / g2
        if not gradient:
            return f, None
        return f, self.gain_gradient(V, L, (-2.0 / g2) * (E @ eng.C.T))

    def gain_gradient(self, V: NDArray, L: NDArray, Gam: NDArray) -> NDArray:
        """``K = dphi/dW`` of a function of the gain with ``dphi = Re tr(Gam^T dL)`` (``Gam`` real,
        stacked ``(s, n, p)``).

        ``dL = sum_j v_j dw_j (B_j - L)`` with ``B_j = (A - lambda_j I) C^+`` (from ``L = V G``,
        ``g_j = w_j B_j``), so row ``j`` of ``K`` is ``conj(B_j Gam^T v_j - L Gam^T v_j)``.
        """
        eng = self.engine
        GV = Gam.transpose(0, 2, 1) @ V
        Y = eng.Cpinv @ GV
        T = eng.A @ Y - Y * self.poles[None, None, :] - L @ GV
        return T.conj().transpose(0, 2, 1)

    def penalized(
        self, X: NDArray, objective: str, k: int | None, zero: NDArray, y: NDArray, rho: NDArray,
        scale: NDArray,
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """:meth:`evaluate_batch` plus the augmented Lagrangian of structural zeros of ``L``, per member
        ``sum_zero (y h + rho h^2 / 2)`` with ``h = L / scale`` on the entries where ``zero`` is True
        (``y`` (s, n, p), ``rho`` and ``scale`` (s,): the members' own multipliers)."""
        f, G = self.evaluate_batch(X, objective, k)
        W = self._W(X)
        try:
            V = np.linalg.inv(W)
        except np.linalg.LinAlgError:
            return np.full(X.shape[0], math.inf), np.zeros_like(X)
        assert G is not None  # evaluate_batch returns a gradient when asked (the default)
        L = self._gain_from(W, V)
        h = np.where(zero, L / scale[:, None, None], 0.0)
        f = f + np.einsum("sij,sij->s", y, h) + 0.5 * rho * np.einsum("sij,sij->s", h, h)
        Gam = np.where(zero, (y + rho[:, None, None] * h) / scale[:, None, None], 0.0)
        G = G + self._grad(self.gain_gradient(V, L, Gam))
        return np.where(np.isfinite(f), f, math.inf), G

    def _grad(self, K: NDArray) -> NDArray[np.float64]:
        _, _, nr, npair, _, _ = self._dims
        gr = (K[:, :nr, None, :].real @ self.Nr)[:, :, 0, :].reshape(K.shape[0], -1)  # k_j N_j
        if not npair:
            return gr
        z = 2.0 * (K[:, nr::2, None, :] @ self._Np_conj)[:, :, 0, :]
        return np.concatenate([gr, z.real.reshape(K.shape[0], -1), z.imag.reshape(K.shape[0], -1)], axis=1)

    def _gain_from(self, W: NDArray, V: NDArray) -> NDArray[np.float64]:
        """``L = (A - V Lambda W) C^+`` (for one matrix or a stack): ``= V G`` with
        ``g_j = w_j (A - lambda_j I) C^+``, formed through the closed loop ``V Lambda W`` as scipy's
        YT does -- measured: 100x smaller pole errors on the badly scaled Chow-Kokotovic plant
        (entries ~1e6) than ``V G``, the same elsewhere (both far below the rounding floor)."""
        eng = self.engine
        M = (V * self.poles[..., None, :]) @ W
        return np.real((eng.A - M) @ eng.Cpinv)

    def design(self, x: NDArray) -> tuple[NDArray[np.float64], NDArray[np.complex128], float, float]:
        """``(L, V~, kappa2, kappa_fro)`` of the coordinates: the gain, the measured unit-column
        eigenvector matrix (complex) and its condition numbers.  ``V~`` holds the right eigenvectors
        of ``A - L C`` (``measure="right"``, ``(A - L C) V~ = V~ diag(poles)``) or the transposed
        unit-norm left eigenvectors (``"left"``: ``X = W~^T``, ``(A - L C)' X = X diag(poles)``).

        Raises
        ------
        numpy.linalg.LinAlgError
            ``W`` is singular.
        """
        W = self.W(x)
        V = np.linalg.inv(W)
        L = self._gain_from(W, V)
        if self.measure == "left":
            Vt = (W / np.linalg.norm(W, axis=1)[:, None]).T.astype(complex)
        else:
            Vt = (V / np.linalg.norm(V, axis=0)).astype(complex)
        s = np.linalg.svd(Vt, compute_uv=False)
        k2 = float(s[0] / s[-1]) if s[-1] > 0 else math.inf
        kf = float(np.linalg.norm(Vt) * np.linalg.norm(np.linalg.inv(Vt)))
        return L, Vt, k2, kf

    def metric(self, x: NDArray, objective: str) -> float:
        """The objective metric itself (kappa2, kappa_fro or eta) at ``x``."""
        f, _ = self.evaluate(x, objective, None, gradient=False)
        if not math.isfinite(f):
            return math.inf
        return math.sqrt(max(f, 0.0)) if objective == "eta" else math.exp(f)


def spectral_dW(F: NDArray, V: NDArray, Vt: NDArray, d: NDArray) -> NDArray:
    """``K = df/dW`` (``df = Re sum conj(K) dW``) of stacked ``W`` from ``F = df/dV~``, ``V~ = W^-1 D^-1``.

    ``H = F D^-1 - V diag(Re(f_j^H v~_j) / d_j^2)`` (the column normalization), ``K = -V^H H V^H``.
    """
    if np.iscomplexobj(F) or np.iscomplexobj(Vt):
        a = np.einsum("sij,sij->sj", F.conj(), Vt).real
        Vh = V.conj().transpose(0, 2, 1)
    else:  # real: no conjugate copies
        a = np.einsum("sij,sij->sj", F, Vt)
        Vh = V.transpose(0, 2, 1)
    # -H with V diag(a / d^2) = V~ diag(a / d): three elementwise passes instead of six
    Hm = (Vt * a[:, None, :] - F) / d[:, None, :]
    return Vh @ Hm @ Vh


def spectral_objective(
    W: NDArray, objective: str, k: int | None, gradient: bool = True
) -> tuple[NDArray, NDArray | None, NDArray | None]:
    """``(f (s,), K = df/dW, V = W^-1)`` of kappa2 / its bound ``phi_k`` / kappa_fro for stacked
    left eigenvector matrices ``W`` (s, n, n); ``f = inf`` (and ``K`` zero) for singular members.

    Raises
    ------
    numpy.linalg.LinAlgError
        A member is exactly singular (the caller evaluates the members one by one).
    """
    V = np.linalg.inv(W)
    d = np.sqrt((V.real**2 + V.imag**2).sum(axis=1) if np.iscomplexobj(V)
                else np.einsum("sij,sij->sj", V, V))
    # one reduction each: min is NaN if any entry is (and NaN > 0 is False)
    if not (d.min() > 0.0 and math.isfinite(float(d.max()))):
        raise np.linalg.LinAlgError("numerically singular eigenvector matrix")
    Vt = V / d[:, None, :]
    f, F = _spectral_terms(Vt, d, W, objective, k)
    f = np.where(np.isfinite(f), f, math.inf)
    if not gradient:
        return f, None, V
    K = spectral_dW(F, V, Vt, d)
    K[~np.isfinite(f)] = 0.0
    return f, K, V


def left_spectral_objective(
    W: NDArray, objective: str, k: int | None, gradient: bool = True
) -> tuple[NDArray, NDArray | None]:
    """``(f (s,), K = df/dW)`` of kappa2 / its bound ``phi_k`` / kappa_fro of the unit-row ``W~``.

    ``W~ = R^-1 W`` (``r_j = ||w_j||``) measured as ``X = W~^T`` (unit columns; kappa2 is the same for
    ``W~`` and ``X``).  With ``G~ = df/dW~ = (df/dX)^T`` and ``dr_j = Re(conj(w_j) . dw_j) / r_j``:
    row ``j`` of ``K`` is ``g~_j / r_j - w_j Re(conj(g~_j) . w_j) / r_j^3``.  kappa2 needs no inverse
    (one SVD); ``f = inf`` (and ``K`` zero) for singular members.

    Raises
    ------
    numpy.linalg.LinAlgError
        kappa_fro of an exactly singular member (the caller evaluates the members one by one).
    """
    r = np.sqrt((W.real**2 + W.imag**2).sum(axis=2) if np.iscomplexobj(W) else np.einsum("sij,sij->si", W, W))
    if not (r.min() > 0.0 and math.isfinite(float(r.max()))):
        raise np.linalg.LinAlgError("zero or non-finite eigenvector row")
    Wt = W / r[:, :, None]
    X = Wt.transpose(0, 2, 1)
    ones = np.ones(r.shape)
    Xinv = np.linalg.inv(X) if objective == "kappa_fro" else X  # only kappa_fro reads it
    f, F = _spectral_terms(X, ones, Xinv, objective, k)
    f = np.where(np.isfinite(f), f, math.inf)
    if not gradient:
        return f, None
    Gt = F.transpose(0, 2, 1)
    a = (Gt.conj() * W).real.sum(axis=2) if np.iscomplexobj(Gt) or np.iscomplexobj(W) \
        else np.einsum("sij,sij->si", Gt, W)
    K = Gt / r[:, :, None] - W * (a / r**3)[:, :, None]
    K[~np.isfinite(f)] = 0.0
    return f, K


def padded_bases(bases: list[NDArray], n: int, r: int, dtype) -> NDArray:
    """Stack ``(len, n, r)`` of bases with at most ``r`` columns each, zero-padded (a subspace at an
    unobservable mode is larger than ``rank C``)."""
    out = np.zeros((len(bases), n, r), dtype=dtype)
    for j, B in enumerate(bases):
        out[j, :, : B.shape[1]] = B
    return out


def _spectral_terms(
    Vt: NDArray, d: NDArray, W: NDArray, objective: str, k: int | None
) -> tuple[NDArray, NDArray]:
    """``(f (s,), F = df/dV~ (s, n, n))`` of a function of stacked unit-column eigenvector matrices."""
    if objective == "kappa_fro":
        X = W * d[:, :, None]  # V~^-1 = D W
        nx2 = np.einsum("sij,sij->s", X.conj(), X).real
        Xh = X.conj().transpose(0, 2, 1)
        return 0.5 * np.log(Vt.shape[1] * nx2), -(Xh @ X @ Xh) / nx2[:, None, None]
    U, s, Vh = np.linalg.svd(Vt)
    if not s[:, -1].min() > 0.0:  # numerically singular members: infinite objective
        bad = ~(s[:, -1] > 0.0)
        s = np.where(bad[:, None], 1.0, s)
        f, F = _spectral_terms_svd(U, s, Vh, k)
        return np.where(bad, math.inf, f), F
    return _spectral_terms_svd(U, s, Vh, k)


def _spectral_terms_svd(U: NDArray, s: NDArray, Vh: NDArray, k: int | None) -> tuple[NDArray, NDArray]:
    """log kappa2 (``k`` None) or its bound ``phi_k`` and ``df/dV~`` from the SVD ``U diag(s) Vh``."""
    s0, sn = s[:, :1], s[:, -1:]
    if k is None:  # exact log kappa2
        F = (U[:, :, :1] / s0[:, None, :]) * Vh[:, :1, :] - (U[:, :, -1:] / sn[:, None, :]) * Vh[:, -1:, :]
        return np.log(s0[:, 0] / sn[:, 0]), F
    e1 = (s / s0) ** (2 * k)  # in (0, 1]: no overflow
    e2 = (sn / s) ** (2 * k)
    s1, s2 = e1.sum(axis=1), e2.sum(axis=1)
    f = np.log(s0[:, 0] / sn[:, 0]) + np.log(s1 * s2) / (2.0 * k)
    al = (e1 / s1[:, None] - e2 / s2[:, None]) / s
    return f, (U * al[:, None, :]) @ Vh
