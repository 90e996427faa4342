"""The ``optdesign`` command.

Sub-commands (``optdesign -h`` lists them)::

    optdesign list [--kind KIND] [--tag TAG]      problems in the library
    optdesign show PROBLEM                         one problem: plant, targets, references, citation
    optdesign kalman [PROBLEM] [--json]            steady-state Kalman filter of a problem's plant

Bad arguments give a one-line error on stderr and exit code 2 (no traceback).  A number that
starts with a minus sign may follow its option with or without ``=``: ``--poles -1,-2``,
``--poles=-1,-2`` and ``--alpha -1e-3`` all work (argparse alone reads ``-1,-2`` as an option).
"""

from __future__ import annotations

import argparse
import json
import math
import re
import sys
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np

from .. import problems
from . import speech

__all__ = ["CLIError", "Parser", "DEFAULT_PROBLEM", "jsonable", "print_json", "plant_of",
           "join_negative_values", "header", "format_poles", "annotate_frequencies", "print_checks",
           "print_outcome", "add_progress_flag", "pole_scale", "flush", "PROBLEM_HELP"]

#: help text of a PROBLEM argument
PROBLEM_HELP = ("problem name (see `optdesign list`) or a problem file: JSON/TOML with the matrices "
                "(A, C, Q, R, ...), .npz or MATLAB .mat (see `python -m pydoc optdesign.problems`)")

#: The embedded example used when no problem is named (seed 000, Example 1).
DEFAULT_PROBLEM = "chang_lee_1984_ex1"


class CLIError(Exception):
    """A user error reported as one line with exit code 2."""


class Parser(argparse.ArgumentParser):
    def error(self, message: str):  # one line, exit 2, no usage dump
        raise CLIError(message)


def jsonable(x: Any) -> Any:
    """A JSON-ready copy of ``x``: arrays as (nested) lists, complex ones as ``{"re": ..., "im": ...}``,
    numpy scalars as Python ones, and non-finite floats as the strings ``"inf"``, ``"-inf"``,
    ``"nan"`` (JSON has no such numbers)."""
    if isinstance(x, np.ndarray):
        if np.iscomplexobj(x):
            return {"re": jsonable(x.real.tolist()), "im": jsonable(x.imag.tolist())}
        return jsonable(x.tolist())
    if isinstance(x, (np.floating, np.integer, np.bool_)):
        return jsonable(x.item())
    if isinstance(x, float):
        return x if math.isfinite(x) else str(x)
    if isinstance(x, complex):
        return {"re": jsonable(x.real), "im": jsonable(x.imag)}
    if isinstance(x, dict):
        return {str(k): jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonable(v) for v in x]
    return x


def print_json(obj: Any) -> None:
    """Print ``obj`` as strict JSON (:func:`jsonable`), indented."""
    print(json.dumps(jsonable(obj), indent=2, default=str))


# ---------------------------------------------------------------- commands
def plant_of(name: str):
    """The problem ``name`` (a library name or a problem file, :func:`optdesign.problems.load`),
    which must have a valid plant (:class:`CLIError` otherwise)."""
    p = problems.load(name)
    if p.plant is None:
        raise CLIError(f"problem {name!r} has no valid plant ({p.notes or 'see its notes'})")
    return p


def header(prob) -> str:
    """The first line of every command's report: ``problem: NAME -- TITLE``."""
    return f"problem: {prob.name} -- {prob.title}" if prob.title else f"problem: {prob.name}"


def format_poles(poles: Iterable[complex] | None) -> str:
    """Poles in the one order of every command (:func:`optdesign.classical.riccati.sort_poles`: by
    real part, then imaginary part), comma-separated; ``"none"`` for None."""
    return speech.format_poles(poles)  # repeated poles once, with their count: "-1 (x2)"


#: "omega = 4.5e-08 rad/s", "at 3.02 rad/s", "frequency 0 rad/s"
_FREQUENCY = re.compile(r"((?:omega =|frequency|at) )([-+0-9.eE]+)( rad/s)")


def annotate_frequencies(text: str, scale: float) -> str:
    """Say where a frequency in ``text`` is DC: ``omega = 4.5e-08 rad/s`` becomes ``omega = 4.5e-08
    rad/s (DC: zero frequency to the scan's resolution)`` when it is at most ``1e-6 * scale``
    (``scale``: the largest pole modulus of the problem, so the bound follows the plant's own time
    scale; frequency scans move ``w = 0`` off a pole at the origin by ``1e-7`` of that)."""
    bound = 1e-6 * (scale if math.isfinite(scale) and scale > 0 else 1.0)

    def note(m: re.Match) -> str:
        try:
            w = float(m.group(2))
        except ValueError:
            return m.group(0)
        return m.group(0) + (" (DC: zero frequency to the scan's resolution)" if abs(w) <= bound else "")

    return _FREQUENCY.sub(note, text)


def pole_scale(*pole_sets: Any) -> float:
    """The largest modulus among the given pole sets (None entries skipped), 1 if there is none."""
    mags = [np.abs(np.asarray(p, dtype=complex)).max(initial=0.0) for p in pole_sets if p is not None]
    top = float(max(mags, default=0.0))
    return top if top > 0 else 1.0


def print_checks(verification, indent: str = "") -> None:
    """``verification:`` and one check per line, or ``verification: none (no design to check)``."""
    if len(verification):
        print(f"{indent}verification:")
        for c in verification:
            print(f"{indent}  {speech.plain_check(c)}")  # in plain words, with the numbers
    else:
        print(f"{indent}verification: none (no design to check)")


def print_outcome(res, scale: float) -> None:
    """The message, the certificate (once: not again when the message already quotes it) and the
    checks of a result; frequencies at DC said so (:func:`annotate_frequencies`)."""
    message = " ".join(str(getattr(res, "message", "") or "").split())
    cert = getattr(res, "certificate", None)
    cert_text = " ".join(str(cert).split()) if cert is not None else ""
    for quoted in (cert_text, " ".join(str(getattr(cert, "reason", "")).split())):
        if quoted and quoted in message:  # the message quotes the certificate: say it once
            message = message.replace(quoted, "").strip(" :;,")
    status = str(getattr(getattr(res, "status", ""), "value", getattr(res, "status", "")))
    if message and message != status:
        print(annotate_frequencies(message, scale))
    if cert_text:
        print(f"certificate: {annotate_frequencies(cert_text, scale)}")
    print_checks(res.verification)


def add_progress_flag(sp: argparse.ArgumentParser, what: str) -> None:
    """``--progress`` / ``--no-progress`` (default: only when stderr is a terminal)."""
    sp.add_argument("--progress", action=argparse.BooleanOptionalAction, default=None,
                    help=f"progress of {what} on stderr (default: only when stderr is a terminal)")


def flush() -> None:
    """Flush stdout (a header printed before a long run shows at once, even through a pipe)."""
    try:
        sys.stdout.flush()
    except (OSError, ValueError):  # pragma: no cover - stdout closed
        pass


#: a value that starts like a negative number (``-1``, ``-.5``, ``-1,-2``, ``-3+1j, -3-1j``)
_NEGATIVE_VALUE = re.compile(r"-(\d|\.\d)")


def join_negative_values(argv: Sequence[str]) -> list[str]:
    """``["--poles", "-1,-2"]`` -> ``["--poles=-1,-2"]``: a long option followed by a value that
    starts like a negative number is joined to it, so argparse does not read the value as an
    option.  (None of the commands has a positional argument that is a negative number, and a flag
    without a value followed by one gets argparse's own one-line error.)"""
    out: list[str] = []
    args = list(argv)
    i = 0
    while i < len(args):
        a = args[i]
        if (a.startswith("--") and "=" not in a and a != "--" and i + 1 < len(args)
                and _NEGATIVE_VALUE.match(args[i + 1])):
            out.append(f"{a}={args[i + 1]}")
            i += 2
            continue
        if a == "--":  # everything after is positional
            out.extend(args[i:])
            break
        out.append(a)
        i += 1
    return out


