"""Starting points of the well-conditioned designs: robust placements (scipy YT / KNV0), random
eigenstructure assignments, Kalman gains, and the reference pole choices of region mode
(:func:`naive_poles`, :func:`suggested_region`, :func:`start_real_counts`).
"""

from __future__ import annotations

import warnings
from collections.abc import Iterator
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..._validate import as_int, as_poles, as_positive_float
from ...analysis import metrics
from ...classical.placement import place_observer
from ...classical.riccati import filter_are
from ...errors import ValidationError
from ...formulate.well_conditioned import PoleStructure, random_gain_for_poles
from ...model.coerce import as_plant
from ...model.plant import Plant
from ...model.regions import Disk, HalfPlane, Region, Sector

__all__ = [
    "naive_poles",
    "suggested_region",
    "start_real_counts",
    "start_real_count",
    "placement_start",
    "better_yt",
    "riccati_start",
    "fixed_starts",
    "region_starts",
    "iter_region_starts",
    "default_region_starts",
]

#: one region start: (origin, initial gain, pole structure, start poles)
RegionStartSpec = tuple[str, NDArray, PoleStructure, NDArray]


def better_yt(plant: Plant, poles: NDArray, L0: NDArray | None, region: Region,
              scipy_yt: NDArray | None = None) -> NDArray | None:
    """The better-conditioned of ``L0`` and scipy's YT with scipy's defaults (rtol 1e-3, 30 sweeps).

    YT's iterations do not decrease kappa2 monotonically: on COMPleib TG1 at the naive poles scipy's
    defaults (rtol 1e-3, 30 sweeps) give kappa2 9.8e5, ``rtol=1e-6, maxiter=100`` 5.2e6.  ``L0``
    None: scipy's YT alone (None when it fails too).  ``scipy_yt``: that YT gain when the caller has
    computed it (not computed again).
    """
    L1 = scipy_yt if scipy_yt is not None else placement_start(plant, poles, "YT", rtol=1e-3, maxiter=30)
    if L1 is None or L0 is None:
        return L0 if L1 is None else L1

    def key(L):  # inside the region first, then kappa2
        X = plant.A - L @ plant.C
        return (not region.contains(np.linalg.eigvals(X)), metrics.kappa2(X))

    return L1 if key(L1) < key(L0) else L0


def placement_start(plant: Plant, poles: NDArray, method: str, maxiter: int | None = None,
                    rtol: float | None = None) -> NDArray | None:
    """scipy's robust placement (``method`` "YT" or "KNV0"; ``maxiter`` sweeps and ``rtol``, default
    :func:`~optdesign.classical.placement.place_observer`'s) as a start gain; None when it fails."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            opts: dict[str, Any] = {k: v for k, v in (("maxiter", maxiter), ("rtol", rtol)) if v is not None}
            L = place_observer(plant, poles, method=method, **opts)
    except (ValueError, np.linalg.LinAlgError):
        return None
    if not np.all(np.isfinite(L)):
        return None
    return L


def fixed_starts(plant, target, starts, rng, pstruct):
    out = []
    for method in ("YT", "KNV0"):
        if len(out) >= starts:
            break
        if method == "KNV0" and np.any(target.imag != 0):
            continue
        L0 = placement_start(plant, target, method)
        if L0 is not None:
            out.append((method, L0, pstruct))
    tries = 0
    while len(out) < starts and tries < 10 * starts:
        tries += 1
        try:
            L0 = random_gain_for_poles(plant, target, rng)
        except (np.linalg.LinAlgError, ValueError):
            continue
        if np.all(np.isfinite(L0)):
            out.append(("random", L0, pstruct))
    if not out:  # repeated poles YT cannot take and no random start: perturb the poles
        pert = target + 1e-3 * max(1.0, float(np.max(np.abs(target)))) * np.arange(target.size)
        L0 = placement_start(plant, as_poles("poles", pert), "YT")
        out.append(("YT (perturbed poles)", np.zeros((plant.n, plant.p)) if L0 is None else L0, pstruct))
    return out


def riccati_start(plant: Plant, rng: np.random.Generator, k: int) -> NDArray:
    """A stabilizing Kalman gain for a random process noise (works for detectable plants).

    The filter of state-space noise ``F F' + 1e-3 I`` (``F = I`` for ``k = 0``) and ``R = I``;
    zero when :func:`~optdesign.riccati.filter_are` fails.
    """
    n, p = plant.n, plant.p
    F = rng.standard_normal((n, n)) if k else np.eye(n)
    Qs = F @ F.T + 1e-3 * np.eye(n)
    try:
        return filter_are(plant.replace(G=np.eye(n), Q=Qs, R=np.eye(p))).L
    except (ValueError, np.linalg.LinAlgError):
        return np.zeros((n, p))


def start_real_counts(n: int) -> tuple[int, ...]:
    """Numbers of real poles of the sampled region starts, in the order they are used.

    The achievable counts are ``n, n - 2, ..., n mod 2``; they are cycled through as ``n - 2``
    (one complex pair), ``n`` (all real), ``n mod 2`` (as many pairs as possible), then the
    others nearest ``n / 2`` first -- so that for ``n = 2, 3`` the first two sampled starts have
    different patterns (measured on seed 001's aircraft, n = 3: the best design has a complex
    pair, which an all-real start misses).

    Parameters
    ----------
    n : int
        Plant order, ``>= 0``.

    Returns
    -------
    tuple of int
        Distinct counts; pass the ``k``-th (cyclically) to ``Region.sample_poles(n, rng, n_real=...)``.

    Raises
    ------
    ValidationError
        ``n`` not a nonnegative integer.

    Examples
    --------
    >>> start_real_counts(3), start_real_counts(6)
    ((1, 3), (4, 6, 0, 2))
    """
    n = as_int("n", n, 0)
    counts = list(range(n, -1, -2))
    order: list[int] = []
    for c in [n - 2, n, n % 2] + sorted(counts, key=lambda c: (abs(c - n / 2), c)):
        if c in counts and c not in order:
            order.append(c)
    return tuple(order)


def start_real_count(n: int, k: int) -> int:
    """The real-pole count of the ``k``-th sampled region start (``start_real_counts(n)`` cycled).

    Examples
    --------
    >>> [start_real_count(2, k) for k in range(3)]
    [0, 2, 0]
    """
    k = as_int("k", k, 0)
    counts = start_real_counts(n)
    return counts[k % len(counts)]


def suggested_region(plant: Plant, *, decay_factor: float = 1.5, damping: float = 0.5) -> Region:
    """A pole region chosen from the plant: faster than it, damped, and bounded.

    ``HalfPlane(alpha) & Sector.from_damping(damping) & Disk(0, 2 max(rho(A), alpha))`` with
    ``alpha = decay_factor x`` the slowest open-loop decay ``min |Re lambda(A)|`` (at least 1 % of
    the spectral radius ``rho(A)``).  An unobservable mode is an eigenvalue of every ``A - LC``:
    ``alpha`` is lowered to 0.9 times its decay so that the region stays reachable.  The region of
    the COMPleib region-mode benchmark (``benchmarks/bench_placement.py``); continuous time only.

    Parameters
    ----------
    plant : Plant
        Continuous time (``plant.dt`` None).
    decay_factor : float, default 1.5
    damping : float in (0, 1), default 0.5

    Returns
    -------
    Region

    Raises
    ------
    ValidationError
        A discrete-time plant, an unobservable mode that is not stable, or a bad factor / damping.
    """
    if not isinstance(plant, Plant):
        raise ValidationError(f"plant must be an optdesign.Plant; found {type(plant).__name__}")
    if plant.is_discrete:
        raise ValidationError("suggested_region is for continuous-time plants (a half-plane and a sector); "
                              "for a discrete plant give a Disk inside the unit circle")
    factor = as_positive_float("decay_factor", decay_factor)
    w = np.linalg.eigvals(plant.A)
    rho = float(np.max(np.abs(w)))
    alpha = factor * max(float(np.min(np.abs(w.real))), 0.01 * rho)
    un = plant.unobservable_modes()
    if un.size:
        if np.max(un.real) >= 0:
            raise ValidationError(f"the unobservable mode(s) {un} are not stable: no observer is stable")
        alpha = min(alpha, 0.9 * float(np.min(-un.real)))
    return HalfPlane(alpha) & Sector.from_damping(damping) & Disk(0.0, 2.0 * max(rho, alpha))


def naive_poles(plant: Plant, region: Region) -> NDArray[np.complex128]:
    """A simple pole choice in a region: the open-loop poles moved into it.

    The reference point of region-mode designs (the design is never worse than scipy's YT
    placement at these poles, see :func:`well_conditioned_observer`).  Each eigenvalue of
    ``A`` is projected onto the region (:meth:`Region.project`) and moved 5 % of the way to
    the region's interior point ``x0`` (strictly inside, by convexity); poles within 1e-9 of
    the real axis are made real and the ``k``-th real pole (ascending, ``k = 0, 1, ...``) is
    shifted by ``-1e-3 (k + 1) |x0|`` when it stays inside.  Poles that still coincide (or
    are closer than ``1e-3`` times the region's inner radius) are moved further toward ``x0``
    until they are apart -- a pole repeated more than ``rank(C)`` times cannot be assigned
    with a diagonalizable ``A - LC``.

    Parameters
    ----------
    plant : Plant
        Uses ``A`` (n, n).
    region : Region
        The pole region (nonempty interior).

    Returns
    -------
    (n,) ndarray of complex
        Conjugate-closed, distinct poles strictly inside ``region``; real poles first (ascending),
        then pairs ``z, conj(z)`` with ``Im z > 0``.

    Raises
    ------
    ValidationError
        ``plant`` is not a Plant or ``region`` not a Region.

    References
    ----------
    ``benchmarks/bench_placement.py`` (COMPleib region mode, "YT @ naive").
    """
    plant = as_plant(plant)
    if not isinstance(region, Region):
        raise ValidationError(f"region must be an optdesign.regions.Region; found {type(region).__name__}")
    w = np.linalg.eigvals(plant.A)
    x0 = float(region.interior_point())
    rho = max(-float(region.distance([x0])[0]), 1e-300)  # a disk of radius rho around x0 is inside
    tau = 1e-3 * rho  # clearance from the boundary
    sep = 1e-4 * rho  # minimum distance between two poles

    def inside(c: complex) -> bool:
        return bool(region.distance([c])[0] < -tau)

    z = region.project(w)
    z = z + 0.05 * (x0 - z)
    z = np.where(np.abs(z.imag) < 1e-9, z.real + 0j, z)
    reals: list[complex] = []
    uppers: list[complex] = []
    for k, v in enumerate(sorted(z, key=lambda v: (v.real, v.imag))):
        if v.imag == 0:
            shifted = complex(v.real - 1e-3 * (k + 1) * abs(x0))
            reals.append(shifted if inside(shifted) else complex(v.real))
        elif v.imag > 0:  # one member per pair (the projection keeps conjugate symmetry)
            uppers.append(complex(v))

    def spread(poles: list[complex], step: complex) -> list[complex]:
        """Move poles that (nearly) coincide with an earlier one toward x0 until they are apart."""
        out: list[complex] = []
        for v in poles:
            c = v
            for m in range(1, 1000):
                if inside(c) and all(abs(c - a) > sep for a in out):
                    break
                if abs(v - x0) > 20 * sep:
                    c = v + min(0.05 + 0.01 * m, 0.95) * (x0 - v)
                else:  # next to x0: step inside the disk of radius rho around it
                    c = v + ((m + 1) // 2) * sep * step * (1 if m % 2 else -1)
            out.append(c)
        return out

    re = sorted(c.real for c in spread(reals, 1.0))
    cp = sorted(spread(uppers, 1j), key=lambda c: (c.real, c.imag))
    cp = [c if c.imag > 0 else complex(c.real, sep) for c in cp]
    res = np.empty(len(re) + 2 * len(cp), dtype=complex)
    res[: len(re)] = re
    res[len(re) :: 2] = cp
    res[len(re) + 1 :: 2] = np.conj(cp)
    return res


def default_region_starts(n: int, objective: str = "kappa2") -> int:
    """Starts of a region design on the placement engine when none are given: 8 up to ``n = 12``, 4 up
    to 24, then 2 (the region analogue of the fixed-pole engine's
    :func:`~optdesign.engines.eigenstructure_fixed.default_starts`); for eta 16 at every size.

    Measured (issue 28): on random plants n = 5, p = 1 and n = 8, p = 2, 8 engine starts reach kappa2
    121.1 and 114.7 where 3 reach 248.6 and 122.6, at 1.1-1.8x their CPU.  Above n = 12 (random plants of
    ``benchmarks/bench_region.py``, region ``HalfPlane(0.5) &
    Sector.from_damping(0.5) & Disk(0, 5)``, CPU per design): at n = 14, 16, 20, 24 (p = 4..6, 9
    plants) 4 starts take 0.52-0.75x the CPU of 8 and end within 1 % of their kappa2 (at most
    +0.95 %, n = 16; 0 to +0.4 % at n = 20 and 24); at n = 30, p = 7 (3 plants) 2 starts take 9-11 s
    against 36-40 s for 8, within 0.4 % (61.67 vs 61.64 on the benchmark's plant, where the commit
    before issue 28 reached 386.7 in 150 s).  Pass ``starts`` for more.

    eta (the engine from every start, IPOPT from the first up to n = 10 -- from round 11; the first two
    before --, :meth:`WellConditionedProblem.solve`):
    on the 50 plants n <= 10 of ``benchmarks/bench_region.py`` the engine from 16 starts matched or beat
    IPOPT from 8 on every plant where the engine from 8 did not (COMPleib DIS2 0.0338 from its 15th
    start, HE3, random n = 4, 9), and with IPOPT from two starts beside it was never more than 1e-3 worse
    than IPOPT from 8 (12 starts: 2 plants worse, DIS2 +79 %; 24: none, 1.2x the CPU of 16).  At
    n = 20 and 30 (p = 5, 7; both stopped by a 150 s limit) 16 starts ended at 57.0 and 96.3 against
    60.9 and 110.5 with 8; with 4 starts at n = 20, 65.1.  Round 11 (each start freed from its start
    point alone, 16 members): 24 starts took 1.07x the CPU of 16 on 49 plants n <= 10 (median 1.63 s
    against 1.46 s), DIS3 -4.9 % but TG1 +8.8 %.  Above n = 10 the 16 members are pruned to 4 after the
    first free-pole stage (round 12), so the starts past the 4th cost one stage each.
    """
    n = as_int("n", n, 1)
    if objective == "eta":
        return 16
    return 8 if n <= 12 else 4 if n <= 24 else 2


def region_starts(plant: Plant, region: Region, starts: int, rng: np.random.Generator,
                  mask: NDArray | None) -> list[RegionStartSpec]:
    """Start 0: scipy YT at :func:`naive_poles`; start 1: the Kalman gain for ``Q = I, R = I``;
    then YT at poles sampled in the region (real/complex patterns of :func:`start_real_counts`).
    Per start ``(origin, L0, structure, poles)``: ``poles`` are the placed poles (or those of
    ``A - L0 C`` for a Kalman gain or a masked one).  The list of :func:`iter_region_starts`.

    Measured on COMPleib (region of ``benchmarks/bench_placement.py``): AC7 ends at kappa2 22.8
    from the Kalman start, at 3e6 from sampled poles; HE5 at 76 from the naive start.
    """
    return list(iter_region_starts(plant, region, starts, rng, mask))


def iter_region_starts(plant: Plant, region: Region, starts: int, rng: np.random.Generator,
                       mask: NDArray | None, *, kalman: bool = True, sweeps: int | None = None,
                       scipy_yt: NDArray | None = None) -> Iterator[RegionStartSpec]:
    """The starts of :func:`region_starts`, one at a time: each start's placement is computed only
    when the caller asks for it (a design that stops early computes no placement it does not run).

    ``kalman=False``: no Kalman start 1 -- start 1 and after sample poles in the region (the
    Kalman gain is still the fallback of a start whose placement fails).  The samples drawn from
    ``rng`` are those of :func:`region_starts` (its Kalman start draws nothing).  ``sweeps``: scipy
    YT's sweeps at the sampled poles (default :func:`~optdesign.classical.placement.place_observer`'s).
    Start 0 is scipy's YT with scipy's defaults (rtol 1e-3, 30 sweeps: the reference of the guarantee
    "never worse than scipy YT at the naive poles"); without ``sweeps`` (IPOPT's starts) the better
    of it and place_observer's (rtol 1e-6, 100 sweeps), :func:`better_yt`.  The engine's starts give
    ``sweeps``: place_observer's run was 5-10 % of a small plant's region design (issue 28, COMPleib
    AC2: 56 ms of 0.6 s).  ``scipy_yt``: scipy's YT at the naive poles when the caller has it (the
    engine's start 0 beside IPOPT's starts; :func:`better_yt`).
    """
    n = plant.n
    observable = plant.is_observable()
    kalman_used = False
    n_sampled = 0
    for k in range(starts):
        P0 = None
        L0: NDArray | None  # None while no placement has succeeded
        if k == 1 and kalman and not kalman_used:
            L0 = riccati_start(plant, rng, 0)
            st = PoleStructure.of(np.linalg.eigvals(plant.A - L0 @ plant.C), tol=1e-6)
            origin = "Kalman gain (Q = I)"
            kalman_used = True
        else:
            if k == 0:
                P0 = naive_poles(plant, region)
                origin = "naive poles + YT"
            else:
                P0 = region.sample_poles(n, rng, n_real=start_real_count(n, n_sampled))
                n_sampled += 1
                origin = "region sample + YT"
            st = PoleStructure.of(P0)
            if k == 0:  # scipy's YT; for IPOPT's starts (no sweeps) the better of it and place_observer's
                ours = placement_start(plant, P0, "YT") if sweeps is None and observable else None
                L0 = better_yt(plant, P0, ours, region, scipy_yt) if observable else None
            else:
                L0 = placement_start(plant, P0, "YT", sweeps) if observable else None
            if L0 is None and observable:
                try:
                    L0 = random_gain_for_poles(plant, P0, rng)
                    origin = origin.replace("+ YT", "+ random assignment")
                except (np.linalg.LinAlgError, ValueError):
                    L0 = None
            if L0 is None:  # detectable but unobservable (or placement failed): a Kalman gain
                L0 = riccati_start(plant, rng, 0 if not kalman_used else k)
                origin = "Kalman gain (Q = I)" if not kalman_used else "Kalman gain (random Q)"
                kalman_used = True
                st = PoleStructure.of(np.linalg.eigvals(plant.A - L0 @ plant.C), tol=1e-6)
                P0 = None
        if mask is not None:
            L0 = np.where(mask, L0, 0.0)
            st = PoleStructure.of(np.linalg.eigvals(plant.A - L0 @ plant.C), tol=1e-6)
            P0 = None
        poles = np.linalg.eigvals(plant.A - L0 @ plant.C) if P0 is None else np.asarray(P0, dtype=complex)
        yield origin, L0, st, poles
