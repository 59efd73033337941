"""The Wavefront OBJ reader: :func:`read_obj`, the file's vertices in the file's order.

Notes
-----
Read: ``v x y z`` (and ``v x y z r g b``: colours, when every vertex has them), ``vt``, ``vn`` and
``f`` with the index forms ``i``, ``i/t``, ``i//n``, ``i/t/n``; indices from 1, negative ones
counting back from the last element read; polygons fanned from their first corner. Texture
coordinates, when every corner of every face has one, go to the triangles:
``triangle["texture_uvs"]`` (m, 3, 2), Open3D's layout. Normals (per corner in OBJ) are checked,
not kept. Comments, groups, objects, materials, smoothing groups, lines and points are ignored. A
malformed line (a ``v`` without three numbers, an index that is not an integer, is 0 or out of
range, a face of fewer than three corners) is a MeshError naming the line. (Open3D's own reader
splits the vertices at texture seams and merges coincident ones: other vertices than the file's.)
"""

from __future__ import annotations

import logging

import numpy as np

from o3dheat.errors import MeshError

__all__ = ["read_obj"]

log = logging.getLogger("o3dheat")


def read_obj(path):
    """A Wavefront OBJ as a tensor mesh with the file's vertices, in the file's order (the rules
    in the module's Notes)."""
    import open3d as o3d

    # utf-8-sig: a byte-order mark (Windows tools write one) is not part of the first line's keyword,
    # which would otherwise read "\ufeffv" and lose the first vertex (every index then off by one)
    v, vt, f = _obj_lines(path.read_bytes().decode("utf-8-sig", errors="replace"))
    if not v:
        raise MeshError(f"{path}: no vertices ('v' lines) could be read (unreadable or empty OBJ)")
    if not f:
        raise MeshError(f"{path}: no triangles could be read (an OBJ without 'f' lines)")
    V, colors = _obj_numbers(v, path, "v", (3, 4, 6, 7))
    uv = None
    if vt:
        uv = _obj_numbers(vt, path, "vt", (2, 3, 1))[0]
        uv = np.c_[uv, np.zeros(len(uv))] if uv.shape[1] == 1 else uv[:, :2]  # "vt u": v = 0
    counts, vi, ti, has_t = _obj_faces(f, path)
    c = _fan(counts)
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


def _obj_lines(text):
    """The ``v``, ``vt`` and ``f`` lines of an OBJ: (line number, rest of the line), faces also
    with the counts of ``v``, ``vt`` and ``vn`` lines before them (what negative indices count from)."""
    v, vt, f = [], [], []
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
    return v, vt, f


def _obj_faces(f, path):
    """(corners per face, 0-based vertex index per corner, texture index per corner or None,
    which corners have a texture index) of the ``f`` lines, every index checked (normal indices
    too, then dropped)."""
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
    return counts, vi, ti, has_t


def _fan(counts):
    """(t, 3) corner numbers of the triangles fanning faces of ``counts`` corners from their first
    corner: corner j of face i is ``start[i] + j``."""
    start = np.r_[0, np.cumsum(counts)[:-1]]
    tri_face = np.repeat(np.arange(len(counts)), counts - 2)
    j = np.arange(len(tri_face)) - np.repeat(np.cumsum(counts - 2) - (counts - 2), counts - 2)
    return np.stack([start[tri_face], start[tri_face] + 1 + j, start[tri_face] + 2 + j], axis=1)


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
