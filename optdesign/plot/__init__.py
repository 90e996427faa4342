"""Pictures of designs: pole maps with regions, model clouds, Pareto fronts and sweeps.

matplotlib is optional and imported lazily (``pip install 'optdesign-control[plot]'``); no function here
selects a backend -- matplotlib's own choice stands (``inline`` in Jupyter, ``Agg`` without a display).
Every function draws on ``ax`` when given, else on a new figure, and returns the Axes (or the
Figure, for the multi-panel study plots).

==============================  ==========================================================
:func:`pole_map`                poles (and open-loop poles) over the shaded pole region
:func:`robust_pole_map`         every model's poles of a robust design, the worst marked
:func:`draw_region`             a region alone (``Region.plot``), clipped to a box
:func:`plot_pareto`             a Pareto front (:func:`optdesign.studies.pareto`)
:func:`plot_table`              one figure of a sweep table (study specs)
==============================  ==========================================================

``result.plot()`` on a design result calls :func:`plot_result`.
"""

from .figures import FIGURE_DPI, FIGURE_FORMATS, save_figure
from .poles import plot_result, pole_map, robust_pole_map, view_box
from .regions import draw_region, region_extent, region_outline

__all__ = [
    "pole_map",
    "robust_pole_map",
    "plot_result",
    "draw_region",
    "region_outline",
    "region_extent",
    "view_box",
    "save_figure",
    "FIGURE_DPI",
    "FIGURE_FORMATS",
]
