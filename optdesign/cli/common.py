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
from collections.abc import Sequence
from typing import Any

import numpy as np

from .. import problems

__all__ = ["CLIError", "Parser", "DEFAULT_PROBLEM", "jsonable", "print_json", "plant_of",
           "join_negative_values"]

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
    """The library problem ``name``, which must have a valid plant (:class:`CLIError` otherwise)."""
    p = problems.load(name)
    if p.plant is None:
        raise CLIError(f"problem {name!r} has no valid plant ({p.notes or 'see its notes'})")
    return p


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


