#!/usr/bin/env python
"""The tables of docs/details/studies.md, "Which descriptor survives resampling", from the study's CSV.

    .venv/bin/o3dheat study scripts/study_descriptors.toml --out study-descriptors/   # about 5 minutes
    .venv/bin/python scripts/study_descriptors.py docs/study_descriptors.csv          # the shipped table

Prints Markdown: the median relative L2 discrepancy per descriptor and kernel over every mesh,
resampling and scale; the same per resampling kind for the paper's weighted kernel; and the
weighted kernel against the others per descriptor (ratio of the medians, > 1: weighted is more
stable). tests/test_docs.py checks that the page quotes these numbers.
"""

from __future__ import annotations

import sys

import pandas as pd

from o3dheat.pipelines.study import ranking

ORDER = ["smooth_height", "diagram", "critical_points", "si_hks", "hks_density", "wks"]
KERNELS = ["weighted", "lumped", "voronoi", "linear"]


def tables(path):
    t = pd.read_csv(path, keep_default_na=False)
    t = t[t["error"] == ""]
    t["rel_l2"] = t["rel_l2"].astype(float)
    overall = t.groupby(["descriptor", "kernel"])["rel_l2"].median().unstack().loc[ORDER, KERNELS]
    w = t[t["kernel"] == "weighted"]
    per_kind = w.groupby(["descriptor", "kind"])["rel_l2"].median().unstack().loc[ORDER]
    ratio = overall[["lumped", "voronoi", "linear"]].div(overall["weighted"], axis=0)
    return t, overall, per_kind, ratio


def markdown(df, fmt="{:.3g}"):
    cols = list(df.columns)
    lines = ["| descriptor | " + " | ".join(cols) + " |", "|---" * (len(cols) + 1) + "|"]
    for name, row in df.iterrows():
        lines.append(f"| {name} | " + " | ".join(fmt.format(v) for v in row) + " |")
    return "\n".join(lines)


def main(path):
    t, overall, per_kind, ratio = tables(path)
    print(f"{len(t)} rows, meshes {sorted(t['mesh'].unique())}, kinds {sorted(t['kind'].unique())}\n")
    print("Median relative L2 discrepancy (all meshes, resamplings and scales):\n")
    print(markdown(overall))
    print("\nThe weighted kernel per resampling kind:\n")
    print(markdown(per_kind))
    print("\nOther kernels' medians over the weighted kernel's (> 1: the weighted kernel is more stable):\n")
    print(markdown(ratio, "{:.2f}"))
    c = t[t["descriptor"] == "critical_points"].groupby("kernel")["rel_l2"]
    print("\ncritical_points (median 0: most scales keep the count): mean " + ", ".join(
        f"{k} {c.mean()[k]:.3f}" for k in KERNELS) + "; share of rows with another count " + ", ".join(
        f"{k} {(c.apply(lambda s: (s > 0).mean()))[k]:.2f}" for k in KERNELS))
    r = ranking(t)
    print("\nMost stable per kind (study.ranking):\n")
    for kind, g in r.groupby("kind"):
        print(f"- {kind}: " + ", ".join(f"{x.descriptor}/{x.kernel} {x.median:.3g}" for x in g.head(6).itertuples()))


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "docs/study_descriptors.csv")
