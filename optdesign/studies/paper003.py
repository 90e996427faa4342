r"""Reproduction of seed 003 (Kim, Lee & Kim): generalized observer and output-noise rejection.

The paper's example (section 5): the third-order discrete plant ``A_D`` (T = 0.01 s),
``C = [1 0 0]``, with a step and a ``0.2 sin(2 pi t)`` output noise.  This module

* analyses the printed gains: the spectral radius of ``F = [[A - HC, -K], [MC, N]]`` for the
  step-noise gains (0.9818, Schur stable) and for the sinusoid-noise gains (1.822: **not**
  stable -- the printed gains, or their OCR, are wrong), and the printed comparison gain
  ``K_P`` (unstable as ``A - K_P C``, stable as ``A + K_P C``);
* designs stable generalized observers for both noise models (pole placement, and the
  well-conditioned NLP when available);
* checks the paper's claim that the estimates are unaffected by the noise, by simulation:
  a stable generalized observer drives ``eps = y - C xh`` to zero, so ``C xh`` follows the
  *noisy* output and ``x - xh`` does not vanish (``C (x - xh) -> -delta``).  With the printed
  step gains the estimate of state 2 keeps a bias of 3.39 times the step; with the
  ``"output"`` coupling the error is confined to the measured state 1 and states 2 and 3 are
  exact;
* compares with the noise-rejecting observer (output-disturbance model), for which
  ``xh -> x``.

Figures (``outdir``): ``seed003_fig1_state2_step.png``, ``seed003_fig2_state3_step.png``,
``seed003_fig3_state2_sinusoid.png``, ``seed003_fig4_state3_sinusoid.png`` (the paper's four
figures: estimated states 2 and 3 under step and sinusoidal noise) and
``seed003_comparison.png`` (generalized vs noise-rejecting observer, state errors and
innovation, same poles).

References
----------
Kim, H. S., Lee, C. H. & Kim, S. B., "A Study on Generalized Observer Structure and its
Characteristic of Noise Reduction" (seed 003), section 5, Fig. 1-4.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .. import problems
from ..design.generalized import (
    GeneralizedObserver,
    NoiseRejectingObserver,
    ObserverSimulation,
    default_poles,
    generalized_observer,
    noise_rejecting_observer,
    simulate_observer,
)
from ..errors import OptDesignError
from ..model.noise import NoiseModel, Sinusoid, Step
from .reproduce import PaperReproduction, ReproRow, fmt, output_dir, paper_reproduction, pyplot, save_figure

__all__ = ["reproduce", "example_cases", "STEP_LEVEL", "SINE_AMPLITUDE"]

#: Step amplitude (lost by the OCR: "delta(t) = 0..."); we use the sinusoid's amplitude.
STEP_LEVEL = 0.2
#: ``delta(t) = 0.2 sin(2 pi t)`` (printed).
SINE_AMPLITUDE = 0.2
_X0 = np.array([1.0, 0.0, 0.0])
_TITLE = "A Study on Generalized Observer Structure and its Characteristic of Noise Reduction"


def example_cases() -> dict[str, dict]:
    """The two cases of section 5: plant, noise model, printed gains (from the problem library)."""
    out = {}
    for key, name in (("step", "kim_lee_kim_step"), ("sinusoid", "kim_lee_kim_sinusoid")):
        prob = problems.load(name)
        plant = prob.plant
        assert plant is not None, f"the library problem {name} has a plant"
        noise: NoiseModel = Step() if key == "step" else Sinusoid(1.0, plant.dt)
        out[key] = dict(problem=prob, plant=plant, noise=noise,
                        H=np.asarray(prob.references["H_printed"], float),
                        K=np.asarray(prob.references["K_printed"], float),
                        K_P=np.asarray(prob.references["K_P_high_gain_printed"], float),
                        N_printed=np.asarray(prob.targets["N"], float))
    return out


def _signal(noise: NoiseModel, steps: int) -> np.ndarray:
    if isinstance(noise, Sinusoid):
        return noise.signal(steps, SINE_AMPLITUDE)
    return Step().signal(steps, STEP_LEVEL)


def _well_conditioned_rows(cases, designed, quick: bool) -> list[ReproRow]:
    """The well-conditioned NLP on the structured pair (kappa2 of F itself): the step case with the
    placed poles fixed, the sinusoid case with poles free in Disk(0, 0.97)."""
    from ..model.regions import Disk

    rows = []
    for key, c in cases.items():
        place = designed[key]["output"]
        kw = dict(poles=place.poles) if key == "step" else dict(region=Disk(0.0, 0.97))
        what = "same poles as place" if key == "step" else "poles free in Disk(0, 0.97)"
        try:
            g = generalized_observer(c["plant"], c["noise"], method="well_conditioned",
                                     starts=1 if quick else 2, seed=0, **kw)
        except (ImportError, OptDesignError) as exc:  # the NLP is unavailable or failed
            rows.append(ReproRow(key, f"well-conditioned generalized observer ({what})", None,
                                 "not available", None, f"{type(exc).__name__}: {exc}"))
            continue
        rows.append(ReproRow(
            key, f"well-conditioned ({what}): kappa2(F) vs place", None,
            f"{g.kappa2:.3g} vs {place.kappa2:.3g}", None,
            f"status {g.status}, success {g.success}, spectral radius {g.spectral_radius:.4f}, "
            f"max|H| {np.max(np.abs(g.H)):.3g}, solver time {getattr(g.solver_stats, 'time', 0.0):.0f} s"))
    return rows


@paper_reproduction
def reproduce(outdir: str | Path, *, quick: bool = False, progress=None) -> PaperReproduction:
    """Recompute seed 003's example, write its figures into ``outdir``, return the table.

    Parameters
    ----------
    outdir : str or Path
        Folder for the PNG figures (created if missing).
    quick : bool
        Shorter simulations and fewer multi-starts (for tests / CI).
    progress : optdesign._progress.Progress, optional
        Told about every figure written.

    Returns
    -------
    PaperReproduction
    """
    outdir = output_dir(outdir)
    cases = example_cases()
    steps = 600 if quick else 1000
    rows: list[ReproRow] = []
    A = cases["step"]["plant"].A
    eA = np.linalg.eigvals(A)
    rows.append(ReproRow("plant", "eigenvalues of A_D", None, fmt(eA), None,
                         f"|z| max {np.max(np.abs(eA)):.5f}: the printed A_D is (slightly) unstable; "
                         "observers do not need a stable plant"))
    # ---------------------------------------------------------------- noise polynomials
    s = cases["sinusoid"]["noise"]
    rows.append(ReproRow("step", "P(q)", "q - (OCR lost the 1)", "q - 1", True,
                         "N = 1, M = 1 (PI observer, eq (8))"))
    rows.append(ReproRow("sinusoid", "P(q) = q^2 - 2 cos(2 pi T) q + 1", "q^2 - 1.9961 q - (lost)",
                         f"q^2 - {-s.coefficients[1]:.5f} q + 1",
                         bool(abs(-s.coefficients[1] - 1.9961) < 5e-5),
                         "N printed [[0, 1], [-1, 1.9961]]; exact 2 cos(0.02 pi) used"))
    # ---------------------------------------------------------------- printed gains
    printed: dict[str, GeneralizedObserver] = {}
    for key, c in cases.items():
        g = GeneralizedObserver.from_gains(c["plant"], c["noise"], c["H"], c["K"])
        printed[key] = g
        # with the printed (rounded) N as well, to show the rounding does not matter
        F_rounded = np.block([[c["plant"].A - c["H"] @ c["plant"].C, -c["K"]],
                              [g.M @ c["plant"].C, c["N_printed"]]])
        rho_r = float(np.max(np.abs(np.linalg.eigvals(F_rounded))))
        stable = g.spectral_radius < 1.0
        rows.append(ReproRow(
            key, "spectral radius of F = [[A-HC, -K], [MC, N]], printed H, K", "< 1 (Theorem 1)",
            f"{g.spectral_radius:.5f}", stable,
            ("Schur stable; eigenvalues " + fmt(g.poles, 4)) if stable else
            f"NOT Schur stable (eigenvalues {fmt(g.poles, 4)}): the printed sinusoid gains, or their OCR, "
            f"are wrong; with the printed rounded N: {rho_r:.4f}"))
    KP = cases["step"]["K_P"]
    C = cases["step"]["plant"].C
    rho_m = float(np.max(np.abs(np.linalg.eigvals(A - KP @ C))))
    rho_p = float(np.max(np.abs(np.linalg.eigvals(A + KP @ C))))
    rows.append(ReproRow("comparison", "spectral radius of A - K_P C (printed high-gain K_P)", "< 1",
                         f"{rho_m:.4f}", False,
                         f"unstable as printed; A + K_P C has {rho_p:.4f}: the paper uses the opposite sign "
                         "(figures use L = -K_P)"))
    # analytic steady-state bias of the printed step gains (internal model: C e -> -delta)
    gs = printed["step"]
    bias = np.real(gs.error_gain(1.0)).ravel()
    rows.append(ReproRow(
        "step", "printed gains: steady state x - xh per unit step (analytic)", "0 (claim: not affected)",
        fmt(bias, 4), False,
        f"C e -> -delta (eps -> 0): x - xh -> [{bias[0]:.3g}, {bias[1]:.3g}, {bias[2]:.3g}] delta; "
        f"the estimate of state 2 is off by {abs(bias[1]):.3g} times the step"))
    # ---------------------------------------------------------------- designed observers
    designed: dict[str, dict[str, GeneralizedObserver]] = {}
    for key, c in cases.items():
        plant, noise = c["plant"], c["noise"]
        poles = default_poles(plant, noise)
        designed[key] = {cp: generalized_observer(plant, noise, poles=poles, coupling=cp)
                         for cp in ("direct", "output")}
        for cp, g in designed[key].items():
            rows.append(ReproRow(
                key, f"designed (place, {cp} coupling): spectral radius", None, f"{g.spectral_radius:.4f}",
                None, f"success {g.success}; kappa2(F) {g.kappa2:.3g}; max|H| {np.max(np.abs(g.H)):.3g}"))
    if not quick:
        rows.extend(_well_conditioned_rows(cases, designed, quick))
    # ---------------------------------------------------------------- simulations
    sims: dict[str, dict[str, tuple[GeneralizedObserver | NoiseRejectingObserver | None,
                                    ObserverSimulation]]] = {}
    for key, c in cases.items():
        plant, noise = c["plant"], c["noise"]
        delta = _signal(noise, steps)
        nr = noise_rejecting_observer(plant, noise, poles=default_poles(plant, noise))
        go_paper = printed[key] if printed[key].is_stable else designed[key]["direct"]
        sims[key] = {
            "paper": (go_paper, simulate_observer(go_paper, delta, x0=_X0)),
            "output": (designed[key]["output"], simulate_observer(designed[key]["output"], delta, x0=_X0)),
            "high_gain": (None, simulate_observer(-KP, delta, x0=_X0, plant=plant)),
            "rejecting": (nr, simulate_observer(nr, delta, x0=_X0)),
        }
        label = "printed gains" if printed[key].is_stable else "designed, direct coupling"
        sp = sims[key]["paper"][1]
        so = sims[key]["output"][1]
        sr = sims[key]["rejecting"][1]
        rows.append(ReproRow(key, f"generalized ({label}): max |eps| over the last quarter", "-> 0",
                             f"{sp.tail('eps'):.2e}", bool(sp.tail("eps") < 1e-3 * SINE_AMPLITUDE),
                             "internal model principle: C xh follows the noisy y"))
        rows.append(ReproRow(key, f"generalized ({label}): max |x - xh| per state, last quarter", "-> 0 (3a)",
                             fmt(np.max(np.abs(sp.error[-steps // 4:]), axis=0), 3), False,
                             "does not vanish: C(x - xh) -> -delta"))
        rows.append(ReproRow(key, "generalized (output coupling): max |x - xh| per state, last quarter",
                             "-> 0 (3a)", fmt(np.max(np.abs(so.error[-steps // 4:]), axis=0), 3), False,
                             "error confined to the measured state 1 (= -delta); states 2, 3 exact"))
        rows.append(ReproRow(key, "generalized: max |xi| over the last quarter", "-> 0 (3b)",
                             f"{sp.tail('internal'):.3g}", False, "xi carries the noise: persistent"))
        assert sr.noise_estimate is not None, "a noise-rejecting observer's simulation estimates the noise"
        d_err = float(np.max(np.abs(sr.noise_estimate - sr.delta)[-steps // 4:]))
        rows.append(ReproRow(key, "noise-rejecting observer: max |x - xh|, last quarter", None,
                             f"{sr.tail('error'):.2e}", None, f"x^ -> x; |delta - Gamma d^| {d_err:.1e}"))
    rows.append(ReproRow(
        "theory", "Theorem 2: F assignable iff (C, A) observable", "iff (C, A) observable", "holds", True,
        "F ~ A_a - L_a C_a, A_a = [[A, E], [0, N]], C_a = [C, 0] with free E; needs rank C = p too; "
        "the proof's eq (23) is false at the noise modes, no condition on noise vs plant modes"))
    figures = _figures(outdir, sims, printed, progress)
    return PaperReproduction(paper="seed 003 (Kim, Lee & Kim)", title=_TITLE, rows=tuple(rows),
                             figures=tuple(figures))


def _symlog(ax, level: float) -> None:
    """Symmetric-log y axis, linear within +-``level``: the transients are drawn whole (no
    clipping) and the steady state (of the size of the noise) stays readable."""
    ax.set_yscale("symlog", linthresh=level, linscale=1.5)
    ax.axhspan(-level, level, color="0.95", zorder=0)
    lo, hi = ax.get_ylim()
    top = max(abs(lo), abs(hi))
    decades = [10.0 ** k for k in range(int(np.floor(np.log10(level))) + 1, int(np.ceil(np.log10(top))) + 1)]
    ticks = sorted({0.0, level / 2, -level / 2, *decades, *(-d for d in decades)})
    ax.set_yticks([v for v in ticks if lo <= v <= hi], [f"{v:g}" for v in ticks if lo <= v <= hi])
    from matplotlib.ticker import NullLocator  # matplotlib is optional: imported when drawing

    ax.yaxis.set_minor_locator(NullLocator())


def _figures(outdir: Path, sims, printed, progress=None) -> list[Path]:
    plt = pyplot()
    out: list[Path] = []
    number = {("step", 1): 1, ("step", 2): 2, ("sinusoid", 1): 3, ("sinusoid", 2): 4}
    level = 2.0 * max(STEP_LEVEL, SINE_AMPLITUDE)
    for (key, i), fig_no in number.items():
        S = sims[key]
        t = S["paper"][1].t
        paper_label = ("generalized, printed gains" if printed[key].is_stable
                       else "generalized, designed, direct coupling (printed gains unstable)")
        fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(7.5, 6.4), sharex=True)
        ax1.plot(t, S["paper"][1].x[:, i], "k-", lw=2.2, label=f"true $x_{i + 1}$")
        styles = (("paper", paper_label, "C0-"), ("output", "generalized, output coupling", "C2--"),
                  ("high_gain", "plain observer $L=-K_P$", "C3:"), ("rejecting", "noise-rejecting", "C1-."))
        for name, lab, st in styles:
            sim = S[name][1]
            ax1.plot(t, sim.xhat[:, i], st, lw=1.2, label=lab)
            ax2.plot(t, sim.error[:, i], st, lw=1.2, label=lab)
        ax1.set_ylabel(f"$x_{i + 1}$, $\\hat x_{i + 1}$")
        ax2.axhline(0.0, color="0.6", lw=0.6)
        ax2.set_ylabel(f"$x_{i + 1} - \\hat x_{i + 1}$ (symmetric log)")
        ax2.set_xlabel("$t$ (s)")
        _symlog(ax2, level)
        noise_txt = (f"step {STEP_LEVEL:g}" if key == "step"
                     else f"${SINE_AMPLITUDE:g}\\,\\sin(2\\pi t)$")
        ax1.set_title(f"Fig. {fig_no}: estimated state {i + 1} with {key} noise ({noise_txt})", fontsize=10)
        ax2.set_title(r"generalized: $C\hat x$ follows the noisy $y$, so $x - \hat x$ does not vanish "
                      r"(printed/direct gains bias states 2-3;" "\n"
                      r"output coupling confines the error to the measured $x_1$); noise-rejecting: "
                      r"$x - \hat x \to 0$", fontsize=7.5)
        fig.legend(*ax1.get_legend_handles_labels(), loc="lower center", ncol=3, fontsize=7.5,
                   frameon=False)
        fig.tight_layout(rect=(0, 0.07, 1, 1))
        out.append(save_figure(fig, outdir / f"seed003_fig{fig_no}_state{i + 1}_{key}.png", layout=False,
                               progress=progress))
    out.append(_figure_comparison(outdir, sims, level, progress))
    return out


def _figure_comparison(outdir: Path, sims, level: float, progress=None) -> Path:
    """Side-by-side comparison, same poles: the generalized vs the noise-rejecting observer."""
    plt = pyplot()
    fig, axes = plt.subplots(2, 2, figsize=(11, 7.0), sharex=True)
    for row, key in enumerate(("step", "sinusoid")):
        for col, name in enumerate(("output", "rejecting")):
            ax = axes[row, col]
            sim = sims[key][name][1]
            for j in range(sim.x.shape[1]):
                ax.plot(sim.t, sim.error[:, j], lw=1.2, label=f"$x_{j + 1} - \\hat x_{j + 1}$")
            ax.plot(sim.t, sim.eps[:, 0], "k--", lw=1.0, label=r"$\varepsilon = y - C\hat x$")
            ax.plot(sim.t, sim.delta[:, 0], color="0.45", lw=0.8, label=r"noise $\delta$")
            ax.axhline(0.0, color="0.8", lw=0.5)
            _symlog(ax, level)
            if name == "output":
                title = (f"generalized observer, {key} noise: " r"$\varepsilon \to 0$, "
                         r"$x - \hat x \to -C^{+}\delta$" f" (tail $|e|$ = {sim.tail('error'):.2f})")
            else:
                title = (f"noise-rejecting observer, {key} noise: " r"$x - \hat x \to 0$"
                         f" (tail $|e|$ = {sim.tail('error'):.0e}), " r"$\varepsilon \to \delta$")
            ax.set_title(title, fontsize=8.5)
            if row == 1:
                ax.set_xlabel("$t$ (s)")
            if col == 0:
                ax.set_ylabel(f"{key} noise: error, innovation\n(symmetric log, linear in the grey band)",
                              fontsize=8.5)
    fig.suptitle("Seed 003: the generalized observer does not reject output noise from the state estimate; "
                 "an output-disturbance (noise-rejecting) observer does (same poles)", fontsize=9)
    fig.legend(*axes[0, 0].get_legend_handles_labels(), loc="lower center", ncol=5, fontsize=8.5,
               frameon=False)
    fig.tight_layout(rect=(0, 0.05, 1, 1))
    return save_figure(fig, outdir / "seed003_comparison.png", layout=False, progress=progress)
