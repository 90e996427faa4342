"""matplotlib access for :mod:`optdesign.plot` (imported lazily, backend never chosen here) and the
figure files the library writes (300 dpi; png, svg or pdf).

Figure files are written as every file optdesign writes (:mod:`optdesign._files`): never over an
existing file or symbolic link unless ``overwrite=True``, drawn into a temporary file in the same
folder and renamed onto the name, never through a symbolic link.

matplotlib picks its own backend (``inline`` in Jupyter, a GUI one on a desktop, ``Agg`` when there
is no display); a script or test that wants a particular one selects it itself (``matplotlib.use``)
before drawing.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from .._files import atomic_path
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
                close: bool = True, overwrite: bool = False, **savefig_kw: Any) -> Path:
    """Lay out (``tight_layout`` unless ``layout=False``), write and (by default) close ``fig``.

    The format follows the file's suffix (``.png``, ``.svg``, ``.pdf``; a name without one gets
    matplotlib's default, ``savefig.format``, as ``fig.savefig`` does); ``dpi`` (default 300) sets
    the resolution of raster output.  The file is drawn into a temporary file next to ``path`` and
    renamed onto it (:func:`optdesign._files.atomic_path`).

    Parameters
    ----------
    fig : matplotlib Figure
    path : str or Path
    dpi : int, default 300
    layout : bool, default True
    close : bool, default True
        Close ``fig`` once written (left open if writing fails).
    overwrite : bool, default False
        Replace a file already at ``path`` (a symbolic link there is replaced itself; the file it
        points to is never written).
    **savefig_kw
        Passed to ``fig.savefig``.

    Returns
    -------
    Path
        The file written.

    Raises
    ------
    OutputExistsError
        A file or symbolic link is at ``path`` and ``overwrite`` is False (nothing written).
    OutputPathError
        A folder at ``path``; a folder that cannot be written.
    """
    path = Path(path)
    if not path.suffix and "format" not in savefig_kw:  # matplotlib's own rule: add the default suffix
        path = path.with_name(path.name + "." + str(pyplot().rcParams["savefig.format"]))
    with atomic_path(path, overwrite=overwrite) as tmp:
        if layout:
            fig.tight_layout()
        fig.savefig(tmp, dpi=dpi, **savefig_kw)
    if close:
        pyplot().close(fig)
    return path
