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
    (:func:`optdesign.classical.bpf.riccati_flow`).  Symmetric PSD by construction, stable on
    long horizons and on stiff or unstable plants.  Error estimate: the difference from a
    recomputation with a 4x shorter base step (rounding only).  For a discrete plant: the
    Riccati recursion in Joseph form (a sum of PSD terms); error estimate: the difference from
    the standard form.
``"bpf"``
    The paper's block-pulse recursion (4.24)-(4.26) with ``steps`` blocks -- numerically the
    Crank-Nicolson transition matrix averaged over each block and then inverted, a
    second-order approximation of P at the block midpoints (see
    :mod:`optdesign.classical.bpf`).  ``t`` holds the block midpoints (or ``t_eval``, where the
    piecewise-constant expansion is only first order).  P is the symmetric part of the paper's
    ``V U^-1``; ``asymmetry`` is the relative size of the part removed.  Error estimate: the
    measured difference from the exact transition solution at the same times.  The recursion
    inverts a transition matrix taken from t = 0 (condition number ``~e^{2 Re(lambda) t}``), so it
    fails on long horizons whatever m is (``RiccatiError``; inaccurate before that, which the
    error estimate shows).
``"ode"``
    :func:`scipy.integrate.solve_ivp` on the ``n(n+1)/2`` entries of the upper triangle (so P is
    exactly symmetric), DOP853, or Radau with the analytic Jacobian when the Hamiltonian is
    stiff on the horizon; ``rtol = tol / 10^4``.  Error estimate: the measured difference from
    the exact transition solution.

References
----------
Ahn, D. S., Lim, Y. S., Lee, S. H. & Lee, M. K., "Design of Kalman filter via BPF", seed 004.
Kenney, C. S. & Leipnik, R. B., IEEE TAC 30 (1985) 962-970.
Lainiotis, D. G., IEEE TAC 21 (1976) 677-689.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._validate import as_positive_float, as_square, as_vector, check_psd
from ..classical.bpf import bpf_evaluate, bpf_riccati, filter_hamiltonian, riccati_flow
from ..errors import NotObservableError, RiccatiError, ValidationError
from ..model.plant import Plant
from ..results import Check, ResultMixin, SolverStats, Status, Verification

__all__ = ["RiccatiTrajectory", "riccati_de", "DEFAULT_TOL", "DEFAULT_STEPS", "PSD_RTOL"]

_METHODS = ("transition", "bpf", "ode")

#: default accuracy demanded by the ``error_estimate`` check, per method
DEFAULT_TOL: dict[str, float] = {"transition": 1e-8, "ode": 1e-8, "bpf": 1e-2}

#: default number of output intervals (transition, ode) or blocks (bpf)
DEFAULT_STEPS = 100

#: smallest eigenvalue accepted as PSD: >= -(PSD_RTOL + method error) * max_k ||P_k||_2
PSD_RTOL = 1e-10

#: the ODE method switches from DOP853 to Radau when rho(M) t_final exceeds this
STIFF_RHO_T = 3e3

_EPS = float(np.finfo(float).eps)


@dataclass(frozen=True, eq=False)
class RiccatiTrajectory(ResultMixin):
    r"""Solution of the filter Riccati differential / difference equation.

    Attributes
    ----------
    t : (k,) ndarray
        Times.  ``"transition"``/``"ode"``: ``linspace(0, t_final, steps + 1)`` or ``t_eval``;
        ``"bpf"``: the block midpoints or ``t_eval``; discrete: ``k dt``.
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
        (discrete).
    P_steady, L_steady : ndarray or None
        Stabilizing solution of the algebraic Riccati equation and its gain (None when none
        exists; ``message`` says why).
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
        ``SOLVED``, or ``NUMERICAL_ERROR`` when the ODE integrator stopped early (then ``t``
        and ``P`` hold what was computed).
    message : str
    solver_stats : SolverStats
        ``time`` excludes the error estimate; ``extra`` holds method details (doublings,
        restarts, nfev, rtol, ...).
    verification : Verification
        ``nonfinite`` (count, must be 0), ``P_min_eig`` (``min_k lambda_min(P_k) /
        max_k ||P_k||_2 >= -(1e-10 + error_estimate)``: PSD to within the method's accuracy),
        ``error_estimate`` (``<= tol``).
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
    status: Status
    message: str
    solver_stats: SolverStats
    verification: Verification
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
        return (f"RiccatiTrajectory({self.method}, {kind}, n={self.P.shape[1]}, {len(self)} times "
                f"in [{self.t[0]:g}, {self.t[-1]:g}], error~{self.error_estimate:.1e}, "
                f"status={self.status.value}, success={self.success})")


# ------------------------------------------------------------------ validation
def _as_steps(value) -> int | None:
    if value is None:
        return None
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise ValidationError(f"steps must be a positive integer; found {value!r}")
    if value < 1:
        raise ValidationError(f"steps must be a positive integer; found {value}")
    return int(value)


def _as_t_eval(t_eval, t_final: float) -> NDArray[np.float64] | None:
    if t_eval is None:
        return None
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
    if P.shape[0] == 0:
        return float("nan")
    den = float(np.max(np.linalg.norm(Pref, axis=(1, 2))))
    num = float(np.max(np.linalg.norm(P - Pref, axis=(1, 2))))
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

    Returns
    -------
    RiccatiTrajectory

    Raises
    ------
    ValidationError
        Not a Plant, no Q or R, unknown method, bpf/ode on a discrete plant, t_final not
        positive (discrete: not a multiple of dt), steps not a positive integer (discrete: not
        ``t_final/dt``), t_eval empty / not increasing / outside ``[0, t_final]`` (discrete: not
        multiples of dt), steps and t_eval both given for transition/ode, tol not positive.
    DimensionError, NotFiniteError, NotSymmetricError, NotPositiveSemidefiniteError
        Bad P0 (the message names P0).
    RiccatiError
        bpf: a transition-matrix coefficient or ``U`` block singular to working precision (long
        horizon); transition: the filter's transient growth needs more restarts than allowed (the
        message suggests method="ode").

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
    if not isinstance(plant, Plant):
        raise ValidationError(f"plant must be an optdesign.Plant; found {type(plant).__name__}")
    if method not in _METHODS:
        raise ValidationError(f"method must be one of {', '.join(repr(m) for m in _METHODS)}; "
                              f"found {method!r}")
    plant.require_noise_model()
    n = plant.n
    P0 = check_psd("P0", as_square("P0", P0, n))
    t_final = as_positive_float("t_final", t_final)
    steps = _as_steps(steps)
    tol_v = DEFAULT_TOL[method] if tol is None else as_positive_float("tol", tol)
    if plant.is_discrete:
        if method != "transition":
            raise ValidationError(
                f"method {method!r} applies to continuous-time plants; plant has dt = {plant.dt:g}: its "
                f"Riccati difference equation is solved exactly by method='transition'")
        return _discrete(plant, P0, t_final, steps, t_eval, tol_v, estimate_error)
    t_eval = _as_t_eval(t_eval, t_final)
    if method != "bpf" and steps is not None and t_eval is not None:
        raise ValidationError(f"give steps or t_eval, not both (method={method!r} returns P at t_eval)")

    W = plant.process_noise()
    M = filter_hamiltonian(plant.A, plant.C, W, plant.R)
    status, message = Status.SOLVED, ""
    asym = 0.0
    if method == "bpf":
        m = steps if steps is not None else DEFAULT_STEPS
        t0 = time.perf_counter()
        res = bpf_riccati(M, P0, t_final, m)
        if t_eval is None:
            t, P = res.t, res.P
        else:
            t, P = t_eval, bpf_evaluate(res.P, t_final, t_eval)
        elapsed = time.perf_counter() - t0
        big = float(np.max(np.linalg.norm(res.P, axis=(1, 2))))
        asym = float(np.max(res.asymmetry)) / big if big > 0 else 0.0
        scheme = (f"block-pulse recursion (4.24)-(4.26), m = {m} blocks of h = {res.h:.4g} "
                  f"(Crank-Nicolson, block-averaged; order 2 at block midpoints)")
        stats = SolverStats(backend="numpy", native_status="bpf", time=elapsed, iterations=m,
                            extra={"h": res.h, "max_asymmetry": asym})
        nsteps = m
    else:
        nsteps = steps if steps is not None else DEFAULT_STEPS
        t = t_eval if t_eval is not None else np.linspace(0.0, t_final, nsteps + 1)
        if t_eval is not None:
            nsteps = int(t.size) - int(t[0] == 0.0)
        t0 = time.perf_counter()
        if method == "transition":
            P, info = riccati_flow(M, P0, t)
            elapsed = time.perf_counter() - t0
            scheme = ("exact Hamiltonian transition matrix: Lainiotis partitioned form, doubling "
                      f"({info['doublings']} per interval), restarted at every output time")
            stats = SolverStats(backend="numpy", native_status="riccati_flow", time=elapsed,
                                iterations=info["substeps"], extra=dict(info))
        else:
            P, t, stats, status, message, scheme = _ode(M, P0, t, tol_v)
    # ---- error estimate
    err, kind = float("nan"), "not computed (estimate_error=False)"
    if estimate_error and P.shape[0]:
        if method == "transition":
            try:
                P2, _ = riccati_flow(M, P0, t, max_norm=0.125)
                err, kind = _rel_diff(P, P2), "rounding: recomputed with a 4x shorter base step"
            except RiccatiError as exc:  # pragma: no cover - the finer base step failed only
                kind = f"unavailable: the recomputation failed ({exc})"
        else:
            try:
                Pref, _ = riccati_flow(M, P0, t)
                err = _rel_diff(P, Pref)
                kind = "measured: difference from the exact transition-matrix solution at t"
            except RiccatiError as exc:
                kind = f"unavailable: the exact reference failed ({exc})"
    return _finish(plant, t, P, method, scheme, nsteps, err, kind, asym, status, message, stats,
                   tol_v, estimate_error)


# ------------------------------------------------------------------ ODE reference
def _ode(M: NDArray, P0: NDArray, t: NDArray, tol: float):
    from scipy.integrate import solve_ivp

    n = P0.shape[0]
    A, S, W = M[n:, n:], M[:n, n:], M[n:, :n]
    iu = np.triu_indices(n)
    N = iu[0].size

    def unpack(y: NDArray) -> NDArray:
        X = np.zeros((n, n))
        X[iu] = y
        return X + np.triu(X, 1).T

    def rhs(_t: float, y: NDArray) -> NDArray:
        P = unpack(y)
        H = A @ P - 0.5 * (P @ S @ P)
        return (H + H.T + W)[iu]

    # Jacobian of vech(Fc X + X Fc'), Fc = A - P S, on symmetric X (for the implicit solver)
    D = np.zeros((n * n, N))
    for c, (i, j) in enumerate(zip(*iu, strict=True)):
        D[i * n + j, c] = 1.0
        D[j * n + i, c] = 1.0
    sel = iu[0] * n + iu[1]
    eye = np.eye(n)

    def jac(_t: float, y: NDArray) -> NDArray:
        Fc = A - unpack(y) @ S
        K = np.kron(Fc, eye) + np.kron(eye, Fc)      # row-major vec of Fc X + X Fc'
        return (K @ D)[sel]

    t_final = float(t[-1]) if t[-1] > 0 else 1.0
    rho = float(np.max(np.abs(np.linalg.eigvals(M))))
    stiff = rho * t_final > STIFF_RHO_T
    integrator = "Radau" if stiff else "DOP853"
    rtol = max(100 * _EPS, tol * 1e-4)
    scale = max(float(np.max(np.abs(P0))), float(np.max(np.abs(W))) * min(t_final, 1.0),
                np.finfo(float).tiny)
    atol = rtol * 1e-3 * scale
    kw = {"jac": jac} if stiff else {}
    t0 = time.perf_counter()
    sol = solve_ivp(rhs, (0.0, float(t[-1])), P0[iu], method=integrator, t_eval=t, rtol=rtol,
                    atol=atol, **kw)
    elapsed = time.perf_counter() - t0
    P = np.array([unpack(sol.y[:, j]) for j in range(sol.y.shape[1])]).reshape(-1, n, n)
    tt = np.asarray(sol.t, dtype=float)
    status = Status.SOLVED if sol.success else Status.NUMERICAL_ERROR
    t_stop = tt[-1] if tt.size else 0.0
    message = "" if sol.success else f"solve_ivp ({integrator}) stopped at t = {t_stop:g}: {sol.message}"
    stats = SolverStats(backend="scipy.integrate.solve_ivp", native_status=str(sol.message),
                        time=elapsed, iterations=int(sol.nfev),
                        extra={"integrator": integrator, "rtol": rtol, "atol": atol,
                               "nfev": int(sol.nfev), "njev": int(getattr(sol, "njev", 0) or 0),
                               "stiff": stiff})
    scheme = f"solve_ivp {integrator} on vech(P) (rtol {rtol:.1e}, atol {atol:.1e})"
    return P, tt, stats, status, message, scheme


# ------------------------------------------------------------------ discrete time
def _discrete(plant: Plant, P0: NDArray, t_final: float, steps: int | None, t_eval, tol: float,
              estimate_error: bool) -> RiccatiTrajectory:
    dt = float(plant.dt)
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
    A, C, R = plant.A, plant.C, plant.R
    W = plant.process_noise()
    t0 = time.perf_counter()
    Pj = _dre(A, C, W, R, P0, idx, joseph=True)
    elapsed = time.perf_counter() - t0
    err, kind = float("nan"), "not computed (estimate_error=False)"
    if estimate_error:
        Ps = _dre(A, C, W, R, P0, idx, joseph=False)
        err, kind = _rel_diff(Pj, Ps), "rounding: Joseph form vs standard form of the recursion"
    stats = SolverStats(backend="numpy", native_status="riccati_recursion", time=elapsed,
                        iterations=int(idx[-1]), extra={})
    scheme = "Riccati difference equation (predictor), Joseph form"
    return _finish(plant, idx * dt, Pj, "transition", scheme, N, err, kind, 0.0, Status.SOLVED, "",
                   stats, tol, estimate_error)


def _dre(A, C, W, R, P0, idx, *, joseph: bool) -> NDArray:
    n = A.shape[0]
    out = np.empty((idx.size, n, n))
    want = {int(k): j for j, k in enumerate(idx)}
    P = P0.copy()
    for k in range(int(idx[-1]) + 1):
        if k in want:
            out[want[k]] = P
        if k == idx[-1]:
            break
        Sk = C @ P @ C.T + R
        L = np.linalg.solve(Sk.T, (A @ P @ C.T).T).T          # A P C' Sk^-1
        if joseph:
            F = A - L @ C
            P = F @ P @ F.T + L @ R @ L.T + W
        else:
            P = A @ P @ A.T + W - L @ Sk @ L.T
        P = 0.5 * (P + P.T)
    return out


# ------------------------------------------------------------------ result
def _gains(plant: Plant, P: NDArray) -> NDArray:
    C, R = plant.C, plant.R
    if plant.is_discrete:
        A = plant.A
        out = np.empty((P.shape[0], plant.n, plant.p))
        for j, Pj in enumerate(P):
            Sk = C @ Pj @ C.T + R
            out[j] = np.linalg.solve(Sk.T, (A @ Pj @ C.T).T).T
        return out
    CP = C @ P                                                  # (k, p, n)
    return np.swapaxes(np.linalg.solve(R[None], CP), 1, 2) if P.shape[0] else np.empty((0, plant.n, plant.p))


def _finish(plant, t, P, method, scheme, nsteps, err, kind, asym, status, message, stats, tol,
            estimate_error) -> RiccatiTrajectory:
    from ..classical.riccati import filter_are

    L = _gains(plant, P)
    P_ss = L_ss = None
    dist = float("nan")
    try:
        are = filter_are(plant)
        P_ss, L_ss = are.P, are.L
        if P.shape[0]:
            den = float(np.linalg.norm(P_ss))
            num = float(np.linalg.norm(P[-1] - P_ss))
            dist = num / den if den > 0 else num
    except (RiccatiError, NotObservableError) as exc:
        note = f"no steady state: {exc}"
        message = f"{message}; {note}" if message else note
    finite = int(np.sum(~np.isfinite(P)))
    checks = [Check.at_most("nonfinite", finite, 0, "non-finite entries of P")]
    if P.shape[0] and finite == 0:
        big = float(np.max(np.linalg.norm(P, 2, axis=(1, 2))))
        lmin = float(np.min(np.linalg.eigvalsh(P)[:, 0]))
        rel = lmin / big if big > 0 else 0.0
        slack = PSD_RTOL + (err if method in ("bpf", "ode") and np.isfinite(err) else 0.0)
        checks.append(Check.at_least("P_min_eig", rel, -slack,
                                     "min_k lambda_min(P_k) / max_k ||P_k||_2 "
                                     "(PSD within the method's error)"))
    if estimate_error:
        checks.append(Check.at_most("error_estimate", err if np.isfinite(err) else np.inf, tol, kind))
    if not message:
        message = f"{method}: {len(t)} times on [{t[0]:g}, {t[-1]:g}]" if len(t) else f"{method}: no output"
    return RiccatiTrajectory(
        t=np.asarray(t, dtype=float), P=P, L=L, method=method, scheme=scheme, steps=int(nsteps),
        P_steady=P_ss, L_steady=L_ss, steady_distance=dist, error_estimate=float(err),
        error_kind=kind, asymmetry=float(asym), status=status, message=message, solver_stats=stats,
        verification=Verification.of(checks), dt=plant.dt)
