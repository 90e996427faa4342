"""Issue 26, item 5: every answer of the inverse-Kalman and robust verbs says what ran
(``route``), in order, and which stage answered; ``method`` stays what was asked."""

import numpy as np

import optdesign as od
from optdesign.model.model_set import ModelSet
from optdesign.regions import HalfPlane
from optdesign.results import Route, Status

PLANT = od.Plant([[0, 1], [-6, -5]], [[1, 0]], R=[[1]])


def test_kalman_for_poles_routes():
    eng = od.kalman_for_poles(PLANT, [-5, -8])
    assert isinstance(eng.route, Route) and eng.route.answered.name == "inverse_kalman_engine"
    nlp = od.kalman_for_poles(PLANT, [-5, -8], method="nlp")
    assert nlp.method == "nlp" and nlp.route.answered.kind == "backend"
    zero = od.kalman_for_poles(PLANT, [-2, -3])
    assert zero.route.names == ("zero_noise",) and zero.route.answered.kind == "direct"
    bad = od.kalman_for_poles(PLANT, [1, -3])
    # no design: no stage "answered"; the last stage is the certificate with the verdict
    assert bad.status == Status.INFEASIBLE and bad.route.answered is None
    assert bad.route[-1].kind == "certificate" and bad.route[-1].outcome == "infeasible"
    assert "route" in eng.record() and "route:" in eng.summary()


def test_kalman_for_poles_several_outputs_route_names_both_stages():
    pl = od.Plant(np.diag([-1.0, -2, -3]) + np.diag([1.0, 1], 1), [[1, 0, 0], [0, 1, 1]], R=np.eye(2))
    res = od.kalman_for_poles(pl, [-2, -3, -4], method="sdp")
    assert res.success
    assert res.route.names[0] == "nlp/ipopt" and res.route.answered.name == "fixed_gain_sdp"


def test_is_kalman_optimal_routes():
    di = od.Plant([[0, 1], [0, 0]], [[1, 0]], R=[[1]])
    yes = od.is_kalman_optimal(di, [[4], [3]])
    assert yes.route.names[0] == "circle_condition" and yes.route.answered.kind == "polish"
    no = od.is_kalman_optimal(di, [[0.4], [9.04]])
    assert no.route[0].outcome == "violated" and no.route[-1].name == "return_difference"
    assert no.route.answered is None


def test_robust_routes():
    rng = np.random.default_rng(5)
    A0, C = rng.standard_normal((4, 4)), rng.standard_normal((1, 4))
    ms = ModelSet.polytope([od.Plant(A0 + 1.5 * rng.standard_normal((4, 4)), C) for _ in range(3)])
    lmi = od.robust_lmi_observer(ms, region=HalfPlane(0.5))
    assert lmi.route.names[0] == "robust_lmi" and lmi.route.answered.name == "robust_lmi"
    assert "common_lyapunov_certificate" in lmi.route.names
    nlp = od.robust_observer(ms, region=HalfPlane(0.5), objective="gain", starts=0, per_model_starts=False)
    assert nlp.route.names[0] == "robust_lmi"
    assert nlp.route.answered is not None or not nlp.success
