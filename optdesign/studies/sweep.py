"""Parameter sweeps over design functions, on any ``concurrent.futures``-style executor.

A sweep evaluates ``design_fn(**point)`` for every point of a grid and returns a
:class:`SweepTable` of records (inputs, status, success, metrics, time, error).  Failures are
recorded, never raised: an exception in the design function, a point that times out or a worker
process that dies becomes a record with ``success=False`` and a one-line ``error``; one bad point
cannot crash a 1,000-point study.

Executors
---------
Anything with ``submit(fn, *args) -> concurrent.futures.Future``: a local process pool (the
default, one worker per available core), a thread pool, :class:`InlineExecutor` (in-process,
serial: debugging, small studies, Pareto fronts), or a Dask cluster's executor
(``client.get_executor()``; a ``dask.distributed.Client`` itself is accepted too) -- unchanged.

Chunks and re-use
-----------------
Points are sent to the workers in *chunks* (consecutive points of the grid), so that the
per-task overhead is amortized and each worker re-uses what it built: the designers of
:mod:`optdesign.studies.designers` build their CasADi problem once per worker process and
re-solve it with new parameter values.  A design function may also carry state from one point
to the next *within a chunk* (warm starts): if it has a method ``start_chunk()``, the worker
calls it at the start of every chunk and evaluates the chunk's points with the callable it
returns.  The chunking depends only on the number of points (never on the executor or the
number of workers) and every chunk starts from a clean state, so a sweep gives identical
results on a process pool, a thread pool, in-process or on a Dask cluster.
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import csv
import dataclasses
import io
import itertools
import json
import math
import multiprocessing
import os
import pickle
import queue
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .._progress import Progress, as_progress
from .._validate import as_int
from ..errors import ValidationError
from .output import write_text
from .reasons import (  # re-exported: their home was this module
    IPOPT_MEANING,
    STATUS_MEANING,
    failure_reason,
    one_line_error,
    plain_reason,
    reason_of,
)

__all__ = [
    "grid",
    "sweep",
    "SweepTable",
    "record_of",
    "InlineExecutor",
    "default_chunksize",
    "TIMING_COLUMNS",
    "failure_reason",
    "plain_reason",
    "one_line_error",
    "STATUS_MEANING",
    "IPOPT_MEANING",
    "MAX_GRID_POINTS",
]

#: the most points :func:`grid` builds (and a study spec's grid may have): counted from the axes'
#: lengths before anything is built.  At ~0.1-10 s a point, 10^5 points are hours to days of
#: work; a larger study is split into several grids (or this limit raised deliberately).
MAX_GRID_POINTS = 100_000

#: columns that depend on the machine and the scheduling, not on the design (ignored by
#: :meth:`SweepTable.diff`)
TIMING_COLUMNS = ("time", "solver_time", "worker")

#: bounds of the default chunk size (see :func:`default_chunksize`)
_MAX_CHUNK = 32
_MIN_TASKS = 16


def grid(**axes: Iterable[Any] | Any) -> list[dict[str, Any]]:
    """Cartesian product of named axes, as a list of points (dicts), last axis fastest.

    Parameters
    ----------
    **axes : iterable or scalar
        One axis per keyword: a list, tuple, range, numpy array or any iterable of values
        (a string or a single number is one value).

    Returns
    -------
    list of dict
        At most :data:`MAX_GRID_POINTS` points: the number is counted from the axes' lengths
        before any point is built.

    Raises
    ------
    ValidationError
        No axis, an empty axis, or more than :data:`MAX_GRID_POINTS` points (the message gives
        each axis's length).

    Examples
    --------
    >>> grid(alpha=[1, 2], zeta=[0.5])
    [{'alpha': 1, 'zeta': 0.5}, {'alpha': 2, 'zeta': 0.5}]
    """
    if not axes:
        raise ValidationError("grid needs at least one axis, e.g. grid(alpha=[1, 2])")
    names = list(axes)
    values = []
    lengths: dict[str, int] = {}

    def check(k: str, length: int) -> None:
        lengths[k] = length
        count = math.prod(lengths.values())
        if count > MAX_GRID_POINTS:
            sizes = " x ".join(f"{a} {m}" for a, m in lengths.items())
            raise ValidationError(f"grid: {sizes} is {'at least ' if len(lengths) < len(names) else ''}"
                                  f"{count} points; at most {MAX_GRID_POINTS} "
                                  "(optdesign.studies.sweep.MAX_GRID_POINTS): split the study")

    for k in names:
        v = axes[k]
        if isinstance(v, (str, bytes)) or not isinstance(v, Iterable):
            items = [v]
        elif isinstance(v, np.ndarray):
            check(k, v.size)
            items = list(v.ravel())
        else:
            if hasattr(v, "__len__"):
                check(k, len(v))  # type: ignore[arg-type]
            items = list(itertools.islice(v, MAX_GRID_POINTS + 1))
        if not items:
            raise ValidationError(f"grid axis {k!r} is empty")
        check(k, len(items))
        values.append([x.item() if isinstance(x, np.generic) else x for x in items])
    return [dict(zip(names, combo, strict=True)) for combo in itertools.product(*values)]


_SCALAR = (int, float, bool, str, np.integer, np.floating, np.bool_)


def record_of(result: Any) -> dict[str, Any]:
    """Flatten a design result into scalar columns (status, success, numeric and str fields).

    An unsuccessful result gets a ``reason`` column (its first failed check and its message, one
    line); it is None for successful ones.

    Uses ``result.record()`` when the result defines it; otherwise every scalar field of a
    dataclass (or mapping) is taken, plus ``success`` and ``status``.  A ``time`` entry of the
    result (solver time) is renamed ``solver_time``: the sweep's ``time`` column is the wall time
    of the point in its worker.
    """
    if hasattr(result, "record") and callable(result.record):
        out = dict(result.record())
    elif dataclasses.is_dataclass(result) and not isinstance(result, type):
        out = {f.name: getattr(result, f.name) for f in dataclasses.fields(result)}
    elif isinstance(result, Mapping):
        out = dict(result)
    else:
        out = {"value": result}
    flat: dict[str, Any] = {}
    for k, v in out.items():
        if isinstance(v, _SCALAR) or v is None:
            flat[k] = v.item() if isinstance(v, np.generic) else v
        elif isinstance(getattr(v, "value", None), str):  # enums such as Status
            flat[k] = v.value
    for k in ("status", "success"):
        if k not in flat and hasattr(result, k):
            v = getattr(result, k)
            flat[k] = getattr(v, "value", v)
    if "reason" not in flat and "success" in flat:
        flat["reason"] = (None if flat["success"]
                          else reason_of(result, flat.get("status"), out.get("message")))
    stats = out.get("solver_stats", getattr(result, "solver_stats", None))
    if "time" in flat:
        flat["solver_time"] = flat.pop("time")
    elif stats is not None and hasattr(stats, "time"):
        flat["solver_time"] = float(stats.time)
    return flat


def _run_chunk(design_fn: Callable[..., Any], chunk: Sequence[tuple[int, dict[str, Any]]],
               keep: bool = False, notify: Any = None) -> list[tuple]:
    """Evaluate one chunk in a worker; never raises for a failing point.

    ``notify`` (optional, anything with ``put``: a queue) receives ``(index, success)`` after every
    point, for the progress report; it never changes what is computed.
    """
    fn = design_fn
    start = getattr(design_fn, "start_chunk", None)
    setup_error = None
    if callable(start):
        try:
            fn = start()
        except Exception as exc:  # noqa: BLE001 - recorded for every point of the chunk
            setup_error = one_line_error(exc)
    rows = []
    for index, point in chunk:
        t0 = time.perf_counter()
        res = None
        if setup_error is not None:
            rec, err = {"status": "error", "success": False}, setup_error
        else:
            try:
                res = fn(**point)
                rec = record_of(res)
                err = None
            except Exception as exc:  # noqa: BLE001 - a sweep records failures, never crashes
                rec = {"status": "error", "success": False}
                err = one_line_error(exc)
        if err is not None:
            rec["reason"] = failure_reason("error", err)
        rows.append((index, rec, time.perf_counter() - t0, err, os.getpid(), res if keep else None))
        if notify is not None:
            try:
                notify.put((index, bool(rec.get("success"))))
            except Exception:  # noqa: BLE001 - progress is never worth losing a point
                pass
    return rows


@dataclass
class SweepTable:
    """Records of a sweep, in the order of the points.

    Each record is a flat dict: the input point's keys, then ``status``, ``success``, metric
    columns, ``solver_time`` (when the result reports one), ``time`` (wall seconds for that
    point in its worker), ``error`` (None or one line) and ``worker`` (process id).

    Attributes
    ----------
    records : list of dict
    inputs : tuple of str
        The input columns (the keys of the points).
    wall_time : float
        Seconds for the whole sweep.
    results : list or None
        The design results themselves (``sweep(..., keep_results=True)``), None for failures.
    meta : dict
        How the sweep ran (executor, chunksize, number of chunks).
    """

    records: list[dict[str, Any]] = field(default_factory=list)
    inputs: tuple[str, ...] = ()
    wall_time: float = 0.0
    results: list[Any] | None = None
    meta: dict[str, Any] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.records)

    def __iter__(self):
        return iter(self.records)

    def __getitem__(self, i: int) -> dict[str, Any]:
        return self.records[i]

    @property
    def columns(self) -> list[str]:
        """Every column, inputs first, then in order of first appearance."""
        cols: list[str] = list(self.inputs)
        for r in self.records:
            for k in r:
                if k not in cols:
                    cols.append(k)
        return cols

    def column(self, name: str) -> np.ndarray:
        """One column as a float array (missing entries -> nan), or an object array if not numeric.

        Raises
        ------
        ValidationError
            No record has this column.
        """
        if name not in self.columns:
            raise ValidationError(f"the sweep table has no column {name!r}; columns: "
                                  f"{', '.join(self.columns)}")
        vals = [r.get(name) for r in self.records]
        if all(v is None or (isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool))
               for v in vals):
            return np.asarray([np.nan if v is None else v for v in vals], dtype=float)
        return np.asarray(vals, dtype=object)

    @property
    def failures(self) -> list[dict[str, Any]]:
        """Records whose design did not succeed (error, solver failure or failed verification)."""
        return [r for r in self.records if not r.get("success")]

    @property
    def n_success(self) -> int:
        return sum(1 for r in self.records if r.get("success"))

    def pivot(self, x: str, y: str, value: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(xs, ys, Z)`` with ``Z[i, j]`` the ``value`` at ``x = xs[j]``, ``y = ys[i]`` (nan where absent).

        For heat maps of two-axis sweeps; failed points keep whatever value they recorded
        (usually nan).
        """
        xv, yv, zv = self.column(x), self.column(y), self.column(value)
        xs = np.unique(xv[~np.isnan(xv)]) if xv.dtype != object else np.unique(xv)
        ys = np.unique(yv[~np.isnan(yv)]) if yv.dtype != object else np.unique(yv)
        Z = np.full((ys.size, xs.size), np.nan)
        xi = {v: j for j, v in enumerate(xs.tolist())}
        yi = {v: i for i, v in enumerate(ys.tolist())}
        for a, b, c in zip(xv.tolist(), yv.tolist(), zv.tolist(), strict=True):
            if a in xi and b in yi:
                try:
                    Z[yi[b], xi[a]] = float(c)
                except (TypeError, ValueError):
                    pass
        return xs, ys, Z

    def diff(self, other: SweepTable, *, ignore: Iterable[str] = TIMING_COLUMNS,
             rtol: float = 0.0) -> list[str]:
        """Cells that differ from ``other`` (empty list: identical results).

        Parameters
        ----------
        other : SweepTable
        ignore : iterable of str
            Columns not compared (default: the timing and worker columns).
        rtol : float
            Relative tolerance for floats (default 0: bit-identical).
        """
        ign = set(ignore)
        out: list[str] = []
        if len(self) != len(other):
            return [f"{len(self)} records vs {len(other)}"]
        for i, (a, b) in enumerate(zip(self.records, other.records, strict=True)):
            for k in sorted((set(a) | set(b)) - ign):
                va, vb = a.get(k), b.get(k)
                if isinstance(va, float) and isinstance(vb, float):
                    if math.isnan(va) and math.isnan(vb):
                        continue
                    if va == vb or (rtol > 0 and abs(va - vb) <= rtol * max(abs(va), abs(vb))):
                        continue
                elif va == vb:
                    continue
                out.append(f"record {i} column {k!r}: {va!r} vs {vb!r}")
        return out

    def to_csv(self, path: str | os.PathLike, *, overwrite: bool = False) -> Path:
        """Write every record (one row per point, :attr:`columns` as header).

        The file is written whole under a temporary name and renamed (never through a symbolic
        link; :mod:`optdesign.studies.output`).

        Raises
        ------
        OutputExistsError
            ``path`` exists (a file or a symbolic link) and ``overwrite`` is False.
        OutputPathError
            A folder at ``path``, or a path with a NUL byte.
        """
        cols = self.columns
        buf = io.StringIO(newline="")
        w = csv.DictWriter(buf, fieldnames=cols)
        w.writeheader()
        for r in self.records:
            w.writerow({k: ("" if r.get(k) is None else repr(r[k]) if isinstance(r.get(k), float)
                            else r.get(k)) for k in cols})
        return write_text(path, buf.getvalue(), overwrite=overwrite, newline="")

    @classmethod
    def from_csv(cls, path: str | os.PathLike, inputs: Sequence[str] = ()) -> SweepTable:
        """Read a table written by :meth:`to_csv` (numbers, booleans and empty cells decoded)."""

        def decode(s: str) -> Any:
            if s == "":
                return None
            if s in ("True", "False"):
                return s == "True"
            for typ in (int, float):
                try:
                    return typ(s)
                except ValueError:
                    pass
            return s

        with Path(path).open(newline="", encoding="utf-8") as fh:
            rows = [{k: decode(v) for k, v in r.items()} for r in csv.DictReader(fh)]
        return cls(records=rows, inputs=tuple(inputs))

    def to_json(self, path: str | os.PathLike | None = None, *, overwrite: bool = False) -> str:
        """JSON text of the table (non-finite floats as the strings ``"inf"``, ``"-inf"``, ``"nan"``),
        also written to ``path`` when given (as :meth:`to_csv`: whole, renamed, never over an
        existing file unless ``overwrite``).

        Raises
        ------
        OutputExistsError
            ``path`` exists (a file or a symbolic link) and ``overwrite`` is False.
        OutputPathError
            A folder at ``path``, or a path with a NUL byte.
        """

        def clean(v):
            if isinstance(v, float) and not math.isfinite(v):
                return str(v)
            return v

        text = json.dumps({"inputs": list(self.inputs), "wall_time": self.wall_time, "meta": self.meta,
                           "records": [{k: clean(v) for k, v in r.items()} for r in self.records]},
                          indent=1, default=str)
        if path is not None:
            write_text(path, text, overwrite=overwrite)
        return text

    def summary(self) -> str:
        """One line: points, successes, failures, wall time."""
        ok = self.n_success
        errors = sum(1 for r in self.records if r.get("error"))
        return (f"{len(self)} points, {ok} successful, {len(self) - ok} failed"
                f"{f' ({errors} with errors)' if errors else ''}, wall {self.wall_time:.2f} s")


class InlineExecutor(cf.Executor):
    """A ``concurrent.futures.Executor`` that runs each task immediately in the calling thread.

    For debugging, tests and small studies (no process start-up, no pickling).
    """

    def __init__(self) -> None:
        self._shutdown = False

    def submit(self, fn, /, *args, **kwargs):
        if self._shutdown:
            raise RuntimeError("cannot submit to an InlineExecutor after shutdown")
        fut: cf.Future = cf.Future()
        try:
            fut.set_result(fn(*args, **kwargs))
        except BaseException as exc:  # noqa: BLE001 - delivered through the future
            fut.set_exception(exc)
        return fut

    def shutdown(self, wait: bool = True, *, cancel_futures: bool = False) -> None:
        self._shutdown = True


def _available_cores() -> int:
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


def default_chunksize(n_points: int) -> int:
    """Points per task when ``chunksize`` is not given: ``min(32, ceil(n / 16))``, at least 1.

    It depends on the number of points only (never on the executor), so results that carry
    warm starts within a chunk are identical on every executor; at least 16 tasks keep a
    cluster of several workers busy.
    """
    return max(1, min(_MAX_CHUNK, math.ceil(n_points / _MIN_TASKS)))


def _resolve_executor(executor: Any, workers: int | None, n_points: int) -> tuple[cf.Executor, bool, str]:
    """``(executor, owned, label)``."""
    if executor is None or executor == "processes":
        w = workers or min(_available_cores(), n_points)
        return cf.ProcessPoolExecutor(max_workers=max(1, w)), True, f"processes({max(1, w)})"
    if executor == "threads":
        w = workers or min(_available_cores(), n_points)
        return cf.ThreadPoolExecutor(max_workers=max(1, w)), True, f"threads({max(1, w)})"
    if executor in ("serial", "inline"):
        return InlineExecutor(), True, "serial"
    if isinstance(executor, str):
        raise ValidationError(
            f"executor must be a concurrent.futures.Executor, a dask Client, or one of 'processes', "
            f"'threads', 'serial'; found {executor!r}")
    is_client = type(executor).__module__.startswith("distributed")
    if is_client and callable(getattr(executor, "get_executor", None)):
        # a dask.distributed.Client: its concurrent.futures interface; pure=False so that a repeated
        # sweep is recomputed (and timed), not served from Dask's cache of identical tasks
        return executor.get_executor(pure=False), False, "dask"
    if not callable(getattr(executor, "submit", None)):
        raise ValidationError(
            f"executor must have a submit(fn, *args) method (concurrent.futures.Executor); "
            f"found {type(executor).__name__}")
    label = type(executor).__name__
    if "distributed" in type(executor).__module__:
        label = "dask"
    return executor, False, label


def _check_picklable(design_fn: Any) -> None:
    try:
        pickle.dumps(design_fn)
    except Exception as exc:  # noqa: BLE001 - any pickling failure
        raise ValidationError(
            f"design_fn must be picklable to run on a process pool (a module-level function or a "
            f"designer object, not a lambda or a local function); pickling failed: {exc}") from None


class _Direct:
    """A ``put`` that updates the progress report at once (in-process executors)."""

    def __init__(self, tracker: _PointTracker) -> None:
        self.tracker = tracker

    def put(self, item: tuple[int, bool]) -> None:
        self.tracker.point(*item)


class _PointTracker:
    """Counts finished points once each (from the workers' notices or from a finished chunk)."""

    def __init__(self, bar: Progress) -> None:
        self.bar = bar
        self.seen: set[int] = set()
        self.failed = 0

    def point(self, index: int, ok: bool) -> None:
        if index in self.seen:
            return
        self.seen.add(index)
        self.failed += not ok
        self.bar.update(1, note=f"{self.failed} failed" if self.failed else "")

    def drain(self, channel: Any) -> None:
        while channel is not None:
            try:
                item = channel.get_nowait()
            except queue.Empty:
                return
            except (OSError, EOFError):  # the manager went away
                return
            self.point(*item)


def _notice_channel(exe: Any, tracker: _PointTracker, stack: contextlib.ExitStack) -> Any:
    """Where workers report finished points: direct (in-process), a queue (threads), a manager
    queue (process pools; started only when progress is shown), None for other executors (Dask:
    the report then advances per chunk)."""
    if not tracker.bar.enabled:
        return None
    if isinstance(exe, InlineExecutor):
        return _Direct(tracker)
    if isinstance(exe, cf.ThreadPoolExecutor):
        return queue.SimpleQueue()
    if isinstance(exe, cf.ProcessPoolExecutor):
        try:
            manager = stack.enter_context(multiprocessing.Manager())
            return manager.Queue()
        except (OSError, EOFError, RuntimeError):  # no manager process: per-chunk progress
            return None
    return None


def _kill_pool(executor: cf.ProcessPoolExecutor) -> None:
    """Stop an owned process pool whose workers may be stuck (after a timeout)."""
    # before Python 3.14 (terminate_workers) there is no public way to stop a busy worker: terminate
    # our own processes -- taken before shutdown(), which forgets them
    procs = list((getattr(executor, "_processes", None) or {}).values())
    executor.shutdown(wait=False, cancel_futures=True)
    for proc in procs:
        try:
            proc.terminate()
        except Exception:  # noqa: BLE001 - already gone
            pass


def _wait_all(futures: dict[cf.Future, list], collect: Callable[[cf.Future, list], None],
              tracker: _PointTracker, channel: Any, timeout: float | None) -> bool:
    """Collect every future as it finishes, reporting the workers' per-point notices in between;
    True if ``timeout`` (seconds from now) ran out first."""
    start = time.perf_counter()
    pending = set(futures)
    poll = 0.2 if channel is not None else None
    while pending:
        wait = poll
        if timeout is not None:
            left = timeout - (time.perf_counter() - start)
            if left <= 0:
                return True
            wait = left if wait is None else min(wait, left)
        done, pending = cf.wait(pending, timeout=wait, return_when=cf.FIRST_COMPLETED)
        tracker.drain(channel)
        for fut in done:
            collect(fut, futures[fut])
    return False


def sweep(
    design_fn: Callable[..., Any],
    points: Sequence[Mapping[str, Any]] | Mapping[str, Iterable[Any]],
    *,
    executor: Any = None,
    progress: bool | None = None,
    chunksize: int | None = None,
    timeout: float | None = None,
    workers: int | None = None,
    keep_results: bool = False,
) -> SweepTable:
    """Evaluate ``design_fn(**point)`` over ``points`` and tabulate the results.

    Parameters
    ----------
    design_fn : callable
        Returns a design result (anything with ``status``/``success`` and scalar fields, a
        ``record()`` method, or a dict).  It runs in the workers, so for a process pool it must
        be picklable (module-level function, or a designer object of
        :mod:`optdesign.studies.designers`).  See the module docstring for ``start_chunk``.
    points : sequence of dict, or dict of axes
        Points (e.g. from :func:`grid`), or the axes themselves (``{"alpha": [...], ...}``,
        passed to :func:`grid`).
    executor : Executor, dask Client, or {"processes", "threads", "serial"}, optional
        Default (None or ``"processes"``): a local process pool with one worker per available
        core, created and shut down here.  ``"threads"``: a thread pool; ``"serial"``: in-process
        (:class:`InlineExecutor`).  Any ``concurrent.futures.Executor`` is used as is and not shut
        down (e.g. ``client.get_executor()`` of a Dask cluster; a Dask ``Client`` is accepted too).
    progress : bool or None
        Report progress on stderr, one step per finished point (``optdesign._progress.Progress``:
        a tqdm bar on a terminal, plain lines otherwise), once the sweep has run for a second.
        ``None`` (default): only when stderr is a terminal; ``True``: always; ``False``: never.
        Per-point reports come from in-process, thread and process-pool executors; other
        executors (Dask) report per chunk.
    chunksize : int, optional
        Points per task; default :func:`default_chunksize` (depends on the number of points only).
    timeout : float, optional
        Seconds to wait for the whole sweep; points not finished by then are recorded as
        failures (``error`` says so) and their tasks are cancelled (an owned process pool is
        terminated).
    workers : int, optional
        Size of the pool created for ``executor`` None / ``"processes"`` / ``"threads"``.
    keep_results : bool, default False
        Also return the design results (``SweepTable.results``); they travel back from the
        workers, so keep it off for big sweeps.

    Returns
    -------
    SweepTable
        Records in the order of ``points``; failures recorded with ``success=False`` and
        ``error`` (None when the design ran but did not succeed).

    Raises
    ------
    ValidationError
        No points, a point that is not a mapping with string keys, ``design_fn`` not callable or
        (process pools) not picklable, bad ``chunksize`` / ``timeout`` / ``workers`` / ``progress`` /
        executor.

    Examples
    --------
    >>> from optdesign.studies import sweep, grid
    >>> t = sweep(lambda a: {"status": "optimal", "success": True, "y": a * a},
    ...           grid(a=[1, 2, 3]), executor="serial")
    >>> t.column("y").tolist()
    [1.0, 4.0, 9.0]
    """
    if isinstance(points, Mapping):
        points = grid(**points)
    if isinstance(points, (str, bytes)) or not isinstance(points, Iterable):
        raise ValidationError("points must be a sequence of dicts (e.g. from grid()); found "
                              f"{type(points).__name__}")
    pts = []
    for i, p in enumerate(points):
        if not isinstance(p, Mapping) or not all(isinstance(k, str) for k in p):
            raise ValidationError(f"point {i} must be a dict with string keys; found {p!r}")
        pts.append(dict(p))
    if not pts:
        raise ValidationError("sweep needs at least one point")
    if not callable(design_fn):
        raise ValidationError(f"design_fn must be callable; found {type(design_fn).__name__}")
    if chunksize is not None:
        chunksize = as_int("chunksize", chunksize, 1)
    if timeout is not None and not (isinstance(timeout, (int, float)) and timeout > 0):
        raise ValidationError(f"timeout must be a positive number of seconds; found {timeout!r}")
    if workers is not None:
        workers = as_int("workers", workers, 1)
    progress = as_progress(progress)
    inputs = tuple(dict.fromkeys(k for p in pts for k in p))
    if executor is None or executor == "processes" or isinstance(executor, cf.ProcessPoolExecutor):
        _check_picklable(design_fn)
    exe, own, label = _resolve_executor(executor, workers, len(pts))
    size = chunksize if chunksize is not None else default_chunksize(len(pts))
    indexed = list(enumerate(pts))
    chunks = [indexed[i:i + size] for i in range(0, len(indexed), size)]
    t0 = time.perf_counter()
    rows: list[Any] = [None] * len(pts)
    results: list[Any] = [None] * len(pts)

    def fill(index: int, rec: dict, dt: float, err: str | None, pid: int | None, res: Any = None) -> None:
        row = dict(pts[index])
        row.update({k: v for k, v in rec.items() if k not in pts[index]})
        row["time"] = dt
        row["error"] = err
        row["worker"] = pid
        rows[index] = row
        results[index] = res

    def fail_chunk(chunk, message: str) -> None:
        for index, _ in chunk:
            if rows[index] is None:
                fill(index, {"status": "error", "success": False}, float("nan"), message, None)

    stack = contextlib.ExitStack()
    bar = stack.enter_context(Progress(len(pts), "sweep", enabled=progress, unit="point", delay=1.0))
    tracker = _PointTracker(bar)
    channel = _notice_channel(exe, tracker, stack)
    timed_out = False
    futures: dict[cf.Future, list] = {}

    def collect(fut: cf.Future, chunk) -> None:
        try:
            out = fut.result()
        except Exception as exc:  # noqa: BLE001 - worker died, task lost, pickling...
            fail_chunk(chunk, f"task failed in the executor: {one_line_error(exc)}")
        else:
            for index, rec, dt, err, pid, res in out:
                fill(index, rec, dt, err, pid, res)
        if not isinstance(channel, _Direct):
            tracker.drain(channel)
        for index, _ in chunk:
            tracker.point(index, bool(rows[index] and rows[index].get("success")))

    try:
        if isinstance(exe, InlineExecutor):
            # in-process: one chunk at a time, so that the bar and the timeout follow the work
            for chunk in chunks:
                if timeout is not None and time.perf_counter() - t0 > timeout:
                    timed_out = True
                    fail_chunk(chunk, f"timed out: not started within timeout={timeout:g} s")
                    continue
                collect(exe.submit(_run_chunk, design_fn, chunk, keep_results, channel), chunk)
        else:
            for chunk in chunks:
                try:
                    futures[exe.submit(_run_chunk, design_fn, chunk, keep_results, channel)] = chunk
                except Exception as exc:  # noqa: BLE001 - e.g. a broken pool: record, keep going
                    fail_chunk(chunk, f"could not submit: {one_line_error(exc)}")
            timed_out = _wait_all(futures, collect, tracker, channel, timeout)
            if timed_out:
                for fut, chunk in futures.items():
                    if not fut.done():
                        fut.cancel()
                        fail_chunk(chunk, f"timed out: not finished within timeout={timeout:g} s")
    except BaseException:
        for fut in futures:
            fut.cancel()
        if own:
            if isinstance(exe, cf.ProcessPoolExecutor):
                _kill_pool(exe)
            else:
                exe.shutdown(wait=False, cancel_futures=True)
            own = False
        raise
    finally:
        if own:
            if timed_out and isinstance(exe, cf.ProcessPoolExecutor):
                _kill_pool(exe)
            else:
                exe.shutdown(wait=not timed_out, cancel_futures=True)
        stack.close()
    meta = {"executor": label, "chunksize": size, "chunks": len(chunks), "timed_out": timed_out}
    return SweepTable(records=rows, inputs=inputs, wall_time=time.perf_counter() - t0,
                      results=results if keep_results else None, meta=meta)
