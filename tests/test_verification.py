"""The shared verification helpers (:mod:`optdesign.design.verification`): the independent Riccati
re-solve by a solver other than the design's, its checks, and the violation measure that ranks
designs that all fail their checks."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import random_observable_plant

from optdesign import Plant
from optdesign.classical.riccati import filter_are
from optdesign.design.verification import (
    ARE_SOLVERS,
    check_violation,
    independent_are,
    resolve_pole_tolerance,
    riccati_checks,
)
from optdesign.errors import ValidationError
from optdesign.results import Check


@pytest.mark.parametrize("dt", [None, 0.1])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_independent_are_uses_the_solver_the_design_did_not(seed, dt):
    rng = np.random.default_rng(seed)
    plant = random_observable_plant(rng, 6, 2, noise=True)
    if dt is not None:
        plant = Plant(0.5 * plant.A, plant.C, R=plant.R, dt=dt)
    F = rng.standard_normal((6, 6))
    plant = plant.replace(G=None, Q=F @ F.T / 6)
    ref = {m: filter_are(plant, m) for m in ARE_SOLVERS}
    for avoid in ARE_SOLVERS:
        are = independent_are(plant, avoid=avoid)
        other = next(m for m in ARE_SOLVERS if m != avoid)
        assert are.method == other
        np.testing.assert_array_equal(are.P, ref[other].P)   # the same solve, nothing else
    assert independent_are(plant).method == "hamiltonian"   # default: designs from scipy's solver


@pytest.mark.parametrize("avoid", ["scipy", "hamiltonian"])
def test_riccati_checks_pass_for_an_exact_design_with_either_re_solver(avoid):
    rng = np.random.default_rng(3)
    plant = random_observable_plant(rng, 5, 1, noise=True)
    F = rng.standard_normal((5, 5))
    Q = F @ F.T / 5
    are = filter_are(plant.replace(G=None, Q=Q))
    checks, resolved, err = riccati_checks(plant, are.L, are.P, Q, avoid=avoid)
    assert resolved is not None and resolved.method != avoid
    assert {c.name for c in checks} == {"riccati_residual", "forward_error", "Q_min_eig", "P_min_eig",
                                        "are_resolve_gain"}
    assert all(c.passed for c in checks), [str(c) for c in checks if not c.passed]
    # a gain that is not the Riccati gain fails the re-solve check, whichever solver re-solves
    checks, _, _ = riccati_checks(plant, are.L * (1 + 1e-3), are.P, Q, avoid=avoid)
    gain = next(c for c in checks if c.name == "are_resolve_gain")
    assert not gain.passed and gain.value > 1e-4


def test_bad_re_solver_choice_raises():
    plant = Plant([[0.0, 1.0], [-2.0, -3.0]], [[1.0, 0.0]], R=[[1.0]], Q=np.eye(2), G=np.eye(2))
    with pytest.raises(ValidationError, match=r"avoid must be one of 'scipy', 'hamiltonian'; found 'qz'"):
        independent_are(plant, avoid="qz")
    are = filter_are(plant)
    with pytest.raises(ValidationError, match=r"avoid must be one of .*found 'QZ'"):
        riccati_checks(plant, are.L, are.P, np.eye(2), avoid="QZ")


def test_check_violation_is_zero_when_passed_and_relative_beyond_the_tolerance():
    assert check_violation(Check.at_most("x", 1e-9, 1e-8)) == 0.0
    assert check_violation(Check.at_most("x", 3e-8, 1e-8)) == pytest.approx(2.0)
    assert check_violation(Check.at_least("Q_min_eig", -1e-12, -1e-14)) == pytest.approx(99.0)
    assert check_violation(Check.at_least("stability_margin", -1.0, 1e-12)) == pytest.approx(1e12 + 1)
    assert check_violation(Check.at_most("mask", 1e-3, 0.0)) == float("inf")
    assert check_violation(Check.at_most("x", float("nan"), 1.0)) == float("inf")
    # another tolerance (an uncapped rounding floor) replaces the check's own
    assert check_violation(Check.at_most("pole_error", 1e-4, 1e-6), 1e-3) == 0.0
    assert check_violation(Check.at_most("pole_error", 1e-2, 1e-6), 1e-3) == pytest.approx(9.0)
    # ordering: a larger excess is a larger violation
    vals = [check_violation(Check.at_most("x", v, 1e-6)) for v in (2e-6, 1e-5, 1e-3)]
    assert vals == sorted(vals)


def test_resolve_pole_tolerance_covers_the_poles_of_a_nearby_gain(rng):
    """The tolerance of a second gain's poles: the first gain's pole error plus the first-order
    movement of its poles by the gain difference.  Random ill-conditioned closed loops and gain
    differences from 1e-9 to 1e-6 relative: the second gain's actual pole error is always within it,
    and the tolerance tracks it (within ESTIMATE_FACTOR + rounding); no difference, no raise."""
    from optdesign.classical.placement import pole_error
    for n in (4, 8, 12):
        for scale in (1e-9, 1e-7, 1e-6):
            A, C = rng.standard_normal((n, n)), rng.standard_normal((1, n))
            L = rng.standard_normal((n, 1)) * 10
            F = A - L @ C
            target = np.linalg.eigvals(F)
            dL = scale * np.linalg.norm(L) * rng.standard_normal((n, 1))
            err = pole_error(np.linalg.eigvals(F - dL @ C), target)
            tol = resolve_pole_tolerance(F, dL @ C, 0.0, 1e-12)
            assert err <= tol <= 1e-12 + 5.0 * max(err, 1e-12)
    F = rng.standard_normal((5, 5))
    assert resolve_pole_tolerance(F, np.zeros((5, 5)), 0.0, 1e-8) == 1e-8
    assert resolve_pole_tolerance(F, np.zeros((5, 5)), 3e-7, 1e-8) == 3e-7


def test_resolve_pole_tolerance_of_a_defective_matrix_is_not_raised():
    """A Jordan block has no eigenvector basis: no first-order movement, the tolerance as given."""
    J = np.array([[-1.0, 1.0], [0.0, -1.0]])
    assert resolve_pole_tolerance(J, 1e-6 * np.ones((2, 2)), 0.0, 1e-8) == 1e-8


def test_stability_check_of_a_defective_stable_loop_uses_henrici_bound():
    """A deadbeat discrete filter (a Jordan block at 0: python-control's ``dlqe`` on the double
    integrator with the noise on the second state) is stable by 1; the first-order rounding floor
    of a defective matrix is infinite, so the check failed and ``dlqe`` raised RiccatiError."""
    from optdesign.compat.control import dlqe
    from optdesign.design.verification import henrici_bound, stability_check

    J = np.array([[0.0, 1.0], [0.0, 0.0]])
    assert 0 < henrici_bound(J) < 1e-6          # ~ sqrt(20 eps): a 2x2 Jordan block
    assert stability_check(J, True).passed
    assert not stability_check(J + np.eye(2), True).passed      # the same block at 1: not stable
    L, P, E = dlqe(J, [[0.0], [1.0]], [[1.0, 0.0]], [[1.0]], [[0.01]])
    np.testing.assert_allclose(np.abs(E), 0.0, atol=1e-6)
    # a simple pole just inside the unit circle, far below any bound: still refused
    assert not stability_check(np.diag([1 - 1e-15, 0.2]), True).passed
