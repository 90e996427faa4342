"""The well-conditioned Kalman-filter NLP: noise covariances as variables, the filter Riccati
equation as a constraint.  Build, never solve.

See :mod:`optdesign.formulate.well_conditioned` for the formulation.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ...model.plant import Plant
from ...model.regions import Region
from .common import NLPScaling, PoleStructure, casadi_module, check_objective, check_q_structure
from .observer_nlp import RegionNLP

__all__ = ["KalmanNLP", "build_kalman_nlp"]


def _chol_or_zero(M: NDArray) -> NDArray:
    try:
        return np.linalg.cholesky(0.5 * (M + M.T))
    except np.linalg.LinAlgError:
        w, U = np.linalg.eigh(0.5 * (M + M.T))
        R = U * np.sqrt(np.maximum(w, 0.0))
        _, r = np.linalg.qr(R.T)
        return r.T


def _tri(ca, f, n: int):
    """Lower-triangular MX from a vector of n(n+1)/2 entries."""
    M = ca.MX.zeros(n, n)
    k = 0
    for i in range(n):
        for j in range(i + 1):
            M[i, j] = f[k]
            k += 1
    return M


def _tri_vals(M: NDArray) -> NDArray:
    n = M.shape[0]
    return np.array([M[i, j] for i in range(n) for j in range(i + 1)])


def _lower(ca, M, n: int):
    return ca.vertcat(*[M[i, j] for i in range(n) for j in range(i + 1)])


class KalmanNLP:
    """Well-conditioned Kalman filter NLP: noise covariances as variables, Riccati as a constraint.

    Variables: ``P = F F'`` (lower-triangular ``F`` with a nonnegative diagonal, so ``P >= 0`` by
    construction), the noise parameters ``theta`` (a scalar multiple of ``Q0``, a diagonal, or a
    Cholesky factor of ``Q``) and the free-pole observer NLP (:class:`RegionNLP`: ``L``, ``V``,
    ``W``, poles), tied together by ``L = P C' R^-1`` (continuous) or ``A P C' (C P C' + R)^-1``
    (discrete, predictor form) and the filter ARE/DARE as equality constraints.  ``R`` is fixed
    (the plant's, or the identity): only the ratio of the covariances matters for the gain.
    """

    def __init__(
        self,
        plant: Plant,
        structure: PoleStructure,
        *,
        objective: str,
        q_structure: str,
        region: Region | None,
        kappa2_max: float | None,
        eta_max: float | None,
        scaling: NLPScaling,
    ) -> None:
        ca = casadi_module()
        self.plant = plant
        self.structure = structure
        self.objective = objective
        self.q_structure = q_structure
        n, p, m = plant.n, plant.p, plant.m
        G = plant.G
        R = plant.R if plant.R is not None else np.eye(p)
        self.R = np.asarray(R, dtype=float)
        Q0 = plant.Q if plant.Q is not None else np.eye(m)
        self.Q_base = np.asarray(Q0, dtype=float)
        # observer NLP with a free gain; the gain is then tied to the Riccati solution
        self.obs = RegionNLP(
            plant,
            structure,
            objective=objective,
            region=region,
            mask=None,
            max_gain=None,
            kappa2_max=kappa2_max,
            eta_max=eta_max,
            decay=None,
            damping=None,
            radius=None,
            scaling=scaling,
        )
        opti = self.obs.opti
        self.opti = opti
        # P = Fp Fp' (Cholesky, positive diagonal): P is PSD by construction
        Fp = opti.variable(n * (n + 1) // 2)
        self.Fp = Fp
        Lp = _tri(ca, Fp, n)
        P = Lp @ Lp.T
        self.P = P
        for i in range(n):
            k = i * (i + 1) // 2 + i
            opti.subject_to(Fp[k] >= 0)
        if q_structure == "scalar":
            theta = opti.variable()
            opti.subject_to(theta >= 0)
            Qm = theta * self.Q_base
        elif q_structure == "diagonal":
            theta = opti.variable(m)
            opti.subject_to(theta >= 0)
            Qm = ca.diag(theta)
        else:  # "full": Q = Fq Fq'
            theta = opti.variable(m * (m + 1) // 2)
            Fq = _tri(ca, theta, m)
            Qm = Fq @ Fq.T
        self.theta = theta
        self.Q = Qm
        A, C = plant.A, plant.C
        Rinv = np.linalg.inv(self.R)
        GQG = G @ Qm @ G.T
        if plant.is_discrete:
            Sx = C @ P @ C.T + self.R
            Lk = A @ P @ C.T @ ca.inv(Sx)
            res = A @ P @ A.T - P - Lk @ Sx @ Lk.T + GQG
        else:
            Lk = P @ C.T @ Rinv
            res = A @ P + P @ A.T - P @ C.T @ Rinv @ C @ P + GQG
        opti.subject_to(_lower(ca, res, n) == 0)
        opti.subject_to(ca.vec(self.obs.L_expr - Lk) == 0)

    def set_initial(self, P0: NDArray, theta0: NDArray | float, L0: NDArray) -> None:
        n = self.plant.n
        self.obs.set_initial_gain(L0)
        Lc = _chol_or_zero(P0 + 1e-12 * np.eye(n))
        self.opti.set_initial(self.Fp, _tri_vals(Lc))
        self.opti.set_initial(self.theta, np.asarray(theta0, dtype=float).ravel())

    def noise(self, value) -> NDArray[np.float64]:
        """The process-noise covariance ``Q`` (m, m) at the solution."""
        ca = casadi_module()
        m = self.plant.m
        return np.asarray(value(ca.densify(self.Q)), dtype=float).reshape(m, m)


def build_kalman_nlp(
    plant: Plant,
    structure: PoleStructure,
    *,
    objective: str = "eta",
    q_structure: str = "scalar",
    region: Region | None = None,
    kappa2_max: float | None = None,
    eta_max: float | None = None,
    scaling: NLPScaling | None = None,
) -> KalmanNLP:
    """Build the well-conditioned Kalman-filter NLP (never solves it).

    Parameters
    ----------
    plant : Plant
        ``A, C, G`` and ``R`` (identity if absent); ``Q`` is the base shape for
        ``q_structure="scalar"`` (identity if absent).
    structure : PoleStructure
    objective : {"kappa2", "kappa_fro", "eta"}
    q_structure : {"scalar", "diagonal", "full"}
        ``Q = theta Q_base``; ``Q = diag(theta)``; ``Q = F F'`` with ``F`` lower triangular.
    region : Region, optional
    kappa2_max, eta_max : float, optional
    scaling : NLPScaling, optional
        Only time scaling is meaningful here; ``T`` and ``S`` must be ones (the Riccati
        constraint is written in the plant's coordinates).

    Returns
    -------
    KalmanNLP

    Raises
    ------
    ValidationError
        Unknown objective or ``q_structure``.
    """
    check_objective(objective)
    check_q_structure(q_structure)
    sc = scaling or NLPScaling.identity(plant.n, plant.p)
    return KalmanNLP(
        plant,
        structure,
        objective=objective,
        q_structure=q_structure,
        region=region,
        kappa2_max=kappa2_max,
        eta_max=eta_max,
        scaling=sc,
    )
