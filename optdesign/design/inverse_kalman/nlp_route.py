"""``method="nlp"``: IPOPT from a few starts, then the answers that do not depend on IPOPT
converging (see ``NLPRoute`` (below))."""


from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from ...errors import OptDesignError, RiccatiError
from ...formulate.inverse_kalman import (
    spectral_terms,
)
from ...results import Status
from .certificates import closest_poles_search
from .common import decision_size, design_from_Q, empty_result, make_stats, objective_of
from .nlp_solves import eig_nlp_solve, rescue_starts, spectral_solve, start_covariances
from .results import InverseKalmanResult
from .sdp_route import fixed_gain_design, run_sdp

#: IPOPT settings of the rescue starts (several outputs: no start converged to a verified design)
RESCUE_OPTIONS = {"ipopt.max_iter": 1500, "ipopt.mu_strategy": "adaptive"}


#: at most this many rescue starts
RESCUE_STARTS = 4


def run_nlp(plant, target, common, Qn, solver, tol, seed, dl, settings=None):
    """``method="nlp"`` (and the L of ``method="sdp"`` with several outputs): ``NLPRoute`` (below)."""
    return NLPRoute(plant, target, common, Qn, solver, tol, seed, dl, settings).run()


class NLPRoute:
    """The NLP route of :func:`kalman_for_poles`: IPOPT from a few starts, then -- when no start
    gives an optimized verified design -- the answers that do not depend on IPOPT converging:

    * one output: the poles fix L, and the fixed-gain SDP at that gain is the global answer (with
      its certificates); IPOPT stalls at the degenerate, rank-deficient optima of ``Q = F F'``
      (a rank-one discrete target of the 200-target cross-validation: every start ended at the
      iteration limit on one CPU and converged on another, so the two methods disagreed by 34 %);
    * several outputs: rescue starts (adaptive barrier), the least-squares form of the spectral
      conditions and the closest-poles search; a verified gain found by them is finished by the
      fixed-gain SDP at that gain (the optimum over its family of Q); nothing verified is
      ``NOT_FOUND`` (a local search is evidence, not proof), never ``INFEASIBLE``.
    """

    def __init__(self, plant, target, common, Qn, solver, tol, seed, dl, settings=None):
        self.plant, self.target, self.common, self.Qn = plant, target, common, Qn
        self.solver, self.tol, self.seed, self.dl = solver, tol, seed, dl
        self.structure, self.objective = common["structure"], common["objective"]
        self.terms = spectral_terms(plant.A, plant.C, target, plant.dt)
        self.formulation = "spectral" if self.terms is not None else "state-space"
        self.dof = decision_size(plant, self.structure) - plant.n
        self.details: dict[str, Any] = {"starts": [], "formulation": self.formulation,
                                        "degrees_of_freedom": self.dof}
        self.best = self.fallback = self.last_rep = None
        self.best_iterations = 0
        settings = dict(settings or {})
        self.derivatives = settings.pop("derivatives", "closed_form")
        self.ipopt_user = settings  # IPOPT options of the caller (over the route's own)

    # ---------------------------------------------------------------- one start
    def _ipopt(self, opts):
        return {**(opts or {}), **self.ipopt_user, **self.dl.ipopt_options()}

    def run_start(self, start, opts) -> None:
        plant, structure, objective = self.plant, self.structure, self.objective
        Qn, target = self.Qn, self.target
        if self.terms is not None:
            rep, Q, Qw = spectral_solve(plant, target, structure, objective, Qn, start["W"], self.terms,
                                        options=self._ipopt(opts), derivatives=self.derivatives)
        else:
            scale = max(1.0, float(np.linalg.norm(start["L"] @ plant.R @ start["L"].T)))
            rep, Q, Qw = eig_nlp_solve(plant, target, structure, objective, Qn, start, scale=scale,
                                        options=self._ipopt(opts))
        self.last_rep = rep
        entry = {"start": len(self.details["starts"]), "kind": start["kind"], "status": rep.status.value,
                 "native": rep.stats.native_status, "iterations": rep.stats.iterations,
                 "time": rep.stats.time, "derivatives": rep.stats.extra.get("derivatives", "symbolic")}
        self.details["starts"].append(entry)
        if not rep.status.is_solved:
            return
        try:
            L, P, Q, Qw, ver, poles = design_from_Q(plant, target, structure, Q, Qw, self.tol)
        except (RiccatiError, OptDesignError, np.linalg.LinAlgError) as exc:
            entry["error"] = str(exc)
            return
        entry["verified"] = ver.passed
        val = objective_of(objective, Q, Q if structure == "full" else Qw, Qn)
        entry["objective"] = val
        cand = (val, rep, L, P, Q, Qw, ver, poles)
        if ver.passed:
            if self.best is None:
                self.best_iterations = int(rep.stats.iterations or 0)
            if self.best is None or (val > self.best[0] if objective == "feasibility"
                                     else val < self.best[0]):
                self.best = cand
        elif self.fallback is None or ver["pole_error"].value < self.fallback[6]["pole_error"].value:
            self.fallback = cand

    # ---------------------------------------------------------------- the route
    def run(self) -> InverseKalmanResult:
        plant, dl = self.plant, self.dl
        nstarts = 2 if plant.p == 1 else 3
        starts = (start_covariances(plant, self.target, self.structure, self.Qn, self.seed, nstarts,
                                     self.solver) if self.dof >= 0 else [])
        for start in starts:
            if dl.expired:
                break
            # once a verified design exists, the other starts only look for a better local optimum:
            # at most twice the iterations the first success took (50 .. 200) -- an iteration budget,
            # not a wall-time one, so that the answer does not depend on the machine's load
            opts = None if self.best is None else {
                "ipopt.max_iter": min(200, max(50, 2 * self.best_iterations))}
            self.run_start(start, opts)
        if self.best is not None:
            return self.result(self.best, f"{self.formulation} formulation")
        if self.fallback is not None and self.fallback[6]["pole_error"].value <= 1e-3:
            # IPOPT converged near the target but the design failed a check: a precision problem
            # (ill-conditioned poles), not a reachability one
            return self.result(self.fallback, f"{self.formulation} formulation")
        if plant.p == 1:
            return self.finish_one_output()
        if starts and not dl.expired:
            self.rescue(starts)
            if self.best is not None:
                return self.finish_with_sdp(self.best, "the rescue starts (adaptive barrier)")
        return self.endgame()

    def rescue(self, starts) -> None:
        """Several outputs, no start converged (typical of rank-deficient targets, whose min-trace
        optimum is a degenerate point of Q = F F' where IPOPT's monotone barrier update crawls):
        the same starts with the adaptive barrier update, the sequential method's Q, seeded random
        starts -- at most :data:`RESCUE_STARTS`, within the time limit."""
        for k, start in enumerate(rescue_starts(self.plant, self.target, self.structure, starts, self.seed)):
            if k >= RESCUE_STARTS or self.dl.expired or self.best is not None:
                break
            self.run_start(start, RESCUE_OPTIONS)
        self.details["rescue"] = True

    def finish_one_output(self) -> InverseKalmanResult:
        """One output, IPOPT found no verified optimum: the poles fix L, so the fixed-gain SDP at
        that gain answers exactly (the global optimum, or a certificate)."""
        natives = ", ".join(e["native"] for e in self.details["starts"]) or "not run"
        res = run_sdp(self.plant, self.target, self.common, self.Qn, self.solver, self.tol, self.seed,
                      self.dl)
        res.extra["nlp"] = self.details
        msg = (f"NLP ({self.formulation} formulation): IPOPT reached no verified optimum ({natives}); one "
               f"output fixes L, so the fixed-gain SDP at that gain gives the answer: {res.message}")
        return dataclasses.replace(res, message=msg)

    def finish_with_sdp(self, cand, source: str) -> InverseKalmanResult:
        """A verified gain whose Q was not optimized: Q from the fixed-gain SDP at that gain."""
        L = cand[2]
        res = fixed_gain_design(self.plant, self.target, self.common, self.Qn, self.solver, self.tol,
                                 self.seed, self.dl, L=L)
        if res.success:
            res.extra["nlp"] = self.details
            return dataclasses.replace(res, message=f"L from {source}; Q the optimum of that gain's family "
                                                    f"by "
                                                    f"the fixed-gain SDP: {res.message}")
        return self.result(cand, source, optimized=False)

    def endgame(self) -> InverseKalmanResult:
        """Several outputs and nothing verified yet: the least-squares form, the closest poles."""
        plant, structure, dl = self.plant, self.structure, self.dl
        if self.terms is not None and not dl.expired:
            cand = self.least_squares()
            if cand is not None:
                return self.finish_with_sdp(cand, "the least-squares spectral formulation")
        closest = ({} if dl.expired else
                   closest_poles_search(plant, self.target, structure, self.Qn, self.seed, dl))
        self.details["closest"] = {k: v for k, v in closest.items() if k != "rep"}
        reached = closest.get("closest_pole_error")
        if reached is not None and reached <= self.tol and closest.get("rep") is not None:
            try:
                L, P, Q, Qw, ver, poles = design_from_Q(plant, self.target, structure, closest["closest_Q"],
                                                         closest["closest_Qw"], self.tol)
                if ver.passed:
                    val = objective_of(self.objective, Q, Q if structure == "full" else Qw, self.Qn)
                    return self.finish_with_sdp((val, closest["rep"], L, P, Q, Qw, ver, poles),
                                                "the closest-poles formulation")
            except (RiccatiError, OptDesignError, np.linalg.LinAlgError):
                pass
        return self.not_found(reached)

    def least_squares(self):
        """A zero of the least-squares form of the spectral conditions from a few starts (also
        where the structure has too few parameters); a verified candidate or None."""
        plant, structure = self.plant, self.structure
        soft_starts = start_covariances(plant, self.target, structure, self.Qn, self.seed, 2, self.solver)
        rng = np.random.default_rng(self.seed + 1)
        k = plant.n if structure == "full" else plant.m
        sc = max(1.0, float(np.linalg.norm(soft_starts[0]["W"]))) if soft_starts else 1.0
        for _ in range(3):  # a few random positive starts as well
            F = rng.standard_normal((k, k))
            Wr = F @ F.T / k if structure != "diagonal" else rng.uniform(0.1, 1.0, k)
            soft_starts.append({"kind": "random", "W": Wr * sc})
        for start in soft_starts:
            if self.dl.expired:
                return None
            rep, Q, Qw = spectral_solve(plant, self.target, structure, self.objective, self.Qn, start["W"],
                                         self.terms, soft=True, options=self.dl.ipopt_options())
            self.details["starts"].append({"kind": "least squares from " + start["kind"],
                                           "status": rep.status.value, "native": rep.stats.native_status,
                                           "iterations": rep.stats.iterations})
            if not rep.status.is_solved:
                continue
            try:
                L, P, Q, Qw, ver, poles = design_from_Q(plant, self.target, structure, Q, Qw, self.tol)
            except (RiccatiError, OptDesignError, np.linalg.LinAlgError):
                continue
            if ver.passed:
                val = objective_of(self.objective, Q, Q if structure == "full" else Qw, self.Qn)
                return (val, rep, L, P, Q, Qw, ver, poles)
        return None

    # ---------------------------------------------------------------- results
    def result(self, cand, note, optimized=True) -> InverseKalmanResult:
        val, rep, L, P, Q, Qw, ver, poles = cand
        st = rep.stats
        starts_used = len(self.details["starts"])
        msg = (f"NLP ({note}; ipopt: {st.native_status}), {starts_used} start(s); L and P from a Riccati "
               f"solve"
               + ("" if optimized else f" (the {self.objective} objective was not optimized)"))
        if not ver.passed:
            msg += "; the verification failed: " + ", ".join(c.name for c in ver.failed)
        status = rep.status if optimized else Status.OPTIMAL_INACCURATE
        return InverseKalmanResult(
            L=L, Q=Q, Qw=Qw, P=P, poles=poles, status=status, message=msg,
            solver_stats=make_stats("ipopt", st.native_status, self.dl.elapsed, st.iterations,
                                objective=st.extra.get("objective"), starts=starts_used,
                                formulation=self.formulation),
            verification=ver, certificate=None, objective_value=val, extra=self.details, **self.common)

    def not_found(self, reached) -> InverseKalmanResult:
        """Nothing verified with several outputs: feasibility unknown (local evidence only)."""
        plant, structure = self.plant, self.structure
        exact = [e["native"] for e in self.details["starts"] if not e["kind"].startswith("least squares")]
        soft = [e["native"] for e in self.details["starts"] if e["kind"].startswith("least squares")]
        native = self.last_rep.stats.native_status if self.last_rep else ""
        stats = make_stats("ipopt", native, self.dl.elapsed)
        if self.dl.expired:
            return empty_result(self.common, Status.TIME_LIMIT,
                          f"time limit reached ({self.dl}) before a verified design was found, after "
                          f"{len(self.details['starts'])} NLP start(s)", None, stats, details=self.details)
        tried = (f"IPOPT found no Kalman filter with these poles from {len(exact)} start(s) "
                 f"({', '.join(exact) or 'none run'})"
                 + (f" nor a zero of the least-squares form from {len(soft)} start(s)" if soft else ""))
        if self.dof < 0:
            why = (f"the {structure} structure has {decision_size(plant, structure)} parameters for "
                   f"{plant.n} pole conditions (generic targets are out of reach); {tried}")
        elif self.dof == 0:
            why = (f"the {structure} structure has exactly {plant.n} parameters for {plant.n} pole "
                   f"conditions (reachable targets are isolated points); {tried}")
        else:
            why = tried
        near = ("" if reached is None else
                f"; the closest poles found are {reached:.3g} away (extra['closest'])")
        return empty_result(self.common, Status.NOT_FOUND,
                      f"no verified design, feasibility unknown: {why}{near} -- a local search is evidence, "
                      f"not proof", None, stats, details=self.details)

