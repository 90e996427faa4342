r"""Riccati differential equation through the Hamiltonian transition matrix: the block-pulse
recursion of seed 004 (Ahn et al.), what it is numerically, and an exact, stable propagator.

The filter Riccati differential equation (seed 004 eq (3.11), project symbols A, C, W = G Q G')

.. math::

    \dot P = A P + P A' + W - P S P, \qquad S = C' R^{-1} C, \qquad P(0) = P_0

is the image of the linear Hamiltonian system (4.4)

.. math::

    \begin{bmatrix} \dot U \\ \dot V \end{bmatrix} = M \begin{bmatrix} U \\ V \end{bmatrix},
    \qquad M = \begin{bmatrix} -A' & S \\ W & A \end{bmatrix}, \qquad
    \begin{bmatrix} U(0) \\ V(0) \end{bmatrix} = \begin{bmatrix} I \\ P_0 \end{bmatrix},
    \qquad P = V U^{-1}

(``J M`` is symmetric for ``J = [[0, I], [-I, 0]]``: M is Hamiltonian and its transition matrix
is symplectic).  Everything here takes that ``2n x 2n`` matrix ``M``
(:func:`filter_hamiltonian`) and an ``(n, n)`` initial covariance.

The block-pulse recursion (seed 004, section 4), with the typos fixed
---------------------------------------------------------------------
The paper differentiates ``Phi(t0, t) xi(t) = xi(t0)`` to get ``d/dt Phi(t0, t) = -Phi(t0, t) M``,
integrates, expands ``Phi(t0, t) = sum_k phi_k H_k(t)`` in block pulses (width ``h = t_f/m``) and
uses the operational matrix of integration (2.6).  Correct forms of the misprinted equations:

* (4.20): ``Phi(t0, t) - I = -int_{t0}^t Phi(t0, tau) M dtau`` (the paper prints
  ``I - Phi(t0, t)`` on the left: a sign error);
* (4.23): ``sum_k (phi_k - I) H_k(t) = -h sum_k phi_k M [H_k(t)/2 + sum_{l>k} H_l(t)]``
  (the paper has ``I - phi_k`` on both sides);
* (4.24)-(4.25), printed correctly: ``phi_1 = (I + h M/2)^-1``,
  ``phi_{k+1} = phi_k (I - h M/2)(I + h M/2)^-1``;
* (4.26): ``Phi(t, t0) ~ phi_k^-1`` on block k, and ``P_k = (phi^-1_{21,k} + phi^-1_{22,k} P0)
  (phi^-1_{11,k} + phi^-1_{12,k} P0)^-1`` -- the paper's gain formula has a spurious first
  inverse in (4.12) and ``phi_{2ik}`` for ``phi_{21k}``.

What the recursion is numerically (proved in ``tests/test_bpf.py`` to rounding error)
-------------------------------------------------------------------------------------
Let ``C = (I - h M/2)(I + h M/2)^-1`` -- the Cayley transform, i.e. the Pade(1,1) /
trapezoidal / **Crank-Nicolson** propagator of ``d/dt Phi = -Phi M`` over one block.  Since
``(I + h M/2)^-1 = (I + C)/2``,

.. math::

    \phi_k = \tfrac12 \left(C^{k-1} + C^{k}\right),

the **trapezoidal-rule average over block k of the Crank-Nicolson nodal values** of
``Phi(t0, t) = e^{-M t}`` -- the block-pulse coefficient (2.5) of the Crank-Nicolson solution.
The same ``phi_k`` solve the full operational-matrix system (4.23) (:func:`bpf_transition_direct`).
Inverted as in (4.26),

.. math::

    \phi_k^{-1} = \left(I + \tfrac h2 M\right) T^{k-1}, \qquad
    T = \left(I - \tfrac h2 M\right)^{-1}\left(I + \tfrac h2 M\right) \approx e^{hM},

i.e. the Crank-Nicolson value of ``e^{M t}`` at the block's left node followed by half an
explicit-Euler step: an approximation of ``Phi(t, t0)`` at the **block midpoint**
``t_{k-1/2} = (k - 1/2) h``.  Consequences:

* the block coefficient ``P_k`` is a **second-order** approximation of ``P(t_{k-1/2})``
  (error ``O(h^2)``, measured order 2.00 over m = 25..400 on the paper's example) and of the
  block average of ``P``; as the piecewise-constant function ``sum_k P_k H_k(t)`` it is only
  **first order** away from the midpoints;
* the Crank-Nicolson nodal values ``T^k [I; P0]`` are symplectic, so their ``V U^-1`` is exactly
  symmetric; the half Euler step is not symplectic, so the paper's ``P_k`` is **not symmetric**:
  its asymmetry is ``O(h^2)``, of the same size as its error (2x on the paper's example).
  :func:`bpf_riccati` returns the symmetric part (whose error is about half) and the asymmetry
  it removed;
* like ``V U^-1`` from one matrix exponential, the recursion propagates ``Phi(t0, t)`` from
  ``t0`` without restarts and then inverts it: ``cond(phi_k) ~ e^{2 Re(lambda) t}`` (lambda the
  eigenvalue of M of largest real part), so rounding error grows with the horizon whatever m is,
  and ``phi_k`` becomes singular to working precision near ``Re(lambda) t ~ 16`` (CAREX 1.2 in
  filter form, ``lambda = sqrt 2``: t ~ 11.5).  The paper's example (``Re(lambda) = 0.525``,
  t_f = 10) is far from that; :func:`bpf_riccati` raises :class:`RiccatiError` when it happens,
  unless the recursion is restarted (below).

Restarts, and the exact propagator
----------------------------------
:func:`bpf_riccati` restarts the recursion on request (``restart_every``; ``riccati_de`` always
does, every :func:`bpf_restart_blocks` blocks): each segment starts from the recursion's own
Crank-Nicolson nodal value, so ``P_k`` is unchanged in exact arithmetic while ``cond(phi_k)``
stays bounded -- the block-pulse method then reaches any horizon.  The exact propagator (the
``"transition"`` method) is in :mod:`optdesign.classical.transition`; its names are re-exported
here.

References
----------
Ahn, D. S., Lim, Y. S., Lee, S. H. & Lee, M. K., "Design of Kalman filter via BPF", seed 004,
sections 2 and 4, eqs (2.5)-(2.7), (4.4), (4.11), (4.20)-(4.26).
Kenney, C. S. & Leipnik, R. B., "Numerical integration of the differential matrix Riccati
equation", IEEE TAC 30 (1985) 962-970 (seed 004 ref [3]; Davison-Maki with restarts).
Lainiotis, D. G., "Partitioned Riccati solutions and integration-free doubling algorithms",
IEEE TAC 21 (1976) 677-689.
Anderson, B. D. O. & Moore, J. B., *Optimal Filtering*, Prentice-Hall 1979 (doubling algorithm).
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.linalg
from numpy.typing import ArrayLike, NDArray

from .._deadline import Deadline
from .._validate import as_matrix, as_positive_float, as_square, check_symmetric
from ..analysis.linalg import sym
from ..errors import RiccatiError, ValidationError
from .transition import (
    RiccatiMap,
    apply_map,
    as_hamiltonian,
    compose_maps,
    davison_maki,
    hamiltonian_scaling,
    riccati_flow,
    riccati_map,
)

__all__ = [
    "integration_matrix",
    "backward_integration_matrix",
    "bpf_coefficients",
    "bpf_evaluate",
    "filter_hamiltonian",
    "filter_hamiltonian_trusted",
    "cayley",
    "bpf_transition",
    "bpf_transition_direct",
    "crank_nicolson_transition",
    "bpf_riccati",
    "bpf_restart_blocks",
    "BPF_RESTART_NORM",
    "BPFRiccati",
    # re-exported from optdesign.classical.transition
    "RiccatiMap",
    "hamiltonian_scaling",
    "riccati_map",
    "compose_maps",
    "apply_map",
    "riccati_flow",
    "davison_maki",
]


# ------------------------------------------------------------------ validation
def _as_count(name: str, value) -> int:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise ValidationError(f"{name} must be a positive integer; found {value!r}")
    if value < 1:
        raise ValidationError(f"{name} must be a positive integer; found {value}")
    return int(value)


# ------------------------------------------------------------ block-pulse basics
def integration_matrix(m: int, t_final: float) -> NDArray[np.float64]:
    r"""Operational matrix of forward integration of the block-pulse basis (seed 004 eq (2.6)).

    ``int_0^t H(tau) dtau ~ P H(t)`` for the column ``H = [H_1, ..., H_m]'`` of block pulses of
    width ``h = t_final/m``: ``P = h (I/2 + strictly upper triangular ones)``.  A function with
    block-pulse coefficients ``c`` (a row) has an integral with coefficients ``c P``; exact for
    the block averages of ``int_0^t c(tau) dtau`` when c is piecewise constant.

    Parameters
    ----------
    m : int
        Number of blocks.
    t_final : float
        Length of the interval ``[0, t_final)``.

    Returns
    -------
    (m, m) ndarray

    Raises
    ------
    ValidationError
        m not a positive integer, t_final not positive.
    """
    m = _as_count("m", m)
    h = as_positive_float("t_final", t_final) / m
    return h * (0.5 * np.eye(m) + np.triu(np.ones((m, m)), 1))


def backward_integration_matrix(m: int, t_final: float) -> NDArray[np.float64]:
    r"""Operational matrix of backward integration ``int_{t_f}^t H ~ P_hat H`` (eq (2.7)):
    ``P_hat = -P'`` with P from :func:`integration_matrix`.

    Raises
    ------
    ValidationError
        m not a positive integer, t_final not positive.
    """
    return -integration_matrix(m, t_final).T


def bpf_coefficients(f: Callable[[float], ArrayLike], t_final: float, m: int,
                     *, nodes: int = 8) -> NDArray[np.float64]:
    r"""Block-pulse coefficients ``X_k = (m/t_f) int_{block k} f(t) dt`` (seed 004 eq (2.5)).

    Computed by ``nodes``-point Gauss-Legendre quadrature on every block (exact for
    polynomials of degree ``2 nodes - 1``).

    Parameters
    ----------
    f : callable
        ``f(t)`` returns a scalar or an array (all of the same shape).
    t_final : float
    m : int
        Number of blocks.
    nodes : int
        Quadrature nodes per block.

    Returns
    -------
    ndarray of shape ``(m, *shape)``

    Raises
    ------
    ValidationError
        m or nodes not a positive integer, t_final not positive.
    """
    m = _as_count("m", m)
    nodes = _as_count("nodes", nodes)
    h = as_positive_float("t_final", t_final) / m
    x, w = np.polynomial.legendre.leggauss(nodes)
    out = []
    for k in range(m):
        vals = [np.asarray(f(k * h + 0.5 * h * (1.0 + xi)), dtype=float) for xi in x]
        out.append(0.5 * sum(wi * v for wi, v in zip(w, vals, strict=True)))
    return np.asarray(out)


def bpf_evaluate(coefficients: ArrayLike, t_final: float, t: ArrayLike) -> NDArray[np.float64]:
    r"""The block-pulse expansion ``sum_k X_k H_k(t)`` at times t (piecewise constant).

    Block k covers ``[(k-1) h, k h)``; ``t = t_final`` belongs to the last block.

    Parameters
    ----------
    coefficients : (m, ...) array_like
    t_final : float
    t : (q,) array_like
        Times in ``[0, t_final]``.

    Returns
    -------
    (q, ...) ndarray

    Raises
    ------
    ValidationError
        t outside ``[0, t_final]``, t_final not positive.
    """
    X = np.asarray(coefficients, dtype=float)
    tf = as_positive_float("t_final", t_final)
    t = np.atleast_1d(np.asarray(t, dtype=float))
    if t.size and (np.min(t) < 0 or np.max(t) > tf * (1 + 1e-12)):
        raise ValidationError(f"t must lie in [0, t_final] = [0, {tf:g}]; found "
                              f"[{np.min(t):g}, {np.max(t):g}]")
    m = X.shape[0]
    k = np.minimum((t / tf * m).astype(int), m - 1)
    return X[k]


def filter_hamiltonian(A: ArrayLike, C: ArrayLike, W: ArrayLike, R: ArrayLike) -> NDArray[np.float64]:
    r"""The Hamiltonian matrix (seed 004 eq (4.4), (4.14)) of the filter Riccati DE.

    ``M = [[-A', C' R^-1 C], [W, A]]`` so that ``P = V U^-1`` solves
    ``P' = A P + P A' + W - P C' R^-1 C P`` when ``[U; V]' = M [U; V]``.

    Parameters
    ----------
    A : (n, n) array_like
    C : (p, n) array_like
    W : (n, n) array_like
        State-space process-noise covariance ``G Q G'``.
    R : (p, p) array_like

    Returns
    -------
    (2n, 2n) ndarray

    Raises
    ------
    DimensionError, NotFiniteError, NotSymmetricError
        Mismatched or bad matrices.
    """
    A = as_square("A", A)
    n = A.shape[0]
    C = as_matrix("C", C, (None, n))
    W = check_symmetric("W", as_square("W", W, n))
    R = check_symmetric("R", as_square("R", R, C.shape[0]))
    return filter_hamiltonian_trusted(A, C, W, R)


def filter_hamiltonian_trusted(A: NDArray[np.float64], C: NDArray[np.float64], W: NDArray[np.float64],
                               R: NDArray[np.float64]) -> NDArray[np.float64]:
    r""":func:`filter_hamiltonian` without its input validation, for callers that have validated
    (e.g. :func:`optdesign.riccati_de`, from a :class:`~optdesign.Plant`): 14 us at n = 10
    against 69 us with the validation (and ``np.block``).

    Parameters
    ----------
    A : (n, n) ndarray
        Finite float matrices of matching shapes, W and R symmetric, R nonsingular: not checked.
    C : (p, n) ndarray
    W : (n, n) ndarray
    R : (p, p) ndarray

    Returns
    -------
    (2n, 2n) ndarray

    Raises
    ------
    numpy.linalg.LinAlgError
        R exactly singular.
    """
    n = A.shape[0]
    M = np.empty((2 * n, 2 * n))
    M[:n, :n] = -A.T
    M[:n, n:] = sym(C.T @ np.linalg.solve(R, C))
    M[n:, :n] = W
    M[n:, n:] = A
    return M


# ------------------------------------------------------- the paper's recursion
def cayley(M: ArrayLike, h: float) -> NDArray[np.float64]:
    r"""``(I - h M/2)(I + h M/2)^-1``: the Pade(1,1) (trapezoidal, Crank-Nicolson) approximation
    of ``e^{-h M}``, the one-block propagator of ``d/dt Phi = -Phi M``.

    Raises
    ------
    DimensionError, NotFiniteError
        M not a finite square matrix.
    ValidationError
        h not positive.
    """
    M = as_square("M", M)
    h = as_positive_float("h", h)
    eye = np.eye(M.shape[0])
    X = np.linalg.solve((eye + 0.5 * h * M).T, (eye - 0.5 * h * M).T).T
    return X  # type: ignore[return-value, unused-ignore]  # stubs (py >= 3.11): solve(float64) is floating


def bpf_transition(M: ArrayLike, t_final: float, m: int) -> NDArray[np.float64]:
    r"""Block-pulse coefficients ``phi_k`` of ``Phi(t0, t)`` by the recursion (4.24)-(4.25).

    ``phi_1 = (I + h M/2)^-1``, ``phi_{k+1} = phi_k (I - h M/2)(I + h M/2)^-1``, ``h = t_final/m``.
    Equal to ``(C^{k-1} + C^k)/2`` with ``C`` = :func:`cayley` (M, h) -- see the module notes.

    Parameters
    ----------
    M : (N, N) array_like
        The system matrix of ``xi' = M xi`` (the Hamiltonian, for the Riccati DE).
    t_final : float
    m : int
        Number of blocks.

    Returns
    -------
    (m, N, N) ndarray

    Raises
    ------
    ValidationError
        m not a positive integer, t_final not positive.
    DimensionError, NotFiniteError
        M not a finite square matrix.
    """
    M = as_square("M", M)
    m = _as_count("m", m)
    h = as_positive_float("t_final", t_final) / m
    eye = np.eye(M.shape[0])
    phi = np.linalg.inv(eye + 0.5 * h * M)                       # (4.24)
    step = (eye - 0.5 * h * M) @ phi                             # (I - hM/2)(I + hM/2)^-1
    out = np.empty((m,) + M.shape)
    for k in range(m):
        out[k] = phi
        phi = phi @ step                                         # (4.25)
    return out


def bpf_transition_direct(M: ArrayLike, t_final: float, m: int) -> NDArray[np.float64]:
    r"""The coefficients ``phi_k`` from the block-pulse form of (4.20) solved as ONE linear system.

    With ``Phi(t0, t) ~ sum_k phi_k H_k(t)`` and the operational matrix ``P_op``
    (:func:`integration_matrix`), the corrected (4.23) reads
    ``phi_l + sum_k (P_op)_{kl} phi_k M = I`` for l = 1..m, i.e. ``X + (P_op' kron I) X M = 1 kron I``
    for the stacked ``X = [phi_1; ...; phi_m]``, solved here by Kronecker vectorization
    (``(m N)^2`` unknowns: small m and N only).  Used to show that the recursion (4.24)-(4.25)
    solves the block-pulse equations exactly.

    Returns
    -------
    (m, N, N) ndarray

    Raises
    ------
    ValidationError
        m not a positive integer, t_final not positive, or ``m N > 400``.
    """
    M = as_square("M", M)
    m = _as_count("m", m)
    N = M.shape[0]
    if m * N > 400:
        raise ValidationError(f"bpf_transition_direct is a dense test of size (m N)^2; m N = {m * N} > 400")
    Pop = integration_matrix(m, t_final)
    # unknown X (m N x N); equation X + K X M = B with K = kron(Pop', I_N)
    K = np.kron(Pop.T, np.eye(N))
    B = np.kron(np.ones((m, 1)), np.eye(N))
    # vec (column-major): vec(K X M) = (M' kron K) vec(X)
    big = np.eye(m * N * N) + np.kron(M.T, K)
    x = np.linalg.solve(big, B.reshape(-1, order="F"))
    X = x.reshape((m * N, N), order="F")
    return X.reshape(m, N, N)


def crank_nicolson_transition(M: ArrayLike, h: float, k: int) -> NDArray[np.float64]:
    r"""Crank-Nicolson nodal values ``T^j``, j = 0..k, of ``e^{M t_j}`` (``t_j = j h``), where
    ``T = (I - h M/2)^-1 (I + h M/2)`` (Pade(1,1) of ``e^{h M}``).

    Returns
    -------
    (k + 1, N, N) ndarray

    Raises
    ------
    ValidationError
        h not positive, k not a positive integer.
    """
    M = as_square("M", M)
    h = as_positive_float("h", h)
    k = _as_count("k", k)
    eye = np.eye(M.shape[0])
    T = np.linalg.solve(eye - 0.5 * h * M, eye + 0.5 * h * M)
    out = np.empty((k + 1,) + M.shape)
    out[0] = eye
    for j in range(k):
        out[j + 1] = T @ out[j]
    return out


@dataclass(frozen=True, eq=False)
class BPFRiccati:
    """The block-pulse solution of the Riccati DE (seed 004 (4.24)-(4.26), (4.11)).

    Attributes
    ----------
    t : (k,) ndarray
        Block midpoints ``(j - 1/2) h``, where the coefficients are second-order accurate
        (``k = m`` unless a time limit stopped the recursion: then the first k blocks).
    P : (k, n, n) ndarray
        Block coefficients: the symmetric part of ``V_k U_k^-1`` (or the raw, slightly
        asymmetric matrices when ``symmetrize=False``).
    asymmetry : (k,) ndarray
        ``||V U^-1 - (V U^-1)'||_F / 2`` per block: the size of the antisymmetric part
        (``O(h^2)``; removed when symmetrized).
    h : float
        Block width ``t_final / m``.
    restart_every : int or None
        Blocks per restarted segment (None: the paper's recursion from t = 0, no restart).
    restarts : int
        Restarts made.
    complete : bool
        False when a time limit stopped the recursion before block m.
    """

    t: NDArray[np.float64]
    P: NDArray[np.float64]
    asymmetry: NDArray[np.float64]
    h: float
    restart_every: int | None = None
    restarts: int = 0
    complete: bool = True


#: a restarted segment spans at most ``BPF_RESTART_NORM / ||M||_1`` seconds, so that ``phi_k``
#: (~ ``e^{-M t}``, t within the segment) has condition number at most ``e^{2 BPF_RESTART_NORM}``
#: (~3e3): inverting it costs at most ~3.5 digits, far below the method's O(h^2) error
BPF_RESTART_NORM = 4.0


def bpf_restart_blocks(M: ArrayLike, h: float) -> int:
    r"""Blocks per restarted segment of :func:`bpf_riccati`: the largest r >= 1 with
    ``||M||_1 r h <= BPF_RESTART_NORM``.

    Within a segment the recursion's ``phi_k ~ e^{-M t}`` has ``||phi_k|| ||phi_k^-1|| <=
    e^{2 ||M||_1 r h}``, so inverting it as (4.26) does loses at most ``2 BPF_RESTART_NORM /
    ln 10 ~ 3.5`` digits, whatever the horizon.

    Parameters
    ----------
    M : (2n, 2n) array_like
        Hamiltonian (:func:`filter_hamiltonian`).
    h : float
        Block width.

    Returns
    -------
    int

    Raises
    ------
    DimensionError, NotFiniteError
        M not a finite 2n x 2n matrix.
    ValidationError
        h not positive.
    """
    M, _ = as_hamiltonian(M)
    h = as_positive_float("h", h)
    nrm = float(np.linalg.norm(M, 1)) * h
    if nrm == 0.0:
        return 2**62
    return max(1, int(np.floor(BPF_RESTART_NORM / nrm)))


def _solve_checked(A: NDArray, B: NDArray, what: str, k: int, m: int, h: float,
                   restarted: bool) -> NDArray:
    """``A^-1 B``, raising RiccatiError when A is singular to working precision (LAPACK rcond)."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", scipy.linalg.LinAlgWarning)
        try:
            X = scipy.linalg.solve(A, B, check_finite=False)
        except (np.linalg.LinAlgError, scipy.linalg.LinAlgWarning, ValueError) as exc:
            if what == "U_k":
                hint = "finite escape of the Riccati solution, or blocks far too wide"
            elif what != "phi_k" or restarted:
                hint = "blocks far too wide for the fastest mode of M (h ||M|| >> 1): use more blocks"
            else:
                hint = ("phi_k approximates e^{-M t}, whose condition number grows like e^{2 Re(lambda) t} "
                        "(lambda: eigenvalue of M): the recursion taken from t = 0 without restarts cannot "
                        "reach this horizon; restart it (restart_every=bpf_restart_blocks(M, h), as "
                        "riccati_de method='bpf' does) or use the restarted exact transition matrix "
                        "(riccati_flow / riccati_de method='transition')")
            raise RiccatiError(f"bpf_riccati: {what} is singular to working precision on block {k + 1} "
                               f"of {m} (t = {(k + 0.5) * h:.4g}): {hint}") from exc
    if not np.all(np.isfinite(X)):
        raise RiccatiError(f"bpf_riccati: non-finite values on block {k + 1} of {m}")
    return X


def bpf_riccati(M: ArrayLike, P0: ArrayLike, t_final: float, m: int,
                *, symmetrize: bool = True, restart_every: int | None = None,
                deadline: Deadline | float | None = None) -> BPFRiccati:
    r"""The paper's block-pulse Riccati solution: ``phi_k`` by (4.24)-(4.25), inverted (4.26),
    ``P_k = (phi^-1_{21,k} + phi^-1_{22,k} P0)(phi^-1_{11,k} + phi^-1_{12,k} P0)^-1`` (4.11),
    optionally restarted.

    Restarts (``restart_every = r``): the recursion is run over segments of r blocks, each from
    its own initial time ``t_j = j h`` with ``[I; P0]`` replaced by ``[I; P(t_j)]``, where
    ``P(t_j)`` is the recursion's own Crank-Nicolson nodal value at the segment's end:
    ``phi_r^-1 = (I + h M/2) T^{r-1}`` gives ``T^r Z = (I - h M/2)^-1 phi_r^-1 Z``.  As
    ``V U^-1`` does not depend on the normalisation of ``[U; V]``, the restarted recursion gives
    the same ``P_k`` as the paper's in exact arithmetic (the same method: block-averaged
    Crank-Nicolson, second order at the midpoints), but inverts ``phi_k`` over one segment only
    -- its condition number stays bounded (:func:`bpf_restart_blocks`) instead of growing like
    ``e^{2 Re(lambda) t}``, so no horizon is out of reach.

    Parameters
    ----------
    M : (2n, 2n) array_like
        Hamiltonian (:func:`filter_hamiltonian`).
    P0 : (n, n) array_like
        Symmetric initial covariance.
    t_final : float
    m : int
        Number of blocks.
    symmetrize : bool
        Return the symmetric part of each ``V U^-1`` (default) or the raw matrix.
    restart_every : int, optional
        Blocks per segment (None: no restart, the paper's recursion from t = 0).
    deadline : Deadline or float, optional
        Time budget (seconds or a shared :class:`~optdesign._deadline.Deadline`): once it has
        expired no new block is started and the blocks computed so far are returned
        (``complete=False``).

    Returns
    -------
    BPFRiccati

    Raises
    ------
    ValidationError
        m or restart_every not a positive integer, t_final not positive, bad deadline.
    DimensionError, NotFiniteError, NotSymmetricError
        Bad M or P0.
    RiccatiError
        ``phi_k`` singular to working precision (without restarts its condition number grows
        like ``e^{2 Re(lambda) t}``: long horizons / fast Hamiltonian modes), or ``U_k``
        singular (finite escape of the Riccati solution, or h far too large).

    References
    ----------
    Seed 004, eqs (4.11), (4.24)-(4.26); restarts as in Davison & Maki / Kenney & Leipnik 1985.
    """
    M, n = as_hamiltonian(M)
    P0 = check_symmetric("P0", as_square("P0", P0, n))
    m = _as_count("m", m)
    seg = m if restart_every is None else _as_count("restart_every", restart_every)
    tf = as_positive_float("t_final", t_final)
    clock = Deadline.of(deadline)
    h = tf / m
    eye = np.eye(2 * n)
    restarted = seg < m
    phi1 = _solve_checked(eye + 0.5 * h * M, eye, "phi_k", 0, m, h, restarted)   # (4.24)
    step = (eye - 0.5 * h * M) @ phi1                            # (I - hM/2)(I + hM/2)^-1
    back = eye - 0.5 * h * M                                     # restarts: T^r Z = back^-1 phi_r^-1 Z
    Z = np.vstack([np.eye(n), P0])
    P = np.empty((m, n, n))
    asym = np.empty(m)
    k = restarts = 0
    Y = Z
    while k < m and not clock.expired:
        if k:                                                    # restart at t_k = k h
            node = _solve_checked(back, Y, "I - hM/2", k - 1, m, h, restarted)   # T^r [I; P(t_j)]
            Pnode = _solve_checked(node[:n].T, node[n:].T, "U_k", k - 1, m, h, restarted).T
            Z = np.vstack([np.eye(n), sym(Pnode)])
            restarts += 1
        phi = phi1
        for _ in range(min(seg, m - k)):
            if clock.expired:
                break
            Y = _solve_checked(phi, Z, "phi_k", k, m, h, restarted)   # phi_k^-1 [I; P(t_j)]  (4.26)
            Pk = _solve_checked(Y[:n].T, Y[n:].T, "U_k", k, m, h, restarted).T   # V U^-1  (4.11)
            asym[k] = 0.5 * np.linalg.norm(Pk - Pk.T)
            P[k] = sym(Pk) if symmetrize else Pk
            phi = phi @ step                                     # (4.25)
            k += 1
    return BPFRiccati(t=(np.arange(k, dtype=np.float64) + 0.5) * h, P=P[:k], asymmetry=asym[:k], h=h,
                      restart_every=None if seg >= m else seg, restarts=restarts, complete=k == m)
