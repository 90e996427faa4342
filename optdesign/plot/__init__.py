"""Pictures of designs: pole maps with regions, model clouds, Pareto fronts and sweeps.

matplotlib is optional and imported lazily; no function here selects a backend.
"""
