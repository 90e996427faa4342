"""Seed 000 (Chang & Lee 1984): which process noise Q >= 0 gives a Kalman filter with these poles?

Run:  python examples/seed000_inverse_kalman.py

1. Example 1 (A = [[0, 1], [-6, -5]], C = [1, 0], R = 1, poles -5, -8) by Solheim's sequential method:
   every step, and the paper's K = [8, -6], Q' = [[76, -42], [-42, 84]].
2. The same question as an SDP: L is fixed by the poles (one output), the Q that work form a family
   (P22 is free); each objective picks one member.  An independent Riccati solve checks each answer.
3. Example 2 (complex pair -1 +- j -> -8, -5, two outputs): the NLP (L is free) and the sequential
   method done correctly; the paper's printed numbers do not reproduce (see the table).
4. Is a given gain Kalman-optimal?  The return-difference certificate on the double integrator.
5. Structured noise (Q = G Qw G'), discrete time.
6. The paper's table of printed vs reproduced values and the figures, written to the build folder
   (``examples/_build/``, or ``$OPTDESIGN_EXAMPLES_OUT``).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from optdesign import Plant, is_kalman_optimal, kalman, kalman_for_poles, problems
from optdesign.classical import solheim
from optdesign.studies import paper000

np.set_printoptions(precision=4, suppress=True)

# --------------------------------------------------------------- 1. the sequential method
ex1 = problems.load("chang_lee_1984_ex1")
plant = Plant(ex1.plant.A, ex1.plant.C, R=ex1.plant.R)   # the noise is the unknown
seq = solheim(plant, [-5, -8])
for k, step in enumerate(seq.steps, start=1):
    print(f"step {k}: {step.moved[0].real:g} -> {step.placed[0].real:g}   q~ = {step.q_tilde[0, 0]:g}   "
          f"K_{k} = {step.K.ravel()}   Q'_{k} =\n{step.Q}")
print("K =", seq.L.ravel(), "  Q' =\n", seq.Q, "\n", seq.verification.summary(), "\n")

# --------------------------------------------------------------- 2. the SDP and its family
for objective in ("min_trace", "feasibility"):
    res = kalman_for_poles(plant, [-5, -8], objective=objective)
    print(f"{objective:12s} P22 = {res.P[1, 1]:8.4f}  Q = {res.Q.ravel()}  poles {res.poles}  "
          f"success {res.success}")
res = kalman_for_poles(plant, [-5, -8], objective="nearest", Q_nominal=seq.Q)
print(f"{'nearest':12s} to the paper's Q': P22 = {res.P[1, 1]:.4f}, Q = {res.Q.ravel()}")
check = kalman(plant.replace(Q=res.Q))               # an independent Kalman design with that Q
print("kalman() with that Q: L =", check.L.ravel(), " poles", check.poles, "\n")

# --------------------------------------------------------------- 3. Example 2 (two outputs)
ex2 = problems.load("chang_lee_1984_ex2")
nlp = kalman_for_poles(ex2.plant, ex2.targets["poles"])          # method "auto" -> "nlp"
seq2 = solheim(ex2.plant, ex2.targets["poles"])
print(nlp.summary())
print("sequential: steps", [s.kind for s in seq2.steps], " K =\n", seq2.L, "\n Q' =\n", seq2.Q)
printed = kalman(ex2.plant.replace(Q=ex2.references["Q_prime_printed"]))
print("the paper's printed Q' gives poles", printed.poles, "instead of -8, -5\n")

# --------------------------------------------------------------- 4. is this gain Kalman-optimal?
di = problems.load("double_integrator_poles_m0p2pm3j")
bad = kalman_for_poles(di.plant, di.targets["poles"])          # -0.2 +- 3j: out of reach
print(bad.status.value, "->", bad.certificate)
answer = is_kalman_optimal(di.plant, di.references["L_analytic"])
print(f"is_kalman_optimal(L = [0.4, 9.04]): {answer.optimal}; |T|^2 - 1 = {answer.min_eigenvalue:.4f} "
      f"at w = {answer.omega:.4f} rad/s\n")

# --------------------------------------------------------------- 5. structure and discrete time
dplant = Plant([[1.0, 0.1], [0.0, 1.0]], [[1.0, 0.0]], G=[[0.005], [0.1]], R=[[0.04]], dt=0.1)
target = kalman(dplant.replace(Q=[[3.0]])).poles                 # reachable with Q = G q G'
res = kalman_for_poles(dplant, target, q_structure="input")
print("discrete, Q = G Qw G':", res.Qw.ravel(), "(3 expected)", res.success)
res = kalman_for_poles(dplant, [0.5, 0.2], q_structure="input")
print("discrete target 0.5, 0.2 with noise through G:", res.status.value, "->", res.certificate, "\n")

# --------------------------------------------------------------- 6. printed vs reproduced, figures
outdir = Path(os.environ.get("OPTDESIGN_EXAMPLES_OUT") or Path(__file__).resolve().parent / "_build")
repro = paper000.reproduce(outdir, overwrite=True)
print(repro.table())
print("figures:", *[str(p) for p in repro.figures], sep="\n  ")
