"""The fixed-gain SDP: the family of Q of one gain, with cvxpy Parameters (DPP)."""


from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..._backends import import_cvxpy
from ...errors import ValidationError
from .common import check_options, noise_input


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
        s = scale_of(L, self.R, None if Q_nominal is None else np.asarray(Q_nominal, dtype=float))
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


def scale_of(L: NDArray, R: NDArray, extra: NDArray | None = None) -> float:
    s = max(float(np.linalg.norm(L @ R @ L.T)), float(np.linalg.norm(L @ R)))
    if extra is not None:
        s = max(s, float(np.linalg.norm(extra)))
    return s if s > 0 and np.isfinite(s) else 1.0


def noise_structure_and_objective(cp, Q, structure: str, G: NDArray | None, objective: str, nominal,
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
    Qw: Any = None
    t: Any = None
    if structure == "full":
        dec = Q
    else:
        Gm = noise_input(structure, G)
        m = Gm.shape[1]
        if structure == "input":
            Qw = cp.Variable((m, m), symmetric=True, name="Qw")
            dec = Qw
        else:
            Qw = cp.Variable(m, name="qw")
            dec = cp.diag(Qw)
        D = Q - Gm @ dec @ Gm.T
        cons += [cp.upper_tri(D) == 0, cp.diag(D) == 0]
    metric = T if structure == "full" else None  # the physical metric of the decision covariance
    if objective == "feasibility":
        t = cp.Variable(name="t")
        if structure == "diagonal":
            cons.append(Qw >= t)
        else:
            k = dec.shape[0]
            N = np.eye(k)
            if metric is not None:  # T Q T' >= t I  <=>  Q >= t T^-1 T^-T
                Ti = np.linalg.inv(metric)
                N = 0.5 * (Ti @ Ti.T + (Ti @ Ti.T).T)
            cons.append(dec - t * N >> 0)
        return Qw, t, cp.Maximize(t)
    cons.append(Qw >= 0 if structure == "diagonal" else dec >> 0)
    if objective == "min_trace":
        if T is None:
            return Qw, t, cp.Minimize(cp.trace(Q))
        M = T.T @ T
        return Qw, t, cp.Minimize(cp.trace((0.5 * (M + M.T)) @ Q))
    if metric is not None:
        return Qw, t, cp.Minimize(cp.norm(metric @ dec @ metric.T - nominal, "fro"))
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
        Built, not solved (solve with :func:`optdesign.backends.cvxpy_backend.solve_cvxpy`).

    Raises
    ------
    ValidationError
        Unknown structure / objective, or a missing G / Q_nominal.
    """
    cp = import_cvxpy()
    check_options(structure, objective, G, Q_nominal)
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
        k = n if structure == "full" else noise_input(structure, G).shape[1]
        nominal = params["Q_nominal"] = cp.Parameter((k, k), symmetric=True, name="Q_nominal")
    Qw, t, obj = noise_structure_and_objective(cp, Q, structure, G, objective, nominal, cons,
                                                None if T is None else np.asarray(T, dtype=float))
    sdp = FixedGainSDP(problem=cp.Problem(obj, cons), P=P, Q=Q, Qw=Qw, t=t, scale=1.0,
                       structure=structure, objective=objective, params=params, A=A, C=C, R=R,
                       dt=dt)
    return sdp.set_gain(L, Q_nominal)

