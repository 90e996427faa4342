#!/usr/bin/env python
"""Developer tool: copy the benchmark collections into the problem library.

Reads the benchmark JSON files (CAREX, DAREX, COMPleib, pole placement, Kalman-filter
references) and writes one problem file per entry into ``problems/<group>/<name>.json`` in the
schema of :mod:`optdesign.problems`; then rewrites the table in ``problems/README.md`` from every
problem file in the library (seed problems included).

This script is run by developers only, when the benchmark data change.  The library never reads
the benchmark folder: what it needs is copied into ``problems/`` (with each entry's ``source``).

Usage::

    python tools/import_benchmarks.py [--src DIR] [--dst DIR] [--check]

``--check`` writes nothing and exits with status 1 if a generated file (or the README table)
differs from the one on disk.

Mappings (see each problem's ``notes``)
---------------------------------------
CAREX (``riccati_care``)
    Control form ``0 = Q + A'X + XA - X B R^-1 B' X``, ``Q = C'WC``.  The plant is the FILTER
    form by duality: ``A_f = A'``, ``C_f = B'`` (m x n), ``G_f = C'`` (n x p), ``Q_f = W``,
    ``R_f = R``; the filter ARE ``A_f P + P A_f' - P C_f' R^-1 C_f P + G_f W G_f' = 0`` is the
    control ARE, so ``P = X`` and the filter gain is ``L = X B R^-1``.  ``plant`` is null when W
    is not PSD or R not PD.
DAREX (``riccati_dare``)
    ``0 = A'XA - X - (A'XB + S)(R + B'XB)^-1 (B'XA + S') + Q``, ``Q = C'Q0C``.  With S = 0 the
    dual is the predictor DARE of the Kalman filter of ``(A', B', G = C', Q0, R, dt = 1)``.  With
    S != 0 and R PD the cross term is removed first (``A_s = A - B R^-1 S'``,
    ``Q_s = Q - S R^-1 S'``: same X, same closed-loop spectrum) and the plant is
    ``(A_s', B', G = I, Q_s, R)`` when ``Q_s`` is PSD.  ``plant`` is null when R is singular.
COMPleib (``plant``)
    ``x' = A x + B1 w + B u``, ``y = C x + D21 w``: plant ``(A, C, G = B1, Q = I, R = D21 D21')``
    when ``D21 D21'`` is PD, else ``R = I``; the cross-covariance ``B1 D21'`` is dropped.
Pole placement (``pole_placement``)
    State feedback ``eig(A - B K) = poles``; the plant is the observer dual ``(A', B')`` so that
    ``L = K'`` gives ``eig(A' - L B') = poles``.  Besides the collection: the Byers-Nash set of 11
    systems (from harold's tests) and Chu's 2007 set of 9 examples (from ControlToolbox.jl), whose
    numbers are held in this script (:data:`BYERS_NASH_SET`, :data:`CHU_SET`) with their sources.
Kalman references (``kalman``, ``kalman_step``)
    Plant ``(A, C, G, Q, R, dt)`` as given; references as published.
"""

from __future__ import annotations

import argparse
import ast
import json
import math
import re
import sys
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_SRC = ROOT.parent / "shared" / "benchmarks"
DEFAULT_DST = ROOT / "problems"

NAME_RE = re.compile(r"^[a-z0-9][a-z0-9_.\-]*$")

CAREX_CITATION = "CAREX v2.0, Abels & Benner, SLICOT Working Note 1999-14, example {ex}"
DAREX_CITATION = "DAREX v2.0, Abels & Benner, SLICOT Working Note 1999-16, example {ex}"
COMPLEIB_CITATION = (
    "COMPleib v1.1, F. Leibfritz, COMPleib: COnstrained Matrix-optimization Problem library "
    "(Univ. Trier, 2004/2005), model {ex}"
)


# --------------------------------------------------------------------------- helpers
def parse_literals(value: Any) -> Any:
    """Recursively turn strings that hold Python literals (``'[[0.0, 1.0]]'``, ``"{'a': 1}"``)
    into real lists / dicts.  Other strings are left alone."""
    if isinstance(value, dict):
        return {k: parse_literals(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [parse_literals(v) for v in value]
    if isinstance(value, str):
        s = value.strip()
        if s[:1] in "[{(" and s[-1:] in "]})":
            try:
                parsed = ast.literal_eval(s)
            except (ValueError, SyntaxError):
                return value
            return parse_literals(parsed)
    return value


def stem(key: str, prefix: str, new_prefix: str) -> str:
    """``"CAREX_3.1(l=6)"`` -> ``"carex_3.1_l6"``; ``"PolePlacement_KNV1985_Ex1"`` -> ``"pp_knv1985_ex1"``."""
    if not key.startswith(prefix):
        raise ValueError(f"{key!r} does not start with {prefix!r}")
    s = key[len(prefix) :].lower()
    s = re.sub(r"\((\w+)=(\d+)\)", r"_\1\2", s)
    name = f"{new_prefix}_{s}"
    if not NAME_RE.match(name):
        raise ValueError(f"generated name {name!r} is not clean")
    return name


def mat(x: Any) -> np.ndarray:
    return np.atleast_2d(np.asarray(x, dtype=float))


def tolist(X: np.ndarray) -> list:
    return np.asarray(X, dtype=float).tolist()


def _sym_tol(X: np.ndarray) -> float:  # same scale as optdesign._validate.sym_tol
    return 100.0 * np.finfo(float).eps * max(1.0, float(np.linalg.norm(X, 1))) * max(1, X.shape[0])


def min_eig(X: np.ndarray) -> float:
    return float(np.linalg.eigvalsh(0.5 * (X + X.T))[0])


def is_psd(X: np.ndarray) -> bool:
    return min_eig(X) >= -_sym_tol(X)


def is_pd(X: np.ndarray) -> bool:
    return min_eig(X) > _sym_tol(X)


def problem(
    name, title, kind, tags, citation, source, notes, plant, targets=None, references=None, data=None
):
    return {
        "name": name,
        "title": title,
        "kind": kind,
        "tags": list(tags),
        "citation": citation,
        "source": source,
        "notes": notes,
        "plant": plant,
        "targets": targets or {},
        "references": references or {},
        "data": data or {},
    }


def check_plant(prob: dict) -> None:
    """Every non-null plant must construct (the library must load)."""
    if prob["plant"] is None:
        return
    from optdesign.model.plant import Plant

    kw = {k: v for k, v in prob["plant"].items() if v is not None}
    Plant(**kw, name=prob["name"])


# --------------------------------------------------------------------------- CAREX
def import_carex(entries: dict) -> list[dict]:
    out = []
    for key, e in entries.items():
        e = parse_literals(e)
        name = stem(key, "CAREX_", "carex")
        A, B, R, C, W = (mat(e[k]) for k in ("A", "B", "R", "C", "W"))
        data_keys = [
            "A",
            "B",
            "R",
            "C",
            "W",
            "G",
            "Q",
            "n",
            "m",
            "p",
            "params",
            "example",
            "example_v1_number",
            "equation",
            "title",
        ]
        data = {k: e[k] for k in data_keys if k in e}
        notes = [
            "Control form 0 = Q + A'X + XA - X B R^-1 B' X with Q = C'WC (data holds the original A, B, R, "
            "C, W, G = B R^-1 B', Q).  The plant is the FILTER form by duality: A_f = A', C_f = B' (m x n), "
            "G_f = C' (n x p), Q_f = W, R_f = R, so the filter ARE's P equals X and the filter gain is "
            "L = X B R^-1."
        ]
        reasons = []
        if not is_pd(R):
            reasons.append(f"R is not positive definite (smallest eigenvalue {min_eig(R):.6g})")
        if not is_psd(W):
            reasons.append(
                f"W is not positive semidefinite (smallest eigenvalue {min_eig(W):.6g}), so Q = C'WC is not "
                "a noise covariance"
            )
        if reasons:
            plant = None
            notes.append(
                "plant is null: " + "; ".join(reasons) + ".  The CARE itself is still a valid test "
                "(use data)."
            )
        else:
            plant = {
                "A": tolist(A.T),
                "C": tolist(B.T),
                "G": tolist(C.T),
                "Q": tolist(W),
                "R": tolist(R),
                "dt": None,
            }
        references: dict[str, Any] = {}
        tags = ["benchmark", "carex"]
        if "X" in e:
            references["X"] = e["X"]
            tags.append("analytic_reference")
        if "X_ref_numeric" in e:
            references["X_ref_numeric"] = e["X_ref_numeric"]
            tags.append("numeric_reference")
        ref = e.get("reference", {})
        for k, v in ref.items():
            references[k] = v
        if key == "CAREX_4.1(n=5)":
            # carex.m v1 documentation: only X[0, n-1] = X[n-1, 0] = sqrt(q r) is known analytically.
            q, r = float(W[0, 0]), float(R[0, 0])
            references["X_first_last"] = math.sqrt(q * r)
            notes.append(
                "references.X_first_last = X[0, n-1] = X[n-1, 0] = sqrt(q r) with q = W, r = R "
                "(the only entries known analytically)."
            )
        if key == "CAREX_2.5":
            references["X_is_stabilizing"] = False
            tags.append("no_stabilizing_solution")
            notes.append(
                "references.X solves the CARE but is NOT stabilizing: with eps = 0 the Hamiltonian "
                "eigenvalues lie on the imaginary axis; a solver must report failure."
            )
        if e.get("notes"):
            notes.append("Source notes: " + e["notes"])
        if "published" in ref:
            notes.append(
                "references.published holds numbers printed in the 1995 CAREX MATLAB package; "
                "references.computed holds norms/condition numbers computed from the data."
            )
        title = f"CAREX {e['example']}: {e['title']}"
        prob = problem(
            name,
            title,
            "riccati_care",
            tags,
            CAREX_CITATION.format(ex=e["example"]),
            e["source"],
            "  ".join(notes),
            plant,
            {},
            references,
            data,
        )
        out.append(("carex", prob))
    return out


# --------------------------------------------------------------------------- DAREX
def import_darex(entries: dict) -> list[dict]:
    out = []
    for key, e in entries.items():
        e = parse_literals(e)
        name = stem(key, "DAREX_", "darex")
        A, B, R, S, C, Q0, Q = (mat(e[k]) for k in ("A", "B", "R", "S", "C", "Q0", "Q"))
        data_keys = [
            "A",
            "B",
            "R",
            "S",
            "C",
            "Q0",
            "Q",
            "n",
            "m",
            "p",
            "params",
            "example",
            "equation",
            "title",
        ]
        data = {k: e[k] for k in data_keys if k in e}
        notes = [
            "Control form 0 = A'XA - X - (A'XB + S)(R + B'XB)^-1 (B'XA + S') + Q with Q = C'Q0C (data holds "
            "the original matrices).  dt = 1.  With S = 0 the plant is the filter form by duality: A_f = A', "
            "C_f = B' (m x n), G_f = C' (n x p), Q_f = Q0, R_f = R; the predictor DARE of its Kalman filter, "
            "P = A_f P A_f' - A_f P C_f'(C_f P C_f' + R)^-1 C_f P A_f' + G_f Q0 G_f', is the control DARE, "
            "so P = X and eig(A_f - L C_f) (L = A_f P C_f'(C_f P C_f' + R)^-1) is the closed-loop spectrum."
        ]
        tags = ["benchmark", "darex"]
        s_nonzero = bool(np.any(S != 0))
        plant = None
        if not is_pd(R):
            notes.append(
                f"plant is null: R is singular (smallest eigenvalue {min_eig(R):.6g}); a filter needs a "
                "positive definite measurement covariance (the DARE needs an extended-pencil solver)."
            )
        elif s_nonzero:
            Rinv_St = np.linalg.solve(R, S.T)
            A_s = A - B @ Rinv_St
            Q_s = Q - S @ Rinv_St
            Q_s = 0.5 * (Q_s + Q_s.T)
            if is_psd(Q_s):
                plant = {
                    "A": tolist(A_s.T),
                    "C": tolist(B.T),
                    "G": tolist(np.eye(A.shape[0])),
                    "Q": tolist(Q_s),
                    "R": tolist(R),
                    "dt": 1.0,
                }
                notes.append(
                    "S != 0: our Plant has no cross-covariance, so the cross term is removed first: A_s = A "
                    "- B R^-1 S', Q_s = Q - S R^-1 S' give the same X and the same closed-loop spectrum; the "
                    "plant is (A_f = A_s', C_f = B', G_f = I, Q_f = Q_s, R).  Its predictor gain is that of "
                    "the decorrelated problem."
                )
                tags.append("cross_term_removed")
            else:
                notes.append(
                    f"plant is null: S != 0 and Q - S R^-1 S' is indefinite (smallest eigenvalue "
                    f"{min_eig(Q_s):.6g}), so no uncorrelated filter form exists."
                )
        elif not is_psd(Q0):
            notes.append(
                f"plant is null: Q0 is not positive semidefinite (smallest eigenvalue {min_eig(Q0):.6g})."
            )
        else:
            plant = {
                "A": tolist(A.T),
                "C": tolist(B.T),
                "G": tolist(C.T),
                "Q": tolist(Q0),
                "R": tolist(R),
                "dt": 1.0,
            }
        references: dict[str, Any] = {}
        if "X_corrected" in e:
            references["X"] = e["X_corrected"]
            data["X_published"] = e["X"]
            notes.append(
                "The published X (data.X_published, returned by BB02AD as exact) does NOT satisfy the "
                "DARE (the (3,3) residual is -9.9); references.X is the corrected stabilizing solution "
                "X_corrected (X33 = 0.1 - 10 = -9.9)."
            )
            tags.append("published_value_wrong")
        elif "X" in e:
            references["X"] = e["X"]
        if "X" in references:
            tags.append("analytic_reference")
        if e.get("notes"):
            notes.append("Source notes: " + e["notes"])
        title = f"DAREX {e['example']}: {e['title'].strip()}"
        prob = problem(
            name,
            title,
            "riccati_dare",
            tags,
            DAREX_CITATION.format(ex=e["example"]),
            e["source"],
            "  ".join(notes),
            plant,
            {},
            references,
            data,
        )
        out.append(("darex", prob))
    return out


# --------------------------------------------------------------------------- COMPleib
def import_compleib(entries: dict) -> list[dict]:
    out = []
    for key, e in entries.items():
        e = parse_literals(e)
        name = stem(key, "COMPleib_", "compleib")
        A, B1, B, C, D21 = (mat(e[k]) for k in ("A", "B1", "B", "C", "D21"))
        data_keys = [
            "A",
            "B1",
            "B",
            "C1",
            "C",
            "D11",
            "D12",
            "D21",
            "nx",
            "nw",
            "nu",
            "nz",
            "ny",
            "model",
            "properties",
        ]
        data = {k: e[k] for k in data_keys if k in e}
        RR = D21 @ D21.T
        notes = [
            "Model x' = A x + B1 w + B u, z = C1 x + D11 w + D12 u, y = C x + D21 w (all matrices in data).  "
            "Plant for estimation: (A, C, G = B1, Q = I, B = B)."
        ]
        if is_pd(RR):
            R = RR
            cross = float(np.max(np.abs(B1 @ D21.T)))
            notes.append("R = D21 D21' (positive definite).")
            if cross > 0:
                notes.append(
                    f"The same w drives process and measurement: the cross-covariance B1 D21' (max "
                    f"|entry| {cross:.6g}) is dropped (our Plant has none)."
                )
        else:
            R = np.eye(C.shape[0])
            notes.append(
                f"D21 D21' is singular (rank {np.linalg.matrix_rank(RR)} of {RR.shape[0]}): R = I is "
                "used instead (a modelling choice, not COMPleib data)."
            )
        plant = {
            "A": tolist(A),
            "C": tolist(C),
            "G": tolist(B1),
            "Q": tolist(np.eye(B1.shape[1])),
            "R": tolist(R),
            "dt": None,
            "B": tolist(B),
        }
        title = f"COMPleib {e['example']}"
        prob = problem(
            name,
            title,
            "plant",
            ["benchmark", "compleib"],
            COMPLEIB_CITATION.format(ex=e["example"]),
            e["source"],
            "  ".join(notes),
            plant,
            {},
            {"properties": e.get("properties", {})},
            data,
        )
        out.append(("compleib", prob))
    return out


# --------------------------------------------------------------------------- pole placement
def import_poleplacement(entries: dict) -> list[dict]:
    out = []
    for key, e in entries.items():
        e = parse_literals(e)
        name = stem(key, "PolePlacement_", "pp")
        A, B = mat(e["A"]), mat(e["B"])
        data = {"A": e["A"], "B": e["B"], "convention": e["convention"]}
        if "params" in e:
            data["params"] = e["params"]
        notes = [
            f"Source convention: {e['convention']}.  The plant is the observer dual A_f = A', C_f = B' "
            "(data holds the original A, B): an observer gain L with eig(A_f - L C_f) = poles gives the "
            "state feedback K = L' with eig(A - B K) = poles."
        ]
        targets: dict[str, Any] = {"poles": e["poles"]}
        references: dict[str, Any] = {}
        if "poles_alt" in e:
            targets["poles_alt"] = e["poles_alt"]
        if key == "PolePlacement_SLICOT_SB01BD_example":
            # partial assignment: only the NP = 2 given poles are placed; eigenvalues with Re < alpha stay.
            targets = {
                "poles": e["ref_closed_loop_eigs_4dec"],
                "poles_assigned": e["poles"],
                "alpha": e["params"]["alpha"],
            }
            F = mat(e["ref_F_4dec"])
            references = {
                "F_4dec": e["ref_F_4dec"],
                "L_4dec": tolist(-F.T),
                "closed_loop_poles_4dec": e["ref_closed_loop_eigs_4dec"],
            }
            notes.append(
                "SLICOT convention A + B F, i.e. K = -F and the dual observer gain L = -F' "
                "(references.L_4dec). Partial assignment (Varga): only targets.poles_assigned are placed, "
                "eigenvalues of A with Re < alpha are kept; targets.poles is the full closed-loop spectrum "
                "of the SLICOT result (4 decimals)."
            )
        if e.get("notes"):
            notes.append("Source notes: " + e["notes"])
        citation = f"Pole assignment test problems: {e['title']}"
        prob = problem(
            name,
            e["title"],
            "pole_placement",
            ["benchmark", "poleplacement"],
            citation,
            e["source"],
            "  ".join(notes),
            {"A": tolist(A.T), "C": tolist(B.T), "dt": None},
            targets,
            references,
            data,
        )
        out.append(("poleplacement", prob))
    return out


# --------------------------------------------------------------------------- Byers-Nash and Chu sets
# Copied by hand from the two public collections below (never read at run time); every entry is
# state feedback eig(A - B K) = poles, imported like the pole-placement collection above.
HAROLD_SOURCE = (
    "ilayn/harold@1e8c948c0db34816393df44a29e5d3939c99876f harold/tests/test_static_ctrl_design.py "
    "(byersnash_A_B_test_pairs, system {ex} of 11)"
)
CHU_SOURCE = (
    "JuliaSystems/ControlToolbox.jl@2fd4e255ecf284e0d844032a90a2a965c20fc19b test/design/place.jl "
    "(example {ex}; the same data at 44e54ed2943b3501c32e0377850bbbdf72ce7210)"
)
BYERS_NASH_CITATION = (
    'R. Byers and S. G. Nash, "Approaches to robust pole assignment", Int. J. Control 49 (1989) '
    "97-117: test system {ex} of 11 ({title})"
)
CHU_CITATION = (
    'E. K. Chu, "Pole assignment via the Schur form", Systems & Control Letters 56 (2007) 303-314, '
    "example {ex} ({title})"
)
_POLES_CHOSEN = (
    "targets.poles are NOT from the paper: the harold collection holds the (A, B) pairs only, and the "
    "paper's target poles were not available here; -1, ..., -n is this library's choice (the target of "
    "systems 3, 9 and 11 of the set)"
)


def _cplx(values: list) -> dict:
    z = np.asarray(values, dtype=complex)
    return {"re": z.real.tolist(), "im": z.imag.tolist()}


_D5, _D51, _D52 = np.diag([1, 10, 0.1, 0.1, 10]), np.diag([1, 0.1, 10, 10, 0.1]), np.diag([1e5, 1e2])
_A5 = [
    [-1.29e-1, 0, 3.96e-2, 2.5e-2, 1.91e-2],
    [3.29e-3, 0, -7.79e-5, 1.22e-4, -6.21e-1],
    [7.18e-2, 0, -1e-1, 8.87e-4, -3.85],
    [4.11e-2, 0, 0, -8.22e-2, 0],
    [3.51e-4, 0, 3.5e-5, 4.26e-5, -7.43e-2],
]
_B5 = [[0, 1.39e-3], [0, 3.59e-5], [0, -9.89e-3], [2.49e-5, 0], [0, -5.34e-6]]
_KNV1_A = [
    [1.38, -0.2077, 6.715, -5.676],
    [-0.5814, -4.29, 0, 0.675],
    [1.067, 4.273, -6.654, 5.893],
    [0.048, 4.273, 1.343, -2.104],
]
_KNV1_B = [[0, 0], [5.679, 0], [1.136, -3.146], [1.136, 0]]
_CHU1_A = [
    [1.38, -2.077e-1, 6.715, -5.67],
    [-5.814e-1, -4.29, 0, 6.77e-1],
    [1.067, 4.273, -6.654, 5.893],
    [4.8e-2, 4.273, 1.343, -2.104],
]

#: (title, A, B, poles, where the poles come from or None when chosen here, notes)
BYERS_NASH_SET = [
    (
        "chemical reactor (Munro 1979)",
        _KNV1_A,
        _KNV1_B,
        [-0.2, -0.5, -5.0566, -8.6659],
        "Kautsky, Nichols & Van Dooren (1985) example 1 (pp_knv1985_ex1; Chu 2007 example 1)",
        "Same A, B as pp_knv1985_ex1.",
    ),
    (
        "distillation column (Klein & Moore 1977)",
        [
            [-0.1094, 0.0628, 0, 0, 0],
            [1.306, -2.132, 0.9807, 0, 0],
            [0, 1.595, -3.149, 1.547, 0],
            [0, 0.0355, 2.632, -4.257, 1.855],
            [0, 0.0023, 0, 0.1636, -0.1625],
        ],
        [[0, 0], [0.638, 0], [0.0838, -0.1396], [0.1004, -0.206], [0.0063, -0.0128]],
        [-0.2, -0.5, -1, -1 + 1j, -1 - 1j],
        "Kautsky, Nichols & Van Dooren (1985) example 2 (Chu 2007 example 2)",
        "Transcription variant: harold has B[1, 0] = 0.638 where pp_knv1985_ex2 (Modelica) and Chu 2007 have "
        "0.0638, and A[4, 1] = 0.0023 where Modelica has 0.00227; copied as harold has them.",
    ),
    (
        "nuclear rocket engine (Davison & Chow 1974)",
        [[-65.0, 65, -19.5, 19.5], [0.1, -0.1, 0, 0], [1, 0, -0.5, -1], [0, 0, 0.4, 0]],
        [[65.0, 0], [0, 0], [0, 0], [0, 0.4]],
        [-1, -2, -3, -4],
        "pp_byers3 (Modelica) and Chu 2007 example 3",
        "Same A, B as pp_byers3; Chu 2007 has A[0, 3] = 19.4 (transcription variant).",
    ),
    (
        "MIMO system (Atkinson 1985)",
        [[0, 1, 0], [0, 0, 1], [-6, -11, -6]],
        [[1, 1], [0, 1], [1, 1]],
        [-1, -2, -3],
        "pp_byers4 (Modelica) and Chu 2007 example 4",
        "Same A, B as pp_byers4.",
    ),
    (
        "drum boiler (Bengtsson 1973)",
        [
            [-0.129, 0, 0.396, 0.25, 0.00191],
            [0.0329, 0, -0.00779, 0.0122, -0.621],
            [0.00718, 0, -0.1, 0.000887, -0.0385],
            [0.00411, 0, 0, -0.0822, 0],
            [0.00351, 0, 0.0035, 0.00426, -0.0743],
        ],
        [[0, 0.1390], [0, 0.0359], [0, -0.0989], [0.0249, 0], [0, -0.00534]],
        [-0.01, -0.02, -0.03, -0.04, -0.05],
        "pp_byers5 (Modelica) and Chu 2007 example 5",
        "harold stores the scaled matrices D A0 D1, D B0 D2 (D = diag(1, 10, .1, .1, 10), D1 = "
        "diag(1, .1, 10, 10, .1), "
        "D2 = diag(1e4, 100)), as pp_byers5; Chu 2007 scales the first input by 1e5 instead "
        "(pp_chu2007_ex5).",
    ),
    (
        "Miminis random example 1",
        [
            [5.8765, 9.3456, 4.5634, 9.3520],
            [6.6526, 0.5867, 3.5829, 0.6534],
            [0, 9.6738, 7.4876, 4.7654],
            [0, 0, 6.6784, 2.5678],
        ],
        [[3.9878, 0.5432], [0, 2.7650], [0, 0], [0, 0]],
        [-29.4986, -10.0922, 2.5201 + 6.891j, 2.5201 - 6.891j],
        "pp_byers6 (Modelica) and Chu 2007 example 6",
        "Same A, B as pp_byers6; two target poles are unstable (a state-feedback benchmark).",
    ),
    (
        "Miminis random example 2 (8 states, 3 inputs)",
        [
            [0.5257, 0.8544, 0.5596, 0.5901, 0.0259, 0.6213, 0.7227, 0.5617],
            [0.9931, 0.0643, 0.1249, 0.3096, 0.5174, 0.3455, 0.8977, 0.4682],
            [0.6489, 0.8279, 0.7279, 0.2552, 0.3917, 0.7065, 0.2428, 0.7795],
            [0.9923, 0.9262, 0.2678, 0.6252, 0.2414, 0.5211, 0.4338, 0.9677],
            [0, 0.5667, 0.5465, 0.1157, 0.5064, 0.2870, 0.7901, 0.9809],
            [0, 0, 0.8672, 0.6117, 0.4236, 0.6503, 0.5069, 0.8187],
            [0, 0, 0, 0, 0.2894, 0.0881, 0.5233, 0.4257],
            [0, 0, 0, 0, 0, 0.4499, 0.5597, 0.2462],
        ],
        [
            [0.9230, 0.3950, 0.8325],
            [0, 0.0366, 0.6105],
            [0, 0, 0.1871],
            [0, 0, 0],
            [0, 0, 0],
            [0, 0, 0],
            [0, 0, 0],
            [0, 0, 0],
        ],
        [-1, -2, -3, -4, -5, -6, -7, -8],
        None,
        "",
    ),
    (
        "aircraft control example I (Kautsky & Nichols 1983)",
        [
            [0, 1, 0, 0],
            [1.40e-4, -2.04, -1.95, -1.33e-2],
            [-2.51e-4, 1, -1.32, -2.38e-2],
            [-5.61e-1, 0, 0.358, -2.79e-1],
        ],
        [[0, 0, 0], [-5.33, 6.45e-3, -2.67e-1], [-1.60e-1, -1.16e-2, -2.51e-1], [0, 1.06e-1, 8.62e-2]],
        [-1, -2, -3, -4],
        None,
        "",
    ),
    (
        "aircraft control example II (Kautsky & Nichols 1983)",
        [
            [0, 1, 0, 0],
            [5.32e-7, -4.18e-1, -0.12, -2.32e-2],
            [-4.62e-9, 1, -0.752, -2.39e-2],
            [-5.61e-1, 0, 0.3, -1.74e-2],
        ],
        [[0, 0], [-1.72e-1, 7.45e-6], [-2.82e-2, -7.78e-5], [0, 3.69e-3]],
        [-1, -2, -3, -4],
        "Chu 2007 example 8",
        "Chu 2007 has A[1, 3] = +2.32e-2, A[3, 2] = -0.3 and B[2, 0] = -2.38e-2 (transcription "
        "variants); copied as "
        "harold has them.",
    ),
    (
        "symmetric example (Kautsky & Nichols 1983)",
        [
            [-3.624, 4.9567e-2, -2.4564e-1, 1.3853e-2],
            [3.3486e-1, -1.8875, -8.1251e-1, -2.8102e-1],
            [-1.9958e-1, -1.1335, -2.2039, -4.5523e-1],
            [1.3784e-1, -4.7140e-1, -3.3229e-1, -4.0605],
        ],
        np.array(
            [[2.3122e-1, 3.0761e-1, 3.6164e-1, 3.3217e-1], [8.8339e-1, 2.1460e-1, 5.6642e-1, 5.0153e-1]]
        ).T.tolist(),
        [-1, -2, -3, -4],
        None,
        "",
    ),
    (
        "ill-conditioned example (Byers & Nash 1989)",
        [[0, 0, 0, 0], [1, 10, 100, 1000], [0, 1, 10, 100], [0, 0, 1, 10]],
        [[1, 0], [0, 1], [0, 0], [0, 0]],
        [-1, -2, -3, -4],
        "Chu 2007 example 9",
        "",
    ),
]

#: (title, A, B, poles, kappa2 bound, ||F||_F bound of the source's test, notes)
CHU_SET = [
    (
        "chemical reactor (KNV 1985 example 1)",
        _CHU1_A,
        _KNV1_B,
        [-0.2, -0.5, -5.0566, -8.6659],
        5,
        5,
        "Transcription variant of pp_knv1985_ex1: A[0, 3] = -5.67 (KNV: -5.676), A[1, 3] = 0.677 "
        "(KNV: 0.675).",
    ),
    (
        "distillation column (KNV 1985 example 2)",
        [
            [-1.094e-1, 6.28e-2, 0, 0, 0],
            [1.306, -2.132, 9.87e-1, 0, 0],
            [0, 1.595, -3.149, 1.547, 0],
            [0, 3.55e-2, 2.632, -4.257, 1.855],
            [0, 2.3e-3, 0, 1.636e-1, -1.625e-1],
        ],
        [[0, 0], [6.38e-2, 0], [8.38e-2, -1.396e-1], [1.004e-1, -2.06e-1], [6.3e-3, -1.28e-2]],
        [-0.2, -0.5, -1, -1 + 1j, -1 - 1j],
        1000,
        200,
        "Transcription variant of pp_knv1985_ex2: A[1, 2] = 0.987 (KNV: 0.9807), A[4, 1] = 0.0023 "
        "(Modelica: 0.00227).",
    ),
    (
        "nuclear rocket engine",
        [[-65.0, 65, -19.5, 19.4], [0.1, -0.1, 0, 0], [1, 0, -0.5, -1], [0, 0, 0.4, 0]],
        [[65.0, 0], [0, 0], [0, 0.4], [0, 0]],
        [-1, -2, -3, -4],
        50,
        100,
        "Differs from pp_byers3 beyond transcription: A[0, 3] = 19.4 (Byers: 19.5) and the second "
        "input enters the "
        "third state (B[2, 1] = 0.4) where pp_byers3 has it in the fourth.",
    ),
    (
        "MIMO system (Atkinson 1985)",
        [[0, 1, 0], [0, 0, 1], [-6, -11, -6]],
        [[1, 1], [0, 1], [1, 1]],
        [-1, -2, -3],
        1000,
        1,
        "Same A, B as pp_byers4.",
    ),
    (
        "drum boiler, scaled",
        (_D5 @ np.array(_A5) @ _D51).tolist(),
        (_D5 @ np.array(_B5) @ _D52).tolist(),
        [-0.01, -0.02, -0.03, -0.04, -0.05],
        1000,
        5,
        "A = D A0 D1, B = D B0 D2 with D = diag(1, 10, .1, .1, 10), D1 = diag(1, .1, 10, 10, .1), D2 "
        "= diag(1e5, 1e2), "
        "evaluated here from the source's A0, B0 (pp_byers5 uses D2 = diag(1e4, 100): a different "
        "input scaling).",
    ),
    (
        "Miminis random example 1",
        [
            [5.8765, 9.3456, 4.5634, 9.3520],
            [6.6526, 0.5867, 3.5829, 0.6534],
            [0, 9.6738, 7.4876, 4.7654],
            [0, 0, 6.6784, 2.5678],
        ],
        [[3.9878, 0.5432], [0, 2.7650], [0, 0], [0, 0]],
        [-29.4986, -10.0922, 2.5201 + 6.891j, 2.5201 - 6.891j],
        5,
        50,
        "Same A, B as pp_byers6.",
    ),
    (
        "chemical reactor with a repeated complex pair",
        _CHU1_A,
        _KNV1_B,
        [-0.5 + 1j, -0.5 - 1j, -0.5 + 1j, -0.5 - 1j],
        1e12,
        5,
        "The source's comment reads 'pole of multiplicity 4 > rank(B) = 2'; that is not what the "
        "data ask: each of "
        "-0.5 +- 1j appears twice, a multiplicity equal to rank(B) = 2, so a diagonalizable (non-defective) "
        "closed loop exists (its kappa2 bound 1e12 is loose).",
    ),
    (
        "aircraft control example II (Kautsky & Nichols 1983)",
        [
            [0, 1, 0, 0],
            [5.32e-7, -4.18e-1, -0.12, 2.32e-2],
            [-4.62e-9, 1, -0.752, -2.39e-2],
            [-5.61e-1, 0, -0.3, -1.74e-2],
        ],
        [[0, 0], [-1.72e-1, 7.45e-6], [-2.38e-2, -7.78e-5], [0, 3.69e-3]],
        [-1, -2, -3, -4],
        1000,
        1000,
        "Transcription variant of Byers & Nash system 9 (pp_byersnash_09): A[1, 3], A[3, 2] and B[2, "
        "0] differ.",
    ),
    (
        "ill-conditioned example (Byers & Nash 1989)",
        [[0, 0, 0, 0], [1, 10, 100, 1000], [0, 1, 10, 100], [0, 0, 1, 10]],
        [[1, 0], [0, 1], [0, 0], [0, 0]],
        [-1, -2, -3, -4],
        1e6,
        10000,
        "Same A, B as pp_byersnash_11.",
    ),
]


def _placement_problem(key, title, A, B, poles, source, notes) -> tuple[str, dict]:
    """A problem in the schema of the pole-placement collection (through :func:`import_poleplacement`),
    with this script's own ``notes`` appended."""
    P = np.asarray(poles, dtype=complex)
    e = {
        "title": title,
        "A": np.asarray(A, dtype=float).tolist(),
        "B": np.asarray(B, dtype=float).tolist(),
        "poles": _cplx(poles) if np.any(P.imag != 0) else P.real.tolist(),
        "source": source,
        "convention": "state feedback u = -K x, eig(A - B K) = poles; observer: use (A.T, C.T)",
    }
    ((group, prob),) = import_poleplacement({key: e})
    prob["notes"] += "  " + notes
    return group, prob


def import_placement_sets() -> list[tuple[str, dict]]:
    """The Byers-Nash set (11 systems, from harold's tests) and Chu's 2007 set (9 examples, from
    ControlToolbox.jl), as pole-placement problems ``pp_byersnash_NN`` and ``pp_chu2007_exN``."""
    out = []
    for k, (title, A, B, poles, origin, notes) in enumerate(BYERS_NASH_SET, start=1):
        origin_note = f"Target poles from {origin}." if origin else _POLES_CHOSEN + "."
        group, prob = _placement_problem(
            f"PolePlacement_byersnash_{k:02d}",
            f"Byers & Nash test system {k}: {title}",
            A,
            B,
            poles,
            HAROLD_SOURCE.format(ex=k),
            f"{origin_note} {notes}".strip(),
        )
        prob["citation"] = BYERS_NASH_CITATION.format(ex=k, title=title)
        prob["tags"] = ["benchmark", "poleplacement", "byers_nash"]
        prob["data"]["poles_origin"] = origin or "optdesign's choice (-1, ..., -n), not from the source"
        out.append((group, prob))
    for k, (title, A, B, poles, kbound, cbound, notes) in enumerate(CHU_SET, start=1):
        group, prob = _placement_problem(
            f"PolePlacement_chu2007_ex{k}",
            f"Chu 2007 example {k}: {title}",
            A,
            B,
            poles,
            CHU_SOURCE.format(ex=k),
            f"Target poles from the source. {notes}",
        )
        prob["citation"] = CHU_CITATION.format(ex=k, title=title)
        prob["tags"] = ["benchmark", "poleplacement", "chu2007"]
        prob["references"] = {
            "kappa2_bound_of_source_test": float(kbound),
            "gain_fro_bound_of_source_test": float(cbound),
        }
        prob["notes"] += (
            "  references: the source's test asserts cond(V) < kappa2_bound_of_source_test and "
            "||F||_F < gain_fro_bound_of_source_test for its own design (bounds, not results)."
        )
        out.append((group, prob))
    return out


# --------------------------------------------------------------------------- Kalman references
def import_kf(entries: dict) -> list[dict]:
    out = []
    for key, e in entries.items():
        e = parse_literals(e)
        name = stem(key, "KF_", "kf")
        citation = f"Kalman filter reference cases: {e['title']}"
        tags = ["benchmark", "kf"]
        data = {k: v for k, v in e.items() if k not in ("title", "source", "collection", "notes")}
        if key == "KF_SLICOT_FB01VD":
            plant = {"A": e["A"], "C": e["C"], "G": e["B"], "Q": e["Qn"], "R": e["Rn"], "dt": 1.0}
            targets = {"P_prior": e["P_prior"], "steps": 1}
            references = {
                "P_next_4dec": e["ref_P_next_4dec"],
                "K_4dec": e["ref_K_4dec"],
                "chol_Rinov_upper_4dec": e["ref_chol_Rinov_upper_4dec"],
            }
            notes = (
                "One step of the conventional (covariance) filter from P_prior.  Equations: "
                + e["equations"]
                + ".  K is the measurement-update (filtered) gain P C' Rinov^-1, not the predictor gain "
                "A P C' Rinov^-1.  References printed to 4 decimals."
            )
            Qn, P_prior = mat(e["Qn"]), mat(e["P_prior"])
            if not is_psd(Qn):
                plant = None
                notes += (
                    f"  plant is null: the example's Qn is not positive semidefinite (smallest eigenvalue "
                    f"{min_eig(Qn):.6g}; P_prior is indefinite too, {min_eig(P_prior):.6g}): SLICOT's "
                    "example data are arbitrary numbers, so the recursion is an algebraic test only (data "
                    "holds A, B, C, Qn, Rn, P_prior; G = B, Q = Qn, R = Rn)."
                )
            kind = "kalman_step"
        elif key == "KF_SLICOT_FB01QD":
            Qs, Rs, S0 = mat(e["Qn_sqrt"]), mat(e["Rn_sqrt"]), mat(e["S0"])
            S3 = mat(e["ref_S_after3_4dec"])
            plant = {
                "A": e["A"],
                "C": e["C"],
                "G": e["B"],
                "Q": tolist(Qs @ Qs.T),
                "R": tolist(Rs @ Rs.T),
                "dt": 1.0,
            }
            targets = {"P0": tolist(S0 @ S0.T), "steps": 3}
            references = {
                "S_after3_4dec": e["ref_S_after3_4dec"],
                "P_after3_4dec": tolist(S3 @ S3.T),
                "L_after3_4dec": e["ref_K_after3_4dec"],
            }
            notes = (
                "Three combined measurement/time updates of the square-root covariance filter from P0 = S0 "
                "S0' = 0.  Equations: " + e["equations"] + ".  Plant Q = Qn_sqrt Qn_sqrt', R = Rn_sqrt "
                "Rn_sqrt' (lower-triangular square roots as in SLICOT).  references.L_after3_4dec is the "
                "PREDICTOR gain K = A P C' Rinov^-1 of the third step (the source's ref_K_after3_4dec); "
                "references.P_after3_4dec = S S' is formed here from the printed S (S is a Cholesky factor "
                "up to column signs; compare S S').  References printed to 4 decimals."
            )
            if e.get("notes"):
                notes += "  Source notes: " + e["notes"]
            kind = "kalman_step"
        elif key == "KF_analytic_alpha_beta_dt":
            prm = e["params"]
            plant = {"A": e["A"], "C": e["C"], "G": e["G"], "Q": e["QN"], "R": e["RN"], "dt": prm["T"]}
            targets = {}
            references = {"alpha": e["ref_alpha"], "beta": e["ref_beta"], "K_filtered": e["ref_K_filtered"]}
            notes = (
                "Steady-state alpha-beta tracker.  Formula: " + e["formula"] + ".  K_filtered is the "
                "a-posteriori (filtered) gain M = P C'(C P C' + R)^-1 with P the predictor DARE solution; "
                "the predictor gain of the library's convention is L = A M."
            )
            kind = "kalman"
        else:
            plant = {"A": e["A"], "C": e["C"], "G": e["G"], "Q": e["QN"], "R": e["RN"], "dt": None}
            targets = {}
            references = {"P": e["ref_P"], "L": e["ref_L"]}
            if "ref_poles" in e:
                references["poles"] = e["ref_poles"]
            notes = (
                "Continuous-time steady-state Kalman filter: A P + P A' - P C' R^-1 C P + G Q G' = 0, "
                "L = P C' R^-1, poles = eig(A - L C)."
            )
            if "formula" in e:
                notes += "  Formula: " + e["formula"] + "."
            kind = "kalman"
        if plant is not None:
            for k in ("Q", "R"):
                ok = is_pd(mat(plant[k])) if k == "R" else is_psd(mat(plant[k]))
                if not ok:
                    raise ValueError(
                        f"{key}: {k} is not a valid covariance; add a null-plant rule with a note"
                    )
        prob = problem(
            name, e["title"], kind, tags, citation, e["source"], notes, plant, targets, references, data
        )
        out.append(("kf", prob))
    return out


# --------------------------------------------------------------------------- writing
def _fmt_number(x: Any) -> str:
    if isinstance(x, bool) or x is None:
        return json.dumps(x)
    if isinstance(x, float) and not math.isfinite(x):
        raise ValueError(f"non-finite number {x!r} cannot be stored in standard JSON")
    return json.dumps(x)


def _is_flat_numbers(v: Any) -> bool:
    return isinstance(v, list) and all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v)


def dumps(obj: Any, indent: int = 0) -> str:
    """JSON with one matrix row per line (readable diffs, compact files)."""
    pad, pad1 = "  " * indent, "  " * (indent + 1)
    if isinstance(obj, dict):
        if not obj:
            return "{}"
        items = [f"{pad1}{json.dumps(str(k))}: {dumps(v, indent + 1)}" for k, v in obj.items()]
        return "{\n" + ",\n".join(items) + "\n" + pad + "}"
    if isinstance(obj, list):
        if not obj:
            return "[]"
        if _is_flat_numbers(obj):
            return "[" + ", ".join(_fmt_number(x) for x in obj) + "]"
        if all(_is_flat_numbers(r) for r in obj):
            rows = [pad1 + dumps(r) for r in obj]
            return "[\n" + ",\n".join(rows) + "\n" + pad + "]"
        items = [pad1 + dumps(v, indent + 1) for v in obj]
        return "[\n" + ",\n".join(items) + "\n" + pad + "]"
    if isinstance(obj, (int, float, bool)) or obj is None:
        return _fmt_number(obj)
    if isinstance(obj, str):
        return json.dumps(obj, ensure_ascii=False)
    raise TypeError(f"cannot store {type(obj).__name__} in a problem file")


def readme_table(dst: Path) -> str:
    rows = []
    for path in sorted(dst.rglob("*.json")):
        raw = json.loads(path.read_text(encoding="utf-8"))
        group = path.parent.relative_to(dst).as_posix()
        title = raw.get("title", "").replace("|", "/")
        plant = "-" if raw.get("plant") is None else "yes"
        rows.append(
            (group, raw["name"], raw.get("kind", ""), plant, title, raw.get("citation", "").replace("|", "/"))
        )
    order = {"seeds": 0, "carex": 1, "darex": 2, "compleib": 3, "poleplacement": 4, "kf": 5}
    rows.sort(key=lambda r: (order.get(r[0], 9), r[0], _natural(r[1])))
    lines = ["| name | kind | plant | what it is | citation |", "|---|---|---|---|---|"]
    lines += [f"| `{n}` | {k} | {p} | {t} | {c} |" for _, n, k, p, t, c in rows]
    return "\n".join(lines)


def _natural(s: str) -> list:
    return [int(t) if t.isdigit() else t for t in re.split(r"(\d+)", s)]


BEGIN, END = "<!-- BEGIN PROBLEM TABLE (tools/import_benchmarks.py) -->", "<!-- END PROBLEM TABLE -->"


def update_readme(dst: Path, check: bool) -> bool:
    path = dst / "README.md"
    text = path.read_text(encoding="utf-8")
    if BEGIN not in text or END not in text:
        raise SystemExit(f"{path} lacks the table markers {BEGIN!r} / {END!r}")
    head, rest = text.split(BEGIN, 1)
    _, tail = rest.split(END, 1)
    new = f"{head}{BEGIN}\n{readme_table(dst)}\n{END}{tail}"
    if new == text:
        return True
    if check:
        print(f"differs: {path}")
        return False
    path.write_text(new, encoding="utf-8")
    return True


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--src", type=Path, default=DEFAULT_SRC, help="benchmark folder (default: %(default)s)")
    ap.add_argument("--dst", type=Path, default=DEFAULT_DST, help="problem library (default: %(default)s)")
    ap.add_argument("--check", action="store_true", help="compare with the files on disk; write nothing")
    args = ap.parse_args(argv)

    importers = {
        "carex.json": import_carex,
        "darex.json": import_darex,
        "compleib.json": import_compleib,
        "poleplacement.json": import_poleplacement,
        "kf.json": import_kf,
    }
    generated: list[tuple[str, dict]] = []
    for fname, fn in importers.items():
        entries = json.loads((args.src / fname).read_text(encoding="utf-8"))
        generated += fn(entries)
    generated += import_placement_sets()

    names = [p["name"] for _, p in generated]
    dup = {n for n in names if names.count(n) > 1}
    if dup:
        raise SystemExit(f"duplicate names: {sorted(dup)}")
    ok = True
    for group, prob in generated:
        check_plant(prob)
        text = dumps(prob) + "\n"
        json.loads(text)  # round-trip: standard JSON
        path = args.dst / group / f"{prob['name']}.json"
        if args.check:
            if not path.exists() or path.read_text(encoding="utf-8") != text:
                print(f"differs: {path}")
                ok = False
            continue
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")
    ok = update_readme(args.dst, args.check) and ok
    if not args.check:
        n_null = sum(p["plant"] is None for _, p in generated)
        print(
            f"wrote {len(generated)} problems ({n_null} with plant null) and the README table to {args.dst}"
        )
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
