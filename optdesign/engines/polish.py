"""Polishing of SDP points for the inverse Kalman families: the linear relations of a fixed gain
re-solved on the face of the PSD cone a point lies on, refined by Gauss-Newton on ``Q = V V'``, and
the same for the spectral conditions of the SDP in Q alone.  The SDP solvers stop at 1e-8 .. 1e-10
accuracy; these polishes make ``(P, Q)`` satisfy the Riccati equation to rounding error with Q
exactly PSD."""


from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..analysis.linalg import commutation, sym
from ..classical.placement import pole_error
from ..formulate.inverse_kalman import (
    fixed_gain_maps,
    noise_input,
    tril_index,
)
from .tolerances import (
    CONJ_IMAG_RTOL,
    FACE_POLISH_THRESHOLDS,
    FACE_REFINE_MAX,
    FACE_REFINE_MIN,
    NORM_FLOOR,
    POLISH_EXACT_RES,
    POLISH_ROUNDING_RES,
    SPECTRAL_POLISH_THRESHOLDS,
)


def min_norm_lstsq(M: NDArray, b: NDArray) -> NDArray:
    """Minimum-norm least squares by a complete orthogonal factorization (LAPACK gelsy: as
    accurate here as the SVD-based gelsd and much faster, notably with oversubscribed BLAS)."""
    from scipy.linalg import lstsq

    return lstsq(M, b, lapack_driver="gelsy", check_finite=False)[0]


def refine_gain(A: NDArray, C: NDArray, L: NDArray, target: NDArray, iters: int = 6) -> NDArray:
    """Newton steps on ``eig(A - L C) = target`` (min-norm corrections); keeps the best L."""
    from scipy.optimize import linear_sum_assignment

    best, best_err = L, pole_error(np.linalg.eigvals(A - L @ C), target)
    if best_err == 0.0:
        return L
    n, p = L.shape
    for _ in range(iters):
        F = A - best @ C
        lam, X = np.linalg.eig(F)
        try:
            Y = np.linalg.inv(X).conj().T  # left eigenvectors, y_i^H x_i = 1
        except np.linalg.LinAlgError:
            return best
        cost = np.abs(lam[:, None] - target[None, :])
        r, c = linear_sum_assignment(cost)
        rows, rhs = [], []
        for i, j in zip(r, c, strict=True):
            if lam[i].imag < -CONJ_IMAG_RTOL * max(1.0, abs(lam[i])):
                continue  # the conjugate equation is implied
            # d lambda_i = -y_i^H dL C x_i
            g = -np.outer(Y[:, i].conj(), C @ X[:, i]).reshape(-1)  # d/d vec_rowmajor(dL)
            d = target[j] - lam[i]
            rows.append(g.real)
            rhs.append(d.real)
            if abs(lam[i].imag) > CONJ_IMAG_RTOL * max(1.0, abs(lam[i])):
                rows.append(g.imag)
                rhs.append(d.imag)
        J = np.asarray(rows)
        dL = min_norm_lstsq(J, np.asarray(rhs))
        cand = best + dL.reshape(n, p)
        err = pole_error(np.linalg.eigvals(A - cand @ C), target)
        if not err < best_err:
            break
        best, best_err = cand, err
    return best


def duplication(n: int) -> NDArray:
    """D with vec(P) = D svec(P) (column-major vec, svec = lower-triangle entries)."""
    I, J = tril_index(n)
    D = np.zeros((n * n, I.size))
    cols = np.arange(I.size)
    D[J * n + I, cols] = 1.0
    D[I * n + J, cols] = 1.0
    return D


def lower_rows(n: int) -> NDArray[np.intp]:
    """Positions of the svec entries in the column-major vec."""
    I, J = tril_index(n)
    return J * n + I


def vec_f(X: NDArray) -> NDArray:
    return np.asarray(X).reshape(-1, order="F")


def face_polish(A, C, L, R, dt, structure, G, P0, W0, rtol):
    """Re-solve the linear relations exactly on the face of the PSD cone that ``W0`` lies on.

    ``W0`` is the decision covariance (Q for "full", Qw for "input", qw vector for "diagonal").
    Returns ``(P, Wdec, residual)`` for the best face among the candidate ranks, or None.
    """
    n = A.shape[0]
    gain_residual, q_of_P = fixed_gain_maps(A, C, L, R, dt)
    In = np.eye(n)
    if dt is None:
        Mg = np.kron(C, In)                       # vec(P C')
        Mq = -(np.kron(In, A) + np.kron(A, In))   # vec(-(A P + P A'))
    else:
        Fc = A - L @ C
        Mg = np.kron(C, Fc)                       # vec(F P C')
        Mq = np.eye(n * n) - np.kron(Fc, Fc)      # vec(P - F P F')
    Dn = duplication(n)
    rows = lower_rows(n)
    MgP = Mg @ Dn
    MqP = (Mq @ Dn)[rows]
    cg = -vec_f(gain_residual(np.zeros((n, n))))   # MgP svec(P) = cg
    cq = vec_f(q_of_P(np.zeros((n, n))))[rows]     # q(P) = cq + MqP svec(P)
    svecP0 = vec_f(P0)[rows]
    Gm = np.eye(n) if structure == "full" else G
    candidates: list[tuple[float, NDArray, NDArray]] = []
    if structure == "diagonal":
        w0 = np.asarray(W0, dtype=float).ravel()
        wmax = max(float(np.max(np.abs(w0))), NORM_FLOOR)
        masks = dict.fromkeys(tuple(w0 > tau * wmax) for tau in FACE_POLISH_THRESHOLDS)
        faces = [np.flatnonzero(np.array(mk)) for mk in masks]
    else:
        lam, U = np.linalg.eigh(sym(np.asarray(W0, dtype=float)))
        lam, U = lam[::-1], U[:, ::-1]
        lmax = max(float(lam[0]), NORM_FLOOR)
        # candidate ranks from eigenvalue gaps, the likeliest thresholds first
        ranks = list(dict.fromkeys(int(np.sum(lam > tau * lmax))
                                   for tau in FACE_POLISH_THRESHOLDS))
        faces = [U[:, :r] for r in ranks]
    for face in faces:
        if structure == "diagonal":
            act = face
            Mw = np.zeros((n * n, act.size))
            for c, i in enumerate(act):
                Mw[:, c] = vec_f(np.outer(G[:, i], G[:, i]))
            Mw = Mw[rows]
            z0w = np.asarray(W0, dtype=float).ravel()[act]
        else:
            Uf = face
            r = Uf.shape[1]
            GU = Gm @ Uf
            Mw = (np.kron(GU, GU) @ duplication(r))[rows] if r else np.zeros((rows.size, 0))
            Wr = Uf.T @ sym(np.asarray(W0, dtype=float)) @ Uf
            z0w = vec_f(Wr)[lower_rows(r)] if r else np.zeros(0)
        # unknowns z = [svec P, w]:  MgP svecP = cg ;  cq + MqP svecP - Mw w = 0
        M = np.block([[MgP, np.zeros((MgP.shape[0], Mw.shape[1]))], [MqP, -Mw]])
        rhs = np.concatenate([cg, -cq])
        z0 = np.concatenate([svecP0, z0w])
        z = z0
        for _ in range(3):  # min-norm correction, then iterative refinement
            dz = min_norm_lstsq(M, rhs - M @ z)
            z = z + dz
        res = float(np.linalg.norm(M @ z - rhs)) / max(NORM_FLOOR, float(np.linalg.norm(rhs)) + 1.0)
        svp = z[: svecP0.size]
        P = (Dn @ svp).reshape(n, n, order="F")
        w = z[svecP0.size:]
        if structure == "diagonal":
            wd = np.zeros(G.shape[1])
            wd[face] = w
            ok = bool(np.all(w > 0)) if w.size else True
            Wdec = wd
        else:
            r = face.shape[1]
            Wr = (duplication(r) @ w).reshape(r, r, order="F") if r else np.zeros((0, 0))
            ok = bool(np.linalg.eigvalsh(Wr)[0] > 0) if r else True
            Wdec = sym(face @ Wr @ face.T) if r else np.zeros((face.shape[0],) * 2)
        if ok and structure != "diagonal" and face.shape[1] and FACE_REFINE_MIN < res < FACE_REFINE_MAX:
            # the face was read off an inexact point: refine it too (Gauss-Newton on Q = V V')
            Wr = Uf.T @ Wdec @ Uf
            lw, Uw = np.linalg.eigh(sym(Wr))
            V0 = Uf @ (Uw * np.sqrt(np.maximum(lw, 0.0)))
            P, V, res = gn_refine(MgP, MqP, cg, cq, Gm, Dn, P, V0, rhs)
            Wdec = sym(V @ V.T)
        if ok:
            candidates.append((res, P, Wdec))
            if res < POLISH_EXACT_RES:  # exact to rounding on this face: no need to try the others
                break
    if not candidates:
        return None
    res, P, Wdec = min(candidates, key=lambda c: c[0])
    if res > rtol:
        return None
    return sym(P), Wdec, res


def gn_refine(MgP, MqP, cg, cq, Gm, Dn, P0, V0, rhs, iters: int = 8):
    """Gauss-Newton (min-norm steps) on ``P C' = L R``-type and ``q(P) = Gm V V' Gm'`` relations.

    Unknowns ``svec(P)`` and ``V`` (k, r); returns ``(P, V, relative residual)`` -- the best
    iterate.  Quadratic convergence from a point within the SDP's accuracy of a solution.
    """
    n = P0.shape[0]
    k, r = V0.shape
    low = lower_rows(n)
    nP = Dn.shape[1]
    K = commutation(k, r)
    x = np.concatenate([vec_f(P0)[low], vec_f(V0)])
    norm_rhs = float(np.linalg.norm(rhs)) + 1.0

    def unpack(x):
        P = (Dn @ x[:nP]).reshape(n, n, order="F")
        V = x[nP:].reshape(k, r, order="F")
        return P, V

    def resid(x):
        _, V = unpack(x)
        r1 = MgP @ x[:nP] - cg
        r2 = cq + MqP @ x[:nP] - vec_f(Gm @ V @ V.T @ Gm.T)[low]
        return np.concatenate([r1, r2])

    best = (float(np.linalg.norm(resid(x))) / norm_rhs, x)
    for _ in range(iters):
        _, V = unpack(x)
        GV = Gm @ V
        JV = -(np.kron(GV, Gm) + np.kron(Gm, GV) @ K)[low]
        J = np.block([[MgP, np.zeros((MgP.shape[0], k * r))], [MqP, JV]])
        dx = min_norm_lstsq(J, -resid(x))
        x = x + dx
        res = float(np.linalg.norm(resid(x))) / norm_rhs
        if res < best[0]:
            best = (res, x)
        else:
            break
        if res < POLISH_ROUNDING_RES:
            break
    P, V = unpack(best[1])
    return sym(P), V, best[0]


def spectral_polish(E: NDArray, off: NDArray, structure: str, G: NDArray | None, W0: NDArray):
    """Exact solutions of the spectral conditions ``E vec(Q) + off = 0`` near ``W0`` with Q PSD:
    Gauss-Newton on ``Q = Gm V V' Gm'`` over candidate ranks (``diagonal``: a linear solve on
    the support).  Returns ``(Wdec, residual)`` or None."""
    best = None
    Gm = np.eye(np.asarray(W0).shape[0]) if structure == "full" else noise_input(structure, G)
    if structure == "diagonal":
        w0 = np.maximum(np.ravel(W0), 0.0)
        wmax = max(float(np.max(w0)), NORM_FLOOR)
        for mk in dict.fromkeys(tuple(w0 > tau * wmax) for tau in SPECTRAL_POLISH_THRESHOLDS):
            act = np.flatnonzero(np.array(mk))
            M = np.column_stack([E @ vec_f(np.outer(Gm[:, i], Gm[:, i])) for i in act]) if act.size else \
                np.zeros((E.shape[0], 0))
            d = w0[act]
            for _ in range(3):
                d = d + min_norm_lstsq(M, -(M @ d + off)) if act.size else d
            res = float(np.linalg.norm(M @ d + off)) / (1.0 + float(np.linalg.norm(off)))
            if np.all(d > 0) and (best is None or res < best[1]):
                wd = np.zeros(Gm.shape[1])
                wd[act] = d
                best = (wd, res)
        return best
    lam, U = np.linalg.eigh(sym(np.asarray(W0, dtype=float)))
    lam, U = lam[::-1], U[:, ::-1]
    lmax = max(float(lam[0]), NORM_FLOOR)
    for r in dict.fromkeys(int(np.sum(lam > tau * lmax)) for tau in SPECTRAL_POLISH_THRESHOLDS):
        if r == 0:
            continue
        k = U.shape[0]
        V = U[:, :r] * np.sqrt(np.maximum(lam[:r], 0.0))
        K = commutation(k, r)

        def resid(V):
            return E @ vec_f(Gm @ V @ V.T @ Gm.T) + off

        cur = float(np.linalg.norm(resid(V)))
        for _ in range(10):
            GV = Gm @ V
            J = E @ (np.kron(GV, Gm) + np.kron(Gm, GV) @ K)
            Vn = V + min_norm_lstsq(J, -resid(V)).reshape(k, r, order="F")
            new = float(np.linalg.norm(resid(Vn)))
            if not new < cur:
                break
            V, cur = Vn, new
            if cur < POLISH_ROUNDING_RES * (1.0 + float(np.linalg.norm(off))):
                break
        res = cur / (1.0 + float(np.linalg.norm(off)))
        if best is None or res < best[1]:
            best = (sym(V @ V.T), res)
        if res < POLISH_EXACT_RES:
            break
    return best

