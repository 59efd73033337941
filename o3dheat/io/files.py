"""Atomic file writes: :func:`atomic_write` (binary), :func:`atomic_write_text` (UTF-8); bounded
reads of regular files only: :func:`read_regular`.

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

__all__ = ["atomic_write", "atomic_write_text", "read_regular"]

#: Most bytes :func:`read_regular` reads by default (a chain, a spectrum, a key: far less).
READ_LIMIT = 16 * 2**30

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


def read_regular(path: PathLike, what: str = "file", limit: int = READ_LIMIT) -> bytes:
    """The bytes of ``path``, which must be a regular file (through links) of at most ``limit``
    bytes: a FIFO, a device (``/dev/zero``, ``/dev/urandom``) or a socket would block or never end.

    The file is opened without blocking (``O_NONBLOCK``) and checked on the open descriptor, so a
    FIFO swapped in after a check is still refused; at most ``limit + 1`` bytes are read.

    Parameters
    ----------
    path : str or Path
        The file.
    what : str
        What it is, for the messages ("spectrum file", "chain file", ...).
    limit : int
        Largest size accepted, in bytes.

    Returns
    -------
    bytes

    Raises
    ------
    NoSuchFile
        It does not exist.
    MeshError
        Not a regular file (a FIFO, a device, a socket), or larger than ``limit``.
    OSError
        A folder (``IsADirectoryError``), or it cannot be read (permissions): the file system's error.

    Examples
    --------
    >>> import os, tempfile
    >>> from o3dheat.io.files import read_regular
    >>> p = os.path.join(tempfile.mkdtemp(), "a.txt"); _ = open(p, "w").write("hi")
    >>> read_regular(p)
    b'hi'
    >>> read_regular("/dev/zero", "key file")
    Traceback (most recent call last):
    ...
    o3dheat.errors.MeshError: /dev/zero is not a regular file (a character device): refused as a key file
    """
    import errno
    import stat

    from o3dheat.errors import NoSuchFile

    path = Path(path)
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except FileNotFoundError:
        raise NoSuchFile(f"no such file: {path}") from None
    except IsADirectoryError:
        raise IsADirectoryError(errno.EISDIR, f"{path} is a folder: give a {what}") from None
    try:
        st = os.fstat(fd)
        if stat.S_ISDIR(st.st_mode):  # the file system's error, as open() gives it, with context
            raise IsADirectoryError(errno.EISDIR, f"{path} is a folder: give a {what}")
        if not stat.S_ISREG(st.st_mode):
            kind = ("a FIFO" if stat.S_ISFIFO(st.st_mode) else "a character device" if stat.S_ISCHR(st.st_mode)
                    else "a block device" if stat.S_ISBLK(st.st_mode) else "a socket" if stat.S_ISSOCK(st.st_mode)
                    else "not a file")
            raise MeshError(f"{path} is not a regular file ({kind}): refused as a {what}")
        if st.st_size > limit:
            raise MeshError(f"{path} has {st.st_size:,} bytes, more than a {what} can ({limit:,})")
        chunks, size = [], 0
        while size <= limit:
            chunk = os.read(fd, min(1 << 24, limit + 1 - size))
            if not chunk:
                break
            chunks.append(chunk)
            size += len(chunk)
        if size > limit:
            raise MeshError(f"{path} grew past {limit:,} bytes while read: refused as a {what}")
        return b"".join(chunks)
    finally:
        os.close(fd)
