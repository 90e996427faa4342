"""Sweep benchmark: parameter re-use vs rebuilding, and a 1,000-point sweep on a local pool and on Dask.

Run:  python benchmarks/bench_sweep.py [--problem compleib_dis2] [--subset 40] [--alphas 40 --zetas 25]
                                        [--b-alphas 40] [--no-dask] [--skip-a | --skip-b] [--variants 4,5]
                                        [--out benchmarks/results/sweep.md]

A. Time per point, one process, the same points (a block of the grid), for
   1. the public verb ``well_conditioned_observer(plant, region=..., starts=2)`` per point (a new
      problem for every call: the placement engine, IPOPT only as a fallback),
   2. ``RegionSweepDesigner(reuse=False, warm_start=False)``: the sweep algorithm (its
      ``WellConditionedProblem`` on the NLP route), a new problem (NLPs rebuilt) per point,
   3. ``RegionSweepDesigner(reuse=True, warm_start=False)``: one problem, NLPs built once, cold starts,
   4. ``RegionSweepDesigner(placement="always")`` (the default before the pool): re-use + warm start
      from the previous point + the placement starts at every point,
   5. ``RegionSweepDesigner(placement="fallback")``: re-use + warm start, placement only when needed;
   6. ``RegionSweepDesigner()`` (default, ``placement="pool"``): re-use + every start's local optimum
      carried to the next point as a warm start, placement on a chunk's first point and when the pool
      collapses to one optimum;
   with the CPU time per point (median and mean), the deterministic work per point (IPOPT iterations,
   IPOPT solves, independent evaluations, scipy placements), the success rate and kappa2 against the
   best found by any variant run.
B. The grid (alpha x damping sector, 1,000 points by default; ``--b-alphas`` alphas) with the default
   designer on a local process pool of 2 workers and on a 2-worker Dask LocalCluster: wall time,
   throughput, identical results.

Numbers, not pass/fail; written as a markdown table (default ``benchmarks/results/sweep.md``).
"""

from __future__ import annotations

import argparse
import datetime
import json
import logging
import os
import platform
import sys
import time
from pathlib import Path

import _common  # noqa: E402,F401  (single-threaded BLAS before numpy)
import numpy as np  # noqa: E402

from optdesign import problems  # noqa: E402
from optdesign.design.well_conditioned import well_conditioned_observer  # noqa: E402
from optdesign.studies import RegionSweepDesigner, grid, sweep  # noqa: E402
from optdesign.studies.designers import clear_cache  # noqa: E402

RADIUS = 20.0


def verb_point(problem: str, alpha: float, zeta: float):
    """The rebuild baseline: the public verb on the point's region (module-level, picklable)."""
    designer = RegionSweepDesigner(problem=problem, radius=RADIUS)
    region = designer.region_for(alpha=alpha, zeta=zeta)
    return well_conditioned_observer(problems.load(problem).plant, region=region,
                                     starts=2, seed=0)


def timed_serial(fn, points):
    """Run fn over points in this process; per-point wall and CPU times and the results."""
    times, cpu, results = [], [], []
    for p in points:
        t0, c0 = time.perf_counter(), time.process_time()
        try:
            r = fn(**p)
        except Exception as exc:  # noqa: BLE001 - counted as a failure
            r = exc
        times.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
        results.append(r)
    return np.array(times), np.array(cpu), results


class WorkCounter:
    """Counts the IPOPT solves, the independent evaluations and the scipy placements of the designs
    (by wrapping the module functions the problem object calls; restored on exit)."""

    def __init__(self) -> None:
        from optdesign.design.well_conditioned import nlp_route, problem, starts

        self.targets = [(nlp_route, "solve_nlp", "solves"), (problem, "evaluate_candidate", "evals"),
                        (starts, "place_observer", "placements")]
        self.counts = dict.fromkeys(("solves", "evals", "placements"), 0)

    def __enter__(self) -> WorkCounter:
        self.saved = [getattr(mod, name) for mod, name, _ in self.targets]
        for (mod, name, key), fn in zip(self.targets, self.saved, strict=True):
            setattr(mod, name, self._counted(fn, key))
        return self

    def _counted(self, fn, key):
        def wrapper(*args, **kwargs):
            self.counts[key] += 1
            return fn(*args, **kwargs)
        return wrapper

    def __exit__(self, *exc) -> None:
        for (mod, name, _), fn in zip(self.targets, self.saved, strict=True):
            setattr(mod, name, fn)


def part_a(problem: str, points: list[dict], which: list[int] | None = None) -> tuple[list[dict], dict]:
    rows = []

    def variant(**kw):  # made when its variant runs (the code before may not know every option)
        return lambda: RegionSweepDesigner(problem=problem, radius=RADIUS, **kw)

    variants = [
        ("public verb per point (rebuild, starts=2)", lambda: None),
        ("designer, NLP rebuilt per point, cold", variant(reuse=False, warm_start=False, placement="always")),
        ("designer, NLP re-used, cold", variant(warm_start=False, placement="always")),
        ("designer, re-used + warm start + placement at every point", variant(placement="always")),
        ("designer, re-used + warm start, placement as fallback", variant(placement="fallback")),
        ("designer, re-used + pool of local optima (placement='pool', the default)", variant()),
    ]
    if which is not None:
        variants = [variants[i - 1] for i in which]
    for name, make in variants:
        clear_cache()
        designer = make()
        with WorkCounter() as work:
            if designer is None:
                times, cpu, res = timed_serial(lambda alpha, zeta: verb_point(problem, alpha, zeta), points)
            else:
                session = designer.start_chunk()  # one chunk: the warm start runs along the points
                times, cpu, res = timed_serial(session, points)
        ok = np.array([not isinstance(r, Exception) and r.success for r in res])
        k = np.array([r.kappa2 if not isinstance(r, Exception) and r.success else np.nan for r in res])
        its = np.array([0 if isinstance(r, Exception) else r.solver_stats.iterations for r in res],
                       dtype=float)
        rows.append({"variant": name, "kappa2": k.tolist(), "median_ms": 1e3 * np.median(times),
                     "mean_ms": 1e3 * np.mean(times),
                     "cpu_median_ms": 1e3 * np.median(cpu), "cpu_total_s": float(np.sum(cpu)),
                     "cpu_mean_ms": 1e3 * np.mean(cpu),
                     **{key: v / len(points) for key, v in work.counts.items()},
                     "first_ms": 1e3 * times[0], "iters": float(np.mean(its)), "success": int(ok.sum()),
                     "n": len(points)})
        print(f"  {name}: median {1e3 * np.median(times):.0f} ms/point "
              f"(CPU median {1e3 * np.median(cpu):.0f}, "
              f"mean {1e3 * np.mean(cpu):.0f}), {np.mean(its):.1f} IPOPT iterations and "
              f"{work.counts['solves'] / len(points):.2f} solves/point, {ok.sum()}/{len(points)} verified",
              flush=True)
    # build + configure cost on its own
    from optdesign.formulate.well_conditioned import NLPScaling, PoleStructure, build_observer_nlp
    from optdesign.backends.casadi_backend import solve_opti

    plant = problems.load(problem).plant
    tb = []
    for _ in range(5):
        t0 = time.perf_counter()
        nlp = build_observer_nlp(plant, PoleStructure(plant.n, 0), fixed_poles=False, decay=1.0, damping=0.5,
                                 radius=RADIUS, scaling=NLPScaling.for_plant(plant, RADIUS, balance=False))
        nlp.set_initial_gain(np.zeros((plant.n, plant.p)))
        solve_opti(nlp.opti, {"ipopt.max_iter": 0})
        tb.append(time.perf_counter() - t0)
    return rows, {"build_configure_ms": 1e3 * float(np.median(tb))}


def score(rows: list[dict]) -> None:
    """kappa2 of every row against the best of all rows at each point (within 0.1 %, worst ratio)."""
    k2 = np.array([np.asarray(r["kappa2"], dtype=float) for r in rows])
    best = np.nanmin(k2, axis=0)
    for r, k in zip(rows, k2, strict=True):
        ratio = k / best
        r["within_1e-3"] = int(np.sum(ratio <= 1 + 1e-3))
        r["worst_ratio"] = float(np.nanmax(ratio)) if np.isfinite(ratio).any() else float("nan")


def part_b(problem: str, points: list[dict], chunk: int, use_dask: bool,
           placement: str = "always") -> list[dict]:
    designer = RegionSweepDesigner(problem=problem, radius=RADIUS, placement=placement)
    out = []
    local = sweep(designer, points, executor="processes", workers=2, chunksize=chunk)
    out.append({"executor": "local process pool (2 workers)", "table": local})
    print(f"  local pool: {local.summary()}", flush=True)
    if use_dask:
        from distributed import Client, LocalCluster

        t0 = time.perf_counter()
        with LocalCluster(n_workers=2, threads_per_worker=1, dashboard_address=":0",
                          silence_logs=logging.ERROR) as cluster, Client(cluster) as client:
            startup = time.perf_counter() - t0
            on_dask = sweep(designer, points, executor=client, chunksize=chunk)
        out.append({"executor": "Dask LocalCluster (2 workers x 1 "
                                "thread)", "table": on_dask, "startup": startup})
        print(f"  Dask: {on_dask.summary()}", flush=True)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--problem", default="compleib_dis2")
    ap.add_argument("--subset", type=int, default=40, help="points of part A (a block of consecutive points)")
    ap.add_argument("--alphas", type=int, default=40)
    ap.add_argument("--zetas", type=int, default=25)
    ap.add_argument("--b-alphas", type=int, default=None, help="alphas of part B (default: --alphas)")
    ap.add_argument("--no-dask", action="store_true")
    ap.add_argument("--skip-a", action="store_true")
    ap.add_argument("--skip-b", action="store_true", help="part A alone")
    ap.add_argument("--variants", default=None,
                    help="part A: the variants to run, by number (1-6, see above), e.g. 4,5")
    ap.add_argument("--b-placement", default="pool", help="part B: the designer's placement mode")
    ap.add_argument("--start", type=int, default=None,
                    help="part A: index of its first grid point (default: a block from the middle)")
    ap.add_argument("--json-out", default=None, help="part A: also write its rows (with kappa2) as JSON")
    ap.add_argument("--b-json-out", default=None,
                    help="part B: also write the local pool's per-point kappa2 and status as JSON")
    ap.add_argument("--before", default=None,
                    help="part A: the JSON of an earlier run (--json-out, e.g. of the code before a change, "
                         "run just before this one): its rows head the table as 'before: ...' and its "
                         "kappa2 counts in the best")
    ap.add_argument("--out", default=str(Path(__file__).resolve().parent / "results" / "sweep.md"))
    args = ap.parse_args(argv)
    # zeta descending: within a chunk the sector widens, so the previous design stays feasible
    points = grid(alpha=np.linspace(0.5, 3.0, args.alphas), zeta=np.linspace(0.9, 0.2, args.zetas))
    start = (len(points) // 2 // args.zetas) * args.zetas  # a block of rows from the middle of the grid
    if args.start is not None:
        start = args.start
    subset = points[start:start + args.subset]
    lines = [
        "# Sweep benchmark: parameter re-use vs rebuilding; local pool vs Dask",
        "",
        f"Generated by `benchmarks/bench_sweep.py` on {datetime.date.today()} -- {platform.platform()}, "
        f"Python {platform.python_version()}, {os.cpu_count()} cores (shared: load average at start "
        f"{', '.join(f'{x:.1f}' for x in os.getloadavg())}), "
        f"OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS')}.",
        "",
        f"Problem `{args.problem}` (COMPleib), objective kappa2, poles in "
        f"`HalfPlane(alpha) & Sector.from_damping(zeta) & Disk(0, {RADIUS:g})`; "
        f"grid alpha = linspace(0.5, 3, {args.alphas}) x zeta = linspace(0.9, 0.2, {args.zetas}) "
        f"= {len(points)} points.",
        "",
    ]
    if not args.skip_a:
        print(f"A. per-point cost on {len(subset)} points", flush=True)
        which = None if args.variants is None else [int(v) for v in args.variants.split(",")]
        rows, extra = part_a(args.problem, subset, which)
        if args.json_out:
            Path(args.json_out).write_text(json.dumps({"rows": rows, "extra": extra}), encoding="utf-8")
        if args.before:
            earlier = json.loads(Path(args.before).read_text(encoding="utf-8"))["rows"]
            rows = [{**r, "variant": f"before: {r['variant']}"} for r in earlier] + rows
        score(rows)
        base = rows[0]["cpu_median_ms"]
        lines += [
            f"## A. Time per point, one process, {len(subset)} consecutive points "
            f"(alpha {subset[0]['alpha']:.3g}..{subset[-1]['alpha']:.3g}, every zeta)",
            "",
            "| variant | median ms/point | first point ms | median CPU ms/point | mean CPU ms/point "
            "| total CPU s | CPU ratio to the first row (median, mean) | IPOPT iterations/point "
            "| IPOPT solves/point | evaluations/point | scipy placements/point "
            "| verified | kappa2 within 0.1% of the best | worst kappa2 / best |",
            "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
        ]
        for r in rows:
            lines.append(f"| {r['variant']} | {r['median_ms']:.0f} | "
                         f"{r['first_ms']:.0f} | {r['cpu_median_ms']:.1f} | {r['cpu_mean_ms']:.0f} | "
                         f"{r['cpu_total_s']:.1f} | {base / r['cpu_median_ms']:.1f}x, "
                         f"{rows[0]['cpu_mean_ms'] / r['cpu_mean_ms']:.1f}x | {r['iters']:.1f} | "
                         f"{r['solves']:.2f} | {r['evals']:.2f} | {r['placements']:.2f} | "
                         f"{r['success']}/{r['n']} | "
                         f"{r['within_1e-3']}/{r['n']} | {r['worst_ratio']:.4g} |")
        lines += [
            "",
            f"Building the NLP and configuring IPOPT (CasADi `Opti` + `nlpsol`, one pole structure) takes "
            f"{extra['build_configure_ms']:.0f} ms (median of 5). The sweep designer's problem object "
            "(`WellConditionedProblem`, NLP route) pays it once per worker and pole structure, then only "
            "sets `opti.parameter` values (decay, damping, radius, bounds) and re-solves; with "
            "`reuse=False` every point builds a new problem. The public verb answers with the placement "
            "engine (IPOPT only as a fallback).",
            "",
        ]
    if args.skip_b:
        return _write(args.out, lines)
    if args.b_alphas is not None:
        points = grid(alpha=np.linspace(0.5, 3.0, args.b_alphas), zeta=np.linspace(0.9, 0.2, args.zetas))
    print(f"B. {len(points)} points on a local pool and on Dask", flush=True)
    runs = part_b(args.problem, points, args.zetas, not args.no_dask, args.b_placement)
    ref = runs[0]["table"]
    if args.b_json_out:
        Path(args.b_json_out).write_text(json.dumps({"points": [
            {"alpha": r["alpha"], "zeta": r["zeta"], "success": bool(r["success"]), "kappa2": r.get("kappa2"),
             "time": r.get("time")} for r in ref.records]}), encoding="utf-8")
    lines += [
        f"## B. {len(points)}-point sweep, designer (placement={args.b_placement!r}), chunks of "
        f"{args.zetas} points (one alpha per chunk)",
        "",
        "| executor | wall time (s) | points/s | median time/point in worker (ms) "
        "| mean time/point in worker (ms) | verified | failed | differences from the local pool |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in runs:
        t = r["table"]
        diff = t.diff(ref)
        extra = f" (+{r['startup']:.1f} s cluster start)" if "startup" in r else ""
        lines.append(f"| {r['executor']} | {t.wall_time:.1f}{extra} | {len(t) / t.wall_time:.2f} | "
                     f"{1e3 * np.nanmedian(t.column('time')):.0f} | "
                     f"{1e3 * np.nanmean(t.column('time')):.0f} | "
                     f"{t.n_success} | {len(t) - t.n_success} | "
                     f"{len(diff)} cells |")
    fails = [r for r in ref.records if not r["success"]]
    if fails:
        lines += ["", "Failed points (local pool): " + ", ".join(
            f"(alpha {r['alpha']:.3g}, zeta {r['zeta']:.3g}: "
            f"{r['error'] or r['status']})" for r in fails[:10])
            + (" ..." if len(fails) > 10 else "")]
    k = ref.column("kappa2")[np.array([r["success"] for r in ref.records])]
    if k.size:
        lines += ["", f"kappa2 over the verified points: min {np.min(k):.4g}, median {np.median(k):.4g}, "
                      f"max {np.max(k):.4g}."]
    return _write(args.out, lines)


def _write(out: str, lines: list[str]) -> int:
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    Path(out).write_text("\n".join(lines) + "\n", encoding="utf-8")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
