"""Mesh and point-cloud files through one table of formats: :func:`read_mesh`, :func:`read_geometry`,
:func:`write_mesh`, :func:`write_geometry`; :data:`READERS` and :data:`WRITERS`.

Notes
-----
Formats: PLY (binary by default, every vertex attribute kept exactly but colours, stored as 8-bit
``red green blue`` unless ``lossless_colors=True``: ``o3dheat.io._ply``) through plyfile,
``.npz`` (numpy, everything exact: ``o3dheat.io._npz``), and for reading only OBJ and STL by
o3dheat's own readers (OBJ: the file's vertices in the file's order, texture coordinates on the
triangles: ``o3dheat.io._obj``; STL: binary or ASCII, a truncated or malformed file refused with
the facet and line: ``o3dheat.io._stl``), and every other format Open3D reads (OFF, GLB, PCD,
XYZ...). A PLY or ``.npz`` without faces is a point cloud.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from o3dheat import checks
from o3dheat.errors import MeshError, NoSuchFile

from ._geometry import attributes
from ._npz import read_npz, write_npz
from ._obj import read_obj
from ._ply import read_ply, write_ply
from ._stl import read_stl

if TYPE_CHECKING:  # o3dheat.typing imports Open3D (1.5 s): for annotations only
    import open3d as o3d

    from o3dheat.typing import PathLike

__all__ = ["read_mesh", "write_mesh", "read_geometry", "write_geometry", "READERS", "WRITERS"]


def write_mesh(path: PathLike, mesh: o3d.t.geometry.TriangleMesh | o3d.geometry.TriangleMesh, binary: bool = True,
               overwrite: bool = True, lossless_colors: bool = False) -> None:
    """Write a mesh and all its vertex attributes to a PLY or ``.npz`` file, atomically.

    Parameters
    ----------
    path : str or Path
        Output file ending in ``.ply`` or ``.npz``.
    mesh : o3d.t.geometry.TriangleMesh or o3d.geometry.TriangleMesh
        The mesh: its positions, triangles and every vertex attribute (normals and colours included) are
        written.
    binary : bool
        PLY only: binary little-endian (default) or ASCII.
    overwrite : bool
        False refuses to replace an existing file.
    lossless_colors : bool
        PLY only. False (default): colours are stored as 8-bit ``uchar red green blue``, what
        every viewer reads, and read back within 1/510. True: float colours that 8 bits do not give
        back exactly are also stored exactly (``o3dheat_colors_0..2``, which other tools show as
        extra properties), and :func:`read_mesh` gives them back bit for bit. (All three flags must
        be bools: ``binary="no"`` is a MeshError, not a binary file.)

    Raises
    ------
    MeshError
        Wrong extension, no triangles, an attribute of the wrong length, an existing file with
        ``overwrite=False``, a folder that does not exist, face indices outside the vertices or
        int32, or (PLY) an attribute PLY cannot give back exactly (the layout in the docstring of
        ``o3dheat.io._ply``), NaN or infinite colours, or colours neither float nor uint8: raised
        before anything is written.
    OSError
        The file system's own error (an unwritable folder, a full disk). The target is never left
        half-written.

    Notes
    -----
    Every vertex attribute comes back exactly (dtype, shape and bits) from :func:`read_mesh`,
    but for colours in PLY: float colours ``c`` are written as ``round(255 * c)`` of ``c`` clipped
    to [0, 1] (a warning says how many colours clipping changed; as Open3D's own writer does) and
    read back as ``k / 255`` in their float type; uint8 colours are written and read back as they
    are. Open3D's readers (``o3d.io.read_triangle_mesh``, ``o3d.t.io.read_triangle_mesh``), MeshLab,
    trimesh and plyfile read the same 8-bit colours. ``lossless_colors=True`` adds the exact copy;
    ``.npz`` is always exact.

    Examples
    --------
    >>> import tempfile, os, numpy as np, open3d as o3d, o3dheat.io as io
    >>> m = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 8)
    >>> p = os.path.join(tempfile.mkdtemp(), "s.ply")
    >>> io.write_mesh(p, m); len(io.read_mesh(p).vertex.positions)
    114
    >>> m.vertex.colors = o3d.core.Tensor(np.full((114, 3), 0.3, np.float32))
    >>> io.write_mesh(p, m)                          # 8-bit red green blue: round(0.3 * 255) = 77
    >>> round(float(io.read_mesh(p).vertex.colors.numpy()[0, 0]) * 255, 4)
    77.0
    >>> io.write_mesh(p, m, lossless_colors=True)    # plus the exact float32 values
    >>> bool(io.read_mesh(p).vertex.colors.numpy()[0, 0] == np.float32(0.3))
    True
    """
    _write(path, *attributes(mesh, need_faces=True), binary=binary, overwrite=overwrite,
           lossless_colors=lossless_colors)


def write_geometry(path: PathLike, geometry: o3d.t.geometry.TriangleMesh | o3d.t.geometry.PointCloud
                   | o3d.geometry.TriangleMesh | o3d.geometry.PointCloud, binary: bool = True,
                   overwrite: bool = True, lossless_colors: bool = False) -> None:
    """Like :func:`write_mesh` for a mesh or a point cloud (a PLY or ``.npz`` without faces).

    Examples
    --------
    >>> import tempfile, os, numpy as np, open3d as o3d, o3dheat.io as io
    >>> pc = o3d.t.geometry.PointCloud(o3d.core.Tensor(np.eye(3)))
    >>> p = os.path.join(tempfile.mkdtemp(), "p.npz"); io.write_geometry(p, pc)
    >>> type(io.read_geometry(p)).__name__
    'PointCloud'
    """
    _write(path, *attributes(geometry, need_faces=False), binary=binary, overwrite=overwrite,
           lossless_colors=lossless_colors)


def _write(path, attrs, F, binary, overwrite, lossless_colors=False):
    for name, value in (("binary", binary), ("overwrite", overwrite), ("lossless_colors", lossless_colors)):
        checks.flag(value, name)
    path = Path(path)
    if path.is_dir():
        raise MeshError(f"{path} is a folder: give a file name (e.g. {path / 'mesh.ply'})")
    suffix = path.suffix.lower()
    if suffix not in WRITERS:
        names = " or ".join(w.lstrip(".").upper() for w in WRITERS)
        raise MeshError(f"o3dheat writes {names}: {path} should end in {' or '.join(WRITERS)}")
    if not overwrite and path.exists():
        raise MeshError(f"{path} exists (not overwritten)")
    n = len(attrs["positions"])
    if F is not None and F.size and (F.min() < 0 or F.max() >= min(n, 2 ** 31)):
        raise MeshError(f"cannot write {path}: face indices outside [0, {min(n, 2 ** 31) - 1}] "
                        f"(the vertices, and PLY's int32 indices)")
    # colours: only PLY stores them lossy (8 bits) by default; the other writers keep them exactly
    options = {"lossless_colors": bool(lossless_colors)} if suffix == ".ply" else {}
    WRITERS[suffix](path, attrs, F, binary, **options)


def read_mesh(path: PathLike) -> o3d.t.geometry.TriangleMesh:
    """Read a mesh with all its vertex attributes.

    Parameters
    ----------
    path : str or Path
        PLY (every vertex property is kept, multi-column attributes written by
        :func:`write_mesh` are restored), ``.npz`` written by :func:`write_mesh`, OBJ (the
        file's vertices in its order), STL (a triangle soup: every triangle its own three
        vertices, welded where o3dheat computes), or any format Open3D reads (OFF, GLB...).

    Returns
    -------
    o3d.t.geometry.TriangleMesh

    Raises
    ------
    MeshError
        Missing, unreadable or truncated file (a PLY whose header declares more rows than the
        file can hold is refused before reading; an STL whose last facet is incomplete), a
        malformed one (naming the OBJ or STL line, the PLY face with a non-integral index), or
        one with no triangles.
    OSError
        The file exists but cannot be read (no permission...): the file system's own error.

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


def read_geometry(path: PathLike) -> o3d.t.geometry.TriangleMesh | o3d.t.geometry.PointCloud:
    """Read a mesh or a point cloud with all its vertex attributes.

    PLY and ``.npz`` files without faces, and the point formats Open3D reads (PCD, XYZ, PTS),
    give an ``o3d.t.geometry.PointCloud``; everything else an ``o3d.t.geometry.TriangleMesh``.

    Raises
    ------
    MeshError
        Missing, undecodable or truncated file.
    OSError
        The file exists but cannot be read (no permission...): the file system's own error.

    Examples
    --------
    >>> import os, tempfile, numpy as np, open3d as o3d, o3dheat.io as io
    >>> pc = o3d.t.geometry.PointCloud(o3d.core.Tensor(np.random.default_rng(0).random((50, 3))))
    >>> pc.point["f"] = o3d.core.Tensor(np.arange(50, dtype=np.int32))
    >>> p = os.path.join(tempfile.mkdtemp(), "points.ply"); io.write_geometry(p, pc)
    >>> g = io.read_geometry(p)                     # no faces: a point cloud
    >>> type(g).__name__, str(g.point["f"].numpy().dtype), g.point["f"].numpy()[-1].item()
    ('PointCloud', 'int32', 49)
    """
    path = Path(path)
    if path.is_dir():
        raise MeshError(f"{path} is a folder: give a mesh file")
    if not path.is_file():
        raise NoSuchFile(f"no such file: {path}")
    return READERS.get(path.suffix.lower(), _read_open3d_mesh)(path)


def _read_points(path):
    """The point formats Open3D reads (PCD, XYZ, PTS): an ``o3d.t.geometry.PointCloud``."""
    import open3d as o3d

    pc = o3d.t.io.read_point_cloud(str(path))
    if "positions" not in pc.point or len(pc.point.positions) == 0:
        raise MeshError(f"{path}: no points could be read (unreadable or empty file)")
    return pc


def _read_open3d_mesh(path):
    """Any other mesh format, by Open3D's reader (OFF, glTF...): its triangles and positions."""
    import open3d as o3d

    legacy = o3d.io.read_triangle_mesh(str(path))
    if len(legacy.triangles) == 0:
        raise MeshError(f"{path}: no triangles could be read (unreadable or empty file)")
    return o3d.t.geometry.TriangleMesh.from_legacy(legacy)


#: suffix -> reader (path -> tensor TriangleMesh or PointCloud): the formats read whole, in the
#: file's order; any other suffix goes to Open3D's mesh reader (positions and triangles). A format
#: is added here and, when it is an output of batches too, in :data:`WRITERS`.
READERS = {".ply": read_ply, ".npz": read_npz, ".stl": read_stl, ".obj": read_obj,
           **dict.fromkeys((".pcd", ".xyz", ".xyzn", ".xyzrgb", ".pts"), _read_points)}


#: suffix -> writer (path, attributes, faces or None, binary): what o3dheat writes, every attribute
#: kept (:func:`write_mesh`, :func:`write_geometry`; batch outputs); the PLY writer also takes
#: ``lossless_colors=`` (the only lossy storage: colours in 8 bits by default).
WRITERS = {".ply": write_ply, ".npz": write_npz}
