"""Mesh and point-cloud files that keep every vertex attribute, and atomic writes.

Formats: PLY (binary by default) through plyfile, ``.npz`` (numpy), and for reading only every
format Open3D reads (OBJ, OFF, STL, GLB, PCD, XYZ...).

PLY layout written here: ``x y z`` (float64), ``nx ny nz`` when there are normals, ``red green
blue`` as uchar (what every viewer reads) and, only when the colours are not exact multiples of
1/255, their exact values as ``o3dheat_colors_0..2`` (float64). Any other vertex attribute ``a``
of shape (n,) is a property ``a``; of shape (n, c) it is ``a_0 .. a_{c-1}`` with a header comment
``o3dheat attribute a c`` so that :func:`read_mesh` restores the (n, c) array. Dtypes are kept.
A PLY without a face element is a point cloud.

``.npz`` layout: ``positions`` and ``indices`` (meshes), and every other attribute ``a`` as
``vertex_a`` with its shape and dtype.
"""

from __future__ import annotations

import logging
import os
import tempfile
from pathlib import Path

import numpy as np

from .errors import MeshError

log = logging.getLogger("o3dheat")

__all__ = ["read_mesh", "write_mesh", "read_geometry", "write_geometry", "atomic_write", "atomic_write_text"]

_RESERVED = {"positions", "normals", "colors"}


def _attributes(geometry, need_faces=True):
    """({name: (n, ...) array}, faces (m, 3) or None) of an Open3D mesh or point cloud."""
    import open3d as o3d

    if isinstance(geometry, o3d.geometry.TriangleMesh):
        geometry = o3d.t.geometry.TriangleMesh.from_legacy(geometry)
    elif isinstance(geometry, o3d.geometry.PointCloud):
        geometry = o3d.t.geometry.PointCloud.from_legacy(geometry)
    if isinstance(geometry, o3d.t.geometry.TriangleMesh):
        attrs = {key: geometry.vertex[key].numpy() for key in geometry.vertex}
        if "indices" not in geometry.triangle:
            raise MeshError("the mesh has no triangles")
        F = geometry.triangle.indices.numpy()
    elif isinstance(geometry, o3d.t.geometry.PointCloud) and not need_faces:
        attrs = {key: geometry.point[key].numpy() for key in geometry.point}
        F = None
    else:
        raise MeshError(f"expected an Open3D TriangleMesh{'' if need_faces else ' or PointCloud'}, "
                        f"got {type(geometry).__name__}")
    if "positions" not in attrs:
        raise MeshError("the geometry has no vertex positions")
    n = len(attrs["positions"])
    for key, arr in attrs.items():
        if len(arr) != n:
            raise MeshError(f"vertex attribute {key!r} has {len(arr)} rows, the geometry {n} vertices")
    return attrs, F


def _file_mode(path):
    """The mode a new file gets from open() (0666 less the umask), or the existing file's."""
    try:
        return os.stat(path).st_mode & 0o777
    except OSError:
        mask = os.umask(0)
        os.umask(mask)
        return 0o666 & ~mask


def write_mesh(path, mesh, binary=True, overwrite=True):
    """Write a mesh and all its vertex attributes to a PLY or ``.npz`` file, atomically.

    Parameters
    ----------
    path : str or Path
        Output file ending in ``.ply`` or ``.npz``.
    mesh : o3d.t.geometry.TriangleMesh or o3d.geometry.TriangleMesh
    binary : bool
        PLY only: binary little-endian (default) or ASCII.
    overwrite : bool
        False refuses to replace an existing file.

    Raises
    ------
    MeshError
        Wrong extension, no triangles, an attribute of the wrong length, an existing file with
        ``overwrite=False``, or an unwritable path. The target is never left half-written.

    Examples
    --------
    >>> import tempfile, os, open3d as o3d, o3dheat.io as io
    >>> m = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 8)
    >>> p = os.path.join(tempfile.mkdtemp(), "s.ply")
    >>> io.write_mesh(p, m); len(io.read_mesh(p).vertex.positions)
    114
    """
    _write(path, *_attributes(mesh, need_faces=True), binary=binary, overwrite=overwrite)


def write_geometry(path, geometry, binary=True, overwrite=True):
    """Like :func:`write_mesh` for a mesh or a point cloud (a PLY or ``.npz`` without faces).

    Examples
    --------
    >>> import tempfile, os, numpy as np, open3d as o3d, o3dheat.io as io
    >>> pc = o3d.t.geometry.PointCloud(o3d.core.Tensor(np.eye(3)))
    >>> p = os.path.join(tempfile.mkdtemp(), "p.npz"); io.write_geometry(p, pc)
    >>> type(io.read_geometry(p)).__name__
    'PointCloud'
    """
    _write(path, *_attributes(geometry, need_faces=False), binary=binary, overwrite=overwrite)


def _write(path, attrs, F, binary, overwrite):
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in (".ply", ".npz"):
        raise MeshError(f"o3dheat writes PLY or NPZ: {path} should end in .ply or .npz")
    if not overwrite and path.exists():
        raise MeshError(f"{path} exists (not overwritten)")
    if suffix == ".npz":
        arrays = {"positions": attrs["positions"]}
        if F is not None:
            arrays["indices"] = F
        arrays.update({f"vertex_{k}": v for k, v in attrs.items() if k != "positions"})
        atomic_write(path, lambda fh: np.savez(fh, **arrays))
        return
    from plyfile import PlyData, PlyElement

    V = attrs["positions"]
    n = len(V)
    fields, cols, comments = [], [], []
    fields += [("x", "f8"), ("y", "f8"), ("z", "f8")]
    cols += [V[:, 0], V[:, 1], V[:, 2]]
    for key, arr in attrs.items():
        if key == "positions":
            continue
        if key == "normals":
            fields += [("nx", "f8"), ("ny", "f8"), ("nz", "f8")]
            cols += [arr[:, 0], arr[:, 1], arr[:, 2]]
        elif key == "colors":
            u8 = np.clip(np.round(np.asarray(arr, dtype=np.float64) * 255), 0, 255).astype(np.uint8)
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
    elements = [PlyElement.describe(vert, "vertex")]
    if F is not None:
        face = np.empty(len(F), dtype=[("vertex_indices", "i4", (3,))])
        face["vertex_indices"] = F
        elements.append(PlyElement.describe(face, "face"))
    ply = PlyData(elements, text=not binary, comments=comments)
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


def _triangulate(polygons, path):
    """(m, 3) int64 triangles from a PLY face list: triangles as they are, polygons of k > 3
    corners fanned from their first corner, ``(v0, v_i, v_{i+1})`` (as Open3D does for OFF and
    PLY; exact for convex polygons, the usual quads), with a warning saying how many."""
    if polygons.dtype != object:  # fixed-size lists
        P = np.asarray(polygons).reshape(len(polygons), -1)
        groups = {P.shape[1]: P}
    else:
        lengths = np.fromiter((len(p) for p in polygons), dtype=np.int64, count=len(polygons))
        groups = {int(k): np.stack(polygons[lengths == k]) for k in np.unique(lengths)}
    if min(groups) < 3:
        raise MeshError(f"{path}: faces with fewer than 3 corners ({min(groups)}): not a surface")
    tris, fanned = [], 0
    for k, P in sorted(groups.items()):
        P = P.astype(np.int64)
        if k > 3:
            fanned += len(P)
            P = np.stack([np.repeat(P[:, :1], k - 2, axis=1), P[:, 1:-1], P[:, 2:]], axis=2).reshape(-1, 3)
        tris.append(P)
    if fanned:
        log.warning("%s: %d polygons with more than 3 corners triangulated (fan from their first corner)",
                    path, fanned)
    return np.concatenate(tris)


def read_mesh(path):
    """Read a mesh with all its vertex attributes.

    Parameters
    ----------
    path : str or Path
        PLY (every vertex property is kept, multi-column attributes written by
        :func:`write_mesh` are restored), ``.npz`` written by :func:`write_mesh`, or any format
        Open3D reads (OBJ, OFF, STL, GLB...).

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

    g = read_geometry(path)
    if not isinstance(g, o3d.t.geometry.TriangleMesh):
        raise MeshError(f"{path}: no triangles (a point cloud); use read_geometry for point clouds")
    return g


def read_geometry(path):
    """Read a mesh or a point cloud with all its vertex attributes.

    PLY and ``.npz`` files without faces, and the point formats Open3D reads (PCD, XYZ, PTS),
    give an ``o3d.t.geometry.PointCloud``; everything else an ``o3d.t.geometry.TriangleMesh``.

    Raises
    ------
    MeshError
        Missing, unreadable or truncated file.
    """
    import open3d as o3d

    path = Path(path)
    if not path.is_file():
        raise MeshError(f"no such file: {path}")
    suffix = path.suffix.lower()
    if suffix == ".npz":
        return _read_npz(path)
    if suffix != ".ply":
        if suffix in (".pcd", ".xyz", ".xyzn", ".xyzrgb", ".pts"):
            pc = o3d.t.io.read_point_cloud(str(path))
            if "positions" not in pc.point or len(pc.point.positions) == 0:
                raise MeshError(f"{path}: no points could be read (unreadable or empty file)")
            return pc
        legacy = o3d.io.read_triangle_mesh(str(path))
        if len(legacy.triangles) == 0:
            raise MeshError(f"{path}: no triangles could be read (unreadable or empty file)")
        return o3d.t.geometry.TriangleMesh.from_legacy(legacy)
    from plyfile import PlyData

    try:
        ply = PlyData.read(str(path))
        vert = ply["vertex"].data
        face = ply["face"].data if "face" in [e.name for e in ply.elements] else None
    except Exception as e:
        raise MeshError(f"{path}: not a readable PLY file ({type(e).__name__}: {e})") from e
    names = list(vert.dtype.names)
    if not {"x", "y", "z"} <= set(names):
        raise MeshError(f"{path}: the vertices have no x, y, z")
    multi = {}
    for c in ply.comments:
        parts = c.split()
        if len(parts) >= 4 and parts[:2] == ["o3dheat", "attribute"]:
            multi[parts[2]] = int(parts[3])
    if face is not None and len(face):
        fkey = "vertex_indices" if "vertex_indices" in face.dtype.names else face.dtype.names[0]
        F = _triangulate(face[fkey], path)
        if F.min() < 0 or F.max() >= len(vert):
            raise MeshError(f"{path}: face indices out of range (corrupted file?)")
    else:
        F = None
    geo, attrs = _geometry(F)
    attrs["positions"] = o3d.core.Tensor(np.stack([vert["x"], vert["y"], vert["z"]], 1).astype(np.float64))
    used = {"x", "y", "z"}
    if {"nx", "ny", "nz"} <= set(names):
        attrs["normals"] = o3d.core.Tensor(np.stack([vert["nx"], vert["ny"], vert["nz"]], 1))
        used |= {"nx", "ny", "nz"}
    for key, c in multi.items():
        cols = [f"{key}_{j}" for j in range(c)]
        if not set(cols) <= set(names):
            continue
        arr = np.stack([vert[nm] for nm in cols], 1)
        used |= set(cols)
        attrs["colors" if key == "o3dheat_colors" else key] = o3d.core.Tensor(np.ascontiguousarray(arr))
    if {"red", "green", "blue"} <= set(names):
        used |= {"red", "green", "blue"}
        if "colors" not in attrs:
            rgb = np.stack([vert["red"], vert["green"], vert["blue"]], 1)
            scale = 255.0 if rgb.dtype == np.uint8 else (65535.0 if rgb.dtype == np.uint16 else 1.0)
            attrs["colors"] = o3d.core.Tensor((rgb / scale).astype(np.float32))
    for nm in names:
        if nm not in used:
            attrs[nm] = o3d.core.Tensor(np.ascontiguousarray(vert[nm]))
    return geo


def _geometry(F):
    """An empty tensor mesh with faces F, or a point cloud when F is None, and its vertex map."""
    import open3d as o3d

    if F is None:
        geo = o3d.t.geometry.PointCloud()
        return geo, geo.point
    geo = o3d.t.geometry.TriangleMesh()
    geo.triangle.indices = o3d.core.Tensor(F)
    return geo, geo.vertex


def read_toml(path):
    """A TOML file as a dict (MeshError when it is missing or invalid)."""
    try:
        import tomllib
    except ImportError:  # pragma: no cover - Python 3.10
        import tomli as tomllib
    path = Path(path)
    try:
        return tomllib.loads(path.read_text())
    except OSError as e:
        raise MeshError(f"cannot read {path}: {e.strerror}") from e
    except tomllib.TOMLDecodeError as e:
        raise MeshError(f"{path}: not valid TOML ({e})") from e


def _read_npz(path):
    import open3d as o3d

    try:
        with np.load(path, allow_pickle=False) as z:
            data = {k: z[k] for k in z.files}
    except Exception as e:
        raise MeshError(f"{path}: not a readable NPZ file ({type(e).__name__}: {e})") from e
    if "positions" not in data:
        raise MeshError(f"{path}: no 'positions' array (not written by o3dheat?)")
    V = data.pop("positions")
    n = len(V)
    if "indices" in data:
        F = data.pop("indices")
        if F.ndim != 2 or F.shape[1] != 3 or (F.size and (F.min() < 0 or F.max() >= n)):
            raise MeshError(f"{path}: 'indices' is not a valid (m, 3) array of vertex indices")
    else:
        F = None
    geo, attrs = _geometry(F)
    attrs["positions"] = o3d.core.Tensor(V)
    for key, arr in data.items():
        name = key[len("vertex_"):] if key.startswith("vertex_") else key
        if len(arr) != n:
            raise MeshError(f"{path}: {key!r} has {len(arr)} rows for {n} vertices")
        attrs[name] = o3d.core.Tensor(np.ascontiguousarray(arr))
    return geo
