"""The dense interior-point method for the one-output fixed-gain SDP (optdesign.engines.fixed_gain_ipm).

It is an accelerator of the Clarabel route: its optimum must be Clarabel's on well-conditioned
random families (continuous and discrete, n = 2..20), a failure must hand the design back to
Clarabel unchanged, and the designs through ``kalman_for_poles`` on the benchmark's targets must
verify and equal the Clarabel route's.
"""

from __future__ import annotations

import numpy as np
import pytest

import optdesign.engines.inverse_kalman_engine as engine
from optdesign import Plant, kalman_for_poles
from optdesign.backends.clarabel_fixed_gain import (
    CLARABEL_OPTIONS,
    family_map,
    fixed_gain_family,
    solve_fixed_gain,
    svec,
)
from optdesign.classical.riccati import filter_are
from optdesign.engines.fixed_gain_ipm import IPM_TOL, solve_fixed_gain_ipm, symmetric_basis
from optdesign.errors import RiccatiError, ValidationError

EPS = float(np.finfo(float).eps)
#: both solvers stop at a relative duality gap: their optima agree to the sum (with a margin of 10)
AGREE = 10.0 * (IPM_TOL + CLARABEL_OPTIONS["tol_gap_rel"])


def _family(seed: int, n: int, dt: float | None):
    """A well-conditioned one-output family: A ~ N(0, 1/n) (shifted stable in continuous time,
    spectral radius below 1 in discrete time), R diagonal, the gain of the Kalman filter of a
    random Q > 0."""
    rng = np.random.default_rng(seed)
    while True:
        A = rng.standard_normal((n, n)) / np.sqrt(n)
        A = A - 1.5 * np.eye(n) if dt is None else A / (1.1 * max(1.0, np.max(np.abs(np.linalg.eigvals(A)))))
        plant = Plant(A, rng.standard_normal((1, n)), dt=dt, R=np.diag(rng.uniform(0.5, 2.0, 1)))
        F = rng.standard_normal((n, n))
        try:
            are = filter_are(plant.replace(Q=F @ F.T / n))
        except RiccatiError:
            continue
        if plant.is_observable():
            break
    fam = fixed_gain_family(family_map(plant.A, plant.C, dt), are.L, np.asarray(plant.R, dtype=float))
    return plant, fam


def _bench_targets(n: int):
    """The targets of ``benchmarks/bench_inverse_kalman.py`` at (n, 1) (seed 0; drawn in its order
    (2, 1), (10, 1), (20, 1), three each; benchmarks/_common.py's plant generator)."""
    rng = np.random.default_rng(0)
    drawn = {}
    for size in (2, 10, 20):
        drawn[size] = []
        for _ in range(3):
            for _ in range(50):
                while True:
                    A = rng.standard_normal((size, size)) / np.sqrt(size)
                    plant = Plant(A, rng.standard_normal((1, size)), R=np.eye(1))
                    if plant.is_observable():
                        break
                F = rng.standard_normal((size, size)) / np.sqrt(size)
                try:
                    drawn[size].append((plant, filter_are(plant.replace(Q=F @ F.T), residual_tol=1e-6)))
                    break
                except RiccatiError:
                    continue
    return drawn[n]


@pytest.mark.parametrize("dt", [None, 0.1])
@pytest.mark.parametrize("n", [2, 3, 5, 8, 12, 16, 20])
def test_ipm_optimum_equals_clarabels(n, dt):
    _, fam = _family(100 + n, n, dt)
    ref = solve_fixed_gain(fam)
    sol, rep = solve_fixed_gain_ipm(fam)
    assert ref.native_status == "Solved"
    assert rep.converged and sol is not None, rep
    assert max(rep.primal_infeasibility, rep.dual_infeasibility, rep.gap) <= IPM_TOL
    f_ref, f_ipm = np.trace(ref.Q) / fam.scale, np.trace(sol.Q) / fam.scale
    assert abs(f_ipm - f_ref) <= AGREE * (1.0 + abs(f_ref))
    # Q PSD to the rounding of Q from P and the IPM's stopping tolerance
    P, Q = sol.P, sol.Q
    qn = float(np.linalg.norm(Q, 2))
    assert np.linalg.eigvalsh(Q)[0] >= -(IPM_TOL + 10 * n * EPS) * qn
    # the affine constraint: P C' = K (K = L R, or F^-1 L R in discrete time) and Q = Q(P)
    m = fam.map
    LR = fam.L @ fam.R
    K = LR if dt is None else np.linalg.solve(m.A - fam.L @ m.C, LR)
    assert np.linalg.norm(P @ m.C.T - K) <= 100 * n * EPS * (np.linalg.norm(P) * np.linalg.norm(m.C)
                                                            + np.linalg.norm(K))
    assert np.allclose(P, P.T, rtol=0, atol=10 * EPS * np.linalg.norm(P))
    assert np.array_equal(sol.Wdec, Q) and sol.status.is_solved and sol.native_status == "ipm: optimal"


def test_symmetric_basis_inverts_svec():
    rng = np.random.default_rng(3)
    n, m = 4, 3
    mats = [(lambda X: X + X.T)(rng.standard_normal((n, n))) for _ in range(m)]
    T = np.column_stack([svec(X) for X in mats])
    B = symmetric_basis(T, n)
    assert np.allclose(B, np.stack(mats), rtol=0, atol=10 * EPS * max(np.linalg.norm(X) for X in mats))
    # <B_i, X> = svec(B_i) . svec(X): the trace pairing the IPM uses
    X = mats[0]
    assert np.allclose(B.reshape(m, -1) @ X.ravel(), T.T @ svec(X), rtol=1e-13)


def test_ipm_that_stops_early_returns_no_solution():
    _, fam = _family(7, 6, None)
    sol, rep = solve_fixed_gain_ipm(fam, max_iter=1)
    assert sol is None and not rep.converged and rep.reason == "iteration limit"
    assert max(rep.primal_infeasibility, rep.dual_infeasibility, rep.gap) > IPM_TOL


def test_ipm_rejects_bad_arguments():
    _, fam = _family(7, 4, None)
    with pytest.raises(ValidationError, match="tol must be"):
        solve_fixed_gain_ipm(fam, tol=0.0)
    with pytest.raises(ValidationError, match=r"max_iter must be an integer >= 1; found 0"):
        solve_fixed_gain_ipm(fam, max_iter=0)


def test_ipm_refuses_non_finite_data():
    _, fam = _family(7, 4, None)
    bad = fixed_gain_family(fam.map, fam.L * np.nan, fam.R)
    sol, rep = solve_fixed_gain_ipm(bad)
    assert sol is None and rep.reason == "empty or non-finite data"


def _route(res):
    return res.extra["engine"]


@pytest.mark.parametrize("n", [10, 20])
def test_bench_targets_through_kalman_for_poles_are_verified_and_equal_the_clarabel_route(
        n, monkeypatch, general_one_output_route):
    plant, are = _bench_targets(n)[0]      # the computable target of each size (floor <= 3e-6)
    res = kalman_for_poles(plant, are.poles)
    assert res.success, res.message
    assert _route(res)["sdp"]["native"] == "ipm: optimal" and "tries" not in _route(res)
    assert _route(res)["kkt"]["passed"]
    monkeypatch.setattr(engine, "ONE_OUTPUT_IPM_MIN_DIM", 10**9)   # the Clarabel route
    ref = kalman_for_poles(plant, are.poles)
    assert ref.success and _route(ref)["sdp"]["native"] != "ipm: optimal"
    assert abs(res.objective_value - ref.objective_value) <= AGREE * (1.0 + abs(ref.objective_value))
    assert res.status == ref.status


def test_failed_ipm_falls_back_to_clarabel(monkeypatch, general_one_output_route):
    plant, are = _bench_targets(10)[1]
    ref = kalman_for_poles(plant, are.poles)
    assert _route(ref)["sdp"]["native"] == "ipm: optimal"
    real = engine.solve_fixed_gain_ipm
    monkeypatch.setattr(engine, "solve_fixed_gain_ipm", lambda fam, **kw: real(fam, max_iter=1, **kw))
    res = kalman_for_poles(plant, are.poles)
    assert "the dense IPM: iteration limit" in _route(res)["tries"]
    assert _route(res)["sdp"]["native"] == "Solved"     # Clarabel, as without the IPM
    assert res.success and res.status == ref.status
    assert abs(res.objective_value - ref.objective_value) <= AGREE * (1.0 + abs(ref.objective_value))


def test_perturbed_ipm_point_still_ends_at_the_optimum(monkeypatch, general_one_output_route):
    """The IPM point only seeds the polish: a point far off the optimum (P moved along null(C)) is
    either polished to a KKT-certified optimum or solved again -- the design is the same."""
    plant, are = _bench_targets(10)[1]
    ref = kalman_for_poles(plant, are.poles)
    real = engine.solve_fixed_gain_ipm

    def off(fam, **kw):
        sol, rep = real(fam, **kw)
        v = fam.map.N[:, 0]
        P = sol.P + 0.3 * np.linalg.norm(sol.P) * np.outer(v, v)
        Q = fam.Q_of_P(P)
        return type(sol)(sol.status, sol.native_status, P, Q, Q, None, sol.iterations, 0.0), rep

    monkeypatch.setattr(engine, "solve_fixed_gain_ipm", off)
    res = kalman_for_poles(plant, are.poles)
    assert res.success and _route(res)["kkt"]["passed"]
    assert abs(res.objective_value - ref.objective_value) <= AGREE * (1.0 + abs(ref.objective_value))


def test_uncertified_ipm_point_is_solved_again_on_clarabel(monkeypatch, general_one_output_route):
    """An IPM design whose KKT test fails is not kept: Clarabel solves the SDP as without the IPM."""
    plant, are = _bench_targets(10)[1]
    ref = kalman_for_poles(plant, are.poles)
    real = engine._kkt

    def kkt(cand):
        out = real(cand)
        return {**out, "passed": False}

    monkeypatch.setattr(engine, "_kkt", kkt)
    res = kalman_for_poles(plant, are.poles)
    assert _route(res)["sdp"]["native"] == "Solved"
    assert _route(res)["tries"] == "the dense IPM: not certified"
    assert res.success
    assert abs(res.objective_value - ref.objective_value) <= AGREE * (1.0 + abs(ref.objective_value))


def test_other_objectives_and_small_systems_do_not_use_the_ipm(general_one_output_route):
    plant, are = _bench_targets(10)[1]
    res = kalman_for_poles(plant, are.poles, objective="nearest", Q_nominal=np.eye(10))
    assert _route(res)["sdp"]["native"] != "ipm: optimal"
    small, are2 = _bench_targets(2)[0]
    assert _route(kalman_for_poles(small, are2.poles))["sdp"]["native"] != "ipm: optimal"
