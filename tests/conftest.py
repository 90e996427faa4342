"""Shared fixtures.  Tests use fixed seeds; nothing here skips a hard case."""

from __future__ import annotations

import os

# Small dense matrices: multithreaded BLAS only adds overhead (and contention on 2 cores).
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402
import pytest  # noqa: E402

#: Set OPTDESIGN_FULL=1 to run the slow studies in full (CI runs them reduced).
FULL = os.environ.get("OPTDESIGN_FULL", "") not in ("", "0")


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20261124)


@pytest.fixture
def general_one_output_route(monkeypatch):
    """The one-output engine without its first route, the n-constraint form
    (:mod:`optdesign.engines.one_output_sdp`): for the tests of what runs when that form certifies
    nothing (the dense IPM, Clarabel on the direct form, the first try, the repair)."""
    from optdesign.engines import inverse_kalman_engine as engine

    monkeypatch.setattr(engine, "_one_output_form", lambda *a, **k: None)


def random_observable_plant(rng: np.random.Generator, n: int, p: int, *, stable: bool | None = None,
                            dt: float | None = None, noise: bool = True):
    """A random observable plant (continuous unless dt), optionally forced stable/unstable."""
    from optdesign import Plant

    while True:
        A = rng.standard_normal((n, n))
        if stable is True:
            A -= (np.max(np.linalg.eigvals(A).real) + 0.5) * np.eye(n)
        elif stable is False:
            A += (0.5 - np.max(np.linalg.eigvals(A).real)) * np.eye(n)
        if dt is not None:
            A = A / (1.1 * max(1.0, np.max(np.abs(np.linalg.eigvals(A)))))
            if stable is False:
                A *= 1.5
        C = rng.standard_normal((p, n))
        kw = {}
        if noise:
            F = rng.standard_normal((n, n))
            kw = dict(Q=F @ F.T + 0.1 * np.eye(n), R=np.diag(rng.uniform(0.5, 2.0, p)))
        plant = Plant(A, C, dt=dt, **kw)
        if plant.is_observable():
            return plant
