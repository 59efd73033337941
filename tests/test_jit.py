"""o3dheat._jit: loops compiled once per installation; which modules compiled in this process."""

import types

import o3dheat._jit as J


def _fake(misses):
    return types.SimpleNamespace(stats=types.SimpleNamespace(cache_misses={("sig",): misses}))


def test_any_compiled_covers_the_modules_inside_a_stage(monkeypatch):
    """A stage's name covers its modules (the demo asks for "o3dheat.topology" while the loops live
    in a module inside it); a module whose name only starts the same does not."""
    monkeypatch.setattr(J, "_COMPILED", {("o3dheat.topology._loops", "a"): _fake(1),
                                         ("o3dheat.topologyx", "b"): _fake(1)})
    assert J.any_compiled("o3dheat.topology") and J.any_compiled("o3dheat.topology._loops")
    assert not J.any_compiled("o3dheat.geometry")
    monkeypatch.setattr(J, "_COMPILED", {("o3dheat.topologyx", "b"): _fake(1),
                                         ("o3dheat.topology._loops", "a"): _fake(0)})
    assert not J.any_compiled("o3dheat.topology")
