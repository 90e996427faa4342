"""Shared pieces of the generalized-observer designs (:mod:`optdesign.design.generalized`): input checks
of the plant and the noise model, the default poles, the coupling ``E`` and the placement pair, the PBH
margin, the internal-model residual, and small array helpers used by the results and the verbs.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..._validate import as_matrix, as_poles
from ...errors import ValidationError
from ...model.coerce import as_plant
from ...model.noise import NoiseModel, cluster_roots
from ...model.plant import Plant

__all__ = [
    "STABILITY_TOL",
    "fmt",
    "check_discrete_plant",
    "sampling_period",
    "check_noise",
    "distinct_modes",
    "default_poles",
    "coupling_matrix",
    "pbh_margin",
    "augmented_placement_pair",
    "internal_model_residual",
    "kappa2_of",
    "readonly",
    "sorted_eigs",
]

#: Margin below 1 of the spectral radius that counts as Schur stable in the checks.
STABILITY_TOL = 1e-9

# --------------------------------------------------------------------------- helpers
def fmt(z: complex) -> str:
    """``z`` for a message: ``"0.5"`` when real (to rounding), ``"0.5+0.2j"`` otherwise."""
    z = complex(z)
    return f"{z.real:.6g}" if abs(z.imag) < 1e-12 else f"{z.real:.6g}{z.imag:+.6g}j"


def check_discrete_plant(plant: Any, what: str) -> Plant:
    """``plant`` as a :class:`~optdesign.model.plant.Plant`; ValidationError naming ``what`` if continuous."""
    plant = as_plant(plant)
    sampling_period(plant, what)
    return plant


def sampling_period(plant: Plant, what: str) -> float:
    """``plant.dt``; ValidationError naming ``what`` for a continuous-time plant."""
    if plant.dt is None:
        raise ValidationError(
            f"{what} needs a discrete-time plant (Plant(..., dt=T)): the noise models are polynomials in "
            "the shift operator q (seed 003 is discrete time); found a continuous-time plant"
        )
    return plant.dt


def check_noise(noise: Any, plant: Plant) -> NoiseModel:
    """``noise`` checked to be a :class:`~optdesign.model.noise.NoiseModel` built for ``plant.dt``.

    Raises
    ------
    ValidationError
        Not a noise model, or one built for another sampling period.
    """
    if not isinstance(noise, NoiseModel):
        raise ValidationError(
            "noise must be an optdesign.noise model (Step(), Sinusoid(f, dt), Polynomial(c), or a sum); "
            f"found {type(noise).__name__}"
        )
    dt = sampling_period(plant, "the noise model")
    if noise.dt is not None and not math.isclose(noise.dt, dt, rel_tol=1e-9):
        raise ValidationError(
            f"noise model {noise.label!r} was built for dt={noise.dt:g} but the plant has dt={dt:g}; "
            "its q-polynomial depends on the sampling period"
        )
    return noise


def distinct_modes(noise: NoiseModel) -> list[complex]:
    """The distinct noise modes (roots of the noise polynomial, repeated roots once)."""
    return [z for z, _ in cluster_roots(noise.modes)]


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
    dt = sampling_period(plant, "default_poles")
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


def coupling_matrix(plant: Plant, noise: NoiseModel, coupling: Any) -> tuple[NDArray[np.float64], str]:
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


def pbh_margin(Aa: NDArray, Ca: NDArray, modes: list[complex]) -> tuple[float, complex]:
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
    E, _ = coupling_matrix(plant, noise, coupling)
    N, _, _ = noise.realization(plant.p)
    rp = N.shape[0]
    Aa = np.block([[plant.A, E], [np.zeros((rp, plant.n)), N]])
    Ca = np.hstack([plant.C, np.zeros((plant.p, rp))])
    return Aa, Ca, E


def internal_model_residual(F: NDArray, Cout: NDArray, Bd: NDArray, D: NDArray,
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


def kappa2_of(X: NDArray) -> float:
    """:func:`optdesign.analysis.metrics.kappa2` of the square matrix ``X``, as a float."""
    from ...analysis.metrics import kappa2

    return float(kappa2(X))


def readonly(X: ArrayLike) -> NDArray:
    """A read-only float (or complex) copy of ``X``, for the frozen result fields."""
    X = np.array(X, dtype=complex if np.iscomplexobj(X) else float, copy=True)
    X.setflags(write=False)
    return X


def sorted_eigs(X: NDArray) -> NDArray[np.complex128]:
    """Eigenvalues of the square matrix ``X``, sorted by real then imaginary part."""
    e = np.linalg.eigvals(X)
    return e[np.lexsort((e.imag, e.real))]

