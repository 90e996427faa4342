"""Helpers of the inverse Kalman engine (:mod:`optdesign.engines.inverse_kalman_engine`) that need none
of its search state: the reported objective, the value of a fixed-gain SDP point, the ranks and factors
of an interior-point PSD matrix, and the validation of ``Q_nominal`` and ``warm_start``.  Split from
the engine module (modules under 800 lines), re-imported there under the same names."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from .._validate import as_square, check_symmetric
from ..backends.clarabel_fixed_gain import FixedGainSolution
from ..errors import ValidationError
from .inverse_kalman_setup import SCALE_FLOOR, EngineSetup
from .tolerances import RANK_EIG_FLOOR, WARM_EIG_FLOOR

#: the engine's helpers (module-private names, imported by the engine only)
__all__ = ["RANK_GAP_RATIO"]

#: candidate ranks of an interior-point PSD matrix: eigenvalue gaps of at least this ratio (its
#: vanishing eigenvalues sit orders below the others, by the barrier's complementarity) ...
RANK_GAP_RATIO = 100.0
def _physical_objective(objective: str, Wdec: NDArray, Qn: NDArray | None, Q: NDArray) -> float:
    """The reported objective: ``trace(Q)``, ``||Qdec - Q_nominal||_F`` or ``lambda_min(Qdec)``."""
    if objective == "min_trace":
        return float(np.trace(Q))
    W = np.diag(Wdec) if np.ndim(Wdec) == 1 else Wdec
    if objective == "nearest":
        return float(np.linalg.norm(W - Qn))
    return float(np.linalg.eigvalsh(0.5 * (W + W.T))[0])


def _sdp_value(objective: str, sol: FixedGainSolution, Qn: NDArray | None, structure: str) -> float:
    """:attr:`_Candidate.value` of a solved SDP (inf for an unsolved one)."""
    if sol.Q is None or sol.Wdec is None:
        return float("inf")
    if objective == "min_trace":
        return float(np.trace(sol.Q))
    if objective == "feasibility":
        return -float(sol.t if sol.t is not None else -np.inf)
    W = np.diag(sol.Wdec) if structure == "diagonal" else sol.Wdec
    return float(np.sum((W - (0.0 if Qn is None else Qn)) ** 2))


def _rank_of(W: NDArray) -> list[int]:
    """Candidate ranks of an interior-point PSD matrix, likeliest first: the largest eigenvalue
    gaps (ratio >= 100) above 1e-13 of the largest eigenvalue, then full rank."""
    w = np.sort(np.linalg.eigvalsh(0.5 * (W + W.T)))[::-1]
    if w[0] <= 0:
        return []
    w = np.maximum(w, SCALE_FLOOR)
    ratios = w[:-1] / w[1:]
    cand = [int(i + 1) for i in np.argsort(-ratios)
            if ratios[i] >= RANK_GAP_RATIO and w[i] > RANK_EIG_FLOOR * w[0]]
    return list(dict.fromkeys(cand[:3] + [int(np.sum(w > RANK_EIG_FLOOR * w[0]))]))


def _factor_of(W: NDArray, r: int, diagonal: bool) -> NDArray:
    """A (k, r) factor of the PSD part of W (diagonal: the square roots of its diagonal)."""
    if diagonal:
        return np.diag(np.sqrt(np.maximum(np.diag(W) if np.ndim(W) == 2 else W, 0.0)))
    w, U = np.linalg.eigh(0.5 * (W + W.T))
    return U[:, ::-1][:, :r] * np.sqrt(np.maximum(w[::-1][:r], 0.0))


def _nominal(setup: EngineSetup, Q_nominal) -> NDArray | None:
    if setup.objective != "nearest":
        return None
    if Q_nominal is None:
        raise ValidationError("objective='nearest' needs Q_nominal")
    k = setup.k
    what = "(n, n) (state-space Q)" if setup.structure == "full" else "(m, m) (noise-input Qw)"
    Qn = as_square("Q_nominal", Q_nominal)
    if Qn.shape[0] != k:
        raise ValidationError(f"Q_nominal for structure={setup.structure!r} must be {what}, i.e. ({k}, {k}); "
                              f"found {Qn.shape}")
    return check_symmetric("Q_nominal", Qn)


def _warm(setup: EngineSetup, warm_start) -> NDArray | None:
    if warm_start is None:
        return None
    k = setup.k
    W = as_square("warm_start", warm_start)
    if W.shape[0] != k:
        raise ValidationError(f"warm_start must be the ({k}, {k}) decision covariance; found {W.shape}")
    W = check_symmetric("warm_start", W)
    w, U = np.linalg.eigh(W)
    if w[-1] <= 0:
        raise ValidationError("warm_start must have a positive eigenvalue; found none")
    # positive definite (Gauss-Newton starts at full rank)
    return (U * np.maximum(w, WARM_EIG_FLOOR * w[-1])) @ U.T
