"""The ``optdesign`` command (the top layer: it may use every other).

::

    optdesign list [--kind KIND] [--tag TAG]     the problem library
    optdesign show PROBLEM                       one problem
    optdesign kalman [PROBLEM] [--json]          steady-state Kalman filter of a problem's plant
    optdesign design PROBLEM --method M [...]    any design verb
    optdesign study SPEC.toml                    a sweep described in a file
    optdesign reproduce [PAPER] [--out DIR]      every seed paper's examples and figures (existing
                                                 files kept unless --overwrite)

PROBLEM is a library name (``optdesign list``) or a problem file of the user's (JSON/TOML with the
matrices, ``.npz``, MATLAB ``.mat``; :func:`optdesign.problems.load_file`).  Every command is
registered statically in :func:`build_parser` (modules ``basic`` and ``design``).
"""

from .common import DEFAULT_PROBLEM, CLIError, join_negative_values, jsonable, plant_of, print_json
from .main import build_parser, main

__all__ = ["main", "build_parser", "CLIError", "DEFAULT_PROBLEM", "jsonable", "print_json", "plant_of",
           "join_negative_values"]
