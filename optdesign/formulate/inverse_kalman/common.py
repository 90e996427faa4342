"""Choices, index helpers and the linear relations shared by the inverse Kalman formulations."""


from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ...errors import ValidationError

STRUCTURES = ("full", "diagonal", "input")


OBJECTIVES = ("min_trace", "nearest", "feasibility")


def check_choice(name: str, value: str, allowed: tuple[str, ...]) -> None:
    if value not in allowed:
        raise ValidationError(f"{name} must be one of {tuple(allowed)}; found {value!r}")


def check_options(structure: str, objective: str, G: NDArray | None, Q_nominal: NDArray | None, *,
                   structures: tuple[str, ...] = STRUCTURES, objectives: tuple[str, ...] = OBJECTIVES,
                   nominal_needed: bool = True) -> None:
    """The option checks every builder shares (structure, objective, G, ``Q_nominal``)."""
    check_choice("structure", structure, structures)
    check_choice("objective", objective, objectives)
    if structure != "full":
        noise_input(structure, G)
    if nominal_needed and objective == "nearest" and Q_nominal is None:
        raise ValidationError("objective='nearest' needs Q_nominal")


def noise_input(structure: str, G: NDArray | None) -> NDArray:
    """The noise input matrix G of a structure that goes through it (``"input"``,
    ``"diagonal"``: ``Q = G Qw G'``).

    Raises
    ------
    ValidationError
        G is None.
    """
    if G is None:
        raise ValidationError(f"structure={structure!r} needs the noise input matrix G")
    return G


def require_terms(A: NDArray, C: NDArray, poles: NDArray, dt: float | None, terms: list | None) -> list:
    """``terms`` or :func:`spectral_terms`; raises where the spectral identity is singular."""
    if terms is None:
        terms = spectral_terms(A, C, poles, dt)
    if terms is None:
        raise ValidationError("a target pole is an eigenvalue of A or of its mirror image: the spectral "
                              "identity is singular there (use build_pole_nlp or build_fixed_gain_sdp)")
    return terms


def tril_index(k: int) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """Row and column indices of the lower triangle, column by column (the factor's vector)."""
    cols, rows = np.triu_indices(k)  # (j, i) with i >= j, ordered by j then i
    return rows.astype(np.intp), cols.astype(np.intp)


def psd_part(W: NDArray) -> NDArray:
    w, V = np.linalg.eigh(0.5 * (W + W.T))
    return (V * np.maximum(w, 0.0)) @ V.T


def chol_factor(W: NDArray) -> NDArray:
    """Lower-triangular factor of a PSD matrix: Cholesky of ``W + 1e-10 max(1, ||W||) I``."""
    k = W.shape[0]
    return np.linalg.cholesky(W + 1e-10 * max(1.0, float(np.linalg.norm(W, 2))) * np.eye(k))


def null_vector_start(M0: NDArray, size: int, c: int, p: int) -> NDArray:
    """Initial null vector of ``M0`` for the c-th repetition of a target: its (c+1)-th smallest
    right singular vector (the smallest when c >= p); complex for a pair (size 2), with the
    phase fixed so that ``Re w' Im w = 0``."""
    j = -1 - c if c < p else -1
    if size == 1:
        return np.linalg.svd(M0.real)[2][j]
    v = np.linalg.svd(M0)[2][j].conj()
    return v * np.exp(-0.5j * np.angle(v @ v))


def fixed_gain_maps(A: NDArray, C: NDArray, L: NDArray, R: NDArray, dt: float | None,
                    scale: float = 1.0) -> tuple[Callable[[Any], Any], Callable[[Any], Any]]:
    """The affine relations (C) / (D) for a fixed gain.

    Returns ``gain_residual(P)`` ((n, p), zero for an admissible P) and ``q_of_P(P)`` ((n, n),
    the process noise that makes P the Riccati solution).  Both accept numpy arrays or cvxpy
    expressions (only ``@``, ``+``, ``-`` and ``.T`` are used).  With ``scale = s`` they are
    the relations for ``P / s`` and ``Q / s`` (the constant terms ``L R`` and ``L R L'`` are
    divided by s).
    """
    LR = L @ R / scale
    LRL = LR @ L.T
    LRL = 0.5 * (LRL + LRL.T)
    if dt is None:
        def gain_residual(P):
            return P @ C.T - LR

        def q_of_P(P):
            return LRL - A @ P - P @ A.T
    else:
        F = A - L @ C

        def gain_residual(P):
            return F @ P @ C.T - LR

        def q_of_P(P):
            return P - F @ P @ F.T - LRL
    return gain_residual, q_of_P


def modal_blocks(poles: NDArray) -> list[tuple[int, complex]]:
    """Real modal pattern of a conjugate-closed pole vector sorted as :func:`as_poles` does.

    Returns a list of ``(size, pole)``: ``(1, s)`` for a real pole, ``(2, a + jb)`` (b > 0) for a
    pair; the block for a pair is ``[[a, b], [-b, a]]``.
    """
    out: list[tuple[int, complex]] = []
    k = 0
    z = np.asarray(poles, dtype=complex)
    while k < z.size:
        if z[k].imag != 0:
            out.append((2, complex(z[k].real, abs(z[k].imag))))
            k += 2
        else:
            out.append((1, complex(z[k].real)))
            k += 1
    return out


def block_matrix(blocks: list[tuple[int, complex]]) -> NDArray[np.float64]:
    n = sum(b for b, _ in blocks)
    Lam = np.zeros((n, n))
    k = 0
    for size, z in blocks:
        if size == 1:
            Lam[k, k] = z.real
        else:
            Lam[k:k + 2, k:k + 2] = [[z.real, z.imag], [-z.imag, z.real]]
        k += size
    return Lam


# --------------------------------------------------------------------- spectral NLP
def singular_resolvent(eig_A: NDArray, s: NDArray, dt: float | None, rtol: float = 1e-8) -> bool:
    """Whether a target ``s`` (complex array) is (relative ``rtol``) an eigenvalue of A or the mirror
    image of one (``-s`` continuous, ``1/s`` discrete), or a discrete target is 0: where the
    resolvents of the spectral conditions are singular."""
    if dt is not None and np.any(np.abs(s) <= rtol):
        return True
    mirror = 1.0 / s if dt is not None else -s
    for z in (s, mirror):
        dist = np.min(np.abs(eig_A[None, :] - z[:, None]), axis=1)
        if np.any(dist <= rtol * np.maximum(1.0, np.abs(z))):
            return True
    return False


def spectral_terms(A: NDArray, C: NDArray, poles: NDArray, dt: float | None,
                   rtol: float = 1e-8) -> list[tuple[int, complex, NDArray, NDArray, float]] | None:
    r"""The resolvent factors of the Kalman spectral identity at each target block.

    For each block ``(size, s)`` of :func:`modal_blocks` returns ``(size, s, G1, G2, w)`` with
    ``G1 = C (s I - A)^-1`` and ``G2 = C (s~ I - A)^-1`` ((p, n), complex), ``s~ = -s``
    (continuous) or ``1/s`` (discrete), and a row weight ``w = 1 / max(1, ||G1|| ||G2||)``.
    Returns None when a target is (relative ``rtol``) an eigenvalue of A or the mirror image
    ``s~`` of one (the resolvent is singular there), or a discrete target is 0.
    """
    n = A.shape[0]
    blocks = modal_blocks(poles)
    if singular_resolvent(np.linalg.eigvals(A), np.array([z for _, z in blocks], dtype=complex), dt, rtol):
        return None
    out = []
    for size, s in blocks:
        s2 = (1.0 / s) if dt is not None else -s
        G1 = np.linalg.solve((s * np.eye(n) - A).T, C.T.astype(complex)).T
        G2 = np.linalg.solve((s2 * np.eye(n) - A).T, C.T.astype(complex)).T
        w = 1.0 / max(1.0, float(np.linalg.norm(G1) * np.linalg.norm(G2)))
        out.append((size, complex(s), G1, G2, w))
    return out


def single_output_gain(A: NDArray, C: NDArray, poles: NDArray, dt: float | None, eig_A: NDArray | None = None,
                       rtol: float = 1e-8) -> NDArray[np.float64] | None:
    r"""The gain the poles fix for one output, from the resolvents at the targets -- the gain of
    :func:`spectral_terms` and ``SpectralBlocks.gain`` with unit null vectors, bit for bit, in one
    batched solve (no per-block terms).

    Each target block ``(size, s)`` of :func:`modal_blocks` gives ``w = -(C (s I - A)^-1)'`` (a left
    eigenvector of ``A - L C`` with ``L' w = 1``); ``L`` solves ``L' [Re w, Im w, ...] = [1, 0, ...]``.
    None where :func:`spectral_terms` is None (a target at an eigenvalue of A or of its mirror image,
    a discrete target at 0; ``eig_A``: the eigenvalues of A when at hand) or the eigenvector
    matrix is singular (a repeated target).

    Parameters
    ----------
    A : (n, n) ndarray
    C : (1, n) ndarray
    poles : (n,) ndarray of complex
        Sorted as :func:`optdesign._validate.as_poles` does (pairs adjacent).
    dt : float or None
    eig_A : (n,) ndarray, optional
    rtol : float

    Returns
    -------
    (n, 1) ndarray or None

    Raises
    ------
    ValidationError
        C is not one row of n columns.
    """
    n = A.shape[0]
    if C.shape != (1, n):
        raise ValidationError(f"single_output_gain needs one output: C must be (1, {n}); found {C.shape}")
    blocks = modal_blocks(poles)
    s = np.array([z for _, z in blocks], dtype=complex)
    if singular_resolvent(np.linalg.eigvals(A) if eig_A is None else eig_A, s, dt, rtol):
        return None
    M = s[:, None, None] * np.eye(n) - A
    G1 = np.linalg.solve(M.transpose(0, 2, 1), np.broadcast_to(C.T.astype(complex), (s.size, n, 1)))[..., 0]
    cols, rhs = [], []
    for b, (size, _) in enumerate(blocks):
        wv = -G1[b]
        if size == 1:
            cols.append(wv.real)
            rhs.append(1.0)
        else:
            cols += [wv.real, wv.imag]
            rhs += [1.0, 0.0]
    try:
        L = np.linalg.solve(np.array(cols), np.array(rhs)[:, None])
    except np.linalg.LinAlgError:
        return None
    return L if np.all(np.isfinite(L)) else None


# ------------------------------------------------------- spectral NLP, exact derivatives
#: structures and objectives the explicit-derivative spectral NLP supports (the others use
#: :func:`build_spectral_nlp`)
FAST_STRUCTURES = ("full", "input")


FAST_OBJECTIVES = ("min_trace", "nearest")

