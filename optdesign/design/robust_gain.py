"""Tools of the robust design for users: each model's own design (:func:`per_model_designs`) and a
given gain judged on every model (:func:`evaluate_gain`).  Split from :mod:`optdesign.design.robust`,
which exports both."""

from __future__ import annotations

from typing import Any

from numpy.typing import ArrayLike

from .._validate import as_int, as_matrix
from ..model.model_set import ModelSet, as_model_set
from ..model.regions import Region
from ..results import Verification
from .robust_result import (
    RobustObserverDesign,
    as_regions,
)
from .robust_verify import DenseCheck, ModelMetrics, dense_check, evaluate_models, gain_checks

__all__ = ["per_model_designs", "evaluate_gain"]


# --------------------------------------------------------------------------- helpers for users


def per_model_designs(models: ModelSet | list, **kwargs: Any) -> list[RobustObserverDesign]:
    """Each model's own robust-observer design (one model at a time): what one gain can do for that
    model alone -- the reference a gain for all models is measured against.

    Parameters
    ----------
    models : ModelSet or sequence of Plant
    **kwargs
        As for :func:`robust_observer` (``region`` may be per model); ``per_model_starts`` is off.

    Returns
    -------
    list of RobustObserverDesign
        One per model (local optima: the NLP is non-convex, so these are not proven bounds).

    Examples
    --------
    >>> from optdesign import ModelSet, Plant, per_model_designs
    >>> from optdesign.regions import HalfPlane
    >>> models = ModelSet.vary(Plant([[0., 1.], [-2., -1.]], [[1., 0.]]), [(1, 0)], 0.2)
    >>> each = per_model_designs(models, region=HalfPlane(1.0), max_gain=10.0, starts=1, nlp_starts=1,
    ...                          dense_points=0)
    >>> [(d.success, round(d.worst_kappa2, 2)) for d in each]    # each model alone: kappa2 = 1
    [(True, 1.0), (True, 1.0), (True, 1.0)]
    """
    from .robust import robust_observer  # (robust imports this module)

    ms = as_model_set(models)
    regions = as_regions(kwargs.pop("region", None), ms, "region", default=True)
    kwargs.pop("per_model_starts", None)
    return [
        robust_observer(ModelSet((ms[i],)), region=regions[i], per_model_starts=False, **kwargs)
        for i in range(len(ms))
    ]


def evaluate_gain(
    models: ModelSet | list,
    L: ArrayLike,
    *,
    region: Region | list | None = None,
    dense_points: int = 0,
    seed: int = 0,
) -> tuple[ModelMetrics, Verification, DenseCheck]:
    """Any gain on every model of a set (e.g. the nominal design on the others).

    Returns
    -------
    metrics : ModelMetrics
    verification : Verification
        Stability and region membership on every model.
    dense : DenseCheck
        At ``dense_points`` random interior plants.

    Raises
    ------
    ValidationError, DimensionError
        Bad models, regions or gain.

    Examples
    --------
    >>> import numpy as np
    >>> from optdesign import ModelSet, Plant, evaluate_gain
    >>> from optdesign.regions import HalfPlane
    >>> models = ModelSet.vary(Plant([[0., 1.], [-2., -1.]], [[1., 0.]]), [(1, 0)], 0.2)
    >>> metrics, verification, dense = evaluate_gain(models, [[4.0], [2.0]], region=HalfPlane(1.0))
    >>> verification.passed, np.round(metrics.kappa2, 2).tolist()     # one gain, three models
    (True, [3.69, 3.39, 3.49])
    """
    ms = as_model_set(models)
    regions = as_regions(region, ms, "region", default=True)
    L = as_matrix("L", L, (ms.n, ms.p))
    mm = evaluate_models(ms, L, regions)
    v = gain_checks(ms, L, mm, regions)
    return (
        mm,
        v,
        dense_check(
            ms,
            L,
            regions[ms.nominal if ms.nominal is not None else 0],
            as_int("dense_points", dense_points, 0),
            as_int("seed", seed, 0),
        ),
    )
