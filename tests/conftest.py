"""Shared test meshes, all made here (no files, no downloads)."""

import os

import numpy as np
import open3d as o3d
import pytest
from hypothesis import settings

# CI replays the same examples on every run (a red CI names a bug, not a lucky draw); locally
# hypothesis explores new examples each time.
settings.register_profile("ci", derandomize=True)
if os.environ.get("CI"):
    settings.load_profile("ci")


def icosphere(level=3, radius=1.0):
    """Unit icosphere (subdivided icosahedron projected on the sphere), as (V, F) arrays."""
    m = o3d.geometry.TriangleMesh.create_icosahedron(1.0)
    if level:
        m = m.subdivide_midpoint(level)
    V = np.asarray(m.vertices, dtype=np.float64)
    V = radius * V / np.linalg.norm(V, axis=1, keepdims=True)
    return V, np.asarray(m.triangles, dtype=np.int64)


def glued_spheres(level=2):
    """Two spheres touching at one vertex (a non-manifold "bowtie" vertex): (V, F)."""
    V, F = icosphere(level)
    top = int(np.argmax(V[:, 2]))
    V2 = V * [1, 1, -1] + [0, 0, 2 * V[top, 2]]  # mirrored: its bottom vertex on the first's top
    bottom = int(np.argmin(V2[:, 2]))
    keep = np.arange(len(V2)) != bottom
    index = np.full(len(V2), -1)
    index[keep] = len(V) + np.arange(keep.sum())
    index[bottom] = top
    return np.vstack([V, V2[keep]]), np.vstack([F, index[F[:, ::-1]]])


def grid(a=2.0, b=1.0, nx=40, ny=20, jitter=0.0, seed=0):
    """Flat a x b rectangle triangulated on an nx x ny grid (optionally jittered inside)."""
    x, y = np.meshgrid(np.linspace(0, a, nx + 1), np.linspace(0, b, ny + 1), indexing="ij")
    V = np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], 1)
    if jitter:
        rng = np.random.default_rng(seed)
        inner = (V[:, 0] > 0) & (V[:, 0] < a) & (V[:, 1] > 0) & (V[:, 1] < b)
        V[inner, :2] += jitter * rng.uniform(-1, 1, (inner.sum(), 2)) * np.array([a / nx, b / ny])
    idx = np.arange((nx + 1) * (ny + 1)).reshape(nx + 1, ny + 1)
    q = np.stack([idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()], 1)
    F = np.concatenate([q[:, [0, 1, 2]], q[:, [0, 2, 3]]])
    return V, F


def torus(R=1.0, r=0.4, radial=48, tubular=24):
    m = o3d.geometry.TriangleMesh.create_torus(R, r, radial, tubular)
    return np.asarray(m.vertices, dtype=np.float64), np.asarray(m.triangles, dtype=np.int64)


def irregular(seed=0):
    """A non-symmetric, irregularly sampled closed surface: a bumpy ellipsoid whose one side is
    refined and whose vertices are jittered (about 1.5k vertices)."""
    V, F = icosphere(3)
    rng = np.random.default_rng(seed)
    V = V * np.array([1.3, 1.0, 0.8]) + 0.05 * np.sin(3 * V[:, [1, 2, 0]])
    m = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(V), o3d.utility.Vector3iVector(F))
    # refine the triangles of one side only: a strongly non-uniform density
    Fa = np.asarray(m.triangles)
    side = V[Fa].mean(1)[:, 0] > 0.2
    Vn, Fn = list(V), []
    cache = {}

    def mid(i, j):
        key = (min(i, j), max(i, j))
        if key not in cache:
            cache[key] = len(Vn)
            Vn.append((V[i] + V[j]) / 2)
        return cache[key]

    for t, s in zip(Fa, side, strict=True):
        if s:
            a, b, c = t
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            Fn += [[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]
        else:
            Fn.append(list(t))
    # close the T-junctions: split the unrefined neighbours of refined edges
    Fn2 = []
    for t in Fn:
        a, b, c = t
        ms = [cache.get((min(x, y), max(x, y))) for x, y in ((a, b), (b, c), (c, a))]
        if all(mm is None for mm in ms) or len(set([a, b, c]) & set(v for v in ms if v is not None)):
            Fn2.append(t)
            continue
        # fan-triangulate the polygon with inserted midpoints
        poly = []
        for (x, _y), mm in zip(((a, b), (b, c), (c, a)), ms, strict=True):
            poly.append(x)
            if mm is not None:
                poly.append(mm)
        Fn2 += [[poly[0], poly[i], poly[i + 1]] for i in range(1, len(poly) - 1)]
    V = np.asarray(Vn)
    V = V + 0.002 * rng.standard_normal(V.shape)
    return V, np.asarray(Fn2, dtype=np.int64)


@pytest.fixture(scope="session")
def sphere3():
    return icosphere(3)


@pytest.fixture(scope="session")
def sphere4():
    return icosphere(4)


@pytest.fixture(scope="session")
def irregular_mesh():
    return irregular()


@pytest.fixture(scope="session")
def torus_mesh():
    return torus()


# --- Open3D meshes with attributes, for the filters' tests ---

def tmesh(V, F, **attrs):
    m = o3d.t.geometry.TriangleMesh()
    m.vertex.positions = o3d.core.Tensor(np.asarray(V, np.float64))
    m.triangle.indices = o3d.core.Tensor(np.asarray(F, np.int64))
    for k, v in attrs.items():
        m.vertex[k] = o3d.core.Tensor(np.ascontiguousarray(v))
    return m


def sphere_points(n=4000, seed=0):
    P = np.random.default_rng(seed).standard_normal((n, 3))
    return P / np.linalg.norm(P, axis=1)[:, None]


@pytest.fixture(scope="module")
def sphere():
    V, F = icosphere(3)
    return tmesh(V, F, height=V[:, 2].copy())
