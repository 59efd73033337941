"""The command's output paths, checked before any work: :func:`check_output` (a file),
:func:`check_folder` and :func:`output_folder` (a folder), :func:`same_file`."""

from __future__ import annotations

import os
from pathlib import Path

from o3dheat.errors import MeshError


def same_file(a, b):
    """Whether two paths name the same file (existing or not)."""
    try:
        return a.resolve() == b.resolve() or (a.exists() and b.exists() and a.samefile(b))
    except OSError:
        return False


def check_output(path, overwrite):
    """Refuse, before any computation, an output that is a folder, lies in a missing folder, or
    exists without --overwrite."""
    if path.is_dir():
        raise MeshError(f"{path} is a folder: give a file name")
    if not path.parent.is_dir():
        raise MeshError(f"the folder {path.parent} does not exist: create it first")
    if path.exists() and not overwrite:
        raise MeshError(f"{path} exists: add --overwrite to replace it")


def check_folder(path, option):
    """Refuse, without creating anything, an output folder that cannot be created: a file, or under
    a file or a folder we cannot write in."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise MeshError(f"{path} is a file: {option} takes a folder")
    parent = path
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent
    if parent != path and (not parent.is_dir() or not os.access(parent, os.W_OK | os.X_OK)):
        why = "a file" if not parent.is_dir() else "not writable"
        raise MeshError(f"cannot create the folder {path} ({option}): {parent} is {why}")


def output_folder(path, option):
    """Create an output folder (and its parents) before any computation: a MeshError when it cannot
    be (:func:`check_folder`), the file system's OSError, naming the folder, when creating it fails."""
    check_folder(path, option)
    try:
        Path(path).mkdir(parents=True, exist_ok=True)
    except OSError as e:  # a file-system failure stays one, naming the folder (as batch and study do)
        raise type(e)(e.errno, f"cannot create the folder {path} ({option}): {e.strerror}") from None
