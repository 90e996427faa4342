"""The public verb :func:`is_kalman_optimal`: is a gain the Kalman gain of some Q >= 0?"""


from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..._deadline import Deadline, dense_time_refusal
from ..._validate import as_frequencies, as_matrix, as_positive_float, renamed
from ...analysis.robustness import circle_condition, resolve_R
from ...backends.report import one_warning_per_call
from ...classical.riccati import format_pole as _fmt
from ...engines.polish import min_norm_lstsq
from ...errors import ValidationError
from ...model.coerce import as_plant
from ...model.plant import Plant
from ...results import Check, SolverStats, Status, Verification
from ..verification import riccati_checks
from .common import EPS, make_stats, project_psd, quiet, stable_poles, sym
from .results import InfeasibilityCertificate, KalmanOptimalityResult
from .route import optimality_route
from .sdp_stage import feasibility_margin, polished_point, sdp_fixed_gain, whitening


@one_warning_per_call
def is_kalman_optimal(
    plant: Plant | Any,
    L: ArrayLike,
    *args: Any,
    R: ArrayLike | None = None,
    omega: ArrayLike | None = None,
    sdp_solver: Literal["CLARABEL", "SCS"] | None = None,
    tol: float = 1e-8,
    time_limit: float | None = None,
    solver: str | None = None,
) -> KalmanOptimalityResult:
    r"""Is L the steady-state Kalman gain of the plant for some process noise ``Q >= 0``?

    For a fixed L the admissible ``(P, Q)`` satisfy linear relations (continuous
    ``P C' = L R``, ``Q = L R L' - A P - P A'``; discrete ``(A - L C) P C' = L R``,
    ``Q = P - (A - LC) P (A - LC)' - L R L'``), so the question is an SDP: maximize the
    smallest eigenvalue ``t`` of Q over that family (``A - L C`` must be stable).  ``t >= 0``:
    optimal, and the maximizing Q (polished) is returned as the certificate.  ``t < 0``: not
    optimal, and the return-difference inequality -- continuous ``T R T^* >= R``, discrete
    ``T V T^* >= R`` with ``T = I + C (sI - A)^-1 L`` (equivalent by the KYP lemma) -- is scanned by
    :func:`optdesign.analysis.robustness.circle_condition` for the frequency where it fails and
    by how much.

    A gain of a rank-deficient Q lies on the boundary (``t = 0``), where the SDP is least
    accurate (``t`` ~ -1e-6 ||Q|| is typical).  Before any verdict a slightly negative ``t`` is
    re-examined: the margin SDP's point and then the min-trace SDP's point are polished onto
    their face of the PSD cone (as :func:`kalman_for_poles` does); a polished Q that passes
    every check is the certificate.  If none does, the answer is "not optimal" only with
    sound evidence -- the frequency scan finds a violation, or an accurate SDP margin below
    ``-sqrt(tol) ||Q||`` -- and otherwise "inconclusive" (``NUMERICAL_ERROR``, never a false
    "infeasible").

    Parameters
    ----------
    plant : Plant, python-control StateSpace or scipy StateSpace / lti / dlti
        A (n, n), C (p, n), dt; R from the plant unless given.
    L : (n, p) array_like
    R : (p, p) array_like, optional
        Measurement-noise covariance, symmetric positive definite (keyword-only; a positional R
        is deprecated).
    omega : array_like, optional
        Seed frequency grid (rad/s) for the circle-condition scan.
    sdp_solver : {"CLARABEL", "SCS"} or None
        (Old spelling ``solver=``: deprecated.)
    tol : float
        Relative tolerance: optimal when ``t >= -tol * max(1, ||Q||)``.
    time_limit : float, optional
        Seconds of wall time, set-up included; when it runs out before a verdict the status is
        ``time_limit`` (never a false "not optimal").  A question whose uninterruptible dense
        set-up (the eigenvalues of ``A - L C``) alone is estimated to outlast it is not started
        (status ``time_limit`` at once, the estimate in ``message``).

    Returns
    -------
    KalmanOptimalityResult

    Raises
    ------
    ValidationError
        No R; plant not a Plant.
    DimensionError, NotFiniteError, NotPositiveDefiniteError
        Malformed L or R.

    References
    ----------
    Kalman, R. E., "When is a linear control system optimal?", J. Basic Eng. 86 (1964);
    Anderson & Moore, *Optimal Filtering* (1979); seed 002 eq (17).

    Examples
    --------
    >>> from optdesign import Plant, is_kalman_optimal
    >>> di = Plant([[0, 1], [0, 0]], [[1, 0]], R=[[1]])
    >>> bool(is_kalman_optimal(di, [[4], [3]])), bool(is_kalman_optimal(di, [[0.4], [9.04]]))
    (True, False)
    """
    if args:  # the former positional R (plant first, R keyword-only in every verb)
        if len(args) > 1 or R is not None:
            raise ValidationError("is_kalman_optimal takes (plant, L) positionally; give R= as a keyword")
        R = renamed("R", None, "a positional R", args[0], None, stacklevel=3)
    solver = renamed("sdp_solver", sdp_solver, "solver", solver, None, stacklevel=3)
    with quiet():
        res = decide_optimality(plant, L, R, omega, solver, tol, time_limit)
    return dataclasses.replace(res, route=optimality_route(res))


def gain_relation_checks(plant: Plant, L: NDArray, R: NDArray):
    """The algebraic necessary condition of optimality: ``C P C'`` (fixed by L: continuous
    ``C L R``; discrete ``C P C'`` from ``(A - L C) P C' = L R``) must be symmetric PSD.

    Returns ``(checks, what)``; the tolerances are the rounding level of the computation
    (``10 n eps`` times the size of what is formed, divided by the size of ``C P C'``; in discrete
    time ``P C'`` comes from a solve with ``A - L C`` and inherits its condition number) -- an
    asymmetry below it is rounding, not evidence (the regression case
    ``tests/data/is_kalman_optimal_false_no_discrete_n8_p2.npz``: 3.7e-9 against a fixed 1e-9
    called a true DARE gain "not optimal")."""
    A, C = plant.A, plant.C
    n = plant.n
    LR = L @ R
    if plant.is_discrete:
        Fc = A - L @ C
        PCt = min_norm_lstsq(Fc, LR)
        CPC = C @ PCt
        cond = float(np.linalg.cond(Fc))
        size = float(np.linalg.norm(C)) * (cond * float(np.linalg.norm(PCt)) + float(np.linalg.norm(L))
                                           * float(np.linalg.norm(R)))
        gap = float(np.linalg.norm(Fc @ PCt - LR)) / max(1e-300, float(np.linalg.norm(LR)))
        gap_tol = 10.0 * n * EPS * cond
    else:
        CPC = C @ LR
        size = float(np.linalg.norm(C)) * float(np.linalg.norm(L)) * float(np.linalg.norm(R))
        gap, gap_tol = 0.0, 1.0
    scale = max(1.0, float(np.linalg.norm(CPC)))
    tol = 10.0 * n * EPS * size / scale
    asym = float(np.linalg.norm(CPC - CPC.T)) / scale
    cmin = float(np.linalg.eigvalsh(sym(CPC))[0]) / scale
    what = "C L R" if not plant.is_discrete else "C P C' (from (A - LC) P C' = L R)"
    checks = [Check.at_most("gain_relation_asymmetry", asym, tol,
                            f"{what} symmetric (to its rounding level)"),
              Check.at_least("gain_relation_min_eig", cmin, -tol, f"{what} PSD (to its rounding level)")]
    if plant.is_discrete:
        checks.append(Check.at_most("gain_relation_residual", gap, gap_tol,
                                    "(A - LC) P C' = L R solvable (to the rounding level of the solve)"))
    return checks, what


def decide_optimality(plant, L, R, omega, solver, tol, time_limit) -> KalmanOptimalityResult:
    t0 = time.perf_counter()
    deadline = Deadline(time_limit)
    plant = as_plant(plant)
    L = as_matrix("L", L, (plant.n, plant.p))
    R = resolve_R(plant, R, "is_kalman_optimal")
    tol = as_positive_float("tol", tol)
    if omega is not None:
        omega = as_frequencies("omega", omega)
    ctx = OptimalityContext(plant, L, R, t0)
    # issue 26: the set-up counts -- the eigenvalues of A - L C (and for L = 0 the Hamiltonian Schur
    # form of the independent Riccati check) are single LAPACK calls that cannot be stopped
    calls = [("eigvals", plant.n)] + ([("hamiltonian_schur", plant.n)] if not np.any(L) else [])
    why = dense_time_refusal(calls, deadline, f"is_kalman_optimal at n = {plant.n}")
    if why:
        return ctx.inconclusive(Status.TIME_LIMIT, f"no verdict: {why}", float("nan"), None, [], None)
    poles = np.linalg.eigvals(plant.A - L @ plant.C)
    disc = plant.is_discrete
    if not np.all(stable_poles(poles, disc)):
        worst = poles[np.argmax(np.abs(poles))] if disc else poles[np.argmax(poles.real)]
        return ctx.no("unstable_target", f"A - L C is not stable (eigenvalue {_fmt(worst)}); a steady-state "
                                         f"Kalman filter always is",
                      checks=[Check.at_most("stability", float(abs(worst) - 1 if disc else worst.real), 0.0,
                                            "A - L C must be stable")])
    if not np.any(L):  # the filter of Q = 0 of a stable plant: P = 0 solves the Riccati equation exactly
        Z = np.zeros((plant.n, plant.n))
        ver = Verification.of(riccati_checks(plant.replace(R=R), L, Z, Z, what="Q = 0")[0])
        return ctx.yes(Z, Z, ver, margin=0.0, status=Status.SOLVED, circ=None,
                       msg="Kalman-optimal: L = 0 is the Kalman gain of Q = 0 (A is stable, P = 0 exactly)")
    circ = None
    try:  # the scan's share of the budget: the SDP stage needs the rest (issue 26: set-up counts)
        circ = circle_condition(plant, L, R=R, omega=omega,
                                time_limit=deadline.fraction(0.4) if deadline.limited else None)
    except np.linalg.LinAlgError:
        circ = None
    checks, _ = gain_relation_checks(plant, L, R)
    if not all(c.passed for c in checks):
        val = {c.name: c.value for c in checks}
        return ctx.no("gain_relation",
                      f"{checks[0].detail.split(' symmetric')[0]} must be symmetric positive semidefinite "
                      f"(it is "
                      f"C P C'); asymmetry {val['gain_relation_asymmetry']:.3g}, smallest eigenvalue "
                      f"{val['gain_relation_min_eig']:.3g} (beyond their rounding level "
                      f"{checks[0].tolerance:.2g})", circ=circ, checks=checks)
    return optimality_by_sdp(ctx, circ, solver, tol, deadline)


def _no_message(kind: str, reason: str, margin: float, circ) -> str:
    """``not Kalman-optimal: <kind>: <reason>`` with the worst frequency and the SDP margin added only
    where the reason does not already state them (one statement per fact)."""
    parts = [f"{kind}: {reason}"]
    if circ is not None and "rad/s" not in reason:
        parts.append(f"worst frequency {circ.omega_worst:.6g} rad/s, min eigenvalue {circ.min_eigenvalue:.4g}")
    if np.isfinite(margin) and "smallest eigenvalue" not in reason:
        parts.append(f"SDP margin {margin:.4g}")
    return "not Kalman-optimal: " + "; ".join(parts)


@dataclass
class OptimalityContext:
    """What the stages of :func:`is_kalman_optimal` share: the question and how to answer it."""

    plant: Plant
    L: NDArray
    R: NDArray
    t0: float

    def stats(self, rep=None) -> SolverStats:
        if rep is None:
            return make_stats("none", t=time.perf_counter() - self.t0)
        return make_stats(rep.stats.backend, rep.stats.native_status, time.perf_counter() - self.t0,
                      rep.stats.iterations)

    def no(self, kind, reason, status=Status.INFEASIBLE, margin=float("nan"), circ=None, checks=(),
           stats=None) -> KalmanOptimalityResult:
        nan = float("nan")
        cert = InfeasibilityCertificate(
            kind=kind, reason=reason, margin=None if not np.isfinite(margin) else margin,
            omega=None if circ is None else circ.omega_worst,
            min_eigenvalue=None if circ is None else circ.min_eigenvalue, circle=circ)
        return KalmanOptimalityResult(
            optimal=False, L=self.L, R=self.R, Q=None, P=None, margin=margin,
            min_eigenvalue=nan if circ is None else circ.min_eigenvalue,
            omega=nan if circ is None else circ.omega_worst, circle=circ, certificate=cert,
            status=status, message=_no_message(kind, reason, margin, circ), verification=Verification.of(checks),
            solver_stats=stats or self.stats())

    def yes(self, P, Q, ver, *, margin, status, circ, msg, rep=None) -> KalmanOptimalityResult:
        nan = float("nan")
        return KalmanOptimalityResult(
            optimal=True, L=self.L, R=self.R, Q=Q, P=P, margin=margin,
            min_eigenvalue=nan if circ is None else circ.min_eigenvalue,
            omega=nan if circ is None else circ.omega_worst, circle=circ, certificate=None,
            status=status, message=msg, verification=ver, solver_stats=self.stats(rep))

    def inconclusive(self, status, msg, margin, circ, checks, rep) -> KalmanOptimalityResult:
        nan = float("nan")
        return KalmanOptimalityResult(
            optimal=False, L=self.L, R=self.R, Q=None, P=None, margin=margin,
            min_eigenvalue=nan if circ is None else circ.min_eigenvalue,
            omega=nan if circ is None else circ.omega_worst, circle=circ, certificate=None,
            status=status, message=msg, verification=Verification.of(checks), solver_stats=self.stats(rep))


def certificate_search(ctx: OptimalityContext, t_star, P0, W0, rep, margin_ok, circle_fails, solver,
                        deadline, notes):
    """A verified Q for the gain: the margin SDP's point (polished), the min-trace SDP's point
    (polished), then -- for badly scaled families -- the same in whitened coordinates.  Returns
    ``(cert, rep)``: ``cert = (P, Q, verification)`` or None."""
    plant, L, R = ctx.plant, ctx.L, ctx.R
    cert = None
    if margin_ok:
        cert = optimality_certificate(plant, L, R, P0, W0, project=True)
        if cert is None:
            notes.append("the margin SDP's point fails the checks")
    if cert is not None or (circle_fails and not margin_ok):
        return cert, rep
    # a boundary gain (rank-deficient Q: margin 0) is where the margin SDP is least accurate:
    # polish its point onto its face of the PSD cone, then the min-trace SDP's point
    if P0 is not None and not margin_ok:
        cert = optimality_certificate(plant, L, R, P0, W0, project=False)
        if cert is not None:
            notes.append("the margin SDP's point polished onto its face of the PSD cone")
            return cert, rep
    if not deadline.expired:
        P1, W1, rep1, _ = sdp_fixed_gain(plant, L, R, "full", "min_trace", None, solver, deadline)
        if P1 is not None:
            cert = optimality_certificate(plant, L, R, P1, W1, project=False)
            if cert is not None:
                notes.append("certificate from the min-trace SDP, polished")
                return cert, rep1
        else:
            notes.append(f"the min-trace SDP failed ({rep1.message})")
    if not deadline.expired and whitening(plant, L, R) is not None:
        # badly scaled family (P over many decades): the same search whitened; only a verified
        # certificate is taken from it, never a verdict
        _, P2, W2, rep2 = feasibility_margin(plant, L, R, "full", solver, deadline, whiten=True)
        if P2 is not None:
            cert = optimality_certificate(plant, L, R, P2, W2, project=False, whiten=True)
            if cert is not None:
                notes.append("certificate from the margin SDP in whitened coordinates, polished")
                return cert, rep2
    return None, rep


def optimality_by_sdp(ctx: OptimalityContext, circ, solver, tol, deadline) -> KalmanOptimalityResult:
    """The SDP stage of :func:`is_kalman_optimal`: a verified Q, or a sound verdict, or "inconclusive"."""
    plant, L, R = ctx.plant, ctx.L, ctx.R
    disc = plant.is_discrete
    t_size = plant.n * (plant.n + 1) // 2
    setup_s = t_size * t_size / SDP_SETUP_RATE
    if deadline.expired or (deadline.limited and setup_s > deadline.remaining()):
        # the frequency scan used the budget, or the SDP's set-up alone (cvxpy's compilation and
        # Clarabel's KKT set-up, which no time limit interrupts) would run past it
        return early_verdict(ctx, circ, deadline, setup_s)
    t_star, P0, W0, rep = feasibility_margin(plant, L, R, "full", solver, deadline)
    qscale = max(1.0, float(np.linalg.norm(W0, 2))) if P0 is not None else 1.0
    margin_ok = P0 is not None and t_star >= -tol * qscale
    # a frequency violation is evidence only beyond its rounding floor (issue 26: -8e-5 against a
    # floor of ~1.5e-4 called scipy's CARE gain "infeasible")
    circle_fails = circ is not None and circ.violation_certain
    notes: list[str] = []
    cert, rep_c = certificate_search(ctx, t_star, P0, W0, rep, margin_ok, circle_fails, solver, deadline,
                                      notes)
    if cert is not None:
        P, Q, ver = cert
        q_min = float(np.linalg.eigvalsh(Q)[0])
        msg = f"Kalman-optimal: Q certificate with smallest eigenvalue {q_min:.4g}"
        if not margin_ok:
            msg += (f" (a boundary or badly scaled gain: the margin SDP reported {t_star:.4g}"
                    f"{'' if P0 is not None else ' / failed'}; the polished Q is exact)")
        if notes:
            msg += "; " + "; ".join(notes)
        if circ is not None:
            msg += f"; circle condition min eigenvalue {circ.min_eigenvalue:.3g}"
        accurate = margin_ok and rep_c is rep and rep.status.is_solved
        status = rep_c.status if accurate else Status.OPTIMAL_INACCURATE
        return ctx.yes(P, Q, ver, margin=t_star if margin_ok else q_min, status=status, circ=circ, msg=msg,
                       rep=rep_c)
    # no verified Q: a verdict only where the evidence is sound
    checks = []
    if P0 is not None:
        checks.append(Check.at_least("margin", t_star, -tol * qscale,
                                     "max over the Q family of lambda_min(Q) (must be >= 0)"))
    if circ is not None:
        checks.append(Check.at_least("circle_condition", circ.min_eigenvalue, -circ.tol,
                                     "min over frequency of lambda_min of the return-difference form"))
    ineq = "T V T* - R" if disc else "T R T* - R"
    circ_txt = (f"lambda_min({ineq}) = {circ.min_eigenvalue:.4g} at omega = {circ.omega_worst:.6g} rad/s"
                if circ is not None else "")
    # an accurate SDP with a clearly negative margin is trusted even if the frequency scan
    # (a grid and local refinement) missed the dip; an inaccurate or marginal one is not
    sdp_sound = (P0 is not None and rep.status == Status.OPTIMAL and t_star < -np.sqrt(tol) * qscale)
    if circle_fails or (circ is None and P0 is not None and not margin_ok) or sdp_sound:
        kind = "return_difference" if circle_fails else "sdp_margin"
        reason = ("no Q >= 0 makes L a Kalman gain: "
                  + (f"the best Q has smallest eigenvalue {t_star:.4g}" if P0 is not None else
                     f"the fixed-gain SDP failed ({rep.message})")
                  + (f"; {circ_txt}" if circ_txt else "")
                  + ("" if circle_fails or circ is None else
                     "; the frequency scan found no violation (a narrow dip between grid points "
                     "can be missed; the SDP margin is accurate)"))
        return ctx.no(kind, reason, margin=t_star if P0 is not None else float("nan"), circ=circ,
                      checks=checks, stats=ctx.stats(rep))
    if deadline.expired:
        return ctx.inconclusive(Status.TIME_LIMIT, f"time limit reached before a verdict ({deadline})",
                                t_star if P0 is not None else float("nan"), circ, checks, rep)
    what = (f"the margin SDP gave {t_star:.4g} ({rep.stats.native_status})" if P0 is not None else
            f"the fixed-gain SDP failed ({rep.message})")
    in_floor = circ is not None and circ.min_eigenvalue < -circ.tol
    holds = (f", while the return-difference inequality holds ({circ_txt})"
             if circ is not None and not in_floor
             else f"; the return-difference inequality fails only inside its rounding floor "
                  f"({circ_txt}, floor "
                  f"{circ.rounding_floor:.2g}: rounding, not evidence)" if in_floor else "")
    msg = (f"inconclusive: {what}, but no polished PSD Q reproduces L" + holds
           + ("; " + "; ".join(notes) if notes else ""))
    status = Status.NUMERICAL_ERROR if rep.status.is_solved or rep.status.is_infeasible else rep.status
    if in_floor:
        status = Status.NOT_FOUND
    return ctx.inconclusive(status, msg, t_star if P0 is not None else float("nan"), circ, checks, rep)


#: the fixed-gain SDP's set-up (cvxpy compilation + Clarabel's KKT set-up) is about ``t^2 /
#: SDP_SETUP_RATE`` seconds, ``t = n(n+1)/2`` (measured: 0.9 s at n = 60, t = 1830, on an idle core;
#: 2.2 s is assumed, for a loaded machine)
SDP_SETUP_RATE = 1.5e6


def early_verdict(ctx: OptimalityContext, circ, deadline: Deadline,
                  setup_s: float = 0.0) -> KalmanOptimalityResult:
    """The answer when the budget ran out before the SDP: a certain frequency violation is still a
    proof; anything else is ``time_limit``."""
    if circ is not None and circ.violation_certain:
        ineq = "T V T* - R" if ctx.plant.is_discrete else "T R T* - R"
        return ctx.no("return_difference",
                      f"no Q >= 0 makes L a Kalman gain: lambda_min({ineq}) = {circ.min_eigenvalue:.4g} at "
                      f"omega = {circ.omega_worst:.6g} rad/s (beyond its rounding floor "
                      f"{circ.rounding_floor:.2g})", circ=circ)
    return ctx.inconclusive(Status.TIME_LIMIT, f"time limit reached before a verdict ({deadline}): the "
                            f"frequency scan found no proof, and the margin SDP's set-up alone (about "
                            f"{setup_s:.2g} s) would run past the limit: not started", float("nan"), circ, [],
                            None)


def optimality_certificate(plant, L, R, P0, W0, *, project: bool, whiten: bool = False):
    """``(P, Q, verification)`` from an SDP point for the gain L, polished onto its face of the
    PSD cone (``project``: else the PSD projection of the unpolished point), when every check
    passes; None otherwise."""
    pol = polished_point(plant.replace(R=R), L, R, "full", P0, W0, whiten=whiten)
    if pol is not None:
        P, Q, _ = pol
    elif project:
        P, Q = P0, project_psd(W0)
    else:
        return None
    checks, _, _ = riccati_checks(plant.replace(R=R), L, P, Q, what="the certificate Q")
    ver = Verification.of(checks)
    return (P, Q, ver) if ver.passed else None

