"""Backends layer: adapters that run a formulation on CasADi/IPOPT, cvxpy (Clarabel, SCS) or Clarabel
directly, each with one status map into the one :class:`~optdesign.results.Status` set, and the solver
report (captured solver output included).

Backends are imported lazily, so importing optdesign stays cheap; a missing backend raises
:class:`optdesign.BackendUnavailableError`.  Our own algorithms live in :mod:`optdesign.engines`.
"""

from .report import SolverReport
from .status import CVXPY_STATUS, IPOPT_STATUS, map_status

__all__ = ["SolverReport", "map_status", "IPOPT_STATUS", "CVXPY_STATUS"]
