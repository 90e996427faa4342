"""Why a design point failed, in one line of the library's words: statuses and IPOPT return codes
spelled out, CasADi's advice and C++ locations removed (the ``reason`` and ``error`` columns of a
:class:`~optdesign.studies.SweepTable`)."""

from __future__ import annotations

import re
import traceback
from pathlib import Path
from typing import Any

__all__ = ["STATUS_MEANING", "IPOPT_MEANING", "plain_reason", "failure_reason", "one_line_error", "reason_of"]


#: what each status means, in one clause (the first part of a failure reason)
STATUS_MEANING: dict[str, str] = {
    "optimal": "solved",
    "optimal_inaccurate": "solved to a looser tolerance",
    "solved": "solved",
    "infeasible": "infeasible: no design exists (a global certificate says so)",
    "infeasible_inaccurate": "infeasible according to an inaccurate solve",
    "not_found": "no verified design found (a local method: feasibility unknown)",
    "iteration_limit": "the iteration limit ran out before a verified design was found",
    "time_limit": "the time limit ran out before a verified design was found",
    "unbounded": "the solver's iterates diverged",
    "numerical_error": "the solver stopped on a numerical difficulty",
    "solver_error": "the solver failed to run",
    "error": "the design raised an error",
}

#: IPOPT return statuses (as CasADi reports them) in our words
IPOPT_MEANING: dict[str, str] = {
    "Solve_Succeeded": "IPOPT converged",
    "Solved_To_Acceptable_Level": "IPOPT converged to its acceptable (looser) tolerance",
    "Feasible_Point_Found": "IPOPT found a feasible point",
    "Infeasible_Problem_Detected": "IPOPT converged to a point that violates the constraints (locally "
                                   "infeasible)",
    "Search_Direction_Becomes_Too_Small": "IPOPT's steps became too small to make progress",
    "Diverging_Iterates": "IPOPT's iterates diverged",
    "User_Requested_Stop": "IPOPT was stopped by a callback",
    "Maximum_Iterations_Exceeded": "IPOPT reached its iteration limit",
    "Maximum_CpuTime_Exceeded": "IPOPT reached its CPU-time limit",
    "Maximum_WallTime_Exceeded": "IPOPT reached its time limit",
    "Restoration_Failed": "IPOPT's feasibility restoration failed",
    "Error_In_Step_Computation": "IPOPT could not compute a step (singular linear system)",
    "Invalid_Number_Detected": "the problem functions gave NaN or inf at an IPOPT iterate",
    "Not_Enough_Degrees_Of_Freedom": "the NLP has more equality constraints than free variables",
    "Invalid_Problem_Definition": "IPOPT refused the problem definition",
    "Invalid_Option": "IPOPT refused an option",
    "Unrecoverable_Exception": "IPOPT failed with an internal exception",
    "NonIpopt_Exception_Thrown": "a function evaluation raised inside IPOPT",
    "Insufficient_Memory": "IPOPT ran out of memory",
    "Internal_Error": "IPOPT failed with an internal error",
}

# "ipopt: Native (Solver failed. You may use opti.debug.value ... return_status is 'Native')"
_IPOPT_MESSAGE = re.compile(r"ipopt: (\w+)(?: \((?:[^()]|\([^()]*\))*\))?")
# CasADi's advice and C++ locations, wherever they are left
_CASADI_NOISE = (
    re.compile(r"Solver failed\.\s*"),
    re.compile(r"You may use opti\.debug\.value to investigate[^.;)]*\.?\s*"),
    re.compile(r"return_status is '\w+'\s*"),
    re.compile(r"Error in Opti::\w+ \[\w+\]\s*(?:at\s*)?"),
    re.compile(r"\S*\.(?:cpp|hpp):\d+:\s*"),
    re.compile(r"Assertion \"[^\"]*\" failed:\s*"),
)


def plain_reason(text: str) -> str:
    """A backend's message in our words, on one line: IPOPT return statuses spelled out
    (:data:`IPOPT_MEANING`), CasADi's advice ("You may use opti.debug.value to investigate ...")
    and C++ source locations removed.

    Examples
    --------
    >>> plain_reason("ipopt: Maximum_Iterations_Exceeded (Solver failed. You may use "
    ...              "opti.debug.value to investigate the latest values of variables. return_status "
    ...              "is 'Maximum_Iterations_Exceeded')")
    'IPOPT reached its iteration limit'
    """
    text = " ".join(str(text).split())

    def spell(m: re.Match) -> str:
        return IPOPT_MEANING.get(m.group(1), f"IPOPT stopped with status {m.group(1)}")

    text = _IPOPT_MESSAGE.sub(spell, text)
    for pat in _CASADI_NOISE:
        text = pat.sub("", text)
    text = re.sub(r"\(\s*\)", "", text)  # parentheses emptied by the removals
    text = re.sub(r"\s+([;,.)])", r"\1", text)
    return " ".join(text.split()).strip(" ;,")


def failure_reason(status: str, detail: str = "", failed_check: Any = None) -> str:
    """Why a point failed, in one line of our vocabulary: ``"<status>: <what it means>; <detail>"``.

    Parameters
    ----------
    status : str
        A :class:`~optdesign.results.Status` value (or ``"error"``).
    detail : str
        The result's message or the error (cleaned by :func:`plain_reason`).
    failed_check : Check, optional
        The first independent check that failed: named with its value and bound.
    """
    status = str(getattr(status, "value", status))
    head = f"{status}: {STATUS_MEANING.get(status, 'not a success')}"
    if failed_check is not None:
        c = failed_check
        check = f"{c.name} = {c.value:.3g} (must be {c.sense} {c.tolerance:.3g})"
        head = (f"{status} but not verified: the independent check {check} fails"
                if status in ("optimal", "optimal_inaccurate", "solved") else f"{head}; failed check {check}")
    detail = plain_reason(detail)
    return (f"{head}; {detail}" if detail else head)[:400]


def reason_of(result: Any, status: Any, message: Any) -> str:
    """Why a result is not a success, in one line (:func:`failure_reason`)."""
    ver = getattr(result, "verification", None)
    failed = list(getattr(ver, "failed", ()) or ())
    if message is None:
        message = getattr(result, "message", "")
    return failure_reason(getattr(status, "value", status) or "", str(message or ""),
                          failed[0] if failed else None)


def one_line_error(exc: BaseException) -> str:
    """``"Type: message at file:line"`` on one line (the message's line breaks become spaces;
    CasADi's advice removed by :func:`plain_reason`)."""
    tb = traceback.extract_tb(exc.__traceback__)
    where = f" at {Path(tb[-1].filename).name}:{tb[-1].lineno}" if tb else ""
    return f"{type(exc).__name__}: {plain_reason(str(exc))}{where}"
