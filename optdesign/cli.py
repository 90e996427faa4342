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
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from .errors import OptDesignError

__all__ = ["main", "build_parser", "register", "CLIError", "DEFAULT_PROBLEM", "jsonable", "print_json",
           "plant_of", "join_negative_values"]

#: The embedded example used when no problem is named (seed 000, Example 1).
DEFAULT_PROBLEM = "chang_lee_1984_ex1"


class CLIError(Exception):
    """A user error reported as one line with exit code 2."""


class _Parser(argparse.ArgumentParser):
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
def cmd_list(args: argparse.Namespace) -> int:
    from . import problems

    names = problems.names(tag=args.tag, kind=args.kind)
    if not names:
        raise CLIError(f"no problem matches kind={args.kind!r} tag={args.tag!r}")
    rows = []
    for n in names:
        p = problems.load(n)
        size = f"n={p.plant.n} p={p.plant.p}" if p.plant is not None else "(no plant)"
        rows.append((n, p.kind, size, p.title))
    if args.json:
        print_json([dict(zip(("name", "kind", "size", "title"), r, strict=True)) for r in rows])
        return 0
    w = [max(len(r[k]) for r in rows) for k in range(3)]
    for r in rows:
        print(f"{r[0]:<{w[0]}}  {r[1]:<{w[1]}}  {r[2]:<{w[2]}}  {r[3]}")
    print(f"\n{len(rows)} problems")
    return 0


def cmd_show(args: argparse.Namespace) -> int:
    from . import problems

    if args.json:
        p = problems.load(args.problem)
        print_json({"name": p.name, "title": p.title, "kind": p.kind, "citation": p.citation,
                     "source": p.source, "notes": p.notes, "tags": p.tags,
                     "plant": None if p.plant is None else p.plant.to_dict(),
                     "targets": p.targets, "references": p.references})
    else:
        print(problems.describe(args.problem))
    return 0


def plant_of(name: str):
    """The library problem ``name``, which must have a valid plant (:class:`CLIError` otherwise)."""
    from . import problems

    p = problems.load(name)
    if p.plant is None:
        raise CLIError(f"problem {name!r} has no valid plant ({p.notes or 'see its notes'})")
    return p


def cmd_kalman(args: argparse.Namespace) -> int:
    from .design.kalman import kalman

    prob = plant_of(args.problem)
    plant = prob.plant
    if not plant.has_noise_model:
        raise CLIError(f"problem {prob.name!r} has no noise model (Q and R): a Kalman filter needs both")
    kf = kalman(plant, method=args.method)
    if args.json:
        print_json({"problem": prob.name, "L": kf.L, "P": kf.P, "poles": kf.poles,
                     "residual": kf.residual, "status": str(kf.status), "success": kf.success,
                     "verification": kf.verification.as_dict()})
    else:
        print(f"problem: {prob.name} — {prob.title}")
        print(kf.summary())
    return 0 if kf.success else 1


Command = Callable[[argparse.Namespace], int]
#: name -> (help, configure(subparser), run).  Other modules may register more commands.
COMMANDS: dict[str, tuple[str, Callable[[argparse.ArgumentParser], None], Command]] = {}


def register(name: str, help: str, configure: Callable[[argparse.ArgumentParser], None],
             run: Command) -> None:
    """Add a sub-command (used by the studies layer)."""
    COMMANDS[name] = (help, configure, run)


def _cfg_list(sp: argparse.ArgumentParser) -> None:
    sp.add_argument("--kind", help="only problems of this kind (e.g. riccati_care, pole_placement)")
    sp.add_argument("--tag", help="only problems with this tag (e.g. seed000) or name prefix (e.g. carex)")
    sp.add_argument("--json", action="store_true", help="machine-readable output")


def _cfg_show(sp: argparse.ArgumentParser) -> None:
    sp.add_argument("problem", help="problem name (see `optdesign list`)")
    sp.add_argument("--json", action="store_true", help="machine-readable output")


def _cfg_kalman(sp: argparse.ArgumentParser) -> None:
    sp.add_argument("problem", nargs="?", default=DEFAULT_PROBLEM,
                    help=f"problem name (default: {DEFAULT_PROBLEM})")
    sp.add_argument("--method", choices=("scipy", "hamiltonian"), default="scipy",
                    help="Riccati solver (default scipy; hamiltonian = ordered Schur of the Hamiltonian)")
    sp.add_argument("--json", action="store_true", help="machine-readable output")


register("list", "list the problems in the library", _cfg_list, cmd_list)
register("show", "show one problem", _cfg_show, cmd_show)
register("kalman", "steady-state Kalman filter of a problem's plant", _cfg_kalman, cmd_kalman)


def _load_plugins() -> None:
    """Import modules that register further commands (absent ones are skipped)."""
    import importlib

    for mod in ("optdesign.studies.cli",):
        try:
            importlib.import_module(mod)
        except ModuleNotFoundError as exc:
            if exc.name != mod:
                raise


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


def build_parser() -> argparse.ArgumentParser:
    _load_plugins()
    parser = _Parser(prog="optdesign", description="State-estimator gains designed by optimization.")
    from . import __version__

    parser.add_argument("--version", action="version", version=f"optdesign {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    for name, (help_, configure, run) in COMMANDS.items():
        sp = sub.add_parser(name, help=help_, description=help_)
        configure(sp)
        sp.set_defaults(_run=run)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``optdesign`` console script; returns the exit code."""
    try:
        parser = build_parser()
        args = parser.parse_args(join_negative_values(sys.argv[1:] if argv is None else argv))
        if not getattr(args, "command", None):
            parser.print_help()
            return 2
        return int(args._run(args) or 0)
    except BrokenPipeError:  # `optdesign list | head`: the reader left; not an error of ours
        import os

        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 0
    except CLIError as exc:
        print(f"optdesign: error: {exc}", file=sys.stderr)
        return 2
    except (OptDesignError, OSError) as exc:
        print(f"optdesign: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:  # pragma: no cover
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
