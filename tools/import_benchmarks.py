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
    ``L = K'`` gives ``eig(A' - L B') = poles``.
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
