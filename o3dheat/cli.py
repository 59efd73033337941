"""The ``o3dheat`` command."""

from __future__ import annotations

import argparse
import logging
import sys

from .errors import MeshError, SolverError

__all__ = ["main"]

EXAMPLES = {
    "demo": "examples:\n  o3dheat demo\n  o3dheat demo --out /tmp/bunny.ply -k 50",
    "info": "examples:\n  o3dheat info mesh.ply",
}


def _parser():
    p = argparse.ArgumentParser(prog="o3dheat", description="Multi-scale heat-kernel analysis for Open3D meshes.")
    p.add_argument("-v", "--verbose", action="store_true", help="log what happens")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    d = sub.add_parser("demo", help="run the demo on the embedded bunny", epilog=EXAMPLES["demo"],
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    d.add_argument("--out", default="o3dheat-demo/bunny_heat.ply", help="output PLY (default: %(default)s)")
    d.add_argument("-k", type=int, default=100, help="eigenpairs (default: %(default)s)")
    d.add_argument("--reduction", type=float, default=0.6, help="decimation fraction (default: %(default)s)")
    d.add_argument("--seed", type=int, default=0, help="noise seed (default: %(default)s)")
    i = sub.add_parser("info", help="check a mesh and report what matters to the FEM operators",
                       epilog=EXAMPLES["info"], formatter_class=argparse.RawDescriptionHelpFormatter)
    i.add_argument("mesh", help="mesh file (PLY, OBJ, OFF, STL, ...)")
    return p


def main(argv=None):
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
    try:
        if args.command == "demo":
            from .demo import run

            run(out=args.out, k=args.k, reduction=args.reduction, seed=args.seed)
        elif args.command == "info":
            from .io import read_mesh
            from .mesh import check_mesh

            print(check_mesh(read_mesh(args.mesh)))
        else:
            p.print_help()
            return 1
    except (MeshError, SolverError, OSError) as e:
        print(f"o3dheat: error: {e}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
