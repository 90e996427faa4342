"""Formulate layer: turn a design question into an optimization problem (CasADi Opti NLP,
cvxpy SDP).  Builds, never solves."""
