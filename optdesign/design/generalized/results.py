"""Results of the generalized-observer designs (:mod:`optdesign.design.generalized`):
:class:`GeneralizedObserver` (and :func:`build_generalized`, its verified construction),
:class:`NoiseRejectingObserver` and :class:`ObserverSimulation`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..._validate import as_matrix
from ...classical.placement import pole_error
from ...errors import ValidationError
from ...model.noise import NoiseModel
from ...model.plant import Plant
from ...results import Check, DesignResult, Route, SolverStats, Stage, Status, Verification
from .common import (
    STABILITY_TOL,
    check_discrete_plant,
    check_noise,
    distinct_modes,
    internal_model_residual,
    kappa2_of,
    readonly,
    sorted_eigs,
)

__all__ = ["GeneralizedObserver", "NoiseRejectingObserver", "ObserverSimulation", "build_generalized"]


# --------------------------------------------------------------------------- results
@dataclass(frozen=True, kw_only=True, eq=False)
class GeneralizedObserver(DesignResult):
    r"""A generalized observer (seed 003 eq (2)) and its independent verification.

    Runs as ``xh(k+1) = A xh + B u + K xi + H eps``, ``xi(k+1) = N xi + M eps``,
    ``eps = y - C xh`` (see :meth:`step`).

    Attributes
    ----------
    plant : Plant
    noise : NoiseModel
    H : (n, p) ndarray
        Proportional (innovation) gain.
    K : (n, r p) ndarray
        Gain of the internal-model state ``xi``.
    N : (r p, r p) ndarray
    M : (r p, p) ndarray
        Realization of the noise model (:meth:`NoiseModel.realization`).
    augmented : (n + r p, n + r p) ndarray
        ``F = [[A - H C, -K], [M C, N]]``, the error dynamics of ``[x - xh; xi]``.
    poles : (n + r p,) ndarray of complex
        Eigenvalues of ``F`` (numpy, sorted).
    spectral_radius : float
        ``max |poles|``; ``< 1`` is seed 003's design condition (Theorem 1).
    kappa2 : float
        Condition number of the unit-column eigenvector matrix of ``F``.
    target_poles : ndarray or None
        The poles asked for (``method="place"``).
    coupling : (n, r p) ndarray or None
        The coupling ``E`` of the placement pair ``(C_a, A_a)`` (None for given gains).
    coupling_kind : str
        ``"output"``, ``"direct"``, ``"zero_free"``, ``"given"`` (an explicit E) or ``"none"``
        (given gains).
    method : str
        ``"place"``, ``"well_conditioned"`` or ``"given"``.
    status, message, verification, solver_stats
        As every design result; ``success`` needs a solved status and every check passed.
    design : object or None
        The underlying :class:`~optdesign.design.well_conditioned.ObserverDesign` of the augmented
        pair (``method="well_conditioned"``).

    Notes
    -----
    Under output noise of the modelled class a *stable* generalized observer drives the
    innovation ``eps = y - C xh`` to zero (internal model principle), hence ``C xh`` follows the
    noisy ``y`` and the state error does **not** vanish: ``C (x - xh) -> -delta``.  See the module
    docstring, :meth:`innovation_gain` and :meth:`error_gain`.
    """

    plant: Plant
    noise: NoiseModel
    H: NDArray[np.float64]
    K: NDArray[np.float64]
    N: NDArray[np.float64]
    M: NDArray[np.float64]
    augmented: NDArray[np.float64]
    poles: NDArray[np.complex128]
    spectral_radius: float
    kappa2: float
    method: str = "place"
    coupling: NDArray[np.float64] | None = None
    coupling_kind: str = "none"
    design: Any = None

    # ---------------------------------------------------------------- sizes
    @property
    def n(self) -> int:
        return self.plant.n

    @property
    def p(self) -> int:
        return self.plant.p

    @property
    def is_stable(self) -> bool:
        """True when ``F`` is Schur (spectral radius < 1)."""
        return bool(self.spectral_radius < 1.0)

    # --------------------------------------------------------- frequency maps
    def _transfer(self, z: complex) -> NDArray[np.complex128]:
        """(z I - F)^{-1} [-H; M], shape (n + r p, p)."""
        Bd = np.vstack([-self.H, self.M]).astype(complex)
        return np.asarray(np.linalg.solve(z * np.eye(self.augmented.shape[0]) - self.augmented, Bd),
                          dtype=np.complex128)

    def error_gain(self, z: complex) -> NDArray[np.complex128]:
        """Transfer from the output noise ``delta`` to the state error ``x - xh`` at ``z``, shape (n, p).

        For a noise mode ``z`` and a stable observer, ``delta(k) = Re(v z^k)`` produces the
        steady-state error ``Re(error_gain(z) v z^k)``; ``C error_gain(z) = -I`` at every noise mode.
        """
        return self._transfer(complex(z))[: self.n]

    def innovation_gain(self, z: complex) -> NDArray[np.complex128]:
        """Transfer from ``delta`` to the innovation ``eps = y - C xh`` at ``z``, shape (p, p).

        Zero at every noise mode (internal model principle): ``eps -> 0``.
        """
        return np.eye(self.p) + self.plant.C @ self.error_gain(z)

    # ------------------------------------------------------------------ run
    def step(self, xhat: ArrayLike, xi: ArrayLike, y: ArrayLike, u: ArrayLike | None = None
             ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """One observer update: returns ``(xh(k+1), xi(k+1))`` from ``xh(k), xi(k), y(k), u(k)``."""
        xhat = np.asarray(xhat, dtype=float)
        xi = np.asarray(xi, dtype=float)
        eps = np.asarray(y, dtype=float).reshape(-1) - self.plant.C @ xhat
        nxt = self.plant.A @ xhat + self.K @ xi + self.H @ eps
        if u is not None:
            if self.plant.B is None:
                raise ValidationError("u given but the plant has no B")
            nxt = nxt + self.plant.B @ np.atleast_1d(np.asarray(u, dtype=float))
        return nxt, self.N @ xi + self.M @ eps

    # ------------------------------------------------------------ analysis
    @classmethod
    def from_gains(cls, plant: Plant, noise: NoiseModel, H: ArrayLike, K: ArrayLike, *,
                   M: ArrayLike | None = None) -> GeneralizedObserver:
        """Analyse given gains (e.g. printed ones): the augmented matrix, its spectral radius,
        the internal-model check; ``success`` is False when ``F`` is not Schur.

        Parameters
        ----------
        plant : Plant
            Discrete time.
        noise : NoiseModel
        H : (n, p) array_like
        K : (n, r p) array_like
        M : (r p, p) array_like, optional
            Default: the model's ``e_r kron I_p``.

        Raises
        ------
        ValidationError, DimensionError
            Bad plant, noise model or gain shapes.
        """
        plant = check_discrete_plant(plant, "a generalized observer")
        noise = check_noise(noise, plant)
        n, p, rp = plant.n, plant.p, noise.order * plant.p
        N, M0, _ = noise.realization(p)
        H = as_matrix("H", H, (n, p))
        K = as_matrix("K", K, (n, rp))
        M = M0 if M is None else as_matrix("M", M, (rp, p))
        return build_generalized(plant, noise, H, K, N, M, method="given", status=Status.SOLVED,
                                  message="given gains (analysed, not designed)",
                                  stats=SolverStats("analytic", "given"))

    def _headline(self) -> str:
        return (f"GeneralizedObserver({self.noise.label}, method={self.method}, status={self.status}, "
                f"spectral radius {self.spectral_radius:.6g}, kappa2 {self.kappa2:.4g}, "
                f"success={self.success})")

    def summary(self) -> str:
        return f"{self._headline()}\n  route: {self.route}\n{self.verification.summary()}"

    def __repr__(self) -> str:
        return self._headline()


def build_generalized(plant, noise, H, K, N, M, *, method, status, message, stats, target=None,
                       coupling=None, coupling_kind="none", extra_checks=(), design=None,
                       region=None) -> GeneralizedObserver:
    """The :class:`GeneralizedObserver` of gains ``H``, ``K`` for ``(N, M)``, with its independent checks
    (Schur stability of ``F``, internal model, target poles, region) and ``extra_checks``."""
    A, C = plant.A, plant.C
    F = np.block([[A - H @ C, -K], [M @ C, N]])
    poles = sorted_eigs(F)
    rho = float(np.max(np.abs(poles)))
    checks = [Check.at_most("spectral_radius", rho, 1.0 - STABILITY_TOL,
                            "Schur stability of F = [[A - HC, -K], [MC, N]] (seed 003 Theorem 1)")]
    modes = distinct_modes(noise)
    if rho < 1.0:
        Cout = np.hstack([C, np.zeros((plant.p, N.shape[0]))])
        res, tol = internal_model_residual(F, Cout, np.vstack([-H, M]), np.eye(plant.p), modes)
        checks.append(Check.at_most("internal_model", res, tol,
                                    "||delta -> eps transfer|| at the noise modes "
                                    "(eps -> 0 under the modelled noise)"))
    if target is not None:
        checks.append(Check.at_most("pole_error", pole_error(poles, target), 1e-6,
                                    "max relative distance of eig(F) to the target poles"))
    if region is not None:
        checks.append(Check.at_most("region_margin", float(region.margin(poles)), 1e-9,
                                    f"max signed distance of eig(F) to {region!r} (<= 0 inside)"))
    checks.extend(extra_checks)
    ro = readonly
    return GeneralizedObserver(
        plant=plant, noise=noise, H=ro(H), K=ro(K), N=ro(N), M=ro(M), augmented=ro(F), poles=ro(poles),
        spectral_radius=rho, kappa2=kappa2_of(F), status=status, message=message,
        verification=Verification.of(checks), solver_stats=stats, method=method,
        target_poles=None if target is None else ro(target),
        coupling=None if coupling is None else ro(coupling), coupling_kind=coupling_kind, design=design,
        route=design_route(method, stats))


def design_route(method: str, stats: SolverStats) -> Route:
    """The one stage of a generalized observer's design: a placement, the well-conditioned design of
    the augmented pair, or the given gains checked."""
    kind = {"place": "direct", "well_conditioned": "engine"}.get(method, "check")
    return Route([Stage(f"{method}/{stats.backend}" if stats.backend else method, kind, "answered",
                        stats.native_status)])


@dataclass(frozen=True, kw_only=True, eq=False)
class NoiseRejectingObserver(DesignResult):
    r"""An observer of the plant augmented with an output-disturbance model of the noise.

    Runs as ``[xh; dh](k+1) = A_a [xh; dh] + [B; 0] u + L_a (y - C_a [xh; dh])`` with
    ``A_a = diag(A, N)``, ``C_a = [C, Gamma]``; ``xh -> x`` and ``Gamma dh -> delta`` for every
    noise of the modelled class (when ``A_a - L_a C_a`` is Schur).

    Attributes
    ----------
    plant : Plant
    noise : NoiseModel
    L : (n + r p, p) ndarray
        The augmented gain ``[L_x; L_d]``.
    A_aug : (n + r p, n + r p) ndarray
    C_aug : (p, n + r p) ndarray
    N : (r p, r p) ndarray
    Gamma : (p, r p) ndarray
    poles : ndarray of complex
        Eigenvalues of ``A_aug - L C_aug``.
    spectral_radius, kappa2 : float
    pbh_margin : float
        ``min_lambda sigma_min([lambda I - A_a; C_a]) / scale`` over the noise modes: how far the
        noise modes are from being confused with the plant's (0 = indistinguishable).
    target_poles, method, status, message, verification, solver_stats, design
        As :class:`GeneralizedObserver`.
    """

    plant: Plant
    noise: NoiseModel
    L: NDArray[np.float64]
    A_aug: NDArray[np.float64]
    C_aug: NDArray[np.float64]
    N: NDArray[np.float64]
    Gamma: NDArray[np.float64]
    poles: NDArray[np.complex128]
    spectral_radius: float
    kappa2: float
    pbh_margin: float
    method: str = "place"
    design: Any = None

    @property
    def Lx(self) -> NDArray[np.float64]:
        """State part of the gain, (n, p)."""
        return self.L[: self.plant.n]

    @property
    def Ld(self) -> NDArray[np.float64]:
        """Noise-state part of the gain, (r p, p)."""
        return self.L[self.plant.n:]

    def step(self, xa: ArrayLike, y: ArrayLike, u: ArrayLike | None = None) -> NDArray[np.float64]:
        """One update of the augmented estimate ``[xh; dh]``."""
        xa = np.asarray(xa, dtype=float)
        nu = np.asarray(y, dtype=float).reshape(-1) - self.C_aug @ xa
        nxt = self.A_aug @ xa + self.L @ nu
        if u is not None:
            if self.plant.B is None:
                raise ValidationError("u given but the plant has no B")
            nxt[: self.plant.n] += self.plant.B @ np.atleast_1d(np.asarray(u, dtype=float))
        return nxt

    def _headline(self) -> str:
        return (f"NoiseRejectingObserver({self.noise.label}, method={self.method}, status={self.status}, "
                f"spectral radius {self.spectral_radius:.6g}, PBH margin {self.pbh_margin:.3g}, "
                f"success={self.success})")

    def summary(self) -> str:
        return f"{self._headline()}\n  route: {self.route}\n{self.verification.summary()}"

    def __repr__(self) -> str:
        return self._headline()


@dataclass(frozen=True, eq=False)
class ObserverSimulation:
    """Trajectories of plant + observer under a given output noise (:func:`simulate_observer`).

    All arrays have one row per sample ``k = 0..T-1``.

    Attributes
    ----------
    t : (T,) ndarray
        ``k dt``.
    x, xhat : (T, n) ndarray
        Plant state and its estimate.
    y : (T, p) ndarray
        Measured output ``C x + delta``.
    delta : (T, p) ndarray
        The output noise.
    eps : (T, p) ndarray
        ``y - C xhat`` (seed 003's innovation, for every observer kind).
    internal : (T, q) ndarray
        The observer's extra state: ``xi`` (generalized), ``dh`` (noise rejecting), empty (plain).
    noise_estimate : (T, p) ndarray or None
        ``Gamma dh`` for the noise-rejecting observer, else None.
    kind : str
        ``"generalized"``, ``"noise_rejecting"`` or ``"luenberger"``.
    C : (p, n) ndarray
    """

    t: NDArray[np.float64]
    x: NDArray[np.float64]
    xhat: NDArray[np.float64]
    y: NDArray[np.float64]
    delta: NDArray[np.float64]
    eps: NDArray[np.float64]
    internal: NDArray[np.float64]
    noise_estimate: NDArray[np.float64] | None
    kind: str
    C: NDArray[np.float64]

    @property
    def error(self) -> NDArray[np.float64]:
        """State estimation error ``x - xhat``, (T, n)."""
        return self.x - self.xhat

    @property
    def output_error(self) -> NDArray[np.float64]:
        """``C xhat - C x`` (estimate vs noise-free output), (T, p)."""
        return self.xhat @ self.C.T - self.x @ self.C.T

    @property
    def tracking(self) -> NDArray[np.float64]:
        """``C xhat - y`` (estimate vs *noisy* measurement) ``= -eps``, (T, p)."""
        return -self.eps

    def tail(self, signal: str, fraction: float = 0.25) -> float:
        """``max |signal|`` over the last ``fraction`` of the run (e.g. ``tail("error")``).

        ``signal`` is any array attribute or property name: ``error``, ``eps``, ``tracking``,
        ``output_error``, ``internal``, ``delta``, ...
        """
        if not 0.0 < float(fraction) <= 1.0:
            raise ValidationError(f"fraction must be in (0, 1]; found {fraction!r}")
        X = getattr(self, signal)
        if X is None:
            raise ValidationError(f"{signal!r} is not available for a {self.kind} observer")
        X = np.asarray(X)
        k0 = int(math.floor(X.shape[0] * (1.0 - float(fraction))))
        return float(np.max(np.abs(X[k0:]))) if X[k0:].size else 0.0


