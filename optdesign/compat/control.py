r"""python-control's call forms and returns, answered by optdesign's verified verbs.

``from optdesign.compat import control as ct`` (or ``from optdesign.compat.control import lqe``)
switches these functions of python-control: the same positional forms, defaults and returns
(ndarrays and tuples, not result objects), with every answer checked before it is returned.

* ``K = place(A, B, p)``: :func:`optdesign.place` (the minimum cond(X) placement); the closed-loop
  eigenvalues are checked against ``p``.
* ``L, P, E = lqe(A, G, C, QN, RN)`` / ``lqe(sys, QN, RN)``: :func:`optdesign.kalman`, continuous (a
  discrete ``sys`` goes to ``dlqe``, as in python-control); Riccati residual, forward error and the
  other solver's P checked.
* ``L, P, E = dlqe(...)``: :func:`optdesign.kalman`, discrete (the predictor gain
  ``A P C' (C P C' + R)^-1`` of python-control's ``dlqe``).
* ``K, S, E = lqr(A, B, Q, R[, N])`` / ``dlqr(...)``: :func:`optdesign.kalman` of the dual pair
  ``(A', B')`` -- LQR's Riccati equation *is* the filter equation of the dual, so the same solvers
  and checks answer it; ``integral_action=`` as python-control.
* ``create_estimator_iosystem(sys, QN, RN, ...)``: python-control's time-varying estimator (states
  ``[xhat; P]``), with the steady state of :func:`optdesign.kalman` as its check.

``method=``: python-control's ``None`` (its default: slycot, then scipy), ``"slycot"`` and
``"scipy"`` are accepted.  ``None`` and ``"scipy"`` run scipy's Riccati solvers (with our
Hamiltonian/symplectic Schur solver as the fallback and the independent cross-check);
``"slycot"`` -- Laub's Schur method on the Hamiltonian (symplectic) matrix, the algorithm of
SLICOT's SB02MD -- runs our implementation of that method, so slycot need not be installed.

Errors subclass both ours and python-control's (when it is installed):
:class:`ControlArgumentError` is an :class:`~optdesign.errors.ArgumentTypeError` and a
``control.ControlArgument`` (so a ``TypeError``), :class:`ControlDimensionError` a
:class:`~optdesign.errors.DimensionError` and a ``control.ControlDimension``.

Deliberate differences (docs: "Differences from scipy and python-control"): a cross-covariance
``NN`` is *supported* by ``lqe`` / ``dlqe`` (python-control raises ``ControlNotImplemented``);
``create_estimator_iosystem`` accepts a feedthrough of the control inputs (python-control raises
``NotImplementedError`` for any nonzero D).

References
----------
python-control 0.10, ``control/statefbk.py`` (place, lqr, dlqr) and ``control/stochsys.py`` (lqe,
dlqe, create_estimator_iosystem).  Laub, A. J., "A Schur method for solving algebraic Riccati
equations", IEEE TAC 24(6) (1979) 913-921.
"""

from __future__ import annotations

from typing import Any, cast

import numpy as np
from numpy.typing import NDArray

from ..errors import (
    ArgumentTypeError,
    DimensionError,
    InfeasibleError,
    NotControllableError,
    NotObservableError,
    OptDesignError,
    RiccatiError,
)
from ..model.plant import Plant

__all__ = ["place", "lqe", "dlqe", "lqr", "dlqr", "create_estimator_iosystem", "ControlArgumentError",
           "ControlDimensionError", "ControlNotImplementedError", "METHODS"]

#: python-control's ``method=`` values and the Riccati method of :func:`optdesign.kalman` that runs
METHODS: dict[Any, str] = {None: "scipy", "scipy": "scipy", "slycot": "hamiltonian"}

_EPS = float(np.finfo(float).eps)


def _control_bases() -> tuple[type, type, type]:
    try:
        from control.exception import ControlArgument, ControlDimension, ControlNotImplemented
    except ImportError:  # pragma: no cover - exercised only without python-control
        return TypeError, ValueError, NotImplementedError
    return ControlArgument, ControlDimension, ControlNotImplemented


_CA, _CD, _CN = _control_bases()


class ControlArgumentError(ArgumentTypeError, _CA):  # type: ignore[misc,valid-type]
    """A bad argument of a python-control call form: ours (ValidationError, TypeError) and
    python-control's ``ControlArgument``."""


class ControlDimensionError(DimensionError, _CD):  # type: ignore[misc,valid-type]
    """Matrices of incompatible sizes: ours and python-control's ``ControlDimension``."""


class ControlNotImplementedError(OptDesignError, _CN):  # type: ignore[misc,valid-type]
    """A python-control form this layer does not answer: ``NotImplementedError`` and
    python-control's ``ControlNotImplemented``."""


# ------------------------------------------------------------------ argument handling
def _is_control(obj: Any) -> bool:
    return (type(obj).__module__ or "").split(".", 1)[0] == "control"


def _is_statespace(obj: Any) -> bool:
    if not _is_control(obj):
        return False
    import control

    return isinstance(obj, control.StateSpace)


def _strict_discrete(sys: Any) -> bool:
    """python-control's ``isdtime(sys, strict=True)``: dt is True or a number > 0."""
    dt = getattr(sys, "dt", None)
    return dt is True or (dt is not None and dt is not False and dt != 0)


def _strict_continuous(sys: Any) -> bool:
    """python-control's ``isctime(sys, strict=True)``: dt == 0 (None means either)."""
    dt = getattr(sys, "dt", None)
    return dt is not None and dt is not True and dt == 0


def _matrix(name: str, X: Any) -> NDArray[np.float64]:
    try:
        M = np.array(X, ndmin=2, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ControlArgumentError(f"{name} must be a numeric matrix; found {type(X).__name__} "
                                   f"({exc})") from exc
    if M.ndim != 2:
        raise ControlDimensionError(f"{name} must be a 2D matrix; found {M.ndim} dimensions")
    return M


def _check_shape(name: str, M: NDArray, rows: int, cols: int, *, square: bool = False) -> NDArray:
    """python-control's ``_check_shape`` messages ("X must be a square matrix", "Incompatible
    dimensions of X matrix; expected (r, c) but found (r', c')")."""
    if square and M.shape[0] != M.shape[1]:
        raise ControlDimensionError(f"{name} must be a square matrix; found shape {M.shape}")
    if M.shape != (rows, cols):
        raise ControlDimensionError(f"Incompatible dimensions of {name} matrix; expected ({rows}, {cols}) "
                                    f"but found {M.shape}")
    return M


def _method(method: Any) -> str:
    try:
        return METHODS[method]
    except (KeyError, TypeError):
        raise ControlArgumentError(f"Unknown method {method!r}: python-control's methods are None, 'slycot' "
                                   f"and 'scipy'") from None


def _no_keywords(kwargs: dict[str, Any]) -> None:
    if kwargs:
        raise ArgumentTypeError(f"unrecognized keyword(s): {sorted(kwargs)}")


def _split_args(args: tuple, fname: str, nsys: int) -> tuple[NDArray, NDArray, NDArray | None, list, Any]:
    """(A, B-or-G, C or None, the remaining arguments, the system or None) of python-control's
    ``f(sys, ...)`` / ``f(A, B[, C], ...)`` forms; ``nsys`` is the number of matrices the system
    replaces (2 for lqr: A, B; 3 for lqe: A, G, C)."""
    if len(args) < 3:
        names = "A, G, C" if nsys == 3 else "A, B"
        raise ControlArgumentError(f"{fname}: not enough input arguments (found {len(args)}; the forms are "
                                   f"{fname}(sys, Q, R) and {fname}({names}, Q, R))")
    first = args[0]
    if _is_statespace(first):
        C = np.array(first.C, ndmin=2, dtype=float) if nsys == 3 else None
        return (np.array(first.A, ndmin=2, dtype=float), np.array(first.B, ndmin=2, dtype=float), C,
                list(args[1:]), first)
    if _is_control(first) or (type(first).__module__ or "").startswith("scipy.signal"):
        raise ControlArgumentError(f"{fname}: LTI system must be in state space form; found "
                                   f"{type(first).__name__}: convert it with control.ss(sys)")
    if len(args) < nsys + 2:
        raise ControlArgumentError(f"{fname}: not enough input arguments (found {len(args)})")
    mats = [_matrix(name, X) for name, X in zip(("A", "G" if nsys == 3 else "B", "C"), args[:nsys])]
    return mats[0], mats[1], (mats[2] if nsys == 3 else None), list(args[nsys:]), None


def _kalman(plant: Plant, method: str, N: NDArray | None, what: str) -> Any:
    """optdesign.kalman, refusing an answer that failed its independent checks."""
    from ..design.kalman import kalman

    kf = kalman(plant, method=method, N=N)
    if not kf.success:
        raise RiccatiError(f"{what}: the Riccati solution failed its independent checks: "
                           f"{', '.join(c.name for c in kf.verification.failed)} ({kf.message})")
    return kf


# ------------------------------------------------------------------ estimators
def _lqe(args: tuple, method: Any, discrete: bool, fname: str) -> tuple[NDArray, NDArray, NDArray]:
    A, G, C, rest, _ = _split_args(args, fname, 3)
    if len(rest) < 2:
        raise ControlArgumentError(f"{fname}: not enough input arguments (QN and RN are needed)")
    if len(rest) > 3:
        raise ControlArgumentError(f"{fname}: too many arguments ({len(args)})")
    n = A.shape[0]
    C = cast(NDArray, C)
    _check_shape("A", A, n, n, square=True)
    _check_shape("G", G, n, G.shape[1])
    _check_shape("C", C, C.shape[0], n)
    QN = _check_shape("QN", _matrix("QN", rest[0]), G.shape[1], G.shape[1], square=True)
    RN = _check_shape("RN", _matrix("RN", rest[1]), C.shape[0], C.shape[0], square=True)
    NN = None
    if len(rest) == 3:
        NN = _check_shape("NN", _matrix("NN", rest[2]), G.shape[1], C.shape[0])
    plant = Plant(A, C, G=G, Q=QN, R=RN, dt=1.0 if discrete else None)
    kf = _kalman(plant, _method(method), NN, fname)
    return np.array(kf.L), np.array(kf.P), np.array(kf.poles)


def lqe(*args: Any, method: Any = None, **kwargs: Any) -> tuple[NDArray, NDArray, NDArray]:
    """python-control's ``lqe``: ``L, P, E = lqe(A, G, C, QN, RN[, NN])`` or ``lqe(sys, QN, RN[, NN])``.

    Continuous Kalman gain ``L = (P C' + G NN) RN^-1`` of ``A P + P A' - (P C' + G NN) RN^-1 (C P +
    NN' G') + G QN G' = 0``; ``E = eig(A - L C)``.  With a system the noise enters through
    ``sys.B`` (``G = sys.B``); a discrete system (``dt`` True or > 0) is passed to :func:`dlqe`, as
    python-control does; ``dt=None`` means continuous here.

    Parameters
    ----------
    A : (n, n) array_like
    G : (n, m) array_like
    C : (p, n) array_like
    QN : (m, m) array_like
        Symmetric PSD.
    RN : (p, p) array_like
        Symmetric PD.
    NN : (m, p) array_like, optional
        Cross-covariance; supported (python-control raises ``ControlNotImplemented``).
    method : {None, "scipy", "slycot"}
        See the module notes.

    Returns
    -------
    L : (n, p) ndarray
    P : (n, n) ndarray
    E : (n,) ndarray of complex

    Raises
    ------
    ControlArgumentError
        Too few arguments, a transfer function, an unknown method or keyword.
    ControlDimensionError
        Incompatible sizes (python-control's messages).
    NotObservableError, RiccatiError, NotPositiveSemidefiniteError, NotPositiveDefiniteError
        From :func:`optdesign.kalman`; a RiccatiError also when the answer fails its checks.

    Examples
    --------
    >>> from optdesign.compat.control import lqe
    >>> L, P, E = lqe([[0., 1.], [0., 0.]], [[0.], [1.]], [[1., 0.]], [[4.]], [[0.25]])
    >>> L.round(6).ravel().tolist(), sorted(E.real.round(6).tolist())   # as control.lqe
    ([2.828427, 4.0], [-1.414214, -1.414214])
    """
    _no_keywords(kwargs)
    if args and _is_statespace(args[0]) and _strict_discrete(args[0]):
        return dlqe(*args, method=method)
    return _lqe(args, method, False, "lqe")


def dlqe(*args: Any, method: Any = None, **kwargs: Any) -> tuple[NDArray, NDArray, NDArray]:
    """python-control's ``dlqe``: ``L, P, E = dlqe(A, G, C, QN, RN[, NN])`` or ``dlqe(sys, QN, RN[, NN])``.

    Discrete (predictor) Kalman gain ``L = (A P C' + G NN)(C P C' + RN)^-1``; ``E = eig(A - L C)``.
    A system with ``dt == 0`` is refused (``dt=None`` or ``True``: discrete).  Parameters, returns
    and errors as :func:`lqe`.

    Examples
    --------
    >>> from optdesign.compat.control import dlqe
    >>> L, P, E = dlqe([[1.0]], [[1.0]], [[1.0]], [[0.1]], [[1.0]])     # a random walk
    >>> round(float(L[0, 0]), 4), round(float(abs(E[0])), 4)           # current-estimator gain, pole
    (0.2702, 0.7298)
    """
    _no_keywords(kwargs)
    if args and _is_statespace(args[0]) and _strict_continuous(args[0]):
        raise ControlArgumentError("dlqe() called with a continuous-time system (dt = 0): use lqe(), or give "
                                   "the system a sampling period")
    return _lqe(args, method, True, "dlqe")


# ------------------------------------------------------------------ regulators
def _lqr(args: tuple, method: Any, integral_action: Any, discrete: bool, fname: str
         ) -> tuple[NDArray, NDArray, NDArray]:
    A, B, _, rest, _ = _split_args(args, fname, 2)
    if len(rest) < 2:
        raise ControlArgumentError(f"{fname}: not enough input arguments (Q and R are needed)")
    if len(rest) > 3:
        raise ControlArgumentError(f"{fname}: too many arguments ({len(args)})")
    n = A.shape[0]
    _check_shape("A", A, n, n, square=True)
    _check_shape("B", B, n, B.shape[1])
    if integral_action is not None:
        if not isinstance(integral_action, np.ndarray):
            raise ControlArgumentError(f"Integral action must pass an array; found "
                                       f"{type(integral_action).__name__}")
        Ci = np.atleast_2d(np.asarray(integral_action, dtype=float))
        if Ci.shape[1] != n:
            raise ControlArgumentError(f"Integral gain size must match system state size: integral_action "
                                       f"has {Ci.shape[1]} columns, the system {n} states")
        ni = Ci.shape[0]
        A = np.block([[A, np.zeros((n, ni))], [Ci, np.eye(ni) if discrete else np.zeros((ni, ni))]])
        B = np.vstack([B, np.zeros((ni, B.shape[1]))])
        n += ni
    m = B.shape[1]
    Q = _check_shape("Q", _matrix("Q", rest[0]), n, n, square=True)
    R = _check_shape("R", _matrix("R", rest[1]), m, m, square=True)
    N = _check_shape("N", _matrix("N", rest[2]), n, m) if len(rest) == 3 else None
    # LQR's Riccati equation is the filter equation of the dual pair (A', B'): G = I, Q, R, N
    dual = Plant(A.T, B.T, Q=Q, R=R, dt=1.0 if discrete else None)
    try:
        kf = _kalman(dual, _method(method), None if N is None or not np.any(N) else N, fname)
    except NotObservableError as exc:
        modes = getattr(exc, "modes", np.zeros(0))
        shown = ", ".join(f"{complex(z):.6g}".strip("()") for z in modes)
        raise NotControllableError(f"{fname}: (A, B) is not stabilizable: uncontrollable unstable mode(s) "
                                   f"{shown}", modes=modes) from exc
    return np.array(kf.L.T), np.array(kf.P), np.array(kf.poles)


def lqr(*args: Any, method: Any = None, integral_action: Any = None, **kwargs: Any
        ) -> tuple[NDArray, NDArray, NDArray]:
    """python-control's ``lqr``: ``K, S, E = lqr(A, B, Q, R[, N])`` or ``lqr(sys, Q, R[, N])``.

    ``u = -K x`` minimizing ``int x' Q x + u' R u + 2 x' N u``: ``K = R^-1 (B' S + N')`` with S the
    stabilizing solution of ``A' S + S A - (S B + N) R^-1 (B' S + N') + Q = 0``; ``E = eig(A - B
    K)``.  Solved as :func:`optdesign.kalman` of the dual pair ``(A', B')`` (the same equation),
    with its independent checks.  A discrete system goes to :func:`dlqr`.

    Parameters
    ----------
    A : (n, n) array_like
    B : (n, m) array_like
    Q : (n, n) array_like
        (n + k) square with ``integral_action``.
    R : (m, m) array_like
    N : (n, m) array_like, optional
    method : {None, "scipy", "slycot"}
    integral_action : (k, n) ndarray, optional
        python-control's integral action: the system is augmented with ``z' = integral_action x``.

    Returns
    -------
    K : (m, n) ndarray
    S : (n, n) ndarray
    E : (n,) ndarray of complex

    Raises
    ------
    ControlArgumentError, ControlDimensionError
        As python-control (bad ``integral_action``, sizes, too few arguments, a transfer function).
    NotControllableError
        (A, B) not stabilizable (the modes are named).
    RiccatiError, NotPositiveSemidefiniteError, NotPositiveDefiniteError
        From the Riccati solve.

    Examples
    --------
    >>> from optdesign.compat.control import lqr
    >>> K, S, E = lqr([[0., 1.], [0., 0.]], [[0.], [1.]], [[1., 0.], [0., 0.]], [[1.]])
    >>> K.round(6).tolist()                                 # [1, sqrt 2]
    [[1.0, 1.414214]]
    """
    _no_keywords(kwargs)
    if args and _is_statespace(args[0]) and _strict_discrete(args[0]):
        return dlqr(*args, method=method, integral_action=integral_action)
    return _lqr(args, method, integral_action, False, "lqr")


def dlqr(*args: Any, method: Any = None, integral_action: Any = None, **kwargs: Any
         ) -> tuple[NDArray, NDArray, NDArray]:
    """python-control's ``dlqr``: ``K, S, E = dlqr(A, B, Q, R[, N])`` or ``dlqr(dsys, Q, R[, N])``.

    ``K = (R + B' S B)^-1 (B' S A + N')``; a system with ``dt == 0`` is refused.  As :func:`lqr`.

    Examples
    --------
    >>> from optdesign.compat.control import dlqr
    >>> K, S, E = dlqr([[1.0]], [[1.0]], [[1.0]], [[1.0]])   # x+ = x + u, cost sum x^2 + u^2
    >>> round(float(K[0, 0]), 6), round(float(S[0, 0]), 6)   # S = golden ratio
    (0.618034, 1.618034)
    """
    _no_keywords(kwargs)
    if args and _is_statespace(args[0]) and _strict_continuous(args[0]):
        raise ControlArgumentError("dlqr: dsys must be discrete time (dt != 0); found a continuous-time "
                                   "system")
    return _lqr(args, method, integral_action, True, "dlqr")


# ------------------------------------------------------------------ place
def _pole_tolerance(M: NDArray, poles: NDArray) -> float:
    """How far a computed eigenvalue of ``M`` may be from its target by rounding alone: the
    Bauer-Fike bound ``kappa(X) * 10 n eps ||M||`` for distinct poles; for a pole of multiplicity k
    the Jordan-block bound ``||M|| (10 n eps)^(1/k)``."""
    n = M.shape[0]
    scale = max(float(np.linalg.norm(M, 2)), float(np.max(np.abs(poles))), 1.0)
    _, mult = np.unique(np.round(poles, 12), return_counts=True)
    k = int(np.max(mult))
    if k > 1:
        return 10.0 * scale * (10.0 * n * _EPS) ** (1.0 / k)
    X = np.linalg.eig(M)[1]
    kappa = float(np.linalg.cond(X / np.linalg.norm(X, axis=0)))
    return max(kappa, 1.0) * 10.0 * n * _EPS * scale


def place(A: Any, B: Any, p: Any) -> NDArray[np.float64]:
    """python-control's ``place``: ``K = place(A, B, p)``, ``eig(A - B K) = p``.

    Answered by :func:`optdesign.place` (the gain of minimum eigenvector condition number; scipy's
    YT, which python-control calls, is among its starts).  The closed-loop eigenvalues are checked
    against ``p`` (to the rounding bound of their condition) before K is returned.

    Parameters
    ----------
    A : (n, n) array_like
    B : (n, m) array_like
    p : (n,) array_like
        Desired eigenvalues (conjugate-closed).

    Returns
    -------
    K : (m, n) ndarray

    Raises
    ------
    ControlDimensionError
        A not square, B without n rows.
    ValueError
        (Ours: ValidationError / InfeasibleError subclasses.)  A pole repeated more than rank(B)
        times where the poles do not fix the gain, poles not conjugate-closed, (A, B) not
        controllable, or no placement found.

    Examples
    --------
    >>> import numpy as np
    >>> from optdesign.compat.control import place
    >>> K = place([[0., 1.], [0., 0.]], [[0.], [1.]], [-1., -2.])     # python-control's call
    >>> K.round(9).tolist(), np.sort(np.linalg.eigvals([[0., 1.], [-2., -3.]])).tolist()
    ([[2.0, 3.0]], [-2.0, -1.0])
    """
    A_ = _matrix("A", A)
    B_ = _matrix("B", B)
    n = A_.shape[0]
    _check_shape("A", A_, n, n, square=True)
    _check_shape("B", B_, n, B_.shape[1])
    poles = np.atleast_1d(np.squeeze(np.asarray(p)))
    from ..design.feedback import place as native_place

    res = native_place(A_, B_, poles)
    K = res.gain_matrix
    if K is None or not np.all(np.isfinite(K)) or not res.success:
        raise InfeasibleError(f"place: no verified placement of the poles {poles.tolist()} "
                              f"(status {getattr(res.status, 'value', res.status)}): {res.message}")
    K = np.asarray(K, dtype=float)
    M = A_ - B_ @ K
    got = np.linalg.eigvals(M)
    target = np.asarray(poles, dtype=complex)
    err = max(float(np.min(np.abs(got - z))) for z in target)
    err = max(err, max(float(np.min(np.abs(target - z))) for z in got))
    tol = _pole_tolerance(M, target)
    if not err <= tol:
        raise InfeasibleError(f"place: the closed-loop eigenvalues are {err:.3g} from the requested poles "
                              f"(rounding bound {tol:.3g}); no verified placement")
    return K


# ------------------------------------------------------------------ the estimator I/O system
def _indices(value: Any, labels: list[str], what: str, *, from_end: bool) -> list[int]:
    """python-control's index forms: an int k (the first k inputs; ``from_end``: the last k), a
    slice, or a list of int offsets / signal names."""
    nin = len(labels)
    if isinstance(value, (int, np.integer)) and not isinstance(value, bool):
        k = int(value)
        if not 0 <= k <= nin:
            raise ControlArgumentError(f"{what}_indices = {k} is out of range: the system has {nin} inputs")
        return list(range(nin - k, nin)) if from_end else list(range(k))
    if isinstance(value, slice):
        return list(range(nin))[value]
    if isinstance(value, str):
        value = [value]
    out: list[int] = []
    for j, v in enumerate(value):
        if isinstance(v, str):
            if v not in labels:
                raise ControlArgumentError(f"{what}_indices[{j}] = {v!r} is not an input of the system "
                                           f"(inputs: {labels})")
            out.append(labels.index(v))
        elif isinstance(v, (int, np.integer)) and not isinstance(v, bool) and -nin <= int(v) < nin:
            out.append(int(v) % nin)
        else:
            raise ControlArgumentError(f"{what}_indices[{j}] must be an input index (0..{nin - 1}) or name; "
                                       f"found {v!r}")
    return out


def _labels(labels: Any, what: str, default: list[str]) -> list[str]:
    if labels is None:
        return list(default)
    if isinstance(labels, str):
        return [labels.format(i=i) for i in range(len(default))]
    labels = list(labels)
    if len(labels) != len(default):
        raise ControlDimensionError(f"incorrect length of {what}_labels: {len(labels)} instead of "
                                    f"{len(default)}")
    return labels


def create_estimator_iosystem(sys: Any, QN: Any, RN: Any, P0: Any = None, G: Any = None, C: Any = None,
                              control_indices: Any = None, disturbance_indices: Any = None,
                              estimate_labels: Any = "xhat[{i}]", covariance_labels: Any = "P[{i},{j}]",
                              measurement_labels: Any = None, control_labels: Any = None,
                              inputs: Any = None, outputs: Any = None, states: Any = None,
                              **kwargs: Any) -> Any:
    r"""python-control's ``create_estimator_iosystem``: the time-varying Kalman filter as an I/O
    system, inputs ``[y; u]``, outputs ``xhat``, states ``[xhat; P]``.

    Continuous::

        xhat' = A xhat + B u - L (C xhat - y),   L = P C' RN^-1,
        P' = A P + P A' + G QN G' - P C' RN^-1 C P

    discrete::

        xhat[k+1] = A xhat + B u - L (C xhat - y),   L = A P C' (RN + C P C')^-1,
        P[k+1] = A P A' + G QN G' - A P C' (RN + C P C')^-1 C P A'

    (the parameter ``correct=False`` drops the correction terms, as python-control).  The same
    arguments, defaults and signal names as python-control; ``P0`` is validated, and without it
    the steady-state P is computed by :func:`optdesign.kalman` (verified) as python-control does
    with its ``lqe`` -- a check that the filter exists; as in python-control the initial state of a
    simulation, ``[xhat0, P0]``, is the caller's.  ``D`` of the
    control inputs is supported (``y - C xhat - D u``); a nonzero D of the disturbances is not.
    For the *steady-state* estimator as a linear system in this layout use
    ``optdesign.kalman(sys, ...).estimator(io="control")``.

    Parameters
    ----------
    sys : control.StateSpace
    QN : (k, k) array_like
        Covariance of the disturbances (the inputs ``disturbance_indices``; default: all inputs,
        added to the controls -- ``G = sys.B``).
    RN : (p, p) array_like
    P0 : (n, n) array_like, optional
    G : (n, k) array_like, optional
    C : (p, n) array_like, optional
        Only for a system with full-state output: the measured combination.
    control_indices, disturbance_indices, estimate_labels, covariance_labels, measurement_labels,
    control_labels, inputs, outputs, states, **kwargs
        As python-control (``kwargs``: ``name``, ``params`` ... of ``NonlinearIOSystem``).

    Returns
    -------
    control.NonlinearIOSystem

    Raises
    ------
    ControlArgumentError
        ``sys`` not a python-control StateSpace (a transfer function: convert with ``control.ss``),
        bad indices.
    ControlDimensionError
        QN, RN, G, P0 of the wrong size.
    ValidationError
        ``C`` given for a system without full-state output, or of the wrong size (python-control's
        messages: "System output must be full state", "System output is the wrong size for C").
    ControlNotImplementedError
        A nonzero feedthrough of the disturbances.

    Examples
    --------
    >>> import control
    >>> from optdesign.compat.control import create_estimator_iosystem
    >>> sys = control.ss([[1., 0.1], [0., 1.]], [[0.005], [0.1]], [[1., 0.]], 0, dt=0.1)
    >>> est = create_estimator_iosystem(sys, [[1.0]], [[0.01]])   # QN through B, RN on y
    >>> est.input_labels, est.output_labels
    (['y[0]', 'u[0]'], ['xhat[0]', 'xhat[1]'])
    """
    if not _is_statespace(sys):
        raise ControlArgumentError(f"Input system must be a linear I/O system (a control.StateSpace); found "
                                   f"{type(sys).__name__}: convert a transfer function with control.ss(sys)")
    import control

    from ..errors import ValidationError

    n, nin = sys.nstates, sys.ninputs
    in_labels = list(sys.input_labels)
    if control_indices is None and disturbance_indices is None:
        ctrl = dist = list(range(nin))
    elif control_indices is not None:
        ctrl = _indices(control_indices, in_labels, "control", from_end=False)
        dist = [i for i in range(nin) if i not in ctrl]
    else:
        dist = _indices(disturbance_indices, in_labels, "disturbance", from_end=True)
        ctrl = [i for i in range(nin) if i not in dist]
    A = np.array(sys.A, dtype=float)
    Bu = np.array(sys.B, dtype=float)[:, ctrl]
    Dsys = np.array(sys.D, dtype=float).reshape(sys.noutputs, nin)
    if np.any(Dsys[:, [j for j in dist if j not in ctrl]]):
        raise ControlNotImplementedError("a nonzero feedthrough D of the disturbance inputs is not "
                                         "implemented (its noise would correlate with the measurement)")
    RN_ = _matrix("RN", RN)
    if C is not None:
        if sys.noutputs != n or not np.allclose(sys.C, np.eye(n)):
            raise ValidationError("System output must be full state to give C (the measured combination)")
        C_ = _matrix("C", C)
        if C_.shape[0] != RN_.shape[0]:
            raise ValidationError(f"System output is the wrong size for C: C has {C_.shape[0]} rows, RN is "
                                  f"{RN_.shape[0]} x {RN_.shape[1]}")
        _check_shape("C", C_, C_.shape[0], n)
        Du = np.zeros((C_.shape[0], len(ctrl)))
    else:
        C_ = np.array(sys.C, dtype=float)
        Du = Dsys[:, ctrl]
    p = C_.shape[0]
    G_ = np.array(sys.B, dtype=float)[:, dist] if G is None else _matrix("G", G)
    G_ = _check_shape("G", G_, n, len(dist))
    QN_ = _check_shape("QN", _matrix("QN", QN), G_.shape[1], G_.shape[1], square=True)
    RN_ = _check_shape("RN", RN_, p, p, square=True)
    discrete = _strict_discrete(sys)
    if P0 is None:
        plant = Plant(A, C_, G=G_, Q=QN_, R=RN_, dt=1.0 if discrete else None)
        P0_ = np.array(_kalman(plant, "scipy", None, "create_estimator_iosystem").P)
    else:
        P0_ = _check_shape("P0", _matrix("P0", P0), n, n, square=True)
    W = G_ @ QN_ @ G_.T
    Rinv = np.linalg.inv(RN_)
    CRC = C_.T @ Rinv @ C_

    def update(t: float, x: NDArray, u: NDArray, params: dict) -> NDArray:
        correct = params.get("correct", True)
        xhat, P = x[:n], x[n:].reshape(n, n)
        y, uc = u[:p], u[p:]
        innov = C_ @ xhat + Du @ uc - y
        if discrete:
            S = RN_ + C_ @ P @ C_.T
            AK = A @ P @ C_.T @ np.linalg.inv(S)
            dx = A @ xhat + Bu @ uc - (AK @ innov if correct else 0.0)
            dP = A @ P @ A.T + W - (AK @ C_ @ P @ A.T if correct else 0.0)
        else:
            L = P @ C_.T @ Rinv
            dx = A @ xhat + Bu @ uc - (L @ innov if correct else 0.0)
            dP = A @ P + P @ A.T + W - (P @ CRC @ P if correct else 0.0)
        return np.concatenate([dx, np.asarray(dP).reshape(-1)])

    def output(t: float, x: NDArray, u: NDArray, params: dict) -> NDArray:
        return x[:n]

    est_labels = _labels(estimate_labels, "estimate", [f"xhat[{i}]" for i in range(n)])
    meas = _labels(measurement_labels, "measurement", [f"y[{i}]" for i in range(p)])
    ctl = _labels(control_labels, "control", [in_labels[i] for i in ctrl])
    if isinstance(covariance_labels, str):
        cov = [covariance_labels.format(i=i, j=j) for i in range(n) for j in range(n)]
    else:
        cov = _labels(covariance_labels, "covariance", [f"P[{i},{j}]" for i in range(n) for j in range(n)])
    est = control.NonlinearIOSystem(
        update, output, dt=sys.dt, states=est_labels + cov if states is None else states,
        inputs=meas + ctl if inputs is None else inputs,
        outputs=est_labels if outputs is None else outputs, **kwargs)
    del P0_   # validated (and, by default, the steady state computed) as python-control does; the
    # initial covariance is the caller's initial state [xhat0, P0] of the simulation
    return est
