r"""Generalized observers with an output-noise model (seed 003), and an observer that really
rejects the noise.

The plant is discrete time, its output corrupted by a persistent noise of known class
(:mod:`optdesign.noise`)::

    x(k+1) = A x(k) + B u(k),      y(k) = C x(k) + delta(k),      P(q) delta = 0.

Generalized observer (seed 003 eq (2))
--------------------------------------
::

    xh(k+1) = A xh + B u + K xi + H eps,     xi(k+1) = N xi + M eps,     eps = y - C xh,

with ``(N, M)`` the realization of the noise model (:meth:`NoiseModel.realization`).  With
``e = x - xh`` the error system is

.. math::

    \begin{bmatrix} e \\ \xi \end{bmatrix}(k+1) =
    \underbrace{\begin{bmatrix} A - HC & -K \\ MC & N \end{bmatrix}}_{F}
    \begin{bmatrix} e \\ \xi \end{bmatrix}(k) +
    \begin{bmatrix} -H \\ M \end{bmatrix} \delta(k),
    \qquad \varepsilon = [C\ 0] \begin{bmatrix} e \\ \xi \end{bmatrix} + \delta ,

and the design condition is that ``F`` is Schur (seed 003 Theorem 1, eq (4)).

**What it guarantees under output noise (internal model principle).**  Because every mode
``lambda`` of the noise is a mode of ``N`` and ``(N, M)`` is controllable, the transfer from
``delta`` to the innovation ``eps`` vanishes there,
``I + [C 0](lambda I - F)^{-1} [-H; M] = 0`` (verified for every design as the
``internal_model`` check).  Hence, for every stable design and every noise of the class:

* ``eps = y - C xh -> 0``, i.e. ``C xh - y -> 0``: the estimate reproduces the **noisy**
  measurement;
* therefore ``C e -> -delta``: the state error ``x - xh`` does **not** converge to zero, and
  ``C xh - C x -> delta``;
* ``xi`` converges to a persistent non-zero signal (it carries the noise).

So the seed's claims (3a) ``x - xh -> 0`` and (3b) ``xi -> 0`` hold only without noise.  What
the seed's proof (eq (13)-(19)) actually shows is ``P(q) e -> 0``: the error converges to a
signal of the noise class, not to zero.  The simulation tests establish this; the example
figure shows it.

**Pole placement as an ordinary observer design.**  For a free *coupling* matrix ``E``
(n, r p) and any ``S`` commuting with ``N``, ``T = diag(I_n, S)`` gives

.. math::

    T F T^{-1} = \begin{bmatrix} A - HC & -K S^{-1} \\ S M C & N \end{bmatrix}
               = A_a - L_a C_a, \quad
    A_a = \begin{bmatrix} A & E \\ 0 & N \end{bmatrix}, \;
    C_a = [C\ \ 0], \;
    L_a = \begin{bmatrix} H \\ -S M \end{bmatrix}, \; K = -E S .

Equivalently, and without any choice, ``F = A_s - L_s C_s`` with ``A_s = [[A, 0], [MC, N]]``,
``C_s = diag(C, I)`` and the *structured* gain ``L_s = [[H, K], [0, 0]]`` (:func:`structured_pair`);
``(C_s, A_s)`` is observable iff ``(C, A)`` is, but the zero rows of ``L_s`` make it a structured
placement, which the pair below turns into an ordinary one.  ``method="well_conditioned"``
optimizes over this structured gain (the NLP's ``kappa2`` is then that of ``F`` itself).

So ``method="place"`` places the poles of the pair ``(C_a, A_a)`` (the observer of a plant
driven by an *input* disturbance ``d(k+1) = N d`` entering through ``E``), takes
``H = L_1``, solves ``S N = N S, S M = -L_2`` for ``S`` (unique: ``(N, M)`` is controllable and
``N`` cyclic per channel; invertible whenever no placed pole is a noise mode) and sets
``K = -E S``.  ``(C_a, A_a)`` is observable iff ``(C, A)`` is observable and, for every noise
mode ``lambda``, ``[[lambda I - A, -E V_lambda], [C, 0]]`` is nonsingular (``V_lambda`` spans the
eigenvectors of ``N`` at ``lambda``).  With ``rank C = p`` a suitable ``E`` always exists, so
seed 003's Theorem 2 holds -- a generalized observer with arbitrary poles exists iff
``(C, A)`` is observable (and ``rank C = p``), **whatever the noise modes**, even when a noise
mode is a plant mode.  (Its proof is wrong, though: eq (23), ``rank(sI - QNQ^{-1}) = n`` for all
``s``, fails at every noise mode; it is the free ``E``, the seed's ``P``, that saves the
conclusion.)  Necessity: an unobservable mode of ``(C, A)`` is an eigenvalue of ``F`` for all
``H, K``.  If ``rank C < p``, the difference of two channels' internal models is unobservable
and ``F`` keeps the noise modes on the unit circle.

The coupling decides *where* the noise goes.  ``coupling="output"`` (default) takes
``E = Pi N - A Pi`` with ``Pi = C^+ Gamma``: then ``(C_a, A_a)`` is similar to the
output-disturbance pair below, and ``x - xh -> -C^+ delta``: the error is confined to the
measured directions (for ``C = [I 0]`` the unmeasured states converge exactly, only the
measured ones follow the noisy ``y``).  It is impossible when a noise mode is a plant mode;
then ``"direct"`` (``E = [C^+, 0, ...]``, the direction of seed 003's printed step gain ``K``) or
``"zero_free"`` (``E = [E_1, 0, ...]`` with ``C A^k E_1 = 0`` for ``k < n - 1``,
``C A^(n-1) E_1 = I``: ``(A, E_1, C)`` has no finite invariant zero, so the pair is observable at
every noise mode) serves, as does any explicit (n, r p) array.

Noise-rejecting observer (output-disturbance model)
---------------------------------------------------
To make ``xh -> x`` the noise must be *estimated* as part of the state: with
``d(k+1) = N d(k)``, ``delta = Gamma d``::

    [x; d](k+1) = diag(A, N) [x; d] + [B; 0] u,     y = [C  Gamma] [x; d],

an ordinary (predictor) observer with gain ``L_a = [L_x; L_d]`` for this pair gives
``[x - xh; d - dh] -> 0`` for every noise of the class.  The pair is observable iff ``(C, A)``
is observable and **no noise mode is a plant mode** (otherwise an output offset of that
mode is indistinguishable from the plant's own response; :class:`NotObservableError` names
the conflict).

The package, by responsibility: :mod:`.common` (input checks, default poles, the coupling and the
placement pair, shared checks), :mod:`.results` (:class:`GeneralizedObserver`,
:class:`NoiseRejectingObserver`, :class:`ObserverSimulation`), :mod:`.verbs`
(:func:`generalized_observer`, :func:`noise_rejecting_observer`, :func:`structured_pair`) and
:mod:`.simulation` (:func:`simulate_observer`).

References
----------
Kim, H. S., Lee, C. H. & Kim, S. B., "A Study on Generalized Observer Structure and its
Characteristic of Noise Reduction" (seed 003), eq (2)-(24), section 5.
Francis, B. A. & Wonham, W. M., "The internal model principle of control theory",
Automatica 12 (1976) 457-465.
Johnson, C. D., "Accommodation of external disturbances in linear regulator and servomechanism
problems", IEEE TAC 16 (1971) 635-644 (disturbance-augmented observers).
"""

from .common import augmented_placement_pair, default_poles
from .results import GeneralizedObserver, NoiseRejectingObserver, ObserverSimulation
from .simulation import simulate_observer
from .verbs import generalized_observer, noise_rejecting_observer, structured_pair

__all__ = [
    "GeneralizedObserver",
    "NoiseRejectingObserver",
    "ObserverSimulation",
    "generalized_observer",
    "noise_rejecting_observer",
    "simulate_observer",
    "default_poles",
    "augmented_placement_pair",
    "structured_pair",
]
