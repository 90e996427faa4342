"""Simulation of a plant and an observer under a given output noise (:func:`simulate_observer`, part of
:mod:`optdesign.design.generalized`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..._validate import as_matrix
from ...errors import DimensionError, ValidationError
from ...model.plant import Plant
from .common import check_discrete_plant, sampling_period
from .results import GeneralizedObserver, NoiseRejectingObserver, ObserverSimulation

__all__ = ["simulate_observer"]


# --------------------------------------------------------------------------- simulation
def simulate_observer(
    observer: GeneralizedObserver | NoiseRejectingObserver | ArrayLike,
    noise: ArrayLike,
    *,
    x0: ArrayLike | None = None,
    xhat0: ArrayLike | None = None,
    u: ArrayLike | None = None,
    plant: Plant | None = None,
) -> ObserverSimulation:
    r"""Run a discrete plant and an observer with a given output noise.

    ``x(k+1) = A x + B u``, ``y(k) = C x(k) + delta(k)``; the observer is updated with ``y(k)``
    (predictor form, as seed 003 eq (2)).

    Parameters
    ----------
    observer : GeneralizedObserver, NoiseRejectingObserver or (n, p) array_like
        An array is a plain Luenberger gain ``L``: ``xh(k+1) = A xh + B u + L (y - C xh)``
        (then ``plant`` is required).
    noise : (T,) or (T, p) array_like
        ``delta(k)`` for ``k = 0..T-1`` (T samples are simulated), e.g.
        ``0.2 * Sinusoid(1, 0.01).signal(T)``.
    x0 : (n,) array_like, optional
        Initial plant state (default zeros).
    xhat0 : (n,) array_like, optional
        Initial estimate (default zeros); the observer's extra state starts at zero.
    u : (T, m) or (T,) array_like, optional
        Input sequence (needs ``plant.B``); default none.
    plant : Plant, optional
        The *true* plant (default: the observer's own model).

    Returns
    -------
    ObserverSimulation

    Raises
    ------
    ValidationError, DimensionError
        Bad shapes, a continuous-time plant, u without B, non-finite data.

    Examples
    --------
    >>> import numpy as np
    >>> from optdesign import Plant, simulate_observer
    >>> plant = Plant([[0.9, 0.1], [0.0, 0.8]], [[1.0, 0.0]], dt=0.1)
    >>> sim = simulate_observer([[0.6], [0.5]], 0.1 * np.ones(300), x0=[1.0, 0.0], plant=plant)
    >>> sim.error.shape, bool(sim.tail("error") > 0.01)     # a plain gain: the offset biases x_hat
    ((300, 2), True)
    """
    gen: GeneralizedObserver | None = None
    rej: NoiseRejectingObserver | None = None
    Lg: NDArray[np.float64] | None = None
    if isinstance(observer, GeneralizedObserver):
        gen, kind, model = observer, "generalized", observer.plant
    elif isinstance(observer, NoiseRejectingObserver):
        rej, kind, model = observer, "noise_rejecting", observer.plant
    else:
        if plant is None:
            raise ValidationError("a plain gain L needs plant=...; or pass a GeneralizedObserver / "
                                  "NoiseRejectingObserver")
        kind, model = "luenberger", check_discrete_plant(plant, "simulate_observer")
        Lg = as_matrix("L", observer, (model.n, model.p))
    true = model if plant is None else check_discrete_plant(plant, "simulate_observer")
    if (true.n, true.p) != (model.n, model.p):
        raise DimensionError(f"plant has (n, p) = ({true.n}, {true.p}) but the observer was designed for "
                             f"({model.n}, {model.p})")
    n, p = model.n, model.p
    d = np.asarray(noise, dtype=float)
    if d.ndim == 1 and p == 1:
        d = d.reshape(-1, 1)
    if d.ndim != 2 or d.shape[1] != p or d.shape[0] < 1:
        raise DimensionError(f"noise must have shape (T,) (one output) or (T, {p}); found {np.shape(noise)}")
    if not np.all(np.isfinite(d)):
        raise ValidationError("noise must be finite")
    T = d.shape[0]
    x = np.zeros(n) if x0 is None else as_matrix("x0", x0, (n, 1)).ravel()
    xh = np.zeros(n) if xhat0 is None else as_matrix("xhat0", xhat0, (n, 1)).ravel()
    U = None
    if u is not None:
        if true.B is None or model.B is None:
            raise ValidationError("u given but the plant has no input matrix B (Plant(..., B=...))")
        U = np.asarray(u, dtype=float)
        if U.ndim == 1:
            U = U.reshape(-1, 1)
        if U.shape != (T, true.B.shape[1]):
            raise DimensionError(f"u must have shape ({T}, {true.B.shape[1]}); found {np.shape(u)}")
    if gen is not None:
        q = gen.N.shape[0]
    elif rej is not None:
        q = rej.N.shape[0]
    else:
        q = 0
    X, XH = np.zeros((T, n)), np.zeros((T, n))
    Y, EPS = np.zeros((T, p)), np.zeros((T, p))
    Z = np.zeros((T, q))
    DH = np.zeros((T, p))  # the noise estimate Gamma z (noise-rejecting observer only)
    z: NDArray[np.float64] = np.zeros(q)
    A, C = model.A, model.C
    for k in range(T):
        y = true.C @ x + d[k]
        X[k], XH[k], Y[k], Z[k] = x, xh, y, z
        EPS[k] = y - C @ xh
        uk = None if U is None else U[k]
        if gen is not None:
            xh, z = gen.step(xh, z, y, uk)
        elif rej is not None:
            DH[k] = rej.Gamma @ z
            xa = rej.step(np.concatenate([xh, z]), y, uk)
            xh, z = xa[:n], xa[n:]
        elif Lg is not None:
            xh = A @ xh + Lg @ (y - C @ xh) + (0.0 if uk is None else model.B @ uk)
        x = true.A @ x + (0.0 if uk is None else true.B @ uk)
    t = np.arange(T, dtype=np.float64) * sampling_period(true, "simulate_observer")
    return ObserverSimulation(t=t, x=X, xhat=XH, y=Y, delta=d.copy(), eps=EPS, internal=Z,
                              noise_estimate=DH if rej is not None else None, kind=kind, C=np.array(C))
