"""Model layer: what is being designed (Plant, pole regions, noise models).  numpy only."""

from .plant import Plant

__all__ = ["Plant"]
