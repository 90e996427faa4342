"""State feedback by duality (issue 16, item 3): place (scipy's place_poles drop-in),
well_conditioned_feedback and the inverse LQR, against scipy, python-control and the duals."""

from __future__ import annotations

import control
import numpy as np
import pytest
import scipy.linalg
import scipy.signal

from optdesign import Plant, kalman_for_poles, problems, well_conditioned_observer
from optdesign.analysis import metrics
from optdesign.design.feedback import dual_plant, lqr_for_poles, place, well_conditioned_feedback
from optdesign.errors import DimensionError, NotControllableError, ValidationError
from optdesign.regions import Disk, HalfPlane, Sector
from optdesign.results import Status

EPS = np.finfo(float).eps
PLACEMENT = ["pp_knv1985_ex1", "pp_byers3", "pp_scipy_test_complex_car"]


def _AB(name):
    prob = problems.load(name)
    return np.array(prob.data["A"]), np.array(prob.data["B"]), prob.targets["poles"], prob.plant


# ------------------------------------------------------------------ place: scipy's drop-in
@pytest.mark.parametrize("name", PLACEMENT)
def test_place_minimizes_cond_X_and_is_a_place_poles_drop_in(name):
    """Issue 27, item 3: place minimizes cond(X) of the unit-column RIGHT eigenvectors of A - B K
    (scipy's X), never worse than scipy's YT and KNV0 on that measure."""
    A, B, poles, _ = _AB(name)
    res = place(A, B, poles, starts=2)
    ref = scipy.signal.place_poles(A, B, poles)
    assert res.success, res.design.verification.summary()
    assert res.design.observer is None and res.route.answered.kind == "engine"
    # scipy's fields, shapes and conventions
    assert res.gain_matrix.shape == ref.gain_matrix.shape
    np.testing.assert_allclose(res.requested_poles, ref.requested_poles, rtol=1e-12)
    np.testing.assert_allclose(res.computed_poles, ref.computed_poles, rtol=1e-6)
    F = A - B @ res.gain_matrix
    resid = np.linalg.norm(F @ res.X - res.X * res.computed_poles[None, :]) / np.linalg.norm(F)
    assert resid < 100 * A.shape[0] * EPS
    np.testing.assert_allclose(np.linalg.norm(res.X, axis=0), 1.0, rtol=1e-14)
    assert res.kappa2 == pytest.approx(np.linalg.cond(res.X), rel=1e-12)
    assert res.kappa2 == pytest.approx(metrics.kappa2(F), rel=1e-6)
    assert res.rtol == res.verification["feedback_pole_error"].value <= 1e-6
    assert isinstance(res.nb_iter, int) and res.nb_iter > 0
    # the measure minimized is scipy's: never worse than YT's cond(X) (YT is one of the starts)
    assert res.kappa2 <= np.linalg.cond(ref.X) * (1 + 1e-6)
    # the dual's (left) measure is reported beside it, within sqrt(n) of it (van der Sluis)
    root_n = np.sqrt(A.shape[0]) * (1 + 1e-9)
    assert res.kappa2 <= root_n * res.kappa2_dual and res.kappa2_dual <= root_n * res.kappa2


def test_place_against_python_control():
    pytest.importorskip("slycot", reason="python-control's place_varga needs slycot (the test extra has it)")
    A, B, poles, _ = _AB("pp_knv1985_ex1")
    res = place(A, B, poles, starts=2)
    for K in (control.place(A, B, poles), control.place_varga(A, B, poles)):
        np.testing.assert_allclose(np.sort(np.linalg.eigvals(A - B @ K).real), np.sort(poles), rtol=1e-6)
        assert res.kappa2 <= metrics.kappa2(A - B @ K) * (1 + 1e-6)


def test_place_single_input_and_unstable_poles():
    """One input: K is fixed by the poles (Ackermann); unstable requested poles are placed (the
    verification checks the poles, not stability), as scipy does."""
    A = np.array([[0.0, 1.0], [2.0, -1.0]])
    B = np.array([[0.0], [1.0]])
    res = place(A, B, [1.0, -3.0], starts=1)
    assert res.success
    np.testing.assert_allclose(res.gain_matrix, scipy.signal.place_poles(A, B, [1.0, -3.0]).gain_matrix,
                               rtol=1e-10)
    assert "feedback_stability_margin" not in res.verification
    # discrete: |z| < 1 is stability
    resd = place(A * 0.3, B, [0.5, 0.2], dt=0.1, starts=1)
    assert resd.success and "feedback_stability_margin" in resd.verification


def test_place_errors():
    A = np.array([[0.0, 1.0], [2.0, -1.0]])
    B = np.array([[0.0], [1.0]])
    with pytest.raises(ValidationError, match="method must be one of 'optdesign', 'YT', 'KNV0'; found 'LS'"):
        place(A, B, [-1, -2], method="LS")
    with pytest.raises(ValidationError, match=r"rtol must be finite and <= 1 .*found 42"):
        place(A, B, [-1, -2], rtol=42)
    with pytest.raises(ValidationError, match="maxiter must be an integer >= 1; found 0"):
        place(A, B, [-1, -2], maxiter=0)
    with pytest.raises(DimensionError, match=r"B has the wrong shape: expected \(2, \?\), found \(3, 1\)"):
        place(A, np.ones((3, 1)), [-1, -2])
    with pytest.raises(DimensionError, match="poles has the wrong length: expected 2, found 3"):
        place(A, B, [-1, -2, -3])
    with pytest.raises(NotControllableError, match=r"\(A, B\) is not controllable.*uncontrollable mode\(s\) -1"
                       ):
        place(np.diag([-1.0, -2.0]), np.array([[0.0], [1.0]]), [-3, -4])
    with pytest.raises(ValidationError, match="objective must be one of"):
        place(A, B, [-1, -2], objective="trace")


# ------------------------------------------------------------------ well_conditioned_feedback
def test_region_structure_and_gain_bound_are_transposed():
    A = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, -2.0, 0.5]])     # unstable, two inputs
    B = np.array([[0.0, 1.0], [1.0, 0.0], [0.0, 1.0]])
    plant = Plant(A, np.eye(3), B=B)
    m, n = B.shape[1], A.shape[0]
    mask = np.ones((m, n), dtype=bool)
    mask[0, 1] = False                                      # K[0, 1] is a structural zero
    region = HalfPlane(0.5) & Sector.from_damping(0.5) & Disk(0.0, 8.0)
    d = well_conditioned_feedback(plant, region=region, structure=mask, max_gain=10.0, starts=2)
    assert d.success, d.verification.summary()
    assert d.K.shape == (m, n) and d.K[0, 1] == 0.0
    assert np.linalg.norm(d.K, 2) <= 10.0 * (1 + 1e-6)
    assert region.margin(np.linalg.eigvals(A - B @ d.K)) <= d.verification["feedback_region_margin"].tolerance
    assert d.verification["feedback_region_margin"].passed
    obs = well_conditioned_observer(dual_plant(A, B), region=region, gain_mask=mask.T, max_gain=10.0,
                                    starts=2)
    np.testing.assert_array_equal(d.K, obs.L.T)
    assert d.kappa2 == obs.kappa2 and d.kappa2_right == pytest.approx(metrics.kappa2(A - B @ d.K), rel=1e-12)


def test_feedback_accepts_systems_and_discrete_plants():
    A = np.array([[1.1, 0.2], [0.0, 0.9]])
    B = np.array([[0.0, 1.0], [1.0, 0.0]])
    sys_ = control.ss(A, B, np.eye(2), 0, 0.1)
    d = well_conditioned_feedback(sys_, region=Disk.unit(0.5), starts=2)
    assert d.success and np.max(np.abs(d.poles)) <= 0.5 + 1e-8
    assert d.plant.is_discrete and d.verification["feedback_stability_margin"].passed


def test_feedback_errors():
    with pytest.raises(ValidationError, match="state feedback needs the input matrix B; plant 'x' has none"):
        well_conditioned_feedback(Plant([[0.0]], [[1.0]], name="x"), poles=[-1.0])
    plant = Plant([[0.0, 1.0], [2.0, -1.0]], [[1.0, 0.0]], B=[[0.0], [1.0]])
    with pytest.raises(DimensionError, match=r"structure has the wrong shape: expected \(1, 2\)"):
        well_conditioned_feedback(plant, poles=[-1, -2], structure=np.ones((2, 1), dtype=bool))
    # a feedthrough D is ignored (issue 27: state feedback and LQR never use C or D)
    with_d = well_conditioned_feedback(control.ss(plant.A, plant.B, plant.C, 1.0), poles=[-1, -2])
    np.testing.assert_array_equal(with_d.K, well_conditioned_feedback(plant, poles=[-1, -2]).K)
    with pytest.raises(ValidationError, match="B must have at least one column"):
        dual_plant(np.eye(2), np.zeros((2, 0)))


# ------------------------------------------------------------------ inverse LQR
def _lqr_reference(A, B, Q, R, dt):
    """scipy's control-form ARE with the returned Q (independent of the filter code path)."""
    if dt is None:
        X = scipy.linalg.solve_continuous_are(A, B, Q, R)
        return np.linalg.solve(R, B.T @ X), X
    X = scipy.linalg.solve_discrete_are(A, B, Q, R)
    return np.linalg.solve(R + B.T @ X @ B, B.T @ X @ A), X


@pytest.mark.parametrize("dt", [None, 0.1])
@pytest.mark.parametrize("structure", ["full", "diagonal", "output"])
def test_inverse_lqr_checked_by_scipy_and_python_control(dt, structure):
    """Targets from a random LQR (so they are achievable); the returned Q, re-solved by scipy's
    solve_*_are and control.lqr / dlqr, reproduces K and the poles."""
    rng = np.random.default_rng(31)
    n, m = 3, 1
    A = rng.standard_normal((n, n)) if dt is None else 0.5 * rng.standard_normal((n, n))
    B = rng.standard_normal((n, m))
    C = rng.standard_normal((2, n))
    R = np.array([[2.0]])
    Wq = {"full": None, "diagonal": np.diag(rng.uniform(0.5, 2.0, n)),
          "output": C.T @ np.diag([1.0, 3.0]) @ C}[structure]
    Q0 = Wq if Wq is not None else (lambda F: F @ F.T)(rng.standard_normal((n, n)))
    K0, _ = _lqr_reference(A, B, Q0, R, dt)
    target = np.linalg.eigvals(A - B @ K0)
    plant = Plant(A, C, B=B, dt=dt)
    res = lqr_for_poles(plant, target, R=R, structure=structure)
    assert res.success, res.summary()
    K, X = _lqr_reference(A, B, res.Q, R, dt)
    scale = max(1.0, float(np.linalg.norm(res.K)))
    assert np.linalg.norm(K - res.K) / scale <= 4 * res.verification["are_resolve_gain"].tolerance + 1e-9
    Kc, _, E = (control.lqr if dt is None else control.dlqr)(A, B, res.Q, R)
    assert np.linalg.norm(Kc - res.K) / scale <= 4 * res.verification["are_resolve_gain"].tolerance + 1e-9
    np.testing.assert_allclose(np.sort_complex(E), np.sort_complex(target), rtol=1e-6)
    assert np.min(np.linalg.eigvalsh(res.Q)) >= -10 * n * EPS * np.linalg.norm(res.Q, 2)
    if structure == "diagonal":
        np.testing.assert_array_equal(res.Q, np.diag(np.diag(res.Q)))
    if structure == "output":
        np.testing.assert_allclose(res.Q, C.T @ res.Qw @ C, rtol=1e-12, atol=1e-12 * np.linalg.norm(res.Q))
    # the dual: kalman_for_poles of (A', B') gives the same Q and K = L'
    Gd = {"full": None, "diagonal": np.eye(n), "output": C.T}[structure]
    kstruct = {"full": "full", "diagonal": "diagonal", "output": "input"}[structure]
    dual = kalman_for_poles(dual_plant(A, B, dt=dt, R=R, G=Gd), target, q_structure=kstruct)
    np.testing.assert_array_equal(res.K, dual.L.T)
    np.testing.assert_array_equal(res.Q, dual.Q)


def test_inverse_lqr_infeasible_target_has_a_certificate():
    """Every single-input LQR loop of the double integrator has damping >= 1/sqrt(2) (return
    difference |1 + K (jw - A)^-1 B| >= 1 <=> k2^2 >= 2 k1): poles -1 +- 2j (damping 0.45) are out of
    reach, with a global certificate; an unstable target is refused likewise."""
    plant = Plant([[0.0, 1.0], [0.0, 0.0]], [[1.0, 0.0]], B=[[0.0], [1.0]])
    res = lqr_for_poles(plant, [-1 + 2j, -1 - 2j])
    assert res.status is Status.INFEASIBLE and res.certificate is not None and res.K is None
    ok = lqr_for_poles(plant, [-1 + 0.5j, -1 - 0.5j])         # damping 0.89: reachable
    assert ok.success
    k1, k2 = ok.K.ravel()
    assert k2 * k2 >= 2 * k1 * (1 - 1e-9)
    bad = lqr_for_poles(plant, [1.0, -2.0])
    assert bad.status is Status.INFEASIBLE and bad.certificate.kind == "unstable_target"


def test_inverse_lqr_errors():
    plant = Plant([[0.0, 1.0], [-6.0, -5.0]], [[1.0, 0.0]], B=[[0.0], [1.0]])
    with pytest.raises(ValidationError, match="structure must be one of 'full', 'diagonal', 'output'"):
        lqr_for_poles(plant, [-5, -8], structure="input")
    with pytest.raises(DimensionError, match=r"R has the wrong shape: expected \(1, 1\)"):
        lqr_for_poles(plant, [-5, -8], R=np.eye(2))
    with pytest.raises(ValidationError, match="R must be positive definite"):
        lqr_for_poles(plant, [-5, -8], R=[[-1.0]])
    with pytest.raises(NotControllableError, match=r"\(A, B\) is not controllable"):
        lqr_for_poles(Plant(np.diag([-1.0, -2.0]), [[1.0, 1.0]], B=[[0.0], [1.0]]), [-3, -4])
    with pytest.raises(ValidationError, match="state feedback needs the input matrix B"):
        lqr_for_poles(Plant([[0.0]], [[1.0]]), [-1.0])


# ------------------------------------------------------------------ issue 27: controller mode, strict input
@pytest.mark.parametrize("name", ["pp_byers5", "pp_chu2007_ex8"])
def test_controller_mode_beats_scipy_on_cond_X(name):
    """The two problems where the dual measure lost to scipy's YT on cond(X) (88.96 vs 88.56 and
    22.64 vs 18.44): the controller-mode engine minimizes cond(X) itself."""
    A, B, poles, _ = _AB(name)
    res = place(A, B, poles)
    assert res.success
    for method in ("YT", "KNV0"):
        try:
            ref = scipy.signal.place_poles(A, B, poles, method=method)
        except ValueError:  # KNV0: complex poles
            continue
        assert res.kappa2 < metrics.kappa2(A - B @ ref.gain_matrix)
    assert res.kappa2 == pytest.approx(metrics.kappa2(A - B @ res.gain_matrix), rel=1e-6)
    # the verb: the same measure, its X a verified unit-column right eigenbasis of A - B K
    d = well_conditioned_feedback(Plant(A, np.eye(A.shape[0]), B=B), poles=poles)
    F = A - B @ d.K
    assert d.success and d.kappa2 == d.kappa2_right == pytest.approx(np.linalg.cond(d.X), rel=1e-12)
    assert np.linalg.norm(F @ d.X - d.X * _col_poles(F, d.X)[None, :]) <= 1e-10 * np.linalg.norm(F)
    assert d.kappa2 <= res.kappa2 * (1 + 1e-6)      # place caps each stage at maxiter = 30, the verb at 400


def _col_poles(F, X):
    """The eigenvalue of each column of an eigenbasis X of F (Rayleigh quotients)."""
    return np.array([X[:, j].conj() @ F @ X[:, j] / (X[:, j].conj() @ X[:, j]) for j in range(X.shape[1])])


def test_repeated_poles_with_one_input_are_placed_by_ackermann():
    A = np.diag([1.0, 2.0, 3.0, 4.0])
    B = np.array([[1.0], [1.0], [1.0], [1.0]])
    poles = [-2.0, -2.0, -1 + 1j, -1 - 1j]
    res = place(A, B, poles)
    assert res.success and res.kappa2 == np.inf and "kappa2 = inf" in res.message
    assert res.verification["feedback_charpoly_error"].passed
    np.testing.assert_allclose(np.poly(A - B @ res.gain_matrix), np.real(np.poly(poles)), rtol=1e-9)
    np.testing.assert_allclose(res.gain_matrix.ravel(), np.ravel(control.acker(A, B, poles)), rtol=1e-8)
    d = well_conditioned_feedback(Plant(A, np.eye(4), B=B), poles=[-2.0] * 4)
    assert d.success and d.kappa2 == np.inf and d.route.answered.name == "ackermann"
    assert np.all(np.isfinite(d.K))


def test_repeated_poles_beyond_rank_B_are_refused_in_B_words():
    from optdesign.errors import DefectivePolesError

    A = np.array([0, 7, 0, 0, 0, 0, 0, 7 / 3.0, 0, 0, 0, 0, 0, 0, 0, 0], dtype=float).reshape(4, 4)
    B = np.array([0, 0, 0, 0, 1, 0, 0, 1], dtype=float).reshape(4, 2)
    with pytest.raises(DefectivePolesError, match=r"-2\+0j is requested 4 times but rank\(B\) = 2") as exc:
        place(A, B, [-2, -2, -2, -2])
    assert isinstance(exc.value, ValueError) and "rank(C)" not in str(exc.value)
    with pytest.raises(DefectivePolesError, match=r"rank\(B\) = 2"):
        well_conditioned_feedback(Plant(A, np.eye(4), B=B), poles=[-2, -2, -2, -2])


def test_two_dimensional_poles_are_refused_not_flattened():
    A = np.array([[0.0, 1.0], [2.0, -1.0]])
    B = np.array([[0.0], [1.0]])
    plant = Plant(A, [[1.0, 0.0]], B=B)
    col = np.array([[-1.0], [-2.0]])
    with pytest.raises(DimensionError, match=r"poles must be a 1-D vector of shape \(k,\); found shape \(2, 1\)"):
        place(A, B, col)
    with pytest.raises(DimensionError, match=r"shape \(2, 1\)"):
        well_conditioned_feedback(plant, poles=col)
    with pytest.raises(DimensionError, match=r"shape \(2, 1\)"):
        lqr_for_poles(plant, col)
    with pytest.raises(ValidationError, match="KNV0.*real poles only"):
        place(A, B, [-1 + 1j, -1 - 1j], method="KNV0")


def test_lqr_for_poles_ignores_D():
    """LQR uses neither C nor D: a system with a feedthrough is accepted (python-control's lqr)."""
    A, B, C = [[0.0, 1.0], [-6.0, -5.0]], [[0.0], [1.0]], [[1.0, 0.0]]
    res = lqr_for_poles(control.ss(A, B, C, [[2.0]]), [-5, -8])
    assert res.success
    np.testing.assert_allclose(res.K, [[34.0, 8.0]], rtol=1e-6)
