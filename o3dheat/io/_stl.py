"""The STL reader (binary and ASCII): :func:`read_stl`, a triangle soup.

Notes
-----
Binary: an 80-byte header, a triangle count and 50 bytes per triangle, read in one block (Open3D's
reader takes 6 s for 2M triangles); a file whose size is not that of its count is ASCII or
truncated. ASCII: every ``facet`` must be complete (``outer loop``, three ``vertex`` lines,
``endloop``, ``endfacet``) and the file must end with ``endsolid``: a truncated file is refused,
naming the facet and the line, never read as part of a mesh.
"""

from __future__ import annotations

import numpy as np

from o3dheat.errors import MeshError

from ._geometry import soup

__all__ = ["read_stl"]


_STL_TRIANGLE = np.dtype([("normal", "<f4", (3,)), ("corners", "<f4", (3, 3)), ("attribute", "<u2")])


def read_stl(path):
    """A binary or ASCII STL as a triangle soup (:func:`o3dheat.io._geometry.soup`; the format
    rules in the module's Notes)."""
    size = path.stat().st_size
    with open(path, "rb") as fh:
        head = fh.read(84)
        count = int(np.frombuffer(head[80:84], "<u4")[0]) if len(head) == 84 else -1
        if count >= 0 and size == 84 + _STL_TRIANGLE.itemsize * count:
            if count == 0:
                raise MeshError(f"{path}: no triangles could be read (a binary STL of 0 triangles)")
            return soup(np.fromfile(fh, dtype=_STL_TRIANGLE, count=count)["corners"])
    text = path.read_bytes()
    if not text.lstrip()[:5].lower() == b"solid" or b"\0" in text[:1024]:
        if count >= 0:
            raise MeshError(f"{path}: not a readable STL: as binary STL its header declares {count} triangles "
                            f"({84 + _STL_TRIANGLE.itemsize * count} bytes), the file has {size} bytes "
                            "(truncated or corrupt), and it is not ASCII STL (no 'solid')")
        raise MeshError(f"{path}: not a readable STL file ({size} bytes)")
    return soup(_ascii_stl_corners(text.decode("ascii", errors="replace"), path))


_STL_FACET = ("facet", "outer", "vertex", "vertex", "vertex", "endloop", "endfacet")


def _ascii_stl_corners(text, path):
    """(3 m, 3) float64 corners of an ASCII STL, its structure checked (see the module's Notes)."""
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
