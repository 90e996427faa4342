"""The seed 001 aircraft pitch observer made robust: one gain for +-20 % on the aerodynamic coefficients.

Seed 001 (Jung & Huh), Example 3: the aircraft pitch model of Messner & Tilbury, measured pitch
angle.  ``examples/seed001_well_conditioned.py`` redesigns the paper's observer for the nominal
model (min kappa2, poles in ``Re s <= -decay`` of the paper's gain, ``||L|| <= ||L_paper||``).  Here
the three aerodynamic coefficients ``A[0,0], A[1,0], A[1,1]`` (-0.313, -0.0139, -0.426) vary by
+-20 % each; the plant is affine in them, so the 8 corners (and the nominal model) span a polytope
of plants that contains every combination.  Three gains are compared on the whole set:

* the nominal design (what a user who ignores the uncertainty gets),
* the LMI gain (common Lyapunov matrix: a certificate for the whole polytope),
* the NLP gain (worst-case kappa2 over the models, from the LMI gain and the per-model designs).

The noise model is a modelling choice (the seed gives none): unit-intensity process noise on every
state and unit measurement noise, for the H2 numbers.

Run (headless; figures go to the build folder ``examples/_build/``, or ``$OPTDESIGN_EXAMPLES_OUT``)::

    python examples/robust_aircraft.py [--quick]

Writes ``robust_aircraft_poles.png`` (the pole clouds of all models and of 300 random plants of the
polytope against the region, for each gain) and ``robust_aircraft_study.png`` (worst-case kappa2
and H2 against the uncertainty size; the Pareto front of worst-case H2 against worst-case kappa2).
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

import numpy as np

from optdesign import problems
from optdesign.design.robust import evaluate_gain, robust_observer
from optdesign.design.robust_lmi import robust_lmi_observer
from optdesign.model.model_set import ModelSet
from optdesign.regions import HalfPlane
from optdesign.studies.reproduce import output_dir, pyplot, save_figure

AERO = [(0, 0), (1, 0), (1, 1)]


def setup(size: float = 0.2):
    ex = problems.load("jung_huh_ex3")
    L_paper = np.asarray(ex.references["cases_printed"][0]["L"], dtype=float).reshape(3, 1)
    plant = ex.plant.replace(Q=np.eye(3), R=[[1.0]], name="aircraft pitch")
    decay = -float(np.max(np.linalg.eigvals(plant.A - L_paper @ plant.C).real))
    region = HalfPlane(decay)
    return plant, region, float(np.linalg.norm(L_paper, 2)), ModelSet.vary(plant, AERO, size)


def row(name: str, ms: ModelSet, L, region, seconds: float) -> dict:
    mm, ver, dense = evaluate_gain(ms, L, region=region, dense_points=300, seed=1)
    out = int(np.sum(mm.margin > 0))
    print(
        f"{name:<28} {mm.worst('kappa2'):>10.4g} {mm.worst('h2'):>9.4g} {out:>4d}/{len(ms)} "
        f"{dense.in_region:>4d}/{dense.count}  {seconds:6.2f} s"
    )
    return {"L": L, "mm": mm, "dense": dense}


def pole_figure(ms: ModelSet, region, designs: dict, outdir: Path) -> Path:
    """Top row: every pole; bottom row: zoom on the slow real pole at the region's boundary."""
    plt = pyplot()
    cloud = ms.interior_points(300, 1)
    fig, axes = plt.subplots(2, len(designs), figsize=(4.2 * len(designs), 7.0))
    edge = -region.alpha
    for col, (name, d) in enumerate(designs.items()):
        L = d["L"]
        pts = np.concatenate([np.linalg.eigvals(pl.A - L @ pl.C) for pl in cloud])
        verts = np.concatenate([np.linalg.eigvals(pl.A - L @ pl.C) for pl in ms])
        allp = np.concatenate([pts, verts])
        slow = allp[np.abs(allp.imag) < 1e-9].real
        zoom = (min(float(slow.min()), edge) - 0.03, max(float(slow.max()), edge) + 0.03)
        full = (min(float(allp.real.min()), edge) * 1.15 - 0.5, 0.5)
        for row, (xr, yr) in enumerate(
            [(full, max(1.0, float(np.abs(allp.imag).max()) * 1.15)), (zoom, 0.05)]
        ):
            ax = axes[row, col]
            ax.axvspan(xr[0], edge, color="tab:green", alpha=0.10,
                       label=r"region $\mathrm{Re}\,s \leq -$decay")
            ax.axvline(edge, color="tab:green", lw=1)
            ax.plot(pts.real, pts.imag, ".", ms=2, color="0.55", label="300 random plants of the polytope")
            ax.plot(verts.real, verts.imag, "x", ms=6, color="tab:red", label="the 9 models")
            ax.set_xlim(*xr)
            ax.set_ylim(-yr, yr)
            ax.grid(alpha=0.3)
            ax.set_xlabel(r"$\mathrm{Re}\,s$")
        axes[0, col].set_title(
            f"{name}: worst $\\kappa_2$ = {d['mm'].worst('kappa2'):.3g}\n"
            f"{d['dense'].in_region}/{d['dense'].count} random plants in the region",
            fontsize=9,
        )
        axes[1, col].set_title("zoom: the slow real pole", fontsize=9)
    axes[0, 0].set_ylabel(r"$\mathrm{Im}\,s$")
    axes[1, 0].set_ylabel(r"$\mathrm{Im}\,s$")
    # one legend for all panels, below them: inside a panel it covered the fast poles
    fig.legend(*axes[0, 0].get_legend_handles_labels(), loc="lower center", ncol=3, fontsize=8, frameon=False)
    fig.suptitle(
        r"Seed 001 aircraft pitch observer, $\pm$20 % on the aerodynamic coefficients: poles of $A - LC$",
        fontsize=10,
    )
    fig.tight_layout(rect=(0, 0.04, 1, 1))
    return save_figure(fig, outdir / "robust_aircraft_poles.png", layout=False, overwrite=True)


def study(plant, region, max_gain, sizes, h2_fracs, outdir: Path) -> Path:
    """Worst-case kappa2 / H2 against the uncertainty size; Pareto front H2 vs kappa2 at +-20 %."""
    plt = pyplot()
    rows = []
    print("\nuncertainty sweep (+-k % on the three aerodynamic coefficients)")
    print(f"{'k %':>5} {'LMI kappa2':>11} {'NLP kappa2':>11} {'NLP H2':>9} {'certified':>10}")
    for k in sizes:
        ms = ModelSet.vary(plant, AERO, k)
        lmi = robust_lmi_observer(ms, region=region, max_gain=max_gain, dense_points=0)
        nlp = robust_observer(
            ms, region=region, max_gain=max_gain, per_model_starts=False, starts=1, dense_points=0
        )
        rows.append((k, lmi.worst_kappa2, nlp.worst_kappa2, nlp.worst_h2))
        print(
            f"{100 * k:5.0f} {lmi.worst_kappa2:11.4g} {nlp.worst_kappa2:11.4g} {nlp.worst_h2:9.4g} "
            f"{str(nlp.certified):>10}"
        )
    ms = ModelSet.vary(plant, AERO, 0.2)
    free = robust_observer(ms, region=region, max_gain=max_gain, per_model_starts=False, dense_points=0)
    h2opt = robust_observer(
        ms, region=region, max_gain=max_gain, objective="h2", per_model_starts=False, dense_points=0
    )
    front = [(h2opt.worst_h2, h2opt.worst_kappa2), (free.worst_h2, free.worst_kappa2)]
    print("\nPareto front at +-20 %: min worst-case kappa2 s.t. worst-case H2 <= h")
    for f in h2_fracs:
        h = h2opt.worst_h2 + f * (free.worst_h2 - h2opt.worst_h2)
        d = robust_observer(
            ms, region=region, max_gain=max_gain, h2_max=h, per_model_starts=False, dense_points=0
        )
        if d.success:
            front.append((d.worst_h2, d.worst_kappa2))
        print(f"  h = {h:8.4g}: {d.status}, worst kappa2 {d.worst_kappa2:.4g}, worst H2 {d.worst_h2:.4g}")
    front.sort()
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(9.5, 3.8))
    r = np.array(rows)
    a1.plot(100 * r[:, 0], r[:, 1], "s--", label=r"LMI worst $\kappa_2$")
    a1.plot(100 * r[:, 0], r[:, 2], "o-", label=r"NLP worst $\kappa_2$")
    a1.set_xlabel(r"uncertainty $\pm k$ % (three aerodynamic coefficients)")
    a1.set_ylabel(r"worst-case $\kappa_2$")
    ax2 = a1.twinx()
    ax2.plot(100 * r[:, 0], r[:, 3], "^:", color="tab:green", label=r"NLP worst $H_2$")
    ax2.set_ylabel(r"worst-case $H_2$ (NLP gain)")
    a1.legend(fontsize=8, loc="upper left")
    ax2.legend(fontsize=8, loc="lower right")
    a1.grid(alpha=0.3)
    fr = np.array(front)
    a2.plot(fr[:, 0], fr[:, 1], "o-")
    a2.set_xlabel(r"worst-case $H_2$ of the estimation error")
    a2.set_ylabel(r"worst-case $\kappa_2$")
    a2.set_title(r"Pareto front at $\pm$20 % (min $\kappa_2$ s.t. $H_2 \leq h$)", fontsize=9)
    a2.grid(alpha=0.3)
    return save_figure(fig, outdir / "robust_aircraft_study.png", overwrite=True)


def main(quick: bool = False) -> None:
    np.set_printoptions(precision=4, suppress=True)
    # the build folder: $OPTDESIGN_EXAMPLES_OUT, else examples/_build/ (never beside the sources)
    outdir = output_dir(os.environ.get("OPTDESIGN_EXAMPLES_OUT") or Path(__file__).parent / "_build")
    plant, region, max_gain, ms = setup()
    print(f"{ms!r}; region {region!r}, ||L|| <= {max_gain:.4g}")
    print(f"{'gain':<28} {'kappa2':>10} {'H2':>9} {'out':>6} {'dense in':>9}  time")
    t0 = time.process_time()
    nominal = robust_observer(ModelSet([ms[ms.nominal]]), region=region, max_gain=max_gain, dense_points=0)
    designs = {"nominal design": row("nominal design", ms, nominal.L, region, time.process_time() - t0)}
    t0 = time.process_time()
    lmi = robust_lmi_observer(ms, region=region, max_gain=max_gain)
    designs["LMI"] = row("LMI (common P)", ms, lmi.L, region, time.process_time() - t0)
    t0 = time.process_time()
    nlp = robust_observer(ms, region=region, max_gain=max_gain)
    designs["NLP"] = row("NLP (worst-case kappa2)", ms, nlp.L, region, time.process_time() - t0)
    print(
        f"\nper-model designs (each model alone): worst {max(nlp.extra['per_model']):.4g}, "
        f"best {min(nlp.extra['per_model']):.4g}"
    )
    print("LMI:", lmi.message)
    print("NLP:", nlp.message)
    print("\n" + nlp.summary())
    figs = [pole_figure(ms, region, designs, outdir)]
    sizes = (0.0, 0.1, 0.2, 0.3) if quick else (0.0, 0.05, 0.1, 0.15, 0.2, 0.25, 0.3)
    figs.append(study(plant, region, max_gain, sizes, (0.5,) if quick else (0.15, 0.35, 0.6, 0.85), outdir))
    print("figures:", *[str(f) for f in figs], sep="\n  ")


if __name__ == "__main__":
    main(quick="--quick" in sys.argv[1:])
