r"""The ``riccati_de`` verb: the time-varying Kalman filter from the Riccati differential
(or difference) equation, by block-pulse functions (seed 004), the exact Hamiltonian
transition matrix, or an ODE solver, with an error estimate for each.

Continuous time (``plant.dt is None``), seed 004 eq (3.10)-(3.12)::

    P' = A P + P A' + G Q G' - P C' R^-1 C P,    P(0) = P0,    L(t) = P(t) C' R^-1

Discrete time (``plant.dt`` set), the time-varying *predictor* filter (the a-priori covariance;
error dynamics ``A - L_k C`` as in :func:`optdesign.riccati.filter_are`)::

    P_{k+1} = A P_k A' + G Q G' - A P_k C' (C P_k C' + R)^-1 C P_k A',
    L_k = A P_k C' (C P_k C' + R)^-1,       t_k = k dt

Both converge to the stabilizing solution of the algebraic equation when one exists
(``P_steady``, from the project's :func:`~optdesign.classical.riccati.filter_are`).

Methods
-------
``"transition"`` (default)
    Exact: the Hamiltonian transition matrix over each output interval in Lainiotis' partitioned
    form, built by doubling from one short exact step and restarted at every output time
    (:func:`optdesign.classical.transition.riccati_flow`).  Symmetric by construction, PSD to
    rounding (checked), stable on long horizons and on stiff or unstable plants.  Error estimate: the
    difference from a recomputation by doubling from a 4x shorter base step (rounding only; never
    the direct one-exponential map that short intervals may use).  For a discrete
    plant: the Riccati recursion in Joseph form (a sum of PSD terms); error estimate: the
    difference from the standard form.
``"bpf"``
    The paper's block-pulse recursion (4.24)-(4.26) with ``steps`` blocks -- numerically the
    Crank-Nicolson transition matrix averaged over each block and then inverted, a
    second-order approximation of P at the block midpoints (see
    :mod:`optdesign.classical.bpf`).  ``t`` holds the block midpoints (or ``t_eval``, where the
    piecewise-constant expansion is only first order).  P is the symmetric part of the paper's
    ``V U^-1``; ``asymmetry`` is the relative size of the part removed.  Error estimate: the
    measured difference from the exact transition solution at the same times.  The recursion
    is restarted every :func:`~optdesign.classical.bpf.bpf_restart_blocks` blocks (from its own
    Crank-Nicolson nodal value: the same P in exact arithmetic), so the transition matrix it
    inverts stays well conditioned on any horizon -- the paper's unrestarted recursion inverts
    one taken from t = 0 (condition number ``~e^{2 Re(lambda) t}``) and breaks within seconds
    on fast or unstable plants (:func:`~optdesign.classical.bpf.bpf_riccati` without
    ``restart_every``).
``"ode"``
    :func:`scipy.integrate.solve_ivp` on the ``n^2`` entries of P (the right-hand side
    ``H + H' + W`` is exactly symmetric, so P stays exactly symmetric), DOP853, ``rtol = tol /
    10^4``; Radau with the analytic Jacobian only when the horizon spans more than
    ``STIFF_RHO_T`` time constants of the Hamiltonian *and* Radau's ``n^2 x n^2`` linear algebra
    costs no more than a right-hand side (:func:`ode_integrator`).  Error estimate: the measured
    difference from the exact transition solution.

Cost and time limits
--------------------
Post-processing is done only when asked: ``estimate_error`` (one more exact solve) and
``steady_state`` (one algebraic Riccati solve, as costly as the whole trajectory at n = 100).
The verification that stays is cheap: a count of non-finite entries and a PSD certificate, a
Cholesky factor of every ``P_k`` shifted by a rounding-level multiple of I (exact eigenvalues
only where one fails).  ``time_limit``
(seconds): once it has expired no new output interval, block or integrator step is started;
the result holds the part of the trajectory computed so far (``t`` stops early), with status
``time_limit`` and a message saying where it stopped.

References
----------
Ahn, D. S., Lim, Y. S., Lee, S. H. & Lee, M. K., "Design of Kalman filter via BPF", seed 004.
Kenney, C. S. & Leipnik, R. B., IEEE TAC 30 (1985) 962-970.
Lainiotis, D. G., IEEE TAC 21 (1976) 677-689.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import overload

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.linalg.lapack import dpotrf as _potrf

from .._deadline import Deadline
from .._validate import as_bool, as_positive_float, as_square, as_vector, check_psd
from ..classical.bpf import bpf_evaluate, bpf_restart_blocks, bpf_riccati, filter_hamiltonian_trusted
from ..classical.transition import as_hamiltonian, riccati_flow
from ..errors import NotObservableError, RiccatiError, ValidationError
from ..model.coerce import as_plant
from ..model.plant import Plant
from ..results import Check, DesignResult, SolverStats, Status, Verification

__all__ = ["RiccatiTrajectory", "riccati_de", "ode_integrator", "DEFAULT_TOL", "DEFAULT_STEPS",
           "PSD_RTOL", "STIFF_RHO_T"]

_METHODS = ("transition", "bpf", "ode")

#: default accuracy demanded by the ``error_estimate`` check, per method
DEFAULT_TOL: dict[str, float] = {"transition": 1e-8, "ode": 1e-8, "bpf": 1e-2}

#: default number of output intervals (transition, ode) or blocks (bpf)
DEFAULT_STEPS = 100

#: smallest eigenvalue accepted as PSD: >= -(PSD_RTOL + method error) * max_k ||P_k||_F
PSD_RTOL = 1e-10

#: the ODE method considers Radau when rho(M) t_final exceeds this (see :func:`ode_integrator`)
STIFF_RHO_T = 3e3

#: Python overhead of one right-hand-side call, in flops (~20 us at a few Gflop/s; measured)
_RHS_OVERHEAD_FLOPS = 1e5

_EPS = float(np.finfo(float).eps)


@dataclass(frozen=True, kw_only=True, eq=False)
class RiccatiTrajectory(DesignResult):
    r"""Solution of the filter Riccati differential / difference equation.

    Attributes
    ----------
    t : (k,) ndarray
        Times.  ``"transition"``/``"ode"``: ``linspace(0, t_final, steps + 1)`` or ``t_eval``;
        ``"bpf"``: the block midpoints or ``t_eval``; discrete: ``k dt``.  Stops early when the
        time limit ran out (status ``time_limit``).
    P : (k, n, n) ndarray
        Error covariance at ``t`` (symmetric).
    L : (k, n, p) ndarray
        Gains at ``t``: ``P C' R^-1`` (continuous), ``A P C' (C P C' + R)^-1`` (discrete).
    method : str
        ``"transition"``, ``"bpf"`` or ``"ode"``.
    scheme : str
        What was computed, in words (e.g. the ODE integrator).
    steps : int
        Output intervals propagated (transition, ode), blocks (bpf) or recursion steps
        (discrete) -- those requested.
    P_steady, L_steady : ndarray or None
        Stabilizing solution of the algebraic Riccati equation and its gain (None when none
        exists, when ``steady_state=False`` or when the time limit ran out; ``message`` says why).
    steady_distance : float
        ``||P(t[-1]) - P_steady||_F / ||P_steady||_F`` (nan without a steady state).
    error_estimate : float
        Estimated (transition, discrete) or measured (bpf, ode) error
        ``max_k ||P_k - P_ref(t_k)||_F / max_k ||P_ref(t_k)||_F``; nan if not computed.
    error_kind : str
        How ``error_estimate`` was obtained.
    asymmetry : float
        bpf: the largest antisymmetric part removed from the paper's ``V U^-1``,
        ``max_k ||P_k - P_k'||_F / 2`` over ``max_k ||P_k||_F``; else 0.
    status : Status
        ``SOLVED``; ``NUMERICAL_ERROR`` when the ODE integrator stopped early; ``TIME_LIMIT``
        when the time limit ran out (then ``t`` and ``P`` hold what was computed).
    message : str
    solver_stats : SolverStats
        ``time`` excludes the error estimate; ``extra`` holds method details (doublings,
        restarts, nfev, rtol, ...) and ``completed`` / ``requested`` output times.
    verification : Verification
        ``nonfinite`` (count, must be 0), ``P_min_eig`` (``min_k lambda_min(P_k) /
        max_k ||P_k||_F >= -(1e-10 + error_estimate)``: PSD to within the method's accuracy;
        where every ``P_k`` plus a rounding-level shift has a Cholesky factor the value is that
        certified lower bound, ``-11 n eps``), ``error_estimate`` (``<= tol``).
    dt : float or None
        The plant's sampling period.
    """

    t: NDArray[np.float64]
    P: NDArray[np.float64]
    L: NDArray[np.float64]
    method: str
    scheme: str
    steps: int
    P_steady: NDArray[np.float64] | None
    L_steady: NDArray[np.float64] | None
    steady_distance: float
    error_estimate: float
    error_kind: str
    asymmetry: float
    dt: float | None = None

    @property
    def P_final(self) -> NDArray[np.float64]:
        """P at the last time."""
        return self.P[-1]

    @property
    def L_final(self) -> NDArray[np.float64]:
        """The gain at the last time."""
        return self.L[-1]

    def __len__(self) -> int:
        return int(self.t.shape[0])

    def __repr__(self) -> str:
        kind = f"dt={self.dt:g}" if self.dt is not None else "continuous"
        span = f"in [{self.t[0]:g}, {self.t[-1]:g}]" if len(self) else "(none)"
        return (f"RiccatiTrajectory({self.method}, {kind}, n={self.P.shape[1]}, {len(self)} times "
                f"{span}, error~{self.error_estimate:.1e}, status={self.status.value}, "
                f"success={self.success})")


# ------------------------------------------------------------------ validation
def _as_steps(value) -> int | None:
    if value is None:
        return None
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise ValidationError(f"steps must be a positive integer; found {value!r}")
    if value < 1:
        raise ValidationError(f"steps must be a positive integer; found {value}")
    return int(value)


@overload
def _as_t_eval(t_eval: None, t_final: float) -> None: ...
@overload
def _as_t_eval(t_eval: ArrayLike, t_final: float) -> NDArray[np.float64]: ...
def _as_t_eval(t_eval: ArrayLike | None, t_final: float) -> NDArray[np.float64] | None:
    if t_eval is None:
        return None
    try:
        kind = "U" if isinstance(t_eval, (str, bytes)) else np.asarray(t_eval).dtype.kind
    except (ValueError, TypeError):                      # ragged nests
        kind = "O"
    if kind in "USVO":
        raise ValidationError(f"t_eval must be a numeric vector of times; found {t_eval!r}")
    t = as_vector("t_eval", t_eval)
    if t.size == 0:
        raise ValidationError("t_eval must hold at least one time; found an empty array")
    if np.any(np.diff(t) <= 0):
        k = int(np.argmax(np.diff(t) <= 0))
        raise ValidationError(f"t_eval must be strictly increasing; found t_eval[{k}] = {t[k]:g} "
                              f">= t_eval[{k + 1}] = {t[k + 1]:g}")
    if t[0] < 0 or t[-1] > t_final * (1 + 1e-12):
        raise ValidationError(f"t_eval must lie in [0, t_final] = [0, {t_final:g}]; found values in "
                              f"[{t[0]:g}, {t[-1]:g}]")
    return np.minimum(t, t_final)


def _rel_diff(P: NDArray, Pref: NDArray) -> float:
    k = min(P.shape[0], Pref.shape[0])
    if k == 0:
        return float("nan")
    den = float(np.max(np.linalg.norm(Pref[:k], axis=(1, 2))))
    num = float(np.max(np.linalg.norm(P[:k] - Pref[:k], axis=(1, 2))))
    if den == 0.0:
        return num
    return num / den


# ------------------------------------------------------------------ the verb
def riccati_de(
    plant: Plant,
    P0: ArrayLike,
    t_final: float,
    *,
    method: str = "transition",
    steps: int | None = None,
    t_eval: ArrayLike | None = None,
    tol: float | None = None,
    estimate_error: bool = True,
    steady_state: bool = True,
    time_limit: float | None = None,
) -> RiccatiTrajectory:
    r"""Time-varying Kalman filter: solve the filter Riccati differential (difference) equation.

    Parameters
    ----------
    plant : Plant
        Must carry Q and R.  Continuous unless ``plant.dt`` is set.
    P0 : (n, n) array_like
        Initial error covariance (symmetric PSD); discrete: the a-priori covariance of step 0.
    t_final : float
        Horizon (> 0).  Discrete: a multiple of ``dt``.
    method : {"transition", "bpf", "ode"}
        See the module notes.  Discrete plants: ``"transition"`` only (the exact recursion).
    steps : int, optional
        ``"transition"``/``"ode"``: output intervals on ``[0, t_final]`` (default 100);
        ``"bpf"``: number of blocks m (default 100; the paper uses 50).  Discrete: must equal
        ``t_final / dt`` if given.
    t_eval : (k,) array_like, optional
        Output times, strictly increasing in ``[0, t_final]`` (instead of ``steps``; with
        ``"bpf"`` both may be given: m blocks, evaluated at ``t_eval``).  Discrete: multiples
        of ``dt``.
    tol : float, optional
        Accuracy the ``error_estimate`` check demands (default 1e-8; bpf 1e-2).  For
        ``"ode"`` it also sets the integrator's ``rtol = tol / 10^4`` (at least ``100 eps``).
    estimate_error : bool
        Compute ``error_estimate`` (costs one extra exact solve); if False it is nan and the
        ``error_estimate`` check is left out.
    steady_state : bool
        Solve the algebraic Riccati equation for ``P_steady``, ``L_steady`` and
        ``steady_distance`` (one ARE solve); if False they are None / nan.
    time_limit : float, optional
        Seconds (None: unlimited).  When it runs out the trajectory computed so far is returned
        with status ``time_limit``; the error estimate and the steady state are then skipped.

    Returns
    -------
    RiccatiTrajectory

    Raises
    ------
    ValidationError
        Not a Plant, no Q or R, unknown method, bpf/ode on a discrete plant, t_final or tol not
        a finite number > 0 (strings -- numeric ones too -- and bools are refused; discrete
        t_final: not a multiple of dt), steps not a positive integer (discrete: not
        ``t_final/dt``), t_eval not numeric / empty / not increasing / outside ``[0, t_final]``
        (discrete: not multiples of dt), steps and t_eval both given for transition/ode,
        estimate_error or steady_state not a bool, time_limit not a number of seconds > 0.
    DimensionError, NotFiniteError, NotSymmetricError, NotPositiveSemidefiniteError
        Bad P0 or t_eval (the message names the argument).
    RiccatiError
        bpf: a block coefficient or ``U`` block singular to working precision (blocks far too
        wide for the plant); transition: the filter's transient growth needs more restarts than
        allowed (the message suggests method="ode").

    Examples
    --------
    >>> import numpy as np
    >>> from optdesign import Plant, riccati_de
    >>> plant = Plant([[0, 1], [-0.64, -0.32]], [[0, 1]], G=[[0], [1]], Q=[[1]], R=[[1]])
    >>> traj = riccati_de(plant, np.zeros((2, 2)), 10.0)
    >>> traj.success, traj.steady_distance < 1e-3
    (True, True)

    References
    ----------
    Seed 004 (Ahn et al.), eqs (3.10)-(3.12), (4.4), (4.11), (4.24)-(4.26).
    """
    clock = Deadline(time_limit)
    plant = as_plant(plant)
    if not isinstance(method, str) or method not in _METHODS:
        raise ValidationError(f"method must be one of {', '.join(repr(m) for m in _METHODS)}; "
                              f"found {method!r}")
    plant.require_noise_model()
    n = plant.n
    P0 = check_psd("P0", as_square("P0", P0, n))
    t_final = as_positive_float("t_final", t_final)
    steps = _as_steps(steps)
    tol_v = DEFAULT_TOL[method] if tol is None else as_positive_float("tol", tol)
    post = {"estimate_error": as_bool("estimate_error", estimate_error),
            "steady_state": as_bool("steady_state", steady_state)}
    if plant.dt is not None:
        if method != "transition":
            raise ValidationError(
                f"method {method!r} applies to continuous-time plants; plant has dt = {plant.dt:g}: its "
                f"Riccati difference equation is solved exactly by method='transition'")
        return _discrete(plant, plant.dt, P0, t_final, steps, t_eval, tol_v, post, clock)
    t_eval = _as_t_eval(t_eval, t_final)
    if method != "bpf" and steps is not None and t_eval is not None:
        raise ValidationError(f"give steps or t_eval, not both (method={method!r} returns P at t_eval)")
    return _continuous(plant, P0, t_final, method, steps, t_eval, tol_v, post, clock)


def _continuous(plant: Plant, P0: NDArray, t_final: float, method: str, steps: int | None,
                t_eval: NDArray | None, tol: float, post: dict, clock: Deadline) -> RiccatiTrajectory:
    M = filter_hamiltonian_trusted(plant.A, plant.C, plant.process_noise(), plant.noise_covariances()[1])
    status, message = Status.SOLVED, ""
    asym = 0.0
    if method == "bpf":
        m = steps if steps is not None else DEFAULT_STEPS
        t0 = time.perf_counter()
        every = bpf_restart_blocks(M, t_final / m)
        res = bpf_riccati(M, P0, t_final, m, restart_every=every if every < m else None, deadline=clock)
        if t_eval is None:
            t, P, requested = res.t, res.P, m
        else:
            reached = t_final if res.complete else res.P.shape[0] * res.h   # the blocks computed
            t = t_eval if res.complete else t_eval[t_eval < reached]
            P, requested = bpf_evaluate(res.P, reached, t) if t.size else res.P[:0], t_eval.size
        elapsed = time.perf_counter() - t0
        big = float(np.max(np.linalg.norm(res.P, axis=(1, 2)))) if res.P.shape[0] else 0.0
        asym = float(np.max(res.asymmetry)) / big if big > 0 else 0.0
        scheme = (f"block-pulse recursion (4.24)-(4.26), m = {m} blocks of h = {res.h:.4g} "
                  f"(Crank-Nicolson, block-averaged; order 2 at block midpoints), "
                  + (f"restarted every {res.restart_every} blocks ({res.restarts} restarts)"
                     if res.restart_every else "not restarted"))
        stats = SolverStats(backend="numpy", native_status="bpf", time=elapsed, iterations=m,
                            extra={"h": res.h, "max_asymmetry": asym, "restart_every": res.restart_every,
                                   "restarts": res.restarts})
        nsteps = m
    else:
        nsteps = steps if steps is not None else DEFAULT_STEPS
        t = t_eval if t_eval is not None else np.linspace(0.0, t_final, nsteps + 1)
        if t_eval is not None:
            nsteps = int(t.size) - int(t[0] == 0.0)
        requested = t.size
        t0 = time.perf_counter()
        if method == "transition":
            P, info = riccati_flow(M, P0, t, deadline=clock)
            elapsed = time.perf_counter() - t0
            scheme = ("exact Hamiltonian transition matrix: Lainiotis partitioned form, doubling "
                      f"({info['doublings']} per interval), restarted at every output time")
            stats = SolverStats(backend="numpy", native_status="riccati_flow", time=elapsed,
                                iterations=info["substeps"], extra=dict(info))
        else:
            P, stats, status, message, scheme = _ode(M, P0, t, tol, clock)
        t = t[:P.shape[0]]
    if P.shape[0] < requested and status is Status.SOLVED:
        status = Status.TIME_LIMIT
        message = _time_limit_message(clock, t, requested, t_final)
    stats.extra.update(completed=int(P.shape[0]), requested=int(requested))
    err, kind = _error_estimate(M, P0, t, P, method, post["estimate_error"], clock)
    return _finish(plant, t, P, method, scheme, nsteps, err, kind, asym, status, message, stats,
                   tol, post, clock)


def _time_limit_message(clock: Deadline, t: NDArray, requested: int, t_final: float) -> str:
    where = f"on [0, {t[-1]:g}]" if len(t) else "at no time"
    limit = float(clock.limit or 0.0)
    return (f"time limit of {limit:g} s reached: P computed {where}, {len(t)} of {requested} output "
            f"times (horizon {t_final:g}); the rest was not computed")


def _error_estimate(M: NDArray, P0: NDArray, t: NDArray, P: NDArray, method: str, wanted: bool,
                    clock: Deadline) -> tuple[float, str]:
    if not wanted:
        return float("nan"), "not computed (estimate_error=False)"
    if clock.expired:
        return float("nan"), "not computed (time limit reached)"
    if not P.shape[0]:
        return float("nan"), "not computed (no output)"
    if method == "transition":
        try:
            P2, _ = riccati_flow(M, P0, t, max_norm=0.125, direct=False, deadline=clock)
        except RiccatiError as exc:  # pragma: no cover - the finer base step failed only
            return float("nan"), f"unavailable: the recomputation failed ({exc})"
        if P2.shape[0] < P.shape[0]:
            return float("nan"), "not computed (time limit reached during the recomputation)"
        return _rel_diff(P, P2), "rounding: recomputed by doubling from a 4x shorter base step"
    try:
        Pref, _ = riccati_flow(M, P0, t, deadline=clock)
    except RiccatiError as exc:
        return float("nan"), f"unavailable: the exact reference failed ({exc})"
    if Pref.shape[0] < P.shape[0]:
        return float("nan"), "not computed (time limit reached during the exact reference)"
    return _rel_diff(P, Pref), "measured: difference from the exact transition-matrix solution at t"


# ------------------------------------------------------------------ ODE reference
def ode_integrator(M: ArrayLike, t_final: float) -> tuple[str, dict]:
    r"""The ``solve_ivp`` method used by ``riccati_de(method="ode")``, and why.

    DOP853 (explicit, order 8) unless both

    * the horizon spans many time constants of the Hamiltonian, ``rho(M) t_final >
      STIFF_RHO_T``: an explicit method's step is then bounded by stability, not accuracy, so
      its evaluations grow like ``4.8 rho(M) t_final`` (measured) while Radau's level off once
      P has settled, and
    * Radau's linear algebra is affordable: each of its evaluations also solves with the LU
      factors of the ``N x N`` Jacobian, ``N = n^2`` (``10 N^2`` flops: one real and one complex
      system) and refactors it every few steps (``~N^3 / 3`` flops per evaluation), which together
      must not exceed one right-hand side (``6 n^3`` flops plus ``1e5`` for the call overhead):
      n <= 7.

    Measured at rtol 1e-12 (random plants as in the tests): Radau on n = 50 over 1000 s (before
    issue 14, on the 1275 entries of vech(P)) took 50 s CPU on one plant, where DOP853 takes 13 s,
    and 8.4 s for its first 3,000 evaluations (reaching t = 0.0125 s) on another; n = 20 over 200 s:
    2.9 s against 0.28 s; n = 10 over 1000 s: 1.5x DOP853; CAREX 2.3 (n = 2, ``rho(M) = 1000``):
    1.6x over 10 s and 0.2x over 100 s (break-even near ``rho(M) t_final = 1.6e4``; Radau is also
    1e4 times more accurate there).

    Parameters
    ----------
    M : (2n, 2n) array_like
        Hamiltonian (:func:`~optdesign.classical.bpf.filter_hamiltonian`).
    t_final : float

    Returns
    -------
    integrator : {"DOP853", "Radau"}
    info : dict
        ``rho_t`` (``rho(M) t_final``), ``stiff``, ``implicit_affordable``.

    Raises
    ------
    DimensionError, NotFiniteError
        M not a finite 2n x 2n matrix.
    ValidationError
        t_final not a finite number > 0.
    """
    M, n = as_hamiltonian(M)
    N = n * n
    rho_t = float(np.max(np.abs(np.linalg.eigvals(M)))) * as_positive_float("t_final", t_final) if n else 0.0
    stiff = rho_t > STIFF_RHO_T
    affordable = 10.0 * N**2 + N**3 / 3.0 <= 6.0 * n**3 + _RHS_OVERHEAD_FLOPS
    integrator = "Radau" if stiff and affordable else "DOP853"
    return integrator, {"rho_t": rho_t, "stiff": stiff, "implicit_affordable": affordable}


def _ode(M: NDArray, P0: NDArray, t: NDArray, tol: float, clock: Deadline):
    from scipy.integrate import solve_ivp

    n = P0.shape[0]
    A, S, W = M[n:, n:], M[:n, n:], M[n:, :n]

    def rhs(_t: float, y: NDArray) -> NDArray:
        P = y.reshape(n, n)
        H = A @ P - 0.5 * (P @ S @ P)
        return (H + H.T + W).ravel()                           # exactly symmetric, whatever P

    t_end = float(t[-1])
    integrator, why = ode_integrator(M, t_end if t_end > 0 else 1.0)
    rtol = max(100 * _EPS, tol * 1e-4)
    scale = max(float(np.max(np.abs(P0))), float(np.max(np.abs(W))) * min(t_end if t_end > 0 else 1.0, 1.0),
                np.finfo(float).tiny)
    atol = rtol * 1e-3 * scale
    kw: dict = {"jac": _jacobian(A, S)} if integrator == "Radau" else {}
    if clock.limited:
        kw["events"] = _OutOfTime(clock)
    t0 = time.perf_counter()
    sol = solve_ivp(rhs, (0.0, t_end), P0.ravel(), method=integrator, t_eval=t, rtol=rtol,
                    atol=atol, **kw)
    elapsed = time.perf_counter() - t0
    P = np.ascontiguousarray(np.asarray(sol.y, dtype=float).T).reshape(-1, n, n)
    tt = np.asarray(sol.t, dtype=float)
    status = Status.SOLVED if sol.success else Status.NUMERICAL_ERROR
    t_stop = tt[-1] if tt.size else 0.0
    message = "" if sol.success else f"solve_ivp ({integrator}) stopped at t = {t_stop:g}: {sol.message}"
    stats = SolverStats(backend="scipy.integrate.solve_ivp", native_status=str(sol.message),
                        time=elapsed, iterations=int(sol.nfev),
                        extra={"integrator": integrator, "rtol": rtol, "atol": atol,
                               "nfev": int(sol.nfev), "njev": int(getattr(sol, "njev", 0) or 0),
                               **why})
    scheme = f"solve_ivp {integrator} on the n^2 entries of P (rtol {rtol:.1e}, atol {atol:.1e})"
    return P, stats, status, message, scheme


def _jacobian(A: NDArray, S: NDArray):
    """The Jacobian ``Fc (x) I + I (x) Fc`` of ``vec(Fc X + X Fc')`` (row-major vec), ``Fc = A - P S``,
    for Radau (dense ``n^2 x n^2``: used only where :func:`ode_integrator` finds it affordable)."""
    n = A.shape[0]
    eye = np.eye(n)

    def jac(_t: float, y: NDArray) -> NDArray:
        Fc = A - y.reshape(n, n) @ S
        return np.kron(Fc, eye) + np.kron(eye, Fc)

    return jac


class _OutOfTime:
    """A terminal ``solve_ivp`` event that fires once the deadline has expired.

    ``solve_ivp`` evaluates events after every step; the first evaluation past the deadline
    places a root at the middle of that step (``g(t) = t_stop - t``, continuous in t), so the
    integration ends there with the output times reached so far.
    """

    terminal = True
    direction = -1.0

    def __init__(self, clock: Deadline) -> None:
        self.clock = clock
        self.t_stop = np.inf
        self.t_last = 0.0

    def __call__(self, t: float, _y: NDArray) -> float:
        if self.t_stop == np.inf and self.clock.expired:
            self.t_stop = 0.5 * (self.t_last + t)
        self.t_last = t
        return self.t_stop - t
# ------------------------------------------------------------------ discrete time
def _discrete(plant: Plant, dt: float, P0: NDArray, t_final: float, steps: int | None, t_eval,
              tol: float, post: dict, clock: Deadline) -> RiccatiTrajectory:
    dt = float(dt)
    N = int(round(t_final / dt))
    if N < 1 or abs(N * dt - t_final) > 1e-9 * t_final:
        raise ValidationError(f"t_final must be a positive multiple of dt = {dt:g} for a discrete plant; "
                              f"found t_final = {t_final:g} ({t_final / dt:.6g} steps)")
    if steps is not None and steps != N:
        raise ValidationError(f"steps is fixed by t_final / dt = {N} for a discrete plant; "
                              f"found steps = {steps}")
    if t_eval is None:
        idx = np.arange(N + 1)
    else:
        te = _as_t_eval(t_eval, t_final)
        k = np.round(te / dt)
        bad = np.abs(k * dt - te) > 1e-9 * max(dt, t_final)
        if np.any(bad):
            raise ValidationError(f"t_eval must be multiples of dt = {dt:g} for a discrete plant; found "
                                  f"{te[bad][0]:g}")
        idx = k.astype(int)
    A, C, (_, R) = plant.A, plant.C, plant.noise_covariances()
    W = plant.process_noise()
    t0 = time.perf_counter()
    Pj = _dre(A, C, W, R, P0, idx, joseph=True, clock=clock)
    elapsed = time.perf_counter() - t0
    status, message = Status.SOLVED, ""
    done = Pj.shape[0]
    if done < idx.size:
        status = Status.TIME_LIMIT
        message = _time_limit_message(clock, idx[:done] * dt, idx.size, t_final)
    err, kind = float("nan"), "not computed (estimate_error=False)"
    if post["estimate_error"] and clock.expired:
        kind = "not computed (time limit reached)"
    elif post["estimate_error"] and done:
        Ps = _dre(A, C, W, R, P0, idx[:done], joseph=False, clock=clock)
        if Ps.shape[0] == done:
            err, kind = _rel_diff(Pj, Ps), "rounding: Joseph form vs standard form of the recursion"
        else:
            kind = "not computed (time limit reached during the standard-form recursion)"
    stats = SolverStats(backend="numpy", native_status="riccati_recursion", time=elapsed,
                        iterations=int(idx[done - 1]) if done else 0,
                        extra={"completed": int(done), "requested": int(idx.size)})
    scheme = "Riccati difference equation (predictor), Joseph form"
    return _finish(plant, idx[:done] * dt, Pj, "transition", scheme, N, err, kind, 0.0, status, message,
                   stats, tol, post, clock)


def _dre(A, C, W, R, P0, idx, *, joseph: bool, clock: Deadline) -> NDArray:
    """P at the steps ``idx`` (stops early, with the steps reached, when the deadline expires)."""
    n = A.shape[0]
    out = np.empty((idx.size, n, n))
    want = {int(k): j for j, k in enumerate(idx)}
    P = P0.copy()
    done = 0
    for k in range(int(idx[-1]) + 1):
        if k in want:
            out[want[k]] = P
            done = want[k] + 1
        if k == idx[-1] or clock.expired:
            break
        Sk = C @ P @ C.T + R
        L = np.linalg.solve(Sk.T, (A @ P @ C.T).T).T          # A P C' Sk^-1
        if joseph:
            F = A - L @ C
            P = F @ P @ F.T + L @ R @ L.T + W
        else:
            P = A @ P @ A.T + W - L @ Sk @ L.T
        P = 0.5 * (P + P.T)
    return out[:done]


# ------------------------------------------------------------------ result
def _gains(plant: Plant, P: NDArray) -> NDArray:
    C, (_, R) = plant.C, plant.noise_covariances()
    if plant.is_discrete:
        A = plant.A
        out = np.empty((P.shape[0], plant.n, plant.p))
        for j, Pj in enumerate(P):
            Sk = C @ Pj @ C.T + R
            out[j] = np.linalg.solve(Sk.T, (A @ Pj @ C.T).T).T
        return out
    K = np.linalg.solve(R, C)                                   # R^-1 C (R symmetric)
    k, n = P.shape[0], plant.n
    return (P.reshape(k * n, n) @ K.T).reshape(k, n, plant.p)   # P C' R^-1, one product


def _psd_check(P: NDArray, slack: float) -> Check:
    r"""``min_k lambda_min(P_k) / max_k ||P_k||_F >= -slack``, certified cheaply.

    A Cholesky factorization of every ``P_k + tau I``, ``tau = 10 n eps max_k ||P_k||_F`` (for
    n <= ``_PSD_BATCH_MAX_N`` batched: one numpy call per chunk of at most ``_PSD_CHUNK_BYTES``, so
    no stack-sized temporaries; above it one LAPACK call per matrix in one reused buffer): if every
    factor exists, ``lambda_min(P_k) >= -tau - n eps ||P_k||`` (Cholesky's backward error), and that
    bound, ``-11 n eps``, is the value.  Otherwise the exact eigenvalues of every ``P_k`` are
    computed and their minimum is the value.
    """
    k, n = P.shape[:2]
    flat = P.reshape(k, n * n)
    scale = float(np.sqrt(np.max(np.einsum("ij,ij->i", flat, flat))))
    detail = "min_k lambda_min(P_k) / max_k ||P_k||_F (PSD within the method's error)"
    if scale > 0 and _shifted_cholesky_exists(P, 10 * n * _EPS * scale):
        return Check.at_least("P_min_eig", -11 * n * _EPS, -slack,
                              detail + f"; lower bound: every P_k + {10 * n * _EPS:.1e} max||P_k|| I "
                                       "has a Cholesky factor")
    lmin = float(np.min(np.linalg.eigvalsh(P)[:, 0]))
    return Check.at_least("P_min_eig", lmin / scale if scale > 0 else 0.0, -slack, detail)


#: largest chunk of the trajectory copied for one batched Cholesky call in :func:`_psd_check`
_PSD_CHUNK_BYTES = 1 << 22

#: largest n for the batched (numpy) Cholesky; above it one scipy ``potrf`` per matrix is faster
#: (measured, 101 matrices: n = 10 0.05 ms vs 0.25 ms, n = 20 0.25 vs 0.53, n = 25 0.90 vs 0.42,
#: n = 50 4.4 vs 1.1, n = 100 9.2 vs 3.9)
_PSD_BATCH_MAX_N = 20


def _shifted_cholesky_exists(P: NDArray, tau: float) -> bool:
    """Whether every ``P_k + tau I`` of the stack ``P`` has a Cholesky factor."""
    k, n = P.shape[:2]
    if n > _PSD_BATCH_MAX_N:
        buf = np.empty((n, n), order="F")
        for Pk in P:
            buf[...] = Pk
            buf.flat[::n + 1] += tau
            if _potrf(buf, lower=1, clean=0, overwrite_a=1)[1] != 0:
                return False
        return True
    chunk = max(1, min(k, _PSD_CHUNK_BYTES // (8 * n * n)))
    buf = np.empty((chunk, n, n))
    for s in range(0, k, chunk):
        b = buf[:min(chunk, k - s)]
        np.copyto(b, P[s:s + b.shape[0]])
        b.reshape(b.shape[0], n * n)[:, ::n + 1] += tau
        try:
            np.linalg.cholesky(b)
        except np.linalg.LinAlgError:
            return False
    return True


def _steady(plant: Plant, P: NDArray, post: dict, clock: Deadline):
    """P_steady, L_steady, steady_distance and a note (or why they are missing)."""
    from ..classical.riccati import filter_are

    if not post["steady_state"]:
        return None, None, float("nan"), ""
    if clock.expired:
        return None, None, float("nan"), "steady state not computed (time limit reached)"
    try:
        are = filter_are(plant)
    except (RiccatiError, NotObservableError) as exc:
        return None, None, float("nan"), f"no steady state: {exc}"
    dist = float("nan")
    if P.shape[0]:
        den = float(np.linalg.norm(are.P))
        num = float(np.linalg.norm(P[-1] - are.P))
        dist = num / den if den > 0 else num
    return are.P, are.L, dist, ""


def _finish(plant, t, P, method, scheme, nsteps, err, kind, asym, status, message, stats, tol,
            post, clock) -> RiccatiTrajectory:
    L = _gains(plant, P)
    P_ss, L_ss, dist, note = _steady(plant, P, post, clock)
    if note:
        message = f"{message}; {note}" if message else note
    finite = 0 if np.isfinite(np.einsum("kij,kij->", P, P)) else int(np.sum(~np.isfinite(P)))
    checks = [Check.at_most("nonfinite", finite, 0, "non-finite entries of P")]
    if P.shape[0] and finite == 0:
        checks.append(_psd_check(P, PSD_RTOL + (err if np.isfinite(err) else 0.0)))
    if post["estimate_error"] and not kind.startswith("not computed"):
        checks.append(Check.at_most("error_estimate", err if np.isfinite(err) else np.inf, tol, kind))
    if not message:
        message = f"{method}: {len(t)} times on [{t[0]:g}, {t[-1]:g}]" if len(t) else f"{method}: no output"
    return RiccatiTrajectory(
        t=np.asarray(t, dtype=float), P=P, L=L, method=method, scheme=scheme, steps=int(nsteps),
        P_steady=P_ss, L_steady=L_ss, steady_distance=dist, error_estimate=float(err),
        error_kind=kind, asymmetry=float(asym), status=status, message=message, solver_stats=stats,
        verification=Verification.of(checks), dt=plant.dt)
