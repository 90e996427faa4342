"""Solvers layer: run a formulation on a backend, map statuses, report.

Backends (CasADi/IPOPT, cvxpy with Clarabel or SCS) are imported lazily, so importing
optdesign stays cheap; a missing backend raises :class:`optdesign.BackendUnavailableError`.
"""

from .report import SolverReport
from .status import CVXPY_STATUS, IPOPT_STATUS, map_status

__all__ = ["SolverReport", "map_status", "IPOPT_STATUS", "CVXPY_STATUS"]
