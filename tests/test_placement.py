"""``pole_error``: the distance between two pole sets under the matching that makes it smallest."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from optdesign.classical.placement import pole_error
from optdesign.errors import DimensionError

# the poles of a discrete Kalman filter (n = 5, p = 2) and a target far from them (round 14: the
# Hungarian matching of least total distance reported 0.456 or 0.572 depending on the poles' order)
_POLES = np.array([0.43843495, 0.28634182, -0.30316111 + 0.04313126j, -0.30316111 - 0.04313126j, -0.12994895])
_TARGET = np.array([-0.75297708, -0.46889205, -0.07669769, 0.74248007, 0.8580986])


def _brute_force(a, t) -> float:
    scale = np.maximum(1.0, np.abs(t))
    return min(float(np.max(np.abs(a[list(pi)] - t) / scale)) for pi in itertools.permutations(range(a.size)))


def test_pole_error_is_the_bottleneck_value_whatever_the_order():
    ref = _brute_force(_POLES, _TARGET)
    values = {pole_error(_POLES[list(pi)], _TARGET[::-1] if k % 2 else _TARGET)
              for k, pi in enumerate(itertools.permutations(range(5)))}
    assert len(values) == 1  # 240 orders, one value
    assert values.pop() == pytest.approx(ref, rel=1e-15)
    # the least-total matching's largest distance: two values over the orders, ref the smaller
    from scipy.optimize import linear_sum_assignment

    hungarian = set()
    for pi in itertools.permutations(range(5)):
        cost = np.abs(_POLES[list(pi)][:, None] - _TARGET[None, :]) / np.maximum(1.0, np.abs(_TARGET))
        r, c = linear_sum_assignment(cost)
        hungarian.add(round(float(cost[r, c].max()), 6))
    assert len(hungarian) > 1 and min(hungarian) == pytest.approx(ref, abs=1e-6)


@pytest.mark.parametrize("seed", range(20))
def test_pole_error_against_every_matching(seed):
    """Random sets n = 1..6, real and complex, near and far from each other: the brute-force
    minimum over all n! matchings of the largest relative distance."""
    rng = np.random.default_rng(seed)
    n = 1 + seed % 6
    t = rng.standard_normal(n) * 3 + 1j * rng.standard_normal(n) * (seed % 2)
    a = t + rng.standard_normal(n) * (10.0 ** rng.uniform(-8, 1)) if seed % 3 else rng.standard_normal(n)
    assert pole_error(a, t) == pytest.approx(_brute_force(np.asarray(a, complex), t), rel=1e-15, abs=0.0)


def test_pole_error_near_a_solution_and_errors():
    t = np.array([-1.0, -2.0 + 1j, -2.0 - 1j])
    assert pole_error(t[::-1], t) == 0.0
    assert pole_error(t + 1e-9, t) == pytest.approx(1e-9, rel=1e-6)
    assert pole_error([], []) == 0.0
    with pytest.raises(DimensionError, match="3 achieved vs 2 target"):
        pole_error(t, t[:2])
