"""Sweeps: grids, tables, failures recorded, executors (in-process, threads, processes, Dask) giving
identical results, parameter re-use in the region designer, progress bar only on a terminal."""

from __future__ import annotations

import io
import json
import logging
import math
import os
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import FULL

from optdesign import Plant, problems
from optdesign.design.verification import kappa2_agreement_tol
from optdesign.design.well_conditioned import WellConditionedProblem
from optdesign.errors import (
    NotConjugateClosedError,
    NotObservableError,
    ProblemNotFoundError,
    ValidationError,
)
from optdesign.regions import Disk, HalfPlane, Sector
from optdesign.results import Check, Status, Verification
from optdesign.studies import (
    InlineExecutor,
    KalmanNoiseDesigner,
    PoleTargetDesigner,
    RegionSweepDesigner,
    SweepTable,
    grid,
    place_baseline,
    record_of,
    sweep,
)
from optdesign.studies.designers import SWEEP_IPOPT_OPTIONS, clear_cache
from optdesign.studies.sweep import default_chunksize

# ------------------------------------------------------------------ module-level design functions
# (picklable: process pools and Dask workers import them from this module or receive them by value)


def square(a, b=0.0):
    if a == 3:
        raise ZeroDivisionError("a = 3 is\nnot allowed")
    return {"status": "optimal", "success": a >= 0, "y": a * a + b}


def slow_square(a):
    time.sleep(0.25)
    return {"status": "optimal", "success": True, "y": a * a}


def sleepy(a, folder=None):
    if folder is not None:  # say which process runs the point
        Path(folder, f"worker{a}.pid").write_text(str(os.getpid()))
    time.sleep(30.0)
    if folder is not None:  # say that the point ran to its end
        Path(folder, f"finished{a}").write_text("done")
    return {"status": "optimal", "success": True}


def _running(pid: int) -> bool:
    """The process exists and is not a zombie (Linux ``/proc``)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


def crash_on_two(a):
    if a == 2:
        os._exit(3)  # a worker process dying (e.g. a segfault in a native solver)
    return {"status": "optimal", "success": True, "y": a}


# a fast COMPleib plant (DIS2: n = 3, p = 2, unstable) for the region designer
DESIGNER = RegionSweepDesigner(problem="compleib_dis2", radius=20.0)
N_ALPHA, N_ZETA = (40, 25) if FULL else (3, 3)
# zeta descending: along a chunk the sector widens (the region gets looser)
POINTS = grid(alpha=np.linspace(0.5, 3.0, N_ALPHA), zeta=np.linspace(0.8, 0.3, N_ZETA))
CHUNK = N_ZETA  # one chunk per alpha: warm starts run along zeta


# ------------------------------------------------------------------ grid / records


def test_grid_is_the_product_last_axis_fastest():
    g = grid(alpha=np.array([1.0, 2.0]), zeta=(0.5, 0.6, 0.7), name="x")
    assert len(g) == 6
    assert g[0] == {"alpha": 1.0, "zeta": 0.5, "name": "x"} and g[1]["zeta"] == 0.6 and g[3]["alpha"] == 2.0
    assert type(g[0]["alpha"]) is float  # numpy scalars become Python scalars
    assert grid(a=range(3), b=(x for x in "pq")) == [{"a": i, "b": c} for i in range(3) for c in "pq"]


@pytest.mark.parametrize("axes, match", [({}, "at least one axis"), ({"a": []}, "axis 'a' is empty")])
def test_grid_errors(axes, match):
    with pytest.raises(ValidationError, match=match):
        grid(**axes)


def test_record_of_uses_record_and_renames_solver_time():
    class R:
        status = Status.OPTIMAL
        success = True

        def record(self):
            return {"kappa2": np.float64(2.5), "time": 0.1, "L": np.eye(2), "status": Status.OPTIMAL}

    rec = record_of(R())
    assert rec == {"kappa2": 2.5, "solver_time": 0.1, "status": "optimal", "success": True, "reason": None}
    assert type(rec["kappa2"]) is float
    # an unsuccessful result says why, in one line: its status in words, its first failed check, its message
    failed = Verification.of([Check.at_most("pole_error", 0.5, 1e-8, "poles"), Check.at_most("x", 0, 1)])

    class Bad:
        status = Status.ITERATION_LIMIT
        success = False
        verification = failed
        message = "IPOPT stopped\n  after 3000 iterations"

    why = record_of(Bad())["reason"]
    assert why == ("iteration_limit: the iteration limit ran out before a verified design was found; "
                   "failed check pole_error = 0.5 (must be <= 1e-08); IPOPT stopped after 3000 iterations")
    assert record_of({"a": 1, "b": [1, 2]}) == {"a": 1}
    assert record_of(3.0) == {"value": 3.0}


# ------------------------------------------------------------------ sweep basics and failures


def test_sweep_records_failures_without_crashing():
    t = sweep(square, grid(a=[0, 1, 2, 3, -1]), executor="serial")
    assert len(t) == 5 and t.inputs == ("a",)
    assert t.column("y")[:3].tolist() == [0.0, 1.0, 4.0]
    bad = t[3]
    assert bad["success"] is False and bad["status"] == "error"
    assert bad["error"].startswith("ZeroDivisionError: a = 3 is not allowed at test_sweep.py:")
    assert "\n" not in bad["error"]
    assert t[4]["success"] is False and t[4]["error"] is None  # ran, but did not succeed
    assert [r["a"] for r in t.failures] == [3, -1] and t.n_success == 3
    assert "5 points, 3 successful, 2 failed (1 with errors)" in t.summary()


def test_sweep_accepts_axes_and_any_executor_object():
    t = sweep(square, {"a": [1, 2], "b": [10.0]}, executor=InlineExecutor())
    assert t.column("y").tolist() == [11.0, 14.0]
    assert t.meta["executor"] == "InlineExecutor"


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"points": []}, "at least one point"),
        ({"points": [1, 2]}, "point 0 must be a dict"),
        ({"points": "a"}, "points must be a sequence"),
        ({"design_fn": 3}, "design_fn must be callable"),
        ({"chunksize": 0}, "chunksize must be an integer >= 1"),
        ({"timeout": -1}, "timeout must be a positive number"),
        ({"workers": 0}, "workers must be an integer >= 1"),
        ({"executor": "gpu"}, "executor must be a concurrent.futures.Executor"),
        ({"executor": object()}, "must have a submit"),
        ({"design_fn": lambda a: a, "executor": "processes"}, "design_fn must be picklable"),
    ],
)
def test_sweep_argument_errors(kwargs, match):
    args = {"design_fn": square, "points": grid(a=[1]), "executor": "serial"}
    args.update(kwargs)
    with pytest.raises(ValidationError, match=match):
        sweep(args.pop("design_fn"), args.pop("points"), **args)


def test_inline_executor_refuses_after_shutdown():
    ex = InlineExecutor()
    assert ex.submit(pow, 2, 3).result() == 8
    ex.shutdown()
    with pytest.raises(RuntimeError, match="after shutdown"):
        ex.submit(pow, 2, 3)


def test_default_chunksize_depends_on_the_points_only():
    assert [default_chunksize(n) for n in (1, 9, 16, 17, 100, 1000, 10**6)] == [1, 1, 1, 2, 7, 32, 32]


def test_a_dying_worker_is_recorded_not_raised():
    t = sweep(crash_on_two, grid(a=[0, 1, 2, 3]), executor="processes", workers=2, chunksize=1)
    assert len(t) == 4
    assert t[2]["success"] is False and "task failed in the executor" in t[2]["error"]
    assert "BrokenProcessPool" in t[2]["error"]


def test_timeout_records_unfinished_points_and_stops_the_pool(tmp_path):
    t = sweep(sleepy, grid(a=[1, 2], folder=[str(tmp_path)]), executor="processes", workers=2, chunksize=1,
              timeout=2.0)
    assert not list(tmp_path.glob("finished*"))  # returned before the 30 s points could end
    assert all(not r["success"] and r["error"].startswith("timed out") for r in t)
    assert t.meta["timed_out"] is True
    # the workers running the points were terminated, not left sleeping in the background
    pids = [int(f.read_text()) for f in sorted(tmp_path.glob("worker*.pid"))]
    assert len(pids) == 2 and os.getpid() not in pids
    if Path("/proc/self/stat").is_file():
        deadline = time.monotonic() + 10.0
        while any(_running(pid) for pid in pids) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert not any(_running(pid) for pid in pids)


# ------------------------------------------------------------------ table I/O


def test_table_csv_json_pivot_and_diff(tmp_path):
    t = sweep(square, grid(a=[0, 1, 2], b=[0.5, 1.5]), executor="serial")
    t.records[0]["kappa2"] = math.inf
    back = SweepTable.from_csv(t.to_csv(tmp_path / "t.csv"), inputs=t.inputs)
    assert back.diff(t, ignore=("time", "worker", "error")) == []
    assert back.column("kappa2")[0] == math.inf
    data = json.loads(t.to_json(tmp_path / "t.json"))
    assert data["records"][0]["kappa2"] == "inf" and data["inputs"] == ["a", "b"]
    xs, ys, Z = t.pivot("a", "b", "y")
    assert xs.tolist() == [0, 1, 2] and ys.tolist() == [0.5, 1.5]
    assert Z[1, 2] == 2 * 2 + 1.5
    other = sweep(square, grid(a=[0, 1, 2], b=[0.5, 1.5]), executor="serial")
    other.records[4]["y"] = 99.0
    d = t.diff(other)
    assert d == ["record 0 column 'kappa2': inf vs None", "record 4 column 'y': 4.5 vs 99.0"]
    with pytest.raises(ValidationError, match="no column 'nope'"):
        t.column("nope")


# ------------------------------------------------------------------ progress bar


def test_progress_automatic_is_quiet_when_not_a_terminal(capsys):
    t = sweep(slow_square, grid(a=range(6)), executor="serial")  # ~1.5 s, progress=None (automatic)
    assert len(t) == 6
    assert capsys.readouterr().err == ""


def test_progress_forced_writes_plain_lines_when_not_a_terminal(capsys):
    sweep(slow_square, grid(a=range(6)), executor="serial", progress=True)  # ~1.5 s
    err = capsys.readouterr().err
    assert "sweep" in err and "6/6" in err  # the last line is always written


def test_progress_bar_shown_on_a_terminal_after_a_second(monkeypatch):
    pytest.importorskip("tqdm")

    class FakeTTY(io.StringIO):
        def isatty(self):
            return True

    fake = FakeTTY()
    monkeypatch.setattr(sys, "stderr", fake)
    sweep(square, grid(a=range(2)), executor="serial")  # well under a second: no bar
    assert fake.getvalue() == ""
    sweep(slow_square, grid(a=range(6)), executor="serial")  # 1.5 s: a bar
    assert "sweep" in fake.getvalue() and "6/6" in fake.getvalue() and "point" in fake.getvalue()
    fake.truncate(0)
    fake.seek(0)
    sweep(slow_square, grid(a=range(6)), executor="serial", progress=False)  # silenced on a terminal too
    assert fake.getvalue() == ""


# ------------------------------------------------------------------ region designer: re-use, verification


def test_region_designer_reuses_its_nlp_and_verifies_every_point():
    clear_cache()
    # placement="always": the first point runs the placement starts on the NLP (the default "pool"
    # probes a chunk's first point for a normal closed loop first, which attains kappa2 = 1 here)
    session = RegionSweepDesigner(problem="compleib_dis2", radius=20.0, placement="always").start_chunk()
    first = session(alpha=1.0, zeta=0.5)
    second = session(alpha=1.2, zeta=0.5)
    assert first.success and second.success
    assert first.solver_stats.extra["nlp_builds"] >= 1
    assert second.solver_stats.extra["nlp_builds"] == 0  # re-solved with new parameter values
    assert second.starts[0].origin == "warm start"
    # the warm start's own gain attains kappa2 = 1 (the lower bound) in the looser region: no IPOPT at all
    assert second.solver_stats.iterations == 0 and [r.origin for r in second.starts] == ["warm start"]
    region = HalfPlane(1.2) & Sector.from_damping(0.5) & Disk(0.0, 20.0)
    # independent check of the answer: poles of A - L C with numpy, inside the point's region
    plant = DESIGNER._plant()
    poles = np.linalg.eigvals(plant.A - second.L @ plant.C)
    assert region.contains(poles, tol=1e-6)
    assert np.max(poles.real) <= -1.2 + 1e-6
    assert {"stability", "region_margin"} <= {c.name for c in second.verification}
    # IPOPT's eigenbasis is checked against numpy's where a solver gave one (the first point); the second
    # point's answer is the first point's gain itself (kappa2 = 1 is the lower bound: no start runs after
    # the warm start), which comes without a solver basis
    assert {"eig_residual", "kappa2_agreement"} <= {c.name for c in first.verification}
    # rebuild mode: same algorithm, a fresh NLP for every point
    rebuilt = RegionSweepDesigner(problem="compleib_dis2", radius=20.0, reuse=False)(alpha=1.2, zeta=0.5)
    assert rebuilt.solver_stats.extra["nlp_builds"] >= 1
    assert rebuilt.success and rebuilt.kappa2 >= 1.0


def test_region_designer_probes_a_chunks_first_point():
    """The default placement="pool" probes a chunk's first point for a normal closed loop in the
    region: at (alpha 1, zeta 0.5) it finds one, kappa2 = 1 (the lower bound) with no NLP built and no
    IPOPT iteration; placement="always" (no probe) runs IPOPT from its placement starts there."""
    clear_cache()
    first = DESIGNER.start_chunk()(alpha=1.0, zeta=0.5)
    assert DESIGNER.placement == "pool"
    assert first.success and first.kappa2 <= 1.0 + kappa2_agreement_tol(1.0)
    assert first.solver_stats.extra["nlp_builds"] == 0 and first.solver_stats.iterations == 0
    poles = np.linalg.eigvals(DESIGNER._plant().A - first.L @ DESIGNER._plant().C)
    assert (HalfPlane(1.0) & Sector.from_damping(0.5) & Disk(0.0, 20.0)).contains(poles, tol=1e-9)
    always = RegionSweepDesigner(problem="compleib_dis2", radius=20.0, placement="always")
    always = always(alpha=1.0, zeta=0.5)
    assert always.success and always.solver_stats.iterations > 0
    assert always.kappa2 >= 1.0 - kappa2_agreement_tol(1.0)  # (nothing beats the bound the probe attains)


def test_region_designer_runs_a_failing_starts_last_stage():
    """COMPleib HE1, alpha 0.75, zeta 0.8 (the example study's chunk start): both placement starts fail
    the free-pole NLP's first two stages (IPOPT's iteration limit); the exact-kappa2 last stage from the
    sampled start converges to a verified 50.24, where giving the starts up kept the naive start's own
    gain, kappa2 725 (the example study's table showed it from the region-core split of 0.2.0 on)."""
    d = RegionSweepDesigner(problem="compleib_he1", objective="kappa2", radius=10.0, starts=2)
    res = d(alpha=0.75, zeta=0.8)
    assert res.success and res.kappa2 < 100.0
    plant = d._plant()
    poles = np.linalg.eigvals(plant.A - res.L @ plant.C)
    assert d.region_for(alpha=0.75, zeta=0.8).contains(poles, tol=1e-9)


def test_region_designer_holds_one_problem_object():
    """reuse=True: the points and chunks of a thread are solved on one WellConditionedProblem (its NLPs
    built once); reuse=False: a new problem for every point."""
    clear_cache()
    prob = DESIGNER.design_problem()
    assert isinstance(prob, WellConditionedProblem)
    assert DESIGNER.design_problem() is prob
    twin = RegionSweepDesigner(problem="compleib_dis2", radius=20.0)  # an equal copy (another chunk)
    assert twin.design_problem() is prob
    first = DESIGNER.start_chunk()(alpha=1.0, zeta=0.6)  # another chunk: the same problem, NLPs re-used
    builds = prob.nlp_builds
    assert first.success and builds >= 1
    DESIGNER.start_chunk()(alpha=2.0, zeta=0.6)
    assert prob.nlp_builds == builds  # same pole structures: re-solved, not rebuilt
    fresh = RegionSweepDesigner(problem="compleib_dis2", radius=20.0, reuse=False)
    assert fresh.design_problem() is not fresh.design_problem()
    clear_cache()
    assert DESIGNER.design_problem() is not prob


@pytest.mark.parametrize("point", [{"alpha": 1.0, "zeta": 0.6}, {"alpha": 2.5, "zeta": 0.8}])
def test_region_designer_point_is_the_problem_solve(point):
    """Without a warm start a point is exactly WellConditionedProblem(...).solve(region=...) with the
    designer's arguments: no design logic of its own."""
    d = RegionSweepDesigner(problem="compleib_dis2", radius=20.0, warm_start=False, reuse=False)
    res = d(**point)
    prob = WellConditionedProblem(problems.load("compleib_dis2").plant, objective="kappa2", starts=2, seed=0,
                                  options=SWEEP_IPOPT_OPTIONS, pole_scale=20.0, route="nlp",
                                  kalman_start=False, region_polish="last")
    ref = prob.solve(region=d.region_for(**point), seed=d.seed_for(**point))
    assert res.success and ref.success
    np.testing.assert_allclose(res.L, ref.L, rtol=0, atol=1e-9 * max(1.0, np.abs(ref.L).max()))
    assert [r.origin for r in res.starts] == [r.origin for r in ref.starts]
    assert res.extra["point"] == point and res.extra["best_origin"] == res.solver_stats.extra["best_origin"]
    assert {"starts", "converged", "best_start", "best_origin", "objective", "nlp_builds"} <= set(
        res.solver_stats.extra)
    assert "Kalman" not in " ".join(r.origin for r in res.starts)  # kalman_start=False: sampled poles


def test_region_designer_fallback_and_initial_gain_warm_starts():
    """placement="fallback": a point with a verified warm start is solved from it alone; initial_gain is
    the warm start of a chunk's first point; the warm start's gain is a candidate as it is, so a looser
    region never gives a worse design."""
    d = RegionSweepDesigner(problem="compleib_dis2", radius=20.0, placement="fallback")
    chunk = d.start_chunk()
    tight = chunk(alpha=2.5, zeta=0.8)  # first point: no warm start, the placement starts
    assert tight.success and len(tight.starts) == d.starts
    loose = chunk(alpha=2.5, zeta=0.7)
    assert loose.success and [r.origin for r in loose.starts] == ["warm start"]
    assert loose.kappa2 <= tight.kappa2 * (1 + 1e-9)
    seeded = RegionSweepDesigner(problem="compleib_dis2", radius=20.0, placement="fallback",
                                 initial_gain=tight.L)(alpha=2.5, zeta=0.7)
    assert seeded.success and [r.origin for r in seeded.starts] == ["warm start"]
    assert seeded.kappa2 <= tight.kappa2 * (1 + 1e-9)


def test_region_designer_refuses_an_unbounded_point_region():
    """An unbounded point region without max_gain is refused by the problem's solve, as by the verb (the
    metric keeps improving as the poles grow): the sweep records the error; a max_gain bounds it."""
    d = RegionSweepDesigner(problem="compleib_dis2")
    t = sweep(d, [{"alpha": 1.0, "zeta": 0.5}], executor="serial")
    assert t[0]["success"] is False
    assert t[0]["error"].startswith("ValidationError: the pole region")
    assert "no max_gain was given" in t[0]["error"]
    with pytest.raises(ValidationError, match=r"unbounded and no max_gain was given: kappa2 and eta can"):
        d(alpha=1.0, zeta=0.5)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"route": "quick"}, r"route must be one of \('auto', 'engine', 'fast', 'multistart', 'nlp'\); found 'quick'"),
        ({"kalman_start": 1}, "kalman_start must be true or false; found 1"),
        ({"pole_scale": 0.0}, "pole_scale must be finite and > 0; found 0.0"),
    ],
)
def test_problem_arguments_of_the_designer_errors(kwargs, match):
    with pytest.raises(ValidationError, match=match):
        WellConditionedProblem(problems.load("compleib_dis2").plant, **kwargs)


@pytest.mark.parametrize("seed, match", [((), r"non-empty sequence of them; found \(\)"),
                                         ([1, -2], r"seed\[1\] must be an integer >= 0; found -2"),
                                         (1.5, "seed must be an integer >= 0; found 1.5")])
def test_problem_seed_sequence_errors(seed, match):
    prob = WellConditionedProblem(problems.load("compleib_dis2").plant, starts=1)
    with pytest.raises(ValidationError, match=match):
        prob.solve(region=HalfPlane(1.0) & Disk(0.0, 20.0), seed=seed)


def test_studies_import_no_formulation_and_no_private_name():
    """Layers: studies/ holds problem objects of the design layer -- it neither imports the formulation
    layer (optdesign.formulate) nor a private name of another module."""
    import re

    import optdesign

    root = Path(optdesign.__file__).parent
    files = sorted((root / "studies").rglob("*.py"))
    assert files
    for f in files:
        src = f.read_text(encoding="utf-8")
        assert not re.search(r"^\s*(from|import)\s+(optdesign\.formulate|\.\.formulate)\b", src, re.M), f.name
        imports = re.findall(r"^\s*from\s+(\S+)\s+import\s+(?:\(([^)]*)\)|([^(\n]+)$)", src, re.M)
        assert imports
        for module, inside, line in imports:
            names = [n.split("#")[0].strip().split(" as ")[0] for n in (inside or line).split(",")]
            private = [n for n in names if n.startswith("_") and module != "__future__"]
            assert not private, (f.name, module, private)
    cli = (root / "cli" / "design.py").read_text(encoding="utf-8")
    assert "_gain_values" not in cli and "gain_values" in cli


def test_region_designer_point_errors_are_recorded():
    pts = [{"alpha": 1.0, "zeta": 1.5}, {"alpha": 25.0, "zeta": 0.5}, {"alpha": 1.0, "beta": 2.0}]
    t = sweep(DESIGNER, pts, executor="serial")
    assert [r["success"] for r in t] == [False, False, False]
    assert "zeta (damping ratio) must be in (0, 1)" in t[0]["error"]
    assert t[1]["error"].startswith("EmptyRegionError")  # Re s <= -25 and |s| <= 20: no pole fits
    assert "unknown parameter 'beta'" in t[2]["error"]


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"objective": "trace"}, "objective must be one of"),
        ({"zeta": 1.0}, r"zeta \(damping ratio\) must be in \(0, 1\)"),
        ({"radius": -1.0}, "radius must be > 0"),
        ({"kappa2_max": 0.5}, "kappa2_max must be >= 1"),
        ({"starts": 0}, "starts must be an integer >= 1"),
        ({"placement": "never"}, "placement must be one of 'always', 'fallback', 'pool'; found"),
        ({"initial_gain": np.ones((2, 2))}, r"initial_gain must be a finite \(3, 2\) array"),
        ({"problem": None}, "exactly one of problem"),
        ({"time_limit": 0.0}, r"time_limit must be a finite number of seconds > 0 or None; found 0.0"),
        ({"time_limit": "10"}, r"time_limit must be a number of seconds > 0 or None; found '10'"),
        ({"options": [1, 2]}, r"options must be a dict of solver options .*; found list \[1, 2\]"),
        ({"options": {"ipopt.bogus": 1}}, r"options must be IPOPT / CasADi .*No such IPOPT option: bogus"),
        ({"options": {"ipopt.max_iter": True}}, r"options: 'ipopt.max_iter' must map to a string or a num"),
        ({"objective": np.array(["kappa2", "eta"])}, "objective must be one of .*; found array"),
        ({"placement": np.array(["always", "fallback"])},
         "placement must be one of 'always', 'fallback', 'pool'; found"),
    ],
)
def test_region_designer_construction_errors(kwargs, match):
    args = {"problem": "compleib_dis2", "radius": 20.0}
    args.update(kwargs)
    with pytest.raises(ValidationError, match=match):
        RegionSweepDesigner(**args)


def test_region_designer_statuses_not_found_and_time_limit():
    """No verified design is local evidence (not_found, never infeasible); a point's time budget gives
    time_limit with its first start's best verified design (no timing assertion: 1 ms is always spent)."""
    # kappa2 <= 1 (a normal A - LC) is impossible with a narrow sector and a fast decay (K[-1, 0] > 1.01
    # in the reference sweep): IPOPT stops at local infeasibility from every start
    d = RegionSweepDesigner(problem="compleib_dis2", radius=20.0, kappa2_max=1.0)(alpha=3.0, zeta=0.8)
    assert d.status == Status.NOT_FOUND and not d.success and d.certificate is None
    assert "feasibility unknown" in d.message and "kappa2_bound" in d.message
    clear_cache()
    # (a point where kappa2 = 1, its lower bound, is out of reach: a design attaining it ends the starts)
    d = RegionSweepDesigner(problem="compleib_dis2", radius=20.0, starts=3, time_limit=1e-3)(alpha=3.0,
                                                                                           zeta=0.8)
    assert d.status == Status.TIME_LIMIT and not d.success
    assert len(d.starts) == 1 and "time limit of 0.001 s reached after 1 of 3 starts" in d.message
    unlimited = RegionSweepDesigner(problem="compleib_dis2", radius=20.0, starts=3)(alpha=3.0, zeta=0.8)
    assert unlimited.success and len(unlimited.starts) == 3 and unlimited.kappa2 > 1.01


def test_region_designer_unknown_problem():
    with pytest.raises(ProblemNotFoundError, match="no problem named 'no_such_problem'"):
        RegionSweepDesigner(problem="no_such_problem")


def test_region_designer_refuses_a_region_outside_the_stability_region():
    # Re s <= 1 and |s| <= 20 allows unstable error dynamics: refused up front, as by the verb
    with pytest.raises(ValidationError, match=r"reaches Re s = 1 > 0: the plant is continuous-time"):
        DESIGNER.check_point(alpha=-1.0)
    t = sweep(DESIGNER, [{"alpha": -1.0}], executor="serial")
    assert t[0]["success"] is False and t[0]["error"].startswith("ValidationError: the pole region")
    # with the sector the region stays in the left half-plane: a negative alpha is then harmless
    DESIGNER.check_point(alpha=-1.0, zeta=0.5)


# ------------------------------------------------------------------ the other designers


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"problem": "chang_lee_1984_ex1", "method": "magic"}, "method must be one of inverse, place"),
        ({"problem": "chang_lee_1984_ex1", "inverse_method": "magic"}, "inverse_method must be one of"),
        ({"problem": "chang_lee_1984_ex1", "method": "place", "objective": "kappa2"},
         r"objective must be one of \(none\) for method 'place'"),
        ({"problem": "chang_lee_1984_ex1", "starts": 0}, "starts must be an integer >= 1; found 0"),
        ({"problem": "chang_lee_1984_ex1", "seed": -1}, "seed must be an integer >= 0; found -1"),
        ({"problem": "chang_lee_1984_ex1", "reuse": 1}, "reuse must be true or false; found 1"),
        ({"plant": problems.load("compleib_dis2").plant}, r"needs poles \(no problem to take them from\)"),
        ({"problem": "compleib_dis2"}, "problem 'compleib_dis2' has no target poles; give poles"),
        ({"problem": "chang_lee_1984_ex1", "poles": ["a", "b"]}, "poles must be numeric"),  # was a ValueError
        ({"problem": "chang_lee_1984_ex1", "method": np.array(["place", "inverse"])}, "method must be one"),
    ],
)
def test_pole_target_designer_construction_errors(kwargs, match):
    with pytest.raises(ValidationError, match=match):
        PoleTargetDesigner(**kwargs)


def test_pole_target_designer_points(monkeypatch):
    d = PoleTargetDesigner(problem="chang_lee_1984_ex1", method="place")
    # the problem's target poles are resolved once per process, not loaded again for every point
    monkeypatch.setattr(problems, "load", lambda *a, **k: pytest.fail("problems.load called per point"))
    np.testing.assert_allclose(d.target(scale=2.0, shift=1.0), [-15.0, -9.0])  # 2 * (-8, -5) + 1
    res = d(scale=2.0)
    assert res.success and res.record()["pole_error"] < 1e-6
    assert res.record()["max_real_pole"] == pytest.approx(-10.0, rel=1e-9)
    for point, match in (({"alpha": 1.0}, "unknown parameter 'alpha' in the point; a pole-target designer"),
                         ({"scale": float("nan")}, "scale must be a finite number; found nan"),
                         ({"shift": True}, "shift must be a finite number; found True")):
        with pytest.raises(ValidationError, match=match):
            d.check_point(**point)


def test_kalman_noise_designer_errors():
    with pytest.raises(ValidationError, match="method must be 'scipy' or 'hamiltonian'; found 'magic'"):
        KalmanNoiseDesigner(problem="compleib_he1", method="magic")
    with pytest.raises(ValidationError, match="plant 'jung_huh_ex1' has no Q and no R"):
        KalmanNoiseDesigner(problem="jung_huh_ex1")
    with pytest.raises(ValidationError, match="needs exactly one of problem"):
        KalmanNoiseDesigner(problem="compleib_he1", plant=problems.load("compleib_he1").plant)
    d = KalmanNoiseDesigner(problem="compleib_he1")
    with pytest.raises(ValidationError, match="unknown parameter 's' in the point; a noise designer takes"):
        d.check_point(s=1.0)
    with pytest.raises(ValidationError, match="q must be finite and > 0; found 0.0"):
        d.check_point(q=0.0)


def test_place_baseline_verified_and_its_failures():
    prob = problems.load("pp_knv1985_ex1")
    plant, target = prob.plant, prob.targets["poles"]
    res = place_baseline(plant, target)
    assert res.success and res.status == Status.SOLVED
    poles = np.linalg.eigvals(plant.A - res.L @ plant.C)  # recomputed here, not trusted
    np.testing.assert_allclose(np.sort_complex(poles), np.sort_complex(target), rtol=1e-6)
    assert res.record()["pole_error"] < 1e-6
    # a pole repeated more than rank(C) times: scipy cannot place it -> a failed result that says why
    bad = place_baseline(plant, [-1.0] * plant.n)
    assert not bad.success and bad.status == Status.SOLVER_ERROR and bad.L is None
    assert "repeated 4 times but C has rank 2" in bad.message
    assert bad.record()["pole_error"] == math.inf and math.isnan(bad.record()["kappa2"])
    with pytest.raises(ValidationError, match="method must be 'YT' or 'KNV0'; found 'ackermann'"):
        place_baseline(plant, target, method="ackermann")
    with pytest.raises(ValidationError, match="plant must be an optdesign.Plant; found ndarray"):
        place_baseline(plant.A, target)
    with pytest.raises(NotConjugateClosedError, match="not closed under complex conjugation"):
        place_baseline(plant, [-1.0, -2.0, -3 + 1j, -3.0])
    with pytest.raises(NotObservableError, match="unobservable"):
        place_baseline(Plant(np.diag([1.0, 2.0]), [[1.0, 0.0]]), [-1.0, -2.0])


# ------------------------------------------------------------------ identical results on every executor


@pytest.fixture(scope="module")
def reference_table():
    """The grid evaluated in-process (the reference for the other executors)."""
    clear_cache()
    return sweep(DESIGNER, POINTS, executor="serial", chunksize=CHUNK)


def test_reference_sweep_succeeds_and_is_physically_sensible(reference_table):
    t = reference_table
    assert t.n_success == len(POINTS), [r["error"] or r["status"] for r in t.failures]
    assert np.all(t.column("max_real_pole") <= -t.column("alpha") + 1e-6)
    assert np.all(t.column("kappa2") >= 1.0 - 1e-12)
    K = t.column("kappa2").reshape(N_ALPHA, N_ZETA)
    # along a chunk the region gets looser and the previous design stays feasible: never worse
    assert np.all(np.diff(K, axis=1) <= 1e-9 * K[:, 1:])
    # DIS2 admits a normal A - LC (kappa2 = 1, with a complex pair) when the sector is wide and the
    # decay small; a narrow sector with a fast decay forbids it (so the starts must include complex
    # pole pairs for the sector to matter at all)
    assert K[0, -1] == pytest.approx(1.0, abs=1e-6) and K[-1, 0] > 1.01


@pytest.mark.parametrize("executor", ["processes", "threads"])
def test_identical_results_on_local_pools(reference_table, executor):
    t = sweep(DESIGNER, POINTS, executor=executor, workers=2, chunksize=CHUNK)
    assert t.diff(reference_table) == []
    if executor == "processes":
        assert os.getpid() not in {r["worker"] for r in t}  # really ran in the pool's processes


@pytest.fixture(scope="module")
def dask_client():
    """A 2-worker Dask LocalCluster for this module (started once, always shut down)."""
    distributed = pytest.importorskip("distributed", reason="dask.distributed is part of the test extra")
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                       dashboard_address=":0", silence_logs=logging.ERROR)
    client = distributed.Client(cluster, timeout=120)
    try:
        client.wait_for_workers(2, timeout=120)
        yield client
    finally:
        client.close(timeout=30)
        cluster.close(timeout=30)


def test_identical_results_on_a_dask_local_cluster(reference_table, dask_client):
    t = sweep(DESIGNER, POINTS, executor=dask_client.get_executor(pure=False), chunksize=CHUNK, timeout=600)
    assert t.meta["executor"] == "dask"
    assert t.diff(reference_table) == []
    workers = {r["worker"] for r in t}
    assert os.getpid() not in workers and None not in workers


def test_dask_client_is_accepted_and_failures_come_back(dask_client):
    pts = [{"alpha": 1.0, "zeta": 0.6}, {"alpha": 1.0, "zeta": 2.0}]
    t = sweep(DESIGNER, pts, executor=dask_client, chunksize=1, timeout=600)
    assert t[0]["success"] is True
    assert t[1]["success"] is False and "zeta (damping ratio)" in t[1]["error"]


def test_eta_sweep_runs_the_placement_engine_and_route_nlp_keeps_ipopt():
    """eta in a sweep (issue 28, round 12): the designer's problem takes the placement engine's route
    by default (COMPleib AC6, alpha 0.5, zeta 0.5, radius 50: eta 0.565 against IPOPT's 14.8);
    ``route="nlp"`` keeps IPOPT, kappa2's default stays IPOPT, and a bad route is refused."""
    plant = problems.load("compleib_ac6").plant
    eng = RegionSweepDesigner(plant=plant, objective="eta", zeta=0.5, radius=50.0)(alpha=0.5)
    nlp = RegionSweepDesigner(plant=plant, objective="eta", zeta=0.5, radius=50.0, route="nlp")(alpha=0.5)
    assert eng.success and nlp.success
    assert eng.route.names[0] == "eigenstructure_engine/region" and nlp.route.names == ("ipopt",)
    assert eng.eta < 0.1 * nlp.eta
    assert RegionSweepDesigner(plant=plant, zeta=0.5, radius=50.0).design_problem().route == "nlp"
    for bad in ("ipopt", ""):  # "" is not "the default"
        with pytest.raises(ValidationError, match="route must be one of"):
            RegionSweepDesigner(plant=plant, objective="eta", radius=50.0, route=bad)
