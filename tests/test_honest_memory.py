"""Issue 26, item 3: memory bounded by the problem's data, set-up inside time_limit."""

import tracemalloc

import numpy as np

import optdesign as od
from optdesign._deadline import Deadline, dense_kkt_refusal
from optdesign.backends.clarabel_fixed_gain import _triangle_map, family_map
from optdesign.engines.inverse_kalman_setup import prepare_inverse_kalman
from optdesign.engines.one_output_sdp import one_output_form, one_output_form_of_plant


def _plant(n, seed=0):
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n, n)) / np.sqrt(n) - 1.5 * np.eye(n)
    return od.Plant(A, rng.standard_normal((1, n)), R=[[1.0]])


def test_lyapunov_form_spans_the_same_complement():
    pl = _plant(9, seed=3)
    old = one_output_form(family_map(pl.A, pl.C, None).T)
    new = one_output_form_of_plant(pl.A, pl.C)
    np.testing.assert_allclose(new.W @ new.W.T, old.W @ old.W.T, atol=1e-12)


def test_triangle_map_without_kronecker_matches():
    rng = np.random.default_rng(1)
    A, C = rng.standard_normal((7, 7)), rng.standard_normal((2, 7))
    fm = family_map(A, C, None)
    N, AN = fm.N, A @ fm.N
    np.testing.assert_allclose(fm.T, _triangle_map(-(np.kron(N, AN) + np.kron(AN, N)), 7, 5), atol=1e-14)


def test_one_output_setup_memory_is_not_quartic():
    """n = 120, one output: the set-up built T (7260 x 7140 doubles, 415 MB) from an n^2 x (n-1)^2
    Kronecker product (1.6 GB) and took its complete QR; now n Lyapunov solves, O(n^3)."""
    pl = _plant(120)
    tracemalloc.start()
    try:
        setup = prepare_inverse_kalman(pl)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert setup.complement_form is not None
    assert peak < 150 * 2**20
    assert "T" not in setup.family.__dict__  # the direct form's map was never built


def test_dense_kkt_refusal_rules():
    assert dense_kkt_refusal(100, None, "x") == ""
    assert "GiB" in dense_kkt_refusal(10**6, None, "a solve")
    assert "s left" in dense_kkt_refusal(20_000, Deadline(1.0), "a solve")


def test_one_output_large_n_keeps_time_limit_and_memory():
    """n = 100, one output, time_limit = 3: the direct-form fallback (minutes, GBs) is refused up
    front with its estimate (before: time_limit=10 was ignored, 476 s and 3.8 GB)."""
    pl = _plant(100)
    target = np.sort(np.linalg.eigvals(pl.A)) - 0.1
    res = od.kalman_for_poles(pl, target, time_limit=3)
    assert res.status in (od.Status.TIME_LIMIT, od.Status.NOT_FOUND) or res.success
    if not res.success:
        assert "not attempted" in res.message
