"""The trace-penalty study of autocovariance least squares: how many disturbances does the data need?

Rajamani & Rawlings (Automatica 45(1), 2009, sec. 4) add ``rho tr(Q)`` to the ALS objective and sweep
``rho``: the fit's residual grows and ``tr(Q)`` falls as ``rho`` grows, and the rank of ``Q`` -- the number of
independent disturbances -- drops at the knee of that trade-off.  :func:`noise_penalty_front` runs
:func:`optdesign.estimate_noise` once per penalty and returns the points as a :class:`ParetoFront` of the two
minimized objectives ``residual`` and ``trace_Q``, with the rank of each estimated Q in its record.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from .._validate import as_vector
from ..errors import ValidationError
from .pareto import ParetoFront, nondominated
from .sweep import SweepTable

__all__ = ["noise_penalty_front", "RANK_RTOL"]


#: relative level below which an eigenvalue of an estimated Q counts as zero: the SDP stops at a relative
#: gap of about 1e-8 (Clarabel's default), so eigenvalues of Q are known to about its square root times the
#: sweep's largest trace
RANK_RTOL = 1e-6


def _rank(Q: np.ndarray | None, scale: float) -> int:
    """Numerical rank of a PSD estimate: eigenvalues above ``RANK_RTOL * scale`` (``scale``: the largest
    ``tr(Q)`` of the sweep), -1 for a missing estimate."""
    if Q is None or not np.all(np.isfinite(Q)):
        return -1
    lam = np.linalg.eigvalsh(0.5 * (Q + Q.T))
    return int(np.sum(lam > RANK_RTOL * scale))


def noise_penalty_front(plant: Any, y: ArrayLike, u: ArrayLike | None = None, *, penalties: ArrayLike,
                        **estimate_kw: Any) -> ParetoFront:
    """Sweep the trace penalty of :func:`~optdesign.design.noise_estimation.estimate_noise`.

    Parameters
    ----------
    plant, y, u
        As :func:`~optdesign.design.noise_estimation.estimate_noise`.
    penalties : (k,) array_like of float
        The values of ``rho`` (``>= 0``; at least two).
    **estimate_kw
        Further keywords of ``estimate_noise`` (``lags``, ``q_structure``, ``L``, ``dt``, ...), the same
        at every point (``trace_penalty`` is the swept one and may not be given).

    Returns
    -------
    ParetoFront
        ``objectives = ("residual", "trace_Q")``; ``table`` records ``trace_penalty``, ``status``,
        ``success``, ``residual``, ``trace_Q`` and ``rank_Q`` per point; ``designs`` the
        :class:`~optdesign.design.noise_estimation.NoiseEstimate` of each; ``levels`` the penalties.
        A point that did not succeed has nan objectives (dominated).

    Raises
    ------
    ValidationError
        Fewer than two penalties, a negative or non-finite one, or ``trace_penalty`` in ``estimate_kw``;
        and whatever ``estimate_noise`` raises for its arguments.

    References
    ----------
    Rajamani, M. R. & Rawlings, J. B., "Estimation of the disturbance structure from data using
    semidefinite programming and optimal weighting", Automatica 45(1) (2009) 142-148.

    Examples
    --------
    >>> import numpy as np
    >>> from optdesign import Plant
    >>> from optdesign.design.noise_estimation import simulate_outputs
    >>> plant = Plant([[0.5, 0.2], [0.7, 0.4]], [[1.0, 1.0]], Q=np.diag([0.1, 0.0]), R=[[0.1]], dt=1.0)
    >>> y = simulate_outputs(plant, 4000, seed=1)
    >>> front = noise_penalty_front(plant, y, penalties=[1e-4, 1e-2, 1.0], lags=10)
    >>> [r["rank_Q"] for r in front.table.records][-1] <= 1
    True
    """
    from ..design.noise_estimation import estimate_noise

    if "trace_penalty" in estimate_kw:
        raise ValidationError("trace_penalty is the swept argument: give the values as penalties=")
    rhos = as_vector("penalties", penalties)
    if rhos.size < 2:
        raise ValidationError(f"penalties must hold at least two values; found {rhos.size}")
    if np.any(rhos < 0):
        raise ValidationError(f"penalties must be >= 0; found {float(rhos.min())!r} at index "
                              f"{int(np.argmin(rhos))}")
    designs = [estimate_noise(plant, y, u, trace_penalty=float(rho), **estimate_kw) for rho in rhos]
    ok = [bool(est.success and est.Q is not None) for est in designs]
    V = np.array([[float(est.residual), float(np.trace(est.Q))] if good else [np.nan, np.nan]
                  for est, good in zip(designs, ok, strict=True)])
    scale = float(np.nanmax(V[:, 1])) if any(ok) else 0.0
    records = [{"trace_penalty": float(rho), "status": est.status.value, "success": est.success,
                "residual": float(V[i, 0]), "trace_Q": float(V[i, 1]),
                "rank_Q": _rank(est.Q, scale) if ok[i] else -1}
               for i, (rho, est) in enumerate(zip(rhos, designs, strict=True))]
    table = SweepTable(records=records, inputs=("trace_penalty",))
    return ParetoFront(objectives=("residual", "trace_Q"), table=table, values=V,
                       nondominated=nondominated(V), designs=list(designs),
                       levels={"trace_penalty": [float(r) for r in rhos]})
