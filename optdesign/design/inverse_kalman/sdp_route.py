"""``method="sdp"``: the fixed-gain SDP at the gain the poles fix (one output), its whitened retry,
the spectral SDP in Q alone, and the one-output verdict."""


from __future__ import annotations

from typing import Any

import numpy as np

from ...backends.cvxpy_backend import solve_cvxpy
from ...engines.polish import spectral_polish
from ...errors import OptDesignError, RiccatiError
from ...formulate.inverse_kalman import (
    build_spectral_sdp,
    spectral_terms,
)
from ...results import Status
from .certificates import infeasible_fixed_gain, one_output_verdict
from .common import (
    design_from_Q,
    empty_result,
    make_stats,
    noise_of,
    objective_of,
    placed_gain,
    project_psd,
    verify_design,
)
from .results import InverseKalmanResult
from .sdp_stage import (
    feasibility_margin,
    polished_point,
    sdp_attempts,
    sdp_decision,
    sdp_fixed_gain,
    whitening,
)


def run_fixed_gain_sdp(plant, target, common, Qn, solver, tol, seed, dl, L=None, *, whiten=False):
    """The fixed-gain SDP at ``L`` (default: the gain the poles fix for one output); ``whiten``:
    in the whitened coordinates of :func:`whitening` (a retry for badly scaled families)."""
    R = np.asarray(plant.R, dtype=float)
    details: dict[str, Any] = {"whitened": whiten}
    if L is None:
        L = details["L_placed"] = placed_gain(plant, target)
    structure, objective = common["structure"], common["objective"]
    P0, W0, rep, _ = sdp_fixed_gain(plant, L, R, structure, objective, Qn, solver, dl, whiten=whiten)
    details["sdp_report"] = rep
    stage_note = ""
    pol = None if P0 is None else polished_point(plant, L, R, structure, P0, W0, whiten=whiten)
    if pol is None and not whiten:
        # the objective SDP failed or its point fits no face: the feasibility (margin) SDP decides
        t_star, Pm, Wm, rep_m = feasibility_margin(plant, L, R, structure, solver, dl)
        details["margin_report"] = rep_m
        if Pm is None and rep_m.status.is_infeasible:
            return infeasible_fixed_gain(plant, target, common, L, R, float("nan"), rep_m, Qn, seed, dl,
                                          details)
        if Pm is None and P0 is None:
            failed = rep_m.status if not rep_m.status.is_solved else Status.NUMERICAL_ERROR
            return empty_result(common, failed,
                          f"the SDP failed: {rep.message}; the feasibility SDP failed too: {rep_m.message}",
                          None, make_stats(rep_m.stats.backend, rep_m.stats.native_status,
                                       dl.elapsed), details=details)
        if Pm is not None:
            wscale = max(1.0, float(np.max(np.abs(Wm))))
            if t_star < -1e-7 * wscale:
                return infeasible_fixed_gain(plant, target, common, L, R, t_star, rep_m, Qn, seed, dl,
                                              details)
            pol = polished_point(plant, L, R, structure, Pm, Wm)
            if pol is not None or P0 is None:
                what = ("returned " + rep.stats.native_status) if P0 is None else \
                    "point fits no face of the PSD cone"
                stage_note = (f"the {objective} SDP {what}; the feasibility SDP's point "
                              f"(margin {t_star:.3g}) is returned instead; ")
                P0, W0, rep = Pm, Wm, rep_m
    if P0 is None:  # the whitened retry failed
        return empty_result(common, rep.status if not rep.status.is_solved else Status.NUMERICAL_ERROR,
                      f"the SDP in whitened coordinates failed: {rep.message}", None,
                      make_stats(rep.stats.backend, rep.stats.native_status, dl.elapsed), details=details)
    Qr, _ = noise_of(structure, plant.G, W0)
    details["sdp_objective_unpolished"] = objective_of(
        objective, Qr, W0 if structure != "diagonal" else np.diag(W0), Qn)
    if pol is None:
        P, Wdec = P0, (np.maximum(W0, 0.0) if structure == "diagonal" else project_psd(W0))
        polish = "not polished (no face of the PSD cone fits); projected onto the PSD cone"
    else:
        P, Wdec, res = pol
        polish = f"polished on its face of the PSD cone (linear residual {res:.1e})"
    Q, Qw = noise_of(structure, plant.G, Wdec)
    ver, poles = verify_design(plant, target, L, P, Q, Qw, structure, tol)
    status = rep.status if (rep.status.is_solved and not stage_note) else Status.OPTIMAL_INACCURATE
    where = " in whitened coordinates" if whiten else ""
    msg = f"SDP{where} ({rep.stats.backend}: {rep.stats.native_status}), {stage_note}{polish}"
    if not ver.passed:
        msg += "; failed checks: " + ", ".join(c.name for c in ver.failed)
    st = rep.stats
    wd = Wdec if structure != "diagonal" else np.diag(Wdec)
    return InverseKalmanResult(
        L=L, Q=Q, Qw=Qw, P=P, poles=poles, status=status, message=msg,
        solver_stats=make_stats(st.backend, st.native_status, dl.elapsed, st.iterations,
                            solve_time=st.time, objective=st.extra.get("objective")),
        verification=ver, certificate=None, objective_value=objective_of(objective, Q, wd, Qn),
        extra=details, **common)


def fixed_gain_design(plant, target, common, Qn, solver, tol, seed, dl, L=None):
    """:func:`run_fixed_gain_sdp`, retried in whitened coordinates when its design does not
    verify and the family is badly scaled; the whitened design is taken only when it verifies."""
    res = run_fixed_gain_sdp(plant, target, common, Qn, solver, tol, seed, dl, L=L)
    if res.success or res.status == Status.INFEASIBLE or dl.expired:
        return res
    Lw = res.L if L is None else L
    if Lw is None:
        Lw = res.extra.get("L_placed")
    if Lw is None or whitening(plant, Lw, np.asarray(plant.R, dtype=float)) is None:
        return res
    alt = run_fixed_gain_sdp(plant, target, common, Qn, solver, tol, seed, dl, L=Lw, whiten=True)
    if alt.success:
        alt.extra["physical_attempt"] = res.message
        return alt
    return res


#: relative change of the objective by the face polish beyond which the spectral SDP is tried too
POLISH_DRIFT = 1e-7


def run_sdp(plant, target, common, Qn, solver, tol, seed, dl):
    """One output: the fixed-gain SDP in (P, Q); if it gives no verified design, the spectral SDP
    in Q alone (better scaled for large gains) -- an infeasibility verdict of an inaccurate
    fixed-gain SDP is not trusted until the spectral SDP agrees.  A verified design whose
    objective SDP was inaccurate (the feasibility SDP's point returned instead: the objective
    not optimized) is compared with the spectral SDP's, and the better verified one kept."""
    res = fixed_gain_design(plant, target, common, Qn, solver, tol, seed, dl)
    raw = res.extra.get("sdp_objective_unpolished")
    drift = (abs(res.objective_value - raw) / max(1e-300, abs(raw)) if raw is not None and
             np.isfinite(res.objective_value) and abs(raw) > 0 else 0.0)
    # the polish moves the SDP point onto an exact solution; where the family is badly
    # conditioned that move can cost objective (seen: 3e-5 of the trace), so such a design
    # is compared with the spectral SDP's too
    if res.success and res.status == Status.OPTIMAL and drift <= POLISH_DRIFT:
        return res
    terms = spectral_terms(plant.A, plant.C, target, plant.dt)
    if terms is None or dl.expired:
        return one_output_verdict(plant, target, common, res, dl)
    alt = run_spectral_sdp(plant, target, common, Qn, solver, tol, terms, dl)
    alt.extra["fixed_gain_attempt"] = res.message
    if res.success:
        if not alt.success:
            return res
        sign = -1.0 if common["objective"] == "feasibility" else 1.0
        better = sign * alt.objective_value < sign * res.objective_value
        return alt if better or (alt.status == Status.OPTIMAL and not
                                 sign * alt.objective_value > sign * res.objective_value) else res
    if alt.success:
        return alt
    if alt.L is not None and (res.L is None or len(alt.verification.failed) < len(res.verification.failed)):
        if res.L is None and res.status.is_infeasible:
            alt.extra["fixed_gain_certificate"] = res.certificate
        return alt  # a design close to the target whose checks fail: better than no design
    return one_output_verdict(plant, target, common, res, dl)


def run_spectral_sdp(plant, target, common, Qn, solver, tol, terms, dl):
    structure, objective = common["structure"], common["objective"]
    rep = sdp = None
    for name, opts in sdp_attempts(solver):
        sdp = build_spectral_sdp(plant.A, plant.C, np.asarray(plant.R, dtype=float), target, dt=plant.dt,
                                 structure=structure, G=plant.G, objective=objective, Q_nominal=Qn,
                                 terms=terms)
        rep = solve_cvxpy(sdp.problem, name, opts)
        if rep.status.is_solved or rep.status.is_infeasible:
            break
    stats = make_stats(rep.stats.backend, rep.stats.native_status, dl.elapsed,
                   rep.stats.iterations, form="spectral")
    if not rep.status.is_solved or sdp.Q.value is None:
        return empty_result(common, rep.status if not rep.status.is_solved else Status.NUMERICAL_ERROR,
                      f"the spectral SDP: {rep.message}", None, stats)
    W0 = sdp_decision(sdp, structure)
    pol = spectral_polish(sdp.coefficients, sdp.offset, structure, plant.G, W0)
    if pol is not None:
        Wdec = pol[0]
    else:
        Wdec = np.maximum(W0, 0.0) if structure == "diagonal" else project_psd(W0)
    Q, Qw = noise_of(structure, plant.G, Wdec)
    try:
        L, P, Q, Qw, ver, poles = design_from_Q(plant, target, structure, Q, Qw, tol)
    except (RiccatiError, OptDesignError, np.linalg.LinAlgError) as exc:
        return empty_result(common, Status.NUMERICAL_ERROR,
                            f"the spectral SDP's Q has no Riccati solution: {exc}",
                      None, stats)
    msg = (f"spectral SDP in Q alone ({rep.stats.backend}: {rep.stats.native_status}); "
           + ("polished" if pol is not None else "not polished")
           + "; L and P from a Riccati solve")
    if not ver.passed:
        msg += "; failed checks: " + ", ".join(c.name for c in ver.failed)
    wd = Wdec if structure != "diagonal" else np.diag(Wdec)
    return InverseKalmanResult(
        L=L, Q=Q, Qw=Qw, P=P, poles=poles, status=rep.status, message=msg, solver_stats=stats,
        verification=ver, certificate=None, objective_value=objective_of(objective, Q, wd, Qn),
        extra={"spectral_sdp_report": rep}, **common)

