"""What running a formulation on a backend returns."""

from __future__ import annotations

import io
import os
import sys
import tempfile
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


@contextmanager
def captured_output() -> Iterator[Captured]:
    """Capture what native solvers print and warn: library code never prints (issue 26).

    Redirects Python's ``sys.stdout`` / ``sys.stderr`` and, at the file-descriptor level, the
    process's descriptors 1 and 2 (CasADi's ``WARNING(...)`` lines, IPOPT's banner, Clarabel's
    and SCS's logs are written there by C++ code that no Python option reaches) to a temporary
    file, and records Python warnings (``warnings.catch_warnings``).  The text and the warnings
    are in the yielded :class:`Captured` after the block; the backends put them in
    ``SolverStats.extra`` (:meth:`Captured.as_extra`).

    The redirect is process-wide while the block runs: output of other threads in that time is
    captured too (the design verbs run their solves in the calling thread).

    Examples
    --------
    >>> with captured_output() as cap:
    ...     print("IPOPT banner")
    >>> cap.lines
    ['IPOPT banner']
    """
    cap = Captured()
    py_out, py_err = sys.stdout, sys.stderr
    for stream in (py_out, py_err):
        try:
            stream.flush()
        except (AttributeError, ValueError, OSError):  # pragma: no cover - closed / odd streams
            pass
    _flush_c_stdio()
    saved: list[int] = []
    buf = io.StringIO()
    with tempfile.TemporaryFile(mode="w+b") as tmp, warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            for fd in (1, 2):
                saved.append(os.dup(fd))
                os.dup2(tmp.fileno(), fd)
        except OSError:  # pragma: no cover - no descriptors 1/2 (embedded interpreters)
            for fd, old in zip((1, 2), saved, strict=False):
                os.dup2(old, fd)
                os.close(old)
            saved = []
        sys.stdout = sys.stderr = buf
        try:
            yield cap
        finally:
            sys.stdout, sys.stderr = py_out, py_err
            _flush_c_stdio()
            for fd, old in zip((1, 2), saved, strict=False):
                os.dup2(old, fd)
                os.close(old)
            tmp.seek(0)
            cap.text = buf.getvalue() + tmp.read().decode("utf-8", errors="replace")
            cap.warnings = [str(w.message) for w in caught]
