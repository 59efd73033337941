"""Compiled loops over faces: :func:`double_areas`, :func:`corner_geometry`, :func:`pattern`,
:func:`fill`, :func:`components`, :func:`abs_row_sums`, :func:`first_rows`.

The loops of :mod:`o3dheat.geometry` and :mod:`o3dheat.spectral.fem`, compiled
(:func:`o3dheat._jit.compiled`): triangle areas, corner cotangents, and the one sparsity pattern
that the stiffness and the consistent mass share, filled in one pass; connected components, row
sums, and the first copies of rows.

Each loop visits the faces in their order and adds into each entry in that order, so results do
not depend on anything but the input. Vertex indices are int64.
"""

from __future__ import annotations

import numpy as np

from o3dheat._jit import compiled
from o3dheat.errors import MeshError

__all__ = ["double_areas", "corner_geometry", "pattern", "fill", "components", "abs_row_sums", "first_rows"]


def _checked(V, F):
    """(V, F) as the loops read them, the face indices checked (compiled loops check no bounds)."""
    V = np.ascontiguousarray(V, dtype=np.float64)
    F = np.ascontiguousarray(F, dtype=np.int64)
    if F.ndim != 2 or F.shape[1] != 3 or V.ndim != 2 or V.shape[1] != 3:
        raise MeshError(f"faces must have shape (m, 3) and vertices (n, 3), got {F.shape} and {V.shape}")
    if F.size and (F.min() < 0 or F.max() >= len(V)):
        raise MeshError(f"face indices must lie in [0, {len(V) - 1}] (the vertices), got {F.min()}..{F.max()}")
    return V, F


def _double_areas(V, F):
    m = F.shape[0]
    out = np.empty(m)
    for t in range(m):
        a, b, c = F[t, 0], F[t, 1], F[t, 2]
        ux, uy, uz = V[b, 0] - V[a, 0], V[b, 1] - V[a, 1], V[b, 2] - V[a, 2]
        vx, vy, vz = V[c, 0] - V[a, 0], V[c, 1] - V[a, 1], V[c, 2] - V[a, 2]
        cx, cy, cz = uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx
        out[t] = np.sqrt(cx * cx + cy * cy + cz * cz)
    return out


def double_areas(V, F):
    """``2 |t|`` of every face: ``‖(v1 − v0) × (v2 − v0)‖``, (m,) float64.

    Examples
    --------
    >>> import numpy as np
    >>> from o3dheat.geometry._loops import double_areas
    >>> double_areas(np.eye(3), np.array([[0, 1, 2]])).round(4).tolist()
    [1.7321]
    """
    V, F = _checked(V, F)
    return compiled(_double_areas)(V, F)


def _corner_geometry(V, F):
    m = F.shape[0]
    dbl = np.empty(m)
    cot = np.empty((m, 3))
    sq = np.empty((m, 3))
    e = np.empty((3, 3))
    for t in range(m):
        for i in range(3):  # e_i = p[i+2] - p[i+1], the edge opposite corner i
            p, q = F[t, (i + 1) % 3], F[t, (i + 2) % 3]
            for d in range(3):
                e[i, d] = V[q, d] - V[p, d]
        cx = e[0, 1] * e[1, 2] - e[0, 2] * e[1, 1]
        cy = e[0, 2] * e[1, 0] - e[0, 0] * e[1, 2]
        cz = e[0, 0] * e[1, 1] - e[0, 1] * e[1, 0]
        a2 = np.sqrt(cx * cx + cy * cy + cz * cz)
        dbl[t] = a2
        for i in range(3):
            # cot at corner i = <a, b> / |a x b| with a, b the edges leaving it: -e_{i+2}, e_{i+1}
            j, k = (i + 2) % 3, (i + 1) % 3
            dot = -(e[j, 0] * e[k, 0] + e[j, 1] * e[k, 1] + e[j, 2] * e[k, 2])
            cot[t, i] = dot / a2 if a2 > 0 else 0.0  # a zero-area face: refused by the caller
            sq[t, i] = e[i, 0] * e[i, 0] + e[i, 1] * e[i, 1] + e[i, 2] * e[i, 2]
    return dbl, cot, sq


def corner_geometry(V, F):
    """Per face: double area (m,), the cotangent at each corner (m, 3) and the squared length of
    the edge opposite each corner (m, 3).

    Examples
    --------
    >>> import numpy as np
    >>> from o3dheat.geometry._loops import corner_geometry
    >>> dbl, cot, sq = corner_geometry(np.array([[0., 0, 0], [1, 0, 0], [0, 1, 0]]), np.array([[0, 1, 2]]))
    >>> dbl.tolist(), (cot + 0.0).round(6).tolist(), sq.tolist()
    ([1.0], [[0.0, 1.0, 1.0]], [[2.0, 1.0, 1.0]])
    """
    return compiled(_corner_geometry)(*_checked(V, F))


def _pattern(F, n):
    m = F.shape[0]
    count = np.zeros(n + 1, np.int64)
    for t in range(m):
        for a in range(3):
            count[F[t, a] + 1] += 2
    start = np.cumsum(count)
    pos = start[:-1].copy()
    cand = np.empty(6 * m, np.int64)
    for t in range(m):
        for a in range(3):
            i = F[t, a]
            cand[pos[i]] = F[t, (a + 1) % 3]
            cand[pos[i] + 1] = F[t, (a + 2) % 3]
            pos[i] += 2
    indptr = np.zeros(n + 1, np.int64)
    indices = np.empty(6 * m + n, np.int64)
    nnz = 0
    for i in range(n):
        # the row's neighbours (repeated) and the vertex itself, insertion-sorted in place, then
        # the repeats squeezed out (a row holds a dozen entries)
        r = nnz
        indices[r] = i
        size = 1 + start[i + 1] - start[i]
        if size > 64:  # a vertex of many faces (a fan): a real sort
            indices[r + 1:r + size] = cand[start[i]:start[i + 1]]
            row = indices[r:r + size].copy()  # (numba's quicksort is quadratic on a fan's order)
            indices[r:r + size] = row[np.argsort(row, kind="mergesort")]
        else:
            size = 1
            for p in range(start[i], start[i + 1]):
                v = cand[p]
                q = r + size
                while q > r and indices[q - 1] > v:
                    indices[q] = indices[q - 1]
                    q -= 1
                indices[q] = v
                size += 1
        last = -1
        for p in range(r, r + size):
            v = indices[p]
            if v != last:
                indices[nnz] = v
                nnz += 1
                last = v
        indptr[i + 1] = nnz
    return indptr, indices[:nnz].copy()


def pattern(F, n):
    """The CSR pattern (indptr, sorted indices) of the vertex adjacency of the faces, diagonal
    included: the pattern of the stiffness and of the consistent mass.

    Examples
    --------
    >>> import numpy as np
    >>> from o3dheat.geometry._loops import pattern
    >>> [a.tolist() for a in pattern(np.array([[0, 1, 2], [1, 3, 2]]), 4)]
    [[0, 3, 7, 11, 14], [0, 1, 2, 0, 1, 2, 3, 0, 1, 2, 3, 1, 2, 3]]
    """
    return compiled(_pattern)(_checked(np.zeros((int(n), 3)), F)[1], int(n))


def _fill(F, cot, dbl, sq, indptr, indices, consistent, n):
    m = F.shape[0]
    L = np.zeros(len(indices))
    B = np.zeros(len(indices) if consistent else 0)
    vor = np.zeros(n)
    lumped = np.zeros(n)
    pos = np.empty(4, np.int64)
    for t in range(m):
        area = 0.5 * dbl[t]
        obtuse = cot[t, 0] < 0 or cot[t, 1] < 0 or cot[t, 2] < 0
        for c in range(3):  # corner c weights the edge (c+1, c+2)
            i, j = F[t, (c + 1) % 3], F[t, (c + 2) % 3]
            for q, (r, col) in enumerate(((i, j), (j, i), (i, i), (j, j))):
                lo, hi = indptr[r], indptr[r + 1]
                while lo < hi:  # binary search in the sorted row (a fan's centre has thousands)
                    mid = (lo + hi) // 2
                    if indices[mid] < col:
                        lo = mid + 1
                    else:
                        hi = mid
                pos[q] = lo
            w = -0.5 * cot[t, c]
            L[pos[0]] += w
            L[pos[1]] += w
            L[pos[2]] -= w
            L[pos[3]] -= w
            if consistent:
                for q in range(4):  # B_ij = |t|/12; each vertex gets |t|/6 from its two edges here
                    B[pos[q]] += area / 12.0
            # mixed Voronoi area of corner c (Meyer et al.): the Voronoi region of a non-obtuse
            # triangle, else half the area at the obtuse corner and a quarter at the others
            v = F[t, c]
            if obtuse:
                vor[v] += area / 2.0 if cot[t, c] < 0 else area / 4.0
            else:
                a, b = (c + 1) % 3, (c + 2) % 3
                vor[v] += (sq[t, a] * cot[t, a] + sq[t, b] * cot[t, b]) / 8.0
            lumped[v] += area / 3.0
    return L, B, vor, lumped


def fill(F, cot, dbl, sq, indptr, indices, n, consistent=True):
    """On the pattern: the stiffness values ``L_ij = −(cot α + cot β)/2``, ``L_ii = −Σ_j L_ij``;
    when ``consistent``, the consistent mass ``B_ij = (|t_r| + |t_s|)/12``, ``B_ii = Σ |t|/6``
    (else an empty array); and per vertex the mixed Voronoi areas and the lumped mass ``Σ |t|/3``.

    Examples
    --------
    >>> import numpy as np
    >>> from o3dheat.geometry._loops import corner_geometry, fill, pattern
    >>> V, F = np.array([[0., 0, 0], [1, 0, 0], [0, 1, 0]]), np.array([[0, 1, 2]])
    >>> ip, ix = pattern(F, 3)
    >>> dbl, cot, sq = corner_geometry(V, F)
    >>> L, B, vor, lumped = fill(F, cot, dbl, sq, ip, ix, 3)
    >>> L.round(3).tolist(), (B * 24).round(3).tolist()
    ([1.0, -0.5, -0.5, -0.5, 0.5, 0.0, -0.5, 0.0, 0.5], [2.0, 1.0, 1.0, 1.0, 2.0, 1.0, 1.0, 1.0, 2.0])
    >>> vor.tolist(), (3 * lumped).tolist()
    ([0.25, 0.125, 0.125], [0.5, 0.5, 0.5])
    """
    return compiled(_fill)(np.ascontiguousarray(F, dtype=np.int64), np.ascontiguousarray(cot),
                           np.ascontiguousarray(dbl), np.ascontiguousarray(sq), indptr, indices, bool(consistent),
                           int(n))


def _components(F, n):
    parent = np.arange(n)
    for t in range(F.shape[0]):
        a = F[t, 0]
        for c in range(1, 3):
            b = F[t, c]
            while parent[a] != a:  # find, halving the paths
                parent[a] = parent[parent[a]]
                a = parent[a]
            while parent[b] != b:
                parent[b] = parent[parent[b]]
                b = parent[b]
            if a != b:
                if a < b:
                    parent[b] = a
                else:
                    parent[a] = b
                    a = b
    labels = np.empty(n, np.int64)
    count = 0
    for i in range(n):  # roots are their part's smallest vertex: parts numbered by it
        r = i
        while parent[r] != r:
            r = parent[r]
        if r == i:
            labels[i] = count
            count += 1
        else:
            labels[i] = labels[r]
    return count, labels


def components(F, n):
    """The connected parts of the faces' vertices: ``(count, labels)``, parts numbered in the
    order of their smallest vertex (a vertex in no face is a part of its own).

    Examples
    --------
    >>> import numpy as np
    >>> from o3dheat.geometry._loops import components
    >>> count, labels = components(np.array([[3, 4, 5], [0, 1, 2]]), 7)
    >>> count, labels.tolist()
    (3, [0, 0, 0, 1, 1, 1, 2])
    """
    return compiled(_components)(np.ascontiguousarray(F, dtype=np.int64), int(n))


def _abs_row_sums(indptr, data):
    n = len(indptr) - 1
    out = np.zeros(n)
    for i in range(n):
        s = 0.0
        for p in range(indptr[i], indptr[i + 1]):
            s += abs(data[p])
        out[i] = s
    return out


def abs_row_sums(indptr, data):
    """``Σ_j |M_ij|`` of a CSR matrix's rows.

    Examples
    --------
    >>> import numpy as np
    >>> from o3dheat.geometry._loops import abs_row_sums
    >>> abs_row_sums(np.array([0, 2, 3]), np.array([1.0, -2.0, 4.0])).tolist()
    [3.0, 4.0]
    """
    return compiled(_abs_row_sums)(indptr, np.ascontiguousarray(data, dtype=np.float64))


def _first_rows(H, E, bits):
    m = H.shape[0]
    size = 1
    while size < 2 * m:
        size *= 2
    slots = size - 1
    keep = np.uint64(slots) if bits >= 64 else np.uint64((1 << bits) - 1)
    table = np.full(size, -1, np.int64)
    first = np.empty(m, np.int64)
    c1, c2 = np.uint64(0xBF58476D1CE4E5B9), np.uint64(0x94D049BB133111EB)
    s30, s27, s31 = np.uint64(30), np.uint64(27), np.uint64(31)
    for i in range(m):
        h = np.uint64(0)
        for c in range(3):  # splitmix64's finalizer, word by word: every input bit reaches every output bit
            x = h ^ H[i, c]
            x = (x ^ (x >> s30)) * c1
            x = (x ^ (x >> s27)) * c2
            h = x ^ (x >> s31)
        p = np.int64(h & keep & np.uint64(slots))
        while True:  # open addressing; rows are compared exactly (NaN equals nothing)
            j = table[p]
            if j < 0:
                table[p] = i
                first[i] = i
                break
            if E[j, 0] == E[i, 0] and E[j, 1] == E[i, 1] and E[j, 2] == E[i, 2]:
                first[i] = j
                break
            p = (p + 1) & slots
    return first


def first_rows(H, E, bits=64):
    """For each row of ``E`` (m, 3), the smallest index of a row equal to it (itself when none
    is), in one pass: a hash table on the words ``H`` (m, 3) uint64, which must be equal for
    equal rows, with exact comparisons of ``E``. ``bits`` keeps that many bits of the hash (fewer:
    more collisions, for tests).

    Examples
    --------
    >>> import numpy as np
    >>> from o3dheat.geometry._loops import first_rows
    >>> E = np.array([[1, 2, 3], [4, 5, 6], [1, 2, 3], [4, 5, 6]])
    >>> first_rows(E.view(np.uint64), E).tolist(), first_rows(E.view(np.uint64), E, bits=1).tolist()
    ([0, 1, 0, 1], [0, 1, 0, 1])
    """
    return compiled(_first_rows)(np.ascontiguousarray(H, dtype=np.uint64), np.ascontiguousarray(E), int(bits))
