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


def test_the_short_names_are_importable_modules_with_one_home():
    """Issue 30: ``import o3dheat.plot`` (and ``.sampling``, ``.batch``, ``.filters``, ...) failed
    although ``o3dheat.plot.field`` worked after ``import o3dheat``: each short name is now the module
    at its home, importable by either name (one module object)."""
    names = ["sampling", "batch", "cluster", "filters", "study", "fem", "heatflow", "kernel", "krylov",
             "approximation", "figures", "plot"]
    code = ("import importlib, sys\n"
            f"for name in {names!r}:\n"
            "    short = importlib.import_module('o3dheat.' + name)\n"
            "    import o3dheat\n"
            "    assert short is getattr(o3dheat, name), name\n"
            "    assert sys.modules[short.__name__] is short and short.__name__ != 'o3dheat.' + name, name\n"
            "from o3dheat.plot import field\n"
            "from o3dheat.filters import apply\n"
            "print('ok')\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0 and out.stdout.strip() == "ok", out.stderr
