r"""Pole regions: where the eigenvalues of an estimator's error dynamics ``A - L C`` must lie.

Every region is a closed convex subset of the complex plane, symmetric about the real
axis (so it makes sense for the poles of a *real* system), with a nonempty interior.
Regions are immutable (frozen dataclasses), validated at construction, hashable,
picklable, and combine by intersection with ``&``::

    >>> from optdesign.regions import HalfPlane, Sector, Disk
    >>> D = HalfPlane(1.0) & Sector.from_damping(0.5) & Disk(0.0, 10.0)
    >>> D.contains([-2 + 1j, -2 - 1j, -3])
    True

Shapes
------
==========================  ===================================================  ==========================
class                       set                                                  real-axis interior
==========================  ===================================================  ==========================
``HalfPlane(alpha)``        ``Re s <= -alpha`` (decay rate ``alpha``, any sign)  ``(-inf, -alpha)``
``Disk(center, radius)``    ``|s - center| <= radius``, ``center`` real           ``(c - r, c + r)``
``Sector(half_angle)``      ``|Im s| <= tan(theta) (apex - Re s)``               ``(-inf, apex)``
``VerticalStrip(lo, hi)``   ``lo <= Re s <= hi``                                 ``(lo, hi)``
``HorizontalStrip(omega)``  ``|Im s| <= omega``                                  ``(-inf, inf)``
``Ellipse(center, a, b)``   ``((Re s - c)/a)^2 + (Im s / b)^2 <= 1``             ``(c - a, c + a)``
``A & B & ...``             :class:`Intersection` (flattened)                    intersection of the above
==========================  ===================================================  ==========================

``Sector.from_damping(zeta)`` is the set of poles with damping ratio ``>= zeta``
(``theta = arccos zeta``).  For discrete-time designs pass a disk inside the unit disk,
e.g. ``Disk.unit(0.9)``; :func:`stability_region` gives the plain stability region of
either time domain.

Common API
----------
``contains(poles, tol)``
    All poles in the closed region (points within ``tol`` of it count).
``distance(poles)``
    Signed Euclidean distance to the boundary, negative inside; exact for every shape
    *and* for intersections (see :class:`Intersection`).
``margin(poles)``
    ``max(distance(poles))``: ``<= 0`` means every pole is inside.
``project(poles)``
    The nearest point of the (closed) region to each pole.
``lmi_matrices()``
    ``(L, M)`` of the Chilali-Gahinet characteristic function (below), for SDPs.
``constraints(re, im)``
    Smooth scalar inequalities ``g_k(re, im) <= 0`` for NLPs (below).
``sample_poles(n, rng)``
    A conjugate-closed set of ``n`` poles strictly inside, to seed multi-start NLPs.

LMI regions (for SDP formulations)
----------------------------------
Each region's interior is the LMI region (Chilali & Gahinet 1996, Definition 2.1)

.. math:: \mathcal D = \{ s \in \mathbb C : f_{\mathcal D}(s) = L + M s + M^T \bar s \prec 0 \}

with real ``L = L^T`` and ``M`` returned by :meth:`Region.lmi_matrices`.  ``A`` has all
its eigenvalues in ``D`` iff there is ``X = X^T > 0`` with (their Theorem 2.2)

.. math:: M_{\mathcal D}(A, X) = L \otimes X + M \otimes (A X) + M^T \otimes (A X)^T \prec 0 .

Intersections stack the members' ``(L, M)`` block-diagonally (their Property 2.3).

Smooth constraints (for NLP formulations)
-----------------------------------------
``region.constraints(re, im)`` returns a list of expressions ``[g_1, ..., g_m]`` built with
plain arithmetic only (``+ - * / **`` and Python-float constants; no numpy calls, no
``abs``/``sqrt``/``max``), so ``re``/``im`` may be floats, numpy arrays (elementwise) or
CasADi ``SX``/``MX`` symbols.  The contract:

* the pole ``re + 1j*im`` lies in the closed region **iff** every ``g_k(re, im) <= 0``
  (exactly, not approximately);
* each ``g_k`` is a polynomial of degree <= 2 (infinitely smooth); the linear ones are
  scaled to unit gradient, the disk's to unit gradient on its boundary; only the sign is
  meaningful, not the value (use :meth:`Region.distance` for distances);
* the regions are symmetric, so a conjugate pair needs the constraints for one member only;
* the number of expressions is fixed per region (:attr:`Region.n_constraints`); an
  intersection concatenates its members' lists in order.

The sector is written as two linear half-planes through its apex rather than the
quadratic ``im^2 cos^2 - re^2 sin^2 <= 0``: the linear pair is exact, convex, and keeps
linearly independent gradients at the apex (the quadratic's gradient vanishes there).

The package, by responsibility: :mod:`.base` (the abstract :class:`Region` with the common API, and
:class:`Intersection`), :mod:`.shapes` (the six elementary shapes), :mod:`.geometry` (the numerical
kernels: boundary crossings, Eberly's nearest point on an ellipse, golden-section search),
:mod:`.factories` (:func:`stability_region`, :func:`region_from_dict`).

References
----------
M. Chilali and P. Gahinet, "H-infinity design with pole placement constraints: an LMI
approach", IEEE Trans. Automatic Control 41(3), 358-367, 1996.

D. Eberly, "Distance from a point to an ellipse, an ellipsoid, or a hyperellipsoid",
Geometric Tools, 2013 (robust bisection used by :class:`Ellipse`).
"""

from .base import Intersection, Region
from .factories import region_from_dict, stability_region
from .shapes import Disk, Ellipse, HalfPlane, HorizontalStrip, Sector, VerticalStrip

__all__ = [
    "Region",
    "HalfPlane",
    "Disk",
    "Sector",
    "VerticalStrip",
    "HorizontalStrip",
    "Ellipse",
    "Intersection",
    "stability_region",
    "region_from_dict",
]
