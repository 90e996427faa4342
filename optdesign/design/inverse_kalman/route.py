"""The visible route of the inverse-Kalman verbs (issue 26, item 2): what ran, in order, and which
stage answered -- built in one place per verb from what the stages record (``extra``:
``sdp_report``, ``margin_report``, ``whitened``, ``physical_attempt``, ``fixed_gain_attempt``,
``spectral_sdp_report``, ``L_source``, ``nlp_message``; the solver statistics; the certificate),
so ``method`` is what was asked and ``route`` what ran."""


from __future__ import annotations

from typing import Any

from ...results import Route, Stage, Status

__all__ = ["inverse_kalman_route", "optimality_route"]


def _outcome(rep: Any) -> str:
    st = getattr(rep, "status", None)
    return "failed" if st is None else Status(st).value


def _detail(rep: Any) -> str:
    stats = getattr(rep, "stats", None)
    return "" if stats is None else f"{stats.backend}: {stats.native_status}"


def _route_stages(res: Any) -> list[Stage]:
    """The stages of the SDP / NLP / sequential routes, from what they recorded."""
    d = res.extra if hasattr(res, "extra") else {}
    stages: list[Stage] = []
    if "nlp_message" in d:
        src = d.get("L_source")
        stages.append(Stage("nlp/ipopt", "backend", "optimal" if src == "the NLP" else "not_found",
                            str(d["nlp_message"])[:80]))
        if src and src != "the NLP":
            stages.append(Stage("sequential (Solheim)", "fallback", "answered", "L from it"))
    if "physical_attempt" in d:
        stages.append(Stage("fixed_gain_sdp", "backend", "not_found", str(d["physical_attempt"])[:80]))
    if "fixed_gain_attempt" in d:
        stages.append(Stage("fixed_gain_sdp", "backend", "not_found", str(d["fixed_gain_attempt"])[:80]))
    if "sdp_report" in d:
        name = "fixed_gain_sdp_whitened" if d.get("whitened") else "fixed_gain_sdp"
        stages.append(Stage(name, "fallback" if d.get("whitened") else "backend", _outcome(d["sdp_report"]),
                            _detail(d["sdp_report"])))
    if "margin_report" in d:
        stages.append(Stage("feasibility_sdp", "fallback", _outcome(d["margin_report"]),
                            _detail(d["margin_report"])))
    if "spectral_sdp_report" in d or getattr(res.solver_stats, "extra", {}).get("form") == "spectral":
        rep = d.get("spectral_sdp_report")
        stages.append(Stage("spectral_sdp", "fallback", _outcome(rep) if rep is not None else str(res.status),
                            _detail(rep)))
    if "solheim" in d:
        stages.append(Stage("sequential (Solheim)", "direct", "solved"))
    if "circle" in d:
        stages.append(Stage("return_difference", "certificate", "no proof",
                            "the inequality holds at the gain"))
    if "refused" in d:
        stages.append(Stage("direct_form_sdp", "backend", "skipped", str(d["refused"])[:80]))
    return stages


def inverse_kalman_route(res: Any, *, early: str | None = None, engine: Any = None,
                         nominal: Any = None) -> Route:
    """The route of a :func:`kalman_for_poles` answer.

    Parameters
    ----------
    res : InverseKalmanResult
        The answer.
    early : str, optional
        The name of an answer that needed no solver (``"unstable_target"``, ``"identity"``,
        ``"zero_noise"``, ``"nominal"``).
    engine : InverseKalmanResult, optional
        The engine's result when the engine ran (returned or not).
    nominal : InverseKalmanResult, optional
        The nominal-noise design kept as a fallback (objective ``"nearest"``).
    """
    answered = res.L is not None
    if early is not None:
        kind = "certificate" if early in ("unstable_target", "identity") else "direct"
        return Route([Stage(early, kind, "answered" if answered else Status(res.status).value)])
    stages: list[Stage] = []
    if nominal is not None:
        stages.append(Stage("nominal_noise", "direct", "rejected", "fails " + ", ".join(
            c.name for c in nominal.verification.failed)))
    if engine is not None:
        from_engine = res is engine or (res.L is not None and engine.L is not None and res.L is engine.L)
        stages.append(Stage("inverse_kalman_engine", "engine",
                            "answered" if from_engine else
                            ("rejected" if engine.L is not None else Status(engine.status).value),
                            getattr(engine.solver_stats, "native_status", "")))
        if from_engine:
            return Route(stages)
    rest = _route_stages(res)
    if not rest and engine is not None and engine.L is None and res is not engine:
        # the engine found nothing: the route that answered after it (or also found nothing)
        rest = [Stage(f"{res.method}", "backend", "answered" if answered else Status(res.status).value,
                      res.solver_stats.native_status if res.solver_stats else "")]
    stages += rest
    if nominal is not None and res is not None and res.L is not None and res.L is nominal.L:
        stages = [Stage("nominal_noise", "direct", "answered", "its pole checks pass")] + stages[1:]
        return Route(stages)
    cert = res.certificate
    if cert is not None and not answered:
        stages.append(Stage(str(cert.kind), "certificate", Status(res.status).value))
    if answered and stages and not any(s.outcome == "answered" for s in stages):
        last = stages[-1]
        stages[-1] = Stage(last.name, last.kind, "answered", last.detail)
    elif answered and not stages:
        stages.append(Stage(f"{res.method}", "backend", "answered", res.solver_stats.native_status))
    if not stages:
        stages.append(Stage(f"{res.method}", "backend", Status(res.status).value,
                            res.solver_stats.native_status if res.solver_stats else ""))
    return Route(stages)


def optimality_route(res: Any) -> Route:
    """The route of an :func:`is_kalman_optimal` answer: the frequency scan, the margin SDP (its
    attempts), the certificate search, the verdict."""
    stages: list[Stage] = []
    circ = res.circle
    if circ is not None:
        out = ("passed" if circ.passed else "violated" if circ.violation_certain else
               "incomplete" if not circ.complete else "inside its rounding floor")
        stages.append(Stage("circle_condition", "check", out,
                            f"min eig {circ.min_eigenvalue:.3g} at {circ.omega_worst:.4g} rad/s"))
    stats = res.solver_stats
    attempts = (stats.extra or {}).get("attempts") if stats is not None else None
    if stats is not None and stats.backend not in ("none", ""):
        for a in attempts or [f"{stats.backend}: {stats.native_status}"]:
            backend, _, native = str(a).partition(": ")
            stages.append(Stage(f"margin_sdp/{backend}", "backend", native or "ran"))
    cert = res.certificate
    if res.optimal:
        stages.append(Stage("polished Q certificate", "polish", "answered", "every check passes"))
    elif cert is not None:
        stages.append(Stage(str(cert.kind), "certificate", Status(res.status).value, "not Kalman-optimal"))
    else:
        stages.append(Stage("verdict", "check", Status(res.status).value, "no proof either way"))
    return Route(stages)
