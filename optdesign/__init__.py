"""optdesign: state-estimator gains designed by optimization.

Observers and Kalman filters that are well conditioned, with poles where you want them;
the inverse Kalman question (which Q >= 0 gives these poles?), Riccati solvers, Kalman
filter robustness, and constraint studies.  NLPs are solved with CasADi/IPOPT; SDPs with Clarabel
(directly, or through cvxpy with Clarabel or SCS) or our dense interior-point method; our own engines
(:mod:`optdesign.engines`) where a benchmark shows them faster at the same optimum.  Every answer is
verified independently (:mod:`optdesign.design.verification`).

Public names are imported lazily, so ``import optdesign`` is cheap and the optional
backends are loaded only when a design needs them.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from .errors import (
    ArgumentTypeError,
    BackendUnavailableError,
    DimensionError,
    EmptyRegionError,
    InfeasibleError,
    NotConjugateClosedError,
    NotControllableError,
    NotFiniteError,
    NotObservableError,
    NotPositiveDefiniteError,
    NotPositiveSemidefiniteError,
    NotSymmetricError,
    OptDesignDeprecationWarning,
    OptDesignError,
    OptDesignWarning,
    OutputExistsError,
    OutputPathError,
    ProblemFileError,
    ProblemNotFoundError,
    RiccatiError,
    SolverError,
    UnreachableModesError,
    ValidationError,
)
from .model.plant import Plant
from .results import Certificate, Check, DesignResult, SolverStats, Status, Verification

__version__ = "0.2.0"

# public name -> module that defines it (imported on first access)
_LAZY: dict[str, str] = {
    # noise covariances from data (autocovariance least squares)
    "estimate_noise": "optdesign.design.noise_estimation",
    "NoiseEstimate": "optdesign.design.noise_estimation",
    "simulate_outputs": "optdesign.design.noise_estimation",
    # foundation: the Kalman filter and its complete API
    "kalman": "optdesign.design.kalman",
    "KalmanFilter": "optdesign.design.kalman",
    "kalmd": "optdesign.design.kalman",
    "kalman_finite_horizon": "optdesign.design.kalman",
    "KalmanSequence": "optdesign.design.kalman",
    "van_loan": "optdesign.classical.sampling",
    # systems in and out
    "as_plant": "optdesign.model.coerce",
    "as_system": "optdesign.model.coerce",
    "estimator_system": "optdesign.design.estimator",
    "EstimatorArrays": "optdesign.design.estimator",
    # robust design for many plant models (issue 15)
    "robust_observer": "optdesign.design.robust",
    "per_model_designs": "optdesign.design.robust_gain",
    "evaluate_gain": "optdesign.design.robust_gain",
    "robust_lmi_observer": "optdesign.design.robust_lmi",
    "RobustObserverDesign": "optdesign.design.robust_result",
    "ModelSet": "optdesign.model.model_set",
    "h2_norm": "optdesign.analysis.norms",
    "hinf_norm": "optdesign.analysis.norms",
    # state feedback by duality
    "place": "optdesign.design.feedback",
    "PlacementResult": "optdesign.design.feedback",
    "well_conditioned_feedback": "optdesign.design.feedback",
    "FeedbackDesign": "optdesign.design.feedback",
    "lqr_for_poles": "optdesign.design.feedback",
    "InverseLQRResult": "optdesign.design.feedback",
    "dual_plant": "optdesign.design.feedback",
    # inverse Kalman (seed 000)
    "kalman_for_poles": "optdesign.design.inverse_kalman",
    "InverseKalmanResult": "optdesign.design.inverse_kalman",
    "InverseKalmanProblem": "optdesign.design.inverse_kalman",
    "is_kalman_optimal": "optdesign.design.inverse_kalman",
    "KalmanOptimalityResult": "optdesign.design.inverse_kalman",
    # well-conditioned observers (seed 001)
    "well_conditioned_observer": "optdesign.design.well_conditioned",
    "well_conditioned_kalman": "optdesign.design.well_conditioned",
    "ObserverDesign": "optdesign.design.well_conditioned",
    # time-varying Kalman gain (seed 004)
    "riccati_de": "optdesign.design.riccati_de",
    "RiccatiTrajectory": "optdesign.design.riccati_de",
    # generalized observers (seed 003)
    "generalized_observer": "optdesign.design.generalized",
    "GeneralizedObserver": "optdesign.design.generalized",
    "noise_rejecting_observer": "optdesign.design.generalized",
    "NoiseRejectingObserver": "optdesign.design.generalized",
    "ObserverSimulation": "optdesign.design.generalized",
    "simulate_observer": "optdesign.design.generalized",
    # robustness (seed 002)
    "return_difference": "optdesign.analysis.robustness",
    "circle_condition": "optdesign.analysis.robustness",
    "filter_margins": "optdesign.analysis.margins",
    "output_delay_kalman": "optdesign.design.output_delay",
}

_SUBMODULES = ("metrics", "regions", "riccati", "problems", "noise", "classical", "studies",
               "analysis", "model", "formulate", "backends", "engines", "design", "compat", "plot")

__all__ = [
    "Plant",
    "Status",
    "Check",
    "Verification",
    "SolverStats",
    "Certificate",
    "DesignResult",
    "OptDesignError",
    "OptDesignWarning",
    "OptDesignDeprecationWarning",
    "ValidationError",
    "ArgumentTypeError",
    "DimensionError",
    "NotFiniteError",
    "NotSymmetricError",
    "NotPositiveDefiniteError",
    "NotPositiveSemidefiniteError",
    "UnreachableModesError",
    "NotObservableError",
    "NotControllableError",
    "NotConjugateClosedError",
    "EmptyRegionError",
    "InfeasibleError",
    "SolverError",
    "BackendUnavailableError",
    "RiccatiError",
    "ProblemNotFoundError",
    "ProblemFileError",
    "OutputExistsError",
    "OutputPathError",
    *_LAZY,
]


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        module = importlib.import_module(_LAZY[name])
        value = getattr(module, name)
        globals()[name] = value
        return value
    if name in _SUBMODULES:
        module = importlib.import_module(f"optdesign.{name}")
        globals()[name] = module
        return module
    raise AttributeError(f"module 'optdesign' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(__all__) | set(_SUBMODULES) | set(globals()))


if TYPE_CHECKING:  # pragma: no cover
    from .design.kalman import KalmanFilter, kalman  # noqa: F401
