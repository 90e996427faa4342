"""The well-conditioned observer NLPs on a CasADi ``Opti``: fixed poles (reduced, left-eigenvector
coordinates) and free poles in a region (full space).  Build, never solve.

See :mod:`optdesign.formulate.well_conditioned` for the formulation.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..._validate import as_poles
from ...errors import ValidationError
from ...model.plant import Plant
from ...model.regions import Region
from .common import (
    GAIN_BOUND_STAGE,
    KAPPA2_BOUND_STAGES,
    KAPPA2_STAGES,
    NLPScaling,
    PoleStructure,
    RecordingOpti,
    casadi_module,
    check_objective,
    eigenvector_coordinates,
    real_modal_basis,
)

__all__ = [
    "ObserverNLP",
    "RegionNLP",
    "FixedPoleNLP",
    "build_observer_nlp",
    "trace_power_chain",
    "complex_basis",
]


def trace_power_chain(ca, M, J_max: int) -> dict[int, Any]:
    """``{J: log(tr(M^k)) / k}`` for ``k = 2**J``, ``J = 0..J_max``, from ONE squaring chain.

    ``lambda_max(M) <= tr(M^k)^(1/k) <= n^(1/k) lambda_max(M)`` for symmetric PSD ``M``.
    Repeated squaring with renormalization avoids overflow: ``B_0 = M / tr M``,
    ``B_{j+1} = B_j^2 / tr(B_j^2)``, ``log tau_{j+1} = log tr(B_j^2) + 2 log tau_j``.
    """
    tau = ca.trace(M)
    B = M / tau
    lt = ca.log(tau)
    out = {0: lt}
    for j in range(J_max):
        B2 = B @ B
        t2 = ca.trace(B2)
        lt = ca.log(t2) + 2.0 * lt
        B = B2 / t2
        out[j + 1] = lt / (2.0 ** (j + 1))
    return out


def complex_basis(
    V: NDArray, st: PoleStructure, real: ArrayLike, uppers: ArrayLike, sign: float
) -> tuple[NDArray[np.complex128], NDArray[np.complex128]]:
    """``(Z, poles)`` from a real modal basis ``V``: unit real columns, then for each pair with
    columns ``(x, y)`` the unit vector ``z = x + sign j y`` and ``conj(z)`` (poles ``u, conj(u)``)."""
    re_, up = np.asarray(real), np.asarray(uppers)
    cols, poles = [], []
    for k in range(st.n_real):
        cols.append(V[:, k] / np.linalg.norm(V[:, k]))
        poles.append(complex(re_[k]))
    for k in range(st.n_pairs):
        j = st.n_real + 2 * k
        z = V[:, j] + sign * 1j * V[:, j + 1]
        z = z / np.linalg.norm(z)
        lam = complex(up[k])
        cols += [z, z.conj()]
        poles += [lam, lam.conjugate()]
    return np.column_stack(cols), np.asarray(poles)


class ObserverNLP:
    """A built (unsolved) well-conditioned-observer NLP on a CasADi ``Opti``.

    Create with :func:`build_observer_nlp`, which returns a :class:`FixedPoleNLP` or a
    :class:`RegionNLP`.  Common attributes: ``opti`` (the problem), ``plant``, ``structure``,
    ``objective``, ``scaling``, ``params`` (name -> ``opti.parameter``), ``fixed_poles``,
    ``L_expr`` (the gain in the plant's units, an MX expression), ``solver_ready`` (set by the
    caller after the first solve, so that re-solves reuse the configured IPOPT instance),
    ``stage_solvers`` (the caller's configured solvers of :meth:`nlpsol_problem`, by
    :attr:`stage_key`; empty until the caller fills it).
    """

    fixed_poles: bool = False

    def _common_init(
        self,
        plant: Plant,
        structure: PoleStructure,
        objective: str,
        mask: NDArray[np.bool_] | None,
        scaling: NLPScaling,
    ) -> None:
        ca = casadi_module()
        self.plant = plant
        self.structure = structure
        self.objective = objective
        self.scaling = scaling
        n, p = plant.n, plant.p
        self.mask = np.ones((n, p), dtype=bool) if mask is None else np.asarray(mask, dtype=bool)
        T = scaling.T
        self._At = (plant.A / T[:, None] * T[None, :]) / scaling.omega
        self._Ct = scaling.S[:, None] * plant.C * T[None, :]
        self.opti: Any = RecordingOpti(ca.Opti())
        self.params: dict[str, Any] = {}
        self.vars: dict[str, Any] = {}
        self.solver_ready = False
        #: IPOPT's max_wall_time the solver was configured with (None: unlimited)
        self.solver_wall_time: float | None = None
        # casadi parameters (one-hot stage weights), None until the objective / the kappa2 bound needs them
        self._stage_w: Any | None = None
        self._bound_w: Any | None = None
        #: index in KAPPA2_STAGES of the kappa2 objective's stage (set_stage; default the last)
        self._stage_index = len(KAPPA2_STAGES) - 1
        self.stage_solvers: dict[Any, Any] = {}
        #: the description's vectors (RecordingOpti.layout), made by nlpsol_problem
        self._layout: dict[str, Any] | None = None
        #: id(expr) -> (expr, casadi.Function of (x, p)) for evaluator()
        self._value_fns: dict[int, tuple[Any, Any]] = {}

    def _objective_and_bounds(self, Vu, Wu, Lorig, dep2, delta2, *, max_gain, kappa2_max, eta_max) -> None:
        """Objective (with kappa2 continuation weights) and the bound constraints."""
        ca = casadi_module()
        opti = self.opti
        p = self.plant.p
        if self.objective == "kappa2" or kappa2_max is not None:
            cv = trace_power_chain(ca, Vu.T @ Vu, KAPPA2_STAGES[-1])
            cw = trace_power_chain(ca, Wu @ Wu.T, KAPPA2_STAGES[-1])
            self.k2_terms = {J: 0.5 * (cv[J] + cw[J]) for J in KAPPA2_STAGES}
            self.log_k2 = self.k2_terms[KAPPA2_STAGES[-1]]
        self.fro2 = ca.sumsqr(Wu)
        if self.objective == "eta" or eta_max is not None:
            self.eta2 = dep2 / delta2
        if kappa2_max is not None:
            self.params["kappa2_max"] = opti.parameter()
            opti.set_value(self.params["kappa2_max"], float(kappa2_max))
            # phi_k <= log kappa2_max for the stage k = 2**J selected by a one-hot parameter
            # (set_bound_stage; default the last, k = 4096)
            bound_w = self._bound_w = opti.parameter(len(KAPPA2_STAGES))
            opti.set_value(bound_w, np.eye(len(KAPPA2_STAGES))[-1])
            phi = sum((bound_w[k] * self.k2_terms[J] for k, J in enumerate(KAPPA2_STAGES)), ca.MX(0))
            opti.subject_to(phi <= ca.log(self.params["kappa2_max"]))
        if eta_max is not None:
            self.params["eta_max"] = opti.parameter()
            opti.set_value(self.params["eta_max"], float(eta_max))
            opti.subject_to(dep2 <= self.params["eta_max"] ** 2 * delta2)
        self.L_expr = Lorig
        if max_gain is not None:
            g = opti.parameter()
            self.params["max_gain"] = g
            opti.set_value(g, float(max_gain))
            # ||L||_2 <= g through the smooth bound tr((L'L/g^2)^k)^(1/k) <= 1, k = 1024
            # (exact for p = 1, conservative by at most p^(1/1024)); an epigraph with slack
            # factors loses LICQ exactly when the bound is active
            Ln = Lorig / g
            chain = trace_power_chain(ca, Ln.T @ Ln + 1e-14 * np.eye(p), GAIN_BOUND_STAGE)
            opti.subject_to(chain[GAIN_BOUND_STAGE] <= 0)
        if self.objective == "kappa2":
            stage_w = self._stage_w = opti.parameter(len(KAPPA2_STAGES))
            opti.set_value(stage_w, np.eye(len(KAPPA2_STAGES))[-1])
            opti.minimize(
                sum((stage_w[k] * self.k2_terms[J] for k, J in enumerate(KAPPA2_STAGES)), ca.MX(0))
            )
        elif self.objective == "kappa_fro":
            opti.minimize(ca.log(self.fro2))
        else:
            opti.minimize(self.eta2)

    # ------------------------------------------------------------------ parameters
    def set_stage(self, J: int) -> None:
        """kappa2 objective: minimize the surrogate of order ``2**J`` (``J`` in :data:`KAPPA2_STAGES`)."""
        if self.objective != "kappa2":
            raise ValidationError(
                f"set_stage applies to the kappa2 objective; this NLP minimizes {self.objective}"
            )
        if J not in KAPPA2_STAGES:
            raise ValidationError(f"stage must be one of {KAPPA2_STAGES}; found {J!r}")
        self._stage_index = KAPPA2_STAGES.index(J)
        self.opti.set_value(self._stage_w, np.eye(len(KAPPA2_STAGES))[self._stage_index])

    # ------------------------------------------------------------------ one stage as an nlpsol problem
    @property
    def stage_key(self) -> int | None:
        """What the objective of :meth:`nlpsol_problem` depends on: the kappa2 objective's stage
        (its index in :data:`KAPPA2_STAGES`), None for the other objectives (one objective)."""
        return self._stage_index if self.objective == "kappa2" else None

    def stage_objective(self):
        """The current stage's objective alone (an MX expression).

        The ``Opti`` objective of kappa2 sums every stage's surrogate with one-hot weights (one
        description for the whole continuation), so its derivatives run the whole squaring chain to
        ``k = 4096`` at every stage; this is the stage's term only (the same values and derivatives:
        on COMPleib DIS2, n = 3, the exact Hessian of stage J = 0 costs 0.07 instead of 0.31 ms per
        iteration).
        """
        if self.objective == "kappa2":
            return self.k2_terms[KAPPA2_STAGES[self._stage_index]]
        return self.opti.f

    def reset_solvers(self) -> None:
        """Forget the configured ``stage_solvers`` and the description's layout (call before
        configuring again, e.g. with new options or after adding to the description)."""
        self.stage_solvers.clear()
        self._layout = None
        self._value_fns.clear()

    def nlpsol_problem(self) -> dict[str, Any]:
        """``{"x", "p", "f", "g"}`` for ``casadi.nlpsol``: the ``Opti`` description's decision vector,
        parameters and constraints with :meth:`stage_objective`; bounds and start from
        :meth:`numeric_start`, results through :meth:`evaluator`."""
        lay = self._description()
        return {"x": lay["x"], "p": lay["p"], "f": self.stage_objective(), "g": lay["g"]}

    def _description(self) -> dict[str, Any]:
        if self._layout is None:
            self._layout = self.opti.layout()
        return self._layout

    def numeric_start(self) -> tuple[NDArray[np.float64], ...]:
        """``(x0, p, lbg, ubg)`` of :meth:`nlpsol_problem`: the initial guess and parameter values set
        on the ``Opti`` description (``set_initial_gain``, :meth:`warm_start`,
        :meth:`set_parameters`, the stages) and the constraint bounds at those parameter values."""
        lay = self._description()
        got = self.opti.start_vectors(lay)
        if got is None:  # values set other than for whole symbols: ask Opti (slower)
            o = self.opti
            got = (np.asarray(o.value(lay["x"], o.initial()), dtype=float).ravel(),
                   np.asarray(o.value(lay["p"], o.value_parameters()), dtype=float).ravel())
        x0, p = got
        lbg, ubg = lay["bounds"](p)
        return x0, p, np.asarray(lbg, dtype=float).ravel(), np.asarray(ubg, dtype=float).ravel()

    def evaluator(self, x: NDArray, p: NDArray):
        """``value(expr)`` at the decision vector ``x`` and parameters ``p`` of :meth:`nlpsol_problem`,
        shaped as ``Opti``'s ``sol.value`` (float, 1-D for a column, 2-D otherwise).  The CasADi
        Function of each expression is made once per configuration (:meth:`reset_solvers`)."""
        ca = casadi_module()
        lay = self._description()

        def value(expr):
            entry = self._value_fns.get(id(expr))
            if entry is None or entry[0] is not expr:
                fn = ca.Function("value", [lay["x"], lay["p"]], [expr])
                entry = self._value_fns[id(expr)] = (expr, fn)
            out = np.asarray(entry[1](x, p), dtype=float)
            if out.size == 1:
                return float(out.ravel()[0])
            return out.ravel() if out.shape[1] == 1 else out

        return value

    def continuation(self, stages: tuple[int, ...] | None = None):
        """``(stages, set_stage)`` of this NLP's continuation.

        The kappa2 objective: ``stages`` (default :data:`KAPPA2_STAGES`) through :meth:`set_stage`;
        another objective with a kappa2 bound: :data:`KAPPA2_BOUND_STAGES` through
        :meth:`set_bound_stage`; otherwise one solve, ``((None,), None)``.
        """
        if self.objective == "kappa2":
            return (KAPPA2_STAGES if stages is None else tuple(stages)), self.set_stage
        if self.has_kappa2_bound:
            return KAPPA2_BOUND_STAGES, self.set_bound_stage
        return (None,), None

    @property
    def has_kappa2_bound(self) -> bool:
        """Built with ``kappa2_max`` (a bound with its own continuation, :meth:`set_bound_stage`)."""
        return self._bound_w is not None

    def set_bound_stage(self, J: int) -> None:
        """Bound ``kappa2 <= kappa2_max`` through the surrogate of order ``2**J`` (``J`` in
        :data:`KAPPA2_STAGES`).

        ``phi_k >= log kappa2`` at every order, so every stage guarantees the bound; a lower order is
        smoother and more conservative (by at most ``log(n) / k``), see :data:`KAPPA2_BOUND_STAGES`.
        """
        if self._bound_w is None:
            raise ValidationError(
                "set_bound_stage applies to an NLP built with kappa2_max; this one has none"
            )
        if J not in KAPPA2_STAGES:
            raise ValidationError(f"stage must be one of {KAPPA2_STAGES}; found {J!r}")
        self.opti.set_value(self._bound_w, np.eye(len(KAPPA2_STAGES))[KAPPA2_STAGES.index(J)])

    def set_parameters(self, **values: float) -> None:
        """Change bound / region parameters the NLP was built with (``max_gain``, ``kappa2_max``,
        ``eta_max``, ``decay``, ``damping``, ``radius``)."""
        for k, v in values.items():
            if k not in self.params:
                raise ValidationError(
                    f"this NLP has no parameter {k!r}; it was built with {sorted(self.params)}"
                )
            self.opti.set_value(self.params[k], float(v))

    def snapshot(self, value) -> dict[str, NDArray[np.float64]]:
        """Numeric values of every decision variable (from ``value`` of a SolverReport)."""
        return {k: np.asarray(value(v), dtype=float) for k, v in self.vars.items() if v is not None}

    def warm_start(self, snapshot: dict[str, NDArray[np.float64]]) -> None:
        """Initial guess = a :meth:`snapshot` of a previous solution of this NLP."""
        for k, v in self.vars.items():
            if v is not None and k in snapshot:
                self.opti.set_initial(v, snapshot[k])

    def gain(self, value) -> NDArray[np.float64]:
        """The gain ``L`` (n, p) in the plant's units from ``value`` (a SolverReport.value)."""
        L = np.asarray(value(self.L_expr), dtype=float).reshape(self.plant.n, self.plant.p)
        return np.where(self.mask, L, 0.0)

    def _initial_basis(self, L0: NDArray) -> tuple[NDArray, NDArray, NDArray[np.complex128]]:
        """``(Vt0, Wt0, poles)``: real modal basis of ``A - L0 C`` (scaled), its inverse, its poles."""
        V0, _, P0 = real_modal_basis(self.plant.A - L0 @ self.plant.C, self.structure)
        Vt0 = V0 / self.scaling.T[:, None]
        try:
            Wt0 = np.linalg.inv(Vt0)
        except np.linalg.LinAlgError:
            Wt0 = np.linalg.pinv(Vt0)
        return Vt0, Wt0, P0

    def set_initial_gain(self, L0: ArrayLike) -> None:  # pragma: no cover - abstract
        raise NotImplementedError

    def basis(self, value) -> tuple[NDArray[np.complex128], NDArray[np.complex128]]:  # pragma: no cover
        raise NotImplementedError


class RegionNLP(ObserverNLP):
    """Free poles (in a region): full-space formulation with variables ``L``, ``V``, ``W``, poles.

    Constraints ``(A - LC) V = V Lambda``, ``W V = I``, modal normalization, region
    constraints on every pole (for a pair, on its upper member: the regions are symmetric).
    """

    fixed_poles = False

    def __init__(
        self,
        plant: Plant,
        structure: PoleStructure,
        *,
        objective: str,
        region: Region | None,
        mask: NDArray[np.bool_] | None,
        max_gain: float | None,
        kappa2_max: float | None,
        eta_max: float | None,
        decay: float | None,
        damping: float | None,
        radius: float | None,
        scaling: NLPScaling,
    ) -> None:
        ca = casadi_module()
        self._common_init(plant, structure, objective, mask, scaling)
        self.region = region
        opti, sc = self.opti, scaling
        n, p = plant.n, plant.p
        T = sc.T
        free = np.argwhere(self.mask)
        Lf = opti.variable(len(free))
        Lt = ca.MX.zeros(n, p)
        for k, (i, j) in enumerate(free):
            Lt[int(i), int(j)] = Lf[k]
        self.vars["Lfree"] = Lf
        nr, npair = structure.n_real, structure.n_pairs
        lr = opti.variable(nr) if nr else None
        pr = opti.variable(npair) if npair else None
        pi = opti.variable(npair) if npair else None
        self.vars.update(lam_real=lr, pair_re=pr, pair_im=pi)
        Lam = ca.MX.zeros(n, n)
        if lr is not None:  # nr > 0
            for k in range(nr):
                Lam[k, k] = lr[k]
        if pr is not None and pi is not None:  # npair > 0
            for k in range(npair):
                j = nr + 2 * k
                Lam[j, j] = pr[k]
                Lam[j + 1, j + 1] = pr[k]
                Lam[j, j + 1] = pi[k]
                Lam[j + 1, j] = -pi[k]
        self.Lam = Lam
        Vt = opti.variable(n, n)
        Wt = opti.variable(n, n)
        self.vars.update(Vt=Vt, Wt=Wt)
        Xt = self._At - Lt @ self._Ct
        opti.subject_to(ca.vec(Xt @ Vt - Vt @ Lam) == 0)
        opti.subject_to(ca.vec(Wt @ Vt - np.eye(n)) == 0)
        V = ca.diag(ca.DM(T)) @ Vt
        W = Wt @ ca.diag(ca.DM(1.0 / T))
        self.V, self.W = V, W
        norms = [ca.sumsqr(V[:, k]) - 1.0 for k in range(nr)]
        for k in range(npair):
            j = nr + 2 * k
            norms.append(ca.sumsqr(V[:, j]) + ca.sumsqr(V[:, j + 1]) - 2.0)
        opti.subject_to(ca.vertcat(*norms) == 0)

        poles = [(lr[k], 0.0) for k in range(nr)] if lr is not None else []
        if pr is not None and pi is not None:
            poles += [(pr[k], pi[k]) for k in range(npair)]
            opti.subject_to(pi >= 0)
        w0 = sc.omega
        if region is not None:
            for re_, im_ in poles:
                gs = [
                    g
                    for g in region.constraints(w0 * re_, w0 * im_)
                    if isinstance(g, ca.MX) and not g.is_constant()
                ]
                if gs:
                    opti.subject_to(ca.vertcat(*gs) <= 0)
        for name, val in (("decay", decay), ("damping", damping), ("radius", radius)):
            if val is not None:
                self.params[name] = opti.parameter()
                opti.set_value(self.params[name], float(val))
        for re_, im_ in poles:
            if decay is not None:
                opti.subject_to(w0 * re_ + self.params["decay"] <= 0)
            if damping is not None:
                z = self.params["damping"]
                sn = ca.sqrt(1 - z * z)
                opti.subject_to(re_ * sn + im_ * z <= 0)
                opti.subject_to(re_ * sn - im_ * z <= 0)
            if radius is not None:
                opti.subject_to(w0 * w0 * (re_ * re_ + im_ * im_) <= self.params["radius"] ** 2)

        delta2 = None
        dep2 = None
        if objective == "eta" or eta_max is not None:
            delta = opti.variable()
            self.vars["delta"] = delta
            opti.subject_to(delta >= 1e-12)
            lowers = [(pr[k], -pi[k]) for k in range(npair)] if pr is not None and pi is not None else []
            ev = poles + lowers
            gaps = [
                (ev[i][0] - ev[j][0]) ** 2 + (ev[i][1] - ev[j][1]) ** 2 - delta * delta
                for i in range(len(ev))
                for j in range(i + 1, len(ev))
            ]
            if gaps:
                opti.subject_to(ca.vertcat(*gaps) >= 0)
            Xo = ca.diag(ca.DM(T)) @ Xt @ ca.diag(ca.DM(1.0 / T))  # (A - LC) / omega
            real_sq = sum((lr[k] ** 2 for k in range(nr)), ca.MX(0)) if lr is not None else ca.MX(0)
            pair_sq = (sum((2 * (pr[k] ** 2 + pi[k] ** 2) for k in range(npair)), ca.MX(0))
                       if pr is not None and pi is not None else ca.MX(0))
            lam2 = real_sq + pair_sq
            dep2 = ca.sumsqr(Xo) - lam2
            delta2 = delta * delta
        Lorig = sc.omega * ca.diag(ca.DM(T)) @ Lt @ ca.diag(ca.DM(sc.S))
        self._objective_and_bounds(
            V, W, Lorig, dep2, delta2, max_gain=max_gain, kappa2_max=kappa2_max, eta_max=eta_max
        )

    def set_initial_gain(self, L0: ArrayLike) -> None:
        """Initial guess from a gain: modal basis of ``A - L0 C`` (masked), its poles, gaps."""
        sc, n, p = self.scaling, self.plant.n, self.plant.p
        st, opti = self.structure, self.opti
        L0 = np.where(self.mask, np.asarray(L0, dtype=float).reshape(n, p), 0.0)
        Vt0, Wt0, P0 = self._initial_basis(L0)
        Lt0 = sc.gain_to_scaled(L0)
        opti.set_initial(self.vars["Lfree"], Lt0[self.mask])
        opti.set_initial(self.vars["Vt"], Vt0)
        opti.set_initial(self.vars["Wt"], Wt0)
        Ps = P0 / sc.omega
        if st.n_real:
            opti.set_initial(self.vars["lam_real"], Ps[: st.n_real].real)
        if st.n_pairs:
            opti.set_initial(self.vars["pair_re"], Ps[st.n_real :: 2].real)
            opti.set_initial(self.vars["pair_im"], np.abs(Ps[st.n_real :: 2].imag))
        if "delta" in self.vars:
            d = np.abs(Ps[:, None] - Ps[None, :])
            np.fill_diagonal(d, np.inf)
            opti.set_initial(self.vars["delta"], 0.99 * float(np.min(d)) if n > 1 else 1.0)

    def basis(self, value) -> tuple[NDArray[np.complex128], NDArray[np.complex128]]:
        """``(Z, poles)``: the solver's complex eigenvector matrix (unit columns) and its poles."""
        st, sc, n = self.structure, self.scaling, self.plant.n
        V = np.asarray(value(self.V), dtype=float).reshape(n, n)
        Lam = np.asarray(value(casadi_module().densify(self.Lam)), dtype=float).reshape(n, n) * sc.omega
        jp = range(st.n_real, n, 2)
        return complex_basis(
            V, st, [Lam[k, k] for k in range(st.n_real)], [complex(Lam[j, j], Lam[j, j + 1]) for j in jp], 1.0
        )


class FixedPoleNLP(ObserverNLP):
    """Fixed poles: reduced formulation over the left-eigenvector parameters only.

    A left eigenvector ``w`` of ``A - L C`` for the pole ``lambda`` satisfies
    ``w (A - lambda I) = g C`` with ``g = w L``: ``[w, -g]`` lies in the ``p``-dimensional left
    null space of ``[[A - lambda I], [C]]`` with orthonormal basis ``N`` (a parameter,
    recomputed by :meth:`set_poles`, in the basis of :func:`eigenvector_coordinates`, whose
    eigenvector part is orthonormal).  The variables are the coordinates ``c`` (real for a real
    pole, ``a + j b`` for a pair, rows ``Re w``, ``Im w``); then ``W = [w_i]``, ``G = [g_i]``,
    ``V = W^-1`` (columns normalized inside the objective) and ``L = V G``.  Every point
    satisfies the pole assignment exactly, the problem is unconstrained (unless a mask or a
    bound adds constraints), and the Hessian is ``(n p) x (n p)`` instead of ``(n^2) x (n^2)``:
    n = 16 ran about 100 times faster per iteration than the full-space form (measured).

    The objective is invariant to the scale of each ``c_i`` (and the phase of a pair's), so
    the Hessian is singular along those directions; IPOPT's regularization handles that.
    Pinning them with ``||c_i|| = 1`` equalities was measured to be worse (hence not offered):
    from the same start the k = 512 stage of a random n = 16, p = 5 plant drifted from kappa2
    199 to 313 in 1000 iterations, while the unconstrained form converged in 13.
    """

    fixed_poles = True

    def __init__(
        self,
        plant: Plant,
        structure: PoleStructure,
        *,
        objective: str,
        mask: NDArray[np.bool_] | None,
        max_gain: float | None,
        kappa2_max: float | None,
        eta_max: float | None,
        scaling: NLPScaling,
    ) -> None:
        ca = casadi_module()
        self._common_init(plant, structure, objective, mask, scaling)
        self.region = None
        opti, sc = self.opti, scaling
        n, p = plant.n, plant.p
        T = sc.T
        nr, npair = structure.n_real, structure.n_pairs
        k = self._k = p  # dimension of each left null space (observable pair)
        rows_w, rows_g = [], []
        self._N: list[tuple[Any, Any | None]] = []
        cvars = []
        for i in range(nr):
            N = opti.parameter(n + p, k)
            c = opti.variable(k)
            self._N.append((N, None))
            cvars.append(("c", c))
            self.vars[f"c{i}"] = c
            y = N @ c
            rows_w.append(y[:n].T)
            rows_g.append(-y[n:].T)
        for i in range(npair):
            Nr = opti.parameter(n + p, k)
            Ni = opti.parameter(n + p, k)
            a = opti.variable(k)
            b = opti.variable(k)
            self._N.append((Nr, Ni))
            self.vars[f"a{i}"] = a
            self.vars[f"b{i}"] = b
            yr = Nr @ a - Ni @ b
            yi = Nr @ b + Ni @ a
            rows_w += [yr[:n].T, yi[:n].T]
            rows_g += [-yr[n:].T, -yi[n:].T]
        Wt = ca.vertcat(*rows_w)  # left modal basis in scaled coordinates
        Gt = ca.vertcat(*rows_g)
        Vt = ca.solve(Wt, ca.MX.eye(n))
        Lt = Vt @ Gt
        V = ca.diag(ca.DM(T)) @ Vt
        # column normalization (pairs share one factor: ||v1||^2 + ||v2||^2 = 2)
        d2 = [ca.sumsqr(V[:, j]) for j in range(nr)]
        for i in range(npair):
            j = nr + 2 * i
            m = 0.5 * (ca.sumsqr(V[:, j]) + ca.sumsqr(V[:, j + 1]))
            d2 += [m, m]
        dvec = ca.sqrt(ca.vertcat(*d2))
        Vu = V @ ca.diag(1.0 / dvec)
        Wu = ca.diag(dvec) @ Wt @ ca.diag(ca.DM(1.0 / T))
        self.Vu, self.Wu = Vu, Wu
        Lorig = sc.omega * ca.diag(ca.DM(T)) @ Lt @ ca.diag(ca.DM(sc.S))
        if (~self.mask).any():
            opti.subject_to(ca.vertcat(*[Lt[int(i), int(j)] for i, j in np.argwhere(~self.mask)]) == 0)
        # eta pieces: poles are parameters, the gap is a parameter
        self._lam2 = opti.parameter()
        self._delta2 = opti.parameter()
        opti.set_value(self._lam2, 0.0)
        opti.set_value(self._delta2, 1.0)
        Xo = ca.diag(ca.DM(T)) @ (self._At - Lt @ self._Ct) @ ca.diag(ca.DM(1.0 / T))
        dep2 = ca.sumsqr(Xo) - self._lam2
        self._objective_and_bounds(
            Vu, Wu, Lorig, dep2, self._delta2, max_gain=max_gain, kappa2_max=kappa2_max, eta_max=eta_max
        )
        #: (real poles, upper pair members) of the target, set by set_poles
        self._poles: tuple[NDArray[np.float64], NDArray[np.complex128]] | None = None

    def set_poles(self, poles: ArrayLike) -> None:
        """Set the target poles (same real/pair pattern as the build): recomputes the null spaces.

        Each null space is handed to the NLP in the basis of :func:`eigenvector_coordinates`
        (its left-eigenvector part orthonormal), so that the variables are as well scaled as the
        eigenvector matrix itself whatever the size of the gain.
        """
        from scipy.linalg import null_space

        real, pairs = self.structure.split(poles)
        w = self.scaling.omega
        n, p = self.plant.n, self.plant.p
        At, Ct = self._At, self._Ct
        nulls = []
        for slot, lam in enumerate([*real, *pairs]):
            lam = complex(lam) / w
            M = np.vstack([At - lam * np.eye(n), Ct])
            N = null_space(M.T)  # y M = 0 <=> M^T y = 0
            if N.shape[1] != self._k:
                raise ValidationError(
                    f"the pole {lam * w:.6g} leaves a {N.shape[1]}-dimensional left null space of "
                    "[A - sI; C] "
                    f"(expected p = {p}): it is an unobservable mode of the plant"
                )
            Nw, Tinv = eigenvector_coordinates(N, n)
            Nr, Ni = self._N[slot]
            self.opti.set_value(Nr, Nw.real)
            if Ni is not None:
                self.opti.set_value(Ni, Nw.imag)
            nulls.append((N, Tinv))
        P = as_poles("poles", poles, n) / w
        d = np.abs(P[:, None] - P[None, :])
        np.fill_diagonal(d, np.inf)
        self.opti.set_value(self._lam2, float(np.sum(np.abs(P) ** 2)))
        self.opti.set_value(self._delta2, float(np.min(d)) ** 2 if n > 1 else 1.0)
        self._poles = (real, pairs)
        self._nulls = nulls

    def set_initial_gain(self, L0: ArrayLike) -> None:
        """Initial coordinates from a gain: left eigenvectors of ``A - L0 C`` projected on the null spaces."""
        if self._poles is None:
            raise ValidationError("call set_poles before set_initial_gain")
        n, p = self.plant.n, self.plant.p
        st = self.structure
        L0 = np.asarray(L0, dtype=float).reshape(n, p)
        _, Wt0, _ = self._initial_basis(L0)
        Lt0 = self.scaling.gain_to_scaled(L0)

        def coords(slot: int, w: NDArray) -> NDArray:
            N, Tinv = self._nulls[slot]
            c = Tinv @ (N.conj().T @ np.concatenate([w, -w @ Lt0]))
            nc = np.linalg.norm(c)
            return c / nc if nc > 0 else np.eye(self._k)[0].astype(c.dtype)

        for i in range(st.n_real):
            self.opti.set_initial(self.vars[f"c{i}"], np.real(coords(i, Wt0[i])))
        for i in range(st.n_pairs):
            j = st.n_real + 2 * i
            c = coords(st.n_real + i, Wt0[j] - 1j * Wt0[j + 1])
            if abs(c[0]) > 0:
                c = c * (abs(c[0]) / c[0])  # phase: Im c_0 = 0
            self.opti.set_initial(self.vars[f"a{i}"], c.real)
            self.opti.set_initial(self.vars[f"b{i}"], c.imag)

    def basis(self, value) -> tuple[NDArray[np.complex128], NDArray[np.complex128]]:
        """``(Z, poles)``: the solver's complex eigenvector matrix (unit columns) and its poles."""
        n = self.plant.n
        V = np.asarray(value(self.Vu), dtype=float).reshape(n, n)
        # a solution exists only for a problem whose poles (parameters of the NLP) were set
        assert self._poles is not None, "basis() before set_poles()"
        real, pairs = self._poles
        # x - j y is the right eigenvector of the upper pole (the rows of W are Re w, Im w)
        return complex_basis(V, self.structure, real, pairs, -1.0)


def build_observer_nlp(
    plant: Plant,
    structure: PoleStructure,
    *,
    fixed_poles: bool,
    objective: str = "kappa2",
    region: Region | None = None,
    mask: ArrayLike | None = None,
    max_gain: float | None = None,
    kappa2_max: float | None = None,
    eta_max: float | None = None,
    decay: float | None = None,
    damping: float | None = None,
    radius: float | None = None,
    scaling: NLPScaling | None = None,
) -> ObserverNLP:
    """Build the well-conditioned-observer NLP (never solves it).

    Parameters
    ----------
    plant : Plant
        Uses ``A`` (n, n), ``C`` (p, n).
    structure : PoleStructure
        Number of real poles and conjugate pairs of ``A - L C``.
    fixed_poles : bool
        True: :class:`FixedPoleNLP` (poles set with :meth:`FixedPoleNLP.set_poles`, re-settable);
        False: :class:`RegionNLP` (poles are variables in ``region`` and the parametric
        ``decay``/``damping``/``radius`` constraints).
    objective : {"kappa2", "kappa_fro", "eta"}
    region : Region, optional
        Free-pole mode only.
    mask : (n, p) array_like of bool, optional
        Free entries of ``L`` (False = structural zero).
    max_gain, kappa2_max, eta_max : float, optional
        Bounds ``||L||_2 <= max_gain``, ``kappa2 <= kappa2_max``, ``eta <= eta_max``, created as
        parameters (change them with ``set_parameters``).
    decay, damping, radius : float, optional
        Free-pole mode: ``Re s <= -decay``, damping ratio ``>= damping``, ``|s| <= radius``, as
        parameters (a sweep over them re-solves the same NLP).
    scaling : NLPScaling, optional
        Default ``NLPScaling.identity(n, p)``.

    Returns
    -------
    ObserverNLP

    Raises
    ------
    ValidationError
        Unknown objective, structure not matching ``n``, mask of the wrong shape, region
        arguments given with ``fixed_poles``.
    """
    check_objective(objective)
    if structure.n != plant.n:
        raise ValidationError(f"pole structure has {structure.n} poles; the plant has n = {plant.n} states")
    if mask is not None:
        mask = np.asarray(mask, dtype=bool)
        if mask.shape != (plant.n, plant.p):
            raise ValidationError(f"mask must have shape ({plant.n}, {plant.p}); found {mask.shape}")
    sc = scaling or NLPScaling.identity(plant.n, plant.p)
    if fixed_poles:
        if region is not None or decay is not None or damping is not None or radius is not None:
            raise ValidationError("region, decay, damping and radius apply to free poles (fixed_poles=False)")
        return FixedPoleNLP(
            plant,
            structure,
            objective=objective,
            mask=mask,
            max_gain=max_gain,
            kappa2_max=kappa2_max,
            eta_max=eta_max,
            scaling=sc,
        )
    return RegionNLP(
        plant,
        structure,
        objective=objective,
        region=region,
        mask=mask,
        max_gain=max_gain,
        kappa2_max=kappa2_max,
        eta_max=eta_max,
        decay=decay,
        damping=damping,
        radius=radius,
        scaling=sc,
    )


# --------------------------------------------------------------------------- Kalman NLP
