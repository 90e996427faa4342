r"""Robustness of state estimators: return difference, circle condition, margins.

The loop of a filter
--------------------
The observer / Kalman filter ``x_hat' = A x_hat + L nu``, ``nu = y - C x_hat`` is a feedback loop
around the innovation ``nu``.  Throughout this module **the loop is broken at the filter input**,
i.e. at the innovation, where the measurement residual enters the gain ``L``.  A perturbation
``Delta`` (p x p) inserted there gives

    x_hat' = A x_hat + L Delta nu,        error dynamics  A - L Delta C,

and the loop transfer matrix seen from the break point is ``G(s) = C (sI - A)^-1 L`` (p x p).
This is the dual of the LQ regulator's loop, which is broken at the plant input with
``A - B Delta K``: transposing one gives the other.  The **return difference** is

    T(s) = I + C (sI - A)^-1 L,            det(sI - A + L Delta C) = det(sI - A) det(I + G(s) Delta),

and ``T(s)^-1 = I - C (sI - A + L C)^-1 L`` is the (output) sensitivity of the filter loop.

Continuous time (seed 002, eqs 16-19).  If ``L = P C' R^-1`` with ``P`` the stabilizing solution of
``A P + P A' - P C' R^-1 C P + W = 0`` (``W = G Q G'``), then for every s

    T(s) R T(-s)' = R + C (sI - A)^-1 W (-sI - A)^-T C',

so on the imaginary axis ``T(jw) R T(jw)^* >= R`` (the *circle condition*).

Discrete time (predictor filter ``x_hat[k+1] = A x_hat[k] + L (y[k] - C x_hat[k])``, error
dynamics ``A - L C``, ``L = A P C' V^-1``, ``V = C P C' + R``, ``P`` the DARE solution
``P = A P A' - A P C' V^-1 C P A' + W``), with ``z = e^{j w dt}``, ``T(z) = I + C (zI - A)^-1 L``:

    T(z) V T(1/z)' = R + C (zI - A)^-1 W (z^-1 I - A)^-T C',

hence on the unit circle ``T V T^* >= R`` -- **not** ``T R T^* >= R``, which can fail for an
optimal discrete filter.  Derivation: write ``P - A P A' = (zI - A) P (z^-1 I - A') + (zI - A) P A'
+ A P (z^-1 I - A')``, use the DARE ``P - A P A' = W - L V L'``, multiply by ``C (zI - A)^-1`` on the
left and ``(z^-1 I - A')^-1 C'`` on the right, use ``A P C' = L V`` and add ``R`` to both sides.  If A is
invertible, ``V`` is determined by ``L`` alone: ``A P C' = L V`` gives ``C P C' = C A^-1 L V`` so
``V = (I - C A^-1 L)^-1 R = T(0)^-1 R`` (whatever ``W`` is).

Guaranteed margins (what holds simultaneously and what does not)
----------------------------------------------------------------
Write ``I + G Delta = [T + (Delta^-1 - I)] Delta``.  With ``Ts = R^-1/2 T R^1/2`` the circle condition
reads ``sigma_min(Ts(jw)) >= 1``, so ``I + G Delta`` is nonsingular on the whole axis whenever
``sigma_max(R^-1/2 (Delta^-1 - I) R^1/2) < 1``; a homotopy from ``Delta = I`` (convex set, closed-loop
eigenvalues continuous and bounded) then shows the perturbed filter stays stable, given that
``A - L C`` is stable and A has no eigenvalue on the imaginary axis (the hypothesis of seed 002
Theorem 2; T is undefined there).  This is what the tests verify with closed-loop eigenvalues of
``A - L Delta C`` for constant complex ``Delta`` (a "phase" perturbation is ``exp(j phi)``).
For **diagonal R** and **diagonal** ``Delta = diag(delta_i)`` (complex constants) this is
``max_i |1/delta_i - 1| < 1``, i.e. ``Re delta_i > 1/2`` for every i, **in all channels
simultaneously**.  In particular

* gain perturbations ``delta_i = k_i`` with every ``k_i`` in ``(1/2, inf)``, simultaneously and
  independently in all channels;
* phase perturbations ``delta_i = exp(j phi_i)`` with every ``|phi_i| < 60 deg``, simultaneously
  (signs may differ between channels);
* mixed per-channel perturbations ``k_i exp(j phi_i)`` only when ``k_i cos(phi_i) > 1/2``: the
  gain and phase margins do **not** hold together (a gain of 0.51 *and* a phase of 59 deg in the
  same channel can destabilize -- see ``tests/test_robustness.py``);
* non-diagonal (crossfeed) perturbations are covered only through the norm bound
  ``sigma_max(R^-1/2 (Delta^-1 - I) R^1/2) < 1``; e.g. ``Delta = [[1, x], [0, 1]]`` (eigenvalues at the
  nominal 1) is guaranteed for ``|x| < sqrt(r_1 / r_2)`` but can destabilize beyond; for the block
  forms of seed 002 eq (22) this gives ``sigma_max(X) < sqrt(sigma_min(R_1) / sigma_max(R_2))``.
* For **non-diagonal R** the per-channel statement is lost: only perturbations that commute with
  ``R^1/2`` -- e.g. the uniform ``Delta = delta I`` -- inherit the margins.

In discrete time ``T V T^* >= R`` gives ``sigma_min(Ts) >= 1/sqrt(lambda_max(R^-1 V))`` =: ``a`` and
the same argument with radius ``a < 1``: gain margin ``(1/(1+a), 1/(1-a))``, phase margin
``2 arcsin(a/2)``.

References
----------
S. J. Lee, "Frequency-domain properties of Kalman filters for linear systems with delay in
output" (seed 002), eqs (16)-(24).  R. E. Kalman, "When is a linear control system optimal?"
(1964).  M. G. Safonov and M. Athans, "Gain and phase margin for multiloop LQG regulators",
IEEE TAC 22 (1977).  N. A. Lehtomaki, N. R. Sandell, M. Athans, IEEE TAC 26 (1981).
U. Shaked, "Guaranteed stability margins for the discrete-time linear quadratic optimal
regulator", IEEE TAC 31 (1986).  P. Seiler, A. Packard, P. Gahinet, "An introduction to disk
margins", IEEE Control Systems 40 (2020).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._deadline import Deadline
from .._validate import as_bool, as_frequencies, as_matrix, as_positive_float, as_vector, check_pd
from ..errors import ValidationError
from ..model.plant import Plant
from .frequency import (
    CHUNK,
    adaptive_minimize,
    as_gain,
    frequency_grid,
    frequency_points,
    nudge_off_poles,
    return_difference_floor,
)

__all__ = [
    "return_difference",
    "circle_condition",
    "CircleConditionResult",
    "frequency_grid",
    "innovation_covariance",
    "resolve_R",
    "adaptive_minimize",
    "circle_search",
    "search_stopped",
    "worst_case_parts",
    "transfer_at",
    "sqrtm_pd",
    "is_diagonal",
    "is_stable_spectrum",
]

#: the margins moved to :mod:`optdesign.analysis.margins`; these names stay importable from here
_MOVED = ("filter_margins", "FilterMargins", "margins_from_radius")


def __getattr__(name: str):
    if name in _MOVED:
        from . import margins

        return getattr(margins, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")

_EPS = np.finfo(float).eps


# --------------------------------------------------------------------------- helpers
def _resolvent(A: NDArray, B: NDArray, pts: NDArray[np.complex128]) -> NDArray[np.complex128]:
    """(s I - A)^-1 B for every s in pts, shape (k, n, m).  Raises LinAlgError if singular."""
    n = A.shape[0]
    M = pts[:, None, None] * np.eye(n)[None] - A[None]
    return np.linalg.solve(M, np.broadcast_to(B.astype(complex), (pts.size,) + B.shape))


def transfer_at(A: NDArray, B: NDArray, C: NDArray, pts: NDArray[np.complex128]) -> NDArray[np.complex128]:
    return np.einsum("ij,kjl->kil", C, _resolvent(A, B, pts))


def sqrtm_pd(R: NDArray) -> tuple[NDArray, NDArray]:
    """Symmetric square root of a symmetric PD matrix and its inverse."""
    w, U = np.linalg.eigh(0.5 * (R + R.T))
    return (U * np.sqrt(w)) @ U.T, (U / np.sqrt(w)) @ U.T


def is_diagonal(R: NDArray) -> bool:
    off = R - np.diag(np.diag(R))
    return bool(np.max(np.abs(off), initial=0.0) <= 1e-12 * np.max(np.abs(np.diag(R))))


def is_stable_spectrum(eigs: NDArray, discrete: bool) -> bool:
    return bool(np.all(np.abs(eigs) < 1.0) if discrete else np.all(eigs.real < 0.0))


def resolve_R(plant: Plant, R: ArrayLike | None, what: str) -> NDArray[np.float64]:
    """The measurement-noise covariance of an analysis: ``R`` if given (checked symmetric PD, (p, p)),
    else ``plant.R``.

    Raises
    ------
    ValidationError
        Neither is available (the message names ``what`` needs it).
    DimensionError, NotFiniteError, NotSymmetricError, NotPositiveDefiniteError
        A malformed ``R``.
    """
    if R is None:
        if plant.R is None:
            raise ValidationError(
                f"{what} needs the measurement-noise covariance R: give R=... or a plant with R"
            )
        return np.asarray(plant.R, dtype=float)
    return check_pd("R", as_matrix("R", R, (plant.p, plant.p)))


_resolve_R = resolve_R  # the former private name (design/inverse_kalman.py imports it): use resolve_R

# --------------------------------------------------------------------------- return difference
def return_difference(
    plant: Plant, L: ArrayLike, omega: ArrayLike, *, time_limit: float | Deadline | None = None
) -> NDArray[np.complex128]:
    r"""Return difference of the filter loop broken at the filter input (the innovation).

    Continuous time: ``T(jw) = I + C (jw I - A)^-1 L``.
    Discrete time (predictor filter with error dynamics ``A - L C``): ``T(z) = I + C (zI - A)^-1 L``
    with ``z = exp(j w dt)``; ``w`` is in rad/s and the Nyquist frequency is ``pi / dt``.

    Parameters
    ----------
    plant : Plant
        Uses A (n, n), C (p, n) and dt.
    L : (n, p) array_like
        Filter (observer) gain, ``x_hat' = A x_hat + L (y - C x_hat)``.
    omega : (k,) array_like of float
        Frequencies in rad/s (a scalar is accepted; a negative frequency gives the conjugate of
        the positive one).
    time_limit : float, optional
        Seconds (``None``: no limit).  The frequencies are then evaluated in chunks of
        :data:`~optdesign.analysis.frequency.CHUNK`; those not reached when the limit expires
        (the first chunk always is) are NaN in ``T``, and a ``RuntimeWarning`` says how many.

    Returns
    -------
    T : (k, p, p) ndarray of complex

    Raises
    ------
    DimensionError
        L is not (n, p) or omega is not a vector.
    NotFiniteError
        L or omega contains NaN or Inf.
    ValidationError
        omega not numeric (strings are refused); a bad ``time_limit``; a frequency is a pole of
        the loop (``jw`` or ``z`` an eigenvalue of A), where T is undefined.

    References
    ----------
    Seed 002 (S. J. Lee), eq (16) with ``c1 = 0``.

    Examples
    --------
    >>> import numpy as np
    >>> from optdesign import Plant, kalman, return_difference
    >>> plant = Plant([[0., 1.], [-4., -0.2]], np.eye(2), Q=np.diag([0.1, 1.0]), R=np.diag([0.5, 2.0]))
    >>> T = return_difference(plant, kalman(plant).L, [0.0, 2.0, 10.0])   # T(jw) = I + C (jwI - A)^-1 L
    >>> T.shape, np.linalg.svd(T, compute_uv=False)[:, -1].round(3).tolist()
    ((3, 2, 2), [0.873, 0.856, 0.994])
    """
    L = as_gain(plant, L)
    w = as_vector("omega", omega)
    deadline = Deadline.of(time_limit)
    if not deadline.limited:
        return _return_difference(plant, L, w)
    T = np.full((w.size, plant.p, plant.p), np.nan, dtype=complex)
    done = 0
    while done < w.size and (done == 0 or not deadline.expired):  # the first chunk always
        T[done:done + CHUNK] = _return_difference(plant, L, w[done:done + CHUNK])
        done = min(done + CHUNK, w.size)
    if done < w.size:
        import warnings

        warnings.warn(f"return_difference: time_limit {deadline.limit:g} s reached after {done} of {w.size} "
                      "frequencies; T is NaN at the others", RuntimeWarning, stacklevel=2)
    return T


def _return_difference(plant: Plant, L: NDArray, w: NDArray) -> NDArray[np.complex128]:
    pts = frequency_points(plant, w)
    try:
        X = _resolvent(plant.A, L, pts)
    except np.linalg.LinAlgError:
        eig = np.linalg.eigvals(plant.A)
        d = np.min(np.abs(pts[:, None] - eig[None, :]), axis=1)
        bad = w[int(np.argmin(d))]
        raise ValidationError(
            f"omega = {bad:.6g} rad/s is a pole of the loop C (sI - A)^-1 L (an eigenvalue of A lies "
            f"{'on the unit circle' if plant.is_discrete else 'on the imaginary axis'} there): T is undefined"
        ) from None
    return np.eye(plant.p)[None] + np.einsum("ij,kjl->kil", plant.C, X)


# --------------------------------------------------------------------------- circle condition
def innovation_covariance(
    plant: Plant, L: ArrayLike, R: ArrayLike | None = None
) -> tuple[NDArray[np.float64], str]:
    r"""Innovation covariance ``V = C P C' + R`` implied by a discrete predictor gain.

    If A is invertible, ``V = T(0)^-1 R = (I - C A^-1 L)^-1 R`` -- true for the Kalman predictor gain
    of *any* process noise W (from ``A P C' = L V``), so the discrete circle condition needs no W.
    Otherwise, if the plant has Q, ``V = C P_L C' + R`` with ``P_L`` the steady error covariance of the
    predictor with gain L (``P_L = (A - LC) P_L (A - LC)' + G Q G' + L R L'``), which equals the DARE
    solution when L is the Kalman gain.

    Returns
    -------
    V : (p, p) ndarray
        Not symmetrized: an asymmetric V shows that L is no Kalman predictor gain for this R.
    source : str
        ``"T(0)^-1 R"`` or ``"lyapunov"``.

    Raises
    ------
    ValidationError
        The plant is continuous, or A is singular and the plant has no Q (pass ``V=`` to
        :func:`circle_condition`), or A - LC is not Schur stable in the Lyapunov fallback.
    """
    if not plant.is_discrete:
        raise ValidationError(
            "innovation_covariance is for discrete plants (dt given); in continuous time V = R")
    L = as_gain(plant, L)
    R = resolve_R(plant, R, "the discrete circle condition")
    A, C = plant.A, plant.C
    if np.linalg.cond(A) < 1e8:
        T0 = np.eye(plant.p) - C @ np.linalg.solve(A, L)
        return np.asarray(np.linalg.solve(T0, R), dtype=np.float64), "T(0)^-1 R"
    if plant.Q is None:
        raise ValidationError(
            f"A is singular (cond {np.linalg.cond(A):.3g}), so the innovation covariance V = CPC' + R is "
            "not determined by L: give V=... or a plant with Q"
        )
    from scipy.linalg import solve_discrete_lyapunov

    Acl = A - L @ C
    rho = float(np.max(np.abs(np.linalg.eigvals(Acl))))
    if rho >= 1.0:
        raise ValidationError(
            f"A - L C is not Schur stable (spectral radius {rho:.6g} >= 1): no steady error covariance"
        )
    P = solve_discrete_lyapunov(Acl, plant.process_noise() + L @ R @ L.T)
    return C @ P @ C.T + R, "lyapunov"


def _min_eig_values(T: NDArray, V: NDArray, R: NDArray) -> NDArray[np.float64]:
    X = T @ V[None].astype(complex) @ np.conj(np.swapaxes(T, 1, 2)) - R[None]
    X = 0.5 * (X + np.conj(np.swapaxes(X, 1, 2)))
    return np.linalg.eigvalsh(X)[:, 0]


@dataclass(frozen=True, eq=False)
class CircleConditionResult:
    r"""Outcome of :func:`circle_condition`.

    Attributes
    ----------
    min_eigenvalue : float
        ``min_w lambda_min(T(jw) V T(jw)^* - R)`` over the evaluated frequencies (continuous:
        ``V = R``).  Negative means the circle condition fails.
    omega_worst : float
        Frequency (rad/s) of that minimum.
    passed : bool
        ``min_eigenvalue >= -tol`` (and, in discrete time, V symmetric positive definite) over a
        complete search.  A search stopped by its time limit never passes: a violation it found
        is certain, the absence of one is not.
    omega, values : (k,) ndarrays
        Every frequency evaluated (grid and local refinement, sorted) and the smallest
        eigenvalue there.
    tol : float
        Absolute tolerance used for ``passed``.
    R, V : (p, p) ndarrays
        The weights of the inequality ``T V T^* >= R``.
    discrete : bool
    dt : float or None
    V_source : str
        ``"R"`` (continuous), ``"given"``, ``"T(0)^-1 R"`` or ``"lyapunov"``.
    T_worst : (p, p) ndarray of complex
        Return difference at ``omega_worst``.
    direction : (p,) ndarray of complex
        Unit eigenvector of ``T V T^* - R`` for its smallest eigenvalue at ``omega_worst``.
    perturbation : (p, p) ndarray of complex
        The smallest perturbation ``Delta`` at the filter input (smallest
        ``sigma_max(R^-1/2 (Delta^-1 - I) R^1/2) = sigma_min(R^-1/2 T R^1/2)``) that puts a
        closed-loop eigenvalue of ``A - L Delta C`` at ``j omega_worst`` (``exp(j omega_worst dt)``).
        When the continuous circle condition fails this lies inside the set the condition would
        cover, which is what makes it a certificate.
    message : str
    complete : bool
        False when ``time_limit`` stopped the search before the whole grid was evaluated and every
        local minimum refined.
    rounding_floor : float
        How far ``min_eigenvalue`` can be off by rounding alone (from the norms of ``T``, ``V``,
        ``C``, ``X = (sI - A)^-1 L`` and the condition of ``sI - A`` at ``omega_worst``:
        :func:`~optdesign.analysis.frequency.return_difference_floor`).
    """

    min_eigenvalue: float
    omega_worst: float
    passed: bool
    omega: NDArray[np.float64]
    values: NDArray[np.float64]
    tol: float
    R: NDArray[np.float64]
    V: NDArray[np.float64]
    discrete: bool
    dt: float | None
    V_source: str
    T_worst: NDArray[np.complex128]
    direction: NDArray[np.complex128]
    perturbation: NDArray[np.complex128]
    message: str = ""
    complete: bool = True
    rounding_floor: float = 0.0

    @property
    def violation_certain(self) -> bool:
        """A violation beyond both ``tol`` and the rounding floor: evidence that L is not a Kalman
        gain.  A violation inside the floor is rounding, not a certificate."""
        if not np.isfinite(self.min_eigenvalue):
            return False
        return bool(self.min_eigenvalue < -max(self.tol, self.rounding_floor))

    @property
    def certificate(self) -> dict[str, Any]:
        """Plain-data evidence (JSON-friendly): where and by how much the inequality is worst."""

        def c(x):
            a = np.asarray(x)
            return {"re": a.real.tolist(), "im": a.imag.tolist()}

        return {
            "inequality": "T V T^* - R >= 0" if self.discrete else "T R T^* - R >= 0",
            "passed": self.passed,
            "min_eigenvalue": self.min_eigenvalue,
            "omega_worst": self.omega_worst,
            "point": ("exp(j w dt)" if self.discrete else "j w"),
            "dt": self.dt,
            "tol": self.tol,
            "V_source": self.V_source,
            "direction": c(self.direction),
            "T_worst": c(self.T_worst),
            "destabilizing_perturbation": c(self.perturbation),
            "complete": self.complete,
            "rounding_floor": self.rounding_floor,
        }

    def summary(self) -> str:
        undecided = not self.complete and self.min_eigenvalue >= -self.tol
        verdict = "holds" if self.passed else "UNDECIDED (time limit)" if undecided else "FAILS"
        ineq = "T V T* >= R" if self.discrete else "T R T* >= R"
        return (
            f"circle condition {ineq} {verdict}: min eigenvalue {self.min_eigenvalue:.4g} at "
            f"omega = {self.omega_worst:.6g} rad/s ({self.omega.size} frequencies, tol {self.tol:.2g})"
            + (f"; {self.message}" if self.message else "")
        )

    def __repr__(self) -> str:
        return f"CircleConditionResult({self.summary()})"


def worst_case_parts(
    T_star: NDArray[np.complex128], V: NDArray[np.float64], R: NDArray[np.float64]
) -> tuple[NDArray[np.complex128], NDArray[np.complex128]]:
    """Eigenvector of ``T V T^* - R`` for its smallest eigenvalue, and the smallest destabilizing
    perturbation ``Delta`` at that frequency (``sigma_max(R^-1/2 (Delta^-1 - I) R^1/2) =
    sigma_min(R^-1/2 T R^1/2)``, ``det(T + Delta^-1 - I) = 0``)."""
    p = T_star.shape[0]
    X = T_star @ V @ T_star.conj().T - R
    _, U = np.linalg.eigh(0.5 * (X + X.conj().T))
    Rh, Rih = sqrtm_pd(R)
    Uu, s, Vh = np.linalg.svd(Rih @ T_star @ Rh)
    E = Rh @ (-s[-1] * np.outer(Uu[:, -1], Vh[-1])) @ Rih      # Vh[-1] = v^*
    try:
        Delta = np.linalg.inv(np.eye(p) + E)
    except np.linalg.LinAlgError:  # pragma: no cover - only if sigma_min == 1 exactly along u
        Delta = np.full((p, p), np.nan + 0j)
    return U[:, 0], Delta


def circle_search(
    T_of: Callable[[NDArray[np.float64]], NDArray[np.complex128]],
    grid: NDArray[np.float64],
    R: NDArray[np.float64],
    V: NDArray[np.float64],
    *,
    log: bool = True,
    refine: bool = True,
    n_refine: int = 8,
    deadline: Deadline | float | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64], bool]:
    """Adaptive search of ``min_w lambda_min(T(w) V T(w)^* - R)`` for any return difference ``T_of``.

    Used by :func:`circle_condition` and by the output-delay filter (whose T is not rational).
    Returns all evaluated frequencies and values, sorted by frequency, and whether the search
    completed within ``deadline`` (:func:`~optdesign.analysis.frequency.adaptive_minimize`).
    """
    Vs = 0.5 * (V + V.T)

    def f(w: NDArray) -> NDArray:
        return _min_eig_values(T_of(w), Vs, R)

    return adaptive_minimize(f, grid, n_refine=n_refine if refine else 0, log=log, deadline=deadline,
                             full_output=True)


def circle_condition(
    plant: Plant,
    L: ArrayLike,
    *,
    R: ArrayLike | None = None,
    omega: ArrayLike | None = None,
    V: ArrayLike | None = None,
    tol: float | None = None,
    refine: bool = True,
    time_limit: float | Deadline | None = None,
) -> CircleConditionResult:
    r"""Check the Kalman circle condition (return-difference inequality) of a filter gain.

    Continuous time: ``T(jw) R T(jw)^* - R >= 0`` for all w, ``T = I + C (jwI - A)^-1 L``.  Every
    stationary Kalman filter satisfies it (seed 002, eq 17 with ``c1 = 0``); a gain that violates it
    is not a Kalman gain for this R and any process noise.

    Discrete time (predictor, error dynamics ``A - L C``, ``z = exp(j w dt)``):
    ``T(z) V T(z)^* - R >= 0`` on the unit circle with ``V = C P C' + R`` the innovation covariance
    (derivation in the module docstring).  ``V`` defaults to :func:`innovation_covariance`
    (``T(0)^-1 R`` when A is invertible, which depends on L only).  ``T R T^* >= R`` itself is *not*
    implied in discrete time.

    The search is adaptive: :func:`frequency_grid` (log grid plus clusters resolving every open-
    and closed-loop pole, so a lightly damped dip of width ``|Re lambda|`` is sampled), then bounded
    scalar minimization around the lowest local minima.  In continuous time ``T -> I`` as
    ``w -> inf``, so for a Kalman filter the infimum 0 is approached at high frequency; the
    reported ``omega_worst`` is then near the top of the grid.

    Parameters
    ----------
    plant : Plant
        A (n, n), C (p, n), dt; R is taken from the plant unless given.
    L : (n, p) array_like
        Filter gain.
    R : (p, p) array_like, optional
        Measurement-noise covariance (symmetric PD); default ``plant.R``.
    omega : (k,) array_like, optional
        Frequencies (rad/s, finite, ``>= 0``, at least one) to use as the seed grid instead of
        :func:`frequency_grid`.
    V : (p, p) array_like, optional
        Discrete time only: innovation covariance.
    tol : float, optional
        Absolute tolerance for ``passed`` (finite, ``>= 0``); default ``1e-8 * ||R||_2``.
    refine : bool
        Refine local minima by bounded scalar minimization (default True).
    time_limit : float, optional
        Seconds (``None``: no limit).  When it runs out the search stops between chunks of the
        grid or between refinements, and the result has ``complete = False``: a violation found is
        reported (``passed`` False, with the frequency), otherwise the verdict is undecided
        (``passed`` False, the message says so).

    Returns
    -------
    CircleConditionResult

    Raises
    ------
    DimensionError, NotFiniteError
        L, R, V or omega malformed.
    NotPositiveDefiniteError
        R not positive definite.
    ValidationError
        No R available; V given for a continuous plant; V cannot be determined (discrete, A singular,
        no Q); omega empty, negative or not numeric; tol not a finite number >= 0; refine not a
        bool; a bad time_limit.

    References
    ----------
    Seed 002 (S. J. Lee), Theorem 1 / eq (17).  U. Shaked (1986) for the discrete-time form.

    Examples
    --------
    >>> import numpy as np
    >>> from optdesign import Plant, circle_condition, kalman
    >>> from optdesign.classical.placement import place_observer
    >>> plant = Plant([[0., 1.], [-4., -0.2]], np.eye(2), Q=np.diag([0.1, 1.0]), R=np.diag([0.5, 2.0]))
    >>> circle_condition(plant, kalman(plant).L).passed        # every Kalman gain passes
    True
    >>> bad = circle_condition(plant, place_observer(plant, [-0.05 + 2j, -0.05 - 2j]))
    >>> bad.passed, bad.omega_worst > 0                    # a placed gain fails, at a frequency
    (False, True)
    """
    deadline = Deadline.of(time_limit)
    L = as_gain(plant, L)
    R = resolve_R(plant, R, "the circle condition")
    refine = as_bool("refine", refine)
    p = plant.p
    message = ""
    if plant.is_discrete:
        if V is None:
            V, V_source = innovation_covariance(plant, L, R)
        else:
            V, V_source = as_matrix("V", V, (p, p)), "given"
        asym = float(np.max(np.abs(V - V.T)))
        Vs = 0.5 * (V + V.T)
        v_ok = asym <= 1e-6 * max(np.linalg.norm(V, 2), _EPS) and np.linalg.eigvalsh(Vs)[0] > 0
        if not v_ok:
            message = (
                f"V ({V_source}) is not symmetric positive definite (asymmetry {asym:.3g}, smallest "
                f"eigenvalue of its symmetric part {np.linalg.eigvalsh(Vs)[0]:.3g}): L is not a Kalman "
                "predictor gain for this R"
            )
    else:
        if V is not None:
            raise ValidationError(
                "V is only used in discrete time; in continuous time the inequality is T R T* >= R")
        Vs, V_source, v_ok = R, "R", True
    if tol is None:
        tol = 1e-8 * float(np.linalg.norm(R, 2))
    else:
        tol = as_positive_float("tol", tol, allow_zero=True)
    grid = frequency_grid(plant, L) if omega is None else np.unique(as_frequencies("omega", omega))
    eigA = np.linalg.eigvals(plant.A)
    if plant.dt is not None:  # discrete
        boundary = eigA[np.abs(np.abs(eigA) - 1.0) < 1e-9]
        scale = 1.0 / plant.dt
    else:
        boundary = eigA[np.abs(eigA.real) < 1e-9 * max(1.0, float(np.max(np.abs(eigA))))]
        scale = max(1.0, float(np.max(np.abs(eigA))))
    pts_of = lambda w: frequency_points(plant, w)  # noqa: E731
    grid = nudge_off_poles(grid, pts_of, boundary, scale)

    def T_of(w: NDArray) -> NDArray:
        w = nudge_off_poles(np.asarray(w, dtype=float), pts_of, boundary, scale)
        return _return_difference(plant, L, w)

    w_all, vals, complete = circle_search(T_of, grid, R, Vs, log=not plant.is_discrete, refine=refine,
                                          deadline=deadline)
    i = int(np.argmin(vals))
    w_star = float(w_all[i])
    T_star = T_of(np.array([w_star]))[0]
    direction, Delta = worst_case_parts(T_star, Vs, R)
    min_eig = float(vals[i])
    floor = return_difference_floor(plant, L, Vs, R, w_star) if min_eig < -tol else 0.0
    holds = bool(min_eig >= -tol)
    passed = holds and v_ok and complete
    if not holds and not message:
        ineq = "T V T* - R" if plant.is_discrete else "T R T* - R"
        message = (f"{ineq} has eigenvalue {min_eig:.4g} < -tol at omega = {w_star:.6g} rad/s: "
                   "L is not a Kalman gain for this R" if min_eig < -floor else
                   f"{ineq} has eigenvalue {min_eig:.4g} < -tol at omega = {w_star:.6g} rad/s, inside its "
                   f"rounding floor {floor:.2g}: no evidence either way")
    if not complete:
        message = "; ".join(filter(None, [message, search_stopped(deadline, w_all.size, holds)]))
    for a in (w_all, vals):
        a.setflags(write=False)
    return CircleConditionResult(
        min_eigenvalue=min_eig, omega_worst=w_star, passed=passed, omega=w_all, values=vals, tol=tol,
        R=R, V=np.asarray(V, dtype=float), discrete=plant.is_discrete, dt=plant.dt, V_source=V_source,
        T_worst=T_star, direction=direction, perturbation=Delta, message=message, complete=complete,
        rounding_floor=floor,
    )


def search_stopped(deadline: Deadline, evaluated: int, holds: bool) -> str:
    """The message of a frequency search stopped by its time limit (shared with the output-delay filter)."""
    verdict = ("no violation among them, but the condition is not proven" if holds
               else "the violation found is certain")
    return (f"time_limit {deadline.limit:g} s reached after {evaluated} frequencies (search incomplete): "
            f"{verdict}")
