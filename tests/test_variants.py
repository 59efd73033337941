"""Kernel variants, mass kinds and the other lists are defined once (issue 15): every consumer
(filters, command, study) reads them from their module, so a new variant is one edit."""

import json
import re
from pathlib import Path

import numpy as np
import open3d as o3d
import pytest

import o3dheat
import o3dheat.pipelines.filters as flt
from o3dheat.cli import main
from o3dheat.spectral import fem, variants

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def sphere():
    return o3d.t.geometry.TriangleMesh.create_sphere(1.0, 10)  # 182 vertices


@pytest.fixture
def twin(monkeypatch):
    """A variant registered in o3dheat.spectral.variants.VARIANTS only: a copy of "weighted" under a new name."""
    monkeypatch.setitem(variants.VARIANTS, "twin", ("consistent", "the weighted kernel again, for a test"))
    return "twin"


@pytest.mark.parametrize("variant", list(variants.VARIANTS))
def test_hks_filter_reaches_every_variant(sphere, variant):
    out = flt.apply(sphere, "hks", variant=variant, k=20, scales=3)
    K = o3dheat.heat_kernel(sphere, k=20, variant=variant)
    assert K.spectrum.mass_kind == variants.VARIANTS[variant][0]
    np.testing.assert_allclose(out.vertex["hks"].numpy(), K.hks(K.scales(3)), rtol=1e-10, atol=1e-14)


def test_every_variant_names_a_mass_kind():
    assert {mass for mass, _ in variants.VARIANTS.values()} <= set(fem.MASS_KINDS)
    for variant in variants.VARIANTS:
        assert variants.variant_of_mass(variants.mass_of(variant)) == variant  # the first of its mass


def test_a_new_variant_reaches_the_kernel_and_the_filters(sphere, twin):
    K = o3dheat.heat_kernel(sphere, k=20, variant=twin)
    W = o3dheat.heat_kernel(sphere, k=20, variant="weighted")
    assert K.variant == twin and K.spectrum.mass_kind == "consistent"
    assert o3dheat.HeatKernel(W.spectrum, variant=twin).variant == twin  # a spectrum of its mass
    # the filters take it (checked when configured) and compute with it
    h = flt.apply(sphere, "hks", variant=twin, k=20, scales=3).vertex["hks"].numpy()
    np.testing.assert_allclose(h, W.hks(W.scales(3)), rtol=1e-10)
    m = flt.apply(sphere, "scalar", kind="height")
    g = flt.apply(m, "heat_smooth", attribute="height", variant=twin, k=20, scales=2)
    np.testing.assert_allclose(g.vertex["height_smooth"].numpy(),
                               W.smooth(m.vertex["height"].numpy(), W.scales(2)), rtol=1e-10, atol=1e-12)
    assert flt.get("feature_approx", variant=twin).variant == twin
    for name in ("hks", "heat_smooth", "feature_approx"):
        (p,) = [p for p in flt.describe(name)["parameters"] if p.name == "variant"]
        assert "'twin'" in p.type
        with pytest.raises(o3dheat.MeshError, match="twin"):  # the refusal lists it too
            flt.get(name, variant="triplet")


def test_a_new_variant_reaches_the_study(twin):
    from conftest import icosphere

    small = dict(descriptors=["smooth_height"], scheduler="sequential", progress=False, k=8, scales=2)
    t = o3dheat.robustness_study({"s": icosphere(1)}, ["jitter"], **small)  # default: every variant
    assert set(t["kernel"]) == set(variants.VARIANTS) and (t["error"] == "").all()
    rows = t.set_index(["kernel", "scale"])["rel_l2"]
    np.testing.assert_allclose(rows["twin"], rows["weighted"], rtol=1e-12)
    with pytest.raises(o3dheat.MeshError, match="twin"):
        o3dheat.robustness_study({"s": icosphere(1)}, ["jitter"], kernels=["triplet"], **small)


def test_a_new_variant_reaches_the_command(tmp_path, capsys, twin):
    from conftest import icosphere

    V, F = icosphere(1)
    o3dheat.io.write_mesh(tmp_path / "s.ply", o3d.t.geometry.TriangleMesh(o3d.core.Tensor(V), o3d.core.Tensor(F)))
    # a filter parameter on the command line
    out = tmp_path / "out.ply"
    assert main(["apply", str(tmp_path / "s.ply"), str(out), "-f", f"hks:variant={twin},k=8,scales=2"]) == 0
    assert o3dheat.io.read_mesh(out).vertex["hks"].shape == (len(V), 2)
    assert main(["filters", "hks"]) == 0 and "'twin'" in capsys.readouterr().out
    # a study's kernel
    cfg = tmp_path / "study.toml"
    cfg.write_text(f'k = 8\nscales = 2\nkernels = ["{twin}"]\ndescriptors = ["smooth_height"]\n'
                   '[meshes]\ns = "s.ply"\n[[resampling]]\nkind = "jitter"\n')
    assert main(["study", str(cfg), "--out", str(tmp_path / "study"), "--scheduler", "sequential"]) == 0
    assert "twin" in capsys.readouterr().out
    # the help lists it
    with pytest.raises(SystemExit):
        main(["study", "--help"])
    assert json.dumps(list(variants.VARIANTS)) in capsys.readouterr().out


def test_mass_kinds_are_fems(sphere, capsys):
    V, F = o3dheat.as_arrays(sphere)
    for mass in fem.MASS_KINDS:
        B = fem.mass_matrix((V, F), mass)
        assert abs(B - fem.operators(V, F, mass)[1]).max() < 1e-15
        assert o3dheat.eigensolve(sphere, k=3, mass=mass).mass_kind == mass
        assert np.all(np.isfinite(o3dheat.diffuse(sphere, V[:, 2], dt=1e-3, steps=2, scheme="implicit", mass=mass)))
    with pytest.raises(SystemExit):
        main(["spectrum", "--help"])
    help_text = " ".join(capsys.readouterr().out.split())
    assert "{" + ",".join(variants.VARIANTS) + "}" in help_text  # spectrum --mass names the kernel variants
    for mass in ("area", None):
        for call in (lambda: fem.mass_matrix((V, F), mass), lambda: o3dheat.eigensolve(sphere, k=3, mass=mass),  # noqa: B023 - called at once
                     lambda: o3dheat.diffuse(sphere, V[:, 2], dt=1e-3, steps=1, mass=mass)):  # noqa: B023 - called at once
            with pytest.raises(o3dheat.MeshError, match=", ".join(fem.MASS_KINDS)):
                call()


def test_other_lists_have_one_home():
    from o3dheat.pipelines.study import DESCRIPTORS

    assert [d for d in DESCRIPTORS if d.startswith("hks_")] == [f"hks_{f}" for f in variants.HKS_FORMS]
    types = {p.name: p.type for p in flt.describe("hks")["parameters"]}
    assert types["grid"] == f"Literal{list(variants.GRIDS)}"
    assert types["form"] == f"Literal{list(variants.HKS_FORMS)}"
    assert types["normalize"] == f"Literal{list(variants.NORMALIZATIONS)}"
    K = o3dheat.heat_kernel(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 6), k=5)
    for bad, message in ((lambda: K.scales(3, grid="linear"), ", ".join(variants.GRIDS)),
                         (lambda: K.hks(1.0, form="diagonal"), ", ".join(variants.HKS_FORMS)),
                         (lambda: o3dheat.HeatKernel(K.spectrum, normalize="max"), "'lambda2'")):
        with pytest.raises(o3dheat.MeshError, match=message):
            bad()


# the modules that consume the lists must not spell them out again (docs point to the definition)
# every module but the two that define the lists (variants: variants, grids, HKS forms; fem: mass kinds)
CONSUMERS = sorted(str(p.relative_to(ROOT)) for p in [*(ROOT / "o3dheat").rglob("*.py"), *(ROOT / "filters").glob("*.py")]
                   if p.relative_to(ROOT).as_posix() not in ("o3dheat/spectral/variants.py", "o3dheat/spectral/fem.py"))


@pytest.mark.parametrize("path", CONSUMERS)
def test_consumers_do_not_repeat_the_lists(path):
    text = (ROOT / path).read_text()
    for names in (list(variants.VARIANTS), list(fem.MASS_KINDS), list(variants.GRIDS), list(variants.HKS_FORMS)):
        # two or more names of one list, quoted, side by side: a copy of the list
        pairs = [rf'"{a}",\s*"{b}"' for a in names for b in names if a != b]
        found = [m.group(0) for p in pairs for m in re.finditer(p, text)]
        assert not found, f"{path} repeats {names}: {found}"
