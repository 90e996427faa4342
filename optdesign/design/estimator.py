r"""Systems out: an observer or Kalman filter as a state-space system.

The estimator takes the known inputs and the measurements, ``[u; y]``, and returns the output
and state estimates, ``[y_hat; x_hat]`` -- the signal layout of MATLAB's ``kalman`` / ``estim``
(``io="optdesign"``, the default).  ``io="control"`` gives python-control's layout: inputs
``[y; u]``, output ``x_hat`` only (what ``create_estimator_iosystem`` returns, and what
``control.create_statefbk_iosystem(sys, K, estimator=est)`` takes; signals named ``y[i]``,
``u[i]``, ``xhat[i]`` -- python-control's default labels, so they connect by name).
With the observer gain L (error dynamics ``A - L C``) and the feedthrough D of the known inputs:

continuous (``form="continuous"``)::

    x_hat' = A x_hat + B u + L (y - C x_hat - D u)
    [y_hat; x_hat] = [C; I] x_hat + [D; 0] u

discrete, predictor (``form="predictor"``, MATLAB's ``'delayed'``): the state is
``x_hat[k|k-1]``::

    x_hat[k+1|k] = A x_hat[k|k-1] + B u[k] + L (y[k] - C x_hat[k|k-1] - D u[k])
    [y_hat[k|k-1]; x_hat[k|k-1]] = [C; I] x_hat[k|k-1] + [D; 0] u[k]

discrete, filter / current (``form="filter"``, MATLAB's ``'current'``): same state, but the outputs
use ``y[k]`` through the innovation gains M (state) and My (output; ``C M`` without noise
feedthrough)::

    x_hat[k|k] = x_hat[k|k-1] + M e[k],   y_hat[k|k] = C x_hat[k|k-1] + D u[k] + My e[k],
    e[k] = y[k] - C x_hat[k|k-1] - D u[k]

The estimator comes back as a python-control ``StateSpace`` when python-control is installed
(signals named ``u[i]``, ``y[i]``, ``yhat[i]``, ``xhat[i]``), else as :class:`EstimatorArrays`
(plain ``A, B, C, D``).

References
----------
MathWorks, *kalman* and *estim* reference pages (Control System Toolbox): estimator equations,
``'current'`` / ``'delayed'`` types, signal layout ``[u; y] -> [y_hat; x_hat]``.
python-control, ``create_estimator_iosystem`` (``control/stochsys.py``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._backends import import_control
from .._validate import as_matrix, as_str
from ..errors import BackendUnavailableError, ValidationError
from ..model.plant import Plant

__all__ = ["EstimatorArrays", "estimator_system", "estimator_of", "FORMS", "OUTPUTS", "IOS"]

#: estimator forms
FORMS = ("continuous", "predictor", "filter")
#: what :func:`estimator_system` returns
OUTPUTS = ("auto", "control", "arrays")
#: signal layouts: ours (MATLAB's) and python-control's
IOS = ("optdesign", "control")


@dataclass(frozen=True, eq=False)
class EstimatorArrays:
    """An estimator as plain arrays; unpacks as ``A, B, C, D = est``.

    Attributes
    ----------
    A : (n, n) ndarray
    B : (n, nu + p) ndarray
        Inputs ``[u; y]`` (``io="control"``: ``[y; u]``).
    C : (p + n, n) ndarray
        Outputs ``[y_hat; x_hat]`` (``io="control"``: ``x_hat``, (n, n)).
    D : (p + n, nu + p) ndarray
    dt : float or None
        Sampling period (None: continuous).
    form : str
        ``"continuous"``, ``"predictor"`` or ``"filter"``.
    inputs, outputs, states : tuple of str
        Signal names.
    """

    A: NDArray[np.float64]
    B: NDArray[np.float64]
    C: NDArray[np.float64]
    D: NDArray[np.float64]
    dt: float | None
    form: str
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    states: tuple[str, ...]

    def __iter__(self):
        return iter((self.A, self.B, self.C, self.D))

    def __len__(self) -> int:
        return 4


def _form(plant: Plant, form: str | None) -> str:
    if form is None:
        return "predictor" if plant.is_discrete else "continuous"
    form = as_str("form", form, FORMS)
    if (form == "continuous") == plant.is_discrete:
        kind = f"discrete (dt = {plant.dt:g})" if plant.is_discrete else "continuous"
        allowed = "'predictor' or 'filter'" if plant.is_discrete else "'continuous'"
        raise ValidationError(f"form must be {allowed} for a {kind} plant; found {form!r}")
    return form


def estimator_system(plant: Plant, L: ArrayLike, *, form: str | None = None, M: ArrayLike | None = None,
                     My: ArrayLike | None = None, D: ArrayLike | None = None, output: str = "auto",
                     name: str | None = None, io: str = "optdesign") -> Any:
    """The estimator of ``plant`` with gain L as a system: inputs ``[u; y]``, outputs ``[y_hat; x_hat]``
    (``io="control"``: inputs ``[y; u]``, output ``x_hat``).

    Parameters
    ----------
    plant : Plant
        ``A`` (n, n), ``C`` (p, n), ``B`` (n, nu) for the known inputs (none: the inputs are ``y``
        only), ``dt``.
    L : (n, p) array_like
        Observer gain (error dynamics ``A - L C``; discrete: the predictor gain).
    form : {"continuous", "predictor", "filter"}, optional
        Default: ``"continuous"`` for a continuous plant, ``"predictor"`` for a discrete one.
    M : (n, p) array_like, optional
        ``form="filter"``: the innovation (measurement-update) gain, e.g. ``KalmanFilter.M``.
    My : (p, p) array_like, optional
        ``form="filter"``: the output innovation gain (default ``C M``).
    D : (p, nu) array_like, optional
        Feedthrough of the known inputs (default zero).
    output : {"auto", "control", "arrays"}
        ``"auto"``: a python-control ``StateSpace`` if python-control is installed, else
        :class:`EstimatorArrays`.
    name : str, optional
        Name of the python-control system.
    io : {"optdesign", "control"}
        Signal layout: ``"optdesign"`` (MATLAB's ``kalman`` / ``estim``: ``[u; y] -> [y_hat;
        x_hat]``) or ``"control"`` (python-control's ``create_estimator_iosystem``: ``[y; u] ->
        x_hat``; pass it as ``estimator=`` to ``control.create_statefbk_iosystem``).  The default
        stays ours: it carries the output estimate (and, in filter form, ``My``), which
        python-control's layout drops.

    Returns
    -------
    control.StateSpace or EstimatorArrays

    Raises
    ------
    ValidationError
        Not a Plant; a form that does not match the plant's time domain, or ``"filter"`` without M;
        an unknown ``output``.
    DimensionError, NotFiniteError
        L, M, My or D of the wrong shape or not finite.
    BackendUnavailableError
        ``output="control"`` without python-control.

    Examples
    --------
    >>> import numpy as np
    >>> from optdesign import Plant, estimator_system
    >>> plant = Plant([[0., 1.], [0., 0.]], [[1., 0.]], B=[[0.], [1.]])
    >>> est = estimator_system(plant, [[2.], [1.]], output="arrays")   # inputs [u; y], outputs [y_hat; x_hat]
    >>> est.B.shape, est.C.shape
    ((2, 2), (3, 2))
    >>> np.linalg.eigvals(est.A).real.round(6).tolist()             # A - L C: a double pole at -1
    [-1.0, -1.0]
    """
    if not isinstance(plant, Plant):
        raise ValidationError(f"plant must be an optdesign.Plant; found {type(plant).__name__}")
    form = _form(plant, form)
    output = as_str("output", output, OUTPUTS)
    io = as_str("io", io, IOS)
    A, C = plant.A, plant.C
    n, p = plant.n, plant.p
    L = as_matrix("L", L, (n, p))
    B = plant.B if plant.B is not None else np.zeros((n, 0))
    nu = B.shape[1]
    D = np.zeros((p, nu)) if D is None else as_matrix("D", D, (p, nu))
    I_n = np.eye(n)
    Ae = A - L @ C
    Be = np.hstack([B - L @ D, L])
    if form == "filter":
        if M is None:
            raise ValidationError("form='filter' needs the innovation gain M (n x p), e.g. KalmanFilter.M")
        M = as_matrix("M", M, (n, p))
        My = C @ M if My is None else as_matrix("My", My, (p, p))
        Ce = np.vstack([C - My @ C, I_n - M @ C])
        De = np.block([[D - My @ D, My], [-M @ D, M]])
    else:
        Ce = np.vstack([C, I_n])
        De = np.block([[D, np.zeros((p, p))], [np.zeros((n, nu + p))]])
    inputs = tuple(f"u[{i}]" for i in range(nu)) + tuple(f"y[{i}]" for i in range(p))
    outputs = tuple(f"yhat[{i}]" for i in range(p)) + tuple(f"xhat[{i}]" for i in range(n))
    states = tuple(f"xe[{i}]" for i in range(n))
    if io == "control":     # inputs [y; u], output x_hat: python-control's create_estimator_iosystem
        perm = list(range(nu, nu + p)) + list(range(nu))
        Be, Ce, De = Be[:, perm], Ce[p:], De[p:][:, perm]
        inputs, outputs = tuple(inputs[j] for j in perm), outputs[p:]
    if output != "arrays":
        try:
            control = import_control("output='control' (or use output='arrays')")
        except BackendUnavailableError:
            if output == "control":
                raise
        else:
            return control.StateSpace(Ae, Be, Ce, De, 0 if plant.dt is None else plant.dt,
                                      inputs=list(inputs), outputs=list(outputs), states=list(states),
                                      name=name or (f"{plant.name}_estimator" if plant.name else None))
    return EstimatorArrays(Ae, Be, Ce, De, plant.dt, form, inputs, outputs, states)


def estimator_of(result: Any, plant: Plant | None = None, *, form: str | None = None,
                 output: str = "auto", io: str = "optdesign") -> Any:
    """The estimator of a design result (``result.estimator()``).

    Reads ``L`` (and, where the result has them, the innovation gains ``M`` / ``My`` and the
    feedthrough ``D`` of a Kalman filter) and the plant (``result.plant`` unless given).

    Raises
    ------
    ValidationError
        The result has no gain (the design failed: its status is named) or no plant and none is
        given; see :func:`estimator_system` for the rest.
    """
    L = getattr(result, "L", None)
    if L is None:
        status = getattr(result, "status", "?")
        raise ValidationError(f"the result has no gain L (status {getattr(status, 'value', status)}): "
                              f"there is no estimator to build")
    plant = plant if plant is not None else getattr(result, "plant", None)
    if plant is None:
        raise ValidationError(f"{type(result).__name__} does not carry its plant: pass plant=")
    M = getattr(result, "M", None)
    return estimator_system(plant, L, form=form, M=M, My=getattr(result, "My", None),
                            D=getattr(result, "D", None), output=output, io=io)
