"""The per-step kernel of the exact Riccati flow (optdesign.classical.transition, issue 14): the
lean application of a step map (preallocated buffers, LAPACK on Fortran-order views, halved
symmetrization) against independent formulas -- the Moebius form of the matrix exponential, repeated
single applications, Davison-Maki restarts -- on random systems with fixed seeds.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg
from conftest import random_observable_plant

from optdesign.classical import transition
from optdesign.classical.bpf import filter_hamiltonian
from optdesign.classical.transition import RiccatiMap, apply_map, davison_maki, riccati_flow, riccati_map
from optdesign.errors import ValidationError

_EPS = float(np.finfo(float).eps)


def _hamiltonian(rng, n: int, p: int, stable: bool):
    plant = random_observable_plant(rng, n, p, stable=stable)
    return filter_hamiltonian(plant.A, plant.C, plant.process_noise(), plant.R)


def _random_psd(rng, n: int) -> np.ndarray:
    X = rng.standard_normal((n, n))
    return X @ X.T / n


@pytest.mark.parametrize("n", [1, 3, 10, 25, 40])
@pytest.mark.parametrize("stable", [True, False])
def test_apply_map_matches_the_moebius_form(n, stable):
    """One application equals ``(E21 + E22 P)(E11 + E12 P)^-1`` of ``E = expm(M dt)`` to the
    rounding of that independent formula (its denominator's condition number), is exactly
    symmetric, and leaves its argument untouched (n = 40: the Cholesky form)."""
    rng = np.random.default_rng(1400 + n + 100 * stable)
    M = _hamiltonian(rng, n, max(1, n // 4), stable)
    dt = 0.5 / float(np.linalg.norm(M, 1))
    rmap = riccati_map(M, 4 * dt, direct=False)        # two doublings
    P = _random_psd(rng, n)
    P_in = P.copy()
    out = apply_map(rmap, P)
    assert np.array_equal(P, P_in)
    assert np.array_equal(out, out.T)
    E = scipy.linalg.expm(M * 4 * dt)
    U, V = E[:n, :n] + E[:n, n:] @ P, E[n:, :n] + E[n:, n:] @ P
    ref = np.linalg.solve(U.T, V.T).T
    tol = 100 * n * _EPS * np.linalg.cond(U) * max(1.0, float(np.linalg.norm(E, 1)))
    assert np.linalg.norm(out - ref) <= tol * np.linalg.norm(ref)


def test_substeps_equal_repeated_applications(rng):
    """A map with ``substeps = 3`` (the growth guard's restarts: ping-pong buffers) gives the
    three single applications, and their composition is the exact map over 3 dt."""
    n = 6
    M = _hamiltonian(rng, n, 2, stable=False)
    one = riccati_map(M, 0.05)
    three = RiccatiMap(Pn=one.Pn, Phi=one.Phi, O=one.O, dt=0.15, doublings=one.doublings, substeps=3)
    P = _random_psd(rng, n)
    stepwise = apply_map(one, apply_map(one, apply_map(one, P)))
    assert np.array_equal(apply_map(three, P), stepwise)
    exact = apply_map(riccati_map(M, 0.15), P)
    assert np.linalg.norm(stepwise - exact) <= 1e3 * n * _EPS * np.linalg.norm(exact)


def test_riccati_flow_with_forced_restarts_agrees_with_davison_maki(rng):
    """A low growth limit forces restarts inside each output interval (substeps > 1 in the loop,
    written through the work buffers into the output stack); the trajectory is unchanged."""
    n = 5
    M = _hamiltonian(rng, n, 2, stable=False)
    times = np.linspace(0.0, 3.0, 31)
    P0 = _random_psd(rng, n)
    P, info = riccati_flow(M, P0, times)
    Pg, infog = riccati_flow(M, P0, times, growth_limit=1.5)
    assert infog["substeps"] > info["substeps"] == times.size - 1
    assert infog["completed"] == times.size and np.all(Pg == np.swapaxes(Pg, 1, 2))
    ref = davison_maki(M, P0, times)
    scale = np.max(np.linalg.norm(ref, axis=(1, 2)))
    for X in (P, Pg):
        assert np.max(np.linalg.norm(X - ref, axis=(1, 2))) <= 1e4 * n * _EPS * scale


def test_repeated_times_copy_the_previous_value(rng):
    """Zero-length output intervals (a repeated time, or t = 0) copy P; nothing is propagated."""
    n = 4
    M = _hamiltonian(rng, n, 1, stable=True)
    P0 = _random_psd(rng, n)
    P, info = riccati_flow(M, P0, [0.0, 0.5, 0.5, 1.0])
    assert np.array_equal(P[0], 0.5 * (P0 + P0.T)) and np.array_equal(P[1], P[2])
    assert info["completed"] == 4 and info["substeps"] == 2 and info["maps"] == 1


@pytest.mark.parametrize("stable", [True, False])
def test_cholesky_and_lu_forms_agree_and_match_davison_maki(monkeypatch, stable):
    """n >= CHOLESKY_MIN_N steps by the Cholesky form, falling back to the LU form where P has no
    Cholesky factor (P0 = 0: the first step); both forms give the same trajectory to rounding,
    and both match Davison-Maki restarts (independent: Moebius form of one exponential)."""
    n = max(transition.CHOLESKY_MIN_N, 8)
    rng = np.random.default_rng(1432 + stable)
    M = _hamiltonian(rng, n, n // 4, stable)
    times = np.linspace(0.0, 2.0, 21)
    ref = davison_maki(M, np.zeros((n, n)), times)
    scale = np.max(np.linalg.norm(ref, axis=(1, 2)))
    out = {}
    for kernel, min_n in (("cholesky", n), ("lu", n + 1)):
        monkeypatch.setattr(transition, "CHOLESKY_MIN_N", min_n)
        P, _ = riccati_flow(M, np.zeros((n, n)), times)
        assert np.all(P == np.swapaxes(P, 1, 2)), kernel
        assert np.max(np.linalg.norm(P - ref, axis=(1, 2))) <= 1e4 * n * _EPS * scale, kernel
        out[kernel] = P
    assert np.max(np.linalg.norm(out["cholesky"] - out["lu"], axis=(1, 2))) <= 100 * n * _EPS * scale


# ------------------------------------------------------------------ the direct map of short intervals
def _loss(M, dt: float) -> float:
    """``||E||_1 ||E11^-1||_1`` of ``E = expm(M dt)``, with the exact inverse (independent of the
    ``gecon`` estimate the guard uses)."""
    n = M.shape[0] // 2
    E = scipy.linalg.expm(M * dt)
    return float(np.linalg.norm(E, 1) * np.linalg.norm(np.linalg.inv(E[:n, :n]), 1))


@pytest.mark.parametrize("seed", range(6))
def test_direct_map_matches_the_doubling_and_davison_maki(seed):
    """Short output intervals (``||M dt||_1 <= DIRECT_MAX_NORM``) take one exponential of the whole
    interval; on random plants (n = 2..12, stable and unstable, P0 random PSD) the trajectory equals
    the doubling's and Davison-Maki's to the guard's promise, ``DIRECT_MAX_LOSS * eps`` relative (times
    n and a factor 10 for the references' own rounding)."""
    rng = np.random.default_rng(1450 + seed)
    n = int(rng.integers(2, 13))
    M = _hamiltonian(rng, n, max(1, n // 4), stable=bool(seed % 2))
    dt = float(rng.uniform(2.0, 12.0)) / float(np.linalg.norm(M, 1))      # s >= 2 doublings otherwise
    times = dt * np.arange(31)
    P0 = _random_psd(rng, n)
    P, info = riccati_flow(M, P0, times, balance=False)
    Pd, info_d = riccati_flow(M, P0, times, balance=False, direct=False, max_norm=1.0 / 16)
    assert info["direct"] == info["maps"] == 1 and info["doublings"] == 0
    assert info_d["direct"] == 0 and info_d["doublings"] >= 4
    assert np.all(P == np.swapaxes(P, 1, 2))
    ref = davison_maki(M, P0, times, max_step=0.25)
    scale = float(np.max(np.linalg.norm(ref, axis=(1, 2))))
    tol = 10 * n * transition.DIRECT_MAX_LOSS * _EPS * scale
    assert np.max(np.linalg.norm(P - Pd, axis=(1, 2))) <= tol
    assert np.max(np.linalg.norm(P - ref, axis=(1, 2))) <= tol


def test_direct_map_guard_falls_back_to_the_doubling():
    """A short interval whose ``E11`` is ill conditioned (a fast stable mode beside a fast unstable
    one, weakly measured: measured loss ``||E|| ||E11^-1|| >> DIRECT_MAX_LOSS`` at ``||M dt||_1 <=
    DIRECT_MAX_NORM``) is refused by the guard: the map is doubled, and it is right (Davison-Maki)."""
    A = np.diag([-6.0, 6.0])
    C = np.array([[1e-3, 1e-3]])
    M = filter_hamiltonian(A, C, np.eye(2), np.eye(1))
    dt = 0.9 * transition.DIRECT_MAX_NORM / float(np.linalg.norm(M, 1))
    assert _loss(M, dt) > 1e3 * transition.DIRECT_MAX_LOSS
    rmap = riccati_map(M, dt)
    assert not rmap.direct and rmap.doublings >= 4
    P0 = 0.5 * np.eye(2)
    ref = davison_maki(M, P0, [0.0, dt], max_step=0.25)[1]
    assert np.linalg.norm(apply_map(rmap, P0) - ref) <= 1e4 * _EPS * np.linalg.norm(ref)


def test_direct_map_respects_the_growth_limit():
    """The direct map is refused where its ``||Phi||_1`` exceeds ``growth_limit`` (the doubling's
    restarts then cover the interval)."""
    rng = np.random.default_rng(1460)
    M = _hamiltonian(rng, 4, 1, stable=False)
    dt = 4.0 / float(np.linalg.norm(M, 1))
    free = riccati_map(M, dt)
    phi = float(np.linalg.norm(free.Phi, 1))
    assert free.direct and phi > 1.0
    capped = riccati_map(M, dt, growth_limit=0.99 * phi)
    assert not capped.direct


def test_riccati_map_refuses_a_non_bool_direct():
    M = _hamiltonian(np.random.default_rng(1461), 2, 1, stable=True)
    with pytest.raises(ValidationError, match="direct must be true or false; found"):
        riccati_map(M, 0.1, direct="yes")
    with pytest.raises(ValidationError, match="direct must be true or false; found"):
        riccati_flow(M, np.eye(2), [0.0, 0.1], direct=1)
