"""How the ``optdesign`` command says things: checks in plain words with their numbers, repeated
poles rounded and counted, a plant shown with its matrices and the meaning of its sizes.

Library results keep their exact fields; these helpers only phrase them for a terminal.
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from typing import Any

import numpy as np

from ..classical.riccati import format_pole, sort_poles

__all__ = ["plain_check", "format_poles", "plant_lines", "POLE_AGREEMENT"]

#: relative distance below which two printed poles count as one repeated pole: the cap of the
#: verification's pole tolerance (``optdesign.design.verification.POLE_FLOOR_CAP``) -- a k-fold
#: defective pole is computed only to about ``eps**(1/k)``, so ``-1 (x2)`` prints as one.
POLE_AGREEMENT = 1e-6


def format_poles(poles: Iterable[complex] | None, rtol: float = POLE_AGREEMENT) -> str:
    """Poles sorted (real part, then imaginary part), comma-separated, repeated poles once with
    their count: ``-1 (x2), -3``; ``"none"`` for None.

    Poles within ``rtol * max(1, |z|)`` of each other are one repeated pole, printed at their mean;
    an imaginary part below that scale is dropped (a split double real pole ``-1 +- 2.6e-8j`` is
    ``-1 (x2)``).
    """
    if poles is None:
        return "none"
    z = sort_poles(np.asarray(poles, dtype=complex).ravel())
    groups: list[list[complex]] = []
    for p in z:
        for g in groups:
            c = complex(np.mean(g))
            if abs(p - c) <= rtol * max(1.0, abs(c)):
                g.append(p)
                break
        else:
            groups.append([p])
    out = []
    for g in groups:
        c = complex(np.mean(g))
        if abs(c.imag) <= rtol * max(1.0, abs(c)):
            c = complex(c.real, 0.0)
        if abs(c.real) <= rtol * max(1.0, abs(c)) and c.imag != 0:
            c = complex(0.0, c.imag)
        out.append(format_pole(c) + (f" (x{len(g)})" if len(g) > 1 else ""))
    return ", ".join(out)


def _g(x: float, digits: int = 3) -> str:
    return f"{x:.{digits}g}"


def _plain(name: str, v: float, t: float, detail: str) -> str | None:
    """The sentence of a known check, or None."""
    if name in ("riccati_residual", "augmented_riccati_residual"):
        return f"the Riccati equation holds to a relative residual of {_g(v, 2)} (allowed {_g(t, 2)})"
    if name == "forward_error":
        return (f"P is accurate to about {_g(v, 2)} (relative), estimated from its residual and its "
                f"sensitivity to rounding (allowed {_g(t, 2)})")
    if name in ("P_min_eig", "Q_min_eig", "p0_min_eig"):
        what = name.split("_")[0]
        return (f"{what} is positive semidefinite: its smallest eigenvalue is {_g(v)} x ||{what}|| "
                f"(must be at least {_g(t, 2)}, the rounding level)") if v >= t else (
                f"{what} is NOT positive semidefinite: its smallest eigenvalue is {_g(v)} x ||{what}|| "
                f"(must be at least {_g(t, 2)})")
    if name == "stability_margin":
        discrete = "max |" in detail or "spectral" in detail or "1 - " in detail
        if discrete:
            return (f"stable: every pole of A - L C has modulus at most {_g(1 - v, 4)} (margin {_g(v)} "
                    f"to the unit circle; must exceed the rounding level {_g(t, 2)})")
        return (f"stable: every pole of A - L C has real part at most {_g(-v, 4)} (margin {_g(v)}; must "
                f"exceed the rounding level {_g(t, 2)})")
    if name == "cross_check":
        m = re.search(r"P_(\w+)", detail)
        other = f"the {m.group(1)} solver's" if m else "a second solver's"
        return (f"P agrees with {other} to {_g(v, 2)} (relative; allowed {_g(t, 2)}, 4 x the two solutions' "
                f"error estimates)") if np.isfinite(v) else f"no second solution to compare with ({detail})"
    if name == "pole_error":
        return f"the poles match the targets to {_g(v, 2)} (relative; allowed {_g(t, 2)})"
    if name == "are_resolve_gain":
        return (f"an independent Riccati solve with the returned Q gives the same gain, to {_g(v, 2)} "
                f"(allowed {_g(t, 2)})")
    if name == "are_resolve_poles":
        return (f"an independent Riccati solve with the returned Q gives the target poles, to {_g(v, 2)} "
                f"(allowed {_g(t, 2)})")
    if name in ("region_margin", "feedback_region_margin"):
        return (f"every pole is in the region, the closest {_g(-v)} from its edge" if v <= 0 else
                f"a pole is {_g(v)} outside the region (allowed {_g(t, 2)})")
    return None


def plain_check(check: Any) -> str:
    """One check in plain words with its numbers, after its mark and name.

    For example ``[ok  ] forward_error: P is accurate to about 2e-15 (relative) ... (allowed 1e-06)``;
    a check without a phrase of its own reads ``<detail>: <value>, must be at most <bound>``.
    """
    mark = "ok  " if check.passed else "FAIL"
    v, t = float(check.value), float(check.tolerance)
    text = _plain(check.name, v, t, check.detail or "")
    if text is None:
        bound = "at most" if check.sense == "<=" else "at least"
        text = f"{check.detail or check.name}: {_g(v, 4)}, must be {bound} {_g(t, 4)}"
    return f"[{mark}] {check.name}: {text}"


def plant_lines(plant: Any, indent: str = "  ") -> list[str]:
    """The plant a command works on: sizes in words and the matrices A, (B,) C, G, Q, R."""
    time = f"discrete, dt = {plant.dt:g}" if plant.is_discrete else "continuous"
    def count(k: int, what: str) -> str:
        return f"{k} {what}" if k == 1 else f"{k} {what}s"

    lines = [f"plant ({time}): n = {count(plant.n, 'state')}, p = {count(plant.p, 'measured output')}, "
             f"m = {count(plant.m, 'noise input')} w (entering through G; E[w w'] = Q, E[v v'] = R)"]
    for k in ("A", "B", "C", "G", "Q", "R"):
        X = getattr(plant, k, None)
        if X is None:
            continue
        with np.printoptions(precision=6, suppress=True, linewidth=100):
            body = np.array2string(np.asarray(X), prefix=f"{indent}{k} = ")
        lines.append(f"{indent}{k} = {body}")
    return lines
