"""Shared pieces of the benchmark scripts (not part of the library).

Importing this module first sets single-threaded BLAS (stable timings on a shared machine: OpenBLAS
threads oversubscribe 2 cores) -- before numpy is imported by the script.
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from optdesign import Plant  # noqa: E402


def random_observable_plant(rng: np.random.Generator, n: int, p: int, *, noise: bool = False) -> Plant:
    """A random observable plant ``A ~ N(0, 1/n)`` (spectral radius ~1), ``C ~ N(0, 1)`` (p x n);
    ``R = I`` when ``noise`` (for Kalman problems; Q is the caller's)."""
    while True:
        A = rng.standard_normal((n, n)) / np.sqrt(n)
        C = rng.standard_normal((p, n))
        plant = Plant(A, C, R=np.eye(p) if noise else None)
        if plant.is_observable():
            return plant
