"""The ``design``, ``study`` and ``reproduce`` commands.

::

    optdesign design PROBLEM --method METHOD [--poles ...] [--region ...] [--json]
    optdesign study SPEC.toml [--executor ...] [--workers N] [--out DIR]
    optdesign reproduce [PAPER ...] [--out DIR] [--quick]

Every user error is a
one-line message with exit code 2 (:class:`optdesign.cli.CLIError`, or an
:class:`~optdesign.errors.OptDesignError` such as a bad spec file); a design that runs but does
not succeed exits with 1, as does a reproduction with a missing or failing paper.
"""

from __future__ import annotations

import argparse
import math
import os
from typing import Any

import numpy as np

from .._validate import as_poles
from ..design.feedback import lqr_for_poles, place, well_conditioned_feedback
from ..design.inverse_kalman import kalman_for_poles
from ..design.kalman import kalman
from ..design.verification import stability_check
from ..design.well_conditioned import well_conditioned_kalman, well_conditioned_observer
from ..errors import ValidationError
from ..model.plant import Plant
from ..model.regions import Disk, HalfPlane, Sector
from ..results import Verification
from ..studies.designers import _gain_values, place_baseline
from ..studies.reproduce import PAPERS, paper_id, reproduce_all
from ..studies.spec import load_spec, parse_poles, parse_region, run_spec
from .common import CLIError, plant_of, print_json

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
        raise CLIError("--alpha/--zeta describe continuous-time regions; this plant is discrete (use "
                       "--region "
                       "disk:R)")
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
    import dataclasses

    if res.L is None:
        return res
    check = stability_check(plant.A - res.L @ plant.C, plant.is_discrete)
    message = res.message
    if not check.passed:
        domain = "|z| < 1" if plant.is_discrete else "Re s < 0"
        message += (f"; A - L C is not stable (stability margin {check.value:.4g}): the requested poles "
                    f"are not all in {domain}, so this gain is no observer")
    return dataclasses.replace(res, verification=res.verification + Verification.of([check]), message=message)


def _fmt_poles(p) -> str:
    if p is None:
        return "-"
    out = []
    for z in np.asarray(p, dtype=complex).ravel():
        out.append(f"{z.real:.6g}{z.imag:+.6g}j" if z.imag else f"{z.real:.6g}")
    return ", ".join(out)


# --------------------------------------------------------------------------- design


def _cfg_design(sp: argparse.ArgumentParser) -> None:
    sp.formatter_class = argparse.RawDescriptionHelpFormatter
    sp.epilog = _REGION_HELP
    sp.add_argument("problem", help="problem name (see `optdesign list`)")
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
    if method == "place":
        target = _target_poles(args, prob)
        res = place(A, B, target, dt=dt, seed=args.seed)
        return res, {"target": target, "K": res.gain_matrix, "poles": res.computed_poles}
    if method == "inverse":
        target = _target_poles(args, prob)
        kw = {"objective": args.objective} if args.objective else {}
        res = lqr_for_poles(fplant, target, **kw)
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
    print(f"problem: {prob.name} -- {prob.title}")
    print(f"method: {method} (state feedback)    status: {out['status']}    success: {out['success']}")
    if out.get("target") is not None:
        print(f"target poles: {_fmt_poles(out['target'])}")
    for k in ("K", "Q"):
        if out.get(k) is not None:
            with np.printoptions(precision=6, linewidth=100):
                print(f"{k} =", np.array2string(np.asarray(out[k]), prefix=f"{k} = "))
    if out.get("poles") is not None:
        print(f"poles of A - B K: {_fmt_poles(out['poles'])}")
    print(res.message)
    if out.get("certificate"):
        print(f"certificate: {res.certificate}")
    print("verification:")
    for c in res.verification:
        print(f"  {c}")


def cmd_design(args: argparse.Namespace) -> int:
    """``optdesign design``: run one design verb on a problem and report the verified result."""
    _check_applicable(args)
    prob = plant_of(args.problem)
    plant = prob.plant
    method = args.method
    out: dict[str, Any] = {"problem": prob.name, "method": method}
    if args.feedback:
        res, extra = _design_feedback(args, prob)
        out.update(extra, feedback=True, status=str(getattr(res.status, "value", res.status)),
                   success=bool(res.success), message=res.message, verification=res.verification.as_dict())
        if args.json:
            print_json(out)
        else:
            _print_feedback(prob, method, res, out)
        return 0 if res.success else 1
    if method == "kalman":
        if not plant.has_noise_model:
            raise CLIError(f"problem {prob.name!r} has no noise model (Q and R): --method kalman needs both")
        res = kalman(plant, method=args.riccati or "scipy")
        out.update(P=res.P, residual=res.residual)
    elif method == "inverse":
        if plant.R is None:
            raise CLIError(f"problem {prob.name!r} has no measurement-noise covariance R: --method inverse "
                           "needs it")
        target = _target_poles(args, prob)
        kw = {"objective": args.objective} if args.objective else {}
        res = kalman_for_poles(plant, target, method=args.inverse_method or "auto", seed=args.seed, **kw)
        out.update(target=res.target, Q=res.Q, P=res.P, solver=res.method, objective=res.objective,
                   certificate=res.certificate.as_dict() if res.certificate is not None else None)
    elif method == "place":
        res = with_stability_check(plant, place_baseline(plant, _target_poles(args, prob)))
        out.update(target=res.target)
    elif method == "well_conditioned":
        region = region_from_args(args, plant.is_discrete)
        kw: dict[str, Any] = {"seed": args.seed}
        for k in ("objective", "max_gain", "starts"):
            if getattr(args, k) is not None:
                kw[k] = getattr(args, k)
        if region is not None:
            if args.poles is not None:
                raise CLIError("give either --poles (fixed poles) or a region "
                               "(--region/--alpha/--zeta/--radius), "
                               "not both")
            res = well_conditioned_observer(plant, region=region, **kw)
            out.update(region=region.to_dict())
        else:
            if args.poles is None and "poles" not in prob.targets:
                raise CLIError("--method well_conditioned needs --poles or a region "
                               "(--region/--alpha/--zeta/"
                               f"--radius); problem {prob.name!r} has no target poles")
            target = _target_poles(args, prob)
            res = well_conditioned_observer(plant, poles=target, **kw)
            out.update(target=target)
    else:  # wc_kalman
        region = region_from_args(args, plant.is_discrete)
        kw = {"seed": args.seed}
        for k in ("objective", "starts"):
            if getattr(args, k) is not None:
                kw[k] = getattr(args, k)
        res = well_conditioned_kalman(plant, region=region, **kw)
        out.update(Q=res.Q, P=res.P, region=region.to_dict() if region is not None else None)

    L = getattr(res, "L", None)
    vals: dict[str, Any] = {}
    if L is not None and np.all(np.isfinite(L)):
        vals = _gain_values(plant, L)
    out.update(status=str(getattr(res.status, "value", res.status)), success=bool(res.success),
               message=res.message,
               L=L, poles=getattr(res, "poles", None), kappa2=vals.get("kappa2"), eta=vals.get("eta"),
               gain_norm=vals.get("gain_norm"), verification=res.verification.as_dict())
    if args.json:
        print_json(out)
    else:
        print(f"problem: {prob.name} -- {prob.title}")
        print(f"method: {method}    status: {out['status']}    success: {out['success']}")
        if "target" in out and out["target"] is not None:
            print(f"target poles: {_fmt_poles(out['target'])}")
        if out.get("region"):
            print(f"region: {getattr(res, 'region', None)!r}")
        if L is not None:
            with np.printoptions(precision=6, linewidth=100, suppress=False):
                print("L =", np.array2string(np.asarray(L), prefix="L = "))
        for k in ("Q", "P"):
            if out.get(k) is not None:
                with np.printoptions(precision=6, linewidth=100):
                    print(f"{k} =", np.array2string(np.asarray(out[k]), prefix=f"{k} = "))
        print(f"poles of A - L C: {_fmt_poles(out['poles'])}")
        if vals:
            print(f"kappa2 = {vals['kappa2']:.6g}   eta = {vals['eta']:.6g}   ||L||_2 = "
                  f"{vals['gain_norm']:.6g}")
        print(res.message)
        if out.get("certificate"):
            print(f"certificate: {res.certificate}")
        print("verification:")
        for c in res.verification:
            print(f"  {c}")
    return 0 if res.success else 1


# --------------------------------------------------------------------------- study


def _cfg_study(sp: argparse.ArgumentParser) -> None:
    sp.formatter_class = argparse.RawDescriptionHelpFormatter
    sp.epilog = ("The spec format is documented in optdesign.studies.spec (python -m pydoc "
                 "optdesign.studies.spec);\n"
                 "an example is examples/study_alpha_sector.toml.")
    sp.add_argument("spec", help="study spec (TOML)")
    sp.add_argument("--executor", choices=("processes", "threads", "serial", "dask"),
                    help="override the spec's executor")
    sp.add_argument("--workers", type=int, help="override the spec's number of workers")
    sp.add_argument("--out", help="override the spec's output folder")
    sp.add_argument("--no-progress", action="store_true", help="no progress bar")
    sp.add_argument("--json", action="store_true", help="print the result summary as JSON")


def cmd_study(args: argparse.Namespace) -> int:
    """``optdesign study``: run a sweep described in a TOML file; CSV, JSON and figures."""
    if args.workers is not None and args.workers < 1:
        raise CLIError(f"--workers must be >= 1; found {args.workers}")
    spec = load_spec(args.spec)
    if args.out is not None:
        _check_out_dir(args.out)
    res = run_spec(spec, executor=args.executor, workers=args.workers, progress=not args.no_progress,
                   output=args.out)
    t = res.table
    if args.json:
        print_json({"spec": str(args.spec), "points": len(t), "successful": t.n_success,
                     "failed": len(t) - t.n_success, "wall_time": t.wall_time, "csv": str(res.csv),
                     "json": str(res.json), "figures": [str(f) for f in res.figures], "meta": t.meta})
    else:
        print(f"study {spec.name}: {spec.problem}, design {spec.design}, {len(spec.points)} points on "
              f"{t.meta.get('executor')}")
        print(t.summary())
        errors = [r for r in t.records if r.get("error")]
        if errors:
            print(f"first error: {errors[0]['error']}")
        failed = [r for r in t.records if not r.get("error") and not r.get("success")]
        if failed:
            at = ", ".join(f"{k} = {failed[0].get(k)}" for k in spec.axes)
            print(f"first unsuccessful point ({at}): {failed[0].get('status')}: "
                  f"{failed[0].get('reason') or 'no reason recorded'}")
        print(f"results: {res.csv}")
        print(f"         {res.json}")
        for f in res.figures:
            print(f"figure:  {f}")
    return 0 if t.n_success else 1


def _check_out_dir(out: str) -> None:
    """``--out``: the folder must exist or be creatable, and be writable (one-line error otherwise)."""
    from pathlib import Path

    path = Path(out)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise CLIError(f"--out {out}: cannot create the folder ({exc.strerror or exc})") from None
    if not path.is_dir() or not os.access(path, os.W_OK):
        raise CLIError(f"--out {out}: not a writable folder")


# --------------------------------------------------------------------------- reproduce


def _cfg_reproduce(sp: argparse.ArgumentParser) -> None:
    sp.formatter_class = argparse.RawDescriptionHelpFormatter
    sp.epilog = "papers:\n" + "\n".join(f"  {k}  {v}" for k, v in PAPERS.items())
    sp.add_argument("papers", nargs="*", metavar="PAPER", help="seed paper(s): 000 ... 004 (default: all)")
    sp.add_argument("--out", default="optdesign-reproduction",
                    help="folder for the figures and summary.md / summary.csv (default "
                         "./optdesign-reproduction)")
    sp.add_argument("--quick", action="store_true", help="smaller grids and fewer starts (CI)")


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
                       "pip install 'optdesign[plot]'") from None
    _check_out_dir(args.out)
    summary = reproduce_all(args.out, papers=papers, quick=args.quick)
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
