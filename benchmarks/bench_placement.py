"""Well-conditioned pole placement against the peers, side by side in one run.

Peers (observer form: ``L = place(A', C', poles)'``):

* ``scipy.signal.place_poles`` with ``method="YT"`` (Tits-Yang) and ``"KNV0"`` (Kautsky-Nichols-
  Van Dooren; real poles only);
* python-control ``place`` (scipy's YT underneath) and ``place_varga`` (SLICOT SB01BD through
  slycot; reported as n/a when slycot is not installed);
* ``optdesign.well_conditioned_observer(plant, poles=...)`` (this library; kappa2 minimized by
  an NLP, multi-start from YT/KNV0/random parametric assignments).

Measured for every method: kappa2 and eta of ``A - LC`` (``optdesign.metrics``), ``||L||_2`` and
wall time; ratios ``optdesign / YT``.  Sets:

1. the pole-placement benchmark problems of ``problems/poleplacement`` (KNV 1985 Ex 1-2, Byers
   3-6, scipy's test cases, SLICOT SB01BD; Chow-Kokotovic asks for a double pole with one output,
   which no diagonalizable design can meet);
2. random observable plants, ``n = 3 .. 40``, ``p = max(2, n // 4)``, random stable poles;
3. the COMPleib plants of ``problems/compleib`` in region mode (poles free in ``Re s <= -alpha``,
   damping >= 0.5, ``|s| <= R``; ``alpha`` = 1.5 x the slowest open-loop decay): kappa2 of the
   design next to YT at the optimizer's poles and YT at a naive choice (the open-loop poles moved
   into the region: ``optdesign.design.well_conditioned.naive_poles``).

Run: ``python benchmarks/bench_placement.py [--quick] [--skip-compleib]``; writes
``benchmarks/results/placement.md``.  Numbers, not pass/fail.
"""

from __future__ import annotations

# isort: off
from _common import random_observable_plant  # first: single-threaded BLAS before numpy
# isort: on

import argparse
import math
import sys
import time
import warnings
from pathlib import Path

import numpy as np

from optdesign import metrics, problems, well_conditioned_observer
from optdesign.design.well_conditioned import naive_poles, suggested_region

HERE = Path(__file__).resolve().parent


def _metrics(plant, L):
    if L is None:
        return None
    X = plant.A - L @ plant.C
    return {"kappa2": metrics.kappa2(X), "eta": metrics.eta(X), "gain": float(np.linalg.norm(L, 2))}


def _timed(fn):
    t = time.perf_counter()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            out = fn()
    except Exception as exc:  # noqa: BLE001 - a peer refusing a problem is a result, not a crash
        return None, time.perf_counter() - t, f"{type(exc).__name__}: {str(exc)[:60]}"
    return out, time.perf_counter() - t, ""


def scipy_gain(plant, poles, method="YT"):
    """scipy's ``place_poles`` on the dual: the observer gain (n, p)."""
    from scipy.signal import place_poles

    return place_poles(plant.A.T, plant.C.T, poles, method=method).gain_matrix.T


def peers(plant, poles):
    """{method: (L or None, seconds, note)} for the peer methods."""
    out = {}
    for m in ("YT", "KNV0"):
        out[f"scipy {m}"] = _timed(lambda m=m: scipy_gain(plant, poles, m))
    try:
        import control
    except ImportError:
        out["control.place"] = (None, 0.0, "python-control not installed")
        out["control.place_varga"] = (None, 0.0, "python-control not installed")
        return out
    out["control.place"] = _timed(lambda: np.asarray(control.place(plant.A.T, plant.C.T, poles)).T)
    try:
        import slycot  # noqa: F401

        out["control.place_varga"] = _timed(
            lambda: np.asarray(control.place_varga(plant.A.T, plant.C.T, poles)).T
        )
    except ImportError:
        out["control.place_varga"] = (None, 0.0, "n/a: slycot not installed")
    return out


def fmt(x, d=4):
    if x is None:
        return "-"
    if isinstance(x, float) and (math.isinf(x) or math.isnan(x)):
        return "inf" if math.isinf(x) else "nan"
    return f"{x:.{d}g}"


def bench_problem(name, plant, poles, starts):
    res = peers(plant, poles)
    # pole assignment as the peers do it: Byers 6 (a state-feedback benchmark) assigns unstable poles
    res["optdesign"] = _timed(
        lambda: well_conditioned_observer(plant, poles=poles, starts=starts, allow_unstable=True)
    )
    rows = []
    ref = None
    for meth, (out, t, note) in res.items():
        if meth == "optdesign" and out is not None:
            d = out
            m = {"kappa2": d.kappa2, "eta": d.eta, "gain": d.gain_norm} if d.success else None
            note = note or ("" if d.success else f"status {d.status}: {d.message[:60]}")
        else:
            m = _metrics(plant, out)
        if meth == "scipy YT" and m is not None:
            ref = m["kappa2"]
        rows.append((name, meth, m, t, note))
    return rows, ref


def random_poles(rng, n):
    n_pairs = n // 4
    re = -rng.uniform(0.5, 5.0, n - 2 * n_pairs)
    pairs = -rng.uniform(0.5, 3.0, n_pairs) + 1j * rng.uniform(0.5, 3.0, n_pairs)
    return np.concatenate([np.sort(re), np.ravel(np.column_stack([pairs, pairs.conj()]))])



def yt_kappa(plant, poles):
    """kappa2 of scipy YT at these poles, or None when YT refuses them."""
    m = _metrics(plant, _timed(lambda: scipy_gain(plant, poles))[0])
    return None if m is None else m["kappa2"]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer sizes and starts")
    ap.add_argument("--skip-compleib", action="store_true")
    ap.add_argument("--sizes", default=None, help="comma-separated n for random plants")
    ap.add_argument("--out", default=str(HERE / "results" / "placement.md"))
    ap.add_argument("--note", default="", help="a sentence added to the report header")
    args = ap.parse_args(argv)
    lines = [
        "# Well-conditioned pole placement vs scipy / python-control",
        "",
        "Generated by `benchmarks/bench_placement.py`" + (" --quick" if args.quick else "") + ".  "
        "kappa2 / eta of `A - LC` by `optdesign.metrics`, `||L||_2`, wall time in seconds "
        "(shared 2-core machine: times are indicative).  `ratio` = kappa2 / kappa2(scipy YT).",
        "",
    ]
    if args.sizes:
        sizes_note = f"Random plant sizes given on the command line: n = {args.sizes}.  {args.note}"
        lines += [sizes_note.rstrip(), ""]
    elif args.note:
        lines += [args.note, ""]

    # 1. benchmark problems
    lines += [
        "## 1. Pole-placement benchmark problems (fixed poles)",
        "",
        "| problem | method | kappa2 | ratio | eta | ‖L‖ | time | note |",
        "|---|---|---|---|---|---|---|---|",
    ]
    summary = []
    for name in problems.names(kind="pole_placement"):
        pr = problems.load(name)
        plant, P = pr.plant, pr.targets["poles"]
        rows, ref = bench_problem(name, plant, P, starts=2 if args.quick else 4)
        for nm, meth, m, t, note in rows:
            k = m["kappa2"] if m else None
            ratio = (k / ref) if (k is not None and ref) else None
            lines.append(
                f"| {nm} | {meth} | {fmt(k, 6)} | {fmt(ratio)} | {fmt(m['eta'] if m else None)} | "
                f"{fmt(m['gain'] if m else None)} | {t:.3f} | {note} |"
            )
            if meth == "optdesign" and ratio is not None:
                summary.append((nm, ratio))
        print(f"{name}: done", file=sys.stderr)
    if summary:
        better5 = sum(1 for _, r in summary if r <= 0.95)
        lines += [
            "",
            f"optdesign / YT kappa2 ratio: median {np.median([r for _, r in summary]):.3f}, "
            f"max {max(r for _, r in summary):.4f}; >= 5 % lower on {better5} of {len(summary)} "
            f"problems YT solves.",
            "",
        ]

    # 2. random plants
    sizes = (
        [int(s) for s in args.sizes.split(",")]
        if args.sizes
        else ([3, 5, 10, 20] if args.quick else [3, 5, 8, 10, 15, 20, 30, 40])
    )
    lines += [
        "## 2. Random observable plants (fixed random stable poles)",
        "",
        "| n | p | method | kappa2 | ratio | eta | ‖L‖ | time | note |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    rng = np.random.default_rng(2024)
    for n in sizes:
        p = max(2, n // 4)
        plant = random_observable_plant(rng, n, p)
        P = random_poles(rng, n)
        starts = 2 if n <= 10 else 1
        rows, ref = bench_problem(f"n={n}", plant, P, starts=starts)
        for _, meth, m, t, note in rows:
            k = m["kappa2"] if m else None
            ratio = (k / ref) if (k is not None and ref) else None
            lines.append(
                f"| {n} | {p} | {meth} | {fmt(k, 6)} | {fmt(ratio)} | {fmt(m['eta'] if m else None)} | "
                f"{fmt(m['gain'] if m else None)} | {t:.2f} | {note} |"
            )
        print(f"random n={n}: done", file=sys.stderr)
    lines.append("")

    # 3. COMPleib region mode
    if not args.skip_compleib:
        lines += [
            "## 3. COMPleib plants, poles free in a region (region mode)",
            "",
            "Region: `HalfPlane(alpha) & Sector.from_damping(0.5) & Disk(0, 2 max(rho(A), alpha))`, "
            "alpha = 1.5 x the slowest open-loop decay (at least 1 % of rho(A); below an unobservable "
            "mode's decay).  `YT @ opt poles`: scipy YT at the optimizer's poles; `YT @ naive`: scipy YT "
            "at the open-loop poles moved into the region.",
            "",
            "| plant | n | p | alpha | kappa2 (optdesign) | YT @ opt poles | YT @ naive | ratio to naive | "
            "‖L‖ | max Re | status | starts ok | time |",
            "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
        ]
        names = [n for n in problems.names() if n.startswith("compleib")]
        n_verified, ratios, total_t = 0, [], 0.0
        for name in names:
            plant = problems.load(name).plant
            region = suggested_region(plant)
            t = time.perf_counter()
            d = well_conditioned_observer(plant, region=region, starts=2)
            t = time.perf_counter() - t
            k_opt = yt_kappa(plant, d.poles) if plant.is_observable() and d.success else None
            k_naive = yt_kappa(plant, naive_poles(plant, region)) if plant.is_observable() else None
            finite = bool(k_naive) and math.isfinite(k_naive)
            ratio = d.kappa2 / k_naive if (d.verification.passed and finite) else None
            n_verified += bool(d.verification.passed)
            total_t += t
            if ratio is not None:
                ratios.append((ratio, name))
            alpha = region.members[0].alpha
            lines.append(
                f"| {name} | {plant.n} | {plant.p} | {alpha:.3g} | {fmt(d.kappa2, 6)} | {fmt(k_opt, 6)} | "
                f"{fmt(k_naive, 6)} | {fmt(ratio)} | {fmt(d.gain_norm)} | "
                f"{fmt(float(np.max(d.poles.real)))} | {d.status}"
                f"{'' if d.verification.passed else ' (not verified)'} | {d.n_converged}/{len(d.starts)} | "
                f"{t:.1f} |"
            )
            print(f"{name}: {d!r} ({t:.1f} s)", file=sys.stderr)
        worst = max(ratios) if ratios else None
        lines += [
            "",
            f"Verified designs: {n_verified} of {len(names)}; kappa2 / (YT @ naive) over the plants where "
            f"YT at the naive poles is finite: median {np.median([r for r, _ in ratios]):.3g}, worst "
            f"{worst[0]:.3g} ({worst[1]}); total time {total_t:.0f} s (starts=2)."
            if ratios
            else f"Verified designs: {n_verified} of {len(names)}.",
        ]
        lines.append("")
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text("\n".join(lines) + "\n", encoding="utf-8")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
