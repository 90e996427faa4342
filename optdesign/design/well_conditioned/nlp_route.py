"""The NLP route of the well-conditioned designs (CasADi / IPOPT): where the placement engine does
not handle a constraint (a gain bound ``max_gain``, the trade-off bounds ``kappa2_max`` /
``eta_max``, structural zeros in a region), beside the engine (eta in a region), or as a fallback
when the engine's design does not verify.

Every start runs the NLP's continuation (:mod:`optdesign.formulate.well_conditioned`); every stage's
candidate is verified independently (:mod:`.evaluation`) and each start keeps its best verified one.
The NLPs are built by the caller's problem object (:class:`~.problem.WellConditionedProblem`), once
per pole structure, and re-solved with new parameters.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..._deadline import Deadline
from ..._validate import as_options, as_poles
from ...model.plant import Plant
from ...model.regions import Region
from ...results import Status
from .evaluation import (
    Candidate,
    Evaluated,
    attains,
    best_of_history,
    metric_of,
    start_record,
)
from .results import StartRecord
from .starts import placement_start

__all__ = [
    "IPOPT_DEFAULTS",
    "REGION_STAGES",
    "REGION_MAX_ITER",
    "REGION_POLISHES",
    "ipopt_options",
    "solve_nlp",
    "stage_plan",
    "read_candidate",
    "solver_error_candidate",
    "run_start",
    "solve_starts",
    "nlp_fixed_runner",
    "nlp_region_runner",
]

#: continuation stages of the free-pole NLP (the fixed-pole polish at its poles runs them all):
#: on COMPleib AC6 stages 3 and 9 changed kappa2 by < 0.2 % at ~40 % of the time
REGION_STAGES = (0, 6, 12)

#: IPOPT's iterations per continuation stage of the free-pole NLP (the caller's ``ipopt.max_iter`` when
#: lower; eta's start beside the engine: ``problem.ETA_NLP_MAX_ITER``)
REGION_MAX_ITER = 300

#: how a region start polishes (:func:`nlp_region_runner`): ``"full"``, the fixed-pole NLP at the
#: start's poles and at the free-pole answer's poles, each through its whole continuation; ``"last"``,
#: only at the answer's poles and the last stage only
REGION_POLISHES = ("full", "last")

#: IPOPT settings of the design verbs (per stage; merged under the caller's ``options``).
#: ``acceptable_obj_change_tol`` ends the long flat tails measured on scipy's 6x6 test case
#: (1000 iterations for a 1e-9 relative change of kappa2).
IPOPT_DEFAULTS: dict[str, Any] = {
    "ipopt.tol": 1e-8,
    "ipopt.constr_viol_tol": 1e-10,
    "ipopt.acceptable_tol": 1e-6,
    "ipopt.acceptable_iter": 5,
    "ipopt.acceptable_obj_change_tol": 1e-10,
    "ipopt.max_iter": 500,
}

#: a function of one candidate -> (metrics, Verification)
Evaluate = Callable[[Candidate], Any]


def ipopt_options(options: Any, defaults: dict[str, Any] | None = None) -> dict[str, Any]:
    """The IPOPT defaults (:data:`IPOPT_DEFAULTS` unless given) with the caller's ``options`` (a dict
    with string keys, or None) merged over them; IPOPT refuses bad names and values up front.

    Raises
    ------
    ValidationError
        ``options`` is not a dict (or None), has a key that is not a string, or an option IPOPT does
        not accept (:func:`optdesign.backends.casadi_backend.check_ipopt_options`).
    """
    from ...backends.casadi_backend import check_ipopt_options

    user = as_options("options", options)
    if user:
        check_ipopt_options(user)
    return {**(IPOPT_DEFAULTS if defaults is None else defaults), **user}


def solve_nlp(nlp, options: dict[str, Any], deadline: Deadline):
    """Solve a built observer NLP with IPOPT within ``deadline`` (a :class:`SolverReport`).

    IPOPT is configured on the first solve and re-used after (``nlp.solver_ready``); under a time
    limit its ``max_wall_time`` is the time left (:meth:`Deadline.ipopt_options`), and the solver
    is re-configured when the cap it has exceeds the time left by more than a tenth of the limit
    (at least 0.05 s) -- so a solve overruns the deadline by at most that, and IPOPT is configured
    at most about ten times per design.

    Each stage of the continuation has its own IPOPT instance (``nlp.stage_solvers``, made on the
    stage's first solve) on the stage's objective alone (:meth:`ObserverNLP.nlpsol_problem`): the
    ``Opti`` description sums all stages' objectives with one-hot weights, whose exact Hessian runs
    the whole squaring chain to ``k = 4096`` at every stage.  Measured on COMPleib DIS2 (n = 3, the
    sweep of ``benchmarks/results/sweep.md``): the same iterates; a J = 0 solve from a YT start (32
    iterations) 30 -> 18 ms CPU, its exact Hessian 0.31 -> 0.07 ms per iteration.
    """
    from ...backends.casadi_backend import ipopt_solver, run_solver, setup_error_report

    configure = not nlp.solver_ready
    opts = options
    cap = getattr(nlp, "solver_wall_time", None)
    if deadline.limit is not None:
        rem = deadline.remaining()
        wall = deadline.ipopt_options()["ipopt.max_wall_time"]
        user = options.get("ipopt.max_wall_time")
        if user is not None:
            wall = min(wall, float(user))
        if configure or cap is None or cap > rem + max(0.1 * deadline.limit, 0.05):
            configure, cap = True, wall
        opts = {**options, "ipopt.max_wall_time": cap}
    elif cap is not None:  # configured under an earlier budget: lift it
        configure, cap = True, None
    if configure:
        nlp.reset_solvers()
    key = nlp.stage_key
    solver = nlp.stage_solvers.get(key)
    if solver is None:
        try:
            solver = ipopt_solver(nlp.nlpsol_problem(), opts, name=f"{type(nlp).__name__}_{key}")
        except RuntimeError as exc:  # e.g. expand=True on an NLP with a linear solve
            return setup_error_report(exc)
        nlp.stage_solvers[key] = solver
    x0, p, lbg, ubg = nlp.numeric_start()
    rep = run_solver(solver, x0, p, lbg, ubg, lambda x: nlp.evaluator(x, p))
    nlp.solver_ready = True
    nlp.solver_wall_time = cap
    return rep


def stage_plan(nlp, objective: str, stages: tuple[int, ...] | None):
    """``(stages, set_stage, skip_after_two_failures)`` of one start (:meth:`ObserverNLP.continuation`).

    A start of the kappa2 objective that failed two stages runs only its last stage (once more, from
    the start: :func:`run_start`); the stages of a kappa2 bound are all tried (a bound too tight for
    the conservative order-64 surrogate may still be met at a higher order).
    """
    plan, set_stage = nlp.continuation(stages if objective == "kappa2" else None)
    return plan, set_stage, objective == "kappa2" or set_stage is None


def _report_fields(rep) -> tuple[Status, str, str, int, float]:
    """``(status, native status, message, iterations, time)`` of a SolverReport (Candidate's order)."""
    st = rep.stats
    return rep.status, st.native_status, rep.message, int(st.iterations or 0), float(st.time)


def solver_error_candidate(plant: Plant, rep, exc: Exception, stage: str) -> Candidate:
    """A failed candidate (NaN gain, status solver_error) for an iterate CasADi could not evaluate."""
    first = str(exc).strip().splitlines()
    why = first[-1] if first else repr(exc)
    _, native, message, iterations, time = _report_fields(rep)
    return Candidate(
        np.full((plant.n, plant.p), np.nan), None, None, Status.SOLVER_ERROR, native,
        f"{message}; the solution could not be evaluated ({type(exc).__name__}: {why[:200]})",
        iterations, time, stage=stage,
    )


def read_candidate(nlp, rep, stage: str) -> tuple[Candidate, bool]:
    """The candidate of one solve (gain and, if it can be read, the solver's eigenbasis) and
    whether the iterate could be evaluated at all; if not, a failed candidate (NaN gain, status
    solver_error) giving CasADi's reason (seen after e.g. a failed restoration phase)."""
    try:
        L = nlp.gain(rep.value)
    except RuntimeError as exc:
        return solver_error_candidate(nlp.plant, rep, exc, stage), False
    try:
        Z, zp = nlp.basis(rep.value)
    except (ValueError, np.linalg.LinAlgError, FloatingPointError, RuntimeError):
        Z, zp = None, None
    return Candidate(L, Z, zp, *_report_fields(rep), stage=stage), True


def run_start(
    nlp, L0: NDArray, objective: str, options: dict[str, Any], verified: Callable[[Candidate], bool],
    stages: tuple[int, ...] | None = None, deadline: Deadline | None = None, force: bool = False,
    final_only: bool = False,
) -> list[Candidate]:
    """Solve from one initial gain through the continuation stages; every stage's candidate.

    No stage is started once ``deadline`` has expired (the list may then be empty), except the
    first one with ``force`` (the first start of a design: IPOPT then gets at least 0.01 s).
    ``final_only``: the last stage only (a warm start from a converged design of a nearby problem).
    """
    deadline = Deadline.of(deadline)
    plan, set_stage, skip = stage_plan(nlp, objective, stages)
    if final_only:
        plan = plan[-1:]
    nlp.set_initial_gain(L0)
    history: list[Candidate] = []
    last_good = None
    todo = list(plan)
    while todo:
        J = todo.pop(0)
        if deadline.expired and (history or not force):
            break
        if J is not None:
            set_stage(J)
        if last_good is not None:
            nlp.warm_start(last_good)
        rep = solve_nlp(nlp, options, deadline)
        cand, _ = read_candidate(nlp, rep, type(nlp).__name__ + ("" if J is None else f" J={J}"))
        history.append(cand)
        if verified(cand):  # (a candidate CasADi could not evaluate has a NaN gain: it fails)
            last_good = nlp.snapshot(rep.value)
        elif last_good is None:
            if skip and len(history) >= 2:
                # two failed stages from this start: only its last stage, once, from the start (the
                # exact objective may converge where the smooth bounds did not: COMPleib HE1 at alpha
                # 0.75, zeta 0.8 reaches kappa2 50.24 there; giving up kept the start's own 725)
                todo = todo[-1:]
            nlp.set_initial_gain(L0)  # retry the next stage from the same start
    return history


def solve_starts(starts_list, runner, objective: str, evaluate: Evaluate, deadline: Deadline,
                 lower_bound: float | None = None, progress=None, first_index: int = 0,
                 ) -> tuple[list[StartRecord], list[Evaluated]]:
    """Run the starts ``(origin, L0, structure[, poles, warm])`` through ``runner(L0, structure, first,
    warm)`` (-> candidates); keep each start's best verified candidate.  No start after the first is
    begun once ``deadline`` has expired, nor once a design attains ``lower_bound`` (the
    objective's, :func:`~.evaluation.objective_lower_bound`).  Indices start at ``first_index``.
    ``starts_list`` may be a lazy iterable: a start is taken from it only when it is run."""
    records: list[StartRecord] = []
    evaluated: list[Evaluated] = []
    pending = iter(starts_list)
    for k in itertools.count():
        if k and (deadline.expired or any(attains(lower_bound, e[0], e[3], e[4]) for e in evaluated)):
            break
        spec = next(pending, None)
        if spec is None:
            break
        origin, L0, structure = spec[0], spec[1], spec[2]
        idx = first_index + k
        hist = runner(L0, structure, k == 0, bool(spec[4]) if len(spec) > 4 else False)
        if not hist:
            continue
        obj, m, v, cand = best_of_history(hist, objective, evaluate)
        message = cand.message + (f" [{cand.stage}]" if cand.stage else "")
        records.append(start_record(idx, origin, cand, m, v, obj, message))
        evaluated.append((obj, idx, m, v, cand))
        if progress is not None:
            progress.update(1, note=f"best {objective} {min(e[0] for e in evaluated):.6g}")
    return records, evaluated


def nlp_fixed_runner(get_nlp: Callable[[Any], Any], target: NDArray, objective: str, options: dict[str, Any],
                     verified: Callable[[Candidate], bool], deadline: Deadline):
    """``runner(L0, structure, first, warm)`` of fixed poles: the reduced NLP (``get_nlp(structure)``, its
    poles set to ``target``) through its continuation from ``L0`` (a warm start: its last stage)."""

    def runner(L0, st, first, warm=False):
        nlp = get_nlp(st)
        nlp.set_poles(target)
        return run_start(nlp, L0, objective, options, verified, deadline=deadline, force=first,
                         final_only=warm)

    return runner


def nlp_region_runner(plant: Plant, region: Region, objective: str, options: dict[str, Any],
                      get_fixed: Callable[[Any], Any], get_region: Callable[[Any], Any],
                      evaluate: Evaluate, deadline: Deadline, *, mask: NDArray | None,
                      lower_bound: float | None = None, polish: str = "full",
                      region_max_iter: int | None = None):
    """``runner(L0, structure, first, warm)`` of poles free in ``region``.

    Each start contributes (0) its own gain, unoptimized, (A) the fixed-pole NLP at the start's
    poles, (B) the free-pole NLP from the start (``get_region(structure)``), (C) the fixed-pole NLP
    at B's poles, from B's gain and from scipy's YT gain there -- each verified; the best is kept,
    so a design is never worse than its start (e.g. scipy YT at the naive poles).  ``polish="last"``
    (:data:`REGION_POLISHES`): no A, and the two C solves run the last stage of the continuation only.
    ``region_max_iter``: IPOPT's iterations per continuation stage of B (None: :data:`REGION_MAX_ITER`;
    the caller's ``ipopt.max_iter`` when lower).

    A warm start (a converged design of a nearby problem, e.g. the previous point of a sweep) runs
    only what it needs: no A (its gain is already the fixed-pole optimum at its own poles: the
    previous design's C), the last stage of B's continuation, the last stage of C from B's gain, and
    no YT gain.  A start stops as soon as one of its verified candidates attains ``lower_bound`` (the
    objective's, :func:`~.evaluation.objective_lower_bound`: a global optimum that nothing can beat)
    -- a warm start already at the bound runs no IPOPT at all.  ``evaluate`` should be memoized per
    solve (:func:`~.evaluation.cached_evaluate`): each candidate is checked here and again when the
    start's best is picked.
    """
    n = plant.n
    observable = plant.is_observable()
    rank_c = int(np.linalg.matrix_rank(plant.C))
    region_opts = dict(options)
    cap = REGION_MAX_ITER if region_max_iter is None else int(region_max_iter)
    region_opts["ipopt.max_iter"] = min(int(options.get("ipopt.max_iter", cap)), cap)
    light = polish == "last"

    def verified(c: Candidate) -> bool:
        return bool(evaluate(c)[1].passed)

    def optimal(cands: list[Candidate]) -> bool:
        """A verified candidate at the objective's lower bound: nothing else can beat it."""
        return lower_bound is not None and any(
            attains(lower_bound, metric_of(objective, m), v, c) for c in cands for m, v in [evaluate(c)])

    def fixed_at(poles_now, L0, final_only):
        """Fixed-pole optimization at given poles (inside the region), or [] if not applicable."""
        from ...errors import ValidationError
        from ...formulate.well_conditioned import PoleStructure

        try:
            P = as_poles("poles", poles_now, n)
        except ValidationError:
            return []
        _, counts = np.unique(np.round(P, 8), return_counts=True)
        if counts.max() > rank_c or (objective == "eta" and counts.max() > 1):
            return []
        nlp = get_fixed(PoleStructure.of(P))
        try:
            nlp.set_poles(P)
        except ValidationError:
            return []
        return run_start(nlp, L0, objective, options, verified, deadline=deadline, final_only=final_only)

    def runner(L0, st, first, warm=False):
        P0 = np.linalg.eigvals(plant.A - L0 @ plant.C)
        raw = Candidate(np.asarray(L0, dtype=float), None, None, Status.SOLVED, "direct",
                        "the start's gain itself (not improved by IPOPT)", 0, 0.0, stage="start gain",
                        backend="start")
        hist = [raw]
        if optimal(hist):
            return hist
        if not (warm or light) and observable and region.contains(P0):
            hist += fixed_at(P0, L0, False)
            if optimal(hist):
                return hist
        # the free-pole NLP from the start itself, with the whole continuation: measured on COMPleib
        # AC6, starting it from the fixed-pole optimum (stages 9, 12 only) ended at kappa2 18.9,
        # from the placement start at 1.27
        hb = [] if deadline.expired else run_start(get_region(st), L0, objective, region_opts, verified,
                                                   stages=REGION_STAGES, deadline=deadline,
                                                   final_only=warm)
        hist += hb
        okb = [(metric_of(objective, m), c) for c in hb for m, v in [evaluate(c)] if v.passed]
        if okb and observable and not optimal(hb):
            cb = min(okb, key=lambda t: t[0])[1]
            Pb = np.linalg.eigvals(plant.A - cb.L @ plant.C)
            hist += fixed_at(Pb, cb.L, warm or light)
            yt = mask is None and not warm and not optimal(hist)
            Lyt = placement_start(plant, Pb, "YT") if yt else None
            if Lyt is not None:  # robust placement at the same poles may sit in a better basin
                hist += fixed_at(Pb, Lyt, light)
        return hist

    return runner
