"""What running a formulation on a backend returns."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from ..results import SolverStats, Status

__all__ = ["SolverReport"]


@dataclass(frozen=True)
class SolverReport:
    """Outcome of one backend run.

    Attributes
    ----------
    status : Status
        Mapped status (see :mod:`optdesign.solvers.status`).
    stats : SolverStats
        Backend name, native status, time, iterations.
    value : callable
        ``value(expr) -> ndarray``: the value of a decision expression at the returned point
        (the last iterate when the solver failed, so callers can still inspect it); for a
        problem in vector form (``nlpsol``), ``value()`` is the whole decision vector.
    objective : float
        Objective value at the returned point (nan if unavailable).
    message : str
        One line: backend, native status and, on failure, the backend's error text.
    """

    status: Status
    stats: SolverStats
    value: Callable[..., Any]
    objective: float = float("nan")
    message: str = ""
