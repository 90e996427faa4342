r"""Newton methods on the Kalman spectral conditions with the null vectors that fix the gain.

The smooth local solver behind :mod:`optdesign.solvers.inverse_kalman_engine`.

The conditions
--------------
For a target block ``(size, s, G1, G2, w)`` of :func:`optdesign.formulate.inverse_kalman.spectral_terms`
(``G1 = C (s I - A)^-1``, ``G2 = C (s~ I - A)^-1``, ``s~ = -s`` or ``1 / s``), ``s`` is a pole of the
steady-state Kalman filter of ``Q`` iff ``M(s) = R + G1 Q G2^T`` is singular.  Its *left* null vector
``g`` (``g^T M(s) = 0``, i.e. ``(R + G2 Q G1^T) g = 0``) is ``L' w`` for the left eigenvector ``w``
of ``A - L C`` at ``s``, and ``w = -G1^T g``.  (Continuous time: ``(A' - s I) w = C' L' w``; the
return difference ``T(s)' g = g + L' (s I - A')^-1 C' g`` vanishes, and ``M(-s) = T(-s) R T(s)'``.
Discrete time the same with ``M(1/s) = T(1/s) V T(s)'``.)  So the null vectors parametrize every
gain with the target poles -- ``L' [w_1 .. w_n] = [g_1 .. g_n]`` (real and imaginary parts for a
pair), Moore's parametric pole placement -- and the residuals

.. math::  r_b(Q, g_b) = w_b \, (R + G_{2,b} Q G_{1,b}^T) \, g_b

are *bilinear* in ``(Q, g)``: for fixed g (a fixed gain) they are the linear family of the
fixed-gain SDP, for fixed Q the g are null vectors.

Variables and derivatives
-------------------------
``Q = Gd Qdec Gd'`` with the decision covariance ``Qdec = V V' (+ t I)`` (``Gd = I`` for the
structure ``"full"``, G for ``"input"``; ``V`` diagonal for ``"diagonal"``: ``qw = v^2``), so
``Q >= 0`` by construction and the rank of Q is the number of columns of V.  The Jacobian and the
Hessian of the Lagrangian ``f + sum_b Re(mu_b^H r_b)`` are in closed form: with ``a = Gd' G1^T g``,
``h = w B^H mu`` (``B = G2 Gd``) the V-V block is ``I_r (x) 2 S`` where

.. math::  S = \nabla_{Q_{dec}} f + \operatorname{sym} \sum_b \operatorname{Re}(\bar h_b a_b^T)

is the dual slack of the joint problem: at a first-order point ``S V = 0``, and ``S >= 0`` is what
makes it a KKT point of the problem over all ``Qdec >= 0`` (else the eigenvector of a negative
eigenvalue of S is a descent direction that raises the rank: :func:`escape_direction`).

Methods
-------
* :func:`project` -- Gauss-Newton (minimum-norm steps) onto ``r = 0``, the normalizations of g kept
  (``||g_b|| = 1``, repeated targets orthonormal null vectors): the retraction, and the feasibility
  phase from an infeasible start (:func:`find_feasible`, with a backtracking line search).
* :func:`newton` -- Newton's method on the feasible manifold: the null-space (reduced) Hessian of
  the Lagrangian, its negative eigenvalues flipped, a step in the tangent space, the retraction
  and an Armijo line search on f; the gauge ``V -> V U`` removed by ``skew(V' dV) = 0``; columns
  of V whose singular value vanishes are truncated (a rank-deficient factor is a degenerate point
  where Newton converges only linearly).

All quantities are scaled: ``R`` and ``Q`` by ``scale`` (the caller's), so that ``Qdec`` is O(1).

References
----------
Moore, B. C., "On the flexibility offered by state feedback in multivariable systems beyond closed
loop eigenvalue assignment", IEEE TAC 21 (1976) 689-692 (the eigenvector parametrization).
Anderson & Moore, *Optimal Filtering* (1979) (the spectral factorization identity).  Burer, S. &
Monteiro, R. D. C., Math. Program. 95 (2003) 329-357 (the factorization ``Q = V V'``).  Absil,
Mahony & Sepulchre, *Optimization Algorithms on Matrix Manifolds* (2008) (Newton with retraction).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sl
from numpy.typing import NDArray

from ..errors import ValidationError

__all__ = [
    "SpectralBlocks",
    "FactorProblem",
    "NewtonReport",
    "spectral_blocks",
    "initial_null_vectors",
    "residual_scale",
    "project",
    "find_feasible",
    "newton",
    "sqp",
    "escape_direction",
]

_EPS = float(np.finfo(float).eps)


# ============================================================================ block data
@dataclass(frozen=True, eq=False)
class SpectralBlocks:
    """The target blocks of one design, stacked (see the module docstring).

    Attributes
    ----------
    size : (nb,) int array
        1 (real target) or 2 (complex pair, the member with positive imaginary part).
    s : (nb,) complex array
        The targets.
    B : (nb, p, k) complex array
        ``G2 Gd``.
    Ga : (nb, k, p) complex array
        ``Gd' G1^T``.
    G1 : (nb, p, n) complex array
    w : (nb,) float array
        Row weights of :func:`spectral_terms`.
    R : (p, p) array
        Scaled measurement-noise covariance ``R / scale``.
    Gd : (n, k) array
        Noise input of the decision covariance (identity for ``"full"``).
    groups : list of list of int
        Blocks of the same (repeated) target.
    re, im : (nb, p) int arrays
        Positions of each block's real parts (and, for a pair, imaginary parts; 0 otherwise) in
        the real residual vector -- and in the real vector of null-vector entries (same layout).
    cplx : (nb,) bool array
        The blocks of complex pairs.
    """

    size: NDArray[np.intp]
    s: NDArray[np.complex128]
    B: NDArray[np.complex128]
    Ga: NDArray[np.complex128]
    G1: NDArray[np.complex128]
    w: NDArray[np.float64]
    R: NDArray[np.float64]
    Gd: NDArray[np.float64]
    groups: list
    re: NDArray[np.intp]
    im: NDArray[np.intp]
    cplx: NDArray[np.bool_]
    _norms: tuple = field(default=(), repr=False)

    @property
    def n(self) -> int:
        return int(self.G1.shape[2])

    @property
    def p(self) -> int:
        return int(self.R.shape[0])

    @property
    def k(self) -> int:
        return int(self.Gd.shape[1])

    @property
    def nb(self) -> int:
        return int(self.size.size)

    @property
    def ng(self) -> int:
        """Number of real null-vector entries (= number of real residual rows)."""
        return int(self.re.size + np.sum(self.cplx) * self.p)

    @property
    def norms(self) -> tuple[float, NDArray[np.float64]]:
        """``(||R||_2, ||B_b||_F ||Ga_b||_F per block)``: the sizes of the residuals' terms."""
        return self._norms

    def unpack_g(self, gvec: NDArray) -> NDArray[np.complex128]:
        """(nb, p) complex null vectors from their real entries."""
        return gvec[self.re] + 1j * np.where(self.cplx[:, None], gvec[self.im], 0.0)

    def pack_g(self, g: NDArray) -> NDArray[np.float64]:
        return self.real_rows(g)

    def real_rows(self, z: NDArray) -> NDArray[np.float64]:
        """Real vector (or rows) from (nb, p, ...) complex block values (real part only for a real
        target)."""
        out = np.zeros((self.ng,) + z.shape[2:])
        out[self.re] = z.real
        out[self.im[self.cplx]] = z[self.cplx].imag
        return out

    def complex_of(self, v: NDArray) -> NDArray[np.complex128]:
        """(nb, p) complex block values from a real vector in the same layout (inverse of
        :meth:`real_rows`)."""
        return self.unpack_g(v)

    def matrix(self, Qdec: NDArray) -> NDArray[np.complex128]:
        """The (nb, p, p) matrices ``w (R + B Qdec Ga)`` (the transposed spectral matrices)."""
        return self.w[:, None, None] * (self.R[None] + self.B @ Qdec[None] @ self.Ga)

    def residual(self, Qdec: NDArray, g: NDArray) -> NDArray[np.float64]:
        a = np.einsum("bkp,bp->bk", self.Ga, g)
        r = g @ self.R.T + np.einsum("bpk,bk->bp", self.B, a @ Qdec)
        return self.real_rows(self.w[:, None] * r)

    def gain(self, g: NDArray) -> tuple[NDArray[np.float64], float]:
        """``L`` from the null vectors, ``L' [Re w, Im w] = [Re g, Im g]`` with ``w = -G1^T g``, and
        the 2-norm condition number of the eigenvector matrix ``[Re w, Im w]`` (column-normalized)."""
        W, Gm = [], []
        for b in range(self.nb):
            wv = -(self.G1[b].T @ g[b])
            if self.size[b] == 1:
                W.append(wv.real)
                Gm.append(g[b].real)
            else:
                W += [wv.real, wv.imag]
                Gm += [g[b].real, g[b].imag]
        Wm, Gmm = np.column_stack(W), np.column_stack(Gm)
        nrm = np.linalg.norm(Wm, axis=0)
        nrm = np.where(nrm > 0, nrm, 1.0)
        cond = float(np.linalg.cond(Wm / nrm))
        L = np.linalg.solve(Wm.T, Gmm.T)
        return L, cond


def spectral_blocks(terms: list, R: NDArray, Gd: NDArray, scale: float = 1.0) -> SpectralBlocks:
    """Stack :func:`spectral_terms` (a list of ``(size, s, G1, G2, w)``) for the decision
    covariance through ``Gd`` ((n, k)); ``R`` is divided by ``scale``."""
    R = np.asarray(R, dtype=float) / float(scale)
    Gd = np.asarray(Gd, dtype=float)
    p = R.shape[0]
    size = np.array([t[0] for t in terms], dtype=np.intp)
    B = np.stack([t[3] @ Gd for t in terms]).astype(complex)
    Ga = np.stack([Gd.T @ t[2].T for t in terms]).astype(complex)
    G1 = np.stack([t[2] for t in terms]).astype(complex)
    real = size == 1
    B[real] = B[real].real
    Ga[real] = Ga[real].real
    G1[real] = G1[real].real
    re = np.zeros((size.size, p), dtype=np.intp)
    im = np.zeros((size.size, p), dtype=np.intp)
    pos = 0
    for b, sz in enumerate(size):
        re[b] = np.arange(pos, pos + p)
        if sz == 2:
            im[b] = np.arange(pos + p, pos + 2 * p)
        pos += sz * p
    seen: dict[tuple[float, float], list[int]] = {}
    for b, t in enumerate(terms):
        seen.setdefault((round(t[1].real, 9), round(t[1].imag, 9)), []).append(b)
    return SpectralBlocks(size=size, s=np.array([t[1] for t in terms], dtype=complex), B=B, Ga=Ga, G1=G1,
                          w=np.array([t[4] for t in terms], dtype=float), R=R, Gd=Gd,
                          groups=[g for g in seen.values() if len(g) > 1],
                          re=re, im=im, cplx=size == 2,
                          _norms=(float(np.linalg.norm(R, 2)),
                                  np.linalg.norm(B, axis=(1, 2)) * np.linalg.norm(Ga, axis=(1, 2))))


def initial_null_vectors(blocks: SpectralBlocks, Qdec: NDArray) -> NDArray[np.complex128]:
    """Unit null-vector guesses at ``Qdec``: the right singular vectors of each block's matrix for
    its smallest singular values (the c-th repetition of a target gets the (c+1)-th smallest)."""
    Mt = blocks.matrix(Qdec)
    g = np.zeros((blocks.nb, blocks.p), dtype=complex)
    count: dict[int, int] = {}
    rep = {b: i for grp in blocks.groups for i, b in enumerate(grp)}
    for b in range(blocks.nb):
        M = Mt[b].real if blocks.size[b] == 1 else Mt[b]
        vh = np.linalg.svd(M)[2]
        c = rep.get(b, 0)
        count[b] = c
        g[b] = vh[-1 - min(c, blocks.p - 1)].conj()
    return _orthonormal(blocks, g)


def _orthonormal(blocks: SpectralBlocks, g: NDArray) -> NDArray[np.complex128]:
    g = g / np.linalg.norm(g, axis=1, keepdims=True)
    for grp in blocks.groups:
        q = np.linalg.qr(np.column_stack([g[b] for b in grp]))[0]
        for c, b in enumerate(grp):
            g[b] = q[:, c].real if blocks.size[b] == 1 else q[:, c]
    return g


# ============================================================================ the problem
@dataclass(eq=False)
class FactorProblem:
    """Objective and constraints in the real vector ``x = [V entries, (t), g entries]``.

    Parameters
    ----------
    blocks : SpectralBlocks
    rank : int
        Columns of V (``k`` for ``diagonal``).
    objective : {"min_trace", "nearest", "feasibility"}
    nominal : (k, k) ndarray, optional
        Scaled ``Q_nominal`` (objective ``"nearest"``).
    diagonal : bool
        ``Qdec = diag(v)^2`` (V diagonal).
    lower : bool
        V lower triangular (``rank = k``): a Cholesky factor, no gauge freedom -- the full-rank
        start of a descent (a truncation makes V dense).
    fixed_g : bool
        The null vectors are constants (a fixed gain): x holds V (and t) only.
    g_fixed : (nb, p) complex array, optional
        Their values when ``fixed_g``.
    """

    blocks: SpectralBlocks
    rank: int
    objective: str = "min_trace"
    nominal: NDArray | None = None
    diagonal: bool = False
    fixed_g: bool = False
    g_fixed: NDArray | None = None
    lower: bool = False

    def __post_init__(self) -> None:
        k = self.blocks.k
        if self.diagonal:
            self.rank = k
            mask = np.eye(k, dtype=bool)
        elif self.lower:
            self.rank = k
            mask = np.tril(np.ones((k, k), dtype=bool))
        else:
            mask = np.ones((k, self.rank), dtype=bool)
        self.idx = np.flatnonzero(mask.T.ravel())  # positions j*k + l of vec(V) (column-major)
        self.nv = int(self.idx.size)
        self.nt = 1 if self.objective == "feasibility" else 0
        self.ng = 0 if self.fixed_g else self.blocks.ng
        self.nx = self.nv + self.nt + self.ng
        self.GtG = self.blocks.Gd.T @ self.blocks.Gd
        if self.objective == "nearest" and self.nominal is None:
            raise ValidationError("objective='nearest' needs the (scaled) nominal covariance")

    # ---------------------------------------------------------------- packing
    def unpack(self, x: NDArray) -> tuple[NDArray, float, NDArray]:
        k, r = self.blocks.k, self.rank
        vv = np.zeros(k * r)
        vv[self.idx] = x[:self.nv]
        V = vv.reshape(r, k).T
        t = float(x[self.nv]) if self.nt else 0.0
        g = self.g_fixed if self.fixed_g else self.blocks.unpack_g(x[self.nv + self.nt:])
        return V, t, g

    def pack(self, V: NDArray, t: float, g: NDArray) -> NDArray[np.float64]:
        parts = [np.asarray(V, dtype=float).T.ravel()[self.idx]]
        if self.nt:
            parts.append(np.array([t], dtype=float))
        if not self.fixed_g:
            parts.append(self.blocks.pack_g(g))
        return np.concatenate(parts)

    def qdec(self, V: NDArray, t: float) -> NDArray[np.float64]:
        Qd = V @ V.T
        return Qd + t * np.eye(Qd.shape[0]) if self.nt else Qd

    # ---------------------------------------------------------------- values
    def f(self, x: NDArray) -> float:
        V, t, _ = self.unpack(x)
        if self.objective == "min_trace":
            return float(np.sum(V * (self.GtG @ V)))
        if self.objective == "feasibility":
            return -t
        E = V @ V.T - self.nominal
        return float(np.sum(E * E))

    def grad(self, x: NDArray) -> NDArray[np.float64]:
        V, _, _ = self.unpack(x)
        out = np.zeros(self.nx)
        if self.objective == "min_trace":
            GV = 2.0 * self.GtG @ V
        elif self.objective == "feasibility":
            GV = np.zeros_like(V)
            out[self.nv] = -1.0
        else:
            GV = 4.0 * (V @ V.T - self.nominal) @ V
        out[:self.nv] = GV.T.ravel()[self.idx]
        return out

    def c(self, x: NDArray) -> NDArray[np.float64]:
        V, t, g = self.unpack(x)
        return self.blocks.residual(self.qdec(V, t), g)

    def jac(self, x: NDArray) -> NDArray[np.float64]:
        """Jacobian of :meth:`c` ((ng_rows, nx))."""
        bl = self.blocks
        V, t, g = self.unpack(x)
        k, r, p = bl.k, self.rank, bl.p
        Qd = self.qdec(V, t)
        wgt = bl.w[:, None, None]
        a = np.einsum("bkp,bp->bk", bl.Ga, g)                     # (nb, k)
        u = a @ V                                                  # (nb, r)
        BV = bl.B @ V                                              # (nb, p, r)
        Jv = (bl.B[:, :, None, :] * u[:, None, :, None] + BV[:, :, :, None] * a[:, None, None, :])
        Jv = (wgt * Jv.reshape(bl.nb, p, r * k)[:, :, self.idx])   # (nb, p, nv)
        J = np.zeros((bl.ng, self.nx))
        J[:, :self.nv] = bl.real_rows(Jv)
        if self.nt:
            J[:, self.nv] = bl.real_rows(wgt[:, :, 0] * np.einsum("bpk,bk->bp", bl.B, a))
        if not self.fixed_g:
            Mt = bl.matrix(Qd)
            o = self.nv + self.nt
            J[bl.re[:, :, None], bl.re[:, None, :] + o] = Mt.real
            c = bl.cplx
            if np.any(c):
                rc, ic, Mc = bl.re[c], bl.im[c], Mt[c]
                J[rc[:, :, None], ic[:, None, :] + o] = -Mc.imag
                J[ic[:, :, None], rc[:, None, :] + o] = Mc.imag
                J[ic[:, :, None], ic[:, None, :] + o] = Mc.real
        return J

    def _mu_h(self, mu: NDArray) -> NDArray[np.complex128]:
        """``h_b = w_b B_b^H mu_b`` ((nb, k)) from the real multipliers."""
        bl = self.blocks
        return bl.w[:, None] * np.einsum("bpk,bp->bk", bl.B.conj(), bl.complex_of(mu))

    def dual_slack(self, x: NDArray, mu: NDArray) -> NDArray[np.float64]:
        """``S = grad_Qdec f + sym(sum_b Re(conj(h_b) a_b^T))`` ((k, k); see the module docstring)."""
        V, _, g = self.unpack(x)
        h = self._mu_h(mu)
        a = np.einsum("bkp,bp->bk", self.blocks.Ga, g)
        K = np.real(h.conj().T @ a)
        S = 0.5 * (K + K.T)
        if self.objective == "min_trace":
            S = S + self.GtG
        elif self.objective == "nearest":
            S = S + 2.0 * (V @ V.T - self.nominal)
        return S

    def hess(self, x: NDArray, mu: NDArray) -> NDArray[np.float64]:
        """Hessian of the Lagrangian ``f + mu' c`` ((nx, nx))."""
        bl = self.blocks
        V, _, g = self.unpack(x)
        k, r, p = bl.k, self.rank, bl.p
        H = np.zeros((self.nx, self.nx))
        h = self._mu_h(mu)
        S = self.dual_slack(x, mu)
        if self.objective == "nearest":
            S = S - 2.0 * (V @ V.T - self.nominal)  # its Hessian is added below in full
        Hvv = np.kron(np.eye(r), 2.0 * S)
        if self.objective == "nearest":
            E = V @ V.T - self.nominal
            Jd = np.kron(V, np.eye(k)) + np.kron(np.eye(k), V) @ _commutation(k, r)
            Hvv += 2.0 * Jd.T @ Jd + 4.0 * np.kron(np.eye(r), E)
        H[:self.nv, :self.nv] = Hvv[np.ix_(self.idx, self.idx)]
        if not self.fixed_g:
            o = self.nv + self.nt
            VGa = np.einsum("kr,bkp->brp", V, bl.Ga)              # (nb, r, p)
            Vh = h @ V                                              # (nb, r)
            Hc = (h.conj()[:, None, :, None] * VGa[:, :, None, :]
                  + Vh.conj()[:, :, None, None] * bl.Ga[:, None, :, :]).reshape(bl.nb, r * k, p)[:, self.idx]
            Hg = bl.real_rows(Hc.transpose(0, 2, 1))
            # the imaginary rows of real_rows are +Im; d/d(Im g) of Re(Hc g) is -Im(Hc)
            Hg[bl.im[bl.cplx]] *= -1.0
            H[:self.nv, o:] = Hg.T
            if self.nt:
                ht = np.einsum("bk,bkp->bp", h.conj(), bl.Ga)
                hr = bl.real_rows(ht[:, :, None])[:, 0]
                hr[bl.im[bl.cplx]] *= -1.0
                H[self.nv, o:] = hr
            H[o:, :o] = H[:o, o:].T
        return H

    # ---------------------------------------------------------------- tangent constraints
    def tangent_rows(self, x: NDArray, gauge: bool = True) -> NDArray[np.float64]:
        """Linear constraints on a step: the normalizations of g (unit norm, phase), the
        orthogonality of repeated targets' null vectors and (``gauge``) ``skew(V' dV) = 0``."""
        bl = self.blocks
        V, _, g = self.unpack(x)
        rows = []
        o = self.nv + self.nt
        if not self.fixed_g:
            N1 = np.zeros((bl.nb, self.nx))       # Re(g^H dg) = 0
            N1[np.arange(bl.nb)[:, None], bl.re + o] = g.real
            c = bl.cplx
            N1[np.flatnonzero(c)[:, None], bl.im[c] + o] = g[c].imag
            rows.extend(N1)
            if np.any(c):                          # Im(g^H dg) = 0 for a pair
                N2 = np.zeros((int(np.sum(c)), self.nx))
                ar = np.arange(N2.shape[0])[:, None]
                N2[ar, bl.re[c] + o] = -g[c].imag
                N2[ar, bl.im[c] + o] = g[c].real
                rows.extend(N2)
            for grp in bl.groups:
                for ia, a_ in enumerate(grp):
                    for b_ in grp[ia + 1:]:
                        ga, gb = g[a_], g[b_]
                        ra, ia_, rb, ib = bl.re[a_] + o, bl.im[a_] + o, bl.re[b_] + o, bl.im[b_] + o
                        row = np.zeros(self.nx)
                        row[ra], row[rb] = gb.real, ga.real
                        if bl.size[a_] == 2:
                            row[ia_], row[ib] = gb.imag, ga.imag
                            rows.append(row)
                            row = np.zeros(self.nx)
                            row[ra], row[ia_] = gb.imag, -gb.real
                            row[rb], row[ib] = -ga.imag, ga.real
                        rows.append(row)
        if gauge and not (self.diagonal or self.lower) and self.rank > 1:
            k, r = bl.k, self.rank
            jj, ll = np.triu_indices(r, 1)
            G = np.zeros((jj.size, k * r))
            for q, (j, l_) in enumerate(zip(jj, ll, strict=True)):
                G[q, l_ * k:(l_ + 1) * k] = V[:, j]
                G[q, j * k:(j + 1) * k] = -V[:, l_]
            Gr = np.zeros((jj.size, self.nx))
            Gr[:, :self.nv] = G[:, self.idx]
            rows.extend(Gr)
        return np.array(rows) if rows else np.zeros((0, self.nx))

    def normalize(self, x: NDArray) -> NDArray[np.float64]:
        """Unit null vectors (repeated targets: orthonormal) -- the residuals are homogeneous in g."""
        if self.fixed_g:
            return x
        V, t, g = self.unpack(x)
        return self.pack(V, t, _orthonormal(self.blocks, g))

    def scale_c(self, x: NDArray) -> float:
        """Size of the terms of the residuals (for relative tolerances)."""
        V, t, _ = self.unpack(x)
        qn = float(np.sum(V * V)) + abs(t) * V.shape[0]   # >= ||Qdec||_2
        bl = self.blocks
        return float(np.max(bl.w * (bl.norms[0] + bl.norms[1] * qn)))


def _commutation(k: int, r: int) -> NDArray[np.float64]:
    """K with vec(V') = K vec(V) for a (k, r) matrix V (column-major vec)."""
    K = np.zeros((k * r, k * r))
    i, j = np.meshgrid(np.arange(k), np.arange(r), indexing="ij")
    K[(i * r + j).ravel(), (j * k + i).ravel()] = 1.0
    return K


def residual_scale(problem: FactorProblem, x: NDArray) -> float:
    """The rounding level of the residuals at x: ``n eps`` times the size of their terms."""
    return 8.0 * problem.blocks.n * _EPS * problem.scale_c(x)


def _lstsq(M: NDArray, b: NDArray) -> NDArray:
    return sl.lstsq(M, b, lapack_driver="gelsy", check_finite=False)[0]


# ============================================================================ methods
def project(problem: FactorProblem, x: NDArray, *, max_iter: int = 12,
            tol_factor: float = 100.0) -> tuple[NDArray, bool, int]:
    """Gauss-Newton (minimum-norm steps, normalizations kept) from x onto the residuals' zero set.

    Returns ``(x, converged, iterations)``: converged when ``||c|| <= tol_factor *``
    :func:`residual_scale` (the residuals at rounding level); stops early when a step does not
    reduce ``||c||`` by 10 % (after the first two), returning the best iterate.
    """
    x = problem.normalize(x)
    c = problem.c(x)
    best = (float(np.linalg.norm(c)), x)
    for it in range(max_iter):
        if best[0] <= tol_factor * residual_scale(problem, best[1]) * np.sqrt(max(1, c.size)):
            return best[1], True, it
        J = problem.jac(x)
        T = problem.tangent_rows(x, gauge=False)
        dx = _lstsq(np.vstack([J, T]), np.concatenate([-c, np.zeros(T.shape[0])]))
        x = problem.normalize(x + dx)
        c = problem.c(x)
        nc = float(np.linalg.norm(c))
        if not np.isfinite(nc):
            break
        if nc < best[0]:
            improved = nc < 0.9 * best[0]
            best = (nc, x)
            if not improved and it >= 2:
                break
        elif it >= 2:
            break
    ok = best[0] <= tol_factor * residual_scale(problem, best[1]) * np.sqrt(max(1, c.size))
    return best[1], bool(ok), max_iter


def find_feasible(problem: FactorProblem, x: NDArray, *, max_iter: int = 60,
                  expired: Callable[[], bool] | None = None) -> tuple[NDArray, bool, int]:
    """Gauss-Newton with a backtracking line search on ``||c||`` from an infeasible start.

    Returns ``(x, converged, iterations)``.  A local method: no convergence says nothing about
    the existence of a solution.
    """
    x = problem.normalize(x)
    c = problem.c(x)
    nc = float(np.linalg.norm(c))
    for it in range(max_iter):
        if nc <= 100.0 * residual_scale(problem, x) * np.sqrt(c.size):
            return x, True, it
        if expired is not None and expired():
            return x, False, it
        J = problem.jac(x)
        T = problem.tangent_rows(x, gauge=False)
        dx = _lstsq(np.vstack([J, T]), np.concatenate([-c, np.zeros(T.shape[0])]))
        alpha = 1.0
        while alpha > 1e-6:
            xn = problem.normalize(x + alpha * dx)
            cn = problem.c(xn)
            nn = float(np.linalg.norm(cn))
            if nn < (1.0 - 1e-4 * alpha) * nc:
                break
            alpha *= 0.5
        else:
            return x, False, it
        x, c, nc = xn, cn, nn
    return x, bool(nc <= 100.0 * residual_scale(problem, x) * np.sqrt(c.size)), max_iter


@dataclass(frozen=True)
class NewtonReport:
    """Outcome of :func:`newton`.

    Attributes
    ----------
    x : ndarray
        Last (feasible) iterate.
    converged : bool
        The reduced gradient reached its tolerance.
    iterations : int
    f : float
        Objective at x (scaled).
    reduced_gradient : float
        ``||Z' grad f||`` at x.
    multipliers : ndarray
        Least-squares multipliers of the residuals at x.
    reason : str
        Why it stopped.
    truncated : int
        Columns of V removed (vanishing singular values).
    problem : FactorProblem
        The problem of x (its rank changes when columns are truncated).
    """

    x: NDArray[np.float64]
    converged: bool
    iterations: int
    f: float
    reduced_gradient: float
    multipliers: NDArray[np.float64]
    reason: str
    truncated: int
    problem: FactorProblem


class _Factored:
    """Pivoted QR of ``M'`` (``M'[:, piv] = Q R``): the null space of M, least-squares multipliers
    and minimum-norm solutions of ``M dx = b`` (the rows of a dependent set are dropped)."""

    def __init__(self, M: NDArray):
        Qf, Rf, piv = sl.qr(M.T, mode="full", pivoting=True, check_finite=False)
        d = np.abs(np.diag(Rf))
        self.rank = int(np.sum(d > 1e-11 * d[0])) if d.size else 0
        self.Z = Qf[:, self.rank:]
        self.Q1 = Qf[:, :self.rank]
        self.R1 = Rf[:self.rank, :self.rank]
        self.piv = piv
        self.m = M.shape[0]

    def multipliers(self, grad: NDArray) -> NDArray[np.float64]:
        """``lam`` with ``M' lam = -grad`` in the least-squares sense."""
        lam = np.zeros(self.m)
        if self.rank:
            lam[self.piv[:self.rank]] = sl.solve_triangular(self.R1, -(self.Q1.T @ grad), check_finite=False)
        return lam

    def min_norm(self, b: NDArray) -> NDArray[np.float64]:
        """The minimum-norm dx with ``M dx = b`` (on the independent rows)."""
        if not self.rank:
            return np.zeros(self.Q1.shape[0])
        y = sl.solve_triangular(self.R1, b[self.piv[:self.rank]], trans="T", check_finite=False)
        return self.Q1 @ y


def _tr_step(w: NDArray, E: NDArray, g: NDArray, radius: float) -> NDArray:
    """Minimizer of ``g'd + d' H d / 2`` over ``||d|| <= radius`` for ``H = E diag(w) E'``
    (the trust-region subproblem in the eigenbasis: ``d = -(H + lam I)^-1 g`` with the smallest
    ``lam >= max(0, -min w)`` that keeps d in the region; the hard case adds the eigenvector of
    the smallest eigenvalue).  More & Sorensen (1983), by bisection on lam."""
    b = E.T @ g
    wmin = float(w[0])
    if wmin > 0:
        d = -b / w
        if np.linalg.norm(d) <= radius:
            return E @ d
    lo = max(0.0, -wmin)
    shift = 1e-12 * max(1.0, float(np.max(np.abs(w))))

    def size(lam):
        return float(np.linalg.norm(b / (w + lam)))

    if size(lo + shift) <= radius:      # hard case: the gradient misses the lowest eigenvector
        d = -b / (w + lo + shift)
        d[0] = 0.0
        tau = np.sqrt(max(radius ** 2 - float(d @ d), 0.0))
        d[0] = -tau if b[0] >= 0 else tau
        return E @ d
    hi = lo + float(np.linalg.norm(b)) / radius + shift
    lo = lo + shift
    for _ in range(100):                 # size(lam) decreases from > radius (lo) to <= radius (hi)
        mid = np.sqrt(lo * hi) if lo > 0 else 0.5 * hi
        if size(mid) > radius:
            lo = mid
        else:
            hi = mid
        if hi - lo <= 1e-12 * hi:
            break
    return E @ (-b / (w + hi))


def _chord_project(problem: FactorProblem, x: NDArray, fac: _Factored, n_rows: int,
                   max_iter: int = 6) -> tuple[NDArray, bool]:
    """The retraction by the chord method: Gauss-Newton corrections with the factored Jacobian
    of the base point (``n_rows`` residual rows, the tangent rows' right-hand side 0); falls back
    to :func:`project` when it stalls."""
    x = problem.normalize(x)
    c = problem.c(x)
    nc = float(np.linalg.norm(c))
    tol = 100.0 * residual_scale(problem, x) * np.sqrt(max(1, c.size))
    rhs = np.zeros(fac.m)
    for _ in range(max_iter):
        if nc <= tol:
            return x, True
        rhs[:n_rows] = -c
        xn = problem.normalize(x + fac.min_norm(rhs))
        cn = problem.c(xn)
        nn = float(np.linalg.norm(cn))
        if not nn < 0.5 * nc:
            break
        x, c, nc = xn, cn, nn
    if nc <= tol:
        return x, True
    xp, ok, _ = project(problem, x)
    return xp, ok


def _truncate(problem: FactorProblem, x: NDArray, rel: float) -> tuple[FactorProblem, NDArray, int]:
    """Drop the columns of V whose singular values are below ``rel`` times the largest."""
    if problem.diagonal or problem.rank <= 1:
        return problem, x, 0
    V, t, g = problem.unpack(x)
    U, sv, _ = np.linalg.svd(V, full_matrices=False)
    keep = int(np.sum(sv > rel * sv[0]))
    if keep >= problem.rank or keep == 0:
        return problem, x, 0
    new = FactorProblem(problem.blocks, keep, problem.objective, problem.nominal, False,
                        problem.fixed_g, problem.g_fixed)
    return new, new.pack(U[:, :keep] * sv[:keep], t, g), problem.rank - keep


def _polish(problem: FactorProblem, x: NDArray) -> tuple[NDArray, float]:
    """The residuals down to rounding (the line search accepts 100x that): ``(x, f)``."""
    xp, _, _ = project(problem, x, tol_factor=1.0)
    if np.linalg.norm(problem.c(xp)) <= np.linalg.norm(problem.c(x)):
        x = xp
    return x, problem.f(x)


def newton(problem: FactorProblem, x: NDArray, *, max_iter: int = 100, gtol: float = 1e-10,
           truncate: float = 1e-5, expired: Callable[[], bool] | None = None,
           log: list | None = None) -> NewtonReport:
    """Newton's method for ``min f`` on the feasible manifold ``c = 0`` from a feasible x.

    Each iteration: the null space Z of the residual Jacobian and the tangent rows, least-squares
    multipliers, the reduced Hessian ``Z' H Z``, the trust-region step of ``Z' grad f`` and
    ``Z'HZ`` (:func:`_tr_step`; the Newton step where Z'HZ is positive definite and the step fits),
    then the retraction (chord method, else :func:`project`) and an Armijo line search on the
    Lagrangian; the radius grows after full steps and shrinks to the accepted length otherwise.  Columns of V with singular value
    below ``truncate`` (relative) are removed first.  Stops when ``||Z' grad f|| <= gtol *
    max(1, |f|)``, after ``max_iter`` iterations, when no step decreases f, or when ``expired()``.
    ``log`` (a list) receives one ``(f, ||Z' grad f||, step length, rank)`` per iteration.
    """
    f = problem.f(x)
    truncated = 0
    mu = np.zeros(problem.blocks.ng)
    gz_norm = float("inf")
    reason = "iteration limit"
    radius = max(1.0, float(np.linalg.norm(x)))
    it = 0
    for it in range(max_iter):
        if expired is not None and expired():
            reason = "time limit"
            break
        pr2, x2, dropped = _truncate(problem, x, truncate)
        if dropped:
            x2, ok, _ = project(pr2, x2)
            if ok:
                problem, x, f = pr2, x2, pr2.f(x2)
                truncated += dropped
        grad = problem.grad(x)
        J = problem.jac(x)
        fac = _Factored(np.vstack([J, problem.tangent_rows(x)]))
        Z = fac.Z
        mu = fac.multipliers(grad)[:J.shape[0]]
        gz = Z.T @ grad
        gz_norm = float(np.linalg.norm(gz))
        if Z.shape[1] == 0 or gz_norm <= gtol * max(1.0, abs(f)):
            x, f = _polish(problem, x)
            return NewtonReport(x, True, it, f, gz_norm, mu, "converged", truncated, problem)
        Hz = Z.T @ problem.hess(x, mu) @ Z
        w, E = np.linalg.eigh(0.5 * (Hz + Hz.T))
        dx = Z @ _tr_step(w, E, gz, radius)
        ndx = float(np.linalg.norm(dx))
        slope = float(grad @ dx)
        if -slope <= 16.0 * _EPS * max(1.0, abs(f)):  # the predicted decrease is rounding
            x, f = _polish(problem, x)
            return NewtonReport(x, True, it, f, gz_norm, mu, "converged (decrease at rounding level)",
                                truncated, problem)
        # merit: the Lagrangian -- insensitive to first order to the retraction's tolerance in
        # the normal directions (f alone is not: its gradient is mostly normal)
        merit = f + float(mu @ problem.c(x))
        alpha = 1.0
        accepted = False
        while alpha > 1e-8:
            xn, ok = _chord_project(problem, x + alpha * dx, fac, J.shape[0])
            if ok:
                fn = problem.f(xn)
                if fn + float(mu @ problem.c(xn)) <= merit + 1e-4 * alpha * slope:
                    accepted = True
                    break
            alpha *= 0.5
        if log is not None:
            log.append((f, gz_norm, alpha if accepted else 0.0, problem.rank))
        if not accepted:
            reason = "no decrease along the Newton direction"
            break
        radius = max(radius, 2.0 * ndx) if alpha == 1.0 else max(alpha * ndx, 1e-8 * radius)
        x, f = xn, fn
    return NewtonReport(x, False, it + 1, f, gz_norm, mu, reason, truncated, problem)


def _filter_accepts(filt: list, theta: float, f: float) -> bool:
    """Not dominated by a filter entry ``(theta_j, f_j)`` (the margins are in the entries)."""
    return all(theta < tj or f < fj for tj, fj in filt)


def sqp(problem: FactorProblem, x: NDArray, *, max_iter: int = 100, feas_rel: float = 1e-6,
        truncate: float = 1e-5, expired: Callable[[], bool] | None = None,
        log: list | None = None) -> NewtonReport:
    """SQP from an infeasible x until it is nearly feasible (``||c|| <= feas_rel *`` the size of the
    residuals' terms), the objective reduced on the way.

    Each step is the minimum-norm normal step ``dn`` (``J dn = -c``, the tangent rows kept) plus the
    tangential step of the trust-region subproblem of ``Z'(grad f + H dn)`` and ``Z'HZ``
    (:func:`_tr_step`: negative curvature is followed, not flipped), with a filter line search on ``(theta, f)``, ``theta = ||c||`` (Waechter &
    Biegler's rules, simplified: a trial point is accepted when the filter does not dominate it
    and it reduces theta or f by a margin of theta, or -- where the step is a descent direction
    that dominates the infeasibility -- when it satisfies Armijo's condition on f).  Moving towards
    feasibility and optimality together lands in better basins than projecting onto the feasible
    set first (measured on the cross-validation targets).  The caller finishes with
    :func:`project` and :func:`newton`; ``converged`` means nearly feasible.

    References
    ----------
    Waechter, A. & Biegler, L. T., "On the implementation of an interior-point filter line-search
    algorithm for large-scale nonlinear programming", Math. Program. 106 (2006) 25-57.
    """
    x = problem.normalize(x)
    mu = np.zeros(problem.blocks.ng)
    truncated = 0
    it = 0
    f = problem.f(x)
    gz_norm = float("inf")
    c = problem.c(x)
    theta0 = float(np.linalg.norm(c))
    theta_max = 1e4 * max(1.0, theta0)
    filt: list[tuple[float, float]] = [(theta_max, -np.inf)]
    g_th, g_f = 1e-5, 1e-5
    radius = max(1.0, float(np.linalg.norm(x)))
    for it in range(max_iter):
        if expired is not None and expired():
            return NewtonReport(x, False, it, f, gz_norm, mu, "time limit", truncated, problem)
        pr2, x2, dropped = _truncate(problem, x, truncate)
        if dropped:  # a new point (the dropped columns change theta and f): a new filter
            problem, x, truncated = pr2, x2, truncated + dropped
            filt = [(theta_max, -np.inf)]
        c = problem.c(x)
        theta = float(np.linalg.norm(c))
        f = problem.f(x)
        if theta <= feas_rel * problem.scale_c(x):
            return NewtonReport(x, True, it, f, gz_norm, mu, "nearly feasible", truncated, problem)
        grad = problem.grad(x)
        J = problem.jac(x)
        fac = _Factored(np.vstack([J, problem.tangent_rows(x)]))
        rhs = np.zeros(fac.m)
        rhs[:J.shape[0]] = -c
        dn = fac.min_norm(rhs)
        mu = fac.multipliers(grad)[:J.shape[0]]
        H = problem.hess(x, mu)
        Z = fac.Z
        ndn = float(np.linalg.norm(dn))
        if ndn > radius:
            dn *= radius / ndn
            ndn = radius
        dx = dn
        if Z.shape[1]:
            gz = Z.T @ (grad + H @ dn)
            gz_norm = float(np.linalg.norm(Z.T @ grad))
            Hz = Z.T @ H @ Z
            w, E = np.linalg.eigh(0.5 * (Hz + Hz.T))
            dx = dn + Z @ _tr_step(w, E, gz, max(np.sqrt(max(radius ** 2 - ndn ** 2, 0.0)), 0.1 * radius))
        ndx = float(np.linalg.norm(dx))
        m = float(grad @ dx)
        alpha = 1.0
        accepted = False
        while alpha > 1e-8:
            xn = problem.normalize(x + alpha * dx)
            th_n, f_n = float(np.linalg.norm(problem.c(xn))), problem.f(xn)
            if np.isfinite(th_n) and np.isfinite(f_n) and _filter_accepts(filt, th_n, f_n):
                switching = m < 0 and alpha * (-m) ** 2.3 > theta ** 1.1
                if switching and f_n <= f + 1e-4 * alpha * m:
                    accepted = True
                    break
                if not switching and (th_n <= (1 - g_th) * theta or f_n <= f - g_f * theta):
                    filt.append(((1 - g_th) * theta, f - g_f * theta))
                    accepted = True
                    break
            alpha *= 0.5
        if log is not None:
            log.append((f, theta, alpha if accepted else 0.0, problem.rank))
        if not accepted:
            return NewtonReport(x, False, it, f, gz_norm, mu, "the filter line search failed", truncated, problem)
        radius = max(radius, 2.0 * ndx) if alpha == 1.0 else max(alpha * ndx, 1e-8 * radius)
        x = xn
    return NewtonReport(x, False, it + 1, problem.f(x), gz_norm, mu, "iteration limit", truncated, problem)


def escape_direction(problem: FactorProblem, x: NDArray, mu: NDArray,
                     tol: float) -> NDArray[np.float64] | None:
    """The eigenvector of the most negative eigenvalue of the dual slack S (see the module
    docstring) when that eigenvalue is below ``-tol``; else None (x is a KKT point of the
    problem over every ``Qdec >= 0``)."""
    S = problem.dual_slack(x, mu)
    w, U = np.linalg.eigh(S)
    if w[0] >= -tol:
        return None
    return U[:, 0]
