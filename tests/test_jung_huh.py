"""Seed 001 (Jung & Huh) closed forms: second-order observers and Kalman filters.

Every closed form is checked against independent linear algebra (numpy eigenvectors,
complex Schur form via optdesign.metrics, scipy's ARE solver) and against the paper's
printed values where those are right; where the paper is wrong the test asserts the
correct value and says what was printed.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.linalg import solve_continuous_are

from optdesign import metrics, problems
from optdesign.classical import (
    QRSet,
    eta_from_kappa2_2x2,
    jung_huh_eq21_printed,
    kalman_2x2_eta,
    kalman_2x2_eta_set,
    kalman_2x2_gain,
    kalman_2x2_kappa2,
    kappa2_from_eta_2x2,
    observer_2x2_eta,
    observer_2x2_gain_region,
    observer_2x2_kappa2,
    observer_2x2_poles,
    observer_2x2_stable,
)
from optdesign.errors import DimensionError, ValidationError

A1, A2 = 2.0, -1.0  # Example 1/2: A = [[0, 1], [2, -1]]


def _X(a1, a2, l1, l2):
    return np.array([[0.0, 1.0], [a1, a2]]) - np.array([[l1], [l2]]) @ np.array([[1.0, 0.0]])


# ----------------------------------------------------------------------------- eq 5-21


def test_example1_printed_kappa2_values():
    """Example 1: L = [10, 5] -> 1.59 and L = [10, 45] -> 9.12 (both printed correctly)."""
    ex = problems.load("jung_huh_ex1")
    for case in ex.references["cases_printed"]:
        l1, l2 = np.ravel(case["L"])
        k = float(observer_2x2_kappa2(A1, A2, l1, l2))
        assert k == pytest.approx(case["kappa2"], abs=0.005)
        assert k == pytest.approx(metrics.kappa2(_X(A1, A2, l1, l2)), rel=1e-12)


def test_eq21_sign_error():
    """Eq (21) prints |a1 - l2 + 1|: at L = [10, 5] that gives 0.2408, not eta = 0.4815.

    The corrected |a1 - l2 - 1| / sqrt(D) reproduces the paper's own kappa2 = 1.59 through eq (19);
    the printed numerator would give kappa2 = 1.269.  For L = [10, 45] the poles are complex and the
    printed formula is not even defined (sqrt of a negative number).
    """
    printed = float(jung_huh_eq21_printed(A1, A2, 10.0, 5.0))
    corrected = float(observer_2x2_eta(A1, A2, 10.0, 5.0))
    assert printed == pytest.approx(4 / (2 * math.sqrt(69)), rel=1e-12)  # |2 - 5 + 1| / sqrt 69
    assert corrected == pytest.approx(4 / math.sqrt(69), rel=1e-12)  # |2 - 5 - 1| / sqrt 69
    assert corrected == pytest.approx(metrics.eta(_X(A1, A2, 10.0, 5.0)), rel=1e-12)
    assert float(kappa2_from_eta_2x2(printed)) == pytest.approx(1.2693, abs=1e-3)
    with np.errstate(invalid="ignore"):
        assert math.isnan(float(jung_huh_eq21_printed(A1, A2, 10.0, 45.0)))


def test_complex_pole_case():
    """L = [10, 45]: complex poles -5.5 +- 4.770j, eta = sqrt(s^2 + (c+1)^2) / sqrt(-D) = 4.5027."""
    p = observer_2x2_poles(A1, A2, 10.0, 45.0)
    assert np.allclose(np.sort_complex(p), np.sort_complex(np.linalg.eigvals(_X(A1, A2, 10.0, 45.0))))
    assert float(observer_2x2_eta(A1, A2, 10.0, 45.0)) == pytest.approx(math.sqrt(81 + 42**2) / math.sqrt(91))
    assert float(observer_2x2_eta(A1, A2, 10.0, 45.0)) == pytest.approx(
        metrics.eta(_X(A1, A2, 10.0, 45.0)), rel=1e-12
    )


@settings(max_examples=200, deadline=None)
@given(a1=st.floats(-5, 5), a2=st.floats(-5, 5), l1=st.floats(-20, 20), l2=st.floats(-50, 50))
def test_closed_forms_match_linear_algebra(a1, a2, l1, l2):
    X = _X(a1, a2, l1, l2)
    D = (a2 + l1) ** 2 + 4 * (a1 - l2)
    if abs(D) < 1e-6 * (1 + (a2 + l1) ** 2):
        return  # (numerically) double pole: both sides are infinite or meaningless
    e = float(observer_2x2_eta(a1, a2, l1, l2))
    em = metrics.eta(X)
    if math.isfinite(em) and em < 1e6:
        assert e == pytest.approx(em, rel=1e-7)
        assert float(observer_2x2_kappa2(a1, a2, l1, l2)) == pytest.approx(metrics.kappa2(X), rel=1e-6)
    if min(abs(l1 - a2), abs(l2 - a1 - a2 * l1)) > 1e-9 * (1 + abs(a2 * l1)):  # not on the boundary
        assert observer_2x2_stable(a1, a2, l1, l2) == bool(np.all(np.linalg.eigvals(X).real < 0))


def test_eq19_and_inverse():
    eta = np.array([0.0, 0.5, 2.0, 10.0])
    k = kappa2_from_eta_2x2(eta)
    assert np.allclose(k, np.sqrt(1 + 2 * eta**2 + 2 * eta * np.sqrt(1 + eta**2)))  # eq (19) as printed
    assert np.allclose(eta_from_kappa2_2x2(k), eta)
    assert float(kappa2_from_eta_2x2(2.0)) == pytest.approx(2 + math.sqrt(5))  # "about 4.3" in the paper
    assert math.isinf(float(kappa2_from_eta_2x2(np.inf)))


def test_double_pole_is_infinite():
    # D = 0: (a2 + l1)^2 = -4 (a1 - l2); l1 = 3 -> s = 2, need c = -1 -> l2 = 3
    assert math.isinf(float(observer_2x2_eta(A1, A2, 3.0, 3.0)))


# ----------------------------------------------------------------------------- gain region (Fig. 2)


def test_gain_region_beta2_brute_force():
    """l2-intervals agree with a grid of eta (complex Schur) and stability; kappa2 <= 2 + sqrt 5 inside."""
    beta = 2.0
    l2 = np.linspace(-40, 120, 16001)
    for l1 in np.linspace(-2, 25, 28):
        iv = observer_2x2_gain_region(A1, A2, beta, l1)
        inside = np.zeros_like(l2, dtype=bool)
        for lo, hi in iv:
            inside |= (l2 >= lo) & (l2 <= hi)
        truth = (observer_2x2_eta(A1, A2, l1, l2) <= beta) & observer_2x2_stable(A1, A2, l1, l2)
        step = l2[1] - l2[0]
        # disagreements only on grid points next to an interval end
        bad = l2[inside != truth]
        ends = np.array([e for ab in iv for e in ab] + [A1 + A2 * l1])
        assert all(np.min(np.abs(ends - b)) <= 1.01 * step for b in bad)
        for lo, hi in iv:
            mid = np.linspace(lo, hi, 7)[1:-1]
            k = [metrics.kappa2(_X(A1, A2, l1, m)) for m in mid]
            assert max(k) <= 2 + math.sqrt(5) + 1e-9


def test_gain_region_contains_paper_gains():
    assert any(lo <= 5.0 <= hi for lo, hi in observer_2x2_gain_region(A1, A2, 2.0, 10.0))  # inside
    assert not any(lo <= 45.0 <= hi for lo, hi in observer_2x2_gain_region(A1, A2, 2.0, 10.0))  # outside


def test_gain_region_unstable_l1_and_bad_beta():
    assert observer_2x2_gain_region(A1, A2, 2.0, -1.0) == []  # l1 <= a2: never stable
    with pytest.raises(ValidationError, match="beta"):
        observer_2x2_gain_region(A1, A2, 0.0, 1.0)
    with pytest.raises(ValidationError, match="l1 must be finite"):
        observer_2x2_gain_region(A1, A2, 2.0, float("nan"))
    with pytest.raises(ValidationError, match="a1 must be a real number"):
        observer_2x2_eta("x", A2, 1.0, 1.0)
    with pytest.raises(ValidationError, match="l2 must be finite"):
        observer_2x2_eta(A1, A2, 1.0, np.inf)
    for bad in ("x", [10.0 + 1j], [[1.0], [1.0, 2.0]]):  # not silently cast (complex) nor a bare numpy error
        with pytest.raises(ValidationError, match="l1 must be a real number or array of real numbers"):
            observer_2x2_poles(A1, A2, bad, 5.0)
    with pytest.raises(DimensionError, match=r"l1 and l2 must broadcast together; found shapes \(2,\) and"):
        observer_2x2_stable(A1, A2, [1.0, 2.0], [1.0, 2.0, 3.0])
    with pytest.raises(ValidationError, match="q_over_r must be a real number or array"):
        kalman_2x2_gain(A1, A2, "high")


# ----------------------------------------------------------------------------- Kalman (eq 29-31)


@pytest.mark.parametrize("qr", [0.0, 0.5, 1.3, 2.0, 3.0, 10.0, 146.0, 1e4])
def test_eq29_is_the_riccati_gain(qr):
    """Eq (29) equals L = P C'/r from scipy's ARE solver (r = 1, q = q/r)."""
    A = np.array([[0.0, 1.0], [A1, A2]])
    C = np.array([[1.0, 0.0]])
    P = solve_continuous_are(A.T, C.T, np.array([[0.0, 0.0], [0.0, qr]]), np.eye(1))
    assert np.allclose(kalman_2x2_gain(A1, A2, qr), (P @ C.T).ravel(), rtol=1e-9, atol=1e-12)


def test_kalman_eta_both_cases():
    """eta(q/r) from the closed form equals the complex-Schur eta of A - L C, real and complex poles."""
    A = np.array([[0.0, 1.0], [A1, A2]])
    C = np.array([[1.0, 0.0]])
    for qr in (0.3, 1.0, 2.0, 3.0, 50.0):  # double pole at q/r = 2.25
        L = kalman_2x2_gain(A1, A2, qr).reshape(2, 1)
        assert float(kalman_2x2_eta(A1, A2, qr)) == pytest.approx(metrics.eta(A - L @ C), rel=1e-9)
        assert float(kalman_2x2_kappa2(A1, A2, qr)) == pytest.approx(metrics.kappa2(A - L @ C), rel=1e-8)
    assert float(kalman_2x2_eta(A1, A2, 2.25)) > 1e6  # double pole (exact: inf)


def test_example2_exact_qr_set_and_printed_intervals_are_wrong():
    """Exact set {q/r : eta <= 2} = [0, 1.3648] U [3.4099, 228.545].

    The paper prints q/r < 1.3 or 4 < q/r < 146.  Both upper ends are wrong: eta stays below 2 up to
    q/r = 1.3648 and again from 3.4099 to 228.545 (e.g. eta(3.5) = 1.94 and eta(200) = 1.92, both
    in the set but outside the printed intervals).  Eq (30)/(31) hold only for real poles (q/r < 2.25);
    beyond the double pole at q/r = 2.25 they are the square root of a negative number, which is
    presumably where the printed second interval went wrong.
    """
    ex = problems.load("jung_huh_ex2")
    s = kalman_2x2_eta_set(ex.data["a"], ex.data["b"], ex.targets["beta"])
    assert isinstance(s, QRSet)
    assert len(s.intervals) == 2
    (a0, a1_), (b0, b1) = s.intervals
    assert a0 == 0.0
    assert a1_ == pytest.approx(1.36480, abs=2e-5)
    assert b0 == pytest.approx(3.40993, abs=2e-5)
    assert b1 == pytest.approx(228.545, abs=2e-3)
    assert s.double_pole == pytest.approx(2.25)
    for r in s.boundary:  # each boundary is a root of eta - beta
        assert float(kalman_2x2_eta(2.0, -1.0, r)) == pytest.approx(2.0, abs=1e-9)
        # independently of eq (29) and the closed form: scipy's ARE gain, complex-Schur eta
        A = np.array([[0.0, 1.0], [2.0, -1.0]])
        C = np.array([[1.0, 0.0]])
        P = solve_continuous_are(A.T, C.T, np.diag([0.0, r]), np.eye(1))
        assert metrics.eta(A - P @ C.T @ C) == pytest.approx(2.0, rel=1e-7)
    # membership agrees with a dense grid
    x = np.geomspace(1e-3, 1e4, 4001)
    assert np.array_equal(s.contains(x), kalman_2x2_eta(2.0, -1.0, x) <= 2.0)
    printed = ex.references["qr_intervals_printed"]
    assert printed[1][1] == 146.0 and not math.isclose(b1, 146.0, rel_tol=0.1)
    assert s.contains(3.5) and s.contains(200.0)
    assert str(s).startswith("[0, 1.3648")


@settings(max_examples=25, deadline=None)
@given(a=st.floats(-3, 3), b=st.floats(-3, 3), beta=st.floats(0.5, 5))
def test_qr_set_matches_grid(a, b, beta):
    s = kalman_2x2_eta_set(a, b, beta)
    x = np.geomspace(1e-3, 1e4, 601)
    eta = kalman_2x2_eta(a, b, x)
    got = s.contains(x)
    truth = eta <= beta
    # points within 1e-6 (relative) of a boundary may go either way
    near = np.zeros_like(x, dtype=bool)
    for r in s.boundary:
        near |= np.abs(x - r) <= 1e-6 * max(1.0, r)
    assert np.array_equal(got[~near], truth[~near])


def test_kalman_errors():
    with pytest.raises(ValidationError, match="q/r"):
        kalman_2x2_gain(A1, A2, -1.0)
    with pytest.raises(ValidationError, match="beta"):
        kalman_2x2_eta_set(A1, A2, -2.0)
    with pytest.raises(ValidationError, match="b must be finite"):
        kalman_2x2_eta_set(A1, float("inf"), 2.0)


# ----------------------------------------------------------------------------- paper reproduction


@pytest.mark.slow
def test_paper001_reproduction(tmp_path):
    """Figures written; printed values that are right agree, the known errors are flagged."""
    from optdesign.studies import paper001

    rep = paper001.reproduce(tmp_path, quick=True)
    assert rep.paper == "001" and len(rep.figures) == 4
    for f in rep.figures:
        assert f.exists() and f.stat().st_size > 10_000
    rows = {(r.example, r.quantity): r for r in rep.rows}
    assert rows[("Ex. 1", "kappa2 at L = [10, 5]")].agrees
    assert rows[("Ex. 1", "kappa2 at L = [10, 45]")].agrees
    assert rows[("Ex. 1", "eta at L = [10, 5]")].agrees is False  # eq (21) sign
    assert rows[("Ex. 2", "q/r with eta <= 2")].agrees is False  # printed intervals wrong
    assert rows[("Ex. 3", "eta at L = [-1.2, 10, 10]")].agrees is False  # real Schur form
    design = [r for r in rep.rows if r.quantity.startswith("design:")]
    assert design and design[0].agrees  # beats the paper's gain
    assert "2.408" in rows[("Ex. 3", "eta at L = [-1.2, 10, 10]")].note
