"""Seed 001 (Jung & Huh): well-conditioned observers and Kalman filters with optdesign.

Run (headless; figures go to the build folder ``examples/_build/``, or ``$OPTDESIGN_EXAMPLES_OUT``)::

    python examples/seed001_well_conditioned.py
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from optdesign import Plant, problems, well_conditioned_kalman, well_conditioned_observer
from optdesign.classical import kalman_2x2_eta_set, observer_2x2_gain_region
from optdesign.classical.placement import place_observer
from optdesign.metrics import kappa2
from optdesign.regions import Disk, HalfPlane, Sector
from optdesign.studies import paper001


def main() -> None:
    np.set_printoptions(precision=4, suppress=True)

    # 1. Fixed poles: the job of scipy's place_poles, but minimizing kappa2 itself.
    pp = problems.load("pp_knv1985_ex2")  # KNV 1985 Ex. 2 in observer form (A', B')
    plant, poles = pp.plant, pp.targets["poles"]
    design = well_conditioned_observer(plant, poles=poles, starts=4, seed=0)
    yt = kappa2(plant.A - place_observer(plant, poles) @ plant.C)
    print("fixed poles:", design)
    print(f"  kappa2 {design.kappa2:.4f} vs scipy YT {yt:.4f}; verification:")
    print("  " + design.verification.summary().replace("\n", "\n  "))

    # 2. Poles free in a region, with a structural zero in L and a bound on ||L||.
    ac17 = problems.load("compleib_ac17").plant
    region = HalfPlane(0.5) & Sector.from_damping(0.5) & Disk(0.0, 6.0)
    mask = np.ones((ac17.n, ac17.p), dtype=bool)
    mask[0, 1] = False  # the first state is not corrected by the second output
    d2 = well_conditioned_observer(ac17, region=region, gain_mask=mask, max_gain=20.0, starts=3)
    print("\nregion design (COMPleib AC17):", d2)
    print("  poles", d2.poles, " L[0, 1] =", d2.L[0, 1])
    for s in d2.starts:
        print(f"  start {s.index} ({s.origin}): {s.status}, verified {s.verified}, kappa2 {s.kappa2:.4g}")

    # 3. Trade-off: minimize eta subject to kappa2 <= bound.
    d3 = well_conditioned_observer(
        plant, poles=poles, objective="eta", kappa2_max=1.2 * design.kappa2, starts=2
    )
    print(f"\neta-optimal with kappa2 <= {1.2 * design.kappa2:.3f}: eta {d3.eta:.3f}, kappa2 {d3.kappa2:.3f}")

    # 4. A true Kalman filter that is well conditioned (Riccati equation as a constraint).
    ex2 = problems.load("jung_huh_ex2")
    kf = well_conditioned_kalman(ex2.plant, objective="eta", starts=3)
    print(
        f"\nwell-conditioned Kalman filter (seed 001 Ex. 2): q/r = {kf.Q[0, 0]:.4g}, eta {kf.eta:.4f}, "
        f"kappa2 {kf.kappa2:.4f}, Riccati residual {kf.verification['riccati_residual'].value:.1e}"
    )

    # 5. Seed 001's closed forms.
    print(
        "\nExample 1, stable gains with eta <= 2 at l1 = 10: l2 in",
        observer_2x2_gain_region(2.0, -1.0, 2.0, 10.0),
    )
    print("Example 2, q/r with eta <= 2:", kalman_2x2_eta_set(2.0, -1.0, 2.0))
    tiny = Plant([[0, 1], [2, -1]], [[1, 0]])
    print(
        "Example 1 gain L = [10, 5]: kappa2 =", round(kappa2(tiny.A - np.array([[10.0], [5.0]]) @ tiny.C), 4)
    )

    # 6. Reproduce the paper: figures and the printed-vs-reproduced table.
    out = Path(os.environ.get("OPTDESIGN_EXAMPLES_OUT") or Path(__file__).resolve().parent / "_build")
    rep = paper001.reproduce(out, overwrite=True)
    print("\n" + rep.table())
    print("figures:", *[str(f) for f in rep.figures], sep="\n  ")


if __name__ == "__main__":
    main()
