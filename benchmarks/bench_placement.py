"""Well-conditioned pole placement: the eigenstructure engine against its peers, side by side in one run.

Observer form throughout (``L = place(A', C', poles)'``).  Peers, each timed in this process with
``time.process_time`` (CPU seconds, median of repeats):

* scipy ``place_poles`` YT at its defaults (``rtol=1e-3, maxiter=30``) and at the tight settings of
  ``optdesign.classical.place_observer`` (``rtol=1e-6, maxiter=100``), and KNV0 (real poles only);
* python-control ``place`` (scipy's YT) and ``place_varga`` (SLICOT SB01BD through slycot);
* the engine: ``optdesign.engines.eigenstructure_fixed.place_fixed`` (fixed poles) and
  ``optdesign.engines.eigenstructure_region.place_region`` (poles in a region);
* with ``--with-verb``, the public verb ``well_conditioned_observer`` at its defaults on a subset;
* an independent multi-start search (default on for n <= 10; ``--no-search``): scipy's L-BFGS-B from
  12 random eigenvector coordinates and the YT start, on the smooth kappa2 bound (k = 16, 4096, then
  65536: within log(n) / 65536 of kappa2), measured at the end by ``optdesign.metrics.kappa2`` --
  another optimizer, twice the starts.

Reported: kappa2, kappa_fro, eta of ``A - LC`` (``optdesign.metrics``), ``||L||_2``, the pole error
(largest relative distance to the targets), CPU time and the ratios engine / best peer, engine /
search and time / YT-tight.  Sections: 1. the pole-placement problems (KNV, Byers, scipy, SLICOT,
Byers-Nash, Chu 2007), 2. random plants n = 5..10, p = 2..4, 3. large random plants, 4. one output,
5. poles repeated beyond rank(C) (nearest distinct designs vs place_varga), 6. COMPleib in region mode,
7. a block of the DIS2 region sweep, 8. structural zeros of L (augmented Lagrangian vs the IPOPT verb),
9. state feedback in controller mode (issue 27): cond(X) of the right eigenvectors of A - B K, the
public ``place`` against scipy YT / KNV0 and python-control on every problem and the random plants
(``--sections 9 --out benchmarks/results/placement_controller.md``).

Run: ``python benchmarks/bench_placement.py [--quick] [--sections 1,2,...] [--with-verb]``; writes
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
from scipy.optimize import minimize

from optdesign import metrics, problems
from optdesign.classical.placement import pole_error
from optdesign.design.well_conditioned import naive_poles, suggested_region
from optdesign.regions import Disk, HalfPlane, Sector
from optdesign.riccati import filter_are
from optdesign.engines.eigenstructure import EigenstructureEngine
from optdesign.engines.eigenstructure_fixed import peer_start, place_fixed
from optdesign.engines.eigenstructure_region import RegionStart, place_region

HERE = Path(__file__).resolve().parent
#: the public verb's row (default settings: the engine's default starts, engine route for fixed poles)
VERB = "verb (well_conditioned_observer, defaults)"


# --------------------------------------------------------------------------- measuring


def cpu(fn, *args, repeats=3, budget=1.0, **kwargs):
    """``(fn(*args, **kwargs), median CPU seconds, note)``; fewer repeats when a call exceeds ``budget``."""
    times, out, note = [], None, ""
    for _ in range(repeats):
        t = time.process_time()
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                out = fn(*args, **kwargs)
        except Exception as exc:  # noqa: BLE001 - a peer refusing a problem is a result
            return None, time.process_time() - t, f"{type(exc).__name__}: {str(exc)[:70]}"
        times.append(time.process_time() - t)
        if times[-1] > budget:
            break
    return out, float(np.median(times)), note


def scores(A, C, L, P, basis_kappa2=None):
    """Metrics of ``A - L C``; ``basis_kappa2``: an engine's verified eigenbasis condition number,
    reported where ``metrics.kappa2`` is inf because of a (semisimple) repeated pole."""
    if L is None or not np.all(np.isfinite(L)):
        return None
    X = A - L @ C
    s = metrics.condition_summary(X)
    k2 = s["kappa2"] if (math.isfinite(s["kappa2"]) or basis_kappa2 is None) else basis_kappa2
    return {
        "kappa2": k2,
        "kappa_fro": s["kappa_fro"],
        "eta": s["eta"],
        "gain": float(np.linalg.norm(L, 2)),
        "pole_err": pole_error(np.linalg.eigvals(X), P),
    }


def scipy_gain(A, C, P, **kw):
    from scipy.signal import place_poles

    return place_poles(A.T, C.T, P, **kw).gain_matrix.T


def peers(A, C, P):
    """{name: (gain or None, CPU seconds, note)}."""
    import control

    return {
        "YT (scipy defaults)": cpu(scipy_gain, A, C, P),
        "YT (rtol 1e-6, 100 it)": cpu(scipy_gain, A, C, P, rtol=1e-6, maxiter=100),
        "KNV0": cpu(scipy_gain, A, C, P, method="KNV0"),
        "control.place": cpu(dual, control.place, A, C, P),
        "control.place_varga": cpu(dual, control.place_varga, A, C, P),
    }


def dual(place, A, C, P):
    """A state-feedback placement routine ``place(A, B, P)`` as an observer gain."""
    return np.asarray(place(A.T, C.T, P)).T


def independent_search(A, C, P, seed=1, starts=12):
    """Best metrics.kappa2 of scipy L-BFGS-B runs (smooth bound k = 16, 4096, 65536) from random
    coordinates and the YT start (its own, independent optimizer and starts)."""
    model = EigenstructureEngine(A, C).model(P)
    rng = np.random.default_rng(seed)
    X0 = [model.random_coords(rng) for _ in range(starts)]
    L0 = peer_start(A, C, model.poles, "YT")
    x = None if L0 is None else model.coords_from_gain(L0)
    if x is not None:
        X0.append(x)
    best = math.inf
    for x in X0:
        if not math.isfinite(model.evaluate(x, "kappa2", 16)[0]):
            continue
        for k in (16, 4096, 65536):
            x = minimize(
                lambda z, _k=k: model.evaluate(z, "kappa2", _k),
                x,
                jac=True,
                method="L-BFGS-B",
                options={"maxiter": 3000, "ftol": 1e-15, "gtol": 1e-12},
            ).x
        try:
            best = min(best, metrics.kappa2(A - model.design(x)[0] @ C))
        except np.linalg.LinAlgError:
            continue
    return best


def fmt(x, d=4):
    if x is None:
        return "-"
    if isinstance(x, float) and not math.isfinite(x):
        return "inf" if x > 0 else "nan"
    return f"{x:.{d}g}"


# --------------------------------------------------------------------------- fixed poles


def fixed_rows(name, A, C, P, *, search, with_verb):
    """Table rows for one fixed-pole problem and its summary entry."""
    res = peers(A, C, P)
    res["engine (place_fixed)"] = cpu(place_fixed, A, C, P)
    if with_verb:
        from optdesign import Plant, well_conditioned_observer

        res[VERB] = cpu(well_conditioned_observer, Plant(A, C), poles=P, allow_unstable=True)
    ref = independent_search(A, C, P) if search else None
    sc = {}
    for meth, (out, t, note) in res.items():
        L = getattr(out, "L", out)
        if meth.startswith("verb") and out is not None and not out.success:
            note = note or f"status {out.status}"
        basis_k2 = out.kappa2 if meth.startswith("engine") and out is not None else None
        if basis_k2 is not None and not math.isfinite(metrics.kappa2(A - L @ C)):
            note = note or "repeated pole: kappa2 of the engine's eigenbasis (not unique)"
        sc[meth] = (scores(A, C, L, P, basis_k2), t, note)
    peer_k = [v[0]["kappa2"] for m, v in sc.items() if v[0] and not m.startswith(("engine", "verb"))]
    best_peer = min(peer_k) if peer_k and math.isfinite(min(peer_k)) else None  # inf: no eigenbasis
    t_yt = sc["YT (rtol 1e-6, 100 it)"][1]
    rows = []
    for meth, (s, t, note) in sc.items():
        k = s["kappa2"] if s else None
        rows.append(
            f"| {name} | {meth} | {fmt(k, 7)} | {fmt(k / best_peer if k and best_peer else None)} | "
            f"{fmt(s['kappa_fro'] if s else None)} | {fmt(s['eta'] if s else None)} | "
            f"{fmt(s['gain'] if s else None)} | {fmt(s['pole_err'] if s else None, 2)} | {t * 1e3:.1f} | "
            f"{fmt(t / t_yt if t_yt > 0 else None, 3)} | {note} |"
        )
    eng = sc["engine (place_fixed)"][0]
    summary = None
    if eng is not None:
        summary = {
            "name": name,
            "k2": eng["kappa2"],
            "best_peer": best_peer,
            "search": ref,
            "t": sc["engine (place_fixed)"][1],
            "t_yt": t_yt,
            "t_verb": sc.get(VERB, (None, None))[1],
        }
    if ref is not None:
        rows.append(
            f"| {name} | independent search (12+1 L-BFGS-B starts) | {fmt(ref, 7)} | "
            f"{fmt(ref / best_peer if best_peer else None)} | | | | | | | |"
        )
    return rows, summary


FIXED_HEADER = [
    "| problem | method | kappa2 | / best peer | kappa_fro | eta | ‖L‖ | pole error | CPU ms | / YT tight "
    "| note |",
    "|---|---|---|---|---|---|---|---|---|---|---|",
]


def summarize(summ):
    ok = [s for s in summ if s is not None and math.isfinite(s["k2"])]
    if not ok:
        return ["(no engine results)"]
    vs_peer = [s["k2"] / s["best_peer"] for s in ok if s["best_peer"]]
    vs_search = [s["k2"] / s["search"] - 1 for s in ok if s["search"] and math.isfinite(s["search"])]
    ratio = [s["t"] / s["t_yt"] for s in ok if s["t_yt"] > 0]
    lines = [
        f"Engine kappa2 / best peer: median {np.median(vs_peer):.4f}, worst {max(vs_peer):.6f} "
        f"({sum(v > 1 + 1e-9 for v in vs_peer)} of {len(vs_peer)} worse than the best peer).",
        f"CPU engine / YT tight: median {np.median(ratio):.2f}, max {max(ratio):.1f}; median CPU engine "
        f"{np.median([s['t'] for s in ok]) * 1e3:.1f} ms vs YT tight "
        f"{np.median([s['t_yt'] for s in ok]) * 1e3:.1f} ms.",
    ]
    if vs_search:
        bad = [s["name"] for s in ok if s["search"] and s["k2"] > s["search"] * (1 + 1e-4)]
        lines.append(
            f"Engine vs independent search: worst relative excess {max(vs_search):.2e}; more than 1e-4 "
            f"above it on {len(bad)} of {len(vs_search)}" + (f" ({', '.join(bad)})" if bad else "") + "."
        )
    verb = [(s["t_verb"], s["t"], s["t_yt"]) for s in ok if s.get("t_verb")]
    if verb:
        lines.append(
            f"The public verb (the engine's default starts, its own verification and result) against "
            f"the engine alone: median CPU {np.median([a for a, _, _ in verb]):.3f} s vs "
            f"{np.median([b for _, b, _ in verb]):.3f} s ({np.median([a / b for a, b, _ in verb]):.1f}x); "
            f"verb / YT tight median {np.median([a / c for a, _, c in verb]):.2f} on these {len(verb)}.  "
            f"Before issue 13 the verb ran IPOPT: 0.27-0.35 s per problem at starts=4, 33 s for the "
            f"complex 6x6."
        )
    return lines


def random_poles(rng, n):
    n_pairs = n // 4
    re = -rng.uniform(0.5, 5.0, n - 2 * n_pairs)
    pairs = -rng.uniform(0.5, 3.0, n_pairs) + 1j * rng.uniform(0.5, 3.0, n_pairs)
    return np.concatenate([np.sort(re), np.ravel(np.column_stack([pairs, pairs.conj()]))])


def section_fixed(args, lines):
    lines += ["## 1. Pole-placement benchmark problems (fixed poles)", ""] + FIXED_HEADER
    summ = []
    verb_set = {"pp_knv1985_ex1", "pp_knv1985_ex2", "pp_byers3", "pp_byers5", "pp_scipy_test_complex_car"}
    for name in problems.names(kind="pole_placement"):
        pr = problems.load(name)
        A, C, P = pr.plant.A, pr.plant.C, np.asarray(pr.targets["poles"])
        if len(set(np.round(P, 10))) < len(P) and max(
            np.unique(np.round(P, 10), return_counts=True)[1]
        ) > np.linalg.matrix_rank(C):
            lines.append(f"| {name} | (defective request: see section 5) | | | | | | | | | |")
            continue
        rows, s = fixed_rows(
            name,
            A,
            C,
            P,
            search=args.search and A.shape[0] <= 10,
            with_verb=args.with_verb and name in verb_set,
        )
        lines += rows
        summ.append(s)
        print(f"{name}: done", file=sys.stderr, flush=True)
    lines += [""] + summarize(summ) + [""]


def section_random(args, lines):
    lines += ["## 2. Random observable plants, n = 5..10, p = 2..4 (random stable poles, n // 4 pairs)", ""]
    lines += FIXED_HEADER
    rng = np.random.default_rng(2024)
    sizes = [(5, 2), (6, 3), (8, 2), (8, 3), (10, 2), (10, 3), (10, 4)]
    summ = []
    for n, p in sizes:
        for rep in range(1 if args.quick else 2):
            plant = random_observable_plant(rng, n, p)
            P = random_poles(rng, n)
            rows, s = fixed_rows(
                f"n={n} p={p} #{rep}",
                plant.A,
                plant.C,
                P,
                search=args.search,
                with_verb=args.with_verb and rep == 0 and n <= 8,
            )
            lines += rows
            summ.append(s)
            print(f"random n={n} p={p}: done", file=sys.stderr, flush=True)
    lines += [""] + summarize(summ) + [""]


def section_large(args, lines):
    lines += [
        "## 3. Large random plants (engine default starts; YT tight for reference)",
        "",
        "| n | p | YT tight kappa2 | YT tight CPU s | engine kappa2 | engine / YT | engine CPU s | status |",
        "|---|---|---|---|---|---|---|---|",
    ]
    rng = np.random.default_rng(77)
    for n, p in [(20, 5), (30, 7)] + ([] if args.quick else [(50, 10)]):
        plant = random_observable_plant(rng, n, p)
        A, C, P = plant.A, plant.C, random_poles(rng, n)
        Ly, ty, _ = cpu(scipy_gain, A, C, P, rtol=1e-6, maxiter=100, repeats=1)
        out, te, _ = cpu(place_fixed, A, C, P, repeats=1)
        ky = metrics.kappa2(A - Ly @ C)
        ke = metrics.kappa2(A - out.L @ C)
        lines.append(
            f"| {n} | {p} | {fmt(ky)} | {ty:.2f} | {fmt(ke)} | {fmt(ke / ky)} | {te:.2f} | {out.status} |"
        )
        print(f"large n={n}: done", file=sys.stderr, flush=True)
    lines.append("")


def section_siso(args, lines):
    lines += [
        "## 4. One output: the unique gain (engine vs scipy YT)",
        "",
        "| n | YT CPU ms | engine CPU ms | engine / YT | ‖L - L_YT‖ / ‖L_YT‖ | pole error YT | "
        "pole error engine | kappa2 |",
        "|---|---|---|---|---|---|---|---|",
    ]
    rng = np.random.default_rng(5)
    for n in (3, 5, 10, 20, 50):
        plant = random_observable_plant(rng, n, 1)
        A, C, P = plant.A, plant.C, random_poles(rng, n)
        Ly, ty, _ = cpu(scipy_gain, A, C, P, rtol=1e-6, maxiter=100, repeats=7, budget=10)
        out, te, _ = cpu(place_fixed, A, C, P, repeats=7, budget=10)
        d = np.linalg.norm(out.L - Ly) / np.linalg.norm(Ly)
        ey = pole_error(np.linalg.eigvals(A - Ly @ C), P)
        ee = pole_error(np.linalg.eigvals(A - out.L @ C), P)
        lines.append(
            f"| {n} | {ty * 1e3:.2f} | {te * 1e3:.2f} | {te / ty:.2f} | {d:.1e} | {ey:.1e} | {ee:.1e} | "
            f"{fmt(out.kappa2)} |"
        )
    lines += [
        "",
        "Beyond n ~ 10 one-output placement is not computable in double precision for random poles "
        "(both pole errors are O(1)); the gains agree where the problem is well conditioned.",
        "",
    ]


def section_defective(args, lines):
    lines += [
        "## 5. Poles repeated more than rank(C) times: refused, or the nearest distinct design",
        "",
        "| problem | method | separation | kappa2 | pole error | rounding floor | CPU ms | note |",
        "|---|---|---|---|---|---|---|---|",
    ]
    import control

    rng = np.random.default_rng(11)
    pl = random_observable_plant(rng, 4, 1)
    cases = [
        (
            "pp_chowkokotovic",
            problems.load("pp_chowkokotovic").plant.A,
            problems.load("pp_chowkokotovic").plant.C,
            np.asarray(problems.load("pp_chowkokotovic").targets["poles"]),
        ),
        ("random n=4 p=1, triple pole", pl.A, pl.C, np.array([-1.0, -1.0, -1.0, -3.0])),
    ]

    def floor(L):
        return fmt(metrics.eigenvalue_rounding_floor(A - L @ C), 2) if L is not None else "-"

    for name, A, C, P in cases:
        out, t, note = cpu(place_fixed, A, C, P, repeats=1)
        lines.append(f"| {name} | engine, no separation | - | - | - | - | {t * 1e3:.1f} | {note} |")
        Lv, t, note = cpu(dual, control.place_varga, A, C, P)
        s = scores(A, C, Lv, P)
        lines.append(
            f"| {name} | control.place_varga | 0 | {fmt(s['kappa2'] if s else None)} | "
            f"{fmt(s['pole_err'] if s else None, 2)} | {floor(Lv)} | {t * 1e3:.2f} | {note} |"
        )
        for sep in (1e-1, 1e-2, 1e-3, 1e-4):
            out, t, note = cpu(place_fixed, A, C, P, separation=sep)
            s = scores(A, C, out.L, P) if out is not None else None
            lines.append(
                f"| {name} | engine, nearest distinct | {sep:g} | {fmt(out.kappa2 if out else None)} | "
                f"{fmt(s['pole_err'] if s else None, 2)} | {floor(out.L if out else None)} | "
                f"{t * 1e3:.2f} | {note} |"
            )
    lines += [
        "",
        "place_varga assigns the repeated pole as a Jordan block (kappa2 = inf, pole error "
        "~ eps^(1/m)); the engine refuses with DefectivePolesError, or with separation=s designs for the "
        "pole set spread on a circle of relative radius s (pole error = s, kappa2 ~ s^-(m-1)).  "
        "Chow-Kokotovic (entries ~1e6) is at the limit of double precision: every method misses its poles "
        "by 4-10 %, about the rounding floor of the design's eigenvalues "
        "(metrics.eigenvalue_rounding_floor).",
        "",
    ]


# --------------------------------------------------------------------------- region mode


def region_starts(plant, region):
    """scipy YT at the naive poles and the Kalman gain of Q = I, R = I (the verb's first two starts;
    the latter only where the Riccati equation is solvable accurately)."""
    n = plant.n
    out = [RegionStart("naive poles + YT", naive_poles(plant, region))]
    try:
        L_k = filter_are(plant.replace(G=np.eye(n), Q=np.eye(n) + 1e-3 * np.eye(n), R=np.eye(plant.p))).L
    except (ValueError, np.linalg.LinAlgError):
        return out
    return out + [RegionStart("Kalman gain (Q = I)", np.linalg.eigvals(plant.A - L_k @ plant.C), L_k)]


def section_region(args, lines):
    lines += [
        "## 6. COMPleib plants, poles free in a region (region mode)",
        "",
        "Region: `suggested_region(plant)` (HalfPlane(alpha) & Sector.from_damping(0.5) & Disk(0, 2 max(rho, "
        "alpha))).  Starts: scipy YT at the naive poles, the Kalman gain (Q = I), one region sample.  "
        "`verified`: every eigenvalue of the returned A - LC in the region (Region.contains, tol 1e-7 "
        "scale).",
        "",
        "| plant | n | p | kappa2 (engine) | YT @ naive | ratio | ‖L‖ | verified | CPU s |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    names = [n for n in problems.names() if n.startswith("compleib")]
    ratios, n_ok, total = [], 0, 0.0
    for name in names:
        plant = problems.load(name).plant
        region = suggested_region(plant)
        out, t, note = cpu(
            place_region,
            plant.A,
            plant.C,
            region,
            starts=region_starts(plant, region),
            n_samples=1,
            repeats=1,
        )
        total += t
        ok = False
        if out is not None and np.all(np.isfinite(out.L)):
            ev = np.linalg.eigvals(plant.A - out.L @ plant.C)
            ok = region.contains(ev, tol=1e-7 * max(1.0, float(np.max(np.abs(ev)))))
        k_naive = None
        if plant.is_observable():
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                try:
                    Ln = scipy_gain(plant.A, plant.C, naive_poles(plant, region), rtol=1e-6, maxiter=100)
                    k_naive = metrics.kappa2(plant.A - Ln @ plant.C)
                except ValueError:
                    pass
        k = out.kappa2 if (out is not None and ok) else None
        r = k / k_naive if (k and k_naive and math.isfinite(k_naive)) else None
        if r is not None:
            ratios.append((r, name))
        n_ok += ok
        verdict = "yes" if ok else "no: " + (note or str(out.status if out else ""))
        lines.append(
            f"| {name} | {plant.n} | {plant.p} | {fmt(k, 6)} | {fmt(k_naive, 6)} | {fmt(r)} | "
            f"{fmt(float(np.linalg.norm(out.L, 2)) if k else None)} | {verdict} | {t:.2f} |"
        )
        print(f"{name}: done ({t:.1f} s)", file=sys.stderr, flush=True)
    worst = max(ratios) if ratios else (math.nan, "-")
    lines += [
        "",
        f"Verified designs: {n_ok} of {len(names)}; kappa2 / (YT @ naive) where finite: median "
        f"{np.median([r for r, _ in ratios]):.3g}, worst {worst[0]:.3g} ({worst[1]}); "
        f"total CPU {total:.1f} s.",
        "",
    ]


def section_sweep(args, lines):
    lines += [
        "## 7. A block of the COMPleib DIS2 region sweep (the 40 points of benchmarks/bench_sweep.py part A)",
        "",
        "Region `HalfPlane(alpha) & Sector.from_damping(zeta) & Disk(0, 20)`, alpha = 1.78..1.85, every "
        "zeta of linspace(0.9, 0.2, 25).  One engine per plant (bases cached).  `cold`: scipy YT at the "
        "naive poles and one region sample per point; `warm`: the previous point's design (poles moved "
        "inside; the last two continuation stages), the naive start for the first point.",
        "",
        "| variant | median CPU ms/point | mean | verified | kappa2 within 0.1 % of the best "
        "| worst / best |",
        "|---|---|---|---|---|---|",
    ]
    plant = problems.load("compleib_dis2").plant
    eng = EigenstructureEngine(plant.A, plant.C)
    alphas = np.linspace(0.5, 3.0, 40)
    zetas = np.linspace(0.9, 0.2, 25)
    points = [(a, z) for a in alphas[20:21] for z in zetas] + [
        (a, z) for a in alphas[21:22] for z in zetas[:15]
    ]
    res = {}
    for variant in ("cold", "warm"):
        times, ks, prev = [], [], None
        for a, z in points:
            region = HalfPlane(a) & Sector.from_damping(z) & Disk(0.0, 20.0)
            st = [RegionStart("naive poles + YT", naive_poles(plant, region))]
            if variant == "warm" and prev is not None:
                st = [RegionStart("previous point", prev.poles, prev.L, warm=True)]
            t = time.process_time()
            out = place_region(
                None, None, region, starts=st, n_samples=1 if variant == "cold" else 0, engine=eng
            )
            times.append(time.process_time() - t)
            ev = np.linalg.eigvals(plant.A - out.L @ plant.C) if np.all(np.isfinite(out.L)) else None
            ok = ev is not None and region.contains(ev, tol=1e-7 * max(1.0, float(np.max(np.abs(ev)))))
            ks.append(out.kappa2 if ok else math.inf)
            prev = out if ok else prev
        res[variant] = (np.array(times), np.array(ks))
    best = np.minimum(res["cold"][1], res["warm"][1])
    for variant, (times, ks) in res.items():
        fin = np.isfinite(ks)
        lines.append(
            f"| {variant} | {np.median(times) * 1e3:.0f} | {np.mean(times) * 1e3:.0f} | "
            f"{fin.sum()}/{len(ks)} | "
            f"{np.sum(ks <= best * 1.001)}/{len(ks)} | {np.max(ks[fin] / best[fin]):.4f} |"
        )
    lines += [
        "",
        "Today's sweep designer (benchmarks/results/sweep.md): 225 ms/point with the NLP re-used and a cold "
        "start per point, 266 ms with warm starts.",
        "",
    ]


def section_mask(args, lines):
    lines += [
        "## 8. Structural zeros of L: the engine's augmented Lagrangian vs the IPOPT verb",
        "",
        "| problem | zeros | engine kappa2 | engine CPU s | engine status | verb kappa2 | verb CPU s | "
        "verb status |",
        "|---|---|---|---|---|---|---|---|",
    ]
    from optdesign import Plant, well_conditioned_observer

    cases = [
        ("pp_knv1985_ex2", [(0, 1), (3, 0)]),
        ("pp_byers5", [(0, 0), (4, 1), (2, 0)]),
        ("pp_scipy_test_complex_car", [(0, 0)]),
        ("pp_byers3", [(1, 0)]),
    ]
    for name, zeros in cases:
        pr = problems.load(name)
        A, C, P = pr.plant.A, pr.plant.C, pr.targets["poles"]
        mask = np.ones((A.shape[0], C.shape[0]), dtype=bool)
        for z in zeros:
            mask[z] = False
        out, te, note = cpu(place_fixed, A, C, P, gain_mask=mask, repeats=1)
        d, tv, vnote = cpu(
            well_conditioned_observer,
            Plant(A, C),
            poles=P,
            gain_mask=mask,
            starts=4,
            allow_unstable=True,
            repeats=1,
        )
        lines.append(
            f"| {name} | {zeros} | {fmt(out.kappa2 if out else None, 7)} | {te:.2f} | "
            f"{out.status if out else note} | {fmt(d.kappa2 if d else None, 7)} | {tv:.2f} | "
            f"{(d.status if d.success else 'not verified') if d else vnote} |"
        )
    lines.append("")


# --------------------------------------------------------------------------- 9. state feedback, controller mode


def cond_x(F, X=None):
    """cond(X) of the unit-column right eigenvectors of F (``X`` given: that basis, normalized)."""
    if X is None:
        _, X = np.linalg.eig(F)
    X = np.asarray(X, dtype=complex)
    X = X / np.linalg.norm(X, axis=0)
    return float(np.linalg.cond(X))


def controller_rows(name, A, B, P):
    """Rows of one state-feedback problem ``eig(A - B K) = P``: cond(X) of every method."""
    import control
    from scipy.signal import place_poles

    from optdesign.design.feedback import place

    def scipy_fsf(**kw):
        return place_poles(A, B, P, **kw)

    runs = {
        "scipy YT (defaults)": cpu(scipy_fsf),
        "scipy YT (rtol 1e-6, 100 it)": cpu(scipy_fsf, rtol=1e-6, maxiter=100),
        "scipy KNV0": cpu(scipy_fsf, method="KNV0"),
        "control.place": cpu(control.place, A, B, P),
        "control.place_varga": cpu(control.place_varga, A, B, P),
        "dual measure (place_fixed on (A', B'), before)": cpu(place_fixed, A.T, B.T, P),
        "optdesign place (controller mode)": cpu(place, A, B, P),
    }
    vals = {}
    for meth, (out, t, note) in runs.items():
        if out is None:
            vals[meth] = (None, t, note)
            continue
        if meth.startswith("scipy"):
            K, k = out.gain_matrix, cond_x(A - B @ out.gain_matrix, out.X)
        elif meth.startswith("dual"):
            K = out.L.T
            k = cond_x(A - B @ K)
        elif meth.startswith("optdesign"):
            K, k = out.gain_matrix, out.kappa2
            note = note or ("" if out.success else f"status {out.status}")
        else:
            K = np.asarray(out)
            k = cond_x(A - B @ K)
        err = pole_error(np.linalg.eigvals(A - B @ K), P)
        if err > 1e-6:
            note = (note + "; " if note else "") + f"pole error {err:.1e}"
            k = math.inf if err > 1e-3 else k
        vals[meth] = (k, t, note)
    peers_k = [v[0] for m, v in vals.items() if v[0] is not None and not m.startswith(("optdesign", "dual"))]
    best = min(peers_k) if peers_k else None
    rows = []
    for meth, (k, t, note) in vals.items():
        ratio = k / best if k is not None and best and math.isfinite(best) and math.isfinite(k) else None
        rows.append(f"| {name} | {meth} | {fmt(k, 7)} | {fmt(ratio)} | {t * 1e3:.1f} | {note} |")
    ours = vals["optdesign place (controller mode)"][0]
    return rows, (name, ours, best, vals["dual measure (place_fixed on (A', B'), before)"][0])


CONTROLLER_HEADER = ["| problem | method | cond(X) | / best peer | CPU ms | note |", "|---|---|---|---|---|---|"]


def section_controller(args, lines):
    lines += [
        "## 9. State feedback in controller mode: cond(X) of the right eigenvectors of A - B K",
        "",
        "Each pole-placement problem in its source's state-feedback form (A, B) = (A', C') of the stored "
        "observer form, and the random plants of section 2 transposed the same way.  cond(X): unit-column "
        "right eigenvectors of A - B K (scipy's X, normalized, for scipy; numpy's eigenvectors for "
        "python-control and the dual-measure row; optdesign's verified basis for ours, which matters only "
        "at a semisimple repeated pole, where numpy's basis is arbitrary).  `dual measure`: the engine as "
        "`place` ran it before issue 27 (minimizing the left eigenvectors' condition).  `/ best peer`: "
        "over scipy YT (both settings), KNV0, control.place and place_varga.  A pole error above 1e-3 "
        "counts as inf.",
        "",
    ] + CONTROLLER_HEADER
    summ = []
    for name in problems.names(kind="pole_placement"):
        pr = problems.load(name)
        A, C, P = pr.plant.A, pr.plant.C, np.asarray(pr.targets["poles"])
        rows, s = controller_rows(name, A.T, C.T, P)
        lines += rows
        summ.append(s)
        print(f"controller {name}: done", file=sys.stderr, flush=True)
    rng = np.random.default_rng(2024)     # the plants and poles of section 2
    sizes = [(5, 2), (6, 3), (8, 2), (8, 3), (10, 2), (10, 3), (10, 4)]
    for n, p in sizes:
        for rep in range(1 if args.quick else 2):
            plant = random_observable_plant(rng, n, p)
            P = random_poles(rng, n)
            rows, s = controller_rows(f"random n={n} m={p} #{rep}", plant.A.T, plant.C.T, P)
            lines += rows
            summ.append(s)
    ok = [(nm, o, b, d) for nm, o, b, d in summ if o is not None and b is not None and math.isfinite(b)]
    worse = [nm for nm, o, b, _ in ok if o > b * (1 + 1e-9)]
    ratios = [o / b for _, o, b, _ in ok]
    dual_worse = [nm for nm, _, b, d in ok if d is not None and d > b * (1 + 1e-9)]
    inf_rows = [nm for nm, o, b, _ in summ if o is not None and not math.isfinite(o)]
    lines += [
        "",
        f"optdesign place (controller mode) cond(X) / best peer over {len(ok)} problems with a finite best "
        f"peer: median {np.median(ratios):.4f}, worst {max(ratios):.6f}; worse than the best peer on "
        f"{len(worse)}" + (f" ({', '.join(worse)})" if worse else "") + ".  The dual measure (before) was "
        f"worse than the best peer on {len(dual_worse)}" + (f" ({', '.join(dual_worse)})" if dual_worse else "")
        + "." + (f"  Defective requests (rank(B) = 1, repeated pole; Ackermann, cond(X) = inf for every "
                 f"method): {', '.join(inf_rows)}." if inf_rows else ""),
        "",
    ]


SECTIONS = {
    "9": section_controller,
    "8": section_mask,
    "1": section_fixed,
    "2": section_random,
    "3": section_large,
    "4": section_siso,
    "5": section_defective,
    "6": section_region,
    "7": section_sweep,
}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer random plants, no n = 50")
    ap.add_argument("--sections", default="1,2,3,4,5,6,7,8,9")
    ap.add_argument("--no-search", dest="search", action="store_false", help="skip the independent search")
    ap.add_argument("--with-verb", action="store_true", help="time the public verb (defaults) on a subset")
    ap.add_argument("--out", default=str(HERE / "results" / "placement.md"))
    args = ap.parse_args(argv)
    lines = [
        "# Well-conditioned pole placement: the eigenstructure engine vs scipy / python-control",
        "",
        "Generated by `benchmarks/bench_placement.py "
        + " ".join(argv if argv is not None else sys.argv[1:])
        + "`.  CPU seconds by `time.process_time` (medians of up to 3 repeats) on the shared machine; "
        "`/ best peer`: kappa2 over the best of scipy YT (defaults and tight), KNV0, python-control place "
        "and "
        "place_varga; `/ YT tight`: CPU over scipy YT with rtol 1e-6, maxiter 100.",
        "",
    ]
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    for key in args.sections.split(","):
        SECTIONS[key.strip()](args, lines)
        out.write_text("\n".join(lines) + "\n", encoding="utf-8")  # after every section: nothing lost
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
