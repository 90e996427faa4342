"""Run a CasADi ``Opti`` problem with IPOPT and report in the common status set."""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from ..errors import BackendUnavailableError
from ..results import SolverStats, Status
from .report import SolverReport
from .status import map_status

__all__ = ["import_casadi", "solve_opti", "DEFAULT_IPOPT_OPTIONS"]

#: Quiet, reasonably tight IPOPT defaults.  Override per call.
DEFAULT_IPOPT_OPTIONS: dict[str, Any] = {
    "ipopt.print_level": 0,
    "ipopt.sb": "yes",
    "print_time": False,
    "ipopt.tol": 1e-10,
    "ipopt.acceptable_tol": 1e-6,
    "ipopt.max_iter": 500,
}


def import_casadi():
    """Import CasADi or raise :class:`BackendUnavailableError` naming the package to install."""
    try:
        import casadi
    except ImportError as exc:  # pragma: no cover - casadi is a hard dependency
        raise BackendUnavailableError(
            "the NLP backend needs CasADi with IPOPT: pip install casadi"
        ) from exc
    return casadi


def solve_opti(opti, options: dict[str, Any] | None = None, *, configure: bool = True) -> SolverReport:
    """Solve ``opti`` with IPOPT; never raises on solver failure.

    Parameters
    ----------
    opti : casadi.Opti
        A fully described problem (variables, constraints, objective, initial guesses and
        parameter values already set).
    options : dict, optional
        Plugin options merged over :data:`DEFAULT_IPOPT_OPTIONS`.
    configure : bool
        Call ``opti.solver("ipopt", ...)``.  Pass False when the caller configured the solver
        once and re-solves with new parameter values (sweeps).

    Returns
    -------
    SolverReport
        ``value(expr)`` evaluates at the solution, or at the last iterate on failure.
    """
    import_casadi()  # a clear BackendUnavailableError when CasADi is missing
    if configure:
        opts = dict(DEFAULT_IPOPT_OPTIONS)
        opts.update(options or {})
        plugin = {k: v for k, v in opts.items() if not k.startswith("ipopt.")}
        ipopt = {k[len("ipopt."):]: v for k, v in opts.items() if k.startswith("ipopt.")}
        opti.solver("ipopt", plugin, ipopt)
    t0 = time.perf_counter()
    error = ""
    try:
        sol = opti.solve()
        getter = sol.value
    except RuntimeError as exc:  # IPOPT did not report success
        error = str(exc).strip().splitlines()[-1] if str(exc).strip() else repr(exc)
        getter = opti.debug.value
    elapsed = time.perf_counter() - t0
    try:
        st = opti.stats()
    except RuntimeError:
        st = {}
    native = str(st.get("return_status", "unknown"))
    status = map_status("ipopt", native)
    if native == "unknown" and not error:
        status = Status.SOLVER_ERROR

    def value(expr):
        return np.asarray(getter(expr), dtype=float)

    try:
        obj = float(getter(opti.f))
    except Exception:  # noqa: BLE001 - objective may be unavailable after a crash
        obj = float("nan")
    stats = SolverStats(
        backend="ipopt",
        native_status=native,
        time=float(st.get("t_wall_total", elapsed)) if st else elapsed,
        iterations=int(st["iter_count"]) if "iter_count" in st else None,
        extra={"objective": obj, **({"error": error} if error else {})},
    )
    msg = f"ipopt: {native}" + (f" ({error})" if error and error not in native else "")
    return SolverReport(status=status, stats=stats, value=value, objective=obj, message=msg)
