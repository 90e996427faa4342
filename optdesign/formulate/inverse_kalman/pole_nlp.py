"""The state-space (eigenvector) NLP: Kalman gains with prescribed -- or the closest -- poles."""


from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..._backends import import_casadi
from .common import block_matrix, check_options, modal_blocks, noise_input, tril_index


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


def lower_factor(ca, opti, k: int):
    """A lower-triangular k x k MX matrix built from k(k+1)/2 new variables."""
    I, J = tril_index(k)
    v = opti.variable(I.size)
    E = np.zeros((k * k, I.size))
    E[J * k + I, np.arange(I.size)] = 1.0  # column-major vec
    return ca.reshape(ca.mtimes(ca.DM(E), v), k, k), v


def lower_entries(ca, M, k: int):
    return ca.vertcat(*[M[int(i), int(j)] for i, j in zip(*tril_index(k), strict=True)])


def casadi_noise(ca, opti, structure: str, n: int, G: NDArray | None, t):
    """The process noise of the NLPs: ``Q = F F'`` (``"full"``), ``Q = G Qw G'`` with
    ``Qw = F F'`` (``"input"``) or ``Qw = diag(qw)``, ``qw >= 0`` (``"diagonal"``); plus
    ``t I`` (``qw >= t``) when the margin variable ``t`` is given.

    Returns ``(F, Fvec, Q, Qw, Qdec)``: the factor (``qw`` for ``"diagonal"``), its decision
    vector, Q, Qw (None for ``"full"``) and the decision covariance (Q or Qw).
    """
    if structure == "diagonal":
        Gm = noise_input(structure, G)
        Fvec = opti.variable(Gm.shape[1])
        opti.subject_to(Fvec >= (t if t is not None else 0))
        Qw = ca.densify(ca.diag(Fvec))
        Gd = ca.DM(Gm)
        return Fvec, Fvec, ca.mtimes(ca.mtimes(Gd, Qw), Gd.T), Qw, Qw
    k = n if structure == "full" else noise_input(structure, G).shape[1]
    F, Fvec = lower_factor(ca, opti, k)
    Qdec = ca.mtimes(F, F.T)
    if t is not None:
        Qdec = Qdec + t * ca.DM(np.eye(k))
    if structure == "full":
        return F, Fvec, Qdec, None, Qdec
    Gd = ca.DM(G)
    return F, Fvec, ca.mtimes(ca.mtimes(Gd, Qdec), Gd.T), Qdec, Qdec


def casadi_objective(ca, opti, objective: str, Q, Qdec, t, Q_nominal: NDArray | None, s: float) -> None:
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
        :func:`optdesign.backends.casadi_backend.solve_opti`.

    Raises
    ------
    ValidationError
        Unknown structure / objective, missing G or Q_nominal.
    """
    ca = import_casadi()
    check_options(structure, objective, G, Q_nominal, nominal_needed=not closest)
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
    F, Fvec, Q, Qw, Qdec = casadi_noise(ca, opti, structure, n, G, t)
    opti.subject_to(lower_entries(ca, Qe - Q, n) == 0)
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
        Lam = ca.DM(block_matrix(blocks))
        casadi_objective(ca, opti, objective, Q, Qdec, t, Q_nominal, s)
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

