"""The engine route of the well-conditioned observer: the dedicated eigenstructure placement engine
(:mod:`optdesign.engines.eigenstructure`) for fixed poles (:func:`place_fixed`, every start in
lockstep) and for poles free in a region (:func:`place_region`, every start in lockstep too: the
time budget acts between its rounds, the objective's lower bound between its stages).

The engine's answers are not trusted: every start's gain, with the engine's eigenbasis and pole
order, is verified by the verb's own evaluation (:func:`~.evaluation.evaluate_candidate`).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..._deadline import Deadline
from ...engines.eigenstructure import EigenstructureEngine, Objective
from ...engines.eigenstructure_fixed import PlacementOutcome, place_fixed
from ...engines.eigenstructure_region import RegionStart, place_region
from ...errors import ValidationError
from ...model.regions import Region
from ...results import Status
from .evaluation import Candidate, Evaluated, bound_level, metric_of, start_record
from .results import StartRecord

__all__ = ["ENGINE", "engine_fixed", "engine_region", "engine_status"]

#: backend name of the engine's designs (SolverStats.backend)
ENGINE = "eigenstructure"

#: the engine's per-start stop reasons -> status.  An iteration limit of the last BFGS stage is
#: ``optimal_inaccurate``: the design is a verified improvement on its start (never worse, by
#: construction) and its metric is computed exactly, only its local optimality is not certified --
#: as IPOPT's "solved to acceptable level" (measured: the n = 30 and 50 benchmarks, 0.13x and 0.20x
#: the kappa2 of scipy YT, end there).
_REASONS: dict[str, Status] = {
    "converged": Status.OPTIMAL,
    "line search": Status.OPTIMAL,
    "duplicate": Status.OPTIMAL,
    "pruned": Status.OPTIMAL,
    "direct": Status.SOLVED,
    "max_iter": Status.OPTIMAL_INACCURATE,
    "max_eval": Status.OPTIMAL_INACCURATE,
    "time_limit": Status.TIME_LIMIT,
}


def engine_status(reason: str) -> Status:
    """The status of one engine start from its stop reason (``_REASONS``; anything else -- a
    singular start, a structural-zero violation -- is ``not_found``)."""
    return _REASONS.get(reason, Status.NOT_FOUND)


def _message(reason: str, stage: str) -> str:
    why = {"duplicate": "reached the point of an earlier start (stopped there)",
           "pruned": "stopped early in the continuation, other starts being better there (its best "
                     "design kept)",
           "direct": "the gain is fixed by the poles (computed directly)",
           "max_iter": "iteration limit of the last BFGS stage (a verified improvement on the start, "
                       "not certified as a local minimum)",
           "max_eval": "evaluation limit of the last BFGS stage",
           "time_limit": "time limit reached: best so far"}.get(reason, reason)
    return f"placement engine ({stage}): {why}"


def _candidates(out: PlacementOutcome, stage: str, wall: float) -> list[tuple[str, Candidate]]:
    """One candidate per engine start (origin, candidate), with its share of the time."""
    share = wall / max(1, len(out.starts))
    res = []
    for r in out.starts:
        L = r.L if r.L is not None else np.full(out.L.shape, np.nan)
        status = engine_status(r.reason)
        zp = r.poles if r.poles is not None else out.poles
        res.append((r.origin, Candidate(np.asarray(L, dtype=float), r.V, None if r.V is None else zp, status,
                                        r.reason, _message(r.reason, stage), int(r.iterations), share,
                                        stage=stage, backend=ENGINE)))
    return res


def engine_fixed(eng: EigenstructureEngine, target: NDArray, objective: Objective, *, starts: int, seed: int,
                 deadline: Deadline, mask: NDArray | None, evaluate: Callable[[Candidate], Any],
                 warm_start: Any = None) -> tuple[list[StartRecord], list[Evaluated]]:
    """Fixed poles on the engine (all starts in lockstep); per start a record and its evaluation.

    ``warm_start``: a gain (or the engine's coordinates) of a previous design for the same poles --
    one more start.
    """
    t0 = time.perf_counter()
    # A, C: the engine's own (place_fixed uses the engine and ignores them)
    out = place_fixed(eng.A, eng.C, target, objective=objective, starts=starts, seed=seed, deadline=deadline,
                      warm_start=warm_start, gain_mask=mask, engine=eng)
    wall = time.perf_counter() - t0
    records: list[StartRecord] = []
    evaluated: list[Evaluated] = []
    for idx, (origin, cand) in enumerate(_candidates(out, "fixed poles", wall)):
        m, v = evaluate(cand)
        obj = metric_of(objective, m)
        records.append(start_record(idx, origin, cand, m, v, obj, cand.message))
        evaluated.append((obj, idx, m, v, cand))
    return records, evaluated


def engine_region(eng: EigenstructureEngine, region: Region, objective: str,
                  specs: list[tuple[str, NDArray | None, NDArray, bool]], *, seed: int, deadline: Deadline,
                  evaluate: Callable[[Candidate], Any], lower_bound: float | None, progress=None,
                  ) -> tuple[list[StartRecord], list[Evaluated]]:
    """Poles free in ``region`` on the engine: one :func:`place_region` with every start ``(origin,
    gain, poles, warm)`` (the warm ones first), run in lockstep; each start's design is a candidate
    verified by ``evaluate``.  A start that attains ``lower_bound`` (:func:`~.evaluation.bound_level`)
    before or during the free-pole stages ends the run: a global optimum."""
    stop_at = None if lower_bound is None else bound_level(lower_bound)
    records: list[StartRecord] = []
    evaluated: list[Evaluated] = []
    if not specs:
        return records, evaluated
    t0 = time.perf_counter()
    n, p = eng.n, eng.p
    try:
        starts = [RegionStart(o, np.asarray(P0, dtype=complex), L0, warm=w) for o, L0, P0, w in specs]
        out = place_region(eng.A, eng.C, region, objective=objective, n_samples=0, seed=seed,
                           deadline=deadline, engine=eng, starts=starts, stop_at=stop_at)
    except ValidationError as exc:  # e.g. start poles the engine cannot use
        cands = [(specs[0][0], Candidate(np.full((n, p), np.nan), None, None, Status.NOT_FOUND, "refused",
                                         f"placement engine refused the starts: {exc}", 0,
                                         time.perf_counter() - t0, stage="free poles", backend=ENGINE))]
    else:
        cands = _candidates(out, "free poles", time.perf_counter() - t0)
        for (_, cand), rec in zip(cands, out.starts, strict=True):
            # a start with a design: optimal (inside the region), its iteration limit optimal_inaccurate
            # as for fixed poles, a time limit time_limit; a start without one: not_found
            if rec.L is None:
                cand.status = Status.TIME_LIMIT if rec.reason == "time_limit" else Status.NOT_FOUND
            elif engine_status(rec.reason) in (Status.OPTIMAL_INACCURATE, Status.TIME_LIMIT):
                cand.status = engine_status(rec.reason)
            else:
                cand.status = Status.OPTIMAL
        if not cands and specs[0][1] is not None:  # the budget was spent before the engine could begin
            L0 = np.asarray(specs[0][1], dtype=float)
            cands = [(specs[0][0], Candidate(L0, None, None, Status.TIME_LIMIT, "time_limit",
                                             "the start's gain itself (the time ran out before "
                                             "the engine could improve it)", 0, time.perf_counter() - t0,
                                             stage="start gain", backend=ENGINE))]
        elif not cands:
            cands = [(specs[0][0], Candidate(out.L, None, None, Status(out.status), out.status.value,
                                             out.message, 0, time.perf_counter() - t0, stage="free poles",
                                             backend=ENGINE))]
    for idx, (origin, cand) in enumerate(cands):
        m, v = evaluate(cand)
        obj = metric_of(objective, m)
        records.append(start_record(idx, origin, cand, m, v, obj, cand.message))
        evaluated.append((obj, idx, m, v, cand))
        if progress is not None:
            progress.update(1, note=f"best {objective} {min(e[0] for e in evaluated):.6g}")
    return records, evaluated
