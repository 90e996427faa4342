"""Where studies write, and how: results never overwrite a file, never escape the working folder
unasked, and never write through a symbolic link.

Rules (every writer of :mod:`optdesign.studies` follows them: :meth:`SweepTable.to_csv
<optdesign.studies.sweep.SweepTable.to_csv>`, :meth:`~optdesign.studies.sweep.SweepTable.to_json`,
:func:`~optdesign.studies.spec.run_spec`, ``optdesign study``):

* **No overwriting unasked.**  A file -- or a symbolic link, even a dangling one -- already at an
  output path is an :class:`~optdesign.errors.OutputExistsError` naming it, unless
  ``overwrite=True`` (``optdesign study --overwrite``).  A study checks all its output paths before
  the sweep starts, so a long run does not end in that error.
* **Written whole, then renamed.**  A file is written under a temporary name in its own folder
  (``.NAME.XXXXXXXX.tmp.SUFFIX``, created exclusively) and renamed onto its name: a reader never
  sees half a file, and a failed write leaves the old file as it was.  Without ``overwrite`` the
  rename is a hard link that fails if the name was taken meanwhile (or, where the file system has
  no hard links, a check just before :func:`os.replace`).
* **Never through a symbolic link.**  The rename replaces the directory entry, so with
  ``overwrite=True`` a link at the output path is itself replaced by the new file; the file it
  pointed to is left untouched.
* **Inside the working folder unless asked.**  The output folder a *spec file* names
  (``study.output``) must lie inside the current directory -- ``../elsewhere``, an absolute path
  elsewhere, or a symbolic link leading out is an :class:`~optdesign.errors.OutputPathError` --
  unless the caller asks: ``optdesign study --allow-outside`` or ``run_spec(...,
  allow_outside=True)``.  A spec cannot grant this itself (there is no spec field for it): a spec
  is often someone else's file.  A folder given on the command line (``--out DIR``) or to
  ``run_spec(output=...)`` is the caller's own choice and may be anywhere.
"""

from __future__ import annotations

import contextlib
import os
import secrets
import stat
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

from ..errors import OutputExistsError, OutputPathError

__all__ = ["file_name", "output_folder", "check_targets", "atomic_path", "write_text"]

_OVERWRITE_HINT = "overwrite=True, or optdesign study --overwrite"


def _path_text(name: str, value: Any) -> str:
    """``value`` as a path string; a NUL byte (which no file system takes) refused by ``name``."""
    if not isinstance(value, (str, os.PathLike)):
        raise OutputPathError(f"{name} must be a path (a string); found {type(value).__name__}")
    text = os.fspath(value)
    if isinstance(text, bytes):
        raise OutputPathError(f"{name} must be a path string; found bytes {text[:40]!r}")
    if "\x00" in text:
        raise OutputPathError(f"{name} contains a NUL character (\\x00), which no file system accepts; "
                              f"found {text[:60]!r}")
    return text


def file_name(name: str, value: Any) -> str:
    """A bare file name: a string without path separators, NUL or other control characters, not
    ``.`` or ``..``.

    Raises
    ------
    OutputPathError
        Naming ``name``, the expected and the found.
    """
    text = _path_text(name, value)
    if (not text.strip() or text in (".", "..") or "/" in text or "\\" in text
            or any(ord(c) < 32 or ord(c) == 127 for c in text)):
        raise OutputPathError(f"{name} must be a file name without slashes or control characters; "
                              f"found {text[:60]!r}")
    return text


def _inside(path: Path, folder: Path) -> bool:
    try:
        path.relative_to(folder)
    except ValueError:
        return False
    return True


def output_folder(path: str | os.PathLike, *, allow_outside: bool = False, field: str = "output",
                  create: bool = True) -> Path:
    """The output folder ``path`` (relative to the current directory), checked and created.

    Parameters
    ----------
    path : str or path
    allow_outside : bool, default False
        Accept a folder outside the current directory (after ``..`` and symbolic links are
        resolved).
    field : str
        What to call ``path`` in an error (``"--out"``, ``"study.toml: study.output"``).
    create : bool, default True
        Create the folder (and its parents) when missing.

    Returns
    -------
    Path
        ``path`` as given (relative stays relative).

    Raises
    ------
    OutputPathError
        A NUL byte; outside the current directory without ``allow_outside``; a file (not a
        folder) in the way, or a folder that cannot be created or written.
    """
    text = _path_text(field, path)
    if not text.strip():
        raise OutputPathError(f"{field} must name a folder; found {text!r}")
    out = Path(text)
    here = Path.cwd().resolve()
    where = (here / out).resolve()
    if not allow_outside and not _inside(where, here):
        raise OutputPathError(
            f"{field} {text}: outside the working folder {here} (it resolves to {where}); ask for it "
            "explicitly (optdesign study --allow-outside, run_spec(..., allow_outside=True)) or give "
            "the folder itself (--out DIR)")
    if create:
        try:
            out.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise OutputPathError(f"{field} {text}: cannot create the folder ({exc.strerror or exc})") \
                from None
        if not out.is_dir() or not os.access(out, os.W_OK):
            raise OutputPathError(f"{field} {text}: not a writable folder")
    return out


def _check_target(path: Path, overwrite: bool) -> None:
    try:
        st = path.lstat()
    except FileNotFoundError:
        return
    except OSError as exc:
        raise OutputPathError(f"{path}: cannot check the output path ({exc.strerror or exc})") from None
    if stat.S_ISLNK(st.st_mode):
        if not overwrite:
            raise OutputExistsError(
                f"{path}: a symbolic link (to {os.readlink(path)}) is where a result is to be written; "
                f"not written through it and not replaced ({_OVERWRITE_HINT}: replaces the link "
                "itself, never the file it points to)", path=str(path))
        return
    if stat.S_ISDIR(st.st_mode):
        raise OutputPathError(f"{path}: a folder is where a result file is to be written")
    if not overwrite:
        raise OutputExistsError(f"{path}: exists; not overwritten ({_OVERWRITE_HINT} replaces it)",
                                path=str(path))


def check_targets(paths: Iterable[str | os.PathLike], *, overwrite: bool = False) -> None:
    """Check output paths before any work: none may exist (file or symbolic link) unless
    ``overwrite``, and none may be a folder.

    Raises
    ------
    OutputExistsError
        The first path that exists (``overwrite`` False).
    OutputPathError
        A NUL byte, or a folder at a path.
    """
    for p in paths:
        _check_target(Path(_path_text("output path", p)), bool(overwrite))


def _temporary(path: Path) -> Path:
    """A new, empty file next to ``path`` (created exclusively, never through a link; the mode of
    an ordinary new file), keeping the suffix so that writers choosing a format by it still do."""
    for _ in range(100):
        tmp = path.with_name(f".{path.stem}.{secrets.token_hex(4)}.tmp{path.suffix}")
        flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0)
        try:
            os.close(os.open(tmp, flags, 0o666))
        except FileExistsError:
            continue
        except OSError as exc:
            raise OutputPathError(f"{path}: cannot write in {path.parent} ({exc.strerror or exc})") \
                from None
        return tmp
    raise OutputPathError(f"{path}: no free temporary name in {path.parent}")  # pragma: no cover


def _commit(tmp: Path, path: Path, overwrite: bool) -> None:
    """Move the finished ``tmp`` onto ``path``: atomically, replacing a file or link only with
    ``overwrite``."""
    if overwrite:
        _check_target(path, True)  # a folder may have appeared meanwhile
        os.replace(tmp, path)
        return
    try:
        os.link(tmp, path)  # fails if the name is taken: no window between check and write
    except FileExistsError:
        _check_target(path, False)
        raise  # pragma: no cover - _check_target raises for anything that exists
    except OSError:  # no hard links on this file system: check, then rename
        _check_target(path, False)
        os.replace(tmp, path)
        return
    tmp.unlink()


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, *, overwrite: bool = False) -> Iterator[Path]:
    """A temporary file to write ``path``'s content into; on success it becomes ``path``.

    ``with atomic_path("out/kappa2.png") as tmp: fig.savefig(tmp)``.  The temporary file sits in
    the same folder and keeps the suffix; it is removed if the block raises.

    Raises
    ------
    OutputExistsError
        ``path`` exists (a file or a symbolic link) and ``overwrite`` is False -- checked before
        the block runs and again when the file is put in place.
    OutputPathError
        A NUL byte, a folder at ``path``, a folder that cannot be written.
    """
    target = Path(_path_text("output path", path))
    _check_target(target, bool(overwrite))
    tmp = _temporary(target)
    try:
        yield tmp
        _commit(tmp, target, bool(overwrite))
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise


def write_text(path: str | os.PathLike, text: str, *, overwrite: bool = False,
               newline: str | None = None) -> Path:
    """Write ``text`` (UTF-8) to ``path`` by :func:`atomic_path`; the path.

    Raises
    ------
    OutputExistsError, OutputPathError
        As :func:`atomic_path`.
    """
    with atomic_path(path, overwrite=overwrite) as tmp, tmp.open("w", encoding="utf-8",
                                                                 newline=newline) as fh:
        fh.write(text)
    return Path(path)
