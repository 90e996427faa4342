"""Model sets for robust design: constructors, what they cover, interior points, bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest

from optdesign import DimensionError, Plant, ValidationError
from optdesign.model.model_set import ModelSet, as_model_set, psd_sqrt

AIRCRAFT = dict(A=[[-0.313, 56.7, 0.0], [-0.0139, -0.426, 0.0], [0.0, 56.7, 0.0]], C=[[0.0, 0.0, 1.0]])


def aircraft(**kw) -> Plant:
    return Plant(AIRCRAFT["A"], AIRCRAFT["C"], **kw)


def test_vary_gives_the_corners_and_the_nominal():
    pl = aircraft()
    ms = ModelSet.vary(pl, [(0, 0), (1, 0), (1, 1)], 0.2)
    assert len(ms) == 9 and ms.kind == "polytope" and ms.nominal == 8 and ms.covers_convex_hull
    np.testing.assert_array_equal(ms[8].A, pl.A)
    corners = {
        tuple(np.round(m.A[[0, 1, 1], [0, 0, 1]] / pl.A[[0, 1, 1], [0, 0, 1]], 12)) for m in ms.plants[:8]
    }
    assert corners == {(a, b, c) for a in (0.8, 1.2) for b in (0.8, 1.2) for c in (0.8, 1.2)}
    assert "A[1,1]" in ms.label(0) and "(nominal)" in ms.label(8)
    np.testing.assert_allclose(ms.weights, np.full(9, 1 / 9))


def test_interior_points_of_a_box_stay_in_the_box():
    pl = aircraft()
    ms = ModelSet.vary(pl, [(0, 0), (1, 1)], 0.2)
    pts = ms.interior_points(50, 3)
    assert len(pts) == 50
    for q in pts:
        r = q.A[[0, 1], [0, 1]] / pl.A[[0, 1], [0, 1]]
        assert np.all(r >= 0.8 - 1e-12) and np.all(r <= 1.2 + 1e-12)
        np.testing.assert_array_equal(q.A[2], pl.A[2])  # the other entries are not varied
    # reproducible
    np.testing.assert_array_equal(ms.interior_points(3, 3)[0].A, ms.interior_points(3, 3)[0].A)


def test_combination_is_affine_in_the_vertex_data():
    rng = np.random.default_rng(1)
    verts = []
    for _ in range(3):
        F = rng.standard_normal((2, 2))
        verts.append(
            Plant(
                rng.standard_normal((3, 3)),
                rng.standard_normal((2, 3)),
                G=rng.standard_normal((3, 2)),
                Q=F @ F.T + np.eye(2),
                R=np.diag(rng.uniform(0.5, 2, 2)),
            )
        )
    ms = ModelSet.polytope(verts)
    th = np.array([0.2, 0.5, 0.3])
    c = ms.combination(th)
    np.testing.assert_allclose(c.A, sum(t * v.A for t, v in zip(th, verts, strict=True)), rtol=1e-14)
    Bw = sum(t * v.G @ psd_sqrt(v.Q) for t, v in zip(th, verts, strict=True))
    np.testing.assert_allclose(c.process_noise(), Bw @ Bw.T, rtol=1e-12)
    Dv = sum(t * psd_sqrt(v.R) for t, v in zip(th, verts, strict=True))
    np.testing.assert_allclose(c.R, Dv @ Dv, rtol=1e-12)
    # a vertex is its own combination
    np.testing.assert_allclose(ms.combination([0, 1, 0]).A, verts[1].A)
    assert len(ms.interior_points(4)) == 4
    with pytest.raises(ValidationError, match="theta must be 3 nonnegative numbers summing to 1"):
        ms.combination([0.5, 0.5, 0.5])


def test_sampled_set_and_the_affine_claim():
    def omo(theta):
        m, d = theta
        return Plant([[0, 1], [-1000 / m, -d / m]], [[1, 0]])

    ms = ModelSet.sample(omo, {"m": (0.9, 1.1), "d": (8, 12)})
    assert len(ms) == 5 and ms.kind == "sampled" and not ms.covers_convex_hull
    np.testing.assert_allclose(ms.parameters[-1], [1.0, 10.0])
    assert len(ms.interior_points(5)) == 5
    with pytest.raises(ValidationError, match="not affine in theta"):
        ModelSet.sample(omo, {"m": (0.9, 1.1), "d": (8, 12)}, affine=True)

    def lin(theta):
        return Plant([[0, 1], [-1000 * theta[0], -theta[1]]], [[1, 0]])

    assert ModelSet.sample(lin, [(0.9, 1.1), (8, 12)], affine=True).kind == "polytope"
    grid = ModelSet.sample(lin, [(0.9, 1.1), (10, 10)], grid=3, samples=2, include_nominal=False, seed=4)
    assert len(grid) == 11 and grid.nominal is None


def test_state_space_systems_are_accepted():
    control = pytest.importorskip("control")
    ms = ModelSet([control.ss(AIRCRAFT["A"], [[0.232], [0.0203], [0.0]], AIRCRAFT["C"], 0), aircraft()])
    assert all(isinstance(pl, Plant) for pl in ms) and ms.n == 3
    np.testing.assert_array_equal(ms[0].A, ms[1].A)


def test_list_of_operating_points_has_no_interior():
    a, b = aircraft(name="a"), aircraft(name="b")
    ms = as_model_set([a, b], weights=[1, 3])
    np.testing.assert_allclose(ms.weights, [0.25, 0.75])
    assert ms.interior_points(10) == [] and ms.kind == "list"
    assert as_model_set(ms) is ms
    assert len(as_model_set(a)) == 1
    assert "2 models" in repr(ms)
    assert math.isclose(float(as_model_set(ms, [1, 1]).weights[0]), 0.5)


@pytest.mark.parametrize(
    ("models", "kwargs", "err", "match"),
    [
        ([], {}, ValidationError, "at least one Plant"),
        (
            [1.0],
            {},
            ValidationError,
            r"models\[0\] must be an optdesign.Plant or a state-space system; found float",
        ),
        (42, {}, ValidationError, "must be a sequence of optdesign.Plant; found int"),
        ("mixed_n", {}, DimensionError, r"same n \(states\): models\[0\] has 3, models\[1\] has 2"),
        ("mixed_dt", {}, ValidationError, "same time domain"),
        ("mixed_noise", {}, ValidationError, "either every model has a noise model"),
        ("ok", {"weights": [1, 2, 3]}, DimensionError, "weights has the wrong length: expected 2"),
        (
            "ok",
            {"weights": [1, -1]},
            ValidationError,
            "weights must be finite and > 0; found -1.0 at index 1",
        ),
        ("ok", {"weights": "ab"}, ValidationError, "weights must be a 1-D sequence"),
        ("ok", {"kind": "cloud"}, ValidationError, "kind must be one of"),
        ("ok", {"nominal": 5}, ValidationError, r"nominal must be a model index in \[0, 1\]; found 5"),
        ("ok", {"kind": "sampled"}, ValidationError, "a sampled model set needs its function"),
    ],
)
def test_model_set_errors(models, kwargs, err, match):
    pl = aircraft()
    cases = {
        "mixed_n": [pl, Plant([[0, 1], [-1, -1]], [[1, 0]])],
        "mixed_dt": [pl, aircraft(dt=0.1)],
        "mixed_noise": [pl, aircraft(Q=np.eye(3), R=[[1]])],
        "ok": [pl, pl],
    }
    with pytest.raises(err, match=match):
        ModelSet(cases.get(models, models) if isinstance(models, str) else models, **kwargs)


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda pl: ModelSet.vary(1.0, [(0, 0)], 0.1), "plant must be an optdesign.Plant"),
        (lambda pl: ModelSet.vary(pl, [(0, 0)], 0.1, matrix="B"), "matrix must be 'A' or 'C'"),
        (lambda pl: ModelSet.vary(pl, [], 0.1), "at least one"),
        (lambda pl: ModelSet.vary(pl, [(0, 0), (0, 0)], 0.1), "must not repeat"),
        (
            lambda pl: ModelSet.vary(pl, [(5, 0)], 0.1),
            r"entry \(5, 0\) is outside A, which has shape \(3, 3\)",
        ),
        (lambda pl: ModelSet.vary(pl, [0], 0.1), "entries must be a sequence of"),
        (lambda pl: ModelSet.vary(pl, [(0, 0)], -0.1), "size must be finite and >= 0"),
        (lambda pl: ModelSet.sample(3, [(0, 1)]), "function must be callable"),
        (lambda pl: ModelSet.sample(lambda t: pl, []), "at least one parameter"),
        (lambda pl: ModelSet.sample(lambda t: pl, [(1, 0)]), "finite lo <= hi"),
        (lambda pl: ModelSet.sample(lambda t: pl, [(0,)]), r"must be a pair \(lo, hi\)"),
        (lambda pl: ModelSet.sample(lambda t: pl, 5), "ranges must be a mapping"),
        (lambda pl: ModelSet.sample(lambda t: 1, [(0, 1)]), "must return an optdesign.Plant; found int"),
        (lambda pl: ModelSet.sample(lambda t: pl, [(0, 1)], grid=1), "grid must be an integer >= 2"),
        (
            lambda pl: ModelSet.sample(lambda t: pl, [(0, 1)], grid=None, include_nominal=False),
            "at least one model",
        ),
        (lambda pl: ModelSet.sample(lambda t: pl, [(0, 1)], grid=3, affine=True), "affine=True needs grid=2"),
        (lambda pl: ModelSet([pl]).interior_points(-1), "count must be an integer >= 0"),
    ],
)
def test_constructor_errors(call, match):
    with pytest.raises(ValidationError, match=match):
        call(aircraft())
