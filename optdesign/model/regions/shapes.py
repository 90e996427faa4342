"""The elementary pole regions: half-plane, disk, sector, vertical and horizontal strips, ellipse.

Each is a frozen dataclass subclass of :class:`~optdesign.model.regions.base.Region`, validated at
construction, with exact signed distances and projections, its Chilali-Gahinet ``(L, M)`` and its smooth
NLP constraints (the table and the contracts are in the docstring of :mod:`optdesign.model.regions`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...errors import ValidationError
from .base import Region, positive_param, real_param
from .geometry import eberly_nearest

__all__ = ["HalfPlane", "Disk", "Sector", "VerticalStrip", "HorizontalStrip", "Ellipse"]

_INF = math.inf


# ----------------------------------------------------------------------------- shapes
@dataclass(frozen=True)
class HalfPlane(Region):
    """The closed half-plane ``Re s <= -alpha`` (guaranteed decay rate ``alpha``).

    Parameters
    ----------
    alpha : float
        Any finite real; ``alpha = 0`` is the continuous-time stability region,
        ``alpha < 0`` allows poles up to ``Re s = -alpha > 0``.

    Notes
    -----
    LMI: ``f(s) = 2 alpha + s + conj(s)``.  Constraint: ``re + alpha <= 0``.
    """

    alpha: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "alpha", real_param("HalfPlane", "alpha", self.alpha))

    def _signed_distance(self, z):
        return z.real + self.alpha

    def _project(self, z):
        return np.minimum(z.real, -self.alpha) + 1j * z.imag

    def real_interval(self):
        return (-_INF, -self.alpha)

    def _ymax(self, xa, xb):
        return _INF

    def _scale(self):
        return max(abs(self.alpha), 1.0)

    def _primitives(self):
        return [("line", 1.0, 0.0, -self.alpha)]

    def lmi_matrices(self):
        return np.array([[2.0 * self.alpha]]), np.array([[1.0]])

    def constraints(self, re, im):
        return [re + self.alpha]


@dataclass(frozen=True)
class Disk(Region):
    """The closed disk ``|s - center| <= radius`` with a real center.

    Parameters
    ----------
    center : float
        Real (a complex center would break the symmetry a real system's poles need).
    radius : float
        ``> 0``.

    Notes
    -----
    LMI: ``f(s) = [[-r, s - c], [conj(s) - c, -r]]``.
    Constraint: ``((re - c)^2 + im^2 - r^2) / (2 r) <= 0`` (unit gradient on the boundary).
    For discrete time, use disks inside the unit disk (:meth:`unit`).

    Raises
    ------
    ValidationError
        Complex ``center``, ``radius <= 0``, or a non-finite parameter.
    """

    center: float
    radius: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "center", real_param("Disk", "center", self.center))
        object.__setattr__(self, "radius", positive_param("Disk", "radius", self.radius))

    @classmethod
    def unit(cls, rho: float = 1.0) -> Disk:
        """The disk ``|s| <= rho`` centered at the origin (discrete-time stability for ``rho <= 1``)."""
        return cls(0.0, positive_param("Disk.unit", "rho", rho))

    def _signed_distance(self, z):
        return np.abs(z - self.center) - self.radius

    def _project(self, z):
        w = z - self.center
        a = np.abs(w)
        out = a > self.radius
        p = z.copy()
        p[out] = self.center + self.radius * w[out] / a[out]
        return p

    def real_interval(self):
        return (self.center - self.radius, self.center + self.radius)

    def _ymax(self, xa, xb):
        return self.radius

    def _scale(self):
        return self.radius

    def _primitives(self):
        c, r = self.center, self.radius
        return [("conic", -1.0, 2.0 * c, r * r - c * c)]

    def lmi_matrices(self):
        c, r = self.center, self.radius
        return np.array([[-r, -c], [-c, -r]]), np.array([[0.0, 1.0], [0.0, 0.0]])

    def constraints(self, re, im):
        c, r = self.center, self.radius
        return [((re - c) ** 2 + im**2 - r * r) * (0.5 / r)]


@dataclass(frozen=True)
class Sector(Region):
    """The closed conic sector ``|Im s| <= tan(half_angle) (apex - Re s)``.

    A cone of half-angle ``theta`` around the negative real axis with its vertex at
    ``apex`` (default the origin).  With ``apex = 0`` it holds the poles whose damping
    ratio is at least ``cos(theta)`` (:meth:`from_damping`).

    Parameters
    ----------
    half_angle : float
        ``theta`` in radians, ``0 < theta < pi/2``.
    apex : float, default 0.0
        Real vertex of the cone.

    Notes
    -----
    LMI (apex 0): ``f(s) = [[sin t (s + s*), cos t (s - s*)], [cos t (s* - s), sin t (s + s*)]]``.
    Constraints: ``(re - apex) sin t + im cos t <= 0`` and ``(re - apex) sin t - im cos t <= 0``.

    Raises
    ------
    ValidationError
        ``half_angle`` outside ``(0, pi/2)`` or a non-finite parameter.
    """

    half_angle: float
    apex: float = 0.0

    def __post_init__(self) -> None:
        t = real_param("Sector", "half_angle", self.half_angle)
        if not 0.0 < t < 0.5 * math.pi:
            raise ValidationError(f"Sector half_angle must be in (0, pi/2) radians; found {t!r}")
        object.__setattr__(self, "half_angle", t)
        object.__setattr__(self, "apex", real_param("Sector", "apex", self.apex))

    @classmethod
    def from_damping(cls, zeta: float, apex: float = 0.0) -> Sector:
        """Poles with damping ratio ``>= zeta``: the sector of half-angle ``arccos(zeta)``.

        Raises
        ------
        ValidationError
            ``zeta`` outside ``(0, 1)``.
        """
        z = real_param("Sector.from_damping", "zeta", zeta)
        if not 0.0 < z < 1.0:
            raise ValidationError(f"Sector.from_damping zeta must be in (0, 1); found {z!r}")
        return cls(math.acos(z), apex)

    @property
    def damping(self) -> float:
        """The minimum damping ratio ``cos(half_angle)`` (meaningful for ``apex = 0``)."""
        return math.cos(self.half_angle)

    def _signed_distance(self, z):
        s, c = math.sin(self.half_angle), math.cos(self.half_angle)
        x = z.real - self.apex
        y = np.abs(z.imag)
        along = -x * c + y * s  # coordinate along the boundary ray
        return np.where(along >= 0, x * s + y * c, np.hypot(x, y))

    def _project(self, z):
        s, c = math.sin(self.half_angle), math.cos(self.half_angle)
        x = z.real - self.apex
        y = np.abs(z.imag)
        along = -x * c + y * s
        d = x * s + y * c
        px = np.where(d <= 0, x, np.where(along >= 0, x - d * s, 0.0))
        py = np.where(d <= 0, y, np.where(along >= 0, y - d * c, 0.0))
        return (px + self.apex) + 1j * np.copysign(py, z.imag)

    def real_interval(self):
        return (-_INF, self.apex)

    def _ymax(self, xa, xb):
        return math.tan(self.half_angle) * max(self.apex - xa, 0.0)

    def _scale(self):
        return max(abs(self.apex), 1.0)

    def _primitives(self):
        s, c = math.sin(self.half_angle), math.cos(self.half_angle)
        return [("line", s, c, s * self.apex), ("line", s, -c, s * self.apex)]

    def lmi_matrices(self):
        s, c = math.sin(self.half_angle), math.cos(self.half_angle)
        M = np.array([[s, c], [-c, s]])
        return -2.0 * s * self.apex * np.eye(2), M

    def constraints(self, re, im):
        s, c = math.sin(self.half_angle), math.cos(self.half_angle)
        x = re - self.apex
        return [x * s + im * c, x * s - im * c]


@dataclass(frozen=True)
class VerticalStrip(Region):
    """The closed vertical strip ``lo <= Re s <= hi``.

    Notes
    -----
    LMI: ``f(s) = diag(2 lo - (s + s*), (s + s*) - 2 hi)``.
    Constraints: ``lo - re <= 0``, ``re - hi <= 0``.

    Raises
    ------
    ValidationError
        ``lo >= hi`` or a non-finite bound.
    """

    lo: float
    hi: float

    def __post_init__(self) -> None:
        lo = real_param("VerticalStrip", "lo", self.lo)
        hi = real_param("VerticalStrip", "hi", self.hi)
        if not lo < hi:
            raise ValidationError(f"VerticalStrip needs lo < hi; found lo={lo!r}, hi={hi!r}")
        object.__setattr__(self, "lo", lo)
        object.__setattr__(self, "hi", hi)

    def _signed_distance(self, z):
        return np.maximum(self.lo - z.real, z.real - self.hi)

    def _project(self, z):
        return np.clip(z.real, self.lo, self.hi) + 1j * z.imag

    def real_interval(self):
        return (self.lo, self.hi)

    def _ymax(self, xa, xb):
        return _INF

    def _scale(self):
        return max(self.hi - self.lo, abs(self.lo), abs(self.hi))

    def _primitives(self):
        return [("line", 1.0, 0.0, self.lo), ("line", 1.0, 0.0, self.hi)]

    def lmi_matrices(self):
        return np.diag([2.0 * self.lo, -2.0 * self.hi]), np.diag([-1.0, 1.0])

    def constraints(self, re, im):
        return [self.lo - re, re - self.hi]


@dataclass(frozen=True)
class HorizontalStrip(Region):
    """The closed horizontal strip ``|Im s| <= omega`` (bounded oscillation frequency).

    Notes
    -----
    LMI: ``f(s) = [[-2 omega, s - s*], [s* - s, -2 omega]]``.
    Constraints: ``im - omega <= 0``, ``-im - omega <= 0``.

    Raises
    ------
    ValidationError
        ``omega <= 0`` or not finite.
    """

    omega: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "omega", positive_param("HorizontalStrip", "omega", self.omega))

    def _signed_distance(self, z):
        return np.abs(z.imag) - self.omega

    def _project(self, z):
        return z.real + 1j * np.clip(z.imag, -self.omega, self.omega)

    def real_interval(self):
        return (-_INF, _INF)

    def _ymax(self, xa, xb):
        return self.omega

    def _scale(self):
        return self.omega

    def _primitives(self):
        return [("line", 0.0, 1.0, self.omega), ("line", 0.0, 1.0, -self.omega)]

    def lmi_matrices(self):
        w = self.omega
        return -2.0 * w * np.eye(2), np.array([[0.0, 1.0], [-1.0, 0.0]])

    def constraints(self, re, im):
        return [im - self.omega, -im - self.omega]


@dataclass(frozen=True)
class Ellipse(Region):
    """The closed ellipse ``((Re s - center)/a)^2 + (Im s / b)^2 <= 1``.

    Parameters
    ----------
    center : float
        Real center.
    a : float
        Semi-axis along the real axis, ``> 0``.
    b : float
        Semi-axis along the imaginary axis, ``> 0``.

    Notes
    -----
    Distances are exact (Eberly's bisection for the nearest boundary point).
    LMI: ``f(s) = [[-1, u(s)], [conj(u(s)), -1]]`` with
    ``u(s) = (s - c)(1/a + 1/b)/2 + (conj(s) - c)(1/a - 1/b)/2``, i.e.
    ``M = [[0, (1/a + 1/b)/2], [(1/a - 1/b)/2, 0]]``.
    Constraint: ``(((re - c)/a)^2 + (im/b)^2 - 1) min(a, b)/2 <= 0``.

    Raises
    ------
    ValidationError
        Complex ``center``, ``a <= 0`` or ``b <= 0``, or a non-finite parameter.
    """

    center: float
    a: float
    b: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "center", real_param("Ellipse", "center", self.center))
        object.__setattr__(self, "a", positive_param("Ellipse", "a", self.a))
        object.__setattr__(self, "b", positive_param("Ellipse", "b", self.b))

    def _nearest_boundary(self, z):
        u = z.real - self.center
        v = z.imag
        au, av = np.abs(u), np.abs(v)
        if self.a >= self.b:
            px, py = eberly_nearest(self.a, self.b, au, av)
        else:
            py, px = eberly_nearest(self.b, self.a, av, au)
        return np.copysign(px, u), np.copysign(py, v), u, v

    def _signed_distance(self, z):
        px, py, u, v = self._nearest_boundary(z)
        g = (u / self.a) ** 2 + (v / self.b) ** 2 - 1.0
        return np.sign(g) * np.hypot(px - u, py - v)

    def _project(self, z):
        px, py, u, v = self._nearest_boundary(z)
        out = (u / self.a) ** 2 + (v / self.b) ** 2 > 1.0
        return np.where(out, (px + self.center) + 1j * py, z)

    def real_interval(self):
        return (self.center - self.a, self.center + self.a)

    def _ymax(self, xa, xb):
        return self.b

    def _scale(self):
        return max(self.a, self.b)

    def _primitives(self):
        c, k = self.center, (self.b / self.a) ** 2
        return [("conic", -k, 2.0 * c * k, self.b**2 - k * c * c)]

    def lmi_matrices(self):
        ia, ib = 1.0 / self.a, 1.0 / self.b
        c = self.center
        L = np.array([[-1.0, -c * ia], [-c * ia, -1.0]])
        M = np.array([[0.0, 0.5 * (ia + ib)], [0.5 * (ia - ib), 0.0]])
        return L, M

    def constraints(self, re, im):
        a, b, c = self.a, self.b, self.center
        return [(((re - c) * (1.0 / a)) ** 2 + (im * (1.0 / b)) ** 2 - 1.0) * (0.5 * min(a, b))]
