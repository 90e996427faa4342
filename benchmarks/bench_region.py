"""Region-mode designs of the well-conditioned observer: today's default (the base commit) and the new
default route side by side (issue 28).

Run:  python benchmarks/bench_region.py run {new,base,prev} --set {subset,full} --objective {kappa2,eta}
          --json F [--route auto|engine|fast|multistart|nlp|default]
      python benchmarks/bench_region.py pair {base,prev} --set ... --objective ... --json OLD.json NEW.json
      python benchmarks/bench_region.py report --base B.json [...] --prev P.json --new N.json
          [--notes NOTES.md] --out benchmarks/results/region.md

``run new`` imports the checkout this script lives in and designs with the verb's default (``--route R``:
``WellConditionedProblem(route=R)``); ``run base`` re-runs this script in a subprocess
with ``PYTHONPATH`` set to a checkout of the commit before issue 28 (``BASE_COMMIT``), made once with::

    mkdir /tmp/region-base-d9d35ed && git archive d9d35ed | tar -x -C /tmp/region-base-d9d35ed

(as ``bench_sweep_grid.py`` measures its baseline).  Each design is one call of
``well_conditioned_observer(plant, region=..., objective=..., time_limit=TIME_LIMIT)``; CPU is
``time.process_time`` around it, single-threaded BLAS (``_common``), after one untimed design of the
first case (the process's one-time imports; its CPU is kept as ``warmup`` in the JSON).  Cases: every
continuous COMPleib plant with n <= 10 (``suggested_region``), random plants n = 3..10 (two per size plus
four more; ``p = max(1, n // 3)``, A ~ N(0, 1/n)) and n = 20 (p = 5), n = 30 (p = 7) with the region of
the issue's random example, ``HalfPlane(0.5) & Sector.from_damping(0.5) & Disk(0, 5)``.  ``--set
subset``: REA2, DIS1, HE5, AC6 and five random plants; ``--set large``: random plants n = 12-30 (``LARGE``).
Numbers, not pass/fail.  Time every run under ``flock /tmp/bench.lock``.

``pair`` (round 15) times an older code and this checkout in one run: two worker processes (``serve``),
each with its code loaded and warmed up, design the same plant one after the other, the order
alternating from plant to plant, and never at the same time.  The machine's speed drifts (measured
in round 15: the same code's 50-plant eta harness took 153 s, and 180 s 38 minutes later), more than
the effects measured; paired designs minutes, not a run, apart share the drift.  Its two run files are
``run``'s format, for ``report``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import _common  # noqa: F401  (single-threaded BLAS before numpy)
import numpy as np

BASE_COMMIT = "d9d35ed"
BASE_DIR = "/tmp/region-base-d9d35ed"
#: the commit before this round's change (the previous stop's final commit: a one-output region no pole
#: set reaches still runs IPOPT's fallback from every start), made as the base: ``git archive d607c1f``
PREV_COMMIT = "d607c1f"
PREV_DIR = "/tmp/region-prev-d607c1f"
DIRS = {"base": (BASE_COMMIT, BASE_DIR), "prev": (PREV_COMMIT, PREV_DIR)}
#: seconds of wall time per design (both codes): today's default ran past 120 s on some n = 9-10 plants
TIME_LIMIT = 150.0
SUBSET_COMPLEIB = ("compleib_rea2", "compleib_dis1", "compleib_he5", "compleib_ac6")


def random_cases(full: bool) -> list[tuple[str, int, int, int]]:
    """``(name, n, p, seed)`` of the random plants."""
    if not full:
        sizes = [5, 5, 6, 8, 10]
    else:
        sizes = [n for n in range(3, 11) for _ in range(2)] + [4, 6, 8, 10] + [20, 30]
    out, count = [], {}
    for n in sizes:
        k = count.get(n, 0)
        count[n] = k + 1
        p = 5 if n == 20 else 7 if n == 30 else max(1, n // 3) if n > 5 or k else 2
        out.append((f"random_n{n}_p{p}_s{k}", n, p, 1000 * n + k))
    return out


#: ``--set large``: random plants above n = 10 ``(n, p, how many)`` (round 12: eta's route there)
LARGE = ((12, 3, 2), (16, 4, 2), (20, 5, 2), (25, 6, 1), (30, 7, 2))


def cases(which: str):
    from _common import random_observable_plant

    from optdesign import problems
    from optdesign.design.well_conditioned import suggested_region
    from optdesign.regions import Disk, HalfPlane, Sector

    random_region = HalfPlane(0.5) & Sector.from_damping(0.5) & Disk(0.0, 5.0)  # the issue's random example
    if which == "large":
        for n, p, count in LARGE:
            for k in range(count):
                plant = random_observable_plant(np.random.default_rng(1000 * n + k), n, p)
                yield f"random_n{n}_p{p}_s{k}", plant, random_region
        return
    names = (SUBSET_COMPLEIB if which == "subset" else
             [n for n in problems.names() if n.startswith("compleib")])
    for name in names:
        plant = problems.load(name).plant
        if plant.n <= 10 and not plant.is_discrete:
            yield name, plant, suggested_region(plant)
    for name, n, p, seed in random_cases(which == "full"):
        plant = random_observable_plant(np.random.default_rng(seed), n, p)
        yield name, plant, random_region


def run(which: str, objective: str, out: str, only: str | None, route: str | None, code: str = "new") -> None:
    design = _designer(objective, route)
    warmup = _warm_up(which, design)
    rows = []
    for name, plant, region in cases(which):
        if only and name not in only.split(","):
            continue
        rows.append(_row(name, plant, region, design))
        print(f"{name} n={plant.n} p={plant.p} {objective} {rows[-1]['status']} {rows[-1]['kappa2']:.6g} "
              f"eta {rows[-1]['eta']:.6g} cpu {rows[-1]['cpu']:.2f} s", flush=True)
        _write(out, objective, code, warmup, rows)


def _designer(objective: str, route: str | None):
    """``design(plant, region)``: the verb's default (``route`` None), else
    ``WellConditionedProblem(route=route)``."""
    from optdesign import well_conditioned_observer
    from optdesign.design.well_conditioned import WellConditionedProblem

    def design(plant, region):
        if route is None:
            return well_conditioned_observer(plant, region=region, objective=objective, time_limit=TIME_LIMIT)
        return WellConditionedProblem(plant, objective=objective, route=route).solve(region=region,
                                                                                   time_limit=TIME_LIMIT)
    return design


def _warm_up(which: str, design) -> dict:
    """One untimed design first: the first design of a process imports what the package loads lazily
    (scipy.signal and its dependencies, about 0.5 s of CPU once), which is not the design's cost."""
    warm_name, warm_plant, warm_region = next(iter(cases(which)))
    c0 = time.process_time()
    design(warm_plant, warm_region)
    return {"name": warm_name, "cpu": time.process_time() - c0}


def _row(name: str, plant, region, design) -> dict:
    """One timed design and what the report reads of it (kappa2 recomputed from the returned gain)."""
    from optdesign import metrics

    c0 = time.process_time()
    d = design(plant, region)
    cpu = time.process_time() - c0
    k2 = float(metrics.kappa2(plant.A - d.L @ plant.C)) if np.all(np.isfinite(d.L)) else float("nan")
    trace = getattr(d, "route", None)
    return {"name": name, "n": plant.n, "p": plant.p, "status": d.status.value,
            "kappa2": float(d.kappa2), "eta": float(d.eta), "kappa2_recomputed": k2,
            "verified": bool(d.verification.passed),
            "cpu": cpu, "route": str(trace.answered.name) if trace and trace.answered else
            d.solver_stats.extra.get("route", "")}


def _write(out: str, objective: str, code: str, warmup: dict, rows: list[dict]) -> None:
    label = DIRS[code][0] if code in DIRS else "this checkout"
    Path(out).write_text(json.dumps({"objective": objective, "code": code, "commit": label,
                                     "warmup": warmup, "rows": rows}, indent=1))


def serve(which: str, objective: str) -> None:
    """A worker of :func:`pair`: warm up, print ``ready``, then per plant name read from stdin one
    design's row (JSON, one line)."""
    design = _designer(objective, None)
    by_name = {name: (plant, region) for name, plant, region in cases(which)}
    warmup = _warm_up(which, design)
    print(json.dumps({"ready": True, "warmup": warmup}), flush=True)
    for line in sys.stdin:
        name = line.strip()
        print(json.dumps(_row(name, *by_name[name], design)), flush=True)


def pair(old: str, which: str, objective: str, outs: tuple[str, str], only: str | None) -> None:
    """The ``old`` code (``base`` or ``prev``) and this checkout, plant by plant in alternating order
    (module docstring); run files ``outs`` (old, new)."""
    codes = (old, "new")
    procs, warm = [], []
    for code in codes:
        env = {**os.environ, "PYTHONPATH": DIRS[code][1]} if code in DIRS else dict(os.environ)
        args = [sys.executable, __file__, "serve", code, "--set", which, "--objective", objective]
        pr = subprocess.Popen(args, env=env, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        procs.append(pr)
        warm.append(_reply(procs[-1], code)["warmup"])
    rows: tuple[list[dict], list[dict]] = ([], [])
    names = [name for name, _, _ in cases(which) if not only or name in only.split(",")]
    for i, name in enumerate(names):
        for j in ((0, 1) if i % 2 == 0 else (1, 0)):
            rows[j].append(_reply(procs[j], codes[j], name))
        a, b = rows[0][-1], rows[1][-1]
        print(f"{name:22s} {objective} {a[objective]:.6g} {b[objective]:.6g}  cpu {a['cpu']:.2f} "
              f"{b['cpu']:.2f} s  ratio {b['cpu'] / a['cpu']:.2f}", flush=True)
        for j, code in enumerate(codes):
            _write(outs[j], objective, code, warm[j], rows[j])
    for pr in procs:
        pr.communicate()


def _reply(pr: subprocess.Popen, code: str, name: str | None = None) -> dict:
    """The worker's next line (after sending it ``name``, a plant to design), as JSON; a worker that
    stopped is said so by name (its traceback is on stderr above)."""
    assert pr.stdin is not None and pr.stdout is not None
    if name is not None:
        pr.stdin.write(name + "\n")
        pr.stdin.flush()
    line = pr.stdout.readline()
    if not line:
        raise SystemExit(f"bench_region pair: the {code!r} worker stopped (exit code {pr.wait()}) "
                         f"before answering{' for ' + name if name else ''}; its error is above")
    return json.loads(line)


def _rows(files: list[str]) -> tuple[str, dict[str, dict]]:
    """``(objective, name -> row)`` of run files of one code (later files override earlier rows)."""
    obj, rows = "", {}
    for f in files:
        d = json.loads(Path(f).read_text())
        obj = d["objective"]
        rows.update({r["name"]: r for r in d["rows"]})
    return obj, rows


def _rel(v: float, ref: float) -> float:
    return (v - ref) / ref if np.isfinite(v) and np.isfinite(ref) else float("nan")


def report(base: list[str], prev: list[str], new: list[str], out: str, notes: str = "") -> None:
    """One table per objective: the base (issue 28's "today's default"), the previous commit and
    this checkout side by side; ``rel`` columns (new - ref) / ref of the objective (negative: new
    better), speed-ups base / new and prev / new CPU."""
    lines = ["# Region-mode designs: today's default (base), the previous commit (prev) and this checkout "
             "(new)", "",
             f"Base: commit {BASE_COMMIT}, the verb's default before issue 28 (IPOPT from 8 starts, then "
             "one engine start; in this checkout `route='multistart'`).  Prev: commit "
             f"{PREV_COMMIT} (the previous stop: the lockstep region engine, 8 starts up to n = 12, 4 up "
             "to 24, then 2, 5 members kept after the second stage; for eta 16 engine starts and "
             "IPOPT from one up to n = 10).  New: this checkout's default (the same starts and path; "
             "a member re-anchored at its chart's edge goes on in the same BFGS batch, round 15).  "
             "Prev and new were timed in one run (`pair`: alternating, plant by plant).  "
             "CPU seconds per design (`time.process_time`, single-threaded BLAS; from round 10 after "
             "one untimed design of the first case per process, the one-time imports), time limit "
             f"{TIME_LIMIT:g} s (wall) per design.  Produced by `benchmarks/bench_region.py report`.", ""]
    _, b = _rows(base)
    _, pv = _rows(prev)
    obj, nw = _rows(new)
    lines += [f"## objective {obj}", "",
              f"| plant | n, p | base {obj} | base status | base CPU | prev {obj} | prev CPU | new {obj} | "
              "new status | new CPU | rel base | rel prev | speed-up base, prev |",
              "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    worse_b, worse_p, cpu = [], [], {"base": [], "prev": [], "new": []}
    sp_b, sp_p = [], []
    for k, rn in nw.items():
        rb, rp = b.get(k), pv.get(k)
        vb = rb[obj] if rb else float("nan")
        vp = rp[obj] if rp else float("nan")
        vn = rn[obj]
        relb, relp = _rel(vn, vb), _rel(vn, vp)
        if rb and ((np.isfinite(relb) and relb > 1e-3) or (np.isfinite(vb) and not np.isfinite(vn))):
            worse_b.append(k)
        if rp and np.isfinite(relp) and relp > 1e-3:
            worse_p.append(k)
        small = rn["n"] <= 10
        if small:
            cpu["new"].append(rn["cpu"])
            if rb:
                cpu["base"].append(rb["cpu"])
            if rp:
                cpu["prev"].append(rp["cpu"])
        if rb:
            sp_b.append(rb["cpu"] / max(rn["cpu"], 1e-9))
        if rp:
            sp_p.append(rp["cpu"] / max(rn["cpu"], 1e-9))

        def cell(r, key, fmt):
            return format(r[key], fmt) if r else "–"

        spb = f"{rb['cpu'] / max(rn['cpu'], 1e-9):.1f}x" if rb else "–"
        spp = f"{rp['cpu'] / max(rn['cpu'], 1e-9):.1f}x" if rp else "–"
        lines.append(f"| {k} | {rn['n']}, {rn['p']} | {cell(rb, obj, '.6g')} | "
                     f"{rb['status'] if rb else '–'} | {cell(rb, 'cpu', '.2f')} | {cell(rp, obj, '.6g')} | "
                     f"{cell(rp, 'cpu', '.2f')} | {vn:.6g} | {rn['status']} | {rn['cpu']:.2f} | "
                     f"{relb:+.1e} | {relp:+.1e} | {spb}, {spp} |")
    med = {c: (f"{np.median(v):.2f} s ({len(v)} plants)" if v else "–") for c, v in cpu.items()}
    lines += ["", f"- median CPU per design at n <= 10: base {med['base']}, prev {med['prev']}, "
              f"new {med['new']}",
              "- the untimed first design of each process (one-time imports): "
              + ", ".join(f"{c} {w['name']} {w['cpu']:.2f} s" for c, fs in (("prev", prev), ("new", new))
                          for w in (json.loads(Path(f).read_text()).get("warmup") for f in fs) if w),
              f"- median speed-up: over base {np.median(sp_b):.1f}x ({len(sp_b)} plants), over prev "
              f"{np.median(sp_p):.1f}x ({len(sp_p)} plants)",
              f"- plants more than 1e-3 (relative) worse than base: {len(worse_b)}"
              + (f" ({', '.join(worse_b)})" if worse_b else ""),
              f"- plants more than 1e-3 (relative) worse than prev: {len(worse_p)}"
              + (f" ({', '.join(worse_p)})" if worse_p else ""), ""]
    if notes:
        lines += [Path(notes).read_text()]
    Path(out).write_text("\n".join(lines) + "\n")


def _check_import(code: str) -> None:
    """The process imports the code it is to measure (a checkout under ``DIRS[code]``, or this one)."""
    import optdesign

    expected = DIRS[code][1] if code in DIRS else str(Path(__file__).resolve().parents[1])
    if not str(Path(optdesign.__file__).resolve()).startswith(expected):
        raise SystemExit(f"imported {optdesign.__file__}, expected a checkout under {expected}")


def main() -> None:
    ap = argparse.ArgumentParser()
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("run")
    r.add_argument("code", choices=("new", "base", "prev"))
    r.add_argument("--set", default="subset", choices=("subset", "full", "large"))
    r.add_argument("--objective", default="kappa2", choices=("kappa2", "eta"))
    r.add_argument("--only", default=None)
    r.add_argument("--json", required=True)
    r.add_argument("--route", default=None, help="WellConditionedProblem(route=...) (new code only; "
                   "default: the verb's default)")
    r.add_argument("--inner", action="store_true", help=argparse.SUPPRESS)
    q = sub.add_parser("pair")
    q.add_argument("code", choices=tuple(DIRS))
    q.add_argument("--set", default="subset", choices=("subset", "full", "large"))
    q.add_argument("--objective", default="kappa2", choices=("kappa2", "eta"))
    q.add_argument("--only", default=None)
    q.add_argument("--json", nargs=2, required=True, metavar=("OLD", "NEW"))
    w = sub.add_parser("serve", help=argparse.SUPPRESS)
    w.add_argument("code", choices=("new", *DIRS))
    w.add_argument("--set", default="subset", choices=("subset", "full", "large"))
    w.add_argument("--objective", default="kappa2", choices=("kappa2", "eta"))
    p = sub.add_parser("report")
    p.add_argument("--base", nargs="+", required=True, help="run files of the base code (later ones win)")
    p.add_argument("--prev", nargs="+", required=True)
    p.add_argument("--new", nargs="+", required=True)
    p.add_argument("--notes", default="", help="a Markdown file appended to the report")
    p.add_argument("--out", default="benchmarks/results/region.md")
    a = ap.parse_args()
    if a.cmd == "report":
        report(a.base, a.prev, a.new, a.out, a.notes)
        return
    if a.cmd == "pair":
        pair(a.code, a.set, a.objective, tuple(a.json), a.only)
        return
    if a.cmd == "serve":
        _check_import(a.code)
        serve(a.set, a.objective)
        return
    if a.code in DIRS and not a.inner:
        root = DIRS[a.code][1]
        env = {**os.environ, "PYTHONPATH": root}
        args = [sys.executable, __file__, "run", a.code, "--set", a.set, "--objective", a.objective,
                "--json", a.json, "--inner"] + (["--only", a.only] if a.only else [])
        subprocess.run(args, env=env, check=True)
        return
    _check_import(a.code)
    route = None if a.code in DIRS else a.route
    run(a.set, a.objective, a.json, a.only, None if route == "default" else route, a.code)


if __name__ == "__main__":
    main()
