"""Benchmark: the Riccati differential equation (issues 5, 11, 14, 26; seed 004) -- the engines of
``optdesign.riccati_de`` against hand-written minimal references, side by side in one process.

Part 1 (issue 26), on issue 26's plants (``A = randn(n, n)/sqrt(n)``, seed 26, ``C = randn(3, n)``,
W = I, R = I, P0 = I), n = 10, 50, 100, horizons 1, 10, 1000 s, 101 output times; CPU time
(``time.process_time``), median of ``--reps`` interleaved runs; error = ``max_k ||P_k - P_ref(t_k)||_F /
max_k ||P_ref(t_k)||_F`` against the exact flow recomputed by doubling from a 32x shorter base step:

* ``restarted expm`` -- one ``E = expm(M d)``, then ``P <- (E21 + E22 P)(E11 + E12 P)^-1`` every step
                        ``d = Delta / s``; the smallest ``s = 2^k`` reaching the transition method's error;
* ``transition``     -- ``riccati_de`` at its defaults (no post-processing since issue 26), and with
                        ``estimate_error=True, steady_state=True``;
* ``ode``            -- ``riccati_de(method="ode")`` at its default tolerance (tol 1e-8), without and with
                        its measured error estimate;
* ``solve_ivp``      -- the cheapest direct DOP853 solve of the same equation on the n^2 entries of P that
                        reaches ode's error: rtol 10^-k (k = 3..13, loosest first), atol 1e-6 (scipy's
                        default) or rtol max|P_ref|.

Part 2 (``--part2``), accuracy target (``--target``, default 1e-6) for the three methods on time-rescaled
random plants: the loosest ODE tolerance and the smallest block count that meet it.

Run:  flock /tmp/bench.lock python benchmarks/bench_riccati_de.py [--quick] [--full] [--part2] [--reps 5]
      --quick: n = 10 and 50 at 10 s, printed only;  --full: also the ODE at n = 100 over 1000 s.
Writes section 1 of benchmarks/results/riccati_de.md (the whole file with --part2).
"""

from __future__ import annotations

# isort: off
import _common  # noqa: F401  (first: single-threaded BLAS before numpy)
# isort: on

import argparse  # noqa: E402
import platform  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import scipy.linalg  # noqa: E402
from scipy.integrate import solve_ivp  # noqa: E402

from optdesign import Plant, riccati_de  # noqa: E402
from optdesign.classical.bpf import filter_hamiltonian, riccati_flow  # noqa: E402
from optdesign.errors import RiccatiError  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "results" / "riccati_de.md"

#: a direct solve_ivp try is stopped after this many times the ode method's evaluations
IVP_NFEV_CAP = 100

#: spectral radius of the Hamiltonian after time rescaling in part 2 (the paper's example has 0.8)
RADIUS = 0.8


# ------------------------------------------------------------------ plants
def test_like_plant(rng: np.random.Generator, n: int, stable: bool) -> Plant:
    """The random plants of tests/conftest.py: A ~ N(0, 1) shifted to spectral abscissa -0.5 / +0.5."""
    p = max(1, n // 4)
    while True:
        A = rng.standard_normal((n, n))
        shift = np.max(np.linalg.eigvals(A).real) + 0.5 if stable else np.max(np.linalg.eigvals(A).real) - 0.5
        A -= shift * np.eye(n)
        C = rng.standard_normal((p, n))
        F = rng.standard_normal((n, n))
        plant = Plant(A, C, Q=F @ F.T + 0.1 * np.eye(n), R=np.diag(rng.uniform(0.5, 2.0, p)))
        if plant.is_observable():
            return plant


def rescaled_plant(rng: np.random.Generator, n: int, radius: float | None = RADIUS) -> Plant:
    """Part 2: a random observable plant (possibly unstable), time rescaled so that the Hamiltonian
    of its Riccati DE has spectral radius ``radius`` (None: as drawn)."""
    p = max(1, n // 4)
    while True:
        A = rng.standard_normal((n, n)) / np.sqrt(n)
        C = rng.standard_normal((p, n))
        F = rng.standard_normal((n, n))
        plant = Plant(A, C, Q=F @ F.T / n + 0.1 * np.eye(n), R=np.eye(p))
        if plant.is_observable():
            break
    if radius is None:
        return plant
    M = hamiltonian(plant)
    c = radius / float(np.max(np.abs(np.linalg.eigvals(M))))
    return plant.replace(A=c * plant.A, Q=c * plant.Q, R=plant.R / c)


def hamiltonian(plant: Plant) -> np.ndarray:
    return filter_hamiltonian(plant.A, plant.C, plant.process_noise(), plant.R)


# ------------------------------------------------------------------ the minimal references
def expm_reference(M: np.ndarray, P0: np.ndarray, t: np.ndarray, sub: int) -> np.ndarray:
    """Restarted single matrix exponential (Davison-Maki): one expm for the step, restart every step."""
    n = P0.shape[0]
    E = scipy.linalg.expm(M * ((t[1] - t[0]) / sub))
    E1, E2 = E[:, :n], E[:, n:]
    out = np.empty((t.size, n, n))
    P = out[0] = P0
    for j in range(1, t.size):
        for _ in range(sub):
            Y = E1 + E2 @ P
            P = np.linalg.solve(Y[:n].T, Y[n:].T).T
            P = 0.5 * (P + P.T)
        out[j] = P
    return out


class _Budget(Exception):
    pass


def ivp_reference(plant: Plant, P0: np.ndarray, t: np.ndarray, rtol: float = 1e-12, atol: float = 1e-15,
                  max_nfev: float = np.inf):
    """solve_ivp DOP853 on the full matrix P (n^2 unknowns); ``(None, nfev)`` once it has used more
    than ``max_nfev`` evaluations (stopped there)."""
    n = P0.shape[0]
    A, W = plant.A, plant.process_noise()
    S = plant.C.T @ np.linalg.solve(plant.R, plant.C)
    count = [0]

    def f(_t, y):
        count[0] += 1
        if count[0] > max_nfev:
            raise _Budget
        P = y.reshape(n, n)
        H = A @ P - 0.5 * (P @ S @ P)
        return (H + H.T + W).ravel()

    try:
        sol = solve_ivp(f, (0.0, float(t[-1])), P0.ravel(), method="DOP853", t_eval=t, rtol=rtol, atol=atol)
    except _Budget:
        return None, count[0]
    if sol.y.shape[1] < t.size:
        return None, int(sol.nfev)
    P = sol.y.T.reshape(-1, n, n)
    return 0.5 * (P + np.swapaxes(P, 1, 2)), int(sol.nfev)


# ------------------------------------------------------------------ measuring
def map_kind(tr) -> str:
    """How the transition method built its step map: one exponential (direct) or doubling."""
    x = tr.solver_stats.extra
    return "direct map (one expm)" if x.get("direct") else f"{x['doublings']} doublings"


def rel(P, Pref) -> float:
    if P.shape != Pref.shape or not np.all(np.isfinite(P)):
        return float("inf")
    return float(np.max(np.linalg.norm(P - Pref, axis=(1, 2))) / np.max(np.linalg.norm(Pref, axis=(1, 2))))


def cpu_medians(fns: dict, reps: int) -> tuple[dict, dict]:
    """CPU seconds of each callable, median of ``reps`` interleaved runs after a first run (a
    callable slower than 2 s is timed by its first run only), and what each first run returned."""
    times: dict[str, list[float]] = {k: [] for k in fns}
    out = {}
    for k, f in fns.items():
        c = time.process_time()
        out[k] = f()
        first = time.process_time() - c
        if first > 2.0:
            times[k].append(first)
    for _ in range(reps):
        for k, f in fns.items():
            if times[k] and times[k][0] > 2.0:
                continue
            c = time.process_time()
            f()
            times[k].append(time.process_time() - c)
    return {k: statistics.median(v) for k, v in times.items()}, out


def issue_plant(n: int, seed: int = 26) -> Plant:
    """Issue 26's family: ``A = randn(n, n)/sqrt(n)``, three outputs ``C = randn(3, n)``, W = I, R = I."""
    rng = np.random.default_rng(seed)
    while True:
        plant = Plant(rng.standard_normal((n, n)) / np.sqrt(n), rng.standard_normal((3, n)),
                      Q=np.eye(n), R=np.eye(3))
        if plant.is_observable():
            return plant


def cheapest_ivp(plant: Plant, P0: np.ndarray, t: np.ndarray, ref: np.ndarray, goal: float, reps: int,
                 max_nfev: float = np.inf):
    """The cheapest direct ``solve_ivp`` (DOP853) whose error against ``ref`` is <= ``goal``: rtol
    10^-k, k = 3..13, each with atol = 1e-6 (scipy's default) and atol = rtol * max|P_ref|, loosest
    first; the first decade that meets the goal is timed (both atol where both meet it).  Tries that
    use more than ``max_nfev`` evaluations are stopped (None if every one meeting the goal would)."""
    big = float(np.max(np.abs(ref)))
    for k in range(3, 14):
        rtol = 10.0 ** -k
        ok = []
        for atol in (1e-6, rtol * big):
            P, nfev = ivp_reference(plant, P0, t, rtol, atol, max_nfev)
            if P is None:
                continue
            e = rel(P, ref)
            if e <= goal:
                ok.append((atol, nfev, e))
        if ok:
            fns = {a: (lambda a=a: ivp_reference(plant, P0, t, rtol, a)) for a, _, _ in ok}
            sec, _ = cpu_medians(fns, reps)
            atol, nfev, e = min(ok, key=lambda r: sec[r[0]])
            return dict(rtol=rtol, atol=atol, nfev=nfev, err=e, sec=sec[atol])
    return None


def issue26_case(n: int, tf: float, reps: int, with_ode: bool, tol: float = 1e-8) -> tuple[list[dict], float]:
    """Issue 26's comparisons at one size: transition vs the restarted exponential, ode vs the
    cheapest direct solve_ivp at equal accuracy; and the reference's own noise (``ref``, doubling
    from a 32x shorter base step, against a 256x shorter one)."""
    plant = issue_plant(n)
    P0 = np.eye(n)
    M = hamiltonian(plant)
    t = np.linspace(0.0, tf, 101)
    ref, _ = riccati_flow(M, P0, t, max_norm=1.0 / 64, direct=False)
    noise = rel(riccati_flow(M, P0, t, max_norm=1.0 / 512, direct=False)[0], ref)
    post = dict(estimate_error=True, steady_state=True)
    sec, res = cpu_medians({"expm": lambda: expm_reference(M, P0, t, 1),
                            "transition": lambda: riccati_de(plant, P0, tf),
                            "transition+post": lambda: riccati_de(plant, P0, tf, **post)}, reps)
    e_tr = rel(res["transition"].P, ref)
    rows = [dict(what="restarted expm", setting="1 substep per output (issue 26's reference)", sec=sec["expm"],
                 err=rel(res["expm"], ref), ratio=1.0),
            dict(what="transition", setting=f"defaults, {map_kind(res['transition'])}",
                 sec=sec["transition"], err=e_tr, ratio=sec["transition"] / sec["expm"]),
            dict(what="transition", setting="estimate_error + steady_state", sec=sec["transition+post"],
                 err=rel(res["transition+post"].P, ref), ratio=sec["transition+post"] / sec["expm"])]
    goal = max(e_tr, noise)
    if rows[0]["err"] > 10 * goal:                 # the exponential with substeps, to the transition's error
        sub, e = 2, np.inf
        with np.errstate(all="ignore"):
            while sub <= 64:
                e = rel(expm_reference(M, P0, t, sub), ref)
                if e <= 10 * goal:
                    break
                sub *= 2
        s_sec, _ = cpu_medians({"x": lambda: expm_reference(M, P0, t, sub)}, reps)
        rows.append(dict(what="restarted expm", setting=f"{sub} substeps per output (error <= 10x transition's: "
                         f"{'yes' if e <= 10 * goal else 'no'})", sec=s_sec["x"], err=e,
                         ratio=s_sec["x"] / sec["expm"]))
    if not with_ode:
        return rows, noise
    sec, res = cpu_medians({"ode": lambda: riccati_de(plant, P0, tf, method="ode", estimate_error=False, tol=tol),
                            "ode defaults": lambda: riccati_de(plant, P0, tf, method="ode", tol=tol)}, reps)
    od = res["ode"]
    e_ode = rel(od.P, ref)
    x = od.solver_stats.extra
    with np.errstate(all="ignore"):
        best = cheapest_ivp(plant, P0, t, ref, max(e_ode, noise), reps, max_nfev=IVP_NFEV_CAP * x["nfev"])
    for key, label in (("ode", "estimate_error=False"), ("ode defaults", "defaults (+ measured error)")):
        rows.append(dict(what="ode", setting=f"{label}, tol {tol:.0e}: rtol {x['rtol']:.0e}, nfev {x['nfev']}",
                         sec=sec[key], err=e_ode, ratio=float("nan") if best is None else sec[key] / best["sec"]))
    if best is None:
        rows.append(dict(what="solve_ivp", setting=f"none down to rtol 1e-13 meets ode's error within "
                         f"{IVP_NFEV_CAP:g}x its {x['nfev']} evaluations",
                         sec=float("nan"), err=float("nan"), ratio=float("nan")))
    else:
        rows.append(dict(what="solve_ivp", setting=f"DOP853 rtol {best['rtol']:.0e}, atol {best['atol']:.0e}, "
                         f"nfev {best['nfev']}", sec=best["sec"], err=best["err"], ratio=1.0))
    return rows, noise


def part1(sizes, horizons, reps: int, max_ode_work: float, tol: float = 1e-8) -> list[str]:
    lines = [
        "## 1. Issue 26: ode vs a direct solve_ivp at equal accuracy, transition vs the restarted exponential",
        "",
        "Issue 26's plants: `A = randn(n, n)/sqrt(n)` (seeded), `C = randn(3, n)`, W = I, R = I, P0 = I,",
        "101 output times; error `max_k ||P_k - P_ref(t_k)||_F / max_k ||P_ref(t_k)||_F` against the exact",
        "flow by doubling from a 32x shorter base step.  CPU time (`time.process_time`), median of",
        f"{reps} interleaved runs after a first (runs over 2 s: the first only).  `ode` and `transition` at",
        "their defaults (no post-processing); `solve_ivp` = the cheapest direct DOP853 solve of the same",
        "equation that reaches ode's error (rtol 10^-k, atol 1e-6 or rtol max|P|; loosest first); the",
        "restarted expm = one `expm(M Delta)` and one Moebius step per output (issue 26's reference; where its",
        "error exceeds 10x the transition's, also the smallest `s = 2^k <= 64` substeps reaching that).",
        "ref. noise: the reference against one from a 256x shorter base step; equal accuracy means the",
        "larger of ode's error and this noise (below it the errors are not resolved).  ratio: transition and",
        "expm rows against the 1-substep expm; ode rows against the cheapest solve_ivp.",
        "",
        "| n | horizon | rho(M) | ref. noise | engine | setting | CPU [ms] | error | ratio |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for n in sizes:
        for tf in horizons:
            rho = float(np.max(np.abs(np.linalg.eigvals(hamiltonian(issue_plant(n))))))
            with_ode = n * n * n * rho * tf <= max_ode_work
            rows, noise = issue26_case(n, tf, reps, with_ode, tol)
            for r in rows:
                line = (f"| {n} | {tf:g} s | {rho:.3g} | {noise:.0e} | {r['what']} | {r['setting']} | "
                        f"{r['sec'] * 1e3:.1f} | {r['err']:.1e} | {r['ratio']:.2f} |")
                lines.append(line)
                print(line, flush=True)
            if not with_ode:
                line = f"| {n} | {tf:g} s | {rho:.3g} | {noise:.0e} | ode | not run (use --full) | | | |"
                lines.append(line)
                print(line, flush=True)
    return lines


# ------------------------------------------------------------------ part 2: accuracy target
def timed(reps: int, fn):
    """The first result and the median CPU time of ``reps`` calls."""
    out, sec = [], []
    for _ in range(reps):
        c = time.process_time()
        out.append(fn())
        sec.append(time.process_time() - c)
    return out[0], statistics.median(sec)


def accuracy_case(plant: Plant, tf: float, target: float, reps: int, with_bpf: bool, max_m: int):
    n = plant.n
    P0 = np.eye(n)
    M = hamiltonian(plant)
    t = np.linspace(0.0, tf, 101)
    ref, _ = riccati_flow(M, P0, t, max_norm=1.0 / 16, direct=False)
    lean = dict(estimate_error=False, steady_state=False)
    rows = []
    tr, sec = timed(reps, lambda: riccati_de(plant, P0, tf, steps=100, **lean))
    e = rel(tr.P, ref)
    rows.append(("transition", map_kind(tr), sec, e, e <= target))
    found = None
    for k in range(2, 11):
        tol = 10.0 ** -k
        od = riccati_de(plant, P0, tf, method="ode", steps=100, tol=tol, **lean)
        if od.status.is_solved and rel(od.P, ref) <= target:
            found = tol
            break
    if found is None:
        rows.append(("ode", "target not met at tol 1e-10", float("nan"), rel(od.P, ref), False))
    else:
        od, sec = timed(reps, lambda: riccati_de(plant, P0, tf, method="ode", steps=100, tol=found, **lean))
        integ = od.solver_stats.extra["integrator"]
        rows.append(("ode", f"{integ}, tol {found:.0e}, nfev {od.solver_stats.extra['nfev']}", sec,
                     rel(od.P, ref), True))
    if with_bpf:
        m, e, failure = 25, np.inf, ""
        while m <= max_m:
            try:
                b = riccati_de(plant, P0, tf, method="bpf", steps=m, **lean)
            except RiccatiError as exc:
                failure = str(exc).split(":")[1].strip()
                break
            exact, _ = riccati_flow(M, P0, b.t, max_norm=1.0 / 16, direct=False)
            e = rel(b.P, exact)
            if e <= target:
                break
            m *= 2
        if failure:
            rows.append(("bpf", f"m = {m}: RiccatiError ({failure})", float("nan"), float("nan"), False))
        elif e <= target:
            b, sec = timed(reps, lambda: riccati_de(plant, P0, tf, method="bpf", steps=m, **lean))
            extra = b.solver_stats.extra
            rows.append(("bpf", f"m = {m}, restarted every {extra['restart_every']} blocks", sec, e, True))
        else:
            rows.append(("bpf", f"m = {m // 2}: error {e:.1e}", float("nan"), e, False))
    return rows


def part2(target: float, reps: int) -> list[str]:
    lines = [
        f"## 2. Accuracy target {target:.0e}: the three methods",
        "",
        "Random plants (p = max(1, n/4)), time-rescaled so that the Hamiltonian M has spectral radius",
        f"{RADIUS} as in the paper's example (last row: not rescaled), P0 = I, 100 output intervals; error",
        "against the exact flow with an 8x shorter base step; CPU time of the whole call",
        f"(`estimate_error=False, steady_state=False`), median of {reps} run(s).",
        "",
        "| n | rho(M) | t_final | method | setting | time [ms] | error | target met |",
        "|---|---|---|---|---|---|---|---|",
    ]
    rng = np.random.default_rng(2026)
    cases = [(n, 10.0, True, RADIUS) for n in (2, 5, 10, 20, 50)]
    cases += [(n, 1000.0, False, RADIUS) for n in (2, 10)]
    cases.append((10, 10.0, True, None))          # not rescaled: Hamiltonian radius ~4.5
    for n, tf, with_bpf, radius in cases:
        plant = rescaled_plant(rng, n, radius)
        rho = float(np.max(np.abs(np.linalg.eigvals(hamiltonian(plant)))))
        max_m = 8192 if n <= 20 else 2048
        for method, setting, sec, err, ok in accuracy_case(plant, tf, target, reps, with_bpf, max_m):
            line = (f"| {n} | {rho:.2g} | {tf:g} | {method} | {setting} | {sec * 1e3:.1f} | {err:.1e} | "
                    f"{'yes' if ok else 'NO'} |")
            lines.append(line)
            print(line, flush=True)
    return lines


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="n = 10, 50 at 10 s only; print, write nothing")
    ap.add_argument("--full", action="store_true", help="also the ODE at n = 100 over 1000 s (minutes)")
    ap.add_argument("--part2", action="store_true", help="also part 2 (accuracy targets), whole file rewritten")
    ap.add_argument("--target", type=float, default=1e-6, help="part 2: relative accuracy target")
    ap.add_argument("--reps", type=int, default=5)
    ap.add_argument("--sizes", type=int, nargs="+", help="part 1 at these n only; printed, nothing written")
    ap.add_argument("--horizons", type=float, nargs="+", help="with --sizes: these horizons (default 10)")
    ap.add_argument("--ode-tol", type=float, default=1e-8, help="the ode method's tol in part 1 (default 1e-8)")
    args = ap.parse_args()
    import optdesign

    print(f"optdesign from {optdesign.__file__}", flush=True)
    if args.sizes:
        part1(args.sizes, args.horizons or (10.0,), args.reps, np.inf, args.ode_tol)
        return
    sizes = (10, 50) if args.quick else (10, 50, 100)
    horizons = (10.0,) if args.quick else (1.0, 10.0, 1000.0)
    section1 = part1(sizes, horizons, args.reps, np.inf if args.full else 2e9, args.ode_tol)
    if args.quick:
        return
    if not args.part2:
        write_section1(section1)
        return
    cmd = "python benchmarks/bench_riccati_de.py --part2" + (" --full" if args.full else "")
    lines = [
        "# Riccati differential equation: engines against minimal references, and accuracy targets",
        "",
        f"`{cmd}` -- {platform.processor() or platform.machine()}, Python {platform.python_version()}, "
        "single-threaded BLAS, shared 2-core machine (CPU times, medians of interleaved runs).",
        "",
        *section1, "", *part2(args.target, 3),
    ]
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text("\n".join(lines) + "\n", encoding="utf-8")
    print(f"\nwritten to {RESULTS}")


def write_section1(section1: list[str]) -> None:
    """Replace section 1 of the results file (up to the next ``## `` heading) with ``section1``."""
    old = RESULTS.read_text(encoding="utf-8").split("\n")
    start = next(i for i, line in enumerate(old) if line.startswith("## 1."))
    end = next((i for i in range(start + 1, len(old)) if old[i].startswith("## ")), len(old))
    tail = old[end:] if end < len(old) else [""]
    RESULTS.write_text("\n".join(old[:start] + section1 + [""] + tail), encoding="utf-8")
    print(f"\nsection 1 written to {RESULTS}")


if __name__ == "__main__":
    main()
