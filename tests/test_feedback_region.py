"""State feedback with poles free in a region, on its own measure (issue 27, item 3).

``well_conditioned_feedback(plant, region=...)`` minimizes cond(X) of the unit-column RIGHT
eigenvectors X of A - B K (scipy's ``X``), as fixed-pole controller mode does, starting from the
dual route's design (the observer of (A', B'), which minimizes the left eigenvectors' condition):
its cond(X) is never worse than the dual route's.  Every expectation below is recomputed with numpy
on A - B K, independently of the library's verification.
"""

from __future__ import annotations

import numpy as np
import pytest

from optdesign import Plant
from optdesign.design.feedback import (
    CONTROLLER_MODE,
    DUAL_MODE,
    dual_plant,
    well_conditioned_feedback,
)
from optdesign.design.well_conditioned import suggested_region, well_conditioned_observer
from optdesign.engines.eigenstructure import EigenstructureEngine, FixedPoleModel
from optdesign.engines.eigenstructure_region import RegionModel, RegionStart, place_region
from optdesign.errors import ValidationError
from optdesign.regions import Disk, HalfPlane, Sector

_EPS = np.finfo(float).eps


def cond_x(F: np.ndarray) -> float:
    """cond(X) of numpy's unit-column right eigenvectors of F (scipy's measure)."""
    _, X = np.linalg.eig(F)
    return float(np.linalg.cond(X / np.linalg.norm(X, axis=0)))


def random_plant(seed: int, n: int, m: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    return rng.standard_normal((n, n)) / np.sqrt(n), rng.standard_normal((n, m))


def dual_route_gain(A: np.ndarray, B: np.ndarray, region, dt: float | None = None, **kw) -> np.ndarray:
    """The gain of the dual route (today's answer before issue 27 item 3): K = L' of the observer of
    (A', B')."""
    obs = well_conditioned_observer(dual_plant(A, B, dt=dt), region=region, **kw)
    assert obs.success, obs.message
    return np.asarray(obs.L).T


def region_tolerance(region, poles: np.ndarray) -> float:
    """The verification's rule, at its floor: REGION_TOL (1e-7) relative to max(1, max |pole|)."""
    return 1e-7 * max(1.0, float(np.max(np.abs(poles))))


def check_design(d, A: np.ndarray, B: np.ndarray, region) -> float:
    """The design's claims against numpy: poles in the region, stable, kappa2 = cond(X) of A - B K
    (its X and numpy's eigenvectors), X a unit-column eigenbasis.  Returns cond(X)."""
    assert d.success, d.verification.summary()
    F = A - B @ d.K
    ev = np.linalg.eigvals(F)
    assert region.margin(ev) <= region_tolerance(region, ev)
    k = cond_x(F)
    # the reported kappa2 is cond(X) of the right eigenvectors, recomputed two ways
    assert d.kappa2 == pytest.approx(k, rel=1e-6)
    assert d.kappa2_right == d.kappa2
    X = d.X
    assert X is not None and X.shape == A.shape
    np.testing.assert_allclose(np.linalg.norm(X, axis=0), 1.0, rtol=0, atol=100 * _EPS)
    assert d.kappa2 == pytest.approx(float(np.linalg.cond(X)), rel=1e-9)
    lam = np.einsum("ij,ij->j", X.conj(), F @ X)
    assert np.linalg.norm(F @ X - X * lam) <= 1e3 * _EPS * np.linalg.norm(F) * np.linalg.norm(X)
    assert d.extra["mode"] == CONTROLLER_MODE
    return k


# ------------------------------------------------------------------ never worse than the dual route
@pytest.mark.parametrize("seed, n, m", [(11, 3, 2), (12, 4, 2), (13, 5, 2)])
def test_region_mode_minimizes_cond_x_and_is_never_worse_than_the_dual_route(seed, n, m):
    A, B = random_plant(seed, n, m)
    region = suggested_region(dual_plant(A, B))
    d = well_conditioned_feedback(Plant(A, np.eye(n), B=B), region=region, starts=2, seed=0)
    k = check_design(d, A, B, region)
    k_dual = cond_x(A - B @ dual_route_gain(A, B, region, starts=2, seed=0))
    assert k <= k_dual * (1 + 1e-9)
    assert d.extra["kappa2_dual_route"] == pytest.approx(k_dual, rel=1e-6)
    # the route names the controller-mode engine, and what answered
    names = [s.name for s in d.route]
    assert any("controller mode" in nm and s.kind == "engine" for nm, s in zip(names, d.route, strict=True))
    assert d.route.answered is not None
    assert "cond(X)" in d.message and "right eigenvectors" in d.message


def test_region_mode_improves_on_the_dual_route_where_the_measures_differ():
    # a plant where the left and right eigenvector conditions differ at the dual optimum
    # (measured: dual route cond(X) 5.641, controller mode 5.301)
    rng = np.random.default_rng(3)
    A, B = rng.standard_normal((5, 5)), rng.standard_normal((5, 2))
    region = HalfPlane(0.5) & Disk(0.0, 6.0) & Sector.from_damping(0.4)
    d = well_conditioned_feedback(Plant(A, np.eye(5), B=B), region=region, starts=2)
    k = check_design(d, A, B, region)
    # the dual route's design, as the verb ran it first (its observer; the tests above make the call
    # independently)
    k_dual = cond_x(A - B @ np.asarray(d.observer.L).T)
    assert k < 0.97 * k_dual
    # the dual design's own measure (left eigenvectors) is reported beside it
    assert d.extra["kappa2_left"] == pytest.approx(cond_x((A - B @ d.K).T), rel=1e-6)


def test_discrete_region():
    A = np.array([[1.1, 0.3, 0.0], [0.0, 0.8, 0.5], [0.2, 0.0, 1.05]])
    B = np.array([[1.0, 0.0], [0.0, 1.0], [0.5, 0.2]])
    region = Disk.unit(0.6)
    d = well_conditioned_feedback(Plant(A, np.eye(3), B=B, dt=0.1), region=region, starts=2)
    k = check_design(d, A, B, region)
    assert np.max(np.abs(d.poles)) <= 0.6 + 1e-7
    assert d.verification["feedback_stability_margin"].passed
    assert k <= cond_x(A - B @ dual_route_gain(A, B, region, dt=0.1, starts=2)) * (1 + 1e-9)


def test_one_input_plant():
    # one input: each pole's eigenvector is fixed by the pole, only the poles move
    A = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [2.0, -1.0, 0.5]])
    B = np.array([[0.0], [0.0], [1.0]])
    region = HalfPlane(1.0) & Sector.from_damping(0.5) & Disk(0.0, 6.0)
    d = well_conditioned_feedback(Plant(A, np.eye(3), B=B), region=region, starts=2)
    k = check_design(d, A, B, region)
    assert k <= cond_x(A - B @ dual_route_gain(A, B, region, starts=2)) * (1 + 1e-9)


def test_kappa_fro_objective():
    A, B = random_plant(21, 4, 2)
    region = suggested_region(dual_plant(A, B))
    d = well_conditioned_feedback(Plant(A, np.eye(4), B=B), region=region, objective="kappa_fro", starts=2)
    check_design(d, A, B, region)
    assert d.objective == "kappa_fro"


# ------------------------------------------------------------------ what stays on the dual route
def test_bounds_stay_on_the_dual_route_and_say_which_measure():
    A, B = random_plant(31, 3, 2)
    region = suggested_region(dual_plant(A, B))
    d = well_conditioned_feedback(Plant(A, np.eye(3), B=B), region=region, max_gain=50.0, starts=2)
    assert d.success
    assert d.extra["mode"] == DUAL_MODE
    assert "LEFT eigenvectors" in d.message
    assert d.kappa2 == pytest.approx(cond_x((A - B @ d.K).T), rel=1e-6)      # the dual measure
    assert d.kappa2_right == pytest.approx(cond_x(A - B @ d.K), rel=1e-6)


# ------------------------------------------------------------------ bad input, still typed
def test_bad_inputs_are_typed():
    A, B = random_plant(41, 3, 2)
    plant = Plant(A, np.eye(3), B=B)
    with pytest.raises(ValidationError, match="region must be an optdesign.regions.Region; found str"):
        well_conditioned_feedback(plant, region="left half plane")
    with pytest.raises(ValidationError, match="unbounded and no max_gain was given"):
        well_conditioned_feedback(plant, region=HalfPlane(1.0))
    with pytest.raises(ValidationError, match="time_limit must be a finite number of seconds > 0"):
        well_conditioned_feedback(plant, region=Disk(-3.0, 1.0), time_limit=-1.0)
    with pytest.raises(ValidationError, match="starts"):
        well_conditioned_feedback(plant, region=Disk(-3.0, 1.0), starts=0)
    with pytest.raises(ValidationError, match=r"reaches Re s = 2 > 0: the plant is continuous-time"):
        well_conditioned_feedback(plant, region=Disk(0.0, 2.0))
    with pytest.raises(ValidationError, match="measure must be one of"):
        place_region(A.T, B.T, Disk(-3.0, 1.0), measure="top", n_samples=1)


# ------------------------------------------------------------------ the engine's measure threading
def test_region_model_left_measure_gradient_matches_central_differences():
    rng = np.random.default_rng(3)
    A, B = rng.standard_normal((5, 5)), rng.standard_normal((5, 2))
    eng = EigenstructureEngine(A.T, B.T)
    region = HalfPlane(0.5) & Disk(0.0, 6.0) & Sector.from_damping(0.4)
    fixed = FixedPoleModel(eng, [-1, -2, -3, -1 + 1j, -1 - 1j], measure="left")
    model = RegionModel(eng, 3, 1, region, (), None, "left")
    X = model.coords_of(fixed, fixed.random_coords(rng)[None, :])
    d = rng.standard_normal(X.shape[1])
    h = 1e-6
    for k in (4, None):
        _, G = model.evaluate_batch(X, "kappa2", k, 1e-3)
        fp, _ = model.evaluate_batch(X + h * d, "kappa2", k, 1e-3)
        fm, _ = model.evaluate_batch(X - h * d, "kappa2", k, 1e-3)
        assert (fp - fm)[0] / (2 * h) == pytest.approx(float(G[0] @ d), rel=1e-5)


def test_place_region_left_measure_is_cond_x_of_the_transposed_loop():
    rng = np.random.default_rng(3)
    A, B = rng.standard_normal((5, 5)), rng.standard_normal((5, 2))
    region = HalfPlane(0.5) & Disk(0.0, 6.0) & Sector.from_damping(0.4)
    start = [RegionStart("sample", np.array([-1.0, -2.0, -3.0, -1 + 1j, -1 - 1j]))]
    left = place_region(A.T, B.T, region, starts=start, n_samples=0, measure="left")
    right = place_region(A.T, B.T, region, starts=start, n_samples=0)
    K_left, K_right = left.L.T, right.L.T
    assert left.kappa2 == pytest.approx(cond_x(A - B @ K_left), rel=1e-6)
    assert right.kappa2 == pytest.approx(cond_x((A - B @ K_right).T), rel=1e-6)
    # each minimizes its own measure: better on it than the other's answer
    assert cond_x(A - B @ K_left) < cond_x(A - B @ K_right)
