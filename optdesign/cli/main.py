"""The ``optdesign`` console script: the parser (every command registered statically) and ``main``."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from .. import __version__
from ..errors import OptDesignError
from . import basic, design, noise
from .common import CLIError, Parser, join_negative_values

__all__ = ["build_parser", "main"]


def build_parser() -> argparse.ArgumentParser:
    parser = Parser(prog="optdesign", description="State-estimator gains designed by optimization.")
    parser.add_argument("--version", action="version", version=f"optdesign {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=Parser)
    for name, help_, configure, run in (*basic.COMMANDS, *design.COMMANDS):
        sp = sub.add_parser(name, help=help_, description=help_)
        configure(sp)
        sp.set_defaults(_run=run)
    noise.register(sub)
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
