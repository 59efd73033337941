"""The offscreen renderer: what is behind the surface is hidden, every part in frame, far from the
origin the same picture, the fallback to matplotlib and its warning, a blank render refused
(PAPER.md row P16)."""

import numpy as np
import pytest
from conftest import icosphere, torus
from pictures import needs_renderer, not_blank, pixels

import o3dheat
import o3dheat.visualization._render as _render
import o3dheat.visualization.plot as plot


def ink(img):
    return np.any(img < 250, axis=2)


@needs_renderer
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


@needs_renderer
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


@needs_renderer
def test_a_scan_far_from_the_origin_renders_the_same():
    V, F = icosphere(3)
    near = plot.render((V, F), V[:, 0])
    far = plot.render((V + [3e6, -2e6, 1e6], F), V[:, 0])  # float32 has ~0.25 units of resolution there
    assert near.shape == far.shape and np.abs(near.astype(int) - far).mean() < 1.0


def test_fallback_to_matplotlib_warns_and_still_draws(monkeypatch, tmp_path):
    V, F = torus(1.0, 0.4, 24, 12)
    monkeypatch.setitem(_render.state, "probe", (False, _render.MISSING + " (test)"))
    monkeypatch.setitem(_render.state, "renderer", None)
    monkeypatch.setitem(_render.state, "warned", False)
    monkeypatch.delenv("O3DHEAT_RENDERER", raising=False)
    with pytest.warns(RuntimeWarning, match="libvulkan1 and mesa-vulkan-drivers"):
        fig = plot.field((V, F), V[:, 0], label="x")
    assert fig.axes[0].name == "3d" and fig.axes[1].get_ylabel() == "x"
    fig.savefig(tmp_path / "m.png")
    assert not_blank(tmp_path / "m.png")
    with pytest.raises(o3dheat.MeshError, match="renderer='matplotlib'"):
        plot.field((V, F), V[:, 0], renderer="open3d")
    with pytest.raises(o3dheat.MeshError, match="mesa-vulkan-drivers"):
        plot.render((V, F), V[:, 0])


def test_matplotlib_on_purpose_is_quiet(monkeypatch, recwarn):
    V, F = torus(1.0, 0.4, 24, 12)
    monkeypatch.setenv("O3DHEAT_RENDERER", "matplotlib")
    fig = plot.fields((V, F), np.c_[V[:, 0], V[:, 1]], critical_points=False)
    assert fig.axes[0].name == "3d" and not [w for w in recwarn if issubclass(w.category, RuntimeWarning)]
    monkeypatch.setenv("O3DHEAT_RENDERER", "vtk")
    with pytest.raises(o3dheat.MeshError, match="O3DHEAT_RENDERER"):
        plot.field((V, F), V[:, 0])


@needs_renderer
def test_a_blank_render_is_refused(monkeypatch):
    V, F = icosphere(2)
    r = _render.renderer("open3d")
    calls = []

    def white(*args):
        calls.append(1)
        return np.full((r.size, r.size, 3), 255, np.uint8)

    monkeypatch.setattr(r, "image", white)
    with pytest.raises(o3dheat.SolverError, match="drew nothing"):
        plot.field((V, F), V[:, 2])
    assert len(calls) == 2  # drawn again once, then refused
