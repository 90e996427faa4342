"""Bad input reaching the design verbs is refused with a typed error naming the argument (issue 11,
item 5).

The checks live in the shared validators (``optdesign._validate``), so one fix covers every verb;
these tests hold the verbs to it.  Before the fix: ``kalman_for_poles(plant, ["a", "b"])`` raised a
bare numpy ValueError, numeric strings (``["-5", "-8"]``, ``dt="0.1"``, ``t_final="10"``) were
converted silently, and ``problems.load(3)`` raised an AttributeError.
"""

from __future__ import annotations

import numpy as np
import pytest

import optdesign as od
from optdesign.classical.placement import place_observer
from optdesign.errors import DimensionError, NotFiniteError, OptDesignError, ValidationError

PLANT = od.Plant(A=[[0.0, 1.0], [-6.0, -5.0]], C=[[1.0, 0.0]], Q=np.eye(2), R=[[1.0]])  # seed 000, Ex 1

VERBS = {
    "kalman_for_poles": lambda poles: od.kalman_for_poles(PLANT, poles),
    "well_conditioned_observer": lambda poles: od.well_conditioned_observer(PLANT, poles=poles),
    "solheim": lambda poles: od.classical.solheim(PLANT, poles),
    "place_observer": lambda poles: place_observer(PLANT, poles),
    # one state and a step-noise state: two poles
    "generalized_observer": lambda poles: od.generalized_observer(od.Plant([[0.5]], [[1.0]], dt=0.1),
                                                                  od.noise.Step(), poles=poles),
}


@pytest.mark.parametrize("verb", VERBS)
@pytest.mark.parametrize("poles, error, match", [
    (["a", "b"], ValidationError, "poles must be numeric; found dtype <U1"),
    (["-5", "-8"], ValidationError, "poles must be numeric; found dtype <U2 .e.g. '-5': numbers written as "
                                    "strings are not accepted"),
    ("-5, -8", ValidationError, "poles must be a numeric vector; found the string '-5, -8'"),
    (-np.ones((2, 2)), DimensionError, r"poles must be a vector \(shape \(k,\), or \(1, k\) / \(k, 1\)\); "
                                       r"found shape \(2, 2\)"),
    ([-5.0, np.nan], NotFiniteError, "poles must be finite; found nan at index 1"),
    ([[-5.0, -8.0], [-1.0]], ValidationError, "poles could not be converted to an array"),
])
def test_bad_poles_are_refused_by_every_verb(verb, poles, error, match):
    with pytest.raises(error, match=match) as info:
        VERBS[verb](poles)
    assert isinstance(info.value, OptDesignError)


@pytest.mark.parametrize("verb", VERBS)
def test_a_row_or_a_column_of_poles_is_refused(verb):
    """Issue 27 item 6: scipy's place_poles refuses poles of shape (4, 1); so does every verb (0.1 flattened
    a row or a column silently)."""
    for shaped in ([[-5.0, -8.0]], [[-5.0], [-8.0]]):
        with pytest.raises(DimensionError, match=r"poles must be a 1-D vector of shape \(k,\); found shape "):
            VERBS[verb](shaped)


def test_numbers_written_as_strings_are_refused():
    with pytest.raises(ValidationError, match="dt must be a real number; found '0.1' .a string."):
        od.Plant(A=[[0.5]], C=[[1.0]], dt="0.1")
    with pytest.raises(ValidationError, match="t_final must be a real number"):
        od.riccati_de(PLANT, np.eye(2), t_final="10")
    with pytest.raises(ValidationError, match="omega must be numeric"):
        od.return_difference(PLANT, od.kalman(PLANT).L, ["1"])
    with pytest.raises(ValidationError, match="name must be a string; found int 3"):
        od.problems.load(3)


def test_options_must_be_a_mapping():
    with pytest.raises(ValidationError, match=r"options must be a dict of solver options \(name -> value\) "
                                              r"or None; found list \[1, 2\]"):
        od.well_conditioned_observer(PLANT, poles=[-1.0, -2.0], options=[1, 2])


@pytest.mark.parametrize("omega, match", [([1.0, np.nan], "omega must be finite; found nan at index 1"),
                                          (["1"], "omega must be numeric"),
                                          ([-1.0], r"omega must be .*>= 0 \(rad/s\)")])
def test_is_kalman_optimal_refuses_a_bad_frequency_grid(omega, match):
    # issue 11, item 5: a NaN frequency gave a NaN certificate (the circle condition's error was swallowed)
    L = od.kalman(PLANT).L
    with pytest.raises(ValidationError, match=match):
        od.is_kalman_optimal(PLANT, L, omega=omega)
