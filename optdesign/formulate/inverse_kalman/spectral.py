"""The spectral identity: the pole conditions linear in Q, as an SDP and as an NLP (Opti)."""


from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..._backends import import_casadi, import_cvxpy
from ...errors import ValidationError
from .common import (
    check_options,
    chol_factor,
    noise_input,
    null_vector_start,
    psd_part,
    require_terms,
    tril_index,
)
from .fixed_gain import noise_structure_and_objective
from .pole_nlp import casadi_noise, casadi_objective


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
    ca = import_casadi()
    check_options(structure, objective, G, Q_nominal, nominal_needed=not soft)
    if soft:
        objective = "min_trace"
    n, p = A.shape[0], C.shape[0]
    terms = require_terms(A, C, poles, dt, terms)
    s = float(scale)
    opti = ca.Opti()
    t = opti.variable() if objective == "feasibility" else None
    Gd = None if G is None else ca.DM(G)
    Gm = np.eye(n) if structure == "full" else noise_input(structure, G)  # Q = Gm Qdec Gm'
    k = Gm.shape[1]
    F, Fvec, Q, Qw, Qdec = casadi_noise(ca, opti, structure, n, G, t)
    # initial values
    Q0 = None
    if W0 is not None:
        W0 = np.asarray(W0, dtype=float)
        if structure == "diagonal":
            q0 = np.maximum(W0.ravel(), 0.0) / s
            opti.set_initial(Fvec, q0)
            Q0 = Gm @ np.diag(q0) @ Gm.T
        else:
            Wp = psd_part(W0) / s
            if t is not None:
                t0 = -1e-3 * max(1.0, float(np.max(np.abs(Wp))))
                opti.set_initial(t, t0)
                Wp = Wp - t0 * np.eye(k)
            opti.set_initial(Fvec, chol_factor(Wp)[tril_index(k)])
            Q0 = Wp if structure == "full" else Gm @ Wp @ Gm.T
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
                opti.set_initial(w, null_vector_start(M0, 1, len(prev), p))
            resid.append(mw(G1, G2, wgt, w)[0])
            cons.append(ca.sumsqr(w) - 1)
            for wo in prev:
                cons.append(ca.dot(w, wo[0]))
            prev.append((w, None))
            nulls.append(w)
        else:
            wr, wi = opti.variable(p), opti.variable(p)
            if M0 is not None:
                v = null_vector_start(M0, 2, len(prev), p)
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
        casadi_objective(ca, opti, objective, Q, Qdec, t, Q_nominal, s)
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
    cp = import_cvxpy()
    check_options(structure, objective, G, Q_nominal)
    if C.shape[0] != 1:
        raise ValidationError(f"the spectral SDP needs one output; C has {C.shape[0]} rows")
    terms = require_terms(A, C, poles, dt, terms)
    n = A.shape[0]
    E, off = spectral_linear_conditions(terms, R)
    # scale Q so that the conditions are O(1): |E vec(Q)| ~ |offset|
    s = float(np.median(np.abs(off[np.abs(off) > 0]))) / max(
        float(np.median(np.linalg.norm(E, axis=1))), 1e-300) if np.any(off) else 1.0
    s = s if (np.isfinite(s) and s > 0) else 1.0
    Q = cp.Variable((n, n), symmetric=True, name="Q")
    cons = [E @ cp.vec(Q, order="F") * s + off == 0]
    nominal = None if Q_nominal is None else np.asarray(Q_nominal) / s
    Qw, t, obj = noise_structure_and_objective(cp, Q, structure, G, objective, nominal, cons)
    return SpectralSDP(problem=cp.Problem(obj, cons), Q=Q, Qw=Qw, t=t, coefficients=E, offset=off,
                       scale=s, structure=structure, objective=objective)

