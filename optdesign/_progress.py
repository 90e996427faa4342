"""Progress reports for long runs, on stderr (private module, public names).

One rule for every long command and verb: progress goes to **stderr** (stdout keeps the results,
so ``optdesign study ... --json > out.json`` stays clean), and by default only when stderr is a
terminal -- ``progress=True`` (``--progress``) forces it, ``progress=False`` (``--no-progress``)
silences it.  On a terminal with tqdm installed a bar is drawn; otherwise (no tqdm, or progress
forced into a log file) plain lines are written, at most one every ``interval`` seconds plus the
first and the last, so that a log stays readable.

In a Jupyter notebook (an IPython kernel; its stderr is not a terminal) the automatic setting
reports too, so a long design in a notebook is not silent: a ``tqdm.auto`` widget bar where tqdm
and ipywidgets are installed, plain lines in the cell's output otherwise.

Use it as a context manager around a loop::

    with Progress(total=len(starts), desc="multi-start", unit="start", enabled=progress) as bar:
        for start in starts:
            ...
            bar.update(1, note=f"best kappa2 {best:.4g}")

or :meth:`Progress.line` for one-off events (``"seed 001: wrote seed001_fig2.png"``).  A disabled
report costs nothing and writes nothing.
"""

from __future__ import annotations

import sys
import time
from typing import IO, Any

from .errors import ValidationError

__all__ = ["Progress", "as_progress", "progress_enabled", "in_notebook"]


def as_progress(value: Any, name: str = "progress") -> bool | None:
    """``None`` (automatic: only on a terminal), ``True`` (always) or ``False`` (never).

    Raises
    ------
    ValidationError
        Anything else (a string such as ``"yes"``, a number): the message names the argument.
    """
    if value is None or isinstance(value, bool):
        return value
    try:
        import numpy as np

        if isinstance(value, np.bool_):
            return bool(value)
    except ImportError:  # pragma: no cover - numpy is a hard dependency
        pass
    raise ValidationError(f"{name} must be True, False or None (automatic: only on a terminal); "
                          f"found {value!r}")


def _isatty(stream: Any) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError, OSError):  # closed or replaced stream
        return False


def in_notebook() -> bool:
    """True inside a Jupyter kernel (IPython's ``ZMQInteractiveShell``), without importing IPython."""
    ipython = sys.modules.get("IPython")
    if ipython is None:
        return False
    try:
        shell = ipython.get_ipython()
    except Exception:  # noqa: BLE001 - a broken or partial IPython means: not a notebook
        return False
    return shell is not None and type(shell).__name__ == "ZMQInteractiveShell"


def progress_enabled(progress: bool | None, stream: IO[str] | None = None) -> bool:
    """Whether to report: ``progress`` if it is a bool, else whether ``stream`` (default stderr) is
    a terminal -- or the process's stderr inside a Jupyter notebook (:func:`in_notebook`)."""
    progress = as_progress(progress)
    if progress is not None:
        return progress
    if (stream is None or stream is sys.stderr) and in_notebook():
        return True
    return _isatty(sys.stderr if stream is None else stream)


def _tqdm_class(notebook: bool = False):
    """tqdm's bar class: ``tqdm.auto`` in a notebook (only with ipywidgets, which its widget needs),
    plain ``tqdm`` on a terminal; None when not installed."""
    try:
        if notebook:
            import ipywidgets  # type: ignore[import-not-found, import-untyped, unused-ignore]  # noqa: F401
            from tqdm.auto import tqdm  # type: ignore[import-untyped]
        else:
            from tqdm import tqdm  # type: ignore[import-untyped]  # optional: optdesign-control[progress]
    except ImportError:
        return None
    return tqdm


def _duration(seconds: float) -> str:
    if seconds < 60:
        return f"{seconds:.1f} s"
    m, s = divmod(int(round(seconds)), 60)
    return f"{m} min {s:02d} s" if m < 60 else f"{m // 60} h {m % 60:02d} min"


class Progress:
    """A progress report on stderr: a tqdm bar on a terminal, plain lines otherwise.

    Parameters
    ----------
    total : int or None
        Number of steps (None: unknown; lines then show the count only).
    desc : str
        What is being counted, shown first (``"sweep"``, ``"multi-start"``).
    enabled : bool or None
        ``None`` (default): only when ``stream`` is a terminal; ``True``: always; ``False``: never
        (:func:`progress_enabled`).
    unit : str
        Name of one step (``"point"``, ``"start"``, ``"paper"``).
    stream : text stream, optional
        Default ``sys.stderr`` (looked up when the report starts, so that a redirected stderr is
        honoured).
    interval : float
        Plain lines: at most one per ``interval`` seconds between the first and the last.
    bar : bool or None
        Draw a tqdm bar: ``None`` (default) when tqdm is installed and ``stream`` is a terminal.
    delay : float
        Seconds before anything is shown (a run shorter than that stays silent); default 0.

    Raises
    ------
    ValidationError
        ``enabled`` or ``bar`` not a bool or None, ``total`` not a non-negative integer or None,
        ``interval`` or ``delay`` negative.

    Examples
    --------
    >>> import io
    >>> out = io.StringIO()
    >>> with Progress(2, "demo", enabled=True, stream=out, unit="step") as p:
    ...     p.update(note="first")
    ...     p.update(note="second")
    >>> print(out.getvalue().splitlines()[-1].split(" (")[0])
    demo: 2/2 steps
    """

    def __init__(self, total: int | None, desc: str, *, enabled: bool | None = None, unit: str = "step",
                 stream: IO[str] | None = None, interval: float = 5.0, bar: bool | None = None,
                 delay: float = 0.0) -> None:
        if total is not None and (isinstance(total, bool) or not isinstance(total, int) or total < 0):
            raise ValidationError(f"total must be an integer >= 0 or None; found {total!r}")
        for key, val in (("interval", interval), ("delay", delay)):
            if not isinstance(val, (int, float)) or isinstance(val, bool) or not val >= 0:
                raise ValidationError(f"{key} must be a number of seconds >= 0; found {val!r}")
        bar = as_progress(bar, "bar")
        self.stream = sys.stderr if stream is None else stream
        self.enabled = progress_enabled(enabled, self.stream)
        self.total, self.desc, self.unit, self.interval = total, str(desc), str(unit), float(interval)
        self.delay = float(delay)
        self.count = 0
        self.note_text = ""
        self._t0 = time.perf_counter()
        self._last_line = -float("inf")
        self._closed = False
        self._bar: Any = None
        if self.enabled:
            notebook = self.stream is sys.stderr and in_notebook()
            tqdm = _tqdm_class(notebook)
            use_bar = tqdm is not None and ((_isatty(self.stream) or notebook) if bar is None else bar)
            if use_bar:
                self._bar = tqdm(total=total, desc=self.desc, unit=f" {self.unit}", file=self.stream,
                                 leave=True, dynamic_ncols=True, mininterval=0.2, delay=self.delay)

    # ----------------------------------------------------------------- context manager
    def __enter__(self) -> Progress:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    @property
    def elapsed(self) -> float:
        """Seconds since the report started."""
        return time.perf_counter() - self._t0

    def _plural(self, k: int | None) -> str:
        return self.unit if k == 1 or self.unit.endswith("s") else f"{self.unit}s"

    def _status(self) -> str:
        done = f"{self.count}/{self.total}" if self.total is not None else f"{self.count}"
        pct = f", {100.0 * self.count / self.total:.0f} %" if self.total else ""
        note = f"; {self.note_text}" if self.note_text else ""
        return f"{self.desc}: {done} {self._plural(self.total)} ({_duration(self.elapsed)}{pct}){note}"

    def _emit(self, text: str) -> None:
        try:
            self.stream.write(text + "\n")
            self.stream.flush()
        except (OSError, ValueError):  # the reader went away: progress is not worth an error
            self.enabled = False

    # ----------------------------------------------------------------- reporting
    def update(self, n: int = 1, note: str | None = None) -> None:
        """``n`` more steps done; ``note`` (optional) replaces the text shown after the count."""
        self.count += int(n)
        if note is not None:
            self.note_text = " ".join(str(note).split())
        if not self.enabled:
            return
        if self._bar is not None:
            if note is not None:
                self._bar.set_postfix_str(self.note_text, refresh=False)
            self._bar.update(int(n))
            return
        now = self.elapsed
        if now < self.delay:  # a short run stays silent
            return
        last = self.total is not None and self.count >= self.total
        if self._last_line == -float("inf") or last or now - self._last_line >= self.interval:
            self._last_line = now
            self._emit(self._status())

    def line(self, text: str) -> None:
        """Write one line (an event: a paper started, a figure written) without breaking the bar."""
        if not self.enabled:
            return
        text = " ".join(str(text).split())
        if self._bar is not None:
            self._bar.write(text, file=self.stream)
        else:
            self._emit(text)

    def close(self) -> None:
        """End the report (the bar stays on screen with its final count)."""
        if self._closed:
            return
        self._closed = True
        if self._bar is not None:
            self._bar.close()

    def __repr__(self) -> str:
        state = "off" if not self.enabled else "bar" if self._bar is not None else "lines"
        return f"Progress({self.desc!r}, {self.count}/{self.total}, {state})"
