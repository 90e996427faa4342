"""Issue 26, item 5: set-up work counts against ``time_limit``.

At n = 5000 ``kalman``, ``kalman_for_poles``, ``is_kalman_optimal`` and ``well_conditioned_observer``
ran for minutes past ``time_limit=5``: their set-up (validation, the observability staircase, the
eigenvalues of A, a Riccati solve) came before any deadline check, and a single LAPACK call cannot be
stopped.  Now a set-up whose calibrated estimate (:func:`optdesign._deadline.dense_time_refusal`)
alone outlasts the limit is refused up front, with the estimate in the message.  The tests use
n = 600 and ``time_limit=1e-3`` (the estimates are 0.14 - 8.6 s: far above the limit on any machine,
and the calls are never started); no assertion depends on the speed of the machine.
"""

import numpy as np
import pytest

import optdesign as od
from optdesign import InverseKalmanProblem, Plant
from optdesign._deadline import (
    DENSE_N3,
    FLOPS_PER_SECOND,
    MIN_REFUSAL_SECONDS,
    Deadline,
    dense_time_estimate,
    dense_time_refusal,
)
from optdesign.engines.inverse_kalman_engine import prepare_inverse_kalman, solve_inverse_kalman
from optdesign.errors import ValidationError
from optdesign.regions import Disk, HalfPlane
from optdesign.results import Status

N = 600
TINY = 1e-3


@pytest.fixture(scope="module")
def big():
    """A stable random plant of order N, three outputs, with Q = I, R = I."""
    rng = np.random.default_rng(20261206)
    A = rng.standard_normal((N, N)) / np.sqrt(N) - 2.0 * np.eye(N)
    return Plant(A, rng.standard_normal((3, N)), Q=np.eye(N), R=np.eye(3))


def _poles():
    return -2.0 - np.arange(N) / N   # their sum is above trace(A) = -2 N: no identity answers first


def test_estimate_is_the_calibrated_cubic():
    one = dense_time_estimate([("eigvals", 100)])
    assert one == pytest.approx(DENSE_N3["eigvals"] * 1e6 / FLOPS_PER_SECOND)
    both = dense_time_estimate([("eigvals", 50), ("eig", 70)])
    assert both == pytest.approx((DENSE_N3["eigvals"] * 50**3 + DENSE_N3["eig"] * 70**3) / FLOPS_PER_SECOND)


def test_refusal_only_beyond_the_time_left_and_the_floor():
    assert dense_time_refusal([("care_qz", 5000)], Deadline(None), "x") == ""   # no limit: never refused
    assert dense_time_refusal([("care_qz", 5000)], None, "x") == ""
    # a small plant under a tiny limit is started (an overrun of at most MIN_REFUSAL_SECONDS)
    assert dense_time_estimate([("care_qz", 20)]) < MIN_REFUSAL_SECONDS
    assert dense_time_refusal([("care_qz", 20)], Deadline(1e-9), "x") == ""
    why = dense_time_refusal([("eigvals", 5000), ("eig", 5000)], Deadline(5.0), "the set-up at n = 5000")
    secs = (DENSE_N3["eigvals"] + DENSE_N3["eig"]) * 5000**3 / FLOPS_PER_SECOND   # 208 s
    assert why.startswith(f"the set-up at n = 5000 needs at least {secs:.3g} s")
    assert "calibrated" in why and "time_limit=5" in why and why.endswith("not attempted")
    assert dense_time_refusal([("eigvals", 5000)], Deadline(1e6), "x") == ""


def test_kalman_refuses_a_riccati_solve_longer_than_the_limit(big):
    """Before: the CARE (a QZ of the 2n pencil, seconds here, hours at n = 5000) ran to its end and
    the filter came back as ``time_limit`` long after the limit."""
    with pytest.raises(ValidationError, match=r"time_limit=0\.001 s cannot be kept: the scipy Riccati "
                                              r"solve at n = 600 needs at least .* s .*calibrated.*not "
                                              r"attempted"):
        od.kalman(big, time_limit=TINY)
    with pytest.raises(ValidationError, match=r"hamiltonian_schur at n = 600"):
        od.kalman(big, method="hamiltonian", time_limit=TINY)
    # kalmd refuses before its discretization (a matrix exponential of order 2n)
    with pytest.raises(ValidationError, match=r"time_limit=0\.001 s cannot be kept: the scipy Riccati"):
        od.kalmd(big, 0.1, time_limit=TINY)


def test_kalman_for_poles_answers_time_limit_at_once(big):
    res = od.kalman_for_poles(big, _poles(), time_limit=TINY)
    assert res.status == Status.TIME_LIMIT and res.L is None and not res.success
    assert "kalman_for_poles at n = 600 needs at least" in res.message and "not attempted" in res.message
    assert res.route.names == ("setup_estimate",) and res.route.answered is None
    assert res.extra["refused"] in res.message


def test_held_problem_counts_its_solve_the_same(big):
    prob = InverseKalmanProblem(big)
    res = prob.solve(_poles(), time_limit=TINY)
    assert res.status == Status.TIME_LIMIT and res.route.names == ("setup_estimate",)


def test_kalman_for_poles_still_validates_its_arguments_first(big):
    with pytest.raises(ValidationError, match="objective"):
        od.kalman_for_poles(big, _poles(), objective="bogus", time_limit=TINY)
    with pytest.raises(ValidationError, match="poles"):
        od.kalman_for_poles(big, _poles()[:-1], time_limit=TINY)


@pytest.mark.parametrize("zero_gain", [False, True])
def test_is_kalman_optimal_answers_time_limit_at_once(big, zero_gain):
    L = np.zeros((N, 3)) if zero_gain else 1e-3 * np.ones((N, 3))
    res = od.is_kalman_optimal(big, L, time_limit=TINY)
    assert res.status == Status.TIME_LIMIT and not res.optimal and res.certificate is None
    assert "is_kalman_optimal at n = 600 needs at least" in res.message
    assert ("hamiltonian_schur" in res.message) == zero_gain


@pytest.mark.parametrize("mode", ["poles", "region"])
def test_well_conditioned_observer_answers_time_limit_at_once(big, mode):
    kw = {"poles": _poles()} if mode == "poles" else {"region": HalfPlane(1.0) & Disk(0.0, 10.0)}
    res = od.well_conditioned_observer(big, time_limit=TINY, **kw)
    assert res.status == Status.TIME_LIMIT and not res.success and np.all(np.isnan(res.L))
    assert "well_conditioned_observer at n = 600 needs at least" in res.message
    assert res.route.names == ("setup_estimate",)


def test_no_limit_is_never_refused_up_front():
    """Without a limit (and with a generous one) small problems run as before."""
    plant = Plant([[0, 1], [-6, -5]], [[1, 0]], R=[[1]])
    assert od.kalman_for_poles(plant, [-5, -8], time_limit=100.0).success


def test_engine_refuses_its_quartic_resolvents():
    """The engine's spectral terms (two solves of order n per target: O(n^4), no deadline check
    inside) took 5 s of a 2 s limit at n = 300; now refused when their estimate outlasts it."""
    rng = np.random.default_rng(3)
    n = 200
    A = rng.standard_normal((n, n)) / np.sqrt(n) - 2.0 * np.eye(n)
    plant = Plant(A, rng.standard_normal((3, n)), R=np.eye(3))
    dl = Deadline(TINY)
    res = solve_inverse_kalman(prepare_inverse_kalman(plant, deadline=dl), -2.0 - np.arange(n) / n,
                               time_limit=dl)
    assert res.status == Status.TIME_LIMIT and res.L is None
    assert "resolvents at n = 200" in res.message and "n^4" in res.message
