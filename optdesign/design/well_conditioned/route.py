"""The route trace of the well-conditioned designs (:class:`~optdesign.results.Route`): which phases ran
-- the placement engine (fixed poles or a region), IPOPT, a fallback, a polish -- and which one produced
the answer.

A design runs its starts in phases; each phase covers a contiguous range of start indices
(:class:`Phase`).  :func:`route_of` turns the phases and the evaluated starts into the result's route:
the phase holding the returned start is ``answered``; the others say how they ended (their best
verified start's status, ``unchanged`` for a polish that did not improve, ``rejected`` when none of
their designs passed the independent checks, ``skipped`` when they ran no start).  Also when IPOPT runs
after the engine (:func:`needs_fallback`) and what its stage says why (:func:`nlp_detail`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..._deadline import Deadline
from ...results import Route, Stage, Status
from .evaluation import Evaluated

__all__ = ["Phase", "route_of", "ENGINE_FIXED", "ENGINE_REGION", "IPOPT", "proof_route", "needs_fallback",
           "nlp_detail"]

#: stage names of the phases
ENGINE_FIXED = "eigenstructure_engine/fixed_poles"
ENGINE_REGION = "eigenstructure_engine/region"
IPOPT = "ipopt"


@dataclass(frozen=True)
class Phase:
    """One phase of a design: ``name`` and ``kind`` of its :class:`~optdesign.results.Stage`, the
    start indices ``first <= index < stop`` it ran, and a short ``detail``."""

    name: str
    kind: str
    first: int
    stop: int
    detail: str = ""


def route_of(phases: list[Phase], evaluated: list[Evaluated], best_index: int | None,
             answered: bool) -> Route:
    """The route of a multi-start design.

    Parameters
    ----------
    phases : list of Phase
        In the order they ran.
    evaluated : list of (objective, index, metrics, Verification, Candidate)
    best_index : int or None
        The start index of the returned design.
    answered : bool
        The design has a verified answer (else no stage is ``answered``).

    Returns
    -------
    Route
    """
    stages = []
    for ph in phases:
        mine = [e for e in evaluated if ph.first <= e[1] < ph.stop]
        secs = float(sum(e[4].time for e in mine))
        detail = ph.detail or f"{len(mine)} start{'s' if len(mine) != 1 else ''}"
        if answered and best_index is not None and ph.first <= best_index < ph.stop:
            outcome = "answered"
        elif not mine:
            outcome = "skipped"
        else:
            good = [e for e in mine if e[3].passed]
            if good and ph.kind == "polish":
                outcome = "unchanged"
            elif good:
                outcome = Status(min(good, key=lambda e: e[0])[4].status).value
            elif any(np.all(np.isfinite(e[4].L)) for e in mine):
                outcome = "rejected"
            else:
                outcome = "failed"
        stages.append(Stage(ph.name, ph.kind, outcome, detail, secs))
    return Route(stages)


def proof_route(name: str) -> Route:
    """The route of an answer from a proof (``infeasible`` before any solver ran)."""
    return Route([Stage(name, "certificate", "infeasible")])


def needs_fallback(evaluated: list[Evaluated], deadline: Deadline) -> bool:
    """The NLP route after the engine: when no engine start verified -- with time left, or without a
    single finite gain to answer with (the NLP route's first start always runs, as the verb promises)."""
    if any(e[3].passed for e in evaluated):
        return False
    return not deadline.expired or not any(np.all(np.isfinite(e[4].L)) for e in evaluated)


def nlp_detail(asked: bool, mask: NDArray | None, bounds: dict[str, float | None]) -> str:
    """Why the NLP ran: the constraints the engine does not take, or a fallback."""
    if not asked:
        return "fallback: no engine design verified"
    why = [k for k, v in bounds.items() if v is not None] + (["gain_mask"] if mask is not None else [])
    return ("for " + ", ".join(why)) if why else "asked (route='nlp')"
