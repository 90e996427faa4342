"""The results a study tabulates per point (:class:`DesignPoint`: a verb's result and its scalar
metrics) and the robust pole-placement baseline of seed 001-style studies (:func:`place_baseline`)."""

from __future__ import annotations

import math
import time
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._validate import as_poles
from ..errors import ValidationError
from ..model.plant import Plant
from ..results import Check, DesignResult, Route, SolverStats, Stage, Status, Verification

__all__ = ["DesignPoint", "BaselinePlacement", "place_baseline", "gain_values"]


# --------------------------------------------------------------------------- generic point result


@dataclass(frozen=True, kw_only=True, eq=False)
class DesignPoint(DesignResult):
    """A design result with the scalar metrics a study tabulates.

    Attributes
    ----------
    result : object
        The verb's own result (``KalmanFilter``, ``InverseKalmanResult``, :class:`BaselinePlacement`, ...).
    values : dict
        Scalar metrics (``kappa2``, ``eta``, ``gain_norm``, ``max_real_pole``, ...).
    status, message, verification
        Those of ``result``.
    """

    result: Any
    values: dict[str, Any]

    def record(self) -> dict[str, Any]:
        return {"status": Status(self.status).value, "success": self.success, **self.values}


def gain_values(plant: Plant, L: NDArray | None) -> dict[str, float]:
    """The scalar metrics of a gain that a study tabulates.

    Parameters
    ----------
    plant : Plant
    L : (n, p) ndarray or None
        Observer gain (error dynamics ``A - L C``).

    Returns
    -------
    dict
        ``kappa2``, ``eta``, ``gain_norm`` (``||L||_2``), ``max_real_pole`` and ``max_abs_pole`` of
        ``A - L C`` (NaN, without ``max_abs_pole``, for a missing or non-finite gain).
    """
    nan = float("nan")
    if L is None or not np.all(np.isfinite(L)):
        return {"kappa2": nan, "eta": nan, "gain_norm": nan, "max_real_pole": nan}
    from ..analysis import metrics

    X = plant.A - L @ plant.C
    m = metrics.condition_summary(X)
    ev = np.linalg.eigvals(X)
    return {"kappa2": float(m["kappa2"]), "eta": float(m["eta"]), "gain_norm": float(np.linalg.norm(L, 2)),
            "max_real_pole": float(np.max(ev.real)), "max_abs_pole": float(np.max(np.abs(ev)))}


# --------------------------------------------------------------------------- placement baseline


@dataclass(frozen=True, kw_only=True, eq=False)
class BaselinePlacement(DesignResult):
    """Observer gain by robust pole placement (scipy ``place_poles`` on the dual), verified: the baseline
    of seed 001-style studies (before 0.2.0 named ``PlacementResult``, a second type of that name beside
    :class:`optdesign.design.feedback.PlacementResult`).

    Attributes
    ----------
    L : (n, p) ndarray
    poles : (n,) ndarray of complex
        ``eig(A - L C)`` recomputed with numpy, sorted.
    target : (n,) ndarray of complex
    kappa2, eta, kappa_fro, gain_norm : float
        Of ``A - L C`` (``optdesign.metrics``).
    method : str
        ``"YT"`` or ``"KNV0"``.
    status : Status
        ``SOLVED``, or ``SOLVER_ERROR`` when placement raised (``message`` says why).
    message : str
    solver_stats : SolverStats
    verification : Verification
        ``pole_error`` (relative, <= 1e-6).
    """

    L: NDArray[np.float64] | None
    poles: NDArray[np.complex128] | None
    target: NDArray[np.complex128]
    kappa2: float
    eta: float
    kappa_fro: float
    gain_norm: float
    method: str

    def record(self) -> dict[str, Any]:
        return {"status": Status(self.status).value, "success": self.success, "kappa2": self.kappa2,
                "eta": self.eta, "kappa_fro": self.kappa_fro, "gain_norm": self.gain_norm,
                "pole_error": self.verification["pole_error"].value if "pole_error" in self.verification
                else float("nan"),
                "max_real_pole": float(np.max(self.poles.real)) if self.poles is not None else float("nan")}


def place_baseline(plant: Plant, poles: ArrayLike, *, method: str = "YT") -> BaselinePlacement:
    """Robust pole placement (the baseline of seed 001-style designs), as a verified result.

    Parameters
    ----------
    plant : Plant
    poles : (n,) array_like of complex
        Conjugate-closed target poles.
    method : {"YT", "KNV0"}

    Returns
    -------
    BaselinePlacement
        A placement that scipy cannot perform (e.g. a pole repeated more than ``rank(C)``
        times) gives ``status`` solver_error with the reason in ``message``.

    Raises
    ------
    ValidationError
        Bad method; ``plant`` not a Plant.
    DimensionError, NotConjugateClosedError
        Bad pole set.
    NotObservableError
        ``(C, A)`` not observable.
    """
    if not isinstance(plant, Plant):
        raise ValidationError(f"plant must be an optdesign.Plant; found {type(plant).__name__}")
    if not isinstance(method, str) or method not in ("YT", "KNV0"):
        raise ValidationError(f"method must be 'YT' or 'KNV0'; found {method!r}")
    from ..classical.placement import place_observer
    from ..design.well_conditioned import POLE_TOL, Candidate, evaluate_candidate

    target = as_poles("poles", poles, plant.n)
    plant.require_observable(what="pole placement")
    t0 = time.perf_counter()
    nan = float("nan")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            L = place_observer(plant, target, method=method)
    except ValidationError as exc:
        stats = SolverStats(backend="scipy", native_status="error", time=time.perf_counter() - t0)
        return BaselinePlacement(
            L=None, poles=None, target=target, kappa2=nan, eta=nan, kappa_fro=nan, gain_norm=nan, method=method,
            status=Status.SOLVER_ERROR, message=str(exc), solver_stats=stats,
            verification=Verification.of([Check.at_most("pole_error", math.inf, POLE_TOL, str(exc))]),
            route=Route([Stage(f"scipy_place_poles/{method}", "backend", "failed", str(exc))]))
    stats = SolverStats(backend="scipy", native_status="placed", time=time.perf_counter() - t0)
    # the verb's checks of a fixed-pole design (pole error, numpy); no stability requirement: a
    # placement baseline may be asked for any pole set
    cand = Candidate(L, None, None, Status.SOLVED, "placed", "", 0, stats.time)
    m, v = evaluate_candidate(plant, cand, target=target, region=None, mask=None, max_gain=None,
                              kappa2_max=None, eta_max=None, stable=False)
    return BaselinePlacement(
        L=L, poles=m["poles"], target=target, kappa2=m["kappa2"], eta=m["eta"], kappa_fro=m["kappa_fro"],
        gain_norm=m["gain_norm"], method=method, status=Status.SOLVED,
        message=f"scipy.signal.place_poles ({method}) on the dual pair", solver_stats=stats, verification=v,
        route=Route([Stage(f"scipy_place_poles/{method}", "backend")]))
