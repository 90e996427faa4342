"""The solve stage of :func:`optdesign.design.noise_estimation.estimate_noise` (internal): the reduced
least squares on ``Q, R >= 0`` (closed form where PSD, else the SDP of
:class:`~optdesign.formulate.als.ALSProgram` with a polish on its face), the identifiability test, the
optimal weighting of Rajamani & Rawlings (2009), the bootstrap and the independent checks.

References
----------
Rajamani, M. R. & Rawlings, J. B., Automatica 45(1) (2009) 142-148 (sec. 4: the weighting; Theorem 1:
uniqueness).  Odelson, B. J., Rajamani, M. R. & Rawlings, J. B., Automatica 42(2) (2006) 303-308.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.linalg
from numpy.typing import NDArray

from .._deadline import Deadline
from ..backends.cvxpy_backend import solve_cvxpy
from ..errors import ValidationError
from ..formulate import als
from ..results import Check, Stage, Status, Verification
from .verification import psd_check

__all__: list[str] = []

_EPS = float(np.finfo(float).eps)
#: largest data vector for which weighting="optimal" forms its (rows x rows) covariance
OPTIMAL_MAX_ROWS = 3000
#: SDP accuracy asked for: the problem is small (k unknowns), the tight tolerances cost a few iterations
#: and put the iterate within ~1e-5 of its face, which the polish then solves exactly
_SDP_ACCURACY = {"CLARABEL": {"tol_gap_rel": 1e-10, "tol_gap_abs": 1e-10, "tol_feas": 1e-10},
                 "SCS": {"eps": 1e-9}}


@dataclass(frozen=True)
class AlsSetup:
    """The discrete model the data follow and the unknowns' bases."""

    Ad: NDArray
    C: NDArray
    Bd: NDArray | None
    G: NDArray
    Q_basis: NDArray          # (kq, m, m)
    W_basis: NDArray          # (kq, n, n): discrete state-space covariance of each
    R_basis: NDArray          # (kr, p, p)
    Rd_basis: NDArray         # (kr, p, p): discrete
    dt: float
    continuous: bool
    q_diagonal: bool


# ------------------------------------------------------------------ solve
@dataclass
class AlsFit:
    theta: NDArray
    Q: NDArray
    R: NDArray
    stage: Stage
    status: Status
    native: str
    iterations: int | None


def _matrices(theta: NDArray, st: AlsSetup) -> tuple[NDArray, NDArray]:
    kq = st.Q_basis.shape[0]
    Q = np.tensordot(theta[:kq], st.Q_basis, 1)
    R = np.tensordot(theta[kq:], st.R_basis, 1)
    return Q, R


def als_coords(Q: NDArray, R: NDArray, st: AlsSetup) -> NDArray:
    """Coordinates of (Q, R) in the bases (upper-triangle entries; the diagonal for diagonal Q)."""
    tq = np.diag(Q) if st.q_diagonal else Q[np.triu_indices(Q.shape[0])]
    return np.concatenate([tq, R[np.triu_indices(R.shape[0])]])


def _psd_margin(X: NDArray) -> float:
    """``lambda_min(X) / max(||X||, tiny)``."""
    lam = np.linalg.eigvalsh(0.5 * (X + X.T))
    big = float(np.max(np.abs(lam))) if lam.size else 0.0
    return float(lam[0]) / big if big > 0 else 0.0


class AlsSolver:
    """The reduced problem of one weighting: ``min ||Rr theta - z||^2 + rho c' theta`` over
    ``Q, R >= 0`` -- closed form where that is PSD (``method="auto"``), else the SDP."""

    def __init__(self, Aw: NDArray, st: AlsSetup, rho: float, method: str, sdp_solver: str, full_rank: bool,
                 reusable: bool = False):
        self.Qr, self.Rr = np.linalg.qr(Aw)
        self.st, self.rho, self.method, self.sdp_solver = st, rho, method, sdp_solver
        self.full_rank, self.reusable = full_rank, reusable
        kq = st.Q_basis.shape[0]
        self.c = np.concatenate([np.trace(st.Q_basis, axis1=1, axis2=2), np.zeros(st.R_basis.shape[0])])
        self.kq = kq
        self.program: als.ALSProgram | None = None

    def unconstrained(self, z: NDArray) -> NDArray | None:
        if not self.full_rank:
            return None
        rhs = z
        if self.rho:
            rhs = z - (0.5 * self.rho) * scipy.linalg.solve_triangular(self.Rr, self.c, trans="T")
        return scipy.linalg.solve_triangular(self.Rr, rhs)

    def solve(self, bw: NDArray, deadline: Deadline) -> tuple[AlsFit, Stage | None]:
        """The fit for the weighted data ``bw`` and the closed-form stage it rejected (or None)."""
        z = self.Qr.T @ bw
        th = self.unconstrained(z)
        rejected = None
        if th is not None:
            Q, R = _matrices(th, self.st)
            mq, mr = _psd_margin(Q), _psd_margin(R)
            tol = -10 * max(Q.shape[0], R.shape[0]) * _EPS
            if self.method == "auto" and mq >= tol and mr >= tol:
                return AlsFit(th, Q, R, Stage("unconstrained_ls", "direct", "answered",
                                            "the least-squares solution is PSD: it is the SDP's optimum"),
                            Status.SOLVED, "solved", None), None
            rejected = Stage("unconstrained_ls", "direct", "rejected" if self.method == "auto" else "skipped",
                             f"lambda_min/||.||: Q {mq:.3g}, R {mr:.3g}" if self.method == "auto"
                             else "method='sdp'")
        return self._sdp(z, th, deadline), rejected

    def _sdp(self, z: NDArray, th: NDArray | None, deadline: Deadline) -> AlsFit:
        if self.program is None:
            st = self.st
            if th is not None:
                Q0, R0 = _matrices(th, st)
                sq = float(np.max(np.abs(np.diag(Q0)))) or 1.0
                sr = float(np.max(np.abs(np.diag(R0)))) or 1.0
            else:
                sq = sr = 1.0
            so = max(float(z @ z), _EPS)
            self.program = als.ALSProgram(self.Rr, st.Q_basis.shape[1], st.R_basis.shape[1], st.q_diagonal,
                                          self.rho, sq, sr, so, reusable=self.reusable)
        t0 = time.process_time()
        opts = dict(_SDP_ACCURACY.get(self.sdp_solver, {}), **deadline.sdp_options(self.sdp_solver))
        # the backend runs it: solver output captured, options checked, a solver failure a status
        report = solve_cvxpy(self.program.at(z), self.sdp_solver, opts)
        status, mapped = report.stats.native_status, report.status
        Q, R = (None, None) if status == "solver_error" else self.program.covariances()
        if Q is None or R is None:
            nan = np.full(len(self.c), np.nan)
            return AlsFit(nan, *_matrices(nan, self.st),
                        Stage(self.sdp_solver.lower(), "backend", mapped.value, status,
                              time.process_time() - t0),
                        mapped, status, report.stats.iterations)
        fit = AlsFit(als_coords(Q, R, self.st), Q, R,
                   Stage(self.sdp_solver.lower(), "backend", "answered", status, time.process_time() - t0),
                   mapped, status, report.stats.iterations)
        return self._polish(fit, z)

    def _objective(self, th: NDArray, z: NDArray) -> float:
        r = self.Rr @ th - z
        return float(r @ r) + self.rho * float(self.c @ th)

    def _polish(self, fit: AlsFit, z: NDArray) -> AlsFit:
        """Solve the least squares on the face of the cone the SDP found (Q = V S V', R = U T U' with
        the eigenvectors of the eigenvalues above a threshold times the largest; diagonal Q: its
        entries above it) in closed form, for thresholds ``1e-8 .. 1e-3`` (an interior-point iterate
        sits ``O(sqrt(gap))`` inside the cone); keep the best candidate that is PSD and fits no
        worse -- the exact optimum on the face instead of the iterate."""
        st = self.st
        best, best_obj, best_rank = None, self._objective(fit.theta, z) + _EPS, 0
        tol = -10 * max(fit.Q.shape[0], fit.R.shape[0]) * _EPS
        for thr in (1e-8, 1e-6, 1e-4, 1e-3):
            FQ, FR = _face(fit.Q, thr, st.q_diagonal), _face(fit.R, thr, False)
            if FQ.shape[0] + FR.shape[0] == 0:
                continue
            F = scipy.linalg.block_diag(FQ.T, FR.T)                    # theta = F s
            M = self.Rr @ F
            s, *_ = np.linalg.lstsq(M, z - 0.5 * self.rho * np.linalg.pinv(M.T) @ (F.T @ self.c), rcond=None)
            th = F @ s
            Q, R = _matrices(th, st)
            obj = self._objective(th, z)
            if _psd_margin(Q) >= tol and _psd_margin(R) >= tol and obj <= best_obj:
                best, best_obj, best_rank = th, obj, F.shape[1]
        if best is None:
            return fit
        Q, R = _matrices(best, st)
        stage = Stage(fit.stage.name + "+polish", fit.stage.kind, "answered",
                      f"{fit.stage.detail}; polished on a face of dimension {best_rank}", fit.stage.time)
        return AlsFit(best, 0.5 * (Q + Q.T), 0.5 * (R + R.T), stage, fit.status, fit.native, fit.iterations)


def _face(X: NDArray, thr: float, diagonal: bool) -> NDArray:
    """Coordinates (rows) of a basis of the face of the cone at X: ``V E V'`` with V the eigenvectors
    of the eigenvalues above ``thr`` times the largest and E the symmetric unit matrices (a diagonal
    X: the unit vectors of its entries above it)."""
    k = X.shape[0]
    if diagonal:
        d = np.diag(X)
        return np.eye(k)[d > thr * max(float(np.max(d)), _EPS)]
    lam, U = np.linalg.eigh(0.5 * (X + X.T))
    big = float(lam[-1]) if lam.size else 0.0
    V = U[:, lam > thr * big] if big > 0 else U[:, :0]
    if V.shape[1] == 0:
        return np.zeros((0, k * (k + 1) // 2))
    B = np.einsum("ia,tab,jb->tij", V, als.symmetric_basis(V.shape[1], "full"), V)
    iu = np.triu_indices(k)
    return B[:, iu[0], iu[1]]


def _whiten(S: NDArray) -> NDArray:
    """A lower-triangular factor of S (eigenvalues clipped at ``rows eps max(lambda)``)."""
    lam, U = np.linalg.eigh(S)
    floor = S.shape[0] * _EPS * float(lam[-1])
    Sreg = (U * np.maximum(lam, floor)) @ U.T
    return np.linalg.cholesky(0.5 * (Sreg + Sreg.T))


def _unknown_names(st: AlsSetup) -> list[str]:
    m, p = st.Q_basis.shape[1], st.R_basis.shape[1]
    qn = [f"Q[{i},{i}]" for i in range(m)] if st.q_diagonal else \
        [f"Q[{i},{j}]" for i, j in zip(*np.triu_indices(m), strict=True)]
    return qn + [f"R[{i},{j}]" for i, j in zip(*np.triu_indices(p), strict=True)]


def identifiability_check(A: NDArray, st: AlsSetup, rho: float, lags: int,
                     q_structure: Any) -> tuple[int, float, bool]:
    """``(rank, condition, full_rank)`` of the ALS matrix with unit-norm columns; raises
    ValidationError (naming ``q_structure``) when it is rank deficient and no trace penalty picks
    one of the fits."""
    rows, k = A.shape
    norms = np.linalg.norm(A, axis=0)
    An = A / np.where(norms > 0, norms, 1.0)
    U, sv, Vt = np.linalg.svd(An, full_matrices=False)
    tol = max(rows, k) * _EPS * float(sv[0]) if sv.size else 0.0
    rank = int(np.sum(sv > tol)) if sv.size else 0
    if np.any(norms == 0):
        rank = min(rank, int(np.sum(norms > 0)))
    full = rank == k
    cond = float(sv[0] / sv[-1]) if sv.size and sv[-1] > 0 and rows >= k else float("inf")
    if not full and rho == 0.0:
        names = _unknown_names(st)
        v = Vt[-1]
        if rows < k:
            reason = f"there are {k} unknowns but only {rows} autocovariance entries (lags = {lags})"
        else:
            big = np.argsort(-np.abs(v))[:4]
            combo = " ".join(f"{v[i]:+.2g}*{names[i]}" for i in big if abs(v[i]) > 1e-3)
            reason = (f"the ALS matrix has rank {rank} < {k} unknowns (smallest singular value "
                      f"{sv[-1]:.3g} of {sv[0]:.3g}); the data cannot tell apart the direction {combo}")
        structure = q_structure if isinstance(q_structure, str) else "a G matrix"
        raise ValidationError(
            f"q_structure={structure!r} is not identifiable from these data: {reason}. Use fewer unknowns "
            f"(q_structure='diagonal' or a G matrix with fewer columns), more lags, or trace_penalty > 0 "
            f"to pick the smallest-trace Q among the fits")
    return rank, cond, full


def _projected_gradient(Aw: NDArray, bw: NDArray, fit: AlsFit, st: AlsSetup, rho: float) -> float:
    """Relative fixed-point residual of the projected gradient step on ``Q, R >= 0`` (zero at the
    optimum of the convex problem): ``||X - Proj(X - t grad)|| / max(||X||, t ||grad(0)||)``,
    ``t = 1 / (2 ||A_w||^2)``; computed from the full weighted data, independently of the solver."""
    kq = st.Q_basis.shape[0]
    g = 2.0 * Aw.T @ (Aw @ fit.theta - bw)
    g[:kq] += rho * np.trace(st.Q_basis, axis1=1, axis2=2)
    # Frobenius gradients: <G, dX> = sum g_i dtheta_i with dX = sum dtheta_i E_i
    wq = np.einsum("kij,kij->k", st.Q_basis, st.Q_basis)
    wr = np.einsum("kij,kij->k", st.R_basis, st.R_basis)
    GQ = np.tensordot(g[:kq] / wq, st.Q_basis, 1)
    GR = np.tensordot(g[kq:] / wr, st.R_basis, 1)
    t = 0.5 / float(np.linalg.norm(Aw, 2)) ** 2

    def proj(X: NDArray, diag: bool) -> NDArray:
        if diag:
            return np.diag(np.maximum(np.diag(X), 0.0))
        lam, U = np.linalg.eigh(0.5 * (X + X.T))
        return (U * np.maximum(lam, 0.0)) @ U.T

    dq = fit.Q - proj(fit.Q - t * GQ, st.q_diagonal)
    dr = fit.R - proj(fit.R - t * GR, False)
    g0 = 2.0 * Aw.T @ bw
    scale = max(float(np.hypot(np.linalg.norm(fit.Q), np.linalg.norm(fit.R))), t * float(np.linalg.norm(g0)),
                _EPS)
    return float(np.hypot(np.linalg.norm(dq), np.linalg.norm(dr))) / scale


def weight_optimally(A: NDArray, b: NDArray, fit: AlsFit, st: AlsSetup, ctx: dict[str, Any],
                       deadline: Deadline
                       ) -> tuple[AlsFit, AlsSolver | None, NDArray | None, dict[str, Any], list[Stage]]:
    """Rajamani & Rawlings (2009) sec. 4: weight ``S(theta_k)^-1`` until the estimate settles."""
    rows = A.shape[0]
    if rows > OPTIMAL_MAX_ROWS:
        raise ValidationError(
            f"weighting='optimal' forms the ({rows} x {rows}) covariance of the autocovariance data "
            f"(p (p + 1)/2 + (lags - 1) p^2 rows), more than {OPTIMAL_MAX_ROWS}: use fewer lags or "
            f"weighting='identity'")
    Abar, C, L, lags, counts = ctx["Abar"], st.C, ctx["L"], ctx["lags"], ctx["counts"]
    changes: list[float] = []
    stages: list[Stage] = []
    solver, Lc, converged = None, None, False
    for _ in range(ctx["max_iter"]):
        if deadline.expired:
            break
        kq = st.Q_basis.shape[0]
        W = np.tensordot(fit.theta[:kq], st.W_basis, 1)
        Rd = np.tensordot(fit.theta[kq:], st.Rd_basis, 1)
        S = als.bartlett_covariance(Abar, C, L, W, Rd, lags, counts)
        Lc = _whiten(S)
        Aw = scipy.linalg.solve_triangular(Lc, A, lower=True)
        bw = scipy.linalg.solve_triangular(Lc, b, lower=True)
        solver = AlsSolver(Aw, st, ctx["rho"], ctx["method"], ctx["sdp_solver"], ctx["full_rank"],
                         reusable=ctx["reusable"])
        new, rejected = solver.solve(bw, deadline)
        if not np.all(np.isfinite(new.theta)):
            stages.append(new.stage)
            break
        change = float(np.linalg.norm(new.theta - fit.theta)) / max(float(np.linalg.norm(fit.theta)), _EPS)
        changes.append(change)
        fit = new
        if change <= ctx["tol"]:
            converged = True
            break
    report: dict[str, Any] = {"iterations": len(changes), "converged": converged, "changes": changes}
    return fit, solver, Lc, report, stages


def run_bootstrap(solver: AlsSolver, Lc: NDArray | None, seg_sums: NDArray, seg_counts: NDArray, mask: NDArray,
               B: int, level: float, rng: np.random.Generator, deadline: Deadline) -> dict[str, Any]:
    """Percentile intervals of (Q, R) from ``B`` re-solves on resampled segments of the record."""
    nseg = seg_sums.shape[0]
    Qs, Rs = [], []
    for _ in range(B):
        if deadline.expired:
            break
        idx = rng.integers(0, nseg, nseg)
        c = seg_counts[idx].sum(0)
        bb = (seg_sums[idx].sum(0) / c[:, None, None]).reshape(-1)[mask]
        bw = bb if Lc is None else scipy.linalg.solve_triangular(Lc, bb, lower=True)
        fit, _ = solver.solve(bw, deadline)
        if np.all(np.isfinite(fit.theta)):
            Qs.append(fit.Q)
            Rs.append(fit.R)
    if not Qs:
        return {"level": level, "replicates": 0, "segments": nseg}
    Qa, Ra = np.array(Qs), np.array(Rs)
    lo, hi = 50 * (1 - level), 50 * (1 + level)
    return {"level": level, "replicates": len(Qs), "segments": nseg,
            "Q_low": np.percentile(Qa, lo, axis=0), "Q_high": np.percentile(Qa, hi, axis=0),
            "R_low": np.percentile(Ra, lo, axis=0), "R_high": np.percentile(Ra, hi, axis=0),
            "Q_std": Qa.std(0, ddof=1) if len(Qs) > 1 else np.zeros_like(Qa[0]),
            "R_std": Ra.std(0, ddof=1) if len(Rs) > 1 else np.zeros_like(Ra[0])}


def estimate_checks(Aw: NDArray, bw: NDArray, fit: AlsFit, st: AlsSetup, rho: float, cond: float) -> Verification:
    """Independent checks: Q and R PSD, and the projected-gradient optimality residual."""
    direct = fit.stage.kind == "direct"
    err = 0.0 if direct else 1e-7             # Clarabel's default relative gap tolerance 1e-8, x10
    pg = _projected_gradient(Aw, bw, fit, st, rho)
    k = fit.theta.size
    pg_tol = (1e-6 if not direct else 0.0) + 100.0 * k * _EPS * min(cond, 1.0 / _EPS)
    return Verification.of([
        psd_check("Q_min_eig", fit.Q, error=err, what="Q"),
        psd_check("R_min_eig", fit.R, error=err, what="R"),
        Check.at_most("projected_gradient", pg, pg_tol,
                      "||X - Proj_psd(X - t grad f)|| / scale: first-order optimality on Q, R >= 0"),
    ])
