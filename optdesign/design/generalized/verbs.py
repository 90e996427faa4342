"""The design verbs of :mod:`optdesign.design.generalized`: :func:`generalized_observer` (placement on the
pair ``(C_a, A_a)`` or the well-conditioned NLP on the structured pair of :func:`structured_pair`) and
:func:`noise_rejecting_observer` (the output-disturbance observer).
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..._deadline import as_time_limit
from ..._validate import as_options, as_poles
from ...classical.placement import place_observer, pole_error
from ...errors import NotObservableError, ValidationError
from ...model.noise import NoiseModel
from ...model.plant import Plant
from ...results import Check, SolverStats, Status, Verification
from .common import (
    STABILITY_TOL,
    check_discrete_plant,
    check_noise,
    coupling_matrix,
    default_poles,
    distinct_modes,
    fmt,
    internal_model_residual,
    kappa2_of,
    pbh_margin,
    readonly,
    sorted_eigs,
)
from .results import GeneralizedObserver, NoiseRejectingObserver, build_generalized, design_route

__all__ = ["generalized_observer", "noise_rejecting_observer", "structured_pair"]

_METHODS = ("place", "well_conditioned")
#: PBH margins (sigma_min / scale) below this count as unobservable.
_PBH_TOL = 1e-8

def _require_full_row_rank_C(plant: Plant, noise: NoiseModel, what: str) -> None:
    rank = int(np.linalg.matrix_rank(plant.C))
    if rank < plant.p:
        modes = np.asarray(distinct_modes(noise), dtype=complex)
        raise NotObservableError(
            f"C has rank {rank} < p = {plant.p} outputs, so {what} is impossible: with dependent outputs the "
            "copies of the noise model of the dependent channels cannot be told apart, and the noise "
            f"mode(s) {', '.join(fmt(z) for z in modes)} stay unobservable; remove the redundant "
            "output rows",
            modes=modes,
        )


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


def _check_target_poles(poles: Any, count: int) -> NDArray[np.complex128]:
    P = as_poles("poles", poles, count)
    bad = P[np.abs(P) >= 1.0]
    if bad.size:
        raise ValidationError(
            f"poles must lie strictly inside the unit circle (discrete time, Schur-stable error dynamics); "
            f"found {', '.join(f'{fmt(z)} (|z| = {abs(z):.6g})' for z in bad)}"
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
    from .. import well_conditioned as wc  # imported lazily: CasADi is loaded only when needed

    return wc.well_conditioned_observer(aug, region=region, poles=poles, objective=objective,
                                        gain_mask=structure, starts=starts, seed=seed, options=options,
                                        time_limit=time_limit)


def _check_common(method: Any, region: Any, options: Any, time_limit: Any) -> float | None:
    """Validate ``method``, ``region``, ``options`` and ``time_limit`` (returned: seconds or None) of the
    two verbs; IPOPT checks the option names and values (in the well-conditioned verb)."""
    from ...model.regions import Region

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
    plant = check_discrete_plant(plant, "a generalized observer")
    noise = check_noise(noise, plant)
    time_limit = _check_common(method, region, options, time_limit)
    what = "a generalized observer (seed 003 Theorem 2)"
    plant.require_observable(what=what)
    _require_full_row_rank_C(plant, noise, what)
    n, p = plant.n, plant.p
    N, M, Gamma = noise.realization(p)
    rp = N.shape[0]
    count = n + rp
    modes = distinct_modes(noise)
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
        E, kind = coupling_matrix(plant, noise, cand)
        Aa = np.block([[plant.A, E], [np.zeros((rp, n)), N]])
        margin, worst = pbh_margin(Aa, Ca, modes)
        if margin >= _PBH_TOL:
            break
    if margin < _PBH_TOL:
        raise NotObservableError(
            f"the placement pair ([C, 0], [[A, E], [0, N]]) with the {kind!r} coupling E is unobservable at "
            f"the noise mode {fmt(worst)} (PBH margin {margin:.2e}): "
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
    return build_generalized(
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
    return build_generalized(
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

    Examples
    --------
    >>> import numpy as np
    >>> from optdesign import Plant, noise_rejecting_observer, simulate_observer
    >>> from optdesign.noise import Step
    >>> plant = Plant([[0.9, 0.1], [0.0, 0.8]], [[1.0, 0.0]], dt=0.1)
    >>> obs = noise_rejecting_observer(plant, Step(), poles=[0.5, 0.6, 0.7])   # a constant output offset
    >>> obs.success, obs.poles.round(6).tolist()
    (True, [0.5, 0.6, 0.7])
    >>> sim = simulate_observer(obs, 0.1 * np.ones(300), x0=[1.0, 0.0])
    >>> bool(sim.tail("error") < 1e-12)                   # x_hat -> x despite the offset
    True
    """
    plant = check_discrete_plant(plant, "a noise-rejecting observer")
    noise = check_noise(noise, plant)
    time_limit = _check_common(method, region, options, time_limit)
    plant.require_observable(what="a noise-rejecting observer")
    n, p = plant.n, plant.p
    N, _, Gamma = noise.realization(p)
    rp = N.shape[0]
    count = n + rp
    modes = distinct_modes(noise)
    Aa = np.block([[plant.A, np.zeros((n, rp))], [np.zeros((rp, n)), N]])
    Ca = np.hstack([plant.C, Gamma])
    margin, worst = pbh_margin(Aa, Ca, modes)
    plant_eigs = np.linalg.eigvals(plant.A)
    clash = [z for z in modes if np.min(np.abs(plant_eigs - z)) <= 1e-6 * max(1.0, abs(z))]
    if clash or margin < _PBH_TOL:
        bad = clash or [worst]
        nearest = [plant_eigs[int(np.argmin(np.abs(plant_eigs - z)))] for z in bad]
        raise NotObservableError(
            f"noise mode(s) {', '.join(fmt(z) for z in bad)} of {noise.label!r} coincide with plant mode(s) "
            f"{', '.join(fmt(z) for z in nearest)}: the output-disturbance pair ([C, Gamma], diag(A, N)) is "
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
    P = sorted_eigs(Fa)
    rho = float(np.max(np.abs(P)))
    checks = [Check.at_most("spectral_radius", rho, 1.0 - STABILITY_TOL, "Schur stability of A_a - L C_a")]
    if target is not None:
        checks.append(Check.at_most("pole_error", pole_error(P, target), 1e-6, "eig(A_a - L C_a) vs target"))
    if check_region is not None:
        checks.append(Check.at_most("region_margin", float(check_region.margin(P)), 1e-9,
                                    f"max signed distance to {check_region!r}"))
    if rho < 1.0:
        # y -> xh transfer of the observer (as a filter) must vanish at the noise modes: a pure noise
        # y(k) = v lambda^k (Gamma V_lambda spans R^p) leaves no trace in the state estimate
        Cx = np.hstack([np.eye(n), np.zeros((n, rp))])
        res, tol = internal_model_residual(Fa, Cx, L, np.zeros((n, p)), modes)
        checks.append(Check.at_most("noise_rejection", res, tol,
                                    "||y -> xh transfer|| at the noise modes "
                                    "(xh ignores the modelled noise)"))
    checks.extend(extra)
    ro = readonly
    return NoiseRejectingObserver(
        plant=plant, noise=noise, L=ro(L), A_aug=ro(Aa), C_aug=ro(Ca), N=ro(N), Gamma=ro(Gamma), poles=ro(P),
        spectral_radius=rho, kappa2=kappa2_of(Fa), pbh_margin=margin, status=status,
        message=message, verification=Verification.of(checks), solver_stats=stats, method=method,
        target_poles=None if target is None else ro(target),
        design=design, route=design_route(method, stats))

