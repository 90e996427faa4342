r"""Reproduction of seed 002 (S. J. Lee): Kalman filters with a delay in the output.

The paper proves (no numerical example) that the stationary filter of ``y = c0 x(t) + c1 x(t-h) + v``
satisfies the circle condition ``T(jw) R T*(jw) >= R`` (eq 17) for its return difference (16), and
hence the guaranteed margins of delay-free filters: gain ``(1/2, inf)`` and phase ``+-60 deg``
(Theorem 2, diagonal R) and crossfeed bounds (23).  This module recomputes all of it on the scalar
example of the problem library (``lee_output_delay_scalar``: ``x' = 0.5 x + w``, ``y = x + 0.5 x(t-1) + v``,
``q = r = 1``):

* ``p0`` and ``K0`` by Pade approximation of ``exp(-sh)`` (degree 1..8) and by sampling with a shift
  register (step ``h/N``), their convergence and agreement;
* the return difference (16) with the true ``exp(-jwh)``, the circle condition (17) and the
  spectral identity (19) behind it;
* the guaranteed margins, checked by closed-loop eigenvalues (delay-free filter exactly; delayed
  filter on its Pade-augmented model), and the margins that do *not* hold (mixed gain+phase);
* eq (23) as printed (``sigma_max(X) < sigma(R1)/sigma(R2)``, no square root) against a
  counterexample; the bound that holds is ``sqrt(sigma_min(R1)/sigma_max(R2))``.

Figures (``outdir``): ``seed002_return_difference.png`` (``|T(jw)|`` against 1 for the delay-free
and delayed filters) and ``seed002_convergence.png`` (``p0`` error against Pade degree and sampling
step).

References
----------
S. J. Lee, "Frequency-domain properties of Kalman filters for linear systems with delay in output"
(seed 002), eqs (3)-(24).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .. import problems
from ..analysis.margins import filter_margins
from ..analysis.robustness import circle_condition, return_difference
from ..design.kalman import kalman
from ..design.output_delay import output_delay_convergence, output_delay_kalman
from ..model.plant import Plant
from .reproduce import PaperReproduction, ReproRow, fmt, output_dir, paper_reproduction, pyplot, save_figure

__all__ = ["reproduce", "crossfeed_counterexample"]

_TITLE = "Frequency-domain properties of Kalman filters for linear systems with delay in output"


def crossfeed_counterexample(R1: float = 16.0, R2: float = 1.0, *, seed: int = 0, tries: int = 200):
    """Search (seeded) a Kalman filter with ``R = diag(R1, R2)`` destabilized by the crossfeed
    ``Delta = [[1, x], [0, 1]]`` with ``sqrt(R1/R2) < |x| < R1/R2`` (inside eq (23) as printed).

    Returns
    -------
    dict or None
        ``plant``, ``L``, ``x``, the printed bound ``R1/R2``, the valid bound ``sqrt(R1/R2)`` and the
        largest real part of ``eig(A - L Delta C)``; None if nothing is found.
    """
    rng = np.random.default_rng(seed)
    printed, valid = R1 / R2, np.sqrt(R1 / R2)
    xs = np.linspace(valid, printed, 12)[1:-1]
    for _ in range(tries):
        n = int(rng.integers(2, 4))
        A = rng.standard_normal((n, n))
        C = rng.standard_normal((2, n))
        F = rng.standard_normal((n, n))
        plant = Plant(A, C, Q=F @ F.T * rng.choice([0.01, 1.0, 100.0]), R=np.diag([R1, R2]))
        if not plant.is_observable():
            continue
        L = kalman(plant).L
        for x in np.concatenate([xs, -xs]):
            D = np.array([[1.0, x], [0.0, 1.0]])
            re = float(np.max(np.linalg.eigvals(A - L @ D @ C).real))
            if re > 0:
                return dict(plant=plant, L=L, x=float(x), printed_bound=printed, valid_bound=valid, max_re=re)
    return None


@paper_reproduction
def reproduce(outdir: str | Path, *, quick: bool = False, progress=None) -> PaperReproduction:
    """Recompute seed 002's results on the scalar example, write the figures, return the table.

    Parameters
    ----------
    outdir : str or Path
        Folder for the PNG figures (created if missing).
    quick : bool
        Fewer orders / steps (for tests and CI).
    progress : optdesign._progress.Progress, optional
        Told about every figure written.

    Returns
    -------
    PaperReproduction
    """
    outdir = output_dir(outdir)
    prob = problems.load("lee_output_delay_scalar")
    d = prob.data
    A, C0, C1, h, Q, R = d["A"], d["C0"], d["C1"], float(d["h"]), d["Q"], d["R"]
    ex = "scalar (a=0.5, c0=1, c1=0.5, h=1, q=r=1)"
    rows: list[ReproRow] = []
    note0 = "the paper has no numerical example (problem from issue 7)"

    # ---------------------------------------------------------------- convergence in the order
    degrees = list(range(1, 7 if quick else 9))
    pade_rows = output_delay_convergence(A, C0, C1, h, Q, R, method="pade", orders=degrees)
    steps = [8, 16, 32, 64] if quick else [8, 16, 32, 64, 128, 256]
    samp_rows = output_delay_convergence(A, C0, C1, h, Q, R, method="sample", orders=steps)
    fp = output_delay_kalman(A, C0, C1, h, Q, R, method="pade")
    p0_ref = float(fp.p0[0, 0])          # Pade [4/4] x 8 sections, Newton-polished ARE
    for r in pade_rows:
        rows.append(ReproRow(ex, f"p0, K0 (Pade [{r.order}/{r.order}], 1 section)", None,
                             f"{r.p0[0, 0]:.12f}, {r.K0[0, 0]:.12f}", None,
                             note0 if r.order == 1 else f"error {abs(r.p0[0, 0] - p0_ref):.1e}"))
    for r in samp_rows:
        rows.append(ReproRow(ex, f"p0, K0 (sampling, step h/{r.order})", None,
                             f"{r.p0[0, 0]:.10f}, {r.K0[0, 0]:.10f}", None,
                             f"error {abs(r.p0[0, 0] - p0_ref):.2e} (second order in the step)"))
    rich = [(4 * b.p0[0, 0] - a.p0[0, 0]) / 3 for a, b in zip(samp_rows[:-1], samp_rows[1:], strict=True)]
    rows.append(ReproRow(ex, f"p0 (sampling h/{steps[-1]}, Richardson with h/{steps[-2]})", None,
                         f"{rich[-1]:.12f}", bool(abs(rich[-1] - p0_ref) < 1e-7),
                         f"agrees with Pade [4/4] x {fp.sections} sections to {abs(rich[-1] - p0_ref):.1e}"))

    # ---------------------------------------------------------------- full filters, both methods
    fs = output_delay_kalman(A, C0, C1, h, Q, R, method="sample", order=32 if quick else 64)
    rows.append(ReproRow(ex, f"p0: Pade ([4/4] x {fp.sections}) vs sampling (h/{fs.order}, extrapolated)",
                         None,
                         f"{fp.p0[0, 0]:.10f} vs {fs.p0[0, 0]:.10f}",
                         bool(abs(fp.p0[0, 0] - fs.p0[0, 0]) < 1e-6 * fp.p0[0, 0]),
                         "the two methods agree in the limit"))
    rows.append(ReproRow(ex, "K(theta) at theta = 0, -h/2, -h (eq 4)", None,
                         fmt(fp.K_theta[[0, fp.sections // 2, -1], 0, 0], 8), None,
                         f"sampling: {fmt(fs.K_theta[[0, (fs.K_theta.shape[0] - 1) // 2, -1], 0, 0], 8)}"))
    rows.append(ReproRow(ex, "boundary condition (8)", "p1(theta) = p0", "p1(0) = p0", False,
                         "typo: the boundary condition is p1(0) = p0 (p1 varies with theta)"))
    rows.append(ReproRow(ex, "Riccati equation (5)", "0 = A_0 p0 + p0 A_0' + ...", "A_0 = A", False,
                         "typo: A_0 in (5) is A"))
    circ = fp.circle_condition()
    spec = float(np.max(fp.spectral_residual(fp.frequency_grid())))
    rows.append(ReproRow(ex, "circle condition (17): min_w (|T|^2 - 1) r, true delay", ">= 0",
                         f"{circ.min_eigenvalue:.3e} at w = {circ.omega_worst:.4g}", circ.passed,
                         "T from eq (16) with exp(-jwh); bars of p1(-s), p2(-s) restored in (15)-(16); "
                         "inf is 0 as w -> inf"))
    rows.append(ReproRow(ex, "spectral identity (19) residual (relative, max over w)", "0",
                         f"{spec:.2e}", bool(spec < 1e-2),
                         f"finite approximation of K(theta) (piecewise linear, {fp.sections} sections)"))
    # delay-free comparisons
    pl_h0 = Plant(A, np.asarray(C0) + np.asarray(C1), Q=Q, R=R)
    pl_c0 = prob.plant
    k_h0, k_c0 = kalman(pl_h0), kalman(pl_c0)
    rows.append(ReproRow("delay-free h = 0 (c = 1.5)", "p", fmt(prob.references["P_h_zero"], 8),
                         fmt(k_h0.P, 8),
                         bool(abs(k_h0.P[0, 0] - prob.references["P_h_zero"][0, 0]) < 1e-10), ""))
    rows.append(ReproRow("delay-free c1 = 0 (c = 1)", "p", fmt(prob.references["P_c1_zero"], 8),
                         fmt(k_c0.P, 8), bool(abs(k_c0.P[0, 0] - prob.references["P_c1_zero"][0, 0]) < 1e-10),
                         "the delayed p0 lies between the two delay-free values"))

    # ---------------------------------------------------------------- Theorem 2: margins
    fm = filter_margins(pl_h0, k_h0.L)
    rows.append(ReproRow("delay-free h = 0", "guaranteed gain margin (20)", "(1/2, inf)",
                         f"({fm.guaranteed_gain_margin[0]:.4g}, {fm.guaranteed_gain_margin[1]:.4g})", True,
                         f"actual: ({fm.gain_margin_lower[0]:.4g}, {fm.gain_margin_upper[0]:.4g})"))
    rows.append(ReproRow("delay-free h = 0", "guaranteed phase margin (21)", "+-60 deg",
                         f"+-{fm.guaranteed_phase_margin:.4g} deg",
                         bool(abs(fm.guaranteed_phase_margin - 60) < 1e-9),
                         f"actual: {fm.phase_margin[0]:.4g} deg"))
    assert fp.augmented is not None, "method='pade' returns the augmented filter"
    Aa, Ca, Ka = fp.augmented

    def max_re(delta):
        return float(np.max(np.linalg.eigvals(Aa - delta * Ka @ Ca).real))

    tests = {"0.51": 0.51, "1000": 1000.0, "exp(+j59deg)": np.exp(1j * np.radians(59)),
             "exp(-j59deg)": np.exp(-1j * np.radians(59))}
    worst = max(max_re(v) for v in tests.values())
    rows.append(ReproRow(ex, "perturbed delayed filter stable, gains 0.51, 1000, phases +-59 deg", "stable",
                         f"max Re eig = {worst:.4g}", bool(worst < 0),
                         "eigenvalues of A_aug - delta K_aug C_aug of the Pade-augmented filter"))
    # what does not hold: gain and phase together
    mixed = 0.51 * np.exp(1j * np.radians(59))
    rows.append(ReproRow(ex, "gain 0.51 AND phase 59 deg together", "(not claimed)",
                         f"max Re eig = {max_re(mixed):.4g}", None,
                         "margins hold one at a time or within Re(delta) > 1/2; 0.51 e^{j59} has Re 0.26"))
    ce = crossfeed_counterexample(seed=0, tries=60 if quick else 200)
    if ce is not None:
        rows.append(ReproRow("crossfeed, R = diag(16, 1)", "eq (23): sigma_max(X) < sigma(R1)/sigma(R2)",
                             "16", f"x = {ce['x']:.3g} destabilizes (max Re {ce['max_re']:.3g})", False,
                             "the bound that holds is sqrt(sigma_min(R1)/sigma_max(R2)) = 4; the OCR may "
                             "have lost the square root"))
    # ---------------------------------------------------------------- figures
    figs = _figures(outdir, fp, k_h0, k_c0, pl_h0, pl_c0, pade_rows, samp_rows, p0_ref, progress)
    return PaperReproduction("002", _TITLE, tuple(rows), figs)


def _figures(outdir, fp, k_h0, k_c0, pl_h0, pl_c0, pade_rows, samp_rows, p0_ref, progress=None):
    plt = pyplot()
    w = np.logspace(-2, 2, 1200)
    T_d = np.abs(fp.return_difference(w)[:, 0, 0])
    T_h0 = np.abs(return_difference(pl_h0, k_h0.L, w)[:, 0, 0])
    T_c0 = np.abs(return_difference(pl_c0, k_c0.L, w)[:, 0, 0])
    c_h0 = circle_condition(pl_h0, k_h0.L)
    c_d = fp.circle_condition()
    fig, (ax, bx) = plt.subplots(2, 1, figsize=(7, 6.4), sharex=True)
    ax.semilogx(w, T_c0, label="delay-free, $y = x + v$ ($c_1 = 0$)")
    ax.semilogx(w, T_h0, label="delay-free, $y = 1.5x + v$ ($h = 0$)")
    ax.semilogx(w, T_d, label="delayed, $y = x + 0.5\\,x(t-1) + v$ (eq 16)", lw=2)
    ax.axhline(1.0, color="k", ls="--", lw=1, label="$|T| = 1$ (circle condition)")
    ax.set_ylabel(r"$|T(j\omega)|$")
    ax.set_title("Return difference of the Kalman filter (seed 002, eqs 16-17)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    H = fp.loop_H(w)[:, 0, :]
    rhs = np.real(np.einsum("ki,ij,kj->k", H, fp.W, H.conj())) / fp.R[0, 0]
    bx.loglog(w, T_h0**2 - 1, label="$h = 0$: $|T|^2 - 1$")
    bx.loglog(w, T_d**2 - 1, lw=2, label="delayed: $|T|^2 - 1$")
    bx.loglog(w, rhs, "k:", label="delayed: $|H|^2 q/r$ (eq 19)")
    bx.set_xlabel(r"$\omega$ (rad/s)")
    bx.set_ylabel(r"$|T|^2 - 1$  ($\geq 0$)")
    bx.set_title(rf"min over $\omega$: delayed {c_d.min_eigenvalue:.1e}, $h = 0$ {c_h0.min_eigenvalue:.1e} "
                 r"($\to 0$ as $\omega \to \infty$)", fontsize=9)
    bx.grid(True, which="both", alpha=0.3)
    bx.legend(fontsize=8)
    f1 = save_figure(fig, outdir / "seed002_return_difference.png", progress=progress)

    fig, (a1, a2) = plt.subplots(1, 2, figsize=(9, 3.8))
    m = [r.order for r in pade_rows]
    a1.semilogy(m, [abs(r.p0[0, 0] - p0_ref) + 1e-17 for r in pade_rows], "o-")
    a1.set_xlabel("Pade degree $m$ (one section; round-off below $10^{-11}$)")
    a1.set_ylabel(f"$|p_0 - p_{{0,\\mathrm{{ref}}}}|$, $p_{{0,\\mathrm{{ref}}}}$ = {p0_ref:.10f}")
    a1.set_title("Pade $[m/m]$ of $e^{-sh}$ + ARE")
    a1.grid(True, which="both", alpha=0.3)
    N = np.array([r.order for r in samp_rows], dtype=float)
    err = np.array([abs(r.p0[0, 0] - p0_ref) for r in samp_rows])
    rich = np.array([abs((4 * b.p0[0, 0] - a.p0[0, 0]) / 3 - p0_ref) + 1e-17
                     for a, b in zip(samp_rows[:-1], samp_rows[1:], strict=True)])
    a2.loglog(1.0 / N, err, "o-", label="shift register + DARE")
    a2.loglog(1.0 / N[1:], rich, "s-", label="Richardson ($N$, $N/2$)")
    a2.loglog(1.0 / N, err[0] * (N[0] / N) ** 2, "k:", label="slope 2")
    a2.set_xlabel("step / $h = 1/N$")
    a2.set_title("Sampling with shift register + DARE")
    a2.grid(True, which="both", alpha=0.3)
    a2.legend(fontsize=8)
    f2 = save_figure(fig, outdir / "seed002_convergence.png", progress=progress)
    return (f1, f2)
