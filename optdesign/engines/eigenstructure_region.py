r"""Region mode of the eigenstructure engine: the poles are variables too (issue 13).

The well-conditioned observer with poles free in a convex region ``D`` (:mod:`optdesign.regions`)
minimizes kappa2 jointly over the eigenvector coordinates ``c`` and the poles, on the machinery
of :mod:`optdesign.engines.eigenstructure`:

* **Moving subspaces.**  The left eigenvector of pole ``lambda`` lies in ``S(lambda)``
  (``w (A - lambda I) Z = 0``).  When ``lambda`` moves, the basis moves by *parallel transport*:
  the basis at a trial pole is the orthonormal basis of ``S(lambda)`` closest to the stage's
  anchor basis (polar factor of ``N(lambda)^H N_anchor``), so the coordinates keep their meaning
  and BFGS keeps its curvature information.  Its derivative is the minimal-norm tangent
  ``dw = dlambda (w Z) M^+`` with ``M = (A - lambda I) Z`` (from ``dw M = w Z dlambda``), which
  gives ``df/dlambda = Re sum_k conj(K_jk) t_jk`` with the same ``K = df/dW`` as for fixed poles
  (a pair's ``sigma + j omega`` counts twice, through the row and its conjugate).  The anchor is
  re-set to the current bases at every continuation stage; a step that would rotate a subspace
  by more than 60 degrees from its anchor is rejected (value inf), so a stage never leaves the
  chart where the transport is defined.
* **The region** enters through the poles' parametrization (issue 28): each free pole is the image
  of free variables under :class:`~optdesign.engines.region_map.PoleMap`, a smooth map of the
  plane onto the closed region that folds at its boundary (from the region's quadratic
  constraints, :meth:`Region.constraints`, fitted by :class:`QuadraticConstraints`).  Every
  iterate is a feasible design, and an optimum on the boundary is a smooth minimum of the
  composed function.  (Before, a log barrier lowered stage by stage to ``1e-9`` kept the poles
  inside, and each start ran with two barrier weights.)  The only barrier left,
  ``-mu sum log(|lambda_i - lambda_j| / rho)`` with ``mu`` lowered with the kappa2 continuation
  (``rho``: the region's inner radius), keeps two poles from meeting on the boundary -- a double
  eigenvalue, whose eigenvectors the poles do not determine.
* **Unobservable modes** of ``(C, A)`` are eigenvalues of every ``A - L C``: they are pinned
  (not variables), with their larger subspaces.

Every start gives three candidates, each kept if better: its own gain (e.g. scipy YT at the
caller's naive poles), the fixed-pole optimum at its poles, and the region optimum followed by
a fixed-pole polish at the final poles -- so the design is never worse than any start.

All starts run in lockstep (issue 28): the free-pole stages of every start, for each real/complex
pole pattern on one model, in one BFGS batch; a member whose line search stops at its chart's edge
is re-anchored and goes on; members at the point of a better one stop after each stage, and after
the second stage only the best few go on
(:mod:`optdesign.engines.eigenstructure_region_lockstep`).

References
----------
Kautsky, Nichols & Van Dooren (1985); Chilali & Gahinet (1996) for the regions; P.-A. Absil,
R. Mahony and R. Sepulchre, Optimization Algorithms on Matrix Manifolds (Princeton, 2008),
ch. 4 and 8 (retractions, vector transport).
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._deadline import Deadline
from .._validate import as_int, as_poles
from ..analysis import metrics
from ..errors import DimensionError, ValidationError
from ..model.regions import Region
from ..results import Status
from .eigenstructure import (
    KAPPA2_CONTINUATION,
    MEASURES,
    EigenstructureEngine,
    FixedPoleModel,
    Measure,
    padded_bases,
)
from .eigenstructure_fixed import PlacementOutcome, StartRecord
from .region_map import PoleMap
from .tolerances import (
    CLEARANCE_FLOOR,
    QUADRATIC_MISFIT_TOL,
    REGION_STAGES,
    STENCIL_MIN_SCALE,
)

if TYPE_CHECKING:  # it builds on this module's model
    from .region_batch import PatternBatch

__all__ = [
    "RegionModel",
    "RegionStart",
    "QuadraticConstraints",
    "place_region",
    "candidate_attains",
    "REGION_STAGES",
    "REGION_FIXED_STAGES",
    "REGION_WARM_STAGES",
    "interior_of",
]

#: continuation of the fixed-pole optimization at a start's poles (before its poles are freed): its
#: minimizer is a candidate and a member of the free-pole stages, which start again from k = 4, so
#: only the first stage runs (issue 28, round 9, 49 plants n <= 10: against the exact kappa2, ending
#: at k = 1024 took 0.91x the CPU with no plant worse by more than 2e-3; ending at k = 4 another 0.90x,
#: HE5, PSM and random n = 6 s0 0.3-0.4 % worse -- the values of the previous stop -- and random n = 9
#: s0 0.25 % better; n = 20 and 30 0.89x and 0.83x, kappa2 -0.1 % and 0.0 %)
REGION_FIXED_STAGES: tuple[int | None, ...] = KAPPA2_CONTINUATION[:1]
#: the stages of a warm start (RegionStart.warm): the last two of REGION_STAGES
REGION_WARM_STAGES: tuple[tuple[int | None, float], ...] = REGION_STAGES[-2:]
#: smallest singular value of ``N(lambda)^H N_anchor`` accepted (cos 60 degrees): a chart's edge, where
#: a member's line search stops and the member is re-anchored (``_region_stages``)
_MIN_OVERLAP = 0.5
#: ... for kappa2: cos 75.5 degrees, a wider chart (issue 28, round 10, measured on 49 plants n <= 10:
#: fewer line searches end at the edge, and fewer re-anchored rounds follow -- they were 30-40 % of
#: the plants at the median's CPU; 0.97x the total CPU, REA2, random n = 6 s0 and s1 0.46, 0.39 and
#: 0.49 s against 0.56, 0.52 and 0.52 s; HE5 -0.33 %, PSM -0.32 %, TG1 +1.2 %, random n = 10 s1,
#: n = 8 s1 and n = 9 s0 +0.13, +0.11 and +0.05 %.  0.2: AC7 +0.37 %, REA2 0.65 s; 0.15: TG1 +6.4 %;
#: 0.1: UWV +4 %.  Not for eta: AC8 +6.5 %, random n = 7 s1 +5 %, n = 10 s1 +4.9 %)
_MIN_OVERLAP_KAPPA2 = 0.25


@dataclass(frozen=True)
class RegionStart:
    """A start of :func:`place_region`: poles strictly inside the region and a gain or coordinates.

    Attributes
    ----------
    origin : str
    poles : (n,) ndarray of complex
    gain : (n, p) ndarray or None
        A gain whose left eigenvectors (projected on the subspaces of ``poles``) start the search;
        None: scipy YT at ``poles`` (one sweep), else random coordinates.
    warm : bool
        The start is a converged design of a nearby problem (the previous point of a sweep): only
        the last continuation stages run (:data:`REGION_WARM_STAGES`), from its fixed-pole polish.
    """

    origin: str
    poles: NDArray[np.complex128]
    gain: NDArray[np.float64] | None = None
    warm: bool = False


class RegionModel:
    """Coordinates and free poles -> objective (with the separation barrier) and gradient.

    The variable vector is ``[c, t, a, b]``: the eigenvector coordinates in the layout of
    :class:`~optdesign.engines.eigenstructure.FixedPoleModel` (free real poles, pinned real poles,
    free pairs, pinned pairs), then the map variables of the free real poles (``t``) and of the
    free pairs' upper members (``a + j b``, :class:`~optdesign.engines.region_map.PoleMap`).

    Parameters
    ----------
    engine : EigenstructureEngine
    n_real, n_pairs : int
        Free real poles and free conjugate pairs (``n_real + 2 n_pairs + len(pinned) = n``).
    region : Region
    pinned : (k,) array_like of complex
        Conjugate-closed poles that are not variables (the unobservable modes).
    interior : (float, float), optional
        ``(x0, rho)`` of :func:`interior_of` when the caller has it (it costs a golden-section search).
    measure : {"right", "left"}, default "right"
        Which eigenvectors of ``A - L C`` the objective measures, as
        :class:`~optdesign.engines.eigenstructure.FixedPoleModel` (``"left"``: state feedback's
        ``cond(X)`` of the transposed loop).

    Raises
    ------
    DimensionError
        The counts do not add up to ``n``.
    """

    @staticmethod
    def overlap_floor(objective: str) -> float:
        """The smallest overlap with its anchor of a free pole's basis in a feasible member, for
        ``objective`` (kappa2: ``_MIN_OVERLAP_KAPPA2``, a wider chart; otherwise ``_MIN_OVERLAP``)."""
        return _MIN_OVERLAP_KAPPA2 if objective == "kappa2" else _MIN_OVERLAP

    def __init__(
        self,
        engine: EigenstructureEngine,
        n_real: int,
        n_pairs: int,
        region: Region,
        pinned: ArrayLike = (),
        interior: tuple[float, float] | None = None,
        measure: Measure = "right",
    ) -> None:
        if measure not in MEASURES:
            raise ValidationError(f"measure must be one of {MEASURES}; found {measure!r}")
        self.engine = engine
        self.region = region
        self.measure = measure
        n, r = engine.n, engine.rank
        pin = np.asarray(pinned, dtype=complex).ravel()
        pin_real = np.sort(pin[pin.imag == 0].real)
        pin_up = pin[pin.imag > 0]
        if n_real + 2 * n_pairs + pin.size != n:
            raise DimensionError(
                f"{n_real} real poles + {n_pairs} pairs + {pin.size} pinned poles != n = {n}"
            )
        self.nrf, self.npf = n_real, n_pairs
        self.pin_real, self.pin_up = pin_real, pin_up
        Bpr = [engine.basis(complex(v)) for v in pin_real]
        Bpp = [engine.basis(complex(v)) for v in pin_up]
        self.r = max([r] + [B.shape[1] for B in Bpr + Bpp])
        self.nr = n_real + pin_real.size
        self.np = n_pairs + pin_up.size
        self.Npr = padded_bases(Bpr, n, self.r, float)
        self.Npp = padded_bases(Bpp, n, self.r, complex)
        self.complex = self.np > 0
        self.ncoord = self.r * (self.nr + 2 * self.np)
        self.size = self.ncoord + n_real + 2 * n_pairs
        x0, self.rho = interior or interior_of(region)  # rho, the inner radius: the barrier's length
        self.map = PoleMap(QuadraticConstraints(region, self.rho).coef, x0)
        # the separation barrier's pairs of pole slots (i < j, at least one free: region_batch)
        free = np.zeros(n, dtype=bool)
        free[:n_real] = True
        free[self.nr : self.nr + 2 * n_pairs] = True
        bi, bj = np.triu_indices(n, 1)
        keep = free[bi] | free[bj]
        self._bi, self._bj = bi[keep], bj[keep]
        self._slots = np.empty(n, dtype=complex)  # the pinned poles in their slots (free ones: set per call)
        self._slots[n_real : self.nr] = pin_real
        self._slots[self.nr + 2 * n_pairs :: 2] = pin_up
        self._slots[self.nr + 2 * n_pairs + 1 :: 2] = pin_up.conj()
        # per-member anchor bases of the free real poles and pairs (set by set_anchor)
        self._anchor_r: NDArray = np.zeros((0, n_real, n, r))
        self._anchor_p: NDArray = np.zeros((0, n_pairs, n, r), dtype=complex)
        self._batch: PatternBatch | None = None  # the evaluation of these anchors
        self._anchored = False

    # ------------------------------------------------------------------ layout
    def split(self, X: NDArray) -> tuple[NDArray, NDArray, NDArray, NDArray]:
        """``(coords (s, ncoord), lambda_real (s, nrf), sigma (s, npf), omega (s, npf))``: the
        poles' values (through the :class:`~optdesign.engines.region_map.PoleMap`)."""
        c, t, a, b = self._raw_split(X)
        return c, self.map.real(t)[0] if self.nrf else t, *(self.map.pair(a, b)[:2] if self.npf else (a, b))

    def _raw_split(self, X: NDArray) -> tuple[NDArray, NDArray, NDArray, NDArray]:
        """``(coords, real-pole variables, pair variables a, b)``: the columns of ``X``."""
        c = X[:, : self.ncoord]
        k = self.ncoord
        lr = X[:, k : k + self.nrf]
        k += self.nrf
        return c, lr, X[:, k : k + self.npf], X[:, k + self.npf :]

    def poles(self, x: NDArray) -> NDArray[np.complex128]:
        """All poles of ``x`` in row order (free reals, pinned reals, free pairs, pinned pairs)."""
        _, lr, sg, om = self.split(np.asarray(x, dtype=float)[None, :])
        return self.all_poles(lr, sg, om)[0]

    def pack(self, coords: NDArray, poles: NDArray) -> NDArray[np.float64]:
        """The variable vector of coordinates (layout of the fixed model at ``poles``) and poles."""
        P = np.asarray(poles, dtype=complex)
        lr = P[: self.nrf].real
        up = P[self.nr :: 2][: self.npf]
        return np.concatenate([coords, self.map.real_inverse(lr), *self.map.pair_inverse(up)])

    # ------------------------------------------------------------------ bases
    def _raw_bases(self, lam: NDArray) -> NDArray:
        """Orthonormal bases ``(..., n, r)`` of ``S(lambda)`` for a stack of poles (any shape ``(...,)``):
        the last ``r`` columns of the complete QR of ``(A - lambda I) Z``, conjugated (the first anchors)."""
        eng = self.engine
        n, r = eng.n, eng.rank
        lam = np.asarray(lam)
        Q = np.linalg.qr(eng.A @ eng.Z - lam[..., None, None] * eng.Z, mode="complete")[0]
        return Q[..., :, n - r :].conj()

    @property
    def pinned(self) -> NDArray[np.complex128]:
        """The pinned poles (conjugate-closed)."""
        return np.concatenate([self.pin_real + 0j, self.pin_up, self.pin_up.conj()])

    def set_anchor(self, X: NDArray, members: NDArray | None = None) -> None:
        """Anchor the bases of the free poles at the members of ``X`` (s, size): their current
        (aligned) bases, so that the coordinates keep their meaning; the raw bases the first time.
        ``members``: re-anchor only these members (indices into the anchors; ``X`` their rows)."""
        if members is not None:
            every = self.anchor_r, self.anchor_p
            self.anchor_r, self.anchor_p = (a[members] for a in every)
            try:
                self.set_anchor(X)
                for a, b in zip(every, (self.anchor_r, self.anchor_p), strict=True):
                    a[members] = b
            finally:
                self.anchor_r, self.anchor_p = every  # the setters drop the cached batch
            return
        if not self._anchored:
            _, lr, sg, om = self.split(X)
            self.anchor_r = self._raw_bases(lr).real if self.nrf else np.zeros((X.shape[0], 0, 1, 1))
            self.anchor_p = self._raw_bases(sg + 1j * om) if self.npf else np.zeros((X.shape[0], 0, 1, 1))
            self._anchored = True
            return
        m = self._members(X)
        if self.nrf:
            self.anchor_r = m["Br"][:, : self.nrf, :, : self.engine.rank].copy()
        if self.npf:
            self.anchor_p = m["Bp"][:, : self.npf, :, : self.engine.rank].copy()

    def _aligned(self, lam: NDArray, anchor: NDArray) -> tuple[NDArray, ...]:
        """The basis of ``S(lambda)`` closest to the anchor, ``N = P Na (Na^H P Na)^(-1/2)`` (``P`` the
        orthogonal projector onto ``S``: the polar factor of ``N_any^H Na`` applied to any orthonormal
        basis gives the same), from the thin QR ``(A - lambda I) Z = Q1 R1`` (``S`` in column form is
        the complement of ``conj(Q1)``).  Returns ``(N, overlap, Q1, R1, e, E)``: the overlap is the
        smallest singular value of ``N^H Na`` (``sqrt`` of the smallest eigenvalue of ``Na^H P Na``),
        and ``N^H Na = E diag(e) E^H`` (Hermitian: the alignment condition) for the pole derivative.
        """
        eng = self.engine
        M = eng.A @ eng.Z - lam[..., None, None] * eng.Z  # (..., n, n - r)
        Q1, R1 = np.linalg.qr(M)
        Qc = Q1.conj()
        X = anchor - Qc @ (np.swapaxes(Q1, -1, -2) @ anchor)  # P Na
        mu, E = np.linalg.eigh(np.swapaxes(X.conj(), -1, -2) @ X)
        e = np.sqrt(np.maximum(mu, 0.0))
        Eh = np.swapaxes(E.conj(), -1, -2)
        N = X @ (E / np.where(e > 0, e, np.inf)[..., None, :]) @ Eh
        return N, e[..., 0].min(axis=-1), Q1, R1, e, E

    def _members(self, X: NDArray) -> dict[str, NDArray]:
        """The aligned bases (``Br``, ``Bp``, padded to ``r``) and ``W`` of the members ``X`` at their
        anchors (the evaluation itself is :class:`~optdesign.engines.region_batch.PatternBatch`'s)."""
        s = X.shape[0]
        n, r, R = self.engine.n, self.engine.rank, self.r
        c, lr, sg, om = self.split(X)
        Br = np.zeros((s, self.nr, n, R))
        Bp = np.zeros((s, self.np, n, R), dtype=complex)
        if self.nrf:
            Br[:, : self.nrf, :, :r] = self._aligned(lr, self.anchor_r)[0]
        if self.npf:
            Bp[:, : self.npf, :, :r] = self._aligned(sg + 1j * om, self.anchor_p)[0]
        Br[:, self.nrf :] = self.Npr[None]
        Bp[:, self.npf :] = self.Npp[None]
        k2 = R * (self.nr + self.np)
        cr = c[:, : R * self.nr].reshape(s, self.nr, R)
        cp = (c[:, R * self.nr : k2] + 1j * c[:, k2:]).reshape(s, self.np, R)
        return {"Br": Br, "Bp": Bp, "W": _rows(Br, Bp, cr, cp, self.complex)}

    # ------------------------------------------------------------------ evaluation
    @property
    def anchor_r(self) -> NDArray:
        """Per-member anchor bases of the free real poles ``(s, nrf, n, r)``."""
        return self._anchor_r

    @anchor_r.setter
    def anchor_r(self, value: NDArray) -> None:
        self._anchor_r, self._batch = value, None

    @property
    def anchor_p(self) -> NDArray:
        """Per-member anchor bases of the free pairs' upper members ``(s, npf, n, r)``."""
        return self._anchor_p

    @anchor_p.setter
    def anchor_p(self, value: NDArray) -> None:
        self._anchor_p, self._batch = value, None

    def evaluate_batch(
        self, X: NDArray, objective: str, k: int | None, mu: float, members: NDArray | None = None
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Objective + barrier and the gradient for a stack ``X`` (s, size) of members (``members``:
        their indices in the anchors, default the first ``s``): the model's own
        :class:`~optdesign.engines.region_batch.PatternBatch` (kept until the anchors change)."""
        from .region_batch import PatternBatch  # it builds on this class

        if self._batch is None:
            count = self._anchor_r.shape[0] if self.nrf else self._anchor_p.shape[0]
            self._batch = PatternBatch([self], [count])
        rows = np.arange(X.shape[0]) if members is None else np.asarray(members)
        return self._batch.evaluate(X, rows, objective, k, mu)

    def _pole_derivative(self, N, Na, Q1, R1, e, E, Kj, c, directions) -> list[NDArray]:
        """``Re sum_k conj(K_jk) dw_jk`` per unit change of each pole along ``directions`` (1: the real
        part, 1j: the imaginary part), stacked over members and slots.

        The anchored basis ``N(lambda)`` (polar-aligned to ``Na``) moves by ``dN = T + N Omega``:
        the transport ``T = (M^+)^T Z^T N dlambda`` (``M = (A - lambda I) Z = Q1 R1``, the part
        normal to the subspace, basis-independent) and a rotation within the subspace fixed by the
        alignment condition ``N^H Na`` Hermitian: ``S Omega + Omega S = T^H Na - Na^H T``,
        ``S = N^H Na = E diag(e) E^H`` (a Lyapunov equation, solved in the eigenbasis of ``S``, which
        :meth:`_aligned` returns).
        """
        Y = self.engine.Z.T @ N  # Z^T N (broadcast over members and slots)
        T1 = Q1.conj() @ np.linalg.solve(np.swapaxes(R1, -1, -2), Y)  # (M^+)^T Z^T N
        Eh = np.swapaxes(E.conj(), -1, -2)
        # B(tau) = (tau T1)^H Na - Na^H (tau T1) = conj(tau) P - tau P^H with P = T1^H Na
        P = np.swapaxes(T1.conj(), -1, -2) @ Na
        Ph = np.swapaxes(P.conj(), -1, -2)
        B = np.stack([np.conj(tau) * P - tau * Ph for tau in directions])
        Om = E @ ((Eh @ B @ E) / (e[..., :, None] + e[..., None, :])) @ Eh
        z = np.einsum("smnr,smn->smr", N.conj(), Kj)  # N^H K_j^T
        v = np.einsum("smr,dsmr->dsm", z.conj(), (Om @ c[..., None])[..., 0])
        h = np.einsum("smn,smn->sm", Kj.conj(), (T1 @ c[..., None])[..., 0])  # linear in tau
        return [np.real(tau * h + v[i]) for i, tau in enumerate(directions)]

    def all_poles(self, lr: NDArray, sg: NDArray, om: NDArray) -> NDArray[np.complex128]:
        """Every pole of each member (s, n) in row order (free reals, pinned reals, free pairs, pinned
        pairs; a pair's upper member, then its conjugate) from the free poles' values ``lr`` (s, nrf)
        and ``sg + j om`` (s, npf)."""
        P = np.broadcast_to(self._slots, (lr.shape[0], self._slots.size)).copy()
        P[:, : self.nrf] = lr
        up = sg + 1j * om
        P[:, self.nr : self.nr + 2 * self.npf : 2] = up
        P[:, self.nr + 1 : self.nr + 2 * self.npf : 2] = up.conj()
        return P

    def fixed(self, x: NDArray, member: int = 0) -> tuple[FixedPoleModel, NDArray[np.float64]]:
        """The fixed-pole model at the poles of ``x`` (anchored as member ``member``) and ``x``'s
        coordinates in it (the left eigenvectors projected on its bases: exact, they lie in the
        subspaces)."""
        keep = self.anchor_r, self.anchor_p
        self.anchor_r, self.anchor_p = (a[member : member + 1] for a in keep)
        try:
            W = self._members(np.asarray(x, dtype=float)[None, :])["W"][0]
        finally:
            self.anchor_r, self.anchor_p = keep
        P = self.poles(x)
        # a pair near the real axis stays a pair
        model = FixedPoleModel(self.engine, P, tol=0.0, measure=self.measure)
        return model, model.coords_from_rows(_reorder(W, P, model.poles))

    def coords_of(self, fixed: FixedPoleModel, X: NDArray) -> NDArray[np.float64]:
        """The variable vectors (s, size), each anchored at its poles, of a fixed-pole model's
        coordinate vectors ``X`` (s, m)."""
        out, ar, ap = [], [], []
        for x in np.atleast_2d(X):
            out.append(self._coords_of(fixed, x))
            ar.append(self.anchor_r)
            ap.append(self.anchor_p)
        self.anchor_r, self.anchor_p = np.concatenate(ar), np.concatenate(ap)
        self._anchored = True
        return np.stack(out)

    def _coords_of(self, fixed: FixedPoleModel, x: NDArray) -> NDArray[np.float64]:
        target = _region_order(self, fixed.poles)
        Wr = _reorder(fixed.W(x), fixed.poles, target)
        self._anchored = False
        X = self.pack(np.zeros(self.ncoord), target)[None, :]
        self.set_anchor(X)
        r, R = self.engine.rank, self.r
        cr = np.zeros((self.nr, R))
        if self.nrf:
            cr[: self.nrf, :r] = np.einsum("jkr,jk->jr", self.anchor_r[0], Wr[: self.nrf].real)
        if self.nr > self.nrf:
            cr[self.nrf :] = np.einsum("jkr,jk->jr", self.Npr, Wr[self.nrf : self.nr].real)
        up = Wr[self.nr :: 2]
        cp = np.zeros((self.np, R), dtype=complex)
        if self.npf:
            cp[: self.npf, :r] = np.einsum("jkr,jk->jr", self.anchor_p[0].conj(), up[: self.npf])
        if self.np > self.npf:
            cp[self.npf :] = np.einsum("jkr,jk->jr", self.Npp.conj(), up[self.npf :])
        return self.pack(np.concatenate([cr.ravel(), cp.real.ravel(), cp.imag.ravel()]), target)


class QuadraticConstraints:
    """A region's smooth constraints as explicit quadratics ``g_k = a + b x + c y + d x^2 + e x y + f y^2``.

    The contract of :meth:`Region.constraints` is plain arithmetic of degree <= 2 (module
    docstring of :mod:`optdesign.model.regions`), so six values per constraint determine it: the
    coefficients are fitted once from a 3 x 3 stencil of width ``scale`` and checked at random
    points (values and exact gradients then cost a few vector operations instead of calling the
    region per evaluation -- measured: the barrier took 42 % of a region evaluation on COMPleib
    DIS2 before).

    Parameters
    ----------
    region : Region
    scale : float
        Length scale of the stencil (the region's inner radius).

    Raises
    ------
    ValidationError
        A constraint is not reproduced by its quadratic (a region breaking the contract).
    """

    def __init__(self, region: Region, scale: float) -> None:
        h = max(float(scale), STENCIL_MIN_SCALE)
        t = np.array([-h, 0.0, h])
        x, y = (a.ravel() for a in np.meshgrid(t, t))
        V = np.column_stack([np.ones_like(x), x, y, x * x, x * y, y * y])
        G = np.column_stack([np.asarray(v, dtype=float) * np.ones_like(x) for v in region.constraints(x, y)])
        self.coef = np.linalg.lstsq(V, G, rcond=None)[0]  # (6, k)
        rng = np.random.default_rng(0)
        xt, yt = rng.uniform(-10 * h, 10 * h, (2, 16))
        Gt = np.column_stack([np.asarray(v, dtype=float) * np.ones_like(xt)
                              for v in region.constraints(xt, yt)])
        Vt = np.column_stack([np.ones_like(xt), xt, yt, xt * xt, xt * yt, yt * yt])
        err = np.max(np.abs(Vt @ self.coef - Gt)) / max(1.0, float(np.max(np.abs(Gt))))
        if not err <= QUADRATIC_MISFIT_TOL:
            raise ValidationError(
                f"the constraints of {region!r} are not quadratic polynomials (relative misfit {err:.2e}): "
                "Region.constraints must be plain arithmetic of degree <= 2"
            )

    def values(self, x: NDArray, y: NDArray) -> tuple[NDArray, NDArray, NDArray]:
        """``(g, dg/dx, dg/dy)`` at points ``x + j y`` (any shape), each with a trailing axis of
        constraints."""
        a, b, c, d, e, f = self.coef
        X, Y = x[..., None], y[..., None]
        g = a + b * X + c * Y + d * X * X + e * X * Y + f * Y * Y
        return g, b + 2 * d * X + e * Y, c + e * X + 2 * f * Y


def _rows(Br: NDArray, Bp: NDArray, cr: NDArray, cp: NDArray, cplx: bool) -> NDArray:
    """Stacked ``W`` from per-member bases and coordinates (reals, then pairs ``w, conj w``)."""
    Wr = np.einsum("sjkr,sjr->sjk", Br, cr)
    if not cplx:
        return Wr
    s, nr = Wr.shape[:2]
    n = Wr.shape[2]
    Wp = np.einsum("sjkr,sjr->sjk", Bp, cp)
    W = np.empty((s, n, n), dtype=complex)
    W[:, :nr] = Wr
    W[:, nr::2] = Wp
    W[:, nr + 1 :: 2] = Wp.conj()
    return W


def _reorder(W: NDArray, poles_from: NDArray, poles_to: NDArray) -> NDArray:
    """Rows of ``W`` (for ``poles_from``) permuted to the order of ``poles_to`` (same multiset)."""
    from scipy.optimize import linear_sum_assignment

    cost = np.abs(np.asarray(poles_to)[:, None] - np.asarray(poles_from)[None, :])
    rows, cols = linear_sum_assignment(cost)
    out = np.empty_like(W)
    out[rows] = W[cols]
    return out


# --------------------------------------------------------------------------- the solver


def interior_of(region: Region) -> tuple[float, float]:
    """``(x0, rho)``: the region's deepest real point and its clearance (a disk of radius ``rho``
    around ``x0`` is inside)."""
    x0 = float(region.interior_point())
    return x0, max(-float(region.distance([x0])[0]), CLEARANCE_FLOOR)


def candidate_attains(eng: EigenstructureEngine, objective: str, cand: tuple | None, stop_at: float | None
                      ) -> bool:
    """A start's candidate ``(value, L, V, poles, stage)`` at or below ``stop_at``, the objective's
    lower bound to the caller's accuracy.  For eta the test is on its value recomputed from ``A - L
    C`` (its Schur form, :func:`~optdesign.analysis.metrics.eta`): the model's value subtracts two
    nearly equal numbers near a normal matrix (``||A - LC||_F^2 - sum |lambda|^2``), rounding that can
    put it below the bound."""
    if stop_at is None or cand is None or not cand[0] <= stop_at:
        return False
    return objective != "eta" or metrics.eta(eng.A - cand[1] @ eng.C) <= stop_at


def place_region(
    A: ArrayLike,
    C: ArrayLike,
    region: Region,
    *,
    objective: str = "kappa2",
    starts: Sequence[RegionStart] | None = None,
    n_samples: int = 2,
    seed: int = 0,
    deadline: Deadline | float | None = None,
    engine: EigenstructureEngine | None = None,
    measure: Measure = "right",
    stop_at: float | None = None,
) -> PlacementOutcome:
    """Observer gain minimizing kappa2 (or kappa_fro, eta) of ``A - L C`` with its poles free in ``region``.

    Parameters
    ----------
    A : (n, n) array_like
    C : (p, n) array_like
    region : Region
        Convex, symmetric about the real axis, nonempty interior; it must contain every
        unobservable mode of ``(C, A)``.
    objective : {"kappa2", "kappa_fro", "eta"}
        eta: its gap through a soft minimum whose order grows over the stages
        (:mod:`~optdesign.engines.region_eta`).
    starts : sequence of RegionStart, optional
        The caller's starts (e.g. scipy YT at the open-loop poles moved into the region, a Kalman
        gain).  Poles outside the region are moved inside (projection, then 5 % toward its
        interior point).
    n_samples : int, default 2
        Further starts at poles sampled in the region (``Region.sample_poles``; all real, then
        as many pairs as possible, alternately), with scipy YT there.
    seed : int, default 0
    deadline : Deadline or float, optional
        No new stage starts after it expires; the best verified-to-be-finite design so far is
        returned with status ``time_limit``.
    engine : EigenstructureEngine, optional
        Re-use an engine built for ``(A, C)`` (``A`` and ``C`` are then ignored).
    measure : {"right", "left"}, default "right"
        Which eigenvectors of ``A - L C`` kappa2 / kappa_fro measure (as
        :func:`~optdesign.engines.eigenstructure_fixed.place_fixed`): ``"left"`` is state feedback's
        ``cond(X)`` of the transposed loop ``A' - C' L'`` (controller mode); the outcome's ``V`` is then
        that ``X``.
    stop_at : float, optional
        The objective's lower bound with the caller's accuracy (kappa2: 1 to the accuracy of a
        computed kappa2; eta: 0 to that accuracy): a start whose candidate attains it before the
        free-pole stages is a global optimum -- the later starts are not prepared and no free-pole
        stage runs; a member that attains it after a BFGS round of the stages ends them (the others
        ``"pruned"``).  eta's test is on eta recomputed from the Schur form of the design
        (:func:`candidate_attains`).

    Returns
    -------
    PlacementOutcome
        The starts all run in lockstep (the warm ones first, in a batch of their own), one record
        per start that ran.  ``extra["region_margin"]`` is ``region.margin(poles)`` (``< 0``:
        strictly inside).

    Raises
    ------
    ValidationError
        ``region`` not a Region; objective not supported in region mode; no start at all; an
        unobservable mode outside the region.
    """
    t0 = time.process_time()
    if not isinstance(region, Region):
        raise ValidationError(f"region must be an optdesign.regions.Region; found {type(region).__name__}")
    if objective not in ("kappa2", "kappa_fro", "eta"):
        raise ValidationError(f"objective must be 'kappa2', 'kappa_fro' or 'eta'; found {objective!r}")
    if measure not in MEASURES:
        raise ValidationError(f"measure must be one of {MEASURES}; found {measure!r}")
    n_samples = as_int("n_samples", n_samples, 0)
    seed = as_int("seed", seed, 0)
    dl = Deadline.of(deadline)
    eng = engine if engine is not None else EigenstructureEngine(A, C)
    pinned = eng.unobservable_modes()
    if pinned.size:
        pinned = as_poles("unobservable modes", pinned)
        d = region.distance(pinned)
        if np.any(d > 0):
            raise ValidationError(
                f"the unobservable mode {pinned[int(np.argmax(d))]:.6g} of (C, A) is an eigenvalue of A - LC "
                f"for every L and lies outside the region (distance {float(np.max(d)):.3g})"
            )
    rng = np.random.default_rng(seed)
    all_starts = list(starts or [])
    nfree = eng.n - pinned.size
    for k in range(n_samples):
        frac = (1.0, 0.0, 0.5)[k % 3]
        P = np.concatenate([region.sample_poles(nfree, rng, real_fraction=frac), pinned])
        all_starts.append(RegionStart("region sample", as_poles("poles", P)))
    if not all_starts:
        raise ValidationError("place_region needs at least one start (starts or n_samples > 0)")
    cands: list[tuple[float, NDArray, NDArray, NDArray, str]] = []  # (value, L, V, poles, stage)
    records: list[StartRecord] = []
    # warm starts run only the last stages: a batch of their own
    order = sorted(range(len(all_starts)), key=lambda i: not all_starts[i].warm)
    warm = [all_starts[i] for i in order if all_starts[i].warm]
    cold = [all_starts[i] for i in order if not all_starts[i].warm]
    from .eigenstructure_region_lockstep import run_lockstep  # it builds on this module's model

    done = run_lockstep(eng, region, warm, pinned, objective, rng, dl, stop_at, measure) if warm else []
    if cold and not any(candidate_attains(eng, objective, b, stop_at) for _, b, _ in done):
        done += run_lockstep(eng, region, cold, pinned, objective, rng, dl, stop_at, measure)
    timed_out = dl.expired and len(done) < len(all_starts)
    for rec, best, to in done:
        timed_out |= to
        records.append(rec)
        if best is not None:
            cands.append(best)
    if not cands:
        nan = math.nan
        return PlacementOutcome(
            np.full((eng.n, eng.p), nan), np.full((eng.n, eng.n), nan + 0j), np.full(eng.n, nan + 0j),
            math.inf, math.inf, objective, math.inf, Status.TIME_LIMIT if timed_out else Status.NOT_FOUND,
            "no start gave a finite design inside the region", 0, 0, tuple(records),
            time=time.process_time() - t0,
        )
    val, L, V, P, stage = min(cands, key=lambda t: t[0])
    sv = np.linalg.svd(V, compute_uv=False)
    k2 = float(sv[0] / sv[-1])
    kf = float(np.linalg.norm(V) * np.linalg.norm(np.linalg.inv(V)))
    status = Status.TIME_LIMIT if timed_out else Status.OPTIMAL
    ib = min(range(len(records)), key=lambda i: records[i].objective_value)
    msg = (
        f"best of {len(records)} region starts (start {ib}, {records[ib].origin}, {stage}): "
        f"{objective} = {val:.6g}" + (" (time limit reached: best so far)" if timed_out else "")
    )
    return PlacementOutcome(
        L, V, P, k2, kf, objective, val, status, msg,
        sum(r.iterations for r in records), sum(r.evaluations for r in records), tuple(records),
        time=time.process_time() - t0, extra={"region_margin": float(region.margin(P))},
    )


def _region_order(model: RegionModel, poles: NDArray) -> NDArray[np.complex128]:
    """Poles in the region model's row order: free reals, pinned reals, free pairs, pinned pairs."""
    P = list(np.asarray(poles, dtype=complex))
    for mu in model.pinned:
        P.pop(int(np.argmin([abs(z - mu) for z in P])))
    fr = np.asarray(P, dtype=complex)
    re = np.sort(fr[fr.imag == 0].real)
    up = fr[fr.imag > 0]
    out = np.empty(model.engine.n, dtype=complex)
    allup = np.concatenate([up, model.pin_up])
    out[: model.nr] = np.concatenate([re, model.pin_real])
    out[model.nr :: 2] = allup
    out[model.nr + 1 :: 2] = allup.conj()
    return out
