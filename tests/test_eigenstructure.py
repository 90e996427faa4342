"""The eigenstructure engine of issue 13 (fixed poles): parametrization, gradients, designs.

References: scipy's YT/KNV0 (one-output gains, never-worse starts), an independent multi-start
search (Nelder-Mead on metrics.kappa2), finite differences for every gradient.  No timing
thresholds: speed is measured in benchmarks/bench_placement.py.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from scipy.optimize import minimize
from scipy.signal import place_poles

from optdesign import metrics, problems
from optdesign._deadline import Deadline
from optdesign.analysis.metrics import eigenvalue_rounding_floor
from optdesign.classical.placement import pole_error
from optdesign.engines.eigenstructure import (
    DefectivePolesError,
    EigenstructureEngine,
    FixedPoleModel,
    pole_multiplicities,
    spread_poles,
)
from optdesign.engines.eigenstructure_fixed import default_starts, place_fixed
from optdesign.errors import DimensionError, NotConjugateClosedError, ValidationError
from optdesign.results import Status

EPS = float(np.finfo(float).eps)


def random_plant(rng, n, p):
    while True:
        A = rng.standard_normal((n, n)) / math.sqrt(n)
        C = rng.standard_normal((p, n))
        O = np.vstack([C @ np.linalg.matrix_power(A, k) for k in range(n)])
        if np.linalg.matrix_rank(O) == n:
            return A, C


def random_poles(rng, n, n_pairs):
    re = -rng.uniform(0.5, 4.0, n - 2 * n_pairs)
    z = -rng.uniform(0.5, 3.0, n_pairs) + 1j * rng.uniform(0.5, 3.0, n_pairs)
    return np.concatenate([re, z, z.conj()])


def yt_gain(A, C, P, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return place_poles(A.T, C.T, P, **kw).gain_matrix.T


def check_design(A, C, out, poles):
    """The outcome's gain places the poles, its V is an eigenbasis, its kappa2 is metrics' kappa2."""
    X = A - out.L @ C
    floor = eigenvalue_rounding_floor(X) if len(pole_multiplicities(poles)) == len(poles) else 1e-8
    assert pole_error(np.linalg.eigvals(X), poles) <= max(1e-12, 1e3 * floor)
    V = out.V
    res = np.linalg.norm(X @ V - V * out.poles[None, :]) / (np.linalg.norm(X) * np.linalg.norm(V))
    assert res <= 1e3 * EPS * out.kappa2
    assert np.allclose(np.linalg.norm(V, axis=0), 1.0, rtol=1e-12)
    sv = np.linalg.svd(V, compute_uv=False)
    assert out.kappa2 == pytest.approx(sv[0] / sv[-1], rel=1e-12)
    if len(pole_multiplicities(poles)) == len(poles):  # distinct: kappa2 is unique and metrics' value
        # two computed eigenbases of X differ by ~ eps ||X|| / gap per column (first-order
        # perturbation), amplified by kappa2 in their condition numbers
        d = np.abs(out.poles[:, None] - out.poles[None, :])
        gap = float(np.min(d[~np.eye(d.shape[0], dtype=bool)])) if d.shape[0] > 1 else 1.0
        tol = 1e-6 + 10 * EPS * out.kappa2 * np.linalg.norm(X) / gap
        assert out.kappa2 == pytest.approx(metrics.kappa2(X), rel=tol)


# ----------------------------------------------------------------------------- gradients


@pytest.mark.parametrize("n,p,pairs", [(4, 2, 0), (5, 2, 1), (6, 3, 2)])
@pytest.mark.parametrize("objective,k", [("kappa2", None), ("kappa2", 8), ("kappa_fro", None), ("eta", None)])
def test_gradients_match_finite_differences(n, p, pairs, objective, k):
    rng = np.random.default_rng(10 * n + p)
    A, C = random_plant(rng, n, p)
    model = EigenstructureEngine(A, C).model(random_poles(rng, n, pairs))
    x = model.random_coords(rng)
    f, g = model.evaluate(x, objective, k)
    h = 1e-6
    E = np.eye(x.size)
    fd = np.array(
        [
            (model.evaluate(x + h * E[i], objective, k)[0] - model.evaluate(x - h * E[i], objective, k)[0])
            / (2 * h)
            for i in range(x.size)
        ]
    )
    # central differences: error ~ h^2 f''' + eps f / h; the objectives are O(1) .. O(10^3) here
    assert np.max(np.abs(fd - g)) <= 1e-6 * max(1.0, np.max(np.abs(g)), abs(f))


def test_batch_evaluation_equals_single():
    rng = np.random.default_rng(3)
    A, C = random_plant(rng, 5, 2)
    model = EigenstructureEngine(A, C).model(random_poles(rng, 5, 1))
    X = np.stack([model.random_coords(rng) for _ in range(4)])
    f, G = model.evaluate_batch(X, "kappa2", 64)
    for i in range(4):
        fi, gi = model.evaluate(X[i], "kappa2", 64)
        assert f[i] == pytest.approx(fi, rel=1e-12)
        np.testing.assert_allclose(G[i], gi, rtol=1e-9, atol=1e-12 * np.max(np.abs(gi)))


def test_surrogate_bounds_exact_kappa2():
    """log kappa2 <= phi_k <= log kappa2 + log(n) / k (the continuation's guarantee)."""
    rng = np.random.default_rng(4)
    A, C = random_plant(rng, 6, 2)
    model = EigenstructureEngine(A, C).model(random_poles(rng, 6, 1))
    for _ in range(5):
        x = model.random_coords(rng)
        f0 = model.evaluate(x, "kappa2", None)[0]
        for k in (4, 64, 1024):
            fk = model.evaluate(x, "kappa2", k)[0]
            assert f0 - 1e-12 <= fk <= f0 + math.log(6) / k + 1e-12


def test_metrics_of_a_model_point_are_metrics_of_its_gain():
    rng = np.random.default_rng(5)
    A, C = random_plant(rng, 5, 2)
    model = EigenstructureEngine(A, C).model(random_poles(rng, 5, 1))
    x = model.random_coords(rng)
    L, V, k2, kf = model.design(x)
    X = A - L @ C
    assert k2 == pytest.approx(metrics.kappa2(X), rel=1e-8)
    assert kf == pytest.approx(metrics.kappa_fro(X), rel=1e-8)
    assert model.metric(x, "eta") == pytest.approx(metrics.eta(X), rel=1e-6)
    assert model.metric(x, "kappa_fro") == pytest.approx(kf, rel=1e-10)


# ----------------------------------------------------------------------------- one output / rank n


def ackermann_observer(A, C, P):
    """Ackermann's formula for the observer: ``L = phi(A) O^-1 e_n``, ``O = [C; CA; ...; CA^(n-1)]``."""
    n = A.shape[0]
    phi = np.poly(P).real
    phiA = sum(c * np.linalg.matrix_power(A, n - k) for k, c in enumerate(phi))
    O = np.vstack([C @ np.linalg.matrix_power(A, k) for k in range(n)])
    return phiA @ np.linalg.solve(O, np.eye(n)[:, -1:])


def test_one_output_is_the_unique_gain_of_yt_and_ackermann():
    A = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [-2.0, -3.0, -1.0]])
    C = np.array([[1.0, 0.0, 0.0]])
    P = np.array([-2.0, -3.0 + 1j, -3.0 - 1j])
    out = place_fixed(A, C, P)
    assert out.status is Status.SOLVED and out.unique and out.iterations == 0
    for ref in (yt_gain(A, C, P), ackermann_observer(A, C, P)):
        assert np.linalg.norm(out.L - ref) <= 1e3 * EPS * out.kappa2 * np.linalg.norm(ref)
    np.testing.assert_allclose(np.poly(A - out.L @ C), np.poly(P).real, rtol=1e-10, atol=1e-10)
    check_design(A, C, out, P)


def test_one_output_on_a_benchmark_plant():
    pr = problems.load("compleib_he1")
    A, C = pr.plant.A, pr.plant.C
    P = np.array([-1.0, -2.0, -3.0, -4.0])
    out = place_fixed(A, C, P)
    assert out.status is Status.SOLVED and out.unique
    Lyt = yt_gain(A, C, P)
    assert np.linalg.norm(out.L - Lyt) <= 1e4 * EPS * out.kappa2 * np.linalg.norm(Lyt)
    check_design(A, C, out, P)


def test_full_rank_output_gives_a_unitary_eigenbasis():
    rng = np.random.default_rng(8)
    A = rng.standard_normal((4, 4))
    out = place_fixed(A, np.eye(4), [-1.0, -2.0, -1.0 + 2j, -1.0 - 2j])
    assert out.status is Status.SOLVED and not out.unique
    assert out.kappa2 == pytest.approx(1.0, abs=1e-12)
    check_design(A, np.eye(4), out, out.poles)


# ----------------------------------------------------------------------------- several outputs


@pytest.mark.parametrize(
    "name", ["pp_knv1985_ex1", "pp_byers3", "pp_scipy_test_complex_car", "pp_chu2007_ex9"]
)
def test_benchmark_problems_never_worse_than_yt_or_knv0(name):
    pr = problems.load(name)
    A, C, P = pr.plant.A, pr.plant.C, pr.targets["poles"]
    out = place_fixed(A, C, P)
    assert out.status is Status.OPTIMAL
    check_design(A, C, out, P)
    peers = [yt_gain(A, C, P), yt_gain(A, C, P, rtol=1e-6, maxiter=100)]
    if np.all(np.asarray(P).imag == 0):
        peers.append(yt_gain(A, C, P, method="KNV0"))
    for L in peers:
        assert out.kappa2 <= metrics.kappa2(A - L @ C) * (1 + 1e-9)


@pytest.mark.parametrize(
    "n,p,seed",
    [
        (4, 2, 0),
        (5, 2, 1),
        pytest.param(6, 3, 2, marks=pytest.mark.slow),
        pytest.param(8, 3, 3, marks=pytest.mark.slow),
    ],
)
def test_random_plants_match_an_independent_multistart_search(n, p, seed):
    """Within 1e-4 of the best of 12 runs of scipy's L-BFGS-B (on the smooth kappa2 bound, k = 16,
    4096, then 65536: within log(n) / 65536 of kappa2; measured at the end by metrics.kappa2):
    another optimizer, twice the starts."""
    rng = np.random.default_rng(100 + seed)
    A, C = random_plant(rng, n, p)
    P = random_poles(rng, n, seed % 2 + n // 4)
    out = place_fixed(A, C, P)
    check_design(A, C, out, P)
    model = EigenstructureEngine(A, C).model(P)
    best = math.inf
    for _ in range(12):
        x = model.random_coords(rng)
        for k in (16, 4096, 65536):
            x = minimize(
                lambda z, _k=k: model.evaluate(z, "kappa2", _k),
                x,
                jac=True,
                method="L-BFGS-B",
                options={"maxiter": 3000, "ftol": 1e-15, "gtol": 1e-12},
            ).x
        best = min(best, metrics.kappa2(A - model.design(x)[0] @ C))
    assert out.kappa2 <= best * (1 + 1e-4)


@pytest.mark.parametrize("objective", ["kappa_fro", "eta"])
def test_other_objectives_improve_on_yt(objective):
    pr = problems.load("pp_knv1985_ex1")
    A, C, P = pr.plant.A, pr.plant.C, pr.targets["poles"]
    out = place_fixed(A, C, P, objective=objective)
    X_yt = A - yt_gain(A, C, P) @ C
    ref = metrics.kappa_fro(X_yt) if objective == "kappa_fro" else metrics.eta(X_yt)
    got = metrics.kappa_fro(A - out.L @ C) if objective == "kappa_fro" else metrics.eta(A - out.L @ C)
    assert got == pytest.approx(out.objective_value, rel=1e-6)
    assert got <= ref * (1 + 1e-9)


def test_warm_start_from_coordinates_and_from_a_gain():
    pr = problems.load("pp_byers5")
    A, C, P = pr.plant.A, pr.plant.C, pr.targets["poles"]
    first = place_fixed(A, C, P)
    again = place_fixed(A, C, P, warm_start=first.coords, starts=1)
    assert again.starts[0].origin == "warm start"
    assert again.kappa2 <= first.kappa2 * (1 + 1e-9)
    assert again.starts[0].evaluations < first.evaluations
    from_gain = place_fixed(A, C, P, warm_start=first.L, starts=1)
    assert from_gain.kappa2 <= first.kappa2 * (1 + 1e-6)


def test_engine_reuse_keeps_bases_and_answers():
    pr = problems.load("pp_knv1985_ex2")
    A, C, P = pr.plant.A, pr.plant.C, pr.targets["poles"]
    eng = EigenstructureEngine(A, C)
    a = place_fixed(None, None, P, engine=eng)
    assert len(eng._bases) == 4  # noqa: SLF001 - the cache: one basis per distinct pole (pairs once)
    b = place_fixed(None, None, P, engine=eng)
    assert a.kappa2 == b.kappa2 and np.array_equal(a.L, b.L)  # same call, same answer


def test_time_limit_returns_the_best_start():
    pr = problems.load("pp_scipy_test_complex_6x6")
    A, C, P = pr.plant.A, pr.plant.C, pr.targets["poles"]
    dl = Deadline(1e-6)
    while not dl.expired:
        pass
    out = place_fixed(A, C, P, deadline=dl)
    assert out.status is Status.TIME_LIMIT and "time limit" in out.message
    assert np.all(np.isfinite(out.L))
    check_design(A, C, out, P)
    assert out.kappa2 <= metrics.kappa2(A - yt_gain(A, C, P, maxiter=1) @ C) * (1 + 1e-9)


def test_default_starts():
    assert [default_starts(n) for n in (1, 12, 13, 24, 25, 50)] == [6, 6, 2, 2, 1, 1]
    with pytest.raises(ValidationError, match="n must be an integer >= 1"):
        default_starts(0)


# ----------------------------------------------------------------------------- repeated poles


def test_repeated_poles_up_to_rank_c():
    rng = np.random.default_rng(21)
    A, C = random_plant(rng, 6, 2)
    P = np.array([-1.0, -1.0, -2.0 + 1j, -2.0 - 1j, -2.0 + 1j, -2.0 - 1j])
    out = place_fixed(A, C, P)
    assert out.status is Status.OPTIMAL and math.isfinite(out.kappa2)
    assert math.isinf(metrics.kappa2(A - out.L @ C))  # repeated: metrics has no unique basis
    check_design(A, C, out, P)


def test_unobservable_mode_among_the_poles():
    pr = problems.load("compleib_ac4")  # -0.05 is unobservable: its subspace is larger
    A, C = pr.plant.A, pr.plant.C
    eng = EigenstructureEngine(A, C)
    assert eng.unobservable_modes() == pytest.approx([-0.05])
    assert eng.basis(-0.05).shape == (4, 3) and eng.basis(-1.0).shape == (4, 2)
    P = np.array([-0.05, -1.0, -2.0, -3.0])
    out = place_fixed(A, C, P)
    check_design(A, C, out, P)


def test_defective_request_refused_with_the_pole_named():
    pr = problems.load("pp_chowkokotovic")
    A, C, P = pr.plant.A, pr.plant.C, pr.targets["poles"]
    with pytest.raises(
        DefectivePolesError, match=r"pole -1\+0j is requested 2 times but rank\(C\) = 1"
    ) as ei:
        place_fixed(A, C, P)
    assert ei.value.multiplicity == 2 and ei.value.rank == 1 and ei.value.pole == -1.0
    assert isinstance(ei.value, ValueError)


def test_nearest_distinct_design_with_a_separation():
    rng = np.random.default_rng(7)
    A, C = random_plant(rng, 4, 1)
    P = np.array([-1.0, -1.0, -1.0, -3.0])
    kappas = []
    for sep in (1e-1, 1e-2):
        out = place_fixed(A, C, P, separation=sep)
        assert out.separation == sep and np.array_equal(out.requested_poles, np.sort(P) + 0j)
        assert pole_error(out.poles, P) == pytest.approx(sep, rel=1e-9)
        check_design(A, C, out, out.poles)
        kappas.append(out.kappa2)
    assert kappas[1] > kappas[0]  # closer to the Jordan block: worse conditioned


def test_spread_poles():
    np.testing.assert_allclose(spread_poles([-1.0, -1.0, -3.0], 1, 1e-2), [-3, -1.01, -0.99], atol=1e-15)
    sp = spread_poles([-1 + 1j, -1 - 1j] * 3, 2, 0.1)
    assert len(pole_multiplicities(sp)) == 6
    assert np.max(np.abs(sp - np.where(sp.imag > 0, -1 + 1j, -1 - 1j))) == pytest.approx(0.1 * math.sqrt(2))
    kept = spread_poles([-1.0, -1.0, -2.0], 2, 0.1)  # multiplicity <= rank: unchanged
    np.testing.assert_array_equal(kept, [-2.0, -1.0, -1.0])
    with pytest.raises(ValidationError, match="separation"):
        spread_poles([-1.0, -1.0], 1, 0.0)
    with pytest.raises(ValidationError, match="rank"):
        spread_poles([-1.0, -1.0], 0, 0.1)


# ----------------------------------------------------------------------------- bad input


def test_bad_input():
    A, C = np.diag([-1.0, -2.0, -3.0]), np.array([[1.0, 1.0, 1.0], [0.0, 1.0, 2.0]])
    P = [-1.0, -2.0, -4.0]
    with pytest.raises(ValidationError, match="objective must be one of"):
        place_fixed(A, C, P, objective="kappa1")
    with pytest.raises(ValidationError, match="starts"):
        place_fixed(A, C, P, starts=0)
    with pytest.raises(DimensionError, match="warm_start must be coordinates"):
        place_fixed(A, C, P, warm_start=np.ones(2))
    with pytest.raises(DimensionError, match="C must have n = 3 columns"):
        EigenstructureEngine(A, np.ones((2, 2)))
    with pytest.raises(DimensionError, match="A must be square"):
        EigenstructureEngine(np.ones((2, 3)), np.ones((1, 3)))
    with pytest.raises(DimensionError, match="C must have rank >= 1"):
        EigenstructureEngine(A, np.zeros((1, 3)))
    with pytest.raises(NotConjugateClosedError):
        place_fixed(A, C, [-1.0, -2.0 + 1j, -3.0])
    with pytest.raises(DimensionError):
        place_fixed(A, C, [-1.0, -2.0])
    with pytest.raises(ValidationError, match="objective 'eta' needs distinct poles"):
        place_fixed(A, C, [-1.0, -1.0, -2.0], objective="eta")
    with pytest.raises(DefectivePolesError, match="requested 3 times"):
        FixedPoleModel(EigenstructureEngine(A, C), [-1.0, -1.0, -1.0])


def test_unassignable_poles_one_output():
    """(C, A) unobservable and the mode not among the poles: the one-output design is singular."""
    from optdesign.errors import NotObservableError

    A, C = np.diag([-1.0, -2.0]), np.array([[1.0, 0.0]])
    with pytest.raises(
        NotObservableError, match="an unobservable mode of \\(C, A\\) must be among the poles"
    ):
        place_fixed(A, C, [-3.0, -4.0])


# ----------------------------------------------------------------------------- structural zeros


def test_structural_zeros_by_augmented_lagrangian():
    pr = problems.load("pp_scipy_test_complex_car")
    A, C, P = pr.plant.A, pr.plant.C, pr.targets["poles"]
    mask = np.ones((A.shape[0], C.shape[0]), dtype=bool)
    mask[0, 0] = False
    free = place_fixed(A, C, P)
    out = place_fixed(A, C, P, gain_mask=mask)
    assert out.status is Status.OPTIMAL and out.extra["mask_violation"] <= 1e-9
    assert np.all(out.L[~mask] == 0.0)  # exact zeros
    X = A - out.L @ C
    assert pole_error(np.linalg.eigvals(X), P) <= 1e-6
    assert out.kappa2 == pytest.approx(metrics.kappa2(X), rel=1e-9)
    assert out.kappa2 >= free.kappa2 * (1 - 1e-9)  # a constraint cannot help
    with pytest.raises(DimensionError, match=r"gain_mask must have shape \(4, 2\)"):
        place_fixed(A, C, P, gain_mask=np.ones((2, 4), bool))
    with pytest.raises(ValidationError, match="gain_mask must be boolean"):
        place_fixed(A, C, P, gain_mask=np.full((4, 2), 0.5))
    with pytest.raises(ValidationError, match="gain_mask has no free entry"):
        place_fixed(A, C, P, gain_mask=np.zeros((4, 2), bool))
    same = place_fixed(A, C, P, gain_mask=np.ones((4, 2), bool))  # no zero: the unconstrained engine
    assert same.kappa2 == free.kappa2


# ------------------------------------------------------------------ issue 27: the controller measure
@pytest.mark.parametrize("poles", [[-1.0, -2.0, -3.0, -4.0, -5.0], [-1.0, -2 + 1j, -2 - 1j, -3 + 2j, -3 - 2j]])
@pytest.mark.parametrize("objective,k", [("kappa2", None), ("kappa2", 4), ("kappa_fro", None)])
def test_left_measure_gradient_matches_finite_differences(poles, objective, k):
    """measure="left": cond of the unit-norm LEFT eigenvectors of A - L C (= the right eigenvectors
    of the state-feedback loop (A - L C)'); analytic gradient against central differences."""
    from optdesign.engines.eigenstructure import EigenstructureEngine, FixedPoleModel

    rng = np.random.default_rng(7)
    A, C = rng.standard_normal((5, 5)), rng.standard_normal((2, 5))
    model = FixedPoleModel(EigenstructureEngine(A, C), poles, measure="left")
    x = model.random_coords(rng)
    f, g = model.evaluate(x, objective, k)
    h = 1e-6
    fd = np.array([(model.evaluate(x + h * e, objective, k, gradient=False)[0]
                    - model.evaluate(x - h * e, objective, k, gradient=False)[0]) / (2 * h) for e in np.eye(x.size)])
    np.testing.assert_allclose(g, fd, rtol=1e-6, atol=1e-6 * np.max(np.abs(g)))
    # the value is cond of the transposed unit-row W, i.e. of the right eigenvectors of (A - L C)'
    L, X, k2, _ = model.design(x)
    Ft = (A - L @ C).T
    np.testing.assert_allclose(np.linalg.norm(X, axis=0), 1.0, rtol=1e-13)
    assert np.linalg.norm(Ft @ X - X * model.poles) <= 1e-10 * np.linalg.norm(Ft)
    if objective == "kappa2" and k is None:
        assert np.exp(f) == pytest.approx(np.linalg.cond(X), rel=1e-10) == pytest.approx(k2, rel=1e-12)


def test_place_fixed_left_measure_minimizes_cond_of_the_transpose():
    from optdesign.engines.eigenstructure_fixed import place_fixed

    prob = problems.load("pp_byers5")
    A, C, P = prob.plant.A, prob.plant.C, np.asarray(prob.targets["poles"])
    left = place_fixed(A, C, P, measure="left")
    right = place_fixed(A, C, P)
    assert left.kappa2 == pytest.approx(metrics.kappa2((A - left.L @ C).T), rel=1e-6)
    # each run is better on its own measure
    assert left.kappa2 < metrics.kappa2((A - right.L @ C).T)
    assert right.kappa2 < metrics.kappa2(A - left.L @ C)
