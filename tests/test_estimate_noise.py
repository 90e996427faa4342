"""estimate_noise: noise covariances from data by autocovariance least squares (issue 31).

(a) convergence to the truth with the data length on several plants, every estimate PSD;
(b) the examples of the ALS papers / package (problems/als); (c) agreement with an independent plain
least-squares solution where that one is PSD; (d) bad input gives typed errors naming the argument.
"""

from __future__ import annotations

import numpy as np
import pytest

from optdesign import Plant
from optdesign.design.noise_estimation import NoiseEstimate, estimate_noise, simulate_outputs
from optdesign.errors import DimensionError, NotFiniteError, ValidationError
from optdesign.formulate.als import AutocovAccumulator, InnovationFilter
from optdesign.results import Status


# ------------------------------------------------------------------ plants
def _scalar():
    return Plant([[0.9]], [[1.0]], dt=1.0), np.array([[0.2]]), np.array([[0.5]])


def _motivating():
    """Rajamani's thesis sec. 2.2 / the ALS package's motivating_example.m (one output, G = [1; 2; 3])."""
    A = np.diag([0.1, 0.2, 0.3])
    A[0, 2] = 0.1
    plant = Plant(A, [[0.1, 0.2, 0.0]], G=[[1.0], [2.0], [3.0]], Q=[[0.2]], R=[[0.4]], dt=1.0)
    return plant, np.array([[0.5]]), np.array([[0.1]])


def _three_outputs():
    """The ALS package's simulate_data8.m (C = I, full 3 x 3 Q and R)."""
    A = np.diag([0.1, 0.2, 0.3])
    A[0, 2] = A[0, 1] = 0.1
    plant = Plant(A, np.eye(3), Q=np.diag([1.0, 2.0, 3.0]), R=1e-3 * np.diag([0.5, 0.2, 0.8]), dt=1.0)
    return plant, np.diag([0.5, 0.2, 0.1]), np.diag([0.5, 0.2, 0.8])


def _continuous():
    plant = Plant([[0.0, 1.0], [-2.0, -0.5]], [[1.0, 0.0]], G=[[0.0], [1.0]], Q=[[0.3]], R=[[0.05]])
    return plant, np.array([[1.0]]), np.array([[0.01]])


PLANTS = {"scalar": (_scalar, None), "motivating": (_motivating, None),
          "three_outputs": (_three_outputs, None), "continuous": (_continuous, 0.1)}


def _error(est: NoiseEstimate, Q: np.ndarray, R: np.ndarray) -> float:
    return float(np.hypot(np.linalg.norm(est.Q - Q), np.linalg.norm(est.R - R)) /
                 np.hypot(np.linalg.norm(Q), np.linalg.norm(R)))


# ------------------------------------------------------------------ (a) convergence
@pytest.mark.parametrize("name", sorted(PLANTS))
def test_error_decreases_like_inverse_sqrt_N(name):
    make, dt = PLANTS[name]
    plant, Q, R = make()
    errs = {}
    for N in (2000, 20000):
        e2 = []
        for seed in range(8):
            y = simulate_outputs(plant, N, Q=Q, R=R, dt=dt, seed=100 + seed)
            est = estimate_noise(plant, y, dt=dt, lags=12)
            assert est.success, est.summary()
            assert np.linalg.eigvalsh(est.Q)[0] >= -1e-9 * np.linalg.norm(est.Q)
            assert np.linalg.eigvalsh(est.R)[0] >= -1e-9 * np.linalg.norm(est.R)
            e2.append(_error(est, Q, R) ** 2)
        errs[N] = np.sqrt(np.mean(e2))
    ratio = errs[2000] / errs[20000]
    # N^-1/2: the ratio is sqrt(10) = 3.16; eight seeds each (the RMS error is known to ~25 %), so a
    # generous factor 2.5 either way
    assert 3.16 / 2.5 < ratio < 3.16 * 2.5, (errs, ratio)
    assert errs[20000] < 0.25


def test_continuous_plant_needs_dt_and_returns_continuous_units():
    plant, Q, R = _continuous()
    y = simulate_outputs(plant, 20000, Q=Q, R=R, dt=0.1, seed=3)
    with pytest.raises(ValidationError, match="give dt"):
        estimate_noise(plant, y)
    est = estimate_noise(plant, y, dt=0.1, lags=20)
    assert abs(est.Q[0, 0] - 1.0) < 0.15 and abs(est.R[0, 0] - 0.01) < 0.001
    np.testing.assert_allclose(est.Rd, est.R / 0.1)
    kf = est.kalman()
    assert kf.plant.is_discrete and kf.extra["Ts"] == 0.1
    assert kf.success


def test_optimal_weighting_converges_and_is_reported():
    plant, Q, R = _three_outputs()
    y = simulate_outputs(plant, 5000, Q=Q, R=R, seed=1)
    est = estimate_noise(plant, y, lags=15, weighting="optimal")
    rep = est.weighting_report
    assert rep["converged"] and 1 <= rep["iterations"] <= 20
    assert rep["changes"][-1] <= 1e-4
    assert est.success and "optimal_weighting" in est.route.answered.name
    assert _error(est, Q, R) < 0.3


def test_bootstrap_intervals_hold_the_truth_and_kalman_is_the_filter_of_the_estimate():
    plant, Q, R = _scalar()
    y = simulate_outputs(plant, 20000, Q=Q, R=R, seed=7)
    est = estimate_noise(plant, y, lags=10, bootstrap=100, seed=0, confidence=0.95)
    c = est.confidence
    assert c["replicates"] == 100 and c["segments"] >= 8
    assert c["Q_low"][0, 0] <= Q[0, 0] <= c["Q_high"][0, 0]
    assert c["R_low"][0, 0] <= R[0, 0] <= c["R_high"][0, 0]
    again = estimate_noise(plant, y, lags=10, bootstrap=100, seed=0, confidence=0.95)
    np.testing.assert_array_equal(again.confidence["Q_low"], c["Q_low"])
    kf = est.kalman()
    from optdesign import kalman
    ref = kalman(plant.replace(Q=est.Q, R=est.R))
    np.testing.assert_allclose(kf.L, ref.L)


def test_trace_penalty_gives_a_low_rank_q_where_full_q_is_unidentifiable():
    """The ALS package's minrank_ex.m: full 2 x 2 Q from one output is not identifiable; the trace
    penalty picks a rank-one Q (one disturbance) that still fits."""
    A = [[0.53565, 0.23972], [0.75473, 0.40629]]
    plant = Plant(A, [[1.0, 1.0]], Q=0.1 * np.eye(2), R=[[0.1]], dt=1.0)
    y = simulate_outputs(plant, 5000, seed=2)
    with pytest.raises(ValidationError, match="q_structure='full' is not identifiable.*rank 3 < 4"):
        estimate_noise(plant, y, lags=15)
    est = estimate_noise(plant, y, lags=15, trace_penalty=1e-2)
    lam = np.linalg.eigvalsh(est.Q)
    assert est.success and est.rank == 3
    assert lam[0] <= 1e-6 * lam[1] and lam[1] > 0.01
    assert est.route.answered.kind == "backend"


def test_structures_diagonal_and_g_matrix():
    plant, Q, R = _three_outputs()
    y = simulate_outputs(plant, 20000, Q=Q, R=R, seed=4)
    diag = estimate_noise(plant, y, lags=10, q_structure="diagonal")
    assert diag.n_unknowns == 3 + 6
    np.testing.assert_array_equal(diag.Q, np.diag(np.diag(diag.Q)))
    assert np.max(np.abs(np.diag(diag.Q) - np.diag(Q))) < 0.1
    G = np.array([[1.0], [0.0], [0.0]])
    est = estimate_noise(plant, y, lags=10, q_structure=G)
    assert est.Q.shape == (1, 1) and np.array_equal(est.G, G)


# ------------------------------------------------------------------ (c) plain least squares
def _plain_ls(plant: Plant, y: np.ndarray, L: np.ndarray, lags: int, burn: int):
    """Independent ALS (Odelson et al. 2006, the Kronecker form): innovations by a loop, sample
    autocovariances by sums, A = [(C (x) O) (I - Abar (x) Abar)^-1 (G (x) G) D_Q, ...], numpy lstsq."""
    A, C, G = plant.A, plant.C, plant.G
    n, p, m = plant.n, plant.p, plant.m
    Ab = A - L @ C
    x = np.zeros(n)
    e = np.empty_like(y)
    for k in range(y.shape[0]):
        e[k] = y[k] - C @ x
        x = A @ x + L @ e[k]
    e = e[burn:]
    Nd = e.shape[0]
    chat = np.array([e[i:].T @ e[:Nd - i] / (Nd - i) for i in range(lags)])
    O = np.vstack([C @ np.linalg.matrix_power(Ab, i) for i in range(lags)])
    Psi = np.vstack([np.eye(p)] + [-C @ np.linalg.matrix_power(Ab, i - 1) @ L for i in range(1, lags)])
    M = np.linalg.inv(np.eye(n * n) - np.kron(Ab, Ab))

    def dup(k):
        D = []
        for i in range(k):
            for j in range(i, k):
                E = np.zeros((k, k))
                E[i, j] = E[j, i] = 1
                D.append(E.reshape(-1, order="F"))
        return np.array(D).T

    AQ = np.kron(C, O) @ M @ np.kron(G, G) @ dup(m)
    AR = (np.kron(C, O) @ M @ np.kron(L, L) + np.kron(np.eye(p), Psi)) @ dup(p)
    b = np.vstack(chat).reshape(-1, order="F")         # vec of the single column [C_0; C_1; ...]
    theta = np.linalg.lstsq(np.hstack([AQ, AR]), b, rcond=None)[0]

    def mat(t, k):
        X = np.zeros((k, k))
        X[np.triu_indices(k)] = t
        return X + np.triu(X, 1).T

    kq = m * (m + 1) // 2
    return mat(theta[:kq], m), mat(theta[kq:], p)


def test_sdp_agrees_with_plain_least_squares_where_that_is_psd():
    plant, Q, R = _motivating()
    y = simulate_outputs(plant, 20000, Q=Q, R=R, seed=11)
    est = estimate_noise(plant, y, lags=15, method="sdp", burn_in=100)
    assert est.route.answered.kind == "backend"
    Qls, Rls = _plain_ls(plant, y, est.L, 15, 100)
    assert np.linalg.eigvalsh(Qls)[0] > 0 and np.linalg.eigvalsh(Rls)[0] > 0
    # p = 1: the single column and our unique entries are the same data; the SDP's accuracy ~1e-7
    np.testing.assert_allclose(est.Q, Qls, rtol=1e-5)
    np.testing.assert_allclose(est.R, Rls, rtol=1e-5)
    auto = estimate_noise(plant, y, lags=15, burn_in=100)
    assert auto.route.answered.name == "unconstrained_ls"
    np.testing.assert_allclose(auto.Q, Qls, rtol=1e-9)


def test_sdp_differs_where_the_plain_solution_is_indefinite():
    """Moving-average measurement noise y = v[k] - 0.5 v[k-1]: a negative lag-1 autocovariance that no
    Q >= 0 explains; the plain solution has Q < 0, the SDP's Q sits on the boundary Q = 0."""
    plant = Plant([[0.5]], [[1.0]], dt=1.0, Q=[[1.0]], R=[[1.0]])
    v = np.random.default_rng(5).standard_normal(5001)
    y = (v[1:] - 0.5 * v[:-1])[:, None]
    est = estimate_noise(plant, y, lags=8, burn_in=100)
    Qls, _ = _plain_ls(plant, y, est.L, 8, 100)
    assert Qls[0, 0] < -0.01
    assert est.success, est.summary()
    assert est.route[1].name == "unconstrained_ls" and est.route[1].outcome == "rejected"
    assert est.route.answered.kind == "backend"
    assert abs(est.Q[0, 0]) <= 1e-9 * est.R[0, 0]


# ------------------------------------------------------------------ streaming pieces
def test_block_innovations_and_chunked_autocovariances_match_plain_loops():
    rng = np.random.default_rng(0)
    n, p = 3, 2
    A = np.diag([0.5, 0.7, -0.3])
    A[0, 1] = 0.3
    C = rng.standard_normal((p, n))
    L = 0.1 * rng.standard_normal((n, p))
    B = rng.standard_normal((n, 1))
    y, u = rng.standard_normal((1000, p)), rng.standard_normal((1000, 1))
    f = InnovationFilter(A - L @ C, L, C, B)
    e1 = np.vstack([f.run(y[:333], u[:333]), f.run(y[333:], u[333:])])
    x, e2 = np.zeros(n), []
    for k in range(1000):
        e2.append(y[k] - C @ x)
        x = A @ x + B @ u[k] + L @ e2[-1]
    np.testing.assert_allclose(e1, np.array(e2), atol=1e-12)
    ref = np.array([e1[i:].T @ e1[:1000 - i] / (1000 - i) for i in range(60)])
    for method in ("direct", "fft"):
        acc = AutocovAccumulator(p, 60, method)
        for chunk in np.array_split(e1, 7):
            acc.push(chunk)
        np.testing.assert_allclose(acc.autocov(), ref, atol=1e-12)


# ------------------------------------------------------------------ (d) bad input
@pytest.fixture(scope="module")
def scalar_data():
    plant, Q, R = _scalar()
    return plant, simulate_outputs(plant, 2000, Q=Q, R=R, seed=0)


def test_too_short_data(scalar_data):
    plant, y = scalar_data
    with pytest.raises(ValidationError, match="y is too short"):
        estimate_noise(plant, y[:100])


def test_lags_too_large(scalar_data):
    plant, y = scalar_data
    with pytest.raises(ValidationError, match="lags = 500 is too large for the data"):
        estimate_noise(plant, y, lags=500)


def test_nan_in_data(scalar_data):
    plant, y = scalar_data
    bad = y.copy()
    bad[17, 0] = np.nan
    with pytest.raises(NotFiniteError, match=r"y must be finite; found nan at index \(17, 0\)"):
        estimate_noise(plant, bad)


def test_wrong_shapes(scalar_data):
    plant, y = scalar_data
    with pytest.raises(DimensionError, match="y has the wrong shape"):
        estimate_noise(plant, np.hstack([y, y]))
    with pytest.raises(DimensionError, match="L has the wrong shape"):
        estimate_noise(plant, y, L=np.zeros((2, 1)))
    with pytest.raises(ValidationError, match="u is given but the plant has no input matrix B"):
        estimate_noise(plant, y, u=y)
    pb = plant.replace(B=[[1.0]])
    with pytest.raises(ValidationError, match="u must have one row per sample"):
        estimate_noise(pb, y, u=y[:10])
    with pytest.raises(DimensionError, match="q_structure has the wrong shape"):
        estimate_noise(plant, y, q_structure=np.ones((2, 1)))


def test_unstable_gain(scalar_data):
    plant, y = scalar_data
    with pytest.raises(ValidationError, match="L must make the discrete error dynamics A - L C stable.*1.6"):
        estimate_noise(plant, y, L=[[-0.7]])


def test_unidentifiable_structure_names_the_reason(scalar_data):
    plant, y = scalar_data
    G = np.array([[1.0, 1.0]])                   # two disturbances entering the same way
    with pytest.raises(ValidationError, match="not identifiable.*cannot tell apart"):
        estimate_noise(plant, y, q_structure=G, lags=10)


def test_bad_options(scalar_data):
    plant, y = scalar_data
    with pytest.raises(ValidationError, match="weighting must be one of"):
        estimate_noise(plant, y, weighting="best")
    with pytest.raises(ValidationError, match="trace_penalty must be"):
        estimate_noise(plant, y, trace_penalty=-1.0)
    with pytest.raises(ValidationError, match="confidence must be in"):
        estimate_noise(plant, y, bootstrap=10, confidence=1.5)
    with pytest.raises(ValidationError, match="bootstrap needs at least 8 segments"):
        estimate_noise(plant, y, lags=30, bootstrap=10)
    with pytest.raises(ValidationError, match="dt = 0.5 differs from the discrete plant's own dt"):
        estimate_noise(plant, y, dt=0.5)


def test_time_limit_returns_the_estimate_so_far():
    plant, Q, R = _scalar()
    y = simulate_outputs(plant, 5000, Q=Q, R=R, seed=9)
    est = estimate_noise(plant, y, lags=10, bootstrap=10_000, seed=0, time_limit=0.5)
    assert est.status is Status.TIME_LIMIT
    assert est.Q is not None and est.confidence["replicates"] < 10_000


# ------------------------------------------------------------------ (b) the papers' / package's examples
def _problem(name):
    from pathlib import Path

    from optdesign import problems
    return problems.load(str(Path(__file__).resolve().parents[1] / "problems" / "als" / f"{name}.json"))


def test_paper_motivating_example_estimates_scatter_around_the_truth():
    """problems/als/als_motivating_example (1000 samples, 15 lags, start 100, the filter of the guesses):
    the mean of the estimates over replications lies within 3 standard errors of the truth."""
    p = _problem("als_motivating_example")
    t = p.targets
    Qs, Rs = [], []
    for seed in range(12):
        y = simulate_outputs(p.plant, int(t["samples"]), Q=t["Q_true"], R=t["R_true"], seed=seed)
        est = estimate_noise(p.plant, y, lags=int(t["lags"]), burn_in=int(t["burn_in"]))
        assert est.success
        Qs.append(est.Q[0, 0])
        Rs.append(est.R[0, 0])
    for vals, truth in ((Qs, t["Q_true"][0, 0]), (Rs, t["R_true"][0, 0])):
        se = np.std(vals, ddof=1) / np.sqrt(len(vals))
        assert abs(np.mean(vals) - truth) < 3 * se + 1e-12, (np.mean(vals), truth, se)


def test_paper_three_output_example_full_q_and_r():
    p = _problem("als_simulate_data8")
    t = p.targets
    y = simulate_outputs(p.plant, int(t["samples"]), Q=t["Q_true"], R=t["R_true"], seed=100)
    for weighting in ("identity", "optimal"):
        est = estimate_noise(p.plant, y, lags=int(t["lags"]), burn_in=int(t["burn_in"]), weighting=weighting)
        assert est.success and est.n_unknowns == 12
        assert np.max(np.abs(est.Q - t["Q_true"])) < 0.2 and np.max(np.abs(est.R - t["R_true"])) < 0.2


def test_paper_minimum_rank_example_trade_off():
    p = _problem("als_minrank_ex")
    t = p.targets
    y = simulate_outputs(p.plant, int(t["samples"]), Q=t["Q_true"], R=t["R_true"], seed=200)
    ranks, traces = [], []
    for rho in np.logspace(-4, 0, 5):
        est = estimate_noise(p.plant, y, lags=int(t["lags"]), burn_in=int(t["burn_in"]), trace_penalty=rho)
        assert est.success
        lam = np.linalg.eigvalsh(est.Q)
        ranks.append(int(np.sum(lam > 1e-6 * max(lam[-1], 1e-300))))
        traces.append(float(np.trace(est.Q)))
    assert ranks[:3] == [p.references["rank_Q_at_knee"]] * 3
    assert all(a >= b - 1e-9 for a, b in zip(traces, traces[1:], strict=False))   # tr(Q) falls with rho


# ------------------------------------------------------------------ CLI
def test_cli_estimate_noise_npz_csv_and_errors(tmp_path, capsys):
    import json

    from optdesign.cli.main import main

    path = str(_problem("als_motivating_example").path)
    p = _problem("als_motivating_example")
    y = simulate_outputs(p.plant, 3000, Q=p.targets["Q_true"], R=p.targets["R_true"], seed=0)
    np.savez(tmp_path / "d.npz", y=y)
    np.savetxt(tmp_path / "d.csv", y, delimiter=",", header="y1", comments="")
    assert main(["estimate-noise", path, str(tmp_path / "d.npz"), "--bootstrap", "20", "--seed", "1"]) == 0
    out = capsys.readouterr().out
    assert "NoiseEstimate: status=solved" in out and "bootstrap (20 replicates" in out
    assert "Kalman filter of the estimate: poles" in out
    assert main(["estimate-noise", path, str(tmp_path / "d.csv"), "--json"]) == 0
    rec = json.loads(capsys.readouterr().out)
    est = estimate_noise(p.plant, y)
    np.testing.assert_allclose(rec["Q"], est.Q)
    assert rec["success"] and rec["filter"]["L"]
    assert main(["estimate-noise", path, str(tmp_path / "missing.csv")]) == 2
    assert "data file" in capsys.readouterr().err
    np.savetxt(tmp_path / "two.csv", np.hstack([y, y]), delimiter=",")
    assert main(["estimate-noise", path, str(tmp_path / "two.csv")]) == 2
    assert "expected 1 columns; found 2" in capsys.readouterr().err
    assert main(["estimate-noise", path, str(tmp_path / "d.csv"), "--lags", "900"]) == 2
    assert "lags = 900 is too large" in capsys.readouterr().err


def test_known_inputs_are_filtered_out():
    """With u applied through B, the estimate from (y, u) matches the truth; a plant with B and no u
    is read as zero input."""
    plant, Q, R = _scalar()
    pb = plant.replace(B=[[1.0]])
    u = np.sin(0.05 * np.arange(20000))[:, None] * 3.0
    y = simulate_outputs(pb, 20000, Q=Q, R=R, u=u, seed=12)
    est = estimate_noise(pb, y, u, lags=10)
    assert abs(est.Q[0, 0] - 0.2) < 0.05 and abs(est.R[0, 0] - 0.5) < 0.05
    y0 = simulate_outputs(plant, 20000, Q=Q, R=R, seed=12)
    np.testing.assert_allclose(estimate_noise(pb, y0, lags=10).Q, estimate_noise(plant, y0, lags=10).Q)


def test_bartlett_covariance_matches_monte_carlo():
    """The covariance of the autocovariance data that the optimal weighting inverts, against the
    spread of the sample autocovariances over 400 independent records (1500 records agree to 0.02 in
    the correlations) (innovations of the true model)."""
    from optdesign.formulate.als import bartlett_covariance, unique_mask

    plant, Q, R = _motivating()
    L = estimate_noise(plant, simulate_outputs(plant, 2000, Q=Q, R=R, seed=0), lags=3).L
    Abar = plant.A - L @ plant.C
    lags, N = 3, 500
    samples = []
    records = 400
    for seed in range(records):
        y = simulate_outputs(plant, N + 50, Q=Q, R=R, seed=1000 + seed)
        f = InnovationFilter(Abar, L, plant.C)
        e = f.run(y)[50:]
        acc = AutocovAccumulator(1, lags)
        acc.push(e)
        samples.append(acc.autocov().reshape(-1)[unique_mask(1, lags)])
    emp = np.cov(np.array(samples).T)
    W = plant.G @ Q @ plant.G.T
    S = bartlett_covariance(Abar, plant.C, L, W, R, lags, acc.counts)
    # four standard errors of the Monte Carlo: variances sqrt(2 / records), correlations 1 / sqrt(records)
    np.testing.assert_allclose(np.diag(emp), np.diag(S), rtol=4 * np.sqrt(2 / records))
    corr_e = emp / np.sqrt(np.outer(np.diag(emp), np.diag(emp)))
    corr_s = S / np.sqrt(np.outer(np.diag(S), np.diag(S)))
    assert np.max(np.abs(corr_e - corr_s)) < 4 / np.sqrt(records)


# ------------------------------------------------------------------ the trace-penalty study (issue 31)
def test_trace_penalty_front_finds_the_number_of_disturbances():
    """Rajamani & Rawlings 2009, sec. 4: sweeping the trace penalty, the residual grows and tr(Q) falls,
    and the rank of Q at the knee is the number of independent disturbances -- here one (Q = diag(0.1,
    0) through G = I, one output; full Q is not identifiable, so the smallest penalty already picks
    the smallest-trace fit).  Large penalties drive Q to zero (rank 0) at a much worse residual."""
    from optdesign.studies import noise_penalty_front

    plant = Plant([[0.5, 0.2], [0.7, 0.4]], [[1.0, 1.0]], Q=np.diag([0.1, 0.0]), R=[[0.1]], dt=1.0)
    y = simulate_outputs(plant, 4000, seed=1)
    front = noise_penalty_front(plant, y, penalties=[1e-6, 1e-4, 1e-2, 1.0, 10.0], lags=10)
    recs = front.table.records
    assert all(r["success"] for r in recs)
    res = [r["residual"] for r in recs]
    tr = [r["trace_Q"] for r in recs]
    assert all(b >= a * (1 - 1e-9) for a, b in zip(res, res[1:]))       # the fit worsens with rho
    assert all(b <= a * (1 + 1e-9) for a, b in zip(tr, tr[1:]))         # tr(Q) falls
    assert [r["rank_Q"] for r in recs[:3]] == [1, 1, 1] and recs[-1]["rank_Q"] == 0
    assert abs(tr[0] - 0.1) < 0.05                                       # the one disturbance's variance
    assert front.nondominated[:3].all() and front.objectives == ("residual", "trace_Q")
    with pytest.raises(ValidationError, match="penalties must hold at least two values"):
        noise_penalty_front(plant, y, penalties=[1e-3], lags=10)
    with pytest.raises(ValidationError, match="trace_penalty is the swept argument"):
        noise_penalty_front(plant, y, penalties=[1e-3, 1e-2], lags=10, trace_penalty=1.0)
