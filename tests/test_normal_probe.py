"""The normal-closed-loop probe (``normal_closed_loop``): a gain with ``A - L C`` normal (kappa2 = 1)
and its poles in a region, and its use by the region sweep's pool (issue 13)."""

from __future__ import annotations

import numpy as np
import pytest

from optdesign import problems
from optdesign.analysis import metrics
from optdesign.design.verification import eigen_spread, kappa2_agreement_tol
from optdesign.design.well_conditioned.normal_probe import normal_closed_loop, normal_freedom
from optdesign.errors import DimensionError, NotFiniteError, ValidationError
from optdesign.regions import Disk, HalfPlane, Sector
from optdesign.studies import RegionSweepDesigner, grid

EPS = np.finfo(float).eps


def _region(alpha: float, zeta: float, radius: float = 20.0):
    return HalfPlane(alpha) & Sector.from_damping(zeta) & Disk(0.0, radius)


def _check_normal_in_region(A, C, L, region):
    """Independent checks: the poles of ``A - L C`` in the region (to the rounding of a normal matrix's
    eigenvalues), kappa2 = 1 to the accuracy of a computed kappa2, and the commutator ``X X' - X' X`` at
    the rounding of the products (``eps ||X||^2`` times a small factor)."""
    X = A - L @ C
    ev = np.linalg.eigvals(X)
    nx = np.linalg.norm(X)
    assert region.contains(ev, tol=10 * EPS * nx)
    assert metrics.kappa2(X) <= 1 + kappa2_agreement_tol(1.0, eigen_spread(X, ev))
    assert np.linalg.norm(X @ X.T - X.T @ X) <= 1e3 * EPS * nx**2


def _constructed(n, p, seed, region):
    """``A = F + L C`` with ``F = U Lambda U'`` normal, its poles region samples (one complex pair when
    ``n >= 2``), ``U``, ``L`` and ``C`` random: a normal in-region closed loop exists by construction."""
    rng = np.random.default_rng(seed)
    U = np.linalg.qr(rng.standard_normal((n, n)))[0]
    z = region.sample_poles(2, rng=rng, n_real=0)
    a, b = z[0].real, abs(z[0].imag)
    reals = region.sample_poles(n - 2, rng=rng, n_real=n - 2).real
    Lam = np.zeros((n, n))
    Lam[:2, :2] = [[a, b], [-b, a]]
    Lam[2:, 2:] = np.diag(reals)
    F = U @ Lam @ U.T
    C = rng.standard_normal((p, n))
    return F + rng.standard_normal((n, p)) @ C, C


@pytest.mark.parametrize("n, p, seed", [(3, 2, 0), (3, 2, 1), (4, 3, 2), (4, 2, 3), (5, 4, 4)])
def test_recovers_a_constructed_normal_closed_loop(n, p, seed):
    region = _region(1.0, 0.5, 20.0)
    A, C = _constructed(n, p, seed, region)
    assert normal_freedom(n, p) >= 0
    L = normal_closed_loop(A, C, region, seed=seed, random_starts=8)
    assert L is not None and L.shape == (n, p)
    _check_normal_in_region(A, C, L, region)


def test_full_output_returns_the_normal_matrix():
    region = _region(1.0, 0.5)
    A, C = _constructed(3, 2, 0, region)
    L, F = normal_closed_loop(A, C, region, seed=0, random_starts=8, full_output=True)
    np.testing.assert_allclose(A - L @ C, F, atol=1e3 * EPS * np.linalg.norm(A))


def test_none_without_freedom():
    """n = 4, p = 1: n (n + 1) / 2 - n (n - p) = 10 - 12 < 0: the probe does not search."""
    rng = np.random.default_rng(0)
    A, C = rng.standard_normal((4, 4)), rng.standard_normal((1, 4))
    assert normal_freedom(4, 1) == -2
    assert normal_closed_loop(A, C, _region(1.0, 0.5)) is None
    assert normal_closed_loop(A, C, _region(1.0, 0.5), full_output=True) == (None, None)


def test_none_where_no_normal_design_fits():
    """COMPleib DIS2 has C = [0 I]: every closed loop F = A - L C has F e1 = A e1, so F_11 = A_11 = -4.
    For a normal F, e1' F e1 lies in the numerical range of F, which for a normal matrix is the convex
    hull of its eigenvalues; so some eigenvalue has Re <= -4 <= some other's Re, and no normal closed
    loop has all its poles in Re s <= -5.  The probe must return None there (and find one at zeta 0.2
    of the same disk, where a pair at -4 +- 7.6i with one real pole fits)."""
    plant = problems.load("compleib_dis2").plant
    assert plant.A[0, 0] == -4 and np.array_equal(plant.C, [[0, 1, 0], [0, 0, 1]])
    assert normal_closed_loop(plant.A, plant.C, HalfPlane(5.0) & Disk(0.0, 20.0), random_starts=4) is None
    region = _region(1.205, 0.2)
    L = normal_closed_loop(plant.A, plant.C, region, random_starts=4)
    assert L is not None
    _check_normal_in_region(plant.A, plant.C, L, region)


def test_starts_from_a_gain_and_a_closed_loop():
    region = _region(1.0, 0.5)
    A, C = _constructed(3, 2, 5, region)
    L = normal_closed_loop(A, C, region, seed=0, random_starts=8)
    assert L is not None
    # a start at the answer: found without random starts, as a gain and as its closed loop
    for start in (L, A - L @ C):
        L2 = normal_closed_loop(A, C, region, starts=[start], random_starts=0)
        assert L2 is not None
        _check_normal_in_region(A, C, L2, region)


@pytest.mark.parametrize("kwargs, error, match", [
    ({"A": np.ones((3, 2))}, DimensionError, r"A must be square; found shape \(3, 2\)"),
    ({"C": np.ones((2, 4))}, DimensionError, r"C must be \(p, 3\) with 1 <= p <= 3; found shape \(2, 4\)"),
    ({"C": np.ones((4, 3))}, DimensionError, r"C must be \(p, 3\) with 1 <= p <= 3; found shape \(4, 3\)"),
    ({"C": [[1.0, 0, 0], [2.0, 0, 0]]}, ValidationError, r"C must have full row rank 2; found singular"),
    ({"A": np.full((3, 3), np.nan)}, NotFiniteError, r"A"),
    ({"region": "disk"}, ValidationError, r"region must be an optdesign Region; found str"),
    ({"starts": [np.ones((2, 2))]}, DimensionError,
     r"starts\[0\] must be a gain \(3, 2\) or a closed loop \(3, 3\); found shape \(2, 2\)"),
    ({"random_starts": -1}, ValidationError, r"random_starts"),
    ({"max_iter": 0}, ValidationError, r"max_iter"),
    ({"seed": "x"}, ValidationError, r"seed must be None, an integer seed >= 0 or a numpy Generator"),
])
def test_validation(kwargs, error, match):
    args = {"A": np.diag([-1.0, -2.0, -3.0]), "C": np.eye(3)[1:], "region": _region(0.5, 0.5), **kwargs}
    with pytest.raises(error, match=match):
        normal_closed_loop(args.pop("A"), args.pop("C"), args.pop("region"), **args)


def test_sweep_pool_attains_the_bound_at_grid_point_288():
    """The grid of bench_sweep_grid.py, alpha row 11 (alpha 1.205), points 286-288 (zeta 0.579-0.521):
    the pool mode's probe finds a normal closed loop (kappa2 = 1) where the default designer's chain
    stays at 1.078-1.075 and reaches 1 only at 288 (the pool without the probe: 1.071 at 288,
    benchmarks/results/sweep_grid.md)."""
    pts = grid(alpha=np.linspace(0.5, 3.0, 40), zeta=np.linspace(0.9, 0.2, 25))
    designer = RegionSweepDesigner(problem="compleib_dis2", radius=20.0, placement="pool")
    session = designer.start_chunk()
    for i in range(286, 289):
        res = session(**pts[i])
        assert res.verification.passed
    X = designer._plant().A - res.L @ designer._plant().C
    assert res.kappa2 <= 1 + kappa2_agreement_tol(1.0, eigen_spread(X, np.linalg.eigvals(X)))
    assert designer.region_for(**pts[288]).contains(np.linalg.eigvals(X), tol=1e-9 * np.linalg.norm(X))


def test_square_c_any_normal_matrix_in_the_region():
    """p = n: C invertible, every F is a closed loop (L = (A - F) C^-1); the probe returns one with
    its poles in the region."""
    rng = np.random.default_rng(7)
    A, C = rng.standard_normal((3, 3)), rng.standard_normal((3, 3))
    region = _region(2.0, 0.7)
    L = normal_closed_loop(A, C, region, seed=0)
    assert L is not None
    _check_normal_in_region(A, C, L, region)
