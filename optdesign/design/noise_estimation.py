r"""Noise covariances from data: autocovariance least squares (ALS) as a semidefinite program.

``estimate_noise(plant, y)`` answers *which Q and R does my data say?*  The innovations of any
stable (suboptimal) filter gain L have autocovariances that are linear in (Q, R)
(:mod:`optdesign.formulate.als`), so (Q, R) follow from a least-squares problem; with ``Q >= 0``,
``R >= 0`` imposed it is a small SDP (cvxpy + Clarabel), and where the plain least-squares
solution is already positive semidefinite it *is* the SDP's optimum (route ``unconstrained_ls``).

* Discrete plants directly; a continuous plant through its sampling at ``dt`` (``kalmd``'s
  model: ``Qd = int_0^dt e^(A t) G Q G' e^(A' t) dt`` by Van Loan's exponential, ``Rd = R / dt``),
  the estimate returned in continuous units.
* ``q_structure``: a full or diagonal Q (m x m, through the plant's G) or a G matrix of one's own
  (Q its full g x g covariance); R is full.  Identifiability is checked: the ALS matrix of the
  structure must have full column rank (Odelson et al. 2006, Lemma 4; Rajamani & Rawlings 2009,
  Theorem 1); otherwise a :class:`~optdesign.errors.ValidationError` names the reason --
  never a silent minimum-norm answer.  With ``trace_penalty > 0`` a rank-deficient Q part is
  allowed: the penalty picks the smallest-trace Q among the fits (the disturbance structure of
  Rajamani & Rawlings 2009, sec. 5).
* ``weighting="optimal"``: the iterative scheme of Rajamani & Rawlings (2009, sec. 4) -- solve,
  compute the covariance S of the autocovariance data for the current estimate (Bartlett's
  formula for Gaussian innovations), re-solve with weight ``S^-1``, until the estimate stops
  moving; the iterations and the relative changes are reported.
* ``bootstrap=B``: confidence intervals from B re-solves on resampled data segments (moving
  blocks of the innovation record; only the right-hand side of the reduced problem changes).

The autocovariances are computed once, streamed over chunks of bounded size
(:class:`~optdesign.formulate.als.AutocovAccumulator`; direct products for few lags, FFT for
many), so records of 10^6 samples and more are handled in bounded memory.

References
----------
Odelson, B. J., Rajamani, M. R. & Rawlings, J. B., Automatica 42(2) (2006) 303-308.
Rajamani, M. R. & Rawlings, J. B., Automatica 45(1) (2009) 142-148.
Lima, F. V., Rajamani, M. R., Rawlings, J. B. & Eaton, J. W., the ALS package (GNU Octave / MATLAB),
version 4.0 (2010): ``als_sdp_mrQ.m`` and its examples ``motivating_example.m``, ``simulate_data8.m``.
Van Loan, C. F., IEEE TAC 23(3) (1978) 395-404.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
import scipy.linalg
from numpy.typing import ArrayLike, NDArray

from .._deadline import Deadline
from .._validate import as_int, as_matrix, as_positive_float, as_rng, as_str
from ..errors import ValidationError
from ..formulate import als
from ..model.coerce import as_plant
from ..model.plant import Plant
from ..results import Check, DesignResult, SolverStats, Stage, Status, Route, Verification
from ..solvers.status import CVXPY_STATUS
from .verification import psd_check

__all__ = ["NoiseEstimate", "estimate_noise", "simulate_outputs"]

_EPS = float(np.finfo(float).eps)
#: largest data vector for which weighting="optimal" forms its (rows x rows) covariance
OPTIMAL_MAX_ROWS = 3000
#: samples per autocovariance lag the data must hold (each lag averages >= 90 % of the record)
SAMPLES_PER_LAG = 10
#: SDP accuracy asked for: the problem is small (k unknowns), the tight tolerances cost a few iterations
#: and put the iterate within ~1e-5 of its face, which the polish then solves exactly
_SDP_ACCURACY = {"CLARABEL": {"tol_gap_rel": 1e-10, "tol_gap_abs": 1e-10, "tol_feas": 1e-10},
                 "SCS": {"eps": 1e-9}}


@dataclass(frozen=True, kw_only=True, eq=False)
class NoiseEstimate(DesignResult):
    """Noise covariances estimated from data by autocovariance least squares.

    Attributes
    ----------
    Q : (m, m) ndarray or None
        Process-noise covariance (through ``G``; continuous units for a continuous plant).
    R : (p, p) ndarray or None
        Measurement-noise covariance (continuous plant: ``Rd dt``, as ``kalmd`` reads it).
    G : (n, m) ndarray
        The process-noise input matrix Q goes with (the plant's, or ``q_structure``'s).
    Qd : (n, n) ndarray or None
        The discrete state-space process-noise covariance of the estimate (``G Q G'``, or Van
        Loan's integral for a continuous plant).
    Rd : (p, p) ndarray or None
        The discrete measurement-noise covariance (``R``, or ``R / dt``).
    residual : float
        ``||A theta - b||_W / ||b||_W``: the relative weighted residual of the fit, recomputed on
        the full (unreduced) ALS data.
    condition : float
        2-norm condition number of the weighted ALS matrix with unit-norm columns.
    rank : int
        Its numerical rank; ``n_unknowns`` the number of columns.
    n_unknowns : int
    lags : int
    n_samples : int
        Innovations used (after the burn-in).
    L : (n, p) ndarray
        The stable predictor gain whose innovations were used.
    plant : Plant
        The plant as given (continuous or discrete).
    dt : float
        Sampling period of the data.
    weighting : str
    weighting_report : dict
        ``iterations``, ``converged``, ``changes`` (relative change of the estimate per
        iteration) of ``weighting="optimal"``; ``{}`` for identity weighting.
    confidence : dict or None
        With ``bootstrap``: ``level``, ``replicates``, ``segments``, ``Q_low``, ``Q_high``,
        ``R_low``, ``R_high`` (percentile intervals), ``Q_std``, ``R_std``.
    autocov : (lags, p, p) ndarray
        The sample autocovariances of the innovations (lag 0 first).
    """

    Q: NDArray[np.float64] | None
    R: NDArray[np.float64] | None
    G: NDArray[np.float64]
    Qd: NDArray[np.float64] | None
    Rd: NDArray[np.float64] | None
    residual: float
    condition: float
    rank: int
    n_unknowns: int
    lags: int
    n_samples: int
    L: NDArray[np.float64]
    plant: Plant
    dt: float
    weighting: str = "identity"
    weighting_report: dict[str, Any] = field(default_factory=dict)
    confidence: dict[str, Any] | None = None
    autocov: NDArray[np.float64] | None = field(default=None, repr=False)
    _summary_fields: tuple[str, ...] = field(
        default=("Q", "R", "residual", "condition", "rank", "n_unknowns", "lags", "n_samples", "weighting"),
        init=False, repr=False)

    def estimated_plant(self) -> Plant:
        """The plant with the estimated ``G``, ``Q`` and ``R`` (raises when R is singular: a Kalman
        filter needs ``R > 0``)."""
        if self.Q is None or self.R is None:
            raise ValidationError(f"no estimate to build a plant from (status {Status(self.status).value})")
        return self.plant.replace(G=self.G, Q=self.Q, R=self.R)

    def kalman(self, **options: Any) -> Any:
        """The steady-state Kalman filter of the estimated covariances: :func:`~optdesign.kalman`
        for a discrete plant, :func:`~optdesign.kalmd` at ``dt`` for a continuous one."""
        from .kalman import kalman, kalmd

        plant = self.estimated_plant()
        return kalmd(plant, self.dt, **options) if not plant.is_discrete else kalman(plant, **options)

    def __repr__(self) -> str:
        return (f"NoiseEstimate(n={self.plant.n}, p={self.plant.p}, lags={self.lags}, "
                f"samples={self.n_samples}, status={Status(self.status).value!r}, success={self.success}, "
                f"residual={self.residual:.2e}, condition={self.condition:.2e})")


# ------------------------------------------------------------------ input
@dataclass(frozen=True)
class _Setup:
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


def _q_basis(plant: Plant, q_structure: Any) -> tuple[NDArray, NDArray, bool]:
    """``(G, basis of Q, diagonal?)`` for ``q_structure``."""
    if isinstance(q_structure, str):
        s = as_str("q_structure", q_structure, ("full", "diagonal"))
        return plant.G, als.symmetric_basis(plant.m, s), s == "diagonal"
    G = as_matrix("q_structure", q_structure, (plant.n, None))
    if G.shape[1] == 0:
        raise ValidationError(f"q_structure as a G matrix needs at least one column; found shape {G.shape}")
    return G, als.symmetric_basis(G.shape[1], "full"), False


def _setup(plant: Plant, q_structure: Any, dt: Any) -> _Setup:
    from .kalman import van_loan

    G, Qb, diag = _q_basis(plant, q_structure)
    Rb = als.symmetric_basis(plant.p, "full")
    if plant.is_discrete:
        if dt is not None and not math.isclose(as_positive_float("dt", dt), float(plant.dt)):
            raise ValidationError(f"dt = {dt!r} differs from the discrete plant's own dt = {plant.dt:g}; "
                                  f"leave dt out for a discrete plant")
        Wb = np.einsum("ia,kab,jb->kij", G, Qb, G)
        return _Setup(plant.A, plant.C, plant.B, G, Qb, Wb, Rb, Rb, float(plant.dt), False, diag)
    if dt is None:
        raise ValidationError("the plant is continuous: give dt, the sampling period of the data (the plant is "
                              "sampled as kalmd does: Qd by Van Loan's integral, Rd = R / dt)")
    Ts = as_positive_float("dt", dt)
    Ad = scipy.linalg.expm(plant.A * Ts)
    Wb = np.stack([van_loan(plant.A, G @ E @ G.T, Ts)[1] for E in Qb])
    Bd = None
    if plant.B is not None:
        n, nu = plant.n, plant.B.shape[1]
        Z = np.zeros((n + nu, n + nu))
        Z[:n, :n], Z[:n, n:] = plant.A, plant.B
        Bd = scipy.linalg.expm(Z * Ts)[:n, n:]
    return _Setup(Ad, plant.C, Bd, G, Qb, Wb, Rb, Rb / Ts, Ts, True, diag)


def _spectral_radius(F: NDArray) -> float:
    return float(np.max(np.abs(np.linalg.eigvals(F))))


def _default_gain(plant: Plant, st: _Setup) -> tuple[NDArray, str]:
    """The plant's own discrete Kalman gain when it has Q and R, else the DARE gain of unit
    weights (``W = I``, ``R = I``): stable whenever (A, C) is detectable."""
    n, p = plant.n, plant.p
    if plant.has_noise_model:
        Rq = plant.R if not st.continuous else plant.R / st.dt
        W = plant.process_noise() if not st.continuous else _van_loan_W(plant, st.dt)
        source = "the plant's own Kalman gain (its Q and R)"
    else:
        W, Rq = np.eye(n), np.eye(p)
        source = "the Kalman gain of unit weights (W = I, R = I)"
    try:
        P = scipy.linalg.solve_discrete_are(st.Ad.T, st.C.T, W, Rq)
    except (np.linalg.LinAlgError, ValueError) as exc:
        raise ValidationError(f"no default stable gain: the discrete Riccati equation of {source} has no "
                              f"stabilizing solution ({exc}); give L (an (n, p) gain with A - L C stable)") from None
    L = st.Ad @ P @ st.C.T @ np.linalg.inv(st.C @ P @ st.C.T + Rq)
    return L, source


def _van_loan_W(plant: Plant, Ts: float) -> NDArray:
    from .kalman import van_loan

    return van_loan(plant.A, plant.process_noise(), Ts)[1]


def _as_data(name: str, X: ArrayLike, cols: int, what: str) -> NDArray:
    arr = as_matrix(name, X, (None, cols))
    return np.ascontiguousarray(arr, dtype=float)


def _check_gain(L: Any, st: _Setup, n: int, p: int) -> NDArray:
    L = as_matrix("L", L, (n, p))
    rho = _spectral_radius(st.Ad - L @ st.C)
    if not rho < 1.0 - 10 * n * _EPS:
        raise ValidationError(f"L must make the discrete error dynamics A - L C stable (spectral radius < 1); "
                              f"found spectral radius {rho:.6g}")
    return L


def _lags_and_burn(lags: Any, rho: float, n_total: int, burn_in: Any, n: int) -> tuple[int, int]:
    """The burn-in (steps for the filter's start-up transient to fall to sqrt(eps): rho^k <= 1.5e-8)
    and the lags; errors name ``y`` (too short) or ``lags`` (too many for the data)."""
    if burn_in is None:
        burn = 0 if rho == 0.0 else int(math.ceil(math.log(math.sqrt(_EPS)) / math.log(rho)))
    else:
        burn = as_int("burn_in", burn_in, 0)
    usable = n_total - burn
    if lags is None:
        N = max(15, 2 * n)
        if usable < SAMPLES_PER_LAG * N:
            raise ValidationError(
                f"y is too short: {n_total} samples, of which {burn} are the filter's start-up (burn_in); "
                f"the default lags = {N} need at least {burn + SAMPLES_PER_LAG * N} samples")
        return N, burn
    N = as_int("lags", lags, 1)
    if usable < SAMPLES_PER_LAG * N:
        raise ValidationError(
            f"lags = {N} is too large for the data: {n_total} samples ({usable} after the burn-in of {burn}) "
            f"allow at most lags = {max(0, usable // SAMPLES_PER_LAG)} ({SAMPLES_PER_LAG} samples per lag)")
    return N, burn


# ------------------------------------------------------------------ data
def _stream(filt: als.InnovationFilter, acc: als.AutocovAccumulator, y: NDArray, u: NDArray | None,
            burn: int, segments: int) -> tuple[NDArray, NDArray]:
    """Run the filter over the record in bounded chunks, feeding the innovations after the burn-in to
    the accumulator; return the per-segment sums (segments, lags, p, p) and counts (segments, lags)."""
    total = y.shape[0]
    chunk = acc.chunk_length()
    k = 0
    while k < burn:                                            # start-up: filtered, not used
        j = min(burn, k + chunk)
        filt.run(y[k:j], None if u is None else u[k:j])
        k = j
    bounds = np.linspace(burn, total, segments + 1).round().astype(int)
    sums = np.zeros((segments, acc.lags, acc.p, acc.p))
    counts = np.zeros((segments, acc.lags))
    for s in range(segments):
        k = bounds[s]
        while k < bounds[s + 1]:
            j = min(bounds[s + 1], k + chunk)
            e = filt.run(y[k:j], None if u is None else u[k:j])
            ss, cc = acc.push(e)
            sums[s] += ss
            counts[s] += cc
            k = j
    return sums, counts


# ------------------------------------------------------------------ solve
@dataclass
class _Fit:
    theta: NDArray
    Q: NDArray
    R: NDArray
    stage: Stage
    status: Status
    native: str
    iterations: int | None


def _matrices(theta: NDArray, st: _Setup) -> tuple[NDArray, NDArray]:
    kq = st.Q_basis.shape[0]
    Q = np.tensordot(theta[:kq], st.Q_basis, 1)
    R = np.tensordot(theta[kq:], st.R_basis, 1)
    return Q, R


def _coords(Q: NDArray, R: NDArray, st: _Setup) -> NDArray:
    """Coordinates of (Q, R) in the bases (upper-triangle entries; the diagonal for diagonal Q)."""
    tq = np.diag(Q) if st.q_diagonal else Q[np.triu_indices(Q.shape[0])]
    return np.concatenate([tq, R[np.triu_indices(R.shape[0])]])


def _psd_margin(X: NDArray) -> float:
    """``lambda_min(X) / max(||X||, tiny)``."""
    lam = np.linalg.eigvalsh(0.5 * (X + X.T))
    big = float(np.max(np.abs(lam))) if lam.size else 0.0
    return float(lam[0]) / big if big > 0 else 0.0


class _Solver:
    """The reduced problem of one weighting: ``min ||Rr theta - z||^2 + rho c' theta`` over
    ``Q, R >= 0`` -- closed form where that is PSD (``method="auto"``), else the SDP."""

    def __init__(self, Aw: NDArray, st: _Setup, rho: float, method: str, sdp_solver: str, full_rank: bool):
        self.Qr, self.Rr = np.linalg.qr(Aw)
        self.st, self.rho, self.method, self.sdp_solver = st, rho, method, sdp_solver
        self.full_rank = full_rank
        kq = st.Q_basis.shape[0]
        self.c = np.concatenate([np.trace(st.Q_basis, axis1=1, axis2=2), np.zeros(st.R_basis.shape[0])])
        self.kq = kq
        self.program: als.ALSProgram | None = None

    def unconstrained(self, z: NDArray) -> NDArray | None:
        if not self.full_rank:
            return None
        rhs = z - (0.5 * self.rho) * scipy.linalg.solve_triangular(self.Rr, self.c, trans="T") if self.rho else z
        return scipy.linalg.solve_triangular(self.Rr, rhs)

    def solve(self, bw: NDArray, deadline: Deadline) -> tuple[_Fit, Stage | None]:
        """The fit for the weighted data ``bw`` and the closed-form stage it rejected (or None)."""
        z = self.Qr.T @ bw
        th = self.unconstrained(z)
        rejected = None
        if th is not None:
            Q, R = _matrices(th, self.st)
            mq, mr = _psd_margin(Q), _psd_margin(R)
            tol = -10 * max(Q.shape[0], R.shape[0]) * _EPS
            if self.method == "auto" and mq >= tol and mr >= tol:
                return _Fit(th, Q, R, Stage("unconstrained_ls", "direct", "answered",
                                            "the least-squares solution is PSD: it is the SDP's optimum"),
                            Status.SOLVED, "solved", None), None
            rejected = Stage("unconstrained_ls", "direct", "rejected" if self.method == "auto" else "skipped",
                             f"lambda_min/||.||: Q {mq:.3g}, R {mr:.3g}" if self.method == "auto"
                             else "method='sdp'")
        return self._sdp(z, th, deadline), rejected

    def _sdp(self, z: NDArray, th: NDArray | None, deadline: Deadline) -> _Fit:
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
                                          self.rho, sq, sr, so)
        t0 = time.process_time()
        opts = dict(_SDP_ACCURACY.get(self.sdp_solver, {}), **deadline.sdp_options(self.sdp_solver))
        status, Q, R, info = self.program.solve(z, self.sdp_solver, opts)
        mapped = CVXPY_STATUS.get(status, Status.SOLVER_ERROR)
        if Q is None or R is None:
            nan = np.full(len(self.c), np.nan)
            return _Fit(nan, *_matrices(nan, self.st),
                        Stage(self.sdp_solver.lower(), "backend", mapped.value, status, time.process_time() - t0),
                        mapped, status, info["iterations"])
        fit = _Fit(_coords(Q, R, self.st), Q, R,
                   Stage(self.sdp_solver.lower(), "backend", "answered", status, time.process_time() - t0),
                   mapped, status, info["iterations"])
        return self._polish(fit, z)

    def _objective(self, th: NDArray, z: NDArray) -> float:
        r = self.Rr @ th - z
        return float(r @ r) + self.rho * float(self.c @ th)

    def _polish(self, fit: _Fit, z: NDArray) -> _Fit:
        """Solve the least squares on the face of the cone the SDP found (Q = V S V', R = U T U' with
        the eigenvectors of the eigenvalues above a threshold times the largest; diagonal Q: its
        entries above it) in closed form, for thresholds ``1e-8 .. 1e-3`` (an interior-point iterate
        sits ``O(sqrt(gap))`` inside the cone); keep the best candidate that is PSD and fits no
        worse -- the exact optimum on the face instead of the iterate."""
        st = self.st
        best, best_obj, best_rank = None, self._objective(fit.theta, z) + _EPS, 0
        tol = -10 * max(fit.Q.shape[0], fit.R.shape[0]) * _EPS
        for thr in (1e-8, 1e-6, 1e-4, 1e-3):
            cols = []
            if st.q_diagonal:
                dq = np.diag(fit.Q)
                for i in np.flatnonzero(dq > thr * max(float(np.max(dq)), _EPS)):
                    cols.append(_coords(np.diag(np.eye(len(dq))[i]), np.zeros_like(fit.R), st))
            else:
                cols += [_coords(X, np.zeros_like(fit.R), st) for X in _face_basis(fit.Q, thr)]
            cols += [_coords(np.zeros_like(fit.Q), X, st) for X in _face_basis(fit.R, thr)]
            if not cols:
                continue
            F = np.array(cols).T                                       # theta = F s
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
        return _Fit(best, 0.5 * (Q + Q.T), 0.5 * (R + R.T), stage, fit.status, fit.native, fit.iterations)


def _face_basis(X: NDArray, thr: float) -> list[NDArray]:
    """Basis ``V E V'`` of the face of the PSD cone at X (V: eigenvectors of the eigenvalues above
    ``thr`` times the largest; E the symmetric unit matrices)."""
    lam, U = np.linalg.eigh(0.5 * (X + X.T))
    big = float(lam[-1]) if lam.size else 0.0
    V = U[:, lam > thr * big] if big > 0 else U[:, :0]
    r = V.shape[1]
    return [V @ E @ V.T for E in als.symmetric_basis(r, "full")] if r else []


def _whiten(S: NDArray) -> NDArray:
    """A lower-triangular factor of S (eigenvalues clipped at ``rows eps max(lambda)``)."""
    lam, U = np.linalg.eigh(S)
    floor = S.shape[0] * _EPS * float(lam[-1])
    Sreg = (U * np.maximum(lam, floor)) @ U.T
    return np.linalg.cholesky(0.5 * (Sreg + Sreg.T))


def _unknown_names(st: _Setup) -> list[str]:
    m, p = st.Q_basis.shape[1], st.R_basis.shape[1]
    qn = [f"Q[{i},{i}]" for i in range(m)] if st.q_diagonal else \
        [f"Q[{i},{j}]" for i, j in zip(*np.triu_indices(m), strict=True)]
    return qn + [f"R[{i},{j}]" for i, j in zip(*np.triu_indices(p), strict=True)]


def _identifiability(A: NDArray, st: _Setup, rho: float, lags: int, q_structure: Any) -> tuple[int, float, bool]:
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
        v = Vt[-1] if rows >= k else Vt[-1]
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


def _projected_gradient(Aw: NDArray, bw: NDArray, fit: _Fit, st: _Setup, rho: float) -> float:
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


def _optimal_weighting(A: NDArray, b: NDArray, fit: _Fit, st: _Setup, ctx: dict[str, Any],
                       deadline: Deadline) -> tuple[_Fit, _Solver, NDArray | None, dict[str, Any], list[Stage]]:
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
        solver = _Solver(Aw, st, ctx["rho"], ctx["method"], ctx["sdp_solver"], ctx["full_rank"])
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
    report = {"iterations": len(changes), "converged": converged, "changes": changes}
    return fit, solver, Lc, report, stages


def _bootstrap(solver: _Solver, Lc: NDArray | None, seg_sums: NDArray, seg_counts: NDArray, mask: NDArray,
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


def _checks(Aw: NDArray, bw: NDArray, fit: _Fit, st: _Setup, rho: float, cond: float) -> Verification:
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


# ------------------------------------------------------------------ the verb
def estimate_noise(
    plant: Plant | Any,
    y: ArrayLike,
    u: ArrayLike | None = None,
    *,
    L: ArrayLike | None = None,
    lags: int | None = None,
    q_structure: Literal["full", "diagonal"] | ArrayLike = "full",
    weighting: Literal["identity", "optimal"] = "identity",
    trace_penalty: float = 0.0,
    dt: float | None = None,
    method: Literal["auto", "sdp"] = "auto",
    sdp_solver: Literal["CLARABEL", "SCS"] = "CLARABEL",
    burn_in: int | None = None,
    bootstrap: int | None = None,
    confidence: float = 0.9,
    max_iter: int = 20,
    tol: float = 1e-4,
    seed: int | None = None,
    time_limit: float | None = None,
) -> NoiseEstimate:
    r"""Process- and measurement-noise covariances from output data, by autocovariance least squares.

    Runs the filter of a stable gain L over the record, takes the sample autocovariances of its
    innovations at lags ``0 .. lags-1`` and fits the model's autocovariances, which are linear in
    (Q, R) (:mod:`optdesign.formulate.als`), subject to ``Q >= 0``, ``R >= 0``::

        minimize  || W^(1/2) (A_Q theta_Q + A_R theta_R - b) ||^2 + rho tr(Q)
        subject to  Q(theta_Q) >= 0,  R(theta_R) >= 0.

    Parameters
    ----------
    plant : Plant, python-control StateSpace or scipy StateSpace / lti / dlti
        ``x[k+1] = A x[k] + B u[k] + G w[k]``, ``y[k] = C x[k] + v[k]`` (discrete), or continuous with
        ``dt`` given.  Q and R of the plant, if any, only choose the default gain.
    y : (N, p) array_like
        The measured outputs, one row per sample (a 1-D array for one output).
    u : (N, nu) array_like, optional
        The known inputs (the plant's B); zero when omitted.
    L : (n, p) array_like, optional
        A predictor gain with ``A - L C`` stable (discrete).  Default: the plant's own steady-state
        Kalman gain when it has Q and R, else the Kalman gain of unit weights.
    lags : int, optional
        Number of autocovariance lags (default ``max(15, 2 n)``).  The record must hold at least
        ``10 lags`` samples after the burn-in.
    q_structure : "full", "diagonal" or (n, g) array_like
        Q full or diagonal through the plant's G, or Q full (g x g) through the G matrix given.
    weighting : "identity" or "optimal"
        ``"optimal"``: the iterative weighting of Rajamani & Rawlings (2009), reported in
        ``weighting_report``.
    trace_penalty : float
        ``rho >= 0`` of ``rho tr(Q)``: larger values give lower-rank Q (the number of independent
        disturbances; sweep it and look for the knee of ``residual`` against ``tr(Q)``).
    dt : float, optional
        Sampling period of the data; required for a continuous plant (refused if it differs from a
        discrete plant's own).
    method : "auto" or "sdp"
        ``"auto"`` returns the closed-form least-squares solution when it is already PSD (it is then
        the SDP's optimum); ``"sdp"`` always solves the SDP.
    sdp_solver : "CLARABEL" or "SCS"
    burn_in : int, optional
        Innovations dropped at the start (default: steps for the filter's start-up transient to fall
        to ``sqrt(eps)``, from the spectral radius of ``A - L C``).
    bootstrap : int, optional
        Number of bootstrap re-solves over resampled segments of the record (>= 2); the intervals
        are in ``confidence``.
    confidence : float
        Level of the bootstrap intervals, in (0, 1).
    max_iter, tol : int, float
        Iterations and relative change at which the optimal weighting stops.
    seed : int, optional
        Seed of the bootstrap's resampling.
    time_limit : float, optional
        Seconds; no weighting iteration or bootstrap replicate starts after it (status
        ``time_limit``, the estimate so far).

    Returns
    -------
    NoiseEstimate
        ``Q``, ``R``, ``residual``, ``condition``, ``.kalman()``; ``verification`` holds
        ``Q_min_eig``, ``R_min_eig`` and ``projected_gradient`` (first-order optimality on the
        cone, recomputed from the full data).

    Raises
    ------
    ValidationError
        A continuous plant without ``dt``; ``y`` too short for the lags or the burn-in; ``lags``
        too large for the data; ``L`` not stabilizing; an unidentifiable ``q_structure`` (the reason
        named); ``u`` without a B; bad option values (named).
    DimensionError, NotFiniteError
        ``y``, ``u``, ``L`` or a G matrix of the wrong shape, or with NaN / Inf (the index named).

    References
    ----------
    Odelson, Rajamani & Rawlings, Automatica 42(2) (2006) 303-308; Rajamani & Rawlings,
    Automatica 45(1) (2009) 142-148; the ALS package (Lima, Rajamani, Rawlings & Eaton, 2010).

    Examples
    --------
    >>> import numpy as np
    >>> from optdesign import Plant
    >>> from optdesign.design.noise_estimation import estimate_noise
    >>> plant = Plant([[0.9]], [[1.0]], dt=1.0)
    >>> rng = np.random.default_rng(0)
    >>> x, y = 0.0, np.empty(20000)
    >>> for k in range(y.size):
    ...     y[k] = x + np.sqrt(0.5) * rng.standard_normal()
    ...     x = 0.9 * x + np.sqrt(0.2) * rng.standard_normal()
    >>> est = estimate_noise(plant, y, lags=10)
    >>> bool(abs(est.Q[0, 0] - 0.2) < 0.05 and abs(est.R[0, 0] - 0.5) < 0.05)
    True
    """
    deadline = Deadline(time_limit)
    t_start = time.process_time()
    pl = as_plant(plant)
    st = _setup(pl, q_structure, dt)
    weighting = as_str("weighting", weighting, ("identity", "optimal"))
    method = as_str("method", method, ("auto", "sdp"))
    sdp_solver = as_str("sdp_solver", sdp_solver, ("CLARABEL", "SCS"))
    rho = as_positive_float("trace_penalty", trace_penalty, allow_zero=True)
    max_iter = as_int("max_iter", max_iter, 1)
    tol = as_positive_float("tol", tol)
    level = as_positive_float("confidence", confidence)
    if not level < 1.0:
        raise ValidationError(f"confidence must be in (0, 1); found {confidence!r}")
    n, p = pl.n, pl.p
    Y = _as_data("y", y, p, "outputs")
    U = None
    if u is not None:
        if st.Bd is None:
            raise ValidationError("u is given but the plant has no input matrix B (give the plant's B, or leave u out)")
        U = _as_data("u", u, st.Bd.shape[1], "inputs")
        if U.shape[0] != Y.shape[0]:
            raise ValidationError(f"u must have one row per sample of y ({Y.shape[0]}); found {U.shape[0]} rows")
    if L is None:
        Lg, gain_source = _default_gain(pl, st)
    else:
        Lg, gain_source = _check_gain(L, st, n, p), "given"
    Abar = st.Ad - Lg @ st.C
    N, burn = _lags_and_burn(lags, _spectral_radius(Abar), Y.shape[0], burn_in, n)
    usable = Y.shape[0] - burn
    B = None
    segments = 1
    if bootstrap is not None:
        B = as_int("bootstrap", bootstrap, 2)
        segments = min(50, usable // (SAMPLES_PER_LAG * N))
        if segments < 8:
            raise ValidationError(f"bootstrap needs at least 8 segments of {SAMPLES_PER_LAG * N} samples "
                                  f"(10 lags each); the record has {usable} usable samples: use more data or "
                                  f"fewer lags")
    rng = as_rng("seed", seed)

    t0 = time.process_time()
    acc = als.AutocovAccumulator(p, N)
    seg_sums, seg_counts = _stream(als.InnovationFilter(Abar, Lg, st.C, st.Bd), acc, Y, U, burn, segments)
    autocov = acc.autocov()
    mask = als.unique_mask(p, N)
    b = autocov.reshape(-1)[mask]
    A = als.als_matrix(Abar, st.C, Lg, st.W_basis, st.Rd_basis, N)
    rank, cond, full = _identifiability(A, st, rho, N, q_structure)
    stages = [Stage("autocovariances", "direct", "unchanged",
                    f"{acc.method}, {usable} innovations, {N} lags, {A.shape[0]} x {A.shape[1]} ALS matrix",
                    time.process_time() - t0)]

    solver = _Solver(A, st, rho, method, sdp_solver, full)
    fit, rejected = solver.solve(b, deadline)
    stages += [s for s in (rejected,) if s is not None]
    Lc, report = None, {}
    if weighting == "optimal" and np.all(np.isfinite(fit.theta)):
        stages.append(fit.stage if fit.stage.outcome != "answered" else
                      Stage(f"identity/{fit.stage.name}", fit.stage.kind, "improved", "first iterate"))
        ctx = {"Abar": Abar, "L": Lg, "lags": N, "counts": acc.counts, "max_iter": max_iter, "tol": tol,
               "rho": rho, "method": method, "sdp_solver": sdp_solver, "full_rank": full}
        fit, wsolver, Lc, report, extra_stages = _optimal_weighting(A, b, fit, st, ctx, deadline)
        stages += extra_stages
        if wsolver is not None:
            solver = wsolver
        stages.append(Stage(f"optimal_weighting/{fit.stage.name}", fit.stage.kind, fit.stage.outcome,
                            f"{report['iterations']} iterations, "
                            + ("converged" if report["converged"] else "not converged"), fit.stage.time))
    else:
        stages.append(fit.stage)
    return _package(pl, st, fit, A, b, Lc, solver, seg_sums, seg_counts, mask, B, level, rng, deadline, stages,
                    dict(rank=rank, cond=cond, lags=N, usable=usable, L=Lg, weighting=weighting, report=report,
                         autocov=autocov, rho=rho, gain_source=gain_source, burn=burn, t_start=t_start))


def _package(pl: Plant, st: _Setup, fit: _Fit, A: NDArray, b: NDArray, Lc: NDArray | None, solver: _Solver,
             seg_sums: NDArray, seg_counts: NDArray, mask: NDArray, B: int | None, level: float,
             rng: np.random.Generator, deadline: Deadline, stages: list[Stage], info: dict[str, Any]) -> NoiseEstimate:
    """Checks, bootstrap, status and message; the result."""
    ok = bool(np.all(np.isfinite(fit.theta)))
    Aw = A if Lc is None else scipy.linalg.solve_triangular(Lc, A, lower=True)
    bw = b if Lc is None else scipy.linalg.solve_triangular(Lc, b, lower=True)
    conf = None
    if ok and B is not None:
        t0 = time.process_time()
        conf = _bootstrap(solver, Lc, seg_sums, seg_counts, mask, B, level, rng, deadline)
        stages.append(Stage("bootstrap", "check", "unchanged",
                            f"{conf['replicates']} of {B} replicates over {conf['segments']} segments",
                            time.process_time() - t0))
    status = fit.status
    report = info["report"]
    if ok and report and not report["converged"]:
        status = Status.TIME_LIMIT if deadline.expired else Status.ITERATION_LIMIT
    if ok and (deadline.expired and (conf is not None and conf["replicates"] < (B or 0))):
        status = Status.TIME_LIMIT
    if ok:
        verification = _checks(Aw, bw, fit, st, info["rho"], info["cond"])
        residual = float(np.linalg.norm(Aw @ fit.theta - bw) / max(float(np.linalg.norm(bw)), _EPS))
        Q, R = fit.Q, fit.R
        Qd = np.tensordot(fit.theta[:st.Q_basis.shape[0]], st.W_basis, 1)
        Rd = np.tensordot(fit.theta[st.Q_basis.shape[0]:], st.Rd_basis, 1)
    else:
        verification = Verification()
        residual = float("nan")
        Q = R = Qd = Rd = None
    kind = "continuous (sampled at dt = %g)" % st.dt if st.continuous else "discrete"
    message = (f"ALS estimate of Q ({st.Q_basis.shape[1]} x {st.Q_basis.shape[1]}"
               f"{', diagonal' if st.q_diagonal else ''}) and R from {info['usable']} innovations of {kind} data, "
               f"{info['lags']} lags, {info['weighting']} weighting")
    if not ok:
        message += f"; the solver returned no estimate ({fit.native})"
    elif verification.passed:
        message += "; all independent checks passed"
    else:
        message += "; failed checks: " + ", ".join(c.name for c in verification.failed)
    stats = SolverStats(backend=fit.stage.name, native_status=fit.native, time=time.process_time() - info["t_start"],
                        iterations=fit.iterations,
                        extra={"gain": info["gain_source"], "burn_in": info["burn"], "trace_penalty": info["rho"]})
    return NoiseEstimate(
        Q=Q, R=R, G=st.G, Qd=Qd, Rd=Rd, residual=residual, condition=info["cond"], rank=info["rank"],
        n_unknowns=A.shape[1], lags=info["lags"], n_samples=info["usable"], L=info["L"], plant=pl, dt=st.dt,
        weighting=info["weighting"], weighting_report=report, confidence=conf, autocov=info["autocov"],
        status=status, message=message, solver_stats=stats, verification=verification,
        route=Route(stages), extra={"b": b, "A": A})


def simulate_outputs(plant: Plant | Any, steps: int, *, Q: ArrayLike | None = None, R: ArrayLike | None = None,
                     dt: float | None = None, u: ArrayLike | None = None, seed: int | None = None) -> NDArray:
    """Outputs ``y`` (steps, p) of the plant driven by Gaussian noise of covariances Q (through G) and R.

    Discrete: ``x[k+1] = A x[k] + B u[k] + G w[k]``, ``y[k] = C x[k] + v[k]``, from ``x[0] = 0`` after a
    start-up of as many steps as the plant's transient needs to fall to ``sqrt(eps)`` (dropped).
    Continuous with ``dt``: the exact sampled model of :func:`estimate_noise` (``Qd`` by Van Loan's
    integral, ``Rd = R / dt``).  For tests, examples and benchmarks of :func:`estimate_noise`.

    Parameters
    ----------
    plant : Plant or state-space system
    steps : int
    Q, R : array_like, optional
        Default: the plant's own.
    dt : float, optional
        Sampling period of a continuous plant.
    u : (steps, nu) array_like, optional
    seed : int, optional

    Returns
    -------
    (steps, p) ndarray
    """
    pl = as_plant(plant)
    if Q is not None or R is not None:
        pl = pl.replace(Q=pl.Q if Q is None else Q, R=pl.R if R is None else R)
    Qm, Rm = pl.noise_covariances()
    steps = as_int("steps", steps, 1)
    st = _setup(pl, "full", dt)
    W = np.tensordot(_coords(Qm, Rm, st)[:st.Q_basis.shape[0]], st.W_basis, 1)
    Rd = Rm / st.dt if st.continuous else Rm
    rng = as_rng("seed", seed)
    rho = _spectral_radius(st.Ad)
    warm = 0 if rho == 0 else (int(min(10**5, math.ceil(math.log(math.sqrt(_EPS)) / math.log(rho)))) if rho < 1
                               else 0)
    n, p = pl.n, pl.p
    sw = _psd_root(W)
    sv = _psd_root(Rd)
    U = None if u is None else _as_data("u", u, 0 if st.Bd is None else st.Bd.shape[1], "inputs")
    Y = np.empty((steps, p))
    x = np.zeros(n)
    Ad, C = st.Ad, st.C
    for k in range(warm):
        x = Ad @ x + sw @ rng.standard_normal(n)
    chunk = 4096
    for k0 in range(0, steps, chunk):
        k1 = min(steps, k0 + chunk)
        Wn = rng.standard_normal((k1 - k0, n)) @ sw.T
        if U is not None and st.Bd is not None:
            Wn += U[k0:k1] @ st.Bd.T
        X = np.empty((k1 - k0, n))
        for k in range(k1 - k0):
            X[k] = x
            x = Ad @ x + Wn[k]
        Y[k0:k1] = X @ C.T + rng.standard_normal((k1 - k0, p)) @ sv.T
    return Y


def _psd_root(X: NDArray) -> NDArray:
    lam, U = np.linalg.eigh(0.5 * (X + X.T))
    return U * np.sqrt(np.maximum(lam, 0.0))
