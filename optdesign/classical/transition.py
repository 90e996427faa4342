r"""The exact propagator of the Riccati differential equation: Lainiotis' partitioned form of
the Hamiltonian transition matrix, built by doubling and restarted at every output time (the
``"transition"`` method of :func:`optdesign.riccati_de`), and Davison-Maki restarts as an
independent cross-check.

The filter Riccati DE ``P' = A P + P A' + W - P S P`` (``S = C' R^-1 C``) is the image of the
linear Hamiltonian system ``[U; V]' = M [U; V]``, ``M = [[-A', S], [W, A]]``, ``P = V U^-1``
(:func:`optdesign.classical.bpf.filter_hamiltonian`).

Exact propagation
-----------------
``V U^-1`` with one matrix exponential over ``[0, t]`` fails as t grows: ``e^{Mt}`` has entries
``~e^{Re(lambda) t}``, so U and V overflow (the paper's example: from t ~ 1350) and, on unstable
or multi-scale plants well before that, the transient drowns in rounding error (CAREX 1.2 in
filter form: error above 1e-8 from t ~ 20; the stiff CAREX 1.6: from t ~ 0.03).  The
Davison-Maki remedy restarts ``[U; V] = [I; P]`` after every short step.  Here the exact step map

.. math::

    P \mapsto (E_{21} + E_{22} P)(E_{11} + E_{12} P)^{-1},\qquad E = e^{M\delta},

is written in Lainiotis' partitioned form (using the symplectic identity
``E22 - E21 E11^-1 E12 = E11^-T``)

.. math::

    P \mapsto P_n + \Phi\, P (I + O P)^{-1} \Phi', \qquad
    P_n = E_{21}E_{11}^{-1},\ O = E_{11}^{-1}E_{12},\ \Phi = E_{11}^{-T},

where ``P_n >= 0`` is the solution from ``P = 0``, ``O >= 0`` an observability Gramian and
``Phi`` the transition matrix of the time-varying filter.  Every term is symmetric positive
semidefinite in exact arithmetic; ``(I + P O)^-1 P Phi'`` is one LU solve with a matrix whose
eigenvalues are >= 1 (:func:`apply_map`: 8.7 n^3 flops, against 6.7 n^3 for the Moebius form,
which loses ``log10 cond(E11)`` digits on long or fast intervals; for ``n >= CHOLESKY_MIN_N``
the same step through Cholesky factors of P and of ``I + U' O U``, 5.7 n^3 flops), the result is
symmetrized, and its PSD-ness to rounding is certified on the whole trajectory by the caller
(:func:`optdesign.riccati_de`: a Cholesky factor of every ``P_k`` plus a rounding-level shift).
Maps over adjacent intervals compose in closed form (:func:`compose_maps`), so
the map over an output interval ``Delta`` is built from a short step ``delta = Delta / 2^s``
(``||M delta||_1 <= 1/2``: E is well conditioned) by ``s`` doublings -- the doubling algorithm of
Lainiotis and of Anderson & Moore -- and then applied once per output interval (a restart).
Short intervals (``||M Delta||_1 <= DIRECT_MAX_NORM``) first try the map from one exponential of
the whole interval, kept only where its measured loss ``||E|| ||E11^-1||`` (LAPACK ``gecon``) is
at most ``DIRECT_MAX_LOSS`` (:func:`riccati_map`): at n = 10 this replaces an exponential and 3..5
doublings (0.25 ms) by one exponential (0.08 ms), with the same error.
Before all this the equation is rescaled exactly (powers of 2, :func:`hamiltonian_scaling`), as
badly scaled plants otherwise lose digits in every exponential (CAREX 1.6: 1e-9 -> 1e-14).
Cost: one ``2n x 2n`` exponential and ``s ~ log2(||M|| Delta)`` doublings per distinct interval
length, then ``O(n^3)`` per output time, independent of the horizon and of the stiffness.
Measured on every CAREX plant in filter form that is a valid plant (unstable and stiff ones
included; 0..10 s, P0 = 0; ``rho(M) t <= 2e4``): the difference from Davison-Maki restarts is
2e-16..1e-12, except the ill-conditioned 2.2: 9e-8 (where Davison-Maki and a tight ODE solve
differ by 2e-8 from each other, and this method's error estimate says 9e-8); the paper's example
stays exact on [0, 1000].

Limit: doubling composes maps whose filter transition ``Phi`` may grow transiently (an unstable
plant with very weak measurements, e.g. CAREX 2.6 with eigenvalues 1e6..3e6).  The doubling stops
while ``||Phi||_1 <= growth_limit`` and the rest of the interval is covered by restarts with the
largest safe map; if that needs more than ``max_substeps`` restarts, :class:`RiccatiError` says so.

References
----------
Kenney, C. S. & Leipnik, R. B., "Numerical integration of the differential matrix Riccati
equation", IEEE TAC 30 (1985) 962-970 (seed 004 ref [3]; Davison-Maki with restarts).
Lainiotis, D. G., "Partitioned Riccati solutions and integration-free doubling algorithms",
IEEE TAC 21 (1976) 677-689.
Anderson, B. D. O. & Moore, J. B., *Optimal Filtering*, Prentice-Hall 1979 (doubling algorithm).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg
from numpy.typing import ArrayLike, NDArray
from scipy.linalg.blas import dsyrk as _syrk
from scipy.linalg.blas import dtrmm as _trmm
from scipy.linalg.blas import dtrsm as _trsm
from scipy.linalg.lapack import dgebal as _gebal
from scipy.linalg.lapack import dgecon as _gecon
from scipy.linalg.lapack import dgesv as _gesv
from scipy.linalg.lapack import dgetrf as _getrf
from scipy.linalg.lapack import dgetrs as _getrs
from scipy.linalg.lapack import dpotrf as _potrf

from .._deadline import Deadline
from .._validate import as_bool, as_positive_float, as_square, check_symmetric
from ..analysis.linalg import sym
from ..errors import DimensionError, RiccatiError, ValidationError

__all__ = [
    "CHOLESKY_MIN_N",
    "DIRECT_MAX_NORM",
    "DIRECT_MAX_LOSS",
    "RiccatiMap",
    "as_hamiltonian",
    "hamiltonian_scaling",
    "riccati_map",
    "compose_maps",
    "apply_map",
    "riccati_flow",
    "davison_maki",
]


def as_hamiltonian(M: ArrayLike) -> tuple[NDArray[np.float64], int]:
    """``M`` as a finite ``2n x 2n`` float matrix, and n.

    Raises
    ------
    DimensionError, NotFiniteError
        M not a finite square matrix of even order (the message names M).
    """
    M = as_square("M", M)
    if M.shape[0] % 2:
        raise DimensionError(f"M must be a 2n x 2n Hamiltonian matrix; found shape {M.shape}")
    return M, M.shape[0] // 2


def _as_initial(P0: ArrayLike, n: int) -> NDArray[np.float64]:
    return check_symmetric("P0", as_square("P0", P0, n))


def _norm1(X: NDArray) -> float:
    """``||X||_1`` (largest column sum; NaN or inf when X is not finite), without ``numpy.linalg.norm``'s
    argument handling."""
    return float(np.abs(X).sum(axis=0).max())


@dataclass(frozen=True, eq=False)
class RiccatiMap:
    r"""The exact Riccati flow over one interval, ``P -> Pn + Phi P (I + O P)^-1 Phi'``.

    Attributes
    ----------
    Pn : (n, n) ndarray
        The solution at the end of the interval started from ``P = 0`` (PSD).
    Phi : (n, n) ndarray
        Transition matrix of the filter ``A - Pn(t) S`` over the interval (``E11^-T``).
    O : (n, n) ndarray
        ``E11^-1 E12`` (PSD): an observability Gramian of the filter.
    dt : float
        Interval length.
    doublings : int
        Doublings used to build the map from the base step.
    substeps : int
        Applications (restarts) of the doubled map needed to cover ``dt`` (1 unless the growth
        guard stopped the doubling).
    direct : bool
        Built from the whole interval's exponential (:func:`riccati_map`), not by doubling.
    """

    Pn: NDArray[np.float64]
    Phi: NDArray[np.float64]
    O: NDArray[np.float64]  # noqa: E741
    dt: float
    doublings: int = 0
    substeps: int = 1
    direct: bool = False


def hamiltonian_scaling(M: ArrayLike) -> tuple[NDArray[np.float64], float]:
    r"""Exact (powers of 2) rescaling of the Riccati DE that balances its Hamiltonian.

    The substitution ``P = rho T Pt T`` with ``T = diag(d)`` maps the blocks of
    ``M = [[-A', S], [W, A]]`` to ``At = T^-1 A T``, ``St = rho T S T``, ``Wt = T^-1 W T^-1 / rho``
    -- a symplectic similarity plus a scalar that equilibrates ``||St||`` and ``||Wt||`` -- and
    leaves the equation's form unchanged.  ``d`` balances ``|M|`` (zero diagonal) under the
    constraint ``diag(T, T^-1)``, as scipy's Riccati solvers do (Benner 2001).  Badly scaled
    plants (CAREX 1.6: ``||M||_1 = 2.8e6`` but spectral radius 577) otherwise lose accuracy in
    every ``2n x 2n`` exponential.

    Parameters
    ----------
    M : (2n, 2n) array_like

    Returns
    -------
    d : (n,) ndarray
        State scaling (powers of 2).
    rho : float
        Covariance scaling (a power of 2).
    """
    M, n = as_hamiltonian(M)
    return _balancing(M, n)


def _balancing(M: NDArray, n: int) -> tuple[NDArray[np.float64], float]:
    """:func:`hamiltonian_scaling` of a validated M (LAPACK ``gebal`` called directly: scipy's
    ``matrix_balance`` adds 20 us of argument checks at n = 10)."""
    Ab = np.abs(M)
    np.fill_diagonal(Ab, 0.0)
    if not np.any(Ab):
        return np.ones(n), 1.0
    *_, sca, info = _gebal(Ab, scale=1, permute=0)
    if info != 0:  # pragma: no cover - gebal fails only on bad arguments
        raise RiccatiError(f"hamiltonian_scaling: LAPACK gebal info = {info}")
    lsca = np.log2(sca)
    d = 2.0 ** np.round((lsca[n:] - lsca[:n]) / 2)
    S = M[:n, n:] * d[:, None] * d[None, :]
    W = M[n:, :n] / d[:, None] / d[None, :]
    ns, nw = float(np.linalg.norm(S)), float(np.linalg.norm(W))
    rho = 1.0 if ns == 0.0 or nw == 0.0 else float(2.0 ** np.round(0.5 * np.log2(nw / ns)))
    return d, rho


def _scaled(M: NDArray, n: int, d: NDArray, rho: float) -> NDArray:
    """The Hamiltonian of the rescaled equation (:func:`hamiltonian_scaling`): exact, d and rho are
    powers of 2."""
    dd = d[:, None] * d[None, :]
    out = np.empty_like(M)
    np.multiply(M[n:, n:], d[None, :] / d[:, None], out=out[n:, n:])       # T^-1 A T
    out[:n, :n] = -out[n:, n:].T
    np.multiply(M[:n, n:], dd * rho, out=out[:n, n:])
    np.divide(M[n:, :n], dd * rho, out=out[n:, :n])
    return out


def _base_map(M: NDArray, n: int, delta: float) -> RiccatiMap:
    E = scipy.linalg.expm(M * delta)
    E11, E12, E21 = E[:n, :n], E[:n, n:], E[n:, :n]
    _, _, X, info = _gesv(E11, np.hstack([E12, np.eye(n)]))     # E11^-1 [E12, I]: one LU
    if info != 0:  # pragma: no cover - E11 ~ I by the step bound
        raise RiccatiError(f"riccati_map: base step singular: E11 (LAPACK gesv info = {info})")
    return _partitioned(E21, X, n, delta)


def _partitioned(E21: NDArray, X: NDArray, n: int, dt: float) -> RiccatiMap:
    """Lainiotis' blocks from ``X = E11^-1 [E12, I]``: ``O = E11^-1 E12``, ``Pn = E21 E11^-1``,
    ``Phi = E11^-T``."""
    O = sym(X[:, :n])  # noqa: E741
    Pn = sym(E21 @ X[:, n:])
    return RiccatiMap(Pn=Pn, Phi=np.ascontiguousarray(X[:, n:].T), O=O, dt=dt)


#: largest ``||M dt||_1`` for which :func:`riccati_map` tries the whole interval's exponential
#: (one ``expm``) before doubling: a refused attempt costs one exponential more than the doubling,
#: and the loss grows with ``||M dt||_1`` (measured on the benchmark's random plants, n = 10..100,
#: balanced: loss 9 at ``||M dt||_1 = 3.8``, 60..94 at 11..14, 2.5e3 at 39, 1.5e4 at 48, 1.9e8 at 129).
DIRECT_MAX_NORM = 16.0

#: largest measured loss ``||E||_1 ||E11^-1||_1`` (``||E11^-1||_1`` from LAPACK ``gecon`` on the LU
#: of E11) accepted for the direct map: its blocks then carry relative rounding errors of at most
#: about ``DIRECT_MAX_LOSS * eps = 2e-13`` (first-order perturbation of ``E21 E11^-1``,
#: ``E11^-1 E12`` and ``E11^-T`` by an exponential accurate to ``eps ||E||``).  Measured (100 steps,
#: against a doubling from a 64x shorter base step): up to loss 1.7e4 the direct trajectory and the
#: doubled one have the same error (1e-13..5e-12); at loss 1.9e8 the direct one has 6e-10 (doubling
#: 2e-12), at 1.3e10 2.5e-8.
DIRECT_MAX_LOSS = 1e3


def _direct_map(M: NDArray, n: int, dt: float, max_loss: float) -> RiccatiMap | None:
    r"""The map over ``dt`` from one exponential ``E = e^{M dt}``, or None where the measured loss
    ``||E||_1 ||E11^-1||_1`` exceeds ``max_loss`` (or E is not finite, or E11 is singular)."""
    E = scipy.linalg.expm(M * dt)
    if not np.isfinite(E.sum()):
        return None
    E11 = E[:n, :n]
    a_norm = _norm1(E11)
    lu, piv, info = _getrf(E11)
    if info != 0:
        return None
    rcond, info = _gecon(lu, a_norm, norm="1")
    e_norm = _norm1(E)
    if info != 0 or not rcond > 0 or e_norm / (rcond * a_norm) > max_loss:
        return None
    X, info = _getrs(lu, piv, np.hstack([E[:n, n:], np.eye(n)]))   # E11^-1 [E12, I]
    if info != 0:  # pragma: no cover - getrs fails only on bad arguments
        return None
    return _partitioned(E[n:, :n], X, n, dt)


def compose_maps(first: RiccatiMap, second: RiccatiMap) -> RiccatiMap:
    r"""The map over two adjacent intervals: ``second o first``.

    With ``G = I + Pn1 O2`` (eigenvalues >= 1: a product of PSD matrices plus I) and
    ``Z = G^-1 Phi1``, by the push-through identities ``Pn1 (I + O2 Pn1)^-1 = G^-1 Pn1`` and
    ``O2 (I + Pn1 O2)^-1 Phi1 = O2 Z``::

        Pn  = Pn2 + Phi2 G^-1 Pn1 Phi2'
        Phi = Phi2 Z
        O   = O1 + Phi1' O2 Z

    -- one LU factorization of G and ``16.7 n^3`` flops.  The sandwiched products are symmetric
    PSD in exact arithmetic; Pn and O are symmetrized, and the PSD-ness of the trajectory is
    checked by the caller (:func:`optdesign.riccati_de`).

    Parameters
    ----------
    first, second : RiccatiMap

    Returns
    -------
    RiccatiMap
        ``dt`` is the sum; ``doublings`` the larger count plus one.
    """
    n = first.Pn.shape[0]
    G = first.Pn @ second.O
    G.reshape(-1)[::n + 1] += 1.0
    _, _, XZ, info = _gesv(G, np.hstack([first.Pn, first.Phi]))   # G^-1 [Pn1, Phi1]
    if info != 0:
        raise RiccatiError(f"compose_maps: I + Pn1 O2 is singular (LAPACK gesv info = {info}): Pn1 or "
                           "O2 is not PSD, or the maps overflowed")
    Z = XZ[:, n:]
    Pn = sym(second.Pn + second.Phi @ sym(XZ[:, :n]) @ second.Phi.T)
    Phi = second.Phi @ Z
    O = sym(first.O + first.Phi.T @ (second.O @ Z))  # noqa: E741
    return RiccatiMap(Pn=Pn, Phi=Phi, O=O, dt=first.dt + second.dt,
                      doublings=max(first.doublings, second.doublings) + 1)


def apply_map(rmap: RiccatiMap, P: ArrayLike) -> NDArray[np.float64]:
    r"""``Pn + Phi (I + P O)^-1 P Phi'`` applied ``rmap.substeps`` times (symmetric result).

    One product ``P [O, Phi']``, one LU solve with ``I + P O`` (eigenvalues >= 1: P and O are
    PSD) and one product with ``Phi`` per application: ``8.7 n^3`` flops, against ``6.7 n^3``
    for the Moebius form ``(E21 + E22 P)(E11 + E12 P)^-1`` of the same step -- which, unlike
    this form, loses ``log10 cond(E11)`` digits on long or fast intervals.  From
    ``n = CHOLESKY_MIN_N`` the same step in Cholesky form, ``Pn + W W'`` with ``W = Phi U K^-T``,
    ``P = U U'``, ``I + U' O U = K K'``: ``5.7 n^3`` flops, fewer than the Moebius form (the LU form
    where P has no Cholesky factor, e.g. P = 0).

    Parameters
    ----------
    rmap : RiccatiMap
    P : (n, n) array_like
        Symmetric PSD.

    Returns
    -------
    (n, n) ndarray

    Raises
    ------
    RiccatiError
        ``I + P O`` exactly singular (P or O not PSD, or overflow; a nearly singular one, from a
        P that is not PSD, shows in the verification of the trajectory).
    """
    P = np.asarray(P, dtype=float)
    return _Applier(rmap)(sym(P))


#: smallest n for the Cholesky form of a step (:func:`apply_map`); below it the LU form is faster
#: (fewer calls).  Measured per step, single-threaded OpenBLAS: n = 10 12.6 vs 9.2 us (LU), n = 40
#: 59 vs 67, n = 64 124 vs 172, n = 100 275 vs 450, n = 150 936 vs 1542.
CHOLESKY_MIN_N = 32


class _Applier:
    r""":func:`apply_map` with the map's constant blocks and the work buffers prepared once (one per
    output interval); each application is written into ``out``.

    LU form (:meth:`_lu_step`, 8.7 n^3 flops): one product ``[O; Phi] P`` (whose transpose, for a
    symmetric P, is ``[P O, P Phi']`` in Fortran order: LAPACK takes both blocks without a copy),
    the identity added through a strided view of the diagonal, one ``gesv`` and one product
    ``(Phi / 2) Y`` whose sum with its transpose is the symmetrized ``Phi Y`` (halving is exact).

    Cholesky form (:meth:`_cholesky_step`, 5.7 n^3 flops, for ``n >= CHOLESKY_MIN_N``): with
    ``P = U U'`` (U lower), ``(I + P O)^-1 P = U (I + U' O U)^-1 U'``; with ``I + U' O U = K K'``
    (eigenvalues >= 1: well conditioned) the step is ``Pn + W W'``, ``W = Phi U K^-T`` -- two
    Cholesky factorizations, three triangular products or solves and one ``syrk``, every term PSD.
    Where P has no Cholesky factor (``P0 = 0``, or P singular to rounding) the LU form is used.
    """

    __slots__ = ("rmap", "n", "left", "half_phi", "B", "T", "diag", "work", "chol", "lu_once", "fO",
                 "fPhi", "fP", "fZ", "fV", "fS")

    def __init__(self, rmap: RiccatiMap) -> None:
        n = rmap.Pn.shape[0]
        self.rmap, self.n = rmap, n
        self.left = np.vstack([rmap.O, rmap.Phi])                 # (2n, n), C order
        self.half_phi = 0.5 * rmap.Phi
        self.B = np.empty((2 * n, n))
        self.T = np.empty((n, n))
        self.diag = self.B.reshape(-1)[:n * n:n + 1]             # diagonal of B[:n] = (P O)'
        self.work = np.empty((2, n, n)) if rmap.substeps > 1 else None
        self.chol = n >= CHOLESKY_MIN_N
        self.lu_once = rmap.substeps == 1 and not self.chol
        if self.chol:
            self.fO, self.fPhi = np.asfortranarray(rmap.O), np.asfortranarray(rmap.Phi)
            self.fP, self.fZ, self.fV = (np.empty((n, n), order="F") for _ in range(3))
            self.fS = np.zeros((n, n), order="F")                # syrk writes its lower triangle only

    def __call__(self, P: NDArray, out: NDArray | None = None) -> NDArray:
        """One map application per substep; ``P`` exactly symmetric (it is never written to)."""
        out = np.empty_like(self.T) if out is None else out
        if self.lu_once:                                          # the common case: no loop
            self._lu_step(P, out)
            return out
        sub = self.rmap.substeps
        for k in range(sub):
            dest = out if k == sub - 1 else self.work[k % 2]     # type: ignore[index]
            if not (self.chol and self._cholesky_step(P, dest)):
                self._lu_step(P, dest)
            P = dest
        return out

    def _lu_step(self, P: NDArray, out: NDArray) -> None:
        n, B = self.n, self.B
        np.matmul(self.left, P, out=B)                            # [O P; Phi P] = [P O, P Phi']'
        self.diag += 1.0
        Bt = B.T
        _, _, Y, info = _gesv(Bt[:, :n], Bt[:, n:], overwrite_a=1, overwrite_b=1)
        if info != 0:                                             # (I + P O)^-1 P Phi' in Y
            raise RiccatiError(f"apply_map: I + P O is singular (LAPACK gesv info = {info}): P or O "
                               "is not PSD, or the map overflowed")
        np.matmul(self.half_phi, Y, out=self.T)
        np.add(self.T, self.T.T, out=out)                         # exactly symmetric
        out += self.rmap.Pn

    def _cholesky_step(self, P: NDArray, out: NDArray) -> bool:
        """The Cholesky form into ``out``; False (nothing written) where a factorization fails."""
        n = self.n
        self.fP[...] = P
        U, info = _potrf(self.fP, lower=1, clean=0, overwrite_a=1)
        if info != 0:
            return False
        self.fZ[...] = self.fO
        Z = _trmm(1.0, U, self.fZ, side=1, lower=1, overwrite_b=1)                # O U
        G = _trmm(1.0, U, Z, side=0, lower=1, trans_a=1, overwrite_b=1)           # U' O U
        G.reshape(-1, order="F")[::n + 1] += 1.0
        K, info = _potrf(G, lower=1, clean=0, overwrite_a=1)
        if info != 0:                               # pragma: no cover - eigenvalues >= 1 but O rounding
            return False
        self.fV[...] = self.fPhi
        V = _trmm(1.0, U, self.fV, side=1, lower=1, overwrite_b=1)                # Phi U
        W = _trsm(1.0, K, V, side=1, lower=1, trans_a=1, overwrite_b=1)           # Phi U K^-T
        S = _syrk(1.0, W, beta=0.0, c=self.fS, lower=1, overwrite_c=1)           # lower of W W'
        np.add(S, S.T, out=out)                                   # exactly symmetric; diagonal 2x
        out.reshape(-1)[::n + 1] *= 0.5
        out += self.rmap.Pn
        return True


def riccati_map(M: ArrayLike, dt: float, *, max_norm: float = 0.5, growth_limit: float = 1e8,
                max_substeps: int = 100_000, direct: bool = True) -> RiccatiMap:
    r"""The exact flow of the Riccati DE over an interval ``dt`` (module notes: base step by one
    matrix exponential with ``||M delta||_1 <= max_norm``, then doubling).

    Short intervals (``max_norm < ||M dt||_1 <= DIRECT_MAX_NORM``, with ``direct``) first try the
    whole interval's exponential ``E = e^{M dt}``: its map ``Pn = E21 E11^-1``, ``O = E11^-1 E12``,
    ``Phi = E11^-T`` loses about ``log10(||E|| ||E11^-1||)`` digits, so it is used only where that
    loss, measured (``gecon`` on the LU of E11), is at most ``DIRECT_MAX_LOSS`` and ``||Phi||_1 <=
    growth_limit``; else the doubling.

    Parameters
    ----------
    M : (2n, 2n) array_like
        Hamiltonian (:func:`filter_hamiltonian`).
    dt : float
        Interval length (> 0).
    max_norm : float
        Bound on ``||M delta||_1`` of the base step.
    growth_limit : float
        Doubling stops when ``||Phi||_1`` would exceed this; the rest of the interval is then
        covered by ``substeps`` restarts.
    max_substeps : int
        Largest number of restarts accepted.
    direct : bool
        Try the whole interval's exponential first (above); False: always the doubling (an
        independent recomputation, e.g. for an error estimate).

    Returns
    -------
    RiccatiMap
        ``doublings = 0`` and ``direct = True`` where the direct map was used.

    Raises
    ------
    ValidationError
        dt or max_norm not a number > 0, direct not a bool.
    RiccatiError
        The growth guard would need more than ``max_substeps`` restarts, or the base-step
        ``E11`` is singular.
    """
    M, n = as_hamiltonian(M)
    dt = as_positive_float("dt", dt)
    max_norm = as_positive_float("max_norm", max_norm)
    direct = as_bool("direct", direct)
    return _riccati_map(M, n, _norm1(M), dt, max_norm, growth_limit,
                        max_substeps, direct)


def _riccati_map(M: NDArray, n: int, m_norm: float, dt: float, max_norm: float, growth_limit: float,
                 max_substeps: int, direct: bool) -> RiccatiMap:
    """:func:`riccati_map` of validated arguments, ``m_norm = ||M||_1``."""
    nrm = m_norm * dt
    s = max(0, int(np.ceil(np.log2(nrm / max_norm)))) if nrm > max_norm else 0
    if s and direct and nrm <= DIRECT_MAX_NORM:
        one = _direct_map(M, n, dt, DIRECT_MAX_LOSS)
        if one is not None and _norm1(one.Phi) <= growth_limit:
            return RiccatiMap(Pn=one.Pn, Phi=one.Phi, O=one.O, dt=dt, direct=True)
    rmap = _base_map(M, n, dt / 2.0**s)
    done = 0
    while done < s:
        cand = compose_maps(rmap, rmap)
        # ||Phi||_1 is nan/inf if Phi is not finite; a sum is not finite if an entry is not
        phi_norm = _norm1(cand.Phi)
        if not (phi_norm <= growth_limit and np.isfinite(cand.Pn.sum() + cand.O.sum())):
            break
        rmap, done = cand, done + 1
    sub = 2 ** (s - done)
    if sub > max_substeps:
        raise RiccatiError(
            f"riccati_map: the filter's transition matrix grows beyond {growth_limit:.0e} within one "
            f"output interval of {dt:.3g} (a stiff, badly scaled or strongly unstable plant): covering "
            f"it needs {sub} restarts > max_substeps = {max_substeps}; use shorter output intervals "
            f"or method='ode'")
    return RiccatiMap(Pn=rmap.Pn, Phi=rmap.Phi, O=rmap.O, dt=dt, doublings=done, substeps=sub)


def riccati_flow(M: ArrayLike, P0: ArrayLike, times: ArrayLike, *, max_norm: float = 0.5,
                 growth_limit: float = 1e8, max_substeps: int = 100_000, balance: bool = True,
                 direct: bool = True,
                 deadline: Deadline | float | None = None) -> tuple[NDArray[np.float64], dict]:
    r"""Exact solution of the Riccati DE at ``times`` by restarted exact step maps.

    For each output interval the map of :func:`riccati_map` (cached by interval length) is
    applied to the previous P.

    Parameters
    ----------
    M : (2n, 2n) array_like
        Hamiltonian (:func:`filter_hamiltonian`).
    P0 : (n, n) array_like
        Symmetric PSD initial value at t = 0.
    times : (k,) array_like
        Non-decreasing times >= 0.
    max_norm, growth_limit, direct
        See :func:`riccati_map`.
    max_substeps : int
        Largest total number of extra restarts the growth guard may add over all intervals.
    balance : bool
        Rescale the equation first (:func:`hamiltonian_scaling`; exact, powers of 2), when that
        reduces ``||M||_1`` (the doublings needed and the digits each exponential loses).
    deadline : Deadline or float, optional
        Time budget (seconds or a shared :class:`~optdesign._deadline.Deadline`): once it has
        expired no new output interval is started, and P is returned at the times reached.

    Returns
    -------
    P : (j, n, n) ndarray
        P at ``times[:j]``; ``j = len(times)`` unless the deadline stopped the propagation.
    info : dict
        ``maps`` (distinct intervals), ``direct`` (of them, built from one exponential),
        ``doublings`` (max), ``substeps`` (total restarts), ``completed`` (j).

    Raises
    ------
    ValidationError
        times negative or decreasing, max_norm not a number > 0, direct not a bool.
    RiccatiError
        The growth guard needs more than ``max_substeps`` extra restarts.
    """
    M, n = as_hamiltonian(M)
    P = _as_initial(P0, n)
    times = np.atleast_1d(np.asarray(times, dtype=float))
    if times.size and (times[0] < 0 or np.any(np.diff(times) < 0)):
        raise ValidationError("times must be non-negative and non-decreasing")
    scale = float(times[-1]) if times.size and times[-1] > 0 else 1.0
    direct = as_bool("direct", direct)
    max_norm = as_positive_float("max_norm", max_norm)
    m_norm = _norm1(M)
    d, rho = _balancing(M, n) if balance else (np.ones(n), 1.0)
    rescaled = bool(rho != 1.0 or np.any(d != 1.0))
    Ms = _scaled(M, n, d, rho) if rescaled else M
    ms_norm = _norm1(Ms)
    if rescaled and ms_norm < m_norm:                   # balanced: fewer doublings, fewer lost digits
        M, P, m_norm = Ms, P / d[:, None] / d[None, :] / rho, ms_norm
    else:
        rescaled = False
    out = np.empty((times.size, n, n))
    dts = np.diff(np.r_[0.0, times])
    live = dts > 1e-14 * scale
    keys = np.zeros(times.size, dtype=np.int64)
    keys[live] = np.round(dts[live] / scale * 2.0**40).astype(np.int64)
    uniq, which = np.unique(keys, return_inverse=True)
    uses = np.bincount(which[live], minlength=uniq.size)        # live intervals per length
    clock = Deadline.of(deadline)
    steps: list[_Applier | None] = [None] * uniq.size
    info = {"maps": 0, "direct": 0, "doublings": 0, "substeps": 0, "completed": 0}
    extra = substeps = 0
    done, limited = times.size, clock.limited
    for j, (alive, w) in enumerate(zip(live.tolist(), which.tolist(), strict=True)):
        if not alive:
            out[j] = P
            continue
        if limited and clock.expired:                           # one clock read per step, if limited
            done = j
            break
        step = steps[w]
        if step is None:
            rmap = _riccati_map(M, n, m_norm, float(dts[j]), max_norm, growth_limit, max_substeps, direct)
            step = steps[w] = _Applier(rmap)
            info["maps"] += 1
            info["direct"] += int(rmap.direct)
            info["doublings"] = max(info["doublings"], rmap.doublings)
            extra += (rmap.substeps - 1) * int(uses[w])
            if extra > max_substeps:
                raise RiccatiError(
                    f"riccati_flow: the filter's transition matrix grows beyond {growth_limit:.0e} "
                    f"within an output interval of {float(dts[j]):.3g} (a stiff, badly scaled or "
                    f"strongly unstable plant): covering the horizon needs {extra} extra restarts > "
                    f"max_substeps = {max_substeps}; use shorter output intervals or a shorter "
                    f"horizon, or method='ode'")
        P = step(P, out[j])
        substeps += step.rmap.substeps
    info["substeps"], info["completed"] = substeps, done
    out = out[:done]
    if rescaled:
        out *= rho * d[:, None] * d[None, :]
    return out, info


def davison_maki(M: ArrayLike, P0: ArrayLike, times: ArrayLike, *,
                 max_step: float = 1.0) -> NDArray[np.float64]:
    r"""Davison-Maki with restarts (Kenney & Leipnik 1985): ``[U; V] = e^{M delta} [I; P]``,
    ``P = V U^-1``, restarted every step ``delta`` with ``rho(M) delta <= max_step``.

    A plain, independent cross-check of :func:`riccati_flow` (cost grows with
    ``rho(M) t_final``: not for stiff problems over long horizons).

    Parameters
    ----------
    M : (2n, 2n) array_like
    P0 : (n, n) array_like
    times : (k,) array_like
        Non-decreasing times >= 0.
    max_step : float
        Bound on ``rho(M) delta``.

    Returns
    -------
    (k, n, n) ndarray

    Raises
    ------
    ValidationError
        times negative or decreasing; more than 10^7 steps needed.
    """
    M, n = as_hamiltonian(M)
    P = _as_initial(P0, n)
    times = np.atleast_1d(np.asarray(times, dtype=float))
    if times.size and (times[0] < 0 or np.any(np.diff(times) < 0)):
        raise ValidationError("times must be non-negative and non-decreasing")
    rho = float(np.max(np.abs(np.linalg.eigvals(M))))
    total = rho * (float(times[-1]) if times.size else 0.0) / max_step
    if total > 1e7:
        raise ValidationError(f"davison_maki would need {total:.2g} steps (> 1e7)")
    out = np.empty((times.size, n, n))
    cache: dict[int, NDArray] = {}
    t_prev = 0.0
    for j, t in enumerate(times):
        dt = float(t) - t_prev
        if dt > 0:
            ns = max(1, int(np.ceil(rho * dt / max_step)))
            d = dt / ns
            key = int(round(d * 2.0**40))
            E = cache.get(key)
            if E is None:
                E = cache[key] = scipy.linalg.expm(M * d)
            for _ in range(ns):
                U = E[:n, :n] + E[:n, n:] @ P
                V = E[n:, :n] + E[n:, n:] @ P
                P = sym(np.linalg.solve(U.T, V.T).T)
        out[j] = P
        t_prev = float(t)
    return out
