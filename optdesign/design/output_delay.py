r"""Stationary Kalman filter for a linear system with a delay in the output (seed 002).

System (seed 002, eqs 1-2)::

    x'(t) = A x(t) + G w(t),        y(t) = C0 x(t) + C1 x(t - h) + v(t),
    E[w w'] = Q delta,  E[v v'] = R delta.

The stationary filter (eqs 3-4) is

    x_hat'(t|t) = A x_hat(t|t) + K0 nu(t),                  K0 = (p0 C0' + p1(-h)' C1') R^-1,
    x_hat(t-h|t) = x_hat(t-h|t-h) + int_{t-h}^t K(t-h-sigma) nu(sigma) d sigma,
    K(theta) = (p1(theta) C0' + p2(theta, -h) C1') R^-1,     theta in [-h, 0],
    nu = y - C0 x_hat(t|t) - C1 x_hat(t-h|t),

where ``p0 = E[e(t) e(t)']``, ``p1(theta) = E[e(t+theta) e(t)']`` and ``p2(theta, eta) =
E[e(t+theta) e(t+eta)']`` are the stationary error covariances of the infinite-dimensional state
``(x(t), x(t+theta))`` (the solution of the operator Riccati equation (5)-(8); ``K(0) = K0``).

Two finite-dimensional approximations converge to it:

``method="pade"``
    The delay is split into ``sections`` equal parts, each replaced by the ``[order/order]`` Pade
    approximant of ``exp(-s h / sections)`` (applied to every state component).  The outputs of
    the sections approximate ``x(t - j h / sections)``; a continuous ARE on the augmented system
    gives ``p0`` and ``K0`` (top blocks) and ``K(theta_j)`` at ``theta_j = -j h / sections``.
``method="sample"``
    Sampling with step ``delta = h / order``; the shift register ``X_k = (x(t_k), x(t_k - delta),
    ..., x(t_k - h))`` turns the delay into a finite state; exact discretization of the dynamics
    (``exp(A delta)``, Van Loan), measurement noise ``R / delta``, a DARE, and the continuous-time
    quantities from the mean of the a-priori and a-posteriori covariances (each is first order in
    ``delta``, with opposite leading errors; the mean is second order), ``K = P C' R^-1``.  With
    ``extrapolate=True`` (default) a Richardson step with ``order/2`` steps makes it fourth order.

The return difference of the filter, seed 002 eq (16) (with the OCR-lost bars restored,
``p1(-s) -> p1_bar(-s)``)::

    T(s) = I + (C0 + C1 e^{-sh}) (sI - A)^-1 K0 + C1 int_{-h}^0 e^{-s (theta + h)} K(theta) d theta

is evaluated with the *true* ``e^{-j w h}`` (the kernel integral is exact for the piecewise-linear
interpolant of ``K`` on the grid).  The circle condition (17) ``T R T^* >= R`` follows from the
spectral identity (19) ``T(s) R T(-s)' = R + H(s) W H(-s)'``, ``H(s) = (C0 + C1 e^{-sh}) (sI - A)^-1``,
``W = G Q G'``; the residual of (19) on a frequency grid is an independent check of the computed
filter (it uses none of the Riccati machinery).

References
----------
S. J. Lee, "Frequency-domain properties of Kalman filters for linear systems with delay in output"
(seed 002), eqs (1)-(19); typos: the boundary condition (8) is ``p1(0) = p0`` and ``A_0`` in (5) is A.
R. H. Kwong and A. S. Willsky, SIAM J. Control Optim. 16 (1978) (the filter (3)-(4)).
"""

from __future__ import annotations

import math
import time
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._deadline import Deadline
from .._validate import (
    as_array,
    as_bool,
    as_frequencies,
    as_int,
    as_matrix,
    as_positive_float,
    as_square,
    as_str,
    as_vector,
    check_pd,
    check_psd,
)
from ..analysis.robustness import (
    CircleConditionResult,
    circle_search,
    search_stopped,
    worst_case_parts,
)
from ..classical.sampling import van_loan
from ..errors import RiccatiError, ValidationError
from ..results import Check, DesignResult, Route, SolverStats, Stage, Status, Verification

__all__ = [
    "output_delay_kalman",
    "OutputDelayKalman",
    "output_delay_convergence",
    "ConvergenceRow",
    "pade_delay",
]


# --------------------------------------------------------------------------- Pade
def pade_delay(tau: float, order: int) -> tuple[NDArray, NDArray, NDArray, NDArray]:
    """State-space realization ``(A, B, C, D)`` of the ``[order/order]`` Pade approximant of ``exp(-s tau)``.

    ``exp(-x) ~ N(-x) / N(x)``, ``N(x) = sum_k c_k x^k``, ``c_k = (2m-k)! m! / ((2m)! k! (m-k)!)``;
    observable-canonical realization in the scaled variable ``s tau``, then scaled back.

    Raises
    ------
    ValidationError
        ``tau`` not a number ``> 0``, or ``order`` not an integer ``>= 1``.
    """
    tau = as_positive_float("tau", tau)
    m = as_int("Pade order", order, 1)
    f = math.factorial
    c = np.array([f(2 * m - k) * f(m) / (f(2 * m) * f(k) * f(m - k)) for k in range(m + 1)])
    den = c[::-1] / c[m]                       # monic, highest power first
    num = (c * (-1.0) ** np.arange(m + 1))[::-1] / c[m]
    d = num[0]                                  # (-1)^m
    r = num[1:] - d * den[1:]                   # strictly proper remainder
    # observable canonical form in x = s tau: x' = Ah x + Bh u, y = Ch x + d u
    Ah = np.zeros((m, m))
    Ah[:, 0] = -den[1:]
    Ah[:-1, 1:] = np.eye(m - 1)
    Bh = r.reshape(m, 1)
    Ch = np.zeros((1, m))
    Ch[0, 0] = 1.0
    return Ah / tau, Bh / tau, Ch, np.array([[d]])


# --------------------------------------------------------------------------- kernel quadrature
def _kernel_weights(theta_asc: NDArray, lam: NDArray) -> NDArray[np.complex128]:
    """Weights ``w[k, j]`` with ``int e^{lam_k x} f(x) dx = sum_j w[k, j] f(x_j)`` for piecewise-linear f."""
    x = theta_asc
    dx = np.diff(x)                                       # (N,)
    z = lam[:, None] * dx[None, :]                        # (k, N)
    small = np.abs(z) < 0.1
    zs = np.where(small, 1.0, z)
    phi1 = np.where(small, 0.0, (np.exp(zs) - 1.0) / zs)  # int_0^1 e^{z v} dv
    phi2 = np.where(small, 0.0, (np.exp(zs) * (zs - 1.0) + 1.0) / zs**2)  # int_0^1 v e^{z v} dv
    if np.any(small):
        zz = z[small]
        s1 = np.zeros_like(zz)
        s2 = np.zeros_like(zz)
        term = np.ones_like(zz)
        for k in range(12):
            s1 += term / (k + 1)
            s2 += term / (k + 2)
            term = term * zz / (k + 1)
        phi1[small] = s1
        phi2[small] = s2
    e = np.exp(lam[:, None] * x[None, :-1])               # (k, N)
    I0 = dx[None, :] * phi1
    I1 = dx[None, :] * phi2                               # (1/dx) * int u e^{lam u} du
    w = np.zeros((lam.size, x.size), dtype=complex)
    w[:, :-1] += e * (I0 - I1)
    w[:, 1:] += e * I1
    return w


# --------------------------------------------------------------------------- result
@dataclass(frozen=True)
class ConvergenceRow:
    """p0 and K0 at one approximation order (see :func:`output_delay_convergence`)."""

    method: str
    order: int
    sections: int
    step: float
    dim: int
    p0: NDArray[np.float64]
    K0: NDArray[np.float64]


@dataclass(frozen=True, kw_only=True, eq=False)
class OutputDelayKalman(DesignResult):
    r"""Stationary Kalman filter of the delayed-output system (seed 002 eqs 3-4).

    Attributes
    ----------
    method : {"pade", "sample"}
    order : int
        Pade degree per section, or number of sampling steps per delay.
    sections : int
        Number of delay sections (Pade); equals ``order`` for sampling.
    h : float
        The output delay.
    A, C0, C1, W, R : ndarrays
        The system (``W = G Q G'``).
    p0 : (n, n) ndarray
        Stationary error covariance of ``x_hat(t|t)``.
    K0 : (n, p) ndarray
        Gain of eq (3), ``(p0 C0' + p1(-h)' C1') R^-1``.
    theta : (N+1,) ndarray
        Grid ``0, -h/N, ..., -h``.
    K_theta : (N+1, n, p) ndarray
        Distributed gain of eq (4), ``K(theta) = (p1(theta) C0' + p2(theta, -h) C1') R^-1``.
    p1 : (N+1, n, n) ndarray
        ``p1(theta) = E[e(t+theta) e(t)']`` on the grid (``p1(0) = p0``).
    dim : int
        Dimension of the augmented finite-dimensional filter.
    p0_change : float
        ``||p0 - p0_coarse||_F / ||p0||_F`` against a coarser approximation (Pade degree - 1, or half
        the sampling steps): the reported convergence estimate.
    status, message, solver_stats, verification
        As every design result; ``verification`` holds the augmented Riccati residual, PSD-ness of
        p0, stability of the augmented filter, the convergence estimate and the residual of the
        spectral identity (19) with the true delay.
    """

    method: str
    order: int
    sections: int
    h: float
    A: NDArray[np.float64]
    C0: NDArray[np.float64]
    C1: NDArray[np.float64]
    W: NDArray[np.float64]
    R: NDArray[np.float64]
    p0: NDArray[np.float64]
    K0: NDArray[np.float64]
    theta: NDArray[np.float64]
    K_theta: NDArray[np.float64]
    p1: NDArray[np.float64]
    dim: int
    p0_change: float
    augmented: tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]] | None = None

    # ----------------------------------------------------------------- frequency domain
    def loop_H(self, omega: ArrayLike) -> NDArray[np.complex128]:
        """``H(jw) = (C0 + C1 e^{-jwh}) (jwI - A)^-1``, shape (k, p, n)."""
        w = as_vector("omega", omega)
        n = self.A.shape[0]
        M = 1j * w[:, None, None] * np.eye(n)[None] - self.A[None]
        Phi = np.linalg.solve(M, np.broadcast_to(np.eye(n, dtype=complex), (w.size, n, n)))
        Cw = self.C0[None] + np.exp(-1j * w * self.h)[:, None, None] * self.C1[None]
        return Cw @ Phi

    def return_difference(self, omega: ArrayLike) -> NDArray[np.complex128]:
        r"""Seed 002 eq (16) at ``s = j w`` with the true delay, shape (k, p, p).

        ``T = I + H(jw) K0 + C1 int_{-h}^0 e^{-jw(theta+h)} K(theta) d theta`` (kernel integrated
        exactly for the piecewise-linear interpolant of ``K_theta``).
        """
        w = as_vector("omega", omega)
        p = self.R.shape[0]
        H = self.loop_H(w)
        th = self.theta[::-1]                     # ascending, -h .. 0
        Kt = self.K_theta[::-1]
        wts = _kernel_weights(th, -1j * w) * np.exp(-1j * w * self.h)[:, None]
        integral = np.einsum("kj,jnp->knp", wts, Kt.astype(complex))
        return np.eye(p)[None] + H @ self.K0[None] + self.C1[None] @ integral

    def spectral_residual(self, omega: ArrayLike, *, relative: bool = True) -> NDArray[np.float64]:
        r"""Residual of eq (19), ``||T R T^* - R - H W H^*||_2`` per frequency.

        Relative (default): divided by ``||R|| + ||H W H^*||``.  The exact filter has residual 0;
        the computed one has the approximation error of the finite-dimensional filter.
        """
        w = as_vector("omega", omega)
        T = self.return_difference(w)
        H = self.loop_H(w)
        HWH = H @ self.W[None] @ np.conj(np.swapaxes(H, 1, 2))
        E = T @ self.R[None] @ np.conj(np.swapaxes(T, 1, 2)) - self.R[None] - HWH
        err = np.linalg.norm(E, axis=(1, 2), ord=2)
        if not relative:
            return err
        return err / (np.linalg.norm(self.R, 2) + np.linalg.norm(HWH, axis=(1, 2), ord=2))

    def frequency_grid(self) -> NDArray[np.float64]:
        """Log grid covering the plant poles and several multiples of ``2 pi / h``, plus 0."""
        mags = np.abs(np.linalg.eigvals(self.A))
        mags = mags[mags > 0]
        lo = min(float(np.min(mags, initial=1.0)), 1.0 / self.h)
        hi = max(float(np.max(mags, initial=1.0)), 2 * np.pi / self.h)
        k = int(np.ceil(40 * (math.log10(hi) - math.log10(lo) + 4)))
        # the delay makes T oscillate with period 2 pi / h: resolve it up to 30 periods
        lin = np.linspace(0.0, 30 * 2 * np.pi / self.h, 60 * 30 + 1)
        return np.unique(np.concatenate([[0.0], np.logspace(math.log10(lo) - 2, math.log10(hi) + 2, k), lin]))

    def circle_condition(
        self, omega: ArrayLike | None = None, *, tol: float | None = None,
        time_limit: float | Deadline | None = None,
    ) -> CircleConditionResult:
        r"""Seed 002 Theorem 1 (eq 17): ``min_w lambda_min(T R T^* - R)`` with the true delay.

        ``tol`` defaults to ``1e-8 ||R||`` plus the largest absolute residual of eq (19) on the
        grid -- the approximation error of the finite-dimensional filter, which the verdict must
        allow for (the exact filter satisfies (19) exactly).  Compare ``min_eigenvalue`` with
        ``tol``: for the seed example the minimum is positive, so no allowance is needed.

        ``omega`` (rad/s, finite, ``>= 0``) replaces :meth:`frequency_grid` as the seed grid;
        ``time_limit`` (seconds) stops the search as in
        :func:`~optdesign.analysis.robustness.circle_condition` (``complete = False``).

        Raises
        ------
        ValidationError, DimensionError, NotFiniteError
            A bad ``omega``, ``tol`` (finite, ``>= 0``) or ``time_limit``.
        """
        deadline = Deadline.of(time_limit)
        R = self.R
        grid = self.frequency_grid() if omega is None else np.unique(as_frequencies("omega", omega))
        if tol is not None:
            tol = as_positive_float("tol", tol, allow_zero=True)
        w_all, vals, complete = circle_search(self.return_difference, grid, R, R, log=True,
                                              deadline=deadline)
        i = int(np.argmin(vals))
        w_star = float(w_all[i])
        if tol is None:
            approx = float(np.max(self.spectral_residual(w_all, relative=False)))
            tol = 1e-8 * float(np.linalg.norm(R, 2)) + approx
        T_star = self.return_difference(np.array([w_star]))[0]
        direction, Delta = worst_case_parts(T_star, R, R)
        min_eig = float(vals[i])
        holds = min_eig >= -tol
        message = "" if holds else f"T R T* - R has eigenvalue {min_eig:.4g} at omega = {w_star:.6g}"
        if not complete:
            message = "; ".join(filter(None, [message, search_stopped(deadline, w_all.size, holds)]))
        return CircleConditionResult(
            min_eigenvalue=min_eig, omega_worst=w_star, passed=holds and complete, omega=w_all, values=vals,
            tol=tol, R=R, V=R, discrete=False, dt=None, V_source="R", T_worst=T_star, direction=direction,
            perturbation=Delta, message=message, complete=complete,
        )

    def summary(self) -> str:
        return (f"output-delay Kalman filter ({self.method}, order {self.order}, sections {self.sections}, "
                f"dim {self.dim}): p0 = {np.array2string(self.p0, precision=6)}, K0 = "
                f"{np.array2string(self.K0.ravel(), precision=6)}, p0 change {self.p0_change:.2e}; "
                f"status {self.status}\n  route: {self.route}\n" + self.verification.summary())


# --------------------------------------------------------------------------- solvers
#: The validated delayed-output system ``(A, C0, C1, W, R, h)``.
_System = tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64],
                NDArray[np.float64], float]


def _solve(method: str, A: NDArray[np.float64], C0: NDArray[np.float64], C1: NDArray[np.float64],
           W: NDArray[np.float64], R: NDArray[np.float64], h: float, m: int, N: int) -> dict[str, Any]:
    """The finite-dimensional filter of one order; every failure is a :class:`RiccatiError`."""
    try:
        if method == "pade":
            return _solve_pade(A, C0, C1, W, R, h, m, N)
        return _solve_sample(A, C0, C1, W, R, h, N)
    except RiccatiError:
        raise
    except (np.linalg.LinAlgError, ValueError) as exc:
        raise RiccatiError(
            f"the augmented Riccati equation of the delayed-output system ({method}) has no stabilizing "
            f"solution: {exc}") from exc


def _solve_pade(A, C0, C1, W, R, h, m, N):
    from scipy.linalg import solve_continuous_are, solve_continuous_lyapunov

    n, p = A.shape[0], C0.shape[0]
    Ap, Bp, Cp, Dp = pade_delay(h / N, m)
    In = np.eye(n)
    Ak, Bk, Ck, Dk = np.kron(Ap, In), np.kron(Bp, In), np.kron(Cp, In), np.kron(Dp, In)
    ns = m * n
    dim = n + N * ns
    Aa = np.zeros((dim, dim))
    Aa[:n, :n] = A
    Ms = [np.zeros((n, dim))]
    Ms[0][:, :n] = In                                     # u_0 = x
    for j in range(1, N + 1):
        sl = slice(n + (j - 1) * ns, n + j * ns)
        Aa[sl, :] += Bk @ Ms[j - 1]
        Aa[sl, sl] += Ak
        Mj = Dk @ Ms[j - 1]
        Mj[:, sl] += Ck
        Ms.append(Mj)                                     # u_j ~ x(t - j h/N)
    Ca = C0 @ Ms[0] + C1 @ Ms[N]
    Wa = np.zeros((dim, dim))
    Wa[:n, :n] = W
    P = solve_continuous_are(Aa.T, Ca.T, Wa, R)
    P = 0.5 * (P + P.T)
    Ri = np.linalg.solve(R, np.eye(p))

    def residual(P):
        res = Aa @ P + P @ Aa.T - P @ Ca.T @ Ri @ Ca @ P + Wa
        return res, float(np.linalg.norm(res) / max(np.linalg.norm(Aa @ P) * 2 + np.linalg.norm(Wa), 1e-300))

    res, rel = residual(P)
    for _ in range(3):   # Newton-Kleinman polishing: the Pade cascade makes the ARE ill-conditioned
        Acl = Aa - P @ Ca.T @ Ri @ Ca
        with warnings.catch_warnings():   # accepted only if the residual drops (below)
            warnings.simplefilter("ignore", RuntimeWarning)
            Pn = P + solve_continuous_lyapunov(Acl, -res)
        if not np.all(np.isfinite(Pn)):
            break
        Pn = 0.5 * (Pn + Pn.T)
        res_n, rel_n = residual(Pn)
        if not rel_n < 0.5 * rel:
            break
        P, res, rel = Pn, res_n, rel_n
    Ka = P @ Ca.T @ Ri
    eig = np.linalg.eigvals(Aa - Ka @ Ca)
    stable = bool(np.max(eig.real) < 0)
    if not stable:
        raise RiccatiError(
            "the augmented Riccati equation of the delayed-output system (pade) has no stabilizing "
            f"solution: eigenvalue {eig[np.argmax(eig.real)]:.4g} of the augmented filter (is the "
            "delayed-output system detectable?)")
    K_theta = np.stack([Mj @ Ka for Mj in Ms])
    p1 = np.stack([Mj @ P @ Ms[0].T for Mj in Ms])
    return dict(p0=p1[0].copy(), K0=K_theta[0].copy(), K_theta=K_theta, p1=p1, dim=dim, residual=rel,
                stable=stable, augmented=(Aa, Ca, Ka))


def _solve_sample(A, C0, C1, W, R, h, N):
    from scipy.linalg import solve_discrete_are

    n, p = A.shape[0], C0.shape[0]
    dt = h / N
    Phi, Qd = van_loan(A, W, dt)
    dim = n * (N + 1)
    F = np.zeros((dim, dim))
    F[:n, :n] = Phi
    F[n:, :-n] = np.eye(n * N)                          # shift register
    Ca = np.zeros((p, dim))
    Ca[:, :n] = C0
    Ca[:, -n:] += C1
    Wa = np.zeros((dim, dim))
    Wa[:n, :n] = Qd
    Rd = R / dt
    P = solve_discrete_are(F.T, Ca.T, Wa, Rd)
    P = 0.5 * (P + P.T)
    Vd = Ca @ P @ Ca.T + Rd
    Lp = F @ P @ Ca.T @ np.linalg.inv(Vd)
    res = F @ P @ F.T - Lp @ Vd @ Lp.T + Wa - P
    rel = float(np.linalg.norm(res) / max(np.linalg.norm(P), 1e-300))
    rho = float(np.max(np.abs(np.linalg.eigvals(F - Lp @ Ca))))
    stable = rho < 1
    if not stable:
        raise RiccatiError(
            "the augmented Riccati equation of the delayed-output system (sample) has no stabilizing "
            f"solution: spectral radius {rho:.6g} of the augmented filter (is the delayed-output system "
            "detectable?)")
    # a-priori and a-posteriori covariances are both O(dt) from the continuous limit, with
    # opposite leading errors: their mean is O(dt^2)
    Pplus = P - P @ Ca.T @ np.linalg.solve(Vd, Ca @ P)
    P = 0.5 * (P + Pplus)
    P = 0.5 * (P + P.T)
    Pb = P.reshape(N + 1, n, N + 1, n)
    K = P @ Ca.T @ np.linalg.inv(R)                     # continuous-time limit of the gain
    K_theta = K.reshape(N + 1, n, p)
    p1 = np.stack([Pb[j, :, 0, :] for j in range(N + 1)])
    return dict(p0=p1[0].copy(), K0=K_theta[0].copy(), K_theta=K_theta, p1=p1, dim=dim, residual=rel,
                stable=stable)


def _validate(A: ArrayLike, C0: ArrayLike, C1: ArrayLike, h: float, Q: ArrayLike, R: ArrayLike,
              G: ArrayLike | None) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64],
                                            float, NDArray[np.float64], NDArray[np.float64]]:
    A = as_square("A", A)
    n = A.shape[0]
    C0 = as_array("C0", C0, (0, 1, 2))
    C0 = as_matrix("C0", C0, (1, n) if C0.ndim == 1 else (None, n))
    p = C0.shape[0]
    C1 = as_matrix("C1", C1, (p, n))
    h = as_positive_float("h", h)
    Gm = np.eye(n) if G is None else as_matrix("G", G, (n, None))
    Qm = check_psd("Q", as_square("Q", Q, Gm.shape[1]))
    Rm = check_pd("R", as_square("R", R, p))
    W = Gm @ Qm @ Gm.T
    return A, C0, C1, h, 0.5 * (W + W.T), Rm


def output_delay_kalman(
    A: ArrayLike,
    C0: ArrayLike,
    C1: ArrayLike,
    h: float,
    Q: ArrayLike,
    R: ArrayLike,
    *,
    method: str = "pade",
    order: int | None = None,
    sections: int | None = None,
    G: ArrayLike | None = None,
    extrapolate: bool = True,
    time_limit: float | None = None,
) -> OutputDelayKalman:
    r"""Stationary Kalman filter for ``y = C0 x(t) + C1 x(t-h) + v`` (seed 002 eqs 3-8).

    Parameters
    ----------
    A : (n, n) array_like
    C0, C1 : (p, n) array_like
        Output matrices of the current and the delayed state.
    h : float
        Output delay, ``> 0`` (for ``h = 0`` use :func:`optdesign.kalman` with ``C = C0 + C1``).
    Q : (m, m) array_like
        Process-noise intensity (``m = n`` unless G is given), symmetric PSD.
    R : (p, p) array_like
        Measurement-noise intensity, symmetric PD.
    method : {"pade", "sample"}
        Rational (Pade) approximation of the delay + continuous ARE, or sampling with a shift
        register + DARE (module docstring); ``"sampling"`` is accepted for ``"sample"``.
    order : int, optional
        Pade degree per section (default 4), or sampling steps per delay (default 32).  The
        augmented dimension is ``n (1 + sections * order)`` (Pade) or ``n (order + 1)`` (sampling).
    sections : int, optional
        Pade only: number of delay sections (default 8); the distributed gain ``K(theta)`` is
        obtained at ``theta_j = -j h / sections`` (the return difference integrates its
        piecewise-linear interpolant, error ``O((h / sections)^2)``).
    G : (n, m) array_like, optional
        Process-noise input matrix (default I).
    extrapolate : bool
        Sampling only: Richardson extrapolation ``(4 X_N - X_{N/2}) / 3`` (fourth-order accurate).
    time_limit : float, optional
        Seconds (``None``: no limit).  The filter of the requested order is always computed (one
        Riccati solve, not interruptible); if the limit has expired by then, the coarser solve (the
        convergence estimate, or the second half of the Richardson step) is skipped and the result
        has status ``time_limit`` with the order-``order`` filter, its checks, and ``p0_change`` NaN.

    Returns
    -------
    OutputDelayKalman
        ``p0``, ``K0``, ``K_theta``, ``p1``, convergence estimate, verification.

    Raises
    ------
    DimensionError, NotFiniteError, NotSymmetricError, NotPositiveSemidefiniteError,
    NotPositiveDefiniteError
        Malformed system matrices.
    ValidationError
        Unknown method (or not a string), bad order/sections, ``h`` not a number ``> 0``, an odd
        ``order`` with extrapolation, ``extrapolate`` not a bool, a bad ``time_limit``.
    RiccatiError
        The augmented Riccati equation has no stabilizing solution (undetectable delayed system).

    References
    ----------
    Seed 002 (S. J. Lee), eqs (3)-(8), (16)-(19).

    Examples
    --------
    >>> from optdesign import output_delay_kalman
    >>> f = output_delay_kalman([[0.5]], [[1.0]], [[0.5]], 1.0, [[1.0]], [[1.0]])   # y = x + 0.5 x(t-1) + v
    >>> f.success, round(float(f.p0[0, 0]), 3), round(float(f.K0[0, 0]), 3)
    (True, 1.382, 1.543)
    """
    deadline = Deadline.of(time_limit)
    A, C0, C1, h, W, R = _validate(A, C0, C1, h, Q, R, G)
    method, m, N, extrapolate = _options(method, order, sections, extrapolate)
    t0 = time.perf_counter()
    sol, coarse, stopped = _solve_with_estimate(method, m, N, extrapolate, (A, C0, C1, W, R, h), deadline)
    elapsed = time.perf_counter() - t0
    p0 = 0.5 * (sol["p0"] + sol["p0"].T)
    nrm = max(float(np.linalg.norm(p0)), 1e-300)
    change = float(np.linalg.norm(p0 - coarse["p0"]) / nrm) if coarse is not None else float("nan")
    N_grid = sol["K_theta"].shape[0] - 1
    theta = -h * np.arange(N_grid + 1) / N_grid
    res = OutputDelayKalman(
        method=method, order=m, sections=N, h=h, A=A, C0=C0, C1=C1, W=W, R=R, p0=p0, K0=sol["K0"],
        theta=theta, K_theta=sol["K_theta"], p1=sol["p1"], dim=sol["dim"], p0_change=change,
        augmented=sol.get("augmented"),
        status=Status.SOLVED, message="", solver_stats=SolverStats(
            "scipy", "solve_continuous_are" if method == "pade" else "solve_discrete_are", elapsed, None,
            {"augmented_dim": sol["dim"]}),
    )
    # independent checks
    grid = np.concatenate([[0.0], np.logspace(-2, 2, 81) * max(1.0, 2 * np.pi / h)])
    spec = float(np.max(res.spectral_residual(grid)))
    checks = [
        Check.at_most("augmented_riccati_residual", sol["residual"], 1e-8,
                      "relative, of the augmented ARE/DARE"),
        Check.at_least("p0_min_eig", float(np.linalg.eigvalsh(p0)[0]), -1e-10 * nrm, "p0 must be PSD"),
        Check.at_least("augmented_filter_stable", 1.0 if sol["stable"] else 0.0, 1.0,
                       "error dynamics of the augmented filter stable"),
        Check.at_most("spectral_identity_residual", spec, 1e-2,
                      "eq (19) with the true delay, relative, max over a grid (approximation error)"),
    ]
    if not math.isnan(change):
        checks.append(Check.at_most("p0_convergence", change, 1e-2,
                                    "relative change of p0 vs a coarser order"))
    ver = Verification.of(checks)
    msg = "; ".join(filter(None, [stopped, "; ".join(str(c) for c in ver.failed)]))
    status = Status.TIME_LIMIT if stopped else Status.SOLVED
    stage = ("pade_augmented_are" if method == "pade" else "sampled_shift_register_dare")
    route = Route([Stage(stage, "direct", "answered" if status is Status.SOLVED else status.value,
                         f"{res.solver_stats.native_status}, augmented dimension {sol['dim']}")])
    return _replace(res, verification=ver, message=msg, status=status, route=route)


def _options(
    method: object, order: object, sections: object, extrapolate: object
) -> tuple[str, int, int, bool]:
    """``(method, m, N, extrapolate)`` of :func:`output_delay_kalman`, validated (``m``: Pade degree or
    sampling steps, ``N``: sections or sampling steps)."""
    method = as_str("method", method, ("pade", "sample", "sampling"))
    method = "sample" if method == "sampling" else method
    extrapolate = as_bool("extrapolate", extrapolate)
    if method == "pade":
        m = 4 if order is None else as_int("order", order, 1)
        N = 8 if sections is None else as_int("sections", sections, 1)
        return method, m, N, extrapolate
    if sections is not None:
        raise ValidationError(f"sections is only used with method='pade'; found sections={sections!r}")
    N = 32 if order is None else as_int("order", order, 1)
    if extrapolate and N % 2:
        raise ValidationError(f"extrapolate=True needs an even order; found {N}")
    return method, N, N, extrapolate


def _solve_with_estimate(method: str, m: int, N: int, extrapolate: bool, system: _System, deadline: Deadline
                         ) -> tuple[dict[str, Any], dict[str, Any] | None, str]:
    """The filter of the requested order and a coarser one (the convergence estimate, or the second
    half of the Richardson step).  The coarser solve is skipped once ``deadline`` has expired: the
    finer answer is returned (not extrapolated) with the reason as the third value."""
    sol = _solve(method, *system, m, N)
    has_coarse = m > 1 if method == "pade" else N >= 2
    if not has_coarse:
        return sol, None, ""
    if deadline.expired:
        what = "Richardson extrapolation" if method == "sample" and extrapolate else "convergence estimate"
        return sol, None, (f"time_limit {deadline.limit:g} s reached after the order-{m} solve: no {what} "
                           f"(coarser order not solved); the answer is the order-{m} filter")
    if method == "pade":
        return sol, _solve(method, *system, m - 1, N), ""
    half = _solve(method, *system, N // 2, N // 2)
    if not extrapolate:
        return sol, half, ""
    out = dict(sol)
    out["K_theta"] = (4 * sol["K_theta"][::2] - half["K_theta"]) / 3
    out["p1"] = (4 * sol["p1"][::2] - half["p1"]) / 3
    out["p0"] = out["p1"][0].copy()
    out["K0"] = out["K_theta"][0].copy()
    out["residual"] = max(sol["residual"], half["residual"])
    out["stable"] = sol["stable"] and half["stable"]
    return out, half, ""   # |extrapolated - half| over-estimates the error of the extrapolation


def _replace(obj: Any, **kw: Any) -> Any:
    from dataclasses import replace

    return replace(obj, **kw)


def output_delay_convergence(
    A: ArrayLike,
    C0: ArrayLike,
    C1: ArrayLike,
    h: float,
    Q: ArrayLike,
    R: ArrayLike,
    *,
    method: str = "pade",
    orders: ArrayLike = (1, 2, 3, 4, 5, 6),
    sections: int = 1,
    G: ArrayLike | None = None,
) -> tuple[ConvergenceRow, ...]:
    """p0 and K0 of the delayed-output filter for a sequence of approximation orders.

    ``method="pade"``: Pade degree per section (``sections`` fixed, default one section -- the
    single ``[m/m]`` approximant of ``exp(-sh)``); ``method="sample"``: number of sampling steps per
    delay (no extrapolation, so the first-order convergence is visible).

    Returns
    -------
    tuple of ConvergenceRow

    Raises
    ------
    ValidationError
        Unknown method, ``orders`` not integers ``>= 1``, ``sections`` not an integer ``>= 1``, and
        the errors of :func:`output_delay_kalman` for the system matrices.
    RiccatiError
        An augmented Riccati equation has no stabilizing solution.
    """
    A, C0, C1, h, W, R = _validate(A, C0, C1, h, Q, R, G)
    method = as_str("method", method, ("pade", "sample"))
    sections = as_int("sections", sections, 1)
    ks = as_vector("orders", orders)
    bad = [o for o in ks if not (o == int(o) and o >= 1)]
    if bad or ks.size == 0:
        found = f"{bad[0]:g}" if bad else "none"
        raise ValidationError(f"orders must be integers >= 1 (at least one); found {found}")
    rows = []
    for k in (int(o) for o in ks):
        if method == "pade":
            s = _solve(method, A, C0, C1, W, R, h, k, sections)
            rows.append(ConvergenceRow("pade", k, sections, h / sections, s["dim"], s["p0"], s["K0"]))
        else:
            s = _solve(method, A, C0, C1, W, R, h, k, k)
            rows.append(ConvergenceRow("sample", k, k, h / k, s["dim"], s["p0"], s["K0"]))
    return tuple(rows)
