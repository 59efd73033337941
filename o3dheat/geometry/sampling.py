"""Resamplings of a surface, each a :class:`Resampled`: :func:`decimate`, :func:`remesh`,
:func:`anisotropic`, :func:`jitter`, :func:`subdivide`, by name :func:`resample` (:data:`KINDS`).

Resamplings (each returns a :class:`Resampled`: a new tensor mesh plus what relates it to its
source; all deterministic, seeded where random):

* :func:`decimate`: quadric decimation (fast-simplification), curvature-adaptive, with the map
  from source vertices to decimated vertices (its collapse replay);
* :func:`remesh`: isotropic explicit remeshing (pymeshlab), a uniform sampling;
* :func:`anisotropic`: one half of the surface coarse and the other fine (pymeshlab remeshing of
  each half), the strongly non-uniform density of the paper's irregular examples;
* :func:`jitter`: vertices moved at random in their tangent planes, no face folded;
* :func:`subdivide`: midpoint (same surface) or Loop subdivision.

Moving functions between samplings: :mod:`o3dheat.geometry.interpolation`; point clouds:
:mod:`o3dheat.geometry.points`.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from o3dheat import checks
from o3dheat.errors import MeshError
from o3dheat.memory import check_memory, give_back

from ._meshlab import area, bound_faces, faces_at, isotropic, meshset
from ._simplify import simplify
from ._tables import degenerate, non_manifold_edge_faces, non_manifold_vertex_mask, unique_rows, vertex_normals
from .mesh import as_arrays

if TYPE_CHECKING:  # o3dheat.typing imports Open3D (1.5 s), which arrays never need: for annotations only
    import open3d as o3d

    from o3dheat.typing import MeshLike

__all__ = ["Resampled", "warm_up", "decimate", "decimate_bytes", "remesh", "anisotropic", "jitter", "subdivide", "resample", "KINDS",
           "MIN_FACES", "REMESH_MAX_FACES"]

log = logging.getLogger("o3dheat")


@dataclass(frozen=True)
class Resampled:
    """A new sampling of a surface.

    Attributes
    ----------
    V : (r, 3) float64 ndarray
    F : (m, 3) int64 ndarray
    kind : str
        "decimate", "remesh", "anisotropic", "jitter" or "subdivide".
    params : dict
        The parameters used.
    vertex_map : (n,) int64 ndarray or None
        For each source vertex, the new vertex it became (decimate: the vertex it collapsed into,
        -1 when it was removed with a non-manifold face; jitter: the identity; subdivide: the same
        index, the new vertices come after). None when no such map exists (remeshing).

    Examples
    --------
    Every function of this module returns one; every o3dheat function takes one as a mesh:

    >>> import open3d as o3d, o3dheat
    >>> from o3dheat.geometry.sampling import subdivide
    >>> r = subdivide(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 10))
    >>> r.kind, r.params, r.V.shape, r.F.shape
    ('subdivide', {'iterations': 1, 'method': 'midpoint'}, (722, 3), (1440, 3))
    >>> r.mesh.vertex.positions.shape, o3dheat.check_mesh(r).euler_characteristic
    (SizeVector[722, 3], 2)
    """

    V: np.ndarray
    F: np.ndarray
    kind: str
    params: dict = field(default_factory=dict)
    vertex_map: np.ndarray | None = None

    @property
    def mesh(self) -> o3d.t.geometry.TriangleMesh:
        """The sampling as a new ``o3d.t.geometry.TriangleMesh``."""
        import open3d as o3d

        m = o3d.t.geometry.TriangleMesh()
        m.vertex.positions = o3d.core.Tensor(self.V)
        m.triangle.indices = o3d.core.Tensor(self.F)
        return m

    @property
    def arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """The sampling as the pair ``(V, F)``: (r, 3) float64 positions, (m, 3) int64 faces."""
        return self.V, self.F

    def __repr__(self):
        return f"Resampled({self.kind}, {self.params}, vertices={len(self.V)}, faces={len(self.F)})"


#: the fewest faces a resampling may leave (a tetrahedron's)
MIN_FACES = 4


def _check_result(V, F, kind, params):
    if len(F) < MIN_FACES or len(V) < 4:
        raise MeshError(f"{kind} with {params} left {len(F)} faces: choose a milder setting")


def _clean(V, F, vertex_map=None):
    """A 2-manifold: degenerate and duplicate faces dropped, then the faces at non-manifold edges
    and vertices (rare after a decimation or remeshing, fatal to the topology), unreferenced
    vertices removed; ``vertex_map`` (source -> V) is carried along. (Dropping, not splitting as
    :func:`o3dheat.repair <o3dheat.geometry.repairs.repair>` does, keeps the vertex map one-to-one.)"""
    F = np.asarray(F, dtype=np.int64)
    F = F[~degenerate(F)]
    _, first = unique_rows(np.sort(F, axis=1), return_index=True)
    F = F[np.sort(first)]
    n0 = len(F)
    for _ in range(10):  # dropping faces can leave new non-manifold vertices: a few rounds
        drop = non_manifold_edge_faces(F, len(V)) | non_manifold_vertex_mask(F, len(V))[F].any(axis=1)
        if not drop.any():
            break
        F = F[~drop]
    if len(F) < n0:
        log.info("%d faces removed to keep a 2-manifold", n0 - len(F))
    used = np.zeros(len(V), bool)
    used[F.reshape(-1)] = True
    remap = np.full(len(V), -1, np.int64)
    remap[used] = np.arange(int(used.sum()))
    if vertex_map is not None:
        vertex_map = np.where(vertex_map >= 0, remap[np.maximum(vertex_map, 0)], -1)
    return V[used], remap[F], vertex_map


def decimate_bytes(faces: int, vertex_map: bool = True) -> int:
    """Peak memory of :func:`decimate` on a mesh of ``faces`` faces, in bytes, beyond the mesh.

    fast-simplification keeps per face its vertices, error terms and flags, and per vertex a
    quadric and its faces: measured 395-446 bytes per input face from 2M to 8M faces (755 at 500k,
    where the fixed part shows), 675-737 with the collapse replay of ``vertex_map``, on a
    curvature-adaptive and a uniform mesh (``scripts/bench_memory.py``). This is 400 (680) bytes
    per face and 180 MiB: 3-13% above each measured peak.

    Parameters
    ----------
    faces : int
        Faces of the mesh to decimate.
    vertex_map : bool
        As for :func:`decimate`.

    Returns
    -------
    int

    Examples
    --------
    >>> from o3dheat.geometry.sampling import decimate_bytes
    >>> round(decimate_bytes(20_000_000, vertex_map=False) / 2**30, 1)    # a 10M-vertex scan
    7.6
    """
    return int((680 if vertex_map else 400) * faces + 180 * 2**20)


def decimate(mesh: MeshLike, reduction: float = 0.7, target_faces: int | None = None, *,
             vertex_map: bool = True) -> Resampled:
    """Quadric decimation (fast-simplification): fewer vertices where the surface is flat.

    One decimation at a time (fast-simplification's state is module-wide); a mesh of more than
    ``o3dheat.geometry._simplify.CHILD_FACES`` (1M) faces is decimated in a forked child process,
    so that the library's work space (about 300 bytes per face, which it keeps until exit) leaves
    with it. The memory needed is checked first (:func:`decimate_bytes`).

    Parameters
    ----------
    mesh : Open3D mesh or (V, F)
        The surface to resample (not modified).
    reduction : float in [0, 1)
        Fraction of the faces to remove; at least :data:`MIN_FACES` faces must remain.
    target_faces : int, optional
        Instead of ``reduction``: the number of faces to keep (>= :data:`MIN_FACES`; no-op when
        the mesh has fewer).
    vertex_map : bool
        Compute :attr:`Resampled.vertex_map` (source vertex -> the decimated vertex it collapsed
        into) by replaying the collapses; False skips the replay (about half the time at a million
        faces) and leaves it None. Both give the same faces; the replay recomputes the vertex
        positions, which then differ slightly.

    Returns
    -------
    Resampled
        With ``vertex_map`` (unless not asked for).

    Notes
    -----
    Thread-safe: fast-simplification's state is module-wide, so concurrent calls (threads, a Dask
    worker's tasks) take turns.

    Raises
    ------
    MeshError
        A reduction outside [0, 1) or one that would leave fewer than :data:`MIN_FACES` faces (a
        closed surface needs 4), a ``target_faces`` that is not an integer >= 4.
    OutOfMemory
        :func:`decimate_bytes` exceeds the memory left (checked before fast-simplification starts:
        it would abort the process).

    Examples
    --------
    >>> import open3d as o3d
    >>> from o3dheat.geometry.sampling import decimate
    >>> r = decimate(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 40), reduction=0.5)
    >>> len(r.F), len(r.vertex_map)               # half of the 6240 faces; one entry per source vertex
    (3120, 3122)
    """
    checks.flag(vertex_map, "vertex_map")
    V, F = as_arrays(mesh)
    identity = np.arange(len(V)) if vertex_map else None  # the map of a decimation that removes nothing
    if target_faces is not None:
        target_faces = checks.count(target_faces, "target_faces", minimum=MIN_FACES, maximum=2**62)
        if target_faces >= len(F):
            return Resampled(V, F, "decimate", {"target_faces": target_faces}, identity)
        reduction = 1.0 - target_faces / len(F)
    if isinstance(reduction, bool) or not isinstance(reduction, (int, float, np.integer, np.floating)) \
            or not 0.0 <= reduction < 1.0:
        raise MeshError(f"reduction must be a number in [0, 1), got {reduction!r}")
    params = {"reduction": float(reduction)}
    left = int(round(len(F) * (1.0 - reduction)))
    if left < MIN_FACES:
        raise MeshError(f"decimate: reduction={reduction:g} of {len(F)} faces would leave {left}, fewer than "
                        f"{MIN_FACES}: use a reduction of at most {1 - MIN_FACES / len(F):.4g}, or target_faces")
    if reduction == 0:
        return Resampled(V, F, "decimate", params, identity)
    check_memory(decimate_bytes(len(F), vertex_map), f"decimating {len(F):,} faces",
                 "decimate a part at a time, pass vertex_map=False, or use a machine with more memory")
    V2, F2, vmap = simplify(V, F, float(reduction), vertex_map)  # one at a time; large ones in a child
    give_back()  # fast-simplification's freed work space, else held in the C heap
    _check_result(V2, F2, "decimate", params)  # (fast-simplification may remove more than asked)
    V2, F2, vmap = _clean(np.asarray(V2, np.float64), np.asarray(F2, np.int64),
                          None if vmap is None else np.asarray(vmap, np.int64))
    _check_result(V2, F2, "decimate", params)
    return Resampled(V2, F2, "decimate", params, vmap)


def warm_up() -> None:
    """Run one pymeshlab filter in the calling thread.

    pymeshlab loads its plugins (and their libraries) at the first filter call. When that first
    call happens in a secondary thread (a Dask worker's task thread), the process was seen to
    abort at exit with a corrupted heap ("malloc_consolidate(): unaligned fastbin chunk").
    Calling this once from the main thread first avoids it; the studies do so on every worker.

    Examples
    --------
    >>> from o3dheat.geometry.sampling import warm_up
    >>> warm_up()
    """
    import open3d as o3d

    m = o3d.geometry.TriangleMesh.create_icosahedron(1.0)
    ms, pymeshlab = meshset(np.asarray(m.vertices), np.asarray(m.triangles))
    isotropic(ms, pymeshlab, 0.5, 1, False)


def _frommeshset(ms, kind, params):
    m = ms.current_mesh()
    # copies: pymeshlab's matrices may point into memory that dies with the MeshSet
    V, F = np.array(m.vertex_matrix(), np.float64, copy=True), np.array(m.face_matrix(), np.int64, copy=True)
    _check_result(V, F, kind, params)
    V, F, _ = _clean(V, F)
    _check_result(V, F, kind, params)
    return Resampled(V, F, kind, params)


#: the default bound on the faces a remeshing may make (:func:`remesh`, :func:`anisotropic`):
#: pymeshlab made about 5,000 faces a second here (a unit sphere at edge length 0.02: 72k faces in
#: 13 s, 2026-12), so a million faces is minutes of work that cannot be interrupted
REMESH_MAX_FACES = 1_000_000


def remesh(mesh: MeshLike, target_edge_length: float | None = None, iterations: int = 10,
           edge_factor: float | None = None, max_faces: int = REMESH_MAX_FACES) -> Resampled:
    """Isotropic explicit remeshing (pymeshlab): a uniform sampling of the same surface.

    Parameters
    ----------
    mesh : Open3D mesh or (V, F)
        The surface to resample (not modified).
    target_edge_length : float, optional
        In the units of the mesh (> 0, smaller than the bounding box).
    iterations : int
        Iterations of pymeshlab's isotropic explicit remeshing (1 to 1000).
    edge_factor : float, optional
        Instead of ``target_edge_length``: a multiple of the mesh's mean edge length (scale-free,
        for studies over meshes of different sizes). With neither given: ``edge_factor=1`` (a
        uniform sampling at the mean edge length).
    max_faces : int
        Refuse, before any work, a remeshing estimated to make more faces (the surface's area over
        an equilateral triangle's at the target length); default :data:`REMESH_MAX_FACES`.

    Returns
    -------
    Resampled

    Raises
    ------
    MeshError
        Bad parameters, or an estimate above ``max_faces`` (e.g. ``target_edge_length=1e-3`` on a
        unit sphere: about 29 million faces).

    Examples
    --------
    >>> import numpy as np, open3d as o3d
    >>> from o3dheat.geometry.sampling import remesh
    >>> r = remesh(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 20), 0.1)
    >>> e = np.linalg.norm(r.V[r.F[:, 0]] - r.V[r.F[:, 1]], axis=1)
    >>> bool(0.07 < np.median(e) < 0.13)
    True
    """
    iterations = checks.count(iterations, "iterations", maximum=1000)
    V, F = as_arrays(mesh)
    if target_edge_length is not None and edge_factor is not None:
        raise MeshError("give target_edge_length or edge_factor, not both")
    if target_edge_length is None and edge_factor is None:
        edge_factor = 1.0
    if edge_factor is not None:
        if not (np.isfinite(edge_factor) and edge_factor > 0):
            raise MeshError(f"edge_factor must be > 0, got {edge_factor}")
        target_edge_length = edge_factor * float(np.mean(np.linalg.norm(V[F[:, 0]] - V[F[:, 1]], axis=1)))
    L = float(target_edge_length)
    diag = float(np.linalg.norm(np.ptp(V, axis=0)))
    if not (np.isfinite(L) and 0 < L < diag):
        raise MeshError(f"target_edge_length must lie in (0, {diag:.4g}) (the bounding-box diagonal), got {L}")
    bound_faces(faces_at(area(V, F), L), max_faces, f"remesh with target_edge_length={L:.4g}")
    ms, pymeshlab = meshset(V, F)
    isotropic(ms, pymeshlab, L, int(iterations), False)
    params = {"target_edge_length": L, "iterations": int(iterations)}
    if edge_factor is not None:
        params["edge_factor"] = float(edge_factor)
    return _frommeshset(ms, "remesh", params)


def anisotropic(mesh: MeshLike, coarse: float = 8.0, fine: float = 0.5, axis: int = 0, iterations: int = 6,
                max_faces: int = REMESH_MAX_FACES) -> Resampled:
    """A strongly non-uniform sampling: the half ``x_axis < median`` remeshed coarse, the other fine.

    Parameters
    ----------
    mesh : Open3D mesh or (V, F)
        The surface to resample (not modified).
    coarse, fine : float
        Target edge lengths of the two halves, as multiples of the mesh's mean edge length.
    axis : int
        0, 1 or 2: the axis that splits the surface.
    iterations : int
        Remeshing iterations per half.
    max_faces : int
        Refuse, before any work, a remeshing estimated to make more faces (as :func:`remesh`).

    Returns
    -------
    Resampled

    Examples
    --------
    >>> import numpy as np, open3d as o3d
    >>> from o3dheat.geometry.sampling import anisotropic
    >>> r = anisotropic(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 30))
    >>> left = r.V[:, 0] < 0
    >>> bool(np.sum(~left) > 10 * np.sum(left))       # the fine half holds most vertices
    True
    """
    iterations = checks.count(iterations, "iterations", maximum=1000)
    V, F = as_arrays(mesh)
    if axis not in (0, 1, 2):
        raise MeshError(f"axis must be 0, 1 or 2, got {axis}")
    try:
        positive = bool(np.isfinite(coarse) and np.isfinite(fine) and coarse > 0 and fine > 0)
    except TypeError:
        positive = False
    if isinstance(coarse, bool) or isinstance(fine, bool) or not positive:
        raise MeshError(f"coarse and fine must be positive numbers, got {coarse!r} and {fine!r}")
    mean_edge = float(np.mean(np.linalg.norm(V[F[:, 0]] - V[F[:, 1]], axis=1)))
    cut = float(np.median(V[:, axis]))
    below = V[F, axis].mean(axis=1) < cut
    faces = sum(faces_at(area(V, F[half]), length * mean_edge) for half, length in ((below, coarse), (~below, fine)))
    bound_faces(faces, max_faces, f"anisotropic with coarse={coarse:g}, fine={fine:g}")
    c = "xyz"[axis]
    ms, pymeshlab = meshset(V, F)
    for cond, length in ((f"({c}0+{c}1+{c}2)/3 < {cut!r}", coarse), (f"({c}0+{c}1+{c}2)/3 >= {cut!r}", fine)):
        ms.set_selection_none()
        ms.compute_selection_by_condition_per_face(condselect=cond)
        isotropic(ms, pymeshlab, length * mean_edge, int(iterations), True)
    ms.set_selection_none()
    return _frommeshset(ms, "anisotropic", {"coarse": coarse, "fine": fine, "axis": axis,
                                             "iterations": int(iterations)})


_JITTER_MIN_AREA = 0.1  # least (new area projected on the original plane) / (original area) of a jittered face


_JITTER_HALVINGS = 8  # rounds that halve the moves of the vertices of failing faces, before zeroing them


def _face_cross(V, F):
    """Cross products ``(b - a) x (c - a)`` of the faces: twice the area times the unit normal."""
    return np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])


def _failing_faces(V, F, n0, nn0, D):
    """Faces whose triangle, moved by ``D``, keeps less than ``_JITTER_MIN_AREA`` of its original area
    when projected on its original plane (``n_new . n_old < min * |n_old|^2``); unmoved faces pass."""
    n1 = _face_cross(V + D, F)
    return np.einsum("ij,ij->i", n1, n0) < _JITTER_MIN_AREA * nn0


def _limit_moves(V, F, d, s):
    """Shrink the per-vertex scales ``s`` of the moves ``d`` until no face fails (see :func:`jitter`).

    Faces of zero area (relative to the mean edge length) are never checked: their vertices must
    come with ``s = 0``. Returns the final scales (a new array)."""
    s = s.copy()
    n0 = _face_cross(V, F)
    nn0 = np.einsum("ij,ij->i", n0, n0)
    for _ in range(_JITTER_HALVINGS):
        bad = _failing_faces(V, F, n0, nn0, s[:, None] * d)
        if not bad.any():
            return s
        s[F[bad].reshape(-1)] *= 0.5
    # last resort: keep the vertices of the failing faces in place. A face whose three vertices stay
    # is the original one (V + 0 d == V exactly) and passes, so every round zeroes at least one
    # moving vertex: at most n rounds, and the result has no failing face by construction.
    while True:
        bad = _failing_faces(V, F, n0, nn0, s[:, None] * d)
        if not bad.any():
            return s
        s[F[bad].reshape(-1)] = 0.0


def jitter(mesh: MeshLike, amount: float = 0.3, seed: int = 0) -> Resampled:
    """Move every vertex at random in its tangent plane, never folding a face.

    Same connectivity, new sample positions. Each vertex gets a Gaussian proposal (standard
    deviation ``amount`` x the mean edge length ``h`` per coordinate, projected on the plane
    normal to its area-weighted vertex normal), which is then shrunk where it would spoil a face:
    while some face, once moved, keeps less than 10 % of its original area when projected on its
    original plane, the moves of that face's vertices are halved (8 rounds at most), then set to 0.

    Guarantee, for any ``amount`` and ``seed``: every face of positive area keeps
    ``n_new . n_old >= 0.1 |n_old|^2`` (``n`` the cross product of two edges, twice the area times
    the unit normal), so no face flips (its normal turns by less than 90 degrees) and none gets
    near-degenerate (its new area is at least 10 % of the original). Faces of zero area in the
    input (below ``1e-12 h^2``) keep their vertices in place, and so do unreferenced vertices. It
    does not rule out self-intersections between faces that do not share a vertex.

    Parameters
    ----------
    mesh : Open3D mesh or (V, F)
        The surface to resample (not modified).
    amount : float
        Standard deviation of the proposed displacement, per tangent direction, as a fraction of
        the mean edge length (>= 0). On a mesh without thin triangles the limiter seldom acts
        below about 0.1; large amounts (> 1) are shrunk almost everywhere (the mean move then
        stays a fraction of an edge length, see ``moved_mean``).
    seed : int
        Seed of the random proposals (numpy's ``default_rng``), >= 0.

    Returns
    -------
    Resampled
        ``vertex_map`` is the identity. ``params`` holds ``amount`` and ``seed`` and, as plain
        floats and ints, ``moved_mean`` and ``moved_max`` (the mean and largest vertex
        displacement in units of the mean edge length), ``limited`` (referenced vertices whose
        move was shrunk, including those kept in place), ``frozen`` (referenced vertices kept in
        place) and ``degenerate`` (faces of zero area, skipped).

    Raises
    ------
    MeshError
        ``amount`` negative, not finite, or so large that the displacements overflow.

    Examples
    --------
    >>> import numpy as np, open3d as o3d
    >>> from o3dheat.geometry.sampling import jitter
    >>> m = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 30)
    >>> a, b = jitter(m, 0.2, seed=1), jitter(m, 0.2, seed=1)
    >>> bool(np.array_equal(a.V, b.V)), bool(abs(np.linalg.norm(a.V, axis=1) - 1).max() < 0.01)
    (True, True)
    >>> r = jitter(m, 3.0)                          # a large amount: shrunk moves, still no fold
    >>> F, V0 = r.F, m.vertex.positions.numpy()
    >>> n0 = np.cross(V0[F[:, 1]] - V0[F[:, 0]], V0[F[:, 2]] - V0[F[:, 0]])
    >>> n1 = np.cross(r.V[F[:, 1]] - r.V[F[:, 0]], r.V[F[:, 2]] - r.V[F[:, 0]])
    >>> bool((np.einsum("ij,ij->i", n1, n0) >= 0.1 * np.einsum("ij,ij->i", n0, n0)).all())
    True
    >>> sorted(r.params)
    ['amount', 'degenerate', 'frozen', 'limited', 'moved_max', 'moved_mean', 'seed']
    """
    V, F = as_arrays(mesh)
    if isinstance(amount, bool) or not isinstance(amount, (int, float, np.integer, np.floating)) \
            or not (np.isfinite(amount) and amount >= 0):
        raise MeshError(f"amount must be a number >= 0, got {amount!r}")
    seed = checks.count(seed, "seed", minimum=0, maximum=2**63 - 1)
    N = vertex_normals(V, F)
    h = float(np.mean(np.linalg.norm(V[F[:, 0]] - V[F[:, 1]], axis=1)))
    with np.errstate(over="ignore", invalid="ignore"):  # overflow: reported below
        d = np.random.default_rng(seed).standard_normal(V.shape) * amount * h
        d -= np.einsum("ij,ij->i", d, N)[:, None] * N  # tangential
    if not np.all(np.isfinite(d)):
        raise MeshError(f"amount {amount} is too large: the displacements overflow")
    used = np.zeros(len(V), bool)
    used[F.reshape(-1)] = True
    degenerate = np.linalg.norm(_face_cross(V, F), axis=1) <= 1e-12 * h * h
    s = used.astype(np.float64)
    s[F[degenerate].reshape(-1)] = 0.0
    s = _limit_moves(V, F[~degenerate], d, s)
    W = V + s[:, None] * d
    moved = np.linalg.norm(W - V, axis=1) / (h if h > 0 else 1.0)
    params = {"amount": float(amount), "seed": int(seed),
              "moved_mean": float(moved.mean()), "moved_max": float(moved.max()),
              "limited": int(np.sum(used & (s < 1.0))) if amount > 0 else 0,
              "frozen": int(np.sum(used & (s == 0.0))) if amount > 0 else 0,
              "degenerate": int(degenerate.sum())}
    return Resampled(W, F.copy(), "jitter", params, np.arange(len(V)))


def subdivide(mesh: MeshLike, iterations: int = 1, method: str = "midpoint") -> Resampled:
    """Subdivide every triangle into four, ``iterations`` times.

    Parameters
    ----------
    mesh : Open3D mesh or (V, F)
        The surface to resample (not modified).
    iterations : int
        Number of subdivisions, 0 to 6 (each multiplies the faces by 4; 0 returns the mesh as it is).
    method : {"midpoint", "loop"}
        "midpoint" keeps the surface (new vertices on the old edges); "loop" smooths it.

    Returns
    -------
    Resampled
        The source vertices keep their indices (``vertex_map`` is the identity on them).

    Examples
    --------
    >>> import open3d as o3d
    >>> from o3dheat.geometry.sampling import subdivide
    >>> len(subdivide(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 10), 2).F)
    5760
    """
    import open3d as o3d

    V, F = as_arrays(mesh)
    if method not in ("midpoint", "loop"):
        raise MeshError(f"method must be 'midpoint' or 'loop', got {method!r}")
    if not (isinstance(iterations, (int, np.integer)) and 0 <= iterations <= 6):
        raise MeshError(f"iterations must be an integer in [0, 6], got {iterations!r}")
    m = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(V), o3d.utility.Vector3iVector(F.astype(np.int32)))
    if iterations:
        m = m.subdivide_midpoint(int(iterations)) if method == "midpoint" else m.subdivide_loop(int(iterations))
    V2, F2 = np.asarray(m.vertices, np.float64), np.asarray(m.triangles, np.int64)
    return Resampled(V2, F2, "subdivide", {"iterations": int(iterations), "method": method}, np.arange(len(V)))


#: resampling kind -> its function: the names :func:`resample` and the studies accept
KINDS = {"decimate": decimate, "remesh": remesh, "anisotropic": anisotropic, "jitter": jitter,
         "subdivide": subdivide}


def resample(mesh: MeshLike, kind: str, **params: object) -> Resampled:
    """One of the resamplings by name: ``resample(mesh, "remesh", target_edge_length=0.01)``.

    Examples
    --------
    >>> import open3d as o3d
    >>> from o3dheat.geometry.sampling import resample
    >>> resample(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 10), "jitter", amount=0.1).kind
    'jitter'
    """
    if kind not in KINDS:
        raise MeshError(f"unknown resampling {kind!r}: use one of {', '.join(KINDS)}")
    try:
        return KINDS[kind](mesh, **params)
    except TypeError as e:
        raise MeshError(f"resampling {kind!r}: {e}") from e
