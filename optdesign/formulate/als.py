r"""The autocovariance least-squares (ALS) stacking: innovations, their autocovariances, and the
linear map from the noise covariances to them.  Builds, never solves
(:func:`optdesign.design.noise_estimation.estimate_noise` solves).

Model (discrete, predictor form).  A stable gain L runs the filter
``x_hat[k+1] = A x_hat[k] + B u[k] + L e[k]``, ``e[k] = y[k] - C x_hat[k]``; the estimation error
``eps[k] = x[k] - x_hat[k]`` obeys ``eps[k+1] = Abar eps[k] + w_s[k] - L v[k]`` with
``Abar = A - L C``, ``E[w_s w_s'] = W`` (the state-space process noise, ``G Q G'``) and
``E[v v'] = R``.  In steady state

    P = Abar P Abar' + W + L R L',
    C_0 = E[e[k] e[k]'] = C P C' + R,
    C_j = E[e[k+j] e[k]'] = C Abar^j P C' - C Abar^(j-1) L R      (j >= 1),

so the first ``lags`` autocovariances are *linear* in (W, R), hence in (Q, R) for any linear
parametrization of Q (full, diagonal, through a G matrix; for a continuous plant through Van
Loan's integral).  This is the single-column ALS form of Rajamani & Rawlings (2009), eq. (9)-(12),
written for the unknowns' basis directly instead of through Kronecker and duplication matrices.

The data vector holds the unique entries of the sample autocovariances: at lag 0 the upper
triangle (``C_0`` is symmetric: the duplicated entries would make the covariance of the data
singular, which the optimal weighting inverts), at lags ``1 .. lags-1`` every entry.

References
----------
Odelson, B. J., Rajamani, M. R. & Rawlings, J. B., "A new autocovariance least-squares method for
estimating noise covariances", Automatica 42(2) (2006) 303-308.
Rajamani, M. R. & Rawlings, J. B., "Estimation of the disturbance structure from data using
semidefinite programming and optimal weighting", Automatica 45(1) (2009) 142-148.
Bartlett, M. S., "On the theoretical specification and sampling properties of autocorrelated
time-series", J. R. Stat. Soc. Suppl. 8(1) (1946) 27-41 (the covariance of sample autocovariances).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import scipy.fft
import scipy.linalg
from numpy.typing import NDArray

__all__ = ["InnovationFilter", "AutocovAccumulator", "unique_mask", "stein_solve", "als_matrix",
           "model_autocov", "bartlett_covariance", "symmetric_basis", "ALSProgram", "FFT_LAGS",
           "KRON_MAX_N"]

#: lags from which the autocovariances are computed by FFT (benchmarks/results/als.md, 10^5 samples: at
#: p = 3 direct 0.015 s / FFT 0.019 s at 64 lags, 0.030 / 0.020 at 128; at p = 1 even at 128)
FFT_LAGS = 96
#: largest state dimension solved by one LU of ``I - Abar (x) Abar`` (n^2 x n^2); larger: per column
KRON_MAX_N = 30
#: bytes one autocovariance chunk may hold (bounded memory for long records)
CHUNK_BYTES = 32 * 2**20


class InnovationFilter:
    r"""The innovations ``e[k] = y[k] - C x_hat[k]`` of the fixed-gain predictor, streamed.

    ``x_hat[k+1] = Abar x_hat[k] + L y[k] + B u[k]`` is run in blocks of ``b`` samples: the state
    at each block start follows ``x[j+1] = Abar^b x[j] + H v_j`` (one small matrix-vector
    product per block) and the innovations inside every block of a chunk come at once from
    ``e = y - O x[j] - T v_j`` (``O = [C; C Abar; ...]``, T the block-Toeplitz matrix of the
    Markov parameters ``C Abar^(t-1-s) [L, B]``) -- matrix products over all blocks instead of a
    Python loop over samples.  The state is carried from chunk to chunk.

    Parameters
    ----------
    Abar : (n, n) ndarray
        ``A - L C``, stable.
    L : (n, p) ndarray
    C : (p, n) ndarray
    B : (n, nu) ndarray or None
    x0 : (n,) ndarray, optional
        Initial estimate (zero by default).
    """

    def __init__(self, Abar: NDArray, L: NDArray, C: NDArray, B: NDArray | None = None,
                 x0: NDArray | None = None) -> None:
        n, p = L.shape
        nu = 0 if B is None else B.shape[1]
        q = p + nu
        self.n, self.p, self.q = n, p, q
        Bin = L if B is None else np.hstack([L, B])
        b = int(max(4, min(64, 256 // max(p, q, 1))))
        pw = [np.eye(n)]
        for _ in range(b):
            pw.append(Abar @ pw[-1])
        self.b = b
        self.Ab = pw[b]
        self.Abar, self.Bin, self.C = Abar, Bin, C
        # H v_j = sum_s Abar^(b-1-s) Bin v[s]   (v_j flattened sample-major: index s q + r)
        self.H = np.hstack([pw[b - 1 - s] @ Bin for s in range(b)])
        self.O = np.vstack([C @ pw[t] for t in range(b)])                  # (b p, n)
        T = np.zeros((b * p, b * q))
        marks = [C @ pw[k] @ Bin for k in range(b)]
        for t in range(1, b):
            for s in range(t):
                T[t * p:(t + 1) * p, s * q:(s + 1) * q] = marks[t - 1 - s]
        self.T = T
        self.x = np.zeros(n) if x0 is None else np.asarray(x0, dtype=float).copy()

    def run(self, y: NDArray, u: NDArray | None = None) -> NDArray:
        """Innovations of the chunk ``y`` (shape (T, p)), ``u`` (T, nu) beside; the state carries on."""
        T = y.shape[0]
        v = y if u is None else np.hstack([y, u])
        b, p, q = self.b, self.p, self.q
        nb = T // b
        out = np.empty_like(y, dtype=float)
        if nb:
            V = v[:nb * b].reshape(nb, b * q)
            D = V @ self.H.T                                      # (nb, n)
            X = np.empty((nb, self.n))
            x = self.x
            Ab = self.Ab
            for j in range(nb):
                X[j] = x
                x = Ab @ x + D[j]
            self.x = x
            E = y[:nb * b].reshape(nb, b * p) - X @ self.O.T - V @ self.T.T
            out[:nb * b] = E.reshape(nb * b, p)
        x = self.x
        for k in range(nb * b, T):                                   # the remainder, sample by sample
            out[k] = y[k] - self.C @ x
            x = self.Abar @ x + self.Bin @ v[k]
        self.x = x
        return out


def unique_mask(p: int, lags: int) -> NDArray[np.bool_]:
    """The entries of the ``(lags, p, p)`` autocovariance stack kept in the data vector: the upper
    triangle at lag 0, everything at lags >= 1 (flattened C-order)."""
    mask = np.ones((lags, p, p), dtype=bool)
    mask[0] = np.triu(np.ones((p, p), dtype=bool))
    return mask.ravel()


class AutocovAccumulator:
    r"""Sums ``S_i = sum_k e[k+i] e[k]'`` and pair counts for lags ``0``, ..., ``lags - 1``, streamed.

    Each pair is counted when its later sample arrives; the last ``lags - 1`` samples are kept
    between pushes, so memory is bounded by the chunk.  Direct (one ``(p, T) @ (T, p)`` product
    per lag) below :data:`FFT_LAGS` lags, by FFT (``p`` real FFTs of the chunk and of the
    extended window, ``p^2`` inverse FFTs) from there.

    Parameters
    ----------
    p : int
    lags : int
    method : {"auto", "direct", "fft"}
    """

    def __init__(self, p: int, lags: int, method: str = "auto") -> None:
        self.p, self.lags = p, lags
        self.method = ("fft" if lags >= FFT_LAGS else "direct") if method == "auto" else method
        self.tail = np.zeros((lags - 1, p))
        self.seen = 0
        self.sums = np.zeros((lags, p, p))
        self.counts = np.zeros(lags)

    def chunk_length(self) -> int:
        """Samples per push that keep the FFT work arrays within ``CHUNK_BYTES``."""
        per = 16 * max(1, self.p) ** 2 + 64 * self.p
        return int(max(4 * self.lags, min(2**18, CHUNK_BYTES // per)))

    def push(self, e: NDArray) -> tuple[NDArray, NDArray]:
        """Add the innovations ``e`` (T, p); return this push's sums ``(lags, p, p)`` and counts."""
        T, N = e.shape[0], self.lags
        z = np.vstack([self.tail, e]) if N > 1 else e
        t0 = N - 1
        if self.method == "fft" and N > 1:
            nfft = scipy.fft.next_fast_len(T + N - 1, real=True)
            X = np.conj(np.fft.rfft(e, nfft, axis=0))                # (F, p)
            Wf = np.fft.rfft(z, nfft, axis=0)
            r = np.fft.irfft(X[:, :, None] * Wf[:, None, :], nfft, axis=0)   # (nfft, p, p)
            s = r[t0 - np.arange(N)]              # S_i[a, b] = sum_s e_a[s] z_b[s + t0 - i]
        else:
            s = np.empty((N, self.p, self.p))
            for i in range(N):
                s[i] = z[t0:].T @ z[t0 - i:t0 - i + T]
        g0 = self.seen
        cnt = np.maximum(0, g0 + T - np.maximum(g0, np.arange(N))).astype(float)
        self.sums += s
        self.counts += cnt
        self.seen += T
        if N > 1:
            self.tail = z[-(N - 1):].copy()
        return s, cnt

    def autocov(self) -> NDArray:
        """``(lags, p, p)``: ``S_i / count_i``."""
        return self.sums / self.counts[:, None, None]


def stein_solve(Abar: NDArray, Ws: NDArray) -> NDArray:
    """``P_k = Abar P_k Abar' + W_k`` for a stack ``Ws`` (k, n, n) at once.

    One LU of ``I - Abar (x) Abar`` for ``n <= KRON_MAX_N``; otherwise scipy's
    ``solve_discrete_lyapunov`` per matrix."""
    n = Abar.shape[0]
    k = Ws.shape[0]
    if k == 0:
        return np.zeros((0, n, n))
    if n <= KRON_MAX_N:
        K = np.eye(n * n) - np.kron(Abar, Abar)
        lu = scipy.linalg.lu_factor(K, check_finite=False)
        Ps = scipy.linalg.lu_solve(lu, Ws.reshape(k, n * n).T, check_finite=False).T.reshape(k, n, n)
    else:
        Ps = np.stack([scipy.linalg.solve_discrete_lyapunov(Abar, W) for W in Ws])
    return 0.5 * (Ps + np.swapaxes(Ps, 1, 2))


def _autocov_of(Abar: NDArray, C: NDArray, L: NDArray, Ps: NDArray, Rs: NDArray, lags: int) -> NDArray:
    """``(k, lags, p, p)`` model autocovariances for stacks of P (k, n, n) and R (k, p, p)."""
    p, n = C.shape
    O = [C]
    for _ in range(lags - 1):
        O.append(O[-1] @ Abar)
    Ostack = np.stack(O)                                              # (lags, p, n): C Abar^i
    PC = Ps @ C.T                                                     # (k, n, p)
    Y = np.einsum("ian,knb->kiab", Ostack, PC)
    Y[:, 0] += Rs
    if lags > 1:
        OL = Ostack[:lags - 1] @ L                                    # (lags-1, p, p): C Abar^(i-1) L
        Y[:, 1:] -= np.einsum("iac,kcb->kiab", OL, Rs)
    return Y


def als_matrix(Abar: NDArray, C: NDArray, L: NDArray, W_basis: NDArray, R_basis: NDArray,
               lags: int) -> NDArray:
    r"""The ALS matrix: column ``j`` holds the unique autocovariance entries of basis direction j.

    Parameters
    ----------
    Abar : (n, n) ndarray
        ``A - L C`` (stable).
    C : (p, n) ndarray
    L : (n, p) ndarray
    W_basis : (kq, n, n) ndarray
        The state-space process-noise covariance of each Q-unknown's basis direction.
    R_basis : (kr, p, p) ndarray
        The (discrete) measurement-noise covariance of each R-unknown's basis direction.
    lags : int

    Returns
    -------
    (m_rows, kq + kr) ndarray
        ``m_rows = p (p + 1) / 2 + (lags - 1) p^2`` (:func:`unique_mask`).
    """
    p, n = C.shape
    kq, kr = W_basis.shape[0], R_basis.shape[0]
    rhs = np.concatenate([W_basis, L @ R_basis @ L.T]) if kr else W_basis
    Ps = stein_solve(Abar, rhs)
    Rs = np.concatenate([np.zeros((kq, p, p)), R_basis])
    Y = _autocov_of(Abar, C, L, Ps, Rs, lags)
    mask = unique_mask(p, lags)
    return Y.reshape(kq + kr, -1)[:, mask].T


def model_autocov(Abar: NDArray, C: NDArray, L: NDArray, W: NDArray, R: NDArray, lags: int) -> NDArray:
    """The model's innovation autocovariances ``C_0``, ..., ``C_(lags-1)``, shape (lags, p, p)."""
    P = stein_solve(Abar, (W + L @ R @ L.T)[None])
    return _autocov_of(Abar, C, L, P, R[None], lags)[0]


def _decay_horizon(Abar: NDArray, eps: float) -> int:
    """Steps until ``rho(Abar)^k <= eps`` (at least 1, at most 5000)."""
    rho = float(np.max(np.abs(np.linalg.eigvals(Abar)))) if Abar.size else 0.0
    if rho <= 0.0:
        return 1
    return int(min(5000, max(1, math.ceil(math.log(eps) / math.log(rho)))))


def bartlett_covariance(Abar: NDArray, C: NDArray, L: NDArray, W: NDArray, R: NDArray, lags: int,
                        counts: NDArray) -> NDArray:
    r"""Covariance of the data vector (the unique sample autocovariances) for Gaussian innovations
    of the model (W, R) (Bartlett 1946)::

        cov(c_ab(i), c_cd(j)) = (1 / n_ij) sum_s [ g_ac(s + i - j) g_bd(s) + g_ad(s + i) g_bc(s - j) ]

    with ``g(h) = E[e[k+h] e[k]']``, ``g(-h) = g(h)'``, the sum truncated where ``rho(Abar)^|s|``
    falls below the double-precision unit roundoff, and ``n_ij = sqrt(count_i count_j)``.

    Returns
    -------
    (m_rows, m_rows) ndarray
        Symmetric positive semidefinite.
    """
    p = C.shape[0]
    H = _decay_horizon(Abar, float(np.finfo(float).eps)) + 2 * lags
    g = model_autocov(Abar, C, L, W, R, H + 1)                        # (H+1, p, p), h >= 0
    Gam = np.concatenate([np.swapaxes(g[:0:-1], 1, 2), g])            # h = -H .. H at index h + H
    size = 2 * H + 1
    T1 = np.empty((2 * lags - 1, p, p, p, p))
    for d in range(-(lags - 1), lags):
        lo, hi = max(0, -d), min(size, size - d)
        T1[d + lags - 1] = np.einsum("sac,sbd->abcd", Gam[lo + d:hi + d], Gam[lo:hi])
    T2 = np.empty((2 * lags - 1, p, p, p, p))
    for sg in range(2 * lags - 1):
        lo, hi = 0, size - sg
        T2[sg] = np.einsum("sad,sbc->abcd", Gam[lo + sg:hi + sg], Gam[lo:hi])
    i = np.arange(lags)
    S = T1[(i[:, None] - i[None, :]) + lags - 1] + T2[i[:, None] + i[None, :]]   # (N, N, p, p, p, p)
    S = S.transpose(0, 2, 3, 1, 4, 5).reshape(lags * p * p, lags * p * p)
    nij = np.sqrt(np.repeat(counts, p * p)[:, None] * np.repeat(counts, p * p)[None, :])
    S = S / nij
    mask = unique_mask(p, lags)
    S = S[np.ix_(mask, mask)]
    return 0.5 * (S + S.T)


def symmetric_basis(k: int, structure: str) -> NDArray:
    """Basis of the symmetric ``k x k`` unknowns: ``"full"`` (``E_ii``, ``E_ij + E_ji`` for i < j,
    so the coordinates are the entries of the upper triangle, row by row) or ``"diagonal"``."""
    if structure == "diagonal":
        out = np.zeros((k, k, k))
        out[np.arange(k), np.arange(k), np.arange(k)] = 1.0
        return out
    iu = np.triu_indices(k)
    out = np.zeros((len(iu[0]), k, k))
    t = np.arange(len(iu[0]))
    out[t, iu[0], iu[1]] = 1.0
    out[t, iu[1], iu[0]] = 1.0
    return out


class ALSProgram:
    r"""The ALS semidefinite program on the reduced least-squares data (built once, solved for new
    right-hand sides).

    With the (weighted) ALS matrix reduced by a QR factorization, ``A_w = Q_r R_r``, the objective
    ``||A_w theta - b_w||^2 = ||R_r theta - z||^2 + const`` (``z = Q_r' b_w``) has ``k`` rows
    whatever the number of lags and outputs; ``theta`` are the coordinates of Q and R in their
    bases.  Q and R are cvxpy matrix variables (PSD), diagonal Q a nonnegative vector; the
    coordinates are linear in their entries.  ``reusable``: ``z`` is a Parameter (bootstrap
    re-solves change only it); otherwise the problem is built with the constant ``z`` of each solve.
    Q and R are scaled by ``scale_q``, ``scale_r`` (their magnitudes) and the objective by
    ``scale_obj`` so the solver sees numbers near one.

    Parameters
    ----------
    Rr : (k, k) ndarray
    m, p : int
        Orders of Q and R.
    q_diagonal : bool
    trace_penalty : float
        ``rho`` of ``+ rho tr(Q)``.
    scale_q, scale_r, scale_obj : float
    reusable : bool
    """

    def __init__(self, Rr: NDArray, m: int, p: int, q_diagonal: bool, trace_penalty: float,
                 scale_q: float, scale_r: float, scale_obj: float, reusable: bool = True) -> None:
        import cvxpy as cp

        self.cp = cp
        kq = m if q_diagonal else m * (m + 1) // 2
        self.kq, self.m, self.p = kq, m, p
        self.scale_q, self.scale_r, self.scale_obj = scale_q, scale_r, scale_obj
        self.rho, self.q_diagonal = trace_penalty, q_diagonal
        self.MR = (Rr[:, kq:] * scale_r) @ _upper_selector(p)          # on vec(R) (F order)
        self.MQ = Rr[:, :kq] * scale_q if q_diagonal else (Rr[:, :kq] * scale_q) @ _upper_selector(m)
        self.reusable = reusable
        self.z: Any = cp.Parameter(Rr.shape[0]) if reusable else None
        self.problem: Any = self._build(self.z) if reusable else None

    def _build(self, z: Any) -> Any:
        """The cvxpy problem for ``z`` (a Parameter: built once, DPP; an array: built per solve, which
        skips DPP's compilation for a single solve)."""
        cp = self.cp
        m, p = self.m, self.p
        self.Rv = cp.Variable((p, p), symmetric=True)
        if self.q_diagonal:
            self.Qv = cp.Variable(m, nonneg=True)
            lin = self.MQ @ self.Qv + self.MR @ cp.vec(self.Rv, order="F")
            trq = cp.sum(self.Qv)
            cons = [self.Rv >> 0]
        else:
            self.Qv = cp.Variable((m, m), symmetric=True)
            lin = self.MQ @ cp.vec(self.Qv, order="F") + self.MR @ cp.vec(self.Rv, order="F")
            trq = cp.trace(self.Qv)
            cons = [self.Qv >> 0, self.Rv >> 0]
        obj = cp.sum_squares(lin - z) / self.scale_obj
        if self.rho > 0:
            obj = obj + (self.rho * self.scale_q / self.scale_obj) * trq
        return cp.Problem(cp.Minimize(obj), cons)

    def at(self, z: NDArray) -> Any:
        """The cvxpy problem for the data ``z`` (its parameter set, or rebuilt when not reusable): built
        here, solved by the caller through the backend
        (:func:`optdesign.backends.cvxpy_backend.solve_cvxpy`)."""
        if self.reusable:
            self.z.value = z
        else:
            self.problem = self._build(z)
        return self.problem

    def covariances(self) -> tuple[NDArray | None, NDArray | None]:
        """``(Q, R)`` of the last solve, unscaled; None when no solution is present."""
        if self.Qv.value is None or self.Rv.value is None:
            return None, None
        Qv = np.asarray(self.Qv.value, dtype=float)
        Q = np.diag(Qv) if Qv.ndim == 1 else 0.5 * (Qv + Qv.T)
        R = np.asarray(self.Rv.value, dtype=float)
        return Q * self.scale_q, 0.5 * (R + R.T) * self.scale_r


def _upper_selector(k: int) -> NDArray:
    """``(k (k+1)/2, k^2)``: picks the upper-triangle entries (row by row) from a column-major vec."""
    iu = np.triu_indices(k)
    S = np.zeros((len(iu[0]), k * k))
    S[np.arange(len(iu[0])), iu[1] * k + iu[0]] = 1.0
    return S
