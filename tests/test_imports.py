"""`import o3dheat` stays cheap: the heavy libraries are imported where they are used (each
module says so where it imports one inside a function)."""

import subprocess
import sys

HEAVY = ["open3d", "numba", "distributed", "dask", "matplotlib", "pandas", "pymeshlab"]


def test_import_o3dheat_does_not_load_the_heavy_libraries():
    code = ("import sys, o3dheat, o3dheat.cli, o3dheat.typing, o3dheat_filters.hks, o3dheat_filters.tracks; "
            f"print([m for m in {HEAVY!r} if m in sys.modules])")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip().splitlines()[-1] == "[]"
