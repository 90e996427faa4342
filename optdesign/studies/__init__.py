"""Studies layer: sweeps and Pareto fronts over design parameters, study specs, paper reproductions.

* :func:`sweep` / :func:`grid` / :class:`SweepTable` -- evaluate a design function over a grid on any
  ``concurrent.futures`` executor (local processes by default, threads, in-process, a Dask cluster);
  failures are recorded, never raised.
* :class:`RegionSweepDesigner` (and the other designers of :mod:`optdesign.studies.designers`) --
  design functions that build their CasADi problem once per worker and re-solve it per point.
* :func:`pareto` -- trade-off fronts (kappa2 / eta / gain) by epsilon-constraints.
* :func:`load_spec` / :func:`run_spec` -- studies described in TOML files (``optdesign study``).
* :func:`reproduce_all` -- every seed paper's examples and figures (``optdesign reproduce``).

Note: ``optdesign.studies.sweep`` and ``optdesign.studies.pareto`` are the *functions* (imported
here); their modules are ``optdesign.studies.sweep`` / ``.pareto`` in ``sys.modules``.
"""

from .designers import (
    DESIGNERS,
    BaselinePlacement,
    DesignPoint,
    KalmanNoiseDesigner,
    PoleTargetDesigner,
    RegionSweepDesigner,
    place_baseline,
)
from .noise_front import noise_penalty_front
from .pareto import ParetoFront, nondominated, pareto, plot_pareto
from .reproduce import PaperOutcome, PaperReproduction, ReproductionSummary, ReproRow, reproduce_all
from .spec import SpecError, StudySpec, load_spec, parse_region, plot_table, run_spec
from .sweep import InlineExecutor, SweepTable, grid, record_of, sweep

__all__ = [
    "noise_penalty_front",
    "sweep",
    "grid",
    "SweepTable",
    "record_of",
    "InlineExecutor",
    "RegionSweepDesigner",
    "KalmanNoiseDesigner",
    "PoleTargetDesigner",
    "DesignPoint",
    "BaselinePlacement",
    "place_baseline",
    "DESIGNERS",
    "pareto",
    "ParetoFront",
    "nondominated",
    "plot_pareto",
    "load_spec",
    "run_spec",
    "parse_region",
    "plot_table",
    "StudySpec",
    "SpecError",
    "reproduce_all",
    "ReproductionSummary",
    "PaperOutcome",
    "PaperReproduction",
    "ReproRow",
]
