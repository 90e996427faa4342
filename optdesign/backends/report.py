"""What running a formulation on a backend returns."""

from __future__ import annotations

import io
import os
import sys
import tempfile
import threading
import warnings
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

from ..results import SolverStats, Status

__all__ = ["SolverReport", "Captured", "captured_output", "MAX_CAPTURED_LINES"]


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
