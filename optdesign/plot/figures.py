"""matplotlib access for :mod:`optdesign.plot` (imported lazily, backend never chosen here) and the
figure files the library writes (300 dpi; png, svg or pdf).

matplotlib picks its own backend (``inline`` in Jupyter, a GUI one on a desktop, ``Agg`` when there
is no display); a script or test that wants a particular one selects it itself (``matplotlib.use``)
before drawing.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..errors import BackendUnavailableError

__all__ = ["pyplot", "save_figure", "new_axes", "FIGURE_DPI", "FIGURE_FORMATS"]

#: resolution of the figures the library writes (raster formats); vector formats ignore it
FIGURE_DPI = 300
#: the file formats the library writes figures in
FIGURE_FORMATS = ("png", "svg", "pdf")


def pyplot() -> Any:
    """``matplotlib.pyplot``, imported on first use, with whatever backend matplotlib chose.

    Raises
    ------
    BackendUnavailableError
        matplotlib is not installed (the message names the extra to install).
    """
    try:
        import matplotlib.pyplot as plt
    except ImportError as exc:  # pragma: no cover - exercised only without matplotlib
        raise BackendUnavailableError("figures need matplotlib, which is not installed: "
                                      "pip install 'optdesign-control[plot]'") from exc
    return plt


def new_axes(ax: Any = None, figsize: tuple[float, float] = (6.4, 4.8)) -> Any:
    """``ax`` itself, or the axes of a new figure when ``ax`` is None."""
    if ax is not None:
        if not hasattr(ax, "add_patch"):
            from ..errors import ValidationError

            raise ValidationError(f"ax must be a matplotlib Axes or None; found {type(ax).__name__}")
        return ax
    _, ax = pyplot().subplots(figsize=figsize)
    return ax


def save_figure(fig: Any, path: str | Path, *, dpi: int = FIGURE_DPI, layout: bool = True,
                close: bool = True, **savefig_kw: Any) -> Path:
    """Lay out (``tight_layout`` unless ``layout=False``), write and (by default) close ``fig``.

    The format follows the file's suffix (``.png``, ``.svg``, ``.pdf``); ``dpi`` (default 300) sets
    the resolution of raster output.

    Returns
    -------
    Path
        The file written.
    """
    if layout:
        fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=dpi, **savefig_kw)
    if close:
        pyplot().close(fig)
    return path
