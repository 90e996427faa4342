"""python-control's own estimator tests, ported onto :mod:`optdesign.compat.control` (issue 27).

Source: python-control 0.10.2, ``control/tests/stochsys_test.py``.  Each test below names the test it
ports; the matrices, tolerances (``assert_almost_equal``: 7 decimals; the simulations' atol/rtol) and
asserted properties are python-control's, the code is ours.  Where a case is about a native verb
(``optdesign.kalman`` with a system, ``dt=True``), the native verb is checked beside the drop-in.

Not ported (not about the functions of the drop-in): ``test_white_noise``, ``test_correlation``
(signal generators), ``test_oep``, ``test_mhe`` (optimal estimation by optimization).

Deliberate difference (docs/guide/differences.rst): ``lqe(sys, Q, R, N)`` / ``dlqe(...)`` with a
cross-covariance *answer* (python-control raises ``ControlNotImplemented``) -- the port checks the
answer instead (``test_lqe_call_format``).
"""

from __future__ import annotations

from math import log, pi

import control as ct
import numpy as np
import pytest

import optdesign as od
from optdesign.compat import control as oc
from optdesign.errors import ArgumentTypeError, OptDesignError

DECIMAL = 7   # numpy's assert_almost_equal default, python-control's tolerance


def _scalar_case():
    """stochsys_test.py's scalar data: A, G, C, QN, RN = 0, 0.1, 1, 10, 2."""
    return tuple(np.array([[x]]) for x in (0.0, 0.1, 1.0, 10.0, 2.0))


# ------------------------------------------------------------------ test_LQE, test_DLQE
@pytest.mark.parametrize("method", [None, "slycot", "scipy"])
def test_LQE(method):
    """stochsys_test.py::test_LQE (check_LQE): P = sqrt(G QN G RN), L = P / RN, E = -L."""
    A, G, C, QN, RN = _scalar_case()
    L, P, E = oc.lqe(A, G, C, QN, RN, method=method)
    P_exp = np.sqrt(G @ QN @ G @ RN)
    np.testing.assert_almost_equal(P, P_exp, DECIMAL)
    np.testing.assert_almost_equal(L, P_exp / RN, DECIMAL)
    np.testing.assert_almost_equal(E, -np.squeeze(P_exp / RN), DECIMAL)


@pytest.mark.parametrize("method", [None, "slycot", "scipy"])
def test_DLQE(method):
    """stochsys_test.py::test_DLQE (check_DLQE): A = 0, so P = G QN G, L = 0, E = 0."""
    A, G, C, QN, RN = _scalar_case()
    L, P, E = oc.dlqe(A, G, C, QN, RN, method=method)
    np.testing.assert_almost_equal(P, G @ QN @ G, DECIMAL)
    np.testing.assert_almost_equal(L, 0.0, DECIMAL)
    np.testing.assert_almost_equal(E, 0.0, DECIMAL)


# ------------------------------------------------------------------ test_lqe_call_format
@pytest.mark.parametrize("cdlqe", [oc.lqe, oc.dlqe], ids=["lqe", "dlqe"])
def test_lqe_call_format(cdlqe):
    """stochsys_test.py::test_lqe_call_format: rss(4, 3, 2) with dt = None (either domain); the
    system form equals the matrix form with G = sys.B; the error forms.  N = 0 answers (the one
    deliberate difference: python-control raises ControlNotImplemented) and equals the N-less call."""
    np.random.seed(1)
    sys_ = ct.rss(4, 3, 2)
    sys_.dt = None
    Q, R, N = np.eye(sys_.ninputs), np.eye(sys_.noutputs), np.zeros((sys_.ninputs, sys_.noutputs))
    Lref, Pref, Eref = cdlqe(sys_.A, sys_.B, sys_.C, Q, R)
    L, P, E = cdlqe(sys_, Q, R)
    np.testing.assert_almost_equal(Lref, L)
    np.testing.assert_almost_equal(Pref, P)
    np.testing.assert_almost_equal(Eref, E)
    # the native verb with the system: the noise through sys.B (issue 27; it raised before)
    kf = od.kalman(ct.ss(sys_.A, sys_.B, sys_.C, 0, None if cdlqe is oc.lqe else 1), Q=Q, R=R)
    np.testing.assert_almost_equal(kf.L, Lref)
    # N = 0: answered, the same
    LN, PN, EN = cdlqe(sys_, Q, R, N)
    np.testing.assert_almost_equal(LN, Lref)
    np.testing.assert_almost_equal(PN, Pref)
    with pytest.raises(ct.ControlDimension, match="Incompatible"):
        cdlqe(sys_.A, sys_.C, sys_.B, Q, R)
    with pytest.raises(ct.ControlDimension, match="Incompatible"):
        cdlqe(sys_.A, sys_.B, sys_.C, R, Q)
    with pytest.raises(ct.ControlArgument, match="not enough input"):
        cdlqe(sys_.A, sys_.C)
    sys_tf = ct.tf(ct.rss(3, 1, 1))
    sys_tf.dt = None
    with pytest.raises(ct.ControlArgument, match="LTI system must be") as info:
        cdlqe(sys_tf, Q, R)
    assert isinstance(info.value, OptDesignError)


def test_lqe_with_cross_covariance_is_answered():
    """The deliberate difference, checked: lqe(A, G, C, QN, RN, NN) solves the cross-term equation
    A P + P A' - (P C' + G NN) RN^-1 (C P + NN' G') + G QN G' = 0, L = (P C' + G NN) RN^-1."""
    np.random.seed(2)
    sys_ = ct.rss(3, 2, 2)
    Q, R, N = np.eye(2), 2.0 * np.eye(2), 0.3 * np.ones((2, 2))
    L, P, E = oc.lqe(sys_.A, sys_.B, sys_.C, Q, R, N)
    A, G, C = sys_.A, sys_.B, sys_.C
    K = P @ C.T + G @ N
    res = A @ P + P @ A.T - K @ np.linalg.solve(R, K.T) + G @ Q @ G.T
    assert np.linalg.norm(res) <= 1e-10 * max(1.0, np.linalg.norm(P))
    np.testing.assert_allclose(L, K @ np.linalg.inv(R), rtol=1e-10)
    np.testing.assert_allclose(np.sort_complex(E), np.sort_complex(np.linalg.eigvals(A - L @ C)), atol=1e-10)


# ------------------------------------------------------------------ test_lqe_discrete
def test_lqe_discrete():
    """stochsys_test.py::test_lqe_discrete: lqe(sys) = lqe(A, B, C); lqe of a discrete system
    (drss: dt = True) is dlqe; dt = None is continuous; dlqe of a continuous system raises."""
    np.random.seed(3)
    csys, dsys = ct.rss(2, 1, 1), ct.drss(2, 1, 1)
    Q, R = np.eye(1), np.eye(1)
    for a, b in zip(oc.lqe(csys, Q, R), oc.lqe(csys.A, csys.B, csys.C, Q, R)):
        np.testing.assert_almost_equal(a, b)
    assert dsys.dt is True
    for a, b in zip(oc.lqe(dsys, Q, R), oc.dlqe(dsys, Q, R)):
        np.testing.assert_almost_equal(a, b)
    asys = ct.ss(csys.A, csys.B, csys.C, csys.D, dt=None)
    for a, b in zip(oc.lqe(asys, Q, R), oc.lqe(csys.A, csys.B, csys.C, Q, R)):
        np.testing.assert_almost_equal(a, b)
    with pytest.raises(ct.ControlArgument, match="called with a continuous"):
        oc.dlqe(csys, Q, R)
    # the native verb takes the dt = True system (issue 27; it was refused): dt = 1, said
    kf = od.kalman(ct.ss(dsys.A, dsys.B, dsys.C, 0, True), Q=Q, R=R)
    np.testing.assert_almost_equal(kf.L, oc.dlqe(dsys, Q, R)[0])
    assert kf.extra["dt_unspecified"] and kf.plant.dt == 1.0


# ------------------------------------------------------------------ test_estimator_iosys
def test_estimator_iosys():
    """stochsys_test.py::test_estimator_iosys: the estimator closes the loop in
    create_statefbk_iosystem; the closed loop's linearization has python-control's blocks."""
    np.random.seed(4)
    sys_ = ct.drss(4, 2, 2, strictly_proper=True)
    K, _, _ = oc.dlqr(sys_, np.eye(4), np.eye(2))
    estim = oc.create_estimator_iosystem(sys_, np.eye(2), np.eye(2), np.eye(4))
    _, clsys = ct.create_statefbk_iosystem(sys_, K, estimator=estim)
    est = estim.linearize(0, 0)
    n = sys_.nstates
    Be1, Be2 = est.B[:n, :sys_.noutputs], est.B[:n, sys_.noutputs:]
    A_chk = np.block([[sys_.A, -sys_.B @ K], [Be1 @ sys_.C, est.A[:n, :n] - Be2 @ K]])
    B_chk = np.block([[sys_.B @ K, sys_.B], [Be2 @ K, Be2]])
    C_chk = np.block([[sys_.C, np.zeros((sys_.noutputs, n))], [np.zeros_like(K), -K]])
    D_chk = np.block([[np.zeros((sys_.noutputs, n + sys_.ninputs))], [K, np.eye(sys_.ninputs)]])
    cls = clsys.linearize(0, 0)
    np.testing.assert_almost_equal(cls.A[:2 * n, :2 * n], A_chk)
    np.testing.assert_almost_equal(cls.B[:2 * n, :], B_chk)
    np.testing.assert_almost_equal(cls.C[:, :2 * n], C_chk)
    np.testing.assert_almost_equal(cls.D, D_chk)
    # and the native steady-state estimator in python-control's layout closes the same loop
    lin = od.kalman(sys_, Q=np.eye(2), R=np.eye(2)).estimator(io="control")
    _, cl2 = ct.create_statefbk_iosystem(sys_, K, estimator=lin)
    assert cl2.nstates == 2 * n


# ------------------------------------------------------------------ test_estimator_iosys_ctime
@pytest.mark.parametrize("sys_args", [
    ([[-1]], [[1]], [[1]], 0),
    ([[-1, 0.1], [0, -2]], [[0], [1]], [[1, 0]], 0),
    ([[-1, 0.1], [0, -2]], [[1, 0], [0, 1]], [[1, 0]], 0),
    ([[-1, 0.1, 0.1], [0, -2, 0], [0.1, 0, -3]], [[1, 0], [0, 0.1], [0, 1]], [[1, 0, 0.1], [0, 1, 0.1]], 0),
], ids=["scalar", "siso2", "2i1o2s", "2i2o3s"])
def test_estimator_iosys_ctime(sys_args):
    """stochsys_test.py::test_estimator_iosys_ctime: simulated from xhat = 0, P = I, the estimate
    converges to the state (atol 1e-6, rtol 1e-3) and P to lqe's P; the optimal estimate is an
    equilibrium (atol 1e-4, rtol 1e-2)."""
    sys_ = ct.ss(*sys_args)
    T = 10 * log(1e-2) / np.max(sys_.poles().real)
    nl = ct.NonlinearIOSystem(lambda t, x, u, params: sys_.A @ x + sys_.B @ u,
                              lambda t, x, u, params: sys_.C @ x + sys_.D @ u,
                              inputs=sys_.ninputs, outputs=sys_.noutputs, states=sys_.nstates)
    t = np.linspace(0, T, 500)
    U = 2e-2 * np.array([np.sin(t + i * pi / 3) for i in range(sys_.ninputs)])
    X0, P0 = np.ones(sys_.nstates), np.eye(sys_.nstates)
    QN, RN = np.eye(sys_.ninputs), np.eye(sys_.noutputs)
    estim = oc.create_estimator_iosystem(sys_, QN, RN)
    resp = ct.input_output_response(nl, t, U, X0)
    _, Pf, _ = oc.lqe(sys_, QN, RN)
    er = ct.input_output_response(estim, t, [resp.outputs, U], [0 * X0, P0])
    n = sys_.nstates
    np.testing.assert_allclose(er.states[:n, -1], resp.states[:, -1], atol=1e-6, rtol=1e-3)
    np.testing.assert_allclose(er.states[n:, -1], Pf.reshape(-1), atol=1e-6, rtol=1e-3)
    ss = ct.input_output_response(estim, t, [resp.outputs, U], [X0, Pf])
    np.testing.assert_allclose(ss.states[n:], np.outer(Pf.reshape(-1), np.ones_like(t)), atol=1e-4, rtol=1e-2)
    np.testing.assert_allclose(ss.states[:n], resp.states, atol=1e-4, rtol=1e-2)


# ------------------------------------------------------------------ test_estimator_errors
def test_estimator_errors():
    """stochsys_test.py::test_estimator_errors: an unknown keyword (TypeError), a transfer function
    (ControlArgument "system must be a linear"), C for a system without full-state output, C of the
    wrong size."""
    np.random.seed(5)
    sys_ = ct.drss(4, 2, 2, strictly_proper=True)
    QN, RN = np.eye(sys_.ninputs), np.eye(sys_.noutputs)
    with pytest.raises(TypeError, match="unrecognized keyword"):
        oc.create_estimator_iosystem(sys_, QN, RN, unknown=True)
    with pytest.raises(ct.ControlArgument, match=".* system must be a linear") as info:
        oc.create_estimator_iosystem(ct.tf([1], [1, 1], dt=True), QN, RN)
    assert isinstance(info.value, ArgumentTypeError)
    with pytest.raises(ValueError, match="output must be full state"):
        oc.create_estimator_iosystem(sys_, QN, RN, C=np.eye(2, 4))
    sys_fs = ct.drss(4, 4, 2, strictly_proper=True)
    sys_fs.C = np.eye(4)
    with pytest.raises(ValueError, match="output is the wrong size"):
        oc.create_estimator_iosystem(sys_fs, QN, RN, C=np.eye(1, 4))


# ------------------------------------------------------------------ test_indices
@pytest.mark.parametrize("ctrl_indices, dist_indices", [
    (slice(0, 3), None),
    (3, None),
    (None, 2),
    ([0, 1, 4], None),
    (["u[0]", "u[1]", "u[4]"], None),
    (["u[0]", "u[1]", "u[4]"], ["u[1]", "u[3]"]),
    (slice(0, 3), slice(3, 5)),
])
def test_indices(ctrl_indices, dist_indices):
    """stochsys_test.py::test_indices: control / disturbance index forms; with correct=False and
    the same integrator settings, the estimator reproduces the noise-free response (rtol 1e-2)."""
    sys_ = ct.ss([[-1, 1, 0, 0], [0, -2, 1, 0], [0, 0, -3, 1], [0, 0, 0, -4]],
                 [[0, 0, 0, 0, 0], [1, 0, 0, 0, 0], [0, 1, 0, .1, 0], [0, 0, 1, 0, .1]],
                 [[1, 0, 0, 0], [0, 1, 0, 0]], 0)
    labels = sys_.input_labels
    if ctrl_indices is not None:
        ctrl = (list(range(5))[ctrl_indices] if isinstance(ctrl_indices, slice) else
                list(range(ctrl_indices)) if isinstance(ctrl_indices, int) else
                [labels.index(v) if isinstance(v, str) else v for v in ctrl_indices])
        dist = [i for i in range(5) if i not in ctrl]
    else:
        dist = list(range(5 - dist_indices, 5))
        ctrl = [i for i in range(5) if i not in dist]
    sysm = ct.ss(sys_.A, sys_.B[:, ctrl], sys_.C, sys_.D[:, ctrl])
    t = np.linspace(0, 10, 20)
    U = np.vstack([np.sin(t + i) for i in range(len(ctrl))])
    ivp = {"method": "RK45", "max_step": 0.01, "atol": 1, "rtol": 1}
    resp = ct.input_output_response(sysm, t, U, np.zeros(4), solve_ivp_kwargs=ivp)
    estim = oc.create_estimator_iosystem(sys_, np.eye(len(dist)), np.eye(2), control_indices=ctrl_indices,
                                         disturbance_indices=dist_indices)
    er = ct.input_output_response(estim, t, [resp.outputs, U], [np.zeros(4), np.eye(4)], solve_ivp_kwargs=ivp,
                                  params={"correct": False})
    np.testing.assert_allclose(resp.states, er.outputs, rtol=1e-2)


def test_estimator_with_control_feedthrough():
    """Beyond python-control (which raises NotImplementedError for D != 0): the feedthrough of the
    control inputs is subtracted, so an exact estimate has zero innovation; a feedthrough of the
    disturbances is refused with a typed NotImplementedError."""
    sys_ = ct.ss([[-1.0, 0.2], [0.0, -2.0]], [[0.0, 1.0], [1.0, 0.0]], [[1.0, 0.0]], [[0.5, 0.0]])
    est = oc.create_estimator_iosystem(sys_, np.eye(1), np.eye(1), control_indices=[0])
    x, u = np.array([0.3, -0.2]), np.array([0.7])
    y = sys_.C @ x + sys_.D[:, [0]] @ u
    P = np.eye(2)
    dx = est.dynamics(0.0, np.concatenate([x, P.ravel()]), np.concatenate([y, u]))[:2]
    np.testing.assert_allclose(dx, sys_.A @ x + sys_.B[:, [0]] @ u, atol=1e-14)
    with pytest.raises(NotImplementedError, match="feedthrough D of the disturbance inputs"):
        oc.create_estimator_iosystem(ct.ss(sys_.A, sys_.B, sys_.C, [[0.0, 0.5]]), np.eye(1), np.eye(1),
                                     control_indices=[0])
