r"""The engines' tolerances and algorithm constants, in one table: each named, with its derivation or
its measurement.

The engines (:mod:`optdesign.engines`) propose candidates and never decide success: that is
:mod:`optdesign.design.verification`'s tolerance table.  What is here are the *inner* thresholds of
the algorithms -- when a factorization is rank deficient, when a stage has converged, when a
polish has reached rounding, the line-search constants -- so that no engine module holds a bare
literal and every number has one name and one reason.

Two kinds:

* **Rounding levels** (:func:`rounding_level`): ``factor * size * eps * scale``, the error of a
  backward-stable computation with ``size`` terms of magnitude ``scale``; the factor is a named
  safety margin (``*_FACTOR``).  These follow the data (size, scale) by construction.
* **Relative thresholds** (``*_RTOL``, ``*_TOL``, stage tables): compared with a quantity already
  normalized by its data's scale (a relative residual, a ratio of singular values, a relative
  decrease of ``f``), so scale-free; their values are measured (the comment says where) or the
  standard values of the cited method.

Every value equals the literal it replaced (issue 29: behaviour unchanged; the engines' tests and
``benchmarks/bench_quasi_newton.py`` were run before and after).

References
----------
J. Nocedal and S. J. Wright, Numerical Optimization, 2nd ed., Springer 2006 (line searches, ch. 3;
trust regions, ch. 4).
A. Waechter and L. T. Biegler, Math. Program. 106 (2006) 25-57 (the filter's margins).
A. S. Lewis and M. L. Overton, Math. Program. 141 (2013) 135-163 (BFGS on nonsmooth functions).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "EPS", "NORM_FLOOR", "rounding_level",
    # eigenstructure placement
    "POLE_COINCIDE_RTOL", "SPREAD_REAL_RTOL", "CONJUGATE_RTOL", "NULL_BASIS_FACTOR", "PBH_RANK_FACTOR",
    "STAGE_FTOL", "STAGE_FTOL_DEFAULT", "STAGE_GTOL", "DISTINCT_FTOL_MIN", "DISTINCT_F_MIN",
    "DISTINCT_X_MIN", "MASK_TOL",
    # quasi-Newton and line searches
    "QN_FTOL", "QN_XTOL", "ARMIJO_C1", "WOLFE_C2",
    # one-output SDP, dense IPM, polish
    "LYAPUNOV_GAP_FACTOR", "QR_RANK_FACTOR", "POLISH_START_TOL", "POLISH_ROUNDING_FACTOR", "KKT_TOL",
    "IPM_TOL", "IPM_FLOOR_FACTOR", "CONJ_IMAG_RTOL", "FACE_POLISH_THRESHOLDS",
    "SPECTRAL_POLISH_THRESHOLDS", "FACE_REFINE_MIN", "FACE_REFINE_MAX", "POLISH_EXACT_RES",
    "POLISH_ROUNDING_RES",
    # spectral factor / Newton / SQP
    "RESIDUAL_ROUNDING_FACTOR", "FEASIBLE_RESIDUAL_FACTOR", "DECREASE_ROUNDING_FACTOR", "QR_RANK_RTOL",
    "TRUNCATE_RTOL", "NEWTON_GTOL", "SQP_FEAS_RTOL", "GN_MIN_STEP", "MIN_STEP", "RADIUS_SHRINK_MIN",
    "TR_SHIFT_RTOL", "TR_BISECT_RTOL", "FILTER_THETA_MAX_FACTOR", "FILTER_GAMMA_THETA", "FILTER_GAMMA_F",
    # normal closed loop search (Levenberg-Marquardt)
    "NORMAL_ROUNDING_FACTOR", "LM_DAMPING_START", "LM_DAMPING_MIN", "LM_DAMPING_MAX", "LM_DIAG_FLOOR",
    # inverse Kalman engine
    "RANK_EIG_FLOOR", "START_REGULARIZATION", "ESCAPE_STEP", "ESCAPE_NORM_FLOOR", "WARM_EIG_FLOOR",
    "IK_KKT_TOL", "CLARABEL_MARGIN_FACTOR", "INVERSE_KALMAN_POLE_TOL", "FIRST_TRY_TOL", "RICCATI_RESIDUAL_TOL",
    "FORWARD_ERROR_TOL", "POLE_FLOOR_CAP", "pole_tolerance", "NOMINAL_EIG_FLOOR",
    # region mode
    "REGION_STAGES", "REGION_FTOL", "REGION_PRUNE_FTOL", "REGION_PRUNE_MARGIN",
    "REGION_PRUNE_HORIZON",
    "MARGIN_RTOL", "DUP_FTOL", "DUP_PTOL",
    "STENCIL_MIN_SCALE",
    "QUADRATIC_MISFIT_TOL", "CLEARANCE_FLOOR", "INSIDE_FRACTION", "MAP_SERIES", "MAP_INVERSE_CLIP",
    "HOMOTOPY_MIN_STEP", "HOMOTOPY_ROUNDING",
]

#: unit roundoff of float64 (2.2e-16)
EPS = float(np.finfo(float).eps)

#: the smallest norm a ratio divides by (``x / max(||y||, NORM_FLOOR)``): a guard against 0 / 0 for
#: an all-zero matrix, far below any data scale (float64 reaches 2.2e-308), so it never changes a
#: ratio of nonzero data
NORM_FLOOR = 1e-300


def pole_tolerance(F: NDArray, tol: float) -> float:
    """``max(tol, min(floor, POLE_FLOOR_CAP))`` with ``floor`` the rounding floor of the eigenvalues
    of F (:func:`~optdesign.analysis.metrics.eigenvalue_rounding_floor`): no gain can be verified to
    better than its poles can be computed; the cap keeps the check meaningful for (nearly) defective
    poles.  The one rule of the engines and of :mod:`optdesign.design.verification` (which re-exports it)."""
    from ..analysis.metrics import eigenvalue_rounding_floor

    return max(float(tol), min(eigenvalue_rounding_floor(F), POLE_FLOOR_CAP))


def rounding_level(size: int, scale: float, factor: float = 1.0) -> float:
    """``factor * size * EPS * scale``: the rounding error of a backward-stable computation with
    ``size`` terms of magnitude ``scale`` (Higham, *Accuracy and Stability of Numerical
    Algorithms*, 2nd ed., 2002, ch. 3), times a safety ``factor``.

    Evaluated left to right in this order, so it equals the expression it replaced bit for bit.

    Parameters
    ----------
    size : int
        Number of terms (a dimension ``n``, or 1 for one rounding).
    scale : float
        Magnitude of the terms (a norm of the data).
    factor : float, default 1
        Safety margin (one of the ``*_FACTOR`` constants).

    Returns
    -------
    float
    """
    return factor * size * EPS * scale


# ======================== eigenstructure placement
# (engines/eigenstructure.py, engines/eigenstructure_fixed.py)

#: two poles within ``POLE_COINCIDE_RTOL max(1, |p|)`` are one repeated pole: ~4.5e5 eps, far above
#: the rounding of poles typed or computed by a user (``~ eps |p|``)
POLE_COINCIDE_RTOL = 1e-10
#: a point of a spread real pole within ``SPREAD_REAL_RTOL`` times the spreading radius of the real
#: axis is put on it (``exp(1j pi)`` has imaginary part 1.2e-16, not 0)
SPREAD_REAL_RTOL = 1e-12
#: relative tolerance of :func:`~optdesign._validate.as_poles` for the fixed-pole model (real vs
#: complex, conjugate partners): its default, ~1e8 eps, the accuracy of poles computed by a user
CONJUGATE_RTOL = 1e-8
#: numerical rank of ``(A - lam I) Z`` (pivoted QR): diagonal entries above
#: ``rounding_level(n, max(|R_11|, ||A||, |lam|), NULL_BASIS_FACTOR)`` -- QR's backward error
#: ``~ n eps ||M||`` with a margin of 100 for the pivoting's underestimate of the smallest singular value
NULL_BASIS_FACTOR = 100.0
#: an eigenvalue ``mu`` of A is unobservable when the smallest singular value of ``[A - mu I; C]``
#: is below ``rounding_level(n, max(||A||, ||C||), PBH_RANK_FACTOR)``: ``mu`` itself is computed to
#: ``~ n eps ||A||`` times its condition number; the margin 1e3 admits conditions up to 1e3
PBH_RANK_FACTOR = 1e3

#: per continuation stage (order ``k`` of the kappa2 bound ``phi_k``, None for the exact function):
#: the relative decrease of ``log kappa2`` over 8 BFGS iterations below which the stage ends.  Loose
#: early stages, measured (issue 13): tight ones spend evaluations on a surrogate whose minimizer is
#: discarded anyway
STAGE_FTOL: dict[int | None, float] = {4: 1e-5, 64: 1e-6, 1024: 1e-8, 16384: 1e-9, None: 1e-9}
#: the decrease tolerance of a stage order not in :data:`STAGE_FTOL`
STAGE_FTOL_DEFAULT = 1e-8
#: gradient tolerance of the smooth stages (``||g||_inf`` of ``log phi_k`` per unit change of the
#: unit-norm coordinates; the exact, nonsmooth stage has none)
STAGE_GTOL = 1e-6
#: duplicate starts (``_distinct``) are judged at the stage's ``ftol``, never below this one
DISTINCT_FTOL_MIN = 1e-12
#: ... with values equal to ``max(DISTINCT_F_MIN, ftol / 10)`` and normalized coordinates to
#: ``max(DISTINCT_X_MIN, sqrt(ftol))`` (near a smooth minimizer ``f - f* ~ |x - x*|^2``).  Measured
#: (issue 13): after the first stage starts in one basin sit up to 4e-3 apart with values equal to
#: 7e-7, distinct basins of equal value 0.4-1.7 apart
DISTINCT_F_MIN = 1e-9
DISTINCT_X_MIN = 1e-6
#: relative violation ``max |L_ij| / ||L_start||_F`` on the structural zeros accepted before they
#: are set to zero exactly (the poles then move by about that much times their condition numbers,
#: which the verification's pole check bounds)
MASK_TOL = 1e-9

# ======================== quasi-Newton, line searches
# (engines/quasi_newton.py and the Armijo tests of engines/spectral_newton.py)

#: default relative decrease of ``f`` over the window below which a BFGS start stops
QN_FTOL = 1e-10
#: a weak Wolfe line search gives up when its bracket ``t ||d|| / (1 + ||x||)`` is below this
#: (Lewis & Overton section 6.2: at a nonsmooth minimizer the normal end); ~4.5e5 eps
QN_XTOL = 1e-10
#: sufficient-decrease (Armijo) constant: the standard value (Nocedal & Wright, section 3.1)
ARMIJO_C1 = 1e-4
#: curvature constant of the (weak) Wolfe condition for quasi-Newton methods (Nocedal & Wright, 3.1)
WOLFE_C2 = 0.9

# ======================== one-output SDP, dense IPM, polish
# (engines/one_output_sdp.py, engines/fixed_gain_ipm.py, engines/polish.py)

#: the Lyapunov operator ``X -> A' X + X A`` is treated as singular when the smallest
#: ``|lam_i + lam_j|`` is below ``rounding_level(n, max(1, ||A||_1), LYAPUNOV_GAP_FACTOR)``: the
#: Bartels-Stewart solve's error grows as ``n eps ||A|| / gap``, at most ~1e-3 relative above it
LYAPUNOV_GAP_FACTOR = 1e3
#: full column rank of a QR factor: smallest ``|R_ii|`` above
#: ``rounding_level(rows, max |R_ii|, QR_RANK_FACTOR)`` (Householder QR's backward error
#: ``~ rows eps ||M||``, margin 1e3)
QR_RANK_FACTOR = 1e3
#: Clarabel's gap and feasibility tolerances before the Newton polish (relative to the normalized
#: data): the polish converges quadratically from there (measured: 2-3 Newton steps to rounding on
#: 24 targets n = 2..20; Clarabel 9-14 iterations)
POLISH_START_TOL = 1e-8
#: the Newton polish stops at a relative residual of ``rounding_level(1, 1, POLISH_ROUNDING_FACTOR)``
#: (4 eps: a few roundings of normalized terms; it otherwise stops when the residual stops halving)
POLISH_ROUNDING_FACTOR = 4.0
#: KKT test of the polished point: smallest eigenvalue of Z over ``||Z||`` at least ``-KKT_TOL``,
#: complementarity ``||Q Z|| / (||Q|| ||Z||)`` and primal infeasibility ``||W' svec(Q) - b|| / ||b||``
#: at most KKT_TOL (the polish reaches 1e-16 .. 1e-15; the engine's dual-slack test is 1e-9 too)
KKT_TOL = 1e-9
#: dense IPM stopping test: relative primal and dual infeasibility and relative duality gap (of the
#: column-scaled data) at most this -- Clarabel's tight settings are 1e-10; the polish finishes on
#: the face.  Measured (``bench_inverse_kalman.py --stages``): 1e-8 saves an IPM iteration but
#: triples the Newton polish at n = 20
IPM_TOL = 1e-9
#: the IPM's Q(x) is PSD to its rounding floor ``scale * dual residual +
#: rounding_level(n, gain ||P|| + scale ||L R L'||, IPM_FLOOR_FACTOR)`` (the terms of Q's formula)
IPM_FLOOR_FACTOR = 10.0
#: an eigenvalue is real for the Newton gain refinement when ``|Im| <= CONJ_IMAG_RTOL max(1, |lam|)``
#: (numpy's eig returns the real eigenvalues of a real matrix with imaginary parts ``~ eps |lam|``)
CONJ_IMAG_RTOL = 1e-12
#: relative eigenvalue thresholds that read the face of the PSD cone off an SDP point, the likeliest
#: first: the SDP solvers stop at 1e-8 .. 1e-10 relative accuracy, so the face's eigenvalues sit
#: above and the solver's residual below one of these (the polish then picks the best face)
FACE_POLISH_THRESHOLDS: tuple[float, ...] = (1e-6, 1e-7, 1e-5, 1e-8, 1e-4, 1e-9, 1e-3)
#: the same list without 1e-9, which the spectral polish has always used (not measured separately)
SPECTRAL_POLISH_THRESHOLDS: tuple[float, ...] = (1e-6, 1e-7, 1e-5, 1e-8, 1e-4, 1e-3)
#: the face polish refines the face by Gauss-Newton when its linear solve left a relative residual
#: in ``(FACE_REFINE_MIN, FACE_REFINE_MAX)``: above rounding (~45 eps) and within quadratic
#: convergence of a solution
FACE_REFINE_MIN = 1e-14
FACE_REFINE_MAX = 1e-3
#: a face (or rank) whose relative residual is below this (~450 eps) is exact to rounding: the
#: others are not tried
POLISH_EXACT_RES = 1e-13
#: Gauss-Newton stops once the relative residual is below this (~4.5 eps: rounding of the terms)
POLISH_ROUNDING_RES = 1e-15

# ======================== spectral factor, Newton, SQP
# (engines/spectral_factor.py, engines/spectral_newton.py)

#: the rounding level of the spectral residuals: ``rounding_level(n, scale of their terms,
#: RESIDUAL_ROUNDING_FACTOR)`` (8: the residuals are sums of a few products of n-vectors)
RESIDUAL_ROUNDING_FACTOR = 8.0
#: a point is feasible when ``||c|| <= FEASIBLE_RESIDUAL_FACTOR * residual_scale * sqrt(#c)``
#: (100x the rounding level per residual; :func:`~optdesign.engines.spectral_newton.project`'s default)
FEASIBLE_RESIDUAL_FACTOR = 100.0
#: Newton stops when the predicted decrease is below
#: ``rounding_level(1, max(1, |f|), DECREASE_ROUNDING_FACTOR)``: f itself is known to a few eps
DECREASE_ROUNDING_FACTOR = 16.0
#: numerical full row rank of the constraint Jacobian (QR of its transpose): smallest ``|R_ii|``
#: above ``QR_RANK_RTOL`` times the largest (~4.5e4 eps)
QR_RANK_RTOL = 1e-11
#: columns of V with relative singular value below this are removed (the Jacobian degenerates as
#: Q loses rank and Gauss-Newton crawls there)
TRUNCATE_RTOL = 1e-5
#: Newton converged when ``||Z' grad f|| <= NEWTON_GTOL max(1, |f|)``
NEWTON_GTOL = 1e-10
#: the SQP phase ends when ``||c|| <= SQP_FEAS_RTOL`` times the size of the residuals' terms
SQP_FEAS_RTOL = 1e-6
#: smallest step of the Gauss-Newton backtracking (at most 20 trial steps)
GN_MIN_STEP = 1e-6
#: smallest step of the Newton and SQP line searches (at most 27 trial steps)
MIN_STEP = 1e-8
#: a trust radius shrinks to the accepted step, never below this fraction of itself
RADIUS_SHRINK_MIN = 1e-8
#: the hard case of the trust-region subproblem is tested at ``lo + TR_SHIFT_RTOL max(1, max |w|)``
#: (just inside the positive definite side of the smallest eigenvalue, ~5e3 eps)
TR_SHIFT_RTOL = 1e-12
#: the trust-region multiplier by bisection to this relative accuracy
TR_BISECT_RTOL = 1e-12
#: the filter's upper bound on the infeasibility: this times ``max(1, theta_0)`` (Waechter & Biegler)
FILTER_THETA_MAX_FACTOR = 1e4
#: the filter's margins ``gamma_theta``, ``gamma_f`` (Waechter & Biegler's values)
FILTER_GAMMA_THETA = 1e-5
FILTER_GAMMA_F = 1e-5

# ======================== normal closed loop search
# (engines/normal_search.py)

#: the target margin inside the region and the residual tolerance:
#: ``rounding_level(1, ||A||, NORMAL_ROUNDING_FACTOR)`` (a normal matrix's eigenvalues round by
#: ``~ eps ||F||``) and that times ``||A||`` for the Gram residual (quadratic in A)
NORMAL_ROUNDING_FACTOR = 100.0
#: Levenberg-Marquardt damping: start, floor after successes (divided by 3), and the ceiling at which
#: a start gives up (multiplied by 4 on failures)
LM_DAMPING_START = 1e-3
LM_DAMPING_MIN = 1e-12
LM_DAMPING_MAX = 1e10
#: added to the diagonal scaling ``diag(J'J)`` so that a zero column still gets damping
LM_DIAG_FLOOR = 1e-12

# ======================== inverse Kalman engine
# (engines/inverse_kalman_engine.py, inverse_kalman_result.py, inverse_kalman_starts.py)

#: candidate ranks of an interior-point PSD matrix count only eigenvalues above this fraction of the
#: largest (~450 eps: below, rounding alone; the gap test is the engine's ``RANK_GAP_RATIO``)
RANK_EIG_FLOOR = 1e-13
#: the full-rank start factor: the Cholesky of ``W + START_REGULARIZATION trace(W) I`` (~4500 eps
#: relative: a PSD W with zero eigenvalues gets a factor, its other eigenvalues moved by rounding only)
START_REGULARIZATION = 1e-12
#: a new column of V along a negative dual-slack direction starts at this fraction of ``||V||``
#: (small: the projection onto the feasible set moves the point little), ``||V||`` taken at least
#: ``ESCAPE_NORM_FLOOR`` (~4500 eps: a vanishing V still gets a column above rounding)
ESCAPE_STEP = 1e-3
ESCAPE_NORM_FLOOR = 1e-12
#: a warm start's eigenvalues are raised to this fraction of its largest (positive definite:
#: Gauss-Newton starts at full rank; 1e-6 keeps its condition number below 1e6)
WARM_EIG_FLOOR = 1e-6
#: relative tolerance of the dual slack's smallest eigenvalue in the KKT test
IK_KKT_TOL = 1e-9
#: the engine's certificates and agreement tests allow 1000x Clarabel's own tolerances
#: (``tol_feas``, ``tol_gap_rel`` of ``CLARABEL_OPTIONS``): a margin or a gap that large is not the
#: interior-point method's stopping slack
CLARABEL_MARGIN_FACTOR = 1e3
#: default relative tolerance of the engine's placed poles (``solve_inverse_kalman(tol=)``): the
#: verb's pole tolerance before its data-derived floor (``max(tol, min(floor, POLE_FLOOR_CAP))``)
INVERSE_KALMAN_POLE_TOL = 1e-8
#: the one-output SDP's loose first try: Clarabel's gap and feasibility tolerances (measured in
#: ``benchmarks/results/inverse_kalman_one_output_tolerances.md``; the polish finishes the point)
FIRST_TRY_TOL = 1e-6
#: relative residual of the filter ARE a returned (P, Q) must meet: 1e-8 = ~5e7 eps, the residual of
#: the Newton points measured on the cross-validation targets stays below 1e-11 (as the verb's table)
RICCATI_RESIDUAL_TOL = 1e-8
#: a posteriori relative forward error of P allowed (the same value as ``POLE_FLOOR_CAP``: P is not
#: required to be more accurate than the poles it places)
FORWARD_ERROR_TOL = 1e-6
#: the pole tolerance is never raised above this, however ill-conditioned the poles (the engines' and
#: the design layer's verification share it: ``optdesign.design.verification`` imports it)
POLE_FLOOR_CAP = 1e-6
#: the scaled nominal start's eigenvalues are raised to this fraction of its largest (positive
#: definite, condition number at most 1e3: a factor of full rank for the SQP)
NOMINAL_EIG_FLOOR = 1e-3

# ======================== region mode of the eigenstructure engine
# (engines/eigenstructure_region.py, eigenstructure_region_lockstep.py)

#: continuation of the region mode: (order k of the kappa2 bound or None for the exact function,
#: weight mu of the barrier) per stage.  The schedule was chosen for the region barrier (issue 28,
#: measured: from mu = 1e-2 the first stage pushed a pole off the boundary where the optimum has it,
#: COMPleib AC17 ending at 1.67521 instead of 1.64565); the region is now the image of the pole map
#: (engines/region_map.py) and mu weights only the separation barrier that keeps poles apart
REGION_STAGES: tuple[tuple[int | None, float], ...] = (
    (4, 1e-3), (64, 1e-4), (1024, 1e-5), (16384, 1e-7), (None, 1e-9)
)
#: relative decrease (over the BFGS window) below which a stage stops, per kappa2 order k: loose early
#: stages as in the fixed-pole engine (their minimizers are discarded by the next stage), the exact
#: function to the accuracy the fixed-pole polish works at
REGION_FTOL: dict[int | None, float] = {4: 1e-7, 64: 1e-7, 1024: 1e-7, 16384: 1e-7, None: 1e-9}
#: ... but kappa2's second stage (k = 64, after which only 4 members go on, its stragglers pruned):
#: measured on 49 plants n <= 10 (issue 28, round 10, with REGION_PRUNE_HORIZON) 0.96x the CPU and none
#: worse than with 1e-7 by more than 1e-4; 3e-6 lost 5 % on COMPleib UWV.  Not for eta: COMPleib AC7
#: +4 % and random n = 10 s2 0.2 % worse than IPOPT alone
REGION_PRUNE_FTOL = 1e-6
#: a member of region mode's second stage still running once as many members as go on have stopped
#: lower stops when its value (log kappa2 bound plus barrier) exceeds theirs by more than this (relative):
#: measured on 49 plants n <= 10 (issue 28), a margin of 0 lost 0.18 % on COMPleib PSM, 0.02 none
REGION_PRUNE_MARGIN = 2e-2
#: ... and only when it would still be above them after this many more BFGS windows at its current
#: rate of decrease (``bfgs_minimize_batch(keep_horizon=...)``): with the second stage's looser
#: REGION_PRUNE_FTOL the members stop sooner, and a member still descending fast was pruned that would have
#: ended best (COMPleib PSM +0.18 % with 0 or 4 windows; 6 and 10 windows none, at the same CPU)
REGION_PRUNE_HORIZON = 10.0
#: a candidate's poles count as inside when ``region.margin`` is at most this times their modulus (the
#: rounding of eigvals of a matrix whose eigenvalues sit on the boundary, with a margin for kappa2 ~ 1e8)
MARGIN_RTOL = 1e-7
#: two members are at one point when their values agree to this (relative; a tenth of the stages'
#: decrease tolerance, as in the fixed-pole engine's ``_distinct``) ...
DUP_FTOL = 1e-8
#: ... (DUP_FTOL) and their sorted poles to this times the poles' scale (``sqrt`` of the decrease tolerance:
#: near a smooth minimizer ``f - f* ~ |x - x*|^2``)
DUP_PTOL = 3e-4
#: the quadratic stencil of a region's constraints is at least this wide (a region of clearance
#: below it is fitted on this scale: its constraints are exact quadratics, so any width fits)
STENCIL_MIN_SCALE = 1e-6
#: a constraint must be reproduced by its quadratic fit to this relative misfit (~4500 eps: rounding
#: of the least-squares fit of exact quadratics; a larger misfit is a region breaking the contract)
QUADRATIC_MISFIT_TOL = 1e-9
#: the region's pole map (engines/region_map.py) uses the series of ``sin(x)/x`` and its derivative
#: below this ``|x|`` (their truncation errors, ``x^4/120`` and ``x^3/30``, are then below 1e-17)
MAP_SERIES = 1e-4
#: a pole handed to the map's inverse sits at most this fraction of the way to the boundary along its
#: ray (a pole on the boundary is the fold: the inverse takes the increasing branch just inside)
MAP_INVERSE_CLIP = 1.0 - 1e-12
#: the target-pole continuation (engines/pole_homotopy.py, issue 26): a path whose step in t falls
#: below this ends (a turning point or a singular target on the way)
HOMOTOPY_MIN_STEP = 1e-6
#: ... a pole with ``|Im|`` below this many roundings of the poles' scale is real when the poles are
#: written as real quadratic factors, and the interpolated factors' roots are rounded to that level
HOMOTOPY_ROUNDING = 1e3
#: the smallest clearance reported for a region's interior point (a guard against a zero divisor;
#: far below any region's scale)
CLEARANCE_FLOOR = 1e-12
#: a start's pole moved inside the region must clear the boundary by this fraction of the region's
#: inner radius, else it is moved halfway to the interior point (a start on the boundary has an
#: infinite barrier)
INSIDE_FRACTION = 1e-3
