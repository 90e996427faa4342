"""Figures of studies: one figure of a sweep table (study specs) and a Pareto front.

Moved here from :mod:`optdesign.studies` (``optdesign.studies.plot_table`` and
``optdesign.studies.plot_pareto`` remain importable); they no longer select matplotlib's backend,
so they draw inline in a notebook.  Files are written at 300 dpi in the format of their suffix.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from .._files import check_targets
from ..errors import ValidationError
from .figures import FIGURE_DPI, new_axes, pyplot, save_figure

__all__ = ["plot_table", "plot_pareto", "LABELS", "SYMBOLS"]

#: human-readable axis labels (matplotlib mathtext for the symbols)
LABELS: dict[str, str] = {
    "alpha": r"decay rate $\alpha$  (poles: $\mathrm{Re}\,s \leq -\alpha$)",
    "zeta": r"damping ratio $\zeta$  (sector)",
    "radius": r"radius bound $|s| \leq$ radius",
    "max_gain": r"gain bound $\|L\|_2 \leq$ max_gain",
    "kappa2_max": r"bound $\kappa_2 \leq$ kappa2_max",
    "eta_max": r"bound $\eta \leq$ eta_max",
    "q": "process-noise multiplier $q$",
    "r": "measurement-noise multiplier $r$",
    "scale": "scale of the target poles",
    "shift": "shift of the target poles' real parts",
    "kappa2": r"$\kappa_2$ of $A - LC$  (eigenvector condition number)",
    "eta": r"$\eta$ of $A - LC$  (non-normality)",
    "kappa_fro": "Frobenius condition number of the eigenvectors",
    "gain_norm": r"gain norm $\|L\|_2$",
    "max_real_pole": r"largest real part of $\mathrm{eig}(A - LC)$",
    "pole_error": "relative pole error",
    "trace_Q": r"$\mathrm{trace}\,Q$",
    "time": "time per point (s)",
    "solver_time": "solver time per point (s)",
    "iterations": "IPOPT iterations",
}

#: the symbol of a grid axis in legends (``alpha = 0.5`` is drawn as a Greek alpha)
SYMBOLS: dict[str, str] = {"alpha": r"$\alpha$", "zeta": r"$\zeta$", "q": "$q$", "r": "$r$",
                           "kappa2_max": r"$\kappa_{2,\max}$", "eta_max": r"$\eta_{\max}$"}


def _label(col: str, width: int = 34) -> str:
    """Axis label of a column; long labels break before their parenthesis."""
    text = LABELS.get(col, col)
    if len(text) > width and "  (" in text:
        head, _, tail = text.partition("  (")
        return f"{head}\n({tail}"
    return text


def _readable_log(axis, values: np.ndarray) -> None:
    """Log-axis ticks as plain numbers (``5, 10, 20, 50``), not ``5 x 10^0``: 1-2-5 steps over a
    few decades, decades only over a wide range."""
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

    v = values[np.isfinite(values) & (values > 0)]
    decades = float(np.log10(v.max() / v.min())) if v.size else 0.0
    subs = (1.0, 2.0, 5.0) if decades <= 3 else (1.0,)
    axis.set_major_locator(LogLocator(base=10.0, subs=subs))
    axis.set_major_formatter(FuncFormatter(lambda x, _pos: f"{x:g}"))
    axis.set_minor_formatter(NullFormatter())


def _title(text: str, note: str) -> str:
    import textwrap

    # never break inside a parenthesized group such as "(|s| <= 10)" or inside mathtext ("$\kappa_2$"):
    # protect their spaces
    depth, math, chars = 0, False, []
    for c in text:
        depth += (c == "(") - (c == ")")
        math ^= c == "$"
        chars.append("\u00a0" if c == " " and (depth > 0 or math) else c)
    lines = [ln.replace("\u00a0", " ") for ln in textwrap.wrap("".join(chars), 70)]
    return "\n".join(lines + ([note.strip()] if note else []))


def plot_table(table: Any, fig: Any, path: str | Path | None = None, *, title: str = "",
               dpi: int = FIGURE_DPI, overwrite: bool = False) -> Any:
    """Draw one figure of a sweep table (successful points only); save it when ``path`` is given.

    Line figures: one curve per value of ``fig.series`` (legend), one panel per ``y`` column,
    axes labelled.  Heatmaps: ``fig.value`` over the ``x`` by ``y`` grid with a colour bar and the
    values written in the cells (failed cells blank, marked "failed").  Failed points are left
    out and counted in the title.

    Parameters
    ----------
    table : optdesign.studies.SweepTable
    fig : optdesign.studies.spec.FigureSpec
        What to draw (``kind``, ``x``, ``y``, ``series``, ``value``, ``logx``, ``logy``, ``title``).
    path : str or Path, optional
        Where to write the figure (format from the suffix: ``.png``, ``.svg``, ``.pdf``).
    title : str
    dpi : int, default 300
        Resolution of raster output.
    overwrite : bool, default False
        Replace a file already at ``path`` (as :func:`~optdesign.plot.save_figure`: written to a
        temporary name and renamed, never through a symbolic link).

    Returns
    -------
    Path (the file written, the figure closed) when ``path`` is given, else the matplotlib Figure.

    Raises
    ------
    OutputExistsError
        A file or symbolic link at ``path`` and ``overwrite`` False (checked before drawing).
    """
    if path is not None:
        check_targets([path], overwrite=overwrite)
    plt = pyplot()
    ok = np.array([bool(r.get("success")) for r in table.records])
    n_fail = int((~ok).sum())
    note = f"({n_fail} of {len(table)} points failed: not drawn)" if n_fail else ""
    if fig.kind == "heatmap":
        value = fig.value or "kappa2"
        recs = [r if r.get("success") else {**r, value: None} for r in table.records]
        masked = type(table)(records=recs, inputs=table.inputs)
        xs, ys, Z = masked.pivot(fig.x, fig.y[0], value)
        f, ax = plt.subplots(figsize=(7.2, 5.0))
        mesh = ax.pcolormesh(xs, ys, Z, shading="nearest", cmap="viridis")
        cb = f.colorbar(mesh, ax=ax)
        cb.set_label(_label(value))
        if xs.size * ys.size <= 150:
            fin = np.isfinite(Z).any()
            lo, hi = (np.nanmin(Z), np.nanmax(Z)) if fin else (0.0, 1.0)
            for i, yv in enumerate(ys):
                for j, xv in enumerate(xs):
                    v = Z[i, j]
                    txt = "failed" if not np.isfinite(v) else f"{v:.3g}"
                    light = np.isfinite(v) and (v - lo) > 0.6 * (hi - lo)
                    ax.text(xv, yv, txt, ha="center", va="center", fontsize=8,
                            color="k" if (light or not np.isfinite(v)) else "w")
        ax.set_xlabel(_label(fig.x))
        ax.set_ylabel(_label(fig.y[0]))
        if fig.logx:
            ax.set_xscale("log")
        if fig.logy:
            ax.set_yscale("log")
        if xs.size <= 12 and xs.dtype != object:
            ax.set_xticks(xs, [f"{v:g}" for v in xs])
        if ys.size <= 12 and ys.dtype != object:
            ax.set_yticks(ys, [f"{v:g}" for v in ys])
        ax.set_title(_title(fig.title or title or f"{fig.value}", note), fontsize=10)
    else:
        f, axs = plt.subplots(len(fig.y), 1, figsize=(7.6, 1.2 + 2.9 * len(fig.y)), sharex=True,
                              squeeze=False)
        xcol = table.column(fig.x)
        groups: list[tuple[Any, np.ndarray]] = []
        if fig.series is None:
            groups.append((None, np.ones(len(table), dtype=bool)))
        else:
            scol = table.column(fig.series)
            for v in dict.fromkeys(scol.tolist()):
                groups.append((v, np.array([s == v for s in scol.tolist()])))
        for k, (ax, ycol) in enumerate(zip(axs[:, 0], fig.y, strict=True)):
            yv = table.column(ycol).astype(float)
            for val, sel in groups:
                idx = np.where(sel)[0]
                order = idx[np.argsort(xcol[idx].astype(float), kind="stable")]
                yy = np.where(ok[order], yv[order], np.nan)
                sym = SYMBOLS.get(fig.series or "", fig.series)
                label = f"{sym} = {val:g}" if isinstance(val, (int, float)) else (
                    f"{sym} = {val}" if fig.series else _label(ycol))
                ax.plot(xcol[order].astype(float), yy, marker="o", ms=3.5, lw=1.4, label=label)
            ax.set_ylabel(_label(ycol))
            if fig.logy:
                ax.set_yscale("log")
                _readable_log(ax.yaxis, yv[ok])
            if fig.logx:
                ax.set_xscale("log")
                _readable_log(ax.xaxis, xcol.astype(float))
            ax.grid(True, alpha=0.3)
            if k == 0 and (fig.series is not None or len(fig.y) == 1):
                ax.legend(fontsize=8, title=SYMBOLS.get(fig.series or "", fig.series), title_fontsize=8,
                          loc="upper left",
                          bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)
        axs[-1, 0].set_xlabel(_label(fig.x))
        axs[0, 0].set_title(_title(fig.title or title or ", ".join(fig.y), note), fontsize=10)
    if path is None:
        f.tight_layout()
        return f
    return save_figure(f, path, dpi=dpi, overwrite=overwrite)


def plot_pareto(front: Any, path: str | Path | None = None, *, x: str | None = None,
                y: str | None = None, color: str | None = None, title: str = "", ax: Any = None,
                dpi: int = FIGURE_DPI, overwrite: bool = False) -> Any:
    """Scatter plot of a front: ``y`` (default the minimized objective) against ``x`` (default the
    second objective), colour = the third objective (if any); non-dominated points joined, dominated
    ones grey, anchors marked; axes labelled, legend.

    Parameters
    ----------
    front : optdesign.studies.ParetoFront
    path : str or Path, optional
        Also write the figure there (format from the suffix), at ``dpi`` (default 300).
    x, y, color : str, optional
        Objectives on the axes and in the colour.
    title : str
    ax : matplotlib Axes, optional
        Draw here (default a new figure).
    dpi : int, default 300
    overwrite : bool, default False
        Replace a file already at ``path`` (as :func:`~optdesign.plot.save_figure`: written to a
        temporary name and renamed, never through a symbolic link).

    Returns
    -------
    matplotlib Figure (saved to ``path`` when given; left open).

    Raises
    ------
    ValidationError
        ``x`` or ``y`` not one of the front's objectives.
    OutputExistsError
        A file or symbolic link at ``path`` and ``overwrite`` False (checked before drawing).
    """
    if path is not None:
        check_targets([path], overwrite=overwrite)
    objs = front.objectives
    y = y or objs[0]
    x = x or objs[1]
    for name, v in (("x", x), ("y", y)):
        if v not in objs:
            raise ValidationError(f"{name} must be one of the front's objectives {objs}; found {v!r}")
    if color is None and len(objs) == 3:
        color = next(o for o in objs if o not in (x, y))
    ix, iy = objs.index(x), objs.index(y)
    V, nd = front.values, front.nondominated
    ok = np.all(np.isfinite(V), axis=1)
    anchors = np.array([r.get("anchor") is not None for r in front.table.records])
    ax = new_axes(ax)
    fig = ax.figure
    dom = ok & ~nd
    if dom.any():
        ax.scatter(V[dom, ix], V[dom, iy], c="0.7", s=18, label="dominated", zorder=1)
    order = np.where(nd)[0][np.argsort(V[nd, ix], kind="stable")]
    if order.size:
        ax.plot(V[order, ix], V[order, iy], "-", color="0.3", lw=1, zorder=2)
        if color is not None:
            sc = ax.scatter(V[order, ix], V[order, iy], c=V[order, objs.index(color)], cmap="viridis", s=36,
                            edgecolors="k", linewidths=0.5, label="non-dominated", zorder=3)
            cb = fig.colorbar(sc, ax=ax)
            cb.set_label(LABELS.get(color, color))
        else:
            ax.scatter(V[order, ix], V[order, iy], c="C0", s=36, edgecolors="k", linewidths=0.5,
                       label="non-dominated", zorder=3)
    am = anchors & ok
    if am.any():
        ax.scatter(V[am, ix], V[am, iy], marker="*", s=160, facecolors="none", edgecolors="C3",
                   label="anchors (one objective alone)", zorder=4)
    n_fail = int((~ok).sum())
    ax.set_xlabel(LABELS.get(x, x))
    ax.set_ylabel(LABELS.get(y, y))
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title((title or f"trade-off: minimize {objs[0]} s.t. bounds on {', '.join(objs[1:])}")
                 + (f"\n({n_fail} bound levels infeasible or failed)" if n_fail else ""), fontsize=10)
    fig.tight_layout()
    if path is not None:
        save_figure(fig, path, dpi=dpi, layout=False, close=False, overwrite=overwrite)
    return fig
