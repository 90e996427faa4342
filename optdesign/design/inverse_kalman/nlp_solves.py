"""One IPOPT solve of the inverse Kalman NLPs (spectral identity, state space) and their starts."""


from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ...backends.casadi_backend import solve_nlpsol, solve_opti
from ...classical.placement import pole_error
from ...classical.riccati import filter_are, filter_dare_doubling, filter_gain
from ...classical.solheim import solheim
from ...errors import OptDesignError, RiccatiError, ValidationError
from ...formulate.inverse_kalman import (
    FAST_OBJECTIVES,
    FAST_STRUCTURES,
    build_pole_nlp,
    build_spectral_nlp,
    build_spectral_nlpsol,
    chol_factor,
    tril_index,
)
from ...model.plant import Plant
from .common import noise_of, placed_gain, project_psd, stable_poles, sym
from .sdp_stage import feasibility_margin


def modal_start(F: NDArray, blocks: list) -> tuple[NDArray, NDArray]:
    """Real modal eigenvector matrix of F arranged like the target blocks, and the matching
    initial pole variables (re per real block, (re, im) per pair)."""
    from scipy.optimize import linear_sum_assignment

    n: int = F.shape[0]
    lam, V = np.linalg.eig(F)
    cand = [k for k in range(n) if lam[k].imag >= -1e-12 * max(1.0, abs(lam[k]))]
    cost = np.zeros((len(blocks), len(cand)))
    for b, (size, z) in enumerate(blocks):
        for c, k in enumerate(cand):
            is_c = abs(lam[k].imag) > 1e-9 * max(1.0, abs(lam[k]))
            cost[b, c] = abs(lam[k] - z) + (0.0 if (size == 2) == is_c else 1e3 * max(1.0, abs(z)))
    rows, cols = linear_sum_assignment(cost)
    assigned = dict(zip(rows.tolist(), cols.tolist(), strict=True))
    X = np.zeros((n, n))
    mu: list[float] = []
    pos = np.cumsum([0] + [s for s, _ in blocks])
    rng = np.random.default_rng(0)
    for b, (size, z) in enumerate(blocks):
        i0 = pos[b]
        if b in assigned:
            k = cand[assigned[b]]
            v, lk = V[:, k], complex(lam[k])
        else:  # fewer eigenvalue groups than blocks: a random vector and the target itself
            v, lk = rng.standard_normal(n) + 1j * rng.standard_normal(n), z
        if size == 1:
            x = np.real(v * np.exp(-1j * np.angle(v[np.argmax(np.abs(v))])))
            X[:, i0] = x / max(float(np.linalg.norm(x)), 1e-300)
            mu.append(float(lk.real))
        else:
            v = v * np.exp(-0.5j * np.angle(v @ v))
            u, w = v.real, v.imag
            if np.linalg.norm(w) < 1e-8 * max(1.0, float(np.linalg.norm(u))):  # real eigenvalue here
                w = rng.standard_normal(n)
                w -= (w @ u) / (u @ u) * u
                w *= 0.1 * np.linalg.norm(u) / np.linalg.norm(w)
            nrm = np.sqrt(u @ u + w @ w)
            X[:, i0], X[:, i0 + 1] = u / nrm, w / nrm
            mu += [float(lk.real), max(abs(float(lk.imag)), 1e-3 * max(1.0, abs(z)))]
    return X, np.asarray(mu)


def eig_nlp_solve(plant, target, structure, objective, Qn, start, *, closest=False, scale=1.0,
                   options=None):
    """The state-space (eigenvector) NLP from ``start`` = dict(L, P, W[, mu]): ``(report, Q, Qw)``."""
    nlp = build_pole_nlp(plant.A, plant.C, np.asarray(plant.R, dtype=float), target, dt=plant.dt,
                         structure=structure, G=plant.G, objective=objective, Q_nominal=Qn,
                         closest=closest, scale=scale)
    opti = nlp.opti
    s = nlp.scale
    opti.set_initial(nlp.L, start["L"])
    opti.set_initial(nlp.P, start["P"] / s)
    W = start["W"] / s
    t0 = 0.0
    if nlp.t is not None:
        Wm = np.diag(W) if structure == "diagonal" else W
        wmin = float(np.linalg.eigvalsh(sym(np.atleast_2d(Wm)))[0])
        t0 = min(0.0, wmin) - 1e-3 * max(1.0, float(np.abs(Wm).max()))
        opti.set_initial(nlp.t, t0)
    if structure == "diagonal":
        opti.set_initial(nlp.Fvec, np.maximum(np.asarray(W).ravel(), max(t0, 0.0) + 1e-8))
    else:
        k = W.shape[0]
        opti.set_initial(nlp.Fvec, chol_factor(project_psd(W - t0 * np.eye(k)))[tril_index(k)])
    X0, mu0 = modal_start(plant.A - start["L"] @ plant.C, nlp.blocks)
    opti.set_initial(nlp.X, X0)
    if nlp.mu is not None:
        opti.set_initial(nlp.mu, start.get("mu", mu0))
    opts = {"ipopt.max_iter": 500, "expand": True}
    opts.update(options or {})
    rep = solve_opti(opti, opts)
    Q = s * rep.value(nlp.Q).reshape(plant.n, plant.n)
    Qw = None if nlp.Qw is None else s * np.atleast_2d(rep.value(nlp.Qw))
    return rep, sym(Q), (None if Qw is None else sym(Qw))


def spectral_solve(plant, target, structure, objective, Qn, W0, terms, *, options=None, soft=False,
                   derivatives: str = "closed_form"):
    """The spectral-identity NLP from the decision covariance ``W0``.

    Structures ``"full"`` / ``"input"`` with objectives ``"min_trace"`` / ``"nearest"`` run
    with closed-form derivatives (:func:`build_spectral_nlpsol`: no symbolic differentiation,
    which dominated the time for n >= 20); the others by CasADi's symbolic derivatives
    (:func:`build_spectral_nlp`).
    """
    Wm = np.diag(np.ravel(W0)) if structure == "diagonal" else np.asarray(W0)
    scale = max(1.0, float(np.linalg.norm(Wm)))
    if not soft and structure in FAST_STRUCTURES and objective in FAST_OBJECTIVES \
            and derivatives == "closed_form":
        fast = build_spectral_nlpsol(plant.A, plant.C, np.asarray(plant.R, dtype=float), target,
                                     dt=plant.dt, structure=structure, G=plant.G, objective=objective,
                                     Q_nominal=Qn, W0=W0, scale=scale, terms=terms)
        opts = {"ipopt.max_iter": 500}
        opts.update(options or {})
        rep = solve_nlpsol(fast.nlp, fast.x0, fast.lbg, fast.ubg, opts, plugin=fast.options,
                           extra={"derivatives": "closed form"})
        Wd = fast.decision(rep.value())
        if structure == "full":
            return rep, sym(Wd), None
        return rep, sym(plant.G @ Wd @ plant.G.T), sym(Wd)
    nlp = build_spectral_nlp(plant.A, plant.C, np.asarray(plant.R, dtype=float), target, dt=plant.dt,
                             structure=structure, G=plant.G, objective=objective, Q_nominal=Qn, W0=W0,
                             scale=scale, terms=terms, soft=soft)
    opts = {"ipopt.max_iter": 500, "expand": True}  # SX evaluation: much faster derivatives
    opts.update(options or {})
    rep = solve_opti(nlp.opti, opts)
    s = nlp.scale
    Q = s * rep.value(nlp.Q).reshape(plant.n, plant.n)
    Qw = None if nlp.Qw is None else s * np.atleast_2d(rep.value(nlp.Qw))
    return rep, sym(Q), (None if Qw is None else sym(Qw))


def start_covariances(plant: Plant, target: NDArray, structure: str, Qn, seed: int, count: int, solver):
    """Initial decision covariances for the NLP, in order.

    1. Single output: the fixed-gain SDP's most positive Q at the (unique) gain -- a feasible
       point when the target is reachable.
    2. The scaled nominal noise whose Kalman filter comes closest to the target (the most
       reliable start with several outputs).
    3. Several outputs (where a placed gain is almost never a Kalman gain, so that SDP is
       infeasible): ``c I`` with ``c = ||L0 R L0'||``, ``L0`` the robust pole placement gain.
    4. Random positive definite matrices of the same scale (seeded), up to ``count``.
    """
    rng = np.random.default_rng(seed)
    R = np.asarray(plant.R, dtype=float)
    k = plant.n if structure == "full" else plant.m
    out = []
    L0 = None

    def shaped(W):
        return np.diag(W).copy() if structure == "diagonal" else W

    if plant.p == 1:
        L0 = placed_gain(plant, target)
        t_star, P0, Wm, _ = feasibility_margin(plant, L0, R, structure, solver)
        if P0 is not None:
            W0 = np.maximum(np.ravel(Wm), 0.0) if structure == "diagonal" else Wm
            out.append({"kind": "fixed-gain SDP", "W": W0, "L": L0, "P": P0, "margin": t_star})
    ks = kalman_start(plant, target, structure, Qn) if (count >= 2 or not out) else None
    if ks is not None:
        out.append({"kind": "scaled nominal", "W": shaped(ks[2]), "L": ks[1].L, "P": ks[1].P})
    # the scale of the other starts: the placed gain's ||L R L'|| (one output) or the nominal's
    if plant.p == 1 or ks is None:
        L0 = placed_gain(plant, target) if L0 is None else L0
        c = max(1e-12, float(np.linalg.norm(L0 @ R @ L0.T, 2)))
        if structure != "full":  # scale of Qw: Q = G Qw G'
            c = c / max(1e-12, float(np.linalg.norm(plant.G, 2)) ** 2)
    else:
        L0 = ks[1].L
        c = max(1e-12, float(np.linalg.norm(np.atleast_2d(ks[2]), 2)))
    P_guess = np.eye(plant.n) * max(1.0, float(np.linalg.norm(L0 @ R)))
    same = any(np.allclose(np.atleast_1d(st["W"]), shaped(c * np.eye(k)), rtol=1e-12, atol=0) for st in out)
    if (len(out) < count or not out) and not same:  # (the scaled nominal is often c I already)
        out.append({"kind": "scaled identity", "W": shaped(c * np.eye(k)), "L": L0, "P": P_guess})
    for _ in range(max(0, count - len(out))):
        F = rng.standard_normal((k, k))
        W = c * (F @ F.T / k + 0.1 * np.eye(k))
        out.append({"kind": "random", "W": shaped(W), "L": L0, "P": P_guess})
    return out[:max(count, 1)]


def rescue_starts(plant: Plant, target: NDArray, structure: str, starts: list, seed: int):
    """Further NLP starts after the first ones failed (a generator: built only when used)."""
    k = plant.n if structure == "full" else plant.m
    for st in starts:
        yield {**st, "kind": st["kind"] + " (adaptive barrier)"}
    if structure == "full":
        try:
            sol = solheim(plant, target)
        except (ValidationError, RiccatiError):
            sol = None
        if sol is not None and sol.success:
            yield {"kind": "sequential (Solheim)", "W": sol.Q, "L": sol.L, "P": sol.P}
    c = max(1e-12, max(float(np.linalg.norm(np.atleast_1d(st["W"]))) for st in starts))
    rng = np.random.default_rng(seed + 7919)
    for i in range(4):
        if i % 2 == 0:
            F = rng.standard_normal((k, k))
            W = c * (F @ F.T / k + 0.1 * np.eye(k))
        else:
            f = rng.standard_normal((k, 1))
            W = c * (f @ f.T / k + 1e-3 * np.eye(k))
        yield {"kind": "random (rescue)", "W": np.diag(W).copy() if structure == "diagonal" else W,
               "L": starts[0]["L"], "P": starts[0]["P"]}


def kalman_start(plant: Plant, target: NDArray, structure: str, Qn: NDArray | None):
    """``(pole error, ARE result, W, Q)``: the Kalman filter of a scaled nominal noise whose
    poles come closest to the target (scale searched on a log grid), or None."""
    n, m = plant.n, plant.m
    if Qn is not None:
        base = np.asarray(Qn, dtype=float)
    else:
        base = np.eye(n if structure == "full" else m)
    if structure == "diagonal":
        d = np.diag(base)
        base = np.diag(np.maximum(d, 1e-3 * max(1.0, float(np.max(d)))))
    # the scale by scipy's bare ARE solvers (fast), the chosen one by filter_are (checked)
    scored = []
    for a in np.logspace(-6, 6, 25):
        W = a * base
        err = fast_pole_error(plant, target, structure, np.diag(W).copy() if structure == "diagonal" else W)
        if np.isfinite(err):
            scored.append((err, a))
    order = [a for _, a in sorted(scored)] or list(np.logspace(-6, 6, 25))  # (none: filter_are decides)
    for a in order:
        W = a * base
        Q = W if structure == "full" else plant.G @ W @ plant.G.T
        try:
            are = filter_are(plant.replace(G=None, Q=sym(Q)))
        except (RiccatiError, OptDesignError):
            continue
        return pole_error(are.poles, target), are, W, sym(Q)
    return None


def fast_pole_error(plant: Plant, target: NDArray, structure: str, Wdec: NDArray) -> float:
    """:func:`pole_error` of the Kalman filter of a decision covariance (scipy's ARE solvers,
    no validation: the search's inner loop); inf where there is no stabilizing solution."""
    from scipy.linalg import schur, solve_discrete_are

    A, C, R = plant.A, plant.C, np.asarray(plant.R, dtype=float)
    n = A.shape[0]
    Q, _ = noise_of(structure, plant.G, Wdec)
    try:
        with np.errstate(all="ignore"):
            if plant.is_discrete:
                Pd = filter_dare_doubling(A, C, Q, R)  # fast; scipy's QZ solver where it fails
                poles = None if Pd is None else np.linalg.eigvals(A - filter_gain(A, C, R, Pd, True) @ C)
                if poles is None or not np.all(stable_poles(poles, True)):
                    Ps = solve_discrete_are(A.T, C.T, Q, R, balanced=False)
                    poles = np.linalg.eigvals(A - filter_gain(A, C, R, Ps, True) @ C)
            else:  # the stable invariant subspace of the Hamiltonian (ordered real Schur form)
                Rinv = np.linalg.inv(R)
                H = np.block([[A.T, -C.T @ Rinv @ C], [-Q, -A]])
                _, Z, sdim = schur(H, output="real", sort="lhp")
                if sdim != n:
                    return float("inf")
                P = np.linalg.solve(Z[:n, :n].T, Z[n:, :n].T).T
                poles = np.linalg.eigvals(A - P @ C.T @ Rinv @ C)
    except (np.linalg.LinAlgError, ValueError):
        return float("inf")
    if not np.all(np.isfinite(poles)) or not np.all(stable_poles(poles, plant.is_discrete)):
        return float("inf")
    return pole_error(poles, target)

