"""Mesh and point-cloud files that keep every vertex attribute, and atomic writes.

Formats: PLY (binary by default) through plyfile, ``.npz`` (numpy), and for reading only OBJ
and STL by o3dheat's own readers (OBJ: the file's vertices in the file's order, texture
coordinates on the triangles; STL: binary or ASCII, a truncated or malformed file refused with
the facet and line), and every other format Open3D reads (OFF, GLB, PCD, XYZ...).

PLY layout written here: ``x y z`` in the positions' own float type (float or double),
``nx ny nz`` (the normals' float type) when there are normals, and colours once, as
``red green blue``: uchar (what every viewer reads) when they are float32 multiples of 1/255,
else their exact values as float or double (their own type; other dtypes with a header comment
``o3dheat colors DTYPE``; files of older versions, which also stored ``o3dheat_colors_0..2``,
read as before). Any other vertex attribute ``a`` of shape (n,) is a property
``a``; of shape (n, c) or (n, a, b...) it is ``a_0 .. a_{c-1}`` (row-major) with a header comment
``o3dheat attribute a C DTYPE [shape=(a,b)]`` (C the number of columns, DTYPE the numpy dtype,
``shape=`` only when the trailing shape is not (C,); ``shape=()`` marks a one-column attribute
stored as ``a``) so that :func:`read_mesh` restores the array with its shape and dtype. Every
property is ``uchar``, ``int``, ``float`` or ``double``: the types that Open3D's own PLY reader
(``o3d.t.io.read_point_cloud`` keeps custom properties), trimesh and meshio all read (Open3D skips
``char``, ``short``, ``ushort`` and ``uint``, meshio's binary reader fails on ``char``, ``short``
and ``ushort``). Other dtypes are stored exactly in one of them and restored from DTYPE: bool as
uchar; int8, int16 and uint16 as int; uint32, int64 and uint64 as int when they fit, else as
double when every ``|value| <= 2**53`` (beyond: refused, use ``.npz``). Names PLY
cannot hold (spaces, non-ASCII), reserved ones (``x y z nx ny nz red green blue``, ``alpha`` but
for one column, ``o3dheat_colors*``) and names whose properties collide (``a_0`` beside a
multi-column ``a``) are refused with a :class:`MeshError` before anything is written, as are
face indices beyond int32. Comments of older files (``o3dheat attribute a C DTYPE``) read as
before, and so do the ``char``/``short``/``ushort``/``uint`` properties older versions wrote. On
reading, a comment is used only when its columns exist, are unused, share one type that holds
the recorded dtype exactly (every value in range) and its name is not reserved; other comments
are ignored with a warning. The header is checked against the file size before plyfile
allocates anything.
A PLY without a face element is a point cloud.

``.npz`` layout: ``positions`` and ``indices`` (meshes), and every other attribute ``a`` as
``vertex_a`` with its shape and dtype (read without pickles).
"""

from __future__ import annotations

import logging
import os
import re
import tempfile
from glob import escape as glob_escape
from pathlib import Path

import numpy as np

from o3dheat.errors import MeshError

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
        The mesh: its positions, triangles and every vertex attribute (normals and colours included) are
        written.
    binary : bool
        PLY only: binary little-endian (default) or ASCII.
    overwrite : bool
        False refuses to replace an existing file. (Both must be bools: ``binary="no"`` is a
        MeshError, not a binary file.)

    Raises
    ------
    MeshError
        Wrong extension, no triangles, an attribute of the wrong length, an existing file with
        ``overwrite=False``, an unwritable path, face indices outside the vertices or int32, or
        (PLY) an attribute PLY cannot give back exactly (see the module documentation): raised
        before anything is written. The target is never left half-written.

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


# Vertex properties with a meaning of their own in PLY (what viewers read): no attribute may be
# stored under these names. "alpha" is allowed for a one-column attribute (where a PLY's alpha,
# read as the attribute "alpha", goes back).
_PLY_RESERVED = {"x", "y", "z", "nx", "ny", "nz", "red", "green", "blue"}
_COLORS_KEY = "o3dheat_colors"  # (older versions stored colours twice: uchar and these columns)
_RAW_COLORS = "o3dheat colors"  # header comment: red green blue hold the values of this dtype
# dtypes a PLY property holds as they are (kind + itemsize) when reading; o3dheat writes only
# _PLY_WRITTEN (uchar, int, float, double: what Open3D, trimesh and meshio all read) and stores
# every other dtype exactly in one of them, recording the original dtype in the header comment.
# _PLY_STORED: original dtype -> the stored types it may be restored from (older versions wrote
# int8/int16/uint16/uint32 natively and uint64 as uint).
_PLY_NATIVE = {"i1", "i2", "i4", "u1", "u2", "u4", "f4", "f8"}
_PLY_WRITTEN = {"u1", "i4", "f4", "f8"}
_PLY_STORED = {"b1": ("u1",), "i1": ("i4",), "i2": ("i4",), "u2": ("i4",), "u4": ("i4", "f8"),
               "i8": ("i4", "f8"), "u8": ("u4", "i4", "f8")}
_MAX_EXACT = 2 ** 53
_NAME_RE = re.compile(r"[!-~]+\Z")  # printable ASCII, no whitespace: one PLY header token


def _code(dtype):
    """'f8', 'i4', 'b1'... of a numpy dtype (kind and size, whatever the byte order)."""
    return f"{dtype.kind}{dtype.itemsize}"


def _ply_storable(name, arr, path):
    """The array a PLY stores for attribute ``name`` (same values, a PLY-native dtype), or
    MeshError when no PLY type holds it exactly."""
    code = _code(arr.dtype)
    if code in _PLY_WRITTEN:
        return arr
    if code == "b1":
        return arr.astype(np.uint8)
    if arr.dtype.kind in "iu":
        lo = int(arr.min()) if arr.size else 0
        hi = int(arr.max()) if arr.size else 0
        if np.iinfo(np.int32).min <= lo and hi <= np.iinfo(np.int32).max:
            return arr.astype(np.int32)
        if -_MAX_EXACT <= lo and hi <= _MAX_EXACT:
            return arr.astype(np.float64)
        raise MeshError(f"cannot write {path}: vertex attribute {name!r} ({arr.dtype}) has values beyond "
                        f"±2**53, which PLY (no 64-bit integers) cannot store exactly: use .npz")
    raise MeshError(f"cannot write {path}: vertex attribute {name!r} has dtype {arr.dtype}, which PLY "
                    f"cannot store: use .npz")


def _float_xyz(key, arr, path):
    if arr.ndim != 2 or arr.shape[1] != 3 or _code(arr.dtype) not in ("f4", "f8"):
        raise MeshError(f"cannot write {path}: PLY stores {key} as (n, 3) float32 or float64, got "
                        f"{arr.shape[1:]} {arr.dtype}: use .npz")
    return arr


def _ply_vertex_table(attrs, path):
    """(fields [(property, dtype str)], columns, header comments) of the PLY vertex element, or
    MeshError (naming the attribute and why) for any attribute PLY cannot give back exactly."""
    V = _float_xyz("positions", attrs["positions"], path)
    fields = [(c, V.dtype.str) for c in "xyz"]
    cols = [V[:, 0], V[:, 1], V[:, 2]]
    comments, owner = [], {c: "positions" for c in "xyz"}

    def add(key, props, arrays):
        for p in props:
            if p in owner:
                why = ("a reserved PLY property" if owner[p] in ("positions", "normals", "colors")
                       else f"already a property of attribute {owner[p]!r}")
                raise MeshError(f"cannot write {path}: vertex attribute {key!r} would be stored as "
                                f"property {p!r}, {why}: rename it")
            owner[p] = key
        fields.extend((p, a.dtype.str) for p, a in zip(props, arrays, strict=True))
        cols.extend(arrays)

    if "normals" in attrs:
        N = _float_xyz("normals", attrs["normals"], path)
        add("normals", ["nx", "ny", "nz"], [N[:, 0], N[:, 1], N[:, 2]])
    if "colors" in attrs:
        C = attrs["colors"]
        if C.ndim != 2 or C.shape[1] != 3:
            raise MeshError(f"cannot write {path}: colors must have shape (n, 3), got {C.shape}: use .npz")
        # stored once, as red green blue: uchar when that is exact (float32 multiples of 1/255,
        # what every viewer reads), else the float values themselves (float or double); other
        # dtypes as their values with a header comment giving the dtype back
        if _code(C.dtype) in ("f4", "f8"):
            u8 = np.clip(np.round(np.asarray(C, dtype=np.float64) * 255), 0, 255).astype(np.uint8)
            S = u8 if C.dtype == np.float32 and np.array_equal((u8 / 255.0).astype(C.dtype), C) else C
        else:
            S = _ply_storable("colors", C, path)
            comments.append(f"{_RAW_COLORS} {C.dtype.str}")
        add("colors", ["red", "green", "blue"], [S[:, 0], S[:, 1], S[:, 2]])
    for key, arr in attrs.items():
        if key in _RESERVED:
            continue
        if not isinstance(key, str) or not _NAME_RE.match(key):
            raise MeshError(f"cannot write {path}: vertex attribute {key!r}: a PLY property name must be "
                            f"printable ASCII without spaces: rename it or use .npz")
        if key in _PLY_RESERVED or key.startswith(_COLORS_KEY) or (key == "alpha" and arr.ndim != 1):
            raise MeshError(f"cannot write {path}: vertex attribute {key!r} has the name of a reserved PLY "
                            f"property (x y z nx ny nz red green blue, alpha only for one column, "
                            f"{_COLORS_KEY}_*): rename it")
        trailing = arr.shape[1:]
        c = int(np.prod(trailing, dtype=np.int64))
        if arr.ndim > 1 and c == 0:
            raise MeshError(f"cannot write {path}: vertex attribute {key!r} has shape {arr.shape}: no "
                            f"column to store in PLY: use .npz")
        S = _ply_storable(key, arr, path).reshape(len(arr), -1)
        if arr.ndim == 1:
            add(key, [key], [S[:, 0]])
            if S.dtype != arr.dtype:
                comments.append(f"o3dheat attribute {key} 1 {arr.dtype.str} shape=()")
        else:
            add(key, [f"{key}_{j}" for j in range(c)], [S[:, j] for j in range(c)])
            shape = "" if arr.ndim == 2 else " shape=(" + ",".join(map(str, trailing)) + ")"
            comments.append(f"o3dheat attribute {key} {c} {arr.dtype.str}{shape}")
    return fields, cols, comments


def _write(path, attrs, F, binary, overwrite):
    for name, flag in (("binary", binary), ("overwrite", overwrite)):
        if not isinstance(flag, (bool, np.bool_)):
            raise MeshError(f"{name} must be True or False, got {flag!r} ({type(flag).__name__})")
    path = Path(path)
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
    WRITERS[suffix](path, attrs, F, binary)


def _write_npz(path, attrs, F, binary):
    arrays = {"positions": attrs["positions"]}
    if F is not None:
        arrays["indices"] = F
    arrays.update({f"vertex_{k}": v for k, v in attrs.items() if k != "positions"})
    for k, v in arrays.items():
        if v.dtype.hasobject:
            raise MeshError(f"cannot write {path}: {k!r} holds Python objects")
    atomic_write(path, lambda fh: np.savez(fh, **arrays))


def _write_ply(path, attrs, F, binary):
    from plyfile import PlyData, PlyElement

    n = len(attrs["positions"])
    fields, cols, comments = _ply_vertex_table(attrs, path)
    try:
        vert = np.empty(n, dtype=[(nm, np.dtype(dt).newbyteorder("<").str) for nm, dt in fields])
        for (nm, _), col in zip(fields, cols, strict=True):
            vert[nm] = col
        elements = [PlyElement.describe(vert, "vertex")]
        if F is not None:
            face = np.empty(len(F), dtype=[("vertex_indices", "i4", (3,))])
            face["vertex_indices"] = F
            elements.append(PlyElement.describe(face, "face"))
        ply = PlyData(elements, text=not binary, byte_order="<", comments=comments)
    except (ValueError, TypeError) as e:  # pragma: no cover - every known case is refused above
        raise MeshError(f"cannot write {path}: {e}") from e
    atomic_write(path, ply.write if not binary else lambda fh: _write_binary_ply(fh, ply, vert, F))


def _write_binary_ply(fh, ply, vert, F):
    """What ``ply.write`` writes for a little-endian binary PLY of ``vert`` and triangles ``F``,
    byte for byte (tested), but the triangles in one block: plyfile writes list properties face
    by face (8 s for 2M faces)."""
    fh.write(ply.header.encode("ascii") + b"\n")
    fh.write(vert.astype(ply["vertex"].dtype("<"), copy=False).tobytes())
    if F is not None:
        block = np.empty(len(F), dtype=np.dtype([("n", "u1"), ("v", "<i4", (3,))]))  # packed: 13 bytes
        block["n"], block["v"] = 3, F
        fh.write(block.tobytes())


def atomic_write(path, write):
    r"""Write a file atomically: ``write(binary_file)`` goes to a temporary file in the same
    folder, which then replaces ``path``. On any error the temporary file is removed and
    ``path`` is untouched. The file gets the permissions ``open()`` would give it.

    Raises
    ------
    MeshError
        The folder does not exist or is not writable.

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


def _remove_stale(folder, prefix, age=3600.0):
    """Remove the temporary files ``{prefix}*.tmp`` that a killed writer left (older than an hour:
    a live writer finishes sooner), so an interrupted run leaves no litter after the next one."""
    import time

    now = time.time()
    for tmp in Path(folder).glob(f"{glob_escape(prefix)}*.tmp"):
        try:
            if now - tmp.stat().st_mtime > age:
                tmp.unlink()
                log.info("removed %s, left by an interrupted write", tmp)
        except OSError:
            pass


def atomic_write_text(path, text):
    r"""Write a text file (UTF-8) atomically (see :func:`atomic_write`).

    Examples
    --------
    >>> import os, tempfile, o3dheat.io as io
    >>> p = os.path.join(tempfile.mkdtemp(), "note.txt")
    >>> io.atomic_write_text(p, "λ₂ = 2\n")
    >>> open(p, encoding="utf-8").read()
    'λ₂ = 2\n'
    """
    atomic_write(path, lambda fh: fh.write(text.encode("utf-8")))


def _triangulate(polygons, path):
    """(m, 3) int64 triangles from a PLY face list: triangles as they are, polygons of k > 3
    corners fanned from their first corner, ``(v0, v_i, v_{i+1})`` (as Open3D does for OFF and
    PLY; exact for convex polygons, the usual quads), with a warning saying how many. Indices
    stored as floats must be integers (MeshError naming the face otherwise: never truncated)."""
    if polygons.dtype != object:  # fixed-size lists
        P = np.asarray(polygons).reshape(len(polygons), -1)
        groups = {P.shape[1]: (P, np.arange(len(P)))}
    else:
        lengths = np.fromiter((len(p) for p in polygons), dtype=np.int64, count=len(polygons))
        groups = {int(k): (np.stack(polygons[lengths == k]), np.flatnonzero(lengths == k))
                  for k in np.unique(lengths)}
    if min(groups) < 3:
        raise MeshError(f"{path}: faces with fewer than 3 corners ({min(groups)}): not a surface")
    tris, fanned = [], 0
    for k, (P, rows) in sorted(groups.items()):
        if P.dtype.kind not in "iu":  # a float index list: integral values only, never truncated
            stored = P.dtype.name
            P = np.asarray(P, dtype=np.float64)
            bad = ~np.isfinite(P) | (P != np.round(P)) | (np.abs(P) >= 2.0 ** 62)
            if bad.any():
                i = int(np.flatnonzero(bad.any(axis=1))[0])
                raise MeshError(f"{path}: face {int(rows[i])} has the vertex index {float(P[i][bad[i]][0])!r}, "
                                f"not an integer (the file stores face indices as {stored}): corrupt file")
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
    if not path.is_file():
        raise MeshError(f"no such file: {path}")
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


_STL_TRIANGLE = np.dtype([("normal", "<f4", (3,)), ("corners", "<f4", (3, 3)), ("attribute", "<u2")])


def _soup(corners):
    """A TriangleMesh whose every triangle has its own three vertices (what STL stores; o3dheat
    welds them where it computes: :func:`o3dheat.geometry.mesh.prepare`)."""
    import open3d as o3d

    V = np.ascontiguousarray(corners, dtype=np.float64).reshape(-1, 3)
    F = np.arange(len(V), dtype=np.int64).reshape(-1, 3)
    return o3d.t.geometry.TriangleMesh(o3d.core.Tensor(V), o3d.core.Tensor(F))


def _read_stl(path):
    """A binary or ASCII STL as a triangle soup (:func:`_soup`). Binary: an 80-byte header, a
    triangle count and 50 bytes per triangle, read in one block (Open3D's reader takes 6 s for 2M
    triangles); a file whose size is not that of its count is ASCII or truncated. ASCII: every
    ``facet`` must be complete (``outer loop``, three ``vertex`` lines, ``endloop``, ``endfacet``)
    and the file must end with ``endsolid``: a truncated file is refused, naming the facet and
    the line, never read as part of a mesh."""
    size = path.stat().st_size
    with open(path, "rb") as fh:
        head = fh.read(84)
        count = int(np.frombuffer(head[80:84], "<u4")[0]) if len(head) == 84 else -1
        if count >= 0 and size == 84 + _STL_TRIANGLE.itemsize * count:
            if count == 0:
                raise MeshError(f"{path}: no triangles could be read (a binary STL of 0 triangles)")
            return _soup(np.fromfile(fh, dtype=_STL_TRIANGLE, count=count)["corners"])
    text = path.read_bytes()
    if not text.lstrip()[:5].lower() == b"solid" or b"\0" in text[:1024]:
        if count >= 0:
            raise MeshError(f"{path}: not a readable STL: as binary STL its header declares {count} triangles "
                            f"({84 + _STL_TRIANGLE.itemsize * count} bytes), the file has {size} bytes "
                            "(truncated or corrupt), and it is not ASCII STL (no 'solid')")
        raise MeshError(f"{path}: not a readable STL file ({size} bytes)")
    return _soup(_ascii_stl_corners(text.decode("ascii", errors="replace"), path))


_STL_FACET = ("facet", "outer", "vertex", "vertex", "vertex", "endloop", "endfacet")


def _ascii_stl_corners(text, path):
    """(3 m, 3) float64 corners of an ASCII STL, its structure checked (see :func:`_read_stl`)."""
    lines = text.splitlines()
    numbers, words = [], []
    for number, line in enumerate(lines, 1):
        w = line.split(None, 1)
        if w:
            numbers.append(number)
            words.append(w)
    keys = [w[0].lower() for w in words]
    facets = 0
    state = -1  # -1: outside a solid; 0..6: position in _STL_FACET (0: between facets)
    for i, key in enumerate(keys):  # the structure, line by line (7 lines per triangle)
        if state == 0 and key == "endsolid":
            state = -1
        elif state == -1 and key == "solid":
            state = 0
        elif state >= 0 and key == _STL_FACET[state]:
            if state == 0:
                facets += 1
            state = (state + 1) % 7
        elif state > 0:
            raise MeshError(f"{path}: facet {facets} is incomplete at line {numbers[i]}: expected "
                            f"{_STL_FACET[state]!r}, found {key!r} (truncated or corrupt ASCII STL)")
        else:
            want = "'solid'" if state == -1 else "'facet' or 'endsolid'"
            raise MeshError(f"{path}: line {numbers[i]}: expected {want}, found {key!r} (corrupt ASCII STL)")
    end = numbers[-1] if numbers else len(lines)
    if state > 0:
        raise MeshError(f"{path}: facet {facets} is incomplete at line {end}: the file ends before its "
                        f"{_STL_FACET[state]!r} (truncated ASCII STL)")
    if state == 0:
        raise MeshError(f"{path}: no 'endsolid' after facet {facets} at line {end}: the file ends early "
                        "(truncated ASCII STL)")
    if facets == 0:
        raise MeshError(f"{path}: no triangles could be read (an ASCII STL of no facet)")
    at = [i for i, key in enumerate(keys) if key == "vertex"]
    try:
        P = np.array([words[i][1].split() for i in at], dtype=np.float64)
        if P.ndim != 2 or P.shape[1] != 3:
            raise ValueError
    except (ValueError, IndexError):
        for i in at:
            parts = words[i][1].split() if len(words[i]) > 1 else []
            try:
                if len(parts) != 3:
                    raise ValueError
                [float(x) for x in parts]
            except ValueError:
                raise MeshError(f"{path}: line {numbers[i]}: a vertex needs three numbers, got "
                                f"{' '.join(parts)[:60]!r} (corrupt ASCII STL)") from None
        raise  # pragma: no cover
    return P


def _read_obj(path):
    """A Wavefront OBJ as a tensor mesh with the file's vertices, in the file's order.

    Read: ``v x y z`` (and ``v x y z r g b``: colours, when every vertex has them), ``vt``,
    ``vn`` and ``f`` with the index forms ``i``, ``i/t``, ``i//n``, ``i/t/n``; indices from 1,
    negative ones counting back from the last element read; polygons fanned from their first
    corner. Texture coordinates, when every corner of every face has one, go to the triangles:
    ``triangle["texture_uvs"]`` (m, 3, 2), Open3D's layout. Normals (per corner in OBJ) are
    checked, not kept. Comments, groups, objects, materials, smoothing groups, lines and points
    are ignored. A malformed line (a ``v`` without three numbers, an index that is not an
    integer, is 0 or out of range, a face of fewer than three corners) is a MeshError naming the
    line. (Open3D's own reader splits the vertices at texture seams and merges coincident ones:
    other vertices than the file's.)"""
    import open3d as o3d

    try:
        text = path.read_bytes().decode("utf-8", errors="replace")
    except OSError as e:
        raise MeshError(f"cannot read {path}: {e.strerror}") from e
    v, vt, f = [], [], []  # (line number, rest of the line); faces also: the counts so far
    n_vn = 0
    for number, line in enumerate(text.splitlines(), 1):
        w = line.split(None, 1)
        if not w:
            continue
        head, rest = w[0], (w[1] if len(w) > 1 else "")
        if head == "v":
            v.append((number, rest))
        elif head == "f":
            f.append((number, rest, len(v), len(vt), n_vn))
        elif head == "vt":
            vt.append((number, rest))
        elif head == "vn":
            n_vn += 1
    if not v:
        raise MeshError(f"{path}: no vertices ('v' lines) could be read (unreadable or empty OBJ)")
    if not f:
        raise MeshError(f"{path}: no triangles could be read (an OBJ without 'f' lines)")
    V, colors = _obj_numbers(v, path, "v", (3, 4, 6, 7))
    uv = None
    if vt:
        uv = _obj_numbers(vt, path, "vt", (2, 3, 1))[0]
        uv = np.c_[uv, np.zeros(len(uv))] if uv.shape[1] == 1 else uv[:, :2]  # "vt u": v = 0
    counts = np.fromiter((len(r.split()) for _, r, _, _, _ in f), dtype=np.int64, count=len(f))
    if counts.min() < 3:
        i = int(np.flatnonzero(counts < 3)[0])
        raise MeshError(f"{path}: line {f[i][0]}: a face needs at least 3 corners, got {counts[i]}")
    info = np.array([(number, nv, nt, nn) for number, _, nv, nt, nn in f], dtype=np.int64)
    per = np.repeat(info, counts, axis=0)  # per corner: line, v, vt, vn counts so far
    joined = " ".join(r for _, r, _, _, _ in f)
    corners = joined.split()
    fields = _obj_fields(joined, corners)
    if fields is None:  # corners of different forms: one by one
        parts = [c.split("/") for c in corners]
        if max(len(q) for q in parts) > 3:
            i = next(i for i, q in enumerate(parts) if len(q) > 3)
            raise MeshError(f"{path}: line {per[i, 0]}: bad face corner {corners[i]!r} (use i, i/t, i//n or i/t/n)")
        fields = [[q[j] if len(q) > j else "" for q in parts] for j in range(3)]
    vi = _obj_indices(fields[0], per[:, 1], per[:, 0], corners, path, "vertex")
    ti = None
    has_t = np.array([t != "" for t in fields[1]], dtype=bool)
    if has_t.any():
        ti = _obj_indices([t or "1" for t in fields[1]], per[:, 2], per[:, 0], corners, path,
                          "texture coordinate", check=has_t)
    has_n = np.array([t != "" for t in fields[2]], dtype=bool)
    if has_n.any():
        _obj_indices([t or "1" for t in fields[2]], per[:, 3], per[:, 0], corners, path, "normal", check=has_n)
    # fan each face from its first corner: corner j of face i is start[i] + j
    start = np.r_[0, np.cumsum(counts)[:-1]]
    tri_face = np.repeat(np.arange(len(counts)), counts - 2)
    j = np.arange(len(tri_face)) - np.repeat(np.cumsum(counts - 2) - (counts - 2), counts - 2)
    c = np.stack([start[tri_face], start[tri_face] + 1 + j, start[tri_face] + 2 + j], axis=1)
    F = vi[c]
    fanned = int(np.sum(counts > 3))
    if fanned:
        log.warning("%s: %d polygons with more than 3 corners triangulated (fan from their first corner)",
                    path, fanned)
    mesh = o3d.t.geometry.TriangleMesh(o3d.core.Tensor(V), o3d.core.Tensor(F))
    if colors is not None:
        mesh.vertex.colors = o3d.core.Tensor(colors)
    if ti is not None:
        if has_t.all():
            mesh.triangle["texture_uvs"] = o3d.core.Tensor(np.ascontiguousarray(uv[ti[c]]))
        else:
            log.info("%s: texture coordinates on some face corners only: not kept", path)
    return mesh


def _obj_fields(joined, corners):
    """The three index fields (v, vt, vn: lists of strings, "" where absent) of face corners all of
    one form (``i``, ``i/t``, ``i//n`` or ``i/t/n``), split in bulk; None for mixed forms (or
    text that is not ASCII), left to the corner-by-corner reading."""
    k = len(corners)
    if "/" not in joined:
        return [corners, [""] * k, [""] * k]
    if not joined.isascii():
        return None
    b = np.frombuffer(joined.encode("ascii"), np.uint8)
    white = np.isin(b, np.frombuffer(b" \t\n\r\x0b\x0c\x1c\x1d\x1e\x1f", np.uint8))
    start = np.flatnonzero(~white & np.r_[True, white[:-1]])
    end = np.flatnonzero(~white & np.r_[white[1:], True]) + 1
    if len(start) != k:  # pragma: no cover - split() and these boundaries agree on ASCII
        return None
    cs = np.r_[0, np.cumsum(b == 47)]  # "/"
    per = cs[end] - cs[start]
    if per.min() != per.max() or per[0] > 2:
        return None
    pair = np.r_[0, np.cumsum((b[:-1] == 47) & (b[1:] == 47)), 0]
    doubles = int(pair[-2]) if len(b) > 1 else 0
    if per[0] == 1 and doubles == 0:
        vt = joined.replace("/", " ").split()
        if len(vt) == 2 * k:
            return [vt[0::2], vt[1::2], [""] * k]
    elif per[0] == 2 and doubles == k:
        vn = joined.replace("//", " ").split()
        if len(vn) == 2 * k:
            return [vn[0::2], [""] * k, vn[1::2]]
    elif per[0] == 2 and doubles == 0:
        vtn = joined.replace("/", " ").split()
        if len(vtn) == 3 * k:
            return [vtn[0::3], vtn[1::3], vtn[2::3]]
    return None


def _obj_numbers(rows, path, what, sizes):
    """(k, c) float64 of the numbers of OBJ lines ``what`` (``c = sizes[0]``, or fewer when a line
    has fewer), and for ``v`` with 6 or 7 numbers on every line their colours (else None)."""
    try:
        A = np.array([r.split() for _, r in rows], dtype=np.float64)
        if A.ndim != 2 or A.shape[1] not in sizes:
            raise ValueError
    except ValueError:
        A = None
    if A is None:  # lines of different lengths, or a bad one: line by line, naming it
        out = []
        for number, rest in rows:
            parts = rest.split()
            try:
                vals = [float(x) for x in parts]
                if len(vals) not in sizes:
                    raise ValueError
            except ValueError:
                raise MeshError(f"{path}: line {number}: '{what}' needs {' or '.join(map(str, sizes))} numbers, "
                                f"got {rest.strip()[:60]!r} (malformed OBJ)") from None
            out.append(vals[:sizes[0]])
        width = min(len(r) for r in out)
        return np.array([r[:width] for r in out], dtype=np.float64), None
    if not np.all(np.isfinite(A)):
        i = int(np.flatnonzero(~np.all(np.isfinite(A), axis=1))[0])
        raise MeshError(f"{path}: line {rows[i][0]}: '{what}' has a NaN or infinite number (malformed OBJ)")
    colors = A[:, 3:6].copy() if what == "v" and A.shape[1] in (6, 7) else None
    return np.ascontiguousarray(A[:, :sizes[0]]), colors


def _obj_indices(tokens, count, lines, corners, path, what, check=None):
    """0-based int64 indices of OBJ index tokens (1-based; negative: from the end of the
    elements read so far, ``count``), MeshError naming the line of a bad one."""
    try:
        idx = np.array(tokens, dtype=np.int64)
    except (ValueError, OverflowError):
        idx = None
    if idx is None:
        for i, t in enumerate(tokens):
            try:
                int(t)
            except ValueError:
                raise MeshError(f"{path}: line {lines[i]}: {what} index {t!r} (in {corners[i]!r}) is not an "
                                "integer (malformed OBJ)") from None
        raise MeshError(f"{path}: {what} indices beyond 64 bits (malformed OBJ)")
    out = np.where(idx < 0, count + idx, idx - 1)
    bad = (idx == 0) | (out < 0) | (out >= count)
    if check is not None:
        bad &= check
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise MeshError(f"{path}: line {lines[i]}: {what} index {tokens[i]} is out of range (1..{count[i]} "
                        f"or -1..-{count[i]} at that line; 0 is not an OBJ index) (malformed OBJ)")
    return out


_PLY_SIZES = {"char": 1, "int8": 1, "uchar": 1, "uint8": 1, "short": 2, "int16": 2, "ushort": 2,
              "uint16": 2, "int": 4, "int32": 4, "uint": 4, "uint32": 4, "float": 4, "float32": 4,
              "double": 8, "float64": 8}
_MAX_HEADER = 65536
_MAX_ROWS = 2 ** 40


def _check_ply_header(path):
    """Parse a PLY header (at most 64 KB) and refuse, before plyfile allocates anything, a file
    too small for the rows its header declares (each binary row needs its fixed properties and
    the count of each list, each ASCII value at least 2 bytes), or an absurd declaration."""
    size = path.stat().st_size
    with open(path, "rb") as fh:
        head = fh.read(_MAX_HEADER)
    bad = f"{path}: not a readable PLY file"
    if not head.startswith(b"ply"):
        raise MeshError(f"{bad} (no 'ply' magic)")
    end, offset, lines = None, 0, []
    for raw in head.split(b"\n"):
        complete = offset + len(raw) < len(head)
        offset += len(raw) + 1
        if raw.strip() == b"end_header" and (complete or len(head) == size):
            end = min(offset, size)
            break
        lines.append(raw.decode("ascii", errors="replace").split())
    if end is None:
        raise MeshError(f"{bad}: no end_header in the first {_MAX_HEADER} bytes" if size > _MAX_HEADER
                        else f"{bad}: no end_header (truncated or not a PLY file)")
    fmt, elements = None, []  # [name, count, binary row bytes, ascii row values]
    for words in lines[1:]:
        if not words or words[0] in ("comment", "obj_info"):
            continue
        if words[0] == "format" and len(words) == 3:
            fmt = words[1]
        elif words[0] == "element" and len(words) == 3:
            if not words[2].isdigit() or int(words[2]) > _MAX_ROWS:
                raise MeshError(f"{bad}: absurd element count in header line {' '.join(words)!r}")
            elements.append([words[1], int(words[2]), 0, 0])
        elif words[0] == "property" and elements and len(words) == 3 and words[1] in _PLY_SIZES:
            elements[-1][2] += _PLY_SIZES[words[1]]
            elements[-1][3] += 1
        elif (words[0] == "property" and elements and len(words) == 5 and words[1] == "list"
              and words[2] in _PLY_SIZES and words[3] in _PLY_SIZES):
            elements[-1][2] += _PLY_SIZES[words[2]]
            elements[-1][3] += 1
        else:
            raise MeshError(f"{bad}: unexpected header line {' '.join(words)[:80]!r}")
    if fmt not in ("ascii", "binary_little_endian", "binary_big_endian"):
        raise MeshError(f"{bad}: unknown format {fmt!r}")
    if fmt == "ascii":
        need = max(sum(count * (2 * values or 1) for _, count, _, values in elements) - 1, 0)
    else:
        need = sum(count * max(row, 1) for _, count, row, _ in elements)
    if need > size - end:
        plural = {"vertex": "vertices", "face": "faces"}
        what = " and ".join(f"{count} {plural.get(name, repr(name) + ' rows')}" for name, count, _, _ in elements)
        raise MeshError(f"{bad}: truncated or corrupt: the header declares {what}, the file has {size} "
                        f"bytes ({size - end} after its header, at least {need} needed)")


def _parse_comment(comment, path):
    """(name, columns, original dtype or None, trailing shape or None) of a comment
    ``o3dheat attribute NAME C DTYPE [shape=(a,b)]``, None for other comments; malformed ones
    are logged and ignored."""
    parts = comment.split()
    if parts[:2] != ["o3dheat", "attribute"]:
        return None
    try:
        if len(parts) < 4 or not parts[3].isdigit() or not 0 < int(parts[3]) <= 1 << 20:
            raise ValueError("no column count")
        name, c = parts[2], int(parts[3])
        dtype = np.dtype(parts[4]) if len(parts) > 4 else None
        if dtype is not None and _code(dtype) not in _PLY_NATIVE | set(_PLY_STORED):
            raise ValueError(f"dtype {dtype} is not one o3dheat writes")
        shape = None
        for extra in parts[5:]:
            if extra.startswith("shape="):
                m = re.fullmatch(r"\(((?:[1-9]\d{0,6},)*(?:[1-9]\d{0,6})?)\)", extra[6:])
                if not m:
                    raise ValueError(f"bad {extra!r}")
                shape = tuple(int(s) for s in m.group(1).split(",") if s)
                if len(shape) > 16 or int(np.prod(shape, dtype=object)) != c:
                    raise ValueError(f"{extra!r} does not hold {c} columns")
    except (ValueError, TypeError) as e:
        log.warning("%s: ignoring malformed header comment %r (%s)", path, comment, e)
        return None
    return name, c, dtype, shape


def _restore(arr, dtype):
    """``arr`` (as stored) in its original dtype, or None when the values do not fit it exactly."""
    if dtype is None:
        return arr.astype(arr.dtype.newbyteorder("="))
    code, stored = _code(dtype), _code(arr.dtype)
    if code == stored:
        return arr.astype(dtype.newbyteorder("="))
    if stored not in _PLY_STORED.get(code, ()):
        return None
    if code == "b1":
        return arr.astype(bool) if np.all((arr == 0) | (arr == 1)) else None
    if arr.dtype.kind == "f" and not (np.all(np.isfinite(arr)) and np.all(arr == np.round(arr))
                                      and np.all(np.abs(arr) <= _MAX_EXACT)):
        return None
    info = np.iinfo(dtype)
    if arr.size and (arr.min() < info.min or arr.max() > info.max):
        return None
    return arr.astype(dtype.newbyteorder("="))


#: face lists read as fixed-size triangles in one block (plyfile's memory-mapped path); polygons
#: of other sizes fall back to plyfile's per-face reading (60x slower: 9 s for 2M faces)
_TRIANGLE_LISTS = {"face": {"vertex_indices": 3, "vertex_index": 3}}


def _read_plydata(path):
    """``plyfile``'s PlyData of a file, all-triangle face lists read in one block."""
    from plyfile import PlyData, PlyElementParseError

    try:
        return PlyData.read(str(path), known_list_len=_TRIANGLE_LISTS)
    except PlyElementParseError:  # polygons (or a damaged file: the face-by-face read says where)
        return PlyData.read(str(path))


def _read_ply(path):
    import open3d as o3d

    _check_ply_header(path)
    try:
        ply = _read_plydata(path)
        vert = ply["vertex"].data
        face = ply["face"].data if "face" in [e.name for e in ply.elements] else None
    except Exception as e:
        raise MeshError(f"{path}: not a readable PLY file ({type(e).__name__}: {e})") from e
    names = list(vert.dtype.names or ())
    if not {"x", "y", "z"} <= set(names):
        raise MeshError(f"{path}: the vertices have no x, y, z")
    if face is not None and len(face):
        fkey = "vertex_indices" if "vertex_indices" in face.dtype.names else face.dtype.names[0]
        F = _triangulate(face[fkey], path)
        if F.min() < 0 or F.max() >= len(vert):
            raise MeshError(f"{path}: face indices out of range (corrupted file?)")
    else:
        F = None
    n = len(vert)
    geo, attrs = _geometry(F)
    xyz = [vert[c] for c in "xyz"]
    same = len({c.dtype.str for c in xyz}) == 1 and _code(xyz[0].dtype) in ("f4", "f8")
    ftype = xyz[0].dtype.newbyteorder("=") if same else np.dtype(np.float64)
    attrs["positions"] = o3d.core.Tensor(np.stack(xyz, 1).astype(ftype))
    used = {"x", "y", "z"}
    if {"nx", "ny", "nz"} <= set(names):
        N = np.stack([vert["nx"], vert["ny"], vert["nz"]], 1)
        attrs["normals"] = o3d.core.Tensor(N.astype(N.dtype.newbyteorder("=") if N.dtype.kind == "f" else np.float64))
        used |= {"nx", "ny", "nz"}
    reserved = _PLY_RESERVED | {"nx", "ny", "nz"}
    for comment in ply.comments:
        parsed = _parse_comment(comment, path)
        if parsed is None:
            continue
        name, c, dtype, shape = parsed
        target = "colors" if name == _COLORS_KEY else name
        cols = [name] if shape == () else [f"{name}_{j}" for j in range(c)]
        why = None
        if target in _RESERVED and not (name == _COLORS_KEY and c == 3 and shape in (None, (3,))):
            why = f"{name!r} is a reserved name"
        elif name in reserved or name in attrs:
            why = f"{name!r} is reserved or already read"
        elif not set(cols) <= set(names) - used or (shape == () and c != 1):
            why = "it names columns that do not exist or are already used"
        elif len({vert[nm].dtype.str for nm in cols}) != 1:
            why = "its columns have different types"
        if why is None:
            arr = _restore(np.stack([vert[nm] for nm in cols], 1), dtype)
            if arr is None:
                why = f"the columns ({vert[cols[0]].dtype}) do not hold {dtype} values"
        if why is not None:
            log.warning("%s: ignoring header comment %r: %s", path, comment, why)
            continue
        used |= set(cols)
        arr = arr.reshape((n,) + (shape if shape is not None else (c,)))
        attrs[target] = o3d.core.Tensor(np.ascontiguousarray(arr))
    if {"red", "green", "blue"} <= set(names):
        used |= {"red", "green", "blue"}
        if "colors" not in attrs:
            rgb = np.stack([vert["red"], vert["green"], vert["blue"]], 1)
            raw = [c.split()[2] for c in ply.comments if c.startswith(_RAW_COLORS + " ") and len(c.split()) == 3]
            restored = None
            if raw:
                try:
                    restored = _restore(rgb, np.dtype(raw[-1]))
                except TypeError:
                    restored = None
                if restored is None:
                    log.warning("%s: ignoring header comment %r: red green blue (%s) do not hold %s values",
                                path, f"{_RAW_COLORS} {raw[-1]}", rgb.dtype, raw[-1])
            if restored is not None:
                attrs["colors"] = o3d.core.Tensor(np.ascontiguousarray(restored))
            elif rgb.dtype.kind == "f" and rgb.dtype.itemsize in (4, 8):  # the values themselves
                attrs["colors"] = o3d.core.Tensor(np.ascontiguousarray(rgb.astype(rgb.dtype.newbyteorder("="))))
            else:
                scale = 255.0 if rgb.dtype == np.uint8 else (65535.0 if rgb.dtype == np.uint16 else 1.0)
                attrs["colors"] = o3d.core.Tensor((rgb / scale).astype(np.float32))
    for nm in names:
        if nm in used:
            continue
        if nm in _RESERVED or nm in attrs:
            log.warning("%s: ignoring vertex property %r (a reserved or already read attribute name)", path, nm)
            continue
        col = vert[nm]
        attrs[nm] = o3d.core.Tensor(np.ascontiguousarray(col.astype(col.dtype.newbyteorder("="))))
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
    r"""A TOML file as a dict (MeshError when it is missing, not UTF-8 or invalid).

    Examples
    --------
    >>> import pathlib, tempfile
    >>> from o3dheat.io import read_toml
    >>> p = pathlib.Path(tempfile.mkdtemp()) / "chain.toml"
    >>> _ = p.write_text('[[filter]]\nname = "scalar"\n')
    >>> read_toml(p)
    {'filter': [{'name': 'scalar'}]}
    """
    try:
        import tomllib
    except ImportError:  # pragma: no cover - Python 3.10
        import tomli as tomllib
    path = Path(path)
    try:
        return tomllib.loads(path.read_text(encoding="utf-8"))
    except UnicodeDecodeError as e:
        raise MeshError(f"{path}: not UTF-8 text ({e.reason} at byte {e.start})") from e
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
        if name == "positions" or arr.ndim == 0:
            raise MeshError(f"{path}: {key!r} is not a vertex attribute o3dheat writes (corrupt or crafted file)")
        if len(arr) != n:
            raise MeshError(f"{path}: {key!r} has {len(arr)} rows for {n} vertices")
        attrs[name] = o3d.core.Tensor(np.ascontiguousarray(arr))
    return geo


#: suffix -> reader (path -> tensor TriangleMesh or PointCloud): the formats read whole, in the
#: file's order; any other suffix goes to Open3D's mesh reader (positions and triangles). A format
#: is added here and, when it is an output of batches too, in :data:`WRITERS`.
READERS = {".ply": _read_ply, ".npz": _read_npz, ".stl": _read_stl, ".obj": _read_obj,
           **dict.fromkeys((".pcd", ".xyz", ".xyzn", ".xyzrgb", ".pts"), _read_points)}
#: suffix -> writer (path, attributes, faces or None, binary): what o3dheat writes, every attribute
#: kept (:func:`write_mesh`, :func:`write_geometry`; batch outputs).
WRITERS = {".ply": _write_ply, ".npz": _write_npz}
