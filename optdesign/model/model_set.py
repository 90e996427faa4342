r"""Sets of plant models for robust estimator design: operating points, polytopes, sampled
parameter boxes.

A real plant is never one model.  A :class:`ModelSet` holds ``N`` plants with the same number
of states ``n``, outputs ``p`` and noise inputs ``m``, in the same time domain, with a weight per
model, and says what the models stand for:

=================  ==========================================================  ======================
kind               the models are                                              covered by a proof
=================  ==========================================================  ======================
``"list"``         operating points (:class:`ModelSet` itself)                 the models only
``"polytope"``     the vertices of a polytope of plants                        every convex
                   (:meth:`ModelSet.polytope`, :meth:`ModelSet.vary`, or       combination of the
                   :meth:`ModelSet.sample` of an *affine* parameter map)       vertices
``"sampled"``      samples (grid or random) of a parameter -> Plant map over   the samples only
                   a box (:meth:`ModelSet.sample`)
=================  ==========================================================  ======================

"Covered by a proof" is what a convex (LMI) design with a common Lyapunov matrix certifies: the
Chilali-Gahinet region LMIs and the H2 / H-infinity LMIs are affine in the vertex data, so when
they hold at every vertex they hold on the convex hull.  The vertex data are

.. math:: (A_i,\ C_i,\ B_{w,i} = G_i Q_i^{1/2},\ D_{v,i} = R_i^{1/2}),

and the plant at the convex combination ``theta`` (``theta >= 0``, ``sum theta = 1``) is
``A = sum theta_i A_i``, ``C = sum theta_i C_i``, process noise entering through
``G = sum theta_i B_{w,i}`` with ``Q = I`` and ``R = (sum theta_i D_{v,i})^2``
(:meth:`ModelSet.combination`).  For a sampled set nothing between the samples is proven:
:meth:`ModelSet.interior_points` then draws fresh parameter values to check a design densely.

References
----------
M. Chilali and P. Gahinet, "H-infinity design with pole placement constraints: an LMI
approach", IEEE TAC 41(3), 1996 (affine dependence on the vertex data).
P. Vogt, E. Lenz and U. Konigorski, "gammasyn -- eine Toolbox zur robusten Polbereichsvorgabe
mittels beschraenkter Optimierung und Straffunktionen", at - Automatisierungstechnik 68(10),
2020 (multiple models: the corners of a parameter box and the nominal model).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._validate import as_int, as_positive_float
from ..errors import DimensionError, ValidationError
from .coerce import as_plant
from .plant import Plant

__all__ = ["ModelSet", "as_model_set", "psd_sqrt", "MODEL_SET_KINDS"]

#: what a model set stands for (see the module docstring)
MODEL_SET_KINDS = ("list", "polytope", "sampled")


def psd_sqrt(X: ArrayLike) -> NDArray[np.float64]:
    """The symmetric PSD square root of a symmetric PSD matrix (negative rounding clipped).

    Parameters
    ----------
    X : (k, k) array_like
        Symmetric positive semidefinite.

    Returns
    -------
    (k, k) ndarray
        ``S = S'`` with ``S @ S = X`` (to rounding).
    """
    M = np.asarray(X, dtype=float)
    w, U = np.linalg.eigh(0.5 * (M + M.T))
    return (U * np.sqrt(np.clip(w, 0.0, None))) @ U.T


def _check_plants(plants: Any) -> tuple[Plant, ...]:
    if isinstance(plants, Plant):
        plants = (plants,)
    try:
        items = tuple(plants)
    except TypeError:
        raise ValidationError(
            f"models must be a sequence of optdesign.Plant; found {type(plants).__name__}"
        ) from None
    if not items:
        raise ValidationError("models must contain at least one Plant; found none")
    converted = []
    for k, pl in enumerate(items):
        if isinstance(pl, Plant):
            converted.append(pl)
            continue
        try:  # python-control / scipy state-space systems: the one conversion point
            converted.append(as_plant(pl))
        except ValidationError as exc:
            raise ValidationError(
                f"models[{k}] must be an optdesign.Plant or a state-space system; found "
                f"{type(pl).__name__} ({exc})"
            ) from None
    items = tuple(converted)
    first = items[0]
    for k, pl in enumerate(items[1:], start=1):
        for what, a, b in (
            ("n (states)", pl.n, first.n),
            ("p (outputs)", pl.p, first.p),
            ("m (noise inputs, columns of G)", pl.m, first.m),
        ):
            if a != b:
                raise DimensionError(
                    f"every model must have the same {what}: models[0] has {b}, models[{k}] has {a}"
                )
        if pl.dt != first.dt:
            raise ValidationError(
                f"every model must be in the same time domain: models[0] has dt={first.dt!r}, "
                f"models[{k}] has dt={pl.dt!r}"
            )
        if pl.has_noise_model != first.has_noise_model:
            raise ValidationError(
                f"either every model has a noise model (Q and R) or none: models[0] "
                f"{'has' if first.has_noise_model else 'has not'}, models[{k}] "
                f"{'has' if pl.has_noise_model else 'has not'}"
            )
    return items


def _check_weights(weights: Any, N: int) -> NDArray[np.float64]:
    if weights is None:
        return np.full(N, 1.0 / N)
    w = np.asarray(weights, dtype=float) if not isinstance(weights, str) else None
    if w is None or w.ndim != 1:
        raise ValidationError(f"weights must be a 1-D sequence of {N} positive numbers; found {weights!r}")
    if w.shape[0] != N:
        raise DimensionError(
            f"weights has the wrong length: expected {N} (one per model), found {w.shape[0]}"
        )
    bad = np.flatnonzero(~(np.isfinite(w) & (w > 0)))
    if bad.size:
        raise ValidationError(
            f"weights must be finite and > 0; found {float(w[bad[0]])!r} at index {int(bad[0])}"
        )
    return w / float(np.sum(w))


def _check_ranges(ranges: Any) -> tuple[tuple[str, ...], NDArray[np.float64]]:
    """``(names, (k, 2) array of [lo, hi])`` from a mapping name -> (lo, hi) or a sequence of pairs."""
    if isinstance(ranges, Mapping):
        names = tuple(str(k) for k in ranges)
        pairs = list(ranges.values())
    else:
        try:
            pairs = list(ranges)
        except TypeError:
            raise ValidationError(
                f"ranges must be a mapping name -> (lo, hi) or a sequence of (lo, hi) pairs; found {ranges!r}"
            ) from None
        names = tuple(f"theta{k}" for k in range(len(pairs)))
    if not pairs:
        raise ValidationError("ranges must give at least one parameter; found none")
    box = np.empty((len(pairs), 2))
    for k, pr in enumerate(pairs):
        try:
            lo, hi = (float(pr[0]), float(pr[1]))
            if len(pr) != 2:
                raise TypeError
        except (TypeError, ValueError, IndexError):
            raise ValidationError(f"ranges[{names[k]!r}] must be a pair (lo, hi); found {pr!r}") from None
        if not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi):
            raise ValidationError(
                f"ranges[{names[k]!r}] must satisfy finite lo <= hi; found ({lo!r}, {hi!r})"
            )
        box[k] = (lo, hi)
    return names, box


#: the most models a model set is built with (:meth:`ModelSet.vary` makes 2**k corners: 20 entries
#: built 1,048,577 plants in 31 s, and every design then evaluates each of them)
MAX_MODELS = 4096


def check_model_count(count: int, what: str) -> None:
    """Refuse, before building anything, a model set of more than :data:`MAX_MODELS` models.

    Raises
    ------
    ValidationError
        ``count > MAX_MODELS`` (the message names what asked for them and how many).
    """
    if count > MAX_MODELS:
        raise ValidationError(f"{what} asks for {count} models; at most {MAX_MODELS} are built (every design "
                              f"evaluates each model): vary fewer entries or sample the box instead")


@dataclass(frozen=True, eq=False, repr=False)
class ModelSet:
    """A set of plant models with one estimator gain to design for all of them.

    Parameters
    ----------
    plants : sequence of Plant (or python-control / scipy state-space systems, via ``as_plant``)
        ``N >= 1`` models with the same ``n``, ``p``, ``m`` and ``dt``; either all or none with a
        noise model (``Q`` and ``R``).
    weights : (N,) array_like, optional
        Positive weights of the models (normalized to sum 1); default equal.
    kind : {"list", "polytope", "sampled"}
        What the models stand for (module docstring).  Use the constructors
        :meth:`polytope`, :meth:`vary` and :meth:`sample` rather than setting it.
    nominal : int, optional
        Index of the nominal model (the one a user who ignores uncertainty designs for).
    name : str, optional
    parameters : (N, k) array_like, optional
        Sampled sets: the parameter values of the models.
    parameter_names : tuple of str
    ranges : (k, 2) array_like, optional
        Sampled sets: the parameter box ``[lo, hi]`` per parameter.
    function : callable, optional
        Sampled sets: ``function(theta) -> Plant`` with ``theta`` a (k,) array.

    Raises
    ------
    ValidationError
        Not a sequence of Plants, no model, mixed time domains or noise models, bad weights,
        unknown kind, ``nominal`` out of range.
    DimensionError
        Models with different ``n``, ``p`` or ``m``; ``weights`` of the wrong length.

    Examples
    --------
    >>> from optdesign import Plant
    >>> from optdesign.model.model_set import ModelSet
    >>> ms = ModelSet.vary(Plant([[0, 1], [-2, -1]], [[1, 0]]), [(1, 0)], 0.2)
    >>> len(ms), ms.kind
    (3, 'polytope')
    """

    plants: Sequence[Plant]
    weights: ArrayLike | None = None
    kind: str = "list"
    nominal: int | None = None
    name: str | None = None
    parameters: NDArray[np.float64] | None = None
    parameter_names: tuple[str, ...] = ()
    ranges: NDArray[np.float64] | None = None
    function: Callable[[NDArray[np.float64]], Plant] | None = None

    def __post_init__(self) -> None:
        plants = _check_plants(self.plants)
        object.__setattr__(self, "plants", plants)
        w = _check_weights(self.weights, len(plants))
        w.setflags(write=False)
        object.__setattr__(self, "weights", w)
        if self.kind not in MODEL_SET_KINDS:
            raise ValidationError(f"kind must be one of {MODEL_SET_KINDS}; found {self.kind!r}")
        if self.nominal is not None:
            k = as_int("nominal", self.nominal, 0)
            if k >= len(plants):
                raise ValidationError(f"nominal must be a model index in [0, {len(plants) - 1}]; found {k}")
            object.__setattr__(self, "nominal", k)
        if self.name is not None and not isinstance(self.name, str):
            raise ValidationError(f"name must be a string; found {type(self.name).__name__}")
        if self.kind == "sampled" and (self.function is None or self.ranges is None):
            raise ValidationError("a sampled model set needs its function and ranges (use ModelSet.sample)")

    # ------------------------------------------------------------------ constructors
    @classmethod
    def polytope(
        cls,
        vertices: Sequence[Plant],
        weights: ArrayLike | None = None,
        *,
        nominal: int | None = None,
        name: str | None = None,
    ) -> ModelSet:
        """The polytope of plants spanned by ``vertices`` (every convex combination is a model).

        Parameters
        ----------
        vertices : sequence of Plant
            The vertex plants (same n, p, m, dt).
        weights : (N,) array_like, optional
        nominal : int, optional
            Index of a nominal vertex, if one of them is.
        name : str, optional

        Raises
        ------
        ValidationError, DimensionError
            As for :class:`ModelSet`.
        """
        return cls(tuple(vertices), weights, "polytope", nominal, name)

    @classmethod
    def vary(
        cls,
        plant: Plant,
        entries: Sequence[tuple[int, int]],
        size: float,
        *,
        matrix: str = "A",
        include_nominal: bool = True,
        name: str | None = None,
    ) -> ModelSet:
        """Entries of one matrix of ``plant`` varied independently by ``+-size`` (relative).

        Each listed entry ``X[i, j]`` ranges over ``X[i, j] (1 + delta)``, ``|delta| <= size``; the
        plant is affine in the deltas, so the ``2**k`` corners of the box are the vertices of a
        polytope that contains every plant of the box (kind ``"polytope"``).

        Parameters
        ----------
        plant : Plant
            The nominal plant.
        entries : sequence of (int, int)
            Indices of the varied entries (``1 <= k``; 2**k vertices).
        size : float
            Relative variation, ``>= 0`` (0.2 for +-20 %).
        matrix : {"A", "C"}
        include_nominal : bool
            Add the nominal plant as the last model (``nominal`` index).
        name : str, optional

        Returns
        -------
        ModelSet
            Kind ``"polytope"`` (the nominal model, if added, is inside the polytope, so it
            changes nothing in what is covered); ``parameters`` are the deltas of each model.

        Raises
        ------
        ValidationError
            Not a Plant, ``matrix`` not "A" or "C", no entry, an entry out of range or repeated,
            ``size`` negative or not finite.
        """
        if not isinstance(plant, Plant):
            raise ValidationError(f"plant must be an optdesign.Plant; found {type(plant).__name__}")
        if matrix not in ("A", "C"):
            raise ValidationError(f"matrix must be 'A' or 'C'; found {matrix!r}")
        size = as_positive_float("size", size, allow_zero=True)
        X0 = np.array(getattr(plant, matrix), dtype=float)
        try:
            idx = [(int(i), int(j)) for i, j in entries]
        except (TypeError, ValueError):
            raise ValidationError(
                f"entries must be a sequence of (row, column) pairs; found {entries!r}"
            ) from None
        if not idx:
            raise ValidationError("entries must list at least one (row, column) pair; found none")
        if len(set(idx)) != len(idx):
            raise ValidationError(f"entries must not repeat an index; found {idx}")
        for i, j in idx:
            if not (0 <= i < X0.shape[0] and 0 <= j < X0.shape[1]):
                raise ValidationError(f"entry ({i}, {j}) is outside {matrix}, which has shape {X0.shape}")
        check_model_count(2 ** len(idx) + bool(include_nominal),
                          f"vary with {len(idx)} entries (2**{len(idx)} corners)")
        corners = np.array(list(itertools.product((-size, size), repeat=len(idx))), dtype=float)
        deltas = np.vstack([corners, np.zeros((1, len(idx)))]) if include_nominal else corners

        def make(delta: NDArray) -> Plant:
            X = X0.copy()
            for (i, j), d in zip(idx, delta, strict=True):
                X[i, j] = X0[i, j] * (1.0 + d)
            return plant.replace(**{matrix: X})

        plants = tuple(make(d) for d in deltas)
        names = tuple(f"{matrix}[{i},{j}]" for i, j in idx)
        label = (
            name if name is not None else f"{plant.name or 'plant'} +-{100 * size:g}% on {', '.join(names)}"
        )
        return cls(
            plants,
            None,
            "polytope",
            len(plants) - 1 if include_nominal else None,
            label,
            deltas,
            names,
            np.column_stack([np.full(len(idx), -size), np.full(len(idx), size)]),
            make,
        )

    @classmethod
    def sample(
        cls,
        function: Callable[[NDArray[np.float64]], Plant],
        ranges: Mapping[str, tuple[float, float]] | Sequence[tuple[float, float]],
        *,
        grid: int | None = 2,
        samples: int = 0,
        seed: int = 0,
        include_nominal: bool = True,
        affine: bool = False,
        name: str | None = None,
    ) -> ModelSet:
        """Models of an uncertain plant ``function(theta)``, ``theta`` in a box, on a grid and/or at random.

        Parameters
        ----------
        function : callable
            ``function(theta) -> Plant`` for a (k,) parameter array.
        ranges : mapping name -> (lo, hi), or sequence of (lo, hi)
            The parameter box.
        grid : int or None, default 2
            Points per parameter of a full grid (2: the corners of the box, gammasyn's choice);
            None for no grid.
        samples : int, default 0
            Further uniformly random parameter points.
        seed : int, default 0
            Seed of the random points.
        include_nominal : bool, default True
            Add the center of the box as the last model (the ``nominal`` index).
        affine : bool, default False
            Claim that ``function`` is affine in ``theta`` (checked at random points: the plant
            must equal the multilinear interpolation of the corners); then the corners are the
            vertices of a polytope that contains the whole box and the set is of kind
            ``"polytope"``.  Needs ``grid=2``.
        name : str, optional

        Returns
        -------
        ModelSet
            Kind ``"sampled"`` (or ``"polytope"`` with ``affine=True``), with ``parameters``,
            ``ranges`` and ``function`` kept for dense checks (:meth:`interior_points`).

        Raises
        ------
        ValidationError
            ``function`` not callable or not returning a Plant, bad ranges, ``grid < 2`` or
            ``samples < 0``, no model at all, ``affine=True`` without ``grid=2`` or for a
            function that is not affine (the message gives the mismatch).
        """
        if not callable(function):
            raise ValidationError(
                f"function must be callable (theta -> Plant); found {type(function).__name__}"
            )
        names, box = _check_ranges(ranges)
        samples = as_int("samples", samples, 0)
        check_model_count(samples, "samples")
        seed = as_int("seed", seed, 0)
        pts: list[NDArray] = []
        if grid is not None:
            grid = as_int("grid", grid, 2)
            check_model_count(grid ** len(names) + samples + bool(include_nominal),
                              f"sample with grid={grid} over {len(names)} parameters "
                              f"({grid}**{len(names)} points)")
            axes = [np.linspace(lo, hi, grid) for lo, hi in box]
            pts.extend(np.array(t, dtype=float) for t in itertools.product(*axes))
        rng = np.random.default_rng(seed)
        pts.extend(rng.uniform(box[:, 0], box[:, 1]) for _ in range(samples))
        if include_nominal:
            pts.append(box.mean(axis=1))
        if not pts:
            raise ValidationError("sample needs grid, samples or include_nominal to give at least one model")
        theta = np.array(pts, dtype=float)
        plants = tuple(_call(function, t) for t in theta)
        kind = "sampled"
        if affine:
            if grid != 2:
                raise ValidationError(
                    f"affine=True needs grid=2 (the corners are the vertices); found grid={grid!r}"
                )
            _check_affine(function, box, theta[: 2 ** len(names)], plants[: 2 ** len(names)], rng)
            kind = "polytope"
        return cls(
            plants,
            None,
            kind,
            len(plants) - 1 if include_nominal else None,
            name,
            theta,
            names,
            box,
            function,
        )

    # ------------------------------------------------------------------ shape
    @property
    def n(self) -> int:
        """Number of states."""
        return self.plants[0].n

    @property
    def p(self) -> int:
        """Number of outputs."""
        return self.plants[0].p

    @property
    def m(self) -> int:
        """Number of process-noise inputs."""
        return self.plants[0].m

    @property
    def dt(self) -> float | None:
        """Sampling period (None: continuous time)."""
        return self.plants[0].dt

    @property
    def is_discrete(self) -> bool:
        return self.plants[0].is_discrete

    @property
    def has_noise_model(self) -> bool:
        """Every model has Q and R (H2 / H-infinity of the estimation error are defined)."""
        return self.plants[0].has_noise_model

    @property
    def covers_convex_hull(self) -> bool:
        """A certificate at the models holds for every convex combination (kind ``"polytope"``)."""
        return self.kind == "polytope"

    def __len__(self) -> int:
        return len(self.plants)

    def __iter__(self) -> Iterator[Plant]:
        return iter(self.plants)

    def __getitem__(self, k: int) -> Plant:
        return self.plants[k]

    def label(self, k: int) -> str:
        """A short name of model ``k`` (its plant name, or ``model k``)."""
        tag = " (nominal)" if k == self.nominal else ""
        if self.parameters is not None and self.parameter_names:
            vals = ", ".join(
                f"{nm}={v:.4g}" for nm, v in zip(self.parameter_names, self.parameters[k], strict=True)
            )
            return f"model {k} [{vals}]{tag}"
        return f"model {k}{tag}"

    # ------------------------------------------------------------------ vertex data
    def vertex_data(self) -> dict[str, NDArray[np.float64]]:
        """The stacked data the LMIs are affine in.

        Returns
        -------
        dict
            ``"A"`` (N, n, n), ``"C"`` (N, p, n); with a noise model also ``"Bw"`` (N, n, m)
            ``= G Q^(1/2)`` and ``"Dv"`` (N, p, p) ``= R^(1/2)``.
        """
        out = {"A": np.stack([pl.A for pl in self.plants]), "C": np.stack([pl.C for pl in self.plants])}
        if self.has_noise_model:
            out["Bw"] = np.stack([_given(pl.G) @ psd_sqrt(_given(pl.Q)) for pl in self.plants])
            out["Dv"] = np.stack([psd_sqrt(_given(pl.R)) for pl in self.plants])
        return out

    def combination(self, theta: ArrayLike) -> Plant:
        """The plant at the convex combination ``theta`` of the models' vertex data.

        Parameters
        ----------
        theta : (N,) array_like
            ``theta >= 0``, ``sum theta = 1``.

        Returns
        -------
        Plant
            ``A = sum theta_i A_i``, ``C = sum theta_i C_i``; with a noise model ``G = sum theta_i
            G_i Q_i^(1/2)``, ``Q = I`` and ``R = (sum theta_i R_i^(1/2))^2``.

        Raises
        ------
        ValidationError
            ``theta`` of the wrong length, negative, or not summing to 1.
        """
        th = np.asarray(theta, dtype=float).ravel()
        if th.shape[0] != len(self) or np.any(th < -1e-12) or abs(float(np.sum(th)) - 1.0) > 1e-9:
            raise ValidationError(
                f"theta must be {len(self)} nonnegative numbers summing to 1; found {np.asarray(theta)!r}"
            )
        d = self.vertex_data()
        A = np.einsum("k,kij->ij", th, d["A"])
        C = np.einsum("k,kij->ij", th, d["C"])
        if not self.has_noise_model:
            return Plant(A, C, dt=self.dt, name="convex combination")
        Bw = np.einsum("k,kij->ij", th, d["Bw"])
        Dv = np.einsum("k,kij->ij", th, d["Dv"])
        return Plant(A, C, G=Bw, Q=np.eye(Bw.shape[1]), R=Dv @ Dv.T, dt=self.dt, name="convex combination")

    def interior_points(self, count: int, rng: np.random.Generator | int | None = 0) -> list[Plant]:
        """Random plants of the set that are not among its models, for a dense check of a design.

        Sets with a parameter box (:meth:`vary`, :meth:`sample`): ``function`` at uniformly random
        points of the box; other polytopes: convex combinations of the vertices with weights
        uniform on the simplex (Dirichlet(1), :meth:`combination`); lists of operating points:
        none (there is nothing between them).

        Parameters
        ----------
        count : int
            How many, ``>= 0``.
        rng : numpy Generator or int seed, default 0

        Returns
        -------
        list of Plant

        Raises
        ------
        ValidationError
            ``count`` not an integer ``>= 0``.
        """
        count = as_int("count", count, 0)
        gen = np.random.default_rng(rng)
        if self.function is not None and self.ranges is not None:
            box = self.ranges
            return [_call(self.function, gen.uniform(box[:, 0], box[:, 1])) for _ in range(count)]
        if self.kind == "polytope":
            return [self.combination(gen.dirichlet(np.ones(len(self)))) for _ in range(count)]
        return []

    def __repr__(self) -> str:
        label = f"{self.name!r}, " if self.name else ""
        time = f"dt={self.dt:g}" if self.is_discrete else "continuous"
        return f"ModelSet({label}{len(self)} models, kind={self.kind}, n={self.n}, p={self.p}, {time})"


def _given(X: NDArray[np.float64] | None) -> NDArray[np.float64]:
    """``X`` (G, or Q / R of a noise model checked before) known to be given; raises if it is not."""
    if X is None:
        raise ValidationError("a model has no noise model (Q and R)")
    return X


def _call(function: Callable, theta: NDArray) -> Plant:
    pl = function(np.array(theta, dtype=float))
    if not isinstance(pl, Plant):
        raise ValidationError(f"function(theta) must return an optdesign.Plant; found {type(pl).__name__}")
    return pl


def _plant_vector(pl: Plant) -> NDArray[np.float64]:
    parts = [pl.A.ravel(), pl.C.ravel(), _given(pl.G).ravel()]
    if pl.has_noise_model:
        parts += [_given(pl.Q).ravel(), _given(pl.R).ravel()]
    return np.concatenate(parts)


def _check_affine(
    function: Callable, box: NDArray, corners: NDArray, plants: Sequence[Plant], rng: np.random.Generator
) -> None:
    """Raise unless ``function`` equals the multilinear interpolation of its corners at random points."""
    k = box.shape[0]
    vals = np.stack([_plant_vector(p) for p in plants])
    scale = max(1.0, float(np.max(np.abs(vals))))
    span = np.where(box[:, 1] > box[:, 0], box[:, 1] - box[:, 0], 1.0)
    for _ in range(4):
        t = rng.uniform(box[:, 0], box[:, 1])
        u = (t - box[:, 0]) / span
        wts = np.array(
            [
                np.prod(
                    [u[j] if c[j] > box[j, 0] or box[j, 1] == box[j, 0] else 1.0 - u[j] for j in range(k)]
                )
                for c in corners
            ]
        )
        expect = wts @ vals
        got = _plant_vector(_call(function, t))
        err = float(np.max(np.abs(got - expect))) / scale
        if err > 1e-9:
            raise ValidationError(
                f"affine=True but function is not affine in theta: at theta={t.tolist()} the plant differs "
                f"from the interpolation of the box corners by {err:.3g} (relative); drop affine=True (the "
                "set is then "
                "covered at its samples only)"
            )


def as_model_set(models: Any, weights: ArrayLike | None = None) -> ModelSet:
    """A :class:`ModelSet` from a ModelSet (``weights`` replace its own) or a sequence of Plants.

    Raises
    ------
    ValidationError, DimensionError
        As for :class:`ModelSet`.
    """
    if isinstance(models, ModelSet):
        if weights is None:
            return models
        return ModelSet(
            models.plants,
            weights,
            models.kind,
            models.nominal,
            models.name,
            models.parameters,
            models.parameter_names,
            models.ranges,
            models.function,
        )
    return ModelSet(models, weights)
