"""Filter parameters: types, choices, command-line text (o3dheat.pipelines._params)."""

import open3d as o3d
import pytest

import o3dheat
import o3dheat.pipelines.filters as flt
from o3dheat.pipelines._params import check_value, type_text


def test_parse_value_reads_command_line_text():
    import typing

    assert flt.parse_value("1e-3+0.5", tuple[float, ...]) == (1e-3, 0.5)
    assert flt.parse_value("none", typing.Optional[float]) is None  # noqa: UP045 - Optional is what is tested
    assert flt.parse_value("true", bool) is True
    with pytest.raises(o3dheat.MeshError):
        flt.parse_value("x", int)


def test_parse_value_lists():
    assert flt.parse_value("0.01+0.05", tuple[float, ...]) == (0.01, 0.05)
    assert flt.parse_value("1e+3+2;1E+1", tuple[float, ...]) == (1000.0, 2.0, 10.0)
    assert flt.parse_value("none", tuple[float, ...] | None) is None


def test_one_of_reads_its_choices_when_checking():
    import typing

    choices = ["a", "b"]
    Choice = typing.Annotated[str, flt.OneOf(lambda: choices)]
    assert check_value(Choice, "b", "pick.which") == "b"
    with pytest.raises(o3dheat.MeshError, match="pick.which must be one of 'a', 'b', got 'c'"):
        check_value(Choice, "c", "pick.which")
    choices.append("c")  # defined later: accepted, and described
    assert check_value(Choice, "c", "pick.which") == "c"
    assert type_text(Choice) == "Literal['a', 'b', 'c']"
    assert flt.parse_value("c", Choice) == "c"
    with pytest.raises(o3dheat.MeshError, match="must be text"):
        check_value(Choice, 3, "pick.which")
    with pytest.raises(TypeError, match="callable"):
        flt.OneOf(("a", "b"))


def test_a_literal_choice_of_none_is_written_none():
    import typing

    from o3dheat.pipelines.filters import parse_value

    tp = typing.Literal[None, "lambda2"]
    assert parse_value("none", tp) is None and parse_value("None", tp) is None
    assert parse_value("lambda2", tp) == "lambda2"
    assert parse_value("none", typing.Literal["a", "b"]) == "none"  # refused later, with the choices
    out = o3dheat.pipelines.filters.apply(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 8), "hks",
                                **{"normalize": parse_value("none", tp), "k": 6, "scales": 2})
    assert out.vertex["hks"].shape[1] == 2


def test_unresolvable_annotations_are_refused_not_ignored():
    """A plugin whose annotations name something undefined had its parameters taken unchecked
    (the hints were silently {}): it is refused, by name and made directly, naming the cause."""
    import dataclasses

    from o3dheat.pipelines._params import hints

    @dataclasses.dataclass(frozen=True)
    class Local:
        size: "NotDefinedAnywhere" = 1  # noqa: F821

        def __call__(self, geometry):
            return geometry

    with pytest.raises(o3dheat.MeshError, match=r"filter class .*Local: the annotations of its parameters cannot be "
                                                r"resolved \(NameError: name 'NotDefinedAnywhere' is not defined\)"):
        hints(Local)
    with pytest.raises(o3dheat.MeshError, match="cannot be resolved"):
        flt.check_parameters(Local())
    with pytest.raises(o3dheat.MeshError, match="cannot be resolved"):
        flt.Chain([Local()])
