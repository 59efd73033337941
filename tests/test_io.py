"""o3dheat.io: lossless PLY round trips and atomic writes."""

import numpy as np
import open3d as o3d
import pytest

import o3dheat
from o3dheat.io import read_mesh, write_mesh


@pytest.fixture
def mesh():
    m = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 10, float_dtype=o3d.core.float64)
    n = len(m.vertex.positions)
    r = np.random.default_rng(0)
    m.vertex["f"] = o3d.core.Tensor(r.standard_normal(n))
    m.vertex["hks"] = o3d.core.Tensor(r.random((n, 4)))
    m.vertex["label"] = o3d.core.Tensor(r.integers(0, 5, n).astype(np.int32))
    m.vertex.colors = o3d.core.Tensor(r.random((n, 3)).astype(np.float32))
    return m


@pytest.mark.parametrize("binary", [True, False])
def test_round_trip_is_exact(tmp_path, mesh, binary):
    p = tmp_path / "m.ply"
    write_mesh(p, mesh, binary=binary)
    back = read_mesh(p)
    for key in mesh.vertex:
        a, b = mesh.vertex[key].numpy(), back.vertex[key].numpy()
        assert a.dtype == b.dtype and a.shape == b.shape, key
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(mesh.triangle.indices.numpy(), back.triangle.indices.numpy())


def test_plain_readers_see_the_columns(tmp_path, mesh):
    p = tmp_path / "m.ply"
    write_mesh(p, mesh)
    from plyfile import PlyData
    names = PlyData.read(str(p))["vertex"].data.dtype.names
    assert {"x", "red", "f", "hks_0", "hks_3", "label"} <= set(names)


def test_write_is_atomic(tmp_path, mesh, monkeypatch):
    p = tmp_path / "m.ply"
    p.write_bytes(b"previous content")
    import plyfile

    def boom(self, stream):
        stream.write(b"partial")
        raise OSError("disk full")

    monkeypatch.setattr(plyfile.PlyData, "write", boom)
    with pytest.raises(OSError):
        write_mesh(p, mesh)
    assert p.read_bytes() == b"previous content"
    assert [x.name for x in tmp_path.iterdir()] == ["m.ply"]


def test_bad_paths(tmp_path, mesh):
    with pytest.raises(o3dheat.MeshError, match="no such file"):
        read_mesh(tmp_path / "missing.ply")
    with pytest.raises(o3dheat.MeshError, match="PLY"):
        write_mesh(tmp_path / "m.obj", mesh)
    with pytest.raises(o3dheat.MeshError, match="does not exist"):
        write_mesh(tmp_path / "nope" / "m.ply", mesh)
    bad = tmp_path / "bad.ply"
    bad.write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 10\nproperty double x\nend_header\n\x00")
    with pytest.raises(o3dheat.MeshError, match="not a readable PLY"):
        read_mesh(bad)


def test_obj_through_open3d(tmp_path):
    p = tmp_path / "box.obj"
    o3d.io.write_triangle_mesh(str(p), o3d.geometry.TriangleMesh.create_box())
    m = read_mesh(p)
    assert len(m.triangle.indices) == 12


def test_written_file_has_ordinary_permissions(tmp_path, mesh):
    import os
    p = tmp_path / "m.ply"
    write_mesh(p, mesh)
    mask = os.umask(0)
    os.umask(mask)
    assert (p.stat().st_mode & 0o777) == (0o666 & ~mask)


def _same(a, b, attrs):
    for key in a:
        x, y = a[key].numpy(), b[key].numpy()
        assert x.dtype == y.dtype and x.shape == y.shape, key
        np.testing.assert_array_equal(x, y)
    assert sorted(k for k in a) == sorted(k for k in b)


def test_npz_round_trip_is_exact(tmp_path, mesh):
    from o3dheat.io import read_geometry, write_geometry

    p = tmp_path / "m.npz"
    write_mesh(p, mesh)
    back = read_mesh(p)
    _same(mesh.vertex, back.vertex, None)
    np.testing.assert_array_equal(mesh.triangle.indices.numpy(), back.triangle.indices.numpy())
    pc = o3d.t.geometry.PointCloud(mesh.vertex.positions)
    pc.point["f"] = mesh.vertex["f"]
    pc.point["hks"] = mesh.vertex["hks"]
    for suffix in (".npz", ".ply"):
        write_geometry(tmp_path / f"p{suffix}", pc)
        back = read_geometry(tmp_path / f"p{suffix}")
        assert isinstance(back, o3d.t.geometry.PointCloud)
        _same(pc.point, back.point, None)
    with pytest.raises(o3dheat.MeshError, match="point cloud"):
        read_mesh(tmp_path / "p.ply")


def test_no_accidental_overwrite_and_corrupt_files(tmp_path, mesh):
    from o3dheat.io import read_geometry

    p = tmp_path / "m.ply"
    write_mesh(p, mesh)
    before = p.read_bytes()
    with pytest.raises(o3dheat.MeshError, match="exists"):
        write_mesh(p, mesh, overwrite=False)
    assert p.read_bytes() == before
    cut = tmp_path / "cut.ply"
    cut.write_bytes(before[: len(before) // 2])  # truncated
    with pytest.raises(o3dheat.MeshError, match="not a readable PLY"):
        read_geometry(cut)
    junk = tmp_path / "junk.npz"
    junk.write_bytes(b"not a zip file")
    with pytest.raises(o3dheat.MeshError, match="not a readable NPZ"):
        read_geometry(junk)
    np.savez(tmp_path / "bad.npz", positions=np.zeros((3, 3)), indices=np.array([[0, 1, 7]]))
    with pytest.raises(o3dheat.MeshError, match="indices"):
        read_geometry(tmp_path / "bad.npz")
    with pytest.raises(o3dheat.MeshError, match="PLY or NPZ"):
        write_mesh(tmp_path / "m.stl", mesh)
