"""The ``kalman`` verb: closed-form references, seed 001 eq (28)-(29), SLICOT, random plants, errors."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import random_observable_plant

import optdesign
from optdesign import KalmanFilter, Plant, kalman, problems
from optdesign.errors import NotObservableError, RiccatiError, SolverError, ValidationError
from optdesign.results import Status

CHECKS = ["riccati_residual", "forward_error", "P_min_eig", "stability_margin", "cross_check"]


# ------------------------------------------------------------------ closed-form filters
@pytest.mark.parametrize("method", ["scipy", "hamiltonian"])
def test_double_integrator_library_reference(method):
    prob = problems.load("kf_analytic_double_integrator_ct")
    kf = kalman(prob.plant, method=method)
    np.testing.assert_allclose(kf.P, prob.references["P"], rtol=1e-12)
    np.testing.assert_allclose(kf.L, prob.references["L"], rtol=1e-12)
    assert kf.success and kf.Kf is None


@pytest.mark.parametrize("q,r", [(1.0, 1.0), (4.0, 0.25), (1e-3, 10.0), (250.0, 0.01)])
def test_double_integrator_closed_form(q, r):
    """x'' = w, y = x + v: P11 = sqrt2 q^1/4 r^3/4, P12 = sqrt(q r), P22 = sqrt2 q^3/4 r^1/4,
    L = [sqrt2 w, w^2] with w = (q/r)^1/4, poles s^2 + sqrt2 w s + w^2 (Butterworth).

    Written both ways: G = [0; 1] with Q = q, and G = I with Q = diag(0, q).
    """
    w = (q / r) ** 0.25
    P = np.array([[np.sqrt(2) * q**0.25 * r**0.75, np.sqrt(q * r)],
                  [np.sqrt(q * r), np.sqrt(2) * q**0.75 * r**0.25]])
    A, C = [[0.0, 1.0], [0.0, 0.0]], [[1.0, 0.0]]
    for plant in (Plant(A, C, G=[[0.0], [1.0]], Q=[[q]], R=[[r]]),
                  Plant(A, C, Q=np.diag([0.0, q]), R=[[r]])):
        kf = kalman(plant)
        np.testing.assert_allclose(kf.P, P, rtol=1e-10)
        np.testing.assert_allclose(kf.L.ravel(), [np.sqrt(2) * w, w * w], rtol=1e-10)
        np.testing.assert_allclose(np.sort_complex(kf.poles),
                                   np.sort_complex(np.roots([1.0, np.sqrt(2) * w, w * w])), rtol=1e-10)
        assert kf.success


def test_scalar_filter():
    """python-control's test_LQE (library problem) and the general scalar closed form
    P = r (a + sqrt(a^2 + c^2 w / r)) / c^2 with w = g^2 q."""
    prob = problems.load("kf_python_control_scalar_lqe")
    kf = kalman(prob.plant)
    assert kf.P[0, 0] == pytest.approx(prob.references["P"].item(), rel=1e-13)
    assert kf.L[0, 0] == pytest.approx(prob.references["L"].item(), rel=1e-13)
    np.testing.assert_allclose(kf.poles, prob.references["poles"], rtol=1e-13)
    rng = np.random.default_rng(7)
    for _ in range(10):
        a, (c, g), (q, r) = rng.normal(), rng.uniform(0.2, 3, 2), rng.uniform(0.1, 5, 2)
        kf = kalman(Plant([[a]], [[c]], G=[[g]], Q=[[q]], R=[[r]]))
        P = r * (a + np.sqrt(a * a + c * c * g * g * q / r)) / (c * c)
        assert kf.P[0, 0] == pytest.approx(P, rel=1e-12)
        assert kf.poles[0].real == pytest.approx(-np.sqrt(a * a + c * c * g * g * q / r), rel=1e-12)


def test_alpha_beta_tracker_discrete():
    """Kalata's steady-state alpha-beta filter: filtered gain Kf = [alpha, beta / T]; L = A Kf."""
    prob = problems.load("kf_analytic_alpha_beta_dt")
    for method in ("scipy", "hamiltonian"):
        kf = kalman(prob.plant, method=method)
        np.testing.assert_allclose(kf.Kf.ravel(), prob.references["K_filtered"].ravel(), rtol=1e-12)
        np.testing.assert_allclose(kf.L, prob.plant.A @ kf.Kf, rtol=1e-14)
        assert kf.success
    # the closed form over a range of tracking indices lambda = sigma_w T^2 / sigma_v
    for T, sw, sv in [(1.0, 0.5, 2.0), (0.1, 3.0, 0.5), (2.0, 0.01, 1.0), (0.5, 10.0, 0.1)]:
        lam = sw * T * T / sv
        rr = (4 + lam - np.sqrt(8 * lam + lam * lam)) / 4
        alpha = 1 - rr * rr
        beta = 2 * (2 - alpha) - 4 * np.sqrt(1 - alpha)
        plant = Plant([[1.0, T], [0.0, 1.0]], [[1.0, 0.0]], G=[[T * T / 2], [T]], Q=[[sw * sw]],
                      R=[[sv * sv]], dt=T)
        kf = kalman(plant)
        np.testing.assert_allclose(kf.Kf.ravel(), [alpha, beta / T], rtol=1e-9)


def test_seed001_eq29_second_order_gain():
    """Seed 001 eq (28)-(29): for A = [[0, 1], [a, b]], G = [0; 1], C = [1, 0], Q = q, R = r,
    L = [b + s, a + b^2 + t + b s] with t = sqrt(a^2 + q/r), s = sqrt(b^2 + 2a + 2t), and
    P11 = r L1, P12 = r L2 (eq 28).  It depends on q/r only (the paper's point); checked for
    Example 2 (a = 2, b = -1) over q/r in [1e-3, 1e3] and for random (a, b)."""
    prob = problems.load("jung_huh_ex2")
    a, b = prob.data["a"], prob.data["b"]
    rng = np.random.default_rng(29)
    cases = [(a, b, qr, r) for qr in np.logspace(-3, 3, 13) for r in (1.0, 7.5)]
    cases += [(rng.uniform(-5, 5), rng.uniform(-5, 5), 10 ** rng.uniform(-2, 2), 1.0) for _ in range(20)]
    for a_, b_, qr, r in cases:
        plant = Plant([[0.0, 1.0], [a_, b_]], [[1.0, 0.0]], G=[[0.0], [1.0]], Q=[[qr * r]], R=[[r]])
        kf = kalman(plant)
        t = np.sqrt(a_ * a_ + qr)
        s = np.sqrt(b_ * b_ + 2 * a_ + 2 * t)
        L = np.array([b_ + s, a_ + b_ * b_ + t + b_ * s])
        np.testing.assert_allclose(kf.L.ravel(), L, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose([kf.P[0, 0], kf.P[0, 1]], r * L, rtol=1e-9, atol=1e-12)
    # the plant of the library problem itself (Q is the design parameter there)
    assert prob.plant.Q is None
    kf = kalman(prob.plant.replace(Q=[[3.0]]))
    assert kf.L[0, 0] == pytest.approx(b + np.sqrt(b * b + 2 * a + 2 * np.sqrt(a * a + 3.0)), rel=1e-12)


def test_slicot_fb01qd_recursion_converges_to_kalman():
    """SLICOT FB01QD: three predictor-form recursion steps from P0 = 0 reproduce the printed
    P (formed from the 4-decimal Cholesky factor: ~1e-4) and predictor gain (4 decimals);
    iterated to convergence the recursion reaches kalman()'s a-priori P and predictor L,
    which confirms the discrete convention (error dynamics A - L C, L = A P C'(CPC'+R)^-1)."""
    prob = problems.load("kf_slicot_fb01qd")
    plant = prob.plant
    A, C, W, R = plant.A, plant.C, plant.process_noise(), plant.R
    P = np.zeros((4, 4))

    def step(P):
        S = C @ P @ C.T + R
        K = A @ P @ C.T @ np.linalg.inv(S)
        return A @ P @ A.T + W - K @ S @ K.T, K

    for _ in range(3):
        P, K = step(P)
    np.testing.assert_allclose(P, prob.references["P_after3_4dec"], atol=3e-4)
    np.testing.assert_allclose(K, prob.references["L_after3_4dec"], atol=5.1e-5)
    for _ in range(400):
        P, K = step(P)
    kf = kalman(plant)
    np.testing.assert_allclose(kf.P, P, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(kf.L, K, rtol=1e-12, atol=1e-12)
    assert kf.success and max(abs(kf.poles)) < 1


# ------------------------------------------------------------------- random properties
def _random_plants():
    rng = np.random.default_rng(20260502)
    out = []
    for i in range(50):
        n = int(rng.integers(2, 7))
        p = int(rng.integers(1, 3))
        dt = None if i % 2 == 0 else 0.1
        stable = (i // 2) % 2 == 0
        out.append(random_observable_plant(rng, n, p, stable=stable, dt=dt))
    return out


@pytest.mark.parametrize("method", ["scipy", "hamiltonian"])
def test_random_plants(method):
    plants = _random_plants()
    kinds = {(pl.is_discrete, bool(np.max(np.abs(np.linalg.eigvals(pl.A))) >= 1 if pl.is_discrete
                                   else np.max(np.linalg.eigvals(pl.A).real) >= 0)) for pl in plants}
    assert kinds == {(False, False), (False, True), (True, False), (True, True)}
    for plant in plants:
        kf = kalman(plant, method=method)
        assert kf.status is Status.SOLVED and kf.success, kf.summary()
        assert kf.residual < 1e-10
        if plant.is_discrete:
            assert np.max(np.abs(kf.poles)) < 1
            np.testing.assert_allclose(kf.L, plant.A @ kf.Kf, rtol=1e-10, atol=1e-13)
        else:
            assert np.max(kf.poles.real) < 0
            L = kf.P @ plant.C.T @ np.linalg.inv(plant.R)
            np.testing.assert_allclose(kf.L, L, rtol=1e-10, atol=1e-13)
        assert np.min(np.linalg.eigvalsh(kf.P)) > -1e-10 * np.linalg.norm(kf.P, 2)
        assert kf.verification["cross_check"].value < 1e-8
        np.testing.assert_array_equal(kf.P, kf.P.T)
        np.testing.assert_allclose(np.sort_complex(kf.poles),
                                   np.sort_complex(np.linalg.eigvals(plant.A - kf.L @ plant.C)), rtol=1e-10)


# -------------------------------------------------------------------- result object
def test_result_object_and_summary():
    prob = problems.load("kf_analytic_double_integrator_ct")
    kf = kalman(prob.plant)
    assert isinstance(kf, KalmanFilter)
    assert [c.name for c in kf.verification] == CHECKS
    assert kf.solver_stats.backend == "scipy" == kf.method
    assert kf.solver_stats.extra["cross_check_method"] == "hamiltonian"
    assert kf.solver_stats.time >= 0
    assert kf.raise_for_status() is kf
    with pytest.raises(AttributeError):
        kf.L = None
    text = kf.summary()
    for piece in ("Kalman filter for plant 'kf_analytic_double_integrator_ct' (continuous, n = 2, p = 1",
                  "method: scipy", "success: True", "L = [[2.828427", "P = ", "poles of A - L C: -1.41421",
                  "Riccati residual (relative):", *CHECKS):
        assert piece in text, piece
    assert "Kf =" not in text
    dkf = kalman(problems.load("kf_analytic_alpha_beta_dt").plant, method="hamiltonian")
    dtext = dkf.summary()
    assert "discrete, dt = 1" in dtext and "Kf = [[0.505137" in dtext and "method: hamiltonian" in dtext
    assert "KalmanFilter(" in repr(dkf) and "success=True" in repr(dkf)


def test_lazy_public_names():
    assert optdesign.kalman is kalman
    assert optdesign.KalmanFilter is KalmanFilter


# ------------------------------------------------- honest verification on hard problems
def test_cross_check_flags_carex_2_8():
    """CAREX 2.8 as a filter: scipy returns P with a tiny residual but 4.7e-4 relative error
    (closed-loop poles -5e-13 +- 1j: the equation is ill-conditioned).  The forward-error
    estimate sees it (its rounding floor ||Omega^-1|| n eps is large) and the Hamiltonian solver
    refuses (ill-conditioned subspace), so the result is not a success."""
    kf = kalman(problems.load("carex_2.8").plant, method="scipy")
    assert kf.status is Status.SOLVED and not kf.success
    failed = kf.verification.failed
    assert [c.name for c in failed] == ["forward_error", "cross_check"]
    fe = kf.verification["forward_error"]
    assert fe.value > 4.7e-4 > fe.tolerance  # the estimate covers the measured 4.7e-4 error
    assert failed[1].value == np.inf and "hamiltonian solver failed" in failed[1].detail
    assert "failed checks: forward_error, cross_check" in kf.message
    with pytest.raises(SolverError, match="failed checks: .*cross_check"):
        kf.raise_for_status()


def test_cross_check_explains_carex_2_6_by_the_other_solvers_error():
    """CAREX 2.6 as a filter (badly scaled): the Hamiltonian solver is right (3e-15 from the
    analytic X) and scipy's P is 5e-4 .. 2e-3 off, by how much depending on the CPU's rounding.
    The cross-check compares the difference with the two solutions' own a posteriori error
    estimates: scipy's residual explains the whole difference, the Hamiltonian solution's
    estimate is at rounding level -- so the Hamiltonian design verifies, and scipy's is refused
    by its residual.  (Before the error estimates, a fixed 1e-6 cross-check tolerance failed the
    right answer.)"""
    prob = problems.load("carex_2.6")
    kf = kalman(prob.plant, method="hamiltonian")
    assert np.linalg.norm(kf.P - prob.references["X"]) / np.linalg.norm(prob.references["X"]) < 1e-12
    assert kf.success, kf.verification.summary()
    cc = kf.verification["cross_check"]
    assert cc.value > 1e-4  # scipy really is off ...
    assert kf.verification["forward_error"].value < 1e-13  # ... and ours really is not
    # scipy's answer is refused by its residual; the Hamiltonian solver answers as the fallback
    # (it raised RiccatiError before the fallback), and the route says so
    fb = kalman(prob.plant, method="scipy")
    assert [(s.name, s.kind, s.outcome) for s in fb.route] == [("scipy", "backend", "failed"),
                                                                ("hamiltonian", "fallback", "answered")]
    assert "relative residual" in fb.route[0].detail and "fallback: the scipy solver failed" in fb.message
    assert fb.method == "hamiltonian" and fb.success
    np.testing.assert_allclose(fb.P, kf.P, rtol=1e-12)


def test_route_names_the_riccati_method_that_ran():
    plant = Plant([[0.0, 1.0], [-2.0, -0.3]], [[1.0, 0.0]], Q=np.eye(2), R=[[0.5]])
    for method, kind in (("scipy", "backend"), ("hamiltonian", "engine")):
        kf = kalman(plant, method=method)
        assert len(kf.route) == 1 and kf.route.answered.name == method and kf.route[0].kind == kind
        assert kf.route[0].time is not None and kf.record()["route"] == method


# ------------------------------------------------------------------------ error paths
def test_errors():
    with pytest.raises(ValidationError, match="has no Q and no R: a Kalman filter needs"):
        kalman(Plant([[0.0, 1.0], [0.0, 0.0]], [[1.0, 0.0]]))
    with pytest.raises(ValidationError, match="plant 'x' has no R"):
        kalman(Plant([[0.0]], [[1.0]], Q=[[1.0]], name="x"))
    with pytest.raises(ValidationError, match="plant must be an optdesign.Plant, a python-control StateSpace "
                                              "or a scipy.signal StateSpace / lti / dlti .*; found ndarray"):
        kalman(np.eye(2))
    with pytest.raises(ValidationError, match=r"method must be one of \('scipy', 'hamiltonian'\); found"):
        kalman(Plant([[0.0]], [[1.0]], Q=[[1.0]], R=[[1.0]]), method="lqe")


@pytest.mark.parametrize("dt", [None, 0.5])
def test_undetectable_plant(dt):
    A = [[1.2, 0.0], [0.0, 0.3]] if dt else [[0.5, 0.0], [0.0, -2.0]]
    plant = Plant(A, [[0.0, 1.0]], Q=np.eye(2), R=[[1.0]], dt=dt)
    match = r"undetectable, so a stabilizing Kalman filter is impossible"
    with pytest.raises(NotObservableError, match=match) as ei:
        kalman(plant)
    np.testing.assert_allclose(ei.value.modes, [1.2 if dt else 0.5])


@pytest.mark.parametrize("dt,where", [(None, "imaginary axis"), (1.0, "unit circle")])
def test_mode_on_boundary_not_excited(dt, where):
    """An undamped oscillator (continuous) / a rotation (discrete) that the noise does not drive."""
    A = [[0.0, 1.0], [-1.0, 0.0]]
    plant = Plant(A, [[1.0, 0.0]], G=[[0.0], [0.0]], Q=[[1.0]], R=[[1.0]], dt=dt)
    with pytest.raises(RiccatiError, match=rf"mode\(s\) 0\+1j, 0-1j on the {where} are not excited"):
        kalman(plant)
    with pytest.raises(RiccatiError, match=rf"mode\(s\) 0\+1j, 0-1j on the {where} are not excited"):
        kalman(plant, method="hamiltonian")
    # driven by the noise, the same plant has a stabilizing filter
    assert kalman(plant.replace(G=[[0.0], [1.0]])).success


def test_time_limit_skips_the_cross_check_honestly():
    plant = problems.load("kf_analytic_double_integrator_ct").plant
    kf = kalman(plant, time_limit=1e-9)
    assert kf.status is Status.TIME_LIMIT and not kf.success
    assert "not run: the time limit" in kf.verification["cross_check"].detail
    assert kalman(plant, time_limit=60.0).success
    with pytest.raises(ValidationError, match="time_limit must be"):
        kalman(plant, time_limit="1")
