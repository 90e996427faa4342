r"""The inverse Kalman problem: which ``Q >= 0`` gives a steady-state filter with these poles?

Two public verbs (seed 000, Chang & Lee 1984):

* :func:`kalman_for_poles` -- find ``Q >= 0`` (state-space, the seeds' ``Q' = D Q D'``) whose
  steady-state Kalman filter has the prescribed error poles ``eig(A - L C)``, by an SDP (single
  output: L is fixed by the poles), a CasADi/IPOPT NLP (several outputs, where L is free), or
  Solheim's sequential method (:func:`optdesign.classical.solheim`).  An unreachable target
  returns an infeasible result with a certificate: the frequency where the return-difference
  inequality fails, the SDP margin, and the closest achievable poles.
* :func:`is_kalman_optimal` -- is a given gain L the Kalman gain of some ``Q >= 0``?  For a
  fixed L the admissible Q form an affine slice of the PSD cone (the linear-in-P relations of
  :mod:`optdesign.formulate.inverse_kalman`), so the answer is an SDP; by the KYP lemma it is
  the return-difference (circle) condition ``T R T^* >= R`` (discrete: ``T V T^* >= R``), which
  :func:`optdesign.analysis.robustness.circle_condition` evaluates and which supplies the
  frequency certificate when the answer is no.

Which member of the family of Q each objective returns
------------------------------------------------------
For a fixed gain the Q that work form a convex set (Example 1 of seed 000: a segment, ``P22``
free, ``Q = [[76, -30 - P22], [-30 - P22, 10 P22 - 36]]``):

* ``"min_trace"`` -- the smallest ``trace(Q)``; the answer lies on the boundary of the PSD cone
  (rank-deficient Q).  Example 1: ``P22 = 350 - sqrt(118864) = 5.2334``, ``Q`` of rank one.
* ``"nearest"`` -- the Q (or Qw) closest in Frobenius norm to ``Q_nominal`` (default: the
  plant's own noise model).
* ``"feasibility"`` -- the most robustly positive member: maximal smallest eigenvalue.
  Example 1: ``P22 = 49.23``, ``lambda_min(Q) = 60.2`` (the maximizer is flat: known to ~1e-4).
* ``method="sequential"`` -- whatever the sequential construction gives (Example 1:
  ``P22 = 12``, the paper's ``Q' = [[76, -42], [-42, 84]]``); the objective is ignored.

With several outputs the NLP optimizes over L as well: the best of a few starts (a local
optimum; at the returned L the returned Q is the optimum of that gain's convex family).

How an answer is computed and checked
-------------------------------------
* ``method="sdp"`` (one output): L from robust pole placement refined by Newton steps on the
  eigenvalues (Ackermann's formula for repeated poles), then the fixed-gain SDP
  (:func:`optdesign.formulate.inverse_kalman.build_fixed_gain_sdp`).  The SDP point is
  *polished*: its face of the PSD cone is read off the eigenvalue gap of Q (``Q = U W U'``),
  the linear relations are re-solved on that face by least squares and the face itself is
  refined by Gauss-Newton on ``Q = V V'``, so that ``(P, Q)`` satisfy the Riccati equation to
  rounding error with Q exactly PSD.  A numerical failure of Clarabel is retried with more
  regularization, then with SCS; an objective SDP whose point fits no face falls back to the
  feasibility SDP's point (status ``optimal_inaccurate``).  Such a design, or one whose polish
  moved the objective by more than 1e-7 relative (a badly scaled family: large gains, nearly
  singular P), is compared with the spectral SDP's (in Q alone), and the better verified one
  is returned.
* ``method="sdp"`` (several outputs, where the poles do not fix L): L from the NLP below
  (else, for a full Q, from the sequential method), then the same fixed-gain SDP at that L.
  Its Q is the objective's optimum over that gain's convex family -- never worse than the
  NLP's own Q -- and a genuine SDP certificate that L is a Kalman gain; the design is
  verified like any other.  If that SDP stage fails the NLP's verified design is returned
  (``method="nlp"``, the reason in ``message``).
* ``method="nlp"``: the spectral-identity NLP in Q alone
  (:func:`optdesign.formulate.inverse_kalman.build_spectral_nlp`) from a few starts; L and P
  then come from one Riccati solve with the optimized Q.  For structures ``"full"`` /
  ``"input"`` and objectives ``"min_trace"`` / ``"nearest"`` the constraint Jacobian and the
  Lagrangian Hessian are evaluated in closed form
  (:func:`optdesign.formulate.inverse_kalman.build_spectral_nlpsol`): CasADi's symbolic
  differentiation of the same problem took most of the time per start for n >= 20.  Where a
  target is an eigenvalue of A (or of its mirror) the state-space NLP is used instead.  When
  no start gives a verified design (typical of rank-deficient targets, whose optimum is a degenerate point of
  ``Q = F F'``), the starts are re-run with IPOPT's adaptive barrier update and a larger
  budget, from the sequential method's Q and from seeded random covariances; then a
  least-squares form of the spectral conditions and the closest-poles search
  decide between "reachable after all" (returned, objective not optimized) and "infeasible"
  (a certificate with the closest achievable poles -- local evidence for several outputs;
  for one output the return-difference test at the gain the poles fix is a proof, and is
  reported as on the SDP path).
* Verification (independent of the solver): numpy eigenvalues of ``A - L C`` against the
  targets, the Riccati residual of the returned P with the returned Q, a re-solve of the
  Riccati equation with the returned Q by the Hamiltonian Schur method whose L and poles must
  match, and the PSD eigenvalues of Q (and Qw) and P.  The pole tolerance is ``tol`` raised to
  the rounding floor of the poles of ``A - L C`` when that is larger (capped at 1e-6): poles
  with eigenvalue condition number kappa cannot be computed better than ``~kappa eps ||A - LC||``.
"""

from ...formulate.inverse_kalman import OBJECTIVES, STRUCTURES
from .common import METHODS
from .optimality import is_kalman_optimal
from .results import InfeasibilityCertificate, InverseKalmanResult, KalmanOptimalityResult
from .sdp_stage import sdp_reuse
from .verb import InverseKalmanProblem, kalman_for_poles

__all__ = [
    "METHODS",
    "OBJECTIVES",
    "STRUCTURES",
    "InfeasibilityCertificate",
    "InverseKalmanResult",
    "kalman_for_poles",
    "InverseKalmanProblem",
    "KalmanOptimalityResult",
    "is_kalman_optimal",
    "sdp_reuse",
]
