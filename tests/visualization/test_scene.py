"""The scene of a scale space (o3dheat.visualization.scene.build) and the View around it: default
fields and grids, counts that are critical_points' own, given (n, T) attributes, decimation with the
fields transferred, the up rule, repairs said, bad input refused in one line before any work."""

import numpy as np
import open3d as o3d
import pytest
from conftest import glued_spheres, icosphere, torus

import o3dheat
from o3dheat.geometry import transfer
from o3dheat.visualization.scene import Recipe, build


def tmesh(V, F, **attributes):
    m = o3d.t.geometry.TriangleMesh()
    m.vertex.positions = o3d.core.Tensor(np.asarray(V, dtype=np.float64))
    m.triangle.indices = o3d.core.Tensor(np.asarray(F, dtype=np.int64))
    for k, v in attributes.items():
        m.vertex[k] = o3d.core.Tensor(np.asarray(v))
    return m


def test_default_scene_is_the_noisy_height_on_both_grids_with_counts_of_critical_points():
    V, F = torus(1.0, 0.4, 40, 20)
    s = build((V, F), recipe=Recipe(k=30))
    assert [f.name for f in s.fields] == ["f", "f_paper"]
    log, paper = s.fields
    assert log.values.shape == (len(V), 20) and paper.values.shape == (len(V), 10)
    K = o3dheat.HeatKernel(o3dheat.eigensolve((V, F), k=30))
    assert np.allclose(log.times, K.scales(20, grid="log")) and np.allclose(paper.times, K.scales(10))
    rng = np.random.default_rng(0)
    f = V[:, 2] + 0.1 * np.ptp(V[:, 2]) * rng.standard_normal(len(V))
    assert np.allclose(log.values, o3dheat.heat_flow((V, F), f, log.times), atol=1e-6 * np.abs(f).max())
    for field in s.fields:
        for j in (0, field.values.shape[1] - 1):
            assert field.critical[j].counts == o3dheat.critical_points((V, F), field.values[:, j]).counts
        assert field.critical[-1].euler_characteristic == 0  # a torus
        assert np.allclose(field.eps_inf, np.abs(field.values - f[:, None]).max(0) / np.abs(f).max())
    assert set(s.tracks) == {"f", "f_paper"} and s.up == "z" and "z up" in s.notes[0]


def test_spectral_method_and_given_times():
    V, F = icosphere(3)
    t = [0.0, 0.05, 0.5]
    s = build((V, F), V[:, 0] + V[:, 1] ** 2, t, Recipe(method="spectral", k=40, tracks=False))
    K = o3dheat.HeatKernel(o3dheat.eigensolve((V, F), k=40))
    assert np.allclose(s.fields[0].values, K.smooth(V[:, 0] + V[:, 1] ** 2, t))
    assert "40 eigenpairs" in s.fields[0].label and s.tracks == {}


def test_attributes_of_several_scales_are_shown_as_they_are_each_a_field():
    V, F = icosphere(2)
    A, B = np.c_[V[:, 0], 2 * V[:, 0]], np.c_[V[:, 1], V[:, 2], V[:, 0]]
    s = build(tmesh(V, F, f_smooth=A, hks=B, crit=np.zeros(len(V), np.int32)))
    assert [f.name for f in s.fields] == ["f_smooth", "hks"]
    assert np.array_equal(s.fields[1].values, B) and np.isnan(s.fields[1].times).all()
    one = build(tmesh(V, F, f_smooth=A), "f_smooth", recipe=Recipe(column=1, tracks=False), t=[0.0, 0.1])
    assert one.fields[0].name == "f_smooth[1]" and np.allclose(one.fields[0].values[:, 0], A[:, 1])
    last = build(tmesh(V, F, f_smooth=A), "f_smooth", recipe=Recipe(column=-1, tracks=False), t=[0.0, 0.1])
    assert last.fields[0].name == "f_smooth[1]"
    with pytest.raises(o3dheat.MeshError, match="column=1 picks a column of a field"):
        build(tmesh(V, F, f_smooth=A), recipe=Recipe(column=1))


@pytest.mark.parametrize("field, recipe, match", [
    ("nope", Recipe(), "no vertex attribute 'nope'"),
    ("bad", Recipe(), "NaN or infinite values \\(first at vertex 3\\)"),
    ("f", Recipe(column=5), "column 5 asked of 'f'"),
])
def test_bad_fields_are_refused_in_one_line(field, recipe, match):
    V, F = icosphere(1)
    bad = V[:, 0].copy()
    bad[3] = np.nan
    with pytest.raises(o3dheat.MeshError, match=match):
        build(tmesh(V, F, bad=bad, f=np.c_[V[:, 0], V[:, 1]]), field, recipe=recipe)


@pytest.mark.parametrize("kw, match", [({"method": "fast"}, "method must be"), ({"up": "w"}, "up must be"),
                                       ({"max_faces": 5}, "max_faces"), ({"cmap": "nope"}, "cmap"),
                                       ({"tracks": "yes"}, "tracks must be True or False"),
                                       ({"column": "1"}, "column must be an integer"),
                                       ({"noise": -1}, "noise")])
def test_bad_recipes_are_refused(kw, match):
    with pytest.raises(o3dheat.MeshError, match=match):
        Recipe(**kw)


def test_a_large_mesh_is_shown_decimated_with_the_fields_of_the_full_mesh_transferred():
    V, F = icosphere(4)  # 5120 faces
    t = [0.01, 0.1]
    s = build((V, F), V[:, 2], t, Recipe(max_faces=1000, tracks=False))
    assert len(s.F) <= 1000 and any("decimated copy: 5,120 → " in n for n in s.notes)
    full = o3dheat.heat_flow((V, F), V[:, 2], t)
    assert np.allclose(s.fields[0].values, transfer(full, (V, F), s.V), atol=1e-6)
    assert s.fields[0].critical[0].counts == o3dheat.critical_points((s.V, s.F), s.fields[0].values[:, 0]).counts


def test_the_decimated_copy_is_made_beside_the_flow_and_its_errors_reach_the_caller(monkeypatch):
    """The copy needs the geometry only: it is made in a background thread while the fields are
    computed, and a failure there is raised by build, not lost."""
    import threading

    from o3dheat.errors import MeshError
    from o3dheat.visualization import scene as scene_module

    V, F = icosphere(4)
    seen = []
    decimate, apply = scene_module.decimate, scene_module.HeatFlow.apply

    def recorded_decimate(*args, **kwargs):
        seen.append(("decimate", threading.current_thread().name))
        return decimate(*args, **kwargs)

    def recorded_apply(self, *args, **kwargs):
        seen.append(("flow", threading.current_thread().name))
        return apply(self, *args, **kwargs)

    monkeypatch.setattr(scene_module, "decimate", recorded_decimate)
    monkeypatch.setattr(scene_module.HeatFlow, "apply", recorded_apply)
    s = build((V, F), V[:, 2], [0.01, 0.1], Recipe(max_faces=1000, tracks=False))
    assert len(s.F) <= 1000
    assert {kind for kind, _ in seen} == {"decimate", "flow"}
    where = dict(seen)
    assert where["decimate"].startswith("o3dheat-surface") and where["flow"] == threading.current_thread().name
    seen.clear()
    with o3dheat.parallel.threads(1):  # one thread asked for: everything in the calling thread
        build((V, F), V[:, 2], [0.01, 0.1], Recipe(max_faces=1000, tracks=False))
    assert dict(seen)["decimate"] == threading.current_thread().name

    def failing(*args, **kwargs):
        raise MeshError("decimate: no luck")

    monkeypatch.setattr(scene_module, "decimate", failing)
    with pytest.raises(MeshError, match="no luck"):
        build((V, F), V[:, 2], [0.01, 0.1], Recipe(max_faces=1000, tracks=False))


def test_up_follows_the_source_file_and_height_is_along_it():
    V, F = icosphere(2)
    s = build((V, F), recipe=Recipe(source="scan.obj", noise=0.0, tracks=False), t=[0.0])
    assert s.up == "y" and "convention of .obj files" in s.notes[0] and s.name == "scan.obj"
    assert np.allclose(s.fields[0].values[:, 0], V[:, 1])
    assert build((V, F), recipe=Recipe(source="part.stl", up="x", noise=0.0, tracks=False), t=[0.0]).up == "x"


def test_a_non_manifold_mesh_is_split_and_said():
    V, F = glued_spheres(2)
    s = build((V, F), V[:, 2], [0.0, 0.1], Recipe(tracks=False))
    assert len(s.V) == len(V) + 1 and any("non-manifold" in n for n in s.notes)


def test_view_saves_refuses_and_shows_inline(tmp_path):
    import html

    V, F = icosphere(2)
    v = o3dheat.view((V, F), V[:, 2], [0.0, 0.1], tracks=False)
    path = v.save(tmp_path / "v.html")
    text = path.read_text()
    assert text == v.html() and text.startswith("<!DOCTYPE html>")
    with pytest.raises(o3dheat.MeshError, match="exists: pass overwrite=True"):
        v.save(path)
    with pytest.raises(o3dheat.MeshError, match="overwrite must be True or False"):
        v.save(path, overwrite="no")
    with pytest.raises(o3dheat.MeshError, match="is a folder"):
        v.save(tmp_path)
    assert path.read_text() == text  # nothing half-written
    inline = v._repr_html_()
    assert inline.startswith("<iframe srcdoc=") and html.unescape(inline.split('srcdoc="')[1].split('" style=')[0]) == text
    assert v.times.tolist() == [0.0, 0.1] and "View(mesh: " in repr(v)
    with pytest.raises(o3dheat.MeshError, match="unknown option"):
        o3dheat.view((V, F), colour="red")


def test_a_large_mesh_gets_its_grids_from_a_decimated_copy_and_says_so(monkeypatch):
    """Issue 35: above 2 x GRID_FACES faces the exact flow's default grids take λ_2 and λ_k from a
    copy decimated to GRID_FACES faces (the mesh's own k-eigenpair solve cost far more than the
    flow at 200k vertices and does not fit at 10M); the labels and the progress say so."""
    import o3dheat.visualization.scene as scene
    from o3dheat.geometry.sampling import decimate

    monkeypatch.setattr(scene, "GRID_FACES", 600)
    V, F = torus(1.0, 0.4, 40, 20)  # 1600 faces
    said = []
    s = build((V, F), recipe=Recipe(k=30, tracks=False), echo=said.append)
    copy = decimate((V, F), target_faces=600, vertex_map=False).arrays
    K = o3dheat.HeatKernel(o3dheat.eigensolve(copy, k=30))
    log, paper = s.fields
    assert np.allclose(log.times, K.scales(20, grid="log")) and np.allclose(paper.times, K.scales(10))
    assert f"of a copy decimated to {len(copy[1]):,} faces" in log.label and "λ_30" in paper.label
    assert any("copy decimated" in line for line in said)
    own = o3dheat.HeatKernel(o3dheat.eigensolve((V, F), k=30))
    assert np.allclose(paper.times, own.scales(10), rtol=0.3)  # nearly the same scales, even on 300 vertices
    small = build((V, F), recipe=Recipe(k=30, tracks=False, method="spectral"))  # the spectral method: its own
    assert np.allclose(small.fields[1].times, own.scales(10))


def test_a_mesh_too_large_for_both_is_decimated_before_the_flow_not_beside_it(monkeypatch):
    """Issue 35: the picture's decimation runs beside the fields' computation only when both fit
    twice over (at 10M vertices each takes 8-10 GB); else first, said."""
    import o3dheat.visualization.scene as scene

    V, F = torus(1.0, 0.4, 40, 20)  # 1600 faces, decimated to 800
    said, threads = [], []
    made = scene._Shown._made
    monkeypatch.setattr(scene._Shown, "_made", staticmethod(lambda *a: threads.append(1) or made(*a)))
    monkeypatch.setattr(scene, "available_memory", lambda: 1000)  # bytes: nothing fits twice
    s = build((V, F), recipe=Recipe(k=20, tracks=False, max_faces=800), echo=said.append)
    assert any("before the fields are computed (memory" in line for line in said)
    assert len(s.F) <= 800 and threads == [1]
    monkeypatch.setattr(scene, "available_memory", lambda: None)
    said.clear()
    build((V, F), recipe=Recipe(k=20, tracks=False, max_faces=800), echo=said.append)
    assert any("while the fields are computed" in line for line in said)
