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
from collections.abc import Sequence
from typing import Any

from .errors import ValidationError

__all__ = ["Deadline", "as_time_limit", "memory_budget", "dense_kkt_refusal", "dense_time_estimate",
           "dense_time_refusal", "FLOPS_PER_SECOND", "DENSE_N3", "DENSE_N4",
           "MIN_REFUSAL_SECONDS"]


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


#: dense floating-point throughput assumed by the up-front time estimates (one core; measured:
#: Clarabel's KKT factorization with a dense 2485 x 2485 block, n = 70, 1.75 s per iteration)
FLOPS_PER_SECOND = 3e9


def memory_budget() -> int:
    """Bytes one solve may use: half the machine's physical memory (4 GiB where it cannot be read)."""
    import os

    try:
        return int(os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")) // 2
    except (AttributeError, ValueError, OSError):  # pragma: no cover - non-POSIX
        return 4 << 30


def dense_kkt_refusal(size: int, deadline: Deadline | None, what: str, iterations: int = 10) -> str:
    """Why an interior-point solve whose KKT system has a dense ``size x size`` block is not
    attempted ("" when it is affordable): its memory (``16 size^2`` bytes: the matrix and its
    factor) beyond :func:`memory_budget`, or -- under a time limit -- ``iterations`` factorizations
    (``size^3 / 3`` flops each at :data:`FLOPS_PER_SECOND`) beyond the time left.  Issue 26: such
    set-ups ran for minutes past ``time_limit`` and into the kernel's OOM killer."""
    need = 16.0 * size * size
    budget = memory_budget()
    if need > budget:
        return (f"{what} needs about {need / 2**30:.1f} GiB (a dense {size} x {size} KKT block), more than "
                f"the {budget / 2**30:.1f} GiB available: not attempted")
    secs = iterations * size ** 3 / 3.0 / FLOPS_PER_SECOND
    if deadline is not None and deadline.limited and secs > deadline.remaining():
        return (f"{what} needs about {secs:.3g} s ({iterations} factorizations of a dense {size} x {size} "
                f"KKT block), more than the {deadline.remaining():.3g} s left: not attempted")
    return ""


#: CPU seconds of one uninterruptible dense LAPACK call on a plant of order n, as
#: ``DENSE_N3[kind] * n^3 / FLOPS_PER_SECOND``.  The coefficients are *calibrated*, not flop counts:
#: measured with single-threaded OpenBLAS on the development machine at n = 200 and 400, twice
#: (issue 26; ``benchmarks/bench_setup_time_limit.py --calibrate``, results in
#: ``benchmarks/results/setup_time_limit.md``), rounded below the smallest measurement, so that the
#: estimate is a lower bound (a refusal never turns away work that would have fit):
#: ``eigvals`` numpy's eigenvalues (measured 2.3-5), ``eig`` with eigenvectors (3.5-7), ``schur``
#: scipy's real Schur form (3.1-6), ``lyapunov`` a continuous Lyapunov solve (6.5-9),
#: ``hamiltonian_schur`` the Schur form of the 2n x 2n Hamiltonian (19.6-28), ``care_qz`` scipy's
#: ``solve_continuous_are`` (its ordered QZ of the 2n pencil: 130-247)
DENSE_N3: dict[str, float] = {"eigvals": 2.0, "eig": 3.0, "schur": 2.5, "lyapunov": 6.0,
                              "hamiltonian_schur": 18.0, "care_qz": 120.0}
#: the same for work of order n^4 (``DENSE_N4[kind] * n^4 / FLOPS_PER_SECOND``): ``resolvents`` the two
#: complex LU solves per target of the inverse Kalman engine's spectral terms (measured 1.1-2.1,
#: 0.63-1.2, 0.58-0.97 at n = 100, 200, 300, falling with n: 0.4 kept as the lower bound)
DENSE_N4: dict[str, float] = {"resolvents": 0.4}

#: an estimate below this many seconds never refuses: the overrun is then at most this, and a tiny
#: limit on a small plant keeps the verbs' documented behaviour (a first step, a filter returned as
#: ``time_limit``); refusals are for set-ups of seconds to hours (issue 26: n = 5000)
MIN_REFUSAL_SECONDS = 0.1


def dense_time_estimate(calls: Sequence[tuple[str, int]]) -> float:
    """CPU seconds of the dense calls ``[(kind, n), ...]`` (kinds of :data:`DENSE_N3` or
    :data:`DENSE_N4`): a calibrated lower bound, ``sum DENSE_N3[kind] n^3 / FLOPS_PER_SECOND`` (n^4
    for the kinds of ``DENSE_N4``)."""
    return float(sum(DENSE_N3[kind] * float(n) ** 3 if kind in DENSE_N3 else DENSE_N4[kind] * float(n) ** 4
                     for kind, n in calls)) / FLOPS_PER_SECOND


def dense_time_refusal(calls: Sequence[tuple[str, int]], deadline: Deadline | None, what: str) -> str:
    """Why a set-up made of uninterruptible dense calls is not started under ``deadline`` ("" when it
    may fit, or without a limit): the estimate of :func:`dense_time_estimate` beyond the time left
    (and beyond :data:`MIN_REFUSAL_SECONDS`).

    Each call, once started, cannot be stopped (LAPACK has no cancellation), so the only honest way
    to keep ``time_limit`` is not to start one that alone outlasts it (issue 26: at n = 5000 a single
    Schur form takes 1-2 minutes, a CARE hours).  The message gives the estimate and says how it is
    made."""
    if deadline is None or not deadline.limited:
        return ""
    secs = dense_time_estimate(calls)
    left = deadline.remaining()
    if secs <= max(left, MIN_REFUSAL_SECONDS):
        return ""
    kinds = ", ".join(f"{kind} at n = {n}" for kind, n in calls)
    return (f"{what} needs at least {secs:.3g} s of uninterruptible dense linear algebra ({kinds}; "
            f"estimated as c n^3 (n^4) flops at {FLOPS_PER_SECOND:.0e} flop/s, c calibrated from "
            f"measured calls at n = 100-400 on one core), more than the {left:.3g} s left of "
            f"time_limit={deadline.limit:g}: "
            f"not attempted")
