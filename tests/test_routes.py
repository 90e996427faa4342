"""Every verb's result says what ran (issue 26 item 2): ``route`` is a non-empty Route whose answering
stage exists for a successful design, and ``summary()`` / ``record()`` carry it."""

from __future__ import annotations

import numpy as np
import pytest

import optdesign as od
from optdesign import Plant
from optdesign.model.model_set import ModelSet
from optdesign.regions import Disk, HalfPlane
from optdesign.results import DesignResult, Route

PLANT = Plant([[0.0, 1.0], [-6.0, -5.0]], [[1.0, 0.0]], Q=np.eye(2), R=[[1.0]], B=[[0.0], [1.0]])
BARE = Plant([[0.0, 1.0], [-6.0, -5.0]], [[1.0, 0.0]])

VERBS = {
    "kalman": lambda: od.kalman(PLANT),
    "kalmd": lambda: od.kalmd(PLANT, 0.1),
    "kalman_for_poles": lambda: od.kalman_for_poles(PLANT, [-5.0, -8.0]),
    "is_kalman_optimal": lambda: od.is_kalman_optimal(PLANT, od.kalman(PLANT).L),
    "well_conditioned_observer (poles)": lambda: od.well_conditioned_observer(PLANT, poles=[-5.0, -8.0]),
    "well_conditioned_observer (region)": lambda: od.well_conditioned_observer(
        BARE, region=HalfPlane(2.0) & Disk(0.0, 20.0), starts=2),
    "well_conditioned_kalman": lambda: od.well_conditioned_kalman(PLANT),
    "place": lambda: od.place(PLANT.A, PLANT.B, [-5.0, -8.0]),
    "well_conditioned_feedback": lambda: od.well_conditioned_feedback(PLANT, poles=[-5.0, -8.0]),
    "lqr_for_poles": lambda: od.lqr_for_poles(PLANT, [-5.0, -8.0]),
    "riccati_de": lambda: od.riccati_de(PLANT, np.eye(2), 1.0),
    "robust_observer": lambda: od.robust_observer(ModelSet([BARE, Plant(1.1 * BARE.A, BARE.C)])),
    "robust_lmi_observer": lambda: od.robust_lmi_observer(ModelSet([BARE, Plant(1.1 * BARE.A, BARE.C)])),
    "output_delay_kalman": lambda: od.output_delay_kalman(PLANT.A, PLANT.C, PLANT.C, 0.1, np.eye(2), np.eye(1)),
    "generalized_observer": lambda: od.generalized_observer(
        Plant([[0.5]], [[1.0]], dt=0.1), od.noise.Step(), poles=[0.2, 0.3]),
}


@pytest.mark.parametrize("verb", VERBS)
def test_every_verb_says_what_ran(verb):
    res = VERBS[verb]()
    assert isinstance(res, DesignResult)
    assert isinstance(res.route, Route) and len(res.route) >= 1, f"{verb}: empty route"
    assert res.success, res.message
    answered = res.route.answered
    assert answered is not None, f"{verb}: no stage answered: {res.route}"
    assert f"route: {res.route}" in res.summary()
    assert res.record()["route"] == answered.name
