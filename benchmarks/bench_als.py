"""Benchmark: ``estimate_noise`` (autocovariance least squares, issue 31) against a hand-written minimal
cvxpy ALS-SDP on the same data, side by side in one process.

The minimal reference (``minimal_als``) is the textbook pipeline of Odelson, Rajamani & Rawlings (2006)
as one would write it from the paper: the innovations by a Python loop, the sample autocovariances by
one product per lag over the whole record, the ALS matrix in Kronecker form
``[(C (x) O)(I - Abar (x) Abar)^-1 (G (x) G) D, ((C (x) O)(I - Abar (x) Abar)^-1 (L (x) L) + I (x) Psi) D]``
and ``cvxpy.Minimize(sum_squares(A [vec Q; vec R] - b))`` with ``Q, R >> 0`` on Clarabel.

Plants: random stable discrete plants (``A`` scaled to spectral radius 0.9), ``p = g = max(1, n // 4)``
outputs and disturbances (G random), true Q and R random PSD, 15 lags, the plant's own Kalman gain of a
wrong guess (``Q = I``, ``R = I``) as the suboptimal filter.  CPU time (``time.process_time``), median of
``--reps`` interleaved runs:

The reference keeps the unique autocovariance entries as ours does (lag 0: the upper triangle), so both
solve the same least-squares problem on the same data.

* ``SDP``  -- from the autocovariances to (Q, R): ours with ``method="sdp"`` (the QR-reduced program,
  polish and checks included) and with ``method="auto"`` (the closed form where it is PSD), against the
  reference's cvxpy problem on the full ALS matrix;
* ``all``  -- the whole call from the data (innovations, autocovariances, ALS matrix, solve, checks).

Then N = 10^6 samples at n = 20: the peak memory that ``estimate_noise`` allocates (``tracemalloc``;
the record itself, 8 N p bytes, is the caller's), and the autocovariance crossover direct / FFT.

Run:  flock /tmp/bench.lock python benchmarks/bench_als.py [--quick] [--reps 3]
Writes benchmarks/results/als.md.
"""

from __future__ import annotations

# isort: off
import _common  # noqa: F401  (first: single-threaded BLAS before numpy)
# isort: on

import argparse  # noqa: E402
import platform  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402
import tracemalloc  # noqa: E402
from pathlib import Path  # noqa: E402

import cvxpy as cp  # noqa: E402
import numpy as np  # noqa: E402

from optdesign import Plant  # noqa: E402
from optdesign.design.noise_estimation import estimate_noise, simulate_outputs  # noqa: E402
from optdesign.formulate.als import AutocovAccumulator  # noqa: E402

LAGS = 15
OUT = Path(__file__).parent / "results" / "als.md"


def make_case(n: int, seed: int):
    rng = np.random.default_rng(seed)
    p = g = max(1, n // 4)
    while True:
        A = rng.standard_normal((n, n))
        A *= 0.9 / np.max(np.abs(np.linalg.eigvals(A)))
        C = rng.standard_normal((p, n))
        G = rng.standard_normal((n, g))
        F = rng.standard_normal((g, g))
        H = rng.standard_normal((p, p))
        Q = F @ F.T / g + 0.1 * np.eye(g)
        R = H @ H.T / p + 0.1 * np.eye(p)
        plant = Plant(A, C, G=G, Q=np.eye(g), R=np.eye(p), dt=1.0)
        if plant.is_observable():
            return plant, Q, R


# ------------------------------------------------------------------ the minimal reference
def minimal_innovations(plant: Plant, L: np.ndarray, y: np.ndarray) -> np.ndarray:
    A, C = plant.A, plant.C
    x = np.zeros(plant.n)
    e = np.empty_like(y)
    for k in range(y.shape[0]):
        e[k] = y[k] - C @ x
        x = A @ x + L @ e[k]
    return e


def minimal_autocov(e: np.ndarray, lags: int) -> np.ndarray:
    N = e.shape[0]
    return np.array([e[i:].T @ e[:N - i] / (N - i) for i in range(lags)])


def minimal_als_sdp(plant: Plant, L: np.ndarray, chat: np.ndarray):
    """Odelson et al. (2006) Kronecker form + cvxpy sum_squares, Q, R >> 0, Clarabel."""
    A, C, G = plant.A, plant.C, plant.G
    n, p, g = plant.n, plant.p, plant.m
    lags = chat.shape[0]
    Ab = A - L @ C
    O = np.vstack([C @ np.linalg.matrix_power(Ab, i) for i in range(lags)])
    Psi = np.vstack([np.eye(p)] + [-C @ np.linalg.matrix_power(Ab, i - 1) @ L for i in range(1, lags)])
    M = np.linalg.inv(np.eye(n * n) - np.kron(Ab, Ab))
    AQ = np.kron(C, O) @ M @ np.kron(G, G)                 # on vec(Q) (column-major)
    AR = np.kron(C, O) @ M @ np.kron(L, L) + np.kron(np.eye(p), Psi)
    b = np.vstack(chat).reshape(-1, order="F")
    # the same data as ours: C_0 is symmetric, its lower off-diagonal entries are dropped (row b*N*p + a
    # of the vec holds C_i[a', b] with i = a // p, a' = a % p)
    idx = np.arange(b.size)
    col, row = idx // (lags * p), idx % (lags * p)
    keep = (row >= p) | (row % p <= col)
    AQ, AR, b = AQ[keep], AR[keep], b[keep]
    Qv = cp.Variable((g, g), symmetric=True)
    Rv = cp.Variable((p, p), symmetric=True)
    obj = cp.sum_squares(AQ @ cp.vec(Qv, order="F") + AR @ cp.vec(Rv, order="F") - b)
    prob = cp.Problem(cp.Minimize(obj), [Qv >> 0, Rv >> 0])
    prob.solve(solver="CLARABEL")

    def f(Q, R):
        r = AQ @ Q.reshape(-1, order="F") + AR @ R.reshape(-1, order="F") - b
        return float(r @ r)

    return Qv.value, Rv.value, f


def minimal_all(plant: Plant, L: np.ndarray, y: np.ndarray, burn: int):
    e = minimal_innovations(plant, L, y)[burn:]
    return minimal_als_sdp(plant, L, minimal_autocov(e, LAGS))


# ------------------------------------------------------------------ timing
def cpu(fn, *args, **kw):
    t = time.process_time()
    out = fn(*args, **kw)
    return time.process_time() - t, out


def row(n: int, N: int, reps: int, seed: int) -> dict:
    plant, Q, R = make_case(n, seed)
    y = simulate_outputs(plant, N, Q=Q, R=R, seed=seed)
    est0 = estimate_noise(plant, y, lags=LAGS)
    L, burn = est0.L, int(est0.solver_stats.extra["burn_in"])
    e = minimal_innovations(plant, L, y)[burn:]
    chat = minimal_autocov(e, LAGS)
    t = {k: [] for k in ("sdp_ours", "sdp_auto", "sdp_ref", "all_ours", "all_ref")}
    for _ in range(reps):
        t["sdp_ref"].append(cpu(minimal_als_sdp, plant, L, chat)[0])
        t["sdp_ours"].append(_ours_from_autocov(plant, y, L, "sdp"))
        t["sdp_auto"].append(_ours_from_autocov(plant, y, L, "auto"))
        t["all_ref"].append(cpu(minimal_all, plant, L, y, burn)[0])
        t["all_ours"].append(cpu(estimate_noise, plant, y, lags=LAGS, L=L)[0])
    Qr, Rr, f = minimal_als_sdp(plant, L, chat)
    est = estimate_noise(plant, y, lags=LAGS, L=L, method="sdp")
    auto = estimate_noise(plant, y, lags=LAGS, L=L)
    med = {k: statistics.median(v) for k, v in t.items()}
    diff = max(np.linalg.norm(est.Q - Qr) / np.linalg.norm(Qr),
               np.linalg.norm(est.R - Rr) / np.linalg.norm(Rr))
    dobj = (f(est.Q, est.R) - f(Qr, Rr)) / f(Qr, Rr)       # < 0: ours fits better
    err = np.hypot(np.linalg.norm(auto.Q - Q), np.linalg.norm(auto.R - R)) / np.hypot(np.linalg.norm(Q),
                                                                                      np.linalg.norm(R))
    return {"n": n, "p": plant.p, "N": N, **med, "diff": diff, "dobj": dobj, "err": err,
            "route": auto.route.answered.name,
            "success": est.success and auto.success}


def _ours_from_autocov(plant, y, L, method):
    """The verb's solve stage alone: the autocovariance stage's CPU time (its route stage) subtracted."""
    est = estimate_noise(plant, y, lags=LAGS, L=L, method=method)
    return est.solver_stats.time - (est.route[0].time or 0.0)


def crossover(N: int, reps: int) -> list[tuple[int, int, float, float]]:
    rng = np.random.default_rng(0)
    out = []
    for p in (1, 3):
        e = rng.standard_normal((N, p))
        for lags in (8, 16, 32, 48, 64, 128):
            tt = {}
            for method in ("direct", "fft"):
                ts = []
                for _ in range(reps):
                    acc = AutocovAccumulator(p, lags, method)
                    t0 = time.process_time()
                    for k in range(0, N, acc.chunk_length()):
                        acc.push(e[k:k + acc.chunk_length()])
                    ts.append(time.process_time() - t0)
                tt[method] = statistics.median(ts)
            out.append((p, lags, tt["direct"], tt["fft"]))
    return out


def big_record(n: int, N: int) -> dict:
    plant, Q, R = make_case(n, 1)
    t0 = time.process_time()
    y = simulate_outputs(plant, N, Q=Q, R=R, seed=1)
    t_sim = time.process_time() - t0
    tracemalloc.start()
    t0 = time.process_time()
    est = estimate_noise(plant, y, lags=LAGS)
    t_est = time.process_time() - t0
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    err = np.hypot(np.linalg.norm(est.Q - Q), np.linalg.norm(est.R - R)) / np.hypot(np.linalg.norm(Q),
                                                                                    np.linalg.norm(R))
    return {"n": n, "p": plant.p, "N": N, "record_MB": y.nbytes / 2**20, "peak_MB": peak / 2**20,
            "cpu": t_est,
            "sim": t_sim, "err": err, "success": est.success, "route": str(est.route)}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--reps", type=int, default=3)
    args = ap.parse_args()
    ns = (2, 5, 10, 20) if not args.quick else (2, 10)
    Ns = (10**3, 10**4, 10**5) if not args.quick else (10**3, 10**4)
    rows = []
    for n in ns:
        for N in Ns:
            r = row(n, N, args.reps, seed=10 * n + len(str(N)))
            rows.append(r)
            print(f"n={n:3d} p={r['p']} N={N:>7d}  SDP ours {r['sdp_ours']:.3f} (auto {r['sdp_auto']:.3f}) "
                  f"ref {r['sdp_ref']:.3f} ratio {r['sdp_ours'] / r['sdp_ref']:.2f}  |  "
                  f"all ours {r['all_ours']:.3f} ref {r['all_ref']:.3f} "
                  f"ratio {r['all_ours'] / r['all_ref']:.2f}  diff {r['diff']:.1e} dobj {r['dobj']:.1e} "
                  f"err {r['err']:.3f} {r['route']}", flush=True)
    cross = crossover(10**5 if not args.quick else 2 * 10**4, args.reps)
    for p, lags, td, tf in cross:
        print(f"autocov p={p} lags={lags}: direct {td:.3f} fft {tf:.3f}")
    big = big_record(20, 10**6 if not args.quick else 10**5)
    print(big)
    if not args.quick:
        write(rows, cross, big, args.reps)


def write(rows, cross, big, reps) -> None:
    lines = [
        "# Autocovariance least squares: `estimate_noise` against a minimal cvxpy ALS-SDP",
        "",
        f"`python benchmarks/bench_als.py` (under `flock /tmp/bench.lock`, single-threaded BLAS), "
        f"{platform.processor() or platform.machine()}, Python {platform.python_version()}, "
        f"cvxpy {cp.__version__}; "
        f"CPU seconds (`time.process_time`), median of {reps} interleaved runs.  Random stable plants, "
        f"p = g = max(1, n/4), true Q, R random PSD, {LAGS} lags; the suboptimal filter of the guess "
        f"Q = I, R = I.",
        "",
        "* **SDP**: from the autocovariances to (Q, R). *ours sdp* = `method=\"sdp\"` (QR-reduced program, "
        "polish, checks), *ours auto* = `method=\"auto\"` (the closed-form least squares where it is PSD, "
        "which then is the "
        "SDP's optimum), *ref* = cvxpy `sum_squares` on the full Kronecker-form ALS matrix, Clarabel.",
        "* **all**: the whole call from the data (innovations, autocovariances, ALS matrix, solve, checks); "
        "the "
        "reference's innovations by a Python loop.",
        "* *diff*: relative difference of our SDP's (Q, R) from the reference's; *dobj*: relative "
        "difference of the least-squares objective at ours and at the reference's (negative: ours fits "
        "better); *err*: relative "
        "error of the estimate against the truth.",
        "",
        "| n | p | N | SDP ours sdp | SDP ours auto | SDP ref | ratio sdp/ref | all ours | all ref | "
        "ratio all | "
        "diff | dobj | err | route (auto) |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(f"| {r['n']} | {r['p']} | {r['N']:.0e} | {r['sdp_ours']:.3f} | {r['sdp_auto']:.4f} | "
                     f"{r['sdp_ref']:.3f} | {r['sdp_ours'] / r['sdp_ref']:.2f} | {r['all_ours']:.3f} | "
                     f"{r['all_ref']:.3f} | {r['all_ours'] / r['all_ref']:.2f} | {r['diff']:.1e} | "
                     f"{r['dobj']:+.1e} | "
                     f"{r['err']:.3f} | "
                     f"{r['route']} |")
    lines += ["", "## Autocovariances: direct products per lag vs FFT (10^5 samples, streamed chunks)", "",
              "| p | lags | direct (s) | FFT (s) |", "|---|---|---|---|"]
    lines += [f"| {p} | {lags} | {td:.3f} | {tf:.3f} |" for p, lags, td, tf in cross]
    lines += ["", "## A record of 10^6 samples", "",
              f"n = {big['n']}, p = {big['p']}, N = {big['N']:.0e}: the record is {big['record_MB']:.1f} MB "
              f"(the caller's); `estimate_noise` allocated at most **{big['peak_MB']:.1f} MB** "
              f"(tracemalloc peak) "
              f"and took {big['cpu']:.2f} s CPU; relative error {big['err']:.4f}; success {big['success']}.  "
              f"Route: {big['route']}.", ""]
    OUT.write_text("\n".join(lines), encoding="utf-8")


if __name__ == "__main__":
    main()
