"""A constraint study through the Python API: the best kappa2 over decay rate and damping sector.

Run:  python examples/study_alpha_sector.py [--dask]

The same study as ``examples/study_alpha_sector.toml`` (``optdesign study`` runs that file):

1. a :class:`~optdesign.studies.RegionSweepDesigner` for COMPleib HE1 -- its CasADi problem is built
   once per worker process, with the decay rate ``alpha`` and the damping ratio ``zeta`` as
   ``opti.parameter`` s, and re-solved for every point (warm-started from the previous one, plus
   placement starts); every point is verified independently (poles with numpy, region distance,
   kappa2);
2. the sweep on a local process pool, the table (CSV) and the figures;
3. with ``--dask``: the same sweep on a 2-worker Dask LocalCluster -- identical results;
4. the spec file run through :func:`~optdesign.studies.run_spec` gives the same table.

Figures and tables go to ``study_alpha_sector/`` in the build folder (``examples/_build/``, or
``$OPTDESIGN_EXAMPLES_OUT``).
"""

from __future__ import annotations

import logging
import os
import sys
from pathlib import Path

import numpy as np

from optdesign.studies import RegionSweepDesigner, grid, load_spec, plot_table, run_spec, sweep

HERE = Path(__file__).resolve().parent
OUT = Path(os.environ.get("OPTDESIGN_EXAMPLES_OUT") or HERE / "_build") / "study_alpha_sector"


def main(use_dask: bool = False) -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    # ------------------------------------------------------------------ 1. the design function
    designer = RegionSweepDesigner(problem="compleib_he1", objective="kappa2", radius=10.0, starts=2)
    points = grid(alpha=[0.25, 0.5, 0.75, 1.0], zeta=[0.8, 0.6, 0.4, 0.2])  # zeta: tight -> loose

    # ------------------------------------------------------------------ 2. local process pool
    table = sweep(designer, points, chunksize=4)  # one chunk per alpha: warm starts run along zeta
    print(table.summary())
    print(f"{'alpha':>6} {'zeta':>5} {'status':>16} {'kappa2':>9} {'eta':>9} {'||L||':>8} {'time':>6}")
    for r in table:
        print(f"{r['alpha']:6.2f} {r['zeta']:5.2f} {r['status']:>16} {r['kappa2']:9.4g} {r['eta']:9.4g} "
              f"{r['gain_norm']:8.4g} {r['time']:6.2f}" + ("" if r["success"] else "   (not verified)"))
    table.to_csv(OUT / "api_alpha_sector.csv", overwrite=True)  # regenerates its own file
    # what the sweep says: a faster decay (larger alpha) or a narrower sector (larger zeta) costs
    # conditioning; the table shows by how much for this plant
    ok = np.array([r["success"] for r in table])
    k2 = table.column("kappa2")
    print(f"kappa2 over the verified points: {np.min(k2[ok]):.3g} .. {np.max(k2[ok]):.3g}")

    spec = load_spec(HERE / "study_alpha_sector.toml")
    for fig in spec.figures:
        print("figure:", plot_table(table, fig, OUT / f"api_{fig.file}", title=spec.title))

    # ------------------------------------------------------------------ 3. Dask (optional)
    if use_dask:
        from distributed import Client, LocalCluster

        with LocalCluster(n_workers=2, threads_per_worker=1, dashboard_address=":0",
                          silence_logs=logging.ERROR) as cluster, Client(cluster) as client:
            on_dask = sweep(designer, points, executor=client, chunksize=4)
        diff = on_dask.diff(table)
        print(f"Dask LocalCluster: {on_dask.summary()}; differences from the local pool: {len(diff)}")

    # ------------------------------------------------------------------ 4. the spec file
    res = run_spec(spec, output=OUT / "from_spec", overwrite=True)
    print(f"spec: {res.table.summary()}; differences from the API sweep: {len(res.table.diff(table))}")


if __name__ == "__main__":  # the guard is needed: the process pool imports this module
    main(use_dask="--dask" in sys.argv[1:])
