"""Engines layer: optdesign's own algorithms, each kept where a benchmark shows it beats the general
solver at the same optimum -- the eigenstructure placement engine (fixed poles and regions, controller
mode), the inverse-Kalman engine (spectral factor, Newton/SQP, its starts and set-up), the one-output
SDP form and the dense interior-point method, the polish steps, the batched quasi-Newton method and the
normal-closed-loop search.  Engines propose candidates; the design layer verifies them
(:mod:`optdesign.design.verification`) and never the engine itself.  Engines do not import ``design/``.
Their inner thresholds (rank decisions, stage and stopping tolerances, line-search constants) are named
once, each with its derivation or measurement, in :mod:`optdesign.engines.tolerances`.
"""
