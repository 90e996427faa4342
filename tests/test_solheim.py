"""Solheim's sequential method (seed 000, Chang & Lee 1984): paper examples, the corrected
equations of the complex-pair case, additivity, discrete time, and every error path."""

from __future__ import annotations

import numpy as np
import pytest

from optdesign import Plant, problems
from optdesign.classical import solheim
from optdesign.classical.placement import place_observer, pole_error
from optdesign.classical.riccati import filter_are, filter_are_residual, hamiltonian_are
from optdesign.classical.solheim import SolheimResult
from optdesign.errors import DimensionError, NotConjugateClosedError, NotObservableError, ValidationError


def _ex1():
    prob = problems.load("chang_lee_1984_ex1")
    return prob, prob.plant.replace(Q=None, G=None)


def _ex2():
    prob = problems.load("chang_lee_1984_ex2")
    return prob, prob.plant


# --------------------------------------------------------------------------- Example 1
def test_example1_reproduces_the_paper_exactly():
    prob, plant = _ex1()
    res = solheim(plant, prob.targets["poles"])
    ref = prob.references
    assert isinstance(res, SolheimResult) and res.success
    np.testing.assert_allclose(res.L, ref["K_printed"], atol=1e-12)
    np.testing.assert_allclose(res.K, ref["K_printed"], atol=1e-12)
    np.testing.assert_allclose(res.Q, ref["Q_prime_printed"], atol=1e-12)
    np.testing.assert_allclose(res.P, ref["P_derived"], atol=1e-12)
    assert pole_error(res.poles, [-5, -8]) < 1e-14


def test_example1_every_step_matches_the_printed_intermediates():
    prob, plant = _ex1()
    res = solheim(plant, prob.targets["poles"])
    steps = prob.references["steps_printed"]
    assert len(res.steps) == 2
    for st, pr in zip(res.steps, steps, strict=True):
        assert st.kind == "real"
        # the printed eigenvector scaling (largest entry 1) makes q~, P~, K~ comparable
        assert st.q_tilde[0, 0] == pytest.approx(pr["q_tilde_printed"], abs=1e-12)
        assert st.P_tilde[0, 0] == pytest.approx(np.max(pr["P_tilde_printed"]), abs=1e-12)
        np.testing.assert_allclose(st.K, pr["K_step_printed"], atol=1e-12)
        np.testing.assert_allclose(st.A_after, pr["A_next_printed"], atol=1e-12)
        np.testing.assert_allclose(st.Q, pr["Q_prime_step_printed"], atol=1e-12)
        np.testing.assert_allclose(np.sort(np.linalg.eigvals(st.A_after).real),
                                   np.sort(pr["poles_next_printed"]), atol=1e-12)
    # step 1 moves -2 -> -5 (h22 = 0.25 with M = [-0.5, 1]), step 2 moves -3 -> -8 (h11 = 1)
    assert res.steps[0].moved[0] == pytest.approx(-2) and res.steps[0].placed[0] == pytest.approx(-5)
    assert res.steps[0].H[0, 0] == pytest.approx(0.25)
    assert res.steps[1].moved[0] == pytest.approx(-3) and res.steps[1].placed[0] == pytest.approx(-8)


def test_example1_appendix_sums_and_an_independent_riccati_solve():
    prob, plant = _ex1()
    res = solheim(plant, prob.targets["poles"])
    np.testing.assert_allclose(sum(s.K for s in res.steps), res.L, atol=1e-14)
    np.testing.assert_allclose(sum(s.Q for s in res.steps), res.Q, atol=1e-14)
    np.testing.assert_allclose(sum(s.P for s in res.steps), res.P, atol=1e-14)
    are = filter_are(plant.replace(Q=res.Q))
    np.testing.assert_allclose(are.L, res.L, atol=1e-12)
    np.testing.assert_allclose(are.P, res.P, atol=1e-12)
    assert res.verification["riccati_residual"].value < 1e-14


# --------------------------------------------------------------------------- Example 2
def test_example2_done_correctly_reaches_the_targets():
    prob, plant = _ex2()
    res = solheim(plant, prob.targets["poles"])
    assert res.success, res.verification.summary()
    assert pole_error(res.poles, [-8, -5]) < 1e-12
    # a direct ARE solve with the sequential Q' gives the same gain and the target poles
    are = filter_are(plant.replace(Q=res.Q))
    np.testing.assert_allclose(are.L, res.L, atol=1e-11)
    assert pole_error(are.poles, [-8, -5]) < 1e-12
    kinds = [s.kind for s in res.steps]
    assert kinds == ["pair_identity", "real"]  # the paper's route: Q~ = q I, then a real step


def test_example2_step1_solves_eq44_eq45_exactly_with_r1_8():
    prob, plant = _ex2()
    st = solheim(plant, prob.targets["poles"]).steps[0]
    q = st.q_tilde[0, 0]
    np.testing.assert_allclose(st.q_tilde, q * np.eye(2), atol=1e-14)  # eq (35): q11 = q22
    H = st.H
    a2, b2 = 1.0, 1.0  # alpha^2, beta^2 of -1 +- j
    r1, r2 = 8.0, -np.sort(-np.abs(st.placed.real))[1]
    # eq (44) and eq (45) (the latter as printed: middle term with (a^2 + b^2), not squared)
    assert q == pytest.approx((r1**2 + r2**2 - 2 * (a2 - b2)) / np.trace(H), rel=1e-12)
    assert r1**2 * r2**2 == pytest.approx(
        (a2 + b2) ** 2 + q * np.trace(H) * (a2 + b2) + q**2 * np.linalg.det(H), rel=1e-12)
    assert q == pytest.approx(67.27342336, rel=1e-9)
    assert r2 == pytest.approx(4.09000098, rel=1e-8)
    # the paper prints q = 66.534 and r2 = -3.98: that pair satisfies (44) but not (45)
    q_p, r2_p = 66.534, 3.98
    assert r1**2 + r2_p**2 == pytest.approx(q_p * 1.2, rel=1e-3)            # (44) holds
    lhs, rhs = r1**2 * r2_p**2, 4 + q_p * 1.2 * 2 + q_p**2 * 0.2
    assert abs(lhs - rhs) > 30                                               # (45) fails by 35


def test_example2_records_why_the_printed_numbers_are_inconsistent():
    """The paper's Example 2 does not reproduce; each printed inconsistency is asserted here."""
    prob, plant = _ex2()
    ref = prob.references
    R, C, A = plant.R, plant.C, plant.A
    s1, s2 = ref["steps_printed"]
    # (1) the printed P~ of step 1 does not solve the modal Riccati equation (29) with q~ = 66.534
    T = np.asarray(s1["T_printed"])
    Lam = np.linalg.solve(T, A @ T)
    H = T.T @ C.T @ np.linalg.solve(R, C @ T)
    Pt = np.asarray(s1["P_tilde_printed"])
    res29 = Lam @ Pt + Pt @ Lam.T - Pt @ H @ Pt + s1["q_tilde_printed"] * np.eye(2)
    assert np.max(np.abs(res29)) > 50  # residual 56.9: P~11 = 3.46 should be 13.73
    Pt_true = hamiltonian_are(Lam.T, (C @ T).T, s1["q_tilde_printed"] * np.eye(2), R)
    assert Pt_true[0, 0] == pytest.approx(13.7314, abs=1e-4)
    # (2) hence A_1 has eigenvalues -8.02, -1.87 (printed -7.976, -1.91), not -8 and -3.98
    A1 = np.asarray(s1["A_next_printed"])
    assert pole_error(np.linalg.eigvals(A1), [-8.0, -3.98]) > 0.5
    # (3) Q'_1 is printed with 66.354 although q~ = 66.534 (transposed digits) ...
    assert s1["Q_prime_step_printed"][0][0] == 66.354 != s1["q_tilde_printed"]
    # ... and the printed final Q' = Q'_1 + Q'_2 uses the transposed value
    np.testing.assert_allclose(np.asarray(s1["Q_prime_step_printed"]) + s2["Q_prime_step_printed"],
                               ref["Q_prime_printed"], atol=1e-9)
    # (4) the printed K only nearly places the poles ...
    assert 1e-3 < pole_error(np.linalg.eigvals(A - np.asarray(ref["K_printed"]) @ C), [-8, -5]) < 1e-2
    # (5) ... and is not the Kalman gain of the printed Q': its ARE gives poles -8.27, -15.70
    are = filter_are(plant.replace(Q=np.asarray(ref["Q_prime_printed"])))
    np.testing.assert_allclose(np.sort(are.poles.real), [-15.6976, -8.2726], atol=1e-3)
    # (6) the printed step-2 q~ = 1050 ("trial and error") with the printed M_1 does not give
    #     the printed P~_2 = 14.8 either: the rank-one Riccati root is p = 60.5
    m = np.asarray(s2["M_printed"])[:, 1]
    h = m @ C.T @ np.linalg.solve(R, C @ m)
    lam = -1.91
    p_root = (lam + np.sqrt(lam**2 + h * s2["q_tilde_printed"])) / h
    assert abs(p_root - 14.8) > 40


def test_example2_diagonal_variant_moves_the_pair_in_one_step():
    prob, plant = _ex2()
    res = solheim(plant, prob.targets["poles"], complex_to_real="diagonal")
    assert res.success and len(res.steps) == 1 and res.steps[0].kind == "pair_diagonal"
    assert pole_error(res.poles, [-8, -5]) < 1e-12
    qt = res.steps[0].q_tilde
    assert qt[0, 1] == 0 and min(qt[0, 0], qt[1, 1]) > 0


# ------------------------------------------------------------- corrected equations
def test_quartic_36_is_the_canonical_characteristic_polynomial_and_39_has_a_sign_typo(rng):
    for _ in range(5):
        a, b = rng.uniform(0.2, 2.0, 2)
        Lam = np.array([[-a, b], [-b, -a]])
        F = rng.standard_normal((2, 2))
        H = F @ F.T
        q = rng.uniform(0.1, 5.0)
        Z = np.block([[-Lam.T, H], [q * np.eye(2), Lam]])
        rho = a * a + b * b
        eq36 = [1, 0, -(2 * (a * a - b * b) + q * np.trace(H)), 0,
                q * q * np.linalg.det(H) + q * np.trace(H) * rho + rho**2]
        np.testing.assert_allclose(np.poly(Z), eq36, rtol=1e-9, atol=1e-9)
    # the polynomial whose roots are +-(-r +- j delta):  s^4 + 2(delta^2 - r^2) s^2 + (r^2 + delta^2)^2
    r, d = 1.5, 0.7
    roots = [-r + 1j * d, -r - 1j * d, r + 1j * d, r - 1j * d]
    np.testing.assert_allclose(np.real(np.poly(roots)), [1, 0, 2 * (d * d - r * r), 0, (r * r + d * d) ** 2],
                               atol=1e-12)
    printed39 = [1, 0, 2 * (r * r - d * d), 0, (r * r + d * d) ** 2]
    assert np.min(np.abs(np.polyval(printed39, roots[0]))) > 1.0


def test_complex_target_on_the_eq41_curve_is_reached_with_q_identity(rng):
    """If the target pair comes from Q~ = q I, the diagonal pair step finds q1 = q2 = q."""
    A = np.array([[-1.0, 2.0], [-2.0, -1.0]])
    C = np.array([[1.0, 0.3], [0.2, 1.0]])
    R = np.diag([1.0, 2.0])
    plant = Plant(A, C, R=R)
    q = 3.0
    target = filter_are(plant.replace(Q=q * np.eye(2))).poles
    assert np.all(np.abs(target.imag) > 0)
    res = solheim(plant, target)
    assert res.success
    st, = res.steps
    assert st.kind == "pair_diagonal"
    # Q' = q T T' for the orthogonal modal basis T with T T' = c I
    np.testing.assert_allclose(res.Q, q * np.eye(2), rtol=1e-9, atol=1e-9)


# ------------------------------------------------------------------ random systems
def _real_eig_plant(rng, n, p, dt=None):
    """Distinct real eigenvalues (gaps >= 0.1: a single output cannot tell nearly equal modes
    apart, so they would be nearly unobservable) and a well-conditioned eigenbasis."""
    while True:
        lam = -rng.uniform(0.3, 3.0, n) if dt is None else rng.uniform(0.1, 0.9, n)
        if n > 1 and np.min(np.diff(np.sort(lam))) < 0.1:
            continue
        V = rng.standard_normal((n, n)) + 2 * np.eye(n)
        A = V @ np.diag(lam) @ np.linalg.inv(V)
        plant = Plant(A, rng.standard_normal((p, n)), R=np.diag(rng.uniform(0.5, 2.0, p)), dt=dt)
        if plant.is_observable() and np.linalg.cond(V) < 50:
            return plant, lam


@pytest.mark.parametrize("p", [1, 2])
def test_leftward_real_moves_give_a_psd_kalman_design(rng, p):
    for n in (2, 3, 5):
        plant, lam = _real_eig_plant(rng, n, p)
        target = np.sort(lam)[::-1] - rng.uniform(0.5, 3.0, n)  # every pole moves left
        res = solheim(plant, target)
        assert res.success, res.verification.summary()
        assert all(s.kind == "real" and s.q_tilde[0, 0] > 0 for s in res.steps)
        if p == 1:  # one output: the poles fix L
            np.testing.assert_allclose(res.L, place_observer(plant, target), rtol=1e-7, atol=1e-9)


def test_discrete_real_steps_add_up_with_the_innovation_covariance(rng):
    for n in (2, 4):
        plant, lam = _real_eig_plant(rng, n, 2, dt=0.1)
        target = np.sort(lam) * rng.uniform(0.2, 0.8, n)  # every pole moves towards 0
        res = solheim(plant, target)
        assert res.success, res.verification.summary()
        # step k uses R_k = C (P_1 + ... + P_{k-1}) C' + R
        acc = np.zeros((n, n))
        for st in res.steps:
            np.testing.assert_allclose(st.R, plant.C @ acc @ plant.C.T + plant.R, atol=1e-12)
            acc = acc + st.P
        assert filter_are_residual(plant, res.P, Qs=res.Q) < 1e-13
        are = filter_are(plant.replace(Q=res.Q))
        np.testing.assert_allclose(are.L, res.L, rtol=1e-9, atol=1e-12)


def test_a_pole_moved_towards_the_origin_gives_an_indefinite_q_and_no_success():
    plant = Plant([[-3.0, 0.0], [0.0, -5.0]], [[1.0, 1.0]], R=[[1.0]])
    res = solheim(plant, [-1.0, -6.0])  # -3 -> -1 needs q~ = (1 - 9)/h < 0
    assert not res.success
    assert not res.verification["Q_min_eig"].passed
    assert "indefinite" in res.message
    assert pole_error(res.poles, [-1, -6]) < 1e-12  # the poles are placed, the Q is not valid


def test_real_eigenvalues_moved_to_a_complex_pair():
    """Not in the paper: two real eigenvalues become a complex pair (a generalized pair step)."""
    plant = Plant([[0.0, 1, 0], [0, 0, 1], [-6, -11, -6]], [[1.0, 0, 0]], R=[[1.0]])  # eig -1, -2, -3
    target = filter_are(plant.replace(Q=10 * np.eye(3))).poles
    assert np.sum(np.abs(target.imag) > 0) == 2
    res = solheim(plant, target)
    assert res.success, res.verification.summary()
    assert res.steps[0].kind in ("pair_diagonal", "pair_rotated")
    assert pole_error(res.poles, target) < 1e-12
    np.testing.assert_allclose(res.L, place_observer(plant, target), rtol=1e-8)


# ---------------------------------------------------------------------- error paths
def test_error_paths():
    plant = Plant([[0, 1], [-6, -5]], [[1, 0]], R=[[1]])
    with pytest.raises(ValidationError, match="stable"):
        solheim(plant, [1.0, -8.0])
    with pytest.raises(ValidationError, match="has no R"):
        solheim(plant.replace(R=None), [-5, -8])
    with pytest.raises(ValidationError, match="complex_to_real must be one of"):
        solheim(plant, [-5, -8], complex_to_real="magic")
    with pytest.raises(DimensionError, match="wrong length"):
        solheim(plant, [-5, -8, -9])
    with pytest.raises(NotConjugateClosedError, match="conjugation"):
        solheim(plant, [-5 + 1j, -8])
    unobs = Plant([[-1.0, 0.0], [0.0, -2.0]], [[1.0, 0.0]], R=[[1.0]])
    with pytest.raises(NotObservableError, match="unobservable"):
        solheim(unobs, [-1.0, -4.0])  # -2 must move but C does not see it
    disc = Plant([[0.5, 0.0], [0.0, 0.2]], [[1.0, 1.0]], R=[[1.0]], dt=1.0)
    with pytest.raises(ValidationError, match="inside the unit circle"):
        solheim(disc, [0.5, 1.5])
    with pytest.raises(ValidationError, match="infinite process noise"):
        solheim(disc, [0.0, 0.2])
    # 0.5 -> -0.5 in discrete time: p~ h = lambda / S - 1 = -2, so C P C' + R = R lambda / S < 0
    with pytest.raises(ValidationError, match=r"step 1 \(real, moving 0\.5\) makes the innovation covariance "
                                              r"C P C' \+ R indefinite"):
        solheim(disc, [-0.5, 0.2])
    # a complex pair that must move but that C does not see
    hidden_pair = Plant([[-1.0, 2.0, 0.0], [-2.0, -1.0, 0.0], [0.0, 0.0, -3.0]], [[0.0, 0.0, 1.0]], R=[[1.0]])
    with pytest.raises(NotObservableError, match=r"the pair -1\+2j, -1-2j is unobservable \(H_E = 0\)"):
        solheim(hidden_pair, [-2.0 + 2.0j, -2.0 - 2.0j, -3.0])
    # a pair step whose coefficient equations have no real root for any orientation of Q~
    pair = Plant([[-1.2, 1.3], [-1.3, -1.2]], [[-0.65, 0.86], [-0.13, 0.67]], R=np.eye(2))
    with pytest.raises(ValidationError, match=r"no real Q~ on the modes -1\.2\+1\.3j, -1\.2-1\.3j moves them "
                                              r"to -5\.8\+5\.2j, -5\.8-5\.2j .* for any orientation"):
        solheim(pair, [-5.8 + 5.2j, -5.8 - 5.2j])


def test_unobservable_mode_that_stays_is_fine():
    unobs = Plant([[-1.0, 0.0], [0.0, -2.0]], [[1.0, 0.0]], R=[[1.0]])
    res = solheim(unobs, [-4.0, -2.0])  # -2 is unobservable but already where it should be
    assert res.success and len(res.steps) == 1
