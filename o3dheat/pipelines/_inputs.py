"""A batch's files: the inputs of paths and glob patterns (:func:`expand`), the output of each (:func:`outputs`).

Both are :mod:`o3dheat.pipelines.batch`'s (``batch.expand``, ``batch.outputs``), and documented there.
"""

from __future__ import annotations

import fnmatch
import os
import re
from collections.abc import Sequence
from pathlib import Path

from o3dheat.errors import MeshError, NoSuchFile
from o3dheat.io import WRITERS
from o3dheat.typing import PathLike

#: the file in the output folder that records the chain (a chain file), for resuming
MANIFEST = "o3dheat-batch.toml"
SUFFIXES = tuple(WRITERS)  # the outputs: what o3dheat.io writes


def expand(patterns: PathLike | Sequence[PathLike], exclude: PathLike | None = None) -> list[Path]:
    """The input files of paths and glob patterns.

    Parameters
    ----------
    patterns : str, Path or sequence of them
        Files, or patterns with ``*``, ``?``, ``[...]`` (``**`` matches folders recursively; ``~``
        is the home folder). Folders and hidden files are not matched. Links to folders are
        followed, but each folder is entered once whatever its names (a link loop such as
        ``ln -s . a/self`` ends), by its own name before a link's.
    exclude : str or Path, optional
        A folder that wildcards (``*``, ``**``...) do not enter: :func:`~o3dheat.pipelines.batch.run` gives its output
        folder, so that the outputs of a folder inside the inputs' tree are not taken for inputs
        (a pattern that names the folder, such as ``out/*.ply``, still looks in it).

    Returns
    -------
    list of Path
        Each pattern's matches sorted by name, patterns in the order given, each file once (the
        same file under two names, by links, is the first).

    Raises
    ------
    MeshError
        A pattern that matches no file, a missing file, a folder, or nothing given.

    Examples
    --------
    >>> import os, tempfile
    >>> from o3dheat.pipelines.batch import expand
    >>> d = tempfile.mkdtemp()
    >>> for name in ("b.ply", "a.ply", "c.obj"):
    ...     open(os.path.join(d, name), "w").close()
    >>> [p.name for p in expand([os.path.join(d, "*.ply"), os.path.join(d, "a.ply")])]
    ['a.ply', 'b.ply']
    >>> os.symlink(d, os.path.join(d, "self"))                  # a loop: each folder once
    >>> [p.name for p in expand(os.path.join(d, "**", "*.ply"))]
    ['a.ply', 'b.ply']
    """
    if isinstance(patterns, (str, os.PathLike)):
        patterns = [patterns]
    skip = set()  # the folders wildcards do not enter, as (device, inode)
    if exclude is not None and _key(os.path.expanduser(os.fspath(exclude))) is not None:
        skip.add(_key(os.path.expanduser(os.fspath(exclude))))
    found, seen = [], set()
    for pattern in patterns:
        text = os.path.expanduser(os.fspath(pattern))
        if _MAGIC.search(text):
            pruned = []
            matches = sorted(set(_glob(text, skip, pruned)))
            if not matches:
                why = f" (the output folder {os.fspath(exclude)} is not searched)" if pruned else ""
                raise MeshError(f"no file matches {os.fspath(pattern)!r}{why}")
        elif os.path.isdir(text):
            raise MeshError(f"{text} is a folder: give files or a pattern such as "
                            f"'{os.path.join(text, '*.ply')}'")
        elif not os.path.isfile(text):
            raise NoSuchFile(f"no such file: {text}")
        else:
            matches = [text]
        for m in matches:
            key = _key(m) or os.path.realpath(m)
            if key not in seen:
                seen.add(key)
                found.append(Path(m))
    if not found:
        raise MeshError("no input files given")
    return found


_MAGIC = re.compile(r"[*?[]")


def _key(path):
    """(device, inode) of a file or folder (links followed): the same for all its names; None when
    it cannot be read."""
    try:
        st = os.stat(path)
    except OSError:
        return None
    return st.st_dev, st.st_ino


def _entries(folder):
    """(name, is a folder, is a link) of a folder's entries, sorted by name; none when unreadable."""
    out = []
    try:
        with os.scandir(folder or os.curdir) as it:
            for e in it:
                try:
                    out.append((e.name, e.is_dir(), e.is_symlink()))
                except OSError:
                    pass
    except OSError:
        return []
    return sorted(out)


def _visible(name, part):
    """``glob``'s rule: a name starting with a dot is matched only by a pattern that does."""
    return not name.startswith(".") or part.startswith(".")


def _glob(pattern, skip, pruned):
    """The files that match a glob pattern (``glob.glob(pattern, recursive=True)``'s rules), where
    each ``**`` enters each folder once: links followed, but a folder already entered (by its own
    name or another link) is not entered again, so link loops end. Wildcards do not enter the
    folders of ``skip`` ((device, inode) pairs); ``pruned`` gets those they did not enter."""
    drive, rest = os.path.splitdrive(pattern)
    seps = os.sep + (os.altsep or "")
    root = drive + os.sep if rest[:1] and rest[0] in seps else drive
    parts = [p for p in re.split(f"[{re.escape(seps)}]", rest) if p]
    return list(_match(root, parts, {}, skip, pruned))


def _match(folder, parts, entered, skip, pruned):
    head, rest = parts[0], parts[1:]
    if head == "**":  # zero or more folders; the remaining parts are matched in each
        for d in _folders(folder, entered.setdefault(len(parts), set()), skip, pruned):
            if rest:
                yield from _match(d, rest, entered, skip, pruned)
            else:
                yield from (os.path.join(d, name) for name, is_dir, _ in _entries(d)
                            if not is_dir and _visible(name, "") and os.path.isfile(os.path.join(d, name)))
        return
    magic = _MAGIC.search(head)
    if magic:
        names = [name for name, is_dir, _ in _entries(folder)
                 if (is_dir or not rest) and _visible(name, head) and fnmatch.fnmatch(name, head)]
    else:
        names = [head]
    for name in names:
        path = os.path.join(folder, name)
        if rest:
            if magic and skip and _key(path) in skip:
                pruned.append(path)
            elif os.path.isdir(path):
                yield from _match(path, rest, entered, skip, pruned)
        elif os.path.isfile(path):
            yield path


def _folders(top, entered, skip, pruned):
    """``top`` and the folders under it, each real folder once (``entered``: the (device, inode) of
    those entered, updated); links to folders are followed after the folders' own names, so that a
    folder is named by its path rather than by a link; hidden folders are left out, as by glob, and
    so are those of ``skip`` under ``top`` (added to ``pruned``)."""
    out, roots = [], [top]
    while roots:
        stack = [roots.pop(0)]
        while stack:
            d = stack.pop()
            key = _key(d or os.curdir)
            if key is None or key in entered:
                continue
            if key in skip and out:
                pruned.append(d)
                continue
            entered.add(key)
            out.append(d)
            subs = [(name, link) for name, is_dir, link in _entries(d) if is_dir and _visible(name, "")]
            stack += [os.path.join(d, name) for name, link in reversed(subs) if not link]
            roots += [os.path.join(d, name) for name, link in subs if link]
    return out


def outputs(inputs: Sequence[PathLike], out_dir: PathLike, suffix: str = ".ply") -> list[Path]:
    """The output file of each input, ``out_dir/<stem><suffix>``, checked.

    Raises
    ------
    MeshError
        Two inputs whose outputs have the same name (compared without regard to case), or an
        output that would replace an input.

    Examples
    --------
    >>> from o3dheat.pipelines.batch import outputs
    >>> [str(p) for p in outputs(["scans/a.ply", "scans/b.obj"], "out")]
    ['out/a.ply', 'out/b.ply']
    >>> outputs(["x/a.ply", "y/a.obj"], "out")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    o3dheat.errors.MeshError: x/a.ply and y/a.obj would both be written to out/a.ply: rename one, ...
    """
    if suffix not in SUFFIXES:
        raise MeshError(f"the outputs are .ply or .npz files, got suffix {suffix!r}")
    out_dir = Path(out_dir)
    inputs = [Path(p) for p in inputs]
    dsts, owner = [], {}
    for src in inputs:
        dst = out_dir / (src.stem + suffix)
        key = dst.name.casefold()
        if key in owner:
            raise MeshError(f"{owner[key]} and {src} would both be written to {out_dir / (owner[key].stem + suffix)}: "
                            "rename one, or run them into different folders")
        owner[key] = src
        dsts.append(dst)
    real_inputs = {os.path.realpath(p).casefold(): p for p in inputs}
    for dst in dsts + [out_dir / MANIFEST]:
        src = real_inputs.get(os.path.realpath(dst).casefold())
        if src is None and dst.exists():  # the same file by another name (a link)
            src = next((p for p in inputs if _same_file(p, dst)), None)
        if src is not None:
            what = "the chain record" if dst.name == MANIFEST else "its output"
            raise MeshError(f"refusing to overwrite the input {src} with {what} {dst}: choose another --out folder")
    return dsts


def _same_file(a, b):
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False
