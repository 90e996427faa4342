"""The public verb :func:`well_conditioned_observer`: validate, build the problem, solve."""

from __future__ import annotations

from typing import Any

from numpy.typing import ArrayLike

from ..._deadline import Deadline, as_time_limit, dense_time_refusal
from ..._validate import renamed
from ...backends.report import one_warning_per_call
from ...model.coerce import as_plant
from ...model.plant import Plant
from ...model.regions import Region
from ...results import Route, Stage, Status
from .problem import Objective, WellConditionedProblem
from .results import ObserverDesign, no_design

__all__ = ["well_conditioned_observer"]


@one_warning_per_call
def well_conditioned_observer(
    plant: Plant | Any,
    *,
    region: Region | None = None,
    poles: ArrayLike | None = None,
    objective: Objective = "kappa2",
    gain_mask: ArrayLike | None = None,
    max_gain: float | None = None,
    kappa2_max: float | None = None,
    eta_max: float | None = None,
    starts: int | None = None,
    seed: int = 0,
    nlp_solver: str | None = None,
    scaling: bool = True,
    options: dict[str, Any] | None = None,
    allow_unstable: bool = False,
    time_limit: float | None = None,
    progress: bool | None = None,
    structure: ArrayLike | None = None,
    solver: str | None = None,
) -> ObserverDesign:
    """Observer gain whose error dynamics ``A - L C`` have a well-conditioned eigenbasis.

    ``WellConditionedProblem(plant, ...).solve()`` (:class:`WellConditionedProblem`: hold one to
    solve the same question many times).

    Parameters
    ----------
    plant : Plant, python-control StateSpace or scipy StateSpace / lti / dlti
        ``A`` (n, n), ``C`` (p, n); continuous, or discrete when ``dt`` is set.
    region : Region, optional
        Poles free inside this region (use a discrete-time region, e.g. ``Disk.unit(0.9)``,
        when ``plant.dt`` is set).  It must lie in the closed stability region of the plant's
        time domain (``Re s <= 0``, or ``|z| <= 1``): a region reaching outside is rejected
        (ValidationError), not silently intersected -- intersect it yourself, e.g.
        ``region & HalfPlane(alpha)``.  Unbounded regions need ``max_gain`` or a bounded member
        (e.g. ``& Disk(0, R)``) when the metric keeps improving as poles move away.
    poles : (n,) array_like of complex, optional
        Fixed poles, stable (``Re < 0``, or ``|z| < 1`` when ``plant.dt`` is set;
        conjugate-closed; a pole may repeat up to ``rank(C)`` times).  Give
        ``region`` or ``poles``, not both; with neither, the region is the stability region
        (``HalfPlane(0)`` or the unit disk).
    objective : {"kappa2", "kappa_fro", "eta"}
        What to minimize: kappa2 of the unit-column eigenvector matrix (seed 001's index),
        its Frobenius counterpart, or Huh & Stein's eta.
    gain_mask : (n, p) array_like of bool, optional
        Free entries of ``L`` (False = structural zero).  (Old spelling ``structure=``: deprecated.)
    max_gain : float, optional
        Bound on ``||L||_2``.
    kappa2_max, eta_max : float, optional
        Trade-off bounds on the metrics that are not minimized (e.g. minimize eta subject to
        ``kappa2 <= kappa2_max``): minimizing eta alone can make kappa2 much worse.
    starts : int, optional
        Number of multi-start runs; default 8, except on the placement engine (no bounds, no
        structural zeros): fixed poles 6 up to n = 12, 2 up to 24, then 1
        (:func:`~optdesign.engines.eigenstructure_fixed.default_starts`), a region 8 up to n = 12, 4
        up to 24, then 2, and 16 for eta
        (:func:`~optdesign.design.well_conditioned.starts.default_region_starts`): measured enough
        for the engine, whose starts run in lockstep.  Fixed poles: scipy YT, KNV0 (real poles) and random
        eigenvector coordinates, run in lockstep by the placement engine.  Region: start 0 is
        scipy YT at :func:`naive_poles` (the open-loop poles moved into the region), start 1 the
        Kalman gain for ``Q = I, R = I``, the others YT at poles sampled in the region
        (:meth:`Region.sample_poles`) with the real/complex patterns of :func:`start_real_counts`
        (the ``j``-th sampled start takes ``start_real_count(n, j)``); Kalman gains replace
        placements when the plant is unobservable.  No further start is run once a solved,
        verified design attains the objective's lower bound (kappa2 = 1, kappa_fro = n, to the
        accuracy of a computed kappa2; eta = 0, a normal ``A - LC``, to that absolute accuracy,
        1e-6): a global optimum.
    seed : int, default 0
        Seed of every random choice (reproducible).
    nlp_solver : {"ipopt"}
        The NLP backend.  (Old spelling ``solver=``: deprecated.)
    scaling : bool, default True
        Time scaling (continuous time) and unit-norm output rows of the NLPs: both leave kappa2 and
        eta unchanged.
    options : dict, optional
        IPOPT options (string keys, ``"ipopt.max_iter"``, ...) of the NLP route, merged over the
        defaults; names and values IPOPT refuses raise ValidationError before anything runs.
    allow_unstable : bool, default False
        Fixed poles only: accept unstable ``poles`` (pole-assignment benchmarks, e.g. Byers 6,
        are state-feedback problems that assign unstable poles); the verification then does not
        require stability.  An observer with unstable error dynamics is otherwise refused.
    time_limit : float, optional
        Seconds of wall time (None: no limit).  The engine checks it at every iteration, IPOPT gets
        the time left (``max_wall_time``); no start after the first begins once it is spent (the
        first start always makes its first step, so a quick verified design is not lost to a tiny
        budget).  The set-up counts: a design whose uninterruptible dense set-up (the eigenvalues
        and eigenvectors of the closed loop) alone is estimated to outlast the limit is not started
        (status ``time_limit`` at once, no gain, the estimate in ``message``).
    progress : bool or None
        Report the starts on stderr (None: only when stderr is a terminal).

    Returns
    -------
    ObserverDesign
        ``success`` is True only when the best start was solved *and* passed verification
        (stability and the poles recomputed with numpy against the target or the region, the
        solver's eigenbasis against ``metrics.kappa2``, ``kappa2_accuracy``: a kappa2 that can be
        stated to about three digits -- a nearly defective ``A - LC`` is no verified design --, mask,
        gain and metric bounds).  The reported kappa2 is the returned gain's, recomputed.  A
        verified design whose solver stopped early (IPOPT's ``iteration_limit``) is returned with
        that status (so ``success`` is False) only when no solved and verified candidate exists;
        the engine's iteration limit is ``optimal_inaccurate`` (a verified improvement on its
        start, not certified as a local minimum).  Other statuses:

        * ``time_limit`` -- the budget ran out before the design finished: ``success`` is
          False (the search was cut short), and ``L``, ``poles`` and the metrics are those of
          the best verified design found so far (``verification.passed`` says whether there
          is one; ``starts`` lists the runs made);
        * ``not_found`` -- no start gave a verified design (e.g. IPOPT stopped at a point of
          local infeasibility, or no placement reaches the region, COMPleib REA4): local
          evidence only, feasibility unknown, no certificate;
        * ``solver_error`` -- every start crashed (the reasons are in ``starts``);
        * ``infeasible`` -- only with a proof in ``certificate``: a pole repeated more than
          ``rank(C)`` times (``A - LC`` would be defective), a repeated pole with objective
          eta (infinite), an unobservable mode outside the region.

    Raises
    ------
    ValidationError
        Both or wrong ``poles``/``region``, unknown objective or solver, bad mask, bounds,
        ``starts``, ``options``, ``time_limit`` or ``progress``; unstable fixed poles (named;
        unless ``allow_unstable``); a region reaching outside the stability region;
        ``allow_unstable`` with a region.
    NotObservableError
        ``(C, A)`` is not observable with fixed poles (names the unobservable modes).
    NotConjugateClosedError, DimensionError
        Bad pole set.

    Notes
    -----
    The placement engine (:mod:`optdesign.engines.eigenstructure`) is the default inner loop:
    the left eigenvectors of ``A - L C`` are parametrized in the subspace of each pole, so every
    point places the poles exactly; kappa2 is minimized through smooth upper bounds tightened by
    continuation, then exactly, by BFGS with analytic gradients.  In a region the poles are
    variables too (the image of free variables under a map onto the region, which folds at its
    boundary: :mod:`optdesign.engines.region_map`); each start keeps the best of its own gain,
    the fixed-pole optimum at its poles and the free-pole optimum polished at its final poles --
    so the design is never worse than scipy YT at :func:`naive_poles` (start 0).

    In a region (kappa2 / kappa_fro without bounds or structural zeros) the engine runs from eight
    starts in lockstep (fewer above n = 12:
    :func:`~optdesign.design.well_conditioned.starts.default_region_starts`), IPOPT only as the
    fallback when no engine design verifies (issue 28: on the 50 plants n <= 10 of
    ``benchmarks/results/region.md`` median CPU 0.41 s against 13.2 s for the previous default --
    IPOPT from every start, now ``WellConditionedProblem(route="multistart")`` -- better than it by
    more than 1e-3 on 17 plants, worse on one, by 0.9 %).  ``result.route`` lists what ran
    and which stage answered.  IPOPT (:mod:`optdesign.formulate.well_conditioned`) takes the
    constraints the engine does not handle -- ``max_gain``, ``kappa2_max`` / ``eta_max``, structural
    zeros in a region -- and is the fallback when no engine design verifies; for eta in a region the
    engine runs from 16 starts and IPOPT from the first, at most 150 iterations per stage (the engine
    alone from 8 was worse on some plants; none above n = 10, where it never beat the engine, or when
    the engine attains eta's lower bound 0).  A kappa2 bound
    with another objective goes through its own continuation (the orders 64, 512, 4096 of the
    surrogate, :data:`~optdesign.formulate.well_conditioned.KAPPA2_BOUND_STAGES`):
    every order guarantees ``kappa2 <= kappa2_max``.  The reported metrics are recomputed with numpy.
    The problem is non-convex: the best of ``starts`` local solutions is returned and ``starts`` holds
    every run.

    References
    ----------
    Seed 001 (Jung & Huh); Kautsky, Nichols & Van Dooren (1985); Tits & Yang (1996); Lewis &
    Overton (2013).

    Examples
    --------
    >>> import numpy as np
    >>> from optdesign import Plant, well_conditioned_observer
    >>> plant = Plant([[0, 1], [2, -1]], [[1, 0]])
    >>> d = well_conditioned_observer(plant, poles=[-2, -3], starts=1)
    >>> bool(d.success), round(d.kappa2, 4)   # a SISO gain is fixed by its poles: 3 + sqrt(10)
    (True, 6.1623)
    """
    deadline = Deadline(as_time_limit(time_limit))
    gain_mask = renamed("gain_mask", gain_mask, "structure", structure, None, stacklevel=3)
    nlp_solver = renamed("nlp_solver", nlp_solver, "solver", solver, "ipopt", stacklevel=3)
    plant = as_plant(plant)
    # issue 26: the set-up counts -- every route computes the eigenvalues and eigenvectors of the
    # closed loop (two LAPACK calls that cannot be stopped): not started when they alone outlast it
    why = dense_time_refusal([("eigvals", plant.n), ("eig", plant.n)], deadline,
                             f"well_conditioned_observer at n = {plant.n}")
    if why:
        stage = Stage("setup_estimate", "check", "time_limit",
                      "refused up front: the set-up alone outlasts the limit")
        return no_design(plant, str(objective), Status.TIME_LIMIT, f"no design: {why}", None, region=region,
                         route=Route([stage]))
    problem = WellConditionedProblem(plant, objective=objective, poles=poles, region=region,
                                     gain_mask=gain_mask, max_gain=max_gain, kappa2_max=kappa2_max,
                                     eta_max=eta_max, starts=starts, seed=seed, nlp_solver=nlp_solver,
                                     scaling=scaling, options=options, allow_unstable=allow_unstable)
    return problem.solve(time_limit=deadline, progress=progress)
