"""Where studies write, and how: results never overwrite a file, never escape the working folder
unasked, and never write through a symbolic link.

Rules (every writer of :mod:`optdesign.studies` follows them: :meth:`SweepTable.to_csv
<optdesign.studies.sweep.SweepTable.to_csv>`, :meth:`~optdesign.studies.sweep.SweepTable.to_json`,
:func:`~optdesign.studies.spec.run_spec`, ``optdesign study``):

* **No overwriting unasked, written whole, never through a symbolic link**: the writer of every
  file optdesign writes, :mod:`optdesign._files` (:func:`atomic_path`, :func:`write_text`,
  :func:`check_targets`, re-exported here), whose rules apply; with ``optdesign study
  --overwrite`` for ``overwrite=True``.  A study checks all its output paths before the sweep
  starts, so a long run does not end in that error.
* **Inside the working folder unless asked.**  The output folder a *spec file* names
  (``study.output``) must lie inside the current directory -- ``../elsewhere``, an absolute path
  elsewhere, or a symbolic link leading out is an :class:`~optdesign.errors.OutputPathError` --
  unless the caller asks: ``optdesign study --allow-outside`` or ``run_spec(...,
  allow_outside=True)``.  A spec cannot grant this itself (there is no spec field for it): a spec
  is often someone else's file.  A folder given on the command line (``--out DIR``) or to
  ``run_spec(output=...)`` is the caller's own choice and may be anywhere.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from .._files import atomic_path, check_targets, path_text, write_text
from ..errors import OutputPathError

__all__ = ["file_name", "output_folder", "check_targets", "atomic_path", "write_text"]


def file_name(name: str, value: Any) -> str:
    """A bare file name: a string without path separators, NUL or other control characters, not
    ``.`` or ``..``.

    Raises
    ------
    OutputPathError
        Naming ``name``, the expected and the found.
    """
    text = path_text(name, value)
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
    text = path_text(field, path)
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
