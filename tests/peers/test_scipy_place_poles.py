"""scipy's own pole-placement tests, run against ``optdesign.compat.scipy.place_poles`` (issue 27).

Ported case by case from scipy's ``TestPlacePoles`` (scipy/signal/tests/test_ltisys.py, scipy main
as fetched on 2026-12-06: ``test_real``, ``test_complex``, ``test_tricky_B``, ``test_errors``): the
same matrices, poles, keyword arguments, tolerances (poles within ``rtol = atol = 1e-8`` of the
eigenvalues of ``A - B K``) and asserted properties, written anew.  29 cases; the matching of poles
here is one-to-one (an optimal assignment), stricter than scipy's helper.  Deliberate differences
are listed in docs/guide/differences.rst.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.optimize import linear_sum_assignment

from optdesign.compat.scipy import place_poles
from optdesign.errors import OptDesignError

RTOL = ATOL = 1e-8       # scipy's _assert_poles_close


def _close(P1, P2):
    """Every pole of P1 matched one-to-one to a pole of P2 within scipy's tolerances."""
    P1, P2 = np.asarray(P1, dtype=complex), np.asarray(P2, dtype=complex)
    assert P1.shape == P2.shape
    r, c = linear_sum_assignment(np.abs(P1[:, None] - P2[None, :]))
    for i, j in zip(r, c, strict=True):
        assert np.allclose([P1[i].real, P1[i].imag], [P2[j].real, P2[j].imag], RTOL, ATOL), (P1[i], P2[j])


def _check(A, B, P, **kwargs):
    """scipy's TestPlacePoles._check: the eigenvalues of A - B K against requested and computed
    poles, and the requested poles against P; plus the verification of optdesign's answer."""
    fsf = place_poles(A, B, P, **kwargs)
    eig = np.linalg.eigvals(A - B @ fsf.gain_matrix)
    _close(eig, fsf.requested_poles)
    _close(eig, fsf.computed_poles)
    _close(P, fsf.requested_poles)
    assert fsf.result.success, fsf.result.verification.summary()
    return fsf


# --------------------------------------------------------------------------- matrices of the tests
# KNV 1985, section 4, example 1 (test_real, test_tricky_B)
A_KNV = np.array([1.380, -0.2077, 6.715, -5.676, -0.5814, -4.290, 0, 0.6750, 1.067, 4.273, -6.654,
                  5.893, 0.0480, 4.273, 1.343, -2.104]).reshape(4, 4)
B_KNV = np.array([0, 5.679, 1.136, 1.136, 0, 0, -3.146, 0]).reshape(4, 2)
P_KNV = np.array([-0.2, -0.5, -5.0566, -8.6659])
# Jaulin's linearized car (test_complex, test_errors)
A_CAR = np.array([[0, 7, 0, 0], [0, 0, 0, 7 / 3.0], [0, 0, 0, 0], [0, 0, 0, 0]])
B_CAR = np.array([[0, 0], [0, 0], [1, 0], [0, 1]])
# test_complex: a Monte Carlo case where YT's rank-two update gives two null vectors
A_MC = np.array([-2148, -2902, -2267, -598, -1722, -1829, -165, -283, -2546, -167, -754, -2285, -543,
                 -1700, -584, -2978, -925, -1300, -1583, -984, -386, -2650, -764, -897, -517, -1598, 2,
                 -1709, -291, -338, -153, -1804, -1106, -1168, -867, -2297]).reshape(6, 6)
B_MC = np.array([-108, -374, -524, -1285, -1232, -161, -1204, -672, -637, -15, -483, -23, -931, -780,
                 -1245, -1129, -1290, -1502, -952, -1374, -62, -964, -930, -939, -792, -756, -1437, -491,
                 -1543, -686]).reshape(6, 5)


def _big():
    """test_complex's 11 x 11 system: ones off the diagonal, the Monte Carlo block in the corner."""
    A = np.ones((11, 11)) - np.eye(11)
    B = np.ones((11, 10)) - np.diag([1] * 10, 1)[:, 1:]
    A[:6, :6] = A_MC
    B[:6, :5] = B_MC
    return A, B


A5 = np.array([0, 7, 0, 0, 0, 0, 0, 7 / 3.0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 5, 0, 0, 0, 0, 9]).reshape(5, 5)
B5 = np.array([0, 0, 0, 0, 1, 0, 0, 1, 2, 3]).reshape(5, 2)


# --------------------------------------------------------------------------- test_real
@pytest.mark.parametrize("method", ["KNV0", "YT"])
def test_real_knv_example_1(method):
    _check(A_KNV, B_KNV, P_KNV, method=method)


def test_real_repeated_poles_up_to_rank_B():
    fsf = _check(A_KNV, B_KNV, (2, 2, 3, 3))
    assert np.isfinite(np.linalg.cond(fsf.X))      # semisimple: a finite-condition eigenbasis


# --------------------------------------------------------------------------- test_complex
def test_complex_car():
    _check(A_CAR, B_CAR, np.array([-3, -1, -2 - 1j, -2 + 1j]))


def test_complex_nearly_double_pole_at_zero():
    _check(A_CAR, B_CAR, [0 - 1e-6j, 0 + 1e-6j, -10, 10], maxiter=1000)


def test_complex_monte_carlo_6x6():
    _check(A_MC, B_MC, [-25.0 - 29.0j, -25.0 + 29.0j, 31.0 - 42.0j, 31.0 + 42.0j, 33.0 - 41.0j, 33.0 + 41.0j])


def test_complex_11x11_every_update_order():
    A, B = _big()
    _check(A, B, [-10, -20, -30, 40, 50, 60, 70, -20 - 5j, -20 + 5j, 5 + 3j, 5 - 3j])


def test_complex_10x10_real_poles_only():
    A, B = _big()
    _check(A[:-1, :-1], B[:-1, :-1], [-10, -20, -30, -40, -50, -60, -70, -80, -90, -100])


def test_complex_10x10_complex_poles_only():
    A, B = _big()
    P = [-10 + 10j, -20 + 20j, -30 + 30j, -40 + 40j, -50 + 50j, -10 - 10j, -20 - 20j, -30 - 30j, -40 - 40j,
         -50 - 50j]
    _check(A[:-1, :-1], B[:-1, :-1], P)


def test_complex_5x5_one_real_pole_runs():
    # scipy only calls place_poles here (no pole check); we check the poles as well
    _check(A5, B5, np.array([-2, -3 + 1j, -3 - 1j, -1 + 1j, -1 - 1j]))


def test_complex_5x5_odd_number_of_real_poles():
    _check(A5, B5, np.array([-2, -3, -4, -1 + 1j, -1 - 1j]))


# --------------------------------------------------------------------------- test_tricky_B
B_SQUARE = np.array([0, 5.679, 1.136, 1.136, 0, 0, -3.146, 0, 1, 2, 3, 4, 5, 6, 7, 8]).reshape(4, 4)


@pytest.mark.parametrize("P", [P_KNV, np.array((-2 + 1j, -2 - 1j, -3, -2))], ids=["real", "complex"])
def test_tricky_B_square(P):
    """rank(B) = n: X = I would do, nothing to optimize: rtol and nb_iter are NaN."""
    fsf = _check(A_KNV, B_SQUARE, P)
    assert np.isnan(fsf.rtol)
    assert np.isnan(fsf.nb_iter)


def test_tricky_B_one_column():
    """One input: the gain is unique, nothing to optimize: rtol and nb_iter are 0."""
    fsf = _check(A_KNV, B_SQUARE[:, 0].reshape(4, 1), np.array((-2 + 1j, -2 - 1j, -3, -2)))
    assert fsf.rtol == 0
    assert fsf.nb_iter == 0


# --------------------------------------------------------------------------- test_errors
A_E = np.array([0, 7, 0, 0, 0, 0, 0, 7 / 3.0, 0, 0, 0, 0, 0, 0, 0, 0]).reshape(4, 4)
B_E = np.array([0, 0, 0, 0, 1, 0, 0, 1]).reshape(4, 2)
P_E = (-2.1, -2.2, -2.3, -2.4)

ERRORS = {
    "method foo": ((A_E, B_E, P_E), {"method": "foo"}),
    "poles not 1-D": ((A_E, B_E, np.array(P_E).reshape(4, 1)), {}),
    "A not 2-D": ((A_E[:, :, np.newaxis], B_E, P_E), {}),
    "B not 2-D": ((A_E, B_E[:, :, np.newaxis], P_E), {}),
    "too many poles": ((A_E, B_E, (-2.1, -2.2, -2.3, -2.4, -3)), {}),
    "not enough poles": ((A_E, B_E, (-2.1, -2.2, -2.3)), {}),
    "rtol > 1": ((A_E, B_E, P_E), {"rtol": 42}),
    "maxiter < 1": ((A_E, B_E, P_E), {"maxiter": -42}),
    "pole repeated beyond rank(B)": ((A_E, B_E, (-2, -2, -2, -2)), {}),
    "uncontrollable": ((np.ones((4, 4)), np.ones((4, 2)), (1, 2, 3, 4)), {}),
    "complex without conjugate": ((A_E, B_E, (-2 + 1j, -2 - 1j, -2 + 3j, -2)), {}),
    "A not square": ((A_E[:, :3], B_E, (-2, -3, -4, -5)), {}),
    "B rows != A rows": ((A_E, B_E[:3, :], (-2, -3, -4, -5)), {}),
    "KNV0 with complex poles": ((A_E, B_E, (-2 + 1j, -2 - 1j, -2 + 3j, -2 - 3j)), {"method": "KNV0"}),
}


@pytest.mark.parametrize("case", list(ERRORS))
def test_errors(case):
    """scipy raises ValueError; so do we, with an optdesign error class naming the argument."""
    args, kwargs = ERRORS[case]
    with pytest.raises(ValueError) as exc:
        place_poles(*args, **kwargs)
    assert isinstance(exc.value, OptDesignError)


def test_errors_messages_speak_of_B_in_state_feedback():
    with pytest.raises(ValueError, match=r"rank\(B\) = 2") as exc:
        place_poles(A_E, B_E, (-2, -2, -2, -2))
    assert "rank(C)" not in str(exc.value)


def test_warning_when_convergence_is_not_reached():
    """rtol = 1e-16 is not met: one UserWarning saying so.  scipy runs its 42 sweeps and reports
    nb_iter == 42; the engine's last stage stops earlier, where no step decreases cond(X) (a
    nonsmooth local minimum), and reports the iterations it ran -- a documented difference
    (docs/guide/differences.rst), so nb_iter <= 42 here."""
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        fsf = place_poles(A_E, B_E, (-1, -2, -3, -4), rtol=1e-16, maxiter=42)
    assert len(w) == 1
    assert issubclass(w[-1].category, UserWarning)
    assert "Convergence was not reached" in str(w[-1].message)
    assert 0 < fsf.nb_iter <= 42 and fsf.rtol > 1e-16


def test_warning_with_maxiter_reached():
    """When the last stage does hit maxiter above rtol, scipy's own message and nb_iter == maxiter
    (rtol <= 0: scipy's way to force maxiter iterations)."""
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        fsf = place_poles(A_MC, B_MC, [-25.0 - 29.0j, -25.0 + 29.0j, 31.0 - 42.0j, 31.0 + 42.0j, 33.0 - 41.0j,
                                       33.0 + 41.0j], rtol=-1, maxiter=5)
    assert [str(x.message).splitlines()[0] for x in w] == ["Convergence was not reached after maxiter iterations."]
    assert fsf.nb_iter == 5
