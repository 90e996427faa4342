"""Seed 003 (Kim, Lee & Kim): generalized observers with an output-noise model, and what they really do.

Run:  python examples/seed003_generalized_observer.py

1. Noise models and their internal-model realization (N, M).
2. The paper's printed gains: is F = [[A - HC, -K], [MC, N]] Schur stable?
3. Designing generalized observers by pole placement (an ordinary observer for an augmented pair) and by
   the well-conditioned NLP.
4. What a stable generalized observer guarantees under output noise -- by simulation:
   eps = y - C xh -> 0, so C xh follows the NOISY output and x - xh does NOT go to zero.
5. The noise-rejecting observer (noise estimated as an output disturbance): xh -> x.
6. The paper's four figures and the side-by-side comparison, written to the build folder
   (``examples/_build/``, or ``$OPTDESIGN_EXAMPLES_OUT``).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from optdesign import (
      GeneralizedObserver,
      generalized_observer,
      noise_rejecting_observer,
      problems,
      simulate_observer,
)
from optdesign.design.generalized import default_poles
from optdesign.noise import Sinusoid, Step
from optdesign.regions import Disk
from optdesign.studies import paper003

np.set_printoptions(precision=4, suppress=True)

# --------------------------------------------------------------------------- 1. noise models
plant = problems.load("kim_lee_kim_step").plant  # A_D (3 x 3), C = [1 0 0], T = 0.01 s
step, sine = Step(), Sinusoid(1.0, dt=plant.dt)  # delta = const,  delta = a sin(2 pi t + phi)
print("step:     P(q) =", step.coefficients, " N =", step.N.tolist(), " M =", step.M.tolist())
print("sinusoid: P(q) =", sine.coefficients, " N =", sine.N.tolist(), " M =", sine.M.ravel().tolist())
print("step + sinusoid: order", (step + sine).order, "modes", (step + sine).modes)

# --------------------------------------------------------------------------- 2. printed gains
ref_step = problems.load("kim_lee_kim_step").references
ref_sine = problems.load("kim_lee_kim_sinusoid").references
printed_step = GeneralizedObserver.from_gains(plant, step, ref_step["H_printed"], ref_step["K_printed"])
printed_sine = GeneralizedObserver.from_gains(plant, sine, ref_sine["H_printed"], ref_sine["K_printed"])
print(f"\nprinted step gains:     spectral radius {printed_step.spectral_radius:.5f} (stable)")
print(f"printed sinusoid gains: spectral radius {printed_sine.spectral_radius:.5f} -> NOT stable "
      f"(success={printed_sine.success}); the printed gains or their OCR are wrong")

# --------------------------------------------------------------------------- 3. design
# n + r = 5 poles of F; default_poles is a Butterworth pattern mapped by z = exp(s dt) (the default of
# generalized_observer); any conjugate-closed set strictly inside the unit circle will do.
poles = default_poles(plant, sine)
obs = generalized_observer(plant, sine, poles=poles)
print("\npoles of F:", obs.poles)
print("designed (sinusoid):", obs.summary())
print("H =", obs.H.ravel(), "\nK =\n", obs.K)
print(obs.verification.summary())

# The same question as an NLP: minimize kappa2 of F's eigenvector matrix over H, K with the poles free in a
# disk (issue 4's well-conditioned observer on the structured pair F = A_s - L_s C_s).
wc = generalized_observer(plant, sine, method="well_conditioned", region=Disk(0.0, 0.97), starts=2)
print(f"well-conditioned: kappa2(F) {wc.kappa2:.3g} (placement above: {obs.kappa2:.3g}), "
      f"success={wc.success}")

# --------------------------------------------------------------------------- 4. what it guarantees
T = 1500
delta = 0.2 * sine.signal(T)  # seed 003: 0.2 sin(2 pi t)
sim = simulate_observer(obs, delta, x0=[1.0, 0.0, 0.0])
print("\ngeneralized observer, last quarter of the run:")
print(f"  max |eps| = max |C xh - y|  = {sim.tail('eps'):.2e}   (-> 0: xh reproduces the NOISY output)")
print(f"  max |C xh - C x - delta|     = {np.max(np.abs(sim.output_error - sim.delta)[-T // 4:]):.2e}")
print(f"  max |x - xh| per state       = {np.max(np.abs(sim.error[-T // 4:]), axis=0)}  (does not vanish)")
direct = generalized_observer(plant, sine, poles=poles, coupling="direct")
sd = simulate_observer(direct, delta, x0=[1.0, 0.0, 0.0])
print(f"  (coupling 'direct', K along C': max |x - xh| = {np.max(np.abs(sd.error[-T // 4:]), axis=0)})")

# --------------------------------------------------------------------------- 5. noise rejection
nr = noise_rejecting_observer(plant, sine, poles=poles)
sr = simulate_observer(nr, delta, x0=[1.0, 0.0, 0.0])
print("\nnoise-rejecting observer:", nr.summary())
print(f"  max |x - xh| = {sr.tail('error'):.2e}, max |delta - delta_hat| = "
      f"{np.max(np.abs(sr.noise_estimate - sr.delta)[-T // 4:]):.2e}")

# --------------------------------------------------------------------------- 6. the paper's figures
outdir = Path(os.environ.get("OPTDESIGN_EXAMPLES_OUT") or Path(__file__).resolve().parent / "_build")
rep = paper003.reproduce(outdir, overwrite=True)
print("\n" + rep.table())
print("\nfigures:", *[str(p) for p in rep.figures], sep="\n  ")
