"""Time budgets shared by the stages of one design (private module, public names).

Every design verb takes ``time_limit=`` (seconds of wall time, ``None`` for no limit) and
honours it: each stage asks the :class:`Deadline` how much time is left, hands that to its
backend (IPOPT ``max_wall_time``, Clarabel ``time_limit``, SCS ``time_limit_secs``) and stops
starting new work once it has expired.  A verb that runs out returns status ``time_limit``
with the best verified answer found so far -- nothing is lost, nothing is raised.
"""

from __future__ import annotations

import math
import time
from typing import Any

from .errors import ValidationError

__all__ = ["Deadline", "as_time_limit"]


def as_time_limit(value: Any, name: str = "time_limit") -> float | None:
    """``None`` (no limit) or a finite number of seconds ``> 0``.

    Raises
    ------
    ValidationError
        Anything else: a string (even a numeric one), a bool, NaN, inf, zero or a negative
        number -- the message names the argument and what was found.
    """
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)) and not _is_numpy_real(value):
        raise ValidationError(f"{name} must be a number of seconds > 0 or None; found {value!r}")
    v = float(value)
    if not math.isfinite(v) or v <= 0:
        raise ValidationError(f"{name} must be a finite number of seconds > 0 or None; found {value!r}")
    return v


def _is_numpy_real(value: Any) -> bool:
    try:
        import numpy as np
    except ImportError:  # pragma: no cover - numpy is a hard dependency
        return False
    return isinstance(value, (np.integer, np.floating)) and not isinstance(value, np.bool_)


class Deadline:
    """A wall-clock budget, started when it is made.

    Parameters
    ----------
    time_limit : float or None
        Seconds (validated by :func:`as_time_limit`); ``None``: unlimited.

    Examples
    --------
    >>> d = Deadline(None)
    >>> d.expired, d.remaining() == float("inf")
    (False, True)
    """

    __slots__ = ("limit", "_start")

    def __init__(self, time_limit: float | None = None) -> None:
        self.limit = as_time_limit(time_limit)
        self._start = time.perf_counter()

    @classmethod
    def of(cls, value: Deadline | float | None) -> Deadline:
        """``value`` if it is a Deadline already (stages share their caller's budget), else a
        new one."""
        return value if isinstance(value, Deadline) else cls(value)

    @property
    def elapsed(self) -> float:
        """Seconds since the budget started."""
        return time.perf_counter() - self._start

    def remaining(self) -> float:
        """Seconds left (``inf`` without a limit; never negative)."""
        if self.limit is None:
            return math.inf
        return max(0.0, self.limit - self.elapsed)

    @property
    def expired(self) -> bool:
        return self.limit is not None and self.elapsed >= self.limit

    @property
    def limited(self) -> bool:
        return self.limit is not None

    def fraction(self, share: float, floor: float = 0.05) -> float:
        """A share of what is left (at least ``floor`` seconds), for one of several stages."""
        rem = self.remaining()
        return rem if math.isinf(rem) else max(floor, share * rem)

    def ipopt_options(self) -> dict[str, Any]:
        """``{"ipopt.max_wall_time": remaining}`` when limited (empty otherwise)."""
        if self.limit is None:
            return {}
        return {"ipopt.max_wall_time": max(0.01, self.remaining())}

    def sdp_options(self, solver: str) -> dict[str, Any]:
        """The time-limit option of an SDP solver (``CLARABEL``: ``time_limit``, ``SCS``:
        ``time_limit_secs``) when limited."""
        if self.limit is None:
            return {}
        key = {"CLARABEL": "time_limit", "SCS": "time_limit_secs"}.get(str(solver).upper())
        return {} if key is None else {key: max(0.01, self.remaining())}

    def __repr__(self) -> str:
        lim = "none" if self.limit is None else f"{self.limit:g} s"
        return f"Deadline(limit={lim}, elapsed={self.elapsed:.3g} s)"
