"""Shared pieces for reproducing the seed papers (used by ``optdesign reproduce`` and ``examples/``).

Each paper has a module ``optdesign.studies.paperNNN`` with a function
``reproduce(outdir, *, quick=False) -> PaperReproduction`` that recomputes the paper's
examples with the library, writes its figures (PNG) into ``outdir`` and returns the table
of printed vs reproduced values.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import BackendUnavailableError

__all__ = ["ReproRow", "PaperReproduction", "pyplot", "format_table"]


@dataclass(frozen=True)
class ReproRow:
    """One printed-vs-reproduced value.

    ``printed`` is the number as the paper prints it (None if the paper prints none);
    ``reproduced`` is what optdesign computes; ``agrees`` says whether they match to the
    paper's printed precision; ``note`` explains any difference (e.g. a known typo).
    """

    example: str
    quantity: str
    printed: str | None
    reproduced: str
    agrees: bool | None
    note: str = ""


@dataclass(frozen=True)
class PaperReproduction:
    """Everything reproduced from one paper."""

    paper: str
    title: str
    rows: tuple[ReproRow, ...] = ()
    figures: tuple[Path, ...] = field(default_factory=tuple)

    def table(self) -> str:
        return format_table(self.rows)


def format_table(rows) -> str:
    """A plain-text table of rows (example | quantity | printed | reproduced | agrees | note)."""
    head = ("example", "quantity", "printed", "reproduced", "agrees", "note")
    body = [(r.example, r.quantity, r.printed if r.printed is not None else "-", r.reproduced,
             {True: "yes", False: "NO", None: "-"}[r.agrees], r.note) for r in rows]
    widths = [min(60, max(len(str(x)) for x in col)) for col in zip(head, *body)]
    line = lambda cells: " | ".join(str(c)[:60].ljust(w) for c, w in zip(cells, widths))  # noqa: E731
    out = [line(head), "-+-".join("-" * w for w in widths)]
    out += [line(b) for b in body]
    return "\n".join(out)


def pyplot():
    """matplotlib.pyplot with the headless Agg backend, or a clear error naming the extra."""
    try:
        import matplotlib

        matplotlib.use("Agg", force=True)
        import matplotlib.pyplot as plt
    except ImportError as exc:  # pragma: no cover - exercised only without matplotlib
        raise BackendUnavailableError("figures need matplotlib: pip install 'optdesign[plot]'") from exc
    return plt


def fmt(x, digits: int = 4) -> str:
    """Format a number or array compactly for the table."""
    import numpy as np

    a = np.asarray(x)
    if a.ndim == 0:
        v = complex(a)
        if v.imag == 0 or math.isnan(v.real):
            return f"{v.real:.{digits}g}"
        return f"{v.real:.{digits}g}{v.imag:+.{digits}g}j"
    return "[" + ", ".join(fmt(v, digits) for v in a.ravel()) + "]"
