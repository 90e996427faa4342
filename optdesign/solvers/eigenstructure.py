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
  log(n) / k``), then by BFGS on the exact function (:mod:`optdesign.solvers.quasi_newton`);
* ``kappa_fro``: ``log ||V~||_F ||V~^{-1}||_F`` (smooth);
* ``eta``: ``(||A - LC||_F^2 - sum |lambda|^2) / gap^2 = eta^2`` for fixed poles (smooth).

Gradients are analytic: for ``f(V~)`` with ``df = Re tr(F^H dV~)``,
``H = F D^{-1} - V diag(Re(f_j^H v~_j) / d_j^2)`` and ``df/dW = -V^H H V^H``; a function of ``L`` with
``dphi = Re tr(Gamma^H dL)`` contributes ``dphi/dw_j = conj((A - lambda_j I) C^+ Gamma^H v_j - L Gamma^H v_j)``
(from ``dL = sum_j v_j dw_j ((A - lambda_j I) C^+ - L)``).  One evaluation costs one inverse and one
SVD of an ``n x n`` matrix: no Hessian is formed.

One output (``rank C = 1``): every ``S_j`` is a line, ``W`` is fixed up to row scaling, so the gain is
unique -- the one of Ackermann's formula and scipy's YT -- and is computed directly
(status ``solved``).  A pole repeated more than ``rank C`` times has no diagonalizable design
(:class:`DefectivePolesError`); :func:`spread_poles` gives the nearest distinct pole set for a
separation the caller chooses.

The engine holds everything that does not depend on the poles (``Z``, ``C^+``) and caches the
null-space bases per pole value, so a caller-held problem object re-solves cheaply
(:class:`EigenstructureEngine`); :func:`place_fixed` is the functional entry point.

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
import time
import warnings
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._deadline import Deadline
from .._validate import as_int, as_matrix, as_poles, as_positive_float
from ..errors import DimensionError, NotObservableError, ValidationError
from ..results import Status
from .quasi_newton import bfgs_minimize_batch

__all__ = [
    "OBJECTIVES",
    "KAPPA2_CONTINUATION",
    "DefectivePolesError",
    "EigenstructureEngine",
    "FixedPoleModel",
    "StartRecord",
    "PlacementOutcome",
    "place_fixed",
    "spread_poles",
    "pole_multiplicities",
]

_EPS = float(np.finfo(float).eps)

#: objectives of the engine
OBJECTIVES = ("kappa2", "kappa_fro", "eta")

#: orders ``k`` of the smooth kappa2 bound ``phi_k`` minimized before the exact function
#: (``None``): measured on the pole-placement problems, starting at the exact function lets
#: BFGS stall for hundreds of iterations at a tie of singular values (scipy's car example: 551
#: evaluations to reach 1e-3 of the optimum, 285 in all with this continuation)
KAPPA2_CONTINUATION: tuple[int | None, ...] = (4, 64, 1024, 16384, None)

Objective = Literal["kappa2", "kappa_fro", "eta"]


class DefectivePolesError(ValidationError):
    """A pole is requested more often than ``rank(C)``: ``A - L C`` would be defective.

    The eigenspace of ``A - L C`` for a pole has dimension at most ``rank(C)``, so a larger
    multiplicity forces a Jordan block: kappa2 is infinite for every gain.  Pass a separation
    (:func:`spread_poles`) to get the nearest distinct-pole design instead.

    Attributes
    ----------
    pole : complex
    multiplicity : int
    rank : int
    """

    def __init__(self, message: str, *, pole: complex, multiplicity: int, rank: int) -> None:
        super().__init__(message)
        self.pole = complex(pole)
        self.multiplicity = int(multiplicity)
        self.rank = int(rank)


# --------------------------------------------------------------------------- pole sets


def pole_multiplicities(poles: ArrayLike, *, rtol: float = 1e-10) -> list[tuple[complex, int]]:
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
    array([-3.  +0.j  , -0.99+0.j  , -1.01+0.j  ])
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
            pts = np.where(np.abs(pts.imag) <= 1e-12 * rad, pts.real + 0j, pts)
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
        P = as_poles("poles", poles)
        real = np.sort(P[P.imag == 0].real)
        up = P[P.imag > 0]
        up = up[np.lexsort((up.imag, up.real))]
        return cls(real, up)


# --------------------------------------------------------------------------- records


@dataclass(frozen=True)
class StartRecord:
    """One start of :func:`place_fixed`.

    Attributes
    ----------
    origin : str
        ``"YT"``, ``"KNV0"``, ``"random"``, ``"warm start"``, ``"unique"``.
    kappa2 : float
        Condition number of the start's final eigenbasis (the engine's ``V``).
    objective_value : float
        The objective metric (kappa2, kappa_fro or eta) at the start's end.
    start_value : float
        The objective metric at the start point (inf if it was not a valid start).
    iterations, evaluations : int
        BFGS steps and objective evaluations over all stages.
    reason : str
        Why the last stage stopped.
    time : float
        CPU seconds.
    """

    origin: str
    kappa2: float
    objective_value: float
    start_value: float
    iterations: int
    evaluations: int
    reason: str
    time: float


@dataclass(frozen=True)
class PlacementOutcome:
    """What the engine found (not verified: the design layer verifies it independently).

    Attributes
    ----------
    L : (n, p) ndarray
        The gain; ``A - L C`` has the poles ``poles`` (up to rounding).
    V : (n, n) ndarray of complex
        Unit-column right eigenvectors of ``A - L C`` (column ``j`` for ``poles[j]``).
    poles : (n,) ndarray of complex
        The placed poles, in the order of ``V``'s columns (real, then pairs ``z, conj z``).
    kappa2, kappa_fro : float
        Condition numbers of ``V`` (2-norm, Frobenius).
    objective : str
    objective_value : float
        The objective metric at ``L`` (kappa2, kappa_fro or eta).
    status : Status
        ``solved`` (unique gain, or ``rank C = n``), ``optimal`` (a local minimum from the best
        start), ``iteration_limit``, ``time_limit`` (best so far), ``not_found`` (no start gave a
        finite objective).
    message : str
    iterations, evaluations : int
        Totals over all starts.
    starts : tuple of StartRecord
    coords : (m,) ndarray
        The eigenvector coordinates of the solution (a warm start for the same poles).
    unique : bool
        One output: the gain is determined by the poles.
    requested_poles : (n,) ndarray of complex
        What the caller asked for (differs from ``poles`` for a spread, nearest distinct design).
    separation : float or None
        The separation used by a nearest distinct-pole design.
    time : float
        CPU seconds.
    """

    L: NDArray[np.float64]
    V: NDArray[np.complex128]
    poles: NDArray[np.complex128]
    kappa2: float
    kappa_fro: float
    objective: str
    objective_value: float
    status: Status
    message: str
    iterations: int = 0
    evaluations: int = 0
    starts: tuple[StartRecord, ...] = ()
    coords: NDArray[np.float64] | None = None
    unique: bool = False
    requested_poles: NDArray[np.complex128] | None = None
    separation: float | None = None
    time: float = 0.0
    extra: dict[str, Any] = field(default_factory=dict)


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
        tol = max(C.shape) * _EPS * (float(s[0]) if s.size else 0.0)
        r = int(np.sum(s > tol))
        if r == 0:
            raise DimensionError("C must have rank >= 1 (it is zero): no output, no observer")
        self.A = A
        self.C = C
        self.n, self.p, self.rank = n, C.shape[0], r
        self.Z = Vt[r:].T.copy()  # (n, n - r), orthonormal basis of null(C)
        self.Cpinv = (Vt[:r].T / s[:r]) @ U[:, :r].T  # (n, p)
        self._bases: dict[complex, NDArray] = {}

    # ------------------------------------------------------------------ bases
    def basis(self, lam: complex) -> NDArray:
        """Orthonormal ``N`` (n, r) with ``S(lam) = {(N c)^T}``; real for a real ``lam``.

        The complete QR of ``M = (A - lam I) Z`` gives ``range(M)^perp``; ``w M = 0`` is the
        bilinear (not Hermitian) condition, so ``N`` is its complex conjugate.
        """
        lam = complex(lam)
        N = self._bases.get(lam)
        if N is not None:
            return N
        n, r = self.n, self.rank
        if r == n:
            N = np.eye(n)
        else:
            M = (self.A - lam * np.eye(n)) @ self.Z if lam.imag else (self.A - lam.real * np.eye(n)) @ self.Z
            Q, _ = np.linalg.qr(M, mode="complete")
            N = Q[:, n - r :].conj()
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
        scale = max(float(np.linalg.norm(self.A, 2)), float(np.linalg.norm(self.C, 2)), 1e-300)
        for mu in w:
            s = np.linalg.svd(np.vstack([self.A - mu * np.eye(self.n), self.C]), compute_uv=False)
            if s[-1] <= 1e3 * self.n * _EPS * scale:
                out.append(mu)
        return np.asarray(out, dtype=complex)

    def model(self, poles: ArrayLike) -> FixedPoleModel:
        """The parametrization for one pole set (bases from the cache)."""
        return FixedPoleModel(self, poles)


class FixedPoleModel:
    """Eigenvector coordinates -> gain, eigenbasis and objective, for one fixed pole set.

    The real coordinate vector ``x`` holds, in order, ``c_j`` (r entries) for every real pole,
    then ``Re c_j`` and ``Im c_j`` for every pair (``j`` in the row order of :class:`_Slots`).

    Parameters
    ----------
    engine : EigenstructureEngine
    poles : (n,) array_like of complex
        Conjugate-closed; a pole may repeat up to ``rank C`` times.

    Raises
    ------
    DimensionError
        Wrong number of poles.
    NotConjugateClosedError
        Poles not closed under conjugation.
    DefectivePolesError
        A pole repeated more than ``rank C`` times.
    """

    def __init__(self, engine: EigenstructureEngine, poles: ArrayLike) -> None:
        self.engine = engine
        n, r = engine.n, engine.rank
        P = as_poles("poles", poles, n)
        for v, m in pole_multiplicities(P):
            if m > r:
                raise DefectivePolesError(
                    f"pole {v:.6g} is requested {m} times but rank(C) = {r}: the eigenspace of A - LC for "
                    f"it has dimension <= rank(C), so A - LC would be defective (kappa2 = inf); give a "
                    "separation for the nearest distinct-pole design",
                    pole=v,
                    multiplicity=m,
                    rank=r,
                )
        self.slots = _Slots.of(P)
        sl = self.slots
        self.poles = sl.row_poles
        self.Nr = np.stack([engine.basis(complex(v)) for v in sl.real]) if sl.nr else np.zeros((0, n, r))
        self.Np = (
            np.stack([engine.basis(complex(v)) for v in sl.upper]).astype(complex)
            if sl.npair
            else np.zeros((0, n, r), dtype=complex)
        )
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
        Wr = np.einsum("jkr,sjr->sjk", self.Nr, cr)
        if not self.complex:
            return Wr
        Wp = np.einsum("jkr,sjr->sjk", self.Np, cp)
        W = np.empty((X.shape[0], n, n), dtype=complex)
        W[:, :nr] = Wr
        W[:, nr::2] = Wp
        W[:, nr + 1 :: 2] = Wp.conj()
        return W

    def coords_from_rows(self, W: NDArray) -> NDArray[np.float64]:
        """Coordinates of rows (projected on the subspaces ``S_j``), each slot normalized."""
        sl = self.slots
        W = np.asarray(W)
        cr = np.einsum("jkr,jk->jr", self.Nr, W[: sl.nr].real) if sl.nr else np.zeros((0, self.engine.rank))
        cp = (
            np.einsum("jkr,jk->jr", self.Np.conj(), W[sl.nr :: 2])
            if sl.npair
            else np.zeros((0, self.engine.rank), complex)
        )
        return self.normalize(np.concatenate([cr.ravel(), cp.real.ravel(), cp.imag.ravel()]))

    def normalize(self, x: NDArray) -> NDArray[np.float64]:
        """Unit-norm coordinates per slot, pair phases fixed (the objectives are invariant to both)."""
        cr, cp = self._split(np.asarray(x, dtype=float)[None, :])
        cr, cp = cr[0], cp[0]
        nr_ = np.linalg.norm(cr, axis=1, keepdims=True)
        cr = cr / np.where(nr_ > 0, nr_, 1.0)
        if cp.size:
            k = np.argmax(np.abs(cp), axis=1)
            piv = cp[np.arange(cp.shape[0]), k]
            ph = np.where(np.abs(piv) > 0, np.abs(piv) / np.where(piv == 0, 1, piv), 1.0)
            cp = cp * ph[:, None]
            npn = np.linalg.norm(cp, axis=1, keepdims=True)
            cp = cp / np.where(npn > 0, npn, 1.0)
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
            V = np.linalg.inv(W)
        except np.linalg.LinAlgError:  # a singular member: the others one by one
            return self._each(X, objective, k, gradient)
        d = np.sqrt(np.einsum("sij,sij->sj", V.conj(), V).real)
        ok = np.isfinite(d).all(axis=1) & (d.min(axis=1) > 0.0)
        if not ok.all():
            if not ok.any():
                return np.full(X.shape[0], math.inf), None if not gradient else np.zeros_like(X)
            return self._each(X, objective, k, gradient)
        Vt = V / d[:, None, :]
        if objective == "eta":
            f, Gam = self._eta_terms(W, V)
            F = None
        else:
            f, F = _spectral_terms(Vt, d, W, objective, k)
            Gam = None
        f = np.where(np.isfinite(f), f, math.inf)
        if not gradient:
            return f, None
        G = self._grad(self._dW(F, V, Vt, d, Gam, W))
        G[~np.isfinite(f)] = 0.0
        return f, G

    def _each(self, X, objective, k, gradient):
        f = np.full(X.shape[0], math.inf)
        G = np.zeros_like(X) if gradient else None
        for i in range(X.shape[0]):
            try:
                fi, Gi = self.evaluate_batch(X[i : i + 1], objective, k, gradient=gradient)
            except np.linalg.LinAlgError:
                continue
            f[i] = fi[0]
            if gradient and Gi is not None:
                G[i] = Gi[0]
        return f, G

    def _eta_terms(self, W: NDArray, V: NDArray) -> tuple[NDArray, NDArray]:
        L = self._gain_from(W, V)
        E = self.engine.A - L @ self.engine.C
        dep2 = np.einsum("sij,sij->s", E, E) - self.lam2
        g2 = self.gap**2 if math.isfinite(self.gap) else 1.0
        return dep2 / g2, -2.0 * (E @ self.engine.C.T) / g2

    def _dW(self, F, V, Vt, d, Gam, W) -> NDArray:
        """``df/dW`` (stacked ``K`` with ``df = Re sum conj(K) dW``) from ``F = df/dV~`` and ``Gam = df/dL``."""
        Vh = V.conj().transpose(0, 2, 1)
        K = np.zeros(V.shape, dtype=V.dtype)
        if F is not None:
            a = np.real(np.einsum("sij,sij->sj", F.conj(), Vt))
            H = F / d[:, None, :] - V * (a / d**2)[:, None, :]
            K = -(Vh @ H @ Vh)
        if Gam is not None:
            eng = self.engine
            L = self._gain_from(W, V)
            GV = Gam.transpose(0, 2, 1) @ V  # Gam real: Gam^H = Gam^T
            Y = eng.Cpinv @ GV
            T = eng.A @ Y - Y * self.poles[None, None, :] - L @ GV
            K = K + T.conj().transpose(0, 2, 1)
        return K

    def _grad(self, K: NDArray) -> NDArray[np.float64]:
        _, _, nr, npair, _, _ = self._dims
        gr = np.einsum("jkr,sjk->sjr", self.Nr, K[:, :nr].real).reshape(K.shape[0], -1)
        if not npair:
            return gr
        z = 2.0 * np.einsum("jkr,sjk->sjr", self.Np.conj(), K[:, nr::2])
        return np.concatenate([gr, z.real.reshape(K.shape[0], -1), z.imag.reshape(K.shape[0], -1)], axis=1)

    def _gain_from(self, W: NDArray, V: NDArray) -> NDArray[np.float64]:
        """``L = V G`` with ``g_j = w_j (A - lambda_j I) C^+`` (for one matrix or a stack)."""
        eng = self.engine
        G = (W @ eng.A - self.poles[:, None] * W) @ eng.Cpinv
        return np.real(V @ G)

    def design(self, x: NDArray) -> tuple[NDArray[np.float64], NDArray[np.complex128], float, float]:
        """``(L, V~, kappa2, kappa_fro)`` of the coordinates: the gain, the unit-column right
        eigenvectors (complex) and their condition numbers.

        Raises
        ------
        numpy.linalg.LinAlgError
            ``W`` is singular.
        """
        W = self.W(x)
        V = np.linalg.inv(W)
        L = self._gain_from(W, V)
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


def _spectral_terms(Vt: NDArray, d: NDArray, W: NDArray, objective: str, k: int | None) -> tuple[NDArray, NDArray]:
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


# --------------------------------------------------------------------------- the solver


def _peer_start(A: NDArray, C: NDArray, poles: NDArray, method: str) -> NDArray[np.float64] | None:
    """scipy's robust placement (YT / KNV0, scipy's default tolerances) on the dual, or None."""
    from scipy.signal import place_poles

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            L = place_poles(A.T, C.T, poles, method=method).gain_matrix.T
    except (ValueError, np.linalg.LinAlgError):
        return None
    return L if np.all(np.isfinite(L)) else None


#: per stage: (order k of the kappa2 bound or None for the exact function, relative decrease
#: tolerance of the stage); loose early stages, measured: tight ones spend evaluations on a
#: surrogate whose minimizer is discarded anyway
_STAGE_FTOL = {4: 1e-5, 64: 1e-6, 1024: 1e-8, 16384: 1e-9, None: 1e-9}
#: gradient tolerance of the smooth stages (log kappa2 per unit change of unit-norm coordinates)
_GTOL = 1e-6


def _run_starts(
    model: FixedPoleModel,
    X0: NDArray,
    objective: str,
    deadline: Deadline,
    max_iter: int,
    stages: tuple[int | None, ...],
) -> list[tuple[NDArray, int, int, str]]:
    """Minimize from every row of ``X0`` through the continuation ``stages`` (all starts in
    lockstep, :func:`~optdesign.solvers.quasi_newton.bfgs_minimize_batch`; each start's
    inverse-Hessian approximation carried from stage to stage).  Per start
    ``(x, iterations, evaluations, reason)``."""
    X = np.array(X0, dtype=float)
    s = X.shape[0]
    its, evs, reasons = np.zeros(s, int), np.zeros(s, int), ["converged"] * s
    H: list[NDArray | None] = [None] * s
    for k in stages:
        if deadline.expired:
            reasons = ["time_limit"] * s
            break

        def fun(Z, _k=k):
            return model.evaluate_batch(Z, objective, _k)

        res, H = bfgs_minimize_batch(
            fun, X, max_iter=max_iter, ftol=_STAGE_FTOL.get(k, 1e-8), gtol=0.0 if k is None else _GTOL,
            deadline=deadline, H0=H,
        )
        for i, r in enumerate(res):
            X[i] = r.x
            its[i] += r.iterations
            evs[i] += r.evaluations
            reasons[i] = r.reason
    return [(model.normalize(X[i]), int(its[i]), int(evs[i]), reasons[i]) for i in range(s)]


def place_fixed(
    A: ArrayLike,
    C: ArrayLike,
    poles: ArrayLike,
    *,
    objective: Objective = "kappa2",
    starts: int = 4,
    seed: int = 0,
    deadline: Deadline | float | None = None,
    warm_start: ArrayLike | None = None,
    separation: float | None = None,
    max_iter: int = 400,
    engine: EigenstructureEngine | None = None,
) -> PlacementOutcome:
    """Observer gain with prescribed poles minimizing kappa2 (or kappa_fro, eta) of ``A - L C``.

    Parameters
    ----------
    A : (n, n) array_like
    C : (p, n) array_like
    poles : (n,) array_like of complex
        Conjugate-closed; a pole may repeat up to ``rank C`` times (more: see ``separation``).
    objective : {"kappa2", "kappa_fro", "eta"}
    starts : int, default 4
        Starting points: scipy YT, scipy KNV0 (real poles only) and random eigenvector
        coordinates, in that order, ``starts`` in all (plus the warm start, if given).
    seed : int, default 0
        Seeds the random starts.
    deadline : Deadline or float, optional
        Time budget (seconds or a shared :class:`~optdesign._deadline.Deadline`): no new start or
        stage begins after it expires; the best answer so far is returned (status ``time_limit``).
    warm_start : array_like, optional
        Coordinates from a previous :class:`PlacementOutcome` (same poles), or a gain ``(n, p)``.
    separation : float, optional
        For poles repeated more than ``rank C`` times: design for the nearest distinct pole set
        (:func:`spread_poles` with this relative separation) instead of refusing.
    max_iter : int, default 400
        BFGS iterations per continuation stage.
    engine : EigenstructureEngine, optional
        Re-use the bases of an engine built for ``(A, C)`` (``A`` and ``C`` are then ignored).

    Returns
    -------
    PlacementOutcome

    Raises
    ------
    ValidationError
        Unknown objective, bad ``starts``/``seed``/``separation``/``max_iter``.
    DimensionError, NotConjugateClosedError
        Bad shapes or poles.
    DefectivePolesError
        A pole repeated more than ``rank C`` times and no ``separation``.
    NotObservableError
        The poles cannot be assigned (an unobservable mode of ``(C, A)`` is not among them).

    References
    ----------
    Kautsky, Nichols & Van Dooren (1985); Tits & Yang (1996); Lewis & Overton (2013).
    """
    t0 = time.process_time()
    if objective not in OBJECTIVES:
        raise ValidationError(f"objective must be one of {OBJECTIVES}; found {objective!r}")
    starts = as_int("starts", starts, 1)
    seed = as_int("seed", seed, 0)
    max_iter = as_int("max_iter", max_iter, 1)
    dl = Deadline.of(deadline)
    eng = engine if engine is not None else EigenstructureEngine(A, C)
    requested = as_poles("poles", poles, eng.n)
    target = requested
    if separation is not None:
        target = spread_poles(requested, eng.rank, separation)
    model = FixedPoleModel(eng, target)
    if objective == "eta" and any(m > 1 for _, m in pole_multiplicities(target)):
        raise ValidationError("objective 'eta' needs distinct poles (eta is infinite at a repeated pole)")
    common = dict(requested_poles=requested, separation=None if separation is None else float(separation))

    if eng.rank == eng.n or eng.rank == 1:
        return _direct(model, objective, t0, common)

    cands = _start_points(model, eng, target, starts, seed, warm_start)
    records: list[StartRecord] = []
    best: tuple[float, NDArray] | None = None
    stages = KAPPA2_CONTINUATION if objective == "kappa2" else (None,)
    ts = time.process_time()
    v0 = [model.metric(x0, objective) for _, x0 in cands]
    live = [i for i, v in enumerate(v0) if math.isfinite(v)]
    runs = _run_starts(model, np.stack([cands[i][1] for i in live]), objective, dl, max_iter, stages) if live else []
    share = (time.process_time() - ts) / max(1, len(live))
    out = dict(zip(live, runs, strict=True))
    for i, (origin, x0) in enumerate(cands):
        if i not in out:
            records.append(StartRecord(origin, math.inf, math.inf, math.inf, 0, 1, "singular start", 0.0))
            continue
        x, its, evs, reason = out[i]
        val = model.metric(x, objective)
        if not val <= v0[i]:  # never worse than the start (rounding in the last stage)
            x, val = x0, v0[i]
        try:
            k2 = model.design(x)[2]
        except np.linalg.LinAlgError:
            k2 = math.inf
        records.append(StartRecord(origin, k2, val, v0[i], its, evs, reason, share))
        if math.isfinite(val) and (best is None or val < best[0]):
            best = (val, x)
    total_it = sum(r.iterations for r in records)
    total_ev = sum(r.evaluations for r in records)
    timed_out = any(r.reason == "time_limit" for r in records) or (dl.expired and best is None)
    limited = bool(records) and all(r.reason in ("max_iter", "max_eval") for r in records if r.reason != "singular start")
    if best is None:
        nan = math.nan
        n, p = eng.n, eng.p
        return PlacementOutcome(
            np.full((n, p), nan), np.full((n, n), nan + 0j), model.poles, math.inf, math.inf, objective,
            math.inf, Status.TIME_LIMIT if timed_out else Status.NOT_FOUND,
            "no start gave a nonsingular eigenvector matrix" + (" before the time limit" if timed_out else ""),
            total_it, total_ev, tuple(records), None, time=time.process_time() - t0, **common,
        )
    val, x = best
    L, Vt, k2, kf = model.design(x)
    status = Status.TIME_LIMIT if timed_out else Status.ITERATION_LIMIT if limited else Status.OPTIMAL
    ib = min(range(len(records)), key=lambda i: records[i].objective_value)
    msg = (
        f"best of {len(records)} starts (start {ib}, {records[ib].origin}): {objective} = {val:.6g}"
        + (" (time limit reached: best so far)" if timed_out else "")
    )
    return PlacementOutcome(
        L, Vt, model.poles, k2, kf, objective, val, status, msg, total_it, total_ev, tuple(records), x,
        time=time.process_time() - t0, **common,
    )


def _direct(model: FixedPoleModel, objective: str, t0: float, common: dict) -> PlacementOutcome:
    """``rank C = 1`` (the unique gain) or ``rank C = n`` (an orthonormal eigenbasis, kappa2 = 1)."""
    eng = model.engine
    sl = model.slots
    if eng.rank == 1:
        x = model.normalize(np.concatenate([np.ones(sl.nr), np.ones(sl.npair), np.zeros(sl.npair)]))
        what, unique = "one output: the gain is unique for these poles", True
    else:  # every S_j is the whole space: rows e_k, (e_a +- j e_b) / sqrt 2 give a unitary W
        n = eng.n
        W = np.zeros((n, n), dtype=complex)
        W[: sl.nr, : sl.nr] = np.eye(sl.nr)
        for i in range(sl.npair):
            a, b = sl.nr + 2 * i, sl.nr + 2 * i + 1
            W[a, a], W[a, b] = 1.0, 1j
        x = model.coords_from_rows(W)
        what, unique = "rank(C) = n: a unitary eigenbasis, kappa2 = 1", False
    try:
        L, Vt, k2, kf = model.design(x)
    except np.linalg.LinAlgError as exc:
        raise NotObservableError(
            f"the poles cannot be assigned: the eigenvector matrix is singular ({exc}); an unobservable "
            "mode of (C, A) must be among the poles"
        ) from exc
    val = model.metric(x, objective)
    rec = StartRecord("unique" if unique else "unitary", k2, val, val, 0, 1, "direct", time.process_time() - t0)
    return PlacementOutcome(
        L, Vt, model.poles, k2, kf, objective, val, Status.SOLVED, what, 0, 1, (rec,), x, unique=unique,
        time=time.process_time() - t0, **common,
    )


def _start_points(
    model: FixedPoleModel,
    eng: EigenstructureEngine,
    target: NDArray,
    starts: int,
    seed: int,
    warm_start: ArrayLike | None,
) -> list[tuple[str, NDArray]]:
    """Warm start (if any), then YT, KNV0 (real poles) and random coordinates: ``starts`` in all."""
    out: list[tuple[str, NDArray]] = []
    if warm_start is not None:
        ws = np.asarray(warm_start, dtype=float)
        if ws.shape == (model.size,):
            out.append(("warm start", model.normalize(ws)))
        elif ws.shape == (eng.n, eng.p):
            x = model.coords_from_gain(ws)
            if x is not None:
                out.append(("warm start", x))
        else:
            raise DimensionError(
                f"warm_start must be coordinates ({model.size},) or a gain ({eng.n}, {eng.p}); found {ws.shape}"
            )
    rng = np.random.default_rng(seed)
    methods = ["YT"] + (["KNV0"] if np.all(target.imag == 0) else [])
    k = 0
    while k < starts:
        if methods:
            m = methods.pop(0)
            L0 = _peer_start(eng.A, eng.C, target, m)
            x = None if L0 is None else model.coords_from_gain(L0)
            if x is not None:
                out.append((m, x))
                k += 1
            continue
        out.append(("random", model.random_coords(rng)))
        k += 1
    return out
