"""The public verb :func:`kalman_for_poles`: validate, pick the route, answer."""


from __future__ import annotations

import dataclasses
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..._backends import import_clarabel
from ..._deadline import Deadline, dense_time_refusal
from ..._validate import as_int, as_poles, as_positive_float, renamed
from ...backends.report import one_warning_per_call
from ...classical.placement import pole_error
from ...classical.riccati import format_pole as _fmt
from ...classical.solheim import solheim
from ...engines.inverse_kalman_engine import EngineSetup
from ...errors import BackendUnavailableError, OptDesignError, RiccatiError, ValidationError
from ...formulate.inverse_kalman import (
    OBJECTIVES,
    STRUCTURES,
    check_choice,
)
from ...model.coerce import as_plant
from ...model.plant import Plant
from ...results import Route, Stage, Status
from ..verification import POLE_FLOOR_CAP, pole_tolerance
from .certificates import identity_certificate
from .common import (
    METHODS,
    POLE_CHECKS,
    best_unverified,
    design_from_Q,
    empty_result,
    make_stats,
    nominal_noise,
    quiet,
    stable_poles,
    uncomputable_poles,
    verify_design,
    with_status,
)
from .engine_route import engine_setup, engine_warm_start, run_engine
from .nlp_route import run_nlp
from .results import InfeasibilityCertificate, InverseKalmanResult
from .route import inverse_kalman_route
from .sdp_route import fixed_gain_design, run_sdp


@one_warning_per_call
def kalman_for_poles(
    plant: Plant | Any,
    poles: ArrayLike,
    *,
    method: Literal["auto", "sdp", "nlp", "sequential"] = "auto",
    objective: Literal["min_trace", "nearest", "feasibility"] = "min_trace",
    Q_nominal: ArrayLike | None = None,
    q_structure: Literal["full", "diagonal", "input"] | None = None,
    sdp_solver: Literal["CLARABEL", "SCS"] | None = None,
    R: ArrayLike | None = None,
    G: ArrayLike | None = None,
    seed: int = 0,
    tol: float = 1e-8,
    time_limit: float | None = None,
    nlp_options: dict[str, Any] | None = None,
    structure: str | None = None,
    solver: str | None = None,
) -> InverseKalmanResult:
    r"""Process noise ``Q >= 0`` whose steady-state Kalman filter has the prescribed poles.

    Finds L, P and Q with ``eig(A - L C) = poles`` and the filter Riccati equation satisfied
    (continuous ``A P + P A' - P C' R^-1 C P + Q = 0``, ``L = P C' R^-1``; discrete predictor
    DARE, ``L = A P C' (C P C' + R)^-1``).  See the module docstring for which member of the
    family each objective returns.

    Parameters
    ----------
    plant : Plant, python-control StateSpace or scipy StateSpace / lti / dlti
        ``A`` (n, n), ``C`` (p, n), ``R`` (p, p) (required: from the plant or ``R=``), ``G`` (n, m)
        for structured Q, ``dt`` for discrete time.  ``plant.Q`` is only used as the default
        ``Q_nominal``.  Systems are converted by :func:`optdesign.as_plant`.
    poles : (n,) array_like of complex
        Target error poles, closed under conjugation.
    method : {"auto", "sdp", "nlp", "sequential"}
        ``"sdp"`` (= ``"auto"``): the inverse Kalman engine
        (:mod:`optdesign.engines.inverse_kalman_engine`) -- one output: L is fixed by the poles and
        the fixed-gain SDP (on Clarabel, polished) gives Q, globally; several outputs: L and Q
        together (the eigenvector parametrization of the gains with the target poles, Newton on
        the feasible set), certified by the fixed-gain SDP at the final L.  Where the engine does
        not apply (a target at an eigenvalue of A or of its mirror image), another SDP solver is
        asked for, or its design does not verify: the cvxpy fixed-gain SDP (one output) or L from
        the NLP then that SDP (several);
        ``"nlp"``: CasADi/IPOPT over ``(L, P, Q = F F')`` (any number of outputs; local);
        ``"sequential"``: Solheim's method (:func:`optdesign.classical.solheim`; structure
        ``"full"``, objective ignored).
    objective : {"min_trace", "nearest", "feasibility"}
    Q_nominal : array_like, optional
        For ``"nearest"``: (n, n) for ``"full"``, (m, m) (compared with Qw) otherwise.
        Default: the plant's noise model.
    q_structure : {"full", "diagonal", "input"}
        ``"full"`` (default): any n x n ``Q >= 0``; ``"input"``: ``Q = G Qw G'``, ``Qw >= 0``;
        ``"diagonal"``: ``Q = G diag(qw) G'``, ``qw >= 0``.  (Old spelling ``structure=``:
        deprecated.)
    sdp_solver : {"CLARABEL", "SCS"} or None
        SDP solver (default Clarabel).  (Old spelling ``solver=``: deprecated.)
    R, G : array_like, optional
        Measurement-noise covariance and noise-input matrix for a system that does not carry
        them (a python-control or scipy system).
    seed : int
        Seeds the NLP multi-start and the closest-poles search (an integer >= 0).
    tol : float
        Pole accuracy required by the verification (relative, :func:`pole_error`; raised to the
        rounding floor of the poles where that is larger).
    nlp_options : dict, optional
        Settings of the NLP route: ``"derivatives"`` (``"closed_form"``, the default, or
        ``"symbolic"``: CasADi's automatic derivatives -- for comparisons) and ``"ipopt.*"`` options
        merged over the route's own.
    time_limit : float, optional
        Seconds of wall time.  Every stage gets what is left (IPOPT ``max_wall_time``, the SDP
        solvers' time limits) and no new start or search begins after it; when it runs out the
        result has status ``time_limit`` and the best verified design found so far, if any.  The
        set-up counts: a design whose uninterruptible dense set-up (the eigenvalues of A, the
        eigenvectors of ``A - L C``) alone is estimated to outlast the limit is not started
        (status ``time_limit`` at once, the estimate in ``message``; ``setup_refusal``).

    Returns
    -------
    InverseKalmanResult
        ``INFEASIBLE`` only with a global certificate (``certificate``): an unstable target, a
        determinant or trace identity every Kalman filter satisfies, the frequency where the
        return-difference inequality fails at the gain the poles fix (one output), or an accurate
        convex SDP.  When a local search finds nothing the status is ``NOT_FOUND`` (feasibility
        unknown; the closest poles found are in ``extra["closest"]``), never ``INFEASIBLE``.
        A solver failure gives its status and the reason in ``message``.  When no route verifies a
        design, the result is the best unverified one (``success`` False, a solver's optimum as
        ``optimal_inaccurate``, the failed checks named in ``message``): the smallest largest check
        violation (:func:`~optdesign.design.verification.check_violation`; a pole error within the
        rounding floor of its poles counts as none), then the better objective.  One output, the
        other routes are not run when the engine's gain and the placed gain refined for its poles
        both miss the targets beyond the pole tolerance (not computable in double precision: the
        poles fix the gain).

    Raises
    ------
    ValidationError
        Bad choice of method / objective / structure, no R, a malformed ``Q_nominal``, a
        seed that is not an integer >= 0.
    BackendUnavailableError
        The SDP methods without an installed SDP solver (names the package to install).
    DimensionError, NotConjugateClosedError
        Wrong number of poles, not closed under conjugation.
    NotObservableError
        (C, A) is not observable (names the modes).

    References
    ----------
    Chang & Lee 1984 (seed 000); Anderson & Moore, *Optimal Filtering* (1979).

    Examples
    --------
    >>> from optdesign import Plant, kalman_for_poles
    >>> res = kalman_for_poles(Plant([[0, 1], [-6, -5]], [[1, 0]], R=[[1]]), [-5, -8])
    >>> res.success, res.L.ravel().round(9).tolist()
    (True, [8.0, -6.0])
    """
    dl = Deadline(time_limit)   # the set-up (validation, observability, the engine's state) counts
    structure = renamed("q_structure", q_structure, "structure", structure, "full")
    solver = renamed("sdp_solver", sdp_solver, "solver", solver, None)
    plant = as_plant(plant, R=R, G=G)
    check_choice("method", method, METHODS)
    check_choice("objective", objective, OBJECTIVES)
    check_choice("q_structure", structure, STRUCTURES)
    target = as_poles("poles", poles, plant.n)
    refused = setup_refusal(plant, target, method, objective, structure, dl)
    if refused is not None:
        return refused
    problem = InverseKalmanProblem(plant, q_structure=structure, objective=objective, Q_nominal=Q_nominal,
                                   sdp_solver=solver, tol=tol, nlp_options=nlp_options)
    return problem.solve(target, method=method, seed=seed, time_limit=dl)


def setup_refusal(plant: Plant, target: NDArray, method: str, objective: str, structure: str,
                  dl: Deadline) -> InverseKalmanResult | None:
    """The ``time_limit`` answer, given up front, of a design whose uninterruptible dense set-up alone
    outlasts the time left (None when it may fit): every route computes the eigenvalues of A and
    verifies with the eigenvectors of ``A - L C`` -- two LAPACK calls of order n that cannot be
    stopped once started (:func:`~optdesign._deadline.dense_time_refusal`: a calibrated lower
    bound).  Issue 26: at n = 5000 the set-up ran past ``time_limit=5`` for minutes."""
    why = dense_time_refusal([("eigvals", plant.n), ("eig", plant.n)], dl,
                             f"kalman_for_poles at n = {plant.n}")
    if not why:
        return None
    common = dict(target_poles=target, method="sdp" if method == "auto" else method, objective=objective,
                  structure=structure, plant=plant)
    res = empty_result(common, Status.TIME_LIMIT, f"no design: {why}", None,
                       make_stats("none", t=dl.elapsed), details={"refused": why})
    stage = Stage("setup_estimate", "check", "time_limit",
                  "refused up front: the set-up alone outlasts the limit")
    return dataclasses.replace(res, route=Route([stage]))


class InverseKalmanProblem:
    """The inverse Kalman question for one plant, held by the caller and solved for many targets.

    Built once from the plant and the fixed choices (structure and objective of Q, nominal, solver,
    tolerances); :meth:`solve` answers for target poles, as :func:`kalman_for_poles` does (which is
    ``InverseKalmanProblem(plant, ...).solve(poles, ...)``).  What does not depend on the target is
    validated and built once: the plant's observability, the engine's per-plant state (the family
    map of the fixed-gain SDP).  A sweep over targets holds one problem and passes the previous
    answer as ``warm_start``.

    Parameters
    ----------
    plant : Plant, python-control StateSpace or scipy StateSpace / lti / dlti
    q_structure, objective, Q_nominal, sdp_solver, R, G, tol, nlp_options
        As for :func:`kalman_for_poles`.

    Examples
    --------
    >>> from optdesign import Plant
    >>> prob = InverseKalmanProblem(Plant([[0, 1], [-6, -5]], [[1, 0]], R=[[1]]))
    >>> [round(float(prob.solve([-5 * s, -8 * s]).objective_value), 4) for s in (1, 2)]
    [92.3341, 4870.4279]
    """

    def __init__(self, plant: Plant | Any, *, q_structure: str = "full", objective: str = "min_trace",
                 Q_nominal: ArrayLike | None = None, sdp_solver: str | None = None,
                 R: ArrayLike | None = None, G: ArrayLike | None = None, tol: float = 1e-8,
                 nlp_options: dict[str, Any] | None = None):
        plant = as_plant(plant, R=R, G=G)
        check_choice("objective", objective, OBJECTIVES)
        check_choice("q_structure", q_structure, STRUCTURES)
        self.tol = as_positive_float("tol", tol)
        if plant.R is None:
            raise ValidationError("kalman_for_poles needs the measurement-noise covariance R: the plant has "
                                  "no R")
        self.nlp = _nlp_settings(nlp_options)
        self.plant, self.structure, self.objective, self.solver = plant, q_structure, objective, sdp_solver
        self.Qn = nominal_noise(plant, q_structure, objective, Q_nominal)
        plant.require_observable(what="placing every filter pole")
        self._engine: EngineSetup | None = None

    def engine(self, dl: Deadline | None = None) -> EngineSetup:
        """The inverse Kalman engine's per-plant state (built on first use; its set-up counts
        against ``dl``, and a set-up the deadline cut short is used once, not kept)."""
        if self._engine is not None:
            return self._engine
        setup = engine_setup(self.plant, self.structure, self.objective, dl)
        if dl is None or not dl.expired:
            self._engine = setup
        return setup

    @one_warning_per_call
    def solve(self, poles: ArrayLike, *, method: str = "auto", seed: int = 0,
              time_limit: float | Deadline | None = None, warm_start: Any = None) -> InverseKalmanResult:
        """Process noise ``Q >= 0`` whose steady-state Kalman filter has these poles.

        Parameters
        ----------
        poles : (n,) array_like of complex
        method : {"auto", "sdp", "nlp", "sequential"}
            As for :func:`kalman_for_poles`.
        seed : int
        time_limit : float or Deadline, optional
            Seconds (a Deadline: the caller's budget, already running).
        warm_start : InverseKalmanResult or array_like, optional
            A previous answer (or its decision covariance) for a nearby target: the engine starts
            from it.

        Returns
        -------
        InverseKalmanResult
        """
        dl = Deadline.of(time_limit)
        plant, structure, objective, tol = self.plant, self.structure, self.objective, self.tol
        check_choice("method", method, METHODS)
        seed = as_int("seed", seed, 0)
        target = as_poles("poles", poles, plant.n)
        refused = setup_refusal(plant, target, method, objective, structure, dl)
        if refused is not None:
            return refused
        if method == "sequential" and structure != "full":
            raise ValidationError("method='sequential' (Solheim) gives a full Q; use q_structure='full'")
        common = dict(target_poles=target, method="sdp" if method == "auto" else method, objective=objective,
                      structure=structure, plant=plant)
        early = self._early_answer(target, common, dl)
        if early is not None:
            name = "zero_noise" if early.certificate is None else str(early.certificate.kind)
            return dataclasses.replace(early, route=inverse_kalman_route(early, early=name))
        nominal = None
        if objective == "nearest" and self.Qn is not None:
            nominal = nominal_design(plant, target, common, self.Qn, tol, dl)
            if nominal is not None and nominal.verification.passed:
                route = inverse_kalman_route(nominal, early="nominal_noise")
                return dataclasses.replace(nominal, route=route)
        res, engine = self._answer(method, target, common, seed, dl, warm_start)
        res = honest_status(res)
        if not res.success and res.L is None and nominal is not None:
            # the routes found nothing; the nominal places the targets, some other check fails
            res = with_status(nominal, nominal.status,
                              f"{nominal.message}; the solver routes found nothing: {res.message}")
        return dataclasses.replace(res, route=inverse_kalman_route(res, engine=engine, nominal=nominal))

    def _answer(self, method, target, common, seed, dl, warm_start):
        """The engine, then the SDP / NLP / sequential routes: ``(answer, the engine's result or
        None)``."""
        plant, tol = self.plant, self.tol
        with quiet():
            engine = None
            if method in ("auto", "sdp") and self._engine_usable():
                warm = (engine_warm_start(warm_start) if isinstance(warm_start, InverseKalmanResult)
                        else warm_start)
                engine = run_engine(self.engine(dl), target, common, self.Qn, tol, seed, dl, warm)
                if engine is not None and (engine.success or engine.status == Status.TIME_LIMIT):
                    return engine, engine
                if engine is not None and engine.L is None:   # the engine found nothing: the other
                    return self._route(method, target, common, seed, dl), engine   # routes answer
                err = None if engine is None else uncomputable_poles(plant, engine, target, tol)
                if err is not None and engine is not None:  # the other routes cannot help
                    own = engine.verification["pole_error"].value
                    return _unverified(engine, f"the targets are not computable in double precision: the "
                                               f"poles fix the gain, and neither the engine's nor the "
                                               f"placed gain refined for its poles places them to the "
                                               f"tolerance (pole errors {own:.1e}, {err:.1e}); the other "
                                               f"routes were not run"), engine
            res = self._route(method, target, common, seed, dl)
            return (res, None) if engine is None else (_best_of(plant, res, engine), engine)

    def _engine_usable(self) -> bool:
        """The engine certifies with Clarabel: used unless another SDP solver was asked for or
        Clarabel is not installed (then the SDP route runs, and says what to install).  The engine
        calls the clarabel package itself, so that is what is looked for (not cvxpy's solver
        discovery, which imports cvxpy: about 0.9 s of CPU on a process's first design)."""
        if self.solver is not None and str(self.solver).upper() != "CLARABEL":
            return False
        try:
            import_clarabel()
        except BackendUnavailableError:
            return False
        return True

    def _early_answer(self, target, common, dl) -> InverseKalmanResult | None:
        """The answers that need no solver: an unstable target, an identity every Kalman filter
        satisfies, the open-loop poles (Q = 0)."""
        plant = self.plant
        disc = plant.is_discrete
        if not np.all(stable_poles(target, disc)):
            bad = target[~stable_poles(target, disc)]
            where = "inside the unit circle" if disc else "in the open left half-plane"
            cert = InfeasibilityCertificate(
                kind="unstable_target",
                reason=f"target pole(s) {', '.join(_fmt(z) for z in bad)} not {where}: every steady-state "
                       f"Kalman filter is stable")
            return empty_result(common, Status.INFEASIBLE, f"infeasible: {cert.reason}", cert,
                                make_stats("none", t=dl.elapsed))
        identity = identity_certificate(plant, target)
        if identity is not None:
            return empty_result(common, Status.INFEASIBLE, f"infeasible: {identity.reason}", identity,
                                make_stats("analytic", t=dl.elapsed))
        if self.objective == "min_trace" and open_loop_target(plant, target, self.tol):
            return zero_noise_design(plant, target, common, self.tol, dl)
        return None

    def _route(self, method, target, common, seed, dl) -> InverseKalmanResult:
        """The SDP / NLP / sequential routes (where the engine does not apply or did not verify)."""
        plant, Qn, solver, tol, nlp = self.plant, self.Qn, self.solver, self.tol, self.nlp
        if method == "auto":
            method = "sdp"
        common = {**common, "method": method}
        if method == "sequential":
            return run_sequential(plant, target, common, tol, dl)
        if method == "sdp":
            if plant.p > 1:
                return run_sdp_outputs(plant, target, common, Qn, solver, tol, seed, dl, nlp)
            return run_sdp(plant, target, common, Qn, solver, tol, seed, dl)
        return run_nlp(plant, target, common, Qn, solver, tol, seed, dl, nlp)


def _unverified(res: InverseKalmanResult, why: str) -> InverseKalmanResult:
    """An unverified design returned as the answer: a solver's optimum becomes
    ``optimal_inaccurate`` (its checks do not confirm it), the reason is added to the message."""
    status = Status.OPTIMAL_INACCURATE if Status(res.status).is_solved else res.status
    return with_status(res, status, f"{res.message}; not verified: {why}")


def _best_of(plant: Plant, res: InverseKalmanResult, engine: InverseKalmanResult) -> InverseKalmanResult:
    """The verb's answer after the engine's design failed a check and the other routes ran: theirs
    if verified or a verdict (a certificate of infeasibility), else the better unverified design
    (:func:`~.common.best_unverified`: the smallest check violation, then the objective; the
    engine's on a tie).  A time limit without a design keeps the engine's design: nothing lost."""
    if res.success or Status(res.status).is_infeasible:
        return res
    if res.status == Status.TIME_LIMIT and res.L is None:
        return with_status(engine, Status.TIME_LIMIT, f"{res.message}; the engine's unverified design is "
                                                      f"returned: {engine.message}")
    best = best_unverified(plant, [engine, res])
    if best is None or best is res:
        return res
    return _unverified(engine, f"no route verified a design, and the engine's is the closest to verifying "
                               f"(smallest check violation, then objective; the other routes: {res.message})")


def open_loop_target(plant: Plant, target: NDArray, tol: float) -> bool:
    """The targets are the (stable) open-loop poles, to their rounding level.

    The tolerance (:func:`pole_tolerance`) is at most ``max(tol, POLE_FLOOR_CAP)``: a pole error
    above that decides without the rounding floor of A (an eigenvector computation)."""
    err = pole_error(np.linalg.eigvals(plant.A), target)
    return err <= max(tol, POLE_FLOOR_CAP) and err <= pole_tolerance(plant.A, tol)


def zero_noise_design(plant, target, common, tol, dl):
    """Targets = the open-loop poles of a stable plant: ``Q = 0`` gives ``P = 0`` and ``L = 0``
    exactly, and has the smallest trace there is (issue 11, item 3: the SDP's near-zero P broke the
    scale of the residual check)."""
    n, p = plant.n, plant.p
    Z = np.zeros((n, n))
    Qw = None if common["structure"] == "full" else np.zeros((plant.m, plant.m))
    L = np.zeros((n, p))
    ver, poles = verify_design(plant, target, L, Z, Z, Qw, common["structure"], tol, avoid="hamiltonian")
    return InverseKalmanResult(
        L=L, Q=Z, Qw=Qw, P=Z.copy(), poles=poles, status=Status.OPTIMAL,
        message="the targets are the open-loop poles of a stable plant: Q = 0 (P = 0, L = 0) is exact and "
                "has the smallest trace",
        solver_stats=make_stats("analytic", "solved", dl.elapsed), verification=ver, certificate=None,
        objective_value=0.0, extra={}, **common)


def nominal_design(plant, target, common, Qn, tol, dl):
    """``objective="nearest"``: when the nominal noise itself places the targets (its Kalman
    filter passes every check), it is the nearest Q there is (distance 0) -- no SDP needed.
    ``None`` otherwise.  (The inverse LQR of harold's ``test_simple_dlqr``, whose targets come
    from the nominal weight, went to an SDP that answered "unbounded", issue 26.)"""
    structure = common["structure"]
    Q, Qw = (Qn, None) if structure == "full" else (None, Qn)
    if Qw is not None:
        Q = plant.G @ Qw @ plant.G.T
    try:
        L, P, Q, Qw, ver, poles = design_from_Q(plant, target, structure, Q, Qw, tol)
    except (RiccatiError, OptDesignError, np.linalg.LinAlgError, ValueError):
        return None
    if not all(c.passed for c in ver if c.name in POLE_CHECKS):
        return None
    ok = ver.passed
    return InverseKalmanResult(
        L=L, Q=Q, Qw=Qw, P=P, poles=poles, status=Status.OPTIMAL if ok else Status.OPTIMAL_INACCURATE,
        message="the nominal Q itself places the targets (its Kalman filter passes every check): it is "
                "the nearest Q, at distance 0" if ok else
                "the nominal Q itself places the targets (the pole checks pass) but its Riccati solution "
                "fails " + ", ".join(c.name for c in ver.failed) + " (an ill-conditioned Riccati equation): "
                "the nearest Q (distance 0), not verified",
        solver_stats=make_stats("analytic", "solved", dl.elapsed), verification=ver, certificate=None,
        objective_value=0.0, extra={}, **common)


def honest_status(res: InverseKalmanResult) -> InverseKalmanResult:
    """The statuses a design question can have: a feasibility question is never ``unbounded``,
    and ``infeasible`` comes only with a certificate; a route that found nothing otherwise
    answers ``not_found`` (issue 26: "the SDP failed: clarabel: infeasible" answered
    ``unbounded`` on a feasible target)."""
    st = Status(res.status)
    if res.L is None and (st == Status.UNBOUNDED or (st.is_infeasible and res.certificate is None)):
        return with_status(res, Status.NOT_FOUND,
                           f"no verified design, feasibility unknown (the solver's {st.value!r} is not a "
                           f"certificate): {res.message}")
    return res


def run_sequential(plant, target, common, tol, dl):
    try:
        sol = solheim(plant, target)
    except (ValidationError, RiccatiError) as exc:
        return empty_result(common, Status.SOLVER_ERROR, f"sequential method not applicable: {exc}", None,
                      make_stats("solheim", "error", dl.elapsed))
    ver, poles = verify_design(plant, target, sol.L, sol.P, sol.Q, None, "full", tol)
    msg = f"Solheim's sequential method: {sol.message}"
    if not ver.passed:
        msg += "; failed checks: " + ", ".join(c.name for c in ver.failed)
    return InverseKalmanResult(
        L=sol.L, Q=sol.Q, Qw=None, P=sol.P, poles=poles, status=Status.SOLVED, message=msg,
        solver_stats=make_stats("solheim", "solved", dl.elapsed, len(sol.steps)),
        verification=ver, certificate=None, objective_value=float(np.trace(sol.Q)),
        extra={"solheim": sol}, **common)


def run_sdp_outputs(plant, target, common, Qn, solver, tol, seed, dl, settings=None):
    """Several outputs: the poles do not fix L.  L from the NLP (else, for a full Q, from the
    sequential method), then the fixed-gain SDP at that L gives the objective's optimum over
    that gain's (convex) family of Q -- a genuine SDP certificate that L is a Kalman gain with
    the target poles; verified as every design is."""
    nlp = run_nlp(plant, target, {**common, "method": "nlp"}, Qn, solver, tol, seed, dl, settings)
    L, source = (nlp.L, "the NLP") if nlp.success else (None, None)
    seq_msg = ""
    if L is None and common["structure"] == "full":
        try:
            sol = solheim(plant, target)
            if sol.success:
                L, source = sol.L, "Solheim's sequential method"
            else:
                seq_msg = f"; the sequential method: {sol.message}"
        except (ValidationError, RiccatiError) as exc:
            seq_msg = f"; the sequential method is not applicable: {exc}"
    if L is None:
        msg = (f"method='sdp' with {plant.p} outputs needs a Kalman gain with these poles, and none was "
               f"found: {nlp.message}{seq_msg}")
        return dataclasses.replace(nlp, message=msg)
    res = fixed_gain_design(plant, target, common, Qn, solver, tol, seed, dl, L=L)
    res.extra["L_source"] = source
    res.extra["nlp_message"] = nlp.message
    if res.success:
        msg = (f"L from {source} ({plant.p} outputs: the poles do not fix L), Q from the fixed-gain "
               + res.message)
        return dataclasses.replace(res, message=msg)
    if nlp.success:  # the SDP stage failed at a verified gain: the NLP's design is the answer
        msg = (f"method='sdp': the fixed-gain SDP at the NLP's gain gave no verified design "
               f"({res.message}); the NLP's design is returned: {nlp.message}")
        return dataclasses.replace(nlp, message=msg)
    return res



def _nlp_settings(nlp_options: Any) -> dict[str, Any]:
    """Validated ``nlp_options`` of :func:`kalman_for_poles`."""
    if nlp_options is None:
        return {}
    if not isinstance(nlp_options, dict) or not all(isinstance(k, str) for k in nlp_options):
        raise ValidationError(f"nlp_options must be a dict with string keys or None; found {nlp_options!r}")
    out = dict(nlp_options)
    der = out.get("derivatives", "closed_form")
    if der not in ("closed_form", "symbolic"):
        raise ValidationError(f"nlp_options['derivatives'] must be 'closed_form' or 'symbolic'; "
                              f"found {der!r}")
    bad = [k for k in out if k != "derivatives" and not k.startswith("ipopt.")]
    if bad:
        raise ValidationError(f"nlp_options keys must be 'derivatives' or 'ipopt.<option>'; found {bad[0]!r}")
    return out
