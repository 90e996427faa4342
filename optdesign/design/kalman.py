"""The ``kalman`` verb: the steady-state Kalman filter of a plant, verified independently.

``kalman(plant)`` solves the filter Riccati equation (continuous or discrete by
``plant.dt``) with one method and checks the answer with independent linear algebra: the
relative Riccati residual, the smallest eigenvalue of P, the stability margin of the error
dynamics ``A - L C``, and the difference from the *other* Riccati solver (scipy's
extended-pencil QZ versus the Hamiltonian/symplectic Schur method of seed 001 eq (25)-(27)).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from .._deadline import Deadline
from ..classical.riccati import RESIDUAL_TOL, filter_are, filter_are_error, filter_are_residual
from ..errors import RiccatiError, ValidationError
from ..model.plant import Plant
from ..results import Check, ResultMixin, SolverStats, Status, Verification
from .verification import cross_check, forward_error_check, psd_check, stability_check

__all__ = ["KalmanFilter", "kalman"]

_METHODS = ("scipy", "hamiltonian")


def _cross_check(plant: Plant, P: NDArray, err: float, other: str) -> Check:
    """The other Riccati solver's P against ours, judged by both error estimates.  No residual
    test on the other solver: its inaccuracy shows up as a difference its estimate explains."""
    try:
        P_other = filter_are(plant, other, residual_tol=np.inf).P
    except RiccatiError as exc:
        return Check.at_most("cross_check", float("inf"), 0.0, f"{other} solver failed: {exc}")
    return cross_check(P, P_other, err, filter_are_error(plant, P_other).relative, other=other)


@dataclass(frozen=True, eq=False)
class KalmanFilter(ResultMixin):
    """Steady-state Kalman filter of a plant.

    Attributes
    ----------
    L : (n, p) ndarray
        Observer gain; the error dynamics are ``A - L C``.  Continuous: ``P C' R^-1``;
        discrete: the predictor gain ``A P C' (C P C' + R)^-1``.
    P : (n, n) ndarray
        Steady-state error covariance (discrete: the a-priori / predicted covariance).
    poles : (n,) ndarray of complex
        ``eig(A - L C)``, sorted by real then imaginary part.
    residual : float
        Relative residual of the filter Riccati equation (``filter_are_residual``).
    Kf : (n, p) ndarray or None
        Discrete time: the filter (measurement-update) gain ``P C' (C P C' + R)^-1``,
        ``L = A Kf``.  None in continuous time.
    plant : Plant
    status : Status
        ``Status.SOLVED`` (failures to solve raise instead).
    message : str
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
    """

    L: NDArray[np.float64]
    P: NDArray[np.float64]
    poles: NDArray[np.complex128]
    residual: float
    Kf: NDArray[np.float64] | None
    plant: Plant
    status: Status
    message: str
    solver_stats: SolverStats
    verification: Verification

    @property
    def method(self) -> str:
        """The Riccati method that produced ``P``."""
        return self.solver_stats.backend

    def summary(self) -> str:
        """Multi-line human-readable report (used by ``optdesign kalman``)."""
        plant = self.plant
        label = f" {plant.name!r}" if plant.name else ""
        time_kind = f"discrete, dt = {plant.dt:g}" if plant.is_discrete else "continuous"
        lines = [
            f"Kalman filter for plant{label} ({time_kind}, n = {plant.n}, p = {plant.p}, m = {plant.m})",
            f"  method: {self.method}   status: {self.status}   success: {self.success}",
        ]

        def block(name: str, X: NDArray) -> None:
            with np.printoptions(precision=6, suppress=False, linewidth=100):
                body = np.array2string(np.asarray(X), prefix="  " + name + " = ")
            lines.append(f"  {name} = {body}")

        block("L", self.L)
        if self.Kf is not None:
            block("Kf", self.Kf)
        block("P", self.P)
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


def kalman(plant: Plant, *, method: str = "scipy", time_limit: float | None = None) -> KalmanFilter:
    """Steady-state Kalman filter of a plant (continuous or discrete by ``plant.dt``).

    Continuous (seed 001 eq (23)-(24))::

        A P + P A' - P C' R^-1 C P + G Q G' = 0,    L = P C' R^-1

    Discrete (predictor form)::

        P = A P A' - A P C'(C P C' + R)^-1 C P A' + G Q G',
        L = A P C'(C P C' + R)^-1,    Kf = P C'(C P C' + R)^-1

    Parameters
    ----------
    plant : Plant
        With Q (m, m) and R (p, p).
    method : {"scipy", "hamiltonian"}
        Riccati solver; the other one is run as an independent cross-check.
    time_limit : float, optional
        Seconds.  When the solve itself uses it up, the independent cross-check is not run and
        the status is ``time_limit`` (the filter is returned, not verified).

    Returns
    -------
    KalmanFilter
        ``status`` is ``Status.SOLVED``; ``success`` is true when every independent check passes.

    Raises
    ------
    ValidationError
        ``plant`` is not a Plant, has no Q or no R, or ``method`` is unknown.
    NotObservableError
        (C, A) is not detectable; the message and ``.modes`` name the undetectable modes.
    RiccatiError
        No stabilizing solution: a mode on the imaginary axis / unit circle not excited by the
        process noise (named), or the solver failed / was inaccurate (the message says why).

    References
    ----------
    Seed 001 (Jung & Huh), eq (22)-(27).

    Examples
    --------
    >>> from optdesign import Plant, kalman
    >>> kf = kalman(Plant([[0., 1.], [0., 0.]], [[1., 0.]], G=[[0.], [1.]], Q=[[4.]], R=[[0.25]]))
    >>> kf.L.round(6).ravel().tolist()    # [sqrt2 (q/r)^(1/4), sqrt(q/r)]
    [2.828427, 4.0]
    """
    if not isinstance(plant, Plant):
        raise ValidationError(f"plant must be an optdesign.Plant; found {type(plant).__name__}")
    if method not in _METHODS:
        raise ValidationError(f"method must be one of {_METHODS}; found {method!r}")
    deadline = Deadline(time_limit)
    t0 = time.perf_counter()
    res = filter_are(plant, method)
    elapsed = time.perf_counter() - t0

    other = _METHODS[1] if method == _METHODS[0] else _METHODS[0]
    err = filter_are_error(plant, res.P)
    t1 = time.perf_counter()
    if deadline.expired:
        cross = Check.at_most("cross_check", float("inf"), 0.0,
                              f"not run: the time limit ({deadline}) ran out")
    else:
        cross = _cross_check(plant, res.P, err.relative, other)
    cross_time = time.perf_counter() - t1

    residual = filter_are_residual(plant, res.P)
    checks = [
        Check.at_most("riccati_residual", residual, RESIDUAL_TOL,
                      "relative residual of the filter Riccati equation"),
        forward_error_check(err),
        psd_check("P_min_eig", res.P, error=min(err.relative, 1.0), what="P"),
        stability_check(plant.A - res.L @ plant.C, plant.is_discrete),
        cross,
    ]
    verification = Verification.of(checks)
    kind = "discrete" if plant.is_discrete else "continuous"
    message = f"steady-state {kind} Kalman filter by the {method} Riccati solver"
    if verification.passed:
        message += "; all independent checks passed"
    else:
        message += "; failed checks: " + ", ".join(c.name for c in verification.failed)
    stats = SolverStats(backend=method, native_status="solved", time=elapsed,
                        extra={"cross_check_method": other, "cross_check_time": cross_time})
    return KalmanFilter(L=res.L, P=res.P, poles=res.poles, residual=res.residual, Kf=res.Kf,
                        plant=plant, status=Status.TIME_LIMIT if deadline.expired else Status.SOLVED,
                        message=message, solver_stats=stats,
                        verification=verification)
