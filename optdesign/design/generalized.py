r"""Generalized observers with an output-noise model (seed 003), and an observer that really
rejects the noise.

The plant is discrete time, its output corrupted by a persistent noise of known class
(:mod:`optdesign.noise`)::

    x(k+1) = A x(k) + B u(k),      y(k) = C x(k) + delta(k),      P(q) delta = 0.

Generalized observer (seed 003 eq (2))
--------------------------------------
::

    xh(k+1) = A xh + B u + K xi + H eps,     xi(k+1) = N xi + M eps,     eps = y - C xh,

with ``(N, M)`` the realization of the noise model (:meth:`NoiseModel.realization`).  With
``e = x - xh`` the error system is

.. math::

    \begin{bmatrix} e \\ \xi \end{bmatrix}(k+1) =
    \underbrace{\begin{bmatrix} A - HC & -K \\ MC & N \end{bmatrix}}_{F}
    \begin{bmatrix} e \\ \xi \end{bmatrix}(k) +
    \begin{bmatrix} -H \\ M \end{bmatrix} \delta(k),
    \qquad \varepsilon = [C\ 0] \begin{bmatrix} e \\ \xi \end{bmatrix} + \delta ,

and the design condition is that ``F`` is Schur (seed 003 Theorem 1, eq (4)).

**What it guarantees under output noise (internal model principle).**  Because every mode
``lambda`` of the noise is a mode of ``N`` and ``(N, M)`` is controllable, the transfer from
``delta`` to the innovation ``eps`` vanishes there,
``I + [C 0](lambda I - F)^{-1} [-H; M] = 0`` (verified for every design as the
``internal_model`` check).  Hence, for every stable design and every noise of the class:

* ``eps = y - C xh -> 0``, i.e. ``C xh - y -> 0``: the estimate reproduces the **noisy**
  measurement;
* therefore ``C e -> -delta``: the state error ``x - xh`` does **not** converge to zero, and
  ``C xh - C x -> delta``;
* ``xi`` converges to a persistent non-zero signal (it carries the noise).

So the seed's claims (3a) ``x - xh -> 0`` and (3b) ``xi -> 0`` hold only without noise.  What
the seed's proof (eq (13)-(19)) actually shows is ``P(q) e -> 0``: the error converges to a
signal of the noise class, not to zero.  The simulation tests establish this; the example
figure shows it.

**Pole placement as an ordinary observer design.**  For a free *coupling* matrix ``E``
(n, r p) and any ``S`` commuting with ``N``, ``T = diag(I_n, S)`` gives

.. math::

    T F T^{-1} = \begin{bmatrix} A - HC & -K S^{-1} \\ S M C & N \end{bmatrix}
               = A_a - L_a C_a, \quad
    A_a = \begin{bmatrix} A & E \\ 0 & N \end{bmatrix}, \;
    C_a = [C\ \ 0], \;
    L_a = \begin{bmatrix} H \\ -S M \end{bmatrix}, \; K = -E S .

Equivalently, and without any choice, ``F = A_s - L_s C_s`` with ``A_s = [[A, 0], [MC, N]]``,
``C_s = diag(C, I)`` and the *structured* gain ``L_s = [[H, K], [0, 0]]`` (:func:`structured_pair`);
``(C_s, A_s)`` is observable iff ``(C, A)`` is, but the zero rows of ``L_s`` make it a structured
placement, which the pair below turns into an ordinary one.  ``method="well_conditioned"``
optimizes over this structured gain (the NLP's ``kappa2`` is then that of ``F`` itself).

So ``method="place"`` places the poles of the pair ``(C_a, A_a)`` (the observer of a plant
driven by an *input* disturbance ``d(k+1) = N d`` entering through ``E``), takes
``H = L_1``, solves ``S N = N S, S M = -L_2`` for ``S`` (unique: ``(N, M)`` is controllable and
``N`` cyclic per channel; invertible whenever no placed pole is a noise mode) and sets
``K = -E S``.  ``(C_a, A_a)`` is observable iff ``(C, A)`` is observable and, for every noise
mode ``lambda``, ``[[lambda I - A, -E V_lambda], [C, 0]]`` is nonsingular (``V_lambda`` spans the
eigenvectors of ``N`` at ``lambda``).  With ``rank C = p`` a suitable ``E`` always exists, so
seed 003's Theorem 2 holds -- a generalized observer with arbitrary poles exists iff
``(C, A)`` is observable (and ``rank C = p``), **whatever the noise modes**, even when a noise
mode is a plant mode.  (Its proof is wrong, though: eq (23), ``rank(sI - QNQ^{-1}) = n`` for all
``s``, fails at every noise mode; it is the free ``E``, the seed's ``P``, that saves the
conclusion.)  Necessity: an unobservable mode of ``(C, A)`` is an eigenvalue of ``F`` for all
``H, K``.  If ``rank C < p``, the difference of two channels' internal models is unobservable
and ``F`` keeps the noise modes on the unit circle.

The coupling decides *where* the noise goes.  ``coupling="output"`` (default) takes
``E = Pi N - A Pi`` with ``Pi = C^+ Gamma``: then ``(C_a, A_a)`` is similar to the
output-disturbance pair below, and ``x - xh -> -C^+ delta``: the error is confined to the
measured directions (for ``C = [I 0]`` the unmeasured states converge exactly, only the
measured ones follow the noisy ``y``).  It is impossible when a noise mode is a plant mode;
then ``"direct"`` (``E = [C^+, 0, ...]``, the direction of seed 003's printed step gain ``K``) or
``"zero_free"`` (``E = [E_1, 0, ...]`` with ``C A^k E_1 = 0`` for ``k < n - 1``,
``C A^(n-1) E_1 = I``: ``(A, E_1, C)`` has no finite invariant zero, so the pair is observable at
every noise mode) serves, as does any explicit (n, r p) array.

Noise-rejecting observer (output-disturbance model)
---------------------------------------------------
To make ``xh -> x`` the noise must be *estimated* as part of the state: with
``d(k+1) = N d(k)``, ``delta = Gamma d``::

    [x; d](k+1) = diag(A, N) [x; d] + [B; 0] u,     y = [C  Gamma] [x; d],

an ordinary (predictor) observer with gain ``L_a = [L_x; L_d]`` for this pair gives
``[x - xh; d - dh] -> 0`` for every noise of the class.  The pair is observable iff ``(C, A)``
is observable and **no noise mode is a plant mode** (otherwise an output offset of that
mode is indistinguishable from the plant's own response; :class:`NotObservableError` names
the conflict).

References
----------
Kim, H. S., Lee, C. H. & Kim, S. B., "A Study on Generalized Observer Structure and its
Characteristic of Noise Reduction" (seed 003), eq (2)-(24), section 5.
Francis, B. A. & Wonham, W. M., "The internal model principle of control theory",
Automatica 12 (1976) 457-465.
Johnson, C. D., "Accommodation of external disturbances in linear regulator and servomechanism
problems", IEEE TAC 16 (1971) 635-644 (disturbance-augmented observers).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._deadline import as_time_limit
from .._validate import as_matrix, as_options, as_poles
from ..classical.placement import place_observer, pole_error
from ..errors import DimensionError, NotObservableError, ValidationError
from ..model.coerce import as_plant
from ..model.noise import NoiseModel, cluster_roots
from ..model.plant import Plant
from ..results import Check, ResultMixin, SolverStats, Status, Verification

__all__ = [
    "GeneralizedObserver",
    "NoiseRejectingObserver",
    "ObserverSimulation",
    "generalized_observer",
    "noise_rejecting_observer",
    "simulate_observer",
    "default_poles",
    "augmented_placement_pair",
    "structured_pair",
]

_METHODS = ("place", "well_conditioned")
_STABILITY_TOL = 1e-9
#: PBH margins (sigma_min / scale) below this count as unobservable.
_PBH_TOL = 1e-8


# --------------------------------------------------------------------------- helpers
def _fmt(z: complex) -> str:
    z = complex(z)
    return f"{z.real:.6g}" if abs(z.imag) < 1e-12 else f"{z.real:.6g}{z.imag:+.6g}j"


def _check_plant(plant: Any, what: str) -> Plant:
    plant = as_plant(plant)
    _sampling_period(plant, what)
    return plant


def _sampling_period(plant: Plant, what: str) -> float:
    """``plant.dt``; ValidationError naming ``what`` for a continuous-time plant."""
    if plant.dt is None:
        raise ValidationError(
            f"{what} needs a discrete-time plant (Plant(..., dt=T)): the noise models are polynomials in "
            "the shift operator q (seed 003 is discrete time); found a continuous-time plant"
        )
    return plant.dt


def _check_noise(noise: Any, plant: Plant) -> NoiseModel:
    if not isinstance(noise, NoiseModel):
        raise ValidationError(
            "noise must be an optdesign.noise model (Step(), Sinusoid(f, dt), Polynomial(c), or a sum); "
            f"found {type(noise).__name__}"
        )
    dt = _sampling_period(plant, "the noise model")
    if noise.dt is not None and not math.isclose(noise.dt, dt, rel_tol=1e-9):
        raise ValidationError(
            f"noise model {noise.label!r} was built for dt={noise.dt:g} but the plant has dt={dt:g}; "
            "its q-polynomial depends on the sampling period"
        )
    return noise


def _distinct_modes(noise: NoiseModel) -> list[complex]:
    return [z for z, _ in cluster_roots(noise.modes)]


def _require_full_row_rank_C(plant: Plant, noise: NoiseModel, what: str) -> None:
    rank = int(np.linalg.matrix_rank(plant.C))
    if rank < plant.p:
        modes = np.asarray(_distinct_modes(noise), dtype=complex)
        raise NotObservableError(
            f"C has rank {rank} < p = {plant.p} outputs, so {what} is impossible: with dependent outputs the "
            "copies of the noise model of the dependent channels cannot be told apart, and the noise "
            f"mode(s) {', '.join(_fmt(z) for z in modes)} stay unobservable; remove the redundant "
            "output rows",
            modes=modes,
        )


def default_poles(plant: Plant, noise: NoiseModel, count: int | None = None) -> NDArray[np.complex128]:
    """Scale-aware default poles for the augmented error dynamics (discrete time).

    A Butterworth pattern of ``count`` (default ``n + r p``) poles in the s-plane at radius
    ``w = 2 max|log(z)| / dt`` over the plant eigenvalues and noise modes (at least ``0.05 / dt``,
    at most ``1 / dt``), mapped by ``z = exp(s dt)``.  Distinct, conjugate-closed, inside the unit
    disk.

    Returns
    -------
    (count,) ndarray of complex

    Raises
    ------
    ValidationError
        ``plant`` is continuous time.
    """
    dt = _sampling_period(plant, "default_poles")
    count = plant.n + noise.order * plant.p if count is None else int(count)
    zs = np.concatenate([np.linalg.eigvals(plant.A), noise.modes])
    zs = zs[np.abs(zs) > 1e-12]
    w0 = float(np.max(np.abs(np.log(zs.astype(complex))))) / dt if zs.size else 0.0
    w = min(max(2.0 * w0, 0.05 / dt), 1.0 / dt)
    k = np.arange(count)
    phi = np.pi * (2 * k + count + 1) / (2 * count)
    s = w * np.exp(1j * phi)
    s = np.where(np.abs(s.imag) < 1e-12 * w, s.real + 0j, s)
    return as_poles("default poles", np.exp(s * dt), count)


def _coupling(plant: Plant, noise: NoiseModel, coupling: Any) -> tuple[NDArray[np.float64], str]:
    """The coupling E (n, r p) of the placement pair, and its name."""
    n, p, r = plant.n, plant.p, noise.order
    N, _, Gamma = noise.realization(p)
    Cp = np.linalg.pinv(plant.C)
    if isinstance(coupling, str):
        if coupling == "output":
            Pi = Cp @ Gamma
            return Pi @ N - plant.A @ Pi, "output"
        if coupling in ("direct", "zero_free"):
            E = np.zeros((n, r * p))
            if coupling == "direct":
                E1 = Cp
            else:  # C A^k E1 = 0 (k < n - 1), C A^(n-1) E1 = I: no finite invariant zeros of (A, E1, C)
                E1 = np.linalg.pinv(plant.observability_matrix())[:, -p:]
            E[:, :p] = E1 / np.linalg.norm(E1, axis=0, keepdims=True)
            return E, coupling
        raise ValidationError(
            f"coupling must be 'output', 'direct', 'zero_free', an (n, r p) array or None; found {coupling!r}"
        )
    E = as_matrix("coupling", coupling, (n, r * p))
    return E, "given"


def _pbh_margin(Aa: NDArray, Ca: NDArray, modes: list[complex]) -> tuple[float, complex]:
    """min over ``modes`` of sigma_min([z I - Aa; Ca]) / max(1, ||Aa||, ||Ca||), and the worst mode
    (``(inf, nan)`` without modes)."""
    scale = max(1.0, np.linalg.norm(Aa, 2), np.linalg.norm(Ca, 2))
    worst, arg = np.inf, complex(np.nan, np.nan)
    I = np.eye(Aa.shape[0])
    for z in modes:
        s = np.linalg.svd(np.vstack([z * I - Aa, Ca.astype(complex)]), compute_uv=False)[-1] / scale
        if s < worst:
            worst, arg = float(s), z
    return worst, arg


def augmented_placement_pair(plant: Plant, noise: NoiseModel, coupling: Any = "output"
                             ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """The pair ``(A_a, C_a)`` whose observer poles are the generalized observer's poles.

    ``A_a = [[A, E], [0, N]]`` (n + r p square), ``C_a = [C, 0]`` (p, n + r p), for the coupling
    ``E`` (see the module docstring).

    Returns
    -------
    A_a, C_a, E
    """
    E, _ = _coupling(plant, noise, coupling)
    N, _, _ = noise.realization(plant.p)
    rp = N.shape[0]
    Aa = np.block([[plant.A, E], [np.zeros((rp, plant.n)), N]])
    Ca = np.hstack([plant.C, np.zeros((plant.p, rp))])
    return Aa, Ca, E


def _solve_commutant(N: NDArray, M: NDArray, L2: NDArray) -> tuple[NDArray[np.float64], float]:
    """S with ``S N = N S`` and ``S M = -L2`` (least squares; returns S and the relative residual)."""
    rp, p = M.shape
    I = np.eye(rp)
    # vec(S N - N S) = (N' kron I - I kron N) vec S ; vec(S M) = (M' kron I) vec S  (column-major vec)
    lhs = np.vstack([np.kron(N.T, I) - np.kron(I, N), np.kron(M.T, I)])
    rhs = np.concatenate([np.zeros(rp * rp), (-L2).ravel(order="F")])
    sol = np.linalg.lstsq(lhs, rhs, rcond=None)[0]
    S = sol.reshape(rp, rp, order="F")
    res = max(float(np.max(np.abs(S @ N - N @ S))), float(np.max(np.abs(S @ M + L2))))
    return S, res / max(1.0, float(np.max(np.abs(L2))))


def _internal_model_residual(F: NDArray, Cout: NDArray, Bd: NDArray, D: NDArray,
                             modes: list[complex]) -> tuple[float, float]:
    """max over modes of ||D + Cout (z I - F)^{-1} Bd||_2, and a rounding-level tolerance for it."""
    worst, tol = 0.0, 0.0
    I = np.eye(F.shape[0])
    for z in modes:
        Zi = np.linalg.solve(z * I - F.astype(complex), Bd.astype(complex))
        T = D + Cout @ Zi
        worst = max(worst, float(np.linalg.norm(T, 2)))
        scale = 1.0 + np.linalg.norm(Cout, 2) * np.linalg.norm(Zi, 2) * np.linalg.cond(z * I - F)
        tol = max(tol, 1e3 * np.finfo(float).eps * F.shape[0] * scale)
    return worst, max(tol, 1e-9)


def _kappa2(X: NDArray) -> float:
    from ..analysis.metrics import kappa2

    return float(kappa2(X))


def _check_target_poles(poles: Any, count: int) -> NDArray[np.complex128]:
    P = as_poles("poles", poles, count)
    bad = P[np.abs(P) >= 1.0]
    if bad.size:
        raise ValidationError(
            f"poles must lie strictly inside the unit circle (discrete time, Schur-stable error dynamics); "
            f"found {', '.join(f'{_fmt(z)} (|z| = {abs(z):.6g})' for z in bad)}"
        )
    return P


def _well_conditioned_setup(plant: Plant, noise: NoiseModel, count: int, region: Any, target: Any):
    """(region, poles) for the well-conditioned NLP: one of them; fixed default poles when neither."""
    if region is not None and target is not None:
        raise ValidationError(
            "method='well_conditioned' takes region (poles free inside it) or poles (fixed poles, "
            "eigenvectors optimized), not both"
        )
    if region is None and target is None:
        target = default_poles(plant, noise, count)
    return region, target


def _call_well_conditioned(aug: Plant, region, poles, objective, starts, seed, structure=None, *,
                           options=None, time_limit=None):
    from . import well_conditioned as wc  # imported lazily: CasADi is loaded only when needed

    return wc.well_conditioned_observer(aug, region=region, poles=poles, objective=objective,
                                        gain_mask=structure, starts=starts, seed=seed, options=options,
                                        time_limit=time_limit)


def _check_common(method: Any, region: Any, options: Any, time_limit: Any) -> float | None:
    """Validate ``method``, ``region``, ``options`` and ``time_limit`` (returned: seconds or None) of the
    two verbs; IPOPT checks the option names and values (in the well-conditioned verb)."""
    from ..model.regions import Region

    if not isinstance(method, str) or method not in _METHODS:
        raise ValidationError(f"method must be one of {_METHODS}; found {method!r}")
    if region is not None and not isinstance(region, Region):
        raise ValidationError(f"region must be an optdesign.regions.Region (e.g. Disk(0, 0.95)) or None; "
                              f"found {type(region).__name__} {region!r}")
    if as_options("options", options) and method == "place":
        raise ValidationError("options (IPOPT options) apply to method='well_conditioned' only; "
                              f"method='place' is a direct computation; found {options!r}")
    return as_time_limit(time_limit)


def _renamed(checks, prefix: str) -> list[Check]:
    return [dataclasses.replace(c, name=f"{prefix}{c.name}") for c in checks]


def _readonly(X: ArrayLike) -> NDArray:
    X = np.array(X, dtype=complex if np.iscomplexobj(X) else float, copy=True)
    X.setflags(write=False)
    return X


def _sorted_eigs(X: NDArray) -> NDArray[np.complex128]:
    e = np.linalg.eigvals(X)
    return e[np.lexsort((e.imag, e.real))]


# --------------------------------------------------------------------------- results
@dataclass(frozen=True, eq=False)
class GeneralizedObserver(ResultMixin):
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
    status: Status
    message: str
    verification: Verification
    solver_stats: SolverStats
    method: str = "place"
    target_poles: NDArray[np.complex128] | None = None
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
        plant = _check_plant(plant, "a generalized observer")
        noise = _check_noise(noise, plant)
        n, p, rp = plant.n, plant.p, noise.order * plant.p
        N, M0, _ = noise.realization(p)
        H = as_matrix("H", H, (n, p))
        K = as_matrix("K", K, (n, rp))
        M = M0 if M is None else as_matrix("M", M, (rp, p))
        return _build_generalized(plant, noise, H, K, N, M, method="given", status=Status.SOLVED,
                                  message="given gains (analysed, not designed)",
                                  stats=SolverStats("analytic", "given"))

    def summary(self) -> str:
        return (f"GeneralizedObserver({self.noise.label}, method={self.method}, status={self.status}, "
                f"spectral radius {self.spectral_radius:.6g}, kappa2 {self.kappa2:.4g}, "
                f"success={self.success})")

    def __repr__(self) -> str:
        return self.summary()


def _build_generalized(plant, noise, H, K, N, M, *, method, status, message, stats, target=None,
                       coupling=None, coupling_kind="none", extra_checks=(), design=None,
                       region=None) -> GeneralizedObserver:
    A, C = plant.A, plant.C
    F = np.block([[A - H @ C, -K], [M @ C, N]])
    poles = _sorted_eigs(F)
    rho = float(np.max(np.abs(poles)))
    checks = [Check.at_most("spectral_radius", rho, 1.0 - _STABILITY_TOL,
                            "Schur stability of F = [[A - HC, -K], [MC, N]] (seed 003 Theorem 1)")]
    modes = _distinct_modes(noise)
    if rho < 1.0:
        Cout = np.hstack([C, np.zeros((plant.p, N.shape[0]))])
        res, tol = _internal_model_residual(F, Cout, np.vstack([-H, M]), np.eye(plant.p), modes)
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
    ro = _readonly
    return GeneralizedObserver(
        plant=plant, noise=noise, H=ro(H), K=ro(K), N=ro(N), M=ro(M), augmented=ro(F), poles=ro(poles),
        spectral_radius=rho, kappa2=_kappa2(F), status=status, message=message,
        verification=Verification.of(checks), solver_stats=stats, method=method,
        target_poles=None if target is None else ro(target),
        coupling=None if coupling is None else ro(coupling), coupling_kind=coupling_kind, design=design)


@dataclass(frozen=True, eq=False)
class NoiseRejectingObserver(ResultMixin):
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
    status: Status
    message: str
    verification: Verification
    solver_stats: SolverStats
    method: str = "place"
    target_poles: NDArray[np.complex128] | None = None
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

    def summary(self) -> str:
        return (f"NoiseRejectingObserver({self.noise.label}, method={self.method}, status={self.status}, "
                f"spectral radius {self.spectral_radius:.6g}, PBH margin {self.pbh_margin:.3g}, "
                f"success={self.success})")

    def __repr__(self) -> str:
        return self.summary()


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


# --------------------------------------------------------------------------- design verbs
def generalized_observer(
    plant: Plant,
    noise: NoiseModel,
    *,
    method: str = "place",
    poles: ArrayLike | None = None,
    region: Any = None,
    objective: str = "kappa2",
    coupling: str | ArrayLike | None = None,
    starts: int = 8,
    seed: int = 0,
    options: dict[str, Any] | None = None,
    time_limit: float | None = None,
) -> GeneralizedObserver:
    r"""Design a generalized observer (seed 003) for an output-noise model.

    Parameters
    ----------
    plant : Plant
        Discrete-time plant, A (n, n), C (p, n) with ``rank C = p``.
    noise : NoiseModel
        ``Step()``, ``Sinusoid(f, dt)``, ``Polynomial(c)`` or a sum (order r); the PI observer
        of seed 003 eq (8) is ``Step()`` (``N = M = I``).
    method : {"place", "well_conditioned"}
        ``"place"``: place the ``n + r p`` eigenvalues of ``F = [[A - HC, -K], [MC, N]]`` at
        ``poles`` (scipy ``place_poles`` on the pair ``(C_a, A_a)``, see the module docstring).
        ``"well_conditioned"``: the well-conditioned observer NLP
        (:func:`~optdesign.design.well_conditioned.well_conditioned_observer`) on the structured
        pair of :func:`structured_pair` (``F = A_s - L_s C_s``, ``L_s = [[H, K], [0, 0]]``), so
        ``objective`` (``kappa2``) of ``F`` itself is minimized over ``H`` and ``K``: eigenvectors
        for fixed ``poles`` (for one output the gain of the plain pair is unique, but ``F`` keeps
        ``(n - 1) r`` free directions), or poles free in ``region`` (give one; with neither, the
        fixed poles are :func:`default_poles`).
    poles : (n + r p,) array_like of complex, optional
        Target eigenvalues of ``F``, strictly inside the unit circle.  Default:
        :func:`default_poles` (unless ``region`` is given with ``"well_conditioned"``).
    region : Region, optional
        Discrete-time pole region, e.g. ``Disk(0, 0.95)``: the constraint of
        ``"well_conditioned"`` (poles free inside it); a verified check for ``"place"``.
    objective : str
        Passed to the well-conditioned design (``"kappa2"``).
    coupling : {"output", "direct", "zero_free"} or (n, r p) array_like, optional
        The coupling ``E`` of the placement pair: decides the direction of the residual state
        error (module docstring).  Default: the first of ``"output"`` (error confined to
        ``range(C')``, ``x - xh -> -C^+ delta``; impossible when a noise mode is a plant mode),
        ``"direct"``, ``"zero_free"`` that keeps ``(C_a, A_a)`` observable.
    starts, seed : int
        Multi-start settings of the well-conditioned design.
    options : dict, optional
        IPOPT options of the well-conditioned design (string keys).
    time_limit : float, optional
        Seconds of wall time of the well-conditioned design (None: no limit); when it runs out the
        status is ``time_limit`` with the best verified design so far (``success`` False).
        ``"place"`` is a direct computation and ignores it.

    Returns
    -------
    GeneralizedObserver
        ``H`` (n, p), ``K`` (n, r p), ``N``, ``M``, ``augmented`` F, ``poles``,
        ``spectral_radius``, ``verification`` (spectral radius < 1, pole error, internal-model
        check, region margin, conditioning of the similarity S).

    Raises
    ------
    NotObservableError
        ``(C, A)`` unobservable (names the modes; they are eigenvalues of F for every H, K), or
        ``rank C < p``, or the chosen coupling leaves the placement pair unobservable at a noise
        mode.
    ValidationError
        Continuous-time plant, noise model for another dt, unknown method, poles not strictly
        inside the unit circle, bad coupling, both ``region`` and ``poles`` with
        ``"well_conditioned"``.

    Notes
    -----
    A stable generalized observer does **not** make ``xh -> x`` under output noise: it drives
    ``eps = y - C xh -> 0``, so ``C (x - xh) -> -delta`` (see the module docstring).  Use
    :func:`noise_rejecting_observer` for ``xh -> x``.

    References
    ----------
    Kim, Lee & Kim (seed 003), Theorem 1 (eq (4)), Theorem 2 (eq (20)-(24)).

    Examples
    --------
    >>> import numpy as np
    >>> from optdesign import Plant, generalized_observer
    >>> from optdesign.noise import Step
    >>> plant = Plant([[1.0, 0.1], [0.0, 1.0]], [[1.0, 0.0]], dt=0.1)
    >>> obs = generalized_observer(plant, Step(), poles=[0.5, 0.6, 0.7])
    >>> bool(obs.success), round(obs.spectral_radius, 6)
    (True, 0.7)
    """
    plant = _check_plant(plant, "a generalized observer")
    noise = _check_noise(noise, plant)
    time_limit = _check_common(method, region, options, time_limit)
    what = "a generalized observer (seed 003 Theorem 2)"
    plant.require_observable(what=what)
    _require_full_row_rank_C(plant, noise, what)
    n, p = plant.n, plant.p
    N, M, Gamma = noise.realization(p)
    rp = N.shape[0]
    count = n + rp
    modes = _distinct_modes(noise)
    target = None if poles is None else _check_target_poles(poles, count)

    if method == "well_conditioned":
        if coupling is not None:
            raise ValidationError("coupling applies to method='place' only (the well-conditioned design "
                                  "optimizes H and K directly)")
        return _generalized_well_conditioned(plant, noise, N, M, count, region, target, objective,
                                             starts, seed, options=options, time_limit=time_limit)

    # coupling E: the first of "output", "direct", "zero_free" that keeps (C_a, A_a) observable
    Ca = np.hstack([plant.C, np.zeros((p, rp))])
    for cand in (("output", "direct", "zero_free") if coupling is None else (coupling,)):
        E, kind = _coupling(plant, noise, cand)
        Aa = np.block([[plant.A, E], [np.zeros((rp, n)), N]])
        margin, worst = _pbh_margin(Aa, Ca, modes)
        if margin >= _PBH_TOL:
            break
    if margin < _PBH_TOL:
        raise NotObservableError(
            f"the placement pair ([C, 0], [[A, E], [0, N]]) with the {kind!r} coupling E is unobservable at "
            f"the noise mode {_fmt(worst)} (PBH margin {margin:.2e}): "
            + ("the noise mode is a plant mode, so the 'output' coupling (noise confined to the measured "
               "directions) is impossible; use the default coupling (None), 'direct', 'zero_free' or "
               "another E"
               if kind == "output" else "choose another coupling E"),
            modes=np.asarray([worst], dtype=complex),
        )
    aug = Plant(Aa, Ca, dt=plant.dt, name=f"generalized-observer pair ({noise.label})")
    if target is None:
        target = default_poles(plant, noise, count)
    La = place_observer(aug, target)
    H = La[:n]
    S, sres = _solve_commutant(N, M, La[n:])
    extra = [
        Check.at_most("commutant_residual", sres, 1e-9, "S N = N S, S M = -L_2"),
        Check.at_most("S_condition", float(np.linalg.cond(S)), 1e12,
                      "cond(S) of the similarity diag(I, S) (infinite if a pole is a noise mode)"),
    ]
    K = -E @ S
    return _build_generalized(
        plant, noise, H, K, N, M, method="place", status=Status.SOLVED,
        message=f"placed the {count} poles of F (pair (C_a, A_a), {kind} coupling)",
        stats=SolverStats("scipy", "place_poles", extra={"pbh_margin": margin}), target=target, coupling=E,
        coupling_kind=kind, extra_checks=extra, region=region)


def structured_pair(plant: Plant, noise: NoiseModel) -> tuple[NDArray, NDArray, NDArray]:
    """``F`` as an observer error matrix with a structured gain: ``F = A_s - L_s C_s``.

    ``A_s = [[A, 0], [M C, N]]``, ``C_s = diag(C, I_{rp})``, ``L_s = [[H, K], [0, 0]]``; the mask
    (n + r p, p + r p) is True on the free entries (the first n rows).

    Returns
    -------
    A_s, C_s, mask
    """
    n, p = plant.n, plant.p
    N, M, _ = noise.realization(p)
    rp = N.shape[0]
    As = np.block([[plant.A, np.zeros((n, rp))], [M @ plant.C, N]])
    Cs = np.block([[plant.C, np.zeros((p, rp))], [np.zeros((rp, n)), np.eye(rp)]])
    mask = np.zeros((n + rp, p + rp), dtype=bool)
    mask[:n, :] = True
    return As, Cs, mask


def _generalized_well_conditioned(plant, noise, N, M, count, region, target, objective, starts, seed, *,
                                  options=None, time_limit=None):
    n, p = plant.n, plant.p
    As, Cs, mask = structured_pair(plant, noise)
    aug = Plant(As, Cs, dt=plant.dt, name=f"generalized-observer structured pair ({noise.label})")
    reg, target = _well_conditioned_setup(plant, noise, count, region, target)
    design = _call_well_conditioned(aug, reg, target, objective, starts, seed, structure=mask,
                                    options=options, time_limit=time_limit)
    Ls = np.asarray(design.L, dtype=float)
    H, K = Ls[:n, :p], Ls[:n, p:]
    extra = _renamed(design.verification, "nlp:")
    extra.append(Check.at_most("structure", float(np.max(np.abs(Ls[n:]))) if Ls[n:].size else 0.0, 1e-12,
                               "rows of the xi-equation in L_s = [[H, K], [0, 0]] are zero"))
    return _build_generalized(
        plant, noise, H, K, N, M, method="well_conditioned", status=Status(design.status),
        message=f"well-conditioned design of F = A_s - L_s C_s (structured gain): {design.message}",
        stats=getattr(design, "solver_stats", SolverStats("ipopt")), target=target, coupling=None,
        coupling_kind="none", extra_checks=extra, design=design, region=reg)


def noise_rejecting_observer(
    plant: Plant,
    noise: NoiseModel,
    *,
    method: str = "place",
    poles: ArrayLike | None = None,
    region: Any = None,
    objective: str = "kappa2",
    starts: int = 8,
    seed: int = 0,
    options: dict[str, Any] | None = None,
    time_limit: float | None = None,
) -> NoiseRejectingObserver:
    r"""An observer that estimates the output noise as part of the state, so ``xh -> x``.

    The plant is augmented with the noise model as an output disturbance,
    ``A_a = diag(A, N)``, ``C_a = [C, Gamma]``, and an ordinary predictor observer is designed
    for ``(C_a, A_a)``.  For every noise of the class, ``x - xh -> 0`` and ``delta - Gamma dh -> 0``.

    Parameters
    ----------
    plant : Plant
        Discrete time.
    noise : NoiseModel
    method : {"place", "well_conditioned"}
    poles : (n + r p,) array_like of complex, optional
        Eigenvalues of ``A_a - L C_a``, strictly inside the unit circle (default
        :func:`default_poles`).
    region, objective, starts, seed, options, time_limit
        As :func:`generalized_observer`.

    Returns
    -------
    NoiseRejectingObserver

    Raises
    ------
    NotObservableError
        ``(C, A)`` unobservable (names the modes), or a noise mode is also a plant mode (names
        the mode: an output offset of that mode cannot be told apart from the plant's own
        response).  (Dependent outputs are fine here: each channel's noise stays observable.)
    ValidationError
        As :func:`generalized_observer`.

    References
    ----------
    Johnson (1971); Francis & Wonham (1976); seed 003 section 5 (the example it is compared on).
    """
    plant = _check_plant(plant, "a noise-rejecting observer")
    noise = _check_noise(noise, plant)
    time_limit = _check_common(method, region, options, time_limit)
    plant.require_observable(what="a noise-rejecting observer")
    n, p = plant.n, plant.p
    N, _, Gamma = noise.realization(p)
    rp = N.shape[0]
    count = n + rp
    modes = _distinct_modes(noise)
    Aa = np.block([[plant.A, np.zeros((n, rp))], [np.zeros((rp, n)), N]])
    Ca = np.hstack([plant.C, Gamma])
    margin, worst = _pbh_margin(Aa, Ca, modes)
    plant_eigs = np.linalg.eigvals(plant.A)
    clash = [z for z in modes if np.min(np.abs(plant_eigs - z)) <= 1e-6 * max(1.0, abs(z))]
    if clash or margin < _PBH_TOL:
        bad = clash or [worst]
        nearest = [plant_eigs[int(np.argmin(np.abs(plant_eigs - z)))] for z in bad]
        raise NotObservableError(
            f"noise mode(s) {', '.join(_fmt(z) for z in bad)} of {noise.label!r} coincide with plant mode(s) "
            f"{', '.join(_fmt(z) for z in nearest)}: the output-disturbance pair ([C, Gamma], diag(A, N)) is "
            "unobservable there (an output offset of that mode cannot be told apart from the plant's own "
            "response), so the noise cannot be rejected from the state estimate; a generalized observer "
            "(generalized_observer) still exists but cannot separate noise from state either",
            modes=np.asarray(bad, dtype=complex),
        )
    target = None if poles is None else _check_target_poles(poles, count)
    aug = Plant(Aa, Ca, dt=plant.dt, name=f"output-disturbance pair ({noise.label})")
    design = None
    extra: list[Check] = []
    if method == "place":
        if target is None:
            target = default_poles(plant, noise, count)
        L = place_observer(aug, target)
        status, message = Status.SOLVED, f"placed the {count} poles of the output-disturbance observer"
        stats = SolverStats("scipy", "place_poles", extra={"pbh_margin": margin})
        check_region = region
    else:
        check_region, target = _well_conditioned_setup(plant, noise, count, region, target)
        design = _call_well_conditioned(aug, check_region, target, objective, starts, seed, options=options,
                                        time_limit=time_limit)
        L = np.asarray(design.L, dtype=float)
        status = Status(design.status)
        message = f"well-conditioned output-disturbance observer: {design.message}"
        stats = getattr(design, "solver_stats", SolverStats("ipopt"))
        extra.extend(_renamed(design.verification, "design:"))
    Fa = Aa - L @ Ca
    P = _sorted_eigs(Fa)
    rho = float(np.max(np.abs(P)))
    checks = [Check.at_most("spectral_radius", rho, 1.0 - _STABILITY_TOL, "Schur stability of A_a - L C_a")]
    if target is not None:
        checks.append(Check.at_most("pole_error", pole_error(P, target), 1e-6, "eig(A_a - L C_a) vs target"))
    if check_region is not None:
        checks.append(Check.at_most("region_margin", float(check_region.margin(P)), 1e-9,
                                    f"max signed distance to {check_region!r}"))
    if rho < 1.0:
        # y -> xh transfer of the observer (as a filter) must vanish at the noise modes: a pure noise
        # y(k) = v lambda^k (Gamma V_lambda spans R^p) leaves no trace in the state estimate
        Cx = np.hstack([np.eye(n), np.zeros((n, rp))])
        res, tol = _internal_model_residual(Fa, Cx, L, np.zeros((n, p)), modes)
        checks.append(Check.at_most("noise_rejection", res, tol,
                                    "||y -> xh transfer|| at the noise modes "
                                    "(xh ignores the modelled noise)"))
    checks.extend(extra)
    ro = _readonly
    return NoiseRejectingObserver(
        plant=plant, noise=noise, L=ro(L), A_aug=ro(Aa), C_aug=ro(Ca), N=ro(N), Gamma=ro(Gamma), poles=ro(P),
        spectral_radius=rho, kappa2=_kappa2(Fa), pbh_margin=margin, status=status,
        message=message, verification=Verification.of(checks), solver_stats=stats, method=method,
        target_poles=None if target is None else ro(target),
        design=design)


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
        kind, model = "luenberger", _check_plant(plant, "simulate_observer")
        Lg = as_matrix("L", observer, (model.n, model.p))
    true = model if plant is None else _check_plant(plant, "simulate_observer")
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
    t = np.arange(T, dtype=np.float64) * _sampling_period(true, "simulate_observer")
    return ObserverSimulation(t=t, x=X, xhat=XH, y=Y, delta=d.copy(), eps=EPS, internal=Z,
                              noise_estimate=DH if rej is not None else None, kind=kind, C=np.array(C))
