"""Region mode of the eigenstructure engine (issue 13) and its quasi-Newton method.

Designs are checked independently: the eigenvalues of the returned ``A - L C`` (numpy) must lie
in the region (``Region.contains`` / ``margin``), the design must be no worse than the caller's
start (scipy YT at the naive poles), gradients match finite differences on and off the anchor.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from optdesign import metrics, problems, well_conditioned_observer
from optdesign._deadline import Deadline
from optdesign._validate import as_poles
from optdesign.design.well_conditioned import naive_poles, suggested_region
from optdesign.engines.eigenstructure import EigenstructureEngine, FixedPoleModel
from optdesign.engines.eigenstructure_fixed import peer_start
from optdesign.engines.eigenstructure_region import (
    QuadraticConstraints,
    RegionModel,
    RegionStart,
    place_region,
)
from optdesign.engines.quasi_newton import bfgs_minimize, bfgs_minimize_batch
from optdesign.errors import DimensionError, ValidationError
from optdesign.regions import Disk, Ellipse, HalfPlane, HorizontalStrip, Sector, VerticalStrip
from optdesign.results import Status


def region_model(name, frac, seed=0):
    plant = problems.load(name).plant
    region = suggested_region(plant)
    eng = EigenstructureEngine(plant.A, plant.C)
    pin = eng.unobservable_modes()
    rng = np.random.default_rng(seed)
    P = as_poles("p", np.concatenate([region.sample_poles(plant.n - pin.size, rng, real_fraction=frac), pin]))
    fixed = FixedPoleModel(eng, P)
    nr = int(np.sum(P.imag == 0)) - pin.size
    model = RegionModel(eng, nr, (plant.n - pin.size - nr) // 2, region, pin)
    return model, fixed, fixed.random_coords(rng), rng


@pytest.mark.parametrize(
    "name,frac",
    [("compleib_dis2", 1.0), ("compleib_dis2", 0.0), ("compleib_ac6", 0.5), ("compleib_ac4", 1.0)],
)
@pytest.mark.parametrize("mu", [0.0, 1e-2])
def test_region_gradient_on_and_off_the_anchor(name, frac, mu):
    model, fixed, xf, rng = region_model(name, frac)
    x = model.coords_of(fixed, xf)[0]
    assert model.evaluate_batch(x[None], "kappa2", 8, 0.0)[0][0] == pytest.approx(
        fixed.evaluate(xf, "kappa2", 8)[0], rel=1e-12
    )  # the same design at the anchor
    off = x.copy()
    off[model.ncoord :] += 0.02 * model.rho * rng.standard_normal(x.size - model.ncoord)
    for z in (x, off):
        f, g = model.evaluate_batch(z[None], "kappa2", 8, mu)
        assert np.isfinite(f[0])
        h, E = 1e-7 * max(1.0, model.rho), np.eye(z.size)
        fd = np.array(
            [
                (
                    model.evaluate_batch((z + h * E[i])[None], "kappa2", 8, mu)[0][0]
                    - model.evaluate_batch((z - h * E[i])[None], "kappa2", 8, mu)[0][0]
                )
                / (2 * h)
                for i in range(z.size)
            ]
        )
        assert np.max(np.abs(fd - g[0])) <= 1e-5 * max(1.0, np.max(np.abs(g[0])))


def test_every_variable_vector_is_a_design_in_the_region():
    """The poles are the image of free variables under the region's PoleMap: any variable vector,
    however far out, gives poles in the (closed) region and a finite design (issue 28)."""
    model, fixed, xf, rng = region_model("compleib_dis2", 1.0)
    x = model.coords_of(fixed, xf)[0]
    for scale in (1.0, 1e2, 1e4):
        z = x.copy()
        z[model.ncoord :] = scale * rng.standard_normal(x.size - model.ncoord)
        P = model.poles(z)
        assert model.region.margin(P) <= 1e-12 * max(1.0, float(np.max(np.abs(P))))
        f, g = model.evaluate_batch(z[None], "kappa2", None, 1e-3)
        assert np.isfinite(f[0]) and np.all(np.isfinite(g))


@pytest.mark.parametrize("name,frac,what", [("compleib_ac6", 0.0, "pair"), ("compleib_dis2", 1.0, "reals")])
def test_two_poles_at_one_point_are_refused(name, frac, what):
    """A double eigenvalue (a pair on the real axis, two real poles at one point) has no finite
    value: its eigenvectors are not determined by the poles (the separation barrier)."""
    model, fixed, xf, _ = region_model(name, frac)
    x = model.coords_of(fixed, xf)[0]
    f, _ = model.evaluate_batch(x[None], "kappa2", None, 1e-3)
    assert np.isfinite(f[0])
    if what == "pair":
        assert model.npf > 0
        # the first pair's (a, b) = (|a|, 0): its upper member on the real axis
        x[model.size - 2 * model.npf] = abs(x[model.size - 2 * model.npf])
        x[model.size - model.npf] = 0.0
    else:
        assert model.nrf > 1
        x[model.ncoord + 1] = x[model.ncoord]  # the second real pole onto the first
    f, g = model.evaluate_batch(x[None], "kappa2", None, 1e-3)
    assert math.isinf(f[0]) and not np.any(g)


@pytest.mark.parametrize("name", ["compleib_dis2", "compleib_ac17", "compleib_he1", "compleib_ac4"])
def test_region_designs_inside_and_never_worse_than_the_naive_start(name):
    plant = problems.load(name).plant
    region = suggested_region(plant)
    start = RegionStart("naive poles + YT", naive_poles(plant, region))
    out = place_region(plant.A, plant.C, region, starts=[start], n_samples=1)
    assert out.status is Status.OPTIMAL
    X = plant.A - out.L @ plant.C
    ev = np.linalg.eigvals(X)
    assert region.contains(ev, tol=1e-7 * max(1.0, float(np.max(np.abs(ev)))))
    # the optimum may lie on the boundary: the model's poles are there to rounding
    assert out.extra["region_margin"] <= 1e-12 * max(1.0, float(np.max(np.abs(out.poles))))
    k2 = metrics.kappa2(X)
    assert out.kappa2 == pytest.approx(k2, rel=1e-6) or math.isinf(k2)
    if plant.is_observable():
        L_yt = peer_start(plant.A, plant.C, as_poles("p", start.poles), "YT")
        assert out.kappa2 <= metrics.kappa2(plant.A - L_yt @ plant.C) * (1 + 1e-9)
    else:  # AC4: the unobservable mode -0.05 is kept
        assert np.min(np.abs(ev + 0.05)) <= 1e-9


def test_region_never_worse_than_a_given_gain():
    plant = problems.load("compleib_ac17").plant
    region = suggested_region(plant)
    first = place_region(
        plant.A, plant.C, region, starts=[RegionStart("n", naive_poles(plant, region))], n_samples=0
    )
    warm = place_region(
        plant.A, plant.C, region, starts=[RegionStart("previous", first.poles, first.L)], n_samples=0
    )
    assert warm.kappa2 <= first.kappa2 * (1 + 1e-9)


def test_other_region_shapes_and_kappa_fro():
    plant = problems.load("compleib_dis2").plant
    for region in (
        Ellipse(-4.0, 3.0, 2.0) & HorizontalStrip(1.5),
        VerticalStrip(-6.0, -2.0) & Disk(-4.0, 3.0),
    ):
        for objective in ("kappa2", "kappa_fro"):
            out = place_region(plant.A, plant.C, region, objective=objective, n_samples=2, seed=3)
            ev = np.linalg.eigvals(plant.A - out.L @ plant.C)
            assert region.contains(ev, tol=1e-7 * max(1.0, float(np.max(np.abs(ev)))))
            X = plant.A - out.L @ plant.C
            got = metrics.kappa2(X) if objective == "kappa2" else metrics.kappa_fro(X)
            assert got == pytest.approx(out.objective_value, rel=1e-6)


def test_unreachable_region_is_not_found():
    """REA4 (eight unstable modes, one output): no computable gain puts the poles in the region."""
    plant = problems.load("compleib_rea4").plant
    region = suggested_region(plant)
    out = place_region(
        plant.A, plant.C, region, starts=[RegionStart("n", naive_poles(plant, region))], n_samples=1
    )
    assert out.status is Status.NOT_FOUND and not np.any(np.isfinite(out.L))


def test_region_time_limit():
    plant = problems.load("compleib_ac6").plant
    region = suggested_region(plant)
    dl = Deadline(1e-6)
    while not dl.expired:
        pass
    out = place_region(
        plant.A,
        plant.C,
        region,
        starts=[RegionStart("n", naive_poles(plant, region))],
        n_samples=0,
        deadline=dl,
    )
    assert out.status is Status.TIME_LIMIT


def test_quadratic_constraints_reproduce_the_region():
    rng = np.random.default_rng(0)
    x, y = rng.uniform(-8, 2, 40), rng.uniform(0, 4, 40)
    for region in (
        HalfPlane(1.0) & Sector.from_damping(0.5) & Disk(0, 6),
        Ellipse(-3, 2, 1) & HorizontalStrip(0.5),
    ):
        qc = QuadraticConstraints(region, 1.0)
        g, gx, gy = qc.values(x, y)
        ref = np.column_stack([np.asarray(v) * np.ones_like(x) for v in region.constraints(x, y)])
        np.testing.assert_allclose(g, ref, atol=1e-12 * max(1.0, np.max(np.abs(ref))))
        h = 1e-5
        gx_fd = (qc.values(x + h, y)[0] - qc.values(x - h, y)[0]) / (2 * h)
        np.testing.assert_allclose(gx, gx_fd, atol=1e-7)


def test_region_errors():
    plant = problems.load("compleib_dis2").plant
    region = suggested_region(plant)
    with pytest.raises(ValidationError, match="region must be an optdesign.regions.Region"):
        place_region(plant.A, plant.C, "disk")
    with pytest.raises(ValidationError, match="must be 'kappa2', 'kappa_fro' or 'eta'; found 'gap'"):
        place_region(plant.A, plant.C, region, objective="gap")
    with pytest.raises(ValidationError, match="needs at least one start"):
        place_region(plant.A, plant.C, region, n_samples=0)
    ac4 = problems.load("compleib_ac4").plant  # unobservable mode -0.05
    with pytest.raises(ValidationError, match=r"unobservable mode -0\.05.* lies outside the region"):
        place_region(ac4.A, ac4.C, HalfPlane(1.0) & Disk(0, 10), n_samples=1)
    eng = EigenstructureEngine(plant.A, plant.C)
    with pytest.raises(DimensionError, match=r"2 real poles \+ 1 pairs \+ 0 pinned poles != n = 3"):
        RegionModel(eng, 2, 1, region)

    class Cubic(HalfPlane):  # breaks the degree <= 2 contract of Region.constraints
        def constraints(self, re, im):
            return [re * re * re + 1.0]

    with pytest.raises(ValidationError, match="are not quadratic polynomials"):
        QuadraticConstraints(Cubic(1.0), 1.0)


# ----------------------------------------------------------------------------- quasi-Newton


def rosenbrock(x):
    f = (1 - x[0]) ** 2 + 100 * (x[1] - x[0] ** 2) ** 2
    return f, np.array([-2 * (1 - x[0]) - 400 * x[0] * (x[1] - x[0] ** 2), 200 * (x[1] - x[0] ** 2)])


def test_bfgs_smooth_and_nonsmooth():
    r, _ = bfgs_minimize(rosenbrock, np.array([-1.2, 1.0]), ftol=1e-16, gtol=1e-10)
    assert r.reason == "converged" and np.allclose(r.x, 1.0, atol=1e-6)

    def nonsmooth(x):  # max of two smooth pieces, minimizer (0, 0) on the kink, f = 0
        a, b = x[0] ** 2 + 2 * abs(x[1]), 2 * x[0] ** 2 + abs(x[1] - 0.0)
        g = np.array([2 * x[0], 2 * np.sign(x[1])]) if a >= b else np.array([4 * x[0], np.sign(x[1])])
        return max(a, b), g

    r, _ = bfgs_minimize(nonsmooth, np.array([1.0, 0.7]), max_iter=500)
    assert r.f <= 1e-6 and r.reason in ("line search", "converged")


def test_bfgs_batch_members_are_independent_and_never_worse():
    X0 = np.array([[-1.2, 1.0], [0.5, -0.5], [2.0, 2.0]])

    def batch(X):
        out = [rosenbrock(x) for x in X]
        return np.array([o[0] for o in out]), np.stack([o[1] for o in out])

    res, H = bfgs_minimize_batch(batch, X0, ftol=1e-16, gtol=1e-10)
    for r, x0 in zip(res, X0, strict=True):
        single, _ = bfgs_minimize(rosenbrock, x0, ftol=1e-16, gtol=1e-10)
        assert r.iterations == single.iterations and np.allclose(r.x, single.x, rtol=0, atol=1e-12)
        assert r.f <= rosenbrock(x0)[0]
    assert len(H) == 3 and H[0].shape == (2, 2)


def test_bfgs_batch_keep_prunes_only_what_is_worse_than_the_kept():
    """keep=k: once k members have stopped, a running member whose value exceeds the k-th lowest of
    theirs by more than the margin stops ("pruned"); the others run as without it, to the same end."""
    X0 = np.array([[0.9, 0.81], [1.1, 1.2], [-1.2, 1.0], [-2.0, 3.0], [1.05, 1.1]])

    def batch(X):
        out = [rosenbrock(x) for x in X]
        return np.array([o[0] for o in out]), np.stack([o[1] for o in out])

    free, _ = bfgs_minimize_batch(batch, X0, ftol=1e-16, gtol=1e-10)
    assert all(r.reason == "converged" for r in free)
    order = np.argsort([r.iterations for r in free])
    kept, _ = bfgs_minimize_batch(batch, X0, ftol=1e-16, gtol=1e-10, keep=2, keep_margin=1e-3)
    pruned = [i for i, r in enumerate(kept) if r.reason == "pruned"]
    assert pruned and set(pruned).isdisjoint(order[:2])  # the first two to stop are never pruned
    bar = sorted(kept[i].f for i in order[:2])[1]
    for i, (a, b) in enumerate(zip(kept, free, strict=True)):
        if i in pruned:  # stopped early, above the bar, at a point its own run passed through
            assert a.iterations < b.iterations and a.f > bar + 1e-3 * max(1.0, abs(bar))
        else:
            assert a.iterations == b.iterations and a.f == b.f
    none, _ = bfgs_minimize_batch(batch, X0, ftol=1e-16, gtol=1e-10, keep=2, keep_margin=1e6)
    assert [r.iterations for r in none] == [r.iterations for r in free]
    with pytest.raises(ValueError, match=r"keep must be >= 0 \(0: keep every start\); found -1"):
        bfgs_minimize_batch(batch, X0, keep=-1)
    with pytest.raises(ValueError, match=r"keep_horizon must be >= 0 \(0: the value alone\); found -1"):
        bfgs_minimize_batch(batch, X0, keep=2, keep_horizon=-1.0)


def test_bfgs_batch_keep_horizon_spares_a_start_still_descending():
    """keep_horizon=h: a start above the bar still runs while ``h`` more windows at its current rate
    of decrease would bring it below; the value alone (h = 0) prunes it.  Two starts stop at once on
    a quadratic, a third descends Rosenbrock's valley (f from 24 down, by more than 1 per window)."""
    X0 = np.array([[1.0, 1.0], [1.0 + 1e-9, 1.0], [-1.2, 1.0]])

    def batch(X):
        out = [rosenbrock(x) for x in X]
        return np.array([o[0] for o in out]), np.stack([o[1] for o in out])

    free, _ = bfgs_minimize_batch(batch, X0, ftol=1e-16, gtol=1e-10)
    assert free[2].reason == "converged" and free[2].iterations > 10
    by_value, _ = bfgs_minimize_batch(batch, X0, ftol=1e-16, gtol=1e-10, keep=2)
    assert by_value[2].reason == "pruned" and by_value[2].f > 1.0
    spared, _ = bfgs_minimize_batch(batch, X0, ftol=1e-16, gtol=1e-10, keep=2, keep_horizon=1e6)
    assert spared[2].iterations > by_value[2].iterations and spared[2].f < 1e-6  # at the valley's end
    for a, b in zip(spared[:2], free[:2], strict=True):  # the first two run as without keep
        assert a.iterations == b.iterations and a.f == b.f


def _charted(c, radius):
    """A quadratic with its minimizer at ``c``, defined only within ``radius`` (inf norm) of each
    start's anchor (``f = inf`` outside: the region mode's chart edge) and the anchors (s, m)."""
    def make(anchors):
        def fun(X, idx):
            f = np.sum((X - c) ** 2 * np.arange(1.0, X.shape[1] + 1.0), axis=1)
            f[np.max(np.abs(X - anchors[idx]), axis=1) > radius] = math.inf
            return f, 2.0 * (X - c) * np.arange(1.0, X.shape[1] + 1.0)
        return fun
    return make


def test_bfgs_batch_restart_goes_on_as_a_batch_called_again():
    """restart= (issue 28, round 15): a start whose line search fails at its chart's edge is
    re-anchored and goes on in the same batch.  Each start's path -- points, values, total
    iterations and evaluations, final inverse Hessian -- is that of the scheme it replaces: the batch
    called again with the restarted starts alone, each with its inverse Hessian (at most 3 times)."""
    c, radius, ftol = np.array([3.0, -2.0, 1.5]), 0.4, 1e-9
    X0 = np.array([[0.0, 0.0, 0.0], [0.5, 0.2, -0.3], [2.9, -1.9, 1.4], [-1.0, 1.0, 2.0]])
    make = _charted(c, radius)

    # the scheme replaced: calls again for the restarted starts
    anchors = X0.copy()
    X, H = X0.copy(), [None] * 4
    its, evs, reasons, todo = np.zeros(4, int), np.zeros(4, int), [""] * 4, np.arange(4)
    for call in range(4):
        fun = make(anchors)
        f_before = fun(X[todo], todo)[0]
        res, Hs = bfgs_minimize_batch(lambda Z, i, t=todo, f=fun: f(Z, t[i]), X[todo], ftol=ftol,
                                      pass_index=True, H0=[H[i] for i in todo])
        again = []
        for j, i in enumerate(todo):
            X[i], H[i], reasons[i] = res[j].x, Hs[j], res[j].reason
            its[i] += res[j].iterations
            evs[i] += res[j].evaluations
            if res[j].reason == "line search" and f_before[j] - res[j].f > ftol * max(1.0, abs(res[j].f)):
                again.append(i)
        if not again or call == 3:
            break
        todo = np.asarray(again)
        anchors[todo] = X[todo]

    anchors2, count = X0.copy(), np.zeros(4, int)

    def restart(i, x, f_leg, f):
        if count[i] >= 3 or not f_leg - f > ftol * max(1.0, abs(f)):
            return False
        count[i] += 1
        anchors2[i] = x
        return True

    res, Hs = bfgs_minimize_batch(make(anchors2), X0, ftol=ftol, pass_index=True, restart=restart)
    assert count.sum() >= 3 and count.max() == 3  # restarts happened, up to the limit
    for i, r in enumerate(res):
        np.testing.assert_array_equal(r.x, X[i])
        assert (r.iterations, r.evaluations, r.reason) == (its[i], evs[i], reasons[i])
        np.testing.assert_array_equal(np.triu(Hs[i]), np.triu(H[i]))
    np.testing.assert_array_equal(anchors2, anchors)


def test_bfgs_batch_first_legs_ends_the_batch_when_asked():
    """first_legs= is called once, when every start has ended its first leg, with every start's
    point; True ends the batch there (the running starts at their points, "line search")."""
    c, radius = np.array([3.0, -2.0, 1.5]), 0.4
    X0 = np.array([[0.0, 0.0, 0.0], [2.9, -1.9, 1.4]])
    make, calls = _charted(c, radius), []

    def run(first_legs):
        anchors = X0.copy()

        def restart(i, x, f_leg, f):
            anchors[i] = x
            return f_leg > f

        return bfgs_minimize_batch(make(anchors), X0, pass_index=True, restart=restart,
                                   first_legs=first_legs)[0]

    def first_legs(X):
        calls.append(X.copy())
        return True

    res = run(first_legs)
    assert len(calls) == 1 and calls[0].shape == X0.shape
    np.testing.assert_array_equal(calls[0][0], res[0].x)  # ended where it was when asked
    assert res[0].reason == "line search" and res[1].reason == "converged"
    free = run(None)
    assert free[0].f < 1e-6 < res[0].f  # without it, the restarted start goes on to the minimizer


def test_bfgs_deadline_and_bad_start():
    dl = Deadline(1e-6)
    while not dl.expired:
        pass
    r, _ = bfgs_minimize(rosenbrock, np.array([-1.2, 1.0]), deadline=dl)
    assert r.reason == "time_limit" and r.iterations == 0
    with pytest.raises(ValueError, match="the objective is not finite at a start"):
        bfgs_minimize(lambda x: (math.inf, None), np.zeros(2))


def test_chart_edge_reanchoring_reaches_the_better_basin():
    """Issue 28: on COMPleib DIS1 the first continuation stages stopped with line-search failures at
    the edge of the anchored chart (28 of 32 infinite trial values: a subspace rotated past 60 degrees,
    not the barrier); re-anchoring there and carrying the inverse Hessians takes the Kalman start from
    kappa2 1.13878 to 1.13443 (IPOPT's best from 8 starts: 1.13392)."""
    from optdesign.design.well_conditioned.starts import riccati_start

    plant = problems.load("compleib_dis1").plant
    region = suggested_region(plant)
    L0 = riccati_start(plant, np.random.default_rng(0), 0)
    start = RegionStart("Kalman", np.linalg.eigvals(plant.A - L0 @ plant.C), L0)
    out = place_region(plant.A, plant.C, region, starts=[start], n_samples=0)
    assert out.status in (Status.OPTIMAL, Status.OPTIMAL_INACCURATE)
    assert out.objective_value < 1.136
    assert region.contains(np.linalg.eigvals(plant.A - out.L @ plant.C), tol=1e-7 * 10)


@pytest.mark.parametrize("n,k_first,before", [(6, 64, [(4, 8)]), (11, 4, [])])
def test_eta_keeps_four_members_after_the_first_stage_above_n10(n, k_first, before, monkeypatch):
    """eta's cold continuation keeps only its 4 best members after the second stage (k = 64) up to
    n = 10 and after the first (k = 4) above (round 12: 0.72-0.89x the engine's CPU at n = 12-30, eta
    within 0.2 %; at n <= 10 it lost 19 % on COMPleib HE5); up to n = 10 its 8 best after the first
    (round 16)."""
    import optdesign.engines.eigenstructure_region_lockstep as lockstep

    class Pruned(Exception):
        pass

    wider: list[tuple[int, int]] = []

    def spy(X, alive, reasons, evaluate, k, mu, keep):
        if keep != 4:
            wider.append((k, keep))
            return
        raise Pruned(k, int(alive.sum()), keep)

    monkeypatch.setattr(lockstep, "_prune", spy)
    rng = np.random.default_rng(n)
    A, C = rng.standard_normal((n, n)) / np.sqrt(n), rng.standard_normal((3, n))
    region = HalfPlane(0.5) & Sector.from_damping(0.5) & Disk(0.0, 5.0)
    starts = [RegionStart(f"sample {i}", region.sample_poles(n, rng)) for i in range(6)]
    with pytest.raises(Pruned) as seen:
        place_region(A, C, region, objective="eta", starts=starts, n_samples=0)
    k, running, keep = seen.value.args
    assert k == k_first and running > 4 and keep == 4 and wider == before


def test_kappa2_keeps_five_members_after_the_second_stage(monkeypatch):
    """kappa2's cold continuation prunes after its second stage (k = 64) to its 5 best members (round
    13: the ranking among near-equal values there depends on the CPU's rounding).  COMPleib UWV ends
    within 1 % of the base commit's 946.417 (with 4 kept: 958.4, +1.3 %, on an AMD EPYC; with 5: 919.1
    there, 952.7 under the Prescott kernel -- the issue's 1e-3 is not met under Prescott)."""
    import optdesign.engines.eigenstructure_region_lockstep as lockstep

    plant = problems.load("compleib_uwv").plant
    region = suggested_region(plant)
    seen = []
    real_prune = lockstep._prune

    def spy(X, alive, reasons, evaluate, k, mu, keep):
        seen.append((k, keep))
        real_prune(X, alive, reasons, evaluate, k, mu, keep)

    monkeypatch.setattr(lockstep, "_prune", spy)
    d = well_conditioned_observer(plant, region=region)
    assert seen == [(64, 5)]
    assert d.verification.passed and d.kappa2 <= 946.417 * 1.01


def test_lockstep_starts_one_record_each_in_order():
    """Starts of different real/complex patterns run in one lockstep batch: one record per start, in
    the order given (warm starts first), the outcome the best of them, the same on a second call."""
    plant = problems.load("compleib_he2").plant
    region = suggested_region(plant)
    rng = np.random.default_rng(4)
    starts = [RegionStart("naive", naive_poles(plant, region))]
    starts += [RegionStart(f"sample {k}", region.sample_poles(plant.n, rng, n_real=k)) for k in (0, 2, 4)]
    out = place_region(plant.A, plant.C, region, starts=starts, n_samples=0)
    again = place_region(plant.A, plant.C, region, starts=starts, n_samples=0)
    assert [r.origin for r in out.starts] == ["naive", "sample 0", "sample 2", "sample 4"]
    assert out.objective_value == min(r.objective_value for r in out.starts)
    assert again.objective_value == out.objective_value
    assert region.contains(np.linalg.eigvals(plant.A - out.L @ plant.C), tol=1e-6)
    warm = RegionStart("warm", np.linalg.eigvals(plant.A - out.L @ plant.C), out.L, warm=True)
    both = place_region(plant.A, plant.C, region, starts=[starts[0], warm], n_samples=0)
    assert [r.origin for r in both.starts] == ["warm", "naive"]
    assert both.objective_value <= out.objective_value * (1 + 1e-9)
