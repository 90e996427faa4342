"""One output and poles free in a region: when no pole set tried is placeable, IPOPT's fallback is not run.

With one output the poles fix the observer gain (``L`` is unique for each pole set), so a design is a
choice of poles alone.  When the engine gives no verified design and the gain placing each pole set
tried in the region -- the region starts' own and :data:`ONE_OUTPUT_SAMPLES` more sampled in it --
has its computed poles (numpy) outside the region, the design answers ``not_found`` at once with
those gains and their failed checks, instead of running IPOPT's fallback from every start.

Measured (issue 28): COMPleib REA4 (n = 8, eight unstable modes near 0.6, observability matrix's
singular values 1.9 to 3.4e-8) took 85-104 s to ``not_found`` with kappa2 (IPOPT from 8 starts, each
to its iteration limit, none in the region); random one-output plants with weakly observable
unstable modes the same (``benchmarks/results/region.md``, round 17).  This is local evidence, not a
certificate: the status stays ``not_found`` (feasibility unknown) and ``route="nlp"`` still runs IPOPT.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from ...model.plant import Plant
from ...model.regions import Region
from ...results import Status
from .evaluation import Candidate, Evaluated, metric_of, start_record
from .results import StartRecord
from .route import IPOPT, Phase
from .starts import placement_start, start_real_count

__all__ = ["ONE_OUTPUT_SAMPLES", "PLACEMENT_CHECK", "unplaced_one_output"]

#: stage name of the check
PLACEMENT_CHECK = "scipy_yt/one_output"

#: pole sets sampled in the region beyond the starts' own before a one-output design skips IPOPT's
#: fallback (:func:`unplaced_one_output`); each costs one scipy YT placement and one evaluation
ONE_OUTPUT_SAMPLES = 24


def unplaced_one_output(plant: Plant, region: Region, objective: str, specs: Sequence[tuple],
                        rng: np.random.Generator, evaluate: Callable[[Candidate], Any], first: int,
                        samples: int = ONE_OUTPUT_SAMPLES
                        ) -> tuple[list[StartRecord], list[Evaluated], list[Phase]] | None:
    """The gains of the pole sets tried, when none puts its poles in ``region``; else None.

    Parameters
    ----------
    plant : Plant
        ``A`` (n, n), ``C`` (1, n); None is returned at once for more than one output.
    region : Region
    objective : str
        The design's objective (each record's value).
    specs : sequence of (origin, L0, structure, poles)
        The region starts (:func:`~.starts.iter_region_starts`): the gain of each whose ``poles``
        lie in the region is tried (a Kalman start's poles are those of its own gain).
    rng : numpy.random.Generator
        Draws the ``samples`` more pole sets (:meth:`Region.sample_poles`, the real/complex
        patterns of :func:`~.starts.start_real_count`), each placed by scipy YT.
    evaluate : callable
        The design's independent checks (:func:`~.evaluation.evaluate_candidate`).
    first : int
        Start index of the first record.

    Returns
    -------
    (records, evaluated, phases) or None
        The tried gains (stage ``"start gain"``; each message says why IPOPT did not run), the one
        whose poles come closest to the region first (the answer when their objectives tie), and the
        route's phases (the check, IPOPT's fallback skipped).  None when a tried gain passes the
        ``region_margin`` check (or with more than one output): then IPOPT's fallback runs as before.
    """
    if plant.p != 1:
        return None
    t0 = time.perf_counter()
    tried = [(o, L0) for o, L0, _, P0 in specs if region.contains(P0)]
    for k in range(samples):
        P = region.sample_poles(plant.n, rng, n_real=start_real_count(plant.n, k))
        L = placement_start(plant, P, "YT")
        if L is not None:
            tried.append(("region sample + YT (one output)", L))
    if not tried:
        return None
    checked = []
    for origin, L in tried:
        cand = Candidate(np.asarray(L, dtype=float), None, None, Status.SOLVED, "direct", "", 0, 0.0,
                         stage="start gain", backend="start")
        m, v = evaluate(cand)
        if v["region_margin"].passed:
            return None
        checked.append((origin, cand, m, v))
    checked.sort(key=lambda c: float(c[3]["region_margin"].value))  # the closest to the region first
    margin = float(checked[0][3]["region_margin"].value)
    reason = (f"one output (the poles fix the gain): none of the {len(tried)} pole sets tried in the region "
              f"gives a gain whose computed poles lie in it (smallest region margin {margin:.3g}), so "
              "IPOPT's fallback was not run (route='nlp' runs it)")
    records: list[StartRecord] = []
    evaluated: list[Evaluated] = []
    each = (time.perf_counter() - t0) / len(checked)
    for i, (origin, cand, m, v) in enumerate(checked):
        cand.message, cand.time = f"the placed gain: {reason}", each
        obj = metric_of(objective, m)
        records.append(start_record(first + i, origin, cand, m, v, obj, cand.message))
        evaluated.append((obj, first + i, m, v, cand))
    phases = [Phase(PLACEMENT_CHECK, "check", first, first + len(checked), f"{len(checked)} pole sets"),
              Phase(IPOPT, "fallback", first + len(checked), first + len(checked), "not run: one output, "
                    "no pole set tried placeable in the region")]
    return records, evaluated, phases
