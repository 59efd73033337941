"""o3dheat.io.meshes (and the codecs behind it): lossless PLY round trips, OBJ and STL, atomic writes."""

import numpy as np
import open3d as o3d
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

import o3dheat
from o3dheat.io import read_mesh, write_geometry, write_mesh


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
    write_mesh(p, mesh, binary=binary, lossless_colors=True)  # colours too (8 bits by default)
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


@pytest.mark.parametrize("binary", [True, False])
def test_write_is_atomic(tmp_path, mesh, monkeypatch, binary):
    p = tmp_path / "m.ply"
    p.write_bytes(b"previous content")
    import plyfile

    import o3dheat.io._ply

    def boom(*args):
        args[0 if binary else 1].write(b"partial")  # (fh, ply, vert, F) or (self, stream)
        raise OSError("disk full")

    if binary:
        monkeypatch.setattr(o3dheat.io._ply, "_write_binary_ply", boom)
    else:
        monkeypatch.setattr(plyfile.PlyData, "write", boom)
    with pytest.raises(OSError):
        write_mesh(p, mesh, binary=binary)
    assert p.read_bytes() == b"previous content"
    assert [x.name for x in tmp_path.iterdir()] == ["m.ply"]


def test_temporary_files_of_a_killed_write_are_removed_by_the_next(tmp_path, mesh):
    import os
    import time

    old = tmp_path / ".m.ply.abc123.tmp"  # what kill -9 during a write leaves
    old.write_bytes(b"partial")
    os.utime(old, (time.time() - 7200,) * 2)
    live = tmp_path / ".m.ply.def456.tmp"  # another writer at work right now
    live.write_bytes(b"partial")
    other = tmp_path / ".n.ply.abc123.tmp"  # another target's: not ours to judge
    other.write_bytes(b"x")
    os.utime(other, (time.time() - 7200,) * 2)
    write_mesh(tmp_path / "m.ply", mesh)
    assert not old.exists() and live.exists() and other.exists()


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


# ---------------------------------------------------------------- exact round trips (issue 13)

_DTYPES = [np.bool_, np.int8, np.int16, np.int32, np.int64, np.uint8, np.uint16, np.uint32, np.uint64,
           np.float32, np.float64]
_FORMATS = [("ply", True), ("ply", False), ("npz", True)]


def _extremes(dtype, size, rng):
    """``size`` values of ``dtype`` with its extremes (64-bit integers: within ±2**53, what PLY
    holds exactly), signed zeros, infinities and subnormals for floats."""
    dtype = np.dtype(dtype)
    if dtype == bool:
        return rng.integers(0, 2, size).astype(bool)
    if dtype.kind in "iu":
        info = np.iinfo(dtype)
        lo, hi = max(int(info.min), -2 ** 53), min(int(info.max), 2 ** 53)
        special = np.array([lo, hi, 0, 1, lo + 1, hi - 1], dtype=dtype)
        vals = rng.integers(lo, hi, size, dtype=dtype, endpoint=True)
    else:
        info = np.finfo(dtype)
        special = np.array([info.max, -info.max, info.tiny, info.smallest_subnormal, -0.0, np.inf, -np.inf,
                            info.eps, 1 / 3], dtype=dtype)
        vals = rng.standard_normal(size).astype(dtype) * dtype.type(10.0) ** rng.integers(-30, 30, size).astype(dtype)
    vals[: min(size, len(special))] = special[:size]
    return vals


def _bits(a):
    """The bytes of an array as unsigned integers (bit-exact comparison, -0.0 != 0.0)."""
    a = np.ascontiguousarray(a)
    return a.view(np.uint8) if a.dtype == bool else a.view(f"u{a.dtype.itemsize}")


def _assert_exact(orig, back):
    assert sorted(orig) == sorted(back)
    for key in orig:
        a, b = orig[key].numpy(), back[key].numpy()
        assert (a.dtype, a.shape) == (b.dtype, b.shape), (key, a.dtype, a.shape, b.dtype, b.shape)
        np.testing.assert_array_equal(_bits(a), _bits(b), err_msg=key)


def _leftovers(folder, keep=()):
    return sorted(p.name for p in folder.iterdir() if p.name not in keep)


def _sphere(float_dtype=np.float32):
    dt = o3d.core.float32 if float_dtype == np.float32 else o3d.core.float64
    return o3d.t.geometry.TriangleMesh.create_sphere(1.0, 4, float_dtype=dt)


@pytest.mark.parametrize("fmt,binary", _FORMATS, ids=["ply-binary", "ply-ascii", "npz"])
@pytest.mark.parametrize("float_dtype", [np.float32, np.float64])
@pytest.mark.parametrize("dtype", _DTYPES, ids=lambda d: np.dtype(d).name)
def test_every_dtype_and_shape_round_trips_exactly(tmp_path, dtype, float_dtype, fmt, binary):
    m = _sphere(float_dtype)
    n = len(m.vertex.positions)
    rng = np.random.default_rng(1)
    m.vertex.normals = o3d.core.Tensor(_extremes(float_dtype, n * 3, rng).reshape(n, 3))
    for name, shape in [("s", (n,)), ("v", (n, 3)), ("t", (n, 2, 3)), ("one", (n, 1)), ("w", (n, 1, 4, 2))]:
        m.vertex[name] = o3d.core.Tensor(_extremes(dtype, int(np.prod(shape)), rng).reshape(shape))
    p = tmp_path / f"m.{fmt}"
    write_mesh(p, m, binary=binary)
    back = read_mesh(p)
    _assert_exact(m.vertex, back.vertex)
    np.testing.assert_array_equal(m.triangle.indices.numpy(), back.triangle.indices.numpy())
    if fmt == "ply":  # also as a point cloud
        from o3dheat.io import read_geometry, write_geometry
        pc = o3d.t.geometry.PointCloud(m.vertex.positions)
        pc.point["t"] = m.vertex["t"]
        write_geometry(tmp_path / "p.ply", pc, binary=binary)
        _assert_exact(pc.point, read_geometry(tmp_path / "p.ply").point)


@pytest.mark.parametrize("binary", [True, False])
def test_foreign_ply_keeps_its_position_type(tmp_path, binary):
    from plyfile import PlyData, PlyElement
    vert = np.zeros(3, dtype=[("x", "f4"), ("y", "f4"), ("z", "f4"), ("q", ">i2")])
    vert["x"], vert["q"] = [0.1, 0.2, 0.3], [1, -2, 3]
    p = tmp_path / "f.ply"
    PlyData([PlyElement.describe(vert, "vertex")], text=not binary, byte_order=">").write(str(p))
    from o3dheat.io import read_geometry
    g = read_geometry(p)
    assert g.point.positions.numpy().dtype == np.float32
    np.testing.assert_array_equal(g.point.positions.numpy()[:, 0], vert["x"])
    assert g.point["q"].numpy().tolist() == [1, -2, 3] and g.point["q"].numpy().dtype == np.int16
    vert = np.zeros(3, dtype=[("x", "i4"), ("y", "f4"), ("z", "f8")])  # mixed: float64
    PlyData([PlyElement.describe(vert, "vertex")], text=not binary).write(str(p))
    assert read_geometry(p).point.positions.numpy().dtype == np.float64


def _refusal_cases(n):
    big = np.zeros(n, np.int64)
    big[3] = 2 ** 53 + 1
    ubig = np.zeros(n, np.uint64)
    ubig[0] = 2 ** 64 - 1
    z = np.zeros(n)
    return [
        ({"a b": z}, "'a b'.*spaces"),
        ({"é": z}, "'é'.*ASCII"),
        ({"x": z}, "'x'.*reserved"),
        ({"nx": z}, "'nx'.*reserved"),
        ({"red": z}, "'red'.*reserved"),
        ({"blue": np.zeros((n, 2))}, "'blue'.*reserved"),
        ({"alpha": np.zeros((n, 2))}, "'alpha'.*reserved"),
        ({"o3dheat_colors_1": z}, "'o3dheat_colors_1'.*reserved"),
        ({"o3dheat_colors": np.zeros((n, 3))}, "'o3dheat_colors'.*reserved"),
        ({"a": np.zeros((n, 2)), "a_0": z}, "property 'a_0', already a property of attribute"),
        ({"a": np.zeros((n, 2, 2)), "a_3": z}, "property 'a_3'"),
        ({"big": big}, "'big'.*2\\*\\*53.*npz"),
        ({"ubig": ubig}, "'ubig'.*2\\*\\*53.*npz"),
        ({"empty": np.zeros((n, 0))}, "'empty'.*no column"),
        ({"normals": np.zeros((n, 3), np.int32)}, "normals.*float"),
        ({"colors": np.zeros((n, 4))}, "colors.*\\(n, 3\\)"),
        ({"colors": np.where(np.arange(3 * n).reshape(n, 3) == 7, np.nan, 0.5)},
         "1 of 26 vertex colours NaN or infinite \\(the first at vertex 2\\)"),
        ({"colors": np.zeros((n, 3), np.int16)}, "colors of dtype int16.*float colours in \\[0, 1\\] or uint8"),
    ]


@pytest.mark.parametrize("case", range(18))
def test_unstorable_attributes_are_refused_before_writing(tmp_path, case):
    m = _sphere()
    attrs, match = _refusal_cases(len(m.vertex.positions))[case]
    for key, arr in attrs.items():
        m.vertex[key] = o3d.core.Tensor(arr)
    old = tmp_path / "old.ply"
    old.write_bytes(b"previous content")
    for p in (old, tmp_path / "new.ply"):
        with pytest.raises(o3dheat.MeshError, match=match):
            write_mesh(p, m)
    assert old.read_bytes() == b"previous content"
    assert _leftovers(tmp_path) == ["old.ply"]


def test_face_indices_beyond_int32_and_bad_positions_are_refused(tmp_path):
    m = _sphere()
    m.triangle.indices = o3d.core.Tensor(np.array([[0, 1, 2 ** 31]], dtype=np.int64))
    for suffix in (".ply", ".npz"):
        with pytest.raises(o3dheat.MeshError, match="face indices outside"):
            write_mesh(tmp_path / f"m{suffix}", m)
    pc = o3d.t.geometry.PointCloud(o3d.core.Tensor(np.eye(3, dtype=np.int32)))
    from o3dheat.io import read_geometry, write_geometry
    with pytest.raises(o3dheat.MeshError, match="positions.*float32 or float64.*npz"):
        write_geometry(tmp_path / "p.ply", pc)
    assert _leftovers(tmp_path) == []
    write_geometry(tmp_path / "p.npz", pc)  # npz keeps them
    _assert_exact(pc.point, read_geometry(tmp_path / "p.npz").point)


_NAMES = st.text(alphabet="anx_0", min_size=1, max_size=3)
_SHAPES = st.one_of(st.just(()), st.tuples(st.integers(1, 3)), st.tuples(st.integers(1, 2), st.integers(1, 3)))


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(attrs=st.dictionaries(_NAMES, st.tuples(st.sampled_from(_DTYPES), _SHAPES, st.booleans()), max_size=4),
       fmt=st.sampled_from(_FORMATS), seed=st.integers(0, 2 ** 32 - 1))
def test_random_attributes_round_trip_or_are_refused(tmp_path_factory, attrs, fmt, seed):
    folder = tmp_path_factory.mktemp("h")
    m = _sphere(np.float64 if seed % 2 else np.float32)
    n = len(m.vertex.positions)
    rng = np.random.default_rng(seed)
    for key, (dtype, shape, wide) in attrs.items():
        size = n * int(np.prod(shape))
        if wide and np.dtype(dtype).kind in "iu":  # the whole range, beyond 2**53 for 64 bits
            vals = rng.integers(np.iinfo(dtype).min, np.iinfo(dtype).max, size, dtype=dtype, endpoint=True)
        else:
            vals = _extremes(dtype, size, rng)
        m.vertex[key] = o3d.core.Tensor(vals.reshape((n,) + shape))
    p = folder / f"m.{fmt[0]}"
    try:
        write_mesh(p, m, binary=fmt[1])
    except o3dheat.MeshError:
        event("refused")
        assert fmt[0] == "ply" and _leftovers(folder) == []
        return
    event(f"round trip ({fmt[0]})")
    assert _leftovers(folder) == [p.name]
    _assert_exact(m.vertex, read_mesh(p).vertex)


# ---------------------------------------------------------------- crafted and old files

def _ply(path, props, comments=(), binary=True, n=4):
    """A PLY point set with x, y, z = arange and the given extra vertex properties."""
    from plyfile import PlyData, PlyElement
    cols = {"x": np.arange(n, dtype="f8"), "y": np.arange(n, dtype="f8") + 10, "z": np.arange(n, dtype="f8") + 20}
    cols.update({k: np.asarray(v) for k, v in props.items()})
    vert = np.empty(n, dtype=[(k, v.dtype.str) for k, v in cols.items()])
    for k, v in cols.items():
        vert[k] = v
    PlyData([PlyElement.describe(vert, "vertex")], text=not binary, comments=list(comments)).write(str(path))
    return cols


_F2 = {"a_0": np.ones(4), "a_1": np.full(4, 0.5)}
_SPOOFS = [  # (comment, extra properties, {attribute: shape} expected beside positions)
    ("o3dheat attribute x 3 <f8", {"x_0": np.ones(4), "x_1": np.ones(4), "x_2": np.ones(4)},
     {"x_0": (4,), "x_1": (4,), "x_2": (4,)}),
    ("o3dheat attribute positions 2 <f8", {"positions_0": np.ones(4), "positions_1": np.ones(4)},
     {"positions_0": (4,), "positions_1": (4,)}),
    ("o3dheat attribute normals 2 <f8", {"normals_0": np.ones(4), "normals_1": np.ones(4)},
     {"normals_0": (4,), "normals_1": (4,)}),
    ("o3dheat attribute colors 1 <f8 shape=()", {"colors": np.ones(4)}, {}),
    ("o3dheat attribute o3dheat_colors 2 <f8", {"o3dheat_colors_0": np.ones(4), "o3dheat_colors_1": np.ones(4)},
     {"o3dheat_colors_0": (4,), "o3dheat_colors_1": (4,)}),
    ("o3dheat attribute a 5 <f8", _F2, {"a_0": (4,), "a_1": (4,)}),
    ("o3dheat attribute a 2 <f8 shape=(1000000,1000000)", _F2, {"a_0": (4,), "a_1": (4,)}),
    ("o3dheat attribute a 2 <f8 shape=(-2,-1)", _F2, {"a_0": (4,), "a_1": (4,)}),
    ("o3dheat attribute a 99999999999999999999 <f8", _F2, {"a_0": (4,), "a_1": (4,)}),
    ("o3dheat attribute a two <f8", _F2, {"a_0": (4,), "a_1": (4,)}),
    ("o3dheat attribute a 2 object", _F2, {"a_0": (4,), "a_1": (4,)}),
    ("o3dheat attribute a 2 <c16", _F2, {"a_0": (4,), "a_1": (4,)}),
    ("o3dheat attribute", _F2, {"a_0": (4,), "a_1": (4,)}),
    ("o3dheat attribute a 2 <i8", _F2, {"a_0": (4,), "a_1": (4,)}),  # 0.5 is no int64
    ("o3dheat attribute a 2 <f4", _F2, {"a_0": (4,), "a_1": (4,)}),  # columns are f8
    ("o3dheat attribute a 2 |b1", {"a_0": np.full(4, 2, np.uint8), "a_1": np.ones(4, np.uint8)},
     {"a_0": (4,), "a_1": (4,)}),
    ("o3dheat attribute a 2 <f8", {"a_0": np.ones(4), "a_1": np.ones(4, "f4")}, {"a_0": (4,), "a_1": (4,)}),
    ("o3dheat attribute a 2 |i1", {"a_0": np.full(4, 300, "i4"), "a_1": np.ones(4, "i4")},  # 300 is no int8
     {"a_0": (4,), "a_1": (4,)}),
    ("o3dheat attribute a 2 <u8", {"a_0": np.full(4, -1, "i4"), "a_1": np.ones(4, "i4")},  # -1 is no uint64
     {"a_0": (4,), "a_1": (4,)}),
    ("o3dheat attribute a 2 <u2", {"a_0": np.ones(4, "f8"), "a_1": np.ones(4, "f8")},  # uint16 is never double
     {"a_0": (4,), "a_1": (4,)}),
    ("o3dheat attribute a_0 1 <f8 shape=()", {"a_0": np.ones(4)}, {"a_0": (4,)}),  # harmless, as written
    ("o3dheat attribute y 1 <f8 shape=()", {}, {}),
]


@pytest.mark.parametrize("case", range(len(_SPOOFS)))
@pytest.mark.parametrize("binary", [True, False])
def test_crafted_comments_are_ignored(tmp_path, caplog, case, binary):
    import logging

    from o3dheat.io import read_geometry
    comment, props, expected = _SPOOFS[case]
    p = tmp_path / "c.ply"
    cols = _ply(p, props, [comment, comment], binary)  # twice: a repeated comment is no problem either
    with caplog.at_level(logging.WARNING, logger="o3dheat"):
        g = read_geometry(p)
    np.testing.assert_array_equal(g.point.positions.numpy(), np.stack([cols["x"], cols["y"], cols["z"]], 1))
    got = {k: g.point[k].numpy().shape for k in g.point if k != "positions"}
    assert got == expected
    if case != len(_SPOOFS) - 2:
        assert "ignoring" in caplog.text


# ------------------------------------------------ files for other tools (issue 15)
def _foreign_mesh():
    """A mesh with an attribute of every kind o3dheat writes, including the ones PLY lacks."""
    m = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 8)
    n = len(m.vertex.positions)
    r = np.random.default_rng(4)
    m.vertex.normals = m.vertex.positions / 1.0
    m.vertex.colors = o3d.core.Tensor(r.random((n, 3)).astype(np.float32))
    m.vertex["f"] = o3d.core.Tensor(r.standard_normal(n))
    m.vertex["hks"] = o3d.core.Tensor(r.random((n, 3)))
    m.vertex["crit"] = o3d.core.Tensor(r.integers(0, 4, n).astype(np.int8))  # what critical_points writes
    m.vertex["i16"] = o3d.core.Tensor(r.integers(-30000, 30000, n).astype(np.int16))
    m.vertex["u16"] = o3d.core.Tensor(r.integers(0, 65535, n).astype(np.uint16))
    m.vertex["u32"] = o3d.core.Tensor(np.arange(n, dtype=np.uint32) + np.uint32(2 ** 32 - 200))  # beyond int32
    m.vertex["big"] = o3d.core.Tensor(np.arange(n, dtype=np.int64) + 2 ** 40)
    m.vertex["flag"] = o3d.core.Tensor(np.arange(n) % 3 == 0)
    return m


def _expected_columns(m):
    """{PLY property: values} of the custom attributes, as other readers should see them."""
    out = {}
    for key in m.vertex:
        if key in ("positions", "normals", "colors"):
            continue
        a = m.vertex[key].numpy()
        if a.ndim == 1:
            out[key] = a.astype(np.float64)
        else:
            out.update({f"{key}_{j}": a[:, j].astype(np.float64) for j in range(a.shape[1])})
    return out


@pytest.mark.parametrize("binary", [True, False])
def test_written_ply_uses_only_types_every_reader_reads(tmp_path, binary):
    from plyfile import PlyData
    m = _foreign_mesh()
    p = tmp_path / "m.ply"
    write_mesh(p, m, binary=binary, lossless_colors=True)
    types = {prop.name: str(prop).split()[1] for prop in PlyData.read(str(p))["vertex"].properties}
    assert set(types.values()) <= {"uchar", "int", "float", "double"}, types
    assert types["crit"] == types["i16"] == types["u16"] == "int" and types["flag"] == "uchar"
    assert types["u32"] == types["big"] == "double" and types["red"] == "uchar"  # colours not k/255:
    assert types["o3dheat_colors_0"] == "float"  # their exact copy, asked for
    _assert_exact(m.vertex, read_mesh(p).vertex)  # o3dheat's own reader: still exact


def test_open3d_reads_our_ply(tmp_path):
    m = _foreign_mesh()
    p = tmp_path / "m.ply"
    write_mesh(p, m)
    V, F = m.vertex.positions.numpy(), m.triangle.indices.numpy()
    legacy = o3d.io.read_triangle_mesh(str(p))
    np.testing.assert_array_equal(np.asarray(legacy.vertices), V)
    np.testing.assert_array_equal(np.asarray(legacy.triangles), F)
    assert legacy.has_vertex_normals() and legacy.has_vertex_colors()
    t = o3d.t.io.read_triangle_mesh(str(p))
    np.testing.assert_array_equal(t.vertex.positions.numpy(), V)
    np.testing.assert_array_equal(t.triangle.indices.numpy(), F)
    pc = o3d.t.io.read_point_cloud(str(p))  # Open3D's reader that keeps custom properties: all of them
    np.testing.assert_array_equal(pc.point.positions.numpy(), V)
    for key, values in _expected_columns(m).items():
        assert key in pc.point, key
        np.testing.assert_array_equal(pc.point[key].numpy().ravel().astype(np.float64), values, err_msg=key)


def test_trimesh_reads_our_ply(tmp_path):
    trimesh = pytest.importorskip("trimesh")
    m = _foreign_mesh()
    p = tmp_path / "m.ply"
    write_mesh(p, m)
    t = trimesh.load(str(p), process=False)
    np.testing.assert_array_equal(t.vertices, m.vertex.positions.numpy())
    np.testing.assert_array_equal(t.faces, m.triangle.indices.numpy())
    data = t.metadata["_ply_raw"]["vertex"]["data"]
    for key, values in _expected_columns(m).items():
        np.testing.assert_array_equal(data[key].ravel().astype(np.float64), values, err_msg=key)


@pytest.mark.parametrize("binary", [True, False])
def test_meshio_reads_our_ply(tmp_path, binary):
    meshio = pytest.importorskip("meshio")
    m = _foreign_mesh()
    p = tmp_path / "m.ply"
    write_mesh(p, m, binary=binary)
    r = meshio.read(str(p))
    np.testing.assert_array_equal(r.points, m.vertex.positions.numpy())
    np.testing.assert_array_equal(r.cells_dict["triangle"], m.triangle.indices.numpy())
    for key, values in _expected_columns(m).items():
        got = r.point_data[key].ravel()
        if key == "flag" and binary:  # meshio 5.3 reads binary uchar as signed: fine for 0/1
            got = got.astype(np.uint8)
        np.testing.assert_array_equal(got.astype(np.float64), values, err_msg=key)


def test_files_of_older_versions_with_char_short_ushort_uint_still_read_exactly(tmp_path):
    from o3dheat.io import read_geometry
    props = {"c": np.array([-128, 0, 1, 127], "i1"), "s": np.array([-3, 0, 1, 2], "i2"),
             "us": np.array([0, 1, 2, 65535], "u2"), "u": np.array([0, 1, 2, 2 ** 32 - 1], "u4"),
             "w_0": np.array([-1, 0, 1, 2], "i1"), "w_1": np.array([5, 6, 7, 8], "i1"),
             "q_0": np.array([0, 1, 2, 3], "u4"), "q_1": np.array([4, 5, 6, 7], "u4")}
    p = tmp_path / "old.ply"
    _ply(p, props, ["o3dheat attribute w 2 |i1", "o3dheat attribute q 2 <u8"])
    g = read_geometry(p)
    for key in ("c", "s", "us", "u"):
        assert g.point[key].numpy().dtype == props[key].dtype
        np.testing.assert_array_equal(g.point[key].numpy(), props[key])
    assert g.point["w"].numpy().dtype == np.int8 and g.point["w"].numpy().tolist()[0] == [-1, 5]
    assert g.point["q"].numpy().dtype == np.uint64 and g.point["q"].numpy().tolist()[3] == [3, 7]


def test_plain_property_named_positions_is_ignored(tmp_path, caplog):
    from o3dheat.io import read_geometry
    p = tmp_path / "c.ply"
    cols = _ply(p, {"positions": np.full(4, 7.0), "normals": np.ones(4)})
    g = read_geometry(p)
    assert sorted(g.point) == ["positions"]
    np.testing.assert_array_equal(g.point.positions.numpy()[:, 0], cols["x"])
    assert "ignoring vertex property 'positions'" in caplog.text


def test_old_format_comments_still_read(tmp_path):
    """Files written before the shape/dtype extension: ``o3dheat attribute NAME C DTYPE``."""
    from o3dheat.io import read_geometry
    r = np.random.default_rng(0)
    hks = r.random((4, 3))
    props = {f"hks_{j}": hks[:, j] for j in range(3)}
    props.update({"lab_0": np.arange(4, dtype="i4"), "lab_1": np.arange(4, dtype="i4"), "f": np.ones(4, "f4")})
    col = r.random((4, 3))
    props.update({f"o3dheat_colors_{j}": col[:, j] for j in range(3)})
    props.update({"red": np.zeros(4, "u1"), "green": np.zeros(4, "u1"), "blue": np.zeros(4, "u1")})
    p = tmp_path / "old.ply"
    _ply(p, props, ["o3dheat attribute hks 3 <f8", "o3dheat attribute lab 2",
                    "o3dheat attribute o3dheat_colors 3 <f8"])
    g = read_geometry(p)
    np.testing.assert_array_equal(g.point["hks"].numpy(), hks)
    assert g.point["lab"].numpy().dtype == np.int32 and g.point["lab"].numpy().shape == (4, 2)
    assert g.point["f"].numpy().dtype == np.float32
    np.testing.assert_array_equal(g.point.colors.numpy(), col)
    assert sorted(g.point) == ["colors", "f", "hks", "lab", "positions"]


_HEAD = (b"ply\nformat %s 1.0\nelement vertex %s\nproperty float x\nproperty float y\nproperty float z\n"
         b"element face %s\nproperty list uchar int vertex_indices\nend_header\n")


@pytest.mark.parametrize("fmt", [b"binary_little_endian", b"ascii"])
def test_huge_header_counts_are_refused_before_reading(tmp_path, fmt):
    p = tmp_path / "huge.ply"
    p.write_bytes(_HEAD % (fmt, b"1000000000", b"0") + bytes(10_000))
    with pytest.raises(o3dheat.MeshError, match=r"truncated or corrupt: the header declares 1000000000 vertices "
                                                r"and 0 faces, the file has \d+ bytes"):
        read_mesh(p)
    p.write_bytes(_HEAD % (fmt, b"3", b"1000000000") + bytes(10_000))
    with pytest.raises(o3dheat.MeshError, match="1000000000 faces"):
        read_mesh(p)
    for count in (b"99999999999999999999999", b"-1", b"1e9"):
        p.write_bytes(_HEAD % (fmt, count, b"0") + bytes(100))
        with pytest.raises(o3dheat.MeshError, match="absurd element count"):
            read_mesh(p)


def test_bad_headers_are_refused(tmp_path):
    p = tmp_path / "h.ply"
    for data, match in [
        (b"ply\nformat ascii 1.0\nelement vertex 1\n" + b"comment x\n" * 8000, "no end_header in the first"),
        (b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n", "no end_header"),
        (b"PLY\n", "no 'ply' magic"),
        (b"ply\nformat weird 1.0\nelement vertex 0\nend_header\n", "unknown format"),
        (b"ply\nformat ascii 1.0\nelement vertex 1\nproperty quad x\nend_header\n1\n", "unexpected header line"),
        (b"ply\nformat ascii 1.0\nproperty float x\nend_header\n", "unexpected header line"),
    ]:
        p.write_bytes(data)
        with pytest.raises(o3dheat.MeshError, match=match):
            read_mesh(p)


def test_written_files_pass_the_header_check_exactly(tmp_path):
    """The size bound is tight enough for real files: an empty-attribute point cloud and a mesh
    with one vertex row cut off."""
    m = _sphere()
    p = tmp_path / "m.ply"
    write_mesh(p, m)
    data = p.read_bytes()
    assert len(read_mesh(p).vertex.positions) == 26
    p.write_bytes(data[: -(48 * 13)])  # all faces but a few bytes: plyfile or the size check refuses
    with pytest.raises(o3dheat.MeshError, match="not a readable PLY"):
        read_mesh(p)


def test_crafted_npz_is_refused(tmp_path):
    from o3dheat.io import read_geometry
    p = tmp_path / "obj.npz"
    np.savez(p, positions=np.zeros((3, 3)), vertex_o=np.array([{"a": 1}, None, 3], dtype=object))
    with pytest.raises(o3dheat.MeshError, match="not a readable NPZ.*pickle"):
        read_geometry(p)
    p = tmp_path / "pos.npz"
    np.savez(p, positions=np.zeros((3, 3)), vertex_positions=np.ones((3, 3)))
    with pytest.raises(o3dheat.MeshError, match="'vertex_positions'"):
        read_geometry(p)


@pytest.mark.parametrize("faces", [True, False])
def test_binary_ply_is_plyfiles_own_bytes_and_reads_back_the_same_both_ways(tmp_path, mesh, monkeypatch, faces):
    """The block writer of triangles gives what plyfile writes face by face, and the block reader
    of triangle lists what plyfile reads face by face."""
    import plyfile

    import o3dheat.io._ply

    geometry = mesh if faces else o3d.t.geometry.PointCloud(mesh.vertex.positions)
    fast, slow = tmp_path / "fast.ply", tmp_path / "slow.ply"
    write_geometry(fast, geometry)
    with monkeypatch.context() as m:
        m.setattr(o3dheat.io._ply, "_write_binary_ply", lambda fh, ply, vert, F: ply.write(fh))
        write_geometry(slow, geometry)
    assert fast.read_bytes() == slow.read_bytes()
    a = o3dheat.io.read_geometry(fast)
    monkeypatch.setattr(o3dheat.io._ply, "_TRIANGLE_LISTS", {})  # plyfile's face-by-face reading
    b = o3dheat.io.read_geometry(fast)
    attrs = (lambda g: g.vertex) if faces else (lambda g: g.point)
    assert sorted(attrs(a)) == sorted(attrs(b))
    for k in attrs(a):
        assert np.array_equal(attrs(a)[k].numpy(), attrs(b)[k].numpy())
    if faces:
        assert np.array_equal(a.triangle.indices.numpy(), b.triangle.indices.numpy())
        assert len(plyfile.PlyData.read(str(fast))["face"].data) == len(mesh.triangle.indices)


def test_binary_stl_is_read_in_one_block_as_open3d_reads_it(tmp_path):
    """Same triangles (as coordinates) as Open3D's STL reader, every triangle with its own three
    vertices; an ASCII STL is read (and checked) by o3dheat too."""
    legacy = o3d.geometry.TriangleMesh.create_torus(1.0, 0.4, 30, 12)
    legacy.compute_triangle_normals()
    path = tmp_path / "t.stl"
    o3d.io.write_triangle_mesh(str(path), legacy)
    ours = o3dheat.io.read_geometry(path)
    V, F = ours.vertex.positions.numpy(), ours.triangle.indices.numpy()
    assert V.dtype == np.float64 and np.array_equal(F, np.arange(3 * len(legacy.triangles)).reshape(-1, 3))
    theirs = o3d.io.read_triangle_mesh(str(path))
    Vo, Fo = np.asarray(theirs.vertices), np.asarray(theirs.triangles)
    assert np.array_equal(V[F], Vo[Fo])  # the same corners, triangle by triangle
    ascii_path = tmp_path / "a.stl"  # Open3D writes no ASCII STL
    ascii_path.write_text(_ascii_stl(Vo[Fo].astype(np.float32)))
    a = o3dheat.io.read_geometry(ascii_path)
    assert len(a.triangle.indices) == len(legacy.triangles)
    np.testing.assert_array_equal(a.vertex.positions.numpy(), Vo[Fo].reshape(-1, 3).astype(np.float32))
    (tmp_path / "empty.stl").write_bytes(bytes(84))  # a binary STL of no triangles
    with pytest.raises(o3dheat.MeshError, match="no triangles could be read"):
        o3dheat.io.read_geometry(tmp_path / "empty.stl")


def _ascii_stl(T):
    return "solid t\n" + "".join("facet normal 0 0 1\n outer loop\n" + "".join(
        f"  vertex {x!r} {y!r} {z!r}\n" for x, y, z in t) + " endloop\nendfacet\n" for t in T.tolist()) + "endsolid t\n"


def _sample(name):
    import importlib.resources

    return importlib.resources.files("pymeshlab") / "tests" / "sample_meshes" / name


def _v_lines(path):
    return np.array([line.split()[1:4] for line in path.read_text().splitlines() if line.startswith("v ")], float)


def _write_binary_stl(path, V, F):
    """A binary STL by hand (numpy): 80-byte header, count, 50 bytes per triangle."""
    T = V[F].astype(np.float32)
    n = np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0])
    rec = np.zeros(len(F), dtype=[("n", "<f4", (3,)), ("c", "<f4", (3, 3)), ("a", "<u2")])
    rec["n"], rec["c"] = n, T
    path.write_bytes(bytes(80) + np.uint32(len(F)).tobytes() + rec.tobytes())


def test_stl_and_obj_of_one_surface_give_one_answer(tmp_path, caplog):
    """cow.obj as read and as binary STL: the same spectrum and Euler characteristic (the OBJ
    went through Open3D, which merged its two vertices 45 and 2904 into a pinched one: 2.3888
    against the STL's 2.3241, chi 1 against 2). The STL's weld says it kept a pair apart."""
    obj = read_mesh(_sample("cow.obj"))
    V, F = o3dheat.as_arrays(obj)
    assert np.array_equal(V, _v_lines(_sample("cow.obj")))  # the file's float64 values
    V32 = V.astype(np.float32).astype(np.float64)  # what an STL holds: compare like with like
    _write_binary_stl(tmp_path / "cow.stl", V, F)
    stl = read_mesh(tmp_path / "cow.stl")
    obj32 = (V32, F)
    ro, rs = o3dheat.check_mesh(obj32), o3dheat.check_mesh(stl)
    assert ro.euler_characteristic == rs.euler_characteristic == 2
    assert ro.non_manifold_vertices == rs.non_manifold_vertices == 0 and rs.split_vertices == 1
    assert (ro.components, ro.boundary_loops) == (rs.components, rs.boundary_loops)
    with caplog.at_level("WARNING", logger="o3dheat"):
        b = o3dheat.eigensolve(stl, k=5).eigenvalues
    assert "1 vertices coincide with another but are kept apart (split" in caplog.text
    a = o3dheat.eigensolve(obj32, k=5).eigenvalues
    np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(o3dheat.eigensolve(obj, k=5).eigenvalues, a, rtol=1e-5, atol=1e-9)
    assert abs(a[1] - 2.3241) < 1e-3


@pytest.mark.parametrize("name", ["bunny10k_textured.obj", "bunny.obj", "cow.obj", "airplane.obj"])
def test_obj_keeps_the_files_vertices_in_order(name):
    """Open3D's reader split bunny10k_textured's 5051 vertices at texture seams (6451) and
    reordered bunny.obj's."""
    m = read_mesh(_sample(name))
    want = _v_lines(_sample(name))
    np.testing.assert_array_equal(m.vertex.positions.numpy(), want)
    F = m.triangle.indices.numpy()
    n_f = sum(1 for line in _sample(name).read_text().splitlines() if line.startswith("f "))
    assert F.dtype == np.int64 and len(F) >= n_f and F.max() < len(want)
    if name == "bunny10k_textured.obj":
        uv = m.triangle["texture_uvs"].numpy()
        assert uv.shape == (len(F), 3, 2) and 0 <= uv.min() and uv.max() <= 1
        # against pymeshlab's loader (same positions and faces, wedge texture coordinates)
        pymeshlab = pytest.importorskip("pymeshlab")
        ms = pymeshlab.MeshSet()
        ms.load_new_mesh(str(_sample(name)))
        pm = ms.current_mesh()
        np.testing.assert_allclose(pm.vertex_matrix(), want, rtol=0, atol=1e-6)
        np.testing.assert_array_equal(pm.face_matrix(), F)


def test_obj_forms_negative_indices_polygons_and_comments(tmp_path, caplog):
    text = """# a comment
mtllib none.mtl
o square
v 0 0 0
v 1 0 0
v 1 1 0 0.5 0.25 1.0
v 0 1 0
vt 0 0
vt 1 0
vt 1 1
vt 0 1
vn 0 0 1
g top
usemtl m
s off
f 1/1/1 2/2/1 3/3/1 4/4/1
v 0 0 1
f -5/-4/-1 -4/-3/-1 -1/-1/-1
l 1 2
"""
    (tmp_path / "q.obj").write_text(text)
    with caplog.at_level("WARNING", logger="o3dheat"):
        m = read_mesh(tmp_path / "q.obj")
    assert "1 polygons with more than 3 corners triangulated" in caplog.text
    assert m.triangle.indices.numpy().tolist() == [[0, 1, 2], [0, 2, 3], [0, 1, 4]]
    assert len(m.vertex.positions) == 5 and "colors" not in m.vertex  # not every v has colours
    uv = m.triangle["texture_uvs"].numpy()
    assert uv[1].tolist() == [[0, 0], [1, 1], [0, 1]] and uv[2].tolist() == [[0, 0], [1, 0], [0, 1]]
    (tmp_path / "c.obj").write_text("v 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 0 1 0 0 0 1\nf 1//1 2//1 3//1\nvn 0 0 1\n"
                                    .replace("vn 0 0 1\n", "").replace("f ", "vn 0 0 1\nf "))
    c = read_mesh(tmp_path / "c.obj")
    assert c.vertex.colors.numpy().tolist() == np.eye(3).tolist() and "texture_uvs" not in c.triangle


@pytest.mark.parametrize("body,line,what", [
    ("v 0 0 0\nv 1 0\nv 0 1 0\nf 1 2 3\n", 2, "'v' needs"),
    ("v 0 0 0\nv 1 0 x\nv 0 1 0\nf 1 2 3\n", 2, "'v' needs"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\n\nf 1 2\n", 5, "at least 3 corners"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", 4, "vertex index 4 is out of range"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", 4, "vertex index 0 is out of range"),
    ("v 0 0 0\nv 1 0 0\nf 1 2 -3\nv 0 1 0\n", 3, "vertex index -3 is out of range"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3.5\n", 4, "vertex index '3.5'"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/2 3/1\n", 5, "texture coordinate index 2 is out of range"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/1/1/1 2 3\n", 4, "bad face corner"),
])
def test_malformed_obj_names_the_line(tmp_path, body, line, what):
    (tmp_path / "bad.obj").write_text(body)
    with pytest.raises(o3dheat.MeshError, match=f"line {line}: .*{what}" if "line" not in what else what):
        read_mesh(tmp_path / "bad.obj")
    (tmp_path / "none.obj").write_text("# nothing\nv 0 0 0\n")
    with pytest.raises(o3dheat.MeshError, match="no triangles"):
        read_mesh(tmp_path / "none.obj")


def test_truncated_stl_is_refused(tmp_path):
    V, F = o3dheat.as_arrays(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 20))
    text = _ascii_stl(V[F].astype(np.float32))
    (tmp_path / "ok.stl").write_text(text)
    assert len(read_mesh(tmp_path / "ok.stl").triangle.indices) == len(F)
    lines = text.splitlines(keepends=True)
    cut = 1 + 7 * 122 + 4  # facet 123: the file ends after two of its vertices (line cut)
    (tmp_path / "cut.stl").write_text("".join(lines[:cut]))
    with pytest.raises(o3dheat.MeshError, match=f"facet 123 is incomplete at line {cut}: the file ends"):
        read_mesh(tmp_path / "cut.stl")
    (tmp_path / "end.stl").write_text("".join(lines[:-1]))  # every facet, no endsolid
    with pytest.raises(o3dheat.MeshError, match="no 'endsolid' after facet"):
        read_mesh(tmp_path / "end.stl")
    bad = lines[:]
    bad[10] = "  vertex 1 2\n"
    (tmp_path / "bad.stl").write_text("".join(bad))
    with pytest.raises(o3dheat.MeshError, match="line 11: a vertex needs three numbers"):
        read_mesh(tmp_path / "bad.stl")
    _write_binary_stl(tmp_path / "b.stl", V, F)
    data = (tmp_path / "b.stl").read_bytes()
    (tmp_path / "b.stl").write_bytes(data[:-20])
    with pytest.raises(o3dheat.MeshError, match=f"declares {len(F)} triangles.*truncated"):
        read_mesh(tmp_path / "b.stl")
    lines[7 * 5] = "facet normal 0 0 1\n"  # facet 5's endfacet replaced: facet 6 starts early
    (tmp_path / "early.stl").write_text("".join(lines))
    with pytest.raises(o3dheat.MeshError, match=f"facet 5 is incomplete at line {1 + 7 * 5}: expected 'endfacet'"):
        read_mesh(tmp_path / "early.stl")


@pytest.mark.parametrize("binary", [True, False])
def test_ply_float_face_indices_must_be_integers(tmp_path, binary):
    from plyfile import PlyData, PlyElement

    vert = np.array([(0, 0, 0), (1, 0, 0), (0, 1, 0), (1, 1, 0)], dtype=[("x", "f4"), ("y", "f4"), ("z", "f4")])
    for values, ok in [([[0, 1, 2], [1, 3, 2]], True), ([[0, 1, 2], [0.5, 3, 2]], False)]:
        face = np.empty(2, dtype=[("vertex_indices", "f4", (3,))])
        face["vertex_indices"] = values
        path = tmp_path / "f.ply"
        PlyData([PlyElement.describe(vert, "vertex"), PlyElement.describe(face, "face")], text=not binary).write(str(path))
        if ok:
            assert read_mesh(path).triangle.indices.numpy().tolist() == values
        else:
            with pytest.raises(o3dheat.MeshError, match="face 1 has the vertex index 0.5, not an integer"):
                read_mesh(path)


@pytest.mark.parametrize("value", ["no", "False", 0, 1, None, np.array([True])])
def test_flags_must_be_bools(tmp_path, mesh, value):
    for kw in ("binary", "overwrite", "lossless_colors"):
        with pytest.raises(o3dheat.MeshError, match=f"{kw} must be True or False"):
            write_mesh(tmp_path / "m.ply", mesh, **{kw: value})
    assert not list(tmp_path.iterdir())
    write_mesh(tmp_path / "m.ply", mesh, binary=np.bool_(False))


@pytest.mark.parametrize("colors,copy", [
    (np.array([[0, 1, 2], [255, 128, 7]] * 21, np.float32)[:42] / np.float32(255), None),  # exact in 8 bits
    (np.random.default_rng(2).random((42, 3)).astype(np.float32), "float"),
    (np.random.default_rng(3).random((42, 3)), "double"),
    (np.random.default_rng(4).integers(0, 256, (42, 3)).astype(np.uint8), None),
])
@pytest.mark.parametrize("lossless", [False, True])
@pytest.mark.parametrize("binary", [True, False])
def test_colours_are_stored_once_in_8_bits(tmp_path, colors, copy, lossless, binary):
    """Colours are uchar red green blue (issue 29: float ones were stored as float or double,
    which Open3D's mesh readers showed black and MeshLab white); their exact copy only with
    lossless_colors and only where 8 bits lose something (it was once written in every file)."""
    from plyfile import PlyData

    m = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 5)  # 42 vertices
    m.vertex.colors = o3d.core.Tensor(colors)
    write_mesh(tmp_path / "c.ply", m, binary=binary, lossless_colors=lossless)
    props = {p.name: str(p).split()[1] for p in PlyData.read(str(tmp_path / "c.ply"))["vertex"].properties}
    extra = [f"o3dheat_colors_{j}" for j in range(3)] if lossless and copy else []
    assert sorted(props) == sorted(["blue", "green", "red", "x", "y", "z"] + extra)
    assert [props[c] for c in ("red", "green", "blue")] == ["uchar"] * 3 and {props[k] for k in extra} <= {copy}
    back = read_mesh(tmp_path / "c.ply").vertex.colors.numpy()
    assert back.dtype == colors.dtype
    if lossless or copy is None:
        np.testing.assert_array_equal(back, colors)
    else:
        np.testing.assert_allclose(back, colors, rtol=0, atol=0.5 / 255 + 1e-7)
    u8 = colors if colors.dtype == np.uint8 else np.round(colors.astype(np.float64) * 255).astype(np.uint8)
    pc = o3d.t.io.read_point_cloud(str(tmp_path / "c.ply")).point.colors.numpy()  # what other readers see
    np.testing.assert_array_equal(pc, u8)


def test_formats_are_one_table_that_reading_and_batches_follow(tmp_path, monkeypatch):
    """Issue 23: one READERS/WRITERS table: a reader added there is what read_mesh and batches
    use; the batches' output suffixes are the writers'."""
    import o3dheat.pipelines._inputs as batch  # the batches' inputs and outputs
    from o3dheat.io import meshes as io

    assert batch.SUFFIXES == tuple(io.WRITERS) and set(io.WRITERS) <= set(io.READERS)
    calls = []
    sphere = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 6)
    monkeypatch.setitem(io.READERS, ".mine", lambda p: calls.append(p) or sphere)
    (tmp_path / "x.mine").write_text("anything")
    assert io.read_mesh(tmp_path / "x.mine") is not None and calls == [tmp_path / "x.mine"]


def test_a_missing_input_is_both_a_mesh_error_and_file_not_found(tmp_path):
    """Errors by kind (issue 23): a path naming no file is a bad argument and the file system's
    FileNotFoundError at once, wherever o3dheat checks an input path before reading it."""
    import o3dheat.pipelines.filters as flt
    from o3dheat import Spectrum
    from o3dheat.errors import MeshError, NoSuchFile
    from o3dheat.io import read_geometry, read_mesh, read_toml
    from o3dheat.pipelines.batch import expand

    missing = tmp_path / "nothing.ply"
    for call in (lambda: read_mesh(missing), lambda: read_geometry(missing), lambda: expand([str(missing)]),
                 lambda: flt.Chain.load(tmp_path / "chain.toml"), lambda: read_toml(tmp_path / "study.toml"),
                 lambda: Spectrum.load(tmp_path / "spectrum.npz")):
        with pytest.raises(NoSuchFile) as info:
            call()
        assert isinstance(info.value, MeshError) and isinstance(info.value, FileNotFoundError)
        assert str(tmp_path) in str(info.value)


def test_a_folder_given_as_a_file_is_named_a_folder_not_a_missing_file(tmp_path):
    """A folder where a mesh or chain file is expected exists: it is a MeshError saying so, not a
    FileNotFoundError (the former 'no such file' named it missing)."""
    import o3dheat.pipelines.filters as flt
    from o3dheat.errors import MeshError
    from o3dheat.io import read_mesh

    for call in (lambda: read_mesh(tmp_path), lambda: flt.Chain.load(tmp_path)):
        with pytest.raises(MeshError, match="folder") as info:
            call()
        assert not isinstance(info.value, FileNotFoundError)


# ------------------------------------------------ colours for every viewer (issue 29)

def _colorized(source):
    """The colorize filter's output on a generated sphere or on one of pymeshlab's sample PLYs
    (colored_airplane.ply coloured anew by its quality, replacing its 8-bit colours; bone.ply by
    height), with a multi-column float64 field beside the colours."""
    import o3dheat.pipelines.filters as flt

    if source == "sphere":
        m = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 20)
    else:
        m = read_mesh(_sample(source))
    attribute = "quality" if "quality" in m.vertex else "height"
    if attribute == "height":
        m = flt.apply(m, "scalar", kind="height")
    m = flt.apply(m, "colorize", attribute=attribute)
    n = len(m.vertex.positions)
    m.vertex["f_smooth"] = o3d.core.Tensor(np.random.default_rng(5).standard_normal((n, 4)))
    return m


_SOURCES = ["sphere", "colored_airplane.ply", "bone.ply"]


_TOL = 0.5 / 255 + 1e-6  # 8 bits: half a step (and float32 rounding)


@pytest.mark.parametrize("source", _SOURCES)
@pytest.mark.parametrize("binary", [True, False])
def test_colorized_ply_has_8_bit_colours_for_every_reader(tmp_path, source, binary):
    """Issue 29: colorize's colours were written as float red green blue, which Open3D's mesh
    readers showed black (at most 1/255) and MeshLab white. Now uchar, read the same by Open3D
    (legacy and tensor), plyfile, o3dheat, trimesh and MeshLab; every other attribute still exact."""
    m = _colorized(source)
    C = m.vertex.colors.numpy()
    assert C.dtype == np.float32 and 0 <= C.min() and C.max() <= 1  # what colorize writes
    p = tmp_path / "c.ply"
    write_mesh(p, m, binary=binary)
    header = p.read_bytes().split(b"end_header")[0]
    assert b"property uchar red\nproperty uchar green\nproperty uchar blue\n" in header
    assert b"o3dheat_colors" not in header  # no float copy unless asked for
    legacy = o3d.io.read_triangle_mesh(str(p))
    np.testing.assert_allclose(np.asarray(legacy.vertex_colors), C, rtol=0, atol=_TOL)
    tensor = o3d.t.io.read_triangle_mesh(str(p)).vertex.colors.numpy()
    np.testing.assert_allclose(tensor, C, rtol=0, atol=_TOL)
    from plyfile import PlyData
    vert = PlyData.read(str(p))["vertex"].data
    rgb = np.stack([vert["red"], vert["green"], vert["blue"]], 1)
    assert rgb.dtype == np.uint8
    np.testing.assert_array_equal(rgb, np.round(C.astype(np.float64) * 255))
    back = read_mesh(p)
    assert back.vertex.colors.numpy().dtype == np.float32
    np.testing.assert_allclose(back.vertex.colors.numpy(), C, rtol=0, atol=_TOL)
    others = [k for k in m.vertex if k != "colors"]
    assert "f_smooth" in others and sorted(back.vertex) == sorted(m.vertex)
    _assert_exact({k: m.vertex[k] for k in others}, {k: back.vertex[k] for k in others})
    import pymeshlab  # MeshLab showed the float colours white

    ms = pymeshlab.MeshSet()
    ms.load_new_mesh(str(p))
    np.testing.assert_array_equal(ms.current_mesh().vertex_color_matrix()[:, :3], rgb / 255)
    trimesh = pytest.importorskip("trimesh")
    t = trimesh.load(str(p), process=False)
    np.testing.assert_array_equal(t.visual.vertex_colors[:, :3], rgb)
    np.testing.assert_allclose(t.visual.vertex_colors[:, :3] / 255, C, rtol=0, atol=_TOL)


@pytest.mark.parametrize("source", _SOURCES)
@pytest.mark.parametrize("binary", [True, False])
def test_lossless_colours_round_trip_exactly_beside_the_8_bits(tmp_path, source, binary):
    m = _colorized(source)
    p = tmp_path / "c.ply"
    write_mesh(p, m, binary=binary, lossless_colors=True)
    header = p.read_bytes().split(b"end_header")[0]
    assert b"property uchar red\n" in header and b"property float o3dheat_colors_0\n" in header
    _assert_exact(m.vertex, read_mesh(p).vertex)  # colours bit for bit too
    legacy = o3d.io.read_triangle_mesh(str(p))  # viewers still read the 8-bit colours
    np.testing.assert_allclose(np.asarray(legacy.vertex_colors), m.vertex.colors.numpy(), rtol=0, atol=_TOL)


def test_8_bit_colours_of_a_file_come_back_byte_for_byte(tmp_path):
    """colored_airplane.ply's uchar colours, read and written again: the same bytes (no copy
    needed, lossless or not), and read back exactly."""
    from plyfile import PlyData

    src = _sample("colored_airplane.ply")
    m = read_mesh(src)
    for lossless in (False, True):
        write_mesh(tmp_path / "a.ply", m, lossless_colors=lossless)
        a, b = PlyData.read(str(src))["vertex"].data, PlyData.read(str(tmp_path / "a.ply"))["vertex"].data
        assert "o3dheat_colors_0" not in b.dtype.names
        for c in ("red", "green", "blue", "alpha"):
            assert b[c].dtype == np.uint8
            np.testing.assert_array_equal(a[c], b[c])
        _assert_exact(m.vertex, read_mesh(tmp_path / "a.ply").vertex)


def test_colours_outside_0_1_are_clipped_as_open3d_writes_them(tmp_path, caplog):
    """Out of [0, 1]: clipped, with a warning counting the colours clipping changed; the bytes
    are those of Open3D's own writer (round(255 * c) of c clipped)."""
    import logging

    from plyfile import PlyData

    m = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 10)
    n = len(m.vertex.positions)
    C = np.random.default_rng(6).uniform(-0.5, 1.5, (n, 3)).astype(np.float32)
    C[:4] = [[0, 1, 0.5 / 255], [1.5 / 255, 2.5 / 255, 1], [-1 / 600, 1 + 1 / 600, 0.5], [1e-9, 0.9999, 0]]
    m.vertex.colors = o3d.core.Tensor(C)
    with caplog.at_level(logging.WARNING, logger="o3dheat"):
        write_mesh(tmp_path / "ours.ply", m)
    out = ((C.astype(np.float64) * 255 < -0.5) | (C.astype(np.float64) * 255 >= 255.5)).any(axis=1)
    assert f"{int(out.sum())} of {n} vertex colours outside [0, 1]" in caplog.text and 0 < out.sum() < n
    legacy = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(m.vertex.positions.numpy().astype(np.float64)),
                                       o3d.utility.Vector3iVector(m.triangle.indices.numpy()))
    legacy.vertex_colors = o3d.utility.Vector3dVector(C.astype(np.float64))
    o3d.io.write_triangle_mesh(str(tmp_path / "open3d.ply"), legacy)
    ours, theirs = (PlyData.read(str(tmp_path / f))["vertex"].data for f in ("ours.ply", "open3d.ply"))
    for c in ("red", "green", "blue"):
        np.testing.assert_array_equal(ours[c], theirs[c])
    back = read_mesh(tmp_path / "ours.ply").vertex.colors.numpy()
    np.testing.assert_allclose(back, np.clip(C, 0, 1), rtol=0, atol=_TOL)
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="o3dheat"):
        write_mesh(tmp_path / "exact.ply", m, lossless_colors=True)  # the copy keeps them
    assert "kept in o3dheat_colors_*" in caplog.text
    np.testing.assert_array_equal(read_mesh(tmp_path / "exact.ply").vertex.colors.numpy(), C)


def test_obj_with_a_byte_order_mark_keeps_its_first_vertex(tmp_path):
    """Issue 30: "\\ufeffv 0 0 0" was not a vertex line: the first vertex was lost and every index
    shifted by one (silently, when the last vertex is unused)."""
    body = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nv 5 5 5\nf 1 2 3\nf 1 2 4\nf 1 3 4\nf 2 3 4\n"
    (tmp_path / "bom.obj").write_bytes(b"\xef\xbb\xbf" + body.encode())
    (tmp_path / "plain.obj").write_text(body)
    a, b = read_mesh(tmp_path / "bom.obj"), read_mesh(tmp_path / "plain.obj")
    assert np.array_equal(a.vertex.positions.numpy(), b.vertex.positions.numpy())
    assert a.vertex.positions.numpy()[0].tolist() == [0.0, 0.0, 0.0]
    assert np.array_equal(a.triangle.indices.numpy(), b.triangle.indices.numpy())


def test_crafted_npz_and_writing_onto_a_folder_are_one_line_errors(tmp_path):
    """Issue 30: an NPZ with a string attribute, complex or 0-d positions gave Open3D's RuntimeError
    or a TypeError; write_mesh onto a folder an IsADirectoryError from the temporary file's rename."""
    m = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 6)
    V, F = m.vertex.positions.numpy().astype(np.float64), m.triangle.indices.numpy()
    cases = {"text": dict(positions=V, indices=F, vertex_name=np.array(["a"] * len(V))),
             "complex": dict(positions=V.astype(complex), indices=F),
             "scalar": dict(positions=np.array(1.0), indices=F),
             "float faces": dict(positions=V, indices=F + 0.5)}
    for name, arrays in cases.items():
        np.savez(tmp_path / f"{name}.npz", **arrays)
        with pytest.raises(o3dheat.MeshError, match="dtype|positions|indices"):
            read_mesh(tmp_path / f"{name}.npz")
    (tmp_path / "dir.ply").mkdir()
    with pytest.raises(o3dheat.MeshError, match="is a folder"):
        write_mesh(tmp_path / "dir.ply", m)
