"""Parts of the inverse Kalman engine (:mod:`optdesign.engines.inverse_kalman_engine`): its candidate
(a feasible factor point), the stages that reach one (stage 1 from a start, from a fixed-gain SDP
point, the repair of an inaccurate one), the reported objective, the value of an SDP point, the ranks
and factors of an interior-point PSD matrix, and the validation of ``Q_nominal`` and ``warm_start``.
Split from the engine module (modules under 800 lines), imported there under the same names."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from .._deadline import Deadline
from .._validate import as_square, check_symmetric
from ..backends.clarabel_fixed_gain import FixedGainSolution
from ..errors import ValidationError
from .inverse_kalman_setup import SCALE_FLOOR, EngineSetup
from .spectral_factor import FactorProblem, SpectralBlocks, initial_null_vectors, spectral_blocks
from .spectral_newton import find_feasible, project, sqp
from .tolerances import RANK_EIG_FLOOR, START_REGULARIZATION, WARM_EIG_FLOOR

#: the engine's helpers (module-private names, imported by the engine only)
__all__ = [
    "RANK_GAP_RATIO", "EngineCandidate", "candidate_from_sdp", "candidate_from_start", "nominal_factor",
    "physical_objective", "repaired_candidate", "sdp_value", "warm_factor",
]

#: candidate ranks of an interior-point PSD matrix: eigenvalue gaps of at least this ratio (its
#: vanishing eigenvalues sit orders below the others, by the barrier's complementarity) ...
RANK_GAP_RATIO = 100.0
def physical_objective(objective: str, Wdec: NDArray, Qn: NDArray | None, Q: NDArray) -> float:
    """The reported objective: ``trace(Q)``, ``||Qdec - Q_nominal||_F`` or ``lambda_min(Qdec)``."""
    if objective == "min_trace":
        return float(np.trace(Q))
    W = np.diag(Wdec) if np.ndim(Wdec) == 1 else Wdec
    if objective == "nearest":
        return float(np.linalg.norm(W - Qn))
    return float(np.linalg.eigvalsh(0.5 * (W + W.T))[0])


def sdp_value(objective: str, sol: FixedGainSolution, Qn: NDArray | None, structure: str) -> float:
    """:attr:`EngineCandidate.value` of a solved SDP (inf for an unsolved one)."""
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


def nominal_factor(setup: EngineSetup, Q_nominal) -> NDArray | None:
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


def warm_factor(setup: EngineSetup, warm_start) -> NDArray | None:
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


@dataclass
class EngineCandidate:
    """A feasible point of one start: its factor problem (scaled by ``scale``) and x."""

    problem: FactorProblem
    x: NDArray
    scale: float
    kind: str = ""
    iterations: int = 0
    history: list = field(default_factory=list)
    multipliers: NDArray | None = None

    @property
    def value(self) -> float:
        """The objective in physical units, comparable between starts (lower is better):
        ``trace(Q)``, ``||Qdec - Q_nominal||_F^2`` or ``-lambda_min``."""
        return self.problem.f(self.x) * self.scale ** (2 if self.problem.objective == "nearest" else 1)

    def parts(self):
        return self.problem.unpack(self.x)


def _start_rank(setup: EngineSetup) -> int:
    """Columns of V at an SQP start: ``min(k, 2 p + 2)`` (the optima measured have rank p .. p + 2;
    a negative eigenvalue of the dual slack adds columns where more are needed)."""
    return setup.k if setup.structure == "diagonal" else min(setup.k, 2 * setup.plant.p + 2)


# ============================================================================ stages
def candidate_from_start(setup: EngineSetup, terms: list, W: NDArray, Qn: NDArray | None, deadline: Deadline,
                rec: dict) -> EngineCandidate | None:
    """Stage 1 from the decision covariance W (the problem scaled by ``||W||``):

    * SQP from W (a factor of ``_start_rank`` columns) until nearly feasible, the objective
      reduced on the way, then projected onto the feasible set; where it stops short, Gauss-Newton
      from its last point (a restoration phase);
    * failing that, Gauss-Newton with a line search from W itself (a full-rank Cholesky factor)
      to the nearest feasible point.

    For the objective ``"feasibility"`` this stage minimizes the trace instead (``Qdec = V V'``,
    the margin t held at 0), so that the point is PSD; Newton then raises t from 0 (a free margin
    in the SQP can end negative: an indefinite Q, measured on input-structured targets).

    None when no feasible point is reached (``rec`` records what was tried)."""
    diagonal = setup.structure == "diagonal"
    scale = max(float(np.linalg.norm(W, 2)), SCALE_FLOOR)
    blocks = spectral_blocks(terms, np.asarray(setup.plant.R, dtype=float), setup.Gd, scale)
    nominal = None if Qn is None else Qn / scale
    Ws = 0.5 * (W + W.T) / scale
    stage = "min_trace" if setup.objective == "feasibility" else setup.objective

    def problem(rank: int, lower: bool = False) -> FactorProblem:
        return FactorProblem(blocks, rank, stage, nominal, diagonal, lower=lower)

    def found(prob: FactorProblem, x: NDArray, iterations: int) -> EngineCandidate:
        if stage != setup.objective:   # the same point in the problem of the margin (t = 0)
            V, _, g = prob.unpack(x)
            prob = FactorProblem(blocks, prob.rank, setup.objective, nominal, diagonal, lower=prob.lower)
            x = prob.pack(V, 0.0, g)
        return EngineCandidate(prob, x, scale, iterations=iterations)

    prob = problem(_start_rank(setup))
    V0 = _factor_of(Ws, prob.rank, diagonal)
    rep = sqp(prob, prob.pack(V0, 0.0, initial_null_vectors(blocks, V0 @ V0.T)), max_iter=_SQP_MAX_ITER,
              expired=lambda: deadline.expired)
    rec.update(sqp_iterations=rep.iterations, sqp=rep.reason)
    prob, x = rep.problem, rep.x
    if rep.converged:
        x, ok, _ = project(prob, x)
        if ok:
            return found(prob, x, rep.iterations)
    if deadline.expired:
        return None
    prob, x, ok, it = find_feasible(prob, x, expired=lambda: deadline.expired)
    rec["restoration_iterations"] = it
    if ok:
        return found(prob, x, rep.iterations + it)
    if deadline.expired:
        return None
    full = not diagonal
    prob = problem(setup.k, lower=full)
    Wr = Ws + START_REGULARIZATION * np.trace(Ws) * np.eye(Ws.shape[0])
    V0 = np.linalg.cholesky(Wr) if full else _factor_of(Wr, setup.k, diagonal)
    prob, x, ok, it2 = find_feasible(prob, prob.pack(V0, 0.0, initial_null_vectors(blocks, V0 @ V0.T)),
                                     expired=lambda: deadline.expired)
    rec["projection_iterations"] = it2
    return found(prob, x, rep.iterations + it + it2) if ok else None


def candidate_from_sdp(setup: EngineSetup, blocks: SpectralBlocks, g: NDArray, sol: FixedGainSolution,
                       scale: float, Qn: NDArray | None, fixed: bool) -> EngineCandidate | None:
    """A feasible factor point from an SDP solution at the gain of g: its face read off the
    eigenvalue gaps, projected onto the residuals' zero set (``fixed``: g kept), or None."""
    diagonal = setup.structure == "diagonal"
    if sol.Wdec is None:
        return None
    t_phys = 0.0 if sol.t is None else sol.t
    W = sol.Wdec - (t_phys if diagonal else t_phys * np.eye(setup.k))
    Wm = np.diag(W) if (diagonal and np.ndim(W) == 1) else W
    t = t_phys / scale
    for r in _rank_of(Wm):
        prob = FactorProblem(blocks, r, setup.objective, None if Qn is None else Qn / scale, diagonal,
                             fixed_g=fixed, g_fixed=g if fixed else None)
        x, ok, _ = project(prob, prob.pack(_factor_of(Wm / scale, r, diagonal), t, g))
        if ok:
            return EngineCandidate(prob, x, scale, kind="sdp")
    return None


def repaired_candidate(setup: EngineSetup, blocks: SpectralBlocks, g: NDArray, sol: FixedGainSolution,
                       scale: float, Qn: NDArray | None, deadline: Deadline) -> EngineCandidate | None:
    """A feasible point at the fixed gain of g from an inaccurate SDP point (eigenvalues of the
    wrong sign, residuals far from rounding): Gauss-Newton with a line search from a factor of its
    PSD part, over the candidate ranks, the largest first; None when none converges."""
    diagonal = setup.structure == "diagonal"
    if sol.Wdec is None:
        return None
    W = np.diag(sol.Wdec) if (diagonal and np.ndim(sol.Wdec) == 1) else sol.Wdec
    for r in sorted(set(_rank_of(W)), reverse=True):
        prob = FactorProblem(blocks, r, setup.objective, None if Qn is None else Qn / scale, diagonal,
                             fixed_g=True, g_fixed=g)
        prob, x, ok, _ = find_feasible(prob, prob.pack(_factor_of(W / scale, r, diagonal), 0.0, g),
                                       expired=lambda: deadline.expired)
        if ok:
            return EngineCandidate(prob, x, scale, kind="repaired sdp")
    return None


#: SQP iterations per start before the restoration (measured: 20 loses a cross-validation target, 40
#: none; beyond, the SQP mostly oscillates at n >= 20 -- the restoration is cheaper)
_SQP_MAX_ITER = 40
