"""Which axis is up, one rule for the whole toolkit: :func:`up_axis`, :func:`height`.

The figures, the interactive page and the default "height" fields of ``o3dheat figure`` and
``o3dheat view`` all ask here. A mesh file carries no "up"; the rule is the file format's
convention, stated wherever it is used (a figure's caption, ``index.md``, the page) and overridden
by ``up=`` / ``--up``:

* OBJ, PLY, OFF, glTF/GLB: **y** up, the convention of graphics scans and their tools (the
  Stanford scans, MeshLab's and pymeshlab's samples, Blender's and most scanners' exports);
* STL and any other file: **z** up, the convention of CAD and 3D printing;
* a mesh made in Python (no file): **z** up, Open3D's convention (its primitives lie in the xy
  plane around z).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from o3dheat.errors import MeshError

__all__ = ["AXES", "Y_UP_SUFFIXES", "up_axis", "height"]

AXES = ("x", "y", "z")
#: File suffixes whose convention is y up.
Y_UP_SUFFIXES = (".obj", ".ply", ".off", ".gltf", ".glb")


def up_axis(up: str = "auto", path=None) -> tuple[str, str]:
    """The vertical axis and why: ``up`` itself, or by the rule of the module docstring.

    Parameters
    ----------
    up : {"auto", "x", "y", "z"}
        "auto" applies the rule; an axis is taken as given.
    path : str or Path, optional
        The file the mesh was read from (None: a mesh made in Python).

    Returns
    -------
    axis : {"x", "y", "z"}
    reason : str
        In words, for a caption: e.g. ``"y up (the convention of .obj files; --up to change)"``.

    Examples
    --------
    >>> from o3dheat.geometry.up import up_axis
    >>> up_axis("auto", "bunny.obj")[0], up_axis("auto", "part.stl")[0], up_axis("auto")[0], up_axis("x")
    ('y', 'z', 'z', ('x', 'x up (as asked)'))
    """
    if isinstance(up, str) and up in AXES:
        return up, f"{up} up (as asked)"
    if up != "auto":
        raise MeshError(f"up must be 'auto', 'x', 'y' or 'z', got {up!r}")
    if path is None:
        return "z", "z up (Open3D's convention for a mesh made in Python; up='y' for a y-up scan)"
    suffix = Path(path).suffix.lower() or "(no suffix)"
    if suffix in Y_UP_SUFFIXES:
        return "y", f"y up (the convention of {suffix} files; --up to change)"
    return "z", f"z up (the convention of {suffix} files; --up to change)"


def height(V, up: str) -> np.ndarray:
    """(n,) the coordinate of each vertex along the axis ``up`` ("x", "y" or "z").

    Examples
    --------
    >>> import numpy as np
    >>> from o3dheat.geometry.up import height
    >>> height(np.array([[1.0, 2.0, 3.0]]), "y").tolist()
    [2.0]
    """
    if up not in AXES:
        raise MeshError(f"up must be 'x', 'y' or 'z', got {up!r}")
    return np.asarray(V, dtype=np.float64)[:, AXES.index(up)].copy()
