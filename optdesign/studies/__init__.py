"""Studies layer: sweeps and Pareto fronts over design parameters."""
