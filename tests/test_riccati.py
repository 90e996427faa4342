"""Riccati solvers: CAREX / DAREX cross-checks, analytic solutions, filter form, error paths.

Run with ``-s`` (or ``-rP``) to see the per-example table of relative differences between
the Hamiltonian/symplectic solvers and scipy.
"""

from __future__ import annotations

import functools

import numpy as np
import pytest
import scipy.linalg

from optdesign import Plant, problems
from optdesign.classical.riccati import filter_are_error
from optdesign.design.verification import FORWARD_ERROR_TOL
from optdesign.errors import (
    DimensionError,
    NotFiniteError,
    NotObservableError,
    NotPositiveDefiniteError,
    NotSymmetricError,
    RiccatiError,
    ValidationError,
)
from optdesign.riccati import (
    RESIDUAL_TOL,
    AREResult,
    filter_are,
    filter_are_residual,
    hamiltonian_are,
    symplectic_dare,
)

CARE = problems.names(kind="riccati_care")
DARE = problems.names(kind="riccati_dare")


def _rel(X, Y) -> float:
    return float(np.linalg.norm(X - Y) / max(np.linalg.norm(Y), 1e-300))


def _care_residual(A, B, Q, R, X) -> float:
    G = B @ np.linalg.solve(R, B.T)
    terms = [A.T @ X, X @ A, X @ G @ X, Q]
    return float(np.linalg.norm(Q + A.T @ X + X @ A - X @ G @ X) / sum(np.linalg.norm(t) for t in terms))


def _dare_residual(A, B, Q, R, X) -> float:
    K = A.T @ X @ B
    corr = K @ np.linalg.solve(R + B.T @ X @ B, K.T)
    terms = [A.T @ X @ A, X, corr, Q]
    return float(np.linalg.norm(A.T @ X @ A - X - corr + Q) / sum(np.linalg.norm(t) for t in terms))


def test_benchmark_libraries_present():
    assert len(CARE) == 20, CARE
    assert len(DARE) == 19, DARE


# ============================================================ tolerances from the data
# Every comparison below is judged by the a posteriori forward-error estimate of each solution
# (filter_are_error: the Newton correction of its residual through the Lyapunov operator of
# the closed loop, plus the rounding floor ||Omega^-1|| n eps).  Two solutions must agree to
# ESTIMATE_FACTOR times the sum of their estimates; a solution and a reference likewise (the
# reference's own estimate included: tabulated references are computed numbers too).  So a
# solver that loses digits on a badly scaled problem (scipy on CAREX 2.6 and DAREX 2.4: by an
# amount that depends on the CPU's rounding) shows it in its own residual -- nothing here is a
# number measured on one machine.
ESTIMATE_FACTOR = 4.0
EPS = np.finfo(float).eps


def _estimate(A, B, Q, R, X, discrete):
    """Relative forward-error estimate of a control-form ARE solution X (via its dual filter form:
    A_f = A', C_f = B', W = Q, whose filter-ARE solution is X)."""
    plant = Plant(A.T, B.T, R=R, dt=1.0 if discrete else None)
    return filter_are_error(plant, X, Qs=0.5 * (Q + Q.T)).relative


def _agree(X, Y, est_x, est_y):
    """``rel(X, Y) <= ESTIMATE_FACTOR (est_x + est_y) + 10 n eps``: the two agree to what their
    error estimates explain."""
    return _rel(X, Y) <= ESTIMATE_FACTOR * (est_x + est_y) + 10 * X.shape[0] * EPS


# ================================================================================ CAREX
# Documented behaviours (not tolerances): where hamiltonian_are must refuse, and why.
CAREX_EXPECT: dict[str, dict] = {
    # Hamiltonian eigenvalues +-eps +-1j with eps = 0: ON the imaginary axis, X = [[2,1],[1,1]]
    # solves the CARE but is not stabilizing.  hamiltonian_are refuses; scipy silently returns
    # that non-stabilizing X (checked below).
    "carex_2.5": dict(fails="eigenvalue.* on the imaginary axis"),
    # closed-loop poles -5e-13 +- 1j (eps^2/2 from the axis, eps = 1e-6): the stable invariant
    # subspace is ill-conditioned (its stable and unstable eigenvalues are 1e-12 apart).
    # hamiltonian_are detects it (non-Lagrangian subspace); scipy returns an X with residual
    # 3e-16 but relative error 4.7e-4 (measured against a 60-digit mpmath solution) -- which its
    # forward-error estimate covers (test_kalman.py::test_cross_check_flags_carex_2_8).
    "carex_2.8": dict(fails="not Lagrangian"),
}


def _carex(name):
    prob = problems.load(name)
    d = prob.data
    return prob, d["A"], d["B"], d["Q"], d["R"]


@functools.cache
def _carex_X(name):
    """(X from hamiltonian_are or None if it fails, X from scipy) of a CAREX example."""
    _, A, B, Q, R = _carex(name)
    try:
        X_h = hamiltonian_are(A, B, Q, R)
    except RiccatiError:
        X_h = None
    return X_h, scipy.linalg.solve_continuous_are(A, B, Q, R)


@pytest.mark.parametrize("name", CARE)
def test_carex_hamiltonian_vs_scipy(name):
    prob, A, B, Q, R = _carex(name)
    exp = CAREX_EXPECT.get(name, {})
    if "fails" in exp:
        with pytest.raises(RiccatiError, match=exp["fails"]):
            hamiltonian_are(A, B, Q, R)
        print(f"\n{name:>14}  n={A.shape[0]:>2}  hamiltonian_are: RiccatiError (expected: {exp['fails']})")
        return
    X_h, X_s = _carex_X(name)
    est_h, est_s = _estimate(A, B, Q, R, X_h, False), _estimate(A, B, Q, R, X_s, False)
    ref = prob.references.get("X", prob.references.get("X_ref_numeric"))
    line = (f"\n{name:>14}  n={A.shape[0]:>2}  |Xh-Xs|/|Xs|={_rel(X_h, X_s):.1e}  est_h={est_h:.1e}  "
            f"est_s={est_s:.1e}  res_h={_care_residual(A, B, Q, R, X_h):.1e}")
    assert np.allclose(X_h, X_h.T, rtol=0, atol=0)
    assert _agree(X_h, X_s, est_h, est_s)
    assert est_h <= FORWARD_ERROR_TOL  # ours is accurate to 6 digits at least, by its own residual
    if ref is not None:
        ref = np.asarray(ref, dtype=float)
        est_r = _estimate(A, B, Q, R, ref, False)
        line += f"  err_h={_rel(X_h, ref):.1e}  err_s={_rel(X_s, ref):.1e}  est_ref={est_r:.1e}"
        assert _agree(X_h, ref, est_h, est_r)
        assert _agree(X_s, ref, est_s, est_r)
    print(line)
    # stabilizing: eig(A - B R^-1 B' X) in the open left half plane
    G = B @ np.linalg.solve(R, B.T)
    assert np.max(np.linalg.eigvals(A - G @ X_h).real) < 0


def test_carex_2_6_scipy_loses_digits_that_its_residual_shows():
    """CAREX 2.6 (||Q|| ~ 1e6, ||B R^-1 B'|| ~ 1e-6): scipy is 5e-4 .. 2e-3 off the analytic X,
    by an amount that depends on the CPU's rounding, and its residual says so (its forward-error
    estimate is at least 1e-5); the balanced Hamiltonian solver is at rounding level."""
    prob, A, B, Q, R = _carex("carex_2.6")
    X_h, X_s = _carex_X("carex_2.6")
    X = prob.references["X"]
    assert _rel(X_s, X) > 1e-5 and _estimate(A, B, Q, R, X_s, False) > 1e-5
    assert _rel(X_h, X) < 1e-12 and _estimate(A, B, Q, R, X_h, False) < 1e-12


def test_carex_2_5_scipy_returns_non_stabilizing_solution():
    """Why hamiltonian_are must refuse CAREX 2.5: the CARE solution exists but A - G X has
    eigenvalues +-1j (to rounding); scipy returns it without complaint."""
    prob, A, B, Q, R = _carex("carex_2.5")
    assert prob.references["X_is_stabilizing"] is False
    X_s = scipy.linalg.solve_continuous_are(A, B, Q, R)
    assert _rel(X_s, prob.references["X"]) < 1e-6
    poles = np.linalg.eigvals(A - B @ np.linalg.solve(R, B.T) @ X_s)
    np.testing.assert_allclose(np.abs(poles.imag), 1.0, atol=1e-6)
    assert np.max(np.abs(poles.real)) < 1e-6


def test_carex_4_1_known_corner_entry():
    """Laub 1979 Ex. 6: only X[0, n-1] = X[n-1, 0] = sqrt(q r) is known analytically."""
    prob, A, B, Q, R = _carex("carex_4.1_n5")
    X = hamiltonian_are(A, B, Q, R)
    est = _estimate(A, B, Q, R, X, False)
    ref = prob.references["X_first_last"]
    assert abs(X[0, -1] - ref) <= ESTIMATE_FACTOR * est * np.linalg.norm(X) + 10 * EPS * abs(ref)
    assert X[-1, 0] == X[0, -1]


@pytest.mark.parametrize("name", [n for n in CARE if problems.load(n).plant is not None])
@pytest.mark.parametrize("method", ["scipy", "hamiltonian"])
def test_carex_filter_form(name, method):
    """The dual filter plant's ARE solution P equals the control-form X; L = X B R^-1."""
    prob, A, B, Q, R = _carex(name)
    plant = prob.plant
    exp = CAREX_EXPECT.get(name, {})
    if method == "hamiltonian" and "fails" in exp:
        with pytest.raises(RiccatiError, match=exp["fails"]):
            filter_are(plant, method)
        return
    res = filter_are(plant, method, residual_tol=np.inf)
    if res.residual > RESIDUAL_TOL:  # filter_are refuses what its residual test rejects (CAREX 2.6, scipy)
        with pytest.raises(RiccatiError, match=r"relative residual .* exceeds 1e-08"):
            filter_are(plant, method)
        assert filter_are_error(plant, res.P).relative > RESIDUAL_TOL
        return
    X_h, X_s = _carex_X(name)
    X = X_s if X_h is None else X_h
    est = filter_are_error(plant, res.P).relative
    est_x = _estimate(A, B, Q, R, X, False)
    assert _agree(res.P, X, est, est_x)
    Lx = X @ B @ np.linalg.inv(R)
    # the gain is linear in P: it inherits P's relative error, amplified by R^-1's conditioning
    cond = np.linalg.cond(R)
    assert _rel(res.L, Lx) <= ESTIMATE_FACTOR * (est + est_x) * cond + 10 * EPS * cond
    assert res.Kf is None and res.method == method
    assert np.max(res.poles.real) < 0
    np.testing.assert_allclose(np.sort_complex(res.poles),
                               np.sort_complex(np.linalg.eigvals(plant.A - res.L @ plant.C)), rtol=1e-8)


# ================================================================================ DAREX
# symplectic_dare vs scipy.linalg.solve_discrete_are on the control-form data, judged by the
# error estimates.  S != 0 with R PD is removed first (A - B R^-1 S', Q - S R^-1 S': same X).
# Documented behaviours:
DAREX_EXPECT: dict[str, dict] = {
    # R singular (R = 0 / rank 1): the symplectic pencil needs R^-1; only an extended-pencil
    # solver (scipy) applies.  symplectic_dare rejects R as not positive definite.
    "darex_1.1": dict(fails="r must be positive definite"),
    "darex_1.2": dict(fails="r must be positive definite"),
    "darex_1.4": dict(fails="r must be positive definite"),
}


def _darex(name):
    prob = problems.load(name)
    d = prob.data
    A, B, Q, R, S = d["A"], d["B"], d["Q"], d["R"], d["S"]
    return prob, A, B, Q, R, S


@pytest.mark.parametrize("name", DARE)
def test_darex_symplectic_vs_scipy(name):
    prob, A, B, Q, R, S = _darex(name)
    exp = DAREX_EXPECT.get(name, {})
    if "fails" in exp:
        with pytest.raises(NotPositiveDefiniteError, match=exp["fails"]):
            symplectic_dare(A, B, Q, R)
        if np.any(S):
            print(f"\n{name:>14}  symplectic_dare: rejected (singular R, S != 0)")
            return
        X_s = scipy.linalg.solve_discrete_are(A, B, Q, R)
        ref = prob.references["X"]
        print(f"\n{name:>14}  symplectic_dare: rejected (singular R); scipy err={_rel(X_s, ref):.1e}")
        # DARE X corrected for 1.4 (published X33 = 0 is wrong); with R singular no error
        # estimate applies (R^-1 does not exist), so the exact reference is compared at rounding level
        assert _rel(X_s, ref) < 1e3 * A.shape[0] * EPS
        return
    if np.any(S):
        RiS = np.linalg.solve(R, S.T)
        A, Q = A - B @ RiS, Q - S @ RiS
    X_h = symplectic_dare(A, B, Q, R)
    X_s = scipy.linalg.solve_discrete_are(A, B, Q, R)
    est_h, est_s = _estimate(A, B, Q, R, X_h, True), _estimate(A, B, Q, R, X_s, True)
    ref = prob.references.get("X")
    line = (f"\n{name:>14}  n={A.shape[0]:>2}  |Xh-Xs|/|Xs|={_rel(X_h, X_s):.1e}  est_h={est_h:.1e}  "
            f"est_s={est_s:.1e}  res_h={_dare_residual(A, B, Q, R, X_h):.1e}")
    assert _agree(X_h, X_s, est_h, est_s)
    assert est_h <= FORWARD_ERROR_TOL
    if ref is not None:
        ref = np.asarray(ref, dtype=float)
        est_r = _estimate(A, B, Q, R, ref, True)
        line += f"  err_h={_rel(X_h, ref):.1e}  err_s={_rel(X_s, ref):.1e}  est_ref={est_r:.1e}"
        assert _agree(X_h, ref, est_h, est_r)
        assert _agree(X_s, ref, est_s, est_r)
    print(line)
    K = np.linalg.solve(R + B.T @ X_h @ B, B.T @ X_h @ A)
    assert np.max(np.abs(np.linalg.eigvals(A - B @ K))) < 1


@pytest.mark.parametrize("name", [n for n in DARE if problems.load(n).plant is not None])
def test_darex_filter_form(name):
    """Predictor DARE of the dual filter plant: P = X, and L = A_f P C_f'(C_f P C_f' + R)^-1."""
    prob = problems.load(name)
    plant = prob.plant
    assert plant.is_discrete
    P_s = filter_are(plant, "scipy")
    P_h = filter_are(plant, "hamiltonian")
    est_s, est_h = filter_are_error(plant, P_s.P).relative, filter_are_error(plant, P_h.P).relative
    assert _agree(P_h.P, P_s.P, est_h, est_s)
    if "X" in prob.references:
        X = np.asarray(prob.references["X"], dtype=float)
        assert _agree(P_h.P, X, est_h, filter_are_error(plant, X).relative)
    for res in (P_s, P_h):
        A, C = plant.A, plant.C
        S = C @ res.P @ C.T + plant.R
        # L and Kf are evaluated from P by the formulas: to rounding of the formula (cond S)
        tol = 10 * plant.n * EPS * np.linalg.cond(S)
        np.testing.assert_allclose(res.L, A @ res.P @ C.T @ np.linalg.inv(S), rtol=tol,
                                   atol=tol * np.linalg.norm(res.L))
        np.testing.assert_allclose(res.Kf, res.P @ C.T @ np.linalg.inv(S), rtol=tol,
                                   atol=tol * np.linalg.norm(res.Kf))
        assert np.max(np.abs(res.poles)) < 1
        assert res.residual <= RESIDUAL_TOL


# ====================================================================== analytic, random
def test_scalar_care_closed_form(rng):
    for _ in range(20):
        a, b, q, r = rng.standard_normal(), rng.uniform(0.1, 3), rng.uniform(0.01, 10), rng.uniform(0.1, 5)
        X = hamiltonian_are([[a]], [[b]], [[q]], [[r]])
        assert X[0, 0] == pytest.approx((a + np.sqrt(a * a + b * b * q / r)) * r / (b * b), rel=1e-12)


def test_scalar_dare_closed_form(rng):
    """x = a^2 x - a^2 b^2 x^2 / (r + b^2 x) + q  ->  b^2 x^2 + (r - a^2 r - q b^2) x - q r = 0."""
    for _ in range(20):
        a, b = 2 * rng.standard_normal(), rng.uniform(0.1, 3)
        q, r = rng.uniform(0.01, 10), rng.uniform(0.1, 5)
        X = symplectic_dare([[a]], [[b]], [[q]], [[r]])
        p1 = r - a * a * r - q * b * b
        x = (-p1 + np.sqrt(p1 * p1 + 4 * b * b * q * r)) / (2 * b * b)
        assert X[0, 0] == pytest.approx(x, rel=1e-11)


@pytest.mark.parametrize("n,m", [(2, 1), (4, 2), (7, 3)])
def test_random_care_dare_agree_with_scipy(n, m, rng):
    for _ in range(8):
        A = rng.standard_normal((n, n))
        B = rng.standard_normal((n, m))
        Cq = rng.standard_normal((n, n))
        Q = Cq.T @ Cq
        F = rng.standard_normal((m, m))
        R = F @ F.T + 0.1 * np.eye(m)
        X = hamiltonian_are(A, B, Q, R)
        assert _rel(X, scipy.linalg.solve_continuous_are(A, B, Q, R)) < 1e-9
        assert _care_residual(A, B, Q, R, X) < 1e-12
        Ad = A / (0.8 * max(1.0, np.max(np.abs(np.linalg.eigvals(A)))))  # mildly unstable at most
        Xd = symplectic_dare(Ad, B, Q, R)
        assert _rel(Xd, scipy.linalg.solve_discrete_are(Ad, B, Q, R)) < 1e-9
        assert _dare_residual(Ad, B, Q, R, Xd) < 1e-12
        assert np.all(np.linalg.eigvalsh(X) > -1e-10) and np.all(np.linalg.eigvalsh(Xd) > -1e-10)


def test_balancing_matters_on_badly_scaled_problem():
    """CAREX 2.6 without the structure-preserving scaling loses 4 digits; with it, none."""
    prob, A, B, Q, R = _carex("carex_2.6")
    assert _rel(hamiltonian_are(A, B, Q, R), prob.references["X"]) < 1e-12
    assert _rel(hamiltonian_are(A, B, Q, R, balance=False), prob.references["X"]) > 1e-6


# ============================================================================ error paths
class TestHamiltonianErrors:
    def test_eigenvalues_on_axis(self):
        a = [[0.0, 1.0], [-1.0, 0.0]]  # undamped oscillator, neither driven nor weighted
        with pytest.raises(RiccatiError, match=r"eigenvalue\(s\) on the imaginary axis \(closest: .*1j"):
            hamiltonian_are(a, [[0.0], [0.0]], np.zeros((2, 2)), [[1.0]])

    def test_wrong_count_of_stable_eigenvalues(self):
        # tol = 0 disables the on-axis test: the Schur ordering then finds 0 stable eigenvalues
        with pytest.raises(RiccatiError, match="expected n = 2 stable Hamiltonian eigenvalues, found 0"):
            hamiltonian_are([[0.0, 1.0], [-1.0, 0.0]], [[0.0], [0.0]], np.zeros((2, 2)), [[1.0]], tol=0.0)

    def test_singular_U11(self):
        # (a, b) = (1, 0) is not stabilizable: the stable eigenvector of H is [0; 1]
        with pytest.raises(RiccatiError, match=r"U11 block .* singular or ill-conditioned \(cond\(U11\) ="):
            hamiltonian_are([[1.0]], [[0.0]], [[1.0]], [[1.0]])

    def test_not_lagrangian_near_axis(self):
        """CAREX 2.8 built inline: closed-loop poles 5e-13 from the axis."""
        e = 1e-6
        A = scipy.linalg.block_diag([[-e, 1.0], [-1.0, -e]], [[e, 1.0], [-1.0, e]])
        with pytest.raises(RiccatiError, match="not Lagrangian .* too close to the imaginary axis"):
            hamiltonian_are(A, np.ones((4, 1)), np.ones((4, 4)), [[1.0]])

    @pytest.mark.parametrize("solver", [hamiltonian_are, symplectic_dare])
    def test_bad_shapes_and_values(self, solver):
        a, b, q, r = np.eye(2), np.ones((2, 1)), np.eye(2), np.eye(1)
        with pytest.raises(DimensionError, match=r"a must be square; found shape \(2, 3\)"):
            solver(np.ones((2, 3)), b, q, r)
        with pytest.raises(DimensionError, match=r"b has the wrong shape: expected \(2, \?\), found"):
            solver(a, np.ones((3, 1)), q, r)
        with pytest.raises(DimensionError, match=r"q has the wrong shape: expected \(2, 2\), found \(3, 3\)"):
            solver(a, b, np.eye(3), r)
        with pytest.raises(DimensionError, match=r"r has the wrong shape: expected \(1, 1\), found \(2, 2\)"):
            solver(a, b, q, np.eye(2))
        with pytest.raises(NotSymmetricError, match="q must be symmetric"):
            solver(a, b, [[1.0, 1.0], [0.0, 1.0]], r)
        with pytest.raises(NotPositiveDefiniteError, match="r must be positive definite; found smallest eig"):
            solver(a, b, q, [[-1.0]])
        with pytest.raises(NotFiniteError, match="a must be finite"):
            solver([[np.nan, 0.0], [0.0, 1.0]], b, q, r)
        with pytest.raises(DimensionError, match="b must have at least one column"):
            solver(a, np.ones((2, 0)), q, r)


class TestSymplecticErrors:
    def test_eigenvalues_on_unit_circle(self):
        with pytest.raises(RiccatiError, match=r"eigenvalue\(s\) on the unit circle"):
            symplectic_dare([[0.0, 1.0], [-1.0, 0.0]], [[0.0], [0.0]], np.zeros((2, 2)), [[1.0]])

    def test_wrong_count_inside(self):
        msg = "expected n = 2 pencil eigenvalues inside the unit circle, found 0"
        with pytest.raises(RiccatiError, match=msg):
            symplectic_dare([[0.0, 1.0], [-1.0, 0.0]], [[0.0], [0.0]], np.zeros((2, 2)), [[1.0]], tol=0.0)

    def test_singular_Z11(self):
        with pytest.raises(RiccatiError, match=r"U11 block .* singular or ill-conditioned"):
            symplectic_dare([[2.0]], [[0.0]], [[1.0]], [[1.0]])

    def test_singular_a_is_fine(self):
        """Infinite pencil eigenvalues (singular a) are handled: deadbeat-like plant."""
        a = np.array([[0.0, 1.0], [0.0, 0.0]])
        X = symplectic_dare(a, [[0.0], [1.0]], np.eye(2), [[1.0]])
        assert _rel(X, scipy.linalg.solve_discrete_are(a, [[0.0], [1.0]], np.eye(2), [[1.0]])) < 1e-12


# ---------------------------------------------------------------------- filter_are errors
def _plant(**kw):
    base = dict(A=[[0.0, 1.0], [-2.0, -3.0]], C=[[1.0, 0.0]], Q=np.eye(2), R=[[1.0]])
    base.update(kw)
    return Plant(**base)


class TestFilterAreErrors:
    def test_missing_noise_model(self):
        with pytest.raises(ValidationError, match="has no Q and no R"):
            filter_are(Plant([[0.0]], [[1.0]]))
        with pytest.raises(ValidationError, match="has no R"):
            filter_are(Plant([[0.0]], [[1.0]], Q=[[1.0]]))

    def test_bad_method(self):
        with pytest.raises(ValidationError, match="method must be 'scipy' or 'hamiltonian'; found 'qz'"):
            filter_are(_plant(), "qz")

    @pytest.mark.parametrize("dt", [None, 0.1])
    def test_undetectable_names_modes(self, dt):
        A = [[1.5, 0.0], [0.0, 0.5]] if dt else [[1.0, 0.0], [0.0, -1.0]]
        plant = Plant(A, [[0.0, 1.0]], Q=np.eye(2), R=[[1.0]], dt=dt, name="twomodes")
        match = r"of plant 'twomodes' is undetectable.*mode\(s\) 1"
        with pytest.raises(NotObservableError, match=match) as ei:
            filter_are(plant)
        assert ei.value.modes.real == pytest.approx([1.5 if dt else 1.0])

    def test_unobservable_but_stable_is_fine(self):
        res = filter_are(Plant([[-1.0, 0.0], [0.0, 2.0]], [[0.0, 1.0]], Q=np.eye(2), R=[[1.0]]))
        assert res.P[0, 0] == pytest.approx(0.5)  # the unobserved stable mode: 2 P00 (-1) + 1 = 0
        assert res.P[1, 1] == pytest.approx(2 + np.sqrt(5))

    def test_undriven_mode_on_imaginary_axis(self):
        plant = _plant(A=[[0.0, 1.0], [-1.0, 0.0]], G=[[0.0], [0.0]], Q=[[1.0]], name="osc")
        match = r"plant 'osc': mode\(s\) 0\+1j, 0-1j on the imaginary axis are not excited"
        with pytest.raises(RiccatiError, match=match):
            filter_are(plant)
        # a hidden (rotated) double integrator driven only in its position: mode 0 not excited
        Qm = np.array([[0.6, -0.8], [0.8, 0.6]])
        plant = Plant(Qm @ [[0.0, 1.0], [0.0, 0.0]] @ Qm.T, np.array([[1.0, 0.0]]) @ Qm.T,
                      G=Qm @ [[1.0], [0.0]], Q=[[1.0]], R=[[1.0]])
        with pytest.raises(RiccatiError, match=r"mode\(s\) 0 on the imaginary axis are not excited"):
            filter_are(plant, "hamiltonian")

    def test_undriven_mode_on_unit_circle(self):
        plant = Plant([[1.0]], [[1.0]], Q=[[0.0]], R=[[1.0]], dt=1.0)
        with pytest.raises(RiccatiError, match=r"mode\(s\) 1 on the unit circle are not excited"):
            filter_are(plant)

    def test_residual_too_large(self):
        with pytest.raises(RiccatiError, match=r"relative residual .* exceeds 0; the solution is not"):
            filter_are(_plant(), residual_tol=0.0)

    def test_scipy_failure_is_wrapped(self, monkeypatch):
        def boom(*args, **kw):
            raise np.linalg.LinAlgError("Failed to find a finite solution.")

        monkeypatch.setattr(scipy.linalg, "solve_continuous_are", boom)
        with pytest.raises(RiccatiError, match=r"filter_are \(scipy\): the solver failed: Failed to find"):
            filter_are(_plant())

    def test_non_stabilizing_solution_rejected(self, monkeypatch):
        """Scalar 2P - P^2 + 1 = 0 has P = 1 +- sqrt2; the minus root solves it but A - LC = sqrt2."""
        minus_root = np.array([[1 - np.sqrt(2)]])
        monkeypatch.setattr(scipy.linalg, "solve_continuous_are", lambda *a, **k: minus_root)
        with pytest.raises(RiccatiError, match=r"not stable \(max Re eig\(A - L C\) = 1\.41421"):
            filter_are(Plant([[1.0]], [[1.0]], Q=[[1.0]], R=[[1.0]]))
        monkeypatch.setattr(scipy.linalg, "solve_discrete_are", lambda *a, **k: np.array([[-0.5]]))
        with pytest.raises(RiccatiError, match=r"not stable \(spectral radius"):
            filter_are(Plant([[2.0]], [[1.0]], Q=[[1.0]], R=[[1.0]], dt=1.0), residual_tol=np.inf)


# ------------------------------------------------------------------- filter_are_residual
def test_filter_are_residual_variants(rng):
    from conftest import random_observable_plant

    for dt in (None, 0.5):
        plant = random_observable_plant(rng, 3, 1, dt=dt)
        G = rng.standard_normal((3, 2))
        plant = plant.replace(G=G, Q=np.diag([1.0, 2.0]))
        res = filter_are(plant)
        W = G @ np.diag([1.0, 2.0]) @ G.T
        r0 = filter_are_residual(plant, res.P)
        assert r0 < 1e-13
        assert filter_are_residual(plant, res.P, Q=np.diag([1.0, 2.0])) == r0
        assert filter_are_residual(plant, res.P, Qs=W) == pytest.approx(r0, abs=1e-15)
        # a different Q: P is no longer a solution.  Residual = ||I||_F / (sum of term norms)
        A, C, P, R = plant.A, plant.C, res.P, plant.R
        if dt is None:
            terms = [A @ P, P @ A.T, P @ C.T @ np.linalg.solve(R, C @ P), W + np.eye(3)]
        else:
            K = A @ P @ C.T
            terms = [A @ P @ A.T, K @ np.linalg.solve(C @ P @ C.T + R, K.T), W + np.eye(3), P]
        den = sum(np.linalg.norm(t) for t in terms)
        assert filter_are_residual(plant, P, Qs=W + np.eye(3)) == pytest.approx(np.sqrt(3) / den, rel=1e-8)
        assert 0 <= filter_are_residual(plant, 10 * res.P) <= 1
    zero = Plant([[-1.0]], [[1.0]], Q=[[0.0]], R=[[1.0]])
    assert filter_are_residual(zero, [[0.0]]) == 0.0


def test_filter_are_residual_errors():
    plant = _plant()
    with pytest.raises(ValidationError, match="at most one of Q .* and Qs"):
        filter_are_residual(plant, np.eye(2), Q=np.eye(2), Qs=np.eye(2))
    with pytest.raises(DimensionError, match=r"P has the wrong shape: expected \(2, 2\), found \(3, 3\)"):
        filter_are_residual(plant, np.eye(3))
    with pytest.raises(DimensionError, match=r"Qs has the wrong shape: expected \(2, 2\)"):
        filter_are_residual(plant, np.eye(2), Qs=np.eye(3))
    with pytest.raises(NotSymmetricError, match="Q must be symmetric"):
        filter_are_residual(plant, np.eye(2), Q=[[1.0, 1.0], [0.0, 1.0]])
    with pytest.raises(ValidationError, match="has no R"):
        filter_are_residual(Plant([[0.0]], [[1.0]], Q=[[1.0]]), [[1.0]])
    with pytest.raises(ValidationError, match="has no Q"):
        filter_are_residual(Plant([[0.0]], [[1.0]], R=[[1.0]]), [[1.0]])
    # given a Q, a plant without one is fine
    assert filter_are_residual(Plant([[0.0]], [[1.0]], R=[[1.0]]), [[1.0]], Q=[[1.0]]) == 0.0


def test_are_result_is_frozen():
    res = filter_are(_plant())
    assert isinstance(res, AREResult)
    with pytest.raises(AttributeError):
        res.P = None
    assert "continuous" in repr(res) and "residual" in repr(res)
    assert res.residual < RESIDUAL_TOL
