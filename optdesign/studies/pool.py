"""The pool of a region sweep's chunk: the distinct verified local optima of a point, carried to the
next point as warm starts (``RegionSweepDesigner(placement="pool")``)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from .._validate import as_int, as_positive_float
from ..design.well_conditioned import ObserverDesign
from ..design.well_conditioned.problem import warm_start_origin

__all__ = ["merge_pool"]


def merge_pool(res: ObserverDesign, previous: list[tuple[float, NDArray[np.float64]]], size: int,
               rtol: float, objective_rtol: float = 0.0) -> list[tuple[float, NDArray[np.float64]]]:
    """The distinct verified local optima of a point, best first: its design's gain, the answers of its
    starts (``res.extra["local_optima"]``), then the members of ``previous`` (the point's warm starts,
    in order) that did not run at this point (the point ended early); at most ``size``.

    Two gains are one optimum when ``||L1 - L2||_2 <= rtol max(||L1||_2, ||L2||_2)``; two answers of
    this point are also one when their objectives agree to ``objective_rtol`` (relative): e.g. the
    mirror images of one design under a symmetry of the plant, whose chains stay images of each other.

    Parameters
    ----------
    res : ObserverDesign
        The point's design (verified).
    previous : list of (objective, (n, p) ndarray)
        The point's warm starts (objective when they last ran), in the order given.
    size : int
        The largest pool.
    rtol, objective_rtol : float
        >= 0.

    Returns
    -------
    list of (objective, (n, p) ndarray)

    Raises
    ------
    ValidationError
        ``size`` not an integer >= 1, ``rtol`` or ``objective_rtol`` not a number >= 0.
    """
    size = as_int("size", size, 1)
    rtol = as_positive_float("rtol", rtol, allow_zero=True)
    objective_rtol = as_positive_float("objective_rtol", objective_rtol, allow_zero=True)
    ran = {r.origin for r in res.starts}
    found = [(float(getattr(res, res.objective)), np.asarray(res.L, dtype=float))]
    found += [(o.objective, o.L) for o in res.extra.get("local_optima", ())]
    carried = [m for i, m in enumerate(previous) if warm_start_origin(i) not in ran]
    out: list[tuple[float, NDArray[np.float64]]] = []
    for f, L in found + carried:
        nL = float(np.linalg.norm(L, 2))
        if all(float(np.linalg.norm(L - M, 2)) > rtol * max(nL, float(np.linalg.norm(M, 2)))
               and not abs(f - g) <= objective_rtol * abs(g) for g, M in out):
            out.append((f, L))
        if len(out) >= size:
            break
    return out
