"""The ``estimate-noise`` command: noise covariances of a problem's plant from a data file, by
autocovariance least squares (:func:`optdesign.design.noise_estimation.estimate_noise`).

    optdesign estimate-noise PROBLEM DATA.csv|DATA.npz [--dt DT] [--lags N] [--q-structure full|diagonal]
                             [--weighting identity|optimal] [--trace-penalty RHO] [--bootstrap B]
                             [--seed S] [--json]

Data files: ``.npz`` with an array ``y`` (samples x outputs) and optionally ``u`` (samples x inputs);
``.csv`` with one row per sample, the outputs in the first p columns and the known inputs (if the plant
has B) in the next ones; a header line is skipped.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np

from ..design.noise_estimation import estimate_noise
from ..errors import OptDesignError
from .common import PROBLEM_HELP, CLIError, format_poles, header, plant_of, print_json

__all__ = ["register", "read_data"]

#: largest data file read (bytes)
MAX_DATA_BYTES = 2**31


def read_data(path: str, p: int, nu: int) -> tuple[np.ndarray, np.ndarray | None]:
    """``(y, u)`` from a ``.npz`` (arrays ``y``, ``u``) or ``.csv`` file (outputs, then inputs).

    Raises
    ------
    CLIError
        Missing file, unknown suffix, unreadable content, missing ``y``, a wrong number of columns.
    """
    f = Path(path)
    if not f.is_file():
        raise CLIError(f"data file {path!r} not found")
    if f.stat().st_size > MAX_DATA_BYTES:
        raise CLIError(f"{path}: larger than {MAX_DATA_BYTES} bytes")
    suffix = f.suffix.lower()
    if suffix == ".npz":
        try:
            with np.load(f, allow_pickle=False) as z:
                if "y" not in z.files:
                    raise CLIError(f"{path}: no array 'y' (found {', '.join(z.files) or 'none'})")
                y = np.asarray(z["y"], dtype=float)
                u = np.asarray(z["u"], dtype=float) if "u" in z.files else None
        except (ValueError, OSError) as exc:
            raise CLIError(f"{path}: not a readable .npz of numeric arrays ({exc})") from None
        if y.ndim == 1:
            y = y[:, None]
        return y, u
    if suffix == ".csv":
        try:
            data = np.loadtxt(f, delimiter=",", ndmin=2)
        except ValueError:
            try:
                data = np.loadtxt(f, delimiter=",", ndmin=2, skiprows=1)
            except ValueError as exc:
                raise CLIError(f"{path}: not a numeric CSV ({exc})") from None
        if data.shape[1] not in (p, p + nu):
            want = f"{p}" if nu == 0 else f"{p} (outputs) or {p + nu} (outputs, then inputs)"
            raise CLIError(f"{path}: expected {want} columns; found {data.shape[1]}")
        return data[:, :p], (data[:, p:] if data.shape[1] > p else None)
    raise CLIError(f"{path}: unknown data file type {suffix or '(no suffix)'!r}; expected .csv or .npz")


def cmd_estimate_noise(args: argparse.Namespace) -> int:
    prob = plant_of(args.problem)
    plant = prob.plant
    nu = 0 if plant.B is None else plant.B.shape[1]
    y, u = read_data(args.data, plant.p, nu)
    est = estimate_noise(plant, y, u, dt=args.dt, lags=args.lags, q_structure=args.q_structure,
                         weighting=args.weighting, trace_penalty=args.trace_penalty, bootstrap=args.bootstrap,
                         seed=args.seed, time_limit=args.time_limit)
    kf = None
    filter_note = ""
    if est.Q is not None:
        try:
            kf = est.kalman()
        except OptDesignError as exc:
            filter_note = f"no Kalman filter of the estimate: {exc}"
    if args.json:
        out: dict[str, Any] = {"problem": prob.name, "status": str(est.status), "success": est.success,
                               "Q": est.Q, "R": est.R, "residual": est.residual, "condition": est.condition,
                               "rank": est.rank, "unknowns": est.n_unknowns, "lags": est.lags,
                               "samples": est.n_samples, "weighting": est.weighting,
                               "weighting_report": est.weighting_report, "route": est.route.as_list(),
                               "verification": est.verification.as_dict()}
        if est.confidence is not None:
            out["confidence"] = est.confidence
        if kf is not None:
            out["filter"] = {"L": kf.L, "poles": kf.poles}
        print_json(out)
    else:
        print(header(prob))
        print(est.summary())
        if est.confidence is not None and est.confidence.get("replicates"):
            c = est.confidence
            print(f"  bootstrap ({c['replicates']} replicates over {c['segments']} segments), "
                  f"{100 * c['level']:.0f} % intervals:")
            with np.printoptions(precision=5, suppress=False, linewidth=100):
                print(f"    Q in [{c['Q_low']}, {c['Q_high']}]")
                print(f"    R in [{c['R_low']}, {c['R_high']}]")
        if kf is not None:
            print(f"  Kalman filter of the estimate: poles {format_poles(kf.poles)}")
        elif filter_note:
            print(f"  {filter_note}")
    return 0 if est.success else 1


def _cfg(sp: argparse.ArgumentParser) -> None:
    sp.add_argument("problem", help=PROBLEM_HELP + "; its plant's Q and R (if any) choose the filter gain")
    sp.add_argument("data", help="the measurements: .npz with y (samples x outputs) and optional u, or .csv "
                                 "(outputs, then inputs, one row per sample)")
    sp.add_argument("--dt", type=float, default=None, help="sampling period of the data (a continuous plant)")
    sp.add_argument("--lags", type=int, default=None, help="autocovariance lags (default max(15, 2 n))")
    sp.add_argument("--q-structure", choices=("full", "diagonal"), default="full",
                    help="Q full or diagonal (through the plant's G)")
    sp.add_argument("--weighting", choices=("identity", "optimal"), default="identity",
                    help="least-squares weighting (optimal: Rajamani & Rawlings 2009, iterated)")
    sp.add_argument("--trace-penalty", type=float, default=0.0,
                    help="rho of + rho tr(Q) (fewer disturbances)")
    sp.add_argument("--bootstrap", type=int, default=None,
                    help="bootstrap re-solves for confidence intervals")
    sp.add_argument("--seed", type=int, default=None, help="seed of the bootstrap")
    sp.add_argument("--time-limit", type=float, default=None, help="seconds")
    sp.add_argument("--json", action="store_true", help="machine-readable output")


HELP = "noise covariances Q, R of a problem's plant from measured data (autocovariance least squares)"


def register(sub: Any) -> None:
    """Add ``estimate-noise`` to the sub-command parsers of ``optdesign``."""
    sp = sub.add_parser("estimate-noise", help=HELP, description=HELP)
    _cfg(sp)
    sp.set_defaults(_run=cmd_estimate_noise)
