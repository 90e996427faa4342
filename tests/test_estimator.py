"""Systems out: estimators as state-space systems, checked by simulation against the plant
(issue 16, item 2)."""

from __future__ import annotations

from types import SimpleNamespace

import control
import numpy as np
import pytest
import scipy.linalg

from optdesign import Plant, kalman, well_conditioned_observer
from optdesign.design.estimator import EstimatorArrays, estimator_of, estimator_system
from optdesign.errors import DimensionError, ValidationError

A = np.array([[0.0, 1.0], [-2.0, -0.3]])
B = np.array([[0.0], [1.0]])
C = np.array([[1.0, 0.0]])
AD = np.array([[0.9, 0.2], [-0.1, 0.8]])


def _zoh_augmented(plant: Plant, est, t_step: float):
    """Exact discretization (piecewise-constant u) of plant + estimator fed with [u; y = C x]:
    states [x; x_e]."""
    Ae, Be, Ce, De = (np.asarray(M) for M in (est.A, est.B, est.C, est.D))
    n, nu = plant.n, plant.B.shape[1]
    Bu, By = Be[:, :nu], Be[:, nu:]
    Aa = np.block([[plant.A, np.zeros((n, n))], [By @ plant.C, Ae]])
    Ba = np.vstack([plant.B, Bu])
    M = np.zeros((2 * n + nu, 2 * n + nu))
    M[:2 * n, :2 * n], M[:2 * n, 2 * n:] = Aa, Ba
    E = scipy.linalg.expm(M * t_step)
    return E[:2 * n, :2 * n], E[:2 * n, 2 * n:], Ce, De


def test_continuous_error_decays_at_the_designed_poles():
    """x - x_hat = expm((A - L C) t) (x0 - x_hat0) whatever the known input: simulated exactly."""
    plant = Plant(A, C, B=B)
    design = well_conditioned_observer(plant, poles=[-2.0, -3.0], starts=1)
    est = design_est = estimator_system(plant, design.L)
    assert isinstance(design_est, control.StateSpace)
    assert design_est.input_labels == ["u[0]", "y[0]"]
    assert design_est.output_labels == ["yhat[0]", "xhat[0]", "xhat[1]"]
    np.testing.assert_allclose(np.sort(np.linalg.eigvals(est.A).real), [-3.0, -2.0], rtol=1e-10)
    h = 0.01
    Ad, Bd, Ce, De = _zoh_augmented(plant, est, h)
    x0 = np.array([1.0, -0.5])
    z = np.r_[x0, 0.0, 0.0]
    F = plant.A - design.L @ plant.C
    worst = 0.0
    for k in range(1, 401):
        u = np.sin(0.7 * k * h) + 0.5
        z = Ad @ z + Bd[:, 0] * u
        err = z[:2] - z[2:]
        worst = max(worst, float(np.linalg.norm(err - scipy.linalg.expm(F * k * h) @ x0)))
        y_hat_x_hat = Ce @ z[2:] + De[:, 0] * u          # outputs [y_hat; x_hat], y input = C x
        np.testing.assert_array_equal(y_hat_x_hat[1:], z[2:])
    assert worst < 400 * 100 * np.finfo(float).eps * np.linalg.norm(x0)   # 400 steps of O(eps) rounding
    # the decay rate is that of the slowest pole: ||e(4)|| ~ e^-2t
    assert np.linalg.norm(z[:2] - z[2:]) < 10 * np.exp(-2.0 * 4.0) * np.linalg.norm(x0)


@pytest.mark.parametrize("form", ["predictor", "filter"])
def test_discrete_estimator_simulated_with_python_control(form):
    """Noise-free plant, estimator run by control.forced_response on the returned system: the
    predicted error obeys e[k+1] = (A - L C) e[k]; the filtered estimate x_hat[k|k] has the error
    (I - M C) e[k]."""
    plant = Plant(AD, C, Q=0.1 * np.eye(2), R=[[0.5]], dt=0.1, B=B)
    kf = kalman(plant)
    est = kf.estimator(form)
    T = 60
    rng = np.random.default_rng(5)
    u = rng.standard_normal(T)
    x0 = np.array([1.0, -1.0])
    x, X, Y = x0.copy(), [], []
    for k in range(T):
        X.append(x)
        Y.append(C @ x)
        x = AD @ x + B[:, 0] * u[k]
    X, Y = np.array(X).T, np.array(Y).T
    out = control.forced_response(est, np.arange(T) * 0.1, np.vstack([u[None, :], Y]), X0=np.zeros(2)).outputs
    xhat = out[1:]
    F = AD - kf.L @ C
    e = np.array([np.linalg.matrix_power(F, k) @ x0 for k in range(T)]).T
    expected = e if form == "predictor" else (np.eye(2) - kf.M @ C) @ e
    tol = 100 * T * np.finfo(float).eps * float(np.max(np.abs(X)))     # T steps of O(eps) rounding
    np.testing.assert_allclose(X - xhat, expected, rtol=0, atol=tol)
    np.testing.assert_allclose(out[0], (C @ xhat)[0], rtol=0, atol=tol)   # y_hat = C x_hat (D = 0)
    assert est.dt == 0.1


def test_predictor_equals_python_control_create_estimator_iosystem():
    """python-control's estimator (started at the steady-state P, so its gain stays the predictor
    gain) gives the same x_hat on a noisy run."""
    sysf = control.ss(AD, np.hstack([B, np.eye(2)]), C, 0, 0.1)     # inputs [u, w1, w2]
    Qn, Rn = 0.1 * np.eye(2), np.array([[0.5]])
    kf = kalman(sysf, Q=Qn, R=Rn, known=[0])
    peer = control.create_estimator_iosystem(sysf, Qn, Rn, control_indices=[0], disturbance_indices=[1, 2])
    rng = np.random.default_rng(11)
    T = 80
    u = rng.standard_normal(T)
    x, Y = np.array([1.0, -1.0]), []
    for k in range(T):
        Y.append(C @ x + np.sqrt(0.5) * rng.standard_normal(1))
        x = AD @ x + B[:, 0] * u[k] + np.sqrt(0.1) * rng.standard_normal(2)
    t = np.arange(T) * 0.1
    Y = np.array(Y).T
    theirs = control.input_output_response(peer, t, np.vstack([Y, u[None, :]]), X0=[np.zeros(2), kf.P])
    ours = control.forced_response(kf.estimator(), t, np.vstack([u[None, :], Y]), X0=np.zeros(2))
    scale = float(np.max(np.abs(ours.outputs[1:])))
    np.testing.assert_allclose(ours.outputs[1:], theirs.outputs, rtol=0,
                               atol=100 * np.finfo(float).eps * scale)


def test_matches_the_documented_kalman_example():
    """Altair Compose's kalman reference page (MATLAB-compatible): A = [-1 .1; 0 -2], B = [0; 1],
    G = I, C = [1 0], Q = 0.1 I, R = 1, N = 0 gives kest.a = [-1.04889 0.1; -0.00082 -2],
    kest.b = [0 0.04889; 1 0.00082] (printed to 5 decimals)."""
    sys_ = control.ss([[-1.0, 0.1], [0.0, -2.0]], [[0.0, 1.0, 0.0], [1.0, 0.0, 1.0]], [[1.0, 0.0]],
                      np.zeros((1, 3)))
    kf = kalman(sys_, Q=0.1 * np.eye(2), R=[[1.0]], N=np.zeros((2, 1)), known=[0])
    est = kf.estimator()
    np.testing.assert_allclose(est.A, [[-1.04889, 0.1], [-0.00082, -2.0]], atol=5e-6)
    np.testing.assert_allclose(est.B, [[0.0, 0.04889], [1.0, 0.00082]], atol=5e-6)
    np.testing.assert_array_equal(est.C, [[1.0, 0.0], [1.0, 0.0], [0.0, 1.0]])


def test_feedthrough_and_arrays_output():
    """With a known-input feedthrough D the estimator subtracts D u and adds it to y_hat."""
    sys_ = control.ss(A, B, C, [[0.4]])
    kf = kalman(sys_, Q=np.eye(2), R=[[1.0]])
    assert kf.D is not None
    est = kf.estimator(output="arrays")
    assert isinstance(est, EstimatorArrays) and est.form == "continuous" and est.dt is None
    Ae, Be, Ce, De = est
    np.testing.assert_allclose(Be[:, :1], B - kf.L * 0.4)
    np.testing.assert_allclose(De, [[0.4, 0.0], [0.0, 0.0], [0.0, 0.0]])
    assert est.inputs == ("u[0]", "y[0]") and est.outputs == ("yhat[0]", "xhat[0]", "xhat[1]")
    assert len(est) == 4
    # filter form with D: x_hat[k|k] = x_hat + M (y - C x_hat - D u)
    sysd = control.ss(AD, B, C, [[0.4]], 0.1)
    kd = kalman(sysd, Q=np.eye(2), R=[[1.0]])
    _, _, Cf, Df = kd.estimator("filter", output="arrays")
    np.testing.assert_allclose(Df[1:], np.hstack([-kd.M * 0.4, kd.M]))
    np.testing.assert_allclose(Cf[1:], np.eye(2) - kd.M @ C)


def test_estimator_of_other_results_and_plain_plants():
    plant = Plant(A, C)                       # no B: the inputs are the measurements only
    design = well_conditioned_observer(plant, poles=[-4.0, -5.0], starts=1)
    est = estimator_of(design, plant)
    assert est.ninputs == 1 and est.noutputs == 3
    # an ObserverDesign carries its plant now (issue 12): the plant argument is optional
    own = estimator_of(design)
    np.testing.assert_allclose(own.A, est.A)
    np.testing.assert_allclose(own.B, est.B)
    with pytest.raises(ValidationError, match="does not carry its plant: pass plant="):
        estimator_of(SimpleNamespace(L=design.L, poles=design.poles))


def test_errors():
    plant = Plant(A, C, B=B)
    dplant = Plant(AD, C, dt=0.1)
    L = np.ones((2, 1))
    with pytest.raises(ValidationError, match=r"form must be 'continuous' for a continuous plant; found"):
        estimator_system(plant, L, form="filter")
    with pytest.raises(ValidationError, match=r"form must be 'predictor' or 'filter' for a discrete \(dt"):
        estimator_system(dplant, L, form="continuous")
    with pytest.raises(ValidationError, match="form must be one of 'continuous', 'predictor', 'filter'"):
        estimator_system(plant, L, form="current")
    with pytest.raises(ValidationError, match=r"form='filter' needs the innovation gain M"):
        estimator_system(dplant, L, form="filter")
    with pytest.raises(DimensionError, match=r"L has the wrong shape: expected \(2, 1\), found \(1, 2\)"):
        estimator_system(plant, np.ones((1, 2)))
    with pytest.raises(DimensionError, match=r"D has the wrong shape"):
        estimator_system(plant, L, D=np.ones((2, 2)))
    with pytest.raises(ValidationError, match="output must be one of 'auto', 'control', 'arrays'"):
        estimator_system(plant, L, output="ss")
    with pytest.raises(ValidationError, match="plant must be an optdesign.Plant; found list"):
        estimator_system([[1.0]], L)

    class Failed:
        L = None
        status = "not_found"

    with pytest.raises(ValidationError, match=r"the result has no gain L \(status not_found\)"):
        estimator_of(Failed(), plant)


# ------------------------------------------------------------------ python-control's layout (issue 27)
@pytest.mark.parametrize("form", ["predictor", "filter"])
def test_control_layout_matches_ours_permuted(form):
    """io="control": inputs [y; u], output x_hat -- the rows of x_hat of our estimator, its input
    columns permuted."""
    kd = kalman(control.ss(AD, B, C, [[0.4]], 0.1), G=np.eye(2), Q=np.eye(2), R=[[1.0]])
    ours = kd.estimator(form, output="arrays")
    theirs = kd.estimator(form, output="arrays", io="control")
    np.testing.assert_array_equal(theirs.A, ours.A)
    np.testing.assert_array_equal(theirs.B, ours.B[:, [1, 0]])
    np.testing.assert_array_equal(theirs.C, ours.C[1:])
    np.testing.assert_array_equal(theirs.D, ours.D[1:][:, [1, 0]])
    assert theirs.inputs == ("y[0]", "u[0]") and theirs.outputs == ("xhat[0]", "xhat[1]")
    with pytest.raises(ValidationError, match="io must be one of 'optdesign', 'control'"):
        kd.estimator(io="matlab")


def test_control_layout_closes_the_loop_in_create_statefbk_iosystem():
    """python-control's stochsys_test.py::test_estimator_iosys, with our steady-state estimator:
    control.create_statefbk_iosystem(sys, K, estimator=est) accepts it and the closed loop is
    [[A, -B K], [L C, A - L C - B K]] (python-control's check, from the estimator's blocks).  Before
    issue 27 our [u; y] -> [y_hat; x_hat] estimator could not be passed."""
    np.random.seed(0)
    sys_ = control.drss(4, 2, 2, strictly_proper=True)
    K, _, _ = control.dlqr(sys_, np.eye(4), np.eye(2))
    kf = kalman(sys_, Q=np.eye(2), R=np.eye(2))
    est = kf.estimator(io="control")
    assert isinstance(est, control.StateSpace) and est.ninputs == 4 and est.noutputs == 4
    _, clsys = control.create_statefbk_iosystem(sys_, K, estimator=est)
    cls = clsys.linearize(0, 0) if not isinstance(clsys, control.StateSpace) else clsys
    L = kf.L
    A_cl = np.block([[sys_.A, -sys_.B @ K], [L @ sys_.C, sys_.A - L @ sys_.C - sys_.B @ K]])
    np.testing.assert_allclose(cls.A[:8, :8], A_cl, atol=1e-12)
    # the separation principle: the closed-loop poles are those of A - B K and A - L C
    expect = np.concatenate([np.linalg.eigvals(sys_.A - sys_.B @ K), kf.poles])
    got = np.linalg.eigvals(cls.A)
    assert max(np.min(np.abs(got - z)) for z in expect) < 1e-8
