"""Seed 002 (S. J. Lee): robustness of Kalman filters, with and without a delay in the output.

Run:  python examples/seed002_kalman_robustness.py

1. The return difference of a filter, loop broken at the filter input (the innovation).
2. The circle condition T R T* >= R: every Kalman filter passes, a hand-placed gain fails at a
   frequency the adaptive search finds, with a destabilizing perturbation as certificate.
3. Guaranteed and actual margins; what holds simultaneously and what does not.
4. Discrete time: the inequality is T V T* >= R with V = C P C' + R (not T R T* >= R).
5. The delayed-output filter of the paper: p0 by Pade approximation and by sampling, the return
   difference (16) with the true delay, the circle condition (17).
6. The paper's results table and figures, written to the build folder (``examples/_build/``, or
   ``$OPTDESIGN_EXAMPLES_OUT``).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from optdesign import (
    Plant,
    circle_condition,
    filter_margins,
    kalman,
    output_delay_kalman,
    problems,
    return_difference,
)
from optdesign.classical.placement import place_observer
from optdesign.studies import paper002

np.set_printoptions(precision=4, suppress=True)

# --------------------------------------------------------------------------- 1. return difference
# a lightly damped oscillator measured in position and velocity
plant = Plant([[0.0, 1.0], [-4.0, -0.2]], np.eye(2), Q=np.diag([0.1, 1.0]), R=np.diag([0.5, 2.0]))
kf = kalman(plant)
T = return_difference(plant, kf.L, [0.0, 2.0, 10.0])  # T(jw) = I + C (jwI - A)^-1 L, shape (3, 2, 2)
print("Kalman gain L =\n", kf.L)
print("sigma_min(T(jw)) at w = 0, 2, 10:", np.linalg.svd(T, compute_uv=False)[:, -1])

# --------------------------------------------------------------------------- 2. circle condition
res = circle_condition(plant, kf.L)  # adaptive: pole-seeded grid + local refinement
print("\nKalman gain:", res.summary())

L_bad = place_observer(plant, [-0.05 + 2j, -0.05 - 2j])  # stabilizing, lightly damped, not optimal
bad = circle_condition(plant, L_bad)
print("placed gain:", bad.summary())
Delta = bad.perturbation  # the smallest perturbation that puts a filter pole at j*omega_worst
poles = np.linalg.eigvals(plant.A - L_bad @ Delta @ plant.C)
print(f"  certificate: A - L Delta C has a pole at {poles[np.argmin(abs(poles.real))]:.4f} "
      f"(j omega_worst = {bad.omega_worst:.4f}j)")

# --------------------------------------------------------------------------- 3. margins
fm = filter_margins(plant, kf.L)
print("\n" + fm.summary())
phases = np.diag(np.exp([1j * np.radians(59), -1j * np.radians(59)]))
for D, what in [(np.diag([0.51, 1000.0]), "gains 0.51 and 1000 in the two channels at once"),
                (phases, "phases +59 and -59 deg at once")]:
    ok = np.max(np.linalg.eigvals(plant.A - kf.L @ D @ plant.C).real) < 0
    print(f"  {what}: {'stable' if ok else 'UNSTABLE'} (guaranteed: diagonal R, Re(delta_i) > 1/2)")
one = Plant([[1.0]], [[1.0]], Q=[[0.01]], R=[[1.0]])   # gain AND phase in the same channel: not covered
L1 = kalman(one).L
for d in (0.51, np.exp(1j * np.radians(59)), 0.51 * np.exp(1j * np.radians(59))):
    re = float(np.max(np.linalg.eigvals(one.A - d * L1 @ one.C).real))
    print(f"  scalar unstable plant, delta = {d:.3f}: max Re = {re:+.4f}")

# --------------------------------------------------------------------------- 4. discrete time
dplant = Plant([[0.5]], [[1.0]], Q=[[1.0]], R=[[1.0]], dt=1.0)
dkf = kalman(dplant)
print("\ndiscrete predictor:", circle_condition(dplant, dkf.L).summary())
print("  with V = R instead:", circle_condition(dplant, dkf.L, V=dplant.R).summary())

# --------------------------------------------------------------------------- 5. output delay
d = problems.load("lee_output_delay_scalar").data  # x' = 0.5 x + w, y = x + 0.5 x(t-1) + v
for method in ("pade", "sample"):
    f = output_delay_kalman(d["A"], d["C0"], d["C1"], d["h"], d["Q"], d["R"], method=method)
    print(f"\n{f.summary()}")
    print("  K(theta) at theta = 0, -h/2, -h:", f.K_theta[[0, (len(f.theta) - 1) // 2, -1], 0, 0])
    print("  circle condition (17), true delay:", f.circle_condition().summary())

# --------------------------------------------------------------------------- 6. the paper
outdir = Path(os.environ.get("OPTDESIGN_EXAMPLES_OUT") or Path(__file__).resolve().parent / "_build")
rep = paper002.reproduce(outdir, overwrite=True)
print("\n" + rep.table())
print("figures:", *rep.figures, sep="\n  ")
