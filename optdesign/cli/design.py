"""The ``design``, ``study`` and ``reproduce`` commands.

::

    optdesign design PROBLEM --method METHOD [--poles ...] [--region ...] [--json] [--progress]
    optdesign study SPEC.toml [--executor ...] [--workers N] [--out DIR] [--allow-failures]
                              [--no-figures] [--progress | --no-progress]
    optdesign reproduce [PAPER ...] [--out DIR] [--overwrite] [--quick] [--progress | --no-progress]

PROBLEM is a library name or a problem file (JSON/TOML, .npz, MATLAB .mat:
:func:`optdesign.problems.load_file`).  Every user error is a one-line message with exit code 2
(:class:`optdesign.cli.CLIError`, or an :class:`~optdesign.errors.OptDesignError` such as a bad
spec or problem file); a design that runs but does not succeed exits with 1, as does a study with a
failed point (unless ``--allow-failures``) and a reproduction with a missing or failing paper.
Progress goes to stderr, by default only when stderr is a terminal; results go to stdout and to the
output folder (relative to the current directory).
"""

from __future__ import annotations

import argparse
import dataclasses
import inspect
import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from .._validate import as_poles
from ..classical.riccati import sort_poles
from ..design.feedback import lqr_for_poles, place, well_conditioned_feedback
from ..design.inverse_kalman import kalman_for_poles
from ..design.kalman import kalman
from ..design.verification import stability_check
from ..design.well_conditioned import well_conditioned_kalman, well_conditioned_observer
from ..errors import ValidationError
from ..model.plant import Plant
from ..model.regions import Disk, HalfPlane, Sector
from ..plot.figures import FIGURE_FORMATS
from ..results import Verification
from ..studies.designers import gain_values, place_baseline
from ..studies.output import output_folder
from ..studies.reproduce import PAPERS, paper_id, reproduce_all
from ..studies.spec import format_region, load_spec, parse_poles, parse_region, require_matplotlib, run_spec
from .common import (
    PROBLEM_HELP,
    CLIError,
    add_progress_flag,
    flush,
    format_poles,
    header,
    plant_of,
    pole_scale,
    print_json,
    print_outcome,
)

__all__ = ["cmd_design", "cmd_study", "cmd_reproduce", "DESIGN_METHODS", "region_from_args",
           "with_stability_check"]

#: ``--method`` choices of ``optdesign design``
DESIGN_METHODS = ("kalman", "inverse", "well_conditioned", "wc_kalman", "place")

_OBJECTIVES = {
    "well_conditioned": ("kappa2", "kappa_fro", "eta"),
    "wc_kalman": ("eta", "kappa2", "kappa_fro"),
    "inverse": ("min_trace", "nearest", "feasibility"),
}

_REGION_HELP = """\
pole regions (--region): members joined by '&', each SHAPE:NUMBERS --
  halfplane:ALPHA        Re s <= -ALPHA (decay rate)
  sector:ZETA            damping ratio >= ZETA (0 < ZETA < 1)
  disk:RADIUS            |s| <= RADIUS  (disk:CENTER,RADIUS for another centre)
  strip:LO,HI            LO <= Re s <= HI
  hstrip:OMEGA           |Im s| <= OMEGA
  ellipse:CENTER,A,B     ((Re s - CENTER)/A)^2 + (Im s/B)^2 <= 1
  stable                 Re s <= 0
--alpha A, --zeta Z, --radius R add halfplane:A, sector:Z, disk:R to the region.

poles (--poles): comma-separated, complex ones as -3+1j: --poles -1,-2,-3+1j,-3-1j (or --poles=...,
  or --poles "-1, -2"); every pole must be stable for an observer (place reports unstable ones as
  not successful).

methods:
  kalman            steady-state Kalman filter (needs the problem's Q and R)
  inverse           Q >= 0 whose Kalman filter has the target poles (kalman_for_poles; --poles or the
                    problem's target poles)
  well_conditioned  observer gain minimizing kappa2 (or --objective) with fixed --poles or poles free
                    in a region (--region / --alpha / --zeta / --radius)
  wc_kalman         Kalman filter (designed noise Q) minimizing eta (or --objective), optional region
  place             robust pole placement baseline (scipy place_poles, --poles or the target poles)

examples:
  optdesign design compleib_dis2 --method well_conditioned --region "halfplane:1 & sector:0.7 & disk:20"
  optdesign design chang_lee_1984_ex1 --method inverse --json
  optdesign design pp_knv1985_ex1 --method place
"""


def region_from_args(args: argparse.Namespace, discrete: bool = False):
    """The region of ``--region`` / ``--alpha`` / ``--zeta`` / ``--radius`` (None if none given)."""
    members = []
    if args.region is not None:
        try:
            members.append(parse_region(args.region, field="--region"))
        except ValidationError as exc:
            raise CLIError(str(exc)) from None
    try:
        if args.alpha is not None:
            members.append(HalfPlane(args.alpha))
        if args.zeta is not None:
            members.append(Sector.from_damping(args.zeta))
        if args.radius is not None:
            members.append(Disk(0.0, args.radius))
    except ValidationError as exc:
        flag = "--zeta" if "zeta" in str(exc) else "--radius" if "adius" in str(exc) else "--alpha"
        raise CLIError(f"{flag}: {' '.join(str(exc).split())}") from None
    if not members:
        return None
    if discrete and (args.alpha is not None or args.zeta is not None):
        raise CLIError("--alpha/--zeta describe continuous-time regions; this plant is discrete "
                       "(use --region disk:R)")
    region = members[0]
    try:
        for m in members[1:]:
            region = region & m
    except ValidationError as exc:
        raise CLIError(f"--region: {' '.join(str(exc).split())}") from None
    return region


def with_stability_check(plant, res):
    """``res`` (a placement result) with the ``stability_margin`` check of ``A - L C`` added to its
    verification (:func:`optdesign.design.verification.stability_check`: stable in the plant's time
    domain, ``Re < 0`` or ``|z| < 1``, by more than the rounding level of the poles).

    A pole placement is no observer unless its error dynamics are stable: unstable requested poles
    are placed (and shown), but the design is reported as not successful, with the reason.
    """
    if res.L is None:
        return res
    check = stability_check(plant.A - res.L @ plant.C, plant.is_discrete)
    message = res.message
    if not check.passed:
        domain = "|z| < 1" if plant.is_discrete else "Re s < 0"
        message += (f"; A - L C is not stable (stability margin {check.value:.4g}): the requested poles "
                    f"are not all in {domain}, so this gain is no observer")
    return dataclasses.replace(res, verification=res.verification + Verification.of([check]), message=message)


def _sorted(poles) -> np.ndarray | None:
    """Poles in the one order of every command (JSON too); None stays None."""
    return None if poles is None else sort_poles(np.asarray(poles, dtype=complex).ravel())


def _matrix(name: str, X) -> None:
    with np.printoptions(precision=6, linewidth=100, suppress=False):
        print(f"{name} =", np.array2string(np.asarray(X), prefix=f"{name} = "))


def _with_progress(fn, kw: dict[str, Any], progress: bool | None) -> dict[str, Any]:
    """``kw`` plus ``progress=`` (None: only on a terminal) when the verb takes it: multi-start
    designs report their starts on stderr."""
    if "progress" in inspect.signature(fn).parameters:
        return {**kw, "progress": progress}
    return kw


# --------------------------------------------------------------------------- design


def _cfg_design(sp: argparse.ArgumentParser) -> None:
    sp.formatter_class = argparse.RawDescriptionHelpFormatter
    sp.epilog = _REGION_HELP
    sp.add_argument("problem", help=PROBLEM_HELP)
    sp.add_argument("--method", required=True, choices=DESIGN_METHODS, help="design verb (see below)")
    sp.add_argument("--poles", help="target poles, e.g. --poles -1,-2,-3+1j,-3-1j (default: the "
                                    "problem's)")
    sp.add_argument("--region", help="pole region, e.g. \"halfplane:1.5 & sector:0.7 & disk:20\" (see below)")
    sp.add_argument("--alpha", type=float, help="decay rate: poles with Re s <= -ALPHA")
    sp.add_argument("--zeta", type=float, help="damping ratio: poles with damping >= ZETA (0 < ZETA < 1)")
    sp.add_argument("--radius", type=float, help="poles with |s| <= RADIUS")
    sp.add_argument("--objective", help="well_conditioned: kappa2|kappa_fro|eta; wc_kalman: "
                                        "eta|kappa2|kappa_fro; "
                                        "inverse: min_trace|nearest|feasibility")
    sp.add_argument("--max-gain", type=float, dest="max_gain", help="well_conditioned: bound on ||L||_2")
    sp.add_argument("--starts", type=int, help="well_conditioned / wc_kalman: number of multi-start runs")
    sp.add_argument("--seed", type=int, default=0, help="seed of every random choice (default 0)")
    sp.add_argument("--inverse-method", dest="inverse_method", choices=("auto", "sdp", "nlp", "sequential"),
                    help="inverse: algorithm of kalman_for_poles (default auto)")
    sp.add_argument("--riccati", choices=("scipy", "hamiltonian"), help="kalman: Riccati solver (default "
                                                                        "scipy)")
    sp.add_argument("--feedback", action="store_true",
                    help="controller mode (state feedback u = -K x by duality): place, well_conditioned and "
                         "inverse (the inverse LQR) on (A, B) -- the problem's data A, B for pole-placement "
                         "problems, else the plant's A, B")
    add_progress_flag(sp, "the multi-start runs")
    sp.add_argument("--json", action="store_true", help="machine-readable output")


_APPLIES = {
    "poles": ("inverse", "well_conditioned", "place"),
    "region": ("well_conditioned", "wc_kalman"),
    "objective": ("well_conditioned", "wc_kalman", "inverse"),
    "max_gain": ("well_conditioned",),
    "starts": ("well_conditioned", "wc_kalman"),
    "inverse_method": ("inverse",),
    "riccati": ("kalman",),
}


def _check_applicable(args: argparse.Namespace) -> None:
    flags = {"poles": "--poles", "region": "--region", "objective": "--objective", "max_gain": "--max-gain",
             "starts": "--starts", "inverse_method": "--inverse-method", "riccati": "--riccati"}
    given = {k: getattr(args, k) is not None for k in flags}
    given["region"] = any(getattr(args, k) is not None for k in ("region", "alpha", "zeta", "radius"))
    for k, ok in _APPLIES.items():
        if given[k] and args.method not in ok:
            what = flags[k] if k != "region" else "--region/--alpha/--zeta/--radius"
            raise CLIError(f"{what} does not apply to --method {args.method} (it applies to {', '.join(ok)})")
    if args.objective is not None and args.objective not in _OBJECTIVES[args.method]:
        raise CLIError(f"--objective: {args.objective!r} is not an objective of --method {args.method}; "
                       "expected "
                       f"{', '.join(_OBJECTIVES[args.method])}")
    if args.starts is not None and args.starts < 1:
        raise CLIError(f"--starts must be >= 1; found {args.starts}")
    if args.seed < 0:
        raise CLIError(f"--seed must be >= 0; found {args.seed}")
    for k in ("max_gain", "radius"):
        v = getattr(args, k)
        if v is not None and not (math.isfinite(v) and v > 0):
            raise CLIError(f"--{k.replace('_', '-')} must be a positive number; found {v}")
    if args.alpha is not None and not math.isfinite(args.alpha):
        raise CLIError(f"--alpha must be finite; found {args.alpha}")


def _target_poles(args: argparse.Namespace, prob) -> np.ndarray:
    if args.poles is not None:
        try:
            poles = parse_poles(args.poles, field="--poles")
            return as_poles("--poles", poles, prob.plant.n)
        except ValidationError as exc:
            msg = " ".join(str(exc).split())
            raise CLIError(msg if msg.startswith("--poles") else f"--poles: {msg}") from None
    if "poles" not in prob.targets:
        raise CLIError(f"problem {prob.name!r} has no target poles: give --poles")
    return np.asarray(prob.targets["poles"], dtype=complex).ravel()


def _feedback_system(prob) -> tuple[np.ndarray, np.ndarray, float | None]:
    """(A, B, dt) of a problem for controller mode: the source data of a pole-placement problem
    (stored as state feedback; its plant is the observer dual), else the plant with its B."""
    data = getattr(prob, "data", None) or {}
    if "A" in data and "B" in data and prob.kind == "pole_placement":
        return np.asarray(data["A"], dtype=float), np.asarray(data["B"], dtype=float), prob.plant.dt
    plant = prob.plant
    if plant.B is None:
        raise CLIError(f"problem {prob.name!r} has no input matrix B: --feedback needs (A, B)")
    return plant.A, plant.B, plant.dt


def _design_feedback(args: argparse.Namespace, prob) -> tuple[Any, dict[str, Any]]:
    """``--feedback``: the controller designs by duality; returns (result, extra output)."""
    A, B, dt = _feedback_system(prob)
    fplant = Plant(A, np.eye(A.shape[0]), B=B, dt=dt, name=prob.name)
    method = args.method
    res: Any
    if method == "place":
        target = _target_poles(args, prob)
        res = place(A, B, target, dt=dt, seed=args.seed)
        return res, {"target": target, "K": res.gain_matrix, "poles": res.computed_poles}
    if method == "inverse":
        target = _target_poles(args, prob)
        opts = {"objective": args.objective} if args.objective else {}
        res = lqr_for_poles(fplant, target, **opts)
        return res, {"target": target, "K": res.K, "Q": res.Q, "poles": getattr(res, "poles", None),
                     "certificate": res.certificate.as_dict() if res.certificate is not None else None}
    if method == "well_conditioned":
        region = region_from_args(args, dt is not None)
        kw: dict[str, Any] = {"seed": args.seed}
        for k in ("objective", "max_gain", "starts"):
            if getattr(args, k) is not None:
                kw[k] = getattr(args, k)
        if region is not None:
            res = well_conditioned_feedback(fplant, region=region, **kw)
            return res, {"region": region.to_dict(), "K": res.K, "poles": res.poles}
        target = _target_poles(args, prob)
        res = well_conditioned_feedback(fplant, poles=target, **kw)
        return res, {"target": target, "K": res.K, "poles": res.poles}
    raise CLIError(f"--feedback applies to --method place, well_conditioned and inverse; found {method!r}")


def _print_feedback(prob, method: str, res, out: dict[str, Any]) -> None:
    print(header(prob))
    print(f"method: {method} (state feedback)    status: {out['status']}    success: {out['success']}")
    if out.get("target") is not None:
        print(f"target poles: {format_poles(out['target'])}")
    if out.get("region"):
        print(f"region: {format_region(res.region) if hasattr(res, 'region') else out['region']}")
    for k in ("K", "Q"):
        if out.get(k) is not None:
            _matrix(k, out[k])
    if out.get("poles") is not None:
        print(f"poles of A - B K: {format_poles(out['poles'])}")
    print_outcome(res, pole_scale(out.get("target"), out.get("poles")))


def _design_observer(args: argparse.Namespace, prob) -> tuple[Any, dict[str, Any]]:
    """The observer verbs (every ``--method`` without ``--feedback``); (result, extra output)."""
    plant, method = prob.plant, args.method
    res: Any
    if method == "kalman":
        if not plant.has_noise_model:
            raise CLIError(f"problem {prob.name!r} has no noise model (Q and R): --method kalman needs both")
        res = kalman(plant, method=args.riccati or "scipy")
        return res, {"P": res.P, "residual": res.residual}
    if method == "inverse":
        if plant.R is None:
            raise CLIError(f"problem {prob.name!r} has no measurement-noise covariance R: --method inverse "
                           "needs it")
        target = _target_poles(args, prob)
        opts = {"objective": args.objective} if args.objective else {}
        res = kalman_for_poles(plant, target, method=args.inverse_method or "auto", seed=args.seed, **opts)
        return res, {"target": res.target, "Q": res.Q, "P": res.P, "solver": res.method,
                     "objective": res.objective,
                     "certificate": res.certificate.as_dict() if res.certificate is not None else None}
    if method == "place":
        res = with_stability_check(plant, place_baseline(plant, _target_poles(args, prob)))
        return res, {"target": res.target}
    region = region_from_args(args, plant.is_discrete)
    kw: dict[str, Any] = {"seed": args.seed}
    names = ("objective", "max_gain", "starts") if method == "well_conditioned" else ("objective", "starts")
    kw.update({k: getattr(args, k) for k in names if getattr(args, k) is not None})
    if method == "wc_kalman":
        res = well_conditioned_kalman(plant, region=region,
                                      **_with_progress(well_conditioned_kalman, kw, args.progress))
        return res, {"Q": res.Q, "P": res.P, "region": region.to_dict() if region is not None else None}
    kw = _with_progress(well_conditioned_observer, kw, args.progress)
    if region is not None:
        if args.poles is not None:
            raise CLIError("give either --poles (fixed poles) or a region "
                           "(--region/--alpha/--zeta/--radius), not both")
        res = well_conditioned_observer(plant, region=region, **kw)
        return res, {"region": region.to_dict()}
    if args.poles is None and "poles" not in prob.targets:
        raise CLIError("--method well_conditioned needs --poles or a region (--region/--alpha/--zeta/"
                       f"--radius); problem {prob.name!r} has no target poles")
    target = _target_poles(args, prob)
    return well_conditioned_observer(plant, poles=target, **kw), {"target": target}


def _print_design(prob, res, out: dict[str, Any], vals: dict[str, Any]) -> None:
    print(header(prob))
    print(f"method: {out['method']}    status: {out['status']}    success: {out['success']}")
    if out.get("target") is not None:
        print(f"target poles: {format_poles(out['target'])}")
    region = getattr(res, "region", None)
    if out.get("region") and region is not None:
        print(f"region: {format_region(region)}")
    if out.get("L") is not None:
        _matrix("L", out["L"])
    for k in ("Q", "P"):
        if out.get(k) is not None:
            _matrix(k, out[k])
    if out.get("poles") is not None:
        print(f"poles of A - L C: {format_poles(out['poles'])}")
    elif out.get("L") is None:
        print("L: none (no gain was designed; the status and the certificate say why)"
              if getattr(res, "certificate", None) is not None else "L: none (no gain was designed)")
    if vals:
        print(f"kappa2 = {vals['kappa2']:.6g}   eta = {vals['eta']:.6g}   ||L||_2 = {vals['gain_norm']:.6g}")
    scale = pole_scale(np.linalg.eigvals(prob.plant.A), out.get("target"), out.get("poles"))
    print_outcome(res, scale)


def cmd_design(args: argparse.Namespace) -> int:
    """``optdesign design``: run one design verb on a problem and report the verified result."""
    _check_applicable(args)
    prob = plant_of(args.problem)
    plant = prob.plant
    out: dict[str, Any] = {"problem": prob.name, "method": args.method}
    if args.feedback:
        res, extra = _design_feedback(args, prob)
        out.update(extra, feedback=True, status=str(getattr(res.status, "value", res.status)),
                   success=bool(res.success), message=res.message, verification=res.verification.as_dict())
        out.update(target=_sorted(out.get("target")), poles=_sorted(out.get("poles")))
        if args.json:
            print_json(out)
        else:
            _print_feedback(prob, args.method, res, out)
        return 0 if res.success else 1
    res, extra = _design_observer(args, prob)
    out.update(extra)
    L = getattr(res, "L", None)
    vals: dict[str, Any] = {}
    if L is not None and np.all(np.isfinite(L)):
        vals = gain_values(plant, L)
    out.update(status=str(getattr(res.status, "value", res.status)), success=bool(res.success),
               message=res.message, L=L, poles=_sorted(getattr(res, "poles", None)),
               kappa2=vals.get("kappa2"), eta=vals.get("eta"), gain_norm=vals.get("gain_norm"),
               verification=res.verification.as_dict())
    out["target"] = _sorted(out.get("target"))
    if args.json:
        print_json(out)
    else:
        _print_design(prob, res, out, vals)
    return 0 if res.success else 1


# --------------------------------------------------------------------------- study


def _cfg_study(sp: argparse.ArgumentParser) -> None:
    sp.formatter_class = argparse.RawDescriptionHelpFormatter
    sp.epilog = ("The spec format is documented in optdesign.studies.spec (python -m pydoc "
                 "optdesign.studies.spec);\n"
                 "an example is examples/study_alpha_sector.toml.\n\n"
                 "Results (CSV, JSON, figures) go to --out, else the spec's output folder, else "
                 "./<name>_results --\nrelative to the current directory, never to the spec file.\n"
                 "Exit code 0 when every point succeeds, 1 when one fails (the failed points are "
                 "listed;\n--allow-failures accepts partial results), 2 for a bad spec or argument.")
    sp.add_argument("spec", help="study spec (TOML)")
    sp.add_argument("--executor", choices=("processes", "threads", "serial", "dask"),
                    help="override the spec's executor")
    sp.add_argument("--workers", type=int, help="override the spec's number of workers")
    sp.add_argument("--out", help="output folder (default: the spec's output, else ./<name>_results)")
    sp.add_argument("--overwrite", action="store_true",
                    help="replace existing result files (or symbolic links in their place: the link, never "
                         "its target); without it an existing one is an error, before the sweep")
    sp.add_argument("--allow-outside", action="store_true", dest="allow_outside",
                    help="accept a spec whose output folder lies outside the current directory")
    sp.add_argument("--allow-failures", action="store_true", dest="allow_failures",
                    help="exit 0 when some points fail (partial results accepted; at least one must succeed)")
    sp.add_argument("--no-figures", action="store_true", dest="no_figures",
                    help="write the CSV and JSON only (no matplotlib needed)")
    sp.add_argument("--format", choices=FIGURE_FORMATS, dest="figure_format",
                    help="file format of every figure, overriding the spec's file suffixes (figures at 300 dpi)")
    add_progress_flag(sp, "the sweep (one step per point)")
    sp.add_argument("--json", action="store_true", help="print the result summary as JSON")


#: failed points listed by ``optdesign study`` (the CSV has them all)
_MAX_LISTED = 20


def _failed_points(spec, table) -> list[dict[str, Any]]:
    return [{**{k: r.get(k) for k in spec.axes}, "status": r.get("status"),
             "reason": r.get("reason") or r.get("error") or "no reason recorded"}
            for r in table.records if not r.get("success")]


def _study_header(spec, executor: str, workers: int | None, out: Path) -> str:
    on = executor + (f" ({workers} workers)" if workers and executor != "serial" else "")
    return (f"study {spec.name}: {spec.problem}, design {spec.design}, {len(spec.points)} points on {on}"
            f" -> {out}{os.sep}")


def cmd_study(args: argparse.Namespace) -> int:
    """``optdesign study``: run a sweep described in a TOML file; CSV, JSON and figures."""
    if args.workers is not None and args.workers < 1:
        raise CLIError(f"--workers must be >= 1; found {args.workers}")
    spec = load_spec(args.spec)
    if args.figure_format is not None:
        spec = dataclasses.replace(spec, figures=tuple(
            dataclasses.replace(f, file=str(Path(f.file).with_suffix("." + args.figure_format)))
            for f in spec.figures))
    if spec.figures and not args.no_figures:
        require_matplotlib(f"the figures of {spec.source}")  # before the sweep, not after it
        _headless()
    out = Path(args.out) if args.out is not None else spec.output
    where = "--out" if args.out is not None else f"{spec.source}: study.output"
    output_folder(out, allow_outside=args.allow_outside or args.out is not None, field=where, create=False)
    _check_out_dir(str(out), where)
    executor = args.executor or spec.executor
    if not args.json:
        print(_study_header(spec, executor, args.workers or spec.workers, out))
        flush()
    res = run_spec(spec, executor=args.executor, workers=args.workers, progress=args.progress,
                   output=out, figures=not args.no_figures, overwrite=args.overwrite)
    t = res.table
    failed = _failed_points(spec, t)
    if args.json:
        print_json({"spec": str(args.spec), "points": len(t), "successful": t.n_success,
                     "failed": len(failed), "failed_points": failed, "wall_time": t.wall_time,
                     "csv": str(res.csv), "json": str(res.json), "figures": [str(f) for f in res.figures],
                     "meta": t.meta})
    else:
        print(t.summary())
        if failed:
            print(f"failed points ({len(failed)} of {len(t)}):")
            for f in failed[:_MAX_LISTED]:
                at = ", ".join(f"{k} = {f[k]:g}" if isinstance(f[k], float) else f"{k} = {f[k]}"
                               for k in spec.axes)
                print(f"  {at}: {f['reason']}")
            if len(failed) > _MAX_LISTED:
                print(f"  ... and {len(failed) - _MAX_LISTED} more (the CSV has them all: columns status, "
                      "reason, error)")
        print(f"results: {res.csv}")
        print(f"         {res.json}")
        for fig in res.figures:
            print(f"figure:  {fig}")
        if failed and args.allow_failures and t.n_success:
            print("partial results accepted (--allow-failures)")
    if not failed:
        return 0
    return 0 if args.allow_failures and t.n_success else 1


def _check_out_dir(out: str, flag: str = "--out") -> None:
    """The output folder must exist or be creatable, and be writable (one-line error otherwise)."""
    path = Path(out)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise CLIError(f"{flag} {out}: cannot create the folder ({exc.strerror or exc})") from None
    if not path.is_dir() or not os.access(path, os.W_OK):
        raise CLIError(f"{flag} {out}: not a writable folder")


def _headless() -> None:
    """The command writes figure files and shows none: matplotlib's file-only backend, chosen here by
    the application (the library never chooses one), unless pyplot is already in use."""
    import sys

    if "matplotlib.pyplot" not in sys.modules:
        import matplotlib

        matplotlib.use("Agg")


# --------------------------------------------------------------------------- reproduce


def _cfg_reproduce(sp: argparse.ArgumentParser) -> None:
    sp.formatter_class = argparse.RawDescriptionHelpFormatter
    sp.epilog = "papers:\n" + "\n".join(f"  {k}  {v}" for k, v in PAPERS.items())
    sp.add_argument("papers", nargs="*", metavar="PAPER", help="seed paper(s): 000 ... 004 (default: all)")
    sp.add_argument("--out", default="optdesign-reproduction",
                    help="folder for the figures and summary.md / summary.csv (default "
                         "./optdesign-reproduction, in the current directory)")
    sp.add_argument("--overwrite", action="store_true",
                    help="replace the figures and summary already in --out (or symbolic links in their "
                         "place: the link, never its target); without it an existing one is an error, before "
                         "any paper runs")
    sp.add_argument("--quick", action="store_true", help="smaller grids and fewer starts (CI)")
    sp.add_argument("--format", choices=FIGURE_FORMATS, default="png", dest="figure_format",
                    help="file format of the figures (default png, at 300 dpi)")
    add_progress_flag(sp, "each paper and figure")


def cmd_reproduce(args: argparse.Namespace) -> int:
    """``optdesign reproduce``: regenerate the seed papers' examples and figures, with a summary table."""
    try:
        papers = [paper_id(p) for p in args.papers] or None
    except ValidationError as exc:
        raise CLIError(str(exc)) from None
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        raise CLIError("reproduce writes figures and needs matplotlib: "
                       "pip install 'optdesign-control[plot]'") from None
    _check_out_dir(args.out)
    _headless()
    ids = papers or list(PAPERS)
    print(f"reproducing seed paper(s) {', '.join(ids)}{' (quick)' if args.quick else ''} -> "
          f"{Path(args.out)}{os.sep}")
    flush()
    summary = reproduce_all(args.out, papers=papers, quick=args.quick, progress=args.progress,
                            figure_format=args.figure_format, overwrite=args.overwrite)
    print(summary.overview())
    print(f"summary: {summary.markdown}")
    print(f"         {summary.csv}")
    print(f"figures: {len(summary.figures)} in {summary.outdir}")
    bad = [o for o in summary.outcomes if not o.ok]
    for o in bad:
        print(f"seed {o.paper}: {o.status}: {o.error}")
    return 0 if not bad else 1


#: (name, help, configure(subparser), run)
COMMANDS = (
    ("design", "design an estimator for a problem with any verb (kalman, inverse, well_conditioned, ...)",
     _cfg_design, cmd_design),
    ("study", "run a sweep described in a TOML spec: CSV, JSON and figures", _cfg_study, cmd_study),
    ("reproduce", "regenerate every seed paper's examples and figures, with a summary table",
     _cfg_reproduce, cmd_reproduce),
)
