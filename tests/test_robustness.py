"""Return difference, circle condition and margins of filters (seed 002, issue 7).

The loop of a filter is broken at the filter input (the innovation): a perturbation Delta gives
error dynamics A - L Delta C.  What is verified here, by closed-loop eigenvalues:

* every continuous Kalman filter (100 random plants, diagonal R, unstable ones included) passes
  the circle condition T R T* >= R and survives, in all channels SIMULTANEOUSLY, diagonal gain
  perturbations in (1/2, inf) and phase perturbations within +-60 deg (and their mixtures with
  Re(delta_i) > 1/2);
* a gain change and a phase change in the SAME channel do not combine (0.51 e^{j59 deg} can
  destabilize), crossfeed beyond the norm bound can destabilize, and with non-diagonal R the
  per-channel margins are lost (counterexamples);
* seed 002 eq (23) as printed (no square root) is violated; the square-root bound holds;
* discrete predictor filters satisfy T V T* >= R (V = C P C' + R) but not T R T* >= R.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from conftest import random_observable_plant
from hypothesis import given, settings
from hypothesis import strategies as st

from optdesign import (
    DimensionError,
    NotFiniteError,
    NotPositiveDefiniteError,
    Plant,
    ValidationError,
    circle_condition,
    filter_margins,
    kalman,
    return_difference,
)
from optdesign.analysis.robustness import (
    CircleConditionResult,
    FilterMargins,
    adaptive_minimize,
    frequency_grid,
    innovation_covariance,
    margins_from_radius,
)
from optdesign.classical.placement import place_observer

DEG = math.pi / 180


def max_re(plant, L, D):
    return float(np.max(np.linalg.eigvals(plant.A - L @ D @ plant.C).real))


def rho(plant, L, D):
    return float(np.max(np.abs(np.linalg.eigvals(plant.A - L @ D @ plant.C))))


def plants_100():
    """100 random continuous plants (n 1..5, p 1..3; stable, unstable, mixed), diagonal R."""
    rng = np.random.default_rng(7001)
    out = []
    for k in range(100):
        n, p = int(rng.integers(1, 6)), int(rng.integers(1, 4))
        out.append(random_observable_plant(rng, n, p, stable=(None, True, False)[k % 3]))
    return out


PLANTS = plants_100()


# ============================================================================ return difference
def test_return_difference_matches_definition(rng):
    plant = random_observable_plant(rng, 4, 2)
    L = kalman(plant).L
    w = np.array([0.0, 0.3, 2.0, 17.0])
    T = return_difference(plant, L, w)
    assert T.shape == (4, 2, 2) and T.dtype == complex
    for k, wk in enumerate(w):
        ref = np.eye(2) + plant.C @ np.linalg.solve(1j * wk * np.eye(4) - plant.A, L)
        np.testing.assert_allclose(T[k], ref, rtol=1e-12, atol=1e-12)
    # T(-jw) = conj(T(jw)) for a real system
    np.testing.assert_allclose(return_difference(plant, L, -w), T.conj(), atol=1e-12)


def test_return_difference_discrete_convention(rng):
    plant = random_observable_plant(rng, 3, 2, dt=0.05)
    L = kalman(plant).L
    w = np.array([0.0, 7.0, math.pi / 0.05])
    T = return_difference(plant, L, w)
    for k, wk in enumerate(w):
        z = np.exp(1j * wk * 0.05)
        np.testing.assert_allclose(T[k], np.eye(2) + plant.C @ np.linalg.solve(z * np.eye(3) - plant.A, L),
                                   atol=1e-12)
    # det T(z) = det(zI - A + LC) / det(zI - A): zeros of T are the filter poles
    z = np.exp(1j * 7.0 * 0.05)
    ratio = np.linalg.det(z * np.eye(3) - plant.A + L @ plant.C) / np.linalg.det(z * np.eye(3) - plant.A)
    assert abs(np.linalg.det(T[1]) - ratio) < 1e-10 * max(1.0, abs(ratio))


def test_continuous_return_difference_identity(rng):
    """T(jw) R T(jw)^* = R + C (jwI - A)^-1 W (jwI - A)^-* C' for the Kalman gain (seed 002 eq 19, c1 = 0)."""
    for _ in range(10):
        plant = random_observable_plant(rng, int(rng.integers(1, 5)), int(rng.integers(1, 3)))
        L = kalman(plant).L
        w = np.array([0.0, 0.1, 1.3, 40.0])
        T = return_difference(plant, L, w)
        for k, wk in enumerate(w):
            H = plant.C @ np.linalg.inv(1j * wk * np.eye(plant.n) - plant.A)
            lhs = T[k] @ plant.R @ T[k].conj().T
            rhs = plant.R + H @ plant.process_noise() @ H.conj().T
            np.testing.assert_allclose(lhs, rhs, atol=1e-9 * np.linalg.norm(rhs))


@settings(max_examples=40, deadline=None)
@given(a=st.floats(-3, 3), c=st.floats(0.2, 3), q=st.floats(0.01, 10), r=st.floats(0.1, 10),
       w=st.floats(0, 50))
def test_scalar_return_difference_closed_form(a, c, q, r, w):
    """Scalar: p = r (a + sqrt(a^2 + c^2 q / r)) / c^2, |T(jw)|^2 - 1 = c^2 q / (r (w^2 + a^2))."""
    if abs(a) < 1e-3 and w < 1e-3:
        return
    plant = Plant([[a]], [[c]], Q=[[q]], R=[[r]])
    p = r * (a + math.sqrt(a * a + c * c * q / r)) / c**2
    L = np.array([[p * c / r]])
    T = return_difference(plant, L, [w])[0, 0, 0]
    assert abs(T) ** 2 - 1 == pytest.approx(c * c * q / (r * (w * w + a * a)), rel=1e-9, abs=1e-12)
    assert circle_condition(plant, L, omega=[w, w + 1.0]).passed


def test_discrete_return_difference_identity(rng):
    """Discrete predictor: T V T^* = R + H W H^*, V = C P C' + R = T(0)^-1 R (module docstring)."""
    for _ in range(10):
        plant = random_observable_plant(rng, int(rng.integers(1, 5)), int(rng.integers(1, 3)), dt=0.1,
                                        stable=bool(rng.integers(2)))
        kf = kalman(plant)
        V = plant.C @ kf.P @ plant.C.T + plant.R
        V_implied, source = innovation_covariance(plant, kf.L)
        assert source == "T(0)^-1 R"
        np.testing.assert_allclose(V_implied, V, rtol=1e-8, atol=1e-10)
        w = np.array([0.0, 3.0, 15.0, math.pi / plant.dt])
        T = return_difference(plant, kf.L, w)
        for k, wk in enumerate(w):
            z = np.exp(1j * wk * plant.dt)
            H = plant.C @ np.linalg.inv(z * np.eye(plant.n) - plant.A)
            rhs = plant.R + H @ plant.process_noise() @ H.conj().T
            np.testing.assert_allclose(T[k] @ V @ T[k].conj().T, rhs, atol=1e-8 * np.linalg.norm(V))


def test_discrete_kalman_violates_TRT_but_satisfies_TVT():
    """Scalar a = 0.5, c = q = r = 1: p = (1/4 + sqrt(1/16 + 4)) / 2, l = a p / (p + 1), |T(-1)| < 1."""
    plant = Plant([[0.5]], [[1.0]], Q=[[1.0]], R=[[1.0]], dt=1.0)
    kf = kalman(plant)
    p = (0.25 + math.sqrt(0.0625 + 4)) / 2
    assert kf.P[0, 0] == pytest.approx(p, rel=1e-12)
    l = 0.5 * p / (p + 1)
    T_nyq = 1 - l / 1.5
    assert abs(return_difference(plant, kf.L, [math.pi])[0, 0, 0] - T_nyq) < 1e-12
    wrong = circle_condition(plant, kf.L, V=plant.R)           # T R T* >= R: not a discrete property
    assert not wrong.passed
    assert wrong.min_eigenvalue == pytest.approx(T_nyq**2 - 1, rel=1e-8)
    assert wrong.omega_worst == pytest.approx(math.pi, rel=1e-9)
    right = circle_condition(plant, kf.L)                      # T V T* >= R
    assert right.passed and right.V_source == "T(0)^-1 R"
    assert right.V[0, 0] == pytest.approx(p + 1, rel=1e-10)


def test_discrete_kalman_filters_pass(rng):
    for k in range(25):
        plant = random_observable_plant(rng, int(rng.integers(1, 6)), int(rng.integers(1, 4)), dt=0.1,
                                        stable=(None, True, False)[k % 3])
        res = circle_condition(plant, kalman(plant).L)
        assert res.passed, res.summary()


def test_discrete_singular_A_uses_lyapunov_covariance():
    A = np.array([[0.0, 1.0], [0.0, 0.0]])  # nilpotent: V is not determined by L alone
    plant = Plant(A, [[1.0, 0.0]], Q=np.eye(2), R=[[0.5]], dt=0.1)
    kf = kalman(plant)
    V, source = innovation_covariance(plant, kf.L)
    assert source == "lyapunov"
    np.testing.assert_allclose(V, plant.C @ kf.P @ plant.C.T + plant.R, rtol=1e-9)
    assert circle_condition(plant, kf.L).passed
    with pytest.raises(ValidationError, match="A is singular"):
        innovation_covariance(plant.replace(Q=None), kf.L)


def test_discrete_non_kalman_gain_flagged_by_asymmetric_V(rng):
    plant = random_observable_plant(rng, 3, 2, dt=0.1, stable=True)
    L = kalman(plant).L
    L2 = L @ np.array([[1.0, 0.4], [0.0, 1.0]])
    res = circle_condition(plant, L2)
    assert not res.passed
    assert "not symmetric positive definite" in res.message


# ============================================================================ the 100 plants
def test_100_kalman_filters_pass_and_keep_guaranteed_margins():
    """Issue 7 must-have: circle condition + guaranteed gain/phase margins by closed-loop eigenvalues.

    Perturbations in the innovation channels (A - L Delta C), with Delta
    * uniform k I, k in {0.51, 1, 10, 1000};
    * one channel at a time at 0.51, 10, 1000 and at exp(+-j59 deg);
    * simultaneous diagonal: random mixes of {0.51, 10, 1000}; phases +-59 deg with random signs;
      mixed gain-or-phase per channel (Re delta_i > 1/2 in every channel).
    """
    rng = np.random.default_rng(11)
    ph = np.exp(1j * 59 * DEG)
    n_unstable = 0
    for plant in PLANTS:
        n_unstable += bool(np.max(np.linalg.eigvals(plant.A).real) > 0)
        L = kalman(plant).L
        res = circle_condition(plant, L)
        assert res.passed, res.summary()
        assert res.min_eigenvalue >= -1e-9 * np.linalg.norm(plant.R, 2)
        p = plant.p
        deltas = [k * np.eye(p) for k in (0.51, 1.0, 10.0, 1000.0)]
        for i in range(p):
            for d in (0.51, 10.0, 1000.0, ph, ph.conjugate()):
                D = np.eye(p, dtype=complex)
                D[i, i] = d
                deltas.append(D)
        for _ in range(4):
            deltas.append(np.diag(rng.choice([0.51, 10.0, 1000.0], p)))
            deltas.append(np.diag(np.exp(1j * 59 * DEG * rng.choice([-1, 1], p))))
            deltas.append(np.diag(rng.choice([0.51, 1000.0, ph, ph.conjugate()], p)))
        for D in deltas:
            assert max_re(plant, L, D) < 0, (plant, np.diag(D))
    assert n_unstable >= 30


@pytest.mark.parametrize("k", range(0, 100, 5))
def test_filter_margins_of_kalman_filters(k):
    """Actual per-channel margins contain the guaranteed ones; brackets checked by eigenvalues."""
    plant = PLANTS[k]
    L = kalman(plant).L
    fm = filter_margins(plant, L)
    assert isinstance(fm, FilterMargins) and fm.stable and fm.R_diagonal and fm.circle.passed
    assert fm.guaranteed_gain_margin == (0.5, math.inf)
    assert fm.guaranteed_phase_margin == pytest.approx(60.0)
    assert fm.radius >= 1 - 1e-6                       # min_w sigma_min(R^-1/2 T R^1/2) >= 1
    assert np.all(fm.gain_margin_lower <= 0.5 + 1e-9)
    assert np.all(np.isinf(fm.gain_margin_upper))
    assert np.all(fm.phase_margin >= 60 - 1e-6)
    assert np.all(fm.circle_disk_margin >= fm.radius - 1e-6)  # |S_ii| <= sigma_max(D S D^-1)
    assert np.all(fm.disk_margin > 0)
    p = plant.p
    for i in range(p):
        lo = fm.gain_margin_lower[i]
        if np.isfinite(lo):
            D = np.eye(p)
            D[i, i] = lo + 1e-4 * abs(lo) * np.sign(1 - lo)
            assert max_re(plant, L, D) < 0
            D[i, i] = lo - 1e-4 * abs(lo) * np.sign(1 - lo)
            assert max_re(plant, L, D) > 0
        pm = fm.phase_margin[i]
        if np.isfinite(pm):
            D = np.eye(p, dtype=complex)
            D[i, i] = np.exp(1j * pm * (1 - 1e-4) * DEG)
            assert max_re(plant, L, D) < 0
            D[i, i] = np.exp(1j * pm * (1 + 1e-4) * DEG)
            D2 = D.conj()
            assert max(max_re(plant, L, D), max_re(plant, L, D2)) > 0


def test_discrete_margins_bracketed_and_implied_radius(rng):
    for k in range(8):
        plant = random_observable_plant(rng, int(rng.integers(1, 5)), int(rng.integers(1, 3)), dt=0.1,
                                        stable=(None, True, False)[k % 3])
        kf = kalman(plant)
        fm = filter_margins(plant, kf.L)
        V = plant.C @ kf.P @ plant.C.T + plant.R
        a = 1 / math.sqrt(max(np.linalg.eigvals(np.linalg.solve(plant.R, V)).real))
        assert fm.implied_radius == pytest.approx(a, rel=1e-8)
        assert fm.radius >= a - 1e-8
        lo, hi = fm.guaranteed_gain_margin
        assert lo == pytest.approx(1 / (1 + a)) and hi == pytest.approx(1 / (1 - a))
        p = plant.p
        for g in (lo * 1.001, hi * 0.999):                     # simultaneous, all channels
            assert rho(plant, kf.L, g * np.eye(p)) < 1
        for i in range(p):
            for m in (fm.gain_margin_lower[i], fm.gain_margin_upper[i]):
                if np.isfinite(m):
                    D = np.eye(p)
                    D[i, i] = m + 1e-4 * abs(m) * np.sign(1 - m)
                    assert rho(plant, kf.L, D) < 1
                    D[i, i] = m - 1e-4 * abs(m) * np.sign(1 - m)
                    assert rho(plant, kf.L, D) > 1


# ============================================================================ what does NOT hold
def test_gain_and_phase_together_can_destabilize():
    """x' = x + w, q = 0.01, c = r = 1: l = 1 + sqrt(1.01), destabilized iff Re(delta) <= a / l = 0.4988."""
    plant = Plant([[1.0]], [[1.0]], Q=[[0.01]], R=[[1.0]])
    L = kalman(plant).L
    assert L[0, 0] == pytest.approx(1 + math.sqrt(1.01), rel=1e-12)
    assert max_re(plant, L, np.array([[0.51]])) < 0                      # gain alone: fine
    assert max_re(plant, L, np.array([[np.exp(1j * 59 * DEG)]])) < 0     # phase alone: fine
    both = 0.51 * np.exp(1j * 59 * DEG)                                  # Re = 0.263 < 1/2
    assert max_re(plant, L, np.array([[both]])) == pytest.approx(1 - both.real * L[0, 0], rel=1e-12)
    assert max_re(plant, L, np.array([[both]])) > 0
    fm = filter_margins(plant, L)
    assert fm.gain_margin_lower[0] == pytest.approx(1 / L[0, 0], rel=1e-9)   # delta = a / l
    assert fm.phase_margin[0] == pytest.approx(math.degrees(math.acos(1 / L[0, 0])), rel=1e-9)


def crossfeed_search(R, bound, xs, seed, tries=200):
    rng = np.random.default_rng(seed)
    for _ in range(tries):
        n = int(rng.integers(2, 4))
        F = rng.standard_normal((n, n))
        plant = Plant(rng.standard_normal((n, n)), rng.standard_normal((2, n)),
                      Q=F @ F.T * rng.choice([0.01, 1, 100]), R=R)
        if not plant.is_observable():
            continue
        L = kalman(plant).L
        # inside the guaranteed bound: always stable
        for x in np.linspace(-0.99, 0.99, 9) * bound:
            assert max_re(plant, L, np.array([[1.0, x], [0.0, 1.0]])) < 0
        for x in np.concatenate([xs, -xs]):
            if max_re(plant, L, np.array([[1.0, x], [0.0, 1.0]])) > 0:
                return x
    return None


def test_crossfeed_beyond_norm_bound_can_destabilize():
    """R = I: Delta = [[1, x], [0, 1]] (both eigenvalues at the nominal 1) is guaranteed for |x| < 1 only."""
    x = crossfeed_search(np.eye(2), 1.0, np.array([1.5, 2.0, 3.0]), seed=0)
    assert x is not None and 1.0 < abs(x) <= 3.0


def test_eq23_as_printed_fails_square_root_bound_holds():
    """Seed 002 eq (23) prints sigma_max(X) < sigma(R1)/sigma(R2) for Delta = [[I, X], [0, I]].

    With R = diag(16, 1) the printed bound is 16; the bound implied by the circle condition is
    sqrt(sigma_min(R1) / sigma_max(R2)) = 4 (R^-1/2 (Delta^-1 - I) R^1/2 = [[0, -X/4], [0, 0]]).
    A Kalman filter destabilized by |x| in (4, 16) is found; |x| < 4 never destabilizes.
    """
    x = crossfeed_search(np.diag([16.0, 1.0]), 4.0, np.linspace(4.0, 16.0, 12)[1:-1], seed=0)
    assert x is not None and 4.0 < abs(x) < 16.0


def test_non_diagonal_R_loses_per_channel_margins():
    rng = np.random.default_rng(3)
    R = np.array([[1.0, 9.5], [9.5, 100.0]])       # correlation 0.95
    found = False
    for _ in range(50):
        n = int(rng.integers(2, 4))
        F = rng.standard_normal((n, n))
        plant = Plant(rng.standard_normal((n, n)), rng.standard_normal((2, n)), Q=F @ F.T, R=R)
        if not plant.is_observable():
            continue
        L = kalman(plant).L
        assert circle_condition(plant, L).passed
        for k in (0.51, 1000.0, np.exp(1j * 59 * DEG)):           # uniform delta I: still guaranteed
            assert max_re(plant, L, k * np.eye(2)) < 0
        for D in (np.diag([1.0, 0.51]), np.diag([1.0, 1000.0]), np.diag([0.51, 1000.0]),
                  np.diag([1.0, np.exp(1j * 59 * DEG)])):
            if max_re(plant, L, D) > 0:
                found = True
                fm = filter_margins(plant, L)
                assert not fm.R_diagonal
                assert "NOT diagonal" in fm.guarantee_scope
                assert any("not diagonal" in s for s in fm.notes)
        if found:
            break
    assert found


# ============================================================================ non-optimal gains
def _dip_plant():
    """Open-loop pairs -0.001 +- 10j and -1 +- 1j; the gain puts poles at -0.0005 +- 10j and -3 +- 1j.

    |T(jw)|^2 = |det(jwI - A + LC)|^2 / |det(jwI - A)|^2 is > 1 except in a dip of width ~1e-3 at
    w = 10, where it drops to about 0.25 * 1.17.
    """
    ol = np.array([-0.001 + 10j, -0.001 - 10j, -1 + 1j, -1 - 1j])
    coeffs = np.real(np.poly(ol))
    A = np.zeros((4, 4))
    A[0, :] = -coeffs[1:]
    A[1:, :-1] = np.eye(3)
    plant = Plant(A, [[0.0, 0.0, 0.0, 1.0]], R=[[1.0]])
    L = place_observer(plant, [-0.0005 + 10j, -0.0005 - 10j, -3 + 1j, -3 - 1j])
    return plant, L


def test_adaptive_search_finds_narrow_dip():
    plant, L = _dip_plant()
    res = circle_condition(plant, L)
    assert not res.passed
    assert res.omega_worst == pytest.approx(10.0, abs=2e-3)
    # the true minimum, by brute force in the dip
    w = np.linspace(9.995, 10.005, 40001)
    T = return_difference(plant, L, w)[:, 0, 0]
    true_min = float(np.min(np.abs(T) ** 2 - 1))
    assert true_min < -0.6
    assert res.min_eigenvalue == pytest.approx(true_min, abs=1e-5)
    assert res.min_eigenvalue <= true_min + 1e-12      # refinement beats the brute-force grid
    # a plain log grid with 2000 points over 5 decades misses it
    coarse = circle_condition(plant, L, omega=np.logspace(-2, 3, 2000), refine=False)
    assert coarse.min_eigenvalue > -1e-3
    # certificate: Re(delta) > 1/2 puts a closed-loop eigenvalue at j omega_worst
    D = res.perturbation
    assert D.shape == (1, 1) and D[0, 0].real > 0.5
    eig = np.linalg.eigvals(plant.A - L @ D @ plant.C)
    assert np.min(np.abs(eig - 1j * res.omega_worst)) < 1e-6
    cert = res.certificate
    json.dumps(cert)
    assert cert["omega_worst"] == res.omega_worst and cert["passed"] is False


def test_non_optimal_gains_reported_with_worst_frequency(rng):
    failed = 0
    for _ in range(30):
        plant = random_observable_plant(rng, 3, 2)
        target = -rng.uniform(0.2, 5.0, 3)
        L = place_observer(plant, target)
        res = circle_condition(plant, L)
        if res.passed:
            continue
        failed += 1
        assert res.min_eigenvalue < -res.tol
        # recompute at the reported frequency, independently
        T = np.eye(2) + plant.C @ np.linalg.solve(1j * res.omega_worst * np.eye(3) - plant.A, L)
        lam = np.linalg.eigvalsh(T @ plant.R @ T.conj().T - plant.R)[0]
        assert lam == pytest.approx(res.min_eigenvalue, abs=1e-9 * max(1, abs(lam)))
        # the certificate perturbation (R-weighted distance < 1) puts an eigenvalue at j omega_worst
        D = res.perturbation
        Rh = np.sqrt(plant.R)       # R diagonal
        size = np.linalg.norm(np.linalg.inv(Rh) @ (np.linalg.inv(D) - np.eye(2)) @ Rh, 2)
        assert size < 1
        eig = np.linalg.eigvals(plant.A - L @ D @ plant.C)
        assert np.min(np.abs(eig - 1j * res.omega_worst)) < 1e-6 * max(1, res.omega_worst)
    assert failed >= 5


# ============================================================================ edge cases and errors
def test_integrator_poles_on_axis():
    """Double integrator: T is infinite at w = 0; the search steps around the pole."""
    plant = Plant([[0.0, 1.0], [0.0, 0.0]], [[1.0, 0.0]], G=[[0.0], [1.0]], Q=[[4.0]], R=[[0.25]])
    L = kalman(plant).L
    res = circle_condition(plant, L)
    assert res.passed and np.all(np.isfinite(res.values))
    with pytest.raises(ValidationError, match="pole of the loop"):
        return_difference(plant, L, [0.0])
    fm = filter_margins(plant, L)
    assert fm.phase_margin[0] >= 60 and fm.gain_margin_lower[0] <= 0.5


def test_unstable_filter_margins_are_nan(rng):
    plant = random_observable_plant(rng, 2, 1, stable=True)
    L = place_observer(plant, [0.5, -1.0])
    fm = filter_margins(plant, L)
    assert not fm.stable and np.all(np.isnan(fm.gain_margin_lower)) and math.isnan(fm.radius)
    assert "unstable" in fm.summary().lower()


def test_margins_from_radius():
    assert margins_from_radius(1.0) == ((0.5, math.inf), pytest.approx(60.0))
    (lo, hi), pm = margins_from_radius(0.5)
    assert (lo, hi) == (pytest.approx(2 / 3), pytest.approx(2.0))
    assert pm == pytest.approx(2 * math.degrees(math.asin(0.25)))
    (lo, hi), pm = margins_from_radius(1.0, skew=0.0)
    assert lo == pytest.approx(1 / 3) and hi == pytest.approx(3.0)
    assert pm == pytest.approx(2 * math.degrees(math.atan(0.5)))
    assert margins_from_radius(0.0) == ((1.0, 1.0), 0.0)
    with pytest.raises(ValidationError, match="skew must be"):
        margins_from_radius(1.0, skew=0.5)


def test_frequency_grid_and_adaptive_minimize():
    plant = Plant([[-0.001, 10.0], [-10.0, -0.001]], [[1.0, 0.0]])
    w = frequency_grid(plant)
    assert w[0] == 0.0 and np.all(np.diff(w) > 0)
    assert np.sum(np.abs(w - 10.0) < 0.01) >= 9            # cluster resolves the resonance
    wd = frequency_grid(plant.replace(A=np.diag([0.5, -0.9]), dt=0.2))
    assert wd[0] == 0.0 and wd[-1] == pytest.approx(math.pi / 0.2)
    f = lambda x: (np.log(np.maximum(x, 1e-300)) - math.log(3.7)) ** 2  # noqa: E731
    ws, vs = adaptive_minimize(f, np.logspace(-2, 2, 9))
    assert ws[np.argmin(vs)] == pytest.approx(3.7, rel=1e-8)


def test_result_types_and_summary(rng):
    plant = random_observable_plant(rng, 2, 1)
    res = circle_condition(plant, kalman(plant).L)
    assert isinstance(res, CircleConditionResult)
    assert res.omega.shape == res.values.shape and np.all(np.diff(res.omega) >= 0)
    assert "holds" in res.summary() and "holds" in repr(res)
    with pytest.raises(AttributeError):
        res.passed = False
    with pytest.raises(ValueError):
        res.values[0] = 1.0


def test_errors(rng):
    plant = random_observable_plant(rng, 3, 2)
    L = kalman(plant).L
    with pytest.raises(DimensionError, match="L has the wrong shape"):
        return_difference(plant, L[:, :1], [1.0])
    with pytest.raises(NotFiniteError, match="omega must be finite"):
        return_difference(plant, L, [np.nan])
    with pytest.raises(ValidationError, match="plant must be an optdesign.Plant"):
        circle_condition(plant.A, L)
    with pytest.raises(ValidationError, match="needs the measurement-noise covariance R"):
        circle_condition(plant.replace(R=None), L)
    with pytest.raises(NotPositiveDefiniteError, match="R must be positive definite"):
        circle_condition(plant, L, R=-np.eye(2))
    with pytest.raises(DimensionError, match="R has the wrong shape"):
        filter_margins(plant, L, R=np.eye(3))
    with pytest.raises(ValidationError, match="V is only used in discrete time"):
        circle_condition(plant, L, V=np.eye(2))
    with pytest.raises(ValidationError, match="tol must be finite"):
        circle_condition(plant, L, tol=-1.0)
    with pytest.raises(DimensionError, match="at least one frequency"):
        circle_condition(plant, L, omega=[])
    with pytest.raises(ValidationError, match="for discrete plants"):
        innovation_covariance(plant, L)
    dplant = random_observable_plant(rng, 2, 1, dt=0.1)
    with pytest.raises(DimensionError, match="V has the wrong shape"):
        circle_condition(dplant, kalman(dplant).L, V=np.eye(2))
    sing = Plant(np.zeros((2, 2)), [[1.0, 1.0]], R=[[1.0]], dt=0.1)
    with pytest.raises(ValidationError, match="pass V|give V"):
        circle_condition(sing, [[0.1], [0.1]])


# ============================================================================ bad input (issue 11, item 5)
def test_frequencies_and_numbers_are_validated(rng):
    plant = random_observable_plant(rng, 3, 2)
    L = kalman(plant).L
    # a bare numpy ValueError before ("could not convert string to float"), and "1" was accepted
    with pytest.raises(ValidationError, match="omega must be numeric; found dtype <U1"):
        return_difference(plant, L, ["a"])
    with pytest.raises(ValidationError, match="omega must be numeric"):
        return_difference(plant, L, ["1"])
    with pytest.raises(DimensionError, match=r"omega must be a vector .*found shape \(2, 2\)"):
        return_difference(plant, L, np.ones((2, 2)))
    # the search grids: finite, nonnegative, not empty (a NaN frequency gave a NaN verdict)
    for fn in (circle_condition, filter_margins):
        with pytest.raises(NotFiniteError, match="omega must be finite; found nan at index 1"):
            fn(plant, L, omega=[1.0, np.nan])
        with pytest.raises(ValidationError, match=r"omega must be >= 0 \(rad/s\); found -1 at index 0"):
            fn(plant, L, omega=[-1.0, 2.0])
    with pytest.raises(ValidationError, match=r"tol must be a real number; found '1e-8' \(a string\)"):
        circle_condition(plant, L, tol="1e-8")
    with pytest.raises(ValidationError, match="refine must be true or false; found 1"):
        circle_condition(plant, L, refine=1)
    with pytest.raises(ValidationError, match="points_per_decade must be an integer >= 1; found '30'"):
        frequency_grid(plant, points_per_decade="30")
    with pytest.raises(ValidationError, match="extra_poles must be numeric"):
        frequency_grid(plant, extra_poles=["-1"])
    with pytest.raises(ValidationError, match=r"alpha must be a real number; found '1' \(a string\)"):
        margins_from_radius("1")
    with pytest.raises(ValidationError, match="skew must be 0 .balanced. or 1 .circle.; found True"):
        margins_from_radius(1.0, skew=True)
    with pytest.raises(ValidationError, match="n_refine must be an integer >= 0; found -1"):
        adaptive_minimize(np.abs, np.linspace(0, 1, 5), n_refine=-1)
    for fn in (circle_condition, filter_margins):
        with pytest.raises(ValidationError, match="time_limit must be a number of seconds > 0 or None; "
                                                  "found '5'"):
            fn(plant, L, time_limit="5")
    with pytest.raises(ValidationError, match="time_limit must be a finite number of seconds > 0"):
        return_difference(plant, L, [1.0], time_limit=0.0)


# ============================================================================ time limits (issue 11, item 9)
def test_time_limit_keeps_what_was_evaluated(rng):
    plant = random_observable_plant(rng, 3, 2)
    L = kalman(plant).L
    full = circle_condition(plant, L)
    same = circle_condition(plant, L, time_limit=3600.0)  # a limit that is not reached changes nothing
    assert same.complete and same.passed == full.passed
    np.testing.assert_array_equal(same.omega, full.omega)
    np.testing.assert_array_equal(same.values, full.values)
    cut = circle_condition(plant, L, time_limit=1e-9)  # expired at once: one chunk of the grid
    assert not cut.complete and not cut.passed  # a partial search proves nothing...
    assert 0 < cut.omega.size < full.omega.size
    assert "UNDECIDED (time limit)" in cut.summary() and "not proven" in cut.message
    assert cut.min_eigenvalue >= full.min_eigenvalue  # ...and saw less of the curve
    assert cut.certificate["complete"] is False


def test_time_limit_still_reports_a_violation_it_found():
    # a placed gain that is not Kalman-optimal: T R T* - R < 0 near its resonance, in the first chunk
    plant = Plant([[0.0, 1.0], [-1.0, -0.1]], [[1.0, 0.0]], R=[[1.0]])
    L = place_observer(plant, [-0.05 + 3j, -0.05 - 3j])
    w = np.linspace(0.0, 4.0, 100)  # fewer than one chunk: evaluated whatever the limit
    cut = circle_condition(plant, L, omega=w, time_limit=1e-9)
    assert not cut.complete and not cut.passed and cut.min_eigenvalue < -cut.tol
    assert "< -tol" in cut.message and "the violation found is certain" in cut.message
    assert "FAILS" in cut.summary()


def test_filter_margins_time_limit(rng):
    plant = random_observable_plant(rng, 3, 2, stable=True)
    L = kalman(plant).L
    fm = filter_margins(plant, L, time_limit=1e-9)
    assert not fm.complete and not fm.circle.complete
    assert np.all(np.isnan(fm.gain_margin_lower)) and math.isnan(fm.radius)
    assert any("time_limit" in note and "0 of 2 channel(s)" in note for note in fm.notes)
    assert any("stopped by the time limit" in note for note in fm.notes)
    full = filter_margins(plant, L, time_limit=3600.0)
    assert full.complete and np.all(np.isfinite(full.disk_margin)) and np.isfinite(full.radius)
    np.testing.assert_array_equal(full.disk_margin, filter_margins(plant, L).disk_margin)


def test_return_difference_time_limit(rng):
    from optdesign.analysis.frequency import CHUNK

    plant = random_observable_plant(rng, 3, 1)
    L = kalman(plant).L
    w = np.linspace(0.1, 50.0, 3 * CHUNK)
    with pytest.warns(RuntimeWarning, match=rf"reached after {CHUNK} of {3 * CHUNK} frequencies"):
        T = return_difference(plant, L, w, time_limit=1e-9)
    np.testing.assert_array_equal(T[:CHUNK], return_difference(plant, L, w[:CHUNK]))
    assert np.all(np.isnan(T[CHUNK:]))
    np.testing.assert_array_equal(return_difference(plant, L, w, time_limit=3600.0),
                                  return_difference(plant, L, w))
