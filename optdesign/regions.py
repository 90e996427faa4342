"""Pole regions (alias of :mod:`optdesign.model.regions`)."""

from .model.regions import *  # noqa: F401,F403
from .model.regions import __all__  # noqa: F401
