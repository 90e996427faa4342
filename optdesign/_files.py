"""Writing files without losing data: every file optdesign writes goes through here (private
module, public names; a foundation below every layer, so :mod:`optdesign.plot` and
:mod:`optdesign.studies` both use it).

Rules (issue 26, item 4):

* **No overwriting unasked.**  A file -- or a symbolic link, even a dangling one -- already at an
  output path is an :class:`~optdesign.errors.OutputExistsError` naming it, unless
  ``overwrite=True`` (``--overwrite`` on the command line).
* **Written whole, then renamed.**  A file is written under a temporary name in its own folder
  (``.NAME.XXXXXXXX.tmp.SUFFIX``, created exclusively) and renamed onto its name: a reader never
  sees half a file, and a failed write leaves the old file as it was.  Without ``overwrite`` the
  rename is a hard link that fails if the name was taken meanwhile (or, where the file system has
  no hard links, a check just before :func:`os.replace`).
* **Never through a symbolic link.**  The rename replaces the directory entry, so with
  ``overwrite=True`` a link at the output path is itself replaced by the new file; the file it
  pointed to is left untouched.

Writers: :func:`write_text` for text (tables, CSV, JSON, Markdown), :func:`atomic_path` for any
writer that takes a file name (``fig.savefig(tmp)``, ``numpy.save(tmp, ...)``).
"""

from __future__ import annotations

import contextlib
import os
import secrets
import stat
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

from .errors import OutputExistsError, OutputPathError, ValidationError

__all__ = ["path_text", "check_targets", "atomic_path", "write_text", "as_overwrite", "OVERWRITE_HINT"]

#: how to ask for overwriting, named in every :class:`OutputExistsError`
OVERWRITE_HINT = "overwrite=True, or --overwrite on the command line"


def path_text(name: str, value: Any) -> str:
    """``value`` as a path string; a NUL byte (which no file system takes) refused by ``name``.

    Raises
    ------
    OutputPathError
        Not a string or path-like; bytes; a NUL character.
    """
    if not isinstance(value, (str, os.PathLike)):
        raise OutputPathError(f"{name} must be a path (a string); found {type(value).__name__}")
    text = os.fspath(value)
    if isinstance(text, bytes):
        raise OutputPathError(f"{name} must be a path string; found bytes {text[:40]!r}")
    if "\x00" in text:
        raise OutputPathError(f"{name} contains a NUL character (\\x00), which no file system accepts; "
                              f"found {text[:60]!r}")
    return text


def as_overwrite(value: Any, name: str = "overwrite") -> bool:
    """``overwrite`` must be True or False (a string such as ``"no"`` would be truthy).

    Raises
    ------
    ValidationError
        Anything but a bool (numpy's included).
    """
    if isinstance(value, bool):
        return value
    try:
        import numpy as np
    except ImportError:  # pragma: no cover - numpy is a hard dependency
        np = None  # type: ignore[assignment]
    if np is not None and isinstance(value, np.bool_):
        return bool(value)
    raise ValidationError(f"{name} must be True or False; found {value!r}")


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
                f"not written through it and not replaced ({OVERWRITE_HINT}: replaces the link "
                "itself, never the file it points to)", path=str(path))
        return
    if stat.S_ISDIR(st.st_mode):
        raise OutputPathError(f"{path}: a folder is where a result file is to be written")
    if not overwrite:
        raise OutputExistsError(f"{path}: exists; not overwritten ({OVERWRITE_HINT} replaces it)",
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
        _check_target(Path(path_text("output path", p)), bool(overwrite))


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
    the same folder, exists (empty) when the block starts, and keeps the suffix; it is removed if
    the block raises.

    Raises
    ------
    OutputExistsError
        ``path`` exists (a file or a symbolic link) and ``overwrite`` is False -- checked before
        the block runs and again when the file is put in place.
    OutputPathError
        A NUL byte, a folder at ``path``, a folder that cannot be written.
    ValidationError
        ``overwrite`` not a bool.
    """
    target = Path(path_text("output path", path))
    overwrite = as_overwrite(overwrite)
    _check_target(target, overwrite)
    tmp = _temporary(target)
    try:
        yield tmp
        _commit(tmp, target, overwrite)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise


def write_text(path: str | os.PathLike, text: str, *, overwrite: bool = False,
               newline: str | None = None) -> Path:
    """Write ``text`` (UTF-8) to ``path`` by :func:`atomic_path`; the path.

    Raises
    ------
    OutputExistsError, OutputPathError, ValidationError
        As :func:`atomic_path`.
    """
    with atomic_path(path, overwrite=overwrite) as tmp, tmp.open("w", encoding="utf-8",
                                                                 newline=newline) as fh:
        fh.write(text)
    return Path(path)
