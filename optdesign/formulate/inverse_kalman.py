r"""Inverse Kalman problem: which ``Q >= 0`` gives a steady-state filter with these poles?

Builds (never solves) the formulations used by :func:`optdesign.kalman_for_poles`.

Linear-in-P relations for a fixed gain L
----------------------------------------
Continuous time, ``A P + P A' - P C' R^-1 C P + Q = 0`` and ``L = P C' R^-1``.  With L
fixed, ``P C' R^-1 C P = L R L'``, so

.. math::

    P C' = L R, \qquad Q = L R L' - A P - P A'            \tag{C}

are linear in P; equivalently ``(A - LC) P + P (A - LC)' + L R L' + Q = 0``, so
``P >= 0`` follows from ``Q >= 0`` when ``A - L C`` is stable.

Discrete time, predictor DARE ``P = A P A' - A P C' S^-1 C P A' + Q`` with the innovation
covariance ``S = C P C' + R`` and ``L = A P C' S^-1``.  From ``L S = A P C'``, i.e.
``L (C P C' + R) = A P C'``,

.. math::

    (A - L C) P C' = L R, \qquad
    Q = P - A P A' + L S L' = P - (A - L C) P (A - L C)' - L R L'   \tag{D}

(the second form uses ``A P C' = L S`` twice), again linear in P for fixed L, and a Lyapunov
(Joseph) form: ``P = F P F' + L R L' + Q`` with ``F = A - L C``, so ``P >= 0`` when F is Schur
stable and ``Q >= 0``.  Conversely, any symmetric P with (C) / (D), ``Q >= 0`` and ``A - L C``
stable is the stabilizing Riccati solution for that Q, and L is its Kalman gain
(in discrete time ``S = C P C' + R > 0`` because ``P >= 0``).

Hence, for a fixed L (single output: L is fixed by the poles), ``{Q >= 0, (C) or (D)}`` is an
SDP in ``(P, Q)`` -- :func:`build_fixed_gain_sdp`.  The family of Q for one L is an affine
slice of the PSD cone (for seed 000's Example 1 it is one-dimensional: ``P22`` is free).

With several outputs L is not fixed by the poles.  :func:`build_spectral_nlp` (the default
NLP) works in Q alone: by the Kalman spectral identity ``T(s) R T(-s)' = R + C (sI - A)^-1 Q
(-sI - A')^-1 C'`` a stable ``s_i`` is a filter pole iff that p x p matrix is singular at
``s_i``, i.e. has a unit null vector ``w_i`` -- constraints bilinear in ``(Q, w_i)`` (linear
in Q for one output), with ``Q = F F'`` so that ``Q >= 0`` by construction; L and P follow
from one Riccati solve (:func:`build_spectral_nlpsol`: the same NLP with closed-form Jacobian
and Lagrangian Hessian, for the full / input structures).  :func:`build_pole_nlp` is the
state-space alternative in ``(L, P, F, X)``: the relations (C)/(D) (bilinear in L and P) and
the eigenvalue conditions in real modal form ``(A - L C) X = X Lambda``; it is used where the
spectral form is singular (a target at an eigenvalue of A or its mirror) and, with
``closest=True`` (the eigenvalues ``Lambda(mu)`` become variables and the objective is their
distance to the targets), for the closest achievable poles reported as a certificate when a
target is out of reach.

Structures of Q: ``"full"`` (any n x n ``Q >= 0``), ``"input"`` (``Q = G Qw G'``, ``Qw >= 0``
m x m) and ``"diagonal"`` (``Q = G diag(qw) G'``, ``qw >= 0``: independent noise inputs; a
diagonal Q when ``G = I``).

Objectives (which member of the family is returned): ``"min_trace"`` minimizes ``trace(Q)``
(state-space Q, whatever the structure); ``"nearest"`` minimizes the Frobenius distance of the
decision covariance (Q for ``"full"``, Qw -- ``diag(qw)`` -- otherwise) to ``Q_nominal``;
``"feasibility"`` maximizes the smallest eigenvalue ``t`` of the decision covariance (the most
robustly positive member; ``t < 0`` at the optimum measures infeasibility).  For a fixed stable
gain that maximum is finite: a direction D with ``D C' = 0`` and ``-(A D + D A') >= 0`` would
give ``(A - LC) D + D (A - LC)' <= 0``, hence ``D >= 0`` and ``C D C' = 0``, hence ``D = 0`` by
observability -- the PSD part of the family is bounded.

References
----------
Chang & Lee 1984 (seed 000), eq (20)-(21).  Kalman, R. E., "When is a linear control system
optimal?", J. Basic Eng. 86 (1964) 51-60 (the inverse problem and the return difference).
Anderson, B. D. O. & Moore, J. B., *Optimal Filtering*, Prentice-Hall 1979 (the spectral
factorization / return-difference identity of the Kalman filter).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..errors import ValidationError

__all__ = [
    "STRUCTURES",
    "OBJECTIVES",
    "fixed_gain_maps",
    "modal_blocks",
    "FixedGainSDP",
    "build_fixed_gain_sdp",
    "PoleNLP",
    "build_pole_nlp",
    "spectral_terms",
    "SpectralNLP",
    "build_spectral_nlp",
    "spectral_linear_conditions",
    "SpectralSDP",
    "build_spectral_sdp",
    "FAST_STRUCTURES",
    "FAST_OBJECTIVES",
    "SpectralNLPSol",
    "build_spectral_nlpsol",
]

STRUCTURES = ("full", "diagonal", "input")
OBJECTIVES = ("min_trace", "nearest", "feasibility")


def _check_choice(name: str, value: str, allowed: tuple[str, ...]) -> None:
    if value not in allowed:
        raise ValidationError(f"{name} must be one of {tuple(allowed)}; found {value!r}")


def _check_options(structure: str, objective: str, G: NDArray | None, Q_nominal: NDArray | None, *,
                   structures: tuple[str, ...] = STRUCTURES, objectives: tuple[str, ...] = OBJECTIVES,
                   nominal_needed: bool = True) -> None:
    """The option checks every builder shares (structure, objective, G, ``Q_nominal``)."""
    _check_choice("structure", structure, structures)
    _check_choice("objective", objective, objectives)
    if structure != "full" and G is None:
        raise ValidationError(f"structure={structure!r} needs the noise input matrix G")
    if nominal_needed and objective == "nearest" and Q_nominal is None:
        raise ValidationError("objective='nearest' needs Q_nominal")


def _require_terms(A: NDArray, C: NDArray, poles: NDArray, dt: float | None, terms: list | None) -> list:
    """``terms`` or :func:`spectral_terms`; raises where the spectral identity is singular."""
    if terms is None:
        terms = spectral_terms(A, C, poles, dt)
    if terms is None:
        raise ValidationError("a target pole is an eigenvalue of A or of its mirror image: the spectral "
                              "identity is singular there (use build_pole_nlp or build_fixed_gain_sdp)")
    return terms


def _tril_index(k: int) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """Row and column indices of the lower triangle, column by column (the factor's vector)."""
    cols, rows = np.triu_indices(k)  # (j, i) with i >= j, ordered by j then i
    return rows.astype(np.intp), cols.astype(np.intp)


def _psd_part(W: NDArray) -> NDArray:
    w, V = np.linalg.eigh(0.5 * (W + W.T))
    return (V * np.maximum(w, 0.0)) @ V.T


def _chol_factor(W: NDArray) -> NDArray:
    """Lower-triangular factor of a PSD matrix: Cholesky of ``W + 1e-10 max(1, ||W||) I``."""
    k = W.shape[0]
    return np.linalg.cholesky(W + 1e-10 * max(1.0, float(np.linalg.norm(W, 2))) * np.eye(k))


def _null_vector_start(M0: NDArray, size: int, c: int, p: int) -> NDArray:
    """Initial null vector of ``M0`` for the c-th repetition of a target: its (c+1)-th smallest
    right singular vector (the smallest when c >= p); complex for a pair (size 2), with the
    phase fixed so that ``Re w' Im w = 0``."""
    j = -1 - c if c < p else -1
    if size == 1:
        return np.linalg.svd(M0.real)[2][j]
    v = np.linalg.svd(M0)[2][j].conj()
    return v * np.exp(-0.5j * np.angle(v @ v))


def fixed_gain_maps(A: NDArray, C: NDArray, L: NDArray, R: NDArray, dt: float | None,
                    scale: float = 1.0) -> tuple[Callable[[Any], Any], Callable[[Any], Any]]:
    """The affine relations (C) / (D) for a fixed gain.

    Returns ``gain_residual(P)`` ((n, p), zero for an admissible P) and ``q_of_P(P)`` ((n, n),
    the process noise that makes P the Riccati solution).  Both accept numpy arrays or cvxpy
    expressions (only ``@``, ``+``, ``-`` and ``.T`` are used).  With ``scale = s`` they are
    the relations for ``P / s`` and ``Q / s`` (the constant terms ``L R`` and ``L R L'`` are
    divided by s).
    """
    LR = L @ R / scale
    LRL = LR @ L.T
    LRL = 0.5 * (LRL + LRL.T)
    if dt is None:
        def gain_residual(P):
            return P @ C.T - LR

        def q_of_P(P):
            return LRL - A @ P - P @ A.T
    else:
        F = A - L @ C

        def gain_residual(P):
            return F @ P @ C.T - LR

        def q_of_P(P):
            return P - F @ P @ F.T - LRL
    return gain_residual, q_of_P


def modal_blocks(poles: NDArray) -> list[tuple[int, complex]]:
    """Real modal pattern of a conjugate-closed pole vector sorted as :func:`as_poles` does.

    Returns a list of ``(size, pole)``: ``(1, s)`` for a real pole, ``(2, a + jb)`` (b > 0) for a
    pair; the block for a pair is ``[[a, b], [-b, a]]``.
    """
    out: list[tuple[int, complex]] = []
    k = 0
    z = np.asarray(poles, dtype=complex)
    while k < z.size:
        if z[k].imag != 0:
            out.append((2, complex(z[k].real, abs(z[k].imag))))
            k += 2
        else:
            out.append((1, complex(z[k].real)))
            k += 1
    return out


def _block_matrix(blocks: list[tuple[int, complex]]) -> NDArray[np.float64]:
    n = sum(b for b, _ in blocks)
    Lam = np.zeros((n, n))
    k = 0
    for size, z in blocks:
        if size == 1:
            Lam[k, k] = z.real
        else:
            Lam[k:k + 2, k:k + 2] = [[z.real, z.imag], [-z.imag, z.real]]
        k += size
    return Lam


# ------------------------------------------------------------------------------ SDP
@dataclass(eq=False)
class FixedGainSDP:
    """A cvxpy problem for the family of Q of a fixed gain (values are scaled by ``scale``).

    In continuous time the gain enters only through cvxpy ``Parameter`` s (DPP), so one problem
    serves every gain of a plant: :meth:`set_gain` binds a new L (and ``Q_nominal``) and the next
    solve re-uses cvxpy's compiled problem instead of canonicalizing it again (4-5x less time per
    solve for small n; ``benchmarks/bench_sweep.py``).

    Attributes
    ----------
    problem : cvxpy.Problem
    P : cvxpy.Variable
        (n, n) symmetric; the error covariance is ``scale * P.value``.
    Q : cvxpy.Variable
        (n, n) symmetric, PSD (for ``"full"``) or equal to ``G Qw G'``; state-space noise is
        ``scale * Q.value``.
    Qw : cvxpy.Variable or None
        (m, m) symmetric PSD (``"input"``) or (m,) nonnegative (``"diagonal"``).
    t : cvxpy.Variable or None
        Smallest-eigenvalue margin (objective ``"feasibility"``), scaled.
    scale : float
        Of the gain last bound by :meth:`set_gain`.
    structure, objective : str
    params : dict
        The cvxpy parameters: ``"LR"`` (n, p) = L R / scale, ``"LRL"`` (n, n) = L R L' / scale,
        ``"Q_nominal"`` (objective ``"nearest"``).
    A, C, R : ndarray
    dt : float or None
        Discrete-time problems are built for one gain (``set_gain`` accepts only that gain,
        for a new ``Q_nominal``).
    """

    problem: Any
    P: Any
    Q: Any
    Qw: Any
    t: Any
    scale: float
    structure: str
    objective: str
    params: dict[str, Any]
    A: NDArray
    C: NDArray
    R: NDArray
    dt: float | None = None
    _L: NDArray | None = field(default=None, repr=False)

    def set_gain(self, L: NDArray, Q_nominal: NDArray | None = None) -> FixedGainSDP:
        """Bind the gain ``L`` ((n, p)) and, for ``"nearest"``, ``Q_nominal``; returns self.

        The variables' values are cleared, so a failed solve can never leave a previous gain's
        solution behind.

        Raises
        ------
        ValidationError
            Wrong shape of L, or ``"nearest"`` without ``Q_nominal``.
        """
        L = np.asarray(L, dtype=float)
        n, p = self.A.shape[0], self.C.shape[0]
        if L.shape != (n, p):
            raise ValidationError(f"L must have shape ({n}, {p}); found {L.shape}")
        if self.objective == "nearest" and Q_nominal is None:
            raise ValidationError("objective='nearest' needs Q_nominal")
        s = _scale_of(L, self.R, None if Q_nominal is None else np.asarray(Q_nominal, dtype=float))
        LR = L @ self.R / s
        LRL = LR @ L.T
        self.params["LR"].value = LR
        self.params["LRL"].value = 0.5 * (LRL + LRL.T)
        if self.dt is not None and self._L is not None and not np.array_equal(L, self._L):
            raise ValidationError("a discrete-time fixed-gain SDP is built for one gain (F P F' with "
                                  "F = A - L C is not DPP): build a new one for another gain")
        self._L = L.copy()
        if "Q_nominal" in self.params:
            Qn = np.asarray(Q_nominal, dtype=float) / s
            self.params["Q_nominal"].value = 0.5 * (Qn + Qn.T)
        self.scale = s
        for v in self.problem.variables():
            v.value = None
        return self


def _scale_of(L: NDArray, R: NDArray, extra: NDArray | None = None) -> float:
    s = max(float(np.linalg.norm(L @ R @ L.T)), float(np.linalg.norm(L @ R)))
    if extra is not None:
        s = max(s, float(np.linalg.norm(extra)))
    return s if s > 0 and np.isfinite(s) else 1.0


def _noise_structure_and_objective(cp, Q, structure: str, G: NDArray | None, objective: str, nominal,
                                   cons: list, T: NDArray | None = None):
    """The part the fixed-gain and spectral SDPs share: the structure of the noise (``Q`` free,
    ``Q = G Qw G'`` or ``Q = G diag(qw) G'``), its PSD constraint and the objective.

    ``nominal`` is the (scaled) ``Q_nominal`` of ``"nearest"`` -- an array or a cvxpy parameter
    of the decision covariance's shape.  ``T`` (optional): the data are in transformed state
    coordinates and the physical noise is ``T Q T'``; the objective is that of the physical
    noise (``trace(T'T Q)``, ``||T Q T' - Q_nominal||``, ``T Q T' >= t I``).  Appends to
    ``cons``; returns ``(Qw, t, objective)`` (``Qw`` None for ``"full"``, ``t`` the margin
    variable of ``"feasibility"`` or None).
    """
    Qw = t = None
    if structure == "full":
        dec = Q
    else:
        m = G.shape[1]
        if structure == "input":
            Qw = cp.Variable((m, m), symmetric=True, name="Qw")
            dec = Qw
        else:
            Qw = cp.Variable(m, name="qw")
            dec = cp.diag(Qw)
        D = Q - G @ dec @ G.T
        cons += [cp.upper_tri(D) == 0, cp.diag(D) == 0]
    metric = structure == "full" and T is not None
    if objective == "feasibility":
        t = cp.Variable(name="t")
        if structure == "diagonal":
            cons.append(Qw >= t)
        else:
            k = dec.shape[0]
            N = np.eye(k)
            if metric:  # T Q T' >= t I  <=>  Q >= t T^-1 T^-T
                Ti = np.linalg.inv(T)
                N = 0.5 * (Ti @ Ti.T + (Ti @ Ti.T).T)
            cons.append(dec - t * N >> 0)
        return Qw, t, cp.Maximize(t)
    cons.append(Qw >= 0 if structure == "diagonal" else dec >> 0)
    if objective == "min_trace":
        if T is None:
            return Qw, t, cp.Minimize(cp.trace(Q))
        M = T.T @ T
        return Qw, t, cp.Minimize(cp.trace((0.5 * (M + M.T)) @ Q))
    if metric:
        return Qw, t, cp.Minimize(cp.norm(T @ dec @ T.T - nominal, "fro"))
    return Qw, t, cp.Minimize(cp.norm(dec - nominal, "fro"))


def build_fixed_gain_sdp(
    A: NDArray, C: NDArray, L: NDArray, R: NDArray, *, dt: float | None = None,
    structure: str = "full", G: NDArray | None = None, objective: str = "min_trace",
    Q_nominal: NDArray | None = None, T: NDArray | None = None,
) -> FixedGainSDP:
    r"""SDP over the Q family of a fixed gain L (relations (C) / (D) of the module docstring).

    In continuous time L (and ``Q_nominal``) are cvxpy parameters: re-bind them with
    :meth:`FixedGainSDP.set_gain` to solve for another gain without rebuilding.  In discrete
    time ``F = A - L C`` multiplies P on both sides (``F P F'``), which is not DPP; the problem
    is built for one gain (``Q_nominal`` stays a parameter).

    Parameters
    ----------
    A : (n, n) ndarray
    C : (p, n) ndarray
    L : (n, p) ndarray
        The fixed gain.
    R : (p, p) ndarray
        Positive definite.
    dt : float, optional
        None for continuous time (relations (C)), else discrete (relations (D)).
    structure : {"full", "diagonal", "input"}
    G : (n, m) ndarray, optional
        Needed for ``"diagonal"`` and ``"input"``.
    objective : {"min_trace", "nearest", "feasibility"}
    Q_nominal : ndarray, optional
        For ``"nearest"``: (n, n) for ``"full"``, (m, m) for ``"input"`` / ``"diagonal"``
        (physical, also when ``T`` is given).
    T : (n, n) ndarray, optional
        The data (A, C, L, G) are given in transformed state coordinates ``x = T x~``; the
        physical covariances are ``T P T'`` and ``T Q T'`` and the objective is evaluated on
        them.  A well-chosen T (the design layer whitens the observer's error covariance) keeps
        the SDP well scaled when the physical P spans many decades.

    Returns
    -------
    FixedGainSDP
        Built, not solved (solve with :func:`optdesign.solvers.cvxpy_backend.solve_cvxpy`).

    Raises
    ------
    ValidationError
        Unknown structure / objective, or a missing G / Q_nominal.
    """
    from ..solvers.cvxpy_backend import import_cvxpy

    cp = import_cvxpy()
    _check_options(structure, objective, G, Q_nominal)
    A = np.asarray(A, dtype=float)
    C = np.asarray(C, dtype=float)
    R = np.asarray(R, dtype=float)
    n, p = A.shape[0], C.shape[0]
    params = {"LR": cp.Parameter((n, p), name="LR"), "LRL": cp.Parameter((n, n), symmetric=True, name="LRL")}
    P = cp.Variable((n, n), symmetric=True, name="P")
    Q = cp.Variable((n, n), symmetric=True, name="Q")
    cons = []
    if dt is None:
        gres = P @ C.T - params["LR"]
        Qe = params["LRL"] - A @ P - P @ A.T
    else:
        # F P F' with a parameter F is not DPP; written F Y with a variable Y = P F' it is, but
        # Clarabel then fails on some problems the direct form solves (measured: 6 of 60 random
        # discrete problems), so the discrete problem keeps F as a constant
        F = A - np.asarray(L, dtype=float) @ C
        gres = F @ P @ C.T - params["LR"]
        Qe = P - F @ P @ F.T - params["LRL"]
    Qe = 0.5 * (Qe + Qe.T)
    D = Q - Qe
    cons += [gres == 0, cp.upper_tri(D) == 0, cp.diag(D) == 0]
    nominal = None
    if objective == "nearest":
        k = n if structure == "full" else G.shape[1]
        nominal = params["Q_nominal"] = cp.Parameter((k, k), symmetric=True, name="Q_nominal")
    Qw, t, obj = _noise_structure_and_objective(cp, Q, structure, G, objective, nominal, cons,
                                                None if T is None else np.asarray(T, dtype=float))
    sdp = FixedGainSDP(problem=cp.Problem(obj, cons), P=P, Q=Q, Qw=Qw, t=t, scale=1.0,
                       structure=structure, objective=objective, params=params, A=A, C=C, R=R,
                       dt=dt)
    return sdp.set_gain(L, Q_nominal)


# ------------------------------------------------------------------------------ NLP
@dataclass(frozen=True, eq=False)
class PoleNLP:
    """A CasADi ``Opti`` problem for Kalman gains with prescribed (or closest) poles.

    All covariances are scaled: the physical ones are ``scale *`` the symbols' values.

    Attributes
    ----------
    opti : casadi.Opti
    L : casadi.MX
        (n, p) gain variable.
    P : casadi.MX
        (n, n) symmetric variable.
    Fvec : casadi.MX
        The decision vector behind F (lower-triangle entries, column by column; for
        ``"diagonal"`` the same as F) -- set its initial value.
    F : casadi.MX
        Lower-triangular factor: ``Q = F F'`` (full) or ``Qw = F F'`` (input), plus ``t I``
        for the objective ``"feasibility"``; for ``"diagonal"`` the (m, 1) variable
        ``qw >= 0`` (``>= t``).
    Q : casadi.MX
        (n, n) state-space process noise expression (scaled).
    Qw : casadi.MX or None
        (m, m) noise-input covariance expression (input / diagonal).
    X : casadi.MX
        (n, n) real modal eigenvector variable.
    Lam : casadi.MX
        (n, n) modal matrix (constant for exact targets, a function of ``mu`` when closest).
    mu : casadi.MX or None
        Pole variables (closest mode): one per real pole, (re, im) per pair.
    t : casadi.MX or None
        Margin variable (objective ``"feasibility"``).
    blocks : list of (int, complex)
        Modal pattern of the targets.
    scale : float
    closest : bool
    """

    opti: Any
    L: Any
    P: Any
    Fvec: Any
    F: Any
    Q: Any
    Qw: Any
    X: Any
    Lam: Any
    mu: Any
    t: Any
    blocks: list
    scale: float
    closest: bool
    structure: str
    objective: str


def _lower_factor(ca, opti, k: int):
    """A lower-triangular k x k MX matrix built from k(k+1)/2 new variables."""
    I, J = _tril_index(k)
    v = opti.variable(I.size)
    E = np.zeros((k * k, I.size))
    E[J * k + I, np.arange(I.size)] = 1.0  # column-major vec
    return ca.reshape(ca.mtimes(ca.DM(E), v), k, k), v


def _lower_entries(ca, M, k: int):
    return ca.vertcat(*[M[int(i), int(j)] for i, j in zip(*_tril_index(k), strict=True)])


def _casadi_noise(ca, opti, structure: str, n: int, G: NDArray | None, t):
    """The process noise of the NLPs: ``Q = F F'`` (``"full"``), ``Q = G Qw G'`` with
    ``Qw = F F'`` (``"input"``) or ``Qw = diag(qw)``, ``qw >= 0`` (``"diagonal"``); plus
    ``t I`` (``qw >= t``) when the margin variable ``t`` is given.

    Returns ``(F, Fvec, Q, Qw, Qdec)``: the factor (``qw`` for ``"diagonal"``), its decision
    vector, Q, Qw (None for ``"full"``) and the decision covariance (Q or Qw).
    """
    if structure == "diagonal":
        Fvec = opti.variable(G.shape[1])
        opti.subject_to(Fvec >= (t if t is not None else 0))
        Qw = ca.densify(ca.diag(Fvec))
        Gd = ca.DM(G)
        return Fvec, Fvec, ca.mtimes(ca.mtimes(Gd, Qw), Gd.T), Qw, Qw
    k = n if structure == "full" else G.shape[1]
    F, Fvec = _lower_factor(ca, opti, k)
    Qdec = ca.mtimes(F, F.T)
    if t is not None:
        Qdec = Qdec + t * ca.DM(np.eye(k))
    if structure == "full":
        return F, Fvec, Qdec, None, Qdec
    Gd = ca.DM(G)
    return F, Fvec, ca.mtimes(ca.mtimes(Gd, Qdec), Gd.T), Qdec, Qdec


def _casadi_objective(ca, opti, objective: str, Q, Qdec, t, Q_nominal: NDArray | None, s: float) -> None:
    """``min trace(Q)``, ``min ||Qdec - Q_nominal / s||_F^2`` or ``max t``."""
    if objective == "min_trace":
        opti.minimize(ca.trace(Q))
    elif objective == "nearest":
        opti.minimize(ca.sumsqr(Qdec - ca.DM(np.asarray(Q_nominal, dtype=float) / s)))
    else:
        opti.minimize(-t)


def build_pole_nlp(
    A: NDArray, C: NDArray, R: NDArray, poles: NDArray, *, dt: float | None = None,
    structure: str = "full", G: NDArray | None = None, objective: str = "min_trace",
    Q_nominal: NDArray | None = None, closest: bool = False, scale: float = 1.0,
    margin: float = 1e-6,
) -> PoleNLP:
    r"""NLP over ``(L, P, Q = F F', X)`` with ``eig(A - L C) = poles`` (or closest to them).

    Constraints: (C) or (D) of the module docstring with L a variable (bilinear), the
    structure of Q, ``(A - L C) X = X Lambda`` in real modal form with each real column /
    complex pair of columns normalized (``x'x = 1``; ``u'u + w'w = 1``, ``u'w = 0``) and, for
    repeated targets, mutually orthogonal columns within the repeated group.  In ``closest``
    mode ``Lambda`` holds the variables ``mu`` (same real/complex pattern as the targets),
    constrained stable by ``margin``, and the objective is
    ``sum |mu_i - s_i|^2 / max(1, |s_i|)^2``.

    Parameters
    ----------
    A, C, R : ndarray
        Plant matrices, (n, n), (p, n), (p, p).
    poles : (n,) ndarray of complex
        Targets sorted as :func:`optdesign._validate.as_poles` returns them.
    dt : float, optional
        Discrete time when given.
    structure : {"full", "diagonal", "input"}
    G : (n, m) ndarray, optional
        For ``"input"`` / ``"diagonal"``.
    objective : {"min_trace", "nearest", "feasibility"}
        Ignored in ``closest`` mode.
    Q_nominal : ndarray, optional
        For ``"nearest"`` (physical units).
    closest : bool
        Closest-achievable-poles mode.
    scale : float
        Covariance scale: the symbols hold ``Q / scale`` and ``P / scale``.
    margin : float
        Closest mode: ``Re mu <= -margin`` (continuous) or ``|mu| <= 1 - margin`` (discrete).

    Returns
    -------
    PoleNLP
        Built, not solved; the caller sets initial values and runs
        :func:`optdesign.solvers.casadi_backend.solve_opti`.

    Raises
    ------
    ValidationError
        Unknown structure / objective, missing G or Q_nominal.
    """
    from ..solvers.casadi_backend import import_casadi

    ca = import_casadi()
    _check_options(structure, objective, G, Q_nominal, nominal_needed=not closest)
    n, p = A.shape[0], C.shape[0]
    s = float(scale)
    opti = ca.Opti()
    L = opti.variable(n, p)
    P = opti.variable(n, n, "symmetric")
    Rs = ca.DM(R / s)  # P, Q scaled by s: L R L' -> L (R/s) L'
    Ad, Cd = ca.DM(A), ca.DM(C)
    Fcl = Ad - ca.mtimes(L, Cd)
    LR = ca.mtimes(L, Rs)
    LRL = ca.mtimes(LR, L.T)
    if dt is None:
        gres = ca.mtimes(P, Cd.T) - LR
        Qe = LRL - ca.mtimes(Ad, P) - ca.mtimes(P, Ad.T)
    else:
        gres = ca.mtimes(ca.mtimes(Fcl, P), Cd.T) - LR
        Qe = P - ca.mtimes(ca.mtimes(Fcl, P), Fcl.T) - LRL
    opti.subject_to(ca.vec(gres) == 0)
    t = opti.variable() if (objective == "feasibility" and not closest) else None
    F, Fvec, Q, Qw, Qdec = _casadi_noise(ca, opti, structure, n, G, t)
    opti.subject_to(_lower_entries(ca, Qe - Q, n) == 0)
    # eigenvalue conditions in real modal form
    target = np.asarray(poles, dtype=complex)
    blocks = modal_blocks(target)
    X = opti.variable(n, n)
    mu = None
    if closest:
        nmu = sum(size for size, _ in blocks)
        mu = opti.variable(nmu)
        rows = []
        k0 = 0
        Lam = ca.MX.zeros(n, n)
        cost = 0
        for size, z in blocks:
            w = max(1.0, abs(z)) ** 2
            if size == 1:
                Lam[k0, k0] = mu[k0]
                cost = cost + (mu[k0] - z.real) ** 2 / w
                if dt is None:
                    rows.append(mu[k0] + margin)
                else:
                    rows.append(mu[k0] ** 2 - (1 - margin) ** 2)
            else:
                a, b = mu[k0], mu[k0 + 1]
                Lam[k0, k0] = a
                Lam[k0, k0 + 1] = b
                Lam[k0 + 1, k0] = -b
                Lam[k0 + 1, k0 + 1] = a
                cost = cost + 2 * ((a - z.real) ** 2 + (b - z.imag) ** 2) / w
                rows.append(a + margin if dt is None else a ** 2 + b ** 2 - (1 - margin) ** 2)
            k0 += size
        opti.subject_to(ca.vertcat(*rows) <= 0)
        opti.minimize(cost)
    else:
        Lam = ca.DM(_block_matrix(blocks))
        _casadi_objective(ca, opti, objective, Q, Qdec, t, Q_nominal, s)
    opti.subject_to(ca.vec(ca.mtimes(Fcl, X) - ca.mtimes(X, Lam)) == 0)
    k0 = 0
    norms = []
    groups: dict[complex, list[int]] = {}
    for size, z in blocks:
        if size == 1:
            norms.append(ca.sumsqr(X[:, k0]) - 1)
        else:
            u, w = X[:, k0], X[:, k0 + 1]
            norms.append(ca.sumsqr(u) + ca.sumsqr(w) - 1)
            norms.append(ca.dot(u, w))
        if not closest:
            key = complex(round(z.real, 10), round(z.imag, 10))
            groups.setdefault(key, []).append(k0)
        k0 += size
    for cols in groups.values():  # repeated targets: keep their eigenvectors independent
        for i in range(len(cols)):
            for j in range(i + 1, len(cols)):
                norms.append(ca.dot(X[:, cols[i]], X[:, cols[j]]))
    opti.subject_to(ca.vertcat(*norms) == 0)
    return PoleNLP(opti=opti, L=L, P=P, Fvec=Fvec, F=F, Q=Q, Qw=Qw, X=X, Lam=Lam, mu=mu, t=t, blocks=blocks,
                   scale=s, closest=closest, structure=structure, objective=objective)


# --------------------------------------------------------------------- spectral NLP
def spectral_terms(A: NDArray, C: NDArray, poles: NDArray, dt: float | None,
                   rtol: float = 1e-8) -> list[tuple[int, complex, NDArray, NDArray, float]] | None:
    r"""The resolvent factors of the Kalman spectral identity at each target block.

    For each block ``(size, s)`` of :func:`modal_blocks` returns ``(size, s, G1, G2, w)`` with
    ``G1 = C (s I - A)^-1`` and ``G2 = C (s~ I - A)^-1`` ((p, n), complex), ``s~ = -s``
    (continuous) or ``1/s`` (discrete), and a row weight ``w = 1 / max(1, ||G1|| ||G2||)``.
    Returns None when a target is (relative ``rtol``) an eigenvalue of A or the mirror image
    ``s~`` of one (the resolvent is singular there), or a discrete target is 0.
    """
    n = A.shape[0]
    eig = np.linalg.eigvals(A)
    out = []
    for size, s in modal_blocks(poles):
        if dt is not None and abs(s) <= rtol:
            return None
        s2 = (1.0 / s) if dt is not None else -s
        for z in (s, s2):
            if np.min(np.abs(eig - z)) <= rtol * max(1.0, abs(z)):
                return None
        G1 = np.linalg.solve((s * np.eye(n) - A).T, C.T.astype(complex)).T
        G2 = np.linalg.solve((s2 * np.eye(n) - A).T, C.T.astype(complex)).T
        w = 1.0 / max(1.0, float(np.linalg.norm(G1) * np.linalg.norm(G2)))
        out.append((size, complex(s), G1, G2, w))
    return out


@dataclass(frozen=True, eq=False)
class SpectralNLP:
    """The spectral-identity NLP (see :func:`build_spectral_nlp`); values scaled by ``scale``.

    Attributes
    ----------
    opti : casadi.Opti
    Fvec : casadi.MX
        Decision vector of the factor (or of ``qw`` for ``"diagonal"``).
    Q : casadi.MX
        (n, n) state-space process noise expression (scaled).
    Qw : casadi.MX or None
        Noise-input covariance expression (input / diagonal).
    t : casadi.MX or None
        Margin variable (objective ``"feasibility"``).
    null_vectors : list of casadi.MX
        The null-vector variables, real and imaginary parts.
    scale : float
    blocks : list of (int, complex)
    """

    opti: Any
    Fvec: Any
    Q: Any
    Qw: Any
    t: Any
    null_vectors: list
    scale: float
    blocks: list
    structure: str
    objective: str


def build_spectral_nlp(
    A: NDArray, C: NDArray, R: NDArray, poles: NDArray, *, dt: float | None = None,
    structure: str = "full", G: NDArray | None = None, objective: str = "min_trace",
    Q_nominal: NDArray | None = None, W0: NDArray | None = None, scale: float = 1.0,
    terms: list | None = None, soft: bool = False,
) -> SpectralNLP:
    r"""NLP in Q alone from the Kalman spectral identity evaluated at the target poles.

    Continuous time: for the Kalman filter of ``(A, C, Q, R)`` the return difference
    ``T(s) = I + C (sI - A)^-1 L`` satisfies ``T(s) R T(-s)' = M(s)`` with

    .. math::

        M(s) = R + C (sI - A)^{-1} Q (-sI - A')^{-1} C' ,

    and ``det T(s) = det(sI - A + LC) / det(sI - A)``.  Discrete time (predictor):
    ``T(z) V T(1/z)' = R + C (zI - A)^-1 Q (z^-1 I - A')^-1 C'`` (V the innovation covariance).
    So a stable ``s_i`` (not an eigenvalue of A or of its mirror ``-A`` / ``A^-1``) is a pole
    of the filter iff ``M(s_i)`` is singular: there is a unit vector ``w_i`` with
    ``M(s_i) w_i = 0``.  Imposing that at every target (complex ``w_i`` split into real and
    imaginary parts, phase fixed by ``Re w' Im w = 0``; a pole repeated k times needs k
    orthonormal null vectors, i.e. a non-defective filter pole) places all n filter poles,
    with ``Q = F F'`` (or ``G F F' G'`` / ``G diag(qw) G'``) as the only design variable --
    P and L then follow from one Riccati solve.  The constraints are bilinear in
    ``(Q, w_i)``; for one output they are linear in Q.

    Parameters
    ----------
    A, C, R : ndarray
    poles : (n,) ndarray of complex
        Targets sorted as :func:`optdesign._validate.as_poles` returns them.
    dt : float, optional
    structure, objective, G, Q_nominal
        As for :func:`build_pole_nlp` (``Q_nominal`` in physical units).
    W0 : ndarray, optional
        Initial decision covariance (physical units): Q (n, n) for ``"full"``, Qw (m, m) for
        ``"input"``, qw (m,) for ``"diagonal"``.  Sets the initial factor and the initial null
        vectors (smallest singular vectors of ``M(s_i)`` at ``W0``).
    scale : float
        Q symbols hold ``Q / scale``.
    terms : list, optional
        Precomputed :func:`spectral_terms`.
    soft : bool
        Least-squares form: minimize ``sum_i ||M(s_i) w_i||^2`` (only the normalizations stay
        constraints; ``objective`` is ignored).  For structures with fewer parameters than
        pole conditions, where the exact form has too few degrees of freedom for IPOPT: a zero
        optimum means the target is reachable after all.

    Returns
    -------
    SpectralNLP

    Raises
    ------
    ValidationError
        Unknown structure / objective, missing G / Q_nominal, or a target at an eigenvalue
        of A or its mirror (use :func:`build_pole_nlp` then).
    """
    from ..solvers.casadi_backend import import_casadi

    ca = import_casadi()
    _check_options(structure, objective, G, Q_nominal, nominal_needed=not soft)
    if soft:
        objective = "min_trace"
    n, p = A.shape[0], C.shape[0]
    terms = _require_terms(A, C, poles, dt, terms)
    s = float(scale)
    opti = ca.Opti()
    t = opti.variable() if objective == "feasibility" else None
    Gd = None if G is None else ca.DM(G)
    k = n if structure == "full" else G.shape[1]
    F, Fvec, Q, Qw, Qdec = _casadi_noise(ca, opti, structure, n, G, t)
    # initial values
    Q0 = None
    if W0 is not None:
        W0 = np.asarray(W0, dtype=float)
        if structure == "diagonal":
            q0 = np.maximum(W0.ravel(), 0.0) / s
            opti.set_initial(Fvec, q0)
            Q0 = G @ np.diag(q0) @ G.T
        else:
            Wp = _psd_part(W0) / s
            if t is not None:
                t0 = -1e-3 * max(1.0, float(np.max(np.abs(Wp))))
                opti.set_initial(t, t0)
                Wp = Wp - t0 * np.eye(k)
            opti.set_initial(Fvec, _chol_factor(Wp)[_tril_index(k)])
            Q0 = Wp if structure == "full" else G @ Wp @ G.T
    Rs = R / s

    def qmul(a):
        """Q a without forming Q: matrix-vector products through the factor (cheaper
        derivatives than the dense n x n product)."""
        if structure == "full":
            b = ca.mtimes(F, ca.mtimes(F.T, a))
            return b + t * a if t is not None else b
        ga = ca.mtimes(Gd.T, a)
        if structure == "diagonal":
            return ca.mtimes(Gd, Fvec * ga)
        b = ca.mtimes(F, ca.mtimes(F.T, ga))
        if t is not None:
            b = b + t * ga
        return ca.mtimes(Gd, b)

    def mw(G1, G2, wgt, wr, wi=None):
        """Real and imaginary parts of wgt (R + G1 Q G2^T) (wr + j wi)."""
        g1r, g1i, g2r, g2i = (ca.DM(X) for X in (G1.real, G1.imag, G2.real, G2.imag))
        if wi is None:
            return wgt * (ca.mtimes(ca.DM(Rs), wr) + ca.mtimes(g1r, qmul(ca.mtimes(g2r.T, wr)))), None
        ar = ca.mtimes(g2r.T, wr) - ca.mtimes(g2i.T, wi)
        ai = ca.mtimes(g2r.T, wi) + ca.mtimes(g2i.T, wr)
        br, bi = qmul(ar), qmul(ai)
        re = ca.mtimes(ca.DM(Rs), wr) + ca.mtimes(g1r, br) - ca.mtimes(g1i, bi)
        im = ca.mtimes(ca.DM(Rs), wi) + ca.mtimes(g1r, bi) + ca.mtimes(g1i, br)
        return wgt * re, wgt * im

    cons = []
    resid = []
    nulls = []
    groups: dict[tuple[float, float], list] = {}
    for size, z, G1, G2, wgt in terms:
        M0 = None if Q0 is None else wgt * (Rs + G1 @ Q0 @ G2.T)
        key = (round(z.real, 9), round(z.imag, 9))
        prev = groups.setdefault(key, [])
        if size == 1:
            w = opti.variable(p)
            if M0 is not None:
                opti.set_initial(w, _null_vector_start(M0, 1, len(prev), p))
            resid.append(mw(G1, G2, wgt, w)[0])
            cons.append(ca.sumsqr(w) - 1)
            for wo in prev:
                cons.append(ca.dot(w, wo[0]))
            prev.append((w, None))
            nulls.append(w)
        else:
            wr, wi = opti.variable(p), opti.variable(p)
            if M0 is not None:
                v = _null_vector_start(M0, 2, len(prev), p)
                opti.set_initial(wr, v.real)
                opti.set_initial(wi, v.imag)
            resid += list(mw(G1, G2, wgt, wr, wi))
            cons += [ca.sumsqr(wr) + ca.sumsqr(wi) - 1, ca.dot(wr, wi)]
            for ar, ai in prev:  # Hermitian orthogonality w_a^H w_b = 0
                cons += [ca.dot(ar, wr) + ca.dot(ai, wi), ca.dot(ar, wi) - ca.dot(ai, wr)]
            prev.append((wr, wi))
            nulls += [wr, wi]
    opti.subject_to(ca.vertcat(*cons) == 0)
    if soft:
        opti.minimize(ca.sumsqr(ca.vertcat(*resid)))
    else:
        opti.subject_to(ca.vertcat(*resid) == 0)
        _casadi_objective(ca, opti, objective, Q, Qdec, t, Q_nominal, s)
    return SpectralNLP(opti=opti, Fvec=Fvec, Q=Q, Qw=Qw, t=t, null_vectors=nulls, scale=s,
                       blocks=[(b[0], b[1]) for b in terms], structure=structure, objective=objective)


# --------------------------------------------------------------------- spectral SDP
@dataclass(frozen=True, eq=False)
class SpectralSDP:
    """The one-output spectral conditions as an SDP in Q alone (values scaled by ``scale``).

    Attributes
    ----------
    problem : cvxpy.Problem
    Q : cvxpy.Variable
        (n, n) symmetric (state-space noise / scale).
    Qw : cvxpy.Variable or None
        (m, m) or (m,) for ``"input"`` / ``"diagonal"``.
    t : cvxpy.Variable or None
    coefficients : ndarray
        (n_eq, n*n) real matrix E and ``offset`` (n_eq,) with the conditions
        ``E vec(Q / scale) + offset = 0`` (column-major vec).
    offset : ndarray
    scale : float
    """

    problem: Any
    Q: Any
    Qw: Any
    t: Any
    coefficients: NDArray[np.float64]
    offset: NDArray[np.float64]
    scale: float
    structure: str
    objective: str


def spectral_linear_conditions(terms: list, R: NDArray) -> tuple[NDArray, NDArray]:
    """For one output: the target conditions ``R + G1 Q G2^T = 0`` as real linear equations
    ``E vec(Q) + offset = 0`` (one per real target, two -- real and imaginary part -- per pair),
    each row scaled to unit norm."""
    rows, off = [], []
    r = float(np.asarray(R).ravel()[0])
    for size, _, G1, G2, _ in terms:
        g1, g2 = G1[0], G2[0]
        coef = np.outer(g2, g1).reshape(-1)  # vec(Q) . coef = g1 Q g2^T (column-major vec)
        parts = [(coef.real, r)] if size == 1 else [(coef.real, r), (coef.imag, 0.0)]
        for c, o in parts:
            nrm = max(float(np.linalg.norm(c)), abs(o), 1e-300)
            rows.append(c / nrm)
            off.append(o / nrm)
    return np.asarray(rows), np.asarray(off)


def build_spectral_sdp(
    A: NDArray, C: NDArray, R: NDArray, poles: NDArray, *, dt: float | None = None,
    structure: str = "full", G: NDArray | None = None, objective: str = "min_trace",
    Q_nominal: NDArray | None = None, terms: list | None = None,
) -> SpectralSDP:
    r"""One output: the spectral conditions of :func:`build_spectral_nlp` are *linear* in Q.

    With p = 1 the null vector is a scalar, so ``s_i`` is a filter pole iff
    ``R + C (s_i I - A)^-1 Q (s~_i I - A)^-T C' = 0`` -- n real linear equations on Q (a pair
    gives the real and imaginary part), plus ``Q >= 0``: an SDP in Q alone, without P or L,
    and better scaled than the fixed-gain SDP when the gain is large (its ``L R L'`` and
    ``A P + P A'`` nearly cancel).  L and P then follow from one Riccati solve.

    Parameters and structures / objectives as for :func:`build_fixed_gain_sdp`.

    Raises
    ------
    ValidationError
        More than one output, a target at an eigenvalue of A or its mirror, or bad options.
    """
    from ..solvers.cvxpy_backend import import_cvxpy

    cp = import_cvxpy()
    _check_options(structure, objective, G, Q_nominal)
    if C.shape[0] != 1:
        raise ValidationError(f"the spectral SDP needs one output; C has {C.shape[0]} rows")
    terms = _require_terms(A, C, poles, dt, terms)
    n = A.shape[0]
    E, off = spectral_linear_conditions(terms, R)
    # scale Q so that the conditions are O(1): |E vec(Q)| ~ |offset|
    s = float(np.median(np.abs(off[np.abs(off) > 0]))) / max(
        float(np.median(np.linalg.norm(E, axis=1))), 1e-300) if np.any(off) else 1.0
    s = s if (np.isfinite(s) and s > 0) else 1.0
    Q = cp.Variable((n, n), symmetric=True, name="Q")
    cons = [E @ cp.vec(Q, order="F") * s + off == 0]
    nominal = None if Q_nominal is None else np.asarray(Q_nominal) / s
    Qw, t, obj = _noise_structure_and_objective(cp, Q, structure, G, objective, nominal, cons)
    return SpectralSDP(problem=cp.Problem(obj, cons), Q=Q, Qw=Qw, t=t, coefficients=E, offset=off,
                       scale=s, structure=structure, objective=objective)


# ------------------------------------------------------- spectral NLP, exact derivatives
#: structures and objectives the explicit-derivative spectral NLP supports (the others use
#: :func:`build_spectral_nlp`)
FAST_STRUCTURES = ("full", "input")
FAST_OBJECTIVES = ("min_trace", "nearest")


@dataclass(eq=False)
class SpectralNLPSol:
    r"""The spectral-identity NLP of :func:`build_spectral_nlp` with explicit derivatives.

    Same variables, constraints and objective as :func:`build_spectral_nlp`, but the
    constraint Jacobian and the Hessian of the Lagrangian are evaluated in closed form with
    numpy (CasADi callbacks ``jac_g`` / ``hess_lag``) instead of by symbolic differentiation:
    with ``Q = Gd F F' Gd'`` every residual ``w (R/s + G1 Q G2^T) w_i`` is bilinear in
    ``(F F', w_i)``, so (``h = G1^H mu`` for the residual multipliers ``mu``, ``b = Gd' G2^T
    w_i``) the Lagrangian's F-F block is block diagonal by column of F
    (``delta_jl Re(conj(h_i) b_k + conj(h_k) b_i)``), its F-w block is two rank-one products
    per null-vector entry and its w-w block comes from the normalizations only.  Symbolic
    differentiation of the same graph costs O(n^5) (1.6 s at n = 20, 12 s at n = 30, per
    start); the closed forms cost nothing to build and O(n^3 p) per evaluation.

    Attributes
    ----------
    nlp : dict
        ``{"x": SX, "f": SX, "g": SX}`` for ``casadi.nlpsol``.
    options : dict
        ``{"jac_g": Callback, "hess_lag": Callback}`` (merge into the nlpsol options; keep this
        object alive while the solver is used).
    x0 : (nx,) ndarray
        Initial point (from ``W0``).
    lbg, ubg : (ng,) ndarray
        All constraints are equalities (zeros).
    scale : float
    k : int
        Size of the decision covariance (n for ``"full"``, m for ``"input"``).
    n_factor : int
        Number of factor entries (the first ``n_factor`` entries of x).
    structure, objective : str
    """

    nlp: dict
    options: dict
    x0: NDArray[np.float64]
    lbg: NDArray[np.float64]
    ubg: NDArray[np.float64]
    scale: float
    k: int
    n_factor: int
    structure: str
    objective: str
    _keep: list = field(default_factory=list, repr=False)

    def decision(self, x: NDArray) -> NDArray[np.float64]:
        """The decision covariance ``F F'`` (physical units) at the point x."""
        F = np.zeros((self.k, self.k))
        F[_tril_index(self.k)] = np.asarray(x, dtype=float).ravel()[: self.n_factor]
        return self.scale * (F @ F.T)


def _make_callback(ca, name, n_in_shapes, out_sparsity, fun):
    """A CasADi Callback with dense inputs of the given (rows, cols) shapes and one sparse
    output; ``fun(*numpy inputs)`` returns the output's nonzeros (CasADi's column-major order)."""

    class _CB(ca.Callback):
        def __init__(self):
            ca.Callback.__init__(self)
            self.construct(name, {})

        def get_n_in(self):
            return len(n_in_shapes)

        def get_n_out(self):
            return 1

        def get_sparsity_in(self, i):
            return ca.Sparsity.dense(*n_in_shapes[i])

        def get_sparsity_out(self, i):
            return out_sparsity

        def has_eval_buffer(self):
            return True

        def eval_buffer(self, arg, res):  # raw nonzero buffers: no DM conversions
            ins = [np.frombuffer(a, dtype=np.float64) for a in arg]
            out = np.frombuffer(res[0], dtype=np.float64)
            out[:] = fun(*ins)
            return 0

        def eval(self, arg):  # pragma: no cover - CasADi uses eval_buffer
            vals = fun(*[np.asarray(a, dtype=float).ravel(order="F") for a in arg])
            return [ca.DM(out_sparsity, vals)]

    return _CB()


def build_spectral_nlpsol(
    A: NDArray, C: NDArray, R: NDArray, poles: NDArray, *, dt: float | None = None,
    structure: str = "full", G: NDArray | None = None, objective: str = "min_trace",
    Q_nominal: NDArray | None = None, W0: NDArray | None = None, scale: float = 1.0,
    terms: list | None = None,
) -> SpectralNLPSol:
    r"""The spectral NLP (:func:`build_spectral_nlp`) as a ``casadi.nlpsol`` problem with
    closed-form derivatives (see :class:`SpectralNLPSol`).

    Parameters as for :func:`build_spectral_nlp` (``structure`` in :data:`FAST_STRUCTURES`,
    ``objective`` in :data:`FAST_OBJECTIVES`).

    Returns
    -------
    SpectralNLPSol
        Built, not solved.

    Raises
    ------
    ValidationError
        An unsupported structure / objective, missing G / Q_nominal, or a target at an
        eigenvalue of A or its mirror.
    """
    from ..solvers.casadi_backend import import_casadi

    ca = import_casadi()
    _check_options(structure, objective, G, Q_nominal, structures=FAST_STRUCTURES, objectives=FAST_OBJECTIVES)
    n, p = A.shape[0], C.shape[0]
    terms = _require_terms(A, C, poles, dt, terms)
    s = float(scale)
    Gd = np.eye(n) if structure == "full" else np.asarray(G, dtype=float)
    k = Gd.shape[1]
    I, J = _tril_index(k)
    nF = I.size
    Rs = np.asarray(R, dtype=float) / s
    N = None if Q_nominal is None else np.asarray(Q_nominal, dtype=float) / s
    GtG = Gd.T @ Gd
    # ---- variables: factor entries, then the null vectors block by block
    blocks = []  # (size, cols of w (wr[, wi]), rows of the residual, H1, B, wRs)
    quad = []    # normalizations: (row, [(i, j, a), ...], const) with c = sum a x_i x_j + const
    nx = nF
    groups: dict[tuple[float, float], list] = {}
    for size, z, G1, G2, wgt in terms:
        if size == 1:
            H1 = wgt * (G1.real @ Gd) + 0j
            B = Gd.T @ G2.real.T + 0j
            cols = (np.arange(nx, nx + p),)
        else:
            H1 = wgt * (G1 @ Gd)
            B = Gd.T @ G2.T
            cols = (np.arange(nx, nx + p), np.arange(nx + p, nx + 2 * p))
        nx += size * p
        blocks.append((size, cols, H1, B, wgt * Rs))
        key = (round(z.real, 9), round(z.imag, 9))
        prev = groups.setdefault(key, [])
        if size == 1:
            wr = cols[0]
            quad.append(([(i, i, 1.0) for i in wr], -1.0))
            for (o,) in prev:
                quad.append(([(a, b, 1.0) for a, b in zip(o, wr, strict=True)], 0.0))
        else:
            wr, wi = cols
            quad.append(([(i, i, 1.0) for i in wr] + [(i, i, 1.0) for i in wi], -1.0))
            quad.append(([(a, b, 1.0) for a, b in zip(wr, wi, strict=True)], 0.0))
            for ar, ai in prev:  # Hermitian orthogonality w_a^H w_b = 0
                quad.append(([(a, b, 1.0) for a, b in zip(ar, wr, strict=True)]
                             + [(a, b, 1.0) for a, b in zip(ai, wi, strict=True)], 0.0))
                quad.append(([(a, b, 1.0) for a, b in zip(ar, wi, strict=True)]
                             + [(a, b, -1.0) for a, b in zip(ai, wr, strict=True)], 0.0))
        prev.append(cols)
    nq = len(quad)
    rows = []
    ng = nq
    for size, *_ in blocks:
        rows.append(np.arange(ng, ng + size * p))
        ng += size * p
    # ---- SX f and g (cheap to build and to evaluate)
    x = ca.SX.sym("x", nx)
    Fs = ca.SX(k, k)
    for c in range(nF):
        Fs[int(I[c]), int(J[c])] = x[c]
    Qd = ca.mtimes(Fs, Fs.T)
    gs = []
    for terms_q, const in quad:
        gs.append(sum(a * x[int(i)] * x[int(j)] for i, j, a in terms_q) + const)
    for size, cols, H1, B, wRs in blocks:
        wr = x[cols[0][0]:cols[0][-1] + 1]
        if size == 1:
            a = ca.mtimes(ca.DM(B.real), wr)
            b = ca.mtimes(Fs, ca.mtimes(Fs.T, a))
            gs.append(ca.mtimes(ca.DM(wRs), wr) + ca.mtimes(ca.DM(H1.real), b))
        else:
            wi = x[cols[1][0]:cols[1][-1] + 1]
            ar = ca.mtimes(ca.DM(B.real), wr) - ca.mtimes(ca.DM(B.imag), wi)
            ai = ca.mtimes(ca.DM(B.real), wi) + ca.mtimes(ca.DM(B.imag), wr)
            br = ca.mtimes(Fs, ca.mtimes(Fs.T, ar))
            bi = ca.mtimes(Fs, ca.mtimes(Fs.T, ai))
            h1r, h1i = ca.DM(H1.real), ca.DM(H1.imag)
            gs.append(ca.mtimes(ca.DM(wRs), wr) + ca.mtimes(h1r, br) - ca.mtimes(h1i, bi))
            gs.append(ca.mtimes(ca.DM(wRs), wi) + ca.mtimes(h1r, bi) + ca.mtimes(h1i, br))
    g = ca.vertcat(*gs)
    if objective == "min_trace":
        f = ca.trace(ca.mtimes(ca.mtimes(Fs.T, ca.DM(GtG)), Fs))
    else:
        f = ca.sumsqr(Qd - ca.DM(N))
    # ---- sparsity patterns
    jr, jc = [], []
    for q, (terms_q, _) in enumerate(quad):
        idx = sorted({int(i) for i, _, _ in terms_q} | {int(j) for _, j, _ in terms_q})
        jr += [q] * len(idx)
        jc += idx
    for (_size, cols, *_), rr in zip(blocks, rows, strict=True):
        wc = np.concatenate(cols)
        cc = np.concatenate([np.arange(nF), wc])
        for r in rr:
            jr += [int(r)] * cc.size
            jc += cc.tolist()
    jsp = ca.Sparsity.triplet(ng, nx, jr, jc)
    jrow, jcol = (np.asarray(v, dtype=np.intp) for v in jsp.get_triplet())
    hr, hc = [], []
    if objective == "nearest":
        fr, fc = np.meshgrid(np.arange(nF), np.arange(nF), indexing="ij")
        keep = fr <= fc
        hr += fr[keep].tolist()
        hc += fc[keep].tolist()
    else:  # block diagonal by column of F
        for c1 in range(nF):
            same = np.flatnonzero((J == J[c1]) & (np.arange(nF) >= c1))
            hr += [c1] * same.size
            hc += same.tolist()
    wall = np.arange(nF, nx)
    fr, fc = np.meshgrid(np.arange(nF), wall, indexing="ij")
    hr += fr.ravel().tolist()
    hc += fc.ravel().tolist()
    for terms_q, _ in quad:
        for i, j, _ in terms_q:
            hr.append(min(int(i), int(j)))
            hc.append(max(int(i), int(j)))
    hsp = ca.Sparsity.triplet(nx, nx, hr, hc)  # duplicates are merged
    hrow, hcol = (np.asarray(v, dtype=np.intp) for v in hsp.get_triplet())

    def factor(xv):
        F = np.zeros((k, k))
        F[I, J] = xv[:nF]
        return F

    def jac_g(xv, _p):
        xv = xv.ravel()
        F = factor(xv)
        Jm = np.zeros((ng, nx))
        for q, (terms_q, _) in enumerate(quad):
            for i, j, a in terms_q:
                Jm[q, i] += a * xv[j]
                Jm[q, j] += a * xv[i]
        for (size, cols, H1, B, wRs), rr in zip(blocks, rows, strict=True):
            wc = xv[cols[0]] + (1j * xv[cols[1]] if size == 2 else 0.0)
            b = B @ wc
            u = F.T @ b
            V = H1 @ F
            JF = H1[:, I] * u[J][None, :] + V[:, J] * b[I][None, :]
            M = wRs + V @ (F.T @ B)
            Jm[rr[:p], :nF] = JF.real
            Jm[np.ix_(rr[:p], cols[0])] = M.real
            if size == 2:
                Jm[rr[p:], :nF] = JF.imag
                Jm[np.ix_(rr[p:], cols[0])] = M.imag
                Jm[np.ix_(rr[:p], cols[1])] = -M.imag
                Jm[np.ix_(rr[p:], cols[1])] = M.real
        return Jm[jrow, jcol]

    def hess_lag(xv, _p, lam_f, lam_g):
        xv = xv.ravel()
        lam_g = lam_g.ravel()
        of = float(np.asarray(lam_f).ravel()[0])
        F = factor(xv)
        H = np.zeros((nx, nx))
        K = np.zeros((k, k))
        for (size, cols, H1, B, _), rr in zip(blocks, rows, strict=True):
            mu = lam_g[rr[:p]] + (1j * lam_g[rr[p:]] if size == 2 else 0.0)
            h = H1.conj().T @ mu
            wc = xv[cols[0]] + (1j * xv[cols[1]] if size == 2 else 0.0)
            b = B @ wc
            hb = np.outer(h.conj(), b).real
            K += hb + hb.T
            FB = F.T @ B
            Fh = F.T @ h
            X = h.conj()[I][:, None] * FB[J, :] + Fh.conj()[J][:, None] * B[I, :]
            H[:nF, cols[0]] += X.real
            if size == 2:
                H[:nF, cols[1]] -= X.imag
        if objective == "min_trace":
            K += 2.0 * of * GtG
            same = J[:, None] == J[None, :]
            H[:nF, :nF] += np.where(same, K[I[:, None], I[None, :]], 0.0)
        else:
            H[:nF, :nF] += np.where(J[:, None] == J[None, :], K[I[:, None], I[None, :]], 0.0)
            E = F @ F.T - N
            FtF = F.T @ F
            Hn = (4.0 * F[I[None, :], J[:, None]] * F[I[:, None], J[None, :]]
                  + 4.0 * (I[:, None] == I[None, :]) * FtF[J[:, None], J[None, :]]
                  + 4.0 * (J[:, None] == J[None, :]) * E[I[:, None], I[None, :]])
            H[:nF, :nF] += of * Hn
        for q, (terms_q, _) in enumerate(quad):
            nu = lam_g[q]
            for i, j, a in terms_q:
                if i == j:
                    H[i, i] += 2.0 * a * nu
                else:
                    H[min(i, j), max(i, j)] += a * nu
        return H[hrow, hcol]

    cb_j = _make_callback(ca, "spectral_jac_g", [(nx, 1), (0, 1)], jsp, jac_g)
    cb_h = _make_callback(ca, "spectral_hess_lag", [(nx, 1), (0, 1), (1, 1), (ng, 1)], hsp, hess_lag)
    gfun = ca.Function("spectral_g", [x, ca.SX.sym("p", 0)], [g])
    # the jac_g callback must return (g, jac_g): wrap it so that g comes from the SX graph
    xm, pm = ca.MX.sym("x", nx), ca.MX.sym("p", 0)
    jac_fun = ca.Function("nlp_jac_g", [xm, pm], [gfun(xm, pm)[0], cb_j(xm, pm)], ["x", "p"],
                          ["g", "jac_g_x"])
    lf, lg = ca.MX.sym("lam_f"), ca.MX.sym("lam_g", ng)
    hess_fun = ca.Function("nlp_hess_l", [xm, pm, lf, lg], [cb_h(xm, pm, lf, lg)],
                           ["x", "p", "lam_f", "lam_g"], ["triu_hess_gamma_x_x"])
    # ---- initial point
    x0 = np.zeros(nx)
    if W0 is not None:
        Wp = _psd_part(np.asarray(W0, dtype=float)) / s
        x0[:nF] = _chol_factor(Wp)[I, J]
        seen: dict[tuple[float, float], int] = {}
        for (size, cols, H1, B, wRs), (_, z, *_r) in zip(blocks, terms, strict=True):
            key = (round(z.real, 9), round(z.imag, 9))
            c = seen.get(key, 0)
            seen[key] = c + 1
            v = _null_vector_start(wRs + H1 @ Wp @ B, size, c, p)
            if size == 1:
                x0[cols[0]] = v
            else:
                x0[cols[0]], x0[cols[1]] = v.real, v.imag
    else:
        x0[:nF] = np.eye(k)[I, J]
        for _size, cols, *_ in blocks:
            x0[cols[0][0]] = 1.0
    zeros = np.zeros(ng)
    return SpectralNLPSol(nlp={"x": x, "f": f, "g": g}, options={"jac_g": jac_fun, "hess_lag": hess_fun},
                          x0=x0, lbg=zeros, ubg=zeros.copy(), scale=s, k=k, n_factor=nF,
                          structure=structure, objective=objective,
                          _keep=[cb_j, cb_h, gfun, jac_fun, hess_fun])
