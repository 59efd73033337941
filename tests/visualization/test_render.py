"""The static figures' renderer: what is behind the surface is hidden, every part in frame, far from the
origin the same picture, the same pixels every time, matplotlib on purpose, a blank render refused
(PAPER.md row P16)."""

import numpy as np
import pytest
from conftest import icosphere, torus
from pictures import pixels

import o3dheat
import o3dheat.visualization._render as _render
import o3dheat.visualization.plot as plot


def ink(img):
    return np.any(img < 250, axis=2)


def test_what_is_behind_the_surface_is_hidden():
    """x on a sphere seen from +x: the maximum (+x) shows, the minimum (-x) is behind the sphere;
    seen from -x the other way round. A level set on the far side leaves the picture unchanged."""
    V, F = icosphere(3)
    f = V[:, 0]
    front = plot.render((V, F), f, level_sets=None, view=(0, 0), cmap="gray")
    back = plot.render((V, F), f, level_sets=None, view=(0, 180), cmap="gray")
    assert pixels(front, "red") > 20 and pixels(front, "blue") == 0
    assert pixels(back, "blue") > 20 and pixels(back, "red") == 0
    plain = plot.render((V, F), f, level_sets=None, critical_points=False, view=(0, 0))
    far = plot.render((V, F), f, level_sets=[-0.7], critical_points=False, view=(0, 0))
    near = plot.render((V, F), f, level_sets=[0.7], critical_points=False, view=(0, 0))
    assert np.array_equal(plain, far)
    dark = (near.max(axis=2) < 60) & ~(plain.max(axis=2) < 60)
    assert dark.sum() > 100  # the near level set: a visible black ring


def touches_border(img):
    m = ink(img)
    return m[0].any() or m[-1].any() or m[:, 0].any() or m[:, -1].any()


def test_every_part_in_frame():
    """A mesh of two parts far apart, and pymeshlab's airplane (wide wings): everything is in the
    picture, with a margin, and the picture is no larger than the geometry needs."""
    from o3dheat.io import sample_mesh

    V1, F1 = icosphere(2)
    V = np.r_[V1, V1 * 0.5 + [6.0, 0.0, 1.0]]
    F = np.r_[F1, F1 + len(V1)]
    img = plot.render((V, F), V[:, 2], view=(10, -90))
    m = ink(img)
    assert not touches_border(img)
    cols = np.flatnonzero(m.any(axis=0))
    assert cols[0] < 0.06 * m.shape[1] and cols[-1] > 0.94 * m.shape[1]  # tight left and right
    assert m[:, : m.shape[1] // 3].any() and m[:, -m.shape[1] // 6:].any()  # both parts
    plane = sample_mesh("airplane")
    Vp = plane.vertex.positions.numpy()
    img = plot.render(plane, Vp[:, 0], critical_points=False)
    assert not touches_border(img) and ink(img).mean() > 0.1


def test_a_scan_far_from_the_origin_renders_the_same():
    V, F = icosphere(3)
    near = plot.render((V, F), V[:, 0])
    far = plot.render((V + [3e6, -2e6, 1e6], F), V[:, 0])  # float32 has ~0.25 units of resolution there
    assert near.shape == far.shape and np.abs(near.astype(int) - far).mean() < 1.0


def test_the_old_open3d_spelling_draws_with_the_rasterizer_and_warns():
    V, F = torus(1.0, 0.4, 24, 12)
    with pytest.warns(DeprecationWarning, match="renderer='raster'"):
        old = plot.field((V, F), V[:, 0], renderer="open3d")
    assert old.axes[0].name != "3d"
    with pytest.raises(o3dheat.MeshError, match="renderer must be one of auto, raster, matplotlib"):
        plot.field((V, F), V[:, 0], renderer="vulkan")


def test_the_same_picture_every_time_and_from_threads_at_once():
    """The same pixels on every call, also from four threads drawing at once."""
    from concurrent.futures import ThreadPoolExecutor

    V, F = icosphere(3)
    first = plot.render((V, F), V[:, 0] + 0.5 * V[:, 2])
    with ThreadPoolExecutor(4) as pool:
        again = list(pool.map(lambda _: plot.render((V, F), V[:, 0] + 0.5 * V[:, 2]), range(8)))
    assert all(np.array_equal(first, img) for img in again)


def test_rasterized_area_is_the_projected_area():
    """A sphere of radius 1 seen along any axis covers pi r^2 of the picture (to a pixel of its
    outline), and a square seen face-on exactly its pixels."""
    from o3dheat.visualization import _raster

    img, depth = np.ones((64, 64, 3), np.float32), np.full((64, 64), -np.inf)
    P = np.array([[8, 8, 0], [40, 8, 0], [40, 40, 0], [8, 40, 0.0]])
    _raster.draw(P, np.array([[0, 1, 2], [0, 2, 3]]), np.zeros((4, 3)), img, depth)
    assert int((img[..., 0] == 0).sum()) == 32 * 32  # no pixel twice, none missed on the diagonal
    V, F = icosphere(4)
    for view in [(0, 0), (90, 0), (0, 90), (35, -60)]:
        img = plot.render((V, F), V[:, 0], level_sets=None, critical_points=False, view=view)
        inside = ink(img).sum()
        radius = img.shape[0] / 2 / 1.08  # the frame has a margin of 4% of the width on each side
        assert abs(inside - np.pi * radius ** 2) < 2 * np.pi * radius * 1.5, view


def test_a_nearer_surface_hides_a_farther_one_whatever_the_order():
    from o3dheat.visualization import _raster

    quad = np.array([[0, 1, 2], [0, 2, 3]])
    near = np.array([[0, 0, 1.0], [16, 0, 1], [16, 16, 1], [0, 16, 1]])
    far = near - [0, 0, 2.0]
    for order in [(near, far), (far, near)]:
        img, depth = np.ones((16, 16, 3), np.float32), np.full((16, 16), -np.inf)
        for P, c in zip(order, [0.0, 0.5] if order[0] is near else [0.5, 0.0], strict=True):
            _raster.draw(P, quad, np.full((4, 3), c), img, depth)
        assert np.all(img == 0.0)  # the near quad is black


def test_matplotlib_on_purpose_is_quiet(monkeypatch, recwarn):
    V, F = torus(1.0, 0.4, 24, 12)
    monkeypatch.setenv("O3DHEAT_RENDERER", "matplotlib")
    fig = plot.fields((V, F), np.c_[V[:, 0], V[:, 1]], critical_points=False)
    assert fig.axes[0].name == "3d" and not [w for w in recwarn if issubclass(w.category, RuntimeWarning)]
    monkeypatch.setenv("O3DHEAT_RENDERER", "vtk")
    with pytest.raises(o3dheat.MeshError, match="O3DHEAT_RENDERER"):
        plot.field((V, F), V[:, 0])


def test_the_crop_keeps_the_whole_width_when_rounding_overshoots():
    """The "intermittently blank" figures: the longer side's pixel count came out as size + 1 by
    rounding (1200 * p / p = 1200.0000000000002), the crop as the slice (-1, 1200), one column of
    white margin, and the picture was refused as blank. This frame is Fig. 3's of the three-part
    mesh of the report (torus, sphere at +3, icosphere at -3)."""
    import open3d as o3d

    a = o3d.geometry.TriangleMesh.create_torus()
    b = o3d.geometry.TriangleMesh.create_sphere(0.5, 20).translate((3, 0, 0))
    c = o3d.geometry.TriangleMesh.create_icosahedron(0.7).subdivide_loop(3).translate((-3, 0, 0))
    m = a + b + c
    V = np.asarray(m.vertices)
    frame = _render.View(V, (20, -60))
    frame.u = (-3.640200020722534, 3.5601544210293667)  # the frame of that figure
    frame.half = np.ptp(frame.u) / 2
    assert 1200 * np.ptp(frame.u) / (2 * frame.half) > 1200  # what rounding made of it
    rows, cols = frame.crop(1200)
    assert cols == slice(0, 1200) and 0 <= rows.start < rows.stop <= 1200
    rng = np.random.default_rng(0)
    for _ in range(300):  # extents of every kind: always inside the render, the longer side whole
        frame = _render.View(V * rng.uniform(0.1, 10, 3) + rng.uniform(-5, 5, 3), (rng.uniform(-80, 80), 360 * rng.random()))
        rows, cols = frame.crop(1200)
        assert 0 <= rows.start < rows.stop <= 1200 and 0 <= cols.start < cols.stop <= 1200
        assert 1200 in (rows.stop - rows.start, cols.stop - cols.start)
    img = plot.render(m, V[:, 2] + 0.3 * V[:, 0], up="y")
    assert ink(img).mean() > 0.05


def test_a_blank_render_is_refused(monkeypatch):
    V, F = icosphere(2)
    calls = []

    def white(self, *args):
        calls.append(1)
        return np.full((self.size, self.size, 3), 255, np.uint8)

    monkeypatch.setattr(_render.Raster, "image", white)
    with pytest.raises(o3dheat.SolverError, match="drew nothing"):
        plot.field((V, F), V[:, 2])
    assert len(calls) == 1  # no retry: the rasterizer has no frames to skip
