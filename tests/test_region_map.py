"""The region engine's pole map (issue 28): a smooth map of the plane onto a closed convex region.

Independent checks: the image is in the region (``Region.margin``), the boundary is reached (the fold
at ``gamma r = pi / 2``), the Jacobian matches central differences, and the inverse of an interior
pole reproduces it.
"""

from __future__ import annotations

import numpy as np
import pytest

from optdesign.engines.eigenstructure_region import QuadraticConstraints, interior_of
from optdesign.engines.region_map import PoleMap
from optdesign.regions import Disk, Ellipse, HalfPlane, HorizontalStrip, Sector, VerticalStrip

REGIONS = [
    HalfPlane(0.5) & Sector.from_damping(0.5) & Disk(0.0, 5.0),
    HalfPlane(1.0),  # unbounded to the left: there the map is the identity along the ray
    Disk(0.3, 0.5),  # a discrete-time region
    Ellipse(-4.0, 3.0, 2.0) & HorizontalStrip(1.5),
    VerticalStrip(-6.0, -2.0) & Disk(-4.0, 3.0),
]


def _map(region):
    x0, rho = interior_of(region)
    return PoleMap(QuadraticConstraints(region, rho).coef, x0), rho


@pytest.mark.parametrize("region", REGIONS, ids=repr)
def test_the_image_is_in_the_region_and_reaches_its_boundary(region):
    pm, rho = _map(region)
    rng = np.random.default_rng(0)
    a, b = 5.0 * rng.standard_normal((2, 4000))
    s, w, *_ = pm.pair(a, b)
    lam = s + 1j * w
    scale = max(1.0, float(np.max(np.abs(lam))))
    assert np.max(region.distance(lam)) <= 1e-12 * scale
    # the fold: along every ray the point at gamma r = pi / 2 is on the boundary
    theta = rng.uniform(-np.pi, np.pi, 200)
    gam = pm._gauge(theta)[0]
    bounded = gam > 1e-8 / rho  # (a direction along a half-plane's edge has gamma ~ rounding)
    r = 0.5 * np.pi / gam[bounded]
    s, w, *_ = pm.pair(r * np.cos(theta[bounded]), r * np.sin(theta[bounded]))
    np.testing.assert_allclose(region.distance(s + 1j * w), 0.0, atol=1e-12 * scale)
    t = 5.0 * rng.standard_normal(500)
    lr = pm.real(t)[0]
    assert np.max(region.distance(lr + 0j)) <= 1e-12 * scale


@pytest.mark.parametrize("region", REGIONS, ids=repr)
def test_jacobian_matches_central_differences(region):
    pm, rho = _map(region)
    rng = np.random.default_rng(1)
    a, b = 3.0 * rho * rng.standard_normal((2, 300)) + 0.1 * rho
    _, _, sa, sb, wa, wb = pm.pair(a, b)
    h = 1e-6 * max(1.0, rho)
    for da, db, ds, dw in ((h, 0.0, sa, wa), (0.0, h, sb, wb)):
        s1, w1, *_ = pm.pair(a + da, b + db)
        s2, w2, *_ = pm.pair(a - da, b - db)
        # a corner's direction (a kink of the gauge) may fall between the two points: the median
        np.testing.assert_allclose(np.median(np.abs((s1 - s2) / (2 * h) - ds)), 0.0, atol=1e-7)
        np.testing.assert_allclose(np.median(np.abs((w1 - w2) / (2 * h) - dw)), 0.0, atol=1e-7)
    t = 3.0 * rho * rng.standard_normal(300)
    lr, dl = pm.real(t)
    fd = (pm.real(t + h)[0] - pm.real(t - h)[0]) / (2 * h)
    np.testing.assert_allclose(fd, dl, atol=1e-6)


@pytest.mark.parametrize("region", REGIONS, ids=repr)
def test_inverse_of_interior_poles(region):
    pm, rho = _map(region)
    rng = np.random.default_rng(2)
    lam = region.sample_poles(40, rng, real_fraction=0.0)
    up = lam[lam.imag > 0]
    up = up[region.distance(up) < -1e-6 * rho]
    s, w, *_ = pm.pair(*pm.pair_inverse(up))
    np.testing.assert_allclose(s + 1j * w, up, rtol=1e-12, atol=1e-12 * rho)
    lr = region.sample_poles(20, rng, real_fraction=1.0).real
    lr = lr[region.distance(lr + 0j) < -1e-6 * rho]
    np.testing.assert_allclose(pm.real(pm.real_inverse(lr))[0], lr, rtol=1e-12, atol=1e-12 * rho)
