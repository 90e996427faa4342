"""Noise covariances from data (issue 31): autocovariance least squares with ``estimate_noise``.

Run (headless; the figure goes to a build folder, not to the source tree)::

    python examples/estimate_noise.py [--out DIR] [--quick]

1. The ALS package's motivating example (problems/als/als_motivating_example: 3 states, one output, one
   disturbance through G = [1; 2; 3], the filter of wrong guesses): estimates against the truth as the record
   grows, replicated -- the error falls like N^-1/2.
2. Three outputs, full 3 x 3 Q and R (als_simulate_data8): identity and optimal weighting, bootstrap
   intervals.
3. From data to a filter with poles you accept: the filter of the estimate, then ``kalman_for_poles(...,
   objective="nearest", Q_nominal=Q_est)`` -- the Q nearest the estimate whose filter has the required poles.
4. The figure: estimated vs true covariances as N grows (``estimate_noise.png`` in ``--out``, default
   ``$OPTDESIGN_EXAMPLES_OUT`` or ``examples/_build/``).
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

import numpy as np

from optdesign import kalman_for_poles, problems
from optdesign.design.noise_estimation import estimate_noise, simulate_outputs

HERE = Path(__file__).resolve().parent


def load(name: str):
    """A problem of problems/als by name (the source tree's file when the installed library predates it)."""
    try:
        return problems.load(name)
    except Exception:  # noqa: BLE001 - an older installed problem library
        return problems.load(str(HERE.parent / "problems" / "als" / f"{name}.json"))


def rel_error(est, Q, R) -> float:
    return float(np.hypot(np.linalg.norm(est.Q - Q), np.linalg.norm(est.R - R)) /
                 np.hypot(np.linalg.norm(Q), np.linalg.norm(R)))


def convergence(prob, Ns, reps: int) -> dict:
    """Estimates of (Q, R) over ``reps`` independent records of each length."""
    t = prob.targets
    Q, R = t["Q_true"], t["R_true"]
    out = {"N": list(Ns), "Q": [], "R": [], "err": []}
    for N in Ns:
        Qs, Rs, errs = [], [], []
        for seed in range(reps):
            y = simulate_outputs(prob.plant, N, Q=Q, R=R, seed=1000 * seed + N % 997)
            est = estimate_noise(prob.plant, y, lags=int(t["lags"]))
            Qs.append(est.Q)
            Rs.append(est.R)
            errs.append(rel_error(est, Q, R))
        out["Q"].append(np.array(Qs))
        out["R"].append(np.array(Rs))
        out["err"].append(float(np.sqrt(np.mean(np.square(errs)))))
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    build = Path(os.environ.get("OPTDESIGN_EXAMPLES_OUT") or HERE / "_build")
    ap.add_argument("--out", type=Path, default=build)
    ap.add_argument("--quick", action="store_true", help="fewer lengths and replications")
    args = ap.parse_args()
    np.set_printoptions(precision=4, suppress=True)

    # 1. the motivating example
    mot = load("als_motivating_example")
    Ns = (500, 2000, 10000) if args.quick else (500, 1000, 2000, 5000, 10000, 20000, 50000)
    reps = 4 if args.quick else 12
    conv = convergence(mot, Ns, reps)
    print(f"1. {mot.title}\n   truth Q = {mot.targets['Q_true'][0, 0]}, R = {mot.targets['R_true'][0, 0]}; "
          f"{reps} records per length")
    print("        N   Q mean +- sd        R mean +- sd       rms rel. error")
    for N, Qs, Rs, e in zip(conv["N"], conv["Q"], conv["R"], conv["err"], strict=True):
        print(f"   {N:6d}   {Qs.mean():.4f} +- {Qs.std(ddof=1):.4f}   "
              f"{Rs.mean():.4f} +- {Rs.std(ddof=1):.4f}   {e:.4f}")
    slope = np.polyfit(np.log(conv["N"]), np.log(conv["err"]), 1)[0]
    print(f"   slope of log(error) against log(N): {slope:.2f} (N^-1/2: -0.5)")

    # 2. three outputs, full Q and R
    d8 = load("als_simulate_data8")
    t = d8.targets
    y = simulate_outputs(d8.plant, int(t["samples"]) * (1 if args.quick else 4), Q=t["Q_true"], R=t["R_true"],
                         seed=8)
    print(f"\n2. {d8.title}")
    for weighting in ("identity", "optimal"):
        est = estimate_noise(d8.plant, y, lags=int(t["lags"]), weighting=weighting, bootstrap=50, seed=0)
        c = est.confidence
        print(f"   {weighting:8s} weighting: rel. error {rel_error(est, t['Q_true'], t['R_true']):.3f}, "
              f"route {est.route.answered.name}, {est.weighting_report or ''}")
        for k in ("Q", "R"):
            print(f"     diag {k} = {np.diag(getattr(est, k))} "
                  f"(90 % interval {np.diag(c[k + '_low'])} .. {np.diag(c[k + '_high'])})")
    conv8 = convergence(d8, Ns, max(2, reps // 3))

    # 3. from data to a filter with poles you accept
    kf = est.kalman()
    print(f"\n3. the filter of the estimate: poles {np.sort(kf.poles.real)}")
    wanted = np.array([0.05, 0.1, 0.15])
    near = kalman_for_poles(est.estimated_plant(), wanted, objective="nearest", Q_nominal=est.Q)
    print(f"   the nearest Q to the estimate with poles {wanted}: status {near.status}, "
          f"||Q - Q_est|| / ||Q_est|| = {np.linalg.norm(near.Q - est.Q) / np.linalg.norm(est.Q):.3f}")
    print(near.Q)

    # 4. the figure
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("\n(matplotlib not installed: no figure)")
        return
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 4))
    N = np.array(conv["N"], dtype=float)
    for key, color in (("Q", "C0"), ("R", "C1")):
        truth = mot.targets[key + "_true"][0, 0]
        vals = np.array([v.reshape(len(v), -1)[:, 0] for v in conv[key]])
        m, s = vals.mean(1), vals.std(1, ddof=1)
        a1.semilogx(N, m, "o-", color=color, label=f"{key} estimate (mean +- sd)")
        a1.fill_between(N, m - s, m + s, color=color, alpha=0.2)
        a1.axhline(truth, color=color, ls="--", lw=1, label=f"{key} true")
    a1.set_xlabel("samples N")
    a1.set_ylabel("covariance")
    a1.set_title("motivating example (1 output): estimates vs truth")
    a1.legend(fontsize=8)
    a2.loglog(N, conv["err"], "o-", label="motivating example (Q, R scalar)")
    a2.loglog(N, conv8["err"], "s-", label="three outputs (full 3x3 Q, R)")
    a2.loglog(N, conv["err"][0] * np.sqrt(N[0] / N), "k:", label="N^-1/2")
    a2.set_xlabel("samples N")
    a2.set_ylabel("rms relative error of (Q, R)")
    a2.set_title("convergence")
    a2.legend(fontsize=8)
    fig.tight_layout()
    args.out.mkdir(parents=True, exist_ok=True)
    path = args.out / "estimate_noise.png"
    fig.savefig(path, dpi=300)  # the library's figure resolution (optdesign.plot.FIGURE_DPI)
    print(f"\nfigure: {path}")


if __name__ == "__main__":
    main()
