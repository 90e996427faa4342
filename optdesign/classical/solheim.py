r"""Solheim's sequential method for a Kalman filter with prescribed poles (seed 000).

Chang & Lee (1984) carry Solheim's (1972) LQR technique over to the Kalman filter: move the
eigenvalues of ``A`` to the targets one (or one pair) at a time, each move made by a process
noise supported on that mode's eigenvector(s) only, and add the steps up.

Real eigenvalue (eq 23-33).  With ``m`` a real eigenvector of the current error matrix
``A_k`` (``A_k m = lambda m``), ``h = m' C' R^-1 C m`` (the ``h_jj`` of ``H_E = M'C'R^-1CM``,
eq 26) and a stable target ``S``, the rank-one noise ``Q'_k = q m m'`` with

.. math::

    \tilde q = \frac{S^2 - \lambda^2}{h} \quad (28), \qquad
    \tilde p = \frac{\lambda - S}{h},\qquad P_k = \tilde p\, m m',\qquad K_k = P_k C' R^{-1}

solves the Riccati equation (29) of ``A_k`` and moves ``lambda`` to ``S``; every other
eigenvalue of ``A_k`` is left where it is (``A_k - K_k C`` maps ``span(m)`` into itself and
acts on the quotient space as ``A_k`` does), so the diagonalization of eq (23) is not even
needed -- one eigenvector per step is.  ``A_{k+1} = A_k - K_k C``.

Additivity (the appendix).  If ``P_1`` solves the ARE of ``(A, Q'_1)`` and ``P_2`` that of
``(A - K_1 C, Q'_2)``, then ``P_1 + P_2`` solves the ARE of ``(A, Q'_1 + Q'_2)`` and
``K = K_1 + K_2``; so the final ``K, Q', P`` are the sums of the steps.

Complex pair (eq 34-45).  In the real modal basis ``T`` (``A_k T = T Lambda``,
``Lambda = [[-alpha, beta], [-beta, -alpha]]``) the paper takes ``Q~ = q I`` (eq 35).  The
4 x 4 canonical matrix ``[[-Lambda', H], [Q~, Lambda]]`` (``H = T'C'R^-1CT``) has the
characteristic polynomial (36)

.. math::

    s^4 - [2(\alpha^2 - \beta^2) + q(h_{11} + h_{22})] s^2
    + q^2 (h_{11} h_{22} - h_{12}^2) + q (h_{11} + h_{22})(\alpha^2 + \beta^2)
    + (\alpha^2 + \beta^2)^2 .

Known errors of the printed equations (checked by expanding the determinant, and by the
paper's own eq (40)): the target polynomial (39) of the pair ``-r +- j delta`` is
``s^4 + 2(delta^2 - r^2) s^2 + (r^2 + delta^2)^2`` (the paper prints ``2(r^2 - delta^2)``;
eq (40) is right only with the corrected sign), and the middle term of (41) carries
``(alpha^2 + beta^2)``, not its square (as (36) and (45) have it).

Complex pair -> two real poles (eq 42-45, the paper's Example 2): with ``q I`` only one of the
two real targets, ``-r1``, can be chosen; (44) and (45) then fix ``q`` and the other pole
``-r2``, which a real step (eq 28) moves on to its target.  The paper finds that last ``q`` "by
trial and error"; here it is eq (28) solved exactly.  (44)-(45) form one quadratic equation
in ``q``; of its roots the one that keeps every step's ``Q`` positive semidefinite is used.

Generalization (flagged ``kind="pair_diagonal"`` in the steps).  A complex pair moved to
another complex pair with ``Q~ = q I`` must satisfy (41) -- a one-parameter family of
reachable pairs -- and the paper treats neither that restriction's way out nor two real
eigenvalues moved to a complex pair.  For these cases ``Q~ = diag(q1, q2)`` in the modal basis
(normalized so that its columns are orthogonal) has two parameters for the two conditions --
the ``s^2`` and ``s^0`` coefficients, i.e. ``mu1^2 + mu2^2 = tr(Lambda^2) + tr(H Q~)`` and
``mu1^2 mu2^2 = det[[-Lambda', H], [Q~, Lambda]]`` -- which reduce to one quadratic equation.
When the target does satisfy (41), ``q1 = q2`` is one of its roots.  The pair's ``P~`` is the
stabilizing solution of the 2 x 2 Riccati equation (29), computed with
:func:`optdesign.classical.riccati.hamiltonian_are`.

Discrete time (not in the paper; derived here).  For the predictor DARE
``P = A P A' - A P C'(C P C' + R)^-1 C P A' + Q'``, ``L = A P C'(C P C' + R)^-1`` the steps
add up too, provided step k+1 uses the innovation covariance of the steps so far as its
measurement covariance: ``R_{k+1} = C P_k C' + R_k``.  A real step is then
``p~ = (lambda/S - 1)/h``, ``q~ = p~ (1 - lambda S)`` with ``h = m' C' R_k^-1 C m``
(the new pole is ``lambda / (1 + p~ h)``); a pair step matches the trace and the second
elementary symmetric function of the 4 x 4 symplectic matrix.

Which member of the family of Q' the method returns: the sum of the rank-one (rank-two for
pairs) steps -- for Chang & Lee's Example 1 ``P22 = 12``, ``Q' = [[76, -42], [-42, 84]]``.  A
real step has ``q~ >= 0`` only when the pole moves away from the origin (``|S| >= |lambda|``
for a stable ``lambda``); otherwise the sequential Q' is indefinite although the target may
well be reachable: ask :func:`optdesign.kalman_for_poles`, which searches the whole family.

References
----------
Chang, S. H. & Lee, Y. B., "A design of Kalman gain for the state estimator with
pre-specified eigenvalues" (seed 000), eq (20)-(45), Examples 1 and 2, appendix.
Solheim, O. A., "Design of optimal control systems with prescribed eigenvalues",
Int. J. Control 15 (1972) 143-160.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._validate import as_poles
from ..analysis.metrics import eigenvalue_rounding_floor
from ..errors import NotObservableError, RiccatiError, ValidationError
from ..model.plant import Plant
from ..results import Check, DesignResult, Status, Verification
from .placement import pole_error
from .riccati import filter_are, filter_are_residual, hamiltonian_are, symplectic_dare
from .riccati import sort_poles as _sort_poles

__all__ = ["solheim", "SolheimResult", "SolheimStep", "COMPLEX_TO_REAL"]

#: how a complex pair of A is moved onto two real targets
COMPLEX_TO_REAL = ("paper", "diagonal")

_MATCH_TOL = 1e-10


# ----------------------------------------------------------------------------- results
@dataclass(frozen=True, eq=False)
class SolheimStep:
    """One step of the sequential method (seed 000, eq 26-33 or 34-45).

    Attributes
    ----------
    kind : {"real", "pair_identity", "pair_diagonal", "pair_rotated"}
        ``"real"``: one real eigenvalue, rank-one ``Q~ = q~`` (eq 28);
        ``"pair_identity"``: a complex pair with ``Q~ = q I`` (eq 35, 44-45);
        ``"pair_diagonal"``: a pair (complex, or two real eigenvalues moved to a complex pair)
        with ``Q~ = diag(q1, q2)`` (generalization, see the module docstring);
        ``"pair_rotated"``: as ``"pair_diagonal"`` with the principal axes of Q~ rotated, used
        when no diagonal Q~ >= 0 exists.
    moved : (k,) ndarray of complex
        The eigenvalue(s) of the current error matrix ``A_k`` that the step moves (k = 1, 2).
    placed : (k,) ndarray of complex
        Where they end up (the eigenvalues of ``Lambda - K~ C M`` computed after the step).
    basis : (n, k) ndarray
        ``M``: the real eigenvector or the real modal basis ``T`` (orthogonal columns,
        ``A_k T = T Lambda``), scaled as in the paper's examples (largest entry 1).  ``q~``,
        ``P~``, ``K~`` and ``H`` depend on this scaling; ``K``, ``Q``, ``P`` do not.
    Lambda : (k, k) ndarray
        Modal block of ``A_k`` on ``basis``.
    H : (k, k) ndarray
        ``H_E = M' C' R_k^-1 C M`` (eq 26/37).
    q_tilde : (k, k) ndarray
        ``Q~`` of the step in modal coordinates.
    P_tilde : (k, k) ndarray
        Stabilizing solution of the modal Riccati equation (29).
    K_tilde : (k, p) ndarray
        Modal gain (eq 30): ``P~ M' C' R^-1`` (continuous), ``Lambda P~ M' C' S_k^-1`` (discrete).
    K : (n, p) ndarray
        The step's gain ``M K~`` (eq 32).
    Q : (n, n) ndarray
        The step's state-space noise ``Q'_k = M Q~ M'`` (eq 33).
    P : (n, n) ndarray
        The step's covariance ``P_k = M P~ M'``.
    A_after : (n, n) ndarray
        ``A_{k+1} = A_k - K_k C``.
    R : (p, p) ndarray
        Measurement covariance the step used (``R``; in discrete time the innovation
        covariance ``C (P_1 + ... + P_{k-1}) C' + R``).
    note : str
        Anything worth knowing (the by-product pole of eq 44-45, a fallback, ...).
    """

    kind: str
    moved: NDArray[np.complex128]
    placed: NDArray[np.complex128]
    basis: NDArray[np.float64]
    Lambda: NDArray[np.float64]
    H: NDArray[np.float64]
    q_tilde: NDArray[np.float64]
    P_tilde: NDArray[np.float64]
    K_tilde: NDArray[np.float64]
    K: NDArray[np.float64]
    Q: NDArray[np.float64]
    P: NDArray[np.float64]
    A_after: NDArray[np.float64]
    R: NDArray[np.float64]
    note: str = ""

    def __repr__(self) -> str:
        mv = ", ".join(_fmt(z) for z in self.moved)
        pl = ", ".join(_fmt(z) for z in self.placed)
        q = np.array2string(np.asarray(self.q_tilde), precision=5, separator=", ")
        return f"SolheimStep({self.kind}: {mv} -> {pl}, q~ = {q})"


@dataclass(frozen=True, kw_only=True, eq=False)
class SolheimResult(DesignResult):
    """Outcome of :func:`solheim`.

    Attributes
    ----------
    L : (n, p) ndarray
        The Kalman gain ``K = sum K_k`` (called K in the paper).
    Q : (n, n) ndarray
        State-space process noise ``Q' = sum Q'_k`` (the seeds' ``D Q D'``).
    P : (n, n) ndarray
        Error covariance ``P = sum P_k``.
    poles : (n,) ndarray of complex
        ``eig(A - L C)`` computed with numpy.
    target : (n,) ndarray of complex
        The requested poles.
    steps : tuple of SolheimStep
        Every step, in order.
    status : Status
        ``SOLVED`` when every step was computed.
    message : str
    verification : Verification
        ``pole_error``, ``riccati_residual`` (of P with Q), ``step_sum`` (the appendix:
        ``L = sum K_k`` equals the gain formula of the summed P), ``Q_min_eig``,
        ``P_min_eig`` and, when Q is PSD, ``are_resolve_gain`` / ``are_resolve_poles`` from
        an independent :func:`~optdesign.classical.riccati.filter_are` with Q.
    plant : Plant
    """

    L: NDArray[np.float64]
    Q: NDArray[np.float64]
    P: NDArray[np.float64]
    poles: NDArray[np.complex128]
    target: NDArray[np.complex128]
    steps: tuple[SolheimStep, ...]
    plant: Plant = field(repr=False)

    @property
    def K(self) -> NDArray[np.float64]:
        """The paper's name for the gain (same as ``L``)."""
        return self.L

    def __repr__(self) -> str:
        return (f"SolheimResult(n={self.L.shape[0]}, steps={len(self.steps)}, status={self.status.value}, "
                f"success={self.success}, pole_error={self.verification['pole_error'].value:.2e})")


# ----------------------------------------------------------------------------- helpers
def _fmt(z: complex) -> str:
    z = complex(z)
    return f"{z.real:.6g}" if abs(z.imag) < 1e-14 else f"{z.real:.6g}{z.imag:+.6g}j"


def _stable(z: NDArray, discrete: bool) -> NDArray[np.bool_]:
    z = np.asarray(z, dtype=complex)
    return np.abs(z) < 1.0 if discrete else z.real < 0.0


def _close(a: complex, b: complex) -> bool:
    return abs(a - b) <= _MATCH_TOL * max(1.0, abs(b))


def _eig_near(A: NDArray, lam: complex) -> tuple[complex, NDArray]:
    """The eigenvalue of A nearest ``lam`` and its unit eigenvector."""
    w, V = np.linalg.eig(A)
    k = int(np.argmin(np.abs(w - lam)))
    return complex(w[k]), V[:, k]


def _real_eigvec(A: NDArray, lam: float) -> tuple[float, NDArray]:
    """Real eigenvector scaled as in the paper's examples: largest entry equal to 1."""
    w, v = _eig_near(A, lam)
    v = np.real(v / v[np.argmax(np.abs(v))])
    return float(w.real), v


def _pair_basis(A: NDArray, lam: complex) -> tuple[NDArray, NDArray, complex]:
    """Real modal basis ``T = [u w]`` (orthogonal columns, ``||u|| >= ||w||``) of the pair
    ``lam, conj(lam)``: ``A T = T [[a, b], [-b, a]]`` with ``lam = a + j b``, ``b > 0``."""
    w, v = _eig_near(A, lam if lam.imag > 0 else lam.conjugate())
    if w.imag < 0:
        w, v = w.conjugate(), v.conj()
    # rotate v (a complex scalar multiple) so that Re v and Im v are orthogonal
    # and the real part is the longer one: v^T v = |v|^2 e^{2j theta}; use v e^{-j theta}
    theta = 0.5 * np.angle(v @ v)
    v = v * np.exp(-1j * theta)
    u, x = v.real, v.imag
    if np.linalg.norm(u) < np.linalg.norm(x):  # multiply by -j: (u + jx)(-j) = x - j u
        u, x = x, -u
    T = np.column_stack([u, x])
    T = T / np.max(np.abs(T))
    a, b = w.real, w.imag
    Lam = np.array([[a, b], [-b, a]])
    return T, Lam, w


def _two_real_basis(A: NDArray, l1: float, l2: float) -> tuple[NDArray, NDArray]:
    w1, m1 = _real_eigvec(A, l1)
    w2, m2 = _real_eigvec(A, l2)
    return np.column_stack([m1, m2]), np.diag([w1, w2])


def _H(M: NDArray, C: NDArray, R: NDArray) -> NDArray:
    CM = C @ M
    H = CM.T @ np.linalg.solve(R, CM)
    return 0.5 * (H + H.T)


def _pair_invariants(Lam: NDArray, CM: NDArray, R: NDArray, Qt: NDArray,
                     discrete: bool) -> tuple[float, float]:
    """The two free coefficients of the 4 x 4 canonical matrix's characteristic polynomial.

    Continuous: the Hamiltonian ``Z = [[-Lam', H], [Q~, Lam]]`` has eigenvalues ``+-mu1, +-mu2``;
    return ``(mu1^2 + mu2^2, mu1^2 mu2^2) = (tr(Z^2)/2, det Z)``.
    Discrete: the symplectic matrix of the dual DARE (``a = Lam'``, ``b = CM'``) has
    eigenvalues ``z1, z2, 1/z1, 1/z2``; return its trace and second elementary symmetric function.
    """
    return _pair_invariants_H(Lam, _H(np.eye(Lam.shape[0]), CM, R), Qt, discrete)


def _pair_invariants_H(Lam: NDArray, H: NDArray, Qt: NDArray, discrete: bool,
                       aiT: NDArray | None = None) -> tuple[float, float]:
    """:func:`_pair_invariants` with ``H = CM' R^-1 CM`` (and, discrete, ``Lam^-1``) given --
    the inner loop of the orientation scan of :func:`_pair_diagonal`."""
    Z = np.empty((4, 4))
    if not discrete:
        Z[:2, :2] = -Lam.T
        Z[:2, 2:] = H
        Z[2:, :2] = Qt
        Z[2:, 2:] = Lam
        # tr(Z^2) / 2 = tr(Lam^2) + tr(H Q~)
        return float(np.sum(Lam * Lam.T) + np.sum(H * Qt.T)), float(np.linalg.det(Z))
    if aiT is None:
        aiT = np.linalg.inv(Lam.T).T
    HaiT = H @ aiT
    Z[:2, :2] = Lam.T + HaiT @ Qt
    Z[:2, 2:] = -HaiT
    Z[2:, :2] = -aiT @ Qt
    Z[2:, 2:] = aiT
    t1 = float(np.trace(Z))
    return t1, 0.5 * (t1 ** 2 - float(np.sum(Z * Z.T)))


def _target_invariants(mu: NDArray, discrete: bool) -> tuple[float, float]:
    mu = np.asarray(mu, dtype=complex)
    if not discrete:
        sq = mu ** 2
        return float(np.real(sq.sum())), float(np.real(np.prod(sq)))
    z = np.concatenate([mu, 1.0 / mu])
    e1 = z.sum()
    e2 = 0.5 * (e1 ** 2 - np.sum(z ** 2))
    return float(np.real(e1)), float(np.real(e2))


def _quadratic_roots(f, x0: float = 0.0, span: float = 1.0, polish: bool = True) -> NDArray[np.float64]:
    """Real roots of the quadratic (or linear) function ``f`` (exact from three samples; with
    ``polish``, refined by Newton steps on f itself)."""
    y0, y1, y2 = f(x0 - span), f(x0), f(x0 + span)
    # the interpolating quadratic of three equally spaced samples (what polyfit would return)
    c = np.array([(y0 - 2.0 * y1 + y2) / (2.0 * span * span), (y2 - y0) / (2.0 * span), y1])
    scale = max(float(np.max(np.abs(c))), 1e-300)
    if abs(c[0]) <= 1e-13 * scale:
        if abs(c[1]) <= 1e-13 * scale:
            return np.array([])
        return np.array([x0 - c[2] / c[1]])
    r = np.roots(c)
    r = r[np.abs(r.imag) <= 1e-9 * np.maximum(1.0, np.abs(r))].real + x0
    if not polish:
        return np.asarray(r, dtype=float)
    # one Newton polish on f itself (removes the sampling round-off)
    out = []
    for x in r:
        for _ in range(3):
            h = 1e-6 * max(1.0, abs(x))
            d = (f(x + h) - f(x - h)) / (2 * h)
            if d == 0 or not np.isfinite(d):
                break
            x = x - f(x) / d
        out.append(x)
    return np.asarray(out, dtype=float)


def _solve_modal_are(Lam: NDArray, CM: NDArray, R: NDArray, Qt: NDArray, discrete: bool) -> NDArray:
    """Stabilizing solution of the modal filter Riccati equation (29) (or its DARE)."""
    solve = symplectic_dare if discrete else hamiltonian_are
    Pt = solve(Lam.T, CM.T, Qt, R)
    return 0.5 * (Pt + Pt.T)


# -------------------------------------------------------------------------- the steps
class _State:
    """Running sums of the sequential method."""

    def __init__(self, plant: Plant, R: NDArray[np.float64]):
        self.A = plant.A.copy()
        self.C = plant.C
        self.R = R.copy()
        self.discrete = plant.is_discrete
        n, p = plant.n, plant.p
        self.L = np.zeros((n, p))
        self.Q = np.zeros((n, n))
        self.P = np.zeros((n, n))
        self.steps: list[SolheimStep] = []

    def apply(self, kind: str, moved, M: NDArray, Lam: NDArray, Qt: NDArray, Pt: NDArray,
              note: str = "") -> None:
        C, R, A = self.C, self.R, self.A
        CM = C @ M
        Pk = M @ Pt @ M.T
        if self.discrete:
            S = C @ Pk @ C.T + R
            R_next = 0.5 * (S + S.T)
            if not np.linalg.eigvalsh(R_next)[0] > 0:
                raise ValidationError(
                    f"solheim (discrete time): step {len(self.steps) + 1} ({kind}, moving "
                    f"{', '.join(_fmt(z) for z in moved)}) makes the innovation covariance C P C' + R "
                    f"indefinite (P~ < 0: a pole moved away from the origin), so the sequential "
                    f"construction breaks down; use optdesign.kalman_for_poles")
            Kt = Lam @ Pt @ np.linalg.solve(S, CM).T
        else:
            Kt = Pt @ np.linalg.solve(R, CM).T
            R_next = R
        K = M @ Kt
        Qk = M @ Qt @ M.T
        A_after = A - K @ C
        placed = np.linalg.eigvals(Lam - Kt @ CM)
        placed = placed[np.lexsort((-placed.imag, -placed.real))]
        self.steps.append(SolheimStep(
            kind=kind, moved=np.asarray(moved, dtype=complex), placed=placed.astype(complex), basis=M,
            Lambda=Lam, H=_H(M, C, R), q_tilde=Qt, P_tilde=Pt, K_tilde=Kt, K=K, Q=Qk,
            P=Pk, A_after=A_after, R=R.copy(), note=note,
        ))
        self.A = A_after
        self.R = R_next
        self.L = self.L + K
        self.Q = self.Q + Qk
        self.P = self.P + Pk


def _real_step(st: _State, lam: float, S: float, note: str = "") -> None:
    lam_k, m = _real_eigvec(st.A, lam)
    h = float(_H(m[:, None], st.C, st.R)[0, 0])
    if h <= 1e-14 * max(1.0, np.linalg.norm(st.C) ** 2 / np.linalg.eigvalsh(st.R)[0]):
        raise NotObservableError(
            f"solheim: eigenvalue {_fmt(lam_k)} cannot be moved to {_fmt(S)}: it is unobservable "
            f"(h = m'C'R^-1Cm = {h:.3g})", modes=[lam_k])
    if st.discrete:  # S != 0: solheim() rejects a zero target (the moved pole is lambda / (1 + p~ h))
        p = (lam_k / S - 1.0) / h
        q = p * (1.0 - lam_k * S)
    else:
        p = (lam_k - S) / h
        q = (S * S - lam_k * lam_k) / h
    st.apply("real", [lam_k], m[:, None], np.array([[lam_k]]), np.array([[q]]), np.array([[p]]), note)


def _pair_paper(st: _State, lam: complex, targets: tuple[float, float]) -> tuple[float, float] | None:
    """The paper's complex -> real step, Q~ = q I (eq 35, 44, 45).

    Returns ``(r2, other)`` -- the by-product pole and the target it must go to -- after
    applying the step, or None when no root keeps both this step's and the follow-up real
    step's q~ nonnegative (nothing is applied then).
    """
    T, Lam, w = _pair_basis(st.A, lam)
    CT, R, disc = st.C @ T, st.R, st.discrete
    chosen = None
    # the paper fixes the target farther from the origin first (Example 2: r1 = 8); the other
    # order is tried when that one has no root keeping both steps' q~ >= 0
    for mu1, other in ((targets[0], targets[1]), (targets[1], targets[0])):
        # I2(q) - f(I1(q)) = 0 with the second real pole eliminated
        if disc:
            a1 = mu1 + 1.0 / mu1

            def g(q, a1=a1):
                i1, i2 = _pair_invariants(Lam, CT, R, q * np.eye(2), True)
                return i2 - (a1 * (i1 - a1) + 2.0)
        else:
            m2 = mu1 * mu1

            def g(q, m2=m2):
                i1, i2 = _pair_invariants(Lam, CT, R, q * np.eye(2), False)
                return i2 - m2 * (i1 - m2)

        valid = []
        for q in _quadratic_roots(g, 0.0, max(1.0, abs(mu1) ** 2)):
            i1, _ = _pair_invariants(Lam, CT, R, q * np.eye(2), disc)
            if disc:
                wsum = i1 - (mu1 + 1.0 / mu1)
                disc2 = wsum * wsum - 4.0
                if disc2 < 0 or wsum == 0:
                    continue
                r2 = (wsum - np.sign(wsum) * np.sqrt(disc2)) / 2.0
                if not abs(r2) < 1.0:
                    continue
                follow_q = (r2 / other - 1.0) * (1.0 - r2 * other)
            else:
                x = i1 - mu1 * mu1
                if x <= 0:
                    continue
                r2 = -np.sqrt(x)
                follow_q = other * other - r2 * r2
            if q >= 0 and follow_q >= -1e-12 * max(1.0, abs(other) ** 2):
                valid.append((q, float(r2)))
        if valid:
            q, r2 = min(valid)
            chosen = (q, mu1, other, r2)
            break
    if chosen is None:
        return None
    q, mu1, other, r2 = chosen
    Qt = q * np.eye(2)
    Pt = _solve_modal_are(Lam, CT, R, Qt, disc)
    note = (f"eq (44)-(45): with r1 = {_fmt(mu1)} fixed, q = {q:.10g} gives the second pole "
            f"{_fmt(r2)}, moved on to {_fmt(other)} by the next (real) step")
    st.apply("pair_identity", [w, w.conjugate()], T, Lam, Qt, Pt, note)
    return r2, other


def _pair_diagonal(st: _State, moved: tuple[complex, complex], target: tuple[complex, complex],
                   note: str = "") -> None:
    """Move a 2-dimensional invariant subspace with ``Q~ = diag(q1, q2)`` (generalization)."""
    l1, l2 = moved
    if abs(complex(l1).imag) > 0:
        T, Lam, w = _pair_basis(st.A, complex(l1))
        moved_now = [w, w.conjugate()]
    else:
        T, Lam = _two_real_basis(st.A, float(np.real(l1)), float(np.real(l2)))
        moved_now = [complex(Lam[0, 0]), complex(Lam[1, 1])]
    CT, R, disc = st.C @ T, st.R, st.discrete
    H = _H(T, st.C, R)
    if np.max(np.abs(np.diag(H))) <= 1e-14 * max(1.0, float(np.linalg.norm(st.C)) ** 2):
        raise NotObservableError(
            f"solheim: the pair {_fmt(moved_now[0])}, {_fmt(moved_now[1])} is unobservable (H_E = 0)",
            modes=moved_now)
    tgt = np.asarray(target, dtype=complex)
    I1, I2 = _target_invariants(tgt, disc)
    Hm = _H(np.eye(2), CT, R)
    aiT = np.linalg.inv(Lam.T).T if disc else None

    def inv(Qt):
        return _pair_invariants_H(Lam, Hm, Qt, disc, aiT)

    base1, _ = inv(np.zeros((2, 2)))
    span = max(1.0, float(np.max(np.abs(tgt))) ** 2)

    def solutions(theta: float, polish: bool = True):
        """Real (q1, q2) with Q~ = R_theta diag(q1, q2) R_theta' meeting both conditions."""
        c, s_ = np.cos(theta), np.sin(theta)
        Rt = np.array([[c, -s_], [s_, c]])
        E1, E2 = Rt @ np.diag([1.0, 0.0]) @ Rt.T, Rt @ np.diag([0.0, 1.0]) @ Rt.T
        # the first invariant is affine in (q1, q2): solve it for the one with the larger weight
        g1 = inv(E1)[0] - base1
        g2 = inv(E2)[0] - base1
        swap = abs(g2) < abs(g1)
        ga, gb = (g2, g1) if swap else (g1, g2)
        if gb == 0:
            return []

        def qs(x):
            other = (I1 - base1 - ga * x) / gb
            return (other, x) if swap else (x, other)

        def f(x):
            q1, q2 = qs(x)
            return inv(q1 * E1 + q2 * E2)[1] - I2

        out = []
        for x in _quadratic_roots(f, 0.0, span, polish):
            q1, q2 = qs(x)
            Qt = q1 * E1 + q2 * E2
            out.append((min(q1, q2), float(np.trace(T @ Qt @ T.T)), theta, 0.5 * (Qt + Qt.T)))
        return out

    # Q~ diagonal in the modal basis first (theta = 0); if no root gives Q~ >= 0 there, scan
    # the orientation theta of Q~'s principal axes (every symmetric 2 x 2 Q~ is reached)
    cands = solutions(0.0)
    psd = [c for c in cands if c[0] >= 0]
    if not psd:
        # the scan compares unpolished roots (f is exactly quadratic: three samples fix it to
        # rounding); the chosen orientation's roots are then polished
        for theta in np.linspace(0.0, np.pi, 181)[1:-1]:
            cands += solutions(float(theta), polish=False)
        psd = [c for c in cands if c[0] >= 0]
    if not cands:
        raise ValidationError(
            f"solheim: no real Q~ on the modes {_fmt(moved_now[0])}, {_fmt(moved_now[1])} moves them to "
            f"{_fmt(tgt[0])}, {_fmt(tgt[1])} (the coefficient equations have no real root for any "
            f"orientation); use optdesign.kalman_for_poles, which searches every Q >= 0")
    # PSD with the smallest trace of Q'_k; otherwise the least indefinite
    best = min(psd, key=lambda c: c[1]) if psd else max(cands, key=lambda c: c[0])
    if best[2] != 0.0:  # from the scan: polish the chosen orientation's root
        best = min(solutions(best[2]), key=lambda c: float(np.linalg.norm(c[3] - best[3])), default=best)
    _, _, theta, Qt = best
    Pt = _solve_modal_are(Lam, CT, R, Qt, disc)
    kind = "pair_diagonal" if theta == 0.0 else "pair_rotated"
    extra = ("Q~ = diag(q1, q2) (generalization of eq (35)) solves the s^2 and s^0 coefficient conditions"
             if theta == 0.0 else
             f"no diagonal Q~ >= 0 exists; Q~ with principal axes rotated by {np.degrees(theta):.0f} deg "
             f"solves the s^2 and s^0 coefficient conditions")
    st.apply(kind, moved_now, T, Lam, Qt, Pt, (note + "; " + extra) if note else extra)


# --------------------------------------------------------------------------- planning
def _group(z: NDArray, tol: float = 1e-8) -> tuple[list[complex], list[complex]]:
    """Split into real values and upper members of conjugate pairs."""
    z = np.asarray(z, dtype=complex)
    scale = max(1.0, float(np.max(np.abs(z)))) if z.size else 1.0
    real = [complex(v.real) for v in z if abs(v.imag) <= tol * scale]
    upper = [complex(v) for v in z if v.imag > tol * scale]
    return sorted(real, key=lambda v: -v.real), sorted(upper, key=lambda v: (-v.real, v.imag))


def _plan(eigs: NDArray, target: NDArray):
    """Pair the eigenvalues of A with the targets.

    Exact matches stay; each remaining complex pair of A takes a complex target pair if one is
    left, else the two leftmost remaining real targets; each remaining complex target pair takes
    the two rightmost remaining real eigenvalues; the real rest is paired in order (rightmost
    eigenvalue to rightmost target).
    """
    ra, ca = _group(eigs)
    rt, ct = _group(target)
    for z in list(ca):
        for w in ct:
            if _close(z, w):
                ca.remove(z)
                ct.remove(w)
                break
    for z in list(ra):
        for w in rt:
            if _close(z, w):
                ra.remove(z)
                rt.remove(w)
                break
    plan: list[tuple[str, tuple[complex, ...], tuple[complex, ...]]] = []  # (kind, moved, targets)
    for z in ca:
        if ct:
            w = ct.pop(0)
            plan.append(("c2c", (z, z.conjugate()), (w, w.conjugate())))
        else:
            if len(rt) < 2:  # pragma: no cover - counts always balance
                raise ValidationError("solheim: cannot pair the eigenvalues with the targets")
            t2, t1 = rt.pop(), rt.pop()  # leftmost two; t2 is the leftmost
            plan.append(("c2r", (z, z.conjugate()), (t2, t1)))
    for w in ct:
        l1, l2 = ra.pop(0), ra.pop(0)
        plan.append(("r2c", (l1, l2), (w, w.conjugate())))
    for z, w in zip(ra, rt, strict=True):
        plan.append(("r2r", (z,), (w,)))
    return plan


def _order(plan: list) -> list:
    """Keep the planned order (pairs first, then real moves rightmost first -- the paper's
    order in Example 1) but defer a move whose target would land within 1 % of an eigenvalue
    that is still to be moved: a nearly repeated eigenvalue makes the next eigenvector
    ill-conditioned."""
    pending = list(plan)
    out = []
    while pending:
        rest_eigs = lambda j: [z for i, st in enumerate(pending) if i != j for z in st[1]]  # noqa: E731
        for j, (_, _, tgt) in enumerate(pending):
            others = rest_eigs(j)
            close = any(abs(t - z) <= 1e-2 * max(1.0, abs(t)) for t in tgt for z in others)
            if not close:
                break
        else:
            j = 0
        out.append(pending.pop(j))
    return out


# ------------------------------------------------------------------------------ verb
def solheim(plant: Plant, poles: ArrayLike, *, complex_to_real: str = "paper") -> SolheimResult:
    r"""Kalman gain and process noise with prescribed filter poles by the sequential method.

    Moves the eigenvalues of ``A`` to ``poles`` one real eigenvalue (eq 23-33) or one complex
    pair (eq 34-45) at a time, each step solving a Riccati equation in the step's modal
    coordinates, and returns every step and the sums ``K = sum K_k``, ``Q' = sum Q'_k``,
    ``P = sum P_k`` (appendix).  The paper's trial-and-error choices are replaced by the exact
    solution of the conditions (see the module docstring for the corrected equations and for
    the generalizations).

    Parameters
    ----------
    plant : Plant
        ``A`` (n, n), ``C`` (p, n), ``R`` (p, p) are used (``G`` and ``Q`` are not: the method
        returns the state-space noise ``Q' = D Q D'``).  Continuous or discrete (``plant.dt``).
    poles : (n,) array_like of complex
        Target filter poles, closed under conjugation, stable (``Re < 0``; ``|z| < 1`` in
        discrete time).
    complex_to_real : {"paper", "diagonal"}
        How a complex pair of A is moved onto two real targets: ``"paper"`` (default) follows
        the paper (``Q~ = q I`` fixes one target, eq 44-45, then a real step moves the
        by-product pole); ``"diagonal"`` does it in one step with ``Q~ = diag(q1, q2)``.  The
        paper's way falls back to the diagonal step when no root of (44)-(45) keeps Q >= 0.

    Returns
    -------
    SolheimResult
        ``L`` (the paper's K), ``Q`` (Q'), ``P``, ``poles``, ``steps``, ``verification``.  A
        result whose Q is indefinite (a pole moved towards the origin) is not ``success``.

    Raises
    ------
    ValidationError
        No R in the plant, unstable or zero (discrete) targets, unknown ``complex_to_real``,
        or a pair step without a real solution.
    DimensionError, NotConjugateClosedError
        Wrong number of poles / not closed under conjugation.
    NotObservableError
        An eigenvalue that must move is unobservable (``h = 0``).
    RiccatiError
        A modal Riccati equation of a pair step has no stabilizing solution.

    References
    ----------
    Chang & Lee 1984 (seed 000), eq (23)-(45), Examples 1-2, appendix; Solheim 1972.

    Examples
    --------
    >>> from optdesign import Plant
    >>> res = solheim(Plant([[0, 1], [-6, -5]], [[1, 0]], R=[[1]]), [-5, -8])
    >>> res.L.ravel().round(9), res.Q.round(9)    # seed 000, Example 1
    (array([ 8., -6.]), array([[ 76., -42.],
           [-42.,  84.]]))
    """
    if complex_to_real not in COMPLEX_TO_REAL:
        raise ValidationError(f"complex_to_real must be one of {COMPLEX_TO_REAL}; found {complex_to_real!r}")
    R = plant.R
    if R is None:
        raise ValidationError("solheim: the plant has no R; the sequential method needs the "
                              "measurement-noise covariance R")
    target = as_poles("poles", poles, plant.n)
    disc = plant.is_discrete
    if not np.all(_stable(target, disc)):
        bad = target[~_stable(target, disc)]
        where = "inside the unit circle" if disc else "in the open left half-plane"
        raise ValidationError(
            f"solheim: target poles must be stable ({where}), since a steady-state Kalman filter is; "
            f"found {', '.join(_fmt(z) for z in bad)}")
    if disc and np.any(target == 0):
        raise ValidationError("solheim: a discrete-time target pole at 0 needs an infinite process noise")
    st = _State(plant, R)
    for kind, moved, tgt in _order(_plan(np.linalg.eigvals(plant.A), target)):
        if kind == "r2r":
            _real_step(st, float(moved[0].real), float(tgt[0].real))
        elif kind == "c2r" and complex_to_real == "paper":
            done = _pair_paper(st, moved[0], (float(tgt[0].real), float(tgt[1].real)))
            if done is None:
                _pair_diagonal(st, moved, tgt, note="eq (44)-(45) has no root keeping Q >= 0; "
                                                    "Q~ = diag(q1, q2) used instead")
            else:
                r2, other = done
                _real_step(st, r2, other,
                           note="moves the by-product pole of eq (44)-(45); q~ from eq (28) "
                                "(the paper: trial and error)")
        else:
            _pair_diagonal(st, moved, tgt)
    return _finish(plant, R, target, st)


def _finish(plant: Plant, R: NDArray[np.float64], target: NDArray, st: _State) -> SolheimResult:
    A, C = plant.A, plant.C
    L, Q, P = st.L, 0.5 * (st.Q + st.Q.T), 0.5 * (st.P + st.P.T)
    poles = _sort_poles(np.linalg.eigvals(A - L @ C))
    perr = pole_error(poles, target)
    nq = max(1.0, float(np.linalg.norm(Q, 2)))
    qmin = float(np.linalg.eigvalsh(Q)[0]) if Q.size else 0.0
    pmin = float(np.linalg.eigvalsh(P)[0])
    npn = max(1.0, float(np.linalg.norm(P, 2)))
    if plant.is_discrete:
        S = C @ P @ C.T + R
        L_formula = A @ np.linalg.solve(S, C @ P).T
    else:
        L_formula = np.linalg.solve(R, C @ P).T
    sum_err = float(np.linalg.norm(L - L_formula)) / max(1.0, float(np.linalg.norm(L)))
    # no pole is computable better than its rounding floor (capped at 1e-6, as in the verbs)
    ptol = max(1e-8, min(eigenvalue_rounding_floor(A - L @ C), 1e-6))
    checks = [
        Check.at_most("pole_error", perr, ptol, "max relative distance of eig(A - L C) to the targets "
                      "(tolerance: 1e-8 or the eigenvalue rounding floor of A - L C)"),
        Check.at_most("riccati_residual", filter_are_residual(plant, P, Qs=Q), 1e-10,
                      "relative residual of the filter ARE for P = sum P_k with Q' = sum Q'_k"),
        Check.at_most("step_sum", sum_err, 1e-9, "appendix: sum K_k equals the gain formula of sum P_k"),
        Check.at_least("Q_min_eig", qmin / nq, -1e-10, "smallest eigenvalue of Q' (relative)"),
        Check.at_least("P_min_eig", pmin / npn, -1e-10, "smallest eigenvalue of P (relative)"),
    ]
    message = f"{len(st.steps)} step(s) of the sequential method"
    if qmin < -1e-10 * nq:
        bad = [i + 1 for i, s in enumerate(st.steps) if np.linalg.eigvalsh(s.q_tilde)[0] < 0]
        message += (f"; Q' is indefinite (step(s) {bad} need a q~ with a negative eigenvalue -- for a real "
                    f"step: the pole moves towards the origin); the target may still be reachable with "
                    f"another Q (use kalman_for_poles)")
    else:
        try:
            Qpsd = Q - min(qmin, 0.0) * np.eye(plant.n)
            are = filter_are(plant.replace(G=None, Q=Qpsd))
            checks.append(Check.at_most(
                "are_resolve_gain", float(np.linalg.norm(are.L - L)) / max(1.0, float(np.linalg.norm(L))),
                1e-8, "gain of an independent filter_are solve with Q' vs sum K_k"))
            checks.append(Check.at_most("are_resolve_poles", pole_error(are.poles, target),
                                        max(1e-8, min(eigenvalue_rounding_floor(A - are.L @ C), 1e-6)),
                                        "poles of the independent filter_are solve vs targets"))
        except (RiccatiError, ValidationError) as exc:
            checks.append(Check.at_most("are_resolve_gain", float("inf"), 1e-8, f"filter_are failed: {exc}"))
    ver = Verification.of(checks)
    if not ver.passed:
        message += "; failed: " + ", ".join(c.name for c in ver.failed)
    return SolheimResult(L=L, Q=Q, P=P, poles=poles, target=target, steps=tuple(st.steps),
                         status=Status.SOLVED, message=message, verification=ver, plant=plant)
