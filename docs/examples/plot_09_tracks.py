"""
Critical points across scales: tracks
=====================================

As ``t`` grows, the critical points of ``Φ_t f`` disappear in pairs, an extremum with a saddle
(§3). :func:`o3dheat.track_critical_points <o3dheat.topology.tracking.track_critical_points>`
follows each one from scale to scale and records when it ends and why; the
:class:`~o3dheat.topology.tracking.Tracks` it returns say which critical point of ``f`` is which
at every scale, how long each lives and which live to the end: features chosen by their lifetime
(:doc:`/guide/scales`).
"""

# %%
# A noisy height under the exact heat flow
# ----------------------------------------
# Tracking needs many scales, from small times on, where only the full kernel is ``Φ_t f``
# (:doc:`plot_08_exact_heat_flow`). The times are those of the ``tracks`` filter: ``t = 0`` (the
# field itself), then 30 log-spaced from the paper's first scale ``(1/10)/λ_k`` to
# ``2 ln(100)/λ_2``, where the field is nearly constant.
# :meth:`HeatFlow.scales <o3dheat.spectral.heatflow.HeatFlow.scales>` computes the ``k``
# eigenvalues that define them (once; the flow itself needs none).
import collections
import itertools

import numpy as np

import o3dheat
from o3dheat.geometry.sampling import decimate
from o3dheat.io import default_mesh
from o3dheat.visualization import charts

bunny, _ = default_mesh()
mesh = decimate(bunny, target_faces=5000).mesh      # 2,502 vertices
V = mesh.vertex.positions.numpy().astype(np.float64)
rng = np.random.default_rng(0)
f = V[:, 1] + 0.1 * np.ptp(V[:, 1]) * rng.standard_normal(len(V))

flow = o3dheat.HeatFlow(mesh)
t_first = flow.scales(k=50)[0]                 # (1/10) / λ_k
t_last = flow.scales(k=50, grid="log")[-1]     # 2 ln(100) / λ_2
t = np.r_[0.0, np.geomspace(t_first, t_last, 30)]
E = flow.apply(f, t)              # (n, 31): Φ_t f at every t; E[:, 0] = f

tr = o3dheat.track_critical_points(mesh, E, t)
print(tr)
print("events:", dict(collections.Counter(e["kind"] for e in tr.events)))
print("M − s + m at every scale:", set(tr.euler_characteristic.tolist()))

# %%
# Most critical points of ``f`` are noise and end at the first step, mostly at a cancellation (an
# extremum and its persistence partner, a saddle, end together); ``split`` and ``merge`` are a
# saddle's multiplicity changing, ``death`` and ``birth`` what nothing else explains. Every
# critical point of every scale lies on one living track, so ``M − s + m`` stays 2 at every
# scale, the Euler characteristic of the closed bunny.
#
# What a track holds
# ------------------
# ``kind``, the vertex at every scale (``-1`` where it does not live), ``first`` and ``last``
# (indices into ``t``), ``lifetime`` (``t[last] − t[first]``, ``inf`` for a track alive at the
# last scale) and the persistence at every scale. The tracks of ``f`` that live longest:
of_f = np.flatnonzero(tr.first == 0)
longest = of_f[np.argsort(-tr.lifetime[of_f], kind="stable")[:8]]
print("track  kind     vertex  last scale  lifetime  persistence in f")
for i in longest:
    print(f"{i:5d}  {tr.kind[i]:7s}  {tr.vertex[i, 0]:6d}  {tr.last[i]:10d}"
          f"  {tr.lifetime[i]:8.3g}  {tr.persistence[i, 0]:16.3g}")

# %%
# The events are listed between consecutive scales, ``{"kind", "scale", "tracks"}``; the last ones
# (a ``creation`` is an extremum and a saddle that begin together):
for e in tr.events[-4:]:
    j = e["scale"]
    who = ", ".join(f"{tr.kind[i]} (track {i})" for i in e["tracks"])
    print(f"t = {t[j]:.3g} -> {t[j + 1]:.3g}: {e['kind']:8s} {who}")

# %%
# Lifetimes
# ---------
# :func:`o3dheat.visualization.charts.lifetime_chart` draws one bar per track, from the scale it
# starts at to the one it ends at, the longest-lived at the top; a "▶" marks the tracks alive at
# the last scale. ``t = 0`` is drawn one grid step left of the first positive time, labelled "0".
chart = charts.lifetime_chart(tr)

# %%
# The tracks on the surface
# -------------------------
# :func:`o3dheat.plot.tracks <o3dheat.visualization.plot.tracks>` draws each track's path over the
# scales on the surface (coloured by ``f`` at the first scale, washed out), with a marker where it
# ends; ``longest`` keeps the longest-lived. Seen from below, the bunny's base, where the minima
# are; :doc:`/guide/viewing` shows the tracks interactively, with a slider over ``t`` and a
# lifetime threshold.
fig = o3dheat.plot.tracks(mesh, tr, E, longest=40, up="y", view=(-25.0, -60.0),
                          title="the 40 longest-lived tracks, from below")
# sphinx_gallery_thumbnail_number = 2

# %%
# Features by lifetime
# --------------------
# :meth:`Tracks.features(j) <o3dheat.topology.tracking.Tracks.features>` gives the critical
# vertices of the first field (here ``f``) whose tracks live to scale ``j``: the lifetime
# criterion of the feature-driven approximation, beside δ-persistence
# (:func:`o3dheat.simplify_critical_points <o3dheat.topology.diagrams.simplify_critical_points>`).
for j in (1, 10, 20, len(t) - 1):
    print(f"critical points of f alive at t = {t[j]:.3g}:", len(tr.features(j)))

# %%
# At the last scale four tracks live (two maxima, a saddle and a minimum), but ``features()``
# gives the two maxima only: the minimum alive at the end was not a critical point of ``f``. The
# bunny's base is flat in height, its minima differ by far less than one step of the flow changes
# them, and the lowest minimum passes from track to track: the tracks follow the flow, not the
# values, and ``creation`` events put new minima beside old ones. ``f``'s own lowest minimum is
# the lowest at the first scale only, and the one at the end was created late:
for i in np.flatnonzero(tr.last == len(t) - 1):
    print(f"alive at the end: track {i}, {tr.kind[i]}, from scale {tr.first[i]}")
A = tr.features()
kinds = [tr.kind[(tr.vertex[:, 0] == v) & (tr.first == 0)][0] for v in A]
print("features():", A, kinds)
lowest = [int(np.flatnonzero(tr.vertex[:, j] == E[:, j].argmin())[0])
          for j in range(len(t))]
print("the track of the lowest minimum at scales j0..j1:")
for i, run in itertools.groupby(range(len(t)), key=lowest.__getitem__):
    run = list(run)
    print(f"  track {i:4d} ({tr.kind[i]}, from scale {tr.first[i]}): {run[0]}..{run[-1]}")

# %%
# Where the global extrema matter, add them to the features (``np.union1d(tr.features(),
# [f.argmin(), f.argmax()])``). The features are the set ``A`` of
# :func:`o3dheat.feature_driven <o3dheat.topology.approximation.feature_driven>`, which takes the
# exact flow as its kernel (``o3dheat.feature_driven(flow, f, A, t)``), and of the
# ``feature_approx`` filter's ``lifetime=`` criterion.
