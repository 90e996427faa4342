"""The lean verification of designs that come from no Riccati solver (``avoid="none"``,
:func:`optdesign.design.verification.lean_riccati_checks`), the shared-Schur forward error estimate
(:func:`optdesign.classical.riccati.are_error_of_terms`) and the one-output engine's first, looser
Clarabel solve (:data:`optdesign.engines.inverse_kalman_engine.ONE_OUTPUT_FIRST_TRY`): the same
checks, tolerances and verdicts as the full path, on random systems with fixed seeds."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import random_observable_plant

from optdesign import Plant, kalman_for_poles
from optdesign.analysis.conditioning import lyapunov_solve, rounding_response
from optdesign.classical.riccati import (
    are_error_of_terms,
    filter_are,
    filter_are_error,
    filter_are_terms,
    hamiltonian_are,
)
from optdesign.design.verification import (
    AVOID_CHOICES,
    lean_riccati_checks,
    newton_kalman_checks,
    pole_check,
    riccati_checks,
)
from optdesign.engines import inverse_kalman_engine as engine
from optdesign.errors import RiccatiError, ValidationError
from optdesign.results import Status

EPS = float(np.finfo(float).eps)


def _design(seed: int, n: int, p: int = 1):
    """A continuous plant, a random Q >= 0 and its Kalman filter, with P from a Lyapunov solve (as
    the engine's designs: from no Riccati solver)."""
    rng = np.random.default_rng(seed)
    plant = random_observable_plant(rng, n, p, noise=True)
    F = rng.standard_normal((n, n))
    Q = F @ F.T / n
    are = filter_are(plant.replace(G=None, Q=Q))
    return plant, are.L, are.P, Q


def _old_error(plant: Plant, P, Qs):
    """The forward error estimate as computed before the shared Schur form: three separate
    Lyapunov solves (:mod:`optdesign.analysis.conditioning`)."""
    A, C, R = plant.A, plant.C, np.asarray(plant.R, dtype=float)
    res, terms = filter_are_terms(A, C, R, Qs, P, False)
    L = np.linalg.solve(R, C @ P).T
    Fc = A - L @ C
    mag = plant.n * EPS * (sum(np.abs(t) for t in terms) + np.abs(P))
    floor = rounding_response(Fc, 0.5 * (mag + mag.T), False)
    corr = float(np.linalg.norm(lyapunov_solve(Fc, -res, False)))
    return corr, floor


@pytest.mark.parametrize("seed, n", [(0, 2), (1, 4), (2, 7), (3, 12)])
def test_shared_schur_error_estimate_is_the_separate_solves_one(seed, n):
    plant, L, P, Q = _design(seed, n)
    P = P * (1 + 1e-9)   # a residual to correct
    corr, floor = _old_error(plant, P, Q)
    est = filter_are_error(plant, P, Qs=Q)
    # the same LAPACK calls in the same order (one Schur form instead of three identical ones)
    assert est.correction == pytest.approx(corr, rel=100 * n * EPS)
    assert est.floor == pytest.approx(floor, rel=100 * n * EPS)
    res, terms = filter_are_terms(plant.A, plant.C, plant.R, Q, P, False)
    again = are_error_of_terms(plant.A, plant.C, plant.R, P, res, terms, False)
    assert again == est


def test_error_estimate_of_an_unstable_closed_loop_is_infinite():
    plant = Plant([[1.0, 0.0], [0.0, 2.0]], [[1.0, 1.0]], R=[[1.0]])
    P = np.zeros((2, 2))   # L = 0: A - L C = A is unstable
    res, terms = filter_are_terms(plant.A, plant.C, plant.R, np.eye(2), P, False)
    est = are_error_of_terms(plant.A, plant.C, plant.R, P, res, terms, False)
    assert np.isinf(est.relative) and np.isinf(est.floor)


@pytest.mark.parametrize("seed, n, p", [(0, 2, 1), (1, 5, 1), (2, 9, 2), (3, 14, 1), (4, 20, 3)])
def test_lean_checks_match_the_full_ones(seed, n, p):
    plant, L, P, Q = _design(seed, n, p)
    full, are_full, err_full = riccati_checks(plant, L, P, Q, avoid="hamiltonian")
    lean = lean_riccati_checks(plant, L, P, Q)
    assert lean is not None
    checks, are, err = lean
    assert [c.name for c in checks] == [c.name for c in full]
    assert [c.passed for c in checks] == [c.passed for c in full] == [True] * len(full)
    assert err == err_full   # the design's own estimate: the same computation
    by = {c.name: c for c in full}
    for c in checks:
        ref = by[c.name]
        if c.name == "are_resolve_gain":   # another solver: its own rounding, its own estimate
            continue
        # PSD values: ||X||_2 from the eigenvalues instead of an SVD, equal to rounding
        assert c.value == pytest.approx(ref.value, rel=1e3 * n * EPS, abs=10 * n * EPS)
        assert c.tolerance == pytest.approx(ref.tolerance, rel=1e3 * n * EPS)
    assert are.method == "hamiltonian" and are_full.method == "scipy"
    # riccati_checks(avoid="none") is the lean path whenever it passes
    via, are_via, _ = riccati_checks(plant, L, P, Q, avoid="none")
    assert are_via.method == "hamiltonian" and [c.value for c in via] == [c.value for c in checks]


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_wrong_gain_falls_back_to_the_full_re_solve(seed):
    plant, L, P, Q = _design(seed, 6)
    bad = L * (1 + 1e-4)
    assert lean_riccati_checks(plant, bad, P, Q) is None   # a lean verdict is only ever a pass
    via, are_via, _ = riccati_checks(plant, bad, P, Q, avoid="none")
    full, _, _ = riccati_checks(plant, bad, P, Q, avoid="hamiltonian")
    assert are_via.method == "scipy"
    assert [(c.name, c.value, c.passed) for c in via] == [(c.name, c.value, c.passed) for c in full]
    gain = next(c for c in via if c.name == "are_resolve_gain")
    assert not gain.passed and gain.value > 1e-5


def test_no_stabilizing_re_solve_fails_the_gain_check_with_the_full_solvers_reason():
    # an undamped mode the noise does not reach: no stabilizing Riccati solution with this Q
    plant = Plant([[0.0, 1.0], [-1.0, 0.0]], [[1.0, 0.0]], R=[[1.0]])
    L = np.array([[1.0], [0.5]])
    P = np.array([[1.0, 0.0], [0.0, 1.0]])
    assert lean_riccati_checks(plant, L, P, np.zeros((2, 2))) is None
    checks, are, _ = riccati_checks(plant, L, P, np.zeros((2, 2)), avoid="none")
    gain = next(c for c in checks if c.name == "are_resolve_gain")
    assert are is None and not gain.passed and "filter_are failed" in gain.detail


def test_discrete_designs_take_the_full_path():
    rng = np.random.default_rng(5)
    cplant = random_observable_plant(rng, 4, 1, noise=True)
    plant = Plant(0.5 * cplant.A, cplant.C, R=cplant.R, dt=0.1)
    Q = np.eye(4)
    are = filter_are(plant.replace(G=None, Q=Q))
    checks, resolved, _ = riccati_checks(plant, are.L, are.P, Q, avoid="none")
    assert resolved is not None and resolved.method == "scipy"
    assert all(c.passed for c in checks)


# ------------------------------------------------------- the Newton-step checks (one output)


def _discrete_design(seed: int, n: int):
    rng = np.random.default_rng(seed)
    cplant = random_observable_plant(rng, n, 1, noise=True)
    A = cplant.A / (1.1 * max(1.0, float(np.max(np.abs(np.linalg.eigvals(cplant.A))))))
    plant = Plant(A, cplant.C, R=cplant.R, dt=0.1)
    F = rng.standard_normal((n, n))
    Q = F @ F.T / n
    are = filter_are(plant.replace(G=None, Q=Q))
    return plant, are.L, are.P, Q, are.poles


@pytest.mark.parametrize("dt", [None, 0.1])
@pytest.mark.parametrize("seed, n", [(0, 2), (1, 4), (2, 7), (3, 12)])
def test_newton_checks_pass_exact_designs_with_the_full_checks_values(seed, n, dt):
    if dt is None:
        plant, L, P, Q = _design(seed, n)
        target = np.linalg.eigvals(plant.A - L @ plant.C)
    else:
        plant, L, P, Q, target = _discrete_design(seed, n)
    out = newton_kalman_checks(plant, L, P, Q, target, 1e-8)
    assert out is not None
    checks, poles = out
    assert [c.name for c in checks] == ["pole_error", "riccati_residual", "forward_error", "Q_min_eig",
                                        "P_min_eig", "are_resolve_gain", "are_resolve_poles"]
    assert all(c.passed for c in checks)
    full, _, err = riccati_checks(plant, L, P, Q, avoid="scipy")
    by = {c.name: c for c in full}
    for c in checks[1:5]:   # the same residual, estimate and PSD values as the full checks
        assert c.value == pytest.approx(by[c.name].value, rel=1e3 * n * EPS, abs=10 * n * EPS)
    # the Newton step's gain is the re-solve's to the error estimates of both
    gain = checks[5]
    assert gain.value <= gain.tolerance
    assert abs(gain.value - by["are_resolve_gain"].value) <= 2 * gain.tolerance
    np.testing.assert_array_equal(poles, pole_check(plant.A - L @ plant.C, target, 1e-8)[1])   # same order


@pytest.mark.parametrize("dt", [None, 0.1])
def test_newton_checks_defer_every_failure_to_the_full_checks(dt):
    if dt is None:
        plant, L, P, Q = _design(4, 5)
        target = np.linalg.eigvals(plant.A - L @ plant.C)
    else:
        plant, L, P, Q, target = _discrete_design(4, 5)
    assert newton_kalman_checks(plant, L, P, Q, target, 1e-8) is not None
    assert newton_kalman_checks(plant, L, P * (1 + 1e-5), Q, target, 1e-8) is None         # residual
    assert newton_kalman_checks(plant, L * (1 + 1e-7), P, Q, target, 1e-8) is None         # gain, poles
    assert newton_kalman_checks(plant, L, P, Q, target * (1 + 1e-4), 1e-8) is None         # poles
    w, U = np.linalg.eigh(Q)
    Qneg = Q - (w[0] + 1e-3 * w[-1]) * np.outer(U[:, 0], U[:, 0])                          # not PSD
    assert newton_kalman_checks(plant, L, P, Qneg, target, 1e-8) is None
    assert newton_kalman_checks(plant.replace(R=None), L, P, Q, target, 1e-8) is None


def test_kalman_for_poles_verifies_one_output_with_the_newton_checks():
    plant = Plant([[0.0, 1.0], [-6.0, -5.0]], [[1.0, 0.0]], R=[[1.0]])
    res = kalman_for_poles(plant, [-5, -8])
    assert res.success and "Newton step" in res.verification["are_resolve_gain"].detail
    # a target whose poles are not computable to tol: the full checks decide and report it
    plant, poles = _uncomputable_target()
    res = kalman_for_poles(plant, poles)
    assert not res.success and "Newton step" not in res.verification["are_resolve_gain"].detail


def test_bad_avoid_raises_even_without_a_re_solve():
    plant, L, P, Q = _design(0, 3)
    assert "none" in AVOID_CHOICES
    with pytest.raises(ValidationError, match=r"avoid must be one of 'scipy', 'hamiltonian', 'none'; "
                                              r"found 'lean'"):
        riccati_checks(plant, L, P, Q, avoid="lean", resolve=False)


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_trusted_hamiltonian_is_the_validated_one(seed):
    rng = np.random.default_rng(seed)
    n = 3 + seed
    a = rng.standard_normal((n, n))
    b = rng.standard_normal((n, 1))
    F = rng.standard_normal((n, n))
    q = F @ F.T
    X = hamiltonian_are(a, b, q, np.eye(1))
    np.testing.assert_array_equal(hamiltonian_are(a, b, q, np.eye(1), trusted=True), X)


def test_trusted_hamiltonian_still_counts_the_stable_eigenvalues():
    a = np.array([[0.0, 1.0], [-1.0, 0.0]])   # an undamped mode, unobservable: eigenvalues on the axis
    with pytest.raises(RiccatiError, match="hamiltonian_are"):
        hamiltonian_are(a, np.zeros((2, 1)), np.zeros((2, 2)), np.eye(1), trusted=True)


# ------------------------------------------------------------------ the one-output first try


def _one_output_targets():
    rng = np.random.default_rng(11)
    out = []
    for n in (2, 3, 5, 8):
        plant = random_observable_plant(rng, n, 1, noise=True)
        F = rng.standard_normal((n, n))
        out.append((plant, filter_are(plant.replace(G=None, Q=F @ F.T / n)).poles))
    return out


def _spy_on_solve_fixed_gain(monkeypatch) -> list:
    """The Clarabel ``options`` of every engine call of ``solve_fixed_gain`` from now on (a list that
    fills as the calls happen)."""
    calls: list = []
    real = engine.solve_fixed_gain

    def spy(*a, **k):
        calls.append(k.get("options"))
        return real(*a, **k)

    monkeypatch.setattr(engine, "solve_fixed_gain", spy)
    return calls


TIGHT = {"tol_gap_abs": 1e-10, "tol_gap_rel": 1e-10, "tol_feas": 1e-10}


@pytest.mark.parametrize("k", range(4))
def test_first_try_gives_the_tight_solves_design(k, monkeypatch, general_one_output_route):
    plant, poles = _one_output_targets()[k]
    monkeypatch.setattr(engine, "ONE_OUTPUT_FIRST_TRY_MIN_DIM", 0)   # small systems: fast tests
    fast = kalman_for_poles(plant, poles)
    monkeypatch.setattr(engine, "ONE_OUTPUT_FIRST_TRY", dict(TIGHT))
    tight = kalman_for_poles(plant, poles)
    assert fast.status == tight.status == Status.OPTIMAL and fast.success and tight.success
    assert "first_try" not in fast.extra["engine"]   # accepted: optimal with its KKT certificate
    assert fast.extra["engine"]["kkt"]["passed"]
    # two Newton points converged on the same face of a convex problem: the same optimum to the
    # forward error of Q (the design's own estimate), at least to 1e-9
    trq = float(np.trace(tight.Q))
    assert float(np.trace(fast.Q)) == pytest.approx(trq, rel=1e-9)
    np.testing.assert_allclose(fast.L, tight.L, rtol=0, atol=1e-7 * max(1.0, float(np.linalg.norm(tight.L))))


def test_first_try_that_fails_is_solved_again_at_full_accuracy(monkeypatch, general_one_output_route):
    plant, poles = _one_output_targets()[2]
    monkeypatch.setattr(engine, "ONE_OUTPUT_FIRST_TRY_MIN_DIM", 0)
    ref = kalman_for_poles(plant, poles)
    # one Clarabel iteration: never solved, so the design is decided by the tight solve
    monkeypatch.setattr(engine, "ONE_OUTPUT_FIRST_TRY", {"max_iter": 1})
    again = kalman_for_poles(plant, poles)
    assert "first_try" in again.extra["engine"]
    assert again.status == ref.status == Status.OPTIMAL and again.success
    assert float(np.trace(again.Q)) == pytest.approx(float(np.trace(ref.Q)), rel=1e-9)


def test_other_objectives_and_small_systems_skip_the_first_try(monkeypatch, general_one_output_route):
    plant, poles = _one_output_targets()[1]
    calls = _spy_on_solve_fixed_gain(monkeypatch)
    kalman_for_poles(plant, poles)   # n - p = 2: below ONE_OUTPUT_FIRST_TRY_MIN_DIM
    assert calls and all(o is None for o in calls)
    monkeypatch.setattr(engine, "ONE_OUTPUT_FIRST_TRY_MIN_DIM", 0)
    calls.clear()
    kalman_for_poles(plant, poles, objective="nearest", Q_nominal=np.eye(plant.n))
    assert calls and all(o is None for o in calls)
    calls.clear()
    kalman_for_poles(plant, poles)
    assert calls[0] == engine.ONE_OUTPUT_FIRST_TRY


def _uncomputable_target():
    """The benchmark's (n = 20, p = 1) target 1 (``benchmarks/bench_inverse_kalman.py``, seed 0):
    its poles' rounding floor is ~2, the unique gain misses them by ~7e-3."""
    from optdesign.errors import OptDesignError

    rng = np.random.default_rng(0)
    out = None
    for n, count in ((2, 3), (10, 3), (20, 2)):
        for _ in range(count):
            for _ in range(50):
                while True:
                    A = rng.standard_normal((n, n)) / np.sqrt(n)
                    C = rng.standard_normal((1, n))
                    plant = Plant(A, C, R=np.eye(1))
                    if plant.is_observable():
                        break
                F = rng.standard_normal((n, n)) / np.sqrt(n)
                try:
                    out = plant, filter_are(plant.replace(Q=F @ F.T), residual_tol=1e-6).poles
                    break
                except OptDesignError:
                    continue
    return out


def test_an_uncomputable_target_is_not_solved_twice(monkeypatch, general_one_output_route):
    plant, poles = _uncomputable_target()
    calls = _spy_on_solve_fixed_gain(monkeypatch)
    res = kalman_for_poles(plant, poles)
    assert len(calls) == 1 and calls[0] == engine.ONE_OUTPUT_FIRST_TRY
    assert res.status == Status.OPTIMAL_INACCURATE and not res.success
    assert "not computable" in res.extra["engine"]["first_try"]
    assert not res.extra["engine"]["kkt"]["passed"]
