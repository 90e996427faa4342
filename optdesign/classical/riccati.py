r"""Algebraic Riccati equations: the steady-state Kalman filter and independent solvers.

Two independent ways to the stabilizing solution:

* ``method="scipy"`` -- :func:`scipy.linalg.solve_continuous_are` /
  :func:`scipy.linalg.solve_discrete_are` (extended-pencil QZ with balancing);
* ``method="hamiltonian"`` -- :func:`hamiltonian_are` (ordered real Schur form of the
  Hamiltonian matrix, seed 001 eq (25)-(27)) and :func:`symplectic_dare` (ordered QZ of the
  symplectic pencil), written here from the textbook construction.

Filter form (the estimator's equations; ``W = G Q G'`` is the state-space process noise):

continuous (``plant.dt is None``)::

    A P + P A' - P C' R^-1 C P + W = 0,      L = P C' R^-1

discrete, a-priori / predictor form::

    P = A P A' - A P C' (C P C' + R)^-1 C P A' + W,
    L = A P C' (C P C' + R)^-1   (predictor gain),   Kf = P C' (C P C' + R)^-1 (filter gain)

so in both cases the estimation error obeys the dynamics ``A - L C``.  By duality the
filter equation is the control-form equation with ``a = A'``, ``b = C'``, ``q = W``, ``r = R``.

References
----------
Jung, J. & Huh, K., seed 001, eq (23)-(27): Riccati equation of the Kalman filter and its
solution ``P = Y X^-1`` from the stable eigenvectors of the Hamiltonian.
Laub, A. J., "A Schur method for solving algebraic Riccati equations", IEEE TAC 24 (1979)
913-921.
Pappas, T., Laub, A. J. & Sandell, N. R., "On the numerical solution of the discrete-time
algebraic Riccati equation", IEEE TAC 25 (1980) 631-641.
Benner, P., "Symplectic balancing of Hamiltonian matrices", SIAM J. Sci. Comput. 22 (2001).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg
from numpy.typing import ArrayLike, NDArray

from .._validate import as_square, check_symmetric
from ..analysis.conditioning import lyapunov_solve, rounding_response, sampled_response
from ..errors import RiccatiError, ValidationError
from ..model.plant import Plant
from .schur_are import format_pole, hamiltonian_are, symplectic_dare

__all__ = [
    "AREResult",
    "format_pole",
    "sort_poles",
    "AREErrorEstimate",
    "filter_are",
    "filter_are_error",
    "filter_are_residual",
    "filter_are_terms",
    "filter_gain",
    "filter_dare_doubling",
    "relative_residual",
    "are_error_of_terms",
    "are_correction_of_terms",
    "hamiltonian_are",
    "symplectic_dare",
    "RESIDUAL_TOL",
]

_EPS = float(np.finfo(float).eps)

#: default bound on the relative residual accepted by :func:`filter_are`
RESIDUAL_TOL = 1e-8



# ---------------------------------------------------------------------- filter ARE
@dataclass(frozen=True, eq=False)
class AREResult:
    """Stabilizing solution of a filter Riccati equation.

    Attributes
    ----------
    P : (n, n) ndarray
        Steady-state error covariance (a-priori / predicted covariance in discrete time).
    L : (n, p) ndarray
        Observer gain with error dynamics ``A - L C``: ``P C' R^-1`` (continuous) or the
        predictor gain ``A P C' (C P C' + R)^-1`` (discrete).
    poles : (n,) ndarray of complex
        ``eig(A - L C)``, sorted by real part then imaginary part.
    residual : float
        Relative residual (:func:`filter_are_residual`), computed independently of the solver.
    method : str
        ``"scipy"`` or ``"hamiltonian"``.
    Kf : (n, p) ndarray or None
        Discrete time only: the filter (measurement-update) gain ``P C' (C P C' + R)^-1``,
        with ``L = A Kf``.  None in continuous time.
    """

    P: NDArray[np.float64]
    L: NDArray[np.float64]
    poles: NDArray[np.complex128]
    residual: float
    method: str
    Kf: NDArray[np.float64] | None = None

    def __repr__(self) -> str:
        kind = "discrete" if self.Kf is not None else "continuous"
        return (f"AREResult({kind}, method={self.method!r}, n={self.P.shape[0]}, "
                f"residual={self.residual:.2e})")


def _process_noise(plant: Plant, Q: ArrayLike | None, Qs: ArrayLike | None) -> NDArray:
    n = plant.n
    if Q is not None and Qs is not None:
        raise ValidationError(
            "give at most one of Q (noise-input covariance) and Qs (state-space covariance)"
        )
    if Qs is not None:
        return check_symmetric("Qs", as_square("Qs", Qs, n))
    if Q is not None:
        Qm = check_symmetric("Q", as_square("Q", Q, plant.m))
        W = plant.G @ Qm @ plant.G.T
        return 0.5 * (W + W.T)
    return plant.process_noise()


def _require_R(plant: Plant) -> NDArray:
    if plant.R is None:
        label = f" {plant.name!r}" if plant.name else ""
        raise ValidationError(f"plant{label} has no R: the filter Riccati equation needs the "
                              f"measurement-noise covariance R")
    return plant.R


def filter_are_residual(
    plant: Plant, P: ArrayLike, Q: ArrayLike | None = None, *, Qs: ArrayLike | None = None
) -> float:
    r"""Relative residual of the filter Riccati equation for a given P.

    Continuous: ``Res = A P + P A' - P C' R^-1 C P + W``;
    discrete: ``Res = A P A' - A P C' (C P C' + R)^-1 C P A' + W - P``; the relative residual
    is ``||Res||_F`` divided by the sum of the Frobenius norms of the terms (so it lies in
    [0, 1]; 0 when every term vanishes).

    Parameters
    ----------
    plant : Plant
        Supplies A, C, G, R (and Q unless overridden); continuous or discrete by ``plant.dt``.
    P : (n, n) array_like
    Q : (m, m) array_like, optional
        Noise-input covariance to use instead of ``plant.Q``; ``W = G Q G'``.
    Qs : (n, n) array_like, optional
        State-space process-noise covariance ``W`` to use directly (for instance a Q found by
        an inverse-Kalman design), ignoring G.  At most one of ``Q``, ``Qs``.

    Returns
    -------
    float

    Raises
    ------
    ValidationError
        No Q available (neither in the plant nor given), no R, or both Q and Qs given.
    DimensionError, NotFiniteError, NotSymmetricError
        Bad P, Q or Qs.
    """
    R = _require_R(plant)
    W = _process_noise(plant, Q, Qs)
    P = as_square("P", P, plant.n)
    return relative_residual(*filter_are_terms(plant.A, plant.C, R, W, P, plant.is_discrete))


def relative_residual(res: NDArray, terms: list[NDArray]) -> float:
    """``||res||_F`` over the sum of the Frobenius norms of ``terms`` (0 when res is 0; inf when
    every term vanishes but res does not): :func:`filter_are_residual` from
    :func:`filter_are_terms`."""
    num = float(np.linalg.norm(res))
    den = float(sum(np.linalg.norm(t) for t in terms))
    if num == 0.0:
        return 0.0
    return num / den if den > 0 else float("inf")


def filter_gain(A: NDArray, C: NDArray, R: NDArray, P: NDArray, discrete: bool) -> NDArray:
    """The Kalman gain of a filter-ARE solution P: ``P C' R^-1`` (continuous) or the predictor gain
    ``A P C' (C P C' + R)^-1`` (discrete); arrays taken as validated."""
    if discrete:
        return np.linalg.solve(C @ P @ C.T + R, C @ P @ A.T).T
    return np.linalg.solve(R, C @ P).T


def filter_are_terms(A: NDArray, C: NDArray, R: NDArray, W: NDArray, P: NDArray,
                     discrete: bool) -> tuple[NDArray, list[NDArray]]:
    """The residual matrix of the filter Riccati equation at P and its terms (float arrays taken
    as validated: A, W, P (n, n), C (p, n), R (p, p))."""
    if discrete:
        APA = A @ P @ A.T
        S = C @ P @ C.T + R
        K = A @ P @ C.T
        corr = K @ np.linalg.solve(S, K.T)
        return APA - corr + W - P, [APA, corr, W, P]
    AP = A @ P
    PCt = P @ C.T
    corr = PCt @ np.linalg.solve(R, PCt.T)
    return AP + AP.T - corr + W, [AP, AP.T, corr, W]


@dataclass(frozen=True)
class AREErrorEstimate:
    """How far a computed filter-ARE solution is from the exact one (first order).

    Attributes
    ----------
    relative : float
        ``(correction + floor) / ||P||`` (Frobenius; ``||P||`` replaced by 1 when P = 0): the
        estimated relative forward error.
    correction : float
        ``||E||`` with ``E = -Omega^{-1}(Res(P))`` the Newton correction (``Omega`` the Lyapunov
        operator of ``F = A - L C``): the error the residual of this P explains.
    floor : float
        The response of the solution to rounding of the equation's terms
        (:func:`~optdesign.analysis.conditioning.rounding_response` at ``n eps (sum |terms| + |P|)``):
        what a computed solution cannot be trusted beyond (inf when ``A - L C`` is not stable).
    """

    relative: float
    correction: float
    floor: float


def filter_are_error(plant: Plant, P: ArrayLike, *, Qs: ArrayLike | None = None) -> AREErrorEstimate:
    r"""A posteriori forward error estimate of a filter-ARE solution P.

    The exact stabilizing solution is ``P + E`` to first order, where E solves the Lyapunov
    equation of the error dynamics ``F = A - L C`` (L the gain of P) with the residual of P:
    continuous ``F E + E F' = -Res(P)``, discrete ``E - F E F' = Res(P)``
    (:mod:`optdesign.analysis.conditioning`).  To ``||E||`` is added the rounding floor: the
    response of the solution to perturbations of the equation's terms by ``n eps`` times their
    entries (a two-sample statistical estimate).  The estimate follows the answer at hand: a
    solver that loses digits shows them in its residual, and an ill-conditioned equation
    (closed-loop poles near the stability boundary) in its floor -- whatever the CPU.  Checked on
    CAREX / DAREX against analytic solutions and between solvers (``tests/test_riccati.py``).

    Parameters
    ----------
    plant : Plant
        A, C, R (and the process noise unless ``Qs`` is given); continuous or discrete.
    P : (n, n) array_like
    Qs : (n, n) array_like, optional
        State-space process-noise covariance to use instead of the plant's ``G Q G'``.

    Returns
    -------
    AREErrorEstimate

    References
    ----------
    Kenney, Laub & Wette, Systems & Control Letters 12 (1989); Kenney & Laub, SIAM J. Sci.
    Comput. 15 (1994); Sun, SIAM J. Matrix Anal. Appl. 19 (1998).
    """
    R = _require_R(plant)
    W = _process_noise(plant, None, Qs)
    P = as_square("P", P, plant.n)
    A, C, disc = plant.A, plant.C, plant.is_discrete
    res, terms = filter_are_terms(A, C, R, W, P, disc)
    return are_error_of_terms(A, C, R, P, res, terms, disc)


def are_error_of_terms(A: NDArray, C: NDArray, R: NDArray, P: NDArray, res: NDArray, terms: list[NDArray],
                       discrete: bool) -> AREErrorEstimate:
    """:func:`filter_are_error` from the residual and terms of :func:`filter_are_terms` (float
    arrays taken as validated).  In continuous time one real Schur form of ``F = A - L C`` serves
    the three Lyapunov solves of the estimate (the rounding response's two samples and the Newton
    correction), each as :func:`scipy.linalg.solve_continuous_lyapunov` does them."""
    return are_correction_of_terms(A, C, R, P, res, terms, discrete)[0]


def are_correction_of_terms(A: NDArray, C: NDArray, R: NDArray, P: NDArray, res: NDArray,
                            terms: list[NDArray], discrete: bool) -> tuple[AREErrorEstimate, NDArray | None]:
    """:func:`are_error_of_terms` and the Newton correction E itself (None when it could not be
    computed): ``P + E`` is one Newton (Kleinman) step of the Riccati equation from P -- the
    stabilizing solution to second order in the error of P when ``A - L C`` is stable."""
    n = A.shape[0]
    inf = AREErrorEstimate(float("inf"), float("inf"), float("inf"))
    with np.errstate(all="ignore"):
        try:
            L = filter_gain(A, C, R, P, discrete)
        except np.linalg.LinAlgError:
            return inf, None
    F = A - L @ C
    magnitude = n * _EPS * (sum(np.abs(t) for t in terms) + np.abs(P))
    magnitude = 0.5 * (magnitude + magnitude.T)
    if discrete:
        floor = rounding_response(F, magnitude, discrete)
        solve = None
    else:
        solve, floor = _continuous_rounding_response(F, magnitude)
    if not np.isfinite(floor):
        return inf, None
    E: NDArray | None
    try:
        with np.errstate(all="ignore"):
            E = lyapunov_solve(F, res, discrete) if solve is None else solve(-res)
        corr = float(np.linalg.norm(E))
    except (np.linalg.LinAlgError, ValueError):
        E, corr = None, float("inf")
    nP = float(np.linalg.norm(P))
    return AREErrorEstimate((corr + floor) / (nP if nP > 0 else 1.0), corr, floor), E


def _continuous_rounding_response(F: NDArray, magnitude: NDArray, samples: int = 2, seed: int = 0):
    """``(solve, floor)``: ``solve(rhs)`` the solution of ``F Z + Z F' = rhs`` from one real Schur
    form of F, and :func:`~optdesign.analysis.conditioning.rounding_response` computed with it (the
    same seeded sign patterns; inf, and ``solve`` None, when F is not stable or a solve fails)."""
    n = F.shape[0]
    if n == 0:
        return (lambda rhs: np.zeros_like(rhs)), 0.0
    try:
        T, U = scipy.linalg.schur(F, output="real", check_finite=False)
    except (np.linalg.LinAlgError, ValueError):
        return None, float("inf")
    if not np.all(np.isfinite(T)) or np.max(np.diag(T)) >= 0.0:  # diag(T): the real parts of eig(F)
        return None, float("inf")
    trsyl = scipy.linalg.get_lapack_funcs("trsyl", (T,))

    def solve(rhs: NDArray) -> NDArray:
        y, scale, info = trsyl(T, T, U.T.dot(rhs.dot(U)), tranb="T")
        if info < 0:
            raise ValueError(f"?TRSYL: illegal value in argument number {-info}")
        return U.dot(y * scale).dot(U.T)

    worst = sampled_response(solve, magnitude, samples=samples, seed=seed)
    return (solve, worst) if np.isfinite(worst) else (None, float("inf"))


def _unexcited_boundary_modes(A: NDArray, F: NDArray, discrete: bool) -> NDArray[np.complex128]:
    """Eigenvalues of A on the imaginary axis (unit circle) that are uncontrollable from F.

    Candidates are the eigenvalues within ``h = 10 sqrt(eps) max(1, ||A||)`` of the boundary
    (a defective eigenvalue is split by rounding by about ``sqrt(eps) ||A||``); candidates
    closer than ``h`` to each other are clustered and replaced by their mean, which is
    accurate to O(eps ||A||) even when the members are not.  A cluster of size k is
    uncontrollable when ``[lambda I - A, F]`` has (up to k) singular values below
    ``1e3 n eps max(||A||, ||F||, 1)`` (PBH test).  The tight rank threshold matters for
    badly scaled plants such as CAREX 2.9 (||A|| = 1.6e7), whose lightly damped modes are
    weakly (sigma_min ~ 3e-10 ||A||) but genuinely excited by the noise.
    """
    n = A.shape[0]
    eps = _EPS
    # diagonal balancing (exact, powers of 2) keeps eigenvalues and controllability and
    # removes the artificial non-normality of badly scaled models (CAREX 2.9: ||A|| 1.6e7 -> 1.1e3)
    A, (sca, _) = scipy.linalg.matrix_balance(A, permute=False, separate=True)
    F = F / sca[:, None]
    scale = max(1.0, float(np.linalg.norm(A, 2)))
    h = 10.0 * np.sqrt(eps) * scale
    lam = np.linalg.eigvals(A)
    dist = np.abs(np.abs(lam) - 1.0) if discrete else np.abs(lam.real)
    cand = lam[dist <= h]
    clusters: list[list[complex]] = []
    for z in cand:
        for cl in clusters:
            if abs(z - np.mean(cl)) <= h:
                cl.append(complex(z))
                break
        else:
            clusters.append([complex(z)])
    thr = 1e3 * n * eps * max(scale, float(np.linalg.norm(F, 2)))
    out: list[complex] = []
    for cl in clusters:
        z = complex(np.mean(cl))
        M = np.hstack([z * np.eye(n) - A, F.astype(complex)])
        sv = np.linalg.svd(M, compute_uv=False)
        deficiency = int(np.sum(sv < thr))
        if not discrete:  # on the axis: the real part is rounding noise
            z = complex(0.0, z.imag)
        if abs(z.imag) <= 1e3 * n * eps * scale:
            z = complex(z.real, 0.0)
        out.extend([z] * min(deficiency, len(cl)))
    return np.asarray(out, dtype=complex)


def _require_noise_reaches_boundary_modes(plant: Plant, Q: NDArray[np.float64]) -> None:
    """(A, G Q^1/2) must have no uncontrollable mode on the imaginary axis / unit circle."""
    lam, V = np.linalg.eigh(Q)
    # drop rounding-level eigenvalues of Q: their square roots (~sqrt(eps)) would fake excitation
    keep = lam > 1e3 * plant.m * _EPS * max(float(np.max(np.abs(lam))), np.finfo(float).tiny)
    F = plant.G @ (V[:, keep] * np.sqrt(lam[keep])) if np.any(keep) else np.zeros((plant.n, 1))
    bad = _unexcited_boundary_modes(plant.A, F, plant.is_discrete)
    where = "unit circle" if plant.is_discrete else "imaginary axis"
    if bad.size:
        label = f" of plant {plant.name!r}" if plant.name else ""
        shown = ", ".join(format_pole(z) for z in bad)
        raise RiccatiError(
            f"no stabilizing solution of the filter Riccati equation{label}: mode(s) {shown} on the "
            f"{where} are not excited by the process noise ((A, G Q^1/2) has uncontrollable "
            f"mode(s) on the {where}), so the optimal filter leaves them unstabilized"
        )


def sort_poles(p: NDArray) -> NDArray[np.complex128]:
    """Poles sorted by real part, then imaginary part (conjugate pairs adjacent).

    Examples
    --------
    >>> from optdesign.riccati import sort_poles
    >>> sort_poles([-1 + 2j, -3, -1 - 2j]).tolist()
    [(-3+0j), (-1-2j), (-1+2j)]
    """
    p = np.asarray(p, dtype=complex)
    return p[np.lexsort((p.imag, p.real))]


def filter_dare_doubling(A: NDArray, C: NDArray, Q: NDArray, R: NDArray, maxit: int = 60) -> NDArray | None:
    """Stabilizing solution P (n x n) of the filter DARE ``P = A P A' - A P C' (C P C' + R)^-1 C P A' + Q``
    by the structure-preserving doubling algorithm (E. K.-W. Chu, H.-Y. Fan, W.-W. Lin and C.-S. Wang,
    *Int. J. Control* 77 (2004); the iteration as in F. Poloni's review of doubling algorithms,
    arXiv:2005.08903), or None when it does not converge in ``maxit`` doublings (no stabilizing
    solution, eigenvalues on the unit circle: the caller falls back to scipy's QZ solver).
    Without detectability of (A, Q) it can converge to a PSD solution that is not the stabilizing
    one: the caller checks the filter's poles and falls back then too.

    A (n x n), C (p x n), Q (n x n) PSD, R (p x p) positive definite, float arrays taken as validated
    (an inner-loop solver, as :func:`filter_gain`).  ``I + G H`` stays
    invertible (G, H PSD), so every step is defined; convergence is quadratic when a stabilizing
    solution exists.  The first solver of the closest-poles search's inner loop
    (``fast_pole_error`` of ``optdesign.design.inverse_kalman``): 2.0-5.1x less CPU than
    ``scipy.linalg.solve_discrete_are(balanced=False)`` at n = 2-10, p = 1-2 (1.3-3.9x in two earlier
    runs of the same plants), the largest relative residual (:func:`filter_are_residual`) per size
    1e-14 to 9e-9 where scipy's is 3e-11 to 5e-3 (``benchmarks/bench_dare_doubling.py``,
    ``benchmarks/results/dare_doubling.md``, AMD EPYC).
    """
    n = A.shape[0]
    Ak, Gk, Hk = A.T, C.T @ np.linalg.solve(R, C), Q
    eye = np.eye(n)
    tol = 8.0 * n * np.finfo(float).eps
    for _ in range(maxit):
        try:
            Winv = np.linalg.inv(eye + Gk @ Hk)
        except np.linalg.LinAlgError:  # Q not PSD to working precision
            return None
        WA = Winv @ Ak
        Hn = Hk + Ak.T @ Hk @ WA
        Gk = Gk + Ak @ Winv @ Gk @ Ak.T
        Ak = Ak @ WA
        change, size = np.abs(Hn - Hk).sum(), np.abs(Hn).sum()
        Hk = Hn
        if not np.isfinite(size):
            return None
        if change <= tol * size:
            return 0.5 * (Hk + Hk.T)
    return None


def filter_are(
    plant: Plant, method: str = "scipy", *, residual_tol: float = RESIDUAL_TOL
) -> AREResult:
    r"""Steady-state Kalman filter Riccati equation of a plant (continuous or discrete).

    Continuous (``plant.dt is None``, seed 001 eq (23)-(24))::

        A P + P A' - P C' R^-1 C P + G Q G' = 0,    L = P C' R^-1

    Discrete (a-priori / predictor DARE)::

        P = A P A' - A P C'(C P C' + R)^-1 C P A' + G Q G',
        L = A P C'(C P C' + R)^-1,    Kf = P C'(C P C' + R)^-1

    In both cases the error dynamics are ``A - L C`` and ``poles = eig(A - L C)``.

    Parameters
    ----------
    plant : Plant
        Must carry Q and R.
    method : {"scipy", "hamiltonian"}
        ``"scipy"``: :func:`scipy.linalg.solve_continuous_are` / ``solve_discrete_are``;
        ``"hamiltonian"``: :func:`hamiltonian_are` / :func:`symplectic_dare`.
    residual_tol : float
        The relative residual (:func:`filter_are_residual`) must not exceed this.

    Returns
    -------
    AREResult

    Raises
    ------
    ValidationError
        The plant has no Q or no R; unknown method.
    NotObservableError
        (C, A) is not detectable (the message and ``.modes`` name the undetectable modes).
    RiccatiError
        (A, G Q^1/2) has an uncontrollable mode on the imaginary axis / unit circle (named);
        the solver failed (its reason is given); the residual exceeds ``residual_tol``; the
        closed loop is not stable.

    References
    ----------
    Seed 001 (Jung & Huh), eq (23)-(27).

    Examples
    --------
    >>> from optdesign import Plant
    >>> from optdesign.riccati import filter_are
    >>> res = filter_are(Plant([[0., 1.], [0., 0.]], [[1., 0.]], G=[[0.], [1.]], Q=[[4.]], R=[[0.25]]))
    >>> res.P.round(6).tolist()
    [[0.707107, 1.0], [1.0, 2.828427]]
    """
    if method not in ("scipy", "hamiltonian"):
        raise ValidationError(f"method must be 'scipy' or 'hamiltonian'; found {method!r}")
    Q, R = plant.noise_covariances()
    plant.require_observable(detectable_ok=True, what="a stabilizing Kalman filter")
    W = plant.process_noise()
    _require_noise_reaches_boundary_modes(plant, Q)
    A, C = plant.A, plant.C
    try:
        if method == "scipy":
            solve = (scipy.linalg.solve_discrete_are if plant.is_discrete
                     else scipy.linalg.solve_continuous_are)
        else:
            solve = symplectic_dare if plant.is_discrete else hamiltonian_are
        P = solve(A.T, C.T, W, R)
    except RiccatiError:
        raise
    except (np.linalg.LinAlgError, ValueError) as exc:
        raise RiccatiError(f"filter_are ({method}): the solver failed: {exc}") from exc
    P = 0.5 * (P + P.T)
    if plant.is_discrete:
        S = C @ P @ C.T + R
        Kf = np.linalg.solve(S, C @ P).T
        L = A @ Kf
    else:
        Kf = None
        L = np.linalg.solve(R, C @ P).T
    poles = sort_poles(np.linalg.eigvals(A - L @ C))
    residual = filter_are_residual(plant, P)
    if not residual <= residual_tol:
        raise RiccatiError(
            f"filter_are ({method}): relative residual {residual:.3g} exceeds {residual_tol:.3g}; "
            f"the solution is not accurate (ill-conditioned equation?)"
        )
    if plant.is_discrete:
        rho = float(np.max(np.abs(poles)))
        if not rho < 1.0:
            raise RiccatiError(f"filter_are ({method}): the filter is not stable (spectral radius "
                               f"of A - L C = {rho:.6g} >= 1)")
    else:
        alpha = float(np.max(poles.real))
        if not alpha < 0.0:
            raise RiccatiError(f"filter_are ({method}): the filter is not stable (max Re eig(A - L C) "
                               f"= {alpha:.6g} >= 0)")
    return AREResult(P=P, L=L, poles=poles, residual=residual, method=method, Kf=Kf)



# the former private spellings (still imported by modules being moved to the public names)
_fmt = format_pole
_sort_poles = sort_poles
