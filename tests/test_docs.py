"""The documentation rule: every public function, class and method has a numpydoc ``Examples``
section (run as a doctest by ``--doctest-modules``), and the site's API pages list every module.

Public means: the names of each module's ``__all__`` (``o3dheat.*``; ``o3dheat_filters.*``, whose
modules have no ``__all__``, contribute the classes and functions they define; modules whose name
starts with ``_`` are the package's internal helpers, not public), and, for each
public class, the functions, class methods and static methods defined in its body whose names do
not start with ``_``. Properties and data are attributes: the class's example shows them.
Examples marked ``# doctest: +SKIP`` count (a Dask cluster of worker processes is too slow for
the test suite).
"""

import importlib
import inspect
import pkgutil
import re
from pathlib import Path

import o3dheat
import o3dheat_filters

DOCS = Path(__file__).resolve().parents[1] / "docs"
EXAMPLES = re.compile(r"^Examples\n-{8,}\n", re.M)


def modules():
    names = [f"o3dheat.{m.name}" for m in pkgutil.iter_modules(o3dheat.__path__) if not m.name.startswith("_")]
    names += [f"o3dheat_filters.{m.name}" for m in pkgutil.iter_modules(o3dheat_filters.__path__)
              if not m.name.startswith("_")]
    return sorted(names)


def public_names(module):
    names = getattr(module, "__all__", None)
    if names is None:
        names = [n for n, o in vars(module).items() if not n.startswith("_")
                 and (inspect.isclass(o) or inspect.isfunction(o)) and o.__module__ == module.__name__]
    return names


def documented():
    """[(qualified name, object)]: every public function, class and method, once each."""
    seen, out = set(), []
    for mod_name in modules():
        module = importlib.import_module(mod_name)
        for name in public_names(module):
            obj = getattr(module, name)
            if not (inspect.isclass(obj) or inspect.isfunction(obj)) or id(obj) in seen:
                continue
            seen.add(id(obj))
            out.append((f"{mod_name}.{name}", obj))
            if inspect.isclass(obj):
                for attr, value in vars(obj).items():
                    if isinstance(value, (staticmethod, classmethod)):
                        value = value.__func__
                    if not attr.startswith("_") and inspect.isfunction(value):
                        out.append((f"{mod_name}.{name}.{attr}", value))
    return out


def test_every_public_function_class_and_method_has_an_example():
    items = documented()
    missing = [name for name, obj in items if not EXAMPLES.search(inspect.getdoc(obj) or "")]
    assert not missing, f"{len(missing)} of {len(items)} public names have no Examples section:\n  " + "\n  ".join(missing)


def test_the_api_reference_lists_every_module():
    # `automodule` documents every name of the module's __all__ (conf.py: members by default)
    api = "\n".join(p.read_text() for p in (DOCS / "api").glob("*.rst"))
    absent = [m for m in modules() if not re.search(rf"^\.\. automodule:: {re.escape(m)}$", api, re.M)]
    assert not absent, f"modules missing from docs/api/: {absent}"

