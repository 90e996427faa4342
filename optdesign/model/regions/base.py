"""The abstract pole region and the intersection of regions.

:class:`Region` carries the common API of every region (``contains``, ``distance``, ``margin``,
``project``, ``lmi_value``, ``sample_poles``, ``interior_point``, ``&``, ``to_dict``) on top of a few
per-shape primitives; :class:`Intersection` is the region ``a & b & ...`` (it lives here because
``Region.__and__`` builds it).  :func:`real_param` and :func:`positive_param` validate the shapes'
parameters.  The contracts are in the docstring of :mod:`optdesign.model.regions`.

References
----------
M. Chilali and P. Gahinet, "H-infinity design with pole placement constraints: an LMI
approach", IEEE Trans. Automatic Control 41(3), 358-367, 1996.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Callable, Sequence
from dataclasses import dataclass, fields
from functools import cached_property
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..._validate import as_positive_float, as_real, as_rng, as_vector
from ...errors import EmptyRegionError, ValidationError
from .geometry import Primitive, golden_argmin, intersect_primitives

__all__ = ["Region", "Intersection", "real_param", "positive_param"]

_INF = math.inf


# ----------------------------------------------------------------------------- helpers
def real_param(owner: str, name: str, value: Any) -> float:
    """A finite real scalar parameter; complex values with nonzero imaginary part are rejected.

    Parameters
    ----------
    owner : str
        What the parameter belongs to (``"Disk"``, ``"Sector.from_damping"``), for the message.
    name : str
        The parameter's name, for the message.
    value : float or complex
        The value given.

    Returns
    -------
    float

    Raises
    ------
    ValidationError
        ``value`` complex with a nonzero imaginary part, or not a real number.
    NotFiniteError
        ``value`` NaN or infinite.
    """
    if isinstance(value, (complex, np.complexfloating)):
        if value.imag != 0:
            raise ValidationError(
                f"{owner} {name} must be real (pole regions must be symmetric about the real axis "
                f"for a real system); found {value!r}"
            )
        value = value.real
    return as_real(f"{owner} {name}", value)


def positive_param(owner: str, name: str, value: Any) -> float:
    """A finite real scalar parameter that must be ``> 0`` (see :func:`real_param` for the arguments).

    Raises
    ------
    ValidationError
        ``value`` not real, or ``<= 0``.
    NotFiniteError
        ``value`` NaN or infinite.
    """
    v = real_param(owner, name, value)
    if not v > 0:
        raise ValidationError(f"{owner} {name} must be > 0; found {v!r}")
    return v


def _as_points(poles: ArrayLike, name: str = "poles") -> NDArray[np.complex128]:
    return as_vector(name, poles, allow_complex=True).astype(complex)


def _fmt(x: float) -> str:
    return "inf" if x == _INF else "-inf" if x == -_INF else f"{x:.6g}"


# ----------------------------------------------------------------------------- base class
class Region(ABC):
    """A closed convex pole region, symmetric about the real axis, with nonempty interior.

    Concrete regions are frozen dataclasses.  See the module docstring for the contracts
    of :meth:`lmi_matrices` and :meth:`constraints`.
    """

    # ------------------------------------------------------------ per-shape primitives
    @abstractmethod
    def _signed_distance(self, z: NDArray[np.complexfloating]) -> NDArray[np.float64]:
        """Exact signed distance to the boundary (negative inside) of validated points."""

    @abstractmethod
    def _project(self, z: NDArray[np.complex128]) -> NDArray[np.complex128]:
        """Nearest point of the closed region (``z`` itself when inside)."""

    @abstractmethod
    def real_interval(self) -> tuple[float, float]:
        """The open interval ``(lo, hi)`` where the region's interior meets the real axis.

        By symmetry and convexity this is also the projection of the region onto the real
        axis, and an intersection has a nonempty interior iff its members' intervals
        overlap.  Ends may be infinite.
        """

    @abstractmethod
    def _ymax(self, xa: float, xb: float) -> float:
        """An upper bound of ``|Im s|`` over the region restricted to ``xa <= Re s <= xb``."""

    @abstractmethod
    def _scale(self) -> float:
        """A length scale from the parameters, used to truncate unbounded regions."""

    @abstractmethod
    def _primitives(self) -> list[Primitive]:
        """The lines and conics that carry the boundary."""

    @abstractmethod
    def lmi_matrices(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        r"""``(L, M)`` of the characteristic function ``f(s) = L + M s + M^T conj(s)``.

        Returns
        -------
        L : (m, m) ndarray, symmetric
        M : (m, m) ndarray

        The region's interior is ``{s : f(s) < 0}`` (negative definite); see the module
        docstring for the matrix condition on ``A`` (Chilali & Gahinet 1996, Thm 2.2).
        """

    @abstractmethod
    def constraints(self, re: Any, im: Any) -> list[Any]:
        """Smooth expressions ``g_k(re, im)``, all ``<= 0`` iff ``re + j im`` is in the region.

        Parameters
        ----------
        re, im : float, ndarray, or CasADi SX/MX
            Real and imaginary part of a pole (arrays are evaluated elementwise).

        Returns
        -------
        list
            ``n_constraints`` expressions of the same type as ``re``/``im``.  Only plain
            arithmetic is applied to the arguments, so symbolic inputs stay symbolic.
            See the module docstring for the full contract.
        """

    # ------------------------------------------------------------ public API
    def distance(self, poles: ArrayLike) -> NDArray[np.float64]:
        """Signed Euclidean distance of each pole to the region's boundary.

        Parameters
        ----------
        poles : (k,) array_like of complex
            Any points (need not be conjugate-closed).

        Returns
        -------
        (k,) ndarray of float
            Negative inside (minus the distance to the boundary), positive outside (the
            distance to the region), zero on the boundary.  Exact for every shape.

        Raises
        ------
        NotFiniteError
            A pole is NaN or infinite.
        """
        return self._signed_distance(_as_points(poles))

    def contains(self, poles: ArrayLike, tol: float = 1e-9) -> bool:
        """True when every pole lies in the closed region, up to an absolute ``tol``.

        Parameters
        ----------
        poles : (k,) array_like of complex
        tol : float, default 1e-9
            Points at distance ``<= tol`` outside the boundary count as inside.

        Raises
        ------
        ValidationError
            ``tol`` negative or not finite; a pole not finite.
        """
        tol = as_positive_float("tol", tol, allow_zero=True)
        d = self.distance(poles)
        return bool(np.all(d <= tol))

    def margin(self, poles: ArrayLike) -> float:
        """``max(distance(poles))``: ``<= 0`` iff every pole is in the region.

        The most violating pole's distance outside, or (if all are inside) minus the
        smallest clearance to the boundary.  An empty set of poles gives ``-inf``.
        """
        d = self.distance(poles)
        return float(np.max(d)) if d.size else -_INF

    def project(self, poles: ArrayLike) -> NDArray[np.complex128]:
        """The nearest point of the closed region to each pole (the pole itself if inside)."""
        return self._project(_as_points(poles))

    def lmi_value(self, s: complex) -> NDArray[np.complex128]:
        """The Hermitian matrix ``f(s) = L + M s + M^T conj(s)``; ``s`` is interior iff ``f(s) < 0``.

        Raises
        ------
        ValidationError, NotFiniteError
            ``s`` is not one finite (complex) number.
        """
        s = complex(as_vector("s", s, 1, allow_complex=True)[0])
        L, M = self.lmi_matrices()
        return L + M * s + M.T * s.conjugate()

    @property
    def n_constraints(self) -> int:
        """Number of expressions returned by :meth:`constraints`."""
        return len(self.constraints(0.0, 0.0))

    def constraint_functions(self) -> list[Callable[[Any, Any], Any]]:
        """The expressions of :meth:`constraints` as separate callables ``g_k(re, im)``."""
        def component(k: int) -> Callable[[Any, Any], Any]:
            return lambda re, im: self.constraints(re, im)[k]

        return [component(k) for k in range(self.n_constraints)]

    @property
    def bounded(self) -> bool:
        """Whether the region is a bounded set."""
        lo, hi = self.real_interval()
        return math.isfinite(lo) and math.isfinite(hi) and math.isfinite(self._ymax(lo, hi))

    def _window(self, window: float | None = None) -> tuple[float, float, float, float]:
        """``(xa, xb, Y, W)``: a bounded box ``[xa, xb] x [-Y, Y]`` meeting the interior."""
        lo, hi = self.real_interval()
        W = self._scale() if window is None else positive_param("sample_poles", "window", window)
        if math.isfinite(lo) and math.isfinite(hi):
            xa, xb = lo, hi
        elif math.isfinite(hi):
            xa, xb = hi - W, hi
        elif math.isfinite(lo):
            xa, xb = lo, lo + W
        else:
            xa, xb = -W, W
        Y = self._ymax(xa, xb)
        if not math.isfinite(Y):
            Y = W
        return xa, xb, Y, W

    def interior_point(self, window: float | None = None) -> float:
        """A real point strictly inside the region, as deep as possible.

        Every nonempty region of this module meets the real axis in its interior (by
        symmetry and convexity), so the point is real: it maximizes the clearance
        ``-distance`` over the real axis, restricted to a bounded window for unbounded
        regions (default window from the region's parameters; ``window`` overrides it).
        """
        # kept per window (a region is immutable): a region design asks for it once per start
        # (sample_poles) -- 3 ms each on the 8 starts of a small plant's design, issue 28
        cache = self.__dict__.setdefault("_interior_points", {})
        if window not in cache:
            xa, xb, _, _ = self._window(window)

            def f(x: float) -> float:
                return float(self._signed_distance(np.array([complex(x, 0.0)]))[0])

            cache[window] = float(golden_argmin(f, xa, xb))
        return cache[window]

    def sample_poles(
        self,
        n: int,
        rng: np.random.Generator | int | None = None,
        real_fraction: float = 0.5,
        *,
        n_real: int | None = None,
        window: float | None = None,
    ) -> NDArray[np.complex128]:
        """A random conjugate-closed set of ``n`` poles strictly inside the region.

        Used to seed multi-start NLPs.  About ``real_fraction * n`` poles are real (one
        more or fewer to make the complex ones pair up), or exactly ``n_real`` when given;
        the others are conjugate pairs with clearly nonzero imaginary parts.  (The rounding
        makes the default ``real_fraction = 0.5`` give all-real poles for ``n = 2`` and
        ``n = 3``: pass ``n_real`` to choose the pattern exactly.)  Every pole has clearance
        ``> 1e-3 rho`` from the boundary, ``rho`` being the clearance of :meth:`interior_point`.  Unbounded
        regions are sampled in a bounded window next to their finite edge, of size
        ``window`` (default: a length from the region's own parameters, e.g. ``|alpha|``
        or 1 for a half-plane).

        Parameters
        ----------
        n : int
            Number of poles, ``>= 0``.
        rng : numpy Generator or int seed, optional
        real_fraction : float in [0, 1], default 0.5
            Ignored when ``n_real`` is given.
        n_real : int, optional
            Exact number of real poles: ``0 <= n_real <= n`` with ``n - n_real`` even.
        window : float, optional
            Length scale of the sampling window for unbounded regions.

        Returns
        -------
        (n,) ndarray of complex
            Real poles first (ascending), then pairs ``z, conj(z)`` with ``Im z > 0``.

        Raises
        ------
        ValidationError
            ``n`` negative or not an integer, ``real_fraction`` outside [0, 1], ``n_real`` not
            an integer in ``[0, n]`` of the parity of ``n``, ``window <= 0``, ``rng`` not a seed or
            a Generator.
        """
        if isinstance(n, (bool, np.bool_)) or not isinstance(n, (int, np.integer)) or n < 0:
            raise ValidationError(f"sample_poles n must be a nonnegative integer; found {n!r}")
        n = int(n)
        rf = real_param("sample_poles", "real_fraction", real_fraction)
        if not 0.0 <= rf <= 1.0:
            raise ValidationError(f"sample_poles real_fraction must be in [0, 1]; found {rf!r}")
        if n_real is None:
            n_real = int(round(rf * n))
            if (n - n_real) % 2:
                n_real = n_real + 1 if n_real < n else n_real - 1
        else:
            if (
                isinstance(n_real, (bool, np.bool_))
                or not isinstance(n_real, (int, np.integer))
                or not 0 <= n_real <= n
                or (n - n_real) % 2
            ):
                raise ValidationError(
                    f"sample_poles n_real must be an integer in [0, {n}] with n - n_real even "
                    f"(complex poles come in pairs); found {n_real!r}"
                )
            n_real = int(n_real)
        gen = as_rng("sample_poles rng", rng)
        n_pairs = (n - n_real) // 2

        xa, xb, Y, _ = self._window(window)
        x0 = self.interior_point(window)
        rho = -float(self._signed_distance(np.array([complex(x0)]))[0])
        tau = 1e-3 * rho

        def accept(z: NDArray[np.complexfloating]) -> NDArray[np.complexfloating]:
            return z[self._signed_distance(z) < -tau]

        reals: list[complex] = []
        pairs: list[complex] = []
        for _ in range(60):
            if len(reals) >= n_real:
                break
            reals.extend(accept(gen.uniform(xa, xb, 256) + 0j).tolist())
        for _ in range(60):
            if len(pairs) >= n_pairs:
                break
            z = gen.uniform(xa, xb, 256) + 1j * gen.uniform(0.0, Y, 256)
            pairs.extend(accept(z[z.imag > tau]).tolist())
        # fall back on the inscribed disk around x0 (always inside: distance is 1-Lipschitz)
        while len(reals) < n_real:
            reals.append(complex(x0 + rho * gen.uniform(-0.9, 0.9)))
        while len(pairs) < n_pairs:
            r = rho * gen.uniform(0.1, 0.9)
            t = math.pi * gen.uniform(0.05, 0.95)
            pairs.append(complex(x0 + r * math.cos(t), r * math.sin(t)))
        re = np.sort(np.real(reals[:n_real])).astype(complex)
        cp = sorted(pairs[:n_pairs], key=lambda z: (z.real, z.imag))
        out = np.empty(n, dtype=complex)
        out[:n_real] = re
        out[n_real::2] = cp
        out[n_real + 1 :: 2] = np.conj(cp)
        return out

    # ------------------------------------------------------------ combination, (de)serialization
    def __and__(self, other: object) -> Region:
        if not isinstance(other, Region):
            raise ValidationError(f"a region can only be intersected with a region (region & region); found "
                                  f"{type(other).__name__} {other!r}")
        members = _flatten((self, other))
        if len(members) == 1:
            return members[0]
        return Intersection(*members)

    def __rand__(self, other: object) -> Region:
        return self.__and__(other)  # only reached for a non-region on the left: refused there

    def plot(self, ax: Any = None, **kw: Any) -> Any:
        """Shade the region on a matplotlib Axes (a new figure's when ``ax`` is None).

        Bounded regions are drawn whole; unbounded ones in a window at their finite edges (or, on
        axes that already hold data, within the axes' limits).  Keywords go to
        :func:`optdesign.plot.draw_region` (``box``, ``color``, ``alpha``, ``label``).

        Returns
        -------
        matplotlib Axes

        Raises
        ------
        BackendUnavailableError
            matplotlib is not installed.
        """
        from ...plot.regions import draw_region

        return draw_region(self, ax, **kw)

    def to_dict(self) -> dict[str, Any]:
        """A JSON-friendly description; :func:`~optdesign.regions.region_from_dict` inverts it."""
        return {"type": type(self).__name__, **{f.name: getattr(self, f.name) for f in fields(self)}}  # type: ignore[arg-type]


def _flatten(regions: Sequence[Region]) -> tuple[Region, ...]:
    out: list[Region] = []
    for r in regions:
        for m in (r.members if isinstance(r, Intersection) else (r,)):
            if m not in out:
                out.append(m)
    return tuple(out)


# ----------------------------------------------------------------------------- intersection
@dataclass(frozen=True, init=False, repr=False)
class Intersection(Region):
    """The intersection of regions, usually built with ``a & b``.

    Nested intersections are flattened and duplicate members dropped.

    Distances are exact: inside, ``max_k d_k`` (the clearance to the nearest member
    boundary) is the exact signed distance; outside, the nearest point of the
    intersection is found exactly among the members' own projections and the corners
    where two member boundaries cross (a finite set for these shapes), and the distance
    to it is returned.  (If rounding made every candidate infeasible -- not observed in
    3000 random intersections --
    the lower bound ``max_k d_k`` would be returned.)

    Raises
    ------
    EmptyRegionError
        The members have no interior point in common.  Exact test: every member meets
        the real axis in an open interval (:meth:`Region.real_interval`), and by symmetry
        and convexity the interior of the intersection is nonempty iff those intervals
        overlap (by more than ``1e-12`` times their magnitude, so members that only touch,
        like ``HalfPlane(1) & VerticalStrip(-1, 0)``, count as empty); the message names a
        pair of members that share no interior point.
    ValidationError
        No members, or a member that is not a :class:`Region`.
    """

    members: tuple[Region, ...]

    def __init__(self, *members: Region) -> None:
        for m in members:
            if not isinstance(m, Region):
                raise ValidationError(
                    f"Intersection members must be Regions; found {type(m).__name__}: {m!r}")
        flat = _flatten(members)
        if not flat:
            raise ValidationError("Intersection needs at least one region; found none")
        object.__setattr__(self, "members", flat)
        lo, hi = self.real_interval()
        width = hi - lo
        scale = max([1.0, *(abs(v) for v in (lo, hi) if math.isfinite(v))])
        if not width > 1e-12 * scale:
            k_lo = max(range(len(flat)), key=lambda k: flat[k].real_interval()[0])
            k_hi = min(range(len(flat)), key=lambda k: flat[k].real_interval()[1])
            a, b = flat[k_lo], flat[k_hi]
            ia, ib = a.real_interval(), b.real_interval()
            raise EmptyRegionError(
                f"the intersection {self!r} has an empty interior: {a!r} meets the real axis in "
                f"({_fmt(ia[0])}, {_fmt(ia[1])}) and {b!r} in ({_fmt(ib[0])}, {_fmt(ib[1])}), which do "
                f"not overlap, so these two members share no interior point (a convex region symmetric "
                f"about the real axis has interior points only if it has real ones)"
            )

    def __repr__(self) -> str:
        return "Intersection(" + ", ".join(repr(m) for m in self.members) + ")"

    def to_dict(self) -> dict[str, Any]:
        return {"type": "Intersection", "members": [m.to_dict() for m in self.members]}

    # the max of member signed distances: exact inside, a lower bound outside
    def _member_max(self, z):
        return np.max(np.stack([m._signed_distance(z) for m in self.members]), axis=0)

    @cached_property
    def _tol(self) -> float:
        return 1e-9 * max(1.0, self._scale())

    @cached_property
    def _corners(self) -> NDArray[np.complex128]:
        prims = [p for m in self.members for p in m._primitives()]
        pts = [v for i in range(len(prims)) for j in range(i + 1, len(prims))
               for v in intersect_primitives(prims[i], prims[j])]
        V = np.array(pts, dtype=complex)
        if V.size:
            V = V[self._member_max(V) <= self._tol * max(1.0, float(np.max(np.abs(V))))]
        return V

    def _nearest(self, z):
        D = self._member_max(z)
        dist, P = D.copy(), z.copy()
        out = np.flatnonzero(D > 0)
        if out.size:
            zo = z[out]
            cand = np.stack([m._project(zo) for m in self.members], axis=1)
            V = self._corners
            if V.size:
                cand = np.concatenate([cand, np.broadcast_to(V, (zo.size, V.size))], axis=1)
            tol = self._tol * np.maximum(1.0, np.abs(cand))
            feas = self._member_max(cand.ravel()).reshape(cand.shape) <= tol
            dd = np.where(feas, np.abs(cand - zo[:, None]), _INF)
            k = np.argmin(dd, axis=1)
            rows = np.arange(zo.size)
            best = dd[rows, k]
            ok = np.isfinite(best)
            dist[out] = np.where(ok, np.maximum(best, D[out]), D[out])
            P[out] = np.where(ok, cand[rows, k], zo)
        return dist, P

    def _signed_distance(self, z):
        return self._nearest(z)[0]

    def _project(self, z):
        return self._nearest(z)[1]

    def real_interval(self):
        ivs = [m.real_interval() for m in self.members]
        return (max(i[0] for i in ivs), min(i[1] for i in ivs))

    def _ymax(self, xa, xb):
        return min(m._ymax(xa, xb) for m in self.members)

    def _scale(self):
        return max(m._scale() for m in self.members)

    def _primitives(self):
        return [p for m in self.members for p in m._primitives()]

    def lmi_matrices(self):
        Ls, Ms = zip(*(m.lmi_matrices() for m in self.members), strict=True)
        size = sum(L.shape[0] for L in Ls)
        L = np.zeros((size, size))
        M = np.zeros((size, size))
        k = 0
        for Lk, Mk in zip(Ls, Ms, strict=True):
            q = Lk.shape[0]
            L[k : k + q, k : k + q] = Lk
            M[k : k + q, k : k + q] = Mk
            k += q
        return L, M

    def constraints(self, re, im):
        return [g for m in self.members for g in m.constraints(re, im)]
