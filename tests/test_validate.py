"""Shared input validation helpers and the result/status types."""

from __future__ import annotations

import numpy as np
import pytest

from optdesign._validate import (
    as_array,
    as_bool,
    as_frequencies,
    as_gain_mask,
    as_int,
    as_matrix,
    as_options,
    as_poles,
    as_positive_float,
    as_real,
    as_rng,
    as_str,
    as_vector,
    check_pd,
    check_psd,
)
from optdesign.errors import (
    DimensionError,
    InfeasibleError,
    NotConjugateClosedError,
    NotFiniteError,
    NotPositiveDefiniteError,
    NotPositiveSemidefiniteError,
    NotSymmetricError,
    SolverError,
    ValidationError,
)
from optdesign.results import Check, ResultMixin, SolverStats, Status, Verification


def test_as_matrix_scalar_and_vector():
    assert as_matrix("R", 2.0).shape == (1, 1)
    assert as_matrix("L", [1.0, 2.0], (None, 1)).shape == (2, 1)
    assert as_matrix("C", [1.0, 2.0], (1, None)).shape == (1, 2)
    with pytest.raises(DimensionError, match="X must be 2-D"):
        as_matrix("X", [1.0, 2.0])
    with pytest.raises(ValidationError, match="X must be numeric"):
        as_matrix("X", [["a", "b"]])
    z = as_matrix("Z", [[1 + 1j]], allow_complex=True)
    assert np.iscomplexobj(z)
    with pytest.raises(NotFiniteError, match=r"X must be finite; found inf at index \(0, 1\)"):
        as_matrix("X", [[0.0, np.inf]])


def test_as_vector():
    np.testing.assert_array_equal(as_vector("x", 3.0), [3.0])
    with pytest.raises(DimensionError, match="x has the wrong length: expected 3, found 2"):
        as_vector("x", [1.0, 2.0], 3)
    with pytest.raises(NotFiniteError, match="x must be finite"):
        as_vector("x", [np.nan])
    with pytest.raises(ValidationError, match="x must be real"):
        as_vector("x", [1j])


def test_psd_pd_checks():
    check_psd("Q", np.zeros((2, 2)))
    with pytest.raises(NotSymmetricError, match=r"Q must be symmetric; found max \|Q - Q'\|"):
        check_psd("Q", np.array([[1.0, 1.0], [0.0, 1.0]]))
    with pytest.raises(NotPositiveSemidefiniteError, match="smallest eigenvalue -2"):
        check_psd("Q", np.diag([1.0, -2.0]))
    with pytest.raises(NotPositiveDefiniteError,
                       match="R must be positive definite; found smallest eigenvalue 0"):
        check_pd("R", np.diag([1.0, 0.0]))
    # tiny asymmetry from round-off is accepted and symmetrized
    X = np.array([[2.0, 1.0 + 1e-16], [1.0, 2.0]])
    np.testing.assert_array_equal(check_pd("X", X), check_pd("X", X).T)


def test_as_positive_float():
    assert as_positive_float("dt", 0.5) == 0.5 and as_positive_float("dt", np.float32(0.5)) == 0.5
    assert as_positive_float("k", 3) == 3.0 and type(as_positive_float("k", np.int64(3))) is float
    assert as_positive_float("dt", np.array(0.25)) == 0.25  # a 0-d array is a number
    assert as_positive_float("t", 0, allow_zero=True) == 0.0
    with pytest.raises(NotFiniteError, match="dt must be finite and > 0; found nan"):
        as_positive_float("dt", float("nan"))
    with pytest.raises(ValidationError, match=r"dt must be finite and > 0; found -1"):
        as_positive_float("dt", -1)
    with pytest.raises(ValidationError, match=r"t must be finite and >= 0; found -0.5"):
        as_positive_float("t", -0.5, allow_zero=True)


@pytest.mark.parametrize("bad, kind", [("0.5", "a string"), (b"0.5", "a string"), (True, "bool"),
                                       (np.bool_(True), "bool"), (1 + 0j, "complex"), (None, "NoneType"),
                                       ([0.5], "list"), (np.array([0.5]), "ndarray")])
def test_numbers_written_otherwise_are_refused(bad, kind):
    # issue 11, item 5: numeric strings were accepted silently (float("0.5")); numpy < 2 calls its
    # boolean type bool_
    with pytest.raises(ValidationError, match=rf"dt must be a real number; found .*\({kind}_?\)"):
        as_positive_float("dt", bad)
    with pytest.raises(ValidationError, match=rf"alpha must be a real number; found .*\({kind}_?\)"):
        as_real("alpha", bad)


def test_as_real():
    assert as_real("alpha", -2) == -2.0 and as_real("alpha", np.float64(0.5)) == 0.5
    with pytest.raises(NotFiniteError, match="alpha must be finite; found inf"):
        as_real("alpha", np.inf)


@pytest.mark.parametrize("make", [as_vector, as_poles, as_frequencies])
@pytest.mark.parametrize("bad", [["a", "b"], ["-1", "-2"], "-1", np.array(["1.0"])])
def test_vectors_refuse_strings(make, bad):
    # issue 11, item 5: ["a", "b"] raised a bare numpy ValueError, ["-1", "-2"] was accepted
    with pytest.raises(ValidationError, match=r"x must be (a )?numeric"):
        make("x", bad)


def test_vector_shapes():
    """A (1, k) or (k, 1) array is an unambiguous vector; (2, 2) or (1, 1, k) is not."""
    np.testing.assert_array_equal(as_vector("x", [[1.0, 2.0, 3.0]]), [1.0, 2.0, 3.0])
    np.testing.assert_array_equal(as_vector("x", [[1.0], [2.0]]), [1.0, 2.0])
    # poles are stricter (issue 27 item 6, as scipy's place_poles): a row or a column is refused
    with pytest.raises(DimensionError, match=r"poles must be a 1-D vector of shape \(k,\); found shape \(2, 1\)"):
        as_poles("poles", [[-1.0], [-2.0]], 2)
    for bad in (np.ones((2, 2)), np.ones((1, 1, 3)), np.ones((2, 3))):
        with pytest.raises(DimensionError, match=r"poles must be a vector \(shape \(k,\), or \(1, k\) / "
                                                 r"\(k, 1\)\); found shape"):
            as_poles("poles", bad)
    with pytest.raises(ValidationError, match="poles could not be converted to an array"):
        as_poles("poles", [[-1.0, -2.0], [-3.0]])
    with pytest.raises(NotFiniteError, match=r"x must be finite; found nan at index 1"):
        as_vector("x", [1.0, np.nan])


def test_as_frequencies():
    np.testing.assert_array_equal(as_frequencies("omega", [0, 2.5]), [0.0, 2.5])
    assert as_frequencies("omega", [-1.0], nonnegative=False)[0] == -1.0
    with pytest.raises(NotFiniteError, match=r"omega must be finite; found nan at index 1"):
        as_frequencies("omega", [1.0, np.nan])
    with pytest.raises(ValidationError, match=r"omega must be >= 0 \(rad/s\); found -2 at index 1"):
        as_frequencies("omega", [1.0, -2.0])
    with pytest.raises(DimensionError, match="omega must contain at least one frequency"):
        as_frequencies("omega", [])


def test_as_array():
    assert as_array("signal", [1.0, 2.0], (1, 2)).shape == (2,)
    assert as_array("signal", [[1.0], [2.0]], (1, 2)).shape == (2, 1)
    with pytest.raises(DimensionError, match=r"signal must be 1-D or 2-D; found 0-D shape \(\)"):
        as_array("signal", 3.0, (1, 2))
    with pytest.raises(ValidationError, match="signal must be numeric"):
        as_array("signal", ["1", "2"], (1, 2))
    with pytest.raises(NotFiniteError, match=r"signal must be finite; found inf at index \(1, 0\)"):
        as_array("signal", [[1.0], [np.inf]], (1, 2))


def test_as_options_as_str_as_rng():
    assert as_options("options", None) == {} and as_options("options", {"ipopt.max_iter": 5}) == {
        "ipopt.max_iter": 5}
    with pytest.raises(ValidationError, match=r"options must be a dict of solver options \(name -> value\) "
                                              r"or None; found list \[1, 2\]"):
        as_options("options", [1, 2])
    with pytest.raises(ValidationError, match="options keys must be option names \\(strings\\); found 1"):
        as_options("options", {1: 2})
    assert as_str("method", "pade", ("pade", "sample")) == "pade"
    with pytest.raises(ValidationError, match="method must be one of 'pade', 'sample'; found 'x'"):
        as_str("method", "x", ("pade", "sample"))
    with pytest.raises(ValidationError, match="name must be a string; found int 3"):
        as_str("name", 3)
    g = np.random.default_rng(1)
    assert as_rng("rng", g) is g and isinstance(as_rng("rng", 3), np.random.Generator)
    for bad in (1.5, True, "abc", -1):
        with pytest.raises(ValidationError, match="rng must be None, an integer seed >= 0 or a numpy "
                                                  "Generator; found"):
            as_rng("rng", bad)


def test_as_poles_orders_and_pairs():
    p = as_poles("poles", [-1 - 2j, -3.0, -1 + 2j, -0.5])
    np.testing.assert_allclose(p, [-3.0, -0.5, -1 + 2j, -1 - 2j])
    assert p.dtype == complex


def test_as_poles_conjugate_closure():
    with pytest.raises(NotConjugateClosedError, match=r"\(-1\+2j\) has no partner"):
        as_poles("poles", [-1 + 2j, -3.0])
    with pytest.raises(NotConjugateClosedError, match="has no partner"):
        as_poles("poles", [-1 + 2j, -1 - 2.5j])
    with pytest.raises(NotConjugateClosedError, match="has no partner"):
        as_poles("poles", [-1 - 2j, -2.0])
    with pytest.raises(DimensionError, match="poles has the wrong length: expected 3, found 2"):
        as_poles("poles", [-1.0, -2.0], 3)
    # multiplicity counts: two copies of the upper member need two partners
    with pytest.raises(NotConjugateClosedError):
        as_poles("poles", [-1 + 1j, -1 + 1j, -1 - 1j, -2.0])


def test_status_and_checks():
    assert Status.OPTIMAL.is_solved and Status.SOLVED.is_solved and not Status.INFEASIBLE.is_solved
    assert str(Status.ITERATION_LIMIT) == "iteration_limit"
    c = Check.at_most("pole_error", 1e-12, 1e-9)
    assert c.passed and "ok" in str(c)
    assert not Check.at_most("x", float("nan"), 1.0).passed
    assert not Check.at_least("margin", -1.0, 0.0).passed
    v = Verification.of([c, Check.at_least("margin", 0.5, 0.0)])
    assert v.passed and "pole_error" in v and v["margin"].value == 0.5
    with pytest.raises(KeyError, match="no check named"):
        v["nope"]
    assert not Verification().passed  # no evidence is not a pass


def test_result_mixin_success_requires_verification():
    from dataclasses import dataclass

    @dataclass(frozen=True)
    class R(ResultMixin):
        status: Status
        message: str
        verification: Verification
        solver_stats: SolverStats = SolverStats("ipopt", "Solve_Succeeded")
        certificate: object = None

    ok = R(Status.OPTIMAL, "fine", Verification.of([Check.at_most("e", 0.0, 1.0)]))
    assert ok.success and ok.raise_for_status() is ok
    bad = R(Status.OPTIMAL, "solver said optimal", Verification.of([Check.at_most("pole_error", 1.0, 1e-9)]))
    assert not bad.success
    with pytest.raises(SolverError, match="failed checks: .*pole_error") as info:
        bad.raise_for_status()
    assert info.value.backend == "ipopt" and info.value.native_status == "Solve_Succeeded"
    inf = R(Status.INFEASIBLE, "target infeasible", Verification(), certificate={"omega": 3.0})
    with pytest.raises(InfeasibleError, match="target infeasible") as info2:
        inf.raise_for_status()
    assert info2.value.certificate == {"omega": 3.0}


def test_as_int_and_as_bool():
    assert as_int("starts", 3, 1) == 3 and type(as_int("k", np.int64(2))) is int
    for bad in (0, 1.0, True, "2", None):
        with pytest.raises(ValidationError, match=r"starts must be an integer >= 1; found"):
            as_int("starts", bad, 1)
    assert as_bool("reuse", True) is True and as_bool("reuse", np.bool_(False)) is False
    for bad in (1, 0, "yes", None):
        with pytest.raises(ValidationError, match="reuse must be true or false; found"):
            as_bool("reuse", bad)


def test_as_gain_mask_is_the_one_mask_validator():
    """One validator for the masks of free gain entries (the well-conditioned, robust and engine routes)."""
    assert as_gain_mask("gain_mask", None, 3, 2) is None
    m = as_gain_mask("gain_mask", [[1, 0], [1, 1], [0, 1]], 3, 2)
    assert m.dtype == bool and m.tolist() == [[True, False], [True, True], [False, True]]
    shape = r"gain_mask \(mask of free entries of L\) must have shape \(3, 2\); found \(2, 3\)"
    with pytest.raises(DimensionError, match=shape):
        as_gain_mask("gain_mask", np.ones((2, 3), bool), 3, 2)
    with pytest.raises(DimensionError, match=r"^gain_mask must have shape \(3, 2\)"):
        as_gain_mask("gain_mask", np.ones((2, 3), bool), 3, 2, label="")
    with pytest.raises(ValidationError, match="must be boolean .*found entries other than 0 and 1"):
        as_gain_mask("gain_mask", np.full((3, 2), 0.5), 3, 2)
    with pytest.raises(ValidationError, match="found a ragged or non-numeric list"):
        as_gain_mask("gain_mask", [[True, False], [True]], 3, 2)
    with pytest.raises(ValidationError, match="found dtype <U1"):
        as_gain_mask("gain_mask", np.array([["a", "b"]] * 3), 3, 2)
    with pytest.raises(ValidationError, match="gain_mask has no free entry"):
        as_gain_mask("gain_mask", np.zeros((3, 2), bool), 3, 2)


def test_controllability_is_not_observability():
    """Issue 29: NotControllableError was a subclass of NotObservableError; both now derive from
    UnreachableModesError (a ValueError), and neither is a kind of the other."""
    import optdesign as od

    assert not issubclass(od.NotControllableError, od.NotObservableError)
    assert not issubclass(od.NotObservableError, od.NotControllableError)
    for cls in (od.NotControllableError, od.NotObservableError):
        assert issubclass(cls, od.UnreachableModesError) and issubclass(cls, ValueError)
    A = np.diag([1.0, 2.0])
    B = np.array([[1.0], [0.0]])                         # the mode at 2 is not controllable
    with pytest.raises(od.NotControllableError, match=r"uncontrollable mode\(s\) 2") as info:
        od.place(A, B, [-1.0, -2.0])
    assert not isinstance(info.value, od.NotObservableError)
    np.testing.assert_allclose(info.value.modes, [2.0])
