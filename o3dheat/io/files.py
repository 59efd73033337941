"""Atomic file writes: :func:`atomic_write` (binary), :func:`atomic_write_text` (UTF-8).

A file is written to a temporary file in its folder, which then replaces it: a reader sees the
old file or the new one, never half of one. Temporary files an interrupted writer left (older
than an hour) are removed by the next write into that folder.
"""

from __future__ import annotations

import logging
import os
import tempfile
import time
from glob import escape as glob_escape
from pathlib import Path
from typing import TYPE_CHECKING

from o3dheat.errors import MeshError

if TYPE_CHECKING:  # o3dheat.typing imports Open3D (1.5 s): for annotations only
    from collections.abc import Callable
    from typing import BinaryIO

    from o3dheat.typing import PathLike

__all__ = ["atomic_write", "atomic_write_text"]

log = logging.getLogger("o3dheat")


def _file_mode(path):
    """The mode a new file gets from open() (0666 less the umask), or the existing file's."""
    try:
        return os.stat(path).st_mode & 0o777
    except OSError:
        mask = os.umask(0)
        os.umask(mask)
        return 0o666 & ~mask


def atomic_write(path: PathLike, write: Callable[[BinaryIO], object]) -> None:
    r"""Write a file atomically: ``write(binary_file)`` goes to a temporary file in the same
    folder, which then replaces ``path``. On any error the temporary file is removed and
    ``path`` is untouched. The file gets the permissions ``open()`` would give it.

    Parameters
    ----------
    path : str or Path
        The file to write (its folder must exist).
    write : callable
        Called once with the open temporary file (binary); what it writes becomes the file.

    Raises
    ------
    MeshError
        The folder does not exist.
    OSError
        The folder is not writable, the disk is full...: the file system's own error (the path
        named), ``path`` untouched.

    Examples
    --------
    >>> import os, tempfile, o3dheat.io as io
    >>> p = os.path.join(tempfile.mkdtemp(), "data.bin")
    >>> io.atomic_write(p, lambda out: out.write(bytes([1, 2, 3])))
    >>> open(p, "rb").read()
    b'\x01\x02\x03'
    >>> def fails(out):
    ...     out.write(b"half")
    ...     raise RuntimeError("interrupted")
    >>> try:
    ...     io.atomic_write(p, fails)
    ... except RuntimeError:
    ...     pass
    >>> open(p, "rb").read(), os.listdir(os.path.dirname(p))    # untouched, no temporary file left
    (b'\x01\x02\x03', ['data.bin'])
    """
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise MeshError(f"cannot write {path}: folder {folder} does not exist")
    _remove_stale(folder, f".{path.name}.")
    try:
        fd, tmp = tempfile.mkstemp(dir=folder, prefix=f".{path.name}.", suffix=".tmp")
    except OSError as e:  # the file system's error, about the target rather than a temporary name
        raise type(e)(e.errno, e.strerror, str(path)) from e
    try:
        with os.fdopen(fd, "wb") as fh:
            write(fh)
        os.chmod(tmp, _file_mode(path))  # mkstemp makes 0600 files: use what open() would
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def _remove_stale(folder, prefix, age=3600.0):
    """Remove the temporary files ``{prefix}*.tmp`` that a killed writer left (older than an hour:
    a live writer finishes sooner), so an interrupted run leaves no litter after the next one."""
    now = time.time()
    for tmp in Path(folder).glob(f"{glob_escape(prefix)}*.tmp"):
        try:
            if now - tmp.stat().st_mtime > age:
                tmp.unlink()
                log.info("removed %s, left by an interrupted write", tmp)
        except OSError:
            pass


def atomic_write_text(path: PathLike, text: str) -> None:
    r"""Write a text file (UTF-8) atomically (see :func:`atomic_write`).

    Parameters
    ----------
    path : str or Path
        The file to write (its folder must exist).
    text : str
        Its contents.

    Examples
    --------
    >>> import os, tempfile, o3dheat.io as io
    >>> p = os.path.join(tempfile.mkdtemp(), "note.txt")
    >>> io.atomic_write_text(p, "λ₂ = 2\n")
    >>> open(p, encoding="utf-8").read()
    'λ₂ = 2\n'
    """
    atomic_write(path, lambda fh: fh.write(text.encode("utf-8")))
