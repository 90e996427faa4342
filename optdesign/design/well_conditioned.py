r"""Well-conditioned observers and Kalman filters (seed 001, generalized to any order).

``well_conditioned_observer`` chooses the observer gain ``L`` so that the eigenvector matrix of
the error dynamics ``A - L C`` is as well conditioned as possible -- minimizing ``kappa2``
(seed 001's principal index), ``kappa_fro`` or Huh & Stein's ``eta`` -- with the poles either

* fixed (the job of ``scipy.signal.place_poles`` YT/KNV0, but minimizing kappa2 itself,
  and accepting a pole repeated up to ``rank(C)`` times), or
* free inside a pole region (:mod:`optdesign.regions`; a discrete-time region when
  ``plant.dt`` is set),

optionally with structural zeros in ``L``, a bound on ``||L||_2`` and a bound on the other
metric (trade-off: minimize eta subject to ``kappa2 <= kappa2_max``, or the reverse).

``well_conditioned_kalman`` does the same for a true Kalman filter: the noise covariance is
the design variable and the filter Riccati equation is a constraint.

Every design follows validate -> formulate (:mod:`optdesign.formulate.well_conditioned`) ->
solve (IPOPT, multi-start) -> verify (numpy/scipy, independently of the solver) -> result.

References
----------
Jung, J. & Huh, K., "Design of the well-conditioned observer using the non-normality
measure" (seed 001).
Huh, K. & Stein, J. L., "Well-conditioned observer design for observer-based monitoring
systems", ASME J. Dyn. Sys. Meas. Control 117 (1995) 592-599.
Kautsky, J., Nichols, N. K. & Van Dooren, P., "Robust pole assignment in linear state
feedback", Int. J. Control 41 (1985) 1129-1155.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._validate import as_poles, as_positive_float
from ..analysis import metrics
from ..classical.placement import place_observer, pole_error
from ..errors import DimensionError, ValidationError
from ..formulate.well_conditioned import (
    KAPPA2_STAGES,
    OBJECTIVES,
    NLPScaling,
    PoleStructure,
    build_kalman_nlp,
    build_observer_nlp,
    random_gain_for_poles,
)
from ..model.plant import Plant
from ..model.regions import Region, stability_region
from ..results import Check, ResultMixin, SolverStats, Status, Verification

__all__ = ["ObserverDesign", "StartRecord", "well_conditioned_observer", "well_conditioned_kalman"]

#: continuation stages of the free-pole NLP (the fixed-pole polish at its poles runs them all):
#: on COMPleib AC6 stages 3 and 9 changed kappa2 by < 0.2 % at ~40 % of the time
REGION_STAGES = (0, 6, 12)
#: relative pole accuracy required of a fixed-pole design
POLE_TOL = 1e-6
#: relative agreement required between the solver's eigenbasis and numpy's kappa2
#: (plus ``100 eps kappa2^2`` for the rounding of ill-conditioned eigenvectors)
KAPPA_TOL = 1e-3

#: IPOPT settings of the design verbs (per stage; merged under the caller's ``options``).
#: ``acceptable_obj_change_tol`` ends the long flat tails measured on scipy's 6x6 test case
#: (1000 iterations for a 1e-9 relative change of kappa2).
_IPOPT_DEFAULTS: dict[str, Any] = {
    "ipopt.tol": 1e-8,
    "ipopt.constr_viol_tol": 1e-10,
    "ipopt.acceptable_tol": 1e-6,
    "ipopt.acceptable_iter": 5,
    "ipopt.acceptable_obj_change_tol": 1e-10,
    "ipopt.max_iter": 500,
}


@dataclass(frozen=True)
class StartRecord:
    """What one multi-start run gave.

    Attributes
    ----------
    index : int
    origin : str
        Where the initial gain came from (``"YT"``, ``"KNV0"``, ``"random"``,
        ``"region sample"``, ``"riccati q=..."``).
    status : Status
        The solver status of the run's last stage.
    verified : bool
        The run's design passed every independent check.
    kappa2, eta, gain_norm : float
        Recomputed with numpy (nan if the run produced no finite gain).
    objective : float
        The objective metric recomputed with numpy (what ranks the starts).
    iterations : int
    time : float
        Seconds in IPOPT.
    message : str
    """

    index: int
    origin: str
    status: Status
    verified: bool
    kappa2: float
    eta: float
    gain_norm: float
    objective: float
    iterations: int
    time: float
    message: str = ""


@dataclass(frozen=True)
class ObserverDesign(ResultMixin):
    """A well-conditioned observer (or Kalman filter) design.

    Attributes
    ----------
    L : (n, p) ndarray
        Observer gain; error dynamics ``A - L C``.
    poles : (n,) ndarray of complex
        ``eig(A - L C)`` recomputed with numpy, sorted by real then imaginary part.
    kappa2 : float
        2-norm condition number of the unit-column eigenvector matrix (``metrics.kappa2``; for a
        repeated pole, where the eigenbasis is not unique and ``metrics.kappa2`` is inf, the
        condition number of the basis found by the solver, verified as an eigenbasis).
    eta : float
        Huh & Stein's non-normality measure (``metrics.eta``; inf for repeated poles).
    kappa_fro : float
        Frobenius condition number of the same eigenbasis.
    gain_norm : float
        ``||L||_2``.
    objective : str
        ``"kappa2"``, ``"kappa_fro"`` or ``"eta"``.
    status : Status
    message : str
    solver_stats : SolverStats
        Totals over all starts; ``extra`` has ``starts``, ``converged``, ``best_start``.
    verification : Verification
        ``pole_error`` or ``region_margin``, ``eig_residual``, ``kappa2_agreement``,
        ``mask``, ``gain_bound``, ``kappa2_bound``, ``eta_bound`` (when relevant), and for
        Kalman designs ``riccati_residual``, ``P_min_eig``, ``Q_min_eig``, ``gain_vs_riccati``.
    starts : tuple of StartRecord
        The per-start history.
    V : (n, n) ndarray of complex or None
        The unit-column eigenvector matrix behind ``kappa2``.
    target_poles : ndarray or None
        Fixed-pole mode: the requested poles.
    region : Region or None
        Region mode: the pole region.
    certificate : dict or None
        Infeasible designs: why (e.g. a pole repeated more than ``rank(C)`` times).
    Q, P, R : ndarray or None
        Kalman designs: the noise covariances found and the Riccati solution.
    """

    L: NDArray[np.float64]
    poles: NDArray[np.complex128]
    kappa2: float
    eta: float
    kappa_fro: float
    gain_norm: float
    objective: str
    status: Status
    message: str
    solver_stats: SolverStats
    verification: Verification
    starts: tuple[StartRecord, ...] = ()
    V: NDArray[np.complex128] | None = None
    target_poles: NDArray[np.complex128] | None = None
    region: Region | None = None
    certificate: dict[str, Any] | None = None
    Q: NDArray[np.float64] | None = None
    P: NDArray[np.float64] | None = None
    R: NDArray[np.float64] | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def n_converged(self) -> int:
        """Number of starts whose design was solved and verified."""
        return sum(1 for s in self.starts if s.verified and Status(s.status).is_solved)

    def record(self) -> dict[str, Any]:
        """Scalar summary for sweeps and tables."""
        return {
            "status": Status(self.status).value,
            "success": self.success,
            "objective": self.objective,
            "kappa2": self.kappa2,
            "eta": self.eta,
            "kappa_fro": self.kappa_fro,
            "gain_norm": self.gain_norm,
            "max_real_pole": float(np.max(self.poles.real)) if self.poles.size else float("nan"),
            "starts": len(self.starts),
            "converged": self.n_converged,
            "time": self.solver_stats.time,
            "iterations": self.solver_stats.iterations,
        }

    def __repr__(self) -> str:
        return (
            f"ObserverDesign(status={Status(self.status).value}, success={self.success}, "
            f"kappa2={self.kappa2:.6g}, eta={self.eta:.6g}, ||L||={self.gain_norm:.4g}, "
            f"converged={self.n_converged}/{len(self.starts)})"
        )


# --------------------------------------------------------------------------- validation helpers


def _check_plant(plant: Any) -> Plant:
    if not isinstance(plant, Plant):
        raise ValidationError(f"plant must be an optdesign.Plant; found {type(plant).__name__}")
    return plant


def _check_mask(structure: Any, n: int, p: int) -> NDArray[np.bool_] | None:
    if structure is None:
        return None
    m = np.asarray(structure)
    if m.shape != (n, p):
        raise DimensionError(
            f"structure (mask of free entries of L) must have shape ({n}, {p}); found {m.shape}"
        )
    if m.dtype != bool:
        if not np.all(np.isin(m, (0, 1))):
            raise ValidationError("structure must be a boolean mask (True = free entry of L, False = zero)")
        m = m.astype(bool)
    if not m.any():
        raise ValidationError("structure has no free entry: L would be zero (nothing to design)")
    return m


def _check_int(name: str, v: Any, lo: int) -> int:
    if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, np.integer)) or v < lo:
        raise ValidationError(f"{name} must be an integer >= {lo}; found {v!r}")
    return int(v)


def _check_solver(solver: Any) -> None:
    if solver != "ipopt":
        raise ValidationError(f"solver must be 'ipopt' (CasADi/IPOPT is the NLP backend); found {solver!r}")


def _metric_of(objective: str, m: dict[str, float]) -> float:
    return float(m[objective])


def _sorted_poles(p: NDArray) -> NDArray[np.complex128]:
    p = np.asarray(p, dtype=complex)
    return p[np.lexsort((p.imag, p.real))]


# --------------------------------------------------------------------------- verification


@dataclass
class _Candidate:
    L: NDArray
    Z: NDArray | None
    Zpoles: NDArray | None
    status: Status
    native: str
    message: str
    iterations: int
    time: float
    stage: str = ""


def _evaluate(
    plant: Plant,
    cand: _Candidate,
    *,
    target: NDArray | None,
    region: Region | None,
    mask: NDArray | None,
    max_gain: float | None,
    kappa2_max: float | None,
    eta_max: float | None,
) -> tuple[dict[str, Any], Verification]:
    """Independent checks of one design (numpy/scipy only) and its metrics."""
    L = cand.L
    checks: list[Check] = []
    if not np.all(np.isfinite(L)):
        checks.append(Check.at_most("finite_gain", float("inf"), 0.0, "the gain has NaN/Inf entries"))
        nan = float("nan")
        return {
            "kappa2": nan,
            "eta": nan,
            "kappa_fro": nan,
            "gain_norm": nan,
            "poles": np.full(plant.n, np.nan + 0j),
            "V": None,
        }, Verification.of(checks)
    X = plant.A - L @ plant.C
    poles = _sorted_poles(np.linalg.eigvals(X))
    scale = max(1.0, float(np.max(np.abs(poles))))
    if target is not None:
        checks.append(
            Check.at_most(
                "pole_error",
                pole_error(poles, target),
                POLE_TOL,
                "max relative error of eig(A - LC) vs the target poles",
            )
        )
    if region is not None:
        checks.append(
            Check.at_most(
                "region_margin",
                region.margin(poles),
                1e-7 * scale,
                "max signed distance of eig(A - LC) to the region (<= 0 inside)",
            )
        )
    summ = metrics.condition_summary(X)
    k2, eta_v, kf = float(summ["kappa2"]), float(summ["eta"]), float(summ["kappa_fro"])
    V = None
    if cand.Z is not None:
        Z, zp = cand.Z, cand.Zpoles
        res = np.linalg.norm(X @ Z - Z * zp[None, :]) / max(np.linalg.norm(X), 1e-300)
        checks.append(
            Check.at_most(
                "eig_residual",
                res,
                1e-7,
                "||(A - LC) Z - Z diag(poles)||_F / ||A - LC||_F for the solver's basis",
            )
        )
        sv = np.linalg.svd(Z, compute_uv=False)
        kz = float(sv[0] / sv[-1]) if sv[-1] > 0 else float("inf")
        if math.isfinite(k2):
            # eigenvectors computed in floating point move by ~eps kappa2 each, so cond(V) by ~eps kappa2^2
            tol = KAPPA_TOL + 100.0 * np.finfo(float).eps * k2 * k2
            checks.append(
                Check.at_most(
                    "kappa2_agreement",
                    abs(kz - k2) / k2,
                    tol,
                    "solver basis cond vs metrics.kappa2 (relative)",
                )
            )
        elif math.isfinite(kz) and res <= 1e-7:
            # repeated pole: the basis is not unique; report the verified basis the solver found
            k2 = kz
            Zi = np.linalg.inv(Z)
            kf = float(np.linalg.norm(Z) * np.linalg.norm(Zi))
            V = Z
        if V is None:
            V = Z
    else:
        V = metrics.eigenvector_matrix(X) if math.isfinite(k2) else None
    gn = float(np.linalg.norm(L, 2))
    if mask is not None:
        off = float(np.max(np.abs(L[~mask]))) if (~mask).any() else 0.0
        checks.append(Check.at_most("mask", off, 0.0, "largest |L| entry outside the structure mask"))
    if max_gain is not None:
        checks.append(Check.at_most("gain_bound", gn, max_gain * (1 + 1e-6), "||L||_2 <= max_gain"))
    if kappa2_max is not None:
        checks.append(Check.at_most("kappa2_bound", k2, kappa2_max * (1 + 1e-6), "kappa2 <= kappa2_max"))
    if eta_max is not None:
        checks.append(Check.at_most("eta_bound", eta_v, eta_max * (1 + 1e-6), "eta <= eta_max"))
    if not checks:
        checks.append(Check.at_most("finite_gain", 0.0, 0.0))
    out = {"kappa2": k2, "eta": eta_v, "kappa_fro": kf, "gain_norm": gn, "poles": poles, "V": V}
    return out, Verification.of(checks)


# --------------------------------------------------------------------------- solving


def _run_start(
    nlp, L0: NDArray, objective: str, options: dict[str, Any], check, stages: tuple[int, ...] | None = None
) -> list[_Candidate]:
    """Solve from one initial gain (continuation stages for kappa2); every stage's candidate."""
    from ..solvers.casadi_backend import solve_opti

    if objective != "kappa2":
        stages = (None,)
    elif stages is None:
        stages = KAPPA2_STAGES
    nlp.set_initial_gain(L0)
    history: list[_Candidate] = []
    last_good = None
    for J in stages:
        if J is not None:
            nlp.set_stage(J)
        if last_good is not None:
            nlp.warm_start(last_good)
        rep = solve_opti(nlp.opti, options, configure=not nlp.solver_ready)
        nlp.solver_ready = True
        L = nlp.gain(rep.value)
        try:
            Z, zp = nlp.basis(rep.value)
        except (ValueError, np.linalg.LinAlgError, FloatingPointError):
            Z, zp = None, None
        cand = _Candidate(
            L,
            Z,
            zp,
            rep.status,
            rep.stats.native_status,
            rep.message,
            int(rep.stats.iterations or 0),
            float(rep.stats.time),
            stage=type(nlp).__name__ + ("" if J is None else f" J={J}"),
        )
        history.append(cand)
        ok, _ = check(cand)
        if ok:
            last_good = nlp.snapshot(rep.value)
        elif J is not None and last_good is None:
            if len(history) >= 2:  # two failed stages from this start: give it up
                break
            nlp.set_initial_gain(L0)  # retry the next stage from the same start
    return history


def _solve_starts(starts_list, runner, objective, evaluate):
    """Run every start through ``runner`` (-> candidates); keep each start's best verified one."""
    records: list[StartRecord] = []
    evaluated: list[tuple[float, int, dict, Verification, _Candidate]] = []
    for idx, (origin, L0, structure) in enumerate(starts_list):
        hist = runner(L0, structure)
        t = sum(c.time for c in hist)
        it = sum(c.iterations for c in hist)
        scored = []
        for c in hist:
            m, v = evaluate(c)
            scored.append((_metric_of(objective, m), m, v, c))
        ok = [x for x in scored if x[2].passed]
        pool = ok if ok else scored[-1:]
        obj, m, v, cand = min(pool, key=lambda x: x[0] if math.isfinite(x[0]) else float("inf"))
        cand = _Candidate(
            cand.L, cand.Z, cand.Zpoles, cand.status, cand.native, cand.message, it, t, cand.stage
        )
        records.append(
            StartRecord(
                idx,
                origin,
                Status(cand.status),
                v.passed,
                m["kappa2"],
                m["eta"],
                m["gain_norm"],
                obj,
                it,
                t,
                cand.message + (f" [{cand.stage}]" if cand.stage else ""),
            )
        )
        evaluated.append((obj, idx, m, v, cand))
    return records, evaluated


def _pick(evaluated):
    def key(e):
        obj, idx, m, v, c = e
        solved = Status(c.status).is_solved
        rank = 0 if (v.passed and solved) else 1 if v.passed else 2
        o = obj if math.isfinite(obj) else float("inf")
        return (rank, o, idx)

    return min(evaluated, key=key)


def _result_from(
    plant,
    records,
    evaluated,
    *,
    objective,
    target,
    region,
    extra_checks=None,
    kalman=None,
    infeasible_msg=None,
) -> ObserverDesign:
    obj, idx, m, v, cand = _pick(evaluated)
    if extra_checks is not None:
        v = v + extra_checks(cand)
    status = Status(cand.status)
    all_infeasible = all(Status(r.status).is_infeasible for r in records)
    certificate = None
    if not v.passed and all_infeasible:
        status = Status.INFEASIBLE
        certificate = {
            "reason": infeasible_msg
            or "IPOPT converged to a point of local infeasibility from "
            "every start (not a proof: the NLP is non-convex)",
            "starts": len(records),
        }
    converged = sum(1 for r in records if r.verified and Status(r.status).is_solved)
    if v.passed and status.is_solved:
        msg = (
            f"best of {len(records)} starts (start {idx}, {records[idx].origin}): {objective} = {obj:.6g}; "
            f"{converged} of {len(records)} starts converged to verified designs"
        )
    else:
        failed = "; ".join(f"{c.name}" for c in v.failed)
        msg = (
            f"no start gave a solved and verified design ({converged} of {len(records)}); best start {idx} "
            f"({records[idx].origin}): {cand.message}" + (f"; failed checks: {failed}" if failed else "")
        )
    stats = SolverStats(
        backend="ipopt",
        native_status=cand.native,
        time=float(sum(r.time for r in records)),
        iterations=int(sum(r.iterations for r in records)),
        extra={"starts": len(records), "converged": converged, "best_start": idx, "objective": obj},
    )
    kw = kalman or {}
    return ObserverDesign(
        L=cand.L,
        poles=m["poles"],
        kappa2=m["kappa2"],
        eta=m["eta"],
        kappa_fro=m["kappa_fro"],
        gain_norm=m["gain_norm"],
        objective=objective,
        status=status,
        message=msg,
        solver_stats=stats,
        verification=v,
        starts=tuple(records),
        V=m["V"],
        target_poles=target,
        region=region,
        certificate=certificate,
        **kw,
    )


def _infeasible(plant, objective, reason: str, certificate: dict, target=None, region=None) -> ObserverDesign:
    n, p = plant.n, plant.p
    nan = float("nan")
    return ObserverDesign(
        L=np.full((n, p), np.nan),
        poles=np.full(n, np.nan + 0j),
        kappa2=float("inf"),
        eta=float("inf"),
        kappa_fro=float("inf"),
        gain_norm=nan,
        objective=objective,
        status=Status.INFEASIBLE,
        message=reason,
        solver_stats=SolverStats(backend="analytic", native_status="infeasible"),
        verification=Verification.of([Check.at_most("feasible", 1.0, 0.0, reason)]),
        starts=(),
        target_poles=target,
        region=region,
        certificate=certificate,
    )


def _placement_start(plant: Plant, poles: NDArray, method: str) -> NDArray | None:
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            L = place_observer(plant, poles, method=method)
    except (ValueError, np.linalg.LinAlgError):
        return None
    if not np.all(np.isfinite(L)):
        return None
    return L


# --------------------------------------------------------------------------- the verbs


def well_conditioned_observer(
    plant: Plant,
    *,
    region: Region | None = None,
    poles: ArrayLike | None = None,
    objective: str = "kappa2",
    structure: ArrayLike | None = None,
    max_gain: float | None = None,
    kappa2_max: float | None = None,
    eta_max: float | None = None,
    starts: int = 8,
    seed: int = 0,
    solver: str = "ipopt",
    scaling: bool = True,
    options: dict[str, Any] | None = None,
) -> ObserverDesign:
    """Observer gain whose error dynamics ``A - L C`` have a well-conditioned eigenbasis.

    Parameters
    ----------
    plant : Plant
        ``A`` (n, n), ``C`` (p, n); continuous, or discrete when ``plant.dt`` is set.
    region : Region, optional
        Poles free inside this region (use a discrete-time region, e.g. ``Disk.unit(0.9)``,
        when ``plant.dt`` is set).  Unbounded regions need ``max_gain`` or a bounded member
        (e.g. ``& Disk(0, R)``) when the metric keeps improving as poles move away.
    poles : (n,) array_like of complex, optional
        Fixed poles (conjugate-closed; a pole may repeat up to ``rank(C)`` times).  Give
        ``region`` or ``poles``, not both; with neither, the region is the stability region
        (``HalfPlane(0)`` or the unit disk).
    objective : {"kappa2", "kappa_fro", "eta"}
        What to minimize: kappa2 of the unit-column eigenvector matrix (seed 001's index),
        its Frobenius counterpart, or Huh & Stein's eta.
    structure : (n, p) array_like of bool, optional
        Free entries of ``L`` (False = structural zero).
    max_gain : float, optional
        Bound on ``||L||_2``.
    kappa2_max, eta_max : float, optional
        Trade-off bounds on the metrics that are not minimized (e.g. minimize eta subject to
        ``kappa2 <= kappa2_max``): minimizing eta alone can make kappa2 much worse.
    starts : int, default 8
        Number of multi-start runs.  Fixed poles: scipy YT, KNV0 (real poles) and random
        parametric eigenstructure assignments; region: robust placement at poles sampled in the
        region (:meth:`Region.sample_poles`), with varied real/complex patterns.
    seed : int, default 0
        Seed of every random choice (reproducible).
    solver : {"ipopt"}
    scaling : bool, default True
        Time scaling (continuous time) and unit-norm output rows: both leave kappa2 and eta
        unchanged.
    options : dict, optional
        IPOPT options (``"ipopt.max_iter"``, ...) merged over the defaults.

    Returns
    -------
    ObserverDesign
        ``success`` is True only when the best start was solved *and* passed verification
        (poles recomputed with numpy against the target or the region, the solver's
        eigenbasis against ``metrics.kappa2``, mask, gain and metric bounds).  Infeasible
        questions (a pole repeated more than ``rank(C)`` times; IPOPT infeasible from every
        start) come back with ``status`` infeasible and a ``certificate``.

    Raises
    ------
    ValidationError
        Both or wrong ``poles``/``region``, unknown objective or solver, bad mask, bounds or
        ``starts``.
    NotObservableError
        ``(C, A)`` is not observable (names the unobservable modes).
    NotConjugateClosedError, DimensionError
        Bad pole set.

    Notes
    -----
    kappa2 is minimized through a smooth upper bound tightened by continuation
    (:mod:`optdesign.formulate.well_conditioned`); the reported kappa2 is recomputed with
    numpy.  The problem is non-convex: the best of ``starts`` local solutions is returned
    and ``starts`` holds every run.

    Fixed poles use the reduced (left-eigenvector) NLP.  In a region each start runs (A) the
    fixed-pole NLP at the sampled poles, (B) the free-pole NLP from the placement at those
    poles, (C) the fixed-pole NLP at B's poles, from B's gain and from scipy's YT gain there;
    every candidate is verified and the best is kept -- so the design is never worse than
    robust placement at its own poles (from those starts).

    References
    ----------
    Seed 001 (Jung & Huh); Kautsky, Nichols & Van Dooren (1985); Tits & Yang (1996).

    Examples
    --------
    >>> import numpy as np
    >>> from optdesign import Plant, well_conditioned_observer
    >>> plant = Plant([[0, 1], [2, -1]], [[1, 0]])
    >>> d = well_conditioned_observer(plant, poles=[-2, -3], starts=1)
    >>> bool(d.success), round(d.kappa2, 4)   # a SISO gain is fixed by its poles: 3 + sqrt(10)
    (True, 6.1623)
    """
    plant = _check_plant(plant)
    if objective not in OBJECTIVES:
        raise ValidationError(f"objective must be one of {OBJECTIVES}; found {objective!r}")
    _check_solver(solver)
    starts = _check_int("starts", starts, 1)
    seed = _check_int("seed", seed, 0)
    n, p = plant.n, plant.p
    mask = _check_mask(structure, n, p)
    max_gain = None if max_gain is None else as_positive_float("max_gain", max_gain)
    eta_max = None if eta_max is None else as_positive_float("eta_max", eta_max)
    if kappa2_max is not None:
        kappa2_max = as_positive_float("kappa2_max", kappa2_max)
        if kappa2_max < 1:
            raise ValidationError(f"kappa2_max must be >= 1 (kappa2 >= 1 always); found {kappa2_max!r}")
    if region is not None and poles is not None:
        raise ValidationError("give either poles (fixed) or region (free poles), not both")
    if region is not None and not isinstance(region, Region):
        raise ValidationError(f"region must be an optdesign.regions.Region; found {type(region).__name__}")
    if poles is not None:
        plant.require_observable(what="well-conditioned observer design with fixed poles")
    opts = dict(_IPOPT_DEFAULTS)
    opts.update(options or {})
    rng = np.random.default_rng(seed)

    if poles is not None:
        target = as_poles("poles", poles, n)
        rank = int(np.linalg.matrix_rank(plant.C))
        vals, counts = np.unique(np.round(target, 10), return_counts=True)
        if counts.max() > rank:
            k = int(np.argmax(counts))
            reason = (
                f"pole {vals[k]} is requested {counts[k]} times but rank(C) = {rank}: the eigenspace of "
                f"A - LC for it has dimension <= rank(C), so A - LC would be defective (kappa2 = inf)"
            )
            return _infeasible(
                plant,
                objective,
                reason,
                {
                    "reason": "multiplicity exceeds rank(C)",
                    "pole": complex(vals[k]),
                    "multiplicity": int(counts[k]),
                    "rank_C": rank,
                },
                target=target,
            )
        if objective == "eta" and counts.max() > 1:
            return _infeasible(
                plant,
                objective,
                "eta is infinite for repeated poles (zero eigenvalue gap)",
                {"reason": "repeated pole with objective eta", "pole": complex(vals[np.argmax(counts)])},
                target=target,
            )
        pstruct = PoleStructure.of(target)
        sc = (
            NLPScaling.for_plant(plant, float(np.max(np.abs(target))), balance=False)
            if scaling
            else NLPScaling.identity(n, p)
        )
        start_list = _fixed_starts(plant, target, starts, rng, pstruct)

        nlp = build_observer_nlp(
            plant,
            pstruct,
            fixed_poles=True,
            objective=objective,
            mask=mask,
            max_gain=max_gain,
            kappa2_max=kappa2_max,
            eta_max=eta_max,
            scaling=sc,
        )
        nlp.set_poles(target)

        def evaluate(c):
            return _evaluate(
                plant,
                c,
                target=target,
                region=None,
                mask=mask,
                max_gain=max_gain,
                kappa2_max=kappa2_max,
                eta_max=eta_max,
            )

        def check(c):
            m, v = evaluate(c)
            return v.passed, _metric_of(objective, m)

        def runner(L0, st):
            return _run_start(nlp, L0, objective, opts, check)

        records, evaluated = _solve_starts(start_list, runner, objective, evaluate)
        return _result_from(plant, records, evaluated, objective=objective, target=target, region=None)

    if region is None:
        region = stability_region(plant.is_discrete)
    if not region.bounded and max_gain is None:
        raise ValidationError(
            f"the pole region {region!r} is unbounded and no max_gain was given: kappa2 and eta can keep "
            "improving as poles (and ||L||) grow without bound; give max_gain or intersect the region with "
            "a Disk, e.g. region & Disk(0, R)"
        )
    unobs = plant.unobservable_modes()
    if unobs.size:
        dist = region.distance(unobs)
        if np.any(dist > 1e-9 * max(1.0, float(np.max(np.abs(unobs))))):
            k = int(np.argmax(dist))
            reason = (
                f"the unobservable mode {unobs[k]:.6g} of (C, A) is an eigenvalue of A - LC for every L "
                f"and lies outside the region (distance {dist[k]:.3g})"
            )
            return _infeasible(
                plant,
                objective,
                reason,
                {"reason": "unobservable mode outside the region", "modes": unobs, "distance": dist},
                region=region,
            )
    try:
        x0 = region.interior_point()
    except Exception:  # noqa: BLE001 - any failure: fall back on the plant's scale
        x0 = 0.0
    sc = NLPScaling.for_plant(plant, abs(x0), balance=False) if scaling else NLPScaling.identity(n, p)
    start_list = _region_starts(plant, region, starts, rng, mask)

    fixed_cache: dict[PoleStructure, Any] = {}
    region_cache: dict[PoleStructure, Any] = {}
    kw = dict(
        objective=objective, mask=mask, max_gain=max_gain, kappa2_max=kappa2_max, eta_max=eta_max, scaling=sc
    )

    def evaluate(c):
        return _evaluate(
            plant,
            c,
            target=None,
            region=region,
            mask=mask,
            max_gain=max_gain,
            kappa2_max=kappa2_max,
            eta_max=eta_max,
        )

    def check(c):
        m, v = evaluate(c)
        return v.passed, _metric_of(objective, m)

    def fixed_at(poles_now, L0):
        """Fixed-pole optimization at given poles (inside the region), or [] if not applicable."""
        try:
            P = as_poles("poles", poles_now, n)
        except ValidationError:
            return []
        st = PoleStructure.of(P)
        _, counts = np.unique(np.round(P, 8), return_counts=True)
        if counts.max() > rank_c or (objective == "eta" and counts.max() > 1):
            return []
        if st not in fixed_cache:
            fixed_cache[st] = build_observer_nlp(plant, st, fixed_poles=True, **kw)
        nlp = fixed_cache[st]
        try:
            nlp.set_poles(P)
        except ValidationError:
            return []
        return _run_start(nlp, L0, objective, opts, check)

    def runner(L0, st):
        # (A) the best eigenbasis at the sampled poles, (B) free poles from there,
        # (C) the best eigenbasis at B's poles -- each verified; the best is kept
        P0 = np.linalg.eigvals(plant.A - L0 @ plant.C)
        hist = fixed_at(P0, L0) if observable and region.contains(P0) else []
        if st not in region_cache:
            region_cache[st] = build_observer_nlp(plant, st, fixed_poles=False, region=region, **kw)
        # the free-pole NLP from the start itself, with the whole continuation: measured on COMPleib
        # AC6, starting it from the fixed-pole optimum (stages 9, 12 only) ended at kappa2 18.9,
        # from the placement start at 1.27
        hb = _run_start(region_cache[st], L0, objective, region_opts, check, stages=REGION_STAGES)
        hist += hb
        okb = [c for c in hb if check(c)[0]]
        if okb and observable:
            cb = min(okb, key=lambda c: check(c)[1])
            Pb = np.linalg.eigvals(plant.A - cb.L @ plant.C)
            hist += fixed_at(Pb, cb.L)
            Lyt = _placement_start(plant, Pb, "YT") if mask is None else None
            if Lyt is not None:  # robust placement at the same poles may sit in a better basin
                hist += fixed_at(Pb, Lyt)
        return hist

    observable = plant.is_observable()
    rank_c = int(np.linalg.matrix_rank(plant.C))
    region_opts = dict(opts)
    region_opts["ipopt.max_iter"] = min(int(opts.get("ipopt.max_iter", 300)), 300)
    records, evaluated = _solve_starts(start_list, runner, objective, evaluate)
    return _result_from(plant, records, evaluated, objective=objective, target=None, region=region)


def _fixed_starts(plant, target, starts, rng, pstruct):
    out = []
    for method in ("YT", "KNV0"):
        if len(out) >= starts:
            break
        if method == "KNV0" and np.any(target.imag != 0):
            continue
        L0 = _placement_start(plant, target, method)
        if L0 is not None:
            out.append((method, L0, pstruct))
    tries = 0
    while len(out) < starts and tries < 10 * starts:
        tries += 1
        try:
            L0 = random_gain_for_poles(plant, target, rng)
        except (np.linalg.LinAlgError, ValueError):
            continue
        if np.all(np.isfinite(L0)):
            out.append(("random", L0, pstruct))
    if not out:  # repeated poles YT cannot take and no random start: perturb the poles
        pert = target + 1e-3 * max(1.0, float(np.max(np.abs(target)))) * np.arange(target.size)
        L0 = _placement_start(plant, as_poles("poles", pert), "YT")
        out.append(("YT (perturbed poles)", np.zeros((plant.n, plant.p)) if L0 is None else L0, pstruct))
    return out


def _riccati_start(plant: Plant, rng: np.random.Generator, k: int) -> NDArray:
    """A stabilizing Kalman gain for a random process noise (works for detectable plants)."""
    from scipy.linalg import solve_continuous_are, solve_discrete_are

    n, p = plant.n, plant.p
    F = rng.standard_normal((n, n)) if k else np.eye(n)
    Qs = F @ F.T + 1e-3 * np.eye(n)
    try:
        if plant.is_discrete:
            P = solve_discrete_are(plant.A.T, plant.C.T, Qs, np.eye(p))
            return plant.A @ P @ plant.C.T @ np.linalg.inv(plant.C @ P @ plant.C.T + np.eye(p))
        P = solve_continuous_are(plant.A.T, plant.C.T, Qs, np.eye(p))
        return P @ plant.C.T
    except (ValueError, np.linalg.LinAlgError):
        return np.zeros((n, p))


def _region_starts(plant, region, starts, rng, mask):
    n = plant.n
    observable = plant.is_observable()
    fractions = [0.5, 1.0, 0.0, 0.25, 0.75]
    out = []
    for k in range(starts):
        rf = fractions[k % len(fractions)]
        P0 = region.sample_poles(n, rng, real_fraction=rf)
        st = PoleStructure.of(P0)
        L0 = _placement_start(plant, P0, "YT") if observable else None
        origin = "region sample + YT"
        if L0 is None and observable:
            try:
                L0 = random_gain_for_poles(plant, P0, rng)
                origin = "region sample + random assignment"
            except (np.linalg.LinAlgError, ValueError):
                L0 = None
        if L0 is None:  # detectable but unobservable (or placement failed): a Kalman gain
            L0 = _riccati_start(plant, rng, k)
            origin = "Kalman gain (random Q)"
            st = PoleStructure.of(np.linalg.eigvals(plant.A - L0 @ plant.C), tol=1e-6)
        if mask is not None:
            L0 = np.where(mask, L0, 0.0)
            st = PoleStructure.of(np.linalg.eigvals(plant.A - L0 @ plant.C), tol=1e-6)
        out.append((origin, L0, st))
    return out


def well_conditioned_kalman(
    plant: Plant,
    *,
    region: Region | None = None,
    objective: str = "eta",
    q_structure: str = "scalar",
    kappa2_max: float | None = None,
    eta_max: float | None = None,
    q_range: tuple[float, float] = (1e-3, 1e3),
    starts: int = 4,
    seed: int = 0,
    solver: str = "ipopt",
    options: dict[str, Any] | None = None,
) -> ObserverDesign:
    """A steady-state Kalman filter whose error dynamics are well conditioned.

    The process-noise covariance is the design variable (``R`` stays the plant's): the NLP
    minimizes the chosen metric of ``A - L C`` subject to the filter Riccati equation
    (continuous ARE, or the predictor DARE when ``plant.dt`` is set), ``P >= 0`` (Cholesky
    factor), ``Q >= 0`` and optional pole-region and metric bounds -- so the result is a true
    Kalman filter for the returned ``Q``, not merely an observer.

    Parameters
    ----------
    plant : Plant
        ``A, C, G`` and ``R`` (identity when absent); with ``q_structure="scalar"`` the design is
        ``Q = q Q0`` with ``Q0 = plant.Q`` (identity when absent), i.e. seed 001's ``q/r``.
    region : Region, optional
        The filter poles must lie in it.
    objective : {"eta", "kappa2", "kappa_fro"}, default "eta"
    q_structure : {"scalar", "diagonal", "full"}
        ``Q = q Q0``; ``Q = diag(q)``; ``Q = F F'`` (lower-triangular ``F``).
    kappa2_max, eta_max : float, optional
        Trade-off bounds.
    q_range : (float, float)
        Range of the scalar multipliers of ``Q0`` used as starting points (log-spaced).
    starts : int, default 4
    seed : int, default 0
    solver : {"ipopt"}
    options : dict, optional
        IPOPT options.

    Returns
    -------
    ObserverDesign
        With ``Q``, ``P``, ``R``; verification adds the Riccati residual (recomputed with
        :func:`optdesign.riccati.filter_are_residual`), ``P >= 0``, ``Q >= 0`` and the gain
        against an independent Riccati solve for the returned ``Q``.

    Raises
    ------
    ValidationError
        Unknown objective, q_structure or solver; bad bounds; ``q_range`` not ``0 < lo <= hi``.
    NotObservableError
        ``(C, A)`` not detectable.

    References
    ----------
    Seed 001, section 2.3 and Example 2 (the gain depends on ``q/r`` only, eq 29).
    """
    from ..classical.riccati import filter_are, filter_are_residual

    plant = _check_plant(plant)
    if objective not in OBJECTIVES:
        raise ValidationError(f"objective must be one of {OBJECTIVES}; found {objective!r}")
    if q_structure not in ("scalar", "diagonal", "full"):
        raise ValidationError(f"q_structure must be 'scalar', 'diagonal' or 'full'; found {q_structure!r}")
    _check_solver(solver)
    starts = _check_int("starts", starts, 1)
    seed = _check_int("seed", seed, 0)
    eta_max = None if eta_max is None else as_positive_float("eta_max", eta_max)
    kappa2_max = None if kappa2_max is None else as_positive_float("kappa2_max", kappa2_max)
    if region is not None and not isinstance(region, Region):
        raise ValidationError(f"region must be an optdesign.regions.Region; found {type(region).__name__}")
    try:
        lo, hi = (float(q_range[0]), float(q_range[1]))
    except (TypeError, ValueError, IndexError):
        raise ValidationError(f"q_range must be a pair (lo, hi); found {q_range!r}") from None
    if not (0 < lo <= hi and math.isfinite(hi)):
        raise ValidationError(f"q_range must satisfy 0 < lo <= hi < inf; found {q_range!r}")
    plant.require_observable(detectable_ok=True, what="a well-conditioned Kalman filter")
    n, p, m = plant.n, plant.p, plant.m
    R = plant.R if plant.R is not None else np.eye(p)
    Q0 = plant.Q if plant.Q is not None else np.eye(m)
    base = plant.replace(R=R, Q=Q0)
    opts = dict(_IPOPT_DEFAULTS)
    opts.update(options or {})
    rng = np.random.default_rng(seed)

    # starting points: Kalman filters for log-spaced multiples of Q0 (random diagonal jitter)
    mults = np.geomspace(lo, hi, starts) if starts > 1 else np.array([math.sqrt(lo * hi)])
    start_list = []
    for k, q in enumerate(mults):
        if q_structure == "scalar":
            Qs = q * Q0
            theta0: Any = q
        elif q_structure == "diagonal":
            d = q * np.maximum(np.diag(Q0), 1e-6) * (np.exp(0.3 * rng.standard_normal(m)) if k else 1.0)
            Qs = np.diag(d)
            theta0 = d
        else:
            Qs = q * Q0
            F = np.linalg.cholesky(Qs + 1e-12 * np.eye(m))
            theta0 = np.array([F[i, j] for i in range(m) for j in range(i + 1)])
        try:
            are = filter_are(base.replace(Q=Qs))
        except (ValueError, np.linalg.LinAlgError):
            continue
        st = PoleStructure.of(are.poles, tol=1e-7)
        start_list.append((f"riccati q={q:.3g}", (are.P, theta0, are.L), st))
    if not start_list:
        raise ValidationError(
            "no Riccati solution exists for any starting noise level in q_range; "
            "check detectability and that G Q G' excites the plant's modes"
        )
    sc = NLPScaling.identity(n, p)

    def build(st):
        return build_kalman_nlp(
            base,
            st,
            objective=objective,
            q_structure=q_structure,
            region=region,
            kappa2_max=kappa2_max,
            eta_max=eta_max,
            scaling=sc,
        )

    def evaluate(c):
        return _evaluate(
            base,
            c,
            target=None,
            region=region,
            mask=None,
            max_gain=None,
            kappa2_max=kappa2_max,
            eta_max=eta_max,
        )

    from ..solvers.casadi_backend import solve_opti

    records: list[StartRecord] = []
    evaluated = []
    cache: dict[Any, Any] = {}
    qinfo: dict[int, tuple[NDArray, NDArray]] = {}
    for idx, (origin, (P0, th0, L0), st) in enumerate(start_list):
        if st not in cache:
            cache[st] = build(st)
        knlp = cache[st]
        knlp.set_initial(P0, th0, L0)
        hist = []
        best = None
        stages = KAPPA2_STAGES if objective == "kappa2" else (None,)
        good = None
        for J in stages:
            if J is not None:
                knlp.obs.set_stage(J)
            if good is not None:
                knlp.obs.warm_start(good[0])
                knlp.opti.set_initial(knlp.Fp, good[1])
                knlp.opti.set_initial(knlp.theta, good[2])
            rep = solve_opti(knlp.opti, opts, configure=not knlp.obs.solver_ready)
            knlp.obs.solver_ready = True
            L = knlp.obs.gain(rep.value)
            try:
                Z, zp = knlp.obs.basis(rep.value)
            except (ValueError, np.linalg.LinAlgError):
                Z, zp = None, None
            c = _Candidate(
                L,
                Z,
                zp,
                rep.status,
                rep.stats.native_status,
                rep.message,
                int(rep.stats.iterations or 0),
                float(rep.stats.time),
                "" if J is None else f"J={J}",
            )
            hist.append(c)
            Qv = knlp.noise(rep.value)
            Pv = np.asarray(rep.value(knlp.P), dtype=float).reshape(n, n)
            _, v = evaluate(c)
            if v.passed:
                good = (
                    knlp.obs.snapshot(rep.value),
                    np.asarray(rep.value(knlp.Fp), dtype=float),
                    np.asarray(rep.value(knlp.theta), dtype=float),
                )
                best = c
                qinfo[idx] = (Qv, Pv)
        cand = best if best is not None else hist[-1]
        if best is None:
            qinfo[idx] = (Qv, Pv)
        t = sum(h.time for h in hist)
        it = sum(h.iterations for h in hist)
        cand = _Candidate(
            cand.L, cand.Z, cand.Zpoles, cand.status, cand.native, cand.message, it, t, cand.stage
        )
        mtr, v = evaluate(cand)
        v = v + _kalman_checks(base, cand.L, *qinfo[idx], filter_are, filter_are_residual)
        obj = _metric_of(objective, mtr)
        records.append(
            StartRecord(
                idx,
                origin,
                Status(cand.status),
                v.passed,
                mtr["kappa2"],
                mtr["eta"],
                mtr["gain_norm"],
                obj,
                it,
                t,
                cand.message,
            )
        )
        evaluated.append((obj, idx, mtr, v, cand))
    best_idx = _pick(evaluated)[1]
    Qb, Pb = qinfo[best_idx]
    res = _result_from(
        base,
        records,
        evaluated,
        objective=objective,
        target=None,
        region=region,
        kalman={"Q": Qb, "P": Pb, "R": np.asarray(R, dtype=float)},
    )
    return res


def _kalman_checks(plant, L, Q, P, filter_are, filter_are_residual) -> Verification:
    checks = []
    Qs = 0.5 * (Q + Q.T)
    Ps = 0.5 * (P + P.T)
    scaleQ = max(1.0, float(np.max(np.abs(Qs)))) if Qs.size else 1.0
    scaleP = max(1.0, float(np.max(np.abs(Ps))))
    checks.append(Check.at_least("Q_min_eig", float(np.linalg.eigvalsh(Qs)[0]), -1e-9 * scaleQ, "Q >= 0"))
    checks.append(Check.at_least("P_min_eig", float(np.linalg.eigvalsh(Ps)[0]), -1e-9 * scaleP, "P >= 0"))
    try:
        res = filter_are_residual(plant, Ps, Q=Qs)
    except (ValueError, np.linalg.LinAlgError) as exc:
        res = float("inf")
        checks.append(Check.at_most("riccati_residual", res, 1e-7, f"residual failed: {exc}"))
    else:
        checks.append(Check.at_most("riccati_residual", res, 1e-7, "relative residual of the filter ARE"))
    try:
        ref = filter_are(plant.replace(Q=Qs))
        dl = float(np.linalg.norm(L - ref.L) / max(np.linalg.norm(ref.L), 1e-300))
        checks.append(
            Check.at_most(
                "gain_vs_riccati", dl, 1e-5, "||L - L_ARE(Q)|| / ||L_ARE(Q)||, independent Riccati solve"
            )
        )
    except (ValueError, np.linalg.LinAlgError) as exc:
        checks.append(Check.at_most("gain_vs_riccati", float("inf"), 1e-5, f"Riccati solve failed: {exc}"))
    return Verification.of(checks)
