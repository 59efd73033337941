"""o3dheat.geometry.points: a surface through a point cloud."""

import numpy as np
import open3d as o3d
import pytest

import o3dheat
from o3dheat.geometry.points import reconstruct
from o3dheat.topology import Surface


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


def test_reconstructing_a_degenerate_cloud_is_a_named_error():
    """Issue 22: collinear, coincident, too few or flat points ended in raw Qhull/Open3D errors."""
    rng = np.random.default_rng(0)
    for msg, P in {"all coincide": np.ones((50, 3)),
                   "one line": np.c_[np.linspace(0, 1, 50), np.zeros(50), np.zeros(50)],
                   "distinct points": rng.random((3, 3)),
                   "one plane": np.c_[rng.random((200, 2)), np.zeros(200)]}.items():
        with pytest.raises(o3dheat.MeshError, match=msg):
            reconstruct(o3d.t.geometry.PointCloud(o3d.core.Tensor(P)))
