"""Result and certificate types of the inverse Kalman verbs (:func:`kalman_for_poles`,
:func:`is_kalman_optimal`)."""


from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ...classical.riccati import _fmt
from ...model.plant import Plant
from ...results import ResultMixin, SolverStats, Status, Verification


@dataclass(frozen=True, eq=False)
class InfeasibilityCertificate:
    """Evidence that a target (or a gain) is not reachable by a steady-state Kalman filter.

    Attributes
    ----------
    kind : str
        ``"unstable_target"`` (a target pole is unstable: every Kalman filter is stable),
        ``"gain_relation"`` (no symmetric P satisfies ``P C' = L R`` / its discrete analogue:
        ``C L R`` resp. ``V - R`` is not symmetric positive semidefinite),
        ``"return_difference"`` (the circle condition fails at ``omega``),
        ``"sdp_margin"`` (the family of Q has no PSD member: ``margin < 0``),
        ``"structure"`` (a structured Q cannot reach the target; see the closest poles),
        ``"nlp_local"`` (several outputs: IPOPT found no feasible point -- local evidence only).
    reason : str
        One sentence.
    margin : float or None
        ``max`` over the Q family (fixed L) of the smallest eigenvalue of the decision
        covariance; negative means infeasible.
    omega : float or None
        Frequency (rad/s) where ``lambda_min(T R T^* - R)`` (discrete ``T V T^* - R``) is smallest.
    min_eigenvalue : float or None
        That smallest eigenvalue (negative: the inequality fails by this much).
    circle : CircleConditionResult or None
        The full frequency scan (:func:`optdesign.analysis.robustness.circle_condition`).
    closest_poles : (n,) ndarray of complex or None
        Closest achievable poles (smallest :func:`pole_error` found) and the corresponding
        design: the best of a scaled nominal noise, the closest-poles NLP (which keeps the
        target's real/complex pattern) and a multi-start Nelder-Mead search on the pole error
        over the noise parameters (where there are at most 10 of them).  The pattern may differ
        from the target's.  A local search: evidence, not proof.
    closest_pole_error : float or None
        :func:`pole_error` of ``closest_poles`` against the target.
    closest_L, closest_Q, closest_Qw : ndarray or None
    """

    kind: str
    reason: str
    margin: float | None = None
    omega: float | None = None
    min_eigenvalue: float | None = None
    circle: Any = None
    closest_poles: NDArray[np.complex128] | None = None
    closest_pole_error: float | None = None
    closest_L: NDArray[np.float64] | None = None
    closest_Q: NDArray[np.float64] | None = None
    closest_Qw: NDArray[np.float64] | None = None

    def as_dict(self) -> dict[str, Any]:
        """Plain-data form (JSON friendly)."""

        def arr(x):
            if x is None:
                return None
            a = np.asarray(x)
            return {"re": a.real.tolist(), "im": a.imag.tolist()} if np.iscomplexobj(a) else a.tolist()

        return {"kind": self.kind, "reason": self.reason, "margin": self.margin, "omega": self.omega,
                "min_eigenvalue": self.min_eigenvalue, "closest_poles": arr(self.closest_poles),
                "closest_pole_error": self.closest_pole_error}

    def __str__(self) -> str:
        parts = [f"{self.kind}: {self.reason}"]
        if self.omega is not None and self.min_eigenvalue is not None:
            parts.append(f"worst frequency {self.omega:.6g} rad/s, min eigenvalue {self.min_eigenvalue:.4g}")
        if self.margin is not None:
            parts.append(f"SDP margin {self.margin:.4g}")
        if self.closest_poles is not None:
            poles = ", ".join(_fmt(z) for z in self.closest_poles)
            parts.append(f"closest achievable poles {poles} (pole error {self.closest_pole_error:.3g})")
        return "; ".join(parts)


@dataclass(frozen=True, eq=False)
class InverseKalmanResult(ResultMixin):
    """Outcome of :func:`kalman_for_poles`.

    Attributes
    ----------
    L : (n, p) ndarray or None
        Kalman gain (continuous ``P C' R^-1``; discrete predictor gain ``A P C' (C P C' + R)^-1``).
    Q : (n, n) ndarray or None
        State-space process-noise covariance (the seeds' ``Q' = D Q D'``), exactly PSD.
    Qw : ndarray or None
        Noise-input covariance with ``Q = G Qw G'`` (structures ``"input"``: (m, m);
        ``"diagonal"``: (m, m) diagonal); None for ``"full"``.
    P : (n, n) ndarray or None
        Steady-state error covariance (discrete: a-priori).
    poles : (n,) ndarray of complex or None
        ``eig(A - L C)`` by numpy.
    target : (n,) ndarray of complex
        Requested poles (sorted, conjugate pairs adjacent).
    status : Status
        ``OPTIMAL`` / ``OPTIMAL_INACCURATE`` / ``SOLVED`` (sequential), ``INFEASIBLE`` (with
        ``certificate``), or a failure status with the reason in ``message``.
    message : str
    solver_stats : SolverStats
    verification : Verification
        ``pole_error``, ``riccati_residual`` (``filter_are_residual`` of P with Q),
        ``are_resolve_gain`` / ``are_resolve_poles`` (an independent ``filter_are`` with the
        returned Q: its L and poles must match), ``Q_min_eig``, ``P_min_eig`` (relative),
        ``structure`` (``Q = G Qw G'``, ``Qw >= 0``) where it applies.
    certificate : InfeasibilityCertificate or None
    method, objective, structure : str
        What was actually run (``method`` is never ``"auto"``).
    objective_value : float
        ``trace(Q)``, ``||Q - Q_nominal||_F`` or the smallest eigenvalue, by objective (nan if none).
    plant : Plant
    details : dict
        Extras: backend reports of every stage, the SDP gain, NLP starts, ...
    """

    L: NDArray[np.float64] | None
    Q: NDArray[np.float64] | None
    Qw: NDArray[np.float64] | None
    P: NDArray[np.float64] | None
    poles: NDArray[np.complex128] | None
    target: NDArray[np.complex128]
    status: Status
    message: str
    solver_stats: SolverStats
    verification: Verification
    certificate: InfeasibilityCertificate | None
    method: str
    objective: str
    structure: str
    objective_value: float
    plant: Plant = field(repr=False)
    details: dict[str, Any] = field(default_factory=dict, repr=False)

    @property
    def pole_error(self) -> float:
        """:func:`pole_error` of the achieved poles (inf without a design)."""
        return self.verification["pole_error"].value if "pole_error" in self.verification else float("inf")

    def summary(self) -> str:
        """Multi-line human-readable report."""
        lines = [f"kalman_for_poles: method={self.method}, objective={self.objective}, "
                 f"structure={self.structure}, status={self.status.value}, success={self.success}",
                 f"  target poles: {', '.join(_fmt(z) for z in self.target)}",
                 f"  {self.message}"]
        if self.L is not None:
            with np.printoptions(precision=6, linewidth=100):
                lines.append("  L = " + np.array2string(self.L, prefix="  L = "))
                lines.append("  Q = " + np.array2string(self.Q, prefix="  Q = "))
        if self.certificate is not None:
            lines.append(f"  certificate: {self.certificate}")
        lines.append("  verification:")
        lines.extend("    " + str(c) for c in self.verification)
        return "\n".join(lines)

    def __repr__(self) -> str:
        pe = self.pole_error
        return (f"InverseKalmanResult(method={self.method!r}, status={self.status.value!r}, "
                f"success={self.success}, pole_error={pe:.2e})")


@dataclass(frozen=True, eq=False)
class KalmanOptimalityResult(ResultMixin):
    """Outcome of :func:`is_kalman_optimal`.

    Attributes
    ----------
    optimal : bool
        True when a ``Q >= 0`` making L the steady-state Kalman gain (for R) was found *and*
        passed every check of ``verification`` (``bool(result)`` is the same).  False both for
        "not optimal" (``status`` infeasible, with ``certificate``) and "inconclusive"
        (``status`` numerical_error: the SDP margin is slightly negative, the return-difference
        inequality holds, but no polished PSD Q reproduces L; no certificate either way).
    L : (n, p) ndarray
    R : (p, p) ndarray
    Q, P : (n, n) ndarray or None
        The certificate of optimality: the most robustly positive member of the family
        (maximal smallest eigenvalue), polished; ``filter_are`` with this Q returns L.
    margin : float
        Max over the family of ``lambda_min(Q)`` (negative: not optimal); nan if the linear
        gain relation itself has no symmetric solution.  For a boundary gain (rank-deficient
        Q, true margin 0) the SDP's estimate may come out slightly negative; when a polished
        PSD Q verifies, ``margin`` is the larger of the two.
    min_eigenvalue, omega : float
        Smallest eigenvalue of ``T R T^* - R`` (discrete ``T V T^* - R``) over frequency and where.
    circle : CircleConditionResult or None
    certificate : InfeasibilityCertificate or None
        Why L is not optimal (None when it is).
    status : Status
        ``OPTIMAL`` / ``OPTIMAL_INACCURATE`` when optimal (the latter: the certificate came from
        polishing an inaccurate SDP point), ``INFEASIBLE`` when not, ``NUMERICAL_ERROR`` when
        inconclusive, a failure status otherwise.
    message : str
    verification : Verification
        When optimal: ``riccati_residual``, ``are_resolve_gain``, ``Q_min_eig``, ``P_min_eig``.
        When not: ``margin`` / ``circle`` checks that document the failure (so ``success`` is
        False: there is no Q).
    solver_stats : SolverStats
    """

    optimal: bool
    L: NDArray[np.float64]
    R: NDArray[np.float64]
    Q: NDArray[np.float64] | None
    P: NDArray[np.float64] | None
    margin: float
    min_eigenvalue: float
    omega: float
    circle: Any
    certificate: InfeasibilityCertificate | None
    status: Status
    message: str
    verification: Verification
    solver_stats: SolverStats

    def __post_init__(self) -> None:
        # "optimal" is a verified claim: a certificate that fails a check proves nothing
        if self.optimal and not self.verification.passed:
            object.__setattr__(self, "optimal", False)

    def __bool__(self) -> bool:
        return bool(self.optimal) and self.verification.passed

    def __repr__(self) -> str:
        return (f"KalmanOptimalityResult(optimal={self.optimal}, margin={self.margin:.3g}, "
                f"min_eigenvalue={self.min_eigenvalue:.3g} at omega={self.omega:.4g})")

