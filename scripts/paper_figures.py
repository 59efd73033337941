#!/usr/bin/env python
"""Reproduce the kinds of the paper's Figs. 1-7 on the embedded meshes, into a folder of PNGs.

    .venv/bin/python scripts/paper_figures.py                 # -> paper-figures/{bunny,torus}/
    .venv/bin/python scripts/paper_figures.py --out /tmp/figs -k 50

Each sub-folder has an index.md saying what each image shows (see o3dheat.visualization.figures.paper_figures).
The same figures for any mesh: ``o3dheat figure MESH -o FOLDER``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from o3dheat.io import bumpy_torus, default_mesh
from o3dheat.visualization.figures import paper_figures


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default="paper-figures", help="output folder (default: %(default)s)")
    ap.add_argument("-k", type=int, default=100, help="eigenpairs (default: %(default)s)")
    ap.add_argument("--noise", type=float, default=0.1, help="relative noise of the field (default: %(default)s)")
    args = ap.parse_args(argv)
    out = Path(args.out)
    bunny, _ = default_mesh()
    cases = [("bunny", bunny, "y"), ("torus", bumpy_torus(96, 48), "z")]
    lines = ["# o3dheat: the kinds of the paper's figures", ""]
    for name, mesh, up in cases:
        index = paper_figures(mesh, out / name, k=args.k, noise=args.noise, name=name, up=up)
        print(f"wrote {index}")
        lines.append(f"- [{name}]({name}/index.md)")
    (out / "index.md").write_text("\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
