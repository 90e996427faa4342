"""Well-conditioned state feedback, compared with scipy and python-control.

The benchmark: Kautsky, Nichols & Van Dooren 1985, Example 1 (a chemical reactor, 4 states,
2 inputs), closed-loop poles -0.2, -0.5, -5.0566, -8.6659.  Every method places the same poles;
they differ in how sensitive those poles are to errors in A.  The script compares

* scipy ``place_poles`` (YT and KNV0), python-control ``place`` and ``place_varga`` (slycot);
* ``optdesign.place`` (the drop-in: same call, same result fields) -- kappa2 minimized;
* ``optdesign.lqr_for_poles`` -- an LQR gain (a state weight Q >= 0) with the same poles, when one
  exists, with its guaranteed margins;

by kappa2 of the closed-loop eigenvectors (right, scipy's ``cond(X)``, what optdesign minimizes
for state feedback since 0.2.0 -- with fixed poles and with poles free in a region -- and left, the
measure of the dual observer, shown for comparison), ``||K||``, the CPU time, and how far the
closed-loop poles move when A is perturbed by random relative errors of 1e-2 (500 samples; figure
``feedback_knv1985_ex1.png`` in the build folder, ``examples/_build/`` or ``$OPTDESIGN_EXAMPLES_OUT``).

Run (headless)::

    python examples/feedback_well_conditioned.py
"""

from __future__ import annotations

import os
import time
from pathlib import Path

import control
import numpy as np
import scipy.signal
from matplotlib.ticker import NullFormatter
from scipy.optimize import linear_sum_assignment

from optdesign import problems
from optdesign.analysis.metrics import kappa2
from optdesign.design.feedback import place
from optdesign.studies.reproduce import output_dir, pyplot, save_figure

FIGURES = Path(os.environ.get("OPTDESIGN_EXAMPLES_OUT") or Path(__file__).resolve().parent / "_build")
REL, SAMPLES = 1e-2, 500     # relative size and number of the random perturbations of A


def _timed(fn):
    t0 = time.process_time()
    out = fn()
    return out, time.process_time() - t0


def _pole_shifts(A: np.ndarray, B: np.ndarray, K: np.ndarray, poles: np.ndarray, rel: float,
                 samples: int, seed: int) -> np.ndarray:
    """Largest distance of the closed-loop poles of (A + E) - B K to the requested poles (matched
    one to one), for random E with ||E||_F = rel ||A||_F; one value per sample."""
    rng = np.random.default_rng(seed)
    target = np.asarray(poles, dtype=complex)
    out = []
    for _ in range(samples):
        E = rng.standard_normal(A.shape)
        E *= rel * np.linalg.norm(A) / np.linalg.norm(E)
        got = np.linalg.eigvals(A + E - B @ K)
        dist = np.abs(got[:, None] - target[None, :])
        rows, cols = linear_sum_assignment(dist)
        out.append(float(np.max(dist[rows, cols])))
    return np.array(out)


def main() -> None:
    prob = problems.load("pp_knv1985_ex1")
    A, B, poles = np.array(prob.data["A"]), np.array(prob.data["B"]), prob.targets["poles"]

    rows = {}
    yt, t_yt = _timed(lambda: scipy.signal.place_poles(A, B, poles, method="YT"))
    rows["scipy place_poles YT"] = (yt.gain_matrix, t_yt)
    knv, t_knv = _timed(lambda: scipy.signal.place_poles(A, B, poles, method="KNV0"))
    rows["scipy place_poles KNV0"] = (knv.gain_matrix, t_knv)
    Kc, t_c = _timed(lambda: control.place(A, B, poles))
    rows["python-control place"] = (Kc, t_c)
    Kv, t_v = _timed(lambda: control.place_varga(A, B, poles))
    rows["python-control place_varga"] = (Kv, t_v)
    ours, t_ours = _timed(lambda: place(A, B, poles))     # the drop-in: same call as place_poles
    rows["optdesign place"] = (ours.gain_matrix, t_ours)
    print(f"optdesign.place: {ours}")
    print("  " + ours.verification.summary().replace("\n", "\n  "))

    print(f"\n{'method':30s} {'kappa2 (right, cond X)':>23s} {'kappa2 (left)':>14s} {'||K||_2':>9s} "
          f"{'pole shift':>15s} {'CPU s':>8s} {'CPU / YT':>9s}")
    print(f"{'':30s} {'':>23s} {'':>14s} {'':>9s} {'(median)':>15s}")
    spreads = {}
    for name, (K, t) in rows.items():
        F = A - B @ K
        shifts = _pole_shifts(A, B, K, poles, REL, SAMPLES, seed=1)
        spreads[name] = shifts
        print(f"{name:30s} {kappa2(F):23.4f} {kappa2(F.T):14.4f} {np.linalg.norm(K, 2):9.3f} "
              f"{np.median(shifts):15.3e} {t:8.4f} {t / t_yt:9.1f}")

    # the inverse LQR: is there a Q >= 0 whose LQR loop has these poles?  (m = 2 inputs: local
    # search, a Q with the answer's certificate, or 'not found' -- never a false 'infeasible')
    from optdesign import Plant
    from optdesign.design.feedback import lqr_for_poles

    lqr = lqr_for_poles(Plant(A, np.eye(4), B=B), poles)
    print(f"\ninverse LQR: {lqr.status.value} (success {lqr.success}); {lqr.message[:160]}")
    if lqr.success:
        F = A - B @ lqr.K
        print(f"  LQR gain with these poles: kappa2 {kappa2(F):.4f}, ||K|| {np.linalg.norm(lqr.K, 2):.3f}, "
              f"trace(Q) {np.trace(lqr.Q):.4g}")

    plt = pyplot()
    fig, (ax0, ax1) = plt.subplots(1, 2, figsize=(11, 4))
    names = list(rows)
    values = [kappa2(A - B @ rows[k][0]) for k in names]
    ax0.barh(names, values, color="tab:blue")
    for y, v in enumerate(values):
        ax0.text(v, y, f" {v:.3g}", va="center", fontsize=9)
    ax0.set_xlabel(r"$\kappa_2$ of the closed-loop eigenvectors ($\mathrm{cond}\,X$, log scale)")
    ax0.set_xscale("log")
    ax0.set_xlim(1.0, 3.0 * max(values))
    ax0.xaxis.set_minor_formatter(NullFormatter())
    ax0.grid(True, axis="x", alpha=0.3)
    for name in names:
        d = np.sort(spreads[name])
        ax1.step(d, np.arange(1, d.size + 1) / d.size, where="post", label=name)
    ax1.set_xscale("log")
    ax1.set_xlabel(f"largest closed-loop pole shift, $\\|E\\| = {REL:g}\\,\\|A\\|$ ({SAMPLES} random $E$)")
    ax1.set_ylabel("fraction of perturbations")
    ax1.grid(True, alpha=0.3)
    ax1.legend(fontsize=8, loc="lower right")
    fig.suptitle("KNV 1985 Ex. 1: the same poles, placed by five methods")
    path = save_figure(fig, output_dir(FIGURES) / "feedback_knv1985_ex1.png", overwrite=True)
    print("\nfigure:", path)


if __name__ == "__main__":
    main()
