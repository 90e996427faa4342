"""Systems in: the one place where a python-control or scipy system becomes a :class:`Plant`.

Every design verb accepts

* an :class:`optdesign.Plant`;
* a python-control ``StateSpace`` (continuous, ``dt = 0`` or ``None``, or discrete, ``dt > 0``);
* a scipy ``signal.StateSpace`` / ``lti`` / ``dlti`` in state-space form,

and converts it with :func:`as_plant` (or :func:`as_system`, which also keeps the feedthrough
matrices that a :class:`Plant` does not model).  The noise data that a system does not carry
(``Q``, ``R``, ``G``) are keyword arguments.  Transfer functions are refused
(:class:`~optdesign.errors.ArgumentTypeError`, a ``TypeError`` as python-control's
``ControlArgument``) with how to convert them: a state estimator needs a state-space
realization, and the realization chosen fixes what the states are -- and with them Q, P, kappa2
and every other design quantity -- so the choice is the caller's (``control.ss(sys)``,
``sys.to_ss()``).  A discrete system with an unspecified sampling period (python-control's
``dt=True``, what ``control.drss`` returns) is designed with ``dt = 1`` and the result says so
(``SystemData.notes``): every gain of a discrete design is independent of the period.

python-control is optional: it is imported only when the object to convert comes from it.

Input and output selection follows MATLAB's ``kalman(sys, Q, R, N, sensors, known)``: ``known``
lists the (0-based) inputs of ``sys`` that are known (deterministic, they make up ``u`` and
``B``); the other inputs are the process noise ``w`` (their columns of ``sys.B`` make up ``G``,
their columns of ``sys.D`` the noise feedthrough ``H``); ``sensors`` lists the measured outputs.

How the noise enters a *system* (not a Plant, which carries its own G) when Q is given -- the
rule, in order (what was used is in ``SystemData.notes``):

1. ``known=`` given: MATLAB's selection above.
2. ``G=`` given: the noise enters through G; every input of ``sys`` is known.
3. Q is ``m x m`` with ``m`` = the number of inputs of ``sys``: the noise enters through
   ``sys.B`` -- python-control's ``lqe(sys, QN, RN)`` and ``create_estimator_iosystem`` ("the
   disturbances are added to the system inputs"): ``G = sys.B``, the inputs stay known
   (``B = sys.B``) and ``H = sys.D``.  (MATLAB's reading, every input noise and none known, gives
   the same gain; ``known=[]`` selects it.)
4. Q is ``m x m`` with ``m`` smaller than the number of inputs: MATLAB's ``kalman(sys, Qn, Rn)``
   -- the *last* m inputs are the process noise, the others known.
5. Q is ``n x n`` with more rows than the system has inputs: the noise enters every state,
   ``G = I`` -- the library's own convention (a :class:`Plant` without G, the Q that
   :func:`optdesign.kalman_for_poles` returns), said in the notes, never silently.  Neither peer
   answers this call (python-control and MATLAB refuse a Q larger than the inputs).
6. Otherwise (Q neither matches nor fits the inputs, and is not n x n): refused, asking for
   ``G=`` or ``known=``.

References
----------
MathWorks, *kalman -- Design Kalman filter for state estimation*, Control System Toolbox
reference page (https://www.mathworks.com/help/control/ref/ss.kalman.html): ``sys`` with inputs
``[u; w]``, ``sensors`` and ``known`` index vectors.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._backends import import_control
from .._validate import as_matrix
from ..errors import ArgumentTypeError, ValidationError
from .plant import Plant

__all__ = ["SystemData", "as_system", "as_plant", "system_kind", "SYSTEM_KINDS"]

#: what :func:`as_plant` accepts, for messages
SYSTEM_KINDS = ("an optdesign.Plant", "a python-control StateSpace",
                "a scipy.signal StateSpace / lti / dlti (state-space form)")

_AUTO_NAME = re.compile(r"^sys\[\d+\]$")   # python-control's generated names


@dataclass(frozen=True, eq=False)
class SystemData:
    """A system converted for design: the plant plus what a :class:`Plant` does not model.

    Attributes
    ----------
    plant : Plant
        ``A``, ``C`` (the measured outputs), ``B`` (the known inputs; None when there are none),
        ``G``, ``Q``, ``R``, ``dt``.
    D : (p, nu) ndarray or None
        Feedthrough of the known inputs to the measured outputs (None when zero or when there are
        no known inputs).  It does not change any gain; the estimator subtracts ``D u``.
    H : (p, m) ndarray or None
        Feedthrough of the process noise to the measured outputs, ``y = C x + D u + H w + v``
        (None when zero).  The Kalman filter folds it into R and N (MATLAB's ``R_bar``, ``N_bar``).
    sensors, known : tuple of int or None
        The selections made (0-based), None when not given.
    source : str
        What the input was (``"Plant"``, ``"python-control StateSpace"``, ``"scipy StateSpace"``).
    notes : tuple of str
        The conventions applied, in words: how the noise enters (the rule of the module notes)
        and an unspecified sampling period taken as 1.  Empty for a Plant.
    dt_unspecified : bool
        The system was discrete with ``dt=True``; ``plant.dt`` is 1.
    """

    plant: Plant
    D: NDArray[np.float64] | None = None
    H: NDArray[np.float64] | None = None
    sensors: tuple[int, ...] | None = None
    known: tuple[int, ...] | None = None
    source: str = "Plant"
    notes: tuple[str, ...] = ()
    dt_unspecified: bool = False


def system_kind(obj: Any) -> str | None:
    """``"plant"``, ``"control"`` (a python-control object), ``"scipy"`` (a scipy.signal LTI object)
    or None, without importing python-control."""
    if isinstance(obj, Plant):
        return "plant"
    module = type(obj).__module__ or ""
    root = module.split(".", 1)[0]
    if root == "control":
        return "control"
    if module.startswith("scipy.signal"):
        return "scipy"
    return None


def _indices(name: str, value: Any, size: int, what: str, *, allow_empty: bool) -> tuple[int, ...]:
    """0-based, distinct, in-range integer indices (a sequence or one integer)."""
    if isinstance(value, (bool, np.bool_)) or isinstance(value, (str, bytes)):
        raise ValidationError(f"{name} must be a list of 0-based {what} indices; found {value!r}")
    items = [value] if isinstance(value, (int, np.integer)) else value
    if not isinstance(items, (Sequence, np.ndarray)):
        raise ValidationError(f"{name} must be a list of 0-based {what} indices; found "
                              f"{type(value).__name__} {value!r}")
    out: list[int] = []
    for k, v in enumerate(list(items)):
        if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, np.integer)):
            raise ValidationError(f"{name}[{k}] must be an integer index; found {v!r}")
        if not 0 <= int(v) < size:
            raise ValidationError(f"{name}[{k}] = {int(v)} is out of range: the system has {size} {what}s "
                                  f"(valid 0-based indices 0..{size - 1})")
        if int(v) in out:
            raise ValidationError(f"{name} lists {what} {int(v)} twice")
        out.append(int(v))
    if not out and not allow_empty:
        raise ValidationError(f"{name} must select at least one {what}; found an empty list")
    return tuple(out)


def _nonzero(X: NDArray | None) -> NDArray | None:
    return None if X is None or X.size == 0 or not np.any(X) else X


#: the note of a system with ``dt=True``
DT_TRUE_NOTE = ("discrete system with an unspecified sampling period (dt=True): designed with dt = 1 "
                "(the gains do not depend on the period; give a number for time axes)")


def _dt_of(dt: Any) -> float | None:
    """Sampling period from a python-control (0 / None: continuous) or scipy (None: continuous)
    system; ``True`` (discrete, unspecified period) is 1."""
    if dt is True:
        return 1.0
    if dt is None or dt == 0:
        return None
    return float(dt)


def _state_space_arrays(sys: Any, kind: str) -> tuple[NDArray, NDArray, NDArray, NDArray, float | None,
                                                       str | None, str]:
    """(A, B, C, D, dt, name, source) of a python-control or scipy state-space object; a clear error
    for anything else of those packages."""
    if kind == "control":
        control = import_control("converting a python-control system")
        if isinstance(sys, control.TransferFunction):
            raise ArgumentTypeError(
                "plant is a python-control TransferFunction: a state estimator needs a state-space model, "
                "and the realization fixes what the states are (and so Q, P and kappa2); convert it "
                "yourself, e.g. control.ss(sys), and pass the StateSpace")
        if not isinstance(sys, control.StateSpace):
            raise ArgumentTypeError(f"plant must be {', '.join(SYSTEM_KINDS[:-1])} or {SYSTEM_KINDS[-1]}; "
                                  f"found the python-control {type(sys).__name__}, which is not a linear "
                                  f"state-space system")
        name = getattr(sys, "name", None)
        name = None if not name or _AUTO_NAME.match(str(name)) else str(name)
        return (np.asarray(sys.A, dtype=float), np.asarray(sys.B, dtype=float),
                np.asarray(sys.C, dtype=float), np.asarray(sys.D, dtype=float),
                _dt_of(sys.dt), name, "python-control StateSpace")
    import scipy.signal as signal

    if isinstance(sys, (signal.TransferFunction, signal.ZerosPolesGain)):
        raise ArgumentTypeError(
            f"plant is a scipy.signal {type(sys).__name__}: a state estimator needs a state-space model, "
            f"and the realization fixes what the states are (and so Q, P and kappa2); convert it "
            f"yourself, e.g. sys.to_ss() (or scipy.signal.tf2ss), and pass the StateSpace")
    if not isinstance(sys, signal.StateSpace):
        raise ArgumentTypeError(f"plant must be {', '.join(SYSTEM_KINDS[:-1])} or {SYSTEM_KINDS[-1]}; found "
                              f"the scipy object {type(sys).__name__}")
    return (np.atleast_2d(np.asarray(sys.A, dtype=float)), np.atleast_2d(np.asarray(sys.B, dtype=float)),
            np.atleast_2d(np.asarray(sys.C, dtype=float)), np.atleast_2d(np.asarray(sys.D, dtype=float)),
            _dt_of(sys.dt), None, "scipy StateSpace")


def _from_plant(plant: Plant, G: Any, Q: Any, R: Any, name: str | None, sensors: Any,
                known: Any) -> SystemData:
    """A Plant, with keyword data only where it has none (no silent override)."""
    if known is not None:
        raise ValidationError("known applies to a system whose inputs mix known inputs and process noise; "
                              "a Plant keeps them apart (B: known inputs, G: noise inputs)")
    changes: dict[str, Any] = {}
    for key, value in (("Q", Q), ("R", R)):
        if value is not None:
            if getattr(plant, key) is not None:
                raise ValidationError(f"{key} given twice: the plant already has {key}; use "
                                      f"plant.replace({key}=...) to change it")
            changes[key] = value
    if G is not None:
        if plant.Q is not None or not np.array_equal(np.asarray(plant.G), np.eye(plant.n)):
            raise ValidationError("G given twice: the plant already has G (with its Q); use "
                                  "plant.replace(G=..., Q=...) to change it")
        changes["G"] = G
    if name is not None:
        changes["name"] = name
    sel = None
    if sensors is not None:
        sel = _indices("sensors", sensors, plant.p, "output", allow_empty=False)
        changes["C"] = plant.C[list(sel)]
        if "R" not in changes and plant.R is not None:
            changes["R"] = plant.R[np.ix_(sel, sel)]
    return SystemData(plant.replace(**changes) if changes else plant, sensors=sel)


def _noise_inputs(A: NDArray, B: NDArray, G: Any, Q: Any, known: Any
                  ) -> tuple[NDArray | None, Any, tuple[int, ...] | None, list[int], str | None]:
    """(B of the known inputs, G, known indices, noise input indices, the rule used in words) of a
    system, by the rule of the module notes."""
    n, nin = A.shape[0], B.shape[1]
    if known is not None:
        kn = _indices("known", known, nin, "input", allow_empty=True)
        rest = [j for j in range(nin) if j not in kn]
        if rest and G is not None:
            raise ValidationError(f"G given twice: with known={list(kn)} the other inputs {rest} of sys are "
                                  f"the process noise, so G is their columns of sys.B; drop G= or list every "
                                  f"input in known")
        Bk = B[:, list(kn)] if kn else None
        note = (f"known={list(kn)}: inputs {rest} of sys are the process noise (G = their columns of sys.B)"
                if rest else None)
        return Bk, (B[:, rest] if rest else G), kn, rest, note
    if G is not None or Q is None:
        return (B if nin else None), G, None, [], None
    m = as_matrix("Q", Q).shape[0]
    if nin and m == nin:
        note = (f"Q is {m} x {m} = the {nin} input(s) of sys: the noise enters through sys.B, added to the "
                f"known inputs (python-control's lqe(sys, QN, RN); known=[] for MATLAB's all-noise reading)")
        return B, B, None, list(range(nin)), note
    if nin and m < nin:
        rest = list(range(nin - m, nin))
        kn = tuple(range(nin - m))
        note = (f"Q is {m} x {m} and sys has {nin} inputs: the last {m} input(s) {rest} are the process "
                f"noise, inputs {list(kn)} known (MATLAB's kalman(sys, Qn, Rn); known= to choose others)")
        return B[:, list(kn)], B[:, rest], kn, rest, note
    if m == n:
        note = (f"Q is n x n = {n} x {n} and sys has {nin} input(s): the noise enters every state (G = I; "
                f"G= or known= to say otherwise)")
        return (B if nin else None), None, None, [], note
    inputs = f"sys has {nin} input(s)" if nin else "sys has no inputs"
    raise ValidationError(
        f"Q is {m} x {m} but {inputs} and the plant has n = {n} states: say how the noise enters -- G= "
        f"(n x {m}), or known=[...] to list the known inputs of sys (the other inputs are the process "
        f"noise, as in MATLAB's kalman(sys, Q, R, N, sensors, known))")


def as_system(sys: Any, *, G: Any = None, Q: Any = None, R: Any = None, sensors: Any = None,
              known: Any = None, name: str | None = None) -> SystemData:
    """Convert a Plant, a python-control ``StateSpace`` or a scipy state-space system.

    Parameters
    ----------
    sys : Plant, control.StateSpace or scipy.signal.StateSpace / lti / dlti
        A python-control ``dt`` of 0 or None and a scipy ``dt`` of None mean continuous time;
        ``dt=True`` (discrete, unspecified period) is taken as 1 (said in ``notes``).
    G : (n, m) array_like, optional
        Process-noise input matrix.  Default for a system: by the rule of the module notes
        (``known=``, else ``sys.B`` when Q matches the inputs, else MATLAB's last-inputs reading);
        for a Plant its own G.  Not with a Plant that has its own G and Q.
    Q : (m, m) array_like, optional
        Process-noise covariance; only where ``sys`` does not carry one.
    R : (p, p) array_like, optional
        Measurement-noise covariance of the measured outputs; only where ``sys`` has none.  For a
        Plant with R and ``sensors``, the sub-block of the selected outputs is taken.
    sensors : sequence of int, optional
        0-based indices of the measured outputs (default: all).
    known : sequence of int, optional
        0-based indices of the known inputs of a system; the others are process noise (their
        columns of ``sys.B`` become G, of ``sys.D`` the noise feedthrough H).  Default: by the rule
        of the module notes.  Not for a Plant.
    name : str, optional
        The plant's label (default: the system's own name, if it set one).

    Returns
    -------
    SystemData

    Raises
    ------
    ArgumentTypeError
        A transfer function (with how to convert it: ``control.ss(sys)``, ``sys.to_ss()``) or
        another kind of object (the accepted kinds are listed); a ``TypeError`` and a
        ``ValidationError``.
    ValidationError
        Q with more rows than ``sys`` has inputs, not n x n, and neither G nor ``known``; data
        given twice (a Plant's own Q, R or G; G with noise inputs
        from ``known``),
        ``sensors`` / ``known`` not distinct 0-based indices in range (the bad entry is named).
    DimensionError, NotFiniteError, NotSymmetricError, NotPositiveSemidefiniteError, NotPositiveDefiniteError
        From the Plant constructor (names the matrix).
    BackendUnavailableError
        Never for a Plant or a scipy system; python-control is needed only for its own objects.

    Examples
    --------
    >>> import scipy.signal
    >>> from optdesign import as_system
    >>> sd = as_system(scipy.signal.StateSpace([[-1.0]], [[1.0]], [[1.0]], [[0.0]]), Q=[[1.0]], R=[[0.1]])
    >>> sd.plant                      # Q matches the inputs: the noise enters through B
    Plant(n=1, p=1, m=1, continuous, Q,R given)
    >>> sd.plant.G.tolist(), sd.source
    ([[1.0]], 'scipy StateSpace')
    """
    kind = system_kind(sys)
    if kind == "plant":
        return _from_plant(sys, G, Q, R, name, sensors, known)
    if kind is None:
        found = type(sys).__name__
        hint = " (a tuple of matrices? build optdesign.Plant(A, C, ...) or control.ss(A, B, C, D))" \
            if isinstance(sys, (tuple, list)) else ""
        raise ArgumentTypeError(f"plant must be {', '.join(SYSTEM_KINDS[:-1])} or {SYSTEM_KINDS[-1]}; found "
                                f"{found}{hint}")
    A, B, C, D, dt, sys_name, source = _state_space_arrays(sys, kind)
    n = A.shape[0] if A.ndim == 2 else 0
    B = B.reshape(n, -1) if B.size else np.zeros((n, 0))
    D = D.reshape(C.shape[0], B.shape[1]) if D.size else np.zeros((C.shape[0], B.shape[1]))
    sel = None if sensors is None else _indices("sensors", sensors, C.shape[0], "output", allow_empty=False)
    rows = list(range(C.shape[0])) if sel is None else list(sel)
    Bk, G_used, kn, rest, note = _noise_inputs(A, B, G, Q, known)
    Dk = D[np.ix_(rows, list(kn))] if kn is not None else D[rows]
    H = D[np.ix_(rows, rest)] if rest else None
    plant = Plant(A, C[rows], G=G_used, Q=Q, R=R, dt=dt, B=Bk,
                  name=name if name is not None else sys_name)
    unspecified = getattr(sys, "dt", None) is True
    notes = tuple(t for t in (note, DT_TRUE_NOTE if unspecified else None) if t)
    return SystemData(plant, D=_nonzero(Dk), H=_nonzero(H), sensors=sel, known=kn, source=source,
                      notes=notes, dt_unspecified=unspecified)


def as_plant(sys: Any, *, G: Any = None, Q: Any = None, R: Any = None, name: str | None = None) -> Plant:
    """The :class:`Plant` of a Plant, a python-control ``StateSpace`` or a scipy state-space system.

    The one conversion point of the design verbs (``Plant.coerce``).  ``sys.B`` becomes the
    known-input matrix B (used for estimators and simulation); Q, R and G are taken from the
    keywords where ``sys`` does not carry them.  See :func:`as_system` for the parameters.

    Raises
    ------
    ValidationError
        As :func:`as_system`; also a system with a nonzero feedthrough D: a Plant models
        ``y = C x + v``.  The gain does not depend on D -- design with ``D = 0``
        (``control.ss(sys.A, sys.B, sys.C, 0)``) and give D to the estimator
        (``estimator_system(..., D=sys.D)``), or call :func:`optdesign.kalman`, which keeps D.

    Examples
    --------
    >>> import control
    >>> plant = as_plant(control.ss([[0, 1], [-6, -5]], [[0], [1]], [[1, 0]], 0), R=[[1]])
    >>> plant.n, plant.p, plant.B.ravel().tolist(), plant.is_discrete
    (2, 1, [0.0, 1.0], False)
    """
    data = as_system(sys, G=G, Q=Q, R=R, name=name)
    if data.D is not None:
        raise ValidationError(
            f"plant has a nonzero feedthrough D (max |D| = {float(np.max(np.abs(data.D))):.3g}): an "
            f"optdesign.Plant models y = C x + v.  The gain does not depend on D: design with D = 0, e.g. "
            f"control.ss(sys.A, sys.B, sys.C, 0), and give D to the estimator "
            f"(estimator_system(..., D=sys.D)); optdesign.kalman(sys, ...) keeps D itself")
    return data.plant
