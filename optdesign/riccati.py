"""Riccati solvers (alias of :mod:`optdesign.classical.riccati`)."""

from .classical.riccati import *  # noqa: F401,F403
from .classical.riccati import __all__  # noqa: F401
