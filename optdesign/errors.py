"""Exception hierarchy of optdesign.

Every exception raised on purpose by optdesign derives from :class:`OptDesignError`
*and* from the builtin a caller would naturally catch (``ValueError`` for bad input,
``numpy.linalg.LinAlgError`` for a Riccati failure, ``RuntimeError`` for a solver
failure, ``ImportError`` for a missing optional backend).  So ``except ValueError``
keeps working, and ``except optdesign.OptDesignError`` catches everything of ours.

Messages name the offending matrix and the expected versus found shape or property,
following ``scipy.linalg._solvers``.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "OptDesignError",
    "ValidationError",
    "ArgumentTypeError",
    "DimensionError",
    "NotFiniteError",
    "NotSymmetricError",
    "NotPositiveDefiniteError",
    "NotPositiveSemidefiniteError",
    "UnreachableModesError",
    "NotObservableError",
    "NotControllableError",
    "NotConjugateClosedError",
    "EmptyRegionError",
    "DefectivePolesError",
    "InfeasibleError",
    "SolverError",
    "BackendUnavailableError",
    "RiccatiError",
    "ProblemNotFoundError",
    "ProblemFileError",
    "OutputPathError",
    "OutputExistsError",
    "OptDesignWarning",
    "OptDesignDeprecationWarning",
]


class OptDesignError(Exception):
    """Root of every exception raised deliberately by optdesign."""


class ValidationError(OptDesignError, ValueError):
    """An input is malformed (wrong shape, non-finite, wrong property)."""


class ArgumentTypeError(ValidationError, TypeError):
    """An argument of a kind the verb cannot take (a transfer function where a state-space
    system is needed; a keyword a verb does not support): ``except TypeError`` catches it, as
    python-control's ``ControlArgument``."""


class DimensionError(ValidationError):
    """A matrix or vector has the wrong shape (message: expected vs found)."""


class NotFiniteError(ValidationError):
    """A matrix contains NaN or Inf."""


class NotSymmetricError(ValidationError):
    """A matrix that must be symmetric (Q, R, P0) is not."""


class NotPositiveDefiniteError(ValidationError):
    """A matrix that must be positive definite (R) is not."""


class NotPositiveSemidefiniteError(ValidationError):
    """A matrix that must be positive semidefinite (Q) is not."""


class UnreachableModesError(ValidationError):
    """A pair is not observable or not controllable: the common base of :class:`NotObservableError`
    and :class:`NotControllableError` (neither is a kind of the other).

    Attributes
    ----------
    modes : ndarray of complex
        The offending eigenvalues of A found by the PBH test.
    """

    def __init__(self, message: str, modes=None):
        super().__init__(message)
        self.modes = np.asarray([] if modes is None else modes, dtype=complex)


class NotObservableError(UnreachableModesError):
    """The pair (C, A) is not observable (or not detectable where that suffices); ``modes`` are the
    unobservable eigenvalues of A found by the PBH test."""


class NotControllableError(UnreachableModesError):
    """The pair (A, B) is not controllable (or not stabilizable): the dual of
    :class:`NotObservableError` for state-feedback designs; ``modes`` are the uncontrollable
    eigenvalues of A.  Not a :class:`NotObservableError` (since 0.2.0): catch
    :class:`UnreachableModesError` for either."""


class NotConjugateClosedError(ValidationError):
    """A set of poles for a real system is not closed under complex conjugation."""


class EmptyRegionError(ValidationError):
    """A pole region (typically an intersection) has an empty interior."""


class DefectivePolesError(ValidationError):
    """A pole is requested more often than ``rank(C)``: ``A - L C`` would be defective.

    The eigenspace of ``A - L C`` for a pole has dimension at most ``rank(C)`` (more at an
    unobservable mode), so a larger multiplicity forces a Jordan block: kappa2 is infinite for
    every gain.  The eigenstructure engine raises it; with a separation
    (:func:`optdesign.engines.eigenstructure.spread_poles`) it designs for the nearest
    distinct-pole set instead.

    Attributes
    ----------
    pole : complex
    multiplicity : int
        How often the pole is requested.
    rank : int
        ``rank(C)``.
    """

    def __init__(self, message: str, *, pole: complex, multiplicity: int, rank: int) -> None:
        super().__init__(message)
        self.pole = complex(pole)
        self.multiplicity = int(multiplicity)
        self.rank = int(rank)


class InfeasibleError(OptDesignError, ValueError):
    """A design question has no solution.

    Design verbs normally *return* an infeasible result with a certificate; this
    exception is raised only where the caller asked for an exception
    (e.g. ``result.raise_for_status()``).

    Attributes
    ----------
    certificate : object or None
        Evidence of infeasibility (e.g. a frequency at which an inequality fails).
    """

    def __init__(self, message: str, certificate=None):
        super().__init__(message)
        self.certificate = certificate


class SolverError(OptDesignError, RuntimeError):
    """A numerical backend failed.  The message names the backend and its native status.

    Attributes
    ----------
    backend : str
    native_status : str
    """

    def __init__(self, message: str, backend: str = "", native_status: str = ""):
        super().__init__(message)
        self.backend = backend
        self.native_status = native_status


class BackendUnavailableError(OptDesignError, ImportError):
    """An optional backend (python-control, dask, matplotlib, a cvxpy solver) is not installed."""


class RiccatiError(OptDesignError, np.linalg.LinAlgError):
    """A Riccati equation has no stabilizing solution or could not be solved accurately.

    The message says which: eigenvalues on the imaginary axis / unit circle, a singular
    X1 block of the invariant-subspace basis, or an excessive residual.
    """


class ProblemNotFoundError(OptDesignError, KeyError):
    """No problem of that name in the problem library."""

    def __str__(self) -> str:  # KeyError quotes its message; keep it readable
        return str(self.args[0]) if self.args else ""


class ProblemFileError(ValidationError):
    """A user's problem file that is missing, unreadable or has a bad field (the message names the
    file and the field)."""


class OutputPathError(ValidationError):
    """An output path that may not be written: outside the working folder without being asked for
    (``allow_outside=True``, ``optdesign study --allow-outside``), a name with a NUL byte or a path
    separator, or a folder standing where a file is to be written (the message names the path and
    the field or flag it came from)."""


class OutputExistsError(OptDesignError, FileExistsError):
    """An output file (or a symbolic link) exists where a result is to be written, and overwriting
    was not asked for (``overwrite=True``, ``optdesign study --overwrite``).

    Attributes
    ----------
    path : str
        The existing file.
    """

    def __init__(self, message: str, path: str = "") -> None:
        super().__init__(message)
        self.path = str(path)

    def __str__(self) -> str:  # OSError's str of one argument is the message; keep it so
        return str(self.args[0]) if self.args else ""


class OptDesignWarning(UserWarning):
    """The one warning optdesign emits of its own (library code never prints): a design call
    returned a *successful* answer while a solver's captured output cast doubt on it -- cvxpy's
    "Solution may be inaccurate", CasADi's "Failed to calculate multipliers", IPOPT's restoration
    failure.  At most one per call, naming the solver and pointing to
    ``result.solver_stats.extra["solver_doubts"]``; the solver's own text is never printed (rule and
    patterns: :mod:`optdesign.backends.report`).  Silence it with
    ``warnings.filterwarnings("ignore", category=optdesign.OptDesignWarning)``, or make it an error
    with ``"error"``."""


class OptDesignDeprecationWarning(DeprecationWarning):
    """A deprecated spelling of optdesign's own (an old argument name, alias or no-op), accepted for
    one release.  Its own class so that a test run can turn exactly these into errors
    (``-W error::optdesign.errors.OptDesignDeprecationWarning``) without the third-party ones."""
