r"""Output-noise models: persistent signals annihilated by a known polynomial.

A noise model says which *class* of signals an output noise ``delta`` belongs to, through
a monic polynomial ``P`` in the forward shift ``q`` (``q delta(k) = delta(k+1)``) with

.. math::

    P(q)\,\delta(k) = \delta(k+r) + a_{r-1}\delta(k+r-1) + \dots + a_0\,\delta(k) = 0 .

Seed 003 writes the same polynomial in ``q^{-1}`` (``P(q^{-1}) = 1 + a_{r-1} q^{-1} + ... +
a_0 q^{-r}``): multiplying by ``q^r`` gives the same coefficient list, so
``coefficients = [1, a_{r-1}, ..., a_0]`` (highest power first, the :func:`numpy.roots`
convention) reads the same in both notations.

================================  ===========================  =======================
model                             ``P(q)``                     modes (roots)
================================  ===========================  =======================
``Step()``                        ``q - 1``                    ``1``
``Sinusoid(f, dt)``               ``q^2 - 2 cos(w dt) q + 1``  ``exp(+-j w dt)``, ``w = 2 pi f``
``Polynomial(c)``                 ``c / c[0]``                 ``roots(c)``
``Step() + Sinusoid(f, dt)``      least common multiple        union of the modes
================================  ===========================  =======================

Each model gives the realization used by the generalized observer of seed 003, eq (14),
for ``p`` output channels (one copy of the model per channel, state ordered by lag,
``xi = [eps(k); eps(k+1); ...; eps(k+r-1)]``)::

    N = companion(P) kron I_p    (r p, r p)   last block row [-a_0 I, ..., -a_{r-1} I]
    M = e_r kron I_p             (r p, p)
    Gamma = e_1' kron I_p        (p, r p)     delta(k) = Gamma d(k) when d(k+1) = N d(k)

``(N, M)`` is controllable and ``(Gamma, N)`` observable for every model (companion form),
which is what the internal-model argument needs.

Accepted noise models
---------------------
Only *persistent, bounded-or-polynomially-growing* noise is modelled: every root of ``P`` must
lie on the unit circle (``| |z| - 1 | <= tol``, default 1e-6; repeated roots, which are computed
only to about ``eps^(1/m)``, are tested as a cluster by the geometric mean of their moduli, which
is accurate).  Roots inside the circle describe noise that dies
out by itself (no internal model is needed to reject it) and roots outside describe noise that
grows exponentially, which no bounded output-noise model covers; both are rejected with a
:class:`~optdesign.errors.ValidationError`.  Repeated roots are accepted (``(q - 1)^2`` models a
ramp).  A sinusoid must have ``0 < f < 1 / (2 dt)`` (strictly below Nyquist: at ``f = 0`` it is a
double root at 1, use ``Polynomial([1, -2, 1])``; at Nyquist ``sin(pi k) = 0``).

References
----------
Kim, H. S., Lee, C. H. & Kim, S. B., "A Study on Generalized Observer Structure and its
Characteristic of Noise Reduction" (seed 003), eq (10)-(14).
Francis, B. A. & Wonham, W. M., "The internal model principle of control theory",
Automatica 12 (1976) 457-465.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._validate import as_array, as_int, as_positive_float, as_real
from ..errors import DimensionError, NotFiniteError, ValidationError

__all__ = ["NoiseModel", "Step", "Sinusoid", "Polynomial", "UNIT_CIRCLE_TOL", "cluster_roots"]

#: Default tolerance on ``| |z| - 1 |`` for the roots of a noise polynomial.
UNIT_CIRCLE_TOL = 1e-6


def _readonly(X: NDArray) -> NDArray:
    X = np.array(X, copy=True)
    X.setflags(write=False)
    return X


def _fmt_root(z: complex) -> str:
    z = complex(z)
    if abs(z.imag) < 1e-12:
        return f"{z.real:.6g}"
    return f"{z.real:.6g}{z.imag:+.6g}j"


def _check_coefficients(name: str, coefficients: ArrayLike) -> NDArray[np.float64]:
    """Finite real 1-D coefficients, leading one non-zero, degree >= 1; returned monic."""
    try:
        c = np.asarray(coefficients)
    except Exception as exc:  # ragged input
        raise ValidationError(f"{name} could not be converted to an array: {exc}") from None
    if c.dtype == object or not (np.issubdtype(c.dtype, np.number) or c.dtype == bool):
        raise ValidationError(f"{name} must be a sequence of real numbers; found dtype {c.dtype}")
    if np.iscomplexobj(c):
        if np.any(np.imag(c) != 0):
            raise ValidationError(
                f"{name} must be real (a real noise has a real annihilator); found complex entries"
            )
        c = np.real(c)
    c = np.atleast_1d(c).astype(float)
    if c.ndim != 1:
        raise DimensionError(f"{name} must be 1-D (highest power first); found shape {c.shape}")
    if c.size < 2:
        raise ValidationError(
            f"{name} must have degree >= 1 (at least 2 coefficients, highest power first); found {c.size}"
        )
    if not np.all(np.isfinite(c)):
        bad = int(np.argmax(~np.isfinite(c)))
        raise NotFiniteError(f"{name} must be finite; found {c[bad]} at index {bad}")
    if c[0] == 0.0:
        raise ValidationError(
            f"{name} must have a non-zero leading coefficient (highest power first); found {c.tolist()}"
        )
    return c / c[0]


def cluster_roots(roots: ArrayLike, tol: float = 1e-4) -> list[tuple[complex, int]]:
    """Group numerically equal roots: ``[(mean root, multiplicity), ...]``.

    A root of multiplicity ``k`` is computed only to about ``eps^(1/k)`` (1e-5 for k = 3), so
    the default relative tolerance is 1e-4; the mean of a cluster is accurate to rounding.

    Parameters
    ----------
    roots : (k,) array_like of complex
        The roots (any shape; raveled), e.g. the computed roots of a noise polynomial.
    tol : float, optional
        Relative tolerance: ``z`` joins a cluster when ``|z - mean| <= tol * max(1, |z|)``.

    Returns
    -------
    list of (complex, int)
        One ``(mean root, multiplicity)`` per cluster, in order of first appearance; the
        multiplicities sum to the number of roots.
    """
    out: list[list[complex]] = []
    for z in np.asarray(roots, dtype=complex).ravel():
        for cl in out:
            if abs(z - np.mean(cl)) <= tol * max(1.0, abs(z)):
                cl.append(complex(z))
                break
        else:
            out.append([complex(z)])
    return [(complex(np.mean(cl)), len(cl)) for cl in out]


def _off_circle(c: NDArray, z: NDArray, tol: float) -> list[tuple[complex, float]]:
    """Clusters of roots of ``c`` that are off the unit circle: ``[(centroid, modulus), ...]``.

    A root of multiplicity m is computed only to ~``eps^(1/m)``, but the symmetric functions of
    its cluster (centroid, product) are accurate.  Each computed root gets the first-order
    forward-error estimate ``fe = eps sum|c_k||z|^k / |P'(z)|`` (about the cluster radius for a
    perturbed multiple root, tiny for a simple root); roots closer than ``10 (fe_i + fe_j)`` are
    linked (single linkage), and a cluster passes when the geometric mean of its moduli,
    ``|prod z_i|^(1/m)``, is within ``tol`` of 1.
    """
    z = np.asarray(z, dtype=complex).ravel()
    dc = np.polyder(c)
    eps = np.finfo(float).eps
    fe = np.empty(z.size)
    for i, zi in enumerate(z):
        d = abs(np.polyval(dc, zi))
        S = float(np.polyval(np.abs(c), abs(zi)))
        fe[i] = np.inf if d == 0.0 else 64.0 * eps * S / d
    parent = list(range(z.size))

    def find(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for i in range(z.size):
        for j in range(i + 1, z.size):
            if abs(z[i] - z[j]) <= 10.0 * (fe[i] + fe[j]) + 1e-14:
                parent[find(i)] = find(j)
    groups: dict[int, list[int]] = {}
    for i in range(z.size):
        groups.setdefault(find(i), []).append(i)
    bad = []
    for idx in groups.values():
        g = float(np.exp(np.mean(np.log(np.abs(z[idx])))))
        if abs(g - 1.0) > tol:
            bad.append((complex(np.mean(z[idx])), g))
    return bad


def _rebuild(cls: type[NoiseModel], state: dict[str, Any]) -> NoiseModel:
    """Unpickle an immutable noise model (used by ``__reduce__``)."""
    obj = object.__new__(cls)
    for k, v in state.items():
        object.__setattr__(obj, k, _readonly(v) if isinstance(v, np.ndarray) else v)
    return obj


class NoiseModel:
    r"""An output-noise model ``P(q) delta = 0`` (base class of :class:`Step`, :class:`Sinusoid`,
    :class:`Polynomial` and their sums).

    Instances are immutable.  ``a + b`` is the model of ``delta_a + delta_b``: its polynomial is
    the least common multiple of the two (shared modes are not duplicated, so
    ``Step() + Step()`` is ``Step()``, not a ramp).

    Attributes
    ----------
    coefficients : (r + 1,) ndarray
        Monic ``P``, highest power first.
    dt : float or None
        The sampling period the model was built for (a sinusoid's ``q``-polynomial depends on
        it); ``None`` when the polynomial does not depend on the sampling period.
    label : str
        A short description, e.g. ``"step"``, ``"sinusoid 1 Hz (dt=0.01)"``.
    """

    __slots__ = ("coefficients", "dt", "label", "_roots")
    # set once by __init__ (object.__setattr__: instances are immutable); declared for type checkers
    coefficients: NDArray[np.float64]
    dt: float | None
    label: str
    _roots: NDArray[np.complex128]

    def __init__(self, coefficients: ArrayLike, *, dt: float | None = None, label: str = "polynomial",
                 tol: float = UNIT_CIRCLE_TOL, roots: ArrayLike | None = None) -> None:
        c = _check_coefficients("coefficients", coefficients)
        tol = as_positive_float("tol", tol)
        dt = None if dt is None else as_positive_float("dt", dt)
        if roots is None:
            z = np.roots(c)
        else:  # exact roots supplied by a subclass / a sum: must be those of c
            z = np.asarray(roots, dtype=complex).ravel()
            if z.size != c.size - 1 or not np.allclose(np.poly(z), c, rtol=0, atol=1e-9):
                raise ValidationError(f"roots {z.tolist()} are not the roots of the polynomial {c.tolist()}")
        bad = _off_circle(c, z, tol)
        if bad:
            shown = ", ".join(f"{_fmt_root(r)} (|z| = {g:.6g})" for r, g in bad)
            raise ValidationError(
                f"noise polynomial {c.tolist()} has root(s) off the unit circle: {shown}; only persistent "
                f"noise with every root on |z| = 1 (within tol={tol:g}) is accepted: roots inside the circle "
                "describe noise that decays by itself, roots outside describe exponentially growing noise"
            )
        object.__setattr__(self, "coefficients", _readonly(c))
        object.__setattr__(self, "dt", dt)
        object.__setattr__(self, "label", str(label))
        object.__setattr__(self, "_roots", _readonly(z.astype(complex)))

    def __setattr__(self, name: str, value: Any) -> None:
        raise AttributeError(f"{type(self).__name__} is immutable")

    def __reduce__(self):
        state = {k: getattr(self, k) for cls in type(self).__mro__ for k in getattr(cls, "__slots__", ())}
        return _rebuild, (type(self), state)

    # ------------------------------------------------------------- polynomial
    @property
    def order(self) -> int:
        """Degree ``r`` of the annihilating polynomial (states per output channel)."""
        return int(self.coefficients.size - 1)

    @property
    def modes(self) -> NDArray[np.complex128]:
        """The roots of ``P`` (the noise's modes, on the unit circle), shape (r,)."""
        return self._roots.copy()

    @property
    def polynomial(self) -> np.poly1d:
        """``P`` as a :class:`numpy.poly1d` (monic, in the forward shift ``q``)."""
        return np.poly1d(self.coefficients)

    # ---------------------------------------------------------- realization
    @property
    def N(self) -> NDArray[np.float64]:
        """Companion matrix of ``P`` for one channel, shape (r, r) (seed 003 eq (14))."""
        return self.realization(1)[0]

    @property
    def M(self) -> NDArray[np.float64]:
        """Input matrix ``e_r`` for one channel, shape (r, 1) (seed 003 eq (14))."""
        return self.realization(1)[1]

    @property
    def Gamma(self) -> NDArray[np.float64]:
        """Output matrix ``e_1'`` for one channel, shape (1, r): ``delta(k) = Gamma d(k)``."""
        return self.realization(1)[2]

    def realization(self, p: int = 1) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """``(N, M, Gamma)`` for ``p`` output channels, one copy of the model per channel.

        Parameters
        ----------
        p : int
            Number of output channels.

        Returns
        -------
        N : (r p, r p) ndarray
            ``companion(P) kron I_p``; the state is ordered by lag,
            ``[v(k); v(k+1); ...; v(k+r-1)]`` with ``v`` in R^p.
        M : (r p, p) ndarray
            ``e_r kron I_p``.
        Gamma : (p, r p) ndarray
            ``e_1' kron I_p``.

        Raises
        ------
        ValidationError
            ``p`` is not a positive integer.
        """
        if isinstance(p, bool) or not isinstance(p, (int, np.integer)) or p < 1:
            raise ValidationError(f"p must be a positive integer (number of outputs); found {p!r}")
        r = self.order
        comp = np.zeros((r, r))
        comp[:-1, 1:] = np.eye(r - 1)
        comp[-1, :] = -self.coefficients[::-1][:-1]  # [-a_0, -a_1, ..., -a_{r-1}]
        er = np.zeros((r, 1))
        er[-1, 0] = 1.0
        e1 = np.zeros((1, r))
        e1[0, 0] = 1.0
        Ip = np.eye(int(p))
        N, M, Gamma = np.kron(comp, Ip), np.kron(er, Ip), np.kron(e1, Ip)
        return N, M, Gamma  # type: ignore[return-value]  # stubs: kron of float64 is floating[Any]

    # --------------------------------------------------------------- signals
    def annihilate(self, signal: ArrayLike) -> NDArray[np.float64]:
        """Apply ``P(q)`` to a sampled signal: ``sum_i c_i delta(k + r - i)``.

        Parameters
        ----------
        signal : (T,) or (T, p) array_like

        Returns
        -------
        (T - r,) or (T - r, p) ndarray
            Zero (to rounding) exactly when the signal belongs to the model.

        Raises
        ------
        ValidationError, NotFiniteError
            ``signal`` not numeric (strings are refused) or not finite.
        DimensionError
            Not 1-D or 2-D, or not longer than ``r`` samples.
        """
        x = as_array("signal", signal, (1, 2))
        r = self.order
        if x.shape[0] <= r:
            raise DimensionError(f"signal must be (T,) or (T, p) with T > {r}; found shape {x.shape}")
        T = x.shape[0]
        out = np.zeros((T - r,) + x.shape[1:])
        for i, ci in enumerate(self.coefficients):
            out += ci * x[r - i:T - i]
        return out

    def simulate(self, steps: int, initial: ArrayLike) -> NDArray[np.float64]:
        """A realization of the noise from its first ``r`` samples.

        Parameters
        ----------
        steps : int
            Number of samples ``T >= r``.
        initial : (r,) or (r, p) array_like
            ``delta(0), ..., delta(r-1)``.

        Returns
        -------
        (T,) or (T, p) ndarray
            ``delta(0..T-1)`` with ``P(q) delta = 0``.

        Raises
        ------
        ValidationError
            ``steps`` not an integer ``>= r``; ``initial`` not numeric.
        DimensionError, NotFiniteError
            ``initial`` of the wrong shape or not finite.
        """
        r = self.order
        steps = as_int("steps", steps, r)
        d0 = as_array("initial", initial, (1, 2))
        if d0.shape[0] != r:
            raise DimensionError(f"initial must have shape ({r},) or ({r}, p); found {d0.shape}")
        out = np.zeros((steps,) + d0.shape[1:])
        out[:r] = d0
        a = self.coefficients[1:]  # delta(k) = -(a_{r-1} delta(k-1) + ... + a_0 delta(k-r))
        for k in range(r, steps):
            out[k] = -np.tensordot(a, out[k - r:k][::-1], axes=1)
        return out

    # -------------------------------------------------------------- algebra
    def __add__(self, other: NoiseModel) -> NoiseModel:
        if not isinstance(other, NoiseModel):
            return NotImplemented
        if self == other:
            return self
        if self.dt is not None and other.dt is not None and not math.isclose(self.dt, other.dt, rel_tol=1e-9):
            raise ValidationError(
                "cannot add noise models built for different sampling periods: "
                f"{self.label} has dt={self.dt:g}, {other.label} has dt={other.dt:g}"
            )
        dt = self.dt if self.dt is not None else other.dt
        merged: dict[complex, int] = {}
        for z, m in cluster_roots(self._roots) + cluster_roots(other._roots):
            for key in merged:
                if abs(key - z) <= 1e-6 * max(1.0, abs(z)):
                    merged[key] = max(merged[key], m)
                    break
            else:
                merged[z] = m
        roots = np.concatenate([np.full(m, z) for z, m in merged.items()])
        roots = roots / np.abs(roots)  # exactly on the circle (all accepted roots are)
        coeffs = np.real(np.poly(roots))
        return NoiseModel(coeffs, dt=dt, label=f"{self.label} + {other.label}", roots=roots)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, NoiseModel):
            return NotImplemented
        return (self.coefficients.shape == other.coefficients.shape
                and bool(np.allclose(self.coefficients, other.coefficients, rtol=0, atol=1e-12))
                and self.dt == other.dt)

    def __hash__(self) -> int:
        return hash((tuple(np.round(self.coefficients, 12)), self.dt))

    def __repr__(self) -> str:
        c = ", ".join(f"{v:.6g}" for v in self.coefficients)
        dt = f", dt={self.dt:g}" if self.dt is not None else ""
        return f"NoiseModel({self.label!r}, P(q) = [{c}]{dt})"


class Step(NoiseModel):
    """A constant output offset: ``P(q) = q - 1``, ``N = 1``, ``M = 1`` (seed 003, section 5).

    The generalized observer with this model is the PI observer (seed 003 eq (8)).

    Examples
    --------
    >>> from optdesign.noise import Step
    >>> Step().coefficients.tolist(), Step().N.tolist()
    ([1.0, -1.0], [[1.0]])
    """

    __slots__ = ()

    def __init__(self) -> None:
        super().__init__([1.0, -1.0], label="step", roots=[1.0])

    def signal(self, steps: int, level: float = 1.0) -> NDArray[np.float64]:
        """``delta(k) = level`` for ``k = 0..steps-1``, shape (steps,)."""
        return self.simulate(steps, [as_real("level", level)])

    def __repr__(self) -> str:
        return "Step()"


class Sinusoid(NoiseModel):
    r"""A sinusoid of known frequency and unknown amplitude and phase.

    ``P(q) = q^2 - 2 cos(theta) q + 1`` with ``theta = omega dt`` rad/sample; modes
    ``exp(+-j theta)``.  Seed 003's example: ``Sinusoid(1.0, 0.01)`` (``0.2 sin(2 pi t)``,
    T = 0.01 s) gives ``P(q) = q^2 - 1.99605 q + 1`` (printed rounded: 1.9961).

    Parameters
    ----------
    frequency : float, optional
        In Hz (cycles per second); ``0 < frequency < 1 / (2 dt)``.
    dt : float
        Sampling period in seconds, ``> 0``.
    omega : float, optional
        Angular frequency in rad/s, instead of ``frequency`` (give exactly one).

    Raises
    ------
    ValidationError
        ``dt`` not positive, frequency missing / both given / not positive / at or above Nyquist.
    """

    __slots__ = ("omega",)
    omega: float
    dt: float  # a sinusoid's polynomial depends on the sampling period: always given

    def __init__(self, frequency: float | None = None, dt: float | None = None, *,
                 omega: float | None = None) -> None:
        if dt is None:
            raise ValidationError("Sinusoid needs the sampling period dt (> 0), e.g. Sinusoid(1.0, dt=0.01)")
        dt = as_positive_float("dt", dt)
        if (frequency is None) == (omega is None):
            raise ValidationError(
                "give exactly one of frequency (Hz) and omega (rad/s); "
                f"found frequency={frequency!r}, omega={omega!r}"
            )
        if frequency is not None:
            f = as_positive_float("frequency", frequency)
            w = 2.0 * math.pi * f
        else:
            w = as_positive_float("omega", omega)
            f = w / (2.0 * math.pi)
        nyq = 1.0 / (2.0 * dt)
        if not f < nyq:
            raise ValidationError(
                f"frequency must be below the Nyquist frequency 1/(2 dt) = {nyq:g} Hz "
                f"(omega < pi/dt = {math.pi / dt:g} rad/s); found {f:g} Hz (omega = {w:g} rad/s)"
            )
        theta = w * dt
        roots = [complex(math.cos(theta), math.sin(theta)), complex(math.cos(theta), -math.sin(theta))]
        super().__init__([1.0, -2.0 * math.cos(theta), 1.0], dt=dt,
                         label=f"sinusoid {f:g} Hz", roots=roots)
        object.__setattr__(self, "omega", float(w))

    @property
    def frequency(self) -> float:
        """Frequency in Hz."""
        return self.omega / (2.0 * math.pi)

    @property
    def theta(self) -> float:
        """Angle per sample ``omega dt`` in rad (the modes are ``exp(+-j theta)``)."""
        return self.omega * self.dt

    def signal(self, steps: int, amplitude: float = 1.0, phase: float = 0.0) -> NDArray[np.float64]:
        """``amplitude sin(omega dt k + phase)`` for ``k = 0..steps-1``, shape (steps,)."""
        steps = as_int("steps", steps, 0)
        amplitude, phase = as_real("amplitude", amplitude), as_real("phase", phase)
        return amplitude * np.sin(self.theta * np.arange(steps) + phase)

    def __repr__(self) -> str:
        return f"Sinusoid({self.frequency:g}, dt={self.dt:g})"


class Polynomial(NoiseModel):
    """Any noise model given by its annihilating polynomial (highest power first).

    Parameters
    ----------
    coefficients : (r + 1,) array_like
        Real, finite, leading coefficient non-zero (the polynomial is made monic).  Read as
        ``P(q)`` or, equivalently, ``P(q^-1)`` (same list).  Every root must lie on the unit
        circle.  E.g. ``[1, -2, 1]`` is a ramp, ``[1, 1]`` the alternating ``(-1)^k``.
    dt : float, optional
        The sampling period the polynomial was built for (checked against the plant's).
    tol : float
        Tolerance on ``| |z| - 1 |`` for the roots (default 1e-6).

    Raises
    ------
    ValidationError
        Non-finite, complex, empty or constant coefficients, a zero leading coefficient, or a
        root off the unit circle.
    """

    __slots__ = ()

    def __init__(self, coefficients: ArrayLike, *, dt: float | None = None,
                 tol: float = UNIT_CIRCLE_TOL) -> None:
        c = _check_coefficients("coefficients", coefficients)
        super().__init__(c, dt=dt, label=f"polynomial of degree {c.size - 1}", tol=tol)
