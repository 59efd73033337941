"""The ``o3dheat`` command: ``info``, ``repair``, ``filters``, ``apply``, ``batch``, ``spectrum``, ``figure``,
``view``, ``study``, ``demo``.

User errors (missing files, unknown filters or parameters, bad values, an output in a folder
that does not exist) print one line starting with ``o3dheat: error:`` and exit with status 2; no
traceback; they are found before any computation. ``-v`` logs what happens; ``--version`` prints
the version.
"""

from __future__ import annotations

import argparse
import itertools
import logging
import sys
from collections.abc import Sequence
from pathlib import Path

import o3dheat
from o3dheat import _cli_pictures, demo, geometry, io
from o3dheat._outputs import check_folder, check_output, output_folder, same_file
from o3dheat.errors import MeshError, SolverError
from o3dheat.pipelines import batch, study
from o3dheat.pipelines import filters as flt
from o3dheat.pipelines._dask_logs import DaskLogs
from o3dheat.spectral import fem, heatflow, spectrum, variants
from o3dheat.visualization import figures

__all__ = ["main"]

EXAMPLES = {
    "demo": """examples:
  o3dheat demo
  o3dheat demo --out /tmp/bunny.ply -k 50""",
    "info": """examples:
  o3dheat info mesh.ply""",
    "repair": """examples:
  o3dheat repair scan.stl scan.ply                       # weld, drop bad faces, split, orient
  o3dheat repair scan.ply clean.ply --min-component-faces 100   # also drop small pieces

Vertex attributes of a PLY input are carried over. The input is never overwritten.""",
    "filters": """examples:
  o3dheat filters                 # list the installed filters
  o3dheat filters heat_smooth     # its parameters, types, defaults and help""",
    "apply": """examples:
  o3dheat apply in.ply out.ply -f scalar:kind=height -f heat_smooth:attribute=height,k=100 \\
      -f colorize:attribute=height_smooth,column=4
  o3dheat apply in.ply out.ply -f hks:scales=16 --save-chain chain.toml
  o3dheat apply other.obj other.ply --chain chain.toml

parameters: -f NAME:key=value,key=value; list values with + (times=0.01+0.02+0.05), not
commas (they separate the parameters); none/true/false are read as such. A filter that reads one
column of a multi-column attribute needs column=N (0-based, -1 the last). Outputs are .ply or
.npz, in a folder that exists; the input is never overwritten unless --overwrite is given.""",
    "batch": """examples:
  o3dheat batch 'scans/*.ply' --out results/ -f scalar:kind=height \\
      -f heat_smooth:attribute=height,k=100 -f colorize:attribute=height_smooth,column=4
  o3dheat batch 'scans/**/*.obj' more/x.ply --out results/ --chain chain.toml --scheduler sequential
  o3dheat batch 'scans/*.ply' --out results/ --chain chain.toml --scheduler tcp://10.0.0.5:8786

Quote the patterns: o3dheat expands them. Each input gives results/<its stem>.ply (or .npz),
written atomically. The chain is recorded in results/o3dheat-batch.toml: running the same chain
again skips the outputs that exist (an interrupted batch resumes, failed files are retried);
another chain into the same folder is refused; --overwrite recomputes every output (and removes
those of files that fail). A file that fails is reported (exit status 1) and does not stop the
others; Ctrl-C keeps the finished outputs (exit status 130). Refused before any work (exit
status 2): a pattern matching nothing, two inputs with the same output name, an output that would
replace an input. Default scheduler: a local Dask cluster, one worker per core.""",
    "spectrum": """examples:
  o3dheat spectrum mesh.ply -k 200 -o spectrum.npz
  o3dheat spectrum mesh.ply -k 200 --mass voronoi -o voronoi.npz

read it back in Python: o3dheat.Spectrum.load("spectrum.npz") (checked: eigenpairs of the stored
operators, B-orthonormal, ascending), and smooth with the kernel of the same variant:
o3dheat.HeatKernel(o3dheat.Spectrum.load("voronoi.npz"), variant="voronoi").

--mass names a kernel variant, as the filters' variant= and the study's kernels do, one of
  <VARIANTS>
The mass kinds of o3dheat.eigensolve(mass=...) are still read where they differ from these
(<OLD_MASSES>), with a note: they are deprecated spellings.""",
    "study": """examples:
  o3dheat study study.toml --out results/                      # a local Dask cluster
  o3dheat study study.toml --out results/ --scheduler sequential
  o3dheat study study.toml --out results/ --scheduler tcp://10.0.0.5:8786

study.toml:
  k = 60
  scales = 10
  grid = "paper"                     # <GRIDS>: each kernel's scales on its reference spectrum
  method = "spectral"                # <METHODS>: "exact" smooths with the full kernel
  kernels = <VARIANTS>   # o3dheat.spectral.variants.VARIANTS (default: all)
  descriptors = ["hks_density", "hks_paper", "smooth_height", "eigenvalues"]
  [meshes]
  bunny = "builtin:bunny@20000"      # embedded, decimated to 20000 faces; or a file path
  [[resampling]]
  name = "decimate-70"
  kind = "decimate"
  reduction = 0.7

An interrupted study resumes: run the same command again.""",
    "figure": """examples:
  o3dheat figure mesh.ply -o figures/                 # noisy height field, the paper's figure kinds
  o3dheat figure mesh.stl -o figures/ --attribute f -k 100 --up y   # a y-up scan in an STL file
  o3dheat figure out.ply -o figures/ --attribute hks --column 4      # one column of an (n, c) attribute

The folder is created (with its parents) before any computation. Up: y for .obj/.ply/.off/.gltf/.glb
files, z for the others (stated in index.md; --up overrides). Progress goes to stderr.""",
    "view": """examples:
  o3dheat view mesh.ply -o view.html                   # noisy height, exact heat flow, 20 + 10 scales
  o3dheat view demo.ply -o view.html                   # every (n, T) attribute (f_smooth, f_exact, hks)
  o3dheat view mesh.ply -o view.html --attribute f --method spectral -k 200
  o3dheat view scan.ply -o view.html --max-faces none --times 0.001+0.01+0.1

One self-contained HTML file: no request leaves it (three.js is inlined); open it from disk.
In the page: drag to orbit, right-drag to pan, wheel to zoom; a slider and a play button over t.""",
}


def _epilog(name):
    """The examples of a command, with the lists defined elsewhere filled in (read now)."""
    import json

    return (EXAMPLES[name].replace("<VARIANTS>", json.dumps(list(variants.VARIANTS), ensure_ascii=False))
            .replace("<OLD_MASSES>", ", ".join(f"{kind} = {variant}" for kind, variant in _former_masses().items()))
            .replace("<GRIDS>", "one of " + ", ".join(map(json.dumps, variants.GRIDS)))
            .replace("<METHODS>", "one of " + ", ".join(map(json.dumps, heatflow.METHODS))))


def _sub(sub, name, help_text):
    return sub.add_parser(name, help=help_text, description=help_text, epilog=_epilog(name),
                          formatter_class=argparse.RawDescriptionHelpFormatter)


def _demo_arguments(p):
    """The arguments of ``o3dheat demo``."""
    p.add_argument("--out", help="output PLY, in a folder that exists (default: o3dheat-demo/bunny_heat.ply, "
                                 "folder created, or bunny_heat-N.ply when that exists: an earlier result is "
                                 "never replaced)")
    p.add_argument("--overwrite", action="store_true", help="allow replacing an existing --out")
    p.add_argument("-k", type=int, default=100, help="eigenpairs (default: %(default)s)")
    p.add_argument("--reduction", type=float, default=0.6, help="decimation fraction (default: %(default)s)")
    p.add_argument("--seed", type=int, default=0, help="noise seed (default: %(default)s)")


def _info_arguments(p):
    """The arguments of ``o3dheat info``."""
    p.add_argument("mesh", help="mesh file (PLY, OBJ, OFF, STL, ...)")


def _repair_arguments(p):
    """The arguments of ``o3dheat repair``."""
    p.add_argument("input", help="mesh file (PLY, OBJ, OFF, STL, ...)")
    p.add_argument("output", help="output .ply or .npz")
    p.add_argument("--min-component-faces", type=int, default=0, metavar="N",
                   help="remove components with fewer faces (default: keep all)")
    p.add_argument("--no-split", action="store_true", help="keep non-manifold edges and vertices")
    p.add_argument("--no-orient", action="store_true", help="keep the faces' orientation")
    p.add_argument("--ascii", action="store_true", help="ASCII PLY instead of binary")
    p.add_argument("--overwrite", action="store_true", help="allow replacing an existing output")


def _filters_arguments(p):
    """The arguments of ``o3dheat filters``."""
    p.add_argument("name", nargs="?", help="a filter name")


def _apply_arguments(p):
    """The arguments of ``o3dheat apply``."""
    p.add_argument("input", help="mesh or point cloud file (PLY, NPZ, OBJ, OFF, STL, PCD, ...)")
    p.add_argument("output", help="output file (.ply or .npz)")
    p.add_argument("-f", "--filter", action="append", default=[], metavar="NAME:key=value,...",
                   help="a filter and its parameters (repeatable; run in order)")
    p.add_argument("--chain", help="a TOML chain file (run before any -f)")
    p.add_argument("--save-chain", metavar="TOML", help="also write the chain that was run")
    p.add_argument("--ascii", action="store_true", help="ASCII PLY instead of binary")
    p.add_argument("--overwrite", action="store_true", help="allow replacing an existing output")
    p.add_argument("--cache", nargs="?", const=True, metavar="DIR",
                   help="keep spectra on disk (default folder: $O3DHEAT_CACHE or the user cache folder, ~/.cache/o3dheat on Linux)")


def _batch_arguments(p):
    """The arguments of ``o3dheat batch``."""
    p.add_argument("inputs", nargs="+", metavar="INPUT", help="files or quoted glob patterns ('scans/*.ply')")
    p.add_argument("--out", required=True, metavar="DIR", help="output folder (created): DIR/<input stem>.ply")
    p.add_argument("-f", "--filter", action="append", default=[], metavar="NAME:key=value,...",
                   help="a filter and its parameters (repeatable; run in order)")
    p.add_argument("--chain", help="a TOML chain file (run before any -f)")
    p.add_argument("--scheduler", help="'sequential', or a Dask scheduler address (default: a local cluster)")
    p.add_argument("--format", choices=["ply", "npz"], default="ply", help="output format (default: %(default)s)")
    p.add_argument("--ascii", action="store_true", help="ASCII PLY instead of binary")
    p.add_argument("--overwrite", action="store_true",
                   help="recompute every output, removing those of files that fail (default: skip the "
                        "outputs that exist)")
    p.add_argument("--progress", action=argparse.BooleanOptionalAction, default=None,
                   help="a progress bar (default: when stderr is a terminal)")


def _spectrum_arguments(p):
    """The arguments of ``o3dheat spectrum``."""
    p.add_argument("input", help="mesh file")
    p.add_argument("-k", type=int, default=100, help="eigenpairs (default: %(default)s)")
    p.add_argument("--mass", default="weighted", metavar="{" + ",".join(variants.VARIANTS) + "}",
                   help="the kernel variant whose eigenproblem L x = λ B x is solved, B its mass "
                        "(o3dheat.spectral.variants.VARIANTS; default: %(default)s): "
                        + "; ".join(f"{name} (B: {mass}): {text}" for name, (mass, text) in variants.VARIANTS.items()))
    p.add_argument("-o", "--out", required=True,
                   help="output .npz, in a folder that exists: the whole spectrum (eigenpairs, operators, areas, "
                        "faces, residuals), read back by o3dheat.Spectrum.load")
    p.add_argument("--overwrite", action="store_true", help="allow replacing an existing output")


def _study_arguments(p):
    """The arguments of ``o3dheat study``."""
    p.add_argument("config", help="study TOML file")
    p.add_argument("--out", required=True, help="output folder, created (tasks/, study.csv, plots)")
    p.add_argument("--scheduler", help="'sequential', or a Dask scheduler address (default: a local cluster)")


def _parser():
    p = argparse.ArgumentParser(prog="o3dheat", description="Multi-scale heat-kernel analysis for Open3D meshes.",
                                epilog="run 'o3dheat COMMAND --help' for examples of each command")

    p.add_argument("-v", "--verbose", action="store_true", help="log what happens")
    p.add_argument("--version", action="version", version=f"%(prog)s {o3dheat.__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    for name, (help_text, arguments, _) in COMMANDS.items():
        arguments(_sub(sub, name, help_text))
    return p


def _parse_filter(text):
    """'name:key=value,key=value' -> (name, {key: value parsed by the filter's types})."""
    import typing

    name, _, rest = text.partition(":")
    name = name.strip()
    hints = flt.parameter_types(name)
    params = {}
    items = [s.strip() for s in rest.split(",") if s.strip()]
    for i, item in enumerate(items):
        key, eq, value = item.partition("=")
        key = key.strip()
        if not eq:
            before = items[i - 1].partition("=") if i else ("", "", "")
            if before[1] and _is_list(hints.get(before[0].strip())):  # times=0.01,0.05
                more = [item, *itertools.takewhile(lambda t: "=" not in t, items[i + 1:])]
                example = f"{before[0].strip()}={'+'.join([before[2].strip()] + more)}"
                raise MeshError(f"-f {text!r}: {item!r} is not key=value: write lists with +: {example}")
            raise MeshError(f"-f {text!r}: expected key=value, got {item!r}")
        if key not in hints:
            fields = ", ".join(p.name for p in flt.describe(name)["parameters"])
            raise MeshError(f"filter {name!r} has no parameter {key!r}; its parameters: {fields}")
        try:
            params[key] = flt.parse_value(value, hints.get(key, typing.Any))
        except MeshError as e:
            raise MeshError(f"-f {name}: parameter {key!r}: {e}") from None
    return name, params


def _is_list(tp):
    """Whether a parameter annotation is a list type (possibly optional)."""
    import typing

    if tp is None:
        return False
    if typing.get_origin(tp) in (tuple, list):
        return True
    return any(typing.get_origin(a) in (tuple, list) for a in typing.get_args(tp))


def _progress(total):
    """A callback drawing a tqdm bar over the chain steps when attached to a terminal."""
    if not sys.stderr.isatty():
        return None, lambda: None
    from tqdm import tqdm

    bar = tqdm(total=total, unit="filter", file=sys.stderr)

    def step(i, flt_obj):
        bar.set_description(type(flt_obj).__name__)
        if i:
            bar.update(1)

    def close():
        bar.update(bar.total - bar.n)
        bar.close()

    return step, close


def _chain(args):
    """The chain of --chain and the -f filters (MeshError when there is none)."""
    chain = flt.Chain.load(args.chain) if args.chain else flt.Chain()
    for text in args.filter:
        name, params = _parse_filter(text)
        chain.append(name, **params)
    if not len(chain):
        raise MeshError("no filter given: use -f NAME:key=value or --chain FILE (o3dheat filters lists them)")
    return chain


def _batch(args):
    chain = _chain(args)
    try:
        table = batch.run(chain, args.inputs, args.out, scheduler=args.scheduler, overwrite=args.overwrite,
                    suffix="." + args.format, binary=not args.ascii, progress=args.progress)
    except KeyboardInterrupt:
        print("o3dheat: interrupted; the finished outputs are kept: run the same command again to resume",
              file=sys.stderr)
        return 130
    print(f"{batch.summary(table)}; outputs in {args.out}")
    failed = table[table["status"] == "failed"]
    if len(failed):
        print(f"{len(failed)} file(s) failed (retried when the same command runs again):", file=sys.stderr)
        for _, r in failed.iterrows():
            print(f"  {batch.named_error(r['input'], r['error'])}", file=sys.stderr)
        return 1
    return 0


def _apply(args):
    src, dst = Path(args.input), Path(args.output)
    if dst.suffix.lower() not in (".ply", ".npz"):
        raise MeshError(f"the output must end in .ply or .npz: {dst}")
    if src.exists() and dst.exists() and src.resolve() == dst.resolve() and not args.overwrite:
        raise MeshError(f"refusing to overwrite the input {src}: choose another output or add --overwrite")
    check_output(dst, args.overwrite)
    if args.save_chain:
        saved = Path(args.save_chain)
        if saved.suffix.lower() != ".toml":
            raise MeshError(f"--save-chain writes a TOML file: {saved} should end in .toml")
        for other, what in ((src, "the input mesh"), (dst, "the output mesh"),
                            (Path(args.chain) if args.chain else None, "the --chain file")):
            if other is not None and same_file(saved, other):
                raise MeshError(f"--save-chain {saved} is {what}: choose another file")
        check_output(saved, args.overwrite)
    chain = _chain(args)
    geometry = io.read_geometry(src)
    if args.cache:
        flt.set_disk_cache(args.cache)
    step, close = _progress(len(chain))
    out = chain(geometry, progress=step)
    close()
    io.write_geometry(dst, out, binary=not args.ascii, overwrite=True)
    if args.save_chain:
        chain.save(args.save_chain)
    attrs = out.vertex if hasattr(out, "vertex") else out.point
    print(f"wrote {dst}: " + ", ".join(f"{k} {tuple(attrs[k].shape)}" for k in attrs))


def _repair(args):
    src, dst = Path(args.input), Path(args.output)
    if dst.suffix.lower() not in (".ply", ".npz"):
        raise MeshError(f"the output must end in .ply or .npz: {dst}")
    if src.exists() and same_file(src, dst):
        raise MeshError(f"refusing to overwrite the input {src}: choose another output")
    check_output(dst, args.overwrite)
    r = geometry.repair(io.read_mesh(src), split=not args.no_split, orient=not args.no_orient,
               min_component_faces=args.min_component_faces)
    io.write_mesh(dst, r.mesh, binary=not args.ascii, overwrite=True)
    print(f"{src}: {r}")
    print(geometry.check_mesh(r.mesh))
    print(f"wrote {dst}")


def _filters(args):
    if not args.name:
        for name in flt.names():
            print(f"{name:<18} {flt.describe(name)['summary']}")
        return
    d = flt.describe(args.name)
    print(f"{d['name']}: {d['summary']}\n\nparameters:")
    for p in d["parameters"]:
        print(f"  {p.name} ({p.type}, default {p.default!r})\n      {p.help}")


def _former_masses():
    """{mass kind: its kernel variant} for the mass kinds (fem.MASS_KINDS) that are not a variant's
    name: the former spellings of ``spectrum --mass``, still read (deprecated)."""
    return {kind: variants.variant_of_mass(kind) for kind in fem.MASS_KINDS if kind not in variants.VARIANTS}


def _mass_of_argument(name):
    """The mass kind of ``spectrum --mass NAME``: a kernel variant's, or a former spelling (a mass kind,
    said on stderr to be deprecated); anything else is a MeshError naming the variants."""
    former = _former_masses()
    if name in former:
        print(f"o3dheat: note: --mass {name} is deprecated: write --mass {former[name]} (the same mass)",
              file=sys.stderr)
        return name
    if name not in variants.VARIANTS:
        raise MeshError(f"unknown --mass {name!r}: use a kernel variant, one of {', '.join(variants.VARIANTS)}")
    return variants.mass_of(name)


def _spectrum(args):
    mass = _mass_of_argument(args.mass)
    out = Path(args.out)
    if out.suffix.lower() != ".npz":
        raise MeshError(f"the spectrum is written as .npz: {out}")
    check_output(out, args.overwrite)
    if args.k < 1:
        raise MeshError(f"-k must be at least 1, got {args.k}")
    s = spectrum.eigensolve(io.read_mesh(args.input), k=args.k, mass=mass)
    s.save(out, overwrite=True)  # check_output refused an existing file without --overwrite
    print(f"wrote {out}: {s.k} eigenpairs of {s.n} vertices, λ in [{s.eigenvalues[0]:.4g}, "
          f"{s.eigenvalues[-1]:.4g}], max residual {s.residuals.max():.1e} ({s.backend})")


def _study(args):
    out = Path(args.out)
    check_folder(out, "--out")  # before the config's meshes are read
    kw = study.load_config(args.config)
    table = study.robustness_study(out=out, scheduler=args.scheduler, **kw)  # creates out once connected
    ok = table[table["error"].fillna("") == ""]
    failed = table[table["error"].fillna("") != ""]
    written = figures.study_figures(table, out)
    if len(ok):
        summary = ok.groupby(["descriptor", "kernel"])["rel_l2"].median().unstack("kernel")
        print(f"median relative L2 discrepancy to the reference sampling ({len(ok)} rows):")
        print(summary.to_string(float_format=lambda x: f"{x:.3g}"))
        ranked = study.ranking(ok)
        print("most stable per resampling kind (median rel_l2; study.ranking):")
        for kind, g in ranked.groupby("kind", sort=False):
            print(f"  {kind}: " + ", ".join(f"{r.descriptor}/{r.kernel} {r.median:.3g}" for r in g.head(5).itertuples()))
    print(f"wrote {out / 'study.csv'}" + (f" and {len(written)} plots ({out}/study_*.png)" if written else
                                          " (no plot: no task succeeded)"))
    if len(failed):
        tasks = len(failed) + ok.groupby(['mesh', 'resampling']).ngroups
        head = (f"all {tasks} task(s) failed; first error: {failed['error'].iloc[0]}" if not len(ok) else
                f"{len(failed)} of {tasks} task(s) failed")
        print(f"{head} (they are retried when the same command runs again):", file=sys.stderr)
        for _, r in failed.iterrows():
            print(f"  {r['mesh']} / {r['resampling']}: {r['error']}", file=sys.stderr)
        return 1
    return 0


#: Dask's records below WARNING dropped, the others on one line (see --verbose)
_QUIET_DASK = DaskLogs(logging.WARNING)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``o3dheat`` command; returns the exit code.

    Examples
    --------
    >>> from o3dheat.cli import main
    >>> main(["info", "/no/such/file.ply"])
    2
    """
    p = _parser()
    args = p.parse_args(argv)
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING, format="%(levelname)s: %(message)s")
    if not args.verbose:  # Dask logs every worker start and stop at INFO, on loggers of its own levels
        for name in ("distributed", "dask"):
            logging.getLogger(name).setLevel(logging.WARNING)
        for handler in logging.getLogger().handlers:
            handler.addFilter(_QUIET_DASK)  # one instance: a handler holds it once, however often main runs
    command = COMMANDS.get(args.command, (None, None, None))[2]
    if command is None:
        p.print_help()
        return 1
    try:
        code = command(args)
    except (MeshError, SolverError, OSError) as e:
        print(f"o3dheat: error: {e}", file=sys.stderr)
        return 2
    return 0 if code is None else code


def _demo(args):
    out = args.out
    if out is None:  # the default name, or the next free one: a rerun keeps earlier results
        out, i = Path("o3dheat-demo") / "bunny_heat.ply", 1
        while out.exists():
            out, i = Path("o3dheat-demo") / f"bunny_heat-{i}.ply", i + 1
    else:
        check_output(Path(out), args.overwrite)
    if not Path(out).parent.is_dir():  # the default folder, created before the work
        output_folder(Path(out).parent, "--out")
    demo.run(out=out, k=args.k, reduction=args.reduction, seed=args.seed)


def _info(args):
    g = io.read_geometry(args.mesh)
    if not hasattr(g, "triangle"):
        raise MeshError(f"{args.mesh} is a point cloud ({len(g.point.positions)} points): info checks meshes")
    print(geometry.check_mesh(g))


#: subcommand -> its function (args -> exit code, None for 0): the one dispatch of :func:`main`
#: the commands: name -> (one-line help, its arguments, what runs it), in the order of --help
COMMANDS = {
    "demo": ("run the demo on the embedded bunny", _demo_arguments, _demo),
    "info": ("check a mesh and report what matters to the FEM operators", _info_arguments, _info),
    "repair": ("repair a mesh: weld, drop bad faces, split non-manifold edges and vertices, orient", _repair_arguments, _repair),
    "filters": ("list the installed filters, or describe one", _filters_arguments, _filters),
    "apply": ("run a chain of filters on a mesh or point cloud and write the result", _apply_arguments, _apply),
    "batch": ("run a chain of filters on many files (in parallel, resumable)", _batch_arguments, _batch),
    "spectrum": ("compute the smallest eigenpairs of a mesh and save them", _spectrum_arguments, _spectrum),
    "study": ("robustness of descriptors across resamplings (a table and plots)", _study_arguments, _study),
    "figure": ("draw the paper's kinds of figures (Figs. 1-7) for a mesh", _cli_pictures.figure_arguments,
               _cli_pictures.figure),
    "view": ("write an interactive page of a field's scale space (one offline HTML file, a slider over t)",
             _cli_pictures.view_arguments, _cli_pictures.view),
}


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
