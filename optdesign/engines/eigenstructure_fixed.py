r"""Fixed-pole well-conditioned placement on the eigenstructure engine: starts, solve, outcome.

:func:`place_fixed` is the functional entry point of the engine of
:mod:`optdesign.engines.eigenstructure` (issue 13): it takes scipy's robust placement (YT, KNV0:
one sweep each) and random eigenvector coordinates as starts, minimizes the objective from all of
them in lockstep (:func:`~optdesign.engines.quasi_newton.bfgs_minimize_batch`) through the kappa2
continuation, and returns a :class:`PlacementOutcome` -- not verified: the design layer verifies
it independently (eigenvalues of ``A - L C``, the eigen-residual of ``V``, kappa2 agreement).

One output (``rank C = 1``, no unobservable mode among the poles): the gain is unique and is
computed directly (status ``solved``), as Ackermann's formula or YT would give it, at the cost of
YT (one QR per pole).

References
----------
Kautsky, Nichols & Van Dooren (1985); Tits & Yang (1996); Lewis & Overton (2013).
"""

from __future__ import annotations

import dataclasses
import math
import time
import warnings
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._deadline import Deadline
from .._validate import as_gain_mask, as_int, as_poles
from ..analysis import metrics
from ..errors import DimensionError, NotObservableError, ValidationError
from ..results import Status
from .eigenstructure import (
    KAPPA2_CONTINUATION,
    OBJECTIVES,
    EigenstructureEngine,
    FixedPoleModel,
    Measure,
    Objective,
    pole_multiplicities,
    spread_poles,
)
from .quasi_newton import bfgs_minimize_batch
from .tolerances import (
    DISTINCT_F_MIN,
    DISTINCT_FTOL_MIN,
    DISTINCT_X_MIN,
    MASK_TOL,
    STAGE_FTOL,
    STAGE_FTOL_DEFAULT,
    STAGE_GTOL,
)

__all__ = [
    "StartRecord",
    "PlacementOutcome",
    "place_fixed",
    "default_starts",
    "peer_start",
    "run_starts",
    "masked_solve",
    "MASK_TOL",
]


# --------------------------------------------------------------------------- records


@dataclass(frozen=True)
class StartRecord:
    """One start of :func:`place_fixed`.

    Attributes
    ----------
    origin : str
        ``"YT"``, ``"KNV0"``, ``"random"``, ``"warm start"``, ``"unique"``.
    kappa2 : float
        Condition number of the start's final eigenbasis (the engine's ``V``).
    objective_value : float
        The objective metric (kappa2, kappa_fro or eta) at the start's end.
    start_value : float
        The objective metric at the start point (inf if it was not a valid start).
    iterations, evaluations : int
        BFGS steps and objective evaluations over all stages.
    reason : str
        Why the last stage stopped.
    time : float
        CPU seconds.
    last_iterations : int
        BFGS steps of the last continuation stage (the exact objective).
    last_decrease : float
        Relative decrease of the objective over the last iterations of that stage
        (``QNResult.decrease`` of :mod:`optdesign.engines.quasi_newton`).
    L : (n, p) ndarray or None
        The start's final gain (None when it has none), so that a caller can verify every start.
    V : (n, n) ndarray of complex or None
        Its unit-column eigenvector matrix (the engine's), when the engine has it.
    poles : (n,) ndarray of complex or None
        The poles of ``V``'s columns (region mode: the start's own final poles).
    """

    origin: str
    kappa2: float
    objective_value: float
    start_value: float
    iterations: int
    evaluations: int
    reason: str
    time: float
    L: NDArray[np.float64] | None = field(default=None, repr=False)
    V: NDArray[np.complex128] | None = field(default=None, repr=False)
    poles: NDArray[np.complex128] | None = field(default=None, repr=False)
    last_iterations: int = 0
    last_decrease: float = math.nan


@dataclass(frozen=True)
class PlacementOutcome:
    """What the engine found (not verified: the design layer verifies it independently).

    Attributes
    ----------
    L : (n, p) ndarray
        The gain; ``A - L C`` has the poles ``poles`` (up to rounding).
    V : (n, n) ndarray of complex
        Unit-column right eigenvectors of ``A - L C`` (column ``j`` for ``poles[j]``).
    poles : (n,) ndarray of complex
        The placed poles, in the order of ``V``'s columns (real, then pairs ``z, conj z``).
    kappa2, kappa_fro : float
        Condition numbers of ``V`` (2-norm, Frobenius).
    objective : str
    objective_value : float
        The objective metric at ``L`` (kappa2, kappa_fro or eta).
    status : Status
        ``solved`` (unique gain, or ``rank C = n``), ``optimal`` (a local minimum from the best
        start), ``iteration_limit``, ``time_limit`` (best so far), ``not_found`` (no start gave a
        finite objective).
    message : str
    iterations, evaluations : int
        Totals over all starts.
    starts : tuple of StartRecord
    coords : (m,) ndarray
        The eigenvector coordinates of the solution (a warm start for the same poles).
    unique : bool
        One output: the gain is determined by the poles.
    requested_poles : (n,) ndarray of complex
        What the caller asked for (differs from ``poles`` for a spread, nearest distinct design).
    separation : float or None
        The separation used by a nearest distinct-pole design.
    time : float
        CPU seconds.
    """

    L: NDArray[np.float64]
    V: NDArray[np.complex128]
    poles: NDArray[np.complex128]
    kappa2: float
    kappa_fro: float
    objective: str
    objective_value: float
    status: Status
    message: str
    iterations: int = 0
    evaluations: int = 0
    starts: tuple[StartRecord, ...] = ()
    coords: NDArray[np.float64] | None = None
    unique: bool = False
    requested_poles: NDArray[np.complex128] | None = None
    separation: float | None = None
    time: float = 0.0
    extra: dict[str, Any] = field(default_factory=dict)


# --------------------------------------------------------------------------- the solver


def peer_start(A: NDArray, C: NDArray, poles: NDArray, method: str) -> NDArray[np.float64] | None:
    """One sweep of scipy's robust placement (YT / KNV0) on the dual, or None if it refuses.

    One sweep, not scipy's default 30: the start is optimized anyway, and the sweeps are what
    costs (measured on random plants: one sweep gives kappa2 within 10 % of 30 sweeps at n = 20
    and 50, at 1/30 of the time -- 0.22 s against 6.1 s at n = 50, p = 10).
    """
    from scipy.signal import place_poles

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            L = place_poles(A.T, C.T, poles, method=method, maxiter=1).gain_matrix.T
    except (ValueError, np.linalg.LinAlgError):
        return None
    return L if np.all(np.isfinite(L)) else None


# the stage tolerances (STAGE_FTOL per order k of the kappa2 bound, STAGE_GTOL on the smooth
# stages), the duplicate-start tests and MASK_TOL are in engines/tolerances.py with their measurements


def run_starts(
    model: FixedPoleModel,
    X0: NDArray,
    objective: str,
    deadline: Deadline,
    max_iter: int,
    stages: tuple[int | None, ...],
    *,
    report: dict[int, tuple[int, float]] | None = None,
    final_ftol: float | None = None,
) -> list[tuple[NDArray, int, int, str]]:
    """Minimize from every row of ``X0`` through the continuation ``stages``.

    All starts run in lockstep (:func:`~optdesign.engines.quasi_newton.bfgs_minimize_batch`), each
    start's inverse-Hessian approximation carried from stage to stage.  After every stage, starts
    that reached the same point as an earlier one (same value to 1e-9, same normalized coordinates
    to 1e-6) stop there: they would follow the same path (measured on random n = 4..6 plants: of 8
    starts, 4 to 6 typically end in two or three basins).  Per start
    ``(x, iterations, evaluations, reason)``; a dropped start reports ``"duplicate"``.
    ``report`` (a dict, filled): per start index, ``(iterations, relative decrease)`` of the last
    stage it ran.  ``final_ftol``: the decrease tolerance of the last stage (default its own).
    """
    X = np.array(X0, dtype=float)
    s = X.shape[0]
    its, evs, reasons = np.zeros(s, int), np.zeros(s, int), ["converged"] * s
    H: list[NDArray | None] = [None] * s
    alive = list(range(s))
    for si, k in enumerate(stages):
        ftol = STAGE_FTOL.get(k, STAGE_FTOL_DEFAULT)
        if final_ftol is not None and si == len(stages) - 1:
            ftol = final_ftol
        if deadline.expired:
            for i in alive:
                reasons[i] = "time_limit"
            break

        def fun(Z, _k=k):
            return model.evaluate_batch(Z, objective, _k)

        res, Hs = bfgs_minimize_batch(
            fun, X[alive], max_iter=max_iter, ftol=ftol, gtol=0.0 if k is None else STAGE_GTOL,
            deadline=deadline, H0=[H[i] for i in alive],
        )
        for j, (i, r) in enumerate(zip(alive, res, strict=True)):
            X[i], H[i] = r.x, Hs[j]
            its[i] += r.iterations
            evs[i] += r.evaluations
            reasons[i] = r.reason
            if report is not None:
                report[i] = (int(r.iterations), float(r.decrease))
        alive = _distinct(model, X, alive, [r.f for r in res], reasons, max(ftol, DISTINCT_FTOL_MIN))
    return [(model.normalize(X[i]), int(its[i]), int(evs[i]), reasons[i]) for i in range(s)]


def _distinct(
    model: FixedPoleModel, X: NDArray, alive: list[int], f: list[float], reasons: list[str], ftol: float
) -> list[int]:
    """The members of ``alive`` not at the point of an earlier one (the others marked duplicates).

    "The same point" is judged at the accuracy the stage converged to (its relative decrease
    tolerance ``ftol``): values equal to ``ftol / 10`` and normalized coordinates to
    ``sqrt(ftol)`` (near a smooth minimizer ``f - f* ~ |x - x*|^2``), but never tighter than
    1e-9 and 1e-6.  Measured (issue 13): after the loose first stage (``ftol = 1e-5``) starts in
    one basin sit up to ~4e-3 apart with values equal to 7e-7, while distinct basins of equal
    value (the flat valleys of Chu's example 9) are 0.4-1.7 apart.
    """
    tol_f, tol_x = max(DISTINCT_F_MIN, 0.1 * ftol), max(DISTINCT_X_MIN, math.sqrt(ftol))
    keep: list[tuple[int, float, NDArray]] = []
    for i, fi in zip(alive, f, strict=True):
        xi = model.normalize(X[i])
        if any(abs(fi - fk) <= tol_f * max(1.0, abs(fk)) and np.max(np.abs(xi - xk)) <= tol_x
               for _, fk, xk in keep):
            reasons[i] = "duplicate"
            continue
        keep.append((i, fi, xi))
    return [i for i, _, _ in keep]


def place_fixed(
    A: ArrayLike,
    C: ArrayLike,
    poles: ArrayLike,
    *,
    objective: Objective = "kappa2",
    starts: int | None = None,
    seed: int = 0,
    deadline: Deadline | float | None = None,
    warm_start: ArrayLike | None = None,
    separation: float | None = None,
    gain_mask: ArrayLike | None = None,
    max_iter: int = 400,
    engine: EigenstructureEngine | None = None,
    measure: Measure = "right",
    final_ftol: float | None = None,
) -> PlacementOutcome:
    """Observer gain with prescribed poles minimizing kappa2 (or kappa_fro, eta) of ``A - L C``.

    Parameters
    ----------
    A : (n, n) array_like
    C : (p, n) array_like
    poles : (n,) array_like of complex
        Conjugate-closed; a pole may repeat up to ``rank C`` times (more: see ``separation``).
    objective : {"kappa2", "kappa_fro", "eta"}
    starts : int, optional
        Starting points: scipy YT, scipy KNV0 (real poles only) and random eigenvector
        coordinates, in that order, ``starts`` in all (plus the warm start, if given); all run in
        lockstep.  Default :func:`default_starts` (6 up to n = 12).
    seed : int, default 0
        Seeds the random starts.
    deadline : Deadline or float, optional
        Time budget (seconds or a shared :class:`~optdesign._deadline.Deadline`): no new start or
        stage begins after it expires; the best answer so far is returned (status ``time_limit``).
    warm_start : array_like, optional
        Coordinates from a previous :class:`PlacementOutcome` (same poles), or a gain ``(n, p)``.
    separation : float, optional
        For poles repeated more than ``rank C`` times: design for the nearest distinct pole set
        (:func:`spread_poles` with this relative separation) instead of refusing.
    gain_mask : (n, p) array_like of bool, optional
        Free entries of ``L`` (False: a structural zero), met by an augmented Lagrangian on the same
        BFGS (:func:`masked_solve`); the zeros are then set exactly and ``V``, ``poles`` and the
        condition numbers are those of the resulting ``A - L C`` (numpy's eigenvectors).
    max_iter : int, default 400
        BFGS iterations per continuation stage.
    engine : EigenstructureEngine, optional
        Re-use the bases of an engine built for ``(A, C)`` (``A`` and ``C`` are then ignored).
    measure : {"right", "left"}, default "right"
        Which eigenvectors of ``A - L C`` kappa2 / kappa_fro measure (:class:`FixedPoleModel`):
        ``"left"`` is the state-feedback measure of the transposed loop ``A' - C' L'`` (cond of its
        unit-column right eigenvectors, scipy's ``X``); the outcome's ``V`` and condition numbers
        are then of that matrix (``(A - L C)' V = V diag(poles)``).
    final_ftol : float, optional
        Relative-decrease tolerance of the last continuation stage (default 1e-9); a value <= 0
        runs that stage to ``max_iter`` or to a failed line search (scipy's ``rtol <= 0``).

    Returns
    -------
    PlacementOutcome

    Raises
    ------
    ValidationError
        Unknown objective, bad ``starts``/``seed``/``separation``/``max_iter``.
    DimensionError, NotConjugateClosedError
        Bad shapes or poles.
    DefectivePolesError
        A pole repeated more than ``rank C`` times and no ``separation``.
    NotObservableError
        The poles cannot be assigned (an unobservable mode of ``(C, A)`` is not among them).

    References
    ----------
    Kautsky, Nichols & Van Dooren (1985); Tits & Yang (1996); Lewis & Overton (2013).
    """
    t0 = time.process_time()
    if objective not in OBJECTIVES:
        raise ValidationError(f"objective must be one of {OBJECTIVES}; found {objective!r}")
    seed = as_int("seed", seed, 0)
    max_iter = as_int("max_iter", max_iter, 1)
    dl = Deadline.of(deadline)
    eng = engine if engine is not None else EigenstructureEngine(A, C)
    starts = default_starts(eng.n) if starts is None else as_int("starts", starts, 1)
    requested = as_poles("poles", poles, eng.n)
    target = requested if separation is None else spread_poles(requested, eng.rank, separation)
    model = FixedPoleModel(eng, target, measure=measure)
    if objective == "eta" and any(m > 1 for _, m in pole_multiplicities(target)):
        raise ValidationError("objective 'eta' needs distinct poles (eta is infinite at a repeated pole)")
    common: dict[str, Any] = {"requested_poles": requested,
                              "separation": None if separation is None else float(separation)}
    zero = _mask_zeros(gain_mask, eng.n, eng.p)
    if zero is None and (eng.rank == eng.n or model.r == 1):
        return _direct(model, objective, t0, common)
    cands = _start_points(model, eng, target, starts, seed, warm_start)
    if zero is not None:
        return masked_solve(model, cands, objective, dl, max_iter, zero, t0, common)
    records, best = _solve_starts(model, cands, objective, dl, max_iter, final_ftol)
    its, evs = sum(r.iterations for r in records), sum(r.evaluations for r in records)
    timed_out = any(r.reason == "time_limit" for r in records)
    if best is None:
        nan = math.nan
        return PlacementOutcome(
            np.full((eng.n, eng.p), nan), np.full((eng.n, eng.n), nan + 0j), model.poles, math.inf, math.inf,
            objective, math.inf, Status.TIME_LIMIT if timed_out else Status.NOT_FOUND,
            "no start gave a nonsingular eigenvector matrix"
            + (" before the time limit" if timed_out else ""),
            its, evs, tuple(records), None, time=time.process_time() - t0, **common,
        )
    ib, x = best
    L, Vt, k2, kf = model.design(x)
    why = records[ib].reason
    status = (
        Status.TIME_LIMIT if timed_out
        else Status.ITERATION_LIMIT if why in ("max_iter", "max_eval")
        else Status.OPTIMAL
    )
    msg = (
        f"best of {len(records)} starts (start {ib}, {records[ib].origin}): {objective} = "
        f"{records[ib].objective_value:.6g}" + (" (time limit reached: best so far)" if timed_out else "")
    )
    return PlacementOutcome(
        L, Vt, model.poles, k2, kf, objective, records[ib].objective_value, status, msg, its, evs,
        tuple(records), x, time=time.process_time() - t0, **common,
    )


def default_starts(n: int) -> int:
    """Starts of :func:`place_fixed` when none are given: 6 up to ``n = 12``, 2 up to 24, then 1.

    Measured on 10 random plants (n = 4..10, p = 2..4) against 13 L-BFGS-B runs: with 4 starts the
    engine missed the best basin on 4 plants (by up to 2 %), with 6 or 8 on none; 6 lockstep starts
    (duplicates stopped early) cost about 1.5x the CPU of 4.  One start costs ~1.7 s at n = 20,
    p = 5 and ~6 s at n = 50, p = 10 (``benchmarks/results/placement.md``), where more would break
    a 10 s budget.
    """
    n = as_int("n", n, 1)
    return 6 if n <= 12 else 2 if n <= 24 else 1


def _solve_starts(
    model: FixedPoleModel, cands: list[tuple[str, NDArray]], objective: str, dl: Deadline, max_iter: int,
    final_ftol: float | None = None,
) -> tuple[list[StartRecord], tuple[int, NDArray] | None]:
    """Run every start (lockstep); per-start records and ``(index, coordinates)`` of the best."""
    stages = KAPPA2_CONTINUATION if objective == "kappa2" else (None,)
    ts = time.process_time()
    v0 = [model.metric(x0, objective) for _, x0 in cands]
    live = [i for i, v in enumerate(v0) if math.isfinite(v)]
    runs = []
    last: dict[int, tuple[int, float]] = {}
    if live:
        runs = run_starts(model, np.stack([cands[i][1] for i in live]), objective, dl, max_iter, stages,
                          report=last, final_ftol=final_ftol)
    last_of = {i: last.get(j, (0, math.nan)) for j, i in enumerate(live)}
    share = (time.process_time() - ts) / max(1, len(live))
    out = dict(zip(live, runs, strict=True))
    records: list[StartRecord] = []
    best: tuple[float, int, NDArray] | None = None
    for i, (origin, x0) in enumerate(cands):
        if i not in out:
            records.append(StartRecord(origin, math.inf, math.inf, math.inf, 0, 1, "singular start", 0.0))
            continue
        x, its, evs, reason = out[i]
        val = model.metric(x, objective)
        if not val <= v0[i]:  # never worse than the start (rounding in the last stage)
            x, val = x0, v0[i]
        try:
            L, Vt, k2, _ = model.design(x)
        except np.linalg.LinAlgError:
            L, Vt, k2 = None, None, math.inf
        records.append(StartRecord(origin, k2, val, v0[i], its, evs, reason, share, L, Vt, model.poles,
                                   *last_of[i]))
        if math.isfinite(val) and (best is None or val < best[0]):
            best = (val, i, x)
    return records, None if best is None else (best[1], best[2])


def _direct(model: FixedPoleModel, objective: str, t0: float, common: dict[str, Any]) -> PlacementOutcome:
    """``rank C = 1`` (the unique gain) or ``rank C = n`` (an orthonormal eigenbasis, kappa2 = 1)."""
    eng = model.engine
    sl = model.slots
    if model.r == 1:
        x = model.normalize(np.concatenate([np.ones(sl.nr), np.ones(sl.npair), np.zeros(sl.npair)]))
        what, unique = "one output: the gain is unique for these poles", True
    else:  # every S_j is the whole space: rows e_k, (e_a +- j e_b) / sqrt 2 give a unitary W
        n = eng.n
        W = np.zeros((n, n), dtype=complex)
        W[: sl.nr, : sl.nr] = np.eye(sl.nr)
        for i in range(sl.npair):
            a, b = sl.nr + 2 * i, sl.nr + 2 * i + 1
            W[a, a], W[a, b] = 1.0, 1j
        x = model.coords_from_rows(W)
        what, unique = "rank(C) = n: a unitary eigenbasis, kappa2 = 1", False
    try:
        L, Vt, k2, kf = model.design(x)
    except np.linalg.LinAlgError as exc:
        raise NotObservableError(
            f"the poles cannot be assigned: the eigenvector matrix is singular ({exc}); an unobservable "
            "mode of (C, A) must be among the poles"
        ) from exc
    val = model.metric(x, objective)
    origin = "unique" if unique else "unitary"
    rec = StartRecord(origin, k2, val, val, 0, 1, "direct", time.process_time() - t0, L, Vt, model.poles)
    return PlacementOutcome(
        L, Vt, model.poles, k2, kf, objective, val, Status.SOLVED, what, 0, 1, (rec,), x, unique=unique,
        time=time.process_time() - t0, **common,
    )


def _start_points(
    model: FixedPoleModel,
    eng: EigenstructureEngine,
    target: NDArray,
    starts: int,
    seed: int,
    warm_start: ArrayLike | None,
) -> list[tuple[str, NDArray]]:
    """Warm start (if any), then YT, KNV0 (real poles) and random coordinates: ``starts`` in all."""
    out: list[tuple[str, NDArray]] = []
    if warm_start is not None:
        ws = np.asarray(warm_start, dtype=float)
        if ws.shape == (model.size,):
            out.append(("warm start", model.normalize(ws)))
        elif ws.shape == (eng.n, eng.p):
            x = model.coords_from_gain(ws)
            if x is not None:
                out.append(("warm start", x))
        else:
            raise DimensionError(
                f"warm_start must be coordinates ({model.size},) or a gain ({eng.n}, {eng.p}); "
                f"found {ws.shape}"
            )
    rng = np.random.default_rng(seed)
    methods = ["YT"] + (["KNV0"] if np.all(target.imag == 0) else [])
    k = 0
    while k < starts:
        if methods:
            m = methods.pop(0)
            L0 = peer_start(eng.A, eng.C, target, m)
            x = None if L0 is None else model.coords_from_gain(L0)
            if x is not None:
                out.append((m, x))
                k += 1
            continue
        out.append(("random", model.random_coords(rng)))
        k += 1
    return out


def _mask_zeros(gain_mask: ArrayLike | None, n: int, p: int) -> NDArray[np.bool_] | None:
    """The structural zeros (True) of a mask of free entries, or None when there are none."""
    m = as_gain_mask("gain_mask", gain_mask, n, p, label="")
    return None if m is None or m.all() else ~m


#: augmented-Lagrangian rounds after the continuation
_MASK_ROUNDS = 12


def masked_solve(
    model: FixedPoleModel,
    cands: list[tuple[str, NDArray]],
    objective: str,
    dl: Deadline,
    max_iter: int,
    zero: NDArray[np.bool_],
    t0: float,
    common: dict[str, Any],
) -> PlacementOutcome:
    """Structural zeros of ``L`` by an augmented Lagrangian on the eigenvector coordinates.

    Every start runs the continuation on ``f + sum_zero (y h + rho h^2 / 2)`` (``h = L_ij / s``,
    ``s`` the Frobenius norm of the start's gain), in lockstep; after every stage the multipliers
    step ``y += rho h`` and ``rho`` grows tenfold where the violation did not shrink fourfold; then
    up to ``_MASK_ROUNDS`` rounds of the last stage until ``max |h| <= MASK_TOL``.  The zeros are
    then set exactly; a start that does not get there is not a candidate (status ``not_found``
    when none does: the mask and the poles may be incompatible, which a local method cannot prove).
    """
    eng = model.engine
    X = np.stack([x for _, x in cands])
    s = X.shape[0]
    scale = np.array([max(1.0, float(np.linalg.norm(model.design(x)[0]))) for x in X])
    y = np.zeros((s, eng.n, eng.p))
    rho = np.full(s, 10.0)
    stages = list(KAPPA2_CONTINUATION if objective == "kappa2" else (None,))
    stages += [stages[-1]] * _MASK_ROUNDS
    viol = np.full(s, np.inf)
    its = evs = 0
    reason = "converged"
    for k in stages:
        if dl.expired:
            reason = "time_limit"
            break

        def fun(Z, idx, _k=k):  # each member with its own multipliers
            return model.penalized(Z, objective, _k, zero, y[idx], rho[idx], scale[idx])

        res, _ = bfgs_minimize_batch(
            fun, X, max_iter=max_iter, ftol=STAGE_FTOL.get(k, STAGE_FTOL_DEFAULT),
            gtol=0.0 if k is None else STAGE_GTOL, deadline=dl, pass_index=True,
        )
        for i, r in enumerate(res):
            X[i] = model.normalize(r.x)
            its, evs = its + r.iterations, evs + r.evaluations
            h = np.where(zero, model.design(X[i])[0] / scale[i], 0.0)
            v = float(np.max(np.abs(h)))
            y[i] += rho[i] * h
            if v > 0.25 * viol[i]:
                rho[i] *= 10.0
            viol[i] = v
        if k == stages[-1] and np.all(viol <= MASK_TOL):
            break
    records, best = [], None
    for i, (origin, _) in enumerate(cands):
        L = model.design(X[i])[0]
        L[zero] = 0.0
        ok = viol[i] <= MASK_TOL
        k2 = metrics.kappa2(_measured(model, L)) if ok else math.inf
        val = _metric_of_gain(model, L, objective) if ok else math.inf
        why = reason if ok else f"mask violation {viol[i]:.1e}"
        records.append(StartRecord(origin, k2, val, math.inf, 0, 0, why, 0.0, L if ok else None))
        if ok and math.isfinite(val) and (best is None or val < best[0]):
            best = (val, i, L)
    records[0] = dataclasses.replace(records[0], iterations=its, evaluations=evs)
    if best is None:
        nan = math.nan
        return PlacementOutcome(
            np.full((eng.n, eng.p), nan), np.full((eng.n, eng.n), nan + 0j), model.poles, math.inf, math.inf,
            objective, math.inf, Status.TIME_LIMIT if reason == "time_limit" else Status.NOT_FOUND,
            f"no start met the structural zeros (smallest violation {float(np.min(viol)):.2e} relative)",
            its, evs, tuple(records), time=time.process_time() - t0, **common,
        )
    val, ib, L = best
    V, w = metrics.eigenvector_matrix(_measured(model, L), return_eigenvalues=True)
    sv = np.linalg.svd(V, compute_uv=False)
    status = Status.TIME_LIMIT if reason == "time_limit" else Status.OPTIMAL
    return PlacementOutcome(
        L, V, w, float(sv[0] / sv[-1]), float(np.linalg.norm(V) * np.linalg.norm(np.linalg.inv(V))),
        objective, val, status,
        f"best of {len(records)} starts with the structural zeros (start {ib}, {records[ib].origin}): "
        f"{objective} = {val:.6g}", its, evs, tuple(records), time=time.process_time() - t0, **common,
        extra={"mask_violation": float(viol[ib])},
    )


def _measured(model: FixedPoleModel, L: NDArray) -> NDArray:
    """The matrix whose right eigenvectors ``model`` measures: ``A - L C`` or its transpose."""
    F = model.engine.A - L @ model.engine.C
    return F.T if model.measure == "left" else F


def _metric_of_gain(model: FixedPoleModel, L: NDArray, objective: str) -> float:
    X = _measured(model, L)
    return {"kappa2": metrics.kappa2, "kappa_fro": metrics.kappa_fro, "eta": metrics.eta}[objective](X)
