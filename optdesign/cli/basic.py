"""The ``list``, ``show`` and ``kalman`` commands."""

from __future__ import annotations

import argparse
from typing import Any

import numpy as np

from .. import problems
from ..design.kalman import kalman, kalmd
from .common import (
    DEFAULT_PROBLEM,
    PROBLEM_HELP,
    CLIError,
    format_poles,
    header,
    plant_of,
    print_checks,
    print_json,
)
from .speech import plant_lines


def cmd_list(args: argparse.Namespace) -> int:
    names = problems.names(tag=args.tag, kind=args.kind)
    if not names:
        raise CLIError(_no_match(args.tag, args.kind))
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


def _no_match(tag: str | None, kind: str | None) -> str:
    """Why ``list`` found nothing, with the valid tags and kinds (and the near ones first)."""
    tags: set[str] = set()
    kinds: set[str] = set()
    for n in problems.names():
        p = problems.load(n)
        tags.update(p.tags)
        kinds.add(p.kind)
    given = " ".join(f"{k}={v!r}" for k, v in (("kind", kind), ("tag", tag)) if v is not None)
    parts = [f"no problem matches {given}"]
    if tag is not None:
        near = sorted(t for t in tags if t.startswith(tag) or tag in t)
        if near and tag not in tags:
            parts[0] += f" (did you mean {', '.join(near)}?)"
        parts.append(f"tags: {', '.join(sorted(tags))} (a tag also matches a name prefix, e.g. carex)")
    if kind is not None:
        parts.append(f"kinds: {', '.join(sorted(kinds))}")
    return "; ".join(parts)


def cmd_show(args: argparse.Namespace) -> int:
    if args.json:
        p = problems.load(args.problem)
        print_json({"name": p.name, "title": p.title, "kind": p.kind, "citation": p.citation,
                     "source": p.source, "notes": p.notes, "tags": p.tags,
                     "plant": None if p.plant is None else p.plant.to_dict(),
                     "targets": p.targets, "references": p.references})
    else:
        print(problems.describe(args.problem))
    return 0


def cmd_kalman(args: argparse.Namespace) -> int:
    prob = plant_of(args.problem)
    plant = prob.plant
    if not plant.has_noise_model:
        raise CLIError(f"problem {prob.name!r} has no noise model (Q and R): a Kalman filter needs both")
    opts: dict[str, Any] = {"sensors": _int_list("--sensors", args.sensors),
                            "known": _int_list("--known", args.known)}
    if args.kalmd is not None:
        kf = kalmd(plant, args.kalmd, method=args.method, **opts)
    else:
        kf = kalman(plant, method=args.method, **opts)
    if args.json:
        print_json({"problem": prob.name, "L": kf.L, "P": kf.P, "poles": kf.poles,
                     "residual": kf.residual, "status": str(kf.status), "success": kf.success,
                     "verification": kf.verification.as_dict()})
    else:
        print(header(prob))
        print("\n".join(plant_lines(plant)))
        if args.kalmd is not None:
            print(f"sampled at Ts = {args.kalmd:g} (kalmd: the discrete filter of the continuous plant)")
        domain = f"discrete, dt = {kf.plant.dt:g}" if kf.plant.is_discrete else "continuous"
        print(f"Kalman filter ({domain}, Riccati solver {args.method}): status {kf.status}, "
              f"success {kf.success}")
        for name in ("L", "P"):
            X = getattr(kf, name)
            with np.printoptions(precision=6, suppress=True, linewidth=100):
                print(f"  {name} = " + np.array2string(X, prefix=f"  {name} = "))
        print(f"  poles of A - L C: {format_poles(kf.poles)}")
        print(f"  {kf.message}")
        print_checks(kf.verification, indent="  ")
    return 0 if kf.success else 1


def _cfg_list(sp: argparse.ArgumentParser) -> None:
    sp.add_argument("--kind", help="only problems of this kind (e.g. riccati_care, pole_placement)")
    sp.add_argument("--tag", help="only problems with this tag (e.g. seed000) or name prefix (e.g. carex)")
    sp.add_argument("--json", action="store_true", help="machine-readable output")


def _cfg_show(sp: argparse.ArgumentParser) -> None:
    sp.add_argument("problem", help=PROBLEM_HELP)
    sp.add_argument("--json", action="store_true", help="machine-readable output")


def _cfg_kalman(sp: argparse.ArgumentParser) -> None:
    sp.add_argument("problem", nargs="?", default=DEFAULT_PROBLEM,
                    help=f"{PROBLEM_HELP} (default: {DEFAULT_PROBLEM})")
    sp.add_argument("--method", choices=("scipy", "hamiltonian"), default="scipy",
                    help="Riccati solver (default scipy; hamiltonian = ordered Schur of the Hamiltonian)")
    sp.add_argument("--sensors", help="measured outputs, e.g. --sensors 0,2 (MATLAB's sensors; default all)")
    sp.add_argument("--known", help="known inputs, e.g. --known 0 (MATLAB's known; default all of B)")
    sp.add_argument("--kalmd", type=float, metavar="TS",
                    help="a discrete filter for the continuous plant at sample time TS (MATLAB's kalmd)")
    sp.add_argument("--json", action="store_true", help="machine-readable output")


def _int_list(flag: str, text: str | None) -> list[int] | None:
    """``"0,2"`` -> ``[0, 2]`` (None for None)."""
    if text is None:
        return None
    try:
        return [int(t) for t in text.replace(";", ",").split(",") if t.strip()]
    except ValueError:
        raise CLIError(f"{flag} must be comma-separated output/input indices, e.g. 0,2; "
                       f"found {text!r}") from None


#: (name, help, configure(subparser), run)
COMMANDS = (
    ("list", "list the problems in the library", _cfg_list, cmd_list),
    ("show", "show one problem", _cfg_show, cmd_show),
    ("kalman", "steady-state Kalman filter of a problem's plant", _cfg_kalman, cmd_kalman),
)
