r"""State feedback by duality: the observer engine serves controllers.

State feedback ``u = -K x`` places the eigenvalues of ``A - B K``; its transpose
``A' - K' B'`` is the error dynamics of an observer of the *dual* plant ``(A_d, C_d) = (A', B')``
with gain ``L = K'``.  The two have the same eigenvalues, so every observer question has a
controller answer at no cost:

* :func:`place` -- a drop-in for :func:`scipy.signal.place_poles` (same result fields:
  ``gain_matrix``, ``computed_poles``, ``requested_poles``, ``X``, ``rtol``, ``nb_iter``) that
  minimizes the condition number of the closed-loop eigenvectors instead of a surrogate;
* :func:`well_conditioned_feedback` -- every option of :func:`well_conditioned_observer`
  (fixed poles or a region, structural zeros of K, a gain bound, trade-off bounds);
* :func:`lqr_for_poles` -- the inverse LQR: which state weight ``Q >= 0`` (R given, optionally
  structured) makes the LQR closed loop have these poles -- the dual of seed 000's question, with
  the same certificates as :func:`kalman_for_poles`.  The LQR equation
  ``A' X + X A - X B R^-1 B' X + Q = 0``, ``K = R^-1 B' X`` is the filter equation of the dual
  plant (discrete: ``K = (R + B' X B)^-1 B' X A``, the dual predictor gain), so ``X = P`` and
  ``K = L'``.

What "kappa2" measures.  State feedback is measured by ``cond(X)`` of the unit-column *right*
eigenvectors ``X`` of ``A - B K`` (scipy's ``X``, MATLAB's ``place``, Kautsky-Nichols-Van Dooren,
Byers-Nash, Chu).  With fixed poles, or poles free in a region, and no bounds the placement engine
runs in controller mode and minimizes exactly that (:mod:`optdesign.design.feedback_controller`;
in a region from the usual starts and from the dual route's design, so never worse than it);
``kappa2`` and ``kappa2_right`` are then equal and ``extra["mode"]`` says ``controller``.  The
routes that design the observer of the dual pair (gain or trade-off bounds, structural zeros,
objective eta) minimize kappa2 of the unit-column eigenvectors of ``(A - B K)'``, i.e. of the
*left* eigenvectors of ``A - B K``; ``kappa2`` is then that, ``kappa2_right`` is ``cond(X)``
beside it, and the message and ``extra["mode"]`` say which measure was optimized.  The two are eigenvector
matrices of the same spectrum, within ``sqrt(n)`` of the optimally scaled condition number of each
other (van der Sluis), close but not equal.

References
----------
Kautsky, J., Nichols, N. K. & Van Dooren, P., "Robust pole assignment in linear state feedback",
Int. J. Control 41(5) (1985) 1129-1155.
Tits, A. L. & Yang, Y., "Globally convergent algorithms for robust pole assignment by state
feedback", IEEE TAC 41(10) (1996) 1432-1452 (scipy's ``"YT"``).
Priess, M. C., Conway, R., Choi, J., Popovich, J. M. & Radcliffe, C., "Solutions to the inverse
LQR problem with application to biological systems analysis", IEEE TCST 23(2) (2015) 770-777.
van der Sluis, A., "Condition numbers and equilibration of matrices", Numer. Math. 14 (1969).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._validate import as_int, as_matrix, as_poles, as_square, as_str, check_pd
from ..analysis import metrics
from ..backends.report import one_warning_per_call
from ..classical.placement import pole_error as classical_pole_error
from ..classical.riccati import sort_poles
from ..errors import NotControllableError, ValidationError
from ..model.coerce import as_system
from ..model.plant import Plant
from ..model.regions import Region
from ..results import Check, DesignResult, Route, Stage, Status, Verification
from .feedback_controller import ackermann_fields, controller_fields, input_rank, needs_ackermann
from .inverse_kalman import kalman_for_poles
from .verification import pole_check, stability_check
from .well_conditioned import well_conditioned_observer

__all__ = [
    "dual_plant",
    "FeedbackDesign",
    "well_conditioned_feedback",
    "PlacementResult",
    "place",
    "InverseLQRResult",
    "lqr_for_poles",
    "LQR_STRUCTURES",
]

#: state-weight structures of :func:`lqr_for_poles` -> (dual noise input G_d, kalman_for_poles structure)
LQR_STRUCTURES = ("full", "diagonal", "output", "output_diagonal")


# --------------------------------------------------------------------------- the dual plant
def dual_plant(A: ArrayLike, B: ArrayLike, *, dt: float | None = None, G: ArrayLike | None = None,
               R: ArrayLike | None = None, name: str | None = None) -> Plant:
    """The observer problem of state feedback: ``Plant(A', B')`` (an observer gain L of it is
    ``K = L'`` with ``eig(A - B K) = eig(A' - L B')``).

    Parameters
    ----------
    A : (n, n) array_like
    B : (n, m) array_like
    dt : float, optional
    G : (n, k) array_like, optional
        Noise input of the dual (the LQR weight ``Q = G Qw G'``).
    R : (m, m) array_like, optional
        The LQR input weight (the dual's measurement-noise covariance).
    name : str, optional

    Raises
    ------
    DimensionError, NotFiniteError, ValidationError
        Bad matrices (named A, B).

    Examples
    --------
    >>> from optdesign import dual_plant
    >>> dual = dual_plant([[0., 1.], [0., 0.]], [[0.], [1.]])   # state feedback on a double integrator
    >>> dual.A.tolist(), dual.C.tolist()                       # Plant(A', B')
    ([[0.0, 0.0], [1.0, 0.0]], [[0.0, 1.0]])
    """
    A = as_square("A", A)
    B = as_matrix("B", B, (A.shape[0], None))
    if B.shape[1] == 0:
        raise ValidationError("B must have at least one column (input); found shape "
                              f"{B.shape}")
    label = None if name is None else f"{name} (dual)"
    return Plant(A.T, B.T, G=None if G is None else np.asarray(G, dtype=float),
                 R=None if R is None else np.asarray(R, dtype=float), dt=dt, name=label)


def _feedback_plant(plant: Any) -> tuple[Plant, NDArray, NDArray]:
    """``(plant, A, B)`` of a Plant (or a system, via :func:`~optdesign.model.coerce.as_system`) that
    has an input matrix B.  A feedthrough D is ignored: state feedback ``u = -K x`` (and LQR) never
    uses C or D."""
    pl = as_system(plant).plant
    if pl.B is None:
        label = f" {pl.name!r}" if pl.name else ""
        raise ValidationError(f"state feedback needs the input matrix B; plant{label} has none "
                              f"(Plant(A, C, B=...), or a system with inputs)")
    return pl, pl.A, pl.B


def _require_controllable(dual: Plant, what: str) -> None:
    """Controllability of (A, B) is observability of the dual; the message speaks of the former."""
    modes = dual.unobservable_modes()
    if modes.size:
        shown = ", ".join(f"{complex(z):.6g}".strip("()") for z in modes)
        raise NotControllableError(f"(A, B) is not controllable, so {what} is impossible: uncontrollable "
                                 f"mode(s) {shown} (PBH test: rank [lambda I - A, B] < n)", modes=modes)


def _primal_words(text: str) -> str:
    """A dual design's message in state-feedback words (its error dynamics are ``(A - B K)'``)."""
    for dual, primal in (("A - L C", "(A - B K)'"), ("A - LC", "(A - B K)'"),
                         ("every Kalman filter", "every LQR loop (a Kalman filter of the dual)")):
        text = text.replace(dual, primal)
    return text


def _primal_checks(A: NDArray, B: NDArray, K: NDArray, dual_v: Verification, *, target: NDArray | None,
                   region: Region | None, discrete: bool, stable: bool) -> list[Check]:
    """The closed loop ``A - B K`` re-verified in primal form (numpy eigenvalues of A - B K, not of the
    dual's transpose), with the dual's tolerances (same poles, same rounding floor)."""
    F = A - B @ K
    out: list[Check] = []
    if target is not None and "pole_error" in dual_v:
        chk, _ = pole_check(F, target, dual_v["pole_error"].tolerance, name="feedback_pole_error",
                            what="eig(A - B K) (numpy)")
        out.append(chk)
    if region is not None and "region_margin" in dual_v:
        out.append(Check.at_most("feedback_region_margin", region.margin(np.linalg.eigvals(F)),
                                 dual_v["region_margin"].tolerance,
                                 "max signed distance of eig(A - B K) to the region (<= 0 inside)"))
    if stable:
        chk = stability_check(F, discrete)
        out.append(Check(name="feedback_stability_margin", value=chk.value, tolerance=chk.tolerance,
                         passed=chk.passed, sense=chk.sense, detail=chk.detail.replace("A - L C", "A - B K")))
    return out


# --------------------------------------------------------------------------- well-conditioned feedback
@dataclass(frozen=True, kw_only=True, eq=False)
class FeedbackDesign(DesignResult):
    """A well-conditioned state-feedback design (the dual of an :class:`ObserverDesign`).

    Attributes
    ----------
    K : (m, n) ndarray or None
        State-feedback gain, ``u = -K x``, closed loop ``A - B K`` (``K = L'`` of the dual observer).
    poles : (n,) ndarray of complex
        ``eig(A - B K)`` by numpy, sorted by real then imaginary part.
    kappa2 : float
        What was minimized: ``cond(X)`` of the unit-column right eigenvectors of ``A - B K``
        (controller mode, fixed poles or a region; infinite for a defective loop), or in the dual
        route kappa2 of the unit-column eigenvectors of ``(A - B K)'`` (see the module notes;
        ``extra["mode"]`` says which).
    kappa2_right : float
        ``cond(X)``: kappa2 of the unit-column right eigenvectors of ``A - B K`` (scipy's measure).
    eta, kappa_fro, gain_norm : float
        Of the dual design (``||K||_2 = ||L||_2``; eta is invariant under transposition).
    objective : str
    region : Region or None
    observer : ObserverDesign or None
        The dual design (its starts, solver statistics, V); None in controller mode.
    X : (n, n) ndarray of complex or None
        Controller mode: the verified unit-column right eigenvectors of ``A - B K`` whose condition
        number is ``kappa2`` (columns in the engine's pole order); None otherwise.
    extra : dict
        ``"mode"``: ``CONTROLLER_MODE`` or ``DUAL_MODE`` (module constants).  Region mode in controller mode
        also: ``kappa2_dual_route`` (cond(X) of the dual route's design, a start),
        ``kappa2_left`` (the dual measure of K), ``chosen`` (``"dual"``, ``"region"`` or
        ``"polish"``: which candidate answered).
    plant : Plant
        The plant (with B).
    verification : Verification
        The dual design's checks plus the closed loop re-verified in primal form:
        ``feedback_pole_error`` or ``feedback_region_margin``, ``feedback_stability_margin``.
    """

    K: NDArray[np.float64] | None
    poles: NDArray[np.complex128]
    kappa2: float
    kappa2_right: float
    eta: float
    kappa_fro: float
    gain_norm: float
    objective: str
    region: Region | None = None
    observer: Any = field(default=None, repr=False)
    plant: Plant | None = field(default=None, repr=False)
    X: NDArray[np.complex128] | None = field(default=None, repr=False)

    def __repr__(self) -> str:
        return (f"FeedbackDesign(status={Status(self.status).value}, success={self.success}, "
                f"kappa2={self.kappa2:.6g}, kappa2_right={self.kappa2_right:.6g}, "
                f"||K||={self.gain_norm:.4g})")


def _feedback_from_observer(obs: Any, A: NDArray, B: NDArray, *, plant: Plant | None, target: NDArray | None,
                            region: Region | None, discrete: bool, stable: bool) -> FeedbackDesign:
    L = getattr(obs, "L", None)
    K = None if L is None else np.array(L, dtype=float).T
    checks = list(obs.verification)
    if K is not None and np.all(np.isfinite(K)):
        checks += _primal_checks(A, B, K, obs.verification, target=target, region=region,
                                 discrete=discrete, stable=stable)
        poles = sort_poles(np.linalg.eigvals(A - B @ K))
        k_right = float(metrics.kappa2(A - B @ K))
    else:
        poles, k_right = np.full(A.shape[0], np.nan + 0j), float("nan")
    v = Verification.of(checks)
    message = _primal_words(obs.message)
    measure = (f"; measure optimized: {obs.objective} of the LEFT eigenvectors of A - B K (the dual "
               f"observer's), "
               f"not cond(X) of the right ones (kappa2_right = {k_right:.6g})")
    return FeedbackDesign(K=K, poles=poles, kappa2=obs.kappa2, kappa2_right=k_right, eta=obs.eta,
                          kappa_fro=obs.kappa_fro, gain_norm=obs.gain_norm, objective=obs.objective,
                          region=region, observer=obs, plant=plant, status=obs.status,
                          message=f"state feedback by duality: {message}{measure}",
                          solver_stats=obs.solver_stats,
                          verification=v, certificate=getattr(obs, "certificate", None),
                          target_poles=target, route=getattr(obs, "route", Route()),
                          extra={"dual": "observer of (A', B'), K = L'", "mode": DUAL_MODE})


@one_warning_per_call
def well_conditioned_feedback(plant: Any, *, poles: ArrayLike | None = None, region: Region | None = None,
                              structure: ArrayLike | None = None, allow_unstable: bool = False,
                              **options: Any) -> FeedbackDesign:
    """State-feedback gain K whose closed loop ``A - B K`` has a well-conditioned eigenbasis.

    Objective kappa2 / kappa_fro without bounds or structural zeros (controller mode): ``cond(X)``
    of the unit-column right eigenvectors ``X`` of ``A - B K`` is minimized (scipy's measure).  Fixed
    poles: the placement engine in controller mode.  Poles in a region:
    :func:`~optdesign.design.well_conditioned.well_conditioned_observer` on the dual plant
    ``(A', B')`` first (half the ``time_limit``; its design ``K = L'`` minimizes the dual measure),
    then the region engine in controller mode from that design and the usual region starts, then the
    fixed-pole controller mode at the final poles; the best verified design on ``cond(X)`` is
    returned (never worse than the dual route's).  With ``max_gain``, ``kappa2_max``, ``eta_max``,
    ``structure``, objective eta or an NLP asked for, the dual route answers alone (its measure, the
    *left* eigenvectors of ``A - B K``, said in the message and ``extra["mode"]``).  Every answer
    is re-verified on ``A - B K``.

    Parameters
    ----------
    plant : Plant or state-space system
        Needs B (n, m); C is not used.  Continuous, or discrete when ``dt`` is set.
    poles : (n,) array_like of complex, optional
        Fixed closed-loop poles.
    region : Region, optional
        Poles free in this region (give ``poles`` or ``region``, not both; neither: the stability
        region).
    structure : (m, n) array_like of bool, optional
        Free entries of K (False = structural zero); transposed for the dual.
    allow_unstable : bool
        Fixed poles only: accept unstable ``poles``.
    **options
        Every other option of ``well_conditioned_observer`` (``objective``, ``max_gain`` (on
        ``||K||_2``), ``kappa2_max``, ``eta_max``, ``starts``, ``seed``, ``solver``, ``scaling``,
        ``options``, ``time_limit``), passed through unchanged.

    Returns
    -------
    FeedbackDesign

    Raises
    ------
    ValidationError
        No B; everything ``well_conditioned_observer`` refuses (named there); a ``structure`` not
        (m, n).
    NotObservableError
        (A, B) not controllable (the uncontrollable modes are named).

    Examples
    --------
    >>> from optdesign import Plant
    >>> plant = Plant([[0, 1], [2, -1]], [[1, 0]], B=[[0], [1]])
    >>> d = well_conditioned_feedback(plant, poles=[-2, -3], starts=1)
    >>> bool(d.success), d.K.round(6).tolist()    # one input: K is fixed by the poles
    (True, [[8.0, 4.0]])
    """
    pl, A, B = _feedback_plant(plant)
    dual = dual_plant(A, B, dt=pl.dt, name=pl.name)
    _require_controllable(dual, "placing every closed-loop pole")
    mask = None
    if structure is not None:
        mask = as_matrix("structure", structure, (B.shape[1], A.shape[0])).astype(bool).T
    target = None
    if poles is not None:
        target = as_poles("poles", poles, A.shape[0])
        fields = _controller_design(A, B, target, pl.is_discrete, allow_unstable, structure is not None,
                                    options)
        if fields is not None:
            return _feedback_from_fields(fields, pl, target, options.get("objective", "kappa2"))
    if target is None and mask is None and _controller_region_ok(options):
        return _region_feedback(pl, A, B, dual, region, allow_unstable, options)
    obs = well_conditioned_observer(dual, poles=target, region=region, gain_mask=mask,
                                    allow_unstable=allow_unstable, **options)
    return _feedback_from_observer(obs, A, B, plant=pl, target=target, region=region,
                                   discrete=pl.is_discrete, stable=not allow_unstable)


#: options of :func:`well_conditioned_feedback` that send fixed poles to the dual route (the NLP)
_DUAL_ROUTE_OPTIONS = ("max_gain", "kappa2_max", "eta_max", "nlp_solver", "solver")

#: ``extra["mode"]`` of a design on state feedback's own measure, and of one by the dual route
CONTROLLER_MODE = "controller: cond(X) of the right eigenvectors of A - B K"
DUAL_MODE = "dual: kappa2 of the left eigenvectors of A - B K (the observer of (A', B'))"


def _controller_region_ok(options: dict[str, Any]) -> bool:
    """Region mode on state feedback's own measure: kappa2 / kappa_fro without bounds or an NLP asked
    for (eta, bounds and structural zeros stay on the dual route, which says so)."""
    return options.get("objective", "kappa2") in ("kappa2", "kappa_fro") and not any(
        options.get(k) is not None for k in _DUAL_ROUTE_OPTIONS)


def _region_feedback(pl: Plant, A: NDArray, B: NDArray, dual: Plant, region: Region | None,
                     allow_unstable: bool, options: dict[str, Any]) -> FeedbackDesign:
    """Poles free in a region, on ``cond(X)`` of ``A - B K``'s right eigenvectors: the dual route first
    (half the time budget; it validates the question), then the region engine in controller mode from
    its design and the usual starts (:func:`~.feedback_controller.region_controller_fields`)."""
    from .._deadline import Deadline, as_time_limit
    from ..model.regions import stability_region
    from .feedback_controller import region_controller_fields

    deadline = Deadline(as_time_limit(options.get("time_limit")))
    dual_opts = dict(options, time_limit=deadline.fraction(0.5) if deadline.limited else None)
    obs = well_conditioned_observer(dual, region=region, allow_unstable=allow_unstable, **dual_opts)
    used = getattr(obs, "region", None) or region or stability_region(pl.is_discrete)
    L = getattr(obs, "L", None)
    dual_K = None if L is None or not np.all(np.isfinite(L)) else np.array(L, dtype=float).T
    f = region_controller_fields(A, B, used, dual=dual, objective=obs.objective, discrete=pl.is_discrete,
                                 starts=options.get("starts"), seed=int(options.get("seed", 0)),
                                 deadline=deadline, dual_K=dual_K)
    if f is None:   # nothing verified in controller mode: the dual route's answer, as it is
        d = _feedback_from_observer(obs, A, B, plant=pl, target=None, region=used, discrete=pl.is_discrete,
                                    stable=True)
        return dataclasses.replace(d, message=d.message + "; the controller mode found no verified design")
    answered = f["chosen"] == "dual"
    dual_stages = [Stage(f"dual route (observer of (A', B'), left eigenvectors): {s.name}", s.kind,
                         s.outcome if answered or s.outcome != "answered" else Status(obs.status).value,
                         s.detail, s.time) for s in getattr(obs, "route", ())]
    extra = {"mode": CONTROLLER_MODE, "dual": "the observer of (A', B') (K = L') was a start",
             "kappa2_dual_route": f["kappa2_dual_route"],
             "kappa2_left": float(metrics.kappa2((A - B @ f["K"]).T)),
             "chosen": f["chosen"]}
    stats = obs.solver_stats
    solver_stats = dataclasses.replace(f["solver_stats"], time=(stats.time or 0.0) + f["solver_stats"].time,
                                       iterations=(stats.iterations or 0) + f["solver_stats"].iterations)
    return FeedbackDesign(K=f["K"], poles=f["poles"], kappa2=f["kappa2"], kappa2_right=f["kappa2_right"],
                          eta=f["eta"], kappa_fro=f["kappa_fro"], gain_norm=f["gain_norm"],
                          objective=obs.objective, region=used, observer=obs, plant=pl, X=f["X"],
                          status=f["status"], message=f["message"] + (
                              "; the dual route (a start) reached its half of the time limit"
                              if Status(obs.status) == Status.TIME_LIMIT else ""),
                          solver_stats=solver_stats, verification=f["verification"], certificate=None,
                          target_poles=None, route=Route(dual_stages + list(f["route"])), extra=extra)


def _controller_design(A: NDArray, B: NDArray, target: NDArray, discrete: bool, allow_unstable: bool,
                       masked: bool, options: dict[str, Any], *, max_iter: int = 400,
                       final_ftol: float | None = None) -> dict[str, Any] | None:
    """The fields of a controller-mode design (Ackermann for a repeated pole with one input, else the
    engine on cond(X)), or None where the dual route answers (bounds, masks, eta, the NLP asked for,
    or the engine found nothing)."""
    from .well_conditioned.evaluation import check_target_stable

    if not allow_unstable:
        check_target_stable(target, discrete)
    if needs_ackermann(target, input_rank(B)):
        return ackermann_fields(A, B, target, discrete=discrete, stable=not allow_unstable)
    objective = options.get("objective", "kappa2")
    if masked or objective not in ("kappa2", "kappa_fro") or any(
            options.get(k) is not None for k in _DUAL_ROUTE_OPTIONS):
        return None
    fields = controller_fields(A, B, target, objective=objective, discrete=discrete, stable=not allow_unstable,
                               starts=options.get("starts"), seed=int(options.get("seed", 0)),
                               time_limit=options.get("time_limit"), max_iter=max_iter, final_ftol=final_ftol)
    return fields if fields["K"] is not None else None


def _feedback_from_fields(f: dict[str, Any], pl: Plant, target: NDArray, objective: str) -> FeedbackDesign:
    """A :class:`FeedbackDesign` of controller-mode fields."""
    out = f.get("outcome")
    extra: dict[str, Any] = {"mode": CONTROLLER_MODE}
    if out is not None:
        best = min(out.starts, key=lambda r: r.objective_value) if out.starts else None
        extra.update(starts=len(out.starts), last_iterations=getattr(best, "last_iterations", 0),
                     last_decrease=getattr(best, "last_decrease", float("nan")),
                     stop_reason=getattr(best, "reason", ""))
    return FeedbackDesign(K=f["K"], poles=f["poles"], kappa2=f["kappa2"], kappa2_right=f["kappa2_right"],
                          eta=f["eta"], kappa_fro=f["kappa_fro"], gain_norm=f["gain_norm"], objective=objective,
                          region=None, observer=None, plant=pl, X=f["X"], status=f["status"], message=f["message"],
                          solver_stats=f["solver_stats"], verification=f["verification"], certificate=None,
                          target_poles=target, route=Route(f["route"]), extra=extra)


# --------------------------------------------------------------------------- place_poles drop-in
def _scipy_order(poles: NDArray) -> NDArray[np.complex128]:
    """scipy's ``place_poles`` order: real poles increasing, then conjugate pairs (negative imaginary
    part first) in lexicographic order."""
    poles = np.sort_complex(np.asarray(poles, dtype=complex))
    real = poles[poles.imag == 0]
    lower = poles[poles.imag < 0]
    pairs = [z for w in lower for z in (w, np.conj(w))]
    return np.concatenate([real, np.asarray(pairs, dtype=complex)])


@dataclass(frozen=True, kw_only=True, eq=False)
class PlacementResult(DesignResult):
    """Result of :func:`place`: the fields of scipy's ``place_poles`` Bunch plus the verification.

    Attributes
    ----------
    gain_matrix : (m, n) ndarray or None
        K with ``eig(A - B K) = requested_poles`` (None when no verified design exists; ``status``
        and ``message`` say why).
    computed_poles : (n,) ndarray
        ``eig(A - B K)`` in scipy's order (real increasing, then conjugate pairs).
    requested_poles : (n,) ndarray
        The poles asked for, in the same order.
    X : (n, n) ndarray of complex
        Unit-column right eigenvectors of ``A - B K``, column j for ``computed_poles[j]``
        (``(A - B K) X = X diag(computed_poles)``); for a defective loop (a repeated pole with one
        input) numpy's eigenvectors, numerically dependent.
    rtol : float
        The relative accuracy achieved on the poles (max relative distance of ``computed_poles``
        to ``requested_poles``).  (:func:`optdesign.compat.scipy.place_poles` reports scipy's
        meaning.)
    nb_iter : int
        Engine (BFGS) iterations over all starts and stages.
    kappa2 : float
        ``cond(X)``: what was minimized (infinite for a defective loop).
    kappa2_dual : float
        kappa2 of the unit-column left eigenvectors of ``A - B K`` (the dual observer's measure), for
        comparison.
    design : FeedbackDesign
        The full design (starts, checks, route).
    """

    gain_matrix: NDArray[np.float64] | None
    computed_poles: NDArray[np.complex128]
    requested_poles: NDArray[np.complex128]
    X: NDArray[np.complex128] | None
    rtol: float
    nb_iter: int
    kappa2: float
    kappa2_dual: float
    design: FeedbackDesign = field(repr=False)

    def __repr__(self) -> str:
        return (f"PlacementResult(status={Status(self.status).value}, success={self.success}, "
                f"kappa2={self.kappa2:.6g}, rtol={self.rtol:.1e}, nb_iter={self.nb_iter})")


def _scipy_rtol(rtol: Any) -> float:
    """scipy's rule: a finite real ``rtol <= 1`` (``<= 0`` runs every stage to ``maxiter``)."""
    try:
        r = float(rtol)
    except (TypeError, ValueError):
        raise ValidationError(f"rtol must be a real number <= 1; found {rtol!r}") from None
    if not math.isfinite(r) or r > 1.0:
        raise ValidationError(f"rtol must be finite and <= 1 (scipy: 'rtol can not be greater than 1'); "
                              f"found {rtol!r}")
    return r


def _in_scipy_order(F: NDArray, X: NDArray | None) -> tuple[NDArray, NDArray]:
    """``(computed poles, X)`` of ``F`` in scipy's order, ``X`` (columns of any order, unit norm)
    matched to the poles by eigen-residual; numpy's eigenvectors where ``X`` is None."""
    w = np.linalg.eigvals(F) if X is not None else None
    if X is None:
        w, X = np.linalg.eig(F)
        X = X / np.linalg.norm(X, axis=0)
    assert w is not None
    order: list[int] = []
    cols: list[int] = []
    for z in _scipy_order(w):
        j = next(i for i in np.argsort(np.abs(w - z)) if i not in order)
        order.append(int(j))
        res = np.linalg.norm(F @ X - X * z, axis=0)
        k = next(i for i in np.argsort(res) if i not in cols)
        cols.append(int(k))
    return w[order], X[:, cols]


def place(A: ArrayLike, B: ArrayLike, poles: ArrayLike, method: str = "optdesign", rtol: float = 1e-3,
          maxiter: int = 30, *, objective: str = "kappa2", dt: float | None = None, **options: Any
          ) -> PlacementResult:
    """Robust pole placement minimizing ``cond(X)``, with the call form of :func:`scipy.signal.place_poles`.

    Same arguments and result fields as scipy (``gain_matrix``, ``computed_poles``,
    ``requested_poles``, ``X``, ``rtol``, ``nb_iter``), plus ``status`` / ``success`` /
    ``verification``; :func:`optdesign.compat.scipy.place_poles` is the strict drop-in (scipy's
    meanings of ``rtol`` and ``nb_iter``, its warning).  The gain minimizes ``cond(X)`` of the
    unit-column right eigenvectors of ``A - B K`` (scipy's robustness measure) by the placement
    engine in controller mode; scipy's YT and KNV0 placements are among its starts, and the design
    is never worse than its starts.  With one input and a repeated pole the gain is unique
    (Ackermann's formula; ``A - B K`` defective, kappa2 infinite).

    Parameters
    ----------
    A : (n, n) array_like
    B : (n, m) array_like
    poles : (n,) array_like
        Closed-loop poles, a 1-D array (a column (n, 1) is refused, as scipy does), conjugate-closed;
        a pole may repeat up to ``rank(B)`` times, or any number of times when ``rank(B) = 1``.
        Unstable poles are allowed (the verification then checks the poles, not stability).
    method : {"optdesign", "YT", "KNV0"}
        Accepted for compatibility (YT and KNV0 are always starts; the optimization always runs);
        ``"KNV0"`` refuses complex poles, as scipy does.
    rtol : float
        Relative-decrease tolerance of the engine's last stage where tighter than its own (1e-9);
        ``<= 0`` runs that stage to ``maxiter``; ``> 1`` is refused (scipy's rule).
    maxiter : int
        BFGS iterations per stage of the engine's continuation, ``>= 1`` (measured on the 31
        benchmark problems: 30 gives cond(X) within 8e-4 of 400, the same on 30 of them).
    objective : {"kappa2", "kappa_fro", "eta"}
    dt : float, optional
        Sampling period: the stability test of a discrete design (``|z| < 1``).
    **options
        Passed to :func:`well_conditioned_feedback` (``starts``, ``seed``, ``time_limit``, ...).

    Returns
    -------
    PlacementResult

    Raises
    ------
    ValidationError
        Bad method, rtol or maxiter; KNV0 with complex poles.
    DimensionError
        Bad shapes; poles not a 1-D array of n.
    DefectivePolesError
        A pole repeated more than ``rank(B)`` times with ``rank(B) >= 2`` (no diagonalizable, hence no
        finite-cond(X), closed loop; scipy refuses it too).
    NotControllableError
        (A, B) not controllable (a ``ValueError``, as scipy's).

    Examples
    --------
    >>> import numpy as np
    >>> res = place(np.array([[0., 1.], [2., -1.]]), np.array([[0.], [1.]]), [-2, -3], starts=1)
    >>> res.gain_matrix.round(6).tolist(), bool(res.success)
    ([[8.0, 4.0]], True)
    """
    as_str("method", method, ("optdesign", "YT", "KNV0"))
    rtol = _scipy_rtol(rtol)
    maxiter = as_int("maxiter", maxiter, 1)
    A = as_square("A", A)
    B = as_matrix("B", B, (A.shape[0], None))
    target = as_poles("poles", poles, A.shape[0])
    if method == "KNV0" and np.any(target.imag != 0):
        raise ValidationError("method 'KNV0' places real poles only (scipy: 'Complex poles are not supported "
                              f"by KNV0'); found complex poles {[complex(z) for z in target if z.imag]}")
    disc = dt is not None
    stable = bool(np.all(np.abs(target) < 1.0)) if disc else bool(np.all(target.real < 0.0))
    pl = Plant(A, np.zeros((1, A.shape[0])), B=B, dt=dt)
    _require_controllable(dual_plant(A, B, dt=dt), "placing every closed-loop pole")
    fields = _controller_design(A, B, target, disc, not stable, bool(options.get("structure") is not None),
                                {"objective": objective, **options}, max_iter=maxiter,
                                final_ftol=min(rtol, 1e-9))
    if fields is not None:
        design = _feedback_from_fields(fields, pl, target, objective)
    else:
        design = well_conditioned_feedback(pl, poles=target, objective=objective, allow_unstable=not stable,
                                           **options)
    return _placement_result(A, B, target, design, method=method, rtol=rtol, maxiter=maxiter)


def _placement_result(A: NDArray, B: NDArray, target: NDArray, design: FeedbackDesign, *, method: str,
                      rtol: float, maxiter: int) -> PlacementResult:
    req = _scipy_order(target)
    K = design.K
    if K is None or not np.all(np.isfinite(K)):
        computed, X, kappa, achieved, kd = np.full(req.shape, np.nan + 0j), None, math.nan, math.inf, math.nan
    else:
        F = A - B @ K
        computed, X = _in_scipy_order(F, design.X)
        kappa = design.kappa2_right if design.X is not None or not math.isfinite(design.kappa2_right) \
            else float(np.linalg.cond(X))
        pe = [c for c in design.verification if c.name == "feedback_pole_error"]
        achieved = pe[0].value if pe else float(classical_pole_error(np.linalg.eigvals(F), target))
        kd = float(metrics.kappa2(F.T))
    iters = design.solver_stats.iterations or 0
    return PlacementResult(gain_matrix=K, computed_poles=computed, requested_poles=req, X=X, rtol=achieved,
                           nb_iter=int(iters), kappa2=kappa, kappa2_dual=kd, design=design,
                           status=design.status, message=design.message, solver_stats=design.solver_stats,
                           verification=design.verification, certificate=design.certificate,
                           target_poles=target, route=design.route,
                           extra={"method": method, "scipy_rtol": rtol, "scipy_maxiter": maxiter,
                                  **design.extra})


# --------------------------------------------------------------------------- inverse LQR
@dataclass(frozen=True, kw_only=True, eq=False)
class InverseLQRResult(DesignResult):
    """Outcome of :func:`lqr_for_poles` (the dual of :class:`InverseKalmanResult`).

    Attributes
    ----------
    K : (m, n) ndarray or None
        The LQR gain, ``u = -K x``: continuous ``R^-1 B' X``, discrete ``(R + B' X B)^-1 B' X A``.
    Q : (n, n) ndarray or None
        The state weight found, PSD (``G_d Qw G_d'``: ``diag(q)`` or ``C' Qy C`` by structure).
    Qw : ndarray or None
        The structured weight: ``q`` as a diagonal matrix (``"diagonal"``), ``Qy`` (``"output"``),
        ``diag(qy)`` (``"output_diagonal"``); None for ``"full"``.
    X : (n, n) ndarray or None
        The stabilizing solution of the LQR Riccati equation.
    R : (m, m) ndarray
    poles : (n,) ndarray of complex or None
        ``eig(A - B K)`` by numpy.
    method, objective, structure : str
    objective_value : float
    kalman : InverseKalmanResult
        The dual design (its certificate, stage reports).
    plant : Plant
    verification : Verification
        The dual's checks (the LQR checks transposed: ``pole_error``, ``riccati_residual``,
        ``are_resolve_gain`` / ``are_resolve_poles``, ``Q_min_eig``, ``P_min_eig``, ...) plus
        ``feedback_pole_error`` on ``A - B K`` in primal form.
    """

    K: NDArray[np.float64] | None = None
    Q: NDArray[np.float64] | None = None
    Qw: NDArray[np.float64] | None = None
    X: NDArray[np.float64] | None = None
    R: NDArray[np.float64]
    poles: NDArray[np.complex128] | None = None
    method: str
    objective: str
    structure: str
    objective_value: float = float("nan")
    kalman: Any = field(default=None, repr=False)
    plant: Plant | None = field(default=None, repr=False)

    def __repr__(self) -> str:
        return (f"InverseLQRResult(method={self.method!r}, status={Status(self.status).value!r}, "
                f"success={self.success})")


def _lqr_structure(structure: str, pl: Plant) -> tuple[NDArray | None, Literal["full", "diagonal", "input"]]:
    """(G of the dual, kalman_for_poles structure) of an LQR weight structure."""
    structure = as_str("structure", structure, LQR_STRUCTURES)
    n = pl.n
    if structure == "full":
        return None, "full"
    if structure == "diagonal":
        return np.eye(n), "diagonal"
    Ct = pl.C.T
    return Ct, "input" if structure == "output" else "diagonal"


@one_warning_per_call
def lqr_for_poles(plant: Any, poles: ArrayLike, *, R: ArrayLike | None = None,
                  structure: Literal["full", "diagonal", "output", "output_diagonal"] = "full",
                  objective: Literal["min_trace", "nearest", "feasibility"] = "min_trace",
                  Q_nominal: ArrayLike | None = None, **options: Any) -> InverseLQRResult:
    r"""Inverse LQR: a state weight ``Q >= 0`` whose LQR closed loop ``A - B K`` has these poles.

    :func:`~optdesign.design.inverse_kalman.kalman_for_poles` on the dual plant ``(A', B')`` with
    measurement-noise covariance R (the LQR input weight), then ``K = L'``, ``X = P``.  Same
    methods, objectives and certificates: ``infeasible`` only with a global certificate (e.g. the
    frequency where the return-difference inequality ``T(jw)^* R T(jw) >= R`` of every LQR loop
    fails), ``not_found`` when a local search finds nothing.

    Parameters
    ----------
    plant : Plant or state-space system
        A (n, n), B (n, m); C (p, n) only for the ``"output"`` structures; continuous or discrete.
        A feedthrough D is ignored (LQR uses neither C nor D).
    poles : (n,) array_like of complex
        Target closed-loop poles, conjugate-closed (stable: every LQR loop is).
    R : (m, m) array_like, optional
        Input weight, symmetric positive definite (default: the identity).
    structure : {"full", "diagonal", "output", "output_diagonal"}
        ``"full"``: any ``Q >= 0``; ``"diagonal"``: ``Q = diag(q)``, ``q >= 0``; ``"output"``:
        ``Q = C' Qy C``, ``Qy >= 0``; ``"output_diagonal"``: ``Q = C' diag(qy) C``.
    objective : {"min_trace", "nearest", "feasibility"}
    Q_nominal : array_like, optional
        For ``"nearest"``: (n, n) for ``"full"`` and ``"diagonal"``, (p, p) for the output structures.
    **options
        Every other option of ``kalman_for_poles`` (``method``, ``solver``, ``seed``, ``tol``,
        ``time_limit``, ...).

    Returns
    -------
    InverseLQRResult

    Raises
    ------
    ValidationError
        No B; bad R (not (m, m) PD), structure, objective; everything ``kalman_for_poles`` refuses.
    NotObservableError
        (A, B) not controllable (the uncontrollable modes are named).

    References
    ----------
    Priess et al., IEEE TCST 23(2) (2015): inverse LQR by LMIs.  Chang & Lee 1984 (seed 000) for
    the filter question it is dual to.

    Examples
    --------
    >>> from optdesign import Plant
    >>> plant = Plant([[0, 1], [-6, -5]], [[1, 0]], B=[[0], [1]])
    >>> res = lqr_for_poles(plant, [-5, -8])
    >>> bool(res.success), res.K.round(6).tolist()
    (True, [[34.0, 8.0]])
    """
    pl, A, B = _feedback_plant(plant)
    m = B.shape[1]
    Rm = np.eye(m) if R is None else check_pd("R", as_square("R", R, m))
    Gd, kstruct = _lqr_structure(structure, pl)
    dual = dual_plant(A, B, dt=pl.dt, G=Gd, R=Rm, name=pl.name)
    _require_controllable(dual, "placing every LQR pole")
    target = as_poles("poles", poles, pl.n)
    res = kalman_for_poles(dual, target, objective=objective, q_structure=kstruct, Q_nominal=Q_nominal,
                           **options)
    K = None if res.L is None else np.array(res.L, dtype=float).T
    checks = list(res.verification)
    poles_cl = None
    if K is not None and np.all(np.isfinite(K)):
        checks += _primal_checks(A, B, K, res.verification, target=target, region=None,
                                 discrete=pl.is_discrete, stable=False)
        poles_cl = sort_poles(np.linalg.eigvals(A - B @ K))
    return InverseLQRResult(K=K, Q=res.Q, Qw=res.Qw, X=res.P, R=Rm, poles=poles_cl, method=res.method,
                            objective=res.objective, structure=structure, objective_value=res.objective_value,
                            kalman=res, plant=pl, status=res.status,
                            message=f"inverse LQR by duality: {_primal_words(res.message)}",
                            solver_stats=res.solver_stats,
                            verification=Verification.of(checks), certificate=res.certificate,
                            target_poles=target, route=getattr(res, "route", Route()),
                            extra={"dual": "kalman_for_poles of (A', B'), K = L', X = P"})
