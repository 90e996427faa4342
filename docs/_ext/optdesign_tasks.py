"""The task groups of the API reference (read by ``optdesign_docs``): which public objects are listed
under which task, in which order.  Edit here to move an object to another group or to add a group;
``tests/test_docs.py`` fails when a name of ``optdesign.__all__`` is in no group."""

from __future__ import annotations

__all__ = ["TASKS"]

#: the API reference's task groups: (title, what it is for, names).  A name is a public dotted path, or
#: ``module.*`` for every name in that module's ``__all__``.  Each object named here has a page of its
#: own (``api/generated/<canonical name>.rst``) and is listed under its task; every name of
#: ``optdesign.__all__`` must be in a group (a name left out is listed under "Other", and a test fails).
TASKS: tuple[tuple[str, str, tuple[str, ...]], ...] = (
    ("Design an observer", "Luenberger observers with their poles placed or free in a region, minimizing "
     "the eigenvector condition number; generalized and noise-rejecting observers; the estimator as a "
     "system.",
     ("optdesign.well_conditioned_observer", "optdesign.ObserverDesign", "optdesign.generalized_observer",
      "optdesign.GeneralizedObserver", "optdesign.noise_rejecting_observer",
      "optdesign.NoiseRejectingObserver",
      "optdesign.simulate_observer", "optdesign.ObserverSimulation", "optdesign.estimator_system",
      "optdesign.EstimatorArrays")),
    ("Kalman filters", "Steady-state, sampled, finite-horizon, well-conditioned and output-delay Kalman "
     "filters, and the noise covariances estimated from data.",
     ("optdesign.kalman", "optdesign.KalmanFilter", "optdesign.kalmd", "optdesign.van_loan",
      "optdesign.kalman_finite_horizon", "optdesign.KalmanSequence", "optdesign.well_conditioned_kalman",
      "optdesign.output_delay_kalman", "optdesign.estimate_noise", "optdesign.NoiseEstimate",
      "optdesign.simulate_outputs")),
    ("Inverse Kalman: which Q gives these poles, is this gain optimal",
     "The process noise whose Kalman filter has given poles (or the certificate that none has), and the "
     "return-difference test of a given gain.",
     ("optdesign.kalman_for_poles", "optdesign.InverseKalmanResult", "optdesign.InverseKalmanProblem",
      "optdesign.is_kalman_optimal", "optdesign.KalmanOptimalityResult")),
    ("State feedback", "The duals: well-conditioned pole placement and the inverse LQR.",
     ("optdesign.place", "optdesign.PlacementResult", "optdesign.well_conditioned_feedback",
      "optdesign.FeedbackDesign", "optdesign.lqr_for_poles", "optdesign.InverseLQRResult",
      "optdesign.dual_plant")),
    ("Robust design", "One gain for a set of models: the NLP on the worst case, the LMI with a common "
     "Lyapunov matrix, and the evaluation of a gain on every model.",
     ("optdesign.robust_observer", "optdesign.robust_lmi_observer", "optdesign.RobustObserverDesign",
      "optdesign.per_model_designs", "optdesign.evaluate_gain", "optdesign.ModelSet")),
    ("Plants and conversions", "The plant, its coercion from python-control and scipy systems, and back.",
     ("optdesign.Plant", "optdesign.as_plant", "optdesign.as_system")),
    ("Pole regions", "Where the poles may go: half-planes, disks, sectors, strips, ellipses and their "
     "intersections, continuous and discrete.", ("optdesign.regions.*",)),
    ("Noise models", "Output-noise models of the generalized observers.", ("optdesign.noise.*",)),
    ("Analysis: conditioning, robustness, norms", "Pure functions of matrices: condition numbers, return "
     "difference, circle condition, margins, H2 and Hinf norms.",
     ("optdesign.return_difference", "optdesign.circle_condition", "optdesign.filter_margins",
      "optdesign.h2_norm", "optdesign.hinf_norm", "optdesign.metrics.*")),
    ("Riccati equations", "Algebraic Riccati equations with residuals and error estimates, and the "
     "Riccati differential equation.",
     ("optdesign.riccati_de", "optdesign.RiccatiTrajectory", "optdesign.riccati.*")),
    ("Studies", "Sweeps and Pareto fronts over design parameters, spec files, the seed papers' "
     "reproductions.", ("optdesign.studies.*",)),
    ("Plots", "Pole maps with regions, model clouds, figures (matplotlib optional, no backend forced).",
     ("optdesign.plot.*",)),
    ("Problem library", "Named design problems with citations and reference values.",
     ("optdesign.problems.*",)),
    ("Drop-ins for scipy and python-control", "The peers' call forms and returns, gains designed by "
     "optdesign.", ("optdesign.compat.scipy.*", "optdesign.compat.control.*")),
    ("Results, statuses and errors", "The result base every verb returns, its checks and route, and the "
     "errors (each a subclass of a builtin, rooted at OptDesignError).",
     ("optdesign.results.*", "optdesign.errors.*")),
)
