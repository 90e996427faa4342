"""python-control's own state-feedback tests, ported onto :mod:`optdesign.compat.control` (issue 27).

Source: python-control 0.10.2, ``control/tests/statefbk_test.py``.  Each test below names the test it
ports; the matrices, tolerances (``assert_array_almost_equal``: 6 decimals, ``assert_almost_equal``: 7)
and asserted properties are python-control's, the code is ours.  Where a case is about a native verb
(``optdesign.place``, ``optdesign.lqr_for_poles``) the native verb is checked beside the drop-in.

Not ported (not functions of the drop-in): ctrb / obsv / gram tests, ``test_care`` / ``test_dare``
(python-control's ``mateqn``), the gain-scheduling and ``create_statefbk_iosystem`` argument tests,
``place_varga``'s partial placement (``alpha``), and the two warning tests
(``testLQR_warning``, ``testDLQR_warning``: python-control does not implement them).
"""

from __future__ import annotations

import control as ct
import numpy as np
import pytest

import optdesign as od
from optdesign.compat import control as oc
from optdesign.errors import OptDesignError

# scipy's place_poles example (statefbk_test.py::testPlace)
A_PLACE = np.array([[1.380, -0.2077, 6.715, -5.676], [-0.5814, -4.290, 0, 0.6750],
                    [1.067, 4.273, -6.654, 5.893], [0.0480, 4.273, 1.343, -2.104]])
B_PLACE = np.array([[0, 5.679], [1.136, 1.136], [0, 0], [-3.146, 0]])


def _check_placed(expected, K, A, B):
    """statefbk_test.py::checkPlaced: sorted eigenvalues of A - B K against the request (6 decimals)."""
    placed = np.sort(np.linalg.eigvals(A - B @ K))
    np.testing.assert_array_almost_equal(np.sort(np.squeeze(np.asarray(expected, dtype=complex))), placed)


# ------------------------------------------------------------------ place
def test_place():
    """statefbk_test.py::testPlace: scipy's example placed; dimension errors (ControlDimension);
    three poles at -0.5 with rank(B) = 2 is a ValueError."""
    P = np.array([-0.5 + 1j, -0.5 - 1j, -5.0566, -8.6659])
    K = oc.place(A_PLACE, B_PLACE, P)
    _check_placed(P, K, A_PLACE, B_PLACE)
    with pytest.raises(ct.ControlDimension):
        oc.place(A_PLACE[1:, :], B_PLACE, P)
    with pytest.raises(ct.ControlDimension) as info:
        oc.place(A_PLACE, B_PLACE[1:, :], P)
    assert isinstance(info.value, OptDesignError)
    with pytest.raises(ValueError):
        oc.place(A_PLACE, B_PLACE, np.array([-0.5, -0.5, -0.5, -8.6659]))


def test_acker():
    """statefbk_test.py::testAcker (onto place: one input, so the gain is Ackermann's): random
    reachable rss(states, 1, 1), poles of another rss, placed to 4 decimals."""
    np.random.seed(0)
    for states in range(1, 5):
        for _ in range(4):
            sys_ = ct.rss(states, 1, 1)
            if np.linalg.matrix_rank(ct.ctrb(sys_.A, sys_.B)) != states:
                continue
            desired = ct.poles(ct.rss(states, 1, 1))
            K = oc.place(sys_.A, sys_.B, desired)
            placed = ct.poles(ct.ss(sys_.A - sys_.B @ K, sys_.B, sys_.C, sys_.D))
            np.testing.assert_array_almost_equal(np.sort(desired), np.sort(placed), decimal=4)


def test_place_varga_distinct_poles():
    """statefbk_test.py::testPlace_varga_continuous, its regression case for python-control bug #177
    (A = [[0, 1], [100, 0]], poles -20 +- 10j), onto place."""
    A, B = np.array([[0.0, 1.0], [100.0, 0.0]]), np.array([[0.0], [1.0]])
    P = np.array([-20 + 10j, -20 - 10j])
    _check_placed(P, oc.place(A, B, P), A, B)


@pytest.mark.parametrize("A, P, dt", [
    ([[1.0, -2.0], [3.0, -4.0]], [-2.0, -2.0], None),      # testPlace_varga_continuous
    ([[1.0, 0.0], [0.0, 0.5]], [0.5, 0.5], 1.0),           # testPlace_varga_discrete
], ids=["continuous", "discrete"])
def test_place_varga_repeated_poles(A, P, dt):
    """statefbk_test.py::testPlace_varga_continuous / _discrete: a double pole with one input (the
    poles fix the gain) -- onto the native place, which reports kappa2 infinite."""
    A, B = np.array(A), np.array([[5.0], [7.0]])
    res = od.place(A, B, P, dt=dt)
    assert res.gain_matrix is not None and np.all(np.isfinite(res.gain_matrix))
    M = A - B @ res.gain_matrix
    np.testing.assert_allclose(np.poly(M), np.poly(P), atol=1e-8)


# ------------------------------------------------------------------ lqr / dlqr
def _check_lqr(K, S, E, Q, R):
    """statefbk_test.py::check_LQR: S = sqrt(Q R), K = S / R, E = -K."""
    S_exp = np.sqrt(Q @ R)
    np.testing.assert_array_almost_equal(S, S_exp)
    np.testing.assert_array_almost_equal(K, S_exp / R)
    np.testing.assert_array_almost_equal(E, -np.squeeze(S_exp / R))


def _check_dlqr(K, S, E, Q, R):
    """statefbk_test.py::check_DLQR: A = 0, so S = Q, K = 0, E = 0."""
    np.testing.assert_array_almost_equal(S, Q)
    np.testing.assert_array_almost_equal(K, 0)
    np.testing.assert_array_almost_equal(E, 0)


@pytest.mark.parametrize("method", [None, "slycot", "scipy"])
def test_LQR_integrator(method):
    """statefbk_test.py::test_LQR_integrator."""
    A, B, Q, R = (np.array([[x]]) for x in (0.0, 1.0, 10.0, 2.0))
    _check_lqr(*oc.lqr(A, B, Q, R, method=method), Q, R)


@pytest.mark.parametrize("method", [None, "slycot", "scipy"])
def test_LQR_3args(method):
    """statefbk_test.py::test_LQR_3args."""
    Q, R = np.array([[10.0]]), np.array([[2.0]])
    _check_lqr(*oc.lqr(ct.ss(0.0, 1.0, 1.0, 0.0), Q, R, method=method), Q, R)


@pytest.mark.parametrize("method", [None, "slycot", "scipy"])
def test_DLQR_3args(method):
    """statefbk_test.py::test_DLQR_3args."""
    Q, R = np.array([[10.0]]), np.array([[2.0]])
    _check_dlqr(*oc.dlqr(ct.ss(0.0, 1.0, 1.0, 0.0, 0.1), Q, R, method=method), Q, R)


def test_DLQR_4args():
    """statefbk_test.py::test_DLQR_4args."""
    A, B, Q, R = (np.array([[x]]) for x in (0.0, 1.0, 10.0, 2.0))
    _check_dlqr(*oc.dlqr(A, B, Q, R), Q, R)


@pytest.mark.parametrize("cdlqr", [oc.lqr, oc.dlqr], ids=["lqr", "dlqr"])
def test_lqr_badmethod(cdlqr):
    """statefbk_test.py::test_lqr_badmethod."""
    with pytest.raises(ct.ControlArgument, match="Unknown method"):
        cdlqr(0, 1, 10, 2, method="nosuchmethod")


@pytest.mark.parametrize("cdlqr", [oc.lqr, oc.dlqr], ids=["lqr", "dlqr"])
def test_lqr_slycot_not_needed(cdlqr):
    """statefbk_test.py::test_lqr_slycot_not_installed: python-control raises ControlSlycot without
    slycot; method='slycot' runs our Schur-method solver, so it answers (the same as 'scipy')."""
    for a, b in zip(cdlqr(0.5, 1, 10, 2, method="slycot"), cdlqr(0.5, 1, 10, 2, method="scipy")):
        np.testing.assert_allclose(a, b, rtol=1e-12)


@pytest.mark.parametrize("cdlqr", [oc.lqr, oc.dlqr], ids=["lqr", "dlqr"])
def test_lqr_call_format(cdlqr):
    """statefbk_test.py::test_lqr_call_format: rss(2, 3, 2) with dt = None; the system form, with N
    = 0, equals the matrix form; the error forms."""
    np.random.seed(6)
    sys_ = ct.rss(2, 3, 2)
    sys_.dt = None
    Q, R, N = np.eye(sys_.nstates), np.eye(sys_.ninputs), np.zeros((sys_.nstates, sys_.ninputs))
    ref = cdlqr(sys_.A, sys_.B, Q, R)
    for got in (cdlqr(sys_, Q, R), cdlqr(sys_, Q, R, N)):
        for a, b in zip(ref, got):
            np.testing.assert_array_almost_equal(a, b)
    with pytest.raises(ct.ControlDimension, match="Incompatible dimen"):
        cdlqr(sys_.A, sys_.C, Q, R)
    with pytest.raises(ct.ControlDimension, match="Q must be a square"):
        cdlqr(sys_.A, sys_.B, sys_.C, R, Q)
    with pytest.raises(ct.ControlArgument, match="not enough input"):
        cdlqr(sys_.A, sys_.B)
    sys_tf = ct.tf(ct.rss(3, 1, 1))
    sys_tf.dt = None
    with pytest.raises(ct.ControlArgument, match="LTI system must be"):
        cdlqr(sys_tf, Q, R)


def test_lqr_discrete():
    """statefbk_test.py::test_lqr_discrete: lqr(sys) = lqr(A, B); lqr of a drss system (dt = True)
    is dlqr; dt = None is continuous; dlqr of a continuous system raises."""
    np.random.seed(7)
    csys, dsys = ct.rss(2, 1, 1), ct.drss(2, 1, 1)
    Q, R = np.eye(2), np.eye(1)
    for a, b in zip(oc.lqr(csys, Q, R), oc.lqr(csys.A, csys.B, Q, R)):
        np.testing.assert_almost_equal(a, b)
    for a, b in zip(oc.lqr(dsys, Q, R), oc.dlqr(dsys, Q, R)):
        np.testing.assert_almost_equal(a, b)
    asys = ct.ss(csys.A, csys.B, csys.C, csys.D, dt=None)
    for a, b in zip(oc.lqr(asys, Q, R), oc.lqr(csys.A, csys.B, Q, R)):
        np.testing.assert_almost_equal(a, b)
    with pytest.raises(ct.ControlArgument, match="dsys must be discrete"):
        oc.dlqr(csys, Q, R)


def test_lqr_matches_python_control_and_is_a_riccati_solution():
    """Beside the port: random systems, our K, S against python-control's, and S against the LQR
    equation (continuous and discrete, with a cross weight)."""
    rng = np.random.default_rng(8)
    for discrete in (False, True):
        A = rng.standard_normal((4, 4)) * (0.4 if discrete else 1.0)
        B = rng.standard_normal((4, 2))
        Q, R, N = np.eye(4), np.diag([1.0, 2.0]), 0.1 * rng.standard_normal((4, 2))
        f, g = (oc.dlqr, ct.dlqr) if discrete else (oc.lqr, ct.lqr)
        K, S, E = f(A, B, Q, R, N)
        Kc, Sc, _ = g(A, B, Q, R, N)
        np.testing.assert_allclose(K, Kc, rtol=1e-8, atol=1e-10)
        np.testing.assert_allclose(S, Sc, rtol=1e-8, atol=1e-10)
        if discrete:
            res = A.T @ S @ A - S - (A.T @ S @ B + N) @ K + Q
        else:
            res = A.T @ S + S @ A - (S @ B + N) @ K + Q
        assert np.linalg.norm(res) <= 1e-10 * np.linalg.norm(S)
        np.testing.assert_allclose(np.sort_complex(E), np.sort_complex(np.linalg.eigvals(A - B @ K)),
                                   atol=1e-10)


# ------------------------------------------------------------------ create_statefbk_iosystem with our gains
@pytest.mark.parametrize("nstates, noutputs, ninputs, nintegrators, type_", [
    (2, 0, 1, 0, None), (2, 1, 1, 0, None), (4, 0, 2, 0, None), (4, 3, 2, 0, None),
    (2, 0, 1, 1, None), (4, 0, 2, 2, None), (4, 3, 2, 2, None), (2, 0, 1, 0, "nonlinear"),
    (4, 0, 2, 2, "nonlinear"), (4, 3, 2, 2, "nonlinear"), (2, 0, 1, 0, "iosystem"), (2, 0, 1, 1, "iosystem"),
])
def test_statefbk_iosys(nstates, ninputs, noutputs, nintegrators, type_):
    """statefbk_test.py::test_statefbk_iosys: the gains of our lqr (and lqe for the estimator) in
    python-control's create_statefbk_iosystem; the closed loop has python-control's blocks."""
    np.random.seed(9)
    if noutputs == 0:
        sys_ = ct.rss(nstates, nstates, ninputs, strictly_proper=True)
        sys_.C = np.eye(nstates)
        est = None
    else:
        sys_ = ct.rss(nstates, noutputs, ninputs, strictly_proper=True)
        L, _, _ = oc.lqe(sys_.A, sys_.B, sys_.C, np.eye(ninputs), np.eye(noutputs))
        est = ct.ss(sys_.A - L @ sys_.C, np.hstack([L, sys_.B]), np.eye(nstates), 0,
                    inputs=sys_.output_labels + sys_.input_labels,
                    outputs=[f"xhat[{i}]" for i in range(nstates)])
    if nintegrators:
        C_int = np.eye(nintegrators, nstates)
        A_aug = np.block([[sys_.A, np.zeros((nstates, nintegrators))],
                          [C_int, np.zeros((nintegrators,) * 2)]])
        B_aug = np.vstack([sys_.B, np.zeros((nintegrators, ninputs))])
        aug = ct.ss(A_aug, B_aug, np.hstack([sys_.C, np.zeros((sys_.C.shape[0], nintegrators))]), 0)
    else:
        C_int = np.zeros((0, nstates))
        aug = sys_
    K, _, _ = oc.lqr(aug, np.eye(nstates + nintegrators), np.eye(ninputs))
    Kp, Ki = K[:, :nstates], K[:, nstates:]
    if type_ == "iosystem":
        fbk = ct.ss(np.zeros((nintegrators,) * 2), np.eye(nintegrators, nstates), -Ki, -Kp)
        ctrl, clsys = ct.create_statefbk_iosystem(sys_, fbk, integral_action=C_int, estimator=est,
                                                  controller_type=type_, name=type_)
    else:
        ctrl, clsys = ct.create_statefbk_iosystem(sys_, K, integral_action=C_int, estimator=est,
                                                  controller_type=type_, name=type_)
    if type_ is not None:
        assert ctrl.name == type_
        clsys = clsys.linearize(0, 0)
    z = np.zeros
    if noutputs == 0:
        Ac = np.block([[sys_.A - sys_.B @ Kp, -sys_.B @ Ki], [C_int, z((nintegrators, nintegrators))]])
        Bc = np.block([[sys_.B @ Kp, sys_.B], [-C_int, z((nintegrators, ninputs))]])
        Cc = np.block([[np.eye(nstates), z((nstates, nintegrators))], [-Kp, -Ki]])
        Dc = np.block([[z((nstates, nstates + ninputs))], [Kp, np.eye(ninputs)]])
    else:
        Be1, Be2 = est.B[:, :noutputs], est.B[:, noutputs:]
        Ac = np.block([[sys_.A, -sys_.B @ Ki, -sys_.B @ Kp],
                       [z((nintegrators, nstates + nintegrators)), C_int],
                       [Be1 @ sys_.C, -Be2 @ Ki, est.A - Be2 @ Kp]])
        Bc = np.block([[sys_.B @ Kp, sys_.B], [-C_int, z((nintegrators, ninputs))], [Be2 @ Kp, Be2]])
        Cc = np.block([[sys_.C, z((noutputs, nintegrators + nstates))], [z(Kp.shape), -Ki, -Kp]])
        Dc = np.block([[z((noutputs, nstates + ninputs))], [Kp, np.eye(ninputs)]])
    np.testing.assert_array_almost_equal(clsys.A, Ac)
    np.testing.assert_array_almost_equal(clsys.B, Bc)
    np.testing.assert_array_almost_equal(clsys.C, Cc)
    np.testing.assert_array_almost_equal(clsys.D, Dc)


def test_statefbk_iosys_unused():
    """statefbk_test.py::test_statefbk_iosys_unused: our estimator and gain, with an extra input
    that the controller does not use, give the same closed-loop A."""
    np.random.seed(10)
    sys_ = ct.rss(2, 1, 1, strictly_proper=True)
    est = oc.create_estimator_iosystem(sys_, np.eye(1), np.eye(1))
    K, _, _ = oc.lqr(sys_, np.eye(2), np.eye(1))
    _, cl0 = ct.create_statefbk_iosystem(sys_, K, estimator=est)
    A0 = cl0.linearize(0, 0).A
    for order, col in ((["u[0]", "d"], 0), (["d", "u[0]"], 1)):
        aug = ct.rss(2, inputs=order, outputs=sys_.output_labels, strictly_proper=True)
        aug.A = sys_.A
        aug.B[:, col:col + 1] = sys_.B
        _, cl = ct.create_statefbk_iosystem(aug, K, estimator=est, control_indices=[col])
        assert "d" in cl.input_labels
        np.testing.assert_allclose(cl.linearize(0, 0).A, A0)


def test_lqr_integral_continuous():
    """statefbk_test.py::test_lqr_integral_continuous: integral_action augments the system; the
    controller and closed loop have python-control's blocks; the closed loop is stable."""
    np.random.seed(11)
    sys_ = ct.rss(4, 4, 2, strictly_proper=True)
    sys_.C = np.eye(4)
    C_int = np.eye(2, 4)
    K, _, _ = oc.lqr(sys_, np.eye(6), np.eye(2), integral_action=C_int)
    Kp, Ki = K[:, :4], K[:, 4:]
    ctrl, clsys = ct.create_statefbk_iosystem(sys_, K, integral_action=C_int)
    np.testing.assert_array_almost_equal(ctrl.A, np.zeros((2, 2)))
    np.testing.assert_array_almost_equal(ctrl.B, np.block([[-C_int, np.zeros((2, 2)), C_int]]))
    np.testing.assert_array_almost_equal(ctrl.C, -Ki)
    np.testing.assert_array_almost_equal(ctrl.D, np.block([[Kp, np.eye(2), -Kp]]))
    np.testing.assert_array_almost_equal(clsys.A, np.block([[sys_.A - sys_.B @ Kp, -sys_.B @ Ki],
                                                            [C_int, np.zeros((2, 2))]]))
    assert np.all(np.real(clsys.poles()) < 0)


def test_lqr_integral_discrete():
    """statefbk_test.py::test_lqr_integral_discrete: the same for drss (dt = True): the integrators
    are z[k+1] = z[k] + C_int x[k]."""
    np.random.seed(12)
    sys_ = ct.drss(4, 4, 2, strictly_proper=True)
    sys_.C = np.eye(4)
    C_int = np.eye(2, 4)
    K, _, _ = oc.lqr(sys_, np.eye(6), np.eye(2), integral_action=C_int)
    Kp = K[:, :4]
    ctrl, clsys = ct.create_statefbk_iosystem(sys_, K, integral_action=C_int)
    assert ct.isdtime(clsys)
    np.testing.assert_array_almost_equal(ctrl.A, np.eye(2))
    np.testing.assert_array_almost_equal(ctrl.B, np.block([[-C_int, np.zeros((2, 2)), C_int]]))
    np.testing.assert_array_almost_equal(ctrl.C, -K[:, 4:])
    np.testing.assert_array_almost_equal(ctrl.D, np.block([[Kp, np.eye(2), -Kp]]))


@pytest.mark.parametrize("rss_fun, lqr_fun", [(ct.rss, oc.lqr), (ct.drss, oc.dlqr)], ids=["lqr", "dlqr"])
def test_lqr_errors(rss_fun, lqr_fun):
    """statefbk_test.py::test_lqr_errors."""
    np.random.seed(13)
    sys_ = rss_fun(4, 4, 2, strictly_proper=True)
    with pytest.raises(ct.ControlArgument, match="must pass an array"):
        lqr_fun(sys_, np.eye(4), np.eye(2), integral_action="invalid argument")
    with pytest.raises(ct.ControlArgument, match="gain size must match"):
        lqr_fun(sys_, np.eye(4), np.eye(2), integral_action=np.eye(2, 3))
    with pytest.raises(TypeError, match="unrecognized keyword"):
        lqr_fun(sys_, np.eye(4), np.eye(2), integrator=None)


# ------------------------------------------------------------------ the native verb of the issue
def test_lqr_for_poles_takes_a_system_with_feedthrough():
    """Issue 27: lqr_for_poles refused D != 0 although LQR never uses C or D (the scipy helper's
    fix); a system with D gives the gain of the same system without it."""
    np.random.seed(14)
    sys_ = ct.rss(3, 1, 1)
    sys_.D = np.array([[0.7]])
    poles = [-1.0, -2.0, -3.0]
    res = od.lqr_for_poles(sys_, poles)
    ref = od.lqr_for_poles(ct.ss(sys_.A, sys_.B, sys_.C, 0), poles)
    np.testing.assert_allclose(res.K, ref.K, rtol=1e-8)


# ------------------------------------------------------------------ the drop-in's own error paths
def test_compat_error_paths():
    """Not stabilizable: a typed error naming the mode in primal words; an unknown keyword of lqe:
    a TypeError; too many arguments."""
    A, B = np.diag([1.0, -1.0]), np.array([[0.0], [1.0]])       # the mode at +1 is not controllable
    with pytest.raises(od.NotControllableError, match=r"lqr: \(A, B\) is not stabilizable: .*mode\(s\) 1"):
        oc.lqr(A, B, np.eye(2), np.eye(1))
    with pytest.raises(TypeError, match="unrecognized keyword"):
        oc.lqe(A, B, np.eye(2), np.eye(1), np.eye(2), solver="x")
    with pytest.raises(ct.ControlArgument, match="too many arguments"):
        oc.lqr(A, B, np.eye(2), np.eye(1), np.zeros((2, 1)), 5)
