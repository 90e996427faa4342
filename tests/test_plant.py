"""Plant: validation at construction, immutability, observability (PBH), conversions."""

from __future__ import annotations

import numpy as np
import pytest

import optdesign
from optdesign import Plant
from optdesign.analysis.metrics import eigenvalue_condition
from optdesign.errors import (
    DimensionError,
    NotFiniteError,
    NotObservableError,
    NotPositiveDefiniteError,
    NotPositiveSemidefiniteError,
    NotSymmetricError,
    OptDesignError,
    ValidationError,
)

A2 = [[0.0, 1.0], [-6.0, -5.0]]
C2 = [[1.0, 0.0]]


def test_basic_properties():
    p = Plant(A2, C2, Q=np.eye(2), R=[[1.0]], name="ex1")
    assert (p.n, p.p, p.m) == (2, 1, 2)
    assert not p.is_discrete and p.has_noise_model
    np.testing.assert_array_equal(p.G, np.eye(2))
    np.testing.assert_allclose(p.process_noise(), np.eye(2))
    assert "ex1" in repr(p) and "continuous" in repr(p)


def test_one_dimensional_C_is_a_row():
    p = Plant(A2, [1.0, 0.0])
    assert p.C.shape == (1, 2)


def test_G_and_Q_shapes():
    p = Plant(A2, C2, G=[[0.0], [1.0]], Q=[[2.0]], R=[[1.0]])
    assert p.m == 1
    np.testing.assert_allclose(p.process_noise(), [[0, 0], [0, 2]])


def test_frozen_and_readonly():
    p = Plant(A2, C2)
    with pytest.raises(AttributeError):
        p.A = np.eye(2)  # type: ignore[misc]
    with pytest.raises(ValueError, match="read-only"):
        p.A[0, 0] = 5.0


def test_input_is_copied():
    A = np.array(A2)
    p = Plant(A, C2)
    A[0, 0] = 99.0
    assert p.A[0, 0] == 0.0


def test_replace_revalidates():
    p = Plant(A2, C2, Q=np.eye(2), R=[[1.0]])
    q = p.replace(dt=0.1)
    assert q.is_discrete and q.dt == 0.1 and not p.is_discrete
    with pytest.raises(NotPositiveDefiniteError, match="R must be positive definite"):
        p.replace(R=[[0.0]])
    with pytest.raises(ValidationError, match=r"Plant.replace: 'D' is not a field of Plant; fields are A, C"):
        p.replace(D=[[0.0]])


@pytest.mark.parametrize(
    "kwargs, error, match",
    [
        (dict(A=[[1.0, 2.0, 3.0]], C=[[1.0]]), DimensionError, r"A must be square; found shape \(1, 3\)"),
        (dict(A=np.zeros((2, 2, 2)), C=[[1.0, 0.0]]), DimensionError, "A must be 2-D"),
        (dict(A=A2, C=[[1.0, 0.0, 0.0]]), DimensionError,
         r"C has the wrong shape: expected \(\?, 2\), found \(1, 3\)"),
        (dict(A=[[np.nan, 1.0], [0.0, 0.0]], C=C2), NotFiniteError, "A must be finite; found nan at index"),
        (dict(A=A2, C=[[np.inf, 0.0]]), NotFiniteError, "C must be finite"),
        (dict(A=A2, C=C2, G=[[1.0], [0.0], [0.0]]), DimensionError,
         r"G has the wrong shape: expected \(2, \?\)"),
        (dict(A=A2, C=C2, Q=[[1.0, 2.0], [0.0, 1.0]]), NotSymmetricError, "Q must be symmetric"),
        (dict(A=A2, C=C2, Q=[[1.0, 0.0], [0.0, -1.0]]), NotPositiveSemidefiniteError,
         "Q must be positive semidefinite; found smallest eigenvalue -1"),
        (dict(A=A2, C=C2, Q=np.eye(3)), ValidationError, "G is required when Q is not n x n"),
        (dict(A=A2, C=C2, G=[[1.0], [0.0]], Q=np.eye(2)), DimensionError,
         r"Q has the wrong shape: expected \(1, 1\)"),
        (dict(A=A2, C=C2, R=[[-1.0]]), NotPositiveDefiniteError, "R must be positive definite"),
        (dict(A=A2, C=C2, R=np.eye(2)), DimensionError, r"R has the wrong shape: expected \(1, 1\)"),
        (dict(A=A2, C=C2, dt=0.0), ValidationError, "dt must be finite and > 0"),
        (dict(A=A2, C=C2, dt=-1.0), ValidationError, "dt must be finite and > 0"),
        (dict(A=A2, C=C2, dt="fast"), ValidationError, "dt must be a real number"),
        # issue 11, item 5: a numeric string was accepted as dt (float("0.1")), a bool too
        (dict(A=A2, C=C2, dt="0.1"), ValidationError, r"dt must be a real number; found '0.1' \(a string\)"),
        (dict(A=A2, C=C2, dt=True), ValidationError, r"dt must be a real number; found True \(bool\)"),
        (dict(A=A2, C=C2, dt=np.nan), NotFiniteError, "dt must be finite and > 0; found nan"),
        (dict(A=A2, C="1, 0"), ValidationError, "C must be a numeric array; found the string '1, 0'"),
        (dict(A=A2, C=[["1", "0"]]), ValidationError, "C must be numeric; found dtype <U1"),
        (dict(A=A2, C=[[1.0, 0.0], [1.0]]), ValidationError, "C could not be converted to an array"),
        (dict(A=A2, C=C2, Q=[[1.0, 0.0], [1.0]]), ValidationError, "Q could not be converted to an array"),
        (dict(A=[[1j, 0.0], [0.0, 1.0]], C=C2), ValidationError, "A must be real"),
        (dict(A=[[1.0, 2.0], [3.0]], C=C2), ValidationError, "A could not be converted|A must be a numeric"),
        (dict(A=np.zeros((0, 0)), C=np.zeros((1, 0))), ValidationError, "at least one state"),
        (dict(A=A2, C=np.zeros((0, 2))), ValidationError, "at least one output"),
        (dict(A=A2, C=C2, B=[[1.0, 0.0, 0.0]]), DimensionError, r"B has the wrong shape"),
        (dict(A=A2, C=C2, name=3), ValidationError, "name must be a string"),
    ],
)
def test_validation_errors(kwargs, error, match):
    with pytest.raises(error, match=match):
        Plant(**kwargs)


def test_errors_are_builtins_and_rooted():
    with pytest.raises(ValueError):
        Plant([[1.0, 2.0]], [[1.0]])
    with pytest.raises(OptDesignError):
        Plant([[1.0, 2.0]], [[1.0]])
    assert issubclass(optdesign.RiccatiError, np.linalg.LinAlgError)
    assert issubclass(optdesign.SolverError, RuntimeError)
    assert issubclass(optdesign.BackendUnavailableError, ImportError)
    assert issubclass(optdesign.ProblemNotFoundError, KeyError)


def test_observability_matrix():
    p = Plant(A2, C2)
    np.testing.assert_allclose(p.observability_matrix(), [[1, 0], [0, 1]])
    assert p.is_observable() and p.unobservable_modes().size == 0


def test_unobservable_modes_named():
    p = Plant([[-1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, -3.0]], [[1.0, 0.0, 1.0]])
    modes = p.unobservable_modes()
    np.testing.assert_allclose(modes, [2.0])
    assert not p.is_observable() and not p.is_detectable()
    with pytest.raises(NotObservableError, match=r"unobservable mode\(s\) 2\+0j") as info:
        p.require_observable()
    np.testing.assert_allclose(info.value.modes, [2.0])


def test_detectable_but_unobservable():
    p = Plant([[-1.0, 0.0], [0.0, 2.0]], [[0.0, 1.0]])
    np.testing.assert_allclose(p.unobservable_modes(), [-1.0])
    assert p.is_detectable()
    p.require_observable(detectable_ok=True)  # no error
    with pytest.raises(NotObservableError, match="unobservable"):
        p.require_observable()


def test_discrete_detectability_uses_unit_circle():
    p = Plant([[0.5, 0.0], [0.0, 1.5]], [[0.0, 1.0]], dt=0.1)
    assert p.is_detectable()
    q = Plant([[0.5, 0.0], [0.0, 1.5]], [[1.0, 0.0]], dt=0.1)
    assert not q.is_detectable()
    with pytest.raises(NotObservableError, match="undetectable mode"):
        q.require_observable(detectable_ok=True)


def test_repeated_eigenvalue_pbh():
    # two Jordan-free copies of eigenvalue -1 seen by one output: one copy is unobservable
    p = Plant(-np.eye(2), [[1.0, 1.0]])
    np.testing.assert_allclose(p.unobservable_modes(), [-1.0])
    # a Jordan block is observable from its last state... from the first row of C = e1'
    j = Plant([[-1.0, 1.0], [0.0, -1.0]], [[1.0, 0.0]])
    assert j.is_observable()


def test_complex_unobservable_pair():
    A = np.zeros((4, 4))
    A[:2, :2] = [[0.0, 2.0], [-2.0, 0.0]]
    A[2:, 2:] = [[-1.0, 1.0], [-1.0, -1.0]]
    p = Plant(A, [[0.0, 0.0, 1.0, 0.0]])
    modes = np.sort_complex(p.unobservable_modes())
    np.testing.assert_allclose(modes, [-2j, 2j], atol=1e-12)


def test_pbh_agrees_with_rank_on_random_plants(rng):
    for _ in range(50):
        n, p = rng.integers(2, 7), rng.integers(1, 3)
        A = rng.standard_normal((n, n))
        C = rng.standard_normal((p, n))
        plant = Plant(A, C)
        assert plant.is_observable() == (np.linalg.matrix_rank(plant.observability_matrix()) == n)


def test_require_noise_model_message():
    with pytest.raises(ValidationError, match="has no Q and no R"):
        Plant(A2, C2, name="x").require_noise_model()
    with pytest.raises(ValidationError, match="has no Q"):
        Plant(A2, C2).process_noise()


def test_from_control_round_trip():
    import control  # optional at run time; part of the [test] extra
    sys = control.ss(A2, [[0.0], [1.0]], C2, 0)
    p = Plant.from_control(sys, Q=np.eye(2), R=[[1.0]])
    np.testing.assert_allclose(p.A, A2)
    assert p.B.shape == (2, 1) and not p.is_discrete
    sysd = control.ss(A2, [[0.0], [1.0]], C2, 0, dt=0.1)
    assert Plant.from_control(sysd).dt == 0.1
    # dt=True (unspecified period, control.drss): dt = 1 (issue 27; it was refused)
    assert Plant.from_control(control.ss(A2, [[0.0], [1.0]], C2, 0, dt=True)).dt == 1.0
    with pytest.raises(ValidationError, match="must be a control.StateSpace"):
        Plant.from_control("not a system")


def test_to_dict():
    d = Plant(A2, C2, R=[[1.0]], dt=0.5, name="z").to_dict()
    assert d["A"] == A2 and d["dt"] == 0.5 and d["Q"] is None and d["name"] == "z"


def test_unobservable_modes_on_constructed_unobservable_plants(rng):
    # x = [x1; x2] with x2 invisible: A = [[A11, 0], [A21, A22]], C = [C1, 0], then a random similarity
    for _ in range(100):
        n = int(rng.integers(2, 8))
        k = int(rng.integers(1, n))
        A = np.zeros((n, n))
        A[:k, :k] = rng.standard_normal((k, k))
        A[k:, :] = rng.standard_normal((n - k, n))
        p = int(rng.integers(1, 3))
        C = np.hstack([rng.standard_normal((p, k)), np.zeros((p, n - k))])
        T = rng.standard_normal((n, n))
        plant = Plant(np.linalg.solve(T, A @ T), C @ T)
        got = np.sort_complex(plant.unobservable_modes())
        want = np.sort_complex(np.linalg.eigvals(A[k:, k:]))
        assert got.shape == want.shape
        np.testing.assert_allclose(got, want, rtol=1e-6, atol=1e-6)


def test_unobservable_modes_badly_scaled_plant():
    # CAREX 2.9 in filter form: ||A|| ~ 2e7, 55 states; observable (absolute thresholds flagged ~40 modes)
    from optdesign import problems

    plant = problems.load("carex_2.9-kf").plant
    assert np.linalg.norm(plant.A) > 1e7
    assert plant.unobservable_modes().size == 0


def test_unobservable_when_C_is_zero():
    p = Plant([[-1.0, 0.0], [0.0, 2.0]], [[0.0, 0.0]])
    np.testing.assert_allclose(np.sort(p.unobservable_modes().real), [-1.0, 2.0])


def test_unobservable_modes_tol_is_validated():
    p = Plant(A2, C2)
    assert p.unobservable_modes(tol=1e-10).size == 0
    for bad in ("1e-10", 0.0, -1.0, np.nan):
        with pytest.raises(ValidationError, match="tol must be"):
            p.unobservable_modes(tol=bad)


def _hidden_plant(rng, n: int, p: int, A22: np.ndarray, *, rotate: bool) -> Plant:
    """A plant whose last ``len(A22)`` states the output cannot see (``x2`` does not drive ``x1``, C
    sees ``x1`` only), hidden by a random orthogonal change of basis if ``rotate``.

    Without the rotation the structure is exact in floating point, so the staircase's bookkeeping
    is tested at any size.  With it, the answer is only as good as the staircase's forward error,
    which grows like eps over the product of its subdiagonals (the Krylov conditioning): for one
    output and more than ~20 states no orthogonal method can decide reliably, so the rotated cases
    stay at a size where the decision is clear (4 hidden modes found on every CPU)."""
    k = n - A22.shape[0]
    A = rng.standard_normal((n, n)) / np.sqrt(n) - np.eye(n)
    A[:k, k:] = 0.0
    A[k:, k:] = A22
    C = np.hstack([rng.standard_normal((p, k)), np.zeros((p, n - k))])
    if not rotate:
        return Plant(A, C)
    T = np.linalg.qr(rng.standard_normal((n, n)))[0]
    return Plant(T.T @ A @ T, C @ T)


@pytest.mark.parametrize("n, p, rotate", [(150, 1, False), (120, 3, False), (60, 6, True), (12, 1, True)])
def test_unobservable_modes_at_scale(rng, n, p, rotate):
    # issue 11, item 8: the staircase is O(n^3) now (reflectors applied to the rows and columns each
    # step changes); it must find the hidden modes, a repeated one included, where p = 1 takes n steps
    A22 = np.diag([-0.2, -0.2, 0.1, 0.3])
    plant = _hidden_plant(rng, n, p, A22, rotate=rotate)
    got = np.sort_complex(plant.unobservable_modes())
    assert got.shape == (4,)
    # the hidden modes are eigenvalues of the trailing block: computed to about eps ||A|| times
    # their condition number in A
    s = eigenvalue_condition(plant.A)[1]
    tol = 1e3 * n * np.finfo(float).eps * np.linalg.norm(plant.A) * float(np.max(s[np.isfinite(s)]))
    np.testing.assert_allclose(got, np.sort_complex(np.diag(A22).astype(complex)), atol=tol)
    assert not plant.is_observable() and not plant.is_detectable()


def test_observable_at_scale_where_a_rank_test_fails(rng):
    n = 150
    full = Plant(rng.standard_normal((n, n)) / np.sqrt(n), rng.standard_normal((1, n)))
    assert full.is_observable()
    # the observability matrix of a single-output plant of this order is numerically singular
    assert np.linalg.matrix_rank(full.observability_matrix()) < n


def test_shared_eigenvalue_between_seen_and_hidden_parts(rng):
    # -1 is an eigenvalue of the visible and of the hidden part: only one copy is unobservable
    A11 = np.diag([-1.0, -2.0, -3.0]) + np.diag([1.0, 1.0], 1)
    A = np.zeros((5, 5))
    A[:3, :3] = A11
    A[3:, 3:] = np.diag([-1.0, 4.0])
    A[3:, :3] = rng.standard_normal((2, 3))
    C = np.zeros((1, 5))
    C[0, 0] = 1.0  # x1 is driven by x2, x2 by x3: the output sees the whole chain
    Qo, _ = np.linalg.qr(rng.standard_normal((5, 5)))
    plant = Plant(Qo @ A @ Qo.T, C @ Qo.T)
    np.testing.assert_allclose(np.sort(plant.unobservable_modes().real), [-1.0, 4.0], atol=1e-9)


def test_unobservable_modes_are_computed_once_and_safe_to_modify():
    p = Plant([[-1.0, 0.0], [0.0, 2.0]], [[1.0, 0.0]])
    first = p.unobservable_modes()
    first[:] = 99.0  # the caller's copy: the plant's answer does not change
    np.testing.assert_allclose(p.unobservable_modes(), [2.0])
    assert p.unobservable_modes() is not p.unobservable_modes()
    q = p.replace(C=[[0.0, 1.0]])  # a new plant: its own staircase
    np.testing.assert_allclose(q.unobservable_modes(), [-1.0])
    assert "_unobservable" not in {f.name for f in __import__("dataclasses").fields(p)}
