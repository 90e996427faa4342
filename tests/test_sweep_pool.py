"""The sweep designer's pool of local optima (placement="pool") and the problem's several warm starts
(``WellConditionedProblem.solve(warm_starts=...)``, ``extra["local_optima"]``)."""

from __future__ import annotations

import numpy as np
import pytest

from optdesign import problems
from optdesign.design.well_conditioned import WellConditionedProblem
from optdesign.design.well_conditioned.problem import LocalOptimum, warm_start_origin
from optdesign.errors import ValidationError
from optdesign.regions import Disk, HalfPlane, Sector
from optdesign.studies import RegionSweepDesigner
from optdesign.studies.designers import clear_cache, merge_pool

RADIUS = 20.0


def _region(alpha: float, zeta: float):
    return HalfPlane(alpha) & Sector.from_damping(zeta) & Disk(0.0, RADIUS)


@pytest.fixture(scope="module")
def dis2():
    return problems.load("compleib_dis2").plant


def test_warm_start_origins():
    assert [warm_start_origin(i) for i in range(3)] == ["warm start", "warm start 2", "warm start 3"]


def test_solve_runs_every_warm_start_and_a_later_one_can_win(dis2):
    """At (alpha 0.5, zeta 0.9) the two placement starts end in two basins (kappa2 1.013 and the lower
    bound 1); given back as warm starts at the next point, worse basin first, both run in order, each
    verified, and the second one's answer is the design -- it fails if ``warm_starts`` is not run."""
    prob = WellConditionedProblem(dis2, route="nlp", kalman_start=False, pole_scale=RADIUS,
                                  region_polish="last", starts=2)
    first = prob.solve(region=_region(0.5, 0.9), seed=0)
    opt = first.extra["local_optima"]
    assert all(isinstance(o, LocalOptimum) for o in opt) and len(opt) == 2
    assert opt[0].objective <= opt[1].objective * (1 - 1e-3)  # two basins
    assert opt[0].objective == pytest.approx(first.kappa2, rel=1e-12)
    assert not opt[0].L.flags.writeable
    nxt = prob.solve(region=_region(0.5, 0.871), warm_start=opt[1].L, warm_starts=[opt[0].L], starts=0)
    assert nxt.success
    assert [r.origin for r in nxt.starts] == ["warm start", "warm start 2"]
    assert all(r.verified for r in nxt.starts)
    best = nxt.solver_stats.extra["best_start"]
    assert [r.origin for r in nxt.starts if r.index == best] == ["warm start 2"]
    assert nxt.kappa2 < nxt.starts[0].kappa2 * (1 - 1e-3)
    assert [o.objective for o in nxt.extra["local_optima"]] == sorted(r.objective for r in nxt.starts)


def test_a_warm_start_without_a_finite_gain_is_skipped(dis2):
    prob = WellConditionedProblem(dis2, route="nlp", kalman_start=False, pole_scale=RADIUS,
                                  region_polish="last", starts=1)
    first = prob.solve(region=_region(1.0, 0.5), seed=0)
    res = prob.solve(region=_region(1.0, 0.5), warm_start=np.full((3, 2), np.nan), warm_starts=[first],
                     starts=0)
    assert [r.origin for r in res.starts] == ["warm start"]
    assert res.kappa2 <= first.kappa2 * (1 + 1e-9)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"region": _region(1.0, 0.5), "warm_starts": np.zeros((3, 2))},
         "warm_starts must be a sequence of designs or gains .*; found ndarray"),
        ({"region": _region(1.0, 0.5), "warm_starts": "L"},
         "warm_starts must be a sequence of designs or gains .*; found str"),
        ({"poles": [-1, -2, -3], "warm_starts": [np.zeros((3, 2))]},
         "warm_starts applies to region mode only .*; found 1 warm starts with fixed poles"),
        ({"region": _region(1.0, 0.5), "warm_starts": [np.zeros((2, 2))]},
         r"warm_start gain must have shape \(3, 2\); found \(2, 2\)"),
    ],
)
def test_warm_starts_errors(dis2, kwargs, match):
    prob = WellConditionedProblem(dis2, route="nlp", starts=1)
    with pytest.raises(ValidationError, match=match):
        prob.solve(**kwargs)


def test_merge_pool_dedupes_and_carries_what_did_not_run(dis2):
    """Copies of one optimum (relative gain distance <= rtol) merge; a warm start that did not run at the
    point (it ended early) is carried on behind the point's answers; the pool is capped."""
    prob = WellConditionedProblem(dis2, route="nlp", kalman_start=False, pole_scale=RADIUS,
                                  region_polish="last", starts=2)
    res = prob.solve(region=_region(0.5, 0.9), seed=0)  # no warm start: both placement starts ran
    a, b = (o.L for o in res.extra["local_optima"])
    near = a * (1 + 1e-6)
    other = np.arange(6.0).reshape(3, 2)
    pool = merge_pool(res, [(2.0, near), (3.0, other)], 5, 1e-3)
    # res.L == a; a and b found; 'near' is a copy of a; 'other' (warm start 2) did not run: carried
    assert len(pool) == 3
    np.testing.assert_array_equal(pool[0][1], a)
    np.testing.assert_array_equal(pool[1][1], b)
    np.testing.assert_array_equal(pool[2][1], other)
    assert pool[0][0] == pytest.approx(res.kappa2, rel=1e-12) and pool[2][0] == 3.0
    assert len(merge_pool(res, [(2.0, near), (3.0, other)], 2, 1e-3)) == 2
    assert len(merge_pool(res, [], 5, 1e-3)) == 2


@pytest.mark.parametrize(
    ("args", "match"),
    [((0, 1e-3), "size must be an integer >= 1"), ((2, -1.0), "rtol must be"),
     ((2, 1e-3, float("nan")), "objective_rtol must be")],
)
def test_merge_pool_errors(dis2, args, match):
    prob = WellConditionedProblem(dis2, route="nlp", kalman_start=False, pole_scale=RADIUS, starts=1)
    res = prob.solve(region=_region(1.0, 0.5), seed=0)
    with pytest.raises(ValidationError, match=match):
        merge_pool(res, [], *args)


ALPHA = float(np.linspace(0.5, 3.0, 40)[20])  # the block of benchmarks/results/sweep.md
ZETAS = [float(z) for z in np.linspace(0.9, 0.2, 25)[:4]]


def test_pool_carries_every_start_to_the_next_point():
    """DIS2, alpha 1.78: at the first point both placement starts end at one optimum (the pool
    collapsed: the placement starts run again at the second point); there they end in two basins, and
    at the third point both are warm-started and no placement start runs -- with the previous design
    alone the pool would be stale and the placement starts would run."""
    clear_cache()
    chunk = RegionSweepDesigner(problem="compleib_dis2", radius=RADIUS, placement="pool").start_chunk()
    p0 = chunk(alpha=ALPHA, zeta=ZETAS[0])
    assert p0.success and p0.solver_stats.extra["pool"] == 1
    p1 = chunk(alpha=ALPHA, zeta=ZETAS[1])
    assert p1.success and "naive poles + YT" in [r.origin for r in p1.starts]
    assert p1.solver_stats.extra["pool"] == 2
    p2 = chunk(alpha=ALPHA, zeta=ZETAS[2])
    assert p2.success and p2.verification.passed
    assert [r.origin for r in p2.starts] == ["warm start", "warm start 2"]
    assert all(r.verified for r in p2.starts)


def test_merge_pool_merges_answers_with_one_objective_value(dis2):
    """Two answers of one point with the same kappa2 (to objective_rtol) are one optimum (mirror images);
    with objective_rtol = 0 both are kept."""
    prob = WellConditionedProblem(dis2, route="nlp", kalman_start=False, pole_scale=RADIUS,
                                  region_polish="last", starts=2)
    seed = RegionSweepDesigner(problem="compleib_dis2", radius=RADIUS).seed_for(alpha=0.5, zeta=0.9)
    res = prob.solve(region=_region(0.5, 0.9), seed=seed)
    a, b = (o.objective for o in res.extra["local_optima"])
    assert a == pytest.approx(b, rel=1e-9)
    assert len(merge_pool(res, [], 5, 1e-3, 0.0)) == 2
    assert len(merge_pool(res, [], 5, 1e-3, 1e-8)) == 1


def test_pool_equals_placement_always_on_a_short_chunk():
    """alpha 1.78, zeta 0.9 .. 0.81 (the start of sweep.md's block): the pool (placement starts at the
    first point and when it collapsed, the second) reaches the kappa2 of placement="always" (the
    previous design + the placement starts at every point) at every point with fewer IPOPT
    iterations."""
    clear_cache()
    pool = RegionSweepDesigner(problem="compleib_dis2", radius=RADIUS, placement="pool").start_chunk()
    ref = RegionSweepDesigner(problem="compleib_dis2", radius=RADIUS, placement="always").start_chunk()
    kp, kr, ip, ir = [], [], 0, 0
    for z in ZETAS:
        a, b = pool(alpha=ALPHA, zeta=z), ref(alpha=ALPHA, zeta=z)
        assert a.success and b.success
        kp.append(a.kappa2)
        kr.append(b.kappa2)
        ip += a.solver_stats.iterations
        ir += b.solver_stats.iterations
    np.testing.assert_allclose(kp, kr, rtol=1e-6)
    assert ip < ir


def test_pool_leaves_out_a_starts_unimproved_gain():
    """COMPleib HE1, alpha 0.75: at zeta 0.8 a start whose NLP stages all fail answers with its own gain
    (stage "start gain"); that is not a local optimum, so it is not in ``extra["local_optima"]`` nor in
    the pool.  With it the pool looked like two optima, the placement starts did not run again at zeta
    0.6 and the chunk stayed at kappa2 43.5 (then 39.7); without it they run and reach 26.16, the kappa2
    of placement="always" there."""
    chunk = RegionSweepDesigner(problem="compleib_he1", objective="kappa2", radius=10.0, starts=2,
                                placement="pool").start_chunk()
    first = chunk(alpha=0.75, zeta=0.8)
    assert first.success
    unimproved = {r.index for r in first.starts if r.message.endswith("[start gain]")}
    assert {o.index for o in first.extra["local_optima"]}.isdisjoint(unimproved)
    second = chunk(alpha=0.75, zeta=0.6)
    assert second.success and second.kappa2 < 30.0


def test_local_optima_are_improved_verified_answers():
    """``local_optima``: verified, finite answers best first; a failed answer is left out, and so is a
    start's own unimproved gain (stage "start gain") unless it attains the objective's lower bound (a
    global optimum)."""
    from optdesign.design.well_conditioned.evaluation import Candidate
    from optdesign.design.well_conditioned.problem import local_optima
    from optdesign.results import Check, Status, Verification

    passed = Verification.of([Check.at_most("x", 0.0, 1.0)])
    failed = Verification.of([Check.at_most("x", 2.0, 1.0)])

    def cand(v, stage):
        return Candidate(np.full((2, 1), v), None, None, Status.OPTIMAL, "", "", 0, 0.0, stage=stage)

    evaluated = [(3.0, 0, {}, passed, cand(3.0, "RegionNLP J=12")),
                 (1.5, 1, {}, passed, cand(1.5, "start gain")),
                 (2.0, 2, {}, passed, cand(2.0, "FixedPoleNLP J=12")),
                 (1.0, 3, {}, failed, cand(1.0, "x"))]
    assert [(o.objective, o.index) for o in local_optima(evaluated)] == [(2.0, 2), (3.0, 0)]
    at_bound = evaluated + [(1.0, 4, {}, passed, cand(1.0, "start gain"))]
    assert [o.index for o in local_optima(at_bound, bound=1.0)] == [4, 2, 0]
    assert [o.index for o in local_optima(at_bound)] == [2, 0]
