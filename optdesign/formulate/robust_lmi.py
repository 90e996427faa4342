r"""LMI formulations of robust observer design over a set of models (cvxpy): build, never solve.

One gain ``L`` for every model ``i`` of a :class:`~optdesign.model.model_set.ModelSet`, with one
common Lyapunov matrix ``P > 0`` and the linearizing change of variables ``Y = P L``, so that
``P (A_i - L C_i) = P A_i - Y C_i =: Z_i`` is affine in ``(P, Y)`` and in the vertex data
``(A_i, C_i, B_{w,i}, D_{v,i})`` (:meth:`ModelSet.vertex_data`).  Every inequality below is
therefore affine in the data, and holding at every model it holds at every convex combination
of them -- the certificate covers the polytope, not only its vertices.

Regions (Chilali & Gahinet 1996, Thm 2.2, applied to ``(A - LC)'``; ``(L_D, M_D)`` from
:meth:`~optdesign.regions.Region.lmi_matrices`)::

    M_i = L_D (x) P + M_D (x) Z_i' + M_D' (x) Z_i  <=  -2 eps (I (x) P)

i.e. every pole of ``A_i - L C_i`` lies in ``{s : f_D(s) <= -2 eps I}``, the region shrunk by
about ``eps`` (exactly ``eps`` for half-planes and sectors, ``2 eps`` for disks): strictness with
a margin that rounding cannot eat.

Estimation error ``e' = X_i e + B_i n`` with ``X_i = A_i - L C_i``, ``B_i = [B_{w,i}, -L D_{v,i}]``
(:func:`optdesign.analysis.norms.error_channel`), ``P B_i = [P B_{w,i}, -Y D_{v,i}]``; with a
scalar ``rho > 0`` that keeps the bounds homogeneous in ``(P, Y, rho)``:

* H2 <= h (continuous): ``Z_i + Z_i' + rho I <= 0``, ``[[W_i, (P B_i)'], [P B_i, P]] >= 0``,
  ``trace W_i <= rho h^2``; (discrete): ``[[P - rho I, Z_i'], [Z_i, P]] >= 0`` and the same
  Schur block.  Then ``P / rho`` dominates the observability Gramian and
  ``H2^2 <= trace(B_i' P B_i) / rho <= h^2``.
* H-infinity <= g (bounded real lemma, continuous):
  ``[[Z_i + Z_i' + rho I, P B_i], [(P B_i)', -rho g^2 I]] <= 0``; (discrete):
  ``[[P, Z_i, P B_i], [Z_i', P - rho I, 0], [(P B_i)', 0, rho g^2 I]] >= 0``.
* ``||L||_2 <= max_gain``: ``P >= sigma I`` and ``||Y||_2 <= max_gain sigma`` (conservative:
  ``||L|| <= ||P^-1|| ||Y||``).
* Structural zeros of ``L`` (``gain_mask``): ``P`` diagonal and ``Y`` zero where ``L`` is, so
  ``L = P^-1 Y`` has the same zeros (conservative: a diagonal Lyapunov matrix).

Objectives:

* ``"cond"`` (default): ``I <= P <= t I``, minimize ``t``.  A well-conditioning proxy with a
  meaning: if ``A - LC = V Lambda V^-1`` has its poles strictly in the region, ``P = (V V^H)^-1``
  satisfies the region LMI and ``cond(P) = kappa2(V)^2`` (for the best diagonal scaling of V), so
  ``sqrt(t)`` is the conditioning of a quadratic certificate.
* ``"gain"``: ``P >= I``, minimize the bound ``s >= ||Y||_2 >= ||L||_2`` (gammasyn's NORMGAIN).
* ``"h2"``: ``rho = 1``, minimize ``nu`` with ``trace W_i <= nu``: the guaranteed worst-case H2
  norm is ``sqrt(nu)`` (the observer dual of msfsyn / Chilali-Gahinet-Apkarian's H2 synthesis).
* ``"hinf"``: ``rho = 1``, minimize ``nu = g^2`` in the bounded-real LMIs.

References
----------
M. Chilali and P. Gahinet, "H-infinity design with pole placement constraints: an LMI
approach", IEEE TAC 41(3), 358-367, 1996.
M. Chilali, P. Gahinet and P. Apkarian, "Robust pole placement in LMI regions", IEEE TAC 44(12),
2257-2270, 1999.
C. Scherer, P. Gahinet and M. Chilali, "Multiobjective output-feedback control via LMI
optimization", IEEE TAC 42(7), 1997.
MathWorks, Robust Control Toolbox, ``msfsyn`` (multi-model / multi-objective state-feedback
synthesis; the observer problem is its dual).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._backends import import_cvxpy
from ..analysis.linalg import sym
from ..errors import ValidationError
from ..model.model_set import ModelSet
from ..model.regions import Region

__all__ = [
    "LMI_OBJECTIVES",
    "LMISpec",
    "RobustLMI",
    "build_robust_lmi",
    "default_margin",
    "lmi_blocks",
    "region_lmi",
]

#: objectives understood by :func:`build_robust_lmi`
LMI_OBJECTIVES = ("cond", "gain", "h2", "hinf")


@dataclass(frozen=True, eq=False)
class LMISpec:
    """The fixed choices of a robust LMI design (everything but the numbers it is solved for).

    Attributes
    ----------
    discrete : bool
    regions : tuple of (Region or None)
        One per model (None: no region constraint for that model).
    objective : str
        One of :data:`LMI_OBJECTIVES`.
    h2_max, hinf_max, max_gain : float or None
        Bounds.
    mask : (n, p) ndarray of bool or None
        Free entries of L (None: all free).
    margin : float
        Region strictness ``eps`` (units of the poles).
    """

    discrete: bool
    regions: tuple[Region | None, ...]
    objective: str
    h2_max: float | None = None
    hinf_max: float | None = None
    max_gain: float | None = None
    mask: NDArray[np.bool_] | None = None
    margin: float = 0.0

    @property
    def diagonal_P(self) -> bool:
        """The Lyapunov matrix is restricted to diagonal (structural zeros in L)."""
        return self.mask is not None and not bool(np.all(self.mask))

    @property
    def homogeneous(self) -> bool:
        """``rho`` is a variable (objectives cond and gain) rather than fixed to 1."""
        return self.objective in ("cond", "gain")

    @property
    def needs_noise(self) -> bool:
        return self.objective in ("h2", "hinf") or self.h2_max is not None or self.hinf_max is not None


@dataclass(eq=False)
class RobustLMI:
    """A built cvxpy problem of :func:`build_robust_lmi`.

    Attributes
    ----------
    problem : cvxpy.Problem
    spec : LMISpec
    variables : dict
        ``"P"`` (n, n), ``"Y"`` (n, p) expressions and the scalar variables that exist among
        ``"rho"``, ``"t"``, ``"s"``, ``"sigma"``, ``"nu"``, and ``"W"`` (list of the H2 Schur
        blocks per model).
    constraints : dict
        Named groups of cvxpy constraints (``"region"``: one per model with a region, ``"h2"``,
        ``"hinf"``, ``"norm"``: normalizations, ``"gain"``), in the same order as
        :func:`lmi_blocks` returns their numpy values; used to read the dual (Farkas)
        certificate of an infeasible problem.
    """

    problem: Any
    spec: LMISpec
    variables: dict[str, Any]
    constraints: dict[str, list[Any]] = field(default_factory=dict)

    def values(self) -> dict[str, Any]:
        """The numeric values of the variables (None where unsolved)."""
        out: dict[str, Any] = {}
        for k, v in self.variables.items():
            if k == "W":
                out[k] = [None if w.value is None else np.asarray(w.value, dtype=float) for w in v]
            else:
                out[k] = None if v.value is None else np.asarray(v.value, dtype=float)
        return out

    def gain(self) -> NDArray[np.float64] | None:
        """``L = P^-1 Y`` from the solution (None if there is none or P is singular)."""
        vals = self.values()
        P, Y = vals["P"], vals["Y"]
        if P is None or Y is None or not (np.all(np.isfinite(P)) and np.all(np.isfinite(Y))):
            return None
        try:
            L = np.linalg.solve(0.5 * (P + P.T), Y)
        except np.linalg.LinAlgError:
            return None
        if self.spec.mask is not None:
            L = np.where(self.spec.mask, L, 0.0)
        return L


def region_lmi(region: Region, P, Z, margin: float, kron=None):
    """``(L_D + 2 margin I) (x) P + M_D (x) Z' + M_D' (x) Z`` (must be ``<= 0``).

    Works on numpy arrays (``kron=None``: ``numpy.kron``) and on cvxpy expressions
    (``kron=cvxpy.kron``): the same code builds the constraint and evaluates it in numpy.

    Parameters
    ----------
    region : Region
    P : (n, n) symmetric
    Z : (n, n)
        ``P (A - L C)``.
    margin : float
    kron : callable, optional
    """
    Ld, Md = region.lmi_matrices()
    k = np.kron if kron is None else kron
    return k(Ld + 2.0 * margin * np.eye(Ld.shape[0]), P) + k(Md, Z.T) + k(Md.T, Z)


def _noise_input(P, Y, Bw: NDArray, Dv: NDArray, hstack):
    return hstack([P @ Bw, -(Y @ Dv)])


def lmi_blocks(
    spec: LMISpec, data: dict[str, NDArray], values: dict[str, Any], *, cp: Any = None
) -> dict[str, list[Any]]:
    """Every constraint matrix of the problem, each of which must be ``>= 0`` (PSD) or, for
    scalars, ``>= 0``.

    With ``cp=None`` the values are numpy arrays (the independent evaluation of a solution: the
    design layer's certificate check); with ``cp=cvxpy`` the values are cvxpy variables and the
    result is the list of expressions the problem constrains.

    Parameters
    ----------
    spec : LMISpec
    data : dict
        :meth:`ModelSet.vertex_data`.
    values : dict
        ``"P"``, ``"Y"``, and the scalars / W blocks the spec uses.
    cp : module, optional

    Returns
    -------
    dict
        Groups ``"region"``, ``"h2"``, ``"hinf"``, ``"norm"``, ``"gain"`` of matrices ``F`` with the
        constraint ``F >= 0`` (``F`` symmetric, or a scalar).
    """
    P, Y = values["P"], values["Y"]
    if cp is None:
        bmat, hstack, eye, zeros = np.block, np.hstack, np.eye, np.zeros
        trace = np.trace
    else:
        bmat, hstack, eye, zeros = cp.bmat, cp.hstack, np.eye, np.zeros
        trace = cp.trace
    n = data["A"].shape[1]
    N = data["A"].shape[0]
    rho = values.get("rho", 1.0) if spec.homogeneous else 1.0
    out: dict[str, list[Any]] = {"region": [], "h2": [], "hinf": [], "norm": [], "gain": []}
    for i in range(N):
        Z = P @ data["A"][i] - Y @ data["C"][i]
        reg = spec.regions[i]
        if reg is not None:
            out["region"].append(sym(-region_lmi(reg, P, Z, spec.margin, None if cp is None else cp.kron)))
        if spec.needs_noise:
            PB = _noise_input(P, Y, data["Bw"][i], data["Dv"][i], hstack)
            k = PB.shape[1]
        if spec.objective == "h2" or spec.h2_max is not None:
            W = values["W"][i]
            if spec.discrete:
                out["h2"].append(sym(bmat([[P - rho * eye(n), Z.T], [Z, P]])))
            else:
                out["h2"].append(sym(-(Z + Z.T + rho * eye(n))))
            out["h2"].append(sym(bmat([[W, PB.T], [PB, P]])))
            h2m = spec.h2_max
            bound = values["nu"] if (spec.objective == "h2" or h2m is None) else rho * h2m**2
            out["h2"].append(bound - trace(W))
            if spec.objective == "h2" and h2m is not None:
                out["h2"].append(h2m**2 - trace(W))
        if spec.objective == "hinf" or spec.hinf_max is not None:
            him = spec.hinf_max
            g2 = values["nu"] if (spec.objective == "hinf" or him is None) else rho * him**2
            if spec.discrete:
                M = bmat(
                    [[P, Z, PB], [Z.T, P - rho * eye(n), zeros((n, k))], [PB.T, zeros((k, n)), g2 * eye(k)]]
                )
                out["hinf"].append(sym(M))
            else:
                M = bmat([[Z + Z.T + rho * eye(n), PB], [PB.T, -g2 * eye(k)]])
                out["hinf"].append(sym(-M))
            if spec.objective == "hinf" and spec.hinf_max is not None:
                out["hinf"].append(spec.hinf_max**2 - values["nu"])
    if spec.objective in ("cond", "gain"):
        out["norm"].append(sym(P - eye(n)))
        if spec.objective == "cond":
            out["norm"].append(sym(values["t"] * eye(n) - P))
    else:
        out["norm"].append(sym(P))  # P >= 0 (its strictness comes from the other blocks)
    if spec.homogeneous and spec.needs_noise:
        out["norm"].append(rho)
    p = Y.shape[1]
    if spec.objective == "gain":
        s = values["s"]
        out["gain"].append(sym(bmat([[s * eye(n), Y], [Y.T, s * eye(p)]])))
    if spec.max_gain is not None:
        sg = values["sigma"]
        out["gain"].append(sym(P - sg * eye(n)))
        out["gain"].append(sym(bmat([[spec.max_gain * sg * eye(n), Y], [Y.T, spec.max_gain * sg * eye(p)]])))
    return out


def default_margin(models: ModelSet) -> float:
    """The default region strictness ``eps = 1e-6 max(1, max_i ||A_i||_2)`` (units of the poles)."""
    return 1e-6 * max(1.0, max(float(np.linalg.norm(pl.A, 2)) for pl in models))


def build_robust_lmi(
    models: ModelSet,
    regions: Sequence[Region | None],
    *,
    objective: str = "cond",
    h2_max: float | None = None,
    hinf_max: float | None = None,
    max_gain: float | None = None,
    gain_mask: NDArray[np.bool_] | None = None,
    margin: float | None = None,
    fixed_gain: NDArray | None = None,
) -> RobustLMI:
    r"""The robust LMI problem (module docstring) for ``models``.

    Parameters
    ----------
    models : ModelSet
    regions : sequence of Region or None
        One per model.
    objective : {"cond", "gain", "h2", "hinf"}
    h2_max, hinf_max : float, optional
        Bounds on every model's H2 / H-infinity norm of the estimation error (need noise models).
    max_gain : float, optional
        Bound on ``||L||_2``.
    gain_mask : (n, p) ndarray of bool, optional
        Free entries of L.
    margin : float, optional
        Region strictness (default ``1e-6 max(1, max_i ||A_i||_2)``).
    fixed_gain : (n, p) ndarray, optional
        Analysis instead of synthesis: ``L`` is given, ``Y = P L``, only ``P`` (and the scalars)
        are variables -- does a common Lyapunov certificate exist for this gain?  ``gain_mask``
        and ``max_gain`` are then ignored (the gain is what it is).

    Returns
    -------
    RobustLMI
        Built, not solved (solve with :func:`optdesign.backends.cvxpy_backend.solve_cvxpy`).

    Raises
    ------
    ValidationError
        Unknown objective, regions of the wrong length, norms without a noise model, a problem
        with nothing to normalize it (objective h2/hinf need the noise model; cond/gain always
        have one).
    """
    cp = import_cvxpy()
    if objective not in LMI_OBJECTIVES:
        raise ValidationError(f"objective must be one of {LMI_OBJECTIVES}; found {objective!r}")
    regions = tuple(regions)
    if len(regions) != len(models):
        raise ValidationError(
            f"regions must give one region (or None) per model: {len(models)} models, {len(regions)} regions"
        )
    data = models.vertex_data()
    if margin is None:
        margin = default_margin(models)
    if fixed_gain is not None:
        fixed_gain = np.asarray(fixed_gain, dtype=float)
        if fixed_gain.shape != (models.n, models.p):
            raise ValidationError(
                f"fixed_gain must have shape ({models.n}, {models.p}); found {fixed_gain.shape}"
            )
        gain_mask, max_gain = None, None
    spec = LMISpec(
        models.is_discrete,
        regions,
        objective,
        h2_max,
        hinf_max,
        max_gain,
        None if gain_mask is None else np.asarray(gain_mask, dtype=bool),
        float(margin),
    )
    if spec.needs_noise and not models.has_noise_model:
        raise ValidationError(
            f"objective {objective!r} / the H2 and H-infinity bounds need a noise model (Q and R) in "
            "every model"
        )
    n, p = models.n, models.p
    var: dict[str, Any] = {}
    if spec.diagonal_P:
        d = cp.Variable(n, name="P_diag")
        var["P"] = cp.diag(d)
    else:
        var["P"] = cp.Variable((n, n), symmetric=True, name="P")
    if fixed_gain is not None:
        var["Y"] = var["P"] @ fixed_gain
    else:
        mask = np.ones((n, p), dtype=bool) if spec.mask is None else spec.mask
        free = np.flatnonzero(mask.ravel(order="F"))
        y = cp.Variable(free.size, name="Y_free")
        S = np.zeros((n * p, free.size))
        S[free, np.arange(free.size)] = 1.0
        var["Y"] = cp.reshape(S @ y, (n, p), order="F")
    if spec.homogeneous and spec.needs_noise:
        var["rho"] = cp.Variable(name="rho")
    if objective == "cond":
        var["t"] = cp.Variable(name="t")
    if objective == "gain":
        var["s"] = cp.Variable(name="s")
    if objective in ("h2", "hinf"):
        var["nu"] = cp.Variable(name="nu")
    if max_gain is not None:
        var["sigma"] = cp.Variable(name="sigma")
    if objective == "h2" or h2_max is not None:
        k = models.m + p
        var["W"] = [cp.Variable((k, k), symmetric=True, name=f"W{i}") for i in range(len(models))]
    blocks = lmi_blocks(spec, data, var, cp=cp)
    cons: dict[str, list[Any]] = {}
    flat = []
    for grp, items in blocks.items():
        cs = [(F >> 0) if getattr(F, "ndim", 0) == 2 else (F >= 0) for F in items]
        cons[grp] = cs
        flat.extend(cs)
    goal = {"cond": var.get("t"), "gain": var.get("s"), "h2": var.get("nu"), "hinf": var.get("nu")}[objective]
    problem = cp.Problem(cp.Minimize(goal), flat)
    return RobustLMI(problem, spec, var, cons)
