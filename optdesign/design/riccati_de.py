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
    scipy's DOP853 on the ``n^2`` entries of P (the right-hand side ``H + H' + W - B B'``,
    ``B = P C' R^-1/2``, is exactly symmetric, so P stays exactly symmetric), stepped directly;
    tolerances from the accuracy asked, ``rtol = 1e-4 tol`` and an absolute tolerance that follows
    the size of P (``ode_tolerances``: a fixed absolute
    tolerance below the right-hand side's rounding floor made the step collapse, issue 26);
    Radau with the analytic Jacobian only when the horizon spans more than
    ``STIFF_RHO_T`` time constants of the Hamiltonian *and* Radau's ``n^2 x n^2`` linear algebra
    costs no more than a right-hand side (:func:`ode_integrator`).  Error estimate (computed by
    default): the measured difference from the exact transition solution.

Cost and time limits
--------------------
Post-processing is done only when asked (issue 26): ``steady_state=True`` (one algebraic Riccati
solve, as costly as the whole trajectory at n = 100) and, for ``"transition"`` and discrete plants,
``estimate_error=True`` (a second exact solve: it doubles the cost).  ``"bpf"`` and ``"ode"``
measure their error by default (``estimate_error=None``): one exact solve, a small part of their
own cost.  Requests that cannot run are refused up front (:class:`ValidationError` naming
``steps``, ``t_eval`` or ``t_final``): more than ``MAX_TRAJECTORY_BYTES`` (2 GiB) for the
trajectory, ``8 k (3 n^2 + n p)`` bytes for k output times, or, without a ``time_limit``, an
estimated run time over ``MAX_SECONDS_UNLIMITED`` (1 h; ``10 n^3`` flops and a call overhead
per interval, block or recursion step).
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
from ..classical.transition import riccati_flow
from ..errors import NotObservableError, RiccatiError, ValidationError
from ..model.coerce import as_plant
from ..model.plant import Plant
from ..results import Check, DesignResult, Route, SolverStats, Stage, Status, Verification
from .riccati_ode import (
    ATOL_PER_RTOL,
    RHS_OVERHEAD_FLOPS,
    RTOL_PER_TOL,
    STIFF_RHO_T,
    gain_factor,
    integrate,
    ode_integrator,
    ode_tolerances,
)

__all__ = ["RiccatiTrajectory", "riccati_de", "ode_integrator", "ode_tolerances", "DEFAULT_TOL",
           "DEFAULT_STEPS", "PSD_RTOL", "STIFF_RHO_T", "RTOL_PER_TOL", "ATOL_PER_RTOL",
           "MAX_TRAJECTORY_BYTES", "MAX_SECONDS_UNLIMITED"]

_METHODS = ("transition", "bpf", "ode")

#: default accuracy demanded by the ``error_estimate`` check, per method
DEFAULT_TOL: dict[str, float] = {"transition": 1e-8, "ode": 1e-8, "bpf": 1e-2}

#: default number of output intervals (transition, ode) or blocks (bpf)
DEFAULT_STEPS = 100

#: smallest eigenvalue accepted as PSD: >= -(PSD_RTOL + method error) * max_k ||P_k||_F
PSD_RTOL = 1e-10


_EPS = float(np.finfo(float).eps)

#: largest memory the trajectory may need (P, gains, the ODE's output and the error estimate's
#: reference: ``8 k (3 n^2 + n p)`` bytes for k output times); larger requests are refused up front
MAX_TRAJECTORY_BYTES = 2 * 1024**3

#: largest estimated run time (seconds) accepted without a ``time_limit``: ``steps`` intervals,
#: blocks or recursion steps of ``10 n^3`` flops plus ``RHS_OVERHEAD_FLOPS`` each, at ``_FLOPS``
MAX_SECONDS_UNLIMITED = 3600.0

#: sustained flop rate assumed by the run-time estimate (one core, n^3 BLAS-3 work; conservative)
_FLOPS = 2e9


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
    route : Route
        One stage, what ran: ``riccati_flow`` [engine] (transition), ``bpf_riccati`` [engine],
        ``scipy.integrate.DOP853`` or ``scipy.integrate.Radau`` [backend] (ode),
        ``riccati_recursion`` [direct] (discrete); outcome ``answered``, or the status when the
        run stopped early.
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
    rtol: float | None = None,
    atol: float | None = None,
    estimate_error: bool | None = None,
    steady_state: bool = False,
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
        Relative error asked of P, ``max_k ||P_k - P(t_k)||_F / max_k ||P(t_k)||_F`` (default
        1e-8; bpf 1e-2): the ``error_estimate`` check demands it, and for ``"ode"`` it sets the
        integrator's tolerances (``rtol = 1e-4 tol``: measured to meet ``tol``, see
        ``ode_tolerances``).
    rtol : float, optional
        ``"ode"`` only: relative error allowed per integrator step on each entry of P, in
        ``[100 eps, 1)`` (overrides the default ``1e-4 tol``).  The error delivered is a
        multiple of it: 0.02-500x measured, the large factors on stiff horizons.
    atol : float, optional
        ``"ode"`` only: absolute error allowed per step on each entry of P, in the units of P
        (> 0, fixed).  Default: ``1e-3 rtol max_ij |P_ij|``, following the largest entry met.
    estimate_error : bool, optional
        Compute ``error_estimate`` (one extra exact solve); if False it is nan and the
        ``error_estimate`` check is left out.  Default (None): True for ``"bpf"`` and ``"ode"``,
        False for ``"transition"`` (where it would double the cost).
    steady_state : bool
        Solve the algebraic Riccati equation for ``P_steady``, ``L_steady`` and
        ``steady_distance`` (one ARE solve); default False: they are None / nan.
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
        estimate_error or steady_state not a bool, time_limit not a number of seconds > 0,
        rtol / atol not a number > 0 (rtol in ``[100 eps, 1)``) or given with another method
        than "ode"; a trajectory too large to store or (without time_limit) to compute in an
        hour: the message names steps, t_eval or t_final and the estimate.
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
    >>> traj = riccati_de(plant, np.zeros((2, 2)), 10.0, steady_state=True)
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
    if method != "ode" and (rtol is not None or atol is not None):
        name = "rtol" if rtol is not None else "atol"
        raise ValidationError(f"{name} applies to method='ode' (the integrator's tolerance); found "
                              f"{name}={rtol if rtol is not None else atol!r} with method={method!r}")
    ode_tols = ode_tolerances(tol_v, rtol=rtol, atol=atol) if method == "ode" else {}
    if estimate_error is None:                  # the approximate methods measure their error
        estimate_error = method in ("bpf", "ode")
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
    nout = t_eval.size if t_eval is not None else (steps or DEFAULT_STEPS) + (method != "bpf")
    work = (steps or DEFAULT_STEPS) if method == "bpf" else nout if method == "transition" else 0
    name = "t_eval" if t_eval is not None and (method != "bpf" or steps is None) else "steps"
    _check_size(n, plant.p, nout + (steps or DEFAULT_STEPS if method == "bpf" else 0), work, name,
                clock.limit)
    return _continuous(plant, P0, t_final, method, steps, t_eval, tol_v, ode_tols, post, clock)


def _continuous(plant: Plant, P0: NDArray, t_final: float, method: str, steps: int | None,
                t_eval: NDArray | None, tol: float, ode_tols: dict, post: dict,
                clock: Deadline) -> RiccatiTrajectory:
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
            P, stats, status, message, scheme = integrate(M, gain_factor(plant), P0, t, ode_tols, clock)
        t = t[:P.shape[0]]
    if P.shape[0] < requested and status is Status.SOLVED:
        status = Status.TIME_LIMIT
        message = _time_limit_message(clock, t, requested, t_final)
    stats.extra.update(completed=int(P.shape[0]), requested=int(requested))
    err, kind, floor = _error_estimate(M, P0, t, P, method, post["estimate_error"], clock)
    return _finish(plant, t, P, method, scheme, nsteps, err, kind, asym, status, message, stats,
                   tol, post, clock, floor=floor)


def _check_size(n: int, p: int, outputs: int, work_steps: int, name: str, time_limit,
                work_name: str | None = None) -> None:
    """Refuse up front a trajectory that cannot be stored or would run for hours (see
    ``MAX_TRAJECTORY_BYTES`` and ``MAX_SECONDS_UNLIMITED``); ``name`` (``work_name`` for the run
    time, default ``name``) is the argument to blame."""
    need = 8.0 * outputs * (3.0 * n * n + n * p)
    if need > MAX_TRAJECTORY_BYTES:
        raise ValidationError(
            f"{name} asks to store {outputs:,} matrices of {n} x {n} (output times, blocks): about "
            f"{need / 2**30:.3g} GiB, "
            f"more than the {MAX_TRAJECTORY_BYTES / 2**30:g} GiB allowed (MAX_TRAJECTORY_BYTES); ask for fewer "
            f"output times (steps or t_eval)")
    seconds = work_steps * (10.0 * n**3 + RHS_OVERHEAD_FLOPS) / _FLOPS
    if time_limit is None and seconds > MAX_SECONDS_UNLIMITED:
        raise ValidationError(
            f"{work_name or name} asks for {work_steps:,} steps of n = {n}: about {seconds:.3g} s, more than the "
            f"{MAX_SECONDS_UNLIMITED:g} s accepted without a time limit (MAX_SECONDS_UNLIMITED); ask for "
            f"fewer or pass time_limit=")


def _time_limit_message(clock: Deadline, t: NDArray, requested: int, t_final: float) -> str:
    where = f"on [0, {t[-1]:g}]" if len(t) else "at no time"
    limit = float(clock.limit or 0.0)
    return (f"time limit of {limit:g} s reached: P computed {where}, {len(t)} of {requested} output "
            f"times (horizon {t_final:g}); the rest was not computed")


def _error_estimate(M: NDArray, P0: NDArray, t: NDArray, P: NDArray, method: str, wanted: bool,
                    clock: Deadline) -> tuple[float, str, float]:
    """``(error, how it was obtained, the reference's own rounding level)``: for ``bpf`` and ``ode`` the
    difference from the exact transition-matrix solution, whose rounding is measured by recomputing it
    from a 4x shorter base step (the check allows ``tol`` plus twice that level: on a plant whose P grows
    by 1e7 the exact flow itself is accurate to about 1e-8 under some BLAS kernels)."""
    nan = float("nan")
    if not wanted:
        return nan, "not computed (estimate_error=False)", 0.0
    if clock.expired:
        return nan, "not computed (time limit reached)", 0.0
    if not P.shape[0]:
        return nan, "not computed (no output)", 0.0
    if method == "transition":
        try:
            P2, _ = riccati_flow(M, P0, t, max_norm=0.125, direct=False, deadline=clock)
        except RiccatiError as exc:  # pragma: no cover - the finer base step failed only
            return nan, f"unavailable: the recomputation failed ({exc})", 0.0
        if P2.shape[0] < P.shape[0]:
            return nan, "not computed (time limit reached during the recomputation)", 0.0
        return _rel_diff(P, P2), "rounding: recomputed by doubling from a 4x shorter base step", 0.0
    try:
        Pref, _ = riccati_flow(M, P0, t, deadline=clock)
        Pfine, _ = riccati_flow(M, P0, t, max_norm=0.125, direct=False, deadline=clock)
    except RiccatiError as exc:
        return nan, f"unavailable: the exact reference failed ({exc})", 0.0
    if min(Pref.shape[0], Pfine.shape[0]) < P.shape[0]:
        return nan, "not computed (time limit reached during the exact reference)", 0.0
    floor = _rel_diff(Pref, Pfine)
    return (_rel_diff(P, Pref), f"measured: difference from the exact transition-matrix solution at t "
            f"(its own rounding {floor:.1e})", floor)


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
    _check_size(plant.n, plant.p, idx.size, N, "t_eval" if t_eval is not None else "t_final", clock.limit,
                work_name="t_final")
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


def _route(method: str, scheme: str, status: Status, stats: SolverStats) -> Route:
    """One stage: the engine (or the scipy integrator) that produced the trajectory."""
    if method == "ode":
        name, kind = stats.backend, "backend"
    elif method == "bpf":
        name, kind = "bpf_riccati", "engine"
    elif stats.native_status == "riccati_recursion":
        name, kind = "riccati_recursion", "direct"
    else:
        name, kind = "riccati_flow", "engine"
    outcome = "answered" if status is Status.SOLVED else status.value
    return Route([Stage(name, kind, outcome, scheme, stats.time)])


def _finish(plant, t, P, method, scheme, nsteps, err, kind, asym, status, message, stats, tol,
            post, clock, *, floor: float = 0.0) -> RiccatiTrajectory:
    L = _gains(plant, P)
    P_ss, L_ss, dist, note = _steady(plant, P, post, clock)
    if note:
        message = f"{message}; {note}" if message else note
    finite = 0 if np.isfinite(np.einsum("kij,kij->", P, P)) else int(np.sum(~np.isfinite(P)))
    checks = [Check.at_most("nonfinite", finite, 0, "non-finite entries of P")]
    if P.shape[0] and finite == 0:
        checks.append(_psd_check(P, PSD_RTOL + (err if np.isfinite(err) else 0.0)))
    if post["estimate_error"] and not kind.startswith("not computed"):
        checks.append(Check.at_most("error_estimate", err if np.isfinite(err) else np.inf, tol + 2.0 * floor,
                                    kind))
    if not message:
        message = f"{method}: {len(t)} times on [{t[0]:g}, {t[-1]:g}]" if len(t) else f"{method}: no output"
    return RiccatiTrajectory(
        route=_route(method, scheme, status, stats),
        t=np.asarray(t, dtype=float), P=P, L=L, method=method, scheme=scheme, steps=int(nsteps),
        P_steady=P_ss, L_steady=L_ss, steady_distance=dist, error_estimate=float(err),
        error_kind=kind, asymmetry=float(asym), status=status, message=message, solver_stats=stats,
        verification=Verification.of(checks), dt=plant.dt)
