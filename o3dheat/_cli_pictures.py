"""The commands that draw: ``o3dheat figure`` (PNG figures) and ``o3dheat view`` (an interactive
page); their arguments and what runs them, for :mod:`o3dheat.cli`'s dispatch table."""

from __future__ import annotations

import sys
import time
from pathlib import Path

from o3dheat import io
from o3dheat._outputs import check_output, output_folder
from o3dheat.errors import MeshError
from o3dheat.pipelines import filters as flt
from o3dheat.visualization import figures, interactive

__all__ = ["figure_arguments", "figure", "view_arguments", "view"]


def _max_faces(text):
    """--max-faces: a count, or 'none' for every face."""
    if text.strip().lower() == "none":
        return None
    try:
        value = int(text)
    except ValueError:
        raise MeshError(f"--max-faces takes a number of faces or 'none', got {text!r}") from None
    if value < 100:
        raise MeshError(f"--max-faces must be at least 100 (or 'none'), got {value}")
    return value


def _echo(start):
    """Progress lines on stderr, each with the seconds since ``start``."""
    def echo(line):
        print(f"[{time.perf_counter() - start:6.1f} s] {line}", file=sys.stderr, flush=True)
    return echo


def _common(p, what):
    p.add_argument("--attribute", help=f"vertex attribute to {what} (default: " + (
        "the mesh's (n, T) attributes, else " if what == "show" else "") + "the height along up + noise)")
    p.add_argument("--column", type=int, metavar="N",
                   help="the column of a multi-column --attribute (0-based, -1 the last)")
    p.add_argument("-k", type=int, default=100, help="eigenpairs (default: %(default)s)")
    p.add_argument("--noise", type=float, default=0.1, help="noise added to the height, relative (default: %(default)s)")
    p.add_argument("--seed", type=int, default=0, help="noise seed (default: %(default)s)")
    p.add_argument("--up", default="auto", choices=["auto", "x", "y", "z"],
                   help="axis drawn vertical (default: auto: y for .obj/.ply/.off/.gltf/.glb files, z otherwise)")


def figure_arguments(p):
    """The arguments of ``o3dheat figure``."""
    p.add_argument("input", help="mesh file")
    p.add_argument("-o", "--out", required=True, help="output folder (created)")
    _common(p, "study")
    p.add_argument("--max-faces", default="30000", metavar="N",
                   help="decimate larger meshes to N faces first, said on the terminal ('none': keep all; "
                        "default: %(default)s)")
    p.add_argument("--overwrite", action="store_true", help="allow replacing the figures of an earlier run")


def figure(args):
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise MeshError(f"{out} is a file: -o takes a folder")
    if (out / "index.md").exists() and not args.overwrite:
        raise MeshError(f"{out} holds the figures of an earlier run: add --overwrite to replace them, or "
                        "choose another folder")
    if args.column is not None and not args.attribute:
        raise MeshError("--column picks a column of --attribute: give --attribute too")
    if args.seed < 0:
        raise MeshError(f"--seed must be >= 0, got {args.seed}")
    max_faces = _max_faces(args.max_faces)
    echo = _echo(time.perf_counter())
    mesh = io.read_mesh(args.input)
    field = None
    if args.attribute:
        if args.attribute not in mesh.vertex:
            raise MeshError(f"no vertex attribute {args.attribute!r}; the mesh has: "
                            f"{', '.join(k for k in mesh.vertex)}")
        field = flt.one_column(mesh.vertex[args.attribute].numpy(), args.attribute, args.column, option="--column ")
    created = not out.exists()
    output_folder(out, "-o")
    try:
        index = figures.paper_figures(mesh, args.out, field=field, k=args.k, noise=args.noise, seed=args.seed,
                                      name=Path(args.input).stem, up=args.up, source=args.input, tracks=True,
                                      max_faces=max_faces, echo=echo)
    except BaseException:
        if created and out.is_dir() and not any(out.iterdir()):
            out.rmdir()  # no empty folder left behind by a failed run
        raise
    print(f"wrote {index} and its figures")


def view_arguments(p):
    """The arguments of ``o3dheat view``."""
    p.add_argument("input", help="mesh file")
    p.add_argument("-o", "--out", required=True, help="output .html file, in a folder that exists")
    _common(p, "show")
    p.add_argument("--method", default="exact", choices=["exact", "spectral"],
                   help="exact: the full heat kernel (heat_flow); spectral: k eigenpairs (default: %(default)s)")
    p.add_argument("--times", metavar="T1+T2+...", help="the scales (default: 20 log-spaced and the paper's 10)")
    p.add_argument("--max-faces", default="400000", metavar="N",
                   help="show larger meshes decimated to N faces, the fields transferred ('none': keep all; "
                        "default: %(default)s)")
    p.add_argument("--no-tracks", action="store_true", help="do not follow the critical points across scales")
    p.add_argument("--overwrite", action="store_true", help="allow replacing an existing output")


def _times(text):
    if text is None:
        return None
    try:
        return [float(s) for s in text.split("+") if s.strip()]
    except ValueError:
        raise MeshError(f"--times takes numbers joined by + (0.01+0.1+1), got {text!r}") from None


def view(args):
    out = Path(args.out)
    if out.suffix.lower() not in (".html", ".htm"):
        raise MeshError(f"the page is written as .html: {out}")
    check_output(out, args.overwrite)
    if args.column is not None and not args.attribute:
        raise MeshError("--column picks a column of --attribute: give --attribute too")
    times, max_faces = _times(args.times), _max_faces(args.max_faces)
    echo = _echo(time.perf_counter())
    mesh = io.read_mesh(args.input)
    echo(f"read {args.input}: {len(mesh.vertex.positions):,} vertices, {len(mesh.triangle.indices):,} faces")
    v = interactive.view(mesh, args.attribute, times, method=args.method, up=args.up, max_faces=max_faces,
                         column=args.column, source=args.input, echo=echo, k=args.k, noise=args.noise,
                         seed=args.seed, tracks=not args.no_tracks)
    v.save(out, overwrite=args.overwrite)
    echo(f"wrote {out} ({out.stat().st_size / 2**20:.1f} MB): open it in a browser (works offline)")
