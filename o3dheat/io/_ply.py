"""The PLY codec (plyfile): :func:`read_ply` and :func:`write_ply`, every vertex attribute kept
exactly (colours in 8 bits unless asked otherwise), the header checked against the file size
before plyfile allocates anything.

Notes
-----
PLY layout written here: ``x y z`` in the positions' own float type (float or double),
``nx ny nz`` (the normals' float type) when there are normals, and colours as ``uchar red green
blue``, what every viewer reads (Open3D's readers, MeshLab, trimesh): float colours as
``round(255 * c)`` of ``c`` clipped to [0, 1] (as Open3D's own writer does; a warning counts the
colours clipping changed; NaN or infinite colours are refused with a :class:`MeshError`), read
back as ``k / 255`` (within 1/510 of what was written) in float32, or in float64 for float64
colours (header comment ``o3dheat colors <f8``); uint8 colours as they are (comment ``o3dheat
colors |u1``: read back as uint8); other dtypes are refused. With ``lossless_colors=True`` float
colours that 8 bits do not give back exactly (float32 multiples of 1/255 need nothing more) are
also stored exactly, as ``o3dheat_colors_0..2`` in their own type with the comment ``o3dheat
attribute o3dheat_colors 3 DTYPE``, which o3dheat's reader gives back as ``colors``. Files of
earlier versions, with ``float``/``double`` or other ``red green blue`` (read as they are), read as
before. Any other vertex attribute ``a`` of shape (n,) is a property
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
"""

from __future__ import annotations

import logging
import re

import numpy as np
from plyfile import PlyData, PlyElement, PlyElementParseError

from o3dheat.errors import MeshError

from ._geometry import RESERVED, new_geometry
from .files import atomic_write

__all__ = ["read_ply", "write_ply"]

log = logging.getLogger("o3dheat")


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


def _ply_colors(C, path, lossless):
    """(the (n, 3) uint8 ``red green blue``, the header comment giving their dtype back or None,
    the exact copy to store as ``o3dheat_colors_0..2`` or None) of colours ``C``, or MeshError
    (the rules in the module's Notes)."""
    if C.ndim != 2 or C.shape[1] != 3:
        raise MeshError(f"cannot write {path}: colors must have shape (n, 3), got {C.shape}: use .npz")
    if C.dtype == np.uint8:
        return C, f"{_RAW_COLORS} {C.dtype.str}", None
    if _code(C.dtype) not in ("f4", "f8"):
        raise MeshError(f"cannot write {path}: colors of dtype {C.dtype}: PLY stores colours as 8-bit red green "
                        f"blue: give float colours in [0, 1] or uint8 (or rename the attribute to keep its values)")
    bad = ~np.isfinite(C).all(axis=1)
    if bad.any():
        raise MeshError(f"cannot write {path}: {int(bad.sum())} of {len(C)} vertex colours NaN or infinite (the "
                        f"first at vertex {int(np.flatnonzero(bad)[0])}): PLY stores colours as 8-bit red green blue "
                        f"in [0, 1]: fix them, or rename the attribute to keep its values")
    scaled = np.asarray(C, dtype=np.float64) * 255
    clipped = ((scaled < -0.5) | (scaled >= 255.5)).any(axis=1)  # where clipping changes the byte
    if clipped.any():
        log.warning("%s: %d of %d vertex colours outside [0, 1] (from %g to %g) clipped to [0, 1] in the 8-bit "
                    "red green blue%s", path, int(clipped.sum()), len(C), float(C.min()), float(C.max()),
                    " (the exact values are kept in o3dheat_colors_*)" if lossless else "")
    u8 = np.floor(np.clip(scaled, 0, 255) + 0.5).astype(np.uint8)  # halves up, as Open3D's std::round
    exact = np.array_equal((u8 / 255.0).astype(C.dtype), C)
    comment = None if C.dtype == np.float32 else f"{_RAW_COLORS} {C.dtype.str}"
    return u8, comment, (C if lossless and not exact else None)


def _ply_vertex_table(attrs, path, lossless_colors=False):
    """(fields [(property, dtype str)], columns, header comments) of the PLY vertex element, or
    MeshError (naming the attribute and why) for any attribute PLY cannot give back exactly
    (colours: 8 bits, and exactly with ``lossless_colors``)."""
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
        u8, comment, copy = _ply_colors(attrs["colors"], path, lossless_colors)
        add("colors", ["red", "green", "blue"], [u8[:, 0], u8[:, 1], u8[:, 2]])
        if comment:
            comments.append(comment)
        if copy is not None:  # lossless_colors: the exact values beside the 8-bit ones
            add("colors", [f"{_COLORS_KEY}_{j}" for j in range(3)], [copy[:, 0], copy[:, 1], copy[:, 2]])
            comments.append(f"o3dheat attribute {_COLORS_KEY} 3 {copy.dtype.str}")
    for key, arr in attrs.items():
        if key in RESERVED:
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


def write_ply(path, attrs, F, binary, lossless_colors=False):
    """Write positions, faces (or None) and attributes to ``path`` atomically, binary (little-endian)
    or ASCII, colours as 8-bit ``red green blue`` (plus their exact copy with ``lossless_colors``);
    MeshError, before anything is written, for an attribute PLY cannot give back exactly."""
    n = len(attrs["positions"])
    fields, cols, comments = _ply_vertex_table(attrs, path, lossless_colors)
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
    try:
        return PlyData.read(str(path), known_list_len=_TRIANGLE_LISTS)
    except PlyElementParseError:  # polygons (or a damaged file: the face-by-face read says where)
        return PlyData.read(str(path))


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


def read_ply(path):
    """A PLY as a tensor mesh (a point cloud without a face element), every vertex property kept:
    positions and normals, attributes the header comments describe restored with their shape and
    dtype, colours, and every other property as an attribute of its own (the rules in the
    module's Notes)."""
    import open3d as o3d

    ply, vert, F = _ply_elements(path)
    names = list(vert.dtype.names or ())
    geo, attrs = new_geometry(F)
    xyz = [vert[c] for c in "xyz"]
    same = len({c.dtype.str for c in xyz}) == 1 and _code(xyz[0].dtype) in ("f4", "f8")
    ftype = xyz[0].dtype.newbyteorder("=") if same else np.dtype(np.float64)
    attrs["positions"] = o3d.core.Tensor(np.stack(xyz, 1).astype(ftype))
    used = {"x", "y", "z"}
    if {"nx", "ny", "nz"} <= set(names):
        N = np.stack([vert["nx"], vert["ny"], vert["nz"]], 1)
        attrs["normals"] = o3d.core.Tensor(N.astype(N.dtype.newbyteorder("=") if N.dtype.kind == "f" else np.float64))
        used |= {"nx", "ny", "nz"}
    for comment in ply.comments:
        _read_commented(comment, vert, names, attrs, used, path)
    if {"red", "green", "blue"} <= set(names):
        used |= {"red", "green", "blue"}
        if "colors" not in attrs:
            attrs["colors"] = o3d.core.Tensor(_read_colors(ply.comments, vert, path))
    for nm in names:
        if nm in used:
            continue
        if nm in RESERVED or nm in attrs:
            log.warning("%s: ignoring vertex property %r (a reserved or already read attribute name)", path, nm)
            continue
        col = vert[nm]
        attrs[nm] = o3d.core.Tensor(np.ascontiguousarray(col.astype(col.dtype.newbyteorder("="))))
    return geo


def _ply_elements(path):
    """(PlyData, its vertex rows, its faces as (m, 3) int64 triangles or None) of a PLY file, the
    header checked first (:func:`_check_ply_header`), the vertices with x, y, z, the face indices
    in range."""
    _check_ply_header(path)
    try:
        ply = _read_plydata(path)
        vert = ply["vertex"].data
        face = ply["face"].data if "face" in [e.name for e in ply.elements] else None
    except Exception as e:
        raise MeshError(f"{path}: not a readable PLY file ({type(e).__name__}: {e})") from e
    if not {"x", "y", "z"} <= set(vert.dtype.names or ()):
        raise MeshError(f"{path}: the vertices have no x, y, z")
    if face is None or not len(face):
        return ply, vert, None
    fkey = "vertex_indices" if "vertex_indices" in face.dtype.names else face.dtype.names[0]
    F = _triangulate(face[fkey], path)
    if F.min() < 0 or F.max() >= len(vert):
        raise MeshError(f"{path}: face indices out of range (corrupted file?)")
    return ply, vert, F


def _read_commented(comment, vert, names, attrs, used, path):
    """Restore into ``attrs`` the attribute a header comment ``o3dheat attribute ...`` describes,
    adding its columns to ``used``; a comment that does not fit the file is ignored with a warning."""
    import open3d as o3d

    parsed = _parse_comment(comment, path)
    if parsed is None:
        return
    name, c, dtype, shape = parsed
    target = "colors" if name == _COLORS_KEY else name
    cols = [name] if shape == () else [f"{name}_{j}" for j in range(c)]
    why = None
    if target in RESERVED and not (name == _COLORS_KEY and c == 3 and shape in (None, (3,))):
        why = f"{name!r} is a reserved name"
    elif name in _PLY_RESERVED | {"nx", "ny", "nz"} or name in attrs:
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
        return
    used |= set(cols)
    arr = arr.reshape((len(vert),) + (shape if shape is not None else (c,)))
    attrs[target] = o3d.core.Tensor(np.ascontiguousarray(arr))


def _read_colors(comments, vert, path):
    """The colours of ``red green blue``: the dtype a header comment ``o3dheat colors DTYPE``
    gives back (uint8 as they are, a float dtype the 8-bit values / 255 in it), float values as
    they are, integers scaled to [0, 1] (float32)."""
    rgb = np.stack([vert["red"], vert["green"], vert["blue"]], 1)
    raw = [c.split()[2] for c in comments if c.startswith(_RAW_COLORS + " ") and len(c.split()) == 3]
    restored = None
    if raw:
        try:
            dtype = np.dtype(raw[-1])
            if rgb.dtype == np.uint8 and _code(dtype) in ("f4", "f8"):
                restored = (rgb / 255.0).astype(dtype.newbyteorder("="))
            else:
                restored = _restore(rgb, dtype)
        except TypeError:
            restored = None
        if restored is None:
            log.warning("%s: ignoring header comment %r: red green blue (%s) do not hold %s values",
                        path, f"{_RAW_COLORS} {raw[-1]}", rgb.dtype, raw[-1])
    if restored is not None:
        return np.ascontiguousarray(restored)
    if rgb.dtype.kind == "f" and rgb.dtype.itemsize in (4, 8):  # the values themselves
        return np.ascontiguousarray(rgb.astype(rgb.dtype.newbyteorder("=")))
    scale = 255.0 if rgb.dtype == np.uint8 else (65535.0 if rgb.dtype == np.uint16 else 1.0)
    return (rgb / scale).astype(np.float32)
