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


def _polygon_ply(path, V, faces, binary=True):
    from plyfile import PlyData, PlyElement

    vert = np.array([tuple(v) for v in V], dtype=[("x", "f8"), ("y", "f8"), ("z", "f8")])
    face = np.empty(len(faces), dtype=[("vertex_indices", object)])
    face["vertex_indices"] = [np.asarray(f, dtype=np.int32) for f in faces]
    PlyData([PlyElement.describe(vert, "vertex"), PlyElement.describe(face, "face")], text=not binary).write(str(path))


@pytest.mark.parametrize("binary", [True, False])
def test_polygons_are_triangulated_on_read(tmp_path, caplog, binary):
    """Quads and other polygons (PLY from modelling tools) are fanned into triangles, like Open3D
    does for OFF: same surface, same spectrum as the triangulated mesh; the warning says so."""
    import logging

    nu, nv, R, r = 24, 12, 1.0, 0.4
    u, v = np.meshgrid(np.arange(nu) * 2 * np.pi / nu, np.arange(nv) * 2 * np.pi / nv, indexing="ij")
    V = np.stack([(R + r * np.cos(v)) * np.cos(u), (R + r * np.cos(v)) * np.sin(u), r * np.sin(v)], -1).reshape(-1, 3)
    idx = lambda i, j: (i % nu) * nv + (j % nv)  # noqa: E731
    quads = [[idx(i, j), idx(i + 1, j), idx(i + 1, j + 1), idx(i, j + 1)] for i in range(nu) for j in range(nv)]
    faces = quads[:-2] + [quads[-2][:3], [quads[-2][0], quads[-2][2], quads[-2][3]]] + [quads[-1]]  # mixed
    p = tmp_path / "quads.ply"
    _polygon_ply(p, V, faces, binary)
    with caplog.at_level(logging.WARNING, logger="o3dheat"):
        m = read_mesh(p)
    assert f"{len(faces) - 2} polygons with more than 3 corners triangulated" in caplog.text
    F = m.triangle.indices.numpy()
    assert F.shape == (2 * nu * nv, 3)
    report = o3dheat.check_mesh(m)
    assert report.components == 1 and report.genus == 1 and report.boundary_loops == 0
    tri = np.array([[q[0], q[1], q[2]] for q in quads] + [[q[0], q[2], q[3]] for q in quads])
    ref = o3dheat.eigensolve((V, tri), k=12)
    np.testing.assert_allclose(o3dheat.eigensolve(m, k=12).eigenvalues, ref.eigenvalues, rtol=1e-10, atol=1e-12)


def test_faces_with_fewer_than_three_corners_are_refused(tmp_path):
    p = tmp_path / "bad.ply"
    _polygon_ply(p, np.eye(3), [[0, 1, 2], [0, 1]])
    with pytest.raises(o3dheat.MeshError, match="fewer than 3 corners"):
        read_mesh(p)
