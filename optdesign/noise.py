"""Output-noise models (alias of :mod:`optdesign.model.noise`)."""

from .model.noise import *  # noqa: F401,F403
from .model.noise import __all__  # noqa: F401
