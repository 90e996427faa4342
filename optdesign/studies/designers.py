"""Study-oriented design functions: build once per worker, re-solve for every point.

A *designer* is a small, picklable, frozen object that :func:`optdesign.studies.sweep` calls
with one point of a grid (``designer(alpha=1.5, zeta=0.6)``) and that returns a design result
(with ``status``, ``success`` and a ``record()`` of scalar metrics).

:class:`RegionSweepDesigner` is the workhorse of region studies ("how does the best kappa2 change
with the decay rate and the damping sector?").  It holds a
:class:`~optdesign.design.well_conditioned.WellConditionedProblem`
(:meth:`~RegionSweepDesigner.design_problem`: one per configuration and worker thread, kept across
the points and chunks the worker runs), and every point is one
:meth:`~optdesign.design.well_conditioned.WellConditionedProblem.solve` on it with the point's region
(``region & HalfPlane(alpha) & Sector.from_damping(zeta) & Disk(0, radius)``) and bounds.  The
problem builds its NLPs once per pole structure, with the decay rate, the damping ratio, the radius
and the bounds as ``opti.parameter`` s, and re-solves them with every point's values (the designer
fixes the NLP scaling, ``pole_scale``, so that its points share the NLPs):

* a *warm start* from the previous point's verified design (same chunk of the sweep, see
  :mod:`optdesign.studies.sweep`; the last stage of the free-pole NLP and of one fixed-pole polish
  at its answer's poles) -- its gain itself is a candidate too, so when the region gets looser (or a
  bound weaker) along a chunk the answer never gets worse; a warm start whose own gain attains
  kappa2 = 1 (the lower bound) is the point's answer, with no IPOPT solve and no further start.
  Order the last axis of a grid from the tightest to the loosest region (e.g. ``zeta`` descending)
  to get this monotonicity; the NLP is non-convex and independent local solves can otherwise land
  in different local optima at neighbouring points;
* ``starts`` *placement starts*: the first at the open-loop poles moved into the point's region
  (:func:`~optdesign.design.well_conditioned.naive_poles`), the others at poles sampled in the
  region (complex-pair patterns first; ``kalman_start=False`` of the problem), each with a robust
  placement (scipy YT) for the initial gain, the free-pole NLP's full continuation and the last stage
  of the fixed-pole polishes at its answer's poles (``region_polish="last"`` of the problem) -- so a
  point never depends on a warm start alone.  For kappa2 and kappa_fro the problem runs IPOPT for every
  point (``route="nlp"``): on DIS2 the placement engine's region route found worse local optima from
  these starts (kappa2 1.12 against 1.05 at ``alpha = 3, zeta = 0.55``, even with 8 starts); for eta
  the placement engine (``route="auto"``; IPOPT's eta was 6-350x higher at most points of 4 of 13
  plants: ``RegionSweepDesigner.route``).

Every candidate is verified independently of the solver, by the problem's checks (stability and the
signed distance of the poles of ``A - L C`` to the point's region, with numpy; the solver's
eigenbasis against :func:`optdesign.metrics.kappa2`; the bounds), and the best verified candidate
is returned as an :class:`~optdesign.design.well_conditioned.ObserverDesign`.  A point whose region
reaches outside the stability region is refused, as the verb refuses it.  ``reuse=False`` builds a
new problem (and NLPs) for every point (same algorithm): the benchmark ``benchmarks/bench_sweep.py``
measures the difference.

:class:`KalmanNoiseDesigner` (axes ``q``, ``r``: noise-ratio studies) and
:class:`PoleTargetDesigner` (axes ``scale``, ``shift`` of a target pole set: where does a
prescribed-pole Kalman target become infeasible?) wrap the other verbs for studies;
:func:`place_baseline` is the scipy placement baseline as a verified result.

References
----------
Jung & Huh (seed 001); Chang & Lee 1984 (seed 000); Kautsky, Nichols & Van Dooren (1985).
"""

from __future__ import annotations

import dataclasses
import math
import threading
import zlib
from collections import OrderedDict
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any, ClassVar, get_args

import numpy as np
from numpy.typing import NDArray

from .._deadline import Deadline, as_time_limit
from .._validate import as_bool, as_int, as_options, as_poles, as_positive_float
from ..design.well_conditioned import ObserverDesign, WellConditionedProblem, check_region_stable
from ..design.well_conditioned.evaluation import bound_level, objective_lower_bound
from ..design.well_conditioned.normal_probe import normal_closed_loop, normal_freedom
from ..design.well_conditioned.problem import Objective
from ..errors import ValidationError
from ..model.plant import Plant
from ..model.regions import Disk, HalfPlane, Region, Sector, stability_region
from ..results import Route
from .points import BaselinePlacement, DesignPoint, gain_values, place_baseline
from .pool import merge_pool

__all__ = [
    "RegionSweepDesigner",
    "KalmanNoiseDesigner",
    "PoleTargetDesigner",
    "DesignPoint",
    "BaselinePlacement",
    "place_baseline",
    "DESIGNERS",
    "SWEEP_IPOPT_OPTIONS",
    "PLACEMENTS",
    "merge_pool",
    "gain_values",
    "clear_cache",
]

#: IPOPT options of the region designer (merged under ``options``); as the verb's defaults but
#: with fewer iterations, so that a hopeless point does not hold a 1,000-point sweep
SWEEP_IPOPT_OPTIONS: dict[str, Any] = {
    "ipopt.tol": 1e-8,
    "ipopt.constr_viol_tol": 1e-10,
    "ipopt.acceptable_tol": 1e-6,
    "ipopt.max_iter": 300,
}

_CACHE_SIZE = 8

#: the ``placement`` modes of :class:`RegionSweepDesigner`
PLACEMENTS = ("always", "fallback", "pool")

#: the sweepable bounds (keyword arguments of :meth:`WellConditionedProblem.solve`)
_BOUNDS = ("max_gain", "kappa2_max", "eta_max")


# --------------------------------------------------------------------------- helpers


def _plant_of(problem: str | None, plant: Plant | None, who: str) -> Plant:
    if (problem is None) == (plant is None):
        raise ValidationError(f"{who} needs exactly one of problem (a library name) or plant")
    if plant is not None:
        if not isinstance(plant, Plant):
            raise ValidationError(f"plant must be an optdesign.Plant; found {type(plant).__name__}")
        return plant
    if not isinstance(problem, str):
        raise ValidationError(f"problem must be a problem name (str); found {type(problem).__name__}")
    return _library_plant(problem)


@lru_cache(maxsize=64)
def _library_plant(name: str) -> Plant:
    from .. import problems

    prob = problems.load(name)
    if prob.plant is None:
        raise ValidationError(f"problem {name!r} has no valid plant ({prob.notes or 'see its notes'})")
    return prob.plant


@lru_cache(maxsize=64)
def _library_poles(name: str) -> tuple[complex, ...]:
    """The target poles of a library problem (loaded once per process, not once per point)."""
    from .. import problems

    prob = problems.load(name)
    if "poles" not in prob.targets:
        raise ValidationError(f"problem {name!r} has no target poles; give poles")
    return tuple(complex(z) for z in np.asarray(prob.targets["poles"], dtype=complex).ravel())


def _point_seed(seed: int, point: Mapping[str, Any]) -> list[int]:
    """Entropy for a point's random choices: the seed and the point's values (order-free)."""
    out = [int(seed)]
    for k in sorted(point):
        v = point[k]
        out.append(zlib.crc32(k.encode()))
        if isinstance(v, (bool, np.bool_)):
            out.append(int(v))
        elif isinstance(v, (int, float, np.integer, np.floating)):
            out.append(int.from_bytes(np.float64(v).tobytes(), "little"))
        else:
            out.append(zlib.crc32(repr(v).encode()))
    return out


def _plant_key(plant: Plant) -> tuple:
    return (plant.A.shape, plant.A.tobytes(), plant.C.shape, plant.C.tobytes(), plant.dt)


def _finite_number(name: str, v: Any, where: str = "") -> float:
    if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, float, np.integer, np.floating)) \
            or not math.isfinite(float(v)):
        raise ValidationError(f"{name} must be a finite number{where}; found {v!r}")
    return float(v)


# --------------------------------------------------------------------------- per-worker problems

_local = threading.local()


def _cache() -> OrderedDict:
    c = getattr(_local, "cache", None)
    if c is None:
        c = _local.cache = OrderedDict()
    return c


def clear_cache() -> None:
    """Forget the problem objects (and their NLPs) held by the region designers in this thread."""
    _cache().clear()


# --------------------------------------------------------------------------- region designer


@dataclass(frozen=True)
class RegionSweepDesigner:
    """Well-conditioned observer over a parametric pole region, for sweeps (build once, re-solve).

    Call it with a point: ``designer(alpha=1.5, zeta=0.6)``.  The pole region of the point is
    ``region & HalfPlane(alpha) & Sector.from_damping(zeta) & Disk(0, radius)`` (the pieces that
    are given, by the point or by the defaults below); with none of them, the stability region.

    Parameters
    ----------
    problem : str, optional
        A library problem whose plant is used (loaded in the worker).  Give ``problem`` or
        ``plant``.
    plant : Plant, optional
    objective : {"kappa2", "kappa_fro", "eta"}
        What to minimize (as :func:`optdesign.design.well_conditioned.well_conditioned_observer`).
    region : Region, optional
        A fixed part of the region (its constraints are part of the NLP).
    alpha, zeta, radius : float, optional
        Defaults of the sweepable region pieces: decay ``Re s <= -alpha``, damping ratio
        ``>= zeta`` (continuous time only) and ``|s| <= radius``.  Unbounded regions need a radius
        or ``max_gain`` when the metric keeps improving as the poles move away.
    max_gain, kappa2_max, eta_max : float, optional
        Defaults of the sweepable bounds ``||L||_2 <= max_gain``, ``kappa2 <= kappa2_max``,
        ``eta <= eta_max``.
    starts : int, default 2
        Placement starts per point (in addition to the warm start).  Start ``k`` samples poles
        with a real-pole fraction of 0, 1, 0.5, 0.25, 0.75 (cyclic): the first has as many
        conjugate pairs as possible, the second is all real.  The pole structure (number of
        pairs) is fixed within a local solve, so ``starts=1`` explores one structure only.
    seed : int, default 0
        Seeds the region samples (combined with the point's values: a point's samples do not
        depend on where or when it runs).
    warm_start : bool, default True
        Start from the previous point's solution (within a chunk of the sweep).
    placement : {"pool", "always", "fallback"}, default "pool"
        ``"pool"``: the session keeps the distinct verified local optima of the previous point (its
        design and every start's answer, :func:`merge_pool`) and warm-starts them all at the next
        point (each: the last continuation stages, best first, stopping at a design that attains the
        objective's lower bound); the placement starts run at a chunk's first point and whenever the
        pool has collapsed to one optimum (the same gain, or the same kappa2: mirror images).  With
        objective kappa2, at a chunk's first point and wherever the pool's best is above 1, the
        session first probes for a normal closed loop (kappa2 = 1) in the region (an accelerator
        only: :func:`~optdesign.design.well_conditioned.normal_probe.normal_closed_loop`).
        ``"always"``: every point also runs the ``starts`` placement starts (robust: a point does
        not depend on the warm start alone), the previous point's design as the warm start;
        ``"fallback"``: a solve from the warm start alone first, the placement starts only when
        there is no warm start or its solve does not succeed (first point of a chunk) -- fast along
        smooth paths, but it follows one local optimum along the chunk.  Measured on DIS2's
        1,000-point grid (``benchmarks/results/sweep_grid.md``): ``"pool"`` 0.6x the CPU of ``"always"``,
        never worse than it (by 0.1 %), better at 14 points (the probe's normal closed loops).
    reuse : bool, default True
        Solve every point on one problem object per worker thread (:meth:`design_problem`), so that
        its NLPs are built once and re-solved; False builds a new problem for every point (for
        benchmarks).
    pole_scale : float, optional
        Time scale of the NLP scaling (default: ``radius`` if given, else the magnitude of the
        fixed region's deepest real point, else the largest of the spectral radius of ``A``,
        ``|alpha|`` and 1).  It must not depend on the point, so it is fixed per designer.
    options : dict, optional
        IPOPT options merged over :data:`SWEEP_IPOPT_OPTIONS`.
    initial_gain : (n, p) array_like, optional
        A known good gain (e.g. an unconstrained optimum): the warm start of every point that has
        no previous verified design to start from (the first point of a chunk).
    time_limit : float, optional
        Seconds of wall time per point (None: no limit).  IPOPT gets the time left; no start
        after the point's first begins once it is spent; the point then has status
        ``time_limit`` (``success`` False) with the best verified design found so far.
    route : {"auto", "engine", "fast", "multistart", "nlp"}, optional
        The problem's region route (:class:`~optdesign.design.well_conditioned.WellConditionedProblem`).
        Default ``"nlp"`` (IPOPT, above) for kappa2 and kappa_fro; ``"auto"`` for eta: the placement
        engine from every start and warm start, IPOPT's first start beside it up to n = 10.  Measured
        (issue 28, round 12: 13 plants n = 4-12, a chunk of 4 points ``alpha = 0.5 .. 0.8``, ``zeta =
        0.5``, against ``"nlp"``): eta the same on 4 plants; lower on 7 (at every point on 6: COMPleib
        AC6 0.565 against 14.8, DIS1 0.235 against 2.17, random n = 7 48 against 17,328); on random
        n = 6 lower at the first point (10.1 against 14.1), higher at the other three (11.5 against
        10.4, +10-15 %); on random n = 12 lower at two points, higher at two (+0.1-0.4 %): 29 of the 52
        points more than 1e-3 lower, 4 higher.  CPU 1.0-2.6x per plant at n <= 10 (AC6 0.73x), 0.1x
        at n = 12 (5 s against 48 s), 0.71x in all (``benchmarks/bench_sweep_eta.py``,
        ``benchmarks/results/sweep_eta.md``).

    Raises
    ------
    ValidationError
        Bad arguments (on construction); at call time, unknown point keys or bad values.

    Examples
    --------
    >>> from optdesign.studies import RegionSweepDesigner, sweep, grid
    >>> d = RegionSweepDesigner(problem="compleib_dis2", radius=20.0)
    >>> table = sweep(d, grid(alpha=[1.0, 2.0], zeta=[0.5, 0.7]), executor="serial")  # doctest: +SKIP
    """

    problem: str | None = None
    plant: Plant | None = None
    objective: str = "kappa2"
    region: Region | None = None
    alpha: float | None = None
    zeta: float | None = None
    radius: float | None = None
    max_gain: float | None = None
    kappa2_max: float | None = None
    eta_max: float | None = None
    starts: int = 2
    seed: int = 0
    warm_start: bool = True
    placement: str = "pool"
    reuse: bool = True
    pole_scale: float | None = None
    options: Mapping[str, Any] | None = None
    initial_gain: Any = field(default=None, compare=False)
    time_limit: float | None = None
    route: str | None = None

    #: point keys understood (sweepable parameters) -> NLP parameter names
    AXES: ClassVar[dict[str, str]] = {"alpha": "decay", "zeta": "damping", "radius": "radius",
                                      "max_gain": "max_gain", "kappa2_max": "kappa2_max",
                                      "eta_max": "eta_max"}

    def __post_init__(self) -> None:
        if self.region is not None and not isinstance(self.region, Region):
            raise ValidationError("region must be an optdesign.regions.Region; found "
                                  f"{type(self.region).__name__}")
        if not isinstance(self.placement, str) or self.placement not in PLACEMENTS:
            raise ValidationError(f"placement must be one of {', '.join(map(repr, PLACEMENTS))}; found "
                                  f"{self.placement!r}")
        as_int("starts", self.starts, 1)
        as_int("seed", self.seed, 0)
        as_bool("warm_start", self.warm_start)
        as_bool("reuse", self.reuse)
        self._check_values(self.defaults(), where="")
        if self.pole_scale is not None:
            as_positive_float("pole_scale", self.pole_scale)
        for k, v in as_options("options", self.options).items():
            if isinstance(v, bool) or not isinstance(v, (str, int, float)):
                raise ValidationError(f"options: {k!r} must map to a string or a number; found {v!r}")
        as_time_limit(self.time_limit)
        plant = _plant_of(self.problem, self.plant, "RegionSweepDesigner")
        if self.initial_gain is not None:
            try:
                L0 = np.array(self.initial_gain, dtype=float)
            except (TypeError, ValueError):
                raise ValidationError(f"initial_gain must be a finite ({plant.n}, {plant.p}) array of "
                                      f"numbers; found {self.initial_gain!r}") from None
            if L0.shape != (plant.n, plant.p) or not np.all(np.isfinite(L0)):
                raise ValidationError(f"initial_gain must be a finite ({plant.n}, {plant.p}) array; found "
                                      "shape "
                                      f"{L0.shape}")
            L0.setflags(write=False)
            object.__setattr__(self, "initial_gain", L0)
        self.design_problem()  # the objective and the IPOPT options, checked by the problem's constructor

    # ------------------------------------------------------------------ configuration
    def defaults(self) -> dict[str, float]:
        """The non-None defaults of the sweepable parameters."""
        return {k: getattr(self, k) for k in self.AXES if getattr(self, k) is not None}

    def _check_values(self, values: Mapping[str, Any], where: str) -> dict[str, float]:
        out: dict[str, float] = {}
        for k, v in values.items():
            if k not in self.AXES:
                raise ValidationError(f"unknown parameter {k!r}{where}; a region designer takes "
                                      f"{', '.join(self.AXES)}")
            v = _finite_number(k, v, where)
            if k == "zeta" and not 0.0 < v < 1.0:
                raise ValidationError(f"zeta (damping ratio) must be in (0, 1){where}; found {v!r}")
            if k in ("radius", "max_gain", "eta_max", "kappa2_max") and not v > 0:
                raise ValidationError(f"{k} must be > 0{where}; found {v!r}")
            if k == "kappa2_max" and v < 1:
                raise ValidationError(f"kappa2_max must be >= 1 (kappa2 >= 1 always){where}; found {v!r}")
            out[k] = v
        return out

    def _plant(self) -> Plant:
        return _plant_of(self.problem, self.plant, "RegionSweepDesigner")

    def _omega(self, plant: Plant) -> float:
        if self.pole_scale is not None:
            return float(self.pole_scale)
        if self.radius is not None:
            return float(self.radius)
        if self.region is not None:
            try:
                x0 = abs(self.region.interior_point())
            except Exception:  # noqa: BLE001 - any failure: fall back on the plant's scale
                x0 = 0.0
            if x0 > 0 and math.isfinite(x0):
                return x0
        rho = float(np.max(np.abs(np.linalg.eigvals(plant.A)))) if plant.n else 1.0
        return max(1.0, rho, abs(self.alpha or 0.0))

    def check_point(self, **point: Any) -> None:
        """Validate a point without solving (unknown keys, values, empty or unstable region)."""
        self.region_for(**point)

    def seed_for(self, **point: Any) -> list[int]:
        """The seed of a point's solve: ``seed`` and the point's values (a numpy ``SeedSequence``
        entropy), so that a point's random starts do not depend on where or when it runs."""
        return _point_seed(self.seed, point)

    def region_for(self, **point: float) -> Region:
        """The pole region of a point (validated), as used for verification.

        Raises
        ------
        ValidationError
            Unknown keys or bad values; alpha/zeta with a discrete-time plant; a region that
            reaches outside the stability region (e.g. ``alpha < 0``), which the well-conditioned
            verb refuses too.
        EmptyRegionError
            The pieces have no common point.
        """
        return self._region_of(self._point_values(point))

    def _point_values(self, point: Mapping[str, Any]) -> dict[str, float]:
        """The sweepable parameters of a point (validated) over the designer's defaults."""
        return {**self.defaults(), **self._check_values(point, where=" in the point")}

    def _region_of(self, vals: Mapping[str, float]) -> Region:
        plant = self._plant()
        members: list[Region] = []
        if self.region is not None:
            members.append(self.region)
        if plant.is_discrete and ("alpha" in vals or "zeta" in vals):
            raise ValidationError("alpha and zeta describe continuous-time regions; this plant is discrete "
                                  "(use radius or a fixed discrete-time region)")
        if "alpha" in vals:
            members.append(HalfPlane(vals["alpha"]))
        if "zeta" in vals:
            members.append(Sector.from_damping(vals["zeta"]))
        if "radius" in vals:
            members.append(Disk(0.0, vals["radius"]))
        if not members:
            return stability_region(plant.is_discrete)
        reg = members[0]
        for m in members[1:]:
            reg = reg & m
        check_region_stable(reg, plant.is_discrete)
        return reg

    # ------------------------------------------------------------------ problem object
    def design_problem(self) -> WellConditionedProblem:
        """The :class:`~optdesign.design.well_conditioned.WellConditionedProblem` the points are solved on.

        ``reuse=True``: one problem per configuration (plant, objective, pole scale, options, starts,
        seed) and thread, held across the points and chunks that the thread (a worker process of a
        pool) runs -- its NLPs are built once per pole structure and re-solved with every point's
        values; ``reuse=False``: a new problem (rebuilt NLPs) on every call.
        """
        plant = self._plant()
        omega = self._omega(plant)
        opts = {**SWEEP_IPOPT_OPTIONS, **(self.options or {})}

        eta = isinstance(self.objective, str) and self.objective == "eta"
        route: Any = self.route if self.route is not None else ("auto" if eta else "nlp")

        def build() -> WellConditionedProblem:
            objective: Any = self.objective  # (validated by the constructor, as the route)
            return WellConditionedProblem(plant, objective=objective, starts=self.starts, seed=self.seed,
                                          options=opts, pole_scale=omega, route=route, kalman_start=False,
                                          region_polish="last")

        if not self.reuse:
            return build()
        # (repr: the key is formed before the constructor has validated the objective)
        key = (_plant_key(plant), repr(self.objective), omega, self.starts, self.seed, repr(route),
               tuple(sorted((k, repr(v)) for k, v in opts.items())))
        cache = _cache()
        prob = cache.get(key)
        if prob is None:
            prob = cache[key] = build()
            while len(cache) > _CACHE_SIZE:
                cache.popitem(last=False)
        else:
            cache.move_to_end(key)
        return prob

    # ------------------------------------------------------------------ calls
    def start_chunk(self) -> _RegionSession:
        """A callable for one chunk of a sweep: carries the warm start from point to point."""
        return _RegionSession(self)

    def __call__(self, **point: float) -> ObserverDesign:
        """Design for one point (no warm start: a fresh session)."""
        return _RegionSession(self)(**point)


#: the normal-closed-loop probe's budget in a sweep (measured: benchmarks/results/sweep_grid.md)
_PROBE: dict[str, int] = {"random_starts": 1, "max_iter": 20}


class _RegionSession:
    """One chunk of a sweep: the previous point's verified design is the next point's warm start.

    The session keeps the distinct verified local optima of the previous point (its design, the
    warm starts' and the placement starts' answers, :func:`merge_pool`).  ``placement="pool"``:
    all of them are the next point's warm starts, the placement starts run only when the pool is
    stale (:meth:`_stale`); a member that did not run at a point (it ended early) is carried on.
    ``"always"`` and ``"fallback"``: the previous point's design alone is the warm start.
    """

    def __init__(self, designer: RegionSweepDesigner) -> None:
        self.d = designer
        #: the sweepable parameters of the previous point and its verified local optima (gains, best first)
        self.prev_params: frozenset[str] | None = None
        self.pool: list[tuple[float, NDArray[np.float64]]] = []
        #: the closest normal closed loop of the last probe (its next start)
        self.probe_F: NDArray[np.float64] | None = None

    def _stale(self) -> bool:
        """The placement starts must run again: no pool, or a pool of one optimum (the placement
        starts' chains have merged into the best one or were lost)."""
        return len(self.pool) < 2

    def _normal_probe(self, pool: list[tuple[float, NDArray[np.float64]]], region: Region,
                      point: Mapping[str, float]) -> NDArray[np.float64] | None:
        """``placement="pool"`` with warm starts, objective kappa2, a chunk's first point or a pool whose
        best is above the lower bound 1: a gain with a normal closed loop in the region
        (:func:`normal_closed_loop`), or None (also when the probe does not apply).  Its starts: the
        closest normal matrix of the chunk's previous probe (a continuation of the probe's own
        problem) and one random start per block layout; the pool's designs as starts did not help
        (measured: ``benchmarks/results/sweep_grid.md``)."""
        d = self.d
        if d.placement != "pool" or d.objective != "kappa2" or not d.warm_start:
            return None
        plant = d._plant()
        bound = objective_lower_bound(d.objective, plant.n)
        if bound is None or (pool and pool[0][0] <= bound_level(bound)):
            return None
        if normal_freedom(plant.n, plant.p) < 0:
            return None
        starts = [] if self.probe_F is None else [self.probe_F]
        out = normal_closed_loop(plant.A, plant.C, region, starts=starts,
                                 seed=np.random.SeedSequence(d.seed_for(**point)), full_output=True, **_PROBE)
        assert isinstance(out, tuple), "full_output=True returns (L, closest normal matrix)"
        L, self.probe_F = out
        return L

    def __call__(self, **point: float) -> ObserverDesign:
        """The design of one point on the designer's problem object (:meth:`WellConditionedProblem.solve`)."""
        d = self.d
        deadline = Deadline(as_time_limit(d.time_limit))  # the point's budget, shared by its solves
        vals = d._point_values(point)  # validates the point
        region = d._region_of(vals)
        params = frozenset(vals)
        problem = d.design_problem()
        builds0 = problem.nlp_builds
        pool = list(self.pool) if d.warm_start and self.prev_params == params else []
        if not pool and d.initial_gain is not None:
            pool = [(math.inf, d.initial_gain)]
        if d.placement != "pool":
            pool = pool[:1]  # the previous point's best design alone
        # progress=False: a point of a study never reports its own starts (the sweep reports points;
        # "automatic" would show every design's bar in a notebook)
        kw: dict[str, Any] = {"region": region, "seed": d.seed_for(**point), "time_limit": deadline,
                              "progress": False, **{k: vals.get(k) for k in _BOUNDS}}
        warm: dict[str, Any] = {}
        if pool:
            warm = {"warm_start": pool[0][1], "warm_starts": [L for _, L in pool[1:]]}
        probe = self._normal_probe(pool, region, point)
        if probe is not None:  # a normal closed loop (kappa2 = 1) first, the pool after it
            warm = {"warm_start": probe, "warm_starts": [L for _, L in pool]}
        res = None
        if pool and (d.placement == "fallback" or (d.placement == "pool" and not self._stale())):
            # the warm starts alone first
            res = problem.solve(starts=0, **warm, **kw)
        if res is None or not (res.success or deadline.expired):  # (a spent budget: the warm starts' answer)
            res = problem.solve(starts=d.starts, **warm, **kw)
        if res.verification.passed and np.all(np.isfinite(res.L)):
            self.prev_params, self.pool = params, merge_pool(res, pool, d.starts + 1, *_pool_rtol(d.options))
        best = res.solver_stats.extra.get("best_start")
        origin = next((r.origin for r in res.starts if r.index == best), None)
        stats = dataclasses.replace(res.solver_stats, extra={**res.solver_stats.extra, "best_origin": origin,
                                                             "nlp_builds": problem.nlp_builds - builds0,
                                                             "pool": len(self.pool)})
        return dataclasses.replace(res, solver_stats=stats,
                                   extra={**res.extra, "point": dict(point), "best_origin": origin})


def _pool_rtol(options: Mapping[str, Any] | None) -> tuple[float, float]:
    """``(gain rtol, objective rtol)`` of :func:`merge_pool`: the square root of IPOPT's
    ``acceptable_tol`` (an optimum converged to that tolerance is accurate to about its root) and
    IPOPT's ``tol`` (two answers whose objectives agree to it are one optimum value)."""
    opts = {**SWEEP_IPOPT_OPTIONS, **(options or {})}
    return (math.sqrt(float(opts.get("ipopt.acceptable_tol", 1e-6))), float(opts.get("ipopt.tol", 1e-8)))


# --------------------------------------------------------------------------- noise-ratio designer


@dataclass(frozen=True)
class KalmanNoiseDesigner:
    """Steady-state Kalman filter with scaled noise covariances, for q/r studies.

    A point ``(q, r)`` designs the filter of ``plant.replace(Q=q Q, R=r R)`` (missing axes: 1);
    the gain depends on ``q/r`` only (seed 001 eq 29).  ``record()`` has ``kappa2`` and ``eta`` of
    ``A - L C``, ``gain_norm``, ``max_real_pole`` and the Riccati ``residual``.

    Parameters
    ----------
    problem : str, optional
    plant : Plant, optional
        Needs a noise model (``Q`` and ``R``).
    method : {"scipy", "hamiltonian"}
    """

    problem: str | None = None
    plant: Plant | None = None
    method: str = "scipy"

    AXES: ClassVar[dict[str, str]] = {"q": "process-noise multiplier", "r": "measurement-noise multiplier"}

    def __post_init__(self) -> None:
        if not isinstance(self.method, str) or self.method not in ("scipy", "hamiltonian"):
            raise ValidationError(f"method must be 'scipy' or 'hamiltonian'; found {self.method!r}")
        _plant_of(self.problem, self.plant, "KalmanNoiseDesigner").require_noise_model()

    def check_point(self, **point: Any) -> None:
        """Validate a point without solving."""
        for k, v in point.items():
            if k not in self.AXES:
                raise ValidationError(f"unknown parameter {k!r} in the point; a noise designer takes q, r")
            as_positive_float(k, v)

    def __call__(self, *, q: float = 1.0, r: float = 1.0) -> DesignPoint:
        from ..design.kalman import kalman

        plant = _plant_of(self.problem, self.plant, "KalmanNoiseDesigner")
        plant.require_noise_model()
        q = as_positive_float("q", q)
        r = as_positive_float("r", r)
        kf = kalman(plant.replace(Q=q * plant.Q, R=r * plant.R), method=self.method)
        vals = gain_values(plant, kf.L)
        vals["residual"] = float(kf.residual)
        vals["solver_time"] = float(kf.solver_stats.time)
        return DesignPoint(result=kf, values=vals, status=kf.status, message=kf.message,
                           verification=kf.verification, route=kf.route)


# --------------------------------------------------------------------------- pole-target designer


@dataclass(frozen=True)
class PoleTargetDesigner:
    """A verb with a target pole set ``scale * poles + shift``, for feasibility studies.

    Parameters
    ----------
    problem : str, optional
        Library problem (its ``targets["poles"]`` are the default poles).
    plant : Plant, optional
    poles : (n,) array_like of complex, optional
        Target poles (default: the problem's).
    method : {"inverse", "place", "well_conditioned"}
        :func:`optdesign.design.inverse_kalman.kalman_for_poles` (which Q >= 0 gives these poles?),
        :func:`place_baseline`, or :func:`~optdesign.design.well_conditioned.well_conditioned_observer`
        with fixed poles.
    inverse_method : str
        ``method`` of ``kalman_for_poles`` (``"auto"``, ``"sdp"``, ``"nlp"``, ``"sequential"``).
    objective : str, optional
        ``objective`` of the verb (``kalman_for_poles``: ``"min_trace"``...; well-conditioned:
        ``"kappa2"``...).
    starts, seed : int
        Well-conditioned multi-start; seed also for ``kalman_for_poles``.
    reuse : bool
        No effect (kept for one release): ``kalman_for_poles`` builds its own problem on every call
        (the deprecated :func:`optdesign.design.inverse_kalman.sdp_reuse` is a no-op).
    """

    problem: str | None = None
    plant: Plant | None = None
    poles: tuple[complex, ...] | None = None
    method: str = "inverse"
    inverse_method: str = "auto"
    objective: str | None = None
    starts: int = 2
    seed: int = 0
    reuse: bool = True

    AXES: ClassVar[dict[str, str]] = {"scale": "multiplies the target poles",
                                      "shift": "added to the real parts of the target poles"}
    METHODS: ClassVar[tuple[str, ...]] = ("inverse", "place", "well_conditioned")

    def __post_init__(self) -> None:
        from ..design.inverse_kalman import METHODS as INVERSE_METHODS
        from ..design.inverse_kalman import OBJECTIVES as INVERSE_OBJECTIVES

        if not isinstance(self.method, str) or self.method not in self.METHODS:
            raise ValidationError(f"method must be one of {', '.join(self.METHODS)}; found {self.method!r}")
        if not isinstance(self.inverse_method, str) or self.inverse_method not in INVERSE_METHODS:
            raise ValidationError(f"inverse_method must be one of {', '.join(INVERSE_METHODS)}; found "
                                  f"{self.inverse_method!r}")
        if self.objective is not None:
            allowed = {"inverse": INVERSE_OBJECTIVES,
                       "well_conditioned": get_args(Objective)}.get(self.method, ())
            if not isinstance(self.objective, str) or self.objective not in allowed:
                raise ValidationError(f"objective must be one of {', '.join(allowed) or '(none)'} for method "
                                      f"{self.method!r}; found {self.objective!r}")
        as_int("starts", self.starts, 1)
        as_int("seed", self.seed, 0)
        as_bool("reuse", self.reuse)
        if self.poles is not None:
            object.__setattr__(self, "poles", tuple(complex(z) for z in as_poles("poles", self.poles)))
        plant = _plant_of(self.problem, self.plant, "PoleTargetDesigner")
        as_poles("poles", self.target(), plant.n)

    def check_point(self, **point: Any) -> None:
        """Validate a point without solving."""
        for k in point:
            if k not in self.AXES:
                raise ValidationError(f"unknown parameter {k!r} in the point; a pole-target designer takes "
                                      f"scale, shift")
        self.target(**point)

    def target(self, *, scale: float = 1.0, shift: float = 0.0) -> NDArray[np.complex128]:
        """The target poles of a point."""
        if self.poles is not None:
            base = np.asarray(self.poles, dtype=complex)
        elif self.problem is None:
            raise ValidationError("PoleTargetDesigner needs poles (no problem to take them from)")
        else:
            base = np.asarray(_library_poles(self.problem), dtype=complex)
        return as_poles("poles", _finite_number("scale", scale) * base + _finite_number("shift", shift))

    def __call__(self, *, scale: float = 1.0, shift: float = 0.0) -> DesignPoint:
        plant = _plant_of(self.problem, self.plant, "PoleTargetDesigner")
        target = self.target(scale=scale, shift=shift)
        res: Any
        kw: dict[str, Any]
        if self.method == "place":
            res = place_baseline(plant, target)
            vals = gain_values(plant, res.L)
            vals["pole_error"] = res.record()["pole_error"]
        elif self.method == "inverse":
            from ..design.inverse_kalman import kalman_for_poles

            kw = {"objective": self.objective} if self.objective else {}
            res = kalman_for_poles(plant, target, method=self.inverse_method, seed=self.seed, **kw)
            vals = gain_values(plant, res.L)
            vals["pole_error"] = float(res.pole_error)
            vals["trace_Q"] = float(np.trace(res.Q)) if res.Q is not None else float("nan")
            vals["certificate"] = res.certificate.kind if res.certificate is not None else None
            vals["solver_time"] = float(res.solver_stats.time)
        else:
            from ..design.well_conditioned import well_conditioned_observer

            kw = {"objective": self.objective} if self.objective else {}
            res = well_conditioned_observer(plant, poles=target, starts=self.starts, seed=self.seed,
                                            progress=False, **kw)
            vals = gain_values(plant, res.L)
            vals["solver_time"] = float(res.solver_stats.time)
        return DesignPoint(result=res, values=vals, status=res.status, message=res.message,
                           verification=res.verification, route=getattr(res, "route", Route()))


#: study verbs (``design`` in a study spec) -> designer class and fixed keyword for it
_Designer = type[RegionSweepDesigner | KalmanNoiseDesigner | PoleTargetDesigner]
DESIGNERS: dict[str, tuple[_Designer, dict[str, Any]]] = {
    "well_conditioned": (RegionSweepDesigner, {}),
    "kalman": (KalmanNoiseDesigner, {}),
    "inverse": (PoleTargetDesigner, {"method": "inverse"}),
    "place": (PoleTargetDesigner, {"method": "place"}),
    "well_conditioned_poles": (PoleTargetDesigner, {"method": "well_conditioned"}),
}
