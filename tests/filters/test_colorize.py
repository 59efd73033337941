"""The colorize filter."""

import numpy as np
import pytest

import o3dheat
import o3dheat.pipelines.filters as flt


def test_colorize(sphere):
    out = flt.apply(sphere, "colorize", attribute="height", colormap="viridis", range=[-1.0, 1.0])
    c = out.vertex["colors"].numpy()
    assert c.dtype == np.float32 and c.shape == (len(c), 3) and 0 <= c.min() and c.max() <= 1
    assert np.unique(c, axis=0).shape[0] > 50  # a ramp, not one colour
    with pytest.raises(o3dheat.MeshError, match="colormap"):
        flt.apply(sphere, "colorize", colormap="nope")
    with pytest.raises(o3dheat.MeshError, match="range"):
        flt.get("colorize", range=[1.0, 0.0])
