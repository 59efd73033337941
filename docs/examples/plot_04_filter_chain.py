"""
A filter chain
==============

Filters compute something on a mesh and return a new mesh with the result as vertex attributes;
a :class:`~o3dheat.pipelines.filters.Chain` runs several of them with one eigensolve, can be saved as TOML
and replayed, from Python or with ``o3dheat apply --chain``.
"""

# %%
import os
import tempfile

import o3dheat
from o3dheat.geometry.sampling import decimate
from o3dheat.io import default_mesh

bunny, _ = default_mesh()
mesh = decimate(bunny, reduction=0.8).mesh
print(o3dheat.filters.names())
print(o3dheat.filters.describe("heat_smooth")["parameters"][0])

# %%
chain = o3dheat.filters.Chain([
    ("scalar", {"kind": "mean_curvature"}),
    ("heat_smooth", {"attribute": "mean_curvature", "k": 80, "scales": 6, "grid": "log"}),
    ("critical_points", {"attribute": "mean_curvature_smooth", "column": 2, "delta": 0.05}),
    ("colorize", {"attribute": "mean_curvature_smooth", "column": 2, "colormap": "viridis"}),
])
out = chain(mesh)
print("attributes:", sorted(out.vertex))
print("smoothed curvature:", tuple(out.vertex["mean_curvature_smooth"].shape))

# %%
# The input is unchanged; the output keeps everything and adds the results. The smoothed mean
# curvature at three of the six scales:
F = out.vertex["mean_curvature_smooth"].numpy()
fig = o3dheat.plot.fields(out, F[:, [0, 2, 4]], titles=["scale 0", "scale 2", "scale 4"],
                          shared_range=False, critical_points=False, up="y", label="mean curvature, smoothed")

# %%
# Saved, a chain is a small TOML file that the command replays on other meshes:
path = os.path.join(tempfile.mkdtemp(), "chain.toml")
chain.save(path)
print(open(path).read())
same = o3dheat.filters.Chain.load(path)(mesh)
print("replayed identically:", (same.vertex["mean_curvature_smooth"].numpy() == F).all())
