"""Shared pieces of the well-conditioned NLP builders: objective and noise-structure vocabulary,
continuation stages, pole structures, real modal bases, random eigenstructure assignments,
eigenvector coordinates and the kappa-preserving scaling.

See :mod:`optdesign.formulate.well_conditioned` for the formulation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..._validate import as_poles
from ...errors import ValidationError
from ...model.plant import Plant

__all__ = [
    "OBJECTIVES",
    "Q_STRUCTURES",
    "check_objective",
    "check_q_structure",
    "KAPPA2_STAGES",
    "KAPPA2_BOUND_STAGES",
    "GAIN_BOUND_STAGE",
    "casadi_module",
    "RecordingOpti",
    "PoleStructure",
    "NLPScaling",
    "real_modal_basis",
    "random_gain_for_poles",
    "eigenvector_coordinates",
]

#: objectives understood by :func:`build_observer_nlp`
OBJECTIVES = ("kappa2", "kappa_fro", "eta")

#: process-noise parametrizations understood by :func:`build_kalman_nlp`
Q_STRUCTURES = ("scalar", "diagonal", "full")


def check_objective(objective: Any) -> str:
    """Raise ValidationError unless ``objective`` is one of :data:`OBJECTIVES`."""
    if not isinstance(objective, str) or objective not in OBJECTIVES:
        raise ValidationError(f"objective must be one of {OBJECTIVES}; found {objective!r}")
    return objective


def check_q_structure(q_structure: Any) -> str:
    """Raise ValidationError unless ``q_structure`` is one of :data:`Q_STRUCTURES`."""
    if not isinstance(q_structure, str) or q_structure not in Q_STRUCTURES:
        raise ValidationError(f"q_structure must be 'scalar', 'diagonal' or 'full'; found {q_structure!r}")
    return q_structure


#: continuation stages of the kappa2 surrogate: orders 2**J of the trace powers
KAPPA2_STAGES = (0, 3, 6, 9, 12)
#: continuation stages of the kappa2 *bound* (``kappa2_max``) when another metric is minimized.
#: The surrogate of order 4096 is nearly the nonsmooth max of the singular values: on Byers 3
#: (minimize eta with kappa2 <= 1.2 x its minimum; YT, KNV0 and kappa2's optimum as starts, each
#: perturbed by 1e-10 eight times: rounding on another CPU) the order-4096 bound alone ended at the
#: iteration limit from 6 of 24 starts (13 of 24 in the old, unscaled null-space coordinates), the
#: order-64 bound from none (kappa2 0.9999 x the bound); the later stages polish from there
KAPPA2_BOUND_STAGES = (6, 9, 12)
#: order 2**GAIN_BOUND_STAGE of the trace power bounding ||L||_2
GAIN_BOUND_STAGE = 10


def casadi_module():
    """The CasADi module (imported lazily: CasADi is loaded only when an NLP is built)."""
    from ...backends.casadi_backend import import_casadi

    return import_casadi()


class RecordingOpti:
    """A CasADi ``Opti`` (every attribute forwarded) that also keeps the numbers given to
    ``set_initial`` / ``set_value`` for a whole variable or parameter, so that a solver made from
    the description (:meth:`start_vectors`) gets its start and parameters without ``Opti.value``
    (0.5 ms per call: it builds a Function each time).

    Parameters
    ----------
    opti : casadi.Opti
    """

    def __init__(self, opti: Any) -> None:
        self.opti = opti
        #: id(symbol) -> (symbol, numbers): the last values set (None: some value was set another way)
        self.initial_values: dict[int, tuple[Any, NDArray]] | None = {}
        self.parameter_values: dict[int, tuple[Any, NDArray]] | None = {}

    def __getattr__(self, name: str) -> Any:
        return getattr(self.opti, name)

    @staticmethod
    def _record(store, args):
        """``store`` with ``args`` (symbol, numbers) recorded, or None (not a whole symbol's values)."""
        if store is None or len(args) != 2 or not getattr(args[0], "is_symbolic", lambda: False)():
            return None
        sym, val = args
        v = np.asarray(val, dtype=float)
        shape = sym.shape
        if v.size == shape[0] * shape[1]:
            flat = (v if v.ndim == 2 else v.reshape(shape, order="F")).ravel(order="F")
        elif v.size == 1:
            flat = np.full(shape[0] * shape[1], float(v.ravel()[0]))
        else:
            return None
        store[id(sym)] = (sym, flat)
        return store

    def set_initial(self, *args: Any) -> None:
        """``Opti.set_initial``, recorded."""
        self.opti.set_initial(*args)
        self.initial_values = self._record(self.initial_values, args)

    def set_value(self, *args: Any) -> None:
        """``Opti.set_value``, recorded."""
        self.opti.set_value(*args)
        self.parameter_values = self._record(self.parameter_values, args)

    def _assemble(self, store, layout: dict[str, Any], kind: str) -> NDArray[np.float64] | None:
        ca = casadi_module()
        vec, size, where = layout[kind], layout["n" + kind], layout[kind + "_index"]
        out = np.zeros(size)
        for key, (sym, flat) in store.items():
            if key not in where:
                try:
                    pos = ca.Function("where", [vec], [ca.vec(sym)])(np.arange(size, dtype=float))
                except RuntimeError:  # not a symbol of this description
                    return None
                where[key] = np.asarray(pos, dtype=float).ravel().round().astype(int)
            out[where[key]] = flat
        return out

    def start_vectors(self, layout: dict[str, Any]) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
        """``(x0, p)``: the recorded initial guess (zero where none was set, as ``Opti``'s) and
        parameter values as the vectors ``layout["x"]``, ``layout["p"]`` (:meth:`layout`), or None
        when some value was set another way (then ask ``Opti.value``)."""
        if self.initial_values is None or self.parameter_values is None:
            return None
        x0 = self._assemble(self.initial_values, layout, "x")
        p = self._assemble(self.parameter_values, layout, "p")
        return None if x0 is None or p is None else (x0, p)

    def layout(self) -> dict[str, Any]:
        """The description's vectors ``x``, ``p``, ``g``, a Function ``bounds(p) -> (lbg, ubg)``, and
        (filled by :meth:`start_vectors`) where each recorded symbol sits in ``x`` / ``p``; made once
        the description is complete (e.g. when a solver is configured)."""
        ca = casadi_module()
        o = self.opti
        x, p = o.x, o.p
        return {"x": x, "p": p, "g": o.g, "nx": int(x.shape[0]), "np": int(p.shape[0]),
                "bounds": ca.Function("bounds", [p], [o.lbg, o.ubg]), "x_index": {}, "p_index": {}}


# --------------------------------------------------------------------------- pole structure


@dataclass(frozen=True)
class PoleStructure:
    """How many real poles and conjugate pairs the modal basis has (real ones first)."""

    n_real: int
    n_pairs: int

    @property
    def n(self) -> int:
        return self.n_real + 2 * self.n_pairs

    @classmethod
    def of(cls, poles: ArrayLike, tol: float = 1e-9) -> PoleStructure:
        """The structure of a conjugate-closed pole set (``|Im| <= tol max(1, |p|)`` counts as real)."""
        p = np.asarray(poles, dtype=complex).ravel()
        scale = max(1.0, float(np.max(np.abs(p)))) if p.size else 1.0
        nr = int(np.sum(np.abs(p.imag) <= tol * scale))
        return cls(nr, (p.size - nr) // 2)

    def split(self, poles: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.complex128]]:
        """``(real poles, upper pair members)`` of a validated pole set with this structure."""
        p = as_poles("poles", poles, self.n)
        s = PoleStructure.of(p)
        if s != self:
            raise ValidationError(
                f"poles have {s.n_real} real poles and {s.n_pairs} pairs; the NLP was built for "
                f"{self.n_real} real poles and {self.n_pairs} pairs"
            )
        return p[: self.n_real].real.copy(), p[self.n_real :: 2].copy()


def _block_lambda(real: NDArray, pairs: NDArray) -> NDArray[np.float64]:
    n = real.size + 2 * pairs.size
    M = np.zeros((n, n))
    k = 0
    for r in real:
        M[k, k] = r
        k += 1
    for z in pairs:
        M[k : k + 2, k : k + 2] = [[z.real, z.imag], [-z.imag, z.real]]
        k += 2
    return M


def real_modal_basis(
    X: ArrayLike, structure: PoleStructure | None = None
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.complex128]]:
    """Scaled real modal basis of ``X`` for a pole structure (initial guesses, tests).

    Parameters
    ----------
    X : (n, n) array_like, real
    structure : PoleStructure, optional
        Default: the structure of ``eig(X)``.  When the spectrum has a different pattern,
        the closest admissible basis is returned (pairs made from two real eigenvectors,
        or a pair split into two real columns); it is then only an initial guess.

    Returns
    -------
    V : (n, n) ndarray
        Real columns of unit norm; pair columns ``sqrt(2) (Re z, Im z)`` for unit ``z``.
    Lam : (n, n) ndarray
        The matching real block-diagonal matrix (``X V ~= V Lam``).
    poles : (n,) ndarray of complex
        The poles in the order of the basis (real first, then ``z, conj z``).
    """
    X = np.asarray(X, dtype=float)
    n = X.shape[0]
    w, Z = np.linalg.eig(X)
    scale = max(1.0, float(np.max(np.abs(w))))
    is_real = np.abs(w.imag) <= 1e-9 * scale
    ridx = [i for i in np.argsort(w.real) if is_real[i]]
    cidx = [i for i in np.argsort(w.real) if (not is_real[i]) and w[i].imag > 0]
    if structure is None:
        structure = PoleStructure(len(ridx), len(cidx))
    # adjust the pattern
    reals = [(w[i].real, np.real(Z[:, i])) for i in ridx]
    pairs = [(w[i], Z[:, i]) for i in cidx]
    while len(reals) > structure.n_real and len(reals) >= 2:  # make a pair from two close reals
        reals.sort(key=lambda t: t[0])
        gaps = [reals[k + 1][0] - reals[k][0] for k in range(len(reals) - 1)]
        k = int(np.argmin(gaps))
        (a, va), (b, vb) = reals[k], reals[k + 1]
        del reals[k : k + 2]
        om = max(0.5 * (b - a), 1e-3 * scale)
        pairs.append((complex(0.5 * (a + b), om), va + 1j * vb))
    while len(pairs) > structure.n_pairs:  # split the pair closest to the axis
        pairs.sort(key=lambda t: abs(t[0].imag))
        z, v = pairs.pop(0)
        reals += [(z.real - 1e-3 * scale, np.real(v)), (z.real + 1e-3 * scale, np.imag(v))]
    reals.sort(key=lambda t: t[0])
    pairs.sort(key=lambda t: (t[0].real, t[0].imag))
    cols: list[NDArray] = []
    poles: list[complex] = []
    for lam, v in reals:
        nv = np.linalg.norm(v)
        cols.append(v / nv if nv > 0 else np.eye(n)[:, len(cols)])
        poles.append(complex(lam))
    for lam, z in pairs:
        z = z / max(np.linalg.norm(z), 1e-300)
        cols += [math.sqrt(2.0) * z.real, math.sqrt(2.0) * z.imag]
        poles += [complex(lam), complex(lam).conjugate()]
    V = np.column_stack(cols)
    P = np.asarray(poles)
    Lam = _block_lambda(P[: len(reals)].real, P[len(reals) :: 2])
    return V, Lam, P


def random_gain_for_poles(plant: Plant, poles: ArrayLike, rng: np.random.Generator) -> NDArray[np.float64]:
    """A random observer gain with ``eig(A - L C) = poles`` (parametric eigenstructure assignment).

    Each left eigenvector ``w_i`` of ``A - L C`` satisfies ``w_i (A - lambda_i I) = g_i C`` for some
    ``g_i``: ``[w_i, -g_i]`` is in the left null space of ``[[A - lambda_i I], [C]]`` (dimension
    ``p`` for an observable pair).  Random combinations (conjugate for pairs, independent for a
    repeated pole) give ``W`` and ``G``; then ``L = W^-1 G``.  Used as multi-start seeds.

    Returns
    -------
    L : (n, p) ndarray
        May be inaccurate when the random ``W`` is ill conditioned; callers verify.
    """
    from scipy.linalg import null_space

    A, C = plant.A, plant.C
    n = plant.n
    P = as_poles("poles", poles, n)
    rows_w: list[NDArray] = []
    rows_g: list[NDArray] = []
    done: set[int] = set()
    for i, lam in enumerate(P):
        if i in done or lam.imag < 0:
            continue
        M = np.vstack([A - lam * np.eye(n), C])  # (n+p, n)
        N = null_space(M.T)  # left null space of M: y M = 0  <=>  M^T y = 0
        k = N.shape[1]
        coef = rng.standard_normal(k) + (1j * rng.standard_normal(k) if lam.imag != 0 else 0.0)
        y = N @ coef
        w, g = y[:n], -y[n:]
        rows_w.append(w)
        rows_g.append(g)
        done.add(i)
        if lam.imag != 0:
            rows_w.append(w.conj())
            rows_g.append(g.conj())
            j = next(
                j
                for j in range(len(P))
                if j not in done and j != i and abs(P[j] - lam.conjugate()) < 1e-12 * max(1.0, abs(lam))
            )
            done.add(j)
    Wm = np.array(rows_w)
    Gm = np.array(rows_g)
    L = np.linalg.solve(Wm, Gm)
    return np.real(L)


def eigenvector_coordinates(N: NDArray, n: int) -> tuple[NDArray, NDArray]:
    """A basis of the left null space of ``[A - lambda I; C]`` in which the eigenvector part is orthonormal.

    ``N`` (n + p, k) has orthonormal columns ``[w; -g]`` (left eigenvector ``w``, ``g = w L``).
    For a large gain ``||g|| >> ||w||``: the ``w`` parts of an orthonormal basis are then tiny,
    and a step in the coordinates ``c`` of ``y = N c`` changes the eigenvector matrix ``W`` (whose
    conditioning is the objective) by ``||g|| / ||w||`` times more than it changes ``y`` -- the
    NLP in ``c`` is badly scaled (on Byers 3 the Hessian of eta^2 had eigenvalues of +-1e6 at
    kappa2's optimum).  With ``N_w = U S V*`` (SVD of the first ``n`` rows), the basis
    ``N' = N V S^-1`` has ``N'_w = U`` orthonormal: ``||w|| = ||c||``.  Directions with no
    eigenvector part (``S = 0`` to rounding; only when ``rank C < p``: ``g C = 0``) keep their
    unit scale.

    Parameters
    ----------
    N : (n + p, k) ndarray
        Orthonormal columns.
    n : int
        Number of states (rows of the eigenvector part).

    Returns
    -------
    N' : (n + p, k) ndarray
        The rescaled basis, spanning the same space.
    Tinv : (k, k) ndarray
        Coordinates ``c' = Tinv c`` in ``N'`` of the point ``N c``.
    """
    _, s, Vh = np.linalg.svd(N[:n])  # Vh: (k, k)
    eps = float(np.finfo(float).eps)
    d = np.ones(N.shape[1])
    if s.size:
        keep = s > max(N.shape) * eps * max(float(s[0]), 1.0)
        d[: s.size] = np.where(keep, s, 1.0)
    T = Vh.conj().T / d[None, :]
    return N @ T, d[:, None] * Vh


# --------------------------------------------------------------------------- scaling


@dataclass(frozen=True)
class NLPScaling:
    """kappa-preserving scaling of the observer NLP.

    ``A~ = T^-1 A T / omega``, ``C~ = S C T``, ``L~ = T^-1 L S^-1 / omega``, ``V = T V~``,
    poles ``lambda~ = lambda / omega``.  ``T`` and ``S`` are diagonal (stored as vectors).
    """

    omega: float
    T: NDArray[np.float64]
    S: NDArray[np.float64]

    @classmethod
    def identity(cls, n: int, p: int) -> NLPScaling:
        return cls(1.0, np.ones(n), np.ones(p))

    @classmethod
    def for_plant(cls, plant: Plant, pole_scale: float | None = None, *, balance: bool = True) -> NLPScaling:
        """Time scale (continuous time only), optional balancing ``T``, unit rows of ``C``.

        The time scale is the power of two nearest to ``pole_scale`` (the magnitude of the
        target poles or of the region: the natural time scale of ``A - L C``; default the
        spectral radius of ``A``), applied only when that scale is outside ``[1e-2, 1e2]``.
        Measured: time scaling within that range changed IPOPT's iteration counts erratically
        (KNV Ex2 from a random start: 151 iterations unscaled, 3000 and no convergence with
        ``omega = 1.41``), and ``omega = rho(A)`` made scipy's 6x6 test case (rho(A) = 7325,
        poles ~ 50) several times slower; unit-norm output rows helped everywhere measured.
        """
        from scipy.linalg import matrix_balance

        A = plant.A
        if plant.is_discrete:
            omega = 1.0
        else:
            scale = float(pole_scale) if pole_scale else float(np.max(np.abs(np.linalg.eigvals(A))))
            omega = 1.0
            if scale > 0 and math.isfinite(scale) and not 1e-2 <= scale <= 1e2:
                omega = float(2.0 ** round(math.log2(scale)))  # a power of two: exact in floating point
        if balance and plant.n > 1:
            _, (sc, _) = matrix_balance(A, permute=False, separate=True)
            T = np.asarray(sc, dtype=float)
        else:
            T = np.ones(plant.n)
        CT = plant.C * T[None, :]
        rn = np.linalg.norm(CT, axis=1)
        S = np.where(rn > 0, 1.0 / np.where(rn > 0, rn, 1.0), 1.0)
        return cls(float(omega), T, S)

    def gain_to_scaled(self, L: NDArray) -> NDArray:
        return (L / self.T[:, None] / self.S[None, :]) / self.omega

    def gain_from_scaled(self, Ls: NDArray) -> NDArray:
        return self.omega * (self.T[:, None] * np.asarray(Ls) * self.S[None, :])


# --------------------------------------------------------------------------- the builder
