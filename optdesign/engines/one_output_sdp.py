r"""The one-output fixed-gain SDP in its n-constraint form: Clarabel, then Newton on its optimality
conditions.

With one output the poles fix the gain L, and the process-noise covariances whose Kalman filter
has that gain form the affine family ``Q(X) = Q0 + T(X)`` of
:mod:`optdesign.backends.clarabel_fixed_gain` (``T`` of dimension ``n(n - 1)/2``; in continuous time
it depends on the plant only).  Its orthogonal complement in the symmetric matrices has dimension
``n``: with an orthonormal basis ``W_1 .. W_n`` of it, Q is in the family iff
``<W_k, Q> = b_k = <W_k, Q0>``.  So the min-trace SDP is the standard pair

.. math::  \min\ \operatorname{tr} Q \ \ \text{s.t.}\ \ \langle W_k, Q\rangle = b_k,\ Q \succeq 0
           \qquad\qquad
           \max\ b' y \ \ \text{s.t.}\ \ Z = I - \textstyle\sum_k y_k W_k \succeq 0

-- n constraints, where the direct form of :func:`~optdesign.backends.clarabel_fixed_gain.solve_fixed_gain`
has ``n(n - 1)/2`` variables.  With p outputs and a given gain the family has dimension ``(n - p)(n -
p + 1)/2`` and its complement ``n p - p(p - 1)/2``: the same form, the several-output engine's
certificate SDP (measured at n = 40, p = 8: 0.6 s with the IPM and the polish, where Clarabel on the
direct form takes 8-9 s; the same optimum to Clarabel's 1e-9).  The data are normalized by
``||b||``: the min-trace Q is often 1e-5 to 1e-8 of ``L R L'``, the scale of the direct form's data,
whose tolerances are then relative to the wrong size (measured: traces 1e-5 apart between two
solvers at n = 10, and garbage at n >= 15, where this form solves every target).

:func:`solve_one_output` solves the dual on Clarabel (variables y, one PSD cone whose multiplier is
Q; from n = :data:`IPM_MIN_N` the dense IPM of :mod:`optdesign.engines.fixed_gain_ipm` on the pair,
whose Schur matrix is n x n, and Clarabel when it fails) to :data:`POLISH_START_TOL`, then runs
Newton's method on the optimality conditions

.. math::  W' \operatorname{svec}(Q) = b, \qquad (Q Z + Z Q)/2 = 0, \qquad Z = I - \operatorname{smat}(W y),

(the AHO system: nonsingular at a strictly complementary, nondegenerate solution, where Newton
converges quadratically -- Alizadeh, Haeberly & Overton 1998), truncates Q to its rank (exactly
PSD: ``V V'``) and checks the KKT conditions: ``Z`` PSD, complementarity, feasibility.  They make
the answer the global optimum over the Q of the gain (weak duality: ``b'y <= tr Q' `` for every
feasible ``Q'``).  Anything else -- a Clarabel status other than solved, a singular or stalling
Newton system, a KKT test that fails -- returns no solution and the reason; the caller then runs
the general route (:mod:`optdesign.engines.inverse_kalman_engine`), the only source of
``infeasible``.

References
----------
Alizadeh, F., Haeberly, J.-P. A. & Overton, M. L., "Primal-dual interior-point methods for
semidefinite programming: convergence rates, stability and numerical results", SIAM J. Optim.
8(3), 746-768 (1998).
Vandenberghe, L. & Boyd, S., "Semidefinite programming", SIAM Review 38(1), 49-95 (1996).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._backends import import_clarabel
from .._deadline import Deadline, dense_kkt_refusal
from ..backends.clarabel_fixed_gain import FixedGainFamily, clarabel_settings, smat, svec, svec_index
from .fixed_gain_ipm import standard_form_ipm, symmetric_basis
from .tolerances import (
    KKT_TOL,
    LYAPUNOV_GAP_FACTOR,
    NORM_FLOOR,
    POLISH_ROUNDING_FACTOR,
    POLISH_START_TOL,
    QR_RANK_FACTOR,
    rounding_level,
)

__all__ = ["POLISH_START_TOL", "KKT_TOL", "IPM_MIN_N", "OneOutputForm", "one_output_form",
           "one_output_form_of_plant", "form_of_basis",
           "OneOutputSolution", "solve_one_output", "symmetric_product_matrix"]

#: the dense IPM (:func:`~optdesign.engines.fixed_gain_ipm.standard_form_ipm`, n x n Schur matrix)
#: instead of Clarabel from this n (Clarabel's KKT system has a dense block of n(n+1)/2 rows).
#: Measured (CPU per SDP with the polish, 2 targets each): Clarabel 1.0-2.4 ms at n = 2-6 (the IPM
#: 3.3-5.9: Python per iteration), 5.3 / 7.1 ms at n = 10, equal at n = 12 (8.5 ms), 19-27 / 10-17
#: at n = 15 and 59-64 / 18-19 ms at n = 20; the same optimum to 2e-15 either way
IPM_MIN_N = 12
#: Newton steps at most (quadratic convergence: 2-3 are used)
POLISH_MAX_ITER = 8
# POLISH_START_TOL and KKT_TOL (re-exported here) are in engines/tolerances.py with their measurements


@dataclass(frozen=True, eq=False)
class OneOutputForm:
    """The n-constraint form of the fixed-gain SDP for the directions ``T`` of a family.

    Attributes
    ----------
    n : int
    W : (n(n+1)/2, nc) ndarray
        Orthonormal basis (Clarabel's scaled triangle, :func:`svec`) of the complement of
        ``range(T)`` (``nc = n`` for one output, ``n p - p(p - 1)/2`` for p).
    clarabel_data : tuple
        ``(P, A, h)`` of the dual on Clarabel (P = 0, A = W, h = svec(I); its one PSD cone is made
        per solve: Clarabel's cone objects do not pickle, and a held problem must), built once.
    basis : (nc, n, n) ndarray
        The matrices ``W_k`` (for the dense IPM).
    """

    n: int
    W: NDArray[np.float64]
    clarabel_data: tuple = field(repr=False)
    basis: NDArray[np.float64] = field(repr=False)


def one_output_form_of_plant(A: NDArray, C: NDArray,
                             deadline: Deadline | None = None) -> OneOutputForm | None:
    r"""The n-constraint form of a one-output continuous plant, without the family's directions T.

    ``W`` is orthogonal to every direction ``-(A M + M A')``, ``M = N X N'``, iff
    ``N' (A' W + W A) N = 0`` -- iff ``A' W + W A = c v' + v c'`` for some ``v`` (``c = C'``, since
    ``C N = 0``).  So the complement is spanned by the n Lyapunov solutions ``W_k`` of
    ``A' W + W A = c e_k' + e_k c'`` -- one real Schur form of A and n triangular Sylvester solves
    (LAPACK ``trsyl``), O(n^3) memory and O(n^4) time, where the QR of T (:func:`one_output_form`)
    needs the ``n(n+1)/2 x n(n-1)/2`` matrix T itself (3.2 GB at n = 200) and O(n^6) time --
    then a thin QR of the n columns ``svec(W_k)``.

    Returns None when A and -A share an eigenvalue to working precision (the Lyapunov operator is
    singular: the caller builds the form from T), or when ``deadline`` expires during the solves.
    """
    import scipy.linalg as sla

    A = np.asarray(A, dtype=float)
    c = np.asarray(C, dtype=float).reshape(-1)
    n = A.shape[0]
    S, U = sla.schur(A, output="real")
    lam = np.linalg.eigvals(A)
    gap = float(np.min(np.abs(lam[:, None] + lam[None, :])))
    if not gap > rounding_level(n, max(1.0, float(np.linalg.norm(A, 1))), LYAPUNOV_GAP_FACTOR):
        return None
    I, J, w = svec_index(n)
    uc = U.T @ c
    cols = np.empty((I.size, n))
    for k in range(n):
        if deadline is not None and deadline.expired:
            return None
        rhs = np.outer(uc, U[k]) + np.outer(U[k], uc)
        X, scale, info = sla.lapack.dtrsyl(S, S, rhs, trana="T", tranb="N", isgn=1)
        if info < 0 or not scale > 0:
            return None
        Wk = U @ (X / scale) @ U.T
        Wk = 0.5 * (Wk + Wk.T)
        cols[:, k] = Wk[I, J] * w
    if not np.all(np.isfinite(cols)):
        return None
    Qf, Rf = np.linalg.qr(cols)
    d = np.abs(np.diag(Rf))
    if not d.min() > rounding_level(I.size, max(float(d.max()), NORM_FLOOR), QR_RANK_FACTOR):
        return None
    return form_of_basis(np.ascontiguousarray(Qf), n)


def one_output_form(T: NDArray) -> OneOutputForm | None:
    """The form of the family directions ``T`` ((n(n+1)/2, m); m = n(n-1)/2 for one output, ``(n -
    p)(n - p + 1)/2`` for p): the complement of ``range(T)`` by a complete QR factorization (of
    dimension n for one output, ``n p - p(p - 1)/2`` for p); None when T does not have full column
    rank (a direction of the family does not move Q: the form does not describe the family)."""

    T = np.asarray(T, dtype=float)
    t, m = T.shape
    n = int(round((np.sqrt(8 * t + 1) - 1) / 2))
    nc = t - m
    if n * (n + 1) // 2 != t or nc < 1 or not np.all(np.isfinite(T)):
        return None
    Qf, Rf = np.linalg.qr(T, mode="complete")
    d = np.abs(np.diag(Rf))
    if m and not d.min() > rounding_level(t, max(float(d.max()), NORM_FLOOR), QR_RANK_FACTOR):
        return None
    return form_of_basis(np.ascontiguousarray(Qf[:, m:]), n)


def form_of_basis(W: NDArray, n: int) -> OneOutputForm:
    """The :class:`OneOutputForm` of an orthonormal basis ``W`` ((n(n+1)/2, nc), Clarabel's
    scaled triangle) of the complement of the family's directions."""
    import scipy.sparse as sp

    t, nc = W.shape
    # Clarabel's CSC data from their parts, 32-bit indices (4x cheaper than from a dense array at small n)
    zero = sp.csc_matrix((np.zeros(0), np.zeros(0, dtype=np.int32), np.zeros(nc + 1, dtype=np.int32)),
                         shape=(nc, nc))
    Wsp = sp.csc_matrix((W.ravel(order="F"), np.tile(np.arange(t, dtype=np.int32), nc),
                         np.arange(0, t * nc + 1, t, dtype=np.int32)), shape=(t, nc))
    return OneOutputForm(n=n, W=W, clarabel_data=(zero, Wsp, svec(np.eye(n))), basis=symmetric_basis(W, n))


@dataclass(frozen=True, eq=False)
class OneOutputSolution:
    """Outcome of :func:`solve_one_output`.

    Attributes
    ----------
    Q : (n, n) ndarray or None
        The min-trace process noise in physical units, ``V V'`` of its rank (None: no solution).
    rank : int
    y : (n,) ndarray or None
        Dual variables (normalized units): ``Z = I - smat(W y)``.
    kkt : dict
        ``min_eig`` (of Z over ||Z||), ``complementarity``, ``infeasibility``, ``gap`` (``(tr Q -
        b'y) / tr Q``), ``passed``.
    native_status : str
        Clarabel's status, or ``"ipm: solved"`` (the dense IPM, n >= :data:`IPM_MIN_N`).
    iterations : int
        The interior-point iterations.
    newton_iterations : int
    reason : str
        Why there is no solution ("" with one).
    """

    Q: NDArray[np.float64] | None
    rank: int
    y: NDArray[np.float64] | None
    kkt: dict[str, Any]
    native_status: str
    iterations: int
    newton_iterations: int
    reason: str = ""


@functools.lru_cache(maxsize=64)
def _product_index(n: int):
    """Index arrays of :func:`symmetric_product_matrix` for size n (read-only)."""
    I, J, w = svec_index(n)
    i, j, k, l = I[:, None], J[:, None], I[None, :], J[None, :]
    coef = w[:, None] / (2.0 * w[None, :] * (1.0 + (k == l)))
    out = (i, j, k, l, coef, (j == l).astype(float), (j == k).astype(float), (i == k).astype(float),
           (i == l).astype(float))
    for a in out:
        a.flags.writeable = False
    return out


def symmetric_product_matrix(X: NDArray) -> NDArray[np.float64]:
    """The matrix of ``H -> svec((X H + H X) / 2)`` acting on ``svec(H)`` (H, X symmetric (n, n);
    :func:`svec` coordinates): the symmetrized Kronecker product ``X (*) I``."""
    i, j, k, l, coef, djl, djk, dik, dil = _product_index(X.shape[0])
    return coef * (X[i, k] * djl + X[i, l] * djk + dik * X[l, j] + dil * X[k, j])


def _failed(reason: str, native: str = "", iterations: int = 0, newton: int = 0) -> OneOutputSolution:
    return OneOutputSolution(None, 0, None, {}, native, iterations, newton, reason)


def _settings(clarabel, deadline: Deadline | None):
    """:func:`~optdesign.backends.clarabel_fixed_gain.clarabel_settings` with the tolerances at
    :data:`POLISH_START_TOL` (the polish finishes the point)."""
    tol = {"tol_gap_abs": POLISH_START_TOL, "tol_gap_rel": POLISH_START_TOL, "tol_feas": POLISH_START_TOL}
    return clarabel_settings(clarabel, tol, deadline)


def solve_one_output(form: OneOutputForm, family: FixedGainFamily, *,
                     deadline: Deadline | None = None) -> OneOutputSolution:
    """The min-trace Q over the family of one gain (structure ``"full"``), globally, or why not.

    Parameters
    ----------
    form : OneOutputForm
        Of ``family.T`` (:func:`one_output_form`).
    family : FixedGainFamily
        The gain's family (:func:`~optdesign.backends.clarabel_fixed_gain.fixed_gain_family`).
    deadline : Deadline, optional
        Its remaining time becomes Clarabel's ``time_limit``.

    Returns
    -------
    OneOutputSolution
        With Q only when Clarabel solved the SDP, Newton converged and the KKT test passed.
    """
    clarabel = import_clarabel()
    n, W = form.n, form.W
    b = W.T @ svec(family.Q0)
    beta = float(np.linalg.norm(b))
    if not (np.isfinite(beta) and beta > 0.0):
        return _failed(f"the family's data b has norm {beta:.3g} (Q = 0 is in the family, or not finite)")
    bn = b / beta
    start = _interior_point(form, bn, deadline) if n >= IPM_MIN_N else None
    if start is None:
        why = dense_kkt_refusal(n * (n + 1) // 2, deadline, f"Clarabel on the n-constraint form at n = {n}")
        if why:
            return _failed(why)
        Pm, Am, h = form.clarabel_data
        cones = [clarabel.PSDTriangleConeT(n)]
        sol = clarabel.DefaultSolver(Pm, -bn, Am, h, cones, _settings(clarabel, deadline)).solve()
        native = str(sol.status)
        iters = int(getattr(sol, "iterations", 0) or 0)
        if native != "Solved":   # AlmostSolved and every other status: the general route decides
            return _failed(f"Clarabel {native}", native, iters)
        q, y = np.array(sol.z, dtype=float), np.array(sol.x, dtype=float)
    else:
        q, y, native, iters = start
    q, y, newton, why = _polish(W, bn, q, y, n)
    if why:
        return _failed(why, native, iters, newton)
    Z = smat(svec(np.eye(n)) - W @ y, n)
    Qn, rank = _truncated(smat(q, n), Z)
    kkt = _kkt(W, bn, y, Qn, Z)
    if not kkt["passed"]:
        return _failed("the polished point fails its KKT test (" + ", ".join(
            f"{k} {v:.2g}" for k, v in kkt.items() if k != "passed") + ")", native, iters, newton)
    Q = (family.scale * beta) * Qn
    return OneOutputSolution(0.5 * (Q + Q.T), rank, y, kkt, native, iters, newton)


def _interior_point(form: OneOutputForm, b: NDArray, deadline: Deadline | None):
    """``(q, y, "ipm: solved", iterations)`` from the dense IPM of
    :func:`~optdesign.engines.fixed_gain_ipm.standard_form_ipm` on the pair (C = I, A_k = W_k), to
    :data:`POLISH_START_TOL`; None when it did not meet its test (Clarabel then solves the SDP)."""
    out, rep = standard_form_ipm(form.basis, b, np.eye(form.n), tol=POLISH_START_TOL, deadline=deadline)
    if out is None:
        return None
    X, _, y, _ = out
    return svec(0.5 * (X + X.T)), y, "ipm: solved", rep.iterations


def _polish(W: NDArray, b: NDArray, q: NDArray, y: NDArray, n: int) -> tuple[NDArray, NDArray, int, str]:
    """Newton's method on ``W' q = b``, ``svec(Q Z + Z Q)/2 = 0`` (``Q = smat(q)``, ``Z = I -
    smat(W y)``) from Clarabel's point, until the residual stops decreasing (it reaches rounding in
    2-3 steps); ``(q, y, steps, "")`` or a reason for failure."""
    e = svec(np.eye(n))
    t, nc = W.shape
    best: tuple[float, NDArray, NDArray] | None = None
    for k in range(POLISH_MAX_ITER + 1):
        Q, Z = smat(q, n), smat(e - W @ y, n)
        r1 = W.T @ q - b
        r2 = 0.5 * svec(Q @ Z + Z @ Q)
        size = max(float(np.linalg.norm(Q)) * float(np.linalg.norm(Z)), NORM_FLOOR)
        res = max(float(np.linalg.norm(r1)), float(np.linalg.norm(r2)) / size)
        if not np.isfinite(res):
            return q, y, k, "the Newton polish produced non-finite values"
        if best is not None and res >= 0.5 * best[0]:   # stopped converging: rounding reached
            return best[1], best[2], k, ""
        best = (res, q, y)
        if res <= rounding_level(1, 1.0, POLISH_ROUNDING_FACTOR):
            return q, y, k, ""
        if k == POLISH_MAX_ITER:
            break
        J = np.zeros((t + nc, t + nc))
        J[:nc, :t] = W.T
        J[nc:, :t] = symmetric_product_matrix(Z)
        J[nc:, t:] = -symmetric_product_matrix(Q) @ W
        try:
            d = np.linalg.solve(J, -np.concatenate([r1, r2]))
        except np.linalg.LinAlgError:
            return q, y, k, ("the Newton system of the polish is singular (no strictly complementary "
                             "solution?)")
        q, y = q + d[:t], y + d[t:]
    assert best is not None   # set at the first iteration
    return best[1], best[2], POLISH_MAX_ITER, ""


def _truncated(Q: NDArray, Z: NDArray) -> tuple[NDArray, int]:
    """``(V V', rank)``: Q truncated to the eigenvectors where it is, relatively, larger than Z
    (strict complementarity: one of them vanishes in each direction), exactly PSD."""
    lam, U = np.linalg.eigh(0.5 * (Q + Q.T))
    zq = np.einsum("ij,ik,kj->j", U, Z, U)   # u_i' Z u_i
    nq = max(float(np.max(np.abs(lam))), NORM_FLOOR)
    nz = max(float(np.max(np.abs(zq))), NORM_FLOOR)
    keep = lam / nq > zq / nz
    V = U[:, keep] * np.sqrt(np.maximum(lam[keep], 0.0))
    return V @ V.T, int(np.sum(keep))


def _kkt(W: NDArray, b: NDArray, y: NDArray, Q: NDArray, Z: NDArray) -> dict[str, Any]:
    """The KKT test of ``(Q, y)`` (normalized units): Z PSD, complementarity, primal feasibility
    (dual feasibility is exact: Z is defined from y), and the relative duality gap."""
    zl = np.linalg.eigvalsh(0.5 * (Z + Z.T))
    nz = max(float(np.max(np.abs(zl))), NORM_FLOOR)
    nq = max(float(np.linalg.norm(Q)), NORM_FLOOR)
    nb = max(float(np.linalg.norm(b)), NORM_FLOOR)
    out = {"min_eig": float(zl[0]) / nz,
           "complementarity": float(np.linalg.norm(Q @ Z)) / (nq * float(np.linalg.norm(Z)) + NORM_FLOOR),
           "infeasibility": float(np.linalg.norm(W.T @ svec(Q) - b)) / nb,
           "gap": abs(float(np.trace(Q)) - float(b @ y)) / max(abs(float(np.trace(Q))), NORM_FLOOR)}
    out["passed"] = bool(out["min_eig"] >= -KKT_TOL and out["complementarity"] <= KKT_TOL
                         and out["infeasibility"] <= KKT_TOL)
    return out
