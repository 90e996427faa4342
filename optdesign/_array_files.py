"""Reading the arrays of binary problem files -- ``.npz`` and MATLAB ``.mat`` -- with the memory
bounded before anything is expanded (private: :func:`optdesign.problems.load_file` calls it with
the limits of :mod:`optdesign.problems`).

Nothing is read before its size is known: the number of members of a zip archive (its end
record), each ``.npy`` header's shape and dtype and the zip's own record of the expanded size; each
MATLAB variable's class and shape (:func:`scipy.io.whosmat`) and, before that, the expanded size
of every compressed variable, counted by streaming it through zlib (a header may state a small
shape over a large body, and :func:`scipy.io.whosmat` itself expands a whole compressed block to
read one header).  Unknown members are refused before they are read; no pickle.
"""

from __future__ import annotations

import math
import os
import struct
import zipfile
import zlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .errors import ProblemFileError

__all__ = ["Limits", "file_error", "check_size", "read_npz", "read_mat"]


@dataclass(frozen=True)
class Limits:
    """What a binary problem file may hold.

    Attributes
    ----------
    dimension : int
        The largest dimension of a matrix (:data:`optdesign.problems.MAX_DIMENSION`).
    array_bytes, expanded_bytes : int
        The largest array, and all arrays together, once expanded (bytes;
        :data:`optdesign.problems.MAX_ARRAY_BYTES`, :data:`optdesign.problems.MAX_EXPANDED_BYTES`).
    fields : tuple of str
        The member names accepted (anything else is refused before it is read).
    matrices : tuple of str
        The members that are matrices (their dimensions checked against ``dimension``).
    """

    dimension: int
    array_bytes: int
    expanded_bytes: int
    fields: tuple[str, ...]
    matrices: tuple[str, ...]


def file_error(src: str, fieldname: str | None, msg: str) -> ProblemFileError:
    """One line naming the file and the field: ``mine.npz: A: ...``."""
    msg = " ".join(str(msg).split())
    return ProblemFileError(f"{src}: {fieldname}: {msg}" if fieldname else f"{src}: {msg}")


def check_size(src: str, fieldname: str, shape: tuple[int, ...], limit: int) -> None:
    """Every dimension of ``shape`` at most ``limit``."""
    big = [d for d in shape if d > limit]
    if big:
        raise file_error(src, fieldname, f"shape {shape} exceeds the size limit: every dimension must be "
                                         f"<= {limit} (optdesign.problems.MAX_DIMENSION)")


def _check_expanded(src: str, name: str, nbytes: int, what: str, total: int, limits: Limits) -> int:
    """``nbytes`` (an array's declared or expanded size) within ``limits.array_bytes``, and the
    running ``total + nbytes`` within ``limits.expanded_bytes``; the new total."""
    if nbytes > limits.array_bytes:
        raise file_error(src, name, f"{what} {nbytes} bytes; at most {limits.array_bytes} per array "
                                    "(optdesign.problems.MAX_ARRAY_BYTES): nothing was expanded")
    total += nbytes
    if total > limits.expanded_bytes:
        raise file_error(src, name, f"the arrays expand to more than {limits.expanded_bytes} bytes in all "
                                    "(optdesign.problems.MAX_EXPANDED_BYTES): nothing was expanded")
    return total


def _unknown_member(src: str, name: str, limits: Limits) -> ProblemFileError:
    return file_error(src, name, f"unknown field for a plant file ({', '.join(limits.fields)})")


def _zip_entries(path: Path) -> int | None:
    """The number of members a zip archive declares (its end-of-central-directory record), read
    before :class:`zipfile.ZipFile` builds one object per member; None if there is no such record
    (not a zip archive: :class:`zipfile.ZipFile` says so)."""
    with path.open("rb") as fh:
        fh.seek(0, os.SEEK_END)
        size = fh.tell()
        fh.seek(max(0, size - (22 + 65535)))
        tail = fh.read()
    at = tail.rfind(b"PK\x05\x06")
    if at < 0 or len(tail) - at < 22:
        return None
    return struct.unpack("<H", tail[at + 10: at + 12])[0]


#: the largest .npy header numpy reads (``numpy.lib.format``'s default ``max_header_size``)
_NPY_HEADER_MAX = 10000


def _npz_shapes(path: Path, src: str, limits: Limits) -> dict[str, tuple[tuple[int, ...], np.dtype]]:
    """Shape and dtype of every array of an ``.npz`` from the ``.npy`` headers, each member's name
    and its declared and expanded sizes checked (nothing is expanded beyond its header)."""
    out = {}
    try:
        entries = _zip_entries(path)
        if entries is not None and entries > len(limits.fields):
            raise file_error(src, None, f"an archive of {entries} members; a plant file has at most "
                                        f"{len(limits.fields)} ({', '.join(limits.fields)})")
        total = 0
        with zipfile.ZipFile(path) as zf:
            for info in zf.infolist():
                if not info.filename.endswith(".npy"):
                    raise file_error(src, info.filename, "not an array (.npz members are .npy files)")
                name = info.filename[:-4]
                if name not in limits.fields:
                    raise _unknown_member(src, name, limits)
                # the member's expanded size as the archive states it (the reader stops there)
                if info.file_size > limits.array_bytes + _NPY_HEADER_MAX:
                    _check_expanded(src, name, info.file_size, "the member expands to", 0, limits)
                with zf.open(info) as fh:
                    version = np.lib.format.read_magic(fh)
                    read = (np.lib.format.read_array_header_1_0 if version == (1, 0)
                            else np.lib.format.read_array_header_2_0)
                    shape, _, dtype = read(fh)
                    header = fh.tell()
                shape = tuple(int(d) for d in shape)
                if dtype.hasobject:
                    raise file_error(src, name, "an object array (it would need pickle, which is not used); "
                                                 "save numbers or strings")
                if name in limits.matrices:
                    check_size(src, name, shape, limits.dimension)
                declared = math.prod(shape) * dtype.itemsize
                total = _check_expanded(src, name, declared, f"shape {shape} of {dtype} declares", total,
                                        limits)
                if declared > info.file_size - header:
                    held = max(info.file_size - header, 0)
                    raise file_error(src, name, f"shape {shape} of {dtype} declares {declared} bytes but "
                                                 f"the member holds {held}: a truncated or forged array")
                out[name] = (shape, dtype)
    except (zipfile.BadZipFile, ValueError, OSError) as exc:
        if isinstance(exc, ProblemFileError):
            raise
        raise file_error(src, None, f"not a readable .npz archive ({exc})") from None
    return out


def read_npz(path: Path, src: str, limits: Limits) -> dict[str, Any]:
    """The arrays of an ``.npz`` problem file, every member's name, declared shape x dtype and
    expanded size checked first (``_npz_shapes``); never unpickled."""
    _npz_shapes(path, src, limits)
    try:
        with np.load(path, allow_pickle=False) as data:
            return {k: data[k] for k in data.files}
    except (ValueError, OSError, zipfile.BadZipFile) as exc:
        raise file_error(src, None, f"cannot read the arrays: {exc}") from None


#: bytes per element of a MATLAB class once read (double / single counted as complex: whosmat does
#: not say; text as numpy's 4-byte characters)
_MAT_ITEM_BYTES = {"double": 16, "single": 8, "logical": 1, "char": 4, "int8": 1, "uint8": 1, "int16": 2,
                   "uint16": 2, "int32": 4, "uint32": 4, "int64": 8, "uint64": 8}
_MI_COMPRESSED = 15


def _mat_name(start: bytes, order: str) -> str | None:
    """The name of a MATLAB v5 variable from the first bytes of its (expanded) miMATRIX element:
    its tag, the array flags, the dimensions, then the name (None if they are not there)."""
    try:
        at = 8 + 16  # the miMATRIX tag, the array flags element
        _, nbytes = struct.unpack_from(order + "II", start, at)
        at += 8 + nbytes + (-nbytes % 8)  # the dimensions element
        tag = struct.unpack_from(order + "I", start, at)[0]
        if tag >> 16:  # small data element: the name's length in the upper half, its bytes next
            return start[at + 4: at + 4 + (tag >> 16)].decode("latin1")
        nbytes = struct.unpack_from(order + "I", start, at + 4)[0]
        return start[at + 8: at + 8 + min(nbytes, 64)].decode("latin1") or None
    except (struct.error, UnicodeDecodeError):
        return None


def _mat_compressed_sizes(path: Path, src: str, limits: Limits) -> None:
    """Stream every compressed variable of a MATLAB v5/v7 file through zlib, counting its expanded
    bytes (kept: at most 1 MiB at a time), and refuse one beyond ``limits.array_bytes`` or a total
    beyond ``limits.expanded_bytes``.  Run before :func:`scipy.io.whosmat`, which expands a whole
    compressed block (up to ~250 MB of zeros) to read one header, and before
    :func:`scipy.io.loadmat`, which expands a variable's body whatever shape its header states."""
    limit = limits.array_bytes + 2**16  # the array and its headers (name, dimensions, flags)
    total = 0
    with path.open("rb") as fh:
        head = fh.read(128)
        if len(head) < 128 or head[126:128] not in (b"IM", b"MI"):
            return  # v4 (no compression) or not MATLAB: scipy.io says which
        order = "<" if head[126:128] == b"IM" else ">"
        index = 0
        while True:
            tag = fh.read(8)
            if len(tag) < 8:
                return
            mdtype, nbytes = struct.unpack(order + "II", tag)
            index += 1
            if mdtype >> 16:  # a small data element (4 bytes of data in the tag): not a variable
                continue
            if mdtype != _MI_COMPRESSED:
                fh.seek(nbytes + (-nbytes % 8), os.SEEK_CUR)
                continue
            z = zlib.decompressobj()
            left, expanded, start = nbytes, 0, b""
            while left > 0 and not z.eof:
                chunk = fh.read(min(left, 2**20))
                if not chunk:
                    break
                left -= len(chunk)
                while chunk and not z.eof:
                    out = z.decompress(chunk, 2**20)
                    start = start or out[:256]
                    expanded += len(out)
                    chunk = z.unconsumed_tail
                    if expanded > limit:
                        where = _mat_name(start, order) or f"variable {index}"
                        raise file_error(src, where, "a compressed variable that expands to more than "
                                          f"{limits.array_bytes} bytes (optdesign.problems.MAX_ARRAY_BYTES): "
                                          "refused before reading")
            total += expanded
            if total > limits.expanded_bytes:
                raise file_error(src, None, f"the variables expand to more than {limits.expanded_bytes} "
                                             "bytes in all (optdesign.problems.MAX_EXPANDED_BYTES)")
            fh.seek(left, os.SEEK_CUR)


def read_mat(path: Path, src: str, limits: Limits) -> dict[str, Any]:
    """The variables of a MATLAB v4-v7 problem file: compressed sizes counted first
    (``_mat_compressed_sizes``), then every variable's class, name and declared size
    (:func:`scipy.io.whosmat`), then only the known variables loaded."""
    import scipy.io

    try:
        _mat_compressed_sizes(path, src, limits)
    except (OSError, struct.error, zlib.error) as exc:
        raise file_error(src, None, f"not a readable MATLAB file ({exc})") from None
    try:
        info = scipy.io.whosmat(path)
    except NotImplementedError:
        raise file_error(src, None, "MATLAB v7.3 (HDF5) files are not supported; save with "
                                     "save(..., '-v7')") from None
    except (ValueError, OSError, TypeError, zlib.error) as exc:
        raise file_error(src, None, f"not a readable MATLAB file ({exc})") from None
    total = 0
    for name, shape, cls in info:
        if cls not in ("double", "single", "char", "logical") and not cls.startswith(("int", "uint")):
            raise file_error(src, name, f"a MATLAB {cls} (expected a numeric matrix, or text for name "
                                         "and title)")
        if name not in limits.fields:
            raise _unknown_member(src, name, limits)
        if name in limits.matrices:
            check_size(src, name, tuple(shape), limits.dimension)
        declared = math.prod(int(d) for d in shape) * _MAT_ITEM_BYTES.get(cls, 8)
        total = _check_expanded(src, name, declared, f"shape {tuple(shape)} of {cls} declares", total,
                                limits)
    try:
        data = scipy.io.loadmat(path, squeeze_me=False, chars_as_strings=True,
                                variable_names=[name for name, _, _ in info])
    except (ValueError, OSError, TypeError, NotImplementedError, zlib.error) as exc:
        raise file_error(src, None, f"cannot read the variables: {exc}") from None
    return {k: v for k, v in data.items() if not k.startswith("__")}
