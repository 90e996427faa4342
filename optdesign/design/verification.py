r"""Independent verification of designs: one vocabulary of checks, one tolerance table.

Every design verb checks its answer here, with numpy/scipy and independently of the solver that
produced it; a design whose check fails is not ``success``, whatever the solver said.  Each check
has one name (:data:`CHECK_NAMES`) and one tolerance rule, derived from the size, scale and
conditioning of the data at hand -- never a bare constant tuned to one CPU:

Tolerance table (value -> tolerance, and why):

``pole_error``
    max relative distance of ``eig(A - L C)`` (numpy) to the targets ->
    ``max(tol, min(floor, 1e-6))``, ``floor`` the rounding floor of the eigenvalues of ``A - L C``
    (:func:`~optdesign.analysis.metrics.eigenvalue_rounding_floor`): no pole is computable better.
``stability_margin``
    ``-max Re`` (continuous) or ``1 - max |.|`` (discrete) of ``eig(A - L C)`` -> more than the
    absolute rounding level of those poles (floor times ``max(1, ||A - L C||)``).
``riccati_residual``
    relative residual of the filter ARE, normalized by the size of its terms -> :data:`RESIDUAL_TOL`
    (1e-8; the residual is scale-free, and 0 when every term vanishes).
``forward_error``
    a posteriori relative error of P (:func:`~optdesign.classical.riccati.filter_are_error`: Newton
    correction of the residual + rounding response) -> :data:`FORWARD_ERROR_TOL` (1e-6: P known to
    6 digits; an ill-conditioned equation fails it honestly through its rounding response).
``P_min_eig``
    ``lambda_min(P) / ||P||`` -> ``>= -(forward error of P + 10 n eps)``: P is known to its error.
``Q_min_eig``, ``Qw_min_eig``
    ``lambda_min(X) / ||X||`` -> ``>= -10 n eps``: eigvalsh is backward stable, so a PSD X shows
    eigenvalues ``>= -n eps ||X||``.
``are_resolve_gain``
    ``||L_are - L|| / max(1, ||L||)``, ``L_are`` from an independent Riccati solve with Q ->
    ``4 (err_P + err_are + 10 n eps cond) ||P|| ||dL/dP|| / max(1, ||L||)``, capped at 1e-6: the two
    gains differ by what the errors of the two P (and the gain formula's rounding) explain.  For a
    one-output design from no Riccati solver (:func:`newton_kalman_checks`) ``L_are`` is the gain of
    one Newton step of the equation from P (the stabilizing solution to second order in P's error:
    P's closed loop is stable), with ``err_are = err_P``; the full checks decide what it does not pass.
``are_resolve_poles``
    poles of that solve vs the targets -> as ``pole_error``; when that gain passed its check but its
    poles miss, raised to the design's pole error plus the first-order movement of its poles by the
    gain difference (:func:`resolve_pole_tolerance`: a gain that agrees to 1e-9 moves poles of
    condition 1e5 by more than their rounding floor).
``cross_check``
    ``||P - P_other|| / max(||P||, ||P_other||)`` -> ``4 (err_P + err_other) + 10 n eps``: two
    solvers agree to what their own error estimates explain (a difference explained by the other
    solver's residual passes).

Observer designs (:mod:`optdesign.design.well_conditioned`; ``floor`` is the rounding floor of the
poles of ``A - L C``, capped at :data:`POLE_FLOOR_CAP`):

``stability``
    ``max Re eig(A - L C)`` -> ``<= -floor max(1, max |pole|)`` (continuous), or the spectral radius
    -> ``<= 1 - floor`` (discrete): stable beyond the rounding level of the poles.
``region_margin``
    ``region.margin(poles)`` (max signed distance, ``<= 0`` inside) -> ``max(REGION_TOL, floor)``
    times ``max(1, max |pole|)``: a free-pole design meets its region constraints to ~1e-10; no pole
    is placed better than it can be computed.
``eig_residual``
    ``||(A - L C) Z - Z diag(poles)||_F / (||A - L C||_F ||Z||_F)`` of the solver's eigenbasis ``Z``
    -> :data:`EIG_RESIDUAL_TOL` (1e-8): ``Z`` is an eigenbasis (backward error, scale-free).
``kappa2_agreement``
    ``|cond(Z) - kappa2| / kappa2`` (``kappa2`` from numpy's eigenvectors,
    :func:`optdesign.analysis.metrics.kappa2`) -> :func:`kappa2_agreement_tol`:
    ``1e-6 + 10 eps kappa2 ||A - L C||_F / gap`` (``gap`` the smallest distance between two poles),
    at most 1 %: two computed eigenbases differ per column by ``~ eps ||X|| / gap``, which kappa2
    amplifies in their condition numbers.
``mask``
    largest ``|L|`` entry outside the structure mask -> ``0`` (the structural zeros are set exactly).
``gain_bound``, ``eta_bound``
    ``||L||_2`` and eta -> the bound times ``1 + BOUND_RTOL`` (1e-6: the NLP meets it to ~1e-10,
    the metric is recomputed with numpy).
``kappa2_bound``
    kappa2 -> ``kappa2_max (1 + kappa2_agreement_tol(kappa2_max))``: to the accuracy of a computed
    kappa2.
``finite_gain``, ``feasible``
    a gain with NaN / Inf entries, or a design with no gain (the verdict is in the message) ->
    fails (value inf, tolerance 0).

The factor 4 (:data:`ESTIMATE_FACTOR`) is the safety margin on first-order *estimates*.

References
----------
Higham, N. J., *Accuracy and Stability of Numerical Algorithms*, 2nd ed., SIAM (2002): backward
stable symmetric eigenvalues (ch. 15 notes), Lyapunov/Sylvester conditioning (ch. 16).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from .._validate import as_str
from ..analysis.metrics import eigenvalue_rounding_floor, eigenvector_matrix
from ..classical.placement import pole_error
from ..classical.riccati import (
    AREErrorEstimate,
    AREResult,
    are_correction_of_terms,
    are_error_of_terms,
    filter_are,
    filter_are_error,
    filter_are_residual,
    filter_are_terms,
    filter_gain,
    hamiltonian_are,
    relative_residual,
    sort_poles,
)
from ..engines.tolerances import (
    FORWARD_ERROR_TOL,
    MARGIN_RTOL,
    POLE_FLOOR_CAP,
    RICCATI_RESIDUAL_TOL,
    pole_tolerance,
)
from ..errors import OptDesignError, RiccatiError
from ..model.plant import Plant
from ..results import Check

__all__ = [
    "CHECK_NAMES",
    "ESTIMATE_FACTOR",
    "RESIDUAL_TOL",
    "FORWARD_ERROR_TOL",
    "POLE_FLOOR_CAP",
    "pole_tolerance",
    "pole_check",
    "resolve_pole_tolerance",
    "resolve_poles_check",
    "stability_check",
    "henrici_bound",
    "psd_check",
    "psd_tolerance",
    "riccati_checks",
    "lean_riccati_checks",
    "newton_kalman_checks",
    "forward_error_check",
    "independent_are",
    "ARE_SOLVERS",
    "AVOID_CHOICES",
    "cross_check",
    "check_violation",
    "relative_difference",
    "EIG_RESIDUAL_TOL",
    "REGION_TOL",
    "BOUND_RTOL",
    "KAPPA2_TOL",
    "KAPPA2_TOL_MAX",
    "kappa2_agreement_tol",
    "eigen_spread",
    "observer_stability_check",
    "region_margin_check",
    "eig_residual_check",
    "kappa2_agreement_check",
    "bound_check",
]

_EPS = float(np.finfo(float).eps)

#: the closed vocabulary of check names used by the verbs (extended per verb family below)
CHECK_NAMES = frozenset({
    "pole_error", "stability_margin", "stability", "spectral_radius", "riccati_residual", "forward_error",
    "P_min_eig", "Q_min_eig", "Qw_min_eig", "are_resolve_gain", "are_resolve_poles", "cross_check",
    "structure", "gain_relation_asymmetry", "gain_relation_min_eig", "gain_relation_residual", "margin",
    "circle_condition", "feedback_pole_error", "feedback_region_margin", "feedback_stability_margin",
    "nonfinite", "error_estimate",
    # observer designs (well-conditioned, generalized)
    "eig_residual", "kappa2_agreement", "kappa2_accuracy", "eta_bound", "finite_gain", "feasible", "finite_noise",
    "gain_vs_riccati", "internal_model", "noise_rejection", "commutant_residual", "S_condition",
    # robust designs (several models)
    "region_margin", "gain_bound", "kappa2_bound", "h2_bound", "hinf_bound", "mask", "lmi_P_min_eig",
    "lmi_region", "lmi_h2_bound", "lmi_hinf_bound", "dense_region", "farkas_radius", "found",
})

#: relative residual of the filter Riccati equation accepted (the residual is scale-free);
#: estimated relative forward error of P accepted; the pole tolerance is never raised above
#: POLE_FLOOR_CAP, however ill-conditioned the poles.  One value each for the engines' own checks and
#: this module: defined in :mod:`optdesign.engines.tolerances` (an engine cannot import design/).
RESIDUAL_TOL = RICCATI_RESIDUAL_TOL
#: the safety factor on first-order error estimates (they are estimates, not bounds)
ESTIMATE_FACTOR = 4.0
#: relative eigen-residual ``||X Z - Z Lambda||_F / (||X||_F ||Z||_F)`` required of a solver's eigenbasis
EIG_RESIDUAL_TOL = 1e-8
#: relative distance outside a pole region accepted (raised to the rounding floor of the poles); the
#: region engine accepts its candidates with the same number
#: (:data:`~optdesign.engines.tolerances.MARGIN_RTOL`, defined there: an engine cannot import design/)
REGION_TOL = MARGIN_RTOL
#: relative excess over a gain or eta bound accepted (the metric is recomputed with numpy)
BOUND_RTOL = 1e-6
#: the floor and the cap of :func:`kappa2_agreement_tol`
KAPPA2_TOL = 1e-6
KAPPA2_TOL_MAX = 1e-2
#: ``||X||_F / gap`` assumed by :func:`kappa2_agreement_tol` when the matrix is not at hand
_DEFAULT_SPREAD = 100.0


def relative_difference(x: NDArray, y: NDArray) -> float:
    """``||x - y|| / max(1, ||y||)`` (0 for equal arrays)."""
    d = float(np.linalg.norm(np.asarray(x) - np.asarray(y)))
    return 0.0 if d == 0 else d / max(1.0, float(np.linalg.norm(y)))


def pole_check(F: NDArray, target: NDArray, tol: float, *, name: str = "pole_error",
               what: str = "eig(A - L C) (numpy)", lazy: bool = False) -> tuple[Check, NDArray]:
    """The ``pole_error`` check of the error dynamics F against ``target``; returns the check and
    the sorted poles.  ``lazy``: the rounding floor of the poles (an eigenvector computation, which
    only ever raises the tolerance) only when the error exceeds ``tol`` -- the same verdict."""
    poles = np.linalg.eigvals(F)
    poles = poles[np.lexsort((poles.imag, poles.real))]
    err = pole_error(poles, target)
    ptol = float(tol) if (lazy and err <= tol) else pole_tolerance(F, tol)
    detail = f"max relative distance of {what} to the targets"
    if ptol > tol:
        detail += f"; tolerance raised from {tol:.1e} to the eigenvalue rounding floor of A - L C"
    return Check.at_most(name, err, ptol, detail), poles


def resolve_pole_tolerance(F: NDArray, dLC: NDArray, own_error: float, tol: float) -> float:
    """The pole tolerance of a second gain that agrees with a verified one to its error estimates:
    ``max(tol, own_error + ESTIMATE_FACTOR max_i |d_i| / max(1, |lambda_i|))``.

    ``F`` (n, n) is ``A - L C`` of the verified gain, whose poles miss the targets by ``own_error``;
    ``dLC`` (n, n) is ``(L_other - L) C``.  To first order the other gain moves pole i by
    ``d_i = -(V^-1 dLC V)_ii`` (V the eigenvector matrix of F), so its poles miss the targets by
    about ``own_error`` plus that.  A gain difference that is small but far above rounding (an
    independent Riccati re-solve agrees with L to its forward error, 1e-9 to 1e-6, not to eps)
    moves ill-conditioned poles by more than their rounding floor.  Where the first-order estimate
    does not hold -- F (numerically) defective, or a movement beyond a tenth of the pole's distance to
    the nearest other pole -- ``tol``."""
    V, w = eigenvector_matrix(F, return_eigenvalues=True)
    if not np.all(np.isfinite(V)):
        return tol
    try:
        d = np.diag(np.linalg.solve(V, dLC @ V))
    except np.linalg.LinAlgError:
        return tol
    gap = np.abs(w[:, None] - w[None, :]) + np.diag(np.full(w.size, np.inf))
    if not (np.all(np.isfinite(d)) and np.all(np.abs(d) <= 0.1 * np.min(gap, axis=1))):
        return tol
    move = float(np.max(np.abs(d) / np.maximum(1.0, np.abs(w))))
    return max(tol, own_error + ESTIMATE_FACTOR * move)


def resolve_poles_check(A: NDArray, C: NDArray, L: NDArray, L_other: NDArray, other_poles: NDArray,
                        target: NDArray, own: Check, gain_passed: bool, tol: float, detail: str, *,
                        floor_known: bool = True) -> Check:
    """``are_resolve_poles``: the poles ``other_poles`` of a second gain ``L_other`` (an independent
    Riccati re-solve, or a Newton step from the design's P) against the targets.

    The tolerance is the design's own (``own``, its ``pole_error`` check) when ``gain_passed`` (the
    gains agree to their error estimates), else the rounding floor of the other gain's poles; when
    that gain passed, the design's poles passed and the other poles still miss, it is raised by
    :func:`resolve_pole_tolerance` (the first-order movement by the measured gain difference) --
    after the rounding floor of the design's poles, when ``own`` was decided without it
    (``floor_known`` False)."""
    err = pole_error(other_poles, target)
    ptol = own.tolerance if gain_passed else pole_tolerance(A - L_other @ C, tol)
    if gain_passed and err > ptol and own.passed:
        F = A - L @ C
        if not floor_known:
            ptol = max(ptol, pole_tolerance(F, tol))
        if err > ptol:
            ptol = resolve_pole_tolerance(F, (L_other - L) @ C, own.value, ptol)
            detail += ("; tolerance: the design's pole error plus the first-order movement of its poles "
                       "by the other gain's difference from L")
    return Check.at_most("are_resolve_poles", err, ptol, detail)


def henrici_bound(F: NDArray) -> float:
    """How far rounding can move any eigenvalue of F, without assuming F diagonalizable.

    Henrici's theorem (Golub & Van Loan, *Matrix Computations*, 4th ed., thm. 7.2.3): with the
    Schur form ``F = Q (D + N) Q^H`` (N strictly upper triangular) and a perturbation of norm
    ``delta``, every eigenvalue moves by at most ``max(theta, theta^(1/n))``, ``theta = delta
    sum_{k<n} ||N||_2^k``.  ``delta = 10 n eps ||F||_F`` (the backward error of the eigenvalue
    solve).  Finite for a defective F (a Jordan block of size k: ~ delta^(1/k)), where the
    first-order floor of :func:`~optdesign.analysis.metrics.eigenvalue_rounding_floor` is infinite.
    """
    import scipy.linalg

    F = np.asarray(F, dtype=float)
    n = F.shape[0]
    if n == 0:
        return 0.0
    T, _ = scipy.linalg.schur(F, output="complex")
    nn = float(np.linalg.norm(np.triu(T, 1), 2))
    delta = 10.0 * n * _EPS * float(np.linalg.norm(F))
    theta = delta * float(sum(nn ** k for k in range(n)))
    return max(theta, theta ** (1.0 / n)) if np.isfinite(theta) else float("inf")


def stability_check(F: NDArray, discrete: bool) -> Check:
    """``stability_margin``: the poles of F must be stable by more than their rounding level: the
    first-order level (eigenvalue condition numbers) or, where it is larger (a nearly defective F,
    e.g. a deadbeat filter's Jordan block at 0), :func:`henrici_bound`."""
    poles = np.linalg.eigvals(F)
    floor = eigenvalue_rounding_floor(F)
    level = (floor if np.isfinite(floor) else 1.0) * max(1.0, float(np.linalg.norm(F, 2)))
    level = min(level, henrici_bound(F))
    if discrete:
        return Check.at_least("stability_margin", 1.0 - float(np.max(np.abs(poles))), level,
                              "1 - max |eig(A - L C)| must exceed the rounding level of the poles")
    return Check.at_least("stability_margin", -float(np.max(poles.real)), level,
                          "-max Re eig(A - L C) must exceed the rounding level of the poles")


def psd_tolerance(X: NDArray, error: float = 0.0) -> float:
    """The (negative) relative bound on ``lambda_min(X) / ||X||`` of a PSD matrix known to a
    relative accuracy ``error``: ``-(error + 10 n eps)``."""
    n = max(1, np.asarray(X).shape[0])
    return -(float(error) + 10.0 * n * _EPS)


def psd_check(name: str, X: NDArray, *, error: float = 0.0, what: str = "",
              eigenvalues: NDArray | None = None) -> Check:
    """``lambda_min(X) / ||X||_2 >= -(error + 10 n eps)`` (0 for ``X = 0``).  ``eigenvalues``: those
    of the symmetric X, ascending, when already at hand (then ``||X||_2 = max |lambda|``)."""
    if eigenvalues is None:
        X = 0.5 * (np.asarray(X, dtype=float) + np.asarray(X, dtype=float).T)
        nx = float(np.linalg.norm(X, 2)) if X.size else 0.0
        lam_min = float(np.linalg.eigvalsh(X)[0]) if X.size else 0.0
    else:
        nx = float(np.max(np.abs(eigenvalues))) if eigenvalues.size else 0.0
        lam_min = float(eigenvalues[0]) if eigenvalues.size else 0.0
    value = lam_min / nx if nx > 0 else 0.0
    label = what or name.replace("_min_eig", "")
    return Check.at_least(name, value, psd_tolerance(X, error),
                          f"smallest eigenvalue of {label} / ||{label}|| (it must be PSD)")


#: the Riccati solvers of :func:`independent_are` (methods of :func:`~optdesign.classical.riccati.filter_are`)
ARE_SOLVERS = ("scipy", "hamiltonian")
#: ``avoid=`` of :func:`riccati_checks`: a solver that produced the design, or ``"none"`` (no Riccati
#: solver did: an SDP point with L and P from a Lyapunov solve) for the lean re-solve
AVOID_CHOICES = ARE_SOLVERS + ("none",)


def independent_are(plant: Plant, *, avoid: str = "scipy") -> AREResult:
    """The Riccati solve used to verify a design, by a solver other than the one that produced it.

    Parameters
    ----------
    plant : Plant
        With the Q and R of the design under test.
    avoid : {"scipy", "hamiltonian"}
        The :func:`~optdesign.classical.riccati.filter_are` method that produced the design's L and P
        (default ``"scipy"``: the NLP and spectral routes take L and P from scipy's QZ solver); the
        re-solve uses the other one -- the Hamiltonian Schur method, or scipy's solver (about half
        the CPU time: no eigenvalue condition estimate), for designs that come from no Riccati
        solver at all (an SDP point, a Lyapunov solve) -- and the avoided one only if that fails.
        No residual test here: an inaccurate re-solve shows up as a measured difference.

    Returns
    -------
    AREResult

    Raises
    ------
    ValidationError
        ``avoid`` is not one of :data:`ARE_SOLVERS`.
    RiccatiError, OptDesignError
        Both solvers failed (the second one's error).
    """
    as_str("avoid", avoid, ARE_SOLVERS)
    first, second = ("hamiltonian", "scipy") if avoid == "scipy" else ("scipy", "hamiltonian")
    try:
        return filter_are(plant, first, residual_tol=np.inf)
    except (RiccatiError, OptDesignError):
        return filter_are(plant, second, residual_tol=np.inf)


def _gain_tolerance(plant: Plant, L: NDArray, P: NDArray, err_p: float, err_are: float, *,
                    norm_P: float | None = None) -> float:
    """How far two gains of (nearly) the same Riccati solution may differ: the gain is linear in P
    (``P C' R^-1``; discrete ``A P C' S^-1``, ``S = C P C' + R``), so by ``(err_p + err_are + the
    rounding of the gain formula, 10 n eps cond(R or S)) ||P|| ||dL/dP||``, relative to
    ``max(1, ||L||)``; capped at :data:`FORWARD_ERROR_TOL`.  ``norm_P``: ``||P||_2`` when at hand."""
    C, R = plant.C, plant.R
    assert R is not None, "called after an independent filter_are of this plant, which needs its R"
    n = plant.n
    if plant.is_discrete:
        S = C @ P @ C.T + R
        Si = np.linalg.inv(S)
        sens = float(np.linalg.norm(plant.A, 2)) * _norm2(C.T @ Si) * \
            (1.0 + _norm2(C @ P @ C.T) * _norm2(Si))
        cond = float(np.linalg.cond(S)) if S.shape[0] > 1 else 1.0
    else:
        sens = _norm2(C.T @ np.linalg.inv(R))
        cond = float(np.linalg.cond(R)) if R.shape[0] > 1 else 1.0
    rel = err_p + err_are + 10.0 * n * _EPS * cond
    nP = float(np.linalg.norm(P, 2)) if norm_P is None else float(norm_P)
    tol = ESTIMATE_FACTOR * rel * nP * sens / max(1.0, float(np.linalg.norm(L)))
    return min(tol + 10.0 * n * _EPS, FORWARD_ERROR_TOL)


def _norm2(X: NDArray) -> float:
    """The 2-norm of a matrix (the Euclidean norm for a single row or column: no SVD)."""
    return float(np.linalg.norm(X)) if min(X.shape) == 1 else float(np.linalg.norm(X, 2))


def forward_error_check(err: AREErrorEstimate) -> Check:
    """``forward_error``: the a posteriori relative error estimate of P is at most 1e-6."""
    value = err.relative if np.isfinite(err.relative) else float("inf")
    return Check.at_most("forward_error", value, FORWARD_ERROR_TOL,
                         "estimated relative error of P (Newton correction of its residual + its response "
                         "to rounding)")


def riccati_checks(plant: Plant, L: NDArray, P: NDArray, Q: NDArray, *, what: str = "the returned Q",
                   resolve: bool = True, avoid: str = "scipy",
                   ) -> tuple[list[Check], AREResult | None, AREErrorEstimate]:
    """The checks that ``(L, P, Q)`` is a steady-state Kalman filter of ``plant`` (with its R):
    ``riccati_residual``, ``forward_error``, ``Q_min_eig``, ``P_min_eig`` and (``resolve``)
    ``are_resolve_gain`` -- an independent Riccati solve with Q (:func:`independent_are`, not by the
    solver ``avoid`` that produced L and P) must return L.

    ``avoid="none"`` (one of :data:`AVOID_CHOICES`): L and P come from no Riccati solver; in
    continuous time the re-solve is then the lean one of :func:`lean_riccati_checks` (the same checks
    and tolerances on the validated arrays), and when that does not pass, the full one
    (:func:`independent_are` with scipy's solver) decides.

    Returns ``(checks, are, error)``: ``are`` is the independent solve (None when it failed or was
    not asked for), ``error`` the forward error estimate of P.
    """
    as_str("avoid", avoid, AVOID_CHOICES)  # before any work: a bad argument is not a failed check
    if avoid == "none" and resolve and not plant.is_discrete and plant.R is not None:
        lean = lean_riccati_checks(plant, L, P, Q, what=what)
        if lean is not None:
            return lean
    avoid = "hamiltonian" if avoid == "none" else avoid
    Qs = 0.5 * (Q + Q.T)
    err = filter_are_error(plant, P, Qs=Qs)
    err_rel = err.relative if np.isfinite(err.relative) else float("inf")
    checks = _kalman_checks(filter_are_residual(plant, P, Qs=Qs), err, Qs, P, what)
    if not resolve:
        return checks, None, err
    resolved = plant.replace(G=None, Q=_psd_part(Qs))  # one plant for the solve and its error
    try:
        are = independent_are(resolved, avoid=avoid)
    except (RiccatiError, OptDesignError, np.linalg.LinAlgError) as exc:
        checks.append(Check.at_most("are_resolve_gain", float("inf"), 0.0, f"filter_are failed: {exc}"))
        return checks, None, err
    err_are = filter_are_error(resolved, are.P).relative
    gtol = _gain_tolerance(plant, L, P, err_rel, err_are if np.isfinite(err_are) else 1.0)
    checks.append(_gain_check(are.L, L, gtol, what))
    return checks, are, err


def _kalman_checks(residual: float, err: AREErrorEstimate, Qs: NDArray, P: NDArray, what: str, *,
                   q_eigenvalues: NDArray | None = None, p_eigenvalues: NDArray | None = None) -> list[Check]:
    """``riccati_residual``, ``forward_error``, ``Q_min_eig``, ``P_min_eig`` of :func:`riccati_checks`
    (the eigenvalues of the symmetric Qs and P, ascending, when already at hand)."""
    err_rel = err.relative if np.isfinite(err.relative) else float("inf")
    return [
        Check.at_most("riccati_residual", residual, RESIDUAL_TOL,
                      f"relative residual of the filter ARE for the returned P with {what}"),
        forward_error_check(err),
        psd_check("Q_min_eig", Qs, what="Q", eigenvalues=q_eigenvalues),
        psd_check("P_min_eig", P, error=min(err_rel, 1.0), what="P", eigenvalues=p_eigenvalues),
    ]


def _gain_check(La: NDArray, L: NDArray, gtol: float, what: str) -> Check:
    return Check.at_most("are_resolve_gain", relative_difference(La, L), gtol,
                         f"||L_are - L|| / max(1, ||L||), L_are from an independent filter_are with "
                         f"{what}; tolerance from the error estimates of both P")


def lean_riccati_checks(plant: Plant, L: NDArray, P: NDArray, Q: NDArray, *, what: str = "the returned Q",
                        ) -> tuple[list[Check], AREResult, AREErrorEstimate] | None:
    """:func:`riccati_checks` of a continuous design that comes from no Riccati solver, at the cost
    of its linear algebra: the same checks, values and tolerances, on the plant's validated arrays
    (no Plant rebuilt, no re-validation); the residual and its terms computed once for the residual
    check and the forward error estimate, one real Schur form of each closed loop for the Lyapunov
    solves of its estimate (the design's P and the re-solve's P each have their own); one symmetric
    eigendecomposition of Q for its PSD check and the PSD part handed to the re-solve; the
    re-solve is the ordered Schur form of the Hamiltonian (``hamiltonian_are(trusted=True)``).

    Returns None -- the caller then runs the full checks -- when that re-solve fails, is not
    stabilizing, or its gain check does not pass (nothing is lost: a lean verdict is only ever a
    pass of the gain check; a failure is decided by the full re-solve).
    """
    A, C = plant.A, plant.C
    R = np.asarray(plant.R, dtype=float)
    Qs = 0.5 * (Q + Q.T)
    res, terms = filter_are_terms(A, C, R, Qs, P, False)
    err = are_error_of_terms(A, C, R, P, res, terms, False)
    err_rel = err.relative if np.isfinite(err.relative) else float("inf")
    eig_q = np.linalg.eigh(Qs)
    checks = _kalman_checks(relative_residual(res, terms), err, Qs, P, what, q_eigenvalues=eig_q[0],
                            p_eigenvalues=np.linalg.eigvalsh(0.5 * (P + P.T)))
    Qp = _psd_part(Qs, eig=eig_q)
    try:
        with np.errstate(all="ignore"):
            Pa = hamiltonian_are(A.T, C.T, Qp, R, trusted=True)
            Pa = 0.5 * (Pa + Pa.T)
            La = np.linalg.solve(R, C @ Pa).T
    except (RiccatiError, np.linalg.LinAlgError, ValueError):
        return None
    if not np.all(np.isfinite(La)):
        return None
    poles = sort_poles(np.linalg.eigvals(A - La @ C))
    if not float(np.max(poles.real)) < 0.0:
        return None
    res_a, terms_a = filter_are_terms(A, C, R, Qp, Pa, False)
    err_are = are_error_of_terms(A, C, R, Pa, res_a, terms_a, False).relative
    gtol = _gain_tolerance(plant, L, P, err_rel, err_are if np.isfinite(err_are) else 1.0)
    gain = _gain_check(La, L, gtol, what)
    if not gain.passed:
        return None
    are = AREResult(P=Pa, L=La, poles=poles, residual=relative_residual(res_a, terms_a), method="hamiltonian")
    return [*checks, gain], are, err


def newton_kalman_checks(plant: Plant, L: NDArray, P: NDArray, Q: NDArray, target: NDArray, tol: float, *,
                         what: str = "the returned Q") -> tuple[list[Check], NDArray] | None:
    """All the checks of a Kalman design with target poles that comes from no Riccati solver, at
    the cost of its linear algebra (in continuous time one real Schur form): a pass, or None (the
    caller then runs the full checks, which decide and report every failure).

    The checks and their tolerance rules are those of :func:`pole_check` and :func:`riccati_checks`,
    with two differences that make them cheap and keep them independent of the solver:

    * the rounding floor of the poles (an eigenvector computation, which only ever raises the
      ``pole_error`` tolerance) is computed only when the error exceeds ``tol``;
    * the Riccati re-solve is one Newton (Kleinman; discrete: Hewer) step of the equation with Q
      from P, ``P1 = P + E`` with E the Newton correction that the forward error estimate computes
      anyway (the Lyapunov / Stein operator of the closed loop of P's own gain; in continuous time
      on the verification's own Schur form): the stabilizing solution to second order in the error
      of P, since P's closed loop is stable (its poles are the targets) -- a Riccati solution whose
      closed loop is stable is the stabilizing one.  ``are_resolve_gain`` compares the gain of P1
      with L (tolerance: the gain check's rule, with the forward error of P for both solutions) and
      ``are_resolve_poles`` its poles with the targets (:func:`resolve_poles_check`).

    Parameters
    ----------
    plant : Plant
        With R (continuous, or discrete: the predictor form, ``L = A P C' (C P C' + R)^-1``).
    L : (n, p) ndarray
    P, Q : (n, n) ndarray
    target : (n,) ndarray of complex
    tol : float
        Pole accuracy required.

    Returns
    -------
    (checks, poles) or None
        ``pole_error``, ``riccati_residual``, ``forward_error``, ``Q_min_eig``, ``P_min_eig``,
        ``are_resolve_gain``, ``are_resolve_poles`` -- every one passed -- and the poles of
        ``A - L C`` sorted as :func:`pole_check` sorts them; None for a plant without R, or when
        any check does not pass.
    """
    if plant.R is None:
        return None
    A, C, disc = plant.A, plant.C, plant.is_discrete
    R = np.asarray(plant.R, dtype=float)
    pcheck, poles = pole_check(A - L @ C, target, tol, lazy=True)
    if not pcheck.passed:
        return None
    Qs = 0.5 * (Q + Q.T)
    res, terms = filter_are_terms(A, C, R, Qs, P, disc)
    est, E = are_correction_of_terms(A, C, R, P, res, terms, disc)
    if E is None or not np.isfinite(est.relative):
        return None
    eig_p = np.linalg.eigvalsh(0.5 * (P + P.T))
    checks = [pcheck,
              *_kalman_checks(relative_residual(res, terms), est, Qs, P, what,
                              q_eigenvalues=np.linalg.eigvalsh(Qs), p_eigenvalues=eig_p)]
    with np.errstate(all="ignore"):
        P1 = P + 0.5 * (E + E.T)
        L1 = filter_gain(A, C, R, P1, disc)
    if not np.all(np.isfinite(L1)):
        return None
    gtol = _gain_tolerance(plant, L, P, est.relative, est.relative, norm_P=float(np.max(np.abs(eig_p))))
    checks.append(Check.at_most(
        "are_resolve_gain", relative_difference(L1, L), gtol,
        f"||L_are - L|| / max(1, ||L||), L_are the gain of one Newton step of the Riccati equation with "
        f"{what} from P (the stabilizing solution to second order in P's error); tolerance from the "
        f"error estimate of P"))
    checks.append(resolve_poles_check(A, C, L, L1, np.linalg.eigvals(A - L1 @ C), target, checks[0],
                                      checks[-1].passed, tol, "poles of that Newton step's gain vs the "
                                      "targets", floor_known=pcheck.tolerance > tol))
    if not all(c.passed for c in checks):
        return None
    return checks, poles


def check_violation(check: Check, tolerance: float | None = None) -> float:
    """How far a check is from passing, relative to its tolerance: 0 when it passes, else
    ``|value - tolerance| / |tolerance|`` (inf for a NaN value or a zero tolerance).

    Ranks designs that all fail their checks (the smallest largest violation first); ``tolerance``
    replaces the check's own (e.g. an uncapped rounding floor).
    """
    tol = check.tolerance if tolerance is None else float(tolerance)
    v = check.value
    ok = v <= tol if check.sense == "<=" else v >= tol
    if ok and not np.isnan(v):
        return 0.0
    if np.isnan(v) or tol == 0.0:
        return float("inf")
    return float(abs(v - tol) / abs(tol))


def cross_check(P: NDArray, P_other: NDArray, err: float, err_other: float, *, other: str) -> Check:
    """``cross_check``: two Riccati solutions agree to what their own error estimates explain."""
    num = float(np.linalg.norm(P - P_other))
    den = max(float(np.linalg.norm(P)), float(np.linalg.norm(P_other)))
    diff = 0.0 if num == 0.0 else (num / den if den > 0 else float("inf"))
    n = P.shape[0]
    tol = ESTIMATE_FACTOR * (err + err_other) + 10.0 * n * _EPS
    return Check.at_most("cross_check", diff, tol,
                         f"||P - P_{other}||_F / max(||P||_F, ||P_{other}||_F); tolerance 4 x the sum of "
                         f"the two error estimates")


# --------------------------------------------------------------------------- observer designs


def eigen_spread(X: NDArray, poles: NDArray) -> float:
    """``||X||_F / gap``, ``gap`` the smallest distance between two of ``poles`` (inf when two
    coincide; 1 for a single pole): how strongly rounding moves the eigenvectors of ``X``."""
    P = np.asarray(poles, dtype=complex).ravel()
    if P.size < 2:
        return 1.0
    d = np.abs(P[:, None] - P[None, :])
    gap = float(np.min(d[~np.eye(P.size, dtype=bool)]))
    nx = float(np.linalg.norm(X))
    return nx / gap if gap > 0 else float("inf")


def kappa2_agreement_tol(kappa2: float, spread: float | None = None) -> float:
    """Relative tolerance of ``|cond(Z) - kappa2| / kappa2`` between two unit-column eigenbases.

    Two exact unit-column eigenbases of a matrix with distinct eigenvalues differ by column phases
    only, so their condition numbers are equal; computed ones differ per column by about
    ``eps ||X||_F / gap`` (first-order perturbation of an eigenvector), which kappa2 amplifies in the
    condition number.  The tolerance is ``KAPPA2_TOL + 10 eps kappa2 spread`` with
    ``spread = ||X||_F / gap`` (:func:`eigen_spread`; 100 when not given: the tolerance of a kappa2
    computed without its matrix at hand, e.g. a bound), never more than ``KAPPA2_TOL_MAX`` (1 %).
    """
    s = _DEFAULT_SPREAD if spread is None else float(spread)
    if not s == s:  # nan: no information, the cap
        return KAPPA2_TOL_MAX
    return float(min(KAPPA2_TOL_MAX, KAPPA2_TOL + 10.0 * _EPS * float(kappa2) * s))


def observer_stability_check(poles: NDArray, discrete: bool, floor: float) -> Check:
    """``stability``: max Re below ``-floor max(1, max |pole|)``, or spectral radius below
    ``1 - floor`` (``floor``: the relative rounding floor of the poles,
    :func:`~optdesign.analysis.metrics.eigenvalue_rounding_floor`)."""
    P = np.asarray(poles, dtype=complex)
    if discrete:
        rho = float(np.max(np.abs(P))) if P.size else 0.0
        return Check.at_most("stability", rho, 1.0 - floor,
                             "spectral radius of A - LC < 1 beyond rounding (discrete time)")
    mr = float(np.max(P.real)) if P.size else -1.0
    tol = -floor * max(1.0, float(np.max(np.abs(P)))) if P.size else 0.0
    return Check.at_most("stability", mr, tol, "max Re eig(A - LC) < 0 beyond rounding (continuous time)")


def region_margin_check(region, poles: NDArray, floor: float) -> Check:
    """``region_margin``: the poles inside ``region`` to ``max(REGION_TOL, floor) max(1, max |pole|)``."""
    P = np.asarray(poles, dtype=complex)
    scale = max(1.0, float(np.max(np.abs(P)))) if P.size else 1.0
    return Check.at_most("region_margin", float(region.margin(P)), max(REGION_TOL, floor) * scale,
                         "max signed distance of eig(A - LC) to the region (<= 0 inside; tolerance "
                         "REGION_TOL or the rounding floor of the poles, relative)")


def eig_residual_check(X: NDArray, Z: NDArray, zpoles: NDArray) -> Check:
    """``eig_residual``: ``Z`` (columns) is an eigenbasis of ``X`` for ``zpoles``."""
    res = float(np.linalg.norm(X @ Z - Z * np.asarray(zpoles)[None, :])) / max(
        float(np.linalg.norm(X)) * float(np.linalg.norm(Z)), 1e-300)
    return Check.at_most("eig_residual", res, EIG_RESIDUAL_TOL,
                         "||(A - LC) Z - Z diag(poles)||_F / (||A - LC||_F ||Z||_F) for the solver's basis")


def kappa2_agreement_check(kappa_solver: float, kappa_numpy: float, spread: float) -> Check:
    """``kappa2_agreement``: the condition number of the solver's basis against ``metrics.kappa2``."""
    return Check.at_most("kappa2_agreement", abs(kappa_solver - kappa_numpy) / kappa_numpy,
                         kappa2_agreement_tol(kappa_numpy, spread),
                         "cond(solver basis) vs metrics.kappa2 (numpy eigenvectors), relative; tolerance "
                         "1e-6 + 10 eps kappa2 ||A - LC||_F / gap")


def bound_check(name: str, value: float, bound: float, rtol: float, what: str) -> Check:
    """``value <= bound (1 + rtol)`` (``gain_bound``, ``kappa2_bound``, ``eta_bound``)."""
    return Check.at_most(name, value, bound * (1.0 + rtol), what)


def _psd_part(X: NDArray, eig: tuple[NDArray, NDArray] | None = None) -> NDArray:
    """The PSD part of the symmetric part of X (``eig``: its eigendecomposition, when at hand)."""
    lam, U = np.linalg.eigh(0.5 * (X + X.T)) if eig is None else eig
    Y = (U * np.maximum(lam, 0.0)) @ U.T
    return 0.5 * (Y + Y.T)
