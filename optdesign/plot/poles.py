"""Pole maps: a design's poles (and the plant's open-loop poles) over its shaded pole region.

:func:`pole_map` draws one set of poles -- of a result of any design verb, or given directly --
with the region it had to meet; :func:`robust_pole_map` draws every model's poles of a robust
design (the model cloud) with the worst model marked; :func:`plot_result` is what
``result.plot()`` calls.  matplotlib is imported when drawing; no backend is selected here.

Markers follow the usual pole-zero-map conventions (MATLAB ``pzmap``, python-control
``pole_zero_plot``): ``x`` for the designed poles, hollow circles for the open-loop poles
``eig(A)``, ``+`` for requested poles; the stability boundary (the imaginary axis, or the unit
circle in discrete time) is dashed.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._validate import as_vector
from ..errors import ValidationError
from .figures import new_axes
from .regions import Box, draw_region, region_extent, region_of

__all__ = ["pole_map", "robust_pole_map", "plot_result", "view_box"]


def _points(name: str, value: Any) -> NDArray[np.complex128]:
    if value is None:
        return np.zeros(0, dtype=complex)
    a = np.asarray(value)
    if a.size == 0:
        return np.zeros(0, dtype=complex)
    return as_vector(name, a.ravel(), allow_complex=True).astype(complex)


def view_box(points: ArrayLike, regions: tuple[Any, ...] = (), discrete: bool = False, pad: float = 0.08) -> Box:
    """Axes limits showing every point, the visible part of every region and the stability boundary.

    Parameters
    ----------
    points : (k,) array_like of complex
    regions : tuple of Region
        Each contributes :func:`~optdesign.plot.regions.region_extent` (its bounding box, or a
        window at the finite edges of an unbounded region).
    discrete : bool
        Include the unit circle; in continuous time the imaginary axis is brought into view when it
        is within twice the points' extent of them (so poles far out are not squeezed).
    pad : float
        Margin added on every side, as a fraction of the box's size.

    Returns
    -------
    (x0, x1, y0, y1) : tuple of float
        Symmetric about the real axis (``y0 = -y1``).
    """
    z = _points("points", points)
    xs = list(z.real)
    ys = list(np.abs(z.imag))
    for r in regions:
        x0, x1, _, y1 = region_extent(r)
        xs += [x0, x1]
        ys.append(y1)
    if discrete:
        xs += [-1.0, 1.0]
        ys.append(1.0)
    if not xs:
        xs, ys = [-1.0, 1.0], [1.0]
    x0, x1, y1 = min(xs), max(xs), max(ys)
    if not discrete and x1 < 0.0 and -x1 <= 2.0 * max(x1 - x0, 2.0 * y1):
        x1 = 0.0  # the imaginary axis is near: bring it into view
    span = max(x1 - x0, 2.0 * y1)
    if span <= 0.0:  # one real point: a window of its own size
        span = max(abs(x0), 1.0)
    x0, x1 = x0 - pad * span, x1 + pad * span
    y1 = max(y1 + pad * span, 0.25 * (x1 - x0))
    return (float(x0), float(x1), -float(y1), float(y1))


def _stability_boundary(ax: Any, box: Box, discrete: bool) -> None:
    style = dict(color="0.45", lw=0.8, ls="--", zorder=1, scalex=False, scaley=False)
    if discrete:
        t = np.linspace(0.0, 2.0 * math.pi, 361)
        ax.plot(np.cos(t), np.sin(t), label="unit circle", **style)
    elif box[0] <= 0.0 <= box[1]:
        ax.plot([0.0, 0.0], [box[2], box[3]], label="imaginary axis", **style)
    ax.axhline(0.0, color="0.8", lw=0.6, zorder=0)


def _finish(ax: Any, box: Box, discrete: bool, title: str | None, legend: bool) -> Any:
    ax.set_xlim(box[0], box[1])
    ax.set_ylim(box[2], box[3])
    if discrete:
        ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel("real part")
    ax.set_ylabel("imaginary part")
    if title:
        ax.set_title(title, fontsize=10)
    if legend:  # below the axes: the shaded region leaves no empty corner inside them
        ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.13), ncol=2, frameon=False)
    return ax


def _result_fields(result: Any) -> dict[str, Any]:
    """The poles, region, plant and kind of a design result (duck-typed over the result classes)."""
    poles = getattr(result, "poles", None)
    if poles is None:
        poles = getattr(result, "computed_poles", None)
    plant = getattr(result, "plant", None)
    if plant is None:
        plant = getattr(getattr(result, "design", None), "plant", None)
    region = getattr(result, "region", None)
    if region is None:
        region = getattr(getattr(result, "design", None), "region", None)
    feedback = any(getattr(result, k, None) is not None for k in ("K", "gain_matrix"))
    return dict(poles=poles, plant=plant, region=region, target=getattr(result, "target_poles", None),
                feedback=feedback)


def pole_map(result_or_poles: Any, region: Any = None, ax: Any = None, open_loop: Any = None, *,
             target: ArrayLike | None = None, discrete: bool | None = None, title: str | None = None,
             legend: bool = True, color: str = "C0") -> Any:
    """Draw poles over their shaded pole region.

    Parameters
    ----------
    result_or_poles : design result or (n,) array_like of complex
        A result of a design verb (``well_conditioned_observer``, ``place``, ``kalman``,
        ``kalman_for_poles``, ``well_conditioned_feedback``, ...: its ``poles`` or
        ``computed_poles``, its ``region``, its plant's open-loop poles and time domain, its
        requested poles), or the poles themselves.  A robust design (it has ``models``) is drawn
        by :func:`robust_pole_map`.
    region : Region, optional
        The region to shade (any shape or intersection); default the result's own region.
    ax : matplotlib Axes, optional
        Draw here; default a new figure.
    open_loop : (n,) array_like of complex or False, optional
        Open-loop poles to mark; default ``eig(A)`` of the result's plant; ``False`` for none.
    target : (n,) array_like of complex, optional
        Requested poles to mark (default the result's ``target_poles``).
    discrete : bool, optional
        Draw the unit circle instead of the imaginary axis; default the plant's time domain
        (continuous for bare poles).
    title : str, optional
        Default: the result's class and status.
    legend : bool, default True
    color : matplotlib colour of the designed poles

    Returns
    -------
    matplotlib Axes
        Its limits contain every pole drawn and the visible part of the region
        (:func:`view_box`).

    Raises
    ------
    ValidationError
        A result without poles (nothing was designed), poles that are not finite numbers, a
        ``region`` that is not a Region, ``ax`` not an Axes.
    BackendUnavailableError
        matplotlib is not installed.

    Examples
    --------
    >>> import numpy as np
    >>> from optdesign.plot import pole_map
    >>> from optdesign.regions import HalfPlane, Sector
    >>> ax = pole_map([-2 + 1j, -2 - 1j, -3], region=HalfPlane(1) & Sector.from_damping(0.5))  # doctest: +SKIP
    """
    if hasattr(result_or_poles, "models") and hasattr(result_or_poles, "L"):
        return robust_pole_map(result_or_poles, region=region, ax=ax, title=title, legend=legend)
    is_result = hasattr(result_or_poles, "status")
    if is_result:
        info = _result_fields(result_or_poles)
        if info["poles"] is None or np.asarray(info["poles"]).size == 0:
            raise ValidationError(f"this {type(result_or_poles).__name__} has no poles to draw (status "
                                  f"{getattr(result_or_poles, 'status', '?')}: {result_or_poles.message})")
    else:
        info = dict(poles=result_or_poles, plant=None, region=None, target=None, feedback=False)
    poles = _points("poles", info["poles"])
    poles = poles[np.isfinite(poles)]
    region = region if region is not None else info["region"]
    if region is not None:
        region_of(region)
    plant = info["plant"]
    if open_loop is None and plant is not None and hasattr(plant, "A"):
        open_loop = np.linalg.eigvals(np.asarray(plant.A, dtype=float))
    ol = np.zeros(0, dtype=complex) if open_loop is False else _points("open_loop", open_loop)
    tg = _points("target", target if target is not None else info["target"])
    tg = tg[np.isfinite(tg)]
    if discrete is None:
        discrete = bool(getattr(plant, "is_discrete", False))
    ax = new_axes(ax)
    box = view_box(np.concatenate([poles, ol, tg]), (region,) if region is not None else (), discrete)
    if region is not None:
        draw_region(region, ax, box=box)
    _stability_boundary(ax, box, discrete)
    if ol.size:
        ax.scatter(ol.real, ol.imag, marker="o", s=46, facecolors="none", edgecolors="0.35", zorder=3,
                   label="open loop  eig(A)")
    if tg.size:
        ax.scatter(tg.real, tg.imag, marker="+", s=90, color="C3", zorder=4, label="requested")
    what = "closed loop  eig(A - BK)" if info["feedback"] else ("estimator  eig(A - LC)" if is_result else "poles")
    ax.scatter(poles.real, poles.imag, marker="x", s=56, color=color, linewidths=1.8, zorder=5, label=what)
    if title is None and is_result:
        title = f"{type(result_or_poles).__name__}: {getattr(result_or_poles.status, 'value', result_or_poles.status)}"
    return _finish(ax, box, discrete, title, legend)


def _robust_inputs(model_set_or_result: Any, gain: Any, region: Any) -> tuple[Any, NDArray, list[Any]]:
    from ..model.model_set import as_model_set

    if hasattr(model_set_or_result, "models") and hasattr(model_set_or_result, "L"):
        res = model_set_or_result
        models = res.models
        L = np.asarray(res.L if gain is None else gain, dtype=float)
        regions = [region] * len(models) if region is not None else list(res.regions or [None] * len(models))
    else:
        models = as_model_set(model_set_or_result)
        if gain is None:
            raise ValidationError("robust_pole_map needs the gain L of shape (n, p) for a model set; found None")
        L = np.asarray(gain, dtype=float)
        regions = [region] * len(models)
    if L.shape != (models.n, models.p):
        raise ValidationError(f"gain must have shape (n, p) = ({models.n}, {models.p}); found {L.shape}")
    if not np.all(np.isfinite(L)):
        raise ValidationError("gain has non-finite entries (the design found no gain): nothing to draw")
    for r in regions:
        if r is not None:
            region_of(r)
    return models, L, regions


def robust_pole_map(model_set_or_result: Any, gain: ArrayLike | None = None, region: Any = None, ax: Any = None,
                    *, title: str | None = None, legend: bool = True) -> Any:
    """Every model's poles ``eig(A_i - L C_i)`` of a robust design (the model cloud), the worst marked.

    Parameters
    ----------
    model_set_or_result : ModelSet, sequence of Plant, or RobustObserverDesign
        The models (a robust result brings its models, gain and per-model regions).
    gain : (n, p) array_like, optional
        The observer gain L (required for a model set; overrides a result's).
    region : Region, optional
        The region every model's poles must meet (default the result's regions).
    ax : matplotlib Axes, optional
    title : str, optional
    legend : bool, default True

    Returns
    -------
    matplotlib Axes

    Notes
    -----
    The worst model is the one with the largest region margin (:meth:`Region.margin`: the most
    violating pole's distance outside, or the smallest clearance inside); without a region, the one
    closest to instability (largest real part, or spectral radius in discrete time).

    Raises
    ------
    ValidationError
        No gain for a model set, a gain of the wrong shape or with non-finite entries, a region
        that is not a Region.
    """
    models, L, regions = _robust_inputs(model_set_or_result, gain, region)
    discrete = bool(models.is_discrete)
    poles = [np.linalg.eigvals(np.asarray(pl.A, float) - L @ np.asarray(pl.C, float)) for pl in models]
    if any(r is not None for r in regions):
        score = np.array([r.margin(p) if r is not None else -math.inf for r, p in zip(regions, poles, strict=True)])
        why = "margin"
    else:
        score = np.array([np.max(np.abs(p)) if discrete else np.max(p.real) for p in poles])
        why = "spectral radius" if discrete else "max Re"
    k = int(np.argmax(score))
    distinct = list(dict.fromkeys(r for r in regions if r is not None))
    allp = np.concatenate(poles)
    ax = new_axes(ax)
    box = view_box(allp, tuple(distinct), discrete)
    for i, r in enumerate(distinct):
        draw_region(r, ax, box=box, color=f"C{2 + i}")
    _stability_boundary(ax, box, discrete)
    others = np.concatenate([p for i, p in enumerate(poles) if i != k]) if len(poles) > 1 else np.zeros(0)
    if others.size:
        ax.scatter(others.real, others.imag, marker=".", s=30, color="C0", alpha=0.55, zorder=4,
                   label=f"poles of the other {len(poles) - 1} models")
    ax.scatter(poles[k].real, poles[k].imag, marker="x", s=70, color="C3", linewidths=2.0, zorder=5,
               label=f"worst: {models.label(k)} ({why} {score[k]:.3g})")
    if title is None:
        title = f"{len(models)} models, one gain"
    return _finish(ax, box, discrete, title, legend)


def plot_result(result: Any, ax: Any = None, **kw: Any) -> Any:
    """``result.plot()``: :func:`robust_pole_map` for a robust design, else :func:`pole_map`."""
    if hasattr(result, "models") and hasattr(result, "L"):
        return robust_pole_map(result, ax=ax, **kw)
    return pole_map(result, ax=ax, **kw)
