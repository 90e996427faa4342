"""Independent evaluation of well-conditioned designs: the checks of one candidate gain, the ranking
of the starts and the outcome of a multi-start design.

Every candidate -- from the placement engine or from IPOPT -- is verified here with numpy/scipy only
(the eigenvalues of ``A - L C``, region membership, kappa2 recomputed by
:mod:`optdesign.analysis.metrics`, the solver's eigenbasis checked as an eigenbasis), with the
tolerances of :mod:`optdesign.design.verification`.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..._deadline import Deadline
from ...analysis import metrics
from ...classical.placement import pole_error
from ...classical.riccati import sort_poles
from ...errors import ValidationError
from ...model.plant import Plant
from ...model.regions import Region
from ...results import Check, Status, Verification
from ..verification import (
    BOUND_RTOL,
    KAPPA2_TOL_MAX,
    POLE_FLOOR_CAP,
    bound_check,
    eig_residual_check,
    eigen_spread,
    kappa2_agreement_check,
    kappa2_agreement_tol,
    observer_stability_check,
    region_margin_check,
)
from .results import StartRecord, n_converged

__all__ = [
    "POLE_TOL",
    "Candidate",
    "evaluate_candidate",
    "cached_evaluate",
    "kappa2_agreement_tol",
    "kappa2_accuracy_check",
    "KAPPA2_ACCURACY_TOL",
    "check_region_stable",
    "check_target_stable",
    "metric_of",
    "start_record",
    "rank_key",
    "pick_best",
    "objective_lower_bound",
    "attains",
    "bound_level",
    "design_outcome",
    "best_of_history",
]

#: relative pole accuracy required of a fixed-pole design
POLE_TOL = 1e-6
#: the largest first-order relative error of a computed kappa2 accepted for a design
#: (:func:`kappa2_accuracy_check`): kappa2 stated to about three digits
KAPPA2_ACCURACY_TOL = 0.1 * KAPPA2_TOL_MAX
#: rounding-size perturbations of :func:`kappa2_accuracy_check` (the largest change is the value): one
#: direction's change is a sample, whose size near a nearly defective pair varied 100x between
#: directions and between CPUs (round 13: a 4 x 4 case with two poles 2e-8 apart, 3.5e-4 under AMD EPYC's
#: OpenBLAS kernel, 2.2e-3 under Prescott's, for the same seeded direction; 1.6e-5 to 1.7e-3 over 20
#: directions)
_ACCURACY_DIRECTIONS = 4
_EPS = float(np.finfo(float).eps)


@dataclass
class Candidate:
    """One solver answer before verification: the gain, the solver's eigenbasis ``Z`` (columns) and
    its poles when it could be read, and what the solver said (status, native status, message,
    iterations, seconds, the stage that produced it, the backend: ``"ipopt"``, ``"eigenstructure"``,
    ``"start"`` for a start's own gain)."""

    L: NDArray
    Z: NDArray | None
    Zpoles: NDArray | None
    status: Status
    native: str
    message: str
    iterations: int
    time: float
    stage: str = ""
    backend: str = "ipopt"


#: one evaluated candidate: (objective metric, start index, metrics, verification, candidate)
Evaluated = tuple[float, int, dict[str, Any], Verification, Candidate]


def _no_gain(plant: Plant) -> tuple[dict[str, Any], Verification]:
    nan = float("nan")
    checks = [Check.at_most("finite_gain", float("inf"), 0.0, "the gain has NaN/Inf entries")]
    return ({"kappa2": nan, "eta": nan, "kappa_fro": nan, "gain_norm": nan,
             "poles": np.full(plant.n, np.nan + 0j), "V": None}, Verification.of(checks))


def evaluate_candidate(
    plant: Plant,
    cand: Candidate,
    *,
    target: NDArray | None,
    region: Region | None,
    mask: NDArray | None,
    max_gain: float | None,
    kappa2_max: float | None,
    eta_max: float | None,
    stable: bool = True,
) -> tuple[dict[str, Any], Verification]:
    """Independent checks of one design (numpy/scipy only) and its metrics.

    Parameters
    ----------
    plant : Plant
    cand : Candidate
    target : (n,) ndarray of complex or None
        Fixed poles: ``pole_error`` against them.
    region : Region or None
        Free poles: ``region_margin``.
    mask, max_gain, kappa2_max, eta_max
        The structural zeros and the bounds of the design (``mask``, ``gain_bound``,
        ``kappa2_bound``, ``eta_bound``).
    stable : bool
        Require ``stability``.

    Returns
    -------
    metrics : dict
        ``kappa2``, ``eta``, ``kappa_fro``, ``gain_norm``, ``poles`` (sorted), ``V``.
    verification : Verification
    """
    L = cand.L
    if not np.all(np.isfinite(L)):
        return _no_gain(plant)
    checks: list[Check] = []
    X = plant.A - L @ plant.C
    poles = sort_poles(np.linalg.eigvals(X))
    summ = metrics.condition_summary(X)   # one Schur form for the metrics and the rounding floor
    # how accurately these poles are computable at all (relative; capped like the pole check)
    floor = min(float(summ["rounding_floor"]), POLE_FLOOR_CAP)
    if stable:
        checks.append(observer_stability_check(poles, plant.is_discrete, floor))
    if target is not None:
        checks.append(Check.at_most("pole_error", pole_error(poles, target), POLE_TOL,
                                    "max relative error of eig(A - LC) vs the target poles"))
    if region is not None:
        checks.append(region_margin_check(region, poles, floor))
    k2, eta_v, kf = float(summ["kappa2"]), float(summ["eta"]), float(summ["kappa_fro"])
    # a pole repeated on request (fixed poles): semisimple by construction, its eigenbasis not unique
    repeated = target is not None and _has_repeats(target)
    V: NDArray | None = None
    if cand.Z is not None and cand.Zpoles is not None:
        Z, zp = cand.Z, cand.Zpoles
        res_check = eig_residual_check(X, Z, zp)
        checks.append(res_check)
        sv = np.linalg.svd(Z, compute_uv=False)
        kz = float(sv[0] / sv[-1]) if sv[-1] > 0 else float("inf")
        if math.isfinite(k2):
            checks.append(kappa2_agreement_check(kz, k2, eigen_spread(X, poles)))
        elif repeated and math.isfinite(kz) and res_check.passed:
            # repeated pole: the basis is not unique; report the verified basis the solver found
            k2 = kz
            kf = float(np.linalg.norm(Z) * np.linalg.norm(np.linalg.inv(Z)))
        V = Z
    elif math.isfinite(k2):
        V = metrics.eigenvector_matrix(X)
    if not repeated:
        checks.append(kappa2_accuracy_check(X, poles, k2))
    gn = float(np.linalg.norm(L, 2))
    if mask is not None:
        off = float(np.max(np.abs(L[~mask]))) if (~mask).any() else 0.0
        checks.append(Check.at_most("mask", off, 0.0, "largest |L| entry outside the structure mask"))
    if max_gain is not None:
        checks.append(bound_check("gain_bound", gn, max_gain, BOUND_RTOL, "||L||_2 <= max_gain"))
    if kappa2_max is not None:  # to the accuracy of a computed kappa2
        checks.append(bound_check("kappa2_bound", k2, kappa2_max, kappa2_agreement_tol(kappa2_max),
                                  "kappa2 <= kappa2_max"))
    if eta_max is not None:
        checks.append(bound_check("eta_bound", eta_v, eta_max, BOUND_RTOL, "eta <= eta_max"))
    if not checks:
        checks.append(Check.at_most("finite_gain", 0.0, 0.0))
    out = {"kappa2": k2, "eta": eta_v, "kappa_fro": kf, "gain_norm": gn, "poles": poles, "V": V}
    return out, Verification.of(checks)


def _has_repeats(poles: NDArray) -> bool:
    """Two of ``poles`` equal (to 1e-10 relative: a repeated pole asked for)."""
    P = np.asarray(poles, dtype=complex).ravel()
    return bool(np.unique(np.round(P / max(1.0, float(np.max(np.abs(P)))), 10)).size < P.size)


def kappa2_accuracy_check(X: NDArray, poles: NDArray, kappa2: float) -> Check:
    """``kappa2_accuracy``: can the kappa2 of ``X = A - L C`` be stated at all?

    A computed unit-column eigenvector moves by about ``eps ||X||_F / gap`` under rounding
    (first-order perturbation; ``gap`` the smallest distance between two poles), which kappa2
    amplifies: ``10 eps kappa2 ||X||_F / gap`` bounds the relative error of a computed kappa2
    (:func:`~optdesign.design.verification.kappa2_agreement_tol`).  When that bound exceeds
    :data:`KAPPA2_ACCURACY_TOL` (about three digits) -- two poles close together -- the kappa2 is
    recomputed for ``X + E``, ``E`` a rounding-size perturbation (``10 eps ||X||_F`` in each of 4
    fixed random directions, ``_ACCURACY_DIRECTIONS``), and the largest relative change is the value
    checked: a pair of nearly coincident poles whose eigenvectors stay apart (a nearly semisimple
    double pole, possible when ``rank C >= 2``) keeps its kappa2 (measured: 4e-5 for a random n = 8
    design with two poles 2e-8 apart), a nearly defective pair does not (the regression case of
    ``tests/data/region_design_near_defective_n8_p2.npz``, two poles 3e-8 apart on a region's edge:
    ``metrics.kappa2`` is inf, numpy's eigenbasis gives 40,802, perturbed 49,000-50,000).  An
    infinite ``kappa2`` (numerically coincident poles) fails: no such design is a verified optimum.
    """
    if not math.isfinite(kappa2):
        value = math.inf
    else:
        value = 10.0 * _EPS * kappa2 * eigen_spread(X, poles)
        if value > KAPPA2_ACCURACY_TOL:
            size = 10.0 * _EPS * float(np.linalg.norm(X))
            value = 0.0
            for g in np.random.default_rng(0).standard_normal((_ACCURACY_DIRECTIONS,) + X.shape):
                try:
                    perturbed = float(metrics.kappa2(X + size * g / float(np.linalg.norm(g))))
                    change = abs(perturbed - kappa2) / kappa2
                except (np.linalg.LinAlgError, ValueError):
                    change = math.inf
                # a NaN change (kappa2 of X + E not computable) counts as inf; max() would skip it
                value = max(value, change if math.isfinite(change) else math.inf)
    return Check.at_most("kappa2_accuracy", value, KAPPA2_ACCURACY_TOL,
                         "relative error of the computed kappa2: the first-order bound 10 eps kappa2 "
                         "||A - LC||_F / gap, or where it exceeds the tolerance the change of kappa2 under a "
                         "rounding-size perturbation (a nearly defective A - LC has no statable kappa2)")


def cached_evaluate(evaluate: Callable[[Candidate], tuple[dict[str, Any], Verification]],
                    ) -> Callable[[Candidate], tuple[dict[str, Any], Verification]]:
    """``evaluate`` (a function of one candidate, e.g. :func:`evaluate_candidate` with the design's
    plant, region and bounds bound) that evaluates each distinct candidate once.

    A candidate is identified by the exact bytes of its gain, its eigenbasis and their poles (all
    that :func:`evaluate_candidate` reads), so a candidate checked by a start's runner, then ranked
    with its start's history, then compared with the other starts is evaluated once.  Make one per
    solve (the cache holds that solve's candidates; nothing is kept across calls).

    Parameters
    ----------
    evaluate : callable
        ``evaluate(candidate) -> (metrics, Verification)``, a pure function of ``L``, ``Z`` and
        ``Zpoles``.

    Returns
    -------
    callable
        The same function, memoized.
    """
    memo: dict[tuple, tuple[dict[str, Any], Verification]] = {}

    def key(a: NDArray | None) -> tuple | None:
        if a is None:
            return None
        a = np.asarray(a)
        return a.shape, a.dtype.str, a.tobytes()

    def cached(cand: Candidate) -> tuple[dict[str, Any], Verification]:
        k = (key(cand.L), key(cand.Z), key(cand.Zpoles))
        out = memo.get(k)
        if out is None:
            out = memo[k] = evaluate(cand)
        return out

    return cached


def _region_sup_modulus(region: Region) -> float:
    """``max |z|`` over a bounded convex region (its boundary found along rays from an interior point)."""
    from scipy.optimize import minimize_scalar

    x0 = region.interior_point()

    def radii(thetas: NDArray) -> NDArray:
        d = np.exp(1j * np.asarray(thetas, dtype=float))
        hi = np.ones(d.shape)
        for _ in range(2000):
            inside = region.distance(x0 + hi * d) <= 0.0
            if not inside.any():
                break
            hi = np.where(inside, 2.0 * hi, hi)
        lo = np.zeros(d.shape)
        for _ in range(60):  # bisection to ~1e-18 relative (below rounding)
            mid = 0.5 * (lo + hi)
            inside = region.distance(x0 + mid * d) <= 0.0
            lo, hi = np.where(inside, mid, lo), np.where(inside, hi, mid)
        return np.abs(x0 + hi * d)

    thetas = np.linspace(0.0, math.pi, 361)  # the region is symmetric about the real axis
    vals = radii(thetas)
    k = int(np.argmax(vals))
    a, b = float(thetas[max(k - 1, 0)]), float(thetas[min(k + 1, thetas.size - 1)])
    # refinement of the best bracket (Brent's bounded search)
    res = minimize_scalar(lambda th: -float(radii(np.array([th]))[0]), bounds=(a, b), method="bounded",
                          options={"xatol": 1e-12})
    return max(float(vals[k]), float(radii(np.array([float(res.x)]))[0]))


def check_region_stable(region: Region, discrete: bool) -> None:
    """A pole region must lie in the (closed) stability region of the plant's time domain.

    Raises
    ------
    ValidationError
        Naming how far the region reaches out (``sup Re s > 0``, or ``sup |z| > 1``).
    """
    if discrete:
        sup = math.inf if not region.bounded else _region_sup_modulus(region)
        if sup > 1.0 + 1e-9:
            raise ValidationError(
                f"the pole region {region!r} reaches |z| = {sup:.6g} > 1: the plant is discrete-time "
                "(dt set) and poles there make the error dynamics unstable; use a region inside the unit "
                "disk, e.g. region & Disk.unit(0.95)"
            )
        return
    hi = float(region.real_interval()[1])
    if hi > 0.0:
        raise ValidationError(
            f"the pole region {region!r} reaches Re s = {hi:.6g} > 0: the plant is continuous-time and "
            "poles there make the error dynamics unstable (for a discrete-time design set plant.dt); "
            "intersect the region with a stable half-plane, e.g. region & HalfPlane(alpha) with alpha > 0"
        )


def check_target_stable(target: NDArray, discrete: bool) -> None:
    """Fixed poles must give stable error dynamics (``allow_unstable`` lifts this).

    Raises
    ------
    ValidationError
        Naming the unstable poles.
    """
    bad = target[np.abs(target) >= 1.0] if discrete else target[target.real >= 0.0]
    if bad.size:
        what = "|z| < 1 (discrete time)" if discrete else "Re s < 0 (continuous time)"
        raise ValidationError(
            f"poles must give stable error dynamics, {what} (allow_unstable=True accepts them); "
            "found unstable poles "
            + ", ".join(f"{z.real:.6g}" if z.imag == 0 else f"{complex(z):.6g}" for z in bad)
        )


# --------------------------------------------------------------------------- ranking and outcome


def metric_of(objective: str, m: dict[str, Any]) -> float:
    """The objective metric (kappa2, kappa_fro or eta) of an evaluation."""
    return float(m[objective])


def start_record(idx: int, origin: str, cand: Candidate, m: dict, v: Verification, obj: float,
                 message: str) -> StartRecord:
    """The history entry of one start whose chosen candidate carries the start's totals."""
    return StartRecord(idx, origin, Status(cand.status), v.passed, m["kappa2"], m["eta"], m["gain_norm"], obj,
                       cand.iterations, cand.time, message)


def rank_key(obj: float, v: Verification, c: Candidate, idx: int = 0) -> tuple[int, float, int]:
    """Verified and solved first, then verified (e.g. an iteration limit), then the rest with a finite
    gain, then those without; by objective."""
    solved = Status(c.status).is_solved
    rank = 0 if (v.passed and solved) else 1 if v.passed else 2 if np.all(np.isfinite(c.L)) else 3
    return (rank, obj if math.isfinite(obj) else float("inf"), idx)


def pick_best(evaluated: list[Evaluated]) -> Evaluated:
    """The best of ``(objective, index, metrics, verification, candidate)`` entries: solved and
    verified first, then verified (e.g. an iteration limit), then the rest (a finite gain first); by
    objective, then index."""
    return min(evaluated, key=lambda e: rank_key(e[0], e[3], e[4], e[1]))


def best_of_history(hist: list[Candidate], objective: str, evaluate) -> tuple[float, dict, Verification,
                                                                             Candidate]:
    """The best verified candidate of one start's history (else its last), carrying the start's
    iteration and time totals."""
    scored = []
    for c in hist:
        m, v = evaluate(c)
        scored.append((metric_of(objective, m), m, v, c))
    ok = [x for x in scored if x[2].passed]
    pool = ok if ok else scored[-1:]
    obj, m, v, cand = min(pool, key=lambda x: rank_key(x[0], x[2], x[3]))
    cand = dataclasses.replace(cand, iterations=sum(c.iterations for c in hist),
                               time=sum(c.time for c in hist))
    return obj, m, v, cand


def objective_lower_bound(objective: str, n: int) -> float | None:
    """The smallest value the objective can take: kappa2 >= 1, kappa_fro >= n (unit columns:
    ``||V||_F = sqrt(n) <= ||V^-1||_F``), eta >= 0 (a normal ``A - LC``)."""
    return {"kappa2": 1.0, "kappa_fro": float(n), "eta": 0.0}.get(objective)


def bound_level(bound: float) -> float:
    """The largest objective value that attains the lower bound ``bound``: ``bound + tol s`` with
    ``s = max(bound, 1)`` and ``tol = kappa2_agreement_tol(s)``, the accuracy of a computed kappa2
    (1e-6).  For kappa2 and kappa_fro a relative test (``bound (1 + tol)``); for eta's bound 0 the
    absolute ``eta <= tol``: to first order ``kappa2 = 1 + O(eta)`` near a normal matrix (exactly
    ``kappa2 = eta + sqrt(1 + eta^2)`` for n = 2, seed 001 eq. (19)), so eta is 0 to the accuracy
    with which kappa2 is 1."""
    s = max(float(bound), 1.0)
    return float(bound) + kappa2_agreement_tol(s) * s


def attains(bound: float | None, obj: float, v: Verification, cand: Candidate) -> bool:
    """A solved, verified design at its objective's lower bound, to the accuracy of a computed kappa2
    (:func:`bound_level`): a global optimum, no other start can do better."""
    return (bound is not None and v.passed and Status(cand.status).is_solved
            and obj <= bound_level(bound))


def design_outcome(records: list[StartRecord], evaluated: list[Evaluated], objective: str, *,
                   deadline: Deadline, planned: int) -> tuple[Evaluated, Status, str]:
    """Status and message of a multi-start design from its records.

    Parameters
    ----------
    records : list of StartRecord
    evaluated : list of (objective, index, metrics, Verification, Candidate)
        Non-empty, as returned with ``records``.
    objective : str
    deadline : Deadline
        Expired at the end: status ``time_limit`` (the budget ran out before the design finished).
    planned : int
        Number of starts the design would have run without a time limit.

    Returns
    -------
    best : tuple
        The :func:`pick_best` entry.
    status : Status
        ``time_limit`` (budget spent; the best verified design so far is kept); the best candidate's
        status when it passed verification (a solved one, or e.g. ``iteration_limit``);
        ``solver_error`` when every start crashed; otherwise ``not_found``: no start gave a
        verified design, which is local evidence only -- never ``infeasible``.
    message : str
    """
    best = pick_best(evaluated)
    obj, idx, _, v, cand = best
    converged = n_converged(records)
    origin = records[[r.index for r in records].index(idx)].origin
    where = f"start {idx} ({origin})"
    failed = "; ".join(c.name for c in v.failed)
    if deadline.expired:
        ran = f"time limit of {deadline.limit:g} s reached after {len(records)} of {planned} starts"
        msg = (f"{ran}; best verified design so far: {where}, {objective} = {obj:.6g}" if v.passed else
               f"{ran}; no verified design yet (best {where}: {cand.message}"
               + (f"; failed checks: {failed})" if failed else ")"))
        return best, Status.TIME_LIMIT, msg
    if v.passed:
        status = Status(cand.status)
        if status.is_solved:
            msg = (f"best of {len(records)} starts (start {idx}, {origin}): {objective} = {obj:.6g}; "
                   f"{converged} of {len(records)} starts converged to verified designs")
            return best, status, msg
    elif records and all(Status(r.status) == Status.SOLVER_ERROR for r in records):
        status = Status.SOLVER_ERROR
    else:
        status = Status.NOT_FOUND
    msg = (f"no start gave a solved and verified design ({converged} of {len(records)}); best {where}: "
           f"{cand.message}" + (f"; failed checks: {failed}" if failed else ""))
    if status == Status.NOT_FOUND:
        msg += " (not found by a local method: feasibility unknown)"
    return best, status, msg
