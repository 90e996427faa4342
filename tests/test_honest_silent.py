"""Issue 26, items 4 and 6: library code never prints (solver chatter is captured into the
result's ``solver_stats.extra``); a bogus solver option is a typed error naming it."""

import numpy as np
import pytest

from optdesign.backends.casadi_backend import solve_nlpsol
from optdesign.backends.cvxpy_backend import solve_cvxpy
from optdesign.backends.report import captured_output
from optdesign.errors import ValidationError


def test_captured_output_takes_python_native_and_warnings(capfd):
    import os
    import warnings
    with captured_output() as cap:
        print("python line")
        os.write(2, b"native line\n")
        warnings.warn("Solution may be inaccurate", UserWarning, stacklevel=1)
    out, err = capfd.readouterr()
    assert out == "" and err == ""
    assert cap.lines == ["python line", "native line"]
    assert cap.warnings == ["Solution may be inaccurate"]


def test_ipopt_chatter_never_reaches_the_terminal(capfd):
    import casadi as ca
    x = ca.SX.sym("x", 2)
    problem = {"x": x, "f": (x[0] - 1) ** 2 + (x[1] + 2) ** 2, "g": x[0] + x[1]}
    # print_level 5 and no "sb": IPOPT's banner and iteration log (what reached users' terminals)
    rep = solve_nlpsol(problem, [0.0, 0.0], [-10.0], [10.0],
                       {"ipopt.print_level": 5, "ipopt.sb": "no", "print_time": True})
    out, err = capfd.readouterr()
    assert out == "" and err == ""
    assert rep.status.is_solved
    assert any("Ipopt" in ln or "iter" in ln for ln in rep.stats.extra["solver_output"])


def test_cvxpy_inaccurate_warning_is_captured(capfd):
    import cvxpy as cp
    rng = np.random.default_rng(0)
    X = cp.Variable((6, 6), PSD=True)
    M = rng.standard_normal((6, 6))
    prob = cp.Problem(cp.Minimize(cp.norm(X - M @ M.T, "fro")), [cp.trace(X) <= 1.0])
    rep = solve_cvxpy(prob, "SCS", {"max_iters": 5, "eps_abs": 1e-12, "eps_rel": 1e-12})
    out, err = capfd.readouterr()
    assert out == "" and err == ""
    assert rep.stats.native_status == "optimal_inaccurate"
    assert any("inaccurate" in w for w in rep.stats.extra["solver_warnings"])


def test_bogus_clarabel_option_is_a_typed_error():
    import cvxpy as cp
    x = cp.Variable()
    prob = cp.Problem(cp.Minimize(x), [x >= 1])
    with pytest.raises(ValidationError, match="unknown CLARABEL option 'not_a_setting'"):
        solve_cvxpy(prob, "CLARABEL", {"not_a_setting": 3})


def test_bogus_option_through_a_verb():
    import optdesign as od
    di = od.Plant([[0, 1], [0, 0]], [[1, 0]], R=[[1]])
    from optdesign.backends.cvxpy_backend import check_solver_options
    with pytest.raises(ValidationError, match="unknown SCS option 'eps'"):
        check_solver_options("SCS", {"eps": 1e-3})
    assert od.is_kalman_optimal(di, [[4], [3]]).status.is_solved


def test_region_design_on_dis1_prints_nothing(capfd):
    """A region-mode design on COMPleib DIS1 printed CasADi's ``WARNING("Failed to calculate
    multipliers")`` three times per design (issue 26); every IPOPT call now runs captured."""
    import optdesign as od
    from optdesign.regions import Disk, HalfPlane, Sector
    plant = od.problems.load("compleib_dis1").plant
    region = HalfPlane(0.3) & Sector.from_damping(0.5) & Disk(0, 10.0)
    res = od.well_conditioned_observer(plant, region=region, time_limit=4)
    out, err = capfd.readouterr()
    assert out == "" and err == ""
    assert res.L is not None


def test_captured_output_on_a_thread_pool_restores_the_streams():
    """Overlapping captures on several threads (a study on the threads executor) share one redirect: the
    streams are restored whatever order the threads finish in, and nothing captured is lost (before:
    each block saved the streams another thread had already redirected, so after the pool the process's
    stdout stayed redirected and the CLI's next print vanished)."""
    import sys
    import time
    from concurrent.futures import ThreadPoolExecutor

    from optdesign.backends.report import captured_output

    out_before, err_before = sys.stdout, sys.stderr

    def work(i):
        with captured_output() as cap:
            print("inside", i)
            time.sleep(0.002 * (i % 3))
        return cap.text

    with ThreadPoolExecutor(4) as pool:
        texts = list(pool.map(work, range(24)))
    assert sys.stdout is out_before and sys.stderr is err_before
    assert sum(t.count("inside") for t in texts) == 24
