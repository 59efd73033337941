"""
Critical points, persistence and feature-driven approximation
=============================================================

A noisy field has thousands of critical points; persistence tells the few that matter from the
rest (§3.1, §3.3). The δ-simplified ones then drive an approximation: ``Φ_t`` of the projection
``pr_A f`` on the set ``A`` is the global component of ``f``, the rest its local component
(Figs. 6 and 7).
"""

# %%
import numpy as np

import o3dheat
from o3dheat.geometry.sampling import decimate
from o3dheat.io import default_mesh

bunny, _ = default_mesh()
mesh = decimate(bunny, reduction=0.8).mesh
V = mesh.vertex.positions.numpy().astype(np.float64)
f = V[:, 1] + 0.03 * np.ptp(V[:, 1]) * np.random.default_rng(1).standard_normal(len(V))

cp = o3dheat.critical_points(mesh, f)
print(cp)                                  # M − s + m = χ = 2 for the (closed, genus 0) bunny

# %%
# The persistence diagram
# -----------------------
# Each point is a homology class of the sublevel sets ``{f <= c}`` as ``c`` grows: a component
# born at a minimum and merged at a saddle (dimension 0), or a loop born at a saddle and filled in
# at a maximum (dimension 1). :func:`o3dheat.persistence <o3dheat.topology.diagrams.persistence>` stores the latter as (maximum, saddle)
# pairs of the superlevel sets, which would lie below the diagonal;
# :func:`o3dheat.visualization.charts.persistence_diagram` draws them as the sublevel sets' (saddle, maximum),
# above it like the others. Noise makes many short-lived pairs near the diagonal, the shape's
# features lie far from it; the classes that never die (the global minimum and maximum of the
# closed bunny) are on the row ∞.
d = o3dheat.persistence(mesh, f)
print(d)
diagram = o3dheat.plot.persistence_diagram(d, f, title="persistence pairs")

# %%
# δ-simplification and the feature-driven approximation
# -----------------------------------------------------
# :func:`o3dheat.simplify_critical_points <o3dheat.topology.diagrams.simplify_critical_points>` keeps the critical points of high persistence, here
# the 42% of them that the paper keeps in its Fig. 6. ``pr_A f`` is ``f`` on ``A`` and 0
# elsewhere, so the global component is ``f`` diffused from the feature points only: its level
# sets follow the global behaviour of ``f``, its values are lower the fewer points ``A`` has (each
# panel has its own colour range).
A_all = np.concatenate([cp.minima, cp.saddles, cp.maxima])
A = o3dheat.simplify_critical_points(mesh, f, keep_fraction=0.42)
print(f"critical points: {len(A_all)}, kept by the simplification: {len(A)}")

K = o3dheat.heat_kernel(mesh, k=100)
t = K.scales(10, grid="log")[3]
glob_all, _ = o3dheat.feature_driven(K, f, A_all, t)
glob, loc = o3dheat.feature_driven(K, f, A, t)
fig = o3dheat.plot.fields(mesh, np.stack([f, glob_all, glob, loc], axis=1),
                          titles=["f", "Φ_t(pr_A f), A = all", "Φ_t(pr_A f), A = simplified",
                                  "local component f − Φ_t(pr_A f)"],
                          shared_range=False, ncols=2, up="y")
for name, g in [("all", glob_all), ("simplified", glob)]:
    print(f"A = {name}: critical points of the global component", o3dheat.critical_points(mesh, g).counts)
