"""Seed 004 (Ahn et al.): the time-varying Kalman gain from the Riccati differential equation.

Run:  python examples/seed004_riccati_de.py

1. The paper's example (damped harmonic oscillator, P0 = 0, 0..10 s): the gain K(t) = P(t) C' R^-1 by
   the exact Hamiltonian transition matrix, by the paper's block-pulse recursion (m = 50 blocks), and
   by an ODE solver -- with each method's error, and the approach to the steady-state (ARE) gain.
2. What the block-pulse recursion is: Crank-Nicolson, block-averaged; second order at the block
   midpoints, first order as a staircase.
3. Long horizons and unstable plants: CAREX 1.2 in filter form (eigenvalue +1) on 0..1000 s.
4. Discrete time: the same oscillator sampled at 0.1 s -- the time-varying predictor gain L_k.
5. The paper's table (printed vs reproduced) and the figures, written to the build folder
   (``examples/_build/``, or ``$OPTDESIGN_EXAMPLES_OUT``).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import scipy.linalg

from optdesign import Plant, problems, riccati_de
from optdesign.classical.bpf import filter_hamiltonian
from optdesign.studies import paper004

np.set_printoptions(precision=5, suppress=True)

# --------------------------------------------------------------- 1. the paper's example
prob = problems.load("ahn_bpf_harmonic_oscillator")
plant = prob.plant                                 # A = [[0, 1], [-0.64, -0.32]], C = [0, 1], G = [0, 1]'
P0 = np.zeros((2, 2))
exact = riccati_de(plant, P0, 10.0, steps=50, estimate_error=True, steady_state=True)  # "transition"
bpf = riccati_de(plant, P0, 10.0, method="bpf", steps=50)       # the paper: m = 50 blocks
ode = riccati_de(plant, P0, 10.0, method="ode", steps=50)       # scipy solve_ivp reference
for tr in (exact, bpf, ode):
    print(f"{tr.method:10s} error {tr.error_estimate:.1e} ({tr.error_kind})\n"
          f"{'':10s} {tr.scheme}\n{'':10s} success {tr.success}, {tr.solver_stats.time * 1e3:.1f} ms")
print("\n  t      K(t) exact            K(t) BPF (block midpoint)")
for k in (0, 5, 10, 20, 49):
    t = bpf.t[k]
    K = riccati_de(plant, P0, 10.0, t_eval=[t]).L[0]
    print(f"{t:5.1f}   {K.ravel()}   {bpf.L[k].ravel()}")
print(f"\nsteady-state gain (ARE): {exact.L_steady.ravel()};  K(10) = {exact.L_final.ravel()};  "
      f"||P(10) - P_ss|| / ||P_ss|| = {exact.steady_distance:.1e}")
print(f"the paper's V U^-1 is not symmetric: antisymmetric part {bpf.asymmetry:.1e} (removed)\n")

# --------------------------------------------------------------- 2. order of the recursion
M = filter_hamiltonian(plant.A, plant.C, plant.process_noise(), plant.R)
conv = paper004.convergence(M, P0, 10.0)
print("   m   midpoints   staircase")
for m, e1, e2 in zip(conv["m"], conv["midpoint"], conv["piecewise"], strict=True):
    print(f"{int(m):4d}   {e1:.2e}    {e2:.2e}")
print("observed order:", conv["order_midpoint"], "(midpoints),", conv["order_piecewise"], "(staircase)\n")

# --------------------------------------------------------------- 3. long horizon, unstable plant
carex = problems.load("carex_1.2").plant                        # filter form of CAREX 1.2: eig(A) = 1, -0.5
t = np.linspace(0.0, 1000.0, 201)
fast = riccati_de(carex, np.eye(2), 1000.0, t_eval=t, steady_state=True)
ref = riccati_de(carex, np.eye(2), 1000.0, method="ode", t_eval=t)
diff = np.max(np.linalg.norm(fast.P - ref.P, axis=(1, 2))) / np.max(np.linalg.norm(ref.P, axis=(1, 2)))
print(f"CAREX 1.2, 0..1000 s: transition {fast.solver_stats.time * 1e3:.1f} ms, ODE "
      f"{ref.solver_stats.time * 1e3:.1f} ms ({ref.solver_stats.extra['integrator']}), "
      f"relative difference {diff:.1e}, distance to the ARE solution {fast.steady_distance:.1e}\n")

# --------------------------------------------------------------- 4. discrete time
dt = 0.1
Ad = scipy.linalg.expm(plant.A * dt)
# first-order sampling of the noise: Q_d ~ G Q G' dt (G scaled by sqrt(dt))
dplant = Plant(Ad, plant.C, G=plant.G * np.sqrt(dt), Q=plant.Q, R=plant.R, dt=dt, name="oscillator, dt = 0.1")
dtr = riccati_de(dplant, P0, 30.0, steady_state=True)           # t = k dt, k = 0..300
print(f"discrete: L_0 = {dtr.L[0].ravel()}, L_10 = {dtr.L[10].ravel()}, L_300 = {dtr.L_final.ravel()}, "
      f"steady L = {dtr.L_steady.ravel()} (distance {dtr.steady_distance:.1e})\n")

# --------------------------------------------------------------- 5. printed vs reproduced, figures
outdir = Path(os.environ.get("OPTDESIGN_EXAMPLES_OUT") or Path(__file__).resolve().parent / "_build")
repro = paper004.reproduce(outdir, overwrite=True)
print(repro.table())
print("figures:", *[str(p) for p in repro.figures], sep="\n  ")
