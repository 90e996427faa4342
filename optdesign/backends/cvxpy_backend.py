"""Run a cvxpy problem on Clarabel or SCS and report in the common status set."""

from __future__ import annotations

import functools
import time
from typing import Any

import numpy as np

from .._backends import import_cvxpy
from ..errors import BackendUnavailableError, ValidationError
from ..results import SolverStats
from .report import SolverReport, captured_output, one_warning_per_call
from .status import map_status

__all__ = ["import_cvxpy", "available_sdp_solvers", "default_sdp_solver", "solve_cvxpy", "SDP_SOLVERS",
           "DEFAULT_OPTIONS"]

#: SDP-capable conic solvers we support, in order of preference (Clarabel is the more
#: accurate interior-point method; SCS is a first-order fallback).
SDP_SOLVERS = ("CLARABEL", "SCS")

#: Tight defaults per solver (interior point: ~1e-9 gaps; SCS: as tight as it usefully goes).
DEFAULT_OPTIONS: dict[str, dict[str, Any]] = {
    "CLARABEL": {"tol_gap_abs": 1e-10, "tol_gap_rel": 1e-10, "tol_feas": 1e-10, "max_iter": 400},
    "SCS": {"eps_abs": 1e-9, "eps_rel": 1e-9, "max_iters": 200_000},
}


@functools.lru_cache(maxsize=1)
def _installed_solvers() -> frozenset[str]:
    # cvxpy's installed_solvers() imports every solver interface: slow (12 % of a small design's
    # time when called per design), and the answer cannot change within a process
    return frozenset(import_cvxpy().installed_solvers())


def available_sdp_solvers() -> tuple[str, ...]:
    """The supported SDP solvers that are installed, in preference order (discovered once per
    process)."""
    installed = _installed_solvers()
    return tuple(s for s in SDP_SOLVERS if s in installed)


def default_sdp_solver() -> str:
    """Clarabel if installed, else SCS."""
    avail = available_sdp_solvers()
    if not avail:
        raise BackendUnavailableError(
            "no SDP solver installed for cvxpy: pip install clarabel (or scs)"
        )
    return avail[0]


def _resolve(solver: str | None) -> str:
    if solver is None:
        return default_sdp_solver()
    name = str(solver).upper()
    if name not in SDP_SOLVERS:
        raise ValidationError(f"solver must be one of {SDP_SOLVERS} (or None for the default); "
                              f"found {solver!r}")
    if name not in available_sdp_solvers():
        raise BackendUnavailableError(f"SDP solver {name} is not installed: pip install {name.lower()}")
    return name


#: keywords of ``cvxpy.Problem.solve`` itself (not passed to the solver)
CVXPY_KEYWORDS = frozenset({"verbose", "warm_start", "ignore_dpp", "canon_backend", "enforce_dpp", "gp",
                            "qcp", "requires_grad", "parallel"})
#: SCS's settings (scs 3.x ``ScsSettings``) and the names cvxpy translates for it
SCS_SETTINGS = frozenset({"max_iters", "eps_abs", "eps_rel", "eps_infeas", "alpha", "scale", "normalize",
                          "rho_x", "adaptive_scale", "acceleration_lookback", "acceleration_interval",
                          "time_limit_secs", "write_data_filename", "log_csv_filename", "use_indirect",
                          "gpu", "mkl", "use_quad_obj"})


def check_solver_options(name: str, options: dict[str, Any]) -> None:
    """Refuse an option the solver does not know before it reaches the solver (issue 26: a bogus
    option reached Clarabel as ``TypeError: unrecognized solver setting``).

    Raises
    ------
    ValidationError
        Naming the option, the solver and the settings it knows.
    """
    if name == "CLARABEL":
        try:
            import clarabel
        except ImportError:  # pragma: no cover - cvxpy reports it
            return
        known = {k for k in dir(clarabel.DefaultSettings()) if not k.startswith("_")}
    elif name == "SCS":
        known = set(SCS_SETTINGS)
    else:  # pragma: no cover - _resolve admits only the two
        return
    bad = sorted(k for k in options if k not in known and k not in CVXPY_KEYWORDS)
    if bad:
        raise ValidationError(f"unknown {name} option {bad[0]!r} in the solver options; {name} knows "
                              f"{', '.join(sorted(known))}")


@one_warning_per_call
def solve_cvxpy(problem, solver: str | None = None, options: dict[str, Any] | None = None) -> SolverReport:
    """Solve a cvxpy problem; never raises on solver failure (status says what happened).

    Parameters
    ----------
    problem : cvxpy.Problem
    solver : {"CLARABEL", "SCS"} or None
        None picks :func:`default_sdp_solver`.
    options : dict, optional
        Solver options merged over the tight defaults.
    """
    cp = import_cvxpy()
    name = _resolve(solver)
    opts = dict(DEFAULT_OPTIONS.get(name, {}))
    opts.update(options or {})
    check_solver_options(name, opts)
    t0 = time.perf_counter()
    error = ""
    with captured_output() as cap:  # cvxpy's "Solution may be inaccurate", the solvers' logs
        try:
            problem.solve(solver=name, **opts)
            native = str(problem.status)
        except cp.error.SolverError as exc:
            native = "solver_error"
            error = str(exc).strip().splitlines()[-1] if str(exc).strip() else repr(exc)
        except TypeError as exc:  # a setting of the right name with a value of the wrong type
            raise ValidationError(f"options for {name}: {exc} (found {options!r})") from None
    elapsed = time.perf_counter() - t0
    status = map_status("cvxpy", native)
    st = problem.solver_stats if error == "" else None
    obj = float(problem.value) if (problem.value is not None and np.isfinite(problem.value)) else float("nan")

    def value(expr):
        v = expr.value
        return None if v is None else np.asarray(v, dtype=float)

    stats = SolverStats(
        backend=name.lower(),
        native_status=native,
        time=float(st.solve_time) if (st is not None and st.solve_time is not None) else elapsed,
        iterations=int(st.num_iters) if (st is not None and st.num_iters is not None) else None,
        extra={"objective": obj, "wall_time": elapsed, **({"error": error} if error else {}),
               **cap.as_extra()},
    )
    msg = f"{name.lower()}: {native}" + (f" ({error})" if error else "")
    return SolverReport(status=status, stats=stats, value=value, objective=obj, message=msg)
