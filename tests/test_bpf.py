"""Block-pulse functions (seed 004) and the exact Riccati transition-matrix propagator.

What is proved here, to rounding error, about the paper's recursion (4.24)-(4.25):
  * it solves the block-pulse (operational-matrix) form of the corrected (4.20)/(4.23) exactly;
  * phi_k = (C^(k-1) + C^k) / 2 with C the Cayley / Pade(1,1) / Crank-Nicolson propagator;
  * phi_k^-1 = (I + h M / 2) T^(k-1) with T the Crank-Nicolson propagator of e^{h M};
and, measured against the exact solution, that the Riccati solution it gives is second order at
the block midpoints (first order as a piecewise-constant function), with an O(h^2) asymmetric part.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg
from conftest import random_observable_plant

from optdesign import problems
from optdesign.classical.bpf import (
    BPF_RESTART_NORM,
    RiccatiMap,
    apply_map,
    backward_integration_matrix,
    bpf_coefficients,
    bpf_evaluate,
    bpf_restart_blocks,
    bpf_riccati,
    bpf_transition,
    bpf_transition_direct,
    cayley,
    compose_maps,
    crank_nicolson_transition,
    davison_maki,
    filter_hamiltonian,
    filter_hamiltonian_trusted,
    hamiltonian_scaling,
    integration_matrix,
    riccati_flow,
    riccati_map,
)
from optdesign.errors import (
    DimensionError,
    NotFiniteError,
    NotSymmetricError,
    RiccatiError,
    ValidationError,
)

J2 = lambda n: np.block([[np.zeros((n, n)), np.eye(n)], [-np.eye(n), np.zeros((n, n))]])  # noqa: E731


def _rel(a, b) -> float:
    return float(np.linalg.norm(np.asarray(a) - np.asarray(b)) / np.linalg.norm(b))


def _traj_rel(P, Pref) -> float:
    return float(np.max(np.linalg.norm(P - Pref, axis=(1, 2))) / np.max(np.linalg.norm(Pref, axis=(1, 2))))


@pytest.fixture(scope="module")
def oscillator():
    """The paper's example: (M, P0, t_final, m)."""
    prob = problems.load("ahn_bpf_harmonic_oscillator")
    pl = prob.plant
    M = filter_hamiltonian(pl.A, pl.C, pl.process_noise(), pl.R)
    P0 = np.asarray(prob.targets["P0"], float)
    return M, P0, float(prob.targets["t_final"]), int(prob.targets["steps"])


def _random_hamiltonian(rng, n, stable=None):
    pl = random_observable_plant(rng, n, 1, stable=stable)
    return filter_hamiltonian(pl.A, pl.C, pl.process_noise(), pl.R)


# ------------------------------------------------------------------ block-pulse basics
def test_integration_matrix_structure_and_exactness():
    m, tf = 6, 3.0
    P = integration_matrix(m, tf)
    h = tf / m
    assert np.allclose(np.diag(P), h / 2) and np.allclose(np.triu(P, 1), h * np.triu(np.ones((m, m)), 1))
    assert np.all(np.tril(P, -1) == 0)
    # the integral of 1 is t; its block-pulse coefficients are the block averages of t (midpoints)
    c_one = bpf_coefficients(lambda t: 1.0, tf, m)
    c_t = bpf_coefficients(lambda t: t, tf, m)
    assert np.allclose(c_one @ P, c_t, rtol=0, atol=1e-14)
    assert np.allclose(c_t, (np.arange(m) + 0.5) * h, atol=1e-14)
    assert np.array_equal(backward_integration_matrix(m, tf), -P.T)


def test_bpf_coefficients_are_block_averages_and_evaluate_is_piecewise_constant():
    tf, m = 2.0, 4
    c = bpf_coefficients(lambda t: np.array([t**3, 1.0]), tf, m)
    h = tf / m
    exact = np.array([((k + 1) ** 4 - k**4) * h**4 / 4 / h for k in range(m)])   # mean of t^3
    assert np.allclose(c[:, 0], exact, rtol=1e-14) and np.allclose(c[:, 1], 1.0)
    vals = bpf_evaluate(c, tf, [0.0, 0.49, 0.5, 1.99, 2.0])
    assert np.array_equal(vals[:, 0], c[[0, 0, 1, 3, 3], 0])                      # t_f is in the last block


def test_filter_hamiltonian_is_hamiltonian(rng):
    M = _random_hamiltonian(rng, 4)
    JM = J2(4) @ M
    assert np.allclose(JM, JM.T, atol=1e-14)
    E = scipy.linalg.expm(0.3 * M)                                                 # symplectic
    assert np.allclose(E.T @ J2(4) @ E, J2(4), atol=1e-12)


def test_trusted_filter_hamiltonian_equals_the_validated_one(rng):
    """The unvalidated variant (for callers that have validated) builds the same matrix, bit for bit."""
    for n, p in ((1, 1), (4, 2), (7, 3)):
        pl = random_observable_plant(rng, n, p, stable=False)
        M = filter_hamiltonian(pl.A, pl.C, pl.process_noise(), pl.R)
        assert np.array_equal(filter_hamiltonian_trusted(pl.A, pl.C, pl.process_noise(), pl.R), M)
        assert np.array_equal(M[:n, :n], -pl.A.T) and np.array_equal(M[n:, n:], pl.A)


# ------------------------------------------------------------------ what the recursion is
def test_recursion_solves_the_operational_matrix_system(rng):
    """(4.24)-(4.25) = the exact solution of phi_l + sum_k P_kl phi_k M = I (corrected (4.23))."""
    M = _random_hamiltonian(rng, 2)
    rec = bpf_transition(M, 3.0, 12)
    direct = bpf_transition_direct(M, 3.0, 12)
    assert max(_rel(rec[k], direct[k]) for k in range(12)) < 1e-12


def test_recursion_is_block_average_of_crank_nicolson(oscillator, rng):
    """phi_k = (C^(k-1) + C^k)/2, C = (I - hM/2)(I + hM/2)^-1 (Pade(1,1) of e^{-hM})."""
    for M, tf, m in ((oscillator[0], oscillator[2], oscillator[3]), (_random_hamiltonian(rng, 3), 2.0, 40)):
        h = tf / m
        phis = bpf_transition(M, tf, m)
        C = cayley(M, h)
        eye = np.eye(len(M))
        assert _rel(C, (eye - h / 2 * M) @ np.linalg.inv(eye + h / 2 * M)) < 1e-14
        powers = [np.eye(len(M))]
        for _ in range(m):
            powers.append(powers[-1] @ C)
        worst = max(_rel(phis[k], 0.5 * (powers[k] + powers[k + 1])) for k in range(m))
        assert worst < 1e-13, worst


def test_inverse_coefficients_are_half_euler_step_from_crank_nicolson(oscillator):
    """phi_k^-1 = (I + hM/2) T^(k-1): Crank-Nicolson e^{M t_(k-1)} then half an explicit Euler step,
    i.e. an O(h^2) approximation of e^{M t} at the block MIDPOINT."""
    M, _, tf, m = oscillator
    h = tf / m
    phis = bpf_transition(M, tf, m)
    T = crank_nicolson_transition(M, h, m)
    half = np.eye(len(M)) + h / 2 * M
    # inverting phi_k costs its condition number (it grows like e^{2 rho t}, ~4e4 here)
    eps = np.finfo(float).eps
    for k in range(m):
        assert _rel(np.linalg.inv(phis[k]), half @ T[k]) < 10 * eps * np.linalg.cond(phis[k])
    # the Pade(1,1) T is second order: error of T^m against e^{M t_f} drops 4x when h halves
    e1 = _rel(crank_nicolson_transition(M, h, m)[-1], scipy.linalg.expm(M * tf))
    e2 = _rel(crank_nicolson_transition(M, h / 2, 2 * m)[-1], scipy.linalg.expm(M * tf))
    assert 3.8 < e1 / e2 < 4.2


def test_crank_nicolson_nodes_symmetric_bpf_coefficients_not(oscillator):
    """T is symplectic (Cayley transform of a Hamiltonian), so V U^-1 at the nodes is exactly
    symmetric; the half Euler step is not, so the paper's P_k has an O(h^2) antisymmetric part."""
    M, P0, tf, m = oscillator
    n = P0.shape[0]
    T = crank_nicolson_transition(M, tf / m, m)
    Z = T @ np.vstack([np.eye(n), P0])
    nodes = np.linalg.solve(np.swapaxes(Z[:, :n], 1, 2), np.swapaxes(Z[:, n:], 1, 2))   # (V U^-1)'
    assert np.max(np.abs(nodes - np.swapaxes(nodes, 1, 2))) < 1e-14
    asym = [np.max(bpf_riccati(M, P0, tf, mm, symmetrize=False).asymmetry) for mm in (50, 100, 200)]
    assert asym[0] > 1e-3
    ratios = np.array(asym[:-1]) / np.array(asym[1:])
    assert np.all((ratios > 3.8) & (ratios < 4.2)), ratios


def test_bpf_riccati_is_second_order_at_midpoints(oscillator):
    """Convergence over m = 25..400 against the exact transition-matrix solution."""
    M, P0, tf, _ = oscillator
    tq = np.linspace(0, tf, 41)
    exact_q, _ = riccati_flow(M, P0, tq)
    mids, raws, pcs = [], [], []
    for m in (25, 50, 100, 200, 400):
        res = bpf_riccati(M, P0, tf, m)
        raw = bpf_riccati(M, P0, tf, m, symmetrize=False)
        exact, _ = riccati_flow(M, P0, res.t)
        mids.append(_traj_rel(res.P, exact))
        raws.append(_traj_rel(raw.P, exact))
        pcs.append(_traj_rel(bpf_evaluate(res.P, tf, tq), exact_q))
    order = lambda e: np.log2(np.array(e[:-1]) / np.array(e[1:]))  # noqa: E731
    assert np.all(np.abs(order(mids) - 2) < 0.02), order(mids)
    assert np.all(np.abs(order(raws) - 2) < 0.07), order(raws)
    assert np.all(np.abs(order(pcs) - 1) < 0.07), order(pcs)
    assert np.all(np.array(mids) < 0.6 * np.array(raws))          # symmetrizing halves the error
    assert 1e-3 < mids[1] < 5e-3                                  # the paper's m = 50: ~2.4e-3


def test_restarted_recursion_is_the_same_method(oscillator, rng):
    """Restarting the recursion from its own Crank-Nicolson nodal value (T^r Z = (I - hM/2)^-1
    phi_r^-1 Z) changes P_k and the asymmetry only by the rounding of the unrestarted recursion,
    eps cond(phi_k): it is the same method, with any segment length."""
    eps = np.finfo(float).eps
    for M, P0, tf, m in ((oscillator[0], oscillator[1], oscillator[2], oscillator[3]),
                         (_random_hamiltonian(rng, 3), np.eye(3), 2.0, 40)):
        plain = bpf_riccati(M, P0, tf, m, symmetrize=False)
        floor = 100 * eps * max(np.linalg.cond(phi) for phi in bpf_transition(M, tf, m))
        auto = bpf_restart_blocks(M, tf / m)
        assert 1 <= auto < m
        for r in (1, 3, 7, auto, m + 5):
            res = bpf_riccati(M, P0, tf, m, symmetrize=False, restart_every=r)
            assert _traj_rel(res.P, plain.P) < floor, (r, _traj_rel(res.P, plain.P), floor)
            assert np.max(np.abs(res.asymmetry - plain.asymmetry)) < floor * np.max(np.abs(plain.P))
            assert res.restarts == (m - 1) // r and res.complete
            assert res.restart_every == (r if r < m else None)


def test_restarted_recursion_is_second_order(oscillator):
    M, P0, tf, _ = oscillator
    errs = []
    for m in (25, 50, 100, 200, 400):
        res = bpf_riccati(M, P0, tf, m, restart_every=1)
        exact, _ = riccati_flow(M, P0, res.t)
        errs.append(_traj_rel(res.P, exact))
    order = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    assert np.all(np.abs(order - 2) < 0.02), order


def test_restart_blocks_bound_the_condition_of_phi(rng):
    """||M||_1 r h <= BPF_RESTART_NORM < ||M||_1 (r + 1) h, so cond(phi_k) <= e^{2 BPF_RESTART_NORM}
    on every segment (measured here on the segment's coefficients)."""
    M = _random_hamiltonian(rng, 4, stable=False)
    nrm = np.linalg.norm(M, 1)
    for h in (1e-3, 0.05, 0.3, 10.0):
        r = bpf_restart_blocks(M, h)
        assert r >= 1 and (r == 1 or nrm * r * h <= BPF_RESTART_NORM < nrm * (r + 1) * h)
        if r > 1:
            phis = bpf_transition(M, r * h, r)
            assert max(np.linalg.cond(phi) for phi in phis) <= np.exp(2 * BPF_RESTART_NORM)
    assert bpf_restart_blocks(np.zeros((4, 4)), 0.1) > 10**15
    with pytest.raises(ValidationError, match="h must be finite and > 0"):
        bpf_restart_blocks(M, 0.0)
    with pytest.raises(DimensionError, match="M must be a 2n x 2n"):
        bpf_restart_blocks(np.eye(3), 0.1)


def test_restarted_bpf_error_names_the_cause(oscillator):
    """Blocks far too wide: CAREX 1.2's Hamiltonian has the real eigenvalues +-sqrt 2, so with
    h = sqrt 2 both I + hM/2 (phi_1^-1) and I - hM/2 (the restart) are singular; with restarts the
    message no longer blames the horizon."""
    pl = problems.load("carex_1.2").plant
    M = filter_hamiltonian(pl.A, pl.C, pl.process_noise(), pl.R)
    h = np.sqrt(2.0)
    with pytest.raises(RiccatiError, match="phi_k is singular.*blocks far too wide for the fastest mode"):
        bpf_riccati(M, np.eye(2), 4 * h, 4, restart_every=1)
    with pytest.raises(RiccatiError, match="phi_k is singular.*restart it"):
        bpf_riccati(M, np.eye(2), 4 * h, 4)
    with pytest.raises(ValidationError, match="restart_every must be a positive integer"):
        bpf_riccati(oscillator[0], oscillator[1], 1.0, 4, restart_every=0)


@pytest.fixture
def ticking(monkeypatch):
    """Every look at a limited Deadline's clock advances it by one second."""
    from optdesign._deadline import Deadline

    looks: dict[int, int] = {}
    start = Deadline.__init__

    def init(self, time_limit=None):
        start(self, time_limit)
        looks[id(self)] = 0

    def elapsed(self):
        looks[id(self)] += 1
        return float(looks[id(self)])

    monkeypatch.setattr(Deadline, "__init__", init)
    monkeypatch.setattr(Deadline, "elapsed", property(elapsed))


def test_deadline_stops_recursion_and_flow(ticking, oscillator):
    """A deadline stops before the next block / output interval; what was computed is returned."""
    M, P0, tf, m = oscillator
    full = bpf_riccati(M, P0, tf, m)
    part = bpf_riccati(M, P0, tf, m, deadline=6.5)
    k = part.P.shape[0]
    assert not part.complete and 0 < k < m and part.t.shape == (k,) and part.asymmetry.shape == (k,)
    assert np.array_equal(part.P, full.P[:k]) and np.array_equal(part.t, full.t[:k])
    times = np.linspace(0, tf, 21)
    P, _ = riccati_flow(M, P0, times)
    Pp, info = riccati_flow(M, P0, times, deadline=4.5)
    j = Pp.shape[0]
    assert 1 < j < times.size and info["completed"] == j and np.array_equal(Pp, P[:j])
    assert riccati_flow(M, P0, times, deadline=1e9)[1]["completed"] == times.size


# ------------------------------------------------------------------ exact propagation
def test_maps_form_a_semigroup(rng):
    M = _random_hamiltonian(rng, 3, stable=False)
    n = 3
    m1, m2 = riccati_map(M, 0.3), riccati_map(M, 0.45)
    both = riccati_map(M, 0.75)
    comp = compose_maps(m1, m2)
    for a, b in ((comp.Pn, both.Pn), (comp.Phi, both.Phi), (comp.O, both.O)):
        assert _rel(a, b) < 1e-12
    P0 = np.eye(n) * 0.7
    assert _rel(apply_map(m2, apply_map(m1, P0)), apply_map(both, P0)) < 1e-12
    # the map reproduces the Moebius form of the exact transition matrix
    E = scipy.linalg.expm(M * 0.3)
    moebius = (E[n:, :n] + E[n:, n:] @ P0) @ np.linalg.inv(E[:n, :n] + E[:n, n:] @ P0)
    assert _rel(apply_map(m1, P0), moebius) < 1e-12
    for X in (m1.Pn, m1.O):
        assert np.min(np.linalg.eigvalsh(X)) > -1e-14 * np.linalg.norm(X)


@pytest.mark.parametrize("stable", [True, False])
def test_riccati_flow_agrees_with_davison_maki(rng, stable):
    for n in (2, 4, 6):
        M = _random_hamiltonian(rng, n, stable=stable)
        F = rng.standard_normal((n, n))
        P0 = F @ F.T
        times = np.linspace(0, 8, 41)
        P, info = riccati_flow(M, P0, times)
        assert np.array_equal(P, np.swapaxes(P, 1, 2))
        assert np.min(np.linalg.eigvalsh(P)) >= -1e-12 * np.max(np.linalg.norm(P, axis=(1, 2)))
        assert np.array_equal(P[0], 0.5 * (P0 + P0.T))
        assert _traj_rel(P, davison_maki(M, P0, times)) < 1e-11
        assert info["maps"] == 1 and info["substeps"] == 40


def test_riccati_flow_nonuniform_times_match_uniform(oscillator):
    M, P0, _, _ = oscillator
    t = np.linspace(0, 5, 51)
    P, _ = riccati_flow(M, P0, t)
    Pn, info = riccati_flow(M, P0, t[[0, 3, 4, 17, 50]])
    assert _traj_rel(Pn, P[[0, 3, 4, 17, 50]]) < 1e-13
    assert info["maps"] == 4


def test_balancing_is_exact_and_needed_on_badly_scaled_plant():
    """CAREX 1.6 (||M||_1 = 2.8e6, spectral radius 577): the symplectic rescaling is by powers of 2;
    with it, the flow matches Davison-Maki on the rescaled equation to 1e-12; without it the
    matrix exponentials lose about 1e-9."""
    pl = problems.load("carex_1.6").plant
    M = filter_hamiltonian(pl.A, pl.C, pl.process_noise(), pl.R)
    d, rho = hamiltonian_scaling(M)
    assert np.all(np.log2(d) == np.round(np.log2(d))) and np.log2(rho) == round(np.log2(rho))
    n = pl.n
    times = np.linspace(0, 1, 11)
    P, _ = riccati_flow(M, np.zeros((n, n)), times)
    Ab = M[n:, n:] / d[:, None] * d[None, :]
    Sb = M[:n, n:] * d[:, None] * d[None, :] * rho
    Wb = M[n:, :n] / d[:, None] / d[None, :] / rho
    Mb = np.block([[-Ab.T, Sb], [Wb, Ab]])
    assert np.linalg.norm(Mb, 1) < 1e-3 * np.linalg.norm(M, 1)
    Pdm = davison_maki(Mb, np.zeros((n, n)), times) * rho * d[None, :, None] * d[None, None, :]
    assert _traj_rel(P, Pdm) < 1e-12
    Pu, _ = riccati_flow(M, np.zeros((n, n)), times, balance=False)
    assert _traj_rel(Pu, P) > 1e-11


def test_growth_guard_refuses_hopeless_horizon():
    """CAREX 2.6 (eigenvalues 1e6..3e6, measurement noise 1e6): the filter transition grows
    beyond 1e8 within 0.1 s, so covering 10 s would need 1.6e6 restarts."""
    pl = problems.load("carex_2.6").plant
    M = filter_hamiltonian(pl.A, pl.C, pl.process_noise(), pl.R)
    with pytest.raises(RiccatiError, match="max_substeps"):
        riccati_flow(M, np.zeros((3, 3)), np.linspace(0, 10, 101))
    with pytest.raises(RiccatiError, match="max_substeps"):
        riccati_map(M, 10.0, max_substeps=10)


def test_map_application_and_composition_refuse_non_psd():
    """I + P O (application) and I + Pn1 O2 (composition) have eigenvalues >= 1 for PSD factors; a
    non-PSD input that makes them singular is reported, not propagated."""
    n = 3
    rmap = RiccatiMap(Pn=np.eye(n), Phi=0.5 * np.eye(n), O=np.eye(n), dt=1.0)
    with pytest.raises(RiccatiError, match=r"apply_map: I \+ P O is singular .*P or O is not PSD"):
        apply_map(rmap, -np.eye(n))
    bad = RiccatiMap(Pn=-np.eye(n), Phi=np.eye(n), O=np.eye(n), dt=1.0)
    with pytest.raises(RiccatiError, match=r"compose_maps: I \+ Pn1 O2 is singular"):
        compose_maps(bad, rmap)


# ------------------------------------------------------------------ bad input
def test_bad_inputs(oscillator):
    M, P0, tf, m = oscillator
    with pytest.raises(ValidationError, match="m must be a positive integer"):
        integration_matrix(0, 1.0)
    with pytest.raises(ValidationError, match="m must be a positive integer"):
        bpf_transition(M, tf, 2.5)
    with pytest.raises(ValidationError, match="t_final must be finite and > 0"):
        integration_matrix(5, -1.0)
    with pytest.raises(ValidationError, match="nodes must be a positive integer"):
        bpf_coefficients(np.sin, 1.0, 3, nodes=0)
    with pytest.raises(DimensionError, match="M must be a 2n x 2n"):
        bpf_riccati(np.eye(3), np.eye(1), 1.0, 4)
    with pytest.raises(DimensionError, match="M must be square"):
        cayley(np.ones((2, 3)), 0.1)
    with pytest.raises(NotFiniteError, match="M must be finite"):
        bpf_transition(np.full((2, 2), np.nan), 1.0, 3)
    with pytest.raises(NotSymmetricError, match="P0 must be symmetric"):
        bpf_riccati(M, [[0, 1], [0, 0]], tf, m)
    with pytest.raises(DimensionError, match=r"P0 has the wrong shape: expected \(2, 2\)"):
        riccati_flow(M, np.eye(3), [0, 1])
    with pytest.raises(ValidationError, match="t must lie in"):
        bpf_evaluate(np.ones((3, 2)), 1.0, [0.5, 1.5])
    with pytest.raises(ValidationError, match="m N = 800 > 400"):
        bpf_transition_direct(M, 1.0, 200)
    with pytest.raises(ValidationError, match="non-decreasing"):
        riccati_flow(M, P0, [0, 2, 1])
    with pytest.raises(ValidationError, match="non-decreasing"):
        davison_maki(M, P0, [-1, 0])
    with pytest.raises(ValidationError, match="would need"):
        davison_maki(M, P0, [0, 1e9])
    with pytest.raises(ValidationError, match="dt must be finite and > 0"):
        riccati_map(M, 0.0)
    with pytest.raises(DimensionError, match=r"C has the wrong shape"):
        filter_hamiltonian(np.eye(2), np.ones((1, 3)), np.eye(2), np.eye(1))
