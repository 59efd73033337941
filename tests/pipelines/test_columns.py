"""Columns and outputs: what a filter may write (o3dheat.pipelines.columns)."""

import open3d as o3d
import pytest

import o3dheat
import o3dheat.pipelines.filters as flt
from o3dheat.errors import MeshError


@pytest.mark.parametrize("step, match", [
    (("scalar", {"kind": "height", "output": "colors"}),
     r"output 'colors' must have shape \(n, 3\) \(Open3D's colors\), got 1 column"),
    (("hks", {"k": 8, "output": "normals"}), r"output 'normals' must have shape \(n, 3\) \(Open3D's normals\), got 10 columns"),
    (("heat_smooth", {"attribute": "height", "k": 8, "times": [0.1], "output": "x"}),
     r"output 'x' is a reserved PLY property \(x y z nx ny nz red green blue"),
    (("colorize", {"attribute": "height", "output": "red"}), r"output 'red' is a reserved PLY property"),
    (("critical_points", {"attribute": "height", "output": "o3dheat_colors_1"}), r"output 'o3dheat_colors_1' is a reserved"),
    (("hks", {"k": 8, "output": "alpha"}), r"output 'alpha' has 10 columns"),
    (("scalar", {"kind": "height", "output": "my field"}), r"output 'my field' is not a name a PLY property can hold"),
    (("heat_smooth", {"attribute": "height", "k": 8, "output": "hauteur_lissée"}), r"output 'hauteur_lissée' is not a name"),
])
def test_outputs_that_cannot_be_written_are_refused_before_any_work(step, match, monkeypatch):
    """Chain.check took a scalar named colors, a field named x or "my field": the run (or the PLY
    writer, after every file's eigensolve) failed."""
    from o3dheat.spectral import spectrum

    monkeypatch.setattr(spectrum, "eigensolve", lambda *a, **k: pytest.fail("an eigensolve ran"))
    mesh = flt.apply(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 6), "scalar", kind="height")
    with pytest.raises(MeshError, match=r"step 2 \(" + step[0] + r"\): " + match):
        flt.Chain([("scalar", {"kind": "height", "axis": 0, "output": "h0"}), step]).check(mesh)
    with pytest.raises(MeshError, match=match):  # apply, a filter called directly: the same check
        flt.apply(mesh, step[0], **step[1])
    with pytest.raises(MeshError, match=match):
        flt.get(step[0], **step[1])(mesh)


def test_writable_outputs_still_written(tmp_path):
    mesh = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 6)
    chain = flt.Chain([("scalar", {"kind": "noise", "attribute": "positions", "output": "colors", "sigma": 0.0}),
                       ("scalar", {"kind": "height", "output": "alpha"}),
                       ("scalar", {"kind": "height", "output": "h-2.v1"})])
    assert chain.check(mesh) == {"positions": 3, "colors": 3, "alpha": 1, "h-2.v1": 1}
    o3dheat.io.write_mesh(tmp_path / "out.ply", chain(mesh))
    back = o3dheat.io.read_mesh(tmp_path / "out.ply")
    assert {"colors", "alpha", "h-2.v1"} <= set(back.vertex)


def test_outputs_whose_ply_properties_collide_are_refused(monkeypatch):
    """PLY stores a 3-column attribute a as a_0 a_1 a_2: an attribute a_1 beside it cannot be written."""
    from o3dheat.spectral import spectrum

    monkeypatch.setattr(spectrum, "eigensolve", lambda *a, **k: pytest.fail("an eigensolve ran"))
    mesh = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 6)
    grown = flt.apply(mesh, "scalar", kind="noise", attribute="positions", output="p")  # (n, 3): p_0 p_1 p_2
    with pytest.raises(MeshError, match=r"step 2 \(scalar\): output 'p_1' \(1 column\) would be stored as PLY "
                                        r"property 'p_1', which attribute 'p' has: rename it"):
        flt.Chain([("scalar", {"kind": "noise", "attribute": "positions", "output": "p"}),
                   ("scalar", {"kind": "height", "output": "p_1"})]).check(mesh)
    with pytest.raises(MeshError, match=r"output 'p_1' \(1 column\) would be stored as PLY property 'p_1'"):
        flt.apply(grown, "scalar", kind="height", output="p_1")
    with pytest.raises(MeshError, match=r"output 'h' \(2 columns\) would be stored as PLY property 'h_1', "
                                        r"which attribute 'h_1' has"):
        flt.apply(flt.apply(mesh, "scalar", output="h_1"), "hks", k=8, scales=2, output="h")
    again = flt.apply(grown, "scalar", kind="height", output="p")  # the same name: replaced, not a collision
    assert again.vertex["p"].shape == (len(mesh.vertex.positions),)
