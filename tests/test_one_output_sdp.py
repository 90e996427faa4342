"""The one-output fixed-gain SDP in its n-constraint form (optdesign.engines.one_output_sdp), the lean
one-output gain, and the engine's use of them.

The form's optimum must be the general route's (the direct form on Clarabel or the dense IPM,
polished on its face) on random families, continuous and discrete, n = 2..20; its answer must be an
exact member of the family, exactly PSD, with a KKT certificate; a failure anywhere must hand the
design to the general route with nothing lost.
"""

from __future__ import annotations

import pickle

import numpy as np
import pytest
from test_fixed_gain_ipm import _bench_targets, _family

import optdesign.engines.inverse_kalman_engine as engine
import optdesign.engines.one_output_sdp as oo
from optdesign import InverseKalmanProblem, Plant, kalman_for_poles
from optdesign._validate import as_poles
from optdesign.analysis.metrics import eigenvalue_rounding_floor
from optdesign.backends.clarabel_fixed_gain import fixed_gain_family, riccati_of_gain, smat, svec
from optdesign.classical.placement import pole_error
from optdesign.engines.fixed_gain_ipm import standard_form_ipm
from optdesign.engines.spectral_factor import spectral_blocks
from optdesign.errors import ValidationError
from optdesign.formulate.inverse_kalman import spectral_terms
from optdesign.formulate.inverse_kalman.common import single_output_gain
from optdesign.results import Status

EPS = float(np.finfo(float).eps)
#: two exact (polished, KKT-certified) optima of the same convex problem: equal to rounding, with
#: the conditioning of the family (measured: 1e-12 .. 3e-10 relative on these families)
AGREE = 1e-8


def _solved(fam):
    form = oo.one_output_form(fam.T)
    assert form is not None
    return form, oo.solve_one_output(form, fam)


# ------------------------------------------------------------------------------------- the form
@pytest.mark.parametrize("n", [2, 4, 7])
def test_form_is_an_orthonormal_basis_of_the_complement_of_the_family(n):
    _, fam = _family(200 + n, n, None)
    form = oo.one_output_form(fam.T)
    W = form.W
    assert W.shape == (n * (n + 1) // 2, n)
    np.testing.assert_allclose(W.T @ W, np.eye(n), rtol=0, atol=50 * n * EPS)
    assert np.max(np.abs(fam.T.T @ W)) <= 50 * n * EPS * np.max(np.abs(fam.T))
    # membership: a point of the family has the family's b, a point off it does not
    b = W.T @ svec(fam.Q0)
    x = np.random.default_rng(n).standard_normal(fam.T.shape[1])
    np.testing.assert_allclose(W.T @ (svec(fam.Q0) + fam.T @ x), b, rtol=0,
                               atol=1e-12 * (1 + np.linalg.norm(x)))
    assert np.linalg.norm(W.T @ (svec(fam.Q0) + W[:, 0]) - b) == pytest.approx(1.0)


def test_form_refuses_directions_that_do_not_move_Q():
    _, fam = _family(204, 4, None)
    T = fam.T.copy()
    T[:, 1] = T[:, 0]
    assert oo.one_output_form(T) is None
    assert oo.one_output_form(np.ones((5, 2))) is None   # not a triangle of any n


def test_symmetric_product_matrix_is_the_symmetrized_product():
    rng = np.random.default_rng(5)
    for n in (1, 2, 5):
        X, H = ((lambda M: M + M.T)(rng.standard_normal((n, n))) for _ in range(2))
        M = oo.symmetric_product_matrix(X)
        np.testing.assert_allclose(M @ svec(H), svec(0.5 * (X @ H + H @ X)), rtol=1e-13, atol=1e-13)


# --------------------------------------------------------------------------- the solve and polish
@pytest.mark.parametrize("dt", [None, 0.1])
@pytest.mark.parametrize("n", [2, 3, 5, 8, 12, 16, 20])
def test_optimum_is_the_general_routes_exact_and_certified(n, dt, general_one_output_route):
    plant, fam = _family(100 + n, n, dt)
    form, sol = _solved(fam)
    assert sol.Q is not None, sol.reason
    assert sol.native_status == ("ipm: solved" if n >= oo.IPM_MIN_N else "Solved")
    assert 1 <= sol.newton_iterations <= oo.POLISH_MAX_ITER
    assert sol.kkt["passed"] and sol.kkt["min_eig"] >= -oo.KKT_TOL
    # exactly PSD (V V') and an exact member of the family
    Q = sol.Q
    nq = float(np.linalg.norm(Q, 2))
    lam = np.linalg.eigvalsh(Q)
    assert lam[0] >= -10 * n * EPS * nq
    # rank r: n - r eigenvalues zero to rounding (V V' of r columns), the others positive
    assert 1 <= sol.rank <= n
    assert np.all(np.abs(lam[:n - sol.rank]) <= 10 * n * EPS * nq) and lam[n - sol.rank] > 0
    b = form.W.T @ svec(fam.Q0)
    assert np.linalg.norm(form.W.T @ svec(Q / fam.scale) - b) <= 1e-12 * np.linalg.norm(b) + 1e-14
    # its Riccati solution for the gain satisfies the gain relation: P C' = L R (continuous),
    # (A - L C) P C' = L R (discrete)
    P = riccati_of_gain(plant.A, plant.C, fam.L, fam.R, Q, dt)
    PC = P @ plant.C.T if dt is None else (plant.A - fam.L @ plant.C) @ P @ plant.C.T
    np.testing.assert_allclose(PC, fam.L @ fam.R, rtol=1e-8, atol=1e-10 * np.linalg.norm(P))
    # the general route (direct form, polished on its face) reaches the same optimum
    setup = engine.prepare_inverse_kalman(plant, verify=False)
    ref = engine.solve_inverse_kalman(setup, np.linalg.eigvals(plant.A - fam.L @ plant.C))
    assert ref.status == Status.OPTIMAL and ref.details["kkt"]["passed"]
    assert np.trace(Q) == pytest.approx(ref.objective_value, rel=AGREE)


@pytest.mark.parametrize("n", [4, 12])
def test_the_dense_ipm_and_clarabel_start_the_polish_at_the_same_optimum(n, monkeypatch):
    _, fam = _family(300 + n, n, None)
    form = oo.one_output_form(fam.T)
    monkeypatch.setattr(oo, "IPM_MIN_N", 1)
    ipm = oo.solve_one_output(form, fam)
    monkeypatch.setattr(oo, "IPM_MIN_N", 10**6)
    cla = oo.solve_one_output(form, fam)
    assert ipm.native_status == "ipm: solved" and cla.native_status == "Solved"
    assert ipm.kkt["passed"] and cla.kkt["passed"] and ipm.rank == cla.rank
    np.testing.assert_allclose(ipm.Q, cla.Q, rtol=0, atol=AGREE * np.linalg.norm(cla.Q))
    # an IPM that does not meet its test hands the SDP to Clarabel
    monkeypatch.setattr(oo, "IPM_MIN_N", 1)
    monkeypatch.setattr(oo, "standard_form_ipm", lambda *a, **k: (None, None))
    again = oo.solve_one_output(form, fam)
    assert again.native_status == "Solved" and again.kkt["passed"]


def test_polish_returns_to_the_optimum_from_a_perturbed_point():
    _, fam = _family(108, 8, None)
    form, sol = _solved(fam)
    b = form.W.T @ svec(fam.Q0)
    bn = b / np.linalg.norm(b)
    Qn = sol.Q / (fam.scale * np.linalg.norm(b))
    rng = np.random.default_rng(1)
    q = svec(Qn) * (1 + 1e-6 * rng.standard_normal(Qn.shape[0] * (Qn.shape[0] + 1) // 2))
    y = sol.y * (1 + 1e-6 * rng.standard_normal(sol.y.size))
    q1, y1, steps, why = oo._polish(form.W, bn, q, y, form.n)
    assert why == "" and 1 <= steps <= 4
    np.testing.assert_allclose(smat(q1, form.n), Qn, rtol=0, atol=1e-12 * np.linalg.norm(Qn))
    np.testing.assert_allclose(y1, sol.y, rtol=0, atol=1e-10 * np.linalg.norm(sol.y))


def test_failures_give_no_solution_and_a_reason(monkeypatch):
    _, fam = _family(105, 5, None)
    form = oo.one_output_form(fam.T)
    # a singular Newton system: Q = 0 and y = 0 leave the y-columns zero
    t = form.W.shape[0]
    b = np.ones(form.n) / np.sqrt(form.n)
    _, _, _, why = oo._polish(form.W, b, np.zeros(t), np.zeros(form.n), form.n)
    assert "singular" in why
    # Clarabel stopped before it solved
    real = oo._settings

    def one_iteration(clarabel, deadline):
        st = real(clarabel, deadline)
        st.max_iter = 1
        return st

    monkeypatch.setattr(oo, "_settings", one_iteration)
    sol = oo.solve_one_output(form, fam)
    assert sol.Q is None and sol.reason == "Clarabel MaxIterations" and sol.iterations == 1
    # Q = 0 is in the family: nothing to solve, said so
    zero = fixed_gain_family(fam.map, np.zeros_like(fam.L), fam.R)
    assert "norm 0" in oo.solve_one_output(form, zero).reason


def test_engine_falls_back_to_the_general_route_when_the_form_certifies_nothing(monkeypatch):
    plant, are = _bench_targets(10)[1]
    res = kalman_for_poles(plant, are.poles)
    assert res.success and res.extra["engine"]["sdp"]["form"] == "n constraints"
    calls = []

    def fails(form, fam, **kw):
        calls.append(fam)
        return oo._failed("test: not certified")

    monkeypatch.setattr(engine, "solve_one_output", fails)
    again = kalman_for_poles(plant, are.poles)
    assert len(calls) == 1 and "form" not in again.extra["engine"]["sdp"]
    assert again.success and again.status == res.status == Status.OPTIMAL
    assert again.objective_value == pytest.approx(res.objective_value, rel=AGREE)
    np.testing.assert_array_equal(again.L, res.L)


def test_a_unique_gain_that_misses_the_cap_is_refined_for_its_poles(monkeypatch):
    """A gain off by 1e-5 (relative) misses its poles beyond the verification's cap: Newton steps on
    its poles (the same gain in exact arithmetic) bring it back, and the design is the exact one's."""
    plant, are = _bench_targets(10)[1]
    ref = kalman_for_poles(plant, are.poles)
    assert ref.success and not ref.extra["engine"]["gain_refined"]
    real = engine.single_output_gain
    monkeypatch.setattr(engine, "single_output_gain", lambda *a, **k: real(*a, **k) * (1 + 1e-5))
    res = kalman_for_poles(plant, are.poles)
    assert res.success and res.status == Status.OPTIMAL and res.extra["engine"]["gain_refined"]
    assert "refined for its poles" in res.message
    assert res.verification["pole_error"].value <= 1e-8
    np.testing.assert_allclose(res.L, ref.L, rtol=1e-8)
    assert res.objective_value == pytest.approx(ref.objective_value, rel=1e-7)


def test_the_form_certifies_targets_the_direct_form_does_not(general_one_output_route):
    """The benchmark's computable n = 20 target: the direct form's data are scaled by ||L R L'||,
    about 1e5 times the optimal Q -- Clarabel stops AlmostSolved there and the general route needs
    its polish; the normalized n-constraint form is solved and certified at once."""
    plant, are = _bench_targets(20)[0]
    setup = engine.prepare_inverse_kalman(plant, verify=False)
    L = single_output_gain(plant.A, plant.C, as_poles("p", are.poles), None)
    fam = fixed_gain_family(setup.family, L, plant.R)
    assert np.trace(fam.Q0) > 1e3 * (1e-300 + np.linalg.norm(setup.complement_form.W.T @ svec(fam.Q0)))
    sol = oo.solve_one_output(setup.complement_form, fam)
    assert sol.Q is not None and sol.native_status == "ipm: solved" and sol.kkt["passed"]
    general = engine.solve_inverse_kalman(setup, are.poles)   # the fixture: the form switched off
    assert general.status.is_solved
    assert general.objective_value == pytest.approx(np.trace(sol.Q), rel=AGREE)


# ------------------------------------------------------------------------------- the lean gain
def test_single_output_gain_is_the_spectral_gain_bit_for_bit():
    rng = np.random.default_rng(11)
    for n in (1, 2, 3, 6, 11):
        for dt in (None, 0.2):
            A = rng.standard_normal((n, n)) / np.sqrt(n)
            C = rng.standard_normal((1, n))
            z = np.concatenate([-rng.uniform(0.5, 2.0, n % 2), *[[complex(-a, w), complex(-a, -w)] for a, w in
                                                                   rng.uniform(0.3, 2.0, (n // 2, 2))]])
            if dt is not None:
                z = np.exp(z * dt)
            target = as_poles("poles", z, n)
            terms = spectral_terms(A, C, target, dt)
            L0 = spectral_blocks(terms, np.eye(1), np.eye(n)).gain(np.ones((len(terms), 1), dtype=complex))[0]
            L1 = single_output_gain(A, C, target, dt)
            np.testing.assert_array_equal(L1, L0)
            F = A - L1 @ C   # it places the targets, to the rounding floor of its poles
            assert pole_error(np.linalg.eigvals(F), target) <= max(1e-8, 10 * eigenvalue_rounding_floor(F))


def test_single_output_gain_where_the_resolvent_is_singular():
    A = np.array([[0.0, 1.0], [-2.0, -3.0]])   # eigenvalues -1, -2
    C = np.array([[1.0, 0.0]])
    assert single_output_gain(A, C, np.array([-1.0, -5.0]), None) is None       # at an eigenvalue of A
    assert single_output_gain(A, C, np.array([-5.0, 2.0]), None) is None        # mirror of -2
    assert single_output_gain(A, C, np.array([-4.0, -4.0]), None) is None       # repeated: no unique w
    assert single_output_gain(A, C, np.array([0.0, 0.5]), 0.1) is None          # discrete target 0
    assert single_output_gain(A, C, np.array([-4.0, -5.0]), None) is not None
    with pytest.raises(ValidationError, match=r"needs one output: C must be \(1, 2\); found \(2, 2\)"):
        single_output_gain(A, np.eye(2), np.array([-4.0, -5.0]), None)


def test_the_standard_form_ipm_rejects_bad_arguments():
    _, fam = _family(104, 4, None)
    form = oo.one_output_form(fam.T)
    b = form.W.T @ svec(fam.Q0)
    with pytest.raises(ValidationError, match="tol must be"):
        standard_form_ipm(form.basis, b, np.eye(4), tol=-1.0)
    with pytest.raises(ValidationError, match=r"max_iter must be an integer >= 1; found 0"):
        standard_form_ipm(form.basis, b, np.eye(4), max_iter=0)


# ------------------------------------------------------------------------- the per-plant state
def test_the_verb_and_a_held_problem_answer_alike():
    plant = Plant([[0.0, 1.0], [-6.0, -5.0]], [[1.0, 0.0]], R=[[1.0]])
    held = InverseKalmanProblem(plant)
    a, b = kalman_for_poles(plant, [-5, -8]), held.solve([-5, -8])
    assert a.success and b.success and a.objective_value == b.objective_value
    np.testing.assert_allclose(a.L.ravel(), [8.0, -6.0], rtol=1e-12)
    assert held.engine() is held.engine()   # built once, held (no hidden cache behind the verb)


def test_a_held_problem_still_pickles():
    """A held problem goes to the workers of a process pool: its setup (with the form) pickles."""
    plant = Plant([[0.0, 1.0], [-6.0, -5.0]], [[1.0, 0.0]], R=[[1.0]])
    held = InverseKalmanProblem(plant)
    first = held.solve([-5, -8])
    again = pickle.loads(pickle.dumps(held)).solve([-5, -8])
    assert first.success and again.success and again.objective_value == first.objective_value


def test_the_form_is_tried_for_one_output_full_min_trace_continuous_or_discrete():
    cplant = Plant([[0.0, 1.0], [-6.0, -5.0]], [[1.0, 0.0]], R=[[1.0]])
    dplant = Plant([[0.5, 0.2], [0.0, 0.3]], [[1.0, 0.0]], R=[[1.0]], dt=0.1)
    cont, disc = engine.prepare_inverse_kalman(cplant), engine.prepare_inverse_kalman(dplant)
    # discrete: the gain's form, per target
    assert cont.complement_form is not None and disc.complement_form is None
    assert cont.one_output_route and disc.one_output_route
    for other in (engine.prepare_inverse_kalman(cplant, objective="nearest"),
                  engine.prepare_inverse_kalman(cplant, q_structure="diagonal")):
        assert not other.one_output_route and other.complement_form is None
    several = engine.prepare_inverse_kalman(Plant(cplant.A, np.eye(2), R=np.eye(2)))
    assert not several.one_output_route and several.complement_form is not None   # the certificate form
    res = kalman_for_poles(cplant, [-5, -8], objective="nearest", Q_nominal=np.eye(2))
    assert res.success and "form" not in res.extra["engine"]["sdp"]
    res = kalman_for_poles(dplant, [0.2, 0.1])
    assert res.success and res.extra["engine"]["sdp"]["form"] == "n constraints"
    assert "Newton step" in res.verification["are_resolve_gain"].detail
