"""Mesh files that keep every vertex attribute: PLY (binary by default) through plyfile, and
other formats (OBJ, OFF, STL, ...) read through Open3D. Writes are atomic.

PLY layout written here: ``x y z`` (float64), ``nx ny nz`` when there are normals, ``red green
blue`` as uchar (what every viewer reads) and, only when the colours are not exact multiples of
1/255, their exact values as ``o3dheat_colors_0..2`` (float64). Any other vertex attribute ``a``
of shape (n,) is a property ``a``; of shape (n, c) it is ``a_0 .. a_{c-1}`` with a header comment
``o3dheat attribute a c`` so that :func:`read_mesh` restores the (n, c) array. Dtypes are kept.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np

from .errors import MeshError

__all__ = ["read_mesh", "write_mesh"]

_RESERVED = {"positions", "normals", "colors"}


def _attributes(mesh):
    import open3d as o3d

    if isinstance(mesh, o3d.geometry.TriangleMesh):
        mesh = o3d.t.geometry.TriangleMesh.from_legacy(mesh)
    if not isinstance(mesh, o3d.t.geometry.TriangleMesh):
        raise MeshError(f"write_mesh needs an Open3D TriangleMesh, got {type(mesh).__name__}")
    attrs = {key: mesh.vertex[key].numpy() for key in mesh.vertex}
    if "indices" not in mesh.triangle:
        raise MeshError("the mesh has no triangles")
    return attrs, mesh.triangle.indices.numpy()


def _file_mode(path):
    """The mode a new file gets from open() (0666 less the umask), or the existing file's."""
    try:
        return os.stat(path).st_mode & 0o777
    except OSError:
        mask = os.umask(0)
        os.umask(mask)
        return 0o666 & ~mask


def write_mesh(path, mesh, binary=True):
    """Write a mesh and all its vertex attributes to a PLY file, atomically.

    Parameters
    ----------
    path : str or Path
        Output file; must end in ``.ply``.
    mesh : o3d.t.geometry.TriangleMesh or o3d.geometry.TriangleMesh
    binary : bool
        Binary little-endian (default) or ASCII PLY.

    Raises
    ------
    MeshError
        Wrong extension, no triangles, an attribute of the wrong length, or an unwritable path.
        The target is never left half-written.

    Examples
    --------
    >>> import tempfile, os, open3d as o3d, o3dheat.io as io
    >>> m = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 8)
    >>> p = os.path.join(tempfile.mkdtemp(), "s.ply")
    >>> io.write_mesh(p, m); len(io.read_mesh(p).vertex.positions)
    114
    """
    from plyfile import PlyData, PlyElement

    path = Path(path)
    if path.suffix.lower() != ".ply":
        raise MeshError(f"write_mesh writes PLY: {path} should end in .ply")
    attrs, F = _attributes(mesh)
    V = attrs["positions"]
    n = len(V)
    fields, cols, comments = [], [], []
    fields += [("x", "f8"), ("y", "f8"), ("z", "f8")]
    cols += [V[:, 0], V[:, 1], V[:, 2]]
    for key, arr in attrs.items():
        if key == "positions":
            continue
        if len(arr) != n:
            raise MeshError(f"vertex attribute {key!r} has {len(arr)} rows, the mesh {n} vertices")
        if key == "normals":
            fields += [("nx", "f8"), ("ny", "f8"), ("nz", "f8")]
            cols += [arr[:, 0], arr[:, 1], arr[:, 2]]
        elif key == "colors":
            c = np.asarray(arr, dtype=np.float64)
            u8 = np.clip(np.round(c * 255), 0, 255).astype(np.uint8)
            fields += [("red", "u1"), ("green", "u1"), ("blue", "u1")]
            cols += [u8[:, 0], u8[:, 1], u8[:, 2]]
            if arr.dtype != np.float32 or not np.array_equal((u8 / 255.0).astype(arr.dtype), arr):
                comments.append(f"o3dheat attribute o3dheat_colors 3 {arr.dtype.str}")
                fields += [(f"o3dheat_colors_{j}", arr.dtype.str) for j in range(3)]
                cols += [arr[:, j] for j in range(3)]
        elif arr.ndim == 1:
            fields.append((key, arr.dtype.str))
            cols.append(arr)
        else:
            a2 = arr.reshape(n, -1)
            comments.append(f"o3dheat attribute {key} {a2.shape[1]} {arr.dtype.str}")
            fields += [(f"{key}_{j}", arr.dtype.str) for j in range(a2.shape[1])]
            cols += [a2[:, j] for j in range(a2.shape[1])]
    vert = np.empty(n, dtype=[(nm, np.dtype(dt).newbyteorder("<").str) for nm, dt in fields])
    for (nm, _), col in zip(fields, cols):
        vert[nm] = col
    face = np.empty(len(F), dtype=[("vertex_indices", "i4", (3,))])
    face["vertex_indices"] = F
    ply = PlyData([PlyElement.describe(vert, "vertex"), PlyElement.describe(face, "face")],
                  text=not binary, comments=comments)
    atomic_write(path, ply.write)


def atomic_write(path, write):
    """Write a file atomically: ``write(binary_file)`` goes to a temporary file in the same
    folder, which then replaces ``path``. On any error the temporary file is removed and
    ``path`` is untouched. The file gets the permissions ``open()`` would give it.

    Raises
    ------
    MeshError
        The folder does not exist or is not writable.
    """
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise MeshError(f"cannot write {path}: folder {folder} does not exist")
    try:
        fd, tmp = tempfile.mkstemp(dir=folder, prefix=f".{path.name}.", suffix=".tmp")
    except OSError as e:
        raise MeshError(f"cannot write {path}: {e.strerror}") from e
    try:
        with os.fdopen(fd, "wb") as fh:
            write(fh)
        os.chmod(tmp, _file_mode(path))  # mkstemp makes 0600 files: use what open() would
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def atomic_write_text(path, text):
    """Write a text file (UTF-8) atomically (see :func:`atomic_write`)."""
    atomic_write(path, lambda fh: fh.write(text.encode("utf-8")))


def read_mesh(path):
    """Read a mesh with all its vertex attributes.

    Parameters
    ----------
    path : str or Path
        PLY (every vertex property is kept, multi-column attributes written by
        :func:`write_mesh` are restored), or any format Open3D reads (OBJ, OFF, STL, GLB...).

    Returns
    -------
    o3d.t.geometry.TriangleMesh

    Raises
    ------
    MeshError
        Missing, unreadable or truncated file, or one with no triangles.

    Examples
    --------
    >>> import tempfile, os, numpy as np, open3d as o3d, o3dheat.io as io
    >>> m = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 8)
    >>> m.vertex["f"] = o3d.core.Tensor(np.arange(114.0))
    >>> p = os.path.join(tempfile.mkdtemp(), "s.ply"); io.write_mesh(p, m)
    >>> io.read_mesh(p).vertex["f"].numpy()[:3].tolist()
    [0.0, 1.0, 2.0]
    """
    import open3d as o3d

    path = Path(path)
    if not path.is_file():
        raise MeshError(f"no such file: {path}")
    if path.suffix.lower() != ".ply":
        legacy = o3d.io.read_triangle_mesh(str(path))
        if len(legacy.triangles) == 0:
            raise MeshError(f"{path}: no triangles could be read (unreadable or empty file)")
        return o3d.t.geometry.TriangleMesh.from_legacy(legacy)
    from plyfile import PlyData

    try:
        ply = PlyData.read(str(path))
        vert = ply["vertex"].data
        face = ply["face"].data
    except Exception as e:
        raise MeshError(f"{path}: not a readable PLY mesh ({type(e).__name__}: {e})") from e
    names = list(vert.dtype.names)
    multi = {}
    for c in ply.comments:
        parts = c.split()
        if len(parts) >= 4 and parts[:2] == ["o3dheat", "attribute"]:
            multi[parts[2]] = int(parts[3])
    fkey = "vertex_indices" if "vertex_indices" in face.dtype.names else face.dtype.names[0]
    try:
        F = np.stack(face[fkey]).astype(np.int64)
    except ValueError as e:
        raise MeshError(f"{path}: faces are not all triangles") from e
    if F.ndim != 2 or F.shape[1] != 3:
        raise MeshError(f"{path}: faces are not all triangles")
    mesh = o3d.t.geometry.TriangleMesh()
    mesh.vertex.positions = o3d.core.Tensor(np.stack([vert["x"], vert["y"], vert["z"]], 1).astype(np.float64))
    mesh.triangle.indices = o3d.core.Tensor(F)
    used = {"x", "y", "z"}
    if {"nx", "ny", "nz"} <= set(names):
        mesh.vertex.normals = o3d.core.Tensor(np.stack([vert["nx"], vert["ny"], vert["nz"]], 1))
        used |= {"nx", "ny", "nz"}
    for key, c in multi.items():
        cols = [f"{key}_{j}" for j in range(c)]
        if not set(cols) <= set(names):
            continue
        arr = np.stack([vert[nm] for nm in cols], 1)
        used |= set(cols)
        mesh.vertex["colors" if key == "o3dheat_colors" else key] = o3d.core.Tensor(np.ascontiguousarray(arr))
    if {"red", "green", "blue"} <= set(names):
        used |= {"red", "green", "blue"}
        if "colors" not in mesh.vertex:
            rgb = np.stack([vert["red"], vert["green"], vert["blue"]], 1)
            scale = 255.0 if rgb.dtype == np.uint8 else (65535.0 if rgb.dtype == np.uint16 else 1.0)
            mesh.vertex.colors = o3d.core.Tensor((rgb / scale).astype(np.float32))
    for nm in names:
        if nm not in used:
            mesh.vertex[nm] = o3d.core.Tensor(np.ascontiguousarray(vert[nm]))
    return mesh
