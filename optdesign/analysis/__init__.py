"""Analysis layer: pure functions of matrices (metrics, observability, return difference, margins)."""
