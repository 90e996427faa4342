r"""Trade-off (Pareto) fronts between conditioning metrics and the gain, by epsilon-constraints.

:func:`pareto` answers "what does a better-conditioned observer cost in gain (or in eta)?": it
minimizes one objective (``kappa2``, ``eta`` or ``kappa_fro``) subject to bounds on the others
(``eta <= eta_max``, ``kappa2 <= kappa2_max``, ``||L||_2 <= max_gain``) over a grid of bound levels
-- the epsilon-constraint method -- with poles free in a region.  The NLP is built once, the bounds
are ``opti.parameter`` s re-set for every level, and every level is warm-started from the
previous one (:class:`~optdesign.studies.designers.RegionSweepDesigner`).  Every point is a
verified design; the non-dominated ones (measured with numpy, not the solver) form the front.

The levels span the range found from the *anchors* (each minimizable objective minimized alone):
for a bounded objective, from its own minimum (or, for ``gain_norm``, which the NLP cannot
minimize, the gain of a placement at the open-loop poles projected into the region: feasible and
usually small) to its value at the primary objective's anchor, beyond which the bound is
inactive.  Levels that cannot be met come back as failed points (IPOPT infeasible), which also
shows where the trade-off ends.

References
----------
Jung & Huh (seed 001): eta and kappa2 as competing conditioning indices; Haimes, Lasdon & Wismer
(1971) for the epsilon-constraint method.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .._validate import as_int
from ..errors import ValidationError
from ..model.plant import Plant
from ..model.regions import Region
from ..plot.studies import plot_pareto  # the figure lives in optdesign.plot; kept importable here
from .designers import RegionSweepDesigner
from .sweep import SweepTable, grid, record_of, sweep

__all__ = ["pareto", "ParetoFront", "nondominated", "plot_pareto", "MINIMIZABLE", "BOUNDABLE",
           "PARETO_IPOPT_OPTIONS"]

#: IPOPT options of the front's points (merged under ``options``): bound levels that cannot be met
#: should fail fast
PARETO_IPOPT_OPTIONS = {"ipopt.max_iter": 500}

#: objectives the NLP can minimize
MINIMIZABLE = ("kappa2", "eta", "kappa_fro")
#: objectives the NLP can bound -> designer parameter
BOUNDABLE = {"kappa2": "kappa2_max", "eta": "eta_max", "gain_norm": "max_gain"}


def nondominated(values: np.ndarray, *, rtol: float = 1e-6) -> np.ndarray:
    """Mask of the non-dominated rows of ``values`` (minimization; rows with nan are dominated).

    Row ``j`` dominates row ``i`` when it is no worse in every column and better in at least one,
    both up to the relative tolerance ``rtol`` (so numerically equal points do not dominate each
    other).

    Parameters
    ----------
    values : (k, m) array_like
    rtol : float

    Returns
    -------
    (k,) ndarray of bool

    Examples
    --------
    >>> import numpy as np
    >>> from optdesign.studies import nondominated
    >>> values = np.array([[1.0, 5.0], [2.0, 3.0], [3.0, 4.0], [4.0, 1.0]])
    >>> nondominated(values).tolist()        # (3, 4) loses to (2, 3)
    [True, True, False, True]
    """
    V = np.asarray(values, dtype=float)
    if V.ndim != 2:
        raise ValidationError(f"values must be a (points, objectives) array; found shape {V.shape}")
    ok = np.all(np.isfinite(V), axis=1)
    out = ok.copy()
    tol = rtol * np.maximum(np.abs(V), 1e-300)
    for i in np.where(ok)[0]:
        for j in np.where(ok)[0]:
            if i == j:
                continue
            if np.all(V[j] <= V[i] + tol[i]) and np.any(V[j] < V[i] - tol[i]):
                out[i] = False
                break
    return out


@dataclass(frozen=True)
class ParetoFront:
    """Points of an epsilon-constraint study and which of them are non-dominated.

    Attributes
    ----------
    objectives : tuple of str
        ``objectives[0]`` is minimized, the others bounded.
    table : SweepTable
        One record per point: the bound levels (``kappa2_max``, ``eta_max``, ``max_gain``), status,
        success, ``kappa2``, ``eta``, ``gain_norm``, ..., and ``anchor`` (the objective an anchor
        point minimizes, None for level points).
    values : (k, m) ndarray
        The objectives of every point, recomputed with numpy (nan for failed points).
    nondominated : (k,) ndarray of bool
    designs : list
        The :class:`~optdesign.design.well_conditioned.ObserverDesign` of every point (None if it
        raised).
    levels : dict
        The bound levels used per bounded objective.
    """

    objectives: tuple[str, ...]
    table: SweepTable
    values: np.ndarray
    nondominated: np.ndarray
    designs: list[Any] = field(default_factory=list)
    levels: dict[str, list[float]] = field(default_factory=dict)

    @property
    def primary(self) -> str:
        return self.objectives[0]

    def _front_order(self) -> np.ndarray:
        """Indices of the non-dominated points, sorted by the second objective."""
        idx = np.where(self.nondominated)[0]
        key = self.values[idx, 1] if self.values.shape[1] > 1 else self.values[idx, 0]
        return idx[np.argsort(key, kind="stable")]

    def front(self) -> list[dict[str, Any]]:
        """Records of the non-dominated points, sorted by the second objective."""
        return [self.table.records[i] for i in self._front_order()]

    def front_designs(self) -> list[Any]:
        """The designs of the non-dominated points (same order as :meth:`front`)."""
        return [self.designs[i] for i in self._front_order()]

    def to_csv(self, path: str | Path, *, overwrite: bool = False) -> Path:
        """Every point, with a ``nondominated`` column (written as :meth:`SweepTable.to_csv
        <optdesign.studies.sweep.SweepTable.to_csv>`: never over an existing file unless
        ``overwrite``, never through a symbolic link)."""
        recs = [{**r, "nondominated": bool(nd)}
                for r, nd in zip(self.table.records, self.nondominated, strict=True)]
        t = SweepTable(records=recs, inputs=self.table.inputs)
        return t.to_csv(path, overwrite=overwrite)

    def plot(self, path: str | Path | None = None, **kw):
        """See :func:`plot_pareto`."""
        return plot_pareto(self, path, **kw)


def _small_gain(plant: Plant, region: Region | None) -> float | None:
    """||L||_2 of a placement at the open-loop poles projected into the region (moved slightly
    inside and apart): a feasible, usually small, gain -- the tight end of the gain levels."""
    from ..classical.placement import place_observer
    from ..model.regions import stability_region

    reg = region if region is not None else stability_region(plant.is_discrete)
    try:
        x0 = reg.interior_point()
        P = reg.project(np.linalg.eigvals(plant.A))
        rho = -float(reg.distance([complex(x0)])[0])
        k = np.arange(P.size)
        P = P + (x0 - P) * 1e-3 + 1e-3 * rho * (k - k.mean()) * (np.abs(P.imag) < 1e-12)
        P = P[np.lexsort((P.imag, P.real))]
        L = place_observer(plant, P)
    except Exception:  # noqa: BLE001 - only a heuristic for the range
        return None
    g = float(np.linalg.norm(L, 2))
    return g if math.isfinite(g) and g > 0 else None


def _levels(lo: float, hi: float, n: int) -> list[float]:
    """``n`` levels from ``hi`` (loose) down to ``lo`` (tight), geometric."""
    if not (math.isfinite(lo) and math.isfinite(hi)) or hi <= 0:
        return []
    lo = max(lo, 1e-12)
    if hi <= lo * (1 + 1e-6) or n == 1:
        return [float(hi)]
    return [float(v) for v in np.geomspace(hi, lo, n)]


def pareto(
    plant: Plant,
    region: Region | None = None,
    objectives: tuple[str, ...] | list[str] = ("kappa2", "eta", "gain_norm"),
    *,
    levels: int = 5,
    ranges: dict[str, tuple[float, float]] | None = None,
    max_gain: float | None = None,
    starts: int = 3,
    placement: str = "fallback",
    seed: int = 0,
    executor: Any = "serial",
    progress: bool = False,
    options: dict[str, Any] | None = None,
) -> ParetoFront:
    """Trade-off front between conditioning objectives and the gain (epsilon-constraint method).

    Parameters
    ----------
    plant : Plant
    region : Region, optional
        Pole region (default: the stability region).  With an unbounded region, include
        ``"gain_norm"`` in ``objectives`` or give ``max_gain``, or the metrics may keep
        improving as the poles run away.
    objectives : sequence of str
        2 or 3 distinct names; the first (``"kappa2"``, ``"eta"`` or ``"kappa_fro"``) is minimized,
        the others (``"kappa2"``, ``"eta"``, ``"gain_norm"``) are bounded.
    levels : int, default 5
        Bound levels per bounded objective (``levels ** (m - 1)`` points, plus the anchors).
    ranges : dict, optional
        ``{objective: (lo, hi)}`` overriding the automatic range of a bounded objective.
    max_gain : float, optional
        A fixed bound on ``||L||_2`` for every point (when ``"gain_norm"`` is not an objective).
    starts : int, default 3
        Placement starts per point; they cycle through all-real, mixed and complex pole patterns.
        The anchors always run them.
    placement : {"fallback", "always"}
        Level points: run the placement starts only when neither the warm start from the previous
        level nor the start from the primary anchor's gain gives a verified design (default), or
        always (slower, occasionally better).
    seed : int, default 0
    executor : optional
        Passed to :func:`~optdesign.studies.sweep.sweep` (default in-process, one chunk, so that
        every level is warm-started from the previous one).
    progress : bool
    options : dict, optional
        IPOPT options (merged over :data:`PARETO_IPOPT_OPTIONS` and the designer's defaults).

    Returns
    -------
    ParetoFront

    Raises
    ------
    ValidationError
        Bad objectives (unknown, repeated, fewer than 2 or more than 3, a primary that cannot be
        minimized or a bounded one that cannot be bounded), ``levels < 1``, bad ``ranges``.
    NotObservableError
        ``(C, A)`` not observable.

    Examples
    --------
    >>> from optdesign import problems
    >>> from optdesign.regions import HalfPlane, Disk
    >>> front = pareto(problems.load("compleib_nn8").plant, HalfPlane(0.5) & Disk(0, 10),
    ...                ("eta", "gain_norm"), levels=3)                      # doctest: +SKIP
    >>> [(round(r["eta"], 3), round(r["gain_norm"], 2)) for r in front.front()]  # doctest: +SKIP
    """
    if not isinstance(plant, Plant):
        raise ValidationError(f"plant must be an optdesign.Plant; found {type(plant).__name__}")
    objs = tuple(objectives) if not isinstance(objectives, str) else (objectives,)
    if not 2 <= len(objs) <= 3 or len(set(objs)) != len(objs):
        raise ValidationError(f"objectives must be 2 or 3 distinct names; found {objectives!r}")
    if objs[0] not in MINIMIZABLE:
        raise ValidationError(f"the first objective is minimized and must be one of {MINIMIZABLE}; found "
                              f"{objs[0]!r}")
    for o in objs[1:]:
        if o not in BOUNDABLE:
            raise ValidationError(f"objective {o!r} cannot be bounded; bounded objectives are "
                                  f"{tuple(BOUNDABLE)}")
    levels = as_int("levels", levels, 1)
    ranges = dict(ranges or {})
    for k, v in ranges.items():
        if k not in objs[1:]:
            raise ValidationError(f"ranges has {k!r}, which is not a bounded objective of {objs}")
        try:
            lo, hi = float(v[0]), float(v[1])
        except (TypeError, ValueError, IndexError):
            raise ValidationError(f"ranges[{k!r}] must be a pair (lo, hi); found {v!r}") from None
        if not (0 < lo <= hi < math.inf):
            raise ValidationError(f"ranges[{k!r}] must satisfy 0 < lo <= hi < inf; found {v!r}")
    if max_gain is not None and "gain_norm" in objs:
        raise ValidationError("give max_gain only when gain_norm is not an objective (it is bounded by "
                              "levels)")
    plant.require_observable(what="a Pareto front of observers")

    opts = dict(PARETO_IPOPT_OPTIONS)
    opts.update(options or {})

    def designer(objective: str, initial_gain=None) -> RegionSweepDesigner:
        return RegionSweepDesigner(plant=plant, objective=objective, region=region, max_gain=max_gain,
                                   starts=starts, seed=seed, options=opts, initial_gain=initial_gain,
                                   placement=placement)

    # anchors: each minimizable objective alone
    anchors = {o: designer(o)() for o in objs if o in MINIMIZABLE}
    prim = anchors[objs[0]]
    lv: dict[str, list[float]] = {}
    for o in objs[1:]:
        if o in ranges:
            lo, hi = ranges[o]
        else:
            vals = [getattr(a, o) for a in anchors.values() if a.success and math.isfinite(getattr(a, o))]
            hi = getattr(prim, o) if prim.success else (max(vals) if vals else math.nan)
            if o == "gain_norm":
                small = _small_gain(plant, region)
                lo = small if small is not None and small < hi else 0.5 * hi
            else:
                own = anchors.get(o)
                if own is not None and own.success:
                    lo = getattr(own, o) * 1.01
                else:
                    lo = min(vals) if vals else math.nan
        lv[o] = _levels(lo, hi, levels)
        if not lv[o]:
            raise ValidationError(f"no range for objective {o!r}: the anchors failed ({prim.message}); "
                                  "give ranges")
    axes = {BOUNDABLE[o]: lv[o] for o in objs[1:]}
    names = list(axes)
    points = grid(**axes)
    # every level also starts from the primary anchor's gain (feasible for the loosest levels)
    des = designer(objs[0], prim.L if prim.success else None)
    chunk = len(points) if executor in ("serial", "threads", None) else None
    table = sweep(des, points, executor=executor, progress=progress, keep_results=True, chunksize=chunk)
    records = [{**r, "anchor": None} for r in table.records]
    designs = list(table.results or [None] * len(records))
    for o, a in anchors.items():
        rec: dict[str, Any] = {k: None for k in names}
        rec.update(record_of(a))
        rec.update({"anchor": o, "time": a.solver_stats.time, "error": None, "worker": None})
        records.append(rec)
        designs.append(a)
    full = SweepTable(records=records, inputs=tuple(names), wall_time=table.wall_time, meta=table.meta)
    V = np.array([[float(r[o]) if r.get("success") and r.get(o) is not None else np.nan for o in objs]
                  for r in records], dtype=np.float64)
    return ParetoFront(objectives=objs, table=full, values=V, nondominated=nondominated(V), designs=designs,
                       levels={o: lv[o] for o in objs[1:]})
