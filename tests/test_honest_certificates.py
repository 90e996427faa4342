"""Issue 26, item 1: no false certificates.

A frequency violation is a proof only beyond its rounding floor; a feasible inverse question gets
a design or an honest ``not_found`` (never ``unbounded``).
"""

import numpy as np
import pytest
import scipy.linalg as sla

import optdesign as od
from optdesign.analysis.frequency import return_difference_floor
from optdesign.analysis.robustness import circle_condition
from optdesign.results import Status


def _care_gain_plant(seed=2, n=60, p=5, rank_q=4):
    """A random continuous plant and scipy's CARE gain for a rank-deficient Q (issue 26: n = 60,
    p = 5, rank(Q) = 4).  Seed 2 puts the scan's minimum -2.1e-8 at omega = 3.4e-4 rad/s, where
    ||T R T*|| is 1.1e6 and sI - A is ill-conditioned: a violation inside the rounding floor."""
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n, n)) / np.sqrt(n)
    C = rng.standard_normal((p, n))
    G = rng.standard_normal((n, rank_q))
    R = np.eye(p)
    P = sla.solve_continuous_are(A.T, C.T, G @ G.T, R)
    return od.Plant(A, C, R=R), P @ C.T


def test_circle_violation_inside_rounding_floor_is_not_certain():
    plant, L = _care_gain_plant()
    circ = circle_condition(plant, L)
    assert circ.min_eigenvalue < -circ.tol  # the scan does see a (rounding) violation
    assert circ.rounding_floor > abs(circ.min_eigenvalue)
    assert not circ.violation_certain
    assert "rounding floor" in circ.message


def test_is_kalman_optimal_true_care_gain_never_infeasible():
    plant, L = _care_gain_plant()
    res = od.is_kalman_optimal(plant, L, time_limit=3)
    assert res.status != Status.INFEASIBLE
    assert res.certificate is None


def test_rounding_floor_rule_constructed():
    """The floor grows with ||T|| and the condition of sI - A: a lightly damped pole at 1e-6
    from the axis puts ||T|| ~ 1e6 at its frequency."""
    A = np.array([[-1e-6, 1.0], [-1.0, -1e-6]])
    plant = od.Plant(A, [[1.0, 0.0]], R=[[1.0]])
    L = np.array([[1.0], [0.5]])
    far = return_difference_floor(plant, L, np.eye(1), np.eye(1), 10.0)
    near = return_difference_floor(plant, L, np.eye(1), np.eye(1), 1.0)
    eps = np.finfo(float).eps
    assert far < 100 * eps
    assert near > 1e6 * far


def test_clear_violation_still_a_certificate():
    di = od.Plant([[0, 1], [0, 0]], [[1, 0]], R=[[1]])
    res = od.is_kalman_optimal(di, [[0.4], [9.04]])
    assert res.status == Status.INFEASIBLE
    assert res.certificate is not None
    assert res.circle.violation_certain


# harold (github.com/ilayn/harold), harold/_tests/test_classical_control.py::test_simple_dlqr:
# M. de Oliveira's MAE280B example, discrete with dt = 0.1; after ``H.a = H.a.T`` the design
# ``lqr(H[:, 0], block_diag(0, 0, 1e-5, 1e-5), 0.1)`` with K = [[1.71884123e-11, 0, 0, -1.79301359e-15]].
_HAROLD_A = np.array([[0, 0, 1, 0],
                      [0, 0, 0, 1],
                      [4.03428022844288e-06, 0, 0, 0.0515652322798669],
                      [0, 0, -0.000104315254033883, 0]])
_HAROLD_B = np.array([[0, 0], [1e-5 / 3, 0], [0, 0], [0, 0.01]])


def _harold_dlqr():
    A, B = _HAROLD_A.T, _HAROLD_B[:, [0]]
    Q, R = sla.block_diag(0, 0, 1e-5, 1e-5), 0.1 * np.eye(1)
    X = sla.solve_discrete_are(A, B, Q, R)
    K = np.linalg.solve(R + B.T @ X @ B, B.T @ X @ A)
    np.testing.assert_allclose(K, [[1.71884123e-11, 0, 0, -1.79301359e-15]], atol=1e-17)
    return od.Plant(A, np.eye(4), B=B, dt=0.1), np.linalg.eigvals(A - B @ K), Q, R


def test_inverse_dlqr_harold_nearest_is_a_design_not_unbounded():
    plant, poles, Q, R = _harold_dlqr()
    res = od.lqr_for_poles(plant, poles, R=R, objective="nearest", Q_nominal=Q)
    assert res.status not in (Status.UNBOUNDED, Status.INFEASIBLE)
    assert res.K is not None
    np.testing.assert_allclose(np.sort_complex(res.poles), np.sort_complex(poles), atol=1e-9)
    assert res.Q is not None and np.linalg.norm(res.Q - Q) <= 1e-9


@pytest.mark.parametrize("status", [Status.UNBOUNDED, Status.INFEASIBLE])
def test_solver_verdict_without_certificate_is_not_found(status):
    from optdesign.design.inverse_kalman.common import empty_result
    from optdesign.design.inverse_kalman.verb import honest_status
    plant = od.Plant([[0, 1], [-2, -3]], [[1, 0]], R=[[1]])
    common = dict(target_poles=np.array([-4.0, -5.0]), method="sdp", objective="nearest", structure="full",
                  plant=plant)
    res = honest_status(empty_result(common, status, "the SDP failed: clarabel: infeasible", None, None))
    assert res.status == Status.NOT_FOUND
    assert "not a certificate" in res.message


def test_is_kalman_optimal_keeps_a_short_time_limit():
    """n = 60, time_limit = 1 returned after 2.7 s (the SDP's set-up past the deadline); now the
    SDP is not started when its set-up alone would run past the limit: status time_limit, with the
    reason in the message."""
    plant, L = _care_gain_plant(seed=0)
    res = od.is_kalman_optimal(plant, L, time_limit=1)
    assert res.status == Status.TIME_LIMIT
    assert res.certificate is None
    assert "set-up" in res.message or "time limit" in res.message
    assert res.route.names[0] == "circle_condition"
