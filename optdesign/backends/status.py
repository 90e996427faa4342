"""Map every backend's native status onto the one :class:`optdesign.results.Status` set.

Modelled on cvxpy's per-solver ``STATUS_MAP`` tables: one table per backend, unknown
native statuses map to ``SOLVER_ERROR`` (never silently to success).
"""

from __future__ import annotations

from ..results import Status

__all__ = ["IPOPT_STATUS", "CVXPY_STATUS", "CLARABEL_STATUS", "map_status"]

#: IPOPT ``return_status`` strings (as reported by CasADi's ``stats()``).
IPOPT_STATUS: dict[str, Status] = {
    "Solve_Succeeded": Status.OPTIMAL,
    "Solved_To_Acceptable_Level": Status.OPTIMAL_INACCURATE,
    "Feasible_Point_Found": Status.OPTIMAL_INACCURATE,
    # IPOPT converged to a point of local infeasibility: no verdict on the problem (no global
    # certificate), so "not found" -- never "infeasible"
    "Infeasible_Problem_Detected": Status.NOT_FOUND,
    "Search_Direction_Becomes_Too_Small": Status.NUMERICAL_ERROR,
    "Diverging_Iterates": Status.UNBOUNDED,
    "User_Requested_Stop": Status.SOLVER_ERROR,
    "Maximum_Iterations_Exceeded": Status.ITERATION_LIMIT,
    "Maximum_CpuTime_Exceeded": Status.TIME_LIMIT,
    "Maximum_WallTime_Exceeded": Status.TIME_LIMIT,
    "Restoration_Failed": Status.NUMERICAL_ERROR,
    "Error_In_Step_Computation": Status.NUMERICAL_ERROR,
    "Invalid_Number_Detected": Status.NUMERICAL_ERROR,
    "Not_Enough_Degrees_Of_Freedom": Status.SOLVER_ERROR,
    "Invalid_Problem_Definition": Status.SOLVER_ERROR,
    "Invalid_Option": Status.SOLVER_ERROR,
    "Unrecoverable_Exception": Status.SOLVER_ERROR,
    "NonIpopt_Exception_Thrown": Status.SOLVER_ERROR,
    "Insufficient_Memory": Status.SOLVER_ERROR,
    "Internal_Error": Status.SOLVER_ERROR,
}

#: cvxpy ``problem.status`` strings (already a unified set; we keep them 1:1).
CVXPY_STATUS: dict[str, Status] = {
    "optimal": Status.OPTIMAL,
    "optimal_inaccurate": Status.OPTIMAL_INACCURATE,
    "infeasible": Status.INFEASIBLE,
    "infeasible_inaccurate": Status.INFEASIBLE_INACCURATE,
    "unbounded": Status.UNBOUNDED,
    "unbounded_inaccurate": Status.UNBOUNDED,
    "user_limit": Status.ITERATION_LIMIT,
    "solver_error": Status.SOLVER_ERROR,
}

#: Clarabel's own ``SolverStatus`` names (the fixed-gain SDP solved on Clarabel directly,
#: :mod:`optdesign.backends.clarabel_fixed_gain`)
CLARABEL_STATUS: dict[str, Status] = {
    "Solved": Status.OPTIMAL,
    "AlmostSolved": Status.OPTIMAL_INACCURATE,
    "PrimalInfeasible": Status.INFEASIBLE,
    "AlmostPrimalInfeasible": Status.INFEASIBLE_INACCURATE,
    "DualInfeasible": Status.UNBOUNDED,
    "AlmostDualInfeasible": Status.UNBOUNDED,
    "MaxIterations": Status.ITERATION_LIMIT,
    "MaxTime": Status.TIME_LIMIT,
    "NumericalError": Status.NUMERICAL_ERROR,
    "InsufficientProgress": Status.NUMERICAL_ERROR,
    "CallbackTerminated": Status.SOLVER_ERROR,
    "Unsolved": Status.SOLVER_ERROR,
}

_TABLES = {"ipopt": IPOPT_STATUS, "cvxpy": CVXPY_STATUS}


def map_status(backend: str, native: str | None) -> Status:
    """The optdesign status for a backend's native status string (unknown -> SOLVER_ERROR)."""
    table = _TABLES.get(backend.lower(), CVXPY_STATUS if backend.lower() in ("clarabel", "scs") else {})
    if native is None:
        return Status.SOLVER_ERROR
    return table.get(str(native), Status.SOLVER_ERROR)
