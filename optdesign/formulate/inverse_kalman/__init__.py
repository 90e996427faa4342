r"""Inverse Kalman problem: which ``Q >= 0`` gives a steady-state filter with these poles?

Builds (never solves) the formulations used by :func:`optdesign.kalman_for_poles`.

Linear-in-P relations for a fixed gain L
----------------------------------------
Continuous time, ``A P + P A' - P C' R^-1 C P + Q = 0`` and ``L = P C' R^-1``.  With L
fixed, ``P C' R^-1 C P = L R L'``, so

.. math::

    P C' = L R, \qquad Q = L R L' - A P - P A'            \tag{C}

are linear in P; equivalently ``(A - LC) P + P (A - LC)' + L R L' + Q = 0``, so
``P >= 0`` follows from ``Q >= 0`` when ``A - L C`` is stable.

Discrete time, predictor DARE ``P = A P A' - A P C' S^-1 C P A' + Q`` with the innovation
covariance ``S = C P C' + R`` and ``L = A P C' S^-1``.  From ``L S = A P C'``, i.e.
``L (C P C' + R) = A P C'``,

.. math::

    (A - L C) P C' = L R, \qquad
    Q = P - A P A' + L S L' = P - (A - L C) P (A - L C)' - L R L'   \tag{D}

(the second form uses ``A P C' = L S`` twice), again linear in P for fixed L, and a Lyapunov
(Joseph) form: ``P = F P F' + L R L' + Q`` with ``F = A - L C``, so ``P >= 0`` when F is Schur
stable and ``Q >= 0``.  Conversely, any symmetric P with (C) / (D), ``Q >= 0`` and ``A - L C``
stable is the stabilizing Riccati solution for that Q, and L is its Kalman gain
(in discrete time ``S = C P C' + R > 0`` because ``P >= 0``).

Hence, for a fixed L (single output: L is fixed by the poles), ``{Q >= 0, (C) or (D)}`` is an
SDP in ``(P, Q)`` -- :func:`build_fixed_gain_sdp`.  The family of Q for one L is an affine
slice of the PSD cone (for seed 000's Example 1 it is one-dimensional: ``P22`` is free).

With several outputs L is not fixed by the poles.  :func:`build_spectral_nlp` (the default
NLP) works in Q alone: by the Kalman spectral identity ``T(s) R T(-s)' = R + C (sI - A)^-1 Q
(-sI - A')^-1 C'`` a stable ``s_i`` is a filter pole iff that p x p matrix is singular at
``s_i``, i.e. has a unit null vector ``w_i`` -- constraints bilinear in ``(Q, w_i)`` (linear
in Q for one output), with ``Q = F F'`` so that ``Q >= 0`` by construction; L and P follow
from one Riccati solve (:func:`build_spectral_nlpsol`: the same NLP with closed-form Jacobian
and Lagrangian Hessian, for the full / input structures).  :func:`build_pole_nlp` is the
state-space alternative in ``(L, P, F, X)``: the relations (C)/(D) (bilinear in L and P) and
the eigenvalue conditions in real modal form ``(A - L C) X = X Lambda``; it is used where the
spectral form is singular (a target at an eigenvalue of A or its mirror) and, with
``closest=True`` (the eigenvalues ``Lambda(mu)`` become variables and the objective is their
distance to the targets), for the closest achievable poles reported as a certificate when a
target is out of reach.

Structures of Q: ``"full"`` (any n x n ``Q >= 0``), ``"input"`` (``Q = G Qw G'``, ``Qw >= 0``
m x m) and ``"diagonal"`` (``Q = G diag(qw) G'``, ``qw >= 0``: independent noise inputs; a
diagonal Q when ``G = I``).

Objectives (which member of the family is returned): ``"min_trace"`` minimizes ``trace(Q)``
(state-space Q, whatever the structure); ``"nearest"`` minimizes the Frobenius distance of the
decision covariance (Q for ``"full"``, Qw -- ``diag(qw)`` -- otherwise) to ``Q_nominal``;
``"feasibility"`` maximizes the smallest eigenvalue ``t`` of the decision covariance (the most
robustly positive member; ``t < 0`` at the optimum measures infeasibility).  For a fixed stable
gain that maximum is finite: a direction D with ``D C' = 0`` and ``-(A D + D A') >= 0`` would
give ``(A - LC) D + D (A - LC)' <= 0``, hence ``D >= 0`` and ``C D C' = 0``, hence ``D = 0`` by
observability -- the PSD part of the family is bounded.

References
----------
Chang & Lee 1984 (seed 000), eq (20)-(21).  Kalman, R. E., "When is a linear control system
optimal?", J. Basic Eng. 86 (1964) 51-60 (the inverse problem and the return difference).
Anderson, B. D. O. & Moore, J. B., *Optimal Filtering*, Prentice-Hall 1979 (the spectral
factorization / return-difference identity of the Kalman filter).
"""

from .common import (
    FAST_OBJECTIVES,
    FAST_STRUCTURES,
    OBJECTIVES,
    STRUCTURES,
    check_choice,
    chol_factor,
    fixed_gain_maps,
    modal_blocks,
    noise_input,
    psd_part,
    spectral_terms,
    tril_index,
)
from .fixed_gain import FixedGainSDP, build_fixed_gain_sdp
from .pole_nlp import PoleNLP, build_pole_nlp
from .spectral import (
    SpectralNLP,
    SpectralSDP,
    build_spectral_nlp,
    build_spectral_sdp,
    spectral_linear_conditions,
)
from .spectral_nlpsol import SpectralNLPSol, build_spectral_nlpsol

__all__ = [
    "STRUCTURES",
    "OBJECTIVES",
    "FAST_STRUCTURES",
    "FAST_OBJECTIVES",
    "check_choice",
    "tril_index",
    "psd_part",
    "chol_factor",
    "fixed_gain_maps",
    "modal_blocks",
    "noise_input",
    "spectral_terms",
    "FixedGainSDP",
    "build_fixed_gain_sdp",
    "PoleNLP",
    "build_pole_nlp",
    "SpectralNLP",
    "build_spectral_nlp",
    "spectral_linear_conditions",
    "SpectralSDP",
    "build_spectral_sdp",
    "SpectralNLPSol",
    "build_spectral_nlpsol",
]
