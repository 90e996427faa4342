"""The optional numerical backends, imported on first use (foundation layer: every layer may use it).

CasADi (IPOPT) and cvxpy (Clarabel, SCS) are hard dependencies, but importing them costs a second;
``import optdesign`` stays cheap and a missing backend raises a
:class:`~optdesign.errors.BackendUnavailableError` that names the package to install.
"""

from __future__ import annotations

from typing import Any

from .errors import BackendUnavailableError

__all__ = ["import_casadi", "import_cvxpy", "import_clarabel", "import_control"]


def import_casadi() -> Any:
    """Import CasADi or raise :class:`BackendUnavailableError` naming the package to install."""
    try:
        import casadi
    except ImportError as exc:  # pragma: no cover - casadi is a hard dependency
        raise BackendUnavailableError("the NLP backend needs CasADi with IPOPT: pip install casadi") from exc
    return casadi


def import_cvxpy() -> Any:
    """Import cvxpy or raise :class:`BackendUnavailableError` naming the package to install."""
    try:
        import cvxpy
    except ImportError as exc:  # pragma: no cover - cvxpy is a hard dependency
        raise BackendUnavailableError("the SDP backend needs cvxpy: pip install cvxpy clarabel scs") from exc
    return cvxpy


def import_control(purpose: str = "this") -> Any:
    """Import python-control (an optional extra) or raise :class:`BackendUnavailableError` naming it.

    Parameters
    ----------
    purpose : str
        What needs it, for the message (e.g. ``"output='control'"``).
    """
    try:
        import control
    except ImportError as exc:
        raise BackendUnavailableError(f"{purpose} needs python-control: pip install control") from exc
    return control


def import_clarabel() -> Any:
    """Import Clarabel (used directly for the fixed-gain SDP) or raise
    :class:`BackendUnavailableError` naming the package to install."""
    try:
        import clarabel
    except ImportError as exc:  # pragma: no cover - clarabel is a hard dependency
        raise BackendUnavailableError("the fixed-gain SDP on Clarabel needs Clarabel: "
                                      "pip install clarabel") from exc
    return clarabel
