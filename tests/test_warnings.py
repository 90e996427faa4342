"""One warning of our own where the user must know (issue 26, item 3): solver chatter that makes a
successful answer less trustworthy -- CasADi's ``WARNING("Failed to calculate multipliers")``,
cvxpy's "Solution may be inaccurate" -- gives exactly one :class:`OptDesignWarning` per call (naming
the solver, pointing to ``result.solver_stats``), nested calls counted once, and never the solver's
own text on stderr (checked at the file-descriptor level, where CasADi's C++ code writes)."""

from __future__ import annotations

import re
import warnings

import numpy as np
import pytest

from optdesign.backends import report
from optdesign.backends.casadi_backend import ipopt_solver, run_solver, solve_nlpsol
from optdesign.backends.cvxpy_backend import solve_cvxpy
from optdesign.backends.report import one_warning_per_call
from optdesign.errors import OptDesignWarning
from optdesign.results import SolverStats


def ours(caught) -> list[warnings.WarningMessage]:
    return [w for w in caught if issubclass(w.category, OptDesignWarning)]


def multiplier_failure():
    """An IPOPT solve that succeeds (x = 1) while CasADi cannot compute the multiplier of the
    parameter: d(x sqrt(p))/dp is infinite at p = 0, so CasADi prints ``WARNING("...nlp_grad failed:
    Inf detected...")`` and ``WARNING("Failed to calculate multipliers")`` on descriptor 2 -- the
    chatter of the issue's region designs, in a few milliseconds."""
    import casadi as ca

    x, p = ca.SX.sym("x"), ca.SX.sym("p")
    solver = ipopt_solver({"x": x, "p": p, "f": (x - 1) ** 2 + x * ca.sqrt(p), "g": x})
    return run_solver(solver, np.zeros(1), np.zeros(1), np.array([-10.0]), np.array([10.0]),
                      lambda xs: (lambda _e=None: xs))


def inaccurate_sdp():
    """SCS stopped after 5 iterations: cvxpy warns "Solution may be inaccurate" (optimal_inaccurate)."""
    import cvxpy as cp

    rng = np.random.default_rng(0)
    X = cp.Variable((6, 6), PSD=True)
    M = rng.standard_normal((6, 6))
    prob = cp.Problem(cp.Minimize(cp.norm(X - M @ M.T, "fro")), [cp.trace(X) <= 1.0])
    return solve_cvxpy(prob, "SCS", {"max_iters": 5, "eps_abs": 1e-12, "eps_rel": 1e-12})


def test_casadi_multiplier_failure_is_one_warning_of_ours_and_silent(capfd):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        rep = multiplier_failure()
    out, err = capfd.readouterr()
    assert out == "" and err == ""  # before: CasADi's two WARNING lines on the terminal
    assert rep.status.is_solved and rep.value()[0] == pytest.approx(1.0, abs=1e-6)
    (w,) = ours(caught)
    text = str(w.message)
    assert text.startswith("run_solver: the answer is returned as a success, but during this call casadi")
    assert "casadi could not calculate the multipliers" in text and "result.solver_stats" in text
    assert "WARNING" not in text and w.filename == __file__  # our words, at the caller's line
    assert any("Failed to calculate multipliers" in d for d in rep.stats.extra["solver_doubts"])
    assert len(caught) == 1  # nothing else leaks as a Python warning either


class _Result:
    def __init__(self, success: bool, backend: str, status: str = "optimal") -> None:
        self.success, self.status = success, status
        self.solver_stats = SolverStats(backend=backend)


def test_cvxpy_inaccurate_solution_is_one_warning_of_ours_and_silent(capfd):
    @one_warning_per_call
    def design(status: str) -> _Result:
        inaccurate_sdp()  # e.g. a first SDP, then a polish that ends "optimal"
        return _Result(True, "scs", status)

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = design("optimal")
    out, err = capfd.readouterr()
    assert out == "" and err == ""  # before: cvxpy's UserWarning text on stderr
    (w,) = ours(caught)
    assert "cvxpy reported that its solution may be inaccurate" in str(w.message)
    assert "Try another solver" not in str(w.message)  # never the solver's own text
    assert res.solver_stats.extra["solver_doubts"][0].startswith("cvxpy: Solution may be inaccurate.")
    assert len(caught) == 1
    # a status that already says it (optimal_inaccurate: the backend's own report too) warns nothing,
    # the lines are recorded all the same
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        rep = inaccurate_sdp()
        res = design("optimal_inaccurate")
    assert rep.stats.native_status == "optimal_inaccurate" and caught == []
    assert rep.stats.extra["solver_doubts"] and res.solver_stats.extra["solver_doubts"]
    assert capfd.readouterr() == ("", "")


def test_nested_calls_warn_once_and_only_for_a_success(capfd):
    @one_warning_per_call
    def design(success: bool, backend: str = "ipopt") -> _Result:
        for _ in range(3):
            multiplier_failure()  # each would warn on its own
        inaccurate_sdp()
        return _Result(success, backend)

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = design(True)
    (w,) = ours(caught)
    text = str(w.message)
    assert "casadi could not calculate the multipliers" in text and "(3 times)" in text
    assert "cvxpy" not in text  # an IPOPT answer: the SDP's doubt is recorded, not warned about
    assert text.startswith("test_nested_calls_warn_once_and_only_for_a_success.design: the answer is "
                           "returned as a success")
    first = res.solver_stats.extra["solver_doubts"][0]  # CasADi's time stamp dropped: one line, counted
    assert first.startswith('casadi: WARNING("Failed to calculate multipliers")') and first.endswith("(x3)")
    assert res.solver_stats.extra["solver_doubts"][1].startswith("cvxpy: Solution may be inaccurate")
    for args in ((False,), (True, "slsqp")):  # a failure says so in its status; another solver's answer
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            res = design(*args)
        assert caught == [] and len(res.solver_stats.extra["solver_doubts"]) == 2
    assert capfd.readouterr() == ("", "")


def test_plain_chatter_is_no_warning(capfd):
    import casadi as ca

    x = ca.SX.sym("x", 2)
    problem = {"x": x, "f": (x[0] - 1) ** 2 + (x[1] + 2) ** 2, "g": x[0] + x[1]}
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        rep = solve_nlpsol(problem, [0.0, 0.0], [-10.0], [10.0], {"ipopt.print_level": 5, "ipopt.sb": "no"})
    assert rep.status.is_solved and rep.stats.extra["solver_output"]  # IPOPT's banner and log: captured
    assert ours(caught) == [] and "solver_doubts" not in rep.stats.extra
    assert capfd.readouterr() == ("", "")


def test_a_verb_warns_once_for_all_its_solves(monkeypatch, capfd):
    """A region design runs dozens of IPOPT solves; with a pattern that matches every one of them
    (IPOPT's exit line, printed at print_level 3) the verb still emits exactly one warning, at the
    caller's line, and the count in the result."""
    import optdesign as od
    from optdesign.regions import Disk, HalfPlane

    monkeypatch.setattr(report, "DOUBT_PATTERNS", (
        ("ipopt", re.compile(r"EXIT: Optimal Solution Found"), "printed its exit line"),))
    plant = od.problems.load("compleib_nn2").plant
    # IPOPT alone (route="nlp"): with "multistart" the engine's polish from IPOPT's best answers since
    # the region engine's poles reach the boundary exactly (issue 28: 1.6180339887 vs IPOPT's 1.6180339901)
    from optdesign.design.well_conditioned import WellConditionedProblem

    problem = WellConditionedProblem(plant, region=HalfPlane(0.5) & Disk(0.0, 20.0), starts=3, seed=0,
                                     options={"ipopt.print_level": 3}, route="nlp")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = problem.solve()
    assert res.success
    (w,) = ours(caught)
    assert str(w.message).startswith("WellConditionedProblem.solve: the answer is returned as a success, "
                                     "but during this call ipopt printed its exit line (")
    assert w.filename == __file__
    (line,) = res.solver_stats.extra["solver_doubts"]
    assert re.fullmatch(r"ipopt: EXIT: Optimal Solution Found\. \(x\d+\)", line)
    assert capfd.readouterr() == ("", "")


def test_deprecations_still_point_at_the_callers_line():
    """The verbs' wrapper adds a frame: a renamed argument's DeprecationWarning must still name the
    caller's line, not the wrapper's."""
    import optdesign as od

    plant = od.problems.load("compleib_nn2").plant
    with pytest.warns(DeprecationWarning, match="solver= is deprecated: use nlp_solver=") as rec:
        od.well_conditioned_observer(plant, poles=[-1.0, -2.0], solver="ipopt")
    assert [w.filename for w in rec if issubclass(w.category, DeprecationWarning)] == [__file__]
