"""The per-plant state of the inverse Kalman engine (:mod:`optdesign.engines.inverse_kalman_engine`):
what does not depend on the target poles, built by :func:`prepare_inverse_kalman` and held by the caller
(a held :class:`~optdesign.InverseKalmanProblem` builds it once) -- the family map of the fixed-gain
SDP, the eigenvalues of A and, in continuous time for a full Q and the minimal trace, the complement
form of that SDP (:mod:`optdesign.engines.one_output_sdp`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._deadline import Deadline
from .._validate import as_poles
from ..backends.clarabel_fixed_gain import FamilyMap, family_map
from ..errors import ValidationError
from ..formulate.inverse_kalman import OBJECTIVES, STRUCTURES, spectral_terms
from ..model.plant import Plant
from .one_output_sdp import OneOutputForm, one_output_form, one_output_form_of_plant

#: floor of a norm used as a divisor or a scale in the inverse Kalman engines (the engines' one floor)
from .tolerances import NORM_FLOOR as SCALE_FLOOR

__all__ = ["EngineSetup", "prepare_inverse_kalman", "engine_applies", "SCALE_FLOOR"]



@dataclass(frozen=True, eq=False)
class EngineSetup:
    """What :func:`solve_inverse_kalman` needs of a plant, built once (:func:`prepare_inverse_kalman`).

    Attributes
    ----------
    plant : Plant
    structure : {"full", "input", "diagonal"}
    objective : {"min_trace", "nearest", "feasibility"}
    Gd : (n, k) ndarray
        Noise input of the decision covariance (identity for ``"full"``, G otherwise).
    family : FamilyMap
        The plant-only part of the fixed-gain SDP (its constraint matrix in continuous time).
    complement_form : OneOutputForm or None
        ``"full"`` / ``"min_trace"``, continuous time: the complement form of the fixed-gain SDP
        (:mod:`optdesign.engines.one_output_sdp`; ``n p - p(p - 1)/2`` constraints: n for one
        output, where it is the whole answer; with several outputs the certificate SDP at the
        engine's gain), built once (in discrete time it depends on the gain: built per target);
        None otherwise.
    eig_A : (n,) ndarray
        The eigenvalues of A (the applicability test of the one-output gain).
    verify : bool
        Check every returned design independently (:func:`solve_inverse_kalman`'s
        ``verification``); False when the caller verifies it itself (the public verb does, with
        :mod:`optdesign.design.verification`: the same checks are not run twice).
    """

    plant: Plant
    structure: str
    objective: str
    Gd: NDArray[np.float64]
    family: FamilyMap
    complement_form: OneOutputForm | None = None
    eig_A: NDArray[np.complex128] | None = None
    verify: bool = True

    @property
    def k(self) -> int:
        """Size of the decision covariance."""
        return int(self.Gd.shape[1])

    @property
    def one_output_route(self) -> bool:
        """The n-constraint form is tried first: one output, ``"full"`` / ``"min_trace"``."""
        return self.plant.p == 1 and self.structure == "full" and self.objective == "min_trace"


#: the family's direction matrix T (n(n+1)/2 x (n-p)(n-p+1)/2 doubles) is built for the complement
#: form only below this many bytes (256 MiB: n ~ 80); above, the form of one output comes from
#: Lyapunov solves (:func:`~optdesign.engines.one_output_sdp.one_output_form_of_plant`) or not at all
TRIANGLE_BYTES_MAX = 256 << 20


def prepare_inverse_kalman(plant: Plant, *, q_structure: str = "full",
                           objective: str = "min_trace", verify: bool = True,
                           deadline: Deadline | None = None) -> EngineSetup:
    """Build the per-plant state of the engine.

    Parameters
    ----------
    plant : Plant
        With R (positive definite; validated by Plant); its G (identity by default) carries the
        noise of ``"input"`` / ``"diagonal"``; ``(C, A)`` observable.
    q_structure : {"full", "input", "diagonal"}
        ``Q`` any n x n ``Q >= 0``; ``Q = G Qw G'`` with ``Qw >= 0``; ``Q = G diag(qw) G'``.
    objective : {"min_trace", "nearest", "feasibility"}
    verify : bool
    deadline : Deadline, optional
        The set-up counts against the caller's time limit: the one-output form's solves stop when
        it expires (the form is then None).

    Returns
    -------
    EngineSetup

    Raises
    ------
    ValidationError
        Not a Plant, no R, unknown structure / objective, C with dependent rows.
    NotObservableError
        (C, A) is not observable (the modes are named).
    """
    if not isinstance(plant, Plant):
        raise ValidationError(f"plant must be an optdesign.Plant; found {type(plant).__name__}")
    if q_structure not in STRUCTURES:
        raise ValidationError(f"q_structure must be one of {STRUCTURES}; found {q_structure!r}")
    if objective not in OBJECTIVES:
        raise ValidationError(f"objective must be one of {OBJECTIVES}; found {objective!r}")
    if plant.R is None:
        raise ValidationError("the inverse Kalman engine needs the measurement-noise covariance R: the plant "
                              "has no R")
    plant.require_observable(what="placing every filter pole")
    Gd = np.eye(plant.n) if q_structure == "full" else np.asarray(plant.G, dtype=float)
    fmap = family_map(plant.A, plant.C, plant.dt)
    full_trace = q_structure == "full" and objective == "min_trace"
    form = None
    if full_trace and plant.dt is None:
        # one output: n Lyapunov solves, O(n^3) memory (issue 26: the QR of T was O(n^4) memory and
        # O(n^6) time -- a MemoryError at n = 150); T only where it is small
        form = one_output_form_of_plant(plant.A, plant.C, deadline) if plant.p == 1 else None
        if form is None and fmap.triangle_bytes <= TRIANGLE_BYTES_MAX and not (
                deadline is not None and deadline.expired):
            T = fmap.T  # continuous time (this branch): the plant's map, never None
            form = None if T is None else one_output_form(T)
    return EngineSetup(plant=plant, structure=q_structure, objective=objective, Gd=Gd, family=fmap,
                       complement_form=form, eig_A=np.linalg.eigvals(plant.A).astype(complex),
                       verify=bool(verify))


def engine_applies(setup: EngineSetup, poles: ArrayLike) -> bool:
    """Whether the spectral form applies: no target (relatively, 1e-8) at an eigenvalue of A or of
    its mirror image (``-A`` / ``A^-1``) and no discrete target at 0 (the resolvents are singular
    there; :func:`optdesign.formulate.inverse_kalman.spectral_terms`)."""
    target = as_poles("poles", poles, setup.plant.n)
    return spectral_terms(setup.plant.A, setup.plant.C, target, setup.plant.dt) is not None
