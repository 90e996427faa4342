"""eta in a region sweep: the designer's placement-engine route against IPOPT's (issue 28, round 12).

Run:  python benchmarks/bench_sweep_eta.py [--out benchmarks/results/sweep_eta.md]

Per plant, one chunk of ``RegionSweepDesigner(plant=..., objective="eta", zeta=0.5, radius=R)`` over
``alpha = 0.5, 0.6, 0.7, 0.8`` (the warm starts carried along the chunk), with the designer's default
route for eta (``"auto"``: the placement engine from every start and warm start, IPOPT's first start
beside it up to n = 10) and with ``route="nlp"`` (IPOPT, the default before round 12).  ``R`` is
``max(5, 2 rho(A))``.  Plants: random observable plants n = 4..12 (``_common.random_observable_plant``,
seed ``1000 n + k``, ``p = max(1, n // 3)``, 2 up to n = 5) and six continuous COMPleib plants.  CPU is
``time.process_time`` per point, single-threaded BLAS (``_common``), each route in its own pass after
one untimed point.  Numbers, not pass/fail; time it alone (``flock /tmp/bench.lock``).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import _common  # noqa: F401  (single-threaded BLAS before numpy)
import numpy as np
from _common import random_observable_plant

ALPHAS = (0.5, 0.6, 0.7, 0.8)
RANDOM = ((4, 0), (5, 0), (6, 0), (7, 1), (8, 1), (10, 0), (12, 0))
COMPLEIB = ("compleib_dis1", "compleib_dis3", "compleib_rea2", "compleib_he3", "compleib_ac6", "compleib_psm")


def plants():
    from optdesign import problems

    for n, k in RANDOM:
        p = max(1, n // 3) if n > 5 else 2
        yield f"random_n{n}_p{p}_s{k}", random_observable_plant(np.random.default_rng(1000 * n + k), n, p)
    for name in COMPLEIB:
        yield name, problems.load(name).plant


def chunk(plant, route: str | None) -> tuple[list[float], list[float]]:
    from optdesign.studies import RegionSweepDesigner

    radius = max(5.0, 2 * float(np.max(np.abs(np.linalg.eigvals(plant.A)))))
    session = RegionSweepDesigner(plant=plant, objective="eta", zeta=0.5, radius=radius,
                                  route=route).start_chunk()
    vals, cpus = [], []
    for a in ALPHAS:
        c0 = time.process_time()
        d = session(alpha=a)
        cpus.append(time.process_time() - c0)
        vals.append(float(d.eta) if d.success else float("nan"))
    return vals, cpus


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default="benchmarks/results/sweep_eta.md")
    a = ap.parse_args()
    cases = list(plants())
    runs: dict[str, dict[str, tuple[list[float], list[float]]]] = {}
    for label, route in (("nlp", "nlp"), ("engine (default)", None)):
        chunk(cases[0][1], route)  # untimed: the process's one-time imports
        runs[label] = {name: chunk(plant, route) for name, plant in cases}
        print(label, "done", flush=True)
    lines = ["# eta in a region sweep: the placement engine against IPOPT (`bench_sweep_eta.py`)", "",
             "One chunk per plant, alpha = " + ", ".join(map(str, ALPHAS)) + ", zeta = 0.5; eta per point "
             "(lower is better) and the chunk's CPU.", "",
             "| plant | IPOPT (`route=\"nlp\"`) eta | CPU | **engine (default)** eta | CPU | ratio |",
             "|---|---|---|---|---|---|"]
    for name, _ in cases:
        (v0, c0), (v1, c1) = runs["nlp"][name], runs["engine (default)"][name]
        lines.append(f"| {name} | {' / '.join(f'{v:.4g}' for v in v0)} | {sum(c0):.2f} s | "
                     f"{' / '.join(f'{v:.4g}' for v in v1)} | {sum(c1):.2f} s | {sum(c1) / sum(c0):.2f}x |")
    worse = [(name, i) for name, _ in cases for i in range(len(ALPHAS))
             if runs["engine (default)"][name][0][i] > runs["nlp"][name][0][i] * (1 + 1e-3)]
    better = [(name, i) for name, _ in cases for i in range(len(ALPHAS))
              if runs["engine (default)"][name][0][i] < runs["nlp"][name][0][i] * (1 - 1e-3)]
    total = [sum(sum(runs[k][name][1]) for name, _ in cases) for k in runs]
    where = ", ".join(f"{n} alpha {ALPHAS[i]}" for n, i in worse) or "none"
    count = len(cases) * len(ALPHAS)
    lines += ["", f"- points more than 1e-3 lower with the engine: {len(better)} of {count}; "
              f"higher: {len(worse)} ({where})",
              f"- CPU in all: {total[1]:.1f} s against {total[0]:.1f} s ({total[1] / total[0]:.2f}x)"]
    Path(a.out).write_text("\n".join(lines) + "\n")
    Path(a.out).with_suffix(".json").write_text(json.dumps(runs, indent=1))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
