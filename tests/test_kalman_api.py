"""The complete Kalman API (issue 16, item 4): cross-covariance N, both discrete forms, kalmd,
sensors / known, finite-horizon discrete gains -- against python-control, scipy, MATLAB's
documented formulas and simulation."""

from __future__ import annotations

import control
import numpy as np
import pytest
import scipy.integrate
import scipy.linalg
import scipy.signal
from numpy.typing import NDArray

from optdesign import Plant, kalman, riccati_de
from optdesign.classical.riccati import filter_are_error
from optdesign.design.kalman import kalman_finite_horizon, kalmd, van_loan
from optdesign.errors import (
    ArgumentTypeError,
    DimensionError,
    NotPositiveDefiniteError,
    NotPositiveSemidefiniteError,
    ValidationError,
)
from optdesign.results import Status

EPS = np.finfo(float).eps


def _correlated_plant(seed: int, n: int = 3, m: int = 2, p: int = 2, dt: float | None = None):
    """A random plant with a random joint covariance [[Q, N], [N', R]] > 0."""
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n, n))
    if dt is not None:
        A /= 1.3 * max(1.0, float(np.max(np.abs(np.linalg.eigvals(A)))))
    G, C = rng.standard_normal((n, m)), rng.standard_normal((p, n))
    F = rng.standard_normal((m + p, m + p))
    J = F @ F.T + 0.1 * np.eye(m + p)
    return Plant(A, C, G=G, Q=J[:m, :m], R=J[m:, m:], dt=dt), J[:m, m:]


def _rel(X, Y) -> float:
    return float(np.linalg.norm(np.asarray(X) - np.asarray(Y)) / np.linalg.norm(Y))


# ------------------------------------------------------------------ cross-covariance N
def _reduced(plant: Plant, N: NDArray) -> Plant:
    """The uncorrelated problem of (plant, N): A - G N R^-1 C, Q - N R^-1 N'."""
    K = N @ np.linalg.inv(plant.R)
    return plant.replace(A=plant.A - plant.G @ K @ plant.C, Q=plant.Q - K @ N.T)


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("dt", [None, 0.1])
def test_cross_covariance_against_scipy_and_python_control(seed, dt):
    """python-control 0.10's lqe / dlqe refuse NN (ControlNotImplemented), so N is checked against
    the Riccati equation they document -- A P + P A' - (P C' + G N) R^-1 (C P + N' G') + G Q G' = 0 --
    solved by scipy (s = G N) and by control.care / control.dare (S = G N), which do not reduce.
    P agrees within 4x the sum of the two solutions' a posteriori error estimates; L is the documented
    gain formula applied to P (to rounding)."""
    plant, N = _correlated_plant(seed, dt=dt)
    kf = kalman(plant, N=N)
    assert kf.success, kf.summary()
    A, C, G, Q, R = plant.A, plant.C, plant.G, plant.Q, plant.R
    W = 0.5 * (G @ Q @ G.T + (G @ Q @ G.T).T)
    if dt is None:
        refs = [scipy.linalg.solve_continuous_are(A.T, C.T, W, R, s=G @ N),
                control.care(A.T, C.T, W, R, S=G @ N)[0]]
        L = (kf.P @ C.T + G @ N) @ np.linalg.inv(R)
        lqe = control.lqe
    else:
        refs = [scipy.linalg.solve_discrete_are(A.T, C.T, W, R, s=G @ N),
                control.dare(A.T, C.T, W, R, S=G @ N)[0]]
        L = (A @ kf.P @ C.T + G @ N) @ np.linalg.inv(C @ kf.P @ C.T + R)
        lqe = control.dlqe
    red = _reduced(plant, N)
    for P_ref in refs:
        err_ref = filter_are_error(red, 0.5 * (P_ref + P_ref.T)).relative
        err_ours = kf.verification["forward_error"].value
        assert _rel(kf.P, P_ref) <= 4 * (err_ours + err_ref) + 10 * plant.n * EPS
    assert _rel(kf.L, L) <= 1e3 * EPS * np.linalg.cond(R if dt is None else C @ kf.P @ C.T + R)
    np.testing.assert_array_equal(kf.N, N)
    try:
        L_peer, _, _ = lqe(A, G, C, Q, R, N)
    except control.ControlNotImplemented:
        L_peer = None                                   # python-control 0.10: not implemented
    if L_peer is not None:                              # pragma: no cover - a future python-control
        assert _rel(kf.L, L_peer) <= 1e-8


def test_zero_cross_covariance_is_the_plain_filter():
    plant, N = _correlated_plant(3)
    a, b = kalman(plant), kalman(plant, N=np.zeros_like(N))
    np.testing.assert_array_equal(a.L, b.L)
    np.testing.assert_array_equal(a.P, b.P)
    assert b.N is None


def test_dlqe_returns_the_predictor_gain():
    """python-control's dlqe returns L = A P C' (C P C' + R)^-1 (the predictor gain, what
    kalman().L is), not the filter gain M = P C' (C P C' + R)^-1."""
    plant = Plant([[0.9, 0.2], [-0.1, 0.8]], [[1.0, 0.0]], Q=0.1 * np.eye(2), R=[[0.5]], dt=0.1)
    kf = kalman(plant)
    L, P, E = control.dlqe(plant.A, np.eye(2), plant.C, plant.Q, plant.R)
    assert _rel(kf.L, L) < 1e-12 and _rel(kf.P, P) < 1e-12
    assert _rel(kf.M, L) > 0.1                          # M is a different matrix
    np.testing.assert_allclose(kf.L, plant.A @ kf.M, rtol=1e-14)


def test_matlab_formulas_with_noise_feedthrough():
    """MATLAB kalman's documented continuous formulas with y = C x + D u + H w + v:
    R_bar = R + H N + N' H' + H Q H', N_bar = G (Q H' + N), L = (P C' + N_bar) R_bar^-1, P from the
    Riccati equation with (G Q G', N_bar, R_bar)."""
    rng = np.random.default_rng(8)
    n, nu, m, p = 3, 1, 2, 2
    A = rng.standard_normal((n, n)) - 2 * np.eye(n)
    Bu, G = rng.standard_normal((n, nu)), rng.standard_normal((n, m))
    C, Du, H = rng.standard_normal((p, n)), rng.standard_normal((p, nu)), 0.3 * rng.standard_normal((p, m))
    Q, R, N = np.diag([1.0, 2.0]), np.diag([0.5, 0.8]), 0.1 * rng.standard_normal((m, p))
    sys_ = control.ss(A, np.hstack([Bu, G]), C, np.hstack([Du, H]))
    kf = kalman(sys_, Q=Q, R=R, N=N, known=[0])
    Rb = R + H @ N + N.T @ H.T + H @ Q @ H.T
    Nb = G @ (Q @ H.T + N)
    P = scipy.linalg.solve_continuous_are(A.T, C.T, G @ Q @ G.T, Rb, s=Nb)
    L = (P @ C.T + Nb) @ np.linalg.inv(Rb)
    assert kf.success
    assert _rel(kf.P, P) < 1e-10 and _rel(kf.L, L) < 1e-10
    np.testing.assert_allclose(kf.extra["R_used"], Rb, rtol=1e-14)
    np.testing.assert_array_equal(kf.D, Du)
    np.testing.assert_array_equal(kf.H, H)


# ------------------------------------------------------------------ simulation
def _simulate(plant: Plant, J: NDArray, L: NDArray, M: NDArray, *, runs: int, steps: int, seed: int):
    """Monte Carlo of x[k+1] = A x + G w, y = C x + v with (w, v) ~ N(0, J): the errors of the
    predictor x_hat[k|k-1] (gain L) and of the updated x_hat[k|k] (gain M) at the last step, over
    independent runs started at x = x_hat = 0."""
    rng = np.random.default_rng(seed)
    n, m = plant.n, plant.m
    Lc = np.linalg.cholesky(J)
    x = np.zeros((runs, n))
    xh = np.zeros((runs, n))
    for _ in range(steps):
        wv = rng.standard_normal((runs, J.shape[0])) @ Lc.T
        w, v = wv[:, :m], wv[:, m:]
        y = x @ plant.C.T + v
        innov = y - xh @ plant.C.T
        upd = xh + innov @ M.T
        e_pred, e_upd = x - xh, x - upd
        x = x @ plant.A.T + w @ plant.G.T
        xh = xh @ plant.A.T + innov @ L.T
    return e_pred, e_upd


def _within_sampling_error(E: NDArray, P: NDArray, sigmas: float = 5.0) -> tuple[bool, float]:
    """Is the sample covariance of the rows of E equal to P within ``sigmas`` standard errors per entry?
    (Gaussian samples: var of the (i, j) estimate = (P_ii P_jj + P_ij^2) / runs.)"""
    runs = E.shape[0]
    S = E.T @ E / runs
    se = np.sqrt((np.outer(np.diag(P), np.diag(P)) + P * P) / runs)
    worst = float(np.max(np.abs(S - P) / se))
    return worst <= sigmas, worst


def test_empirical_error_covariance_with_cross_covariance():
    """20,000 runs of 150 steps (the filter's error has forgotten its start): the predictor error
    covariance is P and the updated one Z, within 5 standard errors of a sample covariance; the
    filter that ignores N is measurably worse (w and v strongly correlated: N = [0.9; 0.3])."""
    plant = Plant([[0.95, 0.3], [-0.2, 0.9]], [[1.0, 0.0]], Q=np.eye(2), R=[[1.0]], dt=0.1)
    N = np.array([[0.9], [0.3]])
    J = np.block([[plant.Q, N], [N.T, plant.R]])
    kf = kalman(plant, N=N)
    rho = float(np.max(np.abs(kf.poles)))
    assert rho ** 150 < 1e-6
    e_pred, e_upd = _simulate(plant, J, kf.L, kf.M, runs=20000, steps=150, seed=4)
    ok_p, worst_p = _within_sampling_error(e_pred, kf.P)
    ok_z, worst_z = _within_sampling_error(e_upd, kf.Z)
    assert ok_p, worst_p
    assert ok_z, worst_z
    np.testing.assert_allclose(kf.Z, kf.P - kf.M @ (plant.C @ kf.P @ plant.C.T + plant.R) @ kf.M.T,
                               rtol=1e-12, atol=1e-14)
    # the filter that ignores N: its error covariance is the Lyapunov solution of its own error
    # dynamics e+ = (A - L C) e + G w - L v, larger than P, and the simulation tells them apart
    naive = kalman(plant)
    e_naive, _ = _simulate(plant, J, naive.L, naive.M, runs=20000, steps=150, seed=4)
    F, GL = plant.A - naive.L @ plant.C, np.hstack([plant.G, -naive.L])
    Pn = scipy.linalg.solve_discrete_lyapunov(F, GL @ J @ GL.T)
    assert _within_sampling_error(e_naive, Pn)[0]
    assert not _within_sampling_error(e_naive, kf.P)[0]
    assert np.trace(Pn) > np.trace(kf.P)


# ------------------------------------------------------------------ kalmd
def test_van_loan_against_a_numerical_integral():
    A = np.array([[0.0, 1.0], [-2.0, -0.3]])
    W = np.array([[0.2, 0.05], [0.05, 1.0]])
    for Ts in (0.01, 0.1, 1.0):
        Ad, Qd = van_loan(A, W, Ts)
        integral, err = scipy.integrate.quad_vec(
            lambda t: scipy.linalg.expm(A * t) @ W @ scipy.linalg.expm(A.T * t), 0.0, Ts,
            epsabs=0.0, epsrel=1e-13)
        np.testing.assert_allclose(Qd, integral, rtol=0, atol=10 * err + 100 * EPS * np.abs(integral).max())
        np.testing.assert_allclose(Ad, scipy.linalg.expm(A * Ts), rtol=1e-13)
        np.testing.assert_array_equal(Qd, Qd.T)


def test_kalmd_follows_matlab_documented_recipe():
    """MATLAB kalmd: ZOH discretization, Qd = int_0^Ts e^(At) G Q G' e^(A't) dt, Rd = R / Ts, then
    the discrete kalman -- checked piece by piece against scipy's cont2discrete and control.c2d."""
    A = np.array([[0.0, 1.0], [-2.0, -0.3]])
    B, C = np.array([[0.0], [1.0]]), np.array([[1.0, 0.0]])
    G, Q, R, Ts = np.array([[0.0], [1.0]]), np.array([[2.0]]), np.array([[0.5]]), 0.05
    sys_ = control.ss(A, np.hstack([B, G]), C, 0)
    kd = kalmd(sys_, Ts, Q=Q, R=R, known=[0])
    assert kd.success and kd.plant.dt == Ts
    Ad, Bd, *_ = scipy.signal.cont2discrete((A, B, C, np.zeros((1, 1))), Ts, method="zoh")
    np.testing.assert_allclose(kd.plant.A, Ad, rtol=1e-13)
    np.testing.assert_allclose(kd.plant.B, Bd, rtol=1e-12)
    np.testing.assert_allclose(kd.plant.B, control.c2d(control.ss(A, B, C, 0), Ts).B, rtol=1e-12)
    np.testing.assert_allclose(kd.extra["Rd"], R / Ts)
    _, Qd = van_loan(A, G @ Q @ G.T, Ts)
    np.testing.assert_array_equal(kd.extra["Qd"], Qd)
    ref = kalman(Plant(Ad, C, Q=Qd, R=R / Ts, dt=Ts))
    assert _rel(kd.L, ref.L) < 1e-12 and _rel(kd.Z, ref.Z) < 1e-12
    assert kd.Z is not None and kd.M is not None


def test_kalmd_approaches_the_continuous_filter():
    """kalmd's filter 'has response characteristics similar to' the continuous one (MATLAB): its
    poles log(z) / Ts tend to the continuous Kalman poles at second order in Ts, M / Ts to L at
    first order."""
    plant = Plant([[0.0, 1.0], [-2.0, -0.3]], [[1.0, 0.0]], Q=np.eye(2), R=[[0.5]])
    kc = kalman(plant)
    pole_err, gain_err = [], []
    for Ts in (1e-1, 1e-2, 1e-3):
        kd = kalmd(plant, Ts)
        pole_err.append(np.max(np.abs(np.sort_complex(np.log(kd.poles) / Ts) - np.sort_complex(kc.poles))))
        gain_err.append(np.max(np.abs(kd.M / Ts - kc.L)))
    for k in range(2):
        assert 50 < pole_err[k] / pole_err[k + 1] < 200
        assert 5 < gain_err[k] / gain_err[k + 1] < 20


# ------------------------------------------------------------------ sensors / known
def test_sensors_and_known_select_like_matlab():
    """kalman(sys, Q, R, N, sensors, known): the filter of the selected outputs and inputs is that of
    the Plant built by hand."""
    rng = np.random.default_rng(2)
    A = rng.standard_normal((3, 3)) - 2 * np.eye(3)
    Bfull = rng.standard_normal((3, 3))        # inputs: w0, u, w1
    Cfull = rng.standard_normal((3, 3))
    sys_ = control.ss(A, Bfull, Cfull, 0)
    Q, R = np.diag([1.0, 3.0]), np.diag([0.5, 2.0])
    kf = kalman(sys_, Q=Q, R=R, sensors=[2, 0], known=[1])
    ref = kalman(Plant(A, Cfull[[2, 0]], G=Bfull[:, [0, 2]], Q=Q, R=R, B=Bfull[:, [1]]))
    np.testing.assert_array_equal(kf.L, ref.L)
    np.testing.assert_array_equal(kf.plant.B, Bfull[:, [1]])
    assert kf.extra["sensors"] == (2, 0) and kf.extra["known"] == (1,)
    est = kf.estimator()
    assert est.ninputs == 1 + 2 and est.noutputs == 2 + 3


# ------------------------------------------------------------------ finite horizon
@pytest.mark.parametrize("seed", range(4))
def test_finite_horizon_equals_riccati_de_and_converges(seed):
    plant, N = _correlated_plant(seed + 40, dt=0.2)
    P0 = np.eye(plant.n)
    seq = kalman_finite_horizon(plant, P0, 120)
    assert seq.success and len(seq) == 121
    tr = riccati_de(plant, P0, 120 * 0.2, estimate_error=False, steady_state=False)
    scale = float(np.max(np.linalg.norm(seq.P, axis=(1, 2))))
    diff = float(np.max(np.linalg.norm(seq.P - tr.P, axis=(1, 2))))
    assert diff <= 4 * (seq.error_estimate + 120 * EPS) * scale
    np.testing.assert_allclose(seq.times, tr.t, rtol=1e-14, atol=1e-14)
    # with N: riccati_de of the reduced (uncorrelated) plant gives the same P; L is shifted by G N R^-1
    seqN = kalman_finite_horizon(plant, P0, 120, N=N)
    K = N @ np.linalg.inv(plant.R)
    trN = riccati_de(_reduced(plant, N), P0, 120 * 0.2, estimate_error=False, steady_state=False)
    scaleN = float(np.max(np.linalg.norm(seqN.P, axis=(1, 2))))
    assert float(np.max(np.linalg.norm(seqN.P - trN.P, axis=(1, 2)))) <= 1e3 * 120 * EPS * scaleN
    np.testing.assert_allclose(seqN.L, trN.L + plant.G @ K, rtol=1e-9, atol=1e-12 * scaleN)
    # converges to the steady-state filter (both forms), at the rate of the slowest filter pole
    kf = kalman(plant, N=N)
    steps = int(np.ceil(np.log(1e-12) / np.log(float(np.max(np.abs(kf.poles))))))
    long = kalman_finite_horizon(plant, P0, steps, N=N)
    for a, b in ((long.P[-1], kf.P), (long.Z[-1], kf.Z), (long.L[-1], kf.L), (long.M[-1], kf.M)):
        assert _rel(a, b) < 1e-8


def test_finite_horizon_covariance_by_simulation_and_optimality():
    """Monte Carlo over 20,000 runs started from x0 ~ N(0, P0): the error covariance of the
    time-varying filter after k steps is P_k (within 5 standard errors).  And the gains are the best
    ones: the filter that ignores N (its covariance propagated exactly by the Joseph form, valid for
    any gain) ends with a larger covariance, and the simulation tells the two apart."""
    plant = Plant([[0.95, 0.3], [-0.2, 0.9]], [[1.0, 0.0]], Q=np.eye(2), R=[[1.0]], dt=0.1)
    N = np.array([[0.9], [0.3]])
    J = np.block([[plant.Q, N], [N.T, plant.R]])
    P0 = np.diag([4.0, 1.0])
    steps = 8
    seq = kalman_finite_horizon(plant, P0, steps, N=N)
    naive = kalman_finite_horizon(plant, P0, steps)             # gains that ignore N

    def run(gains):
        rng = np.random.default_rng(9)
        runs = 20000
        x = rng.standard_normal((runs, 2)) @ np.linalg.cholesky(P0).T
        xh = np.zeros((runs, 2))
        Lc = np.linalg.cholesky(J)
        for k in range(steps):
            wv = rng.standard_normal((runs, 3)) @ Lc.T
            innov = x @ plant.C.T + wv[:, 2:] - xh @ plant.C.T
            x = x @ plant.A.T + wv[:, :2] @ plant.G.T
            xh = xh @ plant.A.T + innov @ gains[k].T
        return x - xh

    e = run(seq.L)
    ok, worst = _within_sampling_error(e, seq.P[steps])
    assert ok, worst
    Pn = P0
    for k in range(steps):                                       # Joseph form with the naive gains
        F, GL = plant.A - naive.L[k] @ plant.C, np.hstack([plant.G, -naive.L[k]])
        Pn = F @ Pn @ F.T + GL @ J @ GL.T
    assert np.trace(Pn) > np.trace(seq.P[steps])
    e_naive = run(naive.L)
    assert _within_sampling_error(e_naive, Pn)[0]
    assert not _within_sampling_error(e_naive, seq.P[steps])[0]


def test_finite_horizon_time_limit():
    plant, _ = _correlated_plant(1, dt=0.1)
    seq = kalman_finite_horizon(plant, np.eye(3), 200000, time_limit=0.05)
    assert seq.status is Status.TIME_LIMIT and not seq.success
    assert 1 <= len(seq) < 200001 and seq.P.shape[0] == seq.Z.shape[0] == seq.L.shape[0] == len(seq)
    assert "time limit reached" in seq.message


# ------------------------------------------------------------------ bad input
def test_errors():
    plant, N = _correlated_plant(0)
    with pytest.raises(NotPositiveSemidefiniteError, match=r"N makes the joint covariance \[\[Q, N\], \[N'"):
        kalman(plant, N=10 * N)
    with pytest.raises(DimensionError, match=r"N has the wrong shape: expected \(2, 2\), found \(2, 1\)"):
        kalman(plant, N=N[:, :1])
    with pytest.raises(ValidationError, match="N must be numeric"):
        kalman(plant, N=[["a", "b"], ["c", "d"]])
    cont = Plant([[0.0, 1.0], [-2.0, -0.3]], [[1.0, 0.0]], Q=np.eye(2), R=[[0.5]])
    for Ts, match in ((0.0, "Ts must be finite and > 0; found 0.0"), (-0.1, "Ts must be finite and > 0"),
                      ("0.1", "Ts must be a real number; found '0.1'"), (np.inf, "Ts must be finite")):
        with pytest.raises(ValidationError, match=match):
            kalmd(cont, Ts)
    with pytest.raises(ValidationError, match=r"kalmd needs a continuous plant; found a discrete one"):
        kalmd(cont.replace(dt=0.1), 0.1)
    with pytest.raises(ValidationError, match="method must be one of"):
        kalmd(cont, 0.1, method="zoh")
    sys_ = control.ss(cont.A, [[0.0, 1.0], [1.0, 0.0]], cont.C, [[0.0, 0.5]])
    with pytest.raises(ValidationError, match="kalmd has no cross-covariance: the noise inputs selected"):
        kalmd(sys_, 0.1, Q=[[1.0]], R=[[1.0]], known=[0])
    with pytest.raises(ValidationError, match=r"sensors\[0\] = 1 is out of range: the system has 1 outputs"):
        kalman(cont, sensors=[1])
    # a perfectly correlated noise feedthrough makes R + H N + N' H' + H Q H' singular
    sys1 = control.ss([[-1.0]], [[1.0]], [[1.0]], [[1.0]])
    with pytest.raises(NotPositiveDefiniteError, match=r"R \+ H N \+ N' H' \+ H Q H' .* must be positive"):
        kalman(sys1, Q=[[1.0]], R=[[1.0]], N=[[-1.0]], known=[])
    dplant = cont.replace(dt=0.1, A=[[0.5, 0.1], [0.0, 0.4]])
    with pytest.raises(ValidationError, match="kalman_finite_horizon is for discrete plants.*riccati_de"):
        kalman_finite_horizon(cont, np.eye(2), 10)
    with pytest.raises(ValidationError, match="steps must be an integer >= 1; found 0"):
        kalman_finite_horizon(dplant, np.eye(2), 0)
    with pytest.raises(ValidationError, match="steps must be an integer >= 1; found 2.5"):
        kalman_finite_horizon(dplant, np.eye(2), 2.5)
    with pytest.raises(NotPositiveSemidefiniteError, match="P0 must be positive semidefinite"):
        kalman_finite_horizon(dplant, -np.eye(2), 10)
    with pytest.raises(ValidationError, match="tol must be finite and > 0"):
        kalman_finite_horizon(dplant, np.eye(2), 10, tol=0.0)
    with pytest.raises(ValidationError, match="Ts must be finite and > 0"):
        van_loan(cont.A, np.eye(2), -1.0)


# ------------------------------------------------------------------ the peers' noise conventions (issue 27)
def test_q_the_size_of_the_inputs_takes_the_noise_through_sys_b_as_control_lqe():
    """python-control's ``lqe(sys, QN, RN)``: G = sys.B.  Before issue 27 this raised (Q 2 x 2 with
    n = 3 asked for G=), and with n == m it took G = I."""
    rng = np.random.default_rng(27)
    for n, m in ((3, 2), (2, 2)):
        A = rng.standard_normal((n, n)) - 2.0 * np.eye(n)
        B, C = rng.standard_normal((n, m)), rng.standard_normal((1, n))
        sys_ = control.ss(A, B, C, 0)
        QN, RN = np.diag([1.0, 3.0]), np.array([[0.5]])
        kf = kalman(sys_, Q=QN, R=RN)
        # python-control's lqe(sys, QN, RN) is the filter of the noise through B; computed here with
        # scipy (control.lqe itself refuses G QN G' as "not symmetric" under OpenBLAS's Prescott kernel)
        P = scipy.linalg.solve_continuous_are(A.T, C.T, B @ QN @ B.T, RN)
        L = P @ C.T @ np.linalg.inv(RN)
        np.testing.assert_allclose(kf.L, L, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(kf.P, P, rtol=1e-9, atol=1e-12)
        np.testing.assert_array_equal(kf.plant.G, B)
        np.testing.assert_array_equal(kf.plant.B, B)          # the inputs stay known (noise added to them)
        assert any("python-control's lqe(sys, QN, RN)" in t for t in kf.extra["notes"])
        assert "the noise enters through sys.B" in kf.message
    # MATLAB's all-noise reading of the same call: same gain, no known inputs
    every = kalman(sys_, Q=QN, R=RN, known=[])
    np.testing.assert_array_equal(every.L, kf.L)
    assert every.plant.B is None


def test_fewer_noise_channels_than_inputs_reads_the_last_inputs_as_noise_as_matlab():
    """MATLAB's kalman(sys, Qn, Rn): the last size(Qn) inputs are noise, the others known.  Before
    issue 27, Q n x n took G = I (here L = 1.0 where the MATLAB reading gives 0.4142)."""
    sys_ = control.ss([[-1.0]], [[1.0, 0.5]], [[1.0]], 0)       # inputs [u, w]
    kf = kalman(sys_, Q=[[4.0]], R=[[1.0]])
    np.testing.assert_array_equal(kf.plant.G, [[0.5]])
    np.testing.assert_array_equal(kf.plant.B, [[1.0]])
    assert kf.extra["known"] == (0,)
    # scalar ARE: -2 P - P^2 + 0.25 * 4 = 0  ->  P = sqrt(2) - 1 = L
    np.testing.assert_allclose(kf.L, [[np.sqrt(2.0) - 1.0]], rtol=1e-12)
    np.testing.assert_array_equal(kalman(sys_, Q=[[4.0]], R=[[1.0]], known=[0]).L, kf.L)
    assert "the last 1 input(s) [1] are the process noise" in kf.message


def _octave_kalman_plant(seed: int):
    """GNU Octave control package, inst/kalman.m, the shared fixture of its 2nd and 3rd tests: a
    discrete n = 3 plant (dt = 1) with inputs [u, w1, w2], D = [1, 0, 0], Q = I2, R = 1 (Octave
    draws Bw = rand - 0.5; a fixed seed here).  Reference: 2000 steps of the filter recursion
    (Octave runs 30 and asserts to 4e-4; the fixed point is reached to rounding here)."""
    rng = np.random.default_rng(seed)
    A = np.array([[1.1269, -0.4940, 0.1129], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    Bw = rng.random((3, 2)) - 0.5
    B = np.hstack([[[-0.3832], [0.5919], [0.5191]], Bw])
    C = np.array([[1.0, 0.0, 0.0]])
    sys_ = control.ss(A, B, C, [[1.0, 0.0, 0.0]], 1)
    PP = np.eye(3)
    for _ in range(2000):
        Pinf = A @ PP @ A.T + Bw @ Bw.T
        K = Pinf @ C.T / (C @ Pinf @ C.T + 1.0)
        PP = (np.eye(3) - K @ C) @ Pinf
    return sys_, A, C, Pinf, K


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_octave_kalman_tests(seed):
    """Octave's kalman.m tests 2 and 3 (``kalman(sys, Q, R, [], 1, 1)`` and ``'current'``): P, the
    predictor gain (inv(A) L = the filter gain K) and the estimator's A, for MATLAB's explicit
    selection and for its default reading (the last size(Q) inputs are noise)."""
    sys_, A, C, Pinf, K = _octave_kalman_plant(seed)
    for kw in (dict(sensors=[0], known=[0]), {}):
        kf = kalman(sys_, Q=np.eye(2), R=[[1.0]], **kw)
        assert kf.success
        np.testing.assert_allclose(kf.P, Pinf, atol=1e-9)
        np.testing.assert_allclose(np.linalg.solve(A, kf.L), K, atol=1e-9)
        np.testing.assert_allclose(kf.M, K, atol=1e-9)
        Ae = kf.estimator(output="arrays").A
        np.testing.assert_allclose(Ae, A - kf.L @ C, atol=1e-12)
        # 'current': the same state matrix A - A K C (Octave asserts kalmfc.a = A - A*K*C)
        np.testing.assert_allclose(kf.estimator("filter", output="arrays").A, A - A @ K @ C, atol=1e-9)


def test_octave_kalman_scalar_with_cross_covariance():
    """Octave's kalman.m test 1: ``sys = ss(-2, 1, 1, 3); kalman(sys, 1, 1, 1)``: the input is the
    noise and feeds through (H = 3), N = 1: g = 0.25, x = 0, estimator [a, b; c, d] =
    [-2.25, 0.25; 1, 0; 1, 0] (Octave's reading: no known input, ``known=[]`` here)."""
    sys_ = control.ss(-2.0, 1.0, 1.0, 3.0)
    kf = kalman(sys_, Q=[[1.0]], R=[[1.0]], N=[[1.0]], known=[])
    np.testing.assert_allclose(kf.L, [[0.25]], atol=1e-12)
    np.testing.assert_allclose(kf.P, [[0.0]], atol=1e-12)
    Ae, Be, Ce, De = kf.estimator(output="arrays")
    np.testing.assert_allclose(np.block([[Ae, Be], [Ce, De]]), [[-2.25, 0.25], [1.0, 0.0], [1.0, 0.0]],
                               atol=1e-12)
    # the python-control reading (Q matches the input: noise added to the known input): same gain
    np.testing.assert_allclose(kalman(sys_, Q=[[1.0]], R=[[1.0]], N=[[1.0]]).L, kf.L, atol=1e-12)


def test_q_n_by_n_beyond_the_inputs_is_every_state_and_said():
    """Q n x n with fewer inputs than n: G = I, the library's convention (what kalman_for_poles
    returns Q for), said in the message and notes -- not silently (issue 27); another size of Q
    beyond the inputs asks for G= or known=."""
    sys_ = control.ss([[-1.0, 0.2], [0.0, -2.0]], [[0.0], [1.0]], [[1.0, 0.0]], 0)
    kf = kalman(sys_, Q=np.eye(2), R=[[1.0]])
    explicit = kalman(sys_, G=np.eye(2), Q=np.eye(2), R=[[1.0]])
    np.testing.assert_array_equal(kf.L, explicit.L)
    np.testing.assert_array_equal(kf.plant.B, [[0.0], [1.0]])
    assert "Q is n x n = 2 x 2 and sys has 1 input(s): the noise enters every state (G = I" in kf.message
    with pytest.raises(ValidationError, match=r"Q is 3 x 3 but sys has 1 input\(s\) and the plant has n = 2 "
                                              r"states: say how the noise enters -- G= \(n x 3\), or known="):
        kalman(sys_, Q=np.eye(3), R=[[1.0]])
    free = kalman(scipy.signal.StateSpace(sys_.A, np.zeros((2, 0)), sys_.C, np.zeros((1, 0))), Q=np.eye(2),
                  R=[[1.0]])
    np.testing.assert_array_equal(free.L, explicit.L)


def test_transfer_functions_raise_a_type_error():
    """python-control raises a TypeError (ControlArgument) for a transfer function; so do we, also a
    ValidationError, saying control.ss(sys)."""
    for tf in (control.tf([1.0], [1.0, 2.0]), scipy.signal.lti([1.0], [1.0, 2.0])):
        with pytest.raises(TypeError, match=r"TransferFunction.*(control.ss\(sys\)|sys.to_ss\(\))") as info:
            kalman(tf, Q=[[1.0]], R=[[1.0]])
        assert isinstance(info.value, ArgumentTypeError) and isinstance(info.value, ValidationError)


def test_kalmd_with_n_is_a_typed_error():
    cont = Plant([[0.0, 1.0], [-2.0, -0.3]], [[1.0, 0.0]], Q=np.eye(2), R=[[0.5]])
    with pytest.raises(ArgumentTypeError, match=r"kalmd has no cross-covariance N \(as MATLAB's kalmd\).*"
                                                 r"kalman\(discrete_plant, N=Nd\)"):
        kalmd(cont, 0.1, N=np.zeros((2, 1)))


def test_drss_systems_with_dt_true_are_designed_with_dt_one():
    np.random.seed(27)                                  # control.drss draws from numpy's global state
    sys_ = control.drss(3, 1, 2, strictly_proper=True)  # python-control's dlqe ignores D; we fold it in
    assert sys_.dt is True
    kf = kalman(sys_, Q=np.eye(2), R=[[1.0]])
    L, P, _ = control.dlqe(sys_, np.eye(2), [[1.0]])
    np.testing.assert_allclose(kf.L, L, rtol=1e-8, atol=1e-12)
    assert kf.plant.dt == 1.0 and kf.extra["dt_unspecified"]
    assert "unspecified sampling period (dt=True): designed with dt = 1" in kf.message
    assert "dt=True: unspecified, taken as 1" in kf.summary()


def test_kalmd_route_is_the_discrete_solve():
    cont = Plant([[0.0, 1.0], [-2.0, -0.3]], [[1.0, 0.0]], Q=np.eye(2), R=[[0.5]])
    kd = kalmd(cont, 0.1, method="hamiltonian")
    assert [(s.name, s.kind, s.outcome) for s in kd.route] == [("hamiltonian", "engine", "answered")]
    assert "route: hamiltonian [engine]: answered" in kd.summary()
