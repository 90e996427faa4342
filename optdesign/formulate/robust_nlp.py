r"""The exact (non-convex) robust observer problem on all models at once: values and analytic
gradients in numpy, posed for IPOPT (CasADi ``nlpsol`` with callbacks) or scipy SLSQP -- built,
never solved.

The variable is the gain itself, ``L`` (its free entries under ``gain_mask``); every model's
error dynamics ``X_i = A_i - L C_i`` move with it.  With ``X = V Lambda V^-1`` (``V`` unit columns,
``W = V^-1``) and ``dX = -dL C``:

* **eigenvalues**: ``d lambda_k = (W dX V)_kk``, so ``d lambda_k / dL = -W[k, :]' (C V)[:, k]'``;
* **conditioning**: ``phi_k(V) = [log sum sigma_j^{2k} + log sum sigma_j^{-2k}] / (2k)`` is a
  smooth upper bound of ``log kappa2(V)`` (``0 <= phi_k - log kappa2 <= log(n) / k``); for
  ``dphi = Re <S, dV>`` (``S = U diag((pi - pi') / sigma) Vh``, ``pi, pi'`` the softmax weights
  of ``+-2k log sigma``) the eigenvector derivative ``dV = V (E o F) + V diag(d)``
  (``F = W dX V``, ``E_jk = 1 / (lambda_k - lambda_j)``, ``d`` keeping the columns at unit norm)
  gives ``dphi / dX = Re(W^H K V^H)`` with ``K = conj(E) o (T - G diag(Re diag T))``,
  ``T = V^H S``, ``G = V^H V``.  Continuation over ``k`` (:data:`KAPPA2_ORDERS`) reaches the
  exact, nonsmooth ``log kappa2`` (its ties of singular values are where the smoothing helps);
* **H2**: ``h = trace(Sigma)`` with ``X Sigma + Sigma X' + G Q G' + L R L' = 0`` and the adjoint
  ``X' Lam + Lam X + I = 0``: ``dh / dL = 2 Lam (L R - Sigma C')`` (discrete:
  ``Sigma = X Sigma X' + ...``, ``Lam = X' Lam X + I``, ``dh / dL = 2 Lam (L R - X Sigma C')``);
* **regions**: :meth:`Region.constraints` at every pole ``(Re lambda, |Im lambda|)``, its
  derivatives by the complex step (the expressions are polynomials of degree <= 2 written in
  plain arithmetic, so ``Im g(re + i h) / h`` is exact); per model and constraint the values are
  sorted over the poles (order statistics are continuous in ``L``, so the constraint vector has a
  fixed size and no jumps when poles collide and leave the real axis).

Problem (``aggregate="max"``, an epigraph variable ``t``)::

    min  t + soft penalty          s.t.  c_i(L) <= t          (every model i)
                                          g(region_i, poles of X_i) <= 0
                                          bounds (kappa2_max, h2_max, hinf_max, ||L||_2 <= max_gain)

with ``c_i = phi_k(V_i)`` (``"kappa2"``) or ``h_i / h_ref`` (``"h2"``); ``aggregate="mean"`` minimizes
``sum_i w_i kappa2_i`` (or ``sum_i w_i h_i / h_ref``) instead; ``"gain"`` minimizes ``||L||_F^2`` (the
smallest gain that meets the constraints; gammasyn's NORMGAIN).  The soft regions add
``soft_weight * sum max(0, g)^2`` (gammasyn's SQUAREPENALTY).

References
----------
A. S. Lewis and M. L. Overton, "Nonsmooth optimization via quasi-Newton methods", Math.
Programming 141, 2013 (nonsmooth kappa2 at optima).
P. Vogt, E. Lenz and U. Konigorski, gammasyn (at - Automatisierungstechnik 68(10), 2020): hard
and soft pole regions for several models, ``EIGENVALUECONDITION`` objective, IPOPT.
R. B. Nelson, "Simplified calculation of eigenvector derivatives", AIAA J. 14(9), 1976.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.linalg
from numpy.typing import NDArray

from .._backends import import_casadi
from ..analysis.norms import hinf_norm
from ..errors import ValidationError
from ..model.model_set import ModelSet
from ..model.regions import Region
from .robust_lmi import default_margin

__all__ = [
    "NLP_OBJECTIVES",
    "AGGREGATES",
    "KAPPA2_ORDERS",
    "Spectrum",
    "spectrum",
    "log_kappa_bound",
    "region_terms",
    "h2_terms",
    "hinf_terms",
    "RobustNLP",
    "build_robust_nlp",
]

#: objectives of the NLP route
NLP_OBJECTIVES = ("kappa2", "h2", "gain")
#: how the per-model objectives are combined
AGGREGATES = ("max", "mean")
#: continuation orders k of the smooth kappa2 bound (None: the exact, nonsmooth log kappa2)
KAPPA2_ORDERS: tuple[int | None, ...] = (2, 16, 128, 1024, None)
#: order of the smooth bound of ||L||_2 used by the gain bound (relative slack <= log(p)/(2 k))
GAIN_ORDER = 512
_H = 1e-30  # complex step


@dataclass(frozen=True, eq=False)
class Spectrum:
    """Eigen-decomposition of one model's error dynamics ``X = V diag(lam) W``.

    Attributes
    ----------
    lam : (n,) complex
    V : (n, n) complex
        Unit-norm columns.
    W : (n, n) complex
        ``V^-1``.
    CV : (p, n) complex
        ``C V``.
    """

    lam: NDArray[np.complex128]
    V: NDArray[np.complex128]
    W: NDArray[np.complex128]
    CV: NDArray[np.complex128]


def spectrum(X: NDArray, C: NDArray) -> Spectrum | None:
    """The eigen-decomposition of ``X`` (None when two eigenvalues coincide to rounding, V is singular, or
    X is not finite)."""
    if not np.all(np.isfinite(X)):
        return None
    lam, V = np.linalg.eig(X)
    gaps = np.abs(lam[:, None] - lam[None, :]) + np.diag(np.full(lam.size, np.inf))
    if lam.size > 1 and float(np.min(gaps)) <= 1e3 * np.finfo(float).eps * max(
        1.0, float(np.max(np.abs(lam)))
    ):
        return None  # a (numerically) repeated eigenvalue: no eigenvector derivative
    V = V.astype(complex) / np.linalg.norm(V, axis=0)
    try:
        W = np.linalg.inv(V)
    except np.linalg.LinAlgError:
        return None
    if not np.all(np.isfinite(W)):
        return None
    return Spectrum(lam.astype(complex), V, W, C @ V)


def _gap_matrix(lam: NDArray) -> NDArray[np.complex128]:
    """``E_jk = 1 / (lam_k - lam_j)`` off the diagonal, 0 on it."""
    D = lam[None, :] - lam[:, None]
    np.fill_diagonal(D, 1.0)
    E = 1.0 / D
    np.fill_diagonal(E, 0.0)
    return E


def log_kappa_bound(sp: Spectrum, order: int | None) -> tuple[float, NDArray[np.float64]]:
    """``phi_k(V)`` (``order = k``; None: exact ``log kappa2``) and its gradient with respect to ``X``.

    Returns
    -------
    value : float
    dX : (n, n) ndarray
        ``d value / dX`` (real), module docstring.
    """
    V, W, lam = sp.V, sp.W, sp.lam
    U, s, Vh = np.linalg.svd(V)
    ls = np.log(s)
    if order is None:
        value = float(ls[0] - ls[-1])
        c = np.zeros_like(s)
        c[0] += 1.0 / s[0]
        c[-1] -= 1.0 / s[-1]
    else:
        a = 2.0 * order * ls
        pa = np.exp(a - a.max())
        pb = np.exp(-a - (-a).max())
        value = float((a.max() + math.log(pa.sum()) + (-a).max() + math.log(pb.sum())) / (2.0 * order))
        c = (pa / pa.sum() - pb / pb.sum()) / s
    S = (U * c) @ Vh
    T = V.conj().T @ S
    G = V.conj().T @ V
    Tt = T - G * np.real(np.diag(T))[None, :]
    K = np.conj(_gap_matrix(lam)) * Tt
    Gx = W.conj().T @ K @ V.conj().T
    return value, np.real(Gx)


def _region_values(region: Region, re: NDArray, im: NDArray) -> tuple[NDArray, NDArray, NDArray]:
    """``g_k(re, im)`` (K, n) and their partial derivatives by the complex step (one evaluation of the
    region's expressions on the stacked points ``[z, z + i h d/dre, z + i h d/dim]``)."""
    n = re.size
    R = np.concatenate([re + 0j, re + 1j * _H, re + 0j])
    I = np.concatenate([im + 0j, im + 0j, im + 1j * _H])
    G = np.array([np.broadcast_to(v, R.shape) for v in region.constraints(R, I)])
    return G[:, :n].real, G[:, n : 2 * n].imag / _H, G[:, 2 * n :].imag / _H


def region_terms(sp: Spectrum, region: Region, mask_free: NDArray[np.intp]) -> tuple[NDArray, NDArray]:
    """Region constraint values of every pole, sorted per constraint, with gradients in the free gain entries.

    Parameters
    ----------
    sp : Spectrum
    region : Region
    mask_free : (f,) ndarray of int
        Column-major indices of the free entries of ``L``.

    Returns
    -------
    values : (K * n,) ndarray
        For each of the region's K constraints, its values at the n poles in descending order.
    jac : (K * n, f) ndarray
        Their derivatives with respect to the free entries of L.
    """
    lam = sp.lam
    re, im = lam.real, np.abs(lam.imag)
    sgn = np.where(lam.imag < 0, -1.0, 1.0)
    g, gr, gi = _region_values(region, re, im)
    # d lam_k / dL[a, c] = -W[k, a] (C V)[c, k]  ->  (n, n*p) column-major in (a, c)
    dlam = -(sp.W[:, :, None] * sp.CV.T[:, None, :])  # (k, a, c)
    dlam = dlam.transpose(0, 2, 1).reshape(lam.size, -1)[:, mask_free]  # column-major (a + n c)
    dre, dim = dlam.real, dlam.imag * sgn[:, None]
    order = np.argsort(-g, axis=1, kind="stable")  # per constraint, the poles in descending order
    rows = np.arange(g.shape[0])[:, None]
    vals = g[rows, order].ravel()
    J = gr[:, :, None] * dre[None] + gi[:, :, None] * dim[None]  # (K, n, f)
    jac = J[rows, order].reshape(vals.size, mask_free.size)
    return vals, jac


def h2_terms(
    A: NDArray, C: NDArray, L: NDArray, BwBw: NDArray, R: NDArray, discrete: bool
) -> tuple[float, NDArray[np.float64]]:
    """``trace(Sigma)`` (the squared H2 norm of the error channel) and its gradient in ``L``.

    Returns ``(inf, zeros)`` when ``A - L C`` is not strictly stable.
    """
    X = A - L @ C
    w = np.linalg.eigvals(X)
    if (np.max(np.abs(w)) >= 1.0) if discrete else (np.max(w.real) >= 0.0):
        return math.inf, np.zeros_like(L)
    BB = BwBw + L @ R @ L.T
    n = A.shape[0]
    if discrete:
        S = scipy.linalg.solve_discrete_lyapunov(X, BB)
        Lam = scipy.linalg.solve_discrete_lyapunov(X.T, np.eye(n))
        grad = 2.0 * (0.5 * (Lam + Lam.T)) @ (L @ R - X @ (0.5 * (S + S.T)) @ C.T)
    else:
        S = scipy.linalg.solve_continuous_lyapunov(X, -BB)
        Lam = scipy.linalg.solve_continuous_lyapunov(X.T, -np.eye(n))
        grad = 2.0 * (0.5 * (Lam + Lam.T)) @ (L @ R - (0.5 * (S + S.T)) @ C.T)
    return float(np.trace(S)), grad


def hinf_terms(
    A: NDArray, C: NDArray, L: NDArray, Bw: NDArray, Dv: NDArray, dt: float | None
) -> tuple[float, NDArray[np.float64]]:
    """H-infinity norm of the error channel and its gradient in ``L`` at the peak frequency.

    ``gamma = sigma_max(T(s*))`` with ``T(s) = (s I - X)^-1 [Bw, -L Dv]``; by the envelope theorem
    ``d gamma = Re(u^H dT v)`` at the peak ``s*`` (``T v = gamma u``), with
    ``dT = R dX R B + R dB``, ``R = (s* I - X)^-1``, ``dX = -dL C``, ``dB = [0, -dL Dv]``.  The
    function is nonsmooth where two peaks (or two singular values) tie.

    Returns ``(inf, zeros)`` when ``A - L C`` is not strictly stable.
    """
    X = A - L @ C
    B = np.hstack([Bw, -L @ Dv])
    h = hinf_norm(X, B, dt=dt)
    if not math.isfinite(h.value):
        return math.inf, np.zeros_like(L)
    if not math.isfinite(h.frequency):  # no feedthrough here, so only for a zero channel
        return float(h.value), np.zeros_like(L)
    n, m = A.shape[0], Bw.shape[1]
    s = np.exp(1j * h.frequency * dt) if dt is not None else 1j * h.frequency
    R = np.linalg.inv(s * np.eye(n) - X)
    T = R @ B
    U, sv, Vh = np.linalg.svd(T)
    u, v = U[:, 0], Vh[0].conj()
    v2 = v[m:]
    M = -(np.outer(C @ (T @ v), u.conj() @ R) + np.outer(Dv @ v2, u.conj() @ R))
    return float(sv[0]), np.real(M).T


def _smooth_norm2(L: NDArray, order: int) -> tuple[float, NDArray]:
    """``log sum sigma^{2k} / (2k)`` (an upper bound of log ||L||_2) and its gradient in L."""
    U, s, Vh = np.linalg.svd(L, full_matrices=False)
    if s[0] == 0.0:
        return -math.inf, np.zeros_like(L)
    a = 2.0 * order * np.log(np.maximum(s, 1e-300))
    pa = np.exp(a - a.max())
    value = float((a.max() + math.log(pa.sum())) / (2.0 * order))
    c = pa / pa.sum() / np.maximum(s, 1e-300)
    return value, (U * c) @ Vh


@dataclass(eq=False)
class RobustNLP:
    """Values and gradients of the robust NLP (module docstring) at a point ``x``.

    ``x = [free entries of L / gain_scale (column-major), t]`` (``t`` only with an epigraph).
    Evaluations are cached for the last ``x``.

    Attributes
    ----------
    models : ModelSet
    regions, soft_regions : tuple of (Region or None)
        Per model.
    objective, aggregate : str
    order : int or None
        Current kappa2 smoothing order (:meth:`set_order`).
    kappa2_max, h2_max, hinf_max, max_gain : float or None
    soft_weight : float
    soft_margin : float
        The soft penalty is on ``max(0, g + soft_margin)``: ``> 0`` pulls the poles that far inside
        (the feasibility phase of the verb uses it to land strictly inside the hard regions).
    mask : (n, p) ndarray of bool
    gain_scale : float
        ``L = gain_scale * x[:f]`` (x of order one).
    h2_ref : float
        Normalization of the H2 terms (their value at the reference gain).
    """

    models: ModelSet
    regions: tuple[Region | None, ...]
    soft_regions: tuple[Region | None, ...]
    objective: str
    aggregate: str
    mask: NDArray[np.bool_]
    gain_scale: float
    order: int | None = KAPPA2_ORDERS[0]
    kappa2_max: float | None = None
    h2_max: float | None = None
    max_gain: float | None = None
    soft_weight: float = 1.0
    soft_margin: float = 0.0
    h2_ref: float = 1.0
    hinf_max: float | None = None
    _cache: dict[str, Any] = field(default_factory=dict, repr=False)
    evaluations: int = 0

    # ------------------------------------------------------------------ layout
    @property
    def free(self) -> NDArray[np.intp]:
        return np.flatnonzero(self.mask.ravel(order="F"))

    @property
    def epigraph(self) -> bool:
        return self.objective in ("kappa2", "h2") and self.aggregate == "max"

    @property
    def n_x(self) -> int:
        return self.free.size + (1 if self.epigraph else 0)

    def gain(self, x: NDArray) -> NDArray[np.float64]:
        """The gain ``L`` (n, p) at ``x``."""
        n, p = self.models.n, self.models.p
        v = np.zeros(n * p)
        v[self.free] = self.gain_scale * np.asarray(x, dtype=float)[: self.free.size]
        return v.reshape((n, p), order="F")

    def point(self, L: NDArray, t: float | None = None) -> NDArray[np.float64]:
        """``x`` for the gain ``L`` (and epigraph value ``t``; default: the current max of the terms)."""
        xl = np.asarray(L, dtype=float).ravel(order="F")[self.free] / self.gain_scale
        if not self.epigraph:
            return xl
        if t is None:
            terms = self._model_terms(np.asarray(L, dtype=float))
            ok = not terms["bad"] and bool(np.all(np.isfinite(terms["c"])))
            t = float(np.max(terms["c"])) if ok else 0.0
        return np.concatenate([xl, [t]])

    def set_order(self, order: int | None) -> None:
        """Set the kappa2 smoothing order (clears the cached evaluation)."""
        self.order = order
        self._cache.pop("key", None)
        self._cache.pop("val", None)

    # ------------------------------------------------------------------ evaluation
    def _model_terms(self, L: NDArray) -> dict[str, Any]:
        """Per-model objective terms, constraint blocks and their gradients (in the free gain entries)."""
        N = len(self.models)
        free = self.free
        wants_kappa = self.objective == "kappa2" or self.kappa2_max is not None
        kv, kj = np.full(N, math.inf), np.zeros((N, free.size))
        reg_v: list[NDArray] = []
        reg_j: list[NDArray] = []
        soft, dsoft = 0.0, np.zeros(free.size)
        for i, pl in enumerate(self.models):
            reg, sreg = self.regions[i], self.soft_regions[i]
            if not (wants_kappa or reg is not None or sreg is not None):
                continue
            sp = spectrum(pl.A - L @ pl.C, pl.C)
            if sp is None:
                return {"bad": True}
            if wants_kappa:
                v, gX = log_kappa_bound(sp, self.order)
                kv[i], kj[i] = v, (-(gX @ pl.C.T)).ravel(order="F")[free]
            if reg is not None:
                rv, rj = region_terms(sp, reg, free)
                reg_v.append(rv)
                reg_j.append(rj)
            if sreg is not None:
                sv, sj = region_terms(sp, sreg, free)
                viol = np.maximum(sv + self.soft_margin, 0.0)
                soft += self.soft_weight * float(np.sum(viol**2))
                dsoft += self.soft_weight * 2.0 * (viol @ sj)
        out: dict[str, Any] = {
            "bad": False,
            "c": kv,
            "dc": kj,
            "reg_v": reg_v,
            "reg_j": reg_j,
            "soft": soft,
            "dsoft": dsoft,
        }
        if self.kappa2_max is not None:
            out["kv"], out["kj"] = kv, kj
        if self.objective == "h2" or self.h2_max is not None:
            Bws, Dvs = self._noise()
            h, dh = np.full(N, math.inf), np.zeros((N, free.size))
            for i, pl in enumerate(self.models):
                val, gL = h2_terms(pl.A, pl.C, L, Bws[i] @ Bws[i].T, Dvs[i] @ Dvs[i].T, pl.is_discrete)
                h[i], dh[i] = val, gL.ravel(order="F")[free]
            out["h"], out["dh"] = h, dh
            if self.objective == "h2":
                out["c"], out["dc"] = h / self.h2_ref, dh / self.h2_ref
        if self.hinf_max is not None:
            Bws, Dvs = self._noise()
            hv, hj = np.full(N, math.inf), np.zeros((N, free.size))
            for i, pl in enumerate(self.models):
                val, gL = hinf_terms(pl.A, pl.C, L, Bws[i], Dvs[i], pl.dt)
                hv[i], hj[i] = val, gL.ravel(order="F")[free]
            out["hi"], out["dhi"] = hv, hj
        return out

    def _finite(self, terms: dict[str, Any]) -> bool:
        """Every term the objective and the constraints use is finite (else: outside the domain)."""
        used = [terms["c"]] if self.objective != "gain" else []
        used += [terms[k] for k in ("h", "hi", "kv") if k in terms]
        return all(bool(np.all(np.isfinite(u))) for u in used)

    def _noise(self) -> tuple[NDArray, NDArray]:
        if "noise" not in self._cache:
            d = self.models.vertex_data()
            self._cache["noise"] = (d["Bw"], d["Dv"])
        return self._cache["noise"]

    def _evaluate(self, x: NDArray) -> dict[str, Any]:
        x = np.asarray(x, dtype=float).ravel()
        key = x.tobytes()
        if self._cache.get("key") == key:
            return self._cache["val"]
        self.evaluations += 1
        L = self.gain(x)
        terms = self._model_terms(L)
        f_ = self.free.size
        nx = self.n_x
        if terms["bad"] or not self._finite(terms):
            val = {
                "f": math.inf,
                "df": np.zeros(nx),
                "g": np.full(self.n_g, math.inf),
                "dg": np.zeros((self.n_g, nx)),
                "L": L,
                "terms": terms,
            }
            self._cache.update(key=key, val=val)
            return val
        s = self.gain_scale
        df = np.zeros(nx)
        # objective
        if self.objective == "gain":
            f = float(np.sum(x[:f_] ** 2))
            df[:f_] = 2.0 * x[:f_]
        elif self.epigraph:
            f = float(x[-1])
            df[-1] = 1.0
        else:
            w = self.models.weights
            if self.objective == "kappa2":
                k = np.exp(terms["c"])
                f = float(w @ k)
                df[:f_] = s * ((w * k) @ terms["dc"])
            else:
                f = float(w @ terms["c"])
                df[:f_] = s * (w @ terms["dc"])
        f += terms["soft"]
        df[:f_] += s * terms["dsoft"]
        # constraints (all of the form g <= ubg)
        gs: list[NDArray] = []
        js: list[NDArray] = []
        if self.epigraph:
            gs.append(terms["c"] - x[-1])
            J = np.zeros((len(self.models), nx))
            J[:, :f_] = s * terms["dc"]
            J[:, -1] = -1.0
            js.append(J)
        for rv, rj in zip(terms["reg_v"], terms["reg_j"], strict=True):
            gs.append(rv)
            js.append(np.hstack([s * rj, np.zeros((rv.size, nx - f_))]))
        if self.kappa2_max is not None:
            gs.append(terms["kv"] - math.log(self.kappa2_max))
            js.append(np.hstack([s * terms["kj"], np.zeros((len(self.models), nx - f_))]))
        if self.h2_max is not None:
            gs.append(terms["h"] / self.h2_max**2 - 1.0)
            js.append(np.hstack([s * terms["dh"] / self.h2_max**2, np.zeros((len(self.models), nx - f_))]))
        if self.hinf_max is not None:
            gs.append(terms["hi"] / self.hinf_max - 1.0)
            js.append(np.hstack([s * terms["dhi"] / self.hinf_max, np.zeros((len(self.models), nx - f_))]))
        if self.max_gain is not None:
            v, gL = _smooth_norm2(L, GAIN_ORDER)
            gs.append(np.array([v - math.log(self.max_gain)]))
            js.append(np.hstack([s * gL.ravel(order="F")[self.free][None, :], np.zeros((1, nx - f_))]))
        g = np.concatenate(gs) if gs else np.zeros(0)
        dg = np.vstack(js) if js else np.zeros((0, nx))
        val = {"f": f, "df": df, "g": g, "dg": dg, "L": L, "terms": terms}
        self._cache.update(key=key, val=val)
        return val

    @property
    def n_g(self) -> int:
        N = len(self.models)
        n = self.models.n
        k = N if self.epigraph else 0
        k += sum(n * r.n_constraints for r in self.regions if r is not None)
        k += N if self.kappa2_max is not None else 0
        k += N if self.h2_max is not None else 0
        k += N if self.hinf_max is not None else 0
        k += 1 if self.max_gain is not None else 0
        return k

    def constraint_margins(self) -> NDArray[np.float64]:
        """How far inside each constraint is imposed (``g <= -margin``), so that the answer passes an
        independent check beyond rounding: for the region rows the LMIs' default strictness
        (:func:`~optdesign.formulate.robust_lmi.default_margin`, so that a common Lyapunov certificate
        can exist for the result), relative ``1e-9`` for the normalized bounds, 0 for the epigraph rows."""
        N, n = len(self.models), self.models.n
        eps = default_margin(self.models)
        parts = [np.zeros(N if self.epigraph else 0)]
        parts += [np.full(n * r.n_constraints, eps) for r in self.regions if r is not None]
        k = sum(N for b in (self.kappa2_max, self.h2_max, self.hinf_max) if b is not None)
        parts.append(np.full(k + (1 if self.max_gain is not None else 0), 1e-9))
        return np.concatenate(parts)

    def exact_objective(self, L: NDArray) -> float:
        """The objective at the gain ``L`` with the exact (unsmoothed) kappa2: what ranks candidates."""
        order = self.order
        self.order = None
        try:
            terms = self._model_terms(np.asarray(L, dtype=float))
        finally:
            self.order = order
        if terms["bad"] or not self._finite(terms):
            return math.inf
        w = self.models.weights
        if self.objective == "gain":
            f = float(np.sum((np.asarray(L) / self.gain_scale) ** 2))
        elif self.aggregate == "max":
            f = float(np.max(terms["c"]))
        elif self.objective == "kappa2":
            f = float(w @ np.exp(terms["c"]))
        else:
            f = float(w @ terms["c"])
        return f + terms["soft"]

    def f(self, x: NDArray) -> float:
        return self._evaluate(x)["f"]

    def grad(self, x: NDArray) -> NDArray[np.float64]:
        return self._evaluate(x)["df"]

    def g(self, x: NDArray) -> NDArray[np.float64]:
        """Constraint values; feasible iff all ``<= 0``."""
        return self._evaluate(x)["g"]

    def jac(self, x: NDArray) -> NDArray[np.float64]:
        return self._evaluate(x)["dg"]

    # ------------------------------------------------------------------ CasADi
    def nlpsol_problem(self) -> tuple[dict[str, Any], dict[str, Any], list[Any]]:
        """``(problem, plugin options, keep-alive list)`` for :func:`solve_nlpsol`: f and g with
        their gradient / Jacobian as numpy callbacks, a limited-memory Hessian."""
        ca = import_casadi()
        nx, ng = self.n_x, self.n_g
        nlp = self

        class _Fun(ca.Callback):  # type: ignore[name-defined]  # ca: the module import_casadi returns
            def __init__(self, name: str, kind: str):
                ca.Callback.__init__(self)
                self.kind = kind
                self.construct(name, {})

            def get_n_in(self):
                return 2 if self.kind.startswith("jac") else 1

            def get_n_out(self):
                return 1

            def get_sparsity_in(self, i):
                return (
                    ca.Sparsity.dense(nx, 1)
                    if i == 0
                    else ca.Sparsity.dense(1 if self.kind == "jac_f" else ng, 1)
                )

            def get_sparsity_out(self, i):
                return {
                    "f": ca.Sparsity.dense(1, 1),
                    "g": ca.Sparsity.dense(ng, 1),
                    "jac_f": ca.Sparsity.dense(1, nx),
                    "jac_g": ca.Sparsity.dense(ng, nx),
                }[self.kind]

            def eval(self, arg):
                x = np.asarray(arg[0], dtype=float).ravel()
                val = nlp._evaluate(x)
                if self.kind == "f":
                    return [ca.DM(min(val["f"], 1e20))]
                if self.kind == "g":
                    return [ca.DM(np.minimum(val["g"], 1e20))]
                if self.kind == "jac_f":
                    return [ca.DM(val["df"][None, :])]
                return [ca.DM(val["dg"])]

            def has_jacobian(self):
                return self.kind in ("f", "g")

            def get_jacobian(self, name, inames, onames, opts):
                cb = _Fun(name, "jac_" + self.kind)
                keep.append(cb)
                x = ca.MX.sym("x", nx)
                o = ca.MX.sym("o", 1 if self.kind == "f" else ng)
                return ca.Function(name, [x, o], [cb(x, o)], inames, onames, opts)

        keep: list[Any] = []
        fcb, gcb = _Fun("robust_f", "f"), _Fun("robust_g", "g")
        keep += [fcb, gcb]
        x = ca.MX.sym("x", nx)
        problem = {"x": x, "f": fcb(x), "g": gcb(x)}
        plugin = {"ipopt.hessian_approximation": "limited-memory"}
        return problem, plugin, keep


def build_robust_nlp(
    models: ModelSet,
    *,
    regions: Sequence[Region | None],
    soft_regions: Sequence[Region | None],
    objective: str = "kappa2",
    aggregate: str = "max",
    gain_mask: NDArray | None = None,
    kappa2_max: float | None = None,
    h2_max: float | None = None,
    hinf_max: float | None = None,
    max_gain: float | None = None,
    soft_weight: float = 1.0,
    gain_scale: float = 1.0,
    h2_ref: float = 1.0,
) -> RobustNLP:
    """The robust NLP (module docstring) for ``models``.

    Parameters
    ----------
    models : ModelSet
    regions, soft_regions : sequence of Region or None
        Hard and soft pole regions, one per model.
    objective : {"kappa2", "h2", "gain"}
    aggregate : {"max", "mean"}
    gain_mask : (n, p) ndarray of bool, optional
    kappa2_max, h2_max, hinf_max, max_gain : float, optional
        Bounds on every model's kappa2, H2 and H-infinity norms, and on ``||L||_2``.
    soft_weight : float
    gain_scale : float
        Typical size of the gain entries (the variables are ``L / gain_scale``).
    h2_ref : float
        Normalization of the H2 objective terms.

    Returns
    -------
    RobustNLP

    Raises
    ------
    ValidationError
        Unknown objective or aggregate; H2 without noise models; regions of the wrong length.
    """
    if objective not in NLP_OBJECTIVES:
        raise ValidationError(f"objective must be one of {NLP_OBJECTIVES}; found {objective!r}")
    if aggregate not in AGGREGATES:
        raise ValidationError(f"aggregate must be one of {AGGREGATES}; found {aggregate!r}")
    regions, soft_regions = tuple(regions), tuple(soft_regions)
    if len(regions) != len(models) or len(soft_regions) != len(models):
        raise ValidationError("regions and soft_regions must give one entry (or None) per model")
    if (objective == "h2" or h2_max is not None or hinf_max is not None) and not models.has_noise_model:
        raise ValidationError(
            "the H2 objective, h2_max and hinf_max need a noise model (Q and R) in every model"
        )
    mask = (
        np.ones((models.n, models.p), dtype=bool) if gain_mask is None else np.asarray(gain_mask, dtype=bool)
    )
    return RobustNLP(
        models,
        regions,
        soft_regions,
        objective,
        aggregate,
        mask,
        float(gain_scale),
        kappa2_max=kappa2_max,
        h2_max=h2_max,
        max_gain=max_gain,
        soft_weight=float(soft_weight),
        h2_ref=float(h2_ref),
        hinf_max=hinf_max,
    )
