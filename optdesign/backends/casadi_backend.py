"""Run a CasADi problem (an ``Opti`` description or an ``nlpsol`` problem dict) with IPOPT and
report in the common status set."""

from __future__ import annotations

import re
import time
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._backends import import_casadi
from ..errors import ValidationError
from ..results import SolverStats, Status
from .report import Captured, SolverReport, captured_output, one_warning_per_call
from .status import map_status

__all__ = ["import_casadi", "solve_opti", "solve_nlpsol", "ipopt_solver", "run_solver", "setup_error_report",
           "DEFAULT_IPOPT_OPTIONS", "check_ipopt_options"]

#: Quiet, reasonably tight IPOPT defaults.  Override per call.
DEFAULT_IPOPT_OPTIONS: dict[str, Any] = {
    "ipopt.print_level": 0,
    "ipopt.sb": "yes",
    "print_time": False,
    "ipopt.tol": 1e-10,
    "ipopt.acceptable_tol": 1e-6,
    "ipopt.max_iter": 500,
}


def _error_line(exc: BaseException) -> str:
    """The informative line of a CasADi error: the last line that is not a list of suggestions,
    without the C++ source location (``.../options.cpp:255: Unknown option: x`` -> ``Unknown
    option: x``)."""
    lines = [ln.strip() for ln in str(exc).splitlines()]
    lines = [ln for ln in lines if ln and not ln.startswith((">", "Did you mean", "Use print_options"))]
    if not lines:
        return repr(exc)
    return re.sub(r"^.*?\.(?:cpp|hpp):\d+:\s*", "", lines[-1]) or lines[-1]


def check_ipopt_options(options: dict[str, Any]) -> None:
    """Refuse ``options`` (a dict with string keys) that CasADi or IPOPT do not accept (unknown
    name, wrong type, invalid value) up front, by configuring IPOPT for a one-variable problem
    with them (a few ms): a bad option is the caller's error, not a failed start.

    Raises
    ------
    ValidationError
        Naming ``options`` and CasADi's / IPOPT's reason.
    """
    ca = import_casadi()
    opts = {**DEFAULT_IPOPT_OPTIONS, **options}
    plugin = {k: v for k, v in opts.items() if not k.startswith("ipopt.")}
    plugin["ipopt"] = {k[len("ipopt."):]: v for k, v in opts.items() if k.startswith("ipopt.")}
    plugin["ipopt"].update({"print_level": 0, "sb": "yes"})  # (x0 = 0 is optimal: no iteration)
    plugin["print_time"] = False
    x = ca.MX.sym("x")
    try:
        with captured_output():
            ca.nlpsol("options_check", "ipopt", {"x": x, "f": x * x}, plugin)(x0=0.0)
    except (RuntimeError, TypeError, NotImplementedError) as exc:
        raise ValidationError(
            f"options must be IPOPT / CasADi options that IPOPT accepts (e.g. {{'ipopt.max_iter': 200}}); "
            f"found {options!r}: {_error_line(exc)}"
        ) from None


@one_warning_per_call
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
        plugin = _plugin_options(options)
        ipopt = plugin.pop("ipopt")
        opti.solver("ipopt", plugin, ipopt)
    t0 = time.perf_counter()
    error = ""
    with captured_output() as cap:  # CasADi's WARNING(...) lines, IPOPT's banner: never printed
        try:
            sol = opti.solve()
            getter = sol.value
        except RuntimeError as exc:  # IPOPT did not report success
            error = _error_line(exc)
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
    return _report(status, native, st, _wall(st, elapsed), obj, error, value, cap)


@one_warning_per_call
def solve_nlpsol(problem: dict[str, Any], x0, lbg, ubg, options: dict[str, Any] | None = None, *,
                 plugin: dict[str, Any] | None = None, extra: dict[str, Any] | None = None,
                 name: str = "nlp") -> SolverReport:
    """Solve an ``nlpsol`` problem dict (``{"x", "f", "g"}`` or one with user derivative
    callbacks) with IPOPT; never raises on solver failure.

    Parameters
    ----------
    problem : dict
        The problem for ``casadi.nlpsol``.
    x0, lbg, ubg : array_like
        Initial point and constraint bounds.
    options : dict, optional
        As for :func:`solve_opti`: plugin options and ``ipopt.``-prefixed IPOPT options, merged
        over :data:`DEFAULT_IPOPT_OPTIONS` (``expand`` is dropped: the problem is built already).
    plugin : dict, optional
        Further plugin options of the formulation (e.g. derivative callbacks), merged last.
    extra : dict, optional
        Entries for ``stats.extra``.
    name : str
        Name of the CasADi function.

    Returns
    -------
    SolverReport
        ``value()`` is the solution vector (the initial point when the solver failed to run).
    """
    ca = import_casadi()
    opts = dict(DEFAULT_IPOPT_OPTIONS)
    opts.update(options or {})
    opts.pop("expand", None)
    plug = {k: v for k, v in opts.items() if not k.startswith("ipopt.")}
    plug.update(plugin or {})
    plug["ipopt"] = {k[len("ipopt."):]: v for k, v in opts.items() if k.startswith("ipopt.")}
    st, xopt, obj, error, elapsed = _ipopt_call(lambda: ca.nlpsol(name, "ipopt", problem, plug), x0,
                                                lbg=lbg, ubg=ubg)
    native = str(st.get("return_status", "solver_error" if error else "unknown"))

    def value(_expr: Any = None) -> NDArray[np.float64]:
        return xopt

    # unknown (and "solver_error") -> SOLVER_ERROR; the time includes making the solver
    return _report(map_status("ipopt", native), native, st, elapsed, obj, error, value, extra=extra)


def _wall(st: dict, elapsed: float) -> float:
    """IPOPT's own wall time of a run (``t_wall_total``), else the caller's measurement."""
    return float(st.get("t_wall_total", elapsed)) if st else elapsed


def _report(status: Status, native: str, st: dict, seconds: float, obj: float, error: str,
            value: Callable[..., Any], cap: Captured | None = None, *,
            extra: dict[str, Any] | None = None) -> SolverReport:
    """The :class:`SolverReport` of one IPOPT run (``st``: its stats, empty if it did not run);
    what it printed (``cap``, or the ``solver_output`` / ``solver_warnings`` that
    :func:`_ipopt_call` put in ``st``) goes to ``extra``."""
    chatter = cap.as_extra() if cap is not None else {
        k: st[k] for k in ("solver_output", "solver_warnings") if k in st}
    stats = SolverStats(backend="ipopt", native_status=native, time=seconds,
                        iterations=int(st["iter_count"]) if "iter_count" in st else None,
                        extra={"objective": obj, **(extra or {}), **chatter,
                               **({"error": error} if error else {})})
    msg = f"ipopt: {native}" + (f" ({error})" if error and error not in native else "")
    return SolverReport(status=status, stats=stats, value=value, objective=obj, message=msg)


def _ipopt_call(make: Callable[[], Any], x0: Any,
                **bounds: Any) -> tuple[dict, NDArray[np.float64], float, str, float]:
    """Make (``make()``) and call an IPOPT Function from ``x0``; ``(stats, x, objective, error line,
    seconds)`` -- on a RuntimeError (a callback, an evaluation or the plugin failed to run) empty
    stats, ``x0``, NaN and the error's first line."""
    t0 = time.perf_counter()
    with captured_output() as cap:  # CasADi's WARNING(...) lines, IPOPT's banner: never printed
        try:
            solver = make()
            sol = solver(x0=x0, **bounds)
            st, x, obj, error = solver.stats(), np.asarray(sol["x"], dtype=float).ravel(), float(sol["f"]), ""
        except RuntimeError as exc:
            st, x, obj = {}, np.asarray(x0, dtype=float).ravel(), float("nan")
            error = _error_line(exc)
    if cap.as_extra():
        st = {**st, **cap.as_extra()}
    return st, x, obj, error, time.perf_counter() - t0


def _plugin_options(options: dict[str, Any] | None) -> dict[str, Any]:
    """CasADi plugin options (``ipopt.``-prefixed keys nested under ``"ipopt"``) of ``options``
    merged over :data:`DEFAULT_IPOPT_OPTIONS`."""
    opts = dict(DEFAULT_IPOPT_OPTIONS)
    opts.update(options or {})
    plug = {k: v for k, v in opts.items() if not k.startswith("ipopt.")}
    plug["ipopt"] = {k[len("ipopt."):]: v for k, v in opts.items() if k.startswith("ipopt.")}
    return plug


def ipopt_solver(problem: dict[str, Any], options: dict[str, Any] | None = None, *, name: str = "nlp"):
    """An IPOPT ``casadi.nlpsol`` Function for ``problem`` (``{"x", "p", "f", "g"}``), configured
    once and called many times by :func:`run_solver`.

    Parameters
    ----------
    problem : dict
        The problem for ``casadi.nlpsol`` (e.g. the expressions of an ``Opti`` description with one
        objective of a continuation, :meth:`ObserverNLP.nlpsol_problem`).
    options : dict, optional
        As for :func:`solve_opti`: plugin options (e.g. ``expand``) and ``ipopt.``-prefixed IPOPT
        options, merged over :data:`DEFAULT_IPOPT_OPTIONS`.
    name : str
        Name of the CasADi function.

    Returns
    -------
    casadi.Function

    Raises
    ------
    RuntimeError
        CasADi refuses the problem or an option (callers validate options up front,
        :func:`check_ipopt_options`).
    """
    ca = import_casadi()
    return ca.nlpsol(name, "ipopt", problem, _plugin_options(options))


@one_warning_per_call
def run_solver(solver, x0: NDArray, p: NDArray, lbg: NDArray, ubg: NDArray,
               value_of: Callable[[NDArray], Callable[[Any], Any]]) -> SolverReport:
    """Run an :func:`ipopt_solver` Function from ``x0`` with parameters ``p`` and constraint bounds
    ``lbg <= g <= ubg``; never raises on solver failure.

    Parameters
    ----------
    solver : casadi.Function
        From :func:`ipopt_solver`.
    x0, p, lbg, ubg : (nx,), (np,), (ng,), (ng,) array_like
    value_of : callable
        ``value_of(x)`` -> ``value(expr)``: evaluates an expression of the problem at the solution
        vector ``x`` (the last iterate when IPOPT fails), e.g. :meth:`ObserverNLP.evaluator`.

    Returns
    -------
    SolverReport
        As :func:`solve_opti`'s: the status mapped from IPOPT's ``return_status``, ``value(expr)``.
    """
    st, x, obj, error, elapsed = _ipopt_call(lambda: solver, x0, p=p, lbg=lbg, ubg=ubg)
    native = str(st.get("return_status", "solver_error" if error else "unknown"))
    # unknown (and "solver_error") -> SOLVER_ERROR
    return _report(map_status("ipopt", native), native, st, _wall(st, elapsed), obj, error, value_of(x))


def setup_error_report(exc: BaseException) -> SolverReport:
    """The report of a solve that could not start: CasADi refused to make the solver (``exc``, e.g.
    ``expand`` on a problem with a linear solve).  Status ``solver_error``; its ``value(expr)`` raises
    RuntimeError (there is no iterate), as ``Opti``'s does after such a failure."""
    line = _error_line(exc)
    stats = SolverStats(backend="ipopt", native_status="solver_error", time=0.0, iterations=0,
                        extra={"objective": float("nan"), "error": line})

    def value(_expr: Any = None) -> NDArray[np.float64]:
        raise RuntimeError(f"no iterate: the solver could not be made ({line})")

    return SolverReport(status=Status.SOLVER_ERROR, stats=stats, value=value, objective=float("nan"),
                        message=f"ipopt: solver_error ({line})")
