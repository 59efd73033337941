"""Resampling, reconstruction and transfer between samplings."""

import numpy as np
import open3d as o3d
import pytest
from conftest import icosphere

import o3dheat
from o3dheat.sampling import decimate, nearest, reconstruct, transfer
from o3dheat.topology import Surface


def test_decimate_gives_an_irregular_2_manifold():
    from o3dheat.demo import default_mesh

    bunny, _ = default_mesh()
    for r in (0.5, 0.8, 0.95):
        V, F = decimate(bunny, reduction=r)
        S = Surface((V, F))  # raises if not a 2-manifold
        assert S.used.all() and abs(len(F) - (1 - r) * len(bunny.triangle.indices)) < 0.02 * len(F) + 10
    V, F = decimate(bunny, target_faces=4000)
    assert len(F) <= 4000
    edge = np.linalg.norm(V[F[:, 0]] - V[F[:, 1]], axis=1)
    assert edge.max() / np.median(edge) > 2  # non-uniform
    with pytest.raises(o3dheat.MeshError):
        decimate(bunny, reduction=1.0)


def test_transfer_is_exact_for_linear_functions():
    V, F = icosphere(3)
    f = 2 * V[:, 0] - V[:, 1] + 0.5
    P = icosphere(2)[0] * 1.0  # points on the sphere, also vertices of the coarser sphere
    g = transfer(f, V, F, P)
    assert np.allclose(g, 2 * P[:, 0] - P[:, 1] + 0.5, atol=1e-6)
    G = transfer(np.stack([f, -f], 1), V, F, P)
    assert G.shape == (len(P), 2) and np.allclose(G[:, 1], -g)
    with pytest.raises(o3dheat.MeshError):
        transfer(f[:5], V, F, P)
    assert nearest(f, V, V[:7] + 1e-9).tolist() == f[:7].tolist()


@pytest.mark.parametrize("method", ["poisson", "ball_pivoting"])
def test_reconstruct_a_sphere(method):
    P = np.random.default_rng(0).standard_normal((4000, 3))
    P /= np.linalg.norm(P, axis=1)[:, None]
    V, F = reconstruct(o3d.geometry.PointCloud(o3d.utility.Vector3dVector(P)), method=method)
    assert abs(np.linalg.norm(V, axis=1).mean() - 1) < 0.02 and len(F) > 1000
    if method == "poisson":
        assert Surface((V, F)).euler_characteristic == 2  # closed, a sphere


def test_reconstruct_bad_input():
    with pytest.raises(o3dheat.MeshError):
        reconstruct(o3d.t.geometry.PointCloud(o3d.core.Tensor(np.zeros((3, 3)))))
    with pytest.raises(o3dheat.MeshError):
        reconstruct(o3d.geometry.PointCloud(), method="poisson")
    with pytest.raises(o3dheat.MeshError):
        reconstruct(o3d.t.geometry.PointCloud(o3d.core.Tensor(np.random.rand(50, 3))), method="nope")
