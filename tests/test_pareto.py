"""Pareto fronts by epsilon-constraints: dominance, bounds respected, the analytic gain limit of a
2-state plant, figure, argument errors."""

from __future__ import annotations

import numpy as np
import pytest

from optdesign import Plant, problems
from optdesign.analysis import metrics
from optdesign.errors import NotObservableError, ValidationError
from optdesign.regions import Disk, HalfPlane
from optdesign.studies import nondominated, pareto, plot_pareto


def test_nondominated_by_hand():
    V = np.array([[1.0, 5.0], [2.0, 3.0], [2.0, 4.0], [3.0, 3.0], [1.0, 5.0], [np.nan, 0.0], [4.0, 1.0]])
    # row 2 is dominated by row 1, row 3 by row 1; rows 0 and 4 tie (neither dominates); nan rows never count
    assert nondominated(V).tolist() == [True, True, False, False, True, False, True]
    # the tolerance: a 1e-9 relative improvement is not a domination
    assert nondominated([[1.0, 1.0], [1.0 - 1e-9, 1.0]]).tolist() == [True, True]
    with pytest.raises(ValidationError, match="points, objectives"):
        nondominated([1.0, 2.0])


@pytest.fixture(scope="module")
def nn2_front():
    """COMPleib NN2 (A = [[0, 1], [-1, 0]], C = [0, 1]): kappa2 against the gain, poles in Re s <= -0.5."""
    plant = problems.load("compleib_nn2").plant
    region = HalfPlane(0.5) & Disk(0.0, 20.0)
    return plant, region, pareto(plant, region, ("kappa2", "gain_norm"), levels=3, starts=3)


def test_front_points_are_verified_and_respect_their_bounds(nn2_front):
    plant, region, front = nn2_front
    recs = front.table.records
    assert front.objectives == ("kappa2", "gain_norm") and len(front.levels["gain_norm"]) == 3
    ok = [i for i, r in enumerate(recs) if r["success"]]
    assert len(ok) >= 3, [r["status"] for r in recs]
    for i in ok:
        r, d = recs[i], front.designs[i]
        # recompute everything from the gain, independently of the solver
        X = plant.A - d.L @ plant.C
        assert region.contains(np.linalg.eigvals(X), tol=1e-6)
        assert metrics.kappa2(X) == pytest.approx(r["kappa2"], rel=1e-9)
        assert np.linalg.norm(d.L, 2) == pytest.approx(r["gain_norm"], rel=1e-9)
        if r["max_gain"] is not None:
            assert r["gain_norm"] <= r["max_gain"] * (1 + 1e-6)
        # analytic limit: trace(A - L C) = -l2 is the sum of the poles, <= -2 * 0.5, so ||L|| >= l2 >= 1
        assert r["gain_norm"] >= 1.0 - 1e-9


def test_front_is_a_trade_off(nn2_front):
    _, _, front = nn2_front
    pts = front.front()
    assert len(pts) >= 2
    gains = [p["gain_norm"] for p in pts]
    k2 = [p["kappa2"] for p in pts]
    assert gains == sorted(gains)
    assert all(a >= b - 1e-9 for a, b in zip(k2, k2[1:], strict=False))  # less gain, worse conditioning
    assert k2[0] > k2[-1] * (1 + 1e-4)  # a real trade-off, not one point
    # every successful point is either on the front or dominated by a front point
    V = front.values
    for i in np.where(np.all(np.isfinite(V), axis=1) & ~front.nondominated)[0]:
        assert any(np.all(V[j] <= V[i] * (1 + 1e-6)) for j in np.where(front.nondominated)[0])
    anchors = [r for r in front.table.records if r["anchor"] == "kappa2"]
    assert len(anchors) == 1 and anchors[0]["kappa2"] == pytest.approx(min(k2), rel=1e-6)


def test_front_figure_and_csv(nn2_front, tmp_path):
    _, _, front = nn2_front
    png = tmp_path / "front.png"
    front.plot(png)
    assert png.stat().st_size > 10_000
    csv = front.to_csv(tmp_path / "front.csv").read_text()
    assert csv.splitlines()[0].startswith("max_gain,") and "nondominated" in csv.splitlines()[0]
    with pytest.raises(ValidationError, match="x must be one of the front's objectives"):
        plot_pareto(front, x="eta")


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"objectives": ("kappa2",)}, "2 or 3 distinct names"),
        ({"objectives": ("kappa2", "kappa2")}, "2 or 3 distinct names"),
        ({"objectives": ("kappa2", "eta", "gain_norm", "kappa_fro")}, "2 or 3 distinct names"),
        ({"objectives": ("gain_norm", "kappa2")}, "first objective is minimized"),
        ({"objectives": ("kappa2", "kappa_fro")}, "'kappa_fro' cannot be bounded"),
        ({"levels": 0}, "levels must be an integer >= 1"),
        ({"ranges": {"eta": (1.0, 2.0)}}, "not a bounded objective"),
        ({"ranges": {"gain_norm": (2.0, 1.0)}}, "0 < lo <= hi"),
        ({"ranges": {"gain_norm": 3.0}}, "must be a pair"),
        ({"max_gain": 3.0}, "give max_gain only when gain_norm is not an objective"),
    ],
)
def test_pareto_argument_errors(kwargs, match):
    plant = problems.load("compleib_nn2").plant
    args = {"objectives": ("kappa2", "gain_norm")}
    args.update(kwargs)
    with pytest.raises(ValidationError, match=match):
        pareto(plant, HalfPlane(0.5), **args)


def test_pareto_rejects_bad_plants():
    with pytest.raises(ValidationError, match="plant must be an optdesign.Plant"):
        pareto(np.eye(2), HalfPlane(0.5))
    with pytest.raises(NotObservableError, match="unobservable"):
        pareto(Plant(np.diag([1.0, 2.0]), [[1.0, 0.0]]), HalfPlane(0.5), ("kappa2", "gain_norm"))
