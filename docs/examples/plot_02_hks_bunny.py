"""
Heat kernel signatures on the bunny
===================================

The heat kernel signature (HKS, §2.2) of a vertex is how much heat stays there after a time
``t``: at small ``t`` it measures local curvature, at large ``t`` how central or protruding the
vertex is on the whole shape. o3dheat computes two forms (see :doc:`/conventions`): ``"density"``,
the usual one (``Σ e^{-λt/2} x(i)²``, the default) and ``"paper"``, the diagonal of ``K_t``.
"""

# %%
import matplotlib.figure
import numpy as np

import o3dheat
from o3dheat.geometry.sampling import decimate
from o3dheat.io import default_mesh

bunny, _ = default_mesh()
mesh = decimate(bunny, reduction=0.8).mesh
K = o3dheat.heat_kernel(mesh, k=100)
t = K.scales(4, grid="log")
H = K.hks(t)                                      # (n, 4), "density" form
print(H.shape, np.round(t, 4))

# %%
# Each scale has its own range of values (heat leaves every vertex as t grows), so each panel is
# coloured on its own: at small ``t`` the HKS follows the local curvature (ear tips, feet, tail),
# at large ``t`` it is highest at the ends of the ears, the parts farthest from the rest.
fig = o3dheat.plot.fields(mesh, np.log(H), titles=[f"log HKS, t = {s:.2g}" for s in t],
                          shared_range=False, level_sets=None, critical_points=False, ncols=2, up="y", label="log HKS")

# %%
# The signature of a few vertices across scales
# ---------------------------------------------
# The curves fall from the local curvature's value towards ``1/area`` (the constant
# eigenfunction's ``x_1(i)² = 1/area``) as ``t`` grows.
ts = K.scales(40, grid="log")
Hs = K.hks(ts)
V = mesh.vertex.positions.numpy()
picks = {"highest (an ear tip)": int(np.argmax(V[:, 1])), "smallest x": int(np.argmin(V[:, 0])),
         "largest x": int(np.argmax(V[:, 0]))}
chart = matplotlib.figure.Figure(figsize=(6, 3.6), layout="constrained")
ax = chart.subplots()
for label, i in picks.items():
    ax.loglog(ts, Hs[i], label=f"{label} (vertex {i})")
area = o3dheat.check_mesh(mesh).area
ax.axhline(1 / area, color="gray", ls="--", lw=1, label="1 / area")
ax.set(xlabel="t (paper convention)", ylabel="HKS (density form)")
_ = ax.legend()  # assigned: the last expression of a cell would print its repr

# %%
# The two forms
# -------------
# The "paper" form is the density times the vertex's own mass row ``(B x)(i) / x(i)``: it is
# dimensionless, but proportional to the area around each vertex, so on an irregular sampling it
# shows the sampling as much as the shape. Their ratio at each vertex is close to the vertex's
# lumped mass:
Hp = K.hks(t[1], form="paper")
Hd = K.hks(t[1])
lumped = np.asarray(o3dheat.mass_matrix(mesh).sum(axis=1)).ravel()
print("median of (paper / density) / lumped mass:", np.median(Hp / Hd / lumped).round(3))
