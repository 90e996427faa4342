"""Numerical kernels of the pole regions: where boundary lines and conics cross, the nearest point of an
ellipse, a golden-section search.

Pure numpy/math on floats and arrays, no region classes: :mod:`optdesign.model.regions.base` uses them for
the corners of intersections and the deepest interior point, :mod:`optdesign.model.regions.shapes` for the
exact distance to an ellipse.  ``Primitive`` (the type of a boundary line or conic, below) is the
annotation they share; it is not in ``__all__`` (a type alias, not an object to document).

References
----------
D. Eberly, "Distance from a point to an ellipse, an ellipsoid, or a hyperellipsoid",
Geometric Tools, 2013 (robust bisection used by :func:`eberly_nearest`).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

__all__ = ["quad_roots", "intersect_primitives", "eberly_nearest", "golden_argmin"]

#: A boundary primitive: ("line", a, b, e) is the line a x + b y = e with a^2 + b^2 = 1;
#: ("conic", q2, q1, q0) is the curve y^2 = q2 x^2 + q1 x + q0 (circles and axis-aligned
#: ellipses centred on the real axis).  Used to find the corners of intersections.
Primitive = tuple[str, float, float, float]


def quad_roots(A: float, B: float, C: float) -> list[float]:
    """Real roots of A t^2 + B t + C = 0 (a double root counts once; degenerate -> [])."""
    s = max(abs(A), abs(B), abs(C))
    if s == 0.0:
        return []
    A, B, C = A / s, B / s, C / s
    if abs(A) < 1e-14:
        return [] if abs(B) < 1e-14 else [-C / B]
    disc = B * B - 4.0 * A * C
    if disc < 0.0:
        if disc < -1e-12:
            return []
        disc = 0.0
    q = -0.5 * (B + math.copysign(math.sqrt(disc), B))
    roots = [q / A]
    if q != 0.0:
        roots.append(C / q)
    return roots


def intersect_primitives(p: Primitive, q: Primitive) -> list[complex]:
    """Intersection points of two boundary primitives (identical or parallel ones give [])."""
    if p[0] == "conic" and q[0] == "line":
        p, q = q, p
    if p[0] == "line" and q[0] == "line":
        _, a1, b1, e1 = p
        _, a2, b2, e2 = q
        det = a1 * b2 - a2 * b1
        if abs(det) < 1e-13:
            return []
        return [complex((e1 * b2 - e2 * b1) / det, (a1 * e2 - a2 * e1) / det)]
    if p[0] == "line":  # line & conic: parametrize the line as p0 + t d, d = (-b, a)
        _, a, b, e = p
        _, q2, q1, q0 = q
        px, py, dx, dy = e * a, e * b, -b, a
        A = dy * dy - q2 * dx * dx
        B = 2.0 * py * dy - 2.0 * q2 * px * dx - q1 * dx
        C = py * py - q2 * px * px - q1 * px - q0
        return [complex(px + t * dx, py + t * dy) for t in quad_roots(A, B, C)]
    # conic & conic: y^2 = P1(x) = P2(x)
    _, a2, a1, a0 = p
    _, b2, b1, b0 = q
    out: list[complex] = []
    for x in quad_roots(a2 - b2, a1 - b1, a0 - b0):
        y2 = a2 * x * x + a1 * x + a0
        if y2 < 0.0:
            if y2 < -1e-12 * max(1.0, abs(a0), x * x):
                continue
            y2 = 0.0
        y = math.sqrt(y2)
        out.extend([complex(x, y), complex(x, -y)])
    return out


def eberly_nearest(e0: float, e1: float, y0: NDArray, y1: NDArray) -> tuple[NDArray, NDArray]:
    """Nearest point on the ellipse (x0/e0)^2 + (x1/e1)^2 = 1 to (y0, y1), first quadrant.

    ``e0 >= e1 > 0`` and ``y0, y1 >= 0`` (arrays).  Case analysis of Eberly (2013), with his
    bisection for the Lagrange parameter replaced by monotone Newton iterations.
    """
    x0 = np.empty_like(y0)
    x1 = np.empty_like(y1)
    A = (y1 > 0) & (y0 > 0)
    if np.any(A):
        r0 = (e0 / e1) ** 2
        z0 = y0[A] / e0
        z1 = y1[A] / e1
        g = z0 * z0 + z1 * z1 - 1.0
        n0 = r0 * z0
        # G(s) = (n0 / (s + r0))^2 + (z1 / (s + 1))^2 - 1 is convex and decreasing for s > -1;
        # Newton from a point left of the root (where one term equals 1, so G >= 0) increases
        # monotonically to the root (Eberly brackets the same root and bisects).
        s = np.maximum(z1 - 1.0, n0 - r0)
        for _ in range(100):
            t0 = n0 / (s + r0)
            t1 = z1 / (s + 1.0)
            G = t0 * t0 + t1 * t1 - 1.0
            dG = -2.0 * (t0 * t0 / (s + r0) + t1 * t1 / (s + 1.0))
            step = -G / dG
            s = s + step
            if np.all(np.abs(step) <= 1e-12 * np.maximum(1.0, np.abs(s))):  # quadratic: error ~ step^2
                break
        s = np.where(g == 0, 0.0, s)
        x0[A] = r0 * y0[A] / (s + r0)
        x1[A] = y1[A] / (s + 1.0)
    B = (y1 > 0) & (y0 <= 0)
    x0[B] = 0.0
    x1[B] = e1
    Cm = ~(y1 > 0)
    if np.any(Cm):
        numer = e0 * y0[Cm]
        denom = e0 * e0 - e1 * e1
        inner = numer < denom
        xde = np.where(inner, numer / denom if denom > 0 else 0.0, 1.0)
        x0[Cm] = np.where(inner, e0 * xde, e0)
        x1[Cm] = np.where(inner, e1 * np.sqrt(np.maximum(1.0 - xde * xde, 0.0)), 0.0)
    return x0, x1


def golden_argmin(f: Callable[[float], float], a: float, b: float, iters: int = 90) -> float:
    """Minimizer of a convex function on [a, b] by golden-section search (endpoints included)."""
    gr = (math.sqrt(5.0) - 1.0) / 2.0
    lo, hi = a, b
    c, d = hi - gr * (hi - lo), lo + gr * (hi - lo)
    fc, fd = f(c), f(d)
    for _ in range(iters):
        if fc <= fd:
            hi, d, fd = d, c, fc
            c = hi - gr * (hi - lo)
            fc = f(c)
        else:
            lo, c, fc = c, d, fd
            d = lo + gr * (hi - lo)
            fd = f(d)
    best = min(((f(x), x) for x in (0.5 * (lo + hi), 0.5 * (a + b), a, b)), key=lambda t: t[0])
    return best[1]
