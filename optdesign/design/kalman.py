r"""The Kalman verbs, verified independently.

``kalman(plant)`` solves the filter Riccati equation (continuous or discrete by ``plant.dt``) with
one method and checks the answer with independent linear algebra: the relative Riccati residual,
the a posteriori forward error of P, the smallest eigenvalue of P, the stability margin of the
error dynamics ``A - L C``, and the difference from the *other* Riccati solver (scipy's
extended-pencil QZ versus the Hamiltonian/symplectic Schur method of seed 001 eq (25)-(27)).

The complete API of the peers (MATLAB ``kalman`` / ``kalmd``, python-control ``lqe`` / ``dlqe``):

* systems in: a Plant, a python-control or scipy state-space system (:mod:`optdesign.model.coerce`),
  with ``sensors`` / ``known`` selection of the measured outputs and known inputs;
* cross-covariance ``N = E[w v']`` (and the noise feedthrough ``H`` of a system,
  ``y = C x + D u + H w + v``), by the standard reduction below;
* discrete time in both forms: the predictor gain L (``x_hat[k+1|k]``, what ``dlqe`` returns) and
  the filter / current form (innovation gains ``M``, ``My`` and updated covariance ``Z``);
* :func:`kalmd`: a discrete filter for a continuous plant, ``Qd`` by Van Loan's matrix exponential,
  ``Rd = R / Ts``;
* :func:`kalman_finite_horizon`: time-varying discrete gains from the Riccati difference equation;
* systems out: ``KalmanFilter.estimator()`` (:mod:`optdesign.design.estimator`).

Cross-covariance (derivation).  With ``y = C x + D u + H w + v`` the measurement noise is
``v_bar = H w + v``, so the pair ``(w, v_bar)`` has ``R_bar = R + H N + N' H' + H Q H'`` and
``E[w v_bar'] = N_e = Q H' + N`` (MATLAB's ``N_bar = G N_e``).  Writing ``G w = G N_e R_bar^-1 v_bar +
G w_perp`` with ``w_perp`` uncorrelated with ``v_bar`` and ``v_bar = y - C x - D u`` a known signal,
the filter of ``(A, G, Q, N_e, R_bar)`` is the filter of the uncorrelated problem

    A_r = A - G N_e R_bar^-1 C,    Q_r = Q - N_e R_bar^-1 N_e'   (>= 0 iff [[Q, N], [N', R]] >= 0)

with the gain shifted by the known-signal term: ``L = L_r + G N_e R_bar^-1``, i.e.
continuous ``L = (P C' + G N_e) R_bar^-1``, discrete (predictor)
``L = (A P C' + G N_e)(C P C' + R_bar)^-1``; the error dynamics ``A - L C = A_r - L_r C``.  The
measurement update is unchanged, ``M = P C' (C P C' + R_bar)^-1``, ``Z = (I - M C) P``, and
``My = C M + H N_e (C P C' + R_bar)^-1`` (the output estimate ``E[C x + H w | y[0..k]]``).  The
residual check is computed on the unreduced cross-term equation (continuous
``A P + P A' - (P C' + G N_e) R_bar^-1 (P C' + G N_e)' + G Q G' = 0``), so a wrong reduction cannot
pass it.

References
----------
Seed 001 (Jung & Huh), eq (22)-(27).
Anderson, B. D. O. & Moore, J. B., *Optimal Filtering*, Prentice-Hall (1979), sec. 5.5
(correlated process and measurement noise).
MathWorks, *kalman* (https://www.mathworks.com/help/control/ref/ss.kalman.html): ``R_bar``,
``N_bar``, ``L = (P C' + N_bar) R_bar^-1``, discrete ``'current'`` / ``'delayed'`` estimators with
``L``, ``M``, ``P``, ``Z``; *kalmd* (https://www.mathworks.com/help/control/ref/ss.kalmd.html):
``Qd = int_0^Ts e^(A t) G Q G' e^(A' t) dt``, ``Rd = R / Ts``, ZOH discretization.
Van Loan, C. F., "Computing integrals involving the matrix exponential", IEEE TAC 23(3) (1978)
395-404.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any, cast

import numpy as np
import scipy.linalg
from numpy.typing import ArrayLike, NDArray

from .._deadline import Deadline, dense_time_refusal
from .._validate import as_int, as_matrix, as_positive_float, as_square, check_psd, sym_tol
from ..classical.riccati import RESIDUAL_TOL, filter_are, filter_are_error, filter_are_residual, sort_poles
from ..classical.sampling import van_loan
from ..errors import (
    ArgumentTypeError,
    NotPositiveDefiniteError,
    NotPositiveSemidefiniteError,
    RiccatiError,
    ValidationError,
)
from ..model.coerce import SystemData, as_system
from ..model.plant import Plant
from ..results import Check, DesignResult, Route, SolverStats, Stage, Status, Verification
from .estimator import estimator_of
from .verification import cross_check, forward_error_check, psd_check, psd_tolerance, stability_check

__all__ = ["KalmanFilter", "kalman", "kalmd", "van_loan", "KalmanSequence", "kalman_finite_horizon"]

_METHODS = ("scipy", "hamiltonian")
_EPS = float(np.finfo(float).eps)


def _cross_check(plant: Plant, P: NDArray, err: float, other: str) -> Check:
    """The other Riccati solver's P against ours, judged by both error estimates.  No residual
    test on the other solver: its inaccuracy shows up as a difference its estimate explains."""
    try:
        P_other = filter_are(plant, other, residual_tol=np.inf).P
    except RiccatiError as exc:
        return Check.at_most("cross_check", float("inf"), 0.0, f"{other} solver failed: {exc}")
    return cross_check(P, P_other, err, filter_are_error(plant, P_other).relative, other=other)


@dataclass(frozen=True, kw_only=True, eq=False)
class KalmanFilter(DesignResult):
    """Steady-state Kalman filter of a plant.

    Attributes
    ----------
    L : (n, p) ndarray
        Observer gain; the error dynamics are ``A - L C``.  Continuous: ``(P C' + G N) R^-1``;
        discrete: the predictor gain ``(A P C' + G N)(C P C' + R)^-1`` (``N = 0`` unless given;
        R and N are MATLAB's ``R_bar``, ``N_e`` when the system has a noise feedthrough H).
    P : (n, n) ndarray
        Steady-state error covariance (discrete: the a-priori / predicted covariance,
        ``E[(x - x_hat[k|k-1])(...)']``).
    poles : (n,) ndarray of complex
        ``eig(A - L C)``, sorted by real then imaginary part.
    residual : float
        Relative residual of the filter Riccati equation (``filter_are_residual``; with N, of the
        cross-term equation).
    Kf : (n, p) ndarray or None
        Discrete time: the filter (measurement-update, innovation) gain ``P C' (C P C' + R)^-1``
        (MATLAB's ``M``, also :attr:`M`); ``L = A Kf`` when N = 0.  None in continuous time.
    Z : (n, n) ndarray or None
        Discrete time: the updated covariance ``E[(x - x_hat[k|k])(...)'] = (I - M C) P`` (Joseph
        form, PSD by construction).
    My : (p, p) ndarray or None
        Discrete time: the output innovation gain of the current estimator (``C M`` without noise
        feedthrough).
    N : (m, p) ndarray or None
        The cross-covariance used (``Q H' + N`` with a noise feedthrough), None when zero.
    D, H : ndarray or None
        Feedthrough of the known inputs and of the noise of the system given (None when zero).
    plant : Plant
        The plant designed for (the measured outputs and known inputs selected).
    status : Status
        ``Status.SOLVED`` (failures to solve raise instead); ``TIME_LIMIT`` when the budget ran
        out before the cross-check.
    solver_stats : SolverStats
        ``backend`` is the method (``"scipy"`` or ``"hamiltonian"``); ``time`` the solve time;
        ``extra`` holds the cross-check method and its time.
    verification : Verification
        Independent checks (tolerances in :mod:`optdesign.design.verification`):
        ``riccati_residual`` (<= 1e-8), ``forward_error`` (the a posteriori error estimate of P,
        :func:`~optdesign.classical.riccati.filter_are_error`, <= 1e-6), ``P_min_eig`` (P is PSD
        to its forward error), ``stability_margin`` (``-max Re`` or ``1 - max |.|`` of
        ``eig(A - L C)`` recomputed from L must exceed the rounding level of those poles), and
        ``cross_check`` (relative difference from the other solver's P, within 4x the sum of
        the two solutions' error estimates -- so a difference explained by the *other*
        solver's inaccuracy passes; ``inf`` with the reason in ``detail`` if the other solver
        failed).
    extra : dict
        ``sensors``, ``known``, ``R_used`` (with a noise feedthrough), and for :func:`kalmd` the
        discretization (``Ts``, ``Qd``, ``Rd``, ``continuous_plant``).
    """

    L: NDArray[np.float64]
    P: NDArray[np.float64]
    poles: NDArray[np.complex128]
    residual: float
    Kf: NDArray[np.float64] | None
    plant: Plant
    Z: NDArray[np.float64] | None = None
    My: NDArray[np.float64] | None = None
    N: NDArray[np.float64] | None = None
    D: NDArray[np.float64] | None = None
    H: NDArray[np.float64] | None = None

    @property
    def method(self) -> str:
        """The Riccati method that produced ``P``."""
        return self.solver_stats.backend

    @property
    def M(self) -> NDArray[np.float64] | None:
        """The innovation gain (MATLAB's ``M``): the field ``Kf``."""
        return self.Kf

    def estimator(self, form: str | None = None, *, output: str = "auto", io: str = "optdesign") -> Any:
        """The filter as a system, inputs ``[u; y]``, outputs ``[y_hat; x_hat]``
        (:func:`~optdesign.design.estimator.estimator_system`): ``form`` ``"continuous"``,
        ``"predictor"`` (discrete default, MATLAB's ``'delayed'``) or ``"filter"`` (``'current'``).
        ``io="control"``: python-control's layout, inputs ``[y; u]``, output ``x_hat`` (for
        ``control.create_statefbk_iosystem(sys, K, estimator=...)``)."""
        return estimator_of(self, form=form, output=output, io=io)

    def summary(self) -> str:
        """Multi-line human-readable report (used by ``optdesign kalman``)."""
        plant = self.plant
        label = f" {plant.name!r}" if plant.name else ""
        time_kind = f"discrete, dt = {plant.dt:g}" if plant.is_discrete else "continuous"
        if self.extra.get("dt_unspecified"):
            time_kind += " (dt=True: unspecified, taken as 1)"
        lines = [
            f"Kalman filter for plant{label} ({time_kind}, n = {plant.n}, p = {plant.p}, m = {plant.m})",
            f"  method: {self.method}   status: {self.status}   success: {self.success}",
        ]
        if self.route:
            lines.append(f"  route: {self.route}")

        def block(name: str, X: NDArray) -> None:
            with np.printoptions(precision=6, suppress=False, linewidth=100):
                body = np.array2string(np.asarray(X), prefix="  " + name + " = ")
            lines.append(f"  {name} = {body}")

        block("L", self.L)
        if self.Kf is not None:
            block("Kf", self.Kf)
        block("P", self.P)
        if self.Z is not None:
            block("Z", self.Z)
        if self.N is not None:
            block("N", self.N)
        poles = ", ".join(f"{complex(z).real:.6g}{complex(z).imag:+.6g}j" if complex(z).imag
                          else f"{complex(z).real:.6g}" for z in self.poles)
        lines.append(f"  poles of A - L C: {poles}")
        lines.append(f"  Riccati residual (relative): {self.residual:.3e}")
        lines.append(f"  {self.message}")
        lines.append("  verification:")
        lines.extend("    " + str(c) for c in self.verification)
        return "\n".join(lines)

    def __repr__(self) -> str:
        return (f"KalmanFilter(plant={self.plant!r}, method={self.method!r}, "
                f"status={self.status.value!r}, success={self.success}, residual={self.residual:.2e})")


# ------------------------------------------------------------------ noise data
def _psd_clip(X: NDArray) -> NDArray:
    """Symmetric part with negative eigenvalues set to 0 (for rounding-level negatives only)."""
    lam, U = np.linalg.eigh(0.5 * (X + X.T))
    Y = (U * np.maximum(lam, 0.0)) @ U.T
    return 0.5 * (Y + Y.T)


def _noise_matrices(plant: Plant) -> tuple[NDArray, NDArray]:
    """``(Q, R)`` of a plant that must have both (a ValidationError naming what is missing)."""
    plant.require_noise_model()
    return cast(NDArray, plant.Q), cast(NDArray, plant.R)


def _noise_data(plant: Plant, N: ArrayLike | None, H: NDArray | None) -> tuple[NDArray | None, NDArray]:
    """The cross-covariance ``N_e = Q H' + N`` (None when zero) and ``R_bar = R + H N + N' H' + H Q H'``.

    Raises NotPositiveSemidefiniteError when ``[[Q, N], [N', R]]`` is indefinite and
    NotPositiveDefiniteError when ``R_bar`` is singular."""
    Q, R = _noise_matrices(plant)
    m, p = plant.m, plant.p
    if N is None and H is None:
        return None, R
    N0 = np.zeros((m, p)) if N is None else as_matrix("N", N, (m, p))
    J = np.block([[Q, N0], [N0.T, R]])
    lmin = float(np.linalg.eigvalsh(J)[0])
    if lmin < -sym_tol(J):
        raise NotPositiveSemidefiniteError(
            f"N makes the joint covariance [[Q, N], [N', R]] of (w, v) indefinite: smallest eigenvalue "
            f"{lmin:.6g} (it must be positive semidefinite, i.e. Q - N R^-1 N' >= 0)")
    if H is None:
        return (N0 if np.any(N0) else None), R
    Ne = Q @ H.T + N0
    Rb = R + H @ N0 + N0.T @ H.T + H @ Q @ H.T
    Rb = 0.5 * (Rb + Rb.T)
    lr = float(np.linalg.eigvalsh(Rb)[0])
    if not lr > sym_tol(Rb):
        raise NotPositiveDefiniteError(
            f"the effective measurement-noise covariance R + H N + N' H' + H Q H' (H: the noise "
            f"feedthrough, the noise columns of sys.D) must be positive definite; found smallest "
            f"eigenvalue {lr:.6g}")
    return (Ne if np.any(Ne) else None), Rb


def _reduced_plant(plant: Plant, Ne: NDArray | None, Rb: NDArray) -> Plant:
    """The uncorrelated problem ``A_r = A - G N_e R^-1 C``, ``Q_r = Q - N_e R^-1 N_e'`` (R = R_bar)."""
    if Ne is None:
        return plant if Rb is plant.R else plant.replace(R=Rb)
    K = np.linalg.solve(Rb, Ne.T).T                       # N_e R^-1, (m, p)
    Qr = _psd_clip(_noise_matrices(plant)[0] - K @ Ne.T)    # >= 0 to rounding: [[Q, N], [N', R]] >= 0
    return plant.replace(A=plant.A - plant.G @ K @ plant.C, Q=Qr, R=Rb)


def _cross_residual(plant: Plant, P: NDArray, Ne: NDArray, Rb: NDArray) -> float:
    """Relative residual of the unreduced cross-term filter equation (normalized as
    :func:`filter_are_residual`)."""
    A, C, G = plant.A, plant.C, cast(NDArray, plant.G)
    W = G @ _noise_matrices(plant)[0] @ G.T
    Sc = G @ Ne
    if plant.is_discrete:
        K = A @ P @ C.T + Sc
        corr = K @ np.linalg.solve(C @ P @ C.T + Rb, K.T)
        APA = A @ P @ A.T
        res, terms = APA - corr + W - P, [APA, corr, W, P]
    else:
        K = P @ C.T + Sc
        corr = K @ np.linalg.solve(Rb, K.T)
        AP = A @ P
        res, terms = AP + AP.T - corr + W, [AP, AP.T, corr, W]
    num = float(np.linalg.norm(res))
    den = float(sum(np.linalg.norm(t) for t in terms))
    return 0.0 if num == 0.0 else (num / den if den > 0 else float("inf"))


# ------------------------------------------------------------------ the verb
def kalman(plant: Any, *, method: str = "scipy", Q: ArrayLike | None = None, R: ArrayLike | None = None,
           G: ArrayLike | None = None, N: ArrayLike | None = None, sensors: Any = None, known: Any = None,
           time_limit: float | None = None) -> KalmanFilter:
    """Steady-state Kalman filter of a plant (continuous or discrete by ``plant.dt``).

    Continuous (seed 001 eq (23)-(24); with N see the module notes)::

        A P + P A' - P C' R^-1 C P + G Q G' = 0,    L = P C' R^-1

    Discrete (predictor form; the filter form beside it)::

        P = A P A' - A P C'(C P C' + R)^-1 C P A' + G Q G',
        L = A P C'(C P C' + R)^-1,    M = Kf = P C'(C P C' + R)^-1,    Z = (I - M C) P

    Parameters
    ----------
    plant : Plant, control.StateSpace or scipy.signal StateSpace / lti / dlti
        With Q (m, m) and R (p, p), carried or given here.
    method : {"scipy", "hamiltonian"}
        Riccati solver; the other one is run as an independent cross-check, and as the fallback
        when the first fails (:class:`RiccatiError`: inaccurate or no answer).  ``route`` says
        which ran and which answered.
    Q, R, G : array_like, optional
        Noise data where ``plant`` does not carry them (:func:`optdesign.model.coerce.as_system`).
        For a *system* (not a Plant) without ``G=`` / ``known=``, how the noise enters follows
        the peers (the rule of :mod:`optdesign.model.coerce`, said in ``extra["notes"]``): Q the
        size of the system's inputs -- the noise enters through ``sys.B`` (python-control's
        ``lqe(sys, QN, RN)``); Q smaller -- the *last* ``len(Q)`` inputs are the noise, the others
        known (MATLAB's ``kalman(sys, Qn, Rn)``); Q larger and n x n -- every state (``G = I``,
        the library's convention, said); otherwise refused, asking for ``G=`` or ``known=``.  A system with ``dt=True`` is
        designed with ``dt = 1`` (said in the message and ``extra["dt_unspecified"]``).
    N : (m, p) array_like, optional
        Cross-covariance ``E[w v']`` (``control.lqe(..., NN)``, MATLAB ``kalman(sys, Q, R, N)``);
        ``[[Q, N], [N', R]]`` must be positive semidefinite.
    sensors : sequence of int, optional
        0-based indices of the measured outputs (MATLAB's ``sensors``); R is theirs.
    known : sequence of int, optional
        0-based indices of the known inputs of a system; the others are the process noise w (their
        columns of ``sys.B`` are G, of ``sys.D`` the noise feedthrough H, folded into R and N).
    time_limit : float, optional
        Seconds.  When the solve itself uses it up, the independent cross-check is not run and
        the status is ``time_limit`` (the filter is returned, not verified).  A Riccati solve
        (one LAPACK call: it cannot be stopped) whose calibrated estimate
        (:func:`~optdesign._deadline.dense_time_refusal`) alone exceeds the limit is not started:
        a ``ValidationError`` naming ``time_limit`` and the estimate.

    Returns
    -------
    KalmanFilter
        ``status`` is ``Status.SOLVED``; ``success`` is true when every independent check passes.
        ``.estimator()`` gives the filter as a system.

    Raises
    ------
    ArgumentTypeError
        ``plant`` is not a Plant or a state-space system (a transfer function: with how to convert
        it, ``control.ss(sys)``); a ``TypeError`` and a ``ValidationError``.
    ValidationError
        ``time_limit`` shorter than the estimated time of the Riccati solve alone (the message
        gives the estimate); ``plant`` has no Q or no R, ``method`` is unknown, bad ``sensors`` /
        ``known`` (named), Q with more rows than a system has inputs, not n x n, and neither ``G=``
        nor ``known=``.
    NotPositiveSemidefiniteError
        N makes ``[[Q, N], [N', R]]`` indefinite.
    NotPositiveDefiniteError
        R (or ``R + H N + N' H' + H Q H'``) is not positive definite.
    DimensionError
        N not (m, p).
    NotObservableError
        (C, A) is not detectable; the message and ``.modes`` name the undetectable modes.
    RiccatiError
        No stabilizing solution: a mode on the imaginary axis / unit circle not excited by the
        process noise (named), or the solver failed / was inaccurate (the message says why).

    References
    ----------
    Seed 001 (Jung & Huh), eq (22)-(27); MathWorks *kalman* reference page; Anderson & Moore (1979).

    Examples
    --------
    >>> from optdesign import Plant, kalman
    >>> kf = kalman(Plant([[0., 1.], [0., 0.]], [[1., 0.]], G=[[0.], [1.]], Q=[[4.]], R=[[0.25]]))
    >>> kf.L.round(6).ravel().tolist()    # [sqrt2 (q/r)^(1/4), sqrt(q/r)]
    [2.828427, 4.0]
    """
    if method not in _METHODS:
        raise ValidationError(f"method must be one of {_METHODS}; found {method!r}")
    deadline = Deadline(time_limit)
    data = as_system(plant, G=G, Q=Q, R=R, sensors=sensors, known=known)
    return _steady_filter(data, method, N, deadline)


def _steady_filter(data: SystemData, method: str, N: ArrayLike | None, deadline: Deadline,
                   extra: dict[str, Any] | None = None) -> KalmanFilter:
    """Solve, verify and package the steady-state filter of a converted system."""
    plant = data.plant
    _refuse_long_solve(method, plant.n, deadline)
    Ne, Rb = _noise_data(plant, N, data.H)
    work = _reduced_plant(plant, Ne, Rb)
    t0 = time.perf_counter()
    res, method, route = _solve_with_fallback(work, method)
    elapsed = time.perf_counter() - t0
    P = res.P
    shift = None if Ne is None else plant.G @ np.linalg.solve(Rb, Ne.T).T      # G N_e R^-1
    L = res.L if shift is None else res.L + shift
    C = plant.C

    other = _METHODS[1] if method == _METHODS[0] else _METHODS[0]
    err = filter_are_error(work, P)
    t1 = time.perf_counter()
    if deadline.expired:
        cross = Check.at_most("cross_check", float("inf"), 0.0,
                              f"not run: the time limit ({deadline}) ran out")
    else:
        cross = _cross_check(work, P, err.relative, other)
    cross_time = time.perf_counter() - t1

    if Ne is None:
        residual = filter_are_residual(work, P)
        what = "relative residual of the filter Riccati equation"
    else:
        residual = _cross_residual(plant, P, Ne, Rb)
        what = "relative residual of the cross-term filter Riccati equation (unreduced, with N)"
    checks = [
        Check.at_most("riccati_residual", residual, RESIDUAL_TOL, what),
        forward_error_check(err),
        psd_check("P_min_eig", P, error=min(err.relative, 1.0), what="P"),
        stability_check(plant.A - L @ C, plant.is_discrete),
        cross,
    ]
    Z = My = None
    if plant.is_discrete:
        S = C @ P @ C.T + Rb
        M = cast(NDArray, res.Kf)
        F = np.eye(plant.n) - M @ C
        Z = F @ P @ F.T + M @ Rb @ M.T
        Z = 0.5 * (Z + Z.T)
        My = C @ M if data.H is None or Ne is None else C @ M + data.H @ np.linalg.solve(S, Ne.T).T
    verification = Verification.of(checks)
    kind = "discrete" if plant.is_discrete else "continuous"
    message = f"steady-state {kind} Kalman filter by the {method} Riccati solver"
    if len(route) > 1:
        message += f" (fallback: the {route[0].name} solver failed)"
    if Ne is not None:
        message += " with cross-covariance N"
    if data.notes:
        message += "; " + "; ".join(data.notes)
    if verification.passed:
        message += "; all independent checks passed"
    else:
        message += "; failed checks: " + ", ".join(c.name for c in verification.failed)
    stats = SolverStats(backend=method, native_status="solved", time=elapsed,
                        extra={"cross_check_method": other, "cross_check_time": cross_time})
    info: dict[str, Any] = {"sensors": data.sensors, "known": data.known, **(extra or {})}
    if data.notes:
        info["notes"] = data.notes
    if data.dt_unspecified:
        info["dt_unspecified"] = True
    if data.H is not None:
        info["R_used"] = Rb
    poles = sort_poles(np.linalg.eigvals(plant.A - L @ C)) if shift is not None else res.poles
    return KalmanFilter(L=L, P=P, poles=poles, residual=residual, Kf=res.Kf, plant=plant, Z=Z, My=My,
                        N=Ne, D=data.D, H=data.H,
                        status=Status.TIME_LIMIT if deadline.expired else Status.SOLVED,
                        message=message, solver_stats=stats, verification=verification, extra=info,
                        route=route)


def _refuse_long_solve(method: str, n: int, deadline: Deadline) -> None:
    """Raise when the Riccati solve alone (one LAPACK call: it cannot be stopped) is estimated to
    outlast the time left (:func:`~optdesign._deadline.dense_time_refusal`; issue 26: hours at
    n = 5000 under ``time_limit=5``)."""
    why = dense_time_refusal([("care_qz" if method == "scipy" else "hamiltonian_schur", n)], deadline,
                             f"the {method} Riccati solve at n = {n}")
    if why:
        raise ValidationError(f"time_limit={deadline.limit:g} s cannot be kept: {why}; give time_limit=None "
                              f"(or a longer one) to run it")


def _stage_kind(method: str) -> str:
    """scipy's solvers are a library backend; the Hamiltonian/symplectic Schur method is ours."""
    return "backend" if method == "scipy" else "engine"


def _solve_with_fallback(work: Plant, method: str) -> tuple[Any, str, Route]:
    """``filter_are`` by ``method``; on a :class:`RiccatiError` (no accurate answer) once more by the
    other method.  Returns the answer, the method that gave it and the route.  Both failing raises
    the first error (the second's reason appended).  A :class:`NotObservableError` is a property of
    the data, not of the solver: it propagates at once."""
    t0 = time.process_time()
    try:
        res = filter_are(work, method)
    except RiccatiError as first:
        failed = Stage(method, _stage_kind(method), "failed", _short(str(first)), time.process_time() - t0)
        other = _METHODS[1] if method == _METHODS[0] else _METHODS[0]
        t1 = time.process_time()
        try:
            res = filter_are(work, other)
        except RiccatiError as second:
            raise RiccatiError(f"{first} (the {other} solver failed too: {second})") from first
        return res, other, Route([failed, Stage(other, "fallback", "answered", "after a RiccatiError",
                                                time.process_time() - t1)])
    return res, method, Route([Stage(method, _stage_kind(method), "answered", "", time.process_time() - t0)])


def _short(text: str, limit: int = 120) -> str:
    return text if len(text) <= limit else text[:limit - 3] + "..."


# ------------------------------------------------------------------ kalmd
def kalmd(plant: Any, Ts: float, *, method: str = "scipy", Q: ArrayLike | None = None,
          R: ArrayLike | None = None, G: ArrayLike | None = None, N: ArrayLike | None = None,
          sensors: Any = None, known: Any = None, time_limit: float | None = None) -> KalmanFilter:
    r"""Discrete Kalman filter for a continuous plant (MATLAB's ``kalmd``).

    The plant is discretized with a zero-order hold at period ``Ts`` (``Ad = e^(A Ts)``,
    ``Bd = int_0^Ts e^(A t) dt B``), the noise by its discrete equivalents

        Qd = int_0^Ts e^(A t) G Q G' e^(A' t) dt   (Van Loan's matrix exponential, :func:`van_loan`),
        Rd = R / Ts,

    and :func:`kalman` designs the discrete filter (both forms: L, M, P, Z).  No cross-covariance
    (as MATLAB's kalmd).

    Parameters
    ----------
    plant : Plant, control.StateSpace or scipy.signal system
        Continuous.
    Ts : float
        Sampling period, > 0.
    method, Q, R, G, sensors, known, time_limit
        As :func:`kalman`.
    N : None
        Not supported (MATLAB's kalmd has no N either): a continuous cross-covariance has no
        discrete equivalent of the form ``Rd = R / Ts``.  Given, it raises
        :class:`~optdesign.errors.ArgumentTypeError` saying what to do instead.

    Returns
    -------
    KalmanFilter
        For the discretized plant (``plant.dt = Ts``, ``G = I``, ``Q = Qd``, ``R = Rd``);
        ``extra`` holds ``Ts``, ``Qd``, ``Rd`` and ``continuous_plant``.

    Raises
    ------
    ArgumentTypeError
        ``N`` given (a ``TypeError``, as an unknown keyword would be, and a ``ValidationError``).
    ValidationError
        ``Ts`` not a finite number > 0; a discrete plant; a noise feedthrough H from ``known``
        (kalmd has no N); and everything :func:`kalman` raises.

    References
    ----------
    MathWorks, *kalmd* reference page; Van Loan (1978); Franklin, Powell & Workman, *Digital
    Control of Dynamic Systems* (1998).

    Examples
    --------
    >>> from optdesign import Plant, kalmd
    >>> plant = Plant([[0., 1.], [0., 0.]], [[1., 0.]], G=[[0.], [1.]], Q=[[1.]], R=[[0.01]])
    >>> kf = kalmd(plant, 0.1)                      # sampled at 0.1 s
    >>> kf.success, kf.L.round(4).ravel().tolist()
    (True, [0.4406, 0.7996])
    """
    if method not in _METHODS:
        raise ValidationError(f"method must be one of {_METHODS}; found {method!r}")
    if N is not None:
        raise ArgumentTypeError(
            "kalmd has no cross-covariance N (as MATLAB's kalmd): a continuous E[w v'] has no discrete "
            "equivalent of the form Rd = R / Ts; discretize the plant and its noise yourself and call "
            "kalman(discrete_plant, N=Nd), or design the continuous filter with kalman(plant, N=N)")
    deadline = Deadline(time_limit)
    Ts = as_positive_float("Ts", Ts)
    data = as_system(plant, G=G, Q=Q, R=R, sensors=sensors, known=known)
    cp = data.plant
    if cp.is_discrete:
        raise ValidationError(f"kalmd needs a continuous plant; found a discrete one (dt = {cp.dt:g}): use "
                              f"kalman(plant) directly")
    if data.H is not None:
        raise ValidationError("kalmd has no cross-covariance: the noise inputs selected by known feed "
                              "through to the outputs (H = the noise columns of sys.D is nonzero); "
                              "discretize yourself and call kalman(..., N=...)")
    _, R = _noise_matrices(cp)
    n = cp.n
    _refuse_long_solve(method, n, deadline)   # before the discretization (a matrix exponential of 2n)
    Ad, Qd = van_loan(cp.A, cp.process_noise(), Ts)
    Bd = None
    if cp.B is not None:
        nu = cp.B.shape[1]
        Z = np.zeros((n + nu, n + nu))
        Z[:n, :n], Z[:n, n:] = cp.A, cp.B
        Bd = scipy.linalg.expm(Z * Ts)[:n, n:]
    Rd = R / Ts
    dp = Plant(Ad, cp.C, Q=Qd, R=Rd, dt=Ts, B=Bd, name=cp.name)
    disc = SystemData(dp, D=data.D, sensors=data.sensors, known=data.known, source=data.source,
                      notes=data.notes)
    return _steady_filter(disc, method, None, deadline,
                          extra={"Ts": Ts, "Qd": Qd, "Rd": Rd, "continuous_plant": cp})


# ------------------------------------------------------------------ finite horizon
@dataclass(frozen=True, kw_only=True, eq=False)
class KalmanSequence(DesignResult):
    """Time-varying discrete Kalman filter over a finite horizon (:func:`kalman_finite_horizon`).

    Attributes
    ----------
    k : (K,) ndarray of int
        Steps ``0 .. steps`` (fewer when the time limit ran out).
    P : (K, n, n) ndarray
        A-priori covariances ``P_k = E[(x_k - x_hat[k|k-1])(...)']``, ``P_0`` as given.
    Z : (K, n, n) ndarray
        Updated covariances ``(I - M_k C) P_k``.
    L : (K, n, p) ndarray
        Predictor gains ``(A P_k C' + G N)(C P_k C' + R)^-1``.
    M : (K, n, p) ndarray
        Innovation gains ``P_k C' (C P_k C' + R)^-1``.
    plant : Plant
    N : (m, p) ndarray or None
    error_estimate : float
        ``max_k ||P_k - P_k^std||_F / max_k ||P_k||_F``: the Joseph-form recursion (returned) against
        the standard form run independently.
    verification : Verification
        ``nonfinite`` (0), ``P_min_eig`` (``min_k lambda_min(P_k) / max_k ||P_k|| >=
        -(error_estimate + 10 n eps)``), ``error_estimate`` (<= ``tol``).
    """

    k: NDArray[np.int64]
    P: NDArray[np.float64]
    Z: NDArray[np.float64]
    L: NDArray[np.float64]
    M: NDArray[np.float64]
    plant: Plant
    N: NDArray[np.float64] | None = None
    error_estimate: float = float("nan")

    @property
    def times(self) -> NDArray[np.float64]:
        """``k dt``."""
        return np.asarray(self.k * float(self.plant.dt or 0.0), dtype=float)

    def __len__(self) -> int:
        return int(self.k.shape[0])

    def __repr__(self) -> str:
        return (f"KalmanSequence(n={self.plant.n}, steps={len(self) - 1}, error~{self.error_estimate:.1e}, "
                f"status={Status(self.status).value}, success={self.success})")


def kalman_finite_horizon(plant: Any, P0: ArrayLike, steps: int, *, Q: ArrayLike | None = None,
                          R: ArrayLike | None = None, G: ArrayLike | None = None, N: ArrayLike | None = None,
                          sensors: Any = None, known: Any = None, tol: float = 1e-8,
                          time_limit: float | None = None) -> KalmanSequence:
    r"""Time-varying discrete Kalman gains from the Riccati difference equation.

    From the a-priori covariance ``P_0`` of step 0, for ``k = 0, 1, ..., steps``::

        S_k = C P_k C' + R,   L_k = (A P_k C' + G N) S_k^-1,   M_k = P_k C' S_k^-1,
        Z_k = (I - M_k C) P_k (I - M_k C)' + M_k R M_k',
        P_{k+1} = (A - L_k C) P_k (A - L_k C)' + [G, -L_k] [[Q, N], [N', R]] [G, -L_k]'

    -- the Joseph forms, sums of PSD terms -- equal to the standard
    ``P_{k+1} = A P_k A' + G Q G' - L_k S_k L_k'``, which is run beside as the error estimate.  With
    ``N = 0`` this is the recursion of :func:`optdesign.riccati_de` on a discrete plant, and it
    converges to :func:`kalman`'s P, L, M, Z.  (The continuous finite-horizon filter is
    :func:`optdesign.riccati_de`.)

    Parameters
    ----------
    plant : Plant or state-space system
        Discrete, with Q and R (or given here).
    P0 : (n, n) array_like
        Symmetric PSD.
    steps : int
        Number of recursion steps, >= 1.
    Q, R, G, N, sensors, known
        As :func:`kalman` (a noise feedthrough folds into R and N the same way).
    tol : float
        Accuracy the ``error_estimate`` check demands.
    time_limit : float, optional
        Seconds; no new step starts once it is spent (status ``time_limit``, the steps computed).

    Returns
    -------
    KalmanSequence

    Raises
    ------
    ValidationError
        A continuous plant (use ``riccati_de``), ``steps`` not an integer >= 1, ``tol`` not > 0, and
        the noise-data errors of :func:`kalman`.
    DimensionError, NotSymmetricError, NotPositiveSemidefiniteError
        Bad P0 (named).

    Examples
    --------
    >>> from optdesign import Plant, kalman, kalman_finite_horizon
    >>> plant = Plant([[1.0]], [[1.0]], Q=[[0.1]], R=[[1.0]], dt=1.0)   # a random walk
    >>> seq = kalman_finite_horizon(plant, [[1.0]], 50)                # from P0 = 1
    >>> float(seq.L[0, 0, 0]), round(float(seq.L[-1, 0, 0]), 4)        # -> the steady-state gain
    (0.5, 0.2702)
    >>> round(float(kalman(plant).L[0, 0]), 4)
    0.2702
    """
    deadline = Deadline(time_limit)
    data = as_system(plant, G=G, Q=Q, R=R, sensors=sensors, known=known)
    pl = data.plant
    if not pl.is_discrete:
        raise ValidationError("kalman_finite_horizon is for discrete plants; the plant is continuous: use "
                              "optdesign.riccati_de(plant, P0, t_final) (the Riccati differential equation)")
    Q, _ = _noise_matrices(pl)
    steps = as_int("steps", steps, 1)
    tol = as_positive_float("tol", tol)
    n, p = pl.n, pl.p
    P0 = check_psd("P0", as_square("P0", P0, n))
    Ne, Rb = _noise_data(pl, N, data.H)
    A, C, G_ = pl.A, pl.C, cast(NDArray, pl.G)
    Nm = np.zeros((pl.m, p)) if Ne is None else Ne
    J = np.block([[Q, Nm], [Nm.T, Rb]])
    W, Sc = G_ @ Q @ G_.T, G_ @ Nm
    t0 = time.perf_counter()
    Ps, Zs, Ls, Ms, Pstd = [P0], [], [], [], [P0]
    P, Pq = P0, P0
    for k in range(steps + 1):
        S = C @ P @ C.T + Rb
        M = np.linalg.solve(S, C @ P).T
        Lk = np.linalg.solve(S, (A @ P @ C.T + Sc).T).T
        F = np.eye(n) - M @ C
        Zk = F @ P @ F.T + M @ Rb @ M.T
        Zs.append(0.5 * (Zk + Zk.T))
        Ls.append(Lk)
        Ms.append(M)
        if k == steps or deadline.expired:
            break
        E = A - Lk @ C
        GL = np.hstack([G_, -Lk])
        P = E @ P @ E.T + GL @ J @ GL.T
        P = 0.5 * (P + P.T)
        Ps.append(P)
        Sq = C @ Pq @ C.T + Rb
        Kq = A @ Pq @ C.T + Sc
        Pq = A @ Pq @ A.T + W - Kq @ np.linalg.solve(Sq, Kq.T)
        Pq = 0.5 * (Pq + Pq.T)
        Pstd.append(Pq)
    elapsed = time.perf_counter() - t0
    K = len(Zs)
    Parr, Zarr = np.array(Ps[:K]), np.array(Zs)
    big = float(np.max(np.linalg.norm(Parr, axis=(1, 2))))
    diff = float(np.max(np.linalg.norm(Parr - np.array(Pstd[:K]), axis=(1, 2))))
    err = diff / big if big > 0 else diff
    bad = int(np.sum(~np.isfinite(Parr))) + int(np.sum(~np.isfinite(Zarr)))
    lmin = min(float(np.min(np.linalg.eigvalsh(Parr))), float(np.min(np.linalg.eigvalsh(Zarr))))
    checks = [
        Check.at_most("nonfinite", bad, 0, "non-finite entries of P and Z"),
        Check.at_least("P_min_eig", lmin / big if big > 0 else 0.0, psd_tolerance(P0, err),
                       "min_k lambda_min(P_k, Z_k) / max_k ||P_k||_F (they must be PSD)"),
        Check.at_most("error_estimate", err, tol,
                      "max_k ||P_k (Joseph form) - P_k (standard form)||_F / max_k ||P_k||_F"),
    ]
    complete = K == steps + 1
    status = Status.SOLVED if complete else Status.TIME_LIMIT
    message = (f"discrete Riccati recursion over {steps} steps" if complete else
               f"time limit reached: {K - 1} of {steps} steps computed")
    return KalmanSequence(k=np.arange(K), P=Parr, Z=Zarr, L=np.array(Ls), M=np.array(Ms), plant=pl, N=Ne,
                          error_estimate=err, status=status, message=message,
                          solver_stats=SolverStats(backend="numpy", native_status="recursion", time=elapsed,
                                                   iterations=K - 1),
                          verification=Verification.of(checks), extra={"sensors": data.sensors,
                                                                       "known": data.known})
