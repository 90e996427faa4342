"""Stationary Kalman filter with a delayed output (seed 002, eqs 3-19; issue 7).

Reference values for the scalar example x' = 0.5 x + w, y = x + 0.5 x(t-1) + v, q = r = 1 come from
the library itself by two independent routes that must agree (the paper prints no numbers):
Pade approximation + ARE and sampling with a shift register + DARE.  The spectral identity (19),
which uses none of the Riccati machinery, checks the whole filter including the distributed gain.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from optdesign import (
    DimensionError,
    NotPositiveDefiniteError,
    Plant,
    RiccatiError,
    ValidationError,
    kalman,
    output_delay_kalman,
    problems,
    return_difference,
)
from optdesign.design.output_delay import (
    OutputDelayKalman,
    output_delay_convergence,
    pade_delay,
)

A, C0, C1, H, Q, R = [[0.5]], [[1.0]], [[0.5]], 1.0, [[1.0]], [[1.0]]


@pytest.fixture(scope="module")
def pade():
    return output_delay_kalman(A, C0, C1, H, Q, R, method="pade")


@pytest.fixture(scope="module")
def sample():
    return output_delay_kalman(A, C0, C1, H, Q, R, method="sample")


def test_problem_library_entry_matches():
    d = problems.load("lee_output_delay_scalar").data
    np.testing.assert_array_equal(d["A"], A)
    np.testing.assert_array_equal(d["C1"], C1)
    assert d["h"] == H


def test_pade_convergence_in_the_order():
    """p0 and K0 per Pade degree (one section): errors fall by >= 10x per degree up to round-off.

    Measured: p0 = 1.4214350, 1.3807307, 1.3816602, 1.3816494, 1.38164951499, 1.38164951462
    (degrees 1..6); K0 = 1.5560961, 1.5429617, 1.5432628, 1.5432594, ...
    """
    rows = output_delay_convergence(A, C0, C1, H, Q, R, method="pade", orders=range(1, 7))
    ref = output_delay_kalman(A, C0, C1, H, Q, R, method="pade", order=5, sections=4).p0[0, 0]
    err = [abs(r.p0[0, 0] - ref) for r in rows]
    for a, b in zip(err[:-2], err[1:-1], strict=True):
        assert b < a / 10
    assert err[-1] < 1e-11
    assert rows[0].p0[0, 0] == pytest.approx(1.4214350088644, abs=1e-9)
    assert rows[-1].K0[0, 0] == pytest.approx(1.5432593802, abs=1e-9)
    assert [r.dim for r in rows] == [1 + m for m in range(1, 7)]


def test_sampling_converges_second_order_and_methods_agree():
    rows = output_delay_convergence(A, C0, C1, H, Q, R, method="sample", orders=[8, 16, 32, 64])
    ref = output_delay_convergence(A, C0, C1, H, Q, R, method="pade", orders=[7])[0].p0[0, 0]
    err = np.array([abs(r.p0[0, 0] - ref) for r in rows])
    ratios = err[:-1] / err[1:]
    np.testing.assert_allclose(ratios, 4.0, rtol=0.02)               # O(step^2)
    rich = [(4 * b.p0[0, 0] - a.p0[0, 0]) / 3 for a, b in zip(rows[:-1], rows[1:], strict=True)]
    assert abs(rich[-1] - ref) < 2e-8                                 # Richardson: O(step^4)
    assert abs(rich[-1] - ref) < abs(rich[-2] - ref) / 8


def test_default_filters_agree(pade, sample):
    assert isinstance(pade, OutputDelayKalman) and pade.success and sample.success
    assert pade.p0[0, 0] == pytest.approx(1.38164951463, abs=1e-9)
    assert sample.p0[0, 0] == pytest.approx(pade.p0[0, 0], rel=1e-6)
    assert sample.K0[0, 0] == pytest.approx(pade.K0[0, 0], rel=1e-6)
    # distributed gain K(theta) on the common grid points theta = 0, -1/4, ..., -1
    kp = pade.K_theta[:: pade.sections // 4, 0, 0]
    ks = sample.K_theta[:: (sample.K_theta.shape[0] - 1) // 4, 0, 0]
    np.testing.assert_allclose(kp, ks, rtol=1e-5)
    # eq (3)-(4) relations: K(0) = K0, p1(0) = p0 (boundary condition (8), corrected)
    np.testing.assert_array_equal(pade.K_theta[0], pade.K0)
    np.testing.assert_allclose(pade.p1[0], pade.p0, atol=1e-14)
    # K0 = (p0 c0 + p1(-h) c1) / r
    assert pade.K0[0, 0] == pytest.approx(pade.p0[0, 0] * 1.0 + pade.p1[-1][0, 0] * 0.5, rel=1e-9)
    assert pade.p0_change < 1e-6 and sample.p0_change < 1e-2
    assert "p0 =" in pade.summary()


def test_delayed_p0_between_delay_free_values(pade):
    ref = problems.load("lee_output_delay_scalar").references
    assert ref["P_h_zero"][0, 0] < pade.p0[0, 0] < ref["P_c1_zero"][0, 0]


def test_circle_condition_with_true_delay(pade, sample):
    for f in (pade, sample):
        res = f.circle_condition()
        assert res.passed
        assert res.min_eigenvalue > 0                    # no allowance for the approximation needed
        grid = f.frequency_grid()
        assert np.max(f.spectral_residual(grid)) < 3e-3   # eq (19)
    # more sections: K(theta) better resolved, eq (19) residual smaller
    coarse = output_delay_kalman(A, C0, C1, H, Q, R, method="pade", order=3, sections=4)
    fine = output_delay_kalman(A, C0, C1, H, Q, R, method="pade", order=3, sections=32)
    g = pade.frequency_grid()
    assert np.max(fine.spectral_residual(g)) < np.max(coarse.spectral_residual(g)) / 20


def test_circle_touched_at_finite_frequency_when_c1_equals_c0():
    """c1 = c0: H(jw) = c0 (1 + e^{-jwh}) / (jw - a) vanishes at w = pi/h, so |T(j pi)| = 1 (eq 19)."""
    f = output_delay_kalman(A, C0, C0, H, Q, R, method="pade", order=3, sections=16)
    res = f.circle_condition()
    assert res.passed
    assert abs(res.min_eigenvalue) <= res.tol
    T_pi = f.return_difference([math.pi])[0, 0, 0]
    assert abs(abs(T_pi) ** 2 - 1) < 1e-3
    dips = res.values[np.abs(res.omega - math.pi) < 0.05]
    assert np.min(dips) < 1e-3


def test_no_delayed_term_is_the_ordinary_kalman_filter(rng):
    n, p = 2, 2
    Am = rng.standard_normal((n, n))
    C = rng.standard_normal((p, n))
    Rm = np.diag([1.0, 2.0])
    plant = Plant(Am, C, Q=np.eye(n), R=Rm)
    kf = kalman(plant)
    for method in ("pade", "sample"):
        f = output_delay_kalman(Am, C, np.zeros((p, n)), 0.7, np.eye(n), Rm, method=method)
        tol = 1e-9 if method == "pade" else 3e-4    # sampling: O(step^4) after extrapolation
        np.testing.assert_allclose(f.p0, kf.P, rtol=tol, atol=tol * np.linalg.norm(kf.P))
        np.testing.assert_allclose(f.K0, kf.L, rtol=tol, atol=tol * np.linalg.norm(kf.L))
        w = np.array([0.0, 0.4, 3.0])
        np.testing.assert_allclose(f.return_difference(w), return_difference(plant, kf.L, w), atol=1e4 * tol)


def test_small_delay_approaches_delay_free_filter(rng):
    Am = rng.standard_normal((2, 2))
    c0, c1 = rng.standard_normal((1, 2)), rng.standard_normal((1, 2))
    P = kalman(Plant(Am, c0 + c1, Q=np.eye(2), R=[[1.0]])).P
    errs = [np.abs(output_delay_kalman(Am, c0, c1, h, np.eye(2), [[1.0]], order=3, sections=2).p0 - P).max()
            for h in (1e-2, 1e-3)]
    assert errs[1] < errs[0] / 5 and errs[1] < 1e-2


def test_two_state_two_output_methods_agree():
    rng = np.random.default_rng(5)
    Am, c0, c1 = (rng.standard_normal((2, 2)) for _ in range(3))
    Rm = np.diag([1.0, 2.0])
    fp = output_delay_kalman(Am, c0, c1, 0.7, np.eye(2), Rm, method="pade")
    fs = output_delay_kalman(Am, c0, c1, 0.7, np.eye(2), Rm, method="sample")
    assert fp.success and fs.success
    np.testing.assert_allclose(fs.p0, fp.p0, rtol=1e-6, atol=1e-8)
    np.testing.assert_allclose(fs.K0, fp.K0, rtol=1e-6, atol=1e-8)
    assert fp.circle_condition().passed


def test_guaranteed_margins_on_pade_augmented_filter(pade):
    """Theorem 2 on the rational model: A_aug - delta K_aug C_aug for delta in the guaranteed set."""
    Aa, Ca, Ka = pade.augmented
    for d in (0.51, 1.0, 10.0, 1000.0, np.exp(1j * math.radians(59)), np.exp(-1j * math.radians(59))):
        assert np.max(np.linalg.eigvals(Aa - d * Ka @ Ca).real) < 0
    both = 0.51 * np.exp(1j * math.radians(59))          # gain and phase together: not guaranteed
    assert np.max(np.linalg.eigvals(Aa - both * Ka @ Ca).real) > 0


def test_pade_delay_realization():
    for m in (1, 2, 5):
        Ap, Bp, Cp, Dp = pade_delay(0.3, m)
        w = np.array([0.1, 1.0, 5.0])
        Hp = np.array([(Cp @ np.linalg.solve(1j * x * np.eye(m) - Ap, Bp) + Dp)[0, 0] for x in w])
        np.testing.assert_allclose(np.abs(Hp), 1.0, atol=1e-12)          # all-pass
        assert abs(Hp[0] - np.exp(-1j * 0.1 * 0.3)) < 1e-4
        assert np.all(np.linalg.eigvals(Ap).real < 0)
    with pytest.raises(ValidationError, match="Pade order"):
        pade_delay(0.3, 0)
    with pytest.raises(ValidationError, match="tau must be finite and > 0"):
        pade_delay(0.0, 2)


def test_errors():
    with pytest.raises(ValidationError, match="method must be"):
        output_delay_kalman(A, C0, C1, H, Q, R, method="euler")
    with pytest.raises(ValidationError, match="order must be an integer"):
        output_delay_kalman(A, C0, C1, H, Q, R, order=0)
    with pytest.raises(ValidationError, match="order must be an integer"):
        output_delay_kalman(A, C0, C1, H, Q, R, order=2.5)
    with pytest.raises(ValidationError, match="sections must be an integer"):
        output_delay_kalman(A, C0, C1, H, Q, R, sections=True)
    with pytest.raises(ValidationError, match="sections is only used"):
        output_delay_kalman(A, C0, C1, H, Q, R, method="sample", sections=4)
    with pytest.raises(ValidationError, match="even order"):
        output_delay_kalman(A, C0, C1, H, Q, R, method="sample", order=15)
    with pytest.raises(ValidationError, match="h must be finite and > 0"):
        output_delay_kalman(A, C0, C1, 0.0, Q, R)
    with pytest.raises(DimensionError, match="C1 has the wrong shape"):
        output_delay_kalman(A, C0, [[1.0, 2.0]], H, Q, R)
    with pytest.raises(NotPositiveDefiniteError, match="R must be positive definite"):
        output_delay_kalman(A, C0, C1, H, Q, [[0.0]])
    with pytest.raises(ValidationError, match="orders must be integers"):
        output_delay_convergence(A, C0, C1, H, Q, R, orders=[1.5])
    with pytest.raises(ValidationError, match="method must be"):
        output_delay_convergence(A, C0, C1, H, Q, R, method="x", orders=[1])
    # unobservable unstable mode (nothing measured): no stabilizing solution
    for method in ("pade", "sample"):
        with pytest.raises(RiccatiError, match="no stabilizing solution"):
            output_delay_kalman([[1.0]], [[0.0]], [[0.0]], H, Q, R, method=method)


def test_bad_input_is_typed_and_named():
    # issue 11, item 5: the convergence study raised a bare LinAlgError for an undetectable system
    for method in ("pade", "sample"):
        with pytest.raises(RiccatiError, match=rf"\({method}\) has no stabilizing solution"):
            output_delay_convergence([[1.0]], [[0.0]], [[0.0]], H, Q, R, method=method, orders=[2])
    # an unhashable method was a TypeError; numbers written as strings were converted silently
    with pytest.raises(ValidationError, match=r"method must be one of 'pade', 'sample', 'sampling'; found "
                                              r"list \['pade'\]"):
        output_delay_kalman(A, C0, C1, H, Q, R, method=["pade"])
    with pytest.raises(ValidationError, match=r"h must be a real number; found '1' \(a string\)"):
        output_delay_kalman(A, C0, C1, "1", Q, R)
    with pytest.raises(ValidationError, match="order must be an integer >= 1; found '4'"):
        output_delay_kalman(A, C0, C1, H, Q, R, order="4")
    with pytest.raises(ValidationError, match="Pade order must be an integer >= 1; found '2'"):
        pade_delay(0.3, "2")
    with pytest.raises(ValidationError, match="extrapolate must be true or false; found 1"):
        output_delay_kalman(A, C0, C1, H, Q, R, method="sample", extrapolate=1)
    with pytest.raises(ValidationError, match="C0 could not be converted to an array"):
        output_delay_kalman(A, [[1.0], [1.0, 2.0]], C1, H, Q, R)
    with pytest.raises(ValidationError, match="sections must be an integer >= 1; found 1.0"):
        output_delay_convergence(A, C0, C1, H, Q, R, orders=[1], sections=1.0)
    with pytest.raises(ValidationError, match="orders must be numeric"):
        output_delay_convergence(A, C0, C1, H, Q, R, orders=["1"])
    with pytest.raises(ValidationError, match="orders must be integers >= 1 .at least one.; found none"):
        output_delay_convergence(A, C0, C1, H, Q, R, orders=[])


def test_frequency_arguments_are_validated(pade):
    with pytest.raises(ValidationError, match="omega must be numeric"):
        pade.return_difference(["1"])
    with pytest.raises(ValidationError, match=r"omega must be >= 0 \(rad/s\); found -1 at index 0"):
        pade.circle_condition([-1.0, 1.0])
    with pytest.raises(ValidationError, match="tol must be finite and >= 0; found -1"):
        pade.circle_condition(tol=-1.0)
    with pytest.raises(ValidationError, match="time_limit must be a number of seconds > 0 or None"):
        pade.circle_condition(time_limit="1")


def test_time_limit(pade):
    # the requested order is always solved; once the limit has passed, the coarser solve (the
    # convergence estimate) is skipped: status time_limit, the filter and its checks kept
    cut = output_delay_kalman(A, C0, C1, H, Q, R, method="pade", time_limit=1e-9)
    assert cut.status == "time_limit" and not cut.success and math.isnan(cut.p0_change)
    assert "time_limit" in cut.message and "no convergence estimate" in cut.message
    np.testing.assert_array_equal(cut.p0, pade.p0)
    np.testing.assert_array_equal(cut.K_theta, pade.K_theta)
    assert "p0_convergence" not in cut.verification and cut.verification["augmented_riccati_residual"].passed
    fine = output_delay_kalman(A, C0, C1, H, Q, R, method="sample", order=16, time_limit=1e-9)
    assert fine.status == "time_limit" and "no Richardson extrapolation" in fine.message
    np.testing.assert_array_equal(fine.p0, output_delay_kalman(A, C0, C1, H, Q, R, method="sample", order=16,
                                                               extrapolate=False).p0)
    same = output_delay_kalman(A, C0, C1, H, Q, R, method="pade", time_limit=3600.0)
    assert same.success and same.p0_change == pade.p0_change
    circ = pade.circle_condition(time_limit=1e-9)
    assert not circ.complete and not circ.passed and "search incomplete" in circ.message
    assert pade.circle_condition(time_limit=3600.0).passed


def test_paper002_reproduction_quick(tmp_path):
    from optdesign.studies import paper002

    rep = paper002.reproduce(tmp_path, quick=True)
    assert rep.paper == "002" and len(rep.figures) == 2
    for f in rep.figures:
        assert f.exists() and f.stat().st_size > 10_000
    disagree = {r.quantity for r in rep.rows if r.agrees is False}
    # only the known typos of the paper and eq (23) as printed (no square root) disagree
    assert disagree == {"boundary condition (8)", "Riccati equation (5)",
                        "eq (23): sigma_max(X) < sigma(R1)/sigma(R2)"}
    assert sum(r.agrees is True for r in rep.rows) >= 8
    assert "circle condition (17)" in rep.table()
