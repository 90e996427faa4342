"""The lockstep runner of the eigenstructure engine's region mode (issue 28).

:func:`run_lockstep` takes the starts of :func:`~optdesign.engines.eigenstructure_region.place_region`
through the free-pole continuation together: every start prepared (its gain and the fixed-pole
optimum at its poles as candidates; the cold starts' fixed-pole continuations in one BFGS batch,
:func:`~optdesign.engines.region_batch.fixed_lockstep`), then the free-pole stages of every start
-- one :class:`~optdesign.engines.eigenstructure_region.RegionModel` per real/complex pole pattern --
in one BFGS batch whose every round is one evaluation of all patterns
(:class:`~optdesign.engines.region_batch.PatternBatch`), members re-anchored at their chart's edge,
de-duplicated and pruned between stages; then every surviving member polished at its final poles
(for kappa2 in one batch too).

References
----------
P.-A. Absil, R. Mahony and R. Sepulchre, Optimization Algorithms on Matrix Manifolds (Princeton, 2008),
ch. 4 and 8 (retractions, vector transport).
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._deadline import Deadline
from .._validate import as_poles
from ..analysis import metrics
from ..errors import ValidationError
from ..model.regions import Region
from .eigenstructure import DefectivePolesError, FixedPoleModel, spectral_objective
from .eigenstructure_fixed import StartRecord, peer_start, run_starts
from .eigenstructure_region import (
    REGION_FIXED_STAGES,
    REGION_STAGES,
    REGION_WARM_STAGES,
    RegionModel,
    RegionStart,
    candidate_attains,
    interior_of,
)
from .quasi_newton import bfgs_minimize_batch
from .region_batch import PatternBatch, fixed_lockstep
from .region_eta import ETA_STAGES, ETA_WARM_STAGES, eta_terms
from .tolerances import (
    DUP_FTOL,
    DUP_PTOL,
    INSIDE_FRACTION,
    MARGIN_RTOL,
    REGION_FTOL,
    REGION_PRUNE_FTOL,
    REGION_PRUNE_HORIZON,
    REGION_PRUNE_MARGIN,
)

__all__ = ["run_lockstep"]

#: BFGS iterations per stage in region mode
_REGION_MAX_ITER = 300
#: ... and per call in the first stage (k = 4) of a cold start, whose minimizers the next stage
#: discards: it only brings the poles into a basin (issue 28, measured on 49 plants n <= 10 together
#: with the exact stage left to the polish, below: 22 % less CPU in all; it ran 300 iterations on
#: COMPleib DIS1, 35 % of the stages' CPU; no plant more than 1e-3 worse than the base commit.  Round
#: 9: 50 instead of 80, with the fixed-pole continuation ending at k = 1024 and the pruning inside the
#: second stage (below), 0.85x the CPU on the same plants, none more than 1e-3 worse)
_FIRST_STAGE_MAX_ITER = 50
#: after this stage (0-based) of the full continuation only the :data:`_KEEP` members of lowest
#: value go on: measured (issue 28) on COMPleib DIS1, AC6 and random n = 6, 10 plants, the member
#: that ends best already has the lowest value after the second stage (k = 64) of 8-16 members -- not
#: always: COMPleib TG1's is the 4th lowest there, and keeping 3 lost 4 % on it (round 9).
#: Within that stage (kappa2) a member still running once :data:`_KEEP` others have stopped lower
#: (by REGION_PRUNE_MARGIN) stops there (``bfgs_minimize_batch(keep=...)``): on random n = 6 one
#: member ran 268 iterations, the others at most 41, to end fifth; round 10: unless it is still
#: descending fast (REGION_PRUNE_HORIZON), with that stage's looser stopping test (REGION_PRUNE_FTOL).
#: Not for eta: on the same plants it saved no CPU and lost 10 % on COMPleib TG1
#: kappa2 keeps 5 (round 13): the ranking among near-equal values there depends on the CPU's rounding
#: (on an AMD EPYC, COMPleib UWV ended at 958.4 with 4 kept, 1.3 % worse than the base commit, against
#: 921.7 on the Intel machine of rounds 1-12; 919.1 with 5 kept; TG1 142.2 -> 136.0; 1.03x the median
#: CPU on 50 plants n <= 10, results/region.md).  Not a strict superset of 4: the straggler rule above
#: stops members against the same count, so a member's end of this stage can differ, and a later
#: duplicate may be dropped for a new twin (under the Prescott kernel UWV 952.75 -> 952.72, TG1
#: 133.407 -> 133.424, +1.3e-4).  eta keeps 4: 5 changed only COMPleib AC7 (-0.24 %) at n <= 10, and
#: above n = 10 every member kept runs the later stages
_PRUNE_AFTER = 1
_KEEP: dict[str, int] = {"kappa2": 5, "eta": 4}
#: ... but for eta above this order, after the first stage (k = 4): on 9 random plants n = 12-30
#: (``HalfPlane(0.5) & Sector.from_damping(0.5) & Disk(0, 5)``) the member that ends best had the lowest
#: value after it on 5 of 6 checked, the 3rd lowest on the sixth; 5 eta unchanged, n = 20 +0.10 %,
#: n = 25 and 30 0.1-0.2 % lower, at 0.72-0.89x the engine's CPU (n = 30: 24 s, was 30 s); at n <= 10
#: (49 plants) it lost 19 % on COMPleib HE5, 4.5 % on HE3, 1.7 % on TG1 (issue 28, round 12)
_ETA_PRUNE_FIRST_N = 10
#: ... and at or below it the :data:`_ETA_KEEP_FIRST` members of lowest value after the first stage
#: (16 starts; issue 28, round 16, 50 plants n <= 10, paired with the same code without it: 0.94x the
#: CPU, median ratio 0.95x; TG1 -0.72 %, AC6 -0.14 %, UWV +0.11 %, the others within 1e-3)
_ETA_KEEP_FIRST = 8
#: re-anchorings per stage of a member whose line search stopped at the edge of its chart.  Each goes
#: on at once in the same BFGS batch (``bfgs_minimize_batch(restart=...)``, issue 28, round 15): the
#: batch had been called again for the re-anchored members alone, up to 4 calls per stage, each as
#: long as its slowest member, while the members that had stopped waited
_MAX_REANCHOR = 3
#: a cold start's fixed-pole stages before its poles are freed (:func:`_prepare`; a warm start's: the
#: exact stage; any other objective's: the exact stage): kappa2's continuation; none for eta, freed from
#: its start point alone (issue 28, round 11: the fixed-pole optimum at the start's poles as a second
#: member doubled the members and its preparation ran up to 400 iterations per start; without both,
#: 0.83x the CPU on 49 plants n <= 10, none more than 1e-3 worse than IPOPT alone; COMPleib AC8
#: +6.9 %, DIS1 +0.26 %, random n = 10 s1 +0.37 %, TG1 -7.1 %, the others within 1e-3)
_COLD_FIXED_STAGES: dict[str, tuple[int | None, ...]] = {"kappa2": REGION_FIXED_STAGES, "eta": ()}


def _inside(
    region: Region, poles: NDArray, pinned: NDArray, interior: tuple[float, float]
) -> NDArray[np.complex128]:
    """``poles`` moved strictly inside ``region`` (projected, then 5 % toward the interior point
    ``x0``), real poles kept real; pinned poles are kept as they are."""
    x0, rho = interior
    P = np.asarray(poles, dtype=complex).copy()
    free = np.ones(P.size, dtype=bool)
    for mu in pinned:
        j = int(np.argmin(np.where(free, np.abs(P - mu), np.inf)))
        free[j] = False
    z = region.project(P[free])
    z = z + 0.05 * (x0 - z)
    bad = region.distance(z) > -INSIDE_FRACTION * rho
    z[bad] = x0 + 0.5 * (z[bad] - x0)
    P[free] = np.where(np.abs(P[free].imag) == 0, z.real + 0j, z)
    return P


def _structure(poles: NDArray, pinned: NDArray) -> tuple[int, int]:
    free = list(np.asarray(poles, dtype=complex))
    for mu in pinned:
        free.pop(int(np.argmin([abs(z - mu) for z in free])))
    fr = np.asarray(free)
    nr = int(np.sum(fr.imag == 0))
    return nr, (fr.size - nr) // 2


def _consider(eng, region, objective, model, x, stage, best):
    """``best`` or the design of ``x`` in ``model`` when it is better and its computed gain's poles
    (not the model's) are inside the region: verify, do not trust."""
    try:
        L, V, _, _ = model.design(x)
    except np.linalg.LinAlgError:
        return best
    v = model.metric(x, objective)
    if not (math.isfinite(v) and (best is None or v < best[0])):
        return best
    ev = np.linalg.eigvals(eng.A - L @ eng.C)
    if np.all(np.isfinite(ev)) and region.margin(ev) <= MARGIN_RTOL * max(1.0, float(np.max(np.abs(ev)))):
        return (v, L, V, model.poles.copy(), stage)
    return best


def _prepare(eng, region, st: RegionStart, pinned, objective, rng, dl, interior, measure="right") -> dict:
    """One start up to its fixed-pole continuation: its gain and its start in the fixed-pole model
    at its (moved inside) poles as candidates.  A dict of the start's state (``"fixed"``, ``"x0"``,
    ``"fstages"``: the continuation :func:`_finish` completes; empty for eta's cold start, freed
    from ``"x0"`` alone); ``"done"`` holds a final record when the start cannot go on."""
    ts = time.process_time()
    state: dict = {"st": st, "best": None, "its": 0, "evs": 0, "timed_out": False, "cpu": 0.0}
    try:
        P0 = as_poles("start poles", st.poles, eng.n)
        P0 = as_poles("start poles", _inside(region, P0, pinned, interior))
        fixed = FixedPoleModel(eng, P0, measure=measure)
    except DefectivePolesError:
        state["done"] = StartRecord(st.origin, math.inf, math.inf, math.inf, 0, 0, "defective start", 0.0)
        return state
    except ValidationError as exc:
        state["done"] = StartRecord(st.origin, math.inf, math.inf, math.inf, 0, 0, f"refused: {exc}", 0.0)
        return state
    L0 = st.gain if st.gain is not None else peer_start(eng.A, eng.C, fixed.poles, "YT")
    x0 = fixed.coords_from_gain(L0) if L0 is not None else None
    if x0 is None or not math.isfinite(fixed.metric(x0, objective)):
        x0 = fixed.random_coords(rng)
    v0 = state["v0"] = fixed.metric(x0, objective)
    if st.gain is not None:
        try:  # the start's own gain, unoptimized (never worse than the caller's start)
            gm = FixedPoleModel(eng, np.linalg.eigvals(eng.A - st.gain @ eng.C), measure=measure)
            xg = gm.coords_from_gain(st.gain)
            if xg is not None:
                state["best"] = _consider(eng, region, objective, gm, xg, "start gain", state["best"])
        except (ValidationError, DefectivePolesError):
            pass
    if not math.isfinite(v0):
        state["done"] = StartRecord(st.origin, math.inf, math.inf, math.inf, 0, 1, "singular start", 0.0)
        return state
    state["best"] = _consider(eng, region, objective, fixed, x0, "start", state["best"])
    fstages = (None,) if st.warm else _COLD_FIXED_STAGES.get(objective, (None,))
    state.update(fixed=fixed, x0=x0, fstages=fstages, cpu=time.process_time() - ts)
    return state


def _finish(eng, region, objective, pinned, state: dict, out: tuple) -> None:
    """A prepared start after its fixed-pole continuation ``out = (x, iterations, evaluations,
    reason)``: the optimum a candidate, and the members to free (from the start and from that
    optimum; a warm start: from the optimum only)."""
    xa, ia, ea, ra = out
    fixed, x0 = state["fixed"], state["x0"]
    state["its"], state["evs"] = ia, ea
    state["best"] = _consider(eng, region, objective, fixed, xa, "fixed poles", state["best"])
    state["timed_out"] = ra == "time_limit"
    state.update(members=xa[None, :] if state["st"].warm else np.stack([x0, xa]),
                 key=_structure(fixed.poles, pinned))


def _prepare_all(eng, region, starts, pinned, objective, rng, dl, interior, stop_at, measure) -> list[dict]:
    """Every start prepared (:func:`_prepare`, :func:`_finish`).  The cold kappa2 starts' fixed-pole
    continuations run in lockstep (:func:`~optdesign.engines.region_batch.fixed_lockstep`, one
    evaluation per round for all; the first alone when ``stop_at`` is given: a start that attains it
    ends the run before the others are prepared); eta's cold starts have none (their one member is
    the start point); the others one by one.  A start whose candidate attains ``stop_at``
    (:func:`~optdesign.engines.eigenstructure_region.candidate_attains`) marks every state
    ``"skip"``."""
    states: list[dict] = []
    batch: list[dict] = []

    def attained(group) -> bool:
        if not any(candidate_attains(eng, objective, s["best"], stop_at) for s in group):
            return False
        for s in states:  # a global optimum: no free-pole stage is needed
            s["skip"] = True
        return True

    for st in starts:
        if dl.expired:
            break
        s = _prepare(eng, region, st, pinned, objective, rng, dl, interior, measure)
        states.append(s)
        if "done" in s:
            continue
        if not s["fstages"]:  # eta's cold start: freed from its start point alone (_prepare)
            s.update(members=s["x0"][None, :], key=_structure(s["fixed"].poles, pinned))
            if attained([s]):
                return states
            continue
        if s["fstages"] is REGION_FIXED_STAGES and (stop_at is None or len(states) > 1):
            batch.append(s)
            continue
        ts = time.process_time()
        (out,) = run_starts(s["fixed"], s["x0"][None, :], objective, dl, 400, s["fstages"])
        _finish(eng, region, objective, pinned, s, out)
        s["cpu"] += time.process_time() - ts
        if attained([s]):
            return states
    outs, shares = _fixed_batches([(s["fixed"], s["x0"]) for s in batch], objective, dl, REGION_FIXED_STAGES)
    for s, out, share in zip(batch, outs, shares, strict=True):
        _finish(eng, region, objective, pinned, s, out)
        s["cpu"] += share
    attained(batch)
    return states


def _fixed_batches(jobs: list[tuple[FixedPoleModel, NDArray]], objective: str, dl,
                   stages: tuple[int | None, ...]) -> tuple[list[tuple], list[float]]:
    """:func:`~optdesign.engines.region_batch.fixed_lockstep` of every ``(fixed-pole model, start
    coordinates)``, one batch per coordinate length (a pole at an unobservable mode pads it): per job
    its ``(x, iterations, evaluations, reason)`` and its share of its batch's CPU time, in the
    order of ``jobs``."""
    outs: list[Any] = [None] * len(jobs)
    shares = [0.0] * len(jobs)
    for size in sorted({fm.size for fm, _ in jobs}):
        idx = [j for j, (fm, _) in enumerate(jobs) if fm.size == size]
        ts = time.process_time()
        done = fixed_lockstep([jobs[j][0] for j in idx], np.stack([jobs[j][1] for j in idx]), objective,
                              dl, 400, stages)
        share = (time.process_time() - ts) / len(idx)
        for j, o in zip(idx, done, strict=True):
            outs[j], shares[j] = o, share
    return outs, shares


def run_lockstep(eng, region, starts: Sequence[RegionStart], pinned, objective, rng, dl, stop_at=None,
                 measure="right"):
    """Every start in lockstep: each prepared (``_prepare_all``), the free-pole stages of all starts
    in one BFGS batch (``_region_stages``: the starts with the same real/complex pole pattern on one
    model, one evaluation of every pattern per round -- on small plants a round's cost is numpy's
    per-call overhead, ``region_batch``), then each member polished at its final poles
    (``_polish``).  Per start ``(record, best candidate, timed_out)``; a
    start whose candidate attains ``stop_at`` ends the run (see :func:`place_region`).  ``measure``:
    which eigenvectors the objective measures (:class:`RegionModel`)."""
    interior = interior_of(region)
    states = _prepare_all(eng, region, starts, pinned, objective, rng, dl, interior, stop_at, measure)
    live = [s for s in states if "done" not in s and "skip" not in s]
    groups: dict[tuple[int, int], list[dict]] = {}
    for s in live:
        groups.setdefault(s["key"], []).append(s)
    batch: list[tuple[RegionModel, NDArray]] = []
    t0 = time.process_time()
    warm = bool(live) and live[0]["st"].warm
    for (nrf, npf), group in groups.items():
        model = RegionModel(eng, nrf, npf, region, pinned, interior, measure)
        rows, ar, ap = [], [], []
        for s in group:
            rows.append(model.coords_of(s["fixed"], s["members"]))
            ar.append(model.anchor_r)
            ap.append(model.anchor_p)
            s.setdefault("parts", []).append((len(batch), sum(x.shape[0] for x in rows[:-1])))
        model.anchor_r, model.anchor_p = np.concatenate(ar), np.concatenate(ap)
        batch.append((model, np.concatenate(rows)))
    # a cold start's free poles stop at k = 16384: the fixed-pole polish at its final poles (_polish)
    # is its exact stage (issue 28: the exact free-pole stage ran to its iteration limit on the larger
    # plants, 20 % of the stages' CPU on COMPleib DIS1)
    stages = REGION_WARM_STAGES if warm else REGION_STAGES[:-1]
    if objective == "eta":  # the gap's soft-min continuation (region_eta)
        stages = ETA_WARM_STAGES if warm else ETA_STAGES
    elif objective != "kappa2":
        stages = ((None, REGION_STAGES[-1][1]),)
    res = _region_stages(batch, objective, stages, dl, stop_at) if batch else []
    share = (time.process_time() - t0) / max(1, len(live))
    jobs: list[tuple[dict, FixedPoleModel, NDArray]] = []
    for s in states:
        if "done" in s:
            continue
        s["reasons"] = ["converged"]
        for g, k0 in s.get("parts", []) if "skip" not in s else []:
            Xg, reasons, its, evs, tb = res[g]
            model, m = batch[g][0], s["members"].shape[0]
            s["its"] += int(its[k0 : k0 + m].sum())
            s["evs"] += int(evs[k0 : k0 + m].sum())
            s["timed_out"] |= tb
            s["reasons"] += reasons[k0 : k0 + m]
            if "infeasible start" in reasons[k0 : k0 + m]:
                continue
            for i in range(k0, k0 + m):
                if reasons[i] not in ("pruned", "duplicate"):  # a better member went on from there
                    fm, xc = model.fixed(Xg[i], i)
                    s["best"] = _consider(eng, region, objective, fm, xc, "free poles", s["best"])
                    jobs.append((s, fm, xc))
    _polish(eng, region, objective, jobs, dl)
    out = []
    for s in states:
        if "done" in s:
            out.append((s["done"], s["best"], False))
            continue
        reasons = s["reasons"][1:] or s["reasons"]
        best = s["best"]
        val = best[0] if best is not None else math.inf
        k2 = math.inf
        if best is not None:
            sv = np.linalg.svd(best[2], compute_uv=False)
            k2 = float(sv[0] / sv[-1])
        reason = min(reasons, key=lambda r: r != "converged")
        design = (best[1], best[2], best[3]) if best is not None else (None, None, None)
        cpu = s["cpu"] + share
        rec = StartRecord(s["st"].origin, k2, val, s["v0"], s["its"], s["evs"], reason, cpu, *design)
        out.append((rec, best, s["timed_out"]))
    return out


def _polish(eng, region, objective, jobs: list[tuple[dict, FixedPoleModel, NDArray]], dl) -> None:
    """Every free-pole design ``(start state, fixed-pole model at its final poles, coordinates)``
    polished at its poles, a candidate of its start: for kappa2 and eta all in one BFGS batch
    (:func:`~optdesign.engines.region_batch.fixed_lockstep`, per coordinate length), kappa_fro one by
    one (:func:`~optdesign.engines.eigenstructure_fixed.run_starts`)."""
    ts = time.process_time()
    if objective in ("kappa2", "eta"):
        outs, _ = _fixed_batches([(fm, xc) for _, fm, xc in jobs], objective, dl, (None,))
    else:
        outs = [run_starts(fm, xc[None, :], objective, dl, 400, (None,))[0] for _, fm, xc in jobs]
    share = (time.process_time() - ts) / max(1, len(jobs))
    for (s, fm, _), (xp, ip, ep, rp) in zip(jobs, outs, strict=True):
        s["its"], s["evs"], s["cpu"] = s["its"] + ip, s["evs"] + ep, s["cpu"] + share
        s["best"] = _consider(eng, region, objective, fm, xp, "free poles, polished", s["best"])
        s["timed_out"] |= rp == "time_limit"


def _region_stages(batch: list[tuple[RegionModel, NDArray]], objective: str,
                   stages: Sequence[tuple[int | None, float]], dl: Deadline, stop_at: float | None = None):
    """The continuation of region mode, every member of every model in one BFGS batch.

    ``batch``: ``(model, X)`` per pole pattern, ``X`` (s, size) its members (anchored).  Each
    member's inverse-Hessian approximation is carried from stage to stage (as in the fixed-pole
    engine's :func:`~optdesign.engines.eigenstructure_fixed.run_starts`).  A member whose line search
    fails at the edge of its chart (a trial step that would rotate a subspace past
    ``RegionModel.overlap_floor`` from its anchor) is re-anchored at its current point and continues
    the stage in the same batch (at most :data:`_MAX_REANCHOR` times per stage): the chart edge is not
    a minimizer.  A member
    without a finite value at a stage's start (two poles at one point: the separation barrier) stops
    there (``"infeasible start"``).  After a stage where a member's exact objective attains
    ``stop_at`` (its lower bound: a global optimum) the stages end there, with only those members.
    Per model ``(X, reasons, iterations (s,), evaluations (s,), timed_out)``.
    """
    models = [b[0] for b in batch]
    sizes = [b[1].shape[0] for b in batch]
    owner = np.repeat(np.arange(len(batch)), sizes)
    X = np.concatenate([b[1] for b in batch])
    total = X.shape[0]
    reasons = ["converged"] * total
    H: list[NDArray | None] = [None] * total
    its, evs = np.zeros(total, int), np.zeros(total, int)
    alive = np.ones(total, dtype=bool)

    merged = PatternBatch(models, sizes)

    def evaluate(Z, rows, k, mu):
        return merged.evaluate(Z, rows, objective, k, mu)

    def anchor():
        for g, model in enumerate(models):
            model.set_anchor(X[owner == g])
        merged.refresh_anchors()

    prune_after = 0 if objective == "eta" and models[0].engine.n > _ETA_PRUNE_FIRST_N else _PRUNE_AFTER
    timed_out = False
    for si, (k, mu) in enumerate(stages):
        if dl.expired:
            timed_out = True
            for i in np.flatnonzero(alive):
                reasons[i] = "time_limit"
            break
        anchor()
        todo = np.flatnonzero(alive)
        bad = ~np.isfinite(evaluate(X[todo], todo, k, mu)[0])
        for i in todo[bad]:
            reasons[i], alive[i] = "infeasible start", False
        todo = todo[~bad]
        if not todo.size:  # no member left
            continue
        ftol = REGION_FTOL.get(k, REGION_FTOL[None])
        # a cold start's first stage (k = 4): capped (the full kappa2 continuation has more than 2 stages)
        its_cap = _FIRST_STAGE_MAX_ITER if si == 0 and objective == "kappa2" and len(stages) > 2 \
            else _REGION_MAX_ITER
        # the stage after which only _KEEP members go on (any cold continuation); for kappa2 its
        # stragglers are stopped inside it and its stopping test is looser (prune_inside)
        prune = si == prune_after and len(stages) > 2
        prune_inside = prune and objective == "kappa2"
        if prune_inside:
            ftol = REGION_PRUNE_FTOL
        anchored = np.zeros(total, int)

        def restart(j, x, f_leg, f, _todo=todo, _ftol=ftol, _anchored=anchored):
            """Re-anchor member ``_todo[j]`` at ``x``, where its line search stopped at its chart's
            edge, when the leg made progress (at most _MAX_REANCHOR times per stage)."""
            i = _todo[j]
            if _anchored[i] >= _MAX_REANCHOR or not f_leg - f > _ftol * max(1.0, abs(f)) or dl.expired:
                return False
            _anchored[i] += 1
            models[owner[i]].set_anchor(x[None, :], members=merged.local[i : i + 1])
            merged.refresh_anchors()
            return True

        def first_legs(Xs, _todo=todo):
            """Whether a member attains ``stop_at`` once every member has ended its first leg (the
            members are marked after the batch, by the same test at the same points)."""
            Xt = X.copy()
            Xt[_todo] = Xs
            return _attained(models, owner, Xt, alive.copy(), list(reasons), objective, stop_at)

        def fun(Z, idx, _k=k, _mu=mu, _todo=todo):
            return evaluate(Z, _todo[idx], _k, _mu)

        res, Hs = bfgs_minimize_batch(fun, X[todo], max_iter=its_cap, ftol=ftol, deadline=dl,
                                      pass_index=True, H0=[H[i] for i in todo],
                                      keep=_KEEP[objective] if prune_inside else 0,
                                      keep_margin=REGION_PRUNE_MARGIN, keep_horizon=REGION_PRUNE_HORIZON,
                                      restart=restart, first_legs=None if stop_at is None else first_legs)
        for j, i in enumerate(todo):
            r = res[j]
            X[i], H[i], reasons[i] = r.x, Hs[j], r.reason
            alive[i] = r.reason != "pruned"
            its[i] += r.iterations
            evs[i] += r.evaluations
        # a global optimum: the later stages cannot improve it
        if stop_at is not None and _attained(models, owner, X, alive, reasons, objective, stop_at):
            break
        _drop_duplicates(models, owner, X, alive, reasons, evaluate, k, mu)
        if prune:
            _prune(X, alive, reasons, evaluate, k, mu, _KEEP[objective])
        elif si == 0 and objective == "eta" and len(stages) > 2:  # a cold eta continuation, n <= 10
            _prune(X, alive, reasons, evaluate, k, mu, _ETA_KEEP_FIRST)
    timed_out |= dl.expired
    out = []
    for g in range(len(batch)):
        sel = owner == g
        out.append((X[sel], [reasons[i] for i in np.flatnonzero(sel)], its[sel], evs[sel], timed_out))
    return out


def _attained(models, owner, X, alive, reasons, objective, stop_at: float) -> bool:
    """When a running member's exact objective (kappa2 or kappa_fro of its eigenvectors; eta of its
    closed loop, :func:`_exact_eta`) is at most ``stop_at`` (its lower bound: a global optimum), the
    others are ``"pruned"`` and the stages end (True)."""
    exact = np.full(X.shape[0], math.inf)
    for g, model in enumerate(models):
        mine = np.flatnonzero(owner == g)
        sel = np.flatnonzero(alive[mine])
        if not sel.size:
            continue
        try:
            W = model._members(X[mine])["W"][sel]
            if objective == "eta":
                exact[mine[sel]] = _exact_eta(W, model.all_poles(*model.split(X[mine[sel]])[1:]), stop_at)
                continue
            f = spectral_objective(W, objective, None, gradient=False)[0]
        except np.linalg.LinAlgError:
            continue
        exact[mine[sel]] = np.exp(f)
    if not np.any(exact <= stop_at):
        return False
    for i in np.flatnonzero(alive & (exact > stop_at)):
        reasons[i], alive[i] = "pruned", False
    return True


def _exact_eta(W: NDArray, P: NDArray, stop_at: float) -> NDArray[np.float64]:
    """eta of each member's closed loop ``W^-1 diag(P) W`` (``W`` (s, n, n), ``P`` (s, n) its poles in
    row order) from its Schur form (:func:`~optdesign.analysis.metrics.eta`) where the model's own
    value (:func:`~optdesign.engines.region_eta.eta_terms`, which subtracts two nearly equal numbers
    near a normal matrix) is within 10 ``stop_at``; inf elsewhere (those members do not attain it)."""
    f = eta_terms(P, W, None)[0]
    out = np.full(W.shape[0], math.inf)
    for i in np.flatnonzero(np.exp(0.5 * f) <= 10.0 * stop_at):
        F = np.linalg.solve(W[i], P[i][:, None] * W[i]).real
        if np.all(np.isfinite(F)):
            out[i] = metrics.eta(F)
    return out


def _prune(X, alive, reasons, evaluate, k, mu, keep: int) -> None:
    """Of the running members, keep the ``keep`` of lowest value running (the others ``"pruned"``;
    :data:`_KEEP`)."""
    idx = np.flatnonzero(alive)
    if idx.size <= keep:
        return
    f = evaluate(X[idx], idx, k, mu)[0]
    for j in np.argsort(f)[keep:]:
        reasons[idx[j]], alive[idx[j]] = "pruned", False


def _drop_duplicates(models, owner, X, alive, reasons, evaluate, k, mu) -> None:
    """Stop the members at the point of a better one (marked ``"duplicate"``): the same value to
    :data:`DUP_FTOL` and the same poles to :data:`DUP_PTOL` times their scale -- they would
    follow the same path through the next stages (as the fixed-pole engine's ``run_starts``
    does).  Poles, unlike coordinates, compare across pole patterns."""
    idx = np.flatnonzero(alive)
    if idx.size < 2:
        return
    f = evaluate(X[idx], idx, k, mu)[0]
    poles = [np.sort_complex(models[owner[i]].poles(X[i])) for i in idx]
    scale = max(1.0, max(float(np.max(np.abs(P))) for P in poles))
    kept: list[int] = []
    for j in np.argsort(f):
        if not math.isfinite(f[j]):
            continue
        if any(abs(f[j] - f[q]) <= DUP_FTOL * max(1.0, abs(f[q]))
               and float(np.max(np.abs(poles[j] - poles[q]))) <= DUP_PTOL * scale for q in kept):
            reasons[idx[j]], alive[idx[j]] = "duplicate", False
        else:
            kept.append(j)
