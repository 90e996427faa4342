"""A user's own plant from a file (issue 17, part 2): JSON / TOML, .npz and MATLAB .mat, in
``problems.load``, ``optdesign design``, ``optdesign kalman``, ``optdesign show`` and study specs --
loaded safely (no pickle, no eval; size checked before anything is built) and every mistake named
by file and field."""

from __future__ import annotations

import json
import pickle
import struct
from pathlib import Path

import numpy as np
import pytest
import scipy.io

from optdesign import problems
from optdesign.cli import main
from optdesign.design.kalman import kalman
from optdesign.errors import ProblemNotFoundError, ValidationError
from optdesign.problems import ProblemFileError
from optdesign.studies.spec import load_spec, run_spec

# Chang & Lee 1984, Example 1 (the library's chang_lee_1984_ex1 plant): the reference for every format
A = [[0.0, 1.0], [-6.0, -5.0]]
C = [[1.0, 0.0]]
Q = [[76.0, -35.233412], [-35.233412, 16.334123]]
R = [[1.0]]


@pytest.fixture(autouse=True)
def _in_tmp(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # relative paths as a user types them; nothing written elsewhere


def write_json(path, obj) -> Path:
    Path(path).write_text(json.dumps(obj))
    return Path(path)


def run(argv, capsys):
    code = main(argv)
    cap = capsys.readouterr()
    return code, cap.out, cap.err


def files_of_every_format(tmp: Path) -> dict[str, Path]:
    out = {"json": write_json(tmp / "mine.json", {"A": A, "C": C, "Q": Q, "R": R, "poles": ["-5", -8]})}
    (tmp / "mine.toml").write_text(f"A = {A}\nC = {C}\nQ = {Q}\nR = {R}\npoles = [-5.0, -8.0]\n"
                                   'title = "my plant"\n')
    out["toml"] = tmp / "mine.toml"
    np.savez(tmp / "mine.npz", A=np.array(A), C=np.array(C), Q=np.array(Q), R=np.array(R),
             poles=np.array([-5.0, -8.0]), dt=np.float64(0.0))
    out["npz"] = tmp / "mine.npz"
    scipy.io.savemat(tmp / "mine.mat", {"A": np.array(A), "C": np.array(C), "Q": np.array(Q),
                                        "R": np.array(R), "poles": np.array([[-5.0, -8.0]]),
                                        "name": "mat_plant"})
    out["mat"] = tmp / "mine.mat"
    schema = json.loads((problems._source_root() / "seeds" / "chang_lee_1984_ex1.json").read_text())
    out["schema"] = write_json(tmp / "schema.json", schema)
    return out


@pytest.mark.parametrize("fmt", ["json", "toml", "npz", "mat", "schema"])
def test_every_format_loads_the_same_plant(fmt, tmp_path):
    path = files_of_every_format(tmp_path)[fmt]
    p = problems.load(str(path))
    assert p.origin == "file" and p.path == str(path) and p.plant.n == 2 and not p.plant.is_discrete
    np.testing.assert_array_equal(p.plant.A, A)
    np.testing.assert_array_equal(p.plant.C, C)
    np.testing.assert_allclose(p.plant.R, R)
    np.testing.assert_allclose(np.sort(p.targets["poles"].real), [-8.0, -5.0])
    assert p.name == {"mat": "mat_plant", "schema": "chang_lee_1984_ex1"}.get(fmt, path.stem)
    assert problems.load(path).name == p.name  # a Path object works too
    # the same Kalman filter as from the library problem (whose Q is the full-precision one)
    lib = kalman(problems.load("chang_lee_1984_ex1").plant)
    np.testing.assert_allclose(kalman(p.plant).L, lib.L, rtol=1e-5)


def test_a_relative_path_and_discrete_time(tmp_path):
    write_json("d.json", {"A": [[0.5]], "C": [[1.0]], "Q": [[1.0]], "R": [[1.0]], "dt": 0.1,
                          "name": "scalar", "notes": "a discrete scalar plant"})
    p = problems.load("./d.json")
    assert p.plant.dt == 0.1 and p.name == "scalar" and p.kind == "user" and p.notes.startswith("a discrete")
    assert problems.load("d.json").plant.dt == 0.1


def test_library_names_are_unchanged():
    assert problems.load("carex_1.1").origin == "library"  # a dot is not a suffix
    assert not problems.is_problem_file("carex_1.1") and problems.is_problem_file("x/y")
    with pytest.raises(ProblemNotFoundError, match="no problem named 'carex_1'"):
        problems.load("carex_1")


# ------------------------------------------------------------------ the command line


@pytest.mark.parametrize("fmt", ["json", "toml", "npz", "mat"])
def test_design_and_kalman_take_a_file(fmt, tmp_path, capsys):
    path = files_of_every_format(tmp_path)[fmt]
    arg = f"./{path.name}"  # issue 17: "optdesign design ./mine.json --method kalman" said "no problem named"
    code, out, err = run(["design", arg, "--method", "kalman", "--json"], capsys)
    assert code == 0, err
    d = json.loads(out)
    assert d["success"] is True
    np.testing.assert_allclose(np.ravel(d["L"]), [8.0, -6.0], rtol=1e-5)  # seed 000, Example 1
    code, out, err = run(["design", arg, "--method", "inverse"], capsys)  # the file's target poles
    assert code == 0, err
    assert "target poles: -8, -5" in out and "poles of A - L C: -8, -5" in out
    code, out, err = run(["kalman", arg], capsys)
    assert code == 0 and out.startswith("problem: ") and "poles of A - L C: -8, -5" in out


def test_show_takes_a_file(tmp_path, capsys):
    files_of_every_format(tmp_path)
    code, out, _ = run(["show", "mine.toml"], capsys)
    assert code == 0 and out.startswith("mine: my plant") and "file: mine.toml" in out
    assert "poles = [-8. -5.]" in out and "array(" not in out
    code, out, _ = run(["show", "mine.json", "--json"], capsys)
    assert code == 0 and json.loads(out)["plant"]["A"] == A


@pytest.mark.parametrize("argv, match", [
    (["design", "./nope.json", "--method", "kalman"], "./nope.json: no such problem file"),
    (["kalman", "bad.json"], "bad.json: R: R must be positive definite"),
    (["show", "typo.json"], "typo.json: Cc: unknown field for a plant file"),
    (["design", "mine.txt", "--method", "kalman"], "mine.txt: unknown kind of problem file '.txt'"),
])
def test_cli_file_errors_are_one_line_exit_2(argv, match, tmp_path, capsys):
    write_json("bad.json", {"A": A, "C": C, "Q": Q, "R": [[-1.0]]})
    write_json("typo.json", {"A": A, "Cc": C})
    Path("mine.txt").write_text("A = 1")
    code, _, err = run(argv, capsys)
    assert code == 2 and err.startswith("optdesign: error: ") and err.count("\n") == 1
    assert match in err and "Traceback" not in err


# ------------------------------------------------------------------ study specs


def test_a_spec_takes_a_problem_file_next_to_it(tmp_path, capsys):
    specdir = tmp_path / "specs"
    specdir.mkdir()
    write_json(specdir / "mine.json", {"A": A, "C": C, "Q": Q, "R": R, "poles": [-5, -8]})
    spec = specdir / "s.toml"
    spec.write_text('[study]\nproblem = "mine.json"\ndesign = "inverse"\nexecutor = "serial"\n'
                    "[grid]\nscale = [1.0, 2.0]\n")
    loaded = load_spec(spec)
    assert loaded.designer.plant is not None and loaded.designer.problem is None
    res = run_spec(loaded, progress=False)
    assert res.table.n_success == 2 and res.csv.resolve().parent == tmp_path / "s_results"  # cwd, not specs/
    # the same through the command line, with the kalman design
    spec.write_text('[study]\nproblem = "mine.json"\ndesign = "kalman"\nexecutor = "serial"\n'
                    '[grid]\nq = [1.0]\n')
    code, out, err = run(["study", str(spec), "--no-progress", "--overwrite"], capsys)  # same s_results/
    assert code == 0, err
    assert "1 points, 1 successful" in out


def test_a_spec_names_a_bad_problem_file(tmp_path, capsys):
    write_json("bad.json", {"A": A, "C": [[1.0, 0.0, 0.0]]})
    Path("s.toml").write_text('[study]\nproblem = "bad.json"\ndesign = "well_conditioned"\n'
                              '[grid]\nalpha = [1]\n')
    code, _, err = run(["study", "s.toml"], capsys)
    assert code == 2 and "s.toml: study.problem: bad.json: C: C has the wrong shape" in err
    Path("s.toml").write_text('[study]\nproblem = "gone.npz"\ndesign = "kalman"\n[grid]\nq = [1]\n')
    code, _, err = run(["study", "s.toml"], capsys)
    assert code == 2 and "study.problem:" in err and "gone.npz: no such problem file" in err


# ------------------------------------------------------------------ mistakes, named by file and field


BAD_JSON = [
    ({"A": A}, "C: missing (a plant needs at least A and C)"),
    ({"A": [[0, 1], [2, 3], [4, 5]], "C": C}, "A: A must be square"),
    ({"A": A, "C": [[1.0, 0.0, 0.0]]}, "C: C has the wrong shape: expected (?, 2), found (1, 3)"),
    ({"A": [[0, 1], [-6, "x"]], "C": C}, "A: A must be numeric"),
    ({"A": [[0, 1], [-6]], "C": C}, "A: "),
    ({"A": A, "C": C, "Q": [[1, 2], [3, 4]]}, "Q: Q must be symmetric"),
    ({"A": A, "C": C, "Q": [[-1, 0], [0, 1]]}, "Q: Q must be positive semidefinite"),
    ({"A": A, "C": C, "R": [[0.0]]}, "R: R must be positive definite"),
    ({"A": A, "C": C, "G": [[1.0]]}, "G: G has the wrong shape"),
    ({"A": A, "C": C, "dt": -0.1}, "dt: dt must be"),
    ({"A": A, "C": C, "dt": "0.1"}, "dt: dt must be"),
    ({"A": A, "C": C, "name": 3}, "name: must be a string; found int"),
    ({"A": A, "C": C, "poles": [-1, "x"]}, "poles: 'x' is not a number"),
    ({"A": A, "C": C, "poles": [-1, -2, -3]}, "poles: poles has the wrong length"),
    ({"A": A, "C": C, "poles": ["-1+2j", -2]}, "poles: "),
    ({"A": A, "Cc": C},
     "Cc: unknown field for a plant file (A, C, G, Q, R, B, dt, name, title, notes, poles)"),
    ({"plant": {"A": A, "C": C, "W": [[1]]}},
     "plant.W: unknown field; a plant has A, C, G, Q, R, B, dt, name"),
    ({"plant": {"A": A, "C": C, "R": [[-2]]}}, "plant.R: R must be positive definite"),
    ({"plant": {"A": A, "C": C}, "targets": {"poles": [1, 2, 3]}},
     "targets.poles: poles has the wrong length"),
    ({"plant": {"A": A, "C": C}, "references": [1]}, "references: must be an object"),
    ({"plant": {"A": A, "C": C}, "tags": "x"}, "tags: must be a list of strings"),
    ({"plant": [1, 2]}, "plant: must be an object with the matrices A, C"),
    ({"plant": {"A": A, "C": C}, "flavour": 1}, "flavour: unknown field for the library schema"),
    ([1, 2], "expected an object with the plant's matrices (A, C, ...); found list"),
]


@pytest.mark.parametrize("obj, match", BAD_JSON)
def test_bad_fields_are_named(obj, match):
    write_json("mine.json", obj)
    with pytest.raises(ProblemFileError, match=f"^mine.json: {_esc(match)}"):
        problems.load("mine.json")


def _esc(text: str) -> str:
    import re

    return re.escape(text)


def test_bad_files_are_named():
    Path("broken.json").write_text('{"A": [[0, 1]')
    Path("broken.toml").write_text("A = [[0, 1]\n")
    Path("latin.json").write_bytes(b'{"name": "\xe9"}')
    Path("folder.json").mkdir()
    cases = [("broken.json", "broken.json: invalid JSON: Expecting"),
             ("broken.toml", "broken.toml: invalid TOML"), ("latin.json", "latin.json: not UTF-8 text"),
             ("folder.json", "folder.json: not a file"), ("absent.mat", "absent.mat: no such problem file")]
    for name, match in cases:
        with pytest.raises(ProblemFileError, match=_esc(match)):
            problems.load(name)
    with pytest.raises(ValidationError, match="path must be a string or a path; found int"):
        problems.load_file(3)
    with pytest.raises(ValidationError, match="name must be a string; found int 3"):
        problems.load(3)  # as before (issue 11)


def test_size_is_checked_before_anything_is_built(monkeypatch):
    write_json("big.json", {"A": [[0.0] * 2001] * 2, "C": [[1.0, 0.0]]})
    with pytest.raises(ProblemFileError, match=r"big.json: A: shape \(2, 2001\) exceeds the size limit: "
                                               r"every dimension must be <= 2000"):
        problems.load("big.json")
    # .npz: the shapes come from the .npy headers; no array is read before the check
    monkeypatch.setattr(problems, "MAX_DIMENSION", 4)
    np.savez("big.npz", A=np.zeros((5, 5)), C=np.zeros((1, 5)))

    def no_load(*args, **kwargs):
        raise AssertionError("an array was read before the size check")

    real_load = np.load
    monkeypatch.setattr(np, "load", no_load)
    with pytest.raises(ProblemFileError, match=r"big.npz: A: shape \(5, 5\) exceeds the size limit"):
        problems.load("big.npz")
    monkeypatch.setattr(np, "load", real_load)  # (not monkeypatch.undo(): it would undo the chdir too)
    scipy.io.savemat("big.mat", {"A": np.zeros((5, 5)), "C": np.zeros((1, 5))})
    monkeypatch.setattr(scipy.io, "loadmat", no_load)
    with pytest.raises(ProblemFileError, match=r"big.mat: A: shape \(5, 5\) exceeds the size limit"):
        problems.load("big.mat")


def test_file_size_limit(monkeypatch):
    write_json("mine.json", {"A": A, "C": C})
    monkeypatch.setattr(problems, "MAX_FILE_BYTES", 10)
    with pytest.raises(ProblemFileError, match=r"mine.json: the file has \d+ bytes; at most 10 are read"):
        problems.load("mine.json")


class _Trap:
    """Unpickling it would leave a file behind: the loader must never unpickle."""

    def __reduce__(self):
        return (Path.write_text, (Path("unpickled.flag").absolute(), "pickle was used"))


def test_npz_object_arrays_are_refused_without_unpickling():
    pickle.dumps(_Trap())  # picklable
    np.savez("trap.npz", A=np.array([_Trap()], dtype=object), C=np.eye(1))
    with pytest.raises(ProblemFileError, match="trap.npz: A: an object array .*pickle, which is not used"):
        problems.load("trap.npz")
    assert not Path("unpickled.flag").exists()


def test_npz_and_mat_mistakes():
    np.savez("mine.npz", A=np.array(A), C=np.array([[1.0, 0.0, 0.0]]))
    with pytest.raises(ProblemFileError, match=r"mine.npz: C: C has the wrong shape"):
        problems.load("mine.npz")
    np.savez("extra.npz", A=np.array(A), C=np.array(C), K=np.ones((2, 1)))
    with pytest.raises(ProblemFileError, match="extra.npz: K: unknown field for a plant file"):
        problems.load("extra.npz")
    Path("junk.npz").write_bytes(b"not a zip file")
    with pytest.raises(ProblemFileError, match="junk.npz: not a readable .npz archive"):
        problems.load("junk.npz")
    scipy.io.savemat("st.mat", {"A": np.array(A), "C": np.array(C), "S": {"a": 1}})
    with pytest.raises(ProblemFileError, match="st.mat: S: a MATLAB struct"):
        problems.load("st.mat")
    scipy.io.savemat("nan.mat", {"A": np.array([[np.nan, 1.0], [0.0, 1.0]]), "C": np.array(C)})
    with pytest.raises(ProblemFileError, match=r"nan.mat: A: A .*(NaN|finite)"):
        problems.load("nan.mat")
    # MATLAB v7.3 (HDF5) is refused with what to do
    header = b"MATLAB 7.3 MAT-file, HDF5 schema 1.00 .".ljust(116, b" ") + b"\0" * 8
    header += struct.pack("<H", 0x0200)
    Path("v73.mat").write_bytes(header + b"IM" + b"\0" * 512)
    with pytest.raises(ProblemFileError, match=r"v73.mat: MATLAB v7.3 \(HDF5\) files are not supported"):
        problems.load("v73.mat")


# ------------------------------------------------------------------ hostile files: typed errors, no blow-up
# (issue 26: numpy MemoryError, RecursionError and Python's digit-limit ValueError escaped; a 7-9 MB
# .npz / .mat was expanded to 2-3 GB before it was refused)


def _npy(shape, data: bytes = b"", descr: str = "<f8") -> bytes:
    """An .npy member whose header claims ``shape`` over ``data`` (forged when they disagree)."""
    import io

    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, {"descr": descr, "fortran_order": False, "shape": shape})
    return buf.getvalue() + data


def _npz(path, **members: bytes) -> Path:
    import zipfile

    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        for name, blob in members.items():
            zf.writestr(f"{name}.npy", blob)
    return Path(path)


def _never(*args, **kwargs):
    raise AssertionError("an array was read before its size was checked")


def test_npz_declaring_a_huge_shape_is_refused_before_reading(monkeypatch, capsys):
    ok_c = _npy((1, 2), np.zeros(2).tobytes())
    _npz("cube.npz", A=_npy((2000, 2000, 2000)), C=ok_c)  # each dimension within MAX_DIMENSION
    _npz("unknown.npz", A=_npy((2, 2), np.zeros(4).tobytes()), X=_npy((10**6, 10**6)))
    _npz("poles.npz", A=_npy((2, 2), np.zeros(4).tobytes()), C=ok_c, poles=_npy((10**9,)))
    _npz("forged.npz", A=_npy((300, 300), np.zeros(4).tobytes()), C=ok_c)  # 720 kB declared, 32 B held
    monkeypatch.setattr(np, "load", _never)
    with pytest.raises(ProblemFileError, match=r"cube.npz: A: shape \(2000, 2000, 2000\) of float64 declares "
                                               r"64000000000 bytes; at most 64000000 per array"):
        problems.load("cube.npz")
    with pytest.raises(ProblemFileError, match="unknown.npz: X: unknown field for a plant file"):
        problems.load("unknown.npz")
    with pytest.raises(ProblemFileError, match=r"poles.npz: poles: shape \(1000000000,\) of float64 decl"):
        problems.load("poles.npz")
    with pytest.raises(ProblemFileError, match=r"forged.npz: A: shape \(300, 300\) of float64 declares "
                                               r"720000 bytes but the member holds 32: a truncated or"):
        problems.load("forged.npz")
    code, _, err = run(["kalman", "cube.npz"], capsys)  # a MemoryError traceback and exit 1 before
    assert code == 2 and err.count("\n") == 1 and "cube.npz: A: shape (2000, 2000, 2000)" in err


def test_npz_compression_bomb_is_refused_before_it_expands(monkeypatch):
    """A member whose expanded size (the zip's own record) is beyond the limit: 4 MB of zeros in
    a few kB, against a limit lowered to 1 MB (:data:`optdesign.problems.MAX_ARRAY_BYTES`)."""
    import zipfile

    monkeypatch.setattr(problems, "MAX_ARRAY_BYTES", 2**20)
    with zipfile.ZipFile("bomb.npz", "w", compression=zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("C.npy", _npy((1, 2), np.zeros(2).tobytes()))
        with zf.open("A.npy", "w") as fh:
            fh.write(_npy((2, 2)))
            for _ in range(4):
                fh.write(bytes(2**20))
    assert Path("bomb.npz").stat().st_size < 20_000
    monkeypatch.setattr(np, "load", _never)
    with pytest.raises(ProblemFileError, match=r"bomb.npz: A: the member expands to 4194\d+ bytes; at most "
                                               r"1048576 per array \(optdesign.problems.MAX_ARRAY_BYTES\)"):
        problems.load("bomb.npz")
    # every member counts toward the total too
    monkeypatch.setattr(problems, "MAX_ARRAY_BYTES", 2**30)
    monkeypatch.setattr(problems, "MAX_EXPANDED_BYTES", 2**20)
    _npz("total.npz", A=_npy((300, 300), bytes(720_000)), Q=_npy((300, 300), bytes(720_000)))
    with pytest.raises(ProblemFileError, match="total.npz: Q: the arrays expand to more than 1048576 bytes"):
        problems.load("total.npz")


def test_npz_with_many_members_is_refused_from_its_end_record(monkeypatch):
    import zipfile

    with zipfile.ZipFile("many.npz", "w") as zf:
        for i in range(40):
            zf.writestr(f"A{i}.npy", b"")
    real = zipfile.ZipFile
    monkeypatch.setattr(zipfile, "ZipFile", _never)  # refused before the central directory is read
    with pytest.raises(ProblemFileError, match="many.npz: an archive of 40 members; a plant file has"):
        problems.load("many.npz")
    monkeypatch.setattr(zipfile, "ZipFile", real)


def _mat_v5(name: str, dims: tuple[int, int], body: bytes) -> bytes:
    """A MATLAB v5 file with one compressed double variable whose header states ``dims`` over a
    real part of ``body`` (forged when they disagree)."""
    import zlib

    def element(mdtype: int, data: bytes) -> bytes:
        return struct.pack("<II", mdtype, len(data)) + data + b"\0" * (-len(data) % 8)

    matrix = (element(6, struct.pack("<II", 6, 0))            # array flags: mxDOUBLE_CLASS
              + element(5, struct.pack("<ii", *dims))          # dimensions
              + element(1, name.encode())                      # name
              + element(9, body))                              # real part (miDOUBLE)
    inner = struct.pack("<II", 14, len(matrix)) + matrix       # miMATRIX
    header = b"MATLAB 5.0 MAT-file, forged for a test".ljust(116, b" ") + b"\0" * 8
    header += struct.pack("<H", 0x0100) + b"IM"
    packed = zlib.compress(inner, 9)
    return header + struct.pack("<II", 15, len(packed)) + packed  # miCOMPRESSED (not padded)


def test_mat_declared_and_compressed_sizes_are_checked_before_loading(monkeypatch):
    scipy.io.savemat("bigpoles.mat", {"A": np.zeros((2, 2)), "C": np.zeros((1, 2)),
                                      "poles": np.zeros((1, 600))}, do_compression=True)
    scipy.io.savemat("other.mat", {"A": np.zeros((2, 2)), "C": np.zeros((1, 2)), "X": np.zeros((1, 3))})
    scipy.io.savemat("z.mat", {"A": np.array(A), "C": np.array(C)}, do_compression=True)
    assert problems.load("z.mat").plant.n == 2  # an honest compressed file loads
    Path("forged.mat").write_bytes(_mat_v5("A", (1, 1), bytes(2**20)))  # 1 MiB behind a 1 x 1 header
    assert Path("forged.mat").stat().st_size < 5_000
    monkeypatch.setattr(problems, "MAX_ARRAY_BYTES", 9000)  # 1 x 600 doubles, counted as complex: 9600
    monkeypatch.setattr(scipy.io, "loadmat", _never)
    with pytest.raises(ProblemFileError, match=r"bigpoles.mat: poles: shape \(1, 600\) of double declares "
                                               r"9600 bytes; at most 9000 per array"):
        problems.load("bigpoles.mat")
    with pytest.raises(ProblemFileError, match="other.mat: X: unknown field for a plant file"):
        problems.load("other.mat")
    monkeypatch.setattr(problems, "MAX_ARRAY_BYTES", 2**16)
    with pytest.raises(ProblemFileError, match=r"forged.mat: A: a compressed variable that expands to more "
                                               r"than 65536 bytes"):
        problems.load("forged.mat")


def test_deep_nesting_and_huge_integers_are_file_errors(capsys):
    Path("deep.json").write_text("[" * 100_000 + "]" * 100_000)   # RecursionError in the parser before
    Path("deep.toml").write_text("A = " + "[" * 100_000 + "]" * 100_000)
    deep = json.loads('{"a": ' * 500 + "1" + "}" * 500)
    write_json("nested.json", {"plant": {"A": A, "C": C}, "data": deep})
    for name in ("deep.json", "deep.toml", "nested.json"):  # nested.json parses; _decode recursed before
        with pytest.raises(ProblemFileError, match=rf"^{name}: nested more than 32 levels deep"):
            problems.load(name)
    Path("digits.json").write_text('{"A": [[' + "1" * 5000 + ']], "C": [[1]]}')
    Path("digits.toml").write_text("A = [[" + "1" * 5000 + "]]\nC = [[1]]\n")
    for name in ("digits.json", "digits.toml"):
        with pytest.raises(ProblemFileError, match=rf"^{name}: a number that cannot be read: an integer of "
                                                   r"more than 4300 digits"):
            problems.load(name)
    code, _, err = run(["kalman", "deep.json"], capsys)
    assert code == 2 and err.count("\n") == 1 and "nested more than 32 levels deep" in err
    assert problems.load_file(write_json("ok.json", {"A": A, "C": C})).plant.n == 2  # a plain one loads


def test_a_nul_byte_in_a_problem_path_is_a_file_error(capsys):
    with pytest.raises(ProblemFileError, match=r"'mine\\x00.json': the path contains a NUL character"):
        problems.load("mine\x00.json")
    with pytest.raises(ProblemFileError, match="NUL character"):
        problems.load_file(Path("a\x00b.npz"))
