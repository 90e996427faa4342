"""Wrong or unclear answers found by independent testing (issue 11), as regression tests.

The two ``.npz`` cases are copied from ``shared/regressions/`` into ``tests/data/`` (the package
never reads ``shared`` at run time); the others are built inline.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import scipy.linalg

from optdesign import Plant, Status, is_kalman_optimal, kalman_for_poles
from optdesign.analysis.robustness import circle_condition
from optdesign.backends.status import map_status
from optdesign.classical.placement import place_observer, pole_error
from optdesign.classical.riccati import filter_are
from optdesign.errors import ValidationError

DATA = Path(__file__).parent / "data"


def _load(name):
    d = np.load(DATA / f"{name}.npz")
    return d, Plant(d["A"], d["C"], R=d["R"], dt=float(d["dt"]))


def _scipy_are(plant, Q):
    """The Kalman gain and poles of Q by scipy alone (independent of optdesign's solvers)."""
    A, C, R = plant.A, plant.C, plant.R
    if plant.is_discrete:
        P = scipy.linalg.solve_discrete_are(A.T, C.T, Q, R)
        L = A @ P @ C.T @ np.linalg.inv(C @ P @ C.T + R)
    else:
        P = scipy.linalg.solve_continuous_are(A.T, C.T, Q, R)
        L = P @ C.T @ np.linalg.inv(R)
    return L, np.linalg.eigvals(A - L @ C)


# ------------------------------------------------------------------- item 1: false infeasible
def test_feasible_badly_scaled_discrete_target_is_never_called_infeasible():
    """n 7, p 3, discrete, badly scaled; ``target`` are the poles of the Kalman filter of Q0 (a Q
    exists).  It used to run 3-4 minutes and answer ``infeasible`` (certificate ``nlp_local``:
    IPOPT at its iteration limit).  A local solver that stops proves nothing: the answer is a
    verified design or ``not_found`` -- within the time limit given."""
    d, plant = _load("inverse_kalman_false_infeasible_discrete_n7_p3")
    L0, poles0 = _scipy_are(plant, d["Q0"])
    assert pole_error(poles0, d["target"]) < 1e-6  # the target is reachable: Q0 reaches it
    res = kalman_for_poles(plant, d["target"], method="sdp", time_limit=30.0)
    assert res.status != Status.INFEASIBLE and not res.status.is_infeasible
    if res.success:
        L, poles = _scipy_are(plant, res.Q)
        assert pole_error(poles, d["target"]) <= res.verification["pole_error"].tolerance * 10
    else:
        assert res.status in (Status.NOT_FOUND, Status.TIME_LIMIT), res.message
        assert res.certificate is None
        assert "feasibility unknown" in res.message or "time limit" in res.message


def test_ipopt_local_infeasibility_is_not_a_verdict():
    assert map_status("ipopt", "Infeasible_Problem_Detected") == Status.NOT_FOUND
    assert map_status("cvxpy", "infeasible") == Status.INFEASIBLE  # a convex solver's dual certificate
    assert not Status.NOT_FOUND.is_infeasible and not Status.NOT_FOUND.is_solved


# -------------------------------------------------------------- item 2: false "not optimal"
def test_true_dare_kalman_gain_is_optimal():
    """n 8, p 2, discrete: L is the DARE gain of Q0 (min eig P = 0.865).  It used to be called not
    optimal (certificate ``gain_relation``) from an asymmetry of 3.7e-9 in C P C' -- rounding, as
    cond(A - L C) = 3e8 makes it.  Now the gain relation is judged at its rounding level and the
    badly scaled family (P from 0.87 to 1.1e7) is certified in whitened coordinates."""
    d, plant = _load("is_kalman_optimal_false_no_discrete_n8_p2")
    are = filter_are(plant.replace(Q=d["Q0"]), residual_tol=np.inf)
    res = is_kalman_optimal(plant, are.L)
    assert res.optimal and res.success, res.message
    assert res.certificate is None
    assert res.verification["gain_relation_asymmetry"].passed if "gain_relation_asymmetry" in \
        res.verification else True
    # the certificate Q is PSD and reproduces L by an independent (scipy) Riccati solve
    assert np.linalg.eigvalsh(res.Q)[0] >= -1e-9 * np.linalg.norm(res.Q, 2)
    L, _ = _scipy_are(plant, res.Q)
    assert np.linalg.norm(L - are.L) <= 1e-6 * np.linalg.norm(are.L)
    # and the frequency-domain condition (KYP) agrees independently
    assert circle_condition(plant, are.L).passed


# ------------------------------------------------------------- item 3: exact trivial answers
@pytest.mark.parametrize("dt", [None, 0.1])
def test_open_loop_poles_are_reached_by_zero_noise(rng, dt):
    """Targets = eig(A) of a stable plant: Q = 0 is exact.  It used to fail its own residual check
    (0.305 with P near 0: the normalization broke at P = 0)."""
    for _ in range(5):
        n, p = int(rng.integers(2, 6)), int(rng.integers(1, 3))
        A = rng.standard_normal((n, n))
        A = A - (np.max(np.linalg.eigvals(A).real) + 0.5) * np.eye(n) if dt is None else \
            0.9 * A / np.max(np.abs(np.linalg.eigvals(A)))
        plant = Plant(A, rng.standard_normal((p, n)), R=np.eye(p), dt=dt)
        res = kalman_for_poles(plant, np.linalg.eigvals(A))
        assert res.success, res.message
        assert np.all(res.Q == 0) and np.all(res.L == 0) and res.objective_value == 0.0
        opt = is_kalman_optimal(plant, np.zeros((n, p)))
        assert opt.optimal and opt.success and np.all(opt.Q == 0), opt.message


# ---------------------------------------------------------------- item 4: missing certificates
@pytest.mark.parametrize("dt", [None, 0.2])
def test_one_output_targets_are_decided_with_a_certificate(rng, dt):
    """One output fixes L, so every target is decided: a verified design, or ``infeasible`` with a
    certificate that holds independently (the return-difference inequality fails at that gain, or
    an identity every Kalman filter satisfies is violated).  An inaccurate SDP used to return no
    certificate at all (n = 2, p = 1)."""
    decided = {"feasible": 0, "infeasible": 0}
    for _ in range(12):
        A = rng.standard_normal((2, 2))
        if dt is not None:
            A = 1.1 * A / np.max(np.abs(np.linalg.eigvals(A)))
        plant = Plant(A, rng.standard_normal((1, 2)), R=[[1.0]], dt=dt)
        if not plant.is_observable():
            continue
        if dt is None:
            target = -rng.uniform(0.2, 4.0, 2)
        else:
            target = rng.uniform(-0.9, 0.9, 2)
        for method in ("sdp", "nlp"):
            res = kalman_for_poles(plant, target, method=method)
            if res.success:
                decided["feasible"] += 1
                continue
            assert res.status == Status.INFEASIBLE, f"{method}: {res.status} {res.message}"
            cert = res.certificate
            assert cert is not None
            if cert.kind == "return_difference":
                L = place_observer(plant, target) if np.min(np.abs(np.diff(target))) > 1e-6 else None
                if L is not None:
                    assert not circle_condition(plant, L).passed
            else:
                assert cert.kind in ("trace", "determinant", "sdp_margin", "unstable_target")
            decided["infeasible"] += 1
    assert decided["feasible"] > 0 and decided["infeasible"] > 0, decided


# --------------------------------------------------------------------------- item 9: time
def test_time_limit_is_honoured_and_loses_nothing():
    """A tiny budget: a result (never an exception), status ``time_limit`` or a verified design,
    and a typed error for a bad limit."""
    rng = np.random.default_rng(4)
    A = rng.standard_normal((6, 6)) - 3 * np.eye(6)
    plant = Plant(A, rng.standard_normal((3, 6)), R=np.eye(3))
    target = filter_are(plant.replace(Q=np.eye(6))).poles
    res = kalman_for_poles(plant, target, method="nlp", time_limit=1e-3)
    assert res.success or res.status == Status.TIME_LIMIT, res.message
    with pytest.raises(ValidationError, match="time_limit must be"):
        kalman_for_poles(plant, target, time_limit="10")
    with pytest.raises(ValidationError, match="time_limit must be"):
        is_kalman_optimal(plant, np.zeros((6, 3)), time_limit=-1)
