"""Result and certificate types of the inverse Kalman verbs (:func:`kalman_for_poles`,
:func:`is_kalman_optimal`)."""


from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ...classical.riccati import format_pole as _fmt
from ...errors import OptDesignDeprecationWarning
from ...model.plant import Plant
from ...results import Certificate, DesignResult
from ..estimator import estimator_of


class InfeasibilityCertificate(Certificate):
    """Evidence that a target (or a gain) is not reachable by a steady-state Kalman filter.

    A :class:`~optdesign.results.Certificate` whose ``data`` has the named entries below (each
    also an attribute, None when absent).

    Attributes
    ----------
    kind : str
        ``"unstable_target"`` (a target pole is unstable: every Kalman filter is stable),
        ``"trace"`` / ``"determinant"`` (an identity every Kalman filter satisfies is violated),
        ``"gain_relation"`` (no symmetric P satisfies ``P C' = L R`` / its discrete analogue:
        ``C L R`` resp. ``V - R`` is not symmetric positive semidefinite),
        ``"return_difference"`` (the circle condition fails at ``omega``),
        ``"sdp_margin"`` (the family of Q has no PSD member: ``margin < 0``),
        ``"structure"`` (one output: no Q of the structure in the gain's family: an accurate SDP).
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
        Closest achievable poles (smallest :func:`~optdesign.classical.placement.pole_error`
        found) and the corresponding design: the best of a scaled nominal noise, the closest-poles
        NLP (which keeps the target's real/complex pattern) and a multi-start Nelder-Mead search on
        the pole error over the noise parameters (where there are at most 10 of them).  The pattern may differ
        from the target's.  A local search: evidence, not proof.
    closest_pole_error : float or None
        :func:`~optdesign.classical.placement.pole_error` of ``closest_poles`` against the target.
    closest_L, closest_Q, closest_Qw : ndarray or None
    """

    __slots__ = ()

    def __init__(self, kind: str, reason: str, *, margin: float | None = None, omega: float | None = None,
                 min_eigenvalue: float | None = None, circle: Any = None,
                 closest_poles: NDArray[np.complex128] | None = None, closest_pole_error: float | None = None,
                 closest_L: NDArray | None = None, closest_Q: NDArray | None = None,
                 closest_Qw: NDArray | None = None, **more: Any) -> None:
        super().__init__(kind, reason, dict(
            margin=margin, omega=omega, min_eigenvalue=min_eigenvalue, circle=circle,
            closest_poles=closest_poles, closest_pole_error=closest_pole_error, closest_L=closest_L,
            closest_Q=closest_Q, closest_Qw=closest_Qw), **more)

    def __reduce__(self):
        return (_rebuild_certificate, (self.kind, self.reason, self.data))

    def as_dict(self) -> dict[str, Any]:
        """Plain-data form (JSON friendly)."""
        d = super().as_dict()
        keep = ("kind", "reason", "margin", "omega", "min_eigenvalue", "closest_poles", "closest_pole_error")
        return {k: d.get(k) for k in keep}

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


def _rebuild_certificate(kind: str, reason: str, data: dict) -> InfeasibilityCertificate:
    return InfeasibilityCertificate(kind, reason, **data)


@dataclass(frozen=True, kw_only=True, eq=False)
class InverseKalmanResult(DesignResult):
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
    target_poles : (n,) ndarray of complex
        Requested poles (sorted, conjugate pairs adjacent); also ``target``.
    status : Status
        ``OPTIMAL`` / ``OPTIMAL_INACCURATE`` / ``SOLVED`` (sequential), ``INFEASIBLE`` (with a
        global ``certificate``), ``NOT_FOUND`` (a local search found nothing: evidence in
        ``extra["closest"]``), ``TIME_LIMIT``, or a failure status with the reason in ``message``.
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
    extra : dict
        Diagnostics: backend reports of every stage, the SDP gain, NLP starts, the closest poles
        of a search that found nothing, ...  (``details``: a deprecated alias.)
    """

    L: NDArray[np.float64] | None = None
    Q: NDArray[np.float64] | None = None
    Qw: NDArray[np.float64] | None = None
    P: NDArray[np.float64] | None = None
    poles: NDArray[np.complex128] | None = None
    method: str
    objective: str
    structure: str
    objective_value: float = float("nan")
    plant: Plant = field(repr=False)

    @property
    def target(self) -> NDArray[np.complex128]:
        """The requested poles (``target_poles``)."""
        return self.target_poles

    @property
    def details(self) -> dict[str, Any]:
        """Deprecated alias of ``extra`` (the result base's diagnostics field): warns
        :class:`~optdesign.errors.OptDesignDeprecationWarning`; goes in the next release."""
        warnings.warn("InverseKalmanResult.details is deprecated: use .extra (the same dict; the alias "
                      "goes in the next release)", OptDesignDeprecationWarning, stacklevel=2)
        return self.extra

    def estimator(self, *, form: str | None = None, output: str = "auto"):
        """The filter as a system: inputs ``[u; y]``, outputs ``[y_hat; x_hat]``
        (:func:`optdesign.estimator_system`; a python-control ``StateSpace`` when python-control is
        installed, plain arrays otherwise).

        Raises
        ------
        ValidationError
            No gain (the design failed).
        """
        return estimator_of(self, self.plant, form=form, output=output)

    @property
    def pole_error(self) -> float:
        """:func:`~optdesign.classical.placement.pole_error` of the achieved poles (inf without a design)."""
        return self.verification["pole_error"].value if "pole_error" in self.verification else float("inf")

    def summary(self) -> str:
        """Multi-line human-readable report."""
        lines = [f"kalman_for_poles: method={self.method}, objective={self.objective}, "
                 f"structure={self.structure}, status={self.status.value}, success={self.success}",
                 f"  target poles: {', '.join(_fmt(z) for z in self.target_poles)}",
                 f"  {self.message}"]
        with np.printoptions(precision=6, linewidth=100):
            for name, X in (("L", self.L), ("Q", self.Q)):
                if X is not None:
                    lines.append(f"  {name} = " + np.array2string(X, prefix=f"  {name} = "))
        if self.certificate is not None:
            lines.append(f"  certificate: {self.certificate}")
        if self.route:
            lines.append(f"  route: {self.route}")
        lines.append("  verification:")
        lines.extend("    " + str(c) for c in self.verification)
        return "\n".join(lines)

    def __repr__(self) -> str:
        pe = self.pole_error
        return (f"InverseKalmanResult(method={self.method!r}, status={self.status.value!r}, "
                f"success={self.success}, pole_error={pe:.2e})")


@dataclass(frozen=True, kw_only=True, eq=False)
class KalmanOptimalityResult(DesignResult):
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
    Q: NDArray[np.float64] | None = None
    P: NDArray[np.float64] | None = None
    margin: float = float("nan")
    min_eigenvalue: float = float("nan")
    omega: float = float("nan")
    circle: Any = None

    def __post_init__(self) -> None:
        # "optimal" is a verified claim: a certificate that fails a check proves nothing
        if self.optimal and not self.verification.passed:
            object.__setattr__(self, "optimal", False)

    def __bool__(self) -> bool:
        """``bool(result)`` is ``optimal`` (a verified claim), so ``if is_kalman_optimal(...)`` reads
        as it should."""
        return bool(self.optimal) and self.verification.passed

    def __repr__(self) -> str:
        return (f"KalmanOptimalityResult(optimal={self.optimal}, margin={self.margin:.3g}, "
                f"min_eigenvalue={self.min_eigenvalue:.3g} at omega={self.omega:.4g})")

