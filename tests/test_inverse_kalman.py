"""Inverse Kalman problem (issue 3, seed 000): kalman_for_poles and is_kalman_optimal.

Paper references (Chang & Lee 1984 Examples 1 and 2), the double-integrator feasibility
examples of the issue, the linear-in-P relations in continuous and discrete time, the spectral
identity, objectives (which member of the Q family), structured Q, certificates, cross-validation
on random feasible targets, and every error path.
"""

from __future__ import annotations

import dataclasses
import subprocess
import sys
from types import SimpleNamespace

import numpy as np
import pytest
from conftest import random_observable_plant

from optdesign import (
    InverseKalmanResult,
    KalmanOptimalityResult,
    Plant,
    Status,
    is_kalman_optimal,
    kalman_for_poles,
    problems,
)
from optdesign.classical import solheim
from optdesign.classical.placement import place_observer, pole_error
from optdesign.classical.riccati import filter_are, filter_are_residual, filter_gain
from optdesign.design.inverse_kalman.sdp_stage import sdp_fixed_gain as _sdp_fixed_gain
from optdesign.design.verification import pole_tolerance as _pole_tolerance
from optdesign.engines.polish import face_polish as _face_polish
from optdesign.errors import (
    DimensionError,
    NotConjugateClosedError,
    NotObservableError,
    NotPositiveDefiniteError,
    OptDesignDeprecationWarning,
    RiccatiError,
    ValidationError,
)
from optdesign.formulate.inverse_kalman import (
    build_fixed_gain_sdp,
    build_spectral_nlp,
    fixed_gain_maps,
    spectral_terms,
)

#: random targets of the cross-validation: the issue's 200 (about 55 s of CPU on the reference
#: machine, 70 s wall under load -- within budget, so it is not reduced by default)
CV_COUNT = 200


def _ex1_plant():
    return problems.load("chang_lee_1984_ex1").plant.replace(Q=None, G=None)


def _are(plant, Q):
    return filter_are(plant.replace(G=None, Q=Q))


def _q_of_p22(x):
    """Example 1's family of Q (L = [8, -6] fixed, P = [[8, -6], [-6, x]])."""
    return np.array([[76.0, -30.0 - x], [-30.0 - x, 10.0 * x - 36.0]])


def _assert_valid(res: InverseKalmanResult, plant: Plant, target, tol=1e-8):
    """Independent re-checks of a successful design (beyond its own verification)."""
    assert res.success, res.summary()
    assert np.linalg.eigvalsh(res.Q)[0] >= -1e-10 * max(1.0, np.linalg.norm(res.Q))
    are = _are(plant, res.Q)
    assert pole_error(are.poles, target) <= max(tol, _pole_tolerance(plant.A - are.L @ plant.C, tol),
                                                _resolve_pole_tolerance(plant, res.Q, are))
    np.testing.assert_allclose(are.L, res.L, rtol=1e-7, atol=1e-9 * max(1.0, np.linalg.norm(res.L)))


def _resolve_pole_tolerance(plant, Q, are):
    """How accurately the re-solved ARE's poles are known: its P to its forward-error estimate
    (``filter_are_error``), so L to that times ``||L||``, so each pole to ``s_i ||C|| ||dL||`` with
    ``s_i`` its eigenvalue condition number (relative to ``max(1, |lambda|)``); times 4, the margin of
    first-order estimates.  (A rank-deficient Q's re-solve is 2e-10 off with scipy 1.10.)"""
    from optdesign.analysis.metrics import eigenvalue_condition
    from optdesign.classical.riccati import filter_are_error

    err = filter_are_error(plant.replace(G=None, Q=0.5 * (Q + Q.T)), are.P).relative
    w, cond = eigenvalue_condition(plant.A - are.L @ plant.C)
    dL = err * np.linalg.norm(are.L) * np.linalg.norm(plant.C)
    return float(4.0 * np.max(cond * dL / np.maximum(1.0, np.abs(w))))


# ------------------------------------------------------------------- seed 000, Example 1
def test_example1_sdp_gain_and_poles():
    plant = _ex1_plant()
    res = kalman_for_poles(plant, [-5, -8])
    assert res.method == "sdp" and res.status == Status.OPTIMAL
    np.testing.assert_allclose(res.L.ravel(), [8, -6], atol=1e-12)
    _assert_valid(res, plant, [-5, -8], tol=1e-12)


def test_example1_each_objective_picks_a_documented_member_of_the_family():
    """P22 is free: Q(P22) = [[76, -30 - P22], [-30 - P22, 10 P22 - 36]] (L fixed by the poles)."""
    from scipy.optimize import minimize_scalar

    plant = _ex1_plant()
    # min_trace: smallest P22 with Q >= 0, root of P22^2 - 700 P22 + 3636 = 0 (Q of rank one)
    res = kalman_for_poles(plant, [-5, -8], objective="min_trace")
    p22 = 350 - np.sqrt(350**2 - 3636)
    assert res.P[1, 1] == pytest.approx(p22, rel=1e-10)
    np.testing.assert_allclose(res.Q, _q_of_p22(p22), rtol=1e-10, atol=1e-9)
    assert np.linalg.matrix_rank(res.Q, tol=1e-8 * np.linalg.norm(res.Q)) == 1
    assert res.objective_value == pytest.approx(np.trace(_q_of_p22(p22)), rel=1e-10)
    # feasibility: the largest smallest eigenvalue over the family (a 1-D concave maximization)
    res = kalman_for_poles(plant, [-5, -8], objective="feasibility")
    lo, hi = 350 - np.sqrt(350**2 - 3636), 350 + np.sqrt(350**2 - 3636)  # Q(P22) >= 0 exactly here
    best = minimize_scalar(lambda x: -np.linalg.eigvalsh(_q_of_p22(x))[0], bounds=(lo, hi),
                           method="bounded", options={"xatol": 1e-10})
    assert res.objective_value == pytest.approx(-best.fun, rel=1e-8)
    # the maximizer sits where the objective is flat: known only to ~sqrt(solver tolerance)
    assert res.P[1, 1] == pytest.approx(best.x, rel=1e-3)
    # nearest to the paper's Q' (which is in the family, P22 = 12): returns it
    res = kalman_for_poles(plant, [-5, -8], objective="nearest", Q_nominal=[[76, -42], [-42, 84]])
    np.testing.assert_allclose(res.Q, [[76, -42], [-42, 84]], atol=1e-7)
    assert res.P[1, 1] == pytest.approx(12, abs=1e-8)
    # nearest to a Q outside the family: the Frobenius projection onto the (convex) family
    res = kalman_for_poles(plant, [-5, -8], objective="nearest", Q_nominal=np.eye(2))
    proj = minimize_scalar(lambda x: np.linalg.norm(_q_of_p22(x) - np.eye(2)), bounds=(lo, hi),
                           method="bounded", options={"xatol": 1e-12})
    assert res.P[1, 1] == pytest.approx(proj.x, rel=1e-6)  # on the boundary here: P22 = lo
    assert res.objective_value == pytest.approx(proj.fun, rel=1e-8)
    # the sequential method: the paper's member, P22 = 12
    res = kalman_for_poles(plant, [-5, -8], method="sequential")
    np.testing.assert_allclose(res.Q, [[76, -42], [-42, 84]], atol=1e-12)
    assert res.P[1, 1] == pytest.approx(12, abs=1e-12)
    # same gain whatever the member
    np.testing.assert_allclose(res.L.ravel(), [8, -6], atol=1e-12)


def test_example1_nlp_agrees_with_the_sdp():
    plant = _ex1_plant()
    sdp = kalman_for_poles(plant, [-5, -8], method="sdp")
    nlp = kalman_for_poles(plant, [-5, -8], method="nlp")
    _assert_valid(nlp, plant, [-5, -8])
    np.testing.assert_allclose(nlp.L, sdp.L, atol=1e-9)
    assert nlp.objective_value == pytest.approx(sdp.objective_value, rel=1e-7)


def test_example1_with_scs():
    plant = _ex1_plant()
    res = kalman_for_poles(plant, [-5, -8], sdp_solver="SCS")
    _assert_valid(res, plant, [-5, -8])
    assert res.solver_stats.backend == "scs"


# ------------------------------------------------------------------- seed 000, Example 2
def test_example2_every_method_reaches_minus8_minus5():
    """Complex pair -1 +- j moved to -8, -5 (two outputs).  The paper's printed numbers do not
    reproduce (tests/test_solheim.py records each inconsistency); every method here reaches
    the poles to 1e-8, verified by a direct ARE solve with the returned Q."""
    prob = problems.load("chang_lee_1984_ex2")
    plant, target = prob.plant, prob.targets["poles"]
    results = {m: kalman_for_poles(plant, target, method=m) for m in ("auto", "nlp", "sequential")}
    for res in results.values():
        _assert_valid(res, plant, target)
        assert pole_error(_are(plant, res.Q).poles, target) < 1e-8
    # auto = the engine (issue 14: several outputs without an NLP detour), reported as "sdp"
    assert results["auto"].method == "sdp"
    assert results["auto"].extra["L_source"] == "the inverse Kalman engine"
    assert results["auto"].objective_value <= np.trace(results["sequential"].Q) + 1e-9
    # the min-trace NLP does not do worse than the sequential member
    assert results["nlp"].objective_value <= np.trace(results["sequential"].Q) + 1e-9
    # the paper's printed Q' is not a valid answer: its ARE poles are far from -8, -5
    printed = np.asarray(prob.references["Q_prime_printed"])
    assert pole_error(_are(plant, printed).poles, target) > 0.5


def _scipy_are_poles(plant, Q):
    """Direct scipy ARE solve (not optdesign's filter_are): the gain and the filter poles."""
    import scipy.linalg as sl

    A, C, R = plant.A, plant.C, plant.R
    if plant.dt is None:
        P = sl.solve_continuous_are(A.T, C.T, Q, R)
        L = P @ C.T @ np.linalg.inv(R)
    else:
        P = sl.solve_discrete_are(A.T, C.T, Q, R)
        L = A @ P @ C.T @ np.linalg.inv(C @ P @ C.T + R)
    return L, np.linalg.eigvals(A - L @ C)


@pytest.mark.parametrize("objective", ["min_trace", "feasibility"])
def test_example2_sdp_with_two_outputs_reaches_minus8_minus5(objective):
    """method='sdp' with p = 2: L from the inverse Kalman engine (it used to come from the NLP:
    issue 14), Q from the fixed-gain SDP at that L (the objective's optimum over the gain's family
    -- never worse than the NLP's own Q)."""
    prob = problems.load("chang_lee_1984_ex2")
    plant, target = prob.plant, prob.targets["poles"]
    res = kalman_for_poles(plant, target, method="sdp", objective=objective)
    assert res.method == "sdp" and res.status.is_solved
    assert res.extra["L_source"] == "the inverse Kalman engine"
    _assert_valid(res, plant, target)
    L, poles = _scipy_are_poles(plant, res.Q)
    assert pole_error(poles, [-8.0, -5.0]) < 1e-8
    np.testing.assert_allclose(L, res.L, rtol=1e-8, atol=1e-10)
    nlp = kalman_for_poles(plant, target, method="nlp", objective=objective)
    if objective == "min_trace":
        assert res.objective_value <= nlp.objective_value * (1 + 1e-9)
    else:
        assert res.objective_value >= nlp.objective_value * (1 - 1e-9)
    assert "fixed-gain SDP" in res.message and "inverse Kalman engine" in res.message


# ---------------------------------------------------------- double integrator (issue 3)
def _di_return_difference_dip(a1=0.4, a0=9.04):
    """Independent reference for the double integrator with ``L = [a1, a0]`` (R = 1):
    ``T(s) = (s^2 + a1 s + a0) / s^2``, so ``T R T* - R = |T(jw)|^2 - 1``; its minimum over w
    by a bounded scalar search.  Returns ``(omega, min value)``."""
    from scipy.optimize import minimize_scalar

    def f(w):
        return abs((1j * w) ** 2 + a1 * 1j * w + a0) ** 2 / w**4 - 1.0

    res = minimize_scalar(f, bounds=(0.5, 10.0), method="bounded", options={"xatol": 1e-12})
    return res.x, res.fun


@pytest.mark.parametrize("name", ["double_integrator_poles_m1_m3", "double_integrator_poles_m2pm2j"])
def test_double_integrator_feasible_targets(name):
    prob = problems.load(name)
    plant, target = prob.plant, prob.targets["poles"]
    ref = prob.references
    for method in ("sdp", "nlp"):
        res = kalman_for_poles(plant, target, method=method)
        # the SDP route is exact to rounding; the NLP stops at IPOPT's tolerance, which on the boundary
        # target (Q = diag(0, 64)) leaves q11 ~ 6e-9 and moves the poles by 2e-10 (CasADi 3.6's IPOPT):
        # the verb's own accuracy, 1e-8, is what it guarantees there
        _assert_valid(res, plant, target, tol=1e-10 if method == "sdp" else 1e-8)
        np.testing.assert_allclose(res.L, ref["L_analytic"], atol=1e-9)
        # q11 = a1^2 - 2 a0 and q22 = a0^2 are fixed; q12 is free (P22)
        np.testing.assert_allclose(np.diag(res.Q), np.diag(ref["Q_diag_analytic"]), atol=1e-8)
    if name.endswith("m2pm2j"):  # boundary case: Q = diag(0, 64) is the only member
        np.testing.assert_allclose(res.Q, ref["Q_diag_analytic"], atol=1e-8)


def test_double_integrator_infeasible_target_has_a_certificate():
    prob = problems.load("double_integrator_poles_m0p2pm3j")
    plant, target, ref = prob.plant, prob.targets["poles"], prob.references
    res = kalman_for_poles(plant, target)
    assert res.status == Status.INFEASIBLE and not res.success
    assert res.L is None and res.Q is None
    cert = res.certificate
    assert cert.kind == "return_difference"
    # |T(jw)|^2 - 1 is smallest at w = 3.02005 where |T|^2 = 0.0176208 (analytic, in the problem;
    # re-derived here by a scalar search of |T(jw)|^2)
    w_ref, dip_ref = _di_return_difference_dip()
    assert ref["worst_omega"] == pytest.approx(w_ref, rel=1e-6)
    assert ref["return_difference_sq_min"] - 1.0 == pytest.approx(dip_ref, rel=1e-8)
    assert cert.omega == pytest.approx(ref["worst_omega"], rel=1e-6)
    assert cert.min_eigenvalue == pytest.approx(ref["return_difference_sq_min"] - 1.0, rel=1e-6)
    assert cert.margin == pytest.approx(0.4**2 - 2 * 9.04, rel=1e-6)  # q11 = a1^2 - 2 a0 < 0
    # closest achievable: the filter poles of the double integrator have damping >= 1/sqrt 2,
    # so the nearest pair is the projection of -0.2 + 3j onto the 135-degree ray: -1.6 +- 1.6j
    np.testing.assert_allclose(np.sort_complex(cert.closest_poles), [-1.6 - 1.6j, -1.6 + 1.6j], atol=1e-5)
    assert cert.closest_pole_error == pytest.approx(abs(-1.4 - 1.4j) / abs(target[0]), rel=1e-4)
    are = _are(plant, cert.closest_Q)  # the closest design is a genuine Kalman filter
    np.testing.assert_allclose(are.L, cert.closest_L, rtol=1e-8)
    assert "return-difference" in res.message
    with pytest.raises(Exception, match="return-difference"):
        res.raise_for_status()


def test_double_integrator_infeasible_target_nlp_has_the_frequency_certificate_too():
    """method='nlp' with one output: the poles fix L, so the return-difference certificate is
    computed at that gain, as on the SDP path."""
    prob = problems.load("double_integrator_poles_m0p2pm3j")
    plant, target, ref = prob.plant, prob.targets["poles"], prob.references
    res = kalman_for_poles(plant, target, method="nlp")
    assert res.status == Status.INFEASIBLE and res.method == "nlp" and res.L is None
    cert = res.certificate
    assert cert.kind == "return_difference" and "return-difference" in cert.reason
    assert cert.omega == pytest.approx(ref["worst_omega"], rel=1e-6)
    assert cert.min_eigenvalue == pytest.approx(ref["return_difference_sq_min"] - 1.0, rel=1e-6)
    assert cert.margin == pytest.approx(0.4**2 - 2 * 9.04, rel=1e-6)
    assert cert.circle is not None and not cert.circle.passed
    np.testing.assert_allclose(np.sort_complex(cert.closest_poles), [-1.6 - 1.6j, -1.6 + 1.6j], atol=1e-5)


def test_unstable_target_is_infeasible_not_an_exception():
    res = kalman_for_poles(_ex1_plant(), [1.0, -8.0])
    assert res.status == Status.INFEASIBLE and res.certificate.kind == "unstable_target"
    disc = Plant([[0.5, 0.1], [0.0, 0.3]], [[1.0, 0.0]], R=[[1.0]], dt=0.1)
    res = kalman_for_poles(disc, [1.2, 0.1])
    assert res.certificate.kind == "unstable_target" and "unit circle" in res.certificate.reason



def test_details_is_a_deprecated_alias_of_extra():
    res = kalman_for_poles(_ex1_plant(), [1.0, -8.0])
    with pytest.warns(OptDesignDeprecationWarning, match=r"details is deprecated: use \.extra"):
        assert res.details is res.extra

# ------------------------------------------------------------ is_kalman_optimal
def test_is_kalman_optimal_double_integrator():
    di = problems.load("double_integrator_poles_m1_m3").plant
    ok = is_kalman_optimal(di, [[4.0], [3.0]])
    assert isinstance(ok, KalmanOptimalityResult) and ok.optimal and bool(ok) and ok.success
    np.testing.assert_allclose(_are(di, ok.Q).L.ravel(), [4, 3], atol=1e-9)
    no = is_kalman_optimal(di, [[0.4], [9.04]])
    assert not no.optimal and not no.success and no.status == Status.INFEASIBLE
    assert no.certificate.kind == "return_difference"
    assert no.omega == pytest.approx(3.02005203, rel=1e-6)
    assert no.min_eigenvalue == pytest.approx(0.0176208 - 1, rel=1e-5)
    w_ref, dip_ref = _di_return_difference_dip()  # the same numbers, derived independently
    assert no.omega == pytest.approx(w_ref, rel=1e-6)
    assert no.min_eigenvalue == pytest.approx(dip_ref, rel=1e-8)
    assert no.margin == pytest.approx(-17.92, rel=1e-9)
    unstable = is_kalman_optimal(di, [[-1.0], [1.0]])
    assert not unstable.optimal and unstable.certificate.kind == "unstable_target"


def test_is_kalman_optimal_several_outputs_and_discrete(rng):
    for dt in (None, 0.1):
        plant = random_observable_plant(rng, 4, 2, dt=dt)
        kf = filter_are(plant)
        ok = is_kalman_optimal(plant, kf.L)
        assert ok.optimal and ok.success, ok.message
        np.testing.assert_allclose(_are(plant, ok.Q).L, kf.L, rtol=1e-7, atol=1e-9)
        # a placed gain with the same poles is (almost surely) not a Kalman gain: C L R (or the
        # discrete C P C') is then not symmetric
        L2 = place_observer(plant, kf.poles)
        no = is_kalman_optimal(plant, L2)
        assert not no.optimal and no.certificate.kind in ("gain_relation", "return_difference", "sdp_margin")
        assert no.message


def test_is_kalman_optimal_discrete_uses_the_innovation_weighted_inequality():
    """Discrete double-integrator-like plant: Kalman-optimal gains pass T V T* >= R (not T R T* >= R)."""
    dt = 0.5
    plant = Plant([[1.0, dt], [0.0, 1.0]], [[1.0, 0.0]], G=[[dt**2 / 2], [dt]], Q=[[4.0]], R=[[0.1]], dt=dt)
    kf = filter_are(plant)
    res = is_kalman_optimal(plant, kf.L)
    assert res.optimal and res.circle.passed and res.circle.V_source == "T(0)^-1 R"


def test_is_kalman_optimal_accepts_gains_of_rank_deficient_Q():
    """Kalman gains of rank-one Q (n 4..8, p 1..3, continuous and discrete) are boundary gains
    (max smallest eigenvalue of the family = 0) where the margin SDP comes out slightly
    negative (audit: -1.6e-6, -1.9e-6, -1.2e-7 with ||Q|| 5-11, for 3 of these 40): never
    "not optimal" -- the polished certificate reproduces L."""
    rng = np.random.default_rng(9)  # the audit's draws
    seen = set()
    for t in range(40):
        n, p = int(rng.integers(4, 9)), int(rng.integers(1, 4))
        dt = None if t % 2 == 0 else 0.1
        plant = random_observable_plant(rng, n, p, dt=dt, noise=False)
        plant = plant.replace(R=np.diag(rng.uniform(0.5, 2.0, p)))
        g = rng.standard_normal((n, 1))
        kf = filter_are(plant.replace(Q=g @ g.T))
        res = is_kalman_optimal(plant, kf.L)
        where = f"t={t} n={n} p={p} dt={dt}"
        assert res.optimal and bool(res) and res.success, f"{where}: {res.message}"
        assert res.certificate is None and res.margin >= -1e-8 * max(1.0, np.linalg.norm(res.Q, 2))
        L, _ = _scipy_are_poles(plant, res.Q)
        np.testing.assert_allclose(L, kf.L, rtol=1e-7, atol=1e-9 * np.linalg.norm(kf.L), err_msg=where)
        assert np.linalg.eigvalsh(res.Q)[0] >= -1e-10 * np.linalg.norm(res.Q, 2)
        seen.add((p, dt is None))
    assert len(seen) == 6  # every p in 1..3, continuous and discrete


def test_is_kalman_optimal_is_inconclusive_not_infeasible_without_a_certificate(monkeypatch):
    """If no polished Q verifies while the return-difference inequality holds, the answer is
    "inconclusive" (numerical_error), never a false "not optimal"; optimal needs verification."""
    from optdesign.design.inverse_kalman import optimality

    rng = np.random.default_rng(4)
    plant = random_observable_plant(rng, 4, 2, noise=False).replace(R=np.eye(2))
    g = rng.standard_normal((4, 1))
    kf = filter_are(plant.replace(Q=g @ g.T))
    monkeypatch.setattr(optimality, "optimality_certificate", lambda *a, **k: None)
    res = is_kalman_optimal(plant, kf.L)
    assert res.status == Status.NUMERICAL_ERROR and not res.optimal and not res and not res.success
    assert res.certificate is None and res.circle.passed
    assert "inconclusive" in res.message and "return-difference inequality holds" in res.message
    # a clearly non-optimal gain is still "not optimal" (no Q needed: its frequency certificate)
    di = problems.load("double_integrator_poles_m1_m3").plant
    no = is_kalman_optimal(di, [[0.4], [9.04]])
    assert no.status == Status.INFEASIBLE and no.certificate.kind == "return_difference"
    # bool() and optimal need the verification to pass
    from optdesign.results import Check, Verification

    monkeypatch.undo()
    ok = is_kalman_optimal(di, [[4.0], [3.0]])
    assert ok.optimal and bool(ok)
    failing = Verification.of([Check.at_most("riccati_residual", 1.0, 1e-8, "a failed check")])
    fake = dataclasses.replace(ok, verification=failing)
    assert not fake.optimal and not bool(fake) and not fake.success


def test_is_kalman_optimal_errors():
    di = problems.load("double_integrator_poles_m1_m3").plant
    with pytest.raises(DimensionError, match="L has the wrong shape"):
        is_kalman_optimal(di, [[1.0, 2.0, 3.0]])
    with pytest.raises(ValidationError, match="is_kalman_optimal needs the measurement-noise covariance R"):
        is_kalman_optimal(di.replace(R=None), [[4.0], [3.0]])
    with pytest.raises(ValidationError, match="tol must be finite and > 0"):
        is_kalman_optimal(di, [[4.0], [3.0]], tol=0.0)
    with pytest.raises(NotPositiveDefiniteError, match="R must be positive definite"):
        is_kalman_optimal(di, [[4.0], [3.0]], R=[[-1.0]])
    with pytest.raises(ValidationError, match="must be an optdesign.Plant"):
        is_kalman_optimal("plant", [[4.0], [3.0]])


# ---------------------------------------------------- the linear relations (C) and (D)
@pytest.mark.parametrize("dt", [None, 0.2])
def test_linear_in_P_relations_hold_for_the_riccati_solution(rng, dt):
    """(C): P C' = L R, Q = L R L' - A P - P A';  (D): (A - LC) P C' = L R,
    Q = P - (A - LC) P (A - LC)' - L R L' -- derived in optdesign.formulate.inverse_kalman."""
    for p in (1, 3):
        plant = random_observable_plant(rng, 5, p, dt=dt)
        kf = filter_are(plant)
        gain_residual, q_of_P = fixed_gain_maps(plant.A, plant.C, kf.L, plant.R, dt)
        scale = np.linalg.norm(kf.P)
        assert np.linalg.norm(gain_residual(kf.P)) < 1e-12 * scale
        np.testing.assert_allclose(q_of_P(kf.P), plant.process_noise(), atol=1e-11 * scale)


@pytest.mark.parametrize("dt", [None, 0.2])
def test_spectral_identity_is_singular_at_the_filter_poles(rng, dt):
    plant = random_observable_plant(rng, 4, 2, dt=dt)
    kf = filter_are(plant)
    W = plant.process_noise()
    terms = spectral_terms(plant.A, plant.C, kf.poles, dt)
    for _, _s, G1, G2, _ in terms:
        M = plant.R + G1 @ W @ G2.T
        sv = np.linalg.svd(M, compute_uv=False)
        assert sv[-1] < 1e-10 * sv[0]
    # and not singular elsewhere
    G1 = np.linalg.solve(((kf.poles[0] - 0.3) * np.eye(4) - plant.A).T, plant.C.T.astype(complex)).T
    s2 = 1 / (kf.poles[0] - 0.3) if dt else -(kf.poles[0] - 0.3)
    G2 = np.linalg.solve((s2 * np.eye(4) - plant.A).T, plant.C.T.astype(complex)).T
    sv = np.linalg.svd(plant.R + G1 @ W @ G2.T, compute_uv=False)
    assert sv[-1] > 1e-6 * sv[0]


@pytest.mark.parametrize("objective", ["min_trace", "feasibility", "nearest"])
def test_parametric_sdp_rebound_equals_a_fresh_build(objective):
    """One fixed-gain SDP re-bound to another gain (cvxpy parameters, DPP) solves the same
    problem as one built for that gain; a solve of the re-bound problem leaves no stale values."""
    from optdesign.backends.cvxpy_backend import solve_cvxpy

    rng = np.random.default_rng(7)
    dt = None
    plant = random_observable_plant(rng, 4, 1, dt=dt)
    gains = [filter_are(plant.replace(Q=F @ F.T + 0.1 * np.eye(4))).L
             for F in (rng.standard_normal((4, 4)) for _ in range(3))]
    Qn = np.eye(4) if objective == "nearest" else None
    reused = build_fixed_gain_sdp(plant.A, plant.C, gains[0], plant.R, dt=dt, objective=objective,
                                  Q_nominal=Qn)
    assert reused.problem.is_dpp()
    for L in gains:
        reused.set_gain(L, Qn)
        assert reused.P.value is None
        fresh = build_fixed_gain_sdp(plant.A, plant.C, L, plant.R, dt=dt, objective=objective, Q_nominal=Qn)
        r1, r2 = solve_cvxpy(reused.problem), solve_cvxpy(fresh.problem)
        assert r1.status.is_solved and r2.status.is_solved, (r1.message, r2.message)
        assert reused.scale == pytest.approx(fresh.scale, rel=1e-15)
        assert r1.objective == pytest.approx(r2.objective, rel=1e-6, abs=1e-9)
        if objective == "nearest":  # strictly convex: one optimum (the others may have a face of them)
            np.testing.assert_allclose(reused.scale * reused.Q.value, fresh.scale * fresh.Q.value,
                                       atol=1e-6 * fresh.scale)
        # the solution really belongs to this gain: relations (C) / (D) hold for it
        gain_residual, q_of_P = fixed_gain_maps(plant.A, plant.C, L, plant.R, dt)
        P = reused.scale * reused.P.value
        assert np.linalg.norm(gain_residual(P)) <= 1e-6 * max(1.0, np.linalg.norm(L))
    with pytest.raises(ValidationError, match=r"L must have shape \(4, 1\)"):
        reused.set_gain(np.ones((4, 2)), Qn)
    # discrete time: built for one gain, and says so when asked for another
    dplant = random_observable_plant(rng, 3, 1, dt=0.1)
    L = filter_are(dplant).L
    dsdp = build_fixed_gain_sdp(dplant.A, dplant.C, L, dplant.R, dt=0.1, objective=objective, Q_nominal=Qn
                                if Qn is None else np.eye(3))
    dsdp.set_gain(L, None if Qn is None else 2 * np.eye(3))
    with pytest.raises(ValidationError, match="built for one gain"):
        dsdp.set_gain(L + 1.0, None if Qn is None else np.eye(3))


def test_same_call_same_answer_whatever_ran_before():
    """Issue 11: the first kalman_for_poles(method="sdp") of a process differed from later ones
    (Q by 5e-11 relative; is_kalman_optimal's certificate by 6.7e-4) because of a hidden SDP
    re-use cache.  Every call builds its own problem now: the answers are identical."""
    from optdesign.design import inverse_kalman as ik

    plant = _ex1_plant()
    targets = [np.array([-5.0, -8.0]) * s for s in (1.0, 1.5, 2.0)]
    first = kalman_for_poles(plant, targets[0], method="sdp")
    cert_first = is_kalman_optimal(plant, first.L)
    later = [kalman_for_poles(plant, t, method="sdp") for t in targets]
    assert all(r.success for r in later)
    np.testing.assert_array_equal(later[0].Q, first.Q)
    np.testing.assert_array_equal(is_kalman_optimal(plant, first.L).Q, cert_first.Q)
    assert not hasattr(ik, "_SDP_CACHE")
    with pytest.warns(DeprecationWarning, match="no effect"), ik.sdp_reuse(False):
        pass


def test_fixed_gain_sdp_parameters_rebind_to_a_new_gain():
    """The formulation's explicit re-use (cvxpy Parameters, DPP): one problem, several gains,
    the same Q as rebuilding for each gain."""
    from optdesign.backends.cvxpy_backend import solve_cvxpy

    plant = _ex1_plant()
    gains = [np.array([[8.0], [-6.0]]), np.array([[12.0], [-4.0]])]
    sdp = build_fixed_gain_sdp(plant.A, plant.C, gains[0], plant.R)
    for L in gains:
        solve_cvxpy(sdp.set_gain(L).problem)
        fresh = build_fixed_gain_sdp(plant.A, plant.C, L, plant.R)
        solve_cvxpy(fresh.problem)
        np.testing.assert_allclose(sdp.scale * sdp.Q.value, fresh.scale * fresh.Q.value, rtol=1e-7, atol=1e-7)


def test_formulations_build_without_solving():
    plant = _ex1_plant()
    sdp = build_fixed_gain_sdp(plant.A, plant.C, np.array([[8.0], [-6.0]]), plant.R)
    assert sdp.problem.status is None and sdp.P.value is None
    nlp = build_spectral_nlp(plant.A, plant.C, plant.R, np.array([-8.0, -5.0]), W0=np.eye(2))
    assert len(nlp.null_vectors) == 2
    with pytest.raises(ValidationError, match="eigenvalue of A"):
        build_spectral_nlp(plant.A, plant.C, plant.R, np.array([-8.0, -2.0]))  # -2 is an eigenvalue of A
    with pytest.raises(ValidationError, match="structure must be one of"):
        build_fixed_gain_sdp(plant.A, plant.C, np.array([[8.0], [-6.0]]), plant.R, structure="banded")
    with pytest.raises(ValidationError, match="needs Q_nominal"):
        build_fixed_gain_sdp(plant.A, plant.C, np.array([[8.0], [-6.0]]), plant.R, objective="nearest")
    with pytest.raises(ValidationError, match="needs the noise input matrix G"):
        build_spectral_nlp(plant.A, plant.C, plant.R, np.array([-8.0, -5.0]), structure="input")


def test_formulation_error_paths():
    """Every builder's option checks, and the fixed-gain SDP's re-binding checks."""
    from optdesign.formulate.inverse_kalman import build_pole_nlp, build_spectral_nlpsol, build_spectral_sdp

    plant = _ex1_plant()
    A, C, R, L = plant.A, plant.C, plant.R, np.array([[8.0], [-6.0]])
    poles = np.array([-8.0, -5.0])
    with pytest.raises(ValidationError,
                       match=r"objective must be one of \('min_trace', 'nearest', 'feasibility'\)"):
        build_pole_nlp(A, C, R, poles, objective="max_trace")
    with pytest.raises(ValidationError, match="structure='diagonal' needs the noise input matrix G"):
        build_pole_nlp(A, C, R, poles, structure="diagonal")
    with pytest.raises(ValidationError, match="objective='nearest' needs Q_nominal"):
        build_pole_nlp(A, C, R, poles, objective="nearest")
    build_pole_nlp(A, C, R, poles, objective="nearest", closest=True)  # closest mode: no nominal needed
    with pytest.raises(ValidationError, match="objective='nearest' needs Q_nominal"):
        build_spectral_sdp(A, C, R, poles, objective="nearest")
    with pytest.raises(ValidationError, match="eigenvalue of A or of its mirror image"):
        build_spectral_sdp(A, C, R, np.array([-8.0, -2.0]))
    # the closed-form-derivative NLP supports fewer structures / objectives
    with pytest.raises(ValidationError,
                       match=r"structure must be one of \('full', 'input'\); found 'diagonal'"):
        build_spectral_nlpsol(A, C, R, poles, structure="diagonal", G=np.eye(2))
    with pytest.raises(ValidationError, match=r"objective must be one of \('min_trace', 'nearest'\)"):
        build_spectral_nlpsol(A, C, R, poles, objective="feasibility")
    with pytest.raises(ValidationError, match="eigenvalue of A or of its mirror image"):
        build_spectral_nlpsol(A, C, R, np.array([-8.0, -2.0]))
    # re-binding a "nearest" SDP needs the nominal again
    sdp = build_fixed_gain_sdp(A, C, L, R, objective="nearest", Q_nominal=np.eye(2))
    with pytest.raises(ValidationError, match="objective='nearest' needs Q_nominal"):
        sdp.set_gain(L)


def test_target_at_an_eigenvalue_of_A_uses_the_state_space_nlp():
    """A stable eigenvalue may stay: the spectral form is singular there, the eigenvector form is not."""
    plant = Plant([[-1.0, 0.0, 0.0], [0.0, -2.0, 1.0], [0.0, 0.0, -3.0]], [[1.0, 1.0, 0.0], [0.0, 1.0, 1.0]],
                  R=np.eye(2))
    target = filter_are(plant.replace(Q=np.diag([0.0, 1.0, 2.0]))).poles
    assert np.min(np.abs(target + 1.0)) < 1e-9  # -1 is unexcited, so it stays
    res = kalman_for_poles(plant, target, method="nlp")
    _assert_valid(res, plant, target)
    assert res.extra["formulation"] == "state-space"
    # the default route: the engine does not apply there, the SDP route (L from that NLP) answers
    auto = kalman_for_poles(plant, target)
    _assert_valid(auto, plant, target)
    assert auto.extra["L_source"] == "the NLP"


# ------------------------------------------------------------------- structured Q
def test_input_structure_reachable_and_diagonal_recovered(rng):
    for dt in (None, 0.1):
        plant = random_observable_plant(rng, 4, 1, dt=dt, noise=False).replace(R=[[1.0]])
        G = rng.standard_normal((4, 2))
        qw = np.array([0.7, 1.9])
        gplant = plant.replace(G=G, Q=np.diag(qw))
        target = filter_are(gplant).poles
        for structure in ("input", "diagonal"):
            res = kalman_for_poles(gplant, target, q_structure=structure)
            assert res.success, res.summary()
            np.testing.assert_allclose(res.Q, G @ res.Qw @ G.T, atol=1e-10 * np.linalg.norm(res.Q))
            assert np.linalg.eigvalsh(res.Qw)[0] >= -1e-12
        # one output: L is fixed; with G of two columns and the poles fixed, qw is unique here
        np.testing.assert_allclose(np.diag(res.Qw), qw, rtol=1e-7)


def _brute_force_closest(gplant, target, structure, rng):
    """Reference closest pole error for a noise of G's structure, by a method of its own: a
    dense log grid (one or two parameters) or a large random sample (the 3-parameter Qw of an
    "input" structure with m = 2), then Nelder-Mead from the five best points."""
    from scipy.optimize import linear_sum_assignment, minimize

    G = np.asarray(gplant.G)
    m = G.shape[1]
    scale = np.maximum(1.0, np.abs(target))

    def distance(poles):  # pole_error's definition, written out (the search's inner loop)
        cost = np.abs(poles[:, None] - target[None, :]) / scale[None, :]
        r, c = linear_sum_assignment(cost)
        return float(np.max(cost[r, c]))

    def W(x):
        if structure == "diagonal":
            return np.diag(np.exp(x))
        F = np.zeros((m, m))
        F[np.tril_indices(m)] = x
        return F @ F.T

    def f(x):
        try:
            _, poles = _scipy_are_poles(gplant, G @ W(x) @ G.T)
        except (np.linalg.LinAlgError, ValueError):
            return np.inf
        return distance(poles) if np.all(poles.real < 0) else np.inf

    if structure == "diagonal":
        axis = np.linspace(np.log(1e-6), np.log(1e6), 241 if m == 1 else 41)
        pts = [np.array(x) for x in (np.array(np.meshgrid(*[axis] * m)).reshape(m, -1).T)]
    else:
        k = m * (m + 1) // 2
        pts = [rng.standard_normal(k) * np.exp(rng.uniform(-4.0, 4.0)) for _ in range(1200)]
    vals = [f(x) for x in pts]
    order = np.argsort(vals)[:5]
    best = min(vals)
    for i in order:
        r = minimize(f, pts[i], method="Nelder-Mead",
                     options={"xatol": 1e-10, "fatol": 1e-13, "maxfev": 2500})
        best = min(best, r.fun)
    return best


@pytest.mark.parametrize("columns, structure", [(1, "diagonal"), (2, "diagonal"), (2, "input")])
def test_structure_that_cannot_reach_the_target_reports_the_closest_poles(rng, columns, structure):
    """The closest achievable poles are really the closest: no worse than a brute-force search
    of the noise parameters (audit: 0.742 / 0.204 / 0.204 reported against 0.730 / 0.127 /
    0.048 before the pole-error search).  With two noise inputs the closest poles are real
    although the target has a (nearly real) complex pair -- the pattern is not kept.

    With two outputs this is a local search: evidence, not proof, so the status is ``not_found``
    (issue 11: ``infeasible`` needs a global certificate) and the evidence is in
    ``details["closest"]``."""
    plant = random_observable_plant(rng, 3, 2, noise=False).replace(R=np.eye(2))
    target = filter_are(plant.replace(Q=np.eye(3) + 0.5)).poles  # full-rank Q
    G = [[1.0], [0.0], [0.0]] if columns == 1 else [[1.0, 0.0], [0.0, 1.0], [0.0, 0.0]]
    gplant = plant.replace(G=G)                                   # no noise on the third state
    res = kalman_for_poles(gplant, target, q_structure=structure)
    assert res.status == Status.NOT_FOUND and res.certificate is None and not res.success
    assert "feasibility unknown" in res.message and "evidence, not proof" in res.message
    cert = SimpleNamespace(**res.extra["closest"])
    assert cert.closest_pole_error > 1e-3 and np.all(np.isfinite(cert.closest_poles))
    # the closest design is a real Kalman filter with noise through G only, and the reported
    # error is that of its poles
    are = _are(gplant, cert.closest_Q)
    np.testing.assert_allclose(np.sort_complex(are.poles), np.sort_complex(cert.closest_poles), atol=1e-8)
    Gm = np.asarray(G)
    np.testing.assert_allclose(Gm @ cert.closest_Qw @ Gm.T, cert.closest_Q, atol=1e-10)
    assert cert.closest_pole_error == pytest.approx(pole_error(are.poles, target), rel=1e-8)
    ref = _brute_force_closest(gplant, target, structure, np.random.default_rng(1))
    assert cert.closest_pole_error <= ref * (1 + 1e-6) + 1e-9, (cert.closest_pole_error, ref)
    if columns == 1:
        assert "1 parameters for 3 pole conditions" in res.message
    elif structure == "input":  # 3 parameters for 3 conditions: a square system, no spare freedom
        assert "reachable targets are isolated points" in res.message
    else:
        assert "2 parameters for 3 pole conditions" in res.message
        assert np.all(np.abs(cert.closest_poles.imag) < 1e-12) and np.any(np.abs(target.imag) > 0)


def test_single_output_structured_infeasible_uses_the_sdp():
    # -1, -3 needs q11 = 10 and q22 = 9 (both fixed by L): rank one Q = q g g' cannot do it
    di = problems.load("double_integrator_poles_m1_m3").plant.replace(G=[[1.0], [2.0]])
    res = kalman_for_poles(di, [-1, -3], q_structure="input")
    assert res.status == Status.INFEASIBLE and res.certificate.kind == "structure"
    assert res.certificate.closest_pole_error > 0.01  # (no margin: even the linear relations fail)
    are = _are(di, res.certificate.closest_Q)
    assert np.linalg.matrix_rank(res.certificate.closest_Q, tol=1e-9 * np.linalg.norm(are.P)) == 1
    # noise on the position only: the integrator mode is not excited, no stabilizing filter at all
    di1 = di.replace(G=[[1.0], [0.0]])
    res = kalman_for_poles(di1, [-1, -3], q_structure="input")
    assert res.status == Status.INFEASIBLE and res.certificate.closest_poles is None
    assert "no closest poles" in res.certificate.reason


# ------------------------------------------------------------- cross-validation
#: the issue's pole accuracy: every method's Q must reproduce the poles to this (relative) ...
CV_POLE_TOL = 1e-8
#: ... and the SDP / NLP min-trace objectives must agree to this (measured: 1.8e-7 at worst)
CV_OBJ_RTOL = 1e-6


def _feasible_target(rng, n, p, dt, rank):
    """A random plant and the poles of the Kalman filter of a random ``Q >= 0`` of the given
    rank (rank-deficient Q: boundary targets, where the SDP margin is 0).  Returns
    ``(plant, ARE result, redraws)``; a draw is redrawn only when the reference Riccati solve
    itself fails (counted).  No target is filtered by its conditioning."""
    redraws = 0
    while True:
        plant = random_observable_plant(rng, n, p, dt=dt, noise=False)
        plant = plant.replace(R=np.diag(rng.uniform(0.5, 2.0, p)))
        F = rng.standard_normal((n, rank)) / np.sqrt(rank)
        try:
            are = filter_are(plant.replace(Q=F @ F.T))
        except RiccatiError:  # no reference to compare with (an unexcited unstable mode, ...)
            redraws += 1
            continue
        return plant, are, redraws


def _cross_validate(rng, count):
    """Every method that applies recovers a Q whose (scipy) ARE reproduces the poles to 1e-8;
    they agree.

    The pole check is ``pole_error <= max(1e-8, floor)`` with ``floor`` the eigenvalue rounding
    floor of ``A - L C`` (``_pole_tolerance``: ``10 eps kappa ||A - L C||``, capped at 1e-6) --
    no pole can be computed more accurately than that; targets that need the raised floor are
    kept and counted (``stats["floor_raised"]``), not redrawn.  With several outputs
    ``method="sdp"`` is the NLP's gain plus the fixed-gain SDP at it: exactly the family check
    made here (without running the NLP twice).
    """
    stats = {"designs": 0, "solheim_applied": 0, "solheim_applied_p>1": 0, "family_checked": 0,
             "floor_raised": 0, "redraws": 0, "worst_pole_error": 0.0, "worst_pole_error_at_1e-8": 0.0,
             "worst_obj_rel": 0.0, "rank_deficient": 0}
    for k in range(count):
        _cross_validate_one(*_cv_target(rng, k), stats)
    return stats


def _cv_target(rng, k):
    """The k-th cross-validation target: ``(k, plant, ARE result, rank, redraws)``."""
    n = 2 + k % 9
    p = min(n, 1 if k % 2 == 0 else 2 + (k // 2) % 2)
    dt = None if (k // 4) % 2 == 0 else 0.1
    rank = (n, 1, max(1, n // 2))[(k // 9) % 3]
    plant, are, redraws = _feasible_target(rng, n, p, dt, rank)
    return k, plant, are, rank, redraws


def _cross_validate_one(k, plant, are, rank, redraws, stats):
    """Cross-validation of one target (see :func:`_cross_validate`); updates ``stats``."""
    n, p, dt = plant.n, plant.p, plant.dt
    stats["redraws"] += redraws
    stats["rank_deficient"] += rank < n
    target = are.poles
    where = f"k={k} n={n} p={p} dt={dt} rank={rank}"
    methods = ("sdp", "nlp") if p == 1 else ("nlp",)
    res = {m: kalman_for_poles(plant, target, method=m) for m in methods}
    for m, r in res.items():
        assert r.success, f"{m} {where}: {r.message}\n{r.verification.summary()}"
        assert r.message
        L, poles = _scipy_are_poles(plant, r.Q)  # independent of optdesign's Riccati solvers
        err = pole_error(poles, target)
        floor = _pole_tolerance(plant.A - L @ plant.C, CV_POLE_TOL)
        assert err <= floor, f"{m} {where}: pole error {err:.3g} > {floor:.3g}"
        stats["worst_pole_error"] = max(stats["worst_pole_error"], err)
        if floor > CV_POLE_TOL:
            stats["floor_raised"] += 1
        else:
            stats["worst_pole_error_at_1e-8"] = max(stats["worst_pole_error_at_1e-8"], err)
        stats["designs"] += 1
    seq = None
    try:
        seq = solheim(plant, target)
    except (ValidationError, RiccatiError):  # a step without a real solution
        pass
    seq_ok = seq is not None and seq.success  # it applies when every step keeps Q >= 0
    if p == 1:  # the poles fix L; the min-trace members must coincide (a convex problem)
        np.testing.assert_allclose(res["nlp"].L, res["sdp"].L, rtol=1e-6,
                                   atol=1e-8 * np.linalg.norm(res["sdp"].L))
        rel = abs(res["nlp"].objective_value - res["sdp"].objective_value) / res["sdp"].objective_value
        stats["worst_obj_rel"] = max(stats["worst_obj_rel"], rel)
        assert rel <= CV_OBJ_RTOL, where
        if seq_ok:
            stats["solheim_applied"] += 1
            np.testing.assert_allclose(seq.L, res["sdp"].L, rtol=1e-6, atol=1e-8 * np.linalg.norm(seq.L))
            assert np.trace(seq.Q) >= res["sdp"].objective_value * (1 - 1e-9)
    else:
        if seq_ok:  # another Kalman gain with these poles: the min-trace NLP must not do worse
            stats["solheim_applied_p>1"] += 1
            assert res["nlp"].objective_value <= np.trace(seq.Q) * (1 + 1e-9), where
        # the NLP's gain is a Kalman gain (an SDP says so independently) ...
        chk = is_kalman_optimal(plant, res["nlp"].L)
        assert chk.optimal and chk.success, f"{where}: {chk.message}"
        # ... and its Q is the min-trace member of that gain's (convex) family: a local
        # optimum of the NLP is the global optimum of the SDP at fixed L
        P0, W0, rep, _ = _sdp_fixed_gain(plant, res["nlp"].L, plant.R, "full", "min_trace", None, None)
        assert rep.status.is_solved, where
        pol = _face_polish(plant.A, plant.C, res["nlp"].L, plant.R, dt, "full", None, P0, W0, 1e-9)
        # no allowance for an unpolished point: the SDP optimum must be reproduced exactly
        assert pol is not None, f"{where}: the min-trace SDP point fits no face"
        stats["family_checked"] += 1
        tr = np.trace(pol[1])
        rel = (tr - res["nlp"].objective_value) / res["nlp"].objective_value
        # an exactly feasible member never beats the NLP's optimum ...
        assert rel >= -CV_OBJ_RTOL, f"{where}: the SDP member undercuts the NLP by {-rel:.3g}"
        if rep.status == Status.OPTIMAL:  # ... and an accurate SDP optimum equals it
            stats["worst_obj_rel"] = max(stats["worst_obj_rel"], abs(rel))
            assert abs(rel) <= CV_OBJ_RTOL, where


@pytest.mark.filterwarnings("ignore:Solution may be inaccurate")
def test_cross_validation_reduced(rng):
    stats = _cross_validate(rng, 18)
    # sdp and nlp for each of the 9 single-output targets, nlp for the 9 others; targets 9..17
    # have a rank-one Q (see _cv_target)
    assert stats["designs"] == 18 + 9 and stats["rank_deficient"] == 9


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore:Solution may be inaccurate")
def test_cross_validation_200_random_targets():
    """The issue's 200 random feasible targets: n = 2..10, one to three outputs, continuous and
    discrete, Q of full rank, rank one and rank n/2 (two thirds rank-deficient)."""
    rng = np.random.default_rng(3)
    count = CV_COUNT
    stats = _cross_validate(rng, count)
    assert stats["designs"] == count + count // 2       # sdp and nlp for p = 1, nlp for p > 1
    assert stats["rank_deficient"] >= count // 2
    assert stats["solheim_applied"] > 0 and stats["solheim_applied_p>1"] > 0
    assert stats["family_checked"] == count // 2
    assert stats["worst_pole_error_at_1e-8"] <= CV_POLE_TOL


# ---------------------------------------------------------------------- error paths
def test_kalman_for_poles_error_paths():
    plant = _ex1_plant()
    with pytest.raises(ValidationError, match="method must be one of"):
        kalman_for_poles(plant, [-5, -8], method="magic")
    with pytest.raises(ValidationError, match="objective must be one of"):
        kalman_for_poles(plant, [-5, -8], objective="max_trace")
    with pytest.raises(ValidationError, match="structure must be one of"):
        kalman_for_poles(plant, [-5, -8], q_structure="banded")
    with pytest.raises(ValidationError, match="gives a full Q"):
        kalman_for_poles(plant, [-5, -8], method="sequential", q_structure="input")
    with pytest.raises(ValidationError, match="has no R"):
        kalman_for_poles(plant.replace(R=None), [-5, -8])
    with pytest.raises(ValidationError, match="needs Q_nominal"):
        kalman_for_poles(plant, [-5, -8], objective="nearest")
    with pytest.raises(ValidationError, match=r"Q_nominal for structure='full' must be n x n"):
        kalman_for_poles(plant, [-5, -8], objective="nearest", Q_nominal=np.eye(3))
    with pytest.raises(ValidationError, match="tol must be finite and > 0"):
        kalman_for_poles(plant, [-5, -8], tol=-1.0)
    with pytest.raises(DimensionError, match="wrong length"):
        kalman_for_poles(plant, [-5, -8, -1])
    with pytest.raises(NotConjugateClosedError, match="conjugation"):
        kalman_for_poles(plant, [-5 + 1j, -8])
    with pytest.raises(NotObservableError, match="unobservable"):
        kalman_for_poles(Plant([[-1.0, 0.0], [0.0, -2.0]], [[1.0, 0.0]], R=[[1.0]]), [-3, -4])
    with pytest.raises(ValidationError, match="must be an optdesign.Plant"):
        kalman_for_poles(np.eye(2), [-1, -2])
    for seed in ("x", -1, 1.5, True, None):
        with pytest.raises(ValidationError, match=r"seed must be an integer >= 0; found"):
            kalman_for_poles(plant, [-5, -8], seed=seed)


def test_one_output_engine_needs_no_cvxpy_solver_discovery():
    """The one-output engine calls Clarabel directly: a fresh process's first design must not import
    cvxpy (its solver discovery cost about 0.9 s of CPU per process before; issue 14)."""
    code = ("import sys\n"
            "from optdesign import Plant, kalman_for_poles\n"
            "res = kalman_for_poles(Plant([[0, 1], [-6, -5]], [[1, 0]], R=[[1]]), [-5, -8])\n"
            "print(res.success, res.solver_stats.backend, 'cvxpy' in sys.modules)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["True", "spectral-newton+clarabel", "False"]


@pytest.mark.parametrize("method", ["sdp", "auto"])
def test_missing_sdp_solver_names_the_package(monkeypatch, method):
    from optdesign.backends import cvxpy_backend
    from optdesign.errors import BackendUnavailableError

    monkeypatch.setattr(cvxpy_backend, "available_sdp_solvers", lambda: ())
    monkeypatch.setitem(sys.modules, "clarabel", None)   # `import clarabel` fails: the engine is off too
    with pytest.raises(BackendUnavailableError, match="no SDP solver installed.*pip install clarabel"):
        kalman_for_poles(_ex1_plant(), [-5, -8], method=method)
    with pytest.raises(BackendUnavailableError, match="pip install clarabel"):
        is_kalman_optimal(_ex1_plant(), [[8.0], [-6.0]])


def test_discrete_pole_at_zero_with_nonsingular_A_is_provably_infeasible():
    """A discrete target pole at 0 needs infinite process noise in Solheim's construction; by
    det(A - L C) = det(A) det(R) / det(C P C' + R) no Kalman filter of a plant with det A != 0 has
    one.  Issue 11, item 4: this used to return ``unbounded`` without a certificate; every method
    now answers infeasible with the determinant identity (before any solver runs)."""
    disc = Plant([[0.5, 0.2], [0.0, 0.3]], [[1.0, 0.0]], R=[[1.0]], dt=1.0)
    for method in ("sequential", "sdp", "nlp"):
        res = kalman_for_poles(disc, [0.0, 0.1], method=method)
        assert res.status == Status.INFEASIBLE and res.certificate.kind == "determinant", method
        assert "never vanishes" in res.certificate.reason
    with pytest.raises(ValidationError, match="infinite process noise"):
        solheim(disc, [0.0, 0.1])
    # a singular A has a filter pole at 0 (the mode x2 -> 0 is read exactly): no certificate then
    sing = Plant([[0.5, 0.0], [0.0, 0.0]], [[1.0, 1.0]], R=[[1.0]], dt=1.0)
    assert kalman_for_poles(sing, [0.0, 0.2]).certificate is None or \
        kalman_for_poles(sing, [0.0, 0.2]).certificate.kind != "determinant"


def test_trace_and_determinant_identities_certify_continuous_targets():
    """Continuous time: trace(A - L C) <= trace(A) and |det(A - L C)| >= |det A| for every Kalman
    filter (the return-difference identity at s = 0); a target violating either is infeasible."""
    plant = _ex1_plant()  # trace -5, det 6
    res = kalman_for_poles(plant, [-1.0, -1.5])  # sum -2.5 > -5
    assert res.status == Status.INFEASIBLE and res.certificate.kind == "trace"
    res = kalman_for_poles(plant, [-0.5, -6.0])  # sum -6.5 <= -5 but product 3 < 6
    assert res.status == Status.INFEASIBLE and res.certificate.kind == "determinant"
    # an independent check: the (one-output) return difference fails at that gain too
    L = place_observer(plant, [-0.5, -6.0])
    assert not is_kalman_optimal(plant, L).optimal


def test_default_nominal_for_nearest_is_the_plant_noise():
    plant = _ex1_plant().replace(Q=[[76, -42], [-42, 84]])
    res = kalman_for_poles(plant, [-5, -8], objective="nearest")
    np.testing.assert_allclose(res.Q, [[76, -42], [-42, 84]], atol=1e-7)
    assert res.objective_value == pytest.approx(0.0, abs=1e-6)
    assert filter_are_residual(plant, res.P, Qs=res.Q) < 1e-12


def test_repeated_single_output_target_uses_ackermann_and_a_capped_pole_tolerance():
    """-2, -2 on the double integrator (critically damped, a defective filter pole): scipy's
    placement refuses the repeated pole, the gain is unique anyway ([4, 4])."""
    di = problems.load("double_integrator_poles_m1_m3").plant
    res = kalman_for_poles(di, [-2.0, -2.0])
    assert res.success, res.summary()
    np.testing.assert_allclose(res.L.ravel(), [4.0, 4.0], atol=1e-12)
    np.testing.assert_allclose(np.diag(res.Q), [16 - 8, 16], atol=1e-9)  # a1^2 - 2 a0, a0^2
    # a defective pole is computed to ~sqrt(eps) only: the tolerance is raised, but capped
    check = res.verification["are_resolve_poles"]
    assert 1e-8 < check.tolerance <= 1e-6


def test_paper000_reproduction_table_and_figures(tmp_path):
    from optdesign.studies import paper000

    rep = paper000.reproduce(tmp_path, quick=True)
    assert rep.paper == "000" and len(rep.figures) == 3
    for path in rep.figures:
        assert path.exists() and path.stat().st_size > 10_000
    ex1 = [r for r in rep.rows if r.example == "Ex. 1" and r.printed is not None]
    assert ex1 and all(r.agrees for r in ex1)                    # Example 1 reproduces exactly
    ex2 = {r.quantity: r for r in rep.rows if r.example == "Ex. 2"}
    assert ex2["step 1: by-product pole r2"].agrees is False       # the paper's -3.98 vs -4.0900
    assert "-4.09" in ex2["step 1: by-product pole r2"].reproduced
    di = [r for r in rep.rows if r.example == "double integrator"]
    assert len(di) == 3 and all(r.agrees for r in di)


@pytest.mark.parametrize("dt", [None, 0.2])
def test_single_output_spectral_conditions_are_linear_in_Q_and_solve_example1(rng, dt):
    from optdesign.formulate.inverse_kalman import build_spectral_sdp, spectral_linear_conditions

    plant = random_observable_plant(rng, 5, 1, dt=dt)
    kf = filter_are(plant)
    E, off = spectral_linear_conditions(spectral_terms(plant.A, plant.C, kf.poles, dt), plant.R)
    assert E.shape == (5, 25)
    W = plant.process_noise()
    assert np.max(np.abs(E @ W.reshape(-1, order="F") + off)) < 1e-10
    with pytest.raises(ValidationError, match="one output"):
        build_spectral_sdp(plant.A, np.vstack([plant.C, plant.C]), np.eye(2), kf.poles, dt=dt)


def test_spectral_sdp_route_reproduces_example1():
    """The fallback of method='sdp' (used when the fixed-gain SDP is badly scaled): same L."""
    from optdesign._deadline import Deadline
    from optdesign.design.inverse_kalman.sdp_route import run_spectral_sdp as _run_spectral_sdp

    plant = _ex1_plant()
    target = np.array([-8.0 + 0j, -5.0 + 0j])
    common = dict(target_poles=target, method="sdp", objective="min_trace", structure="full", plant=plant)
    res = _run_spectral_sdp(plant, target, common, None, None, 1e-8,
                            spectral_terms(plant.A, plant.C, target, None), Deadline(None))
    _assert_valid(res, plant, target, tol=1e-10)
    np.testing.assert_allclose(res.L.ravel(), [8, -6], atol=1e-9)
    assert res.objective_value == pytest.approx(76 + 10 * (350 - np.sqrt(350**2 - 3636)) - 36, rel=1e-8)


# ------------------------------------------------- spectral NLP with closed-form derivatives
@pytest.mark.parametrize("structure,objective,repeated", [
    ("full", "min_trace", False), ("full", "nearest", False), ("input", "min_trace", False),
    ("input", "nearest", False), ("full", "min_trace", True)])
def test_closed_form_spectral_derivatives_equal_casadi_symbolic_ones(rng, structure, objective, repeated):
    import casadi as ca

    from optdesign.formulate.inverse_kalman import build_spectral_nlpsol

    n, p, m = (4, 2, 3) if not repeated else (4, 3, 4)
    A = rng.standard_normal((n, n)) / np.sqrt(n)
    C = rng.standard_normal((p, n))
    G = rng.standard_normal((n, m))
    poles = np.array([-1.0 if repeated else -2.0, -1.0, -0.5 + 1j, -0.5 - 1j])
    k = n if structure == "full" else m
    nlp = build_spectral_nlpsol(A, C, np.diag([1.0, 2.0, 0.5][:p]), poles, structure=structure, G=G,
                                objective=objective, Q_nominal=np.eye(k), W0=np.eye(k), scale=2.0)
    x, f, g = nlp.nlp["x"], nlp.nlp["f"], nlp.nlp["g"]
    lf, lg = ca.SX.sym("lf"), ca.SX.sym("lg", g.shape[0])
    J_ref = ca.Function("J", [x], [ca.jacobian(g, x)])
    H_ref = ca.Function("H", [x, lf, lg], [ca.triu(ca.hessian(lf * f + ca.dot(lg, g), x)[0])])
    none = ca.DM.zeros(0, 1)
    for _ in range(3):
        xv = rng.standard_normal(x.shape[0])
        lv = rng.standard_normal(g.shape[0])
        J = ca.densify(nlp.options["jac_g"](xv, none)[1]).full()
        H = ca.densify(nlp.options["hess_lag"](xv, none, 0.7, lv)).full()
        Jr = ca.densify(J_ref(xv)).full()
        Hr = ca.densify(H_ref(xv, 0.7, lv)).full()
        np.testing.assert_allclose(J, Jr, rtol=1e-12, atol=1e-12 * np.abs(Jr).max())
        np.testing.assert_allclose(H, Hr, rtol=1e-12, atol=1e-12 * np.abs(Hr).max())


@pytest.mark.parametrize("objective", ["min_trace", "nearest"])
def test_closed_form_spectral_nlp_agrees_with_the_symbolic_one(rng, objective, monkeypatch):
    plant = random_observable_plant(rng, 6, 2, noise=False).replace(R=np.diag([1.0, 0.5]))
    F = rng.standard_normal((6, 6)) / np.sqrt(6)
    target = _are(plant, F @ F.T).poles
    kw = dict(method="nlp", objective=objective, Q_nominal=np.eye(6) if objective == "nearest" else None)
    fast = kalman_for_poles(plant, target, **kw)
    slow = kalman_for_poles(plant, target, nlp_options={"derivatives": "symbolic"}, **kw)
    assert fast.success and slow.success
    assert {e["derivatives"] for e in fast.extra["starts"]} == {"closed form"}
    assert {e["derivatives"] for e in slow.extra["starts"]} == {"symbolic"}
    np.testing.assert_allclose(fast.objective_value, slow.objective_value, rtol=1e-6)


# --------------------------------------------- targets no design verifies: the best unverified answer


def _uncomputable_target():
    """n = 20, one output: the poles of the Kalman filter of Q have a rounding floor ~0.6; no gain
    computed in double precision places them to the cap of 1e-6 (the placed gain's pole error ~2e-3,
    the engine's ~2e-3).  The Riccati solve itself is accurate only to a relative residual ~1e-6,
    which depends on the CPU's rounding (no residual test): its P is exact for ``Q - residual``, a
    member of the target's family within ~1e-6 of Q."""
    n = 20
    rng = np.random.default_rng(2)
    A = rng.standard_normal((n, n)) / np.sqrt(n)
    C = rng.standard_normal((1, n))
    F = rng.standard_normal((n, n)) / np.sqrt(n)
    Q = F @ F.T
    are = filter_are(Plant(A, C, Q=Q, R=np.eye(1)), residual_tol=np.inf)
    return Plant(A, C, R=np.eye(1)), are.poles, Q


def test_uncomputable_one_output_target_returns_the_engine_design_and_skips_the_fallbacks(monkeypatch):
    """Issue 14: the verb used to run the SDP fallbacks after the engine (0.6-0.7 s) and return their
    worse unverified design (trace Q ~1e9 against the engine's ~5)."""
    import optdesign.design.inverse_kalman.verb as verb
    from optdesign.design.verification import POLE_FLOOR_CAP
    from optdesign.engines.inverse_kalman_engine import prepare_inverse_kalman, solve_inverse_kalman

    plant, target, Q = _uncomputable_target()

    def fallback(*args, **kwargs):
        raise AssertionError("a fallback route ran on a target no route can verify")

    monkeypatch.setattr(verb, "run_sdp", fallback)
    res = kalman_for_poles(plant, target)
    assert not res.success
    assert res.status == Status.OPTIMAL_INACCURATE
    assert "not computable" in res.message and "the other routes were not run" in res.message
    assert res.verification["pole_error"].value > POLE_FLOOR_CAP
    # the generating Q is feasible (to the residual of its Riccati solve), so the min-trace answer is
    # no larger (it is ~4x smaller; the fallback's design had ~1e9); the engine's own optimum
    assert res.objective_value <= np.trace(Q) * (1 + 1e-3)
    eng = solve_inverse_kalman(prepare_inverse_kalman(plant), target)
    assert res.objective_value == pytest.approx(eng.objective_value, rel=1e-9)
    assert res.L is not None and res.Q is not None and res.P is not None   # nothing lost


def test_uncomputable_poles_measures_the_placed_gain():
    from optdesign.design.inverse_kalman.common import uncomputable_poles
    from optdesign.results import Check, Verification

    plant, target, _ = _uncomputable_target()
    res = kalman_for_poles(plant, target)
    err = uncomputable_poles(plant, res, target, 1e-8)
    assert err is not None and err > 1e-6
    # a well-conditioned target: the placed gain places it, so the other routes can help
    easy = kalman_for_poles(Plant([[0, 1], [-6, -5]], [[1, 0]], R=[[1]]), [-5, -8])
    assert easy.success
    failed = dataclasses.replace(easy, verification=Verification.of(
        [Check.at_most("pole_error", 1e-3, 1e-8)]))
    assert uncomputable_poles(easy.plant, failed, easy.target_poles, 1e-8) is None
    assert uncomputable_poles(easy.plant, easy, easy.target_poles, 1e-8) is None  # it passed
    # several outputs: the poles do not fix the gain, so the other routes may find another
    two = dataclasses.replace(failed, plant=Plant(np.diag([-1.0, -2.0]), np.eye(2), R=np.eye(2)))
    assert uncomputable_poles(two.plant, two, np.array([-3.0, -4.0]), 1e-8) is None


def test_best_unverified_takes_the_smallest_violation_then_the_objective():
    from optdesign.design.inverse_kalman.common import best_unverified, design_violation
    from optdesign.results import Check, Verification

    base = kalman_for_poles(Plant([[0, 1], [-6, -5]], [[1, 0]], R=[[1]]), [-5, -8])
    plant = base.plant

    def variant(value, obj, name="riccati_residual", **kw):
        ver = Verification.of([Check.at_most(name, value, 1e-8)])
        return dataclasses.replace(base, verification=ver, objective_value=obj, **kw)

    close, far = variant(2e-8, 1e9), variant(1e-6, 1.0)
    assert design_violation(plant, close) == pytest.approx(1.0)
    assert design_violation(plant, far) == pytest.approx(99.0)
    assert best_unverified(plant, [far, close]) is close            # violation first
    cheap, dear = variant(2e-8, 3.0), variant(2e-8, 5.0)
    assert best_unverified(plant, [dear, cheap]) is cheap           # then the objective
    m_lo = variant(2e-8, 0.1, objective="feasibility")
    m_hi = variant(2e-8, 0.5, objective="feasibility")
    assert best_unverified(plant, [m_lo, m_hi]) is m_hi              # a larger margin is better
    none = dataclasses.replace(far, L=None)
    assert best_unverified(plant, [none]) is None and design_violation(plant, none) == float("inf")
    assert best_unverified(plant, [none, far]) is far
    # a pole error within the rounding floor of the poles (here ~1e-15) is still a violation, one
    # within an uncomputable target's floor is none
    assert design_violation(plant, variant(1e-6, 1.0, name="pole_error")) > 0
    hard, target, _ = _uncomputable_target()
    res = kalman_for_poles(hard, target)
    assert not res.verification["pole_error"].passed
    only_poles = dataclasses.replace(res, verification=Verification.of(
        [c for c in res.verification.checks if c.name in ("pole_error", "riccati_residual")]))
    assert design_violation(hard, only_poles) == 0.0


# ------------------------------------------------- the closest-poles search's fast DARE (doubling)
def _dare_poles(A, C, R, P):
    """The discrete filter's poles ``eig(A - L C)`` and eigenvectors for the ARE solution P."""
    return np.linalg.eig(A - filter_gain(A, C, R, P, True) @ C)


@pytest.mark.parametrize("seed", range(6))
def test_doubling_dare_is_the_stabilizing_solution_scipy_finds(seed):
    """``filter_dare_doubling`` (the closest-poles search's first DARE solver) returns the
    stabilizing solution when (A, Q) is detectable: scipy's QZ solver's P to ``1e3 n eps cond(P)``,
    with a relative DARE residual (:func:`filter_are_residual`) no larger than scipy's (or than
    that level)."""
    from scipy.linalg import solve_discrete_are

    from optdesign.classical.riccati import filter_dare_doubling

    rng = np.random.default_rng(seed)
    n, p = 2 + seed % 4, 1 + seed % 2
    A = rng.standard_normal((n, n))
    A = 1.2 * A / np.max(np.abs(np.linalg.eigvals(A)))
    C = rng.standard_normal((p, n))
    F = rng.standard_normal((n, n))
    Q, R = F @ F.T, np.eye(p)
    plant = Plant(A, C, R=R, dt=0.1)
    Pd = filter_dare_doubling(A, C, Q, R)
    Ps = solve_discrete_are(A.T, C.T, Q, R, balanced=False)
    assert Pd is not None
    tol = 1e3 * n * np.finfo(float).eps * max(1.0, np.linalg.cond(Ps))
    assert filter_are_residual(plant, Pd, Qs=Q) <= max(filter_are_residual(plant, Ps, Qs=Q), tol)
    np.testing.assert_allclose(Pd, Ps, rtol=0, atol=tol * np.abs(Ps).max())


def test_doubling_dare_hands_an_undetectable_noise_over_to_scipy():
    """Q = 0 on an unstable mode: the doubling converges to P = 0, which is not stabilizing
    (A - LC = A).  ``fast_pole_error`` then uses scipy's stabilizing solution, so the pole error
    is the Kalman filter's, not inf."""
    from scipy.linalg import solve_discrete_are

    from optdesign.classical.riccati import filter_dare_doubling
    from optdesign.design.inverse_kalman.nlp_solves import fast_pole_error

    A, C, R = np.diag([1.5, 0.4]), np.array([[1.0, 1.0]]), np.eye(1)
    Q = np.zeros((2, 2))
    Pd = filter_dare_doubling(A, C, Q, R)
    assert Pd is not None and np.allclose(Pd, 0.0)
    poles, _ = _dare_poles(A, C, R, solve_discrete_are(A.T, C.T, Q, R, balanced=False))
    assert np.all(np.abs(poles) < 1.0)
    plant = Plant(A, C, R=R, dt=0.1)
    # target = the filter's poles: the error is rounding (eigvals of two roundings of one matrix)
    assert fast_pole_error(plant, np.sort_complex(poles), "full", Q) <= 1e3 * np.finfo(float).eps


def test_fast_pole_error_with_the_doubling_equals_scipys_on_random_discrete_plants():
    """The closest-poles search's pole error, doubling first, against the same error through scipy's
    QZ solver alone, on 40 seeded discrete plants n = 2..5 with Q over ten decades and singular
    diagonal Q (where the doubling can end at a non-stabilizing solution and hands over: seed 36)."""
    from scipy.linalg import solve_discrete_are

    from optdesign.classical.riccati import filter_dare_doubling
    from optdesign.design.inverse_kalman.nlp_solves import fast_pole_error

    rng = np.random.default_rng(20261207)
    compared, handed = 0, 0
    for s in range(40):
        n, p = 2 + s % 4, 1 + s % 2
        A = rng.standard_normal((n, n))
        A = rng.uniform(0.5, 1.4) * A / np.max(np.abs(np.linalg.eigvals(A)))
        C, R = rng.standard_normal((p, n)), np.eye(p)
        if s % 3:
            F = rng.standard_normal((n, n)) * np.exp(rng.uniform(-5.0, 5.0))
            Q = F @ F.T
        else:
            Q = np.diag(rng.uniform(0.0, 1.0, n) * (rng.uniform(size=n) > 0.5))
        plant = Plant(A, C, R=R, dt=0.1)
        target = np.sort_complex(rng.uniform(-0.9, 0.9, n).astype(complex))
        P = solve_discrete_are(A.T, C.T, Q, R, balanced=False)
        poles, V = _dare_poles(A, C, R, P)
        assert np.all(np.abs(poles) < 1.0), s  # every case is compared (none skipped)
        # scipy's P is accurate to its relative DARE residual; the poles move by that times their
        # condition (cond V): measured here at most 1.5 of it
        level = filter_are_residual(plant, P, Qs=Q) + n * np.finfo(float).eps
        tol = 10.0 * level * np.linalg.cond(V)
        ref = pole_error(poles, target)
        assert fast_pole_error(plant, target, "full", Q) == pytest.approx(ref, abs=tol), s
        compared += 1
        Pd = filter_dare_doubling(A, C, Q, R)
        handed += Pd is None or not np.all(np.abs(_dare_poles(A, C, R, Pd)[0]) < 1.0)
    assert compared == 40 and handed >= 1, (compared, handed)  # both paths ran
