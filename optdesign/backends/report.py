"""What running a formulation on a backend returns, and what the solvers print.

**Library code never prints** (issue 26, item 3).  Every native solve runs inside
:func:`captured_output`: what CasADi, IPOPT, cvxpy, Clarabel and SCS write to stdout / stderr (at
the file-descriptor level: C++ code writes there) and the Python warnings they raise go to the
result's ``solver_stats.extra`` (``solver_output``, ``solver_warnings``), never to the terminal.

**One warning of our own where the user must know.**  Most chatter is noise (banners, iteration
logs).  Some of it means the answer is less trustworthy than its status says -- the lines matched by
:data:`DOUBT_PATTERNS`: cvxpy's "Solution may be inaccurate", CasADi's "Failed to calculate
multipliers", IPOPT's restoration failure.  The rule:

* the matched lines of a call are recorded, counted, in its result's
  ``solver_stats.extra["solver_doubts"]``;
* a design call (a verb, a problem object's ``solve``, or a backend function called directly) that
  returns a **successful** answer with status ``optimal`` or ``solved`` while such a line of the
  solver that produced it (the family of its ``solver_stats.backend``: CasADi/IPOPT for ``ipopt``,
  cvxpy for ``clarabel`` and ``scs``) was captured during the call emits exactly **one**
  :class:`~optdesign.errors.OptDesignWarning`, whose text names the solver(s) and what the line
  means, and points to ``solver_doubts``; the solver's own text is never printed;
* a call that does not succeed, or whose status is ``optimal_inaccurate``, emits none: its status
  and message already say so; nor does an answer of another solver (an inaccurate warm-start SDP
  before an NLP, an SLSQP answer after an IPOPT stage);
* nested calls (a verb calling a problem's ``solve`` calling a backend; ``lqr_for_poles`` calling
  ``kalman_for_poles``) count as one: the outermost decides (:func:`one_warning_per_call`).

The doubts of a call are those of every solve of the answering solver it ran (a discarded
start's included: a multi-start result does not keep each start's output).  Calls on threads of
one pool share the process-wide redirect, so a doubt may be counted in the call that finished
last.
"""

from __future__ import annotations

import contextvars
import functools
import io
import os
import re
import sys
import tempfile
import threading
import warnings
from collections import Counter
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, TypeVar

from ..errors import OptDesignWarning
from ..results import SolverStats, Status

__all__ = ["SolverReport", "Captured", "captured_output", "MAX_CAPTURED_LINES", "DOUBT_PATTERNS",
           "one_warning_per_call"]

F = TypeVar("F", bound=Callable[..., Any])


@dataclass(frozen=True)
class SolverReport:
    """Outcome of one backend run.

    Attributes
    ----------
    status : Status
        Mapped status (see :mod:`optdesign.backends.status`).
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


class Captured:
    """What a native solve printed and warned (filled when :func:`captured_output` exits).

    Attributes
    ----------
    text : str
        Everything written to stdout / stderr (Python objects and the process's file descriptors
        1 and 2) during the block.
    warnings : list of str
        The messages of the Python warnings raised during the block (cvxpy's "Solution may be
        inaccurate", ...).
    """

    __slots__ = ("text", "warnings")

    def __init__(self) -> None:
        self.text = ""
        self.warnings: list[str] = []

    @property
    def lines(self) -> list[str]:
        """The non-empty lines of ``text``."""
        return [ln for ln in self.text.splitlines() if ln.strip()]

    @property
    def doubts(self) -> list[tuple[str, str, str]]:
        """``(solver, meaning, line)`` for each captured line or warning that casts doubt on the
        answer (:data:`DOUBT_PATTERNS`), in order."""
        found = []
        for line in [*self.lines, *self.warnings]:
            for solver, pattern, meaning in DOUBT_PATTERNS:
                if pattern.search(line):
                    found.append((solver, meaning, _CASADI_STAMP.sub("", " ".join(line.split()))[:200]))
                    break
        return found

    def as_extra(self) -> dict[str, Any]:
        """``{"solver_output": [...], "solver_warnings": [...]}`` with what is non-empty (for
        ``SolverStats.extra``)."""
        out: dict[str, Any] = {}
        if self.lines:
            out["solver_output"] = self.lines[-MAX_CAPTURED_LINES:]
        if self.warnings:
            out["solver_warnings"] = self.warnings[-MAX_CAPTURED_LINES:]
        return out


#: lines of solver chatter kept per solve (the last ones: the final status is what matters)
MAX_CAPTURED_LINES = 50

#: captured lines that make a successful answer less trustworthy: (solver, regex, what it means)
DOUBT_PATTERNS: tuple[tuple[str, re.Pattern[str], str], ...] = (
    ("cvxpy", re.compile(r"solution may be inaccurate", re.I),
     "reported that its solution may be inaccurate"),
    ("casadi", re.compile(r"failed to calculate multipliers", re.I),
     "could not calculate the multipliers (dual variables) of its solution"),
    ("ipopt", re.compile(r"restoration (phase )?failed|restoration_failed", re.I),
     "failed in its restoration phase"),
)

#: the time stamp CasADi puts before its WARNING(...) lines (dropped: the same line repeats)
_CASADI_STAMP = re.compile(r"^CasADi - \d{4}-\d\d-\d\d \d\d:\d\d:\d\d ")

#: the doubts captured during the current design call (None outside one): see one_warning_per_call
_DOUBTS: contextvars.ContextVar[list[tuple[str, str, str]] | None] = contextvars.ContextVar(
    "solver_doubts", default=None)


def _flush_c_stdio() -> None:
    """Flush the C library's stdout / stderr buffers (native solvers write through them)."""
    try:
        import ctypes

        ctypes.CDLL(None).fflush(None)
    except (OSError, AttributeError):  # pragma: no cover - no C library to flush (non-POSIX)
        pass


#: the one process-wide redirect of :func:`captured_output`: nested or concurrent blocks (a sweep on a
#: thread pool) share it -- the first to enter redirects, the last to leave restores and reads
_CAPTURE_LOCK = threading.Lock()
_CAPTURE: dict[str, Any] = {"depth": 0}


def _redirect() -> dict[str, Any]:
    """Start the process-wide redirect (called under the lock by the first block)."""
    state: dict[str, Any] = {"py": (sys.stdout, sys.stderr), "saved": [], "buf": io.StringIO()}
    for stream in state["py"]:
        try:
            stream.flush()
        except (AttributeError, ValueError, OSError):  # pragma: no cover - closed / odd streams
            pass
    _flush_c_stdio()
    state["tmp"] = tempfile.TemporaryFile(mode="w+b")
    state["warn"] = warnings.catch_warnings(record=True)
    state["caught"] = state["warn"].__enter__()
    warnings.simplefilter("always")
    try:
        for fd in (1, 2):
            state["saved"].append(os.dup(fd))
            os.dup2(state["tmp"].fileno(), fd)
    except OSError:  # pragma: no cover - no descriptors 1/2 (embedded interpreters)
        for fd, old in zip((1, 2), state["saved"], strict=False):
            os.dup2(old, fd)
            os.close(old)
        state["saved"] = []
    sys.stdout = sys.stderr = state["buf"]
    return state


def _restore(state: dict[str, Any]) -> tuple[str, list[str]]:
    """End the redirect (called under the lock by the last block): (text, warnings) captured."""
    sys.stdout, sys.stderr = state["py"]
    _flush_c_stdio()
    for fd, old in zip((1, 2), state["saved"], strict=False):
        os.dup2(old, fd)
        os.close(old)
    tmp = state["tmp"]
    tmp.seek(0)
    text = state["buf"].getvalue() + tmp.read().decode("utf-8", errors="replace")
    tmp.close()
    caught = [str(w.message) for w in state["caught"]]
    state["warn"].__exit__(None, None, None)
    return text, caught


@contextmanager
def captured_output() -> Iterator[Captured]:
    """Capture what native solvers print and warn: library code never prints (issue 26).

    Redirects Python's ``sys.stdout`` / ``sys.stderr`` and, at the file-descriptor level, the
    process's descriptors 1 and 2 (CasADi's ``WARNING(...)`` lines, IPOPT's banner, Clarabel's
    and SCS's logs are written there by C++ code that no Python option reaches) to a temporary
    file, and records Python warnings (``warnings.catch_warnings``).  The text and the warnings
    are in the yielded :class:`Captured` after the block; the backends put them in
    ``SolverStats.extra`` (:meth:`Captured.as_extra`).

    The redirect is process-wide and shared: blocks that overlap -- nested, or on several threads at
    once (a sweep on a thread pool) -- use one redirect, set up by the first to enter and undone by
    the last to leave, which receives everything captured meanwhile (the others' ``text`` is empty).
    So the streams are always restored, whatever order the threads finish in.

    Examples
    --------
    >>> with captured_output() as cap:
    ...     print("IPOPT banner")
    >>> cap.lines
    ['IPOPT banner']
    """
    cap = Captured()
    with _CAPTURE_LOCK:
        if _CAPTURE["depth"] == 0:
            _CAPTURE["state"] = _redirect()
        _CAPTURE["depth"] += 1
    try:
        yield cap
    finally:
        with _CAPTURE_LOCK:
            _CAPTURE["depth"] -= 1
            if _CAPTURE["depth"] == 0:
                cap.text, cap.warnings = _restore(_CAPTURE.pop("state"))
        doubts = _DOUBTS.get()
        if doubts is not None:
            doubts.extend(cap.doubts)


#: which captured solvers' doubts concern an answer, by (a part of) its ``solver_stats.backend``
_FAMILIES: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("ipopt", ("casadi", "ipopt")), ("casadi", ("casadi", "ipopt")),
    ("clarabel", ("cvxpy",)), ("scs", ("cvxpy",)), ("cvxpy", ("cvxpy",)),
)


def _stats(result: Any) -> SolverStats | None:
    stats = getattr(result, "solver_stats", None) or getattr(result, "stats", None)
    return stats if isinstance(stats, SolverStats) else None


def _doubts_of_answer(result: Any, doubts: list[tuple[str, str, str]]) -> list[tuple[str, str, str]]:
    """The doubts that concern ``result``: none unless it is returned as a success with a status
    claiming full accuracy (``optimal`` or ``solved``: ``optimal_inaccurate`` already says it), and
    only those of the solver family that produced it (its ``solver_stats.backend``: an IPOPT answer
    is not doubted by an inaccurate warm-start SDP, nor an SLSQP answer by either)."""
    if not (getattr(result, "success", None) is True or not hasattr(result, "success")):
        return []
    try:
        status = Status(getattr(result, "status", None))
    except ValueError:
        return []
    if status not in (Status.OPTIMAL, Status.SOLVED):
        return []
    stats = _stats(result)
    backend = stats.backend.lower() if stats is not None else ""
    families = {f for key, fams in _FAMILIES if key in backend for f in fams}
    return [d for d in doubts if d[0] in families]


def _record(result: Any, doubts: list[tuple[str, str, str]]) -> None:
    """The matched lines of a call, counted, in its result's ``solver_stats.extra["solver_doubts"]``
    (``extra`` is a plain dict)."""
    stats = _stats(result)
    if stats is None:
        return
    lines = Counter(f"{solver}: {line}" for solver, _, line in doubts)   # insertion-ordered
    stats.extra["solver_doubts"] = [text + (f" (x{k})" if k > 1 else "")
                                    for text, k in list(lines.items())[:MAX_CAPTURED_LINES]]


def _warn(where: str, doubts: list[tuple[str, str, str]], stacklevel: int) -> None:
    said: dict[tuple[str, str], int] = {}
    for solver, meaning, _ in doubts:
        said[(solver, meaning)] = said.get((solver, meaning), 0) + 1
    what = "; ".join(f"{solver} {meaning}" + (f" ({k} times)" if k > 1 else "")
                     for (solver, meaning), k in said.items())
    warnings.warn(f"{where}: the answer is returned as a success, but during this call {what}. Check "
                  f"it before relying on it: the solver's lines are in "
                  f"result.solver_stats.extra['solver_doubts']", OptDesignWarning, stacklevel=stacklevel)


def one_warning_per_call(fn: F) -> F:
    """Make ``fn`` (a design verb, a problem's ``solve``, a backend function) one *call* in the
    sense of the rule above: the doubts captured while it runs are collected, and when it returns
    a success with any, one :class:`~optdesign.errors.OptDesignWarning` is emitted (at the
    caller's line) and the matched lines are put in its ``solver_stats.extra["solver_doubts"]``.
    Inside another such call it only collects: the outermost decides."""
    where = fn.__qualname__.replace(".<locals>", "")

    @functools.wraps(fn)
    def call(*args: Any, **kwargs: Any) -> Any:
        if _DOUBTS.get() is not None:
            return fn(*args, **kwargs)
        doubts: list[tuple[str, str, str]] = []
        token = _DOUBTS.set(doubts)
        try:
            result = fn(*args, **kwargs)
        finally:
            _DOUBTS.reset(token)
        if doubts:
            _record(result, doubts)
            concern = _doubts_of_answer(result, doubts)
            if concern:
                _warn(where, concern, stacklevel=3)
        return result

    return call  # type: ignore[return-value]
