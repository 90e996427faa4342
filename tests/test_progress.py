"""Progress on stderr (issue 17, part 2): only on a terminal unless asked, a step per point of a sweep
(not per chunk), one line per paper and figure of a reproduction, and failure reasons in our words."""

from __future__ import annotations

import io
import re
import sys
import time

import pytest

from optdesign._progress import Progress, as_progress, progress_enabled
from optdesign.errors import ValidationError
from optdesign.studies.sweep import IPOPT_MEANING, failure_reason, grid, plain_reason, sweep

CASADI_MESSAGE = ("ipopt: Infeasible_Problem_Detected (Solver failed. You may use opti.debug.value to "
                  "investigate the latest values of variables. return_status is "
                  "'Infeasible_Problem_Detected')")


class FakeTTY(io.StringIO):
    def isatty(self):
        return True


# ------------------------------------------------------------------ the helper


def test_progress_is_silent_off_a_terminal_unless_asked():
    log = io.StringIO()  # not a terminal
    with Progress(3, "demo", stream=log) as p:
        for _ in range(3):
            p.update()
        p.line("an event")
    assert log.getvalue() == "" and not p.enabled
    with Progress(3, "demo", stream=log, enabled=False) as p:
        p.update(3)
    assert log.getvalue() == ""
    with Progress(3, "demo", stream=log, enabled=True, unit="point") as p:  # asked: plain lines
        p.update(note="first")
        p.update()
        p.update(note="2 failed")
        p.line("an   event\nwith a line break")
    lines = log.getvalue().splitlines()
    assert lines[0].startswith("demo: 1/3 points (") and lines[0].endswith("; first")
    assert lines[1].startswith("demo: 3/3 points (") and "100 %" in lines[1]
    assert lines[1].endswith("; 2 failed")
    assert lines[2] == "an event with a line break"
    assert len(lines) == 3  # the second update fell inside the interval: no line for it


def test_progress_draws_a_bar_on_a_terminal():
    pytest.importorskip("tqdm")
    tty = FakeTTY()
    with Progress(4, "sweep", stream=tty, unit="point") as p:
        assert p.enabled and repr(p).endswith("bar)")
        for _ in range(4):
            p.update(note="0 failed")
        p.line("seed 000: wrote a.png")
    text = tty.getvalue()
    assert "sweep" in text and "4/4" in text and "seed 000: wrote a.png" in text


def test_progress_without_tqdm_writes_lines_on_a_terminal(monkeypatch):
    monkeypatch.setitem(sys.modules, "tqdm", None)  # import tqdm fails
    tty = FakeTTY()
    with Progress(2, "reproduce", stream=tty, unit="paper") as p:
        p.update()
        p.update()
    assert tty.getvalue().splitlines()[-1].startswith("reproduce: 2/2 papers")


def test_progress_delay_keeps_a_short_run_silent():
    log = io.StringIO()
    with Progress(2, "sweep", stream=log, enabled=True, delay=60.0) as p:
        p.update(2)
    assert log.getvalue() == ""


def test_progress_enabled_follows_the_stream():
    assert progress_enabled(None, FakeTTY()) is True
    assert progress_enabled(None, io.StringIO()) is False
    assert progress_enabled(True, io.StringIO()) is True and progress_enabled(False, FakeTTY()) is False


@pytest.mark.parametrize("call, match", [
    (lambda: as_progress("yes"), "progress must be True, False or None .* found 'yes'"),
    (lambda: as_progress(1), "progress must be True, False or None"),
    (lambda: Progress(-1, "x"), "total must be an integer >= 0 or None; found -1"),
    (lambda: Progress(2.5, "x"), "total must be an integer >= 0 or None; found 2.5"),
    (lambda: Progress(2, "x", interval=-1), "interval must be a number of seconds >= 0; found -1"),
    (lambda: Progress(2, "x", delay="1"), "delay must be a number of seconds >= 0; found '1'"),
    (lambda: Progress(2, "x", bar="no"), "bar must be True, False or None"),
    (lambda: sweep(_square, grid(a=[1]), executor="serial", progress="on"), "progress must be True, False"),
])
def test_progress_arguments_are_checked(call, match):
    with pytest.raises(ValidationError, match=match):
        call()


# ------------------------------------------------------------------ sweeps: one step per point


def _square(a):
    return {"status": "optimal", "success": True, "y": a * a}


def _slow(a):
    time.sleep(0.4)
    if a == 1:
        return {"status": "not_found", "success": False, "message": CASADI_MESSAGE}
    return {"status": "optimal", "success": True, "y": a * a}


@pytest.mark.parametrize("executor", ["serial", "threads", "processes"])
def test_sweep_reports_every_point_not_every_chunk(executor, monkeypatch):
    # one chunk of 4 points: a per-chunk report could only say 4/4 at the end (issue 17: "tqdm updates
    # only per chunk; a 4-point serial sweep shows no bar").  Points end at >= 0.4, 0.8, 1.2, 1.6 s;
    # the report starts after 1 s, so a line for point 3 (or earlier) must appear before 4/4.
    log = io.StringIO()
    monkeypatch.setattr(sys, "stderr", log)
    t = sweep(_slow, grid(a=[0, 1, 2, 3]), executor=executor, chunksize=4, workers=1, progress=True)
    lines = log.getvalue().splitlines()
    assert t.n_success == 3
    assert any(re.match(r"sweep: [123]/4 points", ln) for ln in lines), lines
    assert lines[-1].startswith("sweep: 4/4 points") and lines[-1].endswith("; 1 failed")


def test_sweep_progress_is_quiet_off_a_terminal_by_default(capsys):
    sweep(_slow, grid(a=[0, 2, 3]), executor="serial", chunksize=3)
    assert capsys.readouterr().err == ""


def test_sweep_results_do_not_depend_on_progress():
    quiet = sweep(_slow, grid(a=[0, 1, 2]), executor="threads", chunksize=3, progress=False)
    shown = sweep(_slow, grid(a=[0, 1, 2]), executor="threads", chunksize=3, progress=True)
    assert shown.diff(quiet) == []


# ------------------------------------------------------------------ failure reasons in our words


def test_failure_reasons_are_in_our_words():
    t = sweep(_slow, grid(a=[1]), executor="serial", progress=False)
    reason = t.records[0]["reason"]
    assert reason.startswith("not_found: no verified design found (a local method: feasibility unknown)")
    assert IPOPT_MEANING["Infeasible_Problem_Detected"] in reason
    for leak in ("opti.debug", "return_status", "Solver failed", "Infeasible_Problem_Detected"):
        assert leak not in reason


def _raises_casadi_error(a):
    raise RuntimeError(".../casadi/core/optistack.cpp:217: Error in Opti::solve [OptiNode] at "
                       ".../optistack_internal.cpp:1333: Assertion \"return_success(accept_if_suboptimal)\" "
                       "failed:\nSolver failed. You may use opti.debug.value to investigate the latest "
                       "values of variables. return_status is 'Maximum_Iterations_Exceeded'")


def test_errors_are_recorded_without_casadi_advice():
    r = sweep(_raises_casadi_error, grid(a=[1]), executor="serial", progress=False).records[0]
    assert r["success"] is False and r["error"].startswith("RuntimeError:")
    assert r["reason"].startswith("error: the design raised an error; RuntimeError")
    for text in (r["error"], r["reason"]):
        assert "opti.debug" not in text and ".cpp" not in text and "Assertion" not in text


@pytest.mark.parametrize("native, meaning", sorted(IPOPT_MEANING.items()))
def test_every_ipopt_status_is_spelled_out(native, meaning):
    text = (f"best of 2 starts: ipopt: {native} (Solver failed. You may use opti.debug.value to investigate "
            f"the latest values of variables. return_status is '{native}')")
    assert plain_reason(text) == f"best of 2 starts: {meaning}"


def test_failure_reason_names_a_failed_check():
    from optdesign.results import Check

    c = Check.at_most("pole_error", 3e-5, 1e-8)
    text = failure_reason("optimal", "ipopt: Solve_Succeeded", c)
    assert text == ("optimal but not verified: the independent check pole_error = 3e-05 (must be <= 1e-08) "
                    "fails; IPOPT converged")
    assert failure_reason("iteration_limit", "IPOPT stopped\n after 3000 iterations", c) == (
        "iteration_limit: the iteration limit ran out before a verified design was found; failed check "
        "pole_error = 3e-05 (must be <= 1e-08); IPOPT stopped after 3000 iterations")
    assert plain_reason("ipopt: Some_New_Status") == "IPOPT stopped with status Some_New_Status"


# ------------------------------------------------------------------ notebooks (issue 30)


class _FakeKernel:
    """Stands for IPython's kernel shell, whose class name marks a Jupyter notebook."""


_FakeKernel.__name__ = "ZMQInteractiveShell"


def test_progress_shows_in_a_notebook_without_a_terminal(monkeypatch):
    import types

    import optdesign._progress as prog

    assert prog.in_notebook() is False or "IPython" in sys.modules
    fake = types.ModuleType("IPython")
    fake.get_ipython = lambda: _FakeKernel()
    monkeypatch.setitem(sys.modules, "IPython", fake)
    assert prog.in_notebook() is True
    err = io.StringIO()  # a notebook's stderr is not a terminal
    monkeypatch.setattr(sys, "stderr", err)
    assert progress_enabled(None) is True
    assert progress_enabled(None, io.StringIO()) is False  # another stream: still only on a terminal
    monkeypatch.setattr(prog, "_tqdm_class", lambda notebook=False: None)  # no tqdm.auto/ipywidgets
    with Progress(2, "demo", unit="step") as p:
        p.update()
        p.update()
    assert p.enabled and err.getvalue().splitlines()[-1].startswith("demo: 2/2 steps")
    fake.get_ipython = lambda: None  # plain IPython loaded, no kernel
    assert prog.in_notebook() is False


def test_pareto_with_progress_false_is_silent_in_a_notebook(monkeypatch):
    """``studies.pareto(progress=False)``: its anchors and levels are designs of their own, whose
    automatic progress turns on in a notebook; a study's point never reports its starts."""
    import types

    import optdesign._progress as prog
    from optdesign import Plant
    from optdesign.regions import Disk, HalfPlane
    from optdesign.studies import pareto

    fake = types.ModuleType("IPython")
    fake.get_ipython = lambda: _FakeKernel()
    monkeypatch.setitem(sys.modules, "IPython", fake)
    monkeypatch.setattr(prog, "_tqdm_class", lambda notebook=False: None)
    err = io.StringIO()
    monkeypatch.setattr(sys, "stderr", err)
    plant = Plant([[0.0, 1.0], [-2.0, -0.5]], [[1.0, 0.0]])
    front = pareto(plant, HalfPlane(0.5) & Disk(0, 10), ("kappa2", "gain_norm"), levels=2, starts=1,
                   progress=False)
    assert front.front()
    assert err.getvalue() == ""
