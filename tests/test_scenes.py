"""Scene files: round trip, rejection of malformed or impossible scenes, the sampler."""

import numpy as np
import pytest

from drake_symplan.world.scenes import (
    ObjectSpec,
    Scene,
    SceneError,
    as_saved,
    load_scene,
    sample_scene,
    save_scene,
    validate_scene,
)


def test_round_trip(tmp_path):
    scene = Scene([ObjectSpec("o0", "cube", [0.7, 0.0, 0.025], 0.0),
                   ObjectSpec("o1", "long", [0.6, 0.25, 0.025], 0.1)])
    save_scene(scene, tmp_path / "s.yaml")
    loaded = load_scene(tmp_path / "s.yaml")
    assert loaded.names == ["o0", "o1"]
    assert loaded.objects[1].type == "long"
    assert np.allclose(loaded.objects[1].position, [0.6, 0.25, 0.025])
    assert loaded.objects[1].yaw == pytest.approx(0.1)


def test_reads_the_documented_format(tmp_path):
    path = tmp_path / "s.yaml"
    path.write_text("objects:\n"
                    "  - {name: o0, type: cube, position: [0.70, 0.00, 0.025], yaw: 0.0}\n"
                    "  - {name: o1, type: long, position: [0.60, 0.25, 0.025], yaw: 0.0}\n")
    assert load_scene(path).names == ["o0", "o1"]


@pytest.mark.parametrize("objects, message", [
    ([("a", "sphere", [0.7, 0, 0.025])], "unknown type 'sphere'"),
    ([("a", "cube", [0.7, 0, 0.025]), ("b", "cube", [0.72, 0, 0.025])], "overlap"),
    ([("a", "cube", [1.3, 0, 0.025])], "outside the workspace"),
    ([("a", "cube", [0.7, 0, 0.2])], "rests on neither"),
    ([("a", "cube", [0.7, 0, 0.025]), ("a", "cube", [0.5, 0, 0.025])], "unique"),
])
def test_rejects_impossible_scenes(objects, message):
    scene = Scene([ObjectSpec(n, t, p, 0.0) for n, t, p in objects])
    with pytest.raises(SceneError, match=message):
        validate_scene(scene)


def test_stacks_are_valid():
    validate_scene(Scene([ObjectSpec("a", "long", [0.7, 0, 0.025]),
                          ObjectSpec("b", "cube", [0.7, 0.1, 0.075]),
                          ObjectSpec("c", "cube", [0.7, 0.1, 0.125])]))


def test_malformed_file(tmp_path):
    path = tmp_path / "s.yaml"
    path.write_text("objects:\n  - {name: o0, type: cube}\n")
    with pytest.raises(SceneError, match="malformed"):
        load_scene(path)
    with pytest.raises(FileNotFoundError):
        load_scene(tmp_path / "missing.yaml")


def test_sampler_is_seeded_and_valid():
    for n in range(2, 9):
        a = sample_scene(np.random.default_rng(n), n)
        b = sample_scene(np.random.default_rng(n), n)
        assert len(a.objects) == n
        assert [o.position for o in a.objects] == [o.position for o in b.objects]
        validate_scene(a)


def test_a_scene_is_checked_as_its_file_reads_back(tmp_path):
    scene = Scene([ObjectSpec("a", "cube", [0.612345678, -0.1, 0.025], 0.123456789)])
    saved = as_saved(scene)  # numbers rounded as written, then validated
    assert saved.objects[0].position == [0.6123, -0.1, 0.025]
    assert saved.objects[0].yaw == 0.1235
    save_scene(scene, tmp_path / "s.yaml")
    assert load_scene(tmp_path / "s.yaml") == saved
