r"""Guaranteed and actual stability margins of a Kalman filter's loop (seed 002): the margins a disk
radius guarantees (:func:`margins_from_radius`) and the loop-at-a-time and simultaneous margins of a
given filter (:func:`filter_margins`, :class:`FilterMargins`).  Split from
:mod:`optdesign.analysis.robustness` (which still exports these names).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._deadline import Deadline
from .._validate import as_frequencies, as_real
from ..errors import ValidationError
from ..model.plant import Plant
from .frequency import (
    adaptive_minimize,
    as_gain,
    frequency_grid,
    frequency_points,
)
from .robustness import (
    CircleConditionResult,
    circle_condition,
    is_diagonal,
    is_stable_spectrum,
    resolve_R,
    sqrtm_pd,
    transfer_at,
)

__all__ = ["margins_from_radius", "FilterMargins", "filter_margins"]

_EPS = np.finfo(float).eps


# --------------------------------------------------------------------------- margins
def margins_from_radius(alpha: float, skew: float = 1.0) -> tuple[tuple[float, float], float]:
    r"""Gain interval and phase margin (deg) guaranteed by a disk margin ``alpha``.

    ``skew = 1`` (the circle-condition disk): perturbations ``f`` with ``|1/f - 1| < alpha``,
    gains ``(1/(1+alpha), 1/(1-alpha))`` and phase ``2 arcsin(alpha/2)``; ``alpha = 1`` gives
    ``(1/2, inf)`` and 60 deg.  ``skew = 0`` (balanced disk): ``f = (1 + d/2)/(1 - d/2)``,
    ``|d| < alpha``, gains ``((2-alpha)/(2+alpha), (2+alpha)/(2-alpha))``, phase ``2 atan(alpha/2)``.

    Raises
    ------
    ValidationError
        ``alpha`` not a real number, ``skew`` not 0 or 1.  (A NaN ``alpha`` -- a margin not
        computed -- gives no margin; ``inf`` the whole disk.)
    """
    if isinstance(alpha, (float, np.floating)) and not math.isfinite(alpha):
        a = float(alpha)
    else:
        a = as_real("alpha", alpha)
    if skew not in (0.0, 1.0) or isinstance(skew, bool):
        raise ValidationError(f"skew must be 0 (balanced) or 1 (circle); found {skew!r}")
    if not a > 0:
        return (1.0, 1.0), 0.0
    if skew == 1.0:
        hi = 1.0 / (1.0 - a) if a < 1.0 else math.inf
        return (1.0 / (1.0 + a), hi), math.degrees(2.0 * math.asin(min(a, 2.0) / 2.0))
    if skew == 0.0:
        hi = (2.0 + a) / (2.0 - a) if a < 2.0 else math.inf
        lo = (2.0 - a) / (2.0 + a) if a < 2.0 else 0.0
        return (lo, hi), math.degrees(2.0 * math.atan(a / 2.0))
    raise ValidationError(f"skew must be 0 (balanced) or 1 (circle); found {skew!r}")


@dataclass(frozen=True, eq=False)
class FilterMargins:
    r"""Stability margins of a filter loop broken at the filter input (innovation).

    Perturbation model: ``x_hat' = A x_hat + L Delta (y - C x_hat)``, error dynamics
    ``A - L Delta C`` (discrete: ``x_hat[k+1] = ...``, same matrices).

    Attributes
    ----------
    discrete : bool
    stable : bool
        Whether the nominal error dynamics ``A - L C`` are stable (margins are NaN otherwise).
    R_diagonal : bool
        Whether R is diagonal: the per-channel (and simultaneous-diagonal) guarantees need it.
    circle : CircleConditionResult
        The circle condition of L.
    implied_radius : float
        Disk radius implied by the circle condition alone: 1 in continuous time, ``1/sqrt(
        lambda_max(R^-1 V))`` in discrete time, 0 when the condition fails.
    guaranteed_gain_margin : (float, float)
        ``(1/(1+a), 1/(1-a))`` with ``a = implied_radius`` (continuous Kalman filter: ``(0.5, inf)``).
    guaranteed_phase_margin : float
        ``2 arcsin(a/2)`` in degrees (continuous Kalman filter: 60).
    guarantee_scope : str
        Which perturbations these guarantees cover (simultaneous diagonal perturbations when R is
        diagonal; only uniform ``delta I`` perturbations otherwise).
    radius : float
        Actual multiloop circle radius ``min_w sigma_min(R^-1/2 T R^1/2) = 1 / max_w sigma_max(
        R^-1/2 S R^1/2)``, ``S = T^-1``: every ``Delta`` with ``sigma_max(R^-1/2 (Delta^-1 - I) R^1/2)
        < radius`` keeps the filter stable (for diagonal R: all diagonal ``Delta`` with
        ``|1/delta_i - 1| < radius`` simultaneously).  ``>= implied_radius`` for a Kalman filter.
    gain_margin_lower, gain_margin_upper : (p,) ndarrays
        Loop-at-a-time gain margins of each channel (others closed at nominal gain 1): the
        channel gain may range over ``(lower, upper)``.  ``-inf`` / ``inf`` if never destabilizing.
    phase_margin : (p,) ndarray
        Loop-at-a-time phase margins (deg); ``inf`` if no pure phase destabilizes.
    phase_crossover : (p,) ndarray
        Frequency (rad/s) where the phase margin is attained.
    disk_margin : (p,) ndarray
        Loop-at-a-time balanced disk margin ``2 / max_w |S_ii - T_ii|`` (Seiler et al.).
    circle_disk_margin : (p,) ndarray
        Loop-at-a-time skew-1 disk margin ``1 / max_w |S_ii|`` (the per-channel circle radius).
    notes : tuple of str
    complete : bool
        False when ``time_limit`` stopped the analysis (the margins not computed are NaN).
    """

    discrete: bool
    stable: bool
    R_diagonal: bool
    circle: CircleConditionResult
    implied_radius: float
    guaranteed_gain_margin: tuple[float, float]
    guaranteed_phase_margin: float
    guarantee_scope: str
    radius: float
    gain_margin_lower: NDArray[np.float64]
    gain_margin_upper: NDArray[np.float64]
    phase_margin: NDArray[np.float64]
    phase_crossover: NDArray[np.float64]
    disk_margin: NDArray[np.float64]
    circle_disk_margin: NDArray[np.float64]
    notes: tuple[str, ...] = field(default_factory=tuple)
    complete: bool = True

    @property
    def simultaneous_gain_margin(self) -> tuple[float, float]:
        """Gain interval guaranteed by ``radius`` (all channels at once if R is diagonal)."""
        return margins_from_radius(self.radius)[0]

    @property
    def simultaneous_phase_margin(self) -> float:
        """Phase margin (deg) guaranteed by ``radius`` (all channels at once if R is diagonal)."""
        return margins_from_radius(self.radius)[1]

    def summary(self) -> str:
        lo, hi = self.guaranteed_gain_margin
        lines = [
            f"filter loop broken at the filter input ({'discrete' if self.discrete else 'continuous'}, "
            f"{'stable' if self.stable else 'UNSTABLE'} nominal error dynamics)",
            self.circle.summary(),
            f"guaranteed by the circle condition: gain ({lo:.4g}, {hi:.4g}), "
            f"phase +-{self.guaranteed_phase_margin:.4g} deg -- {self.guarantee_scope}",
            f"actual multiloop radius {self.radius:.4g}",
        ]
        def margin(x: float, unit: str = "") -> str:  # an infinite margin: no crossing, not "inf ... at nan"
            return "infinite (no crossing)" if math.isinf(x) else f"{x:.4g}{unit}"

        for i in range(self.gain_margin_lower.size):
            pm = self.phase_margin[i]
            phase = margin(pm) if math.isinf(pm) else f"{pm:.4g} deg at {self.phase_crossover[i]:.4g} rad/s"
            lines.append(
                f"  channel {i}: gain margin {margin(self.gain_margin_lower[i])} (lower), "
                f"{margin(self.gain_margin_upper[i])} (upper); phase margin {phase}; "
                f"disk {self.disk_margin[i]:.4g}, circle disk {self.circle_disk_margin[i]:.4g}"
            )
        lines.extend(self.notes)
        return "\n".join(lines)

    def __repr__(self) -> str:
        """One short line (:meth:`summary` has everything): time domain, stability, the circle
        condition, the guaranteed and the actual margins, the worst channel."""
        lo, hi = self.guaranteed_gain_margin
        circle = "holds" if self.circle.passed else "fails"
        domain = "discrete" if self.discrete else "continuous"
        parts = [f"{domain}, {'stable' if self.stable else 'UNSTABLE'}",
                 f"circle condition {circle}",
                 f"guaranteed gain ({lo:.3g}, {hi:.3g}) phase +-{self.guaranteed_phase_margin:.3g} deg",
                 f"radius {self.radius:.3g}"]
        p = self.gain_margin_lower.size
        if p:
            with np.errstate(invalid="ignore"):
                k = int(np.nanargmin(self.disk_margin)) if np.any(np.isfinite(self.disk_margin)) else 0
            parts.append(f"{p} channel{'s' if p > 1 else ''}, worst {k}: gain "
                         f"({self.gain_margin_lower[k]:.3g}, {self.gain_margin_upper[k]:.3g}) phase "
                         f"{self.phase_margin[k]:.3g} deg disk {self.disk_margin[k]:.3g}")
        if not self.complete:
            parts.append("incomplete (time limit)")
        return f"FilterMargins({'; '.join(parts)})"


def _crossings(g: Callable[[NDArray], NDArray], grid: NDArray, v: NDArray) -> list[float]:
    """All roots of a real scalar function of frequency found by sign changes of ``v = g(grid)``."""
    from scipy.optimize import brentq

    roots = list(grid[v == 0.0])
    s = np.sign(v)
    idx = np.flatnonzero(s[:-1] * s[1:] < 0)
    for i in idx:
        try:
            roots.append(brentq(lambda x: float(g(np.array([x]))[0]), grid[i], grid[i + 1], xtol=1e-14,
                                rtol=1e-13))
        except ValueError:  # pragma: no cover - sign change guaranteed
            continue
    return roots


def filter_margins(
    plant: Plant, L: ArrayLike, *, R: ArrayLike | None = None, omega: ArrayLike | None = None,
    time_limit: float | Deadline | None = None,
) -> FilterMargins:
    r"""Guaranteed and actual stability margins of a filter, loop broken at the filter input.

    The loop is broken at the innovation ``nu = y - C x_hat`` where it enters the gain: a perturbation
    ``Delta`` gives error dynamics ``A - L Delta C`` (module docstring).  Reported:

    * the margins *implied by the circle condition* (continuous Kalman filter: gain ``(1/2, inf)``,
      phase ``+-60 deg``; discrete: the smaller disk ``1/sqrt(lambda_max(R^-1 V))``).  With diagonal
      R they hold for diagonal perturbations in **all channels simultaneously**, but not for a gain
      and a phase change together beyond ``k cos(phi) > 1/2`` nor for crossfeed beyond the norm
      bound; with non-diagonal R only for uniform perturbations ``delta I``;
    * the actual multiloop radius ``min_w sigma_min(R^-1/2 T R^1/2)``;
    * per channel (loop-at-a-time, the other channels closed): gain margins, phase margin, balanced
      and skew-1 disk margins, from ``M = C (sI - A + L C)^-1 L``: a perturbation ``delta`` in channel
      i puts a closed-loop eigenvalue at ``s`` iff ``1 + (delta - 1) M_ii(s) = 0``.  Crossings are
      located on :func:`frequency_grid` by sign changes of ``Im M_ii`` and ``Re M_ii - 1/2`` and
      refined with Brent's method.

    Parameters
    ----------
    plant : Plant
    L : (n, p) array_like
    R : (p, p) array_like, optional
        Default ``plant.R``.
    omega : array_like, optional
        Seed grid (rad/s, finite, ``>= 0``) instead of :func:`frequency_grid`.
    time_limit : float, optional
        Seconds for the whole analysis (``None``: no limit), shared by its stages (circle
        condition, multiloop radius, channel by channel).  When it runs out, the margins not yet
        computed are NaN, ``complete`` is False and a note says where it stopped.

    Returns
    -------
    FilterMargins

    Raises
    ------
    DimensionError, NotFiniteError, NotPositiveDefiniteError, ValidationError
        As :func:`circle_condition`.

    References
    ----------
    Seed 002 (S. J. Lee), Theorem 2, eqs (20)-(24); Lehtomaki, Sandell & Athans (1981); Seiler,
    Packard & Gahinet (2020).

    Examples
    --------
    >>> import numpy as np
    >>> from optdesign import Plant, filter_margins, kalman
    >>> plant = Plant([[0., 1.], [-4., -0.2]], np.eye(2), Q=np.diag([0.1, 1.0]), R=np.diag([0.5, 2.0]))
    >>> fm = filter_margins(plant, kalman(plant).L)
    >>> fm.guaranteed_gain_margin, round(fm.guaranteed_phase_margin)   # R diagonal: (1/2, inf), 60 deg
    ((0.5, inf), 60)
    """
    deadline = Deadline.of(time_limit)
    L = as_gain(plant, L)
    R = resolve_R(plant, R, "filter_margins")
    seed = None if omega is None else as_frequencies("omega", omega)
    circ = circle_condition(plant, L, R=R, omega=seed, time_limit=deadline)
    p, disc = plant.p, plant.is_discrete
    R_diag = is_diagonal(R)
    notes: list[str] = []
    Acl = plant.A - L @ plant.C
    stable = is_stable_spectrum(np.linalg.eigvals(Acl), disc)
    if circ.passed:
        if disc:
            lam = float(np.max(np.linalg.eigvals(np.linalg.solve(R, 0.5 * (circ.V + circ.V.T))).real))
            implied = 1.0 / math.sqrt(lam)
        else:
            implied = 1.0
    else:
        implied = 0.0
        notes.append("the circle condition fails, so it implies no margin" if circ.complete else
                     "the circle-condition search was stopped by the time limit, so it implies no margin")
    (glo, ghi), gpm = margins_from_radius(implied)
    if R_diag:
        scope = ("diagonal perturbations delta_i with |1/delta_i - 1| < radius in all channels "
                 "simultaneously (R is diagonal); not mixed gain+phase beyond the disk, not crossfeed")
    else:
        scope = ("R is NOT diagonal: no per-channel guarantee; only perturbations commuting with R^1/2, "
                 "e.g. the uniform delta*I in all channels")
        notes.append("R is not diagonal: the per-channel gain/phase statement of seed 002 Theorem 2 "
                     "does not apply")
    margins = np.full((6, p), np.nan)  # gain lower/upper, phase, phase crossover, disk, circle disk
    def result(radius: float, complete: bool) -> FilterMargins:  # the rows of margins in field order
        lo, up, pm, pc, dm, cdm = margins
        return FilterMargins(disc, stable, R_diag, circ, implied, (glo, ghi), gpm, scope, radius, lo, up, pm,
                             pc, dm, cdm, tuple(notes), complete=complete)
    if not stable:
        notes.append("A - L C is unstable: margins of an unstable loop are not defined (NaN)")
        return result(float("nan"), circ.complete)
    grid = frequency_grid(plant, L) if seed is None else np.unique(seed)
    grid = np.union1d(grid, circ.omega)
    if plant.dt is not None:  # discrete
        grid = grid[grid <= math.pi / plant.dt]
    grid = np.unique(grid)
    pts_of = lambda w: frequency_points(plant, np.asarray(w, dtype=float))  # noqa: E731

    def M_of(w: NDArray) -> NDArray:
        return transfer_at(Acl, L, plant.C, pts_of(w))

    Rh, Rih = sqrtm_pd(R)

    def neg_smax(w: NDArray) -> NDArray:
        S = np.eye(p)[None] - M_of(w)
        return -np.linalg.svd(Rih[None] @ S @ Rh[None], compute_uv=False)[:, 0]

    radius = float("nan")
    complete = circ.complete and not deadline.expired
    if complete:
        _, v, complete = adaptive_minimize(neg_smax, grid, log=not disc, deadline=deadline, full_output=True)
        radius = 1.0 / float(-np.min(v)) if complete else radius
    Mgrid = M_of(grid) if complete else None
    for i in range(p):
        if Mgrid is None or deadline.expired:
            complete = False
            break
        margins[:, i] = _channel_margins(M_of, grid, Mgrid[:, i, i], i, plant.dt)  # dt None: continuous
    if not complete:
        done = int(np.sum(np.isfinite(margins[4])))
        notes.append(f"time_limit {deadline.limit:g} s reached: margins computed for {done} of {p} channel(s)"
                     + ("" if np.isfinite(radius) else ", no multiloop radius") + " (the rest are NaN)")
    return result(radius, complete)


def _channel_margins(M_of: Callable[[NDArray], NDArray], grid: NDArray, Mg: NDArray, i: int,
                     dt: float | None) -> NDArray[np.float64]:
    """Loop-at-a-time margins of channel ``i`` from ``M = C (sI - A + L C)^-1 L`` (``Mg``: ``M_ii`` on
    ``grid``): gain lower/upper, phase margin (deg), its crossover, balanced and skew-1 disk margins."""

    def Mi(w: NDArray) -> NDArray:
        return M_of(w)[:, i, i]

    log = dt is None
    # M_ii is real at w = 0 (and at the Nyquist frequency in discrete time): always candidates
    ends = [0.0] + ([math.pi / dt] if dt is not None else [])
    roots = ends + _crossings(lambda w: Mi(w).imag, grid, Mg.imag)
    deltas = []
    for w0 in roots:
        m = Mi(np.array([w0]))[0]
        if abs(m) > 1e-14:
            deltas.append(1.0 - 1.0 / m.real)
    d = np.asarray(deltas)
    ghi = float(np.min(d[d > 1.0], initial=np.inf))
    glo = float(np.max(d[d < 1.0], initial=-np.inf))
    best, bw = np.inf, np.nan
    for w0 in _crossings(lambda w: Mi(w).real - 0.5, grid, Mg.real - 0.5):
        m = Mi(np.array([w0]))[0]
        phi = abs(math.degrees(np.angle(1.0 - 1.0 / m)))
        if phi < best:
            best, bw = phi, w0
    _, v0 = adaptive_minimize(lambda w: -np.abs(1.0 - 2.0 * Mi(w)), grid, log=log,
                              values=-np.abs(1.0 - 2.0 * Mg))
    _, v1 = adaptive_minimize(lambda w: -np.abs(1.0 - Mi(w)), grid, log=log, values=-np.abs(1.0 - Mg))
    return np.array([glo, ghi, best, bw, 2.0 / float(-np.min(v0)), 1.0 / float(-np.min(v1))])
