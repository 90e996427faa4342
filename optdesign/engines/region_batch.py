"""Every pole pattern of a region-mode round in one evaluation (issue 28).

The lockstep runner (:mod:`~optdesign.engines.eigenstructure_region_lockstep`) keeps one
:class:`~optdesign.engines.eigenstructure_region.RegionModel` per real/complex pole pattern (3-5 of
them on a plant's 8 starts); each BFGS round called every model that had running members, about 2
members per call.  On small plants a call costs numpy's per-call overhead, nearly independent of
the members it holds (measured on COMPleib REA2, n = 4: 0.37 ms for 1 member, 0.52 ms for 16; DIS1,
n = 8: 0.67 ms and 1.48 ms), so a round cost about one call per pattern, and within a call one
stacked QR, inverse and pole derivative per kind of pole (real, pair).

:class:`PatternBatch` evaluates the members of all patterns together.  Their free and pinned poles
are flattened once into tables (per member and slot: its pole variables, its coordinate columns, its
anchor), so that a round is one stacked QR for the aligned bases of every free pole of every member,
one objective (:func:`~optdesign.engines.eigenstructure.spectral_objective` or eta) and one stacked
pole derivative.  A call that holds a complex pair computes in complex arithmetic throughout -- a
real pole's basis and row too, real to rounding -- the same formulas as the per-kind code it
replaces (f and G equal to rounding on the runs of the benchmark; measured on 49 plants n <= 10,
``benchmarks/results/region.md``: 0.56x the CPU of one call per pattern).  A single model's
:meth:`RegionModel.evaluate_batch` is its own batch.

:func:`fixed_lockstep` runs the fixed-pole continuation of every start (each at its own poles) in
one BFGS batch: the starts' fixed-pole models as patterns whose poles are all pinned.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._deadline import Deadline
from .eigenstructure import FixedPoleModel, left_spectral_objective, spectral_objective
from .eigenstructure_region import RegionModel
from .quasi_newton import bfgs_minimize_batch
from .region_eta import eta_terms, pole_pairs
from .tolerances import STAGE_FTOL, STAGE_FTOL_DEFAULT, STAGE_GTOL

__all__ = ["PatternBatch", "fixed_lockstep"]

#: from this many states on, a call holding pairs computes its real poles and its all-real members
#: in real arithmetic, apart (two stacked QRs and objectives instead of one): measured on random
#: n = 20 and 30 plants (issue 28), where complex arithmetic for them cost more than the call saved
_SPLIT_N = 16


def _columns(start: NDArray, width: int) -> NDArray:
    """``(len(start), width)`` column indices ``start[i] + 0..width-1``."""
    return np.asarray(start, dtype=int)[:, None] + np.arange(width)[None, :]


class PatternBatch:
    """The members of several region models (one per pole pattern) evaluated together.

    Parameters
    ----------
    models : list of RegionModel (or of fixed-pole models as :func:`fixed_lockstep` wraps them)
        One per pole pattern, built for the same engine, region, pinned poles and interior point
        (their variable vectors have the same length).
    sizes : list of int
        Members per model; global member ``i`` is member ``i - sum(sizes[:g])`` of model ``g`` (the
        order of the stacked anchors, :meth:`refresh_anchors`).
    """

    def __init__(self, models: list[Any], sizes: list[int]) -> None:
        m0 = models[0]
        if any((m.size, m.r, m.rho, m.measure) != (m0.size, m0.r, m0.rho, m0.measure) for m in models):
            raise ValueError("PatternBatch: the models do not share one variable layout and region")
        self.models, self.sizes = models, list(sizes)
        self.map, self.rho, self.measure = m0.map, m0.rho, m0.measure
        eng = m0.engine
        n, R, r = eng.n, m0.r, eng.rank
        self.n, self.R, self.r = n, R, r
        self.owner = np.repeat(np.arange(len(models)), sizes)
        self.local = np.concatenate([np.arange(s) for s in sizes])
        self.total = int(sum(sizes))
        self.cplx = np.array([models[g].complex for g in self.owner], dtype=bool)
        fr, pr, fp, pp = [], [], [], []  # (member, slot, model's own index) per kind
        slots0 = np.zeros((self.total, n), dtype=complex)  # the pinned poles in their slots
        bi, bj, self._incidence = pole_pairs(n)
        self._bi, self._bj = bi, bj
        self._pair_on = np.zeros((self.total, bi.size), dtype=bool)  # the model's barrier pairs
        for i, g in enumerate(self.owner):
            m = models[g]
            fr += [(i, j, j) for j in range(m.nrf)]
            pr += [(i, m.nrf + q, q) for q in range(m.nr - m.nrf)]
            fp += [(i, m.nr + 2 * q, q) for q in range(m.npf)]
            pp += [(i, m.nr + 2 * (m.npf + q), q) for q in range(m.np - m.npf)]
            slots0[i] = m._slots
            on = np.zeros(bi.size, dtype=bool)
            on[np.searchsorted(bi * n + bj, m._bi * n + m._bj)] = True
            self._pair_on[i] = on
        self._slots0 = slots0
        self._any_pair_on = bool(self._pair_on.any())
        # one table of the free poles (the real ones first) and one of the pinned: per entry its
        # member, slot, coordinate columns as RegionModel lays them out (a real slot's R from R j; a
        # pair's R real parts from R nr, its imaginary parts from R (nr + np); a real entry's
        # "imaginary" columns are the zero column appended to the points) and pole variables
        size = m0.size
        self._free = self._table(
            fr, fp, r,
            cols=(lambda m, j: R * j, lambda m, j: R * (m.nr + j)),
            cols_im=(lambda m, j: 0, lambda m, j: R * (m.nr + m.np + j)),
            var=(lambda m, j: m.ncoord + j, lambda m, j: m.ncoord + m.nrf + j),
            var_b=(lambda m, j: size, lambda m, j: m.ncoord + m.nrf + m.npf + j))
        self._pinned = self._table(
            pr, pp, R,
            cols=(lambda m, j: R * (m.nrf + j), lambda m, j: R * (m.nr + m.npf + j)),
            cols_im=(lambda m, j: 0, lambda m, j: R * (m.nr + m.np + m.npf + j)))
        for T in (self._free, self._pinned):
            T["cols_im"][~T["pair"]] = size
        if pr or pp:
            B = [models[self.owner[i]].Npr[q] for i, _, q in pr]
            B += [models[self.owner[i]].Npp[q] for i, _, q in pp]
            self._pinned["B"] = np.stack(B).astype(complex if pp else float)
        self.refresh_anchors()

    def _table(self, reals, pairs, width: int, **fields) -> dict[str, Any]:
        """Flat per-entry indices of ``reals`` then ``pairs`` (``(member, slot, j)``, ``j`` the index
        within its model): member, slot, j, whether a pair, and per field in ``fields`` (a pair of
        functions ``(model, j) -> column``, for a real entry and for a pair) the column; ``cols`` and
        ``cols_im`` (a coordinate block's first column) become ``width`` columns from there."""
        rows = list(reals) + list(pairs)
        kind = [0] * len(reals) + [1] * len(pairs)
        out = {"mem": np.array([i for i, _, _ in rows], dtype=int),
               "slot": np.array([sl for _, sl, _ in rows], dtype=int),
               "j": np.array([j for _, _, j in rows], dtype=int),
               "pair": np.array(kind, dtype=bool)}
        models = [self.models[self.owner[i]] for i in out["mem"]]
        for name, fns in fields.items():
            col = np.array([fns[k](m, j) for m, j, k in zip(models, out["j"], kind, strict=True)], dtype=int)
            out[name] = _columns(col, width) if name.startswith("col") else col
        return out

    def refresh_anchors(self) -> None:
        """Stack the models' current anchors (after their ``set_anchor``) per free-pole entry."""
        self._selected: dict[bytes, tuple[dict[str, Any], dict[str, Any] | None]] = {}
        E = self._free
        if not E["mem"].size:
            return
        stack = [(self.models[self.owner[i]].anchor_p if pair else self.models[self.owner[i]].anchor_r)
                 [self.local[i], j] for i, j, pair in zip(E["mem"], E["j"], E["pair"], strict=True)]
        E["anchor"] = np.stack(stack).astype(complex if E["pair"].any() else float)

    # ------------------------------------------------------------------ evaluation
    def evaluate(self, Z: NDArray, rows: NDArray, objective: str, k: int | None, mu: float
                 ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Objective + barrier and gradient of the members ``rows`` (global indices) at the points
        ``Z`` (len(rows), size), each in its own model's terms: ``(f (s,), G (s, size))``, ``f = inf``
        (and ``G = 0``) for a member with two poles at one point or a basis past its chart."""
        s, size = Z.shape
        Zx = np.zeros((s, size + 1))  # the zero column of the real entries' "imaginary" parts
        Zx[:, :size] = Z
        E, Ep = self._tables(rows)
        pm, slot, nre = E["pm"], E["slot"], int(E["nre"])
        f, Gx = np.full(s, math.inf), np.zeros_like(Zx)
        # the free poles through the map, then every pole in its slot
        if pm.size:
            lr, dlr = self.map.real(Zx[pm[:nre], E["var"][:nre]])
            ab = Zx[pm[nre:], E["var"][nre:]], Zx[pm[nre:], E["var_b"][nre:]]
            sg, om, sa, sb, wa, wb = self.map.pair(*ab)
        else:  # fixed poles only (fixed_lockstep)
            lr = sg = om = np.zeros(0)
        up = sg + 1j * om
        P = self._slots0[rows].copy()
        P[pm[:nre], slot[:nre]] = lr
        P[pm[nre:], slot[nre:]] = up
        P[pm[nre:], slot[nre:] + 1] = up.conj()
        bar, cbar, ok = self._barrier(P, rows, mu)
        if not ok.any():
            return f, Gx[:, :size]
        cplx = bool(nre < pm.size or (Ep is not None and Ep["nre"] < Ep["pm"].size))
        # at sizes where arithmetic, not calls, is the cost: real arithmetic for the real poles and
        # for the all-real patterns' members, as their own models compute them
        split = bool(cplx and self.n >= _SPLIT_N)
        # the aligned bases of the free poles (one stacked QR per kind), the rows of W
        W = np.zeros((s, self.n, self.n), dtype=complex if cplx else float)
        if pm.size:
            anchor = E["anchor"] if cplx else E["anchor"].real
            lam = np.concatenate([lr, up]) if cplx else lr
            kinds = self._kinds(nre, pm.size, split)
            al = []
            for sl in kinds:
                real = split and sl.stop == nre  # the real poles of a split call
                al.append(self.models[0]._aligned((lam[sl].real if real else lam[sl])[:, None],
                                                  (anchor[sl].real if real else anchor[sl])[:, None]))
            N, ov, Q1, R1, e, Ev = (np.concatenate([x[:, 0] if x.ndim > 1 else x for x in xs])
                                    if len(kinds) > 1 else (xs[0][:, 0] if xs[0].ndim > 1 else xs[0])
                                    for xs in zip(*al, strict=True))
            ok[pm[~(ov > RegionModel.overlap_floor(objective))]] = False
            c = self._put(W, Zx, E, N, cplx)
        if Ep is not None:
            self._put(W, Zx, Ep, Ep["B"] if cplx else Ep["B"].real, cplx)
        idx = np.flatnonzero(ok)
        if not idx.size:
            return f, Gx[:, :size]
        fs, K, cp = self._objective(W[idx], P[idx], objective, k, self.cplx[rows[idx]] if split else None)
        f[idx] = fs + bar[idx]
        Kf = np.zeros((s, self.n, self.n), dtype=K.dtype)
        Kf[idx] = K
        cs = cbar.copy()
        cs[idx] += cp
        # coordinates: B^H K per slot (a pair's two rows: 2 B^H K of its upper one)
        parts = ([(E, N)] if pm.size else []) + ([(Ep, Ep["B"])] if Ep is not None and Ep["pm"].size else [])
        for T, B in parts:
            z = np.einsum("ekr,ek->er", B.conj(), Kf[T["pm"], T["slot"]])
            z[T["nre"]:] *= 2.0
            Gx[T["pm"][:, None], T["cols"]] = z.real
            Gx[T["pm"][T["nre"]:, None], T["cols_im"][T["nre"]:]] = z[T["nre"]:].imag
        # poles: the bases' derivative (RegionModel._pole_derivative) + the explicit terms, folded,
        # then the chain rule through the map
        if pm.size:
            Kj = Kf[pm, slot]
            if not cplx:
                Kj = Kj.real
            d = [np.zeros(pm.size), np.zeros(pm.size)]
            for sl in kinds:
                real = not cplx or (split and sl.stop == nre)
                one = (x[sl, None].real if real else x[sl, None]  # each entry its own "member"
                       for x in (N, anchor, Q1, R1, e, Ev, Kj, c))
                derivative: Any = self.models[0]._pole_derivative
                for i, dd in enumerate(derivative(*one, (1.0,) if real else (1.0, 1j))):
                    d[i][sl] = dd[:, 0]
            Gx[pm[:nre], E["var"][:nre]] = (d[0][:nre] + cs[pm[:nre], slot[:nre]].real) * dlr
            gu, gl = cs[pm[nre:], slot[nre:]], cs[pm[nre:], slot[nre:] + 1]
            if cplx:
                gs = 2.0 * d[0][nre:] + (gu + gl).real
                gw = 2.0 * d[1][nre:] + (gu - gl).imag
                Gx[pm[nre:], E["var"][nre:]] = gs * sa + gw * wa
                Gx[pm[nre:], E["var_b"][nre:]] = gs * sb + gw * wb
        G = Gx[:, :size]
        G[~np.isfinite(f)] = 0.0
        return f, G

    @staticmethod
    def _kinds(nre: int, ne: int, split: bool) -> list[slice]:
        """The groups of free-pole entries computed together: all of them, or (``split``) the real
        ones and the pairs."""
        if split and 0 < nre < ne:
            return [slice(0, nre), slice(nre, ne)]
        return [slice(0, ne)]

    def _tables(self, rows: NDArray) -> tuple[dict[str, Any], dict[str, Any] | None]:
        """The free and pinned tables of the members ``rows`` (:meth:`_select`), kept until the next
        :meth:`refresh_anchors`: a BFGS batch evaluates the same running members round after round
        (issue 28: the selection was 4 % of a small plant's design)."""
        key = np.asarray(rows, dtype=np.intp).tobytes()
        hit = self._selected.get(key)
        if hit is None:
            where = np.full(self.total, -1)
            where[rows] = np.arange(rows.size)
            hit = (self._select(self._free, where),
                   self._select(self._pinned, where) if self._pinned["mem"].size else None)
            self._selected[key] = hit
        return hit

    @staticmethod
    def _select(T: dict[str, Any], where: NDArray) -> dict[str, Any]:
        """The entries of table ``T`` whose member is evaluated, with their position ``pm`` among the
        points and ``nre``, how many of them are real (they come first)."""
        pos = where[T["mem"]]
        e = np.flatnonzero(pos >= 0)
        out = {key: v[e] for key, v in T.items()}
        out.update(pm=pos[e], nre=int(np.count_nonzero(~out["pair"])))
        return out

    @staticmethod
    def _put(W: NDArray, Zx: NDArray, T: dict[str, Any], B: NDArray, cplx: bool) -> NDArray:
        """Each entry's eigenvector row ``B c`` into ``W`` (a pair: the row and its conjugate);
        returns the coordinates ``c`` (complex in a complex call)."""
        pm, nre = T["pm"], T["nre"]
        c = Zx[pm[:, None], T["cols"]]
        if cplx:
            c = c + 1j * Zx[pm[:, None], T["cols_im"]]
        w = np.einsum("ekr,er->ek", B, c)
        W[pm, T["slot"]] = w
        W[pm[nre:], T["slot"][nre:] + 1] = w[nre:].conj()
        return c

    def _barrier(self, P: NDArray, rows: NDArray, mu: float) -> tuple[NDArray, NDArray, NDArray]:
        """The separation barrier ``-mu sum log(|lambda_i - lambda_j| / rho)`` of each member over its
        model's pole pairs (at least one pole free): ``(value, per-slot complex gradient (s, n),
        finite)``.

        The map puts every pole in the closed region, so two poles may meet on its boundary (a pair
        at the real axis, two real poles at one boundary point): a double eigenvalue, whose
        eigenvectors no one can compute to the digits the objective is reported with.  This term
        keeps them apart, by ``~mu / |df/dlambda|`` at the end of the continuation.
        """
        if not self._any_pair_on:  # fixed poles only: no barrier
            return np.zeros(P.shape[0]), np.zeros(P.shape, dtype=complex), np.ones(P.shape[0], dtype=bool)
        on = self._pair_on[rows]
        D = P[:, self._bi] - P[:, self._bj]
        d2 = D.real**2 + D.imag**2
        inside = np.all((d2 > 0) | ~on, axis=1)
        d2 = np.where(on & (d2 > 0), d2, self.rho**2)
        val = -0.5 * mu * np.log(d2 / self.rho**2).sum(axis=1)
        c = (np.where(on, -mu * D / d2, 0.0)) @ self._incidence
        return np.where(inside, val, math.inf), c, inside

    def _objective(self, W: NDArray, P: NDArray, objective: str, k: int | None, kinds: NDArray | None = None
                   ) -> tuple[NDArray, NDArray, NDArray]:
        """``(f, K = df/dW, explicit per-slot pole gradient)`` of the members' ``W`` and poles ``P``:
        the measured eigenvectors' kappa2 / bound / kappa_fro (member by member where the stacked
        inverse fails) or :func:`~optdesign.engines.region_eta.eta_terms`.  ``kinds`` (per member,
        whether its model has pairs): the all-real members in real arithmetic, apart."""
        if kinds is not None and 0 < kinds.sum() < kinds.size:
            out = [np.empty(W.shape[0]), np.zeros(W.shape, dtype=complex), np.zeros(P.shape, dtype=complex)]
            for sel in (~kinds, kinds):
                part = self._objective(W[sel] if sel is kinds else W[sel].real, P[sel], objective, k)
                for o, v in zip(out, part, strict=True):
                    o[sel] = v
            return out[0], out[1], out[2]
        if objective == "eta":
            return eta_terms(P, W, k)
        try:
            fs, K = _spectral(W, objective, k, self.measure)
        except np.linalg.LinAlgError:
            fs, K = np.full(W.shape[0], math.inf), np.zeros_like(W)
            for i in range(W.shape[0]):
                try:
                    (fs[i],), (K[i],) = _spectral(W[i : i + 1], objective, k, self.measure)
                except np.linalg.LinAlgError:
                    pass
        return fs, K, np.zeros(P.shape, dtype=complex)


def _spectral(W: NDArray, objective: str, k: int | None, measure: str) -> tuple[NDArray, NDArray]:
    """``(f, K = df/dW)`` of the measured eigenvectors (right: ``W^-1``; left: the rows of ``W``)."""
    if measure == "left":
        f, K = left_spectral_objective(W, objective, k)
    else:
        f, K, _ = spectral_objective(W, objective, k)
    assert K is not None  # a gradient was asked for
    return f, K


class _Pinned:
    """A :class:`~optdesign.engines.eigenstructure.FixedPoleModel` as a region model whose poles are
    all pinned (its coordinate layout is the pinned part of RegionModel's: real slots, then pairs'
    real parts, then their imaginary parts), for :func:`fixed_lockstep`."""

    nrf = npf = 0
    rho = 1.0
    map = None
    _bi = _bj = np.zeros(0, dtype=int)

    def __init__(self, model: FixedPoleModel) -> None:
        self.engine, self.size, self.r = model.engine, model.size, model.r
        self.measure, self.complex = model.measure, model.complex
        self.ncoord = model.size
        self.nr, self.np = model.slots.nr, model.slots.npair
        self.Npr, self.Npp = model.Nr, model.Np
        self._slots = model.poles.astype(complex)


def fixed_lockstep(models: list[FixedPoleModel], X0: NDArray, objective: str, deadline: Deadline,
                   max_iter: int, stages: tuple[int | None, ...]) -> list[tuple[NDArray, int, int, str]]:
    """:func:`~optdesign.engines.eigenstructure_fixed.run_starts` of one start per model (each at its
    own poles, ``X0`` (s, size) their coordinates), all in one BFGS batch per stage: one evaluation
    per round for all (:class:`PatternBatch`) instead of one per start.  Each member's iterates are
    those of its own ``run_starts`` (a BFGS member does not see the others; one start per model has
    no duplicates to drop).  eta's value is ``eta^2`` itself, the fixed-pole model's (the batch's own
    is ``log eta^2``, the region stages'), so that each start follows its own ``run_starts`` path to
    rounding.  Per model ``(normalized x, iterations, evaluations, reason)``."""
    batch = PatternBatch([_Pinned(m) for m in models], [1] * len(models))
    X = np.array(X0, dtype=float)
    s = X.shape[0]
    its, evs, reasons = np.zeros(s, int), np.zeros(s, int), ["converged"] * s
    H: list[NDArray | None] = [None] * s
    rows = np.arange(s)
    for k in stages:
        if deadline.expired:
            reasons = ["time_limit"] * s
            break

        def fun(Z, idx, _k=k):
            f, G = batch.evaluate(Z, rows[idx], objective, _k, 0.0)
            if objective == "eta":  # eta^2 itself, as run_starts' fixed-pole model (not its log)
                e = np.exp(f)
                return e, G * np.where(np.isfinite(e), e, 0.0)[:, None]
            return f, G

        res, Hs = bfgs_minimize_batch(fun, X, max_iter=max_iter, ftol=STAGE_FTOL.get(k, STAGE_FTOL_DEFAULT),
                                      gtol=0.0 if k is None else STAGE_GTOL, deadline=deadline, H0=H,
                                      pass_index=True)
        for i, r in enumerate(res):
            X[i], H[i], reasons[i] = r.x, Hs[i], r.reason
            its[i] += r.iterations
            evs[i] += r.evaluations
    return [(m.normalize(X[i]), int(its[i]), int(evs[i]), reasons[i]) for i, m in enumerate(models)]
