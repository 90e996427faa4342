"""Starting points of the inverse Kalman engine (:mod:`optdesign.engines.inverse_kalman_engine`): the
decision covariances its SQP starts from (a scaled identity whose Kalman poles are closest to the targets,
the scaled nominal, seeded random covariances, the rescue starts), and the scipy Kalman filter of a noise
covariance they are measured by.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sl
from numpy.typing import NDArray

from .._deadline import Deadline
from ..classical.placement import pole_error
from ..formulate.inverse_kalman import spectral_terms
from ..model.plant import Plant
from .inverse_kalman_setup import SCALE_FLOOR, EngineSetup
from .spectral_factor import initial_null_vectors, spectral_blocks
from .tolerances import NOMINAL_EIG_FLOOR

__all__ = ["stable_mask", "scipy_kalman", "scaled_start", "placement_scale", "decision_starts",
           "rescue_starts", "homotopy_starts", "SCALE_GRID", "NOMINAL_EIG_FLOOR", "RESCUE_FACTORS",
           "HOMOTOPY_SCALES"]

#: the scales of a start tried for its Kalman poles: 25 points, log-spaced over 12 decades around 1
#: (a start whose best scale is at an end of this grid has none close: the placement scale is used)
SCALE_GRID = np.logspace(-6, 6, 25)
#: the rescue starts' scales, as multiples of the scaled identity's (measured on repeated targets:
#: the feasible Q may be one or two decades from every scaled identity)
RESCUE_FACTORS = (10.0, 0.1, 100.0)


def stable_mask(z: NDArray, discrete: bool) -> NDArray[np.bool_]:
    """Elementwise stability of the poles ``z``: ``|z| < 1`` (discrete) or ``Re z < 0`` (continuous)."""
    return np.abs(z) < 1.0 if discrete else np.real(z) < 0.0


def scipy_kalman(plant: Plant, Q: NDArray) -> tuple[NDArray, NDArray, NDArray] | None:
    """(L, P, poles) of the Kalman filter of the state-space noise Q by scipy (no validation), or
    None where there is no stabilizing solution."""
    A, C, R = plant.A, plant.C, np.asarray(plant.R, dtype=float)
    try:
        with np.errstate(all="ignore"):
            if plant.is_discrete:
                P = sl.solve_discrete_are(A.T, C.T, Q, R)
                L = A @ P @ C.T @ np.linalg.inv(C @ P @ C.T + R)
            else:
                P = sl.solve_continuous_are(A.T, C.T, Q, R)
                L = np.linalg.solve(R, C @ P).T
            poles = np.linalg.eigvals(A - L @ C)
    except (np.linalg.LinAlgError, ValueError):
        return None
    if not (np.all(np.isfinite(poles)) and np.all(stable_mask(poles, plant.is_discrete))):
        return None
    return L, 0.5 * (P + P.T), poles


def scaled_start(setup: EngineSetup, target: NDArray, base: NDArray, deadline: Deadline) -> float:
    """The scale ``a`` (log grid 1e-6 .. 1e6) whose ``a base`` has Kalman poles closest to the
    targets (1 when none has a Kalman filter; the best so far when the deadline expires)."""
    best = (1.0, float("inf"))
    for a in SCALE_GRID:
        if deadline.expired:
            break
        kal = scipy_kalman(setup.plant, setup.Gd @ (a * base) @ setup.Gd.T)
        if kal is not None:
            e = pole_error(kal[2], target)
            if e < best[1]:
                best = (float(a), float(e))
    return best[0]


def placement_scale(setup: EngineSetup, target: NDArray) -> float | None:
    """``||L0 R L0'|| / ||Gd||^2`` for a gain L0 with the target poles: the size of the noise such
    a gain asks for (``Q = L R L' - A P - P A'``).  L0 is the gain of the null vectors of the
    spectral matrices at ``Qdec = I`` (any null vectors place the poles: O(n^3), where scipy's
    robust placement takes seconds at n = 20); None where the spectral form does not apply."""
    terms = spectral_terms(setup.plant.A, setup.plant.C, target, setup.plant.dt)
    if terms is None:
        return None
    blocks = spectral_blocks(terms, np.asarray(setup.plant.R, dtype=float), setup.Gd)
    try:
        L0, _ = blocks.gain(initial_null_vectors(blocks, np.eye(setup.k)))
    except np.linalg.LinAlgError:
        return None
    c = float(np.linalg.norm(L0 @ np.asarray(setup.plant.R, dtype=float) @ L0.T, 2))
    c /= max(SCALE_FLOOR, float(np.linalg.norm(setup.Gd, 2)) ** 2)
    return c if np.isfinite(c) and c > 0 else None


def decision_starts(setup: EngineSetup, target: NDArray, Qn: NDArray | None, count: int, seed: int,
            warm: NDArray | None, deadline: Deadline) -> list[tuple[str, NDArray]]:
    """The decision-covariance starts, in order: the warm start, the scaled identity whose Kalman
    poles are closest to the targets, the scaled nominal (``"nearest"``), then seeded random
    covariances at the scale of the scaled identity -- unless that scale is at an end of its grid
    (no scale of the identity comes close), where the pole-placement scale
    (:func:`placement_scale`) replaces it for the random starts and adds its own identity."""
    k = setup.k
    a = scaled_start(setup, target, np.eye(k), deadline)
    inside = SCALE_GRID[0] < a < SCALE_GRID[-1]
    c = placement_scale(setup, target) if not (inside or deadline.expired) else None
    out: list[tuple[str, NDArray]] = []
    if warm is not None:
        out.append(("warm start", warm))
    out.append(("scaled identity", a * np.eye(k)))
    if Qn is not None:
        w, U = np.linalg.eigh(0.5 * (Qn + Qn.T))
        Wn = (U * np.maximum(w, NOMINAL_EIG_FLOOR * max(float(w[-1]), SCALE_FLOOR))) @ U.T
        out.append(("scaled nominal", scaled_start(setup, target, Wn, deadline) * Wn))
    if c is not None:
        out.append(("placement-scaled identity", c * np.eye(k)))
    rng = np.random.default_rng(seed)
    cr = a if c is None else c
    while len(out) < count:
        F = rng.standard_normal((k, k))
        out.append(("random", cr * (F @ F.T / k + 0.1 * np.eye(k))))
    return out[:max(1, count)]


def rescue_starts(setup: EngineSetup, target: NDArray, count: int, seed: int,
                   deadline: Deadline) -> list[tuple[str, NDArray]]:
    """Further starts when none of the first gave a feasible point: seeded random covariances at the
    pole-placement scale and at 10, 1/10 and 100 times the scaled identity's (the feasible Q of a
    target may be far from every scaled identity: measured on repeated targets)."""
    k = setup.k
    a = scaled_start(setup, target, np.eye(k), deadline)
    scales = [c for c in (placement_scale(setup, target), *(f * a for f in RESCUE_FACTORS)) if c is not None]
    rng = np.random.default_rng(seed + 7919)
    out = []
    for i in range(max(1, count)):
        F = rng.standard_normal((k, k))
        out.append(("random (rescue)", scales[i % len(scales)] * (F @ F.T / k + 0.1 * np.eye(k))))
    return out


#: the scales (multiples of the scaled identity's) of the continuation starts, in order
#: (:func:`homotopy_starts`).  Measured on the large-noise sweep (rank 2 and p, 6 scales 1e-3 .. 100
#: on 8 hard seeds): which scale arrives varies from seed to seed over 4 decades either way
HOMOTOPY_SCALES = (1.0, 0.01, 100.0, 0.1, 10.0)


def homotopy_starts(setup: EngineSetup, target: NDArray, seed: int,
                    deadline: Deadline) -> list[tuple[str, NDArray, NDArray]]:
    """``(kind, V0, poles of V0)``: the starts of the continuation in the target poles
    (:func:`optdesign.engines.pole_homotopy.track`) -- seeded random factors of 2 and of p columns
    (diagonal: the scaled identity) at :data:`HOMOTOPY_SCALES` times the scale of the scaled identity whose
    Kalman poles are closest to the targets, each with the Kalman poles of its Q (scipy); the
    starts without a stabilizing Kalman filter are left out."""
    k, p = setup.k, setup.plant.p
    a = scaled_start(setup, target, np.eye(k), deadline)
    diagonal = setup.structure == "diagonal"
    ranks = [k] if diagonal else list(dict.fromkeys([min(2, k), min(p, k)]))
    rng = np.random.default_rng(seed + 104729)
    out = []
    for f in HOMOTOPY_SCALES:
        for r in ranks:
            V0 = np.sqrt(f * a) * (np.eye(k) if diagonal else rng.standard_normal((k, r)))
            kal = scipy_kalman(setup.plant, setup.Gd @ V0 @ V0.T @ setup.Gd.T)
            if kal is not None:
                out.append((f"pole continuation (rank {r}, scale {f * a:.3g})", V0, kal[2]))
    return out
