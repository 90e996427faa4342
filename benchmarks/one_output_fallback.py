"""Random one-output plants with weakly observable unstable modes: which region designs reach IPOPT's
fallback, and does it ever verify a design there?
(issue 28, round 17: ``design/well_conditioned/one_output.py``)

    python benchmarks/one_output_fallback.py [--seed 7] [--count 80] [--objective kappa2] [--json F]

Plant ``t``: n = 4..9, ``A`` with eigenvalues uniform in [-0.5, 0.7] (a random similarity) or
``N(0, 1/n) + shift I``, ``C`` (1, n) with entries scaled by ``10^-u``, u uniform up to 1, 2, 3, 4 in turn;
``suggested_region``; the default verb, ``time_limit=150``.  For every design whose route skipped IPOPT's
fallback (the one-output check), ``route="nlp"`` (IPOPT from every start) is run as well: does it verify?
Round 17 (the previous code, seed 7, 80 plants, and seed 11, 29): 10 of 109 designs reached the fallback, none
verified (46-129 s each); the check skips it on 1 (112.9 s -> 1.7 s, back to back).  Hours of CPU
at the default count.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import _common  # noqa: F401  (single-threaded BLAS before numpy)
import numpy as np

from optdesign import Plant, well_conditioned_observer
from optdesign.design.well_conditioned import suggested_region
from optdesign.design.well_conditioned.problem import WellConditionedProblem
from optdesign.errors import ValidationError


def plants(seed: int, count: int):
    """``(t, plant)`` for the plants of the module docstring (a skipped plant draws as the others)."""
    rng = np.random.default_rng(seed)
    for t in range(count):
        n = int(rng.integers(4, 10))
        k = (1, 2, 3, 4)[t % 4]
        ev = rng.uniform(-0.5, 0.7, n)
        S = rng.standard_normal((n, n))
        if rng.random() < 0.5:
            A = S @ np.diag(ev) @ np.linalg.inv(S)
        else:
            A = rng.standard_normal((n, n)) / np.sqrt(n) + rng.uniform(-0.3, 0.6) * np.eye(n)
        C = rng.standard_normal((1, n)) * (10.0 ** -rng.uniform(0, k, n))
        yield t, Plant(A, C)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--count", type=int, default=80)
    ap.add_argument("--objective", default="kappa2", choices=("kappa2", "eta"))
    ap.add_argument("--json", default=None)
    a = ap.parse_args()
    rows = []
    for t, plant in plants(a.seed, a.count):
        try:
            region = suggested_region(plant)
        except ValidationError:  # an unobservable unstable mode: no stable observer
            continue
        c0 = time.process_time()
        d = well_conditioned_observer(plant, region=region, objective=a.objective, time_limit=150)
        row = {"t": t, "n": plant.n, "status": d.status.value, "verified": bool(d.verification.passed),
               "cpu": time.process_time() - c0,
               "route": str(d.route), "fallback_ran": any(s.kind == "fallback" and s.outcome != "skipped"
                                                          for s in d.route),
               "fallback_skipped": any(s.kind == "fallback" and s.outcome == "skipped" for s in d.route)}
        if row["fallback_skipped"]:
            c0 = time.process_time()
            nlp = WellConditionedProblem(plant, objective=a.objective, route="nlp").solve(region=region,
                                                                                           time_limit=150)
            row.update(nlp_status=nlp.status.value, nlp_verified=bool(nlp.verification.passed),
                       nlp_cpu=time.process_time() - c0)
        rows.append(row)
        print(json.dumps(row), flush=True)
    fell = [r for r in rows if r["fallback_ran"] or r["fallback_skipped"]]
    print(f"{len(fell)} of {len(rows)} designs reached the fallback; verified after it ran: "
          f"{sum(r['verified'] for r in fell if r['fallback_ran'])}; skipped by the one-output check: "
          f"{sum(r['fallback_skipped'] for r in fell)} (IPOPT alone verified "
          f"{sum(r.get('nlp_verified', False) for r in fell)} of them)")
    if a.json:
        Path(a.json).write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
