"""What a panel shows: no critical points beyond the limit, none of rounding errors on a part
constant to them, markers sized per part, the colour range of the part holding the variation
(PAPER.md row P16)."""

import numpy as np
from conftest import icosphere
from pictures import pixels

import o3dheat
import o3dheat.visualization._panels as _panels
import o3dheat.visualization.plot as plot


def ink(img):
    return np.any(img < 250, axis=2)


def legend_texts(fig):
    return [t.get_text() for lg in fig.legends for t in lg.get_texts()]


def test_too_many_critical_points_are_not_drawn(monkeypatch):
    V, F = icosphere(3)
    f = V[:, 2] + 0.3 * np.random.default_rng(1).standard_normal(len(V))
    n = sum(o3dheat.critical_points((V, F), f).counts)
    monkeypatch.setattr(_panels, "MAX_CRITICAL_POINTS", n - 1)
    fig = plot.field((V, F), f, level_sets=None, cmap="gray")
    img = fig.axes[0].get_images()[0].get_array()
    assert pixels(img, "red") == 0 and pixels(img, "blue") == 0
    assert f"{n:,} critical points: too many to draw" in [t.get_text() for t in fig.axes[0].texts]


def two_spheres(tiny=1.0):
    V, F = icosphere(3)
    return np.r_[V, tiny * V + [3.0, 0.0, 0.0]], np.r_[F, F + len(V)], len(V)


def test_a_part_constant_to_rounding_gets_no_critical_points():
    """Φ_t(e_i) is exactly 0 on a part without vertex i; computed, it is rounding errors there,
    with hundreds of "critical points" that buried the part under markers. Such a part is drawn
    constant: no markers on it, the legend does not count them, the panel says so."""
    V, F, n = two_spheres()
    f = np.r_[V[:n, 2], 1e-17 * np.random.default_rng(0).standard_normal(n)]
    assert sum(o3dheat.critical_points((V, F), f).counts) > 100
    assert plot.drawn_critical_points((V, F), f).counts == (1, 0, 1)
    fig = plot.field((V, F), f, level_sets=None, view=(0, -90))
    assert legend_texts(fig) == ["maxima (1)", "minima (1)", "saddles (0)"]
    img = fig.axes[0].get_images()[0].get_array()
    right = img[:, img.shape[1] // 2:]  # the flat sphere, at x = 3
    assert sum(pixels(right, c) for c in ("red", "blue", "green")) == 0
    assert any("constant on 1 part (to numerical error)" in t.get_text() for t in fig.axes[0].texts)
    g = np.r_[V[:n, 2], V[n:, 2]]  # a field that varies on both: nothing left out
    assert plot.drawn_critical_points((V, F), g).counts == o3dheat.critical_points((V, F), g).counts


def test_markers_on_a_small_part_are_sized_for_it():
    """A part a tenth the size of the other, with a noisy field: its markers cover a bounded
    share of its pixels (they were sized for the whole mesh and hid it)."""
    V, F, n = two_spheres(tiny=0.1)
    f = V[:, 2] + np.r_[np.zeros(n), 0.01 * np.random.default_rng(1).standard_normal(n)]
    cp = o3dheat.critical_points((V, F), f)
    assert 20 < sum(cp.counts) <= _panels.MAX_CRITICAL_POINTS
    img = plot.render((V, F), f, level_sets=None, view=(0, -90))
    small = img[:, int(img.shape[1] * 0.85):]
    surface = ink(small).sum()
    marked = sum(pixels(small, c) for c in ("red", "blue", "green"))
    assert surface > 0 and marked < 0.15 * surface, (marked, surface)


def test_a_small_part_holding_the_variation_gets_the_colours():
    """Φ_t(e_i) of a vertex of a part with 3% of the vertices: the others are constant (0, to the
    eigensolver's mixing of equal eigenvalues, 1e-9 of the field), and the colour range is the
    small part's, not the 2-98th percentile of the zeros (all one colour)."""
    V, F, n = two_spheres(tiny=0.5)
    V1, F1 = icosphere(1, 0.3)
    V = np.r_[V, V1 + [0.0, 0.0, 2.5]]
    F = np.r_[F, F1 + 2 * n]
    f = np.r_[1e-12 * np.random.default_rng(0).standard_normal(2 * n), V1[:, 2] + 1.0]
    fig = plot.field((V, F), f, level_sets=None, critical_points=False)
    lo, hi = fig.axes[1].get_ylim()
    assert lo < 0.75 and hi > 1.25  # the small part's values 0.7 .. 1.3 are in the range


def test_an_offset_field_is_not_taken_for_flat():
    """Found in review: a field with a large offset (a georeferenced height, 5e6 + z) was drawn
    flat, with no critical points: flatness is now relative to the field's variation."""
    import open3d as o3d

    from o3dheat.visualization.plot import drawn_critical_points

    m = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 20)
    z = m.vertex.positions.numpy()[:, 2].astype(float)
    assert drawn_critical_points(m, 5e6 + z).counts == o3dheat.critical_points(m, z).counts == (1, 0, 1)
