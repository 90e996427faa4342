"""Pole regions: membership, exact signed distances, LMI and NLP forms, emptiness, sampling."""

from __future__ import annotations

import math
import pickle

import numpy as np
import pytest

from optdesign.errors import DimensionError, EmptyRegionError, NotFiniteError, ValidationError
from optdesign.regions import (
    Disk,
    Ellipse,
    HalfPlane,
    HorizontalStrip,
    Intersection,
    Region,
    Sector,
    VerticalStrip,
    region_from_dict,
    stability_region,
)

# ------------------------------------------------------------------ independent references
# Boundary samples and membership written directly from the set definitions (no library code).
R_WIN = 30.0  # unbounded boundaries are sampled out to |coordinate| <= R_WIN
H = 2e-3  # maximal spacing of boundary samples


def _line(p0: complex, p1: complex) -> np.ndarray:
    k = max(2, int(math.ceil(abs(p1 - p0) / H)) + 1)
    return np.linspace(p0, p1, k)


def _closed_curve(center: float, a: float, b: float) -> np.ndarray:
    k = int(math.ceil(2 * math.pi * max(a, b) / H)) + 1
    t = np.linspace(0.0, 2 * math.pi, k)
    return center + a * np.cos(t) + 1j * b * np.sin(t)


def boundary_samples(r: Region) -> np.ndarray:
    if isinstance(r, HalfPlane):
        return _line(complex(-r.alpha, -R_WIN), complex(-r.alpha, R_WIN))
    if isinstance(r, Disk):
        return _closed_curve(r.center, r.radius, r.radius)
    if isinstance(r, Ellipse):
        return _closed_curve(r.center, r.a, r.b)
    if isinstance(r, Sector):
        far = R_WIN * np.exp(1j * (math.pi - r.half_angle))
        return np.concatenate([_line(r.apex, r.apex + far), _line(r.apex, r.apex + far.conjugate())])
    if isinstance(r, VerticalStrip):
        return np.concatenate([_line(complex(x, -R_WIN), complex(x, R_WIN)) for x in (r.lo, r.hi)])
    if isinstance(r, HorizontalStrip):
        return np.concatenate([_line(complex(-R_WIN, y), complex(R_WIN, y)) for y in (-r.omega, r.omega)])
    if isinstance(r, Intersection):
        parts = []
        for k, m in enumerate(r.members):
            b = boundary_samples(m)
            for j, other in enumerate(r.members):
                if j != k:
                    b = b[inside(other, b, 1e-12)]
            parts.append(b)
        return np.concatenate(parts)
    raise TypeError(r)


def inside(r: Region, z: np.ndarray, eps: float = 0.0) -> np.ndarray:
    x, y = z.real, z.imag
    if isinstance(r, HalfPlane):
        return x <= -r.alpha + eps
    if isinstance(r, Disk):
        return np.abs(z - r.center) <= r.radius + eps
    if isinstance(r, Ellipse):
        return ((x - r.center) / r.a) ** 2 + (y / r.b) ** 2 <= 1 + eps
    if isinstance(r, Sector):
        return np.abs(y) <= math.tan(r.half_angle) * (r.apex - x) + eps
    if isinstance(r, VerticalStrip):
        return (r.lo - eps <= x) & (x <= r.hi + eps)
    if isinstance(r, HorizontalStrip):
        return np.abs(y) <= r.omega + eps
    if isinstance(r, Intersection):
        return np.all([inside(m, z, eps) for m in r.members], axis=0)
    raise TypeError(r)


def brute_distance(r: Region, z: np.ndarray) -> np.ndarray:
    """Signed distance from a boundary discretization: |.| in [exact, exact + H]."""
    b = boundary_samples(r)
    d = np.array([np.min(np.abs(b - zi)) for zi in z])
    return np.where(inside(r, z), -d, d)


BASIC = [
    HalfPlane(1.0),
    HalfPlane(-0.5),
    HalfPlane(0.0),
    Disk(-2.0, 1.5),
    Disk(0.5, 0.7),
    Sector(math.pi / 4),
    Sector(0.3, apex=-1.0),
    Sector.from_damping(0.5),
    VerticalStrip(-3.0, -1.0),
    HorizontalStrip(1.2),
    Ellipse(-1.0, 2.0, 0.6),
    Ellipse(0.5, 0.4, 1.5),
    Ellipse(-1.0, 1.0, 1.0),
]

INTERSECTIONS = [
    HalfPlane(1.0) & Disk(-2.0, 1.5),
    HalfPlane(0.5) & Sector(math.pi / 4) & Disk(0.0, 3.0),
    Sector(0.6) & VerticalStrip(-3.0, -0.5),
    Sector(0.8, apex=-0.5) & HorizontalStrip(0.7),
    Disk(-1.0, 1.5) & Disk(0.0, 1.2),
    Ellipse(-1.0, 2.5, 0.8) & Disk(0.0, 1.5),
    Ellipse(-1.0, 2.5, 0.8) & Sector(0.5) & HalfPlane(0.2),
    Ellipse(-1.0, 1.0, 2.0) & Ellipse(-0.5, 2.0, 0.5),
    VerticalStrip(-2.0, 1.0) & HorizontalStrip(0.5) & Disk(-0.5, 1.4),
    HalfPlane(1.0) & VerticalStrip(-3.0, -1.0),  # coincident boundary lines
    Disk(-1.0, 1.0) & Disk(-1.0, 2.0),  # concentric: one member redundant
]

ALL = BASIC + INTERSECTIONS


def _points(rng: np.random.Generator, k: int, box: float = 4.0) -> np.ndarray:
    return rng.uniform(-box, box, k) + 1j * rng.uniform(-box, box, k)


# ------------------------------------------------------------------ known values
def test_halfplane_known_points():
    r = HalfPlane(1.0)
    np.testing.assert_allclose(r.distance([-3.0, 5j, -1 + 7j]), [-2.0, 1.0, 0.0])
    assert r.contains([-1.0, -1 + 1e-10, -2 + 3j, -2 - 3j])
    assert not r.contains([-1 + 1e-8])
    assert r.contains([-1 + 1e-8], tol=1e-7)
    assert HalfPlane(-2.0).distance(1.0)[0] == pytest.approx(-1.0)
    assert r.margin([-3, -1.5]) == pytest.approx(-0.5)
    assert r.margin([]) == -math.inf and r.contains([])


def test_disk_known_points():
    r = Disk(-2.0, 1.5)
    np.testing.assert_allclose(r.distance([-2.0, 1.0, -2 + 3j, -0.5]), [-1.5, 1.5, 1.5, 0.0], atol=1e-15)
    assert r.contains([-2 + 1j, -2 - 1j]) and not r.contains([0.0])
    assert Disk(1 + 0j, 2).center == 1.0  # complex with zero imaginary part is accepted
    u = Disk.unit()
    assert (u.center, u.radius) == (0.0, 1.0)
    assert Disk.unit(0.8).contains([0.79, 0.5j]) and not Disk.unit(0.8).contains([0.81])


def test_sector_known_points():
    r = Sector(math.pi / 4)
    s = math.sqrt(0.5)
    # inside on the axis; the apex region (right half-plane) measures to the apex; above: to the ray
    np.testing.assert_allclose(
        r.distance([-1.0, 1.0, 1j, -1 + 1j, 3 - 1j, 3 - 4j]),
        [-s, 1.0, s, 0.0, math.sqrt(10), 7 * s],
        atol=1e-15,
    )
    z = Sector.from_damping(0.5)
    assert z.half_angle == pytest.approx(math.pi / 3) and z.damping == pytest.approx(0.5)

    def pole(zeta, wn=2.0):
        return [wn * complex(-zeta, math.sqrt(1 - zeta**2)), wn * complex(-zeta, -math.sqrt(1 - zeta**2))]

    assert z.contains(pole(0.6)) and z.contains(pole(0.5)) and not z.contains(pole(0.4))
    shifted = Sector(math.pi / 4, apex=-1.0)
    np.testing.assert_allclose(shifted.distance([-2.0, 0.0, -2 + 1j]), [-s, 1.0, 0.0], atol=1e-15)


def test_strips_and_ellipse_known_points():
    v = VerticalStrip(-3.0, -1.0)
    np.testing.assert_allclose(v.distance([-2.0, 0.0, -2.5 + 100j, -4.0]), [-1.0, 1.0, -0.5, 1.0])
    h = HorizontalStrip(2.0)
    np.testing.assert_allclose(h.distance([5 + 1j, 3j, -7 - 2j]), [-1.0, 1.0, 0.0])
    e = Ellipse(-1.0, 2.0, 0.5)
    # centre: nearest boundary point is the end of the minor axis; outside on both axes
    np.testing.assert_allclose(e.distance([-1.0, 2.0, -1 + 1.5j, -3.0]), [-0.5, 1.0, 1.0, 0.0], atol=1e-12)
    # a point on the major axis near the centre: its nearest boundary point is off the axis
    # (closed form x = a^2 u / (a^2 - b^2)): distance b sqrt(1 - u^2 / (a^2 - b^2))
    u, a, b = 0.3, 2.0, 0.5
    assert e.distance(-1 + u)[0] == pytest.approx(-b * math.sqrt(1 - u**2 / (a**2 - b**2)), rel=1e-12)


def test_intersection_known_points():
    r = HalfPlane(1.0) & Disk(-2.0, 1.5)
    # inside: clearance to the nearer member boundary; outside: to the nearest point of the intersection
    np.testing.assert_allclose(
        r.distance([-2.0, 0.0, 3j, 2j, -1 + 5j]),
        # 3j: nearest point on the arc; 2j: the corner (-1, sqrt(1.25)); -1+5j: the arc again
        [-1.0, 1.0, math.sqrt(13) - 1.5, math.sqrt(1 + (2 - math.sqrt(1.25)) ** 2), math.sqrt(26) - 1.5],
        rtol=1e-12,
    )
    assert r.contains([-1.5 + 1j, -1.5 - 1j]) and not r.contains([-0.75])
    assert r.bounded and not (HalfPlane(1.0) & VerticalStrip(-3, 0)).bounded
    assert (Sector(0.5) & VerticalStrip(-3, -1)).bounded and not (Sector(0.5) & HalfPlane(1)).bounded


# ------------------------------------------------------------------ exact distances
@pytest.mark.parametrize("region", ALL, ids=repr)
def test_distance_is_exact_against_boundary_discretization(region):
    rng = np.random.default_rng(7)
    z = _points(rng, 60)
    # include points right next to the boundary and corners
    jitter = 1e-3 * (rng.standard_normal(10) + 1j * rng.standard_normal(10))
    z = np.concatenate([z, region.project(z[:10]) + jitter])
    d = region.distance(z)
    ref = brute_distance(region, z)
    assert np.all(np.sign(d) == np.sign(ref)) or np.all(np.abs(d[np.sign(d) != np.sign(ref)]) < 1e-12)
    # the discretization never under-estimates |distance|, and over-estimates it by at most H
    # (H/2 along a smooth arc; up to H next to a corner, where the retained samples stop short)
    assert np.all(np.abs(ref) >= np.abs(d) - 1e-9), np.max(np.abs(d) - np.abs(ref))
    assert np.all(np.abs(ref) <= np.abs(d) + H + 1e-9), np.max(np.abs(ref) - np.abs(d))


def test_distance_exact_on_random_intersections():
    """Random nonempty intersections of every shape against the boundary discretization."""
    rng = np.random.default_rng(99)
    makers = [
        lambda: HalfPlane(rng.uniform(-2, 2)),
        lambda: Disk(rng.uniform(-3, 1), rng.uniform(0.5, 2.5)),
        lambda: Sector(rng.uniform(0.2, 1.3), apex=rng.uniform(-2, 1)),
        lambda: VerticalStrip(*np.sort(rng.uniform(-4, 2, 2))),
        lambda: HorizontalStrip(rng.uniform(0.2, 2)),
        lambda: Ellipse(rng.uniform(-3, 1), rng.uniform(0.5, 2.5), rng.uniform(0.5, 2.5)),
    ]
    tested = 0
    while tested < 25:
        try:
            r = Intersection(*[makers[k]() for k in rng.integers(0, len(makers), rng.integers(2, 5))])
        except EmptyRegionError:
            continue
        tested += 1
        z = _points(rng, 15)
        jitter = 1e-2 * (rng.standard_normal(15) + 1j * rng.standard_normal(15))
        z = np.concatenate([z, r.project(z) + jitter])
        d, ref = r.distance(z), brute_distance(r, z)
        assert np.all(np.abs(ref) >= np.abs(d) - 1e-9), r
        assert np.all(np.abs(ref) <= np.abs(d) + H + 1e-9), r
        assert np.all((d < 0) == inside(r, z)), r


@pytest.mark.parametrize(("a", "b"), [(2.0, 0.6), (0.4, 1.5), (1.0, 1.0), (3.0, 2.999)])
def test_ellipse_distance_along_normals_is_exact(a, b):
    """Points offset by delta along the boundary normal are at distance delta (to ~1e-12)."""
    e = Ellipse(-0.5, a, b)
    t = np.linspace(0.0, 2 * np.pi, 37)
    p = -0.5 + a * np.cos(t) + 1j * b * np.sin(t)
    n = np.cos(t) / a + 1j * np.sin(t) / b  # gradient direction of (x/a)^2 + (y/b)^2
    n /= np.abs(n)
    delta_in = 0.5 * min(a, b) ** 2 / max(a, b)  # below the smallest radius of curvature
    for delta in (1e-9, 1e-3, 0.7, -1e-9, -1e-3, -delta_in):
        np.testing.assert_allclose(e.distance(p + delta * n), delta, rtol=1e-9, atol=1e-13)
    np.testing.assert_allclose(e.distance(p), 0.0, atol=1e-14)


@pytest.mark.parametrize("region", ALL, ids=repr)
def test_projection_is_the_nearest_point(region):
    rng = np.random.default_rng(11)
    z = _points(rng, 200)
    p = region.project(z)
    d = region.distance(z)
    out = d > 0
    np.testing.assert_allclose(np.abs(z - p)[out], d[out], rtol=1e-9, atol=1e-12)
    assert np.all(np.abs(region.distance(p[out])) < 1e-9)  # on the boundary
    np.testing.assert_array_equal(p[~out], z[~out])


@pytest.mark.parametrize("region", ALL, ids=repr)
def test_distance_is_1_lipschitz_and_symmetric(region):
    rng = np.random.default_rng(3)
    z = _points(rng, 300)
    w = z + 0.05 * (rng.standard_normal(300) + 1j * rng.standard_normal(300))
    d_z, d_w = region.distance(z), region.distance(w)
    assert np.all(np.abs(d_z - d_w) <= np.abs(z - w) + 1e-12)
    np.testing.assert_allclose(region.distance(z.conjugate()), d_z, atol=1e-12)


# ------------------------------------------------------------------ LMI form
@pytest.mark.parametrize("region", ALL, ids=repr)
def test_lmi_characteristic_function_matches_membership(region):
    L, M = region.lmi_matrices()
    assert L.shape == M.shape and L.ndim == 2 and L.shape[0] == L.shape[1]
    assert L.dtype == float and M.dtype == float
    np.testing.assert_array_equal(L, L.T)
    rng = np.random.default_rng(5)
    z = _points(rng, 400)
    d = region.distance(z)
    clear = np.abs(d) > 1e-6
    lmax = np.array([np.linalg.eigvalsh(L + M * s + M.T * np.conj(s))[-1] for s in z])
    np.testing.assert_array_equal((lmax < 0)[clear], (d < 0)[clear])
    f = region.lmi_value(z[0])
    np.testing.assert_allclose(f, f.conj().T)


def test_intersection_lmi_is_block_diagonal():
    a, b, c = HalfPlane(1.0), Sector(0.5), Disk(-1.0, 2.0)
    L, M = (a & b & c).lmi_matrices()
    assert L.shape == (5, 5)
    blocks = (slice(0, 1), slice(1, 3), slice(3, 5))
    for (Lk, Mk), sl in zip((a.lmi_matrices(), b.lmi_matrices(), c.lmi_matrices()), blocks, strict=True):
        np.testing.assert_array_equal(L[sl, sl], Lk)
        np.testing.assert_array_equal(M[sl, sl], Mk)
    mask = np.ones((5, 5), bool)
    for sl in (slice(0, 1), slice(1, 3), slice(3, 5)):
        mask[sl, sl] = False
    assert not L[mask].any() and not M[mask].any()


def test_lmi_matrices_match_chilali_gahinet_formulas():
    # Chilali & Gahinet (1996), Section II: half-plane, disk, sector, vertical strip
    L, M = HalfPlane(2.0).lmi_matrices()
    np.testing.assert_array_equal(L, [[4.0]])
    np.testing.assert_array_equal(M, [[1.0]])
    L, M = Disk(-3.0, 1.5).lmi_matrices()
    np.testing.assert_array_equal(L, [[-1.5, 3.0], [3.0, -1.5]])
    np.testing.assert_array_equal(M, [[0.0, 1.0], [0.0, 0.0]])
    t = 0.7
    L, M = Sector(t).lmi_matrices()
    np.testing.assert_array_equal(L, np.zeros((2, 2)))
    np.testing.assert_allclose(M, [[math.sin(t), math.cos(t)], [-math.cos(t), math.sin(t)]])
    L, M = VerticalStrip(-4.0, -1.0).lmi_matrices()
    np.testing.assert_array_equal(L, np.diag([-8.0, 2.0]))
    np.testing.assert_array_equal(M, np.diag([-1.0, 1.0]))


# ------------------------------------------------------------------ NLP constraints
@pytest.mark.parametrize("region", ALL, ids=repr)
def test_constraints_numpy_and_casadi_agree_with_contains(region):
    ca = pytest.importorskip("casadi")
    rng = np.random.default_rng(9)
    z = _points(rng, 300)
    d = region.distance(z)
    clear = np.abs(d) > 1e-7
    # numpy arrays, elementwise
    g_np = np.array(region.constraints(z.real, z.imag))
    assert g_np.shape == (region.n_constraints, z.size)
    np.testing.assert_array_equal(np.all(g_np <= 0, axis=0)[clear], (d <= 0)[clear])
    # CasADi SX and MX symbols
    for sym in (ca.SX, ca.MX):
        re, im = sym.sym("re"), sym.sym("im")
        gs = region.constraints(re, im)
        assert len(gs) == region.n_constraints and all(isinstance(g, sym) for g in gs)
        fun = ca.Function("g", [re, im], [ca.vertcat(*gs)])
        g_ca = np.array(fun(z.real[None, :], z.imag[None, :]))
        np.testing.assert_allclose(g_ca, g_np, rtol=1e-12, atol=1e-12)
    # smooth: no abs / sqrt / min / max / conditionals in the expressions
    re, im = ca.SX.sym("re"), ca.SX.sym("im")
    text = " ".join(str(g) for g in region.constraints(re, im))
    for bad in ("fabs", "sqrt", "fmin", "fmax", "if_else", "?"):
        assert bad not in text
    # boundary points satisfy the constraints with equality up to rounding
    b = region.project(z[d > 0][:20])
    g_b = np.array(region.constraints(b.real, b.imag))
    assert np.all(np.max(g_b, axis=0) <= 1e-9) and np.all(np.max(g_b, axis=0) >= -1e-9)


def test_constraint_functions_are_callables():
    r = HalfPlane(1.0) & Disk(-2.0, 1.5)
    fs = r.constraint_functions()
    assert len(fs) == 2 == r.n_constraints
    assert fs[0](-3.0, 0.0) == pytest.approx(-2.0)
    assert fs[1](-2.0, 0.0) == pytest.approx(-1.5 / 2)  # ((0)^2 - 1.5^2) / (2 * 1.5)


# ------------------------------------------------------------------ emptiness
@pytest.mark.parametrize(
    ("make", "names"),
    [
        (lambda: HalfPlane(5.0) & Disk(0.0, 3.0), r"Disk\(center=0.0, radius=3.0\).*HalfPlane\(alpha=5.0\)"),
        (lambda: HalfPlane(2.0) & VerticalStrip(-1.0, 0.0), r"VerticalStrip\(lo=-1.0, hi=0.0\)"),
        (lambda: Sector(0.5) & VerticalStrip(0.5, 1.0), r"Sector\(half_angle=0.5"),
        (lambda: Sector(0.3, apex=-2.0) & Disk(0.0, 1.0), r"Sector.*apex=-2.0"),
        (lambda: Disk(0.0, 1.0) & Disk(3.0, 1.0), r"Disk\(center=3.0"),
        (lambda: Disk(0.0, 1.0) & Disk(2.0, 1.0), r"Disk\(center=2.0"),  # tangent: empty interior
        (lambda: HalfPlane(1.0) & VerticalStrip(-1.0, 0.0), r"VerticalStrip"),  # shared edge only
        (lambda: (HalfPlane(1.0) & Disk(-2.0, 1.5)) & VerticalStrip(-0.9, 0.0), r"VerticalStrip\(lo=-0.9"),
        (lambda: Ellipse(-5.0, 1.0, 3.0) & HalfPlane(6.0), r"Ellipse"),  # touch at -6 only
        (lambda: stability_region(True) & VerticalStrip(1.0, 2.0), r"Disk\(center=0.0, radius=1.0\)"),
    ],
)
def test_empty_intersections_raise(make, names):
    with pytest.raises(EmptyRegionError, match="empty interior"):
        make()
    with pytest.raises(EmptyRegionError, match=names):
        make()


def test_nonempty_intersections_construct():
    for r in (
        HalfPlane(1.0) & Disk(-2.0, 1.5),
        Sector(0.5) & VerticalStrip(-3.0, -1.0),
        Sector(0.05) & VerticalStrip(-3.0, -2.9),
        HalfPlane(2.0) & VerticalStrip(-3.0, -1.0),
        HorizontalStrip(1e-3) & Disk(100.0, 0.5),
        Sector(0.2, apex=-2.0) & Disk(-2.5, 1.0),
    ):
        x = r.interior_point()
        assert r.distance(x)[0] < 0


def test_interior_point_is_kept_per_window_without_changing_the_region():
    """A region is immutable, so its interior point is computed once per window (a region design asks
    for it once per start); the cache is not part of equality, hashing or the dict form."""
    r = HalfPlane(0.5) & Sector(0.5) & Disk(0.0, 5.0)
    fresh = HalfPlane(0.5) & Sector(0.5) & Disk(0.0, 5.0)
    x = r.interior_point()
    assert r.interior_point() == x == fresh.interior_point() and r.distance(x)[0] < 0
    wide = r.interior_point(window=50.0)
    assert r.interior_point(window=50.0) == wide == fresh.interior_point(window=50.0)
    assert r == fresh and hash(r) == hash(fresh) and r.to_dict() == fresh.to_dict()
    assert pickle.loads(pickle.dumps(r)) == r


def test_emptiness_decision_against_a_grid():
    """Random combinations: raise <=> no grid point has clearance in every member."""
    rng = np.random.default_rng(2024)
    g = np.linspace(-6, 6, 121)
    grid = (g[:, None] + 1j * g[None, :]).ravel()
    h = g[1] - g[0]
    makers = [
        lambda: HalfPlane(rng.uniform(-3, 3)),
        lambda: Disk(rng.uniform(-4, 2), rng.uniform(0.3, 2.5)),
        lambda: Sector(rng.uniform(0.1, 1.4), apex=rng.uniform(-3, 1)),
        lambda: VerticalStrip(*np.sort(rng.uniform(-5, 2, 2))),
        lambda: HorizontalStrip(rng.uniform(0.1, 2)),
        lambda: Ellipse(rng.uniform(-4, 2), rng.uniform(0.3, 2.5), rng.uniform(0.3, 2.5)),
    ]
    raised = built = 0
    for _ in range(150):
        members = [makers[k]() for k in rng.integers(0, len(makers), rng.integers(2, 4))]
        worst = np.max([m.distance(grid) for m in members], axis=0)
        try:
            r = Intersection(*members)
        except EmptyRegionError:
            raised += 1
            assert np.min(worst) > -h, members
        else:
            built += 1
            x = r.interior_point()
            assert max(m.distance(x)[0] for m in members) < 0
            # the exact distance is never below the members' worst distance (equal inside)
            d = r.distance(grid[::7])
            assert np.all(d >= worst[::7] - 1e-12)
            np.testing.assert_allclose(d[d < 0], worst[::7][d < 0])
    assert raised > 10 and built > 10  # both outcomes exercised


# ------------------------------------------------------------------ sampling
@pytest.mark.parametrize("region", ALL, ids=repr)
def test_sample_poles_conjugate_closed_and_strictly_inside(region):
    from optdesign._validate import as_poles

    for n, rf in ((0, 0.5), (1, 0.0), (4, 0.5), (7, 0.3), (6, 0.0), (5, 1.0)):
        p = region.sample_poles(n, rng=123, real_fraction=rf)
        assert p.shape == (n,) and p.dtype == complex
        if n == 0:
            continue
        np.testing.assert_array_equal(as_poles("p", p), p)  # conjugate-closed, canonical order
        assert region.margin(p) < 0
        assert np.all(inside(region, p))
        n_real = int(np.sum(p.imag == 0))
        assert abs(n_real - rf * n) <= 1 and (n - n_real) % 2 == 0
        assert np.all(np.abs(p.imag[p.imag != 0]) > 1e-6)
    np.testing.assert_array_equal(region.sample_poles(6, rng=5), region.sample_poles(6, rng=5))
    assert not np.array_equal(region.sample_poles(6, rng=5), region.sample_poles(6, rng=6))


def test_sample_poles_in_thin_and_unbounded_regions():
    thin = Sector(0.01) & Disk(-2.0, 1.5) & HorizontalStrip(1e-3)
    p = thin.sample_poles(40, rng=np.random.default_rng(0))
    assert thin.margin(p) < 0 and np.sum(p.imag != 0) == 20
    hp = HalfPlane(100.0)
    p = hp.sample_poles(10, rng=1)
    assert hp.margin(p) < 0 and np.all(p.real > -200.0 - 1e-9)  # window of size |alpha|
    p = hp.sample_poles(10, rng=1, window=5.0)
    assert np.all(p.real >= -105.0 - 1e-9)


def test_sample_poles_exact_real_count():
    """n_real fixes the pattern; the default real_fraction = 0.5 rounds to all-real poles for n = 2, 3."""
    region = HalfPlane(1.0) & Sector.from_damping(0.7) & Disk(0.0, 10.0)
    for n in (2, 3):
        assert np.all(region.sample_poles(n, rng=0).imag == 0)
    for n in range(0, 9):
        for n_real in range(n % 2, n + 1, 2):
            p = region.sample_poles(n, rng=n_real, n_real=n_real)
            assert int(np.sum(p.imag == 0)) == n_real and p.size == n
            assert region.margin(p) < 0
    # n_real overrides real_fraction
    np.testing.assert_array_equal(region.sample_poles(4, rng=3, n_real=0, real_fraction=1.0),
                                  region.sample_poles(4, rng=3, n_real=0))
    for bad in (3, -2, 6, 1.0, True):
        with pytest.raises(ValidationError, match=r"n_real must be an integer in \[0, 4\] with n - n_real"):
            region.sample_poles(4, rng=0, n_real=bad)


def test_stability_region():
    assert stability_region(False) == HalfPlane(0.0)
    assert stability_region(False, margin=0.5) == HalfPlane(0.5)
    assert stability_region(True) == Disk(0.0, 1.0)
    assert stability_region(True, margin=0.1) == Disk(0.0, 0.9)
    assert stability_region(True, margin=-0.5).radius == 1.5


# ------------------------------------------------------------------ object behaviour
def test_intersection_flattening_dedup_and_operators():
    a, b, c = HalfPlane(1.0), Sector(0.5), Disk(-1.0, 2.0)
    r = (a & b) & c
    assert r.members == (a, b, c)
    assert (a & (b & c)).members == (a, b, c)
    assert (a & a) is a
    assert (a & b & a).members == (a, b)
    assert r == Intersection(a, b, c) and hash(r) == hash(Intersection(a, b, c))
    assert repr(r) == ("Intersection(HalfPlane(alpha=1.0), Sector(half_angle=0.5, apex=0.0), "
                       "Disk(center=-1.0, radius=2.0))")
    # issue 11, item 5: these were plain TypeErrors
    with pytest.raises(ValidationError, match=r"a region can only be intersected with a region \(region & "
                                              r"region\); found int 3"):
        a & 3  # noqa: B018
    with pytest.raises(ValidationError, match="a region can only be intersected with a region"):
        3 & a  # noqa: B018
    with pytest.raises(ValidationError, match="Intersection members must be Regions; found str: 'disk'"):
        Intersection(a, "disk")
    with pytest.raises(ValidationError, match="at least one region"):
        Intersection()


def test_frozen_pickle_and_dict_roundtrip():
    r = HalfPlane(1.0) & Sector.from_damping(0.4) & Ellipse(-2.0, 3.0, 1.0)
    r.distance([5.0])  # populate cached corners
    with pytest.raises(AttributeError):
        HalfPlane(1.0).alpha = 2.0
    assert pickle.loads(pickle.dumps(r)) == r
    for reg in ALL:
        assert region_from_dict(reg.to_dict()) == reg
    assert region_from_dict({"type": "Disk", "center": -1, "radius": 2}) == Disk(-1.0, 2.0)


# ------------------------------------------------------------------ validation
@pytest.mark.parametrize(
    ("make", "exc", "match"),
    [
        (lambda: HalfPlane(float("nan")), NotFiniteError, "HalfPlane alpha must be finite"),
        (lambda: HalfPlane(math.inf), NotFiniteError, "alpha"),
        (lambda: HalfPlane("1"), ValidationError, "alpha must be a real number"),
        (lambda: HalfPlane(1j), ValidationError, "alpha must be real"),
        (lambda: Disk(-1 + 2j, 1.0), ValidationError, "Disk center must be real.*symmetric"),
        (lambda: Disk(0.0, 0.0), ValidationError, "Disk radius must be > 0"),
        (lambda: Disk(0.0, -1.0), ValidationError, "radius must be > 0; found -1.0"),
        (lambda: Disk(float("nan"), 1.0), NotFiniteError, "center must be finite"),
        (lambda: Disk.unit(0.0), ValidationError, "rho must be > 0"),
        (lambda: Sector(0.0), ValidationError, r"half_angle must be in \(0, pi/2\)"),
        (lambda: Sector(math.pi / 2), ValidationError, "half_angle"),
        (lambda: Sector(-0.1), ValidationError, "half_angle"),
        (lambda: Sector(0.5, apex=math.nan), NotFiniteError, "apex"),
        (lambda: Sector.from_damping(0.0), ValidationError, r"zeta must be in \(0, 1\)"),
        (lambda: Sector.from_damping(1.0), ValidationError, "zeta"),
        (lambda: Sector.from_damping(1.5), ValidationError, "zeta"),
        (lambda: Sector.from_damping(math.nan), NotFiniteError, "zeta"),
        (lambda: VerticalStrip(1.0, 1.0), ValidationError, "lo < hi; found lo=1.0, hi=1.0"),
        (lambda: VerticalStrip(2.0, 1.0), ValidationError, "lo < hi"),
        (lambda: VerticalStrip(-math.inf, 1.0), NotFiniteError, "lo must be finite"),
        (lambda: HorizontalStrip(0.0), ValidationError, "omega must be > 0"),
        (lambda: Ellipse(0.0, 0.0, 1.0), ValidationError, "Ellipse a must be > 0"),
        (lambda: Ellipse(0.0, 1.0, -1.0), ValidationError, "Ellipse b must be > 0"),
        (lambda: Ellipse(1j, 1.0, 1.0), ValidationError, "Ellipse center must be real"),
        (lambda: stability_region(True, margin=1.0), ValidationError, "margin must be < 1"),
        (lambda: stability_region(False, margin=math.nan), NotFiniteError, "margin"),
        (lambda: HalfPlane(1.0).contains([-2.0], tol=-1.0), ValidationError, "tol"),
        (lambda: HalfPlane(1.0).distance([complex("nan")]), NotFiniteError, "poles"),
        (lambda: HalfPlane(1.0).sample_poles(-1), ValidationError, "n must be a nonnegative integer"),
        (lambda: HalfPlane(1.0).sample_poles(2.5), ValidationError, "n must be"),
        (lambda: HalfPlane(1.0).sample_poles(3, real_fraction=1.5), ValidationError, "real_fraction"),
        (lambda: HalfPlane(1.0).sample_poles(3, window=0.0), ValidationError, "window must be > 0"),
        (lambda: region_from_dict({"type": "Blob"}), ValidationError, "unknown region type 'Blob'"),
        (lambda: region_from_dict({"type": "Disk", "center": 0.0}), ValidationError, "bad parameters"),
        (lambda: region_from_dict([1, 2]), ValidationError, "'type' key"),
        (lambda: region_from_dict({"type": "Intersection"}), ValidationError, "'members' list"),
        # issue 11, item 5: a bare TypeError (rng), a bare ValueError or a silent conversion (strings)
        (lambda: HalfPlane(1.0).sample_poles(3, rng="abc"), ValidationError,
         "sample_poles rng must be None, an integer seed >= 0 or a numpy Generator; found str 'abc'"),
        (lambda: HalfPlane(1.0).sample_poles(3, rng=1.5), ValidationError, "rng must be None, an integer"),
        (lambda: HalfPlane(1.0).lmi_value("a"), ValidationError, "s must be a numeric vector; found the "),
        (lambda: HalfPlane(1.0).lmi_value("-1"), ValidationError, "s must be a numeric vector"),
        (lambda: HalfPlane(1.0).lmi_value([1.0, 2.0]), DimensionError, "s has the wrong length: expected 1"),
        (lambda: stability_region("yes"), ValidationError, "stability_region discrete must be true or false"),
        (lambda: stability_region(False, margin="0.1"), ValidationError,
         r"stability_region margin must be a real number; found '0.1' \(a string\)"),
        (lambda: HalfPlane(True), ValidationError, r"HalfPlane alpha must be a real number; found True"),
        (lambda: HalfPlane(1.0).distance(["-1"]), ValidationError, "poles must be numeric"),
        (lambda: HalfPlane(1.0).contains([-2.0], tol="0"), ValidationError, "tol must be a real number"),
        (lambda: region_from_dict({"type": "Disk", "center": "0", "radius": 1}), ValidationError,
         "Disk center must be a real number"),
    ],
)
def test_validation_errors(make, exc, match):
    with pytest.raises(exc, match=match):
        make()
