r"""Well-conditioned observers and Kalman filters (seed 001, generalized to any order).

``well_conditioned_observer`` chooses the observer gain ``L`` so that the eigenvector matrix of
the error dynamics ``A - L C`` is as well conditioned as possible -- minimizing ``kappa2``
(seed 001's principal index), ``kappa_fro`` or Huh & Stein's ``eta`` -- with the poles either

* fixed (the job of ``scipy.signal.place_poles`` YT/KNV0, but minimizing kappa2 itself; like
  YT it accepts a pole repeated up to ``rank(C)`` times -- KNV0 takes real poles only -- and
  above that it answers infeasible with a certificate, where YT raises), or
* free inside a pole region (:mod:`optdesign.regions`; a discrete-time region when
  ``plant.dt`` is set; the region must lie in the closed stability region of the plant's
  time domain),

optionally with structural zeros in ``L``, a bound on ``||L||_2`` and a bound on the other
metric (trade-off: minimize eta subject to ``kappa2 <= kappa2_max``, or the reverse).

``well_conditioned_kalman`` does the same for a true Kalman filter: the noise covariance is
the design variable and the filter Riccati equation is a constraint.

Every design follows validate -> formulate (:mod:`optdesign.formulate.well_conditioned`) ->
solve (IPOPT, multi-start) -> verify (numpy/scipy, independently of the solver) -> result.

References
----------
Jung, J. & Huh, K., "Design of the well-conditioned observer using the non-normality
measure" (seed 001).
Huh, K. & Stein, J. L., "Well-conditioned observer design for observer-based monitoring
systems", ASME J. Dyn. Sys. Meas. Control 117 (1995) 592-599.
Kautsky, J., Nichols, N. K. & Van Dooren, P., "Robust pole assignment in linear state
feedback", Int. J. Control 41 (1985) 1129-1155.
"""

from __future__ import annotations

import dataclasses
import math
import re
import warnings
from dataclasses import dataclass, field
from functools import partial
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._deadline import Deadline, as_time_limit
from .._validate import as_bool, as_int, as_options, as_poles, as_positive_float
from ..analysis import metrics
from ..classical.placement import place_observer, pole_error
from ..classical.riccati import _sort_poles, filter_are, filter_are_residual
from ..errors import DimensionError, ValidationError
from ..formulate.well_conditioned import (
    NLPScaling,
    PoleStructure,
    build_kalman_nlp,
    build_observer_nlp,
    check_objective,
    check_q_structure,
    random_gain_for_poles,
)
from ..model.coerce import as_plant
from ..model.plant import Plant
from ..model.regions import Disk, HalfPlane, Region, Sector, _golden_argmin, stability_region
from ..results import Check, ResultMixin, SolverStats, Status, Verification

__all__ = [
    "ObserverDesign",
    "StartRecord",
    "well_conditioned_observer",
    "well_conditioned_kalman",
    "naive_poles",
    "suggested_region",
    "start_real_counts",
    "start_real_count",
    # building blocks shared with the sweep designers (studies.designers)
    "Candidate",
    "evaluate_candidate",
    "kappa2_agreement_tol",
    "check_region_stable",
    "check_ipopt_options",
    "placement_start",
    "solve_nlp",
    "pick_best",
    "design_outcome",
    "objective_lower_bound",
]

#: continuation stages of the free-pole NLP (the fixed-pole polish at its poles runs them all):
#: on COMPleib AC6 stages 3 and 9 changed kappa2 by < 0.2 % at ~40 % of the time
REGION_STAGES = (0, 6, 12)
#: relative pole accuracy required of a fixed-pole design
POLE_TOL = 1e-6
#: relative distance outside the region accepted (the NLP meets its constraints to ~1e-10; raised to
#: the rounding floor of the poles when they are computable only less accurately)
REGION_TOL = 1e-7
#: relative eigen-residual ``||X Z - Z Lambda||_F / (||X||_F ||Z||_F)`` required of the solver's basis
EIG_RESIDUAL_TOL = 1e-8
#: relative agreement required between cond(solver's basis) and ``metrics.kappa2`` (numpy's
#: eigenvectors): ``KAPPA_TOL + KAPPA_EPS_FACTOR * eps * kappa2``, capped at ``KAPPA_TOL_MAX``
KAPPA_TOL = 1e-6
KAPPA_EPS_FACTOR = 1e3
KAPPA_TOL_MAX = 1e-2

#: IPOPT settings of the design verbs (per stage; merged under the caller's ``options``).
#: ``acceptable_obj_change_tol`` ends the long flat tails measured on scipy's 6x6 test case
#: (1000 iterations for a 1e-9 relative change of kappa2).
_IPOPT_DEFAULTS: dict[str, Any] = {
    "ipopt.tol": 1e-8,
    "ipopt.constr_viol_tol": 1e-10,
    "ipopt.acceptable_tol": 1e-6,
    "ipopt.acceptable_iter": 5,
    "ipopt.acceptable_obj_change_tol": 1e-10,
    "ipopt.max_iter": 500,
}


@dataclass(frozen=True)
class StartRecord:
    """What one multi-start run gave.

    Attributes
    ----------
    index : int
    origin : str
        Where the initial gain came from (``"YT"``, ``"KNV0"``, ``"random"``,
        ``"region sample"``, ``"riccati q=..."``).
    status : Status
        The solver status of the run's last stage.
    verified : bool
        The run's design passed every independent check.
    kappa2, eta, gain_norm : float
        Recomputed with numpy (nan if the run produced no finite gain).
    objective : float
        The objective metric recomputed with numpy (what ranks the starts).
    iterations : int
    time : float
        Seconds in IPOPT.
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


@dataclass(frozen=True)
class ObserverDesign(ResultMixin):
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
    status : Status
    message : str
    solver_stats : SolverStats
        Totals over all starts; ``extra`` has ``starts``, ``converged``, ``best_start``.
    verification : Verification
        ``stability`` (max Re < 0, or spectral radius < 1), ``pole_error`` or ``region_margin``,
        ``eig_residual``, ``kappa2_agreement``,
        ``mask``, ``gain_bound``, ``kappa2_bound``, ``eta_bound`` (when relevant), and for
        Kalman designs ``riccati_residual``, ``P_min_eig``, ``Q_min_eig``, ``gain_vs_riccati``.
    starts : tuple of StartRecord
        The per-start history.
    V : (n, n) ndarray of complex or None
        The unit-column eigenvector matrix behind ``kappa2``.
    target_poles : ndarray or None
        Fixed-pole mode: the requested poles.
    region : Region or None
        Region mode: the pole region.
    certificate : dict or None
        Infeasible designs: why (e.g. a pole repeated more than ``rank(C)`` times).
    Q, P, R : ndarray or None
        Kalman designs: the noise covariances found and the Riccati solution.
    """

    L: NDArray[np.float64]
    poles: NDArray[np.complex128]
    kappa2: float
    eta: float
    kappa_fro: float
    gain_norm: float
    objective: str
    status: Status
    message: str
    solver_stats: SolverStats
    verification: Verification
    starts: tuple[StartRecord, ...] = ()
    V: NDArray[np.complex128] | None = None
    target_poles: NDArray[np.complex128] | None = None
    region: Region | None = None
    certificate: dict[str, Any] | None = None
    Q: NDArray[np.float64] | None = None
    P: NDArray[np.float64] | None = None
    R: NDArray[np.float64] | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def n_converged(self) -> int:
        """Number of starts whose design was solved and verified."""
        return _n_converged(self.starts)

    def record(self) -> dict[str, Any]:
        """Scalar summary for sweeps and tables."""
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
        }

    def __repr__(self) -> str:
        return (
            f"ObserverDesign(status={Status(self.status).value}, success={self.success}, "
            f"kappa2={self.kappa2:.6g}, eta={self.eta:.6g}, ||L||={self.gain_norm:.4g}, "
            f"converged={self.n_converged}/{len(self.starts)})"
        )


# --------------------------------------------------------------------------- validation helpers


def _n_converged(records: tuple[StartRecord, ...] | list[StartRecord]) -> int:
    return sum(1 for r in records if r.verified and Status(r.status).is_solved)


def _check_plant(plant: Any) -> Plant:
    """The plant of a Plant or a python-control / scipy system (:func:`optdesign.as_plant`)."""
    return as_plant(plant)


def _check_mask(structure: Any, n: int, p: int) -> NDArray[np.bool_] | None:
    if structure is None:
        return None
    try:
        m = np.asarray(structure)
    except (ValueError, TypeError):  # ragged nests
        raise ValidationError(f"structure must be a boolean mask of shape ({n}, {p}) (True = free entry of "
                              f"L); found a ragged or non-numeric {type(structure).__name__}") from None
    if m.dtype.kind not in "biuf":
        raise ValidationError(f"structure must be a boolean mask of shape ({n}, {p}) (True = free entry of "
                              f"L); found dtype {m.dtype}")
    if m.shape != (n, p):
        raise DimensionError(
            f"structure (mask of free entries of L) must have shape ({n}, {p}); found {m.shape}"
        )
    if m.dtype != bool:
        if not np.all(np.isin(m, (0, 1))):
            raise ValidationError("structure must be a boolean mask (True = free entry of L, False = zero)")
        m = m.astype(bool)
    if not m.any():
        raise ValidationError("structure has no free entry: L would be zero (nothing to design)")
    return m


def _check_solver(solver: Any) -> None:
    if not isinstance(solver, str) or solver != "ipopt":
        raise ValidationError(f"solver must be 'ipopt' (CasADi/IPOPT is the NLP backend); found {solver!r}")


def _check_region(region: Any) -> Region:
    if not isinstance(region, Region):
        raise ValidationError(f"region must be an optdesign.regions.Region; found {type(region).__name__}")
    return region


def _ipopt_options(options: Any) -> dict[str, Any]:
    """The verbs' IPOPT defaults with the caller's ``options`` (a dict with string keys, or None)
    merged over them.

    Raises
    ------
    ValidationError
        ``options`` is not a dict (or None), or has a key that is not a string.
    """
    user = as_options("options", options)
    if user:
        check_ipopt_options(user)
    return {**_IPOPT_DEFAULTS, **user}


def check_ipopt_options(options: dict[str, Any]) -> None:
    """Refuse ``options`` (a dict with string keys) that CasADi or IPOPT do not accept (unknown
    name, wrong type, invalid value) up front, by configuring IPOPT for a one-variable problem
    with them (a few ms): a bad option is the caller's error, not a failed start.

    Raises
    ------
    ValidationError
        Naming ``options`` and CasADi's / IPOPT's reason.
    """
    from ..solvers.casadi_backend import DEFAULT_IPOPT_OPTIONS, import_casadi

    ca = import_casadi()
    opts = {**DEFAULT_IPOPT_OPTIONS, **options}
    plugin = {k: v for k, v in opts.items() if not k.startswith("ipopt.")}
    plugin["ipopt"] = {k[len("ipopt."):]: v for k, v in opts.items() if k.startswith("ipopt.")}
    plugin["ipopt"].update({"print_level": 0, "sb": "yes"})  # (x0 = 0 is optimal: no iteration)
    plugin["print_time"] = False
    x = ca.MX.sym("x")
    try:
        ca.nlpsol("options_check", "ipopt", {"x": x, "f": x * x}, plugin)(x0=0.0)
    except (RuntimeError, TypeError, NotImplementedError) as exc:
        lines = [ln.strip() for ln in str(exc).splitlines()]
        lines = [ln for ln in lines if ln and not ln.startswith((">", "Did you mean", "Use print_options"))]
        why = re.sub(r"^.*?\.(?:cpp|hpp):\d+:\s*", "", lines[-1]) if lines else repr(exc)
        raise ValidationError(
            f"options must be IPOPT / CasADi options that IPOPT accepts (e.g. {{'ipopt.max_iter': 200}}); "
            f"found {options!r}: {why}"
        ) from None


def _metric_of(objective: str, m: dict[str, float]) -> float:
    return float(m[objective])


def _checker(evaluate, objective: str):
    """``check(candidate) -> (verified, objective metric)`` from an ``evaluate`` function."""

    def check(c: Candidate) -> tuple[bool, float]:
        m, v = evaluate(c)
        return v.passed, _metric_of(objective, m)

    return check


# --------------------------------------------------------------------------- verification


@dataclass
class Candidate:
    """One solver answer before verification: the gain, the solver's eigenbasis ``Z`` (columns) and
    its poles when it could be read, and what the solver said (status, native status, message,
    iterations, seconds, the continuation stage)."""

    L: NDArray
    Z: NDArray | None
    Zpoles: NDArray | None
    status: Status
    native: str
    message: str
    iterations: int
    time: float
    stage: str = ""


def evaluate_candidate(
    plant: Plant,
    cand: Candidate,
    *,
    target: NDArray | None,
    region: Region | None,
    mask: NDArray | None,
    max_gain: float | None,
    kappa2_max: float | None,
    eta_max: float | None,
    stable: bool = True,
) -> tuple[dict[str, Any], Verification]:
    """Independent checks of one design (numpy/scipy only) and its metrics (``stable``: require stability)."""
    L = cand.L
    checks: list[Check] = []
    if not np.all(np.isfinite(L)):
        checks.append(Check.at_most("finite_gain", float("inf"), 0.0, "the gain has NaN/Inf entries"))
        nan = float("nan")
        return {
            "kappa2": nan,
            "eta": nan,
            "kappa_fro": nan,
            "gain_norm": nan,
            "poles": np.full(plant.n, np.nan + 0j),
            "V": None,
        }, Verification.of(checks)
    X = plant.A - L @ plant.C
    poles = _sort_poles(np.linalg.eigvals(X))
    scale = max(1.0, float(np.max(np.abs(poles))))
    # how accurately these poles are computable at all (relative; capped like the pole check)
    floor = min(metrics.eigenvalue_rounding_floor(X), POLE_TOL)
    if stable:
        checks.append(_stability_check(poles, plant.is_discrete, floor))
    if target is not None:
        checks.append(
            Check.at_most(
                "pole_error",
                pole_error(poles, target),
                POLE_TOL,
                "max relative error of eig(A - LC) vs the target poles",
            )
        )
    if region is not None:
        checks.append(
            Check.at_most(
                "region_margin",
                region.margin(poles),
                max(REGION_TOL, floor) * scale,
                "max signed distance of eig(A - LC) to the region (<= 0 inside; tolerance REGION_TOL "
                "or the rounding floor of the poles, relative)",
            )
        )
    summ = metrics.condition_summary(X)
    k2, eta_v, kf = float(summ["kappa2"]), float(summ["eta"]), float(summ["kappa_fro"])
    if cand.Z is not None:
        Z, zp = cand.Z, cand.Zpoles
        res = np.linalg.norm(X @ Z - Z * zp[None, :]) / max(
            np.linalg.norm(X) * np.linalg.norm(Z), 1e-300
        )
        checks.append(
            Check.at_most(
                "eig_residual",
                res,
                EIG_RESIDUAL_TOL,
                "||(A - LC) Z - Z diag(poles)||_F / (||A - LC||_F ||Z||_F) for the solver's basis",
            )
        )
        sv = np.linalg.svd(Z, compute_uv=False)
        kz = float(sv[0] / sv[-1]) if sv[-1] > 0 else float("inf")
        if math.isfinite(k2):
            checks.append(
                Check.at_most(
                    "kappa2_agreement",
                    abs(kz - k2) / k2,
                    kappa2_agreement_tol(k2),
                    "cond(solver basis) vs metrics.kappa2 (numpy eigenvectors), relative",
                )
            )
        elif math.isfinite(kz) and res <= EIG_RESIDUAL_TOL:
            # repeated pole: the basis is not unique; report the verified basis the solver found
            k2 = kz
            kf = float(np.linalg.norm(Z) * np.linalg.norm(np.linalg.inv(Z)))
        V = Z
    else:
        V = metrics.eigenvector_matrix(X) if math.isfinite(k2) else None
    gn = float(np.linalg.norm(L, 2))
    if mask is not None:
        off = float(np.max(np.abs(L[~mask]))) if (~mask).any() else 0.0
        checks.append(Check.at_most("mask", off, 0.0, "largest |L| entry outside the structure mask"))
    if max_gain is not None:
        checks.append(Check.at_most("gain_bound", gn, max_gain * (1 + 1e-6), "||L||_2 <= max_gain"))
    if kappa2_max is not None:  # to the accuracy of a computed kappa2 (kappa2_agreement_tol)
        checks.append(Check.at_most("kappa2_bound", k2, kappa2_max * (1 + kappa2_agreement_tol(kappa2_max)),
                                    "kappa2 <= kappa2_max"))
    if eta_max is not None:
        checks.append(Check.at_most("eta_bound", eta_v, eta_max * (1 + 1e-6), "eta <= eta_max"))
    if not checks:
        checks.append(Check.at_most("finite_gain", 0.0, 0.0))
    out = {"kappa2": k2, "eta": eta_v, "kappa_fro": kf, "gain_norm": gn, "poles": poles, "V": V}
    return out, Verification.of(checks)


def kappa2_agreement_tol(kappa2: float) -> float:
    """Relative tolerance of ``|cond(Z) - kappa2| / kappa2`` between two unit-column eigenbases.

    Two exact unit-column eigenbases of a matrix with distinct eigenvalues differ by column
    phases only, so their condition numbers are equal; the difference measured comes from
    rounding (numpy's eigenvectors, the solver's tolerance), which grows like ``eps kappa2``.
    The tolerance is ``KAPPA_TOL + KAPPA_EPS_FACTOR * eps * kappa2`` and never more than
    ``KAPPA_TOL_MAX`` (1 %), whatever ``kappa2``.
    """
    eps = float(np.finfo(float).eps)
    return float(min(KAPPA_TOL_MAX, KAPPA_TOL + KAPPA_EPS_FACTOR * eps * float(kappa2)))


def _stability_check(poles: NDArray, discrete: bool, floor: float) -> Check:
    """Strict stability of the error dynamics beyond the rounding level of the poles: max Re below
    ``-floor max(1, max |pole|)``, or spectral radius below ``1 - floor`` (``floor``: the relative
    rounding floor of the poles, :func:`~optdesign.analysis.metrics.eigenvalue_rounding_floor`)."""
    if discrete:
        rho = float(np.max(np.abs(poles))) if poles.size else 0.0
        return Check.at_most(
            "stability", rho, 1.0 - floor, "spectral radius of A - LC < 1 beyond rounding (discrete time)"
        )
    mr = float(np.max(poles.real)) if poles.size else -1.0
    tol = -floor * max(1.0, float(np.max(np.abs(poles)))) if poles.size else 0.0
    return Check.at_most("stability", mr, tol, "max Re eig(A - LC) < 0 beyond rounding (continuous time)")


def _region_sup_modulus(region: Region) -> float:
    """``max |z|`` over a bounded convex region (its boundary found along rays from an interior point)."""
    x0 = region.interior_point()

    def radii(thetas: NDArray) -> NDArray:
        d = np.exp(1j * np.asarray(thetas, dtype=float))
        hi = np.ones(d.shape)
        for _ in range(2000):
            inside = region.distance(x0 + hi * d) <= 0.0
            if not inside.any():
                break
            hi = np.where(inside, 2.0 * hi, hi)
        lo = np.zeros(d.shape)
        for _ in range(60):  # bisection to ~1e-18 relative (below rounding)
            mid = 0.5 * (lo + hi)
            inside = region.distance(x0 + mid * d) <= 0.0
            lo, hi = np.where(inside, mid, lo), np.where(inside, hi, mid)
        return np.abs(x0 + hi * d)

    thetas = np.linspace(0.0, math.pi, 361)  # the region is symmetric about the real axis
    vals = radii(thetas)
    k = int(np.argmax(vals))
    a, b = float(thetas[max(k - 1, 0)]), float(thetas[min(k + 1, thetas.size - 1)])
    # golden-section refinement of the best bracket
    t = _golden_argmin(lambda th: -float(radii(np.array([th]))[0]), a, b, iters=60)
    return max(float(vals[k]), float(radii(np.array([t]))[0]))


def check_region_stable(region: Region, discrete: bool) -> None:
    """A pole region must lie in the (closed) stability region of the plant's time domain.

    Raises
    ------
    ValidationError
        Naming how far the region reaches out (``sup Re s > 0``, or ``sup |z| > 1``).
    """
    if discrete:
        sup = math.inf if not region.bounded else _region_sup_modulus(region)
        if sup > 1.0 + 1e-9:
            raise ValidationError(
                f"the pole region {region!r} reaches |z| = {sup:.6g} > 1: the plant is discrete-time "
                "(dt set) and poles there make the error dynamics unstable; use a region inside the unit "
                "disk, e.g. region & Disk.unit(0.95)"
            )
        return
    hi = float(region.real_interval()[1])
    if hi > 0.0:
        raise ValidationError(
            f"the pole region {region!r} reaches Re s = {hi:.6g} > 0: the plant is continuous-time and "
            "poles there make the error dynamics unstable (for a discrete-time design set plant.dt); "
            "intersect the region with a stable half-plane, e.g. region & HalfPlane(alpha) with alpha > 0"
        )


def _check_target_stable(target: NDArray, discrete: bool) -> None:
    bad = target[np.abs(target) >= 1.0] if discrete else target[target.real >= 0.0]
    if bad.size:
        what = "|z| < 1 (discrete time)" if discrete else "Re s < 0 (continuous time)"
        raise ValidationError(
            f"poles must give stable error dynamics, {what} (allow_unstable=True accepts them); "
            "found unstable poles "
            + ", ".join(f"{z.real:.6g}" if z.imag == 0 else f"{complex(z):.6g}" for z in bad)
        )


# --------------------------------------------------------------------------- solving


def solve_nlp(nlp, options: dict[str, Any], deadline: Deadline):
    """Solve a built observer NLP with IPOPT within ``deadline`` (a :class:`SolverReport`).

    IPOPT is configured on the first solve and re-used after (``nlp.solver_ready``); under a time
    limit its ``max_wall_time`` is the time left (:meth:`Deadline.ipopt_options`), and the solver
    is re-configured when the cap it has exceeds the time left by more than a tenth of the limit
    (at least 0.05 s) -- so a solve overruns the deadline by at most that, and IPOPT is configured
    at most about ten times per design.
    """
    from ..solvers.casadi_backend import solve_opti

    configure = not nlp.solver_ready
    opts = options
    cap = getattr(nlp, "solver_wall_time", None)
    if deadline.limit is not None:
        rem = deadline.remaining()
        wall = deadline.ipopt_options()["ipopt.max_wall_time"]
        user = options.get("ipopt.max_wall_time")
        if user is not None:
            wall = min(wall, float(user))
        if configure or cap is None or cap > rem + max(0.1 * deadline.limit, 0.05):
            configure, cap = True, wall
        opts = {**options, "ipopt.max_wall_time": cap}
    elif cap is not None:  # configured under an earlier budget: lift it
        configure, cap = True, None
    rep = solve_opti(nlp.opti, opts, configure=configure)
    nlp.solver_ready = True
    nlp.solver_wall_time = cap
    return rep


def _stage_plan(nlp, objective: str, stages: tuple[int, ...] | None):
    """``(stages, set_stage, give_up_after_two_failures)`` of one start (:meth:`ObserverNLP.continuation`).

    A start of the kappa2 objective is given up after two failed stages; the stages of a kappa2
    bound are all tried (a bound too tight for the conservative order-64 surrogate may still be
    met at a higher order).
    """
    plan, set_stage = nlp.continuation(stages if objective == "kappa2" else None)
    return plan, set_stage, objective == "kappa2" or set_stage is None


def _run_start(
    nlp, L0: NDArray, objective: str, options: dict[str, Any], check, stages: tuple[int, ...] | None = None,
    deadline: Deadline | None = None, force: bool = False,
) -> list[Candidate]:
    """Solve from one initial gain through the continuation stages; every stage's candidate.

    No stage is started once ``deadline`` has expired (the list may then be empty), except the
    first one with ``force`` (the first start of a design: IPOPT then gets at least 0.01 s).
    """
    deadline = Deadline.of(deadline)
    plan, set_stage, give_up = _stage_plan(nlp, objective, stages)
    nlp.set_initial_gain(L0)
    history: list[Candidate] = []
    last_good = None
    for J in plan:
        if deadline.expired and (history or not force):
            break
        if J is not None:
            set_stage(J)
        if last_good is not None:
            nlp.warm_start(last_good)
        rep = solve_nlp(nlp, options, deadline)
        cand, _ = _read_candidate(nlp, rep, type(nlp).__name__ + ("" if J is None else f" J={J}"))
        history.append(cand)
        if check(cand)[0]:  # (a candidate CasADi could not evaluate has a NaN gain: it fails)
            last_good = nlp.snapshot(rep.value)
        elif last_good is None:
            if give_up and len(history) >= 2:  # two failed stages from this start: give it up
                break
            nlp.set_initial_gain(L0)  # retry the next stage from the same start
    return history


def _read_candidate(nlp, rep, stage: str) -> tuple[Candidate, bool]:
    """The candidate of one solve (gain and, if it can be read, the solver's eigenbasis) and
    whether the iterate could be evaluated at all; if not, a failed candidate (NaN gain, status
    solver_error) giving CasADi's reason (seen after e.g. a failed restoration phase)."""
    try:
        L = nlp.gain(rep.value)
    except RuntimeError as exc:
        return _solver_error_candidate(nlp.plant, rep, exc, stage), False
    try:
        Z, zp = nlp.basis(rep.value)
    except (ValueError, np.linalg.LinAlgError, FloatingPointError, RuntimeError):
        Z, zp = None, None
    return Candidate(L, Z, zp, *_report_fields(rep), stage=stage), True


def _report_fields(rep) -> tuple[Status, str, str, int, float]:
    """``(status, native status, message, iterations, time)`` of a SolverReport (Candidate's order)."""
    st = rep.stats
    return rep.status, st.native_status, rep.message, int(st.iterations or 0), float(st.time)


def _solver_error_candidate(plant: Plant, rep, exc: Exception, stage: str) -> Candidate:
    """A failed candidate (NaN gain, status solver_error) for an iterate CasADi could not evaluate."""
    first = str(exc).strip().splitlines()
    why = first[-1] if first else repr(exc)
    _, native, message, iterations, time = _report_fields(rep)
    return Candidate(
        np.full((plant.n, plant.p), np.nan),
        None,
        None,
        Status.SOLVER_ERROR,
        native,
        f"{message}; the solution could not be evaluated ({type(exc).__name__}: {why[:200]})",
        iterations,
        time,
        stage=stage,
    )


def _start_record(idx: int, origin: str, cand: Candidate, m: dict, v: Verification, obj: float,
                  message: str) -> StartRecord:
    """The history entry of one start whose chosen candidate carries the start's totals."""
    return StartRecord(idx, origin, Status(cand.status), v.passed, m["kappa2"], m["eta"], m["gain_norm"], obj,
                       cand.iterations, cand.time, message)


def _rank_key(obj: float, v: Verification, c: Candidate, idx: int = 0) -> tuple[int, float, int]:
    """Verified and solved first, then verified (e.g. an iteration limit), then the rest; by objective."""
    solved = Status(c.status).is_solved
    rank = 0 if (v.passed and solved) else 1 if v.passed else 2
    return (rank, obj if math.isfinite(obj) else float("inf"), idx)


def objective_lower_bound(objective: str, n: int) -> float | None:
    """The smallest value the objective can take: kappa2 >= 1, kappa_fro >= n (unit columns:
    ``||V||_F = sqrt(n) <= ||V^-1||_F``); None for eta (0 only for a normal ``A - LC``, which a
    relative test cannot confirm)."""
    return {"kappa2": 1.0, "kappa_fro": float(n)}.get(objective)


def _attains(bound: float | None, obj: float, v: Verification, cand: Candidate) -> bool:
    """A solved, verified design at its objective's lower bound, to the accuracy of a computed kappa2
    (:func:`kappa2_agreement_tol`): a global optimum, no other start can do better."""
    return (bound is not None and v.passed and Status(cand.status).is_solved
            and obj <= bound * (1.0 + kappa2_agreement_tol(bound)))


def _solve_starts(starts_list, runner, objective, evaluate, deadline: Deadline, lower_bound=None):
    """Run the starts through ``runner(L0, structure, first)`` (-> candidates); keep each start's best
    verified candidate.  No start after the first is begun once ``deadline`` has expired, nor once a
    design attains ``lower_bound`` (the objective's, :func:`objective_lower_bound`)."""
    records: list[StartRecord] = []
    evaluated: list[tuple[float, int, dict, Verification, Candidate]] = []
    for idx, (origin, L0, structure) in enumerate(starts_list):
        if idx and (deadline.expired or any(_attains(lower_bound, e[0], e[3], e[4]) for e in evaluated)):
            break
        hist = runner(L0, structure, idx == 0)
        if not hist:
            continue
        t = sum(c.time for c in hist)
        it = sum(c.iterations for c in hist)
        scored = []
        for c in hist:
            m, v = evaluate(c)
            scored.append((_metric_of(objective, m), m, v, c))
        ok = [x for x in scored if x[2].passed]
        pool = ok if ok else scored[-1:]
        obj, m, v, cand = min(pool, key=lambda x: _rank_key(x[0], x[2], x[3]))
        cand = dataclasses.replace(cand, iterations=it, time=t)
        message = cand.message + (f" [{cand.stage}]" if cand.stage else "")
        records.append(_start_record(idx, origin, cand, m, v, obj, message))
        evaluated.append((obj, idx, m, v, cand))
    return records, evaluated


def pick_best(evaluated):
    """The best of ``(objective, index, metrics, verification, candidate)`` entries: solved and
    verified first, then verified (e.g. an iteration limit), then the rest; by objective, then index."""
    return min(evaluated, key=lambda e: _rank_key(e[0], e[3], e[4], e[1]))


def design_outcome(records, evaluated, objective: str, *, deadline: Deadline, planned: int):
    """Status and message of a multi-start design from its records.

    Parameters
    ----------
    records : list of StartRecord
    evaluated : list of (objective, index, metrics, Verification, Candidate)
        Non-empty, as returned with ``records``.
    objective : str
    deadline : Deadline
        Expired at the end: status ``time_limit`` (the budget ran out before the design finished).
    planned : int
        Number of starts the design would have run without a time limit.

    Returns
    -------
    best : tuple
        The :func:`pick_best` entry.
    status : Status
        ``time_limit`` (budget spent; the best verified design so far is kept); the best candidate's
        status when it passed verification (a solved one, or e.g. ``iteration_limit``);
        ``solver_error`` when every start crashed; otherwise ``not_found``: no start gave a
        verified design, which is local evidence only -- never ``infeasible``.
    message : str
    """
    best = pick_best(evaluated)
    obj, idx, _, v, cand = best
    converged = _n_converged(records)
    origin = records[[r.index for r in records].index(idx)].origin
    where = f"start {idx} ({origin})"
    failed = "; ".join(c.name for c in v.failed)
    if deadline.expired:
        status = Status.TIME_LIMIT
        ran = f"time limit of {deadline.limit:g} s reached after {len(records)} of {planned} starts"
        msg = (f"{ran}; best verified design so far: {where}, {objective} = {obj:.6g}" if v.passed else
               f"{ran}; no verified design yet (best {where}: {cand.message}"
               + (f"; failed checks: {failed})" if failed else ")"))
        return best, status, msg
    if v.passed:
        status = Status(cand.status)
        if status.is_solved:
            msg = (f"best of {len(records)} starts (start {idx}, {origin}): {objective} = {obj:.6g}; "
                   f"{converged} of {len(records)} starts converged to verified designs")
            return best, status, msg
    elif records and all(Status(r.status) == Status.SOLVER_ERROR for r in records):
        status = Status.SOLVER_ERROR
    else:
        status = Status.NOT_FOUND
    msg = (f"no start gave a solved and verified design ({converged} of {len(records)}); best {where}: "
           f"{cand.message}" + (f"; failed checks: {failed}" if failed else ""))
    if status == Status.NOT_FOUND:
        msg += " (not found by a local method: feasibility unknown)"
    return best, status, msg


def _result_from(plant, records, evaluated, *, objective, target, region, deadline: Deadline, planned: int,
                 kalman=None) -> ObserverDesign:
    if not evaluated:  # the time ran out before any start could run
        reason = f"time limit of {deadline.limit:g} s reached before any of the {planned} starts could run"
        return _no_design(plant, objective, Status.TIME_LIMIT, reason, None, target=target, region=region,
                          **(kalman or {}))
    (obj, idx, m, v, cand), status, msg = design_outcome(records, evaluated, objective, deadline=deadline,
                                                         planned=planned)
    bound = objective_lower_bound(objective, plant.n)
    if status.is_solved and len(records) < planned and _attains(bound, obj, v, cand):
        msg += (f"; stopped after {len(records)} of {planned} starts: {objective} = {bound:g} is its lower "
                "bound (a global optimum)")
    stats = SolverStats(
        backend="ipopt",
        native_status=cand.native,
        time=float(sum(r.time for r in records)),
        iterations=int(sum(r.iterations for r in records)),
        extra={"starts": len(records), "planned_starts": planned, "converged": _n_converged(records),
               "best_start": idx, "objective": obj},
    )
    kw = kalman or {}
    return ObserverDesign(
        L=cand.L,
        poles=m["poles"],
        kappa2=m["kappa2"],
        eta=m["eta"],
        kappa_fro=m["kappa_fro"],
        gain_norm=m["gain_norm"],
        objective=objective,
        status=status,
        message=msg,
        solver_stats=stats,
        verification=v,
        starts=tuple(records),
        V=m["V"],
        target_poles=target,
        region=region,
        **kw,
    )


def _no_design(plant, objective, status: Status, reason: str, certificate: dict | None, target=None,
               region=None, **fields) -> ObserverDesign:
    """A result without a gain (NaN): ``infeasible`` with a proof, or ``time_limit`` before any start."""
    n, p = plant.n, plant.p
    nan = float("nan")
    return ObserverDesign(
        L=np.full((n, p), np.nan),
        poles=np.full(n, np.nan + 0j),
        kappa2=float("inf"),
        eta=float("inf"),
        kappa_fro=float("inf"),
        gain_norm=nan,
        objective=objective,
        status=status,
        message=reason,
        solver_stats=SolverStats(backend="analytic" if status.is_infeasible else "ipopt",
                                 native_status=status.value),
        verification=Verification.of([Check.at_most("feasible" if status.is_infeasible else "finite_gain",
                                                    float("inf"), 0.0, reason)]),
        starts=(),
        target_poles=target,
        region=region,
        certificate=certificate,
        **fields,
    )


def _infeasible(plant, objective, reason: str, certificate: dict, target=None, region=None) -> ObserverDesign:
    """Infeasible with a proof (``certificate`` says which)."""
    return _no_design(plant, objective, Status.INFEASIBLE, reason, certificate, target=target, region=region)


def _better_yt(plant: Plant, poles: NDArray, L0: NDArray, region: Region) -> NDArray:
    """The better-conditioned of two YT runs (place_observer's tolerances and scipy's defaults).

    YT's iterations do not decrease kappa2 monotonically: on COMPleib TG1 at the naive poles scipy's
    defaults (rtol 1e-3, 30 sweeps) give kappa2 9.8e5, ``rtol=1e-6, maxiter=100`` 5.2e6.
    """
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            L1 = place_observer(plant, poles, method="YT", rtol=1e-3, maxiter=30)
    except (ValueError, np.linalg.LinAlgError):
        return L0
    if not np.all(np.isfinite(L1)):
        return L0

    def key(L):  # inside the region first, then kappa2
        X = plant.A - L @ plant.C
        return (not region.contains(np.linalg.eigvals(X)), metrics.kappa2(X))

    return L1 if key(L1) < key(L0) else L0


def placement_start(plant: Plant, poles: NDArray, method: str) -> NDArray | None:
    """scipy's robust placement (``method`` "YT" or "KNV0") as a start gain; None when it fails."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            L = place_observer(plant, poles, method=method)
    except (ValueError, np.linalg.LinAlgError):
        return None
    if not np.all(np.isfinite(L)):
        return None
    return L


# --------------------------------------------------------------------------- the verbs


def _kappa2_bound(kappa2_max) -> float | None:
    """A bound on kappa2: None, or a number >= 1 (kappa2 >= 1 always)."""
    if kappa2_max is None:
        return None
    kappa2_max = as_positive_float("kappa2_max", kappa2_max)
    if kappa2_max < 1:
        raise ValidationError(f"kappa2_max must be >= 1 (kappa2 >= 1 always); found {kappa2_max!r}")
    return kappa2_max


def well_conditioned_observer(
    plant: Plant,
    *,
    region: Region | None = None,
    poles: ArrayLike | None = None,
    objective: str = "kappa2",
    structure: ArrayLike | None = None,
    max_gain: float | None = None,
    kappa2_max: float | None = None,
    eta_max: float | None = None,
    starts: int = 8,
    seed: int = 0,
    solver: str = "ipopt",
    scaling: bool = True,
    options: dict[str, Any] | None = None,
    allow_unstable: bool = False,
    time_limit: float | None = None,
) -> ObserverDesign:
    """Observer gain whose error dynamics ``A - L C`` have a well-conditioned eigenbasis.

    Parameters
    ----------
    plant : Plant
        ``A`` (n, n), ``C`` (p, n); continuous, or discrete when ``plant.dt`` is set.
    region : Region, optional
        Poles free inside this region (use a discrete-time region, e.g. ``Disk.unit(0.9)``,
        when ``plant.dt`` is set).  It must lie in the closed stability region of the plant's
        time domain (``Re s <= 0``, or ``|z| <= 1``): a region reaching outside is rejected
        (ValidationError), not silently intersected -- intersect it yourself, e.g.
        ``region & HalfPlane(alpha)``.  Unbounded regions need ``max_gain`` or a bounded member
        (e.g. ``& Disk(0, R)``) when the metric keeps improving as poles move away.
    poles : (n,) array_like of complex, optional
        Fixed poles, stable (``Re < 0``, or ``|z| < 1`` when ``plant.dt`` is set;
        conjugate-closed; a pole may repeat up to ``rank(C)`` times).  Give
        ``region`` or ``poles``, not both; with neither, the region is the stability region
        (``HalfPlane(0)`` or the unit disk).
    objective : {"kappa2", "kappa_fro", "eta"}
        What to minimize: kappa2 of the unit-column eigenvector matrix (seed 001's index),
        its Frobenius counterpart, or Huh & Stein's eta.
    structure : (n, p) array_like of bool, optional
        Free entries of ``L`` (False = structural zero).
    max_gain : float, optional
        Bound on ``||L||_2``.
    kappa2_max, eta_max : float, optional
        Trade-off bounds on the metrics that are not minimized (e.g. minimize eta subject to
        ``kappa2 <= kappa2_max``): minimizing eta alone can make kappa2 much worse.
    starts : int, default 8
        Number of multi-start runs.  Fixed poles: scipy YT, KNV0 (real poles) and random
        parametric eigenstructure assignments.  Region: start 0 is scipy YT at
        :func:`naive_poles` (the open-loop poles moved into the region), start 1 the Kalman
        gain for ``Q = I, R = I``, the others YT at poles sampled in the region
        (:meth:`Region.sample_poles`) with the real/complex patterns of :func:`start_real_counts`
        (the ``j``-th sampled start takes ``start_real_count(n, j)``); Kalman gains replace
        placements when the plant is unobservable.  No further start is run once a solved,
        verified design attains the objective's lower bound (kappa2 = 1, kappa_fro = n, to the
        accuracy of a computed kappa2): a global optimum.
    seed : int, default 0
        Seed of every random choice (reproducible).
    solver : {"ipopt"}
    scaling : bool, default True
        Time scaling (continuous time) and unit-norm output rows: both leave kappa2 and eta
        unchanged.
    options : dict, optional
        IPOPT options (string keys, ``"ipopt.max_iter"``, ...) merged over the defaults; names
        and values IPOPT refuses raise ValidationError before anything runs.
    allow_unstable : bool, default False
        Fixed poles only: accept unstable ``poles`` (pole-assignment benchmarks, e.g. Byers 6,
        are state-feedback problems that assign unstable poles); the verification then does not
        require stability.  An observer with unstable error dynamics is otherwise refused.
    time_limit : float, optional
        Seconds of wall time (None: no limit).  IPOPT gets the time left (``max_wall_time``); no
        start after the first begins once it is spent (the first start always makes its first
        solve, so a quick verified design is not lost to a tiny budget).

    Returns
    -------
    ObserverDesign
        ``success`` is True only when the best start was solved *and* passed verification
        (stability and the poles recomputed with numpy against the target or the region, the
        solver's eigenbasis against ``metrics.kappa2``, mask, gain and metric bounds).  A
        verified design whose solver stopped early (``iteration_limit``) is returned with that
        status (so ``success`` is False) only when no solved and verified candidate exists.
        Other statuses:

        * ``time_limit`` -- the budget ran out before the design finished: ``success`` is
          False (the search was cut short), and ``L``, ``poles`` and the metrics are those of
          the best verified design found so far (``verification.passed`` says whether there
          is one; ``starts`` lists the runs made);
        * ``not_found`` -- no start gave a verified design (e.g. IPOPT stopped at a point of
          local infeasibility, or no placement reaches the region, COMPleib REA4): local
          evidence only, feasibility unknown, no certificate;
        * ``solver_error`` -- every start crashed (the reasons are in ``starts``);
        * ``infeasible`` -- only with a proof in ``certificate``: a pole repeated more than
          ``rank(C)`` times (``A - LC`` would be defective), a repeated pole with objective
          eta (infinite), an unobservable mode outside the region.

    Raises
    ------
    ValidationError
        Both or wrong ``poles``/``region``, unknown objective or solver, bad mask, bounds,
        ``starts``, ``options`` or ``time_limit``; unstable fixed poles (named; unless
        ``allow_unstable``); a region reaching outside the stability region;
        ``allow_unstable`` with a region.
    NotObservableError
        ``(C, A)`` is not observable (names the unobservable modes).
    NotConjugateClosedError, DimensionError
        Bad pole set.

    Notes
    -----
    kappa2 is minimized through a smooth upper bound tightened by continuation
    (:mod:`optdesign.formulate.well_conditioned`); the reported kappa2 is recomputed with
    numpy.  The problem is non-convex: the best of ``starts`` local solutions is returned
    and ``starts`` holds every run.

    A kappa2 bound with another objective goes through its own continuation (the orders 64,
    512, 4096 of the surrogate, :data:`~optdesign.formulate.well_conditioned.KAPPA2_BOUND_STAGES`):
    every order guarantees ``kappa2 <= kappa2_max``, the low one converges robustly, the higher
    ones recover the few tenths of a percent it gives away.

    Fixed poles use the reduced (left-eigenvector) NLP.  In a region each start contributes
    (0) its own gain, unoptimized, (A) the fixed-pole NLP at the start's poles, (B) the
    free-pole NLP from the start, (C) the fixed-pole NLP at B's poles, from B's gain and from
    scipy's YT gain there; every candidate is verified and the best is kept -- so the design
    is never worse than scipy YT at :func:`naive_poles` (start 0, whenever that placement is
    verified) nor than robust placement at its own poles (from those starts).

    References
    ----------
    Seed 001 (Jung & Huh); Kautsky, Nichols & Van Dooren (1985); Tits & Yang (1996).

    Examples
    --------
    >>> import numpy as np
    >>> from optdesign import Plant, well_conditioned_observer
    >>> plant = Plant([[0, 1], [2, -1]], [[1, 0]])
    >>> d = well_conditioned_observer(plant, poles=[-2, -3], starts=1)
    >>> bool(d.success), round(d.kappa2, 4)   # a SISO gain is fixed by its poles: 3 + sqrt(10)
    (True, 6.1623)
    """
    deadline = Deadline(as_time_limit(time_limit))
    plant = _check_plant(plant)
    check_objective(objective)
    _check_solver(solver)
    starts = as_int("starts", starts, 1)
    seed = as_int("seed", seed, 0)
    scaling = as_bool("scaling", scaling)
    n, p = plant.n, plant.p
    mask = _check_mask(structure, n, p)
    max_gain = None if max_gain is None else as_positive_float("max_gain", max_gain)
    eta_max = None if eta_max is None else as_positive_float("eta_max", eta_max)
    kappa2_max = _kappa2_bound(kappa2_max)
    opts = _ipopt_options(options)
    if region is not None and poles is not None:
        raise ValidationError("give either poles (fixed) or region (free poles), not both")
    if not isinstance(allow_unstable, (bool, np.bool_)):
        raise ValidationError(f"allow_unstable must be True or False; found {allow_unstable!r}")
    if allow_unstable and poles is None:
        raise ValidationError(
            "allow_unstable applies to fixed poles only; a region must lie in the stability region"
        )
    if region is not None:
        _check_region(region)
    if poles is not None:
        plant.require_observable(what="well-conditioned observer design with fixed poles")
    bounds = dict(mask=mask, max_gain=max_gain, kappa2_max=kappa2_max, eta_max=eta_max)
    rng = np.random.default_rng(seed)
    if poles is not None:
        target = as_poles("poles", poles, n)
        return _fixed_design(plant, target, objective, bounds, starts, rng, scaling, opts, allow_unstable,
                             deadline)
    if region is None:
        region = stability_region(plant.is_discrete)
    return _region_design(plant, region, objective, bounds, starts, rng, scaling, opts, deadline)


def _repeated_pole_proof(plant: Plant, target: NDArray, objective: str) -> ObserverDesign | None:
    """The infeasible result of a fixed pole set that no diagonalizable ``A - LC`` (or finite eta)
    has, with its proof; None if there is none."""
    rank = int(np.linalg.matrix_rank(plant.C))
    vals, counts = np.unique(np.round(target, 10), return_counts=True)
    k = int(np.argmax(counts))
    if counts[k] > rank:
        reason = (
            f"pole {vals[k]} is requested {counts[k]} times but rank(C) = {rank}: the eigenspace of "
            f"A - LC for it has dimension <= rank(C), so A - LC would be defective (kappa2 = inf)"
        )
        cert = {"reason": "multiplicity exceeds rank(C)", "pole": complex(vals[k]),
                "multiplicity": int(counts[k]), "rank_C": rank}
        return _infeasible(plant, objective, reason, cert, target=target)
    if objective == "eta" and counts[k] > 1:
        return _infeasible(plant, objective, "eta is infinite for repeated poles (zero eigenvalue gap)",
                           {"reason": "repeated pole with objective eta", "pole": complex(vals[k])},
                           target=target)
    return None


def _fixed_design(plant, target, objective, bounds, starts, rng, scaling, opts, allow_unstable,
                  deadline) -> ObserverDesign:
    """Fixed poles: the reduced NLP from scipy's YT / KNV0 and random assignments."""
    n, p = plant.n, plant.p
    if not allow_unstable:
        _check_target_stable(target, plant.is_discrete)
    proof = _repeated_pole_proof(plant, target, objective)
    if proof is not None:
        return proof
    pstruct = PoleStructure.of(target)
    sc = (
        NLPScaling.for_plant(plant, float(np.max(np.abs(target))), balance=False)
        if scaling
        else NLPScaling.identity(n, p)
    )
    start_list = _fixed_starts(plant, target, starts, rng, pstruct)
    nlp = build_observer_nlp(plant, pstruct, fixed_poles=True, objective=objective, scaling=sc, **bounds)
    nlp.set_poles(target)
    evaluate = partial(evaluate_candidate, plant, target=target, region=None, stable=not allow_unstable,
                       **bounds)
    check = _checker(evaluate, objective)

    def runner(L0, st, first):
        return _run_start(nlp, L0, objective, opts, check, deadline=deadline, force=first)

    records, evaluated = _solve_starts(start_list, runner, objective, evaluate, deadline,
                                       objective_lower_bound(objective, n))
    return _result_from(plant, records, evaluated, objective=objective, target=target, region=None,
                        deadline=deadline, planned=len(start_list))


def _region_design(plant, region, objective, bounds, starts, rng, scaling, opts, deadline) -> ObserverDesign:
    """Poles free in ``region``: every start through placements, the free-pole NLP and polishes."""
    n, p = plant.n, plant.p
    mask = bounds["mask"]
    check_region_stable(region, plant.is_discrete)
    if not region.bounded and bounds["max_gain"] is None:
        raise ValidationError(
            f"the pole region {region!r} is unbounded and no max_gain was given: kappa2 and eta can keep "
            "improving as poles (and ||L||) grow without bound; give max_gain or intersect the region with "
            "a Disk, e.g. region & Disk(0, R)"
        )
    unobs = plant.unobservable_modes()
    if unobs.size:
        dist = region.distance(unobs)
        if np.any(dist > 1e-9 * max(1.0, float(np.max(np.abs(unobs))))):
            k = int(np.argmax(dist))
            reason = (
                f"the unobservable mode {unobs[k]:.6g} of (C, A) is an eigenvalue of A - LC for every L "
                f"and lies outside the region (distance {dist[k]:.3g})"
            )
            return _infeasible(
                plant,
                objective,
                reason,
                {"reason": "unobservable mode outside the region", "modes": unobs, "distance": dist},
                region=region,
            )
    try:
        x0 = region.interior_point()
    except Exception:  # noqa: BLE001 - any failure: fall back on the plant's scale
        x0 = 0.0
    sc = NLPScaling.for_plant(plant, abs(x0), balance=False) if scaling else NLPScaling.identity(n, p)
    start_list = _region_starts(plant, region, starts, rng, mask)

    fixed_cache: dict[PoleStructure, Any] = {}
    region_cache: dict[PoleStructure, Any] = {}
    kw = dict(objective=objective, scaling=sc, **bounds)
    evaluate = partial(evaluate_candidate, plant, target=None, region=region, **bounds)
    check = _checker(evaluate, objective)
    observable = plant.is_observable()
    rank_c = int(np.linalg.matrix_rank(plant.C))
    region_opts = dict(opts)
    region_opts["ipopt.max_iter"] = min(int(opts.get("ipopt.max_iter", 300)), 300)

    def fixed_at(poles_now, L0):
        """Fixed-pole optimization at given poles (inside the region), or [] if not applicable."""
        try:
            P = as_poles("poles", poles_now, n)
        except ValidationError:
            return []
        st = PoleStructure.of(P)
        _, counts = np.unique(np.round(P, 8), return_counts=True)
        if counts.max() > rank_c or (objective == "eta" and counts.max() > 1):
            return []
        if st not in fixed_cache:
            fixed_cache[st] = build_observer_nlp(plant, st, fixed_poles=True, **kw)
        nlp = fixed_cache[st]
        try:
            nlp.set_poles(P)
        except ValidationError:
            return []
        return _run_start(nlp, L0, objective, opts, check, deadline=deadline)

    def runner(L0, st, first):
        # (0) the start's gain itself, (A) the best eigenbasis at the sampled poles, (B) free poles
        # from there, (C) the best eigenbasis at B's poles -- each verified; the best is kept, so a
        # design is never worse than its start (e.g. scipy YT at the naive poles)
        P0 = np.linalg.eigvals(plant.A - L0 @ plant.C)
        raw = Candidate(
            np.asarray(L0, dtype=float), None, None, Status.SOLVED, "direct",
            "the start's gain itself (not improved by IPOPT)", 0, 0.0, stage="start gain",
        )
        hist = [raw]
        hist += fixed_at(P0, L0) if observable and region.contains(P0) else []
        if st not in region_cache and not deadline.expired:
            region_cache[st] = build_observer_nlp(plant, st, fixed_poles=False, region=region, **kw)
        # the free-pole NLP from the start itself, with the whole continuation: measured on COMPleib
        # AC6, starting it from the fixed-pole optimum (stages 9, 12 only) ended at kappa2 18.9,
        # from the placement start at 1.27
        hb = [] if deadline.expired else _run_start(region_cache[st], L0, objective, region_opts, check,
                                                    stages=REGION_STAGES, deadline=deadline)
        hist += hb
        checked = [(check(c), c) for c in hb]
        okb = [(obj, c) for (ok, obj), c in checked if ok]
        if okb and observable:
            cb = min(okb, key=lambda t: t[0])[1]
            Pb = np.linalg.eigvals(plant.A - cb.L @ plant.C)
            hist += fixed_at(Pb, cb.L)
            Lyt = placement_start(plant, Pb, "YT") if mask is None else None
            if Lyt is not None:  # robust placement at the same poles may sit in a better basin
                hist += fixed_at(Pb, Lyt)
        return hist

    records, evaluated = _solve_starts(start_list, runner, objective, evaluate, deadline,
                                       objective_lower_bound(objective, n))
    return _result_from(plant, records, evaluated, objective=objective, target=None, region=region,
                        deadline=deadline, planned=len(start_list))


def _fixed_starts(plant, target, starts, rng, pstruct):
    out = []
    for method in ("YT", "KNV0"):
        if len(out) >= starts:
            break
        if method == "KNV0" and np.any(target.imag != 0):
            continue
        L0 = placement_start(plant, target, method)
        if L0 is not None:
            out.append((method, L0, pstruct))
    tries = 0
    while len(out) < starts and tries < 10 * starts:
        tries += 1
        try:
            L0 = random_gain_for_poles(plant, target, rng)
        except (np.linalg.LinAlgError, ValueError):
            continue
        if np.all(np.isfinite(L0)):
            out.append(("random", L0, pstruct))
    if not out:  # repeated poles YT cannot take and no random start: perturb the poles
        pert = target + 1e-3 * max(1.0, float(np.max(np.abs(target)))) * np.arange(target.size)
        L0 = placement_start(plant, as_poles("poles", pert), "YT")
        out.append(("YT (perturbed poles)", np.zeros((plant.n, plant.p)) if L0 is None else L0, pstruct))
    return out


def _riccati_start(plant: Plant, rng: np.random.Generator, k: int) -> NDArray:
    """A stabilizing Kalman gain for a random process noise (works for detectable plants).

    The filter of state-space noise ``F F' + 1e-3 I`` (``F = I`` for ``k = 0``) and ``R = I``;
    zero when :func:`~optdesign.riccati.filter_are` fails.
    """
    n, p = plant.n, plant.p
    F = rng.standard_normal((n, n)) if k else np.eye(n)
    Qs = F @ F.T + 1e-3 * np.eye(n)
    try:
        return filter_are(plant.replace(G=np.eye(n), Q=Qs, R=np.eye(p))).L
    except (ValueError, np.linalg.LinAlgError):
        return np.zeros((n, p))


def start_real_counts(n: int) -> tuple[int, ...]:
    """Numbers of real poles of the sampled region starts, in the order they are used.

    The achievable counts are ``n, n - 2, ..., n mod 2``; they are cycled through as ``n - 2``
    (one complex pair), ``n`` (all real), ``n mod 2`` (as many pairs as possible), then the
    others nearest ``n / 2`` first -- so that for ``n = 2, 3`` the first two sampled starts have
    different patterns (measured on seed 001's aircraft, n = 3: the best design has a complex
    pair, which an all-real start misses).

    Parameters
    ----------
    n : int
        Plant order, ``>= 0``.

    Returns
    -------
    tuple of int
        Distinct counts; pass the ``k``-th (cyclically) to ``Region.sample_poles(n, rng, n_real=...)``.

    Raises
    ------
    ValidationError
        ``n`` not a nonnegative integer.

    Examples
    --------
    >>> start_real_counts(3), start_real_counts(6)
    ((1, 3), (4, 6, 0, 2))
    """
    n = as_int("n", n, 0)
    counts = list(range(n, -1, -2))
    order: list[int] = []
    for c in [n - 2, n, n % 2] + sorted(counts, key=lambda c: (abs(c - n / 2), c)):
        if c in counts and c not in order:
            order.append(c)
    return tuple(order)


def start_real_count(n: int, k: int) -> int:
    """The real-pole count of the ``k``-th sampled region start (``start_real_counts(n)`` cycled).

    Examples
    --------
    >>> [start_real_count(2, k) for k in range(3)]
    [0, 2, 0]
    """
    k = as_int("k", k, 0)
    counts = start_real_counts(n)
    return counts[k % len(counts)]


def suggested_region(plant: Plant, *, decay_factor: float = 1.5, damping: float = 0.5) -> Region:
    """A pole region chosen from the plant: faster than it, damped, and bounded.

    ``HalfPlane(alpha) & Sector.from_damping(damping) & Disk(0, 2 max(rho(A), alpha))`` with
    ``alpha = decay_factor x`` the slowest open-loop decay ``min |Re lambda(A)|`` (at least 1 % of
    the spectral radius ``rho(A)``).  An unobservable mode is an eigenvalue of every ``A - LC``:
    ``alpha`` is lowered to 0.9 times its decay so that the region stays reachable.  The region of
    the COMPleib region-mode benchmark (``benchmarks/bench_placement.py``); continuous time only.

    Parameters
    ----------
    plant : Plant
        Continuous time (``plant.dt`` None).
    decay_factor : float, default 1.5
    damping : float in (0, 1), default 0.5

    Returns
    -------
    Region

    Raises
    ------
    ValidationError
        A discrete-time plant, an unobservable mode that is not stable, or a bad factor / damping.
    """
    if not isinstance(plant, Plant):
        raise ValidationError(f"plant must be an optdesign.Plant; found {type(plant).__name__}")
    if plant.is_discrete:
        raise ValidationError("suggested_region is for continuous-time plants (a half-plane and a sector); "
                              "for a discrete plant give a Disk inside the unit circle")
    factor = as_positive_float("decay_factor", decay_factor)
    w = np.linalg.eigvals(plant.A)
    rho = float(np.max(np.abs(w)))
    alpha = factor * max(float(np.min(np.abs(w.real))), 0.01 * rho)
    un = plant.unobservable_modes()
    if un.size:
        if np.max(un.real) >= 0:
            raise ValidationError(f"the unobservable mode(s) {un} are not stable: no observer is stable")
        alpha = min(alpha, 0.9 * float(np.min(-un.real)))
    return HalfPlane(alpha) & Sector.from_damping(damping) & Disk(0.0, 2.0 * max(rho, alpha))


def naive_poles(plant: Plant, region: Region) -> NDArray[np.complex128]:
    """A simple pole choice in a region: the open-loop poles moved into it.

    The reference point of region-mode designs (the design is never worse than scipy's YT
    placement at these poles, see :func:`well_conditioned_observer`).  Each eigenvalue of
    ``A`` is projected onto the region (:meth:`Region.project`) and moved 5 % of the way to
    the region's interior point ``x0`` (strictly inside, by convexity); poles within 1e-9 of
    the real axis are made real and the ``k``-th real pole (ascending, ``k = 0, 1, ...``) is
    shifted by ``-1e-3 (k + 1) |x0|`` when it stays inside.  Poles that still coincide (or
    are closer than ``1e-3`` times the region's inner radius) are moved further toward ``x0``
    until they are apart -- a pole repeated more than ``rank(C)`` times cannot be assigned
    with a diagonalizable ``A - LC``.

    Parameters
    ----------
    plant : Plant
        Uses ``A`` (n, n).
    region : Region
        The pole region (nonempty interior).

    Returns
    -------
    (n,) ndarray of complex
        Conjugate-closed, distinct poles strictly inside ``region``; real poles first (ascending),
        then pairs ``z, conj(z)`` with ``Im z > 0``.

    Raises
    ------
    ValidationError
        ``plant`` is not a Plant or ``region`` not a Region.

    References
    ----------
    ``benchmarks/bench_placement.py`` (COMPleib region mode, "YT @ naive").
    """
    plant = _check_plant(plant)
    _check_region(region)
    w = np.linalg.eigvals(plant.A)
    x0 = float(region.interior_point())
    rho = max(-float(region.distance([x0])[0]), 1e-300)  # a disk of radius rho around x0 is inside
    tau = 1e-3 * rho  # clearance from the boundary
    sep = 1e-4 * rho  # minimum distance between two poles

    def inside(c: complex) -> bool:
        return bool(region.distance([c])[0] < -tau)

    z = region.project(w)
    z = z + 0.05 * (x0 - z)
    z = np.where(np.abs(z.imag) < 1e-9, z.real + 0j, z)
    reals: list[complex] = []
    uppers: list[complex] = []
    for k, v in enumerate(sorted(z, key=lambda v: (v.real, v.imag))):
        if v.imag == 0:
            shifted = complex(v.real - 1e-3 * (k + 1) * abs(x0))
            reals.append(shifted if inside(shifted) else complex(v.real))
        elif v.imag > 0:  # one member per pair (the projection keeps conjugate symmetry)
            uppers.append(complex(v))

    def spread(poles: list[complex], step: complex) -> list[complex]:
        """Move poles that (nearly) coincide with an earlier one toward x0 until they are apart."""
        out: list[complex] = []
        for v in poles:
            c = v
            for m in range(1, 1000):
                if inside(c) and all(abs(c - a) > sep for a in out):
                    break
                if abs(v - x0) > 20 * sep:
                    c = v + min(0.05 + 0.01 * m, 0.95) * (x0 - v)
                else:  # next to x0: step inside the disk of radius rho around it
                    c = v + ((m + 1) // 2) * sep * step * (1 if m % 2 else -1)
            out.append(c)
        return out

    re = sorted(c.real for c in spread(reals, 1.0))
    cp = sorted(spread(uppers, 1j), key=lambda c: (c.real, c.imag))
    cp = [c if c.imag > 0 else complex(c.real, sep) for c in cp]
    res = np.empty(len(re) + 2 * len(cp), dtype=complex)
    res[: len(re)] = re
    res[len(re) :: 2] = cp
    res[len(re) + 1 :: 2] = np.conj(cp)
    return res


def _region_starts(plant, region, starts, rng, mask):
    """Start 0: scipy YT at :func:`naive_poles`; start 1: the Kalman gain for ``Q = I, R = I``;
    then YT at poles sampled in the region (real/complex patterns of :func:`start_real_counts`).

    Measured on COMPleib (region of ``benchmarks/bench_placement.py``): AC7 ends at kappa2 22.8
    from the Kalman start, at 3e6 from sampled poles; HE5 at 76 from the naive start.
    """
    n = plant.n
    observable = plant.is_observable()
    out = []
    kalman_used = False
    n_sampled = 0
    for k in range(starts):
        if k == 1 and not kalman_used:
            L0 = _riccati_start(plant, rng, 0)
            st = PoleStructure.of(np.linalg.eigvals(plant.A - L0 @ plant.C), tol=1e-6)
            origin = "Kalman gain (Q = I)"
            kalman_used = True
        else:
            if k == 0:
                P0 = naive_poles(plant, region)
                origin = "naive poles + YT"
            else:
                P0 = region.sample_poles(n, rng, n_real=start_real_count(n, n_sampled))
                n_sampled += 1
                origin = "region sample + YT"
            st = PoleStructure.of(P0)
            L0 = placement_start(plant, P0, "YT") if observable else None
            if k == 0 and L0 is not None:
                L0 = _better_yt(plant, P0, L0, region)
            if L0 is None and observable:
                try:
                    L0 = random_gain_for_poles(plant, P0, rng)
                    origin = origin.replace("+ YT", "+ random assignment")
                except (np.linalg.LinAlgError, ValueError):
                    L0 = None
            if L0 is None:  # detectable but unobservable (or placement failed): a Kalman gain
                L0 = _riccati_start(plant, rng, 0 if not kalman_used else k)
                origin = "Kalman gain (Q = I)" if not kalman_used else "Kalman gain (random Q)"
                kalman_used = True
                st = PoleStructure.of(np.linalg.eigvals(plant.A - L0 @ plant.C), tol=1e-6)
        if mask is not None:
            L0 = np.where(mask, L0, 0.0)
            st = PoleStructure.of(np.linalg.eigvals(plant.A - L0 @ plant.C), tol=1e-6)
        out.append((origin, L0, st))
    return out


def well_conditioned_kalman(
    plant: Plant,
    *,
    region: Region | None = None,
    objective: str = "eta",
    q_structure: str = "scalar",
    kappa2_max: float | None = None,
    eta_max: float | None = None,
    q_range: tuple[float, float] = (1e-3, 1e3),
    starts: int = 4,
    seed: int = 0,
    solver: str = "ipopt",
    options: dict[str, Any] | None = None,
    time_limit: float | None = None,
) -> ObserverDesign:
    """A steady-state Kalman filter whose error dynamics are well conditioned.

    The process-noise covariance is the design variable (``R`` stays the plant's): the NLP
    minimizes the chosen metric of ``A - L C`` subject to the filter Riccati equation
    (continuous ARE, or the predictor DARE when ``plant.dt`` is set), ``P >= 0`` (Cholesky
    factor), ``Q >= 0`` and optional pole-region and metric bounds -- so the result is a true
    Kalman filter for the returned ``Q``, not merely an observer.

    Parameters
    ----------
    plant : Plant
        ``A, C, G`` and ``R`` (identity when absent); with ``q_structure="scalar"`` the design is
        ``Q = q Q0`` with ``Q0 = plant.Q`` (identity when absent), i.e. seed 001's ``q/r``.
    region : Region, optional
        The filter poles must lie in it; it must lie in the closed stability region of the
        plant's time domain (ValidationError otherwise, as in :func:`well_conditioned_observer`).
    objective : {"eta", "kappa2", "kappa_fro"}, default "eta"
    q_structure : {"scalar", "diagonal", "full"}
        ``Q = q Q0``; ``Q = diag(q)``; ``Q = F F'`` (lower-triangular ``F``).
    kappa2_max, eta_max : float, optional
        Trade-off bounds.
    q_range : (float, float)
        Range of the scalar multipliers of ``Q0`` used as starting points (log-spaced).
    starts : int, default 4
    seed : int, default 0
    solver : {"ipopt"}
    options : dict, optional
        IPOPT options (string keys), merged over the defaults.
    time_limit : float, optional
        Seconds of wall time (None: no limit); see :func:`well_conditioned_observer`.

    Returns
    -------
    ObserverDesign
        With ``Q``, ``P``, ``R``; verification adds the Riccati residual (recomputed with
        :func:`optdesign.riccati.filter_are_residual`), ``P >= 0``, ``Q >= 0`` and the gain
        against an independent Riccati solve for the returned ``Q``.  Status as for
        :func:`well_conditioned_observer` (``not_found`` when no start gave a verified filter,
        ``time_limit`` when the budget ran out).

    Raises
    ------
    ValidationError
        Unknown objective, q_structure or solver; bad bounds, ``options`` or ``time_limit``;
        ``q_range`` not two numbers ``0 < lo <= hi < inf``; a region reaching outside the
        stability region.
    NotObservableError
        ``(C, A)`` not detectable.

    References
    ----------
    Seed 001, section 2.3 and Example 2 (the gain depends on ``q/r`` only, eq 29).
    """
    deadline = Deadline(as_time_limit(time_limit))
    plant = _check_plant(plant)
    check_objective(objective)
    check_q_structure(q_structure)
    _check_solver(solver)
    starts = as_int("starts", starts, 1)
    seed = as_int("seed", seed, 0)
    eta_max = None if eta_max is None else as_positive_float("eta_max", eta_max)
    kappa2_max = _kappa2_bound(kappa2_max)
    opts = _ipopt_options(options)
    if region is not None:
        check_region_stable(_check_region(region), plant.is_discrete)
    lo, hi = _check_q_range(q_range)
    plant.require_observable(detectable_ok=True, what="a well-conditioned Kalman filter")
    R = plant.R if plant.R is not None else np.eye(plant.p)
    Q0 = plant.Q if plant.Q is not None else np.eye(plant.m)
    base = plant.replace(R=R, Q=Q0)
    start_list = _kalman_starts(base, q_structure, lo, hi, starts, np.random.default_rng(seed))

    def build(st):
        return build_kalman_nlp(base, st, objective=objective, q_structure=q_structure, region=region,
                                kappa2_max=kappa2_max, eta_max=eta_max,
                                scaling=NLPScaling.identity(base.n, base.p))

    evaluate = partial(
        evaluate_candidate, base, target=None, region=region, mask=None, max_gain=None,
        kappa2_max=kappa2_max, eta_max=eta_max,
    )
    records: list[StartRecord] = []
    evaluated = []
    cache: dict[Any, Any] = {}
    qinfo: dict[int, tuple[NDArray, NDArray]] = {}
    for idx, (origin, init, st) in enumerate(start_list):
        if idx and deadline.expired:
            break
        if st not in cache:
            cache[st] = build(st)
        run = _kalman_start(cache[st], init, objective, opts, evaluate, deadline, force=idx == 0)
        if run is None:
            continue
        cand, qinfo[idx] = run
        mtr, v = evaluate(cand)
        v = v + _kalman_checks(base, cand.L, *qinfo[idx])
        obj = _metric_of(objective, mtr)
        records.append(_start_record(idx, origin, cand, mtr, v, obj, cand.message))
        evaluated.append((obj, idx, mtr, v, cand))
    nan_qp = (np.full((plant.m, plant.m), np.nan), np.full((plant.n, plant.n), np.nan))
    Qb, Pb = qinfo[pick_best(evaluated)[1]] if evaluated else nan_qp
    return _result_from(base, records, evaluated, objective=objective, target=None, region=region,
                        deadline=deadline, planned=len(start_list),
                        kalman={"Q": Qb, "P": Pb, "R": np.asarray(R, dtype=float)})


def _check_q_range(q_range: Any) -> tuple[float, float]:
    """``(lo, hi)`` with ``0 < lo <= hi < inf`` from a pair of numbers."""
    if isinstance(q_range, (str, bytes)) or not hasattr(q_range, "__len__") or len(q_range) != 2:
        raise ValidationError(f"q_range must be a pair (lo, hi) of numbers; found {q_range!r}")
    try:
        lo, hi = (as_positive_float("q_range", q_range[0], allow_zero=True),
                  as_positive_float("q_range", q_range[1], allow_zero=True))
    except ValidationError:
        raise ValidationError(f"q_range must be a pair (lo, hi) of numbers; found {q_range!r}") from None
    if not (0 < lo <= hi):
        raise ValidationError(f"q_range must satisfy 0 < lo <= hi < inf; found {q_range!r}")
    return lo, hi


def _kalman_starts(base: Plant, q_structure: str, lo: float, hi: float, starts: int, rng) -> list:
    """Kalman filters for log-spaced multiples of ``Q0`` (random diagonal jitter): ``(origin, (P, theta, L),
    structure)`` per start whose Riccati equation has a solution.

    Raises
    ------
    ValidationError
        No start has one.
    """
    m = base.m
    Q0 = np.asarray(base.Q, dtype=float)
    mults = np.geomspace(lo, hi, starts) if starts > 1 else np.array([math.sqrt(lo * hi)])
    start_list = []
    for k, q in enumerate(mults):
        if q_structure == "scalar":
            Qs = q * Q0
            theta0: Any = q
        elif q_structure == "diagonal":
            d = q * np.maximum(np.diag(Q0), 1e-6) * (np.exp(0.3 * rng.standard_normal(m)) if k else 1.0)
            Qs = np.diag(d)
            theta0 = d
        else:
            Qs = q * Q0
            F = np.linalg.cholesky(Qs + 1e-12 * np.eye(m))
            theta0 = np.array([F[i, j] for i in range(m) for j in range(i + 1)])
        try:
            are = filter_are(base.replace(Q=Qs))
        except (ValueError, np.linalg.LinAlgError):
            continue
        st = PoleStructure.of(are.poles, tol=1e-7)
        start_list.append((f"riccati q={q:.3g}", (are.P, theta0, are.L), st))
    if not start_list:
        raise ValidationError(
            "no Riccati solution exists for any starting noise level in q_range; "
            "check detectability and that G Q G' excites the plant's modes"
        )
    return start_list


def _kalman_start(knlp, init, objective: str, opts, evaluate, deadline: Deadline, force: bool):
    """One start of the Kalman NLP through its continuation: ``(candidate, (Q, P))`` -- the best verified
    stage (with the start's iteration and time totals), else the last one; None when the deadline
    expired before its first stage (which runs anyway with ``force``)."""
    n, m = knlp.plant.n, knlp.plant.m
    knlp.set_initial(*init)
    plan, set_stage, _ = _stage_plan(knlp.obs, objective, None)
    hist: list[Candidate] = []
    best = None
    good = None
    nan_q = (np.full((m, m), np.nan), np.full((n, n), np.nan))
    qp, best_qp = nan_q, None
    for J in plan:
        if deadline.expired and (hist or not force):
            break
        if J is not None:
            set_stage(J)
        if good is not None:
            knlp.obs.warm_start(good[0])
            knlp.opti.set_initial(knlp.Fp, good[1])
            knlp.opti.set_initial(knlp.theta, good[2])
        rep = solve_nlp(knlp.obs, opts, deadline)
        stage = "" if J is None else f"J={J}"
        c, readable = _read_candidate(knlp.obs, rep, stage)
        if readable:
            try:
                qp = (knlp.noise(rep.value), np.asarray(rep.value(knlp.P), dtype=float).reshape(n, n))
            except RuntimeError as exc:  # CasADi cannot evaluate the iterate
                c, readable = _solver_error_candidate(knlp.plant, rep, exc, stage), False
        hist.append(c)
        if not readable:
            qp = nan_q
            break
        if evaluate(c)[1].passed:
            good = (knlp.obs.snapshot(rep.value), np.asarray(rep.value(knlp.Fp), dtype=float),
                    np.asarray(rep.value(knlp.theta), dtype=float))
            best, best_qp = c, qp
    if not hist:
        return None
    cand = best if best is not None else hist[-1]
    cand = dataclasses.replace(cand, iterations=sum(h.iterations for h in hist),
                               time=sum(h.time for h in hist))
    return cand, (best_qp if best is not None else qp)


def _kalman_checks(plant: Plant, L: NDArray, Q: NDArray, P: NDArray) -> Verification:
    checks = []
    if not (np.all(np.isfinite(Q)) and np.all(np.isfinite(P)) and np.all(np.isfinite(L))):
        return Verification.of(
            [Check.at_most("finite_noise", float("inf"), 0.0, "Q, P or L has NaN/Inf entries")]
        )
    Qs = 0.5 * (Q + Q.T)
    Ps = 0.5 * (P + P.T)
    scaleQ = max(1.0, float(np.max(np.abs(Qs)))) if Qs.size else 1.0
    scaleP = max(1.0, float(np.max(np.abs(Ps))))
    checks.append(Check.at_least("Q_min_eig", float(np.linalg.eigvalsh(Qs)[0]), -1e-9 * scaleQ, "Q >= 0"))
    checks.append(Check.at_least("P_min_eig", float(np.linalg.eigvalsh(Ps)[0]), -1e-9 * scaleP, "P >= 0"))
    try:
        res = filter_are_residual(plant, Ps, Q=Qs)
    except (ValueError, np.linalg.LinAlgError) as exc:
        res = float("inf")
        checks.append(Check.at_most("riccati_residual", res, 1e-7, f"residual failed: {exc}"))
    else:
        checks.append(Check.at_most("riccati_residual", res, 1e-7, "relative residual of the filter ARE"))
    try:
        ref = filter_are(plant.replace(Q=Qs))
        dl = float(np.linalg.norm(L - ref.L) / max(np.linalg.norm(ref.L), 1e-300))
        checks.append(
            Check.at_most(
                "gain_vs_riccati", dl, 1e-5, "||L - L_ARE(Q)|| / ||L_ARE(Q)||, independent Riccati solve"
            )
        )
    except (ValueError, np.linalg.LinAlgError) as exc:
        checks.append(Check.at_most("gain_vs_riccati", float("inf"), 1e-5, f"Riccati solve failed: {exc}"))
    return Verification.of(checks)
