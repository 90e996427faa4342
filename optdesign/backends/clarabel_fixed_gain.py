r"""The fixed-gain SDP of the inverse Kalman problem in its smallest conic form, on Clarabel directly.

For a fixed gain L the admissible ``(P, Q)`` form an affine family (the relations (C) / (D) of
:mod:`optdesign.formulate.inverse_kalman`).  ``P C' = K`` -- ``K = L R`` in continuous time,
``K = F^-1 L R`` with ``F = A - L C`` in discrete time (from ``F P C' = L R``) -- has a symmetric
solution iff ``C K`` is symmetric, and then every solution is

.. math::  P = P_0 + N X N', \qquad P_0 = K C^{+\prime} + C^+ K' - C^+ (C K) C^{+\prime},

with ``N`` an orthonormal basis of ``null(C)``, ``C^+`` the pseudo-inverse and ``X`` any symmetric
``(n - p) x (n - p)`` matrix.  So ``Q(X) = Q_0 + \mathcal{T}(X)`` with
``\mathcal{T}(X) = -(A N X N' + N X N' A')`` (continuous) or ``N X N' - F N X N' F'`` (discrete),
and the SDP is, for the structure ``"full"``,

.. math::  \min\ c(Q(X)) \quad \text{s.t.}\quad Q(X) \succeq 0

-- one PSD cone and no equality constraint at all ((n - p)(n - p + 1)/2 variables; the cvxpy form
has n(n + 1) variables and n p + n(n + 1)/2 equalities).  ``"input"`` adds ``Q(X) = G Qw G'``
(equalities) and ``Qw >= 0``; ``"diagonal"`` ``Q(X) = G diag(q) G'`` and ``q >= 0``.  In continuous
time the map :math:`\mathcal{T}` depends on the plant only (:func:`family_map`, built once per
plant); only ``Q_0`` changes with the gain.

Data are scaled by ``s = max(||L R L'||, ||L R||, ||Q_nominal||)``; Clarabel's PSD cone takes
the upper triangle column by column with the off-diagonal entries multiplied by sqrt(2) (so
that the Euclidean norm of that vector is the Frobenius norm).

References
----------
Goulart, P. J. & Chen, Y., "Clarabel: an interior-point solver for conic programs with quadratic
objectives", arXiv:2405.12762 (2024).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.linalg as sl
from numpy.typing import NDArray

from .._backends import import_clarabel
from .._deadline import Deadline
from ..errors import ValidationError
from ..results import Status
from .status import CLARABEL_STATUS

__all__ = [
    "CLARABEL_STATUS",
    "CLARABEL_OPTIONS",
    "CLARABEL_RETRIES",
    "GAIN_RELATION_RTOL",
    "FamilyMap",
    "family_map",
    "FixedGainFamily",
    "fixed_gain_family",
    "FixedGainSolution",
    "solve_fixed_gain",
    "svec",
    "smat",
    "svec_index",
    "clarabel_settings",
    "riccati_of_gain",
]

#: Clarabel's native statuses (``str(solution.status)``) in the one status set

#: tight defaults (as :data:`optdesign.backends.cvxpy_backend.DEFAULT_OPTIONS` for Clarabel), and the
#: QDLDL KKT solver: the constraint matrix of this form is dense (every X direction moves all of Q);
#: QDLDL -- single-threaded, the same rounding on every run -- factors its KKT matrix in about half
#: the CPU time of Clarabel's default choice at n = 15-25 and as fast below, with the same statuses
#: and optima on every target measured, one output and several
#: (``benchmarks/results/inverse_kalman_sdp_forms.md``)
CLARABEL_OPTIONS: dict[str, Any] = {"tol_gap_abs": 1e-10, "tol_gap_rel": 1e-10, "tol_feas": 1e-10,
                                    "max_iter": 400, "direct_solve_method": "qdldl"}

#: settings tried in turn after a numerical failure (InsufficientProgress, NumericalError): stronger
#: static regularization, then no equilibration (measured: each rescues single-output cases)
CLARABEL_RETRIES: tuple[dict[str, Any], ...] = ({}, {"static_regularization_constant": 1e-7},
                                                 {"equilibrate_enable": False})

#: ``C K`` must be symmetric for a symmetric P with ``P C' = K`` to exist; beyond this relative
#: asymmetry (half the digits) the gain is not a Kalman gain and the family is empty
GAIN_RELATION_RTOL = float(np.sqrt(np.finfo(float).eps))

_SQRT2 = float(np.sqrt(2.0))


@functools.lru_cache(maxsize=64)
def svec_index(n: int) -> tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.float64]]:
    """Rows, columns and weights of Clarabel's triangle: (i, j) with i <= j, column by column
    (built once per n; read-only)."""
    I, J = np.triu_indices(n)  # i <= j
    order = np.lexsort((I, J))  # by column j, then row i
    I, J = I[order].astype(np.intp), J[order].astype(np.intp)
    out = (I, J, np.where(I == J, 1.0, _SQRT2))
    for a in out:
        a.flags.writeable = False
    return out


def svec(X: NDArray) -> NDArray[np.float64]:
    """Clarabel's scaled upper-triangle vector of a symmetric matrix."""
    I, J, w = svec_index(X.shape[0])
    return np.asarray(X, dtype=float)[I, J] * w


def smat(x: NDArray, n: int) -> NDArray[np.float64]:
    """Inverse of :func:`svec`; a stack ``x`` of shape (..., n(n+1)/2) gives (..., n, n)."""
    I, J, w = svec_index(n)
    x = np.asarray(x, dtype=float)
    X = np.zeros(x.shape[:-1] + (n, n))
    X[..., I, J] = x / w
    X[..., J, I] = X[..., I, J]
    return X


def _triangle_map(Kmat: NDArray, n_out: int, n_in: int) -> NDArray[np.float64]:
    """The matrix of ``svec(Y)`` as a function of ``svec(X)`` for ``vec(Y) = Kmat vec(X)``
    (column-major vec, Y (n_out, n_out) and X (n_in, n_in) symmetric)."""
    Io, Jo, wo = svec_index(n_out)
    Ii, Ji, wi = svec_index(n_in)
    rows = Kmat[Jo * n_out + Io] * wo[:, None]
    # vec(X) = sum_c x_c / w_c (e_{i j} + e_{j i}) (once on the diagonal)
    T = rows[:, Ji * n_in + Ii] / wi
    off = Ii != Ji
    T[:, off] += rows[:, (Ii * n_in + Ji)[off]] / wi[off]
    return T


@dataclass(frozen=True, eq=False)
class FamilyMap:
    """The gain-independent part of the family: ``N`` (n, n - p) an orthonormal basis of
    null(C), ``Cp`` (n, p) the pseudo-inverse of C, and (continuous time) the triangle matrix
    ``T`` of :math:`\\mathcal{T}` (None in discrete time, where it depends on the gain).

    ``T`` has ``n(n+1)/2 x (n-p)(n-p+1)/2`` entries (3.2 GB at n = 200): it is built on first
    use (:attr:`T`, by ``continuous_triangle_map``, with no larger intermediate), and only
    the routes that need it (the direct form of the fixed-gain SDP, the dense IPM) use it; the
    one-output complement form is built without it (``complement_basis_one_output``).
    """

    A: NDArray[np.float64]
    C: NDArray[np.float64]
    dt: float | None
    N: NDArray[np.float64]
    Cp: NDArray[np.float64]

    @functools.cached_property
    def T(self) -> NDArray[np.float64] | None:  # noqa: N802 - the map's name in the references
        return None if self.dt is not None else continuous_triangle_map(self.A, self.N)

    @property
    def triangle_bytes(self) -> int:
        """Bytes of :attr:`T` (built or not)."""
        n, d = self.N.shape
        return 8 * (n * (n + 1) // 2) * (d * (d + 1) // 2)


def continuous_triangle_map(A: NDArray, N: NDArray) -> NDArray[np.float64]:
    """The triangle matrix of ``X -> -(A N X N' + N X N' A')`` (``svec`` in, ``svec`` out), one
    column per basis matrix of X -- no ``n^2 x d^2`` Kronecker intermediate (issue 26: it was
    ``n^2 (n-1)^2`` doubles, a MemoryError at n = 150)."""
    n, d = N.shape
    AN = A @ N
    Io, Jo, wo = svec_index(n)
    Ii, Ji, wi = svec_index(d)
    T = np.empty((Io.size, Ii.size))
    for c in range(Ii.size):
        i, j = Ii[c], Ji[c]
        # X = (e_i e_j' + e_j e_i') / w (once on the diagonal); N X N' = (N_i N_j' + N_j N_i') / w
        M = np.outer(AN[:, i], N[:, j])
        if i != j:
            M = M + np.outer(AN[:, j], N[:, i])
        Y = -(M + M.T) / wi[c]
        T[:, c] = Y[Io, Jo] * wo
    return T


def family_map(A: NDArray, C: NDArray, dt: float | None) -> FamilyMap:
    """Build the plant-only data of :func:`fixed_gain_family` (once per plant).

    Raises
    ------
    ValidationError
        C has dependent rows (its pseudo-inverse is not a right inverse).
    """
    A = np.asarray(A, dtype=float)
    C = np.asarray(C, dtype=float)
    n, p = A.shape[0], C.shape[0]
    _, sv, Vt = np.linalg.svd(C)
    if sv.size < p or sv[-1] <= n * np.finfo(float).eps * sv[0]:
        raise ValidationError(f"C must have independent rows (rank {p}); its smallest singular value is "
                              f"{sv[-1]:.3g}")
    N = Vt[p:].T
    Cp = np.linalg.pinv(C)
    return FamilyMap(A=A, C=C, dt=dt, N=N, Cp=Cp)


def riccati_of_gain(A: NDArray, C: NDArray, L: NDArray, R: NDArray, Q: NDArray,
                    dt: float | None) -> NDArray[np.float64]:
    """The Riccati solution of Q for the gain L: the Lyapunov solution of ``F = A - L C`` with
    ``L R L' + Q`` (continuous ``F P + P F' = -(L R L' + Q)``, discrete ``P = F P F' + L R L' + Q``);
    symmetric."""
    F = A - L @ C
    rhs = L @ R @ L.T + Q
    P = sl.solve_discrete_lyapunov(F, rhs) if dt is not None else sl.solve_continuous_lyapunov(F, -rhs)
    return 0.5 * (P + P.T)


@dataclass(frozen=True, eq=False)
class FixedGainFamily:
    """The affine family of one gain, scaled by ``scale``: ``P = scale (P0 + N smat(x) N')``,
    ``svec(Q / scale) = svec(Q0) + T x``.

    Attributes
    ----------
    L : (n, p) ndarray
    P0, Q0 : (n, n) ndarray
    T : (n(n+1)/2, d(d+1)/2) ndarray
    scale : float
    gain_residual : float
        ``||C K - (C K)'|| / max(1, ||C K||)``: how far the gain is from admitting a symmetric P at
        all (rounding level for a Kalman gain; the family is empty beyond).
    """

    map: FamilyMap
    L: NDArray[np.float64]
    R: NDArray[np.float64]
    P0: NDArray[np.float64]
    Q0: NDArray[np.float64]
    T_gain: NDArray[np.float64] | None
    scale: float
    gain_residual: float
    LRL: NDArray[np.float64] = field(repr=False, default_factory=lambda: np.zeros((0, 0)))

    @property
    def T(self) -> NDArray[np.float64]:  # noqa: N802
        """The family's directions: the plant's map in continuous time (built on first use),
        the gain's own in discrete time."""
        T = self.map.T if self.T_gain is None else self.T_gain
        if T is None:  # discrete time has no plant map; its gains always carry their own directions
            raise ValueError("the family's directions are undefined: discrete time without the gain's T")
        return T

    def P_of(self, x: NDArray) -> NDArray[np.float64]:
        N = self.map.N
        P = self.P0 + N @ smat(x, N.shape[1]) @ N.T
        return self.scale * 0.5 * (P + P.T)

    def Q_of_P(self, P: NDArray) -> NDArray[np.float64]:
        """The Q that makes P the Riccati solution of this gain (physical units)."""
        A = self.map.A
        if self.map.dt is None:
            Q = self.scale * self.LRL - A @ P - P @ A.T
        else:
            F = A - self.L @ self.map.C
            Q = P - F @ P @ F.T - self.scale * self.LRL
        return 0.5 * (Q + Q.T)


def fixed_gain_family(fmap: FamilyMap, L: NDArray, R: NDArray,
                      Q_nominal: NDArray | None = None) -> FixedGainFamily:
    """The family of ``(P, Q)`` for the gain ``L`` ((n, p)) and measurement noise ``R``."""
    A, C = fmap.A, fmap.C
    L = np.asarray(L, dtype=float)
    R = np.asarray(R, dtype=float)
    LR = L @ R
    LRL = LR @ L.T
    s = max(float(np.linalg.norm(LRL)), float(np.linalg.norm(LR)))
    if Q_nominal is not None:
        s = max(s, float(np.linalg.norm(Q_nominal)))
    s = s if (np.isfinite(s) and s > 0) else 1.0
    F = A - L @ C
    K = LR / s if fmap.dt is None else np.linalg.solve(F, LR) / s
    CK = C @ K
    asym = float(np.linalg.norm(CK - CK.T)) / max(1.0, float(np.linalg.norm(CK)))
    S = 0.5 * (CK + CK.T)
    Cp = fmap.Cp
    P0 = K @ Cp.T + Cp @ K.T - Cp @ S @ Cp.T
    P0 = 0.5 * (P0 + P0.T)
    LRLs = 0.5 * (LRL + LRL.T) / s
    if fmap.dt is None:   # continuous time: the plant's own map (fmap.T, built when used)
        Q0 = LRLs - A @ P0 - P0 @ A.T
        T = None
    else:
        Q0 = P0 - F @ P0 @ F.T - LRLs
        N = fmap.N
        FN = F @ N
        T = _triangle_map(np.kron(N, N) - np.kron(FN, FN), A.shape[0], N.shape[1])
    return FixedGainFamily(map=fmap, L=L, R=R, P0=P0, Q0=0.5 * (Q0 + Q0.T), T_gain=T, scale=s,
                           gain_residual=asym, LRL=LRLs)


@dataclass(frozen=True, eq=False)
class FixedGainSolution:
    """Outcome of :func:`solve_fixed_gain` (physical units).

    Attributes
    ----------
    status : Status
    native_status : str
    P, Q : (n, n) ndarray or None
    Wdec : ndarray or None
        The decision covariance: Q (full), Qw (input, (m, m)) or the vector qw (diagonal).
    t : float or None
        The margin (objective ``"feasibility"``).
    iterations : int
        Over all attempts (:data:`CLARABEL_RETRIES`).
    solve_time : float
        Clarabel's own time (seconds), over all attempts.
    """

    status: Status
    native_status: str
    P: NDArray[np.float64] | None
    Q: NDArray[np.float64] | None
    Wdec: NDArray[np.float64] | None
    t: float | None
    iterations: int
    solve_time: float


def clarabel_settings(clarabel, options: dict[str, Any] | None, deadline: Deadline | None):
    """Clarabel's settings: :data:`CLARABEL_OPTIONS` with ``options`` over them (an unknown key is a
    ValidationError) and the deadline's remaining time as ``time_limit``."""
    st = clarabel.DefaultSettings()
    st.verbose = False
    for key, val in {**CLARABEL_OPTIONS, **(options or {})}.items():
        if not hasattr(st, key):
            raise ValidationError(f"unknown Clarabel option {key!r}")
        setattr(st, key, val)
    if deadline is not None:
        for key, val in deadline.sdp_options("CLARABEL").items():
            setattr(st, key, val)
    return st


def _structure_rows(G: NDArray, structure: str, n: int):
    """For a G of full column rank: the equalities ``E svec(Q) = 0`` that say ``Q = G Qw G'`` (and
    Qw diagonal for ``"diagonal"``), and the map ``Mw svec(Q)`` to ``svec(Qw)`` (input) or to
    ``diag(Qw)`` (diagonal), ``Qw = G^+ Q G^+'``.  None when G has dependent columns."""
    m = G.shape[1]
    U, sv, Vt = np.linalg.svd(G)
    if sv.size < m or sv[-1] <= n * np.finfo(float).eps * sv[0]:
        return None
    Ug, Ng = U[:, :m], U[:, m:]
    Gp = Vt.T @ np.diag(1.0 / sv) @ Ug.T                   # (m, n)
    D = _vec_of_svec(n)
    rows = []
    if Ng.shape[1]:
        rows.append(_svec_rows(Ng.shape[1]) @ np.kron(Ng.T, Ng.T) @ D)   # Ng' Q Ng = 0
        rows.append(np.kron(Ug.T, Ng.T) @ D)                              # Ng' Q Ug = 0
    KW = np.kron(Gp, Gp) @ D                                              # vec(Qw) from svec(Q)
    if structure == "input":
        Mw = _svec_rows(m) @ KW
    else:
        I, J = np.triu_indices(m, 1)
        rows.append(KW[J * m + I])                                        # off-diagonal of Qw = 0
        Mw = KW[np.arange(m) * (m + 1)]
    E = np.vstack(rows) if rows else np.zeros((0, D.shape[1]))
    return E, Mw


def _vec_of_svec(n: int) -> NDArray[np.float64]:
    """D with ``vec(X) = D svec(X)`` (symmetric X, column-major vec)."""
    I, J, w = svec_index(n)
    D = np.zeros((n * n, I.size))
    c = np.arange(I.size)
    D[J * n + I, c] = 1.0 / w
    D[I * n + J, c] = 1.0 / w
    return D


def _svec_rows(n: int) -> NDArray[np.float64]:
    """S with ``svec(X) = S vec(X)``."""
    I, J, w = svec_index(n)
    S = np.zeros((I.size, n * n))
    S[np.arange(I.size), J * n + I] = w
    return S


def _cone_data(clarabel, family: FixedGainFamily, structure: str, G: NDArray, feas: bool, b0: NDArray):
    """``(A blocks, b blocks, cones, Mw, nw)`` of the constraints (``b0 = svec(family.Q0)``);
    ``Mw`` maps ``svec(Q)`` to the decision (None for "full"), ``nw`` counts extra variables (w-form
    for a G of dependent columns)."""
    n = family.Q0.shape[0]
    T = family.T
    nx = T.shape[1]
    tcol = lambda v: [v[:, None]] if feas else []  # noqa: E731 - the margin's column
    if structure == "full":
        return [np.hstack([-T] + tcol(svec(np.eye(n))))], [b0], [clarabel.PSDTriangleConeT(n)], None, 0
    m = G.shape[1]
    rows = _structure_rows(G, structure, n)
    if rows is not None:   # no extra variables: Qw = G^+ Q(x) G^+'
        E, Mw = rows
        eye_w = svec(np.eye(m)) if structure == "input" else np.ones(m)
        z = np.zeros((E.shape[0], 1 if feas else 0))
        cone = clarabel.PSDTriangleConeT(m) if structure == "input" else clarabel.NonnegativeConeT(m)
        return ([np.hstack([E @ T, z]), np.hstack([-Mw @ T] + tcol(eye_w))], [-E @ b0, Mw @ b0],
                [clarabel.ZeroConeT(E.shape[0]), cone], Mw, 0)
    # G with dependent columns: Qw (or q) as variables, Q(x) = G Qw G' as equalities
    if structure == "input":
        nw = m * (m + 1) // 2
        Gs = _triangle_map(np.kron(G, G), n, m)
        eye_w = svec(np.eye(m))
    else:
        nw = m
        Gs = np.column_stack([svec(np.outer(G[:, j], G[:, j])) for j in range(m)])
        eye_w = np.ones(m)
    z = np.zeros((Gs.shape[0], 1 if feas else 0))
    cone = clarabel.PSDTriangleConeT(m) if structure == "input" else clarabel.NonnegativeConeT(m)
    return ([np.hstack([T, -Gs, z]), np.hstack([np.zeros((nw, nx)), -np.eye(nw)] + tcol(eye_w))],
            [-b0, np.zeros(nw)], [clarabel.ZeroConeT(Gs.shape[0]), cone], None, nw)


def solve_fixed_gain(family: FixedGainFamily, structure: str = "full", G: NDArray | None = None,
                     objective: str = "min_trace", Q_nominal: NDArray | None = None, *,
                     options: dict[str, Any] | None = None,
                     deadline: Deadline | None = None) -> FixedGainSolution:
    """Solve the fixed-gain SDP of ``family`` on Clarabel.

    For ``"input"`` / ``"diagonal"`` with a G of independent columns, ``Q = G Qw G'`` is imposed
    as the independent equalities ``Ng' Q Ng = 0``, ``Ng' Q Ug = 0`` (``[Ug, Ng]`` orthonormal,
    ``Ug`` spanning range(G); for ``"diagonal"`` also the off-diagonal of Qw) with
    ``Qw = G^+ Q G^+'`` -- no extra variables and no redundant rows; otherwise Qw is a variable.

    Parameters
    ----------
    family : FixedGainFamily
    structure : {"full", "input", "diagonal"}
    G : (n, m) ndarray, optional
        For ``"input"`` / ``"diagonal"``.
    objective : {"min_trace", "nearest", "feasibility"}
    Q_nominal : ndarray, optional
        ``"nearest"``: (n, n) for ``"full"``, (m, m) otherwise.
    options : dict, optional
        Clarabel settings over :data:`CLARABEL_OPTIONS`.
    deadline : Deadline, optional
        Its remaining time becomes Clarabel's ``time_limit``.

    Returns
    -------
    FixedGainSolution
        Status ``infeasible`` without calling Clarabel when ``C K`` is not symmetric (beyond
        :data:`GAIN_RELATION_RTOL`): no symmetric P satisfies ``P C' = K`` -- a proof.

    Raises
    ------
    ValidationError
        Unknown structure / objective / option, or a missing G / Q_nominal.
    """
    import scipy.sparse as sp

    clarabel = import_clarabel()
    if structure not in ("full", "input", "diagonal"):
        raise ValidationError(f"structure must be 'full', 'input' or 'diagonal'; found {structure!r}")
    if objective not in ("min_trace", "nearest", "feasibility"):
        raise ValidationError(f"objective must be 'min_trace', 'nearest' or 'feasibility'; "
                              f"found {objective!r}")
    if structure != "full" and G is None:
        raise ValidationError(f"structure={structure!r} needs the noise input matrix G")
    if objective == "nearest" and Q_nominal is None:
        raise ValidationError("objective='nearest' needs Q_nominal")
    G = None if G is None else np.asarray(G, dtype=float)
    if family.gain_residual > GAIN_RELATION_RTOL:   # no symmetric P has P C' = K: a proof
        return FixedGainSolution(Status.INFEASIBLE, f"gain relation: ||C K - (C K)'|| / max(1, ||C K||) = "
                                 f"{family.gain_residual:.3g}", None, None, None, None, 0, 0.0)
    s = family.scale
    n = family.Q0.shape[0]
    T = family.T
    nx = T.shape[1]
    b0 = svec(family.Q0)
    feas = objective == "feasibility"
    Gm = np.eye(n) if G is None else G
    A_rows, b, cones, Mw, nw = _cone_data(clarabel, family, structure, Gm, feas, b0)
    nz = nx + nw + (1 if feas else 0)
    q = np.zeros(nz)
    Pm = sp.csc_matrix((nz, nz))
    if objective == "min_trace":
        Id, Jd, _ = svec_index(n)
        diag_w = (Id == Jd).astype(float)
        q[:nx] = diag_w @ T
    elif objective == "feasibility":
        q[-1] = -1.0
    else:
        Qn = np.asarray(Q_nominal, dtype=float) / s
        Qn = 0.5 * (Qn + Qn.T)
        if structure == "full" or Mw is not None:
            Mq = T if structure == "full" else Mw @ T
            off = b0 if structure == "full" else Mw @ b0
            tgt = svec(Qn) if structure != "diagonal" else np.diag(Qn).copy()
            Pm = sp.triu(sp.csc_matrix(Mq.T @ Mq), format="csc")
            q[:nx] = Mq.T @ (off - tgt)
        else:
            tgt = svec(Qn) if structure == "input" else np.diag(Qn).copy()
            iw = np.arange(nx, nx + nw)
            Pm = sp.csc_matrix((np.ones(nw), (iw, iw)), shape=(nz, nz))
            q[nx:nx + nw] = -tgt
    Am = sp.csc_matrix(np.vstack(A_rows))
    bv = np.concatenate(b)
    it, stime = 0, 0.0
    for retry in CLARABEL_RETRIES:   # a numerical failure (not a verdict) is retried
        settings = clarabel_settings(clarabel, {**(options or {}), **retry}, deadline)
        sol = clarabel.DefaultSolver(Pm, q, Am, bv, cones, settings).solve()
        native = str(sol.status)
        status = CLARABEL_STATUS.get(native, Status.SOLVER_ERROR)
        it += int(getattr(sol, "iterations", 0) or 0)
        stime += float(getattr(sol, "solve_time", 0.0) or 0.0)
        if status not in (Status.NUMERICAL_ERROR, Status.SOLVER_ERROR) or (
                deadline is not None and deadline.expired):
            break
    if not status.is_solved:
        return FixedGainSolution(status, native, None, None, None, None, it, stime)
    zv = np.asarray(sol.x, dtype=float)
    P = family.P_of(zv[:nx])
    Q = family.Q_of_P(P)
    if structure == "full":
        Wdec = Q
    elif Mw is not None:
        wv = Mw @ (b0 + T @ zv[:nx])
        Wdec = s * (smat(wv, Gm.shape[1]) if structure == "input" else wv)
    elif structure == "input":
        Wdec = s * smat(zv[nx:nx + nw], Gm.shape[1])
    else:
        Wdec = s * zv[nx:nx + nw]
    t = s * float(zv[-1]) if feas else None
    return FixedGainSolution(status, native, P, Q, Wdec, t, it, stime)
