"""One output, poles free in a region: IPOPT's fallback is not run when no pole set tried is placeable
(``optdesign.design.well_conditioned.one_output``; issue 28, round 17)."""

from __future__ import annotations

import numpy as np
import pytest

from optdesign import Plant, Status, problems, well_conditioned_observer
from optdesign.design.well_conditioned import problem as wcp
from optdesign.design.well_conditioned import suggested_region
from optdesign.design.well_conditioned.evaluation import Candidate, cached_evaluate, evaluate_candidate, rank_key
from optdesign.design.well_conditioned.one_output import ONE_OUTPUT_SAMPLES, unplaced_one_output
from optdesign.design.well_conditioned.starts import region_starts
from optdesign.results import Check, Verification


def _no_ipopt(*args, **kwargs):
    raise AssertionError("IPOPT ran on a one-output region no tried pole set reaches")


@pytest.mark.parametrize("objective", ["kappa2", "eta"])
def test_rea4_answers_not_found_without_ipopt(monkeypatch, objective):
    """COMPleib REA4 (n = 8, one output, eight unstable modes weakly observable together): kappa2 took
    85-104 s to the same ``not_found`` through IPOPT's fallback from 8 starts.  Now no IPOPT runs, the
    answer names the failed checks of a finite gain, and the route says why IPOPT was skipped."""
    monkeypatch.setattr(wcp, "solve_starts", _no_ipopt)
    plant = problems.load("compleib_rea4").plant
    region = suggested_region(plant)
    d = well_conditioned_observer(plant, region=region, objective=objective)
    assert d.status is Status.NOT_FOUND and not d.success and d.certificate is None
    assert "feasibility unknown" in d.message and "one output (the poles fix the gain)" in d.message
    assert not d.verification["region_margin"].passed and "region_margin" in d.message
    assert np.all(np.isfinite(d.L))  # a gain to look at: the closest of those tried, not the engine's nan
    margin = region.margin(np.linalg.eigvals(plant.A - d.L @ plant.C))
    assert margin > 0 and f"smallest region margin {margin:.3g}" in d.message  # really outside
    kinds = [(s.kind, s.outcome) for s in d.route]
    assert kinds == [("engine", "failed"), ("check", "rejected"), ("fallback", "skipped")]
    n_region = sum(1 for r in d.starts if r.origin.startswith(("naive", "region sample")))
    assert n_region >= ONE_OUTPUT_SAMPLES  # the starts' own pole sets and the samples were tried


def _evaluate(plant, region):
    return cached_evaluate(lambda c: evaluate_candidate(plant, c, target=None, region=region, mask=None,
                                                             max_gain=None, kappa2_max=None, eta_max=None))


def test_unplaced_one_output_is_none_when_a_pole_set_is_placeable_or_with_more_outputs():
    easy = Plant([[0.0, 1.0], [-6.0, -5.0]], [[1.0, 0.0]])
    region = suggested_region(easy)
    specs = region_starts(easy, region, 4, np.random.default_rng(0), None)
    assert unplaced_one_output(easy, region, "kappa2", specs, np.random.default_rng(1),
                               _evaluate(easy, region), 4) is None
    two = Plant(easy.A, np.eye(2))
    assert unplaced_one_output(two, region, "kappa2", specs, np.random.default_rng(1),
                               _evaluate(two, region), 4) is None


def test_unplaced_one_output_numbers_its_records_after_the_engine():
    plant = problems.load("compleib_rea4").plant
    region = suggested_region(plant)
    specs = region_starts(plant, region, 3, np.random.default_rng(0), None)
    out = unplaced_one_output(plant, region, "kappa2", specs, np.random.default_rng(1),
                              _evaluate(plant, region), 5, samples=2)
    assert out is not None
    records, evaluated, phases = out
    # start 0 (naive poles) and start 2 (a sample) have their poles in the region, the Kalman start not
    assert [r.index for r in records] == [5, 6, 7, 8] == [e[1] for e in evaluated]
    assert sorted(r.origin for r in records) == ["naive poles + YT", "region sample + YT",
                                                 "region sample + YT (one output)",
                                                 "region sample + YT (one output)"]
    margins = [e[3]["region_margin"].value for e in evaluated]
    assert margins == sorted(margins) and margins[0] > 0  # the closest to the region first
    assert (phases[0].first, phases[0].stop, phases[1].first, phases[1].stop) == (5, 9, 9, 9)
    assert all(not e[3].passed and not e[3]["region_margin"].passed for e in evaluated)


def test_a_one_output_fallback_still_runs_when_a_tried_pole_set_is_placeable(monkeypatch):
    """The engine's designs rejected (forced here) on a plant whose region YT reaches: IPOPT's fallback
    runs as before."""
    calls = []
    real_engine, real_solve = wcp.engine_region, wcp.solve_starts

    def failing_engine(*args, **kwargs):
        records, evaluated = real_engine(*args, **kwargs)
        bad = Verification.of([Check.at_most("forced", 1.0, 0.0)])
        return records, [(e[0], e[1], e[2], bad, e[4]) for e in evaluated]

    def spy(*args, **kwargs):
        calls.append(1)
        return real_solve(*args, **kwargs)

    monkeypatch.setattr(wcp, "engine_region", failing_engine)
    monkeypatch.setattr(wcp, "solve_starts", spy)
    plant = Plant([[0.0, 1.0], [-6.0, -5.0]], [[1.0, 0.0]])
    d = well_conditioned_observer(plant, region=suggested_region(plant), starts=2)
    assert calls and d.success
    assert [s.kind for s in d.route] == ["engine", "fallback"]


def test_rank_key_prefers_a_finite_gain_among_unverified_designs():
    bad = Verification.of([Check.at_most("x", 1.0, 0.0)])

    def cand(L):
        return Candidate(np.asarray(L, dtype=float), None, None, Status.SOLVED, "", "", 0, 0.0)

    nan, finite = cand([[np.nan]]), cand([[1.0]])
    assert rank_key(float("inf"), bad, finite, 9) < rank_key(float("inf"), bad, nan, 0)
    assert rank_key(5.0, bad, finite, 0) < rank_key(1.0, bad, nan, 0)
