"""The inverse Kalman engine as the first route of :func:`kalman_for_poles` (``method="sdp"`` /
``"auto"``): :mod:`optdesign.engines.inverse_kalman_engine` finds L and Q together (one output: the
fixed-gain SDP at the gain the poles fix; several outputs: the eigenvector parametrization of the
gains with the target poles and a Newton method on the feasible set, certified by the fixed-gain SDP
at the final gain).  Its answer is verified here like every design; a target it does not apply to,
or an answer that does not verify, falls back to the SDP / NLP routes."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..._deadline import Deadline
from ...engines.inverse_kalman_engine import EngineSetup, prepare_inverse_kalman, solve_inverse_kalman
from ...errors import RiccatiError
from ...model.plant import Plant
from ...results import Status
from .common import empty_result, make_stats, objective_of, verify_design
from .results import InverseKalmanResult

__all__ = ["engine_setup", "run_engine"]


def engine_setup(plant: Plant, structure: str, objective: str, dl: Deadline | None = None) -> EngineSetup:
    """The engine's per-plant state (built once by a problem object, or per call); its set-up
    counts against ``dl``."""
    # the verb verifies every design itself (design/verification.py): the engine need not
    return prepare_inverse_kalman(plant, q_structure=structure, objective=objective, verify=False,
                                  deadline=dl)


def run_engine(setup: EngineSetup, target: NDArray, common: dict[str, Any], Qn: NDArray | None, tol: float,
               seed: int, dl: Deadline, warm_start: NDArray | None = None) -> InverseKalmanResult | None:
    """The engine's design, verified independently -- also when it fails a check (the verb then
    weighs it against the other routes' designs: ``best_unverified`` (common.py)) -- or None (fall
    back to the other routes): the engine does not apply (a target at an eigenvalue of A or of its
    mirror image).  A search that found no design is returned without one (status ``not_found``,
    the starts in ``extra["engine"]``): the verb then runs the other routes and lists the engine's
    attempt in the route.  A time limit that runs out inside the engine is returned as
    such (nothing is lost: the other routes would have no time either)."""
    plant, structure, objective = setup.plant, common["structure"], common["objective"]
    try:
        er = solve_inverse_kalman(setup, target, Q_nominal=Qn, seed=seed, time_limit=dl, tol=tol,
                                  warm_start=warm_start)
    except (np.linalg.LinAlgError, RiccatiError):  # e.g. a repeated one-output target: the SDP route
        return None                                 # (Ackermann's gain) answers it
    if er.details.get("applicable") is False:   # the engine's own test (engine_applies), run once
        return None
    extra: dict[str, Any] = {"engine": er.details, "engine_message": er.message}
    if plant.p > 1:
        extra["L_source"] = "the inverse Kalman engine"
    L, P, Q = er.L, er.P, er.Q  # the engine returns all three with a design, none without
    if L is not None and P is not None and Q is not None and (er.status.is_solved
                                                              or er.status == Status.TIME_LIMIT):
        # L and P from a Lyapunov solve at the SDP's Q, not from a Riccati solver: the lean re-solve
        ver, poles = verify_design(plant, target, L, P, Q, er.Qw, structure, tol, avoid="none")
        if ver.passed or not (er.status == Status.TIME_LIMIT or dl.expired):
            Wdec = Q if structure == "full" else er.Qw
            st = er.solver_stats
            msg = f"inverse Kalman engine: {er.message}"
            if not ver.passed:
                msg += "; failed checks: " + ", ".join(c.name for c in ver.failed)
            return InverseKalmanResult(
                L=er.L, Q=er.Q, Qw=er.Qw, P=er.P, poles=poles, status=er.status, message=msg,
                solver_stats=make_stats(st.backend or "engine", st.native_status, dl.elapsed, er.iterations,
                                        rank=er.rank),
                verification=ver, certificate=None,
                objective_value=objective_of(objective, Q, Wdec if Wdec is not None else Q, Qn),
                extra=extra, **common)
    if er.status == Status.TIME_LIMIT or dl.expired:
        return empty_result(common, Status.TIME_LIMIT, f"time limit reached in the inverse Kalman engine "
                            f"({dl}): {er.message}", None, make_stats("engine", "time_limit", dl.elapsed),
                            details=extra)
    if er.status == Status.NOT_FOUND:   # ran and found nothing: kept for the route (issue 26), no design
        return empty_result(common, Status.NOT_FOUND, f"inverse Kalman engine: {er.message}", None,
                            make_stats("engine", "not_found", dl.elapsed), details=extra)
    return None


def engine_warm_start(result: InverseKalmanResult) -> NDArray | None:
    """The decision covariance of a verified design, as a warm start for a nearby target."""
    if not result.success:
        return None
    W = result.Q if result.structure == "full" else result.Qw
    return None if W is None else np.array(W, dtype=float)
