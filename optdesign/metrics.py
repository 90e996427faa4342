"""Conditioning metrics of a matrix (alias of :mod:`optdesign.analysis.metrics`)."""

from .analysis.metrics import *  # noqa: F401,F403
from .analysis.metrics import __all__  # noqa: F401
