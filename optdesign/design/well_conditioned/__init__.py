r"""Well-conditioned observers and Kalman filters (seed 001, generalized to any order).

``well_conditioned_observer`` chooses the observer gain ``L`` so that the eigenvector matrix of
the error dynamics ``A - L C`` is as well conditioned as possible -- minimizing ``kappa2``
(seed 001's principal index), ``kappa_fro`` or Huh & Stein's ``eta`` -- with the poles either

* fixed (the job of ``scipy.signal.place_poles`` YT/KNV0, but minimizing kappa2 itself; like
  YT it accepts a pole repeated up to ``rank(C)`` times -- KNV0 takes real poles only -- and
  above that it answers infeasible with a certificate, where YT raises), or
* free inside a pole region (:mod:`optdesign.regions`; a discrete-time region when
  ``plant.dt`` is set; the region must lie in the closed stability region of the plant's
  time domain),

optionally with structural zeros in ``L``, a bound on ``||L||_2`` and a bound on the other
metric (trade-off: minimize eta subject to ``kappa2 <= kappa2_max``, or the reverse).

``well_conditioned_kalman`` does the same for a true Kalman filter: the noise covariance is
the design variable and the filter Riccati equation is a constraint.

Every design follows validate -> problem (:class:`WellConditionedProblem`, held by the caller) ->
solve (the placement engine of :mod:`optdesign.engines.eigenstructure`; IPOPT on the NLPs of
:mod:`optdesign.formulate.well_conditioned` where the engine does not handle a constraint or its
design does not verify) -> verify (numpy/scipy, independently of the solver) -> result.

The package, by responsibility: :mod:`.results` (:class:`ObserverDesign`), :mod:`.evaluation` (the
independent checks of a candidate, the ranking of starts), :mod:`.starts` (starting points and the
reference poles of region mode), :mod:`.engine_route` and :mod:`.nlp_route` (the two inner loops),
:mod:`.problem` (:class:`WellConditionedProblem`), :mod:`.verb` (:func:`well_conditioned_observer`),
:mod:`.kalman` (:func:`well_conditioned_kalman`).

References
----------
Jung, J. & Huh, K., "Design of the well-conditioned observer using the non-normality
measure" (seed 001).
Huh, K. & Stein, J. L., "Well-conditioned observer design for observer-based monitoring
systems", ASME J. Dyn. Sys. Meas. Control 117 (1995) 592-599.
Kautsky, J., Nichols, N. K. & Van Dooren, P., "Robust pole assignment in linear state
feedback", Int. J. Control 41 (1985) 1129-1155.
Lewis, A. S. & Overton, M. L., "Nonsmooth optimization via quasi-Newton methods", Math.
Programming 141 (2013) 135-163.
"""

from ...backends.casadi_backend import check_ipopt_options
from ..verification import kappa2_agreement_tol
from .evaluation import (
    POLE_TOL,
    Candidate,
    check_region_stable,
    design_outcome,
    evaluate_candidate,
    objective_lower_bound,
    pick_best,
)
from .kalman import WellConditionedKalmanProblem, well_conditioned_kalman
from .nlp_route import solve_nlp
from .problem import WellConditionedProblem
from .results import ObserverDesign, StartRecord
from .starts import naive_poles, placement_start, start_real_count, start_real_counts, suggested_region
from .verb import well_conditioned_observer

__all__ = [
    "ObserverDesign",
    "StartRecord",
    "WellConditionedProblem",
    "WellConditionedKalmanProblem",
    "well_conditioned_observer",
    "well_conditioned_kalman",
    "naive_poles",
    "suggested_region",
    "start_real_counts",
    "start_real_count",
    # building blocks (the independent checks and the outcome of a multi-start design)
    "POLE_TOL",
    "Candidate",
    "evaluate_candidate",
    "kappa2_agreement_tol",
    "check_region_stable",
    "check_ipopt_options",
    "placement_start",
    "solve_nlp",
    "pick_best",
    "design_outcome",
    "objective_lower_bound",
]
