"""The plant whose state is to be estimated."""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._validate import as_array, as_matrix, as_positive_float, as_square, check_pd, check_psd
from ..errors import BackendUnavailableError, NotObservableError, SolverError, ValidationError

__all__ = ["Plant"]


def _readonly(X: NDArray[Any]) -> NDArray[Any]:
    X.setflags(write=False)
    return X


def _unobservable_modes(A: NDArray, C: NDArray, tol: float) -> NDArray[np.complex128]:
    """The observability staircase of :meth:`Plant.unobservable_modes` (relative rank tolerance
    ``tol``)."""
    from scipy.linalg import lapack, matrix_balance

    n = A.shape[0]
    _, (s, _) = matrix_balance(A, permute=False, separate=True)
    Ab = (A * s[None, :]) / s[:, None]  # D^-1 A D
    Cb = C * s[None, :]  # C D
    na = max(float(np.linalg.norm(Ab, 1)), 1.0)
    nc = float(np.linalg.norm(Cb, 1))
    if nc == 0.0:
        return np.linalg.eigvals(A).astype(complex)
    atol = tol * na
    # controllability staircase of the dual pair (A', C' scaled like A: output scaling does not
    # change observability)
    F = np.asfortranarray(Ab.T)
    block = Cb.T * (na / nc)
    lwork = 64 * n
    k = 0
    while True:
        U, sv, _ = np.linalg.svd(block, full_matrices=False)
        r = int(np.sum(sv > atol))
        if r == 0:
            break
        if k + r == n:
            return np.zeros(0, dtype=complex)
        # Householder reflectors H = H_1 ... H_r with H' U[:, :r] = [R; 0]: the first r rows of
        # H' block span its range; apply F <- diag(I_k, H)' F diag(I_k, H)
        v, tau, _, info_q = lapack.dgeqrf(U[:, :r])
        F[k:, :], _, info_l = lapack.dormqr("L", "T", v, tau, F[k:, :], lwork)
        F[:, k:], _, info_r = lapack.dormqr("R", "N", v, tau, F[:, k:], lwork)
        if info_q or info_l or info_r:  # pragma: no cover - only for an invalid LAPACK argument
            raise SolverError(f"dgeqrf/dormqr failed (info {info_q}, {info_l}, {info_r})", backend="lapack")
        block = F[k + r:, k:k + r]
        k += r
    return np.linalg.eigvals(F[k:, k:]).astype(complex)


@dataclass(frozen=True, eq=False, repr=False, init=False)
class Plant:
    r"""A linear time-invariant plant seen by a state estimator.

    Continuous time (``dt=None``)::

        x' = A x + B u + G w,    y = C x + v,    E[w w'] = Q,  E[v v'] = R

    Discrete time (``dt > 0``)::

        x[k+1] = A x[k] + B u[k] + G w[k],    y[k] = C x[k] + v[k]

    The state-space process-noise covariance is ``G Q G'`` (the seeds' ``Q' = D Q D'``).

    Parameters
    ----------
    A : (n, n) array_like
        State matrix.
    C : (p, n) array_like
        Output matrix.  A 1-D array of length n is read as one output row.
    G : (n, m) array_like, optional
        Process-noise input matrix.  Default: the identity (m = n).
    Q : (m, m) array_like, optional
        Process-noise covariance, symmetric positive semidefinite.  Needed for Kalman design.
    R : (p, p) array_like, optional
        Measurement-noise covariance, symmetric positive definite.  Needed for Kalman design.
    dt : float, optional
        Sampling period; ``None`` (default) for continuous time.
    name : str, optional
        A label used in messages and reports.
    B : (n, nu) array_like, optional
        Control input matrix, used only for simulation.

    Raises
    ------
    DimensionError
        A is not square or a shape does not match.
    NotFiniteError
        A matrix contains NaN or Inf.
    NotSymmetricError, NotPositiveSemidefiniteError, NotPositiveDefiniteError
        Q not symmetric PSD, R not symmetric PD.
    ValidationError
        dt not a positive number (a string such as ``"0.1"`` is refused, as is a bool); a matrix
        that is not numeric (strings, numeric ones included, ragged lists); name not a string.

    Notes
    -----
    Instances are immutable: the arrays are read-only and :meth:`replace` returns a new,
    re-validated plant.

    Examples
    --------
    >>> from optdesign import Plant
    >>> plant = Plant([[0, 1], [-6, -5]], [[1, 0]], Q=[[1, 0], [0, 1]], R=[[1]])
    >>> plant.n, plant.p, plant.is_discrete
    (2, 1, False)
    """

    A: NDArray[np.float64]
    C: NDArray[np.float64]
    G: NDArray[np.float64]  # always set: the identity when not given
    Q: NDArray[np.float64] | None = None
    R: NDArray[np.float64] | None = None
    dt: float | None = None
    name: str | None = None
    B: NDArray[np.float64] | None = None

    def __init__(self, A: ArrayLike, C: ArrayLike, G: ArrayLike | None = None, Q: ArrayLike | None = None,
                 R: ArrayLike | None = None, dt: float | None = None, name: str | None = None,
                 B: ArrayLike | None = None) -> None:
        A_ = as_square("A", A)
        n = A_.shape[0]
        if n == 0:
            raise ValidationError("A must have at least one state; found shape (0, 0)")
        C_ = as_array("C", C, (0, 1, 2))
        C_ = as_matrix("C", C_, (1, n) if C_.ndim == 1 else (None, n))
        p = C_.shape[0]
        if p == 0:
            raise ValidationError("C must have at least one output row; found shape (0, n)")
        Q_ = None if Q is None else as_square("Q", Q)
        if G is None:
            m = n if Q_ is None else Q_.shape[0]
            if m != n:
                raise ValidationError(
                    f"G is required when Q is not n x n: Q is {m} x {m}, A is {n} x {n}"
                )
            G_ = np.eye(n)
        else:
            G_ = as_matrix("G", G, (n, None))
            m = G_.shape[1]
        Q_ = None if Q_ is None else check_psd("Q", as_square("Q", Q_, m))
        R_ = None if R is None else check_pd("R", as_square("R", R, p))
        dt_ = None if dt is None else as_positive_float("dt", dt)
        B_ = None if B is None else as_matrix("B", B, (n, None))
        if name is not None and not isinstance(name, str):
            raise ValidationError(f"name must be a string; found {type(name).__name__}")
        for k, v in dict(A=A_, C=C_, G=G_, Q=Q_, R=R_, dt=dt_, name=name, B=B_).items():
            object.__setattr__(self, k, _readonly(v) if isinstance(v, np.ndarray) else v)

    # ------------------------------------------------------------------ shape
    @property
    def n(self) -> int:
        """Number of states."""
        return self.A.shape[0]

    @property
    def p(self) -> int:
        """Number of measured outputs."""
        return self.C.shape[0]

    @property
    def m(self) -> int:
        """Number of process-noise inputs (columns of G)."""
        return self.G.shape[1]

    @property
    def is_discrete(self) -> bool:
        """True when the plant is sampled (``dt`` is set)."""
        return self.dt is not None

    @property
    def has_noise_model(self) -> bool:
        """True when both Q and R are given (a Kalman filter can be designed)."""
        return self.Q is not None and self.R is not None

    def process_noise(self) -> NDArray[np.float64]:
        """The state-space process-noise covariance ``G Q G'``, shape (n, n).

        Raises
        ------
        ValidationError
            If Q was not given.
        """
        Q = self.Q
        if Q is None:
            raise self._missing_noise_model(["Q"])
        W = self.G @ Q @ self.G.T
        return 0.5 * (W + W.T)

    def noise_covariances(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``(Q, R)``, the noise covariances a Kalman design needs, both given.

        Returns
        -------
        Q : (m, m) ndarray
            Process-noise covariance.
        R : (p, p) ndarray
            Measurement-noise covariance.

        Raises
        ------
        ValidationError
            Q or R was not given (the message names which).
        """
        Q, R = self.Q, self.R
        if Q is None or R is None:
            raise self._missing_noise_model([k for k, v in (("Q", Q), ("R", R)) if v is None])
        return Q, R

    def require_noise_model(self, need_R: bool = True) -> None:
        """Raise a ValidationError naming what is missing for a Kalman design."""
        missing = [k for k in (("Q", "R") if need_R else ("Q",)) if getattr(self, k) is None]
        if missing:
            raise self._missing_noise_model(missing)

    def _missing_noise_model(self, missing: list[str]) -> ValidationError:
        label = f" {self.name!r}" if self.name else ""
        return ValidationError(
            f"plant{label} has no {' and no '.join(missing)}: a Kalman filter needs the "
            f"process-noise covariance Q and the measurement-noise covariance R"
        )

    # ----------------------------------------------------------- observability
    def observability_matrix(self) -> NDArray[np.float64]:
        """``[C; CA; ...; CA^(n-1)]``, shape (n p, n)."""
        blocks = [self.C]
        for _ in range(self.n - 1):
            blocks.append(blocks[-1] @ self.A)
        return np.vstack(blocks)

    def unobservable_modes(self, tol: float | None = None) -> NDArray[np.complex128]:
        """Eigenvalues of A that the output does not see.

        Computed by the orthogonal observability staircase (the dual of the controllability
        staircase of Van Dooren 1981 / SLICOT TB01UD) on the diagonally balanced pair
        ``(D^-1 A D, C D)``: the unobservable eigenvalues are those of the trailing block that
        the staircase cannot reach.  Equivalent to the PBH test (``rank [lam I - A; C] < n``),
        but it needs no eigenvalue clustering, so repeated eigenvalues and badly scaled plants
        (e.g. CAREX 2.9, ||A|| ~ 1e7) are handled.

        Each step finds the rank of the new block by an SVD and applies the orthogonal
        transformation as Householder reflectors to the rows and columns it changes only
        (LAPACK ``dormqr``), so the whole staircase costs O(n^3) -- a few n^3 flops, less than one
        eigenvalue decomposition of A.  The result for the default ``tol`` is computed once and
        kept on the (immutable) plant.

        The staircase is backward stable, but its forward error grows like ``eps`` over the product
        of its subdiagonal blocks (the conditioning of the Krylov basis of ``C'``): for a single
        output and more than a few tens of states, a mode hidden exactly in exact arithmetic may
        be seen, after rounding, through a coupling far above ``tol`` (no orthogonal method can
        decide that case reliably).  Downstream checks (Riccati residual, stability of the filter)
        then report the ill-posed design.

        Parameters
        ----------
        tol : float, optional
            Relative rank tolerance of the staircase SVDs (default ``1000 n eps``), relative to
            ||A|| after balancing; a finite number ``> 0``.

        Returns
        -------
        (k,) ndarray of complex
            The unobservable eigenvalues (empty when (C, A) is observable).

        Raises
        ------
        ValidationError
            ``tol`` is not a finite number > 0.

        References
        ----------
        P. Van Dooren, "The generalized eigenstructure problem in linear system theory",
        IEEE TAC 26(1), 1981.
        """
        if tol is not None:
            return _unobservable_modes(self.A, self.C, as_positive_float("tol", tol))
        cached: NDArray[np.complex128] | None = self.__dict__.get("_unobservable")
        if cached is None:
            cached = _unobservable_modes(self.A, self.C, 1e3 * self.n * np.finfo(float).eps)
            cached.setflags(write=False)
            object.__setattr__(self, "_unobservable", cached)  # the plant is immutable: computed once
        return cached.copy()

    def is_observable(self, tol: float | None = None) -> bool:
        """True when (C, A) is observable (no unobservable mode)."""
        return self.unobservable_modes(tol).size == 0

    def is_detectable(self, tol: float | None = None) -> bool:
        """True when every unobservable mode is stable (``Re < 0``, or ``|z| < 1`` in discrete time)."""
        modes = self.unobservable_modes(tol)
        return bool(np.all(np.abs(modes) < 1.0) if self.is_discrete else np.all(modes.real < 0.0))

    def require_observable(self, *, detectable_ok: bool = False, what: str = "this design") -> None:
        """Raise :class:`NotObservableError` naming the unobservable modes.

        Parameters
        ----------
        detectable_ok : bool
            Accept unobservable modes that are stable.
        what : str
            Phrase naming the design, used in the message.
        """
        modes = self.unobservable_modes()
        if detectable_ok:
            stable = np.abs(modes) < 1.0 if self.is_discrete else modes.real < 0.0
            modes = modes[~stable]
        if modes.size:
            label = f" of plant {self.name!r}" if self.name else ""
            kind = "undetectable" if detectable_ok else "unobservable"
            shown = ", ".join(f"{complex(z):.6g}".strip("()") for z in modes)
            raise NotObservableError(
                f"(C, A){label} is {kind}, so {what} is impossible: {kind} mode(s) {shown} "
                f"(PBH test: rank [lambda I - A; C] < n)",
                modes=modes,
            )

    # ------------------------------------------------------------ conversion
    def replace(self, **changes: Any) -> Plant:
        """A new plant with some fields replaced (re-validated).

        Raises
        ------
        ValidationError
            A field name that a Plant does not have (or any error of the constructor).
        """
        kw = {f.name: getattr(self, f.name) for f in fields(self)}
        unknown = sorted(set(changes) - set(kw))
        if unknown:
            raise ValidationError(f"Plant.replace: {unknown[0]!r} is not a field of Plant; fields are "
                                  f"{', '.join(kw)}")
        kw.update(changes)
        return Plant(**kw)

    @classmethod
    def from_control(cls, sys, *, G=None, Q=None, R=None, name: str | None = None) -> Plant:
        """Build a plant from a python-control ``StateSpace`` (python-control is optional).

        ``sys.B`` becomes the control input B; ``sys.dt`` of 0 or None means continuous time,
        ``dt=True`` (discrete, unspecified period: what ``control.drss`` returns) is taken as 1, as
        in :func:`optdesign.model.coerce.as_system` (which also says so in its notes).

        Raises
        ------
        BackendUnavailableError
            python-control is not installed.
        ValidationError
            ``sys`` is not a StateSpace.
        """
        try:
            import control
        except ImportError as exc:  # pragma: no cover - exercised only without python-control
            raise BackendUnavailableError(
                "Plant.from_control needs python-control: pip install control"
            ) from exc
        if not isinstance(sys, control.StateSpace):
            raise ValidationError(f"sys must be a control.StateSpace; found {type(sys).__name__}")
        dt = sys.dt
        dt = 1.0 if dt is True else None if (dt is None or dt == 0) else float(dt)
        return cls(np.asarray(sys.A), np.asarray(sys.C), G=G, Q=Q, R=R, dt=dt,
                   name=name if name is not None else (getattr(sys, "name", None) or None),
                   B=np.asarray(sys.B) if np.asarray(sys.B).size else None)

    def to_dict(self) -> dict[str, Any]:
        """Plain-data representation (nested lists), e.g. for JSON output."""
        out: dict[str, Any] = {"name": self.name, "dt": self.dt}
        for k in ("A", "C", "G", "Q", "R", "B"):
            v = getattr(self, k)
            out[k] = None if v is None else v.tolist()
        return out

    def __repr__(self) -> str:
        label = f"{self.name!r}, " if self.name else ""
        time = f"dt={self.dt:g}" if self.is_discrete else "continuous"
        noise = "Q,R given" if self.has_noise_model else "no noise model"
        return f"Plant({label}n={self.n}, p={self.p}, m={self.m}, {time}, {noise})"

    def _repr_html_(self) -> str:
        """Jupyter's view: sizes, time domain and the matrices (A, B, C, G, Q, R) in a table."""
        import html

        from ..results import html_table, html_value

        time = f"discrete, dt = {self.dt:g}" if self.is_discrete else "continuous"
        rows = [("sizes", html.escape(f"n = {self.n} states, p = {self.p} outputs, m = {self.m} noise inputs")),
                ("time", html.escape(time))]
        for k in ("A", "B", "C", "G", "Q", "R"):
            v = getattr(self, k)
            if v is not None:
                rows.append((k, html_value(v)))
        return html_table(f"Plant {self.name}" if self.name else "Plant", rows)
