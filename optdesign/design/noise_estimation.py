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
from ..backends.report import one_warning_per_call
from ..errors import NotFiniteError, ValidationError
from ..formulate import als
from ..model.coerce import as_plant
from ..model.plant import Plant
from ..results import DesignResult, Route, SolverStats, Stage, Status, Verification
from .noise_solve import (
    AlsFit,
    AlsSetup,
    AlsSolver,
    als_coords,
    estimate_checks,
    identifiability_check,
    run_bootstrap,
    weight_optimally,
)

__all__ = ["NoiseEstimate", "estimate_noise", "simulate_outputs"]

_EPS = float(np.finfo(float).eps)
#: samples per autocovariance lag the data must hold (each lag averages >= 90 % of the record)
SAMPLES_PER_LAG = 10


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
def _q_basis(plant: Plant, q_structure: Any) -> tuple[NDArray, NDArray, bool]:
    """``(G, basis of Q, diagonal?)`` for ``q_structure``."""
    if isinstance(q_structure, str):
        s = as_str("q_structure", q_structure, ("full", "diagonal"))
        return plant.G, als.symmetric_basis(plant.m, s), s == "diagonal"
    G = as_matrix("q_structure", q_structure, (plant.n, None))
    if G.shape[1] == 0:
        raise ValidationError(f"q_structure as a G matrix needs at least one column; found shape {G.shape}")
    return G, als.symmetric_basis(G.shape[1], "full"), False


def _setup(plant: Plant, q_structure: Any, dt: Any) -> AlsSetup:
    from ..classical.sampling import van_loan

    G, Qb, diag = _q_basis(plant, q_structure)
    Rb = als.symmetric_basis(plant.p, "full")
    if plant.dt is not None:
        if dt is not None and not math.isclose(as_positive_float("dt", dt), float(plant.dt)):
            raise ValidationError(f"dt = {dt!r} differs from the discrete plant's own dt = {plant.dt:g}; "
                                  f"leave dt out for a discrete plant")
        Wb = np.einsum("ia,kab,jb->kij", G, Qb, G)
        return AlsSetup(plant.A, plant.C, plant.B, G, Qb, Wb, Rb, Rb, float(plant.dt), False, diag)
    if dt is None:
        raise ValidationError("the plant is continuous: give dt, the sampling period of the data (the "
                              "plant is sampled as kalmd does: Qd by Van Loan's integral, Rd = R / dt)")
    Ts = as_positive_float("dt", dt)
    Ad = scipy.linalg.expm(plant.A * Ts)
    Wb = np.stack([van_loan(plant.A, G @ E @ G.T, Ts)[1] for E in Qb])
    Bd = None
    if plant.B is not None:
        n, nu = plant.n, plant.B.shape[1]
        Z = np.zeros((n + nu, n + nu))
        Z[:n, :n], Z[:n, n:] = plant.A, plant.B
        Bd = scipy.linalg.expm(Z * Ts)[:n, n:]
    return AlsSetup(Ad, plant.C, Bd, G, Qb, Wb, Rb, Rb / Ts, Ts, True, diag)


def _spectral_radius(F: NDArray) -> float:
    return float(np.max(np.abs(np.linalg.eigvals(F))))


def _default_gain(plant: Plant, st: AlsSetup) -> tuple[NDArray, str]:
    """The plant's own discrete Kalman gain when it has Q and R, else the DARE gain of unit
    weights (``W = I``, ``R = I``): stable whenever (A, C) is detectable."""
    n, p = plant.n, plant.p
    if plant.has_noise_model:
        Rp = plant.noise_covariances()[1]
        Rq = Rp if not st.continuous else Rp / st.dt
        W = plant.process_noise() if not st.continuous else _van_loan_W(plant, st.dt)
        source = "the plant's own Kalman gain (its Q and R)"
    else:
        W, Rq = np.eye(n), np.eye(p)
        source = "the Kalman gain of unit weights (W = I, R = I)"
    try:
        P = scipy.linalg.solve_discrete_are(st.Ad.T, st.C.T, W, Rq)
    except (np.linalg.LinAlgError, ValueError) as exc:
        raise ValidationError(f"no default stable gain: the discrete Riccati equation of {source} has no "
                              f"stabilizing solution ({exc}); give L (an (n, p) gain with A - L C stable)"
                              ) from None
    L = st.Ad @ P @ st.C.T @ np.linalg.inv(st.C @ P @ st.C.T + Rq)
    return L, source


def _van_loan_W(plant: Plant, Ts: float) -> NDArray:
    from ..classical.sampling import van_loan

    return van_loan(plant.A, plant.process_noise(), Ts)[1]


def _as_data(name: str, X: ArrayLike, cols: int) -> NDArray:
    """A data record (N, cols): a float64 array of that shape is used as is (no copy; finiteness
    checked in blocks, so validating a long record allocates nothing record-sized), anything else
    through :func:`~optdesign._validate.as_matrix`."""
    if isinstance(X, np.ndarray) and X.dtype == np.float64 and X.ndim == 2 and X.shape[1] == cols:
        step = 1 << 16
        for k in range(0, X.shape[0], step):
            blk = X[k:k + step]
            if not np.all(np.isfinite(blk)):
                i, j = (int(v) for v in np.argwhere(~np.isfinite(blk))[0])
                raise NotFiniteError(f"{name} must be finite; found {blk[i, j]} at index ({k + i}, {j})")
        return X
    return np.ascontiguousarray(as_matrix(name, X, (None, cols)), dtype=float)


def _check_gain(L: Any, st: AlsSetup, n: int, p: int) -> NDArray:
    L = as_matrix("L", L, (n, p))
    rho = _spectral_radius(st.Ad - L @ st.C)
    if not rho < 1.0 - 10 * n * _EPS:
        raise ValidationError(f"L must make the discrete error dynamics A - L C stable (spectral radius "
                              f"< 1); "
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


# ------------------------------------------------------------------ the verb
@one_warning_per_call
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
    weighting_s = as_str("weighting", weighting, ("identity", "optimal"))
    method_s = as_str("method", method, ("auto", "sdp"))
    solver_s = as_str("sdp_solver", sdp_solver, ("CLARABEL", "SCS"))
    rho = as_positive_float("trace_penalty", trace_penalty, allow_zero=True)
    max_iter = as_int("max_iter", max_iter, 1)
    tol = as_positive_float("tol", tol)
    level = as_positive_float("confidence", confidence)
    if not level < 1.0:
        raise ValidationError(f"confidence must be in (0, 1); found {confidence!r}")
    n, p = pl.n, pl.p
    Y = _as_data("y", y, p)
    U = None
    if u is not None:
        if st.Bd is None:
            raise ValidationError("u is given but the plant has no input matrix B (give the plant's B, or "
                                  "leave u out)")
        U = _as_data("u", u, st.Bd.shape[1])
        if U.shape[0] != Y.shape[0]:
            raise ValidationError(f"u must have one row per sample of y ({Y.shape[0]}); found "
                                  f"{U.shape[0]} rows")
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
    filt = als.InnovationFilter(Abar, Lg, st.C, st.Bd if U is not None else None)
    seg_sums, seg_counts = _stream(filt, acc, Y, U, burn, segments)
    autocov = acc.autocov()
    mask = als.unique_mask(p, N)
    b = autocov.reshape(-1)[mask]
    A = als.als_matrix(Abar, st.C, Lg, st.W_basis, st.Rd_basis, N)
    rank, cond, full = identifiability_check(A, st, rho, N, q_structure)
    stages = [Stage("autocovariances", "direct", "unchanged",
                    f"{acc.method}, {usable} innovations, {N} lags, {A.shape[0]} x {A.shape[1]} ALS matrix",
                    time.process_time() - t0)]

    solver = AlsSolver(A, st, rho, method_s, solver_s, full,
                     reusable=B is not None and weighting_s == "identity")
    fit, rejected = solver.solve(b, deadline)
    stages += [s for s in (rejected,) if s is not None]
    Lc: NDArray | None = None
    report: dict[str, Any] = {}
    if weighting_s == "optimal" and np.all(np.isfinite(fit.theta)):
        stages.append(fit.stage if fit.stage.outcome != "answered" else
                      Stage(f"identity/{fit.stage.name}", fit.stage.kind, "improved", "first iterate"))
        ctx = {"Abar": Abar, "L": Lg, "lags": N, "counts": acc.counts, "max_iter": max_iter, "tol": tol,
               "rho": rho, "method": method_s, "sdp_solver": solver_s, "full_rank": full,
               "reusable": B is not None}
        fit, wsolver, Lc, report, extra_stages = weight_optimally(A, b, fit, st, ctx, deadline)
        stages += extra_stages
        if wsolver is not None:
            solver = wsolver
        stages.append(Stage(f"optimal_weighting/{fit.stage.name}", fit.stage.kind, fit.stage.outcome,
                            f"{report['iterations']} iterations, "
                            + ("converged" if report["converged"] else "not converged"), fit.stage.time))
    else:
        stages.append(fit.stage)
    return _package(pl, st, fit, A, b, Lc, solver, seg_sums, seg_counts, mask, B, level, rng, deadline,
                    stages, dict(rank=rank, cond=cond, lags=N, usable=usable, L=Lg, weighting=weighting_s,
                                 report=report,
                         autocov=autocov, rho=rho, gain_source=gain_source, burn=burn, t_start=t_start))


def _package(pl: Plant, st: AlsSetup, fit: AlsFit, A: NDArray, b: NDArray, Lc: NDArray | None, solver: AlsSolver,
             seg_sums: NDArray, seg_counts: NDArray, mask: NDArray, B: int | None, level: float,
             rng: np.random.Generator, deadline: Deadline, stages: list[Stage],
             info: dict[str, Any]) -> NoiseEstimate:
    """Checks, bootstrap, status and message; the result."""
    ok = bool(np.all(np.isfinite(fit.theta)))
    Aw = A if Lc is None else scipy.linalg.solve_triangular(Lc, A, lower=True)
    bw = b if Lc is None else scipy.linalg.solve_triangular(Lc, b, lower=True)
    conf = None
    if ok and B is not None:
        t0 = time.process_time()
        conf = run_bootstrap(solver, Lc, seg_sums, seg_counts, mask, B, level, rng, deadline)
        stages.append(Stage("bootstrap", "check", "unchanged",
                            f"{conf['replicates']} of {B} replicates over {conf['segments']} segments",
                            time.process_time() - t0))
    status = fit.status
    report = info["report"]
    if ok and report and not report["converged"]:
        status = Status.TIME_LIMIT if deadline.expired else Status.ITERATION_LIMIT
    if ok and (deadline.expired and (conf is not None and conf["replicates"] < (B or 0))):
        status = Status.TIME_LIMIT
    Q: NDArray | None = None
    R: NDArray | None = None
    Qd: NDArray | None = None
    Rd: NDArray | None = None
    if ok:
        verification = estimate_checks(Aw, bw, fit, st, info["rho"], info["cond"])
        residual = float(np.linalg.norm(Aw @ fit.theta - bw) / max(float(np.linalg.norm(bw)), _EPS))
        Q, R = fit.Q, fit.R
        Qd = np.tensordot(fit.theta[:st.Q_basis.shape[0]], st.W_basis, 1)
        Rd = np.tensordot(fit.theta[st.Q_basis.shape[0]:], st.Rd_basis, 1)
    else:
        verification = Verification()
        residual = float("nan")
    kind = f"continuous (sampled at dt = {st.dt:g})" if st.continuous else "discrete"
    message = (f"ALS estimate of Q ({st.Q_basis.shape[1]} x {st.Q_basis.shape[1]}"
               f"{', diagonal' if st.q_diagonal else ''}) and R from {info['usable']} innovations of {kind} "
               f"data, "
               f"{info['lags']} lags, {info['weighting']} weighting")
    if not ok:
        message += f"; the solver returned no estimate ({fit.native})"
    elif verification.passed:
        message += "; all independent checks passed"
    else:
        message += "; failed checks: " + ", ".join(c.name for c in verification.failed)
    stats = SolverStats(backend=fit.stage.name, native_status=fit.native,
                        time=time.process_time() - info["t_start"],
                        iterations=fit.iterations,
                        extra={"gain": info["gain_source"], "burn_in": info["burn"],
                               "trace_penalty": info["rho"]})
    return NoiseEstimate(
        Q=Q, R=R, G=st.G, Qd=Qd, Rd=Rd, residual=residual, condition=info["cond"], rank=info["rank"],
        n_unknowns=A.shape[1], lags=info["lags"], n_samples=info["usable"], L=info["L"], plant=pl, dt=st.dt,
        weighting=info["weighting"], weighting_report=report, confidence=conf, autocov=info["autocov"],
        status=status, message=message, solver_stats=stats, verification=verification,
        route=Route(stages), extra={"b": b, "A": A})


def simulate_outputs(plant: Plant | Any, steps: int, *, Q: ArrayLike | None = None,
                     R: ArrayLike | None = None,
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

    Examples
    --------
    >>> from optdesign import Plant, simulate_outputs
    >>> plant = Plant([[0.9]], [[1.0]], Q=[[1.0]], R=[[0.5]], dt=1.0)
    >>> y = simulate_outputs(plant, 1000, seed=0)   # x+ = 0.9 x + w, y = x + v
    >>> y.shape, round(float(y.var()), 1)           # q / (1 - 0.81) + r = 5.76
    ((1000, 1), 5.9)
    """
    pl = as_plant(plant)
    if Q is not None or R is not None:
        pl = pl.replace(Q=pl.Q if Q is None else Q, R=pl.R if R is None else R)
    Qm, Rm = pl.noise_covariances()
    steps = as_int("steps", steps, 1)
    st = _setup(pl, "full", dt)
    W = np.tensordot(als_coords(Qm, Rm, st)[:st.Q_basis.shape[0]], st.W_basis, 1)
    Rd = Rm / st.dt if st.continuous else Rm
    rng = as_rng("seed", seed)
    rho = _spectral_radius(st.Ad)
    warm = 0
    if 0 < rho < 1:
        warm = int(min(10**5, math.ceil(math.log(math.sqrt(_EPS)) / math.log(rho))))
    n, p = pl.n, pl.p
    sw = _psd_root(W)
    sv = _psd_root(Rd)
    U = None if u is None else _as_data("u", u, 0 if st.Bd is None else st.Bd.shape[1])
    Y = np.empty((steps, p))
    x = np.zeros(n)
    Ad, C = st.Ad, st.C
    for _ in range(warm):
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
