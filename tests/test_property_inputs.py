"""Whatever a user types, generated (Hypothesis): scene files, goal specs and numeric option
values, malformed ones included, end valid or as one line of bad input, never a traceback."""

from __future__ import annotations

import math

import yaml
from conftest import run
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from drake_symplan.cli.main import BAD_INPUT
from drake_symplan.goals import compiler
from drake_symplan.relations import SpecError, parse
from drake_symplan.world.scenes import ObjectSpec, Scene

CHEAP = settings(max_examples=60, deadline=None,
                 suppress_health_check=[HealthCheck.function_scoped_fixture])

numbers = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(),
                    st.integers(min_value=10**300, max_value=10**400), st.booleans(),
                    st.text(max_size=5), st.none())
objects = st.fixed_dictionaries(
    {"name": st.one_of(st.sampled_from(["o0", "o1", "o2"]), st.integers(), st.booleans()),
     "type": st.sampled_from(["cube", "long", "ball"]),
     "position": st.one_of(st.lists(numbers, min_size=0, max_size=4),
                           st.tuples(st.floats(0.5, 0.9), st.floats(-0.3, 0.3),
                                     st.just(0.025)).map(list))},
    optional={"yaw": numbers, "rpy": st.lists(numbers, max_size=4), "colour": numbers})
scenes = st.one_of(st.fixed_dictionaries({"objects": st.lists(objects, max_size=4)}),
                   st.lists(objects, max_size=2), st.text(max_size=20), st.none())


@CHEAP
@given(data=scenes)
def test_a_scene_file_loads_or_is_one_line_of_bad_input(tmp_path_factory, data):
    from drake_symplan.cli.world_cmds import load_scene_file

    path = tmp_path_factory.mktemp("scene") / "scene.yaml"
    path.write_text(yaml.safe_dump(data) if not isinstance(data, str) else data)
    try:
        scene = load_scene_file(path)
    except BAD_INPUT as e:  # what the command line tells as one line, exit 2
        assert "\n" not in str(e) and str(e)
        return
    assert all(math.isfinite(v) for o in scene.objects for v in o.position)


START = Scene([ObjectSpec("o0", "cube", [0.6, -0.2, 0.025]),
               ObjectSpec("o1", "cube", [0.75, 0.0, 0.025]),
               ObjectSpec("o2", "long", [0.9, 0.1, 0.025]),
               ObjectSpec("o3", "cube", [0.6, 0.15, 0.025])]).object_states()
words = st.sampled_from(["on", "tower", "bridge", "row", "fly", "", "o0", "o1", "o2", "o3",
                         "o9", "tower\x00", " "])


@CHEAP
@given(specs=st.lists(st.lists(words, max_size=6).map(" ".join), min_size=1, max_size=3))
def test_a_goal_spec_compiles_or_is_one_line_of_bad_input(specs):
    try:
        actions = compiler.check(parse(specs), START)
    except SpecError as e:
        assert "\n" not in str(e) and str(e)
        return
    assert all(a.source in START and a.target in START for a in actions)


option_values = st.one_of(st.floats(allow_nan=True, allow_infinity=True).map(repr),
                          st.integers(min_value=-10**30, max_value=10**30).map(str),
                          st.sampled_from(["inf", "-inf", "nan", "1e400", "1e23", "-1", "0",
                                           "three", "", "0x10", "1_000", "٣"]))


@CHEAP
@given(objects=option_values, seed=option_values, jitter=option_values)
def test_numeric_options_are_taken_or_one_line_of_bad_input(tmp_path_factory, capsys,
                                                            objects, seed, jitter):
    out = tmp_path_factory.mktemp("sample") / "scene.yaml"
    code, stdout, err = run(["scene", "sample", "--objects", objects, "--seed", seed,
                             "--yaw-jitter-deg", jitter, "--out", out], capsys)
    assert code in (0, 2), err
    if code == 2:
        assert stdout == "" and err.count("\n") == 1 and not out.exists(), err
    assert "Traceback" not in err
