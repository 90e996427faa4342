r"""Reproduction of seed 004 (Ahn, Lim, Lee & Lee): Kalman filter design via block-pulse functions.

Recomputes, with the library, the paper's only example -- the damped harmonic oscillator
``F = [[0, 1], [-0.64, -0.32]]``, ``G = [0, 1]'``, ``H = [0, 1]``, ``Q = R = 1``, ``P0 = 0``, on
``[0, 10]`` s with ``m = 50`` block pulses -- and what the paper leaves unsaid:

* Fig 2 (the time-varying filter gain ``K(t) = P(t) H' R^-1``): the block-pulse staircase
  (the paper's recursion (4.24)-(4.26), typos fixed) against the exact gain (Hamiltonian
  transition matrix) and the steady-state gain of the algebraic Riccati equation.  The paper
  prints no numbers, so the rows below are reproduced values, not comparisons.
* What the recursion is: ``phi_k = (C^{k-1} + C^k)/2`` with the Crank-Nicolson (Pade(1,1))
  propagator C -- checked to rounding error -- hence second order at the block midpoints
  (measured order over m = 25..400) and first order as a piecewise-constant function; the
  paper's ``V U^-1`` is not symmetric (an ``O(h^2)`` antisymmetric part).
* The misprinted equations (4.12), (4.20), (4.23) and the final gain formula, with their
  corrected forms (rows with ``agrees = NO``).
* Why the exact method needs restarts: ``V U^-1`` from one matrix exponential over ``[0, t]``
  overflows once ``e^{rho t}`` does (the paper's example: from t ~ 1350; before that it is
  accurate, since its Hamiltonian has one time scale), loses the transient on an unstable plant
  (CAREX 1.2: error 1e-7 at t ~ 30, O(1) at t ~ 60) and on a stiff one within a fraction of a
  second (CAREX 1.6); the restarted transition matrix does not.

Figures (``outdir``): ``seed004_fig2_filter_gain.png`` (gains and covariances, BPF m = 50 vs
exact), ``seed004_convergence.png`` (error against m with the order-1 and order-2 slopes, and
the error of the one-exponential solution against t for three plants).

References
----------
Ahn, D. S., Lim, Y. S., Lee, S. H. & Lee, M. K., "Design of Kalman filter via BPF", seed 004,
eqs (3.11), (4.4), (4.11)-(4.12), (4.20)-(4.26), section 5, Fig. 2.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import scipy.linalg

from .. import problems
from ..classical.bpf import (
    bpf_riccati,
    bpf_transition,
    cayley,
    filter_hamiltonian,
    riccati_flow,
)
from ..classical.riccati import filter_are
from .reproduce import PaperReproduction, ReproRow, fmt, output_dir, paper_reproduction, pyplot, save_figure

__all__ = ["reproduce", "convergence", "naive_error", "PROBLEM", "BLOCKS", "NAIVE_PROBLEMS"]

_TITLE = "Design of Kalman Filter via BPF"

#: the problem-library entry of the paper's example
PROBLEM = "ahn_bpf_harmonic_oscillator"

#: block counts of the convergence study
BLOCKS = (25, 50, 100, 200, 400)

#: plants of the one-exponential study: the paper's example, an unstable and a stiff CAREX plant
NAIVE_PROBLEMS = (PROBLEM, "carex_1.2", "carex_1.6")


def _rel(P, Pref) -> float:
    return float(np.max(np.linalg.norm(P - Pref, axis=(1, 2))) / np.max(np.linalg.norm(Pref, axis=(1, 2))))


def convergence(M, P0, t_final: float, blocks=BLOCKS, *, grid: int = 41) -> dict[str, np.ndarray]:
    """Relative errors of the block-pulse solution against the exact one, for each m.

    Returns ``m``, ``midpoint`` (symmetrized coefficients at the block midpoints), ``raw`` (the
    paper's unsymmetrized ``V U^-1`` at the midpoints), ``piecewise`` (the piecewise-constant
    expansion on a fixed grid of ``grid`` times), ``asymmetry`` (largest antisymmetric part over
    the largest ``||P||_F``) and the observed orders ``log2(e(m) / e(2m))`` of each.
    """
    out: dict[str, list] = {"m": [], "midpoint": [], "raw": [], "piecewise": [], "asymmetry": []}
    tq = np.linspace(0.0, t_final, grid)
    exact_q, _ = riccati_flow(M, P0, tq)
    for m in blocks:
        raw = bpf_riccati(M, P0, t_final, m, symmetrize=False)
        sym = 0.5 * (raw.P + np.swapaxes(raw.P, 1, 2))
        exact, _ = riccati_flow(M, P0, raw.t)
        k = np.minimum((tq / t_final * m).astype(int), m - 1)
        out["m"].append(m)
        out["midpoint"].append(_rel(sym, exact))
        out["raw"].append(_rel(raw.P, exact))
        out["piecewise"].append(_rel(sym[k], exact_q))
        out["asymmetry"].append(float(np.max(raw.asymmetry) / np.max(np.linalg.norm(exact, axis=(1, 2)))))
    res = {key: np.asarray(v, dtype=float) for key, v in out.items()}
    for key in ("midpoint", "raw", "piecewise", "asymmetry"):
        e = res[key]
        res[f"order_{key}"] = np.log(e[:-1] / e[1:]) / np.log(res["m"][1:] / res["m"][:-1])
    return res


def naive_error(M, P0, times) -> np.ndarray:
    """Relative error of ``V U^-1`` from ONE matrix exponential over ``[0, t]`` (no restarts),
    against the restarted exact flow, at each time (inf where it overflows or U is singular)."""
    n = P0.shape[0]
    exact, _ = riccati_flow(M, P0, times)
    err = np.empty(len(times))
    Z0 = np.vstack([np.eye(n), P0])
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore")
        for j, t in enumerate(times):
            try:
                Y = scipy.linalg.expm(M * t) @ Z0
                P = np.linalg.solve(Y[:n].T, Y[n:].T).T
                e = np.linalg.norm(P - exact[j]) / np.linalg.norm(exact[j])
                err[j] = e if np.isfinite(e) else np.inf
            except (np.linalg.LinAlgError, ValueError, OverflowError):
                err[j] = np.inf
    return err


@paper_reproduction
def reproduce(outdir: str | Path, *, quick: bool = False, progress=None) -> PaperReproduction:
    """Recompute seed 004's example, write its figures into ``outdir``, return the table.

    Parameters
    ----------
    outdir : str or Path
        Folder for the PNG figures (created if missing).
    quick : bool
        Fewer sample times in the figures (the numbers in the table are the same).
    progress : optdesign._progress.Progress, optional
        Told about every figure written.

    Returns
    -------
    PaperReproduction
    """
    outdir = output_dir(outdir)
    prob = problems.load(PROBLEM)
    plant = prob.plant
    assert plant is not None, f"the library problem {PROBLEM} has a plant"
    P0 = np.asarray(prob.targets["P0"], dtype=float)
    tf = float(prob.targets["t_final"])
    m = int(prob.targets["steps"])
    n = plant.n
    R = plant.noise_covariances()[1]
    M = filter_hamiltonian(plant.A, plant.C, plant.process_noise(), R)
    Rinv_C = np.linalg.solve(R, plant.C)
    ex = "harmonic oscillator, m = 50, tf = 10"
    rows: list[ReproRow] = []

    # ---- Fig 2: BPF (m = 50) against the exact gain
    raw = bpf_riccati(M, P0, tf, m, symmetrize=False)
    sym = 0.5 * (raw.P + np.swapaxes(raw.P, 1, 2))
    exact_mid, _ = riccati_flow(M, P0, raw.t)
    K_paper = raw.P @ Rinv_C.T                   # the paper's K = V U^-1 H' R^-1 (unsymmetrized)
    K_sym = sym @ Rinv_C.T
    K_exact = exact_mid @ Rinv_C.T
    kscale = float(np.max(np.abs(K_exact)))
    rows.append(ReproRow(ex, "Fig 2: K(t), BPF vs exact (max |dK| / max |K|)", None,
                         f"{np.max(np.abs(K_paper - K_exact)) / kscale:.2e} (paper's V U^-1), "
                         f"{np.max(np.abs(K_sym - K_exact)) / kscale:.2e} (symmetrized)", None,
                         "Fig 2 is not digitized; the BPF staircase follows the exact gain to O(h^2)"))
    are = filter_are(plant)
    t_exact = np.linspace(0.0, tf, 201 if quick else 1001)
    P_exact, _ = riccati_flow(M, P0, t_exact)
    K_end = P_exact[-1] @ Rinv_C.T
    rows.append(ReproRow(ex, "K(10) exact", None, fmt(K_end.ravel(), 6), None,
                         "transition-matrix solution at t = 10"))
    rows.append(ReproRow(ex, "K steady state (ARE)", None, fmt(are.L.ravel(), 6), None,
                         f"filter_are; ||P(10) - P_ss||_F / ||P_ss||_F = "
                         f"{np.linalg.norm(P_exact[-1] - are.P) / np.linalg.norm(are.P):.1e}"))
    rows.append(ReproRow(ex, "K on the last block (BPF, t = 9.9)", None, fmt(K_paper[-1].ravel(), 6), None,
                         f"exact at 9.9: {fmt(K_exact[-1].ravel(), 6)}"))

    # ---- what the recursion is
    h = tf / m
    phis = bpf_transition(M, tf, m)
    C = cayley(M, h)
    Ck = np.eye(2 * n)
    worst = 0.0
    for k in range(m):
        Ck1 = Ck @ C
        avg = 0.5 * (Ck + Ck1)
        worst = max(worst, float(np.linalg.norm(phis[k] - avg) / np.linalg.norm(avg)))
        Ck = Ck1
    rows.append(ReproRow(ex, "phi_k = (C^(k-1) + C^k)/2, C = Cayley (Crank-Nicolson)", None,
                         f"max relative difference {worst:.1e}", None,
                         "the recursion IS the block average of the trapezoidal-rule transition matrix"))
    conv = convergence(M, P0, tf)
    rows.append(ReproRow(ex, "order of the BPF recursion (m = 25..400, block midpoints)", None,
                         fmt(conv["order_midpoint"], 3), None,
                         "second order; the paper states no order"))
    rows.append(ReproRow(ex, "order as a piecewise-constant function (fixed grid)", None,
                         fmt(conv["order_piecewise"], 3), None, "first order away from the midpoints"))
    rows.append(ReproRow(ex, "antisymmetric part of the paper's V U^-1 (m = 50)", None,
                         f"{conv['asymmetry'][1]:.2e}", None,
                         "the half Euler step in phi_k^-1 is not symplectic: P_k is not symmetric"))

    # ---- misprinted equations (text rows)
    rows += [
        ReproRow("eq (4.12)", "gain from the transition matrix",
                 "K = (F21 + F22 P0)^-1 (F11 + F12 P0)^-1 H'R^-1",
                 "K = (F21 + F22 P0)(F11 + F12 P0)^-1 H'R^-1", False,
                 "spurious first inverse; (4.11) and the final formula have it right"),
        ReproRow("eq (4.20)", "integral of dPhi(t0,t)/dt = -Phi(t0,t) A", "I - Phi(t0,t) = -int Phi A",
                 "Phi(t0,t) - I = -int Phi A", False, "sign"),
        ReproRow("eq (4.23)", "block-pulse form of (4.20)", "sum (I - phi_k) H_k = h sum (I - phi_k) A [...]",
                 "sum (I - phi_k) H_k = h sum phi_k A [H_k/2 + sum_{l>k} H_l]", False,
                 "I - phi_k on the right should be phi_k; (4.24)-(4.25) follow only from the corrected form"),
        ReproRow("final K(t)", "gain of block k", "(phi_2ik + phi_22k P0)(...)^-1",
                 "(phi^-1_21k + phi^-1_22k P0)(phi^-1_11k + phi^-1_12k P0)^-1 H'R^-1", False,
                 "OCR/typo phi_2ik = phi_21k; the phi here are blocks of phi_k^-1 (4.26)"),
    ]

    # ---- one exponential vs restarts
    t_long = np.geomspace(0.01, 2000.0, 30 if quick else 80)
    naive = {}
    for name in NAIVE_PROBLEMS:
        pl = plant if name == PROBLEM else problems.load(name).plant
        assert pl is not None, f"the library problem {name} has a plant"
        Mx = M if name == PROBLEM else filter_hamiltonian(pl.A, pl.C, pl.process_noise(),
                                                          pl.noise_covariances()[1])
        nerr = naive_error(Mx, np.zeros((pl.n, pl.n)), t_long)
        naive[name] = nerr
        bad = t_long[~(nerr <= 1e-8)]
        over = t_long[~np.isfinite(nerr)]
        text = f"error > 1e-8 from t = {bad[0]:.3g}" if bad.size else "error <= 1e-8 throughout"
        if over.size:
            text += f"; overflow / singular U from t = {over[0]:.3g}"
        rows.append(ReproRow(f"long horizon: {name}", "V U^-1 from one exponential over [0, t]", None,
                             text, None, "the restarted transition matrix (riccati_de method='transition') "
                             "stays exact"))

    figs = (_figure_gain(outdir, raw.t, K_paper, K_sym, t_exact, P_exact, Rinv_C, are, raw.P, h, progress),
            _figure_convergence(outdir, conv, t_long, naive, progress))
    return PaperReproduction(paper="004", title=_TITLE, rows=tuple(rows), figures=figs)


def _stairs(ax, t_mid, y, h, **kw):
    edges = np.r_[t_mid - h / 2, t_mid[-1] + h / 2]
    ax.stairs(y, edges, baseline=None, **kw)


def _figure_gain(outdir: Path, t_mid, K_paper, K_sym, t, P, Rinv_C, are, P_raw, h, progress=None) -> Path:
    plt = pyplot()
    K = P @ Rinv_C.T
    fig, axes = plt.subplots(1, 3, figsize=(13, 4.0))
    for i, ax in enumerate(axes[:2]):
        ax.plot(t, K[:, i, 0], "k-", lw=1.2, label="exact (transition matrix)")
        _stairs(ax, t_mid, K_paper[:, i, 0], h, color="C3", lw=1.2, label="BPF $m = 50$ (paper)")
        ax.axhline(are.L[i, 0], color="C0", ls="--", lw=1, label="steady state (ARE)")
        ax.set_xlabel("$t$ (s)")
        ax.set_ylabel(f"$K_{i + 1}(t)$")
        ax.set_title(f"filter gain $K_{i + 1}(t)$")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    ax = axes[2]
    for (i, j), c in zip(((0, 0), (0, 1), (1, 1)), ("C0", "C1", "C2"), strict=True):
        # the block values as a wide translucent staircase under the thin exact curve: both visible
        _stairs(ax, t_mid, 0.5 * (P_raw[:, i, j] + P_raw[:, j, i]), h, color=c, lw=3.0, alpha=0.4,
                label=f"$P_{{{i + 1}{j + 1}}}$ BPF $m = 50$")
        ax.plot(t, P[:, i, j], color=c, lw=1.1, label=f"$P_{{{i + 1}{j + 1}}}$ exact")
    ax.set_title("covariance $P(t)$: exact and BPF $m = 50$")
    ax.set_xlabel("$t$ (s)")
    ax.set_ylabel("entries of $P(t)$")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7.5, ncol=2, loc="center right", bbox_to_anchor=(1.0, 0.3))  # below P11, P22
    fig.suptitle("Seed 004 Fig 2: harmonic oscillator, time-varying Kalman gain")
    return save_figure(fig, outdir / "seed004_fig2_filter_gain.png", progress=progress)


def _figure_convergence(outdir: Path, conv, t_long, naive, progress=None) -> Path:
    plt = pyplot()
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.2))
    m = conv["m"]
    ax1.loglog(m, conv["midpoint"], "o-", label="BPF at block midpoints (symmetrized)")
    ax1.loglog(m, conv["raw"], "s--", label=r"BPF, paper's $VU^{-1}$ (asymmetric)")
    ax1.loglog(m, conv["piecewise"], "^-", label="BPF as piecewise constant")
    ax1.loglog(m, conv["midpoint"][0] * (m[0] / m) ** 2, "k:", lw=0.8, label="slope $-2$")
    ax1.loglog(m, conv["piecewise"][0] * (m[0] / m), "k-.", lw=0.8, label="slope $-1$")
    ax1.set_xticks(m, [str(int(v)) for v in m])
    ax1.minorticks_off()
    ax1.set_xlabel("blocks $m$")
    ax1.set_ylabel(r"$\max_t \|P - P_{\mathrm{exact}}\|_F \,/\, \max_t \|P_{\mathrm{exact}}\|_F$")
    ax1.set_title("order of the block-pulse recursion")
    ax1.grid(alpha=0.3, which="both")
    ax1.legend(fontsize=8)
    for k, (name, nerr) in enumerate(naive.items()):
        finite = np.isfinite(nerr)
        ax2.loglog(t_long[finite], np.maximum(nerr[finite], 1e-17), "o-", ms=3, color=f"C{k}", label=name)
        if np.any(~finite):
            ax2.axvline(t_long[~finite][0], color=f"C{k}", ls="--", lw=0.8)
    ax2.set_xlabel("$t$ (s)")
    ax2.set_ylabel("relative error")
    ax2.set_title(r"$VU^{-1}$ from one exponential (dashed: overflow)")
    ax2.grid(alpha=0.3, which="both")
    ax2.legend(fontsize=8)
    return save_figure(fig, outdir / "seed004_convergence.png", progress=progress)
