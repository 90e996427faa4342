r"""Reproduction of seed 000 (Chang & Lee 1984): Kalman gain with pre-specified estimator poles.

Recomputes, with the library:

* Example 1 (real -> real, ``A = [[0, 1], [-6, -5]]``, ``C = [1, 0]``, ``R = 1``, poles -5, -8):
  every printed intermediate of Solheim's sequential method (eq 23-33) and the final
  ``K = [8, -6]``, ``Q' = [[76, -42], [-42, 84]]`` -- all reproduce exactly; the SDP's family
  of Q (``P22`` free) and the member each objective picks.
* Example 2 (complex pair -1 +- j -> -8, -5, ``C = I``, ``R = diag(1, 5)``): the method done
  correctly (eq 44-45 solved exactly: ``q = 67.2734``, by-product pole -4.0900; the paper's
  trial-and-error step replaced by eq 28) reaches -8, -5 to rounding error.  The printed
  numbers do not reproduce: the printed ``P~`` does not solve eq (29), so the printed ``A_1``
  has eigenvalues -8.02, -1.87 instead of -8, -3.98; ``Q'_1`` is printed with the digits
  transposed (66.354 for 66.534); the printed final ``Q'`` has ARE poles -8.27, -15.70.
  Eq (39) has a sign typo (``2(delta^2 - r^2)``) and eq (41)'s middle term carries
  ``(alpha^2 + beta^2)``, not its square.
* Issue 3's double integrator (``A = [[0, 1], [0, 0]]``, ``C = [1, 0]``, ``R = 1``, ``G = I``):
  -1, -3 and -2 +- 2j are reachable (the latter only with ``Q = diag(0, 64)``), -0.2 +- 3j is
  not -- the return difference dips to ``|T| = 0.1327`` at 3.02 rad/s -- and the closest
  reachable pair is -1.6 +- 1.6j.

Figures (``outdir``): ``seed000_ex1_family.png`` (the family of Q of Example 1 against
``P22`` with the members picked by each objective), ``seed000_pole_loci.png`` (the filter
poles as the noise of each sequential step is turned up, Examples 1 and 2),
``seed000_double_integrator.png`` (``|1 + C (jwI - A)^-1 L|`` against w for the feasible and
infeasible targets, and the reachable sector of the pole plane).

References
----------
Chang, S. H. & Lee, Y. B., "A Design of Kalman Gain for the State Estimator with
Pre-specified Eigenvalues" (seed 000), eq (20)-(45), Examples 1-2, appendix.
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from .. import problems
from ..analysis.robustness import resolve_R, return_difference
from ..classical.placement import pole_error
from ..classical.riccati import filter_are, hamiltonian_are
from ..classical.solheim import solheim
from ..design.inverse_kalman import kalman_for_poles
from .reproduce import PaperReproduction, ReproRow, fmt, output_dir, paper_reproduction, pyplot, save_figure

__all__ = ["reproduce", "example1_family"]

_TITLE = "A Design of Kalman Gain for the State Estimator with Pre-specified Eigenvalues"


def _close(a, b, tol) -> bool:
    return bool(np.allclose(np.asarray(a, dtype=complex), np.asarray(b, dtype=complex), atol=tol, rtol=0))


def example1_family(num: int = 400) -> dict[str, np.ndarray]:
    """Example 1's family of Q: ``L = [8, -6]`` is fixed by the poles, ``P = [[8, -6], [-6, x]]``
    and ``Q(x) = [[76, -30 - x], [-30 - x, 10 x - 36]]``, PSD for ``x`` in
    ``[350 - sqrt(118864), 350 + sqrt(118864)]`` (roots of ``x^2 - 700 x + 3636``)."""
    lo, hi = 350 - np.sqrt(350**2 - 3636), 350 + np.sqrt(350**2 - 3636)
    x = np.linspace(lo, hi, num)
    q12 = -30 - x
    q22 = 10 * x - 36
    lmin = np.array([np.linalg.eigvalsh([[76, a], [a, b]])[0] for a, b in zip(q12, q22, strict=True)])
    return {"P22": x, "q12": q12, "q22": q22, "trace": 76 + q22, "lambda_min": lmin,
            "bounds": np.array([lo, hi])}


def _loci(plant, steps, num: int):
    """Filter poles as each step's noise is turned up: Q = sum_{i<k} Q_i + s Q_k, s in [0, 1]."""
    out = []
    acc = np.zeros((plant.n, plant.n))
    for st in steps:
        pts = []
        for s in np.linspace(0.0, 1.0, num) ** 3:  # dense near s = 0, where the poles move fastest
            Q = acc + s * st.Q
            w, V = np.linalg.eigh(0.5 * (Q + Q.T))
            Q = (V * np.maximum(w, 0.0)) @ V.T
            try:
                pts.append(filter_are(plant.replace(G=None, Q=Q + 1e-12 * np.eye(plant.n))).poles)
            except Exception:  # noqa: BLE001 - a locus point without a stabilizing solution is skipped
                continue
        out.append(np.asarray(pts))
        acc = acc + st.Q
    return out


@paper_reproduction
def reproduce(outdir: str | Path, *, quick: bool = False, progress=None) -> PaperReproduction:
    """Recompute seed 000's examples, write the figures into ``outdir``, return the table.

    Parameters
    ----------
    outdir : str or Path
        Folder for the PNG figures (created if missing).
    quick : bool
        Coarser loci and frequency grids (for tests / CI).
    progress : optdesign._progress.Progress, optional
        Told about every figure written.

    Returns
    -------
    PaperReproduction
    """
    outdir = output_dir(outdir)
    rows: list[ReproRow] = []
    num = 25 if quick else 80

    # ------------------------------------------------------------------ Example 1
    p1 = problems.load("chang_lee_1984_ex1")
    assert p1.plant is not None, "the library problem chang_lee_1984_ex1 has a plant"
    plant1 = p1.plant.replace(Q=None, G=None)
    ref1 = p1.references
    s1 = solheim(plant1, p1.targets["poles"])
    e = "Ex. 1"
    eig1 = np.sort(np.linalg.eigvals(plant1.A).real)[::-1]
    rows.append(ReproRow(e, "eigenvalues of A", "-2, -3", fmt(eig1), _close(eig1, [-2, -3], 1e-12)))
    for k, (st, pr) in enumerate(zip(s1.steps, ref1["steps_printed"], strict=True), start=1):
        rows.append(ReproRow(e, f"step {k}: move", pr["move"], f"{fmt(st.moved[0])} -> {fmt(st.placed[0])}",
                             _close(st.placed[0], -5 if k == 1 else -8, 1e-12)))
        rows.append(ReproRow(e, f"step {k}: h_jj of H_E", fmt(np.max(pr["H_E_printed"]) if k == 1 else 1.0),
                             fmt(st.H[0, 0]), _close(st.H[0, 0], 0.25 if k == 1 else 1.0, 1e-12),
                             "printed M uses -0.33 for -1/3; H_E's h11 = 0.109 is rounded (0.111)" if k == 1
                             else ""))
        rows.append(ReproRow(e, f"step {k}: q~ (eq 28)", fmt(pr["q_tilde_printed"]), fmt(st.q_tilde[0, 0]),
                             _close(st.q_tilde[0, 0], pr["q_tilde_printed"], 1e-9)))
        rows.append(ReproRow(e, f"step {k}: P~", fmt(np.max(pr["P_tilde_printed"])), fmt(st.P_tilde[0, 0]),
                             _close(st.P_tilde[0, 0], np.max(pr["P_tilde_printed"]), 1e-9)))
        rows.append(ReproRow(e, f"step {k}: K_{k} = M K~", fmt(pr["K_step_printed"]), fmt(st.K),
                             _close(st.K, pr["K_step_printed"], 1e-9)))
        rows.append(ReproRow(e, f"step {k}: A_{k}", fmt(pr["A_next_printed"]), fmt(st.A_after),
                             _close(st.A_after, pr["A_next_printed"], 1e-9)))
        rows.append(ReproRow(e, f"step {k}: Q'_{k} = M Q~ M'", fmt(pr["Q_prime_step_printed"]), fmt(st.Q),
                             _close(st.Q, pr["Q_prime_step_printed"], 1e-9)))
    rows.append(ReproRow(e, "K = K_1 + K_2", fmt(ref1["K_printed"]), fmt(s1.L),
                         _close(s1.L, ref1["K_printed"], 1e-9)))
    rows.append(ReproRow(e, "Q' = Q'_1 + Q'_2", fmt(ref1["Q_prime_printed"]), fmt(s1.Q),
                         _close(s1.Q, ref1["Q_prime_printed"], 1e-9)))
    are1 = filter_are(plant1.replace(Q=s1.Q))
    rows.append(ReproRow(e, "poles of the ARE with Q' (direct solve)", "-5, -8", fmt(are1.poles),
                         pole_error(are1.poles, [-5, -8]) < 1e-12,
                         f"P = {fmt(are1.P)} (appendix: P = P_1 + P_2)"))
    fam = example1_family()
    members = {}
    objectives: list[tuple[Literal["min_trace", "feasibility", "nearest"], NDArray[np.float64] | None]] = [
        ("min_trace", None), ("feasibility", None), ("nearest", np.eye(2))]
    for obj, Q_nominal in objectives:
        r = kalman_for_poles(plant1, p1.targets["poles"], objective=obj, Q_nominal=Q_nominal)
        members[obj] = r
        rows.append(ReproRow(e, f"SDP ({obj}{', to I' if obj == 'nearest' else ''}): P22, Q", None,
                             f"P22 = {np.nan if r.P is None else r.P[1, 1]:.6g}, Q = {fmt(r.Q)}", None,
                             f"pole error of the re-solved ARE "
                             f"{r.verification['are_resolve_poles'].value:.1e}"))
    rows.append(ReproRow(e, "family of Q (P22 free)", None,
                         f"P22 in [{fam['bounds'][0]:.5g}, {fam['bounds'][1]:.5g}]", None,
                         "the paper's member is P22 = 12; min trace is P22 = 350 - sqrt(118864)"))

    # ------------------------------------------------------------------ Example 2
    p2 = problems.load("chang_lee_1984_ex2")
    plant2, ref2 = p2.plant, p2.references
    assert plant2 is not None, "the library problem chang_lee_1984_ex2 has a plant"
    s2 = solheim(plant2, p2.targets["poles"])
    st1, st2 = s2.steps
    pr1, pr2 = ref2["steps_printed"]
    e = "Ex. 2"
    rows.append(ReproRow(e, "eigenvalues of A", "-1 +- j", fmt(np.linalg.eigvals(plant2.A)), True))
    rows.append(ReproRow(e, "step 1: H_E = T'C'R^-1CT", fmt(pr1["H_E_printed"]), fmt(st1.H),
                         _close(np.sort(np.diag(st1.H)), [0.2, 1.0], 1e-12),
                         f"our modal basis T = {fmt(st1.basis)} orders the columns the other way"))
    r2 = float(np.sort(-np.abs(st1.placed.real))[::-1][0])
    rows.append(ReproRow(e, "step 1: q~ (eq 44-45, r1 = 8)", fmt(pr1["q_tilde_printed"]),
                         fmt(st1.q_tilde[0, 0], 6), False,
                         "the printed q satisfies eq (44) with r2 = -3.98 but not eq (45)"))
    rows.append(ReproRow(e, "step 1: by-product pole r2", fmt(pr1["r2_printed"]), fmt(r2, 6), False,
                         "exact root of eq (44)-(45)"))
    T0 = np.asarray(pr1["T_printed"])
    Lam0 = np.linalg.solve(T0, plant2.A @ T0)
    CT0 = plant2.C @ T0
    Pt_paper_q = hamiltonian_are(Lam0.T, CT0.T, pr1["q_tilde_printed"] * np.eye(2),
                                 resolve_R(plant2, None, "the printed-T check"))
    rows.append(ReproRow(e, "step 1: P~ (eq 29, printed q~, printed T)", fmt(pr1["P_tilde_printed"]),
                         fmt(Pt_paper_q), False, "the printed P~ does not solve eq (29): residual 56.9"))
    rows.append(ReproRow(e, "step 1: poles of A_1", fmt(pr1["poles_next_printed"]),
                         fmt(np.sort(st1.placed.real)), False,
                         "with the printed A_1 they are -8.02, -1.87; correctly -8 and the by-product"))
    rows.append(ReproRow(e, "step 1: Q'_1 = T Q~ T'", fmt(pr1["Q_prime_step_printed"]), fmt(st1.Q), False,
                         "printed 66.354 is q~ = 66.534 with two digits transposed"))
    rows.append(ReproRow(e, "step 2: q~ (trial and error -> eq 28)", fmt(pr2["q_tilde_printed"]),
                         fmt(st2.q_tilde[0, 0], 6), None,
                         f"moves {fmt(st2.moved[0])} -> {fmt(st2.placed[0])}; q~ depends on the eigenvector "
                         "scaling (ours: largest entry 1)"))
    rows.append(ReproRow(e, "K = K_1 + K_2", fmt(ref2["K_printed"]), fmt(s2.L), False,
                         "printed K gives poles -8.027, -5.014"))
    rows.append(ReproRow(e, "Q' = Q'_1 + Q'_2", fmt(ref2["Q_prime_printed"]), fmt(s2.Q), False,
                         "the ARE with the printed Q' has poles -8.27, -15.70"))
    are2 = filter_are(plant2.replace(Q=s2.Q))
    rows.append(ReproRow(e, "poles (direct ARE solve with Q')", fmt(ref2["poles_printed"]),
                         fmt(are2.poles, 6), False,
                         f"ours: pole error {pole_error(are2.poles, [-8, -5]):.1e}"))
    are_p = filter_are(plant2.replace(Q=np.asarray(ref2["Q_prime_printed"])))
    rows.append(ReproRow(e, "ARE poles of the printed Q'", fmt(ref2["poles_printed"]), fmt(are_p.poles, 5),
                         False, "the printed Q' and K are inconsistent"))
    nlp2 = kalman_for_poles(plant2, p2.targets["poles"])
    trace2 = np.nan if nlp2.Q is None else float(np.trace(nlp2.Q))
    rows.append(ReproRow(e, "NLP (min trace over L and Q)", None, f"Q = {fmt(nlp2.Q)}, L = {fmt(nlp2.L)}",
                         None, f"trace {trace2:.5g} vs sequential {np.trace(s2.Q):.5g}; pole error "
                         f"{nlp2.verification['are_resolve_poles'].value:.1e}"))
    rows.append(ReproRow("eq (39)", "s^2 coefficient for poles -r +- j delta", "2(r^2 - delta^2)",
                         "2(delta^2 - r^2)", False,
                         "sign typo; eq (40) is right only with the corrected sign"))
    rows.append(ReproRow("eq (41)", "middle term", "q (h11 + h22)(a^2 + b^2)^2", "q (h11 + h22)(a^2 + b^2)",
                         False, "as in eq (36) and (45)"))

    figures = _double_integrator_part(fam, members, num, outdir, plant1, plant2, progress, quick, rows,
                                      s1, s2)
    return PaperReproduction(paper="000", title=_TITLE, rows=tuple(rows), figures=tuple(figures))


def _double_integrator_part(fam, members, num, outdir, plant1, plant2, progress, quick, rows, s1, s2):
    """The double integrator of issue 3 (which targets a Kalman filter can reach, the infeasible
    one's certificate) and the three figures; appends its rows to ``rows``."""
    # ------------------------------------------------------- double integrator (issue 3)
    di = {}
    for name in ("double_integrator_poles_m1_m3", "double_integrator_poles_m2pm2j",
                 "double_integrator_poles_m0p2pm3j"):
        prob = problems.load(name)
        res = kalman_for_poles(prob.plant, prob.targets["poles"])
        di[name] = (prob, res)
        tgt = ", ".join(fmt(z) for z in prob.targets["poles"][::2 if np.iscomplexobj(prob.targets["poles"])
                                                               and np.any(prob.targets["poles"].imag) else 1])
        feasible = bool(prob.references["feasible"])
        if res.success:
            txt = f"feasible, Q = {fmt(res.Q)}"
        else:
            c = res.certificate
            txt = (f"infeasible: min |T|^2 = {1 + c.min_eigenvalue:.6g} at w = {c.omega:.6g}; closest poles "
                   f"{fmt(np.sort_complex(c.closest_poles))}")
        rows.append(ReproRow("double integrator", f"target {tgt}",
                             "feasible" if feasible else "infeasible", txt, res.success == feasible,
                             "issue 3; Q11 = a1^2 - 2 a0 and Q22 = a0^2 are fixed, Q12 free"))

    figures = [_figure_family(outdir, fam, members, s1, progress),
               _figure_loci(outdir, plant1, s1, plant2, s2, num, progress),
               _figure_double_integrator(outdir, di, return_difference, quick, progress)]
    return figures


# ------------------------------------------------------------------------ figures
def _figure_family(outdir: Path, fam, members, s1, progress=None) -> Path:
    plt = pyplot()
    fig, ax = plt.subplots(1, 2, figsize=(10, 4))
    x = fam["P22"]
    ax[0].plot(x, fam["trace"], label=r"$\mathrm{trace}\,Q$")
    ax[0].plot(x, fam["q22"], "--", label="$Q_{22} = 10P_{22} - 36$")
    ax[0].plot(x, fam["q12"], ":", label="$Q_{12} = -30 - P_{22}$")
    ax[0].set_xscale("log")
    ax[0].set_xlabel("$P_{22}$ (free)")
    ax[0].set_ylabel(r"entries of $Q$ ($\mathrm{trace}\,Q$, $Q_{22}$, $Q_{12}$)")
    ax[0].set_title("Example 1: the family of $Q$ ($L = [8, -6]$)")
    ax[1].plot(x, fam["lambda_min"], color="k")
    ax[1].axhline(0, color="0.6", lw=0.8)
    ax[1].set_xscale("log")
    ax[1].set_xlabel("$P_{22}$")
    ax[1].set_ylabel("smallest eigenvalue of $Q$")
    marks = {"min trace": members["min_trace"].P[1, 1], "max min-eig": members["feasibility"].P[1, 1],
             "nearest to $I$": members["nearest"].P[1, 1], "paper (sequential)": s1.P[1, 1]}
    for (lab, v), mk in zip(marks.items(), "os^D", strict=True):
        lm = np.linalg.eigvalsh([[76, -30 - v], [-30 - v, 10 * v - 36]])[0]
        ax[1].plot([v], [lm], mk, label=f"{lab}: $P_{{22}}$ = {v:.4g}")
        ax[0].axvline(v, color="0.8", lw=0.8)
    ax[0].legend(fontsize=8)
    ax[1].legend(fontsize=8)
    return save_figure(fig, outdir / "seed000_ex1_family.png", progress=progress)


def _figure_loci(outdir: Path, plant1, s1, plant2, s2, num: int, progress=None) -> Path:
    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    for ax, plant, res, title in ((axes[0], plant1, s1, r"Example 1: $-2, -3 \to -5, -8$"),
                                  (axes[1], plant2, s2, r"Example 2: $-1 \pm j \to -8, -5$")):
        loci = _loci(plant, res.steps, num)
        for k, pts in enumerate(loci, start=1):
            if pts.size == 0:
                continue
            for j in range(pts.shape[1]):
                # earlier steps drawn wider, so a later step along the same path leaves them visible
                ax.plot(pts[:, j].real, pts[:, j].imag, "-", color=f"C{k - 1}",
                        lw=max(1.5, 6.0 - 4.0 * (k - 1)),
                        alpha=0.85, label=f"step {k} ({res.steps[k - 1].kind})" if j == 0 else None)
        eig = np.linalg.eigvals(plant.A)
        ax.plot(eig.real, eig.imag, "kx", ms=8, label="eigenvalues of $A$")
        ax.plot(res.target.real, res.target.imag, "o", mfc="none", mec="r", ms=9, label="targets")
        ax.axvline(0, color="0.7", lw=0.8)
        ax.set_xlabel(r"$\mathrm{Re}\,s$")
        ax.set_ylabel(r"$\mathrm{Im}\,s$")
        ax.set_title(title)
        ax.legend(fontsize=8)
    fig.suptitle(r"Filter poles as the noise of each sequential step is turned up "
                 r"($Q = \Sigma_i\, Q_i + s\,Q_k$)")
    return save_figure(fig, outdir / "seed000_pole_loci.png", progress=progress)


def _figure_double_integrator(outdir: Path, di, return_difference, quick: bool, progress=None) -> Path:
    plt = pyplot()
    fig, ax = plt.subplots(1, 2, figsize=(10, 4))
    w = np.logspace(-1.5, 2, 300 if quick else 1500)
    for k, (prob, res) in enumerate(di.values()):
        L = np.asarray(prob.references["L_analytic"], dtype=float)
        T = return_difference(prob.plant, L, w)[:, 0, 0]
        z = prob.targets["poles"]
        lab = ", ".join(fmt(v) for v in (z[:1] if np.any(np.asarray(z).imag) else z))
        lab += " (+ conj.)" if np.any(np.asarray(z).imag) else ""
        verdict = "feasible" if res.success else "infeasible"
        ax[0].loglog(w, np.abs(T), color=f"C{k}", label=f"{lab}: {verdict}")
        if not res.success:
            c = res.certificate
            ax[0].plot([c.omega], [np.sqrt(1 + c.min_eigenvalue)], "v", color=f"C{k}")
            ax[0].annotate(f"$|T|$ = {np.sqrt(1 + c.min_eigenvalue):.3f}\nat $\\omega$ = {c.omega:.3f}",
                           (c.omega, np.sqrt(1 + c.min_eigenvalue)), textcoords="offset points",
                           xytext=(10, -5), fontsize=8)
    ax[0].axhline(1.0, color="k", lw=0.8)
    ax[0].set_xlabel(r"$\omega$ (rad/s)")
    ax[0].set_ylabel(r"$|1 + C(j\omega I - A)^{-1}L|$")
    ax[0].set_title(r"Return difference (Kalman: $\geq 1$ for all $\omega$)")
    ax[0].legend(fontsize=8)
    # reachable pole pairs of the double integrator: damping >= 1/sqrt 2 (a1^2 >= 2 a0)
    r = np.linspace(0, 4, 2)
    ax[1].fill_between(-r, r, -r, color="0.9", label=r"reachable (damping $\geq 0.707$)")
    for k, (prob, res) in enumerate(di.values()):
        z = np.asarray(prob.targets["poles"], dtype=complex)
        ax[1].plot(z.real, z.imag, "o", color=f"C{k}", ms=7)
        if not res.success and res.certificate.closest_poles is not None:
            c = res.certificate.closest_poles
            ax[1].plot(c.real, c.imag, "s", mfc="none", color=f"C{k}", ms=8, label="closest reachable")
            for zz in z:
                cc = c[np.argmin(np.abs(c - zz))]
                ax[1].annotate("", xy=(cc.real, cc.imag), xytext=(zz.real, zz.imag),
                               arrowprops={"arrowstyle": "->", "color": f"C{k}"})
    ax[1].set_xlim(-4, 0.5)
    ax[1].set_ylim(-3.5, 3.5)
    ax[1].axvline(0, color="0.6", lw=0.8)
    ax[1].set_xlabel(r"$\mathrm{Re}\,s$")
    ax[1].set_ylabel(r"$\mathrm{Im}\,s$")
    ax[1].set_title("Targets and the reachable sector")
    ax[1].legend(fontsize=8, loc="lower left")
    return save_figure(fig, outdir / "seed000_double_integrator.png", progress=progress)
