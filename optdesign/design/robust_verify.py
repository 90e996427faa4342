r"""Independent checks of a robust observer gain over a set of models (numpy / scipy only).

Three kinds of evidence, each recomputed from the numbers the design returns, never taken from a
solver:

* **per model** (:func:`evaluate_models`, :func:`gain_checks`): the poles of ``A_i - L C_i``, strict
  stability, region membership, kappa2 / eta (:mod:`optdesign.analysis.metrics`), H2 by a Lyapunov
  solve and H-infinity by the Hamiltonian level-set iteration (:mod:`optdesign.analysis.norms`),
  the structural zeros and the bounds;
* **the LMI certificate** (:func:`certify`): given a Lyapunov matrix ``P`` and the gain, the
  Chilali-Gahinet region inequalities, the H2 Gramian bound and the bounded-real inequality are
  evaluated in numpy at every model, and what they *prove* is computed -- the smallest region
  shrink ``eps`` (generalized eigenvalues of ``(M_i, I (x) P)``), the H2 bound
  ``max_i trace(B_i' P B_i) / min_i mu_i`` and the smallest H-infinity level ``gamma`` for which the
  bounded-real inequality holds at every model with one scaling (a 1-D search).  All three are
  affine (or convex) in the vertex data, so for a polytope they hold for every convex
  combination;
* **dense** (:func:`dense_check`): poles and metrics at random interior points of the set
  (:meth:`ModelSet.interior_points`);
* **infeasibility** (:func:`farkas_check`): the dual matrices of an infeasible LMI problem are a
  Farkas certificate when ``sum_j <Z_j, F_j(v)>`` is a negative constant for every ``v``; its
  linear part is rebuilt by evaluating the constraints in numpy at unit vectors, and the residual
  gives the radius within which no solution can exist.

Tolerance rules (from the data, never a bare constant):

=======================  ======================================================================
check                    tolerance
=======================  ======================================================================
``region_margin``        the eigenvalue rounding floor of ``A_i - L C_i``
                         (:func:`~optdesign.analysis.metrics.eigenvalue_rounding_floor`, relative)
                         times ``max(1, |lambda|)``
``stability``            the same floor (strictly inside by more than rounding)
``gain_bound``           relative ``100 eps sqrt(n p)`` (a norm computed by an SVD)
``kappa2_bound``         relative: the agreement of two eigenbases, ``1e-6 + 1e3 eps kappa2``
``h2_bound``             relative ``100 eps ||X||_2 ||Lam||_2`` (capped at 1e-3), ``Lam`` the
                         observability Gramian of ``X = A - L C``: a conditioning estimate of the
                         Lyapunov operator
``hinf_bound``           relative: the level-set accuracy ``1e-9``
LMI inequalities         ``10 d eps ||M||_F / lambda_min(P)`` (``d`` the size of ``M``)
=======================  ======================================================================
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.linalg
from numpy.typing import NDArray

from ..analysis import metrics
from ..analysis.norms import error_channel, estimation_error_h2, estimation_error_hinf
from ..formulate.robust_lmi import RobustLMI, lmi_blocks, region_lmi
from ..model.model_set import ModelSet
from ..model.regions import Region
from ..results import Check, Verification

__all__ = [
    "ModelMetrics",
    "evaluate_models",
    "gain_checks",
    "LMICertificate",
    "certify",
    "certificate_checks",
    "DenseCheck",
    "dense_check",
    "farkas_check",
    "kappa2_tolerance",
]

_EPS = float(np.finfo(float).eps)


def kappa2_tolerance(kappa2: float) -> float:
    """Relative agreement of two unit-column eigenbases' condition numbers: ``1e-6 + 1e3 eps kappa2``."""
    return 1e-6 + 1e3 * _EPS * float(kappa2)


@dataclass(frozen=True)
class ModelMetrics:
    """What one gain does on every model (arrays indexed by model).

    Attributes
    ----------
    poles : tuple of (n,) complex ndarray
        ``eig(A_i - L C_i)``, sorted by real then imaginary part.
    kappa2, eta : (N,) ndarray
        :func:`optdesign.analysis.metrics.kappa2` / ``eta`` (inf when defective).
    h2, hinf : (N,) ndarray
        H2 and H-infinity norms of the estimation-error channel (nan without a noise model,
        inf when unstable).
    hinf_frequency : (N,) ndarray
    margin : (N,) ndarray
        Signed distance of the worst pole to the model's hard region (``<= 0`` inside; nan when
        the model has no region).
    stability : (N,) ndarray
        Max real part (continuous) or spectral radius (discrete).
    floor : (N,) ndarray
        Absolute eigenvalue rounding floor of each model (``eigenvalue_rounding_floor * max(1, |lambda|)``).
    """

    poles: tuple[NDArray[np.complex128], ...]
    kappa2: NDArray[np.float64]
    eta: NDArray[np.float64]
    h2: NDArray[np.float64]
    hinf: NDArray[np.float64]
    hinf_frequency: NDArray[np.float64]
    margin: NDArray[np.float64]
    stability: NDArray[np.float64]
    floor: NDArray[np.float64]

    def worst(self, name: str) -> float:
        """The largest value of a per-model array (nan-aware)."""
        v = np.asarray(getattr(self, name), dtype=float)
        return float(np.nanmax(v)) if np.any(~np.isnan(v)) else math.nan


def _sort(p: NDArray) -> NDArray[np.complex128]:
    return np.asarray(sorted(np.asarray(p, dtype=complex), key=lambda z: (z.real, z.imag)), dtype=complex)


def evaluate_models(
    models: ModelSet, L: NDArray, regions: Sequence[Region | None], *, norms: bool = True
) -> ModelMetrics:
    """Poles, conditioning, norms and region margins of the gain ``L`` on every model.

    Parameters
    ----------
    models : ModelSet
    L : (n, p) ndarray
    regions : sequence of Region or None
        The hard region of each model.
    norms : bool, default True
        Compute H2 and H-infinity (when the models have noise models).
    """
    N = len(models)
    poles = []
    out = {
        k: np.full(N, np.nan)
        for k in ("kappa2", "eta", "h2", "hinf", "hinf_frequency", "margin", "stability", "floor")
    }
    for i, pl in enumerate(models):
        X = pl.A - L @ pl.C
        lam = _sort(np.linalg.eigvals(X))
        poles.append(lam)
        s = metrics.condition_summary(X)
        out["kappa2"][i], out["eta"][i] = float(s["kappa2"]), float(s["eta"])
        out["stability"][i] = float(np.max(np.abs(lam))) if pl.is_discrete else float(np.max(lam.real))
        fl = metrics.eigenvalue_rounding_floor(X)
        out["floor"][i] = fl * max(1.0, float(np.max(np.abs(lam))))
        reg = regions[i]
        if reg is not None:
            out["margin"][i] = reg.margin(lam)
        if norms and pl.has_noise_model:
            out["h2"][i] = estimation_error_h2(pl, L)
            h = estimation_error_hinf(pl, L)
            out["hinf"][i], out["hinf_frequency"][i] = h.value, h.frequency
    return ModelMetrics(tuple(poles), **out)


def _worst(values: NDArray) -> tuple[float, int]:
    v = np.where(np.isnan(values), -np.inf, values)
    k = int(np.argmax(v))
    return float(values[k]), k


def gain_checks(
    models: ModelSet,
    L: NDArray,
    mm: ModelMetrics,
    regions: Sequence[Region | None],
    *,
    mask: NDArray[np.bool_] | None = None,
    max_gain: float | None = None,
    kappa2_max: float | None = None,
    h2_max: float | None = None,
    hinf_max: float | None = None,
) -> Verification:
    """The per-model checks of a gain (worst model named in each check's detail).

    Returns
    -------
    Verification
        ``finite_gain`` or: ``stability``, ``region_margin`` (if any hard region), ``mask``,
        ``gain_bound``, ``kappa2_bound``, ``h2_bound``, ``hinf_bound`` when relevant.
    """
    if not np.all(np.isfinite(L)):
        return Verification.of([Check.at_most("finite_gain", math.inf, 0.0, "the gain has NaN/Inf entries")])
    checks = []
    disc = models.is_discrete
    # stability: strictly inside by more than the rounding floor
    slack = mm.stability - (1.0 if disc else 0.0) + mm.floor
    val, k = _worst(slack)
    checks.append(
        Check.at_most(
            "stability",
            val,
            0.0,
            f"{'spectral radius - 1' if disc else 'max Re'} of A_i - L C_i plus the rounding "
            f"floor (< 0: strictly stable); worst {models.label(k)}",
        )
    )
    if any(r is not None for r in regions):
        val, k = _worst(mm.margin - mm.floor)
        checks.append(
            Check.at_most(
                "region_margin",
                val,
                0.0,
                f"signed distance of the worst pole to its region minus the rounding floor "
                f"(<= 0: inside); worst {models.label(k)}",
            )
        )
    if mask is not None and not np.all(mask):
        off = float(np.max(np.abs(L[~mask])))
        checks.append(Check.at_most("mask", off, 0.0, "largest |L| entry outside gain_mask"))
    gn = float(np.linalg.norm(L, 2))
    if max_gain is not None:
        tol = 100.0 * _EPS * math.sqrt(L.size)
        checks.append(Check.at_most("gain_bound", gn, max_gain * (1.0 + tol), "||L||_2 <= max_gain"))
    if kappa2_max is not None:
        val, k = _worst(mm.kappa2)
        checks.append(
            Check.at_most(
                "kappa2_bound",
                val,
                kappa2_max * (1.0 + kappa2_tolerance(val)),
                f"kappa2 <= kappa2_max on every model; worst {models.label(k)}",
            )
        )
    if h2_max is not None:
        val, k = _worst(mm.h2)
        tol = _h2_tolerance(models[k], L)
        checks.append(
            Check.at_most(
                "h2_bound",
                val,
                h2_max * (1.0 + tol),
                f"H2 of the estimation error <= h2_max on every model; worst {models.label(k)}",
            )
        )
    if hinf_max is not None:
        val, k = _worst(mm.hinf)
        checks.append(
            Check.at_most(
                "hinf_bound",
                val,
                hinf_max * (1.0 + 1e-9),
                f"H-infinity of the estimation error <= hinf_max; worst {models.label(k)}",
            )
        )
    return Verification.of(checks)


def _h2_tolerance(plant, L: NDArray) -> float:
    """Relative accuracy of an H2 norm from two Lyapunov solves: ``100 eps ||Sigma|| ||Lam||``-based."""
    X, B = error_channel(plant, L)
    try:
        if plant.is_discrete:
            Lam = scipy.linalg.solve_discrete_lyapunov(X.T, np.eye(X.shape[0]))
        else:
            Lam = scipy.linalg.solve_continuous_lyapunov(X.T, -np.eye(X.shape[0]))
    except (np.linalg.LinAlgError, ValueError):
        return 1e-6
    cond = max(1.0, float(np.linalg.norm(Lam, 2)) * float(np.linalg.norm(X, 2)))
    return float(min(1e-3, 100.0 * _EPS * cond))


# --------------------------------------------------------------------------- the LMI certificate


@dataclass(frozen=True)
class LMICertificate:
    """What a Lyapunov matrix ``P`` proves about a gain ``L`` on a model set (numpy-evaluated).

    Attributes
    ----------
    P : (n, n) ndarray
    P_min_eig, P_cond : float
    shrink : (N,) ndarray
        Per model (with a region): the largest ``eps`` with ``M_i(P, L) <= -eps (I (x) P)``, i.e. the
        poles lie in ``{s : f_D(s) <= -eps I}`` (nan without a region).  Positive: strictly inside.
    tolerance : (N,) ndarray
        The rounding level of each ``shrink`` (it must exceed it).
    h2_bound : float
        Certified H2 bound over the set (nan if not asked or not provable with this P).
    hinf_bound : float
        Certified H-infinity bound (nan if not asked or not provable).
    covers : str
        ``"convex hull"`` (polytope: every convex combination of the models) or ``"models"``.
    holds : bool
        ``P > 0`` and every region inequality strictly negative beyond rounding.
    """

    P: NDArray[np.float64]
    P_min_eig: float
    P_cond: float
    shrink: NDArray[np.float64]
    tolerance: NDArray[np.float64]
    h2_bound: float
    hinf_bound: float
    covers: str
    holds: bool

    def as_dict(self) -> dict[str, Any]:
        return {
            "P": self.P.tolist(),
            "P_min_eig": self.P_min_eig,
            "P_cond": self.P_cond,
            "shrink": self.shrink.tolist(),
            "h2_bound": self.h2_bound,
            "hinf_bound": self.hinf_bound,
            "covers": self.covers,
            "holds": self.holds,
        }


def _gen_max_eig(M: NDArray, B: NDArray) -> float:
    """Largest generalized eigenvalue of the symmetric pencil ``(M, B)``, ``B > 0``."""
    return float(scipy.linalg.eigh(0.5 * (M + M.T), 0.5 * (B + B.T), eigvals_only=True)[-1])


def _h2_bound(data: dict, P: NDArray, L: NDArray, discrete: bool) -> float:
    mus, tr = [], []
    for A, C, Bw, Dv in zip(data["A"], data["C"], data["Bw"], data["Dv"], strict=True):
        X = A - L @ C
        M = P - X.T @ P @ X if discrete else -(X.T @ P + P @ X)
        mus.append(float(np.linalg.eigvalsh(0.5 * (M + M.T))[0]))
        B = np.hstack([Bw, -L @ Dv])
        tr.append(float(np.trace(B.T @ P @ B)))
    mu = min(mus)
    return math.sqrt(max(tr) / mu) if mu > 0 else math.nan


def _hinf_level(data: dict, P: NDArray, L: NDArray, discrete: bool, c: float) -> float:
    """The smallest gamma with the bounded-real inequality at every model for the scaling ``c``."""
    g2 = 0.0
    for A, C, Bw, Dv in zip(data["A"], data["C"], data["Bw"], data["Dv"], strict=True):
        X = A - L @ C
        B = np.hstack([Bw, -L @ Dv])
        if discrete:
            S = P - c * np.eye(P.shape[0]) - X.T @ P @ X
        else:
            S = -(X.T @ P + P @ X) - c * np.eye(P.shape[0])
        S = 0.5 * (S + S.T)
        try:
            F = np.linalg.cholesky(S)
        except np.linalg.LinAlgError:
            return math.inf
        if discrete:
            Gm = B.T @ P @ X
            K = B.T @ P @ B + Gm @ np.linalg.solve(S, Gm.T)
        else:
            Z = scipy.linalg.solve_triangular(F, P @ B, lower=True)
            K = Z.T @ Z
        g2 = max(g2, float(np.linalg.eigvalsh(0.5 * (K + K.T))[-1]) / c)
    return math.sqrt(g2)


def _hinf_bound(data: dict, P: NDArray, L: NDArray, discrete: bool) -> float:
    mus = []
    for A, C in zip(data["A"], data["C"], strict=True):
        X = A - L @ C
        M = P - X.T @ P @ X if discrete else -(X.T @ P + P @ X)
        mus.append(float(np.linalg.eigvalsh(0.5 * (M + M.T))[0]))
    mu = min(mus)
    if not mu > 0:
        return math.nan
    lo, hi = math.log(mu) - 30.0, math.log(mu)  # c in (0, mu): golden section on log c
    f = lambda lc: _hinf_level(data, P, L, discrete, math.exp(lc))  # noqa: E731
    gr = (math.sqrt(5.0) - 1.0) / 2.0
    a, b = lo, hi - 1e-9
    x1, x2 = b - gr * (b - a), a + gr * (b - a)
    f1, f2 = f(x1), f(x2)
    for _ in range(80):
        if f1 <= f2:
            b, x2, f2 = x2, x1, f1
            x1 = b - gr * (b - a)
            f1 = f(x1)
        else:
            a, x1, f1 = x1, x2, f2
            x2 = a + gr * (b - a)
            f2 = f(x2)
    best = min(f1, f2)
    return best if math.isfinite(best) else math.nan


def certify(
    models: ModelSet,
    L: NDArray,
    P: NDArray,
    regions: Sequence[Region | None],
    *,
    h2: bool = False,
    hinf: bool = False,
) -> LMICertificate:
    """Evaluate the LMI certificate ``P`` for the gain ``L`` in numpy (module docstring).

    Parameters
    ----------
    models : ModelSet
    L : (n, p) ndarray
    P : (n, n) ndarray
        A candidate common Lyapunov matrix (symmetrized here).
    regions : sequence of Region or None
    h2, hinf : bool
        Also compute the certified H2 / H-infinity bounds (need noise models).
    """
    P = 0.5 * (np.asarray(P, dtype=float) + np.asarray(P, dtype=float).T)
    w = np.linalg.eigvalsh(P)
    pmin = float(w[0])
    N = len(models)
    shrink = np.full(N, np.nan)
    tol = np.full(N, np.nan)
    ok = pmin > 10.0 * P.shape[0] * _EPS * float(w[-1])
    if ok:
        for i, pl in enumerate(models):
            reg = regions[i]
            if reg is None:
                continue
            Z = P @ (pl.A - L @ pl.C)
            M = region_lmi(reg, P, Z, 0.0)
            q = M.shape[0] // P.shape[0]
            shrink[i] = -_gen_max_eig(M, np.kron(np.eye(q), P))
            tol[i] = 10.0 * M.shape[0] * _EPS * float(np.linalg.norm(M)) / pmin
    holds = bool(ok and np.all(np.isnan(shrink) | (shrink > tol)))
    data = models.vertex_data()
    h2b = _h2_bound(data, P, L, models.is_discrete) if (h2 and ok and models.has_noise_model) else math.nan
    hib = (
        _hinf_bound(data, P, L, models.is_discrete) if (hinf and ok and models.has_noise_model) else math.nan
    )
    return LMICertificate(
        P,
        pmin,
        float(w[-1] / pmin) if pmin > 0 else math.inf,
        shrink,
        tol,
        h2b,
        hib,
        "convex hull" if models.covers_convex_hull else "models",
        holds,
    )


def certificate_checks(
    cert: LMICertificate, *, h2_claim: float | None = None, hinf_claim: float | None = None
) -> Verification:
    """Checks that the certificate proves what is claimed (region; H2 / H-infinity bounds)."""
    checks = [Check.at_least("lmi_P_min_eig", cert.P_min_eig, 0.0, "common Lyapunov matrix P > 0")]
    has = ~np.isnan(cert.shrink)
    if np.any(has):
        margin = cert.shrink[has] - cert.tolerance[has]
        checks.append(
            Check.at_least(
                "lmi_region",
                float(np.min(margin)),
                0.0,
                "min over models of the certified region shrink eps minus its rounding level "
                "(> 0: every pole of every covered model strictly inside)",
            )
        )
    if h2_claim is not None:
        checks.append(
            Check.at_most(
                "lmi_h2_bound",
                cert.h2_bound if math.isfinite(cert.h2_bound) else math.inf,
                h2_claim * (1.0 + 1e-6),
                "H2 bound proven by P (numpy) <= the claimed bound",
            )
        )
    if hinf_claim is not None:
        val = cert.hinf_bound if math.isfinite(cert.hinf_bound) else math.inf
        checks.append(
            Check.at_most(
                "lmi_hinf_bound",
                val,
                hinf_claim * (1.0 + 1e-6),
                "H-infinity bound proven by P (numpy) <= the claimed bound",
            )
        )
    return Verification.of(checks)


# --------------------------------------------------------------------------- dense check


@dataclass(frozen=True)
class DenseCheck:
    """The gain on random plants of the set that are not among its models.

    Attributes
    ----------
    count : int
        Plants drawn (0 for a list of operating points: nothing lies between them).
    in_region : int
        How many have every pole in their region (the region of the nominal model, or of model 0).
    stable : int
    worst_margin, worst_kappa2, worst_h2 : float
    """

    count: int
    in_region: int
    stable: int
    worst_margin: float
    worst_kappa2: float
    worst_h2: float

    @property
    def fraction(self) -> float:
        """Share of the drawn plants with all poles in the region (nan when none was drawn)."""
        return self.in_region / self.count if self.count else math.nan


def dense_check(models: ModelSet, L: NDArray, region: Region | None, count: int, seed: int = 0) -> DenseCheck:
    """Poles, kappa2 and H2 of ``L`` at ``count`` random interior plants of the set
    (:meth:`ModelSet.interior_points`)."""
    plants = models.interior_points(count, seed)
    inside = stable = 0
    wm = wk = wh = -math.inf
    for pl in plants:
        X = pl.A - L @ pl.C
        lam = np.linalg.eigvals(X)
        fl = metrics.eigenvalue_rounding_floor(X) * max(1.0, float(np.max(np.abs(lam))))
        st = bool(np.max(np.abs(lam)) < 1.0) if pl.is_discrete else bool(np.max(lam.real) < 0.0)
        stable += st
        m = region.margin(lam) if region is not None else -math.inf
        inside += bool(m - fl <= 0.0) and st
        wm = max(wm, m)
        wk = max(wk, metrics.kappa2(X))
        if pl.has_noise_model:
            wh = max(wh, estimation_error_h2(pl, L))
    nan = math.nan
    return DenseCheck(
        len(plants),
        inside,
        stable,
        wm if plants else nan,
        wk if plants else nan,
        wh if wh > -math.inf else nan,
    )


# --------------------------------------------------------------------------- infeasibility


def _psd_part(Z: NDArray) -> NDArray[np.float64]:
    Z = 0.5 * (Z + Z.T)
    w, U = np.linalg.eigh(Z)
    return (U * np.clip(w, 0.0, None)) @ U.T


def farkas_check(lmi: RobustLMI, models: ModelSet, *, refinements: int = 3) -> dict[str, Any]:
    """Verify the dual (Farkas) certificate of an infeasible :class:`RobustLMI` in numpy.

    The constraints are ``F_j(v) >= 0``, affine in the variables ``v``.  For PSD multipliers
    ``Z_j``, ``ell(v) = sum_j <Z_j, F_j(v)> = c0 + r' v``; every feasible ``v`` has ``ell(v) >= 0``,
    so ``c0 < 0`` proves that no feasible point has ``||v||_2 < -c0 / ||r||_2`` (and none at all
    when ``r = 0``).  The affine maps are rebuilt by evaluating every constraint in numpy
    (:func:`~optdesign.formulate.robust_lmi.lmi_blocks`) at ``v = 0`` and at unit vectors; the
    solver's duals are projected onto the PSD cone, then ``refinements`` times corrected toward
    ``r = 0`` (least-norm correction, re-projected), which shrinks the residual to rounding.

    Returns
    -------
    dict
        ``"verified"`` (``c0 < 0`` and the radius exceeds ``1e8`` times the scale of the data --
        the size a solution would need is then beyond what double precision can represent in
        these LMIs), ``"c0"``, ``"residual"`` (``||r||``), ``"radius"``, ``"scale"``.
    """
    cons = [c for grp in ("region", "h2", "hinf", "norm", "gain") for c in lmi.constraints.get(grp, [])]
    duals = []
    for c in cons:
        d = c.dual_value
        if d is None:
            return {"verified": False, "reason": "the solver returned no dual certificate"}
        duals.append(np.asarray(d, dtype=float))
    variables = lmi.problem.variables()
    data = models.vertex_data()
    saved = [v.value for v in variables]

    def blocks_at(values: list[NDArray]) -> NDArray[np.float64]:
        for v, val in zip(variables, values, strict=True):
            v.value = val
        vals: dict[str, Any] = {}
        for k, e in lmi.variables.items():
            vals[k] = (
                [np.asarray(w.value, dtype=float) for w in e]
                if k == "W"
                else np.asarray(e.value, dtype=float)
            )
        bl = lmi_blocks(lmi.spec, data, vals)
        return np.concatenate(
            [
                np.ravel(np.asarray(F, dtype=float))
                for grp in ("region", "h2", "hinf", "norm", "gain")
                for F in bl.get(grp, [])
            ]
        )

    def basis(v) -> list[NDArray]:
        shape = v.shape
        if len(shape) == 2 and v.attributes.get("symmetric"):
            out = []
            for a in range(shape[0]):
                for b in range(a, shape[1]):
                    E = np.zeros(shape)
                    E[a, b] = E[b, a] = 1.0
                    out.append(E)
            return out
        size = int(np.prod(shape)) if shape else 1
        return [np.eye(size)[k].reshape(shape) if shape else np.array(1.0) for k in range(size)]

    zero = [np.zeros(v.shape) if v.shape else np.array(0.0) for v in variables]
    try:
        f0 = blocks_at(zero)
        cols = []
        for j, v in enumerate(variables):
            for E in basis(v):
                vals = list(zero)
                vals[j] = E
                cols.append(blocks_at(vals) - f0)
    finally:
        for v, val in zip(variables, saved, strict=True):
            v.value = val
    Amat = np.array(cols)  # (n_vars, dual entries): r = Amat @ z
    shapes = [np.shape(d) for d in duals]
    sizes = [int(np.prod(sh)) if sh else 1 for sh in shapes]

    def project(z: NDArray) -> NDArray:
        out, k = [], 0
        for sh, sz in zip(shapes, sizes, strict=True):
            part = z[k : k + sz]
            out.append(_psd_part(part.reshape(sh)).ravel() if len(sh) == 2 else np.maximum(part, 0.0))
            k += sz
        return np.concatenate(out)

    z = project(np.concatenate([np.ravel(d) for d in duals]))
    pinv = np.linalg.pinv(Amat @ Amat.T) if Amat.size else np.zeros((0, 0))
    for _ in range(refinements):
        r = Amat @ z
        z = project(z - Amat.T @ (pinv @ r))
    r = Amat @ z
    c0 = float(f0 @ z)
    rn = float(np.linalg.norm(r))
    scale = max(1.0, max(float(np.linalg.norm(A, 2)) for A in data["A"]))
    radius = math.inf if rn == 0.0 else (-c0 / rn if c0 < 0 else 0.0)
    return {
        "verified": bool(c0 < 0 and radius > 1e8 * scale),
        "c0": c0,
        "residual": rn,
        "radius": radius,
        "scale": scale,
    }
