r"""The Kalman spectral conditions with the null vectors that fix the gain, as a smooth problem.

The problem of the local methods of :mod:`optdesign.engines.spectral_newton` (behind
:mod:`optdesign.engines.inverse_kalman_engine`): residuals, objective, closed-form derivatives.

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
eigenvalue of S is a descent direction that raises the rank:
:func:`optdesign.engines.spectral_newton.escape_direction`).

References
----------
Moore, B. C., "On the flexibility offered by state feedback in multivariable systems beyond closed
loop eigenvalue assignment", IEEE TAC 21 (1976) 689-692 (the eigenvector parametrization).
Anderson & Moore, *Optimal Filtering* (1979) (the spectral factorization identity).  Burer, S. &
Monteiro, R. D. C., Math. Program. 95 (2003) 329-357 (the factorization ``Q = V V'``).  Absil,
Mahony & Sepulchre, *Optimization Algorithms on Matrix Manifolds* (2008) (Newton with retraction).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from ..analysis.linalg import commutation
from ..errors import ValidationError
from .tolerances import RESIDUAL_ROUNDING_FACTOR, rounding_level

__all__ = [
    "SpectralBlocks",
    "FactorProblem",
    "spectral_blocks",
    "initial_null_vectors",
    "residual_scale",
]



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
        g = self.g_fixed if (self.fixed_g and self.g_fixed is not None) else \
            self.blocks.unpack_g(x[self.nv + self.nt:])
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
        """Jacobian of ``c`` ((ng_rows, nx))."""
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
            Jd = np.kron(V, np.eye(k)) + np.kron(np.eye(k), V) @ commutation(k, r)
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

    def reduced_hessian(self, x: NDArray, mu: NDArray, Z: NDArray, H: NDArray | None = None) -> NDArray:
        """``Z' H Z`` ((d, d)) for the Hessian H of :meth:`hess` (passed when already built) and Z
        ((nx, d)), from its blocks: the g-g block is zero, and the V-V block ``I_r (x) 2 S`` is
        applied as ``2 S`` times each column block of Z where V is dense (objectives other than
        ``"nearest"``).  At n = 40, p = 8 (nx = 1040, d = 540) a third of the flops of the dense
        product."""
        if H is None:
            H = self.hess(x, mu)
        o, nv = self.nv + self.nt, self.nv
        Zo, Zg = Z[:o], Z[o:]
        if self.objective != "nearest" and nv == self.blocks.k * self.rank:
            k, r = self.blocks.k, self.rank
            S = self.dual_slack(x, mu)   # H[:nv, :nv] = I_r (x) 2 S; its t row and column are zero
            Y = np.zeros_like(Zo)
            Y[:nv] = np.matmul(S, Zo[:nv].reshape(r, k, -1)).reshape(nv, -1)
        else:
            Y = 0.5 * (H[:o, :o] @ Zo)
        if Zg.size:
            Y += H[:o, o:] @ Zg
        M = Zo.T @ Y
        return M + M.T

    # ---------------------------------------------------------------- tangent constraints
    def tangent_rows(self, x: NDArray, gauge: bool = True) -> NDArray[np.float64]:
        """Linear constraints on a step: the normalizations of g (unit norm, phase), the
        orthogonality of repeated targets' null vectors and (``gauge``) ``skew(V' dV) = 0``."""
        bl = self.blocks
        V, _, g = self.unpack(x)
        rows: list[NDArray] = []
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


def residual_scale(problem: FactorProblem, x: NDArray) -> float:
    """The rounding level of the residuals at x: ``n eps`` times the size of their terms."""
    return rounding_level(problem.blocks.n, problem.scale_c(x), RESIDUAL_ROUNDING_FACTOR)
