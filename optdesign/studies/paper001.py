r"""Reproduction of seed 001 (Jung & Huh): well-conditioned observer via the non-normality measure.

Recomputes, with the library:

* Example 1 (``A = [[0, 1], [2, -1]]``, ``C = [1, 0]``): kappa2 over the gain plane (Fig. 1),
  the gain region that is stable with ``eta <= 2`` (Fig. 2, from the closed-form interval
  bounds of :func:`optdesign.classical.observer_2x2_gain_region`, checked on a grid with the
  complex Schur form), the printed kappa2 at ``L = [10, 5]`` (1.59) and ``[10, 45]`` (9.12) --
  both reproduce; eq (21) prints ``|a1 - l2 + 1|`` where the derivation gives ``|a1 - l2 - 1|``,
  and it covers real poles only although ``L = [10, 45]`` has complex poles.
* Example 2 (Kalman filter, ``G = [0, 1]'``): eta and kappa2 against ``q/r`` (Fig. 3) with the
  exact set ``eta <= 2``: ``[0, 1.3648] U [3.4099, 228.545]``.  The printed ``q/r < 1.3 or
  4 < q/r < 146`` is wrong; eq (30)/(31) hold only while the poles are real (``q/r < 2.25``).
  The eta-optimal filter from :func:`optdesign.well_conditioned_kalman` (Riccati as a
  constraint) is marked.
* Example 3 (aircraft pitch, third order): the printed kappa2 values reproduce; the printed
  ``eta = 2.41`` at ``L = [-1.2, 10, 10]'`` is the real-Schur quantity (2.408), the complex-Schur
  eta is 3.107; ``L = [4.4, -0.2, -3.4]'`` makes ``A - LC`` unstable.  Fig. 4: the gains with
  ``eta < 4`` in the box ``|l_i| < 10`` and a design -- poles in ``Re s <= -0.328`` (the paper's
  decay) with ``||L|| <=`` the paper's gain norm -- that beats the paper's gain (kappa2 4.31 < 4.46).

Figures (``outdir``): ``seed001_fig1_kappa2_gain_plane.png``, ``seed001_fig2_gain_region.png``,
``seed001_fig3_qr.png``, ``seed001_fig4_aircraft.png``.

References
----------
Jung, J. & Huh, K., "Design of the well-conditioned observer using the non-normality
measure" (seed 001), eq (1)-(31), Examples 1-3, Fig. 1-4.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import scipy.linalg

from .. import problems
from ..analysis import metrics
from ..classical.jung_huh import (
    jung_huh_eq21_printed,
    kalman_2x2_eta,
    kalman_2x2_eta_set,
    kalman_2x2_gain,
    kalman_2x2_kappa2,
    kappa2_from_eta_2x2,
    observer_2x2_eta,
    observer_2x2_gain_region,
    observer_2x2_kappa2,
    observer_2x2_stable,
)
from ..classical.riccati import filter_are
from ..design.well_conditioned import well_conditioned_kalman, well_conditioned_observer
from ..model.regions import HalfPlane
from .reproduce import PaperReproduction, ReproRow, fmt, output_dir, paper_reproduction, pyplot, save_figure

__all__ = ["reproduce", "real_schur_eta", "aircraft_design"]

_TITLE = "Design of the Well-Conditioned Observer Using the Non-normality Measure"
#: how the figures are written (``bbox_inches="tight"`` instead of ``tight_layout``)
_SAVE: dict[str, Any] = {"layout": False, "bbox_inches": "tight"}  # at save_figure's 300 dpi


def real_schur_eta(X) -> float:
    """The quantity the paper computed as eta: strictly upper part of the REAL Schur form over the gap.

    Not Huh & Stein's eta for complex poles (the real Schur form keeps 2 x 2 blocks, whose
    off-diagonal entry is not part of the non-normal part ``N``); kept to explain the printed 2.41.
    """
    X = np.asarray(X, dtype=float)
    T, _ = scipy.linalg.schur(X, output="real")
    w = np.linalg.eigvals(X)
    d = np.abs(w[:, None] - w[None, :])
    np.fill_diagonal(d, np.inf)
    return float(np.linalg.norm(np.triu(T, 1)) / np.min(d))


def aircraft_design(starts: int = 3):
    """Example 3 redesigned: min kappa2, poles in ``Re s <= -decay(L_paper)``, ``||L|| <= ||L_paper||``."""
    ex = problems.load("jung_huh_ex3")
    plant = ex.plant
    assert plant is not None, "the library problem jung_huh_ex3 has a plant"
    L_paper = np.asarray(ex.references["cases_printed"][0]["L"], dtype=float).reshape(3, 1)
    decay = -float(np.max(np.linalg.eigvals(plant.A - L_paper @ plant.C).real))
    region = HalfPlane(decay)
    d = well_conditioned_observer(
        plant, region=region, max_gain=float(np.linalg.norm(L_paper, 2)), starts=starts
    )
    return d, region, L_paper


@paper_reproduction
def reproduce(outdir: str | Path, *, quick: bool = False, progress=None) -> PaperReproduction:
    """Recompute seed 001's examples, write Fig. 1-4 into ``outdir``, return the table.

    Parameters
    ----------
    outdir : str or Path
        Folder for the PNG figures (created if missing).
    quick : bool
        Coarser grids and fewer multi-starts (for tests / CI).
    progress : optdesign._progress.Progress, optional
        Told about every figure written.

    Returns
    -------
    PaperReproduction
    """
    plt = pyplot()
    outdir = output_dir(outdir)
    rows: list[ReproRow] = []
    figs: list[Path] = []
    for part in (_example1, _example2, _example3):
        r, f = part(plt, outdir, quick, progress)
        rows += r
        figs += f

    return PaperReproduction(paper="001", title=_TITLE, rows=tuple(rows), figures=tuple(figs))


def _example1(plt, outdir: Path, quick: bool, progress) -> tuple[list[ReproRow], list[Path]]:
    """Example 1 (2x2 observer: eq (21), the kappa2 bound) and Fig. 1-2."""
    rows: list[ReproRow] = []
    figs: list[Path] = []
    # ------------------------------------------------------------------ Example 1
    ex1 = problems.load("jung_huh_ex1")
    a1, a2 = float(ex1.data["a1"]), float(ex1.data["a2"])
    beta = float(ex1.targets["beta"])
    plant1 = ex1.plant
    assert plant1 is not None, "the library problem jung_huh_ex1 has a plant"
    e = "Ex. 1"
    for case in ex1.references["cases_printed"]:
        L = np.asarray(case["L"], dtype=float).reshape(2, 1)
        k_cf = float(observer_2x2_kappa2(a1, a2, L[0, 0], L[1, 0]))
        k_m = metrics.kappa2(plant1.A - L @ plant1.C)
        poles = np.linalg.eigvals(plant1.A - L @ plant1.C)
        cplx = bool(np.any(np.abs(poles.imag) > 0))
        rows.append(
            ReproRow(
                e,
                f"kappa2 at L = {fmt(L.ravel())}",
                fmt(case["kappa2"]),
                fmt(k_m, 5),
                abs(k_m - case["kappa2"]) < 0.006,
                f"closed form {k_cf:.5f}; poles {fmt(poles)}"
                + ("; complex poles: eq (21) does not cover this gain" if cplx else ""),
            )
        )
    eta_p = float(jung_huh_eq21_printed(a1, a2, 10.0, 5.0))
    eta_c = float(observer_2x2_eta(a1, a2, 10.0, 5.0))
    rows.append(
        ReproRow(
            e,
            "eta at L = [10, 5]",
            f"eq (21): {eta_p:.4f}",
            fmt(eta_c, 4),
            False,
            "eq (21) prints |a1 - l2 + 1|; eq (15)-(17) give mn = -1/(a1 - l2), hence "
            f"|a1 - l2 - 1|/sqrt(D) = {eta_c:.4f} = metrics.eta; with the printed sign eq (19) "
            f"would give kappa2 {float(kappa2_from_eta_2x2(eta_p)):.3f}, not the printed 1.59",
        )
    )
    kb = float(kappa2_from_eta_2x2(beta))
    rows.append(
        ReproRow(
            e,
            "kappa2 bound in the eta <= 2 region",
            "about 4.3",
            fmt(kb, 5),
            True,
            "eq (19) at eta = 2: 2 + sqrt 5",
        )
    )
    _example1_figures(L, a1, a2, beta, case, e, ex1, figs, kb, outdir, plant1, plt, progress, quick,
                      rows)
    return rows, figs


def _example1_figures(L, a1, a2, beta, case, e, ex1, figs, kb, outdir, plant1, plt, progress, quick, rows):
    """Fig. 1 (kappa2 over the gain plane) and Fig. 2 (the stable gains with eta <= beta), with their
    checks."""
    # Fig. 1: kappa2 over the gain plane
    n1 = 161 if quick else 401
    l1g = np.linspace(-5.0, 30.0, n1)
    l2g = np.linspace(-60.0, 140.0, n1)
    G1, G2 = np.meshgrid(l1g, l2g)
    K = observer_2x2_kappa2(a1, a2, G1, G2)
    stab = observer_2x2_stable(a1, a2, G1, G2)
    rng = np.random.default_rng(1)
    idx = rng.integers(0, n1, size=(40, 2))
    err = max(
        abs(float(K[i, j]) - metrics.kappa2(plant1.A - np.array([[G1[i, j]], [G2[i, j]]]) @ plant1.C))
        / float(K[i, j])
        for i, j in idx
        if np.isfinite(K[i, j]) and K[i, j] < 1e8
    )
    rows.append(
        ReproRow(
            e,
            "Fig. 1 closed form vs metrics.kappa2 (40 random grid points)",
            None,
            f"max rel. diff {err:.1e}",
            err < 1e-8,
        )
    )
    fig, ax = plt.subplots(figsize=(7.5, 5.5))
    Z = np.log10(np.clip(K, 1.0, 1e4))
    pc = ax.pcolormesh(G1, G2, Z, shading="auto", cmap="viridis")
    cb = fig.colorbar(pc, ax=ax)
    cb.set_label(r"$\log_{10}\,\kappa_2(P)$ of $A - LC$ (clipped at $10^4$)")
    ax.contourf(G1, G2, (~stab).astype(float), levels=[0.5, 1.5], colors="none", hatches=["////"])
    ax.contour(G1, G2, (~stab).astype(float), levels=[0.5], colors="white", linewidths=1.0)
    D = (a2 + G1) ** 2 + 4 * (a1 - G2)
    ax.contour(G1, G2, D, levels=[0.0], colors="red", linewidths=1.2, linestyles="--")
    for case, mk in zip(ex1.references["cases_printed"], ("o", "s"), strict=True):
        L = np.ravel(case["L"])
        ax.plot(
            L[0],
            L[1],
            mk,
            color="white",
            mec="black",
            ms=8,
            label=f"$L = [{L[0]:g}, {L[1]:g}]$: $\\kappa_2$ = {observer_2x2_kappa2(a1, a2, L[0], L[1]):.2f}",
        )
    ax.plot([], [], color="red", ls="--", label=r"double pole ($D = 0$): $\kappa_2 = \infty$")
    ax.plot([], [], color="white", lw=0, marker="s", mfc="none", mec="gray",
            label=r"hatched: unstable $A - LC$")
    ax.set_xlabel(r"$l_1$")
    ax.set_ylabel(r"$l_2$")
    ax.set_title(
        r"Seed 001 Fig. 1: $\kappa_2$ of $A - LC$ over the gain plane ($A = [[0, 1], [2, -1]]$, "
        r"$C = [1, 0]$)",
        fontsize=9,
    )
    ax.legend(loc="upper left", fontsize=8, framealpha=0.85)
    figs.append(save_figure(fig, outdir / "seed001_fig1_kappa2_gain_plane.png", progress=progress, **_SAVE))

    # Fig. 2: the region {stable, eta <= beta}
    l1r = np.linspace(a2 + 1e-6, 30.0, 600 if not quick else 200)
    real_lo, real_hi, cx_lo, cx_hi = (np.full(l1r.size, np.nan) for _ in range(4))
    for k, l1 in enumerate(l1r):
        ivs = observer_2x2_gain_region(a1, a2, beta, l1)
        for lo, hi in ivs:
            s, c_mid = a2 + l1, a1 - 0.5 * (lo + hi)
            if s * s + 4 * c_mid > 0:
                real_lo[k], real_hi[k] = lo, hi
            else:
                cx_lo[k], cx_hi[k] = lo, hi
    # check kappa2 <= 2 + sqrt 5 inside on a grid
    inside_k = []
    for l1 in np.linspace(a2 + 0.05, 30, 30 if quick else 80):
        for lo, hi in observer_2x2_gain_region(a1, a2, beta, l1):
            for l2 in np.linspace(lo, hi, 9)[1:-1]:
                inside_k.append(metrics.kappa2(plant1.A - np.array([[l1], [l2]]) @ plant1.C))
    kmax = max(inside_k)
    rows.append(
        ReproRow(
            e,
            "max kappa2 over grid points inside the Fig. 2 region",
            "< 4.3",
            fmt(kmax, 5),
            kmax <= kb + 1e-9,
            f"{len(inside_k)} points, metrics.kappa2 (numpy)",
        )
    )
    fig, ax = plt.subplots(figsize=(7.5, 5.5))
    ax.fill_between(l1r, real_lo, real_hi, color="tab:blue", alpha=0.45, label=r"$\eta \leq 2$, real poles")
    ax.fill_between(l1r, cx_lo, cx_hi, color="tab:orange", alpha=0.55, label=r"$\eta \leq 2$, complex poles")
    l1b = np.linspace(-5, 30, 300)
    ax.plot(l1b, a1 + a2 * l1b, "k-", lw=1.2, label=r"stability boundary $l_2 = a_1 + a_2 l_1$")
    ax.axvline(a2, color="k", ls=":", lw=1.2, label=r"stability boundary $l_1 = a_2$")
    ax.plot(l1b, a1 + (a2 + l1b) ** 2 / 4, "r--", lw=1.0, label=r"double pole ($\eta = \infty$)")
    for case, mk in zip(ex1.references["cases_printed"], ("o", "s"), strict=True):
        L = np.ravel(case["L"])
        ax.plot(L[0], L[1], mk, color="k", ms=7,
                label=f"$L = [{L[0]:g}, {L[1]:g}]$ ($\\kappa_2$ = {case['kappa2']})")
    ax.set_xlim(-5, 30)
    ax.set_ylim(-60, 140)
    ax.set_xlabel(r"$l_1$")
    ax.set_ylabel(r"$l_2$")
    ax.set_title(
        f"Seed 001 Fig. 2: stable gains with $\\eta \\leq {beta:g}$ "
        f"(inside: $\\kappa_2 \\leq 2 + \\sqrt{{5}}$ = {kb:.3f})",
        fontsize=9,
    )
    ax.legend(loc="upper left", fontsize=8, framealpha=0.85)
    figs.append(save_figure(fig, outdir / "seed001_fig2_gain_region.png", progress=progress, **_SAVE))


def _example2(plt, outdir: Path, quick: bool, progress) -> tuple[list[ReproRow], list[Path]]:
    """Example 2 (the Kalman filter against the noise ratio q/r) and Fig. 3."""
    rows: list[ReproRow] = []
    figs: list[Path] = []
    # ------------------------------------------------------------------ Example 2
    ex2 = problems.load("jung_huh_ex2")
    plant2 = ex2.plant
    assert plant2 is not None, "the library problem jung_huh_ex2 has a plant"
    a, b = float(ex2.data["a"]), float(ex2.data["b"])
    beta2 = float(ex2.targets["beta"])
    e = "Ex. 2"
    worst = 0.0
    for qr in (0.5, 1.3, 3.0, 146.0):
        are = filter_are(plant2.replace(Q=[[qr]]))
        worst = max(
            worst, float(np.max(np.abs(are.L.ravel() - kalman_2x2_gain(a, b, qr))) / np.linalg.norm(are.L))
        )
    rows.append(
        ReproRow(
            e,
            "eq (29) vs ARE gain (q/r = 0.5, 1.3, 3, 146)",
            None,
            f"max rel. diff {worst:.1e}",
            worst < 1e-8,
            "optdesign.riccati.filter_are",
        )
    )
    qset = kalman_2x2_eta_set(a, b, beta2)
    printed = ex2.references["qr_intervals_printed"]
    rows.append(
        ReproRow(
            e,
            "q/r with eta <= 2",
            "q/r < 1.3 or 4 < q/r < 146",
            str(qset),
            False,
            f"exact set by root bracketing; eta(1.3) = {float(kalman_2x2_eta(a, b, 1.3)):.3f}, "
            f"eta(4) = {float(kalman_2x2_eta(a, b, 4.0)):.3f}, "
            f"eta(146) = {float(kalman_2x2_eta(a, b, 146.0)):.3f} "
            f"are not 2; eq (30)/(31) assume real poles, which holds only for q/r < {qset.double_pole:.4g} "
            "(double pole)",
        )
    )
    kal = well_conditioned_kalman(plant2, objective="eta", starts=2 if quick else 4)
    q_opt = float(np.nan if kal.Q is None else kal.Q[0, 0])
    x_dense = np.geomspace(1e-3, 1e4, 20001)
    eta_dense = kalman_2x2_eta(a, b, x_dense)
    rows.append(
        ReproRow(
            e,
            "min eta over q/r (NLP, Riccati as constraint)",
            None,
            f"eta {kal.eta:.5f} at q/r {q_opt:.4g}",
            bool(kal.success and kal.eta <= float(np.min(eta_dense)) * (1 + 1e-6)),
            f"dense grid minimum {float(np.min(eta_dense)):.5f} at "
            f"{float(x_dense[np.argmin(eta_dense)]):.4g}; {kal.message}",
        )
    )
    nq = 800 if quick else 3000
    x = np.geomspace(1e-2, 1e3, nq)
    eta_x = kalman_2x2_eta(a, b, x)
    k_x = kalman_2x2_kappa2(a, b, x)
    fig, ax = plt.subplots(figsize=(7.5, 5.0))
    ax.semilogx(x, np.clip(eta_x, 0, 50), color="tab:blue", label=r"$\eta$ (complex Schur form)")
    ax.semilogx(x, np.clip(k_x, 0, 50), color="tab:green", label=r"$\kappa_2(P)$")
    ax.axhline(beta2, color="k", ls="--", lw=1, label=rf"$\beta = {beta2:g}$")
    for k, (lo, hi) in enumerate(qset.intervals):
        ax.axvspan(
            max(lo, x[0]),
            min(hi, x[-1]),
            color="tab:blue",
            alpha=0.15,
            label=r"exact set $\eta \leq 2$" if k == 0 else None,
        )
    for k, (lo, hi) in enumerate(printed):
        ax.plot(
            [max(float(lo), x[0]), float(hi)],
            [0.3, 0.3],
            color="tab:red",
            lw=5,
            alpha=0.7,
            solid_capstyle="butt",
            label="printed $q/r$ intervals (wrong)" if k == 0 else None,
        )
    ax.axvline(
        qset.double_pole, color="tab:red", ls=":", lw=1, label=f"double pole, $q/r$ = {qset.double_pole:.4g}"
    )
    ax.plot(q_opt, kal.eta, "k*", ms=11, label=f"$\\eta$-optimal Kalman filter (NLP): $q/r$ = {q_opt:.3g}")
    ax.set_ylim(0, 12)
    ax.set_xlabel("$q/r$")
    ax.set_ylabel(r"$\eta$, $\kappa_2(P)$ (clipped at 50)")
    ax.set_title(r"Seed 001 Fig. 3: $\eta$ and $\kappa_2$ of the Kalman filter vs the noise ratio $q/r$",
                 fontsize=9)
    ax.legend(loc="upper right", fontsize=8, framealpha=0.85)
    figs.append(save_figure(fig, outdir / "seed001_fig3_qr.png", progress=progress, **_SAVE))
    return rows, figs


def _example3(plt, outdir: Path, quick: bool, progress) -> tuple[list[ReproRow], list[Path]]:
    """Example 3 (the aircraft pitch observer) and Fig. 4."""
    rows: list[ReproRow] = []
    figs: list[Path] = []
    # ------------------------------------------------------------------ Example 3
    ex3 = problems.load("jung_huh_ex3")
    plant3 = ex3.plant
    assert plant3 is not None, "the library problem jung_huh_ex3 has a plant"
    e = "Ex. 3"
    for case in ex3.references["cases_printed"]:
        L = np.asarray(case["L"], dtype=float).reshape(3, 1)
        X = plant3.A - L @ plant3.C
        k_m, e_m, e_rs = metrics.kappa2(X), metrics.eta(X), real_schur_eta(X)
        unstable = bool(np.max(np.linalg.eigvals(X).real) > 0)
        rows.append(
            ReproRow(
                e,
                f"kappa2 at L = {fmt(L.ravel())}",
                fmt(case["kappa2"], 6),
                fmt(k_m, 6),
                abs(k_m - case["kappa2"]) <= 0.006 * max(1.0, case["kappa2"] / 100),
                f"A - LC is UNSTABLE at this gain (eigenvalue {fmt(np.max(np.linalg.eigvals(X).real))})"
                if unstable
                else "",
            )
        )
        agrees = abs(e_m - case["eta"]) <= 0.006 * max(1.0, case["eta"] / 100)
        rows.append(
            ReproRow(
                e,
                f"eta at L = {fmt(L.ravel())}",
                fmt(case["eta"]),
                fmt(e_m, 6),
                agrees,
                ""
                if agrees
                else f"the printed value is the real-Schur quantity ({e_rs:.4f}); "
                "with complex poles the real Schur form keeps a 2x2 block whose off-diagonal "
                "entry is not part of N",
            )
        )
    des, region, L_paper = aircraft_design(starts=3 if quick else 6)
    k_paper = metrics.kappa2(plant3.A - L_paper @ plant3.C)
    rows.append(
        ReproRow(
            e,
            f"design: Re s <= -0.328 (paper's decay), ||L|| <= {np.linalg.norm(L_paper, 2):.2f} (paper's)",
            fmt(k_paper, 5),
            f"kappa2 {des.kappa2:.5f}, L = {fmt(des.L.ravel())}",
            bool(des.success and des.kappa2 < k_paper),
            ("beats the paper's gain" if des.success and des.kappa2 < k_paper else "does NOT beat")
            + f"; eta {des.eta:.4f}; poles {fmt(des.poles)}; {des.message}",
        )
    )
    _example3_figure(L_paper, X, des, e, ex3, figs, k_paper, outdir, plant3, plt, progress, quick, rows)
    return rows, figs


def _example3_figure(L_paper, X, des, e, ex3, figs, k_paper, outdir, plant3, plt, progress, quick, rows):
    """Fig. 4: the gains with eta < 4 in the box, and the poles of the paper's and the optimized gain."""
    # Fig. 4: gains with eta < 4 in the box
    ng = 13 if quick else 25
    g = np.linspace(-10, 10, ng)
    pts, etas, ks = [], [], []
    for l1 in g:
        for l2 in g:
            for l3 in g:
                X = plant3.A - np.array([[l1], [l2], [l3]]) @ plant3.C
                ev = metrics.eta(X)
                if ev < float(ex3.targets["beta"]):
                    pts.append((l1, l2, l3))
                    etas.append(ev)
                    ks.append(metrics.kappa2(X))
    pts = np.array(pts) if pts else np.zeros((0, 3))
    rows.append(
        ReproRow(
            e,
            f"Fig. 4: grid gains with eta < 4 in |l_i| < 10 ({ng}^3 grid)",
            None,
            f"{len(pts)} of {ng**3}; kappa2 <= {max(ks) if ks else float('nan'):.3f} there",
            None,
            "the figure is not digitized: no printed count to compare",
        )
    )
    fig = plt.figure(figsize=(12.5, 5.2))
    fig.subplots_adjust(left=0.06, right=0.98, wspace=0.32)  # room for the 3-D z label (l_3)
    ax = fig.add_subplot(1, 2, 1, projection="3d")
    if len(pts):
        sc = ax.scatter(pts[:, 0], pts[:, 1], pts[:, 2], c=np.log10(ks), s=6, cmap="viridis", alpha=0.6)
        # on the left: the z-axis label (l_3) is on the right of a 3-D axes and collided with it
        cb = fig.colorbar(sc, ax=ax, shrink=0.6, pad=0.04, location="left")
        cb.set_label(r"$\log_{10}\,\kappa_2$")
    ax.scatter(*L_paper.ravel(), color="red", s=60, marker="o",
               label=f"paper's $L$ ($\\kappa_2$ = {k_paper:.2f})")
    Lb = np.ravel(ex3.references["cases_printed"][1]["L"])
    ax.scatter(*Lb, color="black", s=60, marker="x",
               label=r"paper's ill-conditioned $L$ ($\kappa_2$ = 11756)")
    if np.all(np.abs(des.L) <= 10):
        ax.scatter(
            *des.L.ravel(),
            color="gold",
            edgecolor="k",
            s=90,
            marker="*",
            label=f"optimized $L$ ($\\kappa_2$ = {des.kappa2:.2f})",
        )
    ax.set_xlabel(r"$l_1$")
    ax.set_ylabel(r"$l_2$")
    ax.set_zlabel(r"$l_3$")
    for axis in (ax.xaxis, ax.yaxis, ax.zaxis):
        axis.set_ticks([-10, -5, 0, 5, 10])
    ax.set_title(r"gains with $\eta < 4$ in the box $|l_i| < 10$", fontsize=9)
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.05), fontsize=7)
    ax2 = fig.add_subplot(1, 2, 2)
    pp = np.linalg.eigvals(plant3.A - L_paper @ plant3.C)
    dec = -float(np.max(pp.real))
    xmin = min(-12.0, float(np.min(des.poles.real)) * 1.3, float(np.min(pp.real)) * 1.3)
    ymax = max(30.0, float(np.max(np.abs(des.poles.imag))) * 1.2)
    ax2.axvspan(xmin, -dec, color="tab:green", alpha=0.12,
                label=f"region $\\mathrm{{Re}}\\,s \\leq -{dec:.3f}$")
    ax2.plot(
        pp.real,
        pp.imag,
        "ro",
        ms=8,
        label=f"paper's $L$: $\\kappa_2$ = {k_paper:.3f}, $\\|L\\|$ = {np.linalg.norm(L_paper, 2):.2f}",
    )
    ax2.plot(
        des.poles.real,
        des.poles.imag,
        "k*",
        ms=11,
        label=f"optimized: $\\kappa_2$ = {des.kappa2:.3f}, $\\|L\\|$ = {des.gain_norm:.2f}",
    )
    ow = np.linalg.eigvals(plant3.A)
    ax2.plot(ow.real, ow.imag, "bx", ms=8, label="open-loop eigenvalues of $A$")
    ax2.set_xlim(xmin, 1.0)
    ax2.set_ylim(-ymax, ymax)
    ax2.axhline(0, color="gray", lw=0.5)
    ax2.axvline(0, color="gray", lw=0.5)
    ax2.set_xlabel(r"$\mathrm{Re}\,s$")
    ax2.set_ylabel(r"$\mathrm{Im}\,s$")
    ax2.set_title("observer poles (same decay, same gain norm)", fontsize=9)
    ax2.legend(loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=2, fontsize=7, framealpha=0.85)
    fig.suptitle("Seed 001 Fig. 4: aircraft pitch model (Example 3)", fontsize=10)
    figs.append(save_figure(fig, outdir / "seed001_fig4_aircraft.png", progress=progress, **_SAVE))


