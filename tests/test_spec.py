"""JSON specs: validation names the field, the published schema agrees with
the validator, and specs build the maps they describe."""

import doctest
import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import fpiwarp
from fpiwarp import spec as spec_module
from fpiwarp.spec import SpecError, build_transform, load_spec, parse_spec, save_spec, schema, to_spec, validate_spec

SQUARE = [[0, 0], [10, 0], [10, 10], [0, 10]]
MOVED = [[1, 0.5], [9, 1], [10.5, 9], [0, 10]]
PTS = np.array([[2.0, 3.0], [7.5, 1.25], [5.0, 5.0], [9.0, 8.0]])

VALID = [
    {"src": SQUARE, "dst": MOVED},
    {"type": "fpi", "src": SQUARE, "dst": MOVED, "description": "a warp", "$schema": "spec.schema.json"},
    {"src": SQUARE, "dst": MOVED, "edges": [0, 2]},
    {"type": "local", "src": SQUARE, "dst": MOVED, "edges": [3, 0]},
    {"src": SQUARE, "dst": MOVED, "edges": [1.0, 3]},  # JSON integers may be written 1.0
    {"steps": [{"src": SQUARE, "dst": MOVED}]},
    {"type": "compound", "steps": [{"src": SQUARE, "dst": MOVED}, {"steps": [{"src": MOVED, "dst": SQUARE}]}]},
]

# (spec, the field the message must name, a phrase of the problem)
INVALID = [
    ([], "spec", "must be a JSON object"),
    ({}, "spec", "missing required field 'src'"),
    ({"src": SQUARE}, "spec", "missing required field 'dst'"),
    ({"src": SQUARE, "dts": MOVED}, "spec", "unknown field 'dts'"),
    ({"type": "affine", "src": SQUARE, "dst": MOVED}, "type", "must be one of"),
    ({"type": "fpi", "src": SQUARE, "dst": MOVED, "edges": [0, 2]}, "spec", "unknown field 'edges'"),
    ({"type": "local", "src": SQUARE, "dst": MOVED}, "spec", "missing required field 'edges'"),
    ({"src": SQUARE[:3], "dst": MOVED}, "src", "4 [x, y] points"),
    ({"src": SQUARE, "dst": [[0, 0], [1, 0], [1, "1"], [0, 1]]}, "dst[2]", "y is the text '1'"),
    ({"src": [["0", "0"], [1, 0], [1, 1], [0, 1]], "dst": SQUARE}, "src[0]", "x is the text '0'"),
    ({"src": SQUARE, "dst": [[0, 0], [1, 0], [1e200, 1], [0, 1]]}, "dst[2]", "x = 1e+200 lies beyond ±1e+100"),
    ({"src": SQUARE, "dst": [[0, 0], [1, 0], [1, -1e308], [0, 1]]}, "dst[2]", "y = -1e+308 lies beyond"),
    (
        {"steps": [{"src": SQUARE, "dst": [[0, 0], [10**400, 0], [1, 1], [0, 1]]}]},
        "steps[0].dst[1]",
        "integer of 401 digits",
    ),
    ({"src": SQUARE, "dst": [[0, 0], [1, 0], [1, True], [0, 1]]}, "dst[2]", "two numbers"),
    ({"src": SQUARE, "dst": [[0, 0], [1, 0], [1, 1, 1], [0, 1]]}, "dst[2]", "two numbers"),
    ({"src": SQUARE, "dst": MOVED, "edges": [0, 0]}, "edges", "two different edge numbers"),
    ({"src": SQUARE, "dst": MOVED, "edges": [0, 4]}, "edges", "two different edge numbers"),
    ({"src": SQUARE, "dst": MOVED, "edges": [0, 1.5]}, "edges", "two different edge numbers"),
    ({"src": SQUARE, "dst": MOVED, "edges": [0]}, "edges", "two different edge numbers"),
    ({"steps": []}, "steps", "non-empty list"),
    ({"steps": {"src": SQUARE}}, "steps", "non-empty list"),
    ({"steps": [{"src": SQUARE, "dst": MOVED}, {"src": SQUARE}]}, "steps[1]", "missing required field 'dst'"),
    ({"steps": [{"steps": [{"src": SQUARE, "dst": MOVED[:2]}]}]}, "steps[0].steps[0].dst", "4 [x, y]"),
    ({"steps": [{"src": SQUARE, "dst": MOVED}], "src": SQUARE}, "spec", "unknown field 'src'"),
    ({"src": SQUARE, "dst": MOVED, "description": 3}, "description", "must be text"),
]


@pytest.mark.parametrize("spec", VALID)
def test_valid_specs_pass(spec):
    validate_spec(spec)


@pytest.mark.parametrize("spec, where, problem", INVALID)
def test_errors_name_the_field_and_the_problem(spec, where, problem):
    with pytest.raises(SpecError) as info:
        validate_spec(spec)
    message = str(info.value)
    assert message.startswith(f"{where}: "), message
    assert problem in message


@pytest.fixture(scope="module")
def schema_validator():
    jsonschema = pytest.importorskip("jsonschema")
    spec_schema = schema()
    jsonschema.Draft202012Validator.check_schema(spec_schema)
    return jsonschema.Draft202012Validator(spec_schema)


def _accepted(spec):
    try:
        validate_spec(spec)
    except SpecError:
        return False
    return True


@pytest.mark.parametrize("spec", VALID + [case[0] for case in INVALID])
def test_schema_agrees_with_the_validator_on_examples(schema_validator, spec):
    assert schema_validator.is_valid(spec) == _accepted(spec)


# Random JSON built from the spec vocabulary: mostly near-misses of valid specs.
_numbers = st.one_of(st.integers(-5, 12), st.floats(-5, 12, allow_nan=False), st.booleans(), st.just("1"))
_points = st.lists(_numbers, min_size=1, max_size=3)
_quads = st.one_of(st.just(SQUARE), st.just(MOVED), st.lists(_points, min_size=3, max_size=5), st.just(None))
_edges = st.one_of(st.lists(st.one_of(st.integers(-1, 4), st.just(2.0), st.just(0.5)), max_size=3), st.just("0,2"))
_field_values = {
    "src": _quads,
    "dst": _quads,
    "edges": _edges,
    "type": st.sampled_from(["fpi", "local", "compound", "tps", 3]),
    "description": st.one_of(st.text(max_size=3), st.integers()),
    "$schema": st.just("x"),
    "extra": st.integers(),
}


def _objects(children):
    keys = st.lists(st.sampled_from(sorted(_field_values) + ["steps"]), unique=True, max_size=5)

    @st.composite
    def build(draw):
        obj = {}
        for key in draw(keys):
            if key == "steps":
                obj[key] = draw(st.one_of(st.lists(children, max_size=3), st.integers()))
            else:
                obj[key] = draw(_field_values[key])
        return obj

    return build()


_specs = st.recursive(
    st.one_of(st.just({"src": SQUARE, "dst": MOVED}), st.just({"src": SQUARE, "dst": MOVED, "edges": [0, 2]})),
    _objects,
    max_leaves=6,
)


@settings(max_examples=300, deadline=None)
@given(spec=st.one_of(_specs, _objects(_specs), st.lists(st.integers(), max_size=2)))
def test_schema_agrees_with_the_validator_on_random_json(schema_validator, spec):
    assert schema_validator.is_valid(spec) == _accepted(spec)


def test_an_fpi_spec_builds_that_fpi():
    t = build_transform({"src": SQUARE, "dst": MOVED})
    assert isinstance(t, fpiwarp.FPI)
    np.testing.assert_allclose(t(PTS), fpiwarp.FPI(SQUARE, MOVED)(PTS), rtol=0, atol=1e-12)


def test_a_compound_applies_its_steps_in_order():
    second = [[0, 0], [12, 1], [11, 12], [-1, 10]]
    t = build_transform({"steps": [{"src": SQUARE, "dst": MOVED}, {"src": MOVED, "dst": second}]})
    expected = fpiwarp.FPI(MOVED, second)(fpiwarp.FPI(SQUARE, MOVED)(PTS))
    np.testing.assert_allclose(t(PTS), expected, rtol=0, atol=1e-9)
    np.testing.assert_allclose(t(SQUARE), second, rtol=0, atol=1e-9)


def test_a_local_spec_builds_a_local_deformation():
    local = pytest.importorskip("fpiwarp.maps.local")
    dst = [[0, 0], [10, 0], [11, 11], [0, 10]]
    t = build_transform({"src": SQUARE, "dst": dst, "edges": [3, 1]})
    assert isinstance(t, local.LocalDeformation)
    assert tuple(t.edges) in {(3, 1), (1, 3)}
    np.testing.assert_allclose(t(SQUARE), dst, rtol=0, atol=1e-9)


@pytest.mark.parametrize(
    "spec, where, problem",
    [
        ({"src": [[0, 0], [5, 5], [10, 10], [0, 10]], "dst": MOVED}, "src", "collinear"),
        ({"steps": [{"src": SQUARE, "dst": MOVED}, {"src": SQUARE, "dst": SQUARE[::-1]}]}, "steps[1]", "orientation"),
        ({"src": SQUARE, "dst": [[0, 0], [10, 10], [10, 0], [0, 10]]}, "dst", "self-intersecting"),
        (
            {"steps": [{"src": SQUARE, "dst": [[0, 0], [0, 0], [1, 1], [0, 1]]}]},
            "steps[0].dst",
            "points 0 and 1 coincide",
        ),
        (
            {
                "src": [[1e8, 1e8], [1e8 + 1, 1e8], [1e8 + 1, 1e8 + 1], [1e8, 1e8 + 1]],
                "dst": [[1e8, 1e8], [1e8, 1e8 + 1], [1e8 + 1, 1e8 + 1], [1e8 + 1, 1e8]],
            },
            "spec",
            "opposite orientations",
        ),
    ],
)
def test_degenerate_geometry_is_named_with_its_step(spec, where, problem):
    validate_spec(spec)  # the structure is fine: a schema cannot see this
    with pytest.raises(SpecError) as info:
        build_transform(spec)
    assert str(info.value).startswith(f"{where}: ") and problem in str(info.value)


def test_parse_rejects_bad_json_and_non_finite_numbers():
    with pytest.raises(SpecError, match=r"^my\.json: not valid JSON"):
        parse_spec('{"src": [[0, 0],', "my.json")
    with pytest.raises(SpecError, match=r"^my\.json: NaN is not valid JSON"):
        parse_spec('{"src": [[NaN, 0], [1, 0], [1, 1], [0, 1]], "dst": []}', "my.json")
    with pytest.raises(SpecError, match=r"^my\.json: dst: must be"):
        parse_spec(json.dumps({"src": SQUARE, "dst": 5}), "my.json")


def test_load_spec_reads_a_file_and_names_it(tmp_path):
    path = tmp_path / "warp.json"
    path.write_text(json.dumps({"src": SQUARE, "dst": MOVED}))
    assert isinstance(load_spec(path), fpiwarp.FPI)
    path.write_bytes(b"\xff\xfe\x00garbage")
    with pytest.raises(SpecError, match="warp.json"):
        load_spec(path)
    with pytest.raises(FileNotFoundError):
        load_spec(tmp_path / "missing.json")


def _round_trip_cases():
    cases = [fpiwarp.FPI(SQUARE, MOVED), fpiwarp.Compound([fpiwarp.FPI(SQUARE, MOVED), fpiwarp.FPI(MOVED, SQUARE)])]
    try:
        from fpiwarp.maps.local import LocalDeformation
    except ImportError:
        return cases
    return cases + [LocalDeformation(SQUARE, [[0, 0], [10, 0], [11, 11], [0, 10]], edges=(3, 1))]


@pytest.mark.parametrize("transform", _round_trip_cases(), ids=lambda t: type(t).__name__)
def test_to_spec_round_trips_through_json(transform, tmp_path):
    path = tmp_path / "saved.json"
    save_spec(transform, path)
    again = load_spec(path)
    assert type(again) is type(transform)
    np.testing.assert_allclose(again(PTS), transform(PTS), rtol=0, atol=1e-9)
    with pytest.raises(FileExistsError):
        save_spec(transform, path)


def test_to_spec_refuses_maps_it_cannot_describe():
    with pytest.raises(TypeError, match="Mobius"):
        to_spec(fpiwarp.Mobius(1, 2, 0, 1))


def test_docstring_examples():
    import fpiwarp.spec

    result = doctest.testmod(fpiwarp.spec, optionflags=doctest.ELLIPSIS)
    assert result.attempted > 0 and result.failed == 0


# --- nesting limits, byte-order marks, far coordinates (issue 12) ---------------


def _nested(levels):
    spec = {"src": SQUARE, "dst": MOVED}
    for _ in range(levels):
        spec = {"steps": [spec]}
    return spec


@pytest.mark.parametrize("levels", [33, 100, 3000])
def test_deep_compounds_are_one_line_errors(levels):
    with pytest.raises(SpecError) as info:
        build_transform(_nested(levels))
    message = str(info.value)
    assert "\n" not in message and f"more than {spec_module.MAX_NESTING} levels of 'steps'" in message
    assert message.startswith("steps[0]." * spec_module.MAX_NESTING)


def test_the_deepest_allowed_compound_builds_from_text_and_dict():
    spec = _nested(spec_module.MAX_NESTING)
    assert np.allclose(build_transform(spec)(PTS), fpiwarp.FPI(SQUARE, MOVED)(PTS))
    assert np.allclose(parse_spec(json.dumps(spec))(PTS), fpiwarp.FPI(SQUARE, MOVED)(PTS))


@pytest.mark.parametrize(
    "text",
    [
        "[" * 100_000,
        '{"a": ' * 100_000,
        '{"steps": [' * 3000 + json.dumps({"src": SQUARE, "dst": MOVED}) + "]}" * 3000,
        "[" * 69 + "]" * 69,
    ],
)
def test_deeply_nested_text_is_refused_before_parsing(text):
    with pytest.raises(SpecError, match=rf"^deep\.json: brackets nest more than {spec_module.MAX_JSON_DEPTH} deep"):
        parse_spec(text, "deep.json")


def test_brackets_inside_text_do_not_count_as_nesting():
    spec = {"src": SQUARE, "dst": MOVED, "description": "[" * 500 + '\\"{' * 100}
    assert isinstance(parse_spec(json.dumps(spec)), fpiwarp.FPI)


def test_a_utf8_byte_order_mark_is_ignored(tmp_path):
    text = json.dumps({"src": SQUARE, "dst": MOVED})
    assert isinstance(parse_spec("\ufeff" + text), fpiwarp.FPI)
    path = tmp_path / "bom.json"
    path.write_text(text, encoding="utf-8-sig")
    assert path.read_bytes().startswith(b"\xef\xbb\xbf")
    assert np.allclose(load_spec(path)(PTS), fpiwarp.FPI(SQUARE, MOVED)(PTS))


@settings(max_examples=60, deadline=None)
@given(
    st.floats(1.0000001e100, 1e308) | st.floats(-1e308, -1.0000001e100),
    st.integers(0, 3),
    st.integers(0, 1),
    st.sampled_from(["src", "dst"]),
)
def test_coordinates_beyond_the_limit_are_named(value, point, axis, key):
    spec = {
        "steps": [{"src": SQUARE, "dst": MOVED}, {"src": [list(p) for p in SQUARE], "dst": [list(p) for p in MOVED]}]
    }
    spec["steps"][1][key][point][axis] = value
    with pytest.raises(SpecError) as info:
        build_transform(spec)
    assert str(info.value).startswith(f"steps[1].{key}[{point}]: {'xy'[axis]} = ")
    assert "lies beyond" in str(info.value)


@settings(max_examples=60, deadline=None)
@given(st.floats(-1e9, 1e9), st.floats(-1e9, 1e9), st.floats(1e-3, 1e6))
def test_far_and_scaled_specs_build_the_same_map(dx, dy, scale):
    """A spec moved and scaled anywhere in range builds a map that still
    sends its corners home (the checks do not depend on the position)."""
    src = [[x * scale + dx, y * scale + dy] for x, y in SQUARE]
    dst = [[x * scale + dx, y * scale + dy] for x, y in MOVED]
    f = parse_spec(json.dumps({"src": src, "dst": dst}))
    tol = 1e-9 * 10 * scale + 64 * np.finfo(float).eps * (abs(dx) + abs(dy) + 11 * scale)
    assert np.abs(f(src) - np.array(dst)).max() <= tol
