"""The result of the well-conditioned verbs: :class:`ObserverDesign` and its per-start history."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ...errors import ValidationError
from ...model.plant import Plant
from ...model.regions import Region
from ...results import Certificate, Check, DesignResult, SolverStats, Status, Verification
from ..estimator import estimator_of

__all__ = ["StartRecord", "ObserverDesign", "n_converged", "no_design"]


@dataclass(frozen=True)
class StartRecord:
    """What one multi-start run gave.

    Attributes
    ----------
    index : int
    origin : str
        Where the initial gain came from (``"YT"``, ``"KNV0"``, ``"random"``, ``"naive poles +
        YT"``, ``"region sample + YT"``, ``"riccati q=..."``, ``"warm start"``).
    status : Status
        The status of the run (its last stage).
    verified : bool
        The run's design passed every independent check.
    kappa2, eta, gain_norm : float
        Recomputed with numpy (nan if the run produced no finite gain).
    objective : float
        The objective metric recomputed with numpy (what ranks the starts).
    iterations : int
    time : float
        Seconds in the solver.
    message : str
    """

    index: int
    origin: str
    status: Status
    verified: bool
    kappa2: float
    eta: float
    gain_norm: float
    objective: float
    iterations: int
    time: float
    message: str = ""


def n_converged(records: tuple[StartRecord, ...] | list[StartRecord]) -> int:
    """Number of starts whose design was solved and verified."""
    return sum(1 for r in records if r.verified and Status(r.status).is_solved)


@dataclass(frozen=True, kw_only=True, eq=False)
class ObserverDesign(DesignResult):
    """A well-conditioned observer (or Kalman filter) design.

    Attributes
    ----------
    L : (n, p) ndarray
        Observer gain; error dynamics ``A - L C``.
    poles : (n,) ndarray of complex
        ``eig(A - L C)`` recomputed with numpy, sorted by real then imaginary part.
    kappa2 : float
        2-norm condition number of the unit-column eigenvector matrix (``metrics.kappa2``; for a
        repeated pole, where the eigenbasis is not unique and ``metrics.kappa2`` is inf, the
        condition number of the basis found by the solver, verified as an eigenbasis).
    eta : float
        Huh & Stein's non-normality measure (``metrics.eta``; inf for repeated poles).
    kappa_fro : float
        Frobenius condition number of the same eigenbasis.
    gain_norm : float
        ``||L||_2``.
    objective : str
        ``"kappa2"``, ``"kappa_fro"`` or ``"eta"``.
    starts : tuple of StartRecord
        The per-start history.
    V : (n, n) ndarray of complex or None
        The unit-column eigenvector matrix behind ``kappa2``.
    region : Region or None
        Region mode: the pole region.
    Q, P, R : ndarray or None
        Kalman designs: the noise covariances found and the Riccati solution.
    plant : Plant or None
        The plant designed for (:meth:`estimator` builds the observer from it).
    status, message, solver_stats, verification, certificate, target_poles, extra
        The common result fields (:class:`~optdesign.results.DesignResult`).  ``solver_stats``: totals
        over all starts (``backend`` is ``"eigenstructure"`` for the placement engine, ``"ipopt"``
        for the NLP); ``extra`` has ``starts``, ``planned_starts``, ``converged``, ``best_start``,
        ``route``.  ``verification``: ``stability``, ``pole_error`` or ``region_margin``,
        ``eig_residual``, ``kappa2_agreement``, ``mask``, ``gain_bound``, ``kappa2_bound``,
        ``eta_bound`` (when relevant), and for Kalman designs ``riccati_residual``, ``P_min_eig``,
        ``Q_min_eig``, ``gain_vs_riccati`` (:mod:`optdesign.design.verification`).
        ``certificate``: the proof of an ``infeasible`` verdict (a pole repeated more than
        ``rank(C)`` times, eta at a repeated pole, an unobservable mode outside the region).
    """

    L: NDArray[np.float64]
    poles: NDArray[np.complex128]
    kappa2: float
    eta: float
    kappa_fro: float
    gain_norm: float
    objective: str
    starts: tuple[StartRecord, ...] = ()
    V: NDArray[np.complex128] | None = None
    region: Region | None = None
    Q: NDArray[np.float64] | None = None
    P: NDArray[np.float64] | None = None
    R: NDArray[np.float64] | None = None
    plant: Plant | None = field(default=None, repr=False)

    _summary_fields: tuple[str, ...] = field(default=("kappa2", "eta", "gain_norm", "poles", "L"), init=False,
                                             repr=False)

    @property
    def n_converged(self) -> int:
        """Number of starts whose design was solved and verified."""
        return n_converged(self.starts)

    def record(self) -> dict[str, Any]:
        """Scalar summary for sweeps and tables (the keys sweeps rely on; not the common record)."""
        return {
            "status": Status(self.status).value,
            "success": self.success,
            "objective": self.objective,
            "kappa2": self.kappa2,
            "eta": self.eta,
            "kappa_fro": self.kappa_fro,
            "gain_norm": self.gain_norm,
            "max_real_pole": float(np.max(self.poles.real)) if self.poles.size else float("nan"),
            "starts": len(self.starts),
            "converged": self.n_converged,
            "time": self.solver_stats.time,
            "iterations": self.solver_stats.iterations,
            "route": None if self.route.answered is None else self.route.answered.name,
        }

    def estimator(self, *, form: str | None = None, output: str = "auto") -> Any:
        """The observer as a system: inputs ``[u; y]``, outputs ``[y_hat; x_hat]``
        (:func:`optdesign.estimator_system`: a python-control ``StateSpace`` when python-control is
        installed, plain arrays otherwise).

        Raises
        ------
        ValidationError
            No gain (the design failed) or no plant.
        """
        if not np.all(np.isfinite(self.L)):
            raise ValidationError(f"the design has no finite gain L (status {Status(self.status).value}): "
                                  "there is no estimator to build")
        return estimator_of(self, self.plant, form=form, output=output)

    def __repr__(self) -> str:
        return (
            f"ObserverDesign(status={Status(self.status).value}, success={self.success}, "
            f"kappa2={self.kappa2:.6g}, eta={self.eta:.6g}, ||L||={self.gain_norm:.4g}, "
            f"converged={self.n_converged}/{len(self.starts)})"
        )


def no_design(plant: Plant, objective: str, status: Status, reason: str, certificate: Certificate | None,
              *, target: NDArray | None = None, region: Region | None = None, backend: str = "none",
              **fields: Any) -> ObserverDesign:
    """A result without a gain (NaN): ``infeasible`` with a proof, or ``time_limit`` before any start."""
    n, p = plant.n, plant.p
    name = "feasible" if Status(status).is_infeasible else "finite_gain"
    return ObserverDesign(
        L=np.full((n, p), np.nan),
        poles=np.full(n, np.nan + 0j),
        kappa2=float("inf"),
        eta=float("inf"),
        kappa_fro=float("inf"),
        gain_norm=float("nan"),
        objective=objective,
        status=status,
        message=reason,
        solver_stats=SolverStats(backend="analytic" if Status(status).is_infeasible else backend,
                                 native_status=Status(status).value),
        verification=Verification.of([Check.at_most(name, float("inf"), 0.0, reason)]),
        starts=(),
        target_poles=target,
        region=region,
        certificate=certificate,
        plant=plant,
        **fields,
    )
