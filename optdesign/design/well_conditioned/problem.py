"""The caller-held problem object of the well-conditioned observer: :class:`WellConditionedProblem`.

Built once from a plant and the fixed choices (objective, structural zeros, bounds, starts, the NLP
settings) -- validation, the placement engine (:class:`EigenstructureEngine`, the pole-independent
part of the eigenstructure parametrization), and the IPOPT NLPs only when a constraint needs them,
each built once per pole structure and re-solved with new parameters.  :meth:`~WellConditionedProblem.solve`
answers for fixed poles or a region, optionally warm-started from a previous design: the engine
route first (:mod:`~optdesign.design.well_conditioned.engine_route`), the NLP route
(:mod:`~optdesign.design.well_conditioned.nlp_route`) where the engine does not handle a
constraint or its design does not verify.  No hidden caches: everything re-used lives on the problem
object, and the same call gives the same answer whatever ran before in the process.
"""

from __future__ import annotations

import dataclasses
import itertools
from collections.abc import Callable, Iterable, Iterator, Sequence
from functools import partial
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..._deadline import Deadline, as_time_limit
from ..._progress import Progress, as_progress
from ..._validate import as_bool, as_gain_mask, as_int, as_poles, as_positive_float, as_str
from ...backends.report import one_warning_per_call
from ...engines.eigenstructure import EigenstructureEngine
from ...engines.eigenstructure_fixed import default_starts
from ...errors import DimensionError, ValidationError
from ...formulate.well_conditioned import NLPScaling, PoleStructure, build_observer_nlp, check_objective
from ...model.coerce import as_plant
from ...model.plant import Plant
from ...model.regions import Disk, HalfPlane, Intersection, Region, Sector, stability_region
from ...results import Certificate, SolverStats, Status
from .engine_route import ENGINE, engine_fixed, engine_region
from .evaluation import (
    Evaluated,
    attains,
    cached_evaluate,
    check_region_stable,
    check_target_stable,
    design_outcome,
    evaluate_candidate,
    objective_lower_bound,
)
from .nlp_route import REGION_POLISHES, ipopt_options, nlp_fixed_runner, nlp_region_runner, solve_starts
from .one_output import unplaced_one_output
from .results import ObserverDesign, StartRecord, n_converged, no_design
from .route import (
    ENGINE_FIXED,
    ENGINE_REGION,
    IPOPT,
    Phase,
    needs_fallback,
    nlp_detail,
    proof_route,
    route_of,
)
from .starts import default_region_starts, fixed_starts, iter_region_starts

__all__ = ["WellConditionedProblem", "LocalOptimum", "local_optima", "warm_start_origin", "Objective",
           "DEFAULT_STARTS", "check_region", "kappa2_bound",
           "result_from"]

Objective = Literal["kappa2", "kappa_fro", "eta"]

#: starts of a solve when none are given (region mode, the NLP route); fixed poles on the placement
#: engine use :func:`~optdesign.engines.eigenstructure_fixed.default_starts`
DEFAULT_STARTS = 8

#: route "fast" in a region (and eta's "auto"): of the engine's starts (``default_region_starts``), how
#: many IPOPT runs from too (issue 28: on COMPleib DIS1, IPOPT from the Kalman start reaches kappa2 1.13392
#: where the engine stops at 1.13878; on REA2 the engine reaches 1.46204, IPOPT's first two 1.481)
AUTO_NLP_STARTS = 2
#: ... for eta on route "auto" (round 11, 49 plants n <= 10: a second changed no eta; region_eta.md), up to
#: this order (round 12: n = 12-30, 6 plants, IPOPT's start never beat the engine, 4-150 s), 150 iterations
#: per stage (round 16, 50 plants n <= 10: it won on 2, in 56 and 121-130; on 20 it ran to 300 for nothing)
ETA_NLP_STARTS, ETA_NLP_MAX_N, ETA_NLP_MAX_ITER = 1, 10, 150

#: the routes of region mode (``WellConditionedProblem._region_plan``)
ROUTES = ("auto", "engine", "fast", "multistart", "nlp")

#: the bounds a solve may change (``opti.parameter`` s of the NLPs)
_BOUNDS = ("max_gain", "kappa2_max", "eta_max")
#: scipy YT sweeps at the sampled start poles of the region engine (one: the engine optimizes from them)
_ENGINE_SWEEPS = 1


def check_region(region: Any) -> Region:
    """``region`` if it is a :class:`~optdesign.regions.Region`.

    Raises
    ------
    ValidationError
        Anything else.
    """
    if not isinstance(region, Region):
        raise ValidationError(f"region must be an optdesign.regions.Region; found {type(region).__name__}")
    return region


def kappa2_bound(kappa2_max: Any) -> float | None:
    """A bound on kappa2: None, or a number >= 1 (kappa2 >= 1 always)."""
    if kappa2_max is None:
        return None
    kappa2_max = as_positive_float("kappa2_max", kappa2_max)
    if kappa2_max < 1:
        raise ValidationError(f"kappa2_max must be >= 1 (kappa2 >= 1 always); found {kappa2_max!r}")
    return kappa2_max


def _region_parts(region: Region) -> tuple[Region | None, dict[str, float]]:
    """The NLP's parametric pieces of a region -- ``HalfPlane(alpha)`` (decay), a sector at the origin
    (damping), a disk at the origin (radius) -- and the rest (a fixed constraint), so that a sweep over
    those parameters re-solves one NLP."""
    members = list(region.members) if isinstance(region, Intersection) else [region]
    params: dict[str, float] = {}
    rest: list[Region] = []
    for m in members:
        if isinstance(m, HalfPlane) and "decay" not in params:
            params["decay"] = float(m.alpha)
        elif isinstance(m, Sector) and m.apex == 0.0 and "damping" not in params:
            params["damping"] = float(m.damping)
        elif isinstance(m, Disk) and m.center == 0.0 and "radius" not in params:
            params["radius"] = float(m.radius)
        else:
            rest.append(m)
    fixed = None if not rest else rest[0] if len(rest) == 1 else Intersection(*rest)
    return fixed, params


def result_from(plant: Plant, records: list[StartRecord], evaluated: list[Evaluated], *, objective: str,
                target: NDArray | None, region: Region | None, deadline: Deadline, planned: int,
                route: str, kalman: dict[str, Any] | None = None,
                phases: list[Phase] | None = None) -> ObserverDesign:
    """The design of a multi-start run: the best verified start (:func:`~.evaluation.design_outcome`).

    ``route``: the short route name (``extra["route"]``); ``phases``: the phases that ran, for the
    result's :class:`~optdesign.results.Route` (default: one phase over every start, IPOPT when
    ``route`` is ``"nlp"``, else the engine)."""
    if phases is None:
        name = IPOPT if route == "nlp" else ENGINE_REGION if region is not None else ENGINE_FIXED
        phases = [Phase(name, "backend" if route == "nlp" else "engine", 0, max(len(records), 1))]
    if not evaluated:  # the time ran out before any start could run
        reason = f"time limit of {deadline.limit:g} s reached before any of the {planned} starts could run"
        return no_design(plant, objective, Status.TIME_LIMIT, reason, None, target=target, region=region,
                         backend="ipopt" if route == "nlp" else ENGINE,
                         route=route_of(phases, [], None, False),
                         **(kalman or {}))
    (obj, idx, m, v, cand), status, msg = design_outcome(records, evaluated, objective, deadline=deadline,
                                                         planned=planned)
    bound = objective_lower_bound(objective, plant.n)
    if status.is_solved and len(records) < planned and attains(bound, obj, v, cand):
        msg += (f"; stopped after {len(records)} of {planned} starts: {objective} = {bound:g} is its lower "
                "bound (a global optimum)")
    elif status.is_solved and attains(bound, obj, v, cand):
        msg += f"; {objective} = {bound:g} is its lower bound (a global optimum)"
    stats = SolverStats(
        backend=cand.backend, native_status=cand.native,
        time=float(sum(r.time for r in records)), iterations=int(sum(r.iterations for r in records)),
        extra={"starts": len(records), "planned_starts": planned, "converged": n_converged(records),
               "best_start": idx, "objective": obj, "route": route},
    )
    return ObserverDesign(
        L=cand.L, poles=m["poles"], kappa2=m["kappa2"], eta=m["eta"], kappa_fro=m["kappa_fro"],
        gain_norm=m["gain_norm"], objective=objective, status=status, message=msg, solver_stats=stats,
        verification=v, starts=tuple(records), V=m["V"], target_poles=target, region=region, plant=plant,
        extra={"local_optima": local_optima(evaluated, bound)},
        route=route_of(phases, evaluated, idx, bool(v.passed)), **(kalman or {}),
    )


def warm_start_origin(i: int) -> str:
    """The origin (``StartRecord.origin``) of warm start ``i`` of a solve: ``"warm start"`` (the
    first, ``warm_start``), then ``"warm start 2"``, ... (``warm_starts``)."""
    return "warm start" + (f" {i + 1}" if i else "")


def local_optima(evaluated: list[Evaluated], bound: float | None = None) -> tuple[LocalOptimum, ...]:
    """The verified answers of a multi-start run's starts (one per start that gave one), best first
    (by objective, then start index): what a sweep carries to its next point as warm starts.

    A start's own gain that no solver improved (stage ``"start gain"``) counts only when it attains
    the objective's lower ``bound`` (a global optimum): otherwise it is no local optimum of this
    problem (a warm start's gain was one of the previous problem's).  In a sweep's pool such gains
    looked like distinct optima and kept the placement starts from running again (COMPleib HE1,
    alpha 0.75: kappa2 43.5 where they reach 26.2; on the DIS2 grid they cost warm-start solves:
    41.8 against 34.8 ms per point when a warm start's gain is kept)."""
    good = [e for e in evaluated
            if e[3].passed and np.all(np.isfinite(e[4].L))
            and (e[4].stage != "start gain" or attains(bound, e[0], e[3], e[4]))]
    good.sort(key=lambda e: (e[0], e[1]))
    out = []
    for obj, idx, _, _, cand in good:
        L = np.array(cand.L, dtype=float)
        L.setflags(write=False)
        out.append(LocalOptimum(float(obj), int(idx), L))
    return tuple(out)


@dataclasses.dataclass(frozen=True, eq=False)
class LocalOptimum:
    """One start's verified answer of a multi-start design (``extra["local_optima"]``).

    Attributes
    ----------
    objective : float
        The objective of the design, recomputed with numpy.
    index : int
        The start's index (that of its :class:`StartRecord`).
    L : (n, p) ndarray
        The gain (read-only).
    """

    objective: float
    index: int
    L: NDArray[np.float64]


class WellConditionedProblem:
    """The well-conditioned observer question for one plant, held by the caller and solved many times.

    ``WellConditionedProblem(plant, ...).solve(...)`` is :func:`well_conditioned_observer`; a sweep
    holds one problem and passes the previous answer as ``warm_start``.  Built once: validation of
    every fixed choice, the placement engine (cheap: one SVD of ``C``; its null-space bases are
    cached per pole value), and -- only when a constraint needs IPOPT -- the NLPs, one per pole
    structure, re-solved with new parameter values (bounds, decay, damping, radius).

    Parameters
    ----------
    plant : Plant, python-control StateSpace or scipy StateSpace / lti / dlti
        ``A`` (n, n), ``C`` (p, n); continuous, or discrete when ``dt`` is set.
    objective : {"kappa2", "kappa_fro", "eta"}
    poles, region
        The default question of :meth:`solve` (fixed poles, or poles free in a region; give one).
    gain_mask : (n, p) array_like of bool, optional
        Free entries of ``L`` (False = structural zero).
    max_gain, kappa2_max, eta_max : float, optional
        Bounds ``||L||_2 <= max_gain``, ``kappa2 <= kappa2_max``, ``eta <= eta_max`` (a solve may
        change their values).
    starts : int, optional
        Default: :data:`DEFAULT_STARTS` (8), except fixed poles on the placement engine (no bounds, no
        structural zeros): :func:`~optdesign.engines.eigenstructure_fixed.default_starts` (6 up to
        n = 12, 2 up to 24, then 1 -- what the engine needs, measured), and a region on the route
        ``"auto"``, ``"engine"``, ``"fast"`` (no bounds or structural zeros):
        :func:`~optdesign.design.well_conditioned.starts.default_region_starts`
        (8 up to n = 12, 4 up to 24, then 2; eta: 16).
    seed : int, default 0
    nlp_solver : {"ipopt"}
    scaling : bool, default True
        Kappa-preserving scaling of the NLPs.
    options : dict, optional
        IPOPT options (string keys) of the NLP route, checked by IPOPT up front.
    allow_unstable : bool, default False
        Fixed poles: accept unstable poles.
    pole_scale : float, optional
        The pole scale of the NLPs' scaling (> 0).  None (default): from each solve's poles or
        region (the largest target pole modulus, or the modulus of the region's interior point).
        A sweep over regions fixes it, so that its points re-solve the same NLPs (the scaling is
        part of an NLP's key); with it set, the decay / damping / radius of a region are NLP parameters
        (one NLP for every region of that shape), without it each region's constraints are built as
        they are.
    route : {"auto", "engine", "fast", "multistart", "nlp"}, default "auto"
        Region mode (``_region_plan``; what ran is ``result.route``).  ``"auto"`` (= ``"engine"``): for
        kappa2 / kappa_fro without bounds or structural zeros the placement engine from every start (default
        8 up to n = 12: the naive poles with YT, the Kalman gain, region samples; fewer above), all starts in
        lockstep, IPOPT only as the fallback when no engine design verifies (not for one output when no
        pole set tried lands in the region: :mod:`.one_output`); IPOPT from every start for
        bounds and gain masks; for eta as ``"fast"`` from 16 starts, IPOPT from one (``ETA_NLP_STARTS``,
        ``ETA_NLP_MAX_ITER`` iterations per stage; none above n = 10 or when the engine attains eta's lower
        bound 0; ``benchmarks/results/region_eta.md``: without it, DIS2 0.0606 vs 0.0338).  Against the
        previous default (``"multistart"``; ``benchmarks/results/region.md``, 50 plants n <= 10): more than
        1e-3 better on 15, worse on 1 (random n = 6 +0.9 %); median 0.41 s (Intel) vs 13.2 s.
        ``"multistart"``: IPOPT from every start, then one placement-engine start from IPOPT's best design
        (the default before issue 28).  ``"fast"``: the engine from every start, IPOPT from the first
        ``AUTO_NLP_STARTS`` (2) with the light polish (``region_polish="last"``), then the engine from IPOPT's
        best when it beats the engine's.  ``"nlp"``: IPOPT only.  Fixed poles: the engine (IPOPT for bounds).
    kalman_start : bool, default True
        Region mode: start 1 is the Kalman gain for ``Q = I, R = I``; False: every start after the
        first samples poles in the region (complex-pair patterns first).
    region_polish : {"full", "last"}, default "full"
        Region mode, NLP route: how a start polishes the free-pole answer.  ``"full"``: the fixed-pole
        NLP at the start's own poles too, and the fixed-pole NLPs at the answer's poles (from its gain
        and from scipy's YT gain there) through their whole continuation; ``"last"``: only at the
        answer's poles, the last continuation stage only (the sweep designer's: on the DIS2 block of
        ``benchmarks/results/sweep.md`` the same kappa2 at every point, 4.2 instead of 13.3 IPOPT
        solves per point).  A warm start always runs the short path
        (:func:`~.nlp_route.nlp_region_runner`).

    Attributes
    ----------
    nlp_builds : int
        The NLPs built so far (one per pole structure, scaling and set of active bounds).

    Raises
    ------
    ValidationError, DimensionError, NotConjugateClosedError, NotObservableError
        As :func:`well_conditioned_observer`.

    Examples
    --------
    >>> from optdesign import Plant
    >>> prob = WellConditionedProblem(Plant([[0, 1], [2, -1]], [[1, 0]]), starts=1)
    >>> [round(prob.solve(poles=[-2 * s, -3 * s]).kappa2, 4) for s in (1, 2)]
    [6.1623, 16.0623]
    """

    def __init__(self, plant: Plant | Any, *, objective: Objective = "kappa2", poles: ArrayLike | None = None,
                 region: Region | None = None, gain_mask: ArrayLike | None = None,
                 max_gain: float | None = None, kappa2_max: float | None = None,
                 eta_max: float | None = None, starts: int | None = None, seed: int = 0,
                 nlp_solver: str = "ipopt",
                 scaling: bool = True, options: dict[str, Any] | None = None,
                 allow_unstable: bool = False, pole_scale: float | None = None,
                 route: Literal["auto", "engine", "fast", "multistart", "nlp"] = "auto",
                 kalman_start: bool = True,
                 region_polish: Literal["full", "last"] = "full") -> None:
        plant = as_plant(plant)
        check_objective(objective)
        if not isinstance(nlp_solver, str) or nlp_solver != "ipopt":
            raise ValidationError(f"nlp_solver must be 'ipopt' (CasADi/IPOPT is the NLP backend); found "
                                  f"{nlp_solver!r}")
        self.plant, self.objective = plant, objective
        self.starts = None if starts is None else as_int("starts", starts, 1)
        self.seed = as_int("seed", seed, 0)
        self.scaling = as_bool("scaling", scaling)
        self.mask = as_gain_mask("gain_mask", gain_mask, plant.n, plant.p)
        self.bounds = self._bounds(max_gain=max_gain, kappa2_max=kappa2_max, eta_max=eta_max)
        self.options = ipopt_options(options)
        if region is not None and poles is not None:
            raise ValidationError("give either poles (fixed) or region (free poles), not both")
        if not isinstance(allow_unstable, (bool, np.bool_)):
            raise ValidationError(f"allow_unstable must be True or False; found {allow_unstable!r}")
        self.allow_unstable = bool(allow_unstable)
        self.poles = None if poles is None else self._target(poles)
        self.region = None if region is None else self._check_region_mode(region, self.bounds)
        self.engine = EigenstructureEngine(plant.A, plant.C)
        self.pole_scale = None if pole_scale is None else as_positive_float("pole_scale", pole_scale)
        if not isinstance(route, str) or route not in ROUTES:
            raise ValidationError(f"route must be one of {ROUTES}; found {route!r}")
        self.route = route
        self.kalman_start = as_bool("kalman_start", kalman_start)
        self.region_polish = as_str("region_polish", region_polish, REGION_POLISHES)
        self._nlps: dict[tuple, Any] = {}

    @property
    def nlp_builds(self) -> int:
        """The NLPs built so far by this problem (each is re-solved, never rebuilt)."""
        return len(self._nlps)

    # ------------------------------------------------------------------ validation
    @staticmethod
    def _bounds(**values: Any) -> dict[str, float | None]:
        mg, em = values["max_gain"], values["eta_max"]
        return {"max_gain": None if mg is None else as_positive_float("max_gain", mg),
                "kappa2_max": kappa2_bound(values["kappa2_max"]),
                "eta_max": None if em is None else as_positive_float("eta_max", em)}

    def _target(self, poles: ArrayLike) -> NDArray[np.complex128]:
        self.plant.require_observable(what="well-conditioned observer design with fixed poles")
        target = as_poles("poles", poles, self.plant.n)
        if not self.allow_unstable:
            check_target_stable(target, self.plant.is_discrete)
        return target

    def _check_region_mode(self, region: Any, bounds: dict[str, float | None]) -> Region:
        check_region(region)
        if self.allow_unstable:
            raise ValidationError("allow_unstable applies to fixed poles only; a region must lie in the "
                                  "stability region")
        check_region_stable(region, self.plant.is_discrete)
        if not region.bounded and bounds["max_gain"] is None:
            raise ValidationError(
                f"the pole region {region!r} is unbounded and no max_gain was given: kappa2 and eta can "
                "keep improving as poles (and ||L||) grow without bound; give max_gain or intersect the "
                "region with a Disk, e.g. region & Disk(0, R)"
            )
        return region

    def _solve_bounds(self, overrides: dict[str, Any]) -> dict[str, float | None]:
        given = {k: v for k, v in overrides.items() if v is not None}
        if not given:
            return dict(self.bounds)
        return {**self.bounds, **self._bounds(**{k: given.get(k) for k in _BOUNDS})}

    def _scaling(self, pole_scale: float) -> NLPScaling:
        n, p = self.plant.n, self.plant.p
        if self.pole_scale is not None:
            pole_scale = self.pole_scale
        return NLPScaling.for_plant(self.plant, pole_scale, balance=False) if self.scaling else \
            NLPScaling.identity(n, p)

    def _nlp(self, key: tuple, build: Callable[[], Any], values: dict[str, float]) -> Any:
        """The NLP of ``key`` (built once, held by the problem), its parameters set to ``values``."""
        nlp = self._nlps.get(key)
        if nlp is None:
            nlp = self._nlps[key] = build()
        if values:
            nlp.set_parameters(**values)
        return nlp

    def _fixed_nlp_getter(self, bounds: dict[str, float | None],
                          sc: NLPScaling) -> Callable[[PoleStructure], Any]:
        active = {k: v for k, v in bounds.items() if v is not None}

        def get(st: PoleStructure):
            key = ("fixed", st, sc.omega, tuple(sorted(active)))
            return self._nlp(key, lambda: build_observer_nlp(self.plant, st, fixed_poles=True,
                                                             objective=self.objective, scaling=sc,
                                                             mask=self.mask, **active), active)

        return get

    def _region_nlp_getter(self, region: Region, bounds: dict[str, float | None],
                           sc: NLPScaling) -> Callable[[PoleStructure], Any]:
        active = {k: v for k, v in bounds.items() if v is not None}
        # a sweep (pole_scale fixed) re-solves one NLP whose decay / damping / radius are parameters; a
        # single design builds the region's constraints as they are (the formulation of the verb before
        # the problem objects: measured on COMPleib AC17, the parametric form ends in another basin,
        # kappa2 1.675 instead of 1.646)
        fixed, params = _region_parts(region) if self.pole_scale is not None else (region, {})
        values = {**active, **params}

        def get(st: PoleStructure):
            key = ("region", st, sc.omega, tuple(sorted(active)), repr(fixed), tuple(sorted(params)))
            return self._nlp(key, lambda: build_observer_nlp(self.plant, st, fixed_poles=False,
                                                             objective=self.objective, region=fixed,
                                                             scaling=sc, mask=self.mask, **values), values)

        return get

    # ------------------------------------------------------------------ solving
    @one_warning_per_call
    def solve(self, poles: ArrayLike | None = None, region: Region | None = None, *, warm_start: Any = None,
              warm_starts: Sequence[Any] | None = None, time_limit: float | Deadline | None = None,
              progress: bool | None = None,
              starts: int | None = None, seed: int | Sequence[int] | None = None,
              max_gain: float | None = None, kappa2_max: float | None = None,
              eta_max: float | None = None) -> ObserverDesign:
        """The best-conditioned observer for fixed ``poles`` or poles free in ``region``.

        Parameters
        ----------
        poles : (n,) array_like of complex, optional
        region : Region, optional
            Give one (or neither: the problem's own, else the stability region).
        warm_start : ObserverDesign or (n, p) array_like, optional
            A previous design (e.g. the previous point of a sweep) or a gain: one more start, run
            from the engine's last continuation stages (region mode: its poles moved inside the new
            region).
        warm_starts : sequence of ObserverDesign or (n, p) array_like, optional
            Region mode: more warm starts, run after ``warm_start`` in the order given, each as
            ``warm_start`` (e.g. the distinct local optima of the previous point of a sweep,
            ``extra["local_optima"]`` of its design); a warm start without a finite gain is skipped.
        time_limit : float or Deadline, optional
            Seconds of wall time (or a budget shared with the caller); see
            :func:`well_conditioned_observer`.
        progress : bool or None
            Report the starts on stderr (None: only on a terminal).
        starts, seed : int, optional
            Override the problem's for this solve (``starts=0`` with a ``warm_start``: the warm start
            alone).  ``seed`` may also be a sequence of integers >= 0 (the entropy of a numpy
            ``SeedSequence``, e.g. a seed and the values of a sweep point).
        max_gain, kappa2_max, eta_max : float, optional
            Override the problem's bounds for this solve (the NLPs re-solve with the new values).

        Returns
        -------
        ObserverDesign
            ``extra["local_optima"]``: the verified answers of the starts that ran (their gains, best
            first, see :func:`result_from`).

        Raises
        ------
        ValidationError
            Bad arguments; ``warm_starts`` with fixed poles or not a sequence.
        """
        deadline = time_limit if isinstance(time_limit, Deadline) else Deadline(as_time_limit(time_limit))
        progress = as_progress(progress)
        more_warm = _warm_list(warm_starts)
        lowest = 0 if warm_start is not None or more_warm else 1
        chosen = self.starts if starts is None else as_int("starts", starts, lowest)
        seed = self.seed if seed is None else _as_seed(seed)
        bounds = self._solve_bounds({"max_gain": max_gain, "kappa2_max": kappa2_max, "eta_max": eta_max})
        warm = _warm_gain(warm_start, self.plant)
        warms = [w for w in [warm, *(_warm_gain(w, self.plant) for w in more_warm)] if w is not None]
        if region is not None and poles is not None:
            raise ValidationError("give either poles (fixed) or region (free poles), not both")
        if more_warm and (poles is not None or (region is None and self.poles is not None)):
            raise ValidationError(f"warm_starts applies to region mode only (poles free in a region); "
                                  f"found {len(more_warm)} warm starts with fixed poles")
        if poles is not None:
            target = self._target(poles)
        elif region is None and self.poles is not None:
            target = self.poles
        else:
            target = None
        if target is not None:
            n_starts = chosen if chosen is not None else (
                DEFAULT_STARTS if self._needs_nlp(bounds) else default_starts(self.plant.n))
            return self._fixed(target, bounds, n_starts, seed, deadline, warm, progress)
        if region is None:
            region = self.region if self.region is not None else stability_region(self.plant.is_discrete)
        region = self._check_region_mode(region, bounds)
        if chosen is not None:
            n_starts = chosen
        elif self.route != "multistart" and not self._needs_nlp(bounds):
            n_starts = default_region_starts(self.plant.n, self.objective)
        else:
            n_starts = DEFAULT_STARTS
        return self._free(region, bounds, n_starts, seed, deadline, warms, progress)

    def _needs_nlp(self, bounds: dict[str, float | None]) -> bool:
        """Gain or trade-off bounds, or structural zeros: what the placement engine does not take."""
        return self.mask is not None or any(v is not None for v in bounds.values())

    def _repeated_pole_proof(self, target: NDArray) -> ObserverDesign | None:
        """The infeasible result of a fixed pole set that no diagonalizable ``A - LC`` (or finite eta)
        has, with its proof; None if there is none."""
        plant, objective = self.plant, self.objective
        rank = self.engine.rank
        vals, counts = np.unique(np.round(target, 10), return_counts=True)
        k = int(np.argmax(counts))
        if counts[k] > rank == 1 and objective != "eta":  # one output: the poles fix L (issue 27)
            from ..feedback_controller import ackermann_observer
            return ackermann_observer(plant, target, objective, stable=not self.allow_unstable,
                                      mask=self.mask, max_gain=self.bounds.get("max_gain"))
        if counts[k] > rank:
            reason = (
                f"pole {vals[k]} is requested {counts[k]} times but rank(C) = {rank}: the eigenspace of "
                f"A - LC for it has dimension <= rank(C), so A - LC would be defective (kappa2 = inf)"
            )
            cert = Certificate("multiplicity_exceeds_rank", "multiplicity exceeds rank(C)",
                               pole=complex(vals[k]), multiplicity=int(counts[k]), rank_C=rank)
            return no_design(plant, objective, Status.INFEASIBLE, reason, cert, target=target,
                             route=proof_route("multiplicity exceeds rank(C)"))
        if objective == "eta" and counts[k] > 1:
            cert = Certificate("repeated_pole_eta", "repeated pole with objective eta", pole=complex(vals[k]))
            return no_design(plant, objective, Status.INFEASIBLE,
                             "eta is infinite for repeated poles (zero eigenvalue gap)", cert, target=target,
                             route=proof_route("repeated pole with objective eta"))
        return None

    def _fixed(self, target: NDArray, bounds: dict[str, float | None], n_starts: int, seed: int | list[int],
               deadline: Deadline, warm: NDArray | None, progress: bool | None) -> ObserverDesign:
        """Fixed poles: the engine (all starts in lockstep), IPOPT for the bounds or as a fallback."""
        proof = self._repeated_pole_proof(target)
        if proof is not None:
            return proof
        plant, objective = self.plant, self.objective
        evaluate = cached_evaluate(partial(evaluate_candidate, plant, target=target, region=None,
                                           stable=not self.allow_unstable, mask=self.mask, **bounds))
        records: list[StartRecord] = []
        evaluated: list[Evaluated] = []
        # structural zeros go to IPOPT too: the engine's augmented Lagrangian for masks can stop worse
        # (pp_byers5 with 3 zeros: kappa2 406.7 vs IPOPT's 355.4, benchmarks/results/placement.md sec. 8)
        use_nlp = self._needs_nlp(bounds)
        planned = 0
        route = "nlp" if use_nlp else "engine"
        phases: list[Phase] = []
        with Progress(n_starts + (warm is not None), "well-conditioned observer", enabled=progress,
                      unit="start") as bar:
            if not use_nlp:
                records, evaluated = engine_fixed(self.engine, target, objective, starts=max(n_starts, 1),
                                                  seed=_int_seed(seed), deadline=deadline, mask=self.mask,
                                                  evaluate=evaluate, warm_start=warm)
                bar.update(len(records), note=_note(objective, evaluated))
                planned = max(n_starts + (warm is not None), len(records))
                phases.append(Phase(ENGINE_FIXED, "engine", 0, len(records)))
            if use_nlp or needs_fallback(evaluated, deadline):
                route = "nlp" if use_nlp else "engine+nlp"
                sc = self._scaling(float(np.max(np.abs(target))))
                st = PoleStructure.of(target)
                rng = np.random.default_rng(seed)
                specs: list[tuple] = list(fixed_starts(plant, target, max(n_starts, 1), rng, st))
                if warm is not None:
                    specs.insert(0, ("warm start", warm, st, target, True))
                planned += len(specs)
                runner = nlp_fixed_runner(self._fixed_nlp_getter(bounds, sc), target, objective, self.options,
                                          lambda c: bool(evaluate(c)[1].passed), deadline)
                more_r, more_e = solve_starts(specs, runner, objective, evaluate, deadline,
                                              objective_lower_bound(objective, plant.n), bar, len(records))
                phases.append(Phase(IPOPT, "backend" if use_nlp else "fallback", len(records),
                                    len(records) + max(len(more_r), 1),
                                    nlp_detail(use_nlp, self.mask, bounds)))
                records, evaluated = records + more_r, evaluated + more_e
        return result_from(plant, records, evaluated, objective=objective, target=target, region=None,
                           deadline=deadline, planned=planned, route=route, phases=phases)

    def _region_starts(self, region: Region, n_starts: int, rng: np.random.Generator,
                       sweeps: int | None = None, scipy_yt: NDArray | None = None) -> Iterator:
        """The starts of region mode, lazily (:func:`~.starts.iter_region_starts`; without the Kalman start 1
        when ``kalman_start`` is False; ``sweeps``, ``scipy_yt``: as there)."""
        return iter_region_starts(self.plant, region, n_starts, rng, self.mask, kalman=self.kalman_start,
                                  sweeps=sweeps, scipy_yt=scipy_yt)

    def _unobservable_outside(self, region: Region) -> ObserverDesign | None:
        unobs = self.plant.unobservable_modes()
        if not unobs.size:
            return None
        dist = region.distance(unobs)
        if not np.any(dist > 1e-9 * max(1.0, float(np.max(np.abs(unobs))))):
            return None
        k = int(np.argmax(dist))
        reason = (f"the unobservable mode {unobs[k]:.6g} of (C, A) is an eigenvalue of A - LC for every L "
                  f"and lies outside the region (distance {dist[k]:.3g})")
        cert = Certificate("unobservable_mode_outside_region", "unobservable mode outside the region",
                           modes=unobs, distance=dist)
        return no_design(self.plant, self.objective, Status.INFEASIBLE, reason, cert, region=region,
                         route=proof_route("unobservable mode outside the region"))

    def _free(self, region: Region, bounds: dict[str, float | None], n_starts: int, seed: int | list[int],
              deadline: Deadline, warms: list[NDArray], progress: bool | None) -> ObserverDesign:
        """Poles free in ``region``: the engine start by start, IPOPT for what it does not handle or as a
        fallback; the warm starts ``warms`` (gains) first."""
        proof = self._unobservable_outside(region)
        if proof is not None:
            return proof
        plant, objective = self.plant, self.objective
        evaluate = cached_evaluate(partial(evaluate_candidate, plant, target=None, region=region,
                                           mask=self.mask, **bounds))
        rng = np.random.default_rng(seed)
        warm_specs = []
        for i, warm in enumerate(warms):
            Pw = np.linalg.eigvals(plant.A - warm @ plant.C)
            warm_specs.append((warm_start_origin(i), warm, PoleStructure.of(Pw, tol=1e-6), Pw, True))
        engine_ok = not self._needs_nlp(bounds) and objective in ("kappa2", "kappa_fro", "eta")
        use_eng, n_eng, use_nlp, n_nlp, polish, eng_polish = self._region_plan(engine_ok, n_starts)
        # the engine optimizes from the placements anyway: one YT sweep at sampled poles (issue 28,
        # measured: scipy's default 30-100 sweeps were 20-30 % of a small plant's region design)
        specs: Iterable[Any] = self._region_starts(region, n_starts, rng, _ENGINE_SWEEPS if use_eng else None)
        bound = objective_lower_bound(objective, plant.n)
        records: list[StartRecord] = []
        evaluated: list[Evaluated] = []
        planned = 0
        route = "engine" if use_eng else "nlp"
        phases: list[Phase] = []
        spec_list: list = []
        if use_eng:  # the engine's starts are computed now, the NLP re-uses the first of them
            specs = spec_list = list(itertools.islice(specs, max(n_eng, n_nlp)))
        if use_eng and use_nlp and objective == "eta":  # IPOPT from its own starts (those of route "nlp")
            yt = spec_list[0][1] if spec_list[0][0] == "naive poles + YT" and self.mask is None else None
            specs = list(itertools.islice(self._region_starts(region, n_starts, np.random.default_rng(seed),
                                                              scipy_yt=yt), n_nlp))  # scipy's YT once
        with Progress(n_eng + n_nlp + len(warm_specs), "well-conditioned observer", enabled=progress,
                      unit="start") as bar:
            if use_eng:
                eng_specs: list[tuple[str, NDArray | None, NDArray, bool]] = [
                    (w[0], w[1], w[3], True) for w in warm_specs]
                eng_specs += [(o, L0, P0, False) for o, L0, _, P0 in spec_list[:n_eng]]
                planned = len(eng_specs)
                records, evaluated = engine_region(self.engine, region, objective, eng_specs,
                                                   seed=_int_seed(seed),
                                                   deadline=deadline, evaluate=evaluate, lower_bound=bound,
                                                   progress=bar)
                phases.append(Phase(ENGINE_REGION, "engine", 0, len(records)))
            fallback = use_eng and needs_fallback(evaluated, deadline)
            unplaced = unplaced_one_output(plant, region, objective, spec_list, rng, evaluate, len(records)) \
                if fallback else None
            if unplaced:  # one output, no pole set tried placeable: neither IPOPT's fallback nor its start
                fallback, use_nlp, (more_r, more_e, more_p) = False, False, unplaced
                records, evaluated, phases = records + more_r, evaluated + more_e, phases + more_p
            if fallback:  # no engine design verified: IPOPT from every start the engine ran (eta: its own)
                n_nlp = max(n_nlp, len(spec_list))
            run_nlp = use_nlp and not (use_eng and (deadline.expired or any(
                attains(bound, e[0], e[3], e[4]) for e in evaluated)))
            cap = ETA_NLP_MAX_ITER if use_eng and not fallback and objective == "eta" else None
            if run_nlp or fallback:
                route = "nlp" if not use_eng else "engine+nlp"
                planned += n_nlp + len(warm_specs)
                sc = self._scaling(0.0 if self.pole_scale is not None else _interior_scale(region))
                todo = specs[:n_nlp] if isinstance(specs, list) else specs
                nlp_specs = itertools.chain(warm_specs, (s + (False,) for s in todo))
                runner = nlp_region_runner(
                    plant, region, objective, self.options, self._fixed_nlp_getter(bounds, sc),
                    self._region_nlp_getter(region, bounds, sc), evaluate, deadline, mask=self.mask,
                    lower_bound=bound, polish=polish, region_max_iter=cap)
                more_r, more_e = solve_starts(nlp_specs, runner, objective, evaluate, deadline, bound, bar,
                                              len(records))
                kind = "fallback" if fallback else "backend"
                detail = nlp_detail(not fallback, self.mask, bounds)
                if use_eng and not fallback:
                    detail = f"{len(more_r)} start{'s' if len(more_r) != 1 else ''}, beside the engine's"
                elif not use_eng and engine_ok:
                    detail = f"asked (route={self.route!r})"
                phases.append(Phase(IPOPT, kind, len(records), len(records) + max(len(more_r), 1), detail))
                records, evaluated = records + more_r, evaluated + more_e
            if eng_polish and not deadline.expired:
                more_r, more_e = self._engine_polish(region, objective, evaluated, seed, deadline, bound,
                                                     evaluate)
                if more_r:
                    planned += 1
                    route += "+engine polish" if use_eng else "+engine"
                    phases.append(Phase(ENGINE_REGION, "polish", len(records), len(records) + len(more_r),
                                        "engine from the best design"))
                records, evaluated = records + more_r, evaluated + more_e
        return result_from(plant, records, evaluated, objective=objective, target=None, region=region,
                           deadline=deadline, planned=planned, route=route, phases=phases)

    def _region_plan(self, engine_ok: bool, n_starts: int) -> tuple[bool, int, bool, int, str, bool]:
        """``(engine?, engine starts, IPOPT?, IPOPT starts, IPOPT polish, engine polish)`` of a region
        solve (the warm starts run in every phase that runs).

        ``"auto"`` / ``"engine"`` (no bounds or structural zeros; eta above n = ``ETA_NLP_MAX_N``): the
        engine from every start (IPOPT as the fallback).  ``"fast"``, and eta on ``"auto"``: the engine
        from every start, IPOPT (light polish, ``"last"``) from the first ``AUTO_NLP_STARTS`` (eta on
        "auto": ``ETA_NLP_STARTS``), then the engine from IPOPT's best when it beats the engine's.
        ``"multistart"``: IPOPT from every start, then the engine from the best.  ``"nlp"``, or a question
        the engine does not take: IPOPT only."""
        mode = self.route
        if not engine_ok or mode == "nlp":
            return False, 0, True, n_starts, self.region_polish, False
        if mode == "engine" or mode == "auto" and (self.objective != "eta" or self.plant.n > ETA_NLP_MAX_N):
            return True, n_starts, False, 0, self.region_polish, False
        if mode == "multistart":
            return False, 0, True, n_starts, self.region_polish, True
        nlp = ETA_NLP_STARTS if mode == "auto" else AUTO_NLP_STARTS
        return True, n_starts, True, min(nlp, n_starts), "last", True

    def _engine_polish(self, region: Region, objective: str, evaluated: list[Evaluated], seed: Any,
                       deadline: Deadline, bound: float | None,
                       evaluate: Callable[[Any], Any]) -> tuple[list[StartRecord], list[Evaluated]]:
        """One placement-engine start from the best verified design so far (its gain and poles); nothing
        when there is none or it attains the objective's lower bound."""
        good = [e for e in evaluated if e[3].passed and np.all(np.isfinite(e[4].L))]
        if not good:
            return [], []
        best = min(good, key=lambda e: e[0])
        if attains(bound, best[0], best[3], best[4]) or best[4].backend == ENGINE:
            return [], []
        L0 = np.asarray(best[4].L, dtype=float)
        P0 = np.linalg.eigvals(self.plant.A - L0 @ self.plant.C)
        recs, evs = engine_region(self.engine, region, objective,
                                  [("engine from the best design", L0, P0, True)], seed=_int_seed(seed),
                                  deadline=deadline, evaluate=evaluate, lower_bound=bound)
        k = len(evaluated)
        return ([dataclasses.replace(r, index=k + i) for i, r in enumerate(recs)],
                [(e[0], k + i, e[2], e[3], e[4]) for i, e in enumerate(evs)])

    def __repr__(self) -> str:
        what = ("poles" if self.poles is not None else f"region {self.region!r}" if self.region is not None
                else "the stability region")
        starts = "default" if self.starts is None else self.starts
        return (f"WellConditionedProblem(n={self.plant.n}, p={self.plant.p}, objective={self.objective!r}, "
                f"{what}, starts={starts}, NLPs built: {len(self._nlps)})")


def _interior_scale(region: Region) -> float:
    """The modulus of the region's interior point (the NLP scaling's pole scale; 0 if it fails)."""
    try:
        return abs(float(region.interior_point()))
    except Exception:  # noqa: BLE001 - any failure: fall back on the plant's scale
        return 0.0


def _as_seed(seed: Any) -> int | list[int]:
    """A seed: an integer >= 0, or a non-empty sequence of them (SeedSequence entropy)."""
    if isinstance(seed, (list, tuple)):
        if not seed:
            raise ValidationError("seed must be an integer >= 0 or a non-empty sequence of them; found ()")
        return [as_int(f"seed[{i}]", v, 0) for i, v in enumerate(seed)]
    return as_int("seed", seed, 0)


def _int_seed(seed: int | list[int]) -> int:
    """One integer seed (for the placement engine) from a seed or a SeedSequence entropy."""
    return seed if isinstance(seed, int) else int(np.random.SeedSequence(seed).generate_state(1)[0])


def _note(objective: str, evaluated: list[Evaluated]) -> str:
    vals = [e[0] for e in evaluated if e[3].passed]
    return f"best {objective} {min(vals):.6g}" if vals else "no verified design yet"


def _warm_list(warm_starts: Any) -> list[Any]:
    """The extra warm starts of a solve: a list (None: none)."""
    if warm_starts is None:
        return []
    if isinstance(warm_starts, (str, bytes, dict)) or not isinstance(warm_starts, Sequence):
        raise ValidationError(f"warm_starts must be a sequence of designs or gains (or None); found "
                              f"{type(warm_starts).__name__}")
    return list(warm_starts)


def _warm_gain(warm_start: Any, plant: Plant) -> NDArray[np.float64] | None:
    """The gain of a warm start (a previous design or an (n, p) array); None when it has no finite gain."""
    if warm_start is None:
        return None
    L = getattr(warm_start, "L", warm_start)
    try:
        L = np.array(L, dtype=float)
    except (TypeError, ValueError):
        raise ValidationError(f"warm_start must be a design (with a gain L) or an ({plant.n}, {plant.p}) "
                              f"gain; found {type(warm_start).__name__}") from None
    if L.shape != (plant.n, plant.p):
        raise DimensionError(f"warm_start gain must have shape ({plant.n}, {plant.p}); found {L.shape}")
    return L if np.all(np.isfinite(L)) else None
