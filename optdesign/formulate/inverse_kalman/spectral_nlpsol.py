"""The spectral NLP as a ``casadi.nlpsol`` problem with closed-form derivative callbacks."""


from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from ..._backends import import_casadi
from .common import (
    FAST_OBJECTIVES,
    FAST_STRUCTURES,
    check_options,
    chol_factor,
    null_vector_start,
    psd_part,
    require_terms,
    tril_index,
)


@dataclass(eq=False)
class SpectralNLPSol:
    r"""The spectral-identity NLP of :func:`build_spectral_nlp` with explicit derivatives.

    Same variables, constraints and objective as :func:`build_spectral_nlp`, but the
    constraint Jacobian and the Hessian of the Lagrangian are evaluated in closed form with
    numpy (CasADi callbacks ``jac_g`` / ``hess_lag``) instead of by symbolic differentiation:
    with ``Q = Gd F F' Gd'`` every residual ``w (R/s + G1 Q G2^T) w_i`` is bilinear in
    ``(F F', w_i)``, so (``h = G1^H mu`` for the residual multipliers ``mu``, ``b = Gd' G2^T
    w_i``) the Lagrangian's F-F block is block diagonal by column of F
    (``delta_jl Re(conj(h_i) b_k + conj(h_k) b_i)``), its F-w block is two rank-one products
    per null-vector entry and its w-w block comes from the normalizations only.  Symbolic
    differentiation of the same graph costs O(n^5) (1.6 s at n = 20, 12 s at n = 30, per
    start); the closed forms cost nothing to build and O(n^3 p) per evaluation.

    Attributes
    ----------
    nlp : dict
        ``{"x": SX, "f": SX, "g": SX}`` for ``casadi.nlpsol``.
    options : dict
        ``{"jac_g": Callback, "hess_lag": Callback}`` (merge into the nlpsol options; keep this
        object alive while the solver is used).
    x0 : (nx,) ndarray
        Initial point (from ``W0``).
    lbg, ubg : (ng,) ndarray
        All constraints are equalities (zeros).
    scale : float
    k : int
        Size of the decision covariance (n for ``"full"``, m for ``"input"``).
    n_factor : int
        Number of factor entries (the first ``n_factor`` entries of x).
    structure, objective : str
    """

    nlp: dict
    options: dict
    x0: NDArray[np.float64]
    lbg: NDArray[np.float64]
    ubg: NDArray[np.float64]
    scale: float
    k: int
    n_factor: int
    structure: str
    objective: str
    _keep: list = field(default_factory=list, repr=False)

    def decision(self, x: NDArray) -> NDArray[np.float64]:
        """The decision covariance ``F F'`` (physical units) at the point x."""
        F = np.zeros((self.k, self.k))
        F[tril_index(self.k)] = np.asarray(x, dtype=float).ravel()[: self.n_factor]
        return self.scale * (F @ F.T)


def make_callback(ca, name, n_in_shapes, out_sparsity, fun):
    """A CasADi Callback with dense inputs of the given (rows, cols) shapes and one sparse
    output; ``fun(*numpy inputs)`` returns the output's nonzeros (CasADi's column-major order)."""

    class _CB(ca.Callback):
        def __init__(self):
            ca.Callback.__init__(self)
            self.construct(name, {})

        def get_n_in(self):
            return len(n_in_shapes)

        def get_n_out(self):
            return 1

        def get_sparsity_in(self, i):
            return ca.Sparsity.dense(*n_in_shapes[i])

        def get_sparsity_out(self, i):
            return out_sparsity

        def has_eval_buffer(self):
            return True

        def eval_buffer(self, arg, res):  # raw nonzero buffers: no DM conversions
            ins = [np.frombuffer(a, dtype=np.float64) for a in arg]
            out = np.frombuffer(res[0], dtype=np.float64)
            out[:] = fun(*ins)
            return 0

        def eval(self, arg):  # pragma: no cover - CasADi uses eval_buffer
            vals = fun(*[np.asarray(a, dtype=float).ravel(order="F") for a in arg])
            return [ca.DM(out_sparsity, vals)]

    return _CB()


class _Layout:
    """The variable and constraint layout of the spectral NLP with closed-form derivatives: the
    factor entries of ``F`` (``Q = Gd F F' Gd'``), then the null vectors block by block; the
    normalizations (quadratic constraints) first, then the residual rows of each block."""

    def __init__(self, terms: list, Gd: NDArray, Rs: NDArray, p: int, objective: str, N: NDArray | None):
        self.p, self.objective, self.N = p, objective, N
        self.k = k = Gd.shape[1]
        self.I, self.J = I, J = tril_index(k)
        self.nF = nF = I.size
        self.GtG = Gd.T @ Gd
        blocks: list = []  # (size, cols of w (wr[, wi]), H1, B, wRs)
        quad: list = []    # normalizations: ([(i, j, a), ...], const) with c = sum a x_i x_j + const
        nx = nF
        groups: dict[tuple[float, float], list] = {}
        cols: tuple[NDArray[np.integer], ...]  # the columns of w: (wr,) or (wr, wi)
        for size, z, G1, G2, wgt in terms:
            if size == 1:
                H1 = wgt * (G1.real @ Gd) + 0j
                B = Gd.T @ G2.real.T + 0j
                cols = (np.arange(nx, nx + p),)
            else:
                H1 = wgt * (G1 @ Gd)
                B = Gd.T @ G2.T
                cols = (np.arange(nx, nx + p), np.arange(nx + p, nx + 2 * p))
            nx += size * p
            blocks.append((size, cols, H1, B, wgt * Rs))
            key = (round(z.real, 9), round(z.imag, 9))
            prev = groups.setdefault(key, [])
            quad.extend(_normalizations(size, cols, prev))
            prev.append(cols)
        self.blocks, self.quad, self.nx = blocks, quad, nx
        self.rows = []
        ng = len(quad)
        for size, *_ in blocks:
            self.rows.append(np.arange(ng, ng + size * p))
            ng += size * p
        self.ng = ng

    def symbolic(self, ca):
        """``(x, f, g)`` as CasADi SX expressions (cheap to build and to evaluate)."""
        k, nF, I, J = self.k, self.nF, self.I, self.J
        x = ca.SX.sym("x", self.nx)
        Fs = ca.SX(k, k)
        for c in range(nF):
            Fs[int(I[c]), int(J[c])] = x[c]
        Qd = ca.mtimes(Fs, Fs.T)
        gs = []
        for terms_q, const in self.quad:
            gs.append(sum(a * x[int(i)] * x[int(j)] for i, j, a in terms_q) + const)
        for size, cols, H1, B, wRs in self.blocks:
            wr = x[cols[0][0]:cols[0][-1] + 1]
            if size == 1:
                a = ca.mtimes(ca.DM(B.real), wr)
                b = ca.mtimes(Fs, ca.mtimes(Fs.T, a))
                gs.append(ca.mtimes(ca.DM(wRs), wr) + ca.mtimes(ca.DM(H1.real), b))
            else:
                wi = x[cols[1][0]:cols[1][-1] + 1]
                ar = ca.mtimes(ca.DM(B.real), wr) - ca.mtimes(ca.DM(B.imag), wi)
                ai = ca.mtimes(ca.DM(B.real), wi) + ca.mtimes(ca.DM(B.imag), wr)
                br = ca.mtimes(Fs, ca.mtimes(Fs.T, ar))
                bi = ca.mtimes(Fs, ca.mtimes(Fs.T, ai))
                h1r, h1i = ca.DM(H1.real), ca.DM(H1.imag)
                gs.append(ca.mtimes(ca.DM(wRs), wr) + ca.mtimes(h1r, br) - ca.mtimes(h1i, bi))
                gs.append(ca.mtimes(ca.DM(wRs), wi) + ca.mtimes(h1r, bi) + ca.mtimes(h1i, br))
        g = ca.vertcat(*gs)
        if self.objective == "min_trace":
            f = ca.trace(ca.mtimes(ca.mtimes(Fs.T, ca.DM(self.GtG)), Fs))
        else:
            f = ca.sumsqr(Qd - ca.DM(self.N))
        return x, f, g

    def sparsity(self, ca):
        """The sparsity patterns of the constraint Jacobian and of the Lagrangian's upper triangle;
        also sets the triplet indices ``jrow, jcol`` / ``hrow, hcol`` the callbacks return."""
        nF, nx, J = self.nF, self.nx, self.J
        jr: list[int] = []
        jc: list[int] = []
        for q, (terms_q, _) in enumerate(self.quad):
            idx = sorted({int(i) for i, _, _ in terms_q} | {int(j) for _, j, _ in terms_q})
            jr += [q] * len(idx)
            jc += idx
        for (_size, cols, *_), rr in zip(self.blocks, self.rows, strict=True):
            wc = np.concatenate(cols)
            cc = np.concatenate([np.arange(nF), wc])
            for r in rr:
                jr += [int(r)] * cc.size
                jc += cc.tolist()
        jsp = ca.Sparsity.triplet(self.ng, nx, jr, jc)
        self.jrow, self.jcol = (np.asarray(v, dtype=np.intp) for v in jsp.get_triplet())
        hr: list[int] = []
        hc: list[int] = []
        if self.objective == "nearest":
            fr, fc = np.meshgrid(np.arange(nF), np.arange(nF), indexing="ij")
            keep = fr <= fc
            hr += fr[keep].tolist()
            hc += fc[keep].tolist()
        else:  # block diagonal by column of F
            for c1 in range(nF):
                same = np.flatnonzero((J == J[c1]) & (np.arange(nF) >= c1))
                hr += [c1] * same.size
                hc += same.tolist()
        wall = np.arange(nF, nx)
        fr, fc = np.meshgrid(np.arange(nF), wall, indexing="ij")
        hr += fr.ravel().tolist()
        hc += fc.ravel().tolist()
        for terms_q, _ in self.quad:
            for i, j, _ in terms_q:
                hr.append(min(int(i), int(j)))
                hc.append(max(int(i), int(j)))
        hsp = ca.Sparsity.triplet(nx, nx, hr, hc)  # duplicates are merged
        self.hrow, self.hcol = (np.asarray(v, dtype=np.intp) for v in hsp.get_triplet())
        return jsp, hsp

    def factor(self, xv: NDArray) -> NDArray:
        F = np.zeros((self.k, self.k))
        F[self.I, self.J] = xv[:self.nF]
        return F

    def jac_g(self, xv, _p=None):
        """The constraint Jacobian at ``xv`` (its nonzeros, in the order of :meth:`sparsity`)."""
        I, J, nF, p = self.I, self.J, self.nF, self.p
        xv = xv.ravel()
        F = self.factor(xv)
        Jm = np.zeros((self.ng, self.nx))
        for q, (terms_q, _) in enumerate(self.quad):
            for i, j, a in terms_q:
                Jm[q, i] += a * xv[j]
                Jm[q, j] += a * xv[i]
        for (size, cols, H1, B, wRs), rr in zip(self.blocks, self.rows, strict=True):
            wc = xv[cols[0]] + (1j * xv[cols[1]] if size == 2 else 0.0)
            b = B @ wc
            u = F.T @ b
            V = H1 @ F
            JF = H1[:, I] * u[J][None, :] + V[:, J] * b[I][None, :]
            M = wRs + V @ (F.T @ B)
            Jm[rr[:p], :nF] = JF.real
            Jm[np.ix_(rr[:p], cols[0])] = M.real
            if size == 2:
                Jm[rr[p:], :nF] = JF.imag
                Jm[np.ix_(rr[p:], cols[0])] = M.imag
                Jm[np.ix_(rr[:p], cols[1])] = -M.imag
                Jm[np.ix_(rr[p:], cols[1])] = M.real
        return Jm[self.jrow, self.jcol]

    def hess_lag(self, xv, _p, lam_f, lam_g):
        """The upper triangle of the Lagrangian's Hessian (its nonzeros, as :meth:`sparsity`)."""
        I, J, nF, p, k = self.I, self.J, self.nF, self.p, self.k
        xv = xv.ravel()
        lam_g = lam_g.ravel()
        of = float(np.asarray(lam_f).ravel()[0])
        F = self.factor(xv)
        H = np.zeros((self.nx, self.nx))
        K = np.zeros((k, k))
        for (size, cols, H1, B, _), rr in zip(self.blocks, self.rows, strict=True):
            mu = lam_g[rr[:p]] + (1j * lam_g[rr[p:]] if size == 2 else 0.0)
            h = H1.conj().T @ mu
            wc = xv[cols[0]] + (1j * xv[cols[1]] if size == 2 else 0.0)
            b = B @ wc
            hb = np.outer(h.conj(), b).real
            K += hb + hb.T
            FB = F.T @ B
            Fh = F.T @ h
            X = h.conj()[I][:, None] * FB[J, :] + Fh.conj()[J][:, None] * B[I, :]
            H[:nF, cols[0]] += X.real
            if size == 2:
                H[:nF, cols[1]] -= X.imag
        same = J[:, None] == J[None, :]
        if self.objective == "min_trace":
            K += 2.0 * of * self.GtG
            H[:nF, :nF] += np.where(same, K[I[:, None], I[None, :]], 0.0)
        else:
            H[:nF, :nF] += np.where(same, K[I[:, None], I[None, :]], 0.0)
            E = F @ F.T - self.N
            FtF = F.T @ F
            Hn = (4.0 * F[I[None, :], J[:, None]] * F[I[:, None], J[None, :]]
                  + 4.0 * (I[:, None] == I[None, :]) * FtF[J[:, None], J[None, :]]
                  + 4.0 * same * E[I[:, None], I[None, :]])
            H[:nF, :nF] += of * Hn
        for q, (terms_q, _) in enumerate(self.quad):
            nu = lam_g[q]
            for i, j, a in terms_q:
                if i == j:
                    H[i, i] += 2.0 * a * nu
                else:
                    H[min(i, j), max(i, j)] += a * nu
        return H[self.hrow, self.hcol]

    def initial_point(self, W0: NDArray | None, s: float, terms: list) -> NDArray:
        """x0: the factor of ``W0 / s`` and each block's null-vector start (identity and unit
        vectors without ``W0``)."""
        I, J, nF, p, k = self.I, self.J, self.nF, self.p, self.k
        x0 = np.zeros(self.nx)
        if W0 is not None:
            Wp = psd_part(np.asarray(W0, dtype=float)) / s
            x0[:nF] = chol_factor(Wp)[I, J]
            seen: dict[tuple[float, float], int] = {}
            for (size, cols, H1, B, wRs), (_, z, *_r) in zip(self.blocks, terms, strict=True):
                key = (round(z.real, 9), round(z.imag, 9))
                c = seen.get(key, 0)
                seen[key] = c + 1
                v = null_vector_start(wRs + H1 @ Wp @ B, size, c, p)
                if size == 1:
                    x0[cols[0]] = v
                else:
                    x0[cols[0]], x0[cols[1]] = v.real, v.imag
        else:
            x0[:nF] = np.eye(k)[I, J]
            for _size, cols, *_ in self.blocks:
                x0[cols[0][0]] = 1.0
        return x0


def _normalizations(size: int, cols: tuple, prev: list) -> list:
    """The quadratic constraints of one block's null vector: unit norm, and (Hermitian)
    orthogonality to the earlier blocks of the same target."""
    out = []
    if size == 1:
        wr = cols[0]
        out.append(([(i, i, 1.0) for i in wr], -1.0))
        for (o,) in prev:
            out.append(([(a, b, 1.0) for a, b in zip(o, wr, strict=True)], 0.0))
        return out
    wr, wi = cols
    out.append(([(i, i, 1.0) for i in wr] + [(i, i, 1.0) for i in wi], -1.0))
    out.append(([(a, b, 1.0) for a, b in zip(wr, wi, strict=True)], 0.0))
    for ar, ai in prev:  # Hermitian orthogonality w_a^H w_b = 0
        out.append(([(a, b, 1.0) for a, b in zip(ar, wr, strict=True)]
                    + [(a, b, 1.0) for a, b in zip(ai, wi, strict=True)], 0.0))
        out.append(([(a, b, 1.0) for a, b in zip(ar, wi, strict=True)]
                    + [(a, b, -1.0) for a, b in zip(ai, wr, strict=True)], 0.0))
    return out


def build_spectral_nlpsol(
    A: NDArray, C: NDArray, R: NDArray, poles: NDArray, *, dt: float | None = None,
    structure: str = "full", G: NDArray | None = None, objective: str = "min_trace",
    Q_nominal: NDArray | None = None, W0: NDArray | None = None, scale: float = 1.0,
    terms: list | None = None,
) -> SpectralNLPSol:
    r"""The spectral NLP (:func:`build_spectral_nlp`) as a ``casadi.nlpsol`` problem with
    closed-form derivatives (see :class:`SpectralNLPSol`).

    Parameters as for :func:`build_spectral_nlp` (``structure`` in :data:`FAST_STRUCTURES`,
    ``objective`` in :data:`FAST_OBJECTIVES`).

    Returns
    -------
    SpectralNLPSol
        Built, not solved.

    Raises
    ------
    ValidationError
        An unsupported structure / objective, missing G / Q_nominal, or a target at an
        eigenvalue of A or its mirror.
    """
    ca = import_casadi()
    check_options(structure, objective, G, Q_nominal, structures=FAST_STRUCTURES, objectives=FAST_OBJECTIVES)
    n, p = A.shape[0], C.shape[0]
    terms = require_terms(A, C, poles, dt, terms)
    s = float(scale)
    Gd = np.eye(n) if structure == "full" else np.asarray(G, dtype=float)
    Rs = np.asarray(R, dtype=float) / s
    N = None if Q_nominal is None else np.asarray(Q_nominal, dtype=float) / s
    lay = _Layout(terms, Gd, Rs, p, objective, N)
    nx, ng = lay.nx, lay.ng
    x, f, g = lay.symbolic(ca)
    jsp, hsp = lay.sparsity(ca)
    cb_j = make_callback(ca, "spectral_jac_g", [(nx, 1), (0, 1)], jsp, lay.jac_g)
    cb_h = make_callback(ca, "spectral_hess_lag", [(nx, 1), (0, 1), (1, 1), (ng, 1)], hsp, lay.hess_lag)
    gfun = ca.Function("spectral_g", [x, ca.SX.sym("p", 0)], [g])
    # the jac_g callback must return (g, jac_g): wrap it so that g comes from the SX graph
    xm, pm = ca.MX.sym("x", nx), ca.MX.sym("p", 0)
    jac_fun = ca.Function("nlp_jac_g", [xm, pm], [gfun(xm, pm)[0], cb_j(xm, pm)], ["x", "p"],
                          ["g", "jac_g_x"])
    lf, lg = ca.MX.sym("lam_f"), ca.MX.sym("lam_g", ng)
    hess_fun = ca.Function("nlp_hess_l", [xm, pm, lf, lg], [cb_h(xm, pm, lf, lg)],
                           ["x", "p", "lam_f", "lam_g"], ["triu_hess_gamma_x_x"])
    x0 = lay.initial_point(W0, s, terms)
    zeros = np.zeros(ng)
    return SpectralNLPSol(nlp={"x": x, "f": f, "g": g}, options={"jac_g": jac_fun, "hess_lag": hess_fun},
                          x0=x0, lbg=zeros, ubg=zeros.copy(), scale=s, k=lay.k, n_factor=lay.nF,
                          structure=structure, objective=objective,
                          _keep=[cb_j, cb_h, gfun, jac_fun, hess_fun, lay])

