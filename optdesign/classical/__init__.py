"""Classical layer: analytical references (Riccati solvers, the sequential Solheim/Chang-Lee
method, the closed forms of the seed papers, block-pulse Riccati DE, pole placement)."""
from .jung_huh import *  # noqa: E402,F401,F403  (seed 001, issue 4)
from .solheim import solheim  # noqa: E402,F401  (seed 000, issue 3)
