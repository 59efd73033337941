"""
A scale space to look at: the interactive page and its static panels
====================================================================

:func:`o3dheat.view <o3dheat.visualization.interactive.view>` builds one
:class:`~o3dheat.visualization.scene.Scene` of a field's scale space (the surface, the field at
every scale, its critical points and their tracks) and writes it as one offline HTML page with a
slider over ``t`` (:doc:`/guide/viewing`). :func:`o3dheat.visualization.plot.draw` draws the same
scene as static panels, for a paper or a report.
"""

# %%
# A decimated bunny and its page
# ------------------------------
# Without a field, the page shows the noisy height along ``up``, smoothed by the exact heat
# flow at 20 log-spaced scales (the field ``f``) and at the paper's 10 (the field ``f_paper``).
# The embedded bunny is a mesh made in Python, so the up rule would say z: it stands along y,
# hence ``up="y"``. ``k`` is the number of eigenpairs that define the two scale grids (the
# exact heat flow needs none).
import tempfile
from pathlib import Path

import numpy as np

import o3dheat
from o3dheat.geometry.sampling import decimate
from o3dheat.io import default_mesh
from o3dheat.visualization import plot

bunny, _ = default_mesh()
mesh = decimate(bunny, target_faces=5000).mesh
view = o3dheat.view(mesh, up="y", k=50)
print(view)
print("times of f:", np.round(view.times, 5))

with tempfile.TemporaryDirectory() as folder:
    page = view.save(Path(folder) / "bunny.html")     # one self-contained file, no network needed
    print(f"{page.name}: {page.stat().st_size / 1e6:.1f} MB")

# %%
# The critical points at the first and the last scale (minima, saddles, maxima), computed in
# Python on the float64 values; the page's ``o3dheat.counts()`` shows the same numbers.
f = view.scene.fields[0]
print(f"{f.name}: {f.label}")
print("first scale:", f.critical[0].counts, " last scale:", f.critical[-1].counts)
print("notes:", view.scene.notes)

# %%
# The same scene as static panels
# -------------------------------
# :func:`plot.draw <o3dheat.visualization.plot.draw>` draws columns of one of the scene's
# fields with its level sets and critical points (red maxima, blue minima, green saddles), in
# the scene's view, with ``up`` vertical.
columns = [0, 9, 19]
fig = plot.draw(view.scene, columns=columns,
                style=plot.Style(titles=[f"t = {view.times[j]:.2g}" for j in columns], label="Φ_t f"))
