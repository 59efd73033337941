"""The critical_points filter's parameters, checked before any work."""

import open3d as o3d
import pytest

import o3dheat.pipelines.filters as flt
from o3dheat.errors import MeshError


def test_parameters_are_checked_before_any_work(monkeypatch):
    """critical_points' delta/keep_fraction were checked by the persistence code, after the
    eigensolve of the steps before it: a batch computed every file, then failed each."""
    import dataclasses

    from o3dheat.spectral import spectrum
    from o3dheat_filters.critical_points import CriticalPointsFilter

    calls = []
    monkeypatch.setattr(spectrum, "eigensolve", lambda *a, **k: calls.append(1) or pytest.fail("eigensolve ran"))
    smooth = [("scalar", {"kind": "height"}), ("heat_smooth", {"attribute": "height", "k": 10, "scales": 2})]
    for bad, match in (({"delta": -1}, r"critical_points.delta must be >= 0, got -1.0"),
                       ({"delta": float("inf")}, r"critical_points.delta must be a finite number"),
                       ({"keep_fraction": 1.5}, r"critical_points.keep_fraction must be in \[0, 1\], got 1.5"),
                       ({"keep_fraction": "half"}, r"critical_points.keep_fraction must be a number")):
        with pytest.raises(MeshError, match=match):  # by name: at construction
            flt.Chain([*smooth, ("critical_points", {"attribute": "height_smooth", "column": 0, **bad})])
        with pytest.raises(MeshError, match=match):  # made directly: at construction too
            CriticalPointsFilter(attribute="height_smooth", column=0, **bad)

    @dataclasses.dataclass(frozen=True)
    class Blur:  # a plugin declaring its bounds with flt.param, made directly
        sigma: float = flt.param(1.0, gt=0)

        def __call__(self, geometry):
            return geometry

    mesh = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 6)
    with pytest.raises(MeshError, match=r"Blur.sigma must be > 0, got -1.0"):
        flt.Chain([*smooth, Blur(sigma=-1.0)])
    chain = flt.Chain(smooth)
    chain.steps.append(Blur(sigma=0.0))  # past append: Chain.check (run first by every chain) refuses it
    with pytest.raises(MeshError, match=r"step 3 \(Blur\): Blur.sigma must be > 0, got 0.0"):
        chain(mesh)
    assert calls == []
    assert "in [0, 1]" in str(next(p for p in flt.describe("critical_points")["parameters"]
                                    if p.name == "keep_fraction"))
