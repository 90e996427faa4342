"""State feedback with poles free in a region: cond(X) before and after issue 27 item 3.

``well_conditioned_feedback(plant, region=...)`` used to design the observer of the dual pair
``(A', B')`` and so minimized the condition number of the LEFT eigenvectors of ``A - B K``.  It now
minimizes ``cond(X)`` of the unit-column RIGHT eigenvectors ``X`` of ``A - B K`` (scipy's measure),
in controller mode, from the usual starts and from the dual route's design.  Side by side, in one
process, each timed with ``time.process_time`` (CPU seconds):

* **before**: the dual route as the verb ran it (``well_conditioned_observer`` on ``(A', B')``,
  ``K = L'``), with the same ``time_limit``;
* **after**: ``well_conditioned_feedback`` (dual route with half the budget, then the controller mode).

``cond(X)`` is recomputed here for both gains from numpy's unit-column right eigenvectors of
``A - B K``; ``in region``: ``region.margin(eig(A - B K)) <= 1e-7 max(1, max |pole|)``.

Plants: COMPleib plants (``problems/compleib``, state feedback on their own (A, B)), the
state-feedback form ``(A, B) = (A', C')`` of Byers 5 and Chu 2007 example 8
(``problems/poleplacement``; the issue's two cases) and random plants n = 3..8, m = 2 (``A ~ N(0,
1/n)``, ``B ~ N(0, 1)``, seed 2027).  Region: ``suggested_region`` of the dual plant (HalfPlane(alpha)
& Sector.from_damping(0.5) & Disk(0, 2 max(rho, alpha))).  ``starts`` and ``seed`` at the verb's
defaults; ``time_limit`` 30 s per design (``--time-limit``).

Run from the repository root (under the shared timing lock; ``PYTHONPATH=.`` so that this checkout's
``optdesign`` is the one measured)::

    OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 PYTHONPATH=. flock /tmp/bench.lock \
        python benchmarks/bench_feedback_region.py

writes ``benchmarks/results/feedback_region.md``.  Numbers, not pass/fail.
"""

from __future__ import annotations

# isort: off
import _common  # noqa: F401  first: single-threaded BLAS before numpy
# isort: on

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

from optdesign import Plant, problems
from optdesign.design.feedback import dual_plant, well_conditioned_feedback
from optdesign.design.well_conditioned import suggested_region, well_conditioned_observer
from optdesign.errors import OptDesignError

HERE = Path(__file__).resolve().parent

#: COMPleib plants of the default run (n <= 9, continuous; a mix of one and several inputs)
COMPLEIB = ("ac1", "ac4", "ac5", "ac6", "ac7", "dis1", "dis2", "he1", "he5", "nn8", "psm", "rea1", "uwv")
#: the issue's pole-placement problems, in state-feedback form
PLACEMENT = ("pp_byers5", "pp_chu2007_ex8")


def cond_x(F: np.ndarray) -> float:
    """cond(X) of numpy's unit-column right eigenvectors of F."""
    _, X = np.linalg.eig(F)
    return float(np.linalg.cond(X / np.linalg.norm(X, axis=0)))


def in_region(region, F: np.ndarray) -> bool:
    ev = np.linalg.eigvals(F)
    return bool(region.margin(ev) <= 1e-7 * max(1.0, float(np.max(np.abs(ev)))))


def fmt(x, d=5) -> str:
    if x is None:
        return "-"
    if isinstance(x, float) and not math.isfinite(x):
        return str(x)
    return f"{x:.{d}g}"


def measure(A: np.ndarray, B: np.ndarray, region, time_limit: float) -> dict:
    """Before (the dual route) and after (the verb), each on cond(X) of A - B K."""
    out: dict = {}
    t0 = time.process_time()
    try:
        obs = well_conditioned_observer(dual_plant(A, B), region=region, time_limit=time_limit)
        K = None if obs.L is None or not np.all(np.isfinite(obs.L)) else np.asarray(obs.L).T
        out["before"] = (cond_x(A - B @ K) if K is not None else None,
                         K is not None and in_region(region, A - B @ K), obs.status.value)
    except OptDesignError as exc:
        out["before"] = (None, False, f"{type(exc).__name__}")
    out["t_before"] = time.process_time() - t0
    t0 = time.process_time()
    try:
        d = well_conditioned_feedback(Plant(A, np.eye(A.shape[0]), B=B), region=region, time_limit=time_limit)
        K = d.K if d.K is not None and np.all(np.isfinite(d.K)) else None
        k = cond_x(A - B @ K) if K is not None else None
        out["after"] = (k, K is not None and in_region(region, A - B @ K), d.status.value)
        out["reported"] = d.kappa2
        out["chosen"] = d.extra.get("chosen", d.extra.get("mode", ""))
        out["dual_inside"] = d.extra.get("kappa2_dual_route")
    except OptDesignError as exc:
        out["after"] = (None, False, f"{type(exc).__name__}")
    out["t_after"] = time.process_time() - t0
    return out


def plants(quick: bool):
    for name in COMPLEIB[:4] if quick else COMPLEIB:
        pl = problems.load(f"compleib_{name}").plant
        yield f"COMPleib {name.upper()}", pl.A, pl.B
    for name in PLACEMENT:
        pl = problems.load(name).plant
        yield name, pl.A.T, pl.C.T
    rng = np.random.default_rng(2027)
    for n in range(3, 9 if not quick else 5):
        yield f"random n={n} m=2", rng.standard_normal((n, n)) / np.sqrt(n), rng.standard_normal((n, 2))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="4 COMPleib plants, n = 3..4 random")
    ap.add_argument("--time-limit", type=float, default=30.0)
    ap.add_argument("--out", default=str(HERE / "results" / "feedback_region.md"))
    args = ap.parse_args(argv)
    lines = [
        "# State feedback in a region: cond(X) of A - B K before (dual route) and after (controller mode)",
        "",
        f"Generated by `benchmarks/bench_feedback_region.py{' --quick' if args.quick else ''}` "
        f"(time_limit {args.time_limit:g} s per design; CPU seconds by time.process_time, single-threaded "
        "BLAS, under `flock /tmp/bench.lock`).  cond(X): numpy's unit-column right eigenvectors of A - B K, "
        "recomputed here for both gains.  `before`: the dual route (the observer of (A', B'), minimizing "
        "the left eigenvectors' condition; the verb's answer before issue 27 item 3).  `after`: "
        "`well_conditioned_feedback(plant, region=...)` now (its CPU includes the dual route, run first "
        "with half the budget).  `answered`: which candidate (dual = the dual route's design kept, region = "
        "the region engine in controller mode, polish = the fixed-pole controller mode at its poles).  `its "
        "dual start`: cond(X) of the dual route's design inside `after` (half the budget; after <= it by "
        "construction -- `before` ran the dual route with the whole budget, so a timed-out `before` can "
        "differ from it).",
        "",
        "| plant | n | m | cond(X) before | cond(X) after | after / before | its dual start | "
        "in region (b/a) | answered | status (b/a) | CPU before s | CPU after s | CPU ratio |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    ratios, cpu_b, cpu_a, worse = [], 0.0, 0.0, []
    for name, A, B in plants(args.quick):
        region = suggested_region(dual_plant(A, B))
        r = measure(A, B, region, args.time_limit)
        kb, okb, sb = r["before"]
        ka, oka, sa = r.get("after", (None, False, "-"))
        ratio = ka / kb if ka is not None and kb and math.isfinite(kb) and math.isfinite(ka) else None
        if ratio is not None:
            ratios.append(ratio)
            if ratio > 1 + 1e-9:
                worse.append(name)
        cpu_b += r["t_before"]
        cpu_a += r["t_after"]
        lines.append(
            f"| {name} | {A.shape[0]} | {B.shape[1]} | {fmt(kb, 7)} | {fmt(ka, 7)} | {fmt(ratio, 4)} | "
            f"{fmt(r.get('dual_inside'), 7)} | "
            f"{'yes' if okb else 'no'}/{'yes' if oka else 'no'} | {r.get('chosen', '-')} | {sb}/{sa} | "
            f"{r['t_before']:.2f} | {r['t_after']:.2f} | {r['t_after'] / max(r['t_before'], 1e-9):.2f} |")
        print(f"{name}: before {fmt(kb)} after {fmt(ka)} ({r['t_before']:.1f} s / {r['t_after']:.1f} s)",
              file=sys.stderr, flush=True)
    lines += [
        "",
        f"cond(X) after / before over {len(ratios)} plants: median {np.median(ratios):.4f}, best "
        f"{min(ratios):.4f}, worst {max(ratios):.4f}; worse on {len(worse)}"
        + (f" ({', '.join(worse)})" if worse else "") + f".  Total CPU: before {cpu_b:.1f} s, after "
        f"{cpu_a:.1f} s ({cpu_a / max(cpu_b, 1e-9):.2f}x).",
        "",
    ]
    Path(args.out).write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
