r"""The ODE method of :func:`optdesign.riccati_de`: the filter Riccati differential equation
``P' = A P + P A' + W - P S P`` integrated by scipy's DOP853 (or Radau) on the ``n^2`` entries of P,
with tolerances chosen from the accuracy asked of P (private module; the public names are re-exported
by :mod:`optdesign.design.riccati_de`).

Why the absolute tolerance follows the size of P (issue 26)
-----------------------------------------------------------
The error test of an embedded Runge-Kutta pair accepts a step when every entry's error estimate is
below ``atol + rtol |P_ij|``.  The right-hand side's rounding error, though, is set by its largest
terms (``P S P``, of the size of ``max |P_ij|^2 ||S||``), not by the entry.  A fixed ``atol`` far
below ``rtol max|P_ij|`` -- the former default ``rtol 1e-3 max|P0|``, 1e-15 for P0 = I -- asks of the
small entries of a P that has grown an absolute accuracy below that rounding floor: the error
estimate is then noise and the step collapses.  Issue 26's plant (n = 50, ``A = randn/sqrt(n)``, three
outputs, W = R = I, P growing from I to ~1e5 over 10 s): 3,660,365 evaluations and 150 s CPU, where
a direct ``solve_ivp`` with scipy's default ``atol = 1e-6`` needs a few thousand.  Here the absolute
tolerance is ``ATOL_PER_RTOL rtol max|P_ij|`` with the running maximum over the steps (the integrator
object is stepped directly and its ``atol`` updated after each step): the error control is then
norm-wise relative, as the error that ``riccati_de`` reports.  The same plant: 1,634 evaluations.
Where P grows so large that the rounding of the quadratic term exceeds even that (``max_i (P S
P)_ii eps`` above ``1e-3 rtol max|P_ij|``; P ~ 1e6 at n = 100), ``atol`` is raised to ``NOISE_FLOOR``
(10) times that rounding: 2,699 -> 1,868 evaluations for the same error at n = 100.

References
----------
Hairer, E., Norsett, S. P. & Wanner, G., *Solving Ordinary Differential Equations I*, 2nd ed.,
Springer 1993, II.4 (step size control) and II.10 (DOP853).
"""

from __future__ import annotations

import time

import numpy as np
import scipy.linalg
from numpy.typing import ArrayLike, NDArray

from .._deadline import Deadline
from .._validate import as_positive_float
from ..classical.transition import as_hamiltonian
from ..errors import ValidationError
from ..model.plant import Plant
from ..results import SolverStats, Status

__all__ = ["ode_tolerances", "ode_integrator", "integrate", "gain_factor", "RTOL_PER_TOL",
           "ATOL_PER_RTOL", "NOISE_FLOOR", "STIFF_RHO_T"]

#: the default ``rtol = RTOL_PER_TOL * tol`` (measured; see :func:`ode_tolerances`)
RTOL_PER_TOL = 1e-4

#: the default ``atol = ATOL_PER_RTOL * rtol * max|P_ij|`` (the running maximum over the steps)
ATOL_PER_RTOL = 1e-3

#: the absolute tolerance is never below ``NOISE_FLOOR eps`` times the size of the right-hand
#: side's terms (its rounding error over a unit of time; see :func:`integrate`)
NOISE_FLOOR = 10.0

#: the ODE method considers Radau when rho(M) t_final exceeds this (see :func:`ode_integrator`)
STIFF_RHO_T = 3e3

#: Python overhead of one right-hand-side call, in flops (~20 us at a few Gflop/s; measured)
RHS_OVERHEAD_FLOPS = 1e5

_EPS = float(np.finfo(float).eps)

#: smallest rtol the integrators accept (scipy raises smaller ones to it with a warning)
_RTOL_MIN = 100 * _EPS


def ode_tolerances(tol: float, *, rtol: float | None = None, atol: float | None = None) -> dict:
    r"""The integrator tolerances of ``riccati_de(method="ode")`` for the accuracy asked of P.

    ``tol`` is the relative error asked of the trajectory, ``max_k ||P_k - P(t_k)||_F / max_k
    ||P(t_k)||_F`` (what ``riccati_de`` measures as ``error_estimate``).  The integrator controls
    the error of each step, per entry: ``|local error of P_ij| <= atol + rtol |P_ij|``; the global
    error is that, propagated and summed over the steps.

    Defaults: ``rtol = RTOL_PER_TOL tol = 1e-4 tol`` (at least ``100 eps``, at most 1e-3) and
    ``atol = ATOL_PER_RTOL rtol max_ij |P_ij|`` (``1e-3 rtol`` times the largest entry of P met so
    far, updated after every step): an absolute error of each entry a thousandth of the relative
    one, measured on the size of P -- a norm-wise relative control -- and never below ``NOISE_FLOOR
    eps`` times the size of the right-hand side's terms, its rounding floor (see the module notes).  Measured (issue 26; 24 random plants, ``A ~
    N(0, 1/n)`` with three outputs and the tests' ``A ~ N(0, 1)`` shifted stable / unstable, n = 10,
    20, 50, horizons 1-100 s, P0 = I): with this ``atol`` a step tolerance ``rtol = r`` delivers a
    global error between ``0.02 r`` and ``500 r`` -- near ``r`` on short, non-stiff horizons, up to
    ``500 r`` where the step is bounded by stability (``rho(M) t_final`` of 100-3000: the fast
    components' local errors are not damped at the stability boundary and add up) -- hence the
    factor 1e-3, which met ``tol`` in every case measured at ``tol`` = 1e-6 .. 1e-10.

    Parameters
    ----------
    tol : float
        Relative error asked of P (> 0).
    rtol : float, optional
        Relative error allowed per step on each entry of P, in ``[100 eps, 1)``; overrides the
        default from ``tol``.
    atol : float, optional
        Absolute error allowed per step on each entry of P, in the units of P (> 0); fixed for
        the whole integration (the default follows the size of P).

    Returns
    -------
    dict
        ``rtol``, ``atol`` (None: following P) and ``atol_rel`` (the factor on ``max |P_ij|``;
        nan when ``atol`` is fixed).

    Raises
    ------
    ValidationError
        tol, rtol or atol not a finite number > 0 (strings and bools refused); rtol outside
        ``[100 eps, 1)``.
    """
    tol = as_positive_float("tol", tol)
    if rtol is None:
        rtol_v = min(max(RTOL_PER_TOL * tol, _RTOL_MIN), 1e-3)
    else:
        rtol_v = as_positive_float("rtol", rtol)
        if not _RTOL_MIN <= rtol_v < 1.0:
            raise ValidationError(f"rtol must lie in [{_RTOL_MIN:.1e}, 1) (below 100 eps the step "
                                  f"control works below rounding); found rtol={rtol!r}")
    if atol is None:
        return {"rtol": rtol_v, "atol": None, "atol_rel": rtol_v * ATOL_PER_RTOL}
    return {"rtol": rtol_v, "atol": as_positive_float("atol", atol), "atol_rel": float("nan")}


def ode_integrator(M: ArrayLike, t_final: float) -> tuple[str, dict]:
    r"""The ``solve_ivp`` method used by ``riccati_de(method="ode")``, and why.

    DOP853 (explicit, order 8) unless both

    * the horizon spans many time constants of the Hamiltonian, ``rho(M) t_final >
      STIFF_RHO_T``: an explicit method's step is then bounded by stability, not accuracy, so
      its evaluations grow like ``4.8 rho(M) t_final`` (measured) while Radau's level off once
      P has settled, and
    * Radau's linear algebra is affordable: each of its evaluations also solves with the LU
      factors of the ``N x N`` Jacobian, ``N = n^2`` (``10 N^2`` flops: one real and one complex
      system) and refactors it every few steps (``~N^3 / 3`` flops per evaluation), which together
      must not exceed one right-hand side (``6 n^3`` flops plus ``1e5`` for the call overhead):
      n <= 7.

    Measured at rtol 1e-12 (random plants as in the tests): Radau on n = 50 over 1000 s (before
    issue 14, on the 1275 entries of vech(P)) took 50 s CPU on one plant, where DOP853 takes 13 s,
    and 8.4 s for its first 3,000 evaluations (reaching t = 0.0125 s) on another; n = 20 over 200 s:
    2.9 s against 0.28 s; n = 10 over 1000 s: 1.5x DOP853; CAREX 2.3 (n = 2, ``rho(M) = 1000``):
    1.6x over 10 s and 0.2x over 100 s (break-even near ``rho(M) t_final = 1.6e4``; Radau is also
    1e4 times more accurate there).

    Parameters
    ----------
    M : (2n, 2n) array_like
        Hamiltonian (:func:`~optdesign.classical.bpf.filter_hamiltonian`).
    t_final : float

    Returns
    -------
    integrator : {"DOP853", "Radau"}
    info : dict
        ``rho_t`` (``rho(M) t_final``), ``stiff``, ``implicit_affordable``.

    Raises
    ------
    DimensionError, NotFiniteError
        M not a finite 2n x 2n matrix.
    ValidationError
        t_final not a finite number > 0.
    """
    M, n = as_hamiltonian(M)
    N = n * n
    rho_t = float(np.max(np.abs(np.linalg.eigvals(M)))) * as_positive_float("t_final", t_final) if n else 0.0
    stiff = rho_t > STIFF_RHO_T
    affordable = 10.0 * N**2 + N**3 / 3.0 <= 6.0 * n**3 + RHS_OVERHEAD_FLOPS
    integrator = "Radau" if stiff and affordable else "DOP853"
    return integrator, {"rho_t": rho_t, "stiff": stiff, "implicit_affordable": affordable}


def integrate(M: NDArray, K: NDArray | None, P0: NDArray, t: NDArray, tols: dict, clock: Deadline):
    """``P`` at ``t`` by a ``solve_ivp`` integrator stepped here (see :func:`ode_tolerances`).

    The integrator object is stepped directly (as ``solve_ivp`` does) so that, after every
    step, its absolute tolerance follows the size of P: ``atol = atol_rel * max(|P_ij|)``
    (the running maximum), at least the rounding floor of the right-hand side
    (``_rounding_floor``), unless a fixed ``atol`` was given.  ``K`` (``p x n``, ``K' K = S``)
    writes the quadratic term as ``(P K')(P K')'`` (``3 n^2 p`` flops instead of ``4 n^3``).
    """
    from scipy.integrate import DOP853, Radau

    n = P0.shape[0]
    A, S, W = M[n:, n:], M[:n, n:], M[n:, :n]
    rhs = _rhs(A, K, S, W)
    t_end = float(t[-1])
    integrator, why = ode_integrator(M, t_end if t_end > 0 else 1.0)
    rtol, atol_fixed, atol_rel = tols["rtol"], tols["atol"], tols["atol_rel"]
    y0 = P0.ravel().copy()
    big = float(np.max(np.abs(y0))) if y0.size else 0.0
    floor = float(np.max(np.abs(W))) * min(t_end if t_end > 0 else 1.0, 1.0)
    atol0 = atol_fixed if atol_fixed is not None else atol_rel * max(big, floor, np.finfo(float).tiny)
    noise = _rounding_floor(A, K, S, W)
    out = np.empty((t.size, n * n))
    j = int(np.searchsorted(t, 0.0, side="right"))           # outputs at t = 0
    out[:j] = y0
    status, native, message = Status.SOLVED, "reached the end of the interval", ""
    t0 = time.perf_counter()
    if t_end > 0:
        kw: dict = {"jac": _jacobian(A, S)} if integrator == "Radau" else {}
        cls = Radau if integrator == "Radau" else DOP853
        solver = cls(rhs, 0.0, y0, t_end, rtol=rtol, atol=atol0, **kw)
        while solver.status == "running" and not clock.expired:
            native = solver.step() or native
            if solver.status == "failed":
                status = Status.NUMERICAL_ERROR
                message = f"{integrator} stopped at t = {solver.t:g}: {native}"
                break
            k = int(np.searchsorted(t, solver.t, side="right"))
            if k > j:
                if t[k - 1] == solver.t:
                    if k - 1 > j:
                        out[j:k - 1] = solver.dense_output()(t[j:k - 1]).T
                    out[k - 1] = solver.y
                else:
                    out[j:k] = solver.dense_output()(t[j:k]).T
                j = k
            if atol_fixed is None:
                big = max(big, float(np.max(np.abs(solver.y))))
                solver.atol = max(atol_rel * max(big, floor, np.finfo(float).tiny),
                                  noise(solver.y, big))
        nfev, njev = int(solver.nfev), int(getattr(solver, "njev", 0) or 0)
        atol_end = float(solver.atol)
    else:
        nfev, njev, atol_end = 0, 0, atol0
    elapsed = time.perf_counter() - t0
    P = out[:j].reshape(-1, n, n)
    stats = SolverStats(backend="scipy.integrate." + integrator, native_status=native,
                        time=elapsed, iterations=nfev,
                        extra={"integrator": integrator, "rtol": rtol, "atol": atol_end,
                               "atol_rel": atol_rel, "nfev": nfev, "njev": njev, **why})
    how = (f"atol {atol_end:.1e}" if atol_fixed is not None
           else f"atol {atol_rel:.0e} x max|P_ij| ({atol_end:.1e} at the end)")
    scheme = f"{integrator} on the n^2 entries of P (rtol {rtol:.1e}, {how})"
    return P, stats, status, message, scheme


def gain_factor(plant: Plant) -> NDArray | None:
    """``K = L^-1 C`` with ``R = L L'`` (so ``K' K = C' R^-1 C``), or None when ``p >= n``."""
    C, (_, R) = plant.C, plant.noise_covariances()
    if C.shape[0] >= C.shape[1]:
        return None
    return scipy.linalg.solve_triangular(np.linalg.cholesky(R), C, lower=True)


def _rounding_floor(A: NDArray, K: NDArray | None, S: NDArray, W: NDArray):
    """``y -> NOISE_FLOOR * eps * (max_i (P S P)_ii + ||A||_inf max|P_ij| + max|W_ij|)``: the absolute
    tolerance below which the error estimate of a step of length ~1 is the right-hand side's rounding
    (``max |(P S P)_ij| = max_i (P S P)_ii`` for P >= 0: ``||B_i||^2``, ``B = P K'``)."""
    n = A.shape[0]
    a_inf = float(np.max(np.sum(np.abs(A), axis=1))) if n else 0.0
    w = float(np.max(np.abs(W))) if n else 0.0

    def floor(y: NDArray, big: float) -> float:
        P = y.reshape(n, n)
        if K is not None:
            B = P @ K.T
            quad = float(np.max(np.einsum("ij,ij->i", B, B)))
        else:
            quad = float(np.max(np.einsum("ij,jk,ik->i", P, S, P)))
        return NOISE_FLOOR * _EPS * (abs(quad) + 2.0 * a_inf * big + w)

    return floor


def _rhs(A: NDArray, K: NDArray | None, S: NDArray, W: NDArray):
    """``vec(A P + P A' + W - P S P)``, exactly symmetric whatever P (``X X'`` by syrk)."""
    n = A.shape[0]

    if K is None:
        def rhs(_t: float, y: NDArray) -> NDArray:
            P = y.reshape(n, n)
            H = A @ P - 0.5 * (P @ S @ P)
            return (H + H.T + W).ravel()
        return rhs

    KT = np.ascontiguousarray(K.T)

    def rhs_factored(_t: float, y: NDArray) -> NDArray:
        P = y.reshape(n, n)
        H = A @ P
        B = P @ KT
        F = H + H.T
        F += W
        F -= B @ B.T
        return F.ravel()

    return rhs_factored


def _jacobian(A: NDArray, S: NDArray):
    """The Jacobian ``Fc (x) I + I (x) Fc`` of ``vec(Fc X + X Fc')`` (row-major vec), ``Fc = A - P S``,
    for Radau (dense ``n^2 x n^2``: used only where :func:`ode_integrator` finds it affordable)."""
    n = A.shape[0]
    eye = np.eye(n)

    def jac(_t: float, y: NDArray) -> NDArray:
        Fc = A - y.reshape(n, n) @ S
        return np.kron(Fc, eye) + np.kron(eye, Fc)

    return jac


