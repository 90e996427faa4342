"""Drawing pole regions: the part of a region inside a box, as a polygon, shaded on an Axes.

Every region of :mod:`optdesign.model.regions` is closed, convex and symmetric about the real axis
with a nonempty interior, and so is its intersection with a box ``[x0, x1] x [-y, y]`` that meets it.
Such a set is star-shaped about any interior point ``c``: each ray from ``c`` leaves it exactly once,
where ``max(d_region, d_box)`` changes sign (``d`` a signed distance, negative inside).  The outline
is found by bisection along ``n_rays`` rays, vectorized over the rays, using only the region's
signed distance -- so the one routine draws every shape and every intersection.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..errors import ValidationError
from .figures import new_axes

__all__ = ["region_outline", "draw_region", "region_extent", "region_label"]

#: ``(x0, x1, y0, y1)``: a rectangle of the complex plane
Box = tuple[float, float, float, float]


def region_of(region: Any) -> Any:
    from ..model.regions import Region

    if not isinstance(region, Region):
        raise ValidationError(f"region must be an optdesign Region (HalfPlane, Disk, Sector, ..., or an "
                              f"intersection a & b); found {type(region).__name__}")
    return region


def region_extent(region: Any) -> Box:
    """A box showing the region: its bounding box if bounded, else a window at its finite edges.

    The window's size comes from the region's own parameters (as for
    :meth:`~optdesign.model.regions.Region.sample_poles`), so ``HalfPlane(2)`` shows
    ``[-4, -2] x [-Y, Y]`` and the sector's apex is in view.

    Returns
    -------
    (x0, x1, y0, y1) : tuple of float
        Finite, with ``x0 < x1`` and ``y0 = -y1 < 0``.
    """
    region = region_of(region)
    xa, xb, Y, _ = region._window()
    Y = Y if math.isfinite(Y) and Y > 0 else max(xb - xa, 1.0)
    return (float(xa), float(xb), -float(Y), float(Y))


def _g(x: float) -> str:
    return f"{x:.3g}"


def _shift(c: float) -> str:
    return "s" if c == 0 else (f"s - {_g(c)}" if c > 0 else f"s + {_g(-c)}")


def region_label(region: Any) -> str:
    """A short mathematical description of a region for legends, e.g. ``Re s <= -1 and |s| <= 8``.

    Shapes it does not know (user subclasses) are described by their repr.
    """
    region = region_of(region)
    members = getattr(region, "members", None)
    if members is not None:
        return " and ".join(region_label(m) for m in members)
    name = type(region).__name__
    if name == "HalfPlane":
        return f"Re s <= {_g(-region.alpha)}"
    if name == "Disk":
        return f"|{_shift(region.center)}| <= {_g(region.radius)}"
    if name == "Sector":
        zeta = math.cos(region.half_angle)
        apex = "" if region.apex == 0 else f", apex {_g(region.apex)}"
        return f"damping >= {_g(zeta)}{apex}"
    if name == "VerticalStrip":
        return f"{_g(region.lo)} <= Re s <= {_g(region.hi)}"
    if name == "HorizontalStrip":
        return f"|Im s| <= {_g(region.omega)}"
    if name == "Ellipse":
        return f"ellipse at {_g(region.center)}, semi-axes {_g(region.a)}, {_g(region.b)}"
    return repr(region)


def _box_distance(z: NDArray[np.complexfloating], box: Box) -> NDArray[np.float64]:
    """A function with the sign of the signed distance to ``box`` (negative inside)."""
    x0, x1, y0, y1 = box
    return np.maximum.reduce([x0 - z.real, z.real - x1, y0 - z.imag, z.imag - y1])


def region_outline(region: Any, box: Box, n_rays: int = 720) -> tuple[NDArray[np.complex128], NDArray[np.bool_]]:
    """The boundary of ``region`` clipped to ``box``, as a closed polygon.

    Parameters
    ----------
    region : Region
    box : (x0, x1, y0, y1)
        The visible rectangle, ``x0 < x1``, ``y0 < 0 < y1`` (a box symmetric about the real axis, as
        the axes of a pole map are).
    n_rays : int, default 720
        Rays cast from an interior point (the polygon has this many vertices).

    Returns
    -------
    vertices : (n_rays,) ndarray of complex
        The polygon, counter-clockwise; empty when the region does not meet the box.
    on_region : (n_rays,) ndarray of bool
        Which vertices lie on the region's own boundary (the others lie on the box's edges): draw
        the region's edge through these only.

    Notes
    -----
    Each vertex is within ``1e-9`` times the box size of the true boundary along its ray (50
    bisection steps); between vertices the polygon is a chord, so curved edges are inscribed
    (error about ``r (pi / n_rays)^2 / 2`` for a circle of radius ``r``).
    """
    region = region_of(region)
    x0, x1, y0, y1 = (float(v) for v in box)
    if not (x0 < x1 and y0 < 0.0 < y1):
        raise ValidationError(f"box must be (x0, x1, y0, y1) with x0 < x1 and y0 < 0 < y1; found {box!r}")
    lo, hi = region.real_interval()
    a, b = max(lo, x0), min(hi, x1)
    if not a < b:
        return np.zeros(0, dtype=complex), np.zeros(0, dtype=bool)
    c = complex(0.5 * (a + b), 0.0)  # interior to the region (its real interval is open) and to the box
    theta = 2.0 * math.pi * np.arange(n_rays) / n_rays
    u = np.exp(1j * theta)
    size = math.hypot(x1 - x0, y1 - y0)
    box_ = (x0, x1, y0, y1)

    def f(t: NDArray[np.float64]) -> NDArray[np.float64]:
        z = c + t * u
        return np.maximum(region.distance(z), _box_distance(z, box_))

    t_in, t_out = np.zeros(n_rays), np.full(n_rays, size)  # the box's diagonal leaves the box
    for _ in range(50):
        mid = 0.5 * (t_in + t_out)
        inside = f(mid) <= 0.0
        t_in = np.where(inside, mid, t_in)
        t_out = np.where(inside, t_out, mid)
    z = c + t_in * u
    on_box = np.abs(_box_distance(z, box_)) <= 1e-6 * size
    return z, ~on_box


def draw_region(region: Any, ax: Any = None, *, box: Box | None = None, color: str = "C2", alpha: float = 0.18,
                label: str | None = None, n_rays: int = 720) -> Any:
    """Shade the part of ``region`` inside ``box`` on ``ax`` and draw the region's own edge.

    Parameters
    ----------
    region : Region
    ax : matplotlib Axes, optional
        A new figure's axes when None.
    box : (x0, x1, y0, y1), optional
        The rectangle to draw in; default the axes' current limits when ``ax`` is given and has
        data, else :func:`region_extent` padded by 10% (and the axes limits are set to it).
    color, alpha : matplotlib colour and fill opacity
    label : str, optional
        Legend entry of the shaded patch (default: the region's repr, shortened).
    n_rays : int
        Resolution of the outline (:func:`region_outline`).

    Returns
    -------
    matplotlib Axes
    """
    region = region_of(region)
    fresh = ax is None or not (ax.has_data() or ax.patches)
    ax = new_axes(ax)
    if box is None:
        if fresh:
            x0, x1, y0, y1 = region_extent(region)
            px, py = 0.1 * (x1 - x0), 0.1 * (y1 - y0)
            box = (x0 - px, x1 + px, y0 - py, y1 + py)
            ax.set_xlim(box[0], box[1])
            ax.set_ylim(box[2], box[3])
            ax.set_xlabel("real part")
            ax.set_ylabel("imaginary part")
        else:
            (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
            ym = max(abs(y0), abs(y1))
            box = (x0, x1, -ym, ym)
    from matplotlib.patches import Polygon

    z, edge = region_outline(region, box, n_rays)
    if label is None:
        label = "region: " + region_label(region)
    if z.size:
        ax.add_patch(Polygon(np.column_stack([z.real, z.imag]), closed=True, facecolor=color, alpha=alpha,
                             edgecolor="none", label=label, zorder=0))
        # the region's own edge: NaN breaks the line where the outline runs along the box
        zz = np.append(z, z[0])
        ee = np.append(edge, edge[0])
        xs = np.where(ee, zz.real, np.nan)
        ys = np.where(ee, zz.imag, np.nan)
        ax.plot(xs, ys, color=color, lw=1.2, zorder=1, scalex=False, scaley=False)
    return ax
