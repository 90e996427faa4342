"""Result building blocks shared by every design verb: one status set, solver statistics,
and an independent verification record.

A design result is a frozen dataclass that carries ``status``, ``message``,
``solver_stats`` and ``verification``; ``success`` is true only when the status is a
solved one *and* every verification check passed — whatever the solver said.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np

from .errors import InfeasibleError, SolverError

__all__ = ["Status", "Check", "Verification", "SolverStats", "Certificate", "Stage", "Route", "DesignResult",
           "ResultMixin"]


class Status(str, enum.Enum):
    """The one status set of optdesign (cvxpy-style, shared by every backend).

    ``OPTIMAL``/``OPTIMAL_INACCURATE`` come from optimizers, ``SOLVED`` from direct
    (closed-form, analytical, linear-algebra) methods that have no optimality notion.

    ``INFEASIBLE`` is a verdict: it is reported only with a *global* certificate (a
    return-difference frequency, an SDP dual / Farkas certificate, a proof).  A local method
    that stops without a solution reports ``NOT_FOUND`` (feasibility unknown), never
    ``INFEASIBLE`` -- whatever the solver said.
    """

    OPTIMAL = "optimal"
    OPTIMAL_INACCURATE = "optimal_inaccurate"
    SOLVED = "solved"
    INFEASIBLE = "infeasible"
    INFEASIBLE_INACCURATE = "infeasible_inaccurate"
    NOT_FOUND = "not_found"
    UNBOUNDED = "unbounded"
    ITERATION_LIMIT = "iteration_limit"
    TIME_LIMIT = "time_limit"
    NUMERICAL_ERROR = "numerical_error"
    SOLVER_ERROR = "solver_error"

    @property
    def is_solved(self) -> bool:
        return self in (Status.OPTIMAL, Status.OPTIMAL_INACCURATE, Status.SOLVED)

    @property
    def is_infeasible(self) -> bool:
        return self in (Status.INFEASIBLE, Status.INFEASIBLE_INACCURATE)

    @property
    def is_limit(self) -> bool:
        """A budget ran out (iterations or time): the answer is the best found so far."""
        return self in (Status.ITERATION_LIMIT, Status.TIME_LIMIT)

    def __str__(self) -> str:  # "optimal", not "Status.OPTIMAL"
        return self.value


@dataclass(frozen=True)
class Check:
    """One independent check of a design.

    Attributes
    ----------
    name : str
        What is checked, e.g. ``"pole_error"``, ``"riccati_residual"``, ``"Q_min_eig"``.
    value : float
        The measured quantity.
    tolerance : float
        The bound it must satisfy.
    passed : bool
    sense : str
        ``"<="`` (value <= tolerance must hold) or ``">="``.
    detail : str
        Human-readable explanation.
    """

    name: str
    value: float
    tolerance: float
    passed: bool
    sense: str = "<="
    detail: str = ""

    @classmethod
    def at_most(cls, name: str, value: float, tolerance: float, detail: str = "") -> Check:
        v = float(value)
        return cls(name, v, float(tolerance), bool(v <= tolerance and not math.isnan(v)), "<=", detail)

    @classmethod
    def at_least(cls, name: str, value: float, tolerance: float, detail: str = "") -> Check:
        v = float(value)
        return cls(name, v, float(tolerance), bool(v >= tolerance and not math.isnan(v)), ">=", detail)

    def __str__(self) -> str:
        mark = "ok  " if self.passed else "FAIL"
        extra = f"  ({self.detail})" if self.detail else ""
        return f"[{mark}] {self.name} = {self.value:.3e} {self.sense} {self.tolerance:.3e}{extra}"


@dataclass(frozen=True)
class Verification:
    """The independent checks of a design (recomputed with numpy/scipy, not by the solver)."""

    checks: tuple[Check, ...] = ()

    @classmethod
    def of(cls, checks: Iterable[Check]) -> Verification:
        return cls(tuple(checks))

    @property
    def passed(self) -> bool:
        """True when there is at least one check and all pass."""
        return bool(self.checks) and all(c.passed for c in self.checks)

    @property
    def failed(self) -> tuple[Check, ...]:
        return tuple(c for c in self.checks if not c.passed)

    def __getitem__(self, name: str) -> Check:
        for c in self.checks:
            if c.name == name:
                return c
        raise KeyError(f"no check named {name!r}; have {[c.name for c in self.checks]}")

    def __contains__(self, name: object) -> bool:
        return any(c.name == name for c in self.checks)

    def __iter__(self) -> Iterator[Check]:
        return iter(self.checks)

    def __len__(self) -> int:
        return len(self.checks)

    def __add__(self, other: Verification) -> Verification:
        return Verification(self.checks + tuple(other.checks))

    def summary(self) -> str:
        return "\n".join(str(c) for c in self.checks) if self.checks else "(no checks)"

    def as_dict(self) -> dict[str, dict[str, Any]]:
        return {c.name: {"value": c.value, "tolerance": c.tolerance, "passed": c.passed,
                         "sense": c.sense, "detail": c.detail} for c in self.checks}


@dataclass(frozen=True)
class SolverStats:
    """What the backend reported.

    Attributes
    ----------
    backend : str
        e.g. ``"ipopt"``, ``"clarabel"``, ``"scs"``, ``"scipy"``, ``"analytic"``.
    native_status : str
        The backend's own status string, unmapped.
    time : float
        Wall time in seconds (formulation excluded where separable).
    iterations : int or None
    extra : dict
        Anything else (objective value, number of starts, ...).
    """

    backend: str
    native_status: str = ""
    time: float = 0.0
    iterations: int | None = None
    extra: dict[str, Any] = field(default_factory=dict)


#: the kinds of a route's stage
STAGE_KINDS = ("engine", "backend", "fallback", "polish", "certificate", "check", "direct")


@dataclass(frozen=True)
class Stage:
    """One stage of a result's route: what ran, of which kind, and how it ended.

    Attributes
    ----------
    name : str
        What ran, e.g. ``"one_output_form/dense_ipm"``, ``"ipopt"``, ``"eigenstructure_engine"``.
    kind : str
        One of ``engine`` (our own algorithm), ``backend`` (CasADi/IPOPT, cvxpy, Clarabel, scipy),
        ``fallback`` (a retry after a failure), ``polish``, ``certificate``, ``check``, ``direct``
        (a closed form or a linear-algebra solve).
    outcome : str
        ``"answered"`` for the stage that produced the returned answer; otherwise a status value
        (``"not_found"``, ``"infeasible"``, ...), ``"failed"``, ``"rejected"`` (its candidate did not
        pass the independent checks), ``"improved"``, ``"unchanged"`` or ``"skipped"``.
    detail : str
        One short phrase (the backend's own status, why a stage was skipped, ...).
    time : float or None
        CPU seconds of the stage, where measured.
    """

    name: str
    kind: str = "engine"
    outcome: str = "answered"
    detail: str = ""
    time: float | None = None

    def __post_init__(self) -> None:
        if self.kind not in STAGE_KINDS:
            raise ValueError(f"Stage kind must be one of {STAGE_KINDS}, found {self.kind!r}")

    def __str__(self) -> str:
        text = f"{self.name} [{self.kind}]: {self.outcome}"
        if self.detail:
            text += f" ({self.detail})"
        return text

    def as_dict(self) -> dict[str, Any]:
        return {"name": self.name, "kind": self.kind, "outcome": self.outcome, "detail": self.detail,
                "time": self.time}


class Route(tuple):
    """The stages a result went through, in order (cvxpy's solving chain, for design verbs).

    A tuple of :class:`Stage`; ``method`` on a result is what was asked, ``route`` what ran.  The
    stage that produced the answer has ``outcome == "answered"`` (:attr:`answered`); a result
    without an answer (``not_found``, ``infeasible``, ...) has none.

    Examples
    --------
    >>> r = Route([Stage("ipopt", "backend", "not_found"), Stage("engine", "fallback")])
    >>> str(r)
    'ipopt [backend]: not_found -> engine [fallback]: answered'
    >>> r.answered.name
    'engine'
    """

    def __new__(cls, stages: Iterable[Stage] = ()) -> Route:
        items = tuple(stages)
        for s in items:
            if not isinstance(s, Stage):
                raise TypeError(f"Route holds Stage objects, found {type(s).__name__}")
        return super().__new__(cls, items)

    @property
    def answered(self) -> Stage | None:
        """The stage that produced the answer (the last with outcome ``answered``), or None."""
        for s in reversed(self):
            if s.outcome == "answered":
                return s
        return None

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(s.name for s in self)

    def then(self, *stages: Stage) -> Route:
        """A new route with ``stages`` appended."""
        return Route((*self, *stages))

    def as_list(self) -> list[dict[str, Any]]:
        return [s.as_dict() for s in self]

    def __str__(self) -> str:
        return " -> ".join(str(s) for s in self) if self else "(none)"

    def __repr__(self) -> str:
        return f"Route({list(self)!r})"


def _plain(value: Any) -> Any:
    """A JSON-friendly form of a certificate or record value (arrays as lists; complex as
    ``{"re", "im"}``; objects with ``as_dict`` by that)."""
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    if isinstance(value, (np.floating, np.integer, np.bool_)):
        return value.item()
    if isinstance(value, complex):
        return {"re": value.real, "im": value.imag}
    if isinstance(value, np.ndarray):
        return ({"re": value.real.tolist(), "im": value.imag.tolist()} if np.iscomplexobj(value)
                else value.tolist())
    if hasattr(value, "as_dict"):
        return value.as_dict()
    if isinstance(value, Mapping):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    return repr(value)


class Certificate:
    """Evidence for a verdict: ``kind`` (a short code), ``reason`` (one sentence) and ``data``.

    The one certificate type of optdesign.  ``data`` holds the numbers behind the verdict (a
    frequency and an eigenvalue, an SDP margin, the closest poles found, ...); each is also
    readable as an attribute or item (``cert.omega``, ``cert["omega"]``) and is ``None`` when
    absent.  Immutable.

    Parameters
    ----------
    kind : str
    reason : str
    data : mapping, optional
    **more
        Further data entries (merged into ``data``).

    Examples
    --------
    >>> c = Certificate("return_difference", "T R T* - R < 0 at w = 7.3", omega=7.3)
    >>> c.kind, c.omega, c.margin
    ('return_difference', 7.3, None)
    """

    __slots__ = ("kind", "reason", "data")

    def __init__(self, kind: str, reason: str, data: Mapping[str, Any] | None = None, **more: Any) -> None:
        object.__setattr__(self, "kind", str(kind))
        object.__setattr__(self, "reason", str(reason))
        object.__setattr__(self, "data", {**dict(data or {}), **more})

    def __setattr__(self, name: str, value: Any) -> None:
        raise AttributeError(f"Certificate is immutable (cannot set {name!r})")

    def __getattr__(self, name: str) -> Any:
        if name.startswith("__"):
            raise AttributeError(name)
        return object.__getattribute__(self, "data").get(name)

    def __getitem__(self, name: str) -> Any:
        if name in ("kind", "reason"):
            return getattr(self, name)
        return self.data[name]

    def get(self, name: str, default: Any = None) -> Any:
        return self.data.get(name, default)

    def __contains__(self, name: object) -> bool:
        return name in ("kind", "reason") or name in self.data

    def as_dict(self) -> dict[str, Any]:
        """Plain-data form (JSON friendly)."""
        return {"kind": self.kind, "reason": self.reason,
                **{k: _plain(v) for k, v in self.data.items() if not hasattr(v, "omega_worst")}}

    def __str__(self) -> str:
        return f"{self.kind}: {self.reason}"

    def __repr__(self) -> str:
        keys = ", ".join(sorted(self.data))
        return f"Certificate(kind={self.kind!r}, reason={self.reason!r}, data keys: {keys or 'none'})"

    def __reduce__(self):  # picklable (sweeps send results between processes)
        return (Certificate, (self.kind, self.reason, self.data))


def html_value(value: Any) -> str:
    """One cell of an HTML report: numbers to 4-6 digits, poles as ``a +- bj``, small matrices in a
    ``<pre>`` block, large arrays by their shape (escaped)."""
    import html

    if isinstance(value, tuple) and value and all(isinstance(v, np.ndarray) for v in value):
        return "<br>".join(f"[{k}] {html_value(v)}" for k, v in enumerate(value))  # per model
    if isinstance(value, np.ndarray) or (isinstance(value, (list, tuple)) and value
                                         and all(isinstance(v, (int, float, complex, np.number)) for v in value)):
        a = np.asarray(value)
        if a.size > 64:
            return html.escape(f"array of shape {a.shape}")
        if a.ndim == 1 and np.iscomplexobj(a):
            text = ", ".join(f"{z.real:.4g}" if z.imag == 0 else f"{z.real:.4g}{z.imag:+.4g}j" for z in a)
            return html.escape(text)
        with np.printoptions(precision=4, suppress=True, linewidth=80):
            return f"<pre style='margin:0'>{html.escape(str(a))}</pre>"
    if isinstance(value, (float, np.floating)):
        return html.escape(f"{float(value):.6g}")
    return html.escape(str(value))


def html_table(title: str, rows: Iterable[tuple[str, str]]) -> str:
    """A two-column HTML table (``rows`` of already-escaped ``(name, value)`` cells) under a title."""
    import html

    body = "".join(f"<tr><th style='text-align:left'>{name}</th><td style='text-align:left'>{cell}</td></tr>"
                   for name, cell in rows)
    return f"<table><caption style='text-align:left'><b>{html.escape(title)}</b></caption>{body}</table>"


class ResultMixin:
    """Behaviour common to design results (needs ``status``, ``message``, ``verification``)."""

    status: Status
    message: str
    verification: Verification

    @property
    def success(self) -> bool:
        """Solved by the backend *and* passed every independent check."""
        return Status(self.status).is_solved and self.verification.passed

    def raise_for_status(self):
        """Return ``self`` if successful; otherwise raise InfeasibleError or SolverError."""
        if self.success:
            return self
        status = Status(self.status)
        if status.is_infeasible:
            raise InfeasibleError(self.message, certificate=getattr(self, "certificate", None))
        stats = getattr(self, "solver_stats", None)
        failed = "; ".join(str(c) for c in self.verification.failed)
        raise SolverError(
            f"{self.message} (status {status.value}" + (f"; failed checks: {failed}" if failed else "") + ")",
            backend=getattr(stats, "backend", ""), native_status=getattr(stats, "native_status", ""),
        )


def _no_stats() -> SolverStats:
    return SolverStats(backend="none")


@dataclass(frozen=True, kw_only=True, eq=False)
class DesignResult(ResultMixin):
    """The one result base of optdesign's design verbs (frozen, keyword-only).

    Every verb returns a subclass that adds its own fields (``L``, ``P``, ``Q``, ``poles``,
    ``kappa2``, ...).  Verbs *return* a result for every outcome a solver can produce --
    infeasible, not found, a limit, a numerical failure -- and *raise* only for bad input (a
    :class:`~optdesign.errors.ValidationError`) or a missing backend; :meth:`raise_for_status`
    turns an unsuccessful result into an exception when the caller prefers one.

    Attributes
    ----------
    status : Status
    message : str
        One line: what was done and why it ended so.
    solver_stats : SolverStats
    verification : Verification
        The independent checks (:mod:`optdesign.design.verification`).
    certificate : Certificate or None
        The evidence for an ``infeasible`` verdict (or for another claim the verb makes).
    target_poles : ndarray of complex or None
        The requested poles (fixed-pole questions).
    extra : dict
        Diagnostics of the run (per-stage reports, starts, ...).
    route : Route
        The stages that ran, in order, and which produced the answer (:class:`Route`).
    """

    status: Status
    message: str = ""
    solver_stats: SolverStats = field(default_factory=_no_stats)
    verification: Verification = field(default_factory=Verification)
    certificate: Certificate | None = None
    target_poles: Any = None
    extra: dict[str, Any] = field(default_factory=dict, repr=False)
    route: Route = field(default_factory=Route, repr=False)

    #: fields shown by :meth:`summary` and :meth:`record` beyond the common ones (subclasses)
    _summary_fields: tuple[str, ...] = field(default=(), init=False, repr=False)

    def summary(self) -> str:
        """Multi-line human-readable report: status, message, the verb's main fields, the
        certificate and every check."""
        lines = [f"{type(self).__name__}: status={Status(self.status).value}, success={self.success}",
                 f"  {self.message}"]
        for name in self._summary_fields:
            value = getattr(self, name, None)
            if value is None:
                continue
            if isinstance(value, np.ndarray):
                with np.printoptions(precision=6, linewidth=100, suppress=False):
                    body = np.array2string(value, prefix=f"  {name} = ")
                lines.append(f"  {name} = {body}")
            else:
                lines.append(f"  {name} = {value}")
        if self.certificate is not None:
            lines.append(f"  certificate: {self.certificate}")
        if self.route:
            lines.append(f"  route: {self.route}")
        if len(self.verification):
            lines.append("  verification:")
            lines.extend("    " + str(c) for c in self.verification)
        return "\n".join(lines)

    def record(self) -> dict[str, Any]:
        """A flat, JSON-friendly record for sweeps and tables: status, success, the scalar fields,
        and every check's value (``check:<name>``)."""
        out: dict[str, Any] = {"status": Status(self.status).value, "success": self.success}
        for f in fields(self):
            if f.name in ("status", "verification", "solver_stats", "extra", "certificate", "message", "route") \
                    or f.name.startswith("_"):
                continue
            v = getattr(self, f.name)
            if isinstance(v, (bool, int, float, str, np.floating, np.integer)):
                out[f.name] = _plain(v)
        out["time"] = self.solver_stats.time
        out["iterations"] = self.solver_stats.iterations
        out["certificate"] = None if self.certificate is None else self.certificate.kind
        answered = self.route.answered
        out["route"] = None if answered is None else answered.name
        for c in self.verification:
            out[f"check:{c.name}"] = c.value
        return out

    def plot(self, ax: Any = None, **kw: Any) -> Any:
        """A pole map of the design: its poles over its region, with the plant's open-loop poles.

        Robust designs draw every model's poles with the worst model marked.  See
        :func:`optdesign.plot.pole_map` / :func:`optdesign.plot.robust_pole_map` for the keywords.

        Returns
        -------
        matplotlib Axes

        Raises
        ------
        ValidationError
            The result has no poles (nothing was designed).
        BackendUnavailableError
            matplotlib is not installed.
        """
        from .plot.poles import plot_result

        return plot_result(self, ax=ax, **kw)

    def _repr_html_(self) -> str:
        """Jupyter's view: a compact table of status, message, the main numbers, the poles, the route
        and every check (value, bound, passed)."""
        import html

        rows = [("status", html.escape(f"{Status(self.status).value} (success: {self.success})")),
                ("message", html.escape(self.message))]
        names = list(self._summary_fields) or [  # a verb without summary fields: its usual main numbers
            n for n in ("L", "K", "P", "Q", "residual", "kappa2", "objective_value", "value") if hasattr(self, n)]
        if "poles" not in names and getattr(self, "poles", None) is not None:
            names.append("poles")
        for name in names:
            value = getattr(self, name, None)
            if value is not None:
                per_model = isinstance(value, tuple) and name == "poles"
                rows.append((html.escape(name + (" (per model)" if per_model else "")), html_value(value)))
        if self.certificate is not None:
            rows.append(("certificate", html.escape(str(self.certificate))))
        if self.route:
            rows.append(("route", html.escape(str(self.route))))
        checks = "".join(
            f"<tr><td>{'ok' if c.passed else '<b>FAIL</b>'}</td><td>{html.escape(c.name)}</td>"
            f"<td>{c.value:.3e} {html.escape(c.sense)} {c.tolerance:.3e}</td></tr>" for c in self.verification)
        if checks:
            rows.append(("checks", f"<table>{checks}</table>"))
        return html_table(type(self).__name__, rows)
