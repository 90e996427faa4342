"""Result building blocks shared by every design verb: one status set, solver statistics,
and an independent verification record.

A design result is a frozen dataclass that carries ``status``, ``message``,
``solver_stats`` and ``verification``; ``success`` is true only when the status is a
solved one *and* every verification check passed — whatever the solver said.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from typing import Any

from .errors import InfeasibleError, SolverError

__all__ = ["Status", "Check", "Verification", "SolverStats", "ResultMixin"]


class Status(str, enum.Enum):
    """The one status set of optdesign (cvxpy-style, shared by every backend).

    ``OPTIMAL``/``OPTIMAL_INACCURATE`` come from optimizers, ``SOLVED`` from direct
    (closed-form, analytical, linear-algebra) methods that have no optimality notion.

    ``INFEASIBLE`` is a verdict: it is reported only with a *global* certificate (a
    return-difference frequency, an SDP dual / Farkas certificate, a proof).  A local method
    that stops without a solution reports ``NOT_FOUND`` (feasibility unknown), never
    ``INFEASIBLE`` -- whatever the solver said.
    """

    OPTIMAL = "optimal"
    OPTIMAL_INACCURATE = "optimal_inaccurate"
    SOLVED = "solved"
    INFEASIBLE = "infeasible"
    INFEASIBLE_INACCURATE = "infeasible_inaccurate"
    NOT_FOUND = "not_found"
    UNBOUNDED = "unbounded"
    ITERATION_LIMIT = "iteration_limit"
    TIME_LIMIT = "time_limit"
    NUMERICAL_ERROR = "numerical_error"
    SOLVER_ERROR = "solver_error"

    @property
    def is_solved(self) -> bool:
        return self in (Status.OPTIMAL, Status.OPTIMAL_INACCURATE, Status.SOLVED)

    @property
    def is_infeasible(self) -> bool:
        return self in (Status.INFEASIBLE, Status.INFEASIBLE_INACCURATE)

    @property
    def is_limit(self) -> bool:
        """A budget ran out (iterations or time): the answer is the best found so far."""
        return self in (Status.ITERATION_LIMIT, Status.TIME_LIMIT)

    def __str__(self) -> str:  # "optimal", not "Status.OPTIMAL"
        return self.value


@dataclass(frozen=True)
class Check:
    """One independent check of a design.

    Attributes
    ----------
    name : str
        What is checked, e.g. ``"pole_error"``, ``"riccati_residual"``, ``"Q_min_eig"``.
    value : float
        The measured quantity.
    tolerance : float
        The bound it must satisfy.
    passed : bool
    sense : str
        ``"<="`` (value <= tolerance must hold) or ``">="``.
    detail : str
        Human-readable explanation.
    """

    name: str
    value: float
    tolerance: float
    passed: bool
    sense: str = "<="
    detail: str = ""

    @classmethod
    def at_most(cls, name: str, value: float, tolerance: float, detail: str = "") -> Check:
        v = float(value)
        return cls(name, v, float(tolerance), bool(v <= tolerance and not math.isnan(v)), "<=", detail)

    @classmethod
    def at_least(cls, name: str, value: float, tolerance: float, detail: str = "") -> Check:
        v = float(value)
        return cls(name, v, float(tolerance), bool(v >= tolerance and not math.isnan(v)), ">=", detail)

    def __str__(self) -> str:
        mark = "ok  " if self.passed else "FAIL"
        extra = f"  ({self.detail})" if self.detail else ""
        return f"[{mark}] {self.name} = {self.value:.3e} {self.sense} {self.tolerance:.3e}{extra}"


@dataclass(frozen=True)
class Verification:
    """The independent checks of a design (recomputed with numpy/scipy, not by the solver)."""

    checks: tuple[Check, ...] = ()

    @classmethod
    def of(cls, checks: Iterable[Check]) -> Verification:
        return cls(tuple(checks))

    @property
    def passed(self) -> bool:
        """True when there is at least one check and all pass."""
        return bool(self.checks) and all(c.passed for c in self.checks)

    @property
    def failed(self) -> tuple[Check, ...]:
        return tuple(c for c in self.checks if not c.passed)

    def __getitem__(self, name: str) -> Check:
        for c in self.checks:
            if c.name == name:
                return c
        raise KeyError(f"no check named {name!r}; have {[c.name for c in self.checks]}")

    def __contains__(self, name: object) -> bool:
        return any(c.name == name for c in self.checks)

    def __iter__(self) -> Iterator[Check]:
        return iter(self.checks)

    def __len__(self) -> int:
        return len(self.checks)

    def __add__(self, other: Verification) -> Verification:
        return Verification(self.checks + tuple(other.checks))

    def summary(self) -> str:
        return "\n".join(str(c) for c in self.checks) if self.checks else "(no checks)"

    def as_dict(self) -> dict[str, dict[str, Any]]:
        return {c.name: {"value": c.value, "tolerance": c.tolerance, "passed": c.passed,
                         "sense": c.sense, "detail": c.detail} for c in self.checks}


@dataclass(frozen=True)
class SolverStats:
    """What the backend reported.

    Attributes
    ----------
    backend : str
        e.g. ``"ipopt"``, ``"clarabel"``, ``"scs"``, ``"scipy"``, ``"analytic"``.
    native_status : str
        The backend's own status string, unmapped.
    time : float
        Wall time in seconds (formulation excluded where separable).
    iterations : int or None
    extra : dict
        Anything else (objective value, number of starts, ...).
    """

    backend: str
    native_status: str = ""
    time: float = 0.0
    iterations: int | None = None
    extra: dict[str, Any] = field(default_factory=dict)


class ResultMixin:
    """Behaviour common to design results (needs ``status``, ``message``, ``verification``)."""

    status: Status
    message: str
    verification: Verification

    @property
    def success(self) -> bool:
        """Solved by the backend *and* passed every independent check."""
        return Status(self.status).is_solved and self.verification.passed

    def raise_for_status(self):
        """Return ``self`` if successful; otherwise raise InfeasibleError or SolverError."""
        if self.success:
            return self
        status = Status(self.status)
        if status.is_infeasible:
            raise InfeasibleError(self.message, certificate=getattr(self, "certificate", None))
        stats = getattr(self, "solver_stats", None)
        failed = "; ".join(str(c) for c in self.verification.failed)
        raise SolverError(
            f"{self.message} (status {status.value}" + (f"; failed checks: {failed}" if failed else "") + ")",
            backend=getattr(stats, "backend", ""), native_status=getattr(stats, "native_status", ""),
        )
