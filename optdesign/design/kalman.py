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

from ..classical.riccati import RESIDUAL_TOL, filter_are, filter_are_residual
from ..errors import RiccatiError, ValidationError
from ..model.plant import Plant
from ..results import Check, ResultMixin, SolverStats, Status, Verification

__all__ = ["KalmanFilter", "kalman", "CROSS_CHECK_TOL", "PSD_RTOL"]

#: relative difference ||P - P_other||_F / ||P||_F allowed between the two Riccati solvers
CROSS_CHECK_TOL = 1e-6

#: smallest eigenvalue of P accepted as PSD: >= -PSD_RTOL ||P||_2
PSD_RTOL = 1e-10

_METHODS = ("scipy", "hamiltonian")


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
        Independent checks: ``riccati_residual`` (<= 1e-8), ``P_min_eig`` (>= -1e-10 ||P||),
        ``stability_margin`` (``-max Re`` or ``1 - max |.|`` of ``eig(A - L C)`` recomputed
        from L; must exceed ``1e3 eps``, times ``max(1, ||A||)`` in continuous time), and
        ``cross_check`` (relative difference from the other solver's P, <= 1e-6; ``inf`` with
        the reason in ``detail`` if the other solver failed).
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


def kalman(plant: Plant, *, method: str = "scipy") -> KalmanFilter:
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
    t0 = time.perf_counter()
    res = filter_are(plant, method)
    elapsed = time.perf_counter() - t0

    other = _METHODS[1] if method == _METHODS[0] else _METHODS[0]
    t1 = time.perf_counter()
    try:
        # no residual test here: an inaccurate answer of the other solver should show up as
        # a measured difference, not as a missing cross-check
        P_other = filter_are(plant, other, residual_tol=np.inf).P
        num = float(np.linalg.norm(res.P - P_other))
        diff = 0.0 if num == 0.0 else num / max(float(np.linalg.norm(res.P)), float(np.linalg.norm(P_other)))
        cross_detail = f"||P - P_{other}||_F / max(||P||_F, ||P_{other}||_F)"
    except RiccatiError as exc:
        diff = float("inf")
        cross_detail = f"{other} solver failed: {exc}"
    cross_time = time.perf_counter() - t1

    n = plant.n
    residual = filter_are_residual(plant, res.P)
    lmin = float(np.linalg.eigvalsh(res.P)[0])
    # P is known to about its Riccati condition times eps; a singular P (e.g. DAREX 1.7) comes
    # out with eigenvalues of -1e-11 ||P||, so allow 1e-10 ||P|| (and a tiny absolute floor)
    psd_tol = -(PSD_RTOL * float(np.linalg.norm(res.P, 2)) + n * np.finfo(float).tiny)
    # poles recomputed from the returned gain; the margin must exceed their rounding level,
    # not merely be positive
    poles = np.linalg.eigvals(plant.A - res.L @ plant.C)
    if plant.is_discrete:
        margin = 1.0 - float(np.max(np.abs(poles)))
        margin_tol = 1e3 * np.finfo(float).eps
        margin_detail = "1 - max |eig(A - L C)|"
    else:
        margin = -float(np.max(poles.real))
        margin_tol = 1e3 * np.finfo(float).eps * max(1.0, float(np.linalg.norm(plant.A, 2)))
        margin_detail = "-max Re eig(A - L C)"
    checks = [
        Check.at_most("riccati_residual", residual, RESIDUAL_TOL,
                      "relative residual of the filter Riccati equation"),
        Check.at_least("P_min_eig", lmin, psd_tol, "smallest eigenvalue of P (P must be PSD)"),
        Check.at_least("stability_margin", margin, margin_tol, margin_detail),
        Check.at_most("cross_check", diff, CROSS_CHECK_TOL, cross_detail),
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
                        plant=plant, status=Status.SOLVED, message=message, solver_stats=stats,
                        verification=verification)
